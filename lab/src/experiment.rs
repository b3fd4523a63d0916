//! Experiment files: a study declared in RON and run by `vwb run FILE` (or
//! [`run_file`]), so that "this plugin over these scenes and spacings, against the
//! converged reference, error below X" needs no Rust.
//!
//! An experiment names its **scenes** (presets or sample volumes), its **variants**
//! (parameter settings, plugin swaps, plugins switched off or on, over each scene's
//! stack), a **grid** of any float/int parameter or the slice spacing (lists, linear or
//! log ranges), the **reference** each image is compared with (the converged reference
//! of the image's own stack or of a named variant, the CPU twin with the same slices, or
//! another variant's GPU image), the **metrics** its tables show, **assertions** checked
//! over the rows, and a **seed**. Running it renders every scene × variant × grid point
//! on the GPU, times it and compares it, then writes a report (Markdown with tables and
//! the Pareto plot per scene, images, CSV, JSON with the machine, adapter, version and
//! seed) and a JUnit XML file with one test case per assertion. A failed assertion makes
//! the run fail. With `doc_block` the Markdown also replaces a marked block of a doc, so
//! the docs are regenerated from experiment files.
//!
//! Assertions (one per string): `METRIC OP NUMBER` holds when every row satisfies it;
//! `METRIC(VARIANT) OP NUMBER` when every row of that variant does; and
//! `METRIC(A) / METRIC(B) OP NUMBER` compares the medians of the two variants' rows,
//! measured in the same run (e.g. `time(pre) / time(post) < 0.8`). OP is one of
//! `<`, `<=`, `>`, `>=`. METRIC is one of [`Metric::ALL`] (`time` is `frame_ms`).

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, Result, anyhow, bail};
use serde::{Deserialize, Serialize};
use serde_json::json;
use vwb_render::metrics::{self, Metrics, RgbImageF};
use vwb_render::params::{ParamKind, ParamValue};
use vwb_render::plugin::{ConvergedReference, PluginInstance, Statistic};
use vwb_render::preset::{Document, VolumeSource};
use vwb_render::reference::ReferenceOptions;
use vwb_render::renderer::Backend;
use vwb_render::slicing::VolumeBox;
use vwb_render::{GpuContext, TargetFormat, Volume};

use crate::headless;
use crate::measure::{self, Axis, SweepPoint};

mod probe;

/// A study declared in an experiment file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiment {
    /// Names the report and its files.
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// Empty only with a `probe`.
    #[serde(default)]
    pub scenes: Vec<Scene>,
    /// A plugin's probe instead of scenes: the study runs that computation of the
    /// plugin's CPU twin (no GPU, no image) over the variants and the grid, whose keys
    /// are the probe's parameters; its figures are the table's columns
    /// ([`vwb_render::plugin::Probe`], `crate::probe`).
    #[serde(default)]
    pub probe: Option<ProbeSpec>,
    /// Empty: one variant, each scene as it is.
    #[serde(default)]
    pub variants: Vec<Variant>,
    #[serde(default)]
    pub grid: Vec<GridAxis>,
    #[serde(default)]
    pub reference: ReferenceSpec,
    /// Options of the converged reference a plugin supplies (the Monte-Carlo
    /// integral of `shade.dos`: `directions`, `replicas`, `seed`, `eye_step`,
    /// `cone_step`); an error for a stack whose reference is refined slices.
    #[serde(default)]
    pub reference_options: BTreeMap<String, f64>,
    /// The columns of the report's tables (all metrics are in the CSV and JSON).
    #[serde(default = "default_metrics")]
    pub metrics: Vec<Metric>,
    /// Figures plugins report about what their passes computed, `<plugin id>.<name>`
    /// (e.g. `shade.hernell.data_reduction`; `Plugin::statistics`): columns of the
    /// tables after the metrics, in the CSV and JSON, and usable in assertions. A row
    /// whose stack has the plugin off shows —.
    #[serde(default)]
    pub statistics: Vec<String>,
    #[serde(default)]
    pub assertions: Vec<String>,
    /// Written into every plugin parameter named `seed` (noise volumes, Monte-Carlo
    /// references) unless a variant sets it; `None` keeps the presets' seeds.
    #[serde(default)]
    pub seed: Option<u64>,
    #[serde(default)]
    pub render: RenderOverrides,
    /// Timed frames per image (after one untimed frame).
    #[serde(default = "default_frames")]
    pub frames: u32,
    /// The time axis of the Pareto front and plot: `frame_ms` (default) or
    /// `update_ms` (the price of a parameter change, for plugins whose cost is a
    /// volume pass rather than the frame).
    #[serde(default = "default_pareto_time")]
    pub pareto_time: Metric,
    /// How many times each row's update is measured (default 1): after the first
    /// frame of a grid point whose change reran passes, the renderer reruns every
    /// pre-pass and volume pass (`Renderer::rerun_passes`) this many times less one, and
    /// `update_ms` and `update_gpu_ms` are the medians. For rows whose change reruns
    /// all of the stack's passes (a study of one pass's parameters); the first
    /// measurement alone also pays for first use.
    #[serde(default = "default_update_repeats")]
    pub update_repeats: u32,
    /// Convergence tolerance of converged references (RMS ΔE*uv of the last halving).
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Also write the report into the block between `<!-- BEGIN <block> -->` and
    /// `<!-- END <block> -->` of this file (relative to the experiment file's folder).
    #[serde(default)]
    pub doc_block: Option<DocBlock>,
}

fn default_metrics() -> Vec<Metric> {
    vec![Metric::FrameMs, Metric::RmsDeltaE, Metric::ShareAbove6]
}
fn default_frames() -> u32 {
    3
}
fn default_pareto_time() -> Metric {
    Metric::FrameMs
}
fn default_update_repeats() -> u32 {
    1
}
fn default_tolerance() -> f64 {
    0.1
}

/// The probe an experiment runs instead of rendering scenes.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    /// `<plugin id>.<probe name>`, e.g. `flow.lic3d.drift`.
    pub id: String,
    /// The Pareto front's (time, error) figures; None: no front and no plot.
    #[serde(default)]
    pub pareto: Option<(String, String)>,
}

/// A scene: a preset file (relative to the experiment file's folder) or a sample data
/// set by name (`vwb data list`) under the demo preset's stack, with the camera fitted.
#[derive(Debug, Clone, Deserialize)]
pub enum Scene {
    Preset(PathBuf),
    Sample(String),
}

/// One variant of every scene's stack.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Variant {
    pub name: String,
    /// `"<plugin id>.<key>"` (its first instance) or `render.slice_spacing`,
    /// `render.slices` (the spacing that gives about this many slices in the scene's
    /// frame), `render.backend` (raster, compute), `render.target`,
    /// `render.early_termination`, `render.skipping` (true, false),
    /// `render.occupied_proxy` (true, false), `render.hull_cut` (true, false),
    /// `render.slices_per_proxy` (0: auto, 1, 2, 4, 8, 16), `render.volume_format` (auto, r32float, r32float_pairs, r16float, r16unorm, r8unorm), `render.table_format` (auto, rgba32float, rgba16float), `camera.yaw_deg`,
    /// `camera.pitch_deg`, `camera.distance`, `camera.fov_y_deg` (a perspective
    /// camera's vertical field of view).
    #[serde(default)]
    pub set: BTreeMap<String, SetValue>,
    /// (from, to): the first instance of plugin `from` is replaced by plugin `to` with
    /// its default parameters.
    #[serde(default)]
    pub swap: Vec<(String, String)>,
    /// Plugin ids whose instances are switched off.
    #[serde(default)]
    pub disable: Vec<String>,
    /// Plugin ids whose instances are switched on.
    #[serde(default)]
    pub enable: Vec<String>,
    /// This variant's reference instead of the experiment's (e.g. one variant against
    /// another variant's converged reference, or against a plugin-free variant).
    #[serde(default)]
    pub reference: Option<ReferenceSpec>,
    /// The scene's volume physically cropped to these voxels, every other voxel
    /// removed ([`Volume::cropped`]): what a clipped variant is compared with
    /// (`reference: TwinOf("cropped")`), e.g. `crop: (from: (0, 0, 15), to: (32, 32, 32))`.
    #[serde(default)]
    pub crop: Option<Crop>,
    /// Its transfer function is searched for at each grid point (a genetic search,
    /// `vwb_render::search::genetic`, toward another variant's views or an objective)
    /// and the row renders the best genome found; the search's figures are the
    /// statistics `search.*` ([`SEARCH_STATISTICS`]).
    #[serde(default)]
    pub search: Option<SearchSpec>,
    /// A design gallery of its TF is drawn at each grid point (docs/search.md: random
    /// genomes rendered as thumbnails in batched atlases, the most dispersed chosen);
    /// its figures are the statistics `gallery.*` ([`GALLERY_STATISTICS`]) and its sheet
    /// is saved beside the row's image.
    #[serde(default)]
    pub gallery: Option<GallerySpec>,
    /// Its 1D TF is suggested from the data at each grid point (`vwb suggest-tf`:
    /// Kindlmann & Durkin's histogram volume with the noise handling of
    /// docs/classification.md) and the row renders it; the suggestion's figures,
    /// its fog among them, are the statistics `suggest.*` ([`SUGGEST_STATISTICS`]).
    #[serde(default)]
    pub suggest: Option<SuggestSpec>,
}

/// A variant's suggested TF ([`vwb_render::suggest::SuggestOptions`]).
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SuggestSpec {
    /// The noise handling (pre-filter, noise floor, transparent background); default
    /// true, false for the suggestion as it was without it.
    pub filtered: Option<bool>,
    /// Half width (voxels) of the boundary emphasis.
    pub thickness: Option<f64>,
    /// Peak opacity.
    pub max_opacity: Option<f64>,
}

/// The figures of a variant's suggested TF, as statistics: value bins on a boundary
/// (`suggest.bins`, of 256), the pre-filter σ in voxels (`suggest.smoothing`), the
/// suggestion's time (`suggest.ms`), the middle of the first boundary above the
/// background of the noise-handling suggestion (`suggest.first_boundary`: the fog's
/// cut, whatever the variant's options), the fog in all and away from the silhouette
/// (`suggest.fog`, `suggest.fog_away`: `crate::search::fog_share`) and the share of the
/// image the TF covers (`suggest.covered`, α ≥ 0.05).
pub const SUGGEST_STATISTICS: [&str; 7] = [
    "suggest.bins",
    "suggest.smoothing",
    "suggest.ms",
    "suggest.first_boundary",
    "suggest.fog",
    "suggest.fog_away",
    "suggest.covered",
];

impl SuggestSpec {
    fn options(&self) -> vwb_render::suggest::SuggestOptions {
        let base = if self.filtered.unwrap_or(true) {
            vwb_render::suggest::SuggestOptions::default()
        } else {
            vwb_render::suggest::SuggestOptions::unfiltered()
        };
        vwb_render::suggest::SuggestOptions {
            thickness: self.thickness.unwrap_or(base.thickness),
            max_opacity: self.max_opacity.unwrap_or(base.max_opacity),
            ..base
        }
    }
}

/// Suggests a variant's TF from `volume`, measures its fog on `r` with `d`'s stack at
/// `d`'s frame, and puts the suggestion into `d`'s first `classify.tf1d`.
fn suggest_tf(
    spec: &SuggestSpec,
    r: &mut vwb_render::Renderer,
    d: &mut Document,
    volume: &Volume,
) -> Result<BTreeMap<String, f64>> {
    use vwb_render::suggest::{SuggestOptions, suggest};
    // checked at load, and again by `suggest`
    let o = spec.options();
    let start = std::time::Instant::now();
    let s = suggest(volume, &o).map_err(|e| anyhow!("suggest: {e}"))?;
    let ms = start.elapsed().as_secs_f64() * 1e3;
    // the fog's cut: the noise-handling suggestion's first boundary
    let first = if o == SuggestOptions::default() {
        s.first_boundary()
    } else {
        suggest(volume, &SuggestOptions::default())
            .ok()
            .and_then(|n| n.first_boundary())
    };
    let frame = d.frame_settings();
    let (fog, away) = match first {
        Some(f) => crate::search::fog_share(r, &d.stack, &s.curve, f, &frame)?,
        None => (f64::NAN, f64::NAN),
    };
    let covered = crate::search::covered(r, &d.stack, &s.curve, &frame)?;
    let tf = d
        .stack
        .iter_mut()
        .find(|i| i.enabled && i.plugin.id() == "classify.tf1d")
        .ok_or_else(|| anyhow!("suggest: the stack has no classify.tf1d"))?;
    tf.params.set("tf", ParamValue::Tf(s.curve.clone()));
    Ok(BTreeMap::from([
        ("suggest.bins".to_string(), s.boundary_bins() as f64),
        ("suggest.smoothing".to_string(), s.smoothing),
        ("suggest.ms".to_string(), ms),
        (
            "suggest.first_boundary".to_string(),
            first.unwrap_or(f64::NAN),
        ),
        ("suggest.fog".to_string(), fog),
        ("suggest.fog_away".to_string(), away),
        ("suggest.covered".to_string(), covered),
    ]))
}

/// A variant's design gallery ([`vwb_render::search::gallery::GalleryOptions`]; the
/// fields left out take `vwb gallery`'s defaults: pool 256, k 36, tile 64, views 3,
/// seed 1, spacing 1 voxel, at most 3 primitives, 96 tiles per atlas).
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GallerySpec {
    /// Genomes drawn.
    pub pool: Option<usize>,
    /// Genomes chosen.
    pub k: Option<usize>,
    /// Thumbnail side (pixels).
    pub tile: Option<u32>,
    /// Viewpoints per genome.
    pub views: Option<usize>,
    pub seed: Option<u64>,
    /// The thumbnails' slice spacing, voxels.
    pub spacing: Option<f64>,
    pub max_primitives: Option<usize>,
    /// Tiles per atlas (one submission each).
    pub batch: Option<usize>,
}

/// The figures of a variant's gallery, as statistics: thumbnails rendered per second of
/// atlas rendering and read-back (`gallery.thumbnails_per_s`), the smallest pairwise
/// descriptor distance (RMS ΔE*uv) among the chosen (`gallery.dispersion`) and among as
/// many drawn at random (`gallery.random_dispersion`), their ratio
/// (`gallery.dispersion_gain`), and the gallery's wall time (`gallery.seconds`).
pub const GALLERY_STATISTICS: [&str; 5] = [
    "gallery.thumbnails_per_s",
    "gallery.dispersion",
    "gallery.random_dispersion",
    "gallery.dispersion_gain",
    "gallery.seconds",
];

impl GallerySpec {
    fn options(&self) -> vwb_render::search::gallery::GalleryOptions {
        let d = vwb_render::search::gallery::GalleryOptions::default();
        vwb_render::search::gallery::GalleryOptions {
            pool: self.pool.unwrap_or(d.pool),
            k: self.k.unwrap_or(d.k),
            tile: self.tile.unwrap_or(d.tile),
            views: self.views.unwrap_or(d.views),
            seed: self.seed.unwrap_or(d.seed),
            slice_spacing: self.spacing.map_or(d.slice_spacing, |s| s as f32),
            max_primitives: self.max_primitives.unwrap_or(d.max_primitives),
            batch: self.batch.unwrap_or(d.batch),
            around: None,
        }
    }

    /// The options are in range (`own`: the variant, for errors).
    fn check(&self, own: &str) -> Result<(), String> {
        let o = self.options();
        let what = format!("the gallery of variant '{own}'");
        let checks: [(&str, usize, RangeInclusive<usize>); 6] = [
            ("pool", o.pool, 2..=65536),
            ("k", o.k, 1..=o.pool.min(1024)),
            ("tile", o.tile as usize, 8..=512),
            ("views", o.views, 1..=16),
            (
                "max_primitives",
                o.max_primitives,
                1..=vwb_render::search::genome::MAX_PRIMITIVES,
            ),
            ("batch", o.batch, 1..=1024),
        ];
        in_ranges(&what, &checks)?;
        if !(o.slice_spacing.is_finite() && o.slice_spacing > 0.0) {
            return Err(format!("{what}: spacing must be > 0"));
        }
        Ok(())
    }
}

