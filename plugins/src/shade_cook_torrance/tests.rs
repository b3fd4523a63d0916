use super::*;
use crate::lighting::testing::{BASE, constant, ramp_x, shaded, world_light};
use crate::shade_blinn_phong::BlinnPhong;
use vwb_render::params::ParamValue;

fn brdf(roughness: f64) -> Brdf {
    Brdf {
        ka: 0.0,
        kd: 1.0,
        ks: 1.0,
        roughness,
        f0: 0.04,
    }
}

/// GGX is a normalised distribution of microfacet normals: ∫ D(h)(n·h) dω_h = 1 over
/// the hemisphere, for every roughness.
#[test]
fn ggx_distribution_is_normalised() {
    for r in [0.2, 0.35, 0.6, 1.0] {
        let b = brdf(r);
        let n = 20_000;
        // substitute μ = cos θ: ∫₀¹ D(μ) μ 2π dμ, midpoint rule
        let sum: f64 = (0..n)
            .map(|i| {
                let mu = (i as f64 + 0.5) / n as f64;
                b.d(mu) * mu * 2.0 * std::f64::consts::PI / n as f64
            })
            .sum();
        assert!((sum - 1.0).abs() < 2e-3, "roughness {r}: ∫D cos = {sum}");
    }
}

#[test]
fn smith_and_schlick_limits() {
    let b = brdf(0.5);
    assert!((b.g1(1.0) - 1.0).abs() < 1e-12);
    assert_eq!(b.g1(0.0), 0.0);
    for i in 1..100 {
        let x = i as f64 / 100.0;
        assert!(b.g1(x) > 0.0 && b.g1(x) < 1.0 + 1e-12 && b.g1(x) < b.g1(x + 0.01) + 1e-12);
    }
    assert!((b.f(1.0) - 0.04).abs() < 1e-12, "F(0°) = F0");
    assert!((b.f(0.0) - 1.0).abs() < 1e-12, "F(90°) = 1");
}

/// Light, view and normal aligned: D = 1/(πα²), G = 1, F = F0, so the specular
/// factor is π·D·F/4 = F0/(4α²), and the colour is base·(k_a + k_d) + k_s·F0/(4α²).
#[test]
fn head_on_highlight_has_its_closed_form() {
    let p = world_light(&CookTorrance::default(), [-1.0, 0.0, 0.0]);
    let c = shaded(&CookTorrance::default(), &ramp_x(9), &p, DVec3::X);
    let b = Brdf::from_params(&p);
    let a2 = b.roughness.powi(4);
    let expect = BASE.truncate() * (b.ka + b.kd) + DVec3::splat(b.ks * b.f0 / (4.0 * a2));
    assert!((c.truncate() - expect).length() < 1e-5, "{c} vs {expect}");
    assert_eq!(c.w, BASE.w, "opacity is unchanged");
}

/// Without the specular term the model is Lambert's, the diffuse term of Blinn–Phong.
#[test]
fn without_specular_it_is_the_lambertian_of_blinn_phong() {
    let dir = [-0.6, 0.5, 0.3];
    let mut p = world_light(&CookTorrance::default(), dir);
    p.set("ks", ParamValue::Float(0.0));
    let mut q = world_light(&BlinnPhong::default(), dir);
    q.set("ks", ParamValue::Float(0.0));
    for k in ["ka", "kd"] {
        q.set(k, p.get(k).unwrap().clone());
    }
    let ray = DVec3::new(1.0, 0.2, -0.1).normalize();
    let ct = shaded(&CookTorrance::default(), &ramp_x(9), &p, ray);
    let bp = shaded(&BlinnPhong::default(), &ramp_x(9), &q, ray);
    assert!((ct - bp).length() < 1e-9, "{ct} vs {bp}");
}

/// Rough surfaces spread the highlight: off the mirror direction a rough surface is
/// brighter than a smooth one, at the mirror direction dimmer.
#[test]
fn roughness_spreads_the_highlight() {
    let n = DVec3::Z;
    let l = DVec3::new(0.5, 0.0, 1.0).normalize();
    let mirror = DVec3::new(-0.5, 0.0, 1.0).normalize();
    let off = DVec3::new(-0.2, 0.6, 1.0).normalize();
    let (smooth, rough) = (brdf(0.2), brdf(0.7));
    assert!(smooth.factors(n, mirror, l).1 > rough.factors(n, mirror, l).1);
    assert!(smooth.factors(n, off, l).1 < rough.factors(n, off, l).1);
    // back-facing light or view: nothing
    assert_eq!(rough.factors(n, mirror, -l), (0.0, 0.0));
    assert_eq!(rough.factors(n, -mirror, l), (0.0, 0.0));
}

/// Extremes: the smallest roughness and grazing angles stay finite; no gradient means
/// the unlit colour.
#[test]
fn extremes_stay_finite_and_no_gradient_is_unlit() {
    let b = brdf(0.05);
    let n = DVec3::Z;
    for (v, l) in [
        (DVec3::Z, DVec3::Z),
        (DVec3::new(1.0, 0.0, 1e-6).normalize(), DVec3::Z),
        (DVec3::new(1.0, 0.0, 1e-6).normalize(), DVec3::new(-1.0, 0.0, 1e-6).normalize()),
    ] {
        let (d, s) = b.factors(n, v, l);
        assert!(d.is_finite() && s.is_finite() && s >= 0.0, "{v} {l}: {d} {s}");
    }
    let p = world_light(&CookTorrance::default(), [-1.0, 0.0, 0.0]);
    let c = shaded(&CookTorrance::default(), &constant(6), &p, DVec3::X);
    assert_eq!(c, BASE);
}
