use glam::{DVec3, DVec4};
use vwb_render::params::{ParamValue, ParamValues};
use vwb_render::plugin::{CpuContext, CpuSample, CpuTwin, CpuView, Plugin, Transparency};
use vwb_render::shading::{cut_gradient, set_cut_gradient};

use super::*;
use crate::lighting::testing::ramp_x;

fn params(f: impl FnOnce(&mut ParamValues)) -> ParamValues {
    let mut p = ParamValues::defaults(&Shapes::default().params());
    f(&mut p);
    p
}

fn set_shape(p: &mut ParamValues, i: usize, kind: &str, center: [f32; 3], axis: [f32; 3], size: [f32; 3]) {
    let k = slot_keys()[i];
    p.set(k.kind, ParamValue::Enum(kind.into()));
    p.set(k.center, ParamValue::Vec3(center));
    p.set(k.axis, ParamValue::Vec3(axis));
    p.set(k.size, ParamValue::Vec3(size));
}

fn kept(p: &ParamValues, pos: DVec3) -> bool {
    ShapesTwin::new(p).clip(&CpuSample {
        pos,
        ..Default::default()
    })
}

#[test]
fn slots_and_generated_code_cover_sixteen_shapes() {
    let specs = Shapes::default().params();
    // every slot a sphere: the configured code reads every slot's parameters
    let all_on = params(|p| {
        for i in 0..SLOTS {
            set_shape(p, i, "sphere", [0.0; 3], [1.0, 0.0, 0.0], [0.1; 3]);
        }
    });
    let all = Shapes::default()
        .configure(&all_on)
        .expect("other kinds configure another plugin");
    let default_code = Shapes::default().shader().source;
    for (i, k) in slot_keys().iter().enumerate() {
        for key in [k.kind, k.center, k.size, k.invert] {
            assert!(specs.iter().any(|s| s.key == key), "{key}");
        }
        for key in [k.center, k.size, k.invert] {
            assert!(all.shader().source.contains(&format!("params.{key}")), "{key}");
            // the defaults emit slot 0 (a plane) only
            let emitted = default_code.contains(&format!("params.{key}"));
            assert_eq!(emitted, i == 0 && key != k.size, "{key}");
        }
    }
    assert_eq!(slot_keys().len(), 16);
    assert_eq!(ClipRegion::from_params(&all_on).shapes.len(), 16);
    // the configured kinds are what the twin reads
    assert!(Shapes::default().configure(&ParamValues::defaults(&specs)).is_none());
}

#[test]
fn default_plane_keeps_the_side_away_from_its_normal() {
    let p = ParamValues::defaults(&Shapes::default().params());
    assert!(kept(&p, DVec3::new(-0.1, 0.2, 0.3)));
    assert!(!kept(&p, DVec3::new(0.1, 0.2, 0.3)));
}

#[test]
fn primitives_have_exact_distances() {
    let s = |kind, size: [f64; 3]| Shape {
        kind,
        center: DVec3::new(0.1, 0.0, 0.0),
        axis: DVec3::Z,
        size: DVec3::from(size),
        invert: false,
    };
    let p = DVec3::new(0.1, 0.0, 0.5);
    assert!((s(1, [0.0; 3]).sd(p) - 0.5).abs() < 1e-12);
    assert!((s(3, [0.2, 0.0, 0.0]).sd(p) - 0.3).abs() < 1e-12);
    // box half extents 0.1, 0.1, 0.2 along u, v, z: 0.3 beyond the top face
    assert!((s(2, [0.1, 0.1, 0.2]).sd(p) - 0.3).abs() < 1e-12);
    // inside the box: minus the distance to the nearest face
    assert!((s(2, [0.1, 0.1, 0.2]).sd(DVec3::new(0.1, 0.0, 0.15)) + 0.05).abs() < 1e-12);
    // cylinder radius 0.2, half length 0.4: 0.1 beyond the cap
    assert!((s(4, [0.2, 0.0, 0.4]).sd(p) - 0.1).abs() < 1e-12);
    // beside the cylinder's mantle
    assert!((s(4, [0.2, 0.0, 0.4]).sd(DVec3::new(0.4, 0.0, 0.0)) - 0.1).abs() < 1e-12);
    // invert negates
    let mut inv = s(3, [0.2, 0.0, 0.0]);
    inv.invert = true;
    assert!((inv.sd(p) + 0.3).abs() < 1e-12);
}

