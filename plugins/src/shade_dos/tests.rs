use super::mc::{McOptions, render_mc};
use super::*;
use vwb_render::camera::{Camera, Projection};
use vwb_render::params::ParamValue;
use vwb_render::plugin::PluginInstance;
use vwb_render::renderer::FrameSettings;
use vwb_render::tf::{TfCurve, TfPoint};
use vwb_render::volume::{Volume, VoxelData};

#[test]
fn poisson_disk_is_deterministic_inside_and_spread() {
    let a = poisson_disk(MAX_POISSON);
    assert_eq!(a, poisson_disk(MAX_POISSON));
    assert_eq!(a.len(), MAX_POISSON);
    assert!(a.iter().all(|p| p.length_squared() <= 1.0));
    let min = (0..a.len())
        .flat_map(|i| (0..i).map(move |j| (i, j)))
        .map(|(i, j)| a[i].distance(a[j]))
        .fold(f64::INFINITY, f64::min);
    // a Poisson-disk set: no two points closer than a good fraction of the mean spacing
    assert!(min > 0.5 / (MAX_POISSON as f64).sqrt(), "{min}");
}

#[test]
fn grid_kernels_keep_the_points_inside_the_disk() {
    let mut p = ParamValues::defaults(&Dos::default().params());
    for (g, n) in [(2, 4), (3, 9), (4, 12), (13, 137)] {
        p.set("grid", ParamValue::Int(g));
        let k = kernel_points(&p);
        assert!(k.iter().all(|q| q.length_squared() <= 1.0));
        assert_eq!(k.len(), n, "grid {g}");
    }
    p.set("kernel", ParamValue::Enum("poisson".into()));
    p.set("poisson_count", ParamValue::Int(10));
    assert_eq!(kernel_points(&p).len(), 10);
}

/// The shader's grid taps are written out per n (`grid` is structural): the twin's
/// points, in its order; the composed shader validates for every n and
/// keeps its line numbers.
#[test]
fn grid_taps_are_written_out_as_the_twin_takes_them() {
    let base = Dos::default();
    let mut p = ParamValues::defaults(&base.params());
    let limits = wgpu::Limits::default();
    let lines = base.shader().source.lines().count();
    for g in 2..=13 {
        p.set("grid", ParamValue::Int(g));
        let twin = kernel_points(&p);
        let wgsl = grid_taps_wgsl(g as u32, "kernel_tap");
        let taps: Vec<(f64, f64)> = wgsl
            .split("kernel_tap(vec2<f32>(")
            .skip(1)
            .map(|s| {
                let (x, rest) = s.split_once("f, ").unwrap();
                let y = rest.split_once("f)").unwrap().0;
                (x.parse().unwrap(), y.parse().unwrap())
            })
            .collect();
        assert_eq!(taps.len(), twin.len(), "grid {g}");
        assert!(wgsl.ends_with(&format!("n = {}.0;", twin.len())), "grid {g}: {wgsl}");
        for (q, t) in taps.iter().zip(&twin) {
            assert!((q.0 - t.x).abs() < 1e-6 && (q.1 - t.y).abs() < 1e-6, "grid {g}: {q:?} {t:?}");
        }
        let d = if g == 4 {
            assert!(base.configure(&p).is_none(), "the default grid");
            std::sync::Arc::new(base) as std::sync::Arc<dyn Plugin>
        } else {
            base.configure(&p).unwrap()
        };
        let source = d.shader().source;
        assert_eq!(source.lines().count(), lines, "grid {g}");
        assert!(source.contains(&wgsl));
        // composing validates the module with naga
        vwb_render::composer::compose(&[d.as_ref()], vwb_render::TargetFormat::Rgba16Float, &limits)
            .unwrap();
    }
}

#[test]
fn structural_parameters_choose_the_buffer() {
    let base = Dos::default();
    let mut p = ParamValues::defaults(&base.params());
    assert!(base.configure(&p).is_none());
    p.set("buffer_scale", ParamValue::Enum("0.5".into()));
    p.set("buffer_format", ParamValue::Enum("fp16".into()));
    let c = base.configure(&p).unwrap();
    let st = c.slice_state().unwrap();
    assert_eq!((st.scale, st.format), (0.5, StorageFormat::Rgba16Float));
    assert_eq!(
        st.clear[0], 1.0,
        "the occlusion buffers start at full visibility"
    );
    // chromatic extinction: V per channel, in rgba32float at fp32, rgba16float at fp16
    p.set("extinction", ParamValue::Enum("chromatic".into()));
    let st = c.configure(&p).unwrap().slice_state().unwrap();
    assert_eq!((st.format, st.clear), (StorageFormat::Rgba16Float, [1.0; 4]));
    p.set("buffer_format", ParamValue::Enum("fp32".into()));
    let st = base.configure(&p).unwrap().slice_state().unwrap();
    assert_eq!(st.format, StorageFormat::Rgba32Float);
    assert_eq!(extinction(&p), Some(DVec3::ONE));
    // achromatic, the shader has no chromatic code left (same line numbers)
    let chromatic = base.configure(&p).unwrap().shader().source;
    let achromatic = base.shader().source;
    assert_eq!(chromatic.lines().count(), achromatic.lines().count());
    assert!(chromatic.contains("params.extinction"));
    assert!(!achromatic.contains("params.extinction") && !achromatic.contains("fn chromatic_taps"));
    // a directional light: the state travels with it, and the composed slice shader
    // keeps its half-angle paths only then (line for line)
    let limits = wgpu::Limits::default();
    let compose = |d: &dyn Plugin| {
        vwb_render::composer::compose(&[d], vwb_render::TargetFormat::Rgba16Float, &limits)
            .unwrap()
            .main
            .source
    };
    let viewer = compose(&base);
    assert!(!base.slice_state().unwrap().light);
    let mut q = ParamValues::defaults(&base.params());
    q.set("light", ParamValue::Enum("directional".into()));
    let lit = base.configure(&q).unwrap();
    assert!(lit.slice_state().unwrap().light);
    let lit = compose(lit.as_ref());
    assert_eq!(lit.lines().count(), viewer.lines().count());
    assert!(lit.contains("c = select(uv, light_uv(pos), half_angle());"));
    assert!(!viewer.contains("light_uv(pos)"));
}

