//! `shade.hernell` (Hernell, Ljung & Ynnerman 2008): the GPU light passes against the
//! CPU twin on both backends; which passes rerun for which change (camera moves rerun
//! none); progressive refinement over frames; clipped matter casts no light shadow.
//! The measurements (`bash bench/hernell.sh`) write docs/hernell.md.

use std::sync::Arc;

use vwb_render::params::ParamValue;
use vwb_render::{Backend, PluginInstance, Renderer, TargetFormat, Volume};

use crate::clipping::{block_removed_consistency, dos_stack};
use crate::common::*;
use crate::reference::{delta_e_rms, gpu_and_reference};

/// A ball in front of a slab (24³), both with edges ramped over 3 voxels: the ball
/// shadows the slab under an oblique light.
fn ball_and_slab() -> Arc<Volume> {
    synthetic([24; 3], |x, y, z| {
        let c = [x, y, z].map(|v| v as f32 + 0.5 - 9.0);
        let r = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        let ball = ((6.5 - r) / 3.0).clamp(0.0, 1.0);
        let zc = z as f32 + 0.5;
        let slab = ((2.5 - (zc - 19.0).abs()) / 3.0 + 0.5).clamp(0.0, 1.0);
        ball.max(slab)
    })
}

fn tf() -> PluginInstance {
    let mut tf = instance("classify.tf1d");
    tf.params.set(
        "tf",
        ParamValue::Tf(vwb_render::tf::TfCurve::ramp(
            0.3,
            0.7,
            [0.9, 0.8, 0.7, 0.35],
        )),
    );
    tf
}

fn hernell(edit: &[(&str, ParamValue)]) -> PluginInstance {
    let mut h = instance("shade.hernell");
    h.params.set("light", ParamValue::Vec3([0.3, 0.4, -1.0]));
    h.params.set("segment", ParamValue::Int(4));
    h.params.set("radius", ParamValue::Float(3.0));
    h.params
        .set("sphere", ParamValue::Enum("tetrahedron".into()));
    for (k, v) in edit {
        h.params.set(k, v.clone());
    }
    h
}

#[test]
fn gpu_light_passes_match_the_cpu_twin() {
    let cases: Vec<(&str, Vec<(&str, ParamValue)>)> = vec![
        (
            "direct light",
            vec![("scattering", ParamValue::Bool(false))],
        ),
        ("scattering", vec![]),
        (
            "exact",
            vec![
                ("mode", ParamValue::Enum("exact".into())),
                ("scattering", ParamValue::Bool(false)),
            ],
        ),
        (
            "point light inside, SVR 1:4, coloured",
            vec![
                ("light_type", ParamValue::Enum("point".into())),
                ("light", ParamValue::Vec3([0.1, -0.05, 0.2])),
                ("svr", ParamValue::Enum("1:4".into())),
                ("light_color", ParamValue::Color([1.0, 0.7, 0.4, 1.0])),
            ],
        ),
    ];
    let volume = ball_and_slab();
    let mut errors = Vec::new();
    for (label, edit) in cases {
        for backend in [Backend::Raster, Backend::Compute] {
            let s = settings(48, 48, backend);
            let stack = [tf(), hernell(&edit)];
            let (px, reference) =
                gpu_and_reference(volume.clone(), &stack, TargetFormat::Rgba32Float, &s);
            let e = delta_e_rms(&px, &reference, 48, 48);
            eprintln!("{label}, {backend:?}: ΔE*uv RMS {e:.4}");
            errors.push((label, backend, e));
        }
    }
    // the raster backend interpolates sample positions over proxy polygons: on this
    // binary phantom that alone costs (the classification without the light):
    let s = settings(48, 48, Backend::Raster);
    let (px, reference) = gpu_and_reference(volume.clone(), &[tf()], TargetFormat::Rgba32Float, &s);
    let raster_alone = delta_e_rms(&px, &reference, 48, 48);
    eprintln!("classification alone, Raster: ΔE*uv RMS {raster_alone:.4}");
    for (label, backend, e) in errors {
        match backend {
            // the light passes are the twin's, bit for bit but for f32 rounding
            Backend::Compute => assert!(e < 0.05, "{label} {backend:?}: {e}"),
            // raster: the light adds (almost) nothing to the backend's own difference
            Backend::Raster => assert!(e < raster_alone + 0.1, "{label} {backend:?}: {e}"),
        }
    }
}

