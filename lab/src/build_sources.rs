//! The sources the binaries are built from, in one list: `build.rs` marks a build
//! `+dirty` where one of them differs from HEAD (`VWB_BUILD_COMMIT`,
//! [`crate::measure::build`]), and the tests check that mark against the same list.

/// What the binaries are built from, relative to the workspace root: a change in any of
/// them makes a build `+dirty` until it is committed (docs, presets and experiment files
/// do not change the binary; `lab/build.rs` is inside `lab`).
pub const BUILD_SOURCES: [&str; 7] = [
    "app",
    "lab",
    "plugins",
    "render",
    "shaders",
    "Cargo.toml",
    "Cargo.lock",
];
