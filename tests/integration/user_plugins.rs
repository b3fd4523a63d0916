//! User plugins (plugins/src/user.rs): the shipped examples load from their folders,
//! compose and render on the GPU with a visible effect; a broken copy is refused with
//! its file and line; an edited plugin reloads and a broken edit keeps the last good
//! one; an experiment measures a user plugin against the GPU converged reference.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use vwb_plugins::user;
use vwb_render::plugin::{Plugin, PluginInstance};
use vwb_render::renderer::Backend;
use vwb_render::{Renderer, TargetFormat};

use crate::common::{demo, diff, gpu, instance, render, repo, rgb, settings, tmp};

fn examples() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo().join("examples/plugins"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("plugin.ron").is_file())
        .collect();
    v.sort();
    v
}

/// A copy of an example folder in the scratch directory.
fn copy(dir: &Path, name: &str) -> PathBuf {
    let to = tmp(name);
    std::fs::create_dir_all(&to).unwrap();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
    }
    to
}

/// The shipped example in `examples/plugins/<name>`.
fn example(name: &str) -> PathBuf {
    examples()
        .into_iter()
        .find(|d| d.file_name().is_some_and(|f| f == name))
        .unwrap()
}

/// A user plugin folder in the scratch directory: its `plugin.ron` and one WGSL file.
fn plugin_folder(name: &str, manifest: &str, (wgsl, source): (&str, &str)) -> PathBuf {
    let dir = tmp(name);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("plugin.ron"), manifest).unwrap();
    std::fs::write(dir.join(wgsl), source).unwrap();
    dir
}

fn wgsl_of(dir: &Path) -> PathBuf {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|x| x == "wgsl"))
        .unwrap()
}

#[test]
fn shipped_examples_load_and_render_with_an_effect() {
    let dirs = examples();
    let ids: Vec<String> = dirs
        .iter()
        .map(|d| {
            user::load(d)
                .unwrap_or_else(|e| panic!("{e}"))
                .id()
                .to_string()
        })
        .collect();
    assert_eq!(
        ids,
        [
            "shade.gooch",
            "shade.input_tint",
            "shade.light_sweep",
            "shade.toon_lite"
        ]
    );
    let s = settings(48, 48, Backend::Raster);
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let tf = instance("classify.tf1d");
    let plain = rgb(&render(
        &mut r,
        std::slice::from_ref(&tf),
        TargetFormat::Rgba16Float,
        &s,
    ));
    let mut images = Vec::new();
    for d in &dirs {
        let p: Arc<dyn Plugin> = Arc::new(user::load(d).unwrap());
        for backend in [Backend::Raster, Backend::Compute] {
            let s = settings(48, 48, backend);
            let img = rgb(&render(
                &mut r,
                &[tf.clone(), PluginInstance::new(p.clone())],
                TargetFormat::Rgba16Float,
                &s,
            ));
            assert!(img.iter().flatten().all(|c| c.is_finite()));
            let (rms, _) = diff(&img, &plain);
            assert!(
                rms > 0.01,
                "{}: shading changes nothing (RMS {rms})",
                p.id()
            );
            if backend == Backend::Raster {
                images.push(img);
            }
        }
    }
    for i in 0..images.len() {
        for j in i + 1..images.len() {
            let (rms, _) = diff(&images[i], &images[j]);
            assert!(rms > 0.01, "examples {i} and {j} render alike (RMS {rms})");
        }
    }
}

