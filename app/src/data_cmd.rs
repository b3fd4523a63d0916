//! `vwb data list` and `vwb data fetch`: the sample data sets of the manifest
//! (`render/data/samples.ron`) in the data directory ([`samples::data_dir`]).
//!
//! Fetching takes each file from a source — an HTTP(S) base URL, a folder (a lab's
//! mirror: `--from URL_OR_DIR` or `VWB_DATA_URL`), or for `mri_head` the voxels the
//! binary embeds — into `NAME.part`, checks its size and SHA-256 against the manifest and
//! only then renames it into place. An interrupted download keeps its `.part` and the
//! next fetch resumes it with a `Range` request; a file whose checksum does not match
//! is refused and deleted.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use vwb_render::samples::{self, FileState, Sample, SampleFile};

/// The environment variable naming a default mirror (URL or folder).
pub const DATA_URL_ENV: &str = "VWB_DATA_URL";

/// Where fetched files come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Source {
    /// Base URL; a file is `BASE/FILE_NAME`.
    Http(String),
    /// A folder holding the files by name.
    Dir(PathBuf),
}

impl Source {
    /// `http://…` or `https://…` is a URL; `file://PATH` and anything else a folder.
    pub fn parse(s: &str) -> Self {
        if s.starts_with("http://") || s.starts_with("https://") {
            Self::Http(s.trim_end_matches('/').to_string())
        } else {
            Self::Dir(PathBuf::from(s.strip_prefix("file://").unwrap_or(s)))
        }
    }

    /// `--from`, else `VWB_DATA_URL`, else none.
    pub fn from_args(from: Option<&str>) -> Option<Self> {
        from.map(str::to_string)
            .or_else(|| std::env::var(DATA_URL_ENV).ok().filter(|s| !s.is_empty()))
            .map(|s| Self::parse(&s))
    }
}

/// What `vwb data list` prints: the data directory and, per sample, its size and state
/// (checksums computed).
pub fn list(dir: &Path) -> Result<String> {
    let mut out = format!("data directory: {}\n", dir.display());
    for s in &samples::manifest().samples {
        let mut states = Vec::new();
        for f in &s.files {
            states.push(
                samples::check_file(dir, f, true)
                    .with_context(|| format!("{}", dir.join(&f.name).display()))?,
            );
        }
        let state = if states.iter().all(|s| *s == FileState::Verified) {
            "verified".to_string()
        } else if states.iter().all(|s| *s == FileState::Missing) {
            format!("missing (vwb data fetch {})", s.name)
        } else {
            s.files
                .iter()
                .zip(&states)
                .filter(|(_, st)| **st != FileState::Verified)
                .map(|(f, st)| format!("{}: {}", f.name, st.describe()))
                .collect::<Vec<_>>()
                .join(", ")
        };
        out.push_str(&format!(
            "{:<11} {:>9}  {state}\n            {}\n",
            s.name,
            mib(s.size()),
            s.title
        ));
    }
    Ok(out)
}

fn mib(bytes: u64) -> String {
    if bytes < 1 << 20 {
        format!("{:.1} KiB", bytes as f64 / 1024.0)
    } else {
        format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
    }
}

/// Fetches the named samples (all when `names` is empty) into `dir`; files already there
/// and verified are kept. One outcome per sample (a line or the failure); an unknown
/// name or an unusable data directory fails before anything is fetched.
pub fn fetch(
    names: &[String],
    dir: &Path,
    source: Option<&Source>,
) -> Result<Vec<Result<String, String>>> {
    let manifest = samples::manifest();
    let chosen: Vec<&Sample> = if names.is_empty() {
        manifest.samples.iter().collect()
    } else {
        names
            .iter()
            .map(|n| manifest.get(n))
            .collect::<Result<_, _>>()?
    };
    Ok(chosen
        .into_iter()
        .map(|s| fetch_sample(s, dir, source).map_err(|e| format!("{e:#}")))
        .collect())
}

/// Fetches one sample's files.
pub fn fetch_sample(s: &Sample, dir: &Path, source: Option<&Source>) -> Result<String> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the data directory", dir.display()))?;
    let mut fetched = 0;
    for f in &s.files {
        let state = samples::check_file(dir, f, true)
            .with_context(|| format!("{}", dir.join(&f.name).display()))?;
        if state == FileState::Verified {
            continue;
        }
        let part = dir.join(format!("{}.part", f.name));
        match (source, s.embedded_bytes(f)) {
            (Some(Source::Http(base)), _) => {
                download(&format!("{base}/{}", f.name), &part, f.size)?;
            }
            (Some(Source::Dir(from)), _) => {
                let src = from.join(&f.name);
                let mut input = std::fs::File::open(&src)
                    .with_context(|| format!("{}: cannot open", src.display()))?;
                let mut output = std::fs::File::create(&part)
                    .with_context(|| format!("{}: cannot write", part.display()))?;
                std::io::copy(&mut input, &mut output)
                    .with_context(|| format!("{}: cannot copy", src.display()))?;
            }
            (None, Some(bytes)) => std::fs::write(&part, bytes)
                .with_context(|| format!("{}: cannot write", part.display()))?,
            (None, None) => bail!(
                "{}: no download source: no public server publishes these converted files \
                 (made from {}; original at {}). Fetch them from a mirror with `vwb data \
                 fetch --from URL_OR_DIR {}` or set {DATA_URL_ENV}",
                s.name,
                s.origin,
                s.source,
                s.name
            ),
        }
        accept(&part, &dir.join(&f.name), f)?;
        fetched += 1;
    }
    Ok(format!(
        "{}: {} ({} of {} files fetched, all verified)",
        s.name,
        mib(s.size()),
        fetched,
        s.files.len()
    ))
}

