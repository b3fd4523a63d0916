//! Directional occlusion shading (Schott et al. 2009) on the GPU: both backends agree
//! with the CPU twin and with each other, θ = 0 is the head-on transmittance
//! (`test.slice_shadow`), contact shadows darken the CT head and the nuclei, and the
//! occlusion buffer's resolution and precision are independent of the eye buffer.

use vwb_render::params::ParamValue;
use vwb_render::preset::Document;
use vwb_render::{Backend, FrameSettings, PluginInstance, Renderer, TargetFormat};

use crate::common::*;
use crate::reference::{delta_e_rms, gpu_and_reference, gpu_delta_e_rms};

/// An opaque-ish block floating in front of a wall (z grows away from an axis view
/// along +z), and a TF that shows both with colour `rgba`.
fn block_and_wall(
    n: u32,
    block: [std::ops::Range<u32>; 3],
    wall: std::ops::Range<u32>,
    rgba: [f32; 4],
) -> (std::sync::Arc<vwb_render::Volume>, PluginInstance) {
    let vol = synthetic([n; 3], move |x, y, z| {
        let in_block = block[0].contains(&x) && block[1].contains(&y) && block[2].contains(&z);
        if in_block || wall.contains(&z) {
            1.0
        } else {
            0.0
        }
    });
    let mut tf = instance("classify.tf1d");
    tf.params.set(
        "tf",
        ParamValue::Tf(vwb_render::tf::TfCurve::ramp(0.4, 0.6, rgba)),
    );
    (vol, tf)
}

fn dos(theta: f32) -> PluginInstance {
    let mut i = instance("shade.dos");
    i.params.set("theta_deg", ParamValue::Float(theta));
    i
}

#[test]
fn both_backends_match_the_twin_and_each_other() {
    for (kernel, distance, format, scale, extinction) in [
        ("grid", "slice", "fp16", "1", None),
        ("poisson", "exact", "fp32", "0.5", None),
        ("grid", "exact", "fp32", "1", Some([0.4, 1.0, 2.5])),
        ("poisson", "slice", "fp16", "0.5", Some([2.0, 1.0, 0.3])),
    ] {
        let mut d = dos(70.0);
        set_kernel(&mut d, kernel, distance, scale, extinction);
        d.params
            .set("buffer_format", ParamValue::Enum(format.into()));
        let stack = vec![instance("classify.tf1d"), d];
        backends_match_the_twin_and_each_other(
            &stack,
            &format!("dos {kernel} {distance} {format} ×{scale} κ {extinction:?}"),
        );
    }
}

/// Sets `d`'s (shade.dos) occlusion buffer scale (`buffer_scale`: "1", "0.5" or
/// "0.25").
fn set_buffer_scale(d: &mut PluginInstance, scale: &str) {
    d.params.set("buffer_scale", ParamValue::Enum(scale.into()));
}

/// Sets `d`'s (shade.dos) kernel, distance, buffer scale and, where `extinction` is
/// given, chromatic extinction with that κ.
fn set_kernel(
    d: &mut PluginInstance,
    kernel: &str,
    distance: &str,
    scale: &str,
    extinction: Option<[f32; 3]>,
) {
    if let Some(k) = extinction {
        d.params
            .set("extinction", ParamValue::Enum("chromatic".into()));
        d.params.set("extinction_rgb", ParamValue::Vec3(k));
    }
    d.params.set("kernel", ParamValue::Enum(kernel.into()));
    d.params.set("distance", ParamValue::Enum(distance.into()));
    set_buffer_scale(d, scale);
}

/// The demo under `stack` at 48² on both backends: each within 0.5 ΔE*uv RMS of the
/// CPU twin, and the two within 0.01 RGB RMS of each other.
fn backends_match_the_twin_and_each_other(stack: &[PluginInstance], what: &str) {
    backends_match_the_twin_and_each_other_in(stack, what, &settings(48, 48, Backend::Compute));
}

/// [`backends_match_the_twin_and_each_other`] under the frame settings `base` (its
/// backend replaced by each).
fn backends_match_the_twin_and_each_other_in(
    stack: &[PluginInstance],
    what: &str,
    base: &FrameSettings,
) {
    let (w, h) = (base.width, base.height);
    let mut images = Vec::new();
    for backend in [Backend::Compute, Backend::Raster] {
        let s = FrameSettings { backend, ..*base };
        let (px, reference) = gpu_and_reference(demo(), stack, TargetFormat::Rgba32Float, &s);
        let rms = delta_e_rms(&px, &reference, w, h);
        eprintln!("{what} {backend:?}: ΔE RMS vs twin {rms:.4}");
        assert!(rms < 0.5, "{what} {backend:?}: {rms}");
        images.push(px);
    }
    let (rms, _) = diff(&rgb(&images[0]), &rgb(&images[1]));
    eprintln!("{what}: compute vs raster RGB RMS {rms:.4}");
    assert!(rms < 0.01, "{what}: {rms}");
}

