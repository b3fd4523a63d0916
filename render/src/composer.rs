//! The WGSL composer: turns the user's plugin stack into one slice shader.
//!
//! For each enabled plugin instance (in stack order) the composer
//! 1. generates the declarations of its bindings (`params`, resources, per-slice
//!    state, pre-pass target) from one description ([`Binding`]), which also yields the
//!    bind group layout entries, so declarations and layouts cannot disagree;
//! 2. parses and validates the plugin's file on its own (shared prelude + its
//!    declarations + its code), so that errors point at the plugin's file and line;
//! 3. checks the signatures of the hook functions it defines;
//! 4. renames every name the plugin declares at module scope, and its generated
//!    binding names, with a per-instance prefix (`p{index}_{name}_`), token by token,
//!    so two instances of one plugin never collide and line numbers are preserved;
//! 5. inserts the renamed code at `//!PLUGINS` and a call per hook at each
//!    `//!HOOK name` marker of the template `shaders/slice.wgsl`, in stack order.
//!
//! The composed module is validated with naga; any error is mapped back through a
//! per-line origin table to the contributing file and line (a plugin's `.wgsl`, the
//! template, or a generated line). Disabled plugins contribute nothing.

use std::collections::HashSet;
use std::fmt;

use crate::params::UniformLayout;
use crate::plugin::{Plugin, ResourceKind, StorageFormat};

pub const COMMON_FILE: &str = "shaders/common.wgsl";
pub const TEMPLATE_FILE: &str = "shaders/slice.wgsl";
pub const COMMON_WGSL: &str = include_str!("../../shaders/common.wgsl");
pub const TEMPLATE_WGSL: &str = include_str!("../../shaders/slice.wgsl");

/// How the scalar volume (group 0, binding 1) is laid out, which decides the
/// declaration and reads (`volume_value`, `volume_voxel`, `volume_dims`) that
/// shaders/common.wgsl gives every module: its `volume_texture3d` or its
/// `volume_z_pairs` region (the other blanked line for line).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum VolumeLayout {
    /// A filtered 3D texture (`texture_3d<f32>`).
    #[default]
    Texture3d,
    /// Each voxel beside its +z neighbour in a 2D array texture
    /// (`texture_2d_array<f32>`, layer k holding (v(k), v(k + 1))): a trilinear read is
    /// one bilinear fetch and a mix (`VolumeFormat::R32FloatPairs`).
    ZPairs,
}

impl VolumeLayout {
    /// The view dimension of the volume's binding.
    pub fn view_dimension(self) -> wgpu::TextureViewDimension {
        match self {
            VolumeLayout::Texture3d => wgpu::TextureViewDimension::D3,
            VolumeLayout::ZPairs => wgpu::TextureViewDimension::D2Array,
        }
    }
}

/// shaders/common.wgsl with the regions `half_angle` (where `half_angle` is false)
/// and the volume layout that `volume` does not use blanked line for line.
fn common_code(half_angle: bool, volume: VolumeLayout) -> String {
    let unused = match volume {
        VolumeLayout::Texture3d => "volume_z_pairs",
        VolumeLayout::ZPairs => "volume_texture3d",
    };
    let mut regions = vec![(unused, "")];
    if !half_angle {
        regions.push(("half_angle", ""));
    }
    crate::plugin::ShaderSource::without_regions(COMMON_FILE, COMMON_WGSL, &regions)
        .source
        .into_owned()
}

/// Precision of the eye buffer.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
pub enum TargetFormat {
    #[default]
    Rgba16Float,
    Rgba32Float,
}

impl TargetFormat {
    pub fn wgsl(self) -> &'static str {
        match self {
            TargetFormat::Rgba16Float => "rgba16float",
            TargetFormat::Rgba32Float => "rgba32float",
        }
    }
    pub fn wgpu(self) -> wgpu::TextureFormat {
        match self {
            TargetFormat::Rgba16Float => wgpu::TextureFormat::Rgba16Float,
            TargetFormat::Rgba32Float => wgpu::TextureFormat::Rgba32Float,
        }
    }
}

/// The hooks: `setup` (once per ray, before its samples), those that run per sample in
/// this order, `post` (once per pixel, on the accumulated colour after the loop), then
/// the per-slice state update.
pub const HOOKS: [&str; 8] = [
    "setup",
    "clip",
    "sample",
    "classify",
    "shade",
    "composite",
    "post",
    "slice_update",
];

/// Expected signature of each hook: argument types and result type.
fn hook_signature(name: &str) -> Option<(&'static [&'static str], &'static str)> {
    Some(match name {
        "setup" => (&["Ray", "vec2<f32>"], "vec4<f32>"),
        "clip" => (&["Sample"], "bool"),
        "sample" | "classify" | "shade" => (&["Sample"], "Sample"),
        "composite" => (&["Sample", "vec4<f32>"], "vec4<f32>"),
        "post" => (&["vec4<f32>", "vec2<f32>"], "vec4<f32>"),
        "slice_update" => (&["Sample", "vec4<f32>", "vec2<f32>"], "vec4<f32>"),
        "prepass" => (&["vec3<u32>", "vec3<u32>"], "vec4<f32>"),
        "scalar" => (&["vec3<f32>"], "f32"),
        "scalar_grid" => (&[], "vec3<f32>"),
        _ => return None,
    })
}

/// Where a line of composed WGSL came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    File {
        file: String,
        line: u32,
        /// Index of the plugin instance in the enabled stack, for plugin files.
        instance: Option<usize>,
    },
    Generated {
        what: String,
        instance: Option<usize>,
    },
}

/// A composed WGSL module and the origin of each of its lines.
#[derive(Debug, Clone)]
pub struct ComposedModule {
    pub source: String,
    pub origins: Vec<Origin>,
}

impl ComposedModule {
    fn new() -> Self {
        Self {
            source: String::new(),
            origins: Vec::new(),
        }
    }

    fn push_file(&mut self, file: &str, text: &str, instance: Option<usize>) {
        for (i, line) in text.lines().enumerate() {
            self.source.push_str(line);
            self.source.push('\n');
            self.origins.push(Origin::File {
                file: file.to_string(),
                line: i as u32 + 1,
                instance,
            });
        }
    }

    fn push_generated(&mut self, what: &str, text: &str, instance: Option<usize>) {
        for line in text.lines() {
            self.source.push_str(line);
            self.source.push('\n');
            self.origins.push(Origin::Generated {
                what: what.to_string(),
                instance,
            });
        }
    }

    fn push_line(&mut self, line: &str, origin: Origin) {
        self.source.push_str(line);
        self.source.push('\n');
        self.origins.push(origin);
    }

    /// Origin of a 1-based line.
    pub fn origin(&self, line: u32) -> Option<&Origin> {
        self.origins.get(line.checked_sub(1)? as usize)
    }
}

/// What a binding is.
#[derive(Debug, Clone, PartialEq)]
pub enum BindingKind {
    Uniform {
        size: u32,
    },
    Texture1d,
    Texture2d,
    Texture3d,
    StorageTexture2d(StorageFormat),
    StorageTexture3d(StorageFormat),
    /// A read-write storage buffer of u32 (the per-slice state's tile marks).
    StorageBufferU32,
}

/// One generated binding: the WGSL declaration and the layout entry come from it.
#[derive(Debug, Clone, PartialEq)]
pub struct Binding {
    pub group: u32,
    pub binding: u32,
    /// Name as the plugin writes it (`params`, `lut`, `state_prev`, …).
    pub local_name: String,
    pub kind: BindingKind,
    /// Instance (index in the enabled stack) that owns it.
    pub instance: usize,
    /// Role, so that the renderer can bind the right resource.
    pub role: BindingRole,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BindingRole {
    Params,
    Resource(usize),
    PrepassTarget,
    /// The target of the instance's volume pass `k`, sampled ([`crate::plugin::VolumePassDecl`]).
    PassTarget(usize),
    StatePrev,
    StateNext,
    /// The marks of the state's tiles that left `clear` ([`crate::plugin::SliceStateDecl::track_clear`]).
    StateTiles,
}

impl Binding {
    pub fn wgsl(&self, prefix: &str, struct_name: &str) -> String {
        let ty = match &self.kind {
            BindingKind::Uniform { .. } => {
                // the uniform, and the private copy that the code reads (`load_frame`)
                return format!(
                    "@group({}) @binding({}) var<uniform> {prefix}{}{UNIFORM_SUFFIX}: {struct_name};\n\
                     var<private> {prefix}{}: {struct_name};",
                    self.group, self.binding, self.local_name, self.local_name
                );
            }
            BindingKind::StorageBufferU32 => {
                return format!(
                    "@group({}) @binding({}) var<storage, read_write> {prefix}{}: array<u32>;",
                    self.group, self.binding, self.local_name
                );
            }
            BindingKind::Texture1d => "texture_1d<f32>".to_string(),
            BindingKind::Texture2d => "texture_2d<f32>".to_string(),
            BindingKind::Texture3d => "texture_3d<f32>".to_string(),
            BindingKind::StorageTexture2d(f) => {
                format!("texture_storage_2d<{}, write>", f.wgsl())
            }
            BindingKind::StorageTexture3d(f) => {
                format!("texture_storage_3d<{}, write>", f.wgsl())
            }
        };
        format!(
            "@group({}) @binding({}) var {prefix}{}: {ty};",
            self.group, self.binding, self.local_name
        )
    }

