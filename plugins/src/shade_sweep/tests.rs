use super::*;
use vwb_render::volume::{Volume, VoxelData};

/// A half-opaque plate at z = 3 under a light from +z: the swept transmittance is 1
/// above the plate and ½ from it down, and a sample under the plate is lit by
/// ambient + (1 − ambient)·½; a sample above it is fully lit.
#[test]
fn a_plate_halves_the_light_below_it() {
    let volume = Volume::new("cube", [8, 8, 8], 1, [1.0; 3], VoxelData::U8(vec![0; 512])).unwrap();
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(&volume, &scalars);
    let mut params = ParamValues::defaults(&SweepShadows::default().params());
    params.set("light", vwb_render::params::ParamValue::Vec3([0.0, 0.0, 2.0]));
    params.set("ambient", vwb_render::params::ParamValue::Float(0.2));
    let mut twin = SweepTwin {
        travel: DVec3::from(travel(&params).map(f64::from)),
        ambient: 0.2,
        scale: 1.0,
        dims: [0; 3],
        transmittance: Vec::new(),
    };
    let plate = |tex: DVec3, d: DVec3| {
        assert!((d - DVec3::NEG_Z).length() < 1e-12, "{d}");
        if (tex.z * 8.0) as u32 == 3 {
            DVec4::new(1.0, 1.0, 1.0, 0.5)
        } else {
            DVec4::ZERO
        }
    };
    twin.prepare_passes(&ctx, &plate);
    for z in 0..8usize {
        let t = twin.transmittance[(z * 8 + 4) * 8 + 4];
        let want = if z > 3 { 1.0 } else { 0.5 };
        assert!((t as f64 - want).abs() < 1e-6, "z {z}: {t}");
    }
    let lit = |z: f64| {
        let mut s = CpuSample {
            tex: DVec3::new(0.5, 0.5, z / 8.0),
            color: DVec4::new(1.0, 0.5, 0.25, 0.7),
            ..Default::default()
        };
        twin.shade(&ctx, &mut s);
        s.color
    };
    let below = lit(1.5);
    assert!((below.x - 0.6).abs() < 1e-9 && (below.y - 0.3).abs() < 1e-9, "{below}");
    assert_eq!(below.w, 0.7);
    let above = lit(6.5);
    assert!((above.x - 1.0).abs() < 1e-9, "{above}");
}