/// The compute backend runs a slice and the occlusion update in one dispatch, each
/// sample evaluated once, where the occlusion buffer has the eye buffer's resolution;
/// the image is the two-dispatch one. At half resolution, and in the raster backend,
/// the update stays a dispatch of its own.
#[test]
fn one_dispatch_per_slice_keeps_the_image() {
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    for (scale, backend, fusable) in [
        ("1", Backend::Compute, true),
        ("0.5", Backend::Compute, false),
        ("1", Backend::Raster, false),
    ] {
        let mut d = dos(60.0);
        set_buffer_scale(&mut d, scale);
        let stack = [instance("classify.tf1d"), d];
        let mut s = settings(48, 48, backend);
        s.early_termination = Some(0.9);
        let mut images = Vec::new();
        for fused in [true, false] {
            r.set_fused_slices(fused);
            r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
            let stats = r.render(&s).unwrap();
            assert!(stats.per_slice_mode && stats.slices > 0);
            assert_eq!(stats.fused_slices, fused && fusable, "×{scale} {backend:?}");
            images.push(r.read_pixels().unwrap().2);
        }
        let (rms, max) = diff(&rgb(&images[0]), &rgb(&images[1]));
        eprintln!("×{scale} {backend:?}: fused vs two dispatches RGB RMS {rms:.2e}, max {max:.2e}");
        assert!(max < 1e-5 && mean_luma(&rgb(&images[0])) > 0.01, "{max}");
    }
}

/// With `clear_tiles` on, the occlusion update skips its taps where the sample is empty
/// and every tap would read the clear buffer (`SliceStateDecl::track_clear`): the image
/// is the one with every tile marked (every update reads) and the default's without
/// the check and the marks, bit for bit, on both backends, for both kernels and
/// distances, chromatic extinction, a half-resolution buffer and a directional light.
/// After a frame every tile that holds a texel off the clear value is marked; behind a
/// small block only the tiles its shadow reaches are.
#[test]
fn clear_tiles_skip_taps_and_keep_the_image() {
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    for (kernel, distance, scale, extinction, light) in [
        ("grid", "slice", "1", None, None),
        ("poisson", "exact", "0.5", None, None),
        ("grid", "exact", "1", Some([0.4, 1.0, 2.5]), None),
        ("grid", "slice", "1", None, Some([0.6, 0.4, 1.0])),
        ("poisson", "slice", "0.5", None, Some([0.3, -0.5, -1.0])),
    ] {
        let mut d = match light {
            Some(l) => dos_lit(60.0, l),
            None => dos(70.0),
        };
        set_kernel(&mut d, kernel, distance, scale, extinction);
        let what = format!("{kernel} {distance} ×{scale} κ {extinction:?} light {light:?}");
        for backend in [Backend::Compute, Backend::Raster] {
            let stack = [instance("classify.tf1d"), d.clone()];
            clear_tiles_keep_the_image(&mut r, &stack, &settings(64, 64, backend), &what);
        }
    }
    // a block at the back of an empty box, seen head-on: its shadow marks the middle
    let (vol, tf) = block_and_wall(32, [12..20, 12..20, 24..30], 0..0, [0.9, 0.9, 0.9, 0.9]);
    let mut r = Renderer::new(gpu(), vol).unwrap();
    let stack = [tf, dos(30.0)];
    let s = ortho_axis(64, 64, Backend::Compute);
    let (marked, tiles) = clear_tiles_keep_the_image(&mut r, &stack, &s, "block");
    assert!(
        marked > 0 && 2 * marked < tiles,
        "block: {marked} of {tiles} tiles marked"
    );
}

/// Renders `stack` under `s` with the clear tiles tracked, with every tile marked, and
/// without `clear_tiles` (the default: no marks kept): the same pixels, and with
/// tracking every texel off the clear value in a marked tile. The tiles marked and in
/// all, with tracking.
fn clear_tiles_keep_the_image(
    r: &mut Renderer,
    stack: &[PluginInstance],
    s: &FrameSettings,
    what: &str,
) -> (usize, usize) {
    let mut stack = stack.to_vec();
    let dos = stack.len() - 1;
    stack[dos]
        .params
        .set("buffer_format", ParamValue::Enum("fp32".into()));
    let default = stack.clone();
    stack[dos].params.set("clear_tiles", ParamValue::Bool(true));
    let tile = vwb_render::composer::STATE_TILE as usize;
    let mut images = Vec::new();
    let mut counts = (0, 0);
    for tracking in [true, false] {
        r.set_state_tracking(tracking);
        r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
        let stats = r.render(s).unwrap();
        assert!(stats.per_slice_mode && stats.slices > 0, "{what}");
        images.push(r.read_pixels().unwrap().2);
        let st = r
            .read_state(stack[dos].uid)
            .expect("an fp32 state reads back");
        let tiles = st.tiles.expect("shade.dos tracks its clear tiles");
        let tiles_x = (st.size[0] as usize).div_ceil(tile);
        assert_eq!(
            tiles.len(),
            tiles_x * (st.size[1] as usize).div_ceil(tile),
            "{what}"
        );
        let marked = tiles.iter().filter(|&&m| m != 0).count();
        if !tracking {
            assert_eq!(
                marked,
                tiles.len(),
                "{what}: without tracking every tile is marked"
            );
            continue;
        }
        // every texel off the clear value (V = 1 in each channel) lies in a marked tile
        let n = st.components;
        for tex in &st.textures {
            for (i, texel) in tex.chunks_exact(n).enumerate() {
                let (x, y) = (i % st.size[0] as usize, i / st.size[0] as usize);
                assert!(
                    texel.iter().all(|&v| v == 1.0) || tiles[(y / tile) * tiles_x + x / tile] != 0,
                    "{what} {:?}: texel ({x}, {y}) = {texel:?} in an unmarked tile",
                    s.backend
                );
            }
        }
        eprintln!(
            "{what} {:?}: {marked} of {} tiles marked",
            s.backend,
            tiles.len()
        );
        counts = (marked, tiles.len());
    }
    r.set_state_tracking(true);
    r.update_stack(&default, TargetFormat::Rgba32Float).unwrap();
    r.render(s).unwrap();
    images.push(r.read_pixels().unwrap().2);
    let st = r
        .read_state(default[dos].uid)
        .expect("an fp32 state reads back");
    assert!(st.tiles.is_none(), "{what}: no marks without clear_tiles");
    assert!(
        images[0] == images[1],
        "{what} {:?}: the image with clear tiles skipped differs",
        s.backend
    );
    assert!(
        images[2] == images[1],
        "{what} {:?}: the image without clear_tiles differs",
        s.backend
    );
    assert!(mean_luma(&rgb(&images[0])) > 0.001, "{what}");
    counts
}

