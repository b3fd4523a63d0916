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
        integrator: Integrator::Euler,
        kernel: 2,
        ..Lic3d::default()
    };
    assert!(twice.configure(&p).is_none());
    // only Euler's stage is compiled in; RK2 adds the midpoint, RK4 all four
    let stages = |c: &Lic3d| c.prepass().unwrap().shader.source.matches("= lic_dir(p").count();
    assert_eq!(stages(&twice), 1);
    for (integrator, n) in [(Integrator::Rk2, 2), (Integrator::Rk4, 4)] {
        assert_eq!(stages(&Lic3d { integrator, ..twice }), n, "{integrator:?}");
    }
    // only the chosen kernel's weight: the Gaussian's exp, the periodic kernel's cos
    let weights = |kernel| {
        let src = Lic3d { kernel, ..twice }.prepass().unwrap().shader.source;
        (src.contains("w = exp("), src.contains("cos(ripple)"), src.contains("w = 1.0 - x"))
    };
    assert_eq!(weights(0), (false, false, false));
    assert_eq!(weights(1), (false, false, true));
    assert_eq!(weights(2), (true, false, false));
    assert_eq!(weights(3), (false, true, false));
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

/// The twin supplies what the sample hook gives as the shading scalar: the gradient
/// estimators then differentiate the LIC one texel of its grid apart, not the data.
#[test]
fn the_twin_supplies_the_lic_as_the_shading_scalar() {
    // a rotation about the z axis through the centre of an 8³ box
    let n = 8usize;
    let c = (n as f32 - 1.0) / 2.0;
    let data: Vec<f32> = (0..n * n * n)
        .flat_map(|i| {
            let (x, y) = ((i % n) as f32 - c, ((i / n) % n) as f32 - c);
            [-y, x, 0.0]
        })
        .collect();
    let v = Volume::new("rotation", [8; 3], 3, [1.0; 3], VoxelData::F32(data)).unwrap();
    let mut p = defaults();
    p.set("frequency", ParamValue::Enum("2".into()));
    let plugin = Lic3d {
        frequency: 2,
        ..Lic3d::default()
    };
    let scalars = v.normalized_scalars();
    let ctx = CpuContext::new(&v, &scalars);
    let mut twin = plugin.cpu_twin(&p).unwrap();
    twin.prepare(&ctx);
    let twins = vec![twin];
    let shaded = ctx.with_scalar_of(&twins);
    assert_eq!(shaded.shading_grid(), [16; 3]);
    assert_eq!(ctx.shading_grid(), [8; 3]);
    let lic = lic_of(&v, 2, &p);
    let at = |x: usize, y: usize, z: usize| lic.data[(z * 16 + y) * 16 + x] as f64;
    // at a texel centre of the LIC grid the scalar is that texel
    let (x, y, z) = (5, 7, 9);
    let tex = (DVec3::new(x as f64, y as f64, z as f64) + 0.5) / 16.0;
    assert!((shaded.shading_value(tex) - at(x, y, z)).abs() < 1e-9);
    // central differences one LIC texel apart, in ∇f·Δs0 units (Δs0 = 1/8, texel 1/16)
    let g = vwb_render::shading::gradient_central(&shaded, tex);
    let expected = DVec3::new(
        at(x + 1, y, z) - at(x - 1, y, z),
        at(x, y + 1, z) - at(x, y - 1, z),
        at(x, y, z + 1) - at(x, y, z - 1),
    );
    assert!((g - expected).length() < 1e-9, "{g} vs {expected}");
    // not the data's gradient (the normalised magnitude grows with the radius)
    let data = vwb_render::shading::gradient_central(&ctx, tex);
    assert!((g - data).length() > 0.05, "{g} vs {data}");
}
