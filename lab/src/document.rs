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
        volumes: Default::default(),
        camera: Camera::default(),
        render: RenderSection::default(),
        stack,
    }
}

/// The data-driven suggestion for `volume` as a 1D TF (`vwb_render::suggest`:
/// boundaries by Kindlmann and Durkin's method, noise filtered, the background
/// transparent) and a note saying so, or why there is none (no boundary above the
/// noise, a vector volume).
pub fn suggested_tf(
    volume: &vwb_render::Volume,
) -> std::result::Result<(vwb_render::tf::TfCurve, String), String> {
    use vwb_render::suggest::{SuggestOptions, suggest};
    let s = suggest(volume, &SuggestOptions::default()).map_err(|e| e.to_string())?;
    if !s.found() {
        return Err(format!(
            "{}: no boundary found above the noise; the transfer function stays",
            volume.name
        ));
    }
    let note = format!(
        "{}: boundaries found, transfer function suggested (pre-filter σ {} voxels)",
        volume.name, s.smoothing
    );
    Ok((s.curve, note))
}

/// Starts the first enabled `classify.tf1d` of `doc` from [`suggested_tf`] for
/// `volume`, as a volume opened without a preset is shown. `Ok` says what was set;
/// `Err` why the TF stays (no boundary above the noise, a vector volume, no 1D TF in
/// the stack).
pub fn start_from_suggestion(
    doc: &mut Document,
    volume: &vwb_render::Volume,
) -> std::result::Result<String, String> {
    let tf = doc
        .stack
        .iter_mut()
        .find(|i| i.enabled && i.plugin.id() == "classify.tf1d")
        .ok_or("the stack has no 1D transfer function to suggest")?;
    let (curve, note) = suggested_tf(volume)?;
    tf.params
        .set("tf", vwb_render::params::ParamValue::Tf(curve));
    Ok(note)
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

/// Adds a named volume to `doc` (`volumes:`, which plugins' volume inputs name):
/// `source` is a file or a sample name ([`crate::headless::volume_arg`]), `name` a new
/// volume name, or empty for the file's or sample's stem. It loads at once; a name
/// that is taken or not a name, or a source that does not load, is an error naming it,
/// and `doc` is left as it was. Returns the name and the document's named volumes,
/// loaded (for `Renderer::set_inputs`).
pub fn add_named_volume(
    doc: &mut Document,
    name: &str,
    source: &str,
) -> Result<(String, vwb_render::inputs::VolumeInputs)> {
    let (name, source) = name_new_volume(doc, name, source)?;
    let inputs = insert_named_volume(doc, &name, source)?;
    Ok((name, inputs))
}

/// Puts the named volume `name` from `source` (as [`name_new_volume`] gives them) into
/// `doc` and loads the document's named volumes. A name taken (since it was chosen) or
/// a source that does not load is an error, and `doc` is left as it was.
pub fn insert_named_volume(
    doc: &mut Document,
    name: &str,
    source: VolumeSource,
) -> Result<vwb_render::inputs::VolumeInputs> {
    name_is_free(doc, name)?;
    let mut with = doc.clone();
    with.volumes.insert(name.to_string(), source);
    let inputs = crate::headless::inputs_for(&with)?;
    *doc = with;
    Ok(inputs)
}

fn name_is_free(doc: &Document, name: &str) -> Result<()> {
    if doc.volumes.contains_key(name) {
        anyhow::bail!("the document already has a volume named '{name}'");
    }
    Ok(())
}

/// The name and source a new named volume of `doc` takes, loading nothing (what
/// [`add_named_volume`] checks first): `source` a file or a sample name, `name` a new
/// volume name (empty: the file's or sample's stem). An error where the name is not a
/// volume name or is taken.
pub fn name_new_volume(doc: &Document, name: &str, source: &str) -> Result<(String, VolumeSource)> {
    use anyhow::bail;
    let source = crate::headless::volume_arg(Path::new(source));
    let name = match (name, &source) {
        ("", VolumeSource::Sample(n)) => vwb_render::params::volume_name_for(Path::new(n)),
        ("", VolumeSource::File(p)) => vwb_render::params::volume_name_for(p),
        (n, _) => n.to_string(),
    };
    if !vwb_render::params::valid_volume_name(&name) {
        bail!("'{name}' is not a volume name (letters, digits and _, not starting with a digit)");
    }
    name_is_free(doc, &name)?;
    Ok((name, source))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A volume opened without a preset starts from its suggestion; a volume with no
    /// boundary (or a stack without a 1D TF) keeps its TF and says why.
    #[test]
    fn a_volume_without_a_preset_starts_from_its_suggestion() {
        let registry = vwb_plugins::registry();
        let volume = vwb_render::volume::demo();
        let mut doc = first_document(&registry);
        let note = start_from_suggestion(&mut doc, &volume).unwrap();
        assert!(note.contains("suggested"), "{note}");
        let expected = vwb_render::suggest::suggest(&volume, &Default::default())
            .unwrap()
            .curve;
        let tf = doc
            .stack
            .iter()
            .find(|i| i.plugin.id() == "classify.tf1d")
            .unwrap();
        assert_eq!(
            tf.params.get("tf"),
            Some(&vwb_render::params::ParamValue::Tf(expected))
        );
        // a linear ramp: the same gradient everywhere, no boundary
        let flat = vwb_render::Volume::new(
            "ramp",
            [16, 16, 16],
            1,
            [1.0; 3],
            vwb_render::volume::VoxelData::F32((0..4096).map(|i| (i % 16) as f32).collect()),
        )
        .unwrap();
        let mut kept = first_document(&registry);
        let before = kept.stack.clone();
        let e = start_from_suggestion(&mut kept, &flat).unwrap_err();
        assert!(e.contains("ramp") && e.contains("no boundary"), "{e}");
        assert_eq!(kept.stack.len(), before.len());
        for (a, b) in kept.stack.iter().zip(&before) {
            assert_eq!(a.params, b.params);
        }
        doc.stack.retain(|i| i.plugin.id() != "classify.tf1d");
        assert!(
            start_from_suggestion(&mut doc, &volume)
                .unwrap_err()
                .contains("no 1D")
        );
    }
}
