//! `shade.isosurface`: non-polygonal isosurfaces (Rezk-Salama 2001 §7.2, Westermann and
//! Ertl): up to four isovalues, each with a colour and an opacity, shaded with
//! Blinn–Phong under a view-space head light (two-sided: the normal faces the viewer)
//! and combined with the DVR colour the classification gave the sample.
//!
//! Two methods (`method`):
//! - `alpha_test` — the thesis's: a sample passes when its value is ≥ the isovalue
//!   (GL_GEQUAL, which "allows a considerable reduction of the sampling rate" over
//!   GL_EQUAL); it takes the colour of the highest isovalue it passes. With opaque
//!   surfaces the first passing slice is the surface (depth error ≤ one slice); with
//!   opacity < 1 the inside fills up slice by slice, as blending the alpha-tested
//!   fragments would.
//! - `crossing` (default) — our choice for semi-transparent and nested surfaces: a
//!   surface is met where the value crosses the isovalue between the sample and the
//!   next slice along the ray (exactly one of f(s), f(s + Δ) below it); it is shaded at
//!   the linearly interpolated crossing point and composited once per crossing, so its
//!   opacity does not depend on the slice spacing. Several crossings in one step are
//!   taken front to back.
//!
//! Compositing inside a step: crossing: the sample's DVR contribution (opacity
//! corrected for the step), then the surfaces; alpha test: the surface, then the DVR
//! contribution. The result is handed back as a straight colour with opacity per Δs0
//! (α0 = 1 − (1 − A)^(Δs0/Δs)), so that the core's opacity correction restores A.

use std::sync::Arc;

use glam::{DVec3, DVec4};
use vwb_render::params::{Group, ParamSpec, ParamValues};
use vwb_render::plugin::{CpuContext, CpuSample, CpuTwin, Plugin, PrepassDecl, ShaderSource};
use vwb_render::shading::{
    GradientEstimator, Gradients, Light, Material, blinn_phong_factors,
};

use vwb_render::reference::correct_opacity;

use crate::lighting;

#[cfg(test)]
mod tests;

/// The four isosurfaces, a parameter group: surface i's isovalue `iso{i}` and colour
/// `color{i}`; `count` of them are in use.
pub const SURFACES: Group = Group::new("Isosurface", 4).limit("count");

const ISO_DEFAULTS: [(f32, [f32; 4]); 4] = [
    (0.3, [0.95, 0.8, 0.65, 1.0]),
    (0.5, [1.0, 1.0, 0.95, 1.0]),
    (0.7, [0.8, 0.3, 0.2, 1.0]),
    (0.9, [0.3, 0.4, 0.9, 1.0]),
];

#[derive(Debug, Clone, Copy, Default)]
pub struct Isosurface {
    pub gradient: GradientEstimator,
}

impl Plugin for Isosurface {
    fn id(&self) -> &'static str {
        "shade.isosurface"
    }
    fn display_name(&self) -> &'static str {
        "Isosurfaces"
    }
    fn description(&self) -> &'static str {
        "Non-polygonal shaded isosurfaces (alpha test or crossing), over the DVR colour"
    }
    fn params(&self) -> Vec<ParamSpec> {
        let mut p = vec![
            GradientEstimator::param(),
            ParamSpec::enumeration("method", "Method", &["crossing", "alpha_test"], 0)
                .with_doc("crossing: the value crosses the isovalue before the next slice; alpha_test: value ≥ isovalue (thesis)"),
            ParamSpec::int("count", "Isovalues", 1, 4, 1),
        ];
        p.extend(SURFACES.specs(|i| {
            let (v, c) = ISO_DEFAULTS[i];
            vec![
                ParamSpec::float(SURFACES.key("iso{}", i), "Isovalue", 0.0, 1.0, v)
                    .with_doc("normalised value of the surface"),
                ParamSpec::color(SURFACES.key("color{}", i), "Surface colour and opacity", c),
            ]
        }));
        p.extend(lighting::material_params(0.2, 0.8, 0.4, 32.0));
        p.push(lighting::head_light_param());
        p.push(lighting::fade_param());
        p
    }
    fn shader(&self) -> ShaderSource {
        self.gradient.hook_source(
            "plugins/src/shade_isosurface/isosurface.wgsl",
            include_str!("isosurface.wgsl"),
        )
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        self.gradient.prepass()
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let gradient = GradientEstimator::from_params(params);
        (gradient != self.gradient).then(|| Arc::new(Isosurface { gradient }) as Arc<dyn Plugin>)
    }
    /// Over its `count` isovalues: the crossing test (each crossing sorted in by an
    /// insertion loop of at most `count` passes) and the surfaces found, each loop with
    /// its end.
    fn loop_iterations(&self, params: &ParamValues) -> vwb_render::plugin::LoopIterations {
        let count = surface_count(params) as u32;
        vwb_render::plugin::LoopIterations {
            sample: (count + 1) * (count + 3),
            scalar: 0,
        }
    }
    /// Surfaces make opacity where the classification gave none, only where a sample
    /// meets one: `crossing` where the values at the sample and one slice step ahead
    /// straddle an isovalue (lo < iso ≤ hi of a range holding both), `alpha_test` where
    /// the sample's value reaches it (iso ≤ hi), for the surfaces in use whose opacity
    /// is above 0. Filtered values can pass a range's ends by rounding: the test widens
    /// it by [`ISO_MARGIN`].
    fn transparency(
        &self,
        params: &ParamValues,
        _volumes: &vwb_render::inputs::Volumes<'_>,
    ) -> vwb_render::plugin::Transparency {
        let count = surface_count(params);
        let alpha_test = params.enumeration("method") == "alpha_test";
        let isos: Vec<f64> = surfaces(params, count)
            .into_iter()
            .filter(|(_, c)| c.w.clamp(0.0, 1.0) > 0.0)
            .map(|(iso, _)| iso)
            .collect();
        let meets = move |lo: f64, hi: f64| {
            isos.iter().any(|&iso| {
                iso <= hi + ISO_MARGIN && (alpha_test || lo - ISO_MARGIN < iso)
            })
        };
        vwb_render::plugin::Transparency::Adds(
            Arc::new(meets),
            if alpha_test { 0.0 } else { 1.0 },
        )
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        let count = surface_count(params);
        Some(Box::new(IsosurfaceTwin {
            gradients: Gradients::new(self.gradient),
            alpha_test: params.enumeration("method") == "alpha_test",
            surfaces: surfaces(params, count),
            material: lighting::material(params),
            light: lighting::head_light(params),
            floor: params.float("gradient_floor") as f64,
        }))
    }
}