/// Each named count within its range, or an error naming `what`, the count and the
/// range (a search's or a gallery's options).
fn in_ranges(what: &str, checks: &[(&str, usize, RangeInclusive<usize>)]) -> Result<(), String> {
    for (name, v, range) in checks {
        if !range.contains(v) {
            return Err(format!(
                "{what}: {name} {v} is outside {}..={}",
                range.start(),
                range.end()
            ));
        }
    }
    Ok(())
}

/// What a variant's gallery gave at one grid point.
#[derive(Debug, Clone, Serialize)]
pub struct GalleryRecord {
    pub thumbnails: usize,
    pub render_ms: f64,
    pub seconds: f64,
    pub dispersion: f64,
    pub random_dispersion: f64,
    /// The sheet (chosen thumbnails on their grid), relative to the report's folder.
    pub sheet: String,
}

impl GalleryRecord {
    /// A statistic of [`GALLERY_STATISTICS`].
    fn statistic(&self, name: &str) -> f64 {
        match name {
            "gallery.thumbnails_per_s" => self.thumbnails as f64 / (self.render_ms / 1e3).max(1e-9),
            "gallery.dispersion" => self.dispersion,
            "gallery.random_dispersion" => self.random_dispersion,
            "gallery.dispersion_gain" => self.dispersion / self.random_dispersion,
            "gallery.seconds" => self.seconds,
            _ => f64::NAN,
        }
    }
}

/// Draws a variant's gallery on its renderer from `d`'s stack and camera, and saves its
/// sheet as `images/gallery_NNN.png` (`row`: the row's index) in `out`.
fn gallery_of(
    spec: &GallerySpec,
    r: &mut vwb_render::Renderer,
    d: &Document,
    out: &Path,
    row: usize,
) -> Result<GalleryRecord> {
    let o = spec.options();
    let start = std::time::Instant::now();
    let g =
        vwb_render::search::gallery::gallery(r, &d.stack, &d.camera, measure::background(d), &o)
            .map_err(|e| anyhow!("gallery: {e}"))?;
    let seconds = start.elapsed().as_secs_f64();
    let sheet = format!("images/gallery_{row:03}.png");
    headless::save_png(&crate::search::sheet(&g, o.tile), &out.join(&sheet))?;
    Ok(GalleryRecord {
        thumbnails: g.rendered,
        render_ms: g.render_ms,
        seconds,
        dispersion: g.dispersion,
        random_dispersion: g.random_dispersion,
        sheet,
    })
}

/// A variant's TF search: toward the views another variant gives from the search's
/// viewpoints (`target`), or toward an objective, from a seeded random population.
/// The other fields are [`vwb_render::search::genetic::GaOptions`]' (defaults there).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchSpec {
    /// The variant whose views (same scene, same grid point) are the target.
    #[serde(default)]
    pub target: Option<String>,
    /// Or an objective to maximise: `entropy`, `edge_energy`, `histogram_variance` or
    /// `boundary_coverage`.
    #[serde(default)]
    pub objective: Option<String>,
    #[serde(default)]
    pub population: Option<usize>,
    #[serde(default)]
    pub generations: Option<usize>,
    #[serde(default)]
    pub seed: Option<u64>,
    /// Thumbnail side (pixels).
    #[serde(default)]
    pub tile: Option<u32>,
    /// Viewpoints the fitness is taken over.
    #[serde(default)]
    pub views: Option<usize>,
    #[serde(default)]
    pub max_primitives: Option<usize>,
    /// Fit the polled genome's colours to a target by least squares (default true;
    /// `false` to measure the search without it).
    #[serde(default)]
    pub colour_fit: Option<bool>,
    /// The score at which `search.reached` counts the target as reached (default 3:
    /// RMS ΔE*uv 3 to a target's thumbnails).
    #[serde(default)]
    pub reach: Option<f64>,
}

/// The figures of a variant's search, as statistics (columns and assertion terms):
/// the best score of the first generation (`search.first`) and of the last
/// (`search.best`; RMS ΔE*uv to the target's thumbnails, or minus the objective), the
/// first generation whose best scores at most `reach` (`search.reached`, counted from
/// 0; — where none did) and the genomes rendered by then (`search.renders`), the
/// search's wall time (`search.seconds`) and its thumbnails per second
/// (`search.thumbnails_per_s`).
pub const SEARCH_STATISTICS: [&str; 6] = [
    "search.first",
    "search.best",
    "search.reached",
    "search.renders",
    "search.seconds",
    "search.thumbnails_per_s",
];

impl SearchSpec {
    /// The run's options for a stack whose TF model is `space`.
    fn options(
        &self,
        space: vwb_render::search::genome::Space,
    ) -> vwb_render::search::genetic::GaOptions {
        let d = vwb_render::search::genetic::GaOptions::default();
        vwb_render::search::genetic::GaOptions {
            population: self.population.unwrap_or(d.population),
            generations: self.generations.unwrap_or(d.generations),
            seed: self.seed.unwrap_or(d.seed),
            tile: self.tile.unwrap_or(d.tile),
            views: self.views.unwrap_or(d.views),
            max_primitives: self.max_primitives.unwrap_or(d.max_primitives),
            colour_fit: self.colour_fit.unwrap_or(d.colour_fit),
            space,
            ..d
        }
    }

    /// The fitness's target or objective, checked (`named`: whether a variant exists).
    fn check(&self, own: &str, named: impl Fn(&str) -> bool) -> Result<(), String> {
        match (&self.target, &self.objective) {
            (Some(t), None) => {
                if t == own {
                    return Err(format!("variant '{own}' searches toward itself"));
                }
                if !named(t) {
                    return Err(format!(
                        "the search of variant '{own}' targets variant '{t}', which the experiment does not declare"
                    ));
                }
            }
            (None, Some(o)) => {
                if o != crate::search::BOUNDARY_COVERAGE
                    && vwb_render::search::genetic::Objective::from_name(o).is_none()
                {
                    return Err(format!(
                        "the search of variant '{own}': unknown objective '{o}' (entropy, edge_energy, \
                         histogram_variance or {})",
                        crate::search::BOUNDARY_COVERAGE
                    ));
                }
            }
            _ => {
                return Err(format!(
                    "the search of variant '{own}' needs either a target variant or an objective"
                ));
            }
        }
        let checks = [
            ("population", self.population, 2..=1024),
            ("generations", self.generations, 1..=1000),
            ("views", self.views, 1..=16),
            (
                "max_primitives",
                self.max_primitives,
                1..=vwb_render::search::genome::MAX_PRIMITIVES,
            ),
            ("tile", self.tile.map(|t| t as usize), 8..=512),
        ];
        // only what the file sets: the search's defaults are in range
        let set: Vec<_> = checks
            .into_iter()
            .filter_map(|(name, v, range)| v.map(|v| (name, v, range)))
            .collect();
        in_ranges(&format!("the search of variant '{own}'"), &set)?;
        if let Some(r) = self.reach
            && !r.is_finite()
        {
            return Err(format!(
                "the search of variant '{own}': reach must be a finite number"
            ));
        }
        Ok(())
    }
}

/// The voxels `from ≤ (x, y, z) < to` a variant keeps of its scene's volume.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Crop {
    pub from: [u32; 3],
    pub to: [u32; 3],
}

impl Crop {
    fn keep(&self) -> [[u32; 2]; 3] {
        std::array::from_fn(|a| [self.from[a], self.to[a]])
    }
}

/// A value in a variant's `set`: checked against the parameter's spec.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(untagged)]
pub enum SetValue {
    Bool(bool),
    Number(f64),
    Text(String),
    /// A vec3 `(x, y, z)` or a colour `(r, g, b, a)`.
    Numbers(Vec<f64>),
}

/// One axis of the grid: `values: [..]` or `range: "A..B:N"` (`:log` for geometric).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridAxis {
    /// `render.slice_spacing`, `render.size` (the image's side: side × side pixels),
    /// `camera.yaw_deg`, `camera.pitch_deg`, `camera.distance`, `camera.fov_y_deg` or
    /// `<plugin id>.<key>` (a float or int parameter).
    pub param: String,
    #[serde(default)]
    pub values: Option<Vec<f64>>,
    #[serde(default)]
    pub range: Option<String>,
}

/// What each image is compared with.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
pub enum ReferenceSpec {
    /// The converged reference of the image's own stack (the one a plugin supplies, else
    /// refined slices), one per distinct plugin-parameter point.
    #[default]
    Converged,
    /// The converged reference of the named variant at the same grid point (e.g. every
    /// classification mode against the converged post-classification integral).
    ConvergedOf(String),
    /// The CPU twin renderer with the same slices.
    Twin,
    /// The named variant's CPU twin image at the same grid point (its stack and volume,
    /// e.g. the physically cropped data a clipped variant must reproduce).
    TwinOf(String),
    /// The named variant's GPU image at the same grid point.
    Variant(String),
    /// The illumination ground truth of the scene: single scattering of a directional
    /// light with shadows, Monte Carlo on the CPU, for the stack's clip, sample and
    /// classify plugins (shading plugins are what it measures, so they are ignored);
    /// one per scene and grid point, shared by the variants
    /// (`vwb_render::reference::render_single_scattering`).
    SingleScattering(ScatteringSpec),
    /// No reference: the rows are timed only (their error metrics are NaN, shown as —,
    /// and an assertion on them fails). Not `None`, which a variant's optional
    /// `reference` would read as "the experiment's".
    TimeOnly,
}

/// The light and effort of a [`ReferenceSpec::SingleScattering`] reference.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScatteringSpec {
    /// Towards the light, world space; None (the default): a head light from the eye.
    #[serde(default)]
    pub light: Option<(f64, f64, f64)>,
    /// Paths per pixel (default 64).
    #[serde(default = "default_paths")]
    pub samples: u32,
    /// κ of a chromatic extinction on the light's paths (σ per channel = κ·σ on the
    /// shadow rays; the eye ray keeps σ); None (the default): achromatic.
    #[serde(default)]
    pub extinction: Option<(f64, f64, f64)>,
}

fn default_paths() -> u32 {
    64
}

/// A measured quantity of one row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Metric {
    RmsDeltaE,
    MeanDeltaE,
    MaxDeltaE,
    #[serde(rename = "share_above_6")]
    ShareAbove6,
    Ssim,
    PsnrDb,
    /// RMS ΔE*uv after a σ = 1 pixel blur of both images
    /// ([`vwb_render::metrics::Metrics::rms_delta_e_blur`]): structured error only.
    RmsDeltaEBlur,
    FrameMs,
    /// What the grid point's change re-ran: the wall time of the first frame after its
    /// stack is applied less the median wall time of the timed frames (at least 0) —
    /// volume passes (light volumes, LIC volumes), pre-passes and tables that depend on
    /// the slice spacing. The price of a parameter change, where `frame_ms` is the
    /// price of a frame.
    UpdateMs,
    /// The GPU's own time for the update's passes: the timestamps of the pre-passes and
    /// volume passes the first frame ran (their median over `update_repeats`); NaN
    /// where the adapter has no timestamps, or where they cannot be the update's (under
    /// a quarter of `update_ms` on a CPU adapter, under 1 % on a GPU: lavapipe reports
    /// near-zero times for compute passes).
    UpdateGpuMs,
    /// The wall time of applying the grid point's stack to the renderer
    /// (`Renderer::update_stack`: composing and compiling where the code changed, the
    /// uniforms, resource updates such as re-baked tables or masks), before its first
    /// frame: the CPU side of a change, which `update_ms` (frames) does not see.
    ApplyMs,
    /// How many pre-passes and volume-pass dispatches the grid point's first frame ran
    /// ([`Row::update_passes`]): 0 where the change reran nothing.
    PassesRerun,
    Slices,
    GpuMemoryMib,
    /// The share of empty-space-skipping bricks that no sample can make visible (the
    /// transfer function's and the clipping's), NaN with skipping off.
    EmptyBrickShare,
    /// The share of the image's pixels that are not transparent (α > 0.01): what a view
    /// covers, e.g. a clipped view against the whole one.
    Coverage,
}

impl Metric {
    pub const ALL: [Metric; 16] = [
        Metric::RmsDeltaE,
        Metric::MeanDeltaE,
        Metric::MaxDeltaE,
        Metric::ShareAbove6,
        Metric::Ssim,
        Metric::PsnrDb,
        Metric::RmsDeltaEBlur,
        Metric::FrameMs,
        Metric::UpdateMs,
        Metric::UpdateGpuMs,
        Metric::ApplyMs,
        Metric::PassesRerun,
        Metric::Slices,
        Metric::GpuMemoryMib,
        Metric::EmptyBrickShare,
        Metric::Coverage,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Metric::RmsDeltaE => "rms_delta_e",
            Metric::MeanDeltaE => "mean_delta_e",
            Metric::MaxDeltaE => "max_delta_e",
            Metric::ShareAbove6 => "share_above_6",
            Metric::Ssim => "ssim",
            Metric::PsnrDb => "psnr_db",
            Metric::RmsDeltaEBlur => "rms_delta_e_blur",
            Metric::FrameMs => "frame_ms",
            Metric::UpdateMs => "update_ms",
            Metric::UpdateGpuMs => "update_gpu_ms",
            Metric::ApplyMs => "apply_ms",
            Metric::PassesRerun => "passes_rerun",
            Metric::Slices => "slices",
            Metric::GpuMemoryMib => "gpu_memory_mib",
            Metric::EmptyBrickShare => "empty_brick_share",
            Metric::Coverage => "coverage",
        }
    }

    fn header(self) -> &'static str {
        match self {
            Metric::RmsDeltaE => "RMS ΔE*uv",
            Metric::MeanDeltaE => "mean ΔE*uv",
            Metric::MaxDeltaE => "max ΔE*uv",
            Metric::ShareAbove6 => "ΔE > 6",
            Metric::Ssim => "SSIM",
            Metric::PsnrDb => "PSNR (dB)",
            Metric::RmsDeltaEBlur => "RMS ΔE*uv, blurred",
            Metric::FrameMs => "time (ms)",
            Metric::UpdateMs => "update (ms)",
            Metric::UpdateGpuMs => "update, GPU (ms)",
            Metric::ApplyMs => "apply (ms)",
            Metric::PassesRerun => "passes rerun",
            Metric::Slices => "slices",
            Metric::GpuMemoryMib => "GPU memory (MiB)",
            Metric::EmptyBrickShare => "empty bricks",
            Metric::Coverage => "image covered",
        }
    }

    fn parse(s: &str) -> Option<Metric> {
        if s == "time" {
            return Some(Metric::FrameMs);
        }
        Metric::ALL.into_iter().find(|m| m.name() == s)
    }

    fn of(self, row: &Row) -> f64 {
        let m = &row.metrics;
        match self {
            Metric::RmsDeltaE => m.rms_delta_e,
            Metric::MeanDeltaE => m.mean_delta_e,
            Metric::MaxDeltaE => m.max_delta_e,
            Metric::ShareAbove6 => m.share_above_6,
            Metric::Ssim => m.ssim,
            Metric::PsnrDb => m.psnr_db,
            Metric::RmsDeltaEBlur => m.rms_delta_e_blur,
            Metric::FrameMs => row.frame_ms,
            Metric::UpdateMs => row.update_ms,
            Metric::UpdateGpuMs => row.update_gpu_ms,
            Metric::ApplyMs => row.apply_ms,
            Metric::PassesRerun => row.update_passes.len() as f64,
            Metric::Slices => row.slices as f64,
            Metric::GpuMemoryMib => row.gpu_memory_bytes as f64 / (1u64 << 20) as f64,
            Metric::EmptyBrickShare => row.empty_brick_share,
            Metric::Coverage => row.coverage,
        }
    }

    fn cell(self, row: &Row) -> String {
        let v = self.of(row);
        if v.is_nan() {
            return "—".into();
        }
        match self {
            // small shares keep a second digit
            Metric::ShareAbove6 if v > 0.0 && v < 0.01 => format!("{:.2} %", 100.0 * v),
            Metric::ShareAbove6 | Metric::Coverage => format!("{:.1} %", 100.0 * v),
            Metric::Slices | Metric::PassesRerun => format!("{v}"),
            Metric::Ssim => format!("{v:.4}"),
            Metric::GpuMemoryMib => format!("{v:.1}"),
            Metric::EmptyBrickShare => format!("{v:.3}"),
            // errors below 1 keep a third digit (a fine variant against a finer one)
            Metric::RmsDeltaE | Metric::MeanDeltaE | Metric::RmsDeltaEBlur
                if v != 0.0 && v.abs() < 1.0 =>
            {
                format!("{v:.3}")
            }
            _ => format!("{v:.2}"),
        }
    }
}

