//! The slice renderer: uploads the volume, keeps the composed pipeline of the user's
//! plugin stack, and renders view-aligned slices with either backend.
//!
//! - **raster**: proxy polygons drawn front to back; the fragment shader runs the hook
//!   chain; blending composites `under` into the eye buffer.
//! - **compute**: one invocation per pixel steps through the same slice planes, with
//!   optional early ray termination; it rounds its accumulator to fp16 after every
//!   slice when the eye buffer is rgba16float, as the blender does.
//!
//! When an enabled plugin has per-slice state, both backends run slice by slice: draw
//! (or dispatch) slice k reading state A, then run the plugin's update writing state B,
//! swap. Pre-passes run before the slices, and only when the volume or the parameters
//! they depend on changed.
//!
//! Change tracking: [`Renderer::update_stack`] recomposes only when the structure
//! changed (which plugins are enabled, their order, structural parameters, the target
//! format); a parameter change only rewrites the instance's uniform buffer and lets the
//! plugin update its resources. If composition fails, the previous pipeline stays in
//! use and the error is returned.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::Mat4;
use serde::{Deserialize, Serialize};
use wgpu::util::DeviceExt;

use crate::camera::Camera;
use crate::composer::{
    Binding, BindingRole, ComposeError, Composition, STATE_TILE, TargetFormat, VolumeLayout,
    compose_for,
};
use crate::gpu::GpuContext;
use crate::params::ParamValues;
use crate::plugin::{
    Category, GpuInit, GpuResource, PassTarget, Plugin, PluginError, PluginInstance,
};
use crate::skipping::{
    BrickRanges, clear_outside_regions, move_apron, stack_moves, stack_regions, stack_visibility,
};
use crate::slicing::{FramePlan, SliceError, SlicePlan, VolumeBox};
use crate::volume::Volume;

mod atlas;
mod bricks;
mod level;
mod lod;
pub mod march_parts;
mod raster_et;
mod slice_exit;
pub use atlas::{Atlas, AtlasTile, EncodedAtlas};
pub use bricks::{BRICK_GHOST, BrickInfo, MIN_BRICK_LIMIT, RendererOptions, over, split_axis};
use bricks::{Region, Split, upload_or_split};
use level::level_for;
pub use level::{LevelInfo, halve};
pub use lod::{BRICKS_PER_STEP, LOD_BRICK};
pub use raster_et::{RASTER_ET_INTERVAL, RASTER_MASK_WGSL, interval as raster_et_interval};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum Backend {
    #[default]
    Raster,
    Compute,
}

impl Backend {
    pub fn name(self) -> &'static str {
        match self {
            Backend::Raster => "raster",
            Backend::Compute => "compute",
        }
    }
}

impl std::str::FromStr for Backend {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "raster" => Ok(Backend::Raster),
            "compute" => Ok(Backend::Compute),
            _ => Err(format!("unknown backend '{s}' (raster or compute)")),
        }
    }
}

/// Everything about one frame that is not the plugin stack.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameSettings {
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
    /// Distance between slices in voxels (1 = one slice per voxel).
    pub slice_spacing: f32,
    pub backend: Backend,
    /// Stop a ray once its opacity reaches this value: the compute backend after the
    /// slice that reaches it, the raster backend at the end of the run of
    /// [`raster_et_interval`] slices in which it does (a depth mask, `raster_et`).
    pub early_termination: Option<f32>,
}

impl Default for FrameSettings {
    fn default() -> Self {
        Self {
            camera: Camera::default(),
            width: 256,
            height: 256,
            slice_spacing: 1.0,
            backend: Backend::Raster,
            early_termination: None,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Compose(#[from] ComposeError),
    #[error(transparent)]
    Slices(#[from] SliceError),
    #[error(transparent)]
    Plugin(#[from] PluginError),
    #[error("image size {0}x{1} is invalid (1..={2} per side)")]
    BadSize(u32, u32, u32),
    #[error("volume {name}: {dims:?} exceeds the device's 3D texture limit of {limit}")]
    VolumeTooLarge {
        name: String,
        dims: [u32; 3],
        limit: u32,
    },
    #[error(
        "the raster backend needs blending on rgba32float (FLOAT32_BLENDABLE), which this adapter lacks; use --backend compute or rgba16float"
    )]
    NoFloat32Blending,
    #[error("per-slice passes are limited to {max} slices, this frame needs {count}")]
    TooManyPerSliceSlices { count: u32, max: u32 },
    #[error("GPU error: {0}")]
    Gpu(String),
    #[error(
        "the GPU device was lost ({0}); nothing more can be rendered on it: restart vwb \
         (the last image stays)"
    )]
    DeviceLost(String),
    #[error("GPU memory: {what} needs {} MiB, {reason}", bytes.div_ceil(1 << 20))]
    OutOfMemory {
        what: String,
        bytes: u64,
        /// "the budget of N MiB is M MiB short" or the driver's message.
        reason: String,
    },
    #[error("atlas: {0}")]
    Atlas(String),
    #[error("bricks: {0}")]
    Bricks(String),
    #[error("volume format {0}: this adapter lacks {1}; use auto or r32float")]
    VolumeFormatUnsupported(&'static str, &'static str),
    #[error(transparent)]
    Camera(#[from] crate::validate::FieldError),
}

/// Timings of one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameStats {
    pub slices: u32,
    /// GPU time per pass, from timestamp queries: `prepass <plugin id>` for every
    /// pre-pass that ran and `slices` for the slice loop (all hooks of all plugins
    /// in one shader, plus per-slice state updates). Empty without timestamps.
    pub gpu_passes: Vec<(String, f64)>,
    /// Total GPU time in ms, if timestamps are available.
    pub gpu_ms: Option<f64>,
    /// Wall time from encoding to the GPU finishing, in ms.
    pub wall_ms: f64,
    pub per_slice_mode: bool,
    /// The pre-passes of this frame, labelled `<plugin id>/prepass`.
    pub prepasses: Vec<String>,
    /// Volume-pass dispatches of this frame, labelled `<plugin id>/<target>`, one per
    /// refinement step ([`crate::plugin::VolumePassDecl`]).
    pub volume_passes_run: Vec<String>,
    /// Plugin resources rebuilt for a new slice spacing before this frame (e.g.
    /// pre-integration tables; [`Plugin::uses_slice_spacing`]).
    pub spacing_updates: usize,
    /// Raster backend: the share of the renderer's box that its proxy polygons cover
    /// (its visible box's: 1 without empty-space skipping, less where the occupied
    /// bricks' bounds are smaller than the box, and less again with
    /// [`Renderer::set_occupied_proxy`], or the hull's [`HullProxy::Cut`]); `None` for
    /// compute.
    pub proxy_share: Option<f64>,
    /// Raster backend under the hull's scissor ([`HullProxy::Scissor`]): the share of
    /// the frame's pixels that the slices' scissors leave, averaged over the slices
    /// that have polygons; `None` otherwise.
    pub scissor_share: Option<f64>,
    /// Compute backend with per-slice state: the slice and the state updates ran in one
    /// dispatch per slice ([`Renderer::set_fused_slices`]).
    pub fused_slices: bool,
    /// Per-slice state: the share of the (slice, tile) pairs left out of the slices'
    /// dispatches ([`Renderer::set_slice_exit`]); `None` where no dispatch lists its
    /// tiles.
    pub idle_tiles: Option<f64>,
    /// Compute backend without per-slice state: the dispatches its whole-frame march
    /// took (1 on a GPU; on a CPU device more where its loop limiter needs them,
    /// [`march_parts`]); 0 otherwise.
    pub march_parts: u32,
    /// On a CPU device: the invocations (pixels; a SIMD vector's 8 run out together)
    /// whose loops ran out of llvmpipe's loop iterations in the frame returned, so
    /// that their rays may be cut short ([`march_parts`]; [`Renderer::render`] renders again in smaller parts
    /// first, so this stays 0 unless a single sample needs more than the limit).
    pub loop_limited: u32,
    /// Raster backend: the slices each proxy polygon stood for
    /// ([`Renderer::set_raster_group`]; 1 where the frame drew a polygon per slice);
    /// 0 for compute.
    pub raster_group: u32,
}

impl FrameStats {
    /// How many pre-passes this frame ran.
    pub fn prepasses_run(&self) -> usize {
        self.prepasses.len()
    }
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct FrameUniform {
    view_proj: [f32; 16],
    ray_basis: [f32; 16],
    eye: [f32; 4],
    forward: [f32; 4],
    box_min: [f32; 4],
    box_max: [f32; 4],
    viewport: [f32; 4],
    volume_dims: [f32; 4],
    value_range: [f32; 4],
    counts: [u32; 4],
    settings: [f32; 4],
    own_min: [f32; 4],
    own_max: [f32; 4],
    slicing: [f32; 4],
    light: [f32; 4],
    state_rays: [f32; 16],
    inv_extent: [f32; 4],
    hull: [[f32; 4]; 5],
    spread: [u32; 4],
    bricks: [u32; 4],
}

const SLICE_INFO_STRIDE: u64 = 256;

/// How the raster backend fits its proxy polygons to the occupied bricks' hull, a
/// polytope of 26 faces around the bricks that can be visible
/// ([`crate::slicing::Dop`], widened by [`HULL_MARGIN`] voxels), beyond the visible
/// box (their bounding box) that the polygons always stop at. Needs empty-space
/// skipping; the occupied cells ([`Renderer::set_occupied_proxy`]) take precedence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HullProxy {
    /// The visible box's polygons as they are.
    Off,
    /// Each slice's polygon drawn under a scissor to the bounds of its part inside the
    /// hull: the same fragments are shaded the same way, so the image is the same bit
    /// for bit; only pixels that no visible sample can reach are left out.
    #[default]
    Scissor,
    /// The polygons cut to the hull: no fragment outside it, but the positions are
    /// interpolated over other triangles, so the image moves by their rounding
    /// ([`crate::preset::RenderSection::hull_cut`]).
    Cut,
}

impl HullProxy {
    /// `VWB_HULL_PROXY` (`off`, `scissor`, `cut`; a benchmark switch) or the default.
    pub fn from_env() -> Self {
        match std::env::var("VWB_HULL_PROXY").as_deref().map(str::trim) {
            Ok("off") | Ok("0") => Self::Off,
            Ok("cut") => Self::Cut,
            _ => Self::Scissor,
        }
    }
}

/// Whether the compute backend cuts its rays to the occupied bricks' hull (with
/// empty-space skipping; ten slab tests per ray against the hull's diagonal directions,
/// `hull_slabs` in shaders/slice.wgsl, its axis slabs being the visible box the rays
/// already stop at). Every sample it leaves out lies in an empty brick, so the image is
/// the same bit for bit either way.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HullRays {
    /// Rays through the visible box.
    Off,
    /// Cut where the hull holds less than [`HULL_RAYS_SHARE`] of the visible box: where
    /// it holds more, the slab tests would cut next to nothing.
    #[default]
    Auto,
    /// Cut whatever the hull's share (for tests and benchmarks).
    Always,
}

impl HullRays {
    /// `VWB_HULL_RAYS` (`off`, `auto`, `always`; a benchmark switch) or the default.
    pub fn from_env() -> Self {
        match std::env::var("VWB_HULL_RAYS").as_deref().map(str::trim) {
            Ok("off") | Ok("0") => Self::Off,
            Ok("always") => Self::Always,
            _ => Self::Auto,
        }
    }
}

/// The slices per proxy polygon the raster backend can draw ([`Renderer::set_raster_group`];
/// Rezk-Salama 2001, §9.1): powers of two, so that a group never straddles the runs
/// between the depth masks ([`raster_et::interval`], [`raster_et::skip_interval_for`]).
pub const RASTER_GROUPS: [u32; 5] = [1, 2, 4, 8, 16];
// shaders/slice.wgsl (`fragment_proxy`) writes a group's steps out for exactly these.
const _: () = assert!(
    RASTER_GROUPS[0] == 1
        && RASTER_GROUPS[1] == 2
        && RASTER_GROUPS[2] == 4
        && RASTER_GROUPS[3] == 8
        && RASTER_GROUPS[4] == 16
);

/// Logs that `n` invocations ran out of the device's loop iterations even in parts of
/// one slice ([`march_parts`]).
fn warn_loop_limited(n: u32) {
    log::warn!(
        "{n} invocations ran out of the device's loop iterations at one slice per part: their rays may be cut short (a plugin's loops exceed {} iterations a sample)",
        march_parts::LOOP_LIMIT
    );
}

/// The largest of [`RASTER_GROUPS`] not above `n` (1 for 0).
pub fn raster_group_of(n: u32) -> u32 {
    RASTER_GROUPS
        .iter()
        .copied()
        .filter(|&g| g <= n.max(1))
        .max()
        .unwrap_or(1)
}

/// [`Renderer::set_raster_group`]'s value that lets each frame choose: 1 slice per
/// polygon without early termination (the images the presets were made with),
/// [`RASTER_GROUP_WITH_TERMINATION`] with it.
pub const RASTER_GROUP_AUTO: u32 = 0;

/// The slices per proxy polygon of a raster frame with early termination when the
/// group is [`RASTER_GROUP_AUTO`] (the default). Termination is an option, off in
/// every shipped preset, so no preset's image moves. docs/perf.md, "Eight slices per
/// polygon where rays stop", measures it: with termination 0.99, 8 per polygon costs
/// 0.63–0.75× a polygon per slice and brings raster within 1.01–1.17× of compute
/// (1.49–1.87× per slice in the same run; with its skipping masks every 32 slices,
/// `raster_et::RASTER_SKIP_INTERVAL_GROUPED`), its images 0.34–0.53 levels RMS from
/// the polygon per slice's and closer to the CPU twins (0.09–0.14 ΔE*uv RMS against
/// 0.23–0.56).
pub const RASTER_GROUP_WITH_TERMINATION: u32 = 8;

/// Whether `n` is a group setting a document or a command may ask for:
/// [`RASTER_GROUP_AUTO`] or one of [`RASTER_GROUPS`].
pub fn is_raster_group_setting(n: u32) -> bool {
    n == RASTER_GROUP_AUTO || RASTER_GROUPS.contains(&n)
}

/// The group setting that `n` stands for: [`RASTER_GROUP_AUTO`] as itself, any other
/// value rounded down to one of [`RASTER_GROUPS`] ([`raster_group_of`]).
fn raster_group_setting(n: u32) -> u32 {
    match n {
        RASTER_GROUP_AUTO => RASTER_GROUP_AUTO,
        n => raster_group_of(n),
    }
}

/// `VWB_RASTER_GROUP` (a benchmark switch: 1, 2, 4, 8 or 16) or [`RASTER_GROUP_AUTO`].
pub fn raster_group_from_env() -> u32 {
    raster_group_setting(env_count("VWB_RASTER_GROUP", RASTER_GROUP_AUTO))
}

/// The slices per polygon a raster frame asks for under the group setting `n`
/// ([`Renderer::set_raster_group`]) and its early termination.
pub fn raster_group_for(n: u32, early_termination: Option<f32>) -> u32 {
    match n {
        RASTER_GROUP_AUTO if early_termination.is_some() => RASTER_GROUP_WITH_TERMINATION,
        RASTER_GROUP_AUTO => 1,
        n => n,
    }
}

/// [`HullRays::Auto`] cuts the compute backend's rays to the occupied bricks' hull where
/// it holds less than this share of the visible box (the heads and the demo 0.72–0.77,
/// the nuclei 0.99, the ocean 1.0; docs/perf.md, "The compute backend's rays cut to the
/// hull": cutting where the hull holds 0.99–1.0 cost 1.02–1.04×).
pub const HULL_RAYS_SHARE: f32 = 0.9;

/// The compute backend's own box where nothing can be visible: a point far outside the
/// volume's box (whose longest side is 1), so that every ray's interval through it is
/// empty and the march takes no sample; a sample it could still take would lie in an
/// empty brick and add nothing.
fn nowhere(voxel: f32) -> VolumeBox {
    let far = glam::Vec3::splat(1.0e6);
    VolumeBox {
        min: far,
        max: far,
        voxel,
    }
}

/// What empty-space skipping knows of the stack a frame draws: its occupancy grid, and
/// the occupied bricks' hull with the hull's share of the visible box
/// ([`Renderer::hull_of`]).
#[derive(Clone, Copy)]
struct Occupied<'a> {
    bytes: &'a [u8],
    hull: Option<(&'a crate::slicing::Dop, f32)>,
}

/// The hull's ten diagonal slabs as the frame uniform holds them (`Frame.hull` in
/// shaders/common.wgsl): [least, greatest] of direction 2m, then of 2m + 1.
fn hull_uniform(hull: &crate::slicing::Dop) -> [[f32; 4]; 5] {
    let d = &hull.range[3..];
    std::array::from_fn(|m| [d[2 * m][0], d[2 * m][1], d[2 * m + 1][0], d[2 * m + 1][1]])
}

/// Cells per axis of the grid over the visible box on which the hull's share is
/// estimated ([`crate::slicing::Dop::share_of`]).
const HULL_SHARE_GRID: u32 = 16;

/// Margin of the occupied bricks' hull ([`Renderer::set_hull_proxy`]) in voxels: wider
/// than [`HULL_SLIVER`], so that dropping slivers never uncovers an occupied brick.
pub const HULL_MARGIN: f32 = 0.5;

/// The hull proxy's polygons lose vertices within this many voxels of the line through
/// their neighbours ([`crate::slicing::drop_slivers`]).
pub const HULL_SLIVER: f32 = 0.1;

/// Grid in pixels that the hull's scissor rects are widened to, so that neighbouring
/// slices share one rect and one draw (each draw costs llvmpipe its set-up: a draw per
/// slice made a frame that no rect narrows 1.07–1.12× slower).
pub const HULL_SCISSOR_GRID: u32 = 32;

/// A rect [x, y, w, h] widened to [`HULL_SCISSOR_GRID`] within a `size` frame (an
/// empty one stays empty).
fn coarse_rect([x, y, w, h]: [u32; 4], size: [u32; 2]) -> [u32; 4] {
    if w == 0 || h == 0 {
        return [0, 0, 0, 0];
    }
    let g = HULL_SCISSOR_GRID;
    let (x0, y0) = (x / g * g, y / g * g);
    let x1 = (x + w).div_ceil(g).saturating_mul(g).min(size[0]);
    let y1 = (y + h).div_ceil(g).saturating_mul(g).min(size[1]);
    [x0, y0, x1 - x0, y1 - y0]
}

/// A colour target of `format` that blends [`UNDER`].
fn under_target(format: TargetFormat) -> wgpu::ColorTargetState {
    blend_target(format, UNDER)
}

/// A colour target of `format` that blends colour and alpha by `blend`.
fn blend_target(format: TargetFormat, blend: wgpu::BlendComponent) -> wgpu::ColorTargetState {
    wgpu::ColorTargetState {
        format: format.wgpu(),
        blend: Some(wgpu::BlendState {
            color: blend,
            alpha: blend,
        }),
        write_mask: wgpu::ColorWrites::ALL,
    }
}

/// The raster slice pipeline with a fragment entry point (`fs_main`: the proxy's
/// interpolated position; `fs_exact`: the pixel's ray–plane point) and a depth test.
fn raster_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
    target: TargetFormat,
    (fragment, group, frame_from_vertex): (&str, u32, bool),
    depth_stencil: Option<wgpu::DepthStencilState>,
    blend: wgpu::BlendComponent,
) -> wgpu::RenderPipeline {
    // the slices per proxy polygon (`RASTER_GROUP` in shaders/slice.wgsl) and the
    // fragments' frame from their vertices (`FRAME_FROM_VERTEX`); the module's defaults
    // where 1 and off, so that the default pipeline is the module as written
    let mut constants: Vec<(&str, f64)> = Vec::new();
    if group > 1 {
        constants.push(("RASTER_GROUP", group as f64));
    }
    if frame_from_vertex {
        constants.push(("FRAME_FROM_VERTEX", 1.0));
    }
    let options = || wgpu::PipelineCompilationOptions {
        constants: &constants,
        ..Default::default()
    };
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("vwb raster slices"),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            compilation_options: options(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: 16,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &[
                    wgpu::VertexAttribute {
                        format: wgpu::VertexFormat::Float32x3,
                        offset: 0,
                        shader_location: 0,
                    },
                    wgpu::VertexAttribute {
                        format: wgpu::VertexFormat::Uint32,
                        offset: 12,
                        shader_location: 1,
                    },
                ],
            })],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fragment),
            compilation_options: options(),
            targets: &[Some(blend_target(target, blend))],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// The index of a raster pipeline in [`CompiledStack`]'s cache: by (early termination,
/// exact position, "over"), the index `g` of its slices per polygon in
/// [`RASTER_GROUPS`] and the frame from the vertices.
fn raster_index((et, exact, over): (bool, bool, bool), g: usize, frame_from_vertex: bool) -> usize {
    et as usize
        + 2 * exact as usize
        + 4 * over as usize
        + 8 * g
        + 8 * RASTER_GROUPS.len() * frame_from_vertex as usize
}

/// A full-screen pass (one triangle from `entries.0`, no vertex buffers, group 0 of
/// `layout_entries`): the bricks' compositing.
fn fullscreen_pipeline(
    device: &wgpu::Device,
    label: &str,
    wgsl: &str,
    layout_entries: &[wgpu::BindGroupLayoutEntry],
    entries: (&str, &str),
    targets: &[Option<wgpu::ColorTargetState>],
    depth_stencil: Option<wgpu::DepthStencilState>,
) -> (wgpu::RenderPipeline, wgpu::BindGroupLayout) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(wgsl.into()),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: layout_entries,
    });
    let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = fullscreen_render_pipeline(
        device,
        label,
        (&module, &pl),
        entries,
        targets,
        depth_stencil,
        &[],
    );
    (pipeline, layout)
}

