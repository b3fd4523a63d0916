//! The window's genetic search (docs/search.md, "Genetic search"): a population of TFs
//! for the current scene, one generation per click. Fitness is the user's picks
//! (click thumbnails to keep them, then "Next generation" breeds from the picks
//! alone), an image objective, or a target image (the views side by side, as
//! `vwb evolve` writes `target.png` and `best.png`). Objectives and targets can also
//! run several generations at once. Hovering a thumbnail shows its three views
//! enlarged; right-click applies its TF to the stack (save the preset to keep it).
//! The renders run in a background job on the window's device, and every run is as
//! seeded as `vwb evolve`'s.

use std::sync::Arc;

use vwb_lab::job::Job;
use vwb_render::GpuContext;
use vwb_render::camera::Camera;
use vwb_render::metrics::RgbImageF;
use vwb_render::preset::Document;
use vwb_render::search::coverage::Coverage;
use vwb_render::search::genetic::{Fitness, Ga, GaOptions, Generation, Objective};
use vwb_render::search::genome::{Genome, Space};
use vwb_render::volume::Volume;

/// Thumbnail side, population and viewpoints in the window (small: it renders on the
/// window's device between frames).
pub const TILE: u32 = 48;
pub const POPULATION: usize = 16;
const VIEWS: usize = 3;
/// Generations per "Run" click with an objective or a target.
pub const RUN_GENERATIONS: usize = 5;

/// What a generation is judged by.
#[derive(Debug, Clone, PartialEq)]
pub enum Judge {
    /// The thumbnails the user clicks.
    Picks,
    Objective(Objective),
    /// A target image: the views side by side, `TILE` high.
    Target(String),
    /// The data's visible-boundary coverage (vwb_render::search::coverage).
    Coverage,
}

impl Judge {
    /// A score as the user reads it: the objective itself (higher is better), or the
    /// RMS ΔE*uv to the target (lower is better).
    fn shown(&self, score: f64) -> f64 {
        match self {
            Judge::Objective(_) | Judge::Coverage => -score,
            _ => score,
        }
    }

    /// What [`Judge::shown`] is called.
    fn measure(&self) -> String {
        match self {
            Judge::Objective(_) | Judge::Coverage => format!("{} (higher is better)", self.label()),
            _ => "RMS ΔE*uv to the target (lower is better)".into(),
        }
    }

    fn label(&self) -> String {
        match self {
            Judge::Picks => "my picks".into(),
            Judge::Objective(o) => o.name().replace('_', " "),
            Judge::Target(_) => "target image".into(),
            Judge::Coverage => "boundary coverage".into(),
        }
    }
}

/// A finished job: the population it ends on, its views and scores, and the
/// generations it went through.
struct Step {
    ga: Ga,
    views: Vec<Vec<RgbImageF>>,
    scores: Option<Vec<f64>>,
    generations: Vec<Generation>,
    /// The coverage model the job used, for the next job.
    coverage: Option<CoverageCache>,
}

/// The panel's state.
pub struct GaPanel {
    pub judge: Judge,
    /// The current population (None before "Start").
    pub ga: Option<Ga>,
    /// Every genome's views, in population order.
    pub views: Vec<Vec<RgbImageF>>,
    /// The current population's scores (None when judged by picks).
    pub scores: Option<Vec<f64>>,
    /// Indices of the picked genomes.
    pub picks: Vec<usize>,
    /// Best and mean score of each scored generation so far.
    pub progress: Vec<Generation>,
    textures: Vec<Vec<egui::TextureHandle>>,
    job: Option<(Job<Step>, usize)>,
    pub error: Option<String>,
    seed: u64,
    coverage: Option<CoverageCache>,
}

impl Default for GaPanel {
    fn default() -> Self {
        GaPanel {
            judge: Judge::Picks,
            ga: None,
            views: Vec::new(),
            scores: None,
            picks: Vec::new(),
            progress: Vec::new(),
            textures: Vec::new(),
            job: None,
            error: None,
            seed: 0,
            coverage: None,
        }
    }
}

/// What the user asked for this frame.
pub enum GaAction {
    /// Breed `n` generations (picks: always 1); 0 starts a new seeded population.
    Advance(usize),
    /// Put this genome's TF into the stack.
    Apply(Genome),
}

/// The coverage model of a volume from a camera's viewpoints, kept between
/// generations: it is recomputed only when the volume, the camera or what the stack's
/// TF needs of it (`Coverage::gradient_scale_of`) changes.
type CoverageCache = (Arc<Volume>, Camera, Arc<Coverage>);

