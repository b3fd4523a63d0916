//! Command-line interface (clap). Failures return errors that name the file and the
//! cause; `main` prints them and exits non-zero.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use vwb_render::preset::Document;
use vwb_render::renderer::Backend;
use vwb_render::{GpuContext, TargetFormat};

use vwb_lab::measure::{self, Against};
use vwb_lab::{animation, headless};
use vwb_render::reference::DEFAULT_TOLERANCE_DELTA_E;

#[derive(Debug, Parser)]
#[command(
    name = "vwb",
    version,
    about = "Exploration workbench for GPU slice-based direct volume rendering",
    after_help = crate::cli_help::VWB
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Preset to open in the window.
    #[arg(long, global = true)]
    pub preset: Option<PathBuf>,
    /// Volume to open in the window: a volume file (any format `vwb info --volume` reads) or a sample name (`vwb data list`).
    #[arg(long)]
    pub volume: Option<PathBuf>,
    /// Open the window, render, save a screenshot to this PNG and exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Also load user plugins from this folder (a plugin folder with plugin.ron, or a
    /// folder of them; repeatable). The user plugin folder ($VWB_PLUGINS, else
    /// ~/.config/vwb/plugins) is always read.
    #[arg(long, global = true)]
    pub plugins: Vec<PathBuf>,
}

/// Loads and installs the user plugins (the user folder and `--plugins`); a plugin
/// that fails is reported with its file and line and left out.
pub fn install_user_plugins(cli: &Cli) -> Vec<String> {
    let (ids, errors) = vwb_plugins::user::install_from(&cli.plugins);
    if !ids.is_empty() {
        log::info!("user plugins: {}", ids.join(", "));
    }
    for e in &errors {
        eprintln!("warning: user plugin not loaded: {e}");
    }
    errors
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a preset headless to a PNG.
    #[command(after_help = crate::cli_help::RENDER)]
    Render(RenderArgs),
    /// Write the region inside the preset's clip shapes or clip mesh (or --box) as NRRD.
    #[command(after_help = crate::cli_help::CROP)]
    Crop(crate::crop::CropArgs),
    /// Render a preset on the GPU and compare it with the CPU reference, the converged
    /// reference or another preset: writes image.png, against.png, heatmap.png and
    /// metrics.json into the output folder.
    #[command(after_help = crate::cli_help::COMPARE)]
    Compare(CompareArgs),
    /// Time a preset per pass and per plugin (ablation) and list GPU memory per plugin.
    #[command(after_help = crate::cli_help::BENCH)]
    Bench(BenchArgs),
    /// Sweep parameters over a grid; time every point and measure its error against the
    /// converged reference; write sweep.csv, the images and a Pareto plot.
    #[command(after_help = crate::cli_help::SWEEP)]
    Sweep(SweepArgs),
    /// Print the scene (volume, camera, classification, slices) as JSON for peer
    /// renderers such as bench/vtk_peer.py.
    #[command(after_help = crate::cli_help::SCENE)]
    Scene(SceneArgs),
    /// Suggest a transfer function from the data (Kindlmann and Durkin 1998): opacity
    /// on the boundaries found in the histogram volume over value, first and second
    /// directional derivative. Writes the curve as RON (the `tf` of classify.tf1d).
    #[command(after_help = crate::cli_help::SUGGEST_TF)]
    SuggestTf(SuggestTfArgs),
    /// Transfer-function design gallery (Marks et al. 1997): draws a seeded pool of TF
    /// genomes, renders each from several viewpoints in batched atlases, keeps the most
    /// dispersed and lays them out by MDS; writes gallery.png, genomes.ron and
    /// gallery.json. --around/--pick refine around a pick; --apply writes a preset with it.
    #[command(after_help = crate::cli_help::GALLERY)]
    Gallery(GalleryArgs),
    /// Genetic TF search (He et al. 1996) toward the images of a target preset's stack,
    /// seeded and bit-reproducible; writes best.ron, history.csv and best.png.
    #[command(after_help = crate::cli_help::EVOLVE)]
    Evolve(EvolveArgs),
    /// Template adaptation (thesis §6.4): move a TF designed for one volume onto another
    /// by a monotone warp of the value axis found by dynamic programming on their
    /// histograms and boundary profiles p(v); reports which it used.
    #[command(after_help = crate::cli_help::ADAPT_TF)]
    AdaptTf(AdaptTfArgs),
    /// Run an experiment file: scenes × variants × a parameter grid, each image timed and
    /// compared with its reference; writes a report (Markdown, Pareto plots, images,
    /// CSV, JSON, JUnit XML) and fails when an assertion fails.
    #[command(after_help = crate::cli_help::RUN)]
    Run(RunArgs),
    /// Print the adapter, its limits and the registered plugin ids; with --volume, what
    /// was read from a volume file instead (dims, type, spacing, orientation, value
    /// range, notes and warnings).
    #[command(after_help = crate::cli_help::INFO)]
    Info(InfoArgs),
    /// Sample data sets that presets name (`volume: Sample("ct_head")`): list them,
    /// fetch them into the data directory ($VWB_DATA_DIR, else the user's cache).
    #[command(subcommand, after_help = crate::cli_help::DATA)]
    Data(crate::data_cmd::DataCommand),
}

