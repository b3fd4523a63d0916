//! The workbench window driven as a user drives it (egui_kittest: clicks, drags and
//! typing through the accessibility tree), rendering on the same Vulkan device as
//! every other GPU test. Snapshots live in tests/snapshots (`UPDATE_SNAPSHOTS=1`
//! rewrites them).

use std::path::Path;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use vwb_app::window::{Workbench, default_document, wgpu_configuration};
use vwb_render::preset::{Document, VolumeSource};

use crate::common::{gpu, registry, repo, tmp};

/// The CT head's header file in the sample data directory.
const CT: &str = "ct_cranium_256x256x108_int16.nhdr";

/// The window on `doc` at 1100×800, drawing at `scale` × the viewport's resolution.
pub(crate) fn window(doc: Document, scale: f32) -> Harness<'static, Workbench> {
    window_checked(doc, scale, true)
}

/// [`window`], with kittest's check that every widget has an accessible name on or off.
fn window_checked(doc: Document, scale: f32, accessibility: bool) -> Harness<'static, Workbench> {
    window_sized(doc, scale, accessibility, [1100.0, 800.0])
}

/// [`window_checked`] at a window size.
fn window_sized(
    doc: Document,
    scale: f32,
    accessibility: bool,
    size: [f32; 2],
) -> Harness<'static, Workbench> {
    gpu();
    // the sample data directory of the tests
    repo();
    let volume = vwb_lab::headless::load_volume(&doc.volume).expect("volume");
    let mut h = Harness::builder()
        .with_size(size)
        .with_accessibility_check(accessibility)
        .wgpu_setup(wgpu_configuration().wgpu_setup)
        .build_eframe(move |cc| {
            let (tx, _) = mpsc::channel();
            Workbench::new(cc, doc, volume, None, tx).expect("workbench")
        });
    assert_eq!(
        h.state().renderer().gpu().info.backend,
        wgpu::Backend::Vulkan,
        "the window must run on Vulkan"
    );
    h.state_mut().quality_scale = scale;
    h.run_steps(3);
    h
}

/// The window on the embedded demo (tests run in the repository root, as cargo
/// starts them).
fn demo_window() -> Harness<'static, Workbench> {
    window(default_document(&registry()), 0.25)
}

fn ids(h: &Harness<'_, Workbench>) -> Vec<&'static str> {
    h.state()
        .document()
        .stack
        .iter()
        .map(|i| i.plugin.id())
        .collect()
}

fn image(h: &Harness<'_, Workbench>) -> image::RgbImage {
    h.state().image().expect("the viewport has drawn")
}

/// RMS difference of two 8-bit images (0–255).
fn rms(a: &image::RgbImage, b: &image::RgbImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions());
    let n = a.as_raw().len() as f64;
    let sum: f64 = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| (*x as f64 - *y as f64).powi(2))
        .sum();
    (sum / n).sqrt()
}

/// Runs frames until nothing animates (scrolling to a widget is animated).
fn settle(h: &mut Harness<'_, Workbench>) {
    if h.run_ok().is_none() {
        h.run_steps(10);
    }
}

/// Scrolls the `n`-th node labelled `label` into view, clicks it and lets the UI settle.
fn click_nth(h: &mut Harness<'_, Workbench>, label: &str, n: usize) {
    h.get_all_by_label(label)
        .nth(n)
        .unwrap_or_else(|| panic!("no {label} #{n}"))
        .scroll_to_me();
    settle(h);
    // menus open on a click where the pointer already hovers, as with a real mouse
    h.get_all_by_label(label).nth(n).unwrap().hover();
    h.run_steps(1);
    h.get_all_by_label(label).nth(n).unwrap().click();
    h.run_steps(3);
}

pub(crate) fn click(h: &mut Harness<'_, Workbench>, label: &str) {
    click_nth(h, label, 0);
}

/// Adds a plugin through the "Add plugin" menu.
fn add_plugin(h: &mut Harness<'_, Workbench>, category: &str, name: &str) {
    click(h, "Add plugin");

    click(h, category);
    click(h, name);
}

/// The path fields' hint texts (they start empty).
const PRESET_FIELD: &str = "preset file (.ron)";
const VOLUME_FIELD: &str = "volume file or sample";

/// Replaces the text of the text field now showing `current` (or with the hint text
/// `current`).
fn retype(h: &mut Harness<'_, Workbench>, current: &str, text: &str) {
    let current = current.to_string();
    let field = || {
        let c = current.clone();
        move |n: &egui_kittest::kittest::AccessKitNode<'_>| {
            n.role() == egui::Role::TextInput
                && (n.value().as_deref() == Some(c.as_str()) || n.placeholder() == Some(c.as_str()))
        }
    };
    h.get_by(field()).scroll_to_me();
    settle(h);
    h.get_by(field()).click();
    h.run_steps(1);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    h.run_steps(1);
    h.get_by(field()).type_text(text);
    h.run_steps(2);
}

/// Releases the primary button at `pos`, the pointer staying there (kittest's
/// `drop_at` also removes the pointer, which no mouse does).
fn release_at(h: &mut Harness<'_, Workbench>, pos: egui::Pos2) {
    h.event(egui::Event::PointerButton {
        pos,
        button: egui::PointerButton::Primary,
        pressed: false,
        modifiers: egui::Modifiers::NONE,
    });
}

/// A pointer drag from `a` to `b` in `steps` moves, one frame each.
fn drag(h: &mut Harness<'_, Workbench>, a: egui::Pos2, b: egui::Pos2, steps: usize) {
    h.hover_at(a);
    h.step();
    h.drag_at(a);
    h.step();
    for k in 1..=steps {
        h.hover_at(a + (b - a) * (k as f32 / steps as f32));
        h.step();
    }
    release_at(h, b);
    h.run_steps(2);
}

/// The 1D TF of the first plugin.
fn tf_curve(h: &Harness<'_, Workbench>) -> vwb_render::tf::TfCurve {
    match h.state().document().stack[0].params.get("tf") {
        Some(vwb_render::params::ParamValue::Tf(c)) => c.clone(),
        other => panic!("the first plugin has no 1D TF: {other:?}"),
    }
}

/// Where control point `i` of the first plugin's TF is drawn in `editor`.
fn tf_point_on_screen(h: &Harness<'_, Workbench>, editor: egui::Rect, i: usize) -> egui::Pos2 {
    let q = tf_curve(h).points[i];
    egui::pos2(
        editor.left() + q.x * editor.width(),
        editor.bottom() - q.color[3] * editor.height(),
    )
}

/// Drags the second plugin's handle onto the first plugin.
fn drag_second_onto_first(h: &mut Harness<'_, Workbench>) {
    h.get_all_by_label("::").next().unwrap().scroll_to_me();
    settle(h);
    let handles: Vec<egui::Rect> = h.get_all_by_label("::").map(|n| n.rect()).collect();
    assert_eq!(handles.len(), 2);
    drag(h, handles[1].center(), handles[0].center(), 6);
}