/// The render pipeline of a full-screen pass of `module` and `layout` (no vertex
/// buffers; `entries` the vertex and fragment entry points, both compiled with the
/// pipeline constants `constants`).
fn fullscreen_render_pipeline(
    device: &wgpu::Device,
    label: &str,
    (module, layout): (&wgpu::ShaderModule, &wgpu::PipelineLayout),
    entries: (&str, &str),
    targets: &[Option<wgpu::ColorTargetState>],
    depth_stencil: Option<wgpu::DepthStencilState>,
    constants: &[(&str, f64)],
) -> wgpu::RenderPipeline {
    let options = || wgpu::PipelineCompilationOptions {
        constants,
        ..Default::default()
    };
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(entries.0),
            compilation_options: options(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(entries.1),
            compilation_options: options(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Whether the benchmark switch `name` is on: unless it is set to `0` (the defaults of
/// [`Renderer::set_fused_slices`], `VWB_FUSED_SLICES=0` restoring a dispatch per slice
/// and per update, [`Renderer::set_state_tracking`], `VWB_STATE_TRACKING`, and
/// [`Renderer::set_slice_exit`], `VWB_SLICE_EXIT`).
fn env_on(name: &str) -> bool {
    std::env::var(name).map_or(true, |v| v.trim() != "0")
}

/// A count (≥ 1) from the environment variable `name`, else `default`: the benchmark
/// overrides of tuned constants (`VWB_RASTER_ET_INTERVAL`, `VWB_RASTER_PROXY_CELL`,
/// `VWB_SKIP_BRICK`).
pub(crate) fn env_count(name: &str, default: u32) -> u32 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.trim().parse::<u32>().ok())
        .filter(|&n| n >= 1)
        .unwrap_or(default)
}

/// An unfilterable float 2D texture read by a fragment shader (an eye buffer).
fn eye_texture_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// Front-to-back "under" blending of premultiplied colour: src·(1 − dst.a) + dst. The
/// slices blend into the eye buffer with it, and the bricks' partial images into the
/// frame.
const UNDER: wgpu::BlendComponent = wgpu::BlendComponent {
    src_factor: wgpu::BlendFactor::OneMinusDstAlpha,
    dst_factor: wgpu::BlendFactor::One,
    operation: wgpu::BlendOperation::Add,
};
/// Back-to-front "over" blending of premultiplied colour: C = c + (1 − a)·C.
const OVER: wgpu::BlendComponent = wgpu::BlendComponent {
    src_factor: wgpu::BlendFactor::One,
    dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
    operation: wgpu::BlendOperation::Add,
};
/// The display pass (`shaders/display.wgsl`).
pub const DISPLAY_WGSL: &str = include_str!("../../shaders/display.wgsl");
/// The sort-last compositing pass of a split volume (`shaders/composite.wgsl`).
pub const COMPOSITE_WGSL: &str = include_str!("../../shaders/composite.wgsl");
/// Most slices a frame with per-slice passes may have.
pub const MAX_PER_SLICE_SLICES: u32 = 65_536;
const MAX_TIMESTAMPS: u32 = 64;

/// One frame encoded by [`Renderer::record`], not yet booked.
struct Recorded {
    /// When encoding started (after the uniforms and polygons were written).
    start: Instant,
    /// Instances whose pre-pass ran.
    done: Vec<u64>,
    /// Labels of the timestamps written (none unless timed).
    ts_labels: Vec<String>,
    stats: FrameStats,
}

/// A volume pass's record: the parameters and upstream hash it last started with
/// (None: never), and its refinement steps done since.
#[derive(Default)]
struct PassState {
    stamp: Option<(ParamValues, u64)>,
    steps_done: u32,
}

/// A volume pass's bind groups 1 and 3, and a sweep pass's geometry and uniform.
type PassGroups = (
    wgpu::BindGroup,
    wgpu::BindGroup,
    Option<(crate::sweep::Sweep, wgpu::Buffer)>,
);

/// One dispatch of a volume pass in a frame's plan.
struct PassDispatch {
    /// Index into `CompiledStack::volume_passes`.
    pass: usize,
    step: u32,
}

struct InstanceGpu {
    plugin_id: &'static str,
    uniform: wgpu::Buffer,
    uniform_size: u64,
    resources: Vec<GpuResource>,
    params: ParamValues,
    prepass_target: Option<(wgpu::Texture, wgpu::TextureView)>,
    /// Parameters the last pre-pass ran with (None: never ran).
    prepass_done: Option<ParamValues>,
    /// Targets of its volume passes, in declaration order.
    pass_targets: Vec<(wgpu::Texture, wgpu::TextureView)>,
    /// What each volume pass last ran with, and how many refinement steps it has done.
    pass_state: Vec<PassState>,
    /// Hash of the structural parameters the resources were made for.
    structure: u64,
    /// The volumes its inputs resolved to when the resources were made.
    inputs: crate::inputs::InputStamp,
    /// Slice spacing (voxels) the resources were last updated for, for plugins that
    /// use it.
    spacing: f32,
    state: Option<[(wgpu::Texture, wgpu::TextureView); 2]>,
    /// The marks of the state's tiles that left `clear`, where the plugin tracks them
    /// ([`crate::plugin::SliceStateDecl::track_clear`]); made with `state`.
    state_tiles: Option<wgpu::Buffer>,
}

impl InstanceGpu {
    /// Bytes of its uniforms, resources, pre-pass target and per-slice state.
    fn bytes(&self) -> u64 {
        let tex = |t: &wgpu::Texture| {
            let s = t.size();
            s.width as u64
                * s.height as u64
                * s.depth_or_array_layers as u64
                * t.format().block_copy_size(None).unwrap_or(4) as u64
        };
        self.uniform_size
            + self.resources.iter().map(GpuResource::bytes).sum::<u64>()
            + self.prepass_target.as_ref().map_or(0, |(t, _)| tex(t))
            + self.pass_targets.iter().map(|(t, _)| tex(t)).sum::<u64>()
            + self
                .state
                .as_ref()
                .map_or(0, |s| s.iter().map(|(t, _)| tex(t)).sum())
    }
}

/// The stack in use: its compiled pipelines (shared through the compiled-stack cache)
/// and the instances they draw.
struct Pipelines {
    compiled: Arc<CompiledStack>,
    /// (uid, plugin) of the enabled instances, in stack order.
    stack: Vec<(u64, Arc<dyn Plugin>)>,
    key: StructureKey,
}

impl Pipelines {
    /// The uids of the instances, in stack order.
    fn uids(&self) -> Vec<u64> {
        self.stack.iter().map(|(uid, _)| *uid).collect()
    }
}

impl std::ops::Deref for Pipelines {
    type Target = CompiledStack;
    fn deref(&self) -> &CompiledStack {
        &self.compiled
    }
}

/// An immutable compiled stack: the composition, its layouts and pipelines. It depends
/// only on the stack's structure ([`structure_hash`]), not on which instances or
/// parameter values use it, so the renderer keeps the recent ones
/// ([`COMPILED_CACHE_SIZE`]) and toggling a plugin, an ablation or a duplicated
/// instance does not compile again.
struct CompiledStack {
    composition: Composition,
    g1_layout: wgpu::BindGroupLayout,
    g2_layout: wgpu::BindGroupLayout,
    g3_layout: wgpu::BindGroupLayout,
    /// Where an instance defines `post`: the raster backend's full-screen pass after
    /// the slices (`fs_post`) and its group 3 (`post_src`, a copy of the eye buffer).
    post: Option<(wgpu::RenderPipeline, wgpu::BindGroupLayout)>,
    /// The raster pipelines by (early-termination depth test, fragment at the exact
    /// ray–plane point, back-to-front "over" blending for the pixels of half-angle
    /// frames that meet the slices from behind), index `et + 2·exact + 4·over`: the
    /// plain one built with the stack (so that the device validates it), the others on
    /// first use.
    /// By early termination, exact position, order, slices per proxy polygon and
    /// whether the fragments take the frame from their vertices
    /// ([`CompiledStack::raster_for`]).
    raster: [std::sync::OnceLock<wgpu::RenderPipeline>; 16 * RASTER_GROUPS.len()],
    /// The raster backend's chunk bits for empty-space skipping (`fs_raster_chunks`,
    /// [`raster_et`]), built on first use.
    /// (by the frame from the vertices, [`Renderer::set_frame_from_vertex`])
    raster_chunks: [std::sync::OnceLock<wgpu::RenderPipeline>; 2],
    module: wgpu::ShaderModule,
    raster_layout: wgpu::PipelineLayout,
    compute_layout: wgpu::PipelineLayout,
    /// `cs_main_raw` ([`Renderer::set_raw_samples`]), built on first use.
    cs_main_raw: std::sync::OnceLock<wgpu::ComputePipeline>,
    /// Reads of the shading scalar per sample in the main module
    /// ([`march_parts::scalar_reads`]).
    scalar_reads: u32,
    target: TargetFormat,
    cs_main: wgpu::ComputePipeline,
    /// `cs_main` with empty-space skipping.
    cs_main_skip: wgpu::ComputePipeline,
    cs_slice: wgpu::ComputePipeline,
    /// The slice and every state update in one dispatch (with per-slice state).
    cs_slice_fused: Option<wgpu::ComputePipeline>,
    /// The state updates alone, of a transparent slice ([`slice_exit`]); with
    /// `cs_slice_fused`.
    cs_slice_state_only: Option<wgpu::ComputePipeline>,
    cs_resolve: wgpu::ComputePipeline,
    /// (instance index, pipeline) per state update.
    updates: Vec<(usize, wgpu::ComputePipeline)>,
    /// (instance index, pipeline, group-1 layout) per pre-pass.
    prepasses: Vec<(usize, wgpu::ComputePipeline, wgpu::BindGroupLayout)>,
    /// Volume passes in stack order, each instance's in declaration order.
    volume_passes: Vec<CompiledPass>,
}

impl CompiledStack {
    /// The raster pipeline for early termination (depth test), the exact fragment
    /// position (proxy cut to the occupied cells), the order ("over"), the slices
    /// per proxy polygon (one of [`RASTER_GROUPS`]) and the frame from the vertices
    /// ([`Renderer::set_frame_from_vertex`]).
    fn raster_for(
        &self,
        device: &wgpu::Device,
        (et, exact, over): (bool, bool, bool),
        group: u32,
        frame_from_vertex: bool,
    ) -> &wgpu::RenderPipeline {
        let g = RASTER_GROUPS.iter().position(|&n| n == group).unwrap_or(0);
        let i = raster_index((et, exact, over), g, frame_from_vertex);
        self.raster[i].get_or_init(|| {
            let entry = match (exact, over) {
                (false, false) => "fs_main",
                (true, false) => "fs_exact",
                (false, true) => "fs_main_behind",
                (true, true) => "fs_exact_behind",
            };
            raster_pipeline(
                device,
                &self.module,
                &self.raster_layout,
                self.target,
                (entry, RASTER_GROUPS[g], frame_from_vertex),
                et.then(raster_et::slice_depth_state),
                if over { OVER } else { UNDER },
            )
        })
    }

    /// The raster backend's chunk-bits pipeline, built on first use.
    fn chunks_pipeline(
        &self,
        device: &wgpu::Device,
        frame_from_vertex: bool,
    ) -> &wgpu::RenderPipeline {
        self.raster_chunks[frame_from_vertex as usize].get_or_init(|| {
            raster_et::chunks_pipeline(device, &self.module, &self.raster_layout, frame_from_vertex)
        })
    }

    /// `cs_main_raw`, built on first use.
    fn raw_pipeline(&self, device: &wgpu::Device) -> &wgpu::ComputePipeline {
        self.cs_main_raw
            .get_or_init(|| self.main_pipeline(device, "cs_main_raw"))
    }

    /// The whole-frame march: `cs_main_skip` with empty-space skipping, else `cs_main`.
    fn march_pipeline(&self, skipping: bool) -> &wgpu::ComputePipeline {
        if skipping {
            &self.cs_main_skip
        } else {
            &self.cs_main
        }
    }

    fn main_pipeline(&self, device: &wgpu::Device, entry: &str) -> wgpu::ComputePipeline {
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: Some(&self.compute_layout),
            module: &self.module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
    }
}

struct CompiledPass {
    /// Index of the instance in the stack and of the pass in its declarations.
    instance: usize,
    k: usize,
    pipeline: wgpu::ComputePipeline,
    /// Group 3: the storage view of its target (and a sweep's `SweepInfo`).
    layout: wgpu::BindGroupLayout,
    binding: u32,
    /// A sweep pass: the binding of its `SweepInfo` uniform.
    sweep_binding: Option<u32>,
}

/// The smallest scissor [x, y, w, h] holding all of `rects` (none without rects).
fn rect_union(rects: impl IntoIterator<Item = [u32; 4]>) -> Option<[u32; 4]> {
    rects
        .into_iter()
        .map(|[x, y, w, h]| [x, y, x + w, y + h])
        .reduce(|a, b| {
            [
                a[0].min(b[0]),
                a[1].min(b[1]),
                a[2].max(b[2]),
                a[3].max(b[3]),
            ]
        })
        .map(|[x0, y0, x1, y1]| [x0, y0, x1 - x0, y1 - y0])
}

/// The pixels [x0, y0, x1, y1) of a `size` frame that the box `b` can cover: its
/// projected corners with one pixel of margin, the whole frame when a corner lies
/// behind the eye.
fn box_footprint(b: &VolumeBox, view: &crate::camera::View, size: [u32; 2]) -> [u32; 4] {
    let [x, y, w, h] = crate::slicing::screen_rect(&b.corners(), view.view_proj(), size);
    [x, y, x + w, y + h]
}

/// `frame.ray_basis` (shaders/common.wgsl), in f64 and then rounded: columns 0 and 1
/// step one NDC unit right and up (at unit depth for perspective), column 2 is the view
/// direction (perspective: the direction at the centre), column 3 the eye.
fn ray_basis(view: &crate::camera::View) -> Mat4 {
    let inv = view.view.as_dmat4().inverse();
    let p = view.proj.as_dmat4();
    let (sx, sy) = (1.0 / p.x_axis.x, 1.0 / p.y_axis.y);
    let forward = -inv.z_axis;
    glam::DMat4::from_cols(inv.x_axis * sx, inv.y_axis * sy, forward, inv.w_axis).as_mat4()
}

/// A hash of an instance's structural parameter values: what, beside its id, decides
/// its code, resources and passes.
/// Whether any of `keys` has another value in `now` than in `done`.
fn params_changed(keys: &[&str], done: &ParamValues, now: &ParamValues) -> bool {
    keys.iter().any(|k| done.get(k) != now.get(k))
}

/// Whether a volume pass must (re)start: it never ran, the stack upstream of it
/// changed, or one of its `depends_on` parameters did.
fn pass_stale(
    st: &PassState,
    decl: &crate::plugin::VolumePassDecl,
    params: &ParamValues,
    upstream: u64,
) -> bool {
    match &st.stamp {
        None => true,
        Some((done, hash)) => *hash != upstream || params_changed(&decl.depends_on, done, params),
    }
}

/// What a view pass depends on: the view and projection matrices and the eye, by
/// their bits.
fn camera_key(view: &crate::camera::View) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for x in view.view_proj().to_cols_array() {
        x.to_bits().hash(&mut h);
    }
    view.eye.to_array().map(f32::to_bits).hash(&mut h);
    h.finish()
}

/// The sweep of a sweep pass ([`crate::plugin::SweepDecl`]) over its `target` under
/// `params`: the texel's world size is the volume's box over the target's size.
fn sweep_of(
    volume: &Volume,
    decl: &crate::plugin::VolumePassDecl,
    params: &ParamValues,
    target: &wgpu::Texture,
) -> crate::sweep::Sweep {
    let size = target.size();
    let dims = [size.width, size.height, size.depth_or_array_layers];
    let vbox = crate::slicing::VolumeBox::new(volume.dims, volume.spacing);
    let texel = (vbox.max - vbox.min).as_dvec3() / glam::DVec3::from(dims.map(f64::from));
    let (direction, boundary) = decl.sweep.as_ref().map_or(([0.0, 0.0, 1.0], 1.0), |s| {
        ((s.direction)(params), s.boundary)
    });
    crate::sweep::Sweep::new(
        glam::Vec3::from(direction).as_dvec3(),
        dims,
        texel,
        boundary as f64,
    )
}

/// Refinement steps of a volume pass under `params` (at least 1).
fn pass_steps(decl: &crate::plugin::VolumePassDecl, params: &ParamValues) -> u32 {
    decl.steps.as_ref().map_or(1, |steps| {
        steps.count(params).clamp(1, MAX_PER_SLICE_SLICES)
    })
}

fn structure_of(inst: &PluginInstance) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    // the code and the parameter layout: a plugin reloaded from its files (a user
    // plugin) keeps its id but may change both
    let shader = inst.plugin.shader();
    shader.file.hash(&mut h);
    shader.source.hash(&mut h);
    let specs = inst.plugin.params();
    for spec in &specs {
        spec.key.hash(&mut h);
        spec.kind_name().hash(&mut h);
    }
    for spec in specs.iter().filter(|s| s.structural) {
        spec.key.hash(&mut h);
        match inst.params.get(spec.key) {
            None => 0u8.hash(&mut h),
            Some(v) => v.hash_into(&mut h),
        }
    }
    h.finish()
}

/// The hash that keys a compiled stack: the enabled plugins' ids, code, parameter
/// layout and structural values in stack order, the eye-buffer format and the shader
/// overrides.
fn structure_hash(
    entries: &[(u64, &'static str, u64)],
    target: TargetFormat,
    overrides: &std::collections::BTreeMap<String, String>,
) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for (_, id, structure) in entries {
        id.hash(&mut h);
        structure.hash(&mut h);
    }
    target.wgsl().hash(&mut h);
    overrides.hash(&mut h);
    h.finish()
}

/// How many compiled stacks the renderer keeps.
pub const COMPILED_CACHE_SIZE: usize = 32;

#[derive(Debug, Clone, PartialEq)]
struct StructureKey {
    /// (uid, id, structural hash) of the enabled instances, in stack order.
    entries: Vec<(u64, &'static str, u64)>,
    target: TargetFormat,
    /// Changes whenever a shader override is set or cleared.
    overrides: u64,
}

/// Work the renderer has done since it was made, for tests and benchmarks that check
/// it does only what changed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RenderCounters {
    /// Stacks composed and compiled into pipelines.
    pub compiles: u64,
    /// Stack changes served from the compiled-stack cache.
    pub compile_cache_hits: u64,
    /// Volume uploads to the GPU.
    pub volume_uploads: u64,
    /// Plugin instances whose GPU resources were created.
    pub instance_creations: u64,
    /// Pre-pass runs.
    pub prepass_runs: u64,
    /// Volume-pass dispatches (one per refinement step).
    pub volume_pass_runs: u64,
}

#[derive(Clone)]
struct Target {
    width: u32,
    height: u32,
    format: TargetFormat,
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    accum: wgpu::Buffer,
    display: wgpu::Texture,
    display_view: wgpu::TextureView,
}

impl Target {
    /// Eye buffer, accumulation buffer and display texture.
    fn bytes(&self) -> u64 {
        target_bytes(self.width, self.height, self.format)
    }
}

fn target_bytes(w: u32, h: u32, format: TargetFormat) -> u64 {
    let texel = match format {
        TargetFormat::Rgba16Float => 8,
        TargetFormat::Rgba32Float => 16,
    };
    u64::from(w) * u64::from(h) * (texel + 16 + 4)
}

/// Bytes of `volume` stored as `format` ([`upload_volume`]).
fn volume_texture_bytes(format: wgpu::TextureFormat, volume: &Volume) -> u64 {
    dims_texture_bytes(format, volume.dims)
}

/// Bytes of a volume of `dims` voxels stored as `format`.
fn dims_texture_bytes(format: wgpu::TextureFormat, dims: [u32; 3]) -> u64 {
    dims.iter().map(|&d| u64::from(d)).product::<u64>() * texel_bytes(format)
}

/// Bytes of one voxel of the volume texture.
fn texel_bytes(format: wgpu::TextureFormat) -> u64 {
    u64::from(format.block_copy_size(None).unwrap_or(4))
}

/// How the tables a classification reads at every sample (transfer functions,
/// pre-integration and label tables: [`crate::plugin::GpuInit::create_sample_table`])
/// are stored on the GPU (the preset's `render.table_format`, `--table-format`).
/// `auto` is rgba16float on GPUs, where the filtered read of a 128-bit texel is what
/// plain DVR waits on, and rgba32float on CPU devices (docs/perf.md, "Classification
/// tables in 16-bit floats on GPUs"); `rgba32float` keeps a GPU's images those of
/// 32-bit tables (they move by rounding, at most 0.14 levels RMS on the shipped
/// presets), `rgba16float` gives a CPU device the GPU's tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum TableFormat {
    #[default]
    Auto,
    Rgba32Float,
    Rgba16Float,
}

impl TableFormat {
    pub const ALL: [TableFormat; 3] = [
        TableFormat::Auto,
        TableFormat::Rgba32Float,
        TableFormat::Rgba16Float,
    ];

    pub fn name(self) -> &'static str {
        match self {
            TableFormat::Auto => "auto",
            TableFormat::Rgba32Float => "rgba32float",
            TableFormat::Rgba16Float => "rgba16float",
        }
    }

    pub fn parse(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| format!("unknown table format '{s}' (auto, rgba32float or rgba16float)"))
    }

    pub fn is_auto(&self) -> bool {
        *self == TableFormat::Auto
    }
}

/// How the normalised scalar volume is stored on the GPU (the preset's
/// `render.volume_format`, `--volume-format`). Every format is filtered by the
/// sampler; they differ in bytes per voxel and in what sampling costs on an adapter
/// (issue 23, item 4: docs/perf.md measures them). The CPU twins read the f64 values:
/// r32float is the exact one, r16unorm keeps 1/65535 steps (within half a data step of
/// 16-bit data), r16float keeps 11 significant bits, r8unorm 1/255 steps (an 8-bit
/// volume's own resolution; a quarter of r32float's bytes). `r32float_pairs` holds
/// r32float's values in another layout (`VolumeLayout::ZPairs`: each voxel beside its
/// +z neighbour in an rg32float 2D array, twice the bytes), in which a trilinear read
/// is one bilinear fetch and a mix: 0.71–0.73× the sampler's time per read on lavapipe,
/// the same values up to f32 rounding (docs/perf.md, "Sample fetch").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum VolumeFormat {
    /// On CPU devices r32float_pairs where the pair texture fits (1 GiB, the budget and
    /// the adapter's array layers), else r32float where the adapter filters it, else
    /// r16float.
    #[default]
    Auto,
    R32Float,
    R32FloatPairs,
    R16Float,
    R16Unorm,
    R8Unorm,
}

/// The largest pair texture `auto` stores (a CPU device's memory is the host's).
const PAIRS_AUTO_MAX_BYTES: u64 = 1 << 30;

impl VolumeFormat {
    pub const ALL: [VolumeFormat; 6] = [
        VolumeFormat::Auto,
        VolumeFormat::R32Float,
        VolumeFormat::R32FloatPairs,
        VolumeFormat::R16Float,
        VolumeFormat::R16Unorm,
        VolumeFormat::R8Unorm,
    ];

    pub fn name(self) -> &'static str {
        match self {
            VolumeFormat::Auto => "auto",
            VolumeFormat::R32Float => "r32float",
            VolumeFormat::R32FloatPairs => "r32float_pairs",
            VolumeFormat::R16Float => "r16float",
            VolumeFormat::R16Unorm => "r16unorm",
            VolumeFormat::R8Unorm => "r8unorm",
        }
    }

    pub fn parse(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown volume format '{s}' (auto, r32float, r32float_pairs, r16float, r16unorm or r8unorm)"
                )
            })
    }

    pub fn is_auto(&self) -> bool {
        *self == VolumeFormat::Auto
    }

    /// What `auto` stands for on `gpu` before a volume's size is known
    /// (r32float_pairs on CPU devices and r32float on GPUs where the adapter filters
    /// 32-bit floats, else r16float); the other formats are themselves.
    pub fn concrete(self, gpu: &GpuContext) -> VolumeFormat {
        match self {
            VolumeFormat::Auto
                if gpu.float32_filterable() && gpu.info.device_type == wgpu::DeviceType::Cpu =>
            {
                VolumeFormat::R32FloatPairs
            }
            VolumeFormat::Auto if gpu.float32_filterable() => VolumeFormat::R32Float,
            VolumeFormat::Auto => VolumeFormat::R16Float,
            f => f,
        }
    }

    /// The layout of the stored volume, which its shaders read it through.
    pub fn layout(self) -> VolumeLayout {
        match self {
            VolumeFormat::R32FloatPairs => VolumeLayout::ZPairs,
            _ => VolumeLayout::Texture3d,
        }
    }

    /// The format `volume` is stored in when `self` is asked for under a GPU memory
    /// `budget`: `auto` takes a 16-bit format (r16unorm where the adapter has it, else
    /// r16float) when the volume's r32float texture would pass the budget, before a
    /// coarser level is considered: half the bytes for a few hundredths of ΔE*uv (docs/
    /// perf.md) against a level's ΔE of 5–15. A named format is kept.
    pub fn for_budget(
        self,
        gpu: &GpuContext,
        volume: &Volume,
        budget: Option<u64>,
    ) -> Result<VolumeFormat, RenderError> {
        let mut concrete = self.concrete(gpu);
        // a stored level read alone stands for its full volume
        let full = level::full_dims(volume);
        let bytes = |format: VolumeFormat| -> Result<u64, RenderError> {
            Ok(dims_texture_bytes(format.texture_format(gpu)?, full))
        };
        if concrete == VolumeFormat::R32FloatPairs {
            // the array's layers and sides (a split volume's bricks are smaller)
            let l = &gpu.limits;
            let fits = volume.dims[2] <= l.max_texture_array_layers
                && volume.dims[0].max(volume.dims[1]) <= l.max_texture_dimension_2d;
            if self.is_auto() {
                let b = bytes(concrete)?;
                if !fits || b > PAIRS_AUTO_MAX_BYTES || budget.is_some_and(|budget| b > budget) {
                    concrete = VolumeFormat::R32Float;
                }
            } else if !fits {
                return Err(RenderError::VolumeFormatUnsupported(
                    self.name(),
                    "2D array textures of the volume's size (max_texture_array_layers for its depth, max_texture_dimension_2d for its sides)",
                ));
            }
        }
        // also refuses a format the adapter cannot filter
        let stored = bytes(concrete)?;
        let over = budget.is_some_and(|b| stored > b);
        if self.is_auto() && concrete == VolumeFormat::R32Float && over {
            let unorm = VolumeFormat::R16Unorm.texture_format(gpu).is_ok();
            return Ok(if unorm {
                VolumeFormat::R16Unorm
            } else {
                VolumeFormat::R16Float
            });
        }
        Ok(concrete)
    }

    /// The texture format on `gpu`, or why the adapter cannot filter it.
    pub fn texture_format(self, gpu: &GpuContext) -> Result<wgpu::TextureFormat, RenderError> {
        let lacks = |feature| Err(RenderError::VolumeFormatUnsupported(self.name(), feature));
        match self.concrete(gpu) {
            VolumeFormat::R32Float if gpu.float32_filterable() => Ok(wgpu::TextureFormat::R32Float),
            VolumeFormat::R32FloatPairs if gpu.float32_filterable() => {
                Ok(wgpu::TextureFormat::Rg32Float)
            }
            VolumeFormat::R32Float | VolumeFormat::R32FloatPairs => lacks("FLOAT32_FILTERABLE"),
            VolumeFormat::R16Unorm
                if gpu
                    .features
                    .contains(wgpu::Features::TEXTURE_FORMAT_16BIT_NORM) =>
            {
                Ok(wgpu::TextureFormat::R16Unorm)
            }
            VolumeFormat::R16Unorm => lacks("TEXTURE_FORMAT_16BIT_NORM"),
            VolumeFormat::R8Unorm => Ok(wgpu::TextureFormat::R8Unorm),
            VolumeFormat::R16Float | VolumeFormat::Auto => Ok(wgpu::TextureFormat::R16Float),
        }
    }
}

/// Result of [`Renderer::update_stack`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StackChange {
    /// Nothing changed.
    None,
    /// Only parameters changed: uniforms (and plugin resources) were rewritten.
    Params,
    /// The pipeline was recomposed.
    Recomposed,
}

