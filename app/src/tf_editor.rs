//! The 1D transfer-function editor: the curve's opacity over the volume's log-scaled
//! histogram, with a colour strip of the baked TF underneath.
//!
//! - drag a control point: move it (x between its neighbours, y = opacity);
//! - click empty space: insert a point there (colour of the curve at x);
//! - right-click a point: remove it (at least two stay);
//! - click a point: select it; its colour is edited below the plot;
//! - primitives (Gaussian / ramp / box) are listed with their sliders, added and
//!   removed with buttons.

use vwb_render::tf::{PrimitiveShape, TfCurve, TfPoint, TfPrimitive};

/// Plot height in points.
pub const HEIGHT: f32 = 120.0;
/// Pick radius around a control point, in points.
const PICK: f32 = 7.0;

fn to_screen(rect: egui::Rect, x: f32, a: f32) -> egui::Pos2 {
    egui::pos2(
        rect.left() + x.clamp(0.0, 1.0) * rect.width(),
        rect.bottom() - a.clamp(0.0, 1.0) * rect.height(),
    )
}

fn from_screen(rect: egui::Rect, p: egui::Pos2) -> (f32, f32) {
    (
        ((p.x - rect.left()) / rect.width().max(1.0)).clamp(0.0, 1.0),
        ((rect.bottom() - p.y) / rect.height().max(1.0)).clamp(0.0, 1.0),
    )
}

