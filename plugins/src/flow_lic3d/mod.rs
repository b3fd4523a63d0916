//! `flow.lic3d`: 3D line integral convolution of a vector volume (Rezk-Salama 2001
//! §9.3, eqs 9.9–9.10) over a seeded noise volume on the LIC grid (`frequency` × the
//! data's resolution), in one of two modes (`mode`, structural):
//! - `precomputed`: a pre-pass integrates the streamline through every voxel of the LIC
//!   grid and writes the intensity to `lic` (r32float); the pre-pass reruns only when
//!   the volume or an integration or noise parameter changes;
//! - `on_the_fly`: the `sample` hook integrates at the sample itself, so only the
//!   samples the slice loop reaches pay (inside the clip region, before early
//!   termination, outside skipped space; Falk and Weiskopf 2008), with no LIC volume in
//!   memory and no pre-pass.
//!
//! Either way the `sample` hook replaces the sample's value by the intensity (optionally
//! modulated by the field's normalised magnitude), for the classification after it.
//!
//! The field is the volume's 2 or 3 components in voxels per unit time (each divided by
//! the voxel size along its axis, `vwb_render::flow::GridField::from_volume`), uploaded
//! as the plugin's own rgba32float texture (rgba16float, and the noise r16float, with
//! `storage: f16`, the twins then rounding both alike); a scalar volume has no flow (a zero field:
//! the LIC is the noise). Streamlines use unit speed; the choices and their measured
//! trade are in docs/flow.md. The CPU twin computes the same LIC volume with
//! `vwb_render::flow::lic_volume` in f64 over the same noise, or, on the fly, the same
//! integral at the sample (`vwb_render::flow::lic_at`).

use std::sync::Arc;

use glam::DVec3;
use vwb_render::flow::{
    Field, GridField, Integrator, Kernel, LicParams, NoFlow, Noise, OnGrid, Scaled, Speed, lic_at,
    lic_volume, noise_volume,
};
use vwb_render::params::{Components, ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, PassOutputs, Plugin, PluginError,
    LoopIterations, PrepassDecl, Probe, ResourceDecl, ResourceKind, ScalarField, ShaderSource,
    Statistic, StorageFormat,
};
use vwb_render::volume::Volume;

pub mod probes;
#[cfg(test)]
mod tests;

const KERNELS: [&str; 4] = ["box", "tent", "gaussian", "periodic"];
/// The region of lic.wgsl holding each kernel's weight (box: the default 1, none).
const KERNEL_REGIONS: [&str; 4] = ["", "kernel_tent", "kernel_gaussian", "kernel_periodic"];
const NOISES: [&str; 3] = ["white", "gaussian", "sparse"];
const FREQUENCIES: [&str; 2] = ["1", "2"];
const MODES: [&str; 2] = ["precomputed", "on_the_fly"];
const STORAGES: [&str; 2] = ["f32", "f16"];

const SHADER_FILE: &str = "plugins/src/flow_lic3d/lic.wgsl";
const SHADER: &str = include_str!("lic.wgsl");

/// The plugin, configured by its LIC grid's `frequency` (the pre-pass target's scale)
/// and its `mode`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lic3d {
    pub frequency: u32,
    /// `mode: on_the_fly`: the sample hook integrates; no pre-pass, no LIC volume.
    pub on_the_fly: bool,
    /// `storage: f16`: the field and the noise in half floats.
    pub half: bool,
    /// The streamline integrator, compiled in (`integrator` is structural).
    pub integrator: Integrator,
    /// The kernel, an index into `KERNELS`, compiled in (`kernel` is structural).
    pub kernel: usize,
}

impl Default for Lic3d {
    fn default() -> Self {
        Self {
            frequency: 1,
            on_the_fly: false,
            half: false,
            integrator: Integrator::Rk4,
            kernel: 1,
        }
    }
}

fn error(message: String) -> PluginError {
    PluginError::Invalid {
        plugin: "flow.lic3d".into(),
        message,
    }
}