/// The kernel and the attenuation distance are structural: the shader keeps only the
/// chosen loop and distance, line for line.
#[test]
fn structural_kernel_and_distance_choose_the_code() {
    let base = Dos::default();
    let grid = base.shader().source;
    assert!(grid.contains("sum = sum + kernel_tap(vec2<f32>(-0.25f, -0.75f), uv") && grid.contains("n = 12.0;"));
    assert!(!grid.contains("textureLoad(poisson") && !grid.contains("sqrt(d * d"));
    let mut p = ParamValues::defaults(&base.params());
    p.set("kernel", ParamValue::Enum("poisson".into()));
    p.set("distance", ParamValue::Enum("exact".into()));
    let c = base.configure(&p).unwrap();
    assert!(c.configure(&p).is_none(), "configured once");
    let poisson = c.shader().source;
    assert_eq!(poisson.lines().count(), grid.lines().count());
    assert!(poisson.contains("textureLoad(poisson") && poisson.contains("sqrt(d * d"));
    assert!(!poisson.contains("kernel_tap(vec2<f32>("));
    assert!(grid.contains(&format!("const DOS_POISSON_MAX: i32 = {MAX_POISSON};")));
    // chromatic: the per-channel taps follow the same choice
    p.set("extinction", ParamValue::Enum("chromatic".into()));
    let chromatic = base.configure(&p).unwrap().shader().source;
    assert!(chromatic.contains("fn chromatic_taps") && chromatic.contains("chromatic_tap(q, uv"));
    assert!(!chromatic.contains("chromatic_tap(vec2<f32>("));
    p.set("kernel", ParamValue::Enum("grid".into()));
    let chromatic_grid = base.configure(&p).unwrap().shader().source;
    assert!(chromatic_grid.contains(&grid_taps_wgsl(4, "chromatic_tap")));
    assert!(!chromatic_grid.contains("textureLoad(poisson"));
    assert_eq!(chromatic_grid.lines().count(), grid.lines().count());
}

/// Homogeneous slab seen head on, θ = 0: V(s) is the transmittance back to the front
/// face, so L = ∫₀ᴸ c·σ·e^(−2σs) ds = c·(1 − e^(−2σL))/2 (L_a = 1, no ambient).
#[test]
fn monte_carlo_matches_the_closed_form_of_a_slab() {
    let n = 16u32;
    let volume = Volume::new(
        "slab",
        [n; 3],
        1,
        [1.0; 3],
        VoxelData::F32(vec![0.5; (n * n * n) as usize]),
    )
    .unwrap();
    let (c, a) = (0.8f32, 0.1f32);
    let mut tf = PluginInstance::new(std::sync::Arc::new(crate::classify_tf1d::Tf1d::default()));
    let point = |x| TfPoint {
        x,
        color: [c, c, c, a],
    };
    tf.params.set(
        "tf",
        ParamValue::Tf(TfCurve::new(vec![point(0.0), point(1.0)])),
    );
    let mut dos = PluginInstance::new(std::sync::Arc::new(Dos::default()));
    dos.params.set("theta_deg", ParamValue::Float(0.0));
    let achromatic = dos.clone();
    let mut camera = Camera {
        projection: Projection::Orthographic { height: 1.5 },
        ..Default::default()
    };
    camera.axis_view(2, false);
    let settings = FrameSettings {
        camera,
        width: 5,
        height: 5,
        ..Default::default()
    };
    let opts = McOptions {
        directions: 4,
        eye_step: 0.05,
        ..Default::default()
    };
    let img = render_mc(&volume, &[tf.clone(), dos], &settings, &opts, None).unwrap();
    // σ per voxel length; the slab is n voxels thick
    let sigma = -(1.0 - a as f64).ln();
    let expect = c as f64 * (1.0 - (-2.0 * sigma * n as f64).exp()) / 2.0;
    let got = img.pixels[12][0];
    assert!((got - expect).abs() < 2e-4, "{got} vs {expect}");
    // θ = 0 draws one direction only: no noise
    assert_eq!(img.rms_std_error(), 0.0);

    // chromatic extinction: the cone's σ is κ_c·σ, so L_c = c·(1 − e^(−(1 + κ_c)σL))/(1 + κ_c)
    let kappa = [0.25f32, 1.0, 3.0];
    let mut chromatic = achromatic;
    chromatic
        .params
        .set("extinction", ParamValue::Enum("chromatic".into()));
    chromatic
        .params
        .set("extinction_rgb", ParamValue::Vec3(kappa));
    let img = render_mc(&volume, &[tf, chromatic], &settings, &opts, None).unwrap();
    for (ch, k) in kappa.iter().enumerate() {
        let k = 1.0 + *k as f64;
        let expect = c as f64 * (1.0 - (-k * sigma * n as f64).exp()) / k;
        let got = img.pixels[12][ch];
        assert!((got - expect).abs() < 2e-4, "channel {ch}: {got} vs {expect}");
    }
}