    /// The matching bind group layout entry.
    pub fn layout_entry(&self, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
        let ty = match &self.kind {
            BindingKind::Uniform { size } => wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: wgpu::BufferSize::new(*size as u64),
            },
            BindingKind::Texture1d | BindingKind::Texture2d | BindingKind::Texture3d => {
                wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: match self.kind {
                        BindingKind::Texture1d => wgpu::TextureViewDimension::D1,
                        BindingKind::Texture2d => wgpu::TextureViewDimension::D2,
                        _ => wgpu::TextureViewDimension::D3,
                    },
                    multisampled: false,
                }
            }
            BindingKind::StorageTexture2d(f) | BindingKind::StorageTexture3d(f) => {
                wgpu::BindingType::StorageTexture {
                    access: wgpu::StorageTextureAccess::WriteOnly,
                    format: f.wgpu(),
                    view_dimension: if matches!(self.kind, BindingKind::StorageTexture2d(_)) {
                        wgpu::TextureViewDimension::D2
                    } else {
                        wgpu::TextureViewDimension::D3
                    },
                }
            }
            BindingKind::StorageBufferU32 => wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: false },
                has_dynamic_offset: false,
                min_binding_size: wgpu::BufferSize::new(4),
            },
        };
        let visibility = match self.kind {
            // storage writes happen in compute passes only
            BindingKind::StorageTexture2d(_)
            | BindingKind::StorageTexture3d(_)
            | BindingKind::StorageBufferU32 => wgpu::ShaderStages::COMPUTE,
            // the slice vertices read the parameters (`params_to_vertex`)
            BindingKind::Uniform { .. } => visibility | wgpu::ShaderStages::VERTEX,
            _ => visibility,
        };
        wgpu::BindGroupLayoutEntry {
            binding: self.binding,
            visibility,
            ty,
            count: None,
        }
    }
}

/// What the composer produced for one enabled instance.
#[derive(Debug, Clone)]
pub struct InstanceLayout {
    /// Index of the instance in the input list.
    pub input_index: usize,
    pub prefix: String,
    pub hooks: Vec<&'static str>,
    pub uniform: UniformLayout,
    /// Entry point of its state update, if it has per-slice state.
    pub update_entry: Option<String>,
    /// Its per-slice state's tiles are tracked ([`crate::plugin::SliceStateDecl::track_clear`]).
    pub track_clear: bool,
    /// Its pre-pass module (bindings in group 1) and the module's bindings.
    pub prepass: Option<(ComposedModule, Vec<Binding>)>,
    /// Its volume passes, in declaration order: the entry point in the main module
    /// and the group-3 binding of the pass's storage target.
    pub passes: Vec<PassLayout>,
}

/// A volume pass in the main module ([`InstanceLayout::passes`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PassLayout {
    pub entry_point: String,
    /// Binding (group 3) of the storage view of its target.
    pub binding: u32,
    pub format: crate::plugin::StorageFormat,
    pub accumulate: bool,
    /// A sweep pass: the group-3 binding of its `SweepInfo` uniform (the next one).
    pub sweep_binding: Option<u32>,
}

/// First group-3 binding of volume-pass targets (0 and 1 are the compute output).
pub const PASS_BINDING_BASE: u32 = 2;

/// Entry point of the fused slice step (the slice and every per-slice state update in
/// one dispatch), generated when a plugin declares per-slice state.
pub const FUSED_SLICE_ENTRY: &str = "cs_slice_fused";
/// The entry point of the state updates alone over a slice's tiles where no sample can
/// be visible ([`crate::renderer::Renderer::set_slice_exit`]).
pub const STATE_ONLY_ENTRY: &str = "cs_slice_state_only";

/// The functions a plugin's hook file may define besides its hooks to supply the scalar
/// its `sample` hook gives (shading from it): `scalar(tex)`, and the grid it lives on,
/// `scalar_grid()` (the volume's when absent).
pub const SCALAR_FUNCTIONS: [&str; 2] = ["scalar", "scalar_grid"];

/// `shading_value(tex)` and `shading_grid()`, the scalar the gradient estimators of
/// shaders/common.wgsl differentiate and its grid: the provider's `scalar` and
/// `scalar_grid` when the stack has one (the instance prefix, and whether it defines
/// `scalar_grid`), else the volume's value and grid. Every module that includes
/// common.wgsl gets it right after.
fn shading_scalar_wgsl(provider: Option<(&str, bool)>) -> String {
    let (value, grid) = match provider {
        None => (
            "volume_value(tex)".to_string(),
            "frame.volume_dims.xyz".to_string(),
        ),
        Some((p, true)) => (format!("{p}scalar(tex)"), format!("{p}scalar_grid()")),
        Some((p, false)) => (
            format!("{p}scalar(tex)"),
            "frame.volume_dims.xyz".to_string(),
        ),
    };
    format!(
        "fn shading_value(tex: vec3<f32>) -> f32 {{\n    return {value};\n}}\n\
         fn shading_grid() -> vec3<f32> {{\n    return {grid};\n}}\n"
    )
}

/// `sample_value(tex)`, the value the slice template gives each sample before its
/// `sample` hooks: the volume's (`volume_value`), or the w component of `holder`, a
/// pre-pass target that holds the volume's value at every voxel
/// ([`crate::plugin::PrepassDecl::holds_value`]): the same trilinear interpolation of
/// the same f32 voxels, read with what its plugin reads there.
fn sample_value_wgsl(holder: Option<&str>) -> String {
    let read = match holder {
        None => "volume_value(tex)".to_string(),
        Some(t) => format!("textureSampleLevel({t}, linear_clamp, tex, 0.0).w"),
    };
    format!("fn sample_value(tex: vec3<f32>) -> f32 {{\n    return {read};\n}}\n")
}

/// Whether a pre-pass shader reads the gradient estimators or the shading scalar (its
/// module has the volume's value as the shading scalar whatever the stack holds).
fn differentiates_the_shading_scalar(source: &str) -> bool {
    ["gradient_central", "gradient_sobel", "shading_value"]
        .iter()
        .any(|name| {
            source.match_indices(name).any(|(i, _)| {
                let before = source[..i].chars().next_back();
                let after = source[i + name.len()..].chars().next();
                let word = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || c == '_');
                !word(before) && !word(after)
            })
        })
}

/// The per-ray record of an instance with a `setup` hook: what the hook returned for
/// the current ray, read by the instance's other hooks (zero outside a ray, e.g. in
/// volume passes). One private variable per such instance, renamed with its prefix.
pub const RAY_RECORD: &str = "ray_record";
const RAY_RECORD_DECL: &str = "var<private> ray_record: vec4<f32>;";

/// Side length of the tiles of per-slice state texels whose marks
/// [`crate::plugin::SliceStateDecl::track_clear`] keeps.
pub const STATE_TILE: u32 = 8;

/// The functions of a tracked per-slice state (unprefixed): `state_prev_clear(uv,
/// reach)` for the plugin's hooks, and `state_mark(texel, v)`, which the generated
/// update entry points call after storing `v`: a value other than `clear` marks the
/// texel's tile. Marks are plain stores of 1 (concurrent stores of the same value;
/// a read in the same dispatch may miss one, which only a later slice needs, after
/// the dispatch's barrier).
fn state_track_wgsl(clear: [f32; 4]) -> String {
    let c = clear.map(|v| format!("{v:?}")).join(", ");
    let t = STATE_TILE;
    format!(
        "fn state_prev_clear(uv: vec2<f32>, reach: vec2<f32>) -> bool {{\n    \
         let size = vec2<i32>(textureDimensions(state_prev));\n    \
         let tiles_x = (size.x + {t} - 1) / {t};\n    \
         let texels = vec2<f32>(size);\n    \
         let lo = clamp(vec2<i32>(floor((uv - reach) * texels - 0.5)), vec2<i32>(0), size - 1) / {t};\n    \
         let hi = clamp(vec2<i32>(floor((uv + reach) * texels - 0.5)) + 1, vec2<i32>(0), size - 1) / {t};\n    \
         for (var ty = lo.y; ty <= hi.y; ty = ty + 1) {{\n        \
         for (var tx = lo.x; tx <= hi.x; tx = tx + 1) {{\n            \
         if (state_tiles[ty * tiles_x + tx] != 0u) {{\n                return false;\n            }}\n        \
         }}\n    \
         }}\n    \
         return true;\n\
         }}\n\
         fn state_mark(texel: vec2<u32>, v: vec4<f32>) {{\n    \
         if (any(v != vec4<f32>({c}))) {{\n        \
         let tiles_x = (textureDimensions(state_next).x + {t}u - 1u) / {t}u;\n        \
         state_tiles[(texel.y / {t}u) * tiles_x + texel.x / {t}u] = 1u;\n    \
         }}\n\
         }}\n"
    )
}

/// The functions [`state_track_wgsl`] defines.
const STATE_TRACK_FNS: [&str; 2] = ["state_prev_clear", "state_mark"];

/// What `stack_classify` is, for checking a plugin file in isolation.
const STACK_CLASSIFY_STUB: &str = "fn stack_classify(tex: vec3<f32>, dir: vec3<f32>) -> vec4<f32> { return vec4<f32>(tex + dir, 0.0); }";

/// The composed pipeline description.
#[derive(Debug, Clone)]
pub struct Composition {
    pub main: ComposedModule,
    /// Whether an instance defines the `post` hook (the raster backend then runs a
    /// full-screen pass after the slices).
    pub post: bool,
    /// Bindings of groups 1 (plugin resources) and 2 (per-slice state).
    pub bindings: Vec<Binding>,
    pub instances: Vec<InstanceLayout>,
}

/// A composition error, mapped to the contributing file and line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ComposeError {
    #[error("{file}:{line}:{column}: {message}{}", plugin_suffix(plugin))]
    Shader {
        file: String,
        line: u32,
        column: u32,
        message: String,
        plugin: Option<String>,
    },
    #[error("{message}")]
    Limits { message: String },
    #[error("{plugin}: {message}")]
    Plugin { plugin: String, message: String },
}

fn plugin_suffix(p: &Option<String>) -> String {
    match p {
        Some(id) => format!(" (plugin {id})"),
        None => String::new(),
    }
}

impl ComposeError {
    /// The plugin the error belongs to, if any.
    pub fn plugin(&self) -> Option<&str> {
        match self {
            ComposeError::Shader { plugin, .. } => plugin.as_deref(),
            ComposeError::Plugin { plugin, .. } => Some(plugin),
            ComposeError::Limits { .. } => None,
        }
    }
}

// ------------------------------------------------------------------ tokens

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tok {
    Ident,
    Other,
    Trivia,
}

