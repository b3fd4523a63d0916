//! Local illumination shared by the shading plugins (Rezk-Salama 2001, ch. 7): gradient
//! estimators, the shading normal with its fade rule, lights and the Blinn–Phong model.
//! This module is the f64 CPU twin of the WGSL helpers at the end of
//! `shaders/common.wgsl`; each function names its WGSL counterpart.
//!
//! # Gradients
//!
//! Every estimator returns `g = ∇f · Δs0`: the gradient of the normalised scalar in world
//! space (so anisotropic voxels are accounted for: each axis is divided by its voxel
//! size) times Δs0, the world length of one voxel along the finest axis. For isotropic
//! volumes |g| is "normalised value per voxel".
//!
//! | estimator | reads per sample | memory | what |
//! |---|---|---|---|
//! | `auto` (default) | | | `precomputed_central` on CPU adapters where its volume fits ([`auto_estimator`]), else `central`: the same gradients up to rounding |
//! | `central` | 6 trilinear | none | (f(x+h) − f(x−h)) / 2h per axis, h one voxel, at the sample |
//! | `sobel` | 26 trilinear | none | 3×3×3 Sobel (derivative ⊗ \[1,2,1\] ⊗ \[1,2,1\] / 32) at the sample |
//! | `precomputed_central` | 1 trilinear, shared with the sample's value | 16 B/voxel | `central` at every voxel centre, rgba32float, interpolated |
//! | `precomputed_sobel` | 1 trilinear, shared with the sample's value | 16 B/voxel | `sobel` at every voxel centre, rgba32float, interpolated |
//! | `quantized` | 1 nearest | 4 B/voxel | `central` at every voxel centre, direction in 16 bits, magnitude in 8, not interpolated |
//! | `precomputed_normal` | 1 trilinear, beside the sample's value | 4 B/voxel | the thesis's normal texture (§7.2, eq 7.5): `central`'s unit direction scaled and biased into rgb, √magnitude in a, rgba8unorm, interpolated and renormalised |
//! | `precomputed_normal_unnormalized` | as `precomputed_normal` | 4 B/voxel | the same texture, the interpolated normal not renormalised (§7.5: shorter between voxels whose normals differ) |
//!
//! The pre-pass (`shaders/gradient_prepass.wgsl`) evaluates the on-the-fly estimator at
//! voxel centres, where trilinear interpolation returns the voxel itself, and stores
//! (g, value) as rgba32float; it reruns only when the volume changes. The voxel's value
//! in w lets the main module read a sample's value from the same texel as its gradient
//! (`sample_value`, [`crate::plugin::PrepassDecl::holds_value`]): one trilinear fetch
//! gives both, where the on-the-fly estimators add theirs to the volume's.
//! Until session 65 it stored (g, |g|) as rgba16float (8 B/voxel) and each sample
//! fetched the volume as well (docs/perf.md, "One fetch for the value and the gradient").
//!
//! `precomputed_central` is `central` computed in another order. Central differences
//! one texel apart are linear in the reads, and a read one texel off has the same
//! trilinear weights, so the interpolated voxels' differences equal the differences of
//! the interpolated reads; within half a texel of a face, where `central`'s read beyond
//! the face clamps to the edge texel, [`central_edge_factor`] scales the component
//! across that face as the clamp does. The two differ by rounding only (0.03 ΔE*uv RMS
//! on the CT head with fp16 storage, docs/perf.md). That is what lets `auto` pick either:
//! on lavapipe the pre-pass volume's one fetch costs less than `central`'s six, from
//! 512² up, for 16 bytes per voxel (issue 23, item 3).
//!
//! `quantized` is the cheap estimator of CPU ray casters such as VTK's fixed-point
//! caster (issue 23, item 3): the pre-pass stores the direction of `central`'s gradient
//! in 16 bits (the octahedral map of the unit sphere onto [−1, 1]², Meyer et al. 2010,
//! 8 bits per coordinate) and its magnitude in 8 (√|g| in 1/255 steps, clamped to
//! |g| ≤ 1, so the steps are finest near the fade floor), as rgba8unorm; a sample reads
//! its nearest voxel's code with one `textureLoad` (codes are not interpolated). The
//! direction error is below 1° ([`oct_decode`] of [`gradient_code`]); the nearest-voxel
//! lookup facets the shading at the voxel scale, which the experiment
//! `experiments/cheap_shading.ron` measures against the converged reference.
//!
//! `precomputed_normal` is the gradient texture of Rezk-Salama 2001, §7.2 (eq 7.5):
//! the normalised gradient of `central` at every voxel, "scaled and biased" into
//! unsigned 8-bit channels (rgb = 0.5·ĝ + 0.5, decoded as 2·rgb − 1), interpolated by
//! the texture unit. The thesis's layout for semi-transparent shading is kept: the
//! scalar stays in its own texture (the sample's value is the volume's, as for
//! `central`), and a holds the gradient magnitude, here as √|g| in 1/255 steps like
//! `quantized`'s (finest near the fade floor; the thesis stores |g|). A sample's
//! gradient is the interpolated direction renormalised ("[IMPL] normalise in the
//! shader"), with the interpolated code's magnitude a². A zero gradient stores the
//! bias point, which decodes to (1/255, 1/255, 1/255), not zero; its magnitude 0 fades
//! it to unlit. `precomputed_normal_unnormalized` shades with the interpolated vector
//! as it comes from the texture, shorter than 1 between voxels whose normals differ:
//! the thesis's hardware did so, and §7.5 calls the dimming "hardly visible" (its
//! testable claim 9, measured by `experiments/normal_texture.ron`). The length (≤ 1)
//! scales the normal that `shading_normal` returns: on the GPU through the private
//! `shading_normal_scale` that every `gradient_at` sets, in the twin through
//! [`Gradients::normal`]. The interpolation of the 8-bit codes is the texture unit's,
//! and the twin's is f64: lavapipe filters unorm8 textures in 8-bit fixed point (the
//! same codes stored as rgba32float match the twin as closely as `precomputed_central`
//! does), as GPUs' texture units filter with 8-bit weights, so the twin tests hold
//! these two estimators to the bounds they hold on a GPU (`coverage.rs`).
//!
//! # Shading normal and the fade rule
//!
//! `n = −g/|g|` (outward for "bright inside" data such as bone in CT), flipped towards
//! the viewer when shading is two-sided. Where the gradient vanishes the normal is
//! meaningless, so shading fades to unlit: the shaded colour is
//! `mix(unlit, lit, w)` with `w = clamp(|g| / floor, 0, 1)`, `floor` a parameter in
//! normalised value per voxel. `w` is 0 at |g| = 0 (no normal is formed, so no NaN) and
//! continuous.
//!
//! # Lights and Blinn–Phong
//!
//! Light vectors are given in view space (x right, y up, z towards the viewer; point
//! lights relative to the eye) or world space. Per light (unit `l` towards the light,
//! `v = −ray_dir`, `h = normalize(l + v)`): diffuse `max(n·l, 0)`, specular
//! `max(n·h, 0)^shininess` where `n·l > 0` (eqs 7.1–7.4 with the clamps the hardware
//! applied). No distance attenuation. Two ways of applying them:
//! - `modulate`: rgb = base·(k_a + Σ k_d·diff·L) + Σ k_s·spec·L
//! - `additive` (the thesis's semi-transparent mode, §7.3): rgb = base + Σ (k_d·diff + k_s·spec)·L,
//!   with k_a scaling base (k_a = 1 is the thesis's "emission is the ambient term").

