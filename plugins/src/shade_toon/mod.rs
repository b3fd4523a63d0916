//! `shade.toon`: cel shading. Per light of colour L, the diffuse factor d = max(n·l, 0)
//! is quantised into `bands` levels q(d) = Σₖ smoothstep(k/B − s, k/B + s, d)/(B − 1),
//! k = 1…B − 1 (B = bands, s = softness), and rgb = base·(k_a + Σ L·k_d·q(d)). An outline
//! replaces the colour where the iso-surface through the sample is seen edge-on: with
//! e = 1 − smoothstep(w − s, w + s, |n·v|) (w = outline width) the colour becomes
//! mix(rgb, outline.rgb, e·outline.a), so the outline colour's alpha is its strength
//! (0 turns it off). *Choice:* the steps are smooth (softness ≥ 0.005) rather than hard,
//! because a hard step aliases along the slices of a volume and makes the GPU image
//! depend on f32 rounding at the thresholds. The gradient is the normal (shared
//! estimators and fade rule); opacity is unchanged.

use glam::{DVec3, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::CpuContext;
use vwb_render::shading::Light;

use crate::lighting::{Lit, LightingModel, LitColour};

#[cfg(test)]
mod tests;

/// The plugin: the model on the shared gradients, fade rule and lights.
pub type Toon = Lit<ToonModel>;

pub struct ToonModel;

impl LightingModel for ToonModel {
    const ID: &'static str = "shade.toon";
    const NAME: &'static str = "Toon (cel shading)";
    const DESCRIPTION: &'static str =
        "Banded diffuse light with an outline where surfaces are seen edge-on";
    const FILE: &'static str = "plugins/src/shade_toon/toon.wgsl";
    const SOURCE: &'static str = include_str!("toon.wgsl");
    type Twin = ToonStyle;
    fn params() -> Vec<ParamSpec> {
        vec![
            ParamSpec::float("ka", "Ambient k_a", 0.0, 1.0, 0.3),
            ParamSpec::float("kd", "Diffuse k_d", 0.0, 1.0, 0.7),
            ParamSpec::int("bands", "Bands", 2, 8, 3)
                .with_doc("number of diffuse levels, from unlit to fully lit"),
            ParamSpec::float_log("softness", "Step softness", 0.005, 0.2, 0.03)
                .with_doc("half-width of the smooth step between bands and at the outline"),
            ParamSpec::float("outline_width", "Outline width", 0.0, 1.0, 0.3)
                .with_doc("outline where |n·v| is below this (the surface is seen edge-on)"),
            ParamSpec::color("outline_color", "Outline colour", [0.05, 0.05, 0.08, 1.0])
                .with_doc("its alpha is the outline's strength; 0 turns the outline off"),
        ]
    }
    fn twin(params: &ParamValues) -> ToonStyle {
        ToonStyle::from_params(params)
    }
    /// `toon_level`'s loop over the band thresholds: bands − 1 passes and its end.
    fn loop_iterations_per_light(params: &ParamValues) -> u32 {
        params.int("bands").max(2) as u32
    }
}

/// WGSL's `smoothstep`.
fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The toon parameters of `toon.wgsl`, in f64.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToonStyle {
    pub ka: f64,
    pub kd: f64,
    pub bands: i32,
    pub softness: f64,
    pub outline_width: f64,
    pub outline: DVec4,
}

impl ToonStyle {
    pub fn from_params(p: &ParamValues) -> Self {
        Self {
            ka: p.float("ka") as f64,
            kd: p.float("kd") as f64,
            bands: p.int("bands"),
            softness: p.float("softness") as f64,
            outline_width: p.float("outline_width") as f64,
            outline: DVec4::from(p.color("outline_color").map(f64::from)),
        }
    }

    /// `toon_level`: d quantised into `bands` levels.
    pub fn level(&self, d: f64) -> f64 {
        let b = self.bands.max(2);
        let q: f64 = (1..b)
            .map(|k| {
                let t = k as f64 / b as f64;
                smoothstep(t - self.softness, t + self.softness, d)
            })
            .sum();
        q / (b - 1) as f64
    }

    /// The outline weight e for |n·v|.
    pub fn edge(&self, n_dot_v: f64) -> f64 {
        let w = self.outline_width;
        1.0 - smoothstep(w - self.softness, w + self.softness, n_dot_v.abs())
    }
}

/// The lit colour of `toon.wgsl`'s `shade`.
impl LitColour for ToonStyle {
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
            .map(|l| l.color * (self.kd * self.level(n.dot(l.dir(ctx, pos)).max(0.0))))
            .sum();
        let banded = base * (DVec3::splat(self.ka) + d);
        banded.lerp(self.outline.truncate(), self.edge(n.dot(v)) * self.outline.w)
    }
}
