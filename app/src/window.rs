//! The workbench window (eframe + wgpu): the viewport with an orbit camera, the plugin
//! stack editor with parameter widgets generated from each plugin's spec
//! ([`crate::stack_ui`]), preset open/save, slice settings and the frame time. The renderer draws
//! into its own eye buffer on eframe's device; the composited 8-bit image is shown as a
//! native egui texture.
//!
//! Camera: drag = orbit, right/middle drag = pan, wheel = zoom; R resets; 1/2/3 look
//! along x/y/z (shift: the opposite direction). While the camera moves the image is a
//! preview (coarser slices, lower resolution, both settable); it is redrawn at full
//! quality when the camera stops. The timing panel shows the frame time, the GPU time
//! per pass and a plot of the last 120 frames.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc;

use anyhow::{Result, anyhow};
use vwb_render::gpu::{self, GpuContext};
use vwb_render::plugin::{PluginInstance, Registry};
use vwb_render::preset::{Document, RenderSection, VolumeSource};
use vwb_render::renderer::{Backend, FrameSettings};
use vwb_render::{Camera, Renderer};

use crate::cli::{Cli, load_document};
use crate::headless;

/// The preset the workbench opens on (embedded, so it runs anywhere).
pub const DEMO_PRESET: &str = include_str!("../../presets/demo.ron");

