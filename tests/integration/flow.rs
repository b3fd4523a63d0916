//! Flow: streamlines and 3D LIC of vector volumes on the CPU twin (`vwb_render::flow`),
//! rendered by slicing as the thesis does (§9.3: a precomputed LIC volume, a TF), and
//! the study behind docs/flow.md (`bash bench/flow.sh`).

use std::fmt::Write as _;
use std::time::Instant;

use glam::DVec3;
use vwb_render::flow::{
    Abc, Field, GridField, Integrator, LicParams, Noise, Rotation, Scaled, lic_volume,
    noise_volume, rotation_drift,
};
use vwb_render::params::ParamValue;
use vwb_render::volume::{Volume, VoxelData};
use vwb_render::{Backend, Renderer, TargetFormat};

use crate::common::*;

/// RMS difference of two scalar volumes, in 1/255 units.
fn rms_255(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len());
    (a.iter()
        .zip(b)
        .map(|(x, y)| ((x - y) as f64 * 255.0).powi(2))
        .sum::<f64>()
        / a.len().max(1) as f64)
        .sqrt()
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

/// The time a study quotes for a frame: its GPU time on a GPU (the wall time there is
/// mostly overhead), else its wall time.
fn quoted_ms(wall: f64, gpu: Option<f64>) -> f64 {
    if on_gpu() { gpu.unwrap_or(wall) } else { wall }
}