pub struct Renderer {
    gpu: GpuContext,
    /// The raster backend's copy of the eye buffer that `post` hooks read.
    post_src: Option<(wgpu::Texture, wgpu::TextureView)>,
    volume: Arc<Volume>,
    /// The document's named volumes ([`crate::inputs`]).
    inputs: crate::inputs::VolumeInputs,
    vbox: VolumeBox,
    volume_view: wgpu::TextureView,
    linear: wgpu::Sampler,
    nearest: wgpu::Sampler,
    frame_buf: wgpu::Buffer,
    slice_info: wgpu::Buffer,
    slice_info_slices: u32,
    /// The slice tile list group 0 binds where no frame lists tiles (one unused word).
    no_tile_list: wgpu::Buffer,
    g0_layout: wgpu::BindGroupLayout,
    g0: wgpu::BindGroup,
    /// Value range per brick of the volume (empty-space skipping).
    bricks: BrickRanges,
    /// Occupancy per brick for the current stack (1×1×1 "visible" when skipping is off).
    occupancy: wgpu::Buffer,
    /// The occupancy bytes uploaded, when skipping is active.
    occupancy_bytes: Option<Vec<u8>>,
    /// The stack the occupancy was made for, and the apron of the brick ranges it was
    /// made from (wider than 1 for samples its plugins move,
    /// [`crate::plugin::Transparency::Moves`]): a frame at another slice spacing makes
    /// it again when the apron changes.
    occupancy_stack: Vec<PluginInstance>,
    /// How far its plugins move samples (slice steps; [`stack_moves`]).
    occupancy_moves: f64,
    occupancy_apron: u32,
    /// The longest step between two slices along a ray of the last frame (voxels;
    /// [`crate::slicing::FramePlan::max_ray_step`]): what a move or a read ahead of one
    /// step can reach, for the apron.
    occupancy_ray_step: f32,
    /// Brick ranges with a wider apron, for stacks that move samples (by apron).
    moved_ranges: std::sync::Mutex<Option<(u32, Arc<BrickRanges>)>>,
    /// The user's switch (on by default).
    skipping_enabled: bool,
    /// WGSL replacing a plugin file's built-in source (the window's shader editor).
    shader_overrides: std::collections::BTreeMap<String, String>,
    overrides_generation: u64,
    pipelines: Option<Pipelines>,
    /// Recently compiled stacks by [`structure_hash`], oldest first.
    compiled: Vec<(u64, Arc<CompiledStack>)>,
    counters: RenderCounters,
    /// Instances created for the last atlas's tiles ([`Renderer::render_atlas`]).
    atlas_uids: std::collections::HashSet<u64>,
    instances: HashMap<u64, InstanceGpu>,
    target: Option<Target>,
    /// Bytes of the uploaded volume texture.
    volume_bytes: u64,
    /// How the volume is asked to be stored ([`RendererOptions::volume_format`]).
    volume_format: VolumeFormat,
    /// How the classification tables are stored ([`Renderer::set_table_format`]).
    table_format: TableFormat,
    /// Workgroup shape of the whole-frame compute passes (`cs_main`, `cs_main_skip`).
    main_workgroup: [u32; 2],
    /// The whole-frame march in parts on CPU devices, and the loop limiter's counter
    /// ([`march_parts`]).
    march: march_parts::MarchState,
    /// How it is stored ([`VolumeFormat::for_budget`]: never `Auto`).
    stored_format: VolumeFormat,
    /// The layout group 0 binds the volume in and the shaders read it through (the
    /// stored format's; a split volume's placeholder is a 3D texture).
    volume_layout: VolumeLayout,
    /// GPU memory the renderer may hold (`VWB_GPU_MEMORY_LIMIT` bytes, or
    /// [`Renderer::set_gpu_memory_budget`]); `None`: only the driver refuses.
    gpu_budget: Option<u64>,
    vertices: Option<(wgpu::Buffer, u64)>,
    timestamps: Option<(wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer)>,
    display_pipeline: Option<(TargetFormat, wgpu::ComputePipeline, wgpu::BindGroupLayout)>,
    /// Where `VWB_SHADER_DUMP` points, read once.
    dump_dir: Option<std::path::PathBuf>,
    /// Slice spacing (voxels) of the last frame drawn ([`GpuInit::slice_spacing`]).
    slice_spacing: f32,
    /// Most refinement steps of volume passes per frame (None: all).
    refinement_budget: Option<u32>,
    /// Bound in place of a volume pass's own target while that pass writes it.
    dummy_3d: (wgpu::Texture, wgpu::TextureView),
    /// Largest 3D texture extent; a longer axis splits the volume into bricks.
    brick_limit: u32,
    /// Most bytes of one volume texture ([`RendererOptions::max_brick_bytes`]).
    max_brick_bytes: Option<u64>,
    /// Set when the volume passed the GPU memory budget and a coarser level is shown.
    level: Option<LevelInfo>,
    /// Set when this renderer draws one brick of a split volume.
    region: Option<Region>,
    /// Set when the volume is split into bricks: this renderer then only composites
    /// the bricks' partial images (and owns no volume texture of its own).
    split: Option<Split>,
    /// Set when a volume beyond the budget refines its bricks in view ([`lod`]).
    lod: Option<lod::Lod>,
    /// The raster backend's depth mask (early termination, empty-space skipping), made
    /// on first use.
    raster_et: Option<raster_et::RasterEt>,
    /// Raster backend: skip the slices in empty bricks by the depth mask
    /// ([`Renderer::set_raster_skipping`]).
    raster_skipping: bool,
    /// Raster backend: proxy polygons cut to the occupied cells ([`Renderer::set_occupied_proxy`]).
    occupied_proxy: bool,
    /// Raster backend: slices per proxy polygon ([`Renderer::set_raster_group`]).
    raster_group: u32,
    /// Raster backend: the fragments take the frame from their vertices
    /// ([`Renderer::set_frame_from_vertex`]).
    frame_from_vertex: bool,
    /// Raster backend: proxy polygons fitted to the occupied bricks' hull
    /// ([`Renderer::set_hull_proxy`]).
    hull_proxy: HullProxy,
    /// The occupied bricks' bounding polytope (world) and its share of the visible box,
    /// made with `occupancy_bytes` ([`Renderer::hull_of`]).
    occupied_hull: Option<(crate::slicing::Dop, f32)>,
    /// Compute backend with skipping: rays cut to the hull ([`Renderer::set_hull_rays`]).
    hull_rays: HullRays,
    /// Compute backend: the slice and the state updates in one dispatch per slice where
    /// every state has the eye buffer's resolution ([`Renderer::set_fused_slices`]).
    fused_slices: bool,
    /// Per-slice state: track the tiles that still hold their clear value
    /// ([`Renderer::set_state_tracking`]).
    state_tracking: bool,
    /// Per-slice state: each slice's dispatches cover only its listed tiles
    /// ([`Renderer::set_slice_exit`]).
    slice_exit: bool,
    /// What `gradient: auto` resolved to for the last stack ([`Renderer::resolved_gradient`]).
    resolved_gradient: crate::shading::GradientEstimator,
    /// Compute backend: take the march's samples with one fetch each and nothing else
    /// ([`Renderer::set_raw_samples`]).
    raw_samples: bool,
}

fn uniform_entry(
    binding: u32,
    vis: wgpu::ShaderStages,
    dynamic: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: dynamic,
            min_binding_size: None,
        },
        count: None,
    }
}

/// `stack` with `gradient: auto` replaced by `auto` (what it resolves to).
fn with_gradient(
    stack: &[PluginInstance],
    auto: crate::shading::GradientEstimator,
) -> Vec<PluginInstance> {
    stack
        .iter()
        .map(|i| PluginInstance {
            params: crate::shading::resolve_auto(&i.params, auto),
            ..i.clone()
        })
        .collect()
}

/// The size of a per-slice state of `scale` ([`crate::plugin::SliceStateDecl::scale`])
/// for a `size` eye buffer.
fn state_extent(size: [u32; 2], scale: f32) -> [u32; 2] {
    size.map(|s| ((s as f32 * scale).round() as u32).max(1))
}

/// Whether every per-slice state (`sizes`: [`Renderer::state_sizes`]) is allocated
/// with the eye buffer's size `eye`, so that a state texel is a pixel.
fn all_eye_sized(sizes: &[Option<wgpu::Extent3d>], eye: [u32; 2]) -> bool {
    sizes
        .iter()
        .all(|st| st.is_some_and(|e| [e.width, e.height] == eye))
}

/// A storage buffer binding of compute shaders.
fn storage_buffer_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A filterable float 3D texture binding.
fn texture3d_entry(binding: u32, vis: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension: wgpu::TextureViewDimension::D3,
            multisampled: false,
        },
        count: None,
    }
}

fn sampler_entry(binding: u32, vis: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    }
}

impl Renderer {
    /// A renderer for `volume`, with the GPU memory budget of `VWB_GPU_MEMORY_LIMIT`
    /// (bytes; none when unset).
    ///
    /// A volume longer than the adapter's 3D texture limit (or `VWB_BRICK_LIMIT`) along
    /// an axis is split into bricks ([`Renderer::bricks`]).
    pub fn new(gpu: &GpuContext, volume: Arc<Volume>) -> Result<Self, RenderError> {
        Self::with_options(gpu, volume, RendererOptions::from_env())
    }

    /// A renderer for `volume` that holds at most `budget` bytes of GPU memory (see
    /// [`Renderer::set_gpu_memory_budget`]); a volume that does not fit, or that the
    /// driver cannot allocate, fails with [`RenderError::OutOfMemory`].
    pub fn with_gpu_memory_budget(
        gpu: &GpuContext,
        volume: Arc<Volume>,
        budget: Option<u64>,
    ) -> Result<Self, RenderError> {
        let options = RendererOptions {
            gpu_memory_budget: budget,
            ..RendererOptions::from_env()
        };
        Self::with_options(gpu, volume, options)
    }

