//! The 2D transfer-function editor (`classify.tf2d`): the primitives of a [`Tf2d`]
//! over the volume's log-count 2D histogram, value along x and gradient magnitude up
//! y, both in [0, 1].
//!
//! - drag inside a primitive: move its centre (a triangle only along the value axis:
//!   its apex stays at gradient 0);
//! - drag the small square at a primitive's top-right corner: resize it about its
//!   centre (a triangle: its width and its height above gradient 0);
//! - click a primitive: select it (click empty space: deselect); its shape, colour,
//!   centre, size and opacity are edited below the plot;
//! - right-click a primitive: remove it;
//! - "Add rectangle" / "Add triangle" / "Add gaussian": add a primitive and select it.
//!
//! The outlines: a rectangle as itself, a triangle from its apex (v_c, 0) to width w
//! at g = h, a Gaussian as the ellipse at half maximum (full widths w and h). Under
//! them a coarse preview of the classification (`Tf2d::eval`).

use std::hash::Hash;
use std::sync::{Arc, Weak};

use vwb_render::Volume;
use vwb_render::tf2d::{Primitive2d, Shape2d, Tf2d};

/// Smallest size along either axis that dragging or the sliders give.
pub const MIN_SIZE: f32 = 0.005;
/// Largest size along either axis that dragging or the sliders give.
pub const MAX_SIZE: f32 = 2.0;
/// Bins per axis of the histogram texture.
pub const HISTOGRAM_BINS: usize = 128;
/// Side of a resize handle, in points.
const HANDLE: f32 = 8.0;
/// Extra pick margin around a resize handle, in points.
const HANDLE_PICK: f32 = 2.0;
/// Cells per axis of the classification preview.
const PREVIEW: usize = 48;
/// Histogram textures kept per context.
const CACHE_LEN: usize = 4;

/// What the y axis shows: classify.tf2d's `y_axis` (the gradient magnitude times its
/// `gradient_scale`, or the volume's own value, |v| under a LIC).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum YAxis {
    Gradient { scale: f64 },
    Data,
}

impl YAxis {
    /// The axis of a tf2d instance's values (`y_axis`, `gradient_scale`).
    pub fn of(values: &vwb_render::params::ParamValues) -> Self {
        use vwb_render::params::ParamValue;
        match (values.get("y_axis"), values.get("gradient_scale")) {
            (Some(ParamValue::Enum(y)), _) if y == "data" => Self::Data,
            (_, Some(ParamValue::Float(x))) => Self::Gradient { scale: *x as f64 },
            _ => Self::Gradient { scale: 1.0 },
        }
    }
    /// The plot's labels along x and y.
    fn labels(self) -> (&'static str, &'static str) {
        match self {
            Self::Gradient { .. } => ("value", "gradient magnitude"),
            Self::Data => (
                "value the sample hooks give (LIC intensity)",
                "volume value (|v| under a LIC)",
            ),
        }
    }
    /// A cache key: the scale's bits, or NaN's for the data axis.
    fn key(self) -> u64 {
        match self {
            Self::Gradient { scale } => scale.to_bits(),
            Self::Data => f64::NAN.to_bits(),
        }
    }
}

/// Screen position of (value, gradient magnitude); not clamped.
fn to_screen(rect: egui::Rect, v: f32, g: f32) -> egui::Pos2 {
    egui::pos2(
        rect.left() + v * rect.width(),
        rect.bottom() - g * rect.height(),
    )
}

/// (value, gradient magnitude) at a screen position; not clamped.
fn from_screen(rect: egui::Rect, p: egui::Pos2) -> [f32; 2] {
    [
        (p.x - rect.left()) / rect.width().max(1.0),
        (rect.bottom() - p.y) / rect.height().max(1.0),
    ]
}

/// The primitive's top-right corner in TF units: where its resize handle sits.
fn handle_at(p: &Primitive2d) -> [f32; 2] {
    match p.shape {
        Shape2d::Triangle => [p.centre[0] + 0.5 * p.size[0], p.size[1]],
        Shape2d::Rectangle | Shape2d::Gaussian => {
            [p.centre[0] + 0.5 * p.size[0], p.centre[1] + 0.5 * p.size[1]]
        }
    }
}

