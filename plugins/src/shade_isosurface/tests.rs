use super::*;
use vwb_render::params::ParamValue;
use vwb_render::volume::{Volume, VoxelData};

/// f = x/(n − 1) along x.
fn ramp_x(n: u32) -> Volume {
    let data = (0..n * n * n).map(|i| (i % n) as f32).collect();
    Volume::new("ramp", [n; 3], 1, [1.0; 3], VoxelData::F32(data)).unwrap()
}

fn twin(p: &ParamValues) -> IsosurfaceTwin {
    IsosurfaceTwin {
        gradients: Gradients::new(GradientEstimator::Central),
        alpha_test: p.enumeration("method") == "alpha_test",
        surfaces: surfaces(p, p.int("count") as usize),
        material: lighting::material(p),
        light: lighting::head_light(p),
        floor: p.float("gradient_floor") as f64,
    }
}

fn sample_at(x_voxel: f64, n: u32, vol: &Volume, scalars: &[f32], step_voxels: f64) -> CpuSample {
    let ctx = CpuContext::new(vol, scalars);
    let (lo, hi) = ctx.volume_box();
    let tex = DVec3::new((x_voxel + 0.5) / n as f64, 0.5, 0.5);
    let pos = lo + tex * (hi - lo);
    CpuSample {
        pos,
        tex,
        ray_dir: DVec3::X,
        value: ctx.value(tex),
        step: step_voxels * ctx.reference_step(),
        color: DVec4::ZERO,
        ..Default::default()
    }
}

#[test]
fn crossings_are_found_once_at_the_interpolated_point() {
    let n = 11;
    let vol = ramp_x(n);
    let scalars = vol.normalized_scalars();
    let ctx = CpuContext::new(&vol, &scalars);
    let mut p = ParamValues::defaults(&Isosurface::default().params());
    p.set("count", ParamValue::Int(2));
    p.set("iso0", ParamValue::Float(0.33));
    p.set("iso1", ParamValue::Float(0.31));
    let t = twin(&p);
    let (lo, hi) = ctx.volume_box();
    // samples at voxel 3 (value 0.3) stepping one voxel: both surfaces crossed, 0.31 first
    let s = sample_at(3.0, n, &vol, &scalars, 1.0);
    let dir_tex = s.ray_dir * s.step / (hi - lo);
    let hits = t.hits(&ctx, &s, dir_tex);
    assert_eq!(hits.len(), 2);
    assert_eq!(hits[0].1, 1);
    assert!(
        (hits[0].0 - 0.1).abs() < 1e-4 && (hits[1].0 - 0.3).abs() < 1e-4,
        "{hits:?}"
    );
    // the next sample (voxel 4) crosses nothing: each surface is met once
    let s = sample_at(4.0, n, &vol, &scalars, 1.0);
    assert!(t.hits(&ctx, &s, dir_tex).is_empty());
    // an opaque surface makes the sample opaque in its colour (shaded)
    let mut s = sample_at(3.0, n, &vol, &scalars, 1.0);
    t.shade(&ctx, &mut s);
    assert_eq!(s.color.w, 1.0);
    assert!(s.color.x > 0.0);
}

#[test]
fn alpha_test_takes_the_highest_isovalue_passed() {
    let n = 11;
    let vol = ramp_x(n);
    let scalars = vol.normalized_scalars();
    let ctx = CpuContext::new(&vol, &scalars);
    let mut p = ParamValues::defaults(&Isosurface::default().params());
    p.set("method", ParamValue::Enum("alpha_test".into()));
    p.set("count", ParamValue::Int(3));
    p.set("iso0", ParamValue::Float(0.2));
    p.set("iso1", ParamValue::Float(0.6));
    p.set("iso2", ParamValue::Float(0.4));
    let t = twin(&p);
    let hit = |x: f64| t.hits(&ctx, &sample_at(x, n, &vol, &scalars, 1.0), DVec3::ZERO);
    assert!(hit(1.0).is_empty());
    assert_eq!(hit(3.0), vec![(0.0, 0)]);
    assert_eq!(hit(5.0), vec![(0.0, 2)]);
    assert_eq!(hit(9.0), vec![(0.0, 1)]);
}