    /// A renderer for `volume` built with `options` (GPU memory budget, brick limit).
    pub fn with_options(
        gpu: &GpuContext,
        volume: Arc<Volume>,
        options: RendererOptions,
    ) -> Result<Self, RenderError> {
        let device = &gpu.device;
        let budget = options.gpu_memory_budget;
        let brick_limit = options.limit(gpu);
        if volume.dims.contains(&0) {
            return Err(RenderError::VolumeTooLarge {
                name: volume.name.clone(),
                dims: volume.dims,
                limit: gpu.limits.max_texture_dimension_3d,
            });
        }
        // beyond the budget: 16-bit storage where `auto`, then a coarser level, in the
        // full volume's box and Δs0
        let vbox = level::full_box(&volume);
        let stored_format = options.volume_format.for_budget(gpu, &volume, budget)?;
        let full = volume.clone();
        let (volume, level) = match level_for(&volume, budget, stored_format.texture_format(gpu)?)?
        {
            Some((level, info)) => (level, Some(info)),
            None => (volume, None),
        };
        // a coarser level: its bricks in view can be refined, from the full volume in
        // memory (an averaged level) or from the finer stored levels (OME-Zarr)
        let texel = texel_bytes(stored_format.texture_format(gpu)?);
        let brick = options.lod_brick;
        let lod = match (&level, &full.pyramid) {
            (Some(l), _) if !options.refine_in_view || l.factor <= 1 || budget.is_none() => None,
            (Some(l), _) if l.stored.is_none() => Some(lod::Lod::in_memory(
                full,
                l.factor.trailing_zeros(),
                brick,
                brick_limit,
                texel,
            )),
            (Some(l), Some(p)) => l.stored.map(|i| {
                lod::Lod::stored(
                    p.clone(),
                    volume.clone(),
                    i as u32,
                    brick,
                    brick_limit,
                    texel,
                )
            }),
            _ => None,
        };
        let max_brick_bytes = options.max_brick_bytes;
        let volume_format = options.volume_format;
        let main_workgroup = crate::composer::main_workgroup(gpu, options.workgroup);
        let (volume_view, volume_bytes, bricks, split) = upload_or_split(
            gpu,
            &volume,
            &vbox,
            brick_limit,
            max_brick_bytes,
            budget,
            stored_format,
        )?
        .into_parts(gpu, &volume);
        let sampler = |filter| {
            device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("vwb sampler"),
                address_mode_u: wgpu::AddressMode::ClampToEdge,
                address_mode_v: wgpu::AddressMode::ClampToEdge,
                address_mode_w: wgpu::AddressMode::ClampToEdge,
                mag_filter: filter,
                min_filter: filter,
                ..Default::default()
            })
        };
        let linear = sampler(wgpu::FilterMode::Linear);
        let nearest = sampler(wgpu::FilterMode::Nearest);
        let frame_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vwb frame"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let volume_layout = bound_layout(stored_format, split.is_some());
        let g0_layout = g0_layout(device, volume_layout);
        let no_tile_list = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vwb slice tiles (none)"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let slice_info = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vwb slice info"),
            size: SLICE_INFO_STRIDE,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let occupancy = upload_occupancy(gpu, [1, 1, 1], &[255]);
        let g0 = make_g0(
            device,
            &g0_layout,
            &frame_buf,
            &volume_view,
            &linear,
            &nearest,
            [&slice_info, &no_tile_list],
            &occupancy,
        );
        let mut r = Self {
            gpu: gpu.clone(),
            post_src: None,
            volume,
            inputs: Default::default(),
            vbox,
            volume_view,
            linear,
            nearest,
            frame_buf,
            slice_info,
            no_tile_list,
            slice_info_slices: 1,
            g0,
            g0_layout,
            volume_layout,
            bricks,
            occupancy,
            occupancy_bytes: None,
            occupancy_stack: Vec::new(),
            occupancy_moves: 0.0,
            occupancy_apron: 1,
            occupancy_ray_step: 1.0,
            moved_ranges: Default::default(),
            skipping_enabled: true,
            shader_overrides: Default::default(),
            main_workgroup,
            march: march_parts::MarchState::new(device),
            overrides_generation: 0,
            pipelines: None,
            compiled: Vec::new(),
            atlas_uids: Default::default(),
            counters: RenderCounters {
                volume_uploads: split.is_none() as u64,
                ..Default::default()
            },
            instances: HashMap::new(),
            target: None,
            raster_et: None,
            occupied_proxy: false,
            raster_group: raster_group_from_env(),
            frame_from_vertex: gpu.info.device_type == wgpu::DeviceType::Cpu
                && env_on("VWB_FRAME_FROM_VERTEX"),
            raster_skipping: env_on("VWB_RASTER_SKIP"),
            hull_proxy: HullProxy::from_env(),
            occupied_hull: None,
            hull_rays: HullRays::from_env(),
            fused_slices: env_on("VWB_FUSED_SLICES"),
            state_tracking: env_on("VWB_STATE_TRACKING"),
            slice_exit: env_on("VWB_SLICE_EXIT"),
            resolved_gradient: crate::shading::GradientEstimator::Central,
            raw_samples: std::env::var("VWB_RAW_SAMPLES").is_ok_and(|v| v.trim() == "1"),
            volume_bytes,
            gpu_budget: budget,
            volume_format,
            table_format: TableFormat::Auto,
            stored_format,
            vertices: None,
            timestamps: None,
            display_pipeline: None,
            dump_dir: std::env::var_os("VWB_SHADER_DUMP").map(Into::into),
            slice_spacing: 1.0,
            refinement_budget: None,
            dummy_3d: crate::gpu::upload_r8_3d(device, &gpu.queue, "vwb dummy 3d", [1, 1, 1], &[0]),
            brick_limit,
            max_brick_bytes,
            level,
            region: None,
            split,
            lod,
        };
        if gpu.has_timestamps()
            && gpu
                .features
                .contains(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS)
        {
            let qs = device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("vwb timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: MAX_TIMESTAMPS,
            });
            let size = MAX_TIMESTAMPS as u64 * 8;
            let resolve = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vwb timestamp resolve"),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vwb timestamp read"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            r.timestamps = Some((qs, resolve, read));
        }
        Ok(r)
    }

    pub fn gpu(&self) -> &GpuContext {
        &self.gpu
    }

    /// The work done since the renderer was made ([`RenderCounters`]).
    pub fn counters(&self) -> RenderCounters {
        let mut c = self.counters;
        for b in self.split.iter().flat_map(|sp| &sp.children) {
            let d = b.renderer.counters();
            c.compiles += d.compiles;
            c.compile_cache_hits += d.compile_cache_hits;
            c.volume_uploads += d.volume_uploads;
            c.instance_creations += d.instance_creations;
            c.prepass_runs += d.prepass_runs;
            c.volume_pass_runs += d.volume_pass_runs;
        }
        c
    }

    /// The renderers of a split volume's bricks (none for one texture).
    fn brick_renderers(&self) -> impl Iterator<Item = &Renderer> {
        self.split
            .iter()
            .flat_map(|sp| &sp.children)
            .map(|c| &c.renderer)
    }

    pub fn volume(&self) -> &Arc<Volume> {
        &self.volume
    }

    pub fn volume_box(&self) -> &VolumeBox {
        &self.vbox
    }

    /// The coarser level shown in place of a volume beyond the GPU memory budget
    /// (`None`: the volume itself is shown). [`Renderer::volume`] is then the level.
    pub fn level(&self) -> Option<&LevelInfo> {
        self.level.as_ref()
    }

    /// Sets the document's named volumes ([`crate::inputs`]). The next stack update
    /// recreates the resources and reruns the passes of exactly the instances whose
    /// inputs now resolve to another volume; the same volumes (the same `Arc`s under the
    /// same names) change nothing.
    pub fn set_inputs(&mut self, inputs: crate::inputs::VolumeInputs) {
        self.inputs = inputs;
    }

    /// The document's named volumes as last set.
    pub fn inputs(&self) -> &crate::inputs::VolumeInputs {
        &self.inputs
    }

    /// The volume and the named volumes, as plugins' promises see them.
    fn volumes(&self) -> crate::inputs::Volumes<'_> {
        crate::inputs::Volumes::new(&self.volume, &self.inputs)
    }

    /// Replaces the volume; pre-passes rerun, plugin resources are recreated (compiled
    /// stacks are kept: they do not depend on the volume). The same volume (the same
    /// `Arc`) is not uploaded again and changes nothing.
    pub fn set_volume(&mut self, volume: Arc<Volume>) -> Result<(), RenderError> {
        if Arc::ptr_eq(&volume, &self.volume) {
            return Ok(());
        }
        if volume.dims.contains(&0) {
            return Err(RenderError::VolumeTooLarge {
                name: volume.name.clone(),
                dims: volume.dims,
                limit: self.gpu.limits.max_texture_dimension_3d,
            });
        }
        self.upload(volume)
    }

    /// How the volume is asked to be stored on the GPU.
    pub fn volume_format(&self) -> VolumeFormat {
        self.volume_format
    }

    /// How it is stored: the asked format, or for `auto` r32float_pairs on CPU devices
    /// where the pair texture fits, r32float (r16float without float32 filtering) or,
    /// under a GPU memory budget the r32float texture would pass, a 16-bit format
    /// ([`VolumeFormat::for_budget`]).
    pub fn stored_volume_format(&self) -> VolumeFormat {
        self.stored_format
    }

    /// What the user should know about how the volume is stored: that a GPU memory
    /// budget made `auto` keep it in 16 bits (`None` otherwise).
    pub fn storage_notice(&self) -> Option<String> {
        let sixteen = !matches!(
            self.stored_format,
            VolumeFormat::R32Float | VolumeFormat::R32FloatPairs
        );
        let usual = self.volume_format.concrete(&self.gpu);
        (self.volume_format.is_auto() && self.stored_format != usual && sixteen).then(|| {
            format!(
                "volume stored as {} (16 bits) to fit the GPU memory budget of {} MiB",
                self.stored_format.name(),
                self.gpu_budget.unwrap_or(0) >> 20
            )
        })
    }

    /// How the classification tables are stored ([`TableFormat`]).
    pub fn table_format(&self) -> TableFormat {
        self.table_format
    }

    /// Stores the classification tables as `format` from now on: where that changes
    /// it, the plugins' resources are made again at the next stack update
    /// ([`Renderer::update_stack`]; their passes run again), also in a split volume's
    /// bricks (which take it with the parent's other settings, `ChildSettings`).
    pub fn set_table_format(&mut self, format: TableFormat) {
        if format != self.table_format {
            self.table_format = format;
            // as a new volume does (`install`): the next stack update binds the
            // cached pipeline to the new resources
            self.instances.clear();
            self.pipelines = None;
        }
    }

    /// Stores the volume as `format` from now on (uploading it again when that changes
    /// what is stored); an adapter that cannot filter the format is refused and the
    /// volume stays as it was.
    pub fn set_volume_format(&mut self, format: VolumeFormat) -> Result<(), RenderError> {
        let stored = format.for_budget(&self.gpu, &self.volume, self.gpu_budget)?;
        self.volume_format = format;
        if stored != self.stored_format {
            self.upload(self.volume.clone())?;
        }
        Ok(())
    }

    fn upload(&mut self, volume: Arc<Volume>) -> Result<(), RenderError> {
        let stored = self
            .volume_format
            .for_budget(&self.gpu, &volume, self.gpu_budget)?;
        let bytes = volume_texture_bytes(stored.texture_format(&self.gpu)?, &volume);
        let what = format!("volume {} ({:?})", volume.name, volume.dims);
        // the old volume (or its bricks) is freed
        let freeing = self.volume_bytes
            + self
                .brick_renderers()
                .map(Renderer::gpu_memory)
                .sum::<u64>();
        self.check_budget(&what, bytes, freeing)?;
        // the same volume again (in another format) keeps its box, and its level if it
        // is one (a level keeps the full volume's box and Δs0)
        let same = Arc::ptr_eq(&volume, &self.volume);
        let vbox = if same {
            self.vbox
        } else {
            level::full_box(&volume)
        };
        let upload = upload_or_split(
            &self.gpu,
            &volume,
            &vbox,
            self.brick_limit,
            self.max_brick_bytes,
            None,
            stored,
        )?;
        self.stored_format = stored;
        self.vbox = vbox;
        if !same {
            let format = stored.texture_format(&self.gpu)?;
            self.level = level::stored_level_info(&volume, self.gpu_budget, format);
        }
        self.install(upload, &volume);
        // another volume (or format) is shown whole: its bricks are not refined
        self.lod = None;
        self.occupancy = upload_occupancy(&self.gpu, [1, 1, 1], &[255]);
        self.occupancy_bytes = None;
        self.occupied_hull = None;
        self.volume = volume;
        self.rebuild_g0();
        Ok(())
    }

    /// Holds `upload` (of `volume`) as the volume's GPU form, in place of the old one;
    /// plugin resources and pipelines are made again for it. The caller rebuilds
    /// group 0 once the rest of the volume's state is in place.
    fn install(&mut self, upload: bricks::Upload, volume: &Volume) {
        (self.volume_view, self.volume_bytes, self.bricks, self.split) =
            upload.into_parts(&self.gpu, volume);
        let layout = bound_layout(self.stored_format, self.split.is_some());
        if layout != self.volume_layout {
            // group 0 and every compiled module read the volume in its layout
            self.volume_layout = layout;
            self.g0_layout = g0_layout(&self.gpu.device, layout);
            self.compiled.clear();
        }
        if let Ok(mut cache) = self.moved_ranges.lock() {
            *cache = None;
        }
        self.counters.volume_uploads += self.split.is_none() as u64;
        self.instances.clear();
        self.pipelines = None;
    }

    /// Replaces the WGSL of a plugin file (as named by [`crate::plugin::ShaderSource::file`])
    /// for every instance using it, or restores the built-in source (`None`). Takes
    /// effect at the next [`Renderer::update_stack`]; if the new source fails to
    /// compose, that call returns the error (naming the file and line) and the last
    /// good pipeline stays.
    pub fn set_shader_override(&mut self, file: &str, source: Option<String>) {
        match source {
            Some(s) => self.shader_overrides.insert(file.to_string(), s),
            None => self.shader_overrides.remove(file),
        };
        self.overrides_generation += 1;
    }

    /// The overriding WGSL of a plugin file, if any.
    pub fn shader_override(&self, file: &str) -> Option<&str> {
        self.shader_overrides.get(file).map(String::as_str)
    }

    /// Every override, as (file, source).
    pub fn shader_overrides(&self) -> impl Iterator<Item = (&str, &str)> {
        self.shader_overrides
            .iter()
            .map(|(f, s)| (f.as_str(), s.as_str()))
    }

    /// Turns empty-space skipping on or off (on by default; it only ever acts when
    /// every enabled plugin promises how it treats transparent samples). Takes effect
    /// at the next [`Renderer::update_stack`].
    pub fn set_empty_space_skipping(&mut self, on: bool) {
        self.skipping_enabled = on;
    }

    /// Compute backend with per-slice state (e.g. shade.dos): evaluate each slice's
    /// sample once and update every state in the same dispatch (on by default, and where
    /// every state has the eye buffer's resolution; `VWB_FUSED_SLICES=0` starts
    /// renderers with it off), or run the slice and each update as separate dispatches
    /// (docs/perf.md, "Per-slice state in one dispatch"). The image is the same.
    pub fn set_fused_slices(&mut self, on: bool) {
        self.fused_slices = on;
    }

    /// A benchmark of the sampling itself (issue 23: the share of the raw trilinear
    /// sampling rate that DVR reaches): the compute backend's single-pass frames run
    /// `cs_main_raw`, which takes the samples `cs_main` takes with one trilinear fetch
    /// of the volume each and nothing else, and stores (Σ value, sample count, 0, 1) per
    /// pixel. Off by default; `VWB_RAW_SAMPLES=1` starts renderers with it on. Stacks
    /// with per-slice state, split volumes' bricks and atlases render as usual.
    pub fn set_raw_samples(&mut self, on: bool) {
        self.raw_samples = on;
    }

    /// Per-slice state whose every plugin states its reach
    /// ([`crate::plugin::Plugin::slice_state_reach`], `shade.dos`), view-aligned slices,
    /// state of the eye buffer's size: each slice's dispatches cover only the 8 × 8
    /// tiles where a sample can be visible, or where the state can differ from clear and
    /// a later visible sample reads it; the second kind updates the state alone (on by
    /// default; `VWB_SLICE_EXIT=0` starts renderers with it off; `slice_exit.rs`,
    /// docs/perf.md, "Idle tiles of the per-slice path"). The image is the same bit for
    /// bit.
    pub fn set_slice_exit(&mut self, on: bool) {
        self.slice_exit = on;
    }

    /// Per-slice state whose plugin tracks its clear tiles
    /// ([`crate::plugin::SliceStateDecl::track_clear`], `shade.dos`): keep the marks of
    /// the tiles that left the clear value, so that updates under clear tiles skip
    /// their reads (on by default; `VWB_STATE_TRACKING=0` starts renderers with it
    /// off), or mark every tile for good, so that every update reads (docs/perf.md,
    /// "Per-slice state: the taps under a clear buffer"). The image is the same.
    pub fn set_state_tracking(&mut self, on: bool) {
        if self.state_tracking != on {
            self.state_tracking = on;
            for g in self.instances.values_mut() {
                g.state = None;
                g.state_tiles = None;
            }
        }
    }

    /// Raster backend with empty-space skipping: fragments in front of a pixel's next
    /// visible brick fail the depth test before they are shaded ([`raster_et`]; on by
    /// default where slices are view aligned and the proxies are not cut to the occupied
    /// cells; `VWB_RASTER_SKIP=0` starts renderers with it off). The image is the same.
    pub fn set_raster_skipping(&mut self, on: bool) {
        self.raster_skipping = on;
    }

    /// Raster backend: draw one proxy polygon per group of `n` slices (Rezk-Salama 2001,
    /// §9.1, "multi-texture speedup"): its fragments take the group's `n` samples along
    /// their rays, composite them front to back and blend once, which cuts the
    /// rasterisation, depth tests and blends per sample by `n` (docs/perf.md measures
    /// it). `n` is rounded down to one of [`RASTER_GROUPS`]; 1 draws a polygon per
    /// slice. [`RASTER_GROUP_AUTO`] (0, the default) draws a polygon per slice, or
    /// [`RASTER_GROUP_WITH_TERMINATION`] slices per polygon in frames with early
    /// termination. The image moves by the rounding of the blends (the target
    /// rounds once per group, not per slice) and of the sample positions (stepped
    /// along the ray from the group's plane, not interpolated on each plane). Applies
    /// to view-aligned frames without per-slice state whose proxies are not cut (to the
    /// occupied cells or the hull); other frames draw a polygon per slice.
    /// `VWB_RASTER_GROUP` sets the default of new renderers (a benchmark switch).
    pub fn set_raster_group(&mut self, n: u32) {
        self.raster_group = raster_group_setting(n);
    }

    /// Slices per proxy polygon on the raster backend ([`Renderer::set_raster_group`];
    /// [`RASTER_GROUP_AUTO`]: chosen per frame, [`raster_group_for`]).
    pub fn raster_group(&self) -> u32 {
        self.raster_group
    }

    /// Raster backend: whether the slices' fragments take the frame's most read fields
    /// from their vertices' flat outputs (`FRAME_FROM_VERTEX` in shaders/slice.wgsl)
    /// rather than from the uniform buffer. The values are the same, and so are the
    /// images; on CPU devices the fragments run 0.8–0.9× as long (llvmpipe reads a
    /// uniform in a fragment shader one lane at a time; docs/perf.md, "The frame and the
    /// parameters as private copies"). On by default on CPU devices, off on GPUs
    /// (unmeasured there); `VWB_FRAME_FROM_VERTEX=0` turns the default off (a benchmark
    /// switch).
    pub fn set_frame_from_vertex(&mut self, on: bool) {
        self.frame_from_vertex = on;
    }

    /// [`Renderer::set_frame_from_vertex`].
    pub fn frame_from_vertex(&self) -> bool {
        self.frame_from_vertex
    }

    /// Raster backend: cut the proxy polygons to the cells of bricks that can be
    /// visible ([`crate::skipping::occupied_cells`]; needs empty-space skipping) and
    /// sample each fragment at its pixel's exact ray–plane point (`fs_exact`, as the
    /// compute backend does) instead of the interpolated proxy position, which slivers
    /// of the cut polygons interpolate poorly. The image is the full proxy's up to
    /// float rounding of the sample positions; off by default.
    pub fn set_occupied_proxy(&mut self, on: bool) {
        self.occupied_proxy = on;
    }

    /// Raster backend with empty-space skipping: how the proxy polygons are fitted to
    /// the occupied bricks' hull ([`HullProxy`]; `Scissor` by default, which keeps the
    /// image bit for bit; `VWB_HULL_PROXY=off|scissor|cut` sets the default of new
    /// renderers for benchmarks).
    pub fn set_hull_proxy(&mut self, mode: HullProxy) {
        self.hull_proxy = mode;
    }

    /// The raster backend's fit to the occupied bricks' hull.
    pub fn hull_proxy(&self) -> HullProxy {
        self.hull_proxy
    }

    /// Compute backend with empty-space skipping: whether the rays are cut to the
    /// occupied bricks' hull ([`HullRays`]; `Auto` by default; the image is the same bit
    /// for bit; `VWB_HULL_RAYS=off|auto|always` sets the default of new renderers for
    /// benchmarks).
    pub fn set_hull_rays(&mut self, mode: HullRays) {
        self.hull_rays = mode;
    }

    /// Whether the compute backend's next frame (with skipping) cuts its rays to the
    /// occupied bricks' hull, and the share of the visible box inside the hull (1
    /// without one).
    pub fn hull_rays(&self) -> (bool, f32) {
        match &self.occupied_hull {
            Some((_, share)) => (self.cuts_rays(*share), *share),
            None => (false, 1.0),
        }
    }

    /// Whether rays are cut to a hull that holds `share` of the visible box.
    fn cuts_rays(&self, share: f32) -> bool {
        match self.hull_rays {
            HullRays::Off => false,
            HullRays::Auto => share < HULL_RAYS_SHARE,
            HullRays::Always => true,
        }
    }

    /// The occupied bricks' hull of an occupancy grid ([`crate::slicing::Dop`], widened
    /// by [`HULL_MARGIN`] voxels) and its share of the visible box; `None` when no brick
    /// can be visible.
    pub(super) fn hull_of(&self, occupancy: &[u8]) -> Option<(crate::slicing::Dop, f32)> {
        let hull = crate::slicing::Dop::of_boxes(
            crate::skipping::occupied_brick_voxels(occupancy, self.bricks.dims, self.volume.dims)
                .map(|r| bricks::sub_box(&self.vbox, self.volume.dims, r)),
            HULL_MARGIN * self.vbox.voxel,
        )?;
        let share = self
            .visible_box_in(Some(occupancy))
            .map_or(1.0, |visible| hull.share_of(&visible, HULL_SHARE_GRID));
        Some((hull, share))
    }

    /// Workgroup shape of the whole-frame compute passes
    /// ([`crate::composer::main_workgroup`]).
    pub fn main_workgroup(&self) -> [u32; 2] {
        self.main_workgroup
    }

    /// Share of bricks skipped for the current stack, `None` when skipping is off.
    pub fn empty_brick_share(&self) -> Option<f64> {
        if self.split.is_some() {
            let shares: Vec<f64> = self
                .brick_renderers()
                .filter_map(Renderer::empty_brick_share)
                .collect();
            return (!shares.is_empty()).then(|| shares.iter().sum::<f64>() / shares.len() as f64);
        }
        self.occupancy_bytes
            .as_ref()
            .map(|b| b.iter().filter(|&&v| v == 0).count() as f64 / b.len().max(1) as f64)
    }

    /// The occupancy byte per brick a stack allows: bricks no value of which any
    /// classification shows, or wholly outside its clip regions, are 0. `None` when
    /// skipping is off or a plugin promises nothing.
    fn occupancy_of(&self, stack: &[PluginInstance]) -> Option<Vec<u8>> {
        self.occupancy_moving(stack, stack_moves(stack, &self.volumes()))
    }

    /// [`Renderer::occupancy_of`] for a stack whose plugins move samples by `moves`
    /// slice steps ([`stack_moves`]).
    fn occupancy_moving(&self, stack: &[PluginInstance], moves: f64) -> Option<Vec<u8>> {
        if !self.skipping_enabled {
            return None;
        }
        let visible = stack_visibility(stack, &self.volumes())?;
        // a moved sample may read beyond its brick: ranges over a wider apron, and
        // regions widened by the move
        let apron = move_apron(moves, self.occupancy_ray_step);
        let mut bytes = match self.ranges_with_apron(apron) {
            Some(ranges) => ranges.occupancy(&*visible),
            None => self.bricks.occupancy(&*visible),
        };
        clear_outside_regions(
            &mut bytes,
            self.bricks.dims,
            self.volume.dims,
            (self.vbox.min.as_dvec3(), self.vbox.max.as_dvec3()),
            &stack_regions(stack, &self.volumes()),
            moves * self.occupancy_ray_step as f64 * self.vbox.voxel as f64,
        );
        Some(bytes)
    }

    /// The brick ranges over an apron of `apron` voxels (None for 1: `self.bricks`),
    /// made once per apron and volume.
    fn ranges_with_apron(&self, apron: u32) -> Option<Arc<BrickRanges>> {
        if apron <= 1 || self.split.is_some() {
            return None;
        }
        let mut cache = self.moved_ranges.lock().ok()?;
        if let Some((a, r)) = cache.as_ref()
            && *a == apron
        {
            return Some(r.clone());
        }
        let ranges = Arc::new(BrickRanges::with_apron(
            self.volume.dims,
            &self.volume.normalized_scalars(),
            crate::skipping::brick(),
            apron,
        ));
        *cache = Some((apron, ranges.clone()));
        Some(ranges)
    }

    /// Recomputes the occupancy for the stack and uploads it when it changed.
    fn update_occupancy(&mut self, stack: &[PluginInstance]) {
        self.occupancy_stack = stack.to_vec();
        self.occupancy_moves = stack_moves(stack, &self.volumes());
        self.occupancy_apron = move_apron(self.occupancy_moves, self.occupancy_ray_step);
        let bytes = self.occupancy_moving(stack, self.occupancy_moves);
        if bytes == self.occupancy_bytes {
            return;
        }
        self.occupancy = match &bytes {
            Some(b) => upload_occupancy(&self.gpu, self.bricks.dims, b),
            None => upload_occupancy(&self.gpu, [1, 1, 1], &[255]),
        };
        self.occupied_hull = bytes.as_deref().and_then(|b| self.hull_of(b));
        self.occupancy_bytes = bytes;
        self.rebuild_g0();
    }

    fn rebuild_g0(&mut self) {
        self.g0 = self.g0_with(
            &self.frame_buf,
            [&self.slice_info, &self.no_tile_list],
            &self.occupancy,
        );
    }

    /// Bind group 0 over the renderer's volume and samplers with a `frame` uniform,
    /// slice info and tile list (`slices`) and `occupancy` grid of its own.
    fn g0_with(
        &self,
        frame: &wgpu::Buffer,
        slices: [&wgpu::Buffer; 2],
        occupancy: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        make_g0(
            &self.gpu.device,
            &self.g0_layout,
            frame,
            &self.volume_view,
            &self.linear,
            &self.nearest,
            slices,
            occupancy,
        )
    }

    /// The composed WGSL of the current pipeline.
    pub fn composed_wgsl(&self) -> Option<&str> {
        if let Some(first) = self.brick_renderers().next() {
            return first.composed_wgsl();
        }
        self.pipelines
            .as_ref()
            .map(|p| p.composition.main.source.as_str())
    }

    /// Ids of the plugins in the current (last good) pipeline.
    pub fn active_plugins(&self) -> Vec<&'static str> {
        if let Some(first) = self.brick_renderers().next() {
            return first.active_plugins();
        }
        self.pipelines
            .as_ref()
            .map(|p| p.stack.iter().map(|(_, pl)| pl.id()).collect())
            .unwrap_or_default()
    }

    /// GPU memory the renderer holds: the volume, the eye buffer with its
    /// accumulation and display copies, and every instance's resources (enabled or
    /// held while disabled).
    pub fn gpu_memory(&self) -> u64 {
        // bricks sharing one eye buffer hold it once
        let shared: Vec<u64> = self
            .split
            .iter()
            .filter(|sp| sp.shared)
            .flat_map(|sp| &sp.children)
            .filter_map(|c| c.renderer.target.as_ref().map(Target::bytes))
            .collect();
        let counted_twice = shared.iter().skip(1).sum::<u64>();
        self.brick_renderers()
            .map(Renderer::gpu_memory)
            .sum::<u64>()
            - counted_twice
            + self.volume_bytes
            + self.target.as_ref().map_or(0, Target::bytes)
            + self
                .raster_et
                .as_ref()
                .map_or(0, raster_et::RasterEt::bytes)
            + self.instances.values().map(|g| g.bytes()).sum::<u64>()
    }

    /// Caps the GPU memory the renderer may hold (volume, eye buffer, instance
    /// resources). A volume or an image size that would pass it fails with
    /// [`RenderError::OutOfMemory`] before anything is allocated, and what was there
    /// stays. `None` (the default unless `VWB_GPU_MEMORY_LIMIT` is set, in bytes) leaves
    /// the refusal to the driver, which is caught the same way.
    pub fn set_gpu_memory_budget(&mut self, bytes: Option<u64>) {
        self.gpu_budget = bytes;
    }

    pub fn gpu_memory_budget(&self) -> Option<u64> {
        self.gpu_budget
    }

    /// Fails when adding `bytes` (and freeing `freeing`) would pass the budget.
    fn check_budget(&self, what: &str, bytes: u64, freeing: u64) -> Result<(), RenderError> {
        let Some(budget) = self.gpu_budget else {
            return Ok(());
        };
        let after = self
            .gpu_memory()
            .saturating_sub(freeing)
            .saturating_add(bytes);
        if after <= budget {
            return Ok(());
        }
        Err(RenderError::OutOfMemory {
            what: what.to_string(),
            bytes,
            reason: format!(
                "and the renderer would hold {} MiB, more than its GPU memory budget of {} MiB",
                after.div_ceil(1 << 20),
                budget >> 20
            ),
        })
    }

    /// Runs `f` (allocations) in an out-of-memory error scope: a driver refusal becomes
    /// [`RenderError::OutOfMemory`] instead of a logged error and invalid resources.
    fn out_of_memory_scope<T>(
        &self,
        what: &str,
        bytes: u64,
        f: impl FnOnce() -> T,
    ) -> Result<T, RenderError> {
        let scope = self
            .gpu
            .device
            .push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let out = f();
        match pollster::block_on(scope.pop()) {
            None => Ok(out),
            Some(e) => Err(RenderError::OutOfMemory {
                what: what.to_string(),
                bytes,
                reason: format!("and the device is out of memory ({e})"),
            }),
        }
    }

    /// GPU memory per enabled instance in stack order: (uid, plugin id, bytes) of its
    /// uniforms, resources, pre-pass target and per-slice state.
    pub fn plugin_memory(&self) -> Vec<(u64, &'static str, u64)> {
        if self.split.is_some() {
            return sum_by_uid(self.brick_renderers().map(Renderer::plugin_memory));
        }
        let Some(p) = &self.pipelines else {
            return Vec::new();
        };
        p.stack
            .iter()
            .filter_map(|(uid, _)| {
                let g = self.instances.get(uid)?;
                Some((*uid, g.plugin_id, g.bytes()))
            })
            .collect()
    }

    /// GPU memory the renderer keeps for instances of the stack that are disabled
    /// (uid, plugin id, bytes), so that enabling them again neither recreates their
    /// resources nor reruns their pre-passes. Reported by `vwb bench` and the window.
    pub fn disabled_memory(&self) -> Vec<(u64, &'static str, u64)> {
        if self.split.is_some() {
            return sum_by_uid(self.brick_renderers().map(Renderer::disabled_memory));
        }
        let enabled: std::collections::HashSet<u64> = self
            .pipelines
            .as_ref()
            .map(|p| p.stack.iter().map(|(uid, _)| *uid).collect())
            .unwrap_or_default();
        let mut held: Vec<_> = self
            .instances
            .iter()
            .filter(|(uid, _)| !enabled.contains(uid))
            .map(|(uid, g)| (*uid, g.plugin_id, g.bytes()))
            .collect();
        held.sort_unstable();
        held
    }

    /// Brings the pipeline in line with the plugin stack. On a composition error the
    /// previous pipeline stays in use and the error is returned.
    pub fn update_stack(
        &mut self,
        stack: &[PluginInstance],
        target: TargetFormat,
    ) -> Result<StackChange, RenderError> {
        let Some(lod) = &self.lod else {
            return self.apply_stack(stack, target);
        };
        // a volume refined in view: bricks when the stack splits, else the whole level
        let splits = stack
            .iter()
            .filter(|i| i.enabled)
            .all(|i| i.configured().splits_into_bricks());
        if lod.active == splits {
            let change = self.apply_stack(stack, target)?;
            self.remember_lod_stack(stack, target);
            return Ok(change);
        }
        if splits {
            self.enter_lod()?;
        } else {
            self.leave_lod()?;
        }
        match self.apply_stack(stack, target) {
            Ok(change) => {
                self.remember_lod_stack(stack, target);
                Ok(change)
            }
            Err(e) => {
                // back to the last good stack on the form it had
                let lod = self.lod.as_ref().expect("refinable");
                let (last, last_target) = (lod.stack.clone(), lod.target);
                if splits {
                    self.leave_lod()?;
                } else {
                    self.enter_lod()?;
                }
                self.apply_stack(&last, last_target)?;
                Err(e)
            }
        }
    }

    /// `stack` with `gradient: auto` resolved ([`Renderer::auto_gradient`]) and each
    /// plugin configured by its structural parameters (`Plugin::configure`).
    pub(crate) fn configure_stack(&self, stack: &[PluginInstance]) -> Vec<PluginInstance> {
        with_gradient(stack, self.auto_gradient(stack))
            .iter()
            .map(PluginInstance::with_configured_plugin)
            .collect()
    }

    /// What `gradient: auto` resolved to for the stack last applied
    /// ([`Renderer::update_stack`]): what the window shows beside `auto`, without
    /// looking at the stack again every frame.
    pub fn resolved_gradient(&self) -> crate::shading::GradientEstimator {
        self.resolved_gradient
    }

    /// What `gradient: auto` resolves to for `stack` here
    /// ([`crate::shading::auto_estimator`]).
    pub fn auto_gradient(&self, stack: &[PluginInstance]) -> crate::shading::GradientEstimator {
        // the pre-pass volume is rgba32float, filtered: FLOAT32_FILTERABLE (lavapipe has it)
        let cpu =
            self.gpu.info.device_type == wgpu::DeviceType::Cpu && self.gpu.float32_filterable();
        let any_auto = stack
            .iter()
            .any(|i| i.enabled && crate::shading::GradientEstimator::is_auto(&i.params));
        if !(cpu && any_auto) {
            // nothing to resolve, or `central` whatever the stack (this runs at every
            // update: the stack's shaders are looked at only where it matters)
            return crate::shading::GradientEstimator::Central;
        }
        let scalar_replaced = stack.iter().any(|i| {
            i.enabled && crate::composer::defines_fn(&i.configured().shader().source, "scalar")
        });
        crate::shading::auto_estimator(cpu, self.volume.dims, self.gpu_budget, scalar_replaced)
    }

    /// [`Renderer::update_stack`] on the volume's present form (one texture or bricks).
    fn apply_stack(
        &mut self,
        stack: &[PluginInstance],
        target: TargetFormat,
    ) -> Result<StackChange, RenderError> {
        // `auto` resolved here, once for the whole volume: a split volume's bricks are
        // handed the resolved stack (the memory cap is the whole volume's, not a brick's)
        self.resolved_gradient = self.auto_gradient(stack);
        let stack = with_gradient(stack, self.resolved_gradient);
        if self.split.is_some() {
            return self.update_split_stack(&stack, target);
        }
        // structural parameters pick the plugin's configuration (Plugin::configure)
        let stack: Vec<PluginInstance> = stack
            .iter()
            .map(PluginInstance::with_configured_plugin)
            .collect();
        let stack = &stack[..];
        let enabled: Vec<&PluginInstance> = stack.iter().filter(|i| i.enabled).collect();
        let key = StructureKey {
            entries: enabled
                .iter()
                .map(|i| (i.uid, i.plugin.id(), structure_of(i)))
                .collect(),
            target,
            overrides: self.overrides_generation,
        };
        let recompose = self.pipelines.as_ref().is_none_or(|p| p.key != key);
        if recompose {
            let hash = structure_hash(&key.entries, target, &self.shader_overrides);
            let compiled = match self.compiled.iter().position(|(h, _)| *h == hash) {
                Some(i) => {
                    // most recently used last
                    let hit = self.compiled.remove(i);
                    self.counters.compile_cache_hits += 1;
                    hit.1
                }
                None => {
                    let plugins: Vec<&dyn Plugin> =
                        enabled.iter().map(|i| i.plugin.as_ref()).collect();
                    let composition = compose_for(
                        &plugins,
                        target,
                        &self.gpu.limits,
                        &self.shader_overrides,
                        self.volume_layout,
                    )?;
                    self.dump(&composition);
                    let compiled = Arc::new(self.build_pipelines(composition, target)?);
                    self.counters.compiles += 1;
                    compiled
                }
            };
            if self.compiled.len() >= COMPILED_CACHE_SIZE {
                self.compiled.remove(0);
            }
            self.compiled.push((hash, compiled.clone()));
            // resources for new instances (kept for known ones)
            for inst in &enabled {
                self.ensure_instance(inst)?;
            }
            self.pipelines = Some(Pipelines {
                compiled,
                stack: enabled.iter().map(|i| (i.uid, i.plugin.clone())).collect(),
                key,
            });
            let live: std::collections::HashSet<u64> = stack.iter().map(|i| i.uid).collect();
            self.instances.retain(|uid, _| live.contains(uid));
        }
        let mut params_changed = false;
        if !recompose {
            // an input that resolves to another volume (a renamed input, a volume set
            // again under its name) recreates that instance's resources; the same
            // structure means the same plugins, so only those with inputs can
            for inst in &enabled {
                if self
                    .instances
                    .get(&inst.uid)
                    .is_some_and(|g| !g.inputs.is_empty())
                {
                    params_changed |= self.ensure_instance(inst)?;
                }
            }
        }
        for inst in &enabled {
            params_changed |= self.sync_params(inst)?;
        }
        self.update_occupancy(stack);
        Ok(if recompose {
            StackChange::Recomposed
        } else if params_changed {
            StackChange::Params
        } else {
            StackChange::None
        })
    }

    /// Brings spacing-dependent plugin resources (e.g. pre-integration tables) in line
    /// with the frame's slice spacing (voxels); only those whose spacing changed.
    fn sync_spacing(&mut self, spacing: f32) -> Result<usize, RenderError> {
        self.slice_spacing = spacing;
        let Some(p) = &self.pipelines else {
            return Ok(0);
        };
        let stale: Vec<(u64, Arc<dyn Plugin>)> = p
            .stack
            .iter()
            .filter(|(uid, plugin)| {
                plugin.uses_slice_spacing()
                    && self
                        .instances
                        .get(uid)
                        .is_some_and(|g| g.spacing != spacing)
            })
            .cloned()
            .collect();
        let mut updated = 0;
        for (uid, plugin) in stale {
            let Some(g) = self.instances.get(&uid) else {
                continue;
            };
            plugin.update_resources(&self.gpu_init(), &g.params, &g.resources)?;
            if let Some(g) = self.instances.get_mut(&uid) {
                g.spacing = spacing;
            }
            updated += 1;
        }
        Ok(updated)
    }

    fn dump(&self, c: &Composition) {
        let Some(dir) = &self.dump_dir else { return };
        if let Err(e) = std::fs::create_dir_all(dir) {
            log::warn!("VWB_SHADER_DUMP: cannot create {}: {e}", dir.display());
            return;
        }
        let mut files = vec![("composed_main.wgsl".to_string(), c.main.source.clone())];
        for inst in &c.instances {
            if let Some((m, _)) = &inst.prepass {
                files.push((
                    format!("composed_prepass_{}.wgsl", inst.prefix),
                    m.source.clone(),
                ));
            }
        }
        for (name, src) in files {
            let path = dir.join(name);
            if let Err(e) = std::fs::write(&path, src) {
                log::warn!("VWB_SHADER_DUMP: cannot write {}: {e}", path.display());
            }
        }
    }

    fn gpu_init(&self) -> GpuInit<'_> {
        GpuInit {
            device: &self.gpu.device,
            queue: &self.gpu.queue,
            features: self.gpu.features,
            device_type: self.gpu.info.device_type,
            table_format: self.table_format,
            volume: &self.volume,
            inputs: &self.inputs,
            slice_spacing: self.slice_spacing,
        }
    }

    /// A 3D texture of the volume's size times `scale` that a compute pass writes and
    /// hooks sample (pre-pass and volume-pass targets).
    fn storage_target_3d(
        &self,
        label: &str,
        scale: f32,
        format: crate::plugin::StorageFormat,
    ) -> (wgpu::Texture, wgpu::TextureView) {
        let dims = self
            .volume
            .dims
            .map(|d| ((d as f32 * scale).ceil() as u32).max(1));
        let texture = self.gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: dims[0],
                height: dims[1],
                depth_or_array_layers: dims[2],
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D3,
            format: format.wgpu(),
            usage: wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        (texture, view)
    }

    /// Creates the instance's GPU data unless it has them for its plugin, structure and
    /// inputs; whether it created them.
    fn ensure_instance(&mut self, inst: &PluginInstance) -> Result<bool, RenderError> {
        let structure = structure_of(inst);
        let plugin = inst.plugin.as_ref();
        let specs = plugin.params();
        let inputs = self.inputs.stamp(&specs, &inst.params);
        if self.instances.get(&inst.uid).is_some_and(|g| {
            g.plugin_id == inst.plugin.id() && g.structure == structure && g.inputs == inputs
        }) {
            return Ok(false);
        }
        self.inputs
            .check(&self.volume, &specs, &inst.params)
            .map_err(|message| {
                RenderError::Plugin(PluginError::Invalid {
                    plugin: plugin.id().to_string(),
                    message,
                })
            })?;
        let layout = crate::params::UniformLayout::new(&specs);
        let uniform = self
            .gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(plugin.id()),
                contents: &layout.pack(&specs, &inst.params),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
        let resources = plugin.create_resources(&self.gpu_init(), &inst.params)?;
        if resources.len() != plugin.resources().len() {
            return Err(RenderError::Plugin(PluginError::Invalid {
                plugin: plugin.id().to_string(),
                message: format!(
                    "created {} resources but declares {}",
                    resources.len(),
                    plugin.resources().len()
                ),
            }));
        }
        let prepass_target = plugin
            .prepass()
            .map(|pp| self.storage_target_3d(pp.target, pp.scale, pp.format));
        let pass_targets: Vec<_> = plugin
            .volume_passes()
            .iter()
            .map(|vp| self.storage_target_3d(vp.target, vp.scale, vp.format))
            .collect();
        let pass_state = pass_targets.iter().map(|_| PassState::default()).collect();
        self.counters.instance_creations += 1;
        self.instances.insert(
            inst.uid,
            InstanceGpu {
                plugin_id: plugin.id(),
                uniform_size: layout.size as u64,
                uniform,
                resources,
                params: inst.params.clone(),
                prepass_target,
                prepass_done: None,
                pass_targets,
                pass_state,
                structure,
                inputs,
                spacing: self.slice_spacing,
                state: None,
                state_tiles: None,
            },
        );
        Ok(true)
    }

    /// Writes changed parameters; returns whether anything changed.
    fn sync_params(&mut self, inst: &PluginInstance) -> Result<bool, RenderError> {
        let Some(g) = self.instances.get(&inst.uid) else {
            return Ok(false);
        };
        if g.params == inst.params {
            return Ok(false);
        }
        let specs = inst.plugin.params();
        let layout = crate::params::UniformLayout::new(&specs);
        self.gpu
            .queue
            .write_buffer(&g.uniform, 0, &layout.pack(&specs, &inst.params));
        inst.plugin
            .update_resources(&self.gpu_init(), &inst.params, &g.resources)?;
        if let Some(g) = self.instances.get_mut(&inst.uid) {
            g.params = inst.params.clone();
        }
        Ok(true)
    }

    fn build_pipelines(
        &self,
        composition: Composition,
        target: TargetFormat,
    ) -> Result<CompiledStack, RenderError> {
        let device = &self.gpu.device;
        let fc = wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE;
        let layout_for = |group: u32, bindings: &[Binding], label: &str| {
            let entries: Vec<_> = bindings
                .iter()
                .filter(|b| b.group == group)
                .map(|b| b.layout_entry(fc))
                .collect();
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries: &entries,
            })
        };
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let g1_layout = layout_for(1, &composition.bindings, "vwb group 1 (plugins)");
        let g2_layout = layout_for(2, &composition.bindings, "vwb group 2 (slice state)");
        let g3_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vwb group 3 (compute output)"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: target.wgpu(),
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                    count: None,
                },
                storage_buffer_entry(1, false),
                // the march's part (`MarchPart`) and the loop limiter's counter
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(16),
                    },
                    count: None,
                },
                storage_buffer_entry(3, false),
            ],
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("vwb composed slice shader"),
            source: wgpu::ShaderSource::Wgsl(crate::composer::with_main_workgroup(
                composition.main.source.as_str(),
                self.main_workgroup,
            )),
        });
        // groups 0–2 and a group 3 of the entry point's own
        let layout_with = |label: &str, g3: &wgpu::BindGroupLayout| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &[
                    Some(&self.g0_layout),
                    Some(&g1_layout),
                    Some(&g2_layout),
                    Some(g3),
                ],
                immediate_size: 0,
            })
        };
        let raster_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("vwb raster"),
            bind_group_layouts: &[Some(&self.g0_layout), Some(&g1_layout), Some(&g2_layout)],
            immediate_size: 0,
        });
        let compute_layout = layout_with("vwb compute", &g3_layout);
        let raster = raster_pipeline(
            device,
            &module,
            &raster_layout,
            target,
            ("fs_main", 1, self.frame_from_vertex),
            None,
            UNDER,
        );
        let post = composition.post.then(|| {
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("vwb group 3 (post source)"),
                entries: &[wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                }],
            });
            let pipeline_layout = layout_with("vwb post", &layout);
            let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("vwb post"),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_post"),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs_post"),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: target.wgpu(),
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                primitive: Default::default(),
                depth_stencil: None,
                multisample: Default::default(),
                multiview_mask: None,
                cache: None,
            });
            (pipeline, layout)
        });
        let compute = |entry: &str, layout: &wgpu::PipelineLayout, m: &wgpu::ShaderModule| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(layout),
                module: m,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let cs_main = compute("cs_main", &compute_layout, &module);
        let cs_main_skip = compute("cs_main_skip", &compute_layout, &module);
        let cs_slice = compute("cs_slice", &compute_layout, &module);
        let cs_resolve = compute("cs_resolve", &compute_layout, &module);
        let cs_slice_fused = composition
            .instances
            .iter()
            .any(|i| i.update_entry.is_some())
            .then(|| compute(crate::composer::FUSED_SLICE_ENTRY, &compute_layout, &module));
        let cs_slice_state_only = cs_slice_fused
            .is_some()
            .then(|| compute(crate::composer::STATE_ONLY_ENTRY, &compute_layout, &module));
        let mut updates = Vec::new();
        let mut prepasses = Vec::new();
        let mut volume_passes = Vec::new();
        for (i, inst) in composition.instances.iter().enumerate() {
            for (k, vp) in inst.passes.iter().enumerate() {
                let mut entries = vec![wgpu::BindGroupLayoutEntry {
                    binding: vp.binding,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::StorageTexture {
                        access: if vp.accumulate || vp.sweep_binding.is_some() {
                            wgpu::StorageTextureAccess::ReadWrite
                        } else {
                            wgpu::StorageTextureAccess::WriteOnly
                        },
                        format: vp.format.wgpu(),
                        view_dimension: wgpu::TextureViewDimension::D3,
                    },
                    count: None,
                }];
                if let Some(b) = vp.sweep_binding {
                    entries.push(wgpu::BindGroupLayoutEntry {
                        binding: b,
                        visibility: wgpu::ShaderStages::COMPUTE,
                        ty: wgpu::BindingType::Buffer {
                            ty: wgpu::BufferBindingType::Uniform,
                            has_dynamic_offset: false,
                            min_binding_size: None,
                        },
                        count: None,
                    });
                }
                let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("vwb volume pass group 3"),
                    entries: &entries,
                });
                let pl = layout_with("vwb volume pass", &layout);
                volume_passes.push(CompiledPass {
                    instance: i,
                    k,
                    pipeline: compute(&vp.entry_point, &pl, &module),
                    layout,
                    binding: vp.binding,
                    sweep_binding: vp.sweep_binding,
                });
            }
            if let Some(entry) = &inst.update_entry {
                updates.push((i, compute(entry, &compute_layout, &module)));
            }
            if let Some((m, bindings)) = &inst.prepass {
                let pl = layout_for(1, bindings, "vwb prepass group 1");
                let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("vwb prepass"),
                    bind_group_layouts: &[Some(&self.g0_layout), Some(&pl)],
                    immediate_size: 0,
                });
                let pm = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("vwb prepass shader"),
                    source: wgpu::ShaderSource::Wgsl(m.source.as_str().into()),
                });
                prepasses.push((i, compute("prepass_main", &layout, &pm), pl));
            }
        }
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Compose(ComposeError::Limits {
                message: format!("the device rejected the composed pipeline: {err}"),
            }));
        }
        let scalar_reads = march_parts::scalar_reads(&composition.main.source);
        Ok(CompiledStack {
            composition,
            g1_layout,
            g2_layout,
            g3_layout,
            raster: {
                let locks: [std::sync::OnceLock<wgpu::RenderPipeline>; 16 * RASTER_GROUPS.len()] =
                    std::array::from_fn(|_| std::sync::OnceLock::new());
                let _ = locks[raster_index((false, false, false), 0, self.frame_from_vertex)]
                    .set(raster);
                locks
            },
            raster_chunks: Default::default(),
            module,
            raster_layout,
            compute_layout,
            cs_main_raw: std::sync::OnceLock::new(),
            scalar_reads,
            post,
            target,
            cs_main,
            cs_main_skip,
            cs_slice,
            cs_slice_fused,
            cs_slice_state_only,
            cs_resolve,
            updates,
            prepasses,
            volume_passes,
        })
    }

    /// A texture like the eye buffer for the raster backend's `post` pass to read.
    fn ensure_post_src(&mut self) {
        let Some(t) = self.target.as_ref() else {
            return;
        };
        let size = t.texture.size();
        if self
            .post_src
            .as_ref()
            .is_some_and(|(p, _)| p.size() == size && p.format() == t.texture.format())
        {
            return;
        }
        let texture = self.gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("vwb post source"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: t.texture.format(),
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        self.post_src = Some((texture, view));
    }

    fn ensure_target(&mut self, w: u32, h: u32, format: TargetFormat) -> Result<(), RenderError> {
        if self
            .target
            .as_ref()
            .is_some_and(|t| t.width == w && t.height == h && t.format == format)
        {
            return Ok(());
        }
        let bytes = target_bytes(w, h, format);
        let what = format!("the {w}×{h} {format:?} eye buffer");
        let freeing = self.target.as_ref().map_or(0, Target::bytes);
        self.check_budget(&what, bytes, freeing)?;
        let target =
            self.out_of_memory_scope(&what, bytes, || create_target(&self.gpu, w, h, format))?;
        self.target = Some(target);
        // state textures follow the eye buffer's size
        for g in self.instances.values_mut() {
            g.state = None;
            g.state_tiles = None;
        }
        Ok(())
    }
}

