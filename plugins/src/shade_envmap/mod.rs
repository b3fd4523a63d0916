//! `shade.envmap`: reflection maps (Rezk-Salama 2001 §7.4): a diffuse map indexed by
//! the normal and a reflective map indexed by the reflection vector r = 2(n·v)n − v,
//! both longitude–latitude in world space (+y up), mixed as
//! `env = base·(k_a + k_d,env·E(n)) + k_s,env·L(r)` and blended with a Blinn–Phong head
//! light: `lit = mix(env, phong, phong_weight)`. The map is the procedural sky
//! ([`maps::procedural`]) or any image file (`map`, relative to the preset), resampled
//! to 512 × 256; the diffuse map is its cosine convolution at 64 × 32, computed once per
//! file on the CPU. Like the thesis's maps it assumes a distant environment: no
//! self-reflection or self-shadowing. Shading fades to unlit where |∇f| is small (the
//! rule in `vwb_render::shading`).

pub mod maps;

use std::sync::Arc;

use glam::{DVec3, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, PrepassDecl,
    ResourceDecl, ResourceKind, ShaderSource, Transparency, Volumes,
};
use vwb_render::shading::{
    GradientEstimator, Gradients, Light, Material, blinn_phong_factors,
};

use crate::lighting;
use maps::{EnvMaps, LatLong};

#[cfg(test)]
mod tests;

#[derive(Debug, Clone, Copy, Default)]
pub struct EnvMap {
    pub gradient: GradientEstimator,
}

/// The maps the `map` parameter names (the procedural sky when empty).
pub fn env_maps(params: &ParamValues) -> Result<Arc<EnvMaps>, String> {
    match params.path("map") {
        Some(p) => maps::load(p),
        None => Ok(maps::procedural()),
    }
}

impl Plugin for EnvMap {
    fn id(&self) -> &'static str {
        "shade.envmap"
    }
    fn display_name(&self) -> &'static str {
        "Environment map"
    }
    fn description(&self) -> &'static str {
        "Diffuse and specular reflection maps (lat-long), blended with Blinn–Phong"
    }
    fn params(&self) -> Vec<ParamSpec> {
        let mut p = vec![
            GradientEstimator::param(),
            ParamSpec::path("map", "Environment image (lat-long)", "")
                .structural()
                .with_doc("empty: a procedural sky; any image the image crate reads"),
            ParamSpec::float("rotation_deg", "Rotation about +y (°)", -180.0, 180.0, 0.0),
            ParamSpec::float("kd_env", "Diffuse reflection", 0.0, 2.0, 0.9),
            ParamSpec::float("ks_env", "Specular reflection", 0.0, 1.0, 0.25),
            ParamSpec::float("phong_weight", "Blinn–Phong weight", 0.0, 1.0, 0.3)
                .with_doc("0: reflection maps only; 1: Blinn–Phong only"),
        ];
        p.extend(lighting::material_params(0.15, 0.75, 0.3, 24.0));
        p.push(lighting::head_light_param());
        p.push(lighting::fade_param());
        p
    }
    fn shader(&self) -> ShaderSource {
        self.gradient.hook_source(
            "plugins/src/shade_envmap/envmap.wgsl",
            include_str!("envmap.wgsl"),
        )
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![
            ResourceDecl {
                name: "radiance",
                kind: ResourceKind::Texture2d,
            },
            ResourceDecl {
                name: "irradiance",
                kind: ResourceKind::Texture2d,
            },
        ]
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        self.gradient.prepass()
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let gradient = GradientEstimator::from_params(params);
        (gradient != self.gradient).then(|| Arc::new(EnvMap { gradient }) as Arc<dyn Plugin>)
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let m = env_maps(params).map_err(|message| PluginError::Invalid {
            plugin: self.id().into(),
            message,
        })?;
        let upload = |label: &str, map: &LatLong| {
            let t = gpu.create_table(label, map.width, map.height);
            gpu.write_table(&t, &map.texels);
            t
        };
        Ok(vec![
            upload("shade.envmap radiance", &m.radiance),
            upload("shade.envmap irradiance", &m.irradiance),
        ])
    }
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(EnvMapTwin {
            gradients: Gradients::new(self.gradient),
            maps: env_maps(params).ok()?,
            rotation_deg: params.float("rotation_deg") as f64,
            kd_env: params.float("kd_env") as f64,
            ks_env: params.float("ks_env") as f64,
            phong_weight: params.float("phong_weight") as f64,
            material: lighting::material(params),
            light: lighting::head_light(params),
            floor: params.float("gradient_floor") as f64,
        }))
    }
}

/// CPU twin of `envmap.wgsl`.
pub struct EnvMapTwin {
    pub gradients: Gradients,
    pub maps: Arc<EnvMaps>,
    pub rotation_deg: f64,
    pub kd_env: f64,
    pub ks_env: f64,
    pub phong_weight: f64,
    pub material: Material,
    pub light: Light,
    pub floor: f64,
}

impl CpuTwin for EnvMapTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        self.gradients.prepare(ctx);
    }
    fn shade(&self, ctx: &CpuContext, s: &mut CpuSample) {
        if s.color.w <= 0.0 {
            return;
        }
        let v = -s.ray_dir;
        let (_, n, w) = self.gradients.normal(ctx, s.shading_tex(ctx), self.floor, v, true);
        if w <= 0.0 {
            return;
        }
        let base = s.color.truncate();
        let m = &self.material;
        let r = 2.0 * n.dot(v) * n - v;
        let env = base
            * (DVec3::splat(m.ka)
                + self.kd_env * self.maps.irradiance.lookup(n, self.rotation_deg))
            + self.ks_env * self.maps.radiance.lookup(r, self.rotation_deg);
        let (d, sp) = blinn_phong_factors(n, v, self.light.dir(ctx, s.pos), m.shininess);
        let bp = base * (m.ka + m.kd * d) + DVec3::splat(m.ks * sp);
        s.color = DVec4::from((base.lerp(env.lerp(bp, self.phong_weight), w), s.color.w));
        s.normal = n;
    }
}