/// The LIC parameters the values select.
pub fn lic_params(p: &ParamValues) -> LicParams {
    LicParams {
        kernel: match p.enumeration("kernel") {
            "box" => Kernel::Box,
            "gaussian" => Kernel::Gaussian,
            "periodic" => Kernel::Periodic {
                ripples: p.float("ripples") as f64,
                phase: (p.float("phase_deg") as f64).to_radians(),
            },
            _ => Kernel::Tent,
        },
        length: p.float("length") as f64,
        step: p.float("step") as f64,
        integrator: Integrator::from_key(p.enumeration("integrator")),
        speed: Speed::Normalized,
    }
}

/// The noise the values select.
pub fn noise_kind(p: &ParamValues) -> Noise {
    match p.enumeration("noise") {
        "gaussian" => Noise::Gaussian,
        "sparse" => Noise::Sparse {
            density: p.float("density") as f64,
        },
        _ => Noise::White,
    }
}

/// The LIC grid of a volume at `frequency`.
pub fn lic_dims(volume: &Volume, frequency: u32) -> [u32; 3] {
    volume.dims.map(|d| d * frequency)
}

/// The field as the pre-pass samples it: the vectors of the volume `field` (the
/// document's own or a named input on a grid of its own) in voxels of the document's
/// grid `grid`, or none for a scalar volume.
fn field_on(grid: &Volume, field: &Volume) -> Option<GridField> {
    GridField::from_volume(field)
        .ok()
        .map(|f| f.in_voxels_of(grid.dims))
}

/// A field as the flow plugins' shaders sample it: an rgba texture of its vectors (w =
/// 0, and v = 0 too for a 2-component field), half floats when `half`; a 1-voxel zero
/// field for none.
pub fn field_texture(gpu: &GpuInit, label: &str, field: Option<&GridField>, half: bool) -> GpuResource {
    let Some(f) = field else {
        let r = gpu.create_volume_texture(&format!("{label} (none)"), [1, 1, 1], 4);
        gpu.write_floats(&r, &[0.0; 4]);
        return r;
    };
    let c = f.components as usize;
    let texels: Vec<f32> = f
        .data
        .chunks_exact(c)
        .flat_map(|v| [v[0], v[1], if c > 2 { v[2] } else { 0.0 }, 0.0])
        .collect();
    let r = gpu.create_volume_texture_as(label, f.dims, 4, half);
    gpu.write_floats(&r, &texels);
    r
}

/// The seeded noise volume on a LIC grid of `dims` (the values the GPU uploads and the
/// twins convolve).
fn noise_of(dims: [u32; 3], params: &ParamValues) -> GridField {
    noise_volume(dims, noise_kind(params), params.int("seed") as u64)
}

/// Rounds a grid's values to half floats, as a texture with `storage: f16` stores them.
fn round_to_half(g: &mut GridField) {
    for v in &mut g.data {
        *v = half::f16::from_f32(*v).to_f32();
    }
}

/// The flow the LIC follows, as the GPU holds it: the field (none for a scalar volume;
/// on its own grid, its vectors in voxels of the document's grid), rounded to half
/// floats under `storage: f16`, and the map onto the LIC grid.
pub struct LicFlow {
    pub field: Option<GridField>,
    /// The document volume's grid, which the LIC grid refines by `frequency`.
    pub grid: [u32; 3],
    pub frequency: f64,
}

impl LicFlow {
    /// The flow for the document's volume `grid` and the vector volume `field` (the
    /// same or a named input).
    pub fn new(grid: &Volume, field: &Volume, frequency: u32, params: &ParamValues) -> Self {
        let mut field = field_on(grid, field);
        if half_storage(params) {
            field.iter_mut().for_each(round_to_half);
        }
        Self {
            field,
            grid: grid.dims,
            frequency: frequency as f64,
        }
    }

    /// Runs `f` with the field in LIC-grid voxel coordinates.
    fn with_field<R>(&self, f: impl FnOnce(&dyn Field) -> R) -> R {
        match &self.field {
            Some(inner) => f(&Scaled {
                inner: &OnGrid {
                    inner,
                    to: self.grid,
                },
                factor: self.frequency,
            }),
            None => f(&NoFlow),
        }
    }
}

/// What the LIC integrates, on the LIC grid: the flow, the noise and the integration
/// parameters. Both twins use it: the precomputed one integrates at every voxel
/// ([`LicInputs::volume`]), the on-the-fly one at each sample ([`LicInputs::at`]).
pub struct LicInputs {
    pub flow: LicFlow,
    pub noise: GridField,
    pub params: LicParams,
}

