//! The `vwb` application: command-line interface and the workbench window.
//! Everything here drives the renderer crate (`vwb-render`) and the egui-free lab crate
//! (`vwb-lab`: headless rendering, measurement, studies, jobs, document loading); no
//! rendering or measuring logic lives in the app, only the UI and the CLI glue.

pub mod browser_ui;
pub mod cli;
pub mod cli_help;
pub mod clip_handles;
pub mod compare_ui;
pub mod crop;
pub mod data_cmd;
pub mod data_ui;
pub mod evolve_ui;
pub mod gallery_ui;
pub mod loading;
pub mod stack_ui;
#[cfg(test)]
mod test_input;
pub mod tf2d_editor;
pub mod tf_editor;
pub mod tradeoff_ui;
pub mod volumes_ui;
pub mod window;