/// Splits WGSL into (kind, byte range) tokens; comments and white space are trivia.
fn tokenize(src: &str) -> Vec<(Tok, usize, usize)> {
    let b = src.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let start = i;
        let c = b[i];
        if c == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
            out.push((Tok::Trivia, start, i));
        } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
            // block comments nest in WGSL
            let mut depth = 0;
            while i < b.len() {
                if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
            out.push((Tok::Trivia, start, i));
        } else if c.is_ascii_whitespace() {
            while i < b.len() && b[i].is_ascii_whitespace() {
                i += 1;
            }
            out.push((Tok::Trivia, start, i));
        } else if c.is_ascii_alphabetic() || c == b'_' {
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            out.push((Tok::Ident, start, i));
        } else if c.is_ascii_digit() {
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] == b'.') {
                i += 1;
            }
            out.push((Tok::Other, start, i));
        } else {
            // one (possibly multi-byte UTF-8) character
            i += src[i..].chars().next().map_or(1, char::len_utf8);
            out.push((Tok::Other, start, i));
        }
    }
    out
}

/// A module-scope declaration found by scanning tokens.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Decl {
    name: String,
    is_fn: bool,
    line: u32,
}

/// Names declared at module scope (`fn`, `const`, `var`, `override`, `struct`, `alias`).
fn module_decls(src: &str) -> Vec<Decl> {
    let toks: Vec<_> = tokenize(src)
        .into_iter()
        .filter(|t| t.0 != Tok::Trivia)
        .collect();
    let text = |t: &(Tok, usize, usize)| &src[t.1..t.2];
    let mut out = Vec::new();
    let mut depth = 0i32;
    let mut i = 0;
    while i < toks.len() {
        let t = text(&toks[i]);
        match t {
            "{" => depth += 1,
            "}" => depth -= 1,
            "fn" | "const" | "override" | "struct" | "alias" | "var" if depth == 0 => {
                let mut j = i + 1;
                // var<uniform> / var<private>: skip the template list
                if t == "var" && j < toks.len() && text(&toks[j]) == "<" {
                    while j < toks.len() && text(&toks[j]) != ">" {
                        j += 1;
                    }
                    j += 1;
                }
                if let Some(tok) = toks.get(j)
                    && tok.0 == Tok::Ident
                {
                    out.push(Decl {
                        name: text(tok).to_string(),
                        is_fn: t == "fn",
                        line: src[..tok.1].matches('\n').count() as u32 + 1,
                    });
                }
            }
            _ => {}
        }
        i += 1;
    }
    out
}

/// Whether `src` defines a function `name` at module scope (a token scan, without
/// parsing: for questions asked before anything is composed).
pub fn defines_fn(src: &str, name: &str) -> bool {
    module_decls(src).iter().any(|d| d.is_fn && d.name == name)
}

/// Prefixes every identifier in `names` (except member accesses after `.`).
fn rename(src: &str, names: &HashSet<String>, prefix: &str) -> String {
    let mut out = String::with_capacity(src.len() + 64);
    let mut prev_sig: Option<&str> = None;
    for (kind, a, b) in tokenize(src) {
        let t = &src[a..b];
        if kind == Tok::Ident && names.contains(t) && prev_sig != Some(".") {
            out.push_str(prefix);
        }
        out.push_str(t);
        if kind != Tok::Trivia {
            prev_sig = Some(t);
        }
    }
    out
}

// ------------------------------------------------------------------ naga helpers

/// Line (1-based) and column of a byte offset.
fn line_col(src: &str, offset: usize) -> (u32, u32) {
    let offset = offset.min(src.len());
    let prefix = &src[..offset];
    let line = prefix.matches('\n').count() as u32 + 1;
    let col = offset - prefix.rfind('\n').map_or(0, |p| p + 1) + 1;
    (line, col as u32)
}

/// Parses and validates; returns the error message and byte offset of its first span.
fn naga_check(src: &str) -> Result<naga::Module, (String, Option<usize>)> {
    let module = naga::front::wgsl::parse_str(src).map_err(|e| {
        let offset = e
            .labels()
            .next()
            .and_then(|(s, _)| s.to_range())
            .map(|r| r.start);
        let mut msg = e.message().to_string();
        for (_, label) in e.labels() {
            if !label.is_empty() {
                msg.push_str(&format!(" — {label}"));
            }
        }
        (msg, offset)
    })?;
    let mut v = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        // pack2x16float/unpack2x16float need this; every wgpu device on the
        // backends vwb allows has it (DownlevelFlags::SHADER_F16_IN_F32).
        naga::valid::Capabilities::default() | naga::valid::Capabilities::SHADER_FLOAT16_IN_FLOAT32,
    );
    v.validate(&module).map_err(|e| {
        let offset = e
            .spans()
            .next()
            .and_then(|(s, _)| s.to_range())
            .map(|r| r.start);
        // full chain of causes: naga's top error is often generic
        let mut msg = e.as_inner().to_string();
        let mut src_err: Option<&dyn std::error::Error> = std::error::Error::source(e.as_inner());
        while let Some(s) = src_err {
            msg.push_str(&format!(": {s}"));
            src_err = s.source();
        }
        (msg, offset)
    })?;
    Ok(module)
}

fn type_name(module: &naga::Module, ty: naga::Handle<naga::Type>) -> String {
    let t = &module.types[ty];
    if let Some(n) = &t.name {
        return n.clone();
    }
    let scalar = |s: naga::Scalar| match (s.kind, s.width) {
        (naga::ScalarKind::Float, 4) => "f32",
        (naga::ScalarKind::Sint, 4) => "i32",
        (naga::ScalarKind::Uint, 4) => "u32",
        (naga::ScalarKind::Bool, _) => "bool",
        _ => "?",
    };
    match t.inner {
        naga::TypeInner::Scalar(s) => scalar(s).to_string(),
        naga::TypeInner::Vector { size, scalar: s } => {
            format!("vec{}<{}>", size as u8, scalar(s))
        }
        _ => "?".to_string(),
    }
}

// ------------------------------------------------------------------ composition

/// Names of the generated bindings of an instance, as the plugin writes them.
fn instance_bindings(
    plugin: &dyn Plugin,
    instance: usize,
    uniform: &UniformLayout,
    prepass_module: bool,
    group1_next: &mut u32,
    group2_next: &mut u32,
) -> Vec<Binding> {
    let mut out = Vec::new();
    let mut push = |group: u32, next: &mut u32, name: &str, kind, role| {
        out.push(Binding {
            group,
            binding: *next,
            local_name: name.to_string(),
            kind,
            instance,
            role,
        });
        *next += 1;
    };
    push(
        1,
        group1_next,
        "params",
        BindingKind::Uniform { size: uniform.size },
        BindingRole::Params,
    );
    for (i, r) in plugin.resources().iter().enumerate() {
        let kind = match r.kind {
            ResourceKind::Texture1d => BindingKind::Texture1d,
            ResourceKind::Texture2d => BindingKind::Texture2d,
            ResourceKind::Texture3d => BindingKind::Texture3d,
        };
        push(1, group1_next, r.name, kind, BindingRole::Resource(i));
    }
    if let Some(pp) = plugin.prepass() {
        let kind = if prepass_module {
            BindingKind::StorageTexture3d(pp.format)
        } else {
            BindingKind::Texture3d
        };
        push(1, group1_next, pp.target, kind, BindingRole::PrepassTarget);
    }
    if !prepass_module {
        for (k, vp) in plugin.volume_passes().iter().enumerate() {
            push(
                1,
                group1_next,
                vp.target,
                BindingKind::Texture3d,
                BindingRole::PassTarget(k),
            );
        }
    }
    if !prepass_module && let Some(st) = plugin.slice_state() {
        push(
            2,
            group2_next,
            "state_prev",
            BindingKind::Texture2d,
            BindingRole::StatePrev,
        );
        push(
            2,
            group2_next,
            "state_next",
            BindingKind::StorageTexture2d(st.format),
            BindingRole::StateNext,
        );
        if st.track_clear {
            push(
                2,
                group2_next,
                "state_tiles",
                BindingKind::StorageBufferU32,
                BindingRole::StateTiles,
            );
        }
    }
    out
}

fn decls_text(bindings: &[Binding], prefix: &str, uniform: &UniformLayout) -> String {
    let struct_name = format!("{prefix}Params");
    let mut s = uniform.wgsl(&struct_name);
    s.push('\n');
    for b in bindings {
        s.push_str(&b.wgsl(prefix, &struct_name));
        s.push('\n');
    }
    s
}

fn instance_prefix(plugin: &dyn Plugin, index: usize) -> String {
    let name = plugin.id().split('.').nth(1).unwrap_or("plugin");
    format!("p{index}_{name}_")
}

