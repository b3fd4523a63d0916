//! Presets: every shipped preset loads without warnings and composes (naga-valid) for
//! both eye-buffer formats and both volume layouts; round trips; only non-default
//! parameters are saved; unknown keys warn; bad values fail with the path; saves are
//! atomic.

use vwb_render::composer::{TargetFormat, VolumeLayout, compose_for};
use vwb_render::params::ParamValue;
use vwb_render::plugin::Plugin;
use vwb_render::preset::{Document, PresetError, VolumeSource, write_atomic};
use vwb_render::{Backend, Renderer};

use crate::common::*;

/// The `.ron` files of the repository folder `dir`, sorted.
fn ron_files(dir: &str) -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(repo().join(dir))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    v.sort();
    v
}

pub fn shipped_presets() -> Vec<std::path::PathBuf> {
    let v = ron_files("presets");
    assert!(v.len() >= 5, "presets/ holds the shipped presets");
    v
}

/// The benchmarks' own scenes (bench/presets): not shipped, but what the commands in
/// docs/perf.md run, so they are held to the shipped presets' checks.
fn bench_presets() -> Vec<std::path::PathBuf> {
    let v = ron_files("bench/presets");
    assert!(!v.is_empty(), "bench/presets holds the benchmarks' scenes");
    v
}

#[test]
fn every_shipped_preset_loads_and_composes() {
    let reg = registry();
    for path in shipped_presets().into_iter().chain(bench_presets()) {
        let loaded = Document::load(&path, &reg).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            loaded.warnings.is_empty(),
            "{}: {:?}",
            path.display(),
            loaded.warnings
        );
        let doc = loaded.document;
        match &doc.volume {
            VolumeSource::File(f) => {
                // a shipped preset names no path outside the repository
                let f = f
                    .canonicalize()
                    .unwrap_or_else(|e| panic!("{}: volume {}: {e}", path.display(), f.display()));
                assert!(
                    f.starts_with(repo().canonicalize().unwrap()),
                    "{}: volume {} is outside the repository (name a Sample)",
                    path.display(),
                    f.display()
                );
            }
            VolumeSource::Sample(name) => {
                vwb_render::samples::resolve(name)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            }
            VolumeSource::Analytic(a) => {
                let v = a
                    .volume()
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert_eq!(v.components, 3, "{}", path.display());
            }
            VolumeSource::Phantom(p) => {
                p.volume()
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            }
            // shipped presets name their data at its own resolution
            VolumeSource::Resampled(r) => panic!("{}: resampled {r:?}", path.display()),
            VolumeSource::Demo => {}
        }
        let configured: Vec<_> = doc
            .stack
            .iter()
            .filter(|i| i.enabled)
            .map(|i| i.configured())
            .collect();
        let enabled: Vec<&dyn Plugin> = configured.iter().map(|p| p.as_ref()).collect();
        let none = Default::default();
        for target in [TargetFormat::Rgba16Float, TargetFormat::Rgba32Float] {
            for volume in [VolumeLayout::Texture3d, VolumeLayout::ZPairs] {
                compose_for(&enabled, target, &gpu().limits, &none, volume)
                    .unwrap_or_else(|e| panic!("{} ({volume:?}): {e}", path.display()));
            }
        }
    }
}

