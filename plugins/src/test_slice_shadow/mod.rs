//! `test.slice_shadow`: a small plugin with per-slice state, proving the slice loop's
//! ping-pong passes (the pattern directional occlusion shading builds on).
//!
//! State: the opacity accumulated in front of the current slice, per pixel (rgba32float,
//! eye-buffer resolution). `shade` multiplies the colour by 1 − strength·state.
//! Closed form for a homogeneous medium along a ray (per-slice opacity a, colour c):
//! slice k sees state A_k = 1 − (1 − a)^k and contributes c·a·(1 − A_k)·(1 − s·A_k).

use vwb_render::params::ParamSpec;
use vwb_render::plugin::{Plugin, ShaderSource, SliceStateDecl, StorageFormat};

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
        })
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