/// Overrides of every scene's `render:` section.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderOverrides {
    pub size: Option<(u32, u32)>,
    /// `rgba16float` or `rgba32float`.
    pub target: Option<String>,
    /// 0 switches early ray termination off.
    pub early_termination: Option<f32>,
    /// `raster` or `compute`.
    pub backend: Option<String>,
}

/// A marked block of a doc that the report replaces.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DocBlock {
    pub file: PathBuf,
    pub block: String,
    /// Also copy the rows' images next to the doc (`images/<experiment>_<row>.png` in
    /// its folder) and show them in the block, in row order (a figure the doc shows,
    /// regenerated with its table): `true` for every row, or a list of row indices
    /// (from 0). Only into the CPU device's doc.
    #[serde(default)]
    pub images: DocImages,
}

/// Which rows' images a doc block shows ([`DocBlock::images`]).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum DocImages {
    All(bool),
    Rows(Vec<usize>),
}

impl Default for DocImages {
    fn default() -> Self {
        DocImages::All(false)
    }
}

impl DocImages {
    fn shows(&self, row: usize) -> bool {
        match self {
            DocImages::All(all) => *all,
            DocImages::Rows(rows) => rows.contains(&row),
        }
    }
}

/// One measured image.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub scene: String,
    pub variant: String,
    /// The grid values, in the order of [`Experiment::grid`].
    pub values: Vec<f64>,
    pub slices: u32,
    pub frame_ms: f64,
    /// `gpu` (timestamps) or `wall`.
    pub clock: &'static str,
    /// [`Metric::UpdateMs`] (wall clock).
    pub update_ms: f64,
    /// [`Metric::UpdateGpuMs`] (NaN without timestamps).
    pub update_gpu_ms: f64,
    /// [`Metric::ApplyMs`].
    pub apply_ms: f64,
    /// The pre-passes (`<plugin id>/prepass`) and volume passes (`<plugin id>/<target>`,
    /// one per dispatch) of the first frame after the grid point's stack was applied:
    /// what `update_ms` paid for.
    pub update_passes: Vec<String>,
    pub gpu_memory_bytes: u64,
    /// [`Metric::EmptyBrickShare`] (NaN with skipping off).
    pub empty_brick_share: f64,
    /// [`Metric::Coverage`] (NaN for a probe's rows).
    pub coverage: f64,
    pub metrics: Metrics,
    /// [`Experiment::statistics`] by name (absent where the plugin is off).
    pub statistics: BTreeMap<String, f64>,
    /// The image file, relative to the report's folder.
    pub image: String,
    /// Which reference it was compared with (an index into the report's references);
    /// `None` with `reference: TimeOnly`.
    pub reference: Option<usize>,
    pub pareto: bool,
    /// What a searched variant's search found (None for other variants).
    pub search: Option<SearchRecord>,
    /// What a gallery variant's gallery gave (None for other variants).
    pub gallery: Option<GalleryRecord>,
}

/// The GPU timestamps of a frame's pre-passes and volume passes (ms), None where the
/// frame has none or the adapter reports zeros.
fn update_stamps(stats: &vwb_render::FrameStats) -> Option<f64> {
    let ms: f64 = stats
        .gpu_passes
        .iter()
        .filter(|(label, _)| label.starts_with("prepass ") || label.starts_with("pass "))
        .map(|(_, ms)| ms)
        .sum();
    (ms > 0.0).then_some(ms)
}

/// A variant's search at one grid point: the genome the row renders, and how the
/// search got there.
#[derive(Debug, Clone, Serialize)]
pub struct SearchRecord {
    pub genome: vwb_render::search::genome::Genome,
    /// The best score of every generation (lower is better: RMS ΔE*uv to the target's
    /// thumbnails, or minus the objective).
    pub best_by_generation: Vec<f64>,
    /// Where each generation's best came from (`vwb_render::search::genetic::Origin`:
    /// random, elite, colour_fit, newton, poll, shape, structure, child).
    pub best_origins: Vec<&'static str>,
    pub population: usize,
    pub views: usize,
    pub seconds: f64,
    /// The score at which the target counts as reached.
    pub reach: f64,
    /// The row's document with the genome, saved in the report's folder.
    pub preset: String,
}

impl SearchRecord {
    /// A statistic of [`SEARCH_STATISTICS`] (NaN where it does not exist, as a
    /// `search.reached` never reached).
    fn statistic(&self, name: &str) -> f64 {
        let reached = self
            .best_by_generation
            .iter()
            .position(|&b| b <= self.reach);
        let generations = self.best_by_generation.len();
        match name {
            "search.first" => self.best_by_generation.first().copied().unwrap_or(f64::NAN),
            "search.best" => self.best_by_generation.last().copied().unwrap_or(f64::NAN),
            "search.reached" => reached.map_or(f64::NAN, |g| g as f64),
            "search.renders" => reached.map_or(f64::NAN, |g| ((g + 1) * self.population) as f64),
            "search.seconds" => self.seconds,
            "search.thumbnails_per_s" => {
                (generations * self.population * self.views) as f64 / self.seconds.max(1e-9)
            }
            _ => f64::NAN,
        }
    }
}

/// Runs a variant's search on its renderer from `d`'s stack and camera, and puts the
/// best genome into `d`'s TF plugin. `target`: the target variant's document and volume
/// at the same grid point; `observer` sees each generation's best score.
fn search_tf(
    gpu: &GpuContext,
    spec: &SearchSpec,
    r: &mut vwb_render::Renderer,
    d: &mut Document,
    volume: &Arc<Volume>,
    target: Option<(Document, Arc<Volume>)>,
    observer: &mut dyn FnMut(usize, f64),
) -> Result<SearchRecord> {
    use vwb_render::search::{gallery, genetic, genome::Space};
    let space = Space::of_stack(&d.stack).map_err(|e| anyhow!(e))?;
    let o = spec.options(space);
    let bg = measure::background(d);
    let cams = gallery::viewpoints(&d.camera, o.views);
    let fitness = match (target, spec.objective.as_deref()) {
        (Some((td, tvol)), _) => genetic::Fitness::Target(gallery::descriptor(
            &crate::search::views_of(gpu, &td, tvol, &cams, &o, bg)?,
        )),
        (None, Some(crate::search::BOUNDARY_COVERAGE)) => {
            let cover =
                vwb_render::search::coverage::Coverage::for_stack(volume, &cams, o.tile, &d.stack)
                    .map_err(|e| anyhow!(e))?;
            genetic::Fitness::Coverage(Arc::new(cover))
        }
        (None, Some(name)) => genetic::Fitness::Objective(
            genetic::Objective::from_name(name).expect("checked at load"),
        ),
        (None, None) => unreachable!("checked at load"),
    };
    let start = std::time::Instant::now();
    let history = genetic::evolve(r, &d.stack, &d.camera, bg, &fitness, &o, &mut |g, step| {
        observer(g, step.best_score)
    })?;
    let seconds = start.elapsed().as_secs_f64();
    let best = history
        .last()
        .expect("at least one generation")
        .best
        .clone();
    best.apply(&mut d.stack).map_err(|e| anyhow!(e))?;
    Ok(SearchRecord {
        genome: best,
        best_by_generation: history.iter().map(|g| g.best_score).collect(),
        best_origins: history.iter().map(|g| g.origin.name()).collect(),
        population: o.population,
        views: o.views,
        seconds,
        reach: spec.reach.unwrap_or(3.0),
        preset: String::new(),
    })
}

/// A number in an assertion's detail: four decimals, or four digits in scientific
/// notation below 10⁻³ (a probe's small errors).
fn detail_number(x: f64) -> String {
    if x != 0.0 && x.abs() < 1e-3 {
        format!("{x:.3e}")
    } else {
        format!("{x:.4}")
    }
}

/// The metrics of a row with no reference: every error NaN (shown as —).
fn no_metrics(width: u32, height: u32) -> Metrics {
    Metrics {
        width,
        height,
        rms_delta_e: f64::NAN,
        mean_delta_e: f64::NAN,
        max_delta_e: f64::NAN,
        share_above_6: f64::NAN,
        psnr_db: f64::NAN,
        ssim: f64::NAN,
        rms_delta_e_blur: f64::NAN,
    }
}

/// An assertion's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct Checked {
    pub assertion: String,
    pub passed: bool,
    /// What was measured, in words.
    pub detail: String,
}

/// A finished run.
#[derive(Debug, Clone, Serialize)]
pub struct Outcome {
    pub name: String,
    pub rows: Vec<Row>,
    pub references: Vec<serde_json::Value>,
    pub assertions: Vec<Checked>,
    /// The report's Markdown.
    pub markdown: String,
}

impl Outcome {
    pub fn failed(&self) -> Vec<&Checked> {
        self.assertions.iter().filter(|a| !a.passed).collect()
    }
}

/// Reads and checks an experiment file (every assertion parses; at least one scene;
/// variant names are unique; references name existing variants; grid axes have
/// values), naming the file in every error.
pub fn load(path: &Path) -> Result<Experiment> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the experiment file", path.display()))?;
    parse(&text, path)
}

/// [`load`] from text; `path` names the file in errors.
pub fn parse(text: &str, path: &Path) -> Result<Experiment> {
    // `Some(..)` may be left out around optional fields
    let options =
        ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME);
    let e: Experiment = options
        .from_str(text)
        .map_err(|err| anyhow!("{}: {err}", path.display()))?;
    if e.probe.is_some() {
        return probe::checked(e, path);
    }
    let file = path.display();
    if e.scenes.is_empty() {
        bail!("{file}: an experiment needs at least one scene (or a probe)");
    }
    if !(1..=1000).contains(&e.frames) {
        bail!("{file}: frames must be in 1..=1000, got {}", e.frames);
    }
    if !(e.tolerance.is_finite() && e.tolerance > 0.0) {
        bail!("{file}: tolerance must be a finite number > 0");
    }
    if !matches!(
        e.pareto_time,
        Metric::FrameMs | Metric::UpdateMs | Metric::UpdateGpuMs
    ) {
        bail!(
            "{file}: pareto_time must be frame_ms, update_ms or update_gpu_ms, got {}",
            e.pareto_time.name()
        );
    }
    if !(1..=100).contains(&e.update_repeats) {
        bail!(
            "{file}: update_repeats must be in 1..=100, got {}",
            e.update_repeats
        );
    }
    let mut names = std::collections::HashSet::new();
    for v in &e.variants {
        if !names.insert(v.name.as_str()) {
            bail!("{file}: two variants are named '{}'", v.name);
        }
    }
    let named = |n: &str| e.variants.iter().any(|v| v.name == n);
    let specs = std::iter::once((None, &e.reference)).chain(
        e.variants
            .iter()
            .filter_map(|v| v.reference.as_ref().map(|r| (Some(v.name.as_str()), r))),
    );
    for (owner, spec) in specs {
        let whose = owner.map_or_else(String::new, |v| format!(" of variant '{v}'"));
        match spec {
            ReferenceSpec::ConvergedOf(n)
            | ReferenceSpec::Variant(n)
            | ReferenceSpec::TwinOf(n)
                if !named(n) =>
            {
                bail!(
                    "{file}: the reference{whose} names variant '{n}', which the experiment does not declare"
                )
            }
            ReferenceSpec::Variant(n) if owner == Some(n.as_str()) => {
                bail!("{file}: variant '{n}' is its own reference")
            }
            _ => {}
        }
    }
    for v in &e.variants {
        if let Some(search) = &v.search {
            search
                .check(&v.name, named)
                .map_err(|err| anyhow!("{file}: {err}"))?;
            if let Some(t) = &search.target
                && e.variants
                    .iter()
                    .any(|o| &o.name == t && o.search.is_some())
            {
                bail!(
                    "{file}: the search of variant '{}' targets variant '{t}', whose own TF is searched \
                     (a target is a fixed stack)",
                    v.name
                );
            }
        }
    }
    for v in &e.variants {
        let tf_sources = [v.search.is_some(), v.gallery.is_some(), v.suggest.is_some()];
        if tf_sources.iter().filter(|&&x| x).count() > 1 {
            bail!(
                "{file}: variant '{}' has more than one of a search, a gallery and a suggestion; give each its own variant",
                v.name
            );
        }
        if let Some(g) = &v.gallery {
            g.check(&v.name).map_err(|err| anyhow!("{file}: {err}"))?;
        }
        if let Some(sg) = &v.suggest {
            sg.options()
                .check()
                .map_err(|err| anyhow!("{file}: the suggestion of variant '{}': {err}", v.name))?;
        }
    }
    let suggested = e.variants.iter().any(|v| v.suggest.is_some());
    let searched = e.variants.iter().any(|v| v.search.is_some());
    let galleries = e.variants.iter().any(|v| v.gallery.is_some());
    for st in &e.statistics {
        if let Some(targets) = st.strip_prefix(PASS_MS) {
            if targets.split('+').any(|t| t.is_empty() || t.contains('/')) {
                bail!(
                    "{file}: statistic '{st}': name a pass's target after {PASS_MS} (several joined by +), e.g. pass_ms.alpha_lp+alpha_g"
                );
            }
        } else if st.starts_with("suggest.") {
            if !SUGGEST_STATISTICS.contains(&st.as_str()) {
                bail!(
                    "{file}: statistic '{st}': a suggestion reports {}",
                    SUGGEST_STATISTICS.join(", ")
                );
            }
            if !suggested {
                bail!("{file}: statistic '{st}': no variant has a suggested TF");
            }
        } else if st.starts_with("gallery.") {
            if !GALLERY_STATISTICS.contains(&st.as_str()) {
                bail!(
                    "{file}: statistic '{st}': a gallery reports {}",
                    GALLERY_STATISTICS.join(", ")
                );
            }
            if !galleries {
                bail!("{file}: statistic '{st}': no variant has a gallery");
            }
        } else if st.starts_with("search.") {
            if !SEARCH_STATISTICS.contains(&st.as_str()) {
                bail!(
                    "{file}: statistic '{st}': a search reports {}",
                    SEARCH_STATISTICS.join(", ")
                );
            }
            if !searched {
                bail!("{file}: statistic '{st}': no variant has a search");
            }
        } else if !st
            .rsplit_once('.')
            .is_some_and(|(id, name)| id.contains('.') && !name.is_empty())
        {
            bail!("{file}: statistic '{st}' is not of the form <plugin id>.<name>");
        }
    }
    let spacing_axis = e.grid.iter().any(|a| a.param == "render.slice_spacing");
    for v in &e.variants {
        if v.set.contains_key("render.slices")
            && (spacing_axis || v.set.contains_key("render.slice_spacing"))
        {
            bail!(
                "{file}: variant '{}' sets render.slices, which fixes the slice spacing; \
                 leave render.slice_spacing out of its set and of the grid",
                v.name
            );
        }
    }
    for a in &e.grid {
        axis_values(a).map_err(|err| anyhow!("{file}: grid axis '{}': {err}", a.param))?;
    }
    for a in &e.assertions {
        let parsed =
            Assertion::parse(a).map_err(|err| anyhow!("{file}: assertion '{a}': {err}"))?;
        for v in parsed.variants() {
            if !named(v) {
                bail!(
                    "{file}: assertion '{a}' names variant '{v}', which the experiment does not declare"
                );
            }
        }
        for st in parsed.statistics() {
            if !e.statistics.iter().any(|x| x == st) {
                bail!(
                    "{file}: assertion '{a}' reads statistic '{st}', which `statistics` does not list"
                );
            }
        }
    }
    if let Some((w, h)) = e.render.size
        && !((1..=16384).contains(&w) && (1..=16384).contains(&h))
    {
        bail!("{file}: render size {w}x{h} is outside 1..=16384");
    }
    Ok(e)
}