/// θ = 0: every tap reads its own texel, so V is the transmittance towards the
/// viewer, what `test.slice_shadow` at strength 1 computes. Orthographic, so that the
/// slice distance d of Algorithm 3 is also the ray's step (in perspective the rays off
/// the centre step d/cos φ and DOS attenuates over d).
#[test]
fn zero_aperture_is_the_head_on_transmittance() {
    let mut s = ortho_axis(48, 48, Backend::Compute);
    s.camera.yaw_deg += 25.0;
    s.camera.pitch_deg += 15.0;
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let mut d = dos(0.0);
    d.params
        .set("buffer_format", ParamValue::Enum("fp32".into()));
    let a = render(
        &mut r,
        &[instance("classify.tf1d"), d],
        TargetFormat::Rgba32Float,
        &s,
    );
    let b = render(
        &mut r,
        &[instance("classify.tf1d"), instance("test.slice_shadow")],
        TargetFormat::Rgba32Float,
        &s,
    );
    let rms = gpu_delta_e_rms(&a, &b, 48, 48);
    eprintln!("θ = 0 vs head-on transmittance: ΔE RMS {rms:.5}");
    assert!(rms < 0.01, "{rms}");
}

/// With DOS the CT head and the nuclei get darker where matter lies in front (mean
/// luminance falls for every aperture).
#[test]
fn occlusion_darkens_the_ct_head_and_the_nuclei() {
    for preset in ["presets/ct_dos.ron", "presets/nuclei_dos.ron"] {
        let (doc, volume) = preset_scene(preset);
        let s = FrameSettings {
            width: 64,
            height: 64,
            ..doc.frame_settings()
        };
        let mut r = Renderer::new(gpu(), volume).unwrap();
        let mut luma = Vec::new();
        for theta in [None, Some(0.0), Some(45.0), Some(85.0)] {
            let mut stack = doc.stack.clone();
            let i = stack
                .iter()
                .position(|i| i.plugin.id() == "shade.dos")
                .unwrap();
            match theta {
                None => stack[i].enabled = false,
                Some(t) => stack[i].params.set("theta_deg", ParamValue::Float(t)),
            }
            luma.push(mean_luma(&rgb(&render(
                &mut r,
                &stack,
                doc.render.target,
                &s,
            ))));
        }
        eprintln!("{preset}: mean luminance off / θ 0 / 45 / 85: {luma:?}");
        assert!(luma[1..].iter().all(|l| *l < 0.97 * luma[0]), "{luma:?}");
    }
}

/// A contact shadow: an opaque block floating in front of an opaque wall (seen head
/// on) darkens a ring of the wall around its silhouette once the cone opens; at θ = 0
/// only the silhouette itself (hidden by the block) would be shadowed.
#[test]
fn a_block_casts_a_soft_shadow_on_the_wall_behind_it() {
    let (vol, tf) = block_and_wall(32, [12..20, 12..20, 6..9], 22..25, [0.9, 0.9, 0.9, 0.9]);
    let s = ortho_axis(64, 64, Backend::Compute);
    let mut r = Renderer::new(gpu(), vol).unwrap();
    let ring = |img: &[[f64; 3]]| {
        let (mut sum, mut n) = (0.0, 0.0);
        for y in 0..64 {
            for x in 0..64 {
                let d = (x as f64 - 31.5).abs().max((y as f64 - 31.5).abs());
                if (8.5..12.0).contains(&d) {
                    sum += img[y * 64 + x].iter().sum::<f64>() / 3.0;
                    n += 1.0;
                }
            }
        }
        sum / n
    };
    let mut lum = Vec::new();
    for theta in [0.0, 30.0, 60.0] {
        let img = rgb(&render(
            &mut r,
            &[tf.clone(), dos(theta)],
            TargetFormat::Rgba32Float,
            &s,
        ));
        lum.push(ring(&img));
    }
    eprintln!("wall ring luminance at θ 0 / 30 / 60: {lum:?}");
    assert!(lum[1] < 0.95 * lum[0] && lum[2] < lum[1], "{lum:?}");
}

