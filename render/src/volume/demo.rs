//! The embedded demo volume.

use super::{Volume, load_nrrd_bytes};

/// The VolPack MRI head (128x128x84 uint8) as an attached-header, gzip-encoded
/// NRRD; provenance and licence in `data/LICENSE-demo.md`.
const DEMO_NRRD: &[u8] = include_bytes!("../../data/demo_mri_head.nrrd");

/// Where the embedded file sits in this source tree (for tools that read it themselves,
/// such as `vwb scene`'s `demo_path`).
pub const DEMO_SOURCE_PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/demo_mri_head.nrrd");

/// File name used in (impossible) error messages about the embedded file.
const DEMO_FILE: &str = "demo_mri_head.nrrd";

/// The embedded demo volume: a 128x128x84 uint8 MRI head with unit spacing,
/// parsed through the same NRRD reader as files. Named `"demo"`, no source.
pub fn demo() -> Volume {
    // The embedded bytes are fixed at compile time and loaded by the tests, so
    // this cannot fail at run time.
    let mut volume = load_nrrd_bytes(DEMO_FILE, DEMO_NRRD, None)
        .unwrap_or_else(|e| panic!("embedded demo volume is invalid: {e}"));
    volume.name = "demo".to_owned();
    volume.source = None;
    volume
}