/// `vwb gallery`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct GalleryArgs {
    /// Genomes drawn.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(2..=8192))]
    pub pool: u32,
    /// Genomes kept.
    #[arg(long, default_value_t = 36, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub k: u32,
    /// Thumbnail side in pixels.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(16..=256))]
    pub tile: u32,
    /// Viewpoints per descriptor.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub views: u32,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Slice spacing of the thumbnails, voxels.
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    pub spacing: f64,
    /// Primitives per random genome, at most (1–8).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=8))]
    pub max_primitives: u32,
    /// A gallery's genomes.ron: refine around its pick --pick (or apply it with --apply).
    #[arg(long)]
    pub around: Option<PathBuf>,
    /// The pick's index in --around's file (its selection order).
    #[arg(long, default_value_t = 0)]
    pub pick: usize,
    /// Mutation radius of a refinement (0–1).
    #[arg(long, default_value_t = 0.3, value_parser = parse_unit)]
    pub radius: f64,
    /// Write the preset with the pick's TF to -o (a .ron) instead of a gallery.
    #[arg(long)]
    pub apply: bool,
    /// Output folder (or, with --apply, the preset to write).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `vwb gallery`.
pub fn run_gallery(preset: Option<&std::path::Path>, a: &GalleryArgs) -> Result<()> {
    let Some(preset) = preset else {
        bail!("vwb gallery needs --preset P.ron (a stack with classify.tf1d or classify.tf2d)");
    };
    let around = match &a.around {
        Some(f) => Some(vwb_lab::search::read_pick(f, a.pick)?),
        None => None,
    };
    if a.apply {
        let g = around
            .ok_or_else(|| anyhow::anyhow!("--apply needs --around genomes.ron and --pick I"))?;
        vwb_lab::search::apply_pick(preset, &g, &a.output)?;
        eprintln!("wrote {} with pick {}", a.output.display(), a.pick);
        return Ok(());
    }
    let o = vwb_render::search::gallery::GalleryOptions {
        pool: a.pool as usize,
        k: a.k as usize,
        tile: a.tile,
        views: a.views as usize,
        slice_spacing: a.spacing as f32,
        seed: a.seed,
        max_primitives: a.max_primitives as usize,
        around: around.map(|g| (g, a.radius)),
        ..Default::default()
    };
    let g = vwb_lab::search::run_gallery(preset, &o, &a.output)?;
    eprintln!("{}", vwb_lab::search::summary(&g));
    eprintln!("wrote {}", a.output.join("gallery.png").display());
    Ok(())
}

