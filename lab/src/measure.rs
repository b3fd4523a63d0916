//! Measuring the speed–accuracy trade: frame timing (GPU timestamps per pass, wall
//! time as the labelled fallback), per-plugin cost by ablation, GPU memory per plugin,
//! image comparison against the CPU reference renderer, parameter sweeps with a Pareto
//! front, and the scene as JSON for peer renderers (`bench/vtk_peer.py`).

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use serde::Serialize;
use serde_json::json;
use vwb_render::metrics::{self, HEATMAP_DEFAULT_MAX, Metrics, RgbImageF};
use vwb_render::params::{ParamKind, ParamValue};
use vwb_render::plugin::{ConvergedReference, CpuContext, CpuSample};
use vwb_render::preset::{Document, VolumeSource};
use vwb_render::reference::{self, Converged, ReferenceImage, ReferenceOptions};
use vwb_render::slicing::VolumeBox;
use vwb_render::{FrameSettings, GpuContext, Projection, Renderer, TargetFormat, Volume};

use crate::headless;

/// Min, median and max of a series.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Summary {
    pub min: f64,
    pub median: f64,
    pub max: f64,
}

impl Summary {
    /// `None` when the series has no finite value.
    pub fn of(values: &[f64]) -> Option<Self> {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let mid = v.len() / 2;
        let median = if v.len() % 2 == 1 {
            v[mid]
        } else {
            0.5 * (v[mid - 1] + v[mid])
        };
        Some(Self {
            min: v[0],
            median,
            max: v[v.len() - 1],
        })
    }
}

/// Timings of `frames` frames after `warmup` untimed ones.
#[derive(Debug, Clone, Serialize)]
pub struct Timing {
    pub frames: u32,
    pub warmup: u32,
    pub slices: u32,
    /// Encode → GPU idle, on the CPU clock.
    pub wall_ms: Summary,
    /// First to last timestamp of the frame; `None` without timestamp queries.
    pub gpu_ms: Option<Summary>,
    /// The process's CPU time over the frame, all threads (user + system;
    /// [`process_cpu_ms`]); `None` where the platform does not report it. On a CPU
    /// adapter the frame's work runs in this process's threads, so this is the work
    /// itself, which time the host gives other tenants (steal) does not inflate as it
    /// does the wall clock: the steadier figure for comparing two builds on a shared
    /// machine (`bench/ab.py --clock cpu`). Not a frame time: two threads working
    /// for 100 ms count 200 ms.
    pub cpu_ms: Option<Summary>,
    /// Per pass (see `FrameStats::gpu_passes`).
    pub passes: Vec<(String, Summary)>,
    /// The adapter is a CPU (lavapipe): its "GPU" runs on the CPU the wall clock
    /// measures, so a true frame is most of its wall time.
    pub cpu_adapter: bool,
    /// The last frame's raster proxy coverage (`FrameStats::proxy_share`,
    /// `FrameStats::scissor_share`).
    pub proxy_share: Option<f64>,
    pub scissor_share: Option<f64>,
    /// The last frame's share of tiles left out of the per-slice dispatches
    /// (`FrameStats::idle_tiles`).
    pub idle_tiles: Option<f64>,
    /// The last frame's dispatches of the whole-frame march and the invocations that
    /// ran out of the device's loop iterations (`FrameStats::march_parts`,
    /// `FrameStats::loop_limited`).
    pub march_parts: u32,
    pub loop_limited: u32,
    /// The last frame's slices per raster proxy polygon (`FrameStats::raster_group`).
    pub raster_group: u32,
}

impl Timing {
    /// The frame time to compare, with the clock's name: the median of the
    /// timestamps where the adapter has them and they are plausible, else the wall
    /// median. lavapipe's stamps are at times wrong: nearly equal around a compute frame
    /// of hundreds of milliseconds (seen after another renderer on the same device was
    /// dropped). A CPU adapter's frame runs on the CPU the wall clock measures, so its
    /// stamps must cover at least a quarter of the wall time; a GPU's, which can be far
    /// below its submit-and-wait, at least 1 %.
    pub fn frame_ms(&self) -> (f64, &'static str) {
        match self.gpu_ms {
            Some(g) if stamps_plausible(self.cpu_adapter, g.median, self.wall_ms.median) => {
                (g.median, "gpu")
            }
            _ => (self.wall_ms.median, "wall"),
        }
    }
}

/// Whether GPU timestamps of `gpu_ms` can be the work that took `wall_ms`: a CPU
/// adapter's work runs on the CPU the wall clock measures, so its stamps must cover at
/// least a quarter of the wall time; a GPU's, which can be far below its
/// submit-and-wait, at least 1 %.
pub fn stamps_plausible(cpu_adapter: bool, gpu_ms: f64, wall_ms: f64) -> bool {
    let least = if cpu_adapter { 0.25 } else { 0.01 };
    gpu_ms >= least * wall_ms
}

/// Renders `warmup` + `frames` frames and summarises the timed ones.
pub fn time_frames(
    r: &mut Renderer,
    s: &FrameSettings,
    warmup: u32,
    frames: u32,
) -> Result<Timing> {
    for _ in 0..warmup {
        r.render(s)?;
    }
    let (mut wall, mut gpu, mut cpu) = (Vec::new(), Vec::new(), Vec::new());
    let mut passes: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut slices = 0;
    let (mut proxy_share, mut scissor_share, mut idle_tiles) = (None, None, None);
    let (mut march_parts, mut loop_limited, mut raster_group) = (0, 0, 0);
    for _ in 0..frames.max(1) {
        let before = process_cpu_ms();
        let st = r.render(s)?;
        if let (Some(a), Some(b)) = (before, process_cpu_ms()) {
            cpu.push(b - a);
        }
        slices = st.slices;
        (proxy_share, scissor_share) = (st.proxy_share, st.scissor_share);
        idle_tiles = st.idle_tiles;
        (march_parts, loop_limited) = (st.march_parts, st.loop_limited);
        raster_group = st.raster_group;
        wall.push(st.wall_ms);
        gpu.extend(st.gpu_ms);
        for (name, ms) in st.gpu_passes {
            passes.entry(name).or_default().push(ms);
        }
    }
    Ok(Timing {
        cpu_adapter: r.gpu().info.device_type == wgpu::DeviceType::Cpu,
        frames: frames.max(1),
        warmup,
        slices,
        wall_ms: Summary::of(&wall).ok_or_else(|| anyhow!("no finite frame time"))?,
        gpu_ms: Summary::of(&gpu),
        cpu_ms: Summary::of(&cpu),
        passes: passes
            .into_iter()
            .filter_map(|(n, v)| Some((n, Summary::of(&v)?)))
            .collect(),
        proxy_share,
        scissor_share,
        idle_tiles,
        march_parts,
        loop_limited,
        raster_group,
    })
}

