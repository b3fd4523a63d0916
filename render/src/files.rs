//! File helpers shared by every writer: atomic saves that keep the file's mode and
//! follow symbolic links, paths relative to a folder, and "is this the same file".

use std::io::Write;
use std::path::{Component, Path, PathBuf};
use std::sync::Mutex;

/// Files this process reads (presets, volumes, data files, label volumes), with what
/// they are; [`write_atomic`] refuses to write over any of them.
static INPUTS: Mutex<Vec<(String, PathBuf)>> = Mutex::new(Vec::new());

/// Registers an input file (`role` says what it is, e.g. "preset" or "volume data
/// file") that no output of this process may overwrite.
pub fn protect_input(role: &str, path: &Path) {
    if let Ok(mut inputs) = INPUTS.lock()
        && !inputs.iter().any(|(_, p)| p == path)
    {
        inputs.push((role.to_string(), path.to_path_buf()));
    }
}

/// Removes a file from the inputs (the window's preset: saving over it is the point).
pub fn unprotect_input(path: &Path) {
    if let Ok(mut inputs) = INPUTS.lock() {
        inputs.retain(|(_, p)| !same_file(p, path) && p != path);
    }
}

/// An error when `output` is one of the registered inputs (the same file after
/// following links: same device and inode), naming both.
pub fn check_not_input(output: &Path) -> std::io::Result<()> {
    let inputs = INPUTS.lock().map(|i| i.clone()).unwrap_or_default();
    for (role, input) in &inputs {
        if same_file(output, input) {
            return Err(std::io::Error::other(format!(
                "refusing to overwrite the {role} {} (the output {} is the same file); choose \
                 another output path",
                input.display(),
                output.display()
            )));
        }
    }
    Ok(())
}

/// Where a write to `path` lands: `path` itself, or the file a symbolic link (chain)
/// points to, so that saving through a link updates its target instead of replacing
/// the link by a regular file.
pub fn write_target(path: &Path) -> std::io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let link = std::fs::read_link(&p)?;
                p = if link.is_absolute() {
                    link
                } else {
                    p.parent().unwrap_or(Path::new("")).join(link)
                };
            }
            _ => return Ok(p),
        }
    }
    Err(std::io::Error::other(format!(
        "{}: too many levels of symbolic links",
        path.display()
    )))
}

/// Writes `bytes` to `path` atomically: a temporary file in the same folder is
/// written, synced and renamed over the target, then the folder is synced, so the old
/// file stays intact if anything fails and the new one survives a crash. A symbolic
/// link is followed (its target is replaced, the link stays), and an existing file
/// keeps its permissions.
///
/// Refuses to write over a file registered with [`protect_input`].
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    check_not_input(path)?;
    let path = write_target(path)?;
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| "out".into());
    let old = std::fs::metadata(&path).ok();
    if old.as_ref().is_some_and(|m| m.is_dir()) {
        return Err(std::io::Error::other("is a folder, not a file"));
    }
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        if let Some(m) = &old {
            f.set_permissions(m.permissions())?;
        }
        f.sync_all()?;
        std::fs::rename(&tmp, &path)?;
        sync_dir(dir)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Makes a rename in `dir` durable (a no-op where folders cannot be opened).
fn sync_dir(dir: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::fs::File::open(dir)?.sync_all()
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        Ok(())
    }
}

/// `path` made absolute against the working folder, with `.` and `..` folded
/// lexically (no file needs to exist).
pub fn absolute(path: &Path) -> PathBuf {
    let joined = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .unwrap_or_else(|_| PathBuf::from("."))
            .join(path)
    };
    let mut out = PathBuf::new();
    for c in joined.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    out.push(c);
                }
            }
            other => out.push(other),
        }
    }
    out
}

/// `path` (relative to the working folder, or absolute) expressed relative to the
/// folder `base`; `None` where no relative path exists (another drive on Windows).
pub fn relative_to(path: &Path, base: &Path) -> Option<PathBuf> {
    let (p, b) = (absolute(path), absolute(base));
    let pc: Vec<Component> = p.components().collect();
    let bc: Vec<Component> = b.components().collect();
    if pc.first() != bc.first() {
        return None;
    }
    let common = pc.iter().zip(&bc).take_while(|(a, b)| a == b).count();
    let mut out = PathBuf::new();
    for _ in common..bc.len() {
        out.push("..");
    }
    for c in &pc[common..] {
        out.push(c);
    }
    if out.as_os_str().is_empty() {
        out.push(".");
    }
    Some(out)
}

/// Whether two paths name the same existing file (after following links: same
/// device and inode on Unix, same canonical path elsewhere).
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return x.dev() == y.dev() && x.ino() == y.ino();
        }
    }
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("vwb-files-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn relative_paths() {
        let r = |p: &str, b: &str| relative_to(Path::new(p), Path::new(b)).unwrap();
        assert_eq!(r("/a/b/c.nrrd", "/a/d"), PathBuf::from("../b/c.nrrd"));
        assert_eq!(r("/a/b/c.nrrd", "/a/b"), PathBuf::from("c.nrrd"));
        assert_eq!(r("/a/b", "/a/b"), PathBuf::from("."));
        assert_eq!(r("/a/./x/../b/c", "/a"), PathBuf::from("b/c"));
        let cwd = std::env::current_dir().unwrap();
        assert_eq!(
            relative_to(Path::new("x/y.nrrd"), &cwd.join("x")).unwrap(),
            PathBuf::from("y.nrrd")
        );
    }

    #[cfg(unix)]
    #[test]
    fn atomic_write_keeps_the_mode_and_follows_links() {
        use std::os::unix::fs::PermissionsExt;
        let d = scratch("atomic");
        let target = d.join("real.ron");
        std::fs::write(&target, "old").unwrap();
        std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o600)).unwrap();
        let link = d.join("link.ron");
        std::os::unix::fs::symlink("real.ron", &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink(),
            "the link stays a link"
        );
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        let mode = std::fs::metadata(&target).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        assert!(same_file(&link, &target));
        assert!(!same_file(&link, &d.join("missing")));
        // a registered input is never overwritten, not even through a link
        protect_input("test input", &target);
        let e = write_atomic(&link, b"gone").unwrap_err().to_string();
        assert!(e.contains("refusing to overwrite the test input"), "{e}");
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        // a folder is refused, and nothing is left behind
        assert!(write_atomic(&d, b"x").is_err());
        let left: Vec<_> = std::fs::read_dir(&d).unwrap().collect();
        assert_eq!(left.len(), 2);
    }
}