#[test]
fn monte_carlo_noise_falls_as_one_over_root_n() {
    let n = 12u32;
    let data = (0..n * n * n)
        .map(|i| {
            if (i / n) % n > 5 && (i % n) > 3 {
                1.0
            } else {
                0.2
            }
        })
        .collect();
    let volume = Volume::new("steps", [n; 3], 1, [1.0; 3], VoxelData::F32(data)).unwrap();
    let tf = PluginInstance::new(std::sync::Arc::new(crate::classify_tf1d::Tf1d::default()));
    let dos = PluginInstance::new(std::sync::Arc::new(Dos::default()));
    let settings = FrameSettings {
        width: 12,
        height: 12,
        ..Default::default()
    };
    let noise = |d: usize| {
        let opts = McOptions {
            directions: d,
            ..Default::default()
        };
        render_mc(&volume, &[tf.clone(), dos.clone()], &settings, &opts, None)
            .unwrap()
            .rms_std_error()
    };
    let (n16, n64) = (noise(16), noise(64));
    assert!(n16 > 0.0);
    let ratio = n64 / n16;
    assert!((0.3..0.75).contains(&ratio), "{n16} {n64} {ratio}");
    // a stack without shade.dos is refused
    assert!(render_mc(&volume, &[tf], &settings, &McOptions::default(), None).is_err());
}

/// The Monte-Carlo reference's cache key follows what the integral depends on (θ, κ),
/// not the slice algorithm's knobs (kernel, distance mode, buffers); its options are
/// checked by name and range.
#[test]
fn the_monte_carlo_reference_keys_on_the_integral_and_checks_its_options() {
    use std::collections::BTreeMap;
    use vwb_render::plugin::ConvergedReference;
    let r = mc::MonteCarloReference::default();
    let stack = |set: &[(&str, ParamValue)]| {
        let mut i = PluginInstance::new(Arc::new(Dos::default()));
        for (k, v) in set {
            i.params.set(k, v.clone());
        }
        vec![i]
    };
    let key = |set: &[(&str, ParamValue)]| r.key(&stack(set)).unwrap();
    let base = key(&[]);
    for same in [
        ("grid", ParamValue::Int(8)),
        ("kernel", ParamValue::Enum("poisson".into())),
        ("distance", ParamValue::Enum("exact".into())),
        ("buffer_format", ParamValue::Enum("fp16".into())),
        ("buffer_scale", ParamValue::Enum("0.5".into())),
        // κ (1, 1, 1) is the achromatic integral
        ("extinction", ParamValue::Enum("chromatic".into())),
    ] {
        assert_eq!(key(std::slice::from_ref(&same)), base, "{same:?}");
    }
    for different in [
        vec![("theta_deg", ParamValue::Float(30.0))],
        vec![("ambient", ParamValue::Float(0.2))],
        vec![
            ("extinction", ParamValue::Enum("chromatic".into())),
            ("extinction_rgb", ParamValue::Vec3([0.4, 1.0, 2.5])),
        ],
    ] {
        assert_ne!(key(&different), base, "{different:?}");
    }
    let opts = |pairs: &[(&str, f64)]| -> BTreeMap<String, f64> {
        pairs.iter().map(|(k, v)| (k.to_string(), *v)).collect()
    };
    let finer = r
        .with_options(&opts(&[("directions", 48.0), ("eye_step", 0.25)]))
        .unwrap();
    assert_ne!(finer.key(&stack(&[])).unwrap(), base, "options change the image");
    for (bad, why) in [
        (opts(&[("rays", 3.0)]), "unknown Monte-Carlo option 'rays'"),
        (opts(&[("directions", 2.5)]), "whole number"),
        (opts(&[("eye_step", 0.0)]), "(0, 8]"),
        (opts(&[("directions", 2.0)]), "at least replicas"),
    ] {
        let e = r.with_options(&bad).err().expect("refused");
        assert!(e.contains(why), "{bad:?}: {e}");
    }
}