/// Chromatic extinction (σt·κ per channel on the occlusion cone): κ = (1, 1, 1) is
/// the achromatic image; κ_r < 1 < κ_b lets red reach deeper, so the contact shadow
/// on the wall turns warm (red brighter, blue darker than achromatic, green as it
/// was), while the eye ray keeps its achromatic σt: the opacity image is unchanged.
#[test]
fn chromatic_extinction_colours_the_shadow() {
    let (vol, tf) = block_and_wall(32, [12..20, 12..20, 6..9], 22..25, [0.9, 0.9, 0.9, 0.9]);
    let s = ortho_axis(64, 64, Backend::Compute);
    let mut r = Renderer::new(gpu(), vol).unwrap();
    let mut shot = |extinction: Option<[f32; 3]>| {
        let mut d = dos(60.0);
        d.params
            .set("buffer_format", ParamValue::Enum("fp32".into()));
        if let Some(k) = extinction {
            d.params
                .set("extinction", ParamValue::Enum("chromatic".into()));
            d.params.set("extinction_rgb", ParamValue::Vec3(k));
        }
        render(&mut r, &[tf.clone(), d], TargetFormat::Rgba32Float, &s)
    };
    let grey = shot(None);
    let white = shot(Some([1.0, 1.0, 1.0]));
    let warm = shot(Some([0.25, 1.0, 3.0]));
    let (rms, max) = diff(&rgb(&grey), &rgb(&white));
    eprintln!("chromatic κ = 1 vs achromatic: RGB RMS {rms:.2e}, max {max:.2e}");
    assert!(max < 1e-5, "{rms} {max}");
    let alpha = |img: &[[f32; 4]]| img.iter().map(|p| p[3]).collect::<Vec<_>>();
    assert_eq!(
        alpha(&grey),
        alpha(&warm),
        "the eye ray's opacity is achromatic"
    );
    // mean RGB over the ring of wall around the block
    let ring = |img: &[[f64; 3]]| {
        let (mut sum, mut n) = ([0.0; 3], 0.0);
        for y in 0..64 {
            for x in 0..64 {
                let d = (x as f64 - 31.5).abs().max((y as f64 - 31.5).abs());
                if (8.5..12.0).contains(&d) {
                    for c in 0..3 {
                        sum[c] += img[y * 64 + x][c];
                    }
                    n += 1.0;
                }
            }
        }
        sum.map(|v| v / n)
    };
    let (g, w) = (ring(&rgb(&grey)), ring(&rgb(&warm)));
    eprintln!("shadow ring RGB achromatic {g:.4?}, κ (0.25, 1, 3) {w:.4?}");
    assert!(w[0] > 1.05 * g[0] && w[2] < 0.95 * g[2], "{g:?} {w:?}");
    assert!((w[1] - g[1]).abs() < 1e-4, "green keeps κ = 1: {g:?} {w:?}");
}

/// DOS against its Monte-Carlo reference on a small scene. The slice algorithm
/// shades slice k with the visibility of slices < k (the occlusion buffer lags one
/// slice), a first-order bias in the slice distance: the error falls as the slices
/// get finer, at θ = 0 (no kernel) and, more slowly, at θ = 60° (kernel and
/// σt-at-the-tip approximations on top).
#[test]
fn dos_converges_towards_its_monte_carlo_reference() {
    // θ = 0: first order (measured 6.2 / 3.2 / 1.65). θ = 60°: slower (10.4 / 7.8 /
    // 6.5): repeated averaging over per-slice disks of radius d·tan θ spreads the
    // occlusion like a random walk (∝ √(k)·d), narrower than the cone (∝ k·d)
    converges_towards_monte_carlo("viewer", dos, [(0.6, 2.0), (0.9, 7.5)]);
}

/// With a directional light the Monte-Carlo reference integrates the cone around the
/// direction towards the light, and the half-angle slices converge towards it as the
/// viewer's do towards theirs: first order at θ = 0, more slowly at θ = 60°.
#[test]
fn a_directional_light_converges_towards_its_monte_carlo_reference() {
    // measured: θ = 0: 6.4 / 3.4 / 2.0 (the viewer's light: 6.2 / 3.2 / 1.65; the
    // light-space buffer is resampled once more per slice); θ = 60°: 10.6 / 8.1 / 7.0
    // (the viewer's 10.4 / 7.8 / 6.5)
    converges_towards_monte_carlo(
        "directional light",
        |theta| dos_lit(theta, [-0.7, 0.4, 1.0]),
        [(0.65, 2.5), (0.9, 7.5)],
    );
}

/// DOS (`dos_at(θ)`, 8 × 8 grid, fp32 buffer) on the block-and-wall phantom at 32²
/// against its Monte-Carlo reference at slice spacings 1, ½ and ¼, at θ = 0 and 60°:
/// each halving cuts the error by `bounds[i].0` at least, and the finest error is under
/// `bounds[i].1`.
fn converges_towards_monte_carlo(
    what: &str,
    dos_at: impl Fn(f32) -> PluginInstance,
    bounds: [(f64, f64); 2],
) {
    use vwb_plugins::shade_dos::mc::{McOptions, render_mc};
    let (vol, tf) = block_and_wall(24, [8..16, 8..16, 4..8], 14..18, [0.9, 0.8, 0.7, 0.3]);
    let mut s = ortho_axis(32, 32, Backend::Compute);
    s.camera.yaw_deg += 10.0;
    s.camera.pitch_deg += 8.0;
    let mut r = Renderer::new(gpu(), vol.clone()).unwrap();
    for (theta, (ratio, bound)) in [0.0, 60.0].into_iter().zip(bounds) {
        let mut d = dos_at(theta);
        d.params
            .set("buffer_format", ParamValue::Enum("fp32".into()));
        d.params.set("grid", ParamValue::Int(8));
        let stack = vec![tf.clone(), d];
        let opts = McOptions {
            directions: 64,
            eye_step: 0.25,
            cone_step: 0.5,
            ..Default::default()
        };
        let mc = render_mc(&vol, &stack, &s, &opts, None).unwrap();
        let mut errors = Vec::new();
        for spacing in [1.0, 0.5, 0.25] {
            s.slice_spacing = spacing;
            let px = render(&mut r, &stack, TargetFormat::Rgba32Float, &s);
            errors.push(delta_e_rms(&px, &mc.pixels, 32, 32));
        }
        eprintln!(
            "{what}, θ {theta}: DOS vs Monte Carlo ΔE RMS at spacing 1 / 0.5 / 0.25: {errors:.3?} (MC std error RMS {:.5})",
            mc.rms_std_error()
        );
        assert!(
            errors[1] < ratio * errors[0] && errors[2] < ratio * errors[1] && errors[2] < bound,
            "{what}, θ {theta}: {errors:?}"
        );
    }
}