#[test]
fn combinations_intersect_unite_and_complement() {
    // two spheres of radius 0.2 at x = ±0.1: they overlap around the origin
    let two = |combine: &str| {
        params(|p| {
            set_shape(p, 0, "sphere", [-0.1, 0.0, 0.0], [1.0, 0.0, 0.0], [0.2; 3]);
            set_shape(p, 1, "sphere", [0.1, 0.0, 0.0], [1.0, 0.0, 0.0], [0.2; 3]);
            p.set("combine", ParamValue::Enum(combine.into()));
        })
    };
    let (both, left_only, outside) = (DVec3::ZERO, DVec3::new(-0.25, 0.0, 0.0), DVec3::splat(0.4));
    let i = two("intersection");
    assert!(kept(&i, both) && !kept(&i, left_only) && !kept(&i, outside));
    let u = two("union");
    assert!(kept(&u, both) && kept(&u, left_only) && !kept(&u, outside));
    let c = two("complement");
    assert!(!kept(&c, both) && !kept(&c, left_only) && kept(&c, outside));
    // all slots off: nothing is clipped
    let none = params(|p| p.set(slot_keys()[0].kind, ParamValue::Enum("off".into())));
    assert!(kept(&none, both) && kept(&none, outside));
}

#[test]
fn sixteen_planes_cut_a_polyhedron() {
    // 16 planes tangent to a sphere of radius 0.3 (normals on a spiral): the points
    // inside the sphere of radius 0.29 are kept, those beyond radius 0.3·sec(max gap) not
    let p = params(|p| {
        for i in 0..SLOTS {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / SLOTS as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = i as f64 * 2.399963;
            let n = DVec3::new(r * phi.cos(), r * phi.sin(), z);
            let c = n * 0.3;
            set_shape(p, i, "plane", c.as_vec3().into(), n.as_vec3().into(), [0.0; 3]);
        }
    });
    assert_eq!(ClipRegion::from_params(&p).shapes.len(), 16);
    for i in 0..200 {
        let f = |k: f64| (i as f64 * 0.618034 * (k + 1.0)).fract() * 2.0 - 1.0;
        let d = safe_normalize(DVec3::new(f(0.0), f(1.0), f(2.0)));
        assert!(kept(&p, d * 0.29), "{d}");
        assert!(!kept(&p, d * 0.9), "{d}");
    }
}

#[test]
fn camera_slab_follows_the_eye() {
    let p = params(|p| {
        p.set(slot_keys()[0].kind, ParamValue::Enum("off".into()));
        p.set("follow_camera", ParamValue::Bool(true));
        p.set("camera_near", ParamValue::Float(2.0));
        p.set("camera_thickness", ParamValue::Float(0.2));
    });
    let vol = ramp_x(8);
    let scalars = vol.normalized_scalars();
    let mut twin = ShapesTwin::new(&p);
    let at = |twin: &ShapesTwin, z: f64| {
        twin.clip(&CpuSample {
            pos: DVec3::new(0.0, 0.0, z),
            ..Default::default()
        })
    };
    // eye on +z at 2 looking down −z: the slab is z in [−0.2, 0]
    twin.prepare(&CpuContext::new(&vol, &scalars));
    assert!(at(&twin, -0.1) && !at(&twin, 0.1) && !at(&twin, -0.3));
    // the camera moves to −z at −2 looking down +z: the slab is z in [0, 0.2]
    let view = CpuView {
        eye: DVec3::new(0.0, 0.0, -2.0),
        forward: DVec3::Z,
        ..Default::default()
    };
    twin.prepare(&CpuContext::new(&vol, &scalars).with_view(view));
    assert!(at(&twin, 0.1) && !at(&twin, -0.1) && !at(&twin, 0.3));
}