impl LicInputs {
    /// The inputs as the GPU holds them (see [`LicFlow::new`]); with `storage: f16`, the
    /// noise rounded to half floats as well.
    pub fn new(grid: &Volume, field: &Volume, frequency: u32, params: &ParamValues) -> Self {
        let mut noise = noise_of(lic_dims(grid, frequency), params);
        if half_storage(params) {
            round_to_half(&mut noise);
        }
        Self {
            flow: LicFlow::new(grid, field, frequency, params),
            noise,
            params: lic_params(params),
        }
    }

    fn with_field<R>(&self, f: impl FnOnce(&dyn Field) -> R) -> R {
        self.flow.with_field(f)
    }

    /// I at a point of the LIC grid (voxel coordinates), as the on-the-fly hook computes it.
    pub fn at(&self, p: DVec3) -> f64 {
        self.with_field(|field| lic_at(field, &self.noise, p, &self.params))
    }

    /// I at every voxel of the LIC grid (the twin of the pre-pass), x fastest.
    pub fn volume(&self) -> GridField {
        GridField {
            dims: self.noise.dims,
            components: 1,
            data: self.with_field(|field| lic_volume(field, &self.noise, &self.params)),
        }
    }
}

/// Mean |I(p) − I(p + t)| and |I(p) − I(p + s)| over every other voxel of a LIC volume
/// (`data` on `dims`, x fastest; the border left out), with t one voxel along the flow
/// and s one across it (t × z, or t × x where the flow is vertical): streaks along the
/// flow make the first far smaller than the second. `field` is in the LIC grid's voxel
/// coordinates; voxels without flow are skipped. NaN where no voxel counts.
pub fn along_and_across(data: &[f32], dims: [u32; 3], field: &dyn Field) -> (f64, f64) {
    let at = |p: DVec3| {
        let q = p.round();
        ((0..3).all(|a| q[a] >= 0.0 && q[a] < dims[a] as f64)).then(|| {
            let i = q.x as usize + dims[0] as usize * (q.y as usize + dims[1] as usize * q.z as usize);
            data.get(i).map_or(0.0, |v| *v as f64)
        })
    };
    let (mut along, mut across, mut n) = (0.0, 0.0, 0usize);
    for z in 1..dims[2].saturating_sub(1) {
        for y in (1..dims[1].saturating_sub(1)).step_by(2) {
            for x in (1..dims[0].saturating_sub(1)).step_by(2) {
                let p = DVec3::new(x as f64, y as f64, z as f64);
                let Some(v) = field.at(p).filter(|v| v.length() > 1e-9) else {
                    continue;
                };
                let t = v.normalize();
                let side = if t.z.abs() < 0.9 {
                    t.cross(DVec3::Z)
                } else {
                    t.cross(DVec3::X)
                }
                .normalize();
                let (Some(i0), Some(a), Some(b)) = (at(p), at(p + t), at(p + side)) else {
                    continue;
                };
                along += (i0 - a).abs();
                across += (i0 - b).abs();
                n += 1;
            }
        }
    }
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    (along / n as f64, across / n as f64)
}

/// The largest LIC grid (voxels) whose `twin_rms` statistic is computed: 128³.
pub const TWIN_STATISTIC_VOXELS: u64 = 128 * 128 * 128;

/// Whether the values select half-float storage for the field and the noise.
pub fn half_storage(p: &ParamValues) -> bool {
    p.enumeration("storage") == "f16"
}

/// The LIC volume on the LIC grid (the twin of the pre-pass), x fastest.
pub fn lic_of(volume: &Volume, frequency: u32, params: &ParamValues) -> GridField {
    lic_on(volume, volume, frequency, params)
}

/// The LIC volume of the vector volume `field` on the grid of the document's volume
/// `grid` (a named input on a grid of its own).
pub fn lic_on(grid: &Volume, field: &Volume, frequency: u32, params: &ParamValues) -> GridField {
    LicInputs::new(grid, field, frequency, params).volume()
}