/// The window's and `vwb compare`'s converged DOS reference (`MonteCarloReference`,
/// `McOptions::default()`: eye step 0.5, cone step 1 voxel, 32 directions) is cheaper
/// than the one docs/dos.md's experiment files ask for (`reference_options`: eye step
/// 0.25, cone step 0.5, 48 directions). On the demo DOS preset the two agree to well under the slice
/// algorithm's own error (≈ 8 ΔE*uv), so either measures DOS; the figure is in
/// docs/dos.md.
#[test]
fn in_app_monte_carlo_reference_agrees_with_the_study_reference() {
    use vwb_plugins::shade_dos::mc::{McOptions, render_mc};
    let doc = Document::load(&repo().join("presets/demo_dos.ron"), &registry())
        .unwrap()
        .document;
    let s = FrameSettings {
        width: 32,
        height: 32,
        ..doc.frame_settings()
    };
    let cheap = render_mc(&demo(), &doc.stack, &s, &McOptions::default(), None).unwrap();
    let study = McOptions {
        directions: 48,
        eye_step: 0.25,
        cone_step: 0.5,
        ..Default::default()
    };
    let fine = render_mc(&demo(), &doc.stack, &s, &study, None).unwrap();
    let a: Vec<[f32; 4]> = cheap.pixels.iter().map(|p| p.map(|c| c as f32)).collect();
    let rms = delta_e_rms(&a, &fine.pixels, 32, 32);
    eprintln!(
        "in-app Monte Carlo (eye 0.5, cone 1, 32 directions) vs the study's (eye 0.25, cone 0.5, 48): RMS ΔE*uv {rms:.3}"
    );
    assert!(rms > 0.0 && rms < 1.0, "{rms}");
}

/// `shade.dos` with a directional light: half-angle slicing.
fn dos_lit(theta: f32, towards_light: [f32; 3]) -> PluginInstance {
    let mut d = dos(theta);
    d.params
        .set("light", ParamValue::Enum("directional".into()));
    d.params
        .set("light_vector", ParamValue::Vec3(towards_light));
    d
}

/// Half-angle slicing (a directional light): both backends agree with the CPU twin
/// and with each other, for a light on the viewer's side (front to back), a light
/// behind the volume (the eye meets the slices back to front, "over"), and a light
/// given in world space, with both kernels and buffer scales.
#[test]
fn a_directional_light_slices_half_angle_and_both_backends_match_the_twin() {
    for (towards, space, kernel, scale) in [
        ([0.6, 0.4, 1.0], "view", "grid", "1"),
        ([0.3, -0.5, -1.0], "view", "poisson", "0.5"),
        ([1.0, 0.2, 0.1], "world", "grid", "0.5"),
    ] {
        let mut d = dos_lit(60.0, towards);
        d.params.set("light_space", ParamValue::Enum(space.into()));
        d.params.set("kernel", ParamValue::Enum(kernel.into()));
        set_buffer_scale(&mut d, scale);
        let stack = vec![instance("classify.tf1d"), d];
        backends_match_the_twin_and_each_other(
            &stack,
            &format!("dos light {towards:?} ({space}) {kernel} ×{scale}"),
        );
    }
}

/// A directional light along the view of an orthographic camera slices the volume as
/// the viewer's light does (the half-angle axis is the view direction); only the
/// occlusion buffer differs, laid over the box's shadow instead of the screen, so the
/// images agree to within the buffer's resampling.
#[test]
fn a_headlight_gives_the_viewers_image() {
    let s = ortho_axis(64, 64, Backend::Compute);
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let tf = instance("classify.tf1d");
    let viewer = render(
        &mut r,
        &[tf.clone(), dos(60.0)],
        TargetFormat::Rgba32Float,
        &s,
    );
    let lit = render(
        &mut r,
        &[tf, dos_lit(60.0, [0.0, 0.0, 1.0])],
        TargetFormat::Rgba32Float,
        &s,
    );
    let viewer: Vec<[f64; 4]> = viewer.iter().map(|p| p.map(f64::from)).collect();
    let rms = delta_e_rms(&lit, &viewer, 64, 64);
    eprintln!("headlight vs viewer: ΔE RMS {rms:.4}");
    assert!(rms < 1.0, "{rms}");
    // and the light moved off the view changes the image
    let mut r2 = Renderer::new(gpu(), demo()).unwrap();
    let side = render(
        &mut r2,
        &[instance("classify.tf1d"), dos_lit(60.0, [1.0, 0.0, 1.0])],
        TargetFormat::Rgba32Float,
        &s,
    );
    let moved = delta_e_rms(&side, &viewer, 64, 64);
    eprintln!("light from the right vs viewer: ΔE RMS {moved:.4}");
    assert!(moved > 4.0 * rms.max(0.1), "{moved} vs {rms}");
}

