//! User plugins: a folder holding `plugin.ron` (id, name, parameter spec, the WGSL file)
//! and its WGSL hook functions, loaded at start without recompiling vwb.
//!
//! ```ron
//! UserPlugin(
//!     id: "shade.gooch",
//!     name: "Gooch shading",
//!     description: "cool-to-warm tone shading (Gooch et al. 1998)",
//!     shader: "gooch.wgsl",
//!     params: [
//!         Float(key: "mix", label: "Tone mix", min: 0.0, max: 1.0, default: 0.8),
//!         Color(key: "warm", label: "Warm", default: (0.9, 0.6, 0.2, 1.0)),
//!     ],
//! )
//! ```
//!
//! Volume passes (`passes: [..]`, as [`VolumePassDecl`] declares them) write 3D targets
//! that the hooks and later passes read by name; a pass function may call
//! `stack_classify(tex, dir)`:
//!
//! ```ron
//!     passes: [
//!         (target: "transmittance", entry: "transmit", depends_on: ["light"],
//!          sweep: Some((direction: "-light", boundary: 1.0))),
//!     ],
//! ```
//!
//! Each pass has `target`, `entry`, and optionally `format` (default `r32float`),
//! `scale` (0–1 of the volume's size), `depends_on` (parameter keys), `view: true` (a
//! view pass), `sweep` (plane by plane along a `Vec3` parameter, `-` reversing it;
//! the entry then also gets the path length, see [`vwb_render::plugin::SweepDecl`])
//! and `steps` (a progressive pass: a count or an `Int` parameter's key; step i runs
//! with `step` = i and blends into its own previous texel `prev`, over as many frames
//! as the refinement budget needs, and the window shows its progress). Optional
//! fields are written plainly or as `Some(..)`.
//!
//! Parameter kinds: `Float` (with `log: true` for a logarithmic slider), `Int`, `Bool`,
//! `Enum` (options; structural: each option recomposes the pipeline), `Color`, `Vec3`,
//! `Group` (a repeated group) and `Volume` (a named volume input, bound as a texture):
//!
//! ```ron
//!         Volume(key: "field", label: "Second volume", components: "any"),
//! ```
//!
//! A `Volume` parameter names one of the preset's `volumes:` (empty: the document's own
//! volume). Its hooks and passes read it as `field`, a `texture_3d<f32>` on the input's
//! own grid over the document volume's box (sample it at `s.tex` with `linear_clamp`):
//! `.rgb` the components as stored (a scalar's value in `.r`), `.a` the value normalised
//! to [0, 1] by the input's range, which is a vector's magnitude ([`input_texture`]).
//! Another volume under the name recreates the texture and reruns the passes.
//! The WGSL file holds hook functions with the signatures of
//! [`vwb_render::plugin`] (`shade`, `classify`, `clip`, `sample`, `composite`) and may
//! use everything in `shaders/common.wgsl` (e.g. `gradient_central`, `shading_normal`,
//! `light_dir`). A plugin is composed and naga-validated when it loads; errors name the
//! file and line. It has no CPU twin, so it is measured against the GPU converged
//! reference (`vwb_lab::measure`).
//!
//! Plugins load from the user plugin folder (`$VWB_PLUGINS`, else `<config>/vwb/plugins`)
//! and from `--plugins DIR`; [`install`] makes them part of [`crate::registry`], and
//! [`Watch`] reloads a plugin when its files change.

use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock};
use std::time::SystemTime;

use serde::Deserialize;
use vwb_render::composer::{TargetFormat, compose};
use vwb_render::params::{ParamKind, ParamSpec, ParamValues, validate_specs};
use vwb_render::plugin::{
    GpuInit, GpuResource, Plugin, PluginError, ResourceDecl, ResourceKind, ShaderSource,
    StorageFormat, VolumePassDecl, valid_id,
};
use vwb_render::volume::Volume;

use vwb_render::params::interned;

