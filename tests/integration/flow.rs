//! Flow: streamlines and 3D LIC of vector volumes on the CPU twin (`vwb_render::flow`),
//! rendered by slicing as the thesis does (§9.3: a precomputed LIC volume, a TF). The
//! studies behind docs/flow.md are experiment files (`bash bench/flow.sh`).

use glam::DVec3;
use vwb_render::flow::{
    Abc, Field, GridField, LicParams, Noise, Rotation, Scaled, lic_volume, noise_volume,
};
use vwb_render::params::ParamValue;
use vwb_render::renderer::FrameSettings;
use vwb_render::volume::{Volume, VoxelData};
use vwb_render::{Backend, Renderer, TargetFormat};

use crate::common::*;

/// RMS difference of two scalar volumes of one size, in 1/255 units.
fn rms_255(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len());
    vwb_plugins::flow_lic3d::probes::rms_255(a, b)
}

/// GPU memory of one plugin instance (its resources and pass targets), in bytes.
fn plugin_bytes(r: &Renderer, uid: u64) -> u64 {
    r.plugin_memory()
        .iter()
        .filter(|(u, _, _)| *u == uid)
        .map(|(_, _, b)| b)
        .sum()
}

/// Share of a frame's pixels that are not transparent.
fn covered(px: &[[f32; 4]]) -> f64 {
    px.iter().filter(|p| p[3] > 0.01).count() as f64 / px.len() as f64
}

/// The storm's LIC volume at `factor` times its resolution, and its field on that grid.
fn storm_lic(factor: u32, p: &LicParams, kind: Noise) -> (Volume, GridField) {
    let storm =
        vwb_render::volume::load(&data_dir().join("storm_wind_ncsa_25x14x8_float32x3.nhdr"))
            .expect("storm volume");
    let field = GridField::from_volume(&storm).unwrap();
    let dims = storm.dims.map(|d| d * factor);
    let noise = noise_volume(dims, kind, 11);
    let scaled = Scaled {
        inner: &field,
        factor: factor as f64,
    };
    let lic = lic_volume(&scaled, &noise, p);
    let spacing = storm.spacing.map(|s| s / factor as f64);
    let vol = Volume::new("storm_lic", dims, 1, spacing, VoxelData::F32(lic)).unwrap();
    (vol, GridField::sample(&scaled, dims))
}

/// The storm's LIC volume has swirling structure: neighbours along the flow are far
/// more alike than across it; sliced with a TF it renders a finite, visible image.
#[test]
fn storm_lic_shows_structure_along_the_flow() {
    let (lic, field) = storm_lic(4, &LicParams::default(), Noise::White);
    let VoxelData::F32(data) = &lic.data else {
        unreachable!("storm_lic stores f32")
    };
    let (along, across) = vwb_plugins::flow_lic3d::along_and_across(data, lic.dims, &field);
    eprintln!("storm LIC at ×4: mean |ΔI| along the flow {along:.4}, across {across:.4}");
    assert!(along < 0.5 * across, "along {along} across {across}");
    let mut r = Renderer::new(gpu(), std::sync::Arc::new(lic)).unwrap();
    let mut tf = instance("classify.tf1d");
    tf.params.set(
        "tf",
        ParamValue::Tf(vwb_render::tf::TfCurve::ramp(
            0.45,
            0.75,
            [0.9, 0.95, 1.0, 0.15],
        )),
    );
    let px = render(
        &mut r,
        &[tf],
        TargetFormat::Rgba32Float,
        &settings(64, 64, Backend::Compute),
    );
    assert!(px.iter().flatten().all(|c| c.is_finite()));
    assert!(px.iter().filter(|p| p[3] > 0.2).count() > 64 * 64 / 10);
}

/// The twin tests' vector volume: an ABC flow (period 16 voxels) on 24×20×12.
fn small_abc() -> std::sync::Arc<Volume> {
    std::sync::Arc::new(vector_volume(
        &Abc {
            period: 16.0,
            ..Default::default()
        },
        [24, 20, 12],
    ))
}

/// A 3-component volume of `field` sampled at the voxel centres of `dims`.
fn vector_volume(field: &dyn Field, dims: [u32; 3]) -> Volume {
    let g = GridField::sample(field, dims);
    Volume::new("field", dims, 3, [1.0; 3], VoxelData::F32(g.data)).unwrap()
}