/// The fitness a judge gives (None for picks), on `volume` seen from `camera`'s
/// viewpoints with `stack`'s TF; `cached`: the coverage model of that volume and
/// camera, where known.
fn fitness(
    judge: &Judge,
    o: &GaOptions,
    volume: &Volume,
    camera: &Camera,
    stack: &[vwb_render::plugin::PluginInstance],
    cached: Option<Arc<Coverage>>,
) -> Result<Option<Fitness>, String> {
    Ok(match judge {
        Judge::Picks => None,
        Judge::Objective(obj) => Some(Fitness::Objective(*obj)),
        Judge::Coverage => {
            let scale = Coverage::gradient_scale_of(stack)?;
            Some(Fitness::Coverage(match cached {
                Some(c) if c.gradient_scale() == scale => c,
                _ => {
                    let cams = vwb_render::search::gallery::viewpoints(camera, o.views);
                    Arc::new(Coverage::for_stack(volume, &cams, o.tile, stack)?)
                }
            }))
        }
        Judge::Target(path) => {
            let views = vwb_lab::search::read_target(std::path::Path::new(path), o)
                .map_err(|e| format!("{e:#}"))?;
            Some(Fitness::Target(vwb_render::search::gallery::descriptor(
                &views,
            )))
        }
    })
}

impl GaPanel {
    /// Whether a generation is being rendered.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }

    /// The options of a new run (its seed advances with every start).
    fn options(&self) -> GaOptions {
        GaOptions {
            population: POPULATION,
            tile: TILE,
            views: VIEWS,
            seed: self.seed,
            batch: 48,
            ..Default::default()
        }
    }

    /// Starts a run (`n` = 0) or breeds `n` generations from the current one: the
    /// renders run in a background job.
    pub fn advance(&mut self, gpu: &GpuContext, doc: &Document, volume: Arc<Volume>, n: usize) {
        let (ga, picks) = match (&self.ga, n) {
            (Some(ga), n) if n > 0 => (ga.clone(), self.picks.clone()),
            _ => {
                // the TF model of the stack: classify.tf1d or classify.tf2d
                let space = match Space::of_stack(&doc.stack) {
                    Ok(s) => s,
                    Err(e) => {
                        self.error = Some(e);
                        return;
                    }
                };
                self.seed += 1;
                self.progress.clear();
                (
                    Ga::new(&GaOptions {
                        space,
                        ..self.options()
                    }),
                    Vec::new(),
                )
            }
        };
        if n > 0 && self.judge == Judge::Picks && picks.is_empty() {
            self.error = Some("pick the thumbnails to breed from first".into());
            return;
        }
        let (judge, current) = (self.judge.clone(), self.views.clone());
        let cached = self
            .coverage
            .as_ref()
            .filter(|(v, c, _)| Arc::ptr_eq(v, &volume) && *c == doc.camera)
            .map(|(_, _, model)| model.clone());
        let (gpu, stack, camera) = (gpu.clone(), doc.stack.clone(), doc.camera);
        let bg = vwb_lab::measure::background(doc);
        let d = doc.clone();
        self.error = None;
        self.job = Some((
            Job::spawn("genetic search", move || {
                let fitness = fitness(&judge, &ga.options, &volume, &camera, &stack, cached)?;
                let coverage = match &fitness {
                    Some(Fitness::Coverage(c)) => Some((volume.clone(), camera, c.clone())),
                    _ => None,
                };
                let score = |ga: &Ga, views: &[Vec<RgbImageF>]| {
                    fitness.as_ref().map(|f| {
                        ga.population
                            .iter()
                            .zip(views)
                            .map(|(g, v)| f.score(g, v))
                            .collect::<Vec<f64>>()
                    })
                };
                // the current population's scores by the current judge, so that a
                // judge chosen after the render counts
                let mut scores = if n > 0 { score(&ga, &current) } else { None };
                let mut r = vwb_lab::headless::renderer_for(&gpu, &d, volume.clone())
                    .map_err(|e| format!("{e:#}"))?;
                let mut ga = ga;
                let mut generations = Vec::new();
                let mut render = |ga: &Ga| -> Result<_, String> {
                    let views = ga
                        .render(&mut r, &stack, &camera, bg)
                        .map_err(|e| e.to_string())?;
                    let s = score(ga, &views);
                    Ok((views, s))
                };
                if n == 0 {
                    let (views, s) = render(&ga)?;
                    generations.extend(s.as_ref().map(|s| ga.summary(s)));
                    return Ok(Step {
                        ga,
                        views,
                        scores: s,
                        generations,
                        coverage,
                    });
                }
                let mut last = None;
                let target = fitness.as_ref().and_then(Fitness::target_pixels);
                let mut shown = current;
                for _ in 0..n {
                    match (&scores, &target) {
                        (Some(s), Some(t)) => ga.breed_toward(s, &shown, t),
                        (Some(s), None) => ga.breed(s),
                        (None, _) => ga.breed_from_picks(&picks),
                    }
                    let (views, s) = render(&ga)?;
                    shown = views.clone();
                    generations.extend(s.as_ref().map(|s| ga.summary(s)));
                    scores = s.clone();
                    last = Some((views, s));
                }
                let (views, scores) = last.expect("n > 0");
                Ok(Step {
                    ga,
                    views,
                    scores,
                    generations,
                    coverage,
                })
            }),
            n,
        ));
    }

