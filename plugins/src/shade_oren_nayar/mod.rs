//! `shade.oren_nayar`: rough diffuse reflection, the qualitative model of Oren & Nayar
//! (1994): per light of colour L, rgb += L·k_d·base·cos θi·(A + B·max(0, cos(φi − φr))
//! ·sin α·tan β) with A = 1 − 0.5σ²/(σ² + 0.33), B = 0.45σ²/(σ² + 0.09),
//! α = max(θi, θr), β = min(θi, θr), and σ the standard deviation of the facet slopes
//! in radians; plus k_a·base. σ = 0 is Lambert's law (the diffuse term of
//! `shade.blinn_phong`); rough surfaces look flatter and scatter back towards the
//! light. cos(φi − φr) is taken from the projections of l and v onto the tangent
//! plane; tan β divides by max(cos β, 10⁻⁴) (our guard for grazing views). The gradient
//! is the normal (shared estimators and fade rule); opacity is unchanged.

use glam::DVec3;
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::CpuContext;
use vwb_render::shading::{Light, safe_normalize};

use crate::lighting::{Lit, LightingModel, LitColour};

#[cfg(test)]
mod tests;

/// The plugin: the model on the shared gradients, fade rule and lights.
pub type OrenNayar = Lit<OrenNayarModel>;

pub struct OrenNayarModel;

impl LightingModel for OrenNayarModel {
    const ID: &'static str = "shade.oren_nayar";
    const NAME: &'static str = "Oren–Nayar (rough diffuse)";
    const DESCRIPTION: &'static str =
        "Rough diffuse reflection: flatter shading and back-scatter as σ grows";
    const FILE: &'static str = "plugins/src/shade_oren_nayar/oren_nayar.wgsl";
    const SOURCE: &'static str = include_str!("oren_nayar.wgsl");
    type Twin = RoughDiffuse;
    fn params() -> Vec<ParamSpec> {
        vec![
            ParamSpec::float("ka", "Ambient k_a", 0.0, 1.0, 0.25),
            ParamSpec::float("kd", "Diffuse k_d", 0.0, 1.0, 0.8),
            ParamSpec::float("sigma", "Roughness σ (rad)", 0.0, 1.5, 0.5)
                .with_doc("standard deviation of the facet slopes in radians; 0 is Lambert"),
        ]
    }
    fn twin(params: &ParamValues) -> RoughDiffuse {
        RoughDiffuse {
            ka: params.float("ka") as f64,
            kd: params.float("kd") as f64,
            sigma: params.float("sigma") as f64,
        }
    }
}

/// `oren_nayar_factor` in f64: cos θi·(A + B·max(0, cos(φi − φr))·sin α·tan β).
pub fn oren_nayar_factor(sigma: f64, n: DVec3, v: DVec3, l: DVec3) -> f64 {
    let ndl = n.dot(l);
    if ndl.is_nan() || ndl <= 0.0 {
        return 0.0;
    }
    let ndv = n.dot(v).clamp(0.0, 1.0);
    let s2 = sigma * sigma;
    let a = 1.0 - 0.5 * s2 / (s2 + 0.33);
    let b = 0.45 * s2 / (s2 + 0.09);
    let cos_phi = safe_normalize(l - n * ndl)
        .dot(safe_normalize(v - n * ndv))
        .max(0.0);
    let (cos_alpha, cos_beta) = (ndl.min(ndv), ndl.max(ndv));
    let sin_alpha = (1.0 - cos_alpha * cos_alpha).max(0.0).sqrt();
    let tan_beta = (1.0 - cos_beta * cos_beta).max(0.0).sqrt() / cos_beta.max(1.0e-4);
    ndl * (a + b * cos_phi * sin_alpha * tan_beta)
}

/// The material of `oren_nayar.wgsl`, in f64.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoughDiffuse {
    pub ka: f64,
    pub kd: f64,
    pub sigma: f64,
}

/// The lit colour of `oren_nayar.wgsl`'s `shade`.
impl LitColour for RoughDiffuse {
    fn lit(
        &self,
        ctx: &CpuContext,
        lights: &[Light],
        base: DVec3,
        n: DVec3,
        v: DVec3,
        pos: DVec3,
    ) -> DVec3 {
        let d: DVec3 = lights
            .iter()
            .map(|l| l.color * (self.kd * oren_nayar_factor(self.sigma, n, v, l.dir(ctx, pos))))
            .sum();
        base * (DVec3::splat(self.ka) + d)
    }
}