/// The eye buffer, its accumulation buffer and its display texture.
fn create_target(gpu: &GpuContext, w: u32, h: u32, format: TargetFormat) -> Target {
    let device = &gpu.device;
    let size = wgpu::Extent3d {
        width: w,
        height: h,
        depth_or_array_layers: 1,
    };
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("vwb eye buffer"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: format.wgpu(),
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::STORAGE_BINDING
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let view = texture.create_view(&Default::default());
    let accum = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("vwb accumulation"),
        size: w as u64 * h as u64 * 16,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let display = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("vwb display"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::STORAGE_BINDING
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let display_view = display.create_view(&Default::default());
    Target {
        width: w,
        height: h,
        format,
        texture,
        view,
        accum,
        display,
        display_view,
    }
}

impl Renderer {
    fn ensure_slice_info(&mut self, slices: u32) {
        let need = slices.max(1);
        if self.slice_info_slices >= need {
            return;
        }
        let n = need.next_power_of_two();
        let data: Vec<u8> = (0..n)
            .flat_map(|k| {
                let mut chunk = vec![0u8; SLICE_INFO_STRIDE as usize];
                chunk[..4].copy_from_slice(&k.to_le_bytes());
                chunk
            })
            .collect();
        self.slice_info = self
            .gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vwb slice info"),
                contents: &data,
                usage: wgpu::BufferUsages::UNIFORM,
            });
        self.slice_info_slices = n;
        self.rebuild_g0();
    }

    fn ensure_state(&mut self) {
        let Some(stack) = self.pipelines.as_ref().map(|p| p.stack.clone()) else {
            return;
        };
        self.ensure_state_of(&stack);
    }

    /// The per-slice state textures of the instances of `stack` that declare state, at
    /// the eye buffer's size (an atlas's tiles each have their own instances).
    fn ensure_state_of(&mut self, stack: &[(u64, Arc<dyn Plugin>)]) {
        let Some(t) = &self.target else {
            return;
        };
        for (uid, plugin) in stack {
            let Some(decl) = plugin.slice_state() else {
                continue;
            };
            let Some(g) = self.instances.get_mut(uid) else {
                continue;
            };
            if g.state.is_some() {
                continue;
            }
            let [w, h] = state_extent([t.width, t.height], decl.scale);
            let make = || {
                let tex = self.gpu.device.create_texture(&wgpu::TextureDescriptor {
                    label: Some("vwb slice state"),
                    size: wgpu::Extent3d {
                        width: w,
                        height: h,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: decl.format.wgpu(),
                    usage: wgpu::TextureUsages::STORAGE_BINDING
                        | wgpu::TextureUsages::TEXTURE_BINDING
                        | wgpu::TextureUsages::RENDER_ATTACHMENT
                        | wgpu::TextureUsages::COPY_SRC,
                    view_formats: &[],
                });
                let view = tex.create_view(&Default::default());
                (tex, view)
            };
            g.state = Some([make(), make()]);
            // one mark per tile; with tracking off every tile is marked for good (the
            // marks are then not cleared per frame)
            g.state_tiles = decl.track_clear.then(|| {
                let tiles = w.div_ceil(STATE_TILE) as u64 * h.div_ceil(STATE_TILE) as u64;
                let buf = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("vwb slice state tiles"),
                    size: tiles * 4,
                    usage: wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_DST
                        | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                if !self.state_tracking {
                    let marked = vec![0xff_u8; (tiles * 4) as usize];
                    self.gpu.queue.write_buffer(&buf, 0, &marked);
                }
                buf
            });
        }
    }

    /// Clears the per-slice state of the instances of `stack` that have one, before
    /// the first slice.
    fn encode_state_clear(&self, enc: &mut wgpu::CommandEncoder, stack: &[(u64, Arc<dyn Plugin>)]) {
        for (uid, plugin) in stack {
            let (Some(decl), Some(g)) = (plugin.slice_state(), self.instances.get(uid)) else {
                continue;
            };
            let Some(state) = &g.state else { continue };
            if let (Some(tiles), true) = (&g.state_tiles, self.state_tracking) {
                enc.clear_buffer(tiles, 0, None);
            }
            let c = decl.clear;
            let _clear = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("vwb clear state"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &state[0].1,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: c[0] as f64,
                            g: c[1] as f64,
                            b: c[2] as f64,
                            a: c[3] as f64,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                ..Default::default()
            });
        }
    }

    /// The sizes of the state textures the compiled stack's state updates write, for
    /// the instances `uids` (`None` where an instance has no state).
    fn state_sizes(&self, p: &CompiledStack, uids: &[u64]) -> Vec<Option<wgpu::Extent3d>> {
        p.updates
            .iter()
            .map(|(i, _)| {
                let g = self.instances.get(uids.get(*i)?)?;
                Some(g.state.as_ref()?[0].0.size())
            })
            .collect()
    }

    /// The state updates after slice `k`, one dispatch per state texel of each state
    /// (`sizes`: [`Renderer::state_sizes`]); `groups` are bind groups 0 (the frame,
    /// indexed by slice), 1, 2 (the slice's parity) and 3.
    #[allow(clippy::too_many_arguments)]
    fn encode_state_updates(
        &self,
        enc: &mut wgpu::CommandEncoder,
        p: &CompiledStack,
        sizes: &[Option<wgpu::Extent3d>],
        [g0, g1, g2, g3]: [&wgpu::BindGroup; 4],
        k: u32,
        eye: [u32; 2],
        exit: Option<&slice_exit::SliceExit>,
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("vwb state update"),
            timestamp_writes: None,
        });
        pass.set_bind_group(1, g1, &[]);
        pass.set_bind_group(2, g2, &[]);
        pass.set_bind_group(3, g3, &[]);
        // Where every state has the eye buffer's size, the updates evaluate the slice's
        // samples over its listed tiles where one can be visible (chunk k), and the
        // state-only entry point updates every state over its other listed tiles from
        // the pixels' placeholder samples, as the fused path does.
        let split = exit
            .filter(|x| x.eye_space)
            .zip(p.cs_slice_state_only.as_ref())
            .filter(|_| all_eye_sized(sizes, eye));
        if let Some((x, state_only)) = split {
            let n = x
                .workgroups(k)
                .unwrap_or((eye[0].div_ceil(8), eye[1].div_ceil(8)));
            pass.set_bind_group(0, g0, &[(k as u64 * SLICE_INFO_STRIDE) as u32]);
            if n.0 > 0 && n.1 > 0 {
                for (_, pipeline) in &p.updates {
                    pass.set_pipeline(pipeline);
                    pass.dispatch_workgroups(n.0, n.1, 1);
                }
            }
            x.encode_state_only(&mut pass, state_only, g0, k);
            return;
        }
        // with listed tiles, the slice's chunk that lists them all
        let (offset, listed) = match exit {
            Some(x) => x.updates(k),
            None => ((k as u64 * SLICE_INFO_STRIDE) as u32, None),
        };
        pass.set_bind_group(0, g0, &[offset]);
        let grid = exit.map(|x| x.size);
        for ((_, pipeline), size) in p.updates.iter().zip(sizes) {
            let Some(e) = size else { continue };
            // a state of the lists' grid size is updated over the slice's listed tiles
            let n = match listed {
                Some(n) if Some([e.width, e.height]) == grid => n,
                _ => (e.width.div_ceil(8), e.height.div_ceil(8)),
            };
            if n.0 > 0 && n.1 > 0 {
                pass.set_pipeline(pipeline);
                pass.dispatch_workgroups(n.0, n.1, 1);
            }
        }
    }

    /// The compute backend's slices under per-slice state, for the instances `uids`
    /// of the compiled stack `p` (their state cleared before): one dispatch per slice
    /// where every state has the eye buffer's resolution (the state texel is the
    /// pixel; the fused pipeline), else the slice and then each state update; then the
    /// resolve. `groups` are bind groups 0 (the frame, indexed by slice), 1 and 3, `g2`
    /// group 2 for even and odd slices ([`Renderer::group2_for`] of `uids`); `size`
    /// the eye buffer's; `view_aligned` false under half-angle slicing (no fused
    /// pipeline); `exit` the tiles the slices' dispatches cover
    /// ([`slice_exit::SliceExit`], whose buffers `g0` then binds), `None`: the eye
    /// buffer. Whether the fused pipeline ran.
    #[allow(clippy::too_many_arguments)]
    fn encode_compute_slices(
        &self,
        enc: &mut wgpu::CommandEncoder,
        p: &CompiledStack,
        uids: &[u64],
        [g0, g1, g3]: [&wgpu::BindGroup; 3],
        g2: &[wgpu::BindGroup; 2],
        count: u32,
        size: [u32; 2],
        view_aligned: bool,
        exit: Option<&slice_exit::SliceExit>,
    ) -> bool {
        let sizes = self.state_sizes(p, uids);
        // the fused pipeline updates the state texel under each pixel: the state must
        // be in eye-buffer space (not a half-angle frame's light space)
        let fused = p
            .cs_slice_fused
            .as_ref()
            .filter(|_| self.fused_slices && view_aligned && all_eye_sized(&sizes, size));
        let wg = (size[0].div_ceil(8), size[1].div_ceil(8));
        for k in 0..count {
            let parity = &g2[(k % 2) as usize];
            // the slice's dispatch (fused or not) covers its tiles where a sample can be
            // visible (elsewhere the slice changes nothing that is read again)
            let n = exit.and_then(|x| x.workgroups(k)).unwrap_or(wg);
            // and the updates alone over its tiles where no sample can be visible
            let state_only = fused
                .and(p.cs_slice_state_only.as_ref())
                .zip(exit.filter(|x| x.state_only(k).is_some()));
            if (n.0 > 0 && n.1 > 0) || state_only.is_some() {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_bind_group(1, g1, &[]);
                pass.set_bind_group(2, parity, &[]);
                pass.set_bind_group(3, g3, &[]);
                if n.0 > 0 && n.1 > 0 {
                    pass.set_pipeline(fused.unwrap_or(&p.cs_slice));
                    pass.set_bind_group(0, g0, &[(k as u64 * SLICE_INFO_STRIDE) as u32]);
                    pass.dispatch_workgroups(n.0, n.1, 1);
                }
                if let Some((pipeline, x)) = state_only {
                    x.encode_state_only(&mut pass, pipeline, g0, k);
                }
            }
            if fused.is_none() {
                self.encode_state_updates(enc, p, &sizes, [g0, g1, parity, g3], k, size, exit);
            }
        }
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(if count == 0 {
            &p.cs_main
        } else {
            &p.cs_resolve
        });
        pass.set_bind_group(0, g0, &[0]);
        pass.set_bind_group(1, g1, &[]);
        pass.set_bind_group(2, &g2[0], &[]);
        pass.set_bind_group(3, g3, &[]);
        let n = if count == 0 {
            let [mx, my] = self.main_workgroup;
            (size[0].div_ceil(mx), size[1].div_ceil(my))
        } else {
            wg
        };
        pass.dispatch_workgroups(n.0, n.1, 1);
        fused.is_some()
    }

    /// Bind group of group 1 (plugins) for the main pipeline.
    fn group1(&self, p: &Pipelines) -> wgpu::BindGroup {
        self.group1_for(p, &p.uids())
    }

    /// Bind group 1 of a compiled stack drawn by the instances `uids` (in stack order).
    fn group1_for(&self, p: &CompiledStack, uids: &[u64]) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = p
            .composition
            .bindings
            .iter()
            .filter(|b| b.group == 1)
            .filter_map(|b| self.bind_entry(uids, b, None))
            .collect();
        self.gpu
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vwb group 1"),
                layout: &p.g1_layout,
                entries: &entries,
            })
    }

    /// Bind groups of group 2 for even and odd slices.
    fn group2(&self, p: &Pipelines) -> [wgpu::BindGroup; 2] {
        self.group2_for(p, &p.uids())
    }

    /// Bind groups of group 2 of a compiled stack drawn by the instances `uids`, for
    /// even and odd slices.
    fn group2_for(&self, p: &CompiledStack, uids: &[u64]) -> [wgpu::BindGroup; 2] {
        [0usize, 1].map(|parity| {
            let entries: Vec<wgpu::BindGroupEntry> = p
                .composition
                .bindings
                .iter()
                .filter(|b| b.group == 2)
                .filter_map(|b| self.bind_entry(uids, b, Some(parity)))
                .collect();
            self.gpu
                .device
                .create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("vwb group 2"),
                    layout: &p.g2_layout,
                    entries: &entries,
                })
        })
    }

    fn bind_entry<'a>(
        &'a self,
        uids: &[u64],
        b: &Binding,
        parity: Option<usize>,
    ) -> Option<wgpu::BindGroupEntry<'a>> {
        let uid = *uids.get(b.instance)?;
        let g = self.instances.get(&uid)?;
        let resource = match b.role {
            BindingRole::Params => g.uniform.as_entire_binding(),
            BindingRole::Resource(i) => {
                wgpu::BindingResource::TextureView(&g.resources.get(i)?.view)
            }
            BindingRole::PrepassTarget => {
                wgpu::BindingResource::TextureView(&g.prepass_target.as_ref()?.1)
            }
            BindingRole::PassTarget(k) => {
                wgpu::BindingResource::TextureView(&g.pass_targets.get(k)?.1)
            }
            BindingRole::StatePrev => {
                wgpu::BindingResource::TextureView(&g.state.as_ref()?[parity.unwrap_or(0)].1)
            }
            BindingRole::StateNext => {
                wgpu::BindingResource::TextureView(&g.state.as_ref()?[1 - parity.unwrap_or(0)].1)
            }
            BindingRole::StateTiles => g.state_tiles.as_ref()?.as_entire_binding(),
        };
        Some(wgpu::BindGroupEntry {
            binding: b.binding,
            resource,
        })
    }

    fn write_frame(
        &self,
        s: &FrameSettings,
        plan: &FramePlan,
        view: &crate::camera::View,
    ) -> FrameUniform {
        let t = self.target.as_ref().expect("target exists");
        let u = self.frame_uniform(
            s,
            plan,
            view,
            [t.width, t.height],
            t.format,
            self.occupied(),
        );
        self.gpu
            .queue
            .write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&u));
        u
    }

    /// What empty-space skipping knows of the renderer's own stack (`None` when
    /// skipping is off).
    fn occupied(&self) -> Option<Occupied<'_>> {
        self.occupancy_bytes.as_deref().map(|bytes| Occupied {
            bytes,
            hull: self.occupied_hull.as_ref().map(|(h, share)| (h, *share)),
        })
    }

    /// The core uniform of a frame drawn into a `size` eye buffer of `format`, skipping
    /// empty space by `occupied` (the renderer's own stack's, or an atlas tile's; `None`
    /// when skipping is off).
    fn frame_uniform(
        &self,
        s: &FrameSettings,
        plan: &FramePlan,
        view: &crate::camera::View,
        size: [u32; 2],
        format: TargetFormat,
        occupied: Option<Occupied>,
    ) -> FrameUniform {
        let vp: Mat4 = view.view_proj();
        let occupancy = occupied.map(|o| o.bytes);
        // the compute backend's rays take samples only in the part of the box that can
        // be visible, none where nothing can be (a brick's own box is cut the same way by
        // its footprint)
        let (own, open) = match (&self.region, s.backend) {
            (None, Backend::Compute) => (
                self.visible_box_in(occupancy)
                    .unwrap_or_else(|| nowhere(self.vbox.voxel)),
                0,
            ),
            _ => self.own_box(),
        };
        // and, with skipping, only where their rays cross the occupied bricks' hull (the
        // raster backend's rays walk its bricks there for empty-space skipping)
        let hull = match (&self.region, occupied.and_then(|o| o.hull)) {
            (None, Some((dop, share))) if self.cuts_rays(share) => Some(hull_uniform(dop)),
            _ => None,
        };
        let rect = self.pixel_rect(view, size);
        let range = self.volume.range;
        let span = (range[1] - range[0]) as f32;
        let (half, plan) = (plan.half.as_ref(), &plan.slices);
        let n = half.map_or(view.forward, |h| h.normal);
        FrameUniform {
            view_proj: vp.to_cols_array(),
            ray_basis: ray_basis(view).to_cols_array(),
            eye: [
                view.eye.x,
                view.eye.y,
                view.eye.z,
                if view.perspective { 1.0 } else { 0.0 },
            ],
            forward: [view.forward.x, view.forward.y, view.forward.z, plan.spacing],
            box_min: [
                self.vbox.min.x,
                self.vbox.min.y,
                self.vbox.min.z,
                self.vbox.voxel,
            ],
            box_max: [self.vbox.max.x, self.vbox.max.y, self.vbox.max.z, plan.d0],
            viewport: [
                size[0] as f32,
                size[1] as f32,
                1.0 / size[0] as f32,
                1.0 / size[1] as f32,
            ],
            volume_dims: [
                self.volume.dims[0] as f32,
                self.volume.dims[1] as f32,
                self.volume.dims[2] as f32,
                0.0,
            ],
            value_range: [
                range[0] as f32,
                range[1] as f32,
                if span > 0.0 { 1.0 / span } else { 0.0 },
                0.0,
            ],
            counts: [
                plan.count,
                (format == TargetFormat::Rgba16Float) as u32,
                (s.backend == Backend::Compute && s.early_termination.is_some()) as u32,
                hull.is_some() as u32,
            ],
            settings: [
                s.early_termination.unwrap_or(1.0),
                if occupancy.is_some() {
                    crate::skipping::brick() as f32
                } else {
                    0.0
                },
                rect[0] as f32,
                rect[1] as f32,
            ],
            own_min: [own.min.x, own.min.y, own.min.z, 0.0],
            own_max: [own.max.x, own.max.y, own.max.z, open as f32],
            slicing: [n.x, n.y, n.z, half.is_some() as u32 as f32],
            light: half.map_or([0.0; 4], |h| h.light.extend(h.light_step).to_array()),
            state_rays: half.map_or([0.0; 16], |h| h.state_rays.to_cols_array()),
            inv_extent: (self.vbox.max - self.vbox.min)
                .recip()
                .extend(0.0)
                .to_array(),
            hull: hull.unwrap_or_default(),
            spread: {
                // the whole-frame dispatch's workgroup rows (`wg_own`, atlas tiles)
                let rows = (rect[3] - rect[1]).div_ceil(self.main_workgroup[1].max(1));
                [rows, spread_stride(rows), 0, 0]
            },
            // the grid of the occupancy this frame skips with (the header words of its
            // buffer, `upload_occupancy`); without skipping 1 × 1 × 1, which no shader
            // reads then (`frame.settings.y` is 0)
            bricks: match occupancy {
                Some(b) => occupancy_header(self.bricks.dims, b.len()),
                None => occupancy_header([1, 1, 1], 1),
            },
        }
    }

    /// The slices of a frame of `stack` seen from `view`: view-aligned, or halfway
    /// between the view and a light where an enabled instance with per-slice state names
    /// one ([`Plugin::slice_light`]; the first in stack order).
    fn frame_plan(
        &self,
        stack: &[(u64, Arc<dyn Plugin>)],
        view: &crate::camera::View,
        vbox: &VolumeBox,
        spacing: f32,
    ) -> Result<FramePlan, SliceError> {
        let light = stack.iter().find_map(|(uid, plugin)| {
            if !plugin.slice_state()?.light {
                return None;
            }
            plugin.slice_light(&self.instances.get(uid)?.params, view)
        });
        FramePlan::new(view, vbox, spacing, light)
    }

    /// The part of the box whose samples this renderer takes, and the axes whose max
    /// face it shares with the next brick (bit mask): the whole box and none unless
    /// the renderer draws one brick of a split volume.
    fn own_box(&self) -> (VolumeBox, u32) {
        match &self.region {
            Some(r) => (r.own, r.open),
            None => (self.vbox, 0),
        }
    }

    /// The boxes the raster backend's proxy polygons cover: its own box or, when
    /// empty-space skipping knows which bricks can be visible, the occupied cells
    /// ([`crate::skipping::occupied_cells`]) within it (none when nothing is visible).
    fn proxy_boxes(&self) -> Vec<VolumeBox> {
        let own = self.own_box().0;
        let Some(occupancy) = &self.occupancy_bytes else {
            return vec![own];
        };
        let cells = crate::skipping::occupied_cells(
            occupancy,
            self.bricks.dims,
            self.volume.dims,
            crate::skipping::proxy_cell(),
        );
        cells
            .into_iter()
            .filter_map(|r| {
                let b = bricks::sub_box(&self.vbox, self.volume.dims, r);
                let (min, max) = (b.min.max(own.min), b.max.min(own.max));
                (min.cmplt(max).all()).then_some(VolumeBox { min, max, ..own })
            })
            .collect()
    }

    /// The part of the own box (a brick's, or the whole volume's) where a sample can be
    /// visible: with empty-space skipping, the own box cut to the bounding box of its
    /// occupied bricks ([`crate::skipping::occupied_bounds`]), `None` when nothing in it
    /// can be visible; without, the own box. A brick draws only its footprint, and the
    /// compute backend's rays take samples only inside it.
    fn visible_box(&self) -> Option<VolumeBox> {
        self.visible_box_in(self.occupancy_bytes.as_deref())
    }

    /// [`Renderer::visible_box`] for an occupancy (the renderer's own stack's, or an
    /// atlas tile's).
    fn visible_box_in(&self, occupancy: Option<&[u8]>) -> Option<VolumeBox> {
        let own = self.own_box().0;
        let Some(occupancy) = occupancy else {
            return Some(own);
        };
        let r = crate::skipping::occupied_bounds(occupancy, self.bricks.dims, self.volume.dims)?;
        let b = bricks::sub_box(&self.vbox, self.volume.dims, r);
        let (min, max) = (b.min.max(own.min), b.max.min(own.max));
        min.cmplt(max)
            .all()
            .then_some(VolumeBox { min, max, ..own })
    }

    /// The pixels [x0, y0, x1, y1) this renderer's samples can cover in a `size` frame:
    /// the whole frame, or for a brick the footprint of the part of its own box that can
    /// be visible ([`Renderer::visible_box`]; no pixel when nothing can be visible).
    pub(super) fn pixel_rect(&self, view: &crate::camera::View, size: [u32; 2]) -> [u32; 4] {
        if self.region.is_none() {
            return [0, 0, size[0], size[1]];
        }
        match self.visible_box() {
            Some(visible) => box_footprint(&visible, view, size),
            None => [0; 4],
        }
    }

    /// The footprint of a brick's whole own box (the whole frame for a whole volume):
    /// what the refinement of bricks in view weighs, since a coarser level can hide
    /// what its finer level would show.
    pub(super) fn own_pixel_rect(&self, view: &crate::camera::View, size: [u32; 2]) -> [u32; 4] {
        match &self.region {
            Some(r) => box_footprint(&r.own, view, size),
            None => [0, 0, size[0], size[1]],
        }
    }

    /// The box the slice lattice is planned on: the whole volume's, also for a brick,
    /// so that the slices of all bricks lie on the same planes.
    fn lattice_box(&self) -> &VolumeBox {
        self.region.as_ref().map_or(&self.vbox, |r| &r.lattice)
    }

    /// Indices (in the stack) of the instances whose pre-pass is out of date: never run,
    /// or run with other values of the parameters it depends on.
    fn dirty_prepasses(&self, p: &CompiledStack, stack: &[(u64, Arc<dyn Plugin>)]) -> Vec<usize> {
        p.prepasses
            .iter()
            .filter(|(i, _, _)| {
                let (uid, plugin) = &stack[*i];
                let deps = plugin.prepass().map(|d| d.depends_on).unwrap_or_default();
                self.instances
                    .get(uid)
                    .is_some_and(|g| match &g.prepass_done {
                        None => true,
                        Some(done) => params_changed(&deps, done, &g.params),
                    })
            })
            .map(|(i, _, _)| *i)
            .collect()
    }

    /// Encodes the pre-passes of the instances at `dirty` (indices into `stack`), each
    /// after a `stamp`; returns their labels (`<plugin id>/prepass`).
    fn encode_prepasses(
        &self,
        enc: &mut wgpu::CommandEncoder,
        p: &CompiledStack,
        stack: &[(u64, Arc<dyn Plugin>)],
        dirty: &[usize],
        stamp: &mut dyn FnMut(&mut wgpu::CommandEncoder, Option<String>),
    ) -> Vec<String> {
        let device = &self.gpu.device;
        let mut run = Vec::new();
        for (i, pipeline, layout) in &p.prepasses {
            if !dirty.contains(i) {
                continue;
            }
            stamp(enc, Some(format!("prepass {}", stack[*i].1.id())));
            let uid = stack[*i].0;
            let g = &self.instances[&uid];
            let Some((_, bindings)) = &p.composition.instances[*i].prepass else {
                continue;
            };
            let Some((tex, _)) = &g.prepass_target else {
                continue;
            };
            let storage_view = tex.create_view(&Default::default());
            let entries: Vec<wgpu::BindGroupEntry> = bindings
                .iter()
                .filter_map(|b| {
                    let resource = match b.role {
                        BindingRole::Params => g.uniform.as_entire_binding(),
                        BindingRole::Resource(r) => {
                            wgpu::BindingResource::TextureView(&g.resources.get(r)?.view)
                        }
                        BindingRole::PrepassTarget => {
                            wgpu::BindingResource::TextureView(&storage_view)
                        }
                        _ => return None,
                    };
                    Some(wgpu::BindGroupEntry {
                        binding: b.binding,
                        resource,
                    })
                })
                .collect();
            let bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vwb prepass group 1"),
                layout,
                entries: &entries,
            });
            let size = tex.size();
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("vwb prepass"),
                timestamp_writes: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &self.g0, &[0]);
            pass.set_bind_group(1, &bg, &[]);
            pass.dispatch_workgroups(
                size.width.div_ceil(4),
                size.height.div_ceil(4),
                size.depth_or_array_layers.div_ceil(4),
            );
            run.push(format!("{}/prepass", stack[*i].1.id()));
        }
        run
    }

    /// The most refinement steps of progressive volume passes to run per frame
    /// (None, the default: all, so that one frame shows the finished result; a window
    /// sets a small budget and keeps drawing while [`Renderer::refining`]).
    pub fn set_refinement_budget(&mut self, steps: Option<u32>) {
        self.refinement_budget = steps;
        for c in self.split.iter_mut().flat_map(|sp| &mut sp.children) {
            c.renderer.refinement_budget = steps;
        }
    }

    /// Whether a volume pass of the current stack has steps left, or bricks refined in
    /// view are still to be rebuilt or drawn (a window keeps drawing until neither).
    pub fn refining(&self) -> bool {
        self.refinement_progress()
            .is_some_and(|(done, total)| done < total)
            || self.lod_refining()
    }

    /// Refinement steps of the current stack's volume passes done since their inputs
    /// last changed, and their total (None: the stack has no volume pass). Steps of a
    /// pass whose inputs changed since the last frame count as not done.
    pub fn refinement_progress(&self) -> Option<(u32, u32)> {
        if let Some(first) = self.brick_renderers().next() {
            // the bricks refine in step
            return first.refinement_progress();
        }
        let p = self.pipelines.as_ref()?;
        let mut out = None::<(u32, u32)>;
        for cp in &p.volume_passes {
            let (uid, plugin) = &p.stack[cp.instance];
            let Some(g) = self.instances.get(uid) else {
                continue;
            };
            let decl = &plugin.volume_passes()[cp.k];
            let st = &g.pass_state[cp.k];
            let total = pass_steps(decl, &g.params);
            let upstream = self.upstream_hash(&p.stack, *uid);
            let fresh = !pass_stale(st, decl, &g.params, upstream);
            let done = if fresh { st.steps_done.min(total) } else { 0 };
            let (d, t) = out.unwrap_or((0, 0));
            out = Some((d + done, t + total));
        }
        out
    }

    /// Hash of the parameters of the stack's clip, sample and classify instances other
    /// than `skip`: what `stack_classify` reads.
    fn upstream_hash(&self, stack: &[(u64, Arc<dyn Plugin>)], skip: u64) -> u64 {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        for (uid, plugin) in stack {
            if *uid == skip
                || !matches!(
                    plugin.category(),
                    Category::Clip | Category::Sample | Category::Classify
                )
            {
                continue;
            }
            plugin.id().hash(&mut h);
            if let Some(g) = self.instances.get(uid) {
                for (k, v) in &g.params.values {
                    k.hash(&mut h);
                    v.hash_into(&mut h);
                }
            }
        }
        h.finish()
    }

    /// Decides which volume-pass steps this frame runs and records them as run: a
    /// chain restarts at its first out-of-date pass; passes run in order, a later pass
    /// only once the earlier ones have all their steps. With `refine` false, a
    /// progressive pass that has run steps takes no more (an atlas's later tile of a
    /// stack it already planned: one frame's refinement budget per variant).
    fn plan_volume_passes(
        &mut self,
        p: &CompiledStack,
        stack: &[(u64, Arc<dyn Plugin>)],
        camera: u64,
        refine: bool,
    ) -> Vec<PassDispatch> {
        let mut out = Vec::new();
        let mut budget = self.refinement_budget.unwrap_or(u32::MAX).max(1);
        let mut index = 0;
        while index < p.volume_passes.len() {
            let instance = p.volume_passes[index].instance;
            let count = p.volume_passes[index..]
                .iter()
                .take_while(|cp| cp.instance == instance)
                .count();
            let (uid, plugin) = &stack[instance];
            let upstream = self.upstream_hash(stack, *uid);
            // a view pass's inputs include the camera
            let viewed = {
                use std::hash::{Hash, Hasher};
                let mut h = std::collections::hash_map::DefaultHasher::new();
                upstream.hash(&mut h);
                camera.hash(&mut h);
                h.finish()
            };
            let decls = plugin.volume_passes();
            let Some(g) = self.instances.get_mut(uid) else {
                index += count;
                continue;
            };
            let mut restart = false;
            for (k, decl) in decls.iter().enumerate().take(count) {
                let st = &mut g.pass_state[k];
                let upstream = if decl.camera { viewed } else { upstream };
                let stale = restart || pass_stale(st, decl, &g.params, upstream);
                if stale {
                    restart = true;
                    st.stamp = Some((g.params.clone(), upstream));
                    st.steps_done = 0;
                }
            }
            for (k, decl) in decls.iter().enumerate().take(count) {
                let total = pass_steps(decl, &g.params);
                if decl.sweep.is_some() {
                    // every plane in this frame, in order, outside the refinement budget
                    let planes =
                        sweep_of(&self.volume, decl, &g.params, &g.pass_targets[k].0).planes();
                    let st = &mut g.pass_state[k];
                    if st.steps_done == 0 {
                        out.extend((0..planes).map(|step| PassDispatch {
                            pass: index + k,
                            step,
                        }));
                        st.steps_done = 1;
                    }
                    continue;
                }
                let st = &mut g.pass_state[k];
                let held = !refine && decl.steps.is_some() && st.steps_done > 0;
                while st.steps_done < total && budget > 0 && !held {
                    out.push(PassDispatch {
                        pass: index + k,
                        step: st.steps_done,
                    });
                    st.steps_done += 1;
                    if decl.steps.is_some() {
                        budget -= 1;
                    }
                }
                if st.steps_done < total {
                    break;
                }
            }
            index += count;
        }
        // the dispatches index the slice-info buffer by step
        if let Some(last) = out.iter().map(|d| d.step + 1).max() {
            self.ensure_slice_info(last);
        }
        out
    }

    /// Encodes planned volume-pass dispatches, each after a `stamp`, with `g0` (the
    /// frame whose camera a view pass reads) as group 0.
    #[allow(clippy::too_many_arguments)]
    fn encode_volume_passes(
        &self,
        enc: &mut wgpu::CommandEncoder,
        p: &CompiledStack,
        stack: &[(u64, Arc<dyn Plugin>)],
        plan: &[PassDispatch],
        g0: &wgpu::BindGroup,
        stamp: &mut dyn FnMut(&mut wgpu::CommandEncoder, Option<String>),
    ) -> Vec<String> {
        let device = &self.gpu.device;
        let uids: Vec<u64> = stack.iter().map(|(u, _)| *u).collect();
        let mut labels = Vec::new();
        let g2 = {
            let entries: Vec<wgpu::BindGroupEntry> = p
                .composition
                .bindings
                .iter()
                .filter(|b| b.group == 2)
                .filter_map(|b| self.bind_entry(&uids, b, Some(0)))
                .collect();
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vwb volume pass group 2"),
                layout: &p.g2_layout,
                entries: &entries,
            })
        };
        let mut bound: Option<(usize, PassGroups)> = None;
        for d in plan {
            let cp = &p.volume_passes[d.pass];
            let (uid, plugin) = &stack[cp.instance];
            let Some(g) = self.instances.get(uid) else {
                continue;
            };
            let Some((tex, _)) = g.pass_targets.get(cp.k) else {
                continue;
            };
            let label = format!("{}/{}", plugin.id(), plugin.volume_passes()[cp.k].target);
            // a sweep's planes share one stamp and one set of bind groups
            if bound.as_ref().is_none_or(|b| b.0 != d.pass) {
                stamp(enc, Some(format!("pass {label}")));
                bound = Some((
                    d.pass,
                    self.volume_pass_groups(p, &uids, cp, g, plugin.as_ref(), tex),
                ));
            }
            let Some((_, (g1, g3, sweep_info))) = &bound else {
                continue;
            };
            let size = tex.size();
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("vwb volume pass"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&cp.pipeline);
            pass.set_bind_group(0, g0, &[(d.step as u64 * SLICE_INFO_STRIDE) as u32]);
            pass.set_bind_group(1, g1, &[]);
            pass.set_bind_group(2, &g2, &[]);
            pass.set_bind_group(3, g3, &[]);
            if let Some((sw, _)) = sweep_info {
                // one plane
                let [w, h] = sw.plane_size();
                pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
                drop(pass);
                // a sweep's planes count as one run of the pass
                if d.step + 1 == sw.planes() {
                    labels.push(label);
                }
                continue;
            }
            pass.dispatch_workgroups(
                size.width.div_ceil(4),
                size.height.div_ceil(4),
                size.depth_or_array_layers.div_ceil(4),
            );
            labels.push(label);
        }
        labels
    }

    /// The bind groups 1 and 3 of a volume pass (its own target replaced in group 1,
    /// its storage view in group 3) and a sweep pass's geometry with its uniform.
    fn volume_pass_groups(
        &self,
        p: &CompiledStack,
        uids: &[u64],
        cp: &CompiledPass,
        g: &InstanceGpu,
        plugin: &dyn Plugin,
        tex: &wgpu::Texture,
    ) -> PassGroups {
        let device = &self.gpu.device;
        // group 1 with the pass's own target replaced (it is written, not read)
        let entries: Vec<wgpu::BindGroupEntry> = p
            .composition
            .bindings
            .iter()
            .filter(|b| b.group == 1)
            .filter_map(|b| {
                if b.instance == cp.instance && b.role == BindingRole::PassTarget(cp.k) {
                    return Some(wgpu::BindGroupEntry {
                        binding: b.binding,
                        resource: wgpu::BindingResource::TextureView(&self.dummy_3d.1),
                    });
                }
                self.bind_entry(uids, b, None)
            })
            .collect();
        let g1 = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vwb volume pass group 1"),
            layout: &p.g1_layout,
            entries: &entries,
        });
        let storage = tex.create_view(&Default::default());
        let decl = &plugin.volume_passes()[cp.k];
        let sweep = cp
            .sweep_binding
            .map(|b| (b, sweep_of(&self.volume, decl, &g.params, tex)));
        let sweep_info = sweep.map(|(b, sw)| {
            let mut info = [0u8; 32];
            let words: [u32; 6] = [
                sw.axis as u32,
                sw.ascending as u32,
                (sw.length as f32).to_bits(),
                (sw.boundary as f32).to_bits(),
                (sw.shift[0] as f32).to_bits(),
                (sw.shift[1] as f32).to_bits(),
            ];
            for (i, w) in words.iter().enumerate() {
                info[i * 4..i * 4 + 4].copy_from_slice(&w.to_le_bytes());
            }
            let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vwb sweep info"),
                contents: &info,
                usage: wgpu::BufferUsages::UNIFORM,
            });
            (b, sw, buffer)
        });
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: cp.binding,
            resource: wgpu::BindingResource::TextureView(&storage),
        }];
        if let Some((b, _, buffer)) = &sweep_info {
            entries.push(wgpu::BindGroupEntry {
                binding: *b,
                resource: buffer.as_entire_binding(),
            });
        }
        let g3 = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vwb volume pass group 3"),
            layout: &cp.layout,
            entries: &entries,
        });
        (g1, g3, sweep_info.map(|(_, sw, buffer)| (sw, buffer)))
    }

    /// Records that the pre-passes of `uids` ran with their instances' parameters.
    fn mark_prepasses_done(&mut self, uids: impl IntoIterator<Item = u64>) {
        for uid in uids {
            if let Some(g) = self.instances.get_mut(&uid) {
                g.prepass_done = Some(g.params.clone());
            }
        }
    }

    /// The slice plan for settings (what the frame will draw).
    pub fn plan(&self, s: &FrameSettings) -> Result<SlicePlan, RenderError> {
        Ok(self.frame_plan_for(s)?.slices)
    }

    /// The slice plan for settings and, under half-angle slicing, its geometry.
    pub fn frame_plan_for(&self, s: &FrameSettings) -> Result<FramePlan, RenderError> {
        let view = s.camera.view(s.width as f32 / s.height.max(1) as f32);
        Ok(self.current_frame_plan(&view, s.slice_spacing)?)
    }

    /// [`Self::frame_plan`] of the current (last good) stack over the lattice box.
    fn current_frame_plan(
        &self,
        view: &crate::camera::View,
        spacing: f32,
    ) -> Result<FramePlan, SliceError> {
        let stack = self.pipelines.as_ref().map_or(&[][..], |p| &p.stack[..]);
        self.frame_plan(stack, view, self.lattice_box(), spacing)
    }

    /// Renders one frame into the eye buffer with the current (last good) pipeline. On
    /// a CPU device, a frame whose loops ran out of llvmpipe's loop iterations
    /// ([`FrameStats::loop_limited`]) is rendered again in smaller parts
    /// ([`march_parts`]) until none does, or one slice per part is reached.
    pub fn render(&mut self, s: &FrameSettings) -> Result<FrameStats, RenderError> {
        loop {
            let stats = self.render_once(s)?;
            if stats.loop_limited == 0 || !self.shrink_march_parts(stats.slices) {
                if stats.loop_limited > 0 {
                    warn_loop_limited(stats.loop_limited);
                }
                return Ok(stats);
            }
        }
    }

    fn render_once(&mut self, s: &FrameSettings) -> Result<FrameStats, RenderError> {
        if let Some(reason) = self.gpu.lost() {
            return Err(RenderError::DeviceLost(reason));
        }
        let max = self.gpu.limits.max_texture_dimension_2d;
        if s.width == 0 || s.height == 0 || s.width > max || s.height > max {
            return Err(RenderError::BadSize(s.width, s.height, max));
        }
        if self.split.is_some() {
            return self.render_split(s);
        }
        if self.pipelines.is_none() {
            self.apply_stack(&[], TargetFormat::default())?;
        }
        let mut enc = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("vwb frame"),
            });
        let rec = self.record(s, &mut enc, true)?;
        self.gpu.queue.submit([enc.finish()]);
        let n_stamps = rec.ts_labels.len() as u32;
        let (start, ts_labels) = (rec.start, rec.ts_labels.clone());
        let mut stats = self.submitted(rec);
        if let Some((_, _, read)) = &self.timestamps
            && n_stamps > 1
        {
            let ticks = read_ticks(&self.gpu, read, n_stamps);
            let ms = |a: u64, b: u64| ticks_ms(&self.gpu, a, b);
            for i in 0..ticks.len() - 1 {
                stats
                    .gpu_passes
                    .push((ts_labels[i].clone(), ms(ticks[i], ticks[i + 1])));
            }
            stats.gpu_ms = Some(ms(ticks[0], ticks[ticks.len() - 1]));
        } else {
            self.gpu.wait();
        }
        stats.wall_ms = start.elapsed().as_secs_f64() * 1e3;
        if stats.march_parts > 0 && self.gpu.info.device_type == wgpu::DeviceType::Cpu {
            stats.loop_limited = self.march.read(&self.gpu);
        }
        Ok(stats)
    }

    /// Encodes one frame into `enc` (pre-passes and volume passes that are due, then
    /// the slices into the eye buffer) after writing its uniforms and proxy polygons.
    /// With `timed`, GPU timestamps are written and resolved too. The caller submits
    /// `enc` and then hands the result to [`Renderer::submitted`].
    fn record(
        &mut self,
        s: &FrameSettings,
        enc: &mut wgpu::CommandEncoder,
        timed: bool,
    ) -> Result<Recorded, RenderError> {
        let target_format = self
            .pipelines
            .as_ref()
            .map(|p| p.key.target)
            .unwrap_or_default();
        if s.backend == Backend::Raster
            && target_format == TargetFormat::Rgba32Float
            && !self
                .gpu
                .features
                .contains(wgpu::Features::FLOAT32_BLENDABLE)
        {
            return Err(RenderError::NoFloat32Blending);
        }
        crate::validate::check_camera(&s.camera)?;
        let view = s.camera.view(s.width as f32 / s.height as f32);
        let frame_plan = self.current_frame_plan(&view, s.slice_spacing)?;
        let plan = frame_plan.slices;
        let spacing_updates = self.sync_spacing(frame_plan.ray_spacing() / self.vbox.voxel)?;
        // the occupancy's apron for moved samples and slabs follows the longest step
        // between slices along the frame's rays (the spacing, the view's width and,
        // under half-angle slicing, the light): made again where the apron changes, or
        // where the clip regions' widening must grow
        let ray_step = frame_plan.max_ray_step(&view) / self.vbox.voxel;
        let moves = self.occupancy_moves;
        if moves > 0.0
            && (move_apron(moves, ray_step) != self.occupancy_apron
                || ray_step > self.occupancy_ray_step)
        {
            self.occupancy_ray_step = ray_step;
            let stack = std::mem::take(&mut self.occupancy_stack);
            self.update_occupancy(&stack);
        }
        self.ensure_target(s.width, s.height, target_format)?;
        // the copy of the eye buffer that a raster post pass reads; freed for stacks
        // without one
        if s.backend == Backend::Raster
            && self
                .pipelines
                .as_ref()
                .is_some_and(|p| p.compiled.post.is_some())
        {
            self.ensure_post_src();
        } else {
            self.post_src = None;
        }
        self.ensure_state();
        let per_slice = self
            .pipelines
            .as_ref()
            .is_some_and(|p| !p.updates.is_empty());
        if per_slice {
            if plan.count > MAX_PER_SLICE_SLICES {
                return Err(RenderError::TooManyPerSliceSlices {
                    count: plan.count,
                    max: MAX_PER_SLICE_SLICES,
                });
            }
            self.ensure_slice_info(plan.count);
        }
        let pass_plan = match &self.pipelines {
            Some(p) if !p.volume_passes.is_empty() => {
                let (compiled, stack) = (p.compiled.clone(), p.stack.clone());
                self.plan_volume_passes(&compiled, &stack, camera_key(&view), true)
            }
            _ => Vec::new(),
        };
        let frame_u = self.write_frame(s, &frame_plan, &view);
        // the orders in which the raster backend blends the slices: "under" (front to
        // back), or for half-angle slices "over" where the eye meets them from behind,
        // and both (each pixel drawn by its own order's pipeline) where the view's rays
        // meet them in both orders
        let raster_orders: &[bool] = match (s.backend, &frame_plan.half) {
            (Backend::Raster, Some(_)) => match frame_plan.back_to_front(&view, &self.vbox) {
                Some(false) => &[false],
                Some(true) => &[true],
                None => &[false, true],
            },
            _ => &[false],
        };
        let et_interval = raster_et::interval();
        // proxy polygons cut to the occupied cells, fragments at their exact points
        let cut_proxy =
            s.backend == Backend::Raster && self.occupied_proxy && self.occupancy_bytes.is_some();
        // the raster backend's empty-space skipping by the depth mask: view-aligned
        // slices (their depth is their index) on proxies not cut to the occupied cells,
        // a whole volume (the bricks of a split one would each hold a depth buffer and
        // chunk bits of the eye buffer's size)
        let raster_skip = s.backend == Backend::Raster
            && self.raster_skipping
            && self.region.is_none()
            && self.occupancy_bytes.is_some()
            && !cut_proxy
            && frame_plan.half.is_none()
            && {
                // its depth and chunk bits within the GPU memory budget, or no skipping
                let eye = self.target.as_ref().expect("target exists");
                let held = self
                    .raster_et
                    .as_ref()
                    .map_or(0, raster_et::RasterEt::bytes);
                let need = raster_et::RasterEt::bytes_for([eye.width, eye.height], true);
                self.check_budget("raster skipping", need, held).is_ok()
            };
        // the raster backend's depth mask (early termination, skipping): its bind group
        // for this eye buffer; a ray composited "over" cannot terminate early
        let mask_group = match s.backend {
            Backend::Raster
                if raster_orders == [false] && (raster_skip || s.early_termination.is_some()) =>
            {
                let et = self
                    .raster_et
                    .get_or_insert_with(|| raster_et::RasterEt::new(&self.gpu.device));
                let eye = self.target.as_ref().expect("target exists");
                let plan = raster_et::MaskPlan {
                    count: plan.count,
                    et: s.early_termination.map(|t| (t, et_interval)),
                    skip: raster_skip,
                };
                Some(et.prepare(&self.gpu, eye, plan))
            }
            _ => {
                // a frame without the mask holds none of its buffers
                if let Some(et) = self.raster_et.as_mut() {
                    et.release();
                }
                None
            }
        };

        // vertices for the raster backend
        let mut slice_ranges = Vec::new();
        // per slice, the pixels [x, y, w, h] it can cover (empty: none), when known
        let mut slice_rects: Vec<[u32; 4]> = Vec::new();
        let mut scissor_share = None;
        let mut proxy_share = None;
        let mut fused_run = false;
        // slices per proxy polygon this frame ([`Renderer::set_raster_group`])
        let mut group = 1;
        if s.backend == Backend::Raster {
            let own = self.own_box().0;
            // the proxies cover only what can be visible: the occupied cells, or the
            // visible box (the own box cut to the occupied bricks' bounds; nothing when
            // nothing can be visible), as the compute backend's rays do
            let boxes = if cut_proxy {
                self.proxy_boxes()
            } else {
                self.visible_box().into_iter().collect()
            };
            let volume = |b: &VolumeBox| (b.max - b.min).as_dvec3().element_product();
            // the visible box's polygons fitted further to the occupied bricks' hull
            let hull = match (self.occupied_hull.as_ref().map(|(h, _)| h), boxes.first()) {
                (Some(hull), Some(b)) if !cut_proxy && self.hull_proxy != HullProxy::Off => {
                    Some((hull, b))
                }
                _ => None,
            };
            let cut_to_hull = hull.is_some() && self.hull_proxy == HullProxy::Cut;
            // several slices per polygon (§9.1) on the whole proxies of view-aligned
            // frames without per-slice state; a group within every run between masks
            let asked = raster_group_for(self.raster_group, s.early_termination);
            if asked > 1
                && !per_slice
                && !cut_proxy
                && !cut_to_hull
                && frame_plan.half.is_none()
                && boxes.len() == 1
            {
                let mut n = asked;
                let runs = [
                    raster_skip.then(|| raster_et::skip_interval_for(asked)),
                    s.early_termination.map(|_| et_interval),
                ];
                while n > 1 && runs.iter().flatten().any(|r| !r.is_multiple_of(n)) {
                    n /= 2;
                }
                group = n;
            }
            let tris = match hull {
                Some((hull, b)) if cut_to_hull => {
                    plan.triangles_in_dop(b, hull, HULL_SLIVER * self.vbox.voxel)
                }
                _ if group > 1 => plan.group_triangles(&boxes[0], group, view.perspective),
                _ => plan.triangles_in(&boxes),
            };
            // under the scissor: per slice, the pixels its part inside the hull can cover
            if let (Some((hull, b)), false) = (hull, cut_to_hull) {
                let t = self.target.as_ref().expect("target exists");
                let vp = view.view_proj();
                let size = [t.width, t.height];
                slice_rects = (0..plan.count)
                    .map(|k| {
                        let poly = hull.clip(plan.polygon(b, k));
                        coarse_rect(crate::slicing::screen_rect(&poly, vp, size), size)
                    })
                    .collect();
                // a group's polygon (at its first slice) under its slices' rects
                if group > 1 {
                    for k0 in (0..plan.count).step_by(group as usize) {
                        let k1 = (k0 + group).min(plan.count);
                        let rects = slice_rects[k0 as usize..k1 as usize].iter();
                        let drawn = rects.filter(|r| r[2] > 0 && r[3] > 0).copied();
                        slice_rects[k0 as usize] = rect_union(drawn).unwrap_or([0; 4]);
                    }
                }
            }
            let covered = if cut_to_hull {
                // the polygons' area times the slice spacing
                let area = |t: &[(glam::Vec3, u32)]| {
                    0.5 * (t[1].0 - t[0].0).cross(t[2].0 - t[0].0).length() as f64
                };
                tris.chunks_exact(3).map(area).sum::<f64>() * plan.spacing as f64
            } else {
                boxes.iter().map(volume).sum::<f64>()
            };
            proxy_share = Some(covered / volume(&own).max(f64::MIN_POSITIVE));
            let mut data = Vec::with_capacity(tris.len() * 16);
            let mut last = u32::MAX;
            for (i, (p, k)) in tris.iter().enumerate() {
                if *k != last {
                    slice_ranges.push((*k, i as u32, i as u32));
                    last = *k;
                }
                if let Some(r) = slice_ranges.last_mut() {
                    r.2 = i as u32 + 1;
                }
                data.extend_from_slice(bytemuck::cast_slice(&p.to_array()));
                data.extend_from_slice(&k.to_le_bytes());
            }
            // the share of the frame the scissors leave, over the slices with polygons
            if !slice_rects.is_empty() {
                let t = self.target.as_ref().expect("target exists");
                let frame = t.width as f64 * t.height as f64;
                let drawn = slice_ranges.iter().map(|&(k, _, _)| {
                    let [_, _, w, h] = slice_rects[k as usize];
                    w as f64 * h as f64 / frame
                });
                scissor_share = Some(drawn.sum::<f64>() / slice_ranges.len().max(1) as f64);
            }
            let need = (data.len() as u64).max(16);
            if self.vertices.as_ref().is_none_or(|(_, cap)| *cap < need) {
                let cap = need.next_power_of_two();
                let buf = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("vwb proxy polygons"),
                    size: cap,
                    usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                self.vertices = Some((buf, cap));
            }
            if let Some((buf, _)) = &self.vertices
                && !data.is_empty()
            {
                self.gpu.queue.write_buffer(buf, 0, &data);
            }
        }

        let start = Instant::now();
        let p = self.pipelines.as_ref().expect("pipeline exists");
        let t = self.target.as_ref().expect("target exists");
        let device = &self.gpu.device;
        let ts = self.timestamps.as_ref().filter(|_| timed);
        let mut ts_labels: Vec<String> = Vec::new();
        let mut stamp = |enc: &mut wgpu::CommandEncoder, label: Option<String>| {
            if let Some((qs, _, _)) = ts {
                let idx = ts_labels.len() as u32;
                if idx < MAX_TIMESTAMPS {
                    enc.write_timestamp(qs, idx);
                    ts_labels.push(label.unwrap_or_default());
                }
            }
        };

        // pre-passes that are out of date, then volume passes
        let dirty = self.dirty_prepasses(p, &p.stack);
        let prepasses = self.encode_prepasses(enc, p, &p.stack, &dirty, &mut stamp);
        let volume_passes_run =
            self.encode_volume_passes(enc, p, &p.stack, &pass_plan, &self.g0, &mut stamp);

        let g1 = self.group1(p);
        let g2 = self.group2(p);
        // the whole-frame march in parts (on a CPU device, for its loop limiter)
        let whole_march = s.backend == Backend::Compute && !per_slice;
        let parts = if whole_march {
            self.march_parts(&p.compiled, &p.stack, plan.count)
        } else {
            vec![[0, 0]]
        };
        let g3s = self
            .march
            .groups(device, &p.g3_layout, &t.view, &t.accum, &parts);
        let g3 = &g3s[0];

        stamp(enc, Some("slices".to_string()));
        if per_slice {
            self.encode_state_clear(enc, &p.stack);
        }
        // a brick dispatches its footprint only (offset in frame.settings.zw)
        let rect = self.pixel_rect(&view, [t.width, t.height]);
        // cs_main and cs_main_skip run in workgroups of the renderer's shape
        let [mx, my] = self.main_workgroup;
        let wg_own = (
            (rect[2] - rect[0]).div_ceil(mx),
            (rect[3] - rect[1]).div_ceil(my),
        );
        // a brick's raster passes shade its footprint only (the composite reads no other)
        let scissor = (self.region.is_some() && rect[2] > rect[0] && rect[3] > rect[1])
            .then(|| [rect[0], rect[1], rect[2] - rect[0], rect[3] - rect[1]]);
        let state_sizes = if per_slice {
            self.state_sizes(p, &p.uids())
        } else {
            Vec::new()
        };
        // the scissor of slice k: the frame (a brick's footprint), cut to the slice's
        // rect where known; `None` when the slice can cover no pixel
        let slice_scissor = |k: u32| -> Option<[u32; 4]> {
            let frame = scissor.unwrap_or([0, 0, t.width, t.height]);
            let [x, y, w, h] = match slice_rects.get(k as usize) {
                Some(&[x, y, w, h]) => {
                    let (x0, y0) = (x.max(frame[0]), y.max(frame[1]));
                    let x1 = (x + w).min(frame[0] + frame[2]);
                    let y1 = (y + h).min(frame[1] + frame[3]);
                    [x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0)]
                }
                None => frame,
            };
            (w > 0 && h > 0).then_some([x, y, w, h])
        };
        // per-slice state: the tiles each slice's dispatches cover, with the frame's own
        // slice info to list them
        let eye = [t.width, t.height];
        let exit = per_slice
            .then(|| {
                let u = &frame_u;
                self.slice_exit_info(&p.stack, &frame_plan, &view, u, eye, self.occupied())
            })
            .flatten();
        let g0_exit = exit
            .as_ref()
            .map(|x| self.g0_with(&self.frame_buf, [&x.info, &x.list], &self.occupancy));
        let run_updates = |enc: &mut wgpu::CommandEncoder, k: u32| {
            let g0 = g0_exit.as_ref().unwrap_or(&self.g0);
            let groups = [g0, &g1, &g2[(k % 2) as usize], g3];
            self.encode_state_updates(enc, p, &state_sizes, groups, k, eye, exit.as_ref());
        };
        match s.backend {
            Backend::Raster => {
                let vbuf = &self.vertices.as_ref().expect("vertex buffer").0;
                // with early termination: the depth mask, the slice pipeline that tests it
                let et = mask_group.as_ref().zip(self.raster_et.as_ref());
                let raster: Vec<&wgpu::RenderPipeline> = raster_orders
                    .iter()
                    .map(|&over| {
                        p.raster_for(
                            device,
                            (et.is_some(), cut_proxy, over),
                            group,
                            self.frame_from_vertex,
                        )
                    })
                    .collect();
                let begin = |enc: &'_ mut wgpu::CommandEncoder, clear: bool| {
                    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                        label: Some("vwb slices"),
                        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                            view: &t.view,
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations {
                                load: if clear {
                                    wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT)
                                } else {
                                    wgpu::LoadOp::Load
                                },
                                store: wgpu::StoreOp::Store,
                            },
                        })],
                        depth_stencil_attachment: et.map(|(_, et)| et.attachment(clear)),
                        ..Default::default()
                    })
                    .forget_lifetime()
                };
                // the first slices of the runs between masks: with skipping, the first
                // run's too
                let starts = raster_et::run_starts(
                    plan.count,
                    raster_skip.then(|| raster_et::skip_interval_for(group)),
                    s.early_termination.and(et).map(|_| et_interval),
                );
                let masked = |k: u32| (k > 0 || raster_skip) && starts.binary_search(&k).is_ok();
                // the pixels that slices k.. can cover: a mask pass before slice k need
                // touch no other (no later slice tests their depth), so it is scissored
                // to them; none, and it is left out
                let mut remaining = vec![None; plan.count as usize + 1];
                if et.is_some() {
                    for k in (0..plan.count).rev() {
                        let later = remaining[k as usize + 1];
                        remaining[k as usize] =
                            rect_union(slice_scissor(k).into_iter().chain(later));
                    }
                }
                let mask = |enc: &mut wgpu::CommandEncoder, first: u32| {
                    if let (Some((group, et)), Some(rect)) = (et, remaining[first as usize]) {
                        et.encode_mask(enc, group, first, rect);
                    }
                };
                // per slice: clear first (the first run's mask raises a cleared depth)
                if per_slice {
                    drop(begin(enc, true));
                }
                // the chunk bits, in the pixels a slice can cover (those of slices 0..)
                if raster_skip && let (Some((_, et)), Some(rect)) = (et, remaining[0]) {
                    let groups = [&self.g0, &g1, &g2[0]];
                    et.encode_chunks(
                        enc,
                        p.chunks_pipeline(device, self.frame_from_vertex),
                        groups,
                        rect,
                    );
                }
                if per_slice {
                    // one pass per slice followed by the updates (and a mask before every
                    // run of slices)
                    for k in 0..plan.count {
                        if masked(k) {
                            mask(enc, k);
                        }
                        if let Some(&(_, a, b)) = slice_ranges.iter().find(|r| r.0 == k)
                            && let Some([x, y, w, h]) = slice_scissor(k)
                        {
                            let mut pass = begin(enc, false);
                            pass.set_scissor_rect(x, y, w, h);
                            pass.set_bind_group(0, &self.g0, &[0]);
                            pass.set_bind_group(1, &g1, &[]);
                            pass.set_bind_group(2, &g2[(k % 2) as usize], &[]);
                            pass.set_vertex_buffer(0, vbuf.slice(..));
                            for pipeline in &raster {
                                pass.set_pipeline(pipeline);
                                pass.draw(a..b, 0..1);
                            }
                        }
                        run_updates(enc, k);
                    }
                } else {
                    // one pass; with termination, a new one at every run whose mask
                    // reads the eye buffer (a pass of its own); a mask that only skips
                    // is drawn inside the pass, where the run's slices can be drawn
                    let frame_rect = scissor.unwrap_or([0, 0, t.width, t.height]);
                    let terminates = |k: u32| {
                        s.early_termination.is_some()
                            && et.is_some()
                            && k > 0
                            && k.is_multiple_of(et_interval)
                    };
                    let mut open: Option<wgpu::RenderPass<'static>> = None;
                    for (r, &k0) in starts.iter().enumerate() {
                        let k1 = starts.get(r + 1).copied().unwrap_or(plan.count);
                        let in_run = slice_ranges.iter().filter(|s| s.0 >= k0 && s.0 < k1);
                        // the run's draws: each slice in the pixels it can cover, one draw
                        // per run of neighbouring slices under the same scissor (the
                        // rects are coarse so that neighbours share them; a draw costs
                        // llvmpipe its set-up)
                        let mut draws: Vec<([u32; 4], u32, u32)> = Vec::new();
                        if slice_rects.is_empty() {
                            let a = in_run.clone().map(|s| s.1).min();
                            let b = in_run.map(|s| s.2).max();
                            if let (Some(a), Some(b)) = (a, b) {
                                draws.push((frame_rect, a, b));
                            }
                        } else {
                            for &(k, a, b) in in_run {
                                let Some(rect) = slice_scissor(k) else {
                                    continue;
                                };
                                match draws.last_mut() {
                                    Some(d) if d.0 == rect && d.2 == a => d.2 = b,
                                    _ => draws.push((rect, a, b)),
                                }
                            }
                        }
                        let ends_pass = terminates(k0);
                        if ends_pass || open.is_none() {
                            drop(open.take());
                            if ends_pass {
                                mask(enc, k0);
                            }
                            open = Some(begin(enc, r == 0));
                        }
                        let pass = open.as_mut().expect("a slice pass is open");
                        if raster_skip
                            && !ends_pass
                            && let (Some((groups, et)), Some(rect)) =
                                (et, rect_union(draws.iter().map(|d| d.0)))
                        {
                            pass.set_scissor_rect(rect[0], rect[1], rect[2], rect[3]);
                            et.draw_mask(pass, groups, k0);
                        }
                        pass.set_bind_group(0, &self.g0, &[0]);
                        pass.set_bind_group(1, &g1, &[]);
                        pass.set_bind_group(2, &g2[0], &[]);
                        pass.set_vertex_buffer(0, vbuf.slice(..));
                        for ([x, y, w, h], a, b) in draws {
                            pass.set_scissor_rect(x, y, w, h);
                            for pipeline in &raster {
                                pass.set_pipeline(pipeline);
                                pass.draw(a..b, 0..1);
                            }
                        }
                    }
                    drop(open);
                }
                // the post hooks: once per pixel on the accumulated colour
                if let (Some((pipeline, layout)), Some((src, src_view))) =
                    (&p.compiled.post, &self.post_src)
                {
                    enc.copy_texture_to_texture(
                        t.texture.as_image_copy(),
                        src.as_image_copy(),
                        t.texture.size(),
                    );
                    let g3_post = device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("vwb post source"),
                        layout,
                        entries: &[wgpu::BindGroupEntry {
                            binding: 2,
                            resource: wgpu::BindingResource::TextureView(src_view),
                        }],
                    });
                    let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                        label: Some("vwb post"),
                        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                            view: &t.view,
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations {
                                load: wgpu::LoadOp::Load,
                                store: wgpu::StoreOp::Store,
                            },
                        })],
                        ..Default::default()
                    });
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(0, &self.g0, &[0]);
                    pass.set_bind_group(1, &g1, &[]);
                    pass.set_bind_group(2, &g2[0], &[]);
                    pass.set_bind_group(3, &g3_post, &[]);
                    pass.draw(0..3, 0..1);
                }
            }
            Backend::Compute => {
                if per_slice {
                    let uids = p.uids();
                    let groups = [g0_exit.as_ref().unwrap_or(&self.g0), &g1, g3];
                    fused_run = self.encode_compute_slices(
                        enc,
                        p,
                        &uids,
                        groups,
                        &g2,
                        plan.count,
                        [t.width, t.height],
                        frame_plan.half.is_none(),
                        exit.as_ref(),
                    );
                } else {
                    self.march.clear(enc);
                    let pipeline = if self.raw_samples {
                        p.raw_pipeline(&self.gpu.device)
                    } else {
                        p.march_pipeline(self.occupancy_bytes.is_some())
                    };
                    // (the raw kernel takes no part: it runs once)
                    let g3s = if self.raw_samples {
                        &g3s[..1]
                    } else {
                        &g3s[..]
                    };
                    encode_march(enc, pipeline, [&self.g0, &g1, &g2[0]], g3s, wg_own);
                    self.march.copy_out(enc);
                }
            }
        }
        stamp(enc, None);
        // the share of idle tiles, where a state of the lists' grid size used them
        let idle_tiles = exit
            .as_ref()
            .filter(|x| {
                state_sizes
                    .iter()
                    .flatten()
                    .any(|e| [e.width, e.height] == x.size)
            })
            .map(|x| x.idle);
        let n_stamps = ts_labels.len() as u32;
        if let Some((qs, resolve, read)) = ts
            && n_stamps > 0
        {
            enc.resolve_query_set(qs, 0..n_stamps, resolve, 0);
            enc.copy_buffer_to_buffer(resolve, 0, read, 0, n_stamps as u64 * 8);
        }
        let done: Vec<u64> = dirty.iter().map(|i| p.stack[*i].0).collect();
        Ok(Recorded {
            start,
            done,
            ts_labels,
            stats: FrameStats {
                slices: plan.count,
                per_slice_mode: per_slice,
                prepasses,
                volume_passes_run,
                spacing_updates,
                proxy_share,
                scissor_share,
                fused_slices: fused_run,
                idle_tiles,
                march_parts: if whole_march { parts.len() as u32 } else { 0 },
                raster_group: if s.backend == Backend::Raster {
                    group
                } else {
                    0
                },
                ..Default::default()
            },
        })
    }

    /// The parts in which the whole-frame march takes a frame of `count` slices of
    /// `stack` (compiled as `compiled`): one on a GPU; on a CPU device as many as the
    /// stack's loops need ([`march_parts`]), or of the size
    /// [`Renderer::set_march_part_slices`] forces.
    fn march_parts(
        &self,
        compiled: &Arc<CompiledStack>,
        stack: &[(u64, Arc<dyn Plugin>)],
        count: u32,
    ) -> Vec<[u32; 2]> {
        let part = match self.march.forced {
            Some(n) => n,
            None if self.gpu.info.device_type != wgpu::DeviceType::Cpu => return vec![[0, 0]],
            None => {
                let estimate = self.loop_estimate(compiled, stack);
                let key = Arc::as_ptr(compiled) as usize;
                let most = self.march.shrunk(key, estimate).unwrap_or(u32::MAX);
                march_parts::part_slices(estimate).min(most)
            }
        };
        march_parts::parts(count, part)
    }

    /// The loop iterations a sample of `stack` (compiled as `compiled`) costs, as its
    /// plugins declare them ([`Plugin::loop_iterations`]) under their current
    /// parameters.
    fn loop_estimate(&self, compiled: &CompiledStack, stack: &[(u64, Arc<dyn Plugin>)]) -> u32 {
        let loops: Vec<_> = stack
            .iter()
            .filter_map(|(uid, plugin)| {
                let g = self.instances.get(uid)?;
                Some(plugin.loop_iterations(&g.params))
            })
            .collect();
        march_parts::per_sample(&loops, compiled.scalar_reads)
    }

    /// After a frame of `count` slices whose loops ran out
    /// (`FrameStats::loop_limited`): marches the current stack in parts of at most a
    /// quarter of that frame's longest from now on (while its loop estimate stays the
    /// same). Whether they shrank (not below one slice).
    fn shrink_march_parts(&mut self, count: u32) -> bool {
        if let Some(split) = self.split.as_mut() {
            // every brick's renderer (each marches its own part of the rays)
            let mut any = false;
            for c in &mut split.children {
                any |= c.renderer.shrink_march_parts(count);
            }
            return any;
        }
        let Some(p) = self.pipelines.as_ref() else {
            return false;
        };
        let (compiled, stack) = (p.compiled.clone(), p.stack.clone());
        self.shrink_parts_of(&compiled, &stack, count)
    }

    /// [`Renderer::shrink_march_parts`] for the march of `stack` (compiled as
    /// `compiled`) over `count` slices: a frame's, or an atlas tile's.
    fn shrink_parts_of(
        &mut self,
        compiled: &Arc<CompiledStack>,
        stack: &[(u64, Arc<dyn Plugin>)],
        count: u32,
    ) -> bool {
        let now = self.march_parts(compiled, stack, count);
        let longest = now
            .iter()
            .map(|[a, b]| {
                if *b == 0 {
                    count.saturating_sub(*a)
                } else {
                    b - a
                }
            })
            .max()
            .unwrap_or(0);
        if longest <= 1 || self.march.forced.is_some() {
            return false;
        }
        let estimate = self.loop_estimate(compiled, stack);
        let key = Arc::as_ptr(compiled) as usize;
        self.march.set_shrunk(key, estimate, (longest / 4).max(1));
        true
    }

    /// Marches every frame in parts of at most `slices` slices, on any device (`None`:
    /// as the device needs, [`march_parts`]). The image is the same; for tests and
    /// benchmarks of the parts themselves (`VWB_MARCH_PART_SLICES=N` starts renderers
    /// with it).
    pub fn set_march_part_slices(&mut self, slices: Option<u32>) {
        self.march.forced = slices.map(|n| n.max(1));
    }

    /// Books a recorded frame once its encoder was submitted: its pre-passes count as
    /// done. Returns its statistics without timings.
    fn submitted(&mut self, rec: Recorded) -> FrameStats {
        self.mark_prepasses_done(rec.done);
        self.counters.prepass_runs += rec.stats.prepasses_run() as u64;
        self.counters.volume_pass_runs += rec.stats.volume_passes_run.len() as u64;
        rec.stats
    }

    /// Reads the eye buffer: premultiplied RGBA per pixel, row-major from the top.
    pub fn read_pixels(&self) -> Option<(u32, u32, Vec<[f32; 4]>)> {
        let t = self.target.as_ref()?;
        let bpp = match t.format {
            TargetFormat::Rgba16Float => 8,
            TargetFormat::Rgba32Float => 16,
        };
        let bytes = read_texture(&self.gpu, &t.texture, bpp);
        Some((
            t.width,
            t.height,
            decode_rgba(&bytes, t.width, t.height, bpp),
        ))
    }

    /// The raster backend's chunk bits of the last frame that skipped empty space
    /// ([`Renderer::set_raster_skipping`]): per pixel, row by row, bit j set where the
    /// pixel's ray may meet a visible sample in slices j·c … j·c + c − 1, c = ⌈slices /
    /// 64⌉ (`fs_raster_chunks` in shaders/slice.wgsl); `None` before such a frame. For
    /// tests and diagnostics (a readback).
    pub fn raster_chunk_bits(&self) -> Option<(u32, u32, Vec<u64>)> {
        self.raster_et.as_ref()?.chunk_bits(&self.gpu)
    }

    /// Composites the eye buffer over `background` into an 8-bit RGBA texture (for
    /// display) and returns its view.
    pub fn display(&mut self, background: [f32; 4]) -> Option<&wgpu::TextureView> {
        let format = self.target.as_ref()?.format;
        if self.display_pipeline.as_ref().is_none_or(|d| d.0 != format) {
            let device = &self.gpu.device;
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("vwb display"),
                source: wgpu::ShaderSource::Wgsl(DISPLAY_WGSL.into()),
            });
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("vwb display"),
                entries: &[
                    wgpu::BindGroupLayoutEntry {
                        binding: 0,
                        visibility: wgpu::ShaderStages::COMPUTE,
                        ty: wgpu::BindingType::Texture {
                            sample_type: wgpu::TextureSampleType::Float { filterable: false },
                            view_dimension: wgpu::TextureViewDimension::D2,
                            multisampled: false,
                        },
                        count: None,
                    },
                    wgpu::BindGroupLayoutEntry {
                        binding: 1,
                        visibility: wgpu::ShaderStages::COMPUTE,
                        ty: wgpu::BindingType::StorageTexture {
                            access: wgpu::StorageTextureAccess::WriteOnly,
                            format: wgpu::TextureFormat::Rgba8Unorm,
                            view_dimension: wgpu::TextureViewDimension::D2,
                        },
                        count: None,
                    },
                    uniform_entry(2, wgpu::ShaderStages::COMPUTE, false),
                ],
            });
            let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("vwb display"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("vwb display"),
                layout: Some(&pl),
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            });
            self.display_pipeline = Some((format, pipeline, layout));
        }
        let (_, pipeline, layout) = self.display_pipeline.as_ref()?;
        let t = self.target.as_ref()?;
        let device = &self.gpu.device;
        let bg = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vwb background"),
            contents: bytemuck::cast_slice(&background),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vwb display"),
            layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&t.view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&t.display_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: bg.as_entire_binding(),
                },
            ],
        });
        let mut enc = device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(t.width.div_ceil(8), t.height.div_ceil(8), 1);
        }
        self.gpu.queue.submit([enc.finish()]);
        Some(&t.display_view)
    }

    /// The 8-bit display texture (after [`Renderer::display`]).
    pub fn display_texture(&self) -> Option<&wgpu::Texture> {
        self.target.as_ref().map(|t| &t.display)
    }

    /// Reads a pre-pass target of the instance `uid` (for tests): texels as f32 RGBA.
    /// None for a split volume (each brick has its own).
    pub fn read_prepass(&self, uid: u64) -> Option<PassTarget> {
        let g = self.instances.get(&uid)?;
        let (tex, _) = g.prepass_target.as_ref()?;
        read_texels_3d(&self.gpu, tex)
    }

    /// The per-slice state of the instance `uid` as the last frame left it (for tests):
    /// both textures of the pair, and the marks of its tiles where its plugin tracks
    /// them ([`crate::plugin::SliceStateDecl::track_clear`]). None without state, for
    /// a split volume (each brick has its own), or for a 16-bit state format.
    pub fn read_state(&self, uid: u64) -> Option<StateReadback> {
        let g = self.instances.get(&uid)?;
        let [a, b] = g.state.as_ref()?;
        if a.0.format().block_copy_size(None)? / 4 != a.0.format().components() as u32 {
            return None;
        }
        let (size, first) = read_texels_3d(&self.gpu, &a.0)?;
        let (_, second) = read_texels_3d(&self.gpu, &b.0)?;
        let tiles = g.state_tiles.as_ref().map(|buf| {
            let staging = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vwb read state tiles"),
                size: buf.size(),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut enc = self.gpu.device.create_command_encoder(&Default::default());
            enc.copy_buffer_to_buffer(buf, 0, &staging, 0, buf.size());
            self.gpu.queue.submit([enc.finish()]);
            read_buffer(&self.gpu, &staging, buf.size())
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
                .collect()
        });
        Some(StateReadback {
            size: [size[0], size[1]],
            components: a.0.format().components() as usize,
            textures: [first, second],
            tiles,
        })
    }

    /// The figures `inst` reports about what its passes computed after the last frame
    /// ([`crate::plugin::Plugin::statistics`]): its volume-pass targets and its pre-pass
    /// target (`prepass`) as the GPU left them, with this renderer's volume and named
    /// volumes.
    pub fn statistics_of(
        &self,
        inst: &crate::plugin::PluginInstance,
    ) -> Vec<crate::plugin::Statistic> {
        let read = |target: &str| {
            self.read_pass_target(inst.uid, target).or_else(|| {
                (target == "prepass")
                    .then(|| self.read_prepass(inst.uid))
                    .flatten()
            })
        };
        let passes = crate::plugin::PassOutputs {
            volume: &self.volume,
            inputs: &self.inputs,
            read: &read,
        };
        inst.configured().statistics(&inst.params, &passes)
    }

    /// Makes the next frame rerun every pre-pass and volume pass as if its inputs had
    /// changed (progressive passes from their first step), without recreating any
    /// resource: for timing what a change costs more than once
    /// (`update_repeats` in experiment files).
    pub fn rerun_passes(&mut self) {
        for g in self.instances.values_mut() {
            g.prepass_done = None;
            for st in &mut g.pass_state {
                st.stamp = None;
                st.steps_done = 0;
            }
        }
    }

    /// Reads the target of the instance `uid`'s volume pass named `target`
    /// ([`crate::plugin::VolumePassDecl::target`]) as it stands after the last frame:
    /// its size and its texels' f32 components (x fastest). None when the instance has
    /// no such pass, or for a split volume (each brick has its own).
    pub fn read_pass_target(&self, uid: u64, target: &str) -> Option<PassTarget> {
        let g = self.instances.get(&uid)?;
        let (_, plugin) = self
            .pipelines
            .as_ref()?
            .stack
            .iter()
            .find(|(u, _)| *u == uid)?;
        let k = plugin
            .volume_passes()
            .iter()
            .position(|p| p.target == target)?;
        let (tex, _) = g.pass_targets.get(k)?;
        read_texels_3d(&self.gpu, tex)
    }
}