/// CPU time used so far by this process, all its threads (user + system), in
/// milliseconds (`CLOCK_PROCESS_CPUTIME_ID`); `None` where the platform lacks it.
pub fn process_cpu_ms() -> Option<f64> {
    #[cfg(unix)]
    {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `ts` is a valid, writable timespec for the call's duration.
        let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
        (rc == 0).then_some(ts.tv_sec as f64 * 1.0e3 + ts.tv_nsec as f64 * 1.0e-6)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Prints a timing in the format `bench/perf.py` and `bench/vtk_peer.py` parse.
pub fn print_timing(t: &Timing) {
    let line = |name: &str, s: &Summary| {
        println!(
            "{name} median {:.3} min {:.3} max {:.3}",
            s.median, s.min, s.max
        )
    };
    line("wall_ms", &t.wall_ms);
    match &t.gpu_ms {
        None => println!("gpu_ms unavailable (adapter lacks timestamp queries; wall time above)"),
        Some(g) => {
            line("gpu_ms", g);
            for (name, s) in &t.passes {
                line(&format!("pass {name}"), s);
            }
        }
    }
    if let Some(c) = &t.cpu_ms {
        line("cpu_ms", c);
    }
}

/// The document's background as linear [0,1] RGB for the metrics.
pub fn background(doc: &Document) -> [f64; 3] {
    std::array::from_fn(|i| doc.render.background[i] as f64)
}

/// The eye buffer composited over the document's background.
pub fn gpu_image(r: &Renderer, doc: &Document) -> Result<RgbImageF> {
    gpu_image_covered(r, doc).map(|(img, _)| img)
}

/// [`gpu_image`], and from the same read-back the share of its pixels that are not
/// transparent (α > 0.01): what a view covers, e.g. against a clipped view of it.
pub fn gpu_image_covered(r: &Renderer, doc: &Document) -> Result<(RgbImageF, f64)> {
    let (w, h, px) = r
        .read_pixels()
        .ok_or_else(|| anyhow!("nothing was rendered"))?;
    let covered = px.iter().filter(|p| p[3] > 0.01).count() as f64 / px.len().max(1) as f64;
    let img = RgbImageF::from_rgba_f32_premultiplied_over(&px, w, h, background(doc));
    Ok((img, covered))
}

/// Runs `f` with reference options whose progress counter drives a progress bar
/// (`rows` rows per pass; drawn only on a terminal).
fn with_progress<T>(message: &str, rows: Option<u64>, f: impl FnOnce(&ReferenceOptions) -> T) -> T {
    let progress = Arc::new(AtomicUsize::new(0));
    let opts = ReferenceOptions {
        progress: Some(progress.clone()),
        ..Default::default()
    };
    let bar = match rows {
        Some(n) => indicatif::ProgressBar::new(n),
        None => indicatif::ProgressBar::new_spinner(),
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} {bar:30} {pos} rows [{elapsed}]")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message(message.to_string());
    let done = AtomicBool::new(false);
    let out = std::thread::scope(|scope| {
        scope.spawn(|| {
            while !done.load(Ordering::Relaxed) {
                bar.set_position(progress.load(Ordering::Relaxed) as u64);
                std::thread::sleep(Duration::from_millis(100));
            }
        });
        let out = f(&opts);
        done.store(true, Ordering::Relaxed);
        out
    });
    bar.finish_and_clear();
    out
}

/// Settings of the converged reference for a frame: same camera and size, no early
/// termination (the reference approximates the full integral).
fn converged_settings(s: &FrameSettings) -> FrameSettings {
    FrameSettings {
        slice_spacing: reference::CONVERGED_START_SPACING,
        early_termination: None,
        ..*s
    }
}

/// The refined-slices converged reference of a document's frame.
fn converged_of(
    volume: &Volume,
    doc: &Document,
    s: &FrameSettings,
    tolerance: f64,
    o: &ReferenceOptions,
) -> Result<Converged> {
    let o = ReferenceOptions {
        inputs: headless::inputs_for(doc)?,
        ..o.clone()
    };
    Ok(reference::render_converged(
        volume,
        &doc.stack,
        &converged_settings(s),
        &o,
        tolerance,
        background(doc),
    )?)
}

/// The converged CPU reference of a document's scene, composited over its background.
pub fn converged_reference(
    volume: &Volume,
    doc: &Document,
    s: &FrameSettings,
    tolerance: f64,
) -> Result<(RgbImageF, Converged, f64)> {
    let start = Instant::now();
    let c = with_progress("converged reference", None, |o| {
        converged_of(volume, doc, s, tolerance, o)
    })?;
    let img = over(&c.image, doc);
    Ok((img, c, start.elapsed().as_secs_f64()))
}

/// The converged reference that an enabled plugin of the stack supplies itself
/// ([`vwb_render::plugin::ConvergedReference`]; directional occlusion's Monte-Carlo cone
/// integral, since refining its slices converges to the slice algorithm's own limit,
/// docs/dos.md), or `None` when the refined-slices reference is the converged one.
pub fn supplied_reference(doc: &Document) -> Option<Arc<dyn ConvergedReference>> {
    doc.stack
        .iter()
        .filter(|i| i.enabled)
        .find_map(|i| i.configured().converged_reference())
}

/// The converged reference of a frame, composited over the document's background, and
/// a JSON note of how it was made: the reference a plugin of the stack supplies
/// ([`supplied_reference`]), else the refined-slices reference (progress bar on a
/// terminal). `opts` carries cancellation (and, for a supplied reference, nothing else).
pub fn converged_image(
    volume: &Volume,
    doc: &Document,
    s: &FrameSettings,
    tolerance: f64,
    opts: &ReferenceOptions,
) -> Result<(RgbImageF, serde_json::Value)> {
    converged_image_by(volume, doc, supplied_reference(doc), s, tolerance, opts)
}

/// The reference a plugin of the stack supplies ([`supplied_reference`]) with named
/// options (an experiment's `reference_options`), `None` for the refined-slices
/// reference. Options for a stack whose reference is refined slices are an error:
/// that one takes only the tolerance.
pub fn configured_supplier(
    doc: &Document,
    options: &BTreeMap<String, f64>,
) -> Result<Option<Arc<dyn ConvergedReference>>> {
    match supplied_reference(doc) {
        Some(r) if options.is_empty() => Ok(Some(r)),
        Some(r) => r.with_options(options).map(Some).map_err(|e| anyhow!(e)),
        None if options.is_empty() => Ok(None),
        None => bail!(
            "reference options ({}) are for a reference a plugin supplies; this stack's \
             converged reference is refined slices, which takes only the tolerance",
            options.keys().cloned().collect::<Vec<_>>().join(", ")
        ),
    }
}

/// [`converged_image`] by a given supplied reference (the stack's, configured with
/// options: [`configured_supplier`]), or refined slices for `None`.
pub fn converged_image_by(
    volume: &Volume,
    doc: &Document,
    supplier: Option<Arc<dyn ConvergedReference>>,
    s: &FrameSettings,
    tolerance: f64,
    opts: &ReferenceOptions,
) -> Result<(RgbImageF, serde_json::Value)> {
    let start = Instant::now();
    if let Some(supplier) = supplier {
        let r = supplier
            .render(volume, &doc.stack, s, opts.cancel.as_deref())
            .map_err(|e| anyhow!(e))?;
        let mut info = serde_json::Map::new();
        info.insert("kind".into(), json!(supplier.kind()));
        for (k, v) in &r.notes {
            info.insert((*k).into(), json!(v));
        }
        info.insert("seconds".into(), json!(start.elapsed().as_secs_f64()));
        let img =
            RgbImageF::from_rgba_premultiplied_over(&r.pixels, r.width, r.height, background(doc));
        return Ok((img, serde_json::Value::Object(info)));
    }
    if needs_gpu_reference(doc) {
        return gpu_converged(volume, doc, s, tolerance, opts);
    }
    let c = if opts.cancel.is_some() || opts.progress.is_some() {
        converged_of(volume, doc, s, tolerance, opts)?
    } else {
        with_progress("converged reference", None, |o| {
            converged_of(volume, doc, s, tolerance, o)
        })?
    };
    let info = json!({
        "kind": "converged",
        "spacing_voxels": c.spacing,
        "converged": c.converged,
        "last_change_rms_delta_e": c.last_change_rms_delta_e,
        "tolerance_rms_delta_e": tolerance,
        "steps": c.steps,
        "seconds": start.elapsed().as_secs_f64(),
    });
    Ok((over(&c.image, doc), info))
}

/// Whether an enabled plugin of the stack has no CPU twin (a user plugin), so that its
/// converged reference comes from the GPU ([`gpu_converged`]).
pub fn needs_gpu_reference(doc: &Document) -> bool {
    doc.stack
        .iter()
        .filter(|i| i.enabled)
        .any(|i| i.configured().cpu_twin(&i.params).is_none())
}

/// The GPU converged reference, for stacks without CPU twins: the frame rendered into
/// an rgba32float eye buffer with no early termination, the slice spacing halved from
/// [`reference::CONVERGED_START_SPACING`] until one halving changes the image by less
/// than `tolerance` (RMS ΔE*uv) or the spacing reaches
/// [`reference::CONVERGED_MIN_SPACING`]. Its note says `"kind": "gpu-converged"`.
pub fn gpu_converged(
    volume: &Volume,
    doc: &Document,
    s: &FrameSettings,
    tolerance: f64,
    opts: &ReferenceOptions,
) -> Result<(RgbImageF, serde_json::Value)> {
    let start = Instant::now();
    let gpu = GpuContext::new_headless()?;
    let mut d = doc.clone();
    d.render.target = TargetFormat::Rgba32Float;
    d.render.early_termination = None;
    let mut r = headless::renderer_for(&gpu, &d, Arc::new(volume.clone()))?;
    let mut spacing = s.slice_spacing.min(reference::CONVERGED_START_SPACING) as f64;
    let finest = reference::CONVERGED_MIN_SPACING.min(spacing / 2.0);
    let render = |r: &mut Renderer, spacing: f64| -> Result<RgbImageF> {
        let fs = FrameSettings {
            slice_spacing: spacing as f32,
            early_termination: None,
            ..*s
        };
        r.render(&fs)?;
        gpu_image(r, &d)
    };
    let mut image = render(&mut r, spacing)?;
    let mut steps = Vec::new();
    let mut change = f64::INFINITY;
    while spacing / 2.0 >= finest * (1.0 - 1e-9) {
        if opts
            .cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
        {
            bail!("cancelled");
        }
        spacing /= 2.0;
        let next = match render(&mut r, spacing) {
            Ok(img) => img,
            // too many slices for the renderer: keep the finest image rendered
            Err(e) => {
                log::warn!(
                    "GPU converged reference stops at {} voxels: {e:#}",
                    spacing * 2.0
                );
                spacing *= 2.0;
                break;
            }
        };
        change = metrics::try_compare(&next, &image)
            .map_err(|e| anyhow!(e))?
            .rms_delta_e;
        steps.push((spacing, change));
        image = next;
        if change < tolerance {
            break;
        }
    }
    let info = json!({
        "kind": "gpu-converged",
        "note": "a plugin of the stack has no CPU twin: refined slices on the GPU, rgba32float",
        "adapter": gpu.describe(),
        "spacing_voxels": spacing,
        "converged": change < tolerance,
        "last_change_rms_delta_e": change,
        "tolerance_rms_delta_e": tolerance,
        "steps": steps,
        "seconds": start.elapsed().as_secs_f64(),
    });
    Ok((image, info))
}

fn over(img: &ReferenceImage, doc: &Document) -> RgbImageF {
    RgbImageF::from_rgba_premultiplied_over(&img.pixels, img.width, img.height, background(doc))
}

/// The build: the package version and the commit it was built from, e.g.
/// `0.1.0 (commit 1a2b3c4d5e6f)`, or the version alone where the source tree was no
/// git checkout (lab/build.rs).
pub fn build() -> String {
    match env!("VWB_BUILD_COMMIT") {
        "" => env!("CARGO_PKG_VERSION").to_string(),
        commit => format!("{} (commit {commit})", env!("CARGO_PKG_VERSION")),
    }
}

/// The build's commit (lab/build.rs), None where the source tree was no git checkout.
pub fn build_commit() -> Option<&'static str> {
    Some(env!("VWB_BUILD_COMMIT")).filter(|c| !c.is_empty())
}

/// CPU model and core count, for the docs.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{cpu}, {cores} cores")
}

