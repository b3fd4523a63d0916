use super::*;
use vwb_render::flow::NEVER;
use vwb_render::params::{Animation, ParamValue};
use vwb_render::volume::VoxelData;

fn defaults() -> ParamValues {
    ParamValues::defaults(&Arrival::default().params())
}

fn idx(dims: [u32; 3], x: u32, y: u32, z: u32) -> usize {
    (x + dims[0] * (y + dims[1] * z)) as usize
}

/// A scalar volume has no flow: only the seed box is ever reached.
#[test]
fn a_scalar_volume_reaches_only_its_seed() {
    let dims = [20, 4, 3];
    let v = Volume::new("s", dims, 1, [1.0; 3], VoxelData::F32(vec![1.0; 240])).unwrap();
    let a = arrival_of(&v, &defaults());
    // the default seed: x ∈ [0, 0.05] of 20 voxels holds voxel 0 (centre 0.025)
    assert_eq!(a[idx(dims, 0, 2, 1)], 0.0);
    assert!(a.iter().enumerate().all(|(i, t)| (i % 20 == 0) == (*t == 0.0)));
    assert!(a.iter().all(|t| *t == 0.0 || *t == NEVER));
}

/// The field is scaled to a top speed of 1, so times are in voxels at that speed; a
/// uniform flow along x arrives at the distance from the seed over its speed.
#[test]
fn times_are_voxels_at_the_top_speed() {
    let dims = [32, 3, 3];
    let n = 9 * 32;
    // u = 5 (any unit), v = w = 0: after scaling, unit speed
    let data: Vec<f32> = (0..n).flat_map(|_| [5.0, 0.0, 0.0]).collect();
    let v = Volume::new("u", dims, 3, [1.0; 3], VoxelData::F32(data)).unwrap();
    let f = unit_field(&v).expect("a field");
    assert!(f.data.iter().step_by(3).all(|x| *x == 1.0));
    let mut p = defaults();
    p.set("seed_max", ParamValue::Vec3([0.1, 1.0, 1.0]));
    let a = arrival_of(&v, &p);
    // the seed's far face is at x = 0.1·32 − 0.5 = 2.7 voxels
    for x in [5u32, 10, 31] {
        let t = a[idx(dims, x, 1, 1)] as f64;
        assert!((t - (x as f64 - 2.7)).abs() < 1e-4, "x {x}: {t}");
    }
    // a swapped box is the same box
    p.set("seed_min", ParamValue::Vec3([0.1, 1.0, 1.0]));
    p.set("seed_max", ParamValue::Vec3([0.0, 0.0, 0.0]));
    assert_eq!(arrival_of(&v, &p), a);
    // a path shorter than the distance never arrives
    p.set("max_length", ParamValue::Float(8.0));
    assert_eq!(arrival_of(&v, &p)[idx(dims, 20, 1, 1)], NEVER);
}

/// `time` keeps everything reached by it; `band` only the front of that width.
#[test]
fn time_and_band_select_what_is_kept() {
    assert!(kept(0.0, 10.0, 0.0));
    assert!(kept(10.0, 10.0, 0.0));
    assert!(!kept(10.5, 10.0, 0.0));
    assert!(!kept(NEVER as f64, 1024.0, 0.0));
    assert!(!kept(3.0, 10.0, 4.0));
    assert!(kept(7.0, 10.0, 4.0));
}

/// The time is the animation clock and not an input of the pre-pass, so playing it
/// recomputes nothing; the seed and the integration are.
#[test]
fn playing_the_time_reruns_no_pass() {
    let specs = Arrival::default().params();
    let time = specs.iter().find(|s| s.key == "time").unwrap();
    assert_eq!(time.animation, Some(Animation::Clock));
    let deps = Arrival::default().prepass().unwrap().depends_on;
    assert!(!deps.contains(&"time") && !deps.contains(&"band"));
    for k in ["seed_min", "seed_max", "step", "max_length", "integrator"] {
        assert!(deps.contains(&k), "{k}");
        assert!(specs.iter().any(|s| s.key == k), "{k} is a parameter");
    }
    let p = defaults();
    assert_eq!(arrival_params(&p).integrator, Integrator::Rk4);
}

/// The integrator is compiled in: its pre-pass holds its stages only, and choosing
/// another configures another plugin.
#[test]
fn only_the_chosen_integrator_is_compiled_in() {
    let stages = |a: &dyn Plugin| {
        a.prepass()
            .unwrap()
            .shader
            .source
            .matches("= arrival_velocity(p")
            .count()
    };
    for (integrator, n) in Integrator::ALL.into_iter().zip([1, 2, 4]) {
        assert_eq!(stages(&Arrival { integrator }), n, "{integrator:?}");
    }
    let mut p = defaults();
    assert!(Arrival::default().configure(&p).is_none());
    p.set("integrator", ParamValue::Enum("euler".into()));
    let euler = Arrival::default().configure(&p).expect("another integrator");
    assert_eq!(stages(euler.as_ref()), 1);
}
