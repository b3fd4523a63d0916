//! `composite.tonemap`: exposure (in stops) and display gamma of the composited volume
//! image, the first user of the `post` hook (once per pixel on the accumulated colour,
//! after the slice loop; `tonemap.wgsl`). Dim illumination models (global light,
//! occlusion) can be brought to a comparable brightness without touching their
//! parameters or the transfer function. Opacity is unchanged.

use glam::{DVec2, DVec4};
use vwb_render::params::{ParamSpec, ParamValue, ParamValues};
use vwb_render::plugin::{CpuTwin, Plugin, ShaderSource, Transparency, Volumes};

#[cfg(test)]
mod tests;

pub struct Tonemap;

impl Plugin for Tonemap {
    fn id(&self) -> &'static str {
        "composite.tonemap"
    }
    fn display_name(&self) -> &'static str {
        "Exposure and gamma (image)"
    }
    fn description(&self) -> &'static str {
        "Exposure in stops and display gamma of the volume's image, once per pixel after the slices"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::float("exposure", "Exposure (stops)", -4.0, 4.0, 0.0)
                .with_doc("the straight colour times 2^exposure"),
            ParamSpec::float("gamma", "Gamma", 0.4, 2.5, 1.0)
                .with_doc("then raised to 1/gamma (above 1 brightens the mid-tones) and clamped to 1"),
        ]
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource::new_static(
            "plugins/src/composite_tonemap/tonemap.wgsl",
            include_str!("tonemap.wgsl"),
        )
    }
    /// It never touches a sample.
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
    /// One stop brighter with a gamma of 1.5, so that the tests see it act.
    fn demo_params(&self) -> Option<ParamValues> {
        let mut p = ParamValues::defaults(&self.params());
        p.set("exposure", ParamValue::Float(1.0));
        p.set("gamma", ParamValue::Float(1.5));
        Some(p)
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(TonemapTwin {
            exposure: params.float("exposure") as f64,
            gamma: params.float("gamma") as f64,
        }))
    }
}

/// CPU twin of `post`.
pub struct TonemapTwin {
    pub exposure: f64,
    pub gamma: f64,
}

impl TonemapTwin {
    /// The premultiplied colour `c` mapped as `post` maps it.
    pub fn map(&self, c: DVec4) -> DVec4 {
        if c.w.is_nan() || c.w <= 0.0 {
            return c;
        }
        let straight = (c.truncate() / c.w).max(glam::DVec3::ZERO) * self.exposure.exp2();
        let mapped = straight.powf(1.0 / self.gamma).min(glam::DVec3::ONE);
        (mapped * c.w).extend(c.w)
    }
}

impl CpuTwin for TonemapTwin {
    fn post(&self, c: &mut DVec4, _uv: DVec2) {
        *c = self.map(*c);
    }
}
