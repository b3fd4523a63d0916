//! The workbench window (eframe + wgpu): the viewport with an orbit camera, the plugin
//! stack editor with parameter widgets generated from each plugin's spec
//! ([`crate::stack_ui`]), a WGSL editor per plugin, volumes and presets (file dialog,
//! drag and drop, recent files), slice settings, the timing panel, the compare view
//! ([`crate::compare_ui`]) and the trade-off view ([`crate::tradeoff_ui`]). The
//! renderer draws into its own eye buffer on eframe's device; the composited 8-bit
//! image is shown as a native egui texture.
//!
//! Camera: drag = orbit, right/middle drag = pan, wheel = zoom; R resets; 1/2/3 look
//! along x/y/z (shift: the opposite direction). While the camera moves, or a parameter
//! is being dragged, the image is a preview (coarser slices, lower resolution, both
//! settable); it is redrawn at full quality when the interaction stops. The timing
//! panel shows the frame time, the GPU time per pass and a plot of the last 120
//! frames. eframe persists the window state; vwb adds the recent files and the path
//! fields.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc;

use anyhow::{Context as _, Result, anyhow, bail};
use vwb_render::gpu::{self, GpuContext};
use vwb_render::params::ParamValue;
use vwb_render::plugin::{PluginInstance, Registry};
use vwb_render::preset::{Document, VolumeSource};
use vwb_render::renderer::{Backend, FrameSettings};
use vwb_render::{Camera, Renderer};

use crate::cli::{Cli, load_document};
use vwb_lab::headless;

/// The camera controls, shown on the viewport.
pub const CAMERA_HINT: &str =
    "drag: orbit · right-drag: pan · wheel: zoom · R: reset · 1/2/3: look along x/y/z";

pub use vwb_lab::document::{DEMO_PRESET, default_document, first_document};

/// eframe's wgpu setup: vwb's backends (never GL) and features.
pub fn wgpu_configuration() -> egui_wgpu::WgpuConfiguration {
    let mut setup = egui_wgpu::WgpuSetupCreateNew::without_display_handle();
    setup.instance_descriptor.backends = gpu::BACKENDS;
    setup.device_descriptor = Arc::new(|adapter: &wgpu::Adapter| {
        gpu::device_descriptor(
            adapter.features() & gpu::OPTIONAL_FEATURES,
            gpu::wanted_limits(&adapter.limits()),
        )
    });
    egui_wgpu::WgpuConfiguration {
        wgpu_setup: egui_wgpu::WgpuSetup::CreateNew(setup),
        ..Default::default()
    }
}

/// The document and volume the window opens on. When the preset or the volume fails
/// to load, the window still opens, on the demo scene, with the error shown (the
/// returned message); only a `--screenshot` run fails instead, so scripts see it.
pub fn startup(cli: &Cli) -> Result<(Document, Arc<vwb_render::Volume>, Option<String>)> {
    let (doc, volume, error) = startup_or_demo(cli)?;
    Ok((
        doc,
        volume,
        error.map(|e| format!("{e:#} (showing the demo scene)")),
    ))
}

/// [`startup`] with the error itself (a missing sample gets a fetch button).
fn startup_or_demo(
    cli: &Cli,
) -> Result<(Document, Arc<vwb_render::Volume>, Option<anyhow::Error>)> {
    let loaded = (|| {
        // no preset: the first image (the demo, pre-integrated and lit)
        let mut doc = match cli.preset.as_deref() {
            Some(p) => load_document(Some(p))?,
            None => first_document(&vwb_plugins::registry()),
        };
        if let Some(v) = &cli.volume {
            doc.volume = headless::volume_arg(v);
        }
        let volume = headless::load_volume(&doc.volume)?;
        if cli.preset.is_none() && cli.volume.is_some() {
            // a volume opened without a preset starts from its suggested TF
            match vwb_lab::document::start_from_suggestion(&mut doc, &volume) {
                Ok(note) => eprintln!("{note}"),
                Err(why) => eprintln!("note: {why}"),
            }
        }
        headless::check_frame(cli.preset.as_deref(), &doc, &volume)?;
        anyhow::Ok((doc, volume))
    })();
    // the window edits its preset: *Save preset* may write over it (volumes stay
    // protected; a screenshot run saves no preset)
    if let Some(p) = cli.preset.as_ref().filter(|_| cli.screenshot.is_none()) {
        vwb_render::files::unprotect_input(p);
    }
    match loaded {
        Ok((doc, volume)) => Ok((doc, volume, None)),
        Err(e) if cli.screenshot.is_none() => {
            let registry = vwb_plugins::registry();
            let doc = first_document(&registry);
            let volume = headless::load_volume(&doc.volume)?;
            Ok((doc, volume, Some(e)))
        }
        Err(e) => Err(e),
    }
}