#[test]
fn soft_edge_ramps_alpha_over_its_width() {
    let vol = ramp_x(8);
    let scalars = vol.normalized_scalars();
    let ctx = CpuContext::new(&vol, &scalars);
    let p = params(|p| p.set("soft_edge", ParamValue::Float(2.0)));
    let mut twin = ShapesTwin::new(&p);
    twin.prepare(&ctx);
    let voxel = ctx.reference_step();
    let alpha = |x: f64| {
        let mut s = CpuSample {
            pos: DVec3::new(x, 0.0, 0.0),
            color: DVec4::new(1.0, 1.0, 1.0, 0.8),
            ..Default::default()
        };
        twin.shade(&ctx, &mut s);
        s.color.w
    };
    // the default plane is x = 0 (normal +x): α is 0 at the cut, half a width in, full beyond
    assert!(alpha(0.0).abs() < 1e-12);
    assert!((alpha(-voxel) - 0.4).abs() < 1e-9, "{}", alpha(-voxel));
    assert!((alpha(-3.0 * voxel) - 0.8).abs() < 1e-12);
    // without a soft edge α is unchanged
    let mut hard = ShapesTwin::new(&ParamValues::defaults(&Shapes::default().params()));
    hard.prepare(&ctx);
    let mut s = CpuSample {
        pos: DVec3::new(-1e-3, 0.0, 0.0),
        color: DVec4::splat(0.5),
        ..Default::default()
    };
    hard.shade(&ctx, &mut s);
    assert_eq!(s.color.w, 0.5);
}

#[test]
fn cut_layer_sets_the_cut_normal_for_the_shading_gradient() {
    let vol = ramp_x(16);
    let scalars = vol.normalized_scalars();
    let ctx = CpuContext::new(&vol, &scalars);
    let p = params(|p| {
        set_shape(p, 0, "plane", [0.0; 3], [0.0, 1.0, 0.0], [0.0; 3]);
        p.set("cut_shading", ParamValue::Enum("clip_normal".into()));
        p.set("cut_layer", ParamValue::Float(2.0));
    });
    let mut twin = ShapesTwin::new(&p);
    twin.prepare(&ctx);
    let voxel = ctx.reference_step();
    let eval = |y: f64| {
        set_cut_gradient(None);
        twin.clip(&CpuSample {
            pos: DVec3::new(0.1, y, 0.0),
            ..Default::default()
        });
        cut_gradient()
    };
    // inside the layer: −∇sd = −y (the outward normal −g is +y, towards the removed side)
    let g = eval(-voxel).expect("in the layer");
    assert!((g - DVec3::NEG_Y).length() < 1e-9, "{g}");
    // deeper than the layer: the data gradient stays
    assert_eq!(eval(-3.0 * voxel), None);
    // the shading plugins' gradient follows it
    let grads = vwb_render::shading::Gradients::default();
    set_cut_gradient(Some(DVec3::NEG_Y));
    assert_eq!(grads.at(&ctx, DVec3::splat(0.5)), DVec3::NEG_Y);
    set_cut_gradient(None);
    assert!(grads.at(&ctx, DVec3::splat(0.5)).x > 0.0);
}

#[test]
fn bricks_wholly_clipped_are_reported_and_no_kept_point_is_lost() {
    // a sphere of radius 0.2 and a plane: boxes far outside are clipped, boxes touching
    // the kept region are not, for random boxes checked against dense point samples
    let p = params(|p| {
        set_shape(p, 0, "plane", [0.05, 0.0, 0.0], [1.0, 0.2, 0.0], [0.0; 3]);
        set_shape(p, 1, "sphere", [0.0; 3], [1.0, 0.0, 0.0], [0.2; 3]);
    });
    let region = ClipRegion::from_params(&p);
    assert!(!region.may_keep_box(DVec3::splat(0.3), DVec3::splat(0.4)));
    assert!(region.may_keep_box(DVec3::splat(-0.05), DVec3::splat(0.05)));
    let mut clipped = 0;
    for i in 0..300 {
        let f = |k: f64| (i as f64 * 0.618034 * (k + 1.0) + 0.1 * k).fract() - 0.5;
        let lo = DVec3::new(f(0.0), f(1.0), f(2.0));
        let hi = lo + DVec3::splat(0.08);
        if region.may_keep_box(lo, hi) {
            continue;
        }
        clipped += 1;
        for j in 0..125 {
            let t = DVec3::new((j % 5) as f64, ((j / 5) % 5) as f64, (j / 25) as f64) / 4.0;
            let q = lo + (hi - lo) * t;
            assert!(region.sd(q, &CpuView::default()) > 0.0, "{q} kept in a clipped box");
        }
    }
    assert!(clipped > 100, "{clipped}");
    // with the camera slab the promise is view-independent only
    let slab = params(|p| p.set("follow_camera", ParamValue::Bool(true)));
    let demo = vwb_render::volume::demo();
    let volumes = Volumes::of(&demo);
    assert!(matches!(
        Shapes::default().transparency(&slab, &volumes),
        Transparency::Keeps
    ));
    assert!(matches!(
        Shapes::default().transparency(&p, &volumes),
        Transparency::Region(_)
    ));
}
