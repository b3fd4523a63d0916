//! The `vwb` application: command-line interface and the workbench window.
//! Everything here drives the renderer crate; no rendering logic lives in the app.

pub mod browser_ui;
pub mod classification;
pub mod cli;
pub mod cli_help;
pub mod compare_ui;
pub mod crop;
pub mod custom_ui;
pub mod data_cmd;
pub mod data_ui;
pub mod dos_study;
pub mod headless;
pub mod job;
pub mod loading;
pub mod measure;
pub mod outputs;
pub mod stack_ui;
#[cfg(test)]
mod test_input;
pub mod tf2d_editor;
pub mod tf_editor;
pub mod tradeoff_ui;
pub mod window;