/// Steps the UI until `done` holds or `limit` passes.
fn step_until(
    h: &mut Harness<'_, Workbench>,
    limit: Duration,
    mut done: impl FnMut(&mut Harness<'_, Workbench>) -> bool,
) {
    let start = Instant::now();
    while !done(h) {
        assert!(start.elapsed() < limit, "timed out after {limit:?}");
        h.step();
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Add a plugin, change one of its parameters, reorder by dragging, break its shader
/// and see the error at the plugin while the last image stays, revert, save the preset
/// and reload it to the same image; then a snapshot of the window.
#[test]
fn window_edits_a_scene_like_a_user() {
    let mut h = demo_window();
    let start = image(&h);
    assert!(start.pixels().any(|p| p.0.iter().any(|&c| c > 40)), "blank");

    // add a plugin: the image changes
    add_plugin(&mut h, "shade", "Blinn–Phong");
    assert_eq!(ids(&h), ["classify.tf1d", "shade.blinn_phong"]);
    assert!(h.state().error().is_none(), "{:?}", h.state().error());
    let lit = image(&h);
    assert!(rms(&start, &lit) > 1.0, "shading changed nothing");

    // change a parameter: the image changes again
    click_nth(&mut h, "parameters", 1);
    h.get_by_role_and_label(egui::Role::Slider, "Specular k_s")
        .scroll_to_me();
    settle(&mut h);
    let slider = h.get_by_role_and_label(egui::Role::Slider, "Specular k_s");
    slider.set_value_accesskit(1.0);
    h.run_steps(3);
    let shiny = image(&h);
    assert_eq!(
        h.state().document().stack[1].params.float("ks"),
        1.0,
        "the slider sets k_s"
    );
    assert!(rms(&lit, &shiny) > 0.2, "k_s changed nothing");

    // eight slices per raster polygon (§9.1): the same image up to rounding
    click(&mut h, "slices per polygon");
    settle(&mut h);
    h.get_by_role_and_label(egui::Role::Button, "8").click();
    settle(&mut h);
    assert_eq!(h.state().document().render.slices_per_proxy, 8);
    assert_eq!(h.state().renderer().raster_group(), 8);
    let grouped = image(&h);
    let apart = rms(&shiny, &grouped);
    assert!(apart > 0.0 && apart < 2.0, "8 per polygon: {apart}");
    // and back to one: the image as it was
    click(&mut h, "slices per polygon");
    settle(&mut h);
    h.get_by_role_and_label(egui::Role::Button, "1").click();
    settle(&mut h);
    assert_eq!(h.state().document().render.slices_per_proxy, 1);
    assert!(rms(&shiny, &image(&h)) == 0.0, "one per polygon again");

    // early ray termination: on at the recommended threshold, lower, and off again
    click(&mut h, "stop opaque rays");
    settle(&mut h);
    assert_eq!(
        h.state().document().render.early_termination,
        Some(vwb_app::window::EARLY_TERMINATION)
    );
    let slider = h.get_by_role_and_label(egui::Role::Slider, "opacity to stop at");
    slider.set_value_accesskit(0.9);
    settle(&mut h);
    assert_eq!(h.state().document().render.early_termination, Some(0.9));
    let per_slice = image(&h);
    let stopped = rms(&shiny, &per_slice);
    assert!(stopped > 0.0, "rays stopped at 0.9 changed nothing");
    // "auto" slices per polygon: 8 while rays stop (the image moved by rounding)
    click(&mut h, "slices per polygon");
    settle(&mut h);
    h.get_by_role_and_label(egui::Role::Button, "auto").click();
    settle(&mut h);
    assert_eq!(
        h.state().document().render.slices_per_proxy,
        vwb_render::renderer::RASTER_GROUP_AUTO
    );
    let grouped = rms(&per_slice, &image(&h));
    assert!(
        grouped > 0.0 && grouped < 2.0,
        "auto with termination draws 8 per polygon: {grouped}"
    );
    click(&mut h, "stop opaque rays");
    settle(&mut h);
    assert_eq!(h.state().document().render.early_termination, None);
    assert!(h.query_by_label("opacity to stop at").is_none());
    assert!(
        rms(&shiny, &image(&h)) == 0.0,
        "termination off: the image as it was, auto drawing a polygon per slice"
    );

    // per-plugin GPU time by ablation, in the background
    click(&mut h, "Measure per-plugin cost");
    step_until(&mut h, Duration::from_secs(300), |h| {
        h.query_by_label_contains("shade.blinn_phong#1 (plugin)")
            .is_some()
    });

    // reorder by dragging Blinn–Phong's handle onto the first plugin, and back
    drag_second_onto_first(&mut h);
    assert_eq!(ids(&h), ["shade.blinn_phong", "classify.tf1d"]);
    // fold Blinn–Phong's parameters so that both handles are on screen, drag back
    click_nth(&mut h, "parameters", 0);
    drag_second_onto_first(&mut h);
    assert_eq!(ids(&h), ["classify.tf1d", "shade.blinn_phong"]);

    // break the shader: the error names the plugin, its file and line; the last good
    // pipeline keeps drawing the same image
    let before_break = image(&h);
    click_nth(&mut h, "wgsl", 1);
    let editor = h.get_by_role(egui::Role::MultilineTextInput);
    editor.focus();
    h.run_steps(1);
    h.get_by_role(egui::Role::MultilineTextInput)
        .type_text("fn broken( { ");
    h.run_steps(1);
    click(&mut h, "Apply");
    let e = h.state().error().expect("a compile error").to_string();
    assert!(
        e.contains("shade.blinn_phong") && e.contains("plugins/src/shade_blinn_phong/"),
        "{e}"
    );
    assert!(
        e.split("blinn_phong.wgsl:")
            .nth(1)
            .is_some_and(|r| r.chars().next().is_some_and(|c| c.is_ascii_digit())),
        "file:line in {e}"
    );
    // shown in the stack, under the plugin
    assert!(h.query_by_label_contains("blinn_phong.wgsl:").is_some());
    h.state_mut().document_mut().camera.zoom(1.0);
    h.run_steps(2);
    assert_eq!(rms(&before_break, &image(&h)), 0.0, "the last image stays");
    click(&mut h, "Revert to built-in");
    assert!(h.state().error().is_none(), "{:?}", h.state().error());
    click(&mut h, "Close editor");
    assert!(h.query_by_label("Revert to built-in").is_none());

    // save the preset, change the scene, open the preset again: the same image
    let file = tmp("window_preset.ron");
    let _ = std::fs::remove_file(&file);
    retype(&mut h, PRESET_FIELD, file.to_str().unwrap());
    click(&mut h, "Save preset");
    assert!(
        matches!(h.state().file_status(), Some(Ok(m)) if m.starts_with("saved")),
        "{:?}",
        h.state().file_status()
    );
    // its thumbnail beside it, for the preset browser
    let thumb = image::open(file.with_file_name("window_preset.thumb.png")).unwrap();
    assert_eq!(
        thumb.width().max(thumb.height()),
        vwb_app::browser_ui::THUMB
    );
    let saved = image(&h);
    click_nth(&mut h, "parameters", 1);
    h.get_by_role_and_label(egui::Role::Slider, "Specular k_s")
        .scroll_to_me();
    settle(&mut h);
    h.get_by_role_and_label(egui::Role::Slider, "Specular k_s")
        .set_value_accesskit(0.0);
    h.run_steps(3);
    assert!(rms(&saved, &image(&h)) > 0.2);
    click(&mut h, "Open preset");
    assert_eq!(h.state().document().stack[1].params.float("ks"), 1.0);
    assert!(
        rms(&saved, &image(&h)) < 0.01,
        "reloaded image differs by {}",
        rms(&saved, &image(&h))
    );
    assert!(
        h.state()
            .recent()
            .iter()
            .any(|p| p.ends_with("window_preset.ron"))
    );

    // the viewport is deterministic on lavapipe: a snapshot of it (the snapshots are
    // lavapipe's images; a GPU filters and rounds otherwise)
    if !crate::common::on_gpu() {
        egui_kittest::image_snapshot(
            &image::DynamicImage::ImageRgb8(image(&h)).to_rgba8(),
            "window_viewport_demo_phong",
        );
    }
}

/// The user flow of issue 8: open the app, load the CT head, pick a CT preset, switch
/// Blinn–Phong ↔ DOS, edit the TF (preview quality while dragging), run a sweep, read
/// the Pareto plot and apply a point.
#[test]
fn window_ct_flow_phong_dos_tf_sweep_pareto() {
    let ct = crate::common::data_dir().join(CT);
    let mut h = demo_window();

    // load the CT head into the demo scene
    retype(&mut h, VOLUME_FIELD, ct.to_str().unwrap());
    click(&mut h, "Open volume");
    assert!(
        matches!(h.state().file_status(), Some(Ok(_))),
        "{:?}",
        h.state().file_status()
    );
    assert_eq!(h.state().renderer().volume().dims, [256, 256, 108]);
    assert_fitted(&h);

    // a bad volume path is refused, naming the file; the CT stays
    let bad = tmp("no_such_volume.nhdr");
    retype(&mut h, ct.to_str().unwrap(), bad.to_str().unwrap());
    click(&mut h, "Open volume");
    match h.state().file_status() {
        Some(Err(e)) => assert!(e.contains("no_such_volume.nhdr"), "{e}"),
        other => panic!("{other:?}"),
    }
    assert_eq!(h.state().renderer().volume().dims, [256, 256, 108]);

    // pick the CT preset with Blinn–Phong
    retype(&mut h, PRESET_FIELD, "presets/ct_shade_phong.ron");
    click(&mut h, "Open preset");
    assert!(ids(&h).contains(&"shade.blinn_phong"), "{:?}", ids(&h));
    assert_eq!(
        h.state().document().volume,
        VolumeSource::Sample("ct_head".into())
    );
    // opening it again uploads nothing, creates and compiles nothing
    let before = h.state().renderer().counters();
    click(&mut h, "Open preset");
    let after = h.state().renderer().counters();
    assert_eq!(
        (
            after.volume_uploads,
            after.instance_creations,
            after.compiles,
            after.prepass_runs
        ),
        (
            before.volume_uploads,
            before.instance_creations,
            before.compiles,
            before.prepass_runs
        ),
        "{before:?} → {after:?}"
    );
    let phong = image(&h);

    // Blinn–Phong → DOS
    let at = ids(&h)
        .iter()
        .position(|i| *i == "shade.blinn_phong")
        .unwrap();
    click_nth(&mut h, "del", at);
    add_plugin(&mut h, "shade", "Directional occlusion");
    assert!(ids(&h).contains(&"shade.dos") && !ids(&h).contains(&"shade.blinn_phong"));
    assert!(h.state().error().is_none(), "{:?}", h.state().error());
    let dos = image(&h);
    assert!(rms(&phong, &dos) > 1.0);

    // DOS → Blinn–Phong
    let at = ids(&h).iter().position(|i| *i == "shade.dos").unwrap();
    click_nth(&mut h, "del", at);
    add_plugin(&mut h, "shade", "Blinn–Phong");
    assert!(ids(&h).contains(&"shade.blinn_phong") && !ids(&h).contains(&"shade.dos"));
    assert!(rms(&dos, &image(&h)) > 1.0);

    // edit the TF: drag its fifth point (bone) down; preview quality while dragging
    h.get_by_label("transfer function editor").scroll_to_me();
    settle(&mut h);
    let editor = h.get_by_label("transfer function editor").rect();
    let q = tf_curve(&h).points[4];
    let at = tf_point_on_screen(&h, editor, 4);
    let to = at + egui::vec2(0.0, 30.0);
    h.hover_at(at);
    h.step();
    h.drag_at(at);
    h.step();
    let mut previewed = false;
    for k in 1..=4 {
        h.hover_at(at + (to - at) * (k as f32 / 4.0));
        h.step();
        previewed |= h.state().is_preview();
    }
    h.drop_at(to);
    h.run_steps(3);
    assert!(previewed, "dragging a TF point draws previews");
    assert!(!h.state().is_preview(), "full quality after the release");
    let vwb_render::params::ParamValue::Tf(after) = h.state().document().stack[0]
        .params
        .get("tf")
        .cloned()
        .unwrap()
    else {
        panic!()
    };
    assert!(
        after.points[4].color[3] < q.color[3] - 0.05,
        "{} → {}",
        q.color[3],
        after.points[4].color[3]
    );

    // run a sweep over the slice spacing (small images) and read the Pareto plot
    click(&mut h, "Trade-off: sweep and Pareto plot");
    h.get_by_role_and_label(egui::Role::Slider, "sweep image side")
        .scroll_to_me();
    settle(&mut h);
    h.get_by_role_and_label(egui::Role::Slider, "sweep image side")
        .set_value_accesskit(24.0);
    h.run_steps(2);
    retype(&mut h, "0.5..2:3:log", "0.5,1,4");
    click(&mut h, "Run sweep");
    assert!(h.state_mut().tradeoff().job.is_some(), "the sweep started");
    step_until(&mut h, Duration::from_secs(600), |h| {
        h.state_mut().tradeoff().job.is_none()
    });
    if let Some(Err(e)) = &h.state_mut().tradeoff().result {
        panic!("sweep failed: {e}");
    }
    h.get_by_label("Pareto plot").scroll_to_me();
    settle(&mut h);
    let (n, front, coarse) = {
        let t = h.state_mut().tradeoff();
        let r = t.finished().expect("the sweep finished");
        let coarse = r
            .points
            .iter()
            .position(|p| p.values[0] == 4.0)
            .expect("spacing 4");
        (
            r.points.len(),
            r.points.iter().filter(|p| p.pareto).count(),
            coarse,
        )
    };
    assert_eq!(n, 3);
    assert!(front >= 1);
    {
        let t = h.state_mut().tradeoff();
        let r = t.finished().unwrap();
        let fine = r.points.iter().find(|p| p.values[0] == 0.5).unwrap();
        let coarse_p = &r.points[coarse];
        assert!(
            fine.metrics.rms_delta_e < coarse_p.metrics.rms_delta_e,
            "finer slices are closer to the converged reference: {} vs {}",
            fine.metrics.rms_delta_e,
            coarse_p.metrics.rms_delta_e
        );
    }
    assert!(h.query_by_label_contains("on the Pareto front").is_some());
    // click the coarse point: its slice spacing is applied to the scene
    // hovering can re-lay out the plot's axes: follow the point until it stays put
    let mut p = egui::Pos2::ZERO;
    for _ in 0..5 {
        let q = h
            .state_mut()
            .tradeoff()
            .point_on_screen(coarse)
            .expect("drawn");
        if q == p {
            break;
        }
        p = q;
        h.hover_at(p);
        h.step();
    }
    h.drag_at(p);
    h.step();
    release_at(&mut h, p);
    h.run_steps(3);
    assert_eq!(h.state().document().render.slice_spacing, 4.0);
    assert!(
        h.query_by_label_contains("applied slice_spacing=4.000")
            .is_some()
    );
}

/// A broken preset is refused with its file name; the scene and its image stay.
#[test]
fn window_refuses_a_broken_preset_and_keeps_the_scene() {
    let mut h = demo_window();
    let before = image(&h);
    // a fixed path: it is shown in the snapshot below
    let bad = std::env::temp_dir().join("vwb_window_bad_preset.ron");
    std::fs::write(&bad, "(version: 1, plugins: [ (id: \"classify.nope\") ]").unwrap();
    // the path fields start empty, not in a development checkout
    for hint in [PRESET_FIELD, VOLUME_FIELD] {
        let field = h.get_by(|n| n.placeholder() == Some(hint));
        assert_eq!(field.value().as_deref(), Some(""), "{hint}");
    }
    // the viewport explains the camera; the TF editor its axes
    assert!(h.query_by_label(vwb_app::window::CAMERA_HINT).is_some());
    assert!(h.query_by_label_contains("y: opacity 0 … 1").is_some());
    retype(&mut h, PRESET_FIELD, bad.to_str().unwrap());
    click(&mut h, "Open preset");
    match h.state().file_status() {
        Some(Err(e)) => assert!(e.contains("vwb_window_bad_preset.ron"), "{e}"),
        other => panic!("{other:?}"),
    }
    assert_eq!(ids(&h), ["classify.tf1d"]);
    assert_eq!(rms(&before, &image(&h)), 0.0);
    assert!(Path::new(&bad).exists(), "nothing is deleted");

    // a snapshot of the whole window, the timing panel (changing numbers) folded
    assert!(h.query_by_label("frame time plot").is_some());
    click(&mut h, "Timing");
    assert!(h.query_by_label("frame time plot").is_none());
    h.remove_cursor();
    h.run_steps(2);
    if !crate::common::on_gpu() {
        h.snapshot("window_demo");
    }

    // the session (what the window reopens next time) restores the scene and camera
    let session = h.state().session();
    let camera = h.state().document().camera;
    h.state_mut().document_mut().camera.orbit(40.0, 10.0);
    h.state_mut().restore_session(&session).unwrap();
    assert_eq!(h.state().document().camera, camera);

    // a preset naming a sample that the data directory lacks: the error names the
    // fetch command and the button fetches it in the background, then opens the preset
    let data = tmp("window-data");
    let _ = std::fs::remove_dir_all(&data);
    h.state_mut().set_data_dir(data.clone());
    let preset = tmp("window_sample.ron");
    std::fs::write(&preset, r#"(version: 1, volume: Sample("mri_head"))"#).unwrap();
    retype(&mut h, bad.to_str().unwrap(), preset.to_str().unwrap());
    click(&mut h, "Open preset");
    match h.state().file_status() {
        Some(Err(e)) => assert!(e.contains("run `vwb data fetch mri_head`"), "{e}"),
        other => panic!("{other:?}"),
    }
    click(&mut h, "Fetch mri_head");
    step_until(&mut h, Duration::from_secs(60), |h| {
        h.state().document().volume == VolumeSource::Sample("mri_head".into())
    });
    assert_eq!(h.state().renderer().volume().dims, [128, 128, 84]);
    assert!(data.join("mri_head_volpack_128x128x84_uint8.raw").exists());
    assert!(h.query_by_label("Fetch mri_head").is_none());

    // the preset browser: shipped presets and the user's, thumbnails rendered in the
    // background and cached; a click opens one
    let cache = tmp("thumbnails");
    let _ = std::fs::remove_dir_all(&cache);
    h.state_mut().browser().cache = Some(cache.clone());
    click(&mut h, "Preset browser");
    let names: Vec<String> = h
        .state_mut()
        .browser()
        .names()
        .iter()
        .map(|n| n.to_string())
        .collect();
    for n in ["ct_head", "demo", "demo_preintegrated", "window_sample"] {
        assert!(names.iter().any(|m| m == n), "{n} in {names:?}");
    }
    step_until(&mut h, Duration::from_secs(120), |h| {
        let b = h.state_mut().browser();
        assert_eq!(b.failure("ct_bone"), None);
        b.ready("ct_bone")
    });
    assert!(cache.join("ct_bone.png").exists());
    assert!(h.query_by_label("thumbnail of ct_bone").is_some());
    let n = h.get_all_by_label("demo_preintegrated").count();
    assert_eq!(n, 1);
    h.get_by_label("demo_preintegrated").scroll_to_me();
    h.run_steps(5);
    h.get_by_label("demo_preintegrated").click_accesskit();
    h.run_steps(3);
    assert!(
        h.state().document().description.contains("pre-integrated"),
        "{:?}",
        h.state().file_status()
    );
}

/// Every corner of the volume's box is inside the (square) view, the widest near the
/// edge: the camera was fitted to the volume.
fn assert_fitted(h: &Harness<'_, Workbench>) {
    let b = *h.state().renderer().volume_box();
    let v = h.state().document().camera.view(1.0);
    let mut widest = 0.0f32;
    for i in 0..8 {
        let p = glam::Vec3::new(
            if i & 1 == 0 { b.min.x } else { b.max.x },
            if i & 2 == 0 { b.min.y } else { b.max.y },
            if i & 4 == 0 { b.min.z } else { b.max.z },
        );
        let ndc = (v.proj * v.view).project_point3(p);
        assert!(
            ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0,
            "corner {i} cropped: {ndc}"
        );
        widest = widest.max(ndc.x.abs()).max(ndc.y.abs());
    }
    assert!(widest > 0.8, "the volume fills the view ({widest})");
}

/// The UI benchmark of docs/perf.md: frame time of the window (1100×800) with the CT
/// head (presets/ct_head.ron) while a TF point is dragged, for several preview
/// settings, and the full-quality frame after the release. Each UI frame lays out
/// egui and renders the viewport (the renderer waits for its GPU timestamps), without
/// egui's own paint. Writes docs/ui_bench.json. Run:
/// `bash bench/ui.sh`.
#[test]
#[ignore = "benchmark: bash bench/ui.sh"]
fn ui_frame_time_benchmark() {
    let doc = vwb_app::cli::load_document(Some(&repo().join("presets/ct_head.ron")))
        .expect("presets/ct_head.ron");
    let mut h = window(doc, 1.0);
    h.get_by_label("transfer function editor").scroll_to_me();
    settle(&mut h);
    let viewport = h.state().renderer().read_pixels().map(|(w, h, _)| [w, h]);
    let default = (h.state().drag_spacing, h.state().drag_resolution);
    let mut rows = Vec::new();
    for (spacing, resolution) in [(1.0f32, 1.0f32), (2.0, 0.5), (2.0, 0.25), (4.0, 0.25)] {
        h.state_mut().drag_spacing = spacing;
        h.state_mut().drag_resolution = resolution;
        h.run_steps(2);
        let editor = h.get_by_label("transfer function editor").rect();
        let at = tf_point_on_screen(&h, editor, 5);
        h.hover_at(at);
        h.step();
        h.drag_at(at);
        h.step();
        let mut times = Vec::new();
        for k in 0..24 {
            let dy = if k % 2 == 0 { 12.0 } else { -12.0 };
            h.hover_at(at + egui::vec2(0.0, dy));
            let t = Instant::now();
            h.step();
            times.push(t.elapsed().as_secs_f64() * 1e3);
            assert!(h.state().is_preview());
        }
        h.drop_at(at);
        let t = Instant::now();
        h.step();
        let full = t.elapsed().as_secs_f64() * 1e3;
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        let p90 = times[times.len() * 9 / 10];
        eprintln!(
            "preview spacing ×{spacing}, resolution ×{resolution}: median {median:.1} ms, p90 {p90:.1} ms; full-quality frame {full:.1} ms"
        );
        rows.push(serde_json::json!({
            "preview_slice_spacing_factor": spacing,
            "preview_resolution_factor": resolution,
            "ui_frame_ms_median": median,
            "ui_frame_ms_p90": p90,
            "full_quality_frame_ms": full,
            "frames": times.len(),
            "default_on_this_adapter": (spacing, resolution) == default,
        }));
    }
    let out = serde_json::json!({
        "machine": vwb_lab::measure::machine(),
        "adapter": h.state().renderer().gpu().describe(),
        "window": [1100, 800],
        "viewport_pixels_full_quality": viewport,
        "preset": "presets/ct_head.ron",
        "rows": rows,
    });
    vwb_lab::measure::save_json(&repo().join("docs/ui_bench.json"), &out).expect("write");
}

/// A file dropped on the window: egui hands the app its path.
#[derive(Debug)]
struct Dropped(std::path::PathBuf);

impl egui::DroppedFile for Dropped {
    fn path(&self) -> &Path {
        &self.0
    }
    fn bytes(&self) -> Result<Vec<u8>, String> {
        std::fs::read(&self.0).map_err(|e| e.to_string())
    }
}

fn drop_file(h: &mut Harness<'_, Workbench>, path: std::path::PathBuf) {
    h.input_mut()
        .dropped_files
        .push(std::sync::Arc::new(Dropped(path)));
    h.run_steps(3);
}

/// Drag and drop a preset and a volume onto the window; edit the 2D TF of
/// `classify.tf2d` in its editor over the 2D histogram; compare with the converged
/// reference in the background.
#[test]
fn window_drop_files_edit_the_2d_tf_and_compare() {
    let mut h = demo_window();
    drop_file(&mut h, repo().join("presets/demo_tf2d.ron"));
    assert!(
        matches!(h.state().file_status(), Some(Ok(_))),
        "{:?}",
        h.state().file_status()
    );
    assert_eq!(ids(&h), ["classify.tf2d"]);
    let primitives = |h: &Harness<'_, Workbench>| {
        h.state().document().stack[0]
            .params
            .tf2d("tf")
            .map_or(0, |t| t.primitives.len())
    };
    let before = (primitives(&h), image(&h));
    click(&mut h, "Add gaussian");
    assert_eq!(primitives(&h), before.0 + 1, "a primitive was added");
    assert!(
        rms(&before.1, &image(&h)) > 0.1,
        "the image follows the 2D TF"
    );

    // the genetic search on this stack breeds 2D TFs toward boundary coverage (its
    // model reads the plugin's gradient scale), and a genome goes into the classify.tf2d
    use vwb_render::search::genome::{Genome, Space};
    click(&mut h, "Genetic search");
    h.state_mut().evolve.judge = vwb_app::evolve_ui::Judge::Coverage;
    h.run_steps(2);
    click(&mut h, "Start");
    let idle = |h: &Harness<'_, Workbench>| !h.state().evolve.busy();
    step_until(&mut h, Duration::from_secs(120), |h| {
        idle(h) && h.state().evolve.ga.is_some()
    });
    h.run_steps(3);
    assert_eq!(h.state().evolve.error, None);
    let model = h.state().evolve.coverage_model().unwrap();
    assert_eq!(model.gradient_scale(), Some(4.0));
    let ga = h.state().evolve.ga.clone().unwrap();
    assert!(ga.population.iter().all(|g| g.space() == Space::Tf2d));
    let pick = ga.population[3].clone();
    h.state_mut().apply_genome(&pick);
    h.run_steps(3);
    let tf = h.state().document().stack[0]
        .params
        .tf2d("tf")
        .unwrap()
        .clone();
    assert_eq!(Genome::from_tf2d(&tf).unwrap(), pick);
    click(&mut h, "Genetic search");

    // the converged reference of this frame, in the background
    click(&mut h, "Compare with the CPU reference");
    click(&mut h, "converged");
    click(&mut h, "Compute reference");
    step_until(&mut h, Duration::from_secs(300), |h| {
        h.query_by_label_contains("RMS ΔE*uv").is_some()
    });

    // a volume dropped on the window replaces the demo, the stack stays
    drop_file(&mut h, crate::common::data_dir().join(CT));
    assert_eq!(h.state().renderer().volume().dims, [256, 256, 108]);
    assert_eq!(ids(&h), ["classify.tf2d"]);
    assert!(h.state().recent().len() >= 2, "{:?}", h.state().recent());
}

/// GPU memory (issue 20): with a budget that holds the demo and a small eye buffer, a
/// full-resolution frame is retried at lower resolutions until one fits and the window
/// says so; a dropped volume that does not fit opens as a coarser level, with a notice
/// in the status line and the side panel, and its bricks in view are then refined.
#[test]
fn window_retries_at_a_lower_resolution_when_gpu_memory_runs_out() {
    let mut h = demo_window();
    let held = h.state().renderer().gpu_memory();
    h.state_mut()
        .renderer_mut()
        .set_gpu_memory_budget(Some(held + (1 << 18)));
    h.state_mut().quality_scale = 1.0;
    h.run_steps(10);
    let q = h.state().quality_scale;
    assert!((0.125..1.0).contains(&q), "quality {q}");
    let e = h.state().error().unwrap_or_default().to_string();
    assert!(e.contains("GPU memory") && e.contains("retrying at"), "{e}");
    assert!(h.state().renderer().gpu_memory() <= held + (1 << 18));
    image(&h);
    // a volume beyond the budget opens as a coarser level, with a notice
    drop_file(&mut h, crate::common::data_dir().join(CT));
    let level = h
        .state()
        .renderer()
        .level()
        .cloned()
        .expect("a coarser level");
    assert_eq!(level.full_dims, [256, 256, 108]);
    assert_eq!(h.state().renderer().volume().dims, level.level_dims);
    let status = format!("{:?}", h.state().file_status());
    assert!(
        status.contains("opened")
            && status.contains("level")
            && status.contains("budget")
            && status.contains("16 bits"),
        "{status}"
    );
    h.run_steps(2);
    // the status line and the side panel
    assert!(h.query_all_by_label_contains("level (").count() >= 2);
    // its bricks in view are refined within the budget, a few per frame, and the side
    // panel counts them
    for _ in 0..40 {
        if !h.state().renderer().refining() {
            break;
        }
        h.run_steps(1);
    }
    let r = h.state().renderer();
    // the state that would explain a window that stopped refining (once seen under the
    // full suite's load, not reproduced alone or under 5 parallel runs)
    assert!(
        !r.refining(),
        "still refining after 40 frames: bricks {:?}, level {:?}, error {:?}",
        r.brick_refinement(),
        r.level().map(|l| l.refined),
        h.state().error()
    );
    let (done, n) = r.brick_refinement().expect("bricks refined in view");
    assert_eq!(done, n);
    assert!(r.gpu_memory() <= held + (1 << 18), "{}", r.gpu_memory());
    h.run_steps(1);
    assert!(
        h.query_all_by_label_contains("bricks in view refined")
            .count()
            >= 1
    );
}

/// A clip shape's handle over the viewport drags its centre in the image plane (the
/// camera does not orbit), and the image follows.
#[test]
fn window_a_clip_handle_drags_the_shape() {
    let doc = vwb_render::preset::Document::load(
        &repo().join("presets/mri_clip_sphere.ron"),
        &registry(),
    )
    .unwrap()
    .document;
    let mut h = window(doc, 0.25);
    let key = vwb_plugins::clip_shapes::slot_keys()[0].center;
    let center = |h: &Harness<'_, Workbench>| {
        glam::Vec3::from(h.state().document().stack[1].params.vec3(key))
    };
    let (c0, camera, image0) = (center(&h), h.state().document().camera, image(&h));
    let at = h
        .get_by_label("clip.shapes shape 0 (sphere) centre")
        .rect()
        .center();
    drag(&mut h, at, at + egui::vec2(60.0, 0.0), 4);
    settle(&mut h);
    let c1 = center(&h);
    let view = camera.view(1.0);
    eprintln!("centre {c0} → {c1}");
    assert!((c1 - c0).length() > 0.02, "the centre moved");
    assert!(
        (c1 - c0).normalize().dot(view.right).abs() > 0.95,
        "along the image's horizontal"
    );
    assert_eq!(
        h.state().document().camera,
        camera,
        "the camera did not orbit"
    );
    assert!(rms(&image0, &image(&h)) > 1.0, "the cut moved in the image");

    // the radius handle sizes the sphere
    let size = |h: &Harness<'_, Workbench>| {
        h.state().document().stack[1]
            .params
            .vec3(vwb_plugins::clip_shapes::slot_keys()[0].size)[0]
    };
    let r0 = size(&h);
    let at = h
        .get_by_label("clip.shapes shape 0 (sphere) radius")
        .rect()
        .center();
    let centre = h
        .get_by_label("clip.shapes shape 0 (sphere) centre")
        .rect()
        .center();
    // outwards, away from the centre
    let out = (at - centre).normalized() * 25.0;
    drag(&mut h, at, at + out, 4);
    settle(&mut h);
    eprintln!("radius {r0} → {}", size(&h));
    assert!(size(&h) > r0 + 0.02, "the sphere grew");
}

/// A mesh dropped on the window clips the volume (a `clip.mesh` takes the file); an
/// open mesh is refused with its first bad edge and changes nothing.
#[test]
fn window_a_dropped_mesh_clips_the_volume() {
    use vwb_plugins::clip_mesh::mesh;
    let dir = crate::common::tmp("window-mesh");
    std::fs::create_dir_all(&dir).unwrap();
    let good = dir.join("ball.stl");
    mesh::save(&mesh::sphere(32).map_positions(|p| p * 0.3), &good).unwrap();
    let mut open = mesh::cube().map_positions(|p| p * 0.3);
    open.triangles.pop();
    let bad = dir.join("open.obj");
    mesh::save(&open, &bad).unwrap();

    let mut h = demo_window();
    let before = (ids(&h), image(&h));
    drop_file(&mut h, good.clone());
    settle(&mut h);
    assert!(
        matches!(h.state().file_status(), Some(Ok(m)) if m.contains("ball.stl")),
        "{:?}",
        h.state().file_status()
    );
    let mut expected = vec!["clip.mesh"];
    expected.extend(before.0.iter().copied());
    assert_eq!(ids(&h), expected);
    assert!(rms(&before.1, &image(&h)) > 1.0, "the mesh cuts the image");

    drop_file(&mut h, bad);
    let status = format!("{:?}", h.state().file_status());
    assert!(
        status.contains("open.obj") && status.contains("not closed"),
        "{status}"
    );
    assert_eq!(ids(&h), expected, "the stack is unchanged");
    assert_eq!(
        h.state().document().stack[0].params.path("file"),
        Some(good.as_path())
    );
}

/// A label volume added in *Named volumes*, typed by its path: it loads and is listed
/// with its grid, classify.labels' volume input picks it from its list, and the image
/// is classified by its labels. A file that does not load and a name already taken are
/// refused with the file or name in the message, changing nothing; the volume cannot
/// be removed while the plugin names it, and can once the plugin has gone.
#[test]
fn window_adds_a_named_label_volume_and_a_plugin_picks_it() {
    let mut h = demo_window();
    let before = image(&h);
    click(&mut h, "Named volumes (0)");
    let labels = repo().join("presets/data/demo_labels.nrrd");
    retype(&mut h, "file or sample", &labels.display().to_string());
    click(&mut h, "Add");
    let status = format!("{:?}", h.state().file_status());
    assert!(
        status.contains("added volume 'demo_labels' (") && status.contains("×"),
        "{status}"
    );
    assert!(
        h.query_by_label_contains("demo_labels: demo_labels.nrrd")
            .is_some()
    );
    // a file that does not load, and the same name again: refused, nothing changes
    retype(&mut h, "file or sample", "/nonexistent/seg.nrrd");
    click(&mut h, "Add");
    let status = format!("{:?}", h.state().file_status());
    assert!(
        status.contains("Err") && status.contains("seg.nrrd"),
        "{status}"
    );
    retype(
        &mut h,
        "/nonexistent/seg.nrrd",
        &labels.display().to_string(),
    );
    click(&mut h, "Add");
    let status = format!("{:?}", h.state().file_status());
    assert!(
        status.contains("already has a volume named 'demo_labels'"),
        "{status}"
    );
    assert_eq!(h.state().document().volumes.len(), 1);
    // classify.labels in place of the 1D TF, its input picking the new volume
    add_plugin(&mut h, "classify", "Labels");
    // its parameters are folded (eight transfer functions)
    let folds = h.get_all_by_label("parameters").count();
    click_nth(&mut h, "parameters", folds - 1);
    click(&mut h, "Label volume");
    click(&mut h, "demo_labels");
    settle(&mut h);
    let doc = h.state().document();
    let inst = doc.stack.last().unwrap();
    assert_eq!(inst.plugin.id(), "classify.labels");
    assert_eq!(inst.params.volume("labels"), "demo_labels");
    assert!(h.state().error().is_none(), "{:?}", h.state().error());
    assert!(
        rms(&before, &image(&h)) > 1.0,
        "the labels classify the image"
    );
    // in use: Remove does nothing; the plugin gone, it removes the volume
    click(&mut h, "Remove");
    assert_eq!(h.state().document().volumes.len(), 1);
    h.state_mut().document_mut().stack.pop();
    h.state_mut().apply_stack();
    settle(&mut h);
    click(&mut h, "Remove");
    assert!(h.state().document().volumes.is_empty());
    assert!(
        matches!(h.state().file_status(), Some(Ok(m)) if m.contains("removed volume 'demo_labels'")),
        "{:?}",
        h.state().file_status()
    );
}

/// The file dialog (egui_file) opens on the presets folder and lists them; choosing
/// one opens it; Cancel closes the dialog. egui_file's own path fields have no
/// accessible names, so kittest's accessibility check is off here only.
#[test]
fn window_file_dialog_opens_a_preset() {
    let mut h = window_checked(default_document(&registry()), 0.25, false);
    click_nth(&mut h, "…", 1);
    assert!(
        h.query_by_label_contains("ct_head.ron").is_some(),
        "presets listed"
    );
    click(&mut h, "Cancel");
    assert!(h.query_by_label_contains("ct_head.ron").is_none(), "closed");
    click_nth(&mut h, "…", 1);
    // entries carry an icon before the name; the first preset is listed in view
    // (the list only lays out the rows it shows)
    let name = "ct_bone.ron";
    h.get_by_label_contains(name).scroll_to_me();
    settle(&mut h);
    h.get_by_label_contains(name).hover();
    h.run_steps(1);
    h.get_by_label_contains(name).click();
    h.run_steps(2);
    click(&mut h, "Open");
    assert!(
        matches!(h.state().file_status(), Some(Ok(m)) if m.contains(name)),
        "{:?}",
        h.state().file_status()
    );
    let expected =
        vwb_render::preset::Document::load(&repo().join("presets").join(name), &registry())
            .unwrap()
            .document;
    let expected: Vec<&str> = expected.stack.iter().map(|i| i.plugin.id()).collect();
    assert_eq!(ids(&h), expected);
}

/// At the default window size (1000×720) the side panel scrolls: the Compare and
/// Trade-off sections at its bottom can be reached and opened.
#[test]
fn window_side_panel_scrolls_at_the_default_size() {
    let mut h = window_sized(default_document(&registry()), 0.25, true, [1000.0, 720.0]);
    click(&mut h, "Trade-off: sweep and Pareto plot");
    h.get_by_label("Run sweep").scroll_to_me();
    settle(&mut h);
    let run = h.get_by_label("Run sweep").rect();
    assert!(run.max.y <= 720.0, "Run sweep is off screen: {run:?}");
    click(&mut h, "Compare with the CPU reference");
    h.get_by_label("Compute reference").scroll_to_me();
    settle(&mut h);
    let compute = h.get_by_label("Compute reference").rect();
    assert!(
        compute.max.y <= 720.0,
        "Compute reference is off screen: {compute:?}"
    );
}

/// The TF gallery in the window: open the panel, make a gallery (background job), click
/// a thumbnail to refine around it, step back, and apply a TF to the stack: the image
/// changes and the stack's TF is the genome's.
#[test]
fn window_gallery_refines_and_applies_a_tf() {
    let mut h = demo_window();
    click(&mut h, "TF gallery");
    click(&mut h, "New gallery");
    step_until(&mut h, Duration::from_secs(120), |h| {
        !h.state().gallery.busy() && !h.state().gallery.history.is_empty()
    });
    h.run_steps(3);
    assert_eq!(h.state().gallery.history[0].genomes.len(), 16);
    click(&mut h, "gallery TF 2");
    step_until(&mut h, Duration::from_secs(120), |h| {
        !h.state().gallery.busy() && h.state().gallery.history.len() == 2
    });
    h.run_steps(3);
    assert!(h.state().gallery.history[1].radius < 1.0, "a refinement");
    click(&mut h, "Back");
    assert_eq!(h.state().gallery.current, 0);
    assert_eq!(h.state().gallery.history.len(), 2, "the graph keeps it");
    // another branch from the first gallery, then back to the first branch through
    // the image graph
    click(&mut h, "gallery TF 5");
    step_until(&mut h, Duration::from_secs(120), |h| {
        !h.state().gallery.busy() && h.state().gallery.history.len() == 3
    });
    h.run_steps(3);
    assert_eq!(h.state().gallery.history[2].parent, Some(0));
    assert_eq!(h.state().gallery.current, 2);
    click(&mut h, "visited gallery 2");
    assert_eq!(h.state().gallery.current, 1);
    click(&mut h, "visited gallery 1");
    assert_eq!(h.state().gallery.current, 0);

    let before = image(&h);
    let g = h.state().gallery.history[0].genomes[0].clone();
    h.state_mut().apply_genome(&g);
    settle(&mut h);
    h.run_steps(5);
    // the TF editor's colour widgets round colours through f32 conversions (~1e-7)
    let (got, want) = (tf_curve(&h), g.to_curve().unwrap());
    assert_eq!(got.points, want.points);
    assert_eq!(got.primitives.len(), want.primitives.len());
    for (p, q) in got.primitives.iter().zip(&want.primitives) {
        assert_eq!(
            (p.shape, p.centre, p.width, p.height),
            (q.shape, q.centre, q.width, q.height)
        );
        for c in 0..3 {
            assert!((p.color[c] - q.color[c]).abs() < 1e-5, "{p:?} vs {q:?}");
        }
    }
    assert!(rms(&before, &image(&h)) > 1.0, "the applied TF shows");
}

/// The genetic-search panel through the real window: a seeded population, two picks,
/// a generation bred from them (the picks survive, the rest are new), then an
/// objective run of several generations whose best score never rises, and the best TF
/// applied to the stack. A target image that is not the panel's views is refused,
/// naming the file.
#[test]
fn window_evolves_by_picks_and_by_an_objective() {
    use vwb_app::evolve_ui::{Judge, POPULATION, RUN_GENERATIONS};
    let mut h = demo_window();
    click(&mut h, "Genetic search");
    click(&mut h, "Start");
    let idle =
        |h: &Harness<'_, Workbench>| !h.state().evolve.busy() && h.state().evolve.ga.is_some();
    step_until(&mut h, Duration::from_secs(120), |h| idle(h));
    h.run_steps(3);
    let first = h.state().evolve.ga.clone().unwrap();
    assert_eq!(first.population.len(), POPULATION);
    assert_eq!(h.state().evolve.views[0].len(), 3, "three viewpoints");
    click(&mut h, "GA TF 5");
    click(&mut h, "GA TF 2");
    assert_eq!(h.state().evolve.picks, vec![5, 2]);
    click(&mut h, "Next generation");
    step_until(&mut h, Duration::from_secs(120), |h| {
        idle(h) && h.state().evolve.ga.as_ref().unwrap().generation == 1
    });
    h.run_steps(3);
    let second = h.state().evolve.ga.clone().unwrap();
    assert_eq!(second.population[0], first.population[2], "picks survive");
    assert_eq!(second.population[1], first.population[5]);
    assert!(
        second.population[2..]
            .iter()
            .all(|g| !first.population.contains(g)),
        "the rest are children"
    );
    assert!(h.state().evolve.picks.is_empty());

    // an objective: several generations per click, elitism keeps the best
    h.state_mut().evolve.judge =
        Judge::Objective(vwb_render::search::genetic::Objective::EdgeEnergy);
    h.run_steps(2);
    click(&mut h, &format!("Run {RUN_GENERATIONS}"));
    step_until(&mut h, Duration::from_secs(240), |h| {
        idle(h) && h.state().evolve.ga.as_ref().unwrap().generation == 1 + RUN_GENERATIONS
    });
    h.run_steps(3);
    let progress = &h.state().evolve.progress;
    assert_eq!(progress.len(), RUN_GENERATIONS);
    for w in progress.windows(2) {
        assert!(w[1].best_score <= w[0].best_score + 1e-9, "elitism");
    }
    let before = image(&h);
    let best = h.state().evolve.best().unwrap();
    click(&mut h, "Apply best");
    settle(&mut h);
    h.run_steps(5);
    let got = tf_curve(&h);
    assert_eq!(got.primitives.len(), best.len());
    assert!(rms(&before, &image(&h)) > 1.0, "the applied TF shows");

    // boundary coverage: the model of the data is made once and kept between
    // generations while the volume and the camera stay
    h.state_mut().evolve.judge = Judge::Coverage;
    h.run_steps(2);
    let generation = h.state().evolve.ga.as_ref().unwrap().generation;
    for k in 1..=2 {
        click(&mut h, "Next generation");
        step_until(&mut h, Duration::from_secs(120), |h| {
            idle(h) && h.state().evolve.ga.as_ref().unwrap().generation == generation + k
        });
    }
    let model = h.state().evolve.coverage_model().cloned().unwrap();
    assert!(h.state().evolve.scores.is_some(), "scored by coverage");
    click(&mut h, "Next generation");
    step_until(&mut h, Duration::from_secs(120), |h| {
        idle(h) && h.state().evolve.ga.as_ref().unwrap().generation == generation + 3
    });
    assert!(
        std::sync::Arc::ptr_eq(&model, h.state().evolve.coverage_model().unwrap()),
        "the coverage model is reused"
    );

    // a target image of the wrong shape is refused with its name
    let bad = tmp("window_ga_target.png");
    image::RgbImage::new(48, 48).save(&bad).unwrap();
    h.state_mut().evolve.judge = Judge::Target(bad.display().to_string());
    h.run_steps(2);
    click(&mut h, "Next generation");
    step_until(&mut h, Duration::from_secs(60), |h| {
        !h.state().evolve.busy() && h.state().evolve.error.is_some()
    });
    let e = h.state().evolve.error.clone().unwrap_or_default();
    assert!(
        e.contains("window_ga_target.png") && e.contains("1 view(s)"),
        "{e}"
    );
}

/// A user plugin in the stack reloads in the open window when its WGSL changes (the
/// image follows), and a broken edit shows its file and line while the last good
/// version keeps drawing.
#[test]
fn window_reloads_an_edited_user_plugin_and_survives_a_broken_one() {
    use vwb_plugins::user;
    let dir = tmp("window_toon");
    std::fs::create_dir_all(&dir).unwrap();
    let src_dir = repo().join("examples/plugins/toon_lite");
    for f in ["plugin.ron", "toon_lite.wgsl"] {
        std::fs::copy(src_dir.join(f), dir.join(f)).unwrap();
    }
    let manifest = dir.join("plugin.ron");
    let text = std::fs::read_to_string(&manifest).unwrap();
    std::fs::write(
        &manifest,
        text.replace("shade.toon_lite", "shade.toon_window"),
    )
    .unwrap();
    user::install(vec![user::load(&dir).unwrap()]);
    let mut doc = default_document(&registry());
    doc.stack.push(vwb_render::plugin::PluginInstance::new(
        vwb_plugins::registry().get("shade.toon_window").unwrap(),
    ));
    let mut h = window(doc, 0.25);
    h.state_mut().reload_user_plugins(); // the first poll records the files' times
    settle(&mut h);
    let before = image(&h);
    let wgsl = dir.join("toon_lite.wgsl");
    let src = std::fs::read_to_string(&wgsl).unwrap();
    let touch = |secs: u64| {
        let f = std::fs::File::options().write(true).open(&wgsl).unwrap();
        f.set_modified(std::time::SystemTime::now() + Duration::from_secs(secs))
            .unwrap();
    };
    // a darker model: the image follows within the window's one-second poll
    std::fs::write(
        &wgsl,
        src.replace("var rgb = s.color.rgb *", "var rgb = 0.2 * s.color.rgb *"),
    )
    .unwrap();
    touch(10);
    step_until(&mut h, Duration::from_secs(30), |h| {
        h.state()
            .document()
            .stack
            .iter()
            .any(|i| i.plugin.shader().source.contains("0.2 * s.color"))
    });
    settle(&mut h);
    h.run_steps(5);
    let darker = image(&h);
    assert!(rms(&before, &darker) > 1.0, "the edited shader draws");
    // a broken edit: its file and line are shown, the last good image stays
    std::fs::write(&wgsl, src.replace("let d = max(", "let d == max(")).unwrap();
    touch(20);
    step_until(&mut h, Duration::from_secs(30), |h| {
        h.state().error().is_some()
    });
    let e = h.state().error().unwrap().to_string();
    assert!(e.contains("toon_lite.wgsl:"), "{e}");
    h.run_steps(5);
    assert!(
        rms(&darker, &image(&h)) < 0.5,
        "the last good pipeline keeps drawing"
    );
}

/// Writes a label volume to `file`: every voxel `label`, on a 4³ grid over the demo's
/// box, its modification time set to `secs` (so that each write is seen as a change
/// however fast the file system's clock).
fn write_labels(file: &std::path::Path, label: u8, secs: u64) {
    let mut bytes =
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n".to_vec();
    bytes.extend(std::iter::repeat_n(label, 64));
    std::fs::write(file, bytes).unwrap();
    set_modified(file, secs);
}

fn set_modified(file: &std::path::Path, secs: u64) {
    std::fs::File::options()
        .write(true)
        .open(file)
        .unwrap()
        .set_modified(std::time::UNIX_EPOCH + Duration::from_secs(secs))
        .unwrap();
}

/// The window on presets/demo_labels.ron with its label volume from `file` (label 1
/// written at `secs`), settled, and its image.
fn window_with_labels_file(
    file: &std::path::Path,
    secs: u64,
) -> (Harness<'static, Workbench>, image::RgbImage) {
    write_labels(file, 1, secs);
    let mut doc = Document::load(&repo().join("presets/demo_labels.ron"), &registry())
        .unwrap()
        .document;
    doc.volumes
        .insert("labels".into(), VolumeSource::File(file.to_path_buf()));
    let mut h = window(doc, 0.25);
    settle(&mut h);
    let img = image(&h);
    (h, img)
}

/// Runs the window's frames until its named volumes' background load has finished
/// (at most 20 s).
fn until_volumes_loaded(h: &mut Harness<'_, Workbench>) {
    let start = std::time::Instant::now();
    while h.state().is_loading_volumes() {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "the volumes never loaded"
        );
        std::thread::sleep(Duration::from_millis(20));
        h.run_steps(1);
    }
    settle(h);
}