/// `plugin.ron`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(rename = "UserPlugin")]
struct Manifest {
    id: String,
    name: String,
    #[serde(default)]
    description: String,
    /// The WGSL file, relative to the folder.
    shader: PathBuf,
    #[serde(default)]
    params: Vec<ParamDef>,
    /// Volume passes, in order (`VolumePassDecl`).
    #[serde(default)]
    passes: Vec<PassDef>,
}

/// One volume pass of a user plugin: the function `entry` of its WGSL file writes the
/// 3D target `target`, which its hooks and later passes read by name.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct PassDef {
    target: String,
    entry: String,
    /// `r32float` (the default), `rgba16float`, `rgba32float` or `rgba8unorm`.
    #[serde(default)]
    format: Option<String>,
    /// The target's size relative to the volume, in (0, 1].
    #[serde(default)]
    scale: Option<f32>,
    /// The parameters whose change reruns it.
    #[serde(default)]
    depends_on: Vec<String>,
    /// A view pass: it reruns when the camera moves.
    #[serde(default)]
    view: bool,
    /// A sweep along a direction: `direction` names a `Vec3` parameter (a leading
    /// `-` reverses it), `boundary` is the value the sweep enters with (default 1).
    #[serde(default)]
    sweep: Option<SweepDef>,
    /// A progressive pass: its number of refinement steps, a count or the key of an
    /// `Int` parameter. Step i (from 0) runs with `step` = i and reads its own
    /// previous texel as `prev` (r32float), as many steps per frame as the renderer's
    /// refinement budget allows.
    #[serde(default)]
    steps: Option<StepsDef>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