/// Whether (v, g) lies inside the primitive's outline.
fn inside(p: &Primitive2d, [v, g]: [f32; 2]) -> bool {
    let (dv, dg) = (v - p.centre[0], g - p.centre[1]);
    let (w, h) = (p.size[0].max(1e-6), p.size[1].max(1e-6));
    match p.shape {
        Shape2d::Rectangle => dv.abs() <= 0.5 * w && dg.abs() <= 0.5 * h,
        Shape2d::Triangle => (0.0..=h).contains(&g) && dv.abs() <= 0.5 * w * g / h,
        Shape2d::Gaussian => {
            let (tv, tg) = (dv / (0.5 * w), dg / (0.5 * h));
            tv * tv + tg * tg <= 1.0
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Grab {
    Move,
    Resize,
}

/// The primitive (topmost first: the last drawn) and its part under `p`; resize
/// handles before bodies.
fn pick(rect: egui::Rect, tf: &Tf2d, p: egui::Pos2) -> Option<(usize, Grab)> {
    let reach = 0.5 * HANDLE + HANDLE_PICK;
    let handle = tf.primitives.iter().enumerate().rev().find(|(_, q)| {
        let [v, g] = handle_at(q);
        let d = to_screen(rect, v, g) - p;
        d.x.abs() <= reach && d.y.abs() <= reach
    });
    if let Some((i, _)) = handle {
        return Some((i, Grab::Resize));
    }
    let at = from_screen(rect, p);
    tf.primitives
        .iter()
        .rposition(|q| inside(q, at))
        .map(|i| (i, Grab::Move))
}

/// Makes an edited primitive pass `Tf2d::validate`: finite centre, size ≥
/// [`MIN_SIZE`], colour in [0, 1].
fn sanitize(p: &mut Primitive2d) {
    for c in &mut p.centre {
        if !c.is_finite() {
            *c = 0.5;
        }
    }
    for s in &mut p.size {
        *s = if s.is_finite() {
            s.clamp(MIN_SIZE, MAX_SIZE)
        } else {
            0.1
        };
    }
    for c in &mut p.color {
        *c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    }
}

/// A new primitive of `shape` where the demo-like data usually has something to
/// select.
fn default_primitive(shape: Shape2d) -> Primitive2d {
    match shape {
        Shape2d::Rectangle => Primitive2d {
            shape,
            centre: [0.5, 0.5],
            size: [0.2, 0.2],
            color: [0.9, 0.9, 0.9, 0.4],
        },
        Shape2d::Triangle => Primitive2d {
            shape,
            centre: [0.5, 0.0],
            size: [0.2, 0.5],
            color: [1.0, 0.7, 0.5, 0.3],
        },
        Shape2d::Gaussian => Primitive2d {
            shape,
            centre: [0.5, 0.3],
            size: [0.15, 0.2],
            color: [0.6, 0.8, 1.0, 0.5],
        },
    }
}

fn opaque(c: [f32; 4]) -> egui::Color32 {
    let b = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    egui::Color32::from_rgb(b(c[0]), b(c[1]), b(c[2]))
}

/// The editor's state between frames.
#[derive(Debug, Clone, Copy, Default)]
struct State {
    selected: Option<usize>,
    /// The primitive being dragged, how, and the offset (TF units) from the pointer
    /// to the point it moves (the centre or the handle), fixed at the press.
    drag: Option<(usize, Grab, [f32; 2])>,
}

/// What one frame of the editor did.
struct Output {
    changed: bool,
    plot: egui::Rect,
    /// The "Add rectangle", "Add triangle" and "Add gaussian" buttons.
    #[cfg_attr(not(test), allow(dead_code))]
    add_buttons: [egui::Rect; 3],
    #[cfg_attr(not(test), allow(dead_code))]
    selected: Option<usize>,
}

/// Draws and edits `tf` over `histogram` (a texture from [`histogram_texture`],
/// drawn grey); returns whether `tf` changed and the plot's rectangle. After a
/// change `tf` passes `Tf2d::validate`.
pub fn tf2d_editor(
    ui: &mut egui::Ui,
    salt: impl Hash + std::fmt::Debug,
    tf: &mut Tf2d,
    histogram: Option<&egui::TextureHandle>,
    y_axis: YAxis,
) -> (bool, egui::Rect) {
    let out = editor(ui, salt, tf, histogram, y_axis);
    (out.changed, out.plot)
}

fn editor(
    ui: &mut egui::Ui,
    salt: impl Hash + std::fmt::Debug,
    tf: &mut Tf2d,
    histogram: Option<&egui::TextureHandle>,
    y_axis: YAxis,
) -> Output {
    let id = ui.scope_id().with(("tf2d editor", salt));
    let mut state: State = ui.data(|d| d.get_temp(id)).unwrap_or_default();
    let n = tf.primitives.len();
    state.selected = state.selected.filter(|i| *i < n);
    state.drag = state.drag.filter(|d| d.0 < n);
    let mut changed = false;
    let mut edited: Vec<usize> = Vec::new();

    let width = ui.available_width().max(120.0);
    let height = (0.8 * width).clamp(120.0, 280.0);
    let (rect, response) =
        ui.allocate_exact_size(egui::vec2(width, height), egui::Sense::click_and_drag());

    // interaction first, so that this frame draws the result
    let pointer = response.interact_pointer_pos().or(response.hover_pos());
    let primary = egui::PointerButton::Primary;
    // pick at the press, not where the drag is recognised (a few points later)
    if response.drag_started_by(primary)
        && let Some(p0) = ui.input(|i| i.pointer.press_origin()).or(pointer)
    {
        state.drag = pick(rect, tf, p0).map(|(i, grab)| {
            state.selected = Some(i);
            let q = &tf.primitives[i];
            let target = match grab {
                Grab::Move => q.centre,
                Grab::Resize => handle_at(q),
            };
            let at = from_screen(rect, p0);
            (i, grab, [target[0] - at[0], target[1] - at[1]])
        });
    }
    if response.dragged_by(primary)
        && let (Some((i, grab, offset)), Some(p)) = (state.drag, pointer)
    {
        let at = from_screen(rect, p);
        let t = [at[0] + offset[0], at[1] + offset[1]];
        let q = &mut tf.primitives[i];
        let before = *q;
        match (grab, q.shape) {
            (Grab::Move, Shape2d::Triangle) => q.centre[0] = t[0].clamp(0.0, 1.0),
            (Grab::Move, _) => q.centre = t.map(|x| x.clamp(0.0, 1.0)),
            (Grab::Resize, Shape2d::Triangle) => {
                q.size = [2.0 * (t[0] - q.centre[0]), t[1]].map(|s| s.clamp(MIN_SIZE, MAX_SIZE));
            }
            (Grab::Resize, _) => {
                q.size = [2.0 * (t[0] - q.centre[0]), 2.0 * (t[1] - q.centre[1])]
                    .map(|s| s.clamp(MIN_SIZE, MAX_SIZE));
            }
        }
        if *q != before {
            changed = true;
            edited.push(i);
        }
    }
    if response.drag_stopped() {
        state.drag = None;
    }
    if response.clicked()
        && let Some(p) = pointer
    {
        state.selected = pick(rect, tf, p).map(|(i, _)| i);
    }
    if response.secondary_clicked()
        && let Some(p) = pointer
        && let Some((i, _)) = pick(rect, tf, p)
    {
        tf.primitives.remove(i);
        state.selected = match state.selected {
            Some(s) if s == i => None,
            Some(s) if s > i => Some(s - 1),
            s => s,
        };
        state.drag = None;
        edited.clear();
        changed = true;
    }
    if state.drag.is_none()
        && let Some(p) = response.hover_pos()
        && let Some((_, grab)) = pick(rect, tf, p)
    {
        ui.ctx().set_cursor_icon(match grab {
            Grab::Move => egui::CursorIcon::Grab,
            Grab::Resize => egui::CursorIcon::ResizeNeSw,
        });
    }

    // drawing
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, egui::Color32::from_gray(16));
    if let Some(tex) = histogram {
        painter.image(
            tex.id(),
            rect,
            egui::Rect::from_min_max(egui::Pos2::ZERO, egui::pos2(1.0, 1.0)),
            egui::Color32::from_gray(170),
        );
    }
    let mut mesh = egui::Mesh::default();
    let cell = 1.0 / PREVIEW as f32;
    for j in 0..PREVIEW {
        for i in 0..PREVIEW {
            let (v, g) = ((i as f32 + 0.5) * cell, (j as f32 + 0.5) * cell);
            let c = tf.eval(v as f64, g as f64);
            if c[3] <= 0.004 {
                continue;
            }
            let b = |x: f64| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
            let colour =
                egui::Color32::from_rgba_unmultiplied(b(c[0]), b(c[1]), b(c[2]), b(0.85 * c[3]));
            let r = egui::Rect::from_two_pos(
                to_screen(rect, i as f32 * cell, j as f32 * cell),
                to_screen(rect, (i + 1) as f32 * cell, (j + 1) as f32 * cell),
            );
            mesh.add_colored_rect(r, colour);
        }
    }
    painter.add(egui::Shape::mesh(mesh));
    for (k, q) in tf.primitives.iter().enumerate() {
        let selected = state.selected == Some(k);
        let colour = opaque(q.color);
        let [vc, gc] = q.centre;
        let [w, h] = q.size;
        let outline = |width: f32, c: egui::Color32| -> egui::Shape {
            let stroke = egui::Stroke::new(width, c);
            match q.shape {
                Shape2d::Rectangle => egui::Shape::rect_stroke(
                    egui::Rect::from_two_pos(
                        to_screen(rect, vc - 0.5 * w, gc - 0.5 * h),
                        to_screen(rect, vc + 0.5 * w, gc + 0.5 * h),
                    ),
                    0.0,
                    stroke,
                    egui::StrokeKind::Middle,
                ),
                Shape2d::Triangle => egui::Shape::closed_line(
                    vec![
                        to_screen(rect, vc, 0.0),
                        to_screen(rect, vc + 0.5 * w, h),
                        to_screen(rect, vc - 0.5 * w, h),
                    ],
                    stroke,
                ),
                Shape2d::Gaussian => egui::Shape::ellipse_stroke(
                    to_screen(rect, vc, gc),
                    egui::vec2(0.5 * w * rect.width(), 0.5 * h * rect.height()),
                    stroke,
                ),
            }
        };
        let width = if selected { 2.5 } else { 1.5 };
        painter.add(outline(width + 2.0, egui::Color32::from_black_alpha(160)));
        painter.add(outline(width, colour));
        let [hv, hg] = handle_at(q);
        let handle =
            egui::Rect::from_center_size(to_screen(rect, hv, hg), egui::Vec2::splat(HANDLE));
        painter.rect_filled(
            handle,
            1.0,
            if selected {
                egui::Color32::WHITE
            } else {
                colour
            },
        );
        painter.rect_stroke(
            handle,
            1.0,
            egui::Stroke::new(1.0, egui::Color32::BLACK),
            egui::StrokeKind::Outside,
        );
    }
    let weak = ui.visuals().weak_text_color();
    let font = egui::FontId::proportional(10.0);
    let (x_label, y_label) = y_axis.labels();
    painter.text(
        rect.right_bottom() + egui::vec2(-4.0, -2.0),
        egui::Align2::RIGHT_BOTTOM,
        x_label,
        font.clone(),
        weak,
    );
    painter.text(
        rect.left_top() + egui::vec2(4.0, 2.0),
        egui::Align2::LEFT_TOP,
        y_label,
        font,
        weak,
    );

    // the selected primitive's controls
    if let Some(i) = state.selected {
        let mut remove = false;
        let q = &mut tf.primitives[i];
        let before = *q;
        ui.horizontal(|ui| {
            ui.label(format!("primitive {i}"));
            egui::ComboBox::new(id.with("shape"), "shape")
                .selected_text(q.shape.name())
                .show_ui(ui, |ui| {
                    for s in Shape2d::ALL {
                        ui.selectable_value(&mut q.shape, s, s.name());
                    }
                });
            // through a copy: the picker's premultiplied round trip perturbs the
            // components even when nothing was edited
            let mut colour = q.color;
            if ui
                .color_edit_button_rgba_unmultiplied(&mut colour)
                .changed()
            {
                q.color = colour;
            }
            remove = ui.button("Remove").clicked();
        });
        fn slider<'a>(
            value: &'a mut f32,
            range: std::ops::RangeInclusive<f32>,
            text: &str,
        ) -> egui::Slider<'a> {
            egui::Slider::new(value, range)
                .clamping(egui::SliderClamping::Edits)
                .text(text)
        }
        ui.add(slider(&mut q.centre[0], 0.0..=1.0, "centre value"));
        if q.shape == Shape2d::Triangle {
            ui.label("a triangle's apex is at gradient magnitude 0");
        } else {
            ui.add(slider(&mut q.centre[1], 0.0..=1.0, "centre gradient"));
        }
        ui.add(slider(&mut q.size[0], MIN_SIZE..=MAX_SIZE, "width (value)").logarithmic(true));
        ui.add(slider(&mut q.size[1], MIN_SIZE..=MAX_SIZE, "height (gradient)").logarithmic(true));
        ui.add(slider(&mut q.color[3], 0.0..=1.0, "opacity"));
        if *q != before {
            changed = true;
            edited.push(i);
        }
        if remove {
            tf.primitives.remove(i);
            state.selected = None;
            state.drag = None;
            edited.clear();
            changed = true;
        }
    }

    let mut add_buttons = [egui::Rect::NOTHING; 3];
    ui.horizontal(|ui| {
        for (k, (shape, label)) in [
            (Shape2d::Rectangle, "Add rectangle"),
            (Shape2d::Triangle, "Add triangle"),
            (Shape2d::Gaussian, "Add gaussian"),
        ]
        .into_iter()
        .enumerate()
        {
            let button = ui.button(label);
            add_buttons[k] = button.rect;
            if button.clicked() {
                tf.primitives.push(default_primitive(shape));
                state.selected = Some(tf.primitives.len() - 1);
                changed = true;
            }
        }
    });

    for i in edited {
        if let Some(q) = tf.primitives.get_mut(i) {
            sanitize(q);
        }
    }
    ui.data_mut(|d| d.insert_temp(id, state));
    Output {
        changed,
        plot: rect,
        add_buttons,
        selected: state.selected,
    }
}