/// Whether a statistic is the runner's own (a search's, a gallery's or a suggestion's
/// figures, a pass's GPU time) rather than a plugin's.
fn runner_statistic(st: &str) -> bool {
    ["search.", "gallery.", "suggest.", PASS_MS]
        .iter()
        .any(|p| st.starts_with(p))
}

/// The statistics of the GPU time of a row's update passes: `pass_ms.T` is the median,
/// over the update's measurements (`update_repeats`), of the timestamps of the volume
/// passes and pre-passes whose target is `T` (their label ends with `/T`, or is
/// `prepass T` for a plugin's pre-pass); `pass_ms.T1+T2` sums several targets (e.g.
/// `pass_ms.alpha_lp+alpha_g`, `shade.hernell`'s level (A)). NaN where no such pass
/// was stamped (a CPU adapter without timestamps, or lavapipe's zeros).
pub const PASS_MS: &str = "pass_ms.";

fn pass_ms(st: &str, updates: &[Vec<(String, f64)>]) -> f64 {
    let targets: Vec<&str> = st[PASS_MS.len()..].split('+').collect();
    let of = |label: &str| {
        targets
            .iter()
            .any(|t| label.ends_with(&format!("/{t}")) || label == format!("prepass {t}"))
    };
    let sums: Vec<f64> = updates
        .iter()
        .filter_map(|passes| {
            let ms: f64 = passes.iter().filter(|(l, _)| of(l)).map(|(_, ms)| ms).sum();
            (ms > 0.0).then_some(ms)
        })
        .collect();
    measure::Summary::of(&sums).map_or(f64::NAN, |m| m.median)
}

/// Names for an error message, comma-separated, or `none` where there are none.
fn listed(names: &[&str], none: &str) -> String {
    if names.is_empty() {
        none.to_string()
    } else {
        names.join(", ")
    }
}

/// The first enabled instance of plugin `id` in a document's stack, configured.
fn enabled_instance<'a>(d: &'a Document, id: &str) -> Option<&'a PluginInstance> {
    d.stack.iter().find(|i| i.enabled && i.plugin.id() == id)
}

/// Checks that a statistic `<plugin id>.<name>` is reported by the plugin in the
/// variants' stacks that hold it, and that some variant holds it.
fn check_statistic<'a>(st: &str, docs: impl Iterator<Item = &'a Document>) -> Result<()> {
    let (id, name) = st.rsplit_once('.').expect("checked at load");
    let mut held = false;
    for d in docs {
        let Some(inst) = enabled_instance(d, id) else {
            continue;
        };
        held = true;
        let names = inst.configured().statistic_names(&inst.params);
        if !names.contains(&name) {
            bail!(
                "plugin '{id}' reports no '{name}' (it reports: {})",
                listed(&names, "nothing")
            );
        }
    }
    if !held {
        bail!("no variant's stack has plugin '{id}' switched on");
    }
    Ok(())
}

/// The statistics of a row: each plugin's figures from its passes' targets after the
/// row's frames (absent where the plugin is off). Each plugin reports once per row,
/// however many of its figures are wanted (each report reads its targets back).
fn statistics_of(
    wanted: &[String],
    r: &vwb_render::Renderer,
    d: &Document,
) -> BTreeMap<String, f64> {
    let mut reports: HashMap<&str, Vec<Statistic>> = HashMap::new();
    let mut out = BTreeMap::new();
    for st in wanted.iter().filter(|st| !runner_statistic(st)) {
        let (id, name) = st.rsplit_once('.').expect("checked at load");
        let Some(inst) = enabled_instance(d, id) else {
            continue;
        };
        let report = reports.entry(id).or_insert_with(|| r.statistics_of(inst));
        let value = report
            .iter()
            .find(|x| x.name == name)
            .map_or(f64::NAN, |x| x.value);
        out.insert(st.clone(), value);
    }
    out
}

fn axis_values(a: &GridAxis) -> Result<Vec<f64>, String> {
    match (&a.values, &a.range) {
        (Some(v), None) if !v.is_empty() => {
            if let Some(x) = v.iter().find(|x| !x.is_finite()) {
                return Err(format!("{x} is not a finite number"));
            }
            Ok(v.clone())
        }
        (None, Some(r)) => measure::parse_values(r),
        (Some(_), Some(_)) => Err("give either values or range, not both".into()),
        _ => Err("needs values: [..] or range: \"A..B:N\"".into()),
    }
}

/// A comparison operator.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    Lt,
    Le,
    Gt,
    Ge,
}

impl Op {
    fn holds(self, a: f64, b: f64) -> bool {
        match self {
            Op::Lt => a < b,
            Op::Le => a <= b,
            Op::Gt => a > b,
            Op::Ge => a >= b,
        }
    }
}

/// What a term measures: a metric, or a plugin statistic ([`Experiment::statistics`]).
#[derive(Debug, Clone, PartialEq)]
enum Measure {
    Metric(Metric),
    Statistic(String),
}

impl Measure {
    fn name(&self) -> &str {
        match self {
            Measure::Metric(m) => m.name(),
            Measure::Statistic(s) => s,
        }
    }
    fn of(&self, row: &Row) -> f64 {
        match self {
            Measure::Metric(m) => m.of(row),
            Measure::Statistic(s) => row.statistics.get(s).copied().unwrap_or(f64::NAN),
        }
    }
}

/// A metric over all rows or over one variant's rows.
#[derive(Debug, Clone, PartialEq)]
struct Term {
    metric: Measure,
    variant: Option<String>,
}

/// A parsed assertion.
#[derive(Debug, Clone, PartialEq)]
enum Assertion {
    /// Every row (of the variant) satisfies `term op bound`.
    Each { term: Term, op: Op, bound: f64 },
    /// median(a) / median(b) op bound.
    Ratio {
        a: Term,
        b: Term,
        op: Op,
        bound: f64,
    },
}

impl Assertion {
    fn parse(s: &str) -> Result<Assertion, String> {
        Self::parse_in(s, &[])
    }

    /// [`Assertion::parse`] where the names in `figures` (a probe's) read statistics
    /// too, as `<plugin id>.<name>` always does.
    pub(crate) fn parse_in(s: &str, figures: &[String]) -> Result<Assertion, String> {
        let ops = [("<=", Op::Le), (">=", Op::Ge), ("<", Op::Lt), (">", Op::Gt)];
        let (lhs, op, rhs) = ops
            .iter()
            .find_map(|(tok, op)| s.split_once(tok).map(|(l, r)| (l, *op, r)))
            .ok_or("expected METRIC < NUMBER (or <=, >, >=)")?;
        let bound: f64 = rhs
            .trim()
            .parse()
            .ok()
            .filter(|b: &f64| b.is_finite())
            .ok_or_else(|| format!("'{}' is not a finite number", rhs.trim()))?;
        let term = |t: &str| -> Result<Term, String> {
            let t = t.trim();
            let (name, variant) = match t.split_once('(') {
                Some((n, rest)) => {
                    let v = rest
                        .strip_suffix(')')
                        .ok_or_else(|| format!("'{t}': missing ')'"))?
                        .trim();
                    if v.is_empty() {
                        return Err(format!("'{t}': empty variant name"));
                    }
                    (n.trim(), Some(v.to_string()))
                }
                None => (t, None),
            };
            let metric = match Metric::parse(name) {
                Some(m) => Measure::Metric(m),
                None if name.contains('.') || figures.iter().any(|f| f == name) => {
                    Measure::Statistic(name.to_string())
                }
                None => {
                    let all: Vec<&str> = Metric::ALL.iter().map(|m| m.name()).collect();
                    return Err(format!(
                        "unknown metric '{name}' (one of time, {}, or a plugin statistic \
                         `<plugin id>.<name>` listed in `statistics`)",
                        all.join(", ")
                    ));
                }
            };
            Ok(Term { metric, variant })
        };
        Ok(match lhs.split_once('/') {
            Some((a, b)) => {
                let (a, b) = (term(a)?, term(b)?);
                if a.variant.is_none() || b.variant.is_none() {
                    return Err("a ratio compares two variants: METRIC(A) / METRIC(B)".into());
                }
                Assertion::Ratio { a, b, op, bound }
            }
            None => Assertion::Each {
                term: term(lhs)?,
                op,
                bound,
            },
        })
    }

    fn terms(&self) -> Vec<&Term> {
        match self {
            Assertion::Each { term, .. } => vec![term],
            Assertion::Ratio { a, b, .. } => vec![a, b],
        }
    }

    fn variants(&self) -> Vec<&str> {
        self.terms()
            .into_iter()
            .filter_map(|t| t.variant.as_deref())
            .collect()
    }

    /// The plugin statistics it reads.
    fn statistics(&self) -> Vec<&str> {
        self.terms()
            .into_iter()
            .filter_map(|t| match &t.metric {
                Measure::Statistic(s) => Some(s.as_str()),
                Measure::Metric(_) => None,
            })
            .collect()
    }

    fn check(&self, text: &str, rows: &[Row]) -> Checked {
        let of = |t: &Term| -> Vec<&Row> {
            rows.iter()
                .filter(|r| t.variant.as_ref().is_none_or(|v| &r.variant == v))
                .collect()
        };
        let (passed, detail) = match self {
            Assertion::Each { term, op, bound } => {
                let rs = of(term);
                if rs.is_empty() {
                    (false, "no rows to check".to_string())
                } else {
                    let failing: Vec<&&Row> = rs
                        .iter()
                        .filter(|r| !op.holds(term.metric.of(r), *bound))
                        .collect();
                    // the worst row: the failing one furthest from the bound, else the closest
                    let worst = rs
                        .iter()
                        .max_by(|a, b| {
                            let (x, y) = (term.metric.of(a), term.metric.of(b));
                            match op {
                                Op::Lt | Op::Le => x.total_cmp(&y),
                                Op::Gt | Op::Ge => y.total_cmp(&x),
                            }
                        })
                        .expect("not empty");
                    (
                        failing.is_empty(),
                        format!(
                            "{} of {} rows fail; worst {} = {} ({})",
                            failing.len(),
                            rs.len(),
                            term.metric.name(),
                            detail_number(term.metric.of(worst)),
                            worst.label()
                        ),
                    )
                }
            }
            Assertion::Ratio { a, b, op, bound } => {
                let med = |t: &Term| {
                    let v: Vec<f64> = of(t).iter().map(|r| t.metric.of(r)).collect();
                    measure::Summary::of(&v).map(|s| s.median)
                };
                match (med(a), med(b)) {
                    (Some(x), Some(y)) if y != 0.0 => {
                        let ratio = x / y;
                        (
                            op.holds(ratio, *bound),
                            format!(
                                "median {} {} / median {} {} = {:.4}",
                                a.metric.name(),
                                detail_number(x),
                                b.metric.name(),
                                detail_number(y),
                                ratio
                            ),
                        )
                    }
                    _ => (false, "no rows, or a zero denominator".to_string()),
                }
            }
        };
        Checked {
            assertion: text.to_string(),
            passed,
            detail,
        }
    }
}

impl Row {
    fn label(&self) -> String {
        let values: Vec<String> = self.values.iter().map(|v| format!("{v}")).collect();
        if values.is_empty() {
            format!("{}, {}", self.scene, self.variant)
        } else {
            format!("{}, {}, {}", self.scene, self.variant, values.join(", "))
        }
    }
}

/// Applies a `set` entry (`<plugin id>.<key>` or `render.*`, see [`Variant::set`]) to a
/// document, checked against the parameter's spec.
pub fn set_value(doc: &mut Document, key: &str, value: &SetValue) -> Result<()> {
    let num = |what: &str| match value {
        SetValue::Number(x) => Ok(*x),
        _ => Err(anyhow!("'{key}' needs a number ({what})")),
    };
    let text = || match value {
        SetValue::Text(t) => Ok(t.as_str()),
        _ => Err(anyhow!("'{key}' needs a string")),
    };
    match key {
        "render.slice_spacing" => {
            let v = num("slice spacing in voxels")?;
            if !(v.is_finite() && v > 0.0) {
                bail!("'{key}' must be > 0, got {v}");
            }
            doc.render.slice_spacing = v as f32;
        }
        "render.early_termination" => {
            let v = num("opacity in (0, 1]; 0 switches it off")?;
            if !(0.0..=1.0).contains(&v) {
                bail!("'{key}' must be in [0, 1], got {v}");
            }
            doc.render.early_termination = (v > 0.0).then_some(v as f32);
        }
        "render.slices" => {
            bail!("'{key}' depends on the scene's volume; it is set in an experiment's variants")
        }
        "camera.yaw_deg" | "camera.pitch_deg" | "camera.distance" | "camera.fov_y_deg" => {
            let v = num("degrees, or world units for the distance")?;
            let k = measure::CameraKey::parse(key).expect("matched");
            k.set(doc, v).map_err(|e| anyhow!("'{key}': {e}"))?;
        }
        "render.backend" => doc.render.backend = parse_backend(text()?).map_err(|e| anyhow!(e))?,
        "render.skipping" => match value {
            SetValue::Bool(on) => doc.render.empty_space_skipping = *on,
            _ => bail!("'{key}' needs true or false"),
        },
        "render.occupied_proxy" => match value {
            SetValue::Bool(on) => doc.render.occupied_proxy = *on,
            _ => bail!("'{key}' needs true or false"),
        },
        "render.hull_cut" => match value {
            SetValue::Bool(on) => doc.render.hull_cut = *on,
            _ => bail!("'{key}' needs true or false"),
        },
        "render.slices_per_proxy" => {
            let v = num("slices per proxy polygon: 0 (auto), 1, 2, 4, 8 or 16")?;
            let groups = vwb_render::renderer::RASTER_GROUPS;
            // `as` saturates (NaN to 0): a value it changes is none of them
            let n = v as u32;
            if n as f64 != v || !vwb_render::renderer::is_raster_group_setting(n) {
                bail!("'{key}' must be 0 (auto) or one of {groups:?}, got {v}");
            }
            doc.render.slices_per_proxy = n;
        }
        "render.target" => doc.render.target = parse_target(text()?).map_err(|e| anyhow!(e))?,
        "render.volume_format" => {
            doc.render.volume_format =
                vwb_render::renderer::VolumeFormat::parse(text()?).map_err(|e| anyhow!(e))?
        }
        "render.table_format" => {
            doc.render.table_format =
                vwb_render::renderer::TableFormat::parse(text()?).map_err(|e| anyhow!(e))?
        }
        _ => {
            let (id, k) = key.rsplit_once('.').ok_or_else(|| {
                anyhow!("'{key}': expected <plugin id>.<key> or render.slice_spacing")
            })?;
            let inst = doc
                .stack
                .iter_mut()
                .find(|i| i.plugin.id() == id)
                .ok_or_else(|| anyhow!("'{key}': the scene has no plugin '{id}'"))?;
            let specs = inst.plugin.params();
            let spec = specs
                .iter()
                .find(|s| s.key == k)
                .ok_or_else(|| anyhow!("'{key}': plugin '{id}' has no parameter '{k}'"))?;
            inst.params.set(k, param_value(key, spec, value)?);
        }
    }
    Ok(())
}

/// A `set` value as the value of the parameter `spec` (named `key` in errors), checked
/// against its kind and range.
fn param_value(
    key: &str,
    spec: &vwb_render::params::ParamSpec,
    value: &SetValue,
) -> Result<ParamValue> {
    let v = match (&spec.kind, value) {
        (ParamKind::Float { .. }, SetValue::Number(x)) => ParamValue::Float(*x as f32),
        (ParamKind::Int { .. }, SetValue::Number(x)) if x.fract() == 0.0 => {
            ParamValue::Int(*x as i32)
        }
        (ParamKind::Bool { .. }, SetValue::Bool(b)) => ParamValue::Bool(*b),
        (ParamKind::Enum { .. }, SetValue::Text(t)) => ParamValue::Enum(t.clone()),
        (ParamKind::Path { .. }, SetValue::Text(t)) => ParamValue::Path(t.into()),
        (ParamKind::Volume { .. }, SetValue::Text(t)) => ParamValue::Volume(t.clone()),
        (ParamKind::Vec3 { .. }, SetValue::Numbers(x)) if x.len() == 3 => {
            ParamValue::Vec3([x[0] as f32, x[1] as f32, x[2] as f32])
        }
        (ParamKind::Color { .. }, SetValue::Numbers(x)) if x.len() == 4 => {
            ParamValue::Color([x[0] as f32, x[1] as f32, x[2] as f32, x[3] as f32])
        }
        (_, v) => bail!("'{key}' takes {}; {v:?} does not fit it", spec.kind_name()),
    };
    spec.check(&v).map_err(|e| anyhow!("'{key}': {e}"))?;
    Ok(v)
}

