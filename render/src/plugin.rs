//! The plugin API and the typed registry.
//!
//! A plugin contributes WGSL hook functions (its `.wgsl` file holds only those, plus
//! helpers), a parameter spec, optional GPU resources, an optional per-slice state
//! (ping-pong buffers updated after every slice), an optional pre-pass that fills a
//! 3D texture, and an optional CPU twin of its GPU math.
//!
//! Hook signatures (names inside the plugin's file; the composer prefixes them per
//! instance):
//! - `fn setup(r: Ray, uv: vec2<f32>) -> vec4<f32>` — once per ray before its samples;
//!   the result is the instance's `ray_record` (a private `vec4<f32>`) for its other
//!   hooks at every sample of that ray
//! - `fn clip(s: Sample) -> bool` — false drops the sample (runs before sampling)
//! - `fn sample(s: Sample) -> Sample` — may replace `s.value` / set `s.normal`
//! - `fn classify(s: Sample) -> Sample` — sets `s.color` (straight RGBA per Δs0)
//! - `fn shade(s: Sample) -> Sample` — modifies `s.color`
//! - `fn composite(s: Sample, c: vec4<f32>) -> vec4<f32>` — premultiplied contribution
//! - `fn slice_update(s: Sample, c: vec4<f32>, uv: vec2<f32>) -> vec4<f32>` — next
//!   state texel (at state coordinate `uv`) after the current slice (needs
//!   [`SliceStateDecl`])
//! - pre-pass file: `fn prepass(voxel: vec3<u32>, dims: vec3<u32>) -> vec4<f32>`
//! - volume pass (a function of the plugin's hook file named by [`VolumePassDecl`]):
//!   `fn <entry>(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32>`;
//!   it may call `stack_classify(tex, dir)` (the stack's clip, sample and classify hooks
//!   at a texture coordinate: straight RGBA, zero where clipped) and read the targets
//!   of the plugin's earlier passes by name
//!
//! Names the plugin can use: `params.<key>` (its uniform parameters), each declared
//! resource by name, `state_prev` (its state of the previous slice, a texture_2d
//! read with `linear_clamp` at `state_coord(s.pos, s.uv)`), `state_prev_clear(uv, reach)` where
//! the state tracks its clear tiles ([`SliceStateDecl::track_clear`]), its pre-pass target by
//! name (a texture_3d), and everything in `shaders/common.wgsl`.

use std::borrow::Cow;
use std::collections::HashMap;
use std::sync::Arc;

use glam::{DVec2, DVec3, DVec4};

use crate::inputs::VolumeInputs;
pub use crate::inputs::Volumes;
use crate::params::{ParamSpec, ParamValue, ParamValues, validate_specs};
use crate::volume::Volume;

/// Plugin category: the part before the dot of the id.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Category {
    Clip,
    Sample,
    Classify,
    Shade,
    Composite,
    Flow,
    Search,
    Test,
}

impl Category {
    pub const ALL: [Category; 8] = [
        Category::Clip,
        Category::Sample,
        Category::Classify,
        Category::Shade,
        Category::Composite,
        Category::Flow,
        Category::Search,
        Category::Test,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Category::Clip => "clip",
            Category::Sample => "sample",
            Category::Classify => "classify",
            Category::Shade => "shade",
            Category::Composite => "composite",
            Category::Flow => "flow",
            Category::Search => "search",
            Category::Test => "test",
        }
    }

    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == s)
    }
}

/// WGSL source with the file it came from (relative to the repository root), so that
/// errors can name it.
#[derive(Debug, Clone)]
pub struct ShaderSource {
    pub file: Cow<'static, str>,
    pub source: Cow<'static, str>,
}

impl ShaderSource {
    pub const fn new_static(file: &'static str, source: &'static str) -> Self {
        Self {
            file: Cow::Borrowed(file),
            source: Cow::Borrowed(source),
        }
    }

    /// The file with its optional regions left out: every line from a
    /// `// {name}: begin` line to the next `// {name}: end` line (each may be indented)
    /// is blanked, so that compile errors keep their line numbers, and the begin line
    /// becomes `stub` (e.g. a constant stand-in for a function the region defines).
    /// A structural parameter that switches a feature off thus compiles the shader
    /// without it: nothing of the feature is left to cost time.
    pub fn without_region(
        file: &'static str,
        source: &'static str,
        name: &str,
        stub: &str,
    ) -> Self {
        Self::without_regions(file, source, &[(name, stub)])
    }

    /// [`ShaderSource::without_region`] for several regions, each `(name, stub)`: one
    /// file can hold the variants of a plugin's shaders (e.g. a pre-pass and two sample
    /// hooks), each shader keeping the regions it needs.
    pub fn without_regions(
        file: &'static str,
        source: &'static str,
        regions: &[(&str, &str)],
    ) -> Self {
        let marks: Vec<(String, String, &str)> = regions
            .iter()
            .map(|(name, stub)| {
                (
                    format!("// {name}: begin"),
                    format!("// {name}: end"),
                    *stub,
                )
            })
            .collect();
        let mut out = String::with_capacity(source.len());
        let mut inside: Option<usize> = None;
        for line in source.lines() {
            let t = line.trim_start();
            match inside {
                None => match marks.iter().position(|(b, _, _)| t.starts_with(b.as_str())) {
                    Some(i) => {
                        inside = Some(i);
                        out.push_str(marks[i].2);
                    }
                    None => out.push_str(line),
                },
                Some(i) => {
                    if t.starts_with(marks[i].1.as_str()) {
                        inside = None;
                    }
                }
            }
            out.push('\n');
        }
        Self {
            file: Cow::Borrowed(file),
            source: Cow::Owned(out),
        }
    }
}

/// Sampled resources a plugin owns (it creates them in [`Plugin::create_resources`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResourceKind {
    /// `texture_1d<f32>`, filterable (a table of one row: [`GpuInit::create_table_1d`])
    Texture1d,
    /// `texture_2d<f32>`, filterable
    Texture2d,
    /// `texture_3d<f32>`, filterable
    Texture3d,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResourceDecl {
    pub name: &'static str,
    pub kind: ResourceKind,
}

/// A resource created by a plugin, matching its [`ResourceDecl`] at the same index.
#[derive(Debug, Clone)]
pub struct GpuResource {
    pub texture: wgpu::Texture,
    pub view: wgpu::TextureView,
}

impl GpuResource {
    pub fn bytes(&self) -> u64 {
        let s = self.texture.size();
        let bpp = self.texture.format().block_copy_size(None).unwrap_or(4) as u64;
        s.width as u64 * s.height as u64 * s.depth_or_array_layers as u64 * bpp
    }
}

/// Formats for per-slice state and pre-pass targets (both are storage-writable).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StorageFormat {
    R32Float,
    Rgba16Float,
    Rgba32Float,
    /// Four 8-bit unsigned normalised channels (k/255), e.g. packed codes such as the
    /// quantised gradients (`vwb_render::shading`), read with `textureLoad`.
    Rgba8Unorm,
}

impl StorageFormat {
    pub const ALL: [StorageFormat; 4] = [
        StorageFormat::R32Float,
        StorageFormat::Rgba16Float,
        StorageFormat::Rgba32Float,
        StorageFormat::Rgba8Unorm,
    ];
    /// The format named as in WGSL (`r32float`).
    pub fn parse(name: &str) -> Option<StorageFormat> {
        Self::ALL.into_iter().find(|f| f.wgsl() == name)
    }
    pub fn wgsl(self) -> &'static str {
        match self {
            StorageFormat::R32Float => "r32float",
            StorageFormat::Rgba16Float => "rgba16float",
            StorageFormat::Rgba32Float => "rgba32float",
            StorageFormat::Rgba8Unorm => "rgba8unorm",
        }
    }
    pub fn wgpu(self) -> wgpu::TextureFormat {
        match self {
            StorageFormat::R32Float => wgpu::TextureFormat::R32Float,
            StorageFormat::Rgba16Float => wgpu::TextureFormat::Rgba16Float,
            StorageFormat::Rgba32Float => wgpu::TextureFormat::Rgba32Float,
            StorageFormat::Rgba8Unorm => wgpu::TextureFormat::Rgba8Unorm,
        }
    }
    /// Sampling 32-bit float formats with filtering needs FLOAT32_FILTERABLE.
    pub fn needs_float32_filterable(self) -> bool {
        !matches!(self, StorageFormat::Rgba16Float | StorageFormat::Rgba8Unorm)
    }
}

