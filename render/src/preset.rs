//! Presets: the whole document (volume source, camera, slice settings, backend, the
//! ordered plugin list with enabled flags and parameters) in RON, with a `version`.
//!
//! - Only non-default parameters are saved.
//! - Unknown keys (anywhere in the document, or unknown parameter keys) are warnings.
//! - Bad values are errors naming the file and the path, e.g.
//!   `ct.ron: plugins[0] classify.tf1d.opacity: 200 is outside [0.01, 100]`.
//! - Saves are atomic: a temporary file in the same folder is renamed over the target,
//!   so a failed save never destroys the previous file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::camera::Camera;
use crate::composer::TargetFormat;
use crate::params::ParamValues;
use crate::plugin::{PluginInstance, Registry};
use crate::renderer::{Backend, FrameSettings};

pub const PRESET_VERSION: u32 = 1;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub enum VolumeSource {
    /// The demo volume embedded in the binary.
    #[default]
    Demo,
    /// A volume file; relative paths are relative to the preset's folder.
    File(PathBuf),
    /// A sample data set by name (`render/data/samples.ron`), found in the data
    /// directory ([`crate::samples::data_dir`]).
    Sample(String),
    /// A generated analytic vector field ([`crate::flow::AnalyticField`]), e.g.
    /// `Analytic((field: Tornado, size: (64, 64, 64)))`.
    Analytic(crate::flow::AnalyticField),
    /// A generated scalar phantom of voxel-aligned boxes
    /// ([`crate::volume::phantom::Phantom`]), e.g.
    /// `Phantom((size: (32, 32, 32), boxes: [(from: (0, 0, 20), to: (32, 32, 24), value: 1.0)]))`.
    Phantom(crate::volume::phantom::Phantom),
    /// Another source on a grid of `size` voxels over the same box, by nearest
    /// neighbour ([`crate::volume::Volume::resampled`]), e.g. the CT head at twice its
    /// resolution: `Resampled((source: Sample("ct_head"), size: (512, 512, 216)))`.
    Resampled(Resampled),
}

/// A [`VolumeSource::Resampled`]: the source and the grid it is resampled to.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Resampled {
    pub source: Box<VolumeSource>,
    /// 2–1024 voxels per side.
    pub size: [u32; 3],
}

impl VolumeSource {
    /// The file it reads, within a resampled source too (relative paths are the
    /// preset's); `None` for the demo, samples and generated volumes.
    pub fn file(&self) -> Option<&std::path::Path> {
        match self {
            VolumeSource::File(p) => Some(p),
            VolumeSource::Resampled(r) => r.source.file(),
            _ => None,
        }
    }