#[test]
fn a_broken_copy_is_refused_with_file_and_line() {
    let d = copy(&example("gooch"), "broken_gooch");
    let w = wgsl_of(&d);
    let text = std::fs::read_to_string(&w).unwrap();
    let broken = text.replace("params.beta", "params.btea");
    let line = broken.lines().position(|l| l.contains("btea")).unwrap() + 1;
    std::fs::write(&w, broken).unwrap();
    let e = user::load(&d).unwrap_err();
    assert!(e.contains(&format!("{}:{line}:", w.display())), "{e}");
    // a folder of plugins with one broken: the good one loads, the error names the file
    let root = tmp("plugin_root");
    std::fs::create_dir_all(&root).unwrap();
    let good = copy(&example("toon_lite"), "plugin_root/toon");
    let bad = copy(&d, "plugin_root/gooch");
    let (ok, errors) = user::load_all(&root);
    assert_eq!(ok.len(), 1);
    assert_eq!(ok[0].dir, good);
    assert_eq!(errors.len(), 1);
    assert!(errors[0].contains(&bad.display().to_string()), "{errors:?}");
}

#[test]
fn edits_reload_and_a_broken_edit_keeps_the_last_good_plugin() {
    let d = copy(&example("toon_lite"), "reload_toon");
    let manifest = d.join("plugin.ron");
    let text = std::fs::read_to_string(&manifest).unwrap();
    std::fs::write(
        &manifest,
        text.replace("shade.toon_lite", "shade.toon_reload"),
    )
    .unwrap();
    user::install(vec![user::load(&d).unwrap()]);
    let mut watch = user::Watch::default();
    assert!(watch.poll().is_empty(), "the first poll only records");
    let w = wgsl_of(&d);
    let touch = |path: &Path, secs: u64| {
        let f = std::fs::File::options().write(true).open(path).unwrap();
        f.set_modified(std::time::SystemTime::now() + std::time::Duration::from_secs(secs))
            .unwrap();
    };
    let src = std::fs::read_to_string(&w).unwrap();
    std::fs::write(
        &w,
        src.replace("rgb = vec3<f32>(0.0);", "rgb = vec3<f32>(1.0);"),
    )
    .unwrap();
    touch(&w, 10);
    let out = watch.poll();
    let reloaded: Vec<_> = out
        .iter()
        .filter(|(id, _)| id == "shade.toon_reload")
        .collect();
    assert_eq!(reloaded.len(), 1);
    let p = reloaded[0].1.as_ref().unwrap();
    assert!(p.shader().source.contains("vec3<f32>(1.0)"));
    std::fs::write(&w, src.replace("let d = ", "let d == ")).unwrap();
    touch(&w, 20);
    let out = watch.poll();
    let failed = out
        .iter()
        .find(|(id, _)| id == "shade.toon_reload")
        .unwrap();
    let Err(e) = &failed.1 else {
        panic!("a broken edit reloaded")
    };
    assert!(e.contains(&w.display().to_string()), "{e}");
    // the installed (last good) version is still the reloaded one
    let installed = vwb_plugins::registry().get("shade.toon_reload").unwrap();
    assert!(installed.shader().source.contains("vec3<f32>(1.0)"));
}

#[test]
fn an_experiment_measures_a_user_plugin_against_the_gpu_converged_reference() {
    user::install(vec![user::load(&examples()[0]).unwrap()]);
    let preset = repo().join("presets/demo_shaded.ron");
    let body = format!(
        r#"Experiment(
            name: "user",
            scenes: [Preset("{}")],
            variants: [(name: "gooch", swap: [("shade.blinn_phong", "shade.gooch")])],
            grid: [(param: "render.slice_spacing", values: [1.0, 4.0])],
            render: (size: (32, 32), target: "rgba32float"),
            frames: 1,
            tolerance: 0.5,
            assertions: ["rms_delta_e(gooch) < 20"],
        )"#,
        preset.display()
    );
    let file = tmp("user_experiment.ron");
    std::fs::write(&file, body).unwrap();
    let e = vwb_lab::experiment::load(&file).unwrap();
    let o =
        vwb_lab::experiment::run(gpu(), &e, &file, &tmp("user_experiment"), &mut |_| {}).unwrap();
    assert_eq!(o.references.len(), 1);
    assert_eq!(o.references[0]["kind"], serde_json::json!("gpu-converged"));
    assert!(
        o.markdown.contains("on the GPU (no CPU twin)"),
        "{}",
        o.markdown
    );
    // coarser slices are further from the converged image
    assert!(
        o.rows[0].metrics.rms_delta_e < o.rows[1].metrics.rms_delta_e,
        "{:?}",
        o.rows
    );
    assert!(o.failed().is_empty(), "{:?}", o.assertions);
}