/// `vwb evolve`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct EvolveArgs {
    /// The preset whose TF is searched for: its images from the same viewpoints are
    /// the target (score: RMS ΔE*uv).
    #[arg(
        long,
        required_unless_present_any = ["objective", "target"],
        conflicts_with_all = ["objective", "target"]
    )]
    pub target_preset: Option<PathBuf>,
    /// Or a target image: the views side by side (square tiles from the run's
    /// viewpoints, as `target.png` and `best.png` hold them); its height sets the tile.
    #[arg(long, conflicts_with = "objective")]
    pub target: Option<PathBuf>,
    /// Or an objective to maximise: an image objective (entropy, edge_energy,
    /// histogram_variance) or the data's visible-boundary coverage
    /// (boundary_coverage); score: minus the objective.
    #[arg(long, value_parser = parse_objective)]
    pub objective: Option<vwb_lab::search::EvolveTarget>,
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u32).range(4..=512))]
    pub population: u32,
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub generations: u32,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Thumbnail side in pixels [default: 48, or a target image's height].
    #[arg(long, value_parser = clap::value_parser!(u32).range(16..=256))]
    pub tile: Option<u32>,
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `vwb evolve`.
pub fn run_evolve(preset: Option<&std::path::Path>, a: &EvolveArgs) -> Result<()> {
    let Some(preset) = preset else {
        bail!("vwb evolve needs --preset P.ron (a stack with classify.tf1d or classify.tf2d)");
    };
    let target_tile = match &a.target {
        Some(file) => Some(
            image::image_dimensions(file)
                .with_context(|| format!("{}: cannot read the target image", file.display()))?
                .1,
        ),
        None => None,
    };
    let tile = match (a.tile, target_tile) {
        (Some(t), Some(h)) if t != h => bail!(
            "--tile {t} differs from the target image's height {h}: the tiles are the target's"
        ),
        (t, h) => t.or(h).unwrap_or(48),
    };
    let o = vwb_render::search::genetic::GaOptions {
        population: a.population as usize,
        generations: a.generations as usize,
        seed: a.seed,
        tile,
        ..Default::default()
    };
    let target = match (&a.target_preset, &a.target, &a.objective) {
        (Some(p), _, _) => vwb_lab::search::EvolveTarget::Preset(p.clone()),
        (None, Some(f), _) => vwb_lab::search::EvolveTarget::Image(f.clone()),
        (None, None, Some(o)) => o.clone(),
        (None, None, None) => {
            bail!("vwb evolve needs --target-preset Q.ron, --target views.png or --objective NAME")
        }
    };
    let h = vwb_lab::search::run_evolve(preset, &target, &o, &a.output)?;
    let (first, last) = (h[0].best_score, h[h.len() - 1].best_score);
    eprintln!(
        "best score {first:.3} → {last:.3} over {} generations; wrote {}",
        h.len(),
        a.output.join("best.ron").display()
    );
    Ok(())
}

/// `vwb adapt-tf`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct AdaptTfArgs {
    /// The volume the TF was designed for (a file or a sample name).
    #[arg(long)]
    pub reference_volume: PathBuf,
    /// The TF (RON, as `vwb suggest-tf` writes it and classify.tf1d's `tf` holds).
    #[arg(long)]
    pub tf: PathBuf,
    /// The volume to adapt it to.
    #[arg(long)]
    pub volume: PathBuf,
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `vwb adapt-tf`.
pub fn run_adapt_tf(a: &AdaptTfArgs) -> Result<()> {
    let w = vwb_lab::search::run_adapt(&a.reference_volume, &a.tf, &a.volume, &a.output)?;
    eprintln!(
        "warp by the {} signature (mean squared difference {:.5}); wrote {}",
        w.signature,
        w.cost,
        a.output.display()
    );
    Ok(())
}

/// `vwb run`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct RunArgs {
    /// The experiment files (RON; see experiments/ and docs/experiments.md), run in
    /// order.
    #[arg(required = true, num_args = 1..)]
    pub experiments: Vec<PathBuf>,
    /// Folder for the report (default reports/<experiment name>); only with one file.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}

/// `vwb run FILE..`: runs the experiments in order; an error when a file is bad or an
/// assertion fails (the remaining files still run, so every report is written).
pub fn run_experiment(a: &RunArgs) -> Result<()> {
    if a.output.is_some() && a.experiments.len() > 1 {
        bail!("-o names one report folder; give one experiment file with it");
    }
    let mut failed = Vec::new();
    for file in &a.experiments {
        if let Err(e) = vwb_lab::experiment::run_file(file, a.output.as_deref()) {
            if a.experiments.len() == 1 {
                return Err(e);
            }
            eprintln!("error: {e:#}");
            failed.push(file.display().to_string());
        }
    }
    if !failed.is_empty() {
        bail!(
            "{} of {} experiments failed: {}",
            failed.len(),
            a.experiments.len(),
            failed.join(", ")
        );
    }
    Ok(())
}

/// Overrides of the preset's volume and frame settings, shared by the subcommands.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct FrameArgs {
    /// Volume overriding the preset's: a volume file (any format `vwb info --volume` reads) or a sample name (`vwb data list`).
    #[arg(long)]
    pub volume: Option<PathBuf>,
    /// Image size WxH (default: the preset's).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<[u32; 2]>,
    /// Backend overriding the preset's.
    #[arg(long)]
    pub backend: Option<Backend>,
    /// Eye-buffer precision overriding the preset's: rgba16float or rgba32float.
    #[arg(long, value_parser = parse_target)]
    pub target: Option<TargetFormat>,
    /// Slice spacing in voxels overriding the preset's.
    #[arg(long)]
    pub spacing: Option<f32>,
    /// Stop a ray once its opacity reaches this value (0 < T ≤ 1; the raster backend
    /// at the end of a run of slices); `off` disables it.
    #[arg(long, value_parser = parse_early_termination)]
    pub early_termination: Option<EarlyTermination>,
    /// Empty-space skipping on or off (default: the preset's, normally on).
    #[arg(long)]
    pub skipping: Option<OnOff>,
    /// Raster backend: proxy polygons cut to the occupied bricks' cells (needs
    /// skipping; the same image up to float rounding; default: the preset's, normally off).
    #[arg(long)]
    pub occupied_proxy: Option<OnOff>,
    /// Raster backend: proxy polygons cut to the occupied bricks' hull (needs skipping;
    /// faster where air surrounds the matter; the same image up to float rounding;
    /// default: the preset's, normally off, when the polygons are drawn under a scissor
    /// to that hull instead, with the image unchanged).
    #[arg(long)]
    pub hull_cut: Option<OnOff>,
    /// Raster backend: slices per proxy polygon, auto, 1, 2, 4, 8 or 16 (Rezk-Salama
    /// 2001, §9.1: a fragment composites its group's samples and blends once; faster,
    /// the image moved by rounding; default: the preset's, normally auto: 1, or 8 with
    /// early termination).
    #[arg(long, value_parser = parse_slices_per_proxy)]
    pub slices_per_proxy: Option<u32>,
    /// How the volume is stored on the GPU: auto (r32float_pairs on CPU devices,
    /// r32float on GPUs that filter it), r32float, r32float_pairs (each voxel beside its
    /// +z neighbour: a bilinear fetch per read, twice the bytes), r16float, r16unorm
    /// or r8unorm (default: the preset's).
    #[arg(long, value_parser = vwb_render::renderer::VolumeFormat::parse)]
    pub volume_format: Option<vwb_render::renderer::VolumeFormat>,
    /// How the classification tables (transfer functions, pre-integration and label
    /// tables) are stored on the GPU: auto (rgba16float on GPUs, rgba32float on CPU
    /// devices), rgba32float or rgba16float (default: the preset's).
    #[arg(long, value_parser = vwb_render::renderer::TableFormat::parse)]
    pub table_format: Option<vwb_render::renderer::TableFormat>,
    /// Sets a plugin parameter or a render setting, as an experiment variant's `set`
    /// does, after the options above: `--set classify.tf1d.mode=preintegrated`,
    /// `--set shade.dos.buffer_scale=0.5`, `--set render.slice_spacing=0.5`,
    /// `--set shade.blinn_phong.light0_vector=(0,1,0)`; repeatable. VALUE is written as in
    /// an experiment file (true, 0.5, (0, 1, 0), "text"); a bare word is text.
    #[arg(long = "set", value_name = "KEY=VALUE", value_parser = parse_set)]
    pub set: Vec<(String, String)>,
}

/// `--set KEY=VALUE`.
pub fn parse_set(s: &str) -> Result<(String, String), String> {
    match s.split_once('=') {
        Some((k, v)) if !k.trim().is_empty() => Ok((k.trim().to_string(), v.trim().to_string())),
        _ => Err(format!("'{s}' is not KEY=VALUE")),
    }
}