#[test]
fn round_trip_saves_only_non_default_parameters() {
    let reg = registry();
    let path = repo().join("presets/demo_slice_shadow.ron");
    let doc = Document::load(&path, &reg).unwrap().document;
    let text = doc.to_ron();
    assert!(text.contains("strength"), "a changed parameter is saved");
    assert!(
        !text.contains("opacity"),
        "a default parameter is not saved:\n{text}"
    );
    let again = Document::parse(&text, "roundtrip.ron", &reg).unwrap();
    assert!(again.warnings.is_empty());
    let d2 = again.document;
    assert_eq!(d2.camera, doc.camera);
    assert_eq!(d2.render, doc.render);
    assert_eq!(d2.stack.len(), doc.stack.len());
    for (a, b) in d2.stack.iter().zip(&doc.stack) {
        assert_eq!(a.plugin.id(), b.plugin.id());
        assert_eq!(a.enabled, b.enabled);
        assert_eq!(a.params, b.params);
    }
    // slices per polygon: "auto" (0) is the default and not saved; a polygon per slice
    // set outright is saved, so that it stays one where rays stop
    assert!(!text.contains("slices_per_proxy"), "{text}");
    let mut one = doc.clone();
    one.render.slices_per_proxy = 1;
    let text = one.to_ron();
    assert!(text.contains("slices_per_proxy: 1"), "{text}");
    let again = Document::parse(&text, "one.ron", &reg).unwrap().document;
    assert_eq!(again.render.slices_per_proxy, 1);
    assert_eq!(again.render.raster_group(), 1);
    // every shipped preset saves and reloads to the same stack; a repeated group is
    // saved as one list, as the shipped presets write it, never as its flat keys
    for path in shipped_presets() {
        let doc = Document::load(&path, &reg).unwrap().document;
        let text = doc.to_ron();
        let again = Document::parse(&text, "again.ron", &reg)
            .unwrap_or_else(|e| panic!("{}: {e}\n{text}", path.display()))
            .document;
        assert_eq!(again.stack.len(), doc.stack.len());
        for (a, b) in again.stack.iter().zip(&doc.stack) {
            assert_eq!(a.params, b.params, "{}", path.display());
            assert_eq!(a.enabled, b.enabled);
        }
    }
    let path = repo().join("presets/ct_clip_quadrant.ron");
    let text = Document::load(&path, &reg).unwrap().document.to_ron();
    assert!(
        text.contains("\"shape\": [") && !text.contains("shape0_"),
        "{text}"
    );
    let path = repo().join("presets/ct_shade_iso.ron");
    let text = Document::load(&path, &reg).unwrap().document.to_ron();
    assert!(
        text.contains("\"iso\": [") && !text.contains("iso0"),
        "{text}"
    );
}