/// A user plugin declares volume passes in `plugin.ron`: `examples/plugins/light_sweep`
/// sweeps a light's transmittance plane by plane, as the built-in
/// shade.sweep_shadows does in Rust, and with a white light renders the same image on
/// both backends. A pass whose sweep direction is not a Vec3 parameter, or whose entry
/// the WGSL file does not define, is refused naming the file and the pass.
#[test]
fn a_user_plugin_declares_a_sweep_pass() {
    use vwb_render::params::ParamValue;
    let p: Arc<dyn Plugin> = Arc::new(user::load(&example("light_sweep")).unwrap());
    let passes = p.volume_passes();
    assert_eq!(passes.len(), 1);
    assert!(passes[0].sweep.is_some() && passes[0].depends_on == ["light"]);
    let light = ParamValue::Vec3([0.3, -0.8, 0.5]);
    let mut user_inst = PluginInstance::new(p);
    user_inst.params.set("light", light.clone());
    user_inst.params.set("tint", ParamValue::Color([1.0; 4]));
    user_inst.params.set("ambient", ParamValue::Float(0.2));
    let mut builtin = instance("shade.sweep_shadows");
    builtin.params.set("light", light);
    builtin.params.set("ambient", ParamValue::Float(0.2));
    let tf = instance("classify.tf1d");
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    for backend in [Backend::Compute, Backend::Raster] {
        let s = settings(48, 48, backend);
        let plain = rgb(&render(
            &mut r,
            std::slice::from_ref(&tf),
            TargetFormat::Rgba32Float,
            &s,
        ));
        let a = rgb(&render(
            &mut r,
            &[tf.clone(), user_inst.clone()],
            TargetFormat::Rgba32Float,
            &s,
        ));
        let b = rgb(&render(
            &mut r,
            &[tf.clone(), builtin.clone()],
            TargetFormat::Rgba32Float,
            &s,
        ));
        let (same, _) = diff(&a, &b);
        let (shadowed, _) = diff(&a, &plain);
        // f32 rounding only (the same equations, written a little differently)
        assert!(
            same < 1e-3,
            "{backend:?}: the user sweep differs from the built-in (RMS {same})"
        );
        assert!(
            shadowed > 0.02,
            "{backend:?}: the light changes the image (RMS {shadowed})"
        );
    }

    let d = copy(&example("light_sweep"), "broken_sweep");
    let manifest = d.join("plugin.ron");
    let text = std::fs::read_to_string(&manifest).unwrap();
    std::fs::write(
        &manifest,
        text.replace("direction: \"-light\"", "direction: \"ambient\""),
    )
    .unwrap();
    let e = user::load(&d).unwrap_err();
    assert!(
        e.contains("plugin.ron")
            && e.contains("pass 'transmittance'")
            && e.contains("'ambient' is not a Vec3"),
        "{e}"
    );
    std::fs::write(
        &manifest,
        text.replace("entry: \"transmit\"", "entry: \"transmitt\""),
    )
    .unwrap();
    let e = user::load(&d).unwrap_err();
    assert!(
        e.contains("light_sweep.wgsl") && e.contains("transmitt"),
        "{e}"
    );
}

