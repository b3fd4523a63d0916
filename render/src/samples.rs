//! Sample data sets by name: a preset says `volume: Sample("ct_head")` instead of a
//! path, and the name is looked up in the manifest (`render/data/samples.ron`, embedded)
//! and resolved in the data directory.
//!
//! The data directory is `VWB_DATA_DIR` when set, else a process default set with
//! [`set_default_data_dir`] (the test harness points it at the shared test data), else
//! the user's cache directory + `vwb/data`. A sample that is not there is an error that
//! names the command that fetches it (`vwb data fetch ct_head`).

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use serde::Deserialize;
use sha2::{Digest, Sha256};

/// The manifest text (RON).
pub const MANIFEST: &str = include_str!("../data/samples.ron");

/// The environment variable naming the data directory.
pub const DATA_DIR_ENV: &str = "VWB_DATA_DIR";

/// `mri_head`'s header file, byte for byte; its voxels are those of the embedded demo.
const MRI_HEAD_NHDR: &[u8] = include_bytes!("../data/mri_head_volpack_128x128x84_uint8.nhdr");

/// One file of a sample.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct SampleFile {
    pub name: String,
    /// Size in bytes.
    pub size: u64,
    /// SHA-256, lower-case hex.
    pub sha256: String,
}

/// One sample data set.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct Sample {
    pub name: String,
    /// One line: what it shows, type, size, spacing.
    pub title: String,
    pub licence: String,
    /// The original public source (a package page): not a download of these bytes.
    pub source: String,
    /// Package, version and path of the original file.
    pub origin: String,
    /// How the original became these files.
    pub converted: String,
    /// The binary embeds the voxels, so fetching needs no network.
    #[serde(default)]
    pub embedded: bool,
    /// The detached NRRD header first, then its data file.
    pub files: Vec<SampleFile>,
}

impl Sample {
    /// The file a volume is loaded from (the `.nhdr`).
    pub fn header(&self) -> &SampleFile {
        &self.files[0]
    }

    /// Total size of its files in bytes.
    pub fn size(&self) -> u64 {
        self.files.iter().map(|f| f.size).sum()
    }

    /// The bytes of `file` when the binary embeds them (only `mri_head`).
    pub fn embedded_bytes(&self, file: &SampleFile) -> Option<Vec<u8>> {
        if !self.embedded {
            return None;
        }
        if file.name.ends_with(".nhdr") {
            return Some(MRI_HEAD_NHDR.to_vec());
        }
        match crate::volume::demo().data {
            crate::volume::VoxelData::U8(v) => Some(v),
            _ => None,
        }
    }
}

#[derive(Debug, Deserialize)]
pub struct Manifest {
    pub samples: Vec<Sample>,
}

impl Manifest {
    pub fn parse(text: &str) -> Result<Self, String> {
        let m: Manifest = ron::from_str(text).map_err(|e| format!("samples.ron: {e}"))?;
        for s in &m.samples {
            let ok = s.files.first().is_some_and(|f| f.name.ends_with(".nhdr"))
                && s.files.iter().all(|f| {
                    f.sha256.len() == 64 && f.sha256.bytes().all(|b| b.is_ascii_hexdigit())
                });
            if !ok {
                return Err(format!(
                    "samples.ron: sample '{}' needs a .nhdr first and 64-digit SHA-256s",
                    s.name
                ));
            }
        }
        Ok(m)
    }

    pub fn get(&self, name: &str) -> Result<&Sample, SampleError> {
        self.samples
            .iter()
            .find(|s| s.name == name)
            .ok_or_else(|| SampleError::Unknown {
                name: name.to_string(),
                known: self.names().join(", "),
            })
    }

    pub fn names(&self) -> Vec<&str> {
        self.samples.iter().map(|s| s.name.as_str()).collect()
    }
}

/// The embedded manifest (checked by the tests, so parsing cannot fail at run time).
pub fn manifest() -> &'static Manifest {
    static M: OnceLock<Manifest> = OnceLock::new();
    M.get_or_init(|| Manifest::parse(MANIFEST).unwrap_or_else(|e| panic!("{e}")))
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SampleError {
    #[error("unknown sample '{name}' (known: {known})")]
    Unknown { name: String, known: String },
    #[error(
        "sample '{name}' is not in the data directory {dir} ({file} {problem}); run `vwb data fetch {name}` (or set VWB_DATA_DIR to a folder that holds it)"
    )]
    Missing {
        name: String,
        dir: String,
        file: String,
        problem: String,
    },
    #[error("no data directory: set VWB_DATA_DIR (the user's cache directory is unknown)")]
    NoDataDir,
}

static DEFAULT_DIR: OnceLock<PathBuf> = OnceLock::new();

/// Sets the data directory used when `VWB_DATA_DIR` is unset, once per process
/// (the test harness: the shared test data). Returns false when one was set already.
pub fn set_default_data_dir(dir: PathBuf) -> bool {
    DEFAULT_DIR.set(dir).is_ok()
}

/// The data directory: `VWB_DATA_DIR`, else the process default, else the user's
/// cache directory + `vwb/data`.
pub fn data_dir() -> Result<PathBuf, SampleError> {
    if let Some(d) = std::env::var_os(DATA_DIR_ENV).filter(|d| !d.is_empty()) {
        return Ok(PathBuf::from(d));
    }
    if let Some(d) = DEFAULT_DIR.get() {
        return Ok(d.clone());
    }
    dirs::cache_dir()
        .map(|c| c.join("vwb").join("data"))
        .ok_or(SampleError::NoDataDir)
}