/// The value of `--set KEY=VALUE` as an experiment file's `set` writes it (RON: true,
/// 0.5, (0, 1, 0), "text"), and a bare word as text.
pub fn set_value_of(v: &str) -> vwb_lab::experiment::SetValue {
    ron::from_str(v).unwrap_or_else(|_| vwb_lab::experiment::SetValue::Text(v.to_string()))
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

/// `--slices-per-proxy`: `auto` ([`vwb_render::renderer::RASTER_GROUP_AUTO`]) or one of
/// [`vwb_render::renderer::RASTER_GROUPS`].
pub fn parse_slices_per_proxy(s: &str) -> Result<u32, String> {
    let groups = vwb_render::renderer::RASTER_GROUPS;
    if s.trim().eq_ignore_ascii_case("auto") {
        return Ok(vwb_render::renderer::RASTER_GROUP_AUTO);
    }
    s.parse::<u32>()
        .ok()
        .filter(|n| groups.contains(n))
        .ok_or_else(|| format!("slices per proxy '{s}' is neither auto nor one of {groups:?}"))
}

/// `--early-termination`: a threshold or off.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EarlyTermination(pub Option<f32>);

pub fn parse_early_termination(s: &str) -> Result<EarlyTermination, String> {
    if s == "off" {
        return Ok(EarlyTermination(None));
    }
    s.parse::<f32>()
        .ok()
        .filter(|t| *t > 0.0 && *t <= 1.0)
        .map(|t| EarlyTermination(Some(t)))
        .ok_or_else(|| format!("early termination '{s}' is neither off nor a number in (0, 1]"))
}

impl FrameArgs {
    pub fn apply(&self, doc: &mut Document) -> Result<()> {
        if let Some(v) = &self.volume {
            doc.volume = headless::volume_arg(v);
        }
        if let Some(s) = self.size {
            doc.render.size = s;
        }
        if let Some(b) = self.backend {
            doc.render.backend = b;
        }
        if let Some(t) = self.target {
            doc.render.target = t;
        }
        if let Some(s) = self.spacing {
            if !(s.is_finite() && s > 0.0) {
                bail!("--spacing must be a number > 0, got {s}");
            }
            doc.render.slice_spacing = s;
        }
        if let Some(EarlyTermination(t)) = self.early_termination {
            doc.render.early_termination = t;
        }
        if let Some(on) = self.skipping {
            doc.render.empty_space_skipping = on == OnOff::On;
        }
        if let Some(on) = self.occupied_proxy {
            doc.render.occupied_proxy = on == OnOff::On;
        }
        if let Some(on) = self.hull_cut {
            doc.render.hull_cut = on == OnOff::On;
        }
        if let Some(n) = self.slices_per_proxy {
            doc.render.slices_per_proxy = n;
        }
        if let Some(f) = self.volume_format {
            doc.render.volume_format = f;
        }
        if let Some(f) = self.table_format {
            doc.render.table_format = f;
        }
        for (key, raw) in &self.set {
            use vwb_lab::experiment::{SetValue, set_value};
            let value = set_value_of(raw);
            let Err(e) = set_value(doc, key, &value) else {
                continue;
            };
            // an enumeration whose names are numbers (`buffer_scale`: "0.5") takes the
            // number as text; where that fails too, both complaints
            if matches!(value, SetValue::Number(_)) {
                if let Err(t) = set_value(doc, key, &SetValue::Text(raw.clone())) {
                    bail!("--set {key}={raw}: {e} (as text: {t})");
                }
                continue;
            }
            bail!("--set {key}={raw}: {e}");
        }
        Ok(())
    }
}

#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub frame: FrameArgs,
    /// Print per-frame timings (median of --frames after warm-up).
    #[arg(long)]
    pub timings: bool,
    /// Frames to time with --timings (at least 1).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: u32,
    /// Sets the animation clock of the stack (e.g. flow.arrival's time, voxels at the
    /// field's top speed), or the parameter --animate names, to T.
    #[arg(long, value_name = "T")]
    pub time: Option<f32>,
    /// An image sequence: N frames with the animated parameter from A to B (both
    /// included), written as OUTPUT's stem with _0000, _0001, … (e.g. 0:256:65).
    #[arg(long, value_name = "A:B:N", value_parser = parse_sequence)]
    pub sequence: Option<(f32, f32, u32)>,
    /// The parameter --time and --sequence drive instead of the clock: `key` or
    /// `plugin.key` (e.g. flow.lic3d.phase_deg).
    #[arg(long, value_name = "PARAM")]
    pub animate: Option<String>,
    /// Output PNG.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `--sequence A:B:N`.
pub fn parse_sequence(s: &str) -> Result<(f32, f32, u32), String> {
    let parts: Vec<&str> = s.split(':').collect();
    let bad = || format!("sequence '{s}' is not A:B:N (from, to, a frame count from 1 to 100000)");
    let [a, b, n] = parts[..] else {
        return Err(bad());
    };
    let (a, b) = (
        a.parse::<f32>().map_err(|_| bad())?,
        b.parse::<f32>().map_err(|_| bad())?,
    );
    let n = n.parse::<u32>().map_err(|_| bad())?;
    if !(a.is_finite() && b.is_finite() && (1..=100_000).contains(&n)) {
        return Err(bad());
    }
    Ok((a, b, n))
}

#[derive(Debug, clap::Args)]
pub struct CompareArgs {
    #[command(flatten)]
    pub frame: FrameArgs,
    /// reference (CPU twins, same slices), converged (CPU, refined until stable) or a
    /// preset file (rendered on the GPU at the same size).
    #[arg(long, default_value = "reference")]
    pub against: Against,
    /// Convergence tolerance of the converged reference (RMS ΔE*uv between halvings).
    #[arg(long, default_value_t = DEFAULT_TOLERANCE_DELTA_E)]
    pub tolerance: f64,
    /// Frames to time (at least 1).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: u32,
    /// Output folder.
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub frame: FrameArgs,
    /// Timed frames per measurement (at least 1).
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: u32,
    /// Untimed warm-up frames per measurement.
    #[arg(long, default_value_t = 3)]
    pub warmup: u32,
    /// Output CSV.
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(Debug, clap::Args)]
pub struct SweepArgs {
    #[command(flatten)]
    pub frame: FrameArgs,
    /// NAME=A..B:N (N values, append :log for geometric spacing) or NAME=a,b,c; NAME is
    /// render.slice_spacing or <plugin id>.<key>, e.g. classify.tf1d.opacity. Repeat
    /// for a grid.
    #[arg(long = "param", required = true)]
    pub params: Vec<String>,
    /// Timed frames per point (at least 1).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: u32,
    /// Convergence tolerance of the references (RMS ΔE*uv between halvings).
    #[arg(long, default_value_t = DEFAULT_TOLERANCE_DELTA_E)]
    pub tolerance: f64,
    /// Output folder.
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(Debug, clap::Args)]
pub struct SuggestTfArgs {
    /// The volume: a volume file (any format `vwb info --volume` reads) or a sample name (`vwb data list`); the demo when
    /// absent.
    #[arg(long)]
    pub volume: Option<PathBuf>,
    /// Half width of the boundary emphasis in voxels (> 0).
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    pub thickness: f64,
    /// Peak opacity (0 to 1).
    #[arg(long, default_value_t = 0.6, value_parser = parse_unit)]
    pub max_opacity: f64,
    /// Output RON file (a transfer function).
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(Debug, clap::Args)]
pub struct SceneArgs {
    #[command(flatten)]
    pub frame: FrameArgs,
}

pub fn parse_size(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size '{s}' is not WxH"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|&x| (1..=16384).contains(&x))
            .ok_or_else(|| format!("size '{s}': '{v}' is not an integer in 1..=16384"))
    };
    Ok([p(w)?, p(h)?])
}

