//! `shade.cook_torrance`: microfacet reflection (Cook & Torrance 1982) over a
//! Lambertian base, with
//! - the GGX / Trowbridge–Reitz distribution D(h) = α² / (π ((n·h)²(α² − 1) + 1)²)
//!   (Walter et al. 2007), α = roughness² (the perceptually linear convention of
//!   Burley 2012; our choice),
//! - Smith's separable masking–shadowing for GGX, G = G1(l)·G1(v) with
//!   G1(x) = 2(n·x) / ((n·x) + √(α² + (1 − α²)(n·x)²)),
//! - Schlick's Fresnel F = F0 + (1 − F0)(1 − v·h)⁵ with a scalar F0 (0.04: dielectrics).
//!
//! Per light of colour L: rgb += L·(k_d·base·max(n·l, 0) + k_s·π·D·G·F/(4 n·v)), i.e. the
//! specular radiance for an irradiance of π at normal incidence, so that k_d·base·(n·l)
//! is the Lambertian term that `shade.blinn_phong` uses and the two models share one
//! scale; plus k_a·base. Nothing is added where n·l ≤ 0 or n·v ≤ 0. The gradient is
//! the normal (shared estimators and fade rule, `vwb_render::shading`); opacity is
//! unchanged.

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
pub struct CookTorrance {
    pub gradient: GradientEstimator,
}

impl Plugin for CookTorrance {
    fn id(&self) -> &'static str {
        "shade.cook_torrance"
    }
    fn display_name(&self) -> &'static str {
        "Cook–Torrance (GGX)"
    }
    fn description(&self) -> &'static str {
        "Microfacet reflection: GGX distribution, Smith masking, Schlick Fresnel"
    }
    fn params(&self) -> Vec<ParamSpec> {
        let mut p = vec![
            GradientEstimator::param(),
            ParamSpec::float("ka", "Ambient k_a", 0.0, 1.0, 0.2),
            ParamSpec::float("kd", "Diffuse k_d", 0.0, 1.0, 0.75)
                .with_doc("weight of the Lambertian base"),
            ParamSpec::float("ks", "Specular k_s", 0.0, 4.0, 1.0)
                .with_doc("weight of the microfacet term π·D·G·F/(4 n·v)"),
            ParamSpec::float("roughness", "Roughness", 0.05, 1.0, 0.35)
                .with_doc("GGX α = roughness²; small values give sharp highlights"),
            ParamSpec::float("f0", "Fresnel F0", 0.0, 1.0, 0.04)
                .with_doc("reflectance at normal incidence (Schlick): 0.02–0.05 for dielectrics"),
            ParamSpec::boolean("two_sided", "Two-sided", true)
                .with_doc("flip normals towards the viewer (else n = −∇f/|∇f|)"),
            lighting::fade_param(),
        ];
        p.extend(lighting::light_params(4));
        p
    }
    fn shader(&self) -> ShaderSource {
        self.gradient.hook_source(
            "plugins/src/shade_cook_torrance/cook_torrance.wgsl",
            include_str!("cook_torrance.wgsl"),
        )
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        self.gradient.prepass()
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let gradient = GradientEstimator::from_params(params);
        (gradient != self.gradient).then(|| Arc::new(CookTorrance { gradient }) as Arc<dyn Plugin>)
    }
    /// Shading changes colours only.
    fn transparency(&self, _params: &ParamValues) -> Transparency {
        Transparency::Keeps
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(CookTorranceTwin {
            gradients: Gradients::new(self.gradient),
            brdf: Brdf::from_params(params),
            lights: lighting::lights(params, 4),
            two_sided: params.boolean("two_sided"),
            floor: params.float("gradient_floor") as f64,
        }))
    }
}

/// The material of `cook_torrance.wgsl`, in f64.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Brdf {
    pub ka: f64,
    pub kd: f64,
    pub ks: f64,
    pub roughness: f64,
    pub f0: f64,
}

impl Brdf {
    pub fn from_params(p: &ParamValues) -> Self {
        Self {
            ka: p.float("ka") as f64,
            kd: p.float("kd") as f64,
            ks: p.float("ks") as f64,
            roughness: p.float("roughness") as f64,
            f0: p.float("f0") as f64,
        }
    }

    fn alpha(&self) -> f64 {
        self.roughness * self.roughness
    }

    /// GGX D(h).
    pub fn d(&self, ndh: f64) -> f64 {
        let a2 = self.alpha() * self.alpha();
        let t = ndh * ndh * (a2 - 1.0) + 1.0;
        a2 / (std::f64::consts::PI * t * t)
    }

    /// Smith G1 for GGX.
    pub fn g1(&self, ndx: f64) -> f64 {
        let a2 = self.alpha() * self.alpha();
        2.0 * ndx / (ndx + (a2 + (1.0 - a2) * ndx * ndx).sqrt())
    }

    /// Schlick's Fresnel.
    pub fn f(&self, vdh: f64) -> f64 {
        self.f0 + (1.0 - self.f0) * (1.0 - vdh).powi(5)
    }

    /// `cook_torrance_factors`: (max(n·l, 0), π·D·G·F/(4 n·v)); zero where n·l ≤ 0 or
    /// n·v ≤ 0.
    pub fn factors(&self, n: DVec3, v: DVec3, l: DVec3) -> (f64, f64) {
        let (ndl, ndv) = (n.dot(l), n.dot(v));
        if !(ndl > 0.0 && ndv > 0.0) {
            return (0.0, 0.0);
        }
        let h = safe_normalize(l + v);
        let (ndh, vdh) = (n.dot(h).max(0.0), v.dot(h).max(0.0));
        let spec = std::f64::consts::PI * self.d(ndh) * self.g1(ndl) * self.g1(ndv) * self.f(vdh)
            / (4.0 * ndv);
        (ndl, spec)
    }
}

/// CPU twin of `cook_torrance.wgsl`.
pub struct CookTorranceTwin {
    pub gradients: Gradients,
    pub brdf: Brdf,
    pub lights: Vec<Light>,
    pub two_sided: bool,
    pub floor: f64,
}

impl CpuTwin for CookTorranceTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        self.gradients.prepare(ctx);
    }
    fn shade(&self, ctx: &CpuContext, s: &mut CpuSample) {
        if s.color.w <= 0.0 {
            return;
        }
        let v = -s.ray_dir;
        let (n, w) = shading_normal(self.gradients.at(ctx, s.tex), self.floor, v, self.two_sided);
        let (mut diffuse, mut specular) = (DVec3::ZERO, DVec3::ZERO);
        for l in &self.lights {
            let (d, sp) = self.brdf.factors(n, v, l.dir(ctx, s.pos));
            diffuse += l.color * (self.brdf.kd * d);
            specular += l.color * (self.brdf.ks * sp);
        }
        let base = s.color.truncate();
        let lit = base * (DVec3::splat(self.brdf.ka) + diffuse) + specular;
        s.color = DVec4::from((base.lerp(lit, w), s.color.w));
        s.normal = n;
    }
}
