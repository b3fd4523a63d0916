//! `shade.dos`: directional occlusion shading (Schott et al. 2009) in the slice loop.
//!
//! Per slice (front to back): the eye pass shades the slice with the occlusion buffer
//! of the previous slice, `rgb = σs·(L_a·V + ambient)` with σs the TF colour and V the
//! buffer (fractional visibility, eq 10; Algorithm 1), and composites it; then the
//! occlusion pass writes the next buffer (the per-slice state, ping-pong): at every
//! texel the average of the previous buffer over the base of the backward cone,
//! each tap attenuated by `e^(−σt·distance)` (Algorithms 2 and 3).
//!
//! - Cone: phase function Φθ = 1/(2π(1 − cos θ)) inside the aperture θ ∈ [0°, 90°),
//!   pointing back at the viewer; the base radius per slice distance d is
//!   `d·tan θ` (eq 11), mapped to the screen at the slice's depth (eqs 12–15: uv per
//!   world unit = ½·P₀₀/depth for perspective, ½·P₀₀ for orthographic).
//! - Kernels: a regular n × n grid (n = 2…13) over the disk's bounding square, the
//!   points inside the disk; or a Poisson-disk set ([`poisson_disk`], seeded, up to
//!   64 points).
//! - `distance`: `slice` (Algorithm 3, the paper's choice: d) or `exact` (Algorithm 2:
//!   √(d² + |p|²)).
//! - `kernel` and `distance` are structural: the shader keeps only the chosen loop and
//!   distance (regions `grid`, `poisson`, `exact_distance` of dos.wgsl), because
//!   lavapipe runs the code of a uniform branch not taken under a mask (the Poisson
//!   loop once, the exact distance at every tap): `ct_dos` 0.83× on lavapipe, the
//!   images bit for bit (docs/perf.md, "Idle tiles of the per-slice path"). `grid` is
//!   structural too: its points are written out as constants ([`grid_taps_wgsl`]),
//!   no loop: 0.79–0.88× the DOS frame on lavapipe, the images within rounding
//!   (docs/perf.md, "The grid kernel's taps written out").
//! - σt at the cone's tip: −ln(1 − α)/Δs0 from the classified opacity per Δs0 of the
//!   current slice's sample, as the paper reads σt at the fragment. Opacity
//!   α = 1 − e^(−σt·d) is the core's opacity correction of that α.
//! - The occlusion buffer's resolution (`buffer_scale` of the eye buffer) and
//!   precision (`buffer_format`: fp32 r32float, the default, or fp16 rgba16float) are
//!   structural. On lavapipe the fp16 buffer drifts from the twin's fp16 emulation
//!   (RMS ΔE 0.63 on the CT preset against 0.0002 in fp32), and it costs twice the
//!   memory, so fp32 is the default.
//! - Only what is rendered occludes: a clipped or skipped sample reaches the
//!   occlusion pass with α = 0, i.e. σt = 0.
//! - Chromatic extinction (`extinction: chromatic`; the global-light issue, item 9):
//!   Schott et al. map the TF to a chromatic σs and an achromatic σt (their §3), while
//!   the transport equation they start from (eqs 1–3) has a wavelength-dependent σ.
//!   Here σt along the light's paths becomes per channel σt,c = κ_c·σt, with κ the
//!   `extinction_rgb` colour (each in [0, 4]); the eye ray keeps the achromatic σt of
//!   the core's compositing, so the opacity and the silhouette do not change, only the
//!   colour of the shadows (κ_r < κ_b: red light reaches deeper, warm shadows). The
//!   occlusion buffer then holds V per channel (rgba32float, or rgba16float at fp16);
//!   κ = (1, 1, 1) gives the achromatic image. The single-scattering ground truth
//!   takes the same κ on its shadow rays (`ScatteringOptions::extinction`). Choice: κ
//!   is one colour for the whole volume, not per material (the TF carries one α).
//! - Light (`light`): `viewer`, the paper's (the cone points back at the viewer, the
//!   slices are view-aligned), or `directional`, the extension Schott et al. name as
//!   future work (§5): the renderer slices halfway between the view and the light
//!   (half-angle slicing, Kniss et al. 2003; `vwb_render::slicing::HalfAngle`), the
//!   occlusion buffer lies across the light in the light's space, and the cone opens
//!   towards the light (`light_vector`, towards the light, in view or world space).
//!   Per slice the cone's base grows by d·tan θ with d the light's path between two
//!   slices, mapped to the buffer by its texels' world size (orthographic: no
//!   perspective correction). *Choices:* the planes keep the slice spacing along the
//!   view's centre ray and along the light (so they lie Δs·cos ψ apart, ψ half the
//!   angle between the two, and a frame has up to √2 × the slices); the buffer keeps
//!   the eye buffer's texel count (`buffer_scale`) and covers the box's shadow, so
//!   its texels are as large as the box's extent across the light requires. A pixel
//!   whose ray meets the slices from behind (a light facing the viewer) composites
//!   back to front. Measured in docs/dos.md ("A directional light").
//! - θ = 0: every tap reads the texel itself, V becomes the transmittance towards the
//!   viewer (no lateral occlusion): the image equals `test.slice_shadow` at strength 1
//!   with L_a = 1 and no ambient.
//! - `clear_tiles` (structural, off by default): the renderer keeps marks of the
//!   buffer's tiles that left the clear value, and an empty sample whose cone reads only
//!   clear tiles returns V = 1 without its taps. The image is the same. Off by default
//!   because on lavapipe the marks' reads and stores cost more than the taps they skip
//!   once the per-slice dispatches leave the clear tiles out (0.51–0.81× the DOS frame
//!   without them; docs/perf.md, "Storage-buffer words one lane at a time").