/// `flow.lic3d`'s pre-pass against its f64 twin with the same noise and field, for
/// every integrator and kernel and at twice the frequency: RMS ≤ 0.5/255; rendered,
/// the image matches the twin's on both backends; the pre-pass reruns only when an
/// integration parameter changes.
#[test]
fn lic_prepass_matches_its_twin() {
    let vol = small_abc();
    let mut r = Renderer::new(gpu(), vol.clone()).unwrap();
    let s = settings(48, 48, Backend::Compute);
    let mut worst: f64 = 0.0;
    let mut f32_run = None;
    for (integrator, kernel, frequency, storage) in [
        ("rk4", "tent", "1", "f32"),
        ("rk2", "gaussian", "1", "f32"),
        ("euler", "box", "1", "f32"),
        ("rk4", "tent", "2", "f32"),
        ("rk4", "periodic", "1", "f32"),
        ("rk4", "tent", "1", "f16"),
    ] {
        let mut lic = instance("flow.lic3d");
        for (k, v) in [
            ("integrator", integrator),
            ("kernel", kernel),
            ("frequency", frequency),
            ("storage", storage),
        ] {
            lic.params.set(k, ParamValue::Enum(v.into()));
        }
        // an asymmetric kernel: downstream and upstream must not be swapped
        lic.params.set("phase_deg", ParamValue::Float(90.0));
        let stack = vec![lic.clone(), instance("classify.tf1d")];
        render(&mut r, &stack, TargetFormat::Rgba32Float, &s);
        let (got_dims, gpu_lic) = r.read_prepass(lic.uid).expect("the LIC volume");
        let f: u32 = frequency.parse().unwrap();
        let twin = vwb_plugins::flow_lic3d::lic_of(&vol, f, &lic.params);
        assert_eq!(got_dims, twin.dims);
        let rms = rms_255(&gpu_lic, &twin.data);
        // the convolution did something: the LIC is not the noise
        let noise = vwb_render::flow::noise_volume(twin.dims, Noise::White, 1);
        let smoothing = rms_255(&noise.data, &twin.data);
        assert!(smoothing > 20.0, "LIC vs its noise: {smoothing}/255");
        eprintln!(
            "flow.lic3d {integrator} {kernel} ×{frequency} {storage}: GPU vs f64 twin LIC RMS {rms:.2e}/255 (LIC vs noise {smoothing:.1}/255)"
        );
        assert!(
            rms <= 0.5,
            "{integrator} {kernel} ×{frequency} {storage}: {rms}/255"
        );
        if storage == "f32" && integrator == "rk4" && kernel == "tent" && frequency == "1" {
            f32_run = Some((gpu_lic.clone(), twin.data.clone()));
        }
        if storage == "f16" {
            // the textures hold half floats: the GPU's LIC moves from the f32 one about
            // as far as the twin's moves when it rounds its inputs
            let (gpu_f32, twin_f32) = f32_run.as_ref().expect("the f32 run came first");
            let gpu_moved = rms_255(&gpu_lic, gpu_f32);
            let twin_moved = rms_255(&twin.data, twin_f32);
            eprintln!(
                "flow.lic3d f16 storage moves the LIC by {gpu_moved:.2e}/255 (twin {twin_moved:.2e}/255)"
            );
            assert!(
                twin_moved > 0.0 && gpu_moved > 0.5 * twin_moved,
                "{gpu_moved} vs {twin_moved}"
            );
        }
        worst = worst.max(rms);
    }
    // the pre-pass reruns for an integration parameter, not for modulate or the camera
    let mut lic = instance("flow.lic3d");
    let mut stack = vec![lic.clone(), instance("classify.tf1d")];
    let runs = |r: &mut Renderer, stack: &[vwb_render::PluginInstance], s| {
        r.update_stack(stack, TargetFormat::Rgba32Float).unwrap();
        r.render(s).unwrap().prepasses_run()
    };
    assert_eq!(runs(&mut r, &stack, &s), 1);
    let mut moved = s;
    moved.camera.yaw_deg += 40.0;
    assert_eq!(runs(&mut r, &stack, &moved), 0);
    lic.params.set("modulate", ParamValue::Float(0.5));
    stack[0] = lic.clone();
    assert_eq!(runs(&mut r, &stack, &s), 0);
    lic.params.set("length", ParamValue::Float(4.0));
    stack[0] = lic;
    assert_eq!(runs(&mut r, &stack, &s), 1);
    eprintln!("worst LIC volume RMS {worst:.2e}/255");
}