/// Checks one plugin file in isolation and returns its declarations.
fn check_plugin_file(
    plugin: &dyn Plugin,
    file: &str,
    source: &str,
    decls_unprefixed: &str,
    allowed_hooks: &[&str],
) -> Result<Vec<Decl>, ComposeError> {
    let head = format!(
        "{}\n{}{decls_unprefixed}\n",
        common_code(true, VolumeLayout::Texture3d),
        shading_scalar_wgsl(None)
    );
    let head_lines = head.matches('\n').count() as u32;
    let full = format!("{head}{source}\n");
    let shader_err = |msg: String, offset: Option<usize>| {
        let (line, column) = offset.map_or((0, 0), |o| line_col(&full, o));
        let (file, line) = if line > head_lines {
            (file.to_string(), line - head_lines)
        } else {
            // an error in the shared prelude caused by a name clash with the plugin
            (COMMON_FILE.to_string(), line)
        };
        ComposeError::Shader {
            file,
            line,
            column,
            message: msg,
            plugin: Some(plugin.id().to_string()),
        }
    };
    let module = naga_check(&full).map_err(|(m, o)| shader_err(m, o))?;
    if let Some((message, offset)) = private_copy_write(&module) {
        return Err(shader_err(message, offset));
    }
    let decls = module_decls(source);
    let names_of =
        |src: &str| -> HashSet<String> { module_decls(src).into_iter().map(|d| d.name).collect() };
    let (common_names, generated_names) =
        (names_of(COMMON_WGSL), names_of(&shading_scalar_wgsl(None)));
    for d in &decls {
        let shared = if common_names.contains(&d.name) {
            Some(COMMON_FILE)
        } else if generated_names.contains(&d.name) {
            Some("every module (the shading scalar; a plugin supplies its own as `scalar`)")
        } else {
            None
        };
        if let Some(place) = shared {
            return Err(ComposeError::Shader {
                file: file.to_string(),
                line: d.line,
                column: 1,
                message: format!("'{}' is already declared in {place}", d.name),
                plugin: Some(plugin.id().to_string()),
            });
        }
        let Some((args, ret)) = hook_signature(&d.name) else {
            continue;
        };
        if !d.is_fn {
            continue;
        }
        if !allowed_hooks.contains(&d.name.as_str()) {
            return Err(ComposeError::Shader {
                file: file.to_string(),
                line: d.line,
                column: 1,
                message: format!(
                    "hook '{}' is not allowed here (this file may define: {})",
                    d.name,
                    allowed_hooks.join(", ")
                ),
                plugin: Some(plugin.id().to_string()),
            });
        }
        let f = module
            .functions
            .iter()
            .find(|(_, f)| f.name.as_deref() == Some(d.name.as_str()))
            .map(|(_, f)| f);
        let Some(f) = f else { continue };
        let got_args: Vec<String> = f
            .arguments
            .iter()
            .map(|a| type_name(&module, a.ty))
            .collect();
        let got_ret = f
            .result
            .as_ref()
            .map_or("()".to_string(), |r| type_name(&module, r.ty));
        if got_args != args || got_ret != ret {
            return Err(ComposeError::Shader {
                file: file.to_string(),
                line: d.line,
                column: 1,
                message: format!(
                    "hook '{}' must be fn {}({}) -> {ret}, found ({}) -> {got_ret}",
                    d.name,
                    d.name,
                    args.join(", "),
                    got_args.join(", ")
                ),
                plugin: Some(plugin.id().to_string()),
            });
        }
    }
    Ok(decls)
}

/// Per-stage resource counts of a composition, checked against device limits.
fn check_limits(bindings: &[Binding], limits: &wgpu::Limits) -> Result<(), ComposeError> {
    // group 0: frame + slice_info uniforms, volume texture, 2 samplers;
    // group 3 (compute): output storage texture, accumulation storage buffer, the
    // march's part (uniform) and the loop limiter's counter (storage buffer)
    // (the bindings' storage buffers: per-slice state tile marks).
    let mut uniforms = 3u32;
    let mut sampled = 1u32;
    let mut storage_tex = 1u32;
    let mut storage_buf = 2u32;
    let mut per_group = [5u32, 0, 0, 4];
    let mut max_uniform = 0u32;
    for b in bindings {
        per_group[b.group as usize] += 1;
        match b.kind {
            BindingKind::Uniform { size } => {
                uniforms += 1;
                max_uniform = max_uniform.max(size);
            }
            BindingKind::Texture1d | BindingKind::Texture2d | BindingKind::Texture3d => {
                sampled += 1
            }
            BindingKind::StorageBufferU32 => storage_buf += 1,
            BindingKind::StorageTexture2d(_) | BindingKind::StorageTexture3d(_) => storage_tex += 1,
        }
    }
    let checks = [
        (
            "uniform buffers per shader stage",
            uniforms,
            limits.max_uniform_buffers_per_shader_stage,
        ),
        (
            "sampled textures per shader stage",
            sampled,
            limits.max_sampled_textures_per_shader_stage,
        ),
        (
            "storage textures per shader stage",
            storage_tex,
            limits.max_storage_textures_per_shader_stage,
        ),
        (
            "storage buffers per shader stage",
            storage_buf,
            limits.max_storage_buffers_per_shader_stage,
        ),
        (
            "bindings per bind group",
            per_group.into_iter().max().unwrap_or(0),
            limits.max_bindings_per_bind_group,
        ),
        (
            "bytes in one uniform buffer",
            max_uniform,
            limits.max_uniform_buffer_binding_size as u32,
        ),
    ];
    for (what, n, limit) in checks {
        if n > limit {
            return Err(ComposeError::Limits {
                message: format!(
                    "the plugin stack needs {n} {what}, the device allows {limit}; disable or remove a plugin"
                ),
            });
        }
    }
    Ok(())
}

/// The workgroup shape of the template's whole-frame compute entry points.
pub const MAIN_WORKGROUP: [u32; 2] = [8, 8];

/// The whole-frame passes' workgroup shape on `gpu`: `requested` where the device
/// allows it, else the shape measured fastest for the adapter's kind (docs/perf.md,
/// "Workgroup shapes"): [`MAIN_WORKGROUP`] on GPUs, [`CPU_WORKGROUP`] on CPU devices.
pub fn main_workgroup(gpu: &crate::gpu::GpuContext, requested: Option<[u32; 2]>) -> [u32; 2] {
    let l = &gpu.limits;
    let fits = |[x, y]: [u32; 2]| {
        x > 0
            && y > 0
            && x <= l.max_compute_workgroup_size_x
            && y <= l.max_compute_workgroup_size_y
            && x * y <= l.max_compute_invocations_per_workgroup
    };
    match requested {
        Some(wg) if fits(wg) => wg,
        _ if gpu.info.device_type == wgpu::DeviceType::Cpu && fits(CPU_WORKGROUP) => CPU_WORKGROUP,
        _ => MAIN_WORKGROUP,
    }
}

/// The shape chosen on CPU devices (lavapipe).
pub const CPU_WORKGROUP: [u32; 2] = [8, 8];

/// The composed module with `cs_main`, `cs_main_skip` and
/// `cs_main_raw` (every entry point whose name begins with `cs_main`) in workgroups of
/// `wg` (the template declares [`MAIN_WORKGROUP`]), and the template's `MAIN_WG`, from
/// which those entry points place their pixels, set to the same shape; the other entry
/// points keep theirs.
pub fn with_main_workgroup(source: &str, wg: [u32; 2]) -> std::borrow::Cow<'_, str> {
    if wg == MAIN_WORKGROUP {
        return source.into();
    }
    let [x0, y0] = MAIN_WORKGROUP;
    let [x, y] = wg;
    source
        .replace(
            &format!("@compute @workgroup_size({x0}, {y0}, 1)\nfn cs_main"),
            &format!("@compute @workgroup_size({x}, {y}, 1)\nfn cs_main"),
        )
        .replace(
            &format!("const MAIN_WG: vec2<u32> = vec2<u32>({x0}u, {y0}u);"),
            &format!("const MAIN_WG: vec2<u32> = vec2<u32>({x}u, {y}u);"),
        )
        .into()
}

/// A core shader file with its `half_angle` regions (the half-angle slicing paths,
/// render/src/slicing.rs) kept, or blanked line for line (so that errors keep their
/// lines) for stacks whose per-slice state never travels with a light.
fn half_angle_code(
    file: &'static str,
    source: &'static str,
    keep: bool,
) -> std::borrow::Cow<'static, str> {
    if keep {
        std::borrow::Cow::Borrowed(source)
    } else {
        crate::plugin::ShaderSource::without_region(file, source, "half_angle", "").source
    }
}

/// Composes the enabled plugins (in stack order) into the slice shader.
pub fn compose(
    plugins: &[&dyn Plugin],
    target: TargetFormat,
    limits: &wgpu::Limits,
) -> Result<Composition, ComposeError> {
    compose_with(plugins, target, limits, &Default::default())
}

/// [`compose`] with some plugin files' WGSL replaced (`file` → source): errors in a
/// replacement name the file and line like those in the built-in source.
pub fn compose_with(
    plugins: &[&dyn Plugin],
    target: TargetFormat,
    limits: &wgpu::Limits,
    overrides: &std::collections::BTreeMap<String, String>,
) -> Result<Composition, ComposeError> {
    compose_for(plugins, target, limits, overrides, VolumeLayout::Texture3d)
}