/// What `vwb compare` compares against.
#[derive(Debug, Clone, PartialEq)]
pub enum Against {
    /// The CPU twin renderer with the same slices (fp16 accumulation emulated for an
    /// rgba16float target).
    Reference,
    /// The converged CPU reference.
    Converged,
    /// Another preset rendered on the GPU at the same size.
    Preset(PathBuf),
}

impl std::str::FromStr for Against {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Ok(match s {
            "reference" => Against::Reference,
            "converged" => Against::Converged,
            p if p.ends_with(".ron") => Against::Preset(PathBuf::from(p)),
            other => {
                return Err(format!(
                    "'{other}' is neither reference, converged nor a .ron preset"
                ));
            }
        })
    }
}

/// Everything `vwb compare` produces.
pub struct Comparison {
    pub ours: RgbImageF,
    pub theirs: RgbImageF,
    pub metrics: Metrics,
    pub timing: Timing,
    pub against: serde_json::Value,
}

/// Renders the document on the GPU and compares it with `against`.
pub fn compare_document(
    gpu: &GpuContext,
    doc: &Document,
    volume: Arc<Volume>,
    against: &Against,
    frames: u32,
    tolerance: f64,
) -> Result<Comparison> {
    let s = doc.frame_settings();
    let mut r = headless::renderer_for(gpu, doc, volume.clone())?;
    let timing = time_frames(&mut r, &s, 1, frames)?;
    let ours = gpu_image(&r, doc)?;
    let (theirs, info) = match against {
        Against::Reference => {
            let start = Instant::now();
            let (img, slices) = twin_render(&volume, doc, &s)?;
            let info = json!({
                "kind": "reference",
                "emulate_fp16": doc.render.target == TargetFormat::Rgba16Float,
                "slices": slices,
                "seconds": start.elapsed().as_secs_f64(),
            });
            (img, info)
        }
        Against::Converged => {
            let o = ReferenceOptions::default();
            let (img, info) = converged_image(&volume, doc, &s, tolerance, &o)?;
            (img, info)
        }
        Against::Preset(path) => {
            let mut other = crate::document::load_document(Some(path))?;
            other.render.size = doc.render.size;
            let v = headless::load_volume(&other.volume)?;
            let mut r2 = headless::renderer_for(gpu, &other, v)
                .with_context(|| format!("{}", path.display()))?;
            let t2 = time_frames(&mut r2, &other.frame_settings(), 1, frames)?;
            let info = json!({
                "kind": "preset",
                "preset": path,
                "timing": t2,
            });
            (gpu_image(&r2, &other)?, info)
        }
    };
    let metrics = metrics::try_compare(&ours, &theirs).map_err(|e| anyhow!(e))?;
    Ok(Comparison {
        ours,
        theirs,
        metrics,
        timing,
        against: info,
    })
}

/// The CPU twin's image of a frame with the GPU's slices (fp16 accumulation emulated
/// for an rgba16float target), composited over the document's background, and its
/// slice count; a progress bar on a terminal.
pub fn twin_render(volume: &Volume, doc: &Document, s: &FrameSettings) -> Result<(RgbImageF, u32)> {
    let emulate_fp16 = doc.render.target == TargetFormat::Rgba16Float;
    let inputs = headless::inputs_for(doc)?;
    let img = with_progress("reference", Some(s.height as u64), |o| {
        let o = ReferenceOptions {
            emulate_fp16,
            inputs,
            ..o.clone()
        };
        reference::render_reference(volume, &doc.stack, s, &o)
    })?;
    Ok((over(&img, doc), img.slices))
}

/// [`twin_render`]'s image.
pub fn twin_image(volume: &Volume, doc: &Document, s: &FrameSettings) -> Result<RgbImageF> {
    Ok(twin_render(volume, doc, s)?.0)
}