/// Per-slice state: a pair of 2D textures swapped after each slice. The plugin reads
/// the previous one as `state_prev` (at `state_coord(s.pos, s.uv)`) and returns the next texel from
/// `slice_update`. Its resolution is the eye buffer's times `scale`. It lives in
/// eye-buffer space (`state_coord(s.pos, s.uv)` = `s.uv`), or, when a plugin of the stack names a
/// light ([`Plugin::slice_light`]), in the light's space under half-angle slicing
/// ([`crate::slicing::HalfAngle`]; `state_uv_per_world` and `state_step` in
/// shaders/common.wgsl, [`CpuView::state_uv_per_world`] and [`CpuView::state_step`]
/// for the twin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SliceStateDecl {
    pub format: StorageFormat,
    pub scale: f32,
    /// Value the state is cleared to before the first slice.
    pub clear: [f32; 4],
    /// The state may travel with a light ([`Plugin::slice_light`]): the composed code
    /// keeps the half-angle slicing paths, which cost a CPU device even when a frame
    /// does not take them. Without it they are compiled out and `slice_light` is not
    /// asked.
    pub light: bool,
    /// The renderer tracks which tiles of 8 × 8 state texels still hold `clear` in
    /// this frame, and the plugin's hooks may ask `state_prev_clear(uv, reach)`: true
    /// when every texel of `state_prev` that a bilinear read within `reach` (state uv,
    /// per axis) of `uv` can touch still holds `clear`. An update that then knows its
    /// result exactly (e.g. `shade.dos`: an empty sample under a cone of clear buffer
    /// gives `clear` again) skips its reads. A tile is marked once any update writes a
    /// value other than `clear` into it, and stays marked until the state is cleared
    /// (before the first slice), so the answer errs only towards false. Without it the
    /// tracking is compiled out.
    pub track_clear: bool,
}

/// A pre-pass: a compute pass that fills a 3D texture named `target` (read by the
/// plugin's hooks as a `texture_3d<f32>`) from `shader`'s `prepass` function. It
/// reruns only when the volume or one of the parameters in `depends_on` changes.
#[derive(Debug, Clone)]
pub struct PrepassDecl {
    pub target: &'static str,
    pub format: StorageFormat,
    /// Size of the target relative to the volume (1 = one texel per voxel).
    pub scale: f32,
    pub shader: ShaderSource,
    pub depends_on: Vec<&'static str>,
    /// The target's w component holds the volume's value at each voxel, exactly (an
    /// rgba32float target the size of the volume whose pre-pass stores
    /// `volume_voxel(voxel)` there). The main module then reads every sample's value
    /// from it (`sample_value`), so that a sample's value and what the plugin reads
    /// beside it at the same point (a gradient) come from one fetch.
    pub holds_value: bool,
}

/// A volume pass: a compute pass over a 3D texture `target` (read by the plugin's hooks
/// and later passes by that name, as a `texture_3d<f32>` with `linear_clamp`). Unlike a
/// [`PrepassDecl`], its function lives in the plugin's hook file and sees the whole
/// stack: `stack_classify(tex, dir)` runs every plugin's clip, sample and classify
/// hooks, so a light pass sees the current transfer function and casts no light
/// through clipped matter. A plugin's passes form a chain, run in declaration order;
/// when one reruns, every later one does too. A pass reruns when it never ran, when one
/// of its `depends_on` parameters changed, or when a clip, sample or classify
/// instance of the stack changed its parameters (the volume change recreates
/// everything). Camera moves rerun only view passes ([`VolumePassDecl::camera`]).
#[derive(Debug, Clone)]
pub struct VolumePassDecl {
    pub target: &'static str,
    pub format: StorageFormat,
    /// Size of the target relative to the volume (1 = one texel per voxel).
    pub scale: f32,
    /// The pass function in the plugin's hook file.
    pub entry: &'static str,
    pub depends_on: Vec<&'static str>,
    /// Progressive refinement: the number of steps under the instance's parameters
    /// (at least 1 is run; None: one step). Step `step` (0-based) is dispatched with that index; the
    /// renderer runs as many steps per frame as its refinement budget allows
    /// ([`crate::renderer::Renderer::set_refinement_budget`]; all by default), so a
    /// window refines over several frames.
    pub steps: Option<PassSteps>,
    /// The pass reads its own previous texel as `prev` (read-write storage; R32Float
    /// only), e.g. to blend a refinement step into the stored result.
    pub accumulate: bool,
    /// A view pass: it depends on the camera (it may read `frame.eye`,
    /// `frame.forward`, `frame.view_proj`), so it also reruns, with every later pass of
    /// the chain, whenever the view or the projection changes; other passes never rerun
    /// for the camera. An atlas (many views in one submission) reruns it before each
    /// tile whose camera differs from the last. The twin's `prepare_passes` already
    /// runs again for a new camera.
    pub camera: bool,
    /// A sweep: the pass runs plane by plane along a direction instead of over the
    /// whole target at once ([`SweepDecl`], `crate::sweep`).
    pub sweep: Option<SweepDecl>,
}

/// A volume pass that sweeps its target plane by plane along a direction (a light's):
/// the slicing direction other than the view. The planes are normal to the target axis
/// the direction advances most along; each texel gets `prev`, the previous plane's
/// value at its upstream point (bilinear; [`SweepDecl::boundary`] upstream of the first
/// plane and outside the planes), and its entry is
/// `fn <entry>(voxel: vec3<u32>, dims: vec3<u32>, plane: u32, prev: vec4<f32>, length: f32) -> vec4<f32>`
/// with `length` the world path length between two planes along the direction. The
/// target is r32float. Its twin is [`crate::sweep::Sweep::run`].
#[derive(Clone)]
pub struct SweepDecl {
    /// The direction of travel (world space, any length) under the instance's
    /// parameters; list the parameters it reads in `depends_on`.
    pub direction: Arc<SweepDirection>,
    /// The value the light enters with.
    pub boundary: f32,
}

/// A progressive pass's number of refinement steps under an instance's parameters
/// ([`VolumePassDecl::steps`]).
#[derive(Clone)]
pub struct PassSteps(pub Arc<dyn Fn(&ParamValues) -> u32 + Send + Sync>);

impl PassSteps {
    pub fn count(&self, params: &ParamValues) -> u32 {
        (self.0)(params)
    }
}

impl std::fmt::Debug for PassSteps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("PassSteps(..)")
    }
}

/// A sweep's direction of travel under an instance's parameters.
pub type SweepDirection = dyn Fn(&ParamValues) -> [f32; 3] + Send + Sync;

impl std::fmt::Debug for SweepDecl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SweepDecl")
            .field("boundary", &self.boundary)
            .finish_non_exhaustive()
    }
}

impl VolumePassDecl {
    /// A pass writing the r32float target `target` at the volume's resolution from the
    /// hook-file function `entry`, depending on no parameter, one step, not a view
    /// pass; the builder methods below change that.
    pub fn new(target: &'static str, entry: &'static str) -> Self {
        Self {
            target,
            format: StorageFormat::R32Float,
            scale: 1.0,
            entry,
            depends_on: Vec::new(),
            steps: None,
            accumulate: false,
            camera: false,
            sweep: None,
        }
    }
    /// A sweep along `direction(params)` ([`SweepDecl`]), entering with `boundary`.
    pub fn sweep(
        mut self,
        direction: impl Fn(&ParamValues) -> [f32; 3] + Send + Sync + 'static,
        boundary: f32,
    ) -> Self {
        self.sweep = Some(SweepDecl {
            direction: Arc::new(direction),
            boundary,
        });
        self
    }
    /// The target's size relative to the volume.
    pub fn scale(mut self, scale: f32) -> Self {
        self.scale = scale;
        self
    }
    /// The parameters whose change reruns it.
    pub fn depends_on(mut self, keys: &[&'static str]) -> Self {
        self.depends_on = keys.to_vec();
        self
    }
    /// Progressive: `steps(params)` refinement steps, each reading its own previous
    /// texel ([`VolumePassDecl::accumulate`]).
    pub fn progressive(
        mut self,
        steps: impl Fn(&ParamValues) -> u32 + Send + Sync + 'static,
    ) -> Self {
        self.steps = Some(PassSteps(Arc::new(steps)));
        self.accumulate = true;
        self
    }
    /// A view pass ([`VolumePassDecl::camera`]).
    pub fn view(mut self) -> Self {
        self.camera = true;
        self
    }
}

/// What [`Plugin::statistics`] reads: the document's volume and named volumes (what a
/// plugin compares its passes' output with, e.g. its CPU twin's) and the instance's
/// volume-pass targets as the GPU left them after the last frame (by target name, or
/// `prepass` for its pre-pass target: size and f32 components, x fastest; None where
/// the pass is absent).
pub struct PassOutputs<'a> {
    pub volume: &'a Volume,
    pub inputs: &'a crate::inputs::VolumeInputs,
    pub read: &'a ReadPassTarget<'a>,
}

