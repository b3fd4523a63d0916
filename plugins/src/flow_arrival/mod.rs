//! `flow.arrival`: the thesis's time surfaces (Rezk-Salama 2001 §9.3, Figs 9.10–9.11)
//! as one arrival-time volume. The thesis animates 3D LIC by switching between closed
//! "time surface" clip meshes advected from a start mesh; here a pre-pass stores, for
//! every voxel, the time at which matter released from a seed box (a flat box across
//! the flow, the start mesh) reaches it, and the `clip` hook keeps the samples reached
//! by `time`: the time surface at t is the arrival volume's level set t. Playing `time`
//! changes one uniform, so the animation runs at the frame rate of a static frame; the
//! pre-pass reruns only when the seed or an integration parameter changes.
//!
//! Choices where the thesis is silent (measured in docs/flow.md):
//! - each voxel's path is traced backwards in time until it enters the seed box, with
//!   steps of `dt = step / |v|` (a path length of about `step` voxels each), Euler,
//!   RK2 or RK4 on the vectors as they are, and the entry interpolated along the last
//!   step (`vwb_render::flow::arrival_at`, the f64 twin);
//! - the field is the volume's vectors in voxels per unit time, scaled to a top speed
//!   of 1, so times are in voxels travelled at the field's top speed, whatever the
//!   data's units;
//! - voxels whose path leaves the volume, stagnates (|v| < 10⁻⁶ of the top speed) or
//!   runs past `max_length` voxels first are never reached ([`NEVER`](vwb_render::flow::NEVER));
//! - `band` > 0 keeps only the samples that arrived within `band` of `time` (a moving
//!   front of that thickness) instead of everything reached so far.
//!
//! A scalar volume has no flow: only the seed is ever reached. Put the plugin before
//! `flow.lic3d` to mask the LIC (clipped samples never integrate on the fly).

use std::sync::Arc;

use glam::{DVec3, DVec4};
use vwb_render::flow::{
    ArrivalParams, Field, GridField, Integrator, NEVER, NoFlow, OnGrid, SeedBox, arrival_volume,
};
use vwb_render::params::{Components, ParamSpec, ParamValue, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, PrepassDecl,
    ResourceDecl, ResourceKind, ShaderSource, StorageFormat, Transparency, trilinear_grid, Volumes,
};
use vwb_render::volume::Volume;

pub mod probes;
#[cfg(test)]
mod tests;

const SHADER_FILE: &str = "plugins/src/flow_arrival/arrival.wgsl";
const SHADER: &str = include_str!("arrival.wgsl");

/// The plugin, configured by its integrator (structural: only its stages are compiled
/// into the pre-pass).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arrival {
    pub integrator: Integrator,
}

impl Default for Arrival {
    fn default() -> Self {
        Self {
            integrator: Integrator::Rk4,
        }
    }
}

fn error(message: String) -> PluginError {
    PluginError::Invalid {
        plugin: "flow.arrival".into(),
        message,
    }
}

/// The seed box the values select (texture coordinates).
pub fn seed_box(p: &ParamValues) -> SeedBox {
    let [a, b] = ["seed_min", "seed_max"].map(|k| DVec3::from(p.vec3(k).map(f64::from)));
    SeedBox {
        min: a.min(b),
        max: a.max(b),
    }
}

/// The integration parameters the values select.
pub fn arrival_params(p: &ParamValues) -> ArrivalParams {
    ArrivalParams {
        step: p.float("step") as f64,
        max_length: p.float("max_length") as f64,
        integrator: Integrator::from_key(p.enumeration("integrator")),
    }
}

/// The field the pre-pass integrates: the volume's vectors scaled to a top speed of 1
/// (none for a scalar volume or a field that vanishes everywhere).
pub fn unit_field(volume: &Volume) -> Option<GridField> {
    unit_field_on(volume, volume)
}

/// [`unit_field`] of the vector volume `field` (a named input on a grid of its own),
/// its vectors in voxels of the document's volume `grid`, on which the arrival times
/// are computed.
pub fn unit_field_on(grid: &Volume, field: &Volume) -> Option<GridField> {
    let mut f = GridField::from_volume(field).ok()?.in_voxels_of(grid.dims);
    f.to_unit_speed().then_some(f)
}

/// The arrival volume of the pre-pass (its f64 twin, stored as f32 with [`NEVER`](vwb_render::flow::NEVER)).
pub fn arrival_of(volume: &Volume, p: &ParamValues) -> Vec<f32> {
    arrival_on(volume, volume, p)
}