/// [`compose_with`] for a volume stored in `volume`'s layout (every module reads it
/// through that layout's declaration and functions).
pub fn compose_for(
    plugins: &[&dyn Plugin],
    target: TargetFormat,
    limits: &wgpu::Limits,
    overrides: &std::collections::BTreeMap<String, String>,
    volume: VolumeLayout,
) -> Result<Composition, ComposeError> {
    let mut bindings = Vec::new();
    let mut instances = Vec::new();
    let mut segments = Vec::new();
    // the instances' parameter copies in the main module (`load_frame`)
    let mut params = Vec::new();
    let (mut g1, mut g2) = (0u32, 0u32);
    // the last instance that supplies its scalar (prefix, defines scalar_grid, index)
    let mut scalar_provider: Option<(String, bool, usize)> = None;
    // instances whose pre-pass differentiates the shading scalar (a gradient volume)
    let mut gradient_prepasses: Vec<&'static str> = Vec::new();
    // the first instance whose pre-pass target holds the volume's value: (its target's
    // name in the main module, the instance)
    let mut value_holder: Option<(String, usize)> = None;

    for (index, plugin) in plugins.iter().enumerate() {
        let plugin = *plugin;
        let prefix = instance_prefix(plugin, index);
        let uniform = UniformLayout::new(&plugin.params());
        let mut shader = plugin.shader();
        if let Some(source) = overrides.get(shader.file.as_ref()) {
            shader.source = source.clone().into();
        }

        // bindings of the main module
        let inst_bindings = instance_bindings(plugin, index, &uniform, false, &mut g1, &mut g2);
        let local_names: HashSet<String> =
            inst_bindings.iter().map(|b| b.local_name.clone()).collect();

        // check the file in isolation, with unprefixed names
        let mut iso_g1 = 0;
        let mut iso_g2 = 0;
        let iso_bindings =
            instance_bindings(plugin, index, &uniform, false, &mut iso_g1, &mut iso_g2);
        let mut allowed: Vec<&str> = HOOKS[..7].to_vec();
        allowed.extend(SCALAR_FUNCTIONS);
        if plugin.slice_state().is_some() {
            allowed.push("slice_update");
        }
        let passes = plugin.volume_passes();
        let mut iso_decls = decls_text(&iso_bindings, "", &uniform);
        let has_setup = defines_fn(&shader.source, "setup");
        if has_setup {
            iso_decls.push_str(RAY_RECORD_DECL);
            iso_decls.push('\n');
        }
        if !passes.is_empty() {
            iso_decls.push_str(STACK_CLASSIFY_STUB);
            iso_decls.push('\n');
        }
        let track = plugin
            .slice_state()
            .filter(|st| st.track_clear)
            .map(|st| state_track_wgsl(st.clear));
        if let Some(code) = &track {
            iso_decls.push_str(code);
        }
        let decls = check_plugin_file(plugin, &shader.file, &shader.source, &iso_decls, &allowed)?;
        for vp in &passes {
            if !decls.iter().any(|d| d.is_fn && d.name == vp.entry) {
                return Err(ComposeError::Plugin {
                    plugin: plugin.id().to_string(),
                    message: format!(
                        "{} defines no function '{}' for the volume pass '{}'",
                        shader.file, vp.entry, vp.target
                    ),
                });
            }
            if vp.sweep.is_some() && (vp.accumulate || vp.steps.is_some()) {
                return Err(ComposeError::Plugin {
                    plugin: plugin.id().to_string(),
                    message: format!(
                        "the volume pass '{}' sweeps, which runs once per plane: it cannot also accumulate or refine",
                        vp.target
                    ),
                });
            }
            let read_write = vp.accumulate || vp.sweep.is_some();
            if read_write && vp.format != crate::plugin::StorageFormat::R32Float {
                return Err(ComposeError::Plugin {
                    plugin: plugin.id().to_string(),
                    message: format!(
                        "the volume pass '{}' reads its own target (it accumulates or sweeps), which needs r32float (read-write storage), not {}",
                        vp.target,
                        vp.format.wgsl()
                    ),
                });
            }
        }
        let hooks: Vec<&'static str> = HOOKS
            .iter()
            .copied()
            .filter(|h| decls.iter().any(|d| d.is_fn && d.name == *h))
            .collect();
        let defines = |name: &str| decls.iter().any(|d| d.is_fn && d.name == name);
        if defines("scalar") {
            scalar_provider = Some((prefix.clone(), defines("scalar_grid"), index));
        } else if defines("scalar_grid") {
            return Err(ComposeError::Plugin {
                plugin: plugin.id().to_string(),
                message: format!("{} defines scalar_grid but no scalar", shader.file),
            });
        }
        if plugin.slice_state().is_some() && !hooks.contains(&"slice_update") {
            return Err(ComposeError::Plugin {
                plugin: plugin.id().to_string(),
                message: format!(
                    "declares per-slice state but {} defines no slice_update hook",
                    shader.file
                ),
            });
        }
        let mut names: HashSet<String> = decls.iter().map(|d| d.name.clone()).collect();
        names.extend(local_names.iter().cloned());
        names.insert("Params".to_string());
        let mut instance_decls = decls_text(&inst_bindings, &prefix, &uniform);
        if has_setup {
            names.insert(RAY_RECORD.to_string());
            instance_decls.push_str(&rename(RAY_RECORD_DECL, &names, &prefix));
            instance_decls.push('\n');
        }
        if let Some(code) = &track {
            names.extend(STATE_TRACK_FNS.iter().map(|f| f.to_string()));
            instance_decls.push_str(&rename(code, &names, &prefix));
        }
        let renamed = rename(&shader.source, &names, &prefix);

        // the pre-pass module
        let prepass = match plugin.prepass() {
            Some(pp) => {
                if differentiates_the_shading_scalar(&pp.shader.source) {
                    gradient_prepasses.push(plugin.id());
                }
                if pp.holds_value && value_holder.is_none() {
                    value_holder = Some((format!("{prefix}{}", pp.target), index));
                }
                Some(compose_prepass(
                    plugin, index, &prefix, &uniform, &pp, volume,
                )?)
            }
            None => None,
        };

        let update_entry = plugin.slice_state().map(|_| format!("cs_update_{index}"));
        segments.push((index, shader.file.to_string(), instance_decls, renamed));
        params.extend(param_names(&inst_bindings, &prefix));
        bindings.extend(inst_bindings);
        instances.push(InstanceLayout {
            input_index: index,
            prefix,
            hooks,
            uniform,
            update_entry,
            track_clear: track.is_some(),
            prepass,
            passes: Vec::new(),
        });
    }

    // volume passes: a storage view of each target in group 3 and an entry point
    let mut pass_code = Vec::new();
    let mut next_binding = PASS_BINDING_BASE;
    for inst in &mut instances {
        let plugin = plugins[inst.input_index];
        for vp in plugin.volume_passes() {
            let p = &inst.prefix;
            let out = format!("{p}{}_out", vp.target);
            let access = if vp.accumulate { "read_write" } else { "write" };
            let prev = if vp.accumulate {
                format!("textureLoad({out}, gid)")
            } else {
                "vec4<f32>(0.0)".to_string()
            };
            let entry_point = format!("vp_{p}{}", vp.target);
            if vp.sweep.is_some() {
                let sweep_binding = next_binding + 1;
                pass_code.push((
                    inst.input_index,
                    sweep_entry(
                        &out,
                        next_binding,
                        &entry_point,
                        &format!("{p}{}", vp.entry),
                    ),
                ));
                inst.passes.push(PassLayout {
                    entry_point,
                    binding: next_binding,
                    format: vp.format,
                    accumulate: false,
                    sweep_binding: Some(sweep_binding),
                });
                next_binding += 2;
                continue;
            }
            let code = format!(
                "@group(3) @binding({next_binding}) var {out}: texture_storage_3d<{fmt}, {access}>;\n\
                 @compute @workgroup_size(4, 4, 4)\n\
                 fn {entry_point}(@builtin(global_invocation_id) gid: vec3<u32>) {{\n    \
                 load_frame();\n    \
                 let dims = textureDimensions({out});\n    \
                 if (any(gid >= dims)) {{\n        return;\n    }}\n    \
                 textureStore({out}, gid, {p}{entry}(gid, dims, slice_info.index, {prev}));\n\
                 }}",
                fmt = vp.format.wgsl(),
                entry = vp.entry,
            );
            pass_code.push((inst.input_index, code));
            inst.passes.push(PassLayout {
                entry_point,
                binding: next_binding,
                format: vp.format,
                accumulate: vp.accumulate,
                sweep_binding: None,
            });
            next_binding += 1;
        }
    }

    check_limits(&bindings, limits)?;
    let first = first_params_location();
    let free = limits
        .max_inter_stage_shader_variables
        .saturating_sub(first);
    let vertex_params = vertex_params_wgsl(
        &routed_params(&instances, &bindings, &segments, free),
        first,
    );
    if let (Some((_, _, index)), Some(reader)) = (&scalar_provider, gradient_prepasses.first()) {
        // a pre-pass sees its own plugin only: its gradient volume would be the data's
        return Err(ComposeError::Plugin {
            plugin: reader.to_string(),
            message: format!(
                "its precomputed gradient volume is the data's, but {} replaces the value that shading differentiates; choose the central or sobel estimator",
                plugins[*index].id()
            ),
        });
    }

    // assemble (the half-angle paths only where a per-slice state may travel with a
    // light)
    let half_angle = plugins
        .iter()
        .any(|p| p.slice_state().is_some_and(|st| st.light));
    let mut m = ComposedModule::new();
    m.push_file(COMMON_FILE, &common_code(half_angle, volume), None);
    m.push_generated(
        "shading scalar",
        &shading_scalar_wgsl(
            scalar_provider
                .as_ref()
                .map(|(p, grid, _)| (p.as_str(), *grid)),
        ),
        scalar_provider.as_ref().map(|(_, _, i)| *i),
    );
    // a sample's value: the volume's, or where an instance's pre-pass target holds it
    // exactly beside what that instance reads at the sample (a gradient), from there,
    // so that the two are one fetch (issue 23)
    m.push_generated(
        "sample value",
        &sample_value_wgsl(value_holder.as_ref().map(|(target, _)| target.as_str())),
        value_holder.as_ref().map(|(_, index)| *index),
    );
    let template = half_angle_code(TEMPLATE_FILE, TEMPLATE_WGSL, half_angle);
    for (i, line) in template.lines().enumerate() {
        let origin = Origin::File {
            file: TEMPLATE_FILE.to_string(),
            line: i as u32 + 1,
            instance: None,
        };
        let trimmed = line.trim();
        if trimmed == "//!DECLS" {
            for (index, _, decls, _) in &segments {
                m.push_generated("bindings", decls, Some(*index));
            }
            m.push_generated("frame loads", &frame_loads_wgsl(&params), None);
            m.push_generated("parameters through the vertices", &vertex_params.1, None);
        } else if trimmed == "//!VERTEX_PARAMS" {
            m.push_generated("parameters through the vertices", &vertex_params.0, None);
        } else if trimmed == "//!PLUGINS" {
            for (index, file, _, code) in &segments {
                m.push_file(file, code, Some(*index));
            }
        } else if let Some(hook) = trimmed.strip_prefix("//!HOOK ") {
            for inst in &instances {
                if !inst.hooks.contains(&hook) {
                    continue;
                }
                let p = &inst.prefix;
                let call = match hook {
                    "clip" => format!("    if (!{p}clip(s)) {{ return false; }}"),
                    "composite" => format!("    c = {p}composite(s, c);"),
                    "post" => format!("    c = {p}post(c, uv);"),
                    "setup" => format!("    {p}{RAY_RECORD} = {p}setup(r, uv);"),
                    h => format!("    s = {p}{h}(s);"),
                };
                m.push_line(
                    &call,
                    Origin::Generated {
                        what: format!("{hook} hook call"),
                        instance: Some(inst.input_index),
                    },
                );
            }
        } else if trimmed == "//!UPDATES" {
            for inst in &instances {
                if let Some(entry) = &inst.update_entry {
                    let store = state_store(inst);
                    let code = format!(
                        "// The state update of one slice: over the slice's listed tiles where the\n\
                         // state has the size of the list's grid (`slice_tile`), else over every texel.\n\
                         @compute @workgroup_size(8, 8, 1)\n\
                         fn {entry}(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {{\n    \
                         load_frame();\n    \
                         let size = textureDimensions({p}state_next);\n    \
                         var tile = wg.xy;\n    \
                         let grid = vec2<u32>(slice_info.list_size & 0xffffu, slice_info.list_size >> 16u);\n    \
                         if (all(size == grid)) {{\n        tile = slice_tile(wg.xy);\n    }}\n    \
                         let gid = vec3<u32>(tile * 8u + lid.xy, 0u);\n    \
                         if (gid.x >= size.x || gid.y >= size.y) {{\n        return;\n    }}\n    \
                         let e = state_texel_sample(gid.xy, size);\n\
                         {store}\
                         }}",
                        p = inst.prefix
                    );
                    m.push_generated("state update entry point", &code, Some(inst.input_index));
                }
            }
            let stores: String = instances
                .iter()
                .filter(|inst| inst.update_entry.is_some())
                .map(state_store)
                .collect();
            if !stores.is_empty() {
                let code = tile_entry(
                    "// The slice and every state update in one dispatch, each sample evaluated once\n\
                     // (used when every per-slice state has the eye buffer's resolution), over the\n\
                     // slice's tiles (`slice_tile`).",
                    FUSED_SLICE_ENTRY,
                    "slice_step(gid.xy, size, true)",
                    &stores,
                );
                m.push_generated("fused slice entry point", &code, None);
                let code = tile_entry(
                    "// The state updates alone over the slice's tiles where no sample can be visible\n\
                     // (`slice_tile`): every update gets the pixel's transparent placeholder sample.",
                    STATE_ONLY_ENTRY,
                    "slice_placeholder(gid.xy)",
                    &stores,
                );
                m.push_generated("state-only slice entry point", &code, None);
            }
        } else {
            m.push_line(&line.replace("{{TARGET_FORMAT}}", target.wgsl()), origin);
        }
    }
    for (index, code) in &pass_code {
        m.push_generated("volume pass entry point", code, Some(*index));
    }

    validate_composed(&m, plugins)?;
    Ok(Composition {
        main: m,
        post: instances.iter().any(|i| i.hooks.contains(&"post")),
        bindings,
        instances,
    })
}