use glam::{DVec2, DVec3, DVec4};

use crate::params::{ParamSpec, ParamValues};
use crate::plugin::{CpuContext, PrepassDecl, ShaderSource, StorageFormat};

/// Gradient estimator of a shading plugin (the structural parameter `gradient`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum GradientEstimator {
    #[default]
    Central,
    Sobel,
    PrecomputedCentral,
    PrecomputedSobel,
    Quantized,
    PrecomputedNormal,
    PrecomputedNormalUnnormalized,
}

impl GradientEstimator {
    pub const ALL: [Self; 7] = [
        Self::Central,
        Self::Sobel,
        Self::PrecomputedCentral,
        Self::PrecomputedSobel,
        Self::Quantized,
        Self::PrecomputedNormal,
        Self::PrecomputedNormalUnnormalized,
    ];
    pub const NAMES: [&'static str; 7] = [
        "central",
        "sobel",
        "precomputed_central",
        "precomputed_sobel",
        "quantized",
        "precomputed_normal",
        "precomputed_normal_unnormalized",
    ];

    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }
    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.name() == s)
    }
    /// The estimator the `gradient` parameter selects (`central` when absent, and for
    /// `auto` where no renderer resolved it, e.g. in a CPU twin: the same gradients).
    pub fn from_params(params: &ParamValues) -> Self {
        Self::from_name(params.enumeration("gradient")).unwrap_or_default()
    }
    /// Whether a pre-pass volume holds the gradients (the `precomputed_*` ones and
    /// `quantized`).
    pub fn is_precomputed(self) -> bool {
        !matches!(self, Self::Central | Self::Sobel)
    }
    /// Whether the pre-pass holds the thesis's normal texture (`precomputed_normal*`).
    pub fn is_normal_texture(self) -> bool {
        matches!(
            self,
            Self::PrecomputedNormal | Self::PrecomputedNormalUnnormalized
        )
    }
    pub fn is_sobel(self) -> bool {
        matches!(self, Self::Sobel | Self::PrecomputedSobel)
    }

    /// The `gradient` parameter's options: `auto`, then the estimators.
    pub const PARAM_NAMES: [&'static str; 8] = [
        "auto",
        "central",
        "sobel",
        "precomputed_central",
        "precomputed_sobel",
        "quantized",
        "precomputed_normal",
        "precomputed_normal_unnormalized",
    ];

    /// The structural parameter that selects it (default `auto`, which the renderer
    /// resolves: [`auto_estimator`]).
    pub fn param() -> ParamSpec {
        ParamSpec::enumeration("gradient", "Gradient estimator", &Self::PARAM_NAMES, 0)
            .structural()
            .with_doc(
                "auto: precomputed_central on CPU adapters where its volume fits, else \
                 central (the same gradients up to rounding); central: 6 reads per \
                 sample; sobel: 26 reads; precomputed_*: a pre-pass volume (rgba32float, \
                 16 bytes per voxel), 1 interpolated read that also gives the sample's \
                 value; quantized: central's direction \
                 in 16 bits and magnitude in 8 (4 bytes per voxel), 1 read of the nearest \
                 voxel; precomputed_normal: the thesis's normal texture (central's unit \
                 direction scaled and biased into 8 bits per channel, √magnitude in \
                 alpha; 4 bytes per voxel), 1 interpolated read besides the value's, \
                 renormalised; precomputed_normal_unnormalized: the same, the \
                 interpolated normal used as it is (shorter between voxels)",
            )
    }

    /// Whether `params` leave the estimator to the renderer (`gradient: auto`).
    pub fn is_auto(params: &ParamValues) -> bool {
        matches!(params.get("gradient"), Some(crate::params::ParamValue::Enum(s)) if s == "auto")
    }

    /// The plugin's hook file with `fn gradient_at(tex: vec3<f32>) -> vec3<f32>` appended
    /// (the estimator's gradient, or the clip cut's where a clip hook set one: `cut_gradient`)
    /// (appended, so that the file's own line numbers stay those of the file).
    pub fn hook_source(self, file: &'static str, source: &'static str) -> ShaderSource {
        self.append_to(ShaderSource::new_static(file, source))
    }

    /// [`GradientEstimator::hook_source`] for a source already built (e.g. with regions
    /// left out).
    pub fn append_to(self, shader: ShaderSource) -> ShaderSource {
        let body = match self {
            Self::Central => "return cut_gradient(gradient_central(tex));",
            Self::Sobel => "return cut_gradient(gradient_sobel(tex));",
            Self::PrecomputedCentral => {
                "let g = textureSampleLevel(gradient, linear_clamp, tex, 0.0).xyz;\n    \
                 return cut_gradient(g * central_edge_factor(tex, vec3<f32>(textureDimensions(gradient))));"
            }
            Self::PrecomputedSobel => {
                "return cut_gradient(textureSampleLevel(gradient, linear_clamp, tex, 0.0).xyz);"
            }
            Self::Quantized => {
                "let dims = vec3<i32>(textureDimensions(gradient));\n    \
                 let v = clamp(vec3<i32>(floor(tex * vec3<f32>(dims))), vec3<i32>(0), dims - vec3<i32>(1));\n    \
                 return cut_gradient(gradient_decode(textureLoad(gradient, v, 0)));"
            }
            Self::PrecomputedNormal => {
                "return cut_gradient(normal_code_gradient(textureSampleLevel(gradient, linear_clamp, tex, 0.0)));"
            }
            Self::PrecomputedNormalUnnormalized => {
                "let c = textureSampleLevel(gradient, linear_clamp, tex, 0.0);\n    \
                 shading_normal_scale = select(min(length(c.xyz * 2.0 - vec3<f32>(1.0)), 1.0), 1.0, clip_cut_gradient.w > 0.5);\n    \
                 return cut_gradient(normal_code_gradient(c));"
            }
        };
        // every estimator sets the normal's scale, so that a stack of two shading
        // plugins never reads the other's (module docs)
        let scale = match self {
            Self::PrecomputedNormalUnnormalized => "",
            _ => "shading_normal_scale = 1.0;\n    ",
        };
        ShaderSource {
            source: format!(
                "{}\n// appended by vwb_render::shading ({} gradient)\nfn gradient_at(tex: vec3<f32>) -> vec3<f32> {{\n    {scale}{body}\n}}\n",
                shader.source,
                self.name()
            )
            .into(),
            file: shader.file,
        }
    }

    /// The gradient pre-pass of the precomputed estimators (target `gradient`:
    /// rgba32float g and the voxel's value; for `quantized` the rgba8unorm code of
    /// [`gradient_code`], for `precomputed_normal*` that of [`normal_code`]). The value
    /// in w lets the main module read a sample's value and its gradient with one fetch
    /// ([`PrepassDecl::holds_value`]).
    pub fn prepass(self) -> Option<PrepassDecl> {
        let with_value = "vec4<f32>(g, volume_voxel(vec3<i32>(voxel)))";
        let (format, estimator, store) = match self {
            Self::Quantized => (
                StorageFormat::Rgba8Unorm,
                "gradient_central",
                "gradient_encode(g)",
            ),
            Self::PrecomputedSobel => (StorageFormat::Rgba32Float, "gradient_sobel", with_value),
            Self::PrecomputedNormal | Self::PrecomputedNormalUnnormalized => (
                StorageFormat::Rgba8Unorm,
                "gradient_central",
                "normal_encode(g)",
            ),
            _ => (StorageFormat::Rgba32Float, "gradient_central", with_value),
        };
        self.is_precomputed().then(|| PrepassDecl {
            target: "gradient",
            format,
            scale: 1.0,
            shader: ShaderSource {
                file: "shaders/gradient_prepass.wgsl".into(),
                source: include_str!("../../shaders/gradient_prepass.wgsl")
                    .replace("gradient_ESTIMATOR", estimator)
                    .replace("STORED", store)
                    .into(),
            },
            depends_on: vec![],
            holds_value: store == with_value,
        })
    }
}