/// [`arrival_of`] for the vector volume `field` (a named input) over the document's
/// volume `grid`.
pub fn arrival_on(grid: &Volume, field: &Volume, p: &ParamValues) -> Vec<f32> {
    // no flow (the GPU's 1-voxel zero field): only the seed is reached
    let unit = unit_field_on(grid, field);
    let regridded = unit.as_ref().map(|inner| OnGrid {
        inner,
        to: grid.dims,
    });
    let field: &dyn Field = match &regridded {
        Some(g) => g,
        None => &NoFlow,
    };
    arrival_volume(field, grid.dims, &seed_box(p), &arrival_params(p))
}

/// The largest grid (voxels) whose twin statistics are computed: 128³ (the twin takes
/// seconds there).
pub const TWIN_STATISTIC_VOXELS: u64 = 128 * 128 * 128;

/// An arrival volume (the GPU's) against its twin's: the voxels where one is reached and
/// the other not, the voxels both reach, and over those |Δt| / (1 + t), RMS and worst.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Agreement {
    pub disagree: usize,
    pub reached: usize,
    pub rms: f64,
    pub worst: f64,
}

impl Agreement {
    pub fn of(gpu: &[f32], twin: &[f32]) -> Self {
        let (mut disagree, mut reached, mut worst, mut sq) = (0usize, 0usize, 0.0f64, 0.0f64);
        for (g, c) in gpu.iter().zip(twin) {
            if (*g == NEVER) != (*c == NEVER) {
                disagree += 1;
            } else if *c != NEVER {
                reached += 1;
                let e = (*g as f64 - *c as f64).abs() / (1.0 + *c as f64);
                worst = worst.max(e);
                sq += e * e;
            }
        }
        Self {
            disagree,
            reached,
            rms: (sq / reached.max(1) as f64).sqrt(),
            worst,
        }
    }
}

/// Whether a sample with arrival time `t` is kept at `time` with `band`.
pub fn kept(t: f64, time: f64, band: f64) -> bool {
    t <= time && (band <= 0.0 || t > time - band)
}

