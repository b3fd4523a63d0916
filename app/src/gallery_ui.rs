//! The window's transfer-function gallery (design galleries, docs/search.md): "New
//! gallery" draws a seeded pool for the current scene and shows the most dispersed
//! genomes on their MDS grid; clicking a thumbnail refines around it (a smaller mutation
//! radius each time); "Apply" puts a genome's TF into the stack's classify.tf1d (the
//! preset is then saved as usual); "Back" steps through the history of galleries. The
//! renders run in a background job on the window's device.

use std::sync::Arc;

use vwb_lab::job::Job;
use vwb_render::GpuContext;
use vwb_render::plugin::PluginInstance;
use vwb_render::preset::Document;
use vwb_render::search::gallery::{self, GalleryOptions};
use vwb_render::search::genome::Genome;
use vwb_render::volume::Volume;

/// Thumbnail side in the window.
const TILE: u32 = 48;

/// One finished gallery.
pub struct Page {
    pub genomes: Vec<Genome>,
    pub cells: Vec<[u32; 2]>,
    pub cols: u32,
    pub textures: Vec<egui::TextureHandle>,
    pub radius: f64,
    pub summary: String,
}

/// The panel's state.
#[derive(Default)]
pub struct GalleryPanel {
    /// Visited galleries, the last one shown.
    pub history: Vec<Page>,
    job: Option<(Job<gallery::Gallery>, f64)>,
    pub error: Option<String>,
    seed: u64,
}

/// What the user asked for this frame.
pub enum GalleryAction {
    /// Put this genome's TF into the stack.
    Apply(Genome),
}

fn texture(
    ctx: &egui::Context,
    i: usize,
    img: &vwb_render::metrics::RgbImageF,
) -> egui::TextureHandle {
    let rgb = img.to_rgb8();
    let c = egui::ColorImage::from_rgb([rgb.width() as usize, rgb.height() as usize], rgb.as_raw());
    ctx.load_texture(format!("gallery {i}"), c, egui::TextureOptions::LINEAR)
}

impl GalleryPanel {
    /// Starts a gallery (at random, or refined around `around` with `radius`).
    pub fn start(
        &mut self,
        gpu: &GpuContext,
        doc: &Document,
        volume: Arc<Volume>,
        around: Option<(Genome, f64)>,
    ) {
        self.seed += 1;
        let radius = around.as_ref().map_or(1.0, |(_, r)| *r);
        let o = GalleryOptions {
            pool: 48,
            k: 16,
            tile: TILE,
            views: 3,
            seed: self.seed,
            around,
            batch: 72,
            ..Default::default()
        };
        let (gpu, stack, camera): (GpuContext, Vec<PluginInstance>, _) =
            (gpu.clone(), doc.stack.clone(), doc.camera);
        let bg = vwb_lab::measure::background(doc);
        let mut d = doc.clone();
        d.stack = stack.clone();
        self.error = None;
        self.job = Some((
            Job::spawn("gallery", move || {
                let mut r = vwb_lab::headless::renderer_for(&gpu, &d, volume)
                    .map_err(|e| format!("{e:#}"))?;
                gallery::gallery(&mut r, &stack, &camera, bg, &o).map_err(|e| e.to_string())
            }),
            radius,
        ));
    }

    /// Whether a gallery is being rendered.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }

    /// Takes a finished job's gallery into the history.
    pub fn poll(&mut self, ctx: &egui::Context) {
        let Some((job, radius)) = &self.job else {
            return;
        };
        let radius = *radius;
        match job.poll() {
            None => ctx.request_repaint(),
            Some(Err(e)) => {
                self.error = Some(e);
                self.job = None;
            }
            Some(Ok(g)) => {
                let summary = vwb_lab::search::summary(&g);
                self.history.push(Page {
                    genomes: g.chosen.iter().map(|&i| g.pool[i].clone()).collect(),
                    cells: g.cells.clone(),
                    cols: g.cols,
                    textures: g
                        .thumbnails
                        .iter()
                        .enumerate()
                        .map(|(i, t)| texture(ctx, i, t))
                        .collect(),
                    radius,
                    summary,
                });
                self.job = None;
            }
        }
    }

    /// The panel. Returns a genome to apply; `refine` is set to a genome to refine
    /// around (with the next radius) when a thumbnail is clicked.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        new_gallery: &mut bool,
        refine: &mut Option<(Genome, f64)>,
    ) -> Option<GalleryAction> {
        self.poll(ui.ctx());
        let mut action = None;
        ui.horizontal(|ui| {
            if ui
                .add_enabled(!self.busy(), egui::Button::new("New gallery"))
                .on_hover_text("16 dispersed TFs out of 48 random ones, from 3 viewpoints")
                .clicked()
            {
                *new_gallery = true;
            }
            if ui
                .add_enabled(
                    self.history.len() > 1 && !self.busy(),
                    egui::Button::new("Back"),
                )
                .clicked()
            {
                self.history.pop();
            }
            if self.busy() {
                ui.spinner();
                ui.label("rendering…");
            }
        });
        if let Some(e) = &self.error {
            ui.colored_label(egui::Color32::RED, e);
        }
        let Some(page) = self.history.last() else {
            ui.weak("No gallery yet.");
            return None;
        };
        ui.small(format!(
            "{} · step {} · radius {:.2}",
            page.summary,
            self.history.len(),
            page.radius
        ));
        let rows = page.cells.iter().map(|c| c[1]).max().map_or(0, |r| r + 1);
        let size = egui::vec2(TILE as f32, TILE as f32);
        egui::Grid::new("gallery grid")
            .spacing([2.0, 2.0])
            .show(ui, |ui| {
                for row in 0..rows {
                    for col in 0..page.cols {
                        match page.cells.iter().position(|c| *c == [col, row]) {
                            Some(i) => {
                                let r = ui
                                    .add(
                                        egui::Image::new((page.textures[i].id(), size))
                                            .alt_text(format!("gallery TF {i}"))
                                            .sense(egui::Sense::click()),
                                    )
                                    .on_hover_text(
                                        "click: refine around this TF · right-click: apply it",
                                    );
                                if r.clicked() {
                                    *refine = Some((
                                        page.genomes[i].clone(),
                                        (page.radius * 0.5).clamp(0.05, 0.5),
                                    ));
                                }
                                if r.secondary_clicked() {
                                    action = Some(GalleryAction::Apply(page.genomes[i].clone()));
                                }
                            }
                            None => {
                                ui.allocate_space(size);
                            }
                        }
                    }
                    ui.end_row();
                }
            });
        action
    }
}
