use super::*;
use crate::lighting::testing::{BASE, constant, ramp_x, shaded, world_light};
use crate::shade_blinn_phong::BlinnPhong;
use vwb_render::params::ParamValue;

/// σ = 0 is Lambert's law: the same colour as Blinn–Phong without its specular term.
#[test]
fn smooth_surface_is_lambertian() {
    let dir = [-0.6, 0.5, 0.3];
    let mut p = world_light(&OrenNayar::default(), dir);
    p.set("sigma", ParamValue::Float(0.0));
    let mut q = world_light(&BlinnPhong::default(), dir);
    q.set("ks", ParamValue::Float(0.0));
    for k in ["ka", "kd"] {
        q.set(k, p.get(k).unwrap().clone());
    }
    for ray in [DVec3::X, DVec3::new(1.0, 0.4, -0.3).normalize()] {
        let on = shaded(&OrenNayar::default(), &ramp_x(9), &p, ray);
        let bp = shaded(&BlinnPhong::default(), &ramp_x(9), &q, ray);
        assert!((on - bp).length() < 1e-9, "{on} vs {bp}");
    }
}

/// Light and view along the normal: sin α = 0, so the factor is A = 1 − 0.5σ²/(σ² + 0.33).
#[test]
fn head_on_factor_is_a() {
    let sigma: f64 = 0.5;
    let p = {
        let mut p = world_light(&OrenNayar::default(), [-1.0, 0.0, 0.0]);
        p.set("sigma", ParamValue::Float(sigma as f32));
        p
    };
    let c = shaded(&OrenNayar::default(), &ramp_x(9), &p, DVec3::X);
    let a = 1.0 - 0.5 * sigma * sigma / (sigma * sigma + 0.33);
    let (ka, kd) = (p.float("ka") as f64, p.float("kd") as f64);
    let expect = BASE.truncate() * (ka + kd * a);
    assert!((c.truncate() - expect).length() < 1e-6, "{c} vs {expect}");
}

/// Rough surfaces scatter back towards the light: with light and viewer together at
/// 60° from the normal, the rough factor exceeds Lambert's cos θ; with them on
/// opposite sides it falls below.
#[test]
fn rough_surfaces_scatter_back() {
    let n = DVec3::Z;
    let t = 60f64.to_radians();
    let l = DVec3::new(t.sin(), 0.0, t.cos());
    let lambert = t.cos();
    let back = oren_nayar_factor(0.5, n, l, l);
    let forward = oren_nayar_factor(0.5, n, DVec3::new(-t.sin(), 0.0, t.cos()), l);
    assert!(back > lambert * 1.1, "{back} vs {lambert}");
    assert!(forward < lambert, "{forward} vs {lambert}");
    // the closed form for θi = θr = θ, φi = φr: cos θ (A + B sin θ tan θ)
    let s2: f64 = 0.25;
    let (a, b) = (1.0 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09));
    let expect = t.cos() * (a + b * t.sin() * t.tan());
    assert!((back - expect).abs() < 1e-12, "{back} vs {expect}");
}

#[test]
fn grazing_and_back_lit_are_finite_and_no_gradient_is_unlit() {
    let n = DVec3::Z;
    let graze = DVec3::new(1.0, 0.0, 1e-9).normalize();
    for sigma in [0.0, 0.5, 1.5] {
        for (v, l) in [(graze, DVec3::Z), (DVec3::Z, graze), (graze, graze), (-DVec3::Z, DVec3::Z)] {
            let f = oren_nayar_factor(sigma, n, v, l);
            assert!(f.is_finite() && (0.0..=1.5).contains(&f), "σ {sigma} {v} {l}: {f}");
        }
        assert_eq!(oren_nayar_factor(sigma, n, DVec3::Z, -DVec3::Z), 0.0);
    }
    let p = world_light(&OrenNayar::default(), [-1.0, 0.0, 0.0]);
    assert_eq!(shaded(&OrenNayar::default(), &constant(6), &p, DVec3::X), BASE);
}