/// The largest pre-pass volume `auto` precomputes: 2 GiB (512³ voxels).
pub const AUTO_PRECOMPUTE_MAX_BYTES: u64 = 2 << 30;

/// What the `gradient` parameter's `auto` resolves to: `precomputed_central` where it
/// pays, else `central` (the same gradients up to rounding). It pays on CPU adapters
/// (lavapipe: 0.78–0.84× `central`'s shaded frame from 512² up, 0.68× with early
/// termination, 0.91–1.00× at 256²; docs/perf.md, "Cheap shading"), where its
/// rgba32float volume (16 bytes per voxel) takes at most a quarter of the renderer's GPU
/// memory budget and [`AUTO_PRECOMPUTE_MAX_BYTES`]. On GPU adapters `central` stays
/// until a GPU measurement says otherwise. Not where a plugin replaces the shading
/// scalar (`scalar`, e.g. flow.lic3d): the pre-pass grid is the volume's, not that
/// scalar's. The rule does not depend on what the renderer holds at the moment, so
/// that the choice is stable from frame to frame.
pub fn auto_estimator(
    cpu_adapter: bool,
    dims: [u32; 3],
    budget: Option<u64>,
    scalar_replaced: bool,
) -> GradientEstimator {
    let bytes = gradient_volume_bytes(dims);
    let fits = bytes <= AUTO_PRECOMPUTE_MAX_BYTES && budget.is_none_or(|b| bytes <= b / 4);
    if cpu_adapter && fits && !scalar_replaced {
        GradientEstimator::PrecomputedCentral
    } else {
        GradientEstimator::Central
    }
}

/// `params` with `gradient: auto` replaced by `estimator` (other values unchanged).
pub fn resolve_auto(params: &ParamValues, estimator: GradientEstimator) -> ParamValues {
    let mut p = params.clone();
    if GradientEstimator::is_auto(params) {
        p.set(
            "gradient",
            crate::params::ParamValue::Enum(estimator.name().to_string()),
        );
    }
    p
}

/// Bytes of the gradient pre-pass volume for `dims` (rgba32float).
pub fn gradient_volume_bytes(dims: [u32; 3]) -> u64 {
    dims.iter().map(|&d| d.max(1) as u64).product::<u64>() * 16
}

/// `oct_encode`: the octahedral map of a unit vector onto [−1, 1]² (the upper
/// hemisphere onto the inner diamond, the lower one folded onto the corners); (0, 0)
/// for the zero vector.
pub fn oct_encode(n: DVec3) -> DVec2 {
    let s = n.x.abs() + n.y.abs() + n.z.abs();
    if !(s > 0.0 && s.is_finite()) {
        return DVec2::ZERO;
    }
    let p = DVec2::new(n.x, n.y) / s;
    if n.z < 0.0 {
        let sign = DVec2::new(
            if p.x >= 0.0 { 1.0 } else { -1.0 },
            if p.y >= 0.0 { 1.0 } else { -1.0 },
        );
        (DVec2::ONE - DVec2::new(p.y.abs(), p.x.abs())) * sign
    } else {
        p
    }
}

/// `oct_decode`: the unit vector of an octahedral point of [−1, 1]².
pub fn oct_decode(e: DVec2) -> DVec3 {
    let z = 1.0 - e.x.abs() - e.y.abs();
    let xy = if z < 0.0 {
        let sign = DVec2::new(
            if e.x >= 0.0 { 1.0 } else { -1.0 },
            if e.y >= 0.0 { 1.0 } else { -1.0 },
        );
        (DVec2::ONE - DVec2::new(e.y.abs(), e.x.abs())) * sign
    } else {
        e
    };
    safe_normalize(DVec3::new(xy.x, xy.y, z))
}

/// `gradient_encode`: the 8-bit codes (direction u, direction v, magnitude) of a
/// gradient, as the rgba8unorm pre-pass target stores them (module docs).
pub fn gradient_code(g: DVec3) -> [u8; 3] {
    let m = g.length();
    let (e, m) = if m > 0.0 && m.is_finite() {
        (oct_encode(g / m), m.min(1.0))
    } else {
        (DVec2::ZERO, 0.0)
    };
    let q = |x: f64| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(e.x * 0.5 + 0.5), q(e.y * 0.5 + 0.5), q(m.sqrt())]
}

/// `gradient_decode`: the gradient of a code of [`gradient_code`].
pub fn gradient_decode(code: [u8; 3]) -> DVec3 {
    let f = code.map(|c| c as f64 / 255.0);
    oct_decode(DVec2::new(f[0], f[1]) * 2.0 - 1.0) * (f[2] * f[2])
}

/// `normal_encode`: the 8-bit codes of a gradient in the thesis's normal texture
/// (Rezk-Salama 2001, eq 7.5): rgb = 0.5·ĝ + 0.5 and a = √|g| (|g| clamped to 1), each
/// rounded to k/255 (module docs). A zero or non-finite gradient gives the bias point
/// (128, 128, 128) and magnitude 0.
pub fn normal_code(g: DVec3) -> [u8; 4] {
    let m = g.length();
    let (d, m) = if m > 0.0 && m.is_finite() {
        (g / m, m.min(1.0))
    } else {
        (DVec3::ZERO, 0.0)
    };
    let q = |x: f64| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    [
        q(d.x * 0.5 + 0.5),
        q(d.y * 0.5 + 0.5),
        q(d.z * 0.5 + 0.5),
        q(m.sqrt()),
    ]
}

