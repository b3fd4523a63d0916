//! `shade.blinn_phong`: Blinn–Phong local illumination of the classified samples
//! (Rezk-Salama 2001 §7.1–7.3): the gradient replaces the surface normal; ambient,
//! diffuse and specular terms; up to four lights, each directional or point, in view
//! or world space, with a colour; one- or two-sided; `modulate` (rgb = base·(k_a +
//! Σk_d·diff·L) + Σk_s·spec·L) or the thesis's `additive` semi-transparent mode (the
//! diffuse term "simply added"); optional gradient-magnitude opacity
//! α' = α·mix(1, clamp(|∇f|·gm_scale, 0, 1), gm_opacity) (eq 5.12). The gradient
//! estimator is structural (`vwb_render::shading`); where |∇f| falls below
//! `gradient_floor` shading fades to unlit.

use std::sync::Arc;

use glam::DVec4;
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, Plugin, PrepassDecl, ShaderSource, Transparency,
};
use vwb_render::shading::{GradientEstimator, Gradients, Light, Material};

use crate::lighting;

#[cfg(test)]
mod tests;

#[derive(Debug, Clone, Copy, Default)]
pub struct BlinnPhong {
    pub gradient: GradientEstimator,
}

impl Plugin for BlinnPhong {
    fn id(&self) -> &'static str {
        "shade.blinn_phong"
    }
    fn display_name(&self) -> &'static str {
        "Blinn–Phong"
    }
    fn description(&self) -> &'static str {
        "Local illumination with the gradient as normal; up to four lights"
    }
    fn params(&self) -> Vec<ParamSpec> {
        let mut p = vec![
            GradientEstimator::param(),
            ParamSpec::enumeration("mode", "Mode", &["modulate", "additive"], 0)
                .with_doc("modulate: base·(ka + kd·diffuse) + ks·specular; additive: base·ka + kd·diffuse + ks·specular (thesis §7.3)"),
        ];
        p.extend(lighting::material_params(0.25, 0.75, 0.35, 24.0));
        p.extend([
            ParamSpec::boolean("two_sided", "Two-sided", true)
                .with_doc("flip normals towards the viewer (else n = −∇f/|∇f|)"),
            lighting::fade_param(),
            ParamSpec::float("gm_opacity", "Gradient opacity", 0.0, 1.0, 0.0)
                .with_doc("0: off; 1: α scaled by clamp(|∇f|·gm_scale, 0, 1) (eq 5.12)"),
            ParamSpec::float_log("gm_scale", "Gradient opacity scale", 0.1, 100.0, 10.0),
        ]);
        p.extend(lighting::light_params(4));
        p
    }
    fn shader(&self) -> ShaderSource {
        self.gradient.hook_source(
            "plugins/src/shade_blinn_phong/blinn_phong.wgsl",
            include_str!("blinn_phong.wgsl"),
        )
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        self.gradient.prepass()
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let gradient = GradientEstimator::from_params(params);
        (gradient != self.gradient).then(|| Arc::new(BlinnPhong { gradient }) as Arc<dyn Plugin>)
    }
    /// Shading changes colours and may lower opacity, never raises it from zero.
    fn transparency(&self, _params: &ParamValues) -> Transparency {
        Transparency::Keeps
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(BlinnPhongTwin {
            gradients: Gradients::new(self.gradient),
            material: lighting::material(params),
            lights: lighting::lights(params, 4),
            additive: params.enumeration("mode") == "additive",
            two_sided: params.boolean("two_sided"),
            floor: params.float("gradient_floor") as f64,
            gm_opacity: params.float("gm_opacity") as f64,
            gm_scale: params.float("gm_scale") as f64,
        }))
    }
}

/// CPU twin of `blinn_phong.wgsl`.
pub struct BlinnPhongTwin {
    pub gradients: Gradients,
    pub material: Material,
    pub lights: Vec<Light>,
    pub additive: bool,
    pub two_sided: bool,
    pub floor: f64,
    pub gm_opacity: f64,
    pub gm_scale: f64,
}

impl CpuTwin for BlinnPhongTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        self.gradients.prepare(ctx);
    }
    fn shade(&self, ctx: &CpuContext, s: &mut CpuSample) {
        use vwb_render::shading::{blinn_phong, shading_normal};
        if s.color.w <= 0.0 {
            return;
        }
        let v = -s.ray_dir;
        let g = self.gradients.at(ctx, s.shading_tex(ctx));
        let (n, w) = shading_normal(g, self.floor, v, self.two_sided);
        let lights: Vec<_> = self
            .lights
            .iter()
            .map(|l| (l.dir(ctx, s.pos), l.color))
            .collect();
        let base = s.color.truncate();
        let lit = blinn_phong(base, n, v, &lights, &self.material, self.additive);
        let gm = (g.length() * self.gm_scale).clamp(0.0, 1.0);
        let a = s.color.w * (1.0 + (gm - 1.0) * self.gm_opacity);
        s.color = DVec4::from((base.lerp(lit, w), a));
        s.normal = n;
    }
}
