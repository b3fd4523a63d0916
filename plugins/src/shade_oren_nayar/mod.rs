//! `shade.oren_nayar`: rough diffuse reflection, the qualitative model of Oren & Nayar
//! (1994): per light of colour L, rgb += L·k_d·base·cos θi·(A + B·max(0, cos(φi − φr))
//! ·sin α·tan β) with A = 1 − 0.5σ²/(σ² + 0.33), B = 0.45σ²/(σ² + 0.09),
//! α = max(θi, θr), β = min(θi, θr), and σ the standard deviation of the facet slopes
//! in radians; plus k_a·base. σ = 0 is Lambert's law (the diffuse term of
//! `shade.blinn_phong`); rough surfaces look flatter and scatter back towards the
//! light. cos(φi − φr) is taken from the projections of l and v onto the tangent
//! plane; tan β divides by max(cos β, 10⁻⁴) (our guard for grazing views). The gradient
//! is the normal (shared estimators and fade rule); opacity is unchanged.

use std::sync::Arc;

use glam::{DVec3, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, Plugin, PrepassDecl, ShaderSource, Transparency,
};
use vwb_render::shading::{GradientEstimator, Gradients, Light, safe_normalize, shading_normal};

use crate::lighting;

#[cfg(test)]
mod tests;

#[derive(Debug, Clone, Copy, Default)]
pub struct OrenNayar {
    pub gradient: GradientEstimator,
}

impl Plugin for OrenNayar {
    fn id(&self) -> &'static str {
        "shade.oren_nayar"
    }
    fn display_name(&self) -> &'static str {
        "Oren–Nayar (rough diffuse)"
    }
    fn description(&self) -> &'static str {
        "Rough diffuse reflection: flatter shading and back-scatter as σ grows"
    }
    fn params(&self) -> Vec<ParamSpec> {
        let mut p = vec![
            GradientEstimator::param(),
            ParamSpec::float("ka", "Ambient k_a", 0.0, 1.0, 0.25),
            ParamSpec::float("kd", "Diffuse k_d", 0.0, 1.0, 0.8),
            ParamSpec::float("sigma", "Roughness σ (rad)", 0.0, 1.5, 0.5)
                .with_doc("standard deviation of the facet slopes in radians; 0 is Lambert"),
            ParamSpec::boolean("two_sided", "Two-sided", true)
                .with_doc("flip normals towards the viewer (else n = −∇f/|∇f|)"),
            lighting::fade_param(),
        ];
        p.extend(lighting::light_params(4));
        p
    }
    fn shader(&self) -> ShaderSource {
        self.gradient.hook_source(
            "plugins/src/shade_oren_nayar/oren_nayar.wgsl",
            include_str!("oren_nayar.wgsl"),
        )
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        self.gradient.prepass()
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let gradient = GradientEstimator::from_params(params);
        (gradient != self.gradient).then(|| Arc::new(OrenNayar { gradient }) as Arc<dyn Plugin>)
    }
    /// Shading changes colours only.
    fn transparency(&self, _params: &ParamValues) -> Transparency {
        Transparency::Keeps
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(OrenNayarTwin {
            gradients: Gradients::new(self.gradient),
            ka: params.float("ka") as f64,
            kd: params.float("kd") as f64,
            sigma: params.float("sigma") as f64,
            lights: lighting::lights(params, 4),
            two_sided: params.boolean("two_sided"),
            floor: params.float("gradient_floor") as f64,
        }))
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

/// CPU twin of `oren_nayar.wgsl`.
pub struct OrenNayarTwin {
    pub gradients: Gradients,
    pub ka: f64,
    pub kd: f64,
    pub sigma: f64,
    pub lights: Vec<Light>,
    pub two_sided: bool,
    pub floor: f64,
}

impl CpuTwin for OrenNayarTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        self.gradients.prepare(ctx);
    }
    fn shade(&self, ctx: &CpuContext, s: &mut CpuSample) {
        if s.color.w <= 0.0 {
            return;
        }
        let v = -s.ray_dir;
        let (n, w) = shading_normal(self.gradients.at(ctx, s.tex), self.floor, v, self.two_sided);
        let d: DVec3 = self
            .lights
            .iter()
            .map(|l| l.color * (self.kd * oren_nayar_factor(self.sigma, n, v, l.dir(ctx, s.pos))))
            .sum();
        let base = s.color.truncate();
        let lit = base * (DVec3::splat(self.ka) + d);
        s.color = DVec4::from((base.lerp(lit, w), s.color.w));
        s.normal = n;
    }
}