/// Writes JSON atomically.
pub fn save_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    vwb_render::preset::write_atomic(path, text.as_bytes())
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// Writes text atomically.
pub fn save_text(path: &Path, text: &str) -> Result<()> {
    vwb_render::preset::write_atomic(path, text.as_bytes())
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// Shared description of a frame for the JSON outputs.
pub fn frame_json(doc: &Document, t: &Timing, gpu: &GpuContext) -> serde_json::Value {
    let s = doc.frame_settings();
    json!({
        "adapter": gpu.describe(),
        "size": [s.width, s.height],
        "slices": t.slices,
        "slice_spacing_voxels": s.slice_spacing,
        "backend": s.backend.name(),
        "target": doc.render.target.wgsl(),
        "early_termination": s.early_termination,
        "background": background(doc),
        "plugins": doc.stack.iter().filter(|i| i.enabled).map(|i| i.plugin.id()).collect::<Vec<_>>(),
    })
}

/// `vwb compare`: both images, the heatmap and `metrics.json` into `dir`.
pub fn run_compare(
    preset: &Path,
    doc: &Document,
    against: &Against,
    dir: &Path,
    frames: u32,
    tolerance: f64,
) -> Result<Metrics> {
    let volume = headless::load_volume(&doc.volume)?;
    headless::preflight(Some(preset), doc, &volume)?;
    let gpu = GpuContext::new_headless()?;
    eprintln!("adapter: {}", gpu.describe());
    let c = compare_document(&gpu, doc, volume, against, frames, tolerance)?;
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let map = metrics::delta_e_map(&c.ours, &c.theirs);
    let heat = metrics::heatmap(&map, c.ours.width, c.ours.height, HEATMAP_DEFAULT_MAX);
    headless::save_png(&c.ours.to_rgb8(), &dir.join("image.png"))?;
    headless::save_png(&c.theirs.to_rgb8(), &dir.join("against.png"))?;
    headless::save_png(&heat, &dir.join("heatmap.png"))?;
    let report = json!({
        "preset": preset,
        "frame": frame_json(doc, &c.timing, &gpu),
        "timing_ms": c.timing,
        "against": c.against,
        "metrics": c.metrics,
        "convention": "CIE 1976 ΔE*uv per pixel (sRGB-encoded values → CIE XYZ → CIELUV, D65 white), both images composited over the preset's background; PSNR over sRGB channels (peak 1); SSIM of Rec.601 luma, 11×11 Gaussian σ=1.5",
        "heatmap_max_delta_e": HEATMAP_DEFAULT_MAX,
    });
    save_json(&dir.join("metrics.json"), &report)?;
    Ok(c.metrics)
}

/// One row of `vwb bench`'s CSV.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchRow {
    /// frame, pass, cold_pass, plugin, memory
    pub kind: &'static str,
    pub name: String,
    /// gpu or wall (empty for memory)
    pub clock: &'static str,
    pub frames: u32,
    pub ms: Option<Summary>,
    pub bytes: Option<u64>,
}

pub const BENCH_CSV_HEADER: &str = "kind,name,clock,frames,min_ms,median_ms,max_ms,bytes";

impl BenchRow {
    pub fn csv(&self) -> String {
        let f = |v: Option<f64>| v.map(|x| format!("{x:.4}")).unwrap_or_default();
        format!(
            "{},{},{},{},{},{},{},{}",
            self.kind,
            self.name,
            self.clock,
            self.frames,
            f(self.ms.map(|s| s.min)),
            f(self.ms.map(|s| s.median)),
            f(self.ms.map(|s| s.max)),
            self.bytes.map(|b| b.to_string()).unwrap_or_default()
        )
    }
}

/// Per-pass and per-plugin timings and GPU memory of a document.
///
/// Per plugin: the pre-passes have their own timestamps (`cold_pass prepass <id>`, from
/// the first frame, since pre-passes rerun only when their inputs change); the hooks
/// run inside the one composed slice shader, so their cost is measured by ablation:
/// the frame time with the instance enabled minus the frame time with it disabled
/// (`plugin` rows; median of each, so the figure can be slightly negative for a plugin
/// that costs nothing measurable).
pub fn bench_document(
    gpu: &GpuContext,
    doc: &Document,
    volume: Arc<Volume>,
    warmup: u32,
    frames: u32,
) -> Result<Vec<BenchRow>> {
    let s = doc.frame_settings();
    let mut r = headless::renderer_for(gpu, doc, volume)?;
    let cold = r.render(&s)?;
    let full = time_frames(&mut r, &s, warmup, frames)?;
    let (full_ms, clock) = full.frame_ms();
    let mut rows = vec![BenchRow {
        kind: "frame",
        name: "frame".into(),
        clock,
        frames: full.frames,
        ms: Some(full.gpu_ms.unwrap_or(full.wall_ms)),
        bytes: None,
    }];
    if full.gpu_ms.is_some() {
        rows.push(BenchRow {
            kind: "frame",
            name: "frame".into(),
            clock: "wall",
            frames: full.frames,
            ms: Some(full.wall_ms),
            bytes: None,
        });
    }
    if let Some(cpu) = full.cpu_ms {
        rows.push(BenchRow {
            kind: "frame",
            name: "frame".into(),
            clock: "cpu",
            frames: full.frames,
            ms: Some(cpu),
            bytes: None,
        });
    }
    for (name, ms) in &full.passes {
        rows.push(BenchRow {
            kind: "pass",
            name: name.clone(),
            clock: "gpu",
            frames: full.frames,
            ms: Some(*ms),
            bytes: None,
        });
    }
    // the first frame runs the pre-passes; lavapipe's timestamps do not bracket them
    // reliably, so its wall time is reported too (pre-pass ≈ cold − warm wall)
    rows.push(BenchRow {
        kind: "cold_frame",
        name: "frame".into(),
        clock: "wall",
        frames: 1,
        ms: Summary::of(&[cold.wall_ms]),
        bytes: None,
    });
    for (name, ms) in &cold.gpu_passes {
        rows.push(BenchRow {
            kind: "cold_pass",
            name: name.clone(),
            clock: "gpu",
            frames: 1,
            ms: Summary::of(&[*ms]),
            bytes: None,
        });
    }
    for (i, inst) in doc.stack.iter().enumerate() {
        if !inst.enabled {
            continue;
        }
        let mut stack = doc.stack.clone();
        stack[i].enabled = false;
        r.update_stack(&stack, doc.render.target)?;
        let without = time_frames(&mut r, &s, warmup, frames)?;
        let (ms, _) = without.frame_ms();
        let (marginal, note) = plugin_cost(full_ms, ms);
        if let Some(note) = note {
            eprintln!("note: {}#{i}: {note}", inst.plugin.id());
        }
        rows.push(BenchRow {
            kind: "plugin",
            name: format!("{}#{i}", inst.plugin.id()),
            clock,
            frames: full.frames,
            ms: Summary::of(&[marginal]),
            bytes: None,
        });
    }
    r.update_stack(&doc.stack, doc.render.target)?;
    r.render(&s)?;
    let held = r
        .disabled_memory()
        .into_iter()
        .map(|m| ("memory_disabled", m));
    for (kind, (uid, id, bytes)) in r
        .plugin_memory()
        .into_iter()
        .map(|m| ("memory", m))
        .chain(held)
    {
        let index = doc.stack.iter().position(|i| i.uid == uid).unwrap_or(0);
        rows.push(BenchRow {
            kind,
            name: format!("{id}#{index}"),
            clock: "",
            frames: 0,
            ms: None,
            bytes: Some(bytes),
        });
    }
    Ok(rows)
}

/// A plugin's cost by ablation: the frame time with it minus the time without,
/// clamped at 0 with a note when timing noise makes the difference negative (a plugin
/// cannot make a frame faster by running).
pub fn plugin_cost(with_ms: f64, without_ms: f64) -> (f64, Option<String>) {
    let d = with_ms - without_ms;
    if d >= 0.0 {
        (d, None)
    } else {
        (
            0.0,
            Some(format!(
                "the frame took {without_ms:.3} ms without the plugin and {with_ms:.3} ms with \
                 it: its cost is below the timing noise ({d:.3} ms), reported as 0"
            )),
        )
    }
}