/// A block in front of a wall, lit from the left: its shadow falls on the wall to the
/// right of it, and lit from the right, to the left; the viewer's light is symmetric.
#[test]
fn a_directional_light_casts_the_shadow_away_from_the_light() {
    let (vol, tf) = block_and_wall(32, [12..20, 12..20, 6..9], 22..25, [0.9, 0.9, 0.9, 0.9]);
    let s = ortho_axis(64, 64, Backend::Compute);
    let mut r = Renderer::new(gpu(), vol).unwrap();
    // mean luminance of the wall in a strip left and right of the block's silhouette
    let strips = |img: &[[f64; 3]]| {
        let mean = |xs: std::ops::Range<usize>| {
            let (mut sum, mut n) = (0.0, 0.0);
            for y in 26..38 {
                for x in xs.clone() {
                    sum += img[y * 64 + x].iter().sum::<f64>() / 3.0;
                    n += 1.0;
                }
            }
            sum / n
        };
        (mean(14..23), mean(41..50))
    };
    let mut found = Vec::new();
    for d in [
        dos(40.0),
        dos_lit(40.0, [-1.0, 0.0, 1.0]),
        dos_lit(40.0, [1.0, 0.0, 1.0]),
    ] {
        let img = rgb(&render(
            &mut r,
            &[tf.clone(), d],
            TargetFormat::Rgba32Float,
            &s,
        ));
        found.push(strips(&img));
    }
    eprintln!(
        "wall left / right of the block: viewer {:?}, lit from the left {:?}, from the right {:?}",
        found[0], found[1], found[2]
    );
    let (viewer, left_lit, right_lit) = (found[0], found[1], found[2]);
    assert!((viewer.0 - viewer.1).abs() < 0.02 * viewer.0, "{viewer:?}");
    assert!(left_lit.1 < 0.8 * left_lit.0, "{left_lit:?}");
    assert!(right_lit.0 < 0.8 * right_lit.1, "{right_lit:?}");
}

/// The eye inside the volume with a wide view across the light (fov 120°, light from
/// the side): some pixels' rays meet the half-angle slices front to back, others back
/// to front. The compute backend and the twin composite each pixel in its own order;
/// the raster backend draws each slice with an "under" and an "over" pipeline, each
/// discarding the other order's pixels. All three agree, and the image is not a blank
/// one.
#[test]
fn a_wide_view_across_the_light_composites_each_pixel_in_its_own_order() {
    let stack = vec![
        tf_constant([0.9, 0.8, 0.7, 0.06]),
        dos_lit(45.0, [1.0, 0.0, 0.0]),
    ];
    let mut s = settings(40, 40, Backend::Compute);
    s.camera.distance = 0.2;
    s.camera.projection = vwb_render::camera::Projection::Perspective { fov_y_deg: 120.0 };
    // the frame holds both orders
    let view = s.camera.view(1.0);
    let light = registry()
        .get("shade.dos")
        .unwrap()
        .slice_light(&stack[1].params, &view);
    let vbox = vwb_render::slicing::VolumeBox::new(demo().dims, demo().spacing);
    let plan = vwb_render::slicing::FramePlan::new(&view, &vbox, 1.0, light).unwrap();
    assert!(plan.half.is_some() && plan.back_to_front(&view, &vbox).is_none());
    let (px, _) = gpu_and_reference(demo(), &stack, TargetFormat::Rgba32Float, &s);
    let alpha: f64 = px.iter().map(|p| p[3] as f64).sum::<f64>() / px.len() as f64;
    eprintln!("wide view across the light: mean α {alpha:.3}");
    assert!(alpha > 0.05, "{alpha}");
    backends_match_the_twin_and_each_other_in(&stack, "wide view across the light", &s);
}

/// `stack` under `s` with the per-slice path's idle tiles left out of its dispatches
/// ([`Renderer::set_slice_exit`]) and with every tile dispatched: the same pixels bit
/// for bit. Returns the share of idle tiles.
fn idle_tiles_keep_the_image(
    r: &mut Renderer,
    stack: &[PluginInstance],
    s: &FrameSettings,
    what: &str,
) -> Option<f64> {
    let mut images = Vec::new();
    let mut idle = None;
    for exit in [true, false] {
        r.set_slice_exit(exit);
        r.update_stack(stack, TargetFormat::Rgba32Float).unwrap();
        let stats = r.render(s).unwrap();
        assert!(stats.per_slice_mode && stats.slices > 0, "{what}");
        if exit {
            idle = stats.idle_tiles;
        } else {
            assert_eq!(stats.idle_tiles, None, "{what}: every tile runs");
        }
        images.push(r.read_pixels().unwrap().2);
    }
    r.set_slice_exit(true);
    let same = images[0]
        .iter()
        .zip(&images[1])
        .filter(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits))
        .count();
    eprintln!(
        "{what}: idle tiles {idle:?}, {same} of {} pixels the same",
        images[0].len()
    );
    assert_eq!(
        same,
        images[0].len(),
        "{what}: the image with idle tiles left out differs"
    );
    idle
}