/// An evolve objective by name: an image objective, or the data's visible-boundary
/// coverage.
pub fn parse_objective(s: &str) -> Result<vwb_lab::search::EvolveTarget, String> {
    if s == vwb_lab::search::BOUNDARY_COVERAGE {
        return Ok(vwb_lab::search::EvolveTarget::Coverage);
    }
    vwb_render::search::genetic::Objective::from_name(s)
        .map(vwb_lab::search::EvolveTarget::Objective)
        .ok_or_else(|| {
            format!(
                "'{s}' is not an objective (entropy, edge_energy, histogram_variance, {})",
                vwb_lab::search::BOUNDARY_COVERAGE
            )
        })
}

/// A finite number > 0.
pub fn parse_positive(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && *v > 0.0)
        .ok_or_else(|| format!("'{s}' is not a finite number > 0"))
}

/// A number in [0, 1].
pub fn parse_unit(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| (0.0..=1.0).contains(v))
        .ok_or_else(|| format!("'{s}' is not a number in [0, 1]"))
}

pub use vwb_lab::experiment::parse_target;

pub use vwb_lab::document::load_document;

pub fn run_render(preset: Option<&std::path::Path>, a: &RenderArgs) -> Result<()> {
    let Some(preset) = preset else {
        bail!("vwb render needs --preset P.ron");
    };
    let mut doc = load_document(Some(preset))?;
    a.frame.apply(&mut doc)?;
    vwb_lab::outputs::image_format(&a.output)?;
    let animated = if a.time.is_some() || a.sequence.is_some() || a.animate.is_some() {
        if a.time.is_some() && a.sequence.is_some() {
            bail!("--time sets one frame and --sequence many: give one of them");
        }
        if a.timings && a.sequence.is_some() {
            bail!("--timings times one frame: give it without --sequence");
        }
        let params = animation::animated(&doc.stack, a.animate.as_deref())
            .with_context(|| format!("{}", preset.display()))?;
        if let Some(t) = a.time {
            animation::set(&mut doc.stack, &params, t)?;
        }
        if let Some((from, to, _)) = a.sequence {
            // both ends must be in range before anything renders
            animation::check(&params, from)?;
            animation::check(&params, to)?;
        }
        params
    } else {
        Vec::new()
    };
    if let Some(seq) = a.sequence {
        return render_sequence(preset, doc, &animated, seq, &a.output);
    }
    let progress = vwb_lab::progress::Steps::new("vwb render");
    let (gpu, volume, mut r) =
        open_renderer(preset, &doc, &progress, std::slice::from_ref(&a.output))?;
    let settings = doc.frame_settings();
    progress.step("rendering");
    let (img, _, first) = headless::render_image(&mut r, &settings, doc.render.background)?;
    headless::save_png(&img, &a.output)?;
    progress.note(&format!(
        "wrote {} ({}x{}, {} slices, {} backend, volume {} {:?})",
        a.output.display(),
        img.width(),
        img.height(),
        first.slices,
        settings.backend.name(),
        volume.name,
        volume.dims
    ));
    if a.timings {
        progress.step(&format!("timing {} frames", a.frames));
        let t = measure::time_frames(&mut r, &settings, 2, a.frames)?;
        drop(progress);
        println!(
            "timings: {} frames after 2 warm-up, {}x{}, {} slices, backend {}, adapter {}",
            t.frames,
            settings.width,
            settings.height,
            t.slices,
            settings.backend.name(),
            gpu.info.name
        );
        measure::print_timing(&t);
        // how much of the volume empty-space skipping can pass over (bench/scaling.py)
        match r.empty_brick_share() {
            Some(share) => println!("empty_bricks {:.4}", share),
            None => println!("empty_bricks off"),
        }
        // how much of the frame the raster slices draw (the hull's scissor or cut)
        if let Some(share) = t.scissor_share {
            println!("scissor_pixels {share:.4}");
        }
        if let Some(share) = t.proxy_share {
            println!("proxy_volume {share:.4}");
        }
        // how many of the per-slice path's tiles had nothing to do
        if let Some(share) = t.idle_tiles {
            println!("idle_tiles {share:.4}");
        }
        // the compute march's dispatches where llvmpipe's loop limiter needs several
        // (render/src/renderer/march_parts.rs), and what still ran out
        if t.march_parts > 1 {
            println!("march_parts {}", t.march_parts);
        }
        if t.loop_limited > 0 {
            println!("loop_limited {}", t.loop_limited);
        }
        // the raster backend's slices per proxy polygon, where more than one
        if t.raster_group > 1 {
            println!("slices_per_proxy {}", t.raster_group);
        }
        // the compute rays cut to the occupied bricks' hull, and its share of the
        // visible box
        if r.empty_brick_share().is_some() && settings.backend == Backend::Compute {
            let (on, share) = r.hull_rays();
            println!("hull_rays {} {share:.4}", if on { "on" } else { "off" });
        }
    }
    Ok(())
}

