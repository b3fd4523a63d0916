//! `test.slice_shadow`: a small plugin with per-slice state, proving the slice loop's
//! ping-pong passes (the pattern directional occlusion shading builds on).
//!
//! State: the opacity accumulated in front of the current slice, per pixel (rgba32float,
//! eye-buffer resolution). `shade` multiplies the colour by 1 − strength·state.
//! Closed form for a homogeneous medium along a ray (per-slice opacity a, colour c):
//! slice k sees state A_k = 1 − (1 − a)^k and contributes c·a·(1 − A_k)·(1 − s·A_k).

use glam::{DVec2, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, Plugin, ShaderSource, SliceStateDecl, StorageFormat,
    Transparency, Volumes,
};

pub struct SliceShadow;

impl Plugin for SliceShadow {
    fn id(&self) -> &'static str {
        "test.slice_shadow"
    }
    fn display_name(&self) -> &'static str {
        "Slice shadow (per-slice state demo)"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![ParamSpec::float("strength", "Strength", 0.0, 1.0, 1.0)]
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource::new_static(
            "plugins/src/test_slice_shadow/slice_shadow.wgsl",
            include_str!("slice_shadow.wgsl"),
        )
    }
    fn slice_state(&self) -> Option<SliceStateDecl> {
        Some(SliceStateDecl {
            format: StorageFormat::Rgba32Float,
            scale: 1.0,
            clear: [0.0; 4],
            light: false,
            track_clear: false,
        })
    }
    /// `shade` scales the colour only and `slice_update` reads only the contribution's
    /// opacity, so transparent samples stay without effect.
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(SliceShadowTwin {
            strength: params.float("strength") as f64,
        }))
    }
}

/// CPU twin of `slice_shadow.wgsl`.
pub struct SliceShadowTwin {
    pub strength: f64,
}

impl CpuTwin for SliceShadowTwin {
    fn shade(&self, ctx: &CpuContext, s: &mut CpuSample) {
        let occ = ctx.state_prev(ctx.view.state_coord(s)).x;
        let k = 1.0 - self.strength * occ;
        s.color = DVec4::new(s.color.x * k, s.color.y * k, s.color.z * k, s.color.w);
    }

    fn slice_update(&self, ctx: &CpuContext, _s: &CpuSample, c: DVec4, uv: DVec2) -> DVec4 {
        let prev = ctx.state_prev(uv).x;
        DVec4::new(prev + (1.0 - prev) * c.w, 0.0, 0.0, 1.0)
    }
}

/// Closed-form image value along one ray through a homogeneous medium (f64):
/// `n` slices of straight colour `c` and per-slice opacity `a`, strength `s`.
pub fn homogeneous(c: f64, a: f64, n: u32, s: f64) -> (f64, f64) {
    let mut col = 0.0;
    let mut acc = 0.0;
    for _ in 0..n {
        let shaded = c * (1.0 - s * acc);
        col += (1.0 - acc) * a * shaded;
        acc += (1.0 - acc) * a;
    }
    (col, acc)
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use vwb_render::camera::{Camera, Projection};
    use vwb_render::params::ParamValue;
    use vwb_render::plugin::PluginInstance;
    use vwb_render::reference::{ReferenceOptions, render_reference};
    use vwb_render::renderer::FrameSettings;
    use vwb_render::tf::{TfCurve, TfPoint};
    use vwb_render::volume::{Volume, VoxelData};

    use super::*;

    /// The slice-by-slice CPU reference reproduces the closed form through a
    /// homogeneous slab, with the state read back through `state_prev`.
    #[test]
    fn reference_matches_closed_form() {
        let n = 16u32;
        let volume = Volume::new(
            "slab",
            [n; 3],
            1,
            [1.0; 3],
            VoxelData::F32(vec![0.5; (n * n * n) as usize]),
        )
        .unwrap();
        let (c, a) = (0.8f32, 0.1f32);
        let mut tf = PluginInstance::new(Arc::new(crate::classify_tf1d::Tf1d::default()));
        let point = |x| TfPoint {
            x,
            color: [c, c, c, a],
        };
        tf.params.set(
            "tf",
            ParamValue::Tf(TfCurve::new(vec![point(0.0), point(1.0)])),
        );
        for strength in [0.0, 0.5, 1.0] {
            let mut shadow = PluginInstance::new(Arc::new(SliceShadow));
            shadow.params.set("strength", ParamValue::Float(strength));
            let mut camera = Camera {
                projection: Projection::Orthographic { height: 1.5 },
                ..Default::default()
            };
            camera.axis_view(2, false);
            let settings = FrameSettings {
                camera,
                width: 33,
                height: 33,
                slice_spacing: 0.75,
                ..Default::default()
            };
            let img = render_reference(
                &volume,
                &[tf.clone(), shadow],
                &settings,
                &ReferenceOptions::default(),
            )
            .unwrap();
            assert_eq!(img.slices, 21);
            let alpha = 1.0 - (1.0 - a as f64).powf(0.75);
            let (col, acc) = homogeneous(c as f64, alpha, 21, strength as f64);
            let got = img.pixel(16, 16);
            assert!(
                (got[0] - col).abs() < 1e-6,
                "s={strength}: {} vs {col}",
                got[0]
            );
            assert!(
                (got[3] - acc).abs() < 1e-6,
                "s={strength}: {} vs {acc}",
                got[3]
            );
        }
    }
}