/// Named volumes from large files (here every file: `async_load_bytes` 0) load in a
/// background thread, the last good image drawing meanwhile: a file changed on disk
/// is reloaded so, an added volume joins the document only once loaded (a second one
/// waits for it), and one that does not load is not added and says why.
#[test]
fn window_loads_large_named_volumes_in_the_background() {
    let file = tmp("background_labels.nrrd");
    let (mut h, orange) = window_with_labels_file(&file, 2_000_000);
    h.state_mut().async_load_bytes = 0;
    // reloaded in the background
    write_labels(&file, 2, 2_000_010);
    assert!(h.state_mut().reload_changed_volumes());
    assert!(h.state().is_loading_volumes());
    let status = format!("{:?}", h.state().file_status());
    assert!(status.contains("in the background"), "{status}");
    assert!(
        !h.state_mut().reload_changed_volumes(),
        "one load at a time"
    );
    until_volumes_loaded(&mut h);
    let status = format!("{:?}", h.state().file_status());
    assert!(status.contains("reloaded volume 'labels'"), "{status}");
    assert!(
        rms(&orange, &image(&h)) > 1.0,
        "{}",
        rms(&orange, &image(&h))
    );
    // added in the background
    let source = file.display().to_string();
    let msg = h.state_mut().add_named_volume("extra", &source).unwrap();
    assert!(
        msg.contains("loading volume 'extra' in the background"),
        "{msg}"
    );
    assert!(!h.state().document().volumes.contains_key("extra"));
    let busy = h.state_mut().add_named_volume("more", &source).unwrap_err();
    assert!(format!("{busy:#}").contains("still loading"), "{busy:#}");
    until_volumes_loaded(&mut h);
    assert!(h.state().document().volumes.contains_key("extra"));
    let status = format!("{:?}", h.state().file_status());
    assert!(status.contains("added volume 'extra'"), "{status}");
    // a file that does not load is not added, and says so
    let broken = tmp("background_broken.nrrd");
    std::fs::write(&broken, b"NRRD0004\ntype: uchar\ndimension: 3\n").unwrap();
    h.state_mut()
        .add_named_volume("broken", &broken.display().to_string())
        .unwrap();
    until_volumes_loaded(&mut h);
    assert!(!h.state().document().volumes.contains_key("broken"));
    let status = format!("{:?}", h.state().file_status());
    assert!(
        status.contains("Err")
            && status.contains("'broken' was not added")
            && status.contains("background_broken.nrrd"),
        "{status}"
    );
}