/// A volume-pass target read back: its size and its texels' f32 components.
pub type PassTarget = ([u32; 3], Vec<f32>);

/// Reads an instance's volume-pass target by name ([`PassOutputs::read`]).
pub type ReadPassTarget<'a> = dyn Fn(&str) -> Option<PassTarget> + 'a;

/// A figure a plugin reports about what its passes computed (e.g. flat blocking's data
/// reduction), for experiment reports (`statistics:` in an experiment file, named
/// `<plugin id>.<name>`).
#[derive(Debug, Clone, PartialEq)]
pub struct Statistic {
    pub name: &'static str,
    pub value: f64,
}

/// A numerical study of a plugin's CPU twin on its own, with no image and no GPU: an
/// integrator's drift on an analytic field, a twin's error against a finer twin of
/// itself, its CPU time. An experiment file runs it over variants and a grid of its
/// parameters (`probe:` in the file, docs/experiments.md), so that a plugin's own
/// numerics are studied as its images are, with a report, assertions and a doc block.
pub trait Probe: Send + Sync {
    /// Unique within its plugin; experiment files name it `<plugin id>.<name>`.
    fn name(&self) -> &'static str;
    /// One line: what it computes, on what.
    fn description(&self) -> &'static str;
    /// Its parameters, with their defaults and ranges (checked as a plugin's are).
    fn params(&self) -> Vec<ParamSpec>;
    /// The figures every run reports: (name, what it is and its unit).
    fn figures(&self) -> Vec<(&'static str, &'static str)>;
    /// Runs at `params` (every key of [`Probe::params`], checked); returns each figure
    /// of [`Probe::figures`] once. Errors are for inputs the ranges cannot express.
    fn run(&self, params: &ParamValues) -> Result<Vec<Statistic>, String>;
}

/// What a plugin gets to create and update its resources.
pub struct GpuInit<'a> {
    pub device: &'a wgpu::Device,
    pub queue: &'a wgpu::Queue,
    pub features: wgpu::Features,
    /// The adapter's kind: CPU devices and GPUs keep some resources in different
    /// formats ([`GpuInit::sample_table_format`]).
    pub device_type: wgpu::DeviceType,
    /// How the classification tables are asked to be stored
    /// ([`GpuInit::sample_table_format`]).
    pub table_format: crate::renderer::TableFormat,
    pub volume: &'a Volume,
    /// The document's named volumes ([`crate::inputs`]).
    pub inputs: &'a VolumeInputs,
    /// The slice spacing of the frame being drawn, in voxels (Δs/Δs0; 1 before the
    /// first frame). Plugins whose resources depend on it say so with
    /// [`Plugin::uses_slice_spacing`].
    pub slice_spacing: f32,
}

impl GpuInit<'_> {
    /// The volume the input `key` of `params` names ([`crate::params::ParamKind::Volume`]):
    /// a named volume or, for an empty name, the document's own. The renderer has
    /// checked the name and the components before it asks for resources.
    pub fn input(&self, params: &ParamValues, key: &str) -> Result<&Volume, PluginError> {
        self.inputs
            .resolve(self.volume, params, key)
            .map_err(|message| PluginError::Invalid {
                plugin: "volume input".into(),
                message,
            })
    }

    /// A `width` × `height` lookup-table texture in [`GpuInit::lut_format`], sampled by
    /// hooks with `linear_clamp`; fill it with [`GpuInit::write_table`].
    pub fn create_table(&self, label: &str, width: u32, height: u32) -> GpuResource {
        self.table(
            label,
            [width, height],
            wgpu::TextureDimension::D2,
            self.lut_format(),
        )
    }

    /// A `width` × `height` table that a classification reads at every sample, in
    /// [`GpuInit::sample_table_format`]; otherwise as [`GpuInit::create_table`].
    pub fn create_sample_table(&self, label: &str, width: u32, height: u32) -> GpuResource {
        let format = self.sample_table_format();
        self.table(label, [width, height], wgpu::TextureDimension::D2, format)
    }

    /// A one-row table that a classification reads at every sample, as a 1D texture
    /// (`ResourceKind::Texture1d`), in the format of
    /// [`GpuInit::create_sample_table`]. `textureSampleLevel(t, s, x, 0.0)` gives
    /// what a 256 × 1 2D table gives (its second row has weight zero) at half the texel
    /// reads; on lavapipe the lookup takes about three quarters of the 2D one's time
    /// (docs/perf.md, "Sample fetch").
    pub fn create_table_1d(&self, label: &str, width: u32) -> GpuResource {
        let format = self.sample_table_format();
        self.table(label, [width, 1], wgpu::TextureDimension::D1, format)
    }

    fn table(
        &self,
        label: &str,
        [width, height]: [u32; 2],
        dimension: wgpu::TextureDimension,
        format: wgpu::TextureFormat,
    ) -> GpuResource {
        let texture = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension,
            format,
            // COPY_SRC: what a table holds can be read back (tests)
            usage: wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        GpuResource {
            view: texture.create_view(&Default::default()),
            texture,
        }
    }

    /// Uploads straight RGBA texels (row by row, the texture's full size) into a table
    /// texture, converting to its format (rgba32float or rgba16float).
    pub fn write_table(&self, table: &GpuResource, texels: &[[f32; 4]]) {
        self.write_floats(table, texels.as_flattened());
    }

    /// A filterable `dims` 3D float texture with 1 or 4 channels, sampled by hooks with
    /// `linear_clamp`: 32-bit where the device filters those, else 16-bit. Fill it with
    /// [`GpuInit::write_floats`].
    pub fn create_volume_texture(&self, label: &str, dims: [u32; 3], channels: u32) -> GpuResource {
        self.create_volume_texture_as(label, dims, channels, false)
    }

    /// Like [`GpuInit::create_volume_texture`], in r16float / rgba16float also where
    /// 32-bit floats are filterable when `half` (half the memory and texture traffic;
    /// [`GpuInit::write_floats`] rounds to fp16).
    pub fn create_volume_texture_as(
        &self,
        label: &str,
        dims: [u32; 3],
        channels: u32,
        half: bool,
    ) -> GpuResource {
        let half = half || !self.features.contains(wgpu::Features::FLOAT32_FILTERABLE);
        let format = match (channels, half) {
            (1, false) => wgpu::TextureFormat::R32Float,
            (1, true) => wgpu::TextureFormat::R16Float,
            (_, false) => wgpu::TextureFormat::Rgba32Float,
            (_, true) => wgpu::TextureFormat::Rgba16Float,
        };
        let texture = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: dims[0],
                height: dims[1],
                depth_or_array_layers: dims[2],
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D3,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        GpuResource {
            view: texture.create_view(&Default::default()),
            texture,
        }
    }

    /// Uploads float values (x fastest, as many per texel as the texture has channels,
    /// the texture's full size, 2D or 3D), converting to its 32- or 16-bit float format.
    pub fn write_floats(&self, r: &GpuResource, values: &[f32]) {
        let format = r.texture.format();
        let bytes: Vec<u8> = match format {
            wgpu::TextureFormat::Rgba32Float | wgpu::TextureFormat::R32Float => {
                bytemuck::cast_slice(values).to_vec()
            }
            _ => values
                .iter()
                .flat_map(|v| half::f16::from_f32(*v).to_le_bytes())
                .collect(),
        };
        let size = r.texture.size();
        let bpp = format.block_copy_size(None).unwrap_or(16);
        self.queue.write_texture(
            r.texture.as_image_copy(),
            &bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(size.width * bpp),
                rows_per_image: Some(size.height),
            },
            size,
        );
    }

    /// Float format for lookup tables: rgba32float where filterable, else rgba16float.
    pub fn lut_format(&self) -> wgpu::TextureFormat {
        if self.features.contains(wgpu::Features::FLOAT32_FILTERABLE) {
            wgpu::TextureFormat::Rgba32Float
        } else {
            wgpu::TextureFormat::Rgba16Float
        }
    }

    /// Format of the tables a classification reads at every sample (transfer
    /// functions, pre-integration tables: [`GpuInit::create_sample_table`]) as
    /// `table_format` asks ([`crate::renderer::TableFormat`]); `auto`: rgba16float on
    /// GPUs, where the filtered read of a 128-bit texel is what plain DVR waits on (an
    /// H200: 0.55–0.69× the CT head's frame without skipping; docs/perf.md,
    /// "Classification tables in 16-bit floats on GPUs"), [`GpuInit::lut_format`] on
    /// CPU devices, whose images stay those of 32-bit tables. `VWB_LUT_FORMAT`
    /// (`rgba32float`, `rgba16float`) overrides `auto`: a benchmark switch.
    pub fn sample_table_format(&self) -> wgpu::TextureFormat {
        use crate::renderer::TableFormat;
        let mut asked = self.table_format;
        if asked.is_auto() {
            match std::env::var("VWB_LUT_FORMAT").as_deref().map(str::trim) {
                Ok("rgba16float") => asked = TableFormat::Rgba16Float,
                Ok("rgba32float") => asked = TableFormat::Rgba32Float,
                _ => {}
            }
        }
        match asked {
            TableFormat::Rgba16Float => wgpu::TextureFormat::Rgba16Float,
            TableFormat::Rgba32Float => self.lut_format(),
            TableFormat::Auto if self.device_type == wgpu::DeviceType::Cpu => self.lut_format(),
            TableFormat::Auto => wgpu::TextureFormat::Rgba16Float,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum PluginError {
    #[error("{plugin}: {message}")]
    Invalid { plugin: String, message: String },
}

/// A sample on the CPU (f64), mirroring the WGSL `Sample`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CpuSample {
    pub pos: DVec3,
    pub tex: DVec3,
    pub ray_dir: DVec3,
    pub uv: DVec2,
    pub value: f64,
    pub step: f64,
    pub color: DVec4,
    pub normal: DVec3,
    pub slice: u32,
    /// Where shading reads the gradient, as a fraction of `step` ahead along the ray
    /// (0: at the sample; set by pre-integrated classification's `shade_at: centroid`).
    pub shade_at: f64,
    /// The twin of the instance's `ray_record`: what its [`CpuTwin::setup`] returned for
    /// this ray (zero for plugins without one, and outside a ray as in volume passes).
    /// Not part of the WGSL `Sample`: each instance's record is a private variable.
    pub ray_record: DVec4,
}

/// A pixel's ray as `setup` sees it (the WGSL `Ray` and the `uv` beside it).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CpuRay {
    /// The eye for a perspective camera; the pixel's point on the plane through the
    /// eye (normal to the view direction) for an orthographic one.
    pub origin: DVec3,
    /// Unit direction.
    pub dir: DVec3,
    /// Screen coordinate in \[0,1\]² (y down) of the pixel centre.
    pub uv: DVec2,
    /// The image (or atlas tile) size in pixels (`frame.viewport.xy`).
    pub size: DVec2,
}