pub fn run(cli: &Cli) -> Result<()> {
    if let Some(shot) = &cli.screenshot {
        vwb_lab::outputs::image_format(shot)?;
    }
    let (doc, volume, startup_error) = startup_or_demo(cli)?;
    if let Some(e) = &startup_error {
        eprintln!("error: {e:#} (showing the demo scene)");
    }
    if let Some(shot) = &cli.screenshot {
        vwb_lab::outputs::check_output(shot)?;
    }
    let screenshot = cli.screenshot.clone();
    let options = eframe::NativeOptions {
        wgpu_options: wgpu_configuration(),
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([1000.0, 720.0])
            .with_title("vwb"),
        ..Default::default()
    };
    let (err_tx, err_rx) = mpsc::channel::<String>();
    eframe::run_native(
        "vwb",
        options,
        Box::new(move |cc| {
            let mut app = Workbench::new(cc, doc, volume, screenshot, err_tx)?;
            if let Some(e) = startup_error {
                // where it came from, for a missing sample's fetch button
                let opening = cli
                    .preset
                    .clone()
                    .or(cli.volume.clone())
                    .unwrap_or_default();
                app.report_failed_open(e, &opening);
            } else if cli.preset.is_none() {
                // the first image, at the spacing this device affords
                app.fit_first_image_to_device();
                if cli.volume.is_none() && cli.screenshot.is_none() {
                    app.restore_last_session();
                }
            }
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow!("window: {e}"))?;
    if let Ok(e) = err_rx.try_recv() {
        return Err(anyhow!(e));
    }
    Ok(())
}

/// Where a file dialog starts: the path field when it names something, else
/// `fallback` (relative to the working directory) when it exists, else the user's home.
fn start_folder(field: &str, fallback: Option<&str>) -> PathBuf {
    let field = field.trim();
    if !field.is_empty() {
        return PathBuf::from(field);
    }
    fallback
        .map(PathBuf::from)
        .filter(|p| p.is_dir())
        .or_else(dirs::home_dir)
        .unwrap_or_else(|| PathBuf::from("."))
}

enum Shot {
    None,
    Pending(PathBuf),
    Requested(mpsc::Receiver<Result<(), String>>),
}

/// The preview's slice-spacing and resolution factors: ×2 and ×½ on GPUs; ×4 and ×¼ on
/// CPU adapters (lavapipe), where dragging a TF point over the CT head takes a median
/// 150–175 ms per UI frame at (×2, ×½), 45–53 ms at (×2, ×¼) and ~32 ms at (×4, ×¼)
/// (`bash bench/ui.sh`, docs/perf.md).
pub fn default_preview(info: &wgpu::AdapterInfo) -> (f32, f32) {
    if info.device_type == wgpu::DeviceType::Cpu {
        (4.0, 0.25)
    } else {
        (2.0, 0.5)
    }
}

/// The first image's slice spacing on this adapter (voxels): the preset's 0.5 on CPU
/// adapters (1.7 s a frame at 512² on lavapipe), 0.25 on GPUs, where the lit demo's
/// remaining slice rings fade further (docs/perf.md, "First image").
pub fn first_image_spacing(device: wgpu::DeviceType, preset: f32) -> f32 {
    if device == wgpu::DeviceType::Cpu {
        preset
    } else {
        preset.min(0.25)
    }
}

/// What vwb keeps between runs (eframe storage, key [`STORAGE_KEY`]).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Persisted {
    pub recent: Vec<PathBuf>,
    pub preset_path: String,
    pub volume_path: String,
    /// The last scene (preset document: volume, camera, settings, stack) in RON, file
    /// paths absolute; reopened when vwb starts without --preset or --volume.
    pub session: Option<String>,
}

pub const STORAGE_KEY: &str = "vwb";
/// The early-termination threshold that the window's "stop opaque rays" turns on:
/// the front of `experiments/early_termination.ron` (docs/perf.md, "Early ray
/// termination: the error each threshold adds").
pub const EARLY_TERMINATION: f32 = 0.99;
/// Recent files kept.
pub const RECENT: usize = 10;

/// The WGSL editor of one plugin file.
struct WgslEdit {
    file: String,
    plugin: &'static str,
    text: String,
}

/// What a chosen file is for.
#[derive(Clone, Copy)]
enum Purpose {
    Volume,
    Preset,
    NamedVolume,
}

/// Which file dialog is open.
enum Dialog {
    Volume(egui_file::FileDialog),
    Preset(egui_file::FileDialog),
    /// The file of a named volume to add ([`crate::volumes_ui`]).
    NamedVolume(egui_file::FileDialog),
}

pub struct Workbench {
    doc: Document,
    registry: Registry,
    /// Reloads user plugins whose files change (checked about once a second).
    plugin_watch: vwb_plugins::user::Watch,
    plugin_watch_at: std::time::Instant,
    /// Named volumes whose changed file did not load, with the file's stamp then: not
    /// tried again until the file changes again.
    volume_reload_failed: std::collections::HashMap<String, headless::Stamp>,
    /// The transfer-function gallery panel.
    pub gallery: crate::gallery_ui::GalleryPanel,
    /// The genetic-search panel.
    pub evolve: crate::evolve_ui::GaPanel,
    /// The preset path field (open / save).
    preset_path: String,
    /// The volume path field.
    volume_path: String,
    recent: Vec<PathBuf>,
    /// The last run's scene (see [`Persisted::session`]).
    last_session: Option<String>,
    dialog: Option<Dialog>,
    /// The named volumes section's fields.
    named_volumes: crate::volumes_ui::NamedVolumesUi,
    wgsl: Option<WgslEdit>,
    /// Full-quality resolution × (below 1 on slow devices and in tests).
    pub quality_scale: f32,
    /// A parameter is being dragged (preview quality).
    editing: bool,
    compare_against: crate::compare_ui::Against,
    /// Per-plugin cost by ablation (`vwb bench`'s engine) running in a thread, and its
    /// last result.
    ablation: Option<vwb_lab::job::Job<Vec<vwb_lab::measure::BenchRow>>>,
    ablation_rows: Option<Result<Vec<vwb_lab::measure::BenchRow>, String>>,
    tradeoff: crate::tradeoff_ui::TradeoffView,
    /// Result of the last open or save.
    file_status: Option<Result<String, String>>,
    /// A volume loading in the background (app/src/loading.rs).
    loading: Option<crate::loading::VolumeLoad>,
    /// Named volumes loading in the background: one added from a large file, or
    /// large files reloaded after they changed on disk.
    inputs_load: Option<InputsLoad>,
    /// Volume files of at least this many bytes (and streams) load in the background.
    pub async_load_bytes: u64,
    /// A missing sample's fetch button.
    fetch: crate::data_ui::FetchOffer,
    /// The preset browser (thumbnails).
    browser: crate::browser_ui::PresetBrowser,
    renderer: Renderer,
    texture: Option<egui::TextureId>,
    texture_size: [u32; 2],
    dirty: bool,
    /// Clip handles to draw this frame (screen position, hovered or dragged).
    handle_marks: Vec<(egui::Pos2, bool)>,
    frame_ms: Option<f64>,
    /// Per-pass GPU times of the last frame.
    passes: Vec<(String, f64)>,
    /// Frame times (ms) of the last frames, for the timing plot.
    history: std::collections::VecDeque<f64>,
    /// Progressive quality: while the camera moves, the slice spacing is multiplied by
    /// `drag_spacing` and the resolution by `drag_resolution`; full quality when idle.
    pub drag_spacing: f32,
    pub drag_resolution: f32,
    /// The image on screen was drawn at preview quality.
    preview: bool,
    /// Compare view: image side, the running job, the last result as textures.
    compare_side: u32,
    compare_job: Option<crate::compare_ui::CompareJob>,
    compare: Option<Result<(vwb_render::metrics::Metrics, [egui::TextureHandle; 3]), String>>,
    error: Option<String>,
    shot: Shot,
    /// Frames drawn with an image (screenshots wait for one).
    shown: u32,
    errors: mpsc::Sender<String>,
}

impl Workbench {
    pub fn new(
        cc: &eframe::CreationContext<'_>,
        doc: Document,
        volume: Arc<vwb_render::Volume>,
        screenshot: Option<PathBuf>,
        errors: mpsc::Sender<String>,
    ) -> Result<Self, Box<dyn std::error::Error + Send + Sync>> {
        let rs = cc
            .wgpu_render_state
            .as_ref()
            .ok_or("eframe started without wgpu")?;
        let gpu = GpuContext::from_parts(
            rs.instance.clone(),
            rs.adapter.clone(),
            rs.device.clone(),
            rs.queue.clone(),
        )?;
        log::info!("window adapter: {}", gpu.describe());
        let mut renderer = Renderer::with_options(&gpu, volume, headless::renderer_options(&doc))?;
        // progressive light passes refine one step per frame, the window redraws meanwhile
        renderer.set_refinement_budget(Some(1));
        headless::apply_render_switches(&mut renderer, &doc);
        renderer.set_inputs(headless::inputs_for(&doc)?);
        let error = renderer
            .update_stack(&doc.stack, doc.render.target)
            .err()
            .map(|e| e.to_string());
        let persisted: Persisted = cc
            .storage
            .and_then(|s| eframe::get_value(s, STORAGE_KEY))
            .unwrap_or_default();
        let preview = default_preview(&rs.adapter.get_info());
        Ok(Self {
            doc,
            registry: vwb_plugins::registry(),
            preset_path: persisted.preset_path,
            volume_path: persisted.volume_path,
            recent: persisted.recent,
            last_session: persisted.session,
            plugin_watch: Default::default(),
            plugin_watch_at: std::time::Instant::now(),
            volume_reload_failed: Default::default(),
            inputs_load: None,
            gallery: Default::default(),
            evolve: Default::default(),
            dialog: None,
            named_volumes: Default::default(),
            wgsl: None,
            quality_scale: 1.0,
            editing: false,
            compare_against: Default::default(),
            ablation: None,
            ablation_rows: None,
            tradeoff: Default::default(),
            file_status: None,
            loading: None,
            async_load_bytes: crate::loading::DEFAULT_ASYNC_LOAD_BYTES,
            fetch: Default::default(),
            browser: Default::default(),
            renderer,
            texture: None,
            texture_size: [0, 0],
            dirty: true,
            handle_marks: Vec::new(),
            frame_ms: None,
            passes: Vec::new(),
            history: std::collections::VecDeque::new(),
            drag_spacing: preview.0,
            drag_resolution: preview.1,
            preview: false,
            compare_side: 128,
            compare_job: None,
            compare: None,
            error,
            shot: screenshot.map_or(Shot::None, Shot::Pending),
            shown: 0,
            errors,
        })
    }

    /// The scene being edited.
    pub fn document(&self) -> &Document {
        &self.doc
    }

    /// The scene, for scripted edits; call [`Workbench::apply_stack`] afterwards.
    pub fn document_mut(&mut self) -> &mut Document {
        &mut self.doc
    }

    pub fn renderer(&self) -> &Renderer {
        &self.renderer
    }

    /// The last composer, resource or file error shown in the stack.
    /// The renderer, for scripts and tests (e.g. its GPU memory budget).
    pub fn renderer_mut(&mut self) -> &mut Renderer {
        &mut self.renderer
    }

    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }

    /// The folder samples are looked up in and fetched into (default: the data
    /// directory, `VWB_DATA_DIR`).
    pub fn set_data_dir(&mut self, dir: PathBuf) {
        self.fetch.dir = Some(dir);
    }

    /// Shows a failed open (a missing sample gets its fetch button).
    pub fn report_failed_open(&mut self, error: anyhow::Error, path: &std::path::Path) {
        self.fetch.offer(&error, path);
        self.report(Err(error));
    }

    /// The preset browser.
    pub fn browser(&mut self) -> &mut crate::browser_ui::PresetBrowser {
        &mut self.browser
    }

    /// The scene as preset RON with absolute file paths (what [`Persisted::session`]
    /// keeps).
    pub fn session(&self) -> String {
        let mut doc = self.doc.clone();
        let absolute = |p: &mut PathBuf| {
            if let Ok(a) = std::fs::canonicalize(&*p) {
                *p = a;
            }
        };
        for source in std::iter::once(&mut doc.volume).chain(doc.volumes.values_mut()) {
            if let Some(p) = source.file_mut() {
                absolute(p);
            }
        }
        for inst in &mut doc.stack {
            for v in inst.params.values.values_mut() {
                if let vwb_render::params::ParamValue::Path(p) = v
                    && !p.as_os_str().is_empty()
                {
                    absolute(p);
                }
            }
        }
        doc.to_ron()
    }

    /// Reopens a scene saved by [`Workbench::session`]; on any error the current scene
    /// stays and the error is shown (a missing sample with its fetch button).
    pub fn restore_session(&mut self, text: &str) -> Result<String> {
        let doc = Document::parse(text, "last session", &self.registry)?.document;
        let budget = self.renderer.gpu_memory_budget();
        let volume = self
            .fetch
            .load(&doc.volume, std::path::Path::new(""), budget)?;
        self.renderer = self.fresh_renderer(volume, &doc)?;
        self.doc = doc;
        self.error = None;
        self.dirty = true;
        Ok("reopened the last session".into())
    }

    /// Sets the slice spacing of the first image for this adapter
    /// ([`first_image_spacing`]).
    pub fn fit_first_image_to_device(&mut self) {
        let device = self.renderer.gpu().adapter.get_info().device_type;
        let spacing = first_image_spacing(device, self.doc.render.slice_spacing);
        if spacing != self.doc.render.slice_spacing {
            log::info!("first image: {spacing} voxel per slice on this GPU");
            self.doc.render.slice_spacing = spacing;
            self.dirty = true;
        }
    }

    /// Reopens the last run's scene, if there is one.
    pub fn restore_last_session(&mut self) {
        if let Some(text) = self.last_session.take() {
            let outcome = self.restore_session(&text);
            if outcome.is_err() {
                // kept for the fetch button's retry
                self.last_session = Some(text);
            }
            self.report(outcome.context("last session"));
        }
    }

    /// The message of the last file operation (Ok or Err).
    pub fn file_status(&self) -> Option<&Result<String, String>> {
        self.file_status.as_ref()
    }

    pub fn recent(&self) -> &[PathBuf] {
        &self.recent
    }

    pub fn tradeoff(&mut self) -> &mut crate::tradeoff_ui::TradeoffView {
        &mut self.tradeoff
    }

    /// Whether the image on screen is a preview (camera moving, parameter dragged).
    pub fn is_preview(&self) -> bool {
        self.preview
    }

    /// The last frame's time (GPU when timestamps work, else wall clock), ms.
    pub fn frame_ms(&self) -> Option<f64> {
        self.frame_ms
    }

    /// The viewport's last image (8-bit RGB over the background), as drawn.
    pub fn image(&self) -> Option<image::RgbImage> {
        vwb_lab::measure::gpu_image(&self.renderer, &self.doc)
            .ok()
            .map(|i| i.to_rgb8())
    }

    /// Brings the renderer in line with the stack; errors are shown at their plugin and
    /// the last good pipeline keeps rendering.
    pub fn apply_stack(&mut self) {
        self.error = self
            .renderer
            .update_stack(&self.doc.stack, self.doc.render.target)
            .err()
            .map(|e| e.to_string());
        self.dirty = true;
    }

    /// Adds a named volume to the document (`volumes:`, [`crate::volumes_ui`]):
    /// `source` is a file or a sample name, `name` a new volume name (empty: the
    /// file's or sample's stem). A small file or a sample loads now; a file of at
    /// least [`Workbench::async_load_bytes`] loads in a background thread (progress line
    /// and Cancel under the file fields) and joins the document when loaded. On an
    /// error (a name taken or invalid, a file that does not load) nothing changes.
    pub fn add_named_volume(&mut self, name: &str, source: &str) -> Result<String> {
        let (name, source) = vwb_lab::document::name_new_volume(&self.doc, name, source)?;
        if self.loads_in_background(&source) {
            if self.inputs_load.is_some() {
                bail!("a volume is still loading: wait for it, or cancel it, first");
            }
            let mut with = self.doc.clone();
            with.volumes.insert(name.clone(), source.clone());
            self.inputs_load = Some(InputsLoad::start(
                with,
                Some((name.clone(), source)),
                Vec::new(),
            ));
            return Ok(format!("loading volume '{name}' in the background"));
        }
        let inputs = vwb_lab::document::insert_named_volume(&mut self.doc, &name, source)?;
        Ok(self.added_volume(&name, inputs))
    }

    /// Puts the named volumes `inputs` (the document's, with `name` added) into the
    /// renderer; the message.
    fn added_volume(&mut self, name: &str, inputs: vwb_render::inputs::VolumeInputs) -> String {
        let added = inputs
            .get(name)
            .map(|v| crate::volumes_ui::describe_grid(v))
            .unwrap_or_default();
        self.renderer.set_inputs(inputs);
        self.apply_stack();
        format!("added volume '{name}' ({added})")
    }

    /// Whether a named volume from `source` loads in a background thread: a file (or
    /// stream) of at least [`Workbench::async_load_bytes`].
    fn loads_in_background(&self, source: &VolumeSource) -> bool {
        matches!(source, VolumeSource::File(p) if crate::loading::VolumeLoad::wanted(p, self.async_load_bytes))
    }

    /// Named volumes are loading in the background.
    pub fn is_loading_volumes(&self) -> bool {
        self.inputs_load.is_some()
    }

    /// Finishes the named volumes' background load once its thread is done: an added
    /// volume joins the document (unless its name was taken meanwhile), reloaded ones
    /// replace the last good ones, and what reads them reruns. True when it finished.
    pub fn poll_volume_loads(&mut self) -> bool {
        let Some(result) = self.inputs_load.as_ref().and_then(|l| l.job.poll()) else {
            return false;
        };
        let Some(load) = self.inputs_load.take() else {
            return false;
        };
        // `held` keeps the loaded volumes alive while inputs_for finds them again for
        // the document as it is now (edited meanwhile, perhaps)
        let outcome = result.map_err(|e| anyhow!(e)).and_then(|held| {
            let mut doc = self.doc.clone();
            let inputs = match &load.add {
                Some((name, source)) => {
                    vwb_lab::document::insert_named_volume(&mut doc, name, source.clone())
                }
                None => headless::inputs_for(&doc),
            };
            drop(held);
            Ok((doc, inputs?))
        });
        match (&load.add, outcome) {
            (Some((name, _)), Ok((doc, inputs))) => {
                self.doc = doc;
                let msg = self.added_volume(name, inputs);
                self.file_status = Some(Ok(msg));
            }
            (Some((name, _)), Err(e)) => {
                self.file_status = Some(Err(format!("volume '{name}' was not added: {e:#}")));
            }
            (None, outcome) => self.reloaded_volumes(load.changed, outcome.map(|(_, i)| i)),
        }
        true
    }

    /// The background load's line: what loads, for how long, and Cancel (which drops
    /// its result; the file is read to its end in the background).
    fn volume_loads_ui(&mut self, ui: &mut egui::Ui) {
        let Some(load) = &self.inputs_load else {
            return;
        };
        let what = match &load.add {
            Some((name, _)) => format!("loading volume '{name}'"),
            None => format!("reloading {}", names_list(&load.changed)),
        };
        let cancel = ui
            .horizontal(|ui| {
                ui.spinner();
                ui.label(format!(
                    "{what}… {:.0} s",
                    load.started.elapsed().as_secs_f64()
                ));
                ui.button("Cancel").clicked()
            })
            .inner;
        if cancel {
            let load = self.inputs_load.take();
            // a cancelled reload is not retried until the file changes again
            if let Some(load) = load {
                self.volume_reload_failed.extend(load.changed);
            }
            self.file_status = Some(Ok(format!("cancelled {what}")));
        }
    }

    /// Removes a named volume that no plugin's volume input names.
    pub fn remove_named_volume(&mut self, name: &str) -> Result<String> {
        let users = crate::volumes_ui::users_of(&self.doc, name);
        if !users.is_empty() {
            bail!(
                "'{name}' is named by {}: pick another volume there first",
                users.join(", ")
            );
        }
        if self.doc.volumes.remove(name).is_none() {
            bail!("there is no volume named '{name}'");
        }
        self.renderer.set_inputs(headless::inputs_for(&self.doc)?);
        self.apply_stack();
        Ok(format!("removed volume '{name}'"))
    }

    /// Reloads the named volumes whose files changed on disk (checked about once a
    /// second, with the user plugins): the renderer gets the new volume and reruns
    /// what reads it. A file that does not load (half written, say) leaves the last
    /// good volume drawing, shows its error, and is tried again when it changes again.
    /// Large files (at least [`Workbench::async_load_bytes`]) load in a background
    /// thread, the last good volumes drawing meanwhile; no check runs while one loads.
    /// True when something was reloaded, failed, or started loading.
    pub fn reload_changed_volumes(&mut self) -> bool {
        if self.inputs_load.is_some() {
            return false;
        }
        let changed: Vec<(String, headless::Stamp)> = headless::changed_named_volumes(&self.doc)
            .into_iter()
            .filter(|(name, stamp)| self.volume_reload_failed.get(name) != Some(stamp))
            .collect();
        if changed.is_empty() {
            return false;
        }
        // large files load in a background thread; the last good volumes draw meanwhile
        if changed.iter().any(|(name, _)| {
            self.doc
                .volumes
                .get(name)
                .is_some_and(|s| self.loads_in_background(s))
        }) {
            self.file_status = Some(Ok(format!(
                "reloading volume {} in the background: its file changed on disk",
                names_list(&changed)
            )));
            self.inputs_load = Some(InputsLoad::start(self.doc.clone(), None, changed));
            return true;
        }
        let inputs = headless::inputs_for(&self.doc);
        self.reloaded_volumes(changed, inputs);
        true
    }

    /// Puts reloaded named volumes into the renderer, or keeps the last good ones
    /// drawing and records the failure (not retried until the files change again).
    fn reloaded_volumes(
        &mut self,
        changed: Vec<(String, headless::Stamp)>,
        inputs: Result<vwb_render::inputs::VolumeInputs>,
    ) {
        let names = names_list(&changed);
        match inputs {
            Ok(inputs) => {
                self.renderer.set_inputs(inputs);
                self.apply_stack();
                self.volume_reload_failed.clear();
                self.file_status = Some(Ok(format!(
                    "reloaded volume {names}: its file changed on disk"
                )));
            }
            Err(e) => {
                self.volume_reload_failed.extend(changed);
                self.file_status = Some(Err(format!(
                    "volume {names} changed on disk and did not load; the last good one stays: {e:#}"
                )));
            }
        }
    }

    /// Reloads the user plugins whose files changed: the stack's instances of a
    /// reloaded plugin take the new one (keeping the values of parameters that still
    /// exist), and a plugin that no longer loads keeps drawing with its last good version
    /// while its error (file and line) is shown. True when something was reloaded or
    /// failed.
    pub fn reload_user_plugins(&mut self) -> bool {
        let outcomes = self.plugin_watch.poll();
        if outcomes.is_empty() {
            return false;
        }
        let mut errors = Vec::new();
        for (id, outcome) in outcomes {
            match outcome {
                Ok(plugin) => {
                    for inst in self.doc.stack.iter_mut().filter(|i| i.plugin.id() == id) {
                        let mut fresh = PluginInstance::new(plugin.clone());
                        for spec in plugin.params() {
                            if let Some(v) = inst.params.get(spec.key)
                                && spec.check(v).is_ok()
                            {
                                fresh.params.set(spec.key, v.clone());
                            }
                        }
                        inst.plugin = plugin.clone();
                        inst.params = fresh.params;
                    }
                }
                Err(e) => errors.push(e),
            }
        }
        self.registry = vwb_plugins::registry();
        self.apply_stack();
        if !errors.is_empty() {
            self.error = Some(errors.join("\n"));
        }
        true
    }

    /// Puts a genome's TF (from the gallery or the genetic search) into the stack's
    /// first enabled classify.tf1d (classify.tf2d for a 2D genome).
    pub fn apply_genome(&mut self, g: &vwb_render::search::genome::Genome) {
        match g.apply(&mut self.doc.stack) {
            Ok(()) => {
                self.apply_stack();
                self.file_status = Some(Ok("applied the TF (save the preset to keep it)".into()));
            }
            Err(e) => self.file_status = Some(Err(e)),
        }
    }

    /// Shows an error under the file fields (e.g. a preset that failed at start-up).
    pub fn show_error(&mut self, message: String) {
        self.file_status = Some(Err(message));
    }

    /// Shows the outcome of a file operation.
    fn report(&mut self, outcome: Result<String>) {
        self.file_status = Some(outcome.map_err(|e| format!("{e:#}")));
    }

    fn remember(&mut self, path: &std::path::Path) {
        let path = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        self.recent.retain(|p| p != &path);
        self.recent.insert(0, path);
        self.recent.truncate(RECENT);
    }

    /// A renderer for `volume` and `doc` on the window's device, with the current
    /// renderer's WGSL overrides; nothing changes on screen until it is swapped in.
    fn fresh_renderer(&self, volume: Arc<vwb_render::Volume>, doc: &Document) -> Result<Renderer> {
        let options = vwb_render::renderer::RendererOptions {
            gpu_memory_budget: self.renderer.gpu_memory_budget(),
            ..headless::renderer_options(doc)
        };
        let mut renderer = Renderer::with_options(self.renderer.gpu(), volume, options)?;
        renderer.set_refinement_budget(Some(1));
        for (file, source) in self.renderer.shader_overrides() {
            renderer.set_shader_override(file, Some(source.to_string()));
        }
        headless::apply_render_switches(&mut renderer, doc);
        renderer.set_inputs(headless::inputs_for(doc)?);
        renderer.update_stack(&doc.stack, doc.render.target)?;
        Ok(renderer)
    }

    /// Opens a volume file into the current scene; the current volume stays on any
    /// error (unreadable file, lying header, a stack that fails on the new volume).
    pub fn open_volume(&mut self, path: &std::path::Path) -> Result<String> {
        let source = headless::volume_arg(path);
        let budget = self.renderer.gpu_memory_budget();
        let volume = self.fetch.load(&source, path, budget)?;
        self.install_volume(path, volume)
    }

    /// Opens a volume from the UI: large files and streams load in the background
    /// (progress and Cancel under the path field), small ones at once.
    pub fn start_open_volume(&mut self, path: &std::path::Path) {
        if crate::loading::VolumeLoad::wanted(path, self.async_load_bytes) {
            let budget = self.renderer.gpu_memory_budget();
            self.loading = Some(crate::loading::VolumeLoad::start(path, budget));
            self.file_status = None;
        } else {
            let outcome = self.open_volume(path);
            self.report(outcome);
        }
    }

    /// A volume is loading in the background.
    pub fn is_loading(&self) -> bool {
        self.loading.is_some()
    }

    /// The background load's progress bar and Cancel; installs its volume when done.
    fn loading_ui(&mut self, ui: &mut egui::Ui) {
        let Some(mut load) = self.loading.take() else {
            return;
        };
        if load.ui(ui) {
            load.cancel();
            self.report(Ok(format!("cancelled loading {}", load.path.display())));
        } else if let Some(result) = load.poll() {
            let outcome = result
                .map_err(|e| anyhow!(e))
                .and_then(|v| match load.preset.take() {
                    Some((preset, doc)) => self.install_preset(&preset, doc, v),
                    None => self.install_volume(&load.path, v),
                });
            self.report(outcome);
        } else {
            ui.ctx().request_repaint();
            self.loading = Some(load);
        }
    }

    /// Puts a loaded volume into the current scene (see [`Workbench::open_volume`]).
    fn install_volume(
        &mut self,
        path: &std::path::Path,
        volume: Arc<vwb_render::Volume>,
    ) -> Result<String> {
        let source = headless::volume_arg(path);
        let renderer = self
            .fresh_renderer(volume, &self.doc)
            .with_context(|| format!("{}", path.display()))?;
        let v = renderer.volume();
        let mut msg = format!("opened {} {:?}", path.display(), v.dims);
        if let Some(level) = renderer.level() {
            msg += &format!("; {}", level.notice());
        }
        if let Some(notice) = renderer.storage_notice() {
            msg += &format!("; {notice}");
        }
        let vbox = *renderer.volume_box();
        self.doc.camera.fit(vbox.min, vbox.max);
        self.renderer = renderer;
        self.doc.volume = source;
        self.volume_path = path.display().to_string();
        self.error = None;
        self.dirty = true;
        self.remember(path);
        Ok(msg)
    }

    /// [`Workbench::open_any`] from the UI: large volumes load in the background.
    fn start_open_any(&mut self, path: &std::path::Path) {
        if path.extension().is_some_and(|e| e == "ron") {
            self.start_open(path)
        } else if vwb_plugins::clip_mesh::mesh::is_mesh_file(path) {
            let outcome = self.open_mesh(path);
            self.report(outcome);
        } else {
            self.start_open_volume(path)
        }
    }

    /// Opens a preset (`.ron`), a clipping mesh (`.obj`, `.ply`, `.stl`: see
    /// [`Workbench::open_mesh`]) or a volume by its extension.
    pub fn open_any(&mut self, path: &std::path::Path) -> Result<String> {
        if path.extension().is_some_and(|e| e == "ron") {
            self.open(path)
        } else if vwb_plugins::clip_mesh::mesh::is_mesh_file(path) {
            self.open_mesh(path)
        } else {
            self.open_volume(path)
        }
    }

    /// Clips by a mesh file (opened or dropped on the window): the first enabled
    /// `clip.mesh` of the stack takes the file, or a new one is put at the top of the
    /// stack. The mesh is checked first, so a mesh that is not closed is refused with
    /// its first bad edge and the stack is left as it was.
    pub fn open_mesh(&mut self, path: &std::path::Path) -> Result<String> {
        let checked = vwb_plugins::clip_mesh::load_checked(path).map_err(anyhow::Error::msg)?;
        let index = match self
            .doc
            .stack
            .iter()
            .position(|i| i.enabled && i.plugin.id() == "clip.mesh")
        {
            Some(i) => i,
            None => {
                let plugin = self
                    .registry
                    .get("clip.mesh")
                    .context("clip.mesh is not registered")?;
                self.doc.stack.insert(0, PluginInstance::new(plugin));
                0
            }
        };
        let params = &mut self.doc.stack[index].params;
        params.set("source", ParamValue::Enum("file".into()));
        params.set("file", ParamValue::Path(path.to_path_buf()));
        let mut note = format!(
            "clipping by {} ({} triangles)",
            path.display(),
            checked.mesh.triangles.len()
        );
        if let Some(w) = &checked.warning {
            note += &format!("; warning: {w}");
        }
        self.apply_stack();
        Ok(note)
    }

    fn settings(&self, size: [u32; 2]) -> FrameSettings {
        FrameSettings {
            width: size[0],
            height: size[1],
            ..self.doc.frame_settings()
        }
    }

    fn side_panel(&mut self, ui: &mut egui::Ui) {
        ui.heading("vwb");
        ui.label(format!(
            "{} {:?}",
            self.renderer.volume().name,
            self.renderer.volume().dims
        ));
        ui.label(format!("adapter: {}", self.renderer.gpu().info.name));
        if let Some(level) = self.renderer.level() {
            ui.colored_label(
                egui::Color32::from_rgb(230, 160, 40),
                format!("⚠ {}", level.notice()),
            );
        }
        if let Some(notice) = self.renderer.storage_notice() {
            ui.label(notice);
        }
        let bricks = self.renderer.bricks().len();
        if bricks > 0 {
            ui.label(format!(
                "split into {bricks} bricks (beyond one 3D texture), composited sort-last"
            ))
            .on_hover_text(
                "Plugins that carry light or flow across the whole volume cannot render it; \
                 see docs/scale.md",
            );
        }
        for w in headless::frame_warnings(&self.doc, self.renderer.volume()) {
            ui.colored_label(egui::Color32::from_rgb(230, 160, 40), format!("⚠ {w}"));
        }
        ui.separator();
        self.files(ui);
        let picked = egui::CollapsingHeader::new("Preset browser")
            .show(ui, |ui| {
                if self.browser.names().is_empty() {
                    self.browser.refresh(&self.recent);
                }
                self.browser.ui(ui, self.renderer.gpu())
            })
            .body_returned
            .flatten();
        if let Some(path) = picked {
            let outcome = self.open(&path);
            self.report(outcome);
        }
        let (mut new_gallery, mut refine) = (false, None);
        let applied = egui::CollapsingHeader::new("TF gallery")
            .show(ui, |ui| self.gallery.ui(ui, &mut new_gallery, &mut refine))
            .body_returned
            .flatten();
        if new_gallery || refine.is_some() {
            let volume = self.renderer.volume().clone();
            let gpu = self.renderer.gpu().clone();
            self.gallery.start(&gpu, &self.doc, volume, refine);
        }
        if let Some(crate::gallery_ui::GalleryAction::Apply(g)) = applied {
            self.apply_genome(&g);
        }
        let ga = egui::CollapsingHeader::new("Genetic search")
            .show(ui, |ui| self.evolve.ui(ui))
            .body_returned
            .flatten();
        match ga {
            Some(crate::evolve_ui::GaAction::Apply(g)) => self.apply_genome(&g),
            Some(crate::evolve_ui::GaAction::Advance(n)) => {
                let volume = self.renderer.volume().clone();
                let gpu = self.renderer.gpu().clone();
                self.evolve.advance(&gpu, &self.doc, volume, n);
            }
            None => {}
        }
        ui.separator();
        ui.label("Plugins");
        let mut changed = false;
        let volume = self.renderer.volume().clone();
        let inputs: Vec<String> = self.doc.volumes.keys().cloned().collect();
        let cx = crate::stack_ui::StackUi {
            registry: &self.registry,
            error: self.error.as_deref(),
            histogram: &volume.histogram,
            volume: Some(&volume),
            inputs: &inputs,
            named: self.renderer.inputs(),
            auto_gradient: Some(self.renderer.resolved_gradient().name()),
        };
        let response = crate::stack_ui::stack_editor(ui, &cx, &mut self.doc.stack);
        changed |= response.changed;
        if let Some(i) = response.edit_wgsl
            && let Some(inst) = self.doc.stack.get(i)
        {
            let shader = inst.plugin.shader();
            let text = self
                .renderer
                .shader_override(&shader.file)
                .map_or_else(|| shader.source.to_string(), str::to_string);
            self.wgsl = Some(WgslEdit {
                file: shader.file.to_string(),
                plugin: inst.plugin.id(),
                text,
            });
        }
        // a parameter dragged with the pointer held: preview quality until release
        let pointer_down = ui.input(|i| i.pointer.any_down());
        if changed && pointer_down {
            self.editing = true;
        } else if !pointer_down {
            self.editing = false;
        }
        ui.separator();
        let r = &mut self.doc.render;
        changed |= ui
            .add(
                egui::Slider::new(&mut r.slice_spacing, 0.1..=8.0)
                    .logarithmic(true)
                    .text("slice spacing (voxels)"),
            )
            .on_hover_text(
                "distance between the slices through the volume, in voxels: smaller is \
                 sharper and slower; above 1 shows wood-grain rings",
            )
            .changed();
        ui.horizontal(|ui| {
            changed |= ui
                .radio_value(&mut r.backend, Backend::Raster, "raster")
                .on_hover_text("draws each slice as a polygon and blends it (the GPU's rasteriser)")
                .changed();
            changed |= ui
                .radio_value(&mut r.backend, Backend::Compute, "compute")
                .on_hover_text(
                    "one thread per pixel steps through the same slices; with \"stop opaque \
                     rays\" a ray stops at the slice that makes it opaque",
                )
                .changed();
        });
        if r.backend == Backend::Raster {
            let before = r.slices_per_proxy;
            let auto = vwb_render::renderer::RASTER_GROUP_AUTO;
            let name = |n: u32| {
                if n == auto {
                    "auto".to_string()
                } else {
                    n.to_string()
                }
            };
            egui::ComboBox::from_label("slices per polygon")
                .selected_text(name(before))
                .show_ui(ui, |ui| {
                    for n in std::iter::once(auto).chain(vwb_render::renderer::RASTER_GROUPS) {
                        ui.selectable_value(&mut r.slices_per_proxy, n, name(n));
                    }
                })
                .response
                .on_hover_text(format!(
                    "raster: one polygon stands for this many slices, its fragments \
                     composite their samples and blend once (Rezk-Salama 2001, §9.1): \
                     faster on CPU devices, the image moved by rounding. auto: 1, or {} \
                     while \"stop opaque rays\" is on",
                    vwb_render::renderer::RASTER_GROUP_WITH_TERMINATION
                ));
            if r.slices_per_proxy != before {
                // as a document's section reaches a renderer (`apply_render_switches`)
                self.renderer.set_raster_group(r.raster_group());
                self.dirty = true;
            }
        }
        // early ray termination (issue 23, item 6): off by default, so that the presets
        // keep their images; 0.99 is the threshold docs/perf.md recommends
        let mut stop = r.early_termination.is_some();
        if ui
            .checkbox(&mut stop, "stop opaque rays")
            .on_hover_text(format!(
                "early ray termination: a ray stops once its opacity reaches the \
                 threshold (compute: after that slice; raster: at the end of its run of \
                 {} slices, drawn {} slices per polygon unless \"slices per polygon\" \
                 says otherwise). At 0.99 it adds about 0.03 ΔE*uv and saves up to half the \
                 frame on dense scenes (docs/perf.md)",
                vwb_render::renderer::raster_et_interval(),
                vwb_render::renderer::RASTER_GROUP_WITH_TERMINATION
            ))
            .changed()
        {
            r.early_termination = stop.then_some(EARLY_TERMINATION);
            self.dirty = true;
        }
        if let Some(t) = &mut r.early_termination
            && ui
                .add(egui::Slider::new(t, 0.9..=1.0).text("opacity to stop at"))
                .on_hover_text("higher is closer to the full image and slower")
                .changed()
        {
            self.dirty = true;
        }
        if changed {
            self.apply_stack();
        }
        if ui
            .add(
                egui::Slider::new(&mut self.quality_scale, 0.125..=1.0)
                    .text("resolution × (full quality)"),
            )
            .on_hover_text(
                "renders the still image at this fraction of the viewport's pixels and \
                 scales it up: below 1 is faster and blurrier (for slow devices)",
            )
            .changed()
        {
            self.dirty = true;
        }
        ui.separator();
        ui.label("Preview while moving the camera or dragging a parameter");
        ui.add(
            egui::Slider::new(&mut self.drag_spacing, 1.0..=8.0)
                .logarithmic(true)
                .text("slice spacing ×"),
        )
        .on_hover_text("while moving, slices are this many times farther apart (faster, coarser)");
        ui.add(egui::Slider::new(&mut self.drag_resolution, 0.125..=1.0).text("resolution ×"))
            .on_hover_text("while moving, the image has this fraction of the pixels");
        ui.separator();
        egui::CollapsingHeader::new("Timing")
            .default_open(true)
            .show(ui, |ui| self.timing(ui));
        ui.separator();
        self.compare_view(ui);
        egui::CollapsingHeader::new("Trade-off: sweep and Pareto plot").show(ui, |ui| {
            let gpu = self.renderer.gpu().clone();
            if self.tradeoff.ui(ui, &gpu, &mut self.doc, &volume) {
                self.apply_stack();
            }
        });
    }

    /// The WGSL editor window: Apply composes the edited source (an error appears at the
    /// plugin with its file and line, and the last good image stays); Revert restores
    /// the built-in source.
    fn wgsl_window(&mut self, ctx: &egui::Context) {
        let Some(edit) = &mut self.wgsl else {
            return;
        };
        let mut open = true;
        let mut close = false;
        let mut action = None;
        egui::Window::new(format!("WGSL: {}", edit.file))
            .id(egui::Id::unique("wgsl editor"))
            .open(&mut open)
            .default_size([520.0, 420.0])
            .show(ctx, |ui| {
                ui.label(format!("plugin {}", edit.plugin));
                ui.horizontal(|ui| {
                    if ui.button("Apply").clicked() {
                        action = Some(true);
                    }
                    if ui.button("Revert to built-in").clicked() {
                        action = Some(false);
                    }
                    if ui.button("Close editor").clicked() {
                        close = true;
                    }
                });
                let label = ui.label("source");
                egui::ScrollArea::vertical().show(ui, |ui| {
                    ui.add(
                        egui::TextEdit::multiline(&mut edit.text)
                            .code_editor()
                            .desired_width(f32::INFINITY)
                            .desired_rows(24)
                            .id_salt("wgsl text"),
                    )
                    .labelled_by(label.id);
                });
            });
        let file = edit.file.clone();
        match action {
            Some(true) => {
                self.renderer
                    .set_shader_override(&file, Some(edit.text.clone()));
                self.apply_stack();
            }
            Some(false) => {
                self.renderer.set_shader_override(&file, None);
                if let Some(inst) = self
                    .doc
                    .stack
                    .iter()
                    .find(|i| i.plugin.shader().file == file.as_str())
                {
                    edit.text = inst.plugin.shader().source.to_string();
                }
                self.apply_stack();
            }
            None => {}
        }
        if !open || close {
            self.wgsl = None;
        }
    }

    /// Frame time, per-pass GPU times and a plot of the last frames.
    fn timing(&mut self, ui: &mut egui::Ui) {
        match self.frame_ms {
            Some(ms) => ui.label(format!(
                "frame: {ms:.1} ms{}",
                if self.preview { " (preview)" } else { "" }
            )),
            None => ui.label("frame: –"),
        };
        for (name, ms) in &self.passes {
            ui.label(format!("  {name}: {ms:.2} ms"));
        }
        self.per_plugin(ui);
        let points: egui_plot::PlotPoints = self
            .history
            .iter()
            .enumerate()
            .map(|(i, ms)| [i as f64, *ms])
            .collect();
        egui_plot::Plot::new("frame times")
            .height(90.0)
            .allow_drag(false)
            .allow_zoom(false)
            .allow_scroll(false)
            .y_axis_label("ms")
            .show(ui, |plot| {
                plot.line(egui_plot::Line::new("frame ms", points))
            })
            .response
            .widget_info(|| egui::WidgetInfo::labeled(egui::Role::Canvas, true, "frame time plot"));
    }

    /// Per-plugin GPU time: the hooks run inside one composed shader, so each plugin's
    /// cost is the frame time with it minus the frame time without it (ablation, the
    /// engine of `vwb bench`), measured in a thread at 256² over 5 frames; pre-passes
    /// and memory per plugin come with it.
    fn per_plugin(&mut self, ui: &mut egui::Ui) {
        if let Some(job) = &self.ablation {
            if let Some(r) = job.poll() {
                self.ablation_rows = Some(r);
                self.ablation = None;
            } else {
                ui.add(egui::Spinner::new());
                ui.ctx().request_repaint();
            }
        } else if ui
            .button("Measure per-plugin cost")
            .on_hover_text("frame time with each plugin minus without it, 256², 5 frames")
            .clicked()
        {
            let gpu = self.renderer.gpu().clone();
            let volume = self.renderer.volume().clone();
            let mut doc = self.doc.clone();
            doc.render.size = [256, 256];
            self.ablation = Some(vwb_lab::job::Job::spawn("measurement", move || {
                vwb_lab::measure::bench_document(&gpu, &doc, volume, 1, 5)
                    .map_err(|e| format!("{e:#}"))
            }));
        }
        match &self.ablation_rows {
            Some(Ok(rows)) => {
                for r in rows
                    .iter()
                    .filter(|r| r.kind == "plugin" || r.kind == "cold_pass")
                {
                    if let Some(ms) = &r.ms {
                        ui.label(format!("  {} ({}): {:.2} ms", r.name, r.kind, ms.median));
                    }
                }
                for r in rows.iter().filter(|r| r.kind == "memory") {
                    if let Some(b) = r.bytes {
                        ui.label(format!(
                            "  {} memory: {:.1} MiB",
                            r.name,
                            b as f64 / 1048576.0
                        ));
                    }
                }
            }
            Some(Err(e)) => {
                ui.colored_label(egui::Color32::RED, e);
            }
            None => {}
        }
        // disabled plugins keep their resources (no rebuild or pre-pass on re-enabling)
        for (_, id, bytes) in self.renderer.disabled_memory() {
            ui.label(format!(
                "  {id} (disabled) holds {:.1} MiB",
                bytes as f64 / 1048576.0
            ));
        }
    }

    /// The GPU image beside the CPU reference of the same frame, the ΔE*uv heatmap and
    /// the metrics; the reference runs in a thread (progress, cancel).
    fn compare_view(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Compare with the CPU reference").show(ui, |ui| {
            use crate::compare_ui::Against;
            ui.add(egui::Slider::new(&mut self.compare_side, 32..=512).text("image side"));
            let converged = match vwb_lab::measure::supplied_reference(&self.doc) {
                Some(r) => format!("converged ({})", r.label()),
                None => "converged".to_string(),
            };
            ui.horizontal(|ui| {
                ui.radio_value(
                    &mut self.compare_against,
                    Against::SameSlices,
                    "same slices",
                );
                ui.radio_value(&mut self.compare_against, Against::Converged, converged);
            });
            if let Some(job) = &self.compare_job {
                match job.fraction() {
                    Some(f) => ui.add(egui::ProgressBar::new(f).show_percentage()),
                    None => ui.add(egui::ProgressBar::new(0.0).animate(true).text("converging")),
                };
                if ui.button("Cancel").clicked() {
                    job.cancel();
                }
                if let Some(result) = job.poll() {
                    self.compare = Some(result.map(|c| {
                        let load = |name: &str, img: &image::RgbImage| {
                            ui.ctx().load_texture(
                                name,
                                crate::compare_ui::color_image(img),
                                egui::TextureOptions::NEAREST,
                            )
                        };
                        let textures = [
                            load("compare gpu", &c.gpu),
                            load("compare reference", &c.reference),
                            load("compare heatmap", &c.heatmap),
                        ];
                        (c.metrics, textures)
                    }));
                    self.compare_job = None;
                } else {
                    ui.ctx().request_repaint();
                }
            } else if ui.button("Compute reference").clicked() {
                self.compare = None;
                match self.start_compare() {
                    Ok(job) => self.compare_job = Some(job),
                    Err(e) => self.compare = Some(Err(format!("{e:#}"))),
                }
            }
            match &self.compare {
                Some(Ok((m, textures))) => {
                    ui.label(format!(
                        "RMS ΔE*uv {:.3}, max {:.2}, > 6: {:.2} %, PSNR {:.1} dB, SSIM {:.4}",
                        m.rms_delta_e,
                        m.max_delta_e,
                        m.share_above_6 * 100.0,
                        m.psnr_db,
                        m.ssim
                    ));
                    ui.horizontal(|ui| {
                        for (t, label) in textures.iter().zip(["GPU", "reference", "ΔE"]) {
                            ui.vertical(|ui| {
                                ui.label(label);
                                ui.image((t.id(), egui::vec2(96.0, 96.0)));
                            });
                        }
                    });
                }
                Some(Err(e)) => {
                    ui.colored_label(egui::Color32::RED, e);
                }
                None => {}
            }
        });
    }

    /// Renders the frame at the compare size on the GPU and starts its reference.
    fn start_compare(&mut self) -> Result<crate::compare_ui::CompareJob> {
        let side = self.compare_side.clamp(8, 4096);
        let settings = self.settings([side, side]);
        self.renderer.render(&settings)?;
        let (w, h, px) = self
            .renderer
            .read_pixels()
            .ok_or_else(|| anyhow!("no GPU image"))?;
        let bg = vwb_lab::measure::background(&self.doc);
        let gpu = vwb_render::metrics::RgbImageF::from_rgba_f32_premultiplied_over(&px, w, h, bg);
        // the viewport is redrawn at its own size next frame
        self.dirty = true;
        if self.compare_against == crate::compare_ui::Against::Converged {
            return Ok(crate::compare_ui::CompareJob::start_converged(
                self.renderer.volume().clone(),
                self.doc.clone(),
                settings,
                gpu,
                vwb_render::reference::DEFAULT_TOLERANCE_DELTA_E,
            ));
        }
        Ok(crate::compare_ui::CompareJob::start(
            self.renderer.volume().clone(),
            self.renderer.inputs().clone(),
            self.doc.stack.clone(),
            settings,
            self.doc.render.target,
            gpu,
            bg,
        ))
    }

    /// Volumes and presets: path fields, file dialogs, recent files; presets are
    /// saved atomically (a failed save leaves the old file as it was). Files dropped on
    /// the window open too (`.ron` as a preset, anything else as a volume).
    fn files(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.add(
                egui::TextEdit::singleline(&mut self.volume_path)
                    .desired_width(150.0)
                    .hint_text("volume file or sample")
                    .id_salt("volume path"),
            )
            .on_hover_text(
                "volume file (NRRD .nhdr/.nrrd, NIfTI .nii/.nii.gz, MetaImage .mhd/.mha, a TIFF stack, a DICOM file or folder: the whole series loads, an OME-Zarr folder) or a sample name such as ct_head (vwb data list); a mesh (.obj, .ply, .stl) chosen with … or dropped on the window clips the volume (clip.mesh)",
            );
            if ui.button("Open volume").clicked() {
                let path = PathBuf::from(self.volume_path.trim());
                self.start_open_any(&path);
            }
            if ui
                .button("…")
                .on_hover_text("choose a volume, or a mesh to clip by")
                .clicked()
            {
                let mut d = egui_file::FileDialog::open_file()
                    .initial_path(start_folder(&self.volume_path, None))
                    .title("Open volume");
                d.open();
                self.dialog = Some(Dialog::Volume(d));
            }
        });
        self.loading_ui(ui);
        self.volume_loads_ui(ui);
        ui.horizontal(|ui| {
            ui.add(
                egui::TextEdit::singleline(&mut self.preset_path)
                    .desired_width(150.0)
                    .hint_text("preset file (.ron)")
                    .id_salt("preset path"),
            )
            .on_hover_text("preset file (.ron): open it, or save the scene to it");
            let path = PathBuf::from(self.preset_path.trim());
            if ui.button("Open preset").clicked() {
                self.start_open(&path);
            }
            if ui.button("Save preset").clicked() {
                let saved = self.doc.save(&path);
                if saved.is_ok() {
                    self.remember(&path);
                    // its thumbnail beside it, for the preset browser
                    if let Some(img) = self.image() {
                        let thumb = crate::browser_ui::thumbnail_path(&path, None);
                        if let Err(e) = crate::browser_ui::save_thumbnail(&img, &thumb) {
                            log::warn!("{e:#}");
                        }
                    }
                    self.browser.refresh(&self.recent);
                }
                self.file_status = Some(
                    saved
                        .map(|_| format!("saved {}", path.display()))
                        .map_err(|e| e.to_string()),
                );
            }
            if ui.button("…").on_hover_text("choose a preset").clicked() {
                let mut d = egui_file::FileDialog::open_file()
                    .initial_path(start_folder(&self.preset_path, Some("presets")))
                    .title("Open preset");
                d.open();
                self.dialog = Some(Dialog::Preset(d));
            }
        });
        if !self.recent.is_empty() {
            let mut pick = None;
            egui::ComboBox::new("recent files", "recent files")
                .selected_text("open…")
                .width(220.0)
                .show_ui(ui, |ui| {
                    for p in &self.recent {
                        let name = p.file_name().map_or_else(
                            || p.display().to_string(),
                            |n| n.to_string_lossy().into(),
                        );
                        if ui
                            .selectable_label(false, name)
                            .on_hover_text(p.display().to_string())
                            .clicked()
                        {
                            pick = Some(p.clone());
                        }
                    }
                });
            if let Some(p) = pick {
                self.start_open_any(&p);
            }
        }
        let action =
            egui::CollapsingHeader::new(format!("Named volumes ({})", self.doc.volumes.len()))
                .id_salt("named volumes")
                .show(ui, |ui| {
                    self.named_volumes.ui(ui, &self.doc, self.renderer.inputs())
                })
                .body_returned
                .flatten();
        match action {
            Some(crate::volumes_ui::VolumesAction::Add { name, source }) => {
                let outcome = self.add_named_volume(&name, &source);
                if outcome.is_ok() {
                    self.named_volumes = Default::default();
                }
                self.report(outcome);
            }
            Some(crate::volumes_ui::VolumesAction::Remove(name)) => {
                let outcome = self.remove_named_volume(&name);
                self.report(outcome);
            }
            Some(crate::volumes_ui::VolumesAction::Browse) => {
                let mut d = egui_file::FileDialog::open_file()
                    .initial_path(start_folder(&self.named_volumes.source, None))
                    .title("Add a named volume");
                d.open();
                self.dialog = Some(Dialog::NamedVolume(d));
            }
            None => {}
        }
        match &self.file_status {
            Some(Ok(m)) => {
                ui.label(m);
            }
            Some(Err(e)) => {
                ui.colored_label(egui::Color32::RED, e);
            }
            None => {}
        }
        if let Some(path) = self.fetch.ui(ui) {
            // an empty path: the last session was waiting for the sample
            if path.as_os_str().is_empty() {
                self.restore_last_session();
            } else {
                let outcome = self.open_any(&path);
                self.report(outcome);
            }
        }
    }

    /// The open file dialog and files dropped on the window.
    fn file_events(&mut self, ctx: &egui::Context) {
        let mut chosen = None;
        if let Some(dialog) = &mut self.dialog {
            let (d, purpose) = match dialog {
                Dialog::Volume(d) => (d, Purpose::Volume),
                Dialog::Preset(d) => (d, Purpose::Preset),
                Dialog::NamedVolume(d) => (d, Purpose::NamedVolume),
            };
            if d.show(ctx).selected() {
                chosen = d.path().map(|p| (p.to_path_buf(), purpose));
            }
            if !d.visible() {
                self.dialog = None;
            }
        }
        match chosen {
            Some((path, Purpose::Preset)) => self.start_open(&path),
            Some((path, Purpose::NamedVolume)) => {
                self.named_volumes.source = path.display().to_string();
            }
            // a volume, or a mesh to clip by (.obj, .ply, .stl)
            Some((path, Purpose::Volume)) => self.start_open_any(&path),
            None => {}
        }
        let dropped = ctx.input(|i| i.raw.dropped_files.clone());
        // the files of a DICOM series dropped together open once: one file opens its
        // whole series
        let mut series_folders = std::collections::HashSet::new();
        for f in dropped {
            let path = f.path().to_path_buf();
            if path.as_os_str().is_empty() {
                continue;
            }
            if vwb_render::volume::dicom::is_dicom_file(&path)
                && !series_folders.insert(path.parent().map(|p| p.to_path_buf()))
            {
                continue;
            }
            self.start_open_any(&path);
        }
    }

    /// Loads a preset (and its volume); the current one stays on any error.
    pub fn open(&mut self, path: &std::path::Path) -> Result<String> {
        let doc = Document::load(path, &self.registry)?.document;
        let budget = self.renderer.gpu_memory_budget();
        let volume = self.fetch.load(&doc.volume, path, budget)?;
        self.install_preset(path, doc, volume)
    }

    /// Opens a preset from the UI; a large volume (or a stream) loads in the background.
    pub fn start_open(&mut self, path: &std::path::Path) {
        let doc = match Document::load(path, &self.registry) {
            Ok(loaded) => loaded.document,
            Err(e) => return self.report(Err(e.into())),
        };
        match &doc.volume {
            VolumeSource::File(v)
                if crate::loading::VolumeLoad::wanted(v, self.async_load_bytes) =>
            {
                let budget = self.renderer.gpu_memory_budget();
                let mut load = crate::loading::VolumeLoad::start(v, budget);
                load.preset = Some((path.to_path_buf(), doc));
                self.loading = Some(load);
                self.file_status = None;
            }
            _ => {
                let outcome = self.open(path);
                self.report(outcome);
            }
        }
    }

    /// Puts an opened preset and its loaded volume on screen (see [`Workbench::open`]).
    fn install_preset(
        &mut self,
        path: &std::path::Path,
        mut doc: Document,
        volume: Arc<vwb_render::Volume>,
    ) -> Result<String> {
        headless::check_frame(Some(path), &doc, &volume)?;
        if *volume == **self.renderer.volume() {
            // the same data (e.g. the same preset again): keep the renderer, so that the
            // volume is not uploaded again, and carry the instances' identities, so
            // that their resources and pre-pass results stay; on an error the last good
            // pipeline keeps drawing
            vwb_render::plugin::carry_identities(&self.doc.stack, &mut doc.stack);
            let inputs = headless::inputs_for(&doc)?;
            self.renderer.set_volume_format(doc.render.volume_format)?;
            headless::apply_render_switches(&mut self.renderer, &doc);
            let last = self.renderer.inputs().clone();
            self.renderer.set_inputs(inputs);
            if let Err(e) = self.renderer.update_stack(&doc.stack, doc.render.target) {
                self.renderer.set_inputs(last);
                return Err(e.into());
            }
        } else {
            self.renderer = self.fresh_renderer(volume, &doc)?;
        }
        self.doc = doc;
        self.preset_path = path.display().to_string();
        self.error = None;
        self.dirty = true;
        self.remember(path);
        Ok(format!("opened {}", path.display()))
    }

    /// The clip handles' interaction (before the frame renders, so a drag shows at
    /// once): moves a dragged centre; returns whether one is dragged and the screen
    /// segments of the outline to draw (the hovered or dragged shape's).
    fn clip_handles(
        &mut self,
        ui: &mut egui::Ui,
        rect: egui::Rect,
    ) -> (bool, Vec<[egui::Pos2; 2]>) {
        use crate::clip_handles as ch;
        let aspect = rect.width() / rect.height().max(1.0);
        let view = self.doc.camera.view(aspect);
        let vp = view.view_proj();
        let hs = ch::handles(&self.doc.stack, self.renderer.volume_box(), &view);
        let mut dragged = false;
        let mut outline = Vec::new();
        for (i, h) in hs.iter().enumerate() {
            let Some(pos) = ch::project(&vp, rect, h.at) else {
                continue;
            };
            if !rect.contains(pos) {
                continue;
            }
            let r = ui.interact(
                egui::Rect::from_center_size(pos, egui::Vec2::splat(2.0 * ch::RADIUS)),
                ui.scope_id().with(("clip handle", i)),
                egui::Sense::drag(),
            );
            let label = h.label.clone();
            r.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Slider, true, label.clone()));
            let r = r.on_hover_text(match h.kind {
                ch::HandleKind::Center => {
                    format!("{}: drag to move it in the image plane", h.label)
                }
                ch::HandleKind::Axis => format!("{}: drag to turn it", h.label),
                ch::HandleKind::Radius { .. } => format!("{}: drag to size it", h.label),
                ch::HandleKind::Extent { .. } => format!("{}: drag to resize the box", h.label),
            });
            if r.dragged() {
                let delta = r.drag_delta();
                if delta != egui::Vec2::ZERO {
                    ch::apply(&mut self.doc.stack, h, ch::dragged(&vp, rect, h.at, delta));
                    self.apply_stack();
                }
                dragged = true;
            }
            let active = r.dragged() || r.hovered();
            if active {
                outline = h
                    .outline(&self.doc.stack, self.renderer.volume())
                    .iter()
                    .filter_map(|[a, b]| {
                        Some([ch::project(&vp, rect, *a)?, ch::project(&vp, rect, *b)?])
                    })
                    .collect();
            }
            self.handle_marks.push((pos, active));
        }
        (dragged, outline)
    }

    fn viewport(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame) {
        let avail = ui.available_size();
        let (rect, response) = ui.allocate_exact_size(avail, egui::Sense::drag());
        let vbox = *self.renderer.volume_box();
        let cam = &mut self.doc.camera;
        if response.dragged_by(egui::PointerButton::Primary) {
            let d = response.drag_delta();
            cam.orbit(-d.x * 0.4, d.y * 0.4);
            self.dirty = true;
        }
        if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
        {
            let d = response.drag_delta();
            cam.pan(d.x / rect.height().max(1.0), d.y / rect.height().max(1.0));
            self.dirty = true;
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                cam.zoom((scroll * 0.002).exp());
                self.dirty = true;
            }
        }
        ui.input(|i| {
            if i.key_pressed(egui::Key::R) {
                *cam = Camera::default();
                cam.fit(vbox.min, vbox.max);
                self.dirty = true;
            }
            for (k, axis) in [
                (egui::Key::Num1, 0),
                (egui::Key::Num2, 1),
                (egui::Key::Num3, 2),
            ] {
                if i.key_pressed(k) {
                    cam.axis_view(axis, i.modifiers.shift);
                    self.dirty = true;
                }
            }
        });
        let (handle_dragged, outlines) = self.clip_handles(ui, rect);
        let ppp = ui.ctx().pixels_per_point();
        let moving = response.dragged()
            || handle_dragged
            || (response.hovered() && ui.input(|i| i.smooth_scroll_delta.y != 0.0));
        let moving = moving || self.editing;
        let scale = if moving {
            self.drag_resolution.clamp(0.05, 1.0) * self.quality_scale.clamp(0.05, 1.0)
        } else {
            self.quality_scale.clamp(0.05, 1.0)
        };
        let size = [
            ((rect.width() * ppp * scale) as u32).clamp(1, 4096),
            ((rect.height() * ppp * scale) as u32).clamp(1, 4096),
        ];
        // back to full quality once the camera stops
        if size != self.texture_size || (self.preview && !moving) {
            self.dirty = true;
        }
        if self.dirty {
            let mut settings = self.settings(size);
            if moving {
                settings.slice_spacing *= self.drag_spacing.max(1.0);
            }
            match self.renderer.render(&settings) {
                Ok(stats) => {
                    let ms = stats.gpu_ms.unwrap_or(stats.wall_ms);
                    self.frame_ms = Some(ms);
                    self.passes = stats.gpu_passes.clone();
                    self.history.push_back(ms);
                    while self.history.len() > 120 {
                        self.history.pop_front();
                    }
                    self.preview = moving;
                    self.show(frame, size);
                    self.dirty = false;
                }
                Err(e) => {
                    self.dirty = false;
                    // the last image stays on screen; an eye buffer that does not fit in
                    // GPU memory is retried at half the resolution, down to ⅛
                    if matches!(e, vwb_render::renderer::RenderError::OutOfMemory { .. })
                        && self.quality_scale > 0.125
                    {
                        self.quality_scale = (self.quality_scale * 0.5).max(0.125);
                        self.dirty = true;
                        ui.ctx().request_repaint();
                        self.error = Some(format!(
                            "{e}: retrying at {:.1} % of the full resolution (Quality: \
                             resolution × raises it again)",
                            self.quality_scale * 100.0
                        ));
                    } else {
                        self.error = Some(e.to_string());
                    }
                }
            }
        }
        // progressive light passes: draw again until every step is in
        if self.error.is_none() && self.renderer.refining() {
            self.dirty = true;
            ui.ctx().request_repaint();
        }
        if let Some(id) = self.texture {
            ui.painter().image(
                id,
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                egui::Color32::WHITE,
            );
            self.shown += 1;
        }
        // the clip handles over the image, the outline of the one in hand
        let painter = ui.painter_at(rect);
        for seg in &outlines {
            painter.line_segment(
                *seg,
                egui::Stroke::new(1.5, egui::Color32::from_rgb(255, 200, 60)),
            );
        }
        for (pos, active) in std::mem::take(&mut self.handle_marks) {
            let fill = if active {
                egui::Color32::from_rgb(255, 200, 60)
            } else {
                egui::Color32::from_rgba_unmultiplied(255, 200, 60, 120)
            };
            painter.circle(
                pos,
                crate::clip_handles::RADIUS,
                fill,
                egui::Stroke::new(1.0, egui::Color32::BLACK),
            );
        }
        // progressive volume passes (global light): how far the refinement is
        if let Some((done, total)) = self.renderer.refinement_progress()
            && total > 1
        {
            let text = if done < total {
                format!("refining light {done}/{total}")
            } else {
                format!("light refined ({total} steps)")
            };
            ui.put(
                egui::Rect::from_min_size(
                    rect.left_top() + egui::vec2(8.0, 6.0),
                    egui::vec2(220.0, 18.0),
                ),
                egui::Label::new(
                    egui::RichText::new(text)
                        .small()
                        .color(egui::Color32::from_gray(200)),
                )
                .selectable(false),
            );
        }
        let hint = egui::Rect::from_min_size(
            rect.left_bottom() + egui::vec2(8.0, -22.0),
            egui::vec2(rect.width() - 16.0, 18.0),
        );
        ui.put(
            hint,
            egui::Label::new(
                egui::RichText::new(CAMERA_HINT)
                    .small()
                    .color(egui::Color32::from_gray(170)),
            )
            .selectable(false),
        );
    }

    fn show(&mut self, frame: &eframe::Frame, size: [u32; 2]) {
        let Some(rs) = frame.wgpu_render_state() else {
            return;
        };
        let bg = self.doc.render.background;
        let Some(view) = self.renderer.display(bg) else {
            return;
        };
        let mut egui_renderer = rs.renderer.write();
        match self.texture {
            Some(id) => egui_renderer.update_egui_texture_from_wgpu_texture(
                &rs.device,
                view,
                wgpu::FilterMode::Linear,
                id,
            ),
            None => {
                self.texture = Some(egui_renderer.register_native_texture(
                    &rs.device,
                    view,
                    wgpu::FilterMode::Linear,
                ))
            }
        }
        self.texture_size = size;
    }

    fn screenshot(&mut self, ctx: &egui::Context) {
        match std::mem::replace(&mut self.shot, Shot::None) {
            Shot::Pending(path) if self.shown >= 2 => {
                let (tx, rx) = mpsc::channel();
                ctx.request_screenshot(move |img| {
                    let [w, h] = img.size;
                    let mut out = image::RgbImage::new(w as u32, h as u32);
                    for (px, c) in out.pixels_mut().zip(img.pixels.iter()) {
                        *px = image::Rgb([c.r(), c.g(), c.b()]);
                    }
                    let _ = tx.send(headless::save_png(&out, &path).map_err(|e| format!("{e:#}")));
                });
                self.shot = Shot::Requested(rx);
                ctx.request_repaint();
            }
            Shot::Requested(rx) => match rx.try_recv() {
                Ok(result) => {
                    if let Err(e) = result {
                        let _ = self.errors.send(e);
                    }
                    ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                }
                Err(mpsc::TryRecvError::Empty) => {
                    self.shot = Shot::Requested(rx);
                    ctx.request_repaint();
                }
                Err(mpsc::TryRecvError::Disconnected) => {
                    let _ = self.errors.send("screenshot was never delivered".into());
                    ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                }
            },
            other => {
                if matches!(other, Shot::Pending(_)) {
                    ctx.request_repaint();
                }
                self.shot = other;
            }
        }
    }
}

