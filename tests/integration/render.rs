//! Renders on the Vulkan device: both backends agree, checked-in reference images,
//! per-slice state against its closed form, pre-passes fill every z slice and rerun
//! only when needed, and the edge cases (camera inside, NaN voxels, early termination).

use std::path::{Path, PathBuf};

use vwb_plugins::test_slice_shadow::homogeneous;
use vwb_plugins::test_smooth::SmoothTwin;
use vwb_render::Renderer;
use vwb_render::TargetFormat;
use vwb_render::params::ParamValue;
use vwb_render::plugin::CpuContext;
use vwb_render::preset::Document;
use vwb_render::renderer::{Backend, FrameSettings, HULL_RAYS_SHARE, HullProxy, HullRays};
use vwb_render::tf::{TfCurve, TfPoint};

use crate::common::*;
use crate::reference::{delta_e_rms, gpu_delta_e_rms};

const ONE_LEVEL: f64 = 1.0 / 255.0;

#[test]
fn raster_and_compute_agree_on_the_demo() {
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let stack = Document::load(&repo().join("presets/demo.ron"), &registry())
        .unwrap()
        .document
        .stack;
    for target in [TargetFormat::Rgba16Float, TargetFormat::Rgba32Float] {
        let a = rgb(&render(
            &mut r,
            &stack,
            target,
            &settings(128, 128, Backend::Raster),
        ));
        let b = rgb(&render(
            &mut r,
            &stack,
            target,
            &settings(128, 128, Backend::Compute),
        ));
        let (rms, max) = diff(&a, &b);
        eprintln!(
            "{target:?}: raster vs compute RMS {:.5} ({:.3} levels), max {max:.4}",
            rms,
            rms / ONE_LEVEL
        );
        assert!(mean_luma(&a) > 0.05, "the head is visible");
        assert!(rms < ONE_LEVEL, "{target:?}: RMS {rms} ≥ 1/255");
    }
}

fn png_rgb(path: &Path) -> Vec<[f64; 3]> {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8();
    img.pixels()
        .map(|p| p.0.map(|v| v as f64 / 255.0))
        .collect()
}

/// Renders a preset at 128² and compares with tests/reference_images/<name>.png.
fn check_reference(preset: &str, name: &str, backend: Backend) {
    let golden = repo()
        .join("tests/reference_images")
        .join(format!("{name}.png"));
    check_golden(
        &repo().join("presets").join(preset),
        &[(backend, golden)],
        128,
        1.5,
    );
}

/// Renders a preset at `side`² on each backend of `goldens` (one renderer: the volume,
/// its passes and the stack are set up once) and compares with that backend's golden
/// image (`VWB_BLESS=1` writes it). Tolerance: RMS < `rms_levels`/255 and max < 32/255 —
/// lavapipe reproduces the images to the bit; real GPUs filter with fewer bits of weight
/// precision (about 8 on NVIDIA).
fn check_golden(preset: &Path, goldens: &[(Backend, PathBuf)], side: u32, rms_levels: f64) {
    let loaded = Document::load(preset, &registry()).unwrap();
    let doc = loaded.document;
    let volume = vwb_lab::headless::load_volume(&doc.volume).unwrap();
    let mut r = Renderer::new(gpu(), volume).unwrap();
    r.set_inputs(vwb_lab::headless::inputs_for(&doc).unwrap());
    r.set_empty_space_skipping(doc.render.empty_space_skipping);
    r.update_stack(&doc.stack, doc.render.target).unwrap();
    for (backend, golden) in goldens {
        let name = golden.file_stem().unwrap().to_string_lossy().to_string();
        let mut s = doc.frame_settings();
        s.width = side;
        s.height = side;
        s.backend = *backend;
        let (img, _, _) =
            vwb_lab::headless::render_image(&mut r, &s, doc.render.background).unwrap();
        if bless() || !golden.exists() {
            vwb_lab::headless::save_png(&img, golden).unwrap();
            assert!(
                bless(),
                "{} did not exist; wrote it — rerun",
                golden.display()
            );
            continue;
        }
        let want = png_rgb(golden);
        let got: Vec<[f64; 3]> = img
            .pixels()
            .map(|p| p.0.map(|v| v as f64 / 255.0))
            .collect();
        let (rms, max) = diff(&want, &got);
        eprintln!(
            "{name}: RMS {:.3} levels, max {:.0} levels",
            rms / ONE_LEVEL,
            max / ONE_LEVEL
        );
        assert!(
            rms < rms_levels * ONE_LEVEL,
            "{name}: RMS {} levels",
            rms / ONE_LEVEL
        );
        // a GPU's few filtering bits shift a pixel or two of shade.dos's raster
        // occlusion, which carries from slice to slice (95 levels on an H200)
        let max_levels = adapter_bound(32.0, 128.0);
        assert!(
            max < max_levels * ONE_LEVEL,
            "{name}: max {} levels",
            max / ONE_LEVEL
        );
    }
}

/// Every shipped preset on both backends at 64² against its golden image in
/// tests/goldens (RMS ≤ 1/255): a change to the renderer or a plugin that changes what
/// a shipped preset shows fails here. Regenerate deliberately with `VWB_BLESS=1`.
#[test]
fn every_shipped_preset_matches_its_golden_images() {
    let dir = repo().join("tests/goldens");
    std::fs::create_dir_all(&dir).unwrap();
    let presets = crate::presets::shipped_presets();
    let mut names = Vec::new();
    for preset in &presets {
        let stem = preset.file_stem().unwrap().to_string_lossy().to_string();
        let files = [(Backend::Raster, "raster"), (Backend::Compute, "compute")]
            .map(|(backend, tag)| (backend, format!("{stem}_{tag}.png")));
        let goldens = files.each_ref().map(|(backend, f)| (*backend, dir.join(f)));
        check_golden(preset, &goldens, 64, adapter_bound(1.0, 2.0));
        names.extend(files.map(|(_, f)| f));
    }
    // no golden without its preset (a removed or renamed preset takes its images along)
    for e in std::fs::read_dir(&dir).unwrap() {
        let f = e.unwrap().file_name().to_string_lossy().to_string();
        assert!(
            names.contains(&f),
            "tests/goldens/{f} has no shipped preset"
        );
    }
}

#[test]
fn reference_image_demo_raster() {
    check_reference("demo.ron", "demo_raster", Backend::Raster);
}

#[test]
fn reference_image_demo_compute() {
    check_reference("demo_compute.ron", "demo_compute", Backend::Compute);
}

#[test]
fn reference_image_demo_slice_shadow() {
    check_reference(
        "demo_slice_shadow.ron",
        "demo_slice_shadow",
        Backend::Raster,
    );
}

#[test]
fn reference_image_ct_head() {
    check_reference("ct_head.ron", "ct_head", Backend::Raster);
}

fn flat_tf(c: f32, a: f32) -> ParamValue {
    ParamValue::Tf(TfCurve::new(vec![
        TfPoint {
            x: 0.0,
            color: [c, c, c, a],
        },
        TfPoint {
            x: 1.0,
            color: [c, c, c, a],
        },
    ]))
}

/// `cs_main_raw`, the raw-sampling benchmark ([`Renderer::set_raw_samples`]), takes
/// exactly the samples of the compute march. Under an orthographic camera every sample's
/// step is one slice spacing, so a constant opacity a composites to 1 − (1 − a)^n over a
/// ray's n samples: n read back from that image must be the raw kernel's count, pixel
/// for pixel. Its sum is of the values it fetched: n where the volume is 1, less where a
/// ray passes the one voxel of 0. Both loop over `sample_run`'s slices (the first to the
/// last in the box, found by stepping over the range's margins), so the count is also
/// held against the f64 reference's, which tests every slice of its range: equal but
/// where a sample lies on a face within rounding.
#[test]
fn raw_samples_take_the_samples_of_the_march() {
    use vwb_render::{Camera, Projection};
    let vol = synthetic(
        [24, 20, 16],
        |x, y, z| if x + y + z == 0 { 0.0 } else { 1.0 },
    );
    let mut r = Renderer::new(gpu(), vol).unwrap();
    let a = 0.02;
    r.update_stack(
        &[tf_constant([1.0, 1.0, 1.0, a])],
        TargetFormat::Rgba32Float,
    )
    .unwrap();
    let camera = Camera {
        projection: Projection::Orthographic { height: 1.6 },
        yaw_deg: 37.0,
        pitch_deg: 23.0,
        ..Default::default()
    };
    let s = FrameSettings {
        camera,
        width: 48,
        height: 48,
        slice_spacing: 1.0,
        backend: Backend::Compute,
        early_termination: None,
    };
    r.render(&s).unwrap();
    let dvr = r.read_pixels().unwrap().2;
    r.set_raw_samples(true);
    r.render(&s).unwrap();
    let raw = r.read_pixels().unwrap().2;
    let reference = vwb_render::reference::render_reference(
        r.volume(),
        &[tf_constant([1.0, 1.0, 1.0, a])],
        &s,
        &Default::default(),
    )
    .unwrap();
    let count = |alpha: f64| ((1.0 - alpha).ln() / (1.0 - a as f64).ln()).round();
    let mut off = 0;
    for y in 0..48 {
        for x in 0..48 {
            let gpu = count(dvr[(y * 48 + x) as usize][3] as f64);
            let cpu = count(reference.pixel(x, y)[3]);
            assert!(
                (gpu - cpu).abs() <= 1.0,
                "pixel ({x}, {y}): {gpu} samples, reference {cpu}"
            );
            off += (gpu != cpu) as u32;
        }
    }
    assert!(
        off <= 48 * 48 / 100,
        "{off} pixels' sample counts off the reference's"
    );
    let (mut hit, mut short) = (0, 0.0);
    for (i, (d, w)) in dvr.iter().zip(&raw).enumerate() {
        let n = ((1.0 - d[3] as f64).ln() / (1.0 - a as f64).ln()).round();
        assert_eq!(w[1] as f64, n, "pixel {i}: raw count against the march's");
        assert!(
            w[0] <= w[1] + 1e-4 && w[0] >= w[1] - 2.0,
            "pixel {i}: sum {} of {} samples",
            w[0],
            w[1]
        );
        hit += (n > 0.0) as u32;
        short += (w[1] - w[0]) as f64;
    }
    assert!(hit > 48 * 48 / 4, "{hit} pixels see the box");
    assert!(short > 0.01, "no ray fetched the voxel of 0");
    // and back: the march again
    r.set_raw_samples(false);
    r.render(&s).unwrap();
    assert_eq!(r.read_pixels().unwrap().2, dvr);
}

#[test]
fn per_slice_state_matches_its_closed_form_on_both_backends() {
    // homogeneous medium: every sample has colour c and opacity a
    let vol = synthetic(
        [32, 32, 32],
        |x, y, z| if x + y + z == 0 { 0.0 } else { 1.0 },
    );
    let mut r = Renderer::new(gpu(), vol).unwrap();
    let mut tf = instance("classify.tf1d");
    let (c, a) = (0.8, 0.05);
    tf.params.set("tf", flat_tf(c, a));
    let mut shadow = instance("test.slice_shadow");
    shadow.params.set("strength", ParamValue::Float(1.0));
    let stack = vec![tf.clone(), shadow.clone()];
    let s = ortho_axis(32, 32, Backend::Raster);
    let n = r.plan(&s).unwrap().count;
    let (want_c, want_a) = homogeneous(c as f64, a as f64, n, 1.0);
    let mut images = Vec::new();
    for backend in [Backend::Raster, Backend::Compute] {
        let s = ortho_axis(32, 32, backend);
        r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
        let stats = r.render(&s).unwrap();
        assert!(stats.per_slice_mode);
        let px = r.read_pixels().unwrap().2;
        let centre = px[16 * 32 + 16];
        eprintln!(
            "{backend:?}: centre {centre:?}, closed form ({want_c:.5}, {want_a:.5}), {n} slices"
        );
        assert!(
            (centre[0] as f64 - want_c).abs() < 2e-3,
            "{backend:?} colour"
        );
        assert!(
            (centre[3] as f64 - want_a).abs() < 2e-3,
            "{backend:?} alpha"
        );
        images.push(rgb(&px));
    }
    let (rms, _) = diff(&images[0], &images[1]);
    assert!(rms < ONE_LEVEL, "per-slice raster vs compute RMS {rms}");

    // strength 0 equals the image without the plugin
    let mut off = shadow.clone();
    off.params.set("strength", ParamValue::Float(0.0));
    let with = rgb(&render(
        &mut r,
        &[tf.clone(), off],
        TargetFormat::Rgba32Float,
        &s,
    ));
    let without = rgb(&render(&mut r, &[tf], TargetFormat::Rgba32Float, &s));
    let (rms, max) = diff(&with, &without);
    assert!(
        max < 1e-5,
        "strength 0 changes the image: rms {rms} max {max}"
    );
}