/// What `vwb render` does before it renders, one frame or a sequence: loads the
/// document's volume, checks that the `outputs` may be written, runs the preflight
/// checks, opens the GPU and sets up a renderer for the document.
fn open_renderer(
    preset: &std::path::Path,
    doc: &Document,
    progress: &vwb_lab::progress::Steps,
    outputs: &[PathBuf],
) -> Result<(
    GpuContext,
    std::sync::Arc<vwb_render::Volume>,
    vwb_render::Renderer,
)> {
    progress.step("loading the volume");
    let volume = headless::load_volume(&doc.volume)?;
    for o in outputs {
        vwb_lab::outputs::check_output(o)?;
    }
    headless::preflight(Some(preset), doc, &volume)?;
    progress.step("opening the GPU");
    let gpu = GpuContext::new_headless()?;
    progress.note(&format!("adapter: {}", gpu.describe()));
    progress.step("uploading the volume and composing the stack");
    let r = headless::renderer_for(&gpu, doc, volume.clone())
        .with_context(|| format!("{}", preset.display()))?;
    Ok((gpu, volume, r))
}

/// `vwb render --sequence`: one renderer, the animated parameters set per frame (a
/// parameter outside the passes' inputs, like flow.arrival's time, reruns nothing).
fn render_sequence(
    preset: &std::path::Path,
    mut doc: Document,
    params: &[animation::Animated],
    (from, to, count): (f32, f32, u32),
    output: &std::path::Path,
) -> Result<()> {
    let progress = vwb_lab::progress::Steps::new("vwb render --sequence");
    let ends = [0, count - 1].map(|i| animation::frame_path(output, i, count));
    let (_, _, mut r) = open_renderer(preset, &doc, &progress, &ends)?;
    // the sequence's folder (e.g. frames/) is made
    if let Some(dir) = output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    }
    let settings = doc.frame_settings();
    let (mut passes, mut wall) = (0usize, Vec::new());
    for (i, t) in animation::sequence_values(from, to, count)
        .into_iter()
        .enumerate()
    {
        progress.step(&format!("frame {} of {count}", i + 1));
        animation::set(&mut doc.stack, params, t)?;
        r.update_stack(&doc.stack, doc.render.target)?;
        let (img, _, stats) = headless::render_image(&mut r, &settings, doc.render.background)?;
        let path = animation::frame_path(output, i as u32, count);
        headless::save_png(&img, &path)?;
        if i > 0 {
            passes += stats.prepasses_run() + stats.volume_passes_run.len();
            wall.push(stats.wall_ms);
        }
    }
    drop(progress);
    let names: Vec<String> = params
        .iter()
        .map(|p| format!("{}.{}", p.plugin, p.key))
        .collect();
    println!(
        "wrote {count} frames {} … {} ({} from {from} to {to}); after the first, {passes} pre-/volume passes reran{}",
        animation::frame_path(output, 0, count).display(),
        animation::frame_path(output, count - 1, count).display(),
        names.join(", "),
        measure::Summary::of(&wall)
            .map(|s| format!(", median frame {:.1} ms", s.median))
            .unwrap_or_default()
    );
    Ok(())
}

/// `vwb info`'s arguments.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct InfoArgs {
    /// A volume file (NRRD, NIfTI .nii/.nii.gz, MetaImage .mhd/.mha, a TIFF stack, a DICOM
    /// file or folder, an OME-Zarr folder) or a sample name.
    #[arg(long)]
    pub volume: Option<PathBuf>,
}