/// A per-slice entry point over the slice's listed tiles (`slice_tile`), after the
/// comment `doc`: the sample `e` of each pixel from the expression `sample`, then the
/// state updates `stores` ([`state_store`]).
fn tile_entry(doc: &str, name: &str, sample: &str, stores: &str) -> String {
    format!(
        "{doc}\n\
         @compute @workgroup_size(8, 8, 1)\n\
         fn {name}(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {{\n    \
         load_frame();\n    \
         let size = vec2<u32>(frame.viewport.xy);\n    \
         let gid = vec3<u32>(slice_tile(wg.xy) * 8u + lid.xy, 0u);\n    \
         if (gid.x >= size.x || gid.y >= size.y) {{\n        return;\n    }}\n    \
         let e = {sample};\n\
         {stores}}}"
    )
}

/// The statements of an update entry point that store instance `inst`'s next state
/// texel at `gid.xy` from the sample `e` (and mark its tile where it is tracked).
fn state_store(inst: &InstanceLayout) -> String {
    let p = &inst.prefix;
    if inst.track_clear {
        format!(
            "    {{\n        \
             let v = {p}slice_update(e.s, e.c, e.s.uv);\n        \
             textureStore({p}state_next, vec2<i32>(gid.xy), v);\n        \
             {p}state_mark(gid.xy, v);\n    \
             }}\n"
        )
    } else {
        format!(
            "    textureStore({p}state_next, vec2<i32>(gid.xy), {p}slice_update(e.s, e.c, e.s.uv));\n"
        )
    }
}

/// The entry point of a sweep pass writing `out` (group 3, `binding`; its `SweepInfo`
/// at the next binding): one dispatch per plane, `slice_info.index` the plane, each
/// invocation one texel of the plane, `prev` the previous plane's value at the texel's
/// upstream point, interpolated bilinearly with taps outside the plane (and everything
/// before the first plane) at the boundary (`crate::sweep`).
fn sweep_entry(out: &str, binding: u32, entry_point: &str, entry: &str) -> String {
    let info = format!("{out}_sweep");
    format!(
        "@group(3) @binding({binding}) var {out}: texture_storage_3d<r32float, read_write>;\n\
         @group(3) @binding({b1}) var<uniform> {info}: SweepInfo;\n\
         fn {out}_tap(sw: SweepInfo, a: i32, bc: vec2<i32>, size: vec2<i32>) -> f32 {{\n    \
         if (any(bc < vec2<i32>(0)) || any(bc >= size)) {{\n        return sw.boundary;\n    }}\n    \
         return textureLoad({out}, sweep_place(sw, a, bc)).x;\n\
         }}\n\
         @compute @workgroup_size(8, 8, 1)\n\
         fn {entry_point}(@builtin(global_invocation_id) gid: vec3<u32>) {{\n    \
         load_frame();\n    \
         let sw = {info};\n    \
         let dims = textureDimensions({out});\n    \
         let sizes = sweep_sizes(sw, dims);\n    \
         let plane = slice_info.index;\n    \
         if (gid.x >= sizes.y || gid.y >= sizes.z || plane >= sizes.x) {{\n        return;\n    }}\n    \
         let bc = vec2<i32>(gid.xy);\n    \
         let voxel = vec3<u32>(sweep_place(sw, sweep_plane(sw, plane, sizes.x), bc));\n    \
         var prev = vec4<f32>(sw.boundary, 0.0, 0.0, 0.0);\n    \
         if (plane > 0u) {{\n        \
         let a = sweep_plane(sw, plane - 1u, sizes.x);\n        \
         let size = vec2<i32>(sizes.yz);\n        \
         let p = vec2<f32>(bc) + sw.shift;\n        \
         let lo = vec2<i32>(floor(p));\n        \
         let f = p - floor(p);\n        \
         let x0 = mix({out}_tap(sw, a, lo, size), {out}_tap(sw, a, lo + vec2<i32>(1, 0), size), f.x);\n        \
         let x1 = mix({out}_tap(sw, a, lo + vec2<i32>(0, 1), size), {out}_tap(sw, a, lo + vec2<i32>(1, 1), size), f.x);\n        \
         prev.x = mix(x0, x1, f.y);\n    \
         }}\n    \
         textureStore({out}, voxel, {entry}(voxel, dims, plane, prev, sw.length));\n\
         }}",
        b1 = binding + 1,
    )
}

fn compose_prepass(
    plugin: &dyn Plugin,
    index: usize,
    prefix: &str,
    uniform: &UniformLayout,
    pp: &crate::plugin::PrepassDecl,
    volume: VolumeLayout,
) -> Result<(ComposedModule, Vec<Binding>), ComposeError> {
    let (mut g1, mut g2) = (0, 0);
    let iso = instance_bindings(plugin, index, uniform, true, &mut g1, &mut g2);
    let decls = check_plugin_file(
        plugin,
        &pp.shader.file,
        &pp.shader.source,
        &decls_text(&iso, "", uniform),
        &["prepass"],
    )?;
    if !decls.iter().any(|d| d.is_fn && d.name == "prepass") {
        return Err(ComposeError::Plugin {
            plugin: plugin.id().to_string(),
            message: format!("{} defines no prepass function", pp.shader.file),
        });
    }
    let mut names: HashSet<String> = decls.iter().map(|d| d.name.clone()).collect();
    names.extend(iso.iter().map(|b| b.local_name.clone()));
    let mut m = ComposedModule::new();
    m.push_file(COMMON_FILE, &common_code(false, volume), None);
    m.push_generated("shading scalar", &shading_scalar_wgsl(None), None);
    m.push_generated("bindings", &decls_text(&iso, prefix, uniform), Some(index));
    m.push_generated(
        "frame loads",
        &frame_loads_wgsl(&param_names(&iso, prefix)),
        Some(index),
    );
    m.push_file(
        &pp.shader.file,
        &rename(&pp.shader.source, &names, prefix),
        Some(index),
    );
    let target = format!("{prefix}{}", pp.target);
    let entry = format!(
        "@compute @workgroup_size(4, 4, 4)\n\
         fn prepass_main(@builtin(global_invocation_id) gid: vec3<u32>) {{\n    \
         load_frame();\n    \
         let dims = textureDimensions({target});\n    \
         if (any(gid >= dims)) {{\n        return;\n    }}\n    \
         textureStore({target}, gid, {prefix}prepass(gid, dims));\n\
         }}"
    );
    m.push_generated("pre-pass entry point", &entry, Some(index));
    validate_composed(&m, &[plugin])?;
    Ok((m, iso))
}

/// Validates a composed module; errors are mapped through its origin table.
pub fn validate_composed(m: &ComposedModule, plugins: &[&dyn Plugin]) -> Result<(), ComposeError> {
    match naga_check(&m.source) {
        Ok(module) => check_frame_loads(&module).map_err(|message| ComposeError::Shader {
            file: "<composed>".to_string(),
            line: 0,
            column: 0,
            message,
            plugin: None,
        }),
        Err((message, offset)) => Err(map_error(m, plugins, message, offset)),
    }
}

/// The functions that take the frame's private copy (`load_frame`, [`frame_loads_wgsl`];
/// shaders/common.wgsl `load_frame_vertex`, shaders/slice.wgsl `load_frame_fragment`).
const FRAME_LOADS: [&str; 3] = ["load_frame", "load_frame_vertex", "load_frame_fragment"];

