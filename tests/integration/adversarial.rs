//! Adversarial inputs (docs/reliability.md): outputs that name an input, presets saved
//! and reopened from other folders, cameras and spacings that gave flat or black
//! frames, degenerate volumes, corrupt gzip, pipes and FIFOs, misleading option errors,
//! memory limits. Every case here failed or misbehaved before issue 22.

use std::borrow::BorrowMut;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::common::*;
use vwb_render::files::{absolute, relative_to};
use vwb_render::preset::{Document, VolumeSource};

fn vwb() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_vwb"));
    c.current_dir(repo());
    c
}

/// `vwb` with these arguments.
fn cmd(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Command {
    let mut c = vwb();
    c.args(args.iter().map(|a| a.as_ref()));
    c
}

/// `vwb render --size 16x16` with these arguments.
fn render_16(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Command {
    let mut c = cmd(&[&"render", &"--size", &"16x16"]);
    c.args(args.iter().map(|a| a.as_ref()));
    c
}

/// `vwb scene` of the demo preset on another volume (no GPU needed).
fn scene_on(volume: &Path) -> Command {
    cmd(&[
        &"scene",
        &"--preset",
        &"presets/demo.ron",
        &"--volume",
        &volume,
    ])
}

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    let d = tmp(&format!("adv-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs a command, killing it (and failing) if it has not ended within 60 s.
fn run(c: &mut Command) -> Output {
    let mut child = c
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return child.wait_with_output().unwrap();
        }
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("{c:?} hung for 60 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Stderr of a run that must fail cleanly (non-zero, no panic).
fn fails(mut c: impl BorrowMut<Command>) -> String {
    let o = run(c.borrow_mut());
    let stderr = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!o.status.success(), "succeeded: {stderr}");
    assert_ne!(o.status.code(), Some(101), "panicked: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

/// Stderr of a run that must succeed.
fn succeeds(mut c: impl BorrowMut<Command>) -> String {
    let o = run(c.borrow_mut());
    let stderr = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "failed: {stderr}");
    stderr
}

/// An attached NRRD (uint8 or float) of the given dims and samples.
fn nrrd_u8(dims: [u32; 3], data: &[u8]) -> Vec<u8> {
    let mut b = format!(
        "NRRD0004\ntype: uint8\ndimension: 3\nsizes: {} {} {}\nencoding: raw\n\n",
        dims[0], dims[1], dims[2]
    )
    .into_bytes();
    b.extend_from_slice(data);
    b
}

fn nrrd_f32(dims: [u32; 3], data: &[f32]) -> Vec<u8> {
    let mut b = format!(
        "NRRD0004\ntype: float\ndimension: 3\nsizes: {} {} {}\nendian: little\nencoding: raw\n\n",
        dims[0], dims[1], dims[2]
    )
    .into_bytes();
    for v in data {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

/// CRC-32 (IEEE), bit by bit.
fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A gzip stream holding `data` in one stored (uncompressed) deflate block, with the
/// right CRC or a wrong one.
fn gzip_stored(data: &[u8], good_crc: bool) -> Vec<u8> {
    let len = data.len() as u16;
    let mut b = vec![0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 0xff, 0x01];
    b.extend_from_slice(&len.to_le_bytes());
    b.extend_from_slice(&(!len).to_le_bytes());
    b.extend_from_slice(data);
    let crc = crc32(data) ^ if good_crc { 0 } else { 0x5555_5555 };
    b.extend_from_slice(&crc.to_le_bytes());
    b.extend_from_slice(&(data.len() as u32).to_le_bytes());
    b
}

/// A 8³ volume with a bright ball (structure for suggest-tf).
fn ball() -> Vec<u8> {
    let mut v = Vec::new();
    for z in 0..8i32 {
        for y in 0..8i32 {
            for x in 0..8i32 {
                let r2 = (x - 4).pow(2) + (y - 4).pow(2) + (z - 4).pow(2);
                v.push(if r2 < 6 { 200 } else { 10 });
            }
        }
    }
    v
}

/// A detached header `vol.nhdr` with its data file `vol.raw` in `dir`.
fn detached(dir: &Path) -> (PathBuf, PathBuf) {
    let raw = dir.join("vol.raw");
    std::fs::write(&raw, ball()).unwrap();
    let nhdr = dir.join("vol.nhdr");
    std::fs::write(
        &nhdr,
        "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 8 8 8\nencoding: raw\ndata file: vol.raw\n",
    )
    .unwrap();
    (nhdr, raw)
}

#[test]
fn outputs_never_overwrite_inputs() {
    let d = scratch("outputs");
    let preset = d.join("p.ron");
    std::fs::copy(repo().join("presets/demo.ron"), &preset).unwrap();
    let before = std::fs::read(&preset).unwrap();
    let (nhdr, raw) = detached(&d);
    let raw_before = std::fs::read(&raw).unwrap();

    // the preset itself, through a symbolic link with an image name
    let link = d.join("out.png");
    std::os::unix::fs::symlink(&preset, &link).unwrap();
    let e = fails(render_16(&[&"--preset", &preset, &"-o", &link]));
    assert!(
        e.contains("refusing to overwrite the preset") && e.contains("p.ron"),
        "{e}"
    );
    // bench -o the preset: refused for its extension, and through a .csv link for
    // being the preset
    fails(cmd(&[&"bench", &"--preset", &preset, &"-o", &preset]));
    let csv = d.join("out.csv");
    std::os::unix::fs::symlink(&preset, &csv).unwrap();
    let e = fails(cmd(&[&"bench", &"--preset", &preset, &"-o", &csv]));
    assert!(e.contains("refusing to overwrite the preset"), "{e}");
    // suggest-tf -o (a link to) the detached header's data file, and the header
    for (i, target) in [&raw, &nhdr].into_iter().enumerate() {
        let out = d.join(format!("tf{i}.ron"));
        std::os::unix::fs::symlink(target, &out).unwrap();
        let e = fails(cmd(&[&"suggest-tf", &"--volume", &nhdr, &"-o", &out]));
        assert!(e.contains("refusing to overwrite the volume"), "{e}");
    }
    // a hard link to the data file given as the render volume
    let hard = d.join("hard.png");
    std::fs::hard_link(&raw, &hard).unwrap();
    let e = fails(render_16(&[
        &"--preset",
        &preset,
        &"--volume",
        &nhdr,
        &"-o",
        &hard,
    ]));
    assert!(
        e.contains("volume's data file") && e.contains("vol.raw"),
        "{e}"
    );
    // the image format comes from the extension; unknown ones are refused
    let e = fails(render_16(&[
        &"--preset",
        &"presets/demo.ron",
        &"-o",
        &d.join("x.tiff"),
    ]));
    assert!(e.contains("cannot write .tiff images"), "{e}");
    // text outputs too: bench writes CSV, suggest-tf RON
    let e = fails(cmd(&[
        &"bench",
        &"--preset",
        &"presets/demo.ron",
        &"-o",
        &d.join("b.png"),
    ]));
    assert!(e.contains("writes CSV"), "{e}");
    let e = fails(cmd(&[&"suggest-tf", &"-o", &d.join("tf.png")]));
    assert!(e.contains("name the output .ron"), "{e}");
    // a named volume (a label preset's label volume), through a link
    std::fs::create_dir_all(d.join("data")).unwrap();
    let seg = d.join("data/demo_labels.nrrd");
    std::fs::copy(repo().join("presets/data/demo_labels.nrrd"), &seg).unwrap();
    let seg_before = std::fs::read(&seg).unwrap();
    let labels_preset = d.join("labels.ron");
    std::fs::copy(repo().join("presets/demo_labels.ron"), &labels_preset).unwrap();
    let out = d.join("seg.png");
    std::os::unix::fs::symlink(&seg, &out).unwrap();
    let e = fails(render_16(&[&"--preset", &labels_preset, &"-o", &out]));
    assert!(e.contains("refusing to overwrite the volume"), "{e}");
    assert_eq!(std::fs::read(&seg).unwrap(), seg_before);
    assert_eq!(std::fs::read(&preset).unwrap(), before);
    assert_eq!(std::fs::read(&raw).unwrap(), raw_before);
}

#[test]
fn jpg_outputs_hold_jpeg_bytes() {
    let d = scratch("jpg");
    let out = d.join("x.jpg");
    succeeds(cmd(&[
        &"render",
        &"--preset",
        &"presets/demo.ron",
        &"--size",
        &"32x32",
        &"-o",
        &out,
    ]));
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(&bytes[..3], &[0xFF, 0xD8, 0xFF], "not a JPEG");
}

/// Opens a preset by a relative path, saves it by a relative path in another folder
/// (as the window's *Save preset* does), reopens it: the same files.
#[test]
fn presets_saved_elsewhere_reopen_with_the_same_files() {
    let reg = registry();
    let d = scratch("reopen");
    let cwd = std::env::current_dir().unwrap();
    let rel_dir = relative_to(&d, &cwd).unwrap();
    assert!(rel_dir.is_relative());
    let same_doc = |a: &Document, b: &Document| {
        let vol = |d: &Document| match &d.volume {
            VolumeSource::File(p) => Some(absolute(p)),
            _ => None,
        };
        assert_eq!(vol(a), vol(b));
        let named = |d: &Document| {
            d.volumes
                .iter()
                .map(|(n, s)| match s {
                    VolumeSource::File(p) => format!("{n}: {}", absolute(p).display()),
                    other => format!("{n}: {other:?}"),
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(named(a), named(b));
        let paths = |d: &Document| {
            d.stack
                .iter()
                .flat_map(|i| i.params.values.values().cloned())
                .map(|v| match v {
                    vwb_render::params::ParamValue::Path(p) => absolute(&p).display().to_string(),
                    other => format!("{other:?}"),
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(paths(a), paths(b));
        assert_eq!(a.camera, b.camera);
        assert_eq!(a.render, b.render);
    };
    for preset in ["presets/ct_head.ron", "presets/demo_labels.ron"] {
        let opened = Document::load(Path::new(preset), &reg).unwrap().document;
        // the label preset names its label volume
        assert_eq!(
            opened.volumes.len(),
            usize::from(preset.ends_with("labels.ron"))
        );
        let saved = rel_dir.join("sub").join("saved.ron");
        std::fs::create_dir_all(saved.parent().unwrap()).unwrap();
        opened.save(&saved).unwrap();
        let reopened = Document::load(&saved, &reg).unwrap().document;
        same_doc(&opened, &reopened);
        // and once more from there, by an absolute path
        let again = d.join("again.ron");
        reopened.save(&again).unwrap();
        same_doc(&opened, &Document::load(&again, &reg).unwrap().document);
    }
    // the saved text holds paths relative to the preset's folder
    let text = std::fs::read_to_string(rel_dir.join("sub/saved.ron")).unwrap();
    let labels = relative_to(
        &repo().join("presets/data/demo_labels.nrrd"),
        &d.join("sub"),
    );
    assert!(
        text.contains(&labels.unwrap().display().to_string()),
        "{text}"
    );
}

#[test]
fn saving_keeps_the_mode_and_the_link() {
    use std::os::unix::fs::PermissionsExt;
    let d = scratch("mode");
    let real = d.join("real.ron");
    std::fs::copy(repo().join("presets/demo.ron"), &real).unwrap();
    std::fs::set_permissions(&real, std::fs::Permissions::from_mode(0o600)).unwrap();
    let link = d.join("link.ron");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let doc = Document::load(&link, &registry()).unwrap().document;
    doc.save(&link).unwrap();
    assert!(std::fs::symlink_metadata(&link).unwrap().is_symlink());
    let mode = std::fs::metadata(&real).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600);
    Document::load(&real, &registry()).unwrap();
}

#[test]
fn bad_cameras_name_the_file_and_the_field() {
    let reg = registry();
    let cases = [
        ("Perspective(fov_y_deg: 0.0)", "camera.projection.fov_y_deg"),
        (
            "Perspective(fov_y_deg: -20.0)",
            "camera.projection.fov_y_deg",
        ),
        (
            "Perspective(fov_y_deg: 180.0)",
            "camera.projection.fov_y_deg",
        ),
        ("Perspective(fov_y_deg: NaN)", "camera.projection.fov_y_deg"),
        ("Orthographic(height: 0.0)", "camera.projection.height"),
        ("Orthographic(height: NaN)", "camera.projection.height"),
    ];
    for (projection, field) in cases {
        let text = format!("(version: 1, camera: (projection: {projection}))");
        let e = Document::parse(&text, "cam.ron", &reg)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("cam.ron: ") && e.contains(field), "{e}");
    }
    let e = Document::parse("(version: 1, camera: (roll_deg: NaN))", "r.ron", &reg)
        .unwrap_err()
        .to_string();
    assert!(e.contains("r.ron") && e.contains("camera.roll_deg"), "{e}");
    // the renderer refuses them too (the window shows its error)
    let mut r = vwb_render::Renderer::new(gpu(), demo()).unwrap();
    let mut s = settings(16, 16, vwb_render::Backend::Raster);
    s.camera.projection = vwb_render::Projection::Perspective { fov_y_deg: 0.0 };
    let e = r.render(&s).unwrap_err().to_string();
    assert!(e.contains("fov_y_deg"), "{e}");
}

#[test]
fn spacings_name_the_file_and_the_cause() {
    let d = scratch("spacing");
    // a header spacing of 1e-30, and one whose spacings differ by 1e6
    for (spacings, cause) in [("1e-30 1 1", "1e-12..=1e12"), ("1e-6 1 1", "times longer")] {
        let vol = d.join("thin.nrrd");
        let mut b = format!(
            "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nspacings: {spacings}\nencoding: raw\n\n"
        )
        .into_bytes();
        b.extend_from_slice(&[0, 1, 2, 3, 4, 5, 6, 7]);
        std::fs::write(&vol, b).unwrap();
        let e = fails(scene_on(&vol));
        assert!(
            e.contains("thin.nrrd") && e.contains("spacings") && e.contains(cause),
            "{e}"
        );
        assert!(!e.contains("18446744073709551615"), "{e}");
    }
    // a preset spacing of 1e-9 voxels
    let p = d.join("fine.ron");
    std::fs::write(&p, "(version: 1, render: (slice_spacing: 1e-9))").unwrap();
    let e = fails(cmd(&[&"scene", &"--preset", &p]));
    assert!(
        e.contains("fine.ron") && e.contains("render.slice_spacing") && e.contains("slices"),
        "{e}"
    );
    // the window refuses to open it, naming the file and the field
    let mut h = crate::window::window(vwb_app::window::default_document(&registry()), 0.25);
    let e = format!("{:#}", h.state_mut().open(&p).unwrap_err());
    assert!(
        e.contains("fine.ron") && e.contains("render.slice_spacing"),
        "{e}"
    );
}

#[test]
fn a_coarse_eye_buffer_is_warned_about() {
    let demo_at = |spacing: &str| {
        cmd(&[
            &"scene",
            &"--preset",
            &"presets/demo.ron",
            &"--spacing",
            &spacing,
        ])
    };
    let e = succeeds(demo_at("0.002"));
    assert!(
        e.contains("warning") && e.contains("rgba16float") && e.contains("rgba32float"),
        "{e}"
    );
    let e = succeeds(demo_at("0.002").args(["--target", "rgba32float"]));
    assert!(!e.contains("rgba16float"), "{e}");
    // the shipped demo at its own spacing stays quiet
    let e = succeeds(cmd(&[&"scene", &"--preset", &"presets/demo.ron"]));
    assert!(!e.contains("warning"), "{e}");
}

#[test]
fn degenerate_volumes_are_warned_about_and_suggest_tf_says_so() {
    let d = scratch("degenerate");
    let constant = d.join("constant.nrrd");
    std::fs::write(&constant, nrrd_u8([4, 4, 4], &[7; 64])).unwrap();
    let zeros = d.join("zeros.nrrd");
    std::fs::write(&zeros, nrrd_u8([4, 4, 4], &[0; 64])).unwrap();
    let nan = d.join("nan.nrrd");
    std::fs::write(&nan, nrrd_f32([4, 4, 4], &[f32::NAN; 64])).unwrap();
    let one = d.join("one.nrrd");
    std::fs::write(&one, nrrd_u8([1, 1, 1], &[9])).unwrap();
    for (v, want) in [
        (&constant, "same value 7"),
        (&zeros, "same value 0"),
        (&nan, "NaN"),
        (&one, "degenerate"),
    ] {
        let e = succeeds(scene_on(v));
        assert!(e.contains("warning") && e.contains(want), "{v:?}: {e}");
        let out = d.join("tf.ron");
        let e = fails(cmd(&[&"suggest-tf", &"--volume", v, &"-o", &out]));
        assert!(e.contains("degenerate"), "{v:?}: {e}");
        assert!(!e.contains("most opaque value"), "{e}");
        assert!(!out.exists());
    }
    let e = headless_warnings(&one);
    assert!(e.iter().any(|w| w.contains("single voxel")), "{e:?}");
}

fn headless_warnings(volume: &Path) -> Vec<String> {
    let doc = vwb_app::cli::load_document(None).unwrap();
    let v = vwb_lab::headless::load_volume_file(volume).unwrap();
    vwb_lab::headless::frame_warnings(&doc, &v)
}

#[test]
fn corrupt_gzip_is_blamed_on_the_gzip_data() {
    let d = scratch("gzip");
    // decompresses to more than the header needs, and its CRC is wrong
    let gz = gzip_stored(&[5u8; 200], false);
    let mut b = b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: gzip\n\n".to_vec();
    b.extend_from_slice(&gz);
    let path = d.join("bad.nrrd");
    std::fs::write(&path, b).unwrap();
    let e = fails(scene_on(&path));
    assert!(
        e.contains("bad.nrrd") && e.contains("gzip data is corrupt"),
        "{e}"
    );
    assert!(!e.contains("probably wrong"), "{e}");
}

#[test]
fn pipes_are_read_once_and_fifos_never_hang() {
    let d = scratch("fifo");
    let bytes = nrrd_u8([8, 8, 8], &ball());
    // a pipe on stdin, as `--volume <(cat x.nrrd)` gives
    let mut child = vwb()
        .args([
            "scene",
            "--preset",
            "presets/demo.ron",
            "--volume",
            "/dev/stdin",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || stdin.write_all(&bytes));
    let o = child.wait_with_output().unwrap();
    writer.join().unwrap().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(json.to_string().contains("[8,8,8]"), "{json}");
    // a FIFO nobody writes to, as the volume and as a detached data file
    let fifo = d.join("fifo.nrrd");
    let st = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(st.success());
    let e = fails(scene_on(&fifo));
    assert!(e.contains("fifo.nrrd") && e.contains("gave no data"), "{e}");
    let nhdr = d.join("h.nhdr");
    std::fs::write(
        &nhdr,
        "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: fifo.nrrd\n",
    )
    .unwrap();
    let e = fails(scene_on(&nhdr));
    assert!(
        e.contains("not a regular file") && e.contains("h.nhdr"),
        "{e}"
    );
}

#[test]
fn option_and_format_errors_say_what_is_wrong() {
    let d = scratch("options");
    for (opt, value) in [("--thickness", "0"), ("--max-opacity", "2")] {
        let e = fails(cmd(&[&"suggest-tf", &opt, &value, &"-o", &d.join("t.ron")]));
        assert!(e.contains(opt), "{e}");
        assert!(!e.contains("SuggestOptions {"), "Debug dump: {e}");
    }
    // NIfTI: named as such, no Rust function in the advice
    let mut nii = vec![0u8; 352];
    nii[0..4].copy_from_slice(&348i32.to_le_bytes());
    nii[344..348].copy_from_slice(b"n+1\0");
    let path = d.join("brain.nii");
    std::fs::write(&path, nii).unwrap();
    let e = fails(scene_on(&path));
    assert!(e.contains("brain.nii") && e.contains("NIfTI"), "{e}");
    assert!(!e.contains("load_raw"), "{e}");
    // --frames 0 is refused, not silently 1
    for command in ["render", "bench", "compare"] {
        let mut c = cmd(&[
            &command,
            &"--preset",
            &"presets/demo.ron",
            &"--frames",
            &"0",
        ]);
        let e = fails(c.arg("-o").arg(d.join("f.png")));
        assert!(e.contains("--frames"), "{command}: {e}");
    }
}

#[test]
fn memory_limits_fail_cleanly() {
    let d = scratch("memory");
    let path = d.join("big.nrrd");
    std::fs::write(&path, nrrd_u8([64, 64, 64], &vec![1u8; 64 * 64 * 64])).unwrap();
    let mut c = scene_on(&path);
    c.env("VWB_MEMORY_LIMIT", "100000");
    let e = fails(c);
    assert!(e.contains("big.nrrd") && e.contains("available"), "{e}");
    // suggest-tf's working memory is checked before it is allocated
    let small = d.join("small.nrrd");
    let mut v = vec![0u8; 16 * 16 * 16];
    v.iter_mut()
        .enumerate()
        .for_each(|(i, x)| *x = (i % 7) as u8);
    std::fs::write(&small, nrrd_u8([16, 16, 16], &v)).unwrap();
    let mut c = cmd(&[&"suggest-tf", &"--volume", &small, &"-o", &d.join("t.ron")]);
    c.env("VWB_MEMORY_LIMIT", "100000");
    let e = fails(c);
    assert!(e.contains("working memory"), "{e}");
}

#[test]
fn a_failing_start_up_opens_the_demo_with_the_error() {
    use clap::Parser;
    // no arguments: the first image, the demo pre-integrated and lit at the slab
    // centroid (presets/first_image.ron)
    let cli = vwb_app::cli::Cli::parse_from(["vwb"]);
    let (first, volume, error) = vwb_app::window::startup(&cli).unwrap();
    assert!(error.is_none(), "{error:?}");
    assert_eq!(volume.name, "demo");
    let ids: Vec<&str> = first.stack.iter().map(|i| i.plugin.id()).collect();
    assert_eq!(ids, ["classify.tf1d", "shade.blinn_phong"]);
    assert_eq!(first.stack[0].params.enumeration("mode"), "preintegrated");
    assert_eq!(first.stack[0].params.enumeration("shade_at"), "centroid");
    // … at half a voxel per slice on CPU adapters, a quarter on GPUs
    use vwb_app::window::first_image_spacing;
    assert_eq!(first.render.slice_spacing, 0.5);
    assert_eq!(first_image_spacing(wgpu::DeviceType::Cpu, 0.5), 0.5);
    assert_eq!(
        first_image_spacing(wgpu::DeviceType::DiscreteGpu, 0.5),
        0.25
    );
    assert_eq!(
        first_image_spacing(wgpu::DeviceType::IntegratedGpu, 0.1),
        0.1
    );
    let cli = vwb_app::cli::Cli::parse_from(["vwb", "--preset", "presets/missing.ron"]);
    let (doc, volume, error) = vwb_app::window::startup(&cli).unwrap();
    assert_eq!(doc.volume, VolumeSource::Demo);
    assert_eq!(volume.name, "demo");
    // the scene shown instead of a preset that failed is the first image too
    assert_eq!(doc.stack.len(), first.stack.len());
    let error = error.unwrap();
    assert!(error.contains("presets/missing.ron"), "{error}");
    // the window may save over the preset it opened (its volume stays protected)
    let d = scratch("startup");
    let p = d.join("p.ron");
    std::fs::copy(repo().join("presets/demo.ron"), &p).unwrap();
    let cli = vwb_app::cli::Cli::parse_from(["vwb".as_ref(), "--preset".as_ref(), p.as_os_str()]);
    let (doc, _, error) = vwb_app::window::startup(&cli).unwrap();
    assert!(error.is_none());
    doc.save(&p).unwrap();
    // a screenshot run still fails, so scripts notice
    let cli = vwb_app::cli::Cli::parse_from([
        "vwb",
        "--preset",
        "presets/missing.ron",
        "--screenshot",
        "x.png",
    ]);
    assert!(vwb_app::window::startup(&cli).is_err());
}

/// [`ball`] compressed with deflate (Python's `gzip.compress(…, 9, mtime=0)`), so that
/// flips in the compressed stream exercise the decoder, not only the checksum.
const GZIP_BALL: [u8; 53] = [
    0x1f, 0x8b, 0x08, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x03, 0xe3, 0xe2, 0x1a, 0xbc, 0xe0, 0x04,
    0x94, 0x3a, 0x71, 0x02, 0x85, 0x4f, 0xa2, 0xbe, 0x13, 0x27, 0x10, 0x0c, 0xa2, 0xcc, 0x41, 0xd3,
    0x87, 0x4e, 0x23, 0xcc, 0xa1, 0x91, 0xfd, 0x14, 0xfb, 0x9f, 0x14, 0x00, 0x00, 0x56, 0x1a, 0x5d,
    0xd1, 0x00, 0x02, 0x00, 0x00,
];

const GZIP_HEADER: &[u8] = b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 8 8 8\nencoding: gzip\n\n";

/// Bit flips, truncations and splices of valid volume files (NRRD, NIfTI, MetaImage,
/// DICOM), presets and mesh files (OBJ, PLY, STL): never a panic, every error names its file. A quick smoke here; `VWB_FUZZ_CASES=N cargo test
/// --test integration adversarial::fuzz -- --ignored --nocapture` runs more
/// (docs/reliability.md).
fn fuzz_run(cases: usize) -> FuzzCounts {
    let d = scratch("fuzz");
    let reg = registry();
    let mut rng = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        rng
    };
    let seeds_nrrd = [
        nrrd_u8([8, 8, 8], &ball()),
        nrrd_f32(
            [3, 2, 2],
            &[
                0.0,
                1.0,
                f32::NAN,
                2.0,
                3.0,
                4.0,
                5.0,
                6.0,
                7.0,
                8.0,
                9.0,
                1.5,
            ],
        ),
        {
            let mut b = GZIP_HEADER.to_vec();
            b.extend(gzip_stored(&ball(), true));
            b
        },
        [GZIP_HEADER, &GZIP_BALL].concat(),
    ];
    let seeds_preset: Vec<Vec<u8>> = ["demo.ron", "demo_labels.ron", "ct_shade_phong.ron"]
        .iter()
        .map(|p| std::fs::read(repo().join("presets").join(p)).unwrap())
        .collect();
    // NIfTI-1 (.nii and .nii.gz) and MetaImage (.mha, raw and zlib) seeds of the same ball
    let nii = {
        let p = d.join("seed.nii");
        let ball16: Vec<i16> = ball().iter().map(|&v| v as i16).collect();
        let sform = [
            [-1.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0, 0.0],
        ];
        vwb_render::volume::nifti::write_nifti1(&p, [8, 8, 8], [1.0, 2.0, 1.5], sform, &ball16)
            .unwrap();
        std::fs::read(&p).unwrap()
    };
    let nii_gz = {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        e.write_all(&nii).unwrap();
        e.finish().unwrap()
    };
    let mha_header = "ObjectType = Image\nNDims = 3\nDimSize = 8 8 8\nElementType = MET_UCHAR\n\
                      ElementSpacing = 1 1 2\nTransformMatrix = 0 1 0 1 0 0 0 0 1\n";
    let mha = [
        format!("{mha_header}ElementDataFile = LOCAL\n").into_bytes(),
        ball(),
    ]
    .concat();
    let mha_z = {
        use std::io::Write;
        let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
        e.write_all(&ball()).unwrap();
        [
            format!("{mha_header}CompressedData = True\nElementDataFile = LOCAL\n").into_bytes(),
            e.finish().unwrap(),
        ]
        .concat()
    };
    // clip.mesh's files: a small closed box as OBJ, ASCII PLY and binary STL
    let meshes: Vec<(Vec<u8>, &str)> = ["case.obj", "case.ply", "case.stl"]
        .into_iter()
        .map(|name| {
            let p = d.join(format!("seed-{name}"));
            let cube = vwb_plugins::clip_mesh::mesh::cube().map_positions(|p| p * 0.3);
            vwb_plugins::clip_mesh::mesh::save(&cube, &p).unwrap();
            (std::fs::read(&p).unwrap(), name)
        })
        .collect();
    // DICOM: an 8×8 slice, uncompressed and RLE, and a 2-frame enhanced file
    let dicom: Vec<Vec<u8>> = {
        use vwb_render::volume::dicom::{SliceSpec, write_slice};
        let seeds = d.join("dicom-seeds");
        std::fs::create_dir_all(&seeds).unwrap();
        let ball: Vec<i32> = ball().iter().map(|&v| i32::from(v) - 20).collect();
        let specs = [
            SliceSpec {
                rows: 8,
                cols: 8,
                samples: &ball[..64],
                positions: &[[0.0, 0.0, 1.0]],
                rescale: (1.0, -1024.0),
                ..SliceSpec::default()
            },
            SliceSpec {
                rows: 8,
                cols: 8,
                samples: &ball[64..128],
                positions: &[[0.0, 0.0, 1.0]],
                rle: true,
                ..SliceSpec::default()
            },
            SliceSpec {
                rows: 8,
                cols: 8,
                frames: 2,
                samples: &ball[..128],
                positions: &[[0.0, 0.0, 2.0], [0.0, 0.0, 0.5]],
                rescale: (0.5, 3.0),
                ..SliceSpec::default()
            },
        ];
        specs
            .iter()
            .enumerate()
            .map(|(i, spec)| {
                let p = seeds.join(format!("seed{i}.dcm"));
                write_slice(&p, spec).unwrap();
                std::fs::read(&p).unwrap()
            })
            .collect()
    };
    // OME-Zarr: a two-level Zarr v3 store (gzip, vwb's writer) and a Zarr v2 store
    // written by hand (uncompressed); a case mutates one file of a store
    let zarr: Vec<Vec<(std::path::PathBuf, Vec<u8>)>> = {
        use vwb_render::volume::{VoxelData, zarr};
        let v =
            vwb_render::Volume::new("ball", [8, 8, 8], 1, [1.0; 3], VoxelData::U8(ball())).unwrap();
        let half = vwb_render::renderer::halve(&v).unwrap();
        let v3 = d.join("zarr-seed-v3");
        zarr::write(&v3, &[&v, &half]).unwrap();
        let v2 = d.join("zarr-seed-v2");
        std::fs::create_dir_all(v2.join("0/0/0")).unwrap();
        std::fs::write(v2.join(".zgroup"), r#"{"zarr_format": 2}"#).unwrap();
        std::fs::write(
            v2.join(".zattrs"),
            r#"{"multiscales": [{"version": "0.4", "axes": [{"name": "z", "type": "space"},
            {"name": "y", "type": "space"}, {"name": "x", "type": "space"}], "datasets":
            [{"path": "0", "coordinateTransformations": [{"type": "scale", "scale": [2, 1, 1]}]}]}]}"#,
        )
        .unwrap();
        std::fs::write(
            v2.join("0/.zarray"),
            r#"{"zarr_format": 2, "shape": [8, 8, 8], "chunks": [8, 8, 8], "dtype": "|u1",
            "compressor": null, "fill_value": 0, "order": "C", "filters": null,
            "dimension_separator": "/"}"#,
        )
        .unwrap();
        std::fs::write(v2.join("0/0/0/0"), ball()).unwrap();
        [v3, v2]
            .iter()
            .map(|root| {
                zarr::files(root)
                    .into_iter()
                    .map(|f| {
                        let bytes = std::fs::read(&f).unwrap();
                        (f.strip_prefix(root).unwrap().to_path_buf(), bytes)
                    })
                    .collect()
            })
            .collect()
    };
    // VWB_FUZZ_ONLY=DICOM (or another name of FORMATS) fuzzes one format
    let only = std::env::var("VWB_FUZZ_ONLY").ok();
    let kinds: Vec<usize> = (0..FORMATS.len())
        .filter(|&k| {
            only.as_deref()
                .is_none_or(|o| o.eq_ignore_ascii_case(FORMATS[k]))
        })
        .collect();
    assert!(!kinds.is_empty(), "VWB_FUZZ_ONLY names none of {FORMATS:?}");
    let mut counts = FuzzCounts::default();
    for i in 0..cases {
        // NRRD, preset, NIfTI, MetaImage, mesh, DICOM, OME-Zarr in turn
        let kind = kinds[i % kinds.len()];
        let nrrd = kind != 1 && kind != 4;
        // OME-Zarr: the store and which of its files this case mutates
        let (store, mutated) = if kind == 6 {
            let store = &zarr[(next() % 2) as usize];
            (store, (next() as usize) % store.len())
        } else {
            (&zarr[0], 0)
        };
        let (seed, name) = match kind {
            6 => (&store[mutated].1, "case.zarr"),
            0 => (&seeds_nrrd[(next() % 4) as usize], "case.nrrd"),
            1 => (&seeds_preset[(next() % 3) as usize], "case.ron"),
            2 if next() % 2 == 0 => (&nii, "case.nii"),
            2 => (&nii_gz, "case.nii.gz"),
            3 if next() % 2 == 0 => (&mha, "case.mha"),
            3 => (&mha_z, "case.mha"),
            5 => (&dicom[(next() % 3) as usize], "case.dcm"),
            _ => {
                let (b, n) = &meshes[(next() % 3) as usize];
                (b, *n)
            }
        };
        let mut b = seed.clone();
        match next() % 4 {
            0 => {
                let flips = 1 + next() % 8;
                for _ in 0..flips {
                    let at = (next() as usize) % b.len();
                    b[at] ^= 1 << (next() % 8);
                }
            }
            1 => b.truncate((next() as usize) % b.len()),
            2 => {
                let at = (next() as usize) % b.len();
                let digits = b"0123456789-.eN ";
                b[at] = digits[(next() as usize) % digits.len()];
            }
            _ => {
                let a = (next() as usize) % b.len();
                let len = (next() as usize) % 16;
                let copy: Vec<u8> = b[a..(a + len).min(b.len())].to_vec();
                let at = (next() as usize) % b.len();
                b.splice(at..at, copy);
            }
        }
        let path = d.join(name);
        if kind == 6 {
            let _ = std::fs::remove_dir_all(&path);
            for (k, (rel, bytes)) in store.iter().enumerate() {
                let f = path.join(rel);
                std::fs::create_dir_all(f.parent().unwrap()).unwrap();
                std::fs::write(&f, if k == mutated { &b } else { bytes }).unwrap();
            }
        } else {
            std::fs::write(&path, &b).unwrap();
        }
        let t_case = Instant::now();
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            if kind == 4 {
                use vwb_plugins::clip_mesh::mesh;
                mesh::load(&path).and_then(|mut m| m.check(&path.display().to_string()).map(|_| ()))
            } else if nrrd {
                vwb_render::volume::load(&path)
                    .map(|_| ())
                    .map_err(|e| e.to_string())
            } else {
                Document::load(&path, &reg)
                    .map(|_| ())
                    .map_err(|e| e.to_string())
            }
        }));
        // VWB_FUZZ_SLOW=1 keeps each case slower than 50 ms (in the temp directory)
        if std::env::var_os("VWB_FUZZ_SLOW").is_some() && t_case.elapsed().as_millis() > 50 {
            let keep = std::env::temp_dir().join(format!("slow-{i}-{name}"));
            if kind == 6 {
                let _ = std::fs::rename(&path, &keep);
            } else {
                std::fs::copy(&path, &keep).unwrap();
            }
            let error = match &outcome {
                Ok(Err(e)) => e.chars().take(150).collect::<String>(),
                Ok(Ok(())) => "loaded".to_string(),
                Err(_) => "panic".to_string(),
            };
            eprintln!(
                "slow case {i}: {} ms, {error} -> {}",
                t_case.elapsed().as_millis(),
                keep.display()
            );
        }
        counts.cases += 1;
        // long runs report as they go, so a run cut short still leaves its counts
        if cases >= 10_000 && counts.cases % (cases / 10) == 0 {
            eprintln!(
                "fuzz progress: {} of {cases} cases, {} loaded, {} errors, {} panics",
                counts.cases, counts.loaded, counts.errors, counts.panics
            );
        }
        let per = &mut counts.per_format[kind];
        per.0 += 1;
        match outcome {
            Err(_) => {
                counts.panics += 1;
                per.3 += 1;
            }
            Ok(Ok(())) => {
                counts.loaded += 1;
                per.1 += 1;
            }
            Ok(Err(e)) => {
                counts.errors += 1;
                per.2 += 1;
                // the header is untouched: blaming it for the gzip data is wrong
                if nrrd && b.starts_with(GZIP_HEADER) && e.contains("probably wrong") {
                    counts.header_blamed_for_gzip += 1;
                }
                if !e.contains(name) {
                    counts.unnamed.push(e);
                }
            }
        }
    }
    counts
}

/// The fuzzed formats, in the order of [`FuzzCounts::per_format`].
const FORMATS: [&str; 7] = [
    "NRRD",
    "preset",
    "NIfTI",
    "MetaImage",
    "mesh",
    "DICOM",
    "OME-Zarr",
];

#[derive(Debug, Default)]
struct FuzzCounts {
    /// (cases, loaded, errors, panics) for NRRD, presets, NIfTI, MetaImage, meshes, DICOM,
    /// OME-Zarr.
    per_format: [(usize, usize, usize, usize); 7],
    cases: usize,
    loaded: usize,
    errors: usize,
    panics: usize,
    header_blamed_for_gzip: usize,
    unnamed: Vec<String>,
}

#[test]
fn fuzz_smoke() {
    let c = fuzz_run(500);
    assert_eq!(c.panics, 0, "{c:?}");
    assert_eq!(c.header_blamed_for_gzip, 0, "{c:?}");
    assert!(
        c.unnamed.is_empty(),
        "errors without the file name: {:?}",
        c.unnamed
    );
    assert!(c.errors > 0 && c.loaded > 0, "{c:?}");
    for (cases, loaded, errors, _) in c.per_format {
        assert!(cases > 0 && loaded > 0 && errors > 0, "{:?}", c.per_format);
    }
}

#[test]
#[ignore = "long: run with --ignored for the counts in docs/reliability.md"]
fn fuzz() {
    let n = std::env::var("VWB_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5000);
    let c = fuzz_run(n);
    println!(
        "fuzz: {} cases, {} loaded, {} clear errors, {} panics, {} errors without the file \
         name, {} gzip errors blamed on an intact header",
        c.cases,
        c.loaded,
        c.errors,
        c.panics,
        c.unnamed.len(),
        c.header_blamed_for_gzip
    );
    for (name, (cases, loaded, errors, panics)) in FORMATS.iter().zip(c.per_format) {
        println!(
            "fuzz {name}: {cases} cases, {loaded} loaded, {errors} clear errors, {panics} panics"
        );
    }
    assert_eq!(c.panics, 0);
    assert_eq!(c.header_blamed_for_gzip, 0);
    assert!(c.unnamed.is_empty(), "{:?}", c.unnamed);
}

/// The window: open a preset by a relative path, press *Save preset*, reopen it (the
/// flow of issue 22, which failed with `…/…: cannot open`); a degenerate volume shows
/// its warning in the side panel.
#[test]
fn the_window_saves_presets_that_reopen_and_warns() {
    use egui_kittest::kittest::Queryable;
    let d = scratch("window");
    std::fs::write(d.join("flat.nrrd"), nrrd_u8([4, 4, 4], &[7; 64])).unwrap();
    std::fs::write(
        d.join("p.ron"),
        "(version: 1, volume: File(\"flat.nrrd\"), plugins: [(id: \"classify.tf1d\")])",
    )
    .unwrap();
    let rel = relative_to(&d.join("p.ron"), &std::env::current_dir().unwrap()).unwrap();
    let demo = vwb_app::window::default_document(&registry());
    let mut h = crate::window::window(demo, 0.25);
    h.state_mut().open(&rel).unwrap();
    h.run_steps(2);
    assert!(h.query_by_label_contains("is degenerate").is_some());
    crate::window::click(&mut h, "Save preset");
    assert!(
        matches!(h.state().file_status(), Some(Ok(m)) if m.starts_with("saved")),
        "{:?}",
        h.state().file_status()
    );
    h.state_mut().open(&rel).expect("the saved preset reopens");
    assert_eq!(h.state().renderer().volume().dims, [4, 4, 4]);
}

/// Steps the window until `done` or 10 s.
fn step_while(h: &mut egui_kittest::Harness<'_, vwb_app::window::Workbench>, busy: bool) {
    let start = Instant::now();
    while h.state().is_loading() == busy {
        assert!(start.elapsed() < Duration::from_secs(10), "timed out");
        h.step();
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Large volumes and streams load off the UI thread with a progress bar and Cancel: the
/// window keeps drawing while a stalled FIFO is read, and Cancel keeps the old volume.
#[test]
fn the_window_loads_volumes_in_the_background_and_cancels() {
    let d = scratch("background");
    let vol = d.join("ball.nrrd");
    std::fs::write(&vol, nrrd_u8([8, 8, 8], &ball())).unwrap();
    let demo = vwb_app::window::default_document(&registry());
    let mut h = crate::window::window(demo, 0.25);
    h.state_mut().async_load_bytes = 0;
    h.state_mut().start_open_volume(&vol);
    assert!(h.state().is_loading());
    step_while(&mut h, true);
    assert_eq!(h.state().renderer().volume().dims, [8, 8, 8]);
    assert!(
        matches!(h.state().file_status(), Some(Ok(m)) if m.starts_with("opened")),
        "{:?}",
        h.state().file_status()
    );
    // a preset whose volume is large enough loads it in the background too
    let preset = d.join("p.ron");
    std::fs::write(
        &preset,
        "(version: 1, volume: File(\"ball.nrrd\"), plugins: [(id: \"classify.tf1d\")])",
    )
    .unwrap();
    h.state_mut().start_open(&preset);
    assert!(h.state().is_loading());
    step_while(&mut h, true);
    assert!(
        matches!(h.state().file_status(), Some(Ok(m)) if m.starts_with("opened")),
        "{:?}",
        h.state().file_status()
    );
    assert!(matches!(h.state().document().volume, VolumeSource::File(_)));
    // a FIFO that gives its header and then stalls (opened read-write here, so it
    // has a writer before the window opens it)
    let fifo = d.join("stalled.nrrd");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let mut writer = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&fifo)
        .unwrap();
    writer
        .write_all(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 8 8 8\nencoding: raw\n\n")
        .unwrap();
    h.state_mut().start_open_volume(&fifo);
    for _ in 0..20 {
        h.step();
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(
        h.state().is_loading(),
        "the stalled stream is still loading"
    );
    crate::window::click(&mut h, "Cancel");
    assert!(!h.state().is_loading());
    assert!(
        matches!(h.state().file_status(), Some(Ok(m)) if m.starts_with("cancelled")),
        "{:?}",
        h.state().file_status()
    );
    assert_eq!(h.state().renderer().volume().dims, [8, 8, 8]);
    drop(writer);
}

/// Fuzz cases that made dicom-rs guess element lengths from the bytes after an unknown
/// value representation (up to 12 s and gigabytes of allocation per file, found by
/// `VWB_FUZZ_ONLY=DICOM`): each is refused before dicom-rs reads it, with the file and
/// the element named.
#[test]
fn dicom_files_with_unknown_value_representations_are_refused_early() {
    let dir = repo().join("tests/fixtures/dicom_slow");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(files.len() >= 5);
    for (i, f) in files.iter().enumerate() {
        // alone in a folder: a file's series siblings are read too
        let d = scratch(&format!("dicom-slow-{i}"));
        let path = d.join("case.dcm");
        std::fs::copy(f, &path).unwrap();
        let e = vwb_render::volume::load(&path).unwrap_err().to_string();
        assert!(
            e.contains("case.dcm") && e.contains("no valid value representation"),
            "{}: {e}",
            f.display()
        );
    }
}