impl Lic3d {
    /// lic.wgsl without `regions`, without the stages its integrator does not use (the
    /// `rk2` region holds RK2's and RK4's second stage, `rk4` RK4's last two) and
    /// without the other kernels' weights (`kernel_tent`, …; box is none of them).
    fn source(&self, regions: &[(&str, &str)]) -> ShaderSource {
        let mut regions = regions.to_vec();
        regions.extend(self.integrator.region_left_out().map(|r| (r, "")));
        regions.extend(
            KERNEL_REGIONS
                .iter()
                .enumerate()
                .filter(|(k, r)| *k != self.kernel && !r.is_empty())
                .map(|(_, r)| (*r, "")),
        );
        ShaderSource::without_regions(SHADER_FILE, SHADER, &regions)
    }
}

impl Plugin for Lic3d {
    /// Its pre-pass follows streamlines through the whole vector volume.
    fn splits_into_bricks(&self) -> bool {
        false
    }
    /// On the fly, one integral per sample and per read of its scalar (`lic_integral`:
    /// two directions of ⌊L/h⌋ steps, each loop with its end; the outer loop of two as
    /// well, should the compiler not unroll it); precomputed, none (the pre-pass
    /// integrates).
    fn loop_iterations(&self, params: &ParamValues) -> LoopIterations {
        if !self.on_the_fly {
            return LoopIterations::default();
        }
        let (length, step) = (params.float("length"), params.float("step"));
        let steps = if step > 0.0 && (length / step).is_finite() {
            (length / step).floor().clamp(0.0, 1.0e6) as u32
        } else {
            0
        };
        let integral = 2 * (steps + 1) + 3;
        LoopIterations {
            sample: integral,
            scalar: integral,
        }
    }
    fn id(&self) -> &'static str {
        "flow.lic3d"
    }
    fn display_name(&self) -> &'static str {
        "3D LIC"
    }
    fn description(&self) -> &'static str {
        "Line integral convolution of the vector volume over seeded noise, for the classification after it"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::volume("field", "Vector field", Components::Any).with_doc(
                "the document's own volume, or one of its named volumes (on a grid of its own, over the same box); a scalar volume has no flow",
            ),
            ParamSpec::enumeration("mode", "Mode", &MODES, 0)
                .structural()
                .with_doc(
                    "precomputed: a pre-pass writes the LIC volume; on_the_fly: each sample integrates (no volume, output-sensitive)",
                ),
            ParamSpec::enumeration("frequency", "Noise frequency", &FREQUENCIES, 0)
                .structural()
                .with_doc("LIC grid (and noise) resolution per data voxel and axis"),
            ParamSpec::enumeration("noise", "Noise", &NOISES, 0)
                .with_doc("white: uniform; gaussian: N(½, ⅙); sparse: spots at the density"),
            ParamSpec::float("density", "Spot density", 0.005, 0.05, 0.02)
                .with_doc("share of lit voxels of sparse noise"),
            ParamSpec::int("seed", "Seed", 0, 1_000_000, 1),
            ParamSpec::enumeration("kernel", "Kernel", &KERNELS, 1)
                .structural()
                .with_doc(
                    "box, tent 1 − |s|/L, Gaussian with σ = L/3, or periodic (Hann window × a ripple moved by the phase: animation)",
                ),
            ParamSpec::float("ripples", "Ripples per half length", 0.5, 8.0, 2.0)
                .shown_when("kernel", "periodic"),
            ParamSpec::float("phase_deg", "Phase (°)", 0.0, 360.0, 0.0)
                .cycle()
                .shown_when("kernel", "periodic")
                .with_doc("advancing it moves the ripple downstream; on the fly nothing is recomputed"),
            ParamSpec::float("length", "Half length L (voxels)", 1.0, 32.0, 8.0)
                .with_doc("streamline length each way, in voxels of the LIC grid"),
            ParamSpec::float_log("step", "Step h (voxels)", 0.1, 2.0, 0.5),
            ParamSpec::enumeration("integrator", "Integrator", &Integrator::KEYS, 2)
                .structural()
                .with_doc("RK4 at half a voxel drifts < 10⁻⁶ voxels per turn (docs/flow.md); only the chosen one is compiled in"),
            ParamSpec::float("modulate", "Modulate by |v|", 0.0, 1.0, 0.0)
                .with_doc("0: LIC intensity; 1: LIC × normalised field magnitude"),
            ParamSpec::enumeration("storage", "Field and noise storage", &STORAGES, 0)
                .structural()
                .with_doc("f16 halves their memory and the texture traffic of the integration; its error is in docs/flow.md"),
        ]
    }
    fn shader(&self) -> ShaderSource {
        if self.on_the_fly {
            self.source(&[("prepass", ""), ("precomputed", "")])
        } else {
            self.source(&[("integral", ""), ("prepass", ""), ("on_the_fly", "")])
        }
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![
            ResourceDecl {
                name: "field",
                kind: ResourceKind::Texture3d,
            },
            ResourceDecl {
                name: "noise",
                kind: ResourceKind::Texture3d,
            },
        ]
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        if self.on_the_fly {
            return None;
        }
        Some(PrepassDecl {
            target: "lic",
            format: StorageFormat::R32Float,
            scale: self.frequency as f32,
            shader: self.source(&[("precomputed", ""), ("on_the_fly", ""), ("hooks", "")]),
            depends_on: vec![
                "noise",
                "density",
                "seed",
                "kernel",
                "ripples",
                "phase_deg",
                "length",
                "step",
                "integrator",
            ],
            holds_value: false,
        })
    }
    /// The twin's streamline drift on the rotation and its LIC's time against error
    /// ([`probes`]).
    fn probes(&self) -> Vec<Arc<dyn Probe>> {
        vec![
            Arc::new(probes::Drift),
            Arc::new(probes::TwinLic::default()),
        ]
    }
    /// Precomputed: `along_across`, the mean |ΔI| between neighbours of the GPU's LIC
    /// volume along the flow over that across it ([`along_and_across`]: well under 1
    /// where the LIC shows streaks along the flow), and `twin_rms`, the RMS difference (in 1/255) of the GPU's LIC volume
    /// against the f64 twin's with the same noise and unrounded inputs (`storage: f32`;
    /// a half-float run's error includes its rounding). The twin takes seconds per 128³,
    /// so grids above [`TWIN_STATISTIC_VOXELS`] report NaN.
    fn statistic_names(&self, params: &ParamValues) -> Vec<&'static str> {
        if params.enumeration("mode") == "on_the_fly" {
            Vec::new()
        } else {
            vec!["twin_rms", "along_across"]
        }
    }
    fn statistics(&self, params: &ParamValues, passes: &PassOutputs<'_>) -> Vec<Statistic> {
        if self.on_the_fly {
            return Vec::new();
        }
        let Some((dims, gpu)) = (passes.read)("prepass") else {
            return Vec::new();
        };
        let voxels: u64 = dims.iter().map(|&d| d as u64).product();
        let field = passes.inputs.resolve(passes.volume, params, "field");
        let along_across = match &field {
            Ok(field) => {
                // the flow only: the statistic reads the GPU's LIC, not the noise
                let flow = LicFlow::new(passes.volume, field, self.frequency, params);
                let (along, across) = flow.with_field(|f| along_and_across(&gpu, dims, f));
                along / across
            }
            Err(_) => f64::NAN,
        };
        let value = match field {
            Ok(field) if voxels <= TWIN_STATISTIC_VOXELS => {
                let mut full = params.clone();
                full.set("storage", vwb_render::params::ParamValue::Enum("f32".into()));
                let twin = lic_on(passes.volume, field, self.frequency, &full);
                if twin.dims == dims && twin.data.len() == gpu.len() {
                    probes::rms_255(&gpu, &twin.data)
                } else {
                    f64::NAN
                }
            }
            _ => f64::NAN,
        };
        vec![
            Statistic {
                name: "twin_rms",
                value,
            },
            Statistic {
                name: "along_across",
                value: along_across,
            },
        ]
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let c = Lic3d {
            frequency: params.enumeration("frequency").parse().unwrap_or(1),
            on_the_fly: params.enumeration("mode") == "on_the_fly",
            half: half_storage(params),
            integrator: Integrator::from_key(params.enumeration("integrator")),
            kernel: KERNELS
                .iter()
                .position(|k| *k == params.enumeration("kernel"))
                .unwrap_or(1),
        };
        (c != *self).then(|| Arc::new(c) as Arc<dyn Plugin>)
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let dims = lic_dims(gpu.volume, self.frequency);
        if dims
            .iter()
            .any(|&d| d > gpu.device.limits().max_texture_dimension_3d)
        {
            return Err(error(format!(
                "the LIC grid {dims:?} exceeds the device's 3D texture limit; lower the frequency"
            )));
        }
        let field = field_on(gpu.volume, gpu.input(params, "field")?);
        let field = field_texture(gpu, "flow.lic3d field", field.as_ref(), self.half);
        let res = vec![
            field,
            gpu.create_volume_texture_as("flow.lic3d noise", dims, 1, self.half),
        ];
        self.update_resources(gpu, params, &res)?;
        Ok(res)
    }
    /// The noise volume, seeded (the same values the twin convolves).
    fn update_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
        resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        let Some(noise) = resources.get(1) else {
            return Err(error("noise texture missing".into()));
        };
        let n = noise_of(lic_dims(gpu.volume, self.frequency), params);
        gpu.write_floats(noise, &n.data);
        Ok(())
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(Lic3dTwin {
            frequency: self.frequency,
            on_the_fly: self.on_the_fly,
            params: params.clone(),
            modulate: params.float("modulate") as f64,
            lic: None,
            fly: None,
        }))
    }
}