#[test]
fn prepass_fills_every_z_slice_and_reruns_only_when_needed() {
    // values vary along z so that a pre-pass writing only z = 0 (wgpu's GL bug) fails
    let dims = [12, 10, 9];
    let vol = synthetic(dims, |x, y, z| {
        (x as f32 * 0.5 + y as f32 * 0.25 + z as f32 * 3.0).sin()
    });
    let mut r = Renderer::new(gpu(), vol.clone()).unwrap();
    let mut smooth = instance("test.smooth");
    smooth.params.set("radius", ParamValue::Int(0));
    let mut stack = vec![smooth, instance("classify.tf1d")];
    r.update_stack(&stack, TargetFormat::Rgba16Float).unwrap();
    let s = ortho_axis(16, 16, Backend::Compute);
    let first = r.render(&s).unwrap();
    assert_eq!(first.prepasses_run(), 1);
    assert_eq!(first.prepasses, ["test.smooth/prepass"]);
    let again = r.render(&s).unwrap();
    assert_eq!(again.prepasses_run(), 0, "nothing changed");
    assert!(again.prepasses.is_empty());
    let scalars = vol.normalized_scalars();
    let (pdims, texels) = r.read_prepass(stack[0].uid).unwrap();
    assert_eq!(pdims, dims);
    for (i, v) in scalars.iter().enumerate() {
        assert!(
            (texels[i] - v).abs() < 1e-6,
            "texel {i} (z = {}) not written",
            i / 120
        );
    }
    // `amount` is not a pre-pass input
    stack[0].params.set("amount", ParamValue::Float(0.5));
    r.update_stack(&stack, TargetFormat::Rgba16Float).unwrap();
    assert_eq!(r.render(&s).unwrap().prepasses_run(), 0);
    // `radius` is
    stack[0].params.set("radius", ParamValue::Int(1));
    r.update_stack(&stack, TargetFormat::Rgba16Float).unwrap();
    assert_eq!(r.render(&s).unwrap().prepasses_run(), 1);
    let (_, texels) = r.read_prepass(stack[0].uid).unwrap();
    let twin = SmoothTwin {
        radius: 1,
        amount: 1.0,
    };
    let ctx = CpuContext::new(&vol, &scalars);
    for z in 0..dims[2] {
        for y in [0, 4, 9] {
            for x in [0, 5, 11] {
                let want = twin.smoothed_voxel(&ctx, [x as i64, y as i64, z as i64]);
                let got = texels[((z * dims[1] + y) * dims[0] + x) as usize] as f64;
                assert!((got - want).abs() < 1e-5, "({x},{y},{z}): {got} vs {want}");
            }
        }
    }
}

#[test]
fn camera_inside_the_volume_renders_on_both_backends() {
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let stack = vec![instance("classify.tf1d")];
    let mut images = Vec::new();
    for backend in [Backend::Raster, Backend::Compute] {
        let mut s = settings(64, 64, backend);
        s.camera.distance = 0.15;
        let px = render(&mut r, &stack, TargetFormat::Rgba32Float, &s);
        assert!(px.iter().all(|p| p.iter().all(|v| v.is_finite())));
        let img = rgb(&px);
        assert!(
            mean_luma(&img) > 0.01,
            "{backend:?}: inside view is not empty"
        );
        images.push(img);
    }
    let (rms, _) = diff(&images[0], &images[1]);
    assert!(rms < ONE_LEVEL, "inside: raster vs compute RMS {rms}");
}

#[test]
fn nan_and_inf_voxels_give_finite_images() {
    let vol = synthetic([16, 16, 16], |x, y, z| match (x + y + z) % 7 {
        0 => f32::NAN,
        1 => f32::INFINITY,
        2 => f32::NEG_INFINITY,
        _ => (x * y + z) as f32,
    });
    assert!(vol.non_finite > 0);
    let mut r = Renderer::new(gpu(), vol).unwrap();
    for backend in [Backend::Raster, Backend::Compute] {
        let px = render(
            &mut r,
            &[instance("classify.tf1d")],
            TargetFormat::Rgba16Float,
            &settings(32, 32, backend),
        );
        assert!(
            px.iter().all(|p| p.iter().all(|v| v.is_finite())),
            "{backend:?}"
        );
    }
}

#[test]
fn early_termination_stops_opaque_rays_without_visible_change() {
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let mut tf = instance("classify.tf1d");
    tf.params.set("opacity", ParamValue::Float(8.0));
    let stack = vec![tf];
    let mut s = settings(64, 64, Backend::Compute);
    let full = rgb(&render(&mut r, &stack, TargetFormat::Rgba32Float, &s));
    s.early_termination = Some(0.995);
    let early = rgb(&render(&mut r, &stack, TargetFormat::Rgba32Float, &s));
    let (rms, max) = diff(&full, &early);
    assert!(max < 0.006, "early termination changed a pixel by {max}");
    assert!(rms < ONE_LEVEL);
}

/// Early termination in the raster backend (issue 23, item 2): a depth mask drawn every
/// `raster_et_interval()` slices stops the rays that reached the threshold at the end
/// of that run of slices, as the reference renderer models it, in the single-pass and
/// the per-slice (slice-state) paths alike; the compute backend stops them at the slice
/// itself, and without a threshold no ray stops.
#[test]
fn raster_early_termination_stops_rays_at_the_end_of_a_run() {
    // deep along the view axis (about 100 slices) and thin per slice, so that the
    // compute backend (≈ 14 slices), a run of 32 slices and all slices differ clearly
    let vol = synthetic(
        [32, 32, 96],
        |x, y, z| if x + y + z == 0 { 0.0 } else { 1.0 },
    );
    let mut tf = instance("classify.tf1d");
    tf.params.set("tf", flat_tf(0.8, 0.05));
    let mut shadow = instance("test.slice_shadow");
    shadow.params.set("strength", ParamValue::Float(0.5));
    assert!(vwb_render::renderer::raster_et_interval() > 1);
    for stack in [vec![tf.clone()], vec![tf.clone(), shadow]] {
        let per_slice = stack.len() > 1;
        let mut alphas = Vec::new();
        for (backend, et) in [
            (Backend::Raster, None),
            (Backend::Raster, Some(0.5)),
            (Backend::Compute, Some(0.5)),
        ] {
            // no slice plane on a face of the box, where rounding decides per pixel
            // whether the face's sample is taken and so which run a threshold falls in
            let s = FrameSettings {
                early_termination: et,
                slice_spacing: 0.93,
                ..ortho_axis(32, 32, backend)
            };
            let (px, reference) = crate::reference::gpu_and_reference(
                vol.clone(),
                &stack,
                TargetFormat::Rgba32Float,
                &s,
            );
            let e = delta_e_rms(&px, &reference, 32, 32);
            let (gpu_a, ref_a) = (px[16 * 32 + 16][3] as f64, reference[16 * 32 + 16][3]);
            eprintln!(
                "per-slice {per_slice}, {backend:?} {et:?}: centre α {gpu_a:.4} (reference \
                 {ref_a:.4}), ΔE {e:.3}"
            );
            assert!(
                e < twin_bound(backend, per_slice),
                "{backend:?} {et:?}: ΔE {e}"
            );
            assert!((gpu_a - ref_a).abs() < 2e-3, "{backend:?} {et:?}");
            alphas.push(gpu_a);
        }
        assert!(
            alphas[2] < alphas[1] - 0.05 && alphas[1] < alphas[0] - 0.05,
            "compute stops first, raster at the end of the run, neither without ET: {alphas:?}"
        );
    }
}

/// Where raster early termination could cull whole screen tiles (issue 23, item 2;
/// docs/perf.md, "Early termination and skipping in the raster backend"). Per preset
/// at 512²: the eye buffer's opacity at the start of every run of
/// `raster_et_interval()` slices (a compute render of the slices before it, through
/// clip.shapes' camera slab), and per pixel the slices whose plane its ray meets inside
/// the box. A fragment is dead where its pixel had reached 0.99 before its run (the
/// depth mask drops it, at a cost); it could be culled whole where every pixel of its
/// tile had. Prints the share of pixels that reach 0.99 by the last slice, of
/// fragments that are dead, and of dead fragments that tiles of 16, 32 and 64 pixels
/// could cull: the most a tile-culling raster backend can leave out. Run:
/// `bash bench/ignored_test.sh raster_termination_tile_liveness`.
#[test]
#[ignore = "benchmark: bash bench/ignored_test.sh raster_termination_tile_liveness"]
fn raster_termination_tile_liveness() {
    use glam::DVec4;
    let (threshold, size, run) = (0.99, 512u32, vwb_render::renderer::raster_et_interval());
    let tiles = [16u32, 32, 64];
    println!(
        "| preset | slices | pixels reaching {threshold} | dead fragments | of them in stopped tiles: 16 px | 32 px | 64 px |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for preset in [
        "presets/ct_shade_none.ron",
        "presets/demo.ron",
        "presets/nuclei_shade_phong.ron",
    ] {
        let (doc, volume) = preset_scene(preset);
        let s = FrameSettings {
            width: size,
            height: size,
            backend: Backend::Compute,
            early_termination: None,
            ..doc.frame_settings()
        };
        let mut r = Renderer::new(gpu(), volume).unwrap();
        r.set_inputs(vwb_lab::headless::inputs_for(&doc).unwrap());
        let vbox = *r.volume_box();
        let view = s.camera.view(1.0);
        let plan = vwb_render::slicing::SlicePlan::new(&view, &vbox, s.slice_spacing).unwrap();
        // per pixel, the slices [lo, hi] whose plane its ray meets inside the box
        let inv = view.view_proj().as_dmat4().inverse();
        let eye = view.eye.as_dvec3();
        let fwd = view.forward.as_dvec3();
        let (bmin, bmax) = (vbox.min.as_dvec3(), vbox.max.as_dvec3());
        let spans: Vec<Option<(u32, u32)>> = (0..size * size)
            .map(|i| {
                let ndc = [
                    ((i % size) as f64 + 0.5) / size as f64 * 2.0 - 1.0,
                    1.0 - ((i / size) as f64 + 0.5) / size as f64 * 2.0,
                ];
                let q = inv * DVec4::new(ndc[0], ndc[1], 0.5, 1.0);
                let q = q.truncate() / q.w;
                let (o, d) = if view.perspective {
                    (eye, q - eye)
                } else {
                    (q - fwd * (q - eye).dot(fwd), fwd)
                };
                // parametrised by eye depth: o + d·t has depth t
                let d = d / d.dot(fwd);
                let o = o - d * (o - eye).dot(fwd);
                let ta = (bmin - o) / d;
                let tb = (bmax - o) / d;
                let t_in = ta.min(tb).max_element();
                let t_out = ta.max(tb).min_element();
                let (d0, ds) = (plan.d0 as f64, plan.spacing as f64);
                let lo = ((t_in - d0) / ds).ceil().max(0.0);
                let hi = ((t_out - d0) / ds).floor().min(plan.count as f64 - 1.0);
                (t_in <= t_out && lo <= hi).then_some((lo as u32, hi as u32))
            })
            .collect();
        let in_run = |span: Option<(u32, u32)>, k0: u32| {
            span.map_or(0, |(lo, hi)| {
                (hi.min(k0 + run - 1) + 1).saturating_sub(lo.max(k0)) as u64
            })
        };
        let mut slab = instance("clip.shapes");
        slab.params
            .set("shape0_kind", ParamValue::Enum("off".into()));
        slab.params.set("follow_camera", ParamValue::Bool(true));
        slab.params.set("camera_near", ParamValue::Float(0.0));
        let (mut total, mut dead) = (0u64, 0u64);
        let mut culled = [0u64; 3];
        let mut alpha = vec![0.0f32; (size * size) as usize];
        for k0 in (0..plan.count).step_by(run as usize) {
            if k0 > 0 {
                // the eye buffer after the slices before k0
                let mut stack = vec![slab.clone()];
                stack[0].params.set(
                    "camera_thickness",
                    ParamValue::Float(plan.depth(k0) - 0.5 * plan.spacing),
                );
                stack.extend(doc.stack.iter().cloned());
                r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
                r.render(&s).unwrap();
                alpha = r.read_pixels().unwrap().2.iter().map(|p| p[3]).collect();
            }
            let stopped = |i: u32| alpha[i as usize] >= threshold;
            for i in 0..size * size {
                let n = in_run(spans[i as usize], k0);
                total += n;
                if stopped(i) {
                    dead += n;
                }
            }
            for (j, &t) in tiles.iter().enumerate() {
                let g = size.div_ceil(t);
                for tile in 0..g * g {
                    let (x0, y0) = (tile % g * t, tile / g * t);
                    let pixels = || {
                        (y0..(y0 + t).min(size))
                            .flat_map(move |y| (x0..(x0 + t).min(size)).map(move |x| y * size + x))
                    };
                    if pixels().all(stopped) {
                        culled[j] += pixels().map(|i| in_run(spans[i as usize], k0)).sum::<u64>();
                    }
                }
            }
        }
        // the whole frame: how many pixels stop by the last slice
        r.update_stack(&doc.stack, TargetFormat::Rgba32Float)
            .unwrap();
        r.render(&s).unwrap();
        let px = r.read_pixels().unwrap().2;
        let reaching = px.iter().filter(|p| p[3] >= threshold).count() as f64 / px.len() as f64;
        let share = |n: u64, of: u64| n as f64 / of.max(1) as f64;
        println!(
            "| `{}` | {} | {reaching:.3} | {:.3} | {:.3} | {:.3} | {:.3} |",
            Path::new(preset).file_stem().unwrap().to_string_lossy(),
            plan.count,
            share(dead, total),
            share(culled[0], dead),
            share(culled[1], dead),
            share(culled[2], dead),
        );
        assert!(total > 0 && culled[0] >= culled[1] && culled[1] >= culled[2] && dead >= culled[0]);
    }
}

/// A shipped preset, its volume and its frame at 96² on the raster backend, with early
/// termination at `et`.
fn raster_scene(
    registry: &vwb_render::plugin::Registry,
    preset: &str,
    et: Option<f32>,
) -> (Document, std::sync::Arc<vwb_render::Volume>, FrameSettings) {
    let doc = Document::load(&repo().join("presets").join(preset), registry)
        .unwrap()
        .document;
    let volume = vwb_lab::headless::load_volume(&doc.volume).unwrap();
    let s = FrameSettings {
        width: 96,
        height: 96,
        backend: Backend::Raster,
        early_termination: et,
        ..doc.frame_settings()
    };
    (doc, volume, s)
}