/// A ball (x ≈ 6) and a slab (x ≈ 39) with an empty 16-voxel gap of blocks between
/// them (48×24×24): flat blocking skips the gap's blocks and advances eq 7's rays
/// over them.
fn ball_gap_slab() -> Arc<Volume> {
    synthetic([48, 24, 24], |x, y, z| {
        let c = [
            x as f32 + 0.5 - 6.0,
            y as f32 + 0.5 - 9.0,
            z as f32 + 0.5 - 9.0,
        ];
        let r = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        let ball = ((4.5 - r) / 3.0).clamp(0.0, 1.0);
        let xc = x as f32 + 0.5;
        let slab = ((2.5 - (xc - 39.0).abs()) / 3.0 + 0.5).clamp(0.0, 1.0);
        ball.max(slab)
    })
}

/// Flat blocking on the GPU is its twin's: the block levels, the cells, the skipped
/// blocks and the advanced rays (compute, like the other light cases: below 0.05
/// ΔE*uv RMS; measured 0.0000), and it stays close to the unblocked light (measured
/// 0.99).
#[test]
fn flat_blocking_matches_its_twin() {
    let volume = ball_gap_slab();
    let s = settings(48, 48, Backend::Compute);
    let edit = |blocking: bool| {
        let mut e = vec![
            ("light", ParamValue::Vec3([1.0, 0.25, 0.1])),
            ("scattering", ParamValue::Bool(false)),
            ("bias", ParamValue::Float(0.0)),
        ];
        if blocking {
            e.push(("blocking", ParamValue::Enum("16³".into())));
            e.push(("tolerance", ParamValue::Float(0.05)));
        }
        e
    };
    let mut images = Vec::new();
    for blocking in [true, false] {
        let stack = [tf(), hernell(&edit(blocking))];
        let (px, reference) =
            gpu_and_reference(volume.clone(), &stack, TargetFormat::Rgba32Float, &s);
        let e = delta_e_rms(&px, &reference, 48, 48);
        eprintln!("blocking {blocking}: GPU vs twin ΔE*uv RMS {e:.4}");
        assert!(e < 0.05, "blocking {blocking}: {e}");
        images.push(px);
    }
    let e = against(&images[0], &images[1], 48, 48).rms_delta_e;
    eprintln!("blocked vs unblocked: ΔE*uv RMS {e:.3}");
    assert!(e > 0.0 && e < 5.0, "{e}");
    // the blocks: the gap's four are empty
    let stack = [tf(), hernell(&edit(true))];
    let blocks = vwb_render::reference::with_stack_classify(&volume, &stack, |c| {
        vwb_plugins::shade_hernell::blocks_for(&volume, &stack[1].params, 0.05, c)
    })
    .unwrap();
    eprintln!("blocks {:?}: {:?}", blocks.dims, blocks.levels);
    assert_eq!(blocks.dims, [3, 2, 2]);
    // the gap's four blocks (x 16…31) and the three around the ball that it does not
    // reach are empty
    assert_eq!(blocks.histogram()[5], 7, "{:?}", blocks.levels);
    assert!([1, 4, 7, 10].iter().all(|&i| blocks.levels[i] == -1));
    assert!(blocks.reduction() > 1.5, "{}", blocks.reduction());
    // the plugin's statistics (experiment reports) are the GPU's own levels: the
    // (block) pass's target read back, the twin's levels block for block
    let mut r = Renderer::new(gpu(), volume.clone()).unwrap();
    r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
    r.render(&s).unwrap();
    let (dims, gpu_levels) = r.read_pass_target(stack[1].uid, "blocks").unwrap();
    assert_eq!(dims, [3, 2, 2]);
    let gpu_levels: Vec<i32> = gpu_levels.iter().map(|l| l.round() as i32).collect();
    assert_eq!(gpu_levels, blocks.levels);
    assert!(r.read_pass_target(stack[1].uid, "no such target").is_none());
    let stats = r.statistics_of(&stack[1]);
    let stat = |n: &str| stats.iter().find(|x| x.name == n).unwrap().value;
    assert_eq!(stat("data_reduction"), blocks.reduction());
    assert_eq!(stat("empty_blocks"), 7.0 / 12.0);
    for (l, n) in blocks.histogram()[..5].iter().enumerate() {
        assert_eq!(stat(&format!("blocks_level_{l}")), *n as f64, "level {l}");
    }
    assert_eq!(
        stats.iter().map(|x| x.name).collect::<Vec<_>>(),
        stack[1].configured().statistic_names(&stack[1].params)
    );
}

