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

use std::sync::Arc;

use glam::{DVec3, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, Plugin, PrepassDecl, ShaderSource, Transparency,
};
use vwb_render::shading::{GradientEstimator, Gradients, Light, shading_normal};

use crate::lighting;

#[cfg(test)]
mod tests;

#[derive(Debug, Clone, Copy, Default)]
pub struct Toon {
    pub gradient: GradientEstimator,
}

impl Plugin for Toon {
    fn id(&self) -> &'static str {
        "shade.toon"
    }
    fn display_name(&self) -> &'static str {
        "Toon (cel shading)"
    }
    fn description(&self) -> &'static str {
        "Banded diffuse light with an outline where surfaces are seen edge-on"
    }
    fn params(&self) -> Vec<ParamSpec> {
        let mut p = vec![
            GradientEstimator::param(),
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
            ParamSpec::boolean("two_sided", "Two-sided", true)
                .with_doc("flip normals towards the viewer (else n = −∇f/|∇f|)"),
            lighting::fade_param(),
        ];
        p.extend(lighting::light_params(4));
        p
    }
    fn shader(&self) -> ShaderSource {
        self.gradient
            .hook_source("plugins/src/shade_toon/toon.wgsl", include_str!("toon.wgsl"))
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        self.gradient.prepass()
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let gradient = GradientEstimator::from_params(params);
        (gradient != self.gradient).then(|| Arc::new(Toon { gradient }) as Arc<dyn Plugin>)
    }
    /// Shading changes colours only.
    fn transparency(&self, _params: &ParamValues) -> Transparency {
        Transparency::Keeps
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(ToonTwin {
            gradients: Gradients::new(self.gradient),
            style: ToonStyle::from_params(params),
            lights: lighting::lights(params, 4),
            two_sided: params.boolean("two_sided"),
            floor: params.float("gradient_floor") as f64,
        }))
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

/// CPU twin of `toon.wgsl`.
pub struct ToonTwin {
    pub gradients: Gradients,
    pub style: ToonStyle,
    pub lights: Vec<Light>,
    pub two_sided: bool,
    pub floor: f64,
}

impl CpuTwin for ToonTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        self.gradients.prepare(ctx);
    }
    fn shade(&self, ctx: &CpuContext, s: &mut CpuSample) {
        if s.color.w <= 0.0 {
            return;
        }
        let st = &self.style;
        let v = -s.ray_dir;
        let (n, w) = shading_normal(self.gradients.at(ctx, s.tex), self.floor, v, self.two_sided);
        let d: DVec3 = self
            .lights
            .iter()
            .map(|l| l.color * (st.kd * st.level(n.dot(l.dir(ctx, s.pos)).max(0.0))))
            .sum();
        let base = s.color.truncate();
        let banded = base * (DVec3::splat(st.ka) + d);
        let toon = banded.lerp(st.outline.truncate(), st.edge(n.dot(v)) * st.outline.w);
        s.color = DVec4::from((base.lerp(toon, w), s.color.w));
        s.normal = n;
    }
}