impl CpuSample {
    /// `shading_tex(s)`: the texture coordinate where shading plugins evaluate the
    /// gradient.
    pub fn shading_tex(&self, ctx: &CpuContext) -> DVec3 {
        if self.shade_at == 0.0 {
            return self.tex;
        }
        let (lo, hi) = ctx.volume_box();
        self.tex + self.ray_dir * (self.step * self.shade_at) / (hi - lo)
    }
}

/// The camera and slice geometry as CPU twins see them (the twin of `frame.eye`,
/// `frame.forward`, the columns 0 and 1 of `frame.ray_basis` and the slice depths),
/// for view-space lights and image-space kernels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CpuView {
    pub eye: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    pub forward: DVec3,
    /// Lengths of `ray_basis` columns 0 and 1: world units per NDC unit (at unit
    /// depth for perspective).
    pub ray_scale: DVec2,
    pub perspective: bool,
    /// Eye depth of slice 0 along `forward` (`frame.box_max.w`) and the slice spacing
    /// in world units (`frame.forward.w`).
    pub slice_depth0: f64,
    pub slice_spacing: f64,
    /// Under half-angle slicing, the light's space of the per-slice state
    /// ([`crate::slicing::HalfAngle`], as uploaded); `None`: view-aligned slicing,
    /// the state in eye-buffer space.
    pub light: Option<CpuLightSpace>,
}

/// The per-slice state's light space under half-angle slicing (the twin of
/// `frame.slicing`, `frame.light` and `frame.state_rays`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CpuLightSpace {
    /// Unit slice-plane normal.
    pub normal: DVec3,
    /// Unit direction the light travels.
    pub dir: DVec3,
    /// Path length along the light between two slice planes.
    pub step: f64,
    /// One state-NDC unit right and up (world), and the state image's centre.
    pub right: DVec3,
    pub up: DVec3,
    pub origin: DVec3,
}

impl CpuLightSpace {
    pub fn new(h: &crate::slicing::HalfAngle) -> Self {
        let m = h.state_rays.as_dmat4();
        Self {
            normal: h.normal.as_dvec3(),
            dir: m.z_axis.truncate(),
            step: h.light_step as f64,
            right: m.x_axis.truncate(),
            up: m.y_axis.truncate(),
            origin: m.w_axis.truncate(),
        }
    }

    /// The state ray through state coordinate `uv`: origin upstream of the box, and
    /// the light's direction (`state_ray`).
    pub fn ray(&self, uv: DVec2) -> (DVec3, DVec3) {
        let ndc = DVec2::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
        (self.origin + self.right * ndc.x + self.up * ndc.y, self.dir)
    }

    /// The state coordinate of a world point (`light_uv`).
    pub fn uv(&self, p: DVec3) -> DVec2 {
        let q = p - self.origin;
        let ndc = DVec2::new(
            q.dot(self.right) / self.right.length_squared(),
            q.dot(self.up) / self.up.length_squared(),
        );
        DVec2::new(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5)
    }
}

impl Default for CpuView {
    /// A camera on +z looking down −z.
    fn default() -> Self {
        Self {
            eye: DVec3::new(0.0, 0.0, 2.0),
            right: DVec3::X,
            up: DVec3::Y,
            forward: DVec3::NEG_Z,
            ray_scale: DVec2::ONE,
            perspective: false,
            slice_depth0: 0.0,
            slice_spacing: 1.0,
            light: None,
        }
    }
}

impl CpuView {
    /// The view of a frame whose slice 0 lies at eye depth `slice_depth0` with
    /// `slice_spacing` world units between slices (both as uploaded, f32).
    pub fn from_view(v: &crate::camera::View, slice_depth0: f32, slice_spacing: f32) -> Self {
        let inv = v.view.as_dmat4().inverse();
        let p = v.proj.as_dmat4();
        Self {
            eye: v.eye.as_dvec3(),
            right: inv.x_axis.truncate().normalize(),
            up: inv.y_axis.truncate().normalize(),
            forward: v.forward.as_dvec3(),
            ray_scale: DVec2::new(1.0 / p.x_axis.x, 1.0 / p.y_axis.y).abs(),
            perspective: v.perspective,
            slice_depth0: slice_depth0 as f64,
            slice_spacing: slice_spacing as f64,
            light: None,
        }
    }

    /// Screen-uv units per world unit on the plane of slice `k` (the twin of the
    /// perspective correction of Schott et al. 2009, eqs 12–15: NDC per world unit
    /// at the slice's depth, halved for uv).
    pub fn uv_per_world(&self, k: u32) -> DVec2 {
        let depth = if self.perspective {
            (self.slice_depth0 + k as f64 * self.slice_spacing).max(1.0e-9)
        } else {
            1.0
        };
        0.5 / (self.ray_scale * depth)
    }

    /// State-uv units per world unit across the state's rays on the plane of slice
    /// `k` (`state_uv_per_world`): [`CpuView::uv_per_world`], or the light space's
    /// under half-angle slicing.
    pub fn state_uv_per_world(&self, k: u32) -> DVec2 {
        match &self.light {
            Some(l) => 0.5 / DVec2::new(l.right.length(), l.up.length()),
            None => self.uv_per_world(k),
        }
    }

    /// Where a sample reads per-slice state (`state_coord`): its screen coordinate, or
    /// its light-space coordinate under half-angle slicing ([`CpuLightSpace::uv`]).
    pub fn state_coord(&self, s: &CpuSample) -> DVec2 {
        match &self.light {
            Some(l) => l.uv(s.pos),
            None => s.uv,
        }
    }