/// The raster backend's proxies cut to occupied space (issue 23, item 2): beyond the
/// visible box (the occupied bricks' bounds), the polygons cut to the occupied bricks'
/// hull (`HullProxy::Cut`, `render.hull_cut`) or to cells of bricks
/// (`Renderer::set_occupied_proxy`) cover less of the box, on presets with empty
/// space, clipping, per-slice state and a 2D transfer function, and the image stays
/// the visible box's up to the rounding of the sample positions.
#[test]
fn proxies_cut_to_occupied_space_cover_less_and_keep_the_image() {
    let registry = registry();
    for preset in [
        "demo.ron",
        "demo_clip_labels.ron",
        "demo_dos.ron",
        "demo_tf2d.ron",
    ] {
        let (doc, volume, s) = raster_scene(&registry, preset, None);
        let mut images = Vec::new();
        let mut shares = Vec::new();
        // the visible box, the hull, the cells
        for (hull, cells) in [
            (HullProxy::Off, false),
            (HullProxy::Cut, false),
            (HullProxy::Off, true),
        ] {
            let mut r = Renderer::new(gpu(), volume.clone()).unwrap();
            r.set_inputs(vwb_lab::headless::inputs_for(&doc).unwrap());
            r.set_hull_proxy(hull);
            r.set_occupied_proxy(cells);
            r.update_stack(&doc.stack, doc.render.target).unwrap();
            shares.push(r.render(&s).unwrap().proxy_share.unwrap());
            images.push(rgb(&r.read_pixels().unwrap().2));
        }
        assert!(shares[0] <= 1.0, "{preset}: {shares:?}");
        assert!(mean_luma(&images[0]) > 0.02, "{preset}: something is drawn");
        // a document's render.hull_cut reaches the renderers made for it
        let mut cut = doc.clone();
        cut.render.hull_cut = true;
        let r = vwb_lab::headless::renderer_for(gpu(), &cut, volume.clone()).unwrap();
        assert_eq!(r.hull_proxy(), HullProxy::Cut);
        // the default, the hull's scissor, leaves out pixels and keeps the image
        let mut r = Renderer::new(gpu(), volume.clone()).unwrap();
        r.set_inputs(vwb_lab::headless::inputs_for(&doc).unwrap());
        assert_eq!(r.hull_proxy(), HullProxy::Scissor);
        r.update_stack(&doc.stack, doc.render.target).unwrap();
        let pixels = r.render(&s).unwrap().scissor_share.unwrap();
        eprintln!(
            "{preset}: the scissor leaves {:.0} % of the pixels",
            pixels * 100.0
        );
        assert!(pixels < 0.9, "{preset}: scissor share {pixels}");
        assert!(
            rgb(&r.read_pixels().unwrap().2) == images[0],
            "{preset}: scissor image"
        );
        assert_compute_rays_cut_to_the_hull(&doc, &volume, &s, preset);
        for (i, what) in [(1, "hull"), (2, "cells")] {
            let (rms, max) = diff(&images[0], &images[i]);
            eprintln!(
                "{preset}: {what} covers {:.0} % of the box (visible box {:.0} %); RMS {:.3} \
                 levels, max {:.1} levels",
                shares[i] * 100.0,
                shares[0] * 100.0,
                rms / ONE_LEVEL,
                max / ONE_LEVEL
            );
            assert!(shares[i] < 0.9 * shares[0], "{preset} {what}: {shares:?}");
            assert!(shares[i] < 0.7, "{preset} {what}: {shares:?}");
            // a GPU (8-bit trilinear weights) moves the 2D TF's lookups where a cut
            // polygon's interpolated positions differ by a rounding: demo_tf2d's hull
            // 0.86 levels RMS, 42 at a pixel, on the H200
            assert!(
                rms < adapter_bound(0.5, 1.5) * ONE_LEVEL,
                "{preset} {what}: RMS {rms}"
            );
            assert!(
                max < adapter_bound(12.0, 64.0) * ONE_LEVEL,
                "{preset} {what}: max {max}"
            );
        }
    }
}

/// The raster backend's empty-space skipping (issue 23, item 2;
/// `Renderer::set_raster_skipping`, on by default): the slices in front of a pixel's
/// next visible brick fail the depth test, and the image stays the same bit for bit, in
/// one pass and per slice (per-slice state), with a 2D transfer function, clipping and
/// early termination, and with 8 slices per polygon (by default where rays stop, and
/// set outright), whose masks come every 32 slices. The chunk bits it skips by are
/// neither empty nor full: most drawn pixels skip some chunks of slices.
#[test]
fn raster_skipping_keeps_the_image() {
    let registry = registry();
    // the group: the renderer's default (auto: 8 per polygon with termination, its
    // skipping masks every 32 slices), or 8 set outright without termination
    for (preset, et, group) in [
        ("demo.ron", None, None),
        ("demo.ron", Some(0.99), None),
        ("demo.ron", None, Some(8)),
        ("demo_clip_labels.ron", None, None),
        ("demo_dos.ron", Some(0.99), None),
        ("demo_tf2d.ron", None, None),
    ] {
        let (doc, volume, s) = raster_scene(&registry, preset, et);
        let mut images = Vec::new();
        let mut bits = None;
        for skip in [false, true] {
            let mut r = Renderer::new(gpu(), volume.clone()).unwrap();
            if let Some(n) = group {
                r.set_raster_group(n);
            }
            r.set_inputs(vwb_lab::headless::inputs_for(&doc).unwrap());
            r.set_raster_skipping(skip);
            r.update_stack(&doc.stack, doc.render.target).unwrap();
            let drawn = r.render(&s).unwrap().raster_group;
            let want = match (preset, et, group) {
                ("demo_dos.ron", ..) => 1,
                (_, _, Some(n)) => n,
                (_, Some(_), None) => vwb_render::renderer::RASTER_GROUP_WITH_TERMINATION,
                _ => 1,
            };
            assert_eq!(drawn, want, "{preset} {et:?} {group:?}: slices per polygon");
            images.push(r.read_pixels().unwrap().2);
            bits = r.raster_chunk_bits();
            assert_eq!(
                bits.is_some(),
                skip,
                "{preset}: chunk bits only when skipping"
            );
        }
        assert!(
            mean_luma(&rgb(&images[1])) > 0.02,
            "{preset} {et:?}: something is drawn"
        );
        let same = images[0]
            .iter()
            .zip(&images[1])
            .filter(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits))
            .count();
        assert_eq!(same, images[0].len(), "{preset} {et:?}: pixels the same");
        let (w, h, bits) = bits.unwrap();
        assert_eq!((w, h, bits.len()), (96, 96, 96 * 96));
        // the pixels whose rays can meet something, and those that skip a chunk in their
        // span of chunks (between their first and last set bit)
        let drawn: Vec<u64> = bits.into_iter().filter(|&b| b != 0).collect();
        let gaps = drawn
            .iter()
            .filter(|&&b| {
                let span = 64 - b.leading_zeros() - b.trailing_zeros();
                b.count_ones() < span || b.trailing_zeros() > 0
            })
            .count();
        eprintln!(
            "{preset} {et:?}: {} pixels' rays meet visible bricks, {gaps} skip chunks",
            drawn.len()
        );
        assert!(
            drawn.len() > 96 * 96 / 10,
            "{preset}: {} pixels",
            drawn.len()
        );
        assert!(
            gaps * 2 > drawn.len(),
            "{preset}: {gaps} of {}",
            drawn.len()
        );
    }
}

/// The raster backend's fragments take the frame's most read fields from their
/// vertices' flat outputs on CPU devices (`FRAME_FROM_VERTEX`,
/// `Renderer::set_frame_from_vertex`): the same values, so the same image bit for bit as
/// from the uniform buffer, through every fragment entry point and option (early
/// termination, several slices per polygon, the exact ray–plane point of proxies cut to
/// occupied cells, back-to-front pixels of half-angle frames with a light, per-slice
/// state, shading, clipping, pre-integration). On by default on this CPU device.
#[test]
fn the_frame_from_the_vertices_keeps_the_raster_image() {
    let registry = registry();
    for preset in [
        "demo.ron",
        "demo_shaded.ron",
        "demo_dos_light.ron",
        "demo_clip_labels.ron",
        "demo_preintegrated.ron",
    ] {
        let (doc, volume, s) = raster_scene(&registry, preset, None);
        let mut r = Renderer::new(gpu(), volume.clone()).unwrap();
        assert!(
            r.frame_from_vertex(),
            "on by default on a CPU device (unless VWB_FRAME_FROM_VERTEX=0)"
        );
        r.set_inputs(vwb_lab::headless::inputs_for(&doc).unwrap());
        r.update_stack(&doc.stack, doc.render.target).unwrap();
        for (et, group, cells) in [
            (None, 1, false),
            (Some(0.99), 1, false),
            (None, 8, false),
            (Some(0.95), 1, true),
        ] {
            r.set_raster_group(group);
            r.set_occupied_proxy(cells);
            let s = FrameSettings {
                early_termination: et,
                ..s
            };
            let mut images = Vec::new();
            for on in [false, true] {
                r.set_frame_from_vertex(on);
                r.render(&s).unwrap();
                images.push(r.read_pixels().unwrap().2);
            }
            let label = format!("{preset} et {et:?} group {group} cells {cells}");
            assert!(
                mean_luma(&rgb(&images[0])) > 0.02,
                "{label}: something is drawn"
            );
            assert!(
                images[0] == images[1],
                "{label}: the same image bit for bit"
            );
        }
    }
}

/// Several slices per proxy polygon on the raster backend (Rezk-Salama 2001, §9.1;
/// `render.slices_per_proxy`): a polygon per group of 2, 4 or 16 slices, its fragments
/// compositing the group's samples along their rays, renders the image of a polygon
/// per slice up to rounding, and stays as close to the CPU twins (perspective and
/// orthographic, with skipping, early termination, clipping and a 2D transfer
/// function). Frames with per-slice state draw a polygon per slice, as before.
#[test]
fn raster_groups_of_slices_keep_the_image() {
    use vwb_render::reference::{ReferenceOptions, render_reference};
    let registry = registry();
    let ortho = vwb_render::camera::Projection::Orthographic { height: 1.2 };
    for (preset, et, projection) in [
        ("demo.ron", None, None),
        ("demo.ron", Some(0.99), None),
        ("demo.ron", None, Some(ortho)),
        ("demo_clip_labels.ron", None, None),
        ("demo_tf2d.ron", Some(0.95), None),
        ("demo_dos.ron", None, None),
    ] {
        let (doc, volume, mut s) = raster_scene(&registry, preset, et);
        if let Some(p) = projection {
            s.camera.projection = p;
        }
        let per_slice = doc.stack.iter().any(|i| i.plugin.slice_state().is_some());
        let opts = ReferenceOptions {
            emulate_fp16: doc.render.target == TargetFormat::Rgba16Float,
            inputs: vwb_lab::headless::inputs_for(&doc).unwrap(),
            ..Default::default()
        };
        let twin = render_reference(&volume, &doc.stack, &s, &opts)
            .unwrap()
            .pixels;
        // a document's render.slices_per_proxy reaches the renderers made for it
        let mut grouped = doc.clone();
        grouped.render.slices_per_proxy = 8;
        let mut r = vwb_lab::headless::renderer_for(gpu(), &grouped, volume.clone()).unwrap();
        assert_eq!(r.raster_group(), 8);
        // the document's default, "auto": 8 per polygon in frames whose rays stop at an
        // opacity, 1 in the others, the image that of the group set outright
        assert_eq!(
            doc.render.slices_per_proxy,
            vwb_render::renderer::RASTER_GROUP_AUTO
        );
        let mut auto = vwb_lab::headless::renderer_for(gpu(), &doc, volume.clone()).unwrap();
        let drawn = auto.render(&s).unwrap().raster_group;
        let want = match et {
            Some(_) if !per_slice => vwb_render::renderer::RASTER_GROUP_WITH_TERMINATION,
            _ => 1,
        };
        assert_eq!(drawn, want, "{preset} {et:?} {projection:?}: auto");
        r.set_raster_group(want);
        r.render(&s).unwrap();
        assert!(
            auto.read_pixels().unwrap().2 == r.read_pixels().unwrap().2,
            "{preset} {et:?} {projection:?}: auto draws the image of {want} per polygon"
        );
        let mut first = None;
        for n in [1, 2, 4, 16] {
            r.set_raster_group(n);
            let st = r.render(&s).unwrap();
            let px = r.read_pixels().unwrap().2;
            let rms = delta_e_rms(&px, &twin, 96, 96);
            let label = format!("{preset} {et:?} {projection:?} n {n}");
            eprintln!("{label}: twins {rms:.4}");
            assert_eq!(st.raster_group, if per_slice { 1 } else { n }, "{label}");
            assert!(
                rms < twin_bound(Backend::Raster, per_slice),
                "{label}: {rms}"
            );
            let Some((one, one_rms)) = &first else {
                assert!(mean_luma(&rgb(&px)) > 0.02, "{label}: something is drawn");
                first = Some((px, rms));
                continue;
            };
            if per_slice {
                assert!(px == *one, "{label}: a polygon per slice, the same image");
                continue;
            }
            // no further from the twins, and close to a polygon per slice (on a GPU, whose
            // 8-bit filter weights turn the samples' rounding into value steps, the H200
            // measured up to +0.054: demo n 2, 0.159 against 0.105)
            let margin = adapter_bound(0.05, 0.1);
            assert!(rms <= one_rms + margin, "{label}: {rms} against {one_rms}");
            let apart = gpu_delta_e_rms(&px, one, 96, 96);
            eprintln!("{label}: from a polygon per slice {apart:.4}");
            assert!(apart < 0.5, "{label}: {apart}");
        }
    }
}

