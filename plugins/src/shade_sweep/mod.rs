//! `shade.sweep_shadows`: shadows from a directional light by one light-aligned sweep
//! of the volume (Behrens & Ratering 1998, "Adding shadows to a texture-based volume
//! renderer"; the light-aligned slices of Rezk-Salama 2001 §5). It is the first user of
//! a sweep pass ([`VolumePassDecl::sweep`], `render/src/sweep.rs`): the transmittance
//! volume is computed plane by plane along the light, each plane reading the one
//! before, in one pass of O(N³) instead of a ray per voxel (O(N⁴), shade.hernell's
//! exact mode). The pass reruns when the light, the transfer function or the data
//! change, never for the camera. `sweep.wgsl` has the equations. The light volume
//! may be coarser than the data (`resolution`, structural: 1:2 sweeps an eighth of the
//! texels); `experiments/illumination.ron` measures what that costs in error.

use glam::{DVec3, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, Plugin, ShaderSource, StackClassify,
    Transparency, VolumePassDecl, Volumes,
};
use vwb_render::reference::correct_opacity;
use vwb_render::sweep::Sweep;

#[cfg(test)]
mod tests;

/// Light-volume resolutions against the data's (structural).
pub const RESOLUTIONS: [&str; 3] = ["1:1", "1:2", "1:4"];

/// The plugin as its `resolution` configures it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepShadows {
    /// The transmittance volume's size relative to the volume (1, ½, ¼).
    pub scale: f32,
}

impl Default for SweepShadows {
    fn default() -> Self {
        Self { scale: 1.0 }
    }
}

fn resolution_scale(params: &ParamValues) -> f32 {
    match params.enumeration("resolution") {
        "1:2" => 0.5,
        "1:4" => 0.25,
        _ => 1.0,
    }
}

/// The light's direction of travel under `params` (`travel()` in the WGSL).
fn travel(params: &ParamValues) -> [f32; 3] {
    let l = params.vec3("light");
    [-l[0], -l[1], -l[2]]
}

impl Plugin for SweepShadows {
    fn id(&self) -> &'static str {
        "shade.sweep_shadows"
    }
    fn display_name(&self) -> &'static str {
        "Shadows (light-aligned sweep)"
    }
    fn description(&self) -> &'static str {
        "Shadows from a directional light: the transmittance volume swept plane by plane along the light"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::vec3("light", "Light direction (world)", -4.0, 4.0, [0.6, 0.7, 0.4])
                .with_doc("towards the light, in world space; its length does not matter"),
            ParamSpec::float("ambient", "Ambient", 0.0, 1.0, 0.1)
                .with_doc("the light a fully shadowed sample still gets"),
            ParamSpec::enumeration("resolution", "Light volume resolution", &RESOLUTIONS, 0)
                .structural()
                .with_doc("of the data's: 1:2 sweeps an eighth of the texels"),
        ]
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource::new_static(
            "plugins/src/shade_sweep/sweep.wgsl",
            include_str!("sweep.wgsl"),
        )
    }
    fn volume_passes(&self) -> Vec<VolumePassDecl> {
        vec![
            VolumePassDecl::new("transmittance", "transmit")
                .scale(self.scale)
                .depends_on(&["light"])
                .sweep(travel, 1.0),
        ]
    }
    fn configure(&self, params: &ParamValues) -> Option<std::sync::Arc<dyn Plugin>> {
        let c = SweepShadows {
            scale: resolution_scale(params),
        };
        (c != *self).then(|| std::sync::Arc::new(c) as std::sync::Arc<dyn Plugin>)
    }
    /// It scales colours only.
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(SweepTwin {
            travel: DVec3::from(travel(params).map(f64::from)),
            ambient: params.float("ambient") as f64,
            scale: self.scale,
            dims: [0; 3],
            transmittance: Vec::new(),
        }))
    }
}

/// CPU twin: the sweep in f64 (stored as r32float) and the shade hook.
pub struct SweepTwin {
    pub travel: DVec3,
    pub ambient: f64,
    /// The transmittance volume's size relative to the volume.
    pub scale: f32,
    /// Its size in texels (set by `prepare_passes`, as the renderer sizes it).
    pub dims: [u32; 3],
    pub transmittance: Vec<f32>,
}

impl SweepTwin {
    /// The unit direction of travel (`travel()`; zero for a zero light).
    fn unit(&self) -> DVec3 {
        self.travel.normalize_or_zero()
    }
}

impl CpuTwin for SweepTwin {
    fn prepare_passes(&mut self, ctx: &CpuContext, classify: &StackClassify<'_>) {
        let dims = ctx
            .volume
            .dims
            .map(|d| ((d as f32 * self.scale).ceil() as u32).max(1));
        let (lo, hi) = ctx.volume_box();
        let texel = (hi - lo) / DVec3::from(dims.map(f64::from));
        let h = ctx.reference_step();
        let d = self.unit();
        self.dims = dims;
        let n = DVec3::from(dims.map(f64::from));
        self.transmittance = Sweep::new(self.travel, dims, texel, 1.0).run(|v, _, prev, length| {
            let tex = (DVec3::from(v.map(f64::from)) + 0.5) / n;
            prev * (1.0 - correct_opacity(classify(tex, d).w, length / h))
        });
    }
    fn shade(&self, ctx: &CpuContext, s: &mut CpuSample) {
        let (lo, hi) = ctx.volume_box();
        // one texel of the light volume upstream (one voxel at 1:1)
        let ratio = (ctx.volume.dims[0] as f32 / self.dims[0] as f32) as f64;
        let up = s.tex - self.unit() * ctx.reference_step() * ratio / (hi - lo);
        let t = vwb_render::plugin::trilinear_grid(self.dims, up, |i| {
            DVec4::splat(self.transmittance[i] as f64)
        })
        .x;
        let f = self.ambient + (1.0 - self.ambient) * t;
        s.color = (s.color.truncate() * f).extend(s.color.w);
    }
}
