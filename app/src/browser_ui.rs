//! The preset browser: the shipped presets (`presets/` under the working directory)
//! and the user's own (recent `.ron` files) as a grid of thumbnails with names and
//! one-line descriptions; a click opens one.
//!
//! Thumbnails are rendered in the background, one at a time, on the window's device
//! ([`vwb_lab::job::Job`]) and cached as PNGs: a user preset's beside it
//! (`NAME.thumb.png`, also written when the window saves a preset), a shipped preset's
//! in the user's cache (`vwb/thumbnails/`). A cached thumbnail older than its preset
//! is rendered again.

use std::path::{Path, PathBuf};

use vwb_render::GpuContext;
use vwb_render::preset::Document;

use vwb_lab::job::Job;

pub use vwb_lab::thumbnail::{THUMB, render_thumbnail, save_thumbnail, thumbnail_path};

/// The user's thumbnail cache for the shipped presets.
fn default_cache() -> PathBuf {
    dirs::cache_dir()
        .unwrap_or_else(std::env::temp_dir)
        .join("vwb")
        .join("thumbnails")
}

enum Thumb {
    Waiting,
    Ready(egui::TextureHandle),
    Failed(String),
}

struct Entry {
    path: PathBuf,
    name: String,
    description: String,
    shipped: bool,
    thumb: Thumb,
}

#[derive(Default)]
pub struct PresetBrowser {
    /// Thumbnail cache of the shipped presets (default: the user's cache + vwb/thumbnails).
    pub cache: Option<PathBuf>,
    entries: Vec<Entry>,
    /// The thumbnail being rendered: entry index and job.
    job: Option<(usize, Job<image::RgbImage>)>,
}

impl PresetBrowser {
    /// Lists the shipped presets and the user's (`recent` `.ron` files), keeping the
    /// thumbnails of entries already listed.
    pub fn refresh(&mut self, recent: &[PathBuf]) {
        let mut paths: Vec<(PathBuf, bool)> = std::fs::read_dir("presets")
            .map(|d| {
                d.filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.extension().is_some_and(|e| e == "ron"))
                    .map(|p| (p, true))
                    .collect()
            })
            .unwrap_or_default();
        paths.sort();
        for p in recent {
            let shipped = paths.iter().any(|(q, _)| {
                std::fs::canonicalize(q).is_ok_and(|q| Some(q) == std::fs::canonicalize(p).ok())
            });
            if !shipped && p.extension().is_some_and(|e| e == "ron") && p.exists() {
                paths.push((p.clone(), false));
            }
        }
        let registry = vwb_plugins::registry();
        let mut old = std::mem::take(&mut self.entries);
        for (path, shipped) in paths {
            if let Some(i) = old.iter().position(|e| e.path == path) {
                self.entries.push(old.swap_remove(i));
                continue;
            }
            let description = Document::load(&path, &registry)
                .map(|l| l.document.description)
                .unwrap_or_else(|e| e.to_string());
            self.entries.push(Entry {
                name: path
                    .file_stem()
                    .map_or_else(String::new, |s| s.to_string_lossy().to_string()),
                description: description.lines().next().unwrap_or("").to_string(),
                path,
                shipped,
                thumb: Thumb::Waiting,
            });
        }
        self.job = None;
    }

    /// Names of the listed presets.
    pub fn names(&self) -> Vec<&str> {
        self.entries.iter().map(|e| e.name.as_str()).collect()
    }

    /// Whether the thumbnail of preset `name` is drawn.
    pub fn ready(&self, name: &str) -> bool {
        self.entries
            .iter()
            .any(|e| e.name == name && matches!(e.thumb, Thumb::Ready(_)))
    }

    /// Why the thumbnail of preset `name` could not be drawn.
    pub fn failure(&self, name: &str) -> Option<&str> {
        self.entries.iter().find_map(|e| match &e.thumb {
            Thumb::Failed(m) if e.name == name => Some(m.as_str()),
            _ => None,
        })
    }

    fn cache_of(&self, e: &Entry) -> PathBuf {
        let cache = self.cache.clone().unwrap_or_else(default_cache);
        thumbnail_path(&e.path, e.shipped.then_some(cache.as_path()))
    }

    /// Loads cached thumbnails and renders the next missing one in the background.
    fn advance(&mut self, ctx: &egui::Context, gpu: &GpuContext) {
        if let Some((i, job)) = &self.job {
            match job.poll() {
                None => return,
                Some(result) => {
                    let i = *i;
                    self.job = None;
                    let cache = self.entries.get(i).map(|e| self.cache_of(e));
                    if let (Some(e), Some(cache)) = (self.entries.get_mut(i), cache) {
                        e.thumb = match result {
                            Ok(img) => {
                                if let Err(err) = save_thumbnail(&img, &cache) {
                                    log::warn!("{err:#}");
                                }
                                Thumb::Ready(texture(ctx, &e.name, &img))
                            }
                            Err(msg) => Thumb::Failed(msg),
                        };
                    }
                }
            }
        }
        let Some(i) = self
            .entries
            .iter()
            .position(|e| matches!(e.thumb, Thumb::Waiting))
        else {
            return;
        };
        let cache = self.cache_of(&self.entries[i]);
        let e = &mut self.entries[i];
        let fresh = |c: &Path| -> Option<()> {
            let t = std::fs::metadata(c).ok()?.modified().ok()?;
            let p = std::fs::metadata(&e.path).ok()?.modified().ok()?;
            (t >= p).then_some(())
        };
        if fresh(&cache).is_some()
            && let Ok(img) = image::open(&cache)
        {
            e.thumb = Thumb::Ready(texture(ctx, &e.name, &img.to_rgb8()));
            ctx.request_repaint();
            return;
        }
        let (gpu, path) = (gpu.clone(), e.path.clone());
        self.job = Some((
            i,
            Job::spawn("thumbnail", move || {
                render_thumbnail(&gpu, &path).map_err(|e| format!("{e:#}"))
            }),
        ));
        ctx.request_repaint();
    }

    /// The grid; returns the preset clicked.
    pub fn ui(&mut self, ui: &mut egui::Ui, gpu: &GpuContext) -> Option<PathBuf> {
        self.advance(ui.ctx(), gpu);
        if self.job.is_some() {
            ui.ctx().request_repaint();
        }
        let mut open = None;
        ui.horizontal_wrapped(|ui| {
            for e in &self.entries {
                ui.vertical(|ui| {
                    ui.set_width(THUMB as f32 + 8.0);
                    let size = egui::vec2(THUMB as f32, THUMB as f32);
                    let clicked = match &e.thumb {
                        Thumb::Ready(t) => ui
                            .add(
                                egui::Image::new((t.id(), size))
                                    .alt_text(format!("thumbnail of {}", e.name))
                                    .sense(egui::Sense::click()),
                            )
                            .on_hover_text(format!("open {}", e.path.display())),
                        Thumb::Waiting => ui.add_sized(size, egui::Button::new("…")),
                        Thumb::Failed(msg) => ui
                            .add_sized(size, egui::Button::new("no image"))
                            .on_hover_text(msg),
                    }
                    .clicked();
                    if ui.button(&e.name).clicked() || clicked {
                        open = Some(e.path.clone());
                    }
                    ui.small(&e.description);
                });
            }
        });
        open
    }
}

fn texture(ctx: &egui::Context, name: &str, img: &image::RgbImage) -> egui::TextureHandle {
    let c = egui::ColorImage::from_rgb([img.width() as usize, img.height() as usize], img.as_raw());
    ctx.load_texture(format!("thumbnail {name}"), c, egui::TextureOptions::LINEAR)
}
