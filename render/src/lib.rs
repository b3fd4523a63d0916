//! vwb renderer core: volumes, slice geometry, the plugin API and WGSL composer, the
//! raster and compute slice pipelines, presets. No UI dependency.

pub mod camera;
pub mod composer;
pub mod files;
pub mod flow;
pub mod gpu;
pub mod inputs;
pub mod metrics;
pub mod params;
pub mod plugin;
pub mod preset;
pub mod reference;
pub mod renderer;
pub mod rng;
pub mod samples;
pub mod search;
pub mod shading;
pub mod skipping;
pub mod slicing;
pub mod suggest;
pub mod sweep;
pub mod tf;
pub mod tf2d;
pub mod validate;
pub mod volume;

pub use camera::{Camera, Projection};
pub use composer::{ComposeError, TargetFormat};
pub use gpu::GpuContext;
pub use plugin::{Plugin, PluginInstance, Registry};
pub use renderer::{
    Backend, FrameSettings, FrameStats, RenderCounters, RenderError, Renderer, StackChange,
};
pub use volume::Volume;