/// A named volume's file edited on disk while the window shows it is loaded again (the
/// window's once-a-second check, called directly here), and the image follows it. A
/// file that does not load (half written) leaves the last good volume drawing with its
/// error shown, and is not tried again until it changes again.
#[test]
fn window_reloads_a_named_volume_edited_on_disk() {
    let file = tmp("reloaded_labels.nrrd");
    let (mut h, orange) = window_with_labels_file(&file, 1_000_000);
    assert!(
        !h.state_mut().reload_changed_volumes(),
        "nothing changed yet"
    );
    // the labels edited: label 2 (blue) everywhere
    write_labels(&file, 2, 1_000_010);
    assert!(h.state_mut().reload_changed_volumes());
    settle(&mut h);
    let status = format!("{:?}", h.state().file_status());
    assert!(status.contains("reloaded volume 'labels'"), "{status}");
    let blue = image(&h);
    assert!(rms(&orange, &blue) > 1.0, "{}", rms(&orange, &blue));
    // half written: refused, the blue image stays, and it is not retried
    std::fs::write(&file, b"NRRD0004\ntype: uchar\ndimension: 3\n").unwrap();
    set_modified(&file, 1_000_020);
    assert!(h.state_mut().reload_changed_volumes());
    settle(&mut h);
    let status = format!("{:?}", h.state().file_status());
    assert!(
        status.contains("Err")
            && status.contains("did not load")
            && status.contains("reloaded_labels.nrrd"),
        "{status}"
    );
    assert_eq!(rms(&blue, &image(&h)), 0.0);
    assert!(!h.state_mut().reload_changed_volumes(), "not tried again");
    // written whole again: loads, and the image is the first one
    write_labels(&file, 1, 1_000_030);
    assert!(h.state_mut().reload_changed_volumes());
    settle(&mut h);
    assert!(
        rms(&orange, &image(&h)) < 0.5,
        "{}",
        rms(&orange, &image(&h))
    );
}