/// A user plugin's `Volume` parameter binds a named volume input as a texture of its
/// name, with no Rust. The shipped `input_tint` tints by a second volume: by the
/// document's own when none is named; a named input that is zero everywhere tints
/// nothing (the image is the plain one), and the demo under a name tints as the
/// document's own. A pass copying the texture shows its layout for a 3-component
/// input on a grid of its own: `.rgb` the components as stored, `.a` the magnitude
/// normalised by the input's range. A wrong `components` is refused naming the file.
#[test]
fn a_user_plugin_reads_a_named_volume_input() {
    use vwb_render::inputs::VolumeInputs;
    use vwb_render::params::{ParamKind, ParamValue};
    let p: Arc<dyn Plugin> = Arc::new(user::load(&example("input_tint")).unwrap());
    let spec = p.params().into_iter().find(|s| s.key == "field").unwrap();
    assert!(matches!(spec.kind, ParamKind::Volume { .. }));
    assert_eq!(p.resources().len(), 1);
    let tf = instance("classify.tf1d");
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let mut inputs = VolumeInputs::default();
    let d = demo();
    let zero = crate::common::synthetic(d.dims, |_, _, _| 0.0);
    inputs.insert("zero", zero);
    inputs.insert("same", d.clone());
    r.set_inputs(inputs);
    let tint = |field: &str| {
        let mut i = PluginInstance::new(p.clone());
        i.params.set("field", ParamValue::Volume(field.into()));
        i
    };
    for backend in [Backend::Compute, Backend::Raster] {
        let s = settings(48, 48, backend);
        let mut frame =
            |stack: &[PluginInstance]| rgb(&render(&mut r, stack, TargetFormat::Rgba32Float, &s));
        let plain = frame(std::slice::from_ref(&tf));
        let own = frame(&[tf.clone(), tint("")]);
        let zero = frame(&[tf.clone(), tint("zero")]);
        let same = frame(&[tf.clone(), tint("same")]);
        let (tinted, _) = diff(&own, &plain);
        assert!(tinted > 0.01, "{backend:?}: the tint shows (RMS {tinted})");
        // (the raster pipeline with a shade hook rounds a little differently: 1.6e-4)
        let (none, _) = diff(&zero, &plain);
        assert!(
            none < 1e-3,
            "{backend:?}: a zero input tints nothing ({none})"
        );
        let (alike, _) = diff(&same, &own);
        assert!(
            alike < 1e-6,
            "{backend:?}: the demo by name is the demo ({alike})"
        );
    }

    // the texture's layout, for a vector input on a grid of its own
    let dir = plugin_folder(
        "input_copy",
        r#"UserPlugin(id: "test.input_copy", name: "Input copy", shader: "copy.wgsl",
        params: [Volume(key: "field", label: "Input", components: "vector")],
        passes: [(target: "copied", entry: "copy_pass", format: "rgba32float")])"#,
        (
            "copy.wgsl",
            "fn copy_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {\n    return textureLoad(field, voxel, 0);\n}\n",
        ),
    );
    let copy: Arc<dyn Plugin> = Arc::new(user::load(&dir).unwrap_or_else(|e| panic!("{e}")));
    let dims = [9, 7, 5];
    let field = vwb_render::volume::Volume::new(
        "field",
        dims,
        3,
        [2.0, 1.0, 0.5],
        vwb_render::volume::VoxelData::F32(
            (0..9 * 7 * 5 * 3)
                .map(|i| ((i * 37 % 101) as f32 - 50.0) * 0.25)
                .collect(),
        ),
    )
    .unwrap();
    let mut r = Renderer::new(gpu(), crate::common::synthetic(dims, |x, _, _| x as f32)).unwrap();
    let mut inputs = VolumeInputs::default();
    inputs.insert("wind", Arc::new(field.clone()));
    r.set_inputs(inputs);
    let mut inst = PluginInstance::new(copy);
    inst.params.set("field", ParamValue::Volume("wind".into()));
    render(
        &mut r,
        &[tf.clone(), inst.clone()],
        TargetFormat::Rgba32Float,
        &settings(16, 16, Backend::Compute),
    );
    let (got_dims, texels) = r.read_pass_target(inst.uid, "copied").unwrap();
    assert_eq!(got_dims, dims);
    let raw = field.components_f32();
    let norm = field.normalized_scalars();
    let mut worst = 0.0f32;
    for (i, t) in texels.chunks_exact(4).enumerate() {
        for c in 0..3 {
            worst = worst.max((t[c] - raw[i * 3 + c]).abs());
        }
        worst = worst.max((t[3] - norm[i]).abs());
    }
    assert!(worst < 1e-5, "the texture's layout: worst {worst}");
    assert!(norm.iter().any(|n| *n > 0.9) && norm.iter().any(|n| *n < 0.2));

    let broken = std::fs::read_to_string(dir.join("plugin.ron"))
        .unwrap()
        .replace("\"vector\"", "\"vectors\"");
    std::fs::write(dir.join("plugin.ron"), broken).unwrap();
    let e = user::load(&dir).unwrap_err();
    assert!(
        e.contains("plugin.ron") && e.contains("'vectors' is not scalar, vector or any"),
        "{e}"
    );
}

