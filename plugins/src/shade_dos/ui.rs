//! The directional-occlusion plugin's own widget in the window (feature `ui`).

use crate::params::ParamValues;

/// Height of the cone diagram in points.
const CONE_HEIGHT: f32 = 70.0;

/// Directional occlusion: the backward cone of aperture θ drawn to scale over a few
/// slices (Schott et al. 2009, Fig. 3): the occlusion extent d·tan θ grows with the
/// slice distance d. Dragging sideways on the diagram sets θ.
pub fn cone(
    ui: &mut egui::Ui,
    params: &mut ParamValues,
    _volumes: Option<&vwb_render::inputs::Volumes<'_>>,
) -> bool {
    let theta = params.float("theta_deg");
    let width = ui.available_width().clamp(120.0, 260.0);
    let (rect, response) =
        ui.allocate_exact_size(egui::vec2(width, CONE_HEIGHT), egui::Sense::drag());
    let painter = ui.painter_at(rect);
    let visuals = ui.visuals();
    painter.rect_filled(rect, 2.0, visuals.extreme_bg_color);
    // the apex (the sample) at the right, the cone opening towards the eye (or the
    // directional light) at the left
    let apex = egui::pos2(rect.right() - 10.0, rect.center().y);
    let slices = 5;
    let step = (rect.width() - 20.0) / slices as f32;
    let stroke = egui::Stroke::new(1.0, visuals.weak_text_color());
    for k in 1..=slices {
        let x = apex.x - k as f32 * step;
        painter.line_segment(
            [
                egui::pos2(x, rect.top() + 2.0),
                egui::pos2(x, rect.bottom() - 2.0),
            ],
            stroke,
        );
    }
    let half = rect.height() * 0.5 - 4.0;
    let reach = apex.x - rect.left() - 10.0;
    let spread = (theta.to_radians().tan() * reach).min(half);
    let end = egui::pos2(apex.x - reach, apex.y);
    let colour = egui::Color32::from_rgb(230, 160, 60);
    let cone = vec![
        apex,
        egui::pos2(end.x, end.y - spread),
        egui::pos2(end.x, end.y + spread),
    ];
    painter.add(egui::Shape::convex_polygon(
        cone,
        colour.gamma_multiply(0.35),
        egui::Stroke::new(1.5, colour),
    ));
    painter.circle_filled(apex, 3.0, colour);
    painter.text(
        rect.left_top() + egui::vec2(4.0, 2.0),
        egui::Align2::LEFT_TOP,
        format!(
            "θ = {theta:.1}°, cone towards the {} (drag)",
            if params.enumeration("light") == "directional" {
                "light"
            } else {
                "eye"
            }
        ),
        egui::FontId::proportional(11.0),
        visuals.text_color(),
    );
    let dx = response.drag_delta().x;
    if dx != 0.0 {
        let new = (theta - dx * 0.5).clamp(0.0, 89.9);
        if new != theta {
            params.set("theta_deg", crate::params::ParamValue::Float(new));
            return true;
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PluginInstance;

    fn press(pos: egui::Pos2, pressed: bool, button: egui::PointerButton) -> egui::Event {
        egui::Event::PointerButton {
            pos,
            button,
            pressed,
            modifiers: egui::Modifiers::NONE,
        }
    }

    /// Dragging left on the cone diagram widens the cone.
    #[test]
    fn dragging_the_cone_sets_theta() {
        let r = crate::builtin_registry();
        let mut inst = PluginInstance::new(r.get("shade.dos").unwrap());
        let before = inst.params.float("theta_deg");
        let ctx = egui::Context::default();
        let hook: crate::ui::CustomUi = cone;
        let rect = std::cell::Cell::new(egui::Rect::NOTHING);
        let frame = |events: Vec<egui::Event>, t: f64, inst: &mut PluginInstance| {
            let input = egui::RawInput {
                events,
                time: Some(t),
                screen_rect: Some(egui::Rect::from_min_size(
                    egui::Pos2::ZERO,
                    egui::vec2(400.0, 300.0),
                )),
                ..Default::default()
            };
            let mut changed = false;
            let mut out = ctx.run_ui(input, |ui| {
                egui::CentralPanel::default().show(ui, |ui| {
                    let top = ui.cursor().min;
                    changed |= hook(ui, &mut inst.params, None);
                    rect.set(egui::Rect::from_min_size(
                        top,
                        egui::vec2(120.0, CONE_HEIGHT),
                    ));
                });
            });
            out.textures_delta.clear();
            changed
        };
        frame(vec![], 0.0, &mut inst);
        let start = rect.get().center();
        let end = start - egui::vec2(20.0, 0.0);
        let button = |pos, pressed| press(pos, pressed, egui::PointerButton::Primary);
        frame(
            vec![egui::Event::PointerMoved(start), button(start, true)],
            0.1,
            &mut inst,
        );
        let mut changed = false;
        for (i, k) in [0.3f32, 0.6, 1.0].iter().enumerate() {
            let p = start + (end - start) * *k;
            changed |= frame(
                vec![egui::Event::PointerMoved(p)],
                0.2 + i as f64 * 0.1,
                &mut inst,
            );
        }
        frame(vec![button(end, false)], 0.6, &mut inst);
        let after = inst.params.float("theta_deg");
        assert!(changed);
        assert!(
            (after - (before + 10.0)).abs() < 1.0,
            "θ {before} → {after}, expected +10° for a 20-point drag"
        );
    }
}
