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
    assert_eq!(ids, ["shade.gooch", "shade.toon_lite"]);
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
    let (rms, _) = diff(&images[0], &images[1]);
    assert!(rms > 0.01, "the two examples render alike (RMS {rms})");
}

#[test]
fn a_broken_copy_is_refused_with_file_and_line() {
    let d = copy(&examples()[0], "broken_gooch");
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
    let good = copy(&examples()[1], "plugin_root/toon");
    let bad = copy(&d, "plugin_root/gooch");
    let (ok, errors) = user::load_all(&root);
    assert_eq!(ok.len(), 1);
    assert_eq!(ok[0].dir, good);
    assert_eq!(errors.len(), 1);
    assert!(errors[0].contains(&bad.display().to_string()), "{errors:?}");
}

#[test]
fn edits_reload_and_a_broken_edit_keeps_the_last_good_plugin() {
    let d = copy(&examples()[1], "reload_toon");
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