/// The chunk bits of the raster backend's skipping: `mark_slices` (shaders/slice.wgsl)
/// sets the chunks of a range of slices and `first_bit_from` (shaders/raster_mask.wgsl)
/// finds the first set chunk from a slice's, as their 64-bit models say, for every
/// range of slices up to 140 and 1–3 slices per chunk.
#[test]
fn raster_chunk_bits_mark_and_find_slices() {
    const N: u32 = 140;
    let function = |file: &str, name: &str| {
        let start = file.find(&format!("fn {name}(")).expect("the function");
        let len = file[start..].find("\n}\n").expect("its end") + 3;
        file[start..start + len].to_string()
    };
    let source = format!(
        "{}{}
@group(0) @binding(0) var<storage, read_write> out: array<u32>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {{
    let a = id.x;
    let b = id.y;
    let c = id.z + 1u;
    if (a >= {N}u) {{
        return;
    }}
    let bits = mark_slices(vec2<u32>(0u), a, b, c);
    let i = ((id.z * {N}u + b) * {N}u + a) * 3u;
    out[i] = bits.x;
    out[i + 1u] = bits.y;
    out[i + 2u] = first_bit_from(bits, (a * 7u + b) % 64u);
}}",
        function(include_str!("../../shaders/slice.wgsl"), "mark_slices"),
        function(
            include_str!("../../shaders/raster_mask.wgsl"),
            "first_bit_from"
        ),
    );
    let count = (3 * N * N * 3) as usize;
    let values = run_compute_words(gpu(), &source, count, [N.div_ceil(64), N, 3]);
    for c in 1..=3u32 {
        for b in 0..N {
            for a in 0..N {
                let i = (((c - 1) * N + b) * N + a) as usize * 3;
                let got = values[i] as u64 | (values[i + 1] as u64) << 32;
                let (lo, hi) = (a / c, (b / c).min(63));
                let want: u64 = (lo..=hi).filter(|&j| j < 64).map(|j| 1u64 << j).sum();
                assert_eq!(got, want, "mark_slices({a}, {b}, {c})");
                let j = (a * 7 + b) % 64;
                let first = (j..64).find(|&k| want >> k & 1 == 1).unwrap_or(64);
                assert_eq!(values[i + 2], first, "first_bit_from({want:#x}, {j})");
            }
        }
    }
}

/// The compute backend's rays cut to the occupied bricks' hull ([`HullRays`]): by
/// default (`Auto`) where it leaves air around the matter, as on the demo (its hull
/// holds less than [`HULL_RAYS_SHARE`] of the visible box), with the image the same bit
/// for bit as rays through the visible box; not where everything is visible (a flat
/// opaque transfer function: the hull is the box).
fn assert_compute_rays_cut_to_the_hull(
    doc: &Document,
    volume: &std::sync::Arc<vwb_render::Volume>,
    s: &FrameSettings,
    preset: &str,
) {
    let s = FrameSettings {
        backend: Backend::Compute,
        ..*s
    };
    let run = |mode: HullRays, stack: &[vwb_render::PluginInstance]| {
        let mut r = Renderer::new(gpu(), volume.clone()).unwrap();
        r.set_inputs(vwb_lab::headless::inputs_for(doc).unwrap());
        r.set_hull_rays(mode);
        r.update_stack(stack, doc.render.target).unwrap();
        r.render(&s).unwrap();
        let image = rgb(&r.read_pixels().unwrap().2);
        (r.hull_rays(), image)
    };
    let ((on, share), cut) = run(HullRays::Auto, &doc.stack);
    let ((off, _), whole) = run(HullRays::Off, &doc.stack);
    eprintln!(
        "{preset}: the hull holds {:.0} % of the visible box",
        share * 100.0
    );
    assert!(on && !off && share < HULL_RAYS_SHARE, "{preset}: {share}");
    assert!(
        cut == whole,
        "{preset}: rays cut to the hull changed the image"
    );
    let mut opaque = instance("classify.tf1d");
    opaque.params.set("tf", flat_tf(0.8, 0.05));
    let ((on, share), _) = run(HullRays::Auto, &[opaque]);
    assert!(!on && share >= HULL_RAYS_SHARE, "{preset}, opaque: {share}");
}

/// A stack that shows nothing (a transparent transfer function) takes no sample on the
/// compute backend with empty-space skipping: the raw-samples kernel, which takes the
/// march's samples, counts none (the rays' own box is empty; without skipping every
/// ray that meets the box samples it), and the images of the march and of the
/// per-slice path (with shade.dos) are those without skipping, bit for bit.
#[test]
fn nothing_visible_takes_no_samples() {
    let mut clear = instance("classify.tf1d");
    clear.params.set("tf", flat_tf(0.8, 0.0));
    let s = settings(48, 48, Backend::Compute);
    let t = TargetFormat::Rgba16Float;
    for stack in [
        vec![clear.clone()],
        vec![clear.clone(), instance("shade.dos")],
    ] {
        let mut renderers = [true, false].map(|on| {
            let mut r = Renderer::new(gpu(), demo()).unwrap();
            r.set_empty_space_skipping(on);
            r
        });
        let images = renderers.each_mut().map(|r| render(r, &stack, t, &s));
        assert_eq!(renderers[0].empty_brick_share(), Some(1.0));
        assert!(images[0] == images[1], "{} plugins: images", stack.len());
        if stack.len() > 1 {
            continue;
        }
        let counts = renderers.each_mut().map(|r| {
            r.set_raw_samples(true);
            let raw = render(r, &stack, t, &s);
            raw.iter().map(|p| p[1] as f64).sum::<f64>()
        });
        assert_eq!(counts[0], 0.0, "samples taken with nothing visible");
        assert!(counts[1] > 1000.0, "{} samples without skipping", counts[1]);
    }
}

/// An orthographic camera of height h maps the volume box to its exact footprint:
/// seen along z with h = 1.2, the unit cube covers 40 of 48 rows and, at the 4:3
/// aspect, 40 of 64 columns, centred, whatever the camera's distance. A perspective
/// camera's footprint is larger (the near face is closer) and changes with distance. A
/// wrong projection (a perspective divide, a wrong height, aspect or centre) fails.
#[test]
fn orthographic_projection_maps_the_box_to_its_exact_footprint() {
    let cube = synthetic([16; 3], |x, _, _| x as f32);
    let stack = [tf_constant([1.0, 1.0, 1.0, 0.5])];
    // the covered pixels' row and column ranges, and their count
    let footprint = |px: &[[f32; 4]]| {
        let covered: Vec<(usize, usize)> = (0..px.len())
            .filter(|&i| px[i][3] > 0.01)
            .map(|i| (i % 64, i / 64))
            .collect();
        let cols = covered.iter().map(|c| c.0);
        let rows = covered.iter().map(|c| c.1);
        (
            (cols.clone().min().unwrap(), cols.max().unwrap()),
            (rows.clone().min().unwrap(), rows.max().unwrap()),
            covered.len(),
        )
    };
    for backend in [Backend::Raster, Backend::Compute] {
        let mut r = Renderer::new(gpu(), cube.clone()).unwrap();
        let mut s = ortho_axis(64, 48, backend);
        let near = render(&mut r, &stack, TargetFormat::Rgba32Float, &s);
        assert_eq!(
            footprint(&near),
            ((12, 51), (4, 43), 1600),
            "{backend:?}: the unit cube's orthographic footprint"
        );
        s.camera.distance *= 2.5;
        let far = render(&mut r, &stack, TargetFormat::Rgba32Float, &s);
        let (rms, max) = diff(&rgb(&near), &rgb(&far));
        assert!(
            max < 1e-5,
            "{backend:?}: the distance changes nothing: {rms} {max}"
        );

        let mut p = s;
        p.camera.projection = vwb_render::Projection::Perspective { fov_y_deg: 45.0 };
        p.camera.distance = 1.6;
        let persp_near = footprint(&render(&mut r, &stack, TargetFormat::Rgba32Float, &p));
        p.camera.distance = 4.0;
        let persp_far = footprint(&render(&mut r, &stack, TargetFormat::Rgba32Float, &p));
        assert!(
            persp_near.2 > persp_far.2,
            "{backend:?}: {persp_near:?} {persp_far:?}"
        );
    }
}

#[test]
fn bad_sizes_and_spacings_are_errors_not_panics() {
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    r.update_stack(&[instance("classify.tf1d")], TargetFormat::Rgba16Float)
        .unwrap();
    let mut s = settings(0, 10, Backend::Raster);
    assert!(r.render(&s).is_err());
    s.width = 10;
    s.slice_spacing = 0.0;
    assert!(r.render(&s).is_err());
    s.slice_spacing = 1e-6;
    assert!(r.render(&s).unwrap_err().to_string().contains("slices"));
}

/// GPU memory (issue 20): a volume or an eye buffer that would pass the renderer's
/// budget fails with a clear error before anything is allocated, and the last volume
/// and image stay usable; a lost device fails every later frame with its reason,
/// never a panic.
#[test]
fn gpu_memory_limits_and_a_lost_device_are_clear_errors() {
    let stack = [instance("classify.tf1d")];
    let s = settings(48, 48, Backend::Compute);
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let before = render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
    let held = r.gpu_memory();
    // the demo (128×128×84 r32float or r16float) and a 48² eye buffer
    let volume = 128 * 128 * 84 * texel_bytes();
    assert!(held >= volume + 48 * 48 * 28, "{held}");
    r.set_gpu_memory_budget(Some(held + (1 << 20)));
    // a volume 8× larger does not fit: refused, the demo stays
    let big = synthetic([256, 256, 168], |x, y, z| ((x ^ y ^ z) & 1) as f32);
    let e = r.set_volume(big).unwrap_err().to_string();
    assert!(
        e.contains("GPU memory") && e.contains("256, 256, 168") && e.contains("budget"),
        "{e}"
    );
    r.render(&s).unwrap();
    assert_eq!(r.read_pixels().unwrap().2, before, "the demo still renders");
    // an eye buffer that does not fit: refused, a smaller one renders
    let e = r
        .render(&settings(1024, 1024, Backend::Compute))
        .unwrap_err();
    assert!(
        matches!(e, vwb_render::renderer::RenderError::OutOfMemory { .. })
            && e.to_string().contains("1024×1024"),
        "{e}"
    );
    r.set_gpu_memory_budget(None);
    assert_eq!(
        render(&mut r, &stack, TargetFormat::Rgba16Float, &s),
        before
    );
    // a device of its own, lost: every frame says so
    let own = vwb_render::GpuContext::new_headless().unwrap();
    let mut lost = Renderer::new(&own, demo()).unwrap();
    render(&mut lost, &stack, TargetFormat::Rgba16Float, &s);
    assert!(own.lost().is_none());
    own.device.destroy();
    own.wait();
    let e = lost.render(&s).unwrap_err().to_string();
    assert!(
        e.contains("device was lost") && e.contains("restart"),
        "{e}"
    );
}

/// Empty-space skipping changes nothing in the image: every shipped preset (and the
/// per-slice-state one) renders the same with it on and off, bit for bit in the compute
/// backend (also with early termination) and up to the rounding of interpolated sample
/// positions in the raster backend (whose polygons then stop at the visible box), while
/// a good share of the bricks is skipped where the stack allows it. (The extremes suite runs with skipping on against the CPU reference.)
#[test]
fn empty_space_skipping_leaves_images_unchanged() {
    let registry = registry();
    // the raster cases over their bound, every preset measured before failing
    let mut failed = Vec::new();
    for path in crate::presets::shipped_presets() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let doc = Document::load(&path, &registry).unwrap().document;
        let volume = vwb_lab::headless::load_volume(&doc.volume).unwrap();
        let inputs = vwb_lab::headless::inputs_for(&doc).unwrap();
        // one renderer with skipping and one without, each drawing the three settings
        // (their volume passes run once per renderer)
        let mut renderers = [true, false].map(|on| {
            let mut r = Renderer::new(gpu(), volume.clone()).unwrap();
            r.set_inputs(inputs.clone());
            r.set_empty_space_skipping(on);
            // the compute rays cut to the occupied bricks' hull whatever its share
            r.set_hull_rays(HullRays::Always);
            r
        });
        for (backend, early_termination) in [
            (Backend::Raster, None),
            (Backend::Compute, None),
            (Backend::Compute, Some(0.95)),
        ] {
            let s = FrameSettings {
                width: 64,
                height: 64,
                backend,
                early_termination,
                ..doc.frame_settings()
            };
            let images = renderers
                .each_mut()
                .map(|r| render(r, &doc.stack, doc.render.target, &s));
            let share = renderers[0].empty_brick_share();
            if backend == Backend::Raster {
                failed.extend(raster_skipping_change(&images, &name));
                // skipping without the hull's scissor (the default's raster image, bit
                // for bit)
                let scissor = renderers[0].hull_proxy();
                renderers[0].set_hull_proxy(HullProxy::Off);
                let plain = render(&mut renderers[0], &doc.stack, doc.render.target, &s);
                renderers[0].set_hull_proxy(scissor);
                assert!(
                    images[0] == plain,
                    "{name}: the hull's scissor changed the raster image"
                );
            } else {
                assert_kept(
                    &images[0],
                    &images[1],
                    &format!("{name} {}", backend.name()),
                );
            }
            // skipping is off exactly where an enabled plugin promises nothing about
            // transparent samples (e.g. test.smooth and flow.lic3d replace the value)
            let no_promise = doc.stack.iter().filter(|i| i.enabled).any(|i| {
                matches!(
                    i.configured().transparency(
                        &i.params,
                        &vwb_render::inputs::Volumes::new(&volume, &inputs)
                    ),
                    vwb_render::plugin::Transparency::Unknown
                )
            });
            match share {
                None => assert!(no_promise, "{name}: skipping should be on"),
                Some(f) => {
                    assert!(
                        !no_promise,
                        "{name}: skipping despite a plugin without a promise"
                    );
                    eprintln!(
                        "{name} {}: {:.0} % of bricks skipped",
                        backend.name(),
                        f * 100.0
                    );
                    assert!(f > 0.05, "{name}: {f}");
                }
            }
        }
    }
    assert!(failed.is_empty(), "{failed:#?}");
}