/// A sweep axis: what varies and its values.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// As given: `render.slice_spacing` or `<plugin id>.<key>`.
    pub name: String,
    pub target: AxisTarget,
    pub values: Vec<f64>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum AxisTarget {
    Spacing,
    /// The image: `render.size`, a side (the frame is side × side pixels).
    Size,
    /// The camera: `camera.yaw_deg`, `camera.pitch_deg` or `camera.distance`.
    Camera(CameraKey),
    /// A float or int parameter of the first instance of a plugin in the stack.
    Param {
        index: usize,
        key: String,
        int: bool,
    },
}

impl AxisTarget {
    /// Whether the axis changes the converged reference.
    fn changes_reference(&self) -> bool {
        matches!(
            self,
            AxisTarget::Param { .. } | AxisTarget::Camera(_) | AxisTarget::Size
        )
    }
}

/// A camera value a grid axis or an experiment variant sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraKey {
    YawDeg,
    PitchDeg,
    Distance,
    /// The vertical field of view of a perspective camera.
    FovYDeg,
}

impl CameraKey {
    /// `camera.yaw_deg`, `camera.pitch_deg`, `camera.distance` or `camera.fov_y_deg`.
    pub fn parse(name: &str) -> Option<CameraKey> {
        match name {
            "camera.yaw_deg" => Some(CameraKey::YawDeg),
            "camera.pitch_deg" => Some(CameraKey::PitchDeg),
            "camera.distance" => Some(CameraKey::Distance),
            "camera.fov_y_deg" => Some(CameraKey::FovYDeg),
            _ => None,
        }
    }

    /// Sets the value on a document's camera, after checking it (finite; a positive
    /// distance; a pitch within ±90°; a field of view in [1°, 170°] on a perspective
    /// camera: the camera's own limits).
    pub fn set(self, doc: &mut Document, v: f64) -> Result<()> {
        let ok = v.is_finite()
            && match self {
                CameraKey::YawDeg => true,
                CameraKey::PitchDeg => v.abs() <= 90.0,
                CameraKey::Distance => v > 0.0,
                CameraKey::FovYDeg => (1.0..=170.0).contains(&v),
            };
        if !ok {
            bail!(
                "{self:?}: {v} is outside the camera's range (finite; distance > 0; |pitch| ≤ 90°; field of view 1–170°)"
            );
        }
        let c = &mut doc.camera;
        match self {
            CameraKey::YawDeg => c.yaw_deg = v as f32,
            CameraKey::PitchDeg => c.pitch_deg = v as f32,
            CameraKey::Distance => c.distance = v as f32,
            CameraKey::FovYDeg => match &mut c.projection {
                Projection::Perspective { fov_y_deg } => *fov_y_deg = v as f32,
                Projection::Orthographic { .. } => {
                    bail!("{self:?}: the scene's camera is orthographic; it has no field of view")
                }
            },
        }
        Ok(())
    }
}

/// Values of `A..B:N` (N evenly spaced, `:log` for geometric spacing) or `a,b,c`.
pub fn parse_values(s: &str) -> Result<Vec<f64>, String> {
    let num = |v: &str| {
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("'{v}' is not a finite number"))
    };
    if let Some((a, rest)) = s.split_once("..") {
        let mut parts = rest.split(':');
        let b = num(parts.next().unwrap_or(""))?;
        let n: usize = parts
            .next()
            .ok_or_else(|| format!("'{s}': expected A..B:N"))?
            .trim()
            .parse()
            .ok()
            .filter(|n| (1..=10_000).contains(n))
            .ok_or_else(|| format!("'{s}': N must be an integer in 1..=10000"))?;
        let log = match parts.next() {
            None => false,
            Some("log") => true,
            Some(other) => return Err(format!("'{s}': unknown scale '{other}' (only log)")),
        };
        let a = num(a)?;
        if log && (a <= 0.0 || b <= 0.0) {
            return Err(format!("'{s}': a log range needs positive ends"));
        }
        // 12 significant digits, so that 0.25..4:5:log gives 1 rather than 0.9999999999999999
        let tidy = |x: f64| format!("{x:.11e}").parse::<f64>().unwrap_or(x);
        Ok((0..n)
            .map(|i| {
                let t = if n == 1 {
                    0.0
                } else {
                    i as f64 / (n - 1) as f64
                };
                tidy(if log {
                    a * (b / a).powf(t)
                } else {
                    a + (b - a) * t
                })
            })
            .collect())
    } else {
        s.split(',').map(num).collect()
    }
}

/// Parses `--param name=values` against a document.
pub fn parse_axis(spec: &str, doc: &Document) -> Result<Axis> {
    let (name, values) = spec
        .split_once('=')
        .ok_or_else(|| anyhow!("--param '{spec}': expected name=A..B:N"))?;
    let name = name.trim();
    let values = parse_values(values).map_err(|e| anyhow!("--param {name}: {e}"))?;
    axis_for(name, values, doc).map_err(|e| anyhow!("--param {e}"))
}

/// The axis that varies `name` (`render.slice_spacing` or `<plugin id>.<key>`, a float
/// or int parameter of the plugin's first instance) over `values`, checked against the
/// document; errors start with the name.
pub fn axis_for(name: &str, values: Vec<f64>, doc: &Document) -> Result<Axis> {
    let target = if name == "render.slice_spacing" {
        if let Some(v) = values.iter().find(|v| **v <= 0.0) {
            bail!("{name}: slice spacing must be > 0, got {v}");
        }
        AxisTarget::Spacing
    } else if name == "render.size" {
        if let Some(v) = values
            .iter()
            .find(|v| v.fract() != 0.0 || !(1.0..=16384.0).contains(*v))
        {
            bail!("{name}: an image side is a whole number of pixels in 1..=16384, got {v}");
        }
        AxisTarget::Size
    } else if let Some(key) = CameraKey::parse(name) {
        for v in &values {
            key.set(&mut doc.clone(), *v)
                .map_err(|e| anyhow!("{name}: {e}"))?;
        }
        AxisTarget::Camera(key)
    } else {
        let (id, key) = name
            .rsplit_once('.')
            .ok_or_else(|| {
                anyhow!("{name}: expected render.slice_spacing, camera.yaw_deg, camera.pitch_deg, camera.distance, camera.fov_y_deg or <plugin id>.<key>")
            })?;
        let index = doc
            .stack
            .iter()
            .position(|i| i.plugin.id() == id)
            .ok_or_else(|| anyhow!("{name}: the preset has no plugin '{id}'"))?;
        let specs = doc.stack[index].plugin.params();
        let spec = specs
            .iter()
            .find(|p| p.key == key)
            .ok_or_else(|| anyhow!("{name}: plugin '{id}' has no parameter '{key}'"))?;
        let int = match spec.kind {
            ParamKind::Float { .. } => false,
            ParamKind::Int { .. } => true,
            _ => bail!(
                "{name}: only float and int parameters can be swept ('{key}' is {})",
                spec.kind_name()
            ),
        };
        for v in &values {
            let value = if int {
                ParamValue::Int(v.round() as i32)
            } else {
                ParamValue::Float(*v as f32)
            };
            spec.check(&value).map_err(|e| anyhow!("{name}: {e}"))?;
        }
        AxisTarget::Param {
            index,
            key: key.to_string(),
            int,
        }
    };
    Ok(Axis {
        name: name.to_string(),
        target,
        values,
    })
}

/// Applies one value of an axis to a document.
pub fn apply_axis(doc: &mut Document, axis: &Axis, v: f64) {
    match &axis.target {
        AxisTarget::Spacing => doc.render.slice_spacing = v as f32,
        AxisTarget::Size => doc.render.size = [v as u32; 2],
        // checked by axis_for
        AxisTarget::Camera(key) => key.set(doc, v).expect("checked when the axis was made"),
        AxisTarget::Param { index, key, int } => {
            let value = if *int {
                ParamValue::Int(v.round() as i32)
            } else {
                ParamValue::Float(v as f32)
            };
            doc.stack[*index].params.set(key, value);
        }
    }
}