/// `raster` or `compute` (experiment files, the Python package).
pub fn parse_backend(s: &str) -> Result<Backend, String> {
    match s {
        "raster" => Ok(Backend::Raster),
        "compute" => Ok(Backend::Compute),
        _ => Err(format!("unknown backend '{s}' (raster or compute)")),
    }
}

/// `rgba16float` or `rgba32float` (experiment files, the CLI's `--target`).
pub fn parse_target(s: &str) -> Result<TargetFormat, String> {
    match s {
        "rgba16float" => Ok(TargetFormat::Rgba16Float),
        "rgba32float" => Ok(TargetFormat::Rgba32Float),
        _ => Err(format!("unknown target '{s}' (rgba16float or rgba32float)")),
    }
}

/// The slice spacing (voxels) that gives about `slices` slices in a document's frame
/// through `volume`: the count at one voxel scaled, so the count comes within a slice or
/// two of the target.
pub fn spacing_for_slices(doc: &Document, volume: &Volume, slices: f64) -> Result<f32> {
    if !(slices.fract() == 0.0 && (1.0..=vwb_render::slicing::MAX_SLICES as f64).contains(&slices))
    {
        bail!(
            "'render.slices' must be a whole number in 1..={}, got {slices}",
            vwb_render::slicing::MAX_SLICES
        );
    }
    let at_one = vwb_render::validate::check_slices(&doc.camera, doc.render.size, 1.0, volume)
        .map_err(|e| anyhow!("{e}"))?;
    if at_one == 0 {
        bail!("'render.slices': no slice of the frame meets the volume");
    }
    Ok((at_one as f64 / slices) as f32)
}

impl Variant {
    /// The variant of a scene's document (`volume`: the scene's, for `render.slices`).
    fn apply(&self, base: &Document, volume: &Volume) -> Result<Document> {
        let registry = vwb_plugins::registry();
        let mut doc = base.clone();
        for (from, to) in &self.swap {
            let plugin = registry
                .get(to)
                .map_err(|err| anyhow!("swap '{from}' → '{to}': {err}"))?;
            let at = doc
                .stack
                .iter()
                .position(|i| i.plugin.id() == from)
                .ok_or_else(|| {
                    anyhow!("swap '{from}' → '{to}': the scene has no plugin '{from}'")
                })?;
            let enabled = doc.stack[at].enabled;
            let mut inst = PluginInstance::new(plugin);
            inst.enabled = enabled;
            doc.stack[at] = inst;
        }
        for (list, on) in [(&self.disable, false), (&self.enable, true)] {
            for id in list {
                let mut found = false;
                for inst in doc.stack.iter_mut().filter(|i| i.plugin.id() == id) {
                    inst.enabled = on;
                    found = true;
                }
                if !found {
                    bail!("'{id}': the scene has no plugin '{id}' to switch");
                }
            }
        }
        for (key, value) in self.set.iter().filter(|(k, _)| *k != "render.slices") {
            set_value(&mut doc, key, value)?;
        }
        if let Some(n) = self.set.get("render.slices") {
            let SetValue::Number(n) = n else {
                bail!("'render.slices' needs a number (a slice count)");
            };
            doc.render.slice_spacing = spacing_for_slices(&doc, volume, *n)?;
        }
        Ok(doc)
    }
}

/// A loaded scene.
struct SceneDoc {
    name: String,
    doc: Document,
    volume: Arc<Volume>,
}

fn load_scene(scene: &Scene, dir: &Path, e: &Experiment) -> Result<SceneDoc> {
    let (name, mut doc) = match scene {
        Scene::Preset(p) => {
            let path = dir.join(p);
            let name = path.file_stem().map_or_else(
                || path.display().to_string(),
                |s| s.to_string_lossy().into(),
            );
            (name, crate::document::load_document(Some(&path))?)
        }
        Scene::Sample(s) => {
            let mut doc = crate::document::load_document(None)?;
            doc.volume = VolumeSource::Sample(s.clone());
            (s.clone(), doc)
        }
    };
    let volume = headless::load_volume(&doc.volume).with_context(|| format!("scene '{name}'"))?;
    if matches!(scene, Scene::Sample(_)) {
        let b = VolumeBox::new(volume.dims, volume.spacing);
        doc.camera.fit(b.min, b.max);
    }
    if let Some((w, h)) = e.render.size {
        doc.render.size = [w, h];
    }
    if let Some(t) = &e.render.target {
        doc.render.target = parse_target(t).map_err(|e| anyhow!(e))?;
    }
    if let Some(b) = &e.render.backend {
        doc.render.backend = parse_backend(b).map_err(|e| anyhow!(e))?;
    }
    if let Some(t) = e.render.early_termination {
        doc.render.early_termination = (t > 0.0).then_some(t);
    }
    if let Some(seed) = e.seed {
        for inst in &mut doc.stack {
            let has_seed = inst
                .plugin
                .params()
                .iter()
                .any(|s| s.key == "seed" && matches!(s.kind, ParamKind::Int { .. }));
            if has_seed {
                inst.params
                    .set("seed", ParamValue::Int((seed % i32::MAX as u64) as i32));
            }
        }
    }
    Ok(SceneDoc { name, doc, volume })
}

/// The key of a converged reference: the plugin stack (or what the supplied reference
/// depends on, [`ConvergedReference::key`]) and frame without the spacing.
fn reference_key(scene: &str, doc: &Document, supplier: Option<&dyn ConvergedReference>) -> String {
    let mut d = doc.clone();
    d.render.slice_spacing = 1.0;
    d.render.early_termination = None;
    let stack = supplier.and_then(|r| r.key(&d.stack)).unwrap_or_else(|| {
        let parts: Vec<String> = d
            .stack
            .iter()
            .filter(|i| i.enabled)
            .map(|i| format!("{}:{:?}", i.plugin.id(), i.params))
            .collect();
        parts.join(";")
    });
    format!(
        "{scene}|{:?}|{:?}|{:?}|{stack}",
        d.render.size, d.camera, d.render.background,
    )
}

/// What [`run`] reports while it runs.
pub enum Event<'a> {
    Reference {
        scene: &'a str,
        what: &'a str,
    },
    /// A searched variant's generation and its best score.
    Generation {
        scene: &'a str,
        variant: &'a str,
        generation: usize,
        best: f64,
    },
    Row {
        index: usize,
        row: &'a Row,
    },
}

