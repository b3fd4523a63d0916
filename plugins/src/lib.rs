//! vwb plugins: the plugin API (re-exported from the renderer core) and the built-in
//! plugins, one folder each (`mod.rs`, its `.wgsl`, its CPU twin and tests).
//!
//! Adding a plugin: copy a folder, change its id, and add one line to the
//! `builtin_plugins!` list below (docs/plugins.md). The pipeline is never edited.

pub use vwb_render::params;
pub use vwb_render::plugin::*;

pub mod held;
pub mod label_input;
pub mod lighting;
#[cfg(feature = "ui")]
pub mod ui;
pub mod user;

use std::sync::Arc;

use params::{ParamKind, ParamValue, ParamValues};

/// Declares each plugin folder as a module and lists its plugin in
/// [`builtin_registry`], so that a new plugin is one line here. A plugin with widgets of
/// its own (drawn above the generated ones in the window) names them on the same line
/// after `; ui`: a function in its folder (or in a module plugins share, as the label
/// plugins share `label_input`), compiled with the `ui` feature only, so the
/// plugins stay free of egui for headless users.
macro_rules! builtin_plugins {
    ($($folder:ident => $plugin:expr $(; ui $widgets:path)?,)*) => {
        $(pub mod $folder;)*

        /// Every built-in plugin, in registration order.
        fn builtin_plugins() -> Vec<Arc<dyn Plugin>> {
            vec![$(Arc::new($plugin)),*]
        }

        /// The plugins' own widgets, by plugin id.
        #[cfg(feature = "ui")]
        fn builtin_widgets() -> Vec<(String, ui::CustomUi)> {
            let mut all: Vec<(String, ui::CustomUi)> = Vec::new();
            $($(
                let p: Arc<dyn Plugin> = Arc::new($plugin);
                all.push((p.id().to_string(), $widgets));
            )?)*
            all
        }
    };
}

// One line per plugin: its folder and its value (and its own widgets, if any).
builtin_plugins! {
    clip_shapes => clip_shapes::Shapes::default(),
    clip_labels => clip_labels::ClipLabels; ui label_input::present_labels,
    clip_mesh => clip_mesh::ClipMesh::default(),
    sample_jitter => sample_jitter::Jitter,
    classify_tf1d => classify_tf1d::Tf1d::default(),
    classify_labels => classify_labels::Labels; ui label_input::present_labels,
    classify_tf2d => classify_tf2d::Tf2dPlugin::default(),
    shade_blinn_phong => shade_blinn_phong::BlinnPhong::default(),
    shade_isosurface => shade_isosurface::Isosurface::default(),
    shade_envmap => shade_envmap::EnvMap::default(),
    shade_dos => shade_dos::Dos::default(); ui shade_dos::ui::cone,
    shade_cook_torrance => shade_cook_torrance::CookTorrance::default(),
    shade_oren_nayar => shade_oren_nayar::OrenNayar::default(),
    shade_toon => shade_toon::Toon::default(),
    shade_hernell => shade_hernell::Hernell::default(),
    shade_sweep => shade_sweep::SweepShadows::default(),
    composite_tonemap => composite_tonemap::Tonemap,
    flow_arrival => flow_arrival::Arrival::default(),
    flow_lic3d => flow_lic3d::Lic3d::default(),
    test_slice_shadow => test_slice_shadow::SliceShadow,
    test_smooth => test_smooth::Smooth,
    test_vector_passes => test_vector_passes::VectorPasses::default(),
}

/// Every built-in plugin.
pub fn builtin_registry() -> Registry {
    let mut r = Registry::new();
    let all = builtin_plugins();
    for p in all {
        // built-ins are unique by construction; a clash is a programming error caught by tests
        if let Err(e) = r.register(p) {
            log::error!("{e}");
        }
    }
    r
}

/// The built-in plugins and the installed user plugins ([`user::install`]); a user
/// plugin whose id clashes is left out with an error in the log.
pub fn registry() -> Registry {
    let mut r = builtin_registry();
    for p in user::plugins() {
        if let Err(e) = r.register(p) {
            log::error!("{e}");
        }
    }
    r
}