/// With flat blocking the (block) pass runs first, when the classification or the
/// tolerance change, not when the light does.
#[test]
fn the_block_pass_reruns_only_for_the_classification_and_tolerance() {
    let mut r = Renderer::new(gpu(), ball_gap_slab()).unwrap();
    let s = settings(32, 32, Backend::Compute);
    let mut stack = vec![
        tf(),
        hernell(&[
            ("scattering", ParamValue::Bool(false)),
            ("blocking", ParamValue::Enum("16³".into())),
        ]),
    ];
    let mut frame = |stack: &[PluginInstance]| {
        r.update_stack(stack, TargetFormat::Rgba16Float).unwrap();
        r.render(&s).unwrap().volume_passes_run
    };
    let first = frame(&stack);
    assert_eq!(
        first,
        [
            "shade.hernell/blocks",
            "shade.hernell/alpha_lp",
            "shade.hernell/alpha_g",
            "shade.hernell/light_volume"
        ]
    );
    stack[1]
        .params
        .set("light", ParamValue::Vec3([0.0, 1.0, 0.0]));
    assert_eq!(frame(&stack).len(), 3);
    stack[1].params.set("tolerance", ParamValue::Float(0.1));
    assert_eq!(frame(&stack).len(), 4);
    assert!(frame(&stack).is_empty());
}

#[test]
fn light_passes_rerun_only_when_their_inputs_change() {
    let mut r = Renderer::new(gpu(), ball_and_slab()).unwrap();
    let mut s = settings(32, 32, Backend::Compute);
    let mut stack = vec![tf(), hernell(&[])];
    let frame = |r: &mut Renderer, stack: &[PluginInstance], s: &vwb_render::FrameSettings| {
        r.update_stack(stack, TargetFormat::Rgba16Float).unwrap();
        r.render(s).unwrap().volume_passes_run
    };
    // (A) local and global opacity, (B) the light's direction + 4 tetrahedron directions
    let first = frame(&mut r, &stack, &s);
    assert_eq!(first.len(), 7, "{first:?}");
    assert_eq!(first[0], "shade.hernell/alpha_lp");
    assert_eq!(first[1], "shade.hernell/alpha_g");
    assert!(first[2..].iter().all(|l| l == "shade.hernell/light_volume"));
    // (C): camera moves and the final pass's own parameters rerun nothing
    s.camera.yaw_deg += 40.0;
    assert!(frame(&mut r, &stack, &s).is_empty());
    stack[1].params.set("bias", ParamValue::Float(0.3));
    assert!(frame(&mut r, &stack, &s).is_empty());
    // (B) only: the scattering radius
    stack[1].params.set("radius", ParamValue::Float(2.0));
    assert_eq!(frame(&mut r, &stack, &s).len(), 5);
    // (A) and (B): the light, the transfer function
    stack[1]
        .params
        .set("light", ParamValue::Vec3([0.0, 1.0, 0.0]));
    assert_eq!(frame(&mut r, &stack, &s).len(), 7);
    stack[0].params.set(
        "tf",
        ParamValue::Tf(vwb_render::tf::TfCurve::ramp(
            0.2,
            0.7,
            [0.9, 0.8, 0.7, 0.5],
        )),
    );
    assert_eq!(frame(&mut r, &stack, &s).len(), 7);
    assert!(frame(&mut r, &stack, &s).is_empty());
    // exact integration follows the whole path to the light: the segment length is
    // not its input, and editing it reruns nothing
    stack[1]
        .params
        .set("mode", ParamValue::Enum("exact".into()));
    assert_eq!(frame(&mut r, &stack, &s).len(), 7);
    stack[1].params.set("segment", ParamValue::Int(3));
    assert!(frame(&mut r, &stack, &s).is_empty());
    stack[1]
        .params
        .set("mode", ParamValue::Enum("piecewise".into()));
    assert_eq!(frame(&mut r, &stack, &s).len(), 7);
    stack[1].params.set("segment", ParamValue::Int(5));
    assert_eq!(frame(&mut r, &stack, &s).len(), 7);
}