    /// Takes a finished job's generation.
    pub fn poll(&mut self, ctx: &egui::Context) {
        let Some((job, _)) = &self.job else {
            return;
        };
        match job.poll() {
            None => ctx.request_repaint(),
            Some(Err(e)) => {
                self.error = Some(e);
                self.job = None;
            }
            Some(Ok(step)) => {
                self.textures = crate::gallery_ui::view_textures(ctx, "ga", &step.views);
                self.progress.extend(step.generations);
                if step.coverage.is_some() {
                    self.coverage = step.coverage;
                }
                self.ga = Some(step.ga);
                self.views = step.views;
                self.scores = step.scores;
                self.picks.clear();
                self.job = None;
            }
        }
    }

    /// The coverage model the last coverage-judged generation used (kept until the
    /// volume or the camera changes).
    pub fn coverage_model(&self) -> Option<&Arc<Coverage>> {
        self.coverage.as_ref().map(|(_, _, c)| c)
    }

    /// The genome the panel would apply: the best scored, or the first pick.
    pub fn best(&self) -> Option<Genome> {
        let ga = self.ga.as_ref()?;
        match &self.scores {
            Some(s) => Some(ga.summary(s).best),
            None => self.picks.first().map(|&i| ga.population[i].clone()),
        }
    }