enum StepsDef {
    Count(u32),
    Param(String),
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepDef {
    direction: String,
    #[serde(default)]
    boundary: Option<f32>,
}

impl PassDef {
    /// The declaration, checked against the plugin's parameters.
    fn decl(&self, specs: &[ParamSpec]) -> Result<VolumePassDecl, String> {
        let pass = format!("pass '{}'", self.target);
        for (what, name) in [("target", &self.target), ("entry", &self.entry)] {
            if !is_identifier(name) {
                return Err(format!(
                    "{pass}: the {what} '{name}' is not a WGSL identifier"
                ));
            }
        }
        let format = match &self.format {
            None => StorageFormat::R32Float,
            Some(f) => StorageFormat::parse(f).ok_or_else(|| {
                let known: Vec<&str> = StorageFormat::ALL.iter().map(|f| f.wgsl()).collect();
                format!("{pass}: format '{f}' is not one of {}", known.join(", "))
            })?,
        };
        let scale = self.scale.unwrap_or(1.0);
        if !(scale > 0.0 && scale <= 1.0) {
            return Err(format!("{pass}: scale {scale} is not in (0, 1]"));
        }
        let key_of = |k: &str| specs.iter().find(|p| p.key == k);
        let mut depends_on = Vec::new();
        for k in &self.depends_on {
            let spec = key_of(k)
                .ok_or_else(|| format!("{pass}: depends on '{k}', which is not a parameter"))?;
            depends_on.push(spec.key);
        }
        let mut decl =
            VolumePassDecl::new(interned(self.target.clone()), interned(self.entry.clone()))
                .scale(scale)
                .depends_on(&depends_on);
        decl.format = format;
        if self.view {
            decl = decl.view();
        }
        match &self.steps {
            None => {}
            Some(StepsDef::Count(n)) => {
                if *n == 0 {
                    return Err(format!("{pass}: steps 0 (at least 1)"));
                }
                let n = *n;
                decl = decl.progressive(move |_| n);
            }
            Some(StepsDef::Param(k)) => {
                let spec = key_of(k)
                    .filter(|p| matches!(p.kind, ParamKind::Int { .. }))
                    .ok_or_else(|| format!("{pass}: steps '{k}' is not an Int parameter"))?;
                let key: &'static str = spec.key;
                decl = decl.progressive(move |p| p.int(key).max(1) as u32);
                // a new step count restarts the refinement
                if !decl.depends_on.contains(&key) {
                    decl.depends_on.push(key);
                }
            }
        }
        if let Some(sw) = &self.sweep {
            let (negate, key) = match sw.direction.strip_prefix('-') {
                Some(k) => (true, k),
                None => (false, sw.direction.as_str()),
            };
            let spec = key_of(key)
                .filter(|p| matches!(p.kind, ParamKind::Vec3 { .. }))
                .ok_or_else(|| {
                    format!("{pass}: the sweep direction '{key}' is not a Vec3 parameter")
                })?;
            if format != StorageFormat::R32Float {
                return Err(format!(
                    "{pass}: a sweep writes r32float, not {}",
                    format.wgsl()
                ));
            }
            let key: &'static str = spec.key;
            let sign = if negate { -1.0 } else { 1.0 };
            decl = decl.sweep(
                move |p| p.vec3(key).map(|c| sign * c),
                sw.boundary.unwrap_or(1.0),
            );
            if !decl.depends_on.contains(&key) {
                decl.depends_on.push(key);
            }
        }
        Ok(decl)
    }
}

/// Whether `s` is a plain identifier (letters, digits, `_`; not starting with a digit).
fn is_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// One parameter of a user plugin's spec.
#[derive(Debug, Clone, Deserialize)]
enum ParamDef {
    Float {
        key: String,
        label: String,
        min: f32,
        max: f32,
        default: f32,
        #[serde(default)]
        log: bool,
        #[serde(default)]
        doc: String,
    },
    Int {
        key: String,
        label: String,
        min: i32,
        max: i32,
        default: i32,
        #[serde(default)]
        doc: String,
    },
    Bool {
        key: String,
        label: String,
        default: bool,
        #[serde(default)]
        doc: String,
    },
    Enum {
        key: String,
        label: String,
        options: Vec<String>,
        default: usize,
        #[serde(default)]
        doc: String,
    },
    Color {
        key: String,
        label: String,
        default: [f32; 4],
        #[serde(default)]
        doc: String,
    },
    Vec3 {
        key: String,
        label: String,
        min: f32,
        max: f32,
        default: [f32; 3],
        #[serde(default)]
        doc: String,
    },
    /// A named volume input (the preset's `volumes:`, or the document's own volume
    /// when none is named), bound as the `texture_3d<f32>` of the same name: `.rgb` its
    /// components as stored (a scalar's value in `.r`), `.a` its value normalised to
    /// [0, 1] by its range (a vector's magnitude), over the document volume's box.
    /// `components`: `scalar`, `vector` or `any` (the default).
    Volume {
        key: String,
        label: String,
        #[serde(default)]
        components: String,
        #[serde(default)]
        doc: String,
    },
    /// A repeated group (`params::Group`): `count` elements of `params`, whose keys are
    /// templates with one `{}` (`light{}_on`); `switch` names the member template that
    /// turns an element on, `limit` an int parameter holding how many are in use.
    Group {
        name: String,
        count: usize,
        #[serde(default)]
        switch: Option<String>,
        #[serde(default)]
        limit: Option<String>,
        params: Vec<ParamDef>,
    },
}

/// Elements a user plugin's group may have.
const MAX_GROUP: usize = 16;

impl ParamDef {
    /// The specs of a definition: one, or a group's members for every element.
    fn specs(&self) -> Result<Vec<ParamSpec>, String> {
        let ParamDef::Group {
            name,
            count,
            switch,
            limit,
            params,
        } = self
        else {
            return Ok(vec![self.spec()?]);
        };
        if !(1..=MAX_GROUP).contains(count) {
            return Err(format!(
                "group '{name}': count {count} is not in 1..={MAX_GROUP}"
            ));
        }
        let mut group = vwb_render::params::Group::new(interned(name.clone()), *count);
        if let Some(t) = switch {
            group = group.switch(interned(t.clone()));
        }
        if let Some(k) = limit {
            group = group.limit(interned(k.clone()));
        }
        // element i's member: its key template filled in (a nested group has no key, and
        // its `spec` refuses it)
        let member = |p: &ParamDef, i: usize| -> Result<ParamSpec, String> {
            let mut m = p.clone();
            if let Some(key) = m.key_mut() {
                if key.matches("{}").count() != 1 {
                    return Err(format!(
                        "group '{name}': key '{key}' needs one {{}} where the element's index goes"
                    ));
                }
                *key = group.key(key, i).to_string();
            }
            m.spec()
        };
        let err = std::cell::RefCell::new(None);
        let specs = group.specs(|i| {
            params
                .iter()
                .filter_map(|p| member(p, i).map_err(|e| *err.borrow_mut() = Some(e)).ok())
                .collect()
        });
        err.into_inner().map_or(Ok(specs), Err)
    }