#[test]
fn in_scattering_refines_progressively_over_frames() {
    let s = settings(32, 32, Backend::Compute);
    let stack = vec![tf(), hernell(&[])];
    let mut all = Renderer::new(gpu(), ball_and_slab()).unwrap();
    let finished = render(&mut all, &stack, TargetFormat::Rgba32Float, &s);
    assert!(!all.refining());

    let mut r = Renderer::new(gpu(), ball_and_slab()).unwrap();
    r.set_refinement_budget(Some(1));
    let first = render(&mut r, &stack, TargetFormat::Rgba32Float, &s);
    let mut frames = 1;
    let mut last = first.clone();
    while r.refining() {
        last = render(&mut r, &stack, TargetFormat::Rgba32Float, &s);
        frames += 1;
        assert!(frames < 20);
    }
    // (A) with the light's direction, then one direction per frame
    assert_eq!(frames, 5);
    assert_eq!(last, finished);
    let e = against(&first, &finished, 32, 32).rms_delta_e;
    eprintln!("first frame (light direction only) vs refined: ΔE*uv RMS {e:.3}");
    assert!(e > 0.05, "{e}");
}

/// The block in front of the wall under an oblique light (its shadow falls on the
/// visible wall): clipped away by a plane on a voxel boundary, it must cast no light
/// shadow, as if it had been removed (the unclipped image differs by the block and its
/// shadow).
#[test]
fn clipped_matter_casts_no_light_shadow() {
    let (tf, _) = dos_stack();
    let mut h = instance("shade.hernell");
    h.params.set("light", ParamValue::Vec3([0.5, 0.0, -1.0]));
    h.params.set("scattering", ParamValue::Bool(false));
    h.params.set("bias", ParamValue::Float(0.0));
    let (e_clipped, e_unclipped) = block_removed_consistency(tf, h);
    eprintln!("clipped vs cropped ΔE*uv RMS {e_clipped:.4}; unclipped {e_unclipped:.4}");
    assert!(e_clipped < 0.15, "{e_clipped}");
    assert!(e_unclipped > 2.0, "{e_unclipped}");
}

/// Two premultiplied frames over black compared (ΔE*uv).
fn against(a: &[[f32; 4]], b: &[[f32; 4]], w: u32, h: u32) -> vwb_render::metrics::Metrics {
    use vwb_render::metrics::{RgbImageF, compare};
    compare(
        &RgbImageF::from_rgba_f32_premultiplied_over(a, w, h, [0.0; 3]),
        &RgbImageF::from_rgba_f32_premultiplied_over(b, w, h, [0.0; 3]),
    )
}

fn sweep_shadows(light: [f32; 3]) -> PluginInstance {
    let mut i = instance("shade.sweep_shadows");
    i.params.set("light", ParamValue::Vec3(light));
    i.params.set("ambient", ParamValue::Float(0.0));
    i
}