/// The tables a classification reads at every sample are rgba16float on GPUs (the
/// filtered read of a 128-bit texel is what plain DVR waits on there; docs/perf.md,
/// "Classification tables in 16-bit floats on GPUs") and keep 32-bit floats on CPU
/// devices, whose images stay those of 32-bit tables; other tables (kernels,
/// directions, environment maps) keep 32 bits everywhere. The values written to a
/// 16-bit table are the 32-bit table's rounded to the nearest half float.
#[test]
fn classification_tables_are_half_floats_on_gpus() {
    use wgpu::TextureFormat::{Rgba16Float, Rgba32Float};
    let g = gpu();
    let volume = demo();
    let inputs = vwb_render::inputs::VolumeInputs::default();
    assert!(g.features.contains(wgpu::Features::FLOAT32_FILTERABLE));
    use vwb_render::renderer::TableFormat;
    for (device_type, table_format, per_sample) in [
        (wgpu::DeviceType::Cpu, TableFormat::Auto, Rgba32Float),
        (
            wgpu::DeviceType::DiscreteGpu,
            TableFormat::Auto,
            Rgba16Float,
        ),
        (
            wgpu::DeviceType::IntegratedGpu,
            TableFormat::Auto,
            Rgba16Float,
        ),
        (
            wgpu::DeviceType::DiscreteGpu,
            TableFormat::Rgba32Float,
            Rgba32Float,
        ),
        (wgpu::DeviceType::Cpu, TableFormat::Rgba16Float, Rgba16Float),
    ] {
        let init = vwb_render::plugin::GpuInit {
            device: &g.device,
            queue: &g.queue,
            features: g.features,
            device_type,
            table_format,
            volume: &volume,
            inputs: &inputs,
            slice_spacing: 1.0,
        };
        let what = format!("{device_type:?} {}", table_format.name());
        assert_eq!(init.sample_table_format(), per_sample, "{what}");
        let lut = init.create_table_1d("lut", 256);
        assert_eq!(lut.texture.format(), per_sample, "{what}");
        let table = init.create_sample_table("table", 16, 8);
        assert_eq!(table.texture.format(), per_sample, "{what}");
        assert_eq!(table.texture.size().height, 8);
        let kernel = init.create_table("kernel", 16, 1);
        assert_eq!(kernel.texture.format(), Rgba32Float, "{what}");
        // what a 16-bit table holds: each value rounded to the nearest half float
        let texels: Vec<[f32; 4]> = (0..256)
            .map(|i| {
                let x = i as f32 / 255.0;
                [x, x * x, 1.0 - x, 1.0e-4 * x]
            })
            .collect();
        init.write_table(&lut, &texels);
        let back = read_table_1d(g, &lut);
        for (t, b) in texels.iter().zip(&back) {
            for (x, y) in t.iter().zip(b) {
                let tol = if per_sample == Rgba16Float {
                    (x.abs() * 2f32.powi(-11)).max(2f32.powi(-25))
                } else {
                    0.0
                };
                assert!((x - y).abs() <= tol, "{what}: {x} read back as {y}");
            }
        }
    }
}

/// `render.table_format` on a renderer: the format `auto` does not pick (16-bit on
/// lavapipe, 32-bit on a GPU) moves the image by rounding, the one it picks and `auto`
/// again bring it back (bit for bit on lavapipe), also in a split
/// volume's bricks; the setting reads and writes in presets and is refused by name.
#[test]
fn the_table_format_is_a_render_setting() {
    use vwb_render::renderer::{RendererOptions, TableFormat};
    let registry = registry();
    let doc = Document::load(&repo().join("presets/demo_preintegrated.ron"), &registry)
        .unwrap()
        .document;
    let s = FrameSettings {
        width: 48,
        height: 48,
        backend: Backend::Compute,
        ..doc.frame_settings()
    };
    let split = RendererOptions {
        brick_limit: Some(64),
        ..Default::default()
    };
    for options in [RendererOptions::default(), split] {
        let mut r = Renderer::with_options(gpu(), demo(), options).unwrap();
        let what = if options.brick_limit.is_some() {
            "split"
        } else {
            "whole"
        };
        let auto = render(&mut r, &doc.stack, doc.render.target, &s);
        assert_eq!(r.table_format(), TableFormat::Auto);
        // `auto` is rgba32float on a CPU device and rgba16float on a GPU
        let (same, other) = if on_gpu() {
            (TableFormat::Rgba16Float, TableFormat::Rgba32Float)
        } else {
            (TableFormat::Rgba32Float, TableFormat::Rgba16Float)
        };
        r.set_table_format(other);
        let moved = render(&mut r, &doc.stack, doc.render.target, &s);
        let d = gpu_delta_e_rms(&auto, &moved, s.width, s.height);
        assert!(
            d > 0.0 && d < 0.2,
            "{what}: {other:?} tables moved the image by {d}"
        );
        r.set_table_format(same);
        let kept = render(&mut r, &doc.stack, doc.render.target, &s);
        assert_kept(&auto, &kept, &format!("{what}: {same:?} tables"));
        r.set_table_format(TableFormat::Auto);
        let back = render(&mut r, &doc.stack, doc.render.target, &s);
        assert_kept(&auto, &back, &format!("{what}: auto again"));
    }
    // in a preset: written only when not auto
    let mut d = doc.clone();
    d.render.table_format = TableFormat::Rgba16Float;
    let text = d.to_ron();
    assert!(text.contains("table_format: Rgba16Float"), "{text}");
    let again = Document::parse(&text, "t.ron", &registry).unwrap().document;
    assert_eq!(again.render.table_format, TableFormat::Rgba16Float);
    assert!(!doc.to_ron().contains("table_format"));
    assert_eq!(
        TableFormat::parse("rgba32float"),
        Ok(TableFormat::Rgba32Float)
    );
    assert!(
        TableFormat::parse("rgba8unorm")
            .unwrap_err()
            .contains("rgba8unorm")
    );
}

/// The texels of a one-row table (rgba32float or rgba16float) as f32.
fn read_table_1d(g: &vwb_render::GpuContext, t: &vwb_render::plugin::GpuResource) -> Vec<[f32; 4]> {
    let size = t.texture.size();
    let bpp = t.texture.format().block_copy_size(None).unwrap();
    let row = (size.width * bpp).div_ceil(256) * 256;
    let buffer = g.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("table read-back"),
        size: row as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = g.device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        t.texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(1),
            },
        },
        size,
    );
    g.queue.submit([encoder.finish()]);
    buffer
        .slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.unwrap());
    g.device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let bytes = buffer.slice(..).get_mapped_range().unwrap().to_vec();
    let value = |b: &[u8]| match bpp {
        16 => f32::from_le_bytes(b.try_into().unwrap()),
        _ => half::f16::from_le_bytes(b.try_into().unwrap()).to_f32(),
    };
    let c = bpp as usize / 4;
    bytes[..(size.width * bpp) as usize]
        .chunks(bpp as usize)
        .map(|t| [0, 1, 2, 3].map(|k| value(&t[k * c..(k + 1) * c])))
        .collect()
}

/// The raster images with skipping on and off: with skipping the polygons stop at the
/// visible box, so the samples are the same and only their positions, interpolated
/// over other triangles, round differently. Prints the difference; returns what is
/// over the bound. On a GPU the bound is the golden images' (2 levels RMS, 128 at a
/// pixel): its 8-bit filter weights flip whole samples where a position moves by a
/// rounding, at a clip plane (the H200: ct_clip_quadrant 0.46 levels RMS, 16 at a
/// pixel, the seam `bricks::bricked_volumes_render_the_unbricked_image` also shows,
/// open), between toon shading's bands (ct_shade_toon 0.77, 37) and, carried on from
/// slice to slice, in per-slice state (ct_dos_clip 1.6, 96).
fn raster_skipping_change(images: &[Vec<[f32; 4]>; 2], what: &str) -> Option<String> {
    let (rms, max) = diff(&rgb(&images[0]), &rgb(&images[1]));
    let line = format!(
        "{what} raster: RMS {:.3}, max {:.1} levels",
        rms / ONE_LEVEL,
        max / ONE_LEVEL
    );
    eprintln!("{line}");
    let kept =
        rms < adapter_bound(0.25, 2.0) * ONE_LEVEL && max < adapter_bound(12.0, 128.0) * ONE_LEVEL;
    (!kept).then_some(line)
}

/// A plugin that moves samples along their rays (`sample.jitter`, a promise of
/// `Transparency::Moves`) keeps empty-space skipping on and exact: the brick ranges
/// are taken over an apron widened by the move at the frame's slice spacing (2 voxels
/// at spacing 1, 21 at 40) and clip regions are widened alike, so the compute images
/// with skipping on and off are equal bit for bit, also after the spacing changes on
/// the same renderer, while bricks are skipped (at spacing 1 nearly as many as
/// without jitter). Without the wider apron, spacing 40 differs.
#[test]
fn jitter_keeps_skipping_exact() {
    let mut jitter = instance("sample.jitter");
    jitter.params.set("amount", ParamValue::Float(1.0));
    let mut clip = instance("clip.shapes");
    clip.params
        .set("shape0_kind", ParamValue::Enum("sphere".into()));
    clip.params
        .set("shape0_size", ParamValue::Vec3([0.3, 0.3, 0.3]));
    for stack in [
        vec![jitter.clone(), instance("classify.tf1d")],
        vec![jitter.clone(), instance("classify.tf1d"), clip],
    ] {
        jitter_skipping_case(&stack);
    }
}

fn jitter_skipping_case(stack: &[vwb_render::PluginInstance]) {
    let mut renderers = skipping_pair(&demo());
    for spacing in [1.0f32, 3.0, 40.0, 1.0] {
        for backend in [Backend::Compute, Backend::Raster] {
            let s = FrameSettings {
                slice_spacing: spacing,
                ..settings(64, 64, backend)
            };
            let share = skipping_kept(&mut renderers, stack, &s, &format!("spacing {spacing}"));
            if backend == Backend::Raster {
                continue;
            }
            eprintln!(
                "jitter at spacing {spacing}: {:.0} % of bricks skipped",
                share * 100.0
            );
            // 40 voxels: a move of up to 20 widens the apron to 21 voxels (and the
            // clip regions by as much), which leaves little to skip
            if spacing < 40.0 {
                assert!(share > 0.3, "spacing {spacing}: {share}");
            } else {
                assert!(share < 0.3, "spacing {spacing}: {share}");
            }
            assert!(renderers[1].empty_brick_share().is_none());
        }
    }
}

/// Two renderers of `volume`, empty-space skipping on and off.
fn skipping_pair(volume: &std::sync::Arc<vwb_render::Volume>) -> [Renderer; 2] {
    [true, false].map(|on| {
        let mut r = Renderer::new(gpu(), volume.clone()).unwrap();
        r.set_empty_space_skipping(on);
        r
    })
}

/// The frame `s` of `stack` with skipping on and off ([`skipping_pair`]): something
/// shows, the compute images are equal bit for bit, the raster ones within the raster
/// skipping bound. Returns the share of bricks skipped.
fn skipping_kept(
    renderers: &mut [Renderer; 2],
    stack: &[vwb_render::PluginInstance],
    s: &FrameSettings,
    what: &str,
) -> f64 {
    let images = renderers
        .each_mut()
        .map(|r| render(r, stack, TargetFormat::Rgba32Float, s));
    for image in &images {
        assert!(image.iter().any(|p| p[3] > 0.1), "{what}: something shows");
    }
    if s.backend == Backend::Raster {
        let change = raster_skipping_change(&images, what);
        assert!(change.is_none(), "{change:?}");
    } else {
        assert!(images[0] == images[1], "{what}: skipping changed the image");
    }
    renderers[0].empty_brick_share().expect("skipping is on")
}

/// Pre-integrated classification keeps empty-space skipping on and exact: its slab
/// reads the value where the ray meets the next slice, so the bricks' ranges are taken
/// over an apron widened by the frame's longest step between two slices (the spacing
/// over the least cosine between a ray and the slice normal). A volume whose bright
/// ends begin past brick faces that the dark bricks' usual ranges do not reach, TF
/// opaque only at high values, seen along the step (orthographic) and in a
/// wide perspective view (a ray's step up to 1.4× the spacing) at spacings 1, 2.5 and
/// 6: the compute images with skipping on and off equal bit for bit, raster within its
/// skipping bound, while bricks are skipped. With a one-voxel apron (a promise by
/// value alone) the frame along the axis at spacing 2.5 loses the slabs that reach
/// the bright ends, and this test fails. The same holds for `shade.isosurface`
/// (`Transparency::Adds`: a surface crossed between a sample and the next slice) over
/// a classification that shows nothing.
#[test]
fn preintegration_keeps_skipping_exact() {
    use vwb_render::tf::TfCurve;
    // bright below z = 7 and from z = 57: the dark bricks next to them (z 8–15 and
    // 48–55) do not reach that far over a one-voxel apron, whichever way a ray runs
    let volume = synthetic(
        [32, 32, 64],
        |_, _, z| {
            if !(7..57).contains(&z) { 1.0 } else { 0.0 }
        },
    );
    let mut tf = instance("classify.tf1d");
    tf.params
        .set("mode", ParamValue::Enum("preintegrated".into()));
    tf.params.set(
        "tf",
        ParamValue::Tf(TfCurve::ramp(0.05, 1.0, [1.0, 0.8, 0.6, 0.1])),
    );
    // the same for an isosurface met between a sample and the next slice (crossing),
    // over a classification that shows nothing
    let mut iso = instance("shade.isosurface");
    iso.params.set("iso0", ParamValue::Float(0.5));
    iso.params
        .set("color0", ParamValue::Color([0.9, 0.8, 0.7, 0.5]));
    for stack in [vec![tf], vec![tf_constant([0.0; 4]), iso]] {
        read_ahead_skipping_case(&volume, &stack);
    }
}