    /// The key of a single parameter (None for a group).
    fn key_mut(&mut self) -> Option<&mut String> {
        match self {
            ParamDef::Float { key, .. }
            | ParamDef::Int { key, .. }
            | ParamDef::Bool { key, .. }
            | ParamDef::Enum { key, .. }
            | ParamDef::Color { key, .. }
            | ParamDef::Vec3 { key, .. }
            | ParamDef::Volume { key, .. } => Some(key),
            ParamDef::Group { .. } => None,
        }
    }

    fn spec(&self) -> Result<ParamSpec, String> {
        let s = |x: &String| interned(x.clone());
        let (spec, doc) = match self {
            ParamDef::Float {
                key,
                label,
                min,
                max,
                default,
                log,
                doc,
            } => {
                if *log && *min <= 0.0 {
                    return Err(format!("'{key}': a log slider needs min > 0"));
                }
                let spec = if *log {
                    ParamSpec::float_log(s(key), s(label), *min, *max, *default)
                } else {
                    ParamSpec::float(s(key), s(label), *min, *max, *default)
                };
                (spec, doc)
            }
            ParamDef::Int {
                key,
                label,
                min,
                max,
                default,
                doc,
            } => (ParamSpec::int(s(key), s(label), *min, *max, *default), doc),
            ParamDef::Bool {
                key,
                label,
                default,
                doc,
            } => (ParamSpec::boolean(s(key), s(label), *default), doc),
            ParamDef::Enum {
                key,
                label,
                options,
                default,
                doc,
            } => {
                if *default >= options.len() {
                    return Err(format!(
                        "'{key}': default {default} is not an option index (0..{})",
                        options.len()
                    ));
                }
                let opts: Vec<&'static str> = options.iter().map(s).collect();
                (
                    ParamSpec::enumeration(s(key), s(label), &opts, *default).structural(),
                    doc,
                )
            }
            ParamDef::Color {
                key,
                label,
                default,
                doc,
            } => (ParamSpec::color(s(key), s(label), *default), doc),
            ParamDef::Vec3 {
                key,
                label,
                min,
                max,
                default,
                doc,
            } => (ParamSpec::vec3(s(key), s(label), *min, *max, *default), doc),
            ParamDef::Volume {
                key,
                label,
                components,
                doc,
            } => {
                use vwb_render::params::Components;
                let c = match components.as_str() {
                    "" | "any" => Components::Any,
                    "scalar" => Components::Scalar,
                    "vector" => Components::Vector,
                    other => {
                        return Err(format!(
                            "'{key}': components '{other}' is not scalar, vector or any"
                        ));
                    }
                };
                (ParamSpec::volume(s(key), s(label), c), doc)
            }
            ParamDef::Group { name, .. } => {
                return Err(format!("group '{name}': a group inside a group"));
            }
        };
        if let ParamKind::Float {
            min, max, default, ..
        } = spec.kind
            && !(min.is_finite() && max.is_finite() && min < max && (min..=max).contains(&default))
        {
            return Err(format!(
                "'{}': needs finite min < max with the default between them",
                spec.key
            ));
        }
        if let ParamKind::Int { min, max, default } = spec.kind
            && !(min < max && (min..=max).contains(&default))
        {
            return Err(format!(
                "'{}': needs min < max with the default between them",
                spec.key
            ));
        }
        Ok(if doc.is_empty() {
            spec
        } else {
            spec.with_doc(interned(doc.clone()))
        })
    }
}

/// A plugin declared by a folder: its spec and WGSL, no CPU twin.
#[derive(Debug)]
pub struct UserPlugin {
    id: &'static str,
    name: &'static str,
    description: &'static str,
    specs: Vec<ParamSpec>,
    passes: Vec<VolumePassDecl>,
    file: String,
    source: String,
    /// The folder it came from.
    pub dir: PathBuf,
}

impl Plugin for UserPlugin {
    fn id(&self) -> &'static str {
        self.id
    }
    fn display_name(&self) -> &'static str {
        self.name
    }
    fn description(&self) -> &'static str {
        self.description
    }
    fn params(&self) -> Vec<ParamSpec> {
        self.specs.clone()
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource {
            file: self.file.clone().into(),
            source: self.source.clone().into(),
        }
    }
    fn volume_passes(&self) -> Vec<VolumePassDecl> {
        self.passes.clone()
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        self.inputs()
            .map(|name| ResourceDecl {
                name,
                kind: ResourceKind::Texture3d,
            })
            .collect()
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        self.inputs()
            .map(|key| {
                let volume = gpu.input(params, key)?;
                Ok(input_texture(gpu, &format!("{} {key}", self.id), volume))
            })
            .collect()
    }
}