/// `shade.sweep_shadows`, the first sweep pass (a slicing direction other than the
/// view): on both backends it matches its twin and darkens the image; its
/// transmittance agrees with shade.hernell's exact per-voxel integration to the same
/// light (two independent computations of one quantity); the sweep reruns for the
/// light, whatever axis it sweeps along, and for nothing else.
#[test]
fn a_light_sweep_matches_its_twin_and_the_exact_light() {
    use crate::reference::gpu_delta_e_rms;
    let volume = ball_and_slab();
    // what the raster backend's interpolated positions cost on this phantom without
    // any light (gpu_light_passes_match_the_cpu_twin)
    let target = TargetFormat::Rgba32Float;
    let (px, reference) = gpu_and_reference(
        volume.clone(),
        &[tf()],
        target,
        &settings(48, 48, Backend::Raster),
    );
    let raster_alone = delta_e_rms(&px, &reference, 48, 48);
    for light in [[0.3, 0.4, -1.0], [-1.0, 0.2, 0.1]] {
        let stack = vec![tf(), sweep_shadows(light)];
        for backend in [Backend::Compute, Backend::Raster] {
            let s = settings(48, 48, backend);
            let (px, reference) = gpu_and_reference(volume.clone(), &stack, target, &s);
            let rms = delta_e_rms(&px, &reference, 48, 48);
            let what = format!("light {light:?} {}", backend.name());
            eprintln!(
                "sweep shadows, {what}: ΔE*uv RMS {rms:.4} against the twin (raster alone {raster_alone:.4})"
            );
            let bound = match backend {
                Backend::Compute => 0.05,
                Backend::Raster => raster_alone + 0.2,
            };
            assert!(rms < bound, "{what}: {rms}");
            let mut r = Renderer::new(gpu(), volume.clone()).unwrap();
            let unlit = render(&mut r, &stack[..1], target, &s);
            let dark = gpu_delta_e_rms(&px, &unlit, 48, 48);
            assert!(dark > 2.0, "{what}: the shadows darken the image ({dark})");
            let exact = render(
                &mut r,
                &[
                    tf(),
                    hernell(&[
                        ("light", ParamValue::Vec3(light)),
                        ("mode", ParamValue::Enum("exact".into())),
                        ("scattering", ParamValue::Bool(false)),
                        ("bias", ParamValue::Float(0.0)),
                        ("svr", ParamValue::Enum("1:1".into())),
                    ]),
                ],
                target,
                &s,
            );
            let off = gpu_delta_e_rms(&px, &exact, 48, 48);
            eprintln!(
                "sweep shadows, {what}: ΔE*uv RMS {off:.3} from Hernell's exact light ({dark:.2} from none)"
            );
            assert!(off < 0.25 * dark, "{what}: {off} against {dark}");
        }
    }

    let mut r = Renderer::new(gpu(), volume).unwrap();
    let mut s = settings(32, 32, Backend::Compute);
    let mut stack = vec![tf(), sweep_shadows([0.3, 0.4, -1.0])];
    let frame = |r: &mut Renderer, stack: &[PluginInstance], s: &vwb_render::FrameSettings| {
        r.update_stack(stack, TargetFormat::Rgba16Float).unwrap();
        r.render(s).unwrap().volume_passes_run
    };
    assert_eq!(
        frame(&mut r, &stack, &s),
        ["shade.sweep_shadows/transmittance"]
    );
    s.camera.yaw_deg += 40.0;
    assert!(frame(&mut r, &stack, &s).is_empty(), "a camera move");
    stack[1].params.set("ambient", ParamValue::Float(0.3));
    assert!(
        frame(&mut r, &stack, &s).is_empty(),
        "the shade hook's own parameter"
    );
    stack[1]
        .params
        .set("light", ParamValue::Vec3([-1.0, 0.2, 0.1]));
    assert_eq!(frame(&mut r, &stack, &s).len(), 1, "the light, along x now");
    stack[0].params.set("opacity", ParamValue::Float(2.0));
    assert_eq!(frame(&mut r, &stack, &s).len(), 1, "the classification");
    assert!(frame(&mut r, &stack, &s).is_empty());
}
