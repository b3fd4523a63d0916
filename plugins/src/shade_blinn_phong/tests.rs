use super::*;
use glam::DVec3;
use vwb_render::params::ParamValue;
use vwb_render::volume::{Volume, VoxelData};

/// f = x/(n − 1): ∇f points along +x, so the outward normal is −x.
fn ramp_x(n: u32) -> Volume {
    let data = (0..n * n * n).map(|i| (i % n) as f32).collect();
    Volume::new("ramp", [n; 3], 1, [1.0; 3], VoxelData::F32(data)).unwrap()
}

fn constant(n: u32) -> Volume {
    Volume::new(
        "c",
        [n; 3],
        1,
        [1.0; 3],
        VoxelData::F32(vec![3.0; (n * n * n) as usize]),
    )
    .unwrap()
}

fn shaded(vol: &Volume, params: &ParamValues, ray_dir: DVec3) -> DVec4 {
    let scalars = vol.normalized_scalars();
    let ctx = CpuContext::new(vol, &scalars);
    let mut twin = BlinnPhong::default().configure(params).map_or_else(
        || BlinnPhong::default().cpu_twin(params).unwrap(),
        |p| p.cpu_twin(params).unwrap(),
    );
    twin.prepare(&ctx);
    let mut s = CpuSample {
        tex: DVec3::splat(0.5),
        ray_dir,
        color: DVec4::new(0.8, 0.4, 0.2, 0.5),
        ..Default::default()
    };
    twin.shade(&ctx, &mut s);
    s.color
}

fn defaults() -> ParamValues {
    ParamValues::defaults(&BlinnPhong::default().params())
}

#[test]
fn head_on_light_gives_ambient_plus_diffuse_plus_specular() {
    // light along −x in world space, viewer looking along +x: n = −x faces both
    let mut p = defaults();
    p.set("light0_space", ParamValue::Enum("world".into()));
    p.set("light0_vector", ParamValue::Vec3([-1.0, 0.0, 0.0]));
    p.set("gradient_floor", ParamValue::Float(0.001));
    let c = shaded(&ramp_x(9), &p, DVec3::X);
    let (ka, kd, ks) = (0.25, 0.75, 0.35);
    let expect = DVec3::new(0.8, 0.4, 0.2) * (ka + kd) + DVec3::splat(ks);
    assert!((c.truncate() - expect).length() < 1e-5, "{c} vs {expect}");
    assert_eq!(c.w, 0.5);
    // the additive mode adds the light to the colour instead of modulating
    p.set("mode", ParamValue::Enum("additive".into()));
    let c = shaded(&ramp_x(9), &p, DVec3::X);
    let expect = DVec3::new(0.8, 0.4, 0.2) * ka + DVec3::splat(kd + ks);
    assert!((c.truncate() - expect).length() < 1e-5, "{c} vs {expect}");
}

#[test]
fn one_sided_shading_leaves_back_faces_dark_and_two_sided_lights_them() {
    let mut p = defaults();
    p.set("light0_space", ParamValue::Enum("world".into()));
    p.set("light0_vector", ParamValue::Vec3([1.0, 0.0, 0.0]));
    p.set("gradient_floor", ParamValue::Float(0.001));
    // viewer and light on the +x side, normal −x: one-sided gets the ambient term only
    p.set("two_sided", ParamValue::Bool(false));
    let one = shaded(&ramp_x(9), &p, -DVec3::X);
    assert!((one.truncate() - DVec3::new(0.8, 0.4, 0.2) * 0.25).length() < 1e-6);
    p.set("two_sided", ParamValue::Bool(true));
    let two = shaded(&ramp_x(9), &p, -DVec3::X);
    assert!(two.x > one.x + 0.5);
}

#[test]
fn gradient_opacity_and_zero_gradient() {
    let mut p = defaults();
    p.set("gm_opacity", ParamValue::Float(1.0));
    // |∇f| = 1/8 per voxel, × gm_scale 4 = 0.5: α halves
    p.set("gm_scale", ParamValue::Float(4.0));
    let c = shaded(&ramp_x(9), &p, DVec3::X);
    assert!((c.w - 0.25).abs() < 1e-6, "{c}");
    // a constant volume: unlit colour, and α → 0 under full modulation, no NaN
    let c = shaded(&constant(6), &p, DVec3::X);
    assert_eq!(c.truncate(), DVec3::new(0.8, 0.4, 0.2));
    assert_eq!(c.w, 0.0);
}

#[test]
fn every_estimator_gives_the_same_light_on_a_ramp() {
    let mut colours = Vec::new();
    for e in GradientEstimator::NAMES {
        let mut p = defaults();
        p.set("gradient", ParamValue::Enum(e.into()));
        colours.push(shaded(&ramp_x(9), &p, DVec3::X));
    }
    for c in &colours[1..] {
        assert!((*c - colours[0]).length() < 2e-3, "{colours:?}");
    }
}