fn read_ahead_skipping_case(
    volume: &std::sync::Arc<vwb_render::Volume>,
    stack: &[vwb_render::PluginInstance],
) {
    use vwb_render::camera::Projection;
    let name = stack.last().unwrap().plugin.id();
    let mut renderers = skipping_pair(volume);
    let along = ortho_axis(48, 48, Backend::Compute).camera;
    let mut wide = along;
    wide.projection = Projection::Perspective { fov_y_deg: 90.0 };
    wide.distance = 1.2;
    for (view, camera) in [("along", along), ("wide", wide)] {
        for spacing in [1.0f32, 2.5, 6.0] {
            for backend in [Backend::Compute, Backend::Raster] {
                let s = FrameSettings {
                    camera,
                    slice_spacing: spacing,
                    ..settings(48, 48, backend)
                };
                let what = format!("{name}, {view}, spacing {spacing}, {}", backend.name());
                let share = skipping_kept(&mut renderers, stack, &s, &what);
                eprintln!("{what}: {:.0} % of bricks skipped", share * 100.0);
                assert!(share > 0.1, "{what}: {share}");
            }
        }
    }
}

/// How the volume is stored (issue 23, item 4): r32float_pairs (each voxel beside its
/// +z neighbour, a bilinear fetch and a mix per read) renders the demo as r32float does
/// up to f32 rounding on both backends, with and without shading, and on the raster
/// backend also with 8 slices per proxy polygon; r16unorm, r16float
/// and r8unorm within small bounds (`auto` is r32float_pairs on CPU devices, r32float
/// on GPUs that filter it); a format change uploads the volume again only when it
/// changes what is stored, and a change of layout (pairs to a 3D texture and back)
/// renders the layout's own image; a preset names the format, and `auto` is not
/// written.
#[test]
fn volume_formats_render_within_bounds_and_upload_only_on_change() {
    use vwb_render::renderer::{RendererOptions, VolumeFormat};
    let (w, h) = (48, 48);
    let s = settings(w, h, Backend::Compute);
    let stack = vec![instance("classify.tf1d"), instance("shade.blinn_phong")];
    let t = TargetFormat::Rgba32Float;
    // a renderer of the demo asked for `volume_format`
    let made = |volume_format| {
        let options = RendererOptions {
            volume_format,
            ..Default::default()
        };
        let r = Renderer::with_options(gpu(), demo(), options).unwrap();
        assert_eq!(r.volume_format(), volume_format);
        r
    };
    let image = |volume_format| render(&mut made(volume_format), &stack, t, &s);
    let exact = image(VolumeFormat::R32Float);
    let auto = VolumeFormat::Auto.concrete(gpu());
    let cpu = gpu().adapter.get_info().device_type == wgpu::DeviceType::Cpu;
    assert_eq!(auto == VolumeFormat::R32FloatPairs, cpu, "{auto:?}");
    assert_eq!(
        gpu_delta_e_rms(&image(VolumeFormat::Auto), &image(auto), w, h),
        0.0
    );
    // the pairs: the same trilinear values up to rounding, unshaded (the march's
    // reads) and shaded (the gradient pre-pass's), on both backends, and in a raster
    // group's fragments (8 slices per polygon: the steps written out in slice.wgsl)
    for (backend, group) in [
        (Backend::Compute, 1),
        (Backend::Raster, 1),
        (Backend::Raster, 8),
    ] {
        for stack in [vec![instance("classify.tf1d")], stack.clone()] {
            let s = settings(w, h, backend);
            let of = |volume_format| {
                let mut r = made(volume_format);
                r.set_raster_group(group);
                r.update_stack(&stack, t).unwrap();
                let st = r.render(&s).unwrap();
                if backend == Backend::Raster {
                    assert_eq!(st.raster_group, group, "the frame drew {group} per polygon");
                }
                r.read_pixels().unwrap().2
            };
            let (three_d, pairs) = (of(VolumeFormat::R32Float), of(VolumeFormat::R32FloatPairs));
            let worst = three_d
                .iter()
                .zip(&pairs)
                .flat_map(|(a, b)| (0..4).map(move |c| (a[c] - b[c]).abs()))
                .fold(0.0f32, f32::max);
            let what = format!("{} plugins, {}, group {group}", stack.len(), backend.name());
            eprintln!("r32float_pairs against r32float, {what}: max {worst:e}");
            assert!(
                worst > 0.0 || !cpu,
                "{what}: the pairs are read (rounding differs)"
            );
            // lavapipe: 3·10⁻⁷; a GPU's sampler interpolates with 8-bit weights in x
            // and y and the shader mixes in z in f32, where its 3D filter rounds z too
            let bound = adapter_bound(1e-5, 1e-2) as f32;
            assert!(worst < bound, "{what}: {worst}");
        }
    }
    // the demo is u8: k/255 is 257·k/65535, which r16unorm holds exactly
    let unorm = gpu_delta_e_rms(&image(VolumeFormat::R16Unorm), &exact, w, h);
    let half = gpu_delta_e_rms(&image(VolumeFormat::R16Float), &exact, w, h);
    let byte = gpu_delta_e_rms(&image(VolumeFormat::R8Unorm), &exact, w, h);
    eprintln!(
        "r16unorm {unorm:.5}, r16float {half:.5}, r8unorm {byte:.5} ΔE*uv RMS against r32float"
    );
    assert!(unorm < 0.01, "{unorm}");
    assert!(half < 0.5, "{half}");
    // 1/255 steps: the demo's data, but the sampler's 8-bit filtering on lavapipe
    assert!(byte < 1.0, "{byte}");

    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let first = render(&mut r, &stack, t, &s);
    let uploads = r.counters().volume_uploads;
    // naming what auto stores changes nothing
    assert_eq!(r.stored_volume_format(), auto);
    r.set_volume_format(auto).unwrap();
    assert_eq!(r.counters().volume_uploads, uploads);
    r.set_volume_format(VolumeFormat::R16Float).unwrap();
    assert_eq!(r.counters().volume_uploads, uploads + 1);
    let again = render(&mut r, &stack, t, &s);
    assert!(gpu_delta_e_rms(&again, &exact, w, h) < 0.5);
    // from a 3D texture to the pairs and back: each layout's own image
    r.set_volume_format(VolumeFormat::R32FloatPairs).unwrap();
    assert_eq!(r.counters().volume_uploads, uploads + 2);
    let pairs = render(&mut r, &stack, t, &s);
    r.set_volume_format(VolumeFormat::R32Float).unwrap();
    assert_eq!(
        gpu_delta_e_rms(&render(&mut r, &stack, t, &s), &exact, w, h),
        0.0
    );
    r.set_volume_format(VolumeFormat::Auto).unwrap();
    assert_eq!(render(&mut r, &stack, t, &s), first);
    assert_eq!(
        gpu_delta_e_rms(&pairs, &image(VolumeFormat::R32FloatPairs), w, h),
        0.0
    );

    let text = std::fs::read_to_string(repo().join("presets/demo.ron"))
        .unwrap()
        .replace("render: (", "render: (volume_format: R16Unorm, ");
    let doc = Document::parse(&text, "demo with r16unorm", &registry())
        .unwrap()
        .document;
    assert_eq!(doc.render.volume_format, VolumeFormat::R16Unorm);
    assert!(doc.to_ron().contains("volume_format: R16Unorm"));
    let plain = Document::parse(
        &std::fs::read_to_string(repo().join("presets/demo.ron")).unwrap(),
        "demo",
        &registry(),
    )
    .unwrap()
    .document;
    assert!(!plain.to_ron().contains("volume_format"));
    let bad = text.replace("R16Unorm", "R4Unorm");
    let err = Document::parse(&bad, "demo with r4unorm", &registry()).unwrap_err();
    assert!(err.to_string().contains("R4Unorm"), "{err}");
}

/// Model only what the scene needs: compiled stacks are cached by their structure, so
/// toggling a plugin off and on, removing a duplicate again or changing a volume does
/// not compile again; a parameter change compiles nothing; the same volume is not
/// uploaded again; pre-passes run once per volume and instance.
#[test]
fn compiled_stacks_are_cached_and_nothing_is_redone() {
    let t = TargetFormat::Rgba32Float;
    let s = settings(24, 24, Backend::Compute);
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let mut phong = instance("shade.blinn_phong");
    phong
        .params
        .set("gradient", ParamValue::Enum("precomputed_central".into()));
    let mut stack = vec![instance("classify.tf1d"), phong];
    use vwb_render::PluginInstance;
    let step = |r: &mut Renderer, stack: &[PluginInstance]| {
        let change = r.update_stack(stack, t).unwrap();
        r.render(&s).unwrap();
        (change, r.counters())
    };
    let (_, c) = step(&mut r, &stack);
    assert_eq!(
        (c.compiles, c.volume_uploads, c.prepass_runs),
        (1, 1, 1),
        "{c:?}"
    );

    // off: another structure, compiled once
    stack[1].enabled = false;
    let (_, c) = step(&mut r, &stack);
    assert_eq!((c.compiles, c.prepass_runs), (2, 1), "{c:?}");
    // its gradient volume (16 bytes per voxel) stays allocated, and is reported
    let held = r.disabled_memory();
    assert_eq!(held.len(), 1, "{held:?}");
    assert_eq!(held[0].1, "shade.blinn_phong");
    assert!(held[0].2 >= 128 * 128 * 84 * 16, "{held:?}");
    assert!(r.plugin_memory().iter().all(|m| m.1 != "shade.blinn_phong"));
    // on again: the cached pipelines, the instance's resources and pre-pass result kept
    stack[1].enabled = true;
    let (change, c) = step(&mut r, &stack);
    assert_eq!(change, vwb_render::StackChange::Recomposed);
    assert_eq!(
        (
            c.compiles,
            c.compile_cache_hits,
            c.instance_creations,
            c.prepass_runs
        ),
        (2, 1, 2, 1),
        "{c:?}"
    );
    // a parameter: no compile, no pre-pass (the gradient does not depend on it)
    stack[1].params.set("ks", ParamValue::Float(0.9));
    let (change, c) = step(&mut r, &stack);
    assert_eq!(change, vwb_render::StackChange::Params);
    assert_eq!((c.compiles, c.prepass_runs), (2, 1), "{c:?}");
    // a duplicate is a new structure and a new instance (its own pre-pass); removing it
    // returns to a cached structure
    stack.push(stack[1].duplicate());
    let (_, c) = step(&mut r, &stack);
    assert_eq!(
        (c.compiles, c.instance_creations, c.prepass_runs),
        (3, 3, 2),
        "{c:?}"
    );
    stack.pop();
    let (_, c) = step(&mut r, &stack);
    assert_eq!((c.compiles, c.compile_cache_hits), (3, 2), "{c:?}");

    // the same stack opened again as new instances (a preset reopened): with the old
    // identities carried over, nothing is created, compiled or rerun
    let mut reopened: Vec<_> = stack
        .iter()
        .map(|i| {
            let mut n = PluginInstance::new(i.plugin.clone());
            n.params = i.params.clone();
            n
        })
        .collect();
    vwb_render::plugin::carry_identities(&stack, &mut reopened);
    let (change, c) = step(&mut r, &reopened);
    assert_eq!(change, vwb_render::StackChange::None);
    assert_eq!(
        (c.compiles, c.instance_creations, c.prepass_runs),
        (3, 3, 2),
        "{c:?}"
    );

    // the same volume again: nothing uploaded, nothing rerun
    r.set_volume(demo()).unwrap();
    let (_, c) = step(&mut r, &stack);
    assert_eq!(
        (c.volume_uploads, c.prepass_runs, c.compiles),
        (1, 2, 3),
        "{c:?}"
    );
    // another volume: uploaded, the pre-pass reruns, the compiled stack is reused
    r.set_volume(synthetic([12; 3], |x, y, z| (x + y + z) as f32))
        .unwrap();
    let (_, c) = step(&mut r, &stack);
    assert_eq!(
        (c.volume_uploads, c.prepass_runs, c.compiles),
        (2, 3, 3),
        "{c:?}"
    );
}

/// `n` transfer-function variants of `classify.tf1d` (ramps of varying position,
/// width, colour and opacity), each with its own instance, and a camera per variant
/// from four viewpoints.
pub fn tf_variants(n: usize) -> Vec<(vwb_render::Camera, Vec<vwb_render::PluginInstance>)> {
    (0..n)
        .map(|i| {
            let f = i as f32 / n as f32;
            let mut tf = instance("classify.tf1d");
            let color = [0.4 + 0.6 * f, 1.0 - 0.5 * f, 0.3 + 0.4 * (1.0 - f), 0.6];
            let lo = 0.05 + 0.35 * f;
            tf.params.set(
                "tf",
                ParamValue::Tf(TfCurve::ramp(lo, lo + 0.1 + 0.3 * (1.0 - f), color)),
            );
            tf.params.set("opacity", ParamValue::Float(0.5 + 2.0 * f));
            let mut camera = settings(8, 8, Backend::Compute).camera;
            camera.yaw_deg += 30.0 * (i % 4) as f32;
            (camera, vec![tf])
        })
        .collect()
}

/// The atlas tiles of (camera, stack) variants.
fn atlas_tiles(
    variants: &[(vwb_render::Camera, Vec<vwb_render::PluginInstance>)],
) -> Vec<vwb_render::renderer::AtlasTile<'_>> {
    variants
        .iter()
        .map(|(camera, stack)| vwb_render::renderer::AtlasTile {
            camera: *camera,
            stack,
        })
        .collect()
}