/// A user plugin's pass may be progressive (`steps`: a count or an `Int` parameter):
/// step i runs with `step` = i and reads its own previous texel, one step per frame
/// under a refinement budget of 1, and the renderer reports the progress; a new step
/// count restarts the refinement. Steps naming a parameter that is not an Int are
/// refused naming the pass.
#[test]
fn a_user_plugin_declares_a_progressive_pass() {
    use vwb_render::params::ParamValue;
    // after step i the texel holds 1 + 2 + … + (i + 1)
    let dir = plugin_folder(
        "progressive",
        r#"UserPlugin(id: "test.rounds", name: "Rounds", shader: "rounds.wgsl",
        params: [Int(key: "rounds", label: "Rounds", min: 1, max: 16, default: 4),
                 Float(key: "gain", label: "Gain", min: 0.0, max: 1.0, default: 0.5)],
        passes: [(target: "sum", entry: "sum_pass", steps: "rounds", scale: 0.25)])"#,
        (
            "rounds.wgsl",
            "fn sum_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {\n    if (step == 0u) {\n        return vec4<f32>(1.0, 0.0, 0.0, 1.0);\n    }\n    return vec4<f32>(prev.x + f32(step + 1u), 0.0, 0.0, 1.0);\n}\n",
        ),
    );
    let p: Arc<dyn Plugin> = Arc::new(user::load(&dir).unwrap_or_else(|e| panic!("{e}")));
    assert!(p.volume_passes()[0].steps.is_some());
    let tf = instance("classify.tf1d");
    let mut inst = PluginInstance::new(p);
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    r.set_refinement_budget(Some(1));
    let s = settings(16, 16, Backend::Compute);
    let mut sums = Vec::new();
    for frame in 1..=5u32 {
        render(
            &mut r,
            &[tf.clone(), inst.clone()],
            TargetFormat::Rgba32Float,
            &s,
        );
        let (_, texels) = r.read_pass_target(inst.uid, "sum").unwrap();
        assert!(texels.iter().all(|t| *t == texels[0]));
        sums.push(texels[0]);
        assert_eq!(
            r.refinement_progress(),
            Some((frame.min(4), 4)),
            "frame {frame}"
        );
    }
    assert_eq!(sums, [1.0, 3.0, 6.0, 10.0, 10.0]);
    assert!(!r.refining());
    inst.params.set("rounds", ParamValue::Int(2));
    r.set_refinement_budget(None);
    render(
        &mut r,
        &[tf.clone(), inst.clone()],
        TargetFormat::Rgba32Float,
        &s,
    );
    assert_eq!(r.read_pass_target(inst.uid, "sum").unwrap().1[0], 3.0);
    assert_eq!(r.refinement_progress(), Some((2, 2)));
    // a parameter the pass does not depend on reruns nothing
    inst.params.set("gain", ParamValue::Float(0.9));
    r.update_stack(&[tf.clone(), inst.clone()], TargetFormat::Rgba32Float)
        .unwrap();
    let stats = r.render(&s).unwrap();
    assert!(
        stats.volume_passes_run.is_empty(),
        "{:?}",
        stats.volume_passes_run
    );

    let text = std::fs::read_to_string(dir.join("plugin.ron")).unwrap();
    std::fs::write(
        dir.join("plugin.ron"),
        text.replace("steps: \"rounds\"", "steps: \"gain\""),
    )
    .unwrap();
    let e = user::load(&dir).unwrap_err();
    assert!(
        e.contains("plugin.ron") && e.contains("pass 'sum': steps 'gain' is not an Int"),
        "{e}"
    );
    std::fs::write(
        dir.join("plugin.ron"),
        text.replace("steps: \"rounds\"", "steps: 3"),
    )
    .unwrap();
    let p = user::load(&dir).unwrap_or_else(|e| panic!("{e}"));
    let steps = p.volume_passes()[0].steps.clone().unwrap();
    assert_eq!(steps.count(&inst.params), 3);
}