/// A 3D storage target's texels as f32 components (32-bit formats), x fastest.
fn read_texels_3d(gpu: &GpuContext, tex: &wgpu::Texture) -> Option<PassTarget> {
    let bpp = tex.format().block_copy_size(None)?;
    let s = tex.size();
    let bytes = read_texture(gpu, tex, bpp);
    let row = (s.width * bpp).div_ceil(256) * 256;
    let comps = (bpp / 4) as usize;
    let mut out = Vec::new();
    for z in 0..s.depth_or_array_layers {
        for y in 0..s.height {
            let o = ((z * s.height + y) * row) as usize;
            let line = &bytes[o..o + (s.width * bpp) as usize];
            for px in line.chunks_exact(bpp as usize) {
                for c in 0..comps {
                    out.push(f32::from_le_bytes(
                        px[4 * c..4 * c + 4].try_into().expect("4 bytes"),
                    ));
                }
            }
        }
    }
    Some(([s.width, s.height, s.depth_or_array_layers], out))
}

/// The first `n` resolved timestamps in `read` (GPU ticks).
fn read_ticks(gpu: &GpuContext, read: &wgpu::Buffer, n: u32) -> Vec<u64> {
    read_buffer(gpu, read, n as u64 * 8)
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect()
}

/// Milliseconds from tick `a` to tick `b` (0 when `b` is earlier).
fn ticks_ms(gpu: &GpuContext, a: u64, b: u64) -> f64 {
    b.saturating_sub(a) as f64 * gpu.queue.get_timestamp_period() as f64 / 1.0e6
}