/// `flow.lic3d` on the fly (`mode: on_the_fly`): the sample hook integrates at each
/// sample, so no pre-pass runs and no LIC volume is held; the image matches the f64
/// twin integrating at the same points, on both backends, and differs from the
/// precomputed mode's trilinear blend.
#[test]
fn lic_on_the_fly_matches_its_twin_without_a_prepass() {
    use crate::reference::{delta_e_rms, gpu_and_reference, gpu_delta_e_rms};
    let vol = small_abc();
    let mut fly = instance("flow.lic3d");
    fly.params
        .set("mode", ParamValue::Enum("on_the_fly".into()));
    fly.params.set("length", ParamValue::Float(4.0));
    let stack = vec![fly.clone(), instance("classify.tf1d")];
    // raster interpolates the texture coordinates across the proxy polygons, and the
    // integral over noise amplifies those differences (precomputed 0.31, on the fly
    // 0.54 on lavapipe): the coverage test's raster bound for per-slice plugins
    for (backend, bound) in [
        (Backend::Compute, twin_bound(Backend::Compute, false)),
        (Backend::Raster, twin_bound(Backend::Raster, true)),
    ] {
        let s = settings(48, 48, backend);
        let (px, reference) = gpu_and_reference(vol.clone(), &stack, TargetFormat::Rgba32Float, &s);
        assert!(
            reference.iter().filter(|p| p[3] > 0.05).count() > 48 * 48 / 20,
            "the volume is visible"
        );
        let rms = delta_e_rms(&px, &reference, 48, 48);
        eprintln!(
            "flow.lic3d on the fly, {}: ΔE*uv RMS {rms:.4} against the twin",
            backend.name()
        );
        // not the precomputed volume read back: between the LIC grid's voxels the
        // exact integral differs from the trilinear blend of its neighbours' (3.1 ΔE
        // on lavapipe, docs/flow.md)
        let mut pre = fly.clone();
        pre.params
            .set("mode", ParamValue::Enum("precomputed".into()));
        let (_, pre_reference) = gpu_and_reference(
            vol.clone(),
            &[pre, instance("classify.tf1d")],
            TargetFormat::Rgba32Float,
            &s,
        );
        let apart = delta_e_rms(&px, &pre_reference, 48, 48);
        assert!(apart > 1.0, "on the fly vs the precomputed twin: {apart}");
        assert!(rms < bound, "{}: {rms}", backend.name());
    }
    let memory = |stack: &[vwb_render::PluginInstance]| {
        let mut r = Renderer::new(gpu(), vol.clone()).unwrap();
        r.update_stack(stack, TargetFormat::Rgba32Float).unwrap();
        let runs = r
            .render(&settings(32, 32, Backend::Compute))
            .unwrap()
            .prepasses_run();
        (runs, plugin_bytes(&r, stack[0].uid))
    };
    // the kernel's phase animates on the fly without recomputing anything; precomputed,
    // it reruns the pre-pass
    let mut animated = fly.clone();
    animated
        .params
        .set("kernel", ParamValue::Enum("periodic".into()));
    let s = settings(32, 32, Backend::Compute);
    for (mode, reruns) in [("on_the_fly", 0), ("precomputed", 1)] {
        animated.params.set("mode", ParamValue::Enum(mode.into()));
        let mut r = Renderer::new(gpu(), vol.clone()).unwrap();
        let mut frames = Vec::new();
        for phase in [0.0, 120.0] {
            animated.params.set("phase_deg", ParamValue::Float(phase));
            let st = vec![animated.clone(), instance("classify.tf1d")];
            r.update_stack(&st, TargetFormat::Rgba32Float).unwrap();
            let stats = r.render(&s).unwrap();
            if phase > 0.0 {
                assert_eq!(stats.prepasses_run(), reruns, "{mode}");
                assert!(stats.volume_passes_run.is_empty(), "{mode}");
            }
            frames.push(r.read_pixels().unwrap().2);
        }
        let moved = gpu_delta_e_rms(&frames[1], &frames[0], 32, 32);
        assert!(moved > 0.5, "{mode}: the phase moves the ripple ({moved})");
    }
    let mut pre = fly.clone();
    pre.params
        .set("mode", ParamValue::Enum("precomputed".into()));
    let (fly_runs, fly_bytes) = memory(&stack);
    let (pre_runs, pre_bytes) = memory(&[pre, instance("classify.tf1d")]);
    assert_eq!((fly_runs, pre_runs), (0, 1));
    // the LIC volume (r32float on the 24×20×12 grid) is what on the fly saves
    assert_eq!(
        pre_bytes - fly_bytes,
        24 * 20 * 12 * 4,
        "{pre_bytes} vs {fly_bytes}"
    );
}

