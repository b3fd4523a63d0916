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

use glam::DVec3;
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::CpuContext;
use vwb_render::shading::{Light, safe_normalize};

use crate::lighting::{Lit, LightingModel, LitColour};

#[cfg(test)]
mod tests;

/// The plugin: the model on the shared gradients, fade rule and lights.
pub type CookTorrance = Lit<CookTorranceModel>;

pub struct CookTorranceModel;

impl LightingModel for CookTorranceModel {
    const ID: &'static str = "shade.cook_torrance";
    const NAME: &'static str = "Cook–Torrance (GGX)";
    const DESCRIPTION: &'static str =
        "Microfacet reflection: GGX distribution, Smith masking, Schlick Fresnel";
    const FILE: &'static str = "plugins/src/shade_cook_torrance/cook_torrance.wgsl";
    const SOURCE: &'static str = include_str!("cook_torrance.wgsl");
    type Twin = Brdf;
    fn params() -> Vec<ParamSpec> {
        vec![
            ParamSpec::float("ka", "Ambient k_a", 0.0, 1.0, 0.2),
            ParamSpec::float("kd", "Diffuse k_d", 0.0, 1.0, 0.75)
                .with_doc("weight of the Lambertian base"),
            ParamSpec::float("ks", "Specular k_s", 0.0, 4.0, 1.0)
                .with_doc("weight of the microfacet term π·D·G·F/(4 n·v)"),
            ParamSpec::float("roughness", "Roughness", 0.05, 1.0, 0.35)
                .with_doc("GGX α = roughness²; small values give sharp highlights"),
            ParamSpec::float("f0", "Fresnel F0", 0.0, 1.0, 0.04)
                .with_doc("reflectance at normal incidence (Schlick): 0.02–0.05 for dielectrics"),
        ]
    }
    fn twin(params: &ParamValues) -> Brdf {
        Brdf::from_params(params)
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

/// The lit colour of `cook_torrance.wgsl`'s `shade`.
impl LitColour for Brdf {
    fn lit(
        &self,
        ctx: &CpuContext,
        lights: &[Light],
        base: DVec3,
        n: DVec3,
        v: DVec3,
        pos: DVec3,
    ) -> DVec3 {
        let (mut diffuse, mut specular) = (DVec3::ZERO, DVec3::ZERO);
        for l in lights {
            let (d, sp) = self.factors(n, v, l.dir(ctx, pos));
            diffuse += l.color * (self.kd * d);
            specular += l.color * (self.ks * sp);
        }
        base * (DVec3::splat(self.ka) + diffuse) + specular
    }
}