/// Runs an experiment; `dir` resolves its relative paths, `out` receives the report.
/// Errors in the setup name the experiment file; a failed assertion is not an error
/// here (see [`Outcome::failed`]).
pub fn run(
    gpu: &GpuContext,
    e: &Experiment,
    file: &Path,
    out: &Path,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Outcome> {
    if e.probe.is_some() {
        return probe::run(e, file, out, observer);
    }
    let dir = file.parent().unwrap_or(Path::new("."));
    let fname = file.display();
    let default_variant = [Variant {
        name: "as is".into(),
        ..Default::default()
    }];
    let variants: &[Variant] = if e.variants.is_empty() {
        &default_variant
    } else {
        &e.variants
    };
    std::fs::create_dir_all(out.join("images"))
        .with_context(|| format!("{}: cannot create", out.display()))?;
    let grid_values: Vec<Vec<f64>> = e
        .grid
        .iter()
        .map(|a| axis_values(a).map_err(|err| anyhow!("{fname}: grid '{}': {err}", a.param)))
        .collect::<Result<_>>()?;
    let mut rows: Vec<Row> = Vec::new();
    let mut references: Vec<serde_json::Value> = Vec::new();
    let mut images: Vec<RgbImageF> = Vec::new();
    let mut converged: HashMap<String, (usize, RgbImageF)> = HashMap::new();
    // variants' GPU images by scene, variant and grid point: references of other
    // variants, filled by the rows themselves or rendered on demand
    let mut gpu_images: HashMap<String, RgbImageF> = HashMap::new();
    // variants' CPU twin images by scene, variant and grid point (Twin, TwinOf)
    let mut twin_images: HashMap<String, RgbImageF> = HashMap::new();
    let image_key =
        |scene: &str, variant: &str, values: &[f64]| format!("{scene}|{variant}|{values:?}");
    for scene in &e.scenes {
        let sc = load_scene(scene, dir, e).with_context(|| format!("{fname}"))?;
        // every variant's document and axes, checked before anything renders
        let mut docs = Vec::new();
        for v in variants {
            let d = v.apply(&sc.doc, &sc.volume).map_err(|err| {
                anyhow!(
                    "{fname}: variant '{}' on scene '{}': {err}",
                    v.name,
                    sc.name
                )
            })?;
            let axes: Vec<Axis> = e
                .grid
                .iter()
                .zip(&grid_values)
                .map(|(a, vals)| measure::axis_for(&a.param, vals.clone(), &d))
                .collect::<Result<_>>()
                .map_err(|err| {
                    anyhow!(
                        "{fname}: variant '{}' on scene '{}': {err}",
                        v.name,
                        sc.name
                    )
                })?;
            let volume = match &v.crop {
                Some(c) => Arc::new(sc.volume.cropped(c.keep()).map_err(|err| {
                    anyhow!(
                        "{fname}: variant '{}' on scene '{}': crop: {err}",
                        v.name,
                        sc.name
                    )
                })?),
                None => sc.volume.clone(),
            };
            headless::preflight(None, &d, &volume)
                .map_err(|err| anyhow!("{fname}: scene '{}': {err}", sc.name))?;
            docs.push((v, d, axes, volume));
        }
        for st in e.statistics.iter().filter(|st| !runner_statistic(st)) {
            check_statistic(st, docs.iter().map(|(_, d, _, _)| d))
                .map_err(|err| anyhow!("{fname}: scene '{}': statistic '{st}': {err}", sc.name))?;
        }
        let points = measure::grid(&docs[0].2);
        let at = |d: &Document, axes: &[Axis], values: &[f64]| {
            let mut d = d.clone();
            for (axis, v) in axes.iter().zip(values) {
                measure::apply_axis(&mut d, axis, *v);
            }
            d
        };
        let find = |name: &str| {
            docs.iter()
                .find(|(v, _, _, _)| v.name == name)
                .expect("checked at load")
        };
        // the key of a scene's volume as a variant crops it
        let scene_key = |v: &Variant| match &v.crop {
            Some(c) => format!("{} cropped to {:?}", sc.name, c.keep()),
            None => sc.name.clone(),
        };
        let first_row = rows.len();
        for (v, vdoc, axes, volume) in &docs {
            let mut r = headless::renderer_for(gpu, vdoc, volume.clone())
                .with_context(|| format!("{fname}: variant '{}' on scene '{}'", v.name, sc.name))?;
            for values in &points {
                let mut d = at(vdoc, axes, values);
                // a searched variant renders the best TF its search finds here
                let mut search = match &v.search {
                    Some(spec) => {
                        let target = spec.target.as_deref().map(|t| {
                            let (_, od, oa, ovol) = find(t);
                            (at(od, oa, values), ovol.clone())
                        });
                        let found = search_tf(
                            gpu,
                            spec,
                            &mut r,
                            &mut d,
                            volume,
                            target,
                            &mut |generation, best| {
                                observer(Event::Generation {
                                    scene: &sc.name,
                                    variant: &v.name,
                                    generation,
                                    best,
                                })
                            },
                        )
                        .map_err(|err| {
                            anyhow!(
                                "{fname}: variant '{}' on scene '{}': search: {err}",
                                v.name,
                                sc.name
                            )
                        })?;
                        Some(found)
                    }
                    None => None,
                };
                // a gallery variant draws its gallery here (the frame below renders
                // the stack as it is)
                let gallery = match &v.gallery {
                    Some(spec) => Some(gallery_of(spec, &mut r, &d, out, rows.len()).map_err(
                        |err| {
                            anyhow!(
                                "{fname}: variant '{}' on scene '{}': {err}",
                                v.name,
                                sc.name
                            )
                        },
                    )?),
                    None => None,
                };
                // a suggested variant's TF comes from the data
                let suggested = match &v.suggest {
                    Some(spec) => {
                        Some(suggest_tf(spec, &mut r, &mut d, volume).map_err(|err| {
                            anyhow!(
                                "{fname}: variant '{}' on scene '{}': {err}",
                                v.name,
                                sc.name
                            )
                        })?)
                    }
                    None => None,
                };
                let s = d.frame_settings();
                let applying = std::time::Instant::now();
                r.update_stack(&d.stack, d.render.target)?;
                let apply_ms = applying.elapsed().as_secs_f64() * 1e3;
                // the untimed first frame runs what the change invalidated
                let first = r.render(&s)?;
                let timing = measure::time_frames(&mut r, &s, 0, e.frames)?;
                // the update again, where the change reran passes
                let (mut walls, mut stamps) = (vec![first.wall_ms], vec![update_stamps(&first)]);
                // every update's GPU stamps by pass, for `pass_ms.*`
                let mut pass_stamps = vec![first.gpu_passes.clone()];
                if !(first.prepasses.is_empty() && first.volume_passes_run.is_empty()) {
                    for _ in 1..e.update_repeats {
                        r.rerun_passes();
                        let again = r.render(&s)?;
                        walls.push(again.wall_ms);
                        stamps.push(update_stamps(&again));
                        pass_stamps.push(again.gpu_passes);
                    }
                }
                let median = |v: &[f64]| measure::Summary::of(v).map_or(f64::NAN, |m| m.median);
                let update_ms = (median(&walls) - timing.wall_ms.median).max(0.0);
                // only stamps that can be the update's, as frames are judged
                let stamped: Vec<f64> = stamps.into_iter().flatten().collect();
                let cpu = r.gpu().info.device_type == wgpu::DeviceType::Cpu;
                let update_gpu_ms = Some(median(&stamped))
                    .filter(|&g| measure::stamps_plausible(cpu, g, update_ms))
                    .unwrap_or(f64::NAN);
                let (img, coverage) = measure::gpu_image_covered(&r, &d)?;
                let memory: u64 = r.plugin_memory().iter().map(|(_, _, b)| b).sum();
                let mut statistics = statistics_of(&e.statistics, &r, &d);
                if let Some(found) = &search {
                    for st in e.statistics.iter().filter(|st| st.starts_with("search.")) {
                        statistics.insert(st.clone(), found.statistic(st));
                    }
                }
                if let Some(g) = &gallery {
                    for st in e.statistics.iter().filter(|st| st.starts_with("gallery.")) {
                        statistics.insert(st.clone(), g.statistic(st));
                    }
                }
                for st in e.statistics.iter().filter(|st| st.starts_with(PASS_MS)) {
                    statistics.insert(st.clone(), pass_ms(st, &pass_stamps));
                }
                if let Some(figures) = &suggested {
                    for st in e.statistics.iter().filter(|st| st.starts_with("suggest.")) {
                        statistics.insert(st.clone(), figures[st]);
                    }
                }
                let spec = v.reference.as_ref().unwrap_or(&e.reference);
                let reference = match spec {
                    ReferenceSpec::Converged | ReferenceSpec::ConvergedOf(_) => {
                        let (rd, rv, rvol) = match spec {
                            ReferenceSpec::ConvergedOf(n) => {
                                let (ov, od, oa, ovol) = find(n);
                                (at(od, oa, values), *ov, ovol)
                            }
                            _ => (d.clone(), *v, volume),
                        };
                        let supplier = measure::configured_supplier(&rd, &e.reference_options)
                            .map_err(|err| anyhow!("{fname}: reference_options: {err}"))?;
                        let key = reference_key(&scene_key(rv), &rd, supplier.as_deref());
                        if let Some((i, _)) = converged.get(&key) {
                            Some(*i)
                        } else {
                            let whose = match spec {
                                ReferenceSpec::ConvergedOf(n) => n.as_str(),
                                _ => v.name.as_str(),
                            };
                            let at: Vec<String> = e
                                .grid
                                .iter()
                                .zip(values)
                                // the spacing does not change a converged reference
                                .filter(|(a, _)| a.param != "render.slice_spacing")
                                .map(|(a, x)| format!("{} = {x}", a.param))
                                .collect();
                            let what = if at.is_empty() {
                                format!("converged reference of '{whose}'")
                            } else {
                                format!("converged reference of '{whose}' at {}", at.join(", "))
                            };
                            observer(Event::Reference {
                                scene: &sc.name,
                                what: &what,
                            });
                            let (img, mut info) = measure::converged_image_by(
                                rvol,
                                &rd,
                                supplier,
                                &rd.frame_settings(),
                                e.tolerance,
                                &ReferenceOptions::default(),
                            )?;
                            info["scene"] = json!(sc.name);
                            info["what"] = json!(what);
                            let i = references.len();
                            info["image"] = json!(format!("images/reference_{i:02}.png"));
                            headless::save_png(
                                &img.to_rgb8(),
                                &out.join(format!("images/reference_{i:02}.png")),
                            )?;
                            references.push(info);
                            converged.insert(key, (i, img));
                            Some(i)
                        }
                    }
                    ReferenceSpec::SingleScattering(spec) => {
                        let key = format!("{}|single_scattering|{values:?}", scene_key(v));
                        if let Some((i, _)) = converged.get(&key) {
                            Some(*i)
                        } else {
                            observer(Event::Reference {
                                scene: &sc.name,
                                what: "single-scattering ground truth",
                            });
                            let start = std::time::Instant::now();
                            let opts = vwb_render::reference::ScatteringOptions {
                                light: spec.light.map(|(x, y, z)| glam::DVec3::new(x, y, z)),
                                samples: spec.samples,
                                seed: e.seed.unwrap_or(1),
                                extinction: spec
                                    .extinction
                                    .map_or(glam::DVec3::ONE, |(r, g, b)| {
                                        glam::DVec3::new(r, g, b)
                                    }),
                                ..Default::default()
                            };
                            let g = vwb_render::reference::render_single_scattering(
                                volume, &d.stack, &s, &opts,
                            )?;
                            let over = |px: &[[f64; 4]]| {
                                metrics::RgbImageF::from_rgba_premultiplied_over(
                                    px,
                                    g.image.width,
                                    g.image.height,
                                    measure::background(&d),
                                )
                            };
                            let img = over(&g.image.pixels);
                            // the noise floor: an independent run with the next seed
                            let second = vwb_render::reference::render_single_scattering(
                                volume,
                                &d.stack,
                                &s,
                                &vwb_render::reference::ScatteringOptions {
                                    seed: opts.seed.wrapping_add(1),
                                    ..opts.clone()
                                },
                            )?;
                            let floor =
                                metrics::compare(&img, &over(&second.image.pixels)).rms_delta_e;
                            let i = references.len();
                            references.push(json!({
                                "scene": sc.name, "kind": "single_scattering",
                                "what": format!(
                                    "single-scattering ground truth ({} paths per pixel, light ({:.3}, {:.3}, {:.3}){}, 95 % CI ±{:.4} mean, ±{:.4} max per channel; two seeds differ by RMS ΔE*uv {floor:.2}, so an image equal to the true mean scores about {:.2} against it)",
                                    spec.samples, g.light.x, g.light.y, g.light.z,
                                    spec.extinction.map_or(String::new(), |(r, g, b)| format!(", chromatic extinction κ ({r}, {g}, {b}) on the shadow rays")),
                                    g.ci95_mean, g.ci95_max, floor / std::f64::consts::SQRT_2
                                ),
                                "seed_to_seed_rms_delta_e": floor,
                                "light": [g.light.x, g.light.y, g.light.z],
                                "samples": spec.samples,
                                "extinction": spec.extinction.map(|(r, g, b)| [r, g, b]),
                                "ci95_mean": g.ci95_mean,
                                "ci95_max": g.ci95_max,
                                "seconds": start.elapsed().as_secs_f64(),
                                "image": format!("images/reference_{i:02}.png"),
                            }));
                            headless::save_png(
                                &img.to_rgb8(),
                                &out.join(format!("images/reference_{i:02}.png")),
                            )?;
                            converged.insert(key, (i, img));
                            Some(i)
                        }
                    }
                    ReferenceSpec::Twin | ReferenceSpec::TwinOf(_) => {
                        let i = references.len();
                        let whose = match spec {
                            ReferenceSpec::TwinOf(n) => n,
                            _ => &v.name,
                        };
                        // a variant's twin image at a grid point is made once (several
                        // clipped variants compare with one cropped variant's)
                        let key = image_key(&sc.name, whose, values);
                        if !twin_images.contains_key(&key) {
                            let (_, od, oa, ovol) = find(whose);
                            let o = at(od, oa, values);
                            let img = measure::twin_image(ovol, &o, &o.frame_settings())?;
                            twin_images.insert(key.clone(), img);
                        }
                        let img = twin_images[&key].clone();
                        references.push(json!({
                            "scene": sc.name, "kind": "twin", "variant": whose, "values": values,
                            "image": format!("images/reference_{i:02}.png"),
                        }));
                        headless::save_png(
                            &img.to_rgb8(),
                            &out.join(format!("images/reference_{i:02}.png")),
                        )?;
                        images.push(img);
                        Some(i)
                    }
                    ReferenceSpec::Variant(n) => {
                        let key = image_key(&sc.name, n, values);
                        if !gpu_images.contains_key(&key) {
                            let (_, od, oa, ovol) = find(n);
                            let o = at(od, oa, values);
                            let mut r2 = headless::renderer_for(gpu, &o, ovol.clone())?;
                            r2.render(&o.frame_settings())?;
                            gpu_images.insert(key.clone(), measure::gpu_image(&r2, &o)?);
                        }
                        let i = references.len();
                        references.push(json!({
                            "scene": sc.name, "kind": "variant", "variant": n, "values": values,
                        }));
                        images.push(gpu_images[&key].clone());
                        Some(i)
                    }
                    ReferenceSpec::TimeOnly => None,
                };
                let theirs = match (spec, reference) {
                    (_, None) => None,
                    (
                        ReferenceSpec::Converged
                        | ReferenceSpec::ConvergedOf(_)
                        | ReferenceSpec::SingleScattering(_),
                        Some(i),
                    ) => Some(
                        converged
                            .values()
                            .find(|(j, _)| *j == i)
                            .map(|(_, img)| img)
                            .expect("just stored"),
                    ),
                    _ => Some(images.last().expect("just pushed")),
                };
                let m = match theirs {
                    Some(theirs) => {
                        metrics::try_compare(&img, theirs).map_err(|err| anyhow!(err))?
                    }
                    None => no_metrics(img.width, img.height),
                };
                let (ms, clock) = timing.frame_ms();
                let image = format!("images/row_{:03}.png", rows.len());
                headless::save_png(&img.to_rgb8(), &out.join(&image))?;
                // a search's find, as a preset that opens the row's scene with it
                if let Some(found) = &mut search {
                    let preset = format!("presets/row_{:03}.ron", rows.len());
                    std::fs::create_dir_all(out.join("presets"))
                        .with_context(|| format!("{}: cannot create", out.display()))?;
                    d.save(&out.join(&preset))
                        .map_err(|err| anyhow!("{fname}: {err}"))?;
                    found.preset = preset;
                }
                // a later variant compared with this one reuses the image
                gpu_images
                    .entry(image_key(&sc.name, &v.name, values))
                    .or_insert(img);
                rows.push(Row {
                    scene: sc.name.clone(),
                    variant: v.name.clone(),
                    values: values.clone(),
                    slices: timing.slices,
                    frame_ms: ms,
                    clock,
                    update_ms,
                    update_gpu_ms,
                    apply_ms,
                    update_passes: first
                        .prepasses
                        .into_iter()
                        .chain(first.volume_passes_run)
                        .collect(),
                    gpu_memory_bytes: memory,
                    empty_brick_share: r.empty_brick_share().unwrap_or(f64::NAN),
                    coverage,
                    metrics: m,
                    statistics,
                    image,
                    reference,
                    pareto: false,
                    search,
                    gallery,
                });
                observer(Event::Row {
                    index: rows.len() - 1,
                    row: rows.last().expect("just pushed"),
                });
            }
        }
        // the front of the scene's rows with an error (rows timed only have none)
        mark_front(&mut rows[first_row..], |r| {
            (e.pareto_time.of(r), r.metrics.rms_delta_e)
        });
    }
    finish(e, file, Some(gpu), out, rows, references)
}

/// Marks the rows on the Pareto front of `time_error` (lower is better in both); rows
/// whose time or error is not finite stay off it.
fn mark_front(rows: &mut [Row], time_error: impl Fn(&Row) -> (f64, f64)) {
    let measured: Vec<usize> = (0..rows.len())
        .filter(|&i| {
            let (t, err) = time_error(&rows[i]);
            t.is_finite() && err.is_finite()
        })
        .collect();
    let front = measure::pareto_front(
        &measured
            .iter()
            .map(|&i| time_error(&rows[i]))
            .collect::<Vec<_>>(),
    );
    for (&i, f) in measured.iter().zip(front) {
        rows[i].pareto = f;
    }
}

/// Checks the assertions on the rows, writes the report and returns the outcome (`gpu`:
/// None for a probe's run).
fn finish(
    e: &Experiment,
    file: &Path,
    gpu: Option<&GpuContext>,
    out: &Path,
    rows: Vec<Row>,
    references: Vec<serde_json::Value>,
) -> Result<Outcome> {
    let assertions: Vec<Checked> = e
        .assertions
        .iter()
        .map(|a| {
            Assertion::parse_in(a, &e.statistics)
                .expect("checked at load")
                .check(a, &rows)
        })
        .collect();
    let mut outcome = Outcome {
        name: e.name.clone(),
        rows,
        references,
        assertions,
        markdown: String::new(),
    };
    outcome.markdown = markdown(e, file, gpu, &outcome);
    write_outputs(e, file, gpu, out, &outcome)?;
    Ok(outcome)
}

/// The experiment's description for a report line.
fn described(e: &Experiment) -> &str {
    if e.description.is_empty() {
        "no description"
    } else {
        &e.description
    }
}

/// A number for a report line: whole numbers as they are, others to four significant
/// digits.
fn short(x: f64) -> String {
    if x.fract() == 0.0 || !x.is_finite() {
        format!("{x}")
    } else if x.abs() >= 0.01 {
        format!("{}", (x * 1e4).round() / 1e4)
    } else {
        format!("{x:.3e}")
    }
}

/// The report's Markdown (the part a doc block receives).
/// A probe's (`e.probe`) has no GPU and no image: `gpu` is None.
fn markdown(e: &Experiment, file: &Path, gpu: Option<&GpuContext>, o: &Outcome) -> String {
    let mut s = String::new();
    if let Some(spec) = &e.probe {
        s += &probe::header(e, file, spec);
    } else {
        let _ = writeln!(
            s,
            "Experiment `{}` ({}), run by `vwb run {}`. Machine: {}; adapter: {}; vwb {}; seed {}; {} timed frames per image ({} clock, median).",
            e.name,
            described(e),
            file.display(),
            measure::machine(),
            gpu.map_or_else(|| "none".to_string(), |g| g.describe()),
            measure::build(),
            e.seed
                .map_or_else(|| "as the presets set it".to_string(), |s| s.to_string()),
            e.frames,
            o.rows.first().map_or("gpu", |r| r.clock),
        );
    }
    if e.metrics.contains(&Metric::UpdateMs) || e.pareto_time == Metric::UpdateMs {
        let _ = writeln!(
            s,
            "Update: the wall time of the first frame after a grid point's stack is applied, less the median timed frame's wall time — what the change re-ran (volume passes, pre-passes, tables){}{}.",
            if e.update_repeats > 1 {
                format!(
                    "; the median of {} updates where the change reran passes (the first, then every pass rerun)",
                    e.update_repeats
                )
            } else {
                String::new()
            },
            if e.pareto_time == Metric::UpdateMs {
                "; the Pareto front is update time against error"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(s);
    for r in &o.references {
        let what = r["what"]
            .as_str()
            .unwrap_or(r["kind"].as_str().unwrap_or("reference"));
        if r["kind"] == json!("converged") || r["kind"] == json!("gpu-converged") {
            let on = if r["kind"] == json!("converged") {
                "on the CPU"
            } else {
                "on the GPU (no CPU twin)"
            };
            let _ = writeln!(
                s,
                "- Reference for `{}`: {what} at {} voxels, last halving changed RMS ΔE*uv by {:.3} (converged: {}), {:.1} s {on}.",
                r["scene"].as_str().unwrap_or(""),
                r["spacing_voxels"],
                r["last_change_rms_delta_e"].as_f64().unwrap_or(f64::NAN),
                r["converged"],
                r["seconds"].as_f64().unwrap_or(f64::NAN),
            );
        } else if r["kind"] != json!("twin") && r["kind"] != json!("variant") {
            // a supplied reference's own notes (sample counts, steps, statistical error)
            let notes: Vec<String> = r
                .as_object()
                .into_iter()
                .flatten()
                .filter(|(k, v)| {
                    v.is_number()
                        && ![
                            "seconds",
                            "seed_to_seed_rms_delta_e",
                            "ci95_mean",
                            "ci95_max",
                            "samples",
                        ]
                        .contains(&k.as_str())
                })
                .map(|(k, v)| format!("{k} {}", v.as_f64().map_or_else(|| v.to_string(), short)))
                .collect();
            let _ = writeln!(
                s,
                "- Reference for `{}`: {what} ({}{}), {:.1} s on the CPU.",
                r["scene"].as_str().unwrap_or(""),
                r["kind"].as_str().unwrap_or(""),
                if notes.is_empty() {
                    String::new()
                } else {
                    format!(": {}", notes.join(", "))
                },
                r["seconds"].as_f64().unwrap_or(f64::NAN),
            );
        }
    }
    let describe = |spec: &ReferenceSpec| match spec {
        ReferenceSpec::Twin => Some("the CPU twin with the same slices".to_string()),
        ReferenceSpec::Variant(n) => {
            Some(format!("variant `{n}`'s GPU image at the same grid point"))
        }
        ReferenceSpec::ConvergedOf(n) => Some(format!("the converged reference of variant `{n}`")),
        ReferenceSpec::TwinOf(n) => Some(format!(
            "variant `{n}`'s CPU twin (f64) image at the same grid point"
        )),
        ReferenceSpec::TimeOnly => Some("none (timed only)".to_string()),
        _ => None,
    };
    if let Some(d) = describe(&e.reference) {
        let _ = writeln!(s, "- Reference: {d}.");
    }
    for v in &e.variants {
        if let Some(c) = &v.crop {
            let _ = writeln!(
                s,
                "- Variant `{}` renders its scene's volume physically cropped to the voxels \
                 {:?}..{:?} (the others removed, the value range kept).",
                v.name, c.from, c.to
            );
        }
        if v.reference == Some(ReferenceSpec::TimeOnly) {
            let _ = writeln!(s, "- Variant `{}` is timed only (no reference).", v.name);
        } else if let Some(spec) = &v.reference {
            let d = describe(spec).unwrap_or_else(|| match spec {
                ReferenceSpec::SingleScattering(_) => "the single-scattering ground truth".into(),
                _ => "the converged reference of its own stack".into(),
            });
            let _ = writeln!(s, "- Variant `{}` is compared with {d}.", v.name);
        }
    }
    let _ = writeln!(s);
    // a probe's rows have no scene
    let scenes = e.probe.is_none();
    let mut header = vec!["scene".to_string(), "variant".to_string()];
    if !scenes {
        header.remove(0);
    }
    let named = header.len();
    header.extend(e.grid.iter().map(|a| a.param.clone()));
    header.extend(e.metrics.iter().map(|m| m.header().to_string()));
    header.extend(statistic_headers(&e.statistics));
    // the front is time against error: without the time in the table it says nothing
    let timed = match &e.probe {
        Some(p) => p.pareto.is_some(),
        None => e.metrics.contains(&e.pareto_time),
    };
    if timed {
        header.push("Pareto".into());
    }
    let _ = writeln!(s, "| {} |", header.join(" | "));
    let align: Vec<&str> = header
        .iter()
        .enumerate()
        .map(|(i, _)| if i < named { "---" } else { "---:" })
        .collect();
    let _ = writeln!(s, "|{}|", align.join("|"));
    for r in &o.rows {
        let mut cells = vec![r.scene.clone(), r.variant.clone()];
        if !scenes {
            cells.remove(0);
        }
        cells.extend(r.values.iter().map(|v| format!("{v}")));
        cells.extend(e.metrics.iter().map(|m| m.cell(r)));
        cells.extend(
            e.statistics
                .iter()
                .map(|st| statistic_cell(r.statistics.get(st).copied())),
        );
        if timed {
            cells.push(if r.pareto {
                "●".into()
            } else {
                String::new()
            });
        }
        let _ = writeln!(s, "| {} |", cells.join(" | "));
    }
    if !o.assertions.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(s, "Assertions:");
        let _ = writeln!(s);
        for a in &o.assertions {
            let _ = writeln!(
                s,
                "- {} `{}`: {}",
                if a.passed { "pass" } else { "**FAIL**" },
                a.assertion,
                a.detail
            );
        }
    }
    s
}

/// The report's files; `gpu` is None for a probe's run.
fn write_outputs(
    e: &Experiment,
    file: &Path,
    gpu: Option<&GpuContext>,
    out: &Path,
    o: &Outcome,
) -> Result<()> {
    // Pareto plot per scene (a probe's: of its time and error figures, where it names them)
    let pareto_figures = e.probe.as_ref().and_then(|p| p.pareto.as_ref());
    let mut scenes: Vec<&str> = o.rows.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    if e.probe.is_some() && pareto_figures.is_none() {
        scenes.clear();
    }
    let mut plots = String::new();
    for scene in &scenes {
        let rows: Vec<&Row> = o.rows.iter().filter(|r| &r.scene == scene).collect();
        let mut axes = vec![Axis {
            name: "variant".into(),
            target: measure::AxisTarget::Spacing,
            values: Vec::new(),
        }];
        axes.extend(e.grid.iter().map(|a| Axis {
            name: a.param.clone(),
            target: measure::AxisTarget::Spacing,
            values: Vec::new(),
        }));
        let variant_index =
            |name: &str| e.variants.iter().position(|v| v.name == name).unwrap_or(0) as f64;
        let points: Vec<SweepPoint> = rows
            .iter()
            .map(|r| {
                let mut values = vec![variant_index(&r.variant)];
                values.extend(&r.values);
                if let Some((time, error)) = pareto_figures {
                    let figure = |f: &String| r.statistics.get(f).copied().unwrap_or(f64::NAN);
                    let mut metrics = no_metrics(0, 0);
                    metrics.rms_delta_e = figure(error);
                    return SweepPoint {
                        values,
                        slices: 0,
                        ms: figure(time),
                        clock: r.clock,
                        wall_ms: figure(time),
                        metrics,
                        image: String::new(),
                        pareto: r.pareto,
                    };
                }
                SweepPoint {
                    values,
                    slices: r.slices,
                    ms: e.pareto_time.of(r),
                    clock: if e.pareto_time == Metric::UpdateMs {
                        "update"
                    } else {
                        r.clock
                    },
                    wall_ms: e.pareto_time.of(r),
                    metrics: r.metrics,
                    image: r.image.clone(),
                    pareto: r.pareto,
                }
            })
            .collect();
        let title = format!("{} — {scene}", e.name);
        let svg = measure::pareto_svg_labelled(
            &title,
            pareto_figures.map(|(t, e)| (t.as_str(), e.as_str())),
            &axes,
            &points,
        );
        let name = format!("pareto_{}.svg", file_safe(scene));
        measure::save_text(&out.join(&name), &svg)?;
        let _ = writeln!(plots, "![Pareto front, {scene}]({name})");
    }
    let legend: Vec<String> = e
        .variants
        .iter()
        .enumerate()
        .map(|(i, v)| format!("variant={i} is `{}`", v.name))
        .collect();
    let report = format!(
        "# Experiment: {}\n\n{}\n{}\n{}\n",
        e.name,
        o.markdown,
        if legend.is_empty() {
            String::new()
        } else {
            format!("Plot labels: {}.\n", legend.join(", "))
        },
        plots
    );
    measure::save_text(&out.join("report.md"), &report)?;
    // CSV
    let mut csv = String::from("scene,variant");
    for a in &e.grid {
        let _ = write!(csv, ",{}", a.param);
    }
    // a probe's rows have no image metrics
    let metric_columns: &[Metric] = if e.probe.is_some() { &[] } else { &Metric::ALL };
    for m in metric_columns {
        let _ = write!(csv, ",{}", m.name());
    }
    for st in &e.statistics {
        let _ = write!(csv, ",{}", csv_field(st));
    }
    csv.push_str(",clock,pareto,image\n");
    for r in &o.rows {
        let _ = write!(csv, "{},{}", csv_field(&r.scene), csv_field(&r.variant));
        for v in &r.values {
            let _ = write!(csv, ",{v}");
        }
        for m in metric_columns {
            let _ = write!(csv, ",{}", m.of(r));
        }
        for st in &e.statistics {
            let _ = write!(
                csv,
                ",{}",
                r.statistics.get(st).copied().unwrap_or(f64::NAN)
            );
        }
        let _ = writeln!(csv, ",{},{},{}", r.clock, r.pareto, r.image);
    }
    measure::save_text(&out.join("results.csv"), &csv)?;
    measure::save_json(
        &out.join("results.json"),
        &json!({
            "experiment": e.name,
            "file": file,
            "machine": measure::machine(),
            "adapter": gpu.map(|g| g.describe()),
            "probe": e.probe.as_ref().map(|p| &p.id),
            "version": env!("CARGO_PKG_VERSION"),
            "commit": measure::build_commit(),
            "seed": e.seed,
            "frames": e.frames,
            "references": o.references,
            "rows": o.rows,
            "assertions": o.assertions,
        }),
    )?;
    measure::save_text(&out.join("junit.xml"), &junit(e, o))?;
    if let Some(block) = &e.doc_block {
        let dir = file.parent().unwrap_or(Path::new("."));
        let doc = dir.join(&block.file);
        if gpu.is_none_or(|g| g.info.device_type == wgpu::DeviceType::Cpu) {
            let mut body = o.markdown.clone();
            if o.rows
                .iter()
                .enumerate()
                .any(|(i, _)| block.images.shows(i))
            {
                body += &doc_images(e, out, &doc, o, &block.images)?;
            }
            write_block(&doc, &block.block, &body)?;
        } else {
            // a GPU's figures go beside the CPU device's, in docs/gpu/ (the doc's
            // folder's `gpu/`), as the benchmarks write theirs
            let gpu_doc = gpu_doc_path(&doc);
            let title = format!(
                "# {0} on a GPU\n\nThe blocks of experiment files run on a GPU adapter; the \
                 CPU device's are in ../{0}.\n",
                gpu_doc.file_name().unwrap_or_default().to_string_lossy()
            );
            let heading = format!("## Experiment `{}` ({})", e.name, e.description);
            write_or_add_block(&gpu_doc, &title, &block.block, &heading, &o.markdown)?;
        }
    }
    Ok(())
}

/// The rows' images copied beside `doc` (`images/<experiment>_<row>.png`, atomically)
/// and the Markdown that shows them, each captioned with its row.
fn doc_images(
    e: &Experiment,
    out: &Path,
    doc: &Path,
    o: &Outcome,
    which: &DocImages,
) -> Result<String> {
    let dir = doc.parent().unwrap_or(Path::new(".")).join("images");
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let mut s = String::from("\n");
    for (i, r) in o
        .rows
        .iter()
        .enumerate()
        .filter(|(i, r)| !r.image.is_empty() && which.shows(*i))
    {
        let name = format!("{}_{i:03}.png", file_safe(&e.name));
        // a gallery variant's figure is its sheet
        let from = out.join(r.gallery.as_ref().map_or(&r.image, |g| &g.sheet));
        let bytes =
            std::fs::read(&from).with_context(|| format!("{}: cannot read", from.display()))?;
        let to = dir.join(&name);
        vwb_render::files::write_atomic(&to, &bytes)
            .with_context(|| format!("{}: cannot write", to.display()))?;
        let _ = writeln!(s, "![{}](images/{name})", r.label());
    }
    Ok(s)
}

fn file_safe(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The statistics' column headers: their names without the plugin id where no two
/// share a name, else in full.
fn statistic_headers(statistics: &[String]) -> Vec<String> {
    let short = |st: &String| {
        st.rsplit_once('.')
            .map_or(st.clone(), |(_, n)| n.to_string())
    };
    let names: Vec<String> = statistics.iter().map(short).collect();
    let unique = names.iter().collect::<std::collections::HashSet<_>>().len() == names.len();
    let chosen = if unique { names } else { statistics.to_vec() };
    chosen.into_iter().map(|n| format!("`{n}`")).collect()
}

/// A statistic's table cell: — where absent or NaN, whole numbers as such, else three
/// significant digits.
fn statistic_cell(v: Option<f64>) -> String {
    match v {
        Some(v) if v.is_finite() && v == v.round() && v.abs() < 1e15 => format!("{v}"),
        // small figures (a probe's errors) in scientific notation, three digits
        Some(v) if v.is_finite() && v.abs() < 1e-3 => format!("{v:.2e}"),
        Some(v) if v.is_finite() => {
            let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
            format!("{v:.digits$}")
        }
        _ => "—".into(),
    }
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// JUnit XML: one test case per assertion (one passing case "ran" when there are none).
fn junit(e: &Experiment, o: &Outcome) -> String {
    let failures = o.failed().len();
    let mut s = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        s,
        "<testsuite name=\"{}\" tests=\"{}\" failures=\"{failures}\">",
        xml_escape(&e.name),
        o.assertions.len().max(1)
    );
    if o.assertions.is_empty() {
        let _ = writeln!(
            s,
            "  <testcase classname=\"{}\" name=\"ran ({} rows)\"/>",
            xml_escape(&e.name),
            o.rows.len()
        );
    }
    for a in &o.assertions {
        let _ = write!(
            s,
            "  <testcase classname=\"{}\" name=\"{}\"",
            xml_escape(&e.name),
            xml_escape(&a.assertion)
        );
        if a.passed {
            let _ = writeln!(
                s,
                "><system-out>{}</system-out></testcase>",
                xml_escape(&a.detail)
            );
        } else {
            let _ = writeln!(
                s,
                "><failure message=\"{}\"/></testcase>",
                xml_escape(&a.detail)
            );
        }
    }
    s.push_str("</testsuite>\n");
    s
}

/// Replaces the text between `<!-- BEGIN name -->` and `<!-- END name -->` in `path`
/// (atomically); an error names the file when either marker is missing.
pub fn write_block(path: &Path, name: &str, body: &str) -> Result<()> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the doc to update", path.display()))?;
    let (begin, end) = (
        format!("<!-- BEGIN {name} -->"),
        format!("<!-- END {name} -->"),
    );
    let i = text
        .find(&begin)
        .ok_or_else(|| anyhow!("{}: no '{begin}' marker", path.display()))?;
    let j = text[i..]
        .find(&end)
        .map(|j| i + j)
        .ok_or_else(|| anyhow!("{}: no '{end}' marker after '{begin}'", path.display()))?;
    let new = format!("{}{begin}\n{}{}", &text[..i], body, &text[j..]);
    measure::save_text(path, &new)
}

/// Where a GPU adapter's copy of `doc` lives: `gpu/` beside it (docs/gpu/perf.md for
/// docs/perf.md).
pub fn gpu_doc_path(doc: &Path) -> PathBuf {
    let name = doc.file_name().unwrap_or_default();
    doc.parent()
        .unwrap_or(Path::new("."))
        .join("gpu")
        .join(name)
}

/// Writes `body` into the block `name` of `doc`, first adding the block under
/// `heading` at the end where the document has none, or creating the document from
/// `new_doc` (its folder too): a GPU's copy of a doc written before the block existed.
pub fn write_or_add_block(
    doc: &Path,
    new_doc: &str,
    name: &str,
    heading: &str,
    body: &str,
) -> Result<()> {
    let mut text = std::fs::read_to_string(doc).unwrap_or_else(|_| new_doc.to_string());
    if !text.contains(&format!("<!-- BEGIN {name} -->")) {
        text += &format!("\n{heading}\n\n<!-- BEGIN {name} -->\n<!-- END {name} -->\n");
        if let Some(dir) = doc.parent() {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
        }
        measure::save_text(doc, &text)?;
    }
    write_block(doc, name, body)
}

/// Loads and runs an experiment file, printing progress to stderr; the report goes to
/// `out` (default `reports/<name>`). Fails when an assertion fails, after writing the
/// report and the JUnit file.
pub fn run_file(file: &Path, out: Option<&Path>) -> Result<Outcome> {
    let e = load(file)?;
    let out: PathBuf = out.map_or_else(
        || Path::new("reports").join(file_safe(&e.name)),
        Path::to_path_buf,
    );
    crate::outputs::check_output(&out.join("report.md"))?;
    // the update's time where the row's change reran volume passes
    let update = |row: &Row| {
        if row.update_passes.is_empty() {
            String::new()
        } else {
            format!("  update {:.2} ms", row.update_ms)
        }
    };
    let mut print = |ev: Event<'_>| match ev {
        Event::Reference { scene, what } => eprintln!("{scene}: computing the {what}"),
        Event::Generation {
            scene,
            variant,
            generation,
            best,
        } => eprintln!("{scene} · {variant}: search generation {generation}, best {best:.3}"),
        Event::Row { index, row } if row.clock == probe::CLOCK => eprintln!(
            "[{index:>3}] {}: {}",
            row.label(),
            row.statistics
                .iter()
                .map(|(k, v)| format!("{k} {}", short(*v)))
                .collect::<Vec<_>>()
                .join("  ")
        ),
        Event::Row { index, row } if row.reference.is_none() => eprintln!(
            "[{index:>3}] {}: {:>4} slices {:>8.2} ms{}  (timed only)",
            row.label(),
            row.slices,
            row.frame_ms,
            update(row),
        ),
        Event::Row { index, row } => eprintln!(
            "[{index:>3}] {}: {:>4} slices {:>8.2} ms{}  RMS ΔE*uv {:.3}  >6 {:.2}%",
            row.label(),
            row.slices,
            row.frame_ms,
            update(row),
            row.metrics.rms_delta_e,
            100.0 * row.metrics.share_above_6
        ),
    };
    let o = if e.probe.is_some() {
        // the CPU twin alone: no adapter
        probe::run(&e, file, &out, &mut print)?
    } else {
        let gpu = GpuContext::new_headless()?;
        eprintln!("adapter: {}", gpu.describe());
        run(&gpu, &e, file, &out, &mut print)?
    };
    eprintln!("report: {}", out.join("report.md").display());
    let failed = o.failed();
    if !failed.is_empty() {
        let lines: Vec<String> = failed
            .iter()
            .map(|a| format!("  {}: {}", a.assertion, a.detail))
            .collect();
        bail!(
            "{}: {} of {} assertions failed:\n{}",
            file.display(),
            failed.len(),
            o.assertions.len(),
            lines.join("\n")
        );
    }
    Ok(o)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `pass_ms.T1+T2`: the median over the updates of the stamps of the passes with
    /// those targets (and pre-passes by plugin); NaN where none was stamped.
    #[test]
    fn pass_times_sum_their_targets_over_the_median_update() {
        let update = |a: f64, g: f64| {
            vec![
                ("pass shade.hernell/alpha_lp".to_string(), a),
                ("pass shade.hernell/alpha_g".to_string(), g),
                ("pass shade.hernell/light_volume".to_string(), 5.0),
                ("prepass flow.lic3d".to_string(), 7.0),
                ("slices".to_string(), 11.0),
            ]
        };
        let updates = [update(2.0, 1.0), update(4.0, 2.0), update(3.0, 0.5)];
        assert_eq!(pass_ms("pass_ms.alpha_lp+alpha_g", &updates), 3.5);
        assert_eq!(pass_ms("pass_ms.light_volume", &updates), 5.0);
        assert_eq!(pass_ms("pass_ms.flow.lic3d", &updates), 7.0);
        assert!(pass_ms("pass_ms.nothing", &updates).is_nan());
        assert!(pass_ms("pass_ms.alpha_lp", &[update(0.0, 0.0)]).is_nan());
    }

    #[test]
    fn assertions_parse_and_refuse_nonsense() {
        assert_eq!(
            Assertion::parse("rms_delta_e < 0.5").unwrap(),
            Assertion::Each {
                term: Term {
                    metric: Measure::Metric(Metric::RmsDeltaE),
                    variant: None
                },
                op: Op::Lt,
                bound: 0.5
            }
        );
        match Assertion::parse("time(pre) / time(post) <= 0.8").unwrap() {
            Assertion::Ratio { a, b, op, bound } => {
                assert_eq!(a.metric, Measure::Metric(Metric::FrameMs));
                assert_eq!(a.variant.as_deref(), Some("pre"));
                assert_eq!(b.variant.as_deref(), Some("post"));
                assert_eq!((op, bound), (Op::Le, 0.8));
            }
            other => panic!("{other:?}"),
        }
        for bad in [
            "rms_delta_e",
            "rms < 1",
            "rms_delta_e < x",
            "rms_delta_e(pre < 1",
            "time / time(post) < 1",
            "ssim() > 0.9",
            "rms_delta_e < nan",
        ] {
            assert!(Assertion::parse(bad).is_err(), "{bad}");
        }
    }

    fn row(variant: &str, ms: f64, rms: f64) -> Row {
        Row {
            scene: "s".into(),
            variant: variant.into(),
            values: vec![1.0],
            slices: 10,
            frame_ms: ms,
            clock: "gpu",
            update_ms: 0.0,
            update_gpu_ms: f64::NAN,
            apply_ms: f64::NAN,
            update_passes: Vec::new(),
            gpu_memory_bytes: 0,
            empty_brick_share: f64::NAN,
            coverage: f64::NAN,
            metrics: Metrics {
                width: 1,
                height: 1,
                rms_delta_e: rms,
                mean_delta_e: rms,
                max_delta_e: rms,
                share_above_6: 0.0,
                psnr_db: 40.0,
                ssim: 1.0,
                rms_delta_e_blur: rms,
            },
            statistics: BTreeMap::from([("x.y.z".to_string(), ms / 10.0)]),
            image: String::new(),
            reference: Some(0),
            pareto: false,
            search: None,
            gallery: None,
        }
    }

    #[test]
    fn assertions_check_rows_and_medians() {
        let rows = vec![
            row("a", 10.0, 0.2),
            row("a", 12.0, 0.6),
            row("b", 20.0, 0.1),
            row("b", 30.0, 0.1),
        ];
        let check = |s: &str| Assertion::parse(s).unwrap().check(s, &rows);
        assert!(!check("rms_delta_e < 0.5").passed);
        assert!(check("rms_delta_e(b) < 0.5").passed);
        assert!(!check("rms_delta_e(a) < 0.5").passed);
        assert!(check("rms_delta_e(a) < 0.7").passed);
        // medians 11 and 25
        let c = check("time(a) / time(b) < 0.5");
        assert!(c.passed, "{}", c.detail);
        assert!(c.detail.contains("0.44"), "{}", c.detail);
        assert!(!check("time(a) / time(b) > 0.5").passed);
        assert!(!check("ssim(zzz) > 0.5").passed, "no rows never passes");
        // plugin statistics: x.y.z is a tenth of the time (1, 1.2, 2, 3)
        assert!(check("x.y.z(b) >= 2").passed);
        assert!(!check("x.y.z(a) >= 1.1").passed);
        assert!(check("x.y.z(a) / x.y.z(b) < 0.5").passed);
        assert!(
            !check("x.y.q < 1e9").passed,
            "a statistic no row has never passes"
        );
        assert_eq!(statistic_cell(Some(7.0)), "7");
        assert_eq!(statistic_cell(Some(7.2834)), "7.28");
        assert_eq!(statistic_cell(Some(0.0421)), "0.0421");
        assert_eq!(statistic_cell(Some(f64::NAN)), "—");
        assert_eq!(statistic_cell(None), "—");
        let st = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(
            statistic_headers(&st(&["shade.hernell.data_reduction", "a.b.empty"])),
            ["`data_reduction`", "`empty`"]
        );
        assert_eq!(
            statistic_headers(&st(&["a.b.x", "c.d.x"])),
            ["`a.b.x`", "`c.d.x`"]
        );
    }

    #[test]
    fn searches_are_checked_and_report_their_figures() {
        let p = Path::new("exp.ron");
        let with = |variants: &str, statistics: &str| {
            parse(
                &format!(
                    "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], variants: [{variants}], statistics: [{statistics}])"
                ),
                p,
            )
        };
        let err = |v: &str, st: &str| with(v, st).unwrap_err().to_string();
        let ok = "(name: \"hidden\"), (name: \"found\", search: (target: \"hidden\", population: 8, generations: 3))";
        let e = with(ok, "\"search.best\", \"search.reached\"").unwrap();
        let spec = e.variants[1].search.as_ref().unwrap();
        let o = spec.options(vwb_render::search::genome::Space::Tf1d);
        assert_eq!((o.population, o.generations, o.seed), (8, 3, 1));
        for (variants, statistics, says) in [
            (
                "(name: \"a\", search: (target: \"b\"))",
                "",
                "targets variant 'b'",
            ),
            (
                "(name: \"a\", search: (target: \"a\"))",
                "",
                "searches toward itself",
            ),
            (
                "(name: \"a\", search: ())",
                "",
                "needs either a target variant or an objective",
            ),
            (
                "(name: \"h\"), (name: \"a\", search: (target: \"h\", objective: \"entropy\"))",
                "",
                "needs either",
            ),
            (
                "(name: \"a\", search: (objective: \"beauty\"))",
                "",
                "unknown objective 'beauty'",
            ),
            (
                "(name: \"a\", search: (objective: \"entropy\", population: 1))",
                "",
                "population 1",
            ),
            (
                "(name: \"a\", search: (objective: \"entropy\", tile: 4))",
                "",
                "tile 4",
            ),
            (
                "(name: \"h\", search: (objective: \"entropy\")), (name: \"a\", search: (target: \"h\"))",
                "",
                "whose own TF is searched",
            ),
            (ok, "\"search.beauty\"", "a search reports search.first"),
            (
                "(name: \"a\")",
                "\"search.best\"",
                "no variant has a search",
            ),
        ] {
            let e = err(variants, statistics);
            assert!(e.starts_with("exp.ron: ") && e.contains(says), "{e}");
        }
        // the figures of a search that reached 3 at its third generation
        let record = SearchRecord {
            genome: vwb_render::search::genome::Genome::Tf1d(Vec::new()),
            best_by_generation: vec![9.0, 4.0, 2.5, 2.0],
            best_origins: vec!["random", "child", "poll", "newton"],
            population: 10,
            views: 3,
            seconds: 2.0,
            reach: 3.0,
            preset: String::new(),
        };
        let figures: Vec<f64> = SEARCH_STATISTICS
            .iter()
            .map(|n| record.statistic(n))
            .collect();
        assert_eq!(figures, [9.0, 2.0, 2.0, 30.0, 2.0, 60.0]);
        let never = SearchRecord {
            reach: 1.0,
            ..record
        };
        assert!(never.statistic("search.reached").is_nan());
        assert!(never.statistic("search.renders").is_nan());
    }

    #[test]
    fn files_are_checked_with_their_name() {
        let p = Path::new("exp.ron");
        let err = |t: &str| parse(t, p).unwrap_err().to_string();
        assert!(
            err("Experiment(name: \"x\", scenes: [])")
                .contains("exp.ron: an experiment needs at least one scene")
        );
        assert!(
            err("Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], colour: 1)")
                .contains("exp.ron")
        );
        let e = err(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], variants: [(name: \"a\")], reference: ConvergedOf(\"b\"))",
        );
        assert!(e.contains("variant 'b'"), "{e}");
        let e = err(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], assertions: [\"rms_delta_e(q) < 1\"])",
        );
        assert!(e.contains("variant 'q'"), "{e}");
        let e = err(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], grid: [(param: \"render.slice_spacing\")])",
        );
        assert!(e.contains("grid axis"), "{e}");
        // per-variant references name declared variants, never themselves
        let e = err(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], variants: [(name: \"a\", reference: Variant(\"b\"))])",
        );
        assert!(
            e.contains("reference of variant 'a' names variant 'b'"),
            "{e}"
        );
        let e = err(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], variants: [(name: \"a\", reference: Variant(\"a\"))])",
        );
        assert!(e.contains("variant 'a' is its own reference"), "{e}");
        // a slice count fixes the spacing: no spacing axis beside it
        let e = err(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], variants: [(name: \"a\", set: {\"render.slices\": 100})], grid: [(param: \"render.slice_spacing\", values: [1.0])])",
        );
        assert!(e.contains("variant 'a' sets render.slices"), "{e}");
        // statistics are <plugin id>.<name>, and assertions read only listed ones
        let e = err(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], statistics: [\"hernell.reduction\"])",
        );
        assert!(
            e.contains("statistic 'hernell.reduction' is not of the form"),
            "{e}"
        );
        let e = err(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], assertions: [\"shade.hernell.data_reduction > 2\"])",
        );
        assert!(
            e.contains(
                "reads statistic 'shade.hernell.data_reduction', which `statistics` does not list"
            ),
            "{e}"
        );
        let e = err(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], assertions: [\"reduction > 2\"])",
        );
        assert!(e.contains("unknown metric 'reduction'"), "{e}");
        let ok = parse(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\")], variants: [(name: \"a\"), (name: \"b\", reference: ConvergedOf(\"a\")), (name: \"c\", reference: TimeOnly)], reference: TimeOnly, reference_options: {\"directions\": 8})",
            p,
        )
        .unwrap();
        assert_eq!(ok.reference, ReferenceSpec::TimeOnly);
        assert_eq!(
            ok.variants[1].reference,
            Some(ReferenceSpec::ConvergedOf("a".into()))
        );
        assert_eq!(ok.variants[2].reference, Some(ReferenceSpec::TimeOnly));
        assert_eq!(ok.reference_options["directions"], 8.0);
        let ok = parse(
            "Experiment(name: \"x\", scenes: [Preset(\"a.ron\"), Sample(\"ct_head\")], variants: [(name: \"a\", set: {\"classify.tf1d.mode\": \"pre\", \"render.slice_spacing\": 0.5})], grid: [(param: \"render.slice_spacing\", range: \"0.5..2:3:log\")], reference: ConvergedOf(\"a\"), assertions: [\"time < 1e9\"], seed: Some(3))",
            p,
        )
        .unwrap();
        assert_eq!(ok.variants[0].set.len(), 2);
        assert_eq!(axis_values(&ok.grid[0]).unwrap(), vec![0.5, 1.0, 2.0]);
    }

    #[test]
    fn variants_set_swap_and_switch_with_checks() {
        let base = crate::document::load_document(None).unwrap();
        let volume = headless::load_volume(&base.volume).unwrap();
        let v = |set: &[(&str, SetValue)]| Variant {
            name: "v".into(),
            set: set
                .iter()
                .map(|(k, x)| (k.to_string(), x.clone()))
                .collect(),
            ..Default::default()
        };
        let d = v(&[
            ("classify.tf1d.mode", SetValue::Text("pre".into())),
            ("render.slice_spacing", SetValue::Number(0.5)),
        ])
        .apply(&base, &volume)
        .unwrap();
        assert_eq!(d.render.slice_spacing, 0.5);
        let inst = d
            .stack
            .iter()
            .find(|i| i.plugin.id() == "classify.tf1d")
            .unwrap();
        assert_eq!(
            inst.params.get("mode"),
            Some(&ParamValue::Enum("pre".into()))
        );
        for (key, value, expect) in [
            (
                "classify.tf1d.mode",
                SetValue::Text("sideways".into()),
                "mode",
            ),
            (
                "classify.tf1d.nope",
                SetValue::Number(1.0),
                "no parameter 'nope'",
            ),
            (
                "shade.nothing.x",
                SetValue::Number(1.0),
                "no plugin 'shade.nothing'",
            ),
            ("classify.tf1d.mode", SetValue::Number(1.0), "does not fit"),
            (
                "classify.tf1d.mode",
                SetValue::Numbers(vec![1.0, 2.0, 3.0]),
                "does not fit",
            ),
            ("render.slice_spacing", SetValue::Number(-1.0), "> 0"),
        ] {
            let e = v(&[(key, value)])
                .apply(&base, &volume)
                .unwrap_err()
                .to_string();
            assert!(e.contains(expect), "{key}: {e}");
        }
        let swapped = Variant {
            name: "s".into(),
            swap: vec![("classify.tf1d".into(), "classify.tf2d".into())],
            ..Default::default()
        }
        .apply(&base, &volume)
        .unwrap();
        assert!(
            swapped
                .stack
                .iter()
                .any(|i| i.plugin.id() == "classify.tf2d")
        );
        assert!(
            !swapped
                .stack
                .iter()
                .any(|i| i.plugin.id() == "classify.tf1d")
        );
        let off = Variant {
            name: "o".into(),
            disable: vec!["classify.tf1d".into()],
            ..Default::default()
        }
        .apply(&base, &volume)
        .unwrap();
        assert!(
            off.stack
                .iter()
                .all(|i| i.plugin.id() != "classify.tf1d" || !i.enabled)
        );
        // render.slices: the spacing that gives about that many slices in the frame
        for n in [10.0, 1000.0] {
            let d = v(&[("render.slices", SetValue::Number(n))])
                .apply(&base, &volume)
                .unwrap();
            let count = vwb_render::validate::check_slices(
                &d.camera,
                d.render.size,
                d.render.slice_spacing,
                &volume,
            )
            .unwrap() as f64;
            assert!(
                (count - n).abs() <= 2.0,
                "{n} slices asked, {count} planned"
            );
        }
        for bad in [0.0, 2.5, -3.0] {
            let e = v(&[("render.slices", SetValue::Number(bad))])
                .apply(&base, &volume)
                .unwrap_err()
                .to_string();
            assert!(e.contains("whole number"), "{bad}: {e}");
        }
        let mut d = base.clone();
        let e = set_value(&mut d, "render.slices", &SetValue::Number(10.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("set in an experiment's variants"), "{e}");
    }

    #[test]
    fn gpu_copies_of_docs_gain_their_block() {
        assert_eq!(
            gpu_doc_path(Path::new("../docs/perf.md")),
            Path::new("../docs/gpu/perf.md")
        );
        let dir = std::env::temp_dir().join(format!("vwb-gpu-doc-{}", std::process::id()));
        let doc = dir.join("gpu").join("x.md");
        let _ = std::fs::remove_dir_all(&dir);
        write_or_add_block(&doc, "# X\n", "b", "## B", "one\n").unwrap();
        let text = std::fs::read_to_string(&doc).unwrap();
        assert!(
            text.starts_with("# X\n\n## B\n\n<!-- BEGIN b -->\none\n<!-- END b -->"),
            "{text}"
        );
        // a second write replaces the block and adds no second heading
        write_or_add_block(&doc, "# X\n", "b", "## B", "two\n").unwrap();
        let text = std::fs::read_to_string(&doc).unwrap();
        assert_eq!(text.matches("## B").count(), 1, "{text}");
        assert!(text.contains("two") && !text.contains("one"), "{text}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn doc_blocks_are_replaced_or_refused() {
        let dir = std::env::temp_dir().join(format!("vwb-block-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("doc.md");
        std::fs::write(&f, "head\n<!-- BEGIN x -->\nold\n<!-- END x -->\ntail\n").unwrap();
        write_block(&f, "x", "new\n").unwrap();
        assert_eq!(
            std::fs::read_to_string(&f).unwrap(),
            "head\n<!-- BEGIN x -->\nnew\n<!-- END x -->\ntail\n"
        );
        let e = write_block(&f, "y", "z").unwrap_err().to_string();
        assert!(e.contains("doc.md") && e.contains("BEGIN y"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