    /// The path length of the state's rays between two slice planes (`state_step`):
    /// the slice spacing, or the light's step under half-angle slicing.
    pub fn state_step(&self) -> f64 {
        match &self.light {
            Some(l) => l.step,
            None => self.slice_spacing,
        }
    }
}

/// What CPU twins can read: the volume, its normalised scalars, the camera and, for a
/// plugin with per-slice state, its state of the previous slice.
#[derive(Clone, Copy)]
pub struct CpuContext<'a> {
    pub volume: &'a Volume,
    /// Normalised scalars in \[0,1\], x fastest (as uploaded to the GPU).
    pub scalars: &'a [f32],
    /// The plugin's state of the previous slice (`state_prev`), if it has one.
    pub state: Option<&'a StateImage>,
    /// Slice spacing of the frame in voxels (Δs/Δs0), as `GpuInit::slice_spacing`.
    pub spacing: f64,
    /// The frame's camera.
    pub view: CpuView,
    /// The scalar the stack's sample hooks give, where a twin supplies it
    /// ([`CpuTwin::scalar`]); the gradient estimators differentiate it
    /// ([`CpuContext::shading_value`]).
    pub scalar: Option<&'a dyn ScalarField>,
    /// The document's named volumes ([`crate::inputs`]), as the GPU has them.
    pub inputs: &'a VolumeInputs,
}

/// The twin of a plugin's `scalar(tex)` and `scalar_grid()` (render/src/composer.rs):
/// the value its `sample` hook gives at a texture coordinate, and the grid it lives on.
pub trait ScalarField: Send + Sync {
    fn value(&self, ctx: &CpuContext, tex: DVec3) -> f64;
    fn grid(&self, ctx: &CpuContext) -> [u32; 3];
}

/// A per-slice state image on the CPU (the twin of a `state_prev` texture).
#[derive(Debug, Clone, PartialEq)]
pub struct StateImage {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<DVec4>,
}

impl StateImage {
    pub fn new(width: u32, height: u32, clear: DVec4) -> Self {
        Self {
            width,
            height,
            texels: vec![clear; width as usize * height as usize],
        }
    }

    /// Bilinear read at `uv` with texel centres at (i + 0.5)/n and clamp-to-edge, as
    /// `textureSampleLevel(state_prev, linear_clamp, uv, 0.0)`.
    pub fn sample(&self, uv: DVec2) -> DVec4 {
        let (w, h) = (self.width.max(1) as f64, self.height.max(1) as f64);
        let x = (uv.x * w - 0.5).clamp(0.0, w - 1.0);
        let y = (uv.y * h - 0.5).clamp(0.0, h - 1.0);
        if !(x.is_finite() && y.is_finite()) {
            return self.texels[0];
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let x1 = (x0 + 1).min(self.width as usize - 1);
        let y1 = (y0 + 1).min(self.height as usize - 1);
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let at = |x: usize, y: usize| self.texels[y * self.width as usize + x];
        let top = at(x0, y0).lerp(at(x1, y0), fx);
        let bottom = at(x0, y1).lerp(at(x1, y1), fx);
        top.lerp(bottom, fy)
    }
}

impl<'a> CpuContext<'a> {
    pub fn new(volume: &'a Volume, scalars: &'a [f32]) -> Self {
        Self {
            volume,
            scalars,
            state: None,
            spacing: 1.0,
            view: CpuView::default(),
            scalar: None,
            inputs: VolumeInputs::empty(),
        }
    }

    /// The same context with the document's named volumes.
    pub fn with_inputs(self, inputs: &'a VolumeInputs) -> Self {
        Self { inputs, ..self }
    }

    /// The volume the input `key` of `params` names, as [`GpuInit::input`] resolves it
    /// (the document's own volume where the name is unknown; the reference renderer
    /// refuses such a stack before any twin runs).
    pub fn input(&self, params: &ParamValues, key: &str) -> &'a Volume {
        self.inputs
            .resolve(self.volume, params, key)
            .unwrap_or(self.volume)
    }

    /// The same context with the shading scalar of the last twin that supplies one
    /// (the GPU's `shading_value` is the last provider's `scalar`).
    pub fn with_scalar_of(self, twins: &'a [Box<dyn CpuTwin>]) -> Self {
        Self {
            scalar: twins.iter().rev().find_map(|t| t.scalar()),
            ..self
        }
    }

    /// `shading_value(tex)`: the scalar the gradient estimators differentiate (the
    /// volume's value unless a twin supplies its own).
    pub fn shading_value(&self, tex: DVec3) -> f64 {
        match self.scalar {
            Some(f) => f.value(
                &Self {
                    scalar: None,
                    ..*self
                },
                tex,
            ),
            None => self.value(tex),
        }
    }

    /// `shading_grid()`: the grid of [`CpuContext::shading_value`].
    pub fn shading_grid(&self) -> [u32; 3] {
        match self.scalar {
            Some(f) => f.grid(&Self {
                scalar: None,
                ..*self
            }),
            None => self.volume.dims,
        }
    }

    /// The same context for a frame seen by `view`.
    pub fn with_view(self, view: CpuView) -> Self {
        Self { view, ..self }
    }

    /// The same context for a frame with slice spacing `spacing` (voxels).
    pub fn with_spacing(self, spacing: f64) -> Self {
        Self { spacing, ..self }
    }

    /// The volume box in world space (min, max), as the GPU's `frame.box_min/max`.
    pub fn volume_box(&self) -> (DVec3, DVec3) {
        let b = crate::slicing::VolumeBox::new(self.volume.dims, self.volume.spacing);
        (b.min.as_dvec3(), b.max.as_dvec3())
    }

    /// Δs0: the world length of one voxel along the finest axis (`frame.box_min.w`),
    /// the step at which opacities are defined.
    pub fn reference_step(&self) -> f64 {
        crate::slicing::VolumeBox::new(self.volume.dims, self.volume.spacing).voxel as f64
    }

    /// The previous slice's state at `uv` (zero for a plugin without state).
    pub fn state_prev(&self, uv: DVec2) -> DVec4 {
        self.state.map_or(DVec4::ZERO, |s| s.sample(uv))
    }

    /// Trilinear interpolation at a texture coordinate, with texel centres at
    /// (i + 0.5)/n and clamp-to-edge, as the GPU sampler does.
    pub fn value(&self, tex: DVec3) -> f64 {
        self.trilinear(tex, |i| DVec4::splat(self.scalars[i] as f64))
            .x
    }

    /// Trilinear interpolation at `tex` (as [`CpuContext::value`]) of a per-voxel
    /// quantity: `voxel(i)` for the voxel at linear index i (x fastest), e.g. a
    /// classified colour (the twin of sampling a pre-pass target of scale 1).
    pub fn trilinear(&self, tex: DVec3, voxel: impl Fn(usize) -> DVec4) -> DVec4 {
        trilinear_grid(self.volume.dims, tex, voxel)
    }
}

/// Trilinear interpolation at a texture coordinate of a `dims` grid with texel centres
/// at (i + 0.5)/n and clamp-to-edge, as `textureSampleLevel(.., linear_clamp, ..)`
/// reads a 3D texture; `voxel(i)` is the texel at linear index i (x fastest). The CPU
/// twin of sampling any 3D target (a volume pass's at its own resolution, too).
pub fn trilinear_grid(dims: [u32; 3], tex: DVec3, voxel: impl Fn(usize) -> DVec4) -> DVec4 {
    let d = dims;
    let mut i0 = [0usize; 3];
    let mut i1 = [0usize; 3];
    let mut t = [0.0f64; 3];
    for a in 0..3 {
        let n = d[a].max(1) as f64;
        let x = (tex[a] * n - 0.5).clamp(0.0, n - 1.0);
        let f = x.floor();
        i0[a] = f as usize;
        i1[a] = (i0[a] + 1).min(d[a].max(1) as usize - 1);
        t[a] = x - f;
    }
    let at = |x: usize, y: usize, z: usize| voxel((z * d[1] as usize + y) * d[0] as usize + x);
    let c00 = at(i0[0], i0[1], i0[2]).lerp(at(i1[0], i0[1], i0[2]), t[0]);
    let c10 = at(i0[0], i1[1], i0[2]).lerp(at(i1[0], i1[1], i0[2]), t[0]);
    let c01 = at(i0[0], i0[1], i1[2]).lerp(at(i1[0], i0[1], i1[2]), t[0]);
    let c11 = at(i0[0], i1[1], i1[2]).lerp(at(i1[0], i1[1], i1[2]), t[0]);
    c00.lerp(c10, t[1]).lerp(c01.lerp(c11, t[1]), t[2])
}

