//! Studies: programs that measure one question over presets and parameters and write
//! a Markdown report into docs/ (each is reachable from the CLI).

pub mod dos;