/// An atlas of one stack with a progressive pass and a view pass reading it, under a
/// refinement budget of one step per frame: the progressive pass refines one step per
/// atlas (at its first tile, as one frame would), not one per tile; once it is done, the
/// view pass runs before every tile whose camera differs from the last (it waits, as
/// in a single frame, while the budget is spent).
#[test]
fn an_atlas_refines_a_progressive_pass_once_per_variant() {
    use vwb_render::renderer::AtlasTile;
    let dir = plugin_folder(
        "progressive_view",
        r#"UserPlugin(id: "test.rounds_view", name: "Rounds, viewed", shader: "rv.wgsl",
        params: [Int(key: "rounds", label: "Rounds", min: 1, max: 16, default: 4)],
        passes: [(target: "sum", entry: "sum_pass", steps: "rounds", scale: 0.25),
                 (target: "seen", entry: "seen_pass", view: true, scale: 0.25)])"#,
        (
            "rv.wgsl",
            "fn sum_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {\n    return vec4<f32>(prev.x + 1.0, 0.0, 0.0, 1.0);\n}\nfn seen_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {\n    return vec4<f32>(textureLoad(sum, voxel, 0).r + frame.eye.x, 0.0, 0.0, 1.0);\n}\n",
        ),
    );
    let p: Arc<dyn Plugin> = Arc::new(user::load(&dir).unwrap_or_else(|e| panic!("{e}")));
    let stack = vec![instance("classify.tf1d"), PluginInstance::new(p)];
    let s = settings(16, 16, Backend::Compute);
    let mut turned = s.camera;
    turned.yaw_deg += 40.0;
    let tiles = [
        AtlasTile {
            camera: s.camera,
            stack: &stack,
        },
        AtlasTile {
            camera: turned,
            stack: &stack,
        },
    ];
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    r.set_refinement_budget(Some(1));
    let mut runs = Vec::new();
    for round in 1..=5u32 {
        let atlas = r
            .render_atlas(&tiles, &s, TargetFormat::Rgba32Float, 2)
            .unwrap();
        runs.push(atlas.volume_passes_run);
        let (done, total) = r.refinement_progress().unwrap();
        assert_eq!(total, 5, "four steps and the view pass");
        assert!(done >= round.min(4), "round {round}: {done} of {total}");
    }
    // one step per atlas (two if every tile refined); the fourth step spends the first
    // tile's budget, so the view pass runs at the second tile only (as a single frame
    // would defer it); then only the view pass, at both tiles
    assert_eq!(runs, [1, 1, 1, 2, 2]);
}