/// What a volume file holds, as `vwb info --volume` prints it.
pub fn volume_report(v: &vwb_render::Volume) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "volume: {}", v.name);
    if let Some(src) = &v.source {
        let _ = writeln!(s, "file: {}", src.display());
    }
    let _ = writeln!(s, "dims: {} x {} x {}", v.dims[0], v.dims[1], v.dims[2]);
    let _ = writeln!(
        s,
        "samples: {} ({} component{})",
        v.scalar_type().name(),
        v.components,
        if v.components == 1 { "" } else { "s" }
    );
    let _ = writeln!(
        s,
        "spacing: {} x {} x {}",
        v.spacing[0], v.spacing[1], v.spacing[2]
    );
    let _ = writeln!(
        s,
        "orientation: +x left, +y posterior, +z superior (LPS) where the file records it; otherwise the axes as stored"
    );
    let _ = writeln!(s, "value range: {} .. {}", v.range[0], v.range[1]);
    // what classify.labels and clip.labels would read, for choosing labels to show or
    // hide (any volume of non-negative integers qualifies, labelled or not)
    if let Some(labels) = vwb_plugins::label_input::distinct_labels(v) {
        let _ = writeln!(
            s,
            "integer values: {} distinct: {} (as the labels of classify.labels / clip.labels)",
            labels.len(),
            vwb_plugins::label_input::label_runs(&labels, 12)
        );
    }
    if v.non_finite > 0 {
        let _ = writeln!(s, "non-finite samples: {}", v.non_finite);
    }
    for n in &v.notes {
        let _ = writeln!(s, "note: {n}");
    }
    for w in vwb_render::validate::volume_warnings(v) {
        let _ = writeln!(s, "warning: {w}");
    }
    s
}

pub fn run_info(a: &InfoArgs) -> Result<()> {
    if let Some(path) = &a.volume {
        let v = headless::load_volume(&headless::volume_arg(path))?;
        print!("{}", volume_report(&v));
        return Ok(());
    }
    let gpu = GpuContext::new_headless()?;
    println!("adapter: {}", gpu.describe());
    println!("backend: {:?}", gpu.info.backend);
    let f = gpu.features;
    for (name, flag) in [
        ("FLOAT32_FILTERABLE", wgpu::Features::FLOAT32_FILTERABLE),
        ("FLOAT32_BLENDABLE", wgpu::Features::FLOAT32_BLENDABLE),
        ("TIMESTAMP_QUERY", wgpu::Features::TIMESTAMP_QUERY),
        (
            "TIMESTAMP_QUERY_INSIDE_ENCODERS",
            wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS,
        ),
    ] {
        println!(
            "feature {name}: {}",
            if f.contains(flag) { "yes" } else { "no" }
        );
    }
    let l = &gpu.limits;
    println!(
        "limit max_texture_dimension_2d: {}",
        l.max_texture_dimension_2d
    );
    println!(
        "limit max_texture_dimension_3d: {}",
        l.max_texture_dimension_3d
    );
    println!("limit max_bind_groups: {}", l.max_bind_groups);
    println!(
        "limit max_bindings_per_bind_group: {}",
        l.max_bindings_per_bind_group
    );
    println!(
        "limit max_sampled_textures_per_shader_stage: {}",
        l.max_sampled_textures_per_shader_stage
    );
    println!(
        "limit max_storage_textures_per_shader_stage: {}",
        l.max_storage_textures_per_shader_stage
    );
    println!(
        "limit max_uniform_buffers_per_shader_stage: {}",
        l.max_uniform_buffers_per_shader_stage
    );
    println!("limit max_buffer_size: {}", l.max_buffer_size);
    let registry = vwb_plugins::registry();
    for p in registry.plugins() {
        println!("plugin {} ({})", p.id(), p.display_name());
    }
    Ok(())
}

/// The preset of a measurement command with the frame overrides applied.
fn preset_document(
    preset: Option<&std::path::Path>,
    frame: &FrameArgs,
    cmd: &str,
) -> Result<(PathBuf, Document)> {
    let Some(preset) = preset else {
        bail!("vwb {cmd} needs --preset P.ron");
    };
    let mut doc = load_document(Some(preset))?;
    frame.apply(&mut doc)?;
    Ok((preset.to_path_buf(), doc))
}

pub fn run_compare(preset: Option<&std::path::Path>, a: &CompareArgs) -> Result<()> {
    let (path, doc) = preset_document(preset, &a.frame, "compare")?;
    let m = measure::run_compare(&path, &doc, &a.against, &a.output, a.frames, a.tolerance)?;
    println!(
        "RMS ΔE*uv {:.4}  mean {:.4}  max {:.3}  >6: {:.3}%  PSNR {:.2} dB  SSIM {:.5}",
        m.rms_delta_e,
        m.mean_delta_e,
        m.max_delta_e,
        m.share_above_6 * 100.0,
        m.psnr_db,
        m.ssim
    );
    eprintln!(
        "wrote {}/{{image,against,heatmap}}.png and metrics.json",
        a.output.display()
    );
    Ok(())
}

pub fn run_bench(preset: Option<&std::path::Path>, a: &BenchArgs) -> Result<()> {
    vwb_lab::outputs::check_extension(&a.output, "csv", "CSV")?;
    let (path, doc) = preset_document(preset, &a.frame, "bench")?;
    let volume = headless::load_volume(&doc.volume)?;
    vwb_lab::outputs::check_output(&a.output)?;
    headless::preflight(Some(&path), &doc, &volume)?;
    let gpu = GpuContext::new_headless()?;
    eprintln!("adapter: {}", gpu.describe());
    let rows = measure::bench_document(&gpu, &doc, volume, a.warmup, a.frames)?;
    let mut csv = String::from(measure::BENCH_CSV_HEADER);
    csv.push('\n');
    for row in &rows {
        println!("{}", row.csv());
        csv.push_str(&row.csv());
        csv.push('\n');
    }
    measure::save_text(&a.output, &csv)?;
    eprintln!("wrote {}", a.output.display());
    Ok(())
}