pub mod mc;
#[cfg(feature = "ui")]
pub mod ui;

use std::sync::Arc;

use glam::{DVec2, DVec3, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    ConvergedReference, CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, ResourceDecl,
    ResourceKind, ShaderSource, SliceStateDecl, StorageFormat, Transparency, Volumes,
};

#[cfg(test)]
mod tests;

/// Largest Poisson-disk kernel.
pub const MAX_POISSON: usize = 64;

pub const SCALES: [&str; 3] = ["1", "0.5", "0.25"];
pub const FORMATS: [&str; 2] = ["fp16", "fp32"];
pub const EXTINCTIONS: [&str; 2] = ["achromatic", "chromatic"];
pub const LIGHTS: [&str; 2] = ["viewer", "directional"];

/// The direction a `light: directional` light travels in world space, seen from
/// `view` (`None` for the viewer's light).
pub fn light_direction(params: &ParamValues, view: &vwb_render::camera::View) -> Option<glam::Vec3> {
    if params.enumeration("light") != "directional" {
        return None;
    }
    let v = glam::Vec3::from(params.vec3("light_vector"));
    let towards = if params.enumeration("light_space") == "world" {
        v
    } else {
        view.right * v.x + view.up * v.y - view.forward * v.z
    };
    Some(-towards)
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dos {
    /// Occlusion-buffer resolution relative to the eye buffer.
    pub scale: f32,
    pub format: StorageFormat,
    /// Per-channel visibility in the occlusion buffer (chromatic extinction).
    pub chromatic: bool,
    /// `light: directional`: the buffer travels with a directional light (half-angle
    /// slicing).
    pub directional: bool,
    /// `kernel: poisson` (else the grid).
    pub poisson: bool,
    /// The grid kernel's n (0 under `kernel: poisson`): its taps are written out in the
    /// shader ([`grid_taps_wgsl`]).
    pub grid: u32,
    /// `distance: exact` (Algorithm 2; else the slice distance, Algorithm 3).
    pub exact_distance: bool,
    /// `clear_tiles`: the buffer's tiles still clear are tracked, and an empty sample
    /// under clear ones skips its taps (off by default: on lavapipe the check costs
    /// more than the taps it skips).
    pub clear_tiles: bool,
}

impl Default for Dos {
    fn default() -> Self {
        Self {
            scale: 1.0,
            format: StorageFormat::R32Float,
            chromatic: false,
            directional: false,
            poisson: false,
            grid: 4,
            exact_distance: false,
            clear_tiles: false,
        }
    }
}

/// The n × n grid kernel's points inside the unit disk, row by row: q = (index + ½)·
/// (2/n) − 1 in f32 (the cell's width times the index). The shader's taps
/// ([`grid_taps_wgsl`]) and the CPU twin ([`kernel_points`]) both take these.
pub fn grid_points(n: u32) -> Vec<glam::Vec2> {
    let cell = 2.0f32 / n as f32;
    (0..n)
        .flat_map(|j| (0..n).map(move |i| glam::Vec2::new(i as f32 + 0.5, j as f32 + 0.5) * cell - 1.0))
        .filter(|q| q.dot(*q) <= 1.0)
        .collect()
}

/// The grid kernel's taps for an n × n grid, written out as WGSL on one line (so that
/// the shader's lines keep their numbers): `sum = sum + TAP(q, …);` for each of
/// [`grid_points`], then `n = count`. Written out rather than looped over: the loop's
/// bounds, corner tests and counters cost llvmpipe 12–21 % of a DOS frame (docs/perf.md,
/// "The grid kernel's taps written out"). `tap` is `kernel_tap`, or `chromatic_tap`
/// for chromatic extinction.
pub fn grid_taps_wgsl(n: u32, tap: &str) -> String {
    use std::fmt::Write;
    let points = grid_points(n);
    let mut out = String::new();
    for q in &points {
        let _ = write!(
            out,
            "sum = sum + {tap}(vec2<f32>({:?}f, {:?}f), uv, scale, extent, d, sigma_t); ",
            q.x, q.y
        );
    }
    let _ = write!(out, "n = {}.0;", points.len());
    out
}

/// `count` points in the unit disk with a Poisson-disk spacing (dart throwing with a
/// fixed seed and a shrinking minimum distance), deterministic.
pub fn poisson_disk(count: usize) -> Vec<DVec2> {
    let mut rng = vwb_render::rng::XorShift(0x2545_F491_4F6C_DD1D);
    let mut next = || rng.uniform();
    let mut r_min = 1.6 / (count as f64).sqrt();
    let mut pts: Vec<DVec2> = Vec::with_capacity(count);
    let mut tries = 0;
    while pts.len() < count {
        let p = DVec2::new(next() * 2.0 - 1.0, next() * 2.0 - 1.0);
        if p.length_squared() > 1.0 {
            continue;
        }
        if pts.iter().all(|q| q.distance(p) >= r_min) {
            pts.push(p);
            tries = 0;
        } else {
            tries += 1;
            if tries > 2000 {
                r_min *= 0.9;
                tries = 0;
            }
        }
    }
    // stored as f32 on the GPU
    pts.iter().map(|p| p.as_vec2().as_dvec2()).collect()
}

/// The kernel's points in the unit disk for the parameters (grid or Poisson).
pub fn kernel_points(params: &ParamValues) -> Vec<DVec2> {
    if params.enumeration("kernel") == "poisson" {
        let n = (params.int("poisson_count").max(1) as usize).min(MAX_POISSON);
        return poisson_disk(MAX_POISSON)[..n].to_vec();
    }
    // the shader's f32 points
    grid_points(params.int("grid").max(1) as u32)
        .iter()
        .map(|q| q.as_dvec2())
        .collect()
}

impl Plugin for Dos {
    fn id(&self) -> &'static str {
        "shade.dos"
    }
    fn display_name(&self) -> &'static str {
        "Directional occlusion"
    }
    fn description(&self) -> &'static str {
        "Soft shadows from a backward cone, one front-to-back pass (Schott et al. 2009)"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::float("theta_deg", "Cone aperture θ (°)", 0.0, 89.9, 60.0)
                .with_doc("occlusion extent d·tan θ per slice distance d (eq 11)"),
            ParamSpec::enumeration("kernel", "Kernel", &["grid", "poisson"], 0).structural(),
            ParamSpec::int("grid", "Grid n × n", 2, 13, 4)
                .structural()
                .with_doc("the grid's points inside the disk are written out in the shader"),
            ParamSpec::int("poisson_count", "Poisson points", 4, MAX_POISSON as i32, 16),
            ParamSpec::enumeration("distance", "Attenuation distance", &["slice", "exact"], 0)
                .structural()
                .with_doc(
                    "slice: e^(−σt·d) (Algorithm 3); exact: e^(−σt·√(d²+|p|²)) (Algorithm 2)",
                ),
            ParamSpec::float("la", "Ambient radiance L_a", 0.0, 4.0, 1.0),
            ParamSpec::float("ambient", "Ambient term", 0.0, 1.0, 0.0)
                .with_doc("added to L_a·V so that fully occluded matter is not black"),
            ParamSpec::enumeration("light", "Light", &LIGHTS, 0)
                .structural()
                .with_doc(
                    "viewer: the paper's light at the eye (view-aligned slices); directional: soft shadows from a directional light, by half-angle slicing (Kniss et al. 2003)",
                ),
            ParamSpec::enumeration("light_space", "Light space", &["view", "world"], 0)
                .shown_when("light", "directional")
                .with_doc("view: x right, y up, z towards the viewer"),
            ParamSpec::vec3("light_vector", "Direction to the light", -1.0, 1.0, [0.5, 0.5, 1.0])
                .shown_when("light", "directional")
                .with_doc("towards the light, any length"),
            ParamSpec::enumeration("extinction", "Extinction", &EXTINCTIONS, 0)
                .structural()
                .with_doc(
                    "achromatic: one σt (the paper); chromatic: σt·κ per channel on the light's paths",
                ),
            ParamSpec::vec3("extinction_rgb", "Extinction colour κ", 0.0, 4.0, [1.0, 1.0, 1.0])
                .shown_when("extinction", "chromatic")
                .with_doc("σt per channel = κ·σt along the occlusion cone; (1, 1, 1) is achromatic"),
            ParamSpec::enumeration("buffer_scale", "Occlusion buffer scale", &SCALES, 0)
                .structural()
                .with_doc(
                    "the occlusion buffer's resolution per axis: 0.5 takes about half the frame, 0.25 a third or less, for softer shadows (docs/perf.md, \"A smaller occlusion buffer\")",
                ),
            ParamSpec::enumeration("buffer_format", "Occlusion buffer precision", &FORMATS, 1)
                .structural()
                .with_doc(
                    "fp32: r32float (4 bytes/texel, the default; rgba32float when chromatic); fp16: rgba16float (8 bytes)",
                ),
            ParamSpec::boolean("clear_tiles", "Skip taps under clear tiles", false)
                .structural()
                .with_doc(
                    "track the buffer's tiles still clear and skip an empty sample's taps under them; the same image; off: on lavapipe the check costs more than it skips (docs/perf.md, \"Storage-buffer words one lane at a time\")",
                ),
        ]
    }
    fn shader(&self) -> ShaderSource {
        const FILE: &str = "plugins/src/shade_dos/dos.wgsl";
        const SOURCE: &str = include_str!("dos.wgsl");
        // Structural parameters choose the code: uniform branches cost lavapipe both
        // paths (docs/perf.md, "Idle tiles of the per-slice path").
        let mut left_out = Vec::new();
        if !self.chromatic {
            left_out.push(("chromatic", ""));
        }
        let taps;
        if self.poisson {
            left_out.push(("grid", ""));
        } else {
            taps = [
                grid_taps_wgsl(self.grid, "kernel_tap"),
                grid_taps_wgsl(self.grid, "chromatic_tap"),
            ];
            left_out.push(("poisson", ""));
            left_out.push(("grid_taps", taps[0].as_str()));
            left_out.push(("chromatic_grid_taps", taps[1].as_str()));
        }
        if !self.exact_distance {
            left_out.push(("exact_distance", ""));
        }
        if !self.clear_tiles {
            left_out.push(("clear_tiles", ""));
        }
        ShaderSource::without_regions(FILE, SOURCE, &left_out)
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![ResourceDecl {
            name: "poisson",
            kind: ResourceKind::Texture2d,
        }]
    }
    fn slice_state(&self) -> Option<SliceStateDecl> {
        // chromatic: V per channel, so fp32 needs four of them
        let format = match self.format {
            StorageFormat::R32Float if self.chromatic => StorageFormat::Rgba32Float,
            f => f,
        };
        Some(SliceStateDecl {
            format,
            scale: self.scale,
            clear: if self.chromatic {
                [1.0; 4]
            } else {
                [1.0, 0.0, 0.0, 1.0]
            },
            light: self.directional,
            // empty samples under clear cones skip their taps (dos.wgsl), where asked
            track_clear: self.clear_tiles,
        })
    }
    fn slice_light(&self, params: &ParamValues, view: &vwb_render::camera::View) -> Option<glam::Vec3> {
        light_direction(params, view)
    }
    /// The cone's base radius per slice distance, d·tan θ (eq 11): an empty sample
    /// (σt = 0) under a cone of clear buffer (V = 1) averages taps of exactly 1.
    fn slice_state_reach(&self, params: &ParamValues) -> Option<f64> {
        Some((params.float("theta_deg") as f64).to_radians().tan())
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let scale = params
            .enumeration("buffer_scale")
            .parse::<f32>()
            .unwrap_or(1.0);
        let format = if params.enumeration("buffer_format") == "fp16" {
            StorageFormat::Rgba16Float
        } else {
            StorageFormat::R32Float
        };
        let chromatic = params.enumeration("extinction") == "chromatic";
        let c = Dos {
            scale,
            format,
            chromatic,
            directional: params.enumeration("light") == "directional",
            poisson: params.enumeration("kernel") == "poisson",
            grid: if params.enumeration("kernel") == "poisson" {
                0
            } else {
                params.int("grid").clamp(2, 13) as u32
            },
            exact_distance: params.enumeration("distance") == "exact",
            clear_tiles: params.boolean("clear_tiles"),
        };
        (c != *self).then(|| Arc::new(c) as Arc<dyn Plugin>)
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        _params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let t = gpu.create_table("shade.dos poisson kernel", MAX_POISSON as u32, 1);
        let texels: Vec<[f32; 4]> = poisson_disk(MAX_POISSON)
            .iter()
            .map(|p| [p.x as f32, p.y as f32, 0.0, 0.0])
            .collect();
        gpu.write_table(&t, &texels);
        Ok(vec![t])
    }
    /// `shade` scales colours and the occlusion pass reads only the sample's opacity.
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
    /// Refined slices converge to the slice algorithm's own limit, not to the cone
    /// integral: the converged reference is the Monte-Carlo integral (`mc.rs`).
    fn converged_reference(&self) -> Option<Arc<dyn ConvergedReference>> {
        Some(Arc::new(mc::MonteCarloReference::default()))
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(DosTwin {
            theta_deg: params.float("theta_deg") as f64,
            kernel: kernel_points(params),
            exact_distance: params.enumeration("distance") == "exact",
            la: params.float("la") as f64,
            ambient: params.float("ambient") as f64,
            extinction: extinction(params),
        }))
    }
}