/// `normal_code_gradient`: the gradient of an interpolated code of [`normal_code`]
/// (channels in [0, 1]): the decoded direction 2·rgb − 1 renormalised, times the
/// magnitude a²; zero where the direction decodes to zero.
pub fn normal_code_gradient(c: DVec4) -> DVec3 {
    let d = c.truncate() * 2.0 - DVec3::ONE;
    let l = d.length();
    if l > 0.0 {
        d * (c.w * c.w / l)
    } else {
        DVec3::ZERO
    }
}

/// The `precomputed_normal*` estimators' pre-pass volume: `central`'s gradient at every
/// voxel centre (in f32, as the GPU computes it) as the codes of [`normal_code`], in
/// [0, 1] as the texture unit reads them. x fastest.
pub fn normal_texture_volume(ctx: &CpuContext) -> Vec<[f32; 4]> {
    voxel_gradients(ctx, false)
        .into_iter()
        .map(|g| normal_code(g.as_vec3().as_dvec3()).map(|c| c as f32 / 255.0))
        .collect()
}

/// The normal texture's interpolated code at `tex` (trilinear in f64; the texture unit
/// filters the 8-bit codes at its own precision: module docs).
fn normal_texel(ctx: &CpuContext, v: &[[f32; 4]], tex: DVec3) -> DVec4 {
    ctx.trilinear(tex, |i| DVec4::from(v[i].map(f64::from)))
}

/// World size of a texel of the shading scalar's grid (`(box_max − box_min) / n` in
/// the estimators; `voxel_size_world()` for the volume's grid).
fn texel_world(ctx: &CpuContext, grid: [u32; 3]) -> DVec3 {
    let (lo, hi) = ctx.volume_box();
    (hi - lo) / DVec3::from(grid.map(|n| n.max(1) as f64))
}

/// `central_edge_factor` (shaders/common.wgsl): per component, 1 inside the volume's
/// texel centres, falling to ½ at a face, so that the trilinear interpolation of the
/// voxels' central differences (`precomputed_central`) equals the central difference of
/// the interpolated reads (`central`), whose read beyond a face clamps to the edge
/// texel.
pub fn central_edge_factor(tex: DVec3, dims: [u32; 3]) -> DVec3 {
    let n = DVec3::from(dims.map(|d| d.max(1) as f64));
    let beyond = (tex * n - 0.5 * n).abs() - 0.5 * (n - DVec3::ONE);
    DVec3::ONE - beyond.clamp(DVec3::ZERO, DVec3::ONE)
}

/// `gradient_central`: central differences one texel of the shading scalar's grid apart
/// at `tex` ([`CpuContext::shading_value`]), times Δs0.
pub fn gradient_central(ctx: &CpuContext, tex: DVec3) -> DVec3 {
    let grid = ctx.shading_grid();
    let d = DVec3::from(grid.map(|n| 1.0 / n.max(1) as f64));
    let axis = |e: DVec3| ctx.shading_value(tex + e) - ctx.shading_value(tex - e);
    let g = DVec3::new(
        axis(DVec3::new(d.x, 0.0, 0.0)),
        axis(DVec3::new(0.0, d.y, 0.0)),
        axis(DVec3::new(0.0, 0.0, d.z)),
    );
    g * 0.5 * ctx.reference_step() / texel_world(ctx, grid)
}

/// `gradient_sobel`: the 3×3×3 Sobel operator at `tex` (26 reads of the shading
/// scalar), times Δs0.
pub fn gradient_sobel(ctx: &CpuContext, tex: DVec3) -> DVec3 {
    let grid = ctx.shading_grid();
    let d = DVec3::from(grid.map(|n| 1.0 / n.max(1) as f64));
    let mut g = DVec3::ZERO;
    for z in -1..=1 {
        for y in -1..=1 {
            for x in -1..=1 {
                if x == 0 && y == 0 && z == 0 {
                    continue;
                }
                let o = DVec3::new(x as f64, y as f64, z as f64);
                let f = ctx.shading_value(tex + o * d);
                let w = DVec3::splat(2.0) - o.abs();
                g += o * DVec3::new(w.y * w.z, w.x * w.z, w.x * w.y) * f;
            }
        }
    }
    g / 32.0 * ctx.reference_step() / texel_world(ctx, grid)
}

/// The estimator's gradient at every voxel centre (x fastest), as the pre-pass
/// evaluates it.
fn voxel_gradients(ctx: &CpuContext, sobel: bool) -> Vec<DVec3> {
    use rayon::prelude::*;
    let d = ctx.volume.dims.map(|n| n.max(1) as usize);
    (0..d[0] * d[1] * d[2])
        .into_par_iter()
        .map(|i| {
            let v = [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])];
            // the GPU computes the voxel-centre coordinate in f32
            let tex = DVec3::from(std::array::from_fn::<f64, 3, _>(|a| {
                ((v[a] as f32 + 0.5) / d[a] as f32) as f64
            }));
            if sobel {
                gradient_sobel(ctx, tex)
            } else {
                gradient_central(ctx, tex)
            }
        })
        .collect()
}

/// The per-voxel gradient volume of the pre-pass: (g, value) at every voxel centre,
/// in f32 as the rgba32float target stores it. x fastest.
pub fn gradient_volume(ctx: &CpuContext, sobel: bool) -> Vec<[f32; 4]> {
    voxel_gradients(ctx, sobel)
        .into_iter()
        .zip(ctx.scalars.iter())
        .map(|(g, &value)| {
            let g32 = g.as_vec3();
            [g32.x, g32.y, g32.z, value]
        })
        .collect()
}

/// The `quantized` estimator's pre-pass volume, decoded: `central`'s gradient at every
/// voxel centre after [`gradient_code`] and [`gradient_decode`] (the GPU encodes the
/// f32 gradient). x fastest.
pub fn quantized_gradient_volume(ctx: &CpuContext) -> Vec<[f32; 4]> {
    voxel_gradients(ctx, false)
        .into_iter()
        .map(|g| {
            let d = gradient_decode(gradient_code(g.as_vec3().as_dvec3())).as_vec3();
            [d.x, d.y, d.z, d.length()]
        })
        .collect()
}

thread_local! {
    static CUT_GRADIENT: std::cell::Cell<Option<DVec3>> = const { std::cell::Cell::new(None) };
}

/// Twin of `clip_cut_gradient` (shaders/common.wgsl): the gradient a clip twin sets for
/// the sample being evaluated on this thread (shading at the cut); the reference
/// renderer resets it to `None` before each sample's clip hooks.
pub fn set_cut_gradient(g: Option<DVec3>) {
    CUT_GRADIENT.with(|c| c.set(g));
}

