//! The window's trade-off view: set up a sweep over any numeric parameters (slice
//! spacing and every float or int parameter in the stack), run it in a background
//! thread with progress and cancel ([`vwb_lab::measure::sweep`], the engine of
//! `vwb sweep`), and read the Pareto plot of frame time against RMS ΔE*uv from the
//! converged reference. Clicking a point applies its settings to the scene.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use vwb_render::params::ParamKind;
use vwb_render::preset::Document;
use vwb_render::reference::ReferenceOptions;
use vwb_render::{GpuContext, Volume};

use vwb_lab::job::Job;
use vwb_lab::measure::{self, Axis, SweepEvent, SweepPoint};

/// One axis as the user types it: a name from [`candidates`] and values
/// (`A..B:N`, `A..B:N:log` or `a,b,c`).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisEdit {
    pub name: String,
    pub values: String,
}

/// The numeric parameters a sweep can vary in `doc`: `render.slice_spacing` and
/// `<plugin id>.<key>` for every float or int parameter (of the first instance of
/// each plugin, as `vwb sweep --param` addresses them), with the parameter's range.
pub fn candidates(doc: &Document) -> Vec<(String, f64, f64)> {
    let mut out = vec![("render.slice_spacing".to_string(), 0.25, 4.0)];
    let mut seen = std::collections::HashSet::new();
    for inst in &doc.stack {
        if !seen.insert(inst.plugin.id()) {
            continue;
        }
        for spec in inst.plugin.params() {
            let range = match spec.kind {
                ParamKind::Float { min, max, .. } => Some((min as f64, max as f64)),
                ParamKind::Int { min, max, .. } => Some((min as f64, max as f64)),
                _ => None,
            };
            if let Some((lo, hi)) = range {
                out.push((format!("{}.{}", inst.plugin.id(), spec.key), lo, hi));
            }
        }
    }
    out
}

/// A finished sweep as the view shows it.
pub struct SweepResult {
    pub axes: Vec<Axis>,
    pub points: Vec<SweepPoint>,
    /// The plugin ids of the stack it ran on (points apply only to the same stack).
    stack_ids: Vec<&'static str>,
}

/// A sweep running in a thread.
pub struct SweepJob {
    done: Arc<AtomicUsize>,
    total: usize,
    cancel: Arc<AtomicBool>,
    status: Arc<Mutex<String>>,
    job: Job<SweepResult>,
}

impl SweepJob {
    /// Starts the sweep of `axes` over `doc` (rendered at `doc.render.size`) on `gpu`.
    pub fn start(
        gpu: GpuContext,
        doc: Document,
        volume: Arc<Volume>,
        axes: Vec<Axis>,
        frames: u32,
        tolerance: f64,
    ) -> Self {
        let done = Arc::new(AtomicUsize::new(0));
        let cancel = Arc::new(AtomicBool::new(false));
        let status = Arc::new(Mutex::new("starting".to_string()));
        let total = measure::grid(&axes).len();
        let (d, c, st) = (done.clone(), cancel.clone(), status.clone());
        let job = Job::spawn("sweep", move || {
            let opts = ReferenceOptions {
                cancel: Some(c),
                ..Default::default()
            };
            let set = |m: String| {
                if let Ok(mut s) = st.lock() {
                    *s = m;
                }
            };
            measure::sweep(
                &gpu,
                &doc,
                volume,
                &axes,
                frames,
                tolerance,
                &opts,
                &mut |e| match e {
                    SweepEvent::Reference { key } => set(if key.is_empty() {
                        "reference".into()
                    } else {
                        format!("reference {key}")
                    }),
                    SweepEvent::Point { index, total, .. } => {
                        d.store(index + 1, Ordering::Relaxed);
                        set(format!("point {}/{total}", index + 1));
                    }
                },
            )
            .map(|o| SweepResult {
                axes,
                points: o.points,
                stack_ids: doc.stack.iter().map(|i| i.plugin.id()).collect(),
            })
            .map_err(|e| format!("{e:#}"))
        });
        Self {
            done,
            total,
            cancel,
            status,
            job,
        }
    }

    /// Share of the grid points done.
    pub fn fraction(&self) -> f32 {
        self.done.load(Ordering::Relaxed) as f32 / self.total.max(1) as f32
    }