impl eframe::App for Workbench {
    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        let p = Persisted {
            recent: self.recent.clone(),
            preset_path: self.preset_path.clone(),
            volume_path: self.volume_path.clone(),
            session: Some(self.session()),
        };
        eframe::set_value(storage, STORAGE_KEY, &p);
    }

    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.file_events(&ctx);
        if self.plugin_watch_at.elapsed() >= std::time::Duration::from_secs(1) {
            self.plugin_watch_at = std::time::Instant::now();
            self.reload_user_plugins();
            self.reload_changed_volumes();
        }
        if self.poll_volume_loads() {
            ctx.request_repaint();
        } else if self.inputs_load.is_some() {
            ctx.request_repaint_after(std::time::Duration::from_millis(100));
        }
        egui::Panel::left("side").show(ui, |ui| {
            // wheel and scroll bar only: a drag belongs to the widget under it (stack
            // handles, TF editors, sliders)
            egui::ScrollArea::vertical()
                .scroll_source(egui::containers::scroll_area::ScrollSource {
                    drag: egui::containers::scroll_area::DragScroll::Never,
                    ..Default::default()
                })
                .show(ui, |ui| self.side_panel(ui));
        });
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| self.viewport(ui, frame));
        self.wgsl_window(&ctx);
        self.screenshot(&ctx);
    }
}