impl UserPlugin {
    /// The keys of its volume inputs, in the order of its spec (each binds a texture
    /// of that name).
    fn inputs(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.specs
            .iter()
            .filter(|p| matches!(p.kind, ParamKind::Volume { .. }))
            .map(|p| p.key)
    }
}

/// A volume input as a user plugin's WGSL reads it: rgba32float on the input's own
/// grid, `.rgb` its first three components as stored (zero where it has fewer), `.a`
/// its scalar normalised by its range (the magnitude of a vector), non-finite samples
/// as 0.
pub fn input_texture(gpu: &GpuInit, label: &str, volume: &Volume) -> GpuResource {
    let c = volume.components.max(1) as usize;
    let raw = volume.components_f32();
    let normalised = volume.normalized_scalars();
    let texels: Vec<f32> = raw
        .chunks_exact(c)
        .zip(&normalised)
        .flat_map(|(v, n)| {
            let at = |i: usize| v.get(i).copied().unwrap_or(0.0);
            [at(0), at(1), at(2), *n]
        })
        .collect();
    let r = gpu.create_volume_texture(label, volume.dims, 4);
    gpu.write_floats(&r, &texels);
    r
}

/// Loads the plugin in `dir` (its `plugin.ron` and WGSL), composes it behind a 1D
/// transfer function and validates the result with naga. Errors name the file (and the
/// line for WGSL errors).
pub fn load(dir: &Path) -> Result<UserPlugin, String> {
    let manifest_path = dir.join("plugin.ron");
    let text = std::fs::read_to_string(&manifest_path)
        .map_err(|e| format!("{}: cannot read: {e}", manifest_path.display()))?;
    // optional fields are written plainly (`format: "rgba16float"`) or as `Some(..)`
    let m: Manifest = ron::Options::default()
        .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
        .from_str(&text)
        .map_err(|e| format!("{}: {e}", manifest_path.display()))?;
    let at = |msg: String| format!("{}: {msg}", manifest_path.display());
    if !valid_id(&m.id) {
        return Err(at(format!(
            "'{}' is not a plugin id: category.name with a category of clip, sample, classify, shade, composite, flow, search or test and a lowercase name",
            m.id
        )));
    }
    if crate::builtin_registry().get(&m.id).is_ok() {
        return Err(at(format!("'{}' is the id of a built-in plugin", m.id)));
    }
    let specs: Vec<ParamSpec> = m
        .params
        .iter()
        .map(ParamDef::specs)
        .collect::<Result<Vec<_>, _>>()
        .map_err(at)?
        .concat();
    validate_specs(&specs).map_err(at)?;
    let passes = m
        .passes
        .iter()
        .map(|p| p.decl(&specs))
        .collect::<Result<Vec<_>, _>>()
        .map_err(at)?;
    let wgsl = dir.join(&m.shader);
    let source = std::fs::read_to_string(&wgsl)
        .map_err(|e| format!("{}: cannot read: {e}", wgsl.display()))?;
    let plugin = UserPlugin {
        id: interned(m.id),
        name: interned(m.name),
        description: interned(m.description),
        specs,
        passes,
        file: wgsl.display().to_string(),
        source,
        dir: dir.to_path_buf(),
    };
    check_composes(&plugin)?;
    Ok(plugin)
}