impl Plugin for Arrival {
    /// Its pre-pass follows paths through the whole vector volume.
    fn splits_into_bricks(&self) -> bool {
        false
    }
    /// `reached`: the share of voxels the GPU's pre-pass reaches. On grids up to
    /// [`TWIN_STATISTIC_VOXELS`] (else NaN), against the f64 twin ([`Agreement`]):
    /// `twin_disagree`, the share of voxels one reaches and the other not; `twin_rms`, the
    /// RMS of |Δt| / (1 + t) over the voxels both reach; `twin_seconds`, the twin's wall
    /// time on this machine's cores.
    fn statistic_names(&self, _params: &ParamValues) -> Vec<&'static str> {
        vec!["reached", "twin_disagree", "twin_rms", "twin_seconds"]
    }
    fn statistics(
        &self,
        params: &ParamValues,
        passes: &vwb_render::plugin::PassOutputs<'_>,
    ) -> Vec<vwb_render::plugin::Statistic> {
        let Some((dims, gpu)) = (passes.read)("prepass") else {
            return Vec::new();
        };
        let n = gpu.len().max(1) as f64;
        let reached = gpu.iter().filter(|t| **t != NEVER).count() as f64 / n;
        let voxels: u64 = dims.iter().map(|&d| d as u64).product();
        let (mut disagree, mut rms, mut seconds) = (f64::NAN, f64::NAN, f64::NAN);
        if let Ok(field) = passes.inputs.resolve(passes.volume, params, "field")
            && voxels <= TWIN_STATISTIC_VOXELS
        {
            let t = std::time::Instant::now();
            let twin = arrival_on(passes.volume, field, params);
            seconds = t.elapsed().as_secs_f64();
            if twin.len() == gpu.len() {
                let a = Agreement::of(&gpu, &twin);
                disagree = a.disagree as f64 / n;
                rms = a.rms;
            }
        }
        [
            ("reached", reached),
            ("twin_disagree", disagree),
            ("twin_rms", rms),
            ("twin_seconds", seconds),
        ]
        .into_iter()
        .map(|(name, value)| vwb_render::plugin::Statistic { name, value })
        .collect()
    }
    /// The twin's arrival times against the exact ones on the rotation ([`probes`]).
    fn probes(&self) -> Vec<Arc<dyn vwb_render::plugin::Probe>> {
        vec![Arc::new(probes::OnRotation)]
    }
    fn id(&self) -> &'static str {
        "flow.arrival"
    }
    fn display_name(&self) -> &'static str {
        "Time surfaces"
    }
    fn description(&self) -> &'static str {
        "Keeps what the flow from a seed box has reached by a time (an arrival-time volume): play the time to animate"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::volume("field", "Vector field", Components::Any).with_doc(
                "the document's own volume, or one of its named volumes (on a grid of its own, over the same box); a scalar volume has no flow",
            ),
            ParamSpec::float("time", "Time", 0.0, 1024.0, 32.0)
                .clock()
                .with_doc("voxels travelled at the field's top speed; playing it recomputes nothing"),
            ParamSpec::float("band", "Front width", 0.0, 256.0, 0.0)
                .with_doc("0: everything reached by the time; > 0: only what arrived within this time of it"),
            ParamSpec::vec3("seed_min", "Seed box min", 0.0, 1.0, [0.0, 0.0, 0.0])
                .with_doc("corner of the seed box, texture coordinates of the volume box"),
            ParamSpec::vec3("seed_max", "Seed box max", 0.0, 1.0, [0.05, 1.0, 1.0])
                .with_doc("opposite corner: by default a flat box across x at the low end"),
            ParamSpec::float_log("step", "Step (voxels)", 0.1, 2.0, 0.5)
                .with_doc("path length per integration step"),
            ParamSpec::float("max_length", "Longest path (voxels)", 8.0, 2048.0, 256.0)
                .with_doc("paths longer than this never arrive"),
            ParamSpec::enumeration("integrator", "Integrator", &Integrator::KEYS, 2)
                .structural()
                .with_doc("only the chosen one is compiled into the pre-pass"),
        ]
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource::without_regions(SHADER_FILE, SHADER, &[("prepass", "")])
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![ResourceDecl {
            name: "field",
            kind: ResourceKind::Texture3d,
        }]
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        Some(PrepassDecl {
            target: "arrival",
            format: StorageFormat::R32Float,
            scale: 1.0,
            shader: ShaderSource::without_regions(SHADER_FILE, SHADER, &{
                let mut regions = vec![("hook", "")];
                regions.extend(self.integrator.region_left_out().map(|r| (r, "")));
                regions
            }),
            depends_on: vec!["seed_min", "seed_max", "step", "max_length", "integrator"],
            holds_value: false,
        })
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let c = Arrival {
            integrator: Integrator::from_key(params.enumeration("integrator")),
        };
        (c != *self).then(|| Arc::new(c) as Arc<dyn Plugin>)
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        if gpu.volume.dims.iter().any(|&d| d > gpu.device.limits().max_texture_dimension_3d) {
            return Err(error("the volume exceeds the device's 3D texture limit".into()));
        }
        let field = crate::flow_lic3d::field_texture(
            gpu,
            "flow.arrival field",
            unit_field_on(gpu.volume, gpu.input(params, "field")?).as_ref(),
            false,
        );
        Ok(vec![field])
    }
    /// The demo volume is scalar (no flow: only the seed is reached): a seed box over
    /// half of it, so that the clip keeps something to compare.
    fn demo_params(&self) -> Option<ParamValues> {
        let mut p = ParamValues::defaults(&self.params());
        p.set("seed_max", ParamValue::Vec3([0.6, 1.0, 1.0]));
        Some(p)
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(ArrivalTwin {
            params: params.clone(),
            time: params.float("time") as f64,
            band: params.float("band") as f64,
            arrival: None,
        }))
    }
    /// Samples are dropped, never made more opaque.
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
}

/// CPU twin: the arrival volume computed once (`prepare`), sampled trilinearly as the
/// GPU samples `arrival`.
pub struct ArrivalTwin {
    pub params: ParamValues,
    pub time: f64,
    pub band: f64,
    pub arrival: Option<Arc<([u32; 3], Vec<f32>)>>,
}

impl CpuTwin for ArrivalTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        if self.arrival.is_none() {
            let field = ctx.input(&self.params, "field");
            let arrival = arrival_on(ctx.volume, field, &self.params);
            self.arrival = Some(Arc::new((ctx.volume.dims, arrival)));
        }
    }
    fn clip(&self, s: &CpuSample) -> bool {
        let Some(a) = &self.arrival else {
            return true;
        };
        let (dims, data) = (&a.0, &a.1);
        let t = trilinear_grid(*dims, s.tex, |i| DVec4::splat(data[i] as f64)).x;
        kept(t, self.time, self.band)
    }
}