/// Per-instance figures of several renderers summed by uid, in first-seen order.
fn sum_by_uid(
    lists: impl Iterator<Item = Vec<(u64, &'static str, u64)>>,
) -> Vec<(u64, &'static str, u64)> {
    let mut out: Vec<(u64, &'static str, u64)> = Vec::new();
    for list in lists {
        for (uid, id, bytes) in list {
            match out.iter_mut().find(|e| e.0 == uid) {
                Some(e) => e.2 += bytes,
                None => out.push((uid, id, bytes)),
            }
        }
    }
    out
}

/// A per-slice state read back ([`Renderer::read_state`]).
#[derive(Debug, Clone)]
pub struct StateReadback {
    /// Texels of each texture (width, height).
    pub size: [u32; 2],
    /// Components per texel in `textures`.
    pub components: usize,
    /// The pair's textures: f32 components, x fastest.
    pub textures: [Vec<f32>; 2],
    /// The tiles' marks (row-major, [`crate::composer::STATE_TILE`] texels on a side;
    /// nonzero: a texel of the tile left the clear value), where they are tracked.
    pub tiles: Option<Vec<u32>>,
}

/// RGBA texels read back with rows padded to 256 bytes, `bpp` 8 (rgba16float) or 16.
fn decode_rgba(bytes: &[u8], width: u32, height: u32, bpp: u32) -> Vec<[f32; 4]> {
    let row = (width * bpp).div_ceil(256) * 256;
    let mut out = Vec::with_capacity((width * height) as usize);
    for y in 0..height {
        let line = &bytes[(y * row) as usize..(y * row + width * bpp) as usize];
        for px in line.chunks_exact(bpp as usize) {
            let v: [f32; 4] = if bpp == 8 {
                std::array::from_fn(|c| {
                    half::f16::from_le_bytes([px[2 * c], px[2 * c + 1]]).to_f32()
                })
            } else {
                std::array::from_fn(|c| {
                    f32::from_le_bytes(px[4 * c..4 * c + 4].try_into().expect("4 bytes"))
                })
            };
            out.push(v);
        }
    }
    out
}

/// The layout group 0 binds the volume in: the stored format's, or for a split
/// volume (`split`) its placeholder's, a 3D texture (the bricks bind their own).
fn bound_layout(stored: VolumeFormat, split: bool) -> VolumeLayout {
    if split {
        VolumeLayout::Texture3d
    } else {
        stored.layout()
    }
}

/// Group 0's layout (the core bindings every module declares, shaders/common.wgsl),
/// with the volume's binding in `volume`'s layout.
fn g0_layout(device: &wgpu::Device, volume: VolumeLayout) -> wgpu::BindGroupLayout {
    let all = wgpu::ShaderStages::VERTEX_FRAGMENT | wgpu::ShaderStages::COMPUTE;
    let fc = wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE;
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("vwb group 0 (core)"),
        entries: &[
            uniform_entry(0, all, false),
            wgpu::BindGroupLayoutEntry {
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: volume.view_dimension(),
                    multisampled: false,
                },
                ..texture3d_entry(1, fc)
            },
            sampler_entry(2, fc),
            sampler_entry(3, fc),
            uniform_entry(4, fc, true),
            wgpu::BindGroupLayoutEntry {
                visibility: fc,
                ..storage_buffer_entry(5, true)
            },
            storage_buffer_entry(6, true),
        ],
    })
}