/// The compute backend leaves out of each slice's dispatch the tiles where no sample
/// can be visible and the occlusion buffer is either still clear or read by no later
/// visible sample (`vwb_render::renderer` `slice_exit`): the image is the one with
/// every tile dispatched, bit for bit, for both kernels and distances, chromatic
/// extinction, apertures from 0° to 85°, perspective and orthographic views, a clip,
/// skipping off, nothing visible, a block shadowing a second one behind it, and
/// atlases of variants (also with a half-resolution buffer); the raster backend's
/// occlusion updates and the compute backend's updates in dispatches of their own too,
/// and the updates of a half- and a quarter-resolution buffer over tiles of its own
/// grid, and under a directional light (half-angle slicing) the updates over tiles of
/// the buffer across the light. It leaves out tiles wherever it applies; a state that
/// states no reach (`test.slice_shadow`) dispatches every tile.
#[test]
fn idle_tiles_are_left_out_and_keep_the_image() {
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let persp = settings(64, 64, Backend::Compute);
    let mut ortho = ortho_axis(64, 64, Backend::Compute);
    ortho.camera.yaw_deg += 30.0;
    ortho.camera.pitch_deg += 20.0;
    for (kernel, distance, extinction, theta) in [
        ("grid", "slice", None, 60.0),
        ("poisson", "exact", None, 30.0),
        ("grid", "exact", Some([0.4, 1.0, 2.5]), 70.0),
        ("grid", "slice", None, 0.0),
        ("poisson", "slice", None, 85.0),
    ] {
        let mut d = dos(theta);
        set_kernel(&mut d, kernel, distance, "1", extinction);
        d.params
            .set("buffer_format", ParamValue::Enum("fp32".into()));
        let stack = [instance("classify.tf1d"), d];
        for (view, s) in [("perspective", &persp), ("orthographic", &ortho)] {
            let what = format!("{kernel} {distance} κ {extinction:?} θ {theta} {view}");
            let idle = idle_tiles_keep_the_image(&mut r, &stack, s, &what);
            assert!(idle.is_some_and(|i| i > 0.1), "{what}: {idle:?}");
        }
    }
    let (tf, d) = (instance("classify.tf1d"), dos(60.0));
    // a clip through the matter (the default: the plane x = 0)
    let stack = [tf.clone(), instance("clip.shapes"), d.clone()];
    let idle = idle_tiles_keep_the_image(&mut r, &stack, &persp, "clip");
    assert!(idle.is_some_and(|i| i > 0.1), "clip: {idle:?}");
    // without skipping every sample of the box can be visible: fewer tiles are idle
    r.set_empty_space_skipping(false);
    let stack = [tf.clone(), d.clone()];
    let unskipped = idle_tiles_keep_the_image(&mut r, &stack, &persp, "skipping off");
    r.set_empty_space_skipping(true);
    let skipped = idle_tiles_keep_the_image(&mut r, &stack, &persp, "skipping on");
    assert!(
        unskipped.is_some() && unskipped < skipped,
        "{unskipped:?} {skipped:?}"
    );
    // nothing visible: every tile after the first slice is idle
    let mut clear = tf.clone();
    clear.params.set(
        "tf",
        ParamValue::Tf(vwb_render::tf::TfCurve::ramp(
            0.0,
            1.0,
            [1.0, 1.0, 1.0, 0.0],
        )),
    );
    let idle = idle_tiles_keep_the_image(&mut r, &[clear, d.clone()], &persp, "nothing visible");
    assert!(idle.is_some_and(|i| i > 0.95), "nothing visible: {idle:?}");
    // the raster backend's state updates, and the compute backend's with the slice and
    // the update in dispatches of their own, cover the listed tiles too
    // (where every state has the eye buffer's size, the tiles without a visible sample
    // by the state-only entry point), also for a wide Poisson cone with chromatic
    // extinction
    let mut wide = dos(85.0);
    set_kernel(&mut wide, "poisson", "exact", "1", Some([0.4, 1.0, 2.5]));
    let raster = settings(64, 64, Backend::Raster);
    for (stack, what) in [
        ([tf.clone(), d.clone()], "θ 60"),
        ([tf.clone(), wide], "Poisson, exact, chromatic, θ 85"),
    ] {
        let what = format!("raster, {what}");
        let idle = idle_tiles_keep_the_image(&mut r, &stack, &raster, &what);
        assert!(idle.is_some_and(|i| i > 0.1), "{what}: {idle:?}");
        r.set_fused_slices(false);
        let what = format!("two dispatches, {what}");
        let idle = idle_tiles_keep_the_image(&mut r, &stack, &persp, &what);
        r.set_fused_slices(true);
        assert!(idle.is_some_and(|i| i > 0.1), "{what}: {idle:?}");
    }
    // a smaller occlusion buffer: its updates cover the listed tiles of its own grid
    // (the slices' dispatches the whole eye buffer), on both backends
    for scale in ["0.5", "0.25"] {
        let mut small = d.clone();
        set_buffer_scale(&mut small, scale);
        let stack = [tf.clone(), small];
        // at 160², a grid of 10 × 10 or 5 × 5 tiles of the buffer
        let large = settings(160, 160, Backend::Compute);
        for (view, s) in [
            ("perspective", &persp),
            ("orthographic", &ortho),
            ("raster", &raster),
            ("perspective 160²", &large),
        ] {
            let what = format!("buffer scale {scale}, {view}");
            let idle = idle_tiles_keep_the_image(&mut r, &stack, s, &what);
            assert!(idle.is_some_and(|i| i > 0.1), "{what}: {idle:?}");
        }
    }
    // a directional light (half-angle slicing): the updates over the tiles of the
    // buffer across the light, the slices' dispatches over their visible eye tiles; a
    // light on the viewer's side, one from behind (the eye meets the slices back to
    // front), a wide cone, a half-resolution buffer, on both backends
    for (towards, theta, scale) in [
        ([0.6, 0.4, 1.0], 60.0, "1"),
        ([0.3, -0.5, -1.0], 60.0, "1"),
        ([0.6, 0.4, 1.0], 85.0, "1"),
        ([0.6, 0.4, 1.0], 60.0, "0.5"),
    ] {
        let mut lit = dos_lit(theta, towards);
        set_buffer_scale(&mut lit, scale);
        let stack = [tf.clone(), lit];
        for (view, s) in [
            ("perspective", &persp),
            ("orthographic", &ortho),
            ("raster", &raster),
        ] {
            let what =
                format!("light towards {towards:?}, θ {theta}, buffer scale {scale}, {view}");
            let idle = idle_tiles_keep_the_image(&mut r, &stack, s, &what);
            assert!(idle.is_some_and(|i| i > 0.05), "{what}: {idle:?}");
        }
    }
    // a wide cone in a larger buffer, where the cone's reach exceeds the tiles' margins
    let stack = [tf.clone(), dos_lit(85.0, [0.6, 0.4, 1.0])];
    let large = settings(160, 160, Backend::Compute);
    let what = "light, θ 85, 160²";
    let idle = idle_tiles_keep_the_image(&mut r, &stack, &large, what);
    assert!(idle.is_some_and(|i| i > 0.05), "{what}: {idle:?}");
    // what dispatches every tile
    let stack = [tf.clone(), instance("test.slice_shadow")];
    assert_eq!(
        idle_tiles_keep_the_image(&mut r, &stack, &persp, "no reach"),
        None,
        "no reach"
    );

    // a block whose shadow falls on part of a smaller block further back, seen from
    // the side: between them the shadow is still needed on the way to the second block
    // and stale elsewhere
    let vol = synthetic([40; 3], |x, y, z| {
        let front = (8..22).contains(&x) && (8..22).contains(&y) && (4..10).contains(&z);
        let back = (16..26).contains(&x) && (14..30).contains(&y) && (28..34).contains(&z);
        if front || back { 1.0 } else { 0.0 }
    });
    let mut r = Renderer::new(gpu(), vol).unwrap();
    let (tf, _) = crate::clipping::dos_stack();
    let mut s = ortho_axis(96, 96, Backend::Compute);
    s.camera.yaw_deg += 10.0;
    s.camera.pitch_deg += 8.0;
    for (theta, scale) in [(20.0, "1"), (60.0, "1"), (60.0, "0.5")] {
        let mut d = dos(theta);
        set_buffer_scale(&mut d, scale);
        let stack = [tf.clone(), d];
        let what = format!("two blocks θ {theta}, buffer scale {scale}");
        let idle = idle_tiles_keep_the_image(&mut r, &stack, &s, &what);
        assert!(idle.is_some_and(|i| i > 0.1), "{what}: {idle:?}");
    }
    // and lit from the side by a directional light, the front block's shadow crossing
    // empty space onto the back one
    for (towards, theta) in [([0.5, 0.3, 1.0], 20.0), ([-0.4, -0.6, 1.0], 45.0)] {
        let stack = [tf.clone(), dos_lit(theta, towards)];
        let what = format!("two blocks, light towards {towards:?}, θ {theta}");
        let idle = idle_tiles_keep_the_image(&mut r, &stack, &s, &what);
        assert!(idle.is_some_and(|i| i > 0.1), "{what}: {idle:?}");
    }

    // atlases of variants (each tile's own occupancy, hull and reach), with the full
    // buffer and with a half-resolution one of the tile's size (the buffer's scale is
    // structural: one per atlas)
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let mut cams = [persp.camera; 3];
    cams[1].yaw_deg += 40.0;
    cams[2] = ortho.camera;
    for scale in ["1", "0.5"] {
        let stacks: Vec<Vec<PluginInstance>> = [20.0, 60.0, 80.0]
            .iter()
            .map(|&theta| {
                let mut d = dos(theta);
                set_buffer_scale(&mut d, scale);
                vec![instance("classify.tf1d"), d]
            })
            .collect();
        let tiles: Vec<vwb_render::renderer::AtlasTile> = stacks
            .iter()
            .zip(cams)
            .map(|(stack, camera)| vwb_render::renderer::AtlasTile { camera, stack })
            .collect();
        let mut atlases = Vec::new();
        for exit in [true, false] {
            r.set_slice_exit(exit);
            atlases.push(
                r.render_atlas(&tiles, &persp, TargetFormat::Rgba32Float, 3)
                    .unwrap(),
            );
        }
        assert!(
            atlases[0].pixels == atlases[1].pixels,
            "buffer scale {scale}: the atlas with idle tiles left out differs"
        );
        assert!(mean_luma(&rgb(&atlases[0].pixels)) > 0.01);
    }
}
