//! Loading documents (presets) for headless use, and the built-in default document.

use std::path::Path;

use anyhow::Result;
use vwb_render::Camera;
use vwb_render::plugin::{PluginInstance, Registry};
use vwb_render::preset::{Document, RenderSection, VolumeSource};

/// The preset the workbench opens on (embedded, so it runs anywhere).
pub const DEMO_PRESET: &str = include_str!("../../presets/demo.ron");

/// The window's first image (a start with no arguments): the embedded demo,
/// pre-integrated and lit, shaded at the slab centroid (docs/perf.md, "First image").
pub const FIRST_IMAGE_PRESET: &str = include_str!("../../presets/first_image.ron");

/// The document the window opens on when it is started with no arguments and no
/// last session: `presets/first_image.ron` (else [`default_document`]).
pub fn first_document(registry: &Registry) -> Document {
    embedded(FIRST_IMAGE_PRESET, "presets/first_image.ron", registry)
        .unwrap_or_else(|| default_document(registry))
}

/// An embedded preset's document, or None (logged) when it does not parse with
/// `registry`.
fn embedded(text: &str, name: &str, registry: &Registry) -> Option<Document> {
    Document::parse(text, name, registry)
        .map(|loaded| loaded.document)
        .map_err(|e| log::error!("{e}"))
        .ok()
}

/// The document shown when no preset is given: `presets/demo.ron` (the embedded demo
/// volume with a 1D transfer function).
pub fn default_document(registry: &Registry) -> Document {
    if let Some(doc) = embedded(DEMO_PRESET, "presets/demo.ron", registry) {
        return doc;
    }
    let stack = registry
        .get("classify.tf1d")
        .map(|p| vec![PluginInstance::new(p)])
        .unwrap_or_default();
    Document {
        description: "demo: MRI head with the default 1D transfer function".into(),
        volume: VolumeSource::Demo,
        camera: Camera::default(),
        render: RenderSection::default(),
        stack,
    }
}

/// Loads a preset (or the built-in default document) with the built-in plugins and
/// prints its warnings; the volume it names is protected from being overwritten by
/// outputs.
pub fn load_document(preset: Option<&Path>) -> Result<Document> {
    let registry = vwb_plugins::registry();
    let Some(path) = preset else {
        return Ok(default_document(&registry));
    };
    let loaded = Document::load(path, &registry)?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    crate::outputs::protect_document(Some(path), &loaded.document);
    Ok(loaded.document)
}
