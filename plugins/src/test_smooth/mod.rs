//! `test.smooth`: a small plugin with a pre-pass that writes a 3D texture (a box-filtered
//! copy of the volume, r32float), read back by its `sample` hook. The pre-pass reruns
//! only when `radius` changes (or the volume); changing `amount` only rewrites uniforms.

use glam::DVec3;
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, Plugin, PrepassDecl, ShaderSource, StorageFormat,
};

pub struct Smooth;

impl Plugin for Smooth {
    fn id(&self) -> &'static str {
        "test.smooth"
    }
    fn display_name(&self) -> &'static str {
        "Box smoothing (pre-pass demo)"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::int("radius", "Radius (voxels)", 0, 3, 1),
            ParamSpec::float("amount", "Amount", 0.0, 1.0, 1.0),
        ]
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource::new_static(
            "plugins/src/test_smooth/smooth.wgsl",
            include_str!("smooth.wgsl"),
        )
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        Some(PrepassDecl {
            target: "smoothed",
            format: StorageFormat::R32Float,
            scale: 1.0,
            shader: ShaderSource::new_static(
                "plugins/src/test_smooth/prepass.wgsl",
                include_str!("prepass.wgsl"),
            ),
            depends_on: vec!["radius"],
            holds_value: false,
        })
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(SmoothTwin {
            radius: params.int("radius"),
            amount: params.float("amount") as f64,
        }))
    }
}

pub struct SmoothTwin {
    pub radius: i32,
    pub amount: f64,
}

impl SmoothTwin {
    /// Box-filtered value at a voxel, clamped at the borders (the pre-pass).
    pub fn smoothed_voxel(&self, ctx: &CpuContext, v: [i64; 3]) -> f64 {
        let d = ctx.volume.dims.map(|x| x as i64);
        let r = self.radius as i64;
        let mut sum = 0.0;
        for z in -r..=r {
            for y in -r..=r {
                for x in -r..=r {
                    let p = [v[0] + x, v[1] + y, v[2] + z];
                    let c: Vec<usize> = (0..3).map(|a| p[a].clamp(0, d[a] - 1) as usize).collect();
                    sum += ctx.scalars[(c[2] * d[1] as usize + c[1]) * d[0] as usize + c[0]] as f64;
                }
            }
        }
        sum / ((2 * r + 1).pow(3)) as f64
    }

    /// Trilinear interpolation of the smoothed volume (as the GPU samples `smoothed`).
    pub fn smoothed(&self, ctx: &CpuContext, tex: DVec3) -> f64 {
        let d = ctx.volume.dims;
        let mut i0 = [0i64; 3];
        let mut t = [0.0; 3];
        for a in 0..3 {
            let n = d[a].max(1) as f64;
            let x = (tex[a] * n - 0.5).clamp(0.0, n - 1.0);
            i0[a] = x.floor() as i64;
            t[a] = x - x.floor();
        }
        let mut acc = 0.0;
        for corner in 0..8 {
            let o = [
                (corner & 1) as i64,
                ((corner >> 1) & 1) as i64,
                ((corner >> 2) & 1) as i64,
            ];
            let mut w = 1.0;
            let mut v = [0i64; 3];
            for a in 0..3 {
                w *= if o[a] == 1 { t[a] } else { 1.0 - t[a] };
                v[a] = (i0[a] + o[a]).min(d[a] as i64 - 1);
            }
            if w > 0.0 {
                acc += w * self.smoothed_voxel(ctx, v);
            }
        }
        acc
    }
}

impl CpuTwin for SmoothTwin {
    fn sample(&self, ctx: &CpuContext, s: &mut CpuSample) {
        let sm = self.smoothed(ctx, s.tex);
        s.value += (sm - s.value) * self.amount;
    }
}