/// The cartesian product of the axes' values, first axis slowest.
pub fn grid(axes: &[Axis]) -> Vec<Vec<f64>> {
    axes.iter().fold(vec![Vec::new()], |acc, axis| {
        acc.iter()
            .flat_map(|p| {
                axis.values.iter().map(move |v| {
                    let mut q = p.clone();
                    q.push(*v);
                    q
                })
            })
            .collect()
    })
}

/// Marks the points (time, error) no other point beats in both (lower is better);
/// among equal points the first is on the front.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<bool> {
    points
        .iter()
        .enumerate()
        .map(|(i, &(t, e))| {
            t.is_finite()
                && e.is_finite()
                && !points
                    .iter()
                    .enumerate()
                    .any(|(j, &(u, f))| j != i && u <= t && f <= e && (u < t || f < e || j < i))
        })
        .collect()
}

/// One point of a sweep.
#[derive(Debug, Clone, Serialize)]
pub struct SweepPoint {
    pub values: Vec<f64>,
    pub slices: u32,
    pub ms: f64,
    pub clock: &'static str,
    pub wall_ms: f64,
    pub metrics: Metrics,
    pub image: String,
    pub pareto: bool,
}

/// Nice tick values covering [lo, hi].
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = (hi - lo).max(1e-12);
    let raw = span / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() * step;
    (0..)
        .map(|i| first + i as f64 * step)
        .take_while(|v| *v <= hi + step * 1e-9)
        .collect()
}

/// The Pareto plot as SVG: GPU (or wall) ms against RMS ΔE*uv, every point labelled
/// with its axis values, the front drawn as a red staircase.
pub fn pareto_svg(title: &str, axes: &[Axis], points: &[SweepPoint]) -> String {
    pareto_svg_labelled(title, None, axes, points)
}

/// [`pareto_svg`] with its own axis labels (x, y): a probe's time and error figures,
/// carried in each point's `ms` and `metrics.rms_delta_e`.
pub fn pareto_svg_labelled(
    title: &str,
    labels: Option<(&str, &str)>,
    axes: &[Axis],
    points: &[SweepPoint],
) -> String {
    let (w, h) = (720.0, 480.0);
    let (l, r, t, b) = (70.0, 20.0, 40.0, 55.0);
    let finite: Vec<&SweepPoint> = points
        .iter()
        .filter(|p| p.ms.is_finite() && p.metrics.rms_delta_e.is_finite())
        .collect();
    let max_of = |f: &dyn Fn(&SweepPoint) -> f64| finite.iter().map(|p| f(p)).fold(0.0, f64::max);
    let xmax = max_of(&|p| p.ms).max(1e-6) * 1.08;
    let ymax = max_of(&|p| p.metrics.rms_delta_e).max(1e-6) * 1.08;
    let x = |v: f64| l + v / xmax * (w - l - r);
    let y = |v: f64| h - b - v / ymax * (h - t - b);
    let clock = points.first().map_or("gpu", |p| p.clock);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="11">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="22" text-anchor="middle" font-size="14">{}</text>"#,
        w / 2.0,
        escape(title)
    );
    for v in ticks(0.0, xmax) {
        let _ = writeln!(
            s,
            r##"<line x1="{0}" y1="{1}" x2="{0}" y2="{2}" stroke="#ddd"/><text x="{0}" y="{3}" text-anchor="middle">{4}</text>"##,
            x(v),
            t,
            h - b,
            h - b + 15.0,
            trim_num(v)
        );
    }
    for v in ticks(0.0, ymax) {
        let _ = writeln!(
            s,
            r##"<line x1="{0}" y1="{1}" x2="{2}" y2="{1}" stroke="#ddd"/><text x="{3}" y="{4}" text-anchor="end">{5}</text>"##,
            l,
            y(v),
            w - r,
            l - 6.0,
            y(v) + 4.0,
            trim_num(v)
        );
    }
    let _ = writeln!(
        s,
        r##"<line x1="{l}" y1="{0}" x2="{1}" y2="{0}" stroke="black"/><line x1="{l}" y1="{t}" x2="{l}" y2="{0}" stroke="black"/>"##,
        h - b,
        w - r
    );
    // `update`: an experiment's `pareto_time: update_ms`
    let xlabel = if let Some((x, _)) = labels {
        x.to_string()
    } else if clock == "update" {
        "update time (the first frame after a change less a frame), wall ms".to_string()
    } else {
        format!("frame time, {clock} ms (median)")
    };
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
        (l + w - r) / 2.0,
        h - 15.0,
        escape(&xlabel)
    );
    let _ = writeln!(
        s,
        r#"<text transform="translate(18 {}) rotate(-90)" text-anchor="middle">{}</text>"#,
        (t + h - b) / 2.0,
        escape(labels.map_or("RMS ΔE*uv against the converged reference", |(_, y)| y))
    );
    let mut front: Vec<&SweepPoint> = finite.iter().copied().filter(|p| p.pareto).collect();
    front.sort_by(|p, q| p.ms.total_cmp(&q.ms));
    if !front.is_empty() {
        let mut d = format!(
            "M{:.1},{:.1}",
            x(front[0].ms),
            y(front[0].metrics.rms_delta_e)
        );
        for pair in front.windows(2) {
            let _ = write!(
                d,
                " L{:.1},{:.1} L{:.1},{:.1}",
                x(pair[1].ms),
                y(pair[0].metrics.rms_delta_e),
                x(pair[1].ms),
                y(pair[1].metrics.rms_delta_e)
            );
        }
        let _ = writeln!(
            s,
            r##"<path d="{d}" fill="none" stroke="#d62728" stroke-width="1.5"/>"##
        );
    }
    for p in &finite {
        let label: Vec<String> = axes
            .iter()
            .zip(&p.values)
            .map(|(a, v)| format!("{}={}", short(&a.name), trim_num(*v)))
            .collect();
        let (fill, r) = if p.pareto {
            ("#d62728", 4.5)
        } else {
            ("#1f77b4", 3.5)
        };
        let right = x(p.ms) > 0.8 * w;
        let (lx, anchor) = if right {
            (x(p.ms) - 6.0, "end")
        } else {
            (x(p.ms) + 6.0, "start")
        };
        let _ = writeln!(
            s,
            r#"<circle cx="{:.1}" cy="{:.1}" r="{r}" fill="{fill}"><title>{}</title></circle><text x="{lx:.1}" y="{:.1}" font-size="9" fill="{fill}" text-anchor="{anchor}">{}</text>"#,
            x(p.ms),
            y(p.metrics.rms_delta_e),
            escape(&format!(
                "{} → {:.3} ms, ΔE RMS {:.3}",
                label.join(", "),
                p.ms,
                p.metrics.rms_delta_e
            )),
            y(p.metrics.rms_delta_e) - 4.0,
            escape(&label.join(" "))
        );
    }
    let _ = writeln!(
        s,
        r##"<circle cx="{0}" cy="{1}" r="4.5" fill="#d62728"/><text x="{2}" y="{3}">Pareto front</text><circle cx="{0}" cy="{4}" r="3.5" fill="#1f77b4"/><text x="{2}" y="{5}">dominated</text>"##,
        w - r - 110.0,
        t + 8.0,
        w - r - 100.0,
        t + 12.0,
        t + 24.0,
        t + 28.0
    );
    s.push_str("</svg>\n");
    s
}

fn short(name: &str) -> &str {
    name.rsplit('.').next().unwrap_or(name)
}