/// Composes the plugin alone (after a 1D TF unless it classifies itself) and validates
/// it with naga; the error names the WGSL file and line.
fn check_composes(p: &UserPlugin) -> Result<(), String> {
    let tf = crate::classify_tf1d::Tf1d::default();
    let mut stack: Vec<&dyn Plugin> = Vec::new();
    if p.category() != vwb_render::plugin::Category::Classify {
        stack.push(&tf);
    }
    stack.push(p);
    let mut limits = wgpu::Limits::downlevel_defaults();
    limits.max_bind_groups = 4;
    compose(&stack, TargetFormat::Rgba16Float, &limits)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// Every plugin folder (a sub-folder with `plugin.ron`) under `root`, loaded; the
/// folders that fail give their errors instead. A missing `root` gives nothing.
pub fn load_all(root: &Path) -> (Vec<UserPlugin>, Vec<String>) {
    let (mut ok, mut errors) = (Vec::new(), Vec::new());
    let Ok(entries) = std::fs::read_dir(root) else {
        return (ok, errors);
    };
    let mut dirs: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("plugin.ron").is_file())
        .collect();
    dirs.sort();
    for d in dirs {
        match load(&d) {
            Ok(p) => ok.push(p),
            Err(e) => errors.push(e),
        }
    }
    (ok, errors)
}

/// The user plugin folder: `$VWB_PLUGINS`, else `<config dir>/vwb/plugins`.
pub fn default_dir() -> Option<PathBuf> {
    std::env::var_os("VWB_PLUGINS")
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("XDG_CONFIG_HOME").map(|c| PathBuf::from(c).join("vwb/plugins"))
        })
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config/vwb/plugins")))
}

fn installed() -> &'static RwLock<Vec<Arc<UserPlugin>>> {
    static USER: RwLock<Vec<Arc<UserPlugin>>> = RwLock::new(Vec::new());
    &USER
}

/// Adds user plugins to [`crate::registry`] (replacing one with the same id).
pub fn install(plugins: Vec<UserPlugin>) {
    let mut all = installed().write().unwrap_or_else(|e| e.into_inner());
    for p in plugins {
        all.retain(|q| q.id != p.id);
        all.push(Arc::new(p));
    }
}

/// Loads the plugins of the user folder and of `extra` folders, installs them and
/// returns the errors (each naming its file) and the ids loaded.
pub fn install_from(extra: &[PathBuf]) -> (Vec<&'static str>, Vec<String>) {
    let mut roots: Vec<PathBuf> = default_dir().into_iter().collect();
    roots.extend(extra.iter().cloned());
    let (mut ids, mut errors) = (Vec::new(), Vec::new());
    for root in roots {
        if extra.contains(&root) && !root.is_dir() {
            errors.push(format!("{}: no such plugin folder", root.display()));
            continue;
        }
        // a folder that is itself one plugin
        let (ok, errs) = if root.join("plugin.ron").is_file() {
            match load(&root) {
                Ok(p) => (vec![p], vec![]),
                Err(e) => (vec![], vec![e]),
            }
        } else {
            load_all(&root)
        };
        ids.extend(ok.iter().map(|p| p.id));
        errors.extend(errs);
        install(ok);
    }
    (ids, errors)
}