pub fn run_sweep(preset: Option<&std::path::Path>, a: &SweepArgs) -> Result<()> {
    let (_, doc) = preset_document(preset, &a.frame, "sweep")?;
    let axes = a
        .params
        .iter()
        .map(|p| measure::parse_axis(p, &doc))
        .collect::<Result<Vec<_>>>()?;
    let points = measure::run_sweep(&doc, &axes, &a.output, a.frames, a.tolerance)?;
    for p in &points {
        println!(
            "{:?}: {} slices, {:.3} {} ms, RMS ΔE*uv {:.4}{}",
            p.values,
            p.slices,
            p.ms,
            p.clock,
            p.metrics.rms_delta_e,
            if p.pareto { "  (Pareto front)" } else { "" }
        );
    }
    eprintln!(
        "wrote {}/sweep.csv, pareto.svg, sweep.json and the images",
        a.output.display()
    );
    Ok(())
}

pub fn run_suggest_tf(a: &SuggestTfArgs) -> Result<()> {
    let opts = vwb_render::suggest::SuggestOptions {
        thickness: a.thickness,
        max_opacity: a.max_opacity,
        ..Default::default()
    };
    opts.check()?;
    vwb_lab::outputs::check_extension(&a.output, "ron", "a transfer function in RON")?;
    let volume = match &a.volume {
        Some(p) => headless::load_volume(&headless::volume_arg(p))?,
        None => std::sync::Arc::new(vwb_render::volume::demo()),
    };
    vwb_lab::outputs::check_output(&a.output)?;
    let name = a
        .volume
        .as_ref()
        .map_or("demo".to_string(), |p| p.display().to_string());
    let s = vwb_render::suggest::suggest(&volume, &opts)
        .with_context(|| format!("{name}: nothing written"))?;
    let text = ron::ser::to_string_pretty(&s.curve, ron::ser::PrettyConfig::new())
        .with_context(|| format!("{}: cannot serialise", a.output.display()))?;
    vwb_render::preset::write_atomic(&a.output, text.as_bytes())
        .with_context(|| format!("{}: cannot write", a.output.display()))?;
    let peak = s
        .alpha
        .iter()
        .enumerate()
        .filter(|(_, a)| **a > 0.0)
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map_or(
            "no boundary found above the noise: the transfer function is transparent".to_string(),
            |(i, _)| {
                format!(
                    "most opaque value {:.3}",
                    (i as f64 + 0.5) / s.alpha.len() as f64
                )
            },
        );
    let background = s
        .background
        .map_or("no background peak".to_string(), |(p, end)| {
            format!("background peak at {p:.3}, transparent below {end:.3}")
        });
    eprintln!(
        "{name}: pre-filter σ {} voxels, boundary blur σ = {:.2} voxels, noise floor |∇f| {:.4}, {background}; {peak}; {} of {} value bins on a boundary; wrote {}",
        s.smoothing,
        s.sigma,
        s.noise_floor,
        s.boundary_bins(),
        s.alpha.len(),
        a.output.display()
    );
    Ok(())
}

pub fn run_scene(preset: Option<&std::path::Path>, a: &SceneArgs) -> Result<()> {
    let (path, doc) = preset_document(preset, &a.frame, "scene")?;
    let volume = headless::load_volume(&doc.volume)?;
    headless::preflight(Some(&path), &doc, &volume)?;
    let json = measure::scene_json(&doc, &volume, &path);
    println!("{}", serde_json::to_string_pretty(&json)?);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn early_termination_values() {
        assert_eq!(parse_early_termination("off"), Ok(EarlyTermination(None)));
        assert_eq!(
            parse_early_termination("0.99"),
            Ok(EarlyTermination(Some(0.99)))
        );
        for bad in ["0", "1.5", "-0.2", "nan", "x"] {
            assert!(parse_early_termination(bad).is_err(), "{bad}");
        }
        let mut doc = load_document(None).unwrap();
        let args = FrameArgs {
            early_termination: Some(EarlyTermination(Some(0.5))),
            ..Default::default()
        };
        args.apply(&mut doc).unwrap();
        assert_eq!(doc.render.early_termination, Some(0.5));
    }

    mod help {
        use super::super::Cli;
        // Every subcommand's help (its text in crate::cli_help) shows examples that parse.
        use clap::{CommandFactory, Parser};

        /// The commands of a help text's example lines.
        fn examples(help: &str) -> Vec<Vec<String>> {
            help.lines()
                .map(str::trim)
                .filter(|l| l.starts_with("vwb"))
                .map(|l| l.split_whitespace().map(str::to_string).collect())
                .collect()
        }

        #[test]
        fn every_command_shows_examples_that_parse() {
            let mut cmd = Cli::command();
            let mut helps = vec![("vwb".to_string(), cmd.render_long_help().to_string())];
            cmd.build();
            for sub in cmd.get_subcommands_mut().filter(|s| s.get_name() != "help") {
                let name = sub.get_name().to_string();
                helps.push((name.clone(), sub.render_long_help().to_string()));
                for inner in sub.get_subcommands_mut().filter(|s| s.get_name() != "help") {
                    let inner_name = format!("{name} {}", inner.get_name());
                    helps.push((inner_name, inner.render_long_help().to_string()));
                }
            }
            assert!(helps.len() >= 13, "{}", helps.len());
            for (name, help) in helps {
                let cmds = examples(&help);
                assert!(
                    help.contains("Example") && !cmds.is_empty(),
                    "`vwb {name} --help` shows no example:\n{help}"
                );
                let prefix = format!("vwb {name}");
                assert!(
                    name == "vwb" || cmds.iter().any(|c| c.join(" ").starts_with(&prefix)),
                    "`vwb {name} --help`: no example runs {prefix}"
                );
                for c in cmds {
                    if let Err(e) = Cli::try_parse_from(&c) {
                        panic!("{name}: example `{}` does not parse: {e}", c.join(" "));
                    }
                }
            }
        }
    }
}