/// CPU twin of a plugin's GPU hooks, in f64. Each method mirrors the WGSL hook of the
/// same name; the defaults do what an absent hook does.
pub trait CpuTwin: Send + Sync {
    /// Called once per frame before any sample, with the frame's context (e.g. to
    /// build tables that depend on the slice spacing, as `update_resources` does on
    /// the GPU).
    fn prepare(&mut self, _ctx: &CpuContext) {}
    fn clip(&self, _s: &CpuSample) -> bool {
        true
    }
    fn sample(&self, _ctx: &CpuContext, _s: &mut CpuSample) {}
    fn classify(&self, _ctx: &CpuContext, _s: &mut CpuSample) {}
    fn shade(&self, _ctx: &CpuContext, _s: &mut CpuSample) {}
    fn composite(&self, _s: &CpuSample, _c: &mut DVec4) {}
    /// Once per ray before its samples (`setup`): this instance's per-ray record, which
    /// the reference puts in [`CpuSample::ray_record`] before each of the instance's
    /// other hooks.
    fn setup(&self, _ctx: &CpuContext, _ray: &CpuRay) -> DVec4 {
        DVec4::ZERO
    }
    /// Once per pixel after the loop: the accumulated premultiplied colour at the
    /// pixel's uv, before the background.
    fn post(&self, _c: &mut DVec4, _uv: DVec2) {}
    /// The next state texel (plugins with per-slice state): `s` is the shaded sample of
    /// the current slice under the texel, `c` its premultiplied contribution, `uv` the
    /// texel centre; `ctx.state_prev` reads the previous state.
    fn slice_update(&self, _ctx: &CpuContext, _s: &CpuSample, _c: DVec4, _uv: DVec2) -> DVec4 {
        DVec4::ZERO
    }
    /// The twin of the plugin's volume passes, called once per frame after
    /// [`CpuTwin::prepare`]: `classify(tex, dir)` is `stack_classify` (the other
    /// twins' clip, sample and classify at a texture coordinate; zero where clipped).
    fn prepare_passes(&mut self, _ctx: &CpuContext, _classify: &StackClassify<'_>) {}
    /// The twin of the hook file's `scalar` and `scalar_grid` (a plugin whose `sample`
    /// hook replaces the value and supplies it for shading).
    fn scalar(&self) -> Option<&dyn ScalarField> {
        None
    }
}

/// The CPU twin of `stack_classify(tex, dir)` ([`CpuTwin::prepare_passes`]).
pub type StackClassify<'a> = dyn Fn(DVec3, DVec3) -> DVec4 + Sync + 'a;

/// Whether any value in `[lo, hi]` (normalised) can be classified with α > 0.
pub type VisibleFn = dyn Fn(f64, f64) -> bool + Send + Sync;

/// What a plugin promises about transparent samples, for empty-space skipping
/// ([`crate::skipping`]). A wrong promise changes images, so the default promises
/// nothing.
#[derive(Clone)]
pub enum Transparency {
    /// No promise (the default): skipping is off while the plugin is enabled. Right
    /// for plugins that replace `s.value`, make opacity out of nothing, composite from
    /// something other than the contribution (e.g. maximum intensity), or read the
    /// shaded sample in `slice_update` beyond its contribution.
    Unknown,
    /// Samples that reach the plugin with α = 0 leave it with α = 0 and contribute
    /// nothing (clipping, shading that changes colour only).
    Keeps,
    /// A classifier that sets the colour from `s.value` alone: the function says
    /// whether some value in the range gets α > 0. It must be conservative (answer
    /// true when unsure).
    ByValue(Arc<VisibleFn>),
    /// Keeps (as [`Transparency::Keeps`]), and drops every sample outside a region of
    /// world space (clipping): the function says whether some point of the world box
    /// (min, max) can be kept. It must be conservative (answer true when unsure).
    /// Bricks wholly outside are skipped.
    Region(Arc<RegionFn>),
    /// Keeps (as [`Transparency::Keeps`]), but moves each sample along its ray by at
    /// most this many slice steps before the later hooks read it (`sample.jitter`): a
    /// sample tested in one brick may read voxels beyond it, so the renderer takes the
    /// bricks' value ranges over an apron widened by that distance at the frame's slice
    /// spacing ([`crate::skipping::move_apron`]), widens clip regions alike, and
    /// skipping stays exact.
    Moves(f64),
    /// A classifier, as [`Transparency::ByValue`], whose colour at a sample also
    /// depends on values up to this many slice steps ahead along its ray
    /// (pre-integration's slab reads the value where the ray meets the next slice).
    /// The function says whether some value in the range gets α > 0, over a slab
    /// whose two ends lie in the range. The renderer widens the bricks' ranges by
    /// that reach, as for [`Transparency::Moves`]: a sample is then skipped only when
    /// every value its slab can read is transparent, and skipping stays exact.
    ByValueAhead(Arc<VisibleFn>, f64),
    /// A plugin after the classification that leaves transparent samples transparent
    /// except where the function says a value range can make them visible, reading
    /// values up to this many slice steps ahead along the ray (`shade.isosurface`: a
    /// surface met between the sample and the next slice). The renderer joins the
    /// function to the classification's promise (either may make a brick visible) and
    /// widens the bricks' ranges by the reach, as for [`Transparency::ByValueAhead`].
    Adds(Arc<VisibleFn>, f64),
}

/// Whether some point of a world box (min, max) can lie in a plugin's region.
pub type RegionFn = dyn Fn(DVec3, DVec3) -> bool + Send + Sync;

/// A converged reference that a plugin supplies itself, because refining the slices
/// converges to the slice algorithm's own limit rather than to the model the plugin
/// approximates (directional occlusion: the Monte-Carlo cone integral). The measurement
/// code asks the stack's plugins for one ([`Plugin::converged_reference`]) and never
/// names a plugin.
pub trait ConvergedReference: Send + Sync {
    /// Its name in reports (`metrics.json`'s `against.kind`), e.g. `monte_carlo`.
    fn kind(&self) -> &'static str;
    /// Its name for people, e.g. `Monte Carlo`.
    fn label(&self) -> &'static str;
    /// The reference image of the frame (premultiplied RGBA, rows top to bottom).
    fn render(
        &self,
        volume: &Volume,
        stack: &[PluginInstance],
        settings: &crate::renderer::FrameSettings,
        cancel: Option<&std::sync::atomic::AtomicBool>,
    ) -> Result<SuppliedReference, String>;
    /// What the reference of this stack depends on, as a cache key (two stacks with the
    /// same key give the same image for the same frame), or `None` to key it by the
    /// whole enabled stack. A Monte-Carlo integral ignores the slice algorithm's own
    /// knobs (kernel, buffers), so one reference serves all of them.
    fn key(&self, _stack: &[PluginInstance]) -> Option<String> {
        None
    }
    /// This reference with named options (an experiment's `reference_options`, e.g. the
    /// Monte-Carlo sample counts). Unknown names and values out of range are errors; the
    /// default takes no options.
    fn with_options(
        &self,
        options: &std::collections::BTreeMap<String, f64>,
    ) -> Result<Arc<dyn ConvergedReference>, String> {
        Err(format!(
            "the {} reference takes no options (got {})",
            self.label(),
            options.keys().cloned().collect::<Vec<_>>().join(", ")
        ))
    }
}

/// An image from a [`ConvergedReference`].
#[derive(Debug, Clone, PartialEq)]
pub struct SuppliedReference {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f64; 4]>,
    /// How it was made (sample counts, seed, steps, statistical error), for reports.
    pub notes: Vec<(&'static str, f64)>,
}

/// The most loop iterations a plugin's hooks run for one sample, counted as llvmpipe's
/// loop limiter counts them (every pass of a loop's body, and one for every loop the
/// code reaches even where it is not entered); constant loops the compiler unrolls cost
/// nothing. The renderer marches a frame in parts small enough for them on a CPU device
/// ([`crate::renderer::march_parts`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LoopIterations {
    /// Those of its hooks (clip, sample, classify, shade, composite) for one sample.
    pub sample: u32,
    /// Those of one call of its `scalar(tex)` (the value the stack's gradient
    /// estimators differentiate: 6 reads a sample under central differences, 26 under
    /// Sobel, none precomputed).
    pub scalar: u32,
}