/// The header path of sample `name` in the data directory.
pub fn resolve(name: &str) -> Result<PathBuf, SampleError> {
    let sample = manifest().get(name)?;
    resolve_in(sample, &data_dir()?)
}

/// The header path of `sample` in `dir`: every file must be there with its size
/// (checksums are checked by `vwb data list` and `vwb data fetch`, not on each load).
pub fn resolve_in(sample: &Sample, dir: &Path) -> Result<PathBuf, SampleError> {
    for f in &sample.files {
        let problem = match std::fs::metadata(dir.join(&f.name)) {
            Err(_) => "is missing".to_string(),
            Ok(m) if m.len() != f.size => {
                format!("has {} bytes, expected {}", m.len(), f.size)
            }
            Ok(_) => continue,
        };
        return Err(SampleError::Missing {
            name: sample.name.clone(),
            dir: dir.display().to_string(),
            file: f.name.clone(),
            problem,
        });
    }
    Ok(dir.join(&sample.header().name))
}

/// The state of one sample file in a folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileState {
    Missing,
    /// Present with another size (bytes).
    WrongSize(u64),
    /// The size matches; the checksum was not computed.
    Unverified,
    Verified,
    /// The size matches and the checksum does not.
    Corrupt,
}

impl FileState {
    pub fn describe(&self) -> String {
        match self {
            Self::Missing => "missing".into(),
            Self::WrongSize(n) => format!("wrong size ({n} bytes)"),
            Self::Unverified => "present (not verified)".into(),
            Self::Verified => "verified".into(),
            Self::Corrupt => "CHECKSUM MISMATCH".into(),
        }
    }
}

/// Checks `file` in `dir`; `verify` computes the checksum.
pub fn check_file(dir: &Path, file: &SampleFile, verify: bool) -> std::io::Result<FileState> {
    let path = dir.join(&file.name);
    let len = match std::fs::metadata(&path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(FileState::Missing),
        Err(e) => return Err(e),
        Ok(m) => m.len(),
    };
    if len != file.size {
        return Ok(FileState::WrongSize(len));
    }
    if !verify {
        return Ok(FileState::Unverified);
    }
    Ok(if sha256_file(&path)? == file.sha256 {
        FileState::Verified
    } else {
        FileState::Corrupt
    })
}

/// SHA-256 of a file, lower-case hex.
pub fn sha256_file(path: &Path) -> std::io::Result<String> {
    let mut f = std::fs::File::open(path)?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(hex(&h.finalize()))
}

/// SHA-256 of bytes, lower-case hex.
pub fn sha256_bytes(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_manifest_parses_and_names_are_unique() {
        let m = manifest();
        let mut names = m.names();
        assert!(names.len() >= 6, "{names:?}");
        names.sort();
        names.dedup();
        assert_eq!(names.len(), m.samples.len(), "duplicate sample names");
        for s in &m.samples {
            assert!(s.source.starts_with("http"), "{}: source URL", s.name);
            assert!(
                !s.licence.is_empty() && !s.converted.is_empty(),
                "{}",
                s.name
            );
        }
        assert!(matches!(m.get("nope"), Err(SampleError::Unknown { .. })));
    }

    #[test]
    fn bad_manifests_are_refused() {
        let bad = r#"(samples: [(name: "x", title: "", licence: "", source: "", origin: "",
            converted: "", files: [(name: "x.raw", size: 1, sha256: "00")])])"#;
        assert!(Manifest::parse(bad).unwrap_err().contains("'x'"));
        assert!(Manifest::parse("(samples: [").is_err());
    }

    #[test]
    fn the_embedded_mri_head_matches_its_checksums() {
        let s = manifest().get("mri_head").unwrap();
        for f in &s.files {
            let bytes = s.embedded_bytes(f).expect("embedded");
            assert_eq!(bytes.len() as u64, f.size, "{}", f.name);
            assert_eq!(sha256_bytes(&bytes), f.sha256, "{}", f.name);
        }
        let ct = manifest().get("ct_head").unwrap();
        assert!(ct.embedded_bytes(ct.header()).is_none());
    }

    #[test]
    fn resolution_names_the_fetch_command() {
        let dir = std::env::temp_dir().join(format!("vwb-samples-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let s = manifest().get("storm_wind").unwrap();
        let e = resolve_in(s, &dir).unwrap_err().to_string();
        assert!(e.contains("run `vwb data fetch storm_wind`"), "{e}");
        assert!(
            e.contains(&s.header().name) && e.contains("is missing"),
            "{e}"
        );
        // a truncated file is named with its size
        std::fs::write(dir.join(&s.files[0].name), b"NRRD").unwrap();
        std::fs::write(dir.join(&s.files[1].name), b"").unwrap();
        let e = resolve_in(s, &dir).unwrap_err().to_string();
        assert!(e.contains("has 4 bytes, expected"), "{e}");
        assert_eq!(
            check_file(&dir, &s.files[1], true).unwrap(),
            FileState::WrongSize(0)
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