    /// What the sweep is doing now.
    pub fn status(&self) -> String {
        self.status.lock().map(|s| s.clone()).unwrap_or_default()
    }

    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// The result once the thread has finished.
    pub fn poll(&self) -> Option<Result<SweepResult, String>> {
        self.job.poll()
    }
}

/// Applies the settings of sweep point `index` to `doc`; an error when the stack no
/// longer matches the one the sweep ran on.
pub fn apply_point(doc: &mut Document, result: &SweepResult, index: usize) -> Result<(), String> {
    let ids: Vec<&'static str> = doc.stack.iter().map(|i| i.plugin.id()).collect();
    if ids != result.stack_ids {
        return Err("the plugin stack changed since the sweep; run it again".into());
    }
    let point = result
        .points
        .get(index)
        .ok_or_else(|| format!("no sweep point {index}"))?;
    for (axis, v) in result.axes.iter().zip(&point.values) {
        measure::apply_axis(doc, axis, *v);
    }
    Ok(())
}

/// The label of a point: its axis values.
pub fn point_label(axes: &[Axis], p: &SweepPoint) -> String {
    axes.iter()
        .zip(&p.values)
        .map(|(a, v)| {
            let short = a.name.rsplit('.').next().unwrap_or(&a.name);
            format!("{short}={v:.3}")
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// The trade-off view's state.
pub struct TradeoffView {
    pub axes: Vec<AxisEdit>,
    /// Image side of the sweep's frames (pixels).
    pub side: u32,
    /// Timed frames per point (the median is plotted).
    pub frames: u32,
    /// Convergence tolerance of the reference (RMS ΔE*uv).
    pub tolerance: f64,
    pub job: Option<SweepJob>,
    pub result: Option<Result<SweepResult, String>>,
    /// The point whose settings were applied last.
    pub applied: Option<usize>,
    pub message: Option<String>,
    /// Where the points were drawn in the last frame (screen points), for scripted
    /// clicks.
    screen: Vec<egui::Pos2>,
}

impl Default for TradeoffView {
    fn default() -> Self {
        Self {
            axes: vec![AxisEdit {
                name: "render.slice_spacing".into(),
                values: "0.5..2:3:log".into(),
            }],
            side: 64,
            frames: 3,
            tolerance: vwb_render::reference::DEFAULT_TOLERANCE_DELTA_E,
            job: None,
            result: None,
            applied: None,
            message: None,
            screen: Vec::new(),
        }
    }
}

impl TradeoffView {
    /// Where sweep point `i` was drawn in the last frame.
    pub fn point_on_screen(&self, i: usize) -> Option<egui::Pos2> {
        self.screen.get(i).copied()
    }

    /// The finished sweep, if any.
    pub fn finished(&self) -> Option<&SweepResult> {
        self.result.as_ref().and_then(|r| r.as_ref().ok())
    }

    /// Parses the axes against `doc`.
    pub fn parse_axes(&self, doc: &Document) -> Result<Vec<Axis>, String> {
        self.axes
            .iter()
            .map(|a| {
                measure::parse_axis(&format!("{}={}", a.name.trim(), a.values.trim()), doc)
                    .map_err(|e| format!("{e:#}"))
            })
            .collect()
    }

    /// Starts the sweep of the current scene at the view's image size.
    pub fn start(
        &mut self,
        gpu: &GpuContext,
        doc: &Document,
        volume: Arc<Volume>,
    ) -> Result<(), String> {
        let axes = self.parse_axes(doc)?;
        if axes.is_empty() {
            return Err("add at least one parameter".into());
        }
        let mut d = doc.clone();
        d.render.size = [self.side.clamp(8, 2048); 2];
        self.result = None;
        self.applied = None;
        self.job = Some(SweepJob::start(
            gpu.clone(),
            d,
            volume,
            axes,
            self.frames.max(1),
            self.tolerance,
        ));
        Ok(())
    }

    /// Picks up a finished job; true when one finished this call.
    pub fn poll(&mut self) -> bool {
        let Some(result) = self.job.as_ref().and_then(SweepJob::poll) else {
            return false;
        };
        self.result = Some(result);
        self.job = None;
        true
    }

    /// The view; returns true when a clicked point's settings were applied to `doc`.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        gpu: &GpuContext,
        doc: &mut Document,
        volume: &Arc<Volume>,
    ) -> bool {
        let names = candidates(doc);
        let mut remove = None;
        for (i, axis) in self.axes.iter_mut().enumerate() {
            ui.push_id(("sweep axis", i), |ui| {
                ui.horizontal(|ui| {
                    egui::ComboBox::new("name", "parameter")
                        .selected_text(axis.name.as_str())
                        .width(170.0)
                        .show_ui(ui, |ui| {
                            for (n, lo, hi) in &names {
                                if ui.selectable_label(axis.name == *n, n).clicked() {
                                    axis.name = n.clone();
                                    axis.values = format!("{lo}..{hi}:3");
                                }
                            }
                        });
                    if ui.small_button("×").on_hover_text("remove").clicked() {
                        remove = Some(i);
                    }
                });
                ui.horizontal(|ui| {
                    ui.label("values");
                    ui.add(
                        egui::TextEdit::singleline(&mut axis.values)
                            .desired_width(120.0)
                            .id_salt("values"),
                    )
                    .on_hover_text("A..B:N, A..B:N:log or a,b,c");
                });
            });
        }
        if let Some(i) = remove {
            self.axes.remove(i);
        }
        ui.horizontal(|ui| {
            if ui.button("Add parameter").clicked() {
                self.axes.push(AxisEdit {
                    name: "render.slice_spacing".into(),
                    values: "0.5..2:3:log".into(),
                });
            }
        });
        ui.add(egui::Slider::new(&mut self.side, 16..=512).text("sweep image side"));
        ui.add(egui::Slider::new(&mut self.frames, 1..=10).text("frames per point"));
        if let Some(job) = &self.job {
            ui.add(egui::ProgressBar::new(job.fraction()).text(job.status()));
            if ui.button("Cancel sweep").clicked() {
                job.cancel();
            }
            ui.ctx().request_repaint();
        } else if ui.button("Run sweep").clicked()
            && let Err(e) = self.start(gpu, doc, volume.clone())
        {
            self.result = Some(Err(e));
        }
        self.poll();
        let mut applied = false;
        match &self.result {
            Some(Ok(r)) => {
                let (clicked, screen) = pareto_plot(ui, r, self.applied);
                self.screen = screen;
                if let Some(i) = clicked {
                    match apply_point(doc, r, i) {
                        Ok(()) => {
                            self.applied = Some(i);
                            self.message =
                                Some(format!("applied {}", point_label(&r.axes, &r.points[i])));
                            applied = true;
                        }
                        Err(e) => self.message = Some(e),
                    }
                }
                let front = r.points.iter().filter(|p| p.pareto).count();
                ui.label(format!(
                    "{} points, {front} on the Pareto front (red); click one to apply it",
                    r.points.len()
                ));
            }
            Some(Err(e)) => {
                ui.colored_label(egui::Color32::RED, e);
            }
            None => {}
        }
        if let Some(m) = &self.message {
            ui.label(m);
        }
        applied
    }
}

/// The Pareto plot (frame ms against RMS ΔE*uv, the front as a staircase); returns
/// the index of a clicked point (within 12 points of the pointer) and where every
/// point was drawn.
fn pareto_plot(
    ui: &mut egui::Ui,
    r: &SweepResult,
    applied: Option<usize>,
) -> (Option<usize>, Vec<egui::Pos2>) {
    let xy = |p: &SweepPoint| [p.ms, p.metrics.rms_delta_e];
    let mut front: Vec<[f64; 2]> = r.points.iter().filter(|p| p.pareto).map(xy).collect();
    front.sort_by(|a, b| a[0].total_cmp(&b[0]));
    let mut stairs = Vec::new();
    for (k, p) in front.iter().enumerate() {
        if k > 0 {
            stairs.push([p[0], front[k - 1][1]]);
        }
        stairs.push(*p);
    }
    let clock = r.points.first().map_or("gpu", |p| p.clock);
    let response = egui_plot::Plot::new("pareto")
        .height(180.0)
        .x_axis_label(format!("frame ms ({clock})"))
        .y_axis_label("RMS ΔE*uv")
        .include_x(0.0)
        .include_y(0.0)
        .allow_drag(false)
        .allow_zoom(false)
        .allow_scroll(false)
        .label_formatter(|hover| match hover {
            egui_plot::HoverPosition::NearDataPoint { position: p, .. } => {
                Some(format!("{:.2} ms\nΔE {:.3}", p.x, p.y))
            }
            egui_plot::HoverPosition::Elsewhere { .. } => None,
        })
        .show(ui, |plot| {
            plot.line(egui_plot::Line::new("front", stairs).color(egui::Color32::RED));
            let (on, off): (Vec<_>, Vec<_>) = r.points.iter().partition(|p| p.pareto);
            plot.points(
                egui_plot::Points::new("dominated", off.into_iter().map(xy).collect::<Vec<_>>())
                    .radius(3.5)
                    .color(egui::Color32::from_rgb(31, 119, 180)),
            );
            plot.points(
                egui_plot::Points::new("Pareto front", on.into_iter().map(xy).collect::<Vec<_>>())
                    .radius(4.5)
                    .color(egui::Color32::RED),
            );
            if let Some(p) = applied.and_then(|i| r.points.get(i)) {
                plot.points(
                    egui_plot::Points::new("applied", vec![xy(p)])
                        .radius(8.0)
                        .filled(false)
                        .color(egui::Color32::YELLOW),
                );
            }
        });
    response
        .response
        .widget_info(|| egui::WidgetInfo::labeled(egui::Role::Canvas, true, "Pareto plot"));
    let screen: Vec<egui::Pos2> = r
        .points
        .iter()
        .map(|p| {
            let [x, y] = xy(p);
            response
                .transform
                .position_from_point(&egui_plot::PlotPoint::new(x, y))
        })
        .collect();
    let clicked = response
        .response
        .clicked()
        .then(|| {
            response
                .response
                .interact_pointer_pos()
                .or_else(|| ui.input(|i| i.pointer.press_origin()))
        })
        .flatten()
        .and_then(|pointer| {
            screen
                .iter()
                .enumerate()
                .map(|(i, at)| (i, at.distance(pointer)))
                .filter(|(_, d)| *d <= 12.0)
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(i, _)| i)
        });
    (clicked, screen)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc() -> Document {
        let r = vwb_plugins::builtin_registry();
        vwb_lab::document::default_document(&r)
    }

    #[test]
    fn candidates_are_spacing_and_numeric_params() {
        let mut d = doc();
        let r = vwb_plugins::builtin_registry();
        d.stack.push(vwb_render::PluginInstance::new(
            r.get("shade.dos").expect("registered"),
        ));
        let names: Vec<String> = candidates(&d).into_iter().map(|c| c.0).collect();
        assert_eq!(names[0], "render.slice_spacing");
        assert!(
            names.contains(&"shade.dos.theta_deg".to_string()),
            "{names:?}"
        );
        assert!(names.contains(&"shade.dos.grid".to_string()));
        // enums, colours and TFs cannot be swept
        assert!(
            !names
                .iter()
                .any(|n| n.ends_with(".kernel") || n.ends_with(".tf"))
        );
        // every candidate parses as an axis over its own range
        for (n, lo, hi) in candidates(&d) {
            let spec = format!("{n}={lo}..{hi}:2");
            measure::parse_axis(&spec, &d).unwrap_or_else(|e| panic!("{spec}: {e:#}"));
        }
    }

    #[test]
    fn a_point_applies_its_values_only_to_the_same_stack() {
        let mut d = doc();
        let axes = vec![measure::parse_axis("render.slice_spacing=0.5,3", &d).unwrap()];
        let point = |v: f64| SweepPoint {
            values: vec![v],
            slices: 1,
            ms: 1.0,
            clock: "gpu",
            wall_ms: 1.0,
            metrics: Default::default(),
            image: String::new(),
            pareto: true,
        };
        let result = SweepResult {
            axes,
            points: vec![point(0.5), point(3.0)],
            stack_ids: d.stack.iter().map(|i| i.plugin.id()).collect(),
        };
        apply_point(&mut d, &result, 1).unwrap();
        assert_eq!(d.render.slice_spacing, 3.0);
        assert!(apply_point(&mut d, &result, 7).is_err());
        d.stack.clear();
        let e = apply_point(&mut d, &result, 0).unwrap_err();
        assert!(e.contains("stack changed"), "{e}");
        assert!(matches!(
            result.axes[0].target,
            measure::AxisTarget::Spacing
        ));
    }
}
