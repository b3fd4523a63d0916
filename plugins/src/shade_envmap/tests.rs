use super::maps::*;
use super::*;
use vwb_render::params::ParamValue;
use vwb_render::volume::{Volume, VoxelData};

#[test]
fn latlong_lookup_inverts_the_texel_directions() {
    let m = LatLong::from_fn(16, 8, |d| d);
    // at texel centres the bilinear lookup returns the texel itself
    for (x, y) in [(0u32, 0u32), (5, 3), (15, 7), (8, 4)] {
        let t = m.texels[(y * 16 + x) as usize];
        let d = DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64);
        let back = m.lookup(d, 0.0);
        assert!((back - d).length() < 1e-6, "({x},{y}): {back} vs {d}");
    }
    // u wraps: a rotation of 360° changes nothing
    let d = DVec3::new(0.3, 0.2, 0.9).normalize();
    assert!((m.lookup(d, 360.0) - m.lookup(d, 0.0)).length() < 1e-9);
}

#[test]
fn irradiance_of_a_constant_sky_is_the_sky_and_follows_the_light() {
    let white = LatLong::from_fn(64, 32, |_| DVec3::ONE).irradiance();
    assert!(white.texels.iter().all(|t| (t[0] - 1.0).abs() < 1e-5));
    // light from above only: normals pointing up see it all, down see none
    let top =
        LatLong::from_fn(64, 32, |d| DVec3::splat(if d.y > 0.0 { 1.0 } else { 0.0 })).irradiance();
    assert!((top.lookup(DVec3::Y, 0.0).x - 1.0).abs() < 1e-3);
    assert!(top.lookup(-DVec3::Y, 0.0).x < 1e-3);
    let side = top.lookup(DVec3::X, 0.0).x;
    assert!((side - 0.5).abs() < 0.05, "{side}");
}

#[test]
fn twin_reflects_the_environment_and_fades_without_gradient() {
    let n = 9;
    let data = (0..n * n * n).map(|i| (i % n) as f32).collect();
    let vol = Volume::new("ramp", [n; 3], 1, [1.0; 3], VoxelData::F32(data)).unwrap();
    let scalars = vol.normalized_scalars();
    let ctx = CpuContext::new(&vol, &scalars);
    let mut p = ParamValues::defaults(&EnvMap::default().params());
    p.set("phong_weight", ParamValue::Float(0.0));
    p.set("ka", ParamValue::Float(0.0));
    p.set("kd_env", ParamValue::Float(0.0));
    p.set("ks_env", ParamValue::Float(1.0));
    p.set("gradient_floor", ParamValue::Float(0.001));
    let twin = EnvMap::default().cpu_twin(&p).unwrap();
    // n = −x (∇f along +x); looking along +x: the mirror direction is −x
    let mut s = CpuSample {
        tex: DVec3::splat(0.5),
        ray_dir: DVec3::X,
        color: DVec4::new(1.0, 1.0, 1.0, 0.5),
        ..Default::default()
    };
    twin.shade(&ctx, &mut s);
    let sky = procedural().radiance.lookup(-DVec3::X, 0.0);
    assert!(
        (s.color.truncate() - sky).length() < 1e-9,
        "{} vs {sky}",
        s.color
    );
    // constant volume: unchanged
    let c = Volume::new("c", [4; 3], 1, [1.0; 3], VoxelData::F32(vec![1.0; 64])).unwrap();
    let cs = c.normalized_scalars();
    let mut s2 = CpuSample {
        color: DVec4::new(0.3, 0.2, 0.1, 0.5),
        ray_dir: DVec3::X,
        ..Default::default()
    };
    twin.shade(&CpuContext::new(&c, &cs), &mut s2);
    assert_eq!(s2.color, DVec4::new(0.3, 0.2, 0.1, 0.5));
}

#[test]
fn a_missing_map_is_an_error_naming_the_file() {
    let e = load(std::path::Path::new("/nonexistent/sky.hdr")).unwrap_err();
    assert!(e.contains("/nonexistent/sky.hdr"), "{e}");
}