/// Tile `i` of an atlas against the same stack and camera rendered alone on a fresh
/// renderer of `volume` (ΔE*uv RMS ≤ 0.01); the single render's statistics.
/// The atlas `encoded` into `enc`, after submitting it.
fn submitted(
    r: &Renderer,
    enc: wgpu::CommandEncoder,
    encoded: &vwb_render::renderer::EncodedAtlas,
    tiles: usize,
) -> vwb_render::renderer::Atlas {
    gpu().queue.submit([enc.finish()]);
    vwb_render::renderer::Atlas {
        cols: encoded.cols,
        rows: encoded.rows,
        tile: encoded.tile,
        tiles,
        pixels: r.read_atlas(encoded),
        wall_ms: 0.0,
        prepasses_run: 0,
        volume_passes_run: 0,
        loop_limited: 0,
    }
}

fn assert_tile_is_its_single_render(
    atlas: &vwb_render::renderer::Atlas,
    i: usize,
    volume: &std::sync::Arc<vwb_render::Volume>,
    stack: &[vwb_render::PluginInstance],
    camera: vwb_render::Camera,
    s: &FrameSettings,
    t: TargetFormat,
) -> vwb_render::renderer::FrameStats {
    let mut single_r = Renderer::new(gpu(), volume.clone()).unwrap();
    single_r.update_stack(stack, t).unwrap();
    let stats = single_r.render(&FrameSettings { camera, ..*s }).unwrap();
    let single = single_r.read_pixels().unwrap().2;
    let reference: Vec<[f64; 4]> = single.iter().map(|p| p.map(f64::from)).collect();
    let [w, h] = atlas.tile;
    let rms = delta_e_rms(&atlas.tile_pixels(i), &reference, w, h);
    assert!(rms <= 0.01, "tile {i}: ΔE*uv RMS {rms}");
    stats
}

/// An atlas of variants whose stacks have volume passes (TF variants under Hernell's
/// global light, then under a swept light: each variant's light volume is its own):
/// the atlas runs each variant's passes once, and each tile equals its single render
/// on a fresh renderer. A second atlas of the same variants reruns no pass.
#[test]
fn an_atlas_runs_each_variants_volume_passes() {
    // shade.hernell: progressive light passes; shade.sweep_shadows: a sweep, plane by plane
    for (id, least) in [("shade.hernell", 3), ("shade.sweep_shadows", 1)] {
        atlas_runs_volume_passes_of(id, least);
    }
}

fn atlas_runs_volume_passes_of(id: &str, least_passes: usize) {
    let variants: Vec<_> = tf_variants(4)
        .into_iter()
        .map(|(camera, mut stack)| {
            let mut light = instance(id);
            if id == "shade.hernell" {
                light.params.set("segment", ParamValue::Int(4));
            }
            stack.push(light);
            (camera, stack)
        })
        .collect();
    let s = settings(32, 32, Backend::Compute);
    let t = TargetFormat::Rgba32Float;
    let tiles = atlas_tiles(&variants);
    // a ball, small enough for a quick light volume
    let ball = synthetic([32, 32, 24], |x, y, z| {
        let d = ((x as f32 - 15.5).powi(2) + (y as f32 - 15.5).powi(2) + (z as f32 - 11.5).powi(2))
            .sqrt();
        (1.0 - d / 16.0).max(0.0)
    });
    let mut r = Renderer::new(gpu(), ball.clone()).unwrap();
    let atlas = r.render_atlas(&tiles, &s, t, 2).unwrap();
    let mut dispatches = 0;
    for (i, (camera, stack)) in variants.iter().enumerate() {
        let stats = assert_tile_is_its_single_render(&atlas, i, &ball, stack, *camera, &s, t);
        // every step of the light volume's refinement and the opacity passes
        assert!(stats.volume_passes_run.len() >= least_passes, "{id}");
        dispatches += stats.volume_passes_run.len();
    }
    assert_eq!(atlas.volume_passes_run, dispatches);
    let again = r.render_atlas(&tiles, &s, t, 2).unwrap();
    assert_eq!(again.volume_passes_run, 0);
    assert_eq!(again.pixels, atlas.pixels);
}

/// An atlas of variants with per-slice state (TF variants under directional occlusion
/// shading, from the viewer, and in a second atlas from directional lights) is drawn in one submission, each tile's slices and state updates in turn
/// with its state cleared first, and each tile equals its single render on a fresh
/// renderer. Two such atlases encoded into the caller's one encoder give the same
/// tiles, at another tile size too (the state follows the tile), and a design gallery
/// on the DOS demo preset runs (it failed before session 49).
#[test]
fn an_atlas_of_per_slice_variants_matches_their_single_renders() {
    // the viewer's light; or a directional light (half-angle slicing: two dispatches
    // per slice, the state in the light's space), its vector varying by tile
    let dos_variants = |directional: bool| -> Vec<_> {
        tf_variants(4)
            .into_iter()
            .enumerate()
            .map(|(i, (camera, mut stack))| {
                let mut dos = instance("shade.dos");
                if directional {
                    dos.params
                        .set("light", ParamValue::Enum("directional".into()));
                    dos.params.set(
                        "light_vector",
                        ParamValue::Vec3([0.6, 0.5 - 0.3 * i as f32, 0.6]),
                    );
                }
                stack.push(dos);
                (camera, stack)
            })
            .collect()
    };
    let s = settings(32, 32, Backend::Compute);
    let t = TargetFormat::Rgba32Float;
    let lit = dos_variants(true);
    let lit_tiles = atlas_tiles(&lit);
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let atlas = r.render_atlas(&lit_tiles, &s, t, 2).unwrap();
    for (i, (camera, stack)) in lit.iter().enumerate() {
        assert_tile_is_its_single_render(&atlas, i, &demo(), stack, *camera, &s, t);
    }
    let variants = dos_variants(false);
    let tiles = atlas_tiles(&variants);
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let atlas = r.render_atlas(&tiles, &s, t, 3).unwrap();
    assert_eq!((atlas.cols, atlas.rows, atlas.tiles), (3, 2, 4));
    for (i, (camera, stack)) in variants.iter().enumerate() {
        let stats = assert_tile_is_its_single_render(&atlas, i, &demo(), stack, *camera, &s, t);
        assert!(stats.per_slice_mode);
        if i > 0 {
            let (d, _) = diff(&rgb(&atlas.tile_pixels(i)), &rgb(&atlas.tile_pixels(i - 1)));
            assert!(d > 1e-3, "tiles {} and {i} differ", i - 1);
        }
    }
    // one encoder, two atlases: the tiles again, and at 24² each its single render
    let small = FrameSettings {
        width: 24,
        height: 24,
        ..s
    };
    let mut enc = gpu().device.create_command_encoder(&Default::default());
    let first = r.encode_atlas(&mut enc, &tiles, &s, t, 3).unwrap();
    let firsts = submitted(&r, enc, &first, tiles.len());
    for i in 0..tiles.len() {
        let (d, _) = diff(&rgb(&firsts.tile_pixels(i)), &rgb(&atlas.tile_pixels(i)));
        assert!(d < 1e-6, "encoded tile {i}: {d}");
    }
    let mut enc = gpu().device.create_command_encoder(&Default::default());
    let _ = r.encode_atlas(&mut enc, &tiles[..2], &s, t, 2).unwrap();
    let second = r.encode_atlas(&mut enc, &tiles, &small, t, 2).unwrap();
    let seconds = submitted(&r, enc, &second, tiles.len());
    for (i, (camera, stack)) in variants.iter().enumerate() {
        assert_tile_is_its_single_render(&seconds, i, &demo(), stack, *camera, &small, t);
    }

    // a gallery on a DOS preset
    let doc = Document::load(&repo().join("presets/demo_dos.ron"), &registry())
        .unwrap()
        .document;
    let mut r = vwb_lab::headless::renderer_for(gpu(), &doc, demo()).unwrap();
    let thumbs = vwb_render::search::gallery::thumbnails(
        &mut r,
        &doc.stack,
        &[vwb_render::search::genome::Genome::random(
            vwb_render::search::genome::Space::Tf1d,
            &mut vwb_render::rng::Rng::at(3, 0),
            2,
        )],
        &[doc.camera],
        16,
        2.0,
        [0.0; 3],
        8,
    )
    .unwrap();
    assert_eq!((thumbs.len(), thumbs[0].len()), (1, 1));
}

/// Many views in one submission: 64 TF variants from four viewpoints at 128², one
/// atlas, one command encoder. Each tile is its single render (ΔE*uv RMS ≤ 0.01); the
/// speed against 64 single renders is `bash bench/atlas.sh`'s (docs/perf.md).
#[test]
fn an_atlas_of_64_variants_matches_their_single_renders() {
    use vwb_render::renderer::AtlasTile;
    let variants = tf_variants(64);
    let s = settings(128, 128, Backend::Compute);
    let t = TargetFormat::Rgba32Float;
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    // rays cut to each tile's own hull, whatever its share (the balls' below hold 0.92
    // and 0.76 of their boxes)
    r.set_hull_rays(HullRays::Always);
    let tiles = atlas_tiles(&variants);
    let atlas = r.render_atlas(&tiles, &s, t, 8).unwrap();
    assert_eq!((atlas.cols, atlas.rows, atlas.tiles), (8, 8, 64));
    assert_eq!(
        r.counters().compiles,
        1,
        "one compiled stack serves every tile"
    );
    let mut worst = 0.0f64;
    let mut single_r = Renderer::new(gpu(), demo()).unwrap();
    for (i, (camera, stack)) in variants.iter().enumerate() {
        let single = render(
            &mut single_r,
            stack,
            t,
            &FrameSettings {
                camera: *camera,
                ..s
            },
        );
        let tile = atlas.tile_pixels(i);
        let reference: Vec<[f64; 4]> = single.iter().map(|p| p.map(f64::from)).collect();
        let rms = delta_e_rms(&tile, &reference, 128, 128);
        assert!(rms <= 0.01, "tile {i}: ΔE*uv RMS {rms}");
        worst = worst.max(rms);
        // the variants differ from one another
        if i > 0 {
            let (d, _) = diff(&rgb(&tile), &rgb(&atlas.tile_pixels(i - 1)));
            assert!(d > 1e-3, "tiles {} and {i} differ", i - 1);
        }
    }
    eprintln!(
        "atlas of 64 at 128²: worst tile ΔE*uv RMS {worst:.5}, {:.1} ms",
        atlas.wall_ms
    );

    // two atlases encoded into the caller's one command encoder, one submission
    let mut enc = gpu().device.create_command_encoder(&Default::default());
    let first = r.encode_atlas(&mut enc, &tiles[..8], &s, t, 4).unwrap();
    let second = r.encode_atlas(&mut enc, &tiles[8..16], &s, t, 4).unwrap();
    gpu().queue.submit([enc.finish()]);
    for (k, encoded) in [first, second].iter().enumerate() {
        let part = vwb_render::renderer::Atlas {
            cols: encoded.cols,
            rows: encoded.rows,
            tile: encoded.tile,
            tiles: 8,
            pixels: r.read_atlas(encoded),
            wall_ms: 0.0,
            prepasses_run: 0,
            volume_passes_run: 0,
            loop_limited: 0,
        };
        for j in 0..8 {
            let (d, _) = diff(
                &rgb(&part.tile_pixels(j)),
                &rgb(&atlas.tile_pixels(8 * k + j)),
            );
            assert!(d < 1e-6, "atlas {k} tile {j}: {d}");
        }
    }

    // each tile's rays cross the part its own stack can show (its visible box and
    // hull): a ball of radius 0.1 kept in tile 0 (whose stack the renderer takes), one
    // of 0.45 in tile 1
    let balls: Vec<Vec<vwb_render::PluginInstance>> = [0.1, 0.45]
        .map(|radius| {
            let mut ball = instance("clip.shapes");
            let k = vwb_plugins::clip_shapes::slot_keys()[0];
            ball.params.set(k.kind, ParamValue::Enum("sphere".into()));
            ball.params
                .set(k.size, ParamValue::Vec3([radius, 0.0, 0.0]));
            vec![instance("classify.tf1d"), ball]
        })
        .into();
    let ball_tiles: Vec<AtlasTile> = balls
        .iter()
        .map(|stack| AtlasTile {
            camera: s.camera,
            stack,
        })
        .collect();
    let small = FrameSettings {
        width: 48,
        height: 48,
        ..s
    };
    let ball_atlas = r.render_atlas(&ball_tiles, &small, t, 2).unwrap();
    for (i, stack) in balls.iter().enumerate() {
        let single = render(&mut single_r, stack, t, &small);
        let reference: Vec<[f64; 4]> = single.iter().map(|p| p.map(f64::from)).collect();
        let rms = delta_e_rms(&ball_atlas.tile_pixels(i), &reference, 48, 48);
        assert!(rms <= 0.01, "ball tile {i}: ΔE*uv RMS {rms}");
    }

    // a tile of another structure is refused, naming it
    let mut odd = variants[3].1.clone();
    odd.push(instance("shade.blinn_phong"));
    let mut bad = tiles.clone();
    bad[3] = AtlasTile {
        camera: variants[3].0,
        stack: &odd,
    };
    let e = r.render_atlas(&bad, &s, t, 8).unwrap_err().to_string();
    assert!(e.contains("tile 3"), "{e}");
}

