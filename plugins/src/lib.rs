//! vwb plugins: the plugin API (re-exported from the renderer core) and the built-in
//! plugins, one folder each (`mod.rs`, its `.wgsl`, its CPU twin and tests).
//!
//! Adding a plugin: copy a folder, change its id, and add one line to
//! [`builtin_registry`]. The pipeline is never edited.

pub use vwb_render::params;
pub use vwb_render::plugin::*;

pub mod classify_labels;
pub mod classify_tf1d;
pub mod classify_tf2d;
pub mod lighting;
pub mod shade_blinn_phong;
pub mod shade_dos;
pub mod shade_envmap;
pub mod shade_isosurface;
pub mod test_slice_shadow;
pub mod test_smooth;

use std::sync::Arc;

/// Every built-in plugin. One line per plugin.
pub fn builtin_registry() -> Registry {
    let mut r = Registry::new();
    let all: Vec<Arc<dyn Plugin>> = vec![
        Arc::new(classify_tf1d::Tf1d::default()),
        Arc::new(classify_labels::Labels),
        Arc::new(classify_tf2d::Tf2dPlugin::default()),
        Arc::new(shade_blinn_phong::BlinnPhong::default()),
        Arc::new(shade_isosurface::Isosurface::default()),
        Arc::new(shade_envmap::EnvMap::default()),
        Arc::new(shade_dos::Dos::default()),
        Arc::new(test_slice_shadow::SliceShadow),
        Arc::new(test_smooth::Smooth),
    ];
    for p in all {
        // built-ins are unique by construction; a clash is a programming error caught by tests
        if let Err(e) = r.register(p) {
            log::error!("{e}");
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use vwb_render::composer::{TargetFormat, compose};

    #[test]
    fn builtins_register_without_clash() {
        let r = builtin_registry();
        assert_eq!(r.plugins().len(), 9);
        let mut fresh = Registry::new();
        for p in r.plugins() {
            fresh.register(p.clone()).unwrap();
        }
        assert!(fresh.register(r.plugins()[0].clone()).is_err());
    }

    /// Every configuration a structural enum parameter selects, per built-in.
    fn configurations(p: &Arc<dyn Plugin>) -> Vec<Arc<dyn Plugin>> {
        let mut all = vec![p.clone()];
        for spec in p.params().iter().filter(|s| s.structural) {
            if let params::ParamKind::Enum { options, .. } = &spec.kind {
                for o in options {
                    let mut values = params::ParamValues::defaults(&p.params());
                    values.set(spec.key, params::ParamValue::Enum(o.to_string()));
                    if let Some(c) = p.configure(&values) {
                        all.push(c);
                    }
                }
            }
        }
        all
    }

    #[test]
    fn every_builtin_composes_alone_and_twice() {
        let r = builtin_registry();
        let all: Vec<_> = r.plugins().iter().flat_map(configurations).collect();
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
