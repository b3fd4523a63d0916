//! The document's named volumes in the window (`volumes:` in a preset): the volumes
//! that plugins' volume inputs name beside the document's own (a label volume for
//! `classify.labels` and `clip.labels`, a vector field for `flow.lic3d`).
//!
//! The section lists each named volume with its source, grid and components, adds one
//! from a file (typed, or chosen with *…*) or a sample by name, and removes one that
//! no plugin names. A plugin's volume input then picks the name from its list. A new
//! volume loads at once (named volumes are usually small: label volumes, fields); an
//! error names the volume and its file and changes nothing.

use vwb_render::inputs::VolumeInputs;
use vwb_render::preset::{Document, VolumeSource};

/// What the section's fields hold between frames.
#[derive(Debug, Default)]
pub struct NamedVolumesUi {
    /// The name to add under (empty: the file's stem).
    pub name: String,
    /// The file or sample name to add.
    pub source: String,
}

/// What the user asked of the section.
#[derive(Debug, Clone, PartialEq)]
pub enum VolumesAction {
    /// Add `source` under `name`.
    Add { name: String, source: String },
    /// Remove the named volume.
    Remove(String),
    /// Choose the file with the file dialog.
    Browse,
}

/// How the section shows a volume's source.
pub fn describe_source(source: &VolumeSource) -> String {
    match source {
        VolumeSource::Demo => "the embedded demo".into(),
        VolumeSource::File(p) => p
            .file_name()
            .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into()),
        VolumeSource::Sample(n) => format!("sample {n}"),
        VolumeSource::Analytic(f) => format!("analytic {:?} {:?}", f.field, f.size),
        VolumeSource::Phantom(p) => format!("phantom {:?}", p.size),
        VolumeSource::Resampled(r) => {
            format!("{} resampled to {:?}", describe_source(&r.source), r.size)
        }
    }
}

/// A volume's grid, and its components where it is a vector volume: `64×64×64`,
/// `32×32×32 × 3 components`.
pub fn describe_grid(v: &vwb_render::Volume) -> String {
    let [x, y, z] = v.dims;
    if v.components == 1 {
        format!("{x}×{y}×{z}")
    } else {
        format!("{x}×{y}×{z} × {} components", v.components)
    }
}

/// The plugins (as `id.key`) whose volume inputs name `name` in `doc`.
pub fn users_of(doc: &Document, name: &str) -> Vec<String> {
    doc.stack
        .iter()
        .flat_map(|inst| {
            inst.plugin
                .params()
                .into_iter()
                .filter(|s| matches!(s.kind, vwb_render::params::ParamKind::Volume { .. }))
                .filter(|s| inst.params.volume(s.key) == name)
                .map(|s| format!("{}.{}", inst.plugin.id(), s.key))
                .collect::<Vec<_>>()
        })
        .collect()
}

impl NamedVolumesUi {
    /// The section's body: the list, then the fields to add one.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        doc: &Document,
        inputs: &VolumeInputs,
    ) -> Option<VolumesAction> {
        let mut action = None;
        if doc.volumes.is_empty() {
            ui.weak("none: plugins' volume inputs read the volume itself");
        }
        for (name, source) in &doc.volumes {
            ui.horizontal(|ui| {
                let grid = inputs
                    .get(name)
                    .map_or_else(String::new, |v| format!(", {}", describe_grid(v)));
                ui.label(format!("{name}: {}{grid}", describe_source(source)));
                let users = users_of(doc, name);
                let remove = ui.add_enabled(users.is_empty(), egui::Button::new("Remove"));
                let remove = if users.is_empty() {
                    remove.on_hover_text(format!("remove the named volume '{name}'"))
                } else {
                    remove.on_disabled_hover_text(format!("named by {}", users.join(", ")))
                };
                if remove.clicked() {
                    action = Some(VolumesAction::Remove(name.clone()));
                }
            });
        }
        ui.horizontal(|ui| {
            ui.add(
                egui::TextEdit::singleline(&mut self.name)
                    .desired_width(70.0)
                    .hint_text("name")
                    .id_salt("named volume name"),
            )
            .on_hover_text(
                "the name plugins' volume inputs pick (letters, digits and _); empty: the file's stem",
            );
            ui.add(
                egui::TextEdit::singleline(&mut self.source)
                    .desired_width(120.0)
                    .hint_text("file or sample")
                    .id_salt("named volume source"),
            )
            .on_hover_text("a volume file or a sample name (e.g. a label volume beside the data)");
            if ui
                .button("…")
                .on_hover_text("choose the named volume's file")
                .clicked()
            {
                action = Some(VolumesAction::Browse);
            }
            if ui
                .add_enabled(!self.source.trim().is_empty(), egui::Button::new("Add"))
                .on_hover_text("load it and add it to the document's named volumes")
                .clicked()
            {
                action = Some(VolumesAction::Add {
                    name: self.name.trim().to_string(),
                    source: self.source.trim().to_string(),
                });
            }
        });
        action
    }
}
