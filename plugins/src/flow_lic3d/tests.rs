use super::*;
use vwb_render::params::ParamValue;
use vwb_render::volume::VoxelData;

fn defaults() -> ParamValues {
    ParamValues::defaults(&Lic3d::default().params())
}

/// A scalar volume has no flow: its LIC is the noise itself.
#[test]
fn a_scalar_volume_convolves_to_its_noise() {
    let v = Volume::new("s", [6, 5, 4], 1, [1.0; 3], VoxelData::F32(vec![1.0; 120])).unwrap();
    let p = defaults();
    let lic = lic_of(&v, 1, &p);
    let noise = noise_volume([6, 5, 4], Noise::White, 1);
    assert_eq!(lic.data, noise.data);
    // twice the frequency: a grid twice as fine
    assert_eq!(lic_of(&v, 2, &p).dims, [12, 10, 8]);
}

/// The parameters select the LIC's kernel, step, integrator and noise; the frequency
/// configures the pre-pass scale.
#[test]
fn parameters_select_the_integral_and_the_grid() {
    let mut p = defaults();
    p.set("kernel", ParamValue::Enum("gaussian".into()));
    p.set("integrator", ParamValue::Enum("euler".into()));
    p.set("noise", ParamValue::Enum("sparse".into()));
    p.set("density", ParamValue::Float(0.03));
    let l = lic_params(&p);
    assert_eq!((l.kernel, l.integrator, l.step), (Kernel::Gaussian, Integrator::Euler, 0.5));
    assert_eq!(noise_kind(&p), Noise::Sparse { density: 0.03f32 as f64 });
    p.set("frequency", ParamValue::Enum("2".into()));
    let c = Lic3d::default().configure(&p).expect("another grid");
    assert_eq!(c.prepass().unwrap().scale, 2.0);
    let twice = Lic3d {
        frequency: 2,
        ..Lic3d::default()
    };
    assert!(twice.configure(&p).is_none());
    // on the fly: no pre-pass, and the hook integrates (no `lic` texture in the shader)
    p.set("mode", ParamValue::Enum("on_the_fly".into()));
    let fly = twice.configure(&p).expect("another mode");
    assert!(fly.prepass().is_none());
    let src = fly.shader().source;
    assert!(src.contains("lic_integral(x0, d)") && !src.contains("textureSampleLevel(lic,"));
    let pre = twice.shader().source;
    assert!(pre.contains("textureSampleLevel(lic,") && !pre.contains("fn lic_integral"));
    let prepass = twice.prepass().unwrap().shader.source;
    assert!(prepass.contains("fn prepass") && !prepass.contains("fn sample"));
}