/// The suffix of a parameter uniform's name; the plugin's code reads the private copy
/// under the plain name ([`Binding::wgsl`]).
const UNIFORM_SUFFIX: &str = "_uniform";

/// A module's `load_frame`: the frame's private copy (shaders/common.wgsl) and each of
/// `params` (the instances' parameters, by their names in the module) from its uniform.
/// Every entry point calls it first ([`check_frame_loads`]).
fn frame_loads_wgsl(params: &[String]) -> String {
    let mut s = String::from(
        "// Every entry point's first call: the frame's and each plugin instance's parameters'\n\
         // private copies from their uniforms (shaders/common.wgsl, `frame`).\n\
         fn load_frame() {\n    frame = frame_uniform;\n",
    );
    for p in params {
        s.push_str(&format!("    {p} = {p}{UNIFORM_SUFFIX};\n"));
    }
    s.push_str("}\n");
    s
}

/// The first location of the slice template's `VsOut` (shaders/slice.wgsl) free for
/// the parameters that [`vertex_params_wgsl`] routes: one past its highest `@location`.
fn first_params_location() -> u32 {
    let body = TEMPLATE_WGSL
        .split("struct VsOut {")
        .nth(1)
        .and_then(|s| s.split("\n}").next())
        .unwrap_or("");
    body.match_indices("@location(")
        .filter_map(|(i, m)| body[i + m.len()..].split(')').next()?.parse::<u32>().ok())
        .max()
        .map_or(0, |l| l + 1)
}

/// One parameter that the slice vertices pass to their fragments as flat words.
struct RoutedParam {
    /// The instance's private copy in the module (`p1_blinn_phong_params`).
    copy: String,
    key: &'static str,
    wgsl_type: &'static str,
}

impl RoutedParam {
    /// The member's type, and the words it takes (vectors by their components).
    fn words(&self) -> (&'static str, usize) {
        match self.wgsl_type {
            "vec4<f32>" => ("f32", 4),
            "vec3<f32>" => ("f32", 3),
            t => (t, 1),
        }
    }
}

/// The parameters to route through the slice vertices' flat outputs: each instance's
/// members that its code reads (`copy.key`), in stack order, then the frame's ray basis,
/// as many whole members as the `free` locations of `VsOut` hold (those that the device's
/// `max_inter_stage_shader_variables` leaves). llvmpipe reads a uniform in a fragment
/// shader one lane at a time, about 30 instructions a word, and a flat input as one
/// broadcast (docs/perf.md, "The parameters through the vertices"). `instances` and
/// `segments` are parallel, one entry per enabled instance.
fn routed_params(
    instances: &[InstanceLayout],
    bindings: &[Binding],
    segments: &[(usize, String, String, String)],
    free: u32,
) -> Vec<RoutedParam> {
    let mut budget = 4 * free as usize;
    let mut out = Vec::new();
    for (inst, (.., code)) in instances.iter().zip(segments) {
        let uniforms = bindings.iter().filter(|b| {
            b.instance == inst.input_index && matches!(b.kind, BindingKind::Uniform { .. })
        });
        for b in uniforms {
            let copy = format!("{}{}", inst.prefix, b.local_name);
            for m in &inst.uniform.members {
                let p = RoutedParam {
                    copy: copy.clone(),
                    key: m.key,
                    wgsl_type: m.wgsl_type,
                };
                let words = p.words().1;
                if words <= budget && reads_member(code, &copy, m.key) {
                    budget -= words;
                    out.push(p);
                }
            }
        }
    }
    // then the frame's ray basis, which `pixel_ray` reads (the chunk bits' fragments
    // always, a slice fragment where an instance sets up its rays)
    for key in FRAME_RAY_BASIS {
        if budget >= 4 {
            budget -= 4;
            out.push(RoutedParam {
                copy: "frame".to_string(),
                key,
                wgsl_type: "vec4<f32>",
            });
        }
    }
    out
}

/// The frame's members after the parameters in [`routed_params`]: the columns of its
/// `ray_basis` (shaders/common.wgsl `pixel_ray`).
const FRAME_RAY_BASIS: [&str; 4] = [
    "ray_basis[0]",
    "ray_basis[1]",
    "ray_basis[2]",
    "ray_basis[3]",
];

/// Whether `code` reads `copy.key` (a whole member name, not a prefix of another).
fn reads_member(code: &str, copy: &str, key: &str) -> bool {
    let needle = format!("{copy}.{key}");
    code.match_indices(&needle).any(|(i, _)| {
        let before = code[..i].chars().next_back();
        let after = code[i + needle.len()..].chars().next();
        let ident = |c: Option<char>| c.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_');
        !ident(before) && !ident(after)
    })
}

/// The fields of `VsOut` (from location `first`) and the functions `params_to_vertex` and
/// `params_from_vertex` (shaders/slice.wgsl `frame_to_vertex`, `load_frame_fragment`) that carry
/// `routed` as flat words. The values are the uniform's, bit for bit.
fn vertex_params_wgsl(routed: &[RoutedParam], first: u32) -> (String, String) {
    const C: [&str; 4] = ["x", "y", "z", "w"];
    let slot = |w: usize| format!("params_{}.{}", w / 4, C[w % 4]);
    let mut words: Vec<String> = Vec::new();
    let mut reads = String::new();
    for p in routed {
        let (ty, n) = p.words();
        let member = format!("{}{UNIFORM_SUFFIX}.{}", p.copy, p.key);
        let mut parts = Vec::new();
        for c in C.iter().take(n) {
            let v = if n == 1 {
                member.clone()
            } else {
                format!("{member}.{c}")
            };
            words.push(if ty == "u32" {
                v
            } else {
                format!("bitcast<u32>({v})")
            });
            let w = format!("in.{}", slot(words.len() - 1));
            parts.push(if ty == "u32" {
                w
            } else {
                format!("bitcast<{ty}>({w})")
            });
        }
        let value = if n == 1 {
            parts.remove(0)
        } else {
            format!("{}({})", p.wgsl_type, parts.join(", "))
        };
        reads.push_str(&format!("    {}.{} = {value};\n", p.copy, p.key));
    }
    let locations = words.len().div_ceil(4);
    words.resize(4 * locations, "0u".to_string());
    let mut fields = String::new();
    let mut writes = String::new();
    for (l, w) in words.chunks(4).enumerate() {
        fields.push_str(&format!(
            "    @location({}) @interpolate(flat) params_{l}: vec4<u32>,\n",
            first + l as u32
        ));
        writes.push_str(&format!(
            "    (*o).params_{l} = vec4<u32>({});\n",
            w.join(", ")
        ));
    }
    let fns = format!(
        "// The plugin instances' parameters that the slice fragments read, as flat words of\n\
         // every vertex, and the frame's ray basis (where `FRAME_FROM_VERTEX`; as many as the\n\
         // device's inter-stage locations hold): written by `frame_to_vertex`, read by\n\
         // `load_frame_fragment`.\n\
         fn params_to_vertex(o: ptr<function, VsOut>) {{\n{writes}}}\n\
         fn params_from_vertex(in: VsOut) {{\n{reads}}}\n"
    );
    (fields, fns)
}

/// The names in a module of the parameter uniforms among an instance's `bindings`
/// (their private copies', with the instance's `prefix`), for [`frame_loads_wgsl`].
fn param_names(bindings: &[Binding], prefix: &str) -> Vec<String> {
    bindings
        .iter()
        .filter(|b| matches!(b.kind, BindingKind::Uniform { .. }))
        .map(|b| format!("{prefix}{}", b.local_name))
        .collect()
}

/// Checks that every entry point of a module with the private `frame` (shaders/
/// common.wgsl) calls one of [`FRAME_LOADS`] before anything else: an entry point that
/// does not would read a frame of zeros, silently.
pub fn check_frame_loads(module: &naga::Module) -> Result<(), String> {
    let has_frame = module
        .global_variables
        .iter()
        .any(|(_, g)| g.name.as_deref() == Some("frame") && g.space == naga::AddressSpace::Private);
    if !has_frame {
        return Ok(());
    }
    for ep in &module.entry_points {
        let first = ep
            .function
            .body
            .iter()
            .find(|st| !matches!(st, naga::Statement::Emit(_)));
        let loads = match first {
            Some(naga::Statement::Call { function, .. }) => module.functions[*function]
                .name
                .as_deref()
                .is_some_and(|n| FRAME_LOADS.contains(&n)),
            _ => false,
        };
        if !loads {
            return Err(format!(
                "entry point `{}` does not begin with `load_frame()` (or `load_frame_vertex()`, or for a slice fragment `load_frame_fragment(in)`): it would read a frame of zeros",
                ep.name
            ));
        }
    }
    Ok(())
}

/// The first assignment to the frame or to a parameter copy (a private global beside a
/// uniform of its name and [`UNIFORM_SUFFIX`]) outside [`FRAME_LOADS`]: (message, offset
/// in the source). They were uniforms, read-only; as private copies a write would
/// change what the writing invocation's later hooks and other plugins read, so plugin
/// code may not write them.
fn private_copy_write(module: &naga::Module) -> Option<(String, Option<usize>)> {
    let name_of = |g: naga::Handle<naga::GlobalVariable>| {
        module.global_variables[g].name.clone().unwrap_or_default()
    };
    let names: HashSet<&str> = module
        .global_variables
        .iter()
        .filter_map(|(_, g)| g.name.as_deref())
        .collect();
    let copies: HashSet<naga::Handle<naga::GlobalVariable>> = module
        .global_variables
        .iter()
        .filter(|(_, g)| {
            g.space == naga::AddressSpace::Private
                && g.name.as_deref().is_some_and(|n| {
                    n == "frame" || names.contains(format!("{n}{UNIFORM_SUFFIX}").as_str())
                })
        })
        .map(|(h, _)| h)
        .collect();
    let functions = module
        .functions
        .iter()
        .map(|(_, f)| f)
        .chain(module.entry_points.iter().map(|ep| &ep.function));
    for f in functions {
        let name = f.name.as_deref().unwrap_or("");
        if FRAME_LOADS.contains(&name) {
            continue;
        }
        if let Some((g, span)) = store_into(&f.body, f, &copies) {
            return Some((
                format!(
                    "`{name}` assigns to `{}`: the frame and the parameters are read-only (copy them into a local variable to change them)",
                    name_of(g)
                ),
                span.to_range().map(|r| r.start),
            ));
        }
    }
    None
}

