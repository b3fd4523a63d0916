//! `sample.jitter`: per-pixel jitter of the slice positions, the first user of the
//! `setup` hook (once per ray, before its samples; `jitter.wgsl`). At coarse slice
//! spacing the view-aligned slices leave a wood-grain pattern of rings; moving every
//! sample of a pixel's ray by the same random fraction of the slice step (a different
//! one per pixel) trades that structured error for unstructured noise of the same
//! size, which the eye forgives and a later filter can remove (Keller & Heidrich 2001,
//! "Interleaved sampling": the offsets of a 4×4 block of pixels spread evenly over the
//! step). `experiments/slice_jitter.ron` measures the trade against the converged
//! reference.
//!
//! The offset is centred (amount·(u − ½) of the step), so that on average the samples
//! stay where the slices are. It does not split into bricks (a moved sample may read
//! beyond its brick). Its transparency promise is [`Transparency::Moves`] by amount/2
//! steps: a moved sample may read voxels beyond the brick it is tested in, so the
//! renderer takes the bricks' value ranges over an apron widened by that distance and
//! empty-space skipping stays on and exact (before session 49 skipping was off while
//! it was enabled, up to 1.6× the frame).

use glam::{DVec2, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuRay, CpuSample, CpuTwin, Plugin, ShaderSource, Transparency, Volumes,
};

#[cfg(test)]
mod tests;

/// The offset patterns, as `params.pattern` indexes them.
pub const PATTERNS: [&str; 2] = ["hash", "interleaved"];

pub struct Jitter;

impl Plugin for Jitter {
    fn id(&self) -> &'static str {
        "sample.jitter"
    }
    fn display_name(&self) -> &'static str {
        "Slice jitter"
    }
    fn description(&self) -> &'static str {
        "Moves each pixel's samples by a per-pixel fraction of the slice step: wood-grain rings become fine noise"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::enumeration("pattern", "Pattern", &PATTERNS, 0).with_doc(
                "hash: white noise per pixel; interleaved: a 4×4 ordered-dither matrix of 16 offsets",
            ),
            ParamSpec::float("amount", "Amount (steps)", 0.0, 1.0, 1.0)
                .with_doc("the offsets span this fraction of the slice step, centred on the slice"),
            ParamSpec::int("seed", "Seed", 0, 1_000_000, 1),
        ]
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource::new_static(
            "plugins/src/sample_jitter/jitter.wgsl",
            include_str!("jitter.wgsl"),
        )
    }
    fn transparency(&self, params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        // |amount·(u − ½)| < amount/2 of a step
        Transparency::Moves(0.5 * params.float("amount").abs() as f64)
    }
    fn splits_into_bricks(&self) -> bool {
        false
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(JitterTwin {
            interleaved: params.enumeration("pattern") == PATTERNS[1],
            amount: params.float("amount") as f64,
            seed: params.int("seed") as u32,
        }))
    }
}

/// CPU twin of `setup` and `sample`.
pub struct JitterTwin {
    pub interleaved: bool,
    pub amount: f64,
    pub seed: u32,
}

/// `jitter_hash`: the PCG output permutation on u32.
pub fn hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747796405).wrapping_add(2891336453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277803737);
    (word >> 22) ^ word
}

impl JitterTwin {
    /// `jitter_offset`: the offset in [0,1) of pixel `px`.
    pub fn offset(&self, px: [u32; 2]) -> f64 {
        if self.interleaved {
            let (x, y) = (px[0] & 3, px[1] & 3);
            let e = x ^ y;
            let b = ((e & 1) << 3) | ((y & 1) << 2) | (e & 2) | ((y >> 1) & 1);
            return (((b.wrapping_add(self.seed)) & 15) as f64 + 0.5) / 16.0;
        }
        let h = hash(px[0].wrapping_add(hash(px[1].wrapping_add(hash(self.seed)))));
        (h >> 8) as f64 / 16_777_216.0
    }
}

impl CpuTwin for JitterTwin {
    fn setup(&self, _ctx: &CpuContext, ray: &CpuRay) -> DVec4 {
        let px = pixel(ray.uv, ray.size);
        DVec4::new(self.amount * (self.offset(px) - 0.5), 0.0, 0.0, 0.0)
    }
    fn sample(&self, ctx: &CpuContext, s: &mut CpuSample) {
        let d = s.ray_record.x * s.step;
        if d == 0.0 {
            return;
        }
        let (lo, hi) = ctx.volume_box();
        s.pos += s.ray_dir * d;
        s.tex = ((s.pos - lo) / (hi - lo)).clamp(glam::DVec3::ZERO, glam::DVec3::ONE);
        s.value = ctx.value(s.tex);
    }
}

/// The pixel under `uv` in an image of `size` pixels (as `setup` finds it).
pub fn pixel(uv: DVec2, size: DVec2) -> [u32; 2] {
    let p = (uv * size).floor();
    [p.x as u32, p.y as u32]
}