fn nearest(rect: egui::Rect, curve: &TfCurve, p: egui::Pos2) -> Option<usize> {
    curve
        .points
        .iter()
        .enumerate()
        .map(|(i, q)| (i, to_screen(rect, q.x, q.color[3]).distance(p)))
        .filter(|(_, d)| *d <= PICK)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

fn colour(c: [f64; 4]) -> egui::Color32 {
    let b = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    egui::Color32::from_rgb(b(c[0]), b(c[1]), b(c[2]))
}

/// The caption under a TF plot: what its axes are, with the data range when known.
pub fn axes_caption(range: Option<[f64; 2]>) -> String {
    let x = match range {
        Some([lo, hi]) => format!("x: value, 0 = {lo:.4} … 1 = {hi:.4} (data range)"),
        None => "x: value, 0 … 1 over the data range".to_string(),
    };
    format!("{x}; y: opacity 0 … 1; grey bars: log histogram")
}

/// Draws and edits `curve` over `histogram` (counts per equal bin of the normalised
/// value range); returns whether the curve changed and the plot's rectangle.
pub fn tf_editor(
    ui: &mut egui::Ui,
    salt: impl std::hash::Hash + std::fmt::Debug,
    curve: &mut TfCurve,
    histogram: &[u64],
) -> (bool, egui::Rect) {
    let id = ui.scope_id().with(("tf editor", salt));
    let mut selected: Option<usize> = ui.data(|d| d.get_temp(id)).flatten();
    let mut changed = false;
    let width = ui.available_width().max(120.0);
    let (rect, response) =
        ui.allocate_exact_size(egui::vec2(width, HEIGHT), egui::Sense::click_and_drag());
    response.widget_info(|| {
        egui::WidgetInfo::labeled(egui::Role::Canvas, true, "transfer function editor")
    });
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, egui::Color32::from_gray(24));
    // log-scaled histogram
    let max = histogram.iter().copied().max().unwrap_or(0).max(1) as f32;
    let n = histogram.len().max(1) as f32;
    for (i, &c) in histogram.iter().enumerate() {
        let h = (1.0 + c as f32).ln() / (1.0 + max).ln();
        let x0 = rect.left() + i as f32 / n * rect.width();
        let x1 = rect.left() + (i + 1) as f32 / n * rect.width();
        painter.rect_filled(
            egui::Rect::from_min_max(
                egui::pos2(x0, rect.bottom() - h * rect.height()),
                egui::pos2(x1, rect.bottom()),
            ),
            0.0,
            egui::Color32::from_gray(60),
        );
    }
    // the combined opacity (points and primitives) and its colour strip
    let samples: Vec<(f32, [f64; 4])> = (0..=128)
        .map(|i| {
            let x = i as f32 / 128.0;
            (x, curve.eval(x as f64))
        })
        .collect();
    let line: Vec<egui::Pos2> = samples
        .iter()
        .map(|(x, c)| to_screen(rect, *x, c[3] as f32))
        .collect();
    painter.add(egui::Shape::line(
        line,
        egui::Stroke::new(1.5, egui::Color32::WHITE),
    ));
    for w in samples.windows(2) {
        let strip = egui::Rect::from_min_max(
            egui::pos2(rect.left() + w[0].0 * rect.width(), rect.bottom() - 6.0),
            egui::pos2(rect.left() + w[1].0 * rect.width(), rect.bottom()),
        );
        painter.rect_filled(strip, 0.0, colour(w[0].1));
    }
    // axis values: opacity on the left, the normalised value along the bottom
    let font = egui::FontId::proportional(10.0);
    let grey = egui::Color32::from_gray(150);
    for (a, text) in [(1.0, "1"), (0.5, "0.5")] {
        let at = to_screen(rect, 0.0, a) + egui::vec2(2.0, 1.0);
        painter.text(at, egui::Align2::LEFT_TOP, text, font.clone(), grey);
    }
    for (x, align) in [
        (0.0, egui::Align2::LEFT_BOTTOM),
        (0.5, egui::Align2::CENTER_BOTTOM),
        (1.0, egui::Align2::RIGHT_BOTTOM),
    ] {
        let at = to_screen(rect, x, 0.0) + egui::vec2(0.0, -7.0);
        painter.text(at, align, format!("{x}"), font.clone(), grey);
    }
    for (i, p) in curve.points.iter().enumerate() {
        let c = colour(p.color.map(f64::from));
        let at = to_screen(rect, p.x, p.color[3]);
        painter.circle_filled(at, 4.5, c);
        let stroke = if selected == Some(i) { 2.0 } else { 1.0 };
        painter.circle_stroke(at, 4.5, egui::Stroke::new(stroke, egui::Color32::WHITE));
    }

    // interaction
    let pointer = response.interact_pointer_pos().or(response.hover_pos());
    // pick at the press, not where the drag is recognised (a few points later)
    if response.drag_started()
        && let Some(p) = ui.input(|i| i.pointer.press_origin()).or(pointer)
    {
        selected = nearest(rect, curve, p);
    }
    if response.dragged()
        && let (Some(i), Some(p)) = (selected, pointer)
        && i < curve.points.len()
    {
        let (x, a) = from_screen(rect, p);
        let lo = if i == 0 { 0.0 } else { curve.points[i - 1].x };
        let hi = curve.points.get(i + 1).map_or(1.0, |q| q.x);
        let last = i + 1 == curve.points.len();
        let q = &mut curve.points[i];
        let new_x = if i == 0 || last {
            q.x // the end points keep their place on the value axis
        } else {
            x.clamp(lo, hi)
        };
        if new_x != q.x || a != q.color[3] {
            q.x = new_x;
            q.color[3] = a;
            changed = true;
        }
    }
    if response.clicked()
        && let Some(p) = pointer
        && nearest(rect, curve, p).is_some()
    {
        selected = nearest(rect, curve, p);
    } else if response.clicked()
        && let Some(p) = pointer
    {
        let (x, a) = from_screen(rect, p);
        let c = curve.eval_points(x as f64);
        let at = curve.points.partition_point(|q| q.x < x);
        curve.points.insert(
            at,
            TfPoint {
                x,
                color: [c[0] as f32, c[1] as f32, c[2] as f32, a],
            },
        );
        selected = Some(at);
        changed = true;
    }
    if response.secondary_clicked()
        && let Some(p) = pointer
        && let Some(i) = nearest(rect, curve, p)
        && curve.points.len() > 2
    {
        curve.points.remove(i);
        selected = None;
        changed = true;
    }

    // the selected point's colour, the log axis, the primitives
    if let Some(i) = selected.filter(|i| *i < curve.points.len()) {
        ui.horizontal(|ui| {
            let p = &mut curve.points[i];
            let mut rgb = [p.color[0], p.color[1], p.color[2]];
            if ui.color_edit_button_rgb(&mut rgb).changed() {
                p.color[..3].copy_from_slice(&rgb);
                changed = true;
            }
            ui.label(format!("point {i}: x {:.3}, α {:.3}", p.x, p.color[3]));
        });
    }
    changed |= ui
        .checkbox(&mut curve.log_opacity, "logarithmic opacity axis")
        .changed();
    let mut remove = None;
    for (k, prim) in curve.primitives.iter_mut().enumerate() {
        ui.push_id(id.with(k), |ui| {
            ui.horizontal(|ui| {
                egui::ComboBox::new("shape", "shape")
                    .selected_text(prim.shape.name())
                    .show_ui(ui, |ui| {
                        for s in [
                            PrimitiveShape::Gaussian,
                            PrimitiveShape::Ramp,
                            PrimitiveShape::Box,
                        ] {
                            changed |= ui.selectable_value(&mut prim.shape, s, s.name()).changed();
                        }
                    });
                changed |= ui.color_edit_button_rgb(&mut prim.color).changed();
                if ui.button("del").clicked() {
                    remove = Some(k);
                }
            });
            changed |= ui
                .add(egui::Slider::new(&mut prim.centre, 0.0..=1.0).text("centre"))
                .changed();
            changed |= ui
                .add(
                    egui::Slider::new(&mut prim.width, 0.001..=1.0)
                        .logarithmic(true)
                        .text("width"),
                )
                .changed();
            changed |= ui
                .add(egui::Slider::new(&mut prim.height, 0.0..=1.0).text("height"))
                .changed();
        });
    }
    if let Some(k) = remove {
        curve.primitives.remove(k);
        changed = true;
    }
    if ui.button("add Gaussian").clicked() {
        curve.primitives.push(TfPrimitive {
            shape: PrimitiveShape::Gaussian,
            centre: 0.5,
            width: 0.05,
            height: 0.5,
            color: [1.0, 1.0, 1.0],
        });
        changed = true;
    }
    ui.data_mut(|d| d.insert_temp(id, selected));
    (changed, rect)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_input::press;

    fn curve() -> TfCurve {
        TfCurve::new(vec![
            TfPoint {
                x: 0.0,
                color: [0.0, 0.0, 0.0, 0.0],
            },
            TfPoint {
                x: 0.5,
                color: [1.0, 0.5, 0.2, 0.4],
            },
            TfPoint {
                x: 1.0,
                color: [1.0, 1.0, 1.0, 0.9],
            },
        ])
    }

    /// Runs one frame of the editor with `events`; returns (changed, plot rect).
    fn frame(ctx: &egui::Context, c: &mut TfCurve, events: Vec<egui::Event>) -> (bool, egui::Rect) {
        let input = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(
                egui::Pos2::ZERO,
                egui::vec2(400.0, 400.0),
            )),
            events,
            ..Default::default()
        };
        let mut result = (false, egui::Rect::NOTHING);
        let mut out = ctx.run_ui(input, |ui| {
            egui::CentralPanel::default().show(ui, |ui| {
                result = tf_editor(ui, 1, c, &[5, 50, 500, 50, 5]);
            });
        });
        out.textures_delta.clear();
        result
    }

    /// Dragging the middle point moves it; right-clicking removes it; a click on
    /// empty space inserts one — driven through egui's input as a user would.
    #[test]
    fn drag_remove_and_insert_points() {
        let ctx = egui::Context::default();
        let mut c = curve();
        let (_, rect) = frame(&ctx, &mut c, vec![]);
        let at = to_screen(rect, 0.5, 0.4);
        let to = to_screen(rect, 0.6, 0.8);
        let primary = egui::PointerButton::Primary;
        frame(&ctx, &mut c, vec![egui::Event::PointerMoved(at)]);
        frame(&ctx, &mut c, vec![press(at, true, primary)]);
        let mut moved = false;
        for k in 1..=6 {
            let p = at + (to - at) * (k as f32 / 6.0);
            moved |= frame(&ctx, &mut c, vec![egui::Event::PointerMoved(p)]).0;
        }
        frame(&ctx, &mut c, vec![press(to, false, primary)]);
        assert!(moved);
        assert!(
            (c.points[1].x - 0.6).abs() < 0.02 && (c.points[1].color[3] - 0.8).abs() < 0.02,
            "{:?}",
            c.points[1]
        );
        assert_eq!(c.points[0].x, 0.0, "end points keep their value");

        // right-click removes the middle point
        let here = to_screen(rect, c.points[1].x, c.points[1].color[3]);
        let secondary = egui::PointerButton::Secondary;
        frame(&ctx, &mut c, vec![egui::Event::PointerMoved(here)]);
        frame(&ctx, &mut c, vec![press(here, true, secondary)]);
        frame(&ctx, &mut c, vec![press(here, false, secondary)]);
        assert_eq!(c.points.len(), 2);

        // a click on empty space inserts a point there
        let empty = to_screen(rect, 0.3, 0.5);
        frame(&ctx, &mut c, vec![egui::Event::PointerMoved(empty)]);
        frame(&ctx, &mut c, vec![press(empty, true, primary)]);
        frame(&ctx, &mut c, vec![press(empty, false, primary)]);
        assert_eq!(c.points.len(), 3, "{:?}", c.points);
        assert!((c.points[1].x - 0.3).abs() < 0.02 && (c.points[1].color[3] - 0.5).abs() < 0.02);
        assert!(c.validate().is_ok());
    }
}