/// Shading from LIC gradients: with `flow.lic3d` in the stack, a shading plugin's
/// central and Sobel estimators differentiate the LIC on its grid (the value the
/// sample hook gives), precomputed and on the fly; the image matches the f64 twin on
/// both backends, and differs from the unlit LIC. The precomputed estimators' gradient
/// volume would be the data's: that stack is refused, naming both plugins, and the
/// last good pipeline keeps drawing.
#[test]
fn shading_from_lic_gradients_matches_its_twin() {
    use crate::reference::{delta_e_rms, gpu_and_reference};
    let vol = small_abc();
    let stack_of = |mode: &str, frequency: &str, gradient: &str| {
        let mut lic = instance("flow.lic3d");
        lic.params.set("mode", ParamValue::Enum(mode.into()));
        lic.params
            .set("frequency", ParamValue::Enum(frequency.into()));
        lic.params.set("length", ParamValue::Float(4.0));
        let mut phong = instance("shade.blinn_phong");
        phong
            .params
            .set("gradient", ParamValue::Enum(gradient.into()));
        vec![lic, instance("classify.tf1d"), phong]
    };
    for (mode, frequency, gradient) in [
        ("precomputed", "1", "central"),
        ("precomputed", "2", "sobel"),
        ("on_the_fly", "1", "central"),
    ] {
        let stack = stack_of(mode, frequency, gradient);
        // the bounds of lic_on_the_fly_matches_its_twin_without_a_prepass
        for (backend, bound) in [
            (Backend::Compute, twin_bound(Backend::Compute, false)),
            (Backend::Raster, twin_bound(Backend::Raster, true)),
        ] {
            let s = settings(48, 48, backend);
            let (px, reference) =
                gpu_and_reference(vol.clone(), &stack, TargetFormat::Rgba32Float, &s);
            assert!(
                reference.iter().filter(|p| p[3] > 0.05).count() > 48 * 48 / 20,
                "the volume is visible"
            );
            let rms = delta_e_rms(&px, &reference, 48, 48);
            let (unlit, _) =
                gpu_and_reference(vol.clone(), &stack[..2], TargetFormat::Rgba32Float, &s);
            let lit = delta_e_rms(&unlit, &reference, 48, 48);
            eprintln!(
                "shading from LIC gradients, {mode} ×{frequency} {gradient}, {}: ΔE*uv RMS {rms:.4} against the twin ({lit:.2} from the unlit LIC)",
                backend.name()
            );
            assert!(lit > 2.0, "the lighting shows: {lit}");
            assert!(rms < bound, "{mode} {gradient} {}: {rms}", backend.name());
        }
    }
    let s = settings(32, 32, Backend::Compute);
    let mut r = Renderer::new(gpu(), vol.clone()).unwrap();
    let good = render(
        &mut r,
        &stack_of("precomputed", "1", "central"),
        TargetFormat::Rgba16Float,
        &s,
    );
    let e = r
        .update_stack(
            &stack_of("precomputed", "1", "precomputed_central"),
            TargetFormat::Rgba16Float,
        )
        .expect_err("a gradient volume of the data under a LIC is refused")
        .to_string();
    assert!(
        e.contains("shade.blinn_phong")
            && e.contains("flow.lic3d")
            && e.contains("central or sobel"),
        "{e}"
    );
    r.render(&s).unwrap();
    assert_eq!(good, r.read_pixels().unwrap().2);
}

/// A tornado (swirl, inflow, updraft) on 24×24×16 and a flat seed box across its
/// updraft at the bottom: `flow.arrival`'s scene.
fn tornado_scene() -> (std::sync::Arc<Volume>, vwb_render::PluginInstance) {
    let vol = std::sync::Arc::new(vector_volume(
        &vwb_render::flow::Tornado {
            center: DVec3::new(11.5, 11.5, 2.0),
            core: 4.0,
            inflow: 0.3,
            updraft: 0.4,
        },
        [24, 24, 16],
    ));
    let mut arrival = instance("flow.arrival");
    arrival
        .params
        .set("seed_max", ParamValue::Vec3([1.0, 1.0, 0.08]));
    (vol, arrival)
}