/// The document shown when no preset is given: `presets/demo.ron` (the embedded demo
/// volume with a 1D transfer function).
pub fn default_document(registry: &Registry) -> Document {
    match Document::parse(DEMO_PRESET, "presets/demo.ron", registry) {
        Ok(loaded) => return loaded.document,
        Err(e) => log::error!("{e}"),
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

pub fn run(cli: &Cli) -> Result<()> {
    let mut doc = load_document(cli.preset.as_deref())?;
    if let Some(v) = &cli.volume {
        doc.volume = VolumeSource::File(v.clone());
    }
    let volume = headless::load_volume(&doc.volume)?;
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
            let app = Workbench::new(cc, doc, volume, screenshot, err_tx)?;
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow!("window: {e}"))?;
    if let Ok(e) = err_rx.try_recv() {
        return Err(anyhow!(e));
    }
    Ok(())
}

enum Shot {
    None,
    Pending(PathBuf),
    Requested(mpsc::Receiver<Result<(), String>>),
}

pub struct Workbench {
    doc: Document,
    registry: Registry,
    /// The preset path field (open / save).
    preset_path: String,
    /// Result of the last open or save.
    file_status: Option<Result<String, String>>,
    renderer: Renderer,
    texture: Option<egui::TextureId>,
    texture_size: [u32; 2],
    dirty: bool,
    frame_ms: Option<f64>,
    /// Per-pass GPU times of the last frame.
    passes: Vec<(String, f64)>,
    /// Frame times (ms) of the last frames, for the timing plot.
    history: std::collections::VecDeque<f64>,
    /// Progressive quality: while the camera moves, the slice spacing is multiplied by
    /// `drag_spacing` and the resolution by `drag_resolution`; full quality when idle.
    drag_spacing: f32,
    drag_resolution: f32,
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
        let mut renderer = Renderer::new(&gpu, volume)?;
        let error = renderer
            .update_stack(&doc.stack, doc.render.target)
            .err()
            .map(|e| e.to_string());
        Ok(Self {
            doc,
            registry: vwb_plugins::builtin_registry(),
            preset_path: "presets/my_preset.ron".into(),
            file_status: None,
            renderer,
            texture: None,
            texture_size: [0, 0],
            dirty: true,
            frame_ms: None,
            passes: Vec::new(),
            history: std::collections::VecDeque::new(),
            drag_spacing: 2.0,
            drag_resolution: 0.5,
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
        ui.separator();
        self.files(ui);
        ui.separator();
        ui.label("Plugins");
        let mut changed = false;
        egui::ScrollArea::vertical()
            .max_height(ui.available_height() * 0.6)
            .show(ui, |ui| {
                changed |= crate::stack_ui::stack_editor(
                    ui,
                    &self.registry,
                    &mut self.doc.stack,
                    self.error.as_deref(),
                    &self.renderer.volume().histogram,
                );
            });
        ui.separator();
        let r = &mut self.doc.render;
        changed |= ui
            .add(
                egui::Slider::new(&mut r.slice_spacing, 0.1..=8.0)
                    .logarithmic(true)
                    .text("slice spacing (voxels)"),
            )
            .changed();
        ui.horizontal(|ui| {
            changed |= ui
                .radio_value(&mut r.backend, Backend::Raster, "raster")
                .changed();
            changed |= ui
                .radio_value(&mut r.backend, Backend::Compute, "compute")
                .changed();
        });
        if changed {
            self.error = self
                .renderer
                .update_stack(&self.doc.stack, self.doc.render.target)
                .err()
                .map(|e| e.to_string());
            self.dirty = true;
        }
        ui.separator();
        ui.label("Preview while moving the camera");
        ui.add(
            egui::Slider::new(&mut self.drag_spacing, 1.0..=8.0)
                .logarithmic(true)
                .text("slice spacing ×"),
        );
        ui.add(egui::Slider::new(&mut self.drag_resolution, 0.125..=1.0).text("resolution ×"));
        ui.separator();
        self.timing(ui);
        ui.separator();
        self.compare_view(ui);
    }

    /// Frame time, per-pass GPU times and a plot of the last frames.
    fn timing(&self, ui: &mut egui::Ui) {
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
            });
    }

    /// The GPU image beside the CPU reference of the same frame, the ΔE*uv heatmap and
    /// the metrics; the reference runs in a thread (progress, cancel).
    fn compare_view(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Compare with the CPU reference").show(ui, |ui| {
            ui.add(egui::Slider::new(&mut self.compare_side, 32..=512).text("image side"));
            if let Some(job) = &self.compare_job {
                ui.add(egui::ProgressBar::new(job.fraction()).show_percentage());
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
        let bg = crate::measure::background(&self.doc);
        let gpu = vwb_render::metrics::RgbImageF::from_rgba_f32_premultiplied_over(&px, w, h, bg);
        // the viewport is redrawn at its own size next frame
        self.dirty = true;
        Ok(crate::compare_ui::CompareJob::start(
            self.renderer.volume().clone(),
            self.doc.stack.clone(),
            settings,
            self.doc.render.target,
            gpu,
            bg,
        ))
    }

    /// Preset open and save (atomic: a failed save leaves the old file as it was).
    fn files(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.text_edit_singleline(&mut self.preset_path);
        });
        ui.horizontal(|ui| {
            let path = PathBuf::from(self.preset_path.trim());
            if ui.button("Open preset").clicked() {
                self.file_status = Some(self.open(&path).map_err(|e| format!("{e:#}")));
            }
            if ui.button("Save preset").clicked() {
                self.file_status = Some(
                    self.doc
                        .save(&path)
                        .map(|_| format!("saved {}", path.display()))
                        .map_err(|e| e.to_string()),
                );
            }
        });
        match &self.file_status {
            Some(Ok(m)) => {
                ui.label(m);
            }
            Some(Err(e)) => {
                ui.colored_label(egui::Color32::RED, e);
            }
            None => {}
        }
    }

    /// Loads a preset (and its volume); the current one stays on any error.
    fn open(&mut self, path: &std::path::Path) -> Result<String> {
        let doc = Document::load(path, &self.registry)?.document;
        let volume = headless::load_volume(&doc.volume)?;
        let mut renderer = Renderer::new(self.renderer.gpu(), volume)?;
        renderer.update_stack(&doc.stack, doc.render.target)?;
        self.renderer = renderer;
        self.doc = doc;
        self.error = None;
        self.dirty = true;
        Ok(format!("opened {}", path.display()))
    }

    fn viewport(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame) {
        let avail = ui.available_size();
        let (rect, response) = ui.allocate_exact_size(avail, egui::Sense::drag());
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
        let ppp = ui.ctx().pixels_per_point();
        let moving = response.dragged()
            || (response.hovered() && ui.input(|i| i.smooth_scroll_delta.y != 0.0));
        let scale = if moving {
            self.drag_resolution.clamp(0.05, 1.0)
        } else {
            1.0
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
                }
                Err(e) => self.error = Some(e.to_string()),
            }
            self.dirty = false;
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
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        egui::Panel::left("side").show(ui, |ui| self.side_panel(ui));
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| self.viewport(ui, frame));
        let ctx = ui.ctx().clone();
        self.screenshot(&ctx);
    }
}