/// How far a filtered value may pass its voxels' range by rounding, in normalised
/// units, for the transparency promise (f32 weights sum to 1 within a few ulps).
pub const ISO_MARGIN: f64 = 1.0e-5;

/// How many surfaces are in use: `count`, within the group's 1…4.
fn surface_count(params: &ParamValues) -> usize {
    params.int("count").clamp(1, 4) as usize
}

/// The first `count` surfaces: (isovalue, colour with opacity).
pub fn surfaces(params: &ParamValues, count: usize) -> Vec<(f64, DVec4)> {
    (0..count)
        .map(|i| {
            (
                params.float(SURFACES.key("iso{}", i)) as f64,
                DVec4::from(params.color(SURFACES.key("color{}", i)).map(f64::from)),
            )
        })
        .collect()
}

/// CPU twin of `isosurface.wgsl`.
pub struct IsosurfaceTwin {
    pub gradients: Gradients,
    pub alpha_test: bool,
    /// (isovalue, colour with opacity) per surface.
    pub surfaces: Vec<(f64, DVec4)>,
    pub material: Material,
    pub light: Light,
    pub floor: f64,
}

impl IsosurfaceTwin {
    fn surface_rgb(&self, ctx: &CpuContext, c: DVec3, tex: DVec3, pos: DVec3, v: DVec3) -> DVec3 {
        let (_, n, w) = self.gradients.normal(ctx, tex, self.floor, v, true);
        let (d, s) = blinn_phong_factors(n, v, self.light.dir(ctx, pos), self.material.shininess);
        let m = &self.material;
        let lit = c * (m.ka + m.kd * d) + DVec3::splat(m.ks * s);
        c.lerp(lit, w)
    }

    /// The surfaces met in the step after `s`: (t, index), front to back.
    pub fn hits(&self, ctx: &CpuContext, s: &CpuSample, dir_tex: DVec3) -> Vec<(f64, usize)> {
        let f0 = s.value;
        if self.alpha_test {
            let best = self
                .surfaces
                .iter()
                .enumerate()
                .filter(|(_, (iso, _))| f0 >= *iso)
                .fold(None::<(usize, f64)>, |b, (i, (iso, _))| match b {
                    Some((_, v)) if *iso <= v => b,
                    _ => Some((i, *iso)),
                });
            return best.map(|(i, _)| vec![(0.0, i)]).unwrap_or_default();
        }
        let f1 = ctx.value(s.tex + dir_tex);
        let mut hits: Vec<(f64, usize)> = self
            .surfaces
            .iter()
            .enumerate()
            .filter(|(_, (iso, _))| (f0 < *iso) != (f1 < *iso))
            .map(|(i, (iso, _))| (((iso - f0) / (f1 - f0)).clamp(0.0, 1.0), i))
            .collect();
        // stable, like the GPU's insertion sort
        hits.sort_by(|a, b| a.0.total_cmp(&b.0));
        hits
    }
}

impl CpuTwin for IsosurfaceTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        self.gradients.prepare(ctx);
    }
    fn shade(&self, ctx: &CpuContext, s: &mut CpuSample) {
        let (lo, hi) = ctx.volume_box();
        let dir_tex = s.ray_dir * s.step / (hi - lo);
        let hits = self.hits(ctx, s, dir_tex);
        if hits.is_empty() {
            return;
        }
        let v = -s.ray_dir;
        let ratio = s.step / ctx.reference_step();
        let a_d = correct_opacity(s.color.w, ratio);
        let dvr = (s.color.truncate() * a_d).extend(a_d);
        let mut acc = if self.alpha_test { DVec4::ZERO } else { dvr };
        for (t, i) in hits {
            let c = self.surfaces[i].1;
            let a = c.w.clamp(0.0, 1.0);
            let rgb = self.surface_rgb(
                ctx,
                c.truncate(),
                s.tex + dir_tex * t,
                s.pos + s.ray_dir * (t * s.step),
                v,
            );
            acc += (1.0 - acc.w) * (rgb * a).extend(a);
        }
        if self.alpha_test {
            acc += (1.0 - acc.w) * dvr;
        }
        if acc.w >= 1.0 {
            s.color = (acc.truncate() / acc.w.max(1e-30)).extend(1.0);
        } else if acc.w > 0.0 {
            s.color = (acc.truncate() / acc.w).extend(1.0 - (1.0 - acc.w).powf(1.0 / ratio));
        }
    }
}