/// A plugin type. Instances (with their own parameter values) live in a stack.
pub trait Plugin: Send + Sync + 'static {
    /// Stable id `category.name`, e.g. `classify.tf1d`.
    fn id(&self) -> &'static str;
    fn display_name(&self) -> &'static str;
    fn description(&self) -> &'static str {
        ""
    }
    fn category(&self) -> Category {
        self.id()
            .split('.')
            .next()
            .and_then(Category::from_name)
            .unwrap_or(Category::Test)
    }
    fn params(&self) -> Vec<ParamSpec>;
    /// The hook functions.
    fn shader(&self) -> ShaderSource;
    fn resources(&self) -> Vec<ResourceDecl> {
        Vec::new()
    }
    fn slice_state(&self) -> Option<SliceStateDecl> {
        None
    }
    /// The direction (world space, any length) a light travels along which this
    /// plugin's per-slice state sweeps under `params`, seen from `view`; `None` (the
    /// default): the state travels with the eye. Asked only where the plugin's
    /// [`SliceStateDecl::light`] is set (make the parameters that name a light
    /// structural). Where an enabled instance of a stack
    /// returns one, the frame is sliced halfway between the view and that light
    /// ([`crate::slicing::HalfAngle`]) and every per-slice state lives in the light's
    /// space; the first such instance in stack order decides.
    fn slice_light(
        &self,
        _params: &ParamValues,
        _view: &crate::camera::View,
    ) -> Option<glam::Vec3> {
        None
    }
    /// How far one slice's state update reaches under `params`: the radius, in world
    /// units per world unit of the slice spacing, on the slice's plane, within which an
    /// update reads the previous slice's state (besides the bilinear footprint of the
    /// reads). Stating it promises, for a slice's sample that is transparent (α = 0:
    /// clipped, skipped or classified away), that the update reads of the sample only
    /// its opacity, `slice` and `uv`, and that where every texel of `state_prev` within
    /// that reach holds the state's [`SliceStateDecl::clear`], it writes `clear` exactly.
    /// The renderer then dispatches, per slice, only the 8 × 8 tiles where a sample can
    /// be visible or where the state can differ from clear and be read by a later
    /// visible sample, and updates the tiles of the second kind from the pixel's
    /// placeholder sample (colour 0) without evaluating it (exact;
    /// [`crate::renderer::Renderer::set_slice_exit`]). `None` (the default): unknown,
    /// every tile runs every slice.
    fn slice_state_reach(&self, _params: &ParamValues) -> Option<f64> {
        None
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        None
    }
    /// Its volume passes, in order ([`VolumePassDecl`]).
    fn volume_passes(&self) -> Vec<VolumePassDecl> {
        Vec::new()
    }
    /// Creates the resources declared by [`Plugin::resources`], in order.
    fn create_resources(
        &self,
        _gpu: &GpuInit,
        _params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        Ok(Vec::new())
    }
    /// Updates resources after a parameter change (e.g. re-bakes a lookup table).
    fn update_resources(
        &self,
        _gpu: &GpuInit,
        _params: &ParamValues,
        _resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        Ok(())
    }
    /// CPU twin for the given parameters, if the plugin has one.
    fn cpu_twin(&self, _params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        None
    }
    /// Its promise about transparent samples, for empty-space skipping, over the
    /// document's volumes (a promise may depend on a volume input: the labels a label
    /// volume holds).
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Unknown
    }
    /// The region of world space outside which it drops every sample, over the
    /// document's volume `volumes.main` (bricks wholly outside are skipped): by default that of
    /// [`Transparency::Region`]; a plugin whose region depends on the volume (a mesh
    /// voxelised over the volume box) answers here and promises
    /// [`Transparency::Keeps`].
    fn region(&self, params: &ParamValues, volumes: &Volumes<'_>) -> Option<Arc<RegionFn>> {
        match self.transparency(params, volumes) {
            Transparency::Region(f) => Some(f),
            _ => None,
        }
    }
    /// The plugin as its structural parameters configure it, where they change its
    /// code, resources, pre-pass or state (e.g. a classification mode). The returned
    /// plugin has the same id and parameters; `None` (the default) means `self`.
    /// Everything structural (composition, resources, pre-pass, twin, transparency) is
    /// asked of the configured plugin ([`PluginInstance::configured`]).
    fn configure(&self, _params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        None
    }
    /// Parameter values under which the plugin renders the embedded demo volume when its
    /// defaults cannot (e.g. it needs a label volume beside the data). The test suite
    /// renders every registered plugin from these (`vwb_plugins::structural_modes`);
    /// `None` (the default): the defaults render.
    fn demo_params(&self) -> Option<ParamValues> {
        None
    }
    /// The named volumes beside the embedded demo volume that its demo parameters'
    /// volume inputs name (e.g. the demo's label volume); the test suite renders the
    /// plugin with them. Empty (the default): the demo volume alone.
    fn demo_inputs(&self) -> VolumeInputs {
        VolumeInputs::default()
    }
    /// Its own converged reference, where refined slices do not converge to the model
    /// it approximates ([`ConvergedReference`]); `None` (the default): the refined-slices
    /// reference of the CPU twins is the converged reference.
    fn converged_reference(&self) -> Option<Arc<dyn ConvergedReference>> {
        None
    }
    /// Studies of its CPU twin that need no image ([`Probe`]); none by default.
    fn probes(&self) -> Vec<Arc<dyn Probe>> {
        Vec::new()
    }
    /// Whether it renders a volume split into bricks (the volume longer than the 3D
    /// texture limit, `vwb_render::renderer::RendererOptions`) as it renders the whole
    /// volume: every input it reads at a sample is the scalar volume within a few
    /// voxels of it, or a pre-pass of it. By default a plugin with per-slice state or
    /// volume passes carries light or flow across the whole volume and does not, nor
    /// does one with a named volume input (it spans the whole volume's box) or a `post`
    /// hook (it sees the whole image, not a brick's); a
    /// plugin that reads a grid of its own over the volume (labels, a voxelised mesh)
    /// answers `false` here. A split volume refuses a stack with such a plugin.
    fn splits_into_bricks(&self) -> bool {
        self.slice_state().is_none()
            && self.volume_passes().is_empty()
            && !crate::composer::defines_fn(&self.shader().source, "post")
            && !self
                .params()
                .iter()
                .any(|s| matches!(s.kind, crate::params::ParamKind::Volume { .. }))
    }
    /// The most loop iterations its hooks run per sample under `params`
    /// ([`LoopIterations`]); none by default. Declaring too few costs nothing but a
    /// frame on a CPU device: the renderer finds the shortfall after the frame and
    /// renders it again in smaller parts.
    fn loop_iterations(&self, _params: &ParamValues) -> LoopIterations {
        LoopIterations::default()
    }
    /// Whether [`Plugin::update_resources`] must run again when the slice spacing
    /// changes ([`GpuInit::slice_spacing`]), e.g. for a pre-integration table.
    fn uses_slice_spacing(&self) -> bool {
        false
    }
    /// The names of the figures [`Plugin::statistics`] reports under `params` (checked
    /// when an experiment file asks for one).
    fn statistic_names(&self, _params: &ParamValues) -> Vec<&'static str> {
        Vec::new()
    }
    /// Figures about what the instance's volume passes computed, read from their
    /// targets after a frame (the GPU's own result, not a twin's), each named in
    /// [`Plugin::statistic_names`]; empty by default.
    fn statistics(&self, _params: &ParamValues, _passes: &PassOutputs<'_>) -> Vec<Statistic> {
        Vec::new()
    }
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RegistryError {
    #[error("plugin id '{0}' is already registered")]
    Duplicate(String),
    #[error(
        "plugin id '{0}' is not of the form category.name (lowercase; category one of clip, sample, classify, shade, composite, flow, search, test)"
    )]
    BadId(String),
    #[error("plugin '{id}': {message}")]
    BadSpec { id: String, message: String },
    #[error("no plugin '{0}' is registered")]
    Unknown(String),
}