#[allow(clippy::too_many_arguments)]
fn make_g0(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    volume: &wgpu::TextureView,
    linear: &wgpu::Sampler,
    nearest: &wgpu::Sampler,
    [slice_info, tile_list]: [&wgpu::Buffer; 2],
    occupancy: &wgpu::Buffer,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("vwb group 0"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: frame.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(volume),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::Sampler(linear),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: wgpu::BindingResource::Sampler(nearest),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: slice_info,
                    offset: 0,
                    size: wgpu::BufferSize::new(32),
                }),
            },
            wgpu::BindGroupEntry {
                binding: 5,
                resource: occupancy.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 6,
                resource: tile_list.as_entire_binding(),
            },
        ],
    })
}

/// Uploads brick occupancy bytes (255 = may be visible) as the storage buffer
/// `occupancy` of shaders/common.wgsl: the grid's dims in words 0–2, then one bit per
/// brick (x fastest) from word 4, then from the word that word 3 names eight bytes per
/// brick (two words), one per octant of ray directions: the bit again (bit 7) and how
/// many bricks beyond it the pure box ahead of it reaches (bits 0–6,
/// [`crate::skipping::pure_boxes_ahead`], at most [`crate::skipping::run_bricks_cap`]).
/// A bit costs a load, a shift and a mask where the R8Unorm 3D texture it replaced cost
/// a texel fetch that lavapipe runs with a level per lane, about 200 instructions
/// (docs/perf.md, "A ray's samples as one run").
fn upload_occupancy(gpu: &GpuContext, dims: [u32; 3], bytes: &[u8]) -> wgpu::Buffer {
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vwb brick occupancy"),
            contents: bytemuck::cast_slice(&occupancy_words(dims, bytes)),
            usage: wgpu::BufferUsages::STORAGE,
        })
}

/// The words of [`upload_occupancy`]'s buffer: a byte above 127 sets its brick's bit.
pub(crate) fn occupancy_words(dims: [u32; 3], bytes: &[u8]) -> Vec<u32> {
    occupancy_words_capped(dims, bytes, crate::skipping::run_bricks_cap())
}

/// The first four words of [`upload_occupancy`]'s buffer for `bricks` bricks of a grid
/// of `dims`: the dims, then the word where the bricks' bytes begin (after one bit per
/// brick from word 4). The frame uniform holds them too (`Frame.bricks`).
fn occupancy_header(dims: [u32; 3], bricks: usize) -> [u32; 4] {
    [dims[0], dims[1], dims[2], (4 + bricks.div_ceil(32)) as u32]
}

/// [`occupancy_words`] with the pure boxes' extents capped at `cap`.
fn occupancy_words_capped(dims: [u32; 3], bytes: &[u8], cap: u8) -> Vec<u32> {
    let mut words = occupancy_header(dims, bytes.len()).to_vec();
    let cells = words[3] as usize;
    words.resize(cells + 2 * bytes.len(), 0);
    for (i, _) in bytes.iter().enumerate().filter(|(_, b)| **b > 127) {
        words[4 + i / 32] |= 1 << (i % 32);
    }
    let boxes = crate::skipping::pure_boxes_ahead(bytes, dims);
    for (i, (b, extents)) in bytes.iter().zip(boxes).enumerate() {
        for (octant, r) in extents.into_iter().enumerate() {
            let cell = u32::from(*b > 127) << 7 | u32::from(r.min(cap));
            words[cells + 2 * i + octant / 4] |= cell << (8 * (octant % 4));
        }
    }
    words
}

/// Uploads the normalised scalar volume as `format` ([`VolumeFormat::texture_format`]):
/// rg32float is `r32float_pairs`' layout, a 2D array whose layer k holds each voxel
/// of slice k beside its +z neighbour (the last slice's beside itself).
fn upload_volume(
    gpu: &GpuContext,
    volume: &Volume,
    format: wgpu::TextureFormat,
) -> wgpu::TextureView {
    let scalars = volume.normalized_scalars();
    let pairs = format == wgpu::TextureFormat::Rg32Float;
    let bytes: Vec<u8> = match format {
        wgpu::TextureFormat::Rg32Float => {
            let layer = volume.dims[0] as usize * volume.dims[1] as usize;
            let next = |i: usize| {
                if i + layer < scalars.len() {
                    i + layer
                } else {
                    i
                }
            };
            (0..scalars.len())
                .flat_map(|i| [scalars[i], scalars[next(i)]])
                .flat_map(f32::to_le_bytes)
                .collect()
        }
        wgpu::TextureFormat::R16Float => scalars
            .iter()
            .flat_map(|v| half::f16::from_f32(*v).to_le_bytes())
            .collect(),
        wgpu::TextureFormat::R16Unorm => scalars
            .iter()
            .flat_map(|v| ((v.clamp(0.0, 1.0) * 65535.0).round() as u16).to_le_bytes())
            .collect(),
        wgpu::TextureFormat::R8Unorm => scalars
            .iter()
            .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect(),
        _ => bytemuck::cast_slice(&scalars).to_vec(),
    };
    let [w, h, d] = volume.dims;
    let texture = gpu.device.create_texture_with_data(
        &gpu.queue,
        &wgpu::TextureDescriptor {
            label: Some("vwb volume"),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: d,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: if pairs {
                wgpu::TextureDimension::D2
            } else {
                wgpu::TextureDimension::D3
            },
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        &bytes,
    );
    texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: pairs.then_some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    })
}

/// Copies a texture (2D or 3D) to host memory; rows padded to 256 bytes.
fn read_texture(gpu: &GpuContext, tex: &wgpu::Texture, bpp: u32) -> Vec<u8> {
    let s = tex.size();
    let row = (s.width * bpp).div_ceil(256) * 256;
    let size = row as u64 * s.height as u64 * s.depth_or_array_layers as u64;
    let buf = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("vwb readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    enc.copy_texture_to_buffer(
        tex.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buf,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(s.height),
            },
        },
        s,
    );
    gpu.queue.submit([enc.finish()]);
    read_buffer(gpu, &buf, size)
}

/// The stride by which `spread_row` (shaders/slice.wgsl) permutes `rows` workgroup rows:
/// the first integer from ⌊rows · 0.618034⌋ (in f32, as the shader computes it; at least
/// 1) that is coprime to `rows`.
fn spread_stride(rows: u32) -> u32 {
    fn gcd(mut a: u32, mut b: u32) -> u32 {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    }
    let mut s = ((rows as f32 * 0.618034f32) as u32).max(1);
    while gcd(s, rows) > 1 {
        s += 1;
    }
    s
}

/// The whole-frame march (`pipeline`: `cs_main`, `cs_main_skip` or `cs_main_raw`) over
/// `n` workgroups, once per part of the frame (`g3s`, [`march_parts`]), in one pass.
fn encode_march(
    enc: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    [g0, g1, g2]: [&wgpu::BindGroup; 3],
    g3s: &[wgpu::BindGroup],
    n: (u32, u32),
) {
    let mut pass = enc.begin_compute_pass(&Default::default());
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, g0, &[0]);
    pass.set_bind_group(1, g1, &[]);
    pass.set_bind_group(2, g2, &[]);
    if n.0 == 0 || n.1 == 0 {
        return;
    }
    for g3 in g3s {
        pass.set_bind_group(3, g3, &[]);
        pass.dispatch_workgroups(n.0, n.1, 1);
    }
}

fn read_buffer(gpu: &GpuContext, buf: &wgpu::Buffer, size: u64) -> Vec<u8> {
    let slice = buf.slice(..size);
    slice.map_async(wgpu::MapMode::Read, |_| {});
    gpu.wait();
    let data = match slice.get_mapped_range() {
        Ok(view) => view.to_vec(),
        Err(e) => {
            log::error!("readback failed: {e}");
            vec![0; size as usize]
        }
    };
    buf.unmap();
    data
}

#[cfg(test)]
mod tests {
    /// The rows' stride that the frame uniform hands `spread_row`: the shader's own
    /// search (the first integer from ⌊rows · 0.618034⌋ coprime to rows), so q ↦ q·s mod
    /// rows is a permutation of the rows; 64 rows (512² in 8 × 8 workgroups) take 39,
    /// 66 rows take 41 (40 shares the factor 2 with 66).
    #[test]
    fn the_spread_stride_permutes_the_rows() {
        assert_eq!(super::spread_stride(64), 39);
        assert_eq!(super::spread_stride(66), 41);
        assert_eq!(super::spread_stride(0), 1);
        assert_eq!(super::spread_stride(1), 1);
        for rows in 1..600u32 {
            let s = super::spread_stride(rows);
            let first = ((rows as f32 * 0.618034f32) as u32).max(1);
            assert!(s >= first, "{rows}: {s}");
            let mut seen = vec![false; rows as usize];
            for q in 0..rows {
                seen[((q * s) % rows) as usize] = true;
            }
            assert!(seen.iter().all(|&x| x), "{rows}: {s} is no permutation");
            // the first such: every stride between shares a factor with rows
            for t in first..s {
                assert!((2..=t).any(|d| t % d == 0 && rows % d == 0), "{rows}: {t}");
            }
        }
    }

    /// Slices per proxy polygon round down to one of the groups, each dividing the
    /// runs between the depth masks.
    #[test]
    fn raster_groups_round_down_to_a_power_of_two() {
        let got: Vec<u32> = [0, 1, 2, 3, 5, 8, 15, 16, 17, 1000]
            .into_iter()
            .map(super::raster_group_of)
            .collect();
        assert_eq!(got, [1, 1, 2, 2, 4, 8, 8, 16, 16, 16]);
        // every group divides the runs between the raster backend's depth masks
        for g in super::RASTER_GROUPS {
            assert!(super::raster_et::skip_interval_default(g).is_multiple_of(g));
            assert!(super::raster_et::RASTER_SKIP_INTERVAL.is_multiple_of(g));
            assert!(super::raster_et::RASTER_ET_INTERVAL.is_multiple_of(g));
        }
        // the settings: auto and the groups, nothing else
        assert!(super::is_raster_group_setting(super::RASTER_GROUP_AUTO));
        assert!(!super::is_raster_group_setting(3));
        assert_eq!(super::raster_group_setting(0), super::RASTER_GROUP_AUTO);
        assert_eq!(super::raster_group_setting(12), 8);
    }

    /// The occupancy buffer's words: the grid's dims, the first word of the bricks'
    /// bytes, then bit i of word 4 + i / 32 set exactly where byte i is above 127 (the
    /// shader's `brick_visible` reads bit i at brick x + dx·(y + dy·z)), with a partial
    /// last word; then brick i's eight bytes, one per octant: the same bit (bit 7) and
    /// its pure box's extent, capped (`brick_cell`).
    #[test]
    fn occupancy_words_hold_one_bit_per_brick() {
        let dims = [5u32, 4, 3];
        let bytes: Vec<u8> = (0..60u32)
            .map(|i| match i % 7 {
                0 => 255,
                3 => 128,
                5 => 127,
                _ => 0,
            })
            .collect();
        let boxes = crate::skipping::pure_boxes_ahead(&bytes, dims);
        for cap in [0, 1, 127] {
            let words = super::occupancy_words_capped(dims, &bytes, cap);
            assert_eq!(&words[..4], &[5, 4, 3, 6]);
            assert_eq!(words.len(), 4 + 2 + 2 * 60);
            for (i, b) in bytes.iter().enumerate() {
                let bit = words[4 + i / 32] >> (i % 32) & 1;
                assert_eq!(bit == 1, *b > 127, "brick {i}: byte {b}, bit {bit}");
                for octant in 0..8 {
                    let cell = words[6 + 2 * i + octant / 4] >> (8 * (octant % 4)) & 0xFF;
                    assert_eq!(cell >> 7, bit, "brick {i}: the cell's bit");
                    assert_eq!(
                        cell & 127,
                        u32::from(boxes[i][octant].min(cap)),
                        "brick {i}"
                    );
                }
            }
            assert_eq!(words[5] >> 28, 0, "bits past the last brick stay clear");
        }
    }
}