/// `flow.arrival`'s pre-pass against its f64 twin (`vwb_render::flow::arrival_at`):
/// the same voxels reached and the same times; the image against the twins on both
/// backends; playing the time reruns no pre-pass and uncovers more of the volume.
#[test]
fn arrival_volume_matches_its_twin_and_the_time_plays_without_a_prepass() {
    use crate::reference::{delta_e_rms, gpu_and_reference};
    let (vol, mut arrival) = tornado_scene();
    arrival.params.set("time", ParamValue::Float(12.0));
    let stack = vec![arrival.clone(), instance("classify.tf1d")];
    let mut r = Renderer::new(gpu(), vol.clone()).unwrap();
    let s = settings(48, 48, Backend::Compute);
    render(&mut r, &stack, TargetFormat::Rgba32Float, &s);
    let (dims, gpu_t) = r.read_prepass(arrival.uid).expect("the arrival volume");
    assert_eq!(dims, vol.dims);
    let twin = vwb_plugins::flow_arrival::arrival_of(&vol, &arrival.params);
    let vwb_plugins::flow_arrival::Agreement {
        disagree,
        reached,
        rms,
        worst,
    } = vwb_plugins::flow_arrival::Agreement::of(&gpu_t, &twin);
    eprintln!(
        "flow.arrival: {reached} of {} voxels reached, {disagree} disagree on reached/never; \
         time error RMS {rms:.2e}, worst {worst:.2e} (relative to 1 + t)",
        twin.len()
    );
    assert!(
        reached > twin.len() / 4,
        "the flow reaches a good part: {reached}"
    );
    assert!(reached < twin.len(), "and not everything");
    assert!(disagree * 1000 <= twin.len(), "{disagree} voxels disagree");
    assert!(rms < 1e-4 && worst < 1e-2, "{rms} {worst}");

    // the image against the twins (raster interpolates texture coordinates across the
    // proxy polygons: the coverage test's raster bound)
    for (backend, bound) in [
        (Backend::Compute, twin_bound(Backend::Compute, false)),
        (Backend::Raster, twin_bound(Backend::Raster, true)),
    ] {
        let s = settings(48, 48, backend);
        let (px, reference) = gpu_and_reference(vol.clone(), &stack, TargetFormat::Rgba32Float, &s);
        let rms = delta_e_rms(&px, &reference, 48, 48);
        eprintln!(
            "flow.arrival, {}: ΔE*uv RMS {rms:.4} against the twins",
            backend.name()
        );
        assert!(rms < bound, "{}: {rms}", backend.name());
    }

    // playing the time: no pre-pass, more covered at each step
    let mut last = -1.0;
    for (frame, t) in [0.5f32, 4.0, 8.0, 16.0, 1000.0].into_iter().enumerate() {
        let mut a = arrival.clone();
        a.params.set("time", ParamValue::Float(t));
        r.update_stack(&[a, instance("classify.tf1d")], TargetFormat::Rgba32Float)
            .unwrap();
        let st = r.render(&s).unwrap();
        assert_eq!(st.prepasses_run(), 0, "time {t} reran the pre-pass");
        let c = covered(&r.read_pixels().unwrap().2);
        eprintln!("flow.arrival time {t}: {:.1} % covered", c * 100.0);
        assert!(c > last, "frame {frame}: {c} after {last}");
        last = c;
    }
    // the seed is an integration input
    let mut moved = arrival.clone();
    moved
        .params
        .set("seed_max", ParamValue::Vec3([1.0, 1.0, 0.2]));
    r.update_stack(
        &[moved, instance("classify.tf1d")],
        TargetFormat::Rgba32Float,
    )
    .unwrap();
    assert_eq!(r.render(&s).unwrap().prepasses_run(), 1);
}