    /// The panel; returns what the user asked for.
    pub fn ui(&mut self, ui: &mut egui::Ui) -> Option<GaAction> {
        self.poll(ui.ctx());
        let mut action = None;
        let idle = !self.busy();
        ui.horizontal(|ui| {
            let mut judge = self.judge.clone();
            egui::ComboBox::from_label("Fitness")
                .selected_text(judge.label())
                .show_ui(ui, |ui| {
                    ui.selectable_value(&mut judge, Judge::Picks, "my picks");
                    for o in Objective::ALL {
                        let j = Judge::Objective(o);
                        let label = j.label();
                        ui.selectable_value(&mut judge, j, label);
                    }
                    ui.selectable_value(&mut judge, Judge::Coverage, "boundary coverage")
                        .on_hover_text(
                            "how much of each boundary of the data (Kindlmann-Durkin) is seen, \
                             less the fog",
                        );
                    if !matches!(judge, Judge::Target(_)) {
                        let j = Judge::Target(String::new());
                        ui.selectable_value(&mut judge, j, "target image");
                    }
                });
            if judge != self.judge {
                // the shown scores follow an image objective at once (the others score
                // at the next generation)
                self.scores = match (&judge, &self.ga) {
                    (Judge::Objective(o), Some(ga)) => Some(
                        ga.population
                            .iter()
                            .zip(&self.views)
                            .map(|(g, v)| Fitness::Objective(*o).score(g, v))
                            .collect(),
                    ),
                    _ => None,
                };
                self.progress.clear();
                self.judge = judge;
            }
        });
        if let Judge::Target(path) = &mut self.judge {
            ui.horizontal(|ui| {
                ui.label("Target PNG");
                ui.add(
                    egui::TextEdit::singleline(path)
                        .hint_text(format!("{VIEWS} views of {TILE}² side by side"))
                        .desired_width(160.0),
                );
            });
        }
        ui.horizontal(|ui| {
            if ui
                .add_enabled(idle, egui::Button::new("Start"))
                .on_hover_text(format!(
                    "{POPULATION} random TFs, seeded, from {VIEWS} viewpoints"
                ))
                .clicked()
            {
                action = Some(GaAction::Advance(0));
            }
            let can_breed = idle
                && self.ga.is_some()
                && match &self.judge {
                    Judge::Picks => !self.picks.is_empty(),
                    Judge::Objective(_) | Judge::Coverage => true,
                    Judge::Target(path) => !path.is_empty(),
                };
            if ui
                .add_enabled(can_breed, egui::Button::new("Next generation"))
                .on_hover_text("breed from the picks (or the scores)")
                .clicked()
            {
                action = Some(GaAction::Advance(1));
            }
            if self.judge != Judge::Picks
                && ui
                    .add_enabled(
                        can_breed,
                        egui::Button::new(format!("Run {RUN_GENERATIONS}")),
                    )
                    .clicked()
            {
                action = Some(GaAction::Advance(RUN_GENERATIONS));
            }
            if ui
                .add_enabled(
                    idle && self.best().is_some(),
                    egui::Button::new("Apply best"),
                )
                .on_hover_text("put the best (or first picked) TF into the stack")
                .clicked()
            {
                action = self.best().map(GaAction::Apply);
            }
        });
        if let Some((_, n)) = &self.job {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label(match n {
                    0 => "rendering the first generation…".to_string(),
                    n => format!("breeding {n} generation(s)…"),
                });
            });
        }
        if let Some(e) = &self.error {
            ui.colored_label(egui::Color32::RED, e);
        }
        let Some(ga) = &self.ga else {
            ui.weak("No population yet.");
            return action;
        };
        ui.small(match &self.scores {
            Some(s) => {
                let g = ga.summary(s);
                format!(
                    "generation {} · best {:.2} · mean {:.2}: {}",
                    ga.generation,
                    self.judge.shown(g.best_score),
                    self.judge.shown(g.mean_score),
                    self.judge.measure()
                )
            }
            None => format!(
                "generation {} · {} picked · click to pick, right-click to apply",
                ga.generation,
                self.picks.len()
            ),
        });
        if self.progress.len() > 1 {
            let judge = &self.judge;
            let first = judge.shown(self.progress[0].best_score);
            let last = judge.shown(self.progress[self.progress.len() - 1].best_score);
            ui.small(format!(
                "best from {first:.2} to {last:.2} over {} generations",
                self.progress.len()
            ));
            let line = |f: fn(&Generation) -> f64| {
                egui_plot::PlotPoints::from_iter(
                    self.progress
                        .iter()
                        .enumerate()
                        .map(|(i, g)| [i as f64, judge.shown(f(g))]),
                )
            };
            egui_plot::Plot::new("ga progress")
                .height(70.0)
                .show_axes([false, true])
                .allow_drag(false)
                .allow_zoom(false)
                .allow_scroll(false)
                .show(ui, |p| {
                    p.line(egui_plot::Line::new("best", line(|g| g.best_score)));
                    p.line(egui_plot::Line::new("mean", line(|g| g.mean_score)));
                });
        }
        let size = egui::vec2(TILE as f32, TILE as f32);
        let cols = (POPULATION as f64).sqrt().ceil() as usize;
        let mut toggled = None;
        egui::Grid::new("ga grid")
            .spacing([2.0, 2.0])
            .show(ui, |ui| {
                for (i, tex) in self.textures.iter().enumerate() {
                    let picked = self.picks.contains(&i);
                    let image = egui::Image::new((tex[0].id(), size))
                        .alt_text(format!("GA TF {i}"))
                        .sense(egui::Sense::click());
                    let r = ui.add(image);
                    if picked {
                        ui.painter().rect_stroke(
                            r.rect,
                            0.0,
                            egui::Stroke::new(3.0, egui::Color32::YELLOW),
                            egui::StrokeKind::Inside,
                        );
                    }
                    let score = self.scores.as_ref().map(|s| s[i]);
                    let r = r.on_hover_ui(|ui| {
                        ui.horizontal(|ui| {
                            for t in tex {
                                ui.image((t.id(), 3.0 * size));
                            }
                        });
                        ui.label(match score {
                            Some(s) => format!(
                                "{:.2} · click: pick · right-click: apply",
                                self.judge.shown(s)
                            ),
                            None => "click: pick · right-click: apply".into(),
                        });
                    });
                    if r.clicked() {
                        toggled = Some(i);
                    }
                    if r.secondary_clicked() {
                        action = Some(GaAction::Apply(ga.population[i].clone()));
                    }
                    if (i + 1) % cols == 0 {
                        ui.end_row();
                    }
                }
            });
        if let Some(i) = toggled {
            match self.picks.iter().position(|&p| p == i) {
                Some(k) => {
                    self.picks.remove(k);
                }
                None => self.picks.push(i),
            }
        }
        action
    }
}