/// Named volumes (`volumes:`) round-trip through a save, and relative file paths in
/// them are relative to the preset's folder, as the main volume's are.
#[test]
fn named_volumes_round_trip_and_resolve_beside_the_preset() {
    let reg = registry();
    let text = r#"(version: 1, volume: Demo,
        volumes: {"wind": Analytic((field: Abc, size: (8, 6, 4))), "labels": File("data/demo_labels.nrrd"),
            "fine": Resampled((source: File("data/demo_labels.nrrd"), size: (16, 16, 8)))},
        plugins: [(id: "flow.lic3d", params: {"field": "wind"})])"#;
    let doc = Document::parse(text, "named.ron", &reg).unwrap().document;
    assert_eq!(doc.volumes.len(), 3);
    assert_eq!(doc.stack[0].params.volume("field"), "wind");
    let again = Document::parse(&doc.to_ron(), "again.ron", &reg)
        .unwrap()
        .document;
    assert_eq!(again.volumes, doc.volumes);
    assert_eq!(again.stack[0].params, doc.stack[0].params);
    // loaded from a file: relative to its folder; saved: relative again
    let dir = std::env::temp_dir().join(format!("vwb-named-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("named.ron");
    std::fs::write(&path, text).unwrap();
    let loaded = Document::load(&path, &reg).unwrap().document;
    assert_eq!(
        loaded.volumes["labels"],
        VolumeSource::File(dir.join("data/demo_labels.nrrd"))
    );
    // a resampled file's path too
    let VolumeSource::Resampled(fine) = &loaded.volumes["fine"] else {
        panic!("{:?}", loaded.volumes["fine"])
    };
    assert_eq!(
        *fine.source,
        VolumeSource::File(dir.join("data/demo_labels.nrrd"))
    );
    loaded.save(&path).unwrap();
    let saved = std::fs::read_to_string(&path).unwrap();
    assert!(saved.contains("File(\"data/demo_labels.nrrd\")"), "{saved}");
    let resaved = Document::parse(&saved, "saved.ron", &reg).unwrap().document;
    assert_eq!(resaved.volumes["fine"], doc.volumes["fine"], "{saved}");
    // it loads at its size over the same box
    std::fs::create_dir_all(dir.join("data")).unwrap();
    std::fs::copy(
        repo().join("presets/data/demo_labels.nrrd"),
        dir.join("data/demo_labels.nrrd"),
    )
    .unwrap();
    let labels = vwb_lab::headless::load_volume(&loaded.volumes["labels"]).unwrap();
    let v = vwb_lab::headless::load_volume(&loaded.volumes["fine"]).unwrap();
    assert_eq!(v.dims, [16, 16, 8]);
    for a in 0..3 {
        let (old, new) = (
            labels.spacing[a] * labels.dims[a] as f64,
            v.spacing[a] * v.dims[a] as f64,
        );
        assert!((old - new).abs() < 1e-9, "axis {a}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A preset written before label volumes were named inputs gives the label file's
/// path as the plugin's `labels` value. It still opens: the file becomes a named
/// volume (called after its stem; a second plugin naming the same file shares it), a
/// warning says so, the paths resolve beside the preset, and it renders the image the
/// new form renders. Saving writes the new form.
#[test]
fn legacy_label_paths_open_as_named_volumes() {
    let reg = registry();
    let dir = tmp("legacy_labels");
    std::fs::create_dir_all(dir.join("data")).unwrap();
    std::fs::copy(
        repo().join("presets/data/demo_labels.nrrd"),
        dir.join("data/demo_labels.nrrd"),
    )
    .unwrap();
    let path = dir.join("old.ron");
    std::fs::write(
        &path,
        r#"(version: 1, volume: Demo, volumes: {"demo_labels": Analytic((field: Abc, size: (4, 4, 4)))},
        plugins: [
            (id: "classify.labels", params: {"labels": "data/demo_labels.nrrd", "show_0": false}),
            (id: "clip.labels", params: {"labels": "data/demo_labels.nrrd", "range0_from": 1, "range0_to": 1}),
        ])"#,
    )
    .unwrap();
    let loaded = Document::load(&path, &reg).unwrap();
    let doc = loaded.document;
    let all = loaded.warnings.join("\n");
    assert!(
        all.contains("plugins[0] classify.labels.labels") && all.contains("\"demo_labels_2\""),
        "{all}"
    );
    // the stem is taken by another volume: `_2`; the clip plugin shares the name
    assert_eq!(doc.stack[0].params.volume("labels"), "demo_labels_2");
    assert_eq!(doc.stack[1].params.volume("labels"), "demo_labels_2");
    assert_eq!(
        doc.volumes["demo_labels_2"],
        VolumeSource::File(dir.join("data/demo_labels.nrrd"))
    );
    // the image of the new form, the shipped preset's stack
    let new = Document::load(&repo().join("presets/demo_labels.ron"), &reg)
        .unwrap()
        .document;
    let inputs = vwb_lab::headless::inputs_for(&doc).unwrap();
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    r.set_inputs(inputs);
    let s = settings(48, 48, Backend::Compute);
    let old_image = render(&mut r, &doc.stack[..1], TargetFormat::Rgba16Float, &s);
    let mut fresh = Renderer::new(gpu(), demo()).unwrap();
    fresh.set_inputs(vwb_lab::headless::inputs_for(&new).unwrap());
    let mut stack = new.stack.clone();
    stack[0].params = doc.stack[0].params.clone();
    stack[0]
        .params
        .set("labels", ParamValue::Volume("labels".into()));
    let new_image = render(&mut fresh, &stack, TargetFormat::Rgba16Float, &s);
    assert!(old_image.iter().any(|p| p[3] > 0.05), "labels are visible");
    assert!(old_image == new_image);
    // saved: the new form, no path where a name belongs
    doc.save(&path).unwrap();
    let saved = std::fs::read_to_string(&path).unwrap();
    assert!(
        saved.contains("\"demo_labels_2\": File(\"data/demo_labels.nrrd\")")
            && saved.contains("\"labels\": \"demo_labels_2\""),
        "{saved}"
    );
    let reopened = Document::load(&path, &reg).unwrap();
    assert!(reopened.warnings.is_empty(), "{:?}", reopened.warnings);
}

#[test]
fn unknown_keys_warn() {
    let reg = registry();
    let text = r#"(version: 1, colour_mode: "x", render: (slice_spacing: 1.0, sharpness: 2.0),
        plugins: [(id: "classify.tf1d", params: {"opacity": 0.5, "gamma": 2.0})])"#;
    let loaded = Document::parse(text, "warn.ron", &reg).unwrap();
    let all = loaded.warnings.join("\n");
    assert!(all.contains("colour_mode"), "{all}");
    assert!(all.contains("sharpness"), "{all}");
    assert!(all.contains("classify.tf1d.gamma"), "{all}");
    assert_eq!(
        loaded.document.stack[0].params.get("opacity"),
        Some(&ParamValue::Float(0.5))
    );
}

#[test]
fn bad_values_fail_with_their_path() {
    let reg = registry();
    let cases = [
        (
            r#"(version: 1, plugins: [(id: "classify.tf1d", params: {"opacity": 500.0})])"#,
            "plugins[0] classify.tf1d.opacity",
        ),
        (
            r#"(version: 1, plugins: [(id: "classify.tf1d", params: {"tf": (points: [(x: 0.5, color: (1,1,1,1)), (x: 0.2, color: (1,1,1,1))])})])"#,
            "point 1",
        ),
        (
            r#"(version: 1, plugins: [(id: "classify.tf1d", params: {"tf": (points: [])})])"#,
            "no control points",
        ),
        (
            r#"(version: 1, plugins: [(id: "classify.nope")])"#,
            "plugins[0]",
        ),
        (r#"(version: 7)"#, "version"),
        (
            r#"(version: 1, render: (slice_spacing: -1.0))"#,
            "render.slice_spacing",
        ),
        (r#"(version: 1, render: (size: (0, 10)))"#, "render.size"),
        (
            r#"(version: 1, render: (slices_per_proxy: 3))"#,
            "render.slices_per_proxy",
        ),
        (
            r#"(version: 1, plugins: [(id: "test.smooth", params: {"radius": 1.5})])"#,
            "test.smooth.radius",
        ),
        (
            r#"(version: 1, volume: Sample("ct_hed"))"#,
            "volume: unknown sample 'ct_hed' (known: ct_head,",
        ),
        (
            r#"(version: 1, volume: Analytic((field: Tornado, size: (64, 0, 100000))))"#,
            "volume: an analytic field's size must be 2–512 voxels per side",
        ),
        (
            r#"(version: 1, volume: Analytic((field: Hurricane, size: (8, 8, 8))))"#,
            "Hurricane",
        ),
        (
            r#"(version: 1, volume: Phantom((size: (8, 8, 8), boxes: [(from: (0, 0, 0), to: (4, 4, 9), value: 1.0)])))"#,
            "volume: phantom box 0: from [0, 0, 0] to [4, 4, 9] must be non-empty and inside the size [8, 8, 8]",
        ),
        (
            r#"(version: 1, volume: Phantom((size: (8, 8, 100000))))"#,
            "volume: a phantom's size must be 2–512 voxels per side",
        ),
        (
            r#"(version: 1, volume: Phantom((size: (8, 8, 8), colour: 1.0)))"#,
            "colour",
        ),
        (
            r#"(version: 1, volume: Resampled((source: Sample("ct_head"), size: (512, 512, 2000))))"#,
            "volume: a resampled volume's size must be 2–1024 voxels per side, got [512, 512, 2000]",
        ),
        (
            r#"(version: 1, volume: Resampled((source: Sample("ct_hed"), size: (8, 8, 8))))"#,
            "volume: unknown sample 'ct_hed'",
        ),
        (
            r#"(version: 1, volumes: {"wind": Sample("storm_wnd")})"#,
            "volumes.wind: unknown sample 'storm_wnd'",
        ),
        (
            r#"(version: 1, volumes: {"2wind": Sample("storm_wind")})"#,
            "volumes.2wind: a volume's name is letters, digits and _",
        ),
        (
            r#"(version: 1, volumes: {"wind": Analytic((field: Abc, size: (8, 8, 1)))})"#,
            "volumes.wind: an analytic field's size",
        ),
        (
            r#"(version: 1, volumes: {"wind": Sample("storm_wind")}, plugins: [(id: "flow.lic3d", params: {"field": "gust"})])"#,
            "plugins[0] flow.lic3d.field: there is no volume named 'gust' in `volumes:` (it has wind)",
        ),
        (
            r#"(version: 1, plugins: [(id: "flow.lic3d", params: {"field": "wind"})])"#,
            "flow.lic3d.field: there is no volume named 'wind' in `volumes:` (it has none)",
        ),
        (
            r#"(version: 1, plugins: [(id: "flow.lic3d", params: {"field": 3})])"#,
            "expected the name of one of the preset's volumes",
        ),
    ];
    for (text, want) in cases {
        let err = Document::parse(text, "bad.ron", &reg).unwrap_err();
        let msg = err.to_string();
        assert!(msg.starts_with("bad.ron: "), "{msg}");
        assert!(msg.contains(want), "expected '{want}' in: {msg}");
    }
    // syntax errors name the file and position
    let err = Document::parse("(version: 1, plugins: [", "syntax.ron", &reg).unwrap_err();
    assert!(matches!(err, PresetError::Syntax { .. }));
    assert!(err.to_string().starts_with("syntax.ron: 1:"), "{err}");
}

#[test]
fn saves_are_atomic() {
    let dir = std::env::temp_dir().join(format!("vwb-atomic-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("p.ron");
    std::fs::write(&path, "old").unwrap();
    write_atomic(&path, b"new").unwrap();
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
    // a failing save (the target is a directory) leaves no temporary file behind
    let target_dir = dir.join("taken");
    std::fs::create_dir_all(target_dir.join("inner")).unwrap();
    assert!(write_atomic(&target_dir, b"x").is_err());
    assert!(
        target_dir.join("inner").is_dir(),
        "the old content survives"
    );
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty());
    std::fs::remove_dir_all(&dir).ok();
}

/// A named volume resampled from a file is watched like the file itself: edited on
/// disk, it is reported changed ([`vwb_lab::headless::changed_named_volumes`], what the
/// window checks once a second) and loaded again, resampled again. Outputs may not
/// overwrite it either.
#[test]
fn a_resampled_file_is_watched_and_protected_like_the_file() {
    use vwb_lab::headless::{changed_named_volumes, inputs_for};
    use vwb_render::preset::Resampled;
    let file = tmp("resampled_source.nrrd");
    let write = |value: u8, secs: u64| {
        let mut bytes =
            b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n".to_vec();
        bytes.extend((0..64u8).map(|i| if i == 0 { 0 } else { value }));
        std::fs::write(&file, bytes).unwrap();
        std::fs::File::options()
            .write(true)
            .open(&file)
            .unwrap()
            .set_modified(std::time::UNIX_EPOCH + std::time::Duration::from_secs(secs))
            .unwrap();
    };
    write(10, 2_000_000);
    let mut doc = Document::load(&repo().join("presets/demo.ron"), &registry())
        .unwrap()
        .document;
    doc.volumes.insert(
        "fine".into(),
        VolumeSource::Resampled(Resampled {
            source: Box::new(VolumeSource::File(file.clone())),
            size: [8, 8, 8],
        }),
    );
    let first = inputs_for(&doc).unwrap();
    let v1 = first.get("fine").unwrap().clone();
    assert_eq!(v1.dims, [8, 8, 8]);
    assert!(
        changed_named_volumes(&doc).is_empty(),
        "nothing changed yet"
    );
    write(200, 2_000_010);
    let changed = changed_named_volumes(&doc);
    assert_eq!(changed.len(), 1, "{changed:?}");
    assert_eq!(changed[0].0, "fine");
    let again = inputs_for(&doc).unwrap();
    let v2 = again.get("fine").unwrap();
    assert!(!std::sync::Arc::ptr_eq(&v1, v2), "loaded again");
    assert_eq!(v2.dims, [8, 8, 8]);
    assert_ne!(v1.range, v2.range, "the new file's values");
    assert!(changed_named_volumes(&doc).is_empty());
    // an output may not overwrite the file under the resampling
    vwb_lab::outputs::protect_document(None, &doc);
    let err = vwb_lab::outputs::check_output(&file)
        .unwrap_err()
        .to_string();
    assert!(err.contains("resampled_source.nrrd"), "{err}");
}