/// A named volume input (`volumes:` in a preset) on a grid of its own: `flow.lic3d`
/// integrates a 12×10×12 ABC field over a scalar 24×20×12 volume's LIC grid. The GPU's
/// LIC volume matches the f64 twin reading the same input (RMS ≤ 0.5/255), and so does
/// the rendered image against the reference renderer. The pre-pass reruns exactly when
/// the input resolves to another volume: not for the same volume set again, once for
/// another volume under the name and once for another name. An unknown name is refused
/// naming the plugin and the names the document has, and the last good pipeline keeps
/// drawing; the reference renderer refuses it too.
#[test]
fn a_named_vector_input_on_its_own_grid_drives_the_lic() {
    use crate::reference::delta_e_rms;
    use vwb_render::inputs::VolumeInputs;
    use vwb_render::reference::{ReferenceError, ReferenceOptions, render_reference};
    let scalar = synthetic([24, 20, 12], |x, y, z| ((x + 2 * y + 3 * z) % 17) as f32);
    let wind = std::sync::Arc::new(vector_volume(
        &Abc {
            period: 8.0,
            ..Default::default()
        },
        [12, 10, 12],
    ));
    let inputs = |v: &std::sync::Arc<Volume>| {
        let mut i = VolumeInputs::default();
        i.insert("wind", v.clone());
        i
    };
    let mut lic = instance("flow.lic3d");
    lic.params.set("field", ParamValue::Volume("wind".into()));
    lic.params.set("length", ParamValue::Float(4.0));
    let stack = vec![lic.clone(), instance("classify.tf1d")];
    let mut r = Renderer::new(gpu(), scalar.clone()).unwrap();
    r.set_inputs(inputs(&wind));
    let s = settings(48, 48, Backend::Compute);
    r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
    assert_eq!(r.render(&s).unwrap().prepasses_run(), 1);
    let px = r.read_pixels().unwrap().2;
    let (dims, gpu_lic) = r.read_prepass(lic.uid).expect("the LIC volume");
    // the LIC grid is the document's; the field is read on its own grid
    assert_eq!(dims, [24, 20, 12]);
    let twin = vwb_plugins::flow_lic3d::lic_on(&scalar, &wind, 1, &lic.params);
    let rms = rms_255(&gpu_lic, &twin.data);
    let noise = noise_volume(twin.dims, Noise::White, 1);
    let smoothing = rms_255(&noise.data, &twin.data);
    eprintln!("named input: GPU vs twin LIC RMS {rms:.2e}/255 (LIC vs noise {smoothing:.1}/255)");
    assert!(rms <= 0.5, "{rms}/255");
    assert!(
        smoothing > 20.0,
        "the field convolves the noise: {smoothing}/255"
    );
    // the same field resampled onto the document's grid would give another LIC: the
    // input is read on its own grid, not stretched as if it were the document's
    let stretched = vector_volume(
        &Abc {
            period: 8.0,
            ..Default::default()
        },
        [24, 20, 12],
    );
    let other = vwb_plugins::flow_lic3d::lic_on(&scalar, &stretched, 1, &lic.params);
    assert!(rms_255(&other.data, &twin.data) > 5.0 * rms.max(0.01));
    // the reference renderer reads the same input
    let opts = ReferenceOptions {
        inputs: inputs(&wind),
        ..Default::default()
    };
    let reference = render_reference(&scalar, &stack, &s, &opts).unwrap();
    let visible = reference.pixels.iter().filter(|p| p[3] > 0.05).count();
    assert!(
        visible > 48 * 48 / 20,
        "the volume is visible ({visible} pixels)"
    );
    let image = delta_e_rms(&px, &reference.pixels, 48, 48);
    eprintln!("named input: image ΔE*uv RMS {image:.4} against the twin");
    assert!(image < twin_bound(Backend::Compute, false), "{image}");
    let e = render_reference(&scalar, &stack, &s, &ReferenceOptions::default()).unwrap_err();
    assert!(matches!(e, ReferenceError::Input { .. }), "{e}");

    // reruns: the same volume again, none; another volume under the name, one;
    // the document's own (scalar: no flow), one
    let runs = |r: &mut Renderer, stack: &[vwb_render::PluginInstance]| {
        r.update_stack(stack, TargetFormat::Rgba32Float).unwrap();
        r.render(&s).unwrap().prepasses_run()
    };
    r.set_inputs(inputs(&wind));
    assert_eq!(runs(&mut r, &stack), 0);
    let turned = std::sync::Arc::new(vector_volume(
        &Rotation {
            center: DVec3::new(5.5, 4.5, 5.5),
        },
        [12, 10, 12],
    ));
    r.set_inputs(inputs(&turned));
    assert_eq!(runs(&mut r, &stack), 1);
    let (_, rotated) = r.read_prepass(lic.uid).unwrap();
    assert!(
        rms_255(&rotated, &gpu_lic) > 5.0,
        "another field, another LIC"
    );
    let mut own = lic.clone();
    own.params.set("field", ParamValue::Volume(String::new()));
    assert_eq!(runs(&mut r, &[own.clone(), instance("classify.tf1d")]), 1);
    let (_, plain) = r.read_prepass(lic.uid).unwrap();
    let twin_plain = vwb_plugins::flow_lic3d::lic_of(&scalar, 1, &own.params);
    assert!(rms_255(&plain, &twin_plain.data) <= 0.5);

    // an unknown name: refused, naming the plugin and the known names; the last good
    // pipeline keeps drawing
    let mut lost = lic.clone();
    lost.params.set("field", ParamValue::Volume("gust".into()));
    let e = r
        .update_stack(
            &[lost, instance("classify.tf1d")],
            TargetFormat::Rgba32Float,
        )
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("flow.lic3d") && e.contains("no volume named 'gust'") && e.contains("wind"),
        "{e}"
    );
    r.render(&s).expect("the last good pipeline draws");
}

/// The bound on a pass volume resampled from the 25×14×8 storm onto another grid,
/// relative to its largest value: a GPU's 8-bit trilinear weights (NVIDIA) move a
/// value by up to 1/512 of a voxel difference (the H200: 1.25e-3 of 0.94 in `speed`,
/// 3.1e-4 of 0.20 in `facing`).
fn resampled_bound() -> f64 {
    adapter_bound(1e-4, 3e-3)
}

