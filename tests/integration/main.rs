//! Integration tests of vwb on the CPU Vulkan device (Mesa lavapipe) or any real GPU.
//! GPU tests fail — never skip — when no Vulkan adapter exists.
//!
//! `VWB_BLESS=1 cargo test --test integration` regenerates the golden files.

#[cfg(unix)]
mod adversarial;
mod bricks;
mod classification;
mod cli;
mod clip_mesh;
mod clipping;
mod common;
mod composer;
mod coverage;
mod data;
mod dos;
mod experiment;
mod extremes;
mod fetch;
mod flow;
mod formats;
mod hernell;
mod presets;
mod reference;
mod render;
mod search;
mod shading;
mod user_plugins;
mod window;
