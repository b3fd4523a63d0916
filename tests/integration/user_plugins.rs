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
    assert_eq!(ids, ["shade.gooch", "shade.light_sweep", "shade.toon_lite"]);
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
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let (rms, _) = diff(&images[i], &images[j]);
        assert!(rms > 0.01, "examples {i} and {j} render alike (RMS {rms})");
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