/// Checks a finished `.part` against the manifest and renames it into place; a wrong
/// size or checksum deletes it.
fn accept(part: &Path, dest: &Path, f: &SampleFile) -> Result<()> {
    let len = std::fs::metadata(part)
        .with_context(|| format!("{}", part.display()))?
        .len();
    let problem = if len != f.size {
        Some(format!("has {len} bytes, the manifest says {}", f.size))
    } else {
        let sum = samples::sha256_file(part).with_context(|| format!("{}", part.display()))?;
        (sum != f.sha256)
            .then(|| format!("SHA-256 {sum} does not match the manifest's {}", f.sha256))
    };
    if let Some(problem) = problem {
        let _ = std::fs::remove_file(part);
        bail!(
            "{}: {problem}; the download was refused and deleted",
            f.name
        );
    }
    std::fs::rename(part, dest)
        .with_context(|| format!("{}: cannot move into place", dest.display()))
}

/// An HTTP agent; loopback hosts bypass any proxy from the environment.
fn agent(url: &str) -> ureq::Agent {
    let rest = url.split("://").nth(1).unwrap_or("");
    let loopback = ["127.0.0.1", "localhost", "[::1]"]
        .iter()
        .any(|h| rest.starts_with(h));
    let mut cfg = ureq::Agent::config_builder()
        .timeout_connect(Some(std::time::Duration::from_secs(30)))
        .timeout_recv_response(Some(std::time::Duration::from_secs(60)));
    if loopback {
        cfg = cfg.proxy(None);
    }
    cfg.build().new_agent()
}

/// Downloads `url` into `part`, resuming what `part` already holds with a `Range`
/// request; a progress bar on a terminal. An interrupted transfer keeps `part`.
pub fn download(url: &str, part: &Path, size: u64) -> Result<()> {
    let mut have = std::fs::metadata(part).map_or(0, |m| m.len());
    if have > size {
        std::fs::remove_file(part).with_context(|| format!("{}", part.display()))?;
        have = 0;
    }
    if have == size {
        return Ok(());
    }
    let mut request = agent(url).get(url);
    if have > 0 {
        request = request.header("Range", &format!("bytes={have}-"));
    }
    let mut response = request
        .call()
        .with_context(|| format!("{url}: download failed"))?;
    let resumed = response.status().as_u16() == 206;
    if resumed {
        let range = response
            .headers()
            .get("content-range")
            .and_then(|v| v.to_str().ok())
            .unwrap_or("");
        if !range.starts_with(&format!("bytes {have}-")) {
            bail!("{url}: the server answered the range {have}- with '{range}'");
        }
    } else {
        have = 0;
    }
    let mut file = std::fs::OpenOptions::new()
        .create(true)
        .write(true)
        .append(resumed)
        .truncate(!resumed)
        .open(part)
        .with_context(|| format!("{}: cannot write", part.display()))?;
    let bar = indicatif::ProgressBar::new(size);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} {bar:30} {bytes}/{total_bytes} [{eta}]")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message(part.file_name().map_or(String::new(), |n| {
        n.to_string_lossy().trim_end_matches(".part").to_string()
    }));
    bar.set_position(have);
    let mut reader = response.body_mut().as_reader();
    let mut buf = vec![0u8; 1 << 16];
    let mut got = have;
    loop {
        let n = match reader.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) => {
                file.flush().ok();
                bar.abandon();
                bail!(
                    "{url}: interrupted after {got} of {size} bytes ({e}); {} keeps them and \
                     the same command resumes",
                    part.display()
                );
            }
        };
        file.write_all(&buf[..n])
            .with_context(|| format!("{}: cannot write", part.display()))?;
        got += n as u64;
        bar.set_position(got);
        if got > size {
            break;
        }
    }
    file.sync_all()
        .with_context(|| format!("{}: cannot write", part.display()))?;
    bar.finish_and_clear();
    if got < size {
        bail!(
            "{url}: the transfer ended after {got} of {size} bytes; {} keeps them and the \
             same command resumes",
            part.display()
        );
    }
    Ok(())
}

/// `vwb data …`
#[derive(Debug, clap::Subcommand)]
pub enum DataCommand {
    /// List the samples: size, and whether the data directory holds them with the
    /// manifest's checksums.
    #[command(after_help = crate::cli_help::DATA_LIST)]
    List,
    /// Download samples into the data directory (all when no NAME is given), verify
    /// their SHA-256 and resume interrupted downloads.
    #[command(after_help = crate::cli_help::DATA_FETCH)]
    Fetch(FetchArgs),
}

#[derive(Debug, clap::Args)]
pub struct FetchArgs {
    /// Sample names (see `vwb data list`).
    pub names: Vec<String>,
    /// Mirror of the sample files: an http(s) base URL or a folder (default:
    /// $VWB_DATA_URL; mri_head needs none).
    #[arg(long)]
    pub from: Option<String>,
}

pub fn run(cmd: &DataCommand) -> Result<()> {
    let dir = samples::data_dir()?;
    match cmd {
        DataCommand::List => print!("{}", list(&dir)?),
        DataCommand::Fetch(a) => {
            let source = Source::from_args(a.from.as_deref());
            let outcomes = fetch(&a.names, &dir, source.as_ref())?;
            eprintln!("data directory: {}", dir.display());
            let mut failed = Vec::new();
            for o in outcomes {
                match o {
                    Ok(line) => println!("{line}"),
                    Err(e) => failed.push(e),
                }
            }
            if !failed.is_empty() {
                bail!("{}", failed.join("\n"));
            }
        }
    }
    Ok(())
}