/// The plugin contract's chain of volume passes over a named 3-component input: the
/// storm's wind (25×14×8, u, v, w) beside a scalar 20×16×12 volume. `test.vector_passes`
/// runs three passes on the volume's grid, each reading the one before (speed sampled
/// from the input, a blur, a gradient magnitude); each target matches the f64 twin,
/// and so does the image. Its gain reruns nothing, the camera nothing; the same input
/// set again reruns nothing, another volume under the name reruns all three. With its
/// view pass on, a camera move reruns that pass alone, whose target follows the
/// camera as the twin's does; in an atlas it reruns per camera and each tile is its
/// single render.
#[test]
fn three_chained_volume_passes_over_a_named_vector_input() {
    use crate::reference::delta_e_rms;
    use vwb_render::inputs::VolumeInputs;
    use vwb_render::reference::{ReferenceOptions, render_reference};
    let storm = vwb_lab::headless::load_volume(&vwb_render::preset::VolumeSource::Sample(
        "storm_wind".into(),
    ))
    .expect("the storm sample");
    assert_eq!((storm.dims, storm.components), ([25, 14, 8], 3));
    let scalar = synthetic([20, 16, 12], |x, y, z| (x + y + z) as f32);
    let mut inputs = VolumeInputs::default();
    inputs.insert("storm", storm.clone());
    let mut passes = instance("test.vector_passes");
    passes
        .params
        .set("field", ParamValue::Volume("storm".into()));
    let stack = vec![passes.clone(), instance("classify.tf1d")];
    let mut r = Renderer::new(gpu(), scalar.clone()).unwrap();
    r.set_inputs(inputs.clone());
    r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
    let s = settings(48, 48, Backend::Compute);
    let stats = r.render(&s).unwrap();
    assert_eq!(
        stats.volume_passes_run.len(),
        3,
        "{:?}",
        stats.volume_passes_run
    );
    let px = r.read_pixels().unwrap().2;
    let field = vwb_plugins::test_vector_passes::input_field(&storm);
    let (speed, blurred, edges) =
        vwb_plugins::test_vector_passes::pass_volumes(scalar.dims, Some(&field));
    for (name, twin) in [("speed", &speed), ("blurred", &blurred), ("edges", &edges)] {
        let (dims, gpu_t) = r.read_pass_target(passes.uid, name).expect("the target");
        assert_eq!(dims, scalar.dims, "{name}");
        let top = twin.data.iter().cloned().fold(0.0f64, f64::max);
        let worst = gpu_t
            .iter()
            .zip(&twin.data)
            .map(|(g, t)| (*g as f64 - t).abs())
            .fold(0.0f64, f64::max);
        eprintln!("test.vector_passes {name}: max |GPU − twin| {worst:.2e} (max {top:.3})");
        assert!(
            top > 0.0 && worst <= resampled_bound() * top.max(1.0),
            "{name}: {worst} of {top}"
        );
    }
    let opts = ReferenceOptions {
        inputs,
        ..Default::default()
    };
    let reference = render_reference(&scalar, &stack, &s, &opts).unwrap();
    let visible = reference.pixels.iter().filter(|p| p[3] > 0.05).count();
    assert!(visible > 48 * 48 / 20, "visible: {visible}");
    let image = delta_e_rms(&px, &reference.pixels, 48, 48);
    eprintln!("test.vector_passes: image ΔE*uv RMS {image:.4} against the twin");
    assert!(image < twin_bound(Backend::Compute, false), "{image}");

    let runs = |r: &mut Renderer, stack: &[vwb_render::PluginInstance], s| {
        r.update_stack(stack, TargetFormat::Rgba32Float).unwrap();
        r.render(s).unwrap().volume_passes_run.len()
    };
    let mut brighter = passes.clone();
    brighter.params.set("gain", ParamValue::Float(16.0));
    let stack = vec![brighter, instance("classify.tf1d")];
    assert_eq!(runs(&mut r, &stack, &s), 0);
    let mut turned = s;
    turned.camera.yaw_deg += 50.0;
    assert_eq!(runs(&mut r, &stack, &turned), 0);
    let mut again = VolumeInputs::default();
    again.insert("storm", storm.clone());
    r.set_inputs(again);
    assert_eq!(runs(&mut r, &stack, &s), 0);
    let mut calm = VolumeInputs::default();
    calm.insert(
        "storm",
        std::sync::Arc::new(vector_volume(&Abc::default(), [10, 10, 10])),
    );
    r.set_inputs(calm);
    assert_eq!(runs(&mut r, &stack, &s), 3);

    // a view pass: the fourth pass reads the camera; a camera move reruns it alone,
    // a parameter no pass reads reruns nothing; each frame's target is the twin's for
    // that camera, and so is the image
    r.set_inputs(opts.inputs.clone());
    let mut viewed = passes.clone();
    viewed.params.set("view", ParamValue::Bool(true));
    let stack = vec![viewed.clone(), instance("classify.tf1d")];
    assert_eq!(runs(&mut r, &stack, &s), 4);
    let vbox = r.volume_box();
    let (lo, hi) = (vbox.min.as_dvec3(), vbox.max.as_dvec3());
    let mut seen = Vec::new();
    let cameras = [s, turned, turned, s];
    for (k, cam) in cameras.iter().enumerate() {
        let ran = runs(&mut r, &stack, cam);
        // frame 0 has the camera of the frame above, frame 2 that of frame 1
        assert_eq!(ran, if k % 2 == 0 { 0 } else { 1 }, "frame {k}");
        let view = vwb_render::plugin::CpuView::from_view(
            &cam.camera.view(cam.width as f32 / cam.height as f32),
            0.0,
            1.0,
        );
        let twin = vwb_plugins::test_vector_passes::facing_volume(&blurred, &view, (lo, hi));
        let (_, gpu_t) = r.read_pass_target(viewed.uid, "facing").unwrap();
        let worst = gpu_t
            .iter()
            .zip(&twin.data)
            .map(|(g, t)| (*g as f64 - t).abs())
            .fold(0.0f64, f64::max);
        let top = twin.data.iter().cloned().fold(0.0f64, f64::max);
        assert!(
            top > 0.0 && worst <= resampled_bound() * top.max(1.0),
            "frame {k}: {worst} of {top}"
        );
        seen.push(gpu_t);
    }
    assert!(
        rms_255(&seen[0], &seen[1]) > 1.0,
        "the view pass follows the camera"
    );
    runs(&mut r, &stack, &turned);
    let px = r.read_pixels().unwrap().2;
    let reference = render_reference(&scalar, &stack, &turned, &opts).unwrap();
    let image = delta_e_rms(&px, &reference.pixels, 48, 48);
    eprintln!("test.vector_passes with a view pass: image ΔE*uv RMS {image:.4} against the twin");
    assert!(image < twin_bound(Backend::Compute, false), "{image}");
    // an atlas draws many cameras in one submission: the view pass reruns before
    // each tile whose camera differs from the last (here turned → s → turned → turned
    // → s: three runs), and each tile is its single render
    let cameras = [s, turned, turned, s];
    let tiles: Vec<_> = cameras
        .iter()
        .map(|c| vwb_render::renderer::AtlasTile {
            camera: c.camera,
            stack: &stack,
        })
        .collect();
    let atlas = r
        .render_atlas(&tiles, &s, TargetFormat::Rgba32Float, 2)
        .unwrap();
    assert_eq!(atlas.volume_passes_run, 3);
    for (i, cam) in cameras.iter().enumerate() {
        runs(&mut r, &stack, cam);
        let single: Vec<[f64; 4]> = r
            .read_pixels()
            .unwrap()
            .2
            .iter()
            .map(|p| p.map(f64::from))
            .collect();
        let e = delta_e_rms(&atlas.tile_pixels(i), &single, 48, 48);
        assert!(
            e <= 0.01,
            "tile {i}: ΔE*uv RMS {e} against its single render"
        );
    }
    let (d, _) = diff(&rgb(&atlas.tile_pixels(0)), &rgb(&atlas.tile_pixels(1)));
    assert!(d > 1e-3, "the tiles see different cameras: {d}");
}