fn trim_num(v: f64) -> String {
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// What a running sweep reports.
pub enum SweepEvent<'a> {
    /// A reference is being computed for these plugin parameters.
    Reference { key: &'a str },
    /// Grid point `index` of `total` is done.
    Point {
        index: usize,
        total: usize,
        point: &'a SweepPoint,
    },
}

/// A finished sweep: the points (Pareto flags set), their GPU images and the
/// references with a JSON note each.
pub struct SweepOutcome {
    pub points: Vec<SweepPoint>,
    pub images: Vec<RgbImageF>,
    pub references: Vec<(RgbImageF, serde_json::Value)>,
}

/// Every grid point rendered on the GPU, timed, and compared with the converged
/// reference of its parameters ([`converged_image`]: one per distinct plugin-parameter
/// point; slice spacing does not change it). `opts.cancel` stops it between steps.
/// Shared by `vwb sweep` and the window's trade-off view.
#[allow(clippy::too_many_arguments)]
pub fn sweep(
    gpu: &GpuContext,
    doc: &Document,
    volume: Arc<Volume>,
    axes: &[Axis],
    frames: u32,
    tolerance: f64,
    opts: &ReferenceOptions,
    observer: &mut dyn FnMut(SweepEvent<'_>),
) -> Result<SweepOutcome> {
    if axes.is_empty() {
        bail!("a sweep needs at least one parameter");
    }
    let cancelled = || {
        opts.cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
    };
    let points = grid(axes);
    let mut r = headless::renderer_for(gpu, doc, volume.clone())?;
    let mut references: HashMap<String, usize> = HashMap::new();
    let mut out = SweepOutcome {
        points: Vec::new(),
        images: Vec::new(),
        references: Vec::new(),
    };
    for (n, values) in points.iter().enumerate() {
        if cancelled() {
            bail!("cancelled");
        }
        let mut d = doc.clone();
        for (axis, v) in axes.iter().zip(values) {
            apply_axis(&mut d, axis, *v);
        }
        let key = axes
            .iter()
            .zip(values)
            .filter(|(a, _)| a.target.changes_reference())
            .map(|(a, v)| format!("{}={v}", a.name))
            .collect::<Vec<_>>()
            .join(",");
        let s = d.frame_settings();
        if !references.contains_key(&key) {
            observer(SweepEvent::Reference { key: &key });
            let (img, mut info) = converged_image(&volume, &d, &s, tolerance, opts)?;
            if info["converged"] == json!(false) {
                log::warn!(
                    "the reference for '{key}' did not converge (last change {} ΔE RMS at {} voxels)",
                    info["last_change_rms_delta_e"],
                    info["spacing_voxels"]
                );
            }
            info["index"] = json!(out.references.len());
            info["params"] = json!(key);
            references.insert(key.clone(), out.references.len());
            out.references.push((img, info));
        }
        r.update_stack(&d.stack, d.render.target)?;
        let timing = time_frames(&mut r, &s, 1, frames)?;
        let img = gpu_image(&r, &d)?;
        let reference = &out.references[references[&key]].0;
        let metrics = metrics::try_compare(&img, reference).map_err(|e| anyhow!(e))?;
        let (ms, clock) = timing.frame_ms();
        out.points.push(SweepPoint {
            values: values.clone(),
            slices: timing.slices,
            ms,
            clock,
            wall_ms: timing.wall_ms.median,
            metrics,
            image: format!("point_{n:03}.png"),
            pareto: false,
        });
        out.images.push(img);
        observer(SweepEvent::Point {
            index: n,
            total: points.len(),
            point: out.points.last().expect("just pushed"),
        });
    }
    let front = pareto_front(
        &out.points
            .iter()
            .map(|p| (p.ms, p.metrics.rms_delta_e))
            .collect::<Vec<_>>(),
    );
    for (p, f) in out.points.iter_mut().zip(front) {
        p.pareto = f;
    }
    Ok(out)
}

/// Runs a sweep ([`sweep`]) and writes `sweep.csv`, `point_NNN.png`,
/// `reference_NN.png`, `pareto.svg` and `sweep.json` into `dir`.
pub fn run_sweep(
    doc: &Document,
    axes: &[Axis],
    dir: &Path,
    frames: u32,
    tolerance: f64,
) -> Result<Vec<SweepPoint>> {
    if axes.is_empty() {
        bail!("vwb sweep needs at least one --param");
    }
    let volume = headless::load_volume(&doc.volume)?;
    let gpu = GpuContext::new_headless()?;
    eprintln!("adapter: {}", gpu.describe());
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let bar = indicatif::ProgressBar::new(grid(axes).len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "sweep {bar:30} {pos}/{len} [{elapsed}<{eta}] {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let outcome = sweep(
        &gpu,
        doc,
        volume,
        axes,
        frames,
        tolerance,
        &ReferenceOptions::default(),
        &mut |e| match e {
            SweepEvent::Reference { key } => bar.set_message(format!("reference {key}")),
            SweepEvent::Point { point, .. } => {
                bar.set_message(
                    axes.iter()
                        .zip(&point.values)
                        .map(|(a, v)| format!("{}={}", short(&a.name), trim_num(*v)))
                        .collect::<Vec<_>>()
                        .join(" "),
                );
                bar.inc(1);
            }
        },
    )?;
    bar.finish_and_clear();
    for (img, info) in &outcome.references {
        let idx = info["index"].as_u64().unwrap_or(0);
        headless::save_png(&img.to_rgb8(), &dir.join(format!("reference_{idx:02}.png")))?;
    }
    for (p, img) in outcome.points.iter().zip(&outcome.images) {
        headless::save_png(&img.to_rgb8(), &dir.join(&p.image))?;
    }
    let reference_notes: Vec<serde_json::Value> =
        outcome.references.iter().map(|(_, i)| i.clone()).collect();
    let out = outcome.points;
    let mut csv = String::new();
    for a in axes {
        let _ = write!(csv, "{},", a.name);
    }
    csv.push_str("slices,clock,frame_ms,wall_ms,rms_delta_e,mean_delta_e,max_delta_e,share_above_6,psnr_db,ssim,pareto,image\n");
    for p in &out {
        for v in &p.values {
            let _ = write!(csv, "{v},");
        }
        let m = &p.metrics;
        let _ = writeln!(
            csv,
            "{},{},{:.4},{:.4},{:.5},{:.5},{:.4},{:.6},{:.3},{:.6},{},{}",
            p.slices,
            p.clock,
            p.ms,
            p.wall_ms,
            m.rms_delta_e,
            m.mean_delta_e,
            m.max_delta_e,
            m.share_above_6,
            m.psnr_db,
            m.ssim,
            p.pareto,
            p.image
        );
    }
    save_text(&dir.join("sweep.csv"), &csv)?;
    let title = format!(
        "{} — {} ({}x{})",
        doc.description,
        axes.iter()
            .map(|a| a.name.as_str())
            .collect::<Vec<_>>()
            .join(" × "),
        doc.render.size[0],
        doc.render.size[1]
    );
    save_text(&dir.join("pareto.svg"), &pareto_svg(&title, axes, &out))?;
    save_json(
        &dir.join("sweep.json"),
        &json!({
            "adapter": gpu.describe(),
            "axes": axes.iter().map(|a| json!({"name": a.name, "values": a.values})).collect::<Vec<_>>(),
            "references": reference_notes,
            "points": out,
        }),
    )?;
    Ok(out)
}

/// The scene as JSON for peer renderers: volume, camera in vwb world space (the box
/// centred at the origin, longest side 1), the classification of the stack's CPU
/// twins sampled at 256 normalised values, slice spacing, size and background.
pub fn scene_json(doc: &Document, volume: &Volume, preset: &Path) -> serde_json::Value {
    let s = doc.frame_settings();
    let view = s.camera.view(s.width as f32 / s.height as f32);
    let vbox = VolumeBox::new(volume.dims, volume.spacing);
    let twins: Option<Vec<_>> = doc
        .stack
        .iter()
        .filter(|i| i.enabled)
        .map(|i| i.configured().cpu_twin(&i.params))
        .collect();
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(volume, &scalars).with_spacing(s.slice_spacing as f64);
    let lut = twins.map(|mut twins| {
        for t in &mut twins {
            t.prepare(&ctx);
        }
        (0..256)
            .map(|i| {
                let v = i as f64 / 255.0;
                let mut sample = CpuSample {
                    value: v,
                    color: glam::DVec4::splat(v),
                    ..Default::default()
                };
                for t in &twins {
                    t.classify(&ctx, &mut sample);
                }
                sample.color.to_array().map(|c| c.clamp(0.0, 1.0))
            })
            .collect::<Vec<_>>()
    });
    let (path, demo_path) = match &doc.volume {
        VolumeSource::Demo => (None, Some(vwb_render::volume::DEMO_SOURCE_PATH)),
        VolumeSource::File(p) => (Some(std::fs::canonicalize(p).unwrap_or(p.clone())), None),
        VolumeSource::Sample(name) => (
            vwb_render::samples::resolve(name)
                .ok()
                .map(|p| std::fs::canonicalize(&p).unwrap_or(p)),
            None,
        ),
        VolumeSource::Analytic(_) | VolumeSource::Phantom(_) | VolumeSource::Resampled(_) => {
            (None, None)
        }
    };
    // Blinn–Phong material of an enabled shade.blinn_phong (for peers' shading)
    let shading = doc
        .stack
        .iter()
        .find(|i| i.enabled && i.plugin.id() == "shade.blinn_phong")
        .map(|i| {
            let f = |k: &str| i.params.float(k);
            json!({
                "model": "blinn_phong", "ka": f("ka"), "kd": f("kd"), "ks": f("ks"),
                "shininess": f("shininess"),
            })
        });
    let (fov, height) = match s.camera.projection {
        Projection::Perspective { fov_y_deg } => (Some(fov_y_deg), None),
        Projection::Orthographic { height } => (None, Some(height)),
    };
    json!({
        "preset": preset,
        "volume": {
            "path": path, "demo_path": demo_path, "dims": volume.dims,
            "spacing": volume.spacing, "components": volume.components, "range": volume.range,
            "box_min": vbox.min.to_array(), "box_max": vbox.max.to_array(),
        },
        "image": {"width": s.width, "height": s.height},
        "background": background(doc),
        "camera": {
            "eye": view.eye.to_array(), "target": s.camera.target(), "up": view.up.to_array(),
            "projection": if view.perspective { "perspective" } else { "orthographic" },
            "fov_y_deg": fov, "ortho_height": height, "near": view.near, "far": view.far,
        },
        "slice_spacing_voxels": s.slice_spacing,
        "backend": s.backend.name(),
        "tf": lut.map(|l| json!({"lut": l, "domain": "normalized"})),
        "shading": shading,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn implausible_timestamps_fall_back_to_the_wall_clock() {
        let timing = |gpu: f64, wall: f64| Timing {
            cpu_adapter: false,
            frames: 3,
            warmup: 1,
            slices: 10,
            wall_ms: Summary::of(&[wall]).unwrap(),
            gpu_ms: Summary::of(&[gpu]),
            cpu_ms: None,
            passes: Vec::new(),
            proxy_share: None,
            scissor_share: None,
            idle_tiles: None,
            march_parts: 1,
            loop_limited: 0,
            raster_group: 0,
        };
        // a GPU frame well below its submit-and-wait is the GPU's
        assert_eq!(timing(0.29, 2.0).frame_ms(), (0.29, "gpu"));
        // 0.03 ms stamped around an 800 ms frame is not
        assert_eq!(timing(0.03, 800.0).frame_ms(), (800.0, "wall"));
        assert_eq!(timing(f64::NAN, 5.0).frame_ms(), (5.0, "wall"));
        // a CPU adapter's frame is most of its wall time
        let cpu = |gpu, wall| Timing {
            cpu_adapter: true,
            ..timing(gpu, wall)
        };
        assert_eq!(cpu(0.29, 2.0).frame_ms(), (2.0, "wall"));
        assert_eq!(cpu(1.8, 2.0).frame_ms(), (1.8, "gpu"));
    }

    #[cfg(unix)]
    #[test]
    fn the_process_cpu_clock_counts_work() {
        let start = process_cpu_ms().expect("CLOCK_PROCESS_CPUTIME_ID");
        let wall = std::time::Instant::now();
        let mut x = 0u64;
        // work until the clock has counted 20 ms (or 10 s of wall time have passed)
        while process_cpu_ms().unwrap() - start < 20.0 && wall.elapsed().as_secs() < 10 {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
        let used = process_cpu_ms().unwrap() - start;
        assert!(
            used >= 20.0,
            "{used} ms of CPU time after {:?}",
            wall.elapsed()
        );
        // (whether a sleeping thread adds none cannot be asserted here: the clock counts
        // every thread of the process, and the harness runs other tests beside this one)
        let (a, b) = (process_cpu_ms().unwrap(), process_cpu_ms().unwrap());
        assert!(b >= a, "monotonic: {a} then {b}");
    }

    #[test]
    fn plugin_cost_is_never_negative() {
        assert_eq!(plugin_cost(3.0, 2.5), (0.5, None));
        let (ms, note) = plugin_cost(2.0, 2.2);
        assert_eq!(ms, 0.0);
        assert!(note.unwrap().contains("below the timing noise"));
    }

    #[test]
    fn values_ranges_and_lists() {
        assert_eq!(parse_values("0..1:3").unwrap(), vec![0.0, 0.5, 1.0]);
        assert_eq!(
            parse_values("0.25..4:5:log").unwrap(),
            vec![0.25, 0.5, 1.0, 2.0, 4.0]
        );
        assert_eq!(parse_values("2..2:1").unwrap(), vec![2.0]);
        assert_eq!(parse_values("1, 2,3").unwrap(), vec![1.0, 2.0, 3.0]);
        for bad in [
            "0..1",
            "0..1:0",
            "0..1:x",
            "0..1:3:lin",
            "0..1:3:log",
            "a,b",
            "nan",
            "1..inf:2",
        ] {
            assert!(parse_values(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn grid_is_the_cartesian_product() {
        let axis = |values: Vec<f64>| Axis {
            name: "x".into(),
            target: AxisTarget::Spacing,
            values,
        };
        let g = grid(&[axis(vec![1.0, 2.0]), axis(vec![3.0, 4.0, 5.0])]);
        assert_eq!(g.len(), 6);
        assert_eq!(g[0], vec![1.0, 3.0]);
        assert_eq!(g[5], vec![2.0, 5.0]);
    }

    #[test]
    fn pareto_front_marks_undominated_points() {
        let pts = [
            (1.0, 5.0),
            (2.0, 3.0),
            (2.5, 4.0),
            (4.0, 1.0),
            (4.0, 1.0),
            (5.0, 1.5),
            (f64::NAN, 0.0),
        ];
        assert_eq!(
            pareto_front(&pts),
            vec![true, true, false, true, false, false, false]
        );
    }

    #[test]
    fn summary_median() {
        let s = Summary::of(&[3.0, 1.0, f64::NAN, 2.0, 10.0]).unwrap();
        assert_eq!((s.min, s.median, s.max), (1.0, 2.5, 10.0));
        assert!(Summary::of(&[f64::NAN]).is_none());
    }

    #[test]
    fn ticks_are_round() {
        let t = ticks(0.0, 1.0);
        assert_eq!(t.len(), 6);
        for (got, want) in t.iter().zip([0.0, 0.2, 0.4, 0.6, 0.8, 1.0]) {
            assert!((got - want).abs() < 1e-12, "{t:?}");
        }
        assert!(ticks(0.0, 37.0).contains(&20.0));
    }
}
