//! `shade.blinn_phong`: Blinn–Phong local illumination of the classified samples
//! (Rezk-Salama 2001 §7.1–7.3): the gradient replaces the surface normal; ambient,
//! diffuse and specular terms; up to four lights, each directional or point, in view
//! or world space, with a colour; one- or two-sided; `modulate` (rgb = base·(k_a +
//! Σk_d·diff·L) + Σk_s·spec·L) or the thesis's `additive` semi-transparent mode (the
//! diffuse term "simply added"); optional gradient-magnitude opacity
//! α' = α·mix(1, clamp(|∇f|·gm_scale, 0, 1), gm_opacity) (eq 5.12). The gradient
//! estimator is structural (`vwb_render::shading`); where |∇f| falls below
//! `gradient_floor` shading fades to unlit. `lighting: table` shades the view-space
//! directional lights through a lighting table indexed by the normal (table.rs).

use std::sync::Arc;

use glam::{DVec3, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, PrepassDecl,
    ResourceDecl, ResourceKind, ShaderSource, Transparency, Volumes,
};
use vwb_render::shading::{GradientEstimator, Gradients, Light, LightKind, Material};

use crate::lighting;

pub mod table;
#[cfg(test)]
mod tests;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlinnPhong {
    pub gradient: GradientEstimator,
    /// `lighting: table`: the view-space directional lights come from the lighting table.
    pub table: bool,
    /// The lights evaluated per sample (on, and not tabulated), by kind: only those are
    /// compiled in, since a CPU device runs a branch's code whether it is taken or not.
    pub per_sample: [Option<LightKind>; 4],
}

impl Default for BlinnPhong {
    /// As the default parameters configure it: light 0 on, per sample.
    fn default() -> Self {
        Self {
            gradient: GradientEstimator::default(),
            table: false,
            per_sample: [Some(LightKind::Directional), None, None, None],
        }
    }
}

fn is_table(params: &ParamValues) -> bool {
    params.enumeration("lighting") == "table"
}

const FILE: &str = "plugins/src/shade_blinn_phong/blinn_phong.wgsl";
const SOURCE: &str = include_str!("blinn_phong.wgsl");

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
            ParamSpec::enumeration("lighting", "Lighting", &["direct", "table"], 0)
                .structural()
                .with_doc("direct: every light per sample; table: view-space directional lights from a table over the normal (view vector (0, 0, 1)), rebuilt only when they or k_d, k_s, n change"),
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
        p.extend(lighting::light_params());
        p
    }
    fn shader(&self) -> ShaderSource {
        let mut s = self
            .gradient
            .append_to(lighting::with_lights(FILE, SOURCE, self.per_sample));
        s.source.to_mut().push_str(if self.table {
            table::TABLE_WGSL
        } else {
            table::DIRECT_WGSL
        });
        s
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        if self.table {
            vec![ResourceDecl {
                name: "light_table",
                kind: ResourceKind::Texture2d,
            }]
        } else {
            Vec::new()
        }
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        Ok(if self.table {
            let lights = lighting::lights(params);
            vec![table::create(gpu, &lights, &lighting::material(params))]
        } else {
            Vec::new()
        })
    }
    fn update_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
        resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        if let (true, Some(t)) = (self.table, resources.first()) {
            let lights = lighting::lights(params);
            table::upload(gpu, t, &lights, &lighting::material(params));
        }
        Ok(())
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        self.gradient.prepass()
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let table = is_table(params);
        let lights = lighting::light_slots(params);
        let c = BlinnPhong {
            gradient: GradientEstimator::from_params(params),
            table,
            per_sample: std::array::from_fn(|i| {
                lights[i]
                    .filter(|l| !(table && table::tabulated(l)))
                    .map(|l| l.kind)
            }),
        };
        (c != *self).then(|| Arc::new(c) as Arc<dyn Plugin>)
    }
    /// Shading changes colours and may lower opacity, never raises it from zero.
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        let material = lighting::material(params);
        let lights = lighting::lights(params);
        Some(Box::new(BlinnPhongTwin {
            gradients: Gradients::new(self.gradient),
            table: is_table(params).then(|| table::bake(&lights, &material)),
            material,
            lights,
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
    /// The baked lighting table (`lighting: table`).
    pub table: Option<Vec<[f32; 4]>>,
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
        use vwb_render::shading::blinn_phong_with;
        if s.color.w <= 0.0 {
            return;
        }
        let v = -s.ray_dir;
        let (g, n, w) =
            self.gradients
                .normal(ctx, s.shading_tex(ctx), self.floor, v, self.two_sided);
        let lights: Vec<_> = self
            .lights
            .iter()
            .filter(|l| self.table.is_none() || !table::tabulated(l))
            .map(|l| (l.dir(ctx, s.pos), l.color))
            .collect();
        let base = s.color.truncate();
        let tabulated = self.table.as_ref().map(|t| {
            let view = &ctx.view;
            table::lookup(t, DVec3::new(n.dot(view.right), n.dot(view.up), -n.dot(view.forward)))
        });
        let lit = blinn_phong_with(base, n, v, &lights, &self.material, self.additive, tabulated);
        let gm = (g.length() * self.gm_scale).clamp(0.0, 1.0);
        let a = s.color.w * (1.0 + (gm - 1.0) * self.gm_opacity);
        s.color = DVec4::from((base.lerp(lit, w), a));
        s.normal = n;
    }
}