#[test]
fn a_half_transparent_surface_over_dvr_keeps_its_opacity_per_crossing() {
    let n = 11;
    let vol = ramp_x(n);
    let scalars = vol.normalized_scalars();
    let ctx = CpuContext::new(&vol, &scalars);
    let mut p = ParamValues::defaults(&Isosurface::default().params());
    p.set("iso0", ParamValue::Float(0.345));
    p.set("color0", ParamValue::Color([1.0, 1.0, 1.0, 0.5]));
    let t = twin(&p);
    for step in [0.5, 1.0, 2.0] {
        // the sample before the crossing, with a faint DVR colour
        let mut s = sample_at(3.0, n, &vol, &scalars, step);
        s.color = DVec4::new(0.0, 0.0, 1.0, 0.1);
        t.shade(&ctx, &mut s);
        // after the core's opacity correction the step's opacity is
        // 1 − (1 − a_dvr(step))(1 − 0.5)
        let ratio = step;
        let a_dvr = 1.0 - 0.9f64.powf(ratio);
        let total = 1.0 - (1.0 - s.color.w).powf(ratio);
        assert!(
            (total - (1.0 - (1.0 - a_dvr) * 0.5)).abs() < 1e-9,
            "{step}: {total}"
        );
    }
}

/// The transparency promise holds: a transparent sample that the twin makes visible
/// (a surface met with opacity > 0) lies in a range the promise calls visible (the
/// range of the sample's value and the value one step ahead, where the method reads
/// it), for both methods, and surfaces of opacity 0 promise nothing. Over samples
/// along a ramp at several steps, against the twin's `shade` itself.
#[test]
fn the_transparency_promise_holds_where_surfaces_are_met() {
    use vwb_render::plugin::Transparency;
    let n = 17;
    let vol = ramp_x(n);
    let scalars = vol.normalized_scalars();
    let ctx = CpuContext::new(&vol, &scalars);
    let volumes = vwb_render::inputs::Volumes::of(&vol);
    let (lo_box, hi_box) = ctx.volume_box();
    for method in ["crossing", "alpha_test"] {
        for clear in [false, true] {
            let mut p = ParamValues::defaults(&Isosurface::default().params());
            p.set("method", ParamValue::Enum(method.into()));
            p.set("count", ParamValue::Int(2));
            p.set("iso0", ParamValue::Float(0.4));
            p.set("iso1", ParamValue::Float(0.7));
            if clear {
                p.set("color1", ParamValue::Color([1.0, 0.0, 0.0, 0.0]));
            }
            let Transparency::Adds(meets, ahead) = Isosurface::default().transparency(&p, &volumes)
            else {
                panic!("isosurfaces add by value");
            };
            assert_eq!(ahead, if method == "crossing" { 1.0 } else { 0.0 });
            let t = twin(&p);
            let (mut shown, mut tested) = (0, 0);
            for step in [0.5, 1.0, 2.5] {
                for k in 0..=160 {
                    let x = k as f64 / 10.0;
                    let mut s = sample_at(x, n, &vol, &scalars, step);
                    let f0 = s.value;
                    let dir_tex = s.ray_dir * s.step / (hi_box - lo_box);
                    let f1 = if ahead > 0.0 { ctx.value(s.tex + dir_tex) } else { f0 };
                    t.shade(&ctx, &mut s);
                    tested += 1;
                    if s.color.w > 0.0 {
                        shown += 1;
                        assert!(
                            meets(f0.min(f1), f0.max(f1)),
                            "{method}, clear {clear}: {f0} → {f1} is shown"
                        );
                    }
                }
            }
            assert!(shown > 0 && shown < tested, "{method}: {shown} of {tested}");
        }
    }
    // a surface of opacity 0 alone promises nothing visible anywhere
    let mut p = ParamValues::defaults(&Isosurface::default().params());
    p.set("color0", ParamValue::Color([1.0, 1.0, 1.0, 0.0]));
    let Transparency::Adds(meets, _) = Isosurface::default().transparency(&p, &volumes) else {
        panic!()
    };
    assert!(!meets(0.0, 1.0));
}