/// The cut gradient of the current sample, if a clip twin set one.
pub fn cut_gradient() -> Option<DVec3> {
    CUT_GRADIENT.with(|c| c.get())
}

/// CPU twin of a shading plugin's `gradient_at`: the estimator plus, for the
/// precomputed ones, the pre-pass volume (built in [`Gradients::prepare`]).
#[derive(Debug, Clone, Default)]
pub struct Gradients {
    pub estimator: GradientEstimator,
    volume: Option<Vec<[f32; 4]>>,
}

impl Gradients {
    pub fn new(estimator: GradientEstimator) -> Self {
        Self {
            estimator,
            volume: None,
        }
    }
    /// Builds the pre-pass volume once (precomputed estimators).
    pub fn prepare(&mut self, ctx: &CpuContext) {
        if self.estimator.is_precomputed() && self.volume.is_none() {
            self.volume = Some(if self.estimator == GradientEstimator::Quantized {
                quantized_gradient_volume(ctx)
            } else if self.estimator.is_normal_texture() {
                normal_texture_volume(ctx)
            } else {
                gradient_volume(ctx, self.estimator.is_sobel())
            });
        }
    }
    /// `shading_normal(gradient_at(tex), floor, view, two_sided)` as the GPU evaluates it:
    /// (g, n, w), with n scaled by `shading_normal_scale` (the interpolated normal's
    /// length for `precomputed_normal_unnormalized` where no clip cut sets the gradient,
    /// else 1).
    pub fn normal(
        &self,
        ctx: &CpuContext,
        tex: DVec3,
        floor: f64,
        view: DVec3,
        two_sided: bool,
    ) -> (DVec3, DVec3, f64) {
        let g = self.at(ctx, tex);
        let (n, w) = shading_normal(g, floor, view, two_sided);
        let scale = match (self.estimator, &self.volume) {
            (GradientEstimator::PrecomputedNormalUnnormalized, Some(v))
                if cut_gradient().is_none() =>
            {
                let c = normal_texel(ctx, v, tex);
                (c.truncate() * 2.0 - DVec3::ONE).length().min(1.0)
            }
            _ => 1.0,
        };
        (g, n * scale, w)
    }
    /// `gradient_at(tex)`: the clip cut's gradient where a clip twin set one for the
    /// current sample ([`set_cut_gradient`]), else the estimator's.
    pub fn at(&self, ctx: &CpuContext, tex: DVec3) -> DVec3 {
        if let Some(g) = cut_gradient() {
            return g;
        }
        match (self.estimator, &self.volume) {
            (GradientEstimator::Central, _) => gradient_central(ctx, tex),
            (GradientEstimator::Sobel, _) => gradient_sobel(ctx, tex),
            (GradientEstimator::Quantized, Some(v)) => {
                let d = ctx.volume.dims.map(|n| n.max(1));
                let i = std::array::from_fn::<usize, 3, _>(|a| {
                    // floor(tex·dims) in f32, clamped to the grid, as the hook computes it
                    let t = [tex.x, tex.y, tex.z][a] as f32 * d[a] as f32;
                    (t.floor().max(0.0) as usize).min(d[a] as usize - 1)
                });
                let c = v[i[0] + d[0] as usize * (i[1] + d[1] as usize * i[2])];
                DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)
            }
            (e, Some(v)) if e.is_normal_texture() => {
                normal_code_gradient(normal_texel(ctx, v, tex))
            }
            (e, Some(v)) => {
                let g = ctx
                    .trilinear(tex, |i| DVec4::from(v[i].map(f64::from)))
                    .truncate();
                if e == GradientEstimator::PrecomputedCentral {
                    g * central_edge_factor(tex, ctx.volume.dims)
                } else {
                    g
                }
            }
            (e, None) => {
                if e.is_sobel() {
                    gradient_sobel(ctx, tex)
                } else {
                    gradient_central(ctx, tex)
                }
            }
        }
    }
}

/// `safe_normalize`: the unit vector, or zero for a zero (or non-finite) vector.
pub fn safe_normalize(v: DVec3) -> DVec3 {
    let l = v.length();
    if l > 0.0 && l.is_finite() {
        v / l
    } else {
        DVec3::ZERO
    }
}

/// `shading_normal`: (n, w) — the outward unit normal −g/|g| (towards `view` when
/// `two_sided`) and the lit weight w = clamp(|g|/floor, 0, 1) of the fade rule. Zero
/// (and w = 0) for a zero or non-finite gradient.
pub fn shading_normal(g: DVec3, floor: f64, view: DVec3, two_sided: bool) -> (DVec3, f64) {
    let m = g.length();
    if !(m > 0.0 && m.is_finite()) {
        return (DVec3::ZERO, 0.0);
    }
    let mut n = -g / m;
    if two_sided && n.dot(view) < 0.0 {
        n = -n;
    }
    let w = f64::from((m / floor.max(1.0e-12)) as f32).clamp(0.0, 1.0);
    (n, w)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LightKind {
    #[default]
    Directional,
    Point,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LightSpace {
    #[default]
    View,
    World,
}

/// A light of a shading plugin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Light {
    pub kind: LightKind,
    pub space: LightSpace,
    /// Directional: the direction towards the light; point: its position.
    pub vector: DVec3,
    pub color: DVec3,
}

impl Light {
    /// `light_dir`: unit direction from `pos` towards the light.
    pub fn dir(&self, ctx: &CpuContext, pos: DVec3) -> DVec3 {
        let v = &ctx.view;
        let mut w = self.vector;
        if self.space == LightSpace::View {
            w = v.right * w.x + v.up * w.y - v.forward * w.z;
        }
        if self.kind == LightKind::Point {
            if self.space == LightSpace::View {
                w += v.eye;
            }
            return safe_normalize(w - pos);
        }
        safe_normalize(w)
    }
}

/// Material constants of the Blinn–Phong model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    pub ka: f64,
    pub kd: f64,
    pub ks: f64,
    pub shininess: f64,
}

/// `blinn_phong_factors`: (diffuse, specular) for unit normal `n`, view `v`, light `l`.
pub fn blinn_phong_factors(n: DVec3, v: DVec3, l: DVec3, shininess: f64) -> (f64, f64) {
    let diff = n.dot(l).max(0.0);
    let h = safe_normalize(l + v);
    let ndh = n.dot(h);
    let spec = if diff > 0.0 && ndh > 0.0 {
        ndh.powf(shininess)
    } else {
        0.0
    };
    (diff, spec)
}

/// The lit colour of `base` (modulated or additive, module docs).
pub fn blinn_phong(
    base: DVec3,
    n: DVec3,
    v: DVec3,
    lights: &[(DVec3, DVec3)],
    m: &Material,
    additive: bool,
) -> DVec3 {
    blinn_phong_with(base, n, v, lights, m, additive, None)
}

