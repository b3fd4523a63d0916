//! The window's transfer-function gallery (design galleries, docs/search.md): "New
//! gallery" draws a seeded pool for the current scene and shows the most dispersed
//! genomes on their MDS grid; clicking a thumbnail refines around it (a smaller mutation
//! radius each time); right-click puts a genome's TF into the stack's classify.tf1d
//! (classify.tf2d on a 2D stack; the preset is then saved as usual); hovering shows a
//! genome's views enlarged. The
//! visited galleries form an image graph (after Ma 1999): each refinement hangs under
//! the gallery it was picked from, "Back" goes to the parent, and clicking a node of
//! the graph returns to that gallery, so a branch once left is not lost. The renders
//! run in a background job on the window's device.

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
    /// Per genome, a texture per view (the first view is the thumbnail).
    pub textures: Vec<Vec<egui::TextureHandle>>,
    pub radius: f64,
    pub summary: String,
    /// The gallery this one refines (None: a new gallery, a root of the graph).
    pub parent: Option<usize>,
    /// The image of the graph's node: the pick this gallery refines, or for a new
    /// gallery its first thumbnail.
    node: egui::TextureHandle,
}

/// A gallery being rendered: the job, its radius, and the gallery it refines with
/// the pick's thumbnail (None: a new gallery).
type PendingGallery = (
    Job<gallery::Gallery>,
    f64,
    Option<(usize, egui::TextureHandle)>,
);

/// The panel's state.
#[derive(Default)]
pub struct GalleryPanel {
    /// Every visited gallery: the nodes of the image graph, in the order made.
    pub history: Vec<Page>,
    /// The gallery shown (an index into `history`).
    pub current: usize,
    job: Option<PendingGallery>,
    pub error: Option<String>,
    seed: u64,
}

/// What the user asked for this frame.
pub enum GalleryAction {
    /// Put this genome's TF into the stack.
    Apply(Genome),
}

/// Textures of every genome's views (`views[genome][view]`), named `prefix genome view`.
pub fn view_textures(
    ctx: &egui::Context,
    prefix: &str,
    views: &[Vec<vwb_render::metrics::RgbImageF>],
) -> Vec<Vec<egui::TextureHandle>> {
    views
        .iter()
        .enumerate()
        .map(|(i, views)| {
            views
                .iter()
                .enumerate()
                .map(|(v, img)| {
                    let rgb = img.to_rgb8();
                    let c = egui::ColorImage::from_rgb(
                        [rgb.width() as usize, rgb.height() as usize],
                        rgb.as_raw(),
                    );
                    ctx.load_texture(format!("{prefix} {i} {v}"), c, egui::TextureOptions::LINEAR)
                })
                .collect()
        })
        .collect()
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
        // a refinement hangs under the gallery shown, its node the pick's thumbnail; a
        // new gallery is a root
        let parent = around.as_ref().and_then(|(g, _)| {
            let page = self.page()?;
            let i = page.genomes.iter().position(|x| x == g)?;
            Some((self.current, page.textures[i][0].clone()))
        });
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
            parent,
        ));
    }

    /// The gallery shown.
    pub fn page(&self) -> Option<&Page> {
        self.history.get(self.current)
    }

    /// Shows the parent of the gallery shown (the graph keeps every gallery).
    pub fn back(&mut self) {
        if let Some(p) = self.page().and_then(|p| p.parent) {
            self.current = p;
        }
    }

    /// Whether a gallery is being rendered.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }

    /// Takes a finished job's gallery into the history.
    pub fn poll(&mut self, ctx: &egui::Context) {
        let Some((job, radius, parent)) = &self.job else {
            return;
        };
        let (radius, parent) = (*radius, parent.clone());
        match job.poll() {
            None => ctx.request_repaint(),
            Some(Err(e)) => {
                self.error = Some(e);
                self.job = None;
            }
            Some(Ok(g)) => {
                let summary = vwb_lab::search::summary(&g);
                let page = self.history.len();
                let textures = view_textures(ctx, &format!("gallery {page}"), &g.views);
                let (parent, node) = match parent {
                    Some((p, node)) => (Some(p), node),
                    None => (None, textures[0][0].clone()),
                };
                self.history.push(Page {
                    genomes: g.chosen.iter().map(|&i| g.pool[i].clone()).collect(),
                    cells: g.cells.clone(),
                    cols: g.cols,
                    textures,
                    radius,
                    summary,
                    parent,
                    node,
                });
                self.current = page;
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
            let has_parent = self.page().is_some_and(|p| p.parent.is_some());
            if ui
                .add_enabled(has_parent && !self.busy(), egui::Button::new("Back"))
                .on_hover_text("the gallery this one refines (the graph keeps both)")
                .clicked()
            {
                self.back();
            }
            if self.busy() {
                ui.spinner();
                ui.label("rendering…");
            }
        });
        if let Some(e) = &self.error {
            ui.colored_label(egui::Color32::RED, e);
        }
        if self.history.len() > 1 {
            self.graph_ui(ui);
        }
        let Some(page) = self.page() else {
            ui.weak("No gallery yet.");
            return None;
        };
        ui.small(format!(
            "{} · gallery {} of {} · radius {:.2}",
            page.summary,
            self.current + 1,
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
                                let views = &page.textures[i];
                                let r = ui
                                    .add(
                                        egui::Image::new((views[0].id(), size))
                                            .alt_text(format!("gallery TF {i}"))
                                            .sense(egui::Sense::click()),
                                    )
                                    .on_hover_ui(|ui| {
                                        ui.horizontal(|ui| {
                                            for t in views {
                                                ui.image((t.id(), 3.0 * size));
                                            }
                                        });
                                        ui.label(
                                            "click: refine around this TF · right-click: apply it",
                                        );
                                    });
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

    /// The image graph: every visited gallery as its first thumbnail (for a refinement,
    /// the pick it refines), indented under the gallery it was picked from; the
    /// gallery shown is framed, and a click shows another.
    fn graph_ui(&mut self, ui: &mut egui::Ui) {
        // depth-first order from the roots
        let mut order = Vec::new();
        let mut stack: Vec<(usize, usize)> = (0..self.history.len())
            .rev()
            .filter(|&i| self.history[i].parent.is_none())
            .map(|i| (i, 0))
            .collect();
        while let Some((i, depth)) = stack.pop() {
            order.push((i, depth));
            for c in (0..self.history.len()).rev() {
                if self.history[c].parent == Some(i) {
                    stack.push((c, depth + 1));
                }
            }
        }
        let size = egui::vec2(20.0, 20.0);
        let mut go = None;
        egui::CollapsingHeader::new("Visited galleries")
            .default_open(true)
            .show(ui, |ui| {
                for (i, depth) in order {
                    let page = &self.history[i];
                    ui.horizontal(|ui| {
                        ui.add_space(12.0 * depth as f32);
                        let r = ui.add(
                            egui::Image::new((page.node.id(), size))
                                .alt_text(format!("visited gallery {}", i + 1))
                                .sense(egui::Sense::click()),
                        );
                        if i == self.current {
                            ui.painter().rect_stroke(
                                r.rect,
                                0.0,
                                egui::Stroke::new(2.0, egui::Color32::YELLOW),
                                egui::StrokeKind::Outside,
                            );
                        }
                        if r.clicked() {
                            go = Some(i);
                        }
                        ui.small(format!("gallery {} · radius {:.2}", i + 1, page.radius));
                    });
                }
            });
        if let Some(i) = go {
            self.current = i;
        }
    }
}