/// The installed user plugins.
pub fn plugins() -> Vec<Arc<dyn Plugin>> {
    installed()
        .read()
        .unwrap_or_else(|e| e.into_inner())
        .iter()
        .map(|p| p.clone() as Arc<dyn Plugin>)
        .collect()
}

/// A reload's outcome: the plugin id and the reloaded plugin or the error.
pub type Reload = (String, Result<Arc<dyn Plugin>, String>);

/// Watches the installed plugins' files; [`Watch::poll`] reloads the ones that changed.
#[derive(Default)]
pub struct Watch {
    seen: Vec<(PathBuf, Option<SystemTime>)>,
}

fn stamp(dir: &Path) -> Option<SystemTime> {
    let mut newest = None;
    for e in std::fs::read_dir(dir).ok()?.flatten() {
        if let Ok(t) = e.metadata().and_then(|m| m.modified()) {
            newest = newest.max(Some(t));
        }
    }
    newest
}

impl Watch {
    /// Reloads every installed plugin whose folder changed since the last poll (the
    /// first poll only records the times). Returns (id, outcome): a reloaded plugin is
    /// installed; a failed one keeps the installed version and gives the error.
    pub fn poll(&mut self) -> Vec<Reload> {
        let dirs: Vec<(String, PathBuf)> = installed()
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
            .map(|p| (p.id.to_string(), p.dir.clone()))
            .collect();
        let mut out = Vec::new();
        for (id, dir) in dirs {
            let now = stamp(&dir);
            match self.seen.iter_mut().find(|(d, _)| *d == dir) {
                None => self.seen.push((dir, now)),
                Some((_, t)) if *t != now => {
                    *t = now;
                    match load(&dir) {
                        Ok(p) => {
                            let p = Arc::new(p);
                            let mut all = installed().write().unwrap_or_else(|e| e.into_inner());
                            all.retain(|q| q.dir != dir);
                            all.push(p.clone());
                            out.push((id, Ok(p as Arc<dyn Plugin>)));
                        }
                        Err(e) => out.push((id, Err(e))),
                    }
                }
                Some(_) => {}
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder(name: &str, manifest: &str, wgsl: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("vwb-user-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("plugin.ron"), manifest).unwrap();
        std::fs::write(d.join("p.wgsl"), wgsl).unwrap();
        d
    }

    const TINT: &str = "fn shade(s: Sample) -> Sample {\n    var o = s;\n    o.color = vec4<f32>(s.color.rgb * params.gain, s.color.a);\n    return o;\n}\n";

    #[test]
    fn a_folder_becomes_a_plugin_with_its_spec() {
        let d = folder(
            "ok",
            r#"UserPlugin(id: "shade.tint_test", name: "Tint", shader: "p.wgsl",
                params: [Float(key: "gain", label: "Gain", min: 0.0, max: 2.0, default: 0.5),
                         Enum(key: "mode", label: "Mode", options: ["a", "b"], default: 1)])"#,
            TINT,
        );
        let p = load(&d).unwrap();
        assert_eq!(p.id(), "shade.tint_test");
        assert_eq!(p.category(), vwb_render::plugin::Category::Shade);
        let specs = p.params();
        assert_eq!(specs.len(), 2);
        assert!(specs[1].structural);
        assert!(
            p.cpu_twin(&vwb_render::params::ParamValues::defaults(&specs))
                .is_none()
        );
        std::fs::remove_dir_all(&d).ok();
    }

    /// A group in plugin.ron: flat keys per element for the WGSL, the element's
    /// switch; a key without `{}`, a group in a group and an absurd count are refused
    /// naming plugin.ron and the group.
    #[test]
    fn a_group_of_parameters_becomes_flat_keys_per_element() {
        let wgsl = "fn shade(s: Sample) -> Sample {\n    var o = s;\n    var g = 1.0;\n    if (params.tone0_on != 0u) { g = g * params.tone0_gain; }\n    if (params.tone2_on != 0u) { g = g * params.tone2_gain; }\n    o.color = vec4<f32>(s.color.rgb * g, s.color.a);\n    return o;\n}\n";
        let group = |members: &str, count: usize| {
            format!(
                r#"UserPlugin(id: "shade.tones_test", name: "Tones", shader: "p.wgsl",
                params: [Group(name: "Tone", count: {count}, switch: Some("tone{{}}_on"), params: [{members}])])"#
            )
        };
        let good = r#"Bool(key: "tone{}_on", label: "On", default: true),
                      Float(key: "tone{}_gain", label: "Gain", min: 0.0, max: 2.0, default: 0.9)"#;
        let d = folder("group", &group(good, 3), wgsl);
        let p = load(&d).unwrap();
        let specs = p.params();
        let keys: Vec<&str> = specs.iter().map(|s| s.key).collect();
        assert_eq!(
            keys,
            [
                "tone0_on",
                "tone0_gain",
                "tone1_on",
                "tone1_gain",
                "tone2_on",
                "tone2_gain"
            ]
        );
        let e = specs[3].element.unwrap();
        assert_eq!(
            (e.group.name, e.index, e.group.switch),
            ("Tone", 1, Some("tone{}_on"))
        );
        for (members, count, why) in [
            (
                r#"Float(key: "gain", label: "G", min: 0.0, max: 2.0, default: 1.0)"#,
                3,
                "needs one {}",
            ),
            (
                r#"Group(name: "In", count: 2, params: [])"#,
                3,
                "a group inside a group",
            ),
            (good, 0, "count 0 is not in 1..=16"),
            (
                r#"Float(key: "tone{}_on", label: "G", min: 0.0, max: 2.0, default: 1.0)"#,
                3,
                "its switch 'tone0_on'",
            ),
        ] {
            std::fs::write(d.join("plugin.ron"), group(members, count)).unwrap();
            let e = load(&d).unwrap_err();
            assert!(e.contains("plugin.ron") && e.contains(why), "{why}: {e}");
        }
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn broken_plugins_are_refused_with_file_and_line() {
        let manifest = r#"UserPlugin(id: "shade.broken_test", name: "B", shader: "p.wgsl",
            params: [Float(key: "gain", label: "Gain", min: 0.0, max: 2.0, default: 0.5)])"#;
        let d = folder(
            "wgsl",
            manifest,
            &TINT.replace("s.color.a);", "s.color.a)\n"),
        );
        let e = load(&d).unwrap_err();
        // the missing `;` of line 3 is reported at the next token, line 5
        assert!(e.contains("p.wgsl:5:") && e.contains("expected `;`"), "{e}");
        std::fs::remove_dir_all(&d).ok();
        let d = folder(
            "param",
            manifest,
            &TINT.replace("params.gain", "params.gian"),
        );
        let e = load(&d).unwrap_err();
        assert!(e.contains("p.wgsl:3:") && e.contains("gian"), "{e}");
        std::fs::remove_dir_all(&d).ok();
        for (bad, expect) in [
            (
                manifest.replace("shade.broken_test", "shiny.x"),
                "is not a plugin id",
            ),
            (
                manifest.replace("shade.broken_test", "classify.tf1d"),
                "built-in",
            ),
            (manifest.replace("default: 0.5", "default: 5.0"), "'gain'"),
            (manifest.replace("name:", "nome:"), "plugin.ron"),
        ] {
            let d = folder("manifest", &bad, TINT);
            let e = load(&d).unwrap_err();
            assert!(e.contains("plugin.ron") && e.contains(expect), "{e}");
            std::fs::remove_dir_all(&d).ok();
        }
    }
}