/// A plugin's probes are well formed: names are lowercase identifiers, unique within
/// the plugin, as are each probe's figure names; each parameter spec validates.
fn check_probes(plugin: &dyn Plugin) -> Result<(), String> {
    let ident = crate::params::lowercase_ident;
    let mut names = std::collections::HashSet::new();
    for p in plugin.probes() {
        let name = p.name();
        if !ident(name) || !names.insert(name) {
            return Err(format!(
                "probe '{name}': a probe name is a unique lowercase identifier"
            ));
        }
        validate_specs(&p.params()).map_err(|m| format!("probe '{name}': {m}"))?;
        let mut figures = std::collections::HashSet::new();
        for (f, _) in p.figures() {
            if !ident(f) || !figures.insert(f) {
                return Err(format!(
                    "probe '{name}': figure '{f}': a figure name is a unique lowercase identifier"
                ));
            }
        }
    }
    Ok(())
}

/// Typed registry of plugin types; ids are unique.
#[derive(Default, Clone)]
pub struct Registry {
    plugins: Vec<Arc<dyn Plugin>>,
    index: HashMap<&'static str, usize>,
}

impl std::fmt::Debug for Registry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.ids()).finish()
    }
}

/// Checks an id of the form `category.name`.
pub fn valid_id(id: &str) -> bool {
    let Some((cat, name)) = id.split_once('.') else {
        return false;
    };
    Category::from_name(cat).is_some() && crate::params::lowercase_ident(name)
}

impl Registry {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn register(&mut self, plugin: Arc<dyn Plugin>) -> Result<(), RegistryError> {
        let id = plugin.id();
        if !valid_id(id) {
            return Err(RegistryError::BadId(id.to_string()));
        }
        if self.index.contains_key(id) {
            return Err(RegistryError::Duplicate(id.to_string()));
        }
        validate_specs(&plugin.params()).map_err(|message| RegistryError::BadSpec {
            id: id.to_string(),
            message,
        })?;
        check_probes(plugin.as_ref()).map_err(|message| RegistryError::BadSpec {
            id: id.to_string(),
            message,
        })?;
        self.index.insert(id, self.plugins.len());
        self.plugins.push(plugin);
        Ok(())
    }

    pub fn get(&self, id: &str) -> Result<Arc<dyn Plugin>, RegistryError> {
        self.index
            .get(id)
            .map(|&i| self.plugins[i].clone())
            .ok_or_else(|| RegistryError::Unknown(id.to_string()))
    }

    pub fn ids(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.plugins.iter().map(|p| p.id())
    }

    pub fn plugins(&self) -> &[Arc<dyn Plugin>] {
        &self.plugins
    }

    pub fn by_category(&self, c: Category) -> impl Iterator<Item = &Arc<dyn Plugin>> {
        self.plugins.iter().filter(move |p| p.category() == c)
    }
}

/// One entry of the user's plugin stack.
#[derive(Clone)]
pub struct PluginInstance {
    pub plugin: Arc<dyn Plugin>,
    pub enabled: bool,
    pub params: ParamValues,
    /// Identity that survives reordering (keeps GPU resources and pre-pass results).
    pub uid: u64,
}

impl std::fmt::Debug for PluginInstance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PluginInstance")
            .field("id", &self.plugin.id())
            .field("enabled", &self.enabled)
            .field("uid", &self.uid)
            .finish()
    }
}

static NEXT_UID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

impl PluginInstance {
    pub fn new(plugin: Arc<dyn Plugin>) -> Self {
        let params = ParamValues::defaults(&plugin.params());
        Self {
            plugin,
            enabled: true,
            params,
            uid: NEXT_UID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        }
    }

    /// The plugin as configured by this instance's structural parameters
    /// ([`Plugin::configure`]).
    pub fn configured(&self) -> Arc<dyn Plugin> {
        self.plugin
            .configure(&self.params)
            .unwrap_or_else(|| self.plugin.clone())
    }

    /// This instance with its plugin replaced by the configured one.
    pub fn with_configured_plugin(&self) -> Self {
        Self {
            plugin: self.configured(),
            ..self.clone()
        }
    }

    /// A copy with a new identity (the UI's "duplicate").
    pub fn duplicate(&self) -> Self {
        Self {
            uid: NEXT_UID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            ..self.clone()
        }
    }
}

/// Gives the instances of `new` the identities of their counterparts in `old` (the
/// same position, plugin id and structural parameter values), so that a renderer
/// drawing `old` keeps their GPU resources and pre-pass results when it switches to
/// `new` (e.g. the same preset opened again); only what differs is rebuilt.
pub fn carry_identities(old: &[PluginInstance], new: &mut [PluginInstance]) {
    let structure = |i: &PluginInstance| -> Vec<Option<ParamValue>> {
        i.plugin
            .params()
            .iter()
            .filter(|s| s.structural)
            .map(|s| i.params.get(s.key).cloned())
            .collect()
    };
    for (o, n) in old.iter().zip(new.iter_mut()) {
        if o.plugin.id() == n.plugin.id() && structure(o) == structure(n) {
            n.uid = o.uid;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Dummy(&'static str);
    impl Plugin for Dummy {
        fn id(&self) -> &'static str {
            self.0
        }
        fn display_name(&self) -> &'static str {
            "Dummy"
        }
        fn params(&self) -> Vec<ParamSpec> {
            Vec::new()
        }
        fn shader(&self) -> ShaderSource {
            ShaderSource::new_static("dummy.wgsl", "")
        }
    }

    #[test]
    fn registry_rejects_duplicates_and_bad_ids() {
        let mut r = Registry::new();
        r.register(Arc::new(Dummy("classify.a"))).unwrap();
        assert_eq!(
            r.register(Arc::new(Dummy("classify.a"))).unwrap_err(),
            RegistryError::Duplicate("classify.a".into())
        );
        for bad in [
            "nodot",
            "unknowncat.x",
            "classify.",
            "classify.Upper",
            "shade.a-b",
        ] {
            assert!(matches!(
                r.register(Arc::new(Dummy(bad))),
                Err(RegistryError::BadId(_))
            ));
        }
        assert_eq!(r.ids().collect::<Vec<_>>(), vec!["classify.a"]);
        assert_eq!(r.get("classify.a").unwrap().category(), Category::Classify);
        assert!(r.get("classify.b").is_err());
    }

    /// A probe with the given name, parameter keys and figure names.
    struct P(
        &'static str,
        &'static [&'static str],
        &'static [&'static str],
    );
    impl Probe for P {
        fn name(&self) -> &'static str {
            self.0
        }
        fn description(&self) -> &'static str {
            ""
        }
        fn params(&self) -> Vec<ParamSpec> {
            self.1
                .iter()
                .map(|k| ParamSpec::float(k, "x", 0.0, 1.0, 0.5))
                .collect()
        }
        fn figures(&self) -> Vec<(&'static str, &'static str)> {
            self.2.iter().map(|f| (*f, "")).collect()
        }
        fn run(&self, _: &ParamValues) -> Result<Vec<Statistic>, String> {
            Ok(Vec::new())
        }
    }
    struct Probing(
        Vec<(
            &'static str,
            &'static [&'static str],
            &'static [&'static str],
        )>,
    );
    impl Plugin for Probing {
        fn id(&self) -> &'static str {
            "flow.probing"
        }
        fn display_name(&self) -> &'static str {
            "Probing"
        }
        fn params(&self) -> Vec<ParamSpec> {
            Vec::new()
        }
        fn shader(&self) -> ShaderSource {
            ShaderSource::new_static("probing.wgsl", "")
        }
        fn probes(&self) -> Vec<Arc<dyn Probe>> {
            self.0
                .iter()
                .map(|&(n, k, f)| Arc::new(P(n, k, f)) as Arc<dyn Probe>)
                .collect()
        }
    }

    #[test]
    fn registry_checks_the_probes() {
        let ok = Probing(vec![
            ("drift", &["step"], &["drift", "steps"]),
            ("time", &[], &["seconds"]),
        ]);
        Registry::new().register(Arc::new(ok)).unwrap();
        for (bad, why) in [
            (
                Probing(vec![("a", &[], &[]), ("a", &[], &[])]),
                "probe 'a': a probe name",
            ),
            (Probing(vec![("Bad", &[], &[])]), "probe 'Bad'"),
            (Probing(vec![("a", &["step", "step"], &[])]), "probe 'a': "),
            (Probing(vec![("a", &[], &["x", "x"])]), "figure 'x'"),
            (Probing(vec![("a", &[], &["no-dash"])]), "figure 'no-dash'"),
        ] {
            match Registry::new().register(Arc::new(bad)) {
                Err(RegistryError::BadSpec { id, message }) => {
                    assert_eq!(id, "flow.probing");
                    assert!(message.contains(why), "{message}");
                }
                other => panic!("{why}: {:?}", other.err()),
            }
        }
    }
}
