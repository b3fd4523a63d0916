//! The `vwb` binary: `render` of each shipped preset, `info`, failures with a message
//! naming the file and the cause and a non-zero exit, and VWB_SHADER_DUMP.

use std::process::Command;

use crate::common::*;
use crate::presets::shipped_presets;

fn vwb() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_vwb"));
    c.current_dir(repo()).env("VWB_DATA_DIR", data_dir());
    c
}

#[test]
fn render_writes_a_png_for_every_shipped_preset() {
    gpu();
    for preset in shipped_presets() {
        let stem = preset.file_stem().unwrap().to_string_lossy().to_string();
        let out = tmp(&format!("{stem}.png"));
        let o = vwb()
            .args(["render", "--preset"])
            .arg(&preset)
            .args(["--size", "96x80", "-o"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{stem}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        // piped: no spinner, no terminal control characters, just the lines
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !err.contains('\r') && !err.contains('\u{1b}'),
            "{stem}: progress drawn into a pipe: {err:?}"
        );
        assert!(err.contains("wrote "), "{err}");
        let img = image::open(&out).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (96, 80));
        let lit = img.pixels().filter(|p| p.0.iter().any(|&v| v > 40)).count();
        assert!(
            lit > 96 * 80 / 20,
            "{stem}: the head is visible ({lit} lit pixels)"
        );
    }
}