/// Named volumes loading in a background thread ([`Workbench::add_named_volume`] and
/// [`Workbench::reload_changed_volumes`] for files of at least
/// [`Workbench::async_load_bytes`]).
struct InputsLoad {
    /// The document's named volumes, loaded (they stay held while this lives).
    job: vwb_lab::job::Job<vwb_render::inputs::VolumeInputs>,
    /// The volume being added (its name and source); None for a reload.
    add: Option<(String, VolumeSource)>,
    /// The reloaded volumes with their files' stamps (for a reload).
    changed: Vec<(String, headless::Stamp)>,
    started: std::time::Instant,
}

impl InputsLoad {
    /// Loads `doc`'s named volumes in a thread ([`headless::inputs_for`]).
    fn start(
        doc: Document,
        add: Option<(String, VolumeSource)>,
        changed: Vec<(String, headless::Stamp)>,
    ) -> Self {
        let job = vwb_lab::job::Job::spawn("volume loading", move || {
            headless::inputs_for(&doc).map_err(|e| format!("{e:#}"))
        });
        Self {
            job,
            add,
            changed,
            started: std::time::Instant::now(),
        }
    }
}

/// `'a', 'b'`: the names of `changed`.
fn names_list(changed: &[(String, headless::Stamp)]) -> String {
    changed
        .iter()
        .map(|(n, _)| format!("'{n}'"))
        .collect::<Vec<_>>()
        .join(", ")
}