/// [`blinn_phong`] with the (k_d-weighted diffuse, k_s-weighted specular) sums of
/// further lights already evaluated, e.g. read from a lighting table.
/// The Blinn–Phong (diffuse, specular) sums of the lights (unit direction, colour) at unit
/// normal `n` seen along unit `v`, weighted by k_d and k_s: what a lighting table holds.
pub fn light_terms(n: DVec3, v: DVec3, lights: &[(DVec3, DVec3)], m: &Material) -> (DVec3, DVec3) {
    let (mut diffuse, mut specular) = (DVec3::ZERO, DVec3::ZERO);
    for (l, color) in lights {
        let (d, s) = blinn_phong_factors(n, v, *l, m.shininess);
        diffuse += *color * (m.kd * d);
        specular += *color * (m.ks * s);
    }
    (diffuse, specular)
}

pub fn blinn_phong_with(
    base: DVec3,
    n: DVec3,
    v: DVec3,
    lights: &[(DVec3, DVec3)],
    m: &Material,
    additive: bool,
    tabulated: Option<(DVec3, DVec3)>,
) -> DVec3 {
    let (mut diffuse, mut specular) = tabulated.unwrap_or((DVec3::ZERO, DVec3::ZERO));
    let (d, s) = light_terms(n, v, lights, m);
    diffuse += d;
    specular += s;
    if additive {
        base * m.ka + diffuse + specular
    } else {
        base * (DVec3::splat(m.ka) + diffuse) + specular
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plugin::CpuView;
    use crate::volume::{Volume, VoxelData};

    fn ramp(dims: [u32; 3], spacing: [f64; 3], f: impl Fn(f64, f64, f64) -> f64) -> Volume {
        let mut data = Vec::new();
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    data.push(f(x as f64, y as f64, z as f64) as f32);
                }
            }
        }
        Volume::new("ramp", dims, 1, spacing, VoxelData::F32(data)).unwrap()
    }

    /// A linear field gives its exact gradient with every estimator, also with
    /// anisotropic voxels, away from the clamped border.
    #[test]
    fn linear_field_gives_its_gradient_with_every_estimator() {
        // f = 2x + 3y − z (raw); range over 16³ is [−15, 75]
        let vol = ramp([16, 16, 16], [1.0, 2.0, 0.5], |x, y, z| {
            2.0 * x + 3.0 * y - z
        });
        let scalars = vol.normalized_scalars();
        let ctx = CpuContext::new(&vol, &scalars);
        let (lo, hi) = (vol.range[0], vol.range[1]);
        // per world unit: raw per voxel / spacing; normalised: / (hi − lo); times Δs0 = 0.5·s
        let b = crate::slicing::VolumeBox::new(vol.dims, vol.spacing);
        let world_per_voxel = (b.max - b.min).as_dvec3() / 16.0;
        let expect = DVec3::new(2.0, 3.0, -1.0) / world_per_voxel / (hi - lo) * b.voxel as f64;
        let tex = DVec3::new(7.3, 8.1, 6.6) / 16.0;
        for e in GradientEstimator::ALL {
            let mut g = Gradients::new(e);
            g.prepare(&ctx);
            let got = g.at(&ctx, tex);
            // f32 scalars and pre-pass volume; 8-bit codes (1°)
            let tol = match e {
                // 8-bit codes: quantized's direction within 1°, the normal texture's
                // components within 1/255, both magnitudes as √|g| in 1/255 steps
                GradientEstimator::Quantized => 2e-2,
                e if e.is_normal_texture() => 2e-2,
                e if e.is_precomputed() => 1e-5,
                _ => 1e-6,
            };
            assert!(
                (got - expect).length() <= tol * expect.length(),
                "{}: {got} vs {expect}",
                e.name()
            );
        }
    }

    /// The thesis's normal encoding (Rezk-Salama 2001, eq 7.5; its testable claim 1):
    /// rgb = 0.5·n + 0.5 round-trips within 1/255 per component at 8 bits, so the decoded
    /// normal has length 1 within √3/255; the magnitude round-trips within its √ step; a
    /// zero, NaN or infinite gradient stores magnitude 0 (the fade leaves it unlit).
    #[test]
    fn normal_codes_round_trip_within_one_step() {
        let mut worst = 0.0f64;
        for i in 0..2000 {
            // a spiral over the sphere, and magnitudes from 10⁻⁴ to 1
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / 2000.0;
            let phi = i as f64 * 2.399_963;
            let r = (1.0 - z * z).sqrt();
            let n = DVec3::new(r * phi.cos(), r * phi.sin(), z);
            let m = 10f64.powf(-4.0 + 4.0 * (i % 97) as f64 / 96.0);
            let c = normal_code(n * m);
            let rgb = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) / 255.0;
            let d = rgb * 2.0 - DVec3::ONE;
            let err = (d - n).abs().max_element();
            worst = worst.max(err);
            assert!(err <= 1.0 / 255.0 + 1e-12, "{n}: {d}");
            assert!((d.length() - 1.0).abs() <= 3f64.sqrt() / 255.0, "{d}");
            // √m in 1/255 steps
            let a = c[3] as f64 / 255.0;
            assert!((a - m.sqrt()).abs() <= 0.5 / 255.0 + 1e-12, "{m}: {a}");
            // the decoded gradient points along n, with the decoded magnitude
            let g = normal_code_gradient(rgb.extend(a));
            assert!((g.length() - a * a).abs() <= 1e-12);
            if a > 0.0 {
                assert!(
                    g.normalize().dot(n) > (2.0f64).to_radians().cos(),
                    "{n}: {g}"
                );
            }
        }
        assert!(worst > 0.5 / 255.0, "the 8-bit steps show: {worst}");
        for bad in [
            DVec3::ZERO,
            DVec3::splat(f64::NAN),
            DVec3::new(f64::INFINITY, 0.0, 0.0),
        ] {
            assert_eq!(normal_code(bad), [128, 128, 128, 0], "{bad}");
        }
        // the bias point decodes to (1/255, 1/255, 1/255), not zero; magnitude 0 keeps
        // the gradient zero
        let c = normal_code(DVec3::ZERO).map(|c| c as f64 / 255.0);
        assert_eq!(normal_code_gradient(DVec4::from(c)), DVec3::ZERO);
        // magnitudes above 1 clamp
        assert_eq!(normal_code(DVec3::new(0.0, 7.0, 0.0))[3], 255);
    }

    /// Between voxels whose normals differ the interpolated normal is shorter than 1:
    /// `precomputed_normal` renormalises it, `precomputed_normal_unnormalized` shades with
    /// it as it is (§7.5). A ridge along x: the normals of its two flanks are opposite,
    /// and the voxel on its crest has no gradient (the bias point, magnitude 0).
    #[test]
    fn unnormalized_normals_are_shorter_between_differing_voxels() {
        let vol = ramp([5, 4, 4], [1.0; 3], |x, _, _| {
            [0.0, 0.5, 1.0, 0.5, 0.0][x as usize]
        });
        let scalars = vol.normalized_scalars();
        let ctx = CpuContext::new(&vol, &scalars);
        let v = DVec3::new(0.3, 0.2, 1.0).normalize();
        let at = |e: GradientEstimator, x: f64| {
            let mut g = Gradients::new(e);
            g.prepare(&ctx);
            g.normal(&ctx, DVec3::new(x / 5.0, 0.5, 0.5), 0.02, v, false)
        };
        for e in GradientEstimator::ALL {
            // at a voxel centre of a flank every estimator gives a unit normal along ∓x
            let (_, n, w) = at(e, 1.5);
            assert!((n.length() - 1.0).abs() < 1e-2, "{}: {n}", e.name());
            assert!(n.x < -0.99 && w == 1.0, "{}: {n} {w}", e.name());
        }
        // halfway between the flank and the crest: the crest stores the bias point, so
        // the interpolated normal is half as long; its gradient (and fade) the same
        let (g_unit, n_unit, _) = at(GradientEstimator::PrecomputedNormal, 2.0);
        let (g_short, n_short, _) = at(GradientEstimator::PrecomputedNormalUnnormalized, 2.0);
        assert!((n_unit.length() - 1.0).abs() < 1e-9, "{n_unit}");
        assert!((n_short.length() - 0.5).abs() < 0.01, "{n_short}");
        assert!((n_short.normalize() - n_unit).length() < 1e-9);
        assert_eq!(g_unit, g_short);
        // two neighbouring voxels with opposite normals (a ridge two voxels wide),
        // halfway: the unnormalised normal cancels to (nearly) nothing, the renormalised
        // one is a unit vector across both (the codes' bias, 1/255 in y and z), at the
        // full fade weight: interpolated directions know no magnitude (`central`'s
        // interpolated differences are zero there and fade to unlit)
        let vol = ramp([6, 4, 4], [1.0; 3], |x, _, _| {
            [0.0, 0.0, 1.0, 1.0, 0.0, 0.0][x as usize]
        });
        let scalars = vol.normalized_scalars();
        let ctx = CpuContext::new(&vol, &scalars);
        let tex = DVec3::new(3.0 / 6.0, 0.5, 0.5);
        let normal = |e: GradientEstimator| {
            let mut g = Gradients::new(e);
            g.prepare(&ctx);
            g.normal(&ctx, tex, 0.02, v, false)
        };
        let (_, n_cancel, _) = normal(GradientEstimator::PrecomputedNormalUnnormalized);
        assert!(n_cancel.length() < 0.01, "{n_cancel}");
        let (_, n_across, w) = normal(GradientEstimator::PrecomputedNormal);
        assert!((n_across.length() - 1.0).abs() < 1e-9 && n_across.x.abs() < 1e-9);
        assert_eq!(w, 1.0);
        let (g, _, w) = normal(GradientEstimator::PrecomputedCentral);
        assert!(g.length() < 1e-6 && w < 1e-4, "{g} {w}");
    }

    /// The twins of `precomputed_central` and `central` agree everywhere in the box,
    /// also within half a voxel of its faces and corners (where `central`'s reads
    /// clamp), up to the stored values' f32 rounding; without the faces' factor they
    /// do not.
    #[test]
    fn precomputed_central_matches_central_up_to_the_faces() {
        let vol = ramp([8, 6, 5], [1.0, 1.5, 2.0], |x, y, z| {
            x * x + 3.0 * y - (z * 1.3).sin() * 4.0
        });
        let scalars = vol.normalized_scalars();
        let ctx = CpuContext::new(&vol, &scalars);
        let central = Gradients::new(GradientEstimator::Central);
        let mut pre = Gradients::new(GradientEstimator::PrecomputedCentral);
        pre.prepare(&ctx);
        let mut worst_without = 0.0f64;
        for (i, t) in [0.0, 0.01, 0.05, 0.09, 0.3, 0.5, 0.77, 0.93, 0.97, 1.0]
            .iter()
            .enumerate()
        {
            for u in [0.0, 0.04, 0.5, 0.96, 1.0] {
                let tex = DVec3::new(*t, u, [0.02, 0.5, 0.99][i % 3]);
                let (a, b) = (central.at(&ctx, tex), pre.at(&ctx, tex));
                assert!(
                    (a - b).length() <= 1e-5 * a.length().max(1e-3),
                    "at {tex}: central {a}, precomputed {b}"
                );
                let raw = b / central_edge_factor(tex, vol.dims);
                worst_without = worst_without.max((a - raw).length() / a.length().max(1e-3));
            }
        }
        assert!(worst_without > 0.1, "the factor matters: {worst_without}");
    }

    /// On white noise the Sobel operator's averaging over the 3×3 neighbourhood gives
    /// gradients with about 0.38× the standard deviation of central differences
    /// (√(72/1024) vs √(1/2) per axis).
    #[test]
    fn sobel_smooths_noise_that_central_differences_keep() {
        let hash = |x: f64, y: f64, z: f64| {
            let h = ((x * 73.0 + y * 179.0 + z * 283.0) as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            (h >> 40) as f64 / (1u64 << 24) as f64
        };
        let vol = ramp([12, 12, 12], [1.0; 3], hash);
        let scalars = vol.normalized_scalars();
        let ctx = CpuContext::new(&vol, &scalars);
        let (mut c, mut s) = (0.0, 0.0);
        for z in 2..10 {
            for y in 2..10 {
                for x in 2..10 {
                    let tex = (DVec3::new(x as f64, y as f64, z as f64) + 0.5) / 12.0;
                    c += gradient_central(&ctx, tex).length_squared();
                    s += gradient_sobel(&ctx, tex).length_squared();
                }
            }
        }
        let ratio = (s / c).sqrt();
        assert!(ratio > 0.25 && ratio < 0.5, "sobel/central {ratio}");
    }

    #[test]
    fn zero_and_tiny_gradients_fade_to_unlit_without_nan() {
        let v = DVec3::Z;
        assert_eq!(
            shading_normal(DVec3::ZERO, 0.02, v, true),
            (DVec3::ZERO, 0.0)
        );
        assert_eq!(shading_normal(DVec3::splat(f64::NAN), 0.02, v, true).1, 0.0);
        let (n, w) = shading_normal(DVec3::new(0.0, 0.0, 1e-30), 0.02, v, true);
        assert!(n.is_finite() && (0.0..1e-20).contains(&w));
        let (_, w_half) = shading_normal(DVec3::new(0.0, 0.01, 0.0), 0.02, v, true);
        assert!((w_half - 0.5).abs() < 1e-6);
        let (_, w_one) = shading_normal(DVec3::new(0.0, 1.0, 0.0), 0.02, v, true);
        assert_eq!(w_one, 1.0);
        // two-sided flips towards the viewer; one-sided keeps −g
        let (n1, _) = shading_normal(DVec3::new(0.0, 0.0, 1.0), 0.02, v, false);
        let (n2, _) = shading_normal(DVec3::new(0.0, 0.0, 1.0), 0.02, v, true);
        assert_eq!(n1, -DVec3::Z);
        assert_eq!(n2, DVec3::Z);
    }

    #[test]
    fn blinn_phong_terms() {
        let n = DVec3::Z;
        let v = DVec3::Z;
        let l = DVec3::new(0.0, (60f64).to_radians().sin(), (60f64).to_radians().cos());
        let (d, s) = blinn_phong_factors(n, v, l, 1.0);
        assert!((d - 0.5).abs() < 1e-12);
        // h is at 30°
        assert!((s - (30f64).to_radians().cos()).abs() < 1e-12);
        // light behind: no diffuse, no specular
        assert_eq!(blinn_phong_factors(n, v, -l, 8.0), (0.0, 0.0));
        let m = Material {
            ka: 0.1,
            kd: 0.8,
            ks: 0.0,
            shininess: 8.0,
        };
        let base = DVec3::new(1.0, 0.5, 0.25);
        let lit = blinn_phong(base, n, v, &[(l, DVec3::ONE)], &m, false);
        assert!((lit - base * 0.5).length() < 1e-12);
        let add = blinn_phong(base, n, v, &[(l, DVec3::ONE)], &m, true);
        assert!((add - (base * 0.1 + DVec3::splat(0.4))).length() < 1e-12);
    }

    #[test]
    fn view_space_lights_follow_the_camera() {
        let vol = ramp([2, 2, 2], [1.0; 3], |x, _, _| x);
        let scalars = vol.normalized_scalars();
        let mut ctx = CpuContext::new(&vol, &scalars);
        ctx.view = CpuView {
            eye: DVec3::new(0.0, 0.0, 3.0),
            right: DVec3::X,
            up: DVec3::Y,
            forward: -DVec3::Z,
            ..CpuView::default()
        };
        let head = Light {
            kind: LightKind::Directional,
            space: LightSpace::View,
            vector: DVec3::Z,
            color: DVec3::ONE,
        };
        assert!((head.dir(&ctx, DVec3::ZERO) - DVec3::Z).length() < 1e-12);
        ctx.view.forward = DVec3::X;
        ctx.view.right = DVec3::Z;
        assert!((head.dir(&ctx, DVec3::ZERO) + DVec3::X).length() < 1e-12);
        let point = Light {
            kind: LightKind::Point,
            space: LightSpace::World,
            vector: DVec3::new(0.0, 2.0, 0.0),
            color: DVec3::ONE,
        };
        assert!((point.dir(&ctx, DVec3::new(0.0, 1.0, 0.0)) - DVec3::Y).length() < 1e-12);
    }

    /// Directions over the whole sphere (a Fibonacci spiral) plus the axes, the
    /// octahedron's faces and the equator, where the map folds.
    fn sphere_directions(n: usize) -> Vec<DVec3> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let mut d: Vec<DVec3> = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let phi = golden * i as f64;
                DVec3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect();
        for a in [DVec3::X, DVec3::Y, DVec3::Z] {
            d.extend([a, -a]);
        }
        for s in [
            [1.0, 1.0, 1.0],
            [-1.0, 1.0, -1.0],
            [1.0, -1.0, 0.0],
            [-1.0, 0.0, -1e-9],
        ] {
            d.push(DVec3::from(s).normalize());
        }
        d
    }

    #[test]
    fn octahedral_map_is_its_own_inverse_over_the_sphere() {
        for n in sphere_directions(4000) {
            let e = oct_encode(n);
            assert!(e.x.abs() <= 1.0 && e.y.abs() <= 1.0, "{n} -> {e}");
            let back = oct_decode(e);
            assert!((back - n).length() < 1e-12, "{n} -> {e} -> {back}");
        }
        assert_eq!(oct_encode(DVec3::ZERO), DVec2::ZERO);
        assert_eq!(oct_encode(DVec3::splat(f64::NAN)), DVec2::ZERO);
    }

    /// The quantised codes keep the direction within 1° and the magnitude within half
    /// a step of √|g| (|g| within √|g|/255 + 1/255²); zero, NaN and
    /// huge gradients give finite codes.
    #[test]
    fn quantized_codes_keep_direction_and_magnitude() {
        let mut worst = 0.0f64;
        for (i, n) in sphere_directions(20000).into_iter().enumerate() {
            let m = 0.02 + 0.9 * (i % 97) as f64 / 96.0;
            let g = gradient_decode(gradient_code(n * m));
            worst = worst.max(g.normalize().dot(n).clamp(-1.0, 1.0).acos().to_degrees());
            let step = 2.0 * m.sqrt() / 255.0;
            assert!(
                (g.length() - m).abs() <= 0.5 * step + 4e-6,
                "{m} vs {}",
                g.length()
            );
        }
        assert!(worst < 1.0, "worst direction error {worst}°");
        assert!(worst > 0.1, "the codes do quantise: {worst}°");
        assert_eq!(gradient_decode(gradient_code(DVec3::ZERO)).length(), 0.0);
        assert_eq!(
            gradient_decode(gradient_code(DVec3::splat(f64::NAN))).length(),
            0.0
        );
        let huge = gradient_decode(gradient_code(DVec3::new(0.0, 5.0, 0.0)));
        assert!(
            (huge - DVec3::Y).length() < 1e-2,
            "{huge}: clamped to |g| = 1"
        );
    }

    /// The twin of the quantized estimator reads the nearest voxel's code: constant
    /// within a voxel, and the code of `central` at that voxel's centre.
    #[test]
    fn quantized_estimator_reads_the_nearest_voxel() {
        let vol = ramp([8, 8, 8], [1.0; 3], |x, y, z| x * x + 2.0 * y - z);
        let scalars = vol.normalized_scalars();
        let ctx = CpuContext::new(&vol, &scalars);
        let mut g = Gradients::new(GradientEstimator::Quantized);
        g.prepare(&ctx);
        let centre = (DVec3::new(3.0, 4.0, 2.0) + 0.5) / 8.0;
        let expect = gradient_decode(gradient_code(
            gradient_central(&ctx, centre).as_vec3().as_dvec3(),
        ));
        for off in [
            DVec3::ZERO,
            DVec3::splat(0.45 / 8.0),
            DVec3::splat(-0.45 / 8.0),
        ] {
            let got = g.at(&ctx, centre + off);
            assert!((got - expect).length() < 1e-6, "{got} vs {expect}");
        }
        // the next voxel along x holds another gradient (f = x² grows faster)
        let next = g.at(&ctx, centre + DVec3::new(1.0 / 8.0, 0.0, 0.0));
        assert!((next - expect).length() > 1e-3);
    }
}