/// The atlas against a loop of single renders (update the stack, render, read back
/// each), 64 TF variants from four viewpoints at 64² and 128² on the demo, and 16 of
/// them under shade.dos (per-slice state) at 64², median of 3 rounds, interleaved.
/// Writes docs/atlas_bench.json (docs/gpu/ on a GPU). Run:
/// `bash bench/atlas.sh`.
#[test]
#[ignore = "benchmark: bash bench/atlas.sh"]
fn atlas_benchmark() {
    use std::time::Instant;
    use vwb_render::renderer::AtlasTile;
    let t = TargetFormat::Rgba32Float;
    let mut rows = Vec::new();
    // (stack, tiles, side): the 1D TF alone, and under shade.dos (per-slice state:
    // a dispatch per slice and tile, in one submission since session 51)
    let with_dos = |n: usize| -> Vec<_> {
        tf_variants(n)
            .into_iter()
            .map(|(camera, mut stack)| {
                stack.push(instance("shade.dos"));
                (camera, stack)
            })
            .collect()
    };
    let cases = [
        ("classify.tf1d", tf_variants(64), 64u32),
        ("classify.tf1d", tf_variants(64), 128),
        ("classify.tf1d + shade.dos", with_dos(16), 64),
    ];
    for (stack_name, variants, side) in cases {
        let n = variants.len();
        let s = settings(side, side, Backend::Compute);
        let tiles: Vec<AtlasTile> = variants
            .iter()
            .map(|(camera, stack)| AtlasTile {
                camera: *camera,
                stack,
            })
            .collect();
        let mut r = Renderer::new(gpu(), demo()).unwrap();
        // warm: compile, instances and tables
        r.render_atlas(&tiles, &s, t, 8).unwrap();
        for (camera, stack) in &variants {
            render(
                &mut r,
                stack,
                t,
                &FrameSettings {
                    camera: *camera,
                    ..s
                },
            );
        }
        let (mut atlas_ms, mut single_ms) = (Vec::new(), Vec::new());
        for _ in 0..3 {
            let start = Instant::now();
            r.render_atlas(&tiles, &s, t, 8).unwrap();
            atlas_ms.push(start.elapsed().as_secs_f64() * 1e3);
            let start = Instant::now();
            for (camera, stack) in &variants {
                render(
                    &mut r,
                    stack,
                    t,
                    &FrameSettings {
                        camera: *camera,
                        ..s
                    },
                );
            }
            single_ms.push(start.elapsed().as_secs_f64() * 1e3);
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (a, b) = (median(&mut atlas_ms), median(&mut single_ms));
        eprintln!(
            "{stack_name}, {side}²: atlas {a:.1} ms ({:.2} ms/tile), {n} single renders {b:.1} ms ({:.2} ms/tile): ratio {:.3}",
            a / n as f64,
            b / n as f64,
            a / b
        );
        rows.push(serde_json::json!({
            "stack": stack_name,
            "tile": side,
            "tiles": n,
            "atlas_ms": a,
            "single_renders_ms": b,
            "atlas_ms_per_tile": a / n as f64,
            "single_ms_per_tile": b / n as f64,
            "atlas_over_single": a / b,
        }));
    }
    let out = serde_json::json!({
        "machine": vwb_lab::measure::machine(),
        "adapter": gpu().describe(),
        "scene": "embedded demo, classify.tf1d ramps (64 variants, 4 viewpoints; 16 under shade.dos), compute, rgba32float, spacing 1",
        "rows": rows,
    });
    vwb_lab::measure::save_json(&bench_doc("atlas_bench.json"), &out).expect("write");
}

/// The workgroup shape of the whole-frame compute passes (issue 23, item 4) changes
/// how pixels are grouped, never a pixel: every shape gives the 8×8 image bit for bit,
/// with and without empty-space skipping, at a size no shape divides, and in an atlas,
/// whether its invocations cover blocks of 4 × 2 pixels (`main_pixel`) or rows (6×6,
/// 1×1).
/// A shape the device cannot run falls back to the adapter's default.
#[test]
fn workgroup_shapes_render_the_same_pixels() {
    use vwb_render::renderer::{AtlasTile, RendererOptions};
    let s = settings(50, 37, Backend::Compute);
    let stack = vec![instance("classify.tf1d"), instance("shade.blinn_phong")];
    let t = TargetFormat::Rgba32Float;
    let mut cams = [s.camera; 2];
    cams[1].yaw_deg += 70.0;
    let run = |wg: [u32; 2]| {
        let options = RendererOptions {
            workgroup: Some(wg),
            ..Default::default()
        };
        let mut r = Renderer::with_options(gpu(), demo(), options).unwrap();
        let skip = render(&mut r, &stack, t, &s);
        r.set_empty_space_skipping(false);
        let all = render(&mut r, &stack, t, &s);
        let tiles: Vec<_> = cams
            .iter()
            .map(|c| AtlasTile {
                camera: *c,
                stack: &stack,
            })
            .collect();
        let atlas = r.render_atlas(&tiles, &s, t, 2).unwrap().pixels;
        (r.main_workgroup(), skip, all, atlas)
    };
    let base = run([8, 8]);
    assert_eq!(base.0, [8, 8]);
    assert!(base.1.iter().any(|p| p[3] > 0.1), "the demo is visible");
    for wg in [[16, 16], [16, 4], [4, 16], [32, 2], [6, 6], [1, 1]] {
        let other = run(wg);
        assert_eq!(other.0, wg);
        assert!(other.1 == base.1, "{wg:?} with skipping");
        assert!(other.2 == base.2, "{wg:?} without skipping");
        assert!(other.3 == base.3, "{wg:?} in an atlas");
    }
    // 4096 invocations exceed every device's limit: the adapter's default instead
    let fallback = run([64, 64]);
    assert_ne!(fallback.0, [64, 64]);
    assert!(fallback.1 == base.1);
}

/// `spread_row` (shaders/slice.wgsl), which orders a whole-frame dispatch's workgroup
/// rows so that every thread of a CPU device gets rows from all over the image, is a
/// permutation of the rows for every row count up to 600 (a row rendered twice would
/// leave another unrendered), and it spreads: the first half of the dispatch's rows
/// holds between a third and two thirds of the image's top half. The kernel runs the
/// shader's own search (its frame uniform names no rows here); the stride a frame
/// uniform hands it is that search's (`renderer::tests::the_spread_stride_permutes_the_rows`).
#[test]
fn spread_rows_are_a_permutation() {
    const MAX_ROWS: u32 = 600;
    let template = include_str!("../../shaders/slice.wgsl");
    let start = template
        .find("fn spread_row(")
        .expect("spread_row in slice.wgsl");
    let len = template[start..].find("\n}\n").expect("its end") + 3;
    let source = format!(
        "struct Frame {{ spread: vec4<u32> }}
var<private> frame: Frame = Frame(vec4<u32>(0u));
{}
@group(0) @binding(0) var<storage, read_write> out: array<u32>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {{
    // rows r = 1..=MAX, q < r, at offset r·(r−1)/2
    let rows = id.y + 1u;
    if (id.x < rows) {{
        out[rows * (rows - 1u) / 2u + id.x] = spread_row(id.x, rows);
    }}
}}",
        &template[start..start + len]
    );
    let count = (MAX_ROWS * (MAX_ROWS + 1) / 2) as usize;
    let values = run_compute_words(gpu(), &source, count, [MAX_ROWS.div_ceil(64), MAX_ROWS, 1]);
    for rows in 1..=MAX_ROWS {
        let at = (rows * (rows - 1) / 2) as usize;
        let order = &values[at..at + rows as usize];
        let mut seen = vec![false; rows as usize];
        for &t in order {
            assert!(t < rows && !seen[t as usize], "{rows} rows: {order:?}");
            seen[t as usize] = true;
        }
        if rows >= 8 {
            let top = order[..rows as usize / 2]
                .iter()
                .filter(|&&t| t < rows / 2)
                .count() as f64;
            let half = (rows / 2) as f64;
            assert!(
                (half / 3.0..=half * 2.0 / 3.0 + 1.0).contains(&top),
                "{rows} rows: {top} of the first half's rows in the top half"
            );
        }
    }
}

/// The `post` hook runs once per pixel on the accumulated colour on every path: the
/// compute backend's single dispatch and its per-slice resolve, the raster backend's
/// full-screen pass after the slices (also after per-slice state), in rgba16float and
/// rgba32float. `composite.tonemap` (one stop, gamma 1.5) matches its twin everywhere
/// and changes the image.
#[test]
fn post_hooks_run_once_per_pixel_on_every_path() {
    use crate::reference::{delta_e_rms, gpu_and_reference, gpu_delta_e_rms};
    let tonemap = {
        let p = vwb_plugins::registry().get("composite.tonemap").unwrap();
        let mut i = vwb_render::PluginInstance::new(p.clone());
        i.params = p.demo_params().unwrap();
        i
    };
    for per_slice in [false, true] {
        let mut plain = vec![instance("classify.tf1d")];
        if per_slice {
            plain.push(instance("shade.dos"));
        }
        let mut mapped = plain.clone();
        mapped.push(tonemap.clone());
        for backend in [Backend::Compute, Backend::Raster] {
            for target in [TargetFormat::Rgba16Float, TargetFormat::Rgba32Float] {
                let s = settings(48, 48, backend);
                let (px, reference) = gpu_and_reference(demo(), &mapped, target, &s);
                let rms = delta_e_rms(&px, &reference, 48, 48);
                let what = format!("{} {target:?} per-slice {per_slice}", backend.name());
                eprintln!("post hook, {what}: ΔE*uv RMS {rms:.4} against the twin");
                assert!(rms < twin_bound(backend, per_slice), "{what}: {rms}");
                let mut r = Renderer::new(gpu(), demo()).unwrap();
                let before = render(&mut r, &plain, target, &s);
                let moved = gpu_delta_e_rms(&px, &before, 48, 48);
                assert!(
                    moved > 2.0,
                    "{what}: the tone map changes the image ({moved})"
                );
            }
        }
    }
}

/// `setup` hooks run once per ray before its samples, and each instance's hooks read
/// its own record, on every path: the compute backend's single dispatch and its
/// per-slice dispatches (under per-slice state), the raster backend's fragments.
/// `sample.jitter` (interleaved, a whole step) at a coarse spacing of 3 voxels matches
/// its twin everywhere and changes the image (without the record the samples would
/// stay on the slices).
#[test]
fn setup_hooks_run_once_per_ray_on_every_path() {
    use crate::reference::{delta_e_rms, gpu_and_reference, gpu_delta_e_rms};
    let jitter = {
        let mut i = instance("sample.jitter");
        i.params
            .set("pattern", ParamValue::Enum("interleaved".into()));
        i
    };
    for per_slice in [false, true] {
        let mut plain = vec![instance("classify.tf1d")];
        if per_slice {
            plain.push(instance("shade.dos"));
        }
        let mut jittered = vec![jitter.clone()];
        jittered.extend(plain.iter().cloned());
        for backend in [Backend::Compute, Backend::Raster] {
            let mut s = settings(48, 48, backend);
            s.slice_spacing = 3.0;
            let target = TargetFormat::Rgba16Float;
            let (px, reference) = gpu_and_reference(demo(), &jittered, target, &s);
            let rms = delta_e_rms(&px, &reference, 48, 48);
            let what = format!("{} per-slice {per_slice}", backend.name());
            eprintln!("setup hook, {what}: ΔE*uv RMS {rms:.4} against the twin");
            assert!(rms < twin_bound(backend, per_slice), "{what}: {rms}");
            let mut r = Renderer::new(gpu(), demo()).unwrap();
            let on_slices = render(&mut r, &plain, target, &s);
            let moved = gpu_delta_e_rms(&px, &on_slices, 48, 48);
            eprintln!("setup hook, {what}: ΔE*uv RMS {moved:.3} from the unjittered image");
            assert!(
                moved > 1.0,
                "{what}: the jitter moves the samples ({moved})"
            );
        }
    }
}

/// The whole-frame march in parts (render/src/renderer/march_parts.rs, for llvmpipe's
/// loop limiter) gives the image of the march in one dispatch bit for bit: each part
/// marches its slices from the colour the part before left, rays that terminated early
/// take no more samples, and the brick lookups start again in every part. Parts of 7
/// slices (about 30 per frame here) with and without empty-space skipping and early
/// termination, unshaded and Blinn–Phong.
#[test]
fn march_parts_render_the_whole_march() {
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let tf = instance("classify.tf1d");
    let mut phong = instance("shade.blinn_phong");
    phong
        .params
        .set("gradient", ParamValue::Enum("central".into()));
    for stack in [vec![tf.clone()], vec![tf, phong]] {
        for (skipping, et) in [
            (true, None),
            (false, None),
            (true, Some(0.9)),
            (false, Some(0.95)),
        ] {
            r.set_empty_space_skipping(skipping);
            let s = FrameSettings {
                early_termination: et,
                ..settings(48, 40, Backend::Compute)
            };
            r.set_march_part_slices(None);
            let whole = render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
            let stats = r.render(&s).unwrap();
            assert!(stats.slices > 100, "{} slices", stats.slices);
            let one = if on_gpu() {
                1
            } else {
                stats.slices.div_ceil(30_000)
            };
            assert_eq!(
                stats.march_parts, one,
                "a frame that fits marches in one part"
            );
            assert_eq!(stats.loop_limited, 0);
            r.set_march_part_slices(Some(7));
            let parts = render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
            let stats = r.render(&s).unwrap();
            assert_eq!(stats.march_parts, stats.slices.div_ceil(7));
            let what = format!("{} plugins, skipping {skipping}, ET {et:?}", stack.len());
            assert!(
                whole.iter().any(|p| p[3] > 0.5),
                "{what}: the frame shows something"
            );
            let differ = whole.iter().zip(&parts).filter(|(a, b)| a != b).count();
            assert_eq!(
                differ, 0,
                "{what}: {differ} pixels differ from the whole march"
            );
        }
    }
    r.set_march_part_slices(None);
}