/// Every structural mode of a plugin: its defaults (its demo parameters where it has
/// them, [`Plugin::demo_params`]), then each option of each structural enum parameter
/// and the other value of each structural bool in turn (the others as in the first), as
/// (label, values). The tests use it to cover every registered plugin in every
/// mode without a hand-kept list.
pub fn structural_modes(p: &dyn Plugin) -> Vec<(String, ParamValues)> {
    let specs = p.params();
    let defaults = p
        .demo_params()
        .unwrap_or_else(|| ParamValues::defaults(&specs));
    let mut modes = vec![("defaults".to_string(), defaults.clone())];
    for spec in specs.iter().filter(|s| s.structural) {
        if let ParamKind::Enum { options, default } = &spec.kind {
            for o in options
                .iter()
                .enumerate()
                .filter(|(i, _)| i != default)
                .map(|(_, o)| o)
            {
                let mut values = defaults.clone();
                values.set(spec.key, ParamValue::Enum(o.to_string()));
                modes.push((format!("{}={o}", spec.key), values));
            }
        }
        if let ParamKind::Bool { default } = spec.kind {
            let mut values = defaults.clone();
            values.set(spec.key, ParamValue::Bool(!default));
            modes.push((format!("{}={}", spec.key, !default), values));
        }
    }
    modes
}

#[cfg(test)]
mod tests {
    use super::*;
    use vwb_render::composer::{TargetFormat, compose};

    #[test]
    fn builtins_register_without_clash() {
        let r = builtin_registry();
        assert_eq!(r.plugins().len(), 22);
        let mut fresh = Registry::new();
        for p in r.plugins() {
            fresh.register(p.clone()).unwrap();
        }
        assert!(fresh.register(r.plugins()[0].clone()).is_err());
    }

    /// Every built-in probe runs at its defaults (the sample data aside: the suggestion's
    /// default is the embedded demo) and reports each of its figures once, finite.
    #[test]
    fn every_probe_runs_at_its_defaults_and_reports_its_figures() {
        let r = builtin_registry();
        let mut n = 0;
        for p in r.plugins() {
            for probe in p.probes() {
                let params = vwb_render::params::ParamValues::defaults(&probe.params());
                let out = probe
                    .run(&params)
                    .unwrap_or_else(|e| panic!("{}.{}: {e}", p.id(), probe.name()));
                let names: Vec<&str> = out.iter().map(|s| s.name).collect();
                let want: Vec<&str> = probe.figures().iter().map(|(f, _)| *f).collect();
                assert_eq!(names, want, "{}.{}", p.id(), probe.name());
                assert!(
                    out.iter().all(|s| s.value.is_finite()),
                    "{}.{}: {out:?}",
                    p.id(),
                    probe.name()
                );
                n += 1;
            }
        }
        assert!(n >= 6, "{n} probes");
    }

    #[test]
    fn every_builtin_composes_alone_and_twice() {
        let r = builtin_registry();
        let all: Vec<_> = r
            .plugins()
            .iter()
            .flat_map(|p| {
                structural_modes(p.as_ref())
                    .into_iter()
                    .map(|(_, values)| p.configure(&values).unwrap_or_else(|| p.clone()))
            })
            .collect();
        assert!(all.len() >= 5, "tf1d's three modes are composed");
        for p in &all {
            let one: Vec<&dyn Plugin> = vec![p.as_ref()];
            compose(&one, TargetFormat::Rgba16Float, &wgpu::Limits::default())
                .unwrap_or_else(|e| panic!("{}: {e}", p.id()));
            // two instances of one plugin never collide
            let two: Vec<&dyn Plugin> = vec![p.as_ref(), p.as_ref()];
            compose(&two, TargetFormat::Rgba32Float, &wgpu::Limits::default())
                .unwrap_or_else(|e| panic!("{} twice: {e}", p.id()));
        }
    }
}
