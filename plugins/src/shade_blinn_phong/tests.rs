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

fn configured(p: &ParamValues) -> Arc<dyn Plugin> {
    BlinnPhong::default()
        .configure(p)
        .unwrap_or_else(|| Arc::new(BlinnPhong::default()))
}

/// Only the lights evaluated per sample are compiled in: those that are on, and in
/// table mode not the view-space directional ones (the table holds them).
#[test]
fn only_the_lights_in_use_are_compiled_in() {
    let mut p = defaults();
    // the default plugin is what the default parameters configure
    assert!(BlinnPhong::default().configure(&p).is_none());
    let calls = |p: &ParamValues| {
        let s = configured(p).shader();
        (0..4)
            .filter(|i| s.source.contains(&format!("add_light(t, params.light{i}_on")))
            .collect::<Vec<_>>()
    };
    assert_eq!(calls(&p), [0]);
    p.set("light2_on", ParamValue::Bool(true));
    assert_eq!(calls(&p), [0, 2]);
    p.set("lighting", ParamValue::Enum("table".into()));
    assert_eq!(calls(&p), Vec::<usize>::new());
    p.set("light2_space", ParamValue::Enum("world".into()));
    assert_eq!(calls(&p), [2]);
    p.set("light0_type", ParamValue::Enum("point".into()));
    assert_eq!(calls(&p), [0, 2]);
    // each compiled light's kind is fixed in the code and its world-space vector comes
    // from the per-ray `setup` hook; its space stays a uniform there
    let src = configured(&p).shader().source;
    assert!(src.contains("add_light(t, params.light0_on, 1u, 1u, light_world[0]"), "{src}");
    assert!(src.contains("add_light(t, params.light2_on, 0u, 1u, light_world[2]"));
    assert!(src.contains(
        "light_world[0] = light_world_vector(1u, params.light0_space, params.light0_vector);"
    ));
    assert!(!src.contains("light_world[1]") && !src.contains("light_world[3] ="));
    // a light's kind is structural: switching it recomposes
    let before = configured(&p);
    p.set("light2_type", ParamValue::Enum("point".into()));
    assert!(before.configure(&p).is_some());
    // the compiled shader keeps the file's line numbers (regions are blanked)
    let c = configured(&p);
    let lines = c.shader().source.lines().count();
    assert!(lines > include_str!("blinn_phong.wgsl").lines().count());
    assert_eq!(c.resources().len(), 1);
    assert!(configured(&defaults()).resources().is_empty());
}

/// The table holds k_d·diffuse and k_s·specular of the view-space directional lights
/// for the view vector (0, 0, 1): a normal's cell gives them within the cell's
/// direction error (256² cells: under 1°).
#[test]
fn the_lighting_table_matches_direct_evaluation() {
    let mut p = defaults();
    p.set("light1_on", ParamValue::Bool(true));
    p.set("light1_color", ParamValue::Color([1.0, 0.2, 0.1, 1.0]));
    let lights = lighting::lights(&p);
    let m = lighting::material(&p);
    let texels = table::bake(&lights, &m);
    assert_eq!(texels.len(), (2 * table::SIZE * table::SIZE) as usize);
    let v = DVec3::Z;
    let dirs: Vec<_> = lights
        .iter()
        .map(|l| (vwb_render::shading::safe_normalize(l.vector), l.color))
        .collect();
    let (mut worst, mut sum, mut n) = (0.0f64, 0.0, 0);
    for k in 0..5000 {
        let z = 1.0 - 2.0 * (k as f64 + 0.5) / 5000.0;
        let r = (1.0 - z * z).sqrt();
        let phi = 2.399_963_229_728_653 * k as f64;
        let normal = DVec3::new(r * phi.cos(), r * phi.sin(), z);
        let (d, s) = table::lookup(&texels, normal);
        let (ed, es) = vwb_render::shading::light_terms(normal, v, &dirs, &m);
        let e = (d - ed).length().max((s - es).length());
        worst = worst.max(e);
        sum += e;
        n += 1;
    }
    assert!(worst < 0.05, "worst {worst}");
    assert!(sum / (n as f64) < 0.005, "mean {}", sum / n as f64);
    assert!(worst > 0.0, "the table quantises the normal");
}

/// Lights the table cannot hold (world space, point) are still evaluated per sample:
/// with only such lights, table mode shades exactly as direct mode.
#[test]
fn table_mode_evaluates_untabulated_lights_per_sample() {
    let mut p = defaults();
    p.set("light0_space", ParamValue::Enum("world".into()));
    p.set("light0_vector", ParamValue::Vec3([-1.0, 0.3, 0.0]));
    p.set("gradient_floor", ParamValue::Float(0.001));
    let direct = shaded(&ramp_x(9), &p, DVec3::X);
    p.set("lighting", ParamValue::Enum("table".into()));
    let table = shaded(&ramp_x(9), &p, DVec3::X);
    assert_eq!(direct, table);
    // a view-space light is read from the table: close to direct, not equal
    p.set("light0_space", ParamValue::Enum("view".into()));
    p.set("light0_vector", ParamValue::Vec3([-1.0, 0.2, 1.0]));
    let table = shaded(&ramp_x(9), &p, DVec3::new(0.0, 0.0, -1.0));
    p.set("lighting", ParamValue::Enum("direct".into()));
    let direct = shaded(&ramp_x(9), &p, DVec3::new(0.0, 0.0, -1.0));
    assert!(direct.x > 0.8 * 0.25 + 0.1, "lit: {direct}");
    assert!((table - direct).length() < 0.02, "{table} vs {direct}");
    assert_ne!(table, direct);
}