/// The histogram as a grey image: ln(1 + count) linear to grey, the largest white;
/// value along x, gradient magnitude 0 in the bottom row. `hist` is `bins` × `bins`,
/// value fastest, gradient rows from 0 up (as `histogram2d` gives it).
fn histogram_image(hist: &[f32], bins: usize) -> egui::ColorImage {
    let max = hist
        .iter()
        .copied()
        .filter(|x| x.is_finite())
        .fold(0.0f32, f32::max);
    let scale = if max > 0.0 { 255.0 / max } else { 0.0 };
    let grey = (0..bins * bins).map(|k| {
        let (x, row) = (k % bins, k / bins);
        let g = bins - 1 - row;
        let h = hist.get(g * bins + x).copied().unwrap_or(0.0);
        if h.is_finite() {
            (h.max(0.0) * scale).round().min(255.0) as u8
        } else {
            0
        }
    });
    egui::ColorImage::from_gray_iter([bins, bins], grey)
}

/// One cached histogram texture: the volume (weak, so that its address cannot be
/// reused while the entry lives), the y axis's key and the texture.
#[derive(Clone)]
struct CachedHistogram {
    volume: Weak<Volume>,
    y_axis: u64,
    texture: egui::TextureHandle,
}

/// The histogram under [`tf2d_editor`] as a [`HISTOGRAM_BINS`]² grey texture: over
/// (value, clamp(|∇f|·scale, 0, 1)) for the gradient axis; for the data axis, the
/// volume's values along y in every column
/// ([`vwb_plugins::classify_tf2d::histogram_data_rows`]: x is what the stack's sample
/// hooks give). Computed once per (volume, y axis) and cached in `ctx` (the last few).
pub fn histogram_texture(
    ctx: &egui::Context,
    volume: &Arc<Volume>,
    y_axis: YAxis,
) -> egui::TextureHandle {
    let id = egui::Id::unique("vwb tf2d editor histogram textures");
    let mut cache: Vec<CachedHistogram> = ctx.data(|d| d.get_temp(id)).unwrap_or_default();
    cache.retain(|e| e.volume.strong_count() > 0);
    let hit = cache.iter().position(|e| {
        std::ptr::eq(e.volume.as_ptr(), Arc::as_ptr(volume)) && e.y_axis == y_axis.key()
    });
    let entry = match hit {
        Some(k) => cache.remove(k),
        None => {
            let hist = match y_axis {
                YAxis::Gradient { scale } => {
                    vwb_plugins::classify_tf2d::histogram2d(volume, scale, HISTOGRAM_BINS)
                }
                YAxis::Data => {
                    vwb_plugins::classify_tf2d::histogram_data_rows(volume, HISTOGRAM_BINS)
                }
            };
            let texture = ctx.load_texture(
                format!("tf2d histogram {} {y_axis:?}", volume.name),
                histogram_image(&hist, HISTOGRAM_BINS),
                egui::TextureOptions::LINEAR,
            );
            CachedHistogram {
                volume: Arc::downgrade(volume),
                y_axis: y_axis.key(),
                texture,
            }
        }
    };
    let texture = entry.texture.clone();
    cache.push(entry);
    if cache.len() > CACHE_LEN {
        cache.remove(0);
    }
    ctx.data_mut(|d| d.insert_temp(id, cache));
    texture
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_input::press;

    fn rectangle(centre: [f32; 2], size: [f32; 2]) -> Primitive2d {
        Primitive2d {
            shape: Shape2d::Rectangle,
            centre,
            size,
            color: [1.0, 0.5, 0.2, 0.6],
        }
    }

    /// A headless egui context fed one frame at a time, 1/60 s apart.
    struct Headless {
        ctx: egui::Context,
        time: f64,
    }

    impl Headless {
        fn new() -> Self {
            Headless {
                ctx: egui::Context::default(),
                time: 0.0,
            }
        }

        /// Runs one frame of the editor with `events`.
        fn frame(&mut self, tf: &mut Tf2d, events: Vec<egui::Event>) -> Output {
            self.time += 1.0 / 60.0;
            let input = egui::RawInput {
                screen_rect: Some(egui::Rect::from_min_size(
                    egui::Pos2::ZERO,
                    egui::vec2(500.0, 900.0),
                )),
                time: Some(self.time),
                events,
                ..Default::default()
            };
            let mut result = None;
            let mut out = self.ctx.run_ui(input, |ui| {
                egui::CentralPanel::default().show(ui, |ui| {
                    result = Some(editor(ui, 1, tf, None, YAxis::Gradient { scale: 1.0 }));
                });
            });
            out.textures_delta.clear();
            result.expect("the editor ran")
        }

        /// Presses the primary button at `from`, drags to `to` in six steps and
        /// releases; whether any frame reported a change.
        fn drag(&mut self, tf: &mut Tf2d, from: egui::Pos2, to: egui::Pos2) -> bool {
            let primary = egui::PointerButton::Primary;
            let mut changed = self
                .frame(tf, vec![egui::Event::PointerMoved(from)])
                .changed;
            changed |= self.frame(tf, vec![press(from, true, primary)]).changed;
            for k in 1..=6 {
                let p = from + (to - from) * (k as f32 / 6.0);
                changed |= self.frame(tf, vec![egui::Event::PointerMoved(p)]).changed;
            }
            changed |= self.frame(tf, vec![press(to, false, primary)]).changed;
            changed
        }

        /// Clicks `button` at `at` without moving; the last frame's output.
        fn click(&mut self, tf: &mut Tf2d, at: egui::Pos2, button: egui::PointerButton) -> Output {
            self.frame(tf, vec![egui::Event::PointerMoved(at)]);
            self.frame(tf, vec![press(at, true, button)]);
            self.frame(tf, vec![press(at, false, button)])
        }
    }

    fn close(a: [f32; 2], b: [f32; 2], tol: f32) -> bool {
        (a[0] - b[0]).abs() < tol && (a[1] - b[1]).abs() < tol
    }

    /// (a) Dragging inside a primitive moves its centre by the dragged amount in TF
    /// units (grabbed off-centre: no jump to the pointer) and selects it; a
    /// triangle moves along the value axis only.
    #[test]
    fn dragging_inside_moves_the_centre() {
        let mut ui = Headless::new();
        let mut tf = Tf2d {
            primitives: vec![rectangle([0.5, 0.5], [0.3, 0.3])],
        };
        let rect = ui.frame(&mut tf, vec![]).plot;
        assert!(rect.width() > 100.0 && rect.height() > 100.0, "{rect:?}");
        let from = to_screen(rect, 0.42, 0.44);
        let to = to_screen(rect, 0.57, 0.64);
        assert!(ui.drag(&mut tf, from, to));
        let p = tf.primitives[0];
        assert!(close(p.centre, [0.65, 0.7], 0.01), "{p:?}");
        assert_eq!(p.size, [0.3, 0.3], "moving keeps the size");
        assert_eq!(ui.frame(&mut tf, vec![]).selected, Some(0));
        assert!(tf.validate().is_ok());

        // dragging past the edge keeps the centre in [0, 1]
        let from = to_screen(rect, 0.65, 0.7);
        ui.drag(&mut tf, from, rect.left_top() - egui::vec2(6.0, 6.0));
        let p = tf.primitives[0];
        assert!(close(p.centre, [0.0, 1.0], 1e-6), "{p:?}");

        let mut tf = Tf2d {
            primitives: vec![default_primitive(Shape2d::Triangle)],
        };
        let from = to_screen(rect, 0.5, 0.4);
        let to = to_screen(rect, 0.3, 0.2);
        assert!(ui.drag(&mut tf, from, to));
        let p = tf.primitives[0];
        assert!(close(p.centre, [0.3, 0.0], 0.01), "{p:?}");
        assert_eq!(p.size, [0.2, 0.5]);
    }

    /// (b) Dragging the top-right handle resizes about the centre; the size stays
    /// at least `MIN_SIZE`.
    #[test]
    fn dragging_the_handle_resizes() {
        let mut ui = Headless::new();
        let mut tf = Tf2d {
            primitives: vec![rectangle([0.5, 0.5], [0.2, 0.2])],
        };
        let rect = ui.frame(&mut tf, vec![]).plot;
        let handle = to_screen(rect, 0.6, 0.6);
        assert!(ui.drag(&mut tf, handle, to_screen(rect, 0.7, 0.75)));
        let p = tf.primitives[0];
        assert!(close(p.size, [0.4, 0.5], 0.01), "{p:?}");
        assert_eq!(p.centre, [0.5, 0.5], "resizing keeps the centre");

        // shrinking past the centre stops at the minimum size
        let handle = to_screen(rect, 0.7, 0.75);
        ui.drag(&mut tf, handle, to_screen(rect, 0.2, 0.1));
        let p = tf.primitives[0];
        assert_eq!(p.size, [MIN_SIZE, MIN_SIZE], "{p:?}");
        assert!(tf.validate().is_ok());

        // a triangle's handle sets its width and its height above gradient 0
        let mut tf = Tf2d {
            primitives: vec![default_primitive(Shape2d::Triangle)],
        };
        let handle = to_screen(rect, 0.6, 0.5);
        assert!(ui.drag(&mut tf, handle, to_screen(rect, 0.65, 0.8)));
        let p = tf.primitives[0];
        assert!(close(p.size, [0.3, 0.8], 0.01), "{p:?}");
        assert_eq!(p.centre, [0.5, 0.0]);
    }

    /// (c) Right-clicking a primitive removes it (the topmost where they overlap);
    /// right-clicking empty space removes nothing; a click selects.
    #[test]
    fn right_click_removes_and_click_selects() {
        let mut ui = Headless::new();
        let a = rectangle([0.3, 0.3], [0.2, 0.2]);
        let b = Primitive2d {
            shape: Shape2d::Gaussian,
            ..rectangle([0.7, 0.6], [0.2, 0.2])
        };
        let mut tf = Tf2d {
            primitives: vec![a, b],
        };
        let rect = ui.frame(&mut tf, vec![]).plot;
        let secondary = egui::PointerButton::Secondary;
        let primary = egui::PointerButton::Primary;

        let out = ui.click(&mut tf, to_screen(rect, 0.7, 0.6), primary);
        assert_eq!(out.selected, Some(1));
        assert!(!out.changed);
        let out = ui.click(&mut tf, to_screen(rect, 0.05, 0.9), primary);
        assert_eq!(out.selected, None, "a click on empty space deselects");

        let out = ui.click(&mut tf, to_screen(rect, 0.05, 0.9), secondary);
        assert!(!out.changed);
        assert_eq!(tf.primitives.len(), 2);

        // the Gaussian's half-maximum ellipse has radius 0.1: 0.78 is inside
        let out = ui.click(&mut tf, to_screen(rect, 0.78, 0.6), secondary);
        assert!(out.changed);
        assert_eq!(tf.primitives, vec![a]);

        ui.click(&mut tf, to_screen(rect, 0.35, 0.25), primary);
        ui.click(&mut tf, to_screen(rect, 0.35, 0.25), secondary);
        assert!(tf.primitives.is_empty());
        assert_eq!(ui.frame(&mut tf, vec![]).selected, None);
    }

    /// (d) The "Add …" buttons, clicked where they are drawn, add a primitive of
    /// their shape and select it; its controls then appear.
    #[test]
    fn add_buttons_add_and_select() {
        let mut ui = Headless::new();
        let mut tf = Tf2d::default();
        let out = ui.frame(&mut tf, vec![]);
        let gaussian = out.add_buttons[2];
        assert!(gaussian.is_positive() && gaussian.top() > out.plot.bottom());
        let out = ui.click(&mut tf, gaussian.center(), egui::PointerButton::Primary);
        assert!(out.changed);
        assert_eq!(tf.primitives.len(), 1);
        assert_eq!(tf.primitives[0].shape, Shape2d::Gaussian);
        assert_eq!(out.selected, Some(0));
        assert!(tf.validate().is_ok());

        // the selected primitive's controls push the buttons down
        let out = ui.frame(&mut tf, vec![]);
        assert!(out.add_buttons[0].top() > gaussian.bottom());
        let out = ui.click(
            &mut tf,
            out.add_buttons[1].center(),
            egui::PointerButton::Primary,
        );
        assert!(out.changed);
        assert_eq!(
            tf.primitives.iter().map(|p| p.shape).collect::<Vec<_>>(),
            [Shape2d::Gaussian, Shape2d::Triangle]
        );
        assert_eq!(out.selected, Some(1));
        // a new primitive is where a click finds it
        let p = tf.primitives[1];
        assert!(inside(&p, [p.centre[0], 0.5 * p.size[1]]));
    }

    /// (e) The histogram texture is computed once per (volume, y axis).
    #[test]
    fn histogram_texture_is_cached_per_volume_and_axis() {
        let ctx = egui::Context::default();
        let volume = Arc::new(vwb_render::volume::demo());
        let g = |scale| YAxis::Gradient { scale };
        let first = histogram_texture(&ctx, &volume, g(4.0));
        assert_eq!(first.size(), [HISTOGRAM_BINS, HISTOGRAM_BINS]);
        assert_eq!(histogram_texture(&ctx, &volume, g(4.0)).id(), first.id());
        let other_scale = histogram_texture(&ctx, &volume, g(8.0));
        assert_ne!(other_scale.id(), first.id());
        assert_eq!(histogram_texture(&ctx, &volume, g(4.0)).id(), first.id());
        let other_volume = Arc::new(vwb_render::volume::demo());
        assert_ne!(
            histogram_texture(&ctx, &other_volume, g(4.0)).id(),
            first.id()
        );
        assert_eq!(
            histogram_texture(&ctx, &volume, g(8.0)).id(),
            other_scale.id()
        );
        let data = histogram_texture(&ctx, &volume, YAxis::Data);
        assert_ne!(data.id(), first.id());
        assert_eq!(
            histogram_texture(&ctx, &volume, YAxis::Data).id(),
            data.id()
        );
    }

    /// With `y_axis: data` the histogram is the volume's values along y, the same in
    /// every column, and the axes say what they show.
    #[test]
    fn the_data_axis_shows_the_volume_values_along_y() {
        use vwb_render::params::{ParamValue, ParamValues};
        let volume = vwb_render::volume::demo();
        let bins = 16;
        let hist = vwb_plugins::classify_tf2d::histogram_data_rows(&volume, bins);
        assert_eq!(hist.len(), bins * bins);
        for row in hist.chunks(bins) {
            assert!(row.iter().all(|&c| c == row[0]), "{row:?}");
        }
        // the rows are the log counts of the values (the demo's background is 0)
        let total: f64 = hist
            .chunks(bins)
            .map(|row| (row[0] as f64).exp_m1().round())
            .sum();
        assert_eq!(total as usize, volume.normalized_scalars().len());
        assert!(
            hist[0] > hist[(bins - 1) * bins],
            "most of the demo is background"
        );
        let mut values = ParamValues::default();
        values.set("gradient_scale", ParamValue::Float(4.0));
        assert_eq!(YAxis::of(&values), YAxis::Gradient { scale: 4.0 });
        values.set("y_axis", ParamValue::Enum("data".into()));
        assert_eq!(YAxis::of(&values), YAxis::Data);
        assert!(YAxis::Data.labels().1.contains("volume value"));
    }

    /// The grey image: the largest log count white, gradient 0 at the bottom,
    /// value along x.
    #[test]
    fn histogram_image_orientation_and_scale() {
        let bins = 4;
        let mut hist = vec![0.0f32; bins * bins];
        hist[1] = 2.0; // value bin 1, gradient bin 0
        hist[3 * bins + 2] = 1.0; // value bin 2, gradient bin 3
        let image = histogram_image(&hist, bins);
        assert_eq!(image.size, [bins, bins]);
        let at = |x: usize, y: usize| image.pixels[y * bins + x];
        assert_eq!(at(1, bins - 1), egui::Color32::WHITE);
        assert_eq!(at(2, 0), egui::Color32::from_gray(128));
        assert_eq!(at(0, 0), egui::Color32::BLACK);
        assert_eq!(at(1, 0), egui::Color32::BLACK);
    }
}