/// Frames of `r` timed as the studies time them: on a GPU 9 after 10 warm-up frames
/// (its clocks ramp up), else 3 after 1.
fn study_timing(r: &mut Renderer, s: &vwb_render::FrameSettings) -> vwb_lab::measure::Timing {
    let (warm, frames) = if on_gpu() { (10, 9) } else { (1, 3) };
    vwb_lab::measure::time_frames(r, s, warm, frames).unwrap()
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

/// Mean |I(p) − I(p + d)| over the volume for d one voxel along the flow, and across
/// it (along v × z, or v × x where v is vertical).
fn along_and_across(lic: &Volume, field: &GridField) -> (f64, f64) {
    let d = lic.dims;
    let at = |p: DVec3| {
        let q = p.round();
        ((0..3).all(|a| q[a] >= 0.0 && q[a] < d[a] as f64))
            .then(|| lic.scalar(q.x as u32, q.y as u32, q.z as u32))
    };
    let (mut along, mut across, mut n) = (0.0, 0.0, 0);
    for z in 1..d[2] - 1 {
        for y in (1..d[1] - 1).step_by(2) {
            for x in (1..d[0] - 1).step_by(2) {
                let p = DVec3::new(x as f64, y as f64, z as f64);
                let Some(v) = field.at(p).filter(|v| v.length() > 1e-9) else {
                    continue;
                };
                let t = v.normalize();
                let side = if t.z.abs() < 0.9 {
                    t.cross(DVec3::Z)
                } else {
                    t.cross(DVec3::X)
                }
                .normalize();
                let (Some(i0), Some(a), Some(b)) = (at(p), at(p + t), at(p + side)) else {
                    continue;
                };
                along += (i0 - a).abs();
                across += (i0 - b).abs();
                n += 1;
            }
        }
    }
    (along / n as f64, across / n as f64)
}

/// The storm's LIC volume has swirling structure: neighbours along the flow are far
/// more alike than across it; sliced with a TF it renders a finite, visible image.
#[test]
fn storm_lic_shows_structure_along_the_flow() {
    let (lic, field) = storm_lic(4, &LicParams::default(), Noise::White);
    let (along, across) = along_and_across(&lic, &field);
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

/// docs/flow.md: streamline drift per integrator and step on the rotation, LIC time and
/// error against a fine reference (the Pareto front), the storm's LIC image. Run:
/// `bash bench/flow.sh`.
#[test]
#[ignore = "study: bash bench/flow.sh"]
fn flow_study() {
    let mut o = String::new();
    let machine = vwb_lab::measure::machine();
    let _ = writeln!(o, "# Flow: streamlines and 3D LIC\n");
    let _ = writeln!(
        o,
        "Written by `bash bench/flow.sh` (`flow_study` in tests/integration/flow.rs). Machine: {machine}; \
         adapter: {}. The CPU twin (`vwb_render::flow`, f64, rayon) and the GPU plugin `flow.lic3d` in its two \
         modes: precomputed (a pre-pass writes the LIC volume, rerun only when the field, the noise or an \
         integration parameter changes; `lic_prepass_matches_its_twin`) and on the fly (the sample hook \
         integrates; `lic_on_the_fly_matches_its_twin_without_a_prepass`).\n",
        gpu().describe()
    );

    // drift after one turn at radius 8 on the analytic rotation
    let c = DVec3::new(128.0, 128.0, 128.0);
    let rot = Rotation { center: c };
    let _ = writeln!(o, "## Streamline drift on the rotation v = (−y, x, 0)\n");
    let _ = writeln!(
        o,
        "Seeded at radius 8 voxels, unit speed (step = arc length), ⌈2π·8/h⌉ steps (one turn); drift = | |p − c| − 8 | voxels \
         at the end. The field is linear, so a grid samples it exactly; these are the integrators' own errors.\n"
    );
    let _ = writeln!(
        o,
        "| integrator | h (voxels) | steps | drift (voxels) |\n|---|---:|---:|---:|"
    );
    for integrator in Integrator::ALL {
        for h in [2.0, 1.0, 0.5, 0.25, 0.1] {
            let steps = (std::f64::consts::TAU * 8.0 / h).ceil() as usize;
            let d = rotation_drift(&rot, c, 8.0, h, integrator, steps);
            let _ = writeln!(o, "| {} | {h} | {steps} | {d:.3e} |", integrator.name());
        }
    }
    let inviwo = rotation_drift(&rot, c, 8.0, 0.003 * 256.0, Integrator::Euler, 200);
    let _ = writeln!(
        o,
        "| Euler, Inviwo LIC3D defaults (200 samples, step 0.003 of the texture = 0.768 voxels at 256³) | 0.768 | 200 | {inviwo:.3} |\n"
    );
    let _ = writeln!(
        o,
        "Unit-speed Euler moves off the circle by r² → r² + h² per step, so after n steps it is √(r² + n·h²) − r \
         voxels out: the Inviwo row's 200 steps of 0.768 voxels end {inviwo:.2} voxels off (the issue quotes ≈ 4.7 for \
         Inviwo's own velocity scaling). RK4 at half a voxel, our default, stays within 10⁻⁶ voxels.\n"
    );

    // LIC: time and error against a fine reference, over h, L and the integrator
    let dims = [64u32, 64, 64];
    let abc = Abc {
        period: 64.0,
        ..Default::default()
    };
    let noise = noise_volume(dims, Noise::White, 7);
    let reference_params = LicParams {
        step: 0.125,
        ..Default::default()
    };
    let t = Instant::now();
    let reference = lic_volume(&abc, &noise, &reference_params);
    let reference_s = t.elapsed().as_secs_f64();
    let _ = writeln!(o, "## LIC: time against error\n");
    let _ = writeln!(
        o,
        "ABC flow (period 64 voxels) on 64³, white noise, tent kernel; error: RMS difference of the LIC volume \
         against the same L with RK4 at h = 0.125 ({reference_s:.2} s), in 1/255 units. Time: the CPU twin on \
         this machine.\n"
    );
    let _ = writeln!(
        o,
        "| integrator | h | L | time (s) | RMS error (/255) | Pareto |\n|---|---:|---:|---:|---:|---|"
    );
    let mut points = Vec::new();
    for integrator in Integrator::ALL {
        for h in [2.0, 1.0, 0.5, 0.25] {
            let p = LicParams {
                step: h,
                integrator,
                ..Default::default()
            };
            let t = Instant::now();
            let lic = lic_volume(&abc, &noise, &p);
            let secs = t.elapsed().as_secs_f64();
            let rms = rms_255(&lic, &reference);
            points.push((integrator.name(), h, 8.0, secs, rms));
        }
    }
    for (name, h, l, secs, rms) in &points {
        let dominated = points
            .iter()
            .any(|q| q.3 <= *secs && q.4 <= *rms && (q.3 < *secs || q.4 < *rms));
        let _ = writeln!(
            o,
            "| {name} | {h} | {l} | {secs:.3} | {rms:.3} | {} |",
            if dominated { "" } else { "front" }
        );
    }
    let _ = writeln!(
        o,
        "\nAt a given h, RK2 and RK4 give nearly the same error: against the reference at h = 0.125 the error is \
         mostly the convolution's sampling (the sum's spacing), not the streamline's; Euler's drift adds to it \
         at h ≥ 0.5. RK2 is on the front at every h but the finest. Times are wall times on a shared 2-core \
         machine (± 20 %)."
    );

    // the integrators on the GPU (an experiment file's block with its discussion, kept
    // as written), then the precompute time: experiment files
    let old = std::fs::read_to_string(bench_doc("flow.md")).unwrap_or_default();
    o.push('\n');
    o += kept_section(
        &old,
        "### On the GPU: the integrator against the image",
        "## Precompute time",
        &["flow_integrators"],
    )
    .trim_end();
    o.push('\n');
    let _ = write!(
        o,
        "\n## Precompute time\n\n\
         The pre-pass of the precomputed mode: ABC flow (period = the grid's side), `flow.lic3d`'s defaults (white \
         noise, RK4, h = 0.5, L = 8: 2 × 16 steps per voxel, tent kernel) and L = 20 (2 × 40 steps), in f32 and f16 \
         storage, seen at 32² so that slicing costs little. `update (ms)` is the pre-pass as a change costs it (wall \
         clock, the median of three reruns); `update, GPU (ms)` its GPU timestamps where the adapter has them. \
         `twin_rms` is the RMS difference of the GPU's LIC volume against the f64 twin with the same noise and \
         unrounded inputs, in 1/255 (`storage: f16` keeps the field and the noise in half floats: half their memory \
         and texture traffic, for that error; against a twin that rounds them alike it is the f32 row's, \
         `lic_prepass_matches_its_twin`). The issue's H100 target is the 256³ block's L = 20 rows in ≤ 150 ms \
         (timestamps); a CPU adapter cannot judge it, and on a GPU `vwb run` writes the blocks into \
         docs/gpu/flow.md. Each block is written by its experiment file (`vwb run experiments/NAME.ron`, the name \
         in its marker) and kept by this study.\n\n{}",
        kept_experiment_blocks(&old, &["flow_precompute", "flow_precompute_256"])
    );

    // on the fly against precomputed, and output sensitivity: experiment files
    let _ = write!(
        o,
        "## On the fly against precomputed\n\n\
         The two modes in one scene (experiments/scenes/abc_lic_half.ron: the ABC flow on 64³, `flow.lic3d` \
         defaults, head-on, one slice per voxel, 128²), whole and with half the image clipped by a plane, then \
         animated (the periodic kernel's phase advanced at every grid point). `time (ms)` is a frame; \
         `update (ms)` is the first frame after a change less a frame: in `flow_modes` the first frame on each \
         variant's fresh renderer (the pre-pass and first use), in `flow_animation` what a new phase reruns \
         (the precomputed mode's pre-pass; its first row also pays for first use). The pre-pass grows with the LIC grid (8× at frequency 2) and on the fly with \
         the samples that reach the hook, so on the fly pays for small, clipped or early-terminated views of \
         large grids, for LICs that change every frame, and where the LIC volume would not fit. Each block is \
         written by its experiment file (`vwb run experiments/NAME.ron`, the name in its marker) and kept by \
         this study.\n\n{}",
        kept_experiment_blocks(&old, &["flow_modes", "flow_animation"])
    );
    let _ = write!(
        o,
        "{SENSITIVITY_HEADING}\n\n{}\n\n",
        kept_block(
            &old,
            "lic_output_sensitivity",
            "`bash bench/ignored_test.sh lic_output_sensitivity`"
        )
    );

    experiment_blocks(&mut o);
    arrival_study(&mut o);

    // a field from a named volume (written by hand, kept as written)
    o += &kept_section(&old, "## A field from a named volume", "## The storm", &[]);

    // the storm
    let (lic, field) = storm_lic(4, &LicParams::default(), Noise::White);
    let (along, across) = along_and_across(&lic, &field);
    // the picture: sparse noise (5 % spots) shows streaks, the thesis's sparse look
    let (lic, _) = storm_lic(4, &LicParams::default(), Noise::Sparse { density: 0.05 });
    let _ = writeln!(
        o,
        "## The storm\n\nNCSA storm wind (25×14×8, u,v,w), LIC at 4× its resolution (100×56×32), RK4, h = 0.5, L = 8, \
         white noise: mean |ΔI| between neighbours along the flow {along:.4}, across it {across:.4} \
         (`storm_lic_shows_structure_along_the_flow` asserts along < ½ across). Below, the same with sparse noise \
         (5 % of the voxels lit), rendered by slicing with a 1D TF that shows the upper half of the LIC values:\n\n\
         ![storm LIC](images/storm_lic.png)\n"
    );
    let mut r = Renderer::new(gpu(), std::sync::Arc::new(lic)).unwrap();
    let mut tf = instance("classify.tf1d");
    tf.params.set(
        "tf",
        ParamValue::Tf(vwb_render::tf::TfCurve::ramp(
            0.06,
            0.3,
            [1.0, 0.85, 0.5, 0.35],
        )),
    );
    let mut s = settings(384, 384, Backend::Compute);
    s.camera.pitch_deg = 40.0;
    s.camera.yaw_deg = 20.0;
    s.camera.roll_deg = 0.0;
    render(&mut r, &[tf], TargetFormat::Rgba32Float, &s);
    let (w, h, px) = r.read_pixels().unwrap();
    let rgb = vwb_lab::headless::composite_over(&px, [0.0, 0.0, 0.0, 1.0]);
    let bytes: Vec<u8> = rgb
        .iter()
        .flat_map(|p| p.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8))
        .collect();
    image::save_buffer(
        bench_doc("images/storm_lic.png"),
        &bytes,
        w,
        h,
        image::ExtendedColorType::Rgb8,
    )
    .unwrap();
    // the storm behind its time surfaces, at three times
    let (doc, storm) = preset_scene("presets/storm_time_surfaces.ron");
    let mut r = vwb_lab::headless::renderer_for(gpu(), &doc, storm).unwrap();
    let mut s = doc.frame_settings();
    (s.width, s.height) = (256, 256);
    let mut strip = image::RgbImage::new(3 * 256, 256);
    let mut stack = doc.stack.clone();
    for (k, t) in [8.0f32, 24.0, 60.0].into_iter().enumerate() {
        stack[0].params.set("time", ParamValue::Float(t));
        r.update_stack(&stack, doc.render.target).unwrap();
        let (img, _, _) =
            vwb_lab::headless::render_image(&mut r, &s, doc.render.background).unwrap();
        image::imageops::replace(&mut strip, &img, k as i64 * 256, 0);
    }
    vwb_lab::headless::save_png(&strip, &bench_doc("images/storm_time_surfaces.png")).unwrap();
    let _ = writeln!(
        o,
        "\n`presets/storm_time_surfaces.ron` at time 8, 24 and 60 (voxels at the storm's top speed): the LIC of the \
         wind carried from a seed box on the low-x side.\n\n![storm time surfaces](images/storm_time_surfaces.png)\n"
    );
    std::fs::write(bench_doc("flow.md"), o).unwrap();
}

/// The scene of the on-the-fly study, experiments/scenes/abc_lic_half.ron (the
/// experiment files flow_modes and flow_animation read it too): the ABC flow on 64³;
/// `flow.lic3d` in a mode; `clip.shapes` with a plane through the centre (axis x),
/// switched on, which, head-on along z, clips away half of the volume's footprint;
/// the default 1D TF; and the scene's frame settings at `side`².
#[allow(clippy::type_complexity)]
fn lic_half_scene() -> (
    std::sync::Arc<Volume>,
    impl Fn(&str) -> vwb_render::PluginInstance,
    vwb_render::PluginInstance,
    vwb_render::PluginInstance,
    impl Fn(u32) -> vwb_render::FrameSettings,
) {
    let (doc, vol) = preset_scene("experiments/scenes/abc_lic_half.ron");
    let of = |id: &str| {
        let mut i = doc
            .stack
            .iter()
            .find(|i| i.plugin.id() == id)
            .unwrap()
            .clone();
        i.enabled = true;
        i
    };
    let (lic, plane, tf) = (of("flow.lic3d"), of("clip.shapes"), of("classify.tf1d"));
    let with_mode = move |mode: &str| {
        let mut i = lic.clone();
        i.params.set("mode", ParamValue::Enum(mode.into()));
        i
    };
    let frame = doc.frame_settings();
    let at = move |side: u32| {
        let mut s = frame;
        (s.width, s.height) = (side, side);
        s
    };
    (vol, with_mode, plane, tf, at)
}

const SENSITIVITY_HEADING: &str = "### Output sensitivity by image size";

/// Output sensitivity of on-the-fly LIC by image size (docs/flow.md or docs/gpu/flow.md,
/// block `lic_output_sensitivity`): the frame with half the image clipped against the
/// full one, in the scene of [`lic_half_scene`]. A GPU runs one thread per pixel; an
/// image too small to fill it several times over is bound by the latency of one
/// thread's integrals, not by the work, and clipping half of the threads saves less
/// than half the time. Run: `bash bench/ignored_test.sh lic_output_sensitivity`.
#[test]
#[ignore = "benchmark: bash bench/ignored_test.sh lic_output_sensitivity"]
fn lic_output_sensitivity() {
    let (vol, with_mode, plane, tf, head_on) = lic_half_scene();
    let sides: &[u32] = if on_gpu() {
        &[256, 512, 1024, 2048]
    } else {
        &[64, 128, 256]
    };
    let mut rows = String::new();
    for &side in sides {
        let s = head_on(side);
        let mut ms = Vec::new();
        for stack in [
            vec![with_mode("on_the_fly"), tf.clone()],
            vec![with_mode("on_the_fly"), plane.clone(), tf.clone()],
        ] {
            let mut r = Renderer::new(gpu(), vol.clone()).unwrap();
            r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
            let t = study_timing(&mut r, &s);
            let (_, _, px) = r.read_pixels().unwrap();
            let frame = quoted_ms(t.wall_ms.median, t.gpu_ms.map(|g| g.median));
            ms.push((frame, covered(&px)));
        }
        let (full, half) = (ms[0], ms[1]);
        eprintln!("{side}²: {:.2} ms full, {:.2} ms half", full.0, half.0);
        let _ = writeln!(
            rows,
            "| {side}² | {} | {} | {:.0} % | {:.2} |",
            fmt_ms(full.0),
            fmt_ms(half.0),
            half.1 / full.1.max(1e-12) * 100.0,
            half.0 / full.0
        );
    }
    let body = format!(
        "Machine: {}; adapter: {}. Command: `bash bench/ignored_test.sh lic_output_sensitivity`. The scene of the \
         on-the-fly study above (ABC flow on 64³, `flow.lic3d` on the fly with its defaults, head-on along z, one \
         slice per voxel, compute backend); frame: median {} of {} frames after {}. Coverage: the clipped frame's \
         non-transparent pixels against the full frame's.\n\n\
         | image | full (ms) | half clipped (ms) | pixels kept | ratio |\n|---|---:|---:|---:|---:|\n{rows}\n\
         The compute backend runs one thread per pixel, which marches its ray; a clipped pixel's thread finishes \
         early. Where the image holds fewer threads than the device keeps in flight (an H200: 132 SMs of up to \
         2048 threads), a frame lasts as long as the slowest threads' chains of dependent texture reads, so \
         removing half of the threads saves less than half the time; once the image fills the device several \
         times over, the time follows the work. A CPU device (lavapipe) runs the work in order on its cores and \
         saves half at every size.\n",
        vwb_lab::measure::machine(),
        gpu().describe(),
        if on_gpu() {
            "GPU time (timestamps)"
        } else {
            "wall time"
        },
        if on_gpu() { 9 } else { 3 },
        if on_gpu() { 10 } else { 1 },
    );
    write_or_add_block(
        &bench_doc("flow.md"),
        "lic_output_sensitivity",
        SENSITIVITY_HEADING,
        &body,
    );
    eprintln!("{body}");
}

/// The text of `old` (docs/flow.md before the study rewrites it) from the first line
/// starting with `from` up to the line starting with `to`: a section written by hand
/// around experiment blocks, kept as it stands. Where it is missing, `from` and the
/// blocks of the experiment files `names` (empty, saying how to run them).
fn kept_section(old: &str, from: &str, to: &str, names: &[&str]) -> String {
    let start = old.find(&format!("\n{from}")).map(|i| i + 1);
    let kept = start.and_then(|i| old[i..].find(&format!("\n{to}")).map(|j| &old[i..=i + j]));
    match kept {
        Some(text) => text.to_string(),
        None => format!("{from}\n\n{}", kept_experiment_blocks("", names)),
    }
}

/// The section holding the blocks of the experiment files that write into
/// docs/flow.md, each kept as the last run of its experiment wrote it (the study
/// rewrites the rest of the document).
fn experiment_blocks(o: &mut String) {
    let old = std::fs::read_to_string(bench_doc("flow.md")).unwrap_or_default();
    let _ = write!(
        o,
        "## Lighting, occlusion and clipping of the LIC\n\n\
         Each block below is written by its experiment file (`vwb run experiments/NAME.ron`, the name in its \
         marker) and kept by this study.\n\n{}",
        kept_experiment_blocks(&old, &["flow_lit", "flow_dos", "flow_clip"])
    );
}

/// A renderer for `vol` and `stack` at 32² (compute) after the frame that runs the
/// pre-pass and one that runs none: the first frame's stats and its wall time minus
/// the second's (the pre-pass's time where a CPU adapter has no timestamps).
fn prepass_once(
    vol: &std::sync::Arc<Volume>,
    stack: Vec<vwb_render::PluginInstance>,
) -> (
    Renderer,
    vwb_render::FrameSettings,
    vwb_render::FrameStats,
    f64,
) {
    let mut r = Renderer::new(gpu(), vol.clone()).unwrap();
    r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
    let s = settings(32, 32, Backend::Compute);
    let first = r.render(&s).unwrap();
    assert_eq!(first.prepasses_run(), 1);
    let second = r.render(&s).unwrap();
    assert_eq!(second.prepasses_run(), 0);
    let ms = first.wall_ms - second.wall_ms;
    (r, s, first, ms)
}

/// An arrival volume read back from the GPU against its twin's: voxels where one is
/// reached and the other not, and over the voxels both reach, |Δt| / (1 + t).
struct ArrivalAgreement {
    disagree: usize,
    reached: usize,
    rms: f64,
    worst: f64,
}

impl ArrivalAgreement {
    fn of(gpu_t: &[f32], twin: &[f32]) -> Self {
        let never = vwb_render::flow::NEVER;
        let (mut disagree, mut reached, mut worst, mut sq) = (0usize, 0usize, 0.0f64, 0.0f64);
        for (g, c) in gpu_t.iter().zip(twin) {
            if (*g == never) != (*c == never) {
                disagree += 1;
            } else if *c != never {
                reached += 1;
                let e = (*g as f64 - *c as f64).abs() / (1.0 + *c as f64);
                worst = worst.max(e);
                sq += e * e;
            }
        }
        Self {
            disagree,
            reached,
            rms: (sq / reached.max(1) as f64).sqrt(),
            worst,
        }
    }
}

/// On a GPU, the median of 7 pre-pass timestamps, each run forced by the stack
/// `stack_at(k)` gives (an input of the pre-pass changed in a way that leaves its result
/// the same): a first run pays for first use and the clocks ramp up. `None` on a CPU
/// adapter.
fn rerun_median_ms(
    r: &mut Renderer,
    s: &vwb_render::FrameSettings,
    stack_at: impl Fn(usize) -> Vec<vwb_render::PluginInstance>,
) -> Option<f64> {
    if !on_gpu() {
        return None;
    }
    let ms: Vec<f64> = (0..7)
        .filter_map(|k| {
            r.update_stack(&stack_at(k), TargetFormat::Rgba32Float)
                .unwrap();
            let st = r.render(s).unwrap();
            assert_eq!(st.prepasses_run(), 1);
            stamped_ms(&st, |l| l.starts_with("prepass"))
        })
        .collect();
    vwb_lab::measure::Summary::of(&ms).map(|m| m.median)
}

/// The arrival-time sections of docs/flow.md: accuracy on the rotation against the
/// exact arrival, the pre-pass against its twin and its time, and the animation's frame
/// time against a static frame.
fn arrival_study(o: &mut String) {
    use vwb_render::flow::{ArrivalParams, SeedBox, Tornado, arrival_at};
    let _ = writeln!(
        o,
        "## Time surfaces: the arrival-time volume (`flow.arrival`)\n"
    );
    let _ = writeln!(
        o,
        "The thesis animates the LIC by switching between closed time-surface clip meshes advected from a start \
         mesh. `flow.arrival` stores instead, per voxel, when matter released from a seed box reaches it (traced \
         backwards in time with steps of `dt = h/|v|`, the entry interpolated along the last step, times in voxels at \
         the field's top speed), and its clip hook keeps what arrived by `time`: the time surface at t is that \
         volume's level set, and playing t changes one uniform.\n"
    );
    // accuracy: rotation v = (−y, x, 0), angular speed 1, seed on the ray θ = 0 (one
    // voxel thick): the exact arrival at angle θ and radius r is θ − asin(½/r)
    let c = DVec3::new(64.0, 64.0, 2.0);
    let rot = Rotation { center: c };
    let dims = [128, 128, 4];
    let seed = SeedBox {
        min: DVec3::new(64.5 / 128.0, 64.0 / 128.0, 0.0),
        max: DVec3::new(1.0, 65.0 / 128.0, 1.0),
    };
    let _ = writeln!(
        o,
        "### Accuracy on the rotation\n\nv = (−y, x, 0) (angular speed 1), the seed a one-voxel-thick box on the ray θ = 0; \
         the exact arrival at angle θ and radius r is θ − asin(½/r). Error: RMS and worst |t − exact| / exact over r ∈ \
         {{8, 16, 32, 48}} × θ ∈ {{0.5, 1.5, 3, 4.5, 6}} rad (the f64 twin; the GPU matches it, below).\n\n\
         | integrator | h (voxels) | RMS relative error | worst |\n|---|---:|---:|---:|"
    );
    for integrator in Integrator::ALL {
        for h in [2.0, 1.0, 0.5, 0.25] {
            let a = ArrivalParams {
                step: h,
                max_length: 1024.0,
                integrator,
            };
            let (mut sq, mut worst, mut n) = (0.0f64, 0.0f64, 0);
            for r in [8.0f64, 16.0, 32.0, 48.0] {
                for theta in [0.5f64, 1.5, 3.0, 4.5, 6.0] {
                    let p = c + DVec3::new(r * theta.cos(), r * theta.sin(), 0.0);
                    let exact = theta - (0.5 / r).asin();
                    let t = arrival_at(&rot, dims, &seed, p, &a);
                    let e = if t.is_finite() {
                        (t - exact).abs() / exact
                    } else {
                        1.0
                    };
                    sq += e * e;
                    worst = worst.max(e);
                    n += 1;
                }
            }
            let rms = (sq / n as f64).sqrt();
            let _ = writeln!(
                o,
                "| {} | {h} | {rms:.2e} | {worst:.2e} |",
                integrator.name()
            );
            if integrator == Integrator::Rk4 && h <= 0.5 {
                assert!(rms < 1e-2, "RK4 h {h}: {rms}");
            }
        }
    }
    let _ = writeln!(
        o,
        "\nThe error left at small h is the entry's: the path enters the seed box within a step, and the \
         interpolation along the step's chord is first order in the curvature; Euler adds its drift off the circle.\n"
    );

    // GPU pre-pass: time and agreement with the twin, on tornadoes filling the grid
    let sides: &[u32] = if on_gpu() { &[64, 128, 256] } else { &[32, 64] };
    let _ = writeln!(
        o,
        "### The pre-pass\n\nA tornado filling the grid (core side/6, inflow 0.3, updraft 0.4), the seed a flat box \
         across the updraft at the bottom (z ≤ 8 %), RK4, h = 0.5, paths up to 256 voxels: `flow.arrival`'s \
         defaults. GPU time as for the LIC pre-pass (on a GPU the median of 7 reruns' timestamps, else the first \
         frame's wall time minus the second's, at 32²). Agreement with the f64 twin: voxels where one is reached and the other not, and the RMS \
         of |Δt| / (1 + t) over the reached ones.\n\n\
         | grid | reached | GPU pre-pass (s) | twin (s) | reached/never disagree | time error RMS |\n|---|---:|---:|---:|---:|---:|"
    );
    for &side in sides {
        let sf = side as f64;
        let vol = std::sync::Arc::new(vector_volume(
            &Tornado {
                center: DVec3::new(sf / 2.0 - 0.5, sf / 2.0 - 0.5, sf / 8.0),
                core: sf / 6.0,
                inflow: 0.3,
                updraft: 0.4,
            },
            [side; 3],
        ));
        let mut arrival = instance("flow.arrival");
        arrival
            .params
            .set("seed_max", ParamValue::Vec3([1.0, 1.0, 0.08]));
        let (mut r, s, _, once_ms) =
            prepass_once(&vol, vec![arrival.clone(), instance("classify.tf1d")]);
        // on a GPU the median of 7 reruns: paths of up to 255.9 or 256 voxels take the
        // same ⌈L/h⌉ = 512 steps, so each rerun computes the same volume
        let stamped = rerun_median_ms(&mut r, &s, |k| {
            let mut again = arrival.clone();
            let l = if k % 2 == 0 { 255.9 } else { 256.0 };
            again.params.set("max_length", ParamValue::Float(l));
            vec![again, instance("classify.tf1d")]
        });
        let gpu_s = stamped.unwrap_or(once_ms) / 1e3;
        let (_, gpu_t) = r.read_prepass(arrival.uid).expect("the arrival volume");
        let (twin_s, agreement) = if side <= 128 {
            let t = Instant::now();
            let twin = vwb_plugins::flow_arrival::arrival_of(&vol, &arrival.params);
            let secs = t.elapsed().as_secs_f64();
            let a = ArrivalAgreement::of(&gpu_t, &twin);
            assert!(
                a.disagree * 1000 <= twin.len(),
                "{side}³: {} disagree",
                a.disagree
            );
            (
                format!("{secs:.1}"),
                format!("{} | {:.1e}", a.disagree, a.rms),
            )
        } else {
            ("—".into(), "— | —".into())
        };
        let reached = gpu_t
            .iter()
            .filter(|t| **t != vwb_render::flow::NEVER)
            .count() as f64
            / gpu_t.len() as f64;
        eprintln!(
            "arrival {side}³: GPU {gpu_s:.3} s, twin {twin_s} s, reached {:.0} %",
            reached * 100.0
        );
        let _ = writeln!(
            o,
            "| {side}³ | {:.0} % | {gpu_s:.3} | {twin_s} | {agreement} |",
            reached * 100.0
        );
    }

    // the animation: the time advanced every frame against a static frame, with the LIC
    // precomputed and on the fly behind the mask
    let side = if on_gpu() { 512 } else { 128 };
    let vol = std::sync::Arc::new(vector_volume(
        &Tornado {
            center: DVec3::new(31.5, 31.5, 8.0),
            core: 10.0,
            inflow: 0.3,
            updraft: 0.4,
        },
        [64; 3],
    ));
    let mut s = settings(side, side, Backend::Compute);
    s.camera.pitch_deg = 20.0;
    // the integrators of the pre-pass on the GPU (an experiment file's block with its
    // discussion, kept as written)
    let old = std::fs::read_to_string(bench_doc("flow.md")).unwrap_or_default();
    o.push('\n');
    *o += kept_section(
        &old,
        "The integrator and the step of the pre-pass against the image",
        "### Playing the time",
        &["flow_arrival_integrators"],
    )
    .trim_end();
    o.push('\n');
    let _ = writeln!(
        o,
        "\n### Playing the time\n\nThe 64³ tornado, `flow.arrival` (time 0 → 64 over the frames) before `flow.lic3d` and \
         the default 1D TF, compute at {side}²: the median {} of the 8 frames right after the time advanced by 8 \
         (0 → 64), against the median of the same stack's static frames at those times (nothing changed). Pre-passes \
         rerun: counted over the animated frames.\n\n| LIC mode | static frame (ms) | animated frame (ms) | ratio | pre-passes rerun |\n|---|---:|---:|---:|---:|",
        if on_gpu() {
            "GPU time (timestamps)"
        } else {
            "wall time"
        }
    );
    for mode in ["precomputed", "on_the_fly"] {
        let mut arrival = instance("flow.arrival");
        arrival
            .params
            .set("seed_max", ParamValue::Vec3([1.0, 1.0, 0.08]));
        let mut lic = instance("flow.lic3d");
        lic.params.set("mode", ParamValue::Enum(mode.into()));
        let mut r = Renderer::new(gpu(), vol.clone()).unwrap();
        let mut timed = |r: &mut Renderer, t: f32| {
            arrival.params.set("time", ParamValue::Float(t));
            r.update_stack(
                &[arrival.clone(), lic.clone(), instance("classify.tf1d")],
                TargetFormat::Rgba32Float,
            )
            .unwrap();
            r.render(&s).unwrap()
        };
        // warm-up (a GPU ramps its clocks up)
        for _ in 0..if on_gpu() { 10 } else { 1 } {
            timed(&mut r, 0.0);
        }
        // each time twice: the first frame after the time moved, then a static one
        let (mut statics, mut moving, mut reruns) = (Vec::new(), Vec::new(), 0);
        for f in 0..8 {
            let t = 8.0 * (f + 1) as f32;
            let st = timed(&mut r, t);
            reruns += st.prepasses_run();
            moving.push(quoted_ms(st.wall_ms, st.gpu_ms));
            let still = timed(&mut r, t);
            statics.push(quoted_ms(still.wall_ms, still.gpu_ms));
        }
        assert_eq!(reruns, 0, "{mode}: playing the time reran a pre-pass");
        let a = vwb_lab::measure::Summary::of(&statics).unwrap().median;
        let b = vwb_lab::measure::Summary::of(&moving).unwrap().median;
        eprintln!("arrival animation, LIC {mode}: static {a:.2} ms, animated {b:.2} ms");
        let _ = writeln!(
            o,
            "| {mode} | {} | {} | {:.2} | {reruns} |",
            fmt_ms(a),
            fmt_ms(b),
            b / a
        );
    }
    let _ = writeln!(
        o,
        "\nThe animated frames cost what static ones do (the ratio is the frame-to-frame noise): nothing is \
         recomputed. `presets/storm_time_surfaces.ron` \
         is the storm's LIC behind the time surfaces (below); `vwb render --preset presets/storm_time_surfaces.ron \
         --sequence 0:60:31 -o frames/storm.png` writes the animation as images, and the window plays `time` (Play, speed, \
         loop beside its slider).\n"
    );
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
    let ArrivalAgreement {
        disagree,
        reached,
        rms,
        worst,
    } = ArrivalAgreement::of(&gpu_t, &twin);
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
            top > 0.0 && worst <= 1e-4 * top.max(1.0),
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
            top > 0.0 && worst <= 1e-4 * top.max(1.0),
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
