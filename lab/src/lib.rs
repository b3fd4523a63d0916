//! `vwb-lab`: everything the workbench does without a window. Headless rendering
//! ([`headless`]), the measurement engine (timing, comparison against converged
//! references, per-plugin cost, sweeps with Pareto fronts, scene JSON: [`measure`]),
//! background jobs ([`job`]), document loading ([`document`]), the output-path rules
//! ([`outputs`]) and experiment files, the studies declared in RON that regenerate the
//! docs ([`experiment`], `vwb run`).
//!
//! It depends on the renderer and the built-in plugins, never on egui: the app's CLI
//! and window are thin layers over it, and scripts or other front ends (a Python
//! binding, an experiment runner) can use it directly. No module here imports the app.

pub mod animation;
pub mod build_sources;
pub mod document;
pub mod experiment;
pub mod headless;
pub mod job;
pub mod measure;
pub mod outputs;
pub mod progress;
pub mod search;
pub mod thumbnail;