/// A user plugin's loops, which it does not declare
/// ([`vwb_render::plugin::Plugin::loop_iterations`]): on a CPU device the shader notes
/// where they ran out of llvmpipe's loop iterations, and `Renderer::render` renders the
/// frame again in smaller parts until they do not; its image is then that of parts of
/// one slice each (which cannot run out here). Marched in one part by force, the frame
/// is cut short and says so (`FrameStats::loop_limited`). An atlas of such tiles
/// (galleries, genetic search) is rendered again in smaller parts likewise
/// (`Renderer::render_atlas`, `Atlas::loop_limited`). A GPU has no such limit.
#[test]
fn a_user_plugins_loops_are_found_and_marched_in_parts() {
    let manifest = r#"UserPlugin(
    id: "sample.loops",
    name: "Loops",
    description: "the sample's value as the mean of `steps` copies of itself",
    shader: "loops.wgsl",
    params: [Int(key: "steps", label: "Steps", min: 1, max: 100000, default: 1000)],
)"#;
    let source = "fn sample(s: Sample) -> Sample {
    var o = s;
    var v = 0.0;
    for (var i = 0; i < params.steps; i++) {
        v = v + s.value;
    }
    o.value = v / f32(max(params.steps, 1));
    return o;
}
";
    let dir = plugin_folder("loops", manifest, ("loops.wgsl", source));
    let p: Arc<dyn Plugin> = Arc::new(user::load(&dir).unwrap_or_else(|e| panic!("{e}")));
    let stack = [PluginInstance::new(p), instance("classify.tf1d")];
    let s = settings(24, 24, Backend::Compute);
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let found = render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
    let stats = r.render(&s).unwrap();
    assert_eq!(
        stats.loop_limited, 0,
        "the parts found leave no ray cut short"
    );
    r.set_march_part_slices(Some(1));
    let single = render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
    let differ = found.iter().zip(&single).filter(|(a, b)| a != b).count();
    assert_eq!(differ, 0, "{differ} pixels differ from parts of one slice");
    assert!(
        found.iter().any(|p| p[3] > 0.2),
        "the frame shows something"
    );
    // an atlas of two tiles of the stack: the first is the single render's
    let turned = vwb_render::Camera {
        yaw_deg: s.camera.yaw_deg + 40.0,
        ..s.camera
    };
    let tiles = [s.camera, turned].map(|camera| vwb_render::renderer::AtlasTile {
        camera,
        stack: &stack,
    });
    let mut a = Renderer::new(gpu(), demo()).unwrap();
    let atlas = a
        .render_atlas(&tiles, &s, TargetFormat::Rgba16Float, 2)
        .unwrap();
    assert_eq!(
        atlas.loop_limited, 0,
        "the atlas's parts leave no ray cut short"
    );
    let (d, _) = diff(&rgb(&atlas.tile_pixels(0)), &rgb(&single));
    assert!(d < 1e-6, "the atlas's first tile is the single render: {d}");
    if crate::common::on_gpu() {
        return;
    }
    a.set_march_part_slices(Some(100_000));
    let cut = a
        .render_atlas(&tiles, &s, TargetFormat::Rgba16Float, 2)
        .unwrap();
    assert!(cut.loop_limited > 0, "the atlas's shortfall is noted");
    let (d, _) = diff(&rgb(&cut.tile_pixels(0)), &rgb(&single));
    assert!(d > 0.01, "an atlas cut short looks different (RMS {d})");
    // (~1 000 iterations a sample: 60 slices a part at most)
    assert!(
        stats.march_parts >= stats.slices.div_ceil(60),
        "{} parts for {} slices",
        stats.march_parts,
        stats.slices
    );
    r.set_march_part_slices(Some(100_000));
    let cut = render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
    assert!(
        r.render(&s).unwrap().loop_limited > 0,
        "the shortfall is noted"
    );
    let (rms, _) = crate::common::diff(&rgb(&cut), &rgb(&single));
    assert!(rms > 0.01, "a frame cut short looks different (RMS {rms})");
}
