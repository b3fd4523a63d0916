//! Coverage by construction: every registered plugin, in every structural mode its
//! enum parameters select ([`vwb_plugins::structural_modes`]), is composed and
//! naga-validated, rendered on both backends and compared with its CPU twin. There is
//! no hand-kept list: a plugin added to the registry is covered here, and one without
//! a twin fails.

use std::sync::{Arc, OnceLock};

use vwb_render::params::ParamValues;
use vwb_render::plugin::Category;
use vwb_render::{Backend, PluginInstance, TargetFormat, Volume};

use crate::common::*;
use crate::reference::{delta_e_rms, delta_e_rms_near, gpu_and_references_with};

/// The stack that shows `id` in the mode `values`: a classifier alone, anything else
/// after the default 1D transfer function.
fn stack_for(id: &str, values: &ParamValues) -> Vec<PluginInstance> {
    let mut p = instance(id);
    p.params = values.clone();
    if p.plugin.category() == Category::Classify {
        vec![p]
    } else {
        vec![instance("classify.tf1d"), p]
    }
}

/// The demo, but half its resolution for `shade.hernell`: its light volume (the GPU's
/// pass on lavapipe and the f64 twin's, with scattering) cost about 16 s per mode at
/// 128×128×84 and 2 at 64×64×42 (session 61), six modes in all; each mode's arithmetic
/// is the same at either size, and tests/integration/hernell.rs and the shipped
/// presets hold the full-size volumes.
fn volume_for(id: &str) -> Arc<Volume> {
    static HALF: OnceLock<Arc<Volume>> = OnceLock::new();
    if id != "shade.hernell" {
        return demo();
    }
    HALF.get_or_init(|| Arc::new(demo().resampled([64, 64, 42]).unwrap()))
        .clone()
}

#[test]
fn every_registered_plugin_in_every_mode_matches_its_cpu_twin() {
    let registry = registry();
    let mut covered = Vec::new();
    let mut failed = Vec::new();
    let mut worst = (0.0f64, String::new());
    for plugin in registry.plugins() {
        let id = plugin.id();
        for (mode, values) in vwb_plugins::structural_modes(plugin.as_ref()) {
            let configured = plugin.configure(&values).unwrap_or_else(|| plugin.clone());
            assert!(
                configured.cpu_twin(&values).is_some(),
                "{id} ({mode}) has no CPU twin"
            );
            let per_slice = configured.slice_state().is_some();
            let stack = stack_for(id, &values);
            let both = [Backend::Compute, Backend::Raster].map(|b| settings(48, 48, b));
            let images = gpu_and_references_with(
                volume_for(id),
                &plugin.demo_inputs(),
                &stack,
                TargetFormat::Rgba32Float,
                &both,
            );
            for (s, (px, reference)) in both.iter().zip(images) {
                let backend = s.backend;
                assert!(
                    reference.iter().filter(|p| p[3] > 0.05).count() > 48 * 48 / 20,
                    "{id} ({mode}): the volume is visible"
                );
                let rms = delta_e_rms(&px, &reference, 48, 48);
                let near = delta_e_rms_near(&px, &reference, 48, 48);
                eprintln!(
                    "{id} ({mode}) {}: ΔE*uv RMS {rms:.4} (near {near:.4})",
                    backend.name()
                );
                // the bounds and measure of every_shipped_preset_matches_its_cpu_twins;
                // a GPU's where the texture unit filters 8-bit codes
                let (bound, use_near) = twin_bound_of(backend, per_slice, filters_unorm8(&values));
                let measured = if use_near { near } else { rms };
                if measured >= bound {
                    failed.push(format!("{id} ({mode}) {}: ΔE*uv RMS {rms}", backend.name()));
                }
                if rms > worst.0 {
                    worst = (rms, format!("{id} ({mode}) {}", backend.name()));
                }
            }
            covered.push(format!("{id} ({mode})"));
        }
    }
    eprintln!(
        "{} plugin modes covered; worst ΔE*uv RMS {:.4} ({})",
        covered.len(),
        worst.0,
        worst.1
    );
    // every mode measured before failing, so that one run shows them all
    assert!(failed.is_empty(), "{failed:#?}");
    for id in registry.ids() {
        assert!(
            covered.iter().any(|c| c.starts_with(&format!("{id} ("))),
            "{id} is covered"
        );
    }
}
