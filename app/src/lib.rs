//! The `vwb` application: command-line interface and the workbench window.
//! Everything here drives the renderer crate; no rendering logic lives in the app.

pub mod classification;
pub mod cli;
pub mod compare_ui;
pub mod crop;
pub mod custom_ui;
pub mod dos_study;
pub mod headless;
pub mod job;
pub mod measure;
pub mod stack_ui;
#[cfg(test)]
mod test_input;
pub mod tf2d_editor;
pub mod tf_editor;
pub mod tradeoff_ui;
pub mod window;