/// `flow.lic3d` on the fly at its longest streamlines (L = 32 voxels, h = 0.25: 7
/// integrals of 2 × 128 steps a sample under central differences, ~1 800 loop
/// iterations) lit by Blinn–Phong: every ray takes all its samples and the image
/// matches the f64 twin. On llvmpipe one invocation gets 65 535 loop iterations, which
/// such a ray spent after ~35 samples; its frame (3.4 ΔE*uv RMS from the twin, 5 % of
/// the pixels beyond 6, before the march was split) now marches in parts of the size
/// the plugin's declared loops allow (render/src/renderer/march_parts.rs).
#[test]
fn lic_on_the_fly_at_its_longest_streamlines_takes_every_sample() {
    use crate::reference::{delta_e_rms, gpu_and_reference};
    let vol = small_abc();
    let mut lic = instance("flow.lic3d");
    lic.params
        .set("mode", ParamValue::Enum("on_the_fly".into()));
    lic.params.set("length", ParamValue::Float(32.0));
    lic.params.set("step", ParamValue::Float(0.25));
    let mut phong = instance("shade.blinn_phong");
    phong
        .params
        .set("gradient", ParamValue::Enum("central".into()));
    let stack = vec![lic, instance("classify.tf1d"), phong];
    // four slices a voxel: ~100 samples a ray
    let s = FrameSettings {
        slice_spacing: 0.25,
        ..settings(16, 16, Backend::Compute)
    };
    let (px, reference) = gpu_and_reference(vol.clone(), &stack, TargetFormat::Rgba32Float, &s);
    assert!(
        reference.iter().filter(|p| p[3] > 0.05).count() > 16 * 16 / 20,
        "the volume is visible"
    );
    let rms = delta_e_rms(&px, &reference, 16, 16);
    eprintln!("flow.lic3d on the fly, L 32, h 0.25, lit: ΔE*uv RMS {rms:.4} against the twin");
    assert!(rms < twin_bound(Backend::Compute, false), "{rms}");
    let mut r = Renderer::new(gpu(), vol).unwrap();
    r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
    let stats = r.render(&s).unwrap();
    assert_eq!(stats.loop_limited, 0);
    if !crate::common::on_gpu() {
        // 2 + 7 · 261 loop iterations a sample: 32 slices a part
        assert!(
            stats.march_parts >= stats.slices.div_ceil(32) && stats.slices > 64,
            "{} slices in {} parts",
            stats.slices,
            stats.march_parts
        );
    }
}