/// κ of the chromatic extinction (σt per channel = κ·σt), `None` when achromatic.
pub fn extinction(params: &ParamValues) -> Option<DVec3> {
    (params.enumeration("extinction") == "chromatic")
        .then(|| glam::Vec3::from(params.vec3("extinction_rgb")).as_dvec3())
}

/// CPU twin of `dos.wgsl`.
pub struct DosTwin {
    pub theta_deg: f64,
    pub kernel: Vec<DVec2>,
    pub exact_distance: bool,
    pub la: f64,
    pub ambient: f64,
    /// κ of the chromatic extinction; `None`: achromatic (one channel).
    pub extinction: Option<DVec3>,
}

impl CpuTwin for DosTwin {
    fn shade(&self, ctx: &CpuContext, s: &mut CpuSample) {
        let state = ctx.state_prev(ctx.view.state_coord(s));
        let v = if self.extinction.is_some() {
            state.truncate()
        } else {
            DVec3::splat(state.x)
        };
        let k = v * self.la + self.ambient;
        s.color = (s.color.truncate() * k).extend(s.color.w);
    }

    fn slice_update(&self, ctx: &CpuContext, s: &CpuSample, _c: DVec4, uv: DVec2) -> DVec4 {
        let a = if s.color.w.is_nan() {
            0.0
        } else {
            s.color.w.clamp(0.0, 1.0)
        };
        let sigma_t = -(1.0 - a).max(1.0e-30).ln() / ctx.reference_step();
        let d = ctx.view.state_step();
        let extent = d * (self.theta_deg as f32).to_radians().tan() as f64;
        let scale = ctx.view.state_uv_per_world(s.slice);
        let mut sum = DVec3::ZERO;
        for q in &self.kernel {
            let p = *q * extent;
            let pt = uv + DVec2::new(p.x, -p.y) * scale;
            let dist = if self.exact_distance {
                (d * d + p.length_squared()).sqrt()
            } else {
                d
            };
            let prev = ctx.state_prev(pt);
            sum += match self.extinction {
                Some(k) => prev.truncate() * (-sigma_t * k * dist).exp(),
                None => DVec3::new(prev.x * (-sigma_t * dist).exp(), 0.0, 0.0),
            };
        }
        (sum / self.kernel.len().max(1) as f64).extend(1.0)
    }
}