/// The first statement of `block` (nested blocks included) that stores through a
/// pointer into one of `globals` (a member or an element of it included).
fn store_into(
    block: &naga::Block,
    f: &naga::Function,
    globals: &HashSet<naga::Handle<naga::GlobalVariable>>,
) -> Option<(naga::Handle<naga::GlobalVariable>, naga::Span)> {
    let root = |mut e: naga::Handle<naga::Expression>| loop {
        match f.expressions[e] {
            naga::Expression::GlobalVariable(g) => return Some(g),
            naga::Expression::AccessIndex { base, .. } | naga::Expression::Access { base, .. } => {
                e = base
            }
            _ => return None,
        }
    };
    for (st, span) in block.span_iter() {
        let found = match st {
            naga::Statement::Store { pointer, .. } => root(*pointer)
                .filter(|g| globals.contains(g))
                .map(|g| (g, *span)),
            naga::Statement::Block(b) => store_into(b, f, globals),
            naga::Statement::If { accept, reject, .. } => {
                store_into(accept, f, globals).or_else(|| store_into(reject, f, globals))
            }
            naga::Statement::Switch { cases, .. } => {
                cases.iter().find_map(|c| store_into(&c.body, f, globals))
            }
            naga::Statement::Loop {
                body, continuing, ..
            } => store_into(body, f, globals).or_else(|| store_into(continuing, f, globals)),
            _ => None,
        };
        if found.is_some() {
            return found;
        }
    }
    None
}

fn map_error(
    m: &ComposedModule,
    plugins: &[&dyn Plugin],
    message: String,
    offset: Option<usize>,
) -> ComposeError {
    let (line, column) = offset.map_or((0, 0), |o| line_col(&m.source, o));
    let plugin_id = |i: Option<usize>| i.and_then(|i| plugins.get(i)).map(|p| p.id().to_string());
    match m.origin(line) {
        Some(Origin::File {
            file,
            line,
            instance,
        }) => ComposeError::Shader {
            file: file.clone(),
            line: *line,
            column,
            message,
            plugin: plugin_id(*instance),
        },
        Some(Origin::Generated { what, instance }) => ComposeError::Shader {
            file: format!("<generated {what}>"),
            line: 0,
            column,
            message,
            plugin: plugin_id(*instance),
        },
        None => ComposeError::Shader {
            file: "<composed>".to_string(),
            line,
            column,
            message,
            plugin: None,
        },
    }
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Origin::File { file, line, .. } => write!(f, "{file}:{line}"),
            Origin::Generated { what, .. } => write!(f, "<generated {what}>"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An entry point of a module with the private frame that does not take it first
    /// (`load_frame`) is refused by name; a late load counts as none; modules without
    /// the private frame (the display and compositing shaders) are not concerned.
    #[test]
    fn every_entry_point_must_load_the_frame_first() {
        let head = "struct Frame { a: f32 }\n\
                    @group(0) @binding(0) var<uniform> frame_uniform: Frame;\n\
                    var<private> frame: Frame;\n\
                    fn load_frame() { frame = frame_uniform; }\n\
                    @group(0) @binding(1) var<storage, read_write> out: array<f32>;\n";
        let good = "@compute @workgroup_size(1) fn good() { load_frame(); out[0] = frame.a; }\n";
        let module = naga_check(&format!("{head}{good}")).unwrap();
        assert_eq!(check_frame_loads(&module), Ok(()));
        for bad in [
            "@compute @workgroup_size(1) fn bad() { out[0] = frame.a; }\n",
            "@compute @workgroup_size(1) fn bad() { out[0] = 1.0; load_frame(); }\n",
        ] {
            let module = naga_check(&format!("{head}{good}{bad}")).unwrap();
            let err = check_frame_loads(&module).unwrap_err();
            assert!(err.contains("`bad`"), "{err}");
        }
        let uniform_only = "struct Frame { a: f32 }\n\
                            @group(0) @binding(0) var<uniform> frame: Frame;\n\
                            @group(0) @binding(1) var<storage, read_write> out: array<f32>;\n\
                            @compute @workgroup_size(1) fn main() { out[0] = frame.a; }\n";
        assert_eq!(
            check_frame_loads(&naga_check(uniform_only).unwrap()),
            Ok(())
        );
    }

    /// Plugin code may read the frame and its parameters (private copies of their
    /// uniforms) and change local copies, but not assign to them, anywhere in a
    /// function; `load_frame` alone writes them.
    #[test]
    fn the_frame_and_the_parameters_are_read_only() {
        let head = "struct Frame { a: f32, b: vec4<f32> }\n\
                    struct Params { k: f32 }\n\
                    @group(0) @binding(0) var<uniform> frame_uniform: Frame;\n\
                    var<private> frame: Frame;\n\
                    @group(1) @binding(0) var<uniform> params_uniform: Params;\n\
                    var<private> params: Params;\n\
                    var<private> scratch: f32;\n\
                    fn load_frame() { frame = frame_uniform; params = params_uniform; }\n";
        let fine = "fn f(x: f32) -> f32 { var p = params; p.k = 2.0; scratch = x; return p.k * frame.a; }\n";
        let module = naga_check(&format!("{head}{fine}")).unwrap();
        assert_eq!(private_copy_write(&module), None);
        for (bad, global) in [
            (
                "fn f(x: f32) -> f32 { params.k = x; return x; }\n",
                "params",
            ),
            (
                "fn f(x: f32) -> f32 { if (x > 0.0) { frame.b.y = x; } return x; }\n",
                "frame",
            ),
            (
                "fn f(x: f32) -> f32 { loop { frame = frame_uniform; break; } return x; }\n",
                "frame",
            ),
        ] {
            let src = format!("{head}{bad}");
            let (message, offset) = private_copy_write(&naga_check(&src).unwrap()).unwrap();
            assert!(
                message.contains(&format!("`f` assigns to `{global}`")),
                "{message}"
            );
            let at = offset.expect("the statement's offset");
            assert!(at >= head.len(), "{at}: in the function");
        }
    }

    #[test]
    fn tokenizer_keeps_text_and_skips_comments() {
        let src = "fn a(x: f32) -> f32 { /* a /* nested */ b */ return x.a + 1.0e-3; } // a\n";
        let joined: String = tokenize(src).iter().map(|t| &src[t.1..t.2]).collect();
        assert_eq!(joined, src);
        let names: HashSet<String> = ["a".to_string()].into();
        let r = rename(src, &names, "p0_");
        assert_eq!(
            r,
            "fn p0_a(x: f32) -> f32 { /* a /* nested */ b */ return x.a + 1.0e-3; } // a\n"
        );
    }

    #[test]
    fn decls_are_found_at_module_scope_only() {
        let src = "const K = 1.0;\nvar<private> g: f32;\nstruct S { a: f32 }\nfn f() { let inner = 1; }\nalias T = f32;\noverride o: f32 = 1.0;";
        let d: Vec<(String, bool, u32)> = module_decls(src)
            .into_iter()
            .map(|d| (d.name, d.is_fn, d.line))
            .collect();
        assert_eq!(
            d,
            vec![
                ("K".into(), false, 1),
                ("g".into(), false, 2),
                ("S".into(), false, 3),
                ("f".into(), true, 4),
                ("T".into(), false, 5),
                ("o".into(), false, 6)
            ]
        );
    }

    #[test]
    fn standalone_shaders_are_valid() {
        naga_check(crate::renderer::DISPLAY_WGSL).expect("shaders/display.wgsl");
        naga_check(crate::renderer::COMPOSITE_WGSL).expect("shaders/composite.wgsl");
        naga_check(crate::renderer::RASTER_MASK_WGSL).expect("shaders/raster_mask.wgsl");
    }

    /// Each volume layout's module declares the volume once, in its own type, and the
    /// two modules have the same lines (the other region blanked line for line), so
    /// that errors map to the same lines of shaders/common.wgsl.
    #[test]
    fn volume_layouts_declare_their_own_volume_line_for_line() {
        let none = Default::default();
        let limits = wgpu::Limits::default();
        let of = |layout| {
            compose_for(&[], TargetFormat::Rgba16Float, &limits, &none, layout)
                .unwrap()
                .main
                .source
        };
        let (three_d, pairs) = (of(VolumeLayout::Texture3d), of(VolumeLayout::ZPairs));
        assert_eq!(three_d.lines().count(), pairs.lines().count());
        for (src, own, other) in [
            (&three_d, "texture_3d<f32>", "texture_2d_array<f32>"),
            (&pairs, "texture_2d_array<f32>", "texture_3d<f32>"),
        ] {
            let decl = |ty: &str| format!("var volume_tex: {ty};");
            assert_eq!(src.matches(&decl(own)).count(), 1);
            assert_eq!(src.matches(&decl(other)).count(), 0);
            assert_eq!(src.matches("fn volume_value(").count(), 1);
        }
        // the lines outside the two regions are the same
        let differing = three_d
            .lines()
            .zip(pairs.lines())
            .filter(|(a, b)| a != b)
            .count();
        let region = |name: &str| {
            let begin = COMMON_WGSL.find(&format!("// {name}: begin")).unwrap();
            let end = COMMON_WGSL.find(&format!("// {name}: end")).unwrap();
            COMMON_WGSL[begin..end].lines().count() + 1
        };
        assert!(differing <= region("volume_texture3d") + region("volume_z_pairs"));
    }

    #[test]
    fn empty_stack_composes_and_validates() {
        let c = compose(&[], TargetFormat::Rgba16Float, &wgpu::Limits::default()).unwrap();
        assert!(c.main.source.contains("fn cs_main"));
        assert!(c.bindings.is_empty());
        assert_eq!(c.main.source.lines().count(), c.main.origins.len());
    }
}
