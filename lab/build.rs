//! Records the commit the laboratory is built from as `VWB_BUILD_COMMIT`, so that an
//! experiment's report names the build that measured it (`vwb_lab::measure::build`):
//! `git rev-parse --short=12 HEAD` in the source tree, empty where the tree is no git
//! checkout (a source archive) or git is missing; with `+dirty` where the sources the
//! binary is built from (the crates, the shaders, the lock file; the list in
//! `src/build_sources.rs`) differ from that commit. Reruns when HEAD moves or one of
//! those sources changes.

use std::path::{Path, PathBuf};
use std::process::Command;

fn git(dir: &Path, args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .args(args)
        .current_dir(dir)
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
        .filter(|s| !s.is_empty())
}

#[path = "src/build_sources.rs"]
mod build_sources;
use build_sources::BUILD_SOURCES as SOURCES;

fn main() {
    let dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| ".".into()));
    let root = dir.parent().unwrap_or(&dir).to_path_buf();
    let mut commit = git(&dir, &["rev-parse", "--short=12", "HEAD"]).unwrap_or_default();
    if !commit.is_empty() {
        let mut args = vec!["status", "--porcelain", "--untracked-files=normal", "--"];
        args.extend(SOURCES.iter().copied().filter(|s| root.join(s).exists()));
        // `git status` prints nothing for a clean tree (and fails outside a checkout)
        if git(&root, &args).is_some() {
            commit.push_str("+dirty");
        }
        for s in SOURCES {
            let path = root.join(s);
            if path.exists() {
                // a folder is scanned for changes throughout
                println!("cargo:rerun-if-changed={}", path.display());
            }
        }
    }
    println!("cargo:rustc-env=VWB_BUILD_COMMIT={commit}");
    // HEAD, the branch it points at and the packed refs: where a commit or a checkout
    // shows; only paths that exist (a missing one would rerun the script every build)
    let mut watched = vec!["HEAD".to_string(), "packed-refs".to_string()];
    if let Some(branch) = git(&dir, &["symbolic-ref", "-q", "HEAD"]) {
        watched.push(branch);
    }
    let mut any = false;
    for name in watched {
        if let Some(path) = git(&dir, &["rev-parse", "--git-path", &name]) {
            let path = dir.join(path);
            if path.exists() {
                println!("cargo:rerun-if-changed={}", path.display());
                any = true;
            }
        }
    }
    if !any {
        println!("cargo:rerun-if-changed=build.rs");
    }
}