    /// [`VolumeSource::file`], to rewrite it.
    pub fn file_mut(&mut self) -> Option<&mut PathBuf> {
        match self {
            VolumeSource::File(p) => Some(p),
            VolumeSource::Resampled(r) => r.source.file_mut(),
            _ => None,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RenderSection {
    /// Distance between slices in voxels.
    pub slice_spacing: f32,
    pub backend: Backend,
    pub target: TargetFormat,
    /// Stop rays at this opacity (the raster backend at the end of a run of slices,
    /// [`crate::renderer::raster_et_interval`]).
    pub early_termination: Option<f32>,
    /// Background the image is composited over (straight RGBA; alpha ignored).
    pub background: [f32; 4],
    /// Default image size.
    pub size: [u32; 2],
    /// Skip the hooks of samples in bricks that cannot be visible (render/src/skipping.rs);
    /// never changes the image.
    pub empty_space_skipping: bool,
    /// Raster backend: proxy polygons cut to the occupied bricks' cells
    /// ([`crate::Renderer::set_occupied_proxy`]); the same image up to float rounding.
    /// Written only when on.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub occupied_proxy: bool,
    /// Raster backend: proxy polygons cut to the occupied bricks' hull
    /// ([`crate::renderer::HullProxy::Cut`]): faster where air surrounds the matter,
    /// the image moved by the rounding of interpolated sample positions. Off, the
    /// polygons are drawn under a scissor to that hull, which keeps the image bit for
    /// bit. Written only when on.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub hull_cut: bool,
    /// Raster backend: slices per proxy polygon, 1, 2, 4, 8 or 16
    /// ([`crate::Renderer::set_raster_group`], Rezk-Salama 2001 §9.1): fewer
    /// polygons, depth tests and blends for the same samples, the image moved by the
    /// rounding of the blends and sample positions. 0 (the default, "auto"): a polygon
    /// per slice, or [`crate::renderer::RASTER_GROUP_WITH_TERMINATION`] slices per
    /// polygon where `early_termination` is on. Written only when not 0.
    #[serde(skip_serializing_if = "is_auto_group")]
    pub slices_per_proxy: u32,
    /// How the volume is stored on the GPU ([`crate::renderer::VolumeFormat`]);
    /// written only when not `Auto`.
    #[serde(skip_serializing_if = "crate::renderer::VolumeFormat::is_auto")]
    pub volume_format: crate::renderer::VolumeFormat,
    /// How the classification tables are stored on the GPU
    /// ([`crate::renderer::TableFormat`]); written only when not `Auto`.
    #[serde(skip_serializing_if = "crate::renderer::TableFormat::is_auto")]
    pub table_format: crate::renderer::TableFormat,
}

impl RenderSection {
    /// The raster backend's fit to the occupied bricks' hull this section asks for:
    /// [`crate::renderer::HullProxy::Cut`] with `hull_cut`, else the renderer's default
    /// (`Scissor`, or what the benchmark switch `VWB_HULL_PROXY` says).
    pub fn hull_proxy(&self) -> crate::renderer::HullProxy {
        if self.hull_cut {
            crate::renderer::HullProxy::Cut
        } else {
            crate::renderer::HullProxy::from_env()
        }
    }

    /// The raster backend's slices per proxy polygon this section asks for:
    /// `slices_per_proxy` where it is not auto, else the renderer's default
    /// ([`crate::renderer::RASTER_GROUP_AUTO`], or what the benchmark switch
    /// `VWB_RASTER_GROUP` says).
    pub fn raster_group(&self) -> u32 {
        if self.slices_per_proxy != crate::renderer::RASTER_GROUP_AUTO {
            self.slices_per_proxy
        } else {
            crate::renderer::raster_group_from_env()
        }
    }
}

impl Default for RenderSection {
    fn default() -> Self {
        Self {
            slice_spacing: 1.0,
            backend: Backend::Raster,
            target: TargetFormat::Rgba16Float,
            early_termination: None,
            background: [0.0, 0.0, 0.0, 1.0],
            size: [512, 512],
            empty_space_skipping: true,
            occupied_proxy: false,
            hull_cut: false,
            slices_per_proxy: crate::renderer::RASTER_GROUP_AUTO,
            volume_format: crate::renderer::VolumeFormat::Auto,
            table_format: crate::renderer::TableFormat::Auto,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PluginEntry {
    pub id: String,
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub enabled: bool,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub params: BTreeMap<String, ron::Value>,
}

fn is_auto_group(n: &u32) -> bool {
    *n == crate::renderer::RASTER_GROUP_AUTO
}

fn yes() -> bool {
    true
}
fn is_true(b: &bool) -> bool {
    *b
}

/// The file format.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PresetFile {
    pub version: u32,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    #[serde(default)]
    pub volume: VolumeSource,
    /// Named volumes beside `volume`, each with its own grid, spacing and components,
    /// that plugins' volume inputs name ([`crate::inputs`]); e.g.
    /// `volumes: {"wind": Sample("storm_wind")}`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub volumes: BTreeMap<String, VolumeSource>,
    #[serde(default)]
    pub camera: Camera,
    #[serde(default)]
    pub render: RenderSection,
    #[serde(default)]
    pub plugins: Vec<PluginEntry>,
}

/// A resolved document: plugins looked up in the registry, parameters typed.
#[derive(Debug, Clone)]
pub struct Document {
    pub description: String,
    pub volume: VolumeSource,
    /// Named volumes that plugins' volume inputs name ([`PresetFile::volumes`]).
    pub volumes: BTreeMap<String, VolumeSource>,
    pub camera: Camera,
    pub render: RenderSection,
    pub stack: Vec<PluginInstance>,
}

#[derive(Debug, thiserror::Error)]
pub enum PresetError {
    /// The cause is part of the message (not a `source`), so that error chains print
    /// it once.
    #[error("{file}: {cause}")]
    Io { file: String, cause: std::io::Error },
    #[error("{file}: {message}")]
    Syntax { file: String, message: String },
    #[error("{file}: {path}: {message}")]
    Value {
        file: String,
        path: String,
        message: String,
    },
}

/// A parsed document and the warnings met on the way.
#[derive(Debug)]
pub struct Loaded {
    pub document: Document,
    pub warnings: Vec<String>,
}

impl Document {
    pub fn frame_settings(&self) -> FrameSettings {
        FrameSettings {
            camera: self.camera,
            width: self.render.size[0],
            height: self.render.size[1],
            slice_spacing: self.render.slice_spacing,
            backend: self.render.backend,
            early_termination: self.render.early_termination,
        }
    }

    /// Loads a preset file.
    pub fn load(path: &Path, registry: &Registry) -> Result<Loaded, PresetError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|cause| PresetError::Io {
            file: file.clone(),
            cause,
        })?;
        let mut loaded = Self::parse(&text, &file, registry)?;
        // relative volume paths are relative to the preset
        let doc = &mut loaded.document;
        for source in std::iter::once(&mut doc.volume).chain(doc.volumes.values_mut()) {
            if let Some(p) = source.file_mut()
                && p.is_relative()
                && let Some(dir) = path.parent()
            {
                *p = dir.join(&*p);
            }
        }
        // and so are path parameters (e.g. environment maps, meshes)
        if let Some(dir) = path.parent() {
            for inst in &mut loaded.document.stack {
                for v in inst.params.values.values_mut() {
                    if let crate::params::ParamValue::Path(p) = v
                        && p.is_relative()
                        && !p.as_os_str().is_empty()
                    {
                        *p = dir.join(&*p);
                    }
                }
            }
        }
        Ok(loaded)
    }

    /// Parses preset text; `file` names the source in messages.
    pub fn parse(text: &str, file: &str, registry: &Registry) -> Result<Loaded, PresetError> {
        let mut warnings = Vec::new();
        let syntax = |message: String| PresetError::Syntax {
            file: file.to_string(),
            message,
        };
        let mut de = ron::Deserializer::from_str(text).map_err(|e| syntax(e.to_string()))?;
        let raw: PresetFile = serde_ignored::deserialize(&mut de, |p| {
            warnings.push(format!("{file}: unknown key '{p}' ignored"));
        })
        .map_err(|e| syntax(de.span_error(e).to_string()))?;
        de.end().map_err(|e| syntax(de.span_error(e).to_string()))?;
        let value_err = |path: String, message: String| PresetError::Value {
            file: file.to_string(),
            path,
            message,
        };
        if raw.version != PRESET_VERSION {
            return Err(value_err(
                "version".into(),
                format!(
                    "version {} is not supported (expected {PRESET_VERSION})",
                    raw.version
                ),
            ));
        }
        let r = &raw.render;
        if !(r.slice_spacing.is_finite() && r.slice_spacing > 0.0) {
            return Err(value_err(
                "render.slice_spacing".into(),
                format!("{} must be finite and > 0", r.slice_spacing),
            ));
        }
        if r.size[0] == 0 || r.size[1] == 0 || r.size[0] > 16384 || r.size[1] > 16384 {
            return Err(value_err(
                "render.size".into(),
                format!("{:?} must be within 1..=16384 per side", r.size),
            ));
        }
        if !crate::renderer::is_raster_group_setting(r.slices_per_proxy) {
            return Err(value_err(
                "render.slices_per_proxy".into(),
                format!(
                    "{} must be 0 (auto) or one of {:?}",
                    r.slices_per_proxy,
                    crate::renderer::RASTER_GROUPS
                ),
            ));
        }
        if let Some(t) = r.early_termination
            && !(t > 0.0 && t <= 1.0)
        {
            return Err(value_err(
                "render.early_termination".into(),
                format!("{t} must be in (0, 1]"),
            ));
        }
        if r.background.iter().any(|c| !c.is_finite()) {
            return Err(value_err(
                "render.background".into(),
                "components must be finite".into(),
            ));
        }
        check_source(&raw.volume).map_err(|e| value_err("volume".into(), e))?;
        for (name, source) in &raw.volumes {
            let path = format!("volumes.{name}");
            if !crate::params::valid_volume_name(name) {
                return Err(value_err(
                    path,
                    "a volume's name is letters, digits and _, not starting with a digit".into(),
                ));
            }
            check_source(source).map_err(|e| value_err(path, e))?;
        }
        crate::validate::check_camera(&raw.camera).map_err(|e| value_err(e.field, e.message))?;
        // named volumes, with those that legacy file paths in volume inputs add
        let mut volumes = raw.volumes.clone();
        let mut stack = Vec::new();
        for (i, entry) in raw.plugins.iter().enumerate() {
            let plugin = registry
                .get(&entry.id)
                .map_err(|e| value_err(format!("plugins[{i}]"), e.to_string()))?;
            let specs = plugin.params();
            let mut params = ParamValues::defaults(&specs);
            let flat = crate::params::flatten_groups(&specs, &entry.params)
                .map_err(|(key, m)| value_err(format!("plugins[{i}] {}.{key}", entry.id), m))?;
            for (key, value) in &flat {
                let path = format!("plugins[{i}] {}.{key}", entry.id);
                match specs.iter().find(|s| s.key == key) {
                    None => warnings.push(format!(
                        "{file}: {path}: unknown parameter ignored (known: {})",
                        specs.iter().map(|s| s.key).collect::<Vec<_>>().join(", ")
                    )),
                    Some(spec) => {
                        let migrated;
                        let value = match legacy_volume_path(spec, value) {
                            Some(legacy) => {
                                let name = name_volume_file(&mut volumes, &legacy);
                                warnings.push(format!(
                                    "{file}: {path}: a file path where a volume name belongs \
                                     (the form before named volumes); read as volumes: \
                                     {{\"{name}\": File(\"{shown}\")}} and \"{key}\": \"{name}\" \
                                     (saving writes that form)",
                                    shown = legacy.display(),
                                ));
                                migrated = ron::Value::String(name);
                                &migrated
                            }
                            None => value,
                        };
                        let v = spec
                            .from_ron(value)
                            .map_err(|m| value_err(path.clone(), m))?;
                        if let crate::params::ParamValue::Volume(name) = &v
                            && !name.is_empty()
                            && !volumes.contains_key(name)
                        {
                            let known: Vec<&str> = volumes.keys().map(String::as_str).collect();
                            return Err(value_err(
                                path,
                                format!(
                                    "there is no volume named '{name}' in `volumes:` ({})",
                                    if known.is_empty() {
                                        "it has none".to_string()
                                    } else {
                                        format!("it has {}", known.join(", "))
                                    }
                                ),
                            ));
                        }
                        params.set(key, v);
                    }
                }
            }
            let mut inst = PluginInstance::new(plugin);
            inst.enabled = entry.enabled;
            inst.params = params;
            stack.push(inst);
        }
        Ok(Loaded {
            document: Document {
                description: raw.description,
                volume: raw.volume,
                volumes,
                camera: raw.camera,
                render: raw.render,
                stack,
            },
            warnings,
        })
    }

    /// The file form, with only non-default parameters.
    pub fn to_file(&self) -> PresetFile {
        PresetFile {
            version: PRESET_VERSION,
            description: self.description.clone(),
            volume: self.volume.clone(),
            volumes: self.volumes.clone(),
            camera: self.camera,
            render: self.render,
            plugins: self
                .stack
                .iter()
                .map(|inst| {
                    let specs = inst.plugin.params();
                    // non-default values only, each repeated group as one list
                    let flat = specs
                        .iter()
                        .filter_map(|s| {
                            let v = inst.params.get(s.key)?;
                            (*v != s.default_value()).then(|| (s.key.to_string(), v.to_ron()))
                        })
                        .collect();
                    let params = crate::params::group_flat_keys(&specs, flat);
                    PluginEntry {
                        id: inst.plugin.id().to_string(),
                        enabled: inst.enabled,
                        params,
                    }
                })
                .collect(),
        }
    }

    /// This document with its file paths relative to the folder of the preset `path`.
    pub fn relative_to_preset(&self, path: &Path) -> Document {
        let dir = crate::files::absolute(path);
        let dir = dir.parent().unwrap_or(Path::new("/"));
        let rel = |p: &Path| {
            crate::files::relative_to(p, dir).unwrap_or_else(|| crate::files::absolute(p))
        };
        let mut doc = self.clone();
        for source in std::iter::once(&mut doc.volume).chain(doc.volumes.values_mut()) {
            if let Some(p) = source.file_mut() {
                *p = rel(p);
            }
        }
        for inst in &mut doc.stack {
            for v in inst.params.values.values_mut() {
                if let crate::params::ParamValue::Path(p) = v
                    && !p.as_os_str().is_empty()
                {
                    *p = rel(p);
                }
            }
        }
        doc
    }

    pub fn to_ron(&self) -> String {
        let cfg = ron::ser::PrettyConfig::new()
            .depth_limit(6)
            .struct_names(false)
            .separate_tuple_members(false);
        ron::ser::to_string_pretty(&self.to_file(), cfg)
            .unwrap_or_else(|e| format!("// serialisation failed: {e}\n"))
    }

    /// Saves atomically (temporary file + rename in the same folder). File paths (the
    /// volume and the named volumes, path parameters such as maps and meshes), held
    /// relative to the working folder or absolute, are written relative to the preset's
    /// own folder, as [`Document::load`] reads them (absolute where no relative path
    /// exists).
    pub fn save(&self, path: &Path) -> Result<(), PresetError> {
        write_atomic(path, self.relative_to_preset(path).to_ron().as_bytes()).map_err(|cause| {
            PresetError::Io {
                file: path.display().to_string(),
                cause,
            }
        })
    }
}

pub use crate::files::write_atomic;

/// The file path a volume input's value held before volume inputs named the
/// document's volumes (`"labels": "data/demo_labels.nrrd"`): a string that is not a
/// volume name, given to a [`crate::params::ParamKind::Volume`] parameter.
fn legacy_volume_path(spec: &crate::params::ParamSpec, value: &ron::Value) -> Option<PathBuf> {
    match (&spec.kind, value) {
        (crate::params::ParamKind::Volume { .. }, ron::Value::String(s))
            if !s.is_empty() && !crate::params::valid_volume_name(s) =>
        {
            Some(PathBuf::from(s))
        }
        _ => None,
    }
}

/// The name under which `volumes` holds the file `path`: the one it has, or a new one
/// from the file's stem (letters, digits and _; `_2`, `_3`… where taken), added.
fn name_volume_file(volumes: &mut BTreeMap<String, VolumeSource>, path: &Path) -> String {
    let source = VolumeSource::File(path.to_path_buf());
    if let Some((name, _)) = volumes.iter().find(|(_, s)| **s == source) {
        return name.clone();
    }
    let name = crate::params::volume_name_for(path);
    let mut unique = name.clone();
    let mut n = 2;
    while volumes.contains_key(&unique) {
        unique = format!("{name}_{n}");
        n += 1;
    }
    volumes.insert(unique.clone(), source);
    unique
}

/// Checks what can be checked of a volume source before loading it: a sample's name,
/// an analytic field's or a phantom's size.
fn check_source(source: &VolumeSource) -> Result<(), String> {
    match source {
        VolumeSource::Sample(name) => crate::samples::manifest()
            .get(name)
            .map(|_| ())
            .map_err(|e| e.to_string()),
        VolumeSource::Analytic(a) => a.check(),
        VolumeSource::Phantom(p) => p.check(),
        VolumeSource::Resampled(r) => {
            if !r.size.iter().all(|s| (2..=1024).contains(s)) {
                return Err(format!(
                    "a resampled volume's size must be 2–1024 voxels per side, got {:?}",
                    r.size
                ));
            }
            check_source(&r.source)
        }
        VolumeSource::Demo | VolumeSource::File(_) => Ok(()),
    }
}