/// CPU twin: precomputed, the LIC volume computed once (`prepare`), sampled trilinearly
/// as the GPU samples `lic`; on the fly, the integral at each sample.
pub struct Lic3dTwin {
    pub frequency: u32,
    pub on_the_fly: bool,
    pub params: ParamValues,
    pub modulate: f64,
    pub lic: Option<Arc<GridField>>,
    pub fly: Option<Arc<LicInputs>>,
}

impl CpuTwin for Lic3dTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        if self.on_the_fly {
            if self.fly.is_none() {
                self.fly = Some(Arc::new(LicInputs::new(
                    ctx.volume,
                    ctx.input(&self.params, "field"),
                    self.frequency,
                    &self.params,
                )));
            }
        } else if self.lic.is_none() {
            let field = ctx.input(&self.params, "field");
            self.lic = Some(Arc::new(lic_on(ctx.volume, field, self.frequency, &self.params)));
        }
    }
    fn sample(&self, _ctx: &CpuContext, s: &mut CpuSample) {
        if let Some(i) = self.intensity(s.tex) {
            s.value = self.modulated(i, s.value);
        }
    }
    fn scalar(&self) -> Option<&dyn ScalarField> {
        Some(self)
    }
}

impl Lic3dTwin {
    /// I at a texture coordinate: the LIC volume sampled trilinearly, or integrated
    /// there on the fly (None before `prepare`).
    fn intensity(&self, tex: DVec3) -> Option<f64> {
        // texture coordinates to LIC-grid voxel coordinates, clamped into the box
        let grid = |dims: [u32; 3]| {
            let d = DVec3::from(dims.map(f64::from));
            (tex * d - DVec3::splat(0.5)).clamp(DVec3::splat(-0.5), d - DVec3::splat(0.5))
        };
        if let Some(fly) = &self.fly {
            Some(fly.at(grid(fly.noise.dims)))
        } else {
            self.lic
                .as_ref()
                .map(|lic| lic.at(grid(lic.dims)).map_or(0.0, |v| v.x))
        }
    }

    /// The sample's value: I, modulated by the normalised magnitude `m`.
    fn modulated(&self, i: f64, m: f64) -> f64 {
        i + (i * m - i) * self.modulate
    }
}

/// The twin of `scalar` and `scalar_grid`: the value `sample` gives at a texture
/// coordinate, on the LIC grid (shading from LIC gradients).
impl ScalarField for Lic3dTwin {
    fn value(&self, ctx: &CpuContext, tex: DVec3) -> f64 {
        let m = ctx.value(tex);
        self.intensity(tex).map_or(m, |i| self.modulated(i, m))
    }
    fn grid(&self, ctx: &CpuContext) -> [u32; 3] {
        lic_dims(ctx.volume, self.frequency)
    }
}