#[test]
fn render_timings_and_backend_override() {
    let out = tmp("t.png");
    let o = vwb()
        .args([
            "render",
            "--preset",
            "presets/demo.ron",
            "--size",
            "64x64",
            "--backend",
            "compute",
            "--timings",
            "--frames",
            "2",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("backend compute"), "{stdout}");
    assert!(stdout.contains("wall_ms median"), "{stdout}");
    // raster with early termination: 8 slices per polygon by default ("auto"), one
    // where `--slices-per-proxy 1` says so
    for (group, want) in [(None, Some(8)), (Some("1"), None), (Some("auto"), Some(8))] {
        let mut cmd = vwb();
        cmd.args(["render", "--preset", "presets/demo.ron", "--size", "64x64"])
            .args([
                "--backend",
                "raster",
                "--early-termination",
                "0.99",
                "--timings",
            ])
            .args(["--frames", "1", "-o"])
            .arg(&out);
        if let Some(g) = group {
            cmd.args(["--slices-per-proxy", g]);
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stdout = String::from_utf8_lossy(&o.stdout);
        let drawn = stdout
            .lines()
            .find_map(|l| l.strip_prefix("slices_per_proxy "))
            .map(|n| n.trim().parse::<u32>().unwrap());
        assert_eq!(drawn, want, "--slices-per-proxy {group:?}:\n{stdout}");
    }
}

/// `--set KEY=VALUE` sets a plugin parameter or a render setting as an experiment's
/// `set` does, the value written as there: an enumeration whose names are numbers, a
/// number, a vec3, a quoted name; the preset's
/// own value gives the preset's image; a wrong key or value is refused by name.
#[test]
fn render_sets_parameters_by_key() {
    let png = |name: &str, set: &[&str]| -> Result<Vec<u8>, String> {
        let out = tmp(name);
        let mut c = vwb();
        c.args([
            "render",
            "--preset",
            "presets/demo_dos.ron",
            "--size",
            "48x40",
            "-o",
        ])
        .arg(&out);
        for s in set {
            c.args(["--set", s]);
        }
        let o = c.output().unwrap();
        if !o.status.success() {
            return Err(String::from_utf8_lossy(&o.stderr).into_owned());
        }
        Ok(image::open(&out).unwrap().to_rgba8().into_raw())
    };
    let base = png("set_base.png", &[]).unwrap();
    let same = png("set_same.png", &["shade.dos.buffer_scale=1"]).unwrap();
    assert!(same == base, "the preset's own value, the preset's image");
    let half = png("set_half.png", &["shade.dos.buffer_scale=0.5"]).unwrap();
    assert!(
        half != base,
        "a half-resolution occlusion buffer changes the image"
    );
    // the value as an experiment file writes it: the name quoted, a vec3 in parentheses
    let quoted = png("set_quoted.png", &["shade.dos.buffer_scale=\"0.5\""]).unwrap();
    assert!(quoted == half, "a quoted name, the same setting");
    let tinted = png(
        "set_vec3.png",
        &[
            "shade.dos.extinction=chromatic",
            "shade.dos.extinction_rgb=(1, 0.5, 0.25)",
        ],
    )
    .unwrap();
    assert!(tinted != base && tinted != half);
    let both = png(
        "set_both.png",
        &["shade.dos.theta_deg=30", "render.slice_spacing=2"],
    )
    .unwrap();
    assert!(both != base && both != half);
    for (bad, says) in [
        ("shade.dos.buffer_scale=0.3", "not one of"),
        ("shade.dos.theta_deg=600", "outside"),
        ("shade.nothing.x=1", "shade.nothing"),
        ("render.skipping=maybe", "render.skipping"),
        ("no_equals_sign", "KEY=VALUE"),
    ] {
        let e = png("set_bad.png", &[bad]).unwrap_err();
        assert!(e.contains(says), "{bad}: {e}");
    }
}

#[test]
fn failures_name_the_file_and_exit_non_zero() {
    let bad = tmp("bad.ron");
    std::fs::write(
        &bad,
        r#"(version: 1, plugins: [(id: "classify.tf1d", params: {"opacity": -3.0})])"#,
    )
    .unwrap();
    let cases: Vec<(Vec<String>, String)> = vec![
        (
            vec![
                "render".into(),
                "--preset".into(),
                bad.display().to_string(),
                "-o".into(),
                tmp("x.png").display().to_string(),
            ],
            "classify.tf1d.opacity".into(),
        ),
        (
            vec![
                "render".into(),
                "--preset".into(),
                "presets/missing.ron".into(),
                "-o".into(),
                tmp("x.png").display().to_string(),
            ],
            "presets/missing.ron".into(),
        ),
        (
            vec![
                "render".into(),
                "--preset".into(),
                "presets/demo.ron".into(),
                "--volume".into(),
                "Cargo.toml".into(),
                "-o".into(),
                tmp("x.png").display().to_string(),
            ],
            "Cargo.toml".into(),
        ),
        (
            vec![
                "render".into(),
                "--preset".into(),
                "presets/demo.ron".into(),
                "--size".into(),
                "0x5".into(),
                "-o".into(),
                tmp("x.png").display().to_string(),
            ],
            "size".into(),
        ),
    ];
    for (args, want) in cases {
        let o = vwb().args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert_ne!(o.status.code(), Some(101), "{args:?} panicked: {stderr}");
        assert!(
            stderr.contains(&want),
            "{args:?}: expected '{want}' in {stderr}"
        );
        // the cause is said once, not repeated by the error chain
        let cause = "No such file or directory";
        assert!(stderr.matches(cause).count() <= 1, "{stderr}");
    }
    let o = vwb()
        .args([
            "render",
            "--preset",
            "presets/demo.ron",
            "--volume",
            "missing.nhdr",
            "-o",
        ])
        .arg(tmp("x.png"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("missing.nhdr: cannot open"), "{stderr}");
    assert_eq!(stderr.matches("No such file").count(), 1, "{stderr}");
}

/// `--time` sets the stack's clock, `--sequence` writes numbered frames with it
/// advancing (no pre-pass reruns), and wrong uses say why.
#[test]
fn render_time_and_sequence() {
    let dir = tmp("sequence");
    // the storm's time surfaces at 48², with `extra` arguments, to `out`
    let storm = |extra: &[&str], out: &std::path::Path| {
        let o = vwb()
            .args([
                "render",
                "--preset",
                "presets/storm_time_surfaces.ron",
                "--size",
                "48x48",
            ])
            .args(extra)
            .arg("-o")
            .arg(out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).to_string()
    };
    let stdout = storm(&["--sequence", "0:60:3"], &dir.join("storm.png"));
    assert!(
        stdout.contains("wrote 3 frames") && stdout.contains("flow.arrival.time"),
        "{stdout}"
    );
    assert!(stdout.contains("0 pre-/volume passes reran"), "{stdout}");
    let frames: Vec<Vec<u8>> = (0..3)
        .map(|i| std::fs::read(dir.join(format!("storm_000{i}.png"))).unwrap())
        .collect();
    assert!(
        frames[0] != frames[1] && frames[1] != frames[2],
        "the frames differ"
    );
    // --time T renders what frame T of a sequence renders
    let one = dir.join("t30.png");
    storm(&["--time", "30"], &one);
    assert_eq!(std::fs::read(&one).unwrap(), frames[1]);
    for (args, says) in [
        (
            vec!["--preset", "presets/demo.ron", "--time", "3"],
            "no clock parameter",
        ),
        (
            vec![
                "--preset",
                "presets/storm_time_surfaces.ron",
                "--time",
                "5000",
            ],
            "outside flow.arrival's time range",
        ),
        (
            vec![
                "--preset",
                "presets/storm_lic.ron",
                "--animate",
                "nope",
                "--time",
                "1",
            ],
            "'nope'",
        ),
        (
            vec!["--preset", "presets/storm_lic.ron", "--sequence", "0:10"],
            "is not A:B:N",
        ),
        (
            vec![
                "--preset",
                "presets/storm_time_surfaces.ron",
                "--time",
                "1",
                "--sequence",
                "0:1:2",
            ],
            "give one of them",
        ),
    ] {
        let o = vwb()
            .arg("render")
            .args(&args)
            .arg("-o")
            .arg(dir.join("x.png"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && stderr.contains(says),
            "{args:?}: {stderr}"
        );
    }
}

#[test]
fn info_lists_adapter_and_plugins() {
    let o = vwb().arg("info").output().unwrap();
    assert!(o.status.success());
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.contains("adapter: ") && s.contains("Vulkan"), "{s}");
    assert!(s.contains("plugin classify.tf1d"), "{s}");
    assert!(s.contains("limit max_texture_dimension_3d"), "{s}");
}

#[test]
fn shader_dump_writes_the_composed_wgsl() {
    let dir = tmp("dump");
    let o = vwb()
        .env("VWB_SHADER_DUMP", &dir)
        .args([
            "render",
            "--preset",
            "presets/demo_smooth.ron",
            "--size",
            "32x32",
            "-o",
        ])
        .arg(tmp("d.png"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let main = std::fs::read_to_string(dir.join("composed_main.wgsl")).unwrap();
    assert!(main.contains("fn p1_tf1d_classify("));
    assert!(
        std::fs::read_dir(&dir).unwrap().count() >= 2,
        "the pre-pass module is dumped too"
    );
}

#[test]
fn sweep_over_slice_spacing_converges_and_writes_a_pareto_plot() {
    gpu();
    let dir = tmp("sweep");
    let o = vwb()
        .args(["sweep", "--preset", "presets/demo.ron", "--size", "48x48"])
        .args(["--target", "rgba32float", "--frames", "2"])
        .args(["--param", "render.slice_spacing=0.5,1,2,4", "-o"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(dir.join("sweep.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    assert_eq!(rows.len(), 4);
    let num = |r: &Vec<String>, c: &str| r[col(c)].parse::<f64>().unwrap();
    // finer spacing: more slices and less error against the converged reference
    for pair in rows.windows(2) {
        assert!(num(&pair[0], "slices") > num(&pair[1], "slices"));
        assert!(
            num(&pair[0], "rms_delta_e") < num(&pair[1], "rms_delta_e"),
            "{csv}"
        );
    }
    assert!(rows.iter().any(|r| r[col("pareto")] == "true"));
    for r in &rows {
        assert!(dir.join(&r[col("image")]).exists());
    }
    let svg = std::fs::read_to_string(dir.join("pareto.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("Pareto front"));
    assert!(dir.join("reference_00.png").exists());
}

#[test]
fn compare_bench_and_scene() {
    gpu();
    let dir = tmp("compare");
    let o = vwb()
        .args(["compare", "--preset", "presets/demo.ron", "--size", "40x32"])
        .args(["--against", "converged", "-o"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["image.png", "against.png", "heatmap.png"] {
        assert!(dir.join(f).exists(), "{f}");
    }
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("metrics.json")).unwrap()).unwrap();
    let rms = m["metrics"]["rms_delta_e"].as_f64().unwrap();
    assert!(rms > 0.0 && rms < 5.0, "{rms}");
    assert_eq!(m["against"]["converged"], true);
    assert!(m["metrics"]["ssim"].as_f64().unwrap() > 0.9);

    let csv = tmp("bench.csv");
    let o = vwb()
        .args([
            "bench",
            "--preset",
            "presets/demo_smooth.ron",
            "--size",
            "32x32",
        ])
        .args(["--frames", "2", "--warmup", "1", "-o"])
        .arg(&csv)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.starts_with("kind,name,clock"));
    for needle in [
        "frame,frame,",
        "plugin,test.smooth#0",
        "plugin,classify.tf1d#1",
        "memory,test.smooth#0",
        "cold_pass,prepass test.smooth",
    ] {
        assert!(text.contains(needle), "{needle} in\n{text}");
    }

    let o = vwb()
        .args(["scene", "--preset", "presets/demo.ron"])
        .output()
        .unwrap();
    assert!(o.status.success());
    let scene: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(scene["tf"]["lut"].as_array().unwrap().len(), 256);
    assert_eq!(scene["volume"]["dims"], serde_json::json!([128, 128, 84]));
    // tools such as bench/vtk_peer.py read the demo volume from this file
    let demo = scene["volume"]["demo_path"].as_str().unwrap();
    assert!(std::path::Path::new(demo).is_file(), "{demo}");

    // bad parameters name the cause
    for (args, needle) in [
        (
            vec!["--param", "classify.nope.x=1..2:3"],
            "no plugin 'classify.nope'",
        ),
        (
            vec!["--param", "classify.tf1d.opacity=1..2"],
            "expected A..B:N",
        ),
        (vec!["--param", "classify.tf1d.opacity=0..2:3"], "opacity"),
        (
            vec!["--param", "render.slice_spacing=0,1"],
            "slice spacing must be > 0",
        ),
    ] {
        let o = vwb()
            .args(["sweep", "--preset", "presets/demo.ron", "-o"])
            .arg(tmp("bad"))
            .args(&args)
            .output()
            .unwrap();
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

#[test]
fn suggest_tf_writes_a_valid_transfer_function() {
    let out = tmp("suggested_tf.ron");
    let o = vwb().args(["suggest-tf", "-o"]).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("boundary blur"), "{err}");
    let curve: vwb_render::tf::TfCurve =
        ron::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    curve.validate().unwrap();
    // the demo head has boundaries: some values are opaque, the background is not
    let alphas: Vec<f64> = (0..=100).map(|i| curve.eval(i as f64 / 100.0)[3]).collect();
    assert!(alphas.iter().any(|&a| a > 0.2), "{alphas:?}");
    assert!(
        alphas[0] < 0.05,
        "background value is transparent: {}",
        alphas[0]
    );
    // a vector volume is refused with the file named
    let o = vwb()
        .args(["suggest-tf", "--volume"])
        .arg(data_dir().join("storm_wind_ncsa_25x14x8_float32x3.nhdr"))
        .arg("-o")
        .arg(tmp("never.ron"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("storm_wind") && err.contains("vector volume"),
        "{err}"
    );
}

/// For a stack with shade.dos, `--against converged` is the Monte-Carlo reference
/// (the same integral as docs/dos.md's experiment files, at half their resolution); the
/// bench's ablation charges DOS's passes to it.
#[test]
fn dos_compares_against_monte_carlo_and_its_cost_is_measured() {
    gpu();
    let dir = tmp("compare-dos");
    let o = vwb()
        .args([
            "compare",
            "--preset",
            "presets/demo_dos.ron",
            "--size",
            "24x24",
        ])
        .args(["--against", "converged", "-o"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["against"]["kind"], "monte_carlo");
    assert!(m["against"]["rms_std_error"].as_f64().unwrap() < 0.01);
    let rms = m["metrics"]["rms_delta_e"].as_f64().unwrap();
    // measured 8.07 on lavapipe: at spacing 1 and θ = 60° the slice algorithm lags the
    // cone integral by one slice and spreads occlusion by its kernel
    // (dos::dos_converges_towards_its_monte_carlo_reference, docs/dos.md)
    assert!(rms > 6.0 && rms < 10.0, "{rms}");

    // per-plugin cost by ablation: DOS's per-slice passes are most of the frame, so its
    // cost is positive and below the frame time; the classifier's magnitude is bounded
    // by the frame (it may be negative: it enables empty-space skipping). Measured
    // 0.94-0.96 of the frame alone on lavapipe; a CI run on 2 cores shared with the
    // other tests measured 0.46 (one frame of three took twice the median), so the bound
    // is a third and the medians are over 5 frames: it still fails if the ablation does
    // not charge DOS's passes to it (0 or the classifier's share)
    let csv = tmp("bench-dos.csv");
    let o = vwb()
        .args([
            "bench",
            "--preset",
            "presets/demo_dos.ron",
            "--size",
            "32x32",
        ])
        .args(["--frames", "5", "--warmup", "1", "-o"])
        .arg(&csv)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    let median = |kind: &str, name: &str| -> f64 {
        text.lines()
            .map(|l| l.split(',').collect::<Vec<_>>())
            .find(|c| c[0] == kind && c[1] == name)
            .unwrap_or_else(|| panic!("{kind},{name} in\n{text}"))[5]
            .parse()
            .unwrap()
    };
    let frame = median("frame", "frame");
    let dos = median("plugin", "shade.dos#1");
    let tf = median("plugin", "classify.tf1d#0");
    assert!(
        dos > frame / 3.0 && dos < 1.1 * frame,
        "shade.dos costs {dos} ms of a {frame} ms frame\n{text}"
    );
    assert!(
        tf.abs() < frame,
        "classify.tf1d: {tf} ms of {frame}\n{text}"
    );
}

/// `vwb run` takes several experiment files; `-o` names one report folder, so it goes
/// with one file only, and a missing file is named.
#[test]
fn run_takes_several_files_and_one_output_folder_for_one() {
    let o = vwb()
        .args(["run", "experiments/dos.ron", "experiments/dos_ct.ron", "-o"])
        .arg(tmp("two"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("-o names one report folder"), "{err}");
    let o = vwb()
        .args(["run", "/nonexistent/a.ron", "/nonexistent/b.ron"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("/nonexistent/a.ron")
            && err.contains("/nonexistent/b.ron")
            && err.contains("2 of 2 experiments failed"),
        "{err}"
    );
}

/// The real window under Xvfb: `vwb --screenshot` opens it on the embedded demo,
/// renders, saves a screenshot and exits; the viewport is not blank.
#[test]
fn window_screenshot_under_xvfb_is_not_blank() {
    gpu();
    let out = tmp("window.png");
    let o = Command::new("xvfb-run")
        .args(["-a", env!("CARGO_BIN_EXE_vwb"), "--screenshot"])
        .arg(&out)
        .current_dir(repo())
        .output()
        .unwrap_or_else(|e| {
            panic!("the window test needs xvfb-run (scripts/test installs xvfb and xauth): {e}")
        });
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&out).unwrap().to_rgb8();
    let (w, h) = img.dimensions();
    assert!(w >= 400 && h >= 300, "{w}×{h}");
    // the viewport (the right half) shows the volume: many distinct colours, and
    // pixels brighter than the background
    let mut colours = std::collections::HashSet::new();
    let mut bright = 0;
    for y in 0..h {
        for x in w / 2..w {
            let p = img.get_pixel(x, y).0;
            colours.insert(p);
            if p.iter().map(|&c| c as u32).sum::<u32>() > 150 {
                bright += 1;
            }
        }
    }
    eprintln!(
        "window screenshot {w}×{h}: {} colours, {bright} bright pixels",
        colours.len()
    );
    assert!(colours.len() > 200 && bright > (w / 2 * h / 50) as usize);
}

/// On a terminal `vwb render` shows which step it is at (a spinner on stderr), and
/// clears it: run under `script`, which gives the command a pseudo-terminal.
#[test]
fn render_shows_progress_on_a_terminal() {
    gpu();
    let out = tmp("tty.png");
    let cmd = format!(
        "{} render --preset {} --size 64x64 -o {}",
        env!("CARGO_BIN_EXE_vwb"),
        repo().join("presets/ct_head.ron").display(),
        out.display()
    );
    let o = std::process::Command::new("script")
        .args(["-qec", &cmd, "/dev/null"])
        .env("VWB_DATA_DIR", data_dir())
        .output()
        .expect("`script` (util-linux) runs the command on a pseudo-terminal");
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{text}");
    assert!(text.contains("vwb render: loading the volume"), "{text:?}");
    assert!(text.contains("wrote "), "{text:?}");
    assert!(out.is_file());
}
