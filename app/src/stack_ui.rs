//! The plugin-stack editor of the window: parameter widgets generated from each
//! plugin's declarative spec (log sliders, integer sliders, checkboxes, combo boxes,
//! colour pickers, vec3 drag values, path fields), and the stack operations (add from
//! the registry by category, remove, reorder by dragging the :: handle or with up/down,
//! duplicate, enable/disable, open the plugin's WGSL in the editor). A plugin may add
//! its own widgets above the generated ones ([`vwb_plugins::ui`], declared beside the plugin). A composer or
//! resource error appears under the plugin it names.

use std::path::PathBuf;

use vwb_render::params::{Animation, ParamKind, ParamSpec, ParamValue, ParamValues};
use vwb_render::plugin::{Category, PluginInstance, Registry};

/// A change to the stack's order or membership.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StackOp {
    Up(usize),
    Down(usize),
    Duplicate(usize),
    Remove(usize),
    /// Drag and drop: the entry at `from` is inserted before the entry now at `to`
    /// (`to == len` appends).
    Move {
        from: usize,
        to: usize,
    },
}

/// Applies `op`; false when it does nothing (e.g. moving the first entry up).
pub fn apply(stack: &mut Vec<PluginInstance>, op: StackOp) -> bool {
    match op {
        StackOp::Up(i) if i > 0 && i < stack.len() => stack.swap(i - 1, i),
        StackOp::Down(i) if i + 1 < stack.len() => stack.swap(i, i + 1),
        StackOp::Duplicate(i) if i < stack.len() => {
            let copy = stack[i].duplicate();
            stack.insert(i + 1, copy);
        }
        StackOp::Remove(i) if i < stack.len() => {
            stack.remove(i);
        }
        StackOp::Move { from, to }
            if from < stack.len() && to <= stack.len() && to != from && to != from + 1 =>
        {
            let inst = stack.remove(from);
            stack.insert(if to > from { to - 1 } else { to }, inst);
        }
        _ => return false,
    }
    true
}

/// Widgets for `values` generated from `specs`; true when a value changed. 1D transfer
/// functions get the curve editor over the histogram ([`crate::tf_editor`]), 2D ones
/// the 2D editor over the 2D histogram ([`crate::tf2d_editor`]). The elements of a
/// parameter group ([`vwb_render::params::Group`]: lights, clip shapes, label TFs,
/// isosurfaces) each get a header ("Light 1 · off"): the elements in use are listed,
/// those switched off after the first are left out (the first stays, to switch on), and
/// those past the group's limit are hidden.
pub fn param_widgets(
    ui: &mut egui::Ui,
    salt: u64,
    specs: &[ParamSpec],
    values: &mut ParamValues,
    cx: &StackUi<'_>,
) -> bool {
    // the y axis of a 2D TF's histogram (classify.tf2d's `y_axis` and
    // `gradient_scale`; plugins without them have no 2D TF)
    let y_axis = crate::tf2d_editor::YAxis::of(values);
    let mut changed = false;
    // the groups with an element switched off so far: only the first such is listed
    let mut off_seen: Vec<vwb_render::params::Group> = Vec::new();
    let mut k = 0;
    while k < specs.len() {
        let Some(element) = specs[k].element else {
            if specs[k].is_shown(values) {
                changed |= param_widget(ui, salt, &specs[k], values, cx, y_axis);
            }
            k += 1;
            continue;
        };
        let run = specs[k..]
            .iter()
            .take_while(|s| s.element == Some(element))
            .count();
        let members = &specs[k..k + run];
        k += run;
        let (group, index) = (element.group, element.index);
        let on = group.is_on(index, values);
        let first_off = !on && !off_seen.contains(&group);
        if !on {
            off_seen.push(group);
        }
        if !group.in_use(index, values) || !(on || first_off) {
            continue;
        }
        // an element that is off shows its switch only
        let switch = group.switch.map(|t| group.key(t, index));
        let title = if on {
            format!("{} {index}", group.name)
        } else {
            format!("{} {index} · off", group.name)
        };
        egui::CollapsingHeader::new(title)
            .id_salt((salt, group.name, index))
            .default_open(on && index == 0)
            .show(ui, |ui| {
                for spec in members {
                    if (on || switch == Some(spec.key)) && spec.is_shown(values) {
                        changed |= param_widget(ui, salt, spec, values, cx, y_axis);
                    }
                }
            });
    }
    changed
}

/// The widget of one parameter; true when it changed the value.
fn param_widget(
    ui: &mut egui::Ui,
    salt: u64,
    spec: &ParamSpec,
    values: &mut ParamValues,
    cx: &StackUi<'_>,
    y_axis: crate::tf2d_editor::YAxis,
) -> bool {
    let Some(current) = values.get(spec.key).cloned() else {
        return false;
    };
    let mut new = current.clone();
    let response = match (&spec.kind, &mut new) {
        (ParamKind::Float { min, max, log, .. }, ParamValue::Float(v)) => Some(
            ui.horizontal(|ui| {
                let r = ui.add(
                    egui::Slider::new(v, *min..=*max)
                        .logarithmic(*log)
                        .text(spec.label),
                );
                if let Some(animation) = spec.animation {
                    playback(
                        ui,
                        egui::Id::unique((salt, spec.key)),
                        animation,
                        v,
                        [*min, *max],
                    );
                }
                r
            })
            .inner,
        ),
        (ParamKind::Int { min, max, .. }, ParamValue::Int(v)) => {
            Some(ui.add(egui::Slider::new(v, *min..=*max).text(spec.label)))
        }
        (ParamKind::Bool { .. }, ParamValue::Bool(b)) => Some(ui.checkbox(b, spec.label)),
        (ParamKind::Enum { options, .. }, ParamValue::Enum(s)) => Some(
            egui::ComboBox::new((salt, spec.key), spec.label)
                .selected_text(match (spec.key, s.as_str(), cx.auto_gradient) {
                    ("gradient", "auto", Some(resolved)) => format!("auto ({resolved})"),
                    _ => s.clone(),
                })
                .show_ui(ui, |ui| {
                    for o in options.iter() {
                        ui.selectable_value(s, o.to_string(), *o);
                    }
                })
                .response,
        ),
        (ParamKind::Color { .. }, ParamValue::Color(c)) => Some(
            ui.horizontal(|ui| {
                let r = ui.color_edit_button_rgba_unmultiplied(c);
                ui.label(spec.label);
                r
            })
            .inner,
        ),
        (ParamKind::Vec3 { min, max, .. }, ParamValue::Vec3(v)) => Some(
            ui.horizontal(|ui| {
                for (x, axis) in v.iter_mut().zip(["x ", "y ", "z "]) {
                    ui.add(
                        egui::DragValue::new(x)
                            .speed(0.01)
                            .range(*min..=*max)
                            .prefix(axis),
                    );
                }
                ui.label(spec.label)
            })
            .response,
        ),
        (ParamKind::Path { .. }, ParamValue::Path(p)) => Some(path_field(ui, salt, spec, p)),
        (ParamKind::Volume { components }, ParamValue::Volume(name)) => Some(
            egui::ComboBox::new((salt, spec.key), spec.label)
                .selected_text(if name.is_empty() {
                    "(the volume)"
                } else {
                    name.as_str()
                })
                .show_ui(ui, |ui| {
                    ui.selectable_value(name, String::new(), "(the volume)");
                    for n in cx.inputs {
                        ui.selectable_value(name, n.clone(), n.as_str());
                    }
                })
                .response
                .on_hover_text(format!(
                    "{}: the document's own volume or one of its named volumes (`volumes:` in the preset)",
                    components.describe()
                )),
        ),
        (ParamKind::Tf { .. }, ParamValue::Tf(t)) => {
            ui.horizontal(|ui| {
                ui.label(spec.label);
                if let Some(volume) = cx.volume {
                    suggest_button(ui, (salt, spec.key), volume, t);
                }
            });
            // one editor state per plugin instance and parameter (classify.labels
            // has eight curves)
            crate::tf_editor::tf_editor(ui, (salt, spec.key), t, cx.histogram);
            ui.small(crate::tf_editor::axes_caption(cx.volume.map(|v| v.range)));
            None
        }
        (ParamKind::Tf2d { .. }, ParamValue::Tf2d(t)) => {
            ui.label(spec.label);
            let texture = cx
                .volume
                .map(|v| crate::tf2d_editor::histogram_texture(ui.ctx(), v, y_axis));
            crate::tf2d_editor::tf2d_editor(ui, (salt, spec.key), t, texture.as_ref(), y_axis);
            None
        }
        _ => None,
    };
    if let Some(r) = response
        && !spec.doc.is_empty()
    {
        r.on_hover_text(spec.doc);
    }
    if new == current {
        return false;
    }
    values.set(spec.key, new);
    true
}

/// How an animated parameter plays ([`playback`]): kept in egui's memory per plugin
/// instance and parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Playback {
    pub playing: bool,
    /// Units of the parameter per second.
    pub speed: f32,
    /// Start again at the minimum after the maximum (else stop there).
    pub looping: bool,
}

impl Playback {
    fn new(animation: Animation, [min, max]: [f32; 2]) -> Self {
        Self {
            playing: false,
            speed: (max - min) / 10.0,
            looping: animation == Animation::Cycle,
        }
    }

    /// The value `dt` seconds after `v` in `[min, max]`; stops at the maximum unless
    /// looping.
    pub fn advance(&mut self, v: f32, dt: f32, [min, max]: [f32; 2]) -> f32 {
        let next = v + self.speed * dt;
        if next <= max {
            return next.max(min);
        }
        if self.looping && max > min {
            min + (next - max).rem_euclid(max - min)
        } else {
            self.playing = false;
            max
        }
    }
}

/// Play / pause, speed and loop for an animated float ([`vwb_render::params::Animation`]):
/// while playing, the value advances by speed × the frame time each frame, and the
/// window renders again (the parameter's uniform only, where the plugin keeps it out
/// of its passes).
fn playback(ui: &mut egui::Ui, id: egui::Id, animation: Animation, v: &mut f32, range: [f32; 2]) {
    let mut state = ui
        .data(|d| d.get_temp::<Playback>(id))
        .unwrap_or_else(|| Playback::new(animation, range));
    let label = if state.playing { "Pause" } else { "Play" };
    if ui.button(label).clicked() {
        if !state.playing && *v >= range[1] && !state.looping {
            *v = range[0];
        }
        state.playing = !state.playing;
    }
    ui.add(
        egui::DragValue::new(&mut state.speed)
            .speed(0.1)
            .range(0.0..=(range[1] - range[0]) * 10.0)
            .suffix("/s"),
    )
    .on_hover_text("speed: units per second");
    ui.checkbox(&mut state.looping, "loop");
    if state.playing {
        let dt = ui.input(|i| i.stable_dt).min(0.1);
        *v = state.advance(*v, dt, range);
        ui.ctx().request_repaint();
    }
    ui.data_mut(|d| d.insert_temp(id, state));
}

/// A path field that applies its text when editing ends (Enter or focus lost), so that
/// partial paths are never loaded.
fn path_field(ui: &mut egui::Ui, salt: u64, spec: &ParamSpec, p: &mut PathBuf) -> egui::Response {
    let id = ui.scope_id().with((salt, spec.key, "path"));
    let mut text = ui
        .data_mut(|d| d.get_temp::<String>(id))
        .unwrap_or_else(|| p.display().to_string());
    let r = ui
        .horizontal(|ui| {
            let r = ui.text_edit_singleline(&mut text);
            ui.label(spec.label);
            r
        })
        .inner;
    if r.lost_focus() {
        *p = PathBuf::from(text.trim());
        ui.data_mut(|d| d.remove::<String>(id));
    } else if r.has_focus() {
        ui.data_mut(|d| d.insert_temp(id, text));
    }
    r
}

/// What the stack editor needs besides the stack.
pub struct StackUi<'a> {
    pub registry: &'a Registry,
    /// The last composer or resource error: shown under the first plugin whose id it
    /// names, else above the stack.
    pub error: Option<&'a str>,
    /// The volume's value histogram (1D TF editors).
    pub histogram: &'a [u64],
    /// The volume (the 2D TF editor's histogram).
    pub volume: Option<&'a std::sync::Arc<vwb_render::Volume>>,
    /// The names of the document's named volumes (`volumes:`), which volume inputs
    /// choose from.
    pub inputs: &'a [String],
    /// The named volumes as loaded (plugins' own widgets read their inputs: a label
    /// plugin lists its labels).
    pub named: &'a vwb_render::inputs::VolumeInputs,
    /// What a shading plugin's `gradient: auto` resolves to on this renderer
    /// (`Renderer::auto_gradient`), shown beside `auto`; None where no renderer is at
    /// hand.
    pub auto_gradient: Option<&'static str>,
}

impl StackUi<'_> {
    /// The volume and the named volumes, where the editor has the volume.
    fn volumes(&self) -> Option<vwb_render::inputs::Volumes<'_>> {
        self.volume
            .map(|v| vwb_render::inputs::Volumes::new(v, self.named))
    }
}

/// "Suggest" beside a 1D TF editor: replaces `tf` by the data-driven suggestion for the
/// volume ([`vwb_lab::document::suggested_tf`]), or says beside the button why it kept
/// it (no boundary above the noise, a vector volume).
fn suggest_button(
    ui: &mut egui::Ui,
    salt: impl std::hash::Hash + std::fmt::Debug,
    volume: &vwb_render::Volume,
    tf: &mut vwb_render::tf::TfCurve,
) {
    let note_id = ui.scope_id().with(("suggest note", salt));
    let clicked = ui
        .button("Suggest")
        .on_hover_text(
            "a transfer function from the volume's boundaries (Kindlmann–Durkin, noise filtered, background transparent)",
        )
        .clicked();
    if clicked {
        let note = match vwb_lab::document::suggested_tf(volume) {
            Ok((curve, note)) => {
                *tf = curve;
                note
            }
            Err(why) => why,
        };
        ui.data_mut(|d| d.insert_temp(note_id, note));
    }
    if let Some(note) = ui.data(|d| d.get_temp::<String>(note_id)) {
        ui.small(note);
    }
}

/// What happened in the stack editor this frame.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct StackResponse {
    /// The stack or a parameter changed.
    pub changed: bool,
    /// The "wgsl" button of this stack entry was clicked.
    pub edit_wgsl: Option<usize>,
}

/// The stack editor.
pub fn stack_editor(
    ui: &mut egui::Ui,
    cx: &StackUi<'_>,
    stack: &mut Vec<PluginInstance>,
) -> StackResponse {
    let mut changed = false;
    let mut edit_wgsl = None;
    let mut op = None;
    let error = cx.error;
    let at = error.and_then(|e| stack.iter().position(|i| e.contains(i.plugin.id())));
    if let (Some(e), None) = (error, at) {
        ui.colored_label(egui::Color32::RED, e);
    }
    let n = stack.len();
    let drag_id = ui.scope_id().with("stack drag");
    for (i, inst) in stack.iter_mut().enumerate() {
        let (_, dropped) = ui.dnd_drop_zone::<usize, _>(egui::Frame::NONE, |ui| {
            ui.push_id(inst.uid, |ui| {
                ui.horizontal(|ui| {
                    ui.dnd_drag_source(drag_id.with(inst.uid), i, |ui| {
                        // not selectable: the drag moves the plugin, not a text selection
                        ui.add(egui::Label::new("::").selectable(false))
                            .on_hover_text("drag onto another plugin to move it there");
                    });
                    changed |= ui
                        .checkbox(&mut inst.enabled, "on")
                        .on_hover_text("enabled")
                        .changed();
                    // enabled: drawn strong; disabled: weak
                    let name = egui::RichText::new(inst.plugin.display_name());
                    let name = if inst.enabled {
                        name.strong()
                    } else {
                        name.weak()
                    };
                    ui.label(name).on_hover_text(format!(
                        "{}\n{}",
                        inst.plugin.id(),
                        inst.plugin.description()
                    ));
                    if ui.add_enabled(i > 0, egui::Button::new("up")).clicked() {
                        op = Some(StackOp::Up(i));
                    }
                    if ui
                        .add_enabled(i + 1 < n, egui::Button::new("down"))
                        .clicked()
                    {
                        op = Some(StackOp::Down(i));
                    }
                    if ui.button("copy").on_hover_text("duplicate").clicked() {
                        op = Some(StackOp::Duplicate(i));
                    }
                    if ui.button("del").on_hover_text("remove").clicked() {
                        op = Some(StackOp::Remove(i));
                    }
                    if ui
                        .button("wgsl")
                        .on_hover_text("edit this plugin's shader")
                        .clicked()
                    {
                        edit_wgsl = Some(i);
                    }
                });
            });
        });
        if let Some(from) = dropped {
            op = Some(StackOp::Move { from: *from, to: i });
        }
        ui.push_id(inst.uid, |ui| {
            if at == Some(i)
                && let Some(e) = error
            {
                ui.colored_label(egui::Color32::RED, e);
            }
            egui::CollapsingHeader::new("parameters")
                .id_salt(("params", inst.uid))
                .default_open(i == 0)
                .show(ui, |ui| {
                    if let Some(custom) = vwb_plugins::ui::custom_ui(inst.plugin.id()) {
                        changed |= custom(ui, &mut inst.params, cx.volumes().as_ref());
                    }
                    let specs = inst.plugin.params();
                    changed |= param_widgets(ui, inst.uid, &specs, &mut inst.params, cx);
                });
        });
        ui.separator();
    }
    // while a plugin is dragged: dropping below the last one moves it to the end
    if egui::DragAndDrop::has_payload_of_type::<usize>(ui.ctx()) {
        let (_, dropped) = ui.dnd_drop_zone::<usize, _>(egui::Frame::NONE, |ui| {
            ui.weak("drop here to move to the end");
        });
        if let Some(from) = dropped {
            op = Some(StackOp::Move { from: *from, to: n });
        }
    }
    if let Some(op) = op {
        changed |= apply(stack, op);
    }
    ui.menu_button("Add plugin", |ui| {
        for c in Category::ALL {
            let plugins: Vec<_> = cx.registry.by_category(c).cloned().collect();
            if plugins.is_empty() {
                continue;
            }
            ui.menu_button(c.name(), |ui| {
                for p in plugins {
                    if ui
                        .button(p.display_name())
                        .on_hover_text(p.description())
                        .clicked()
                    {
                        stack.push(PluginInstance::new(p));
                        changed = true;
                        ui.close();
                    }
                }
            });
        }
    });
    StackResponse { changed, edit_wgsl }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stack() -> Vec<PluginInstance> {
        let r = vwb_plugins::builtin_registry();
        ["classify.tf1d", "shade.blinn_phong", "shade.dos"]
            .iter()
            .map(|id| PluginInstance::new(r.get(id).unwrap()))
            .collect()
    }

    fn ids(s: &[PluginInstance]) -> Vec<&'static str> {
        s.iter().map(|i| i.plugin.id()).collect()
    }

    #[test]
    fn stack_operations() {
        let mut s = stack();
        assert!(!apply(&mut s, StackOp::Up(0)));
        assert!(!apply(&mut s, StackOp::Down(2)));
        assert!(apply(&mut s, StackOp::Down(0)));
        assert_eq!(ids(&s), ["shade.blinn_phong", "classify.tf1d", "shade.dos"]);
        assert!(apply(&mut s, StackOp::Up(2)));
        assert_eq!(ids(&s), ["shade.blinn_phong", "shade.dos", "classify.tf1d"]);
        let uid = s[1].uid;
        assert!(apply(&mut s, StackOp::Duplicate(1)));
        assert_eq!(s.len(), 4);
        assert_eq!(s[2].plugin.id(), "shade.dos");
        assert_ne!(s[2].uid, uid, "a duplicate has its own identity");
        assert!(apply(&mut s, StackOp::Remove(0)));
        assert!(!apply(&mut s, StackOp::Remove(9)));
        assert_eq!(ids(&s), ["shade.dos", "shade.dos", "classify.tf1d"]);
        // drag and drop: before the entry at `to`, or to the end
        let mut s = stack();
        assert!(apply(&mut s, StackOp::Move { from: 0, to: 3 }));
        assert_eq!(ids(&s), ["shade.blinn_phong", "shade.dos", "classify.tf1d"]);
        assert!(apply(&mut s, StackOp::Move { from: 2, to: 0 }));
        assert_eq!(ids(&s), ["classify.tf1d", "shade.blinn_phong", "shade.dos"]);
        assert!(apply(&mut s, StackOp::Move { from: 2, to: 1 }));
        assert_eq!(ids(&s), ["classify.tf1d", "shade.dos", "shade.blinn_phong"]);
        for (from, to) in [(1, 1), (1, 2), (0, 4), (5, 0)] {
            assert!(!apply(&mut s, StackOp::Move { from, to }), "{from}→{to}");
        }
    }

    /// Playing advances by speed × time, stops at the maximum or loops to the minimum.
    #[test]
    fn playback_advances_loops_and_stops() {
        let mut p = Playback::new(Animation::Clock, [0.0, 100.0]);
        assert!(!p.looping && p.speed == 10.0);
        p.playing = true;
        assert_eq!(p.advance(20.0, 0.5, [0.0, 100.0]), 25.0);
        assert_eq!(p.advance(98.0, 0.5, [0.0, 100.0]), 100.0);
        assert!(!p.playing, "a clock stops at its end");
        let mut c = Playback::new(Animation::Cycle, [0.0, 360.0]);
        assert!(c.looping);
        c.playing = true;
        assert!((c.advance(350.0, 1.0, [0.0, 360.0]) - 26.0).abs() < 1e-4);
        assert!(c.playing);
    }

    /// A playing parameter advances frame by frame in the real widget: `flow.arrival`'s
    /// time, after a click on Play, at the speed shown.
    #[test]
    fn a_played_time_advances_with_the_frames() {
        let r = vwb_plugins::builtin_registry();
        let mut i = PluginInstance::new(r.get("flow.arrival").unwrap());
        let specs = i.plugin.params();
        let ctx = egui::Context::default();
        let id = egui::Id::unique((7u64, "time"));
        let before = i.params.float("time");
        let mut time = 0.0;
        for frame in 0..6 {
            if frame == 1 {
                // what the Play button does
                ctx.data_mut(|d| {
                    let mut p = Playback::new(Animation::Clock, [0.0, 1024.0]);
                    p.playing = true;
                    d.insert_temp(id, p)
                });
            }
            let input = egui::RawInput {
                time: Some(time),
                ..Default::default()
            };
            time += 0.05;
            let mut out = ctx.run_ui(input, |ui| {
                let cx = StackUi {
                    registry: &r,
                    error: None,
                    histogram: &[],
                    volume: None,
                    inputs: &[],
                    named: vwb_render::inputs::VolumeInputs::empty(),
                    auto_gradient: None,
                };
                param_widgets(ui, 7, &specs, &mut i.params, &cx);
            });
            out.textures_delta.clear();
        }
        let after = i.params.float("time");
        // five frames played at 102.4 per second, each at most 0.1 s
        assert!(after > before + 1.0, "{before} → {after}");
        assert!(
            after <= before + 5.0 * 0.1 * 102.4 + 1e-3,
            "{before} → {after}"
        );
    }

    /// Every built-in plugin's parameters lay out headless without panicking, and
    /// untouched widgets change nothing.
    #[test]
    fn every_builtin_spec_lays_out_and_changes_nothing_by_itself() {
        let r = vwb_plugins::builtin_registry();
        let mut all: Vec<PluginInstance> = r
            .plugins()
            .iter()
            .map(|p| PluginInstance::new(p.clone()))
            .collect();
        let before: Vec<_> = all.iter().map(|i| i.params.clone()).collect();
        let ctx = egui::Context::default();
        let mut changed = false;
        for _ in 0..2 {
            let mut out = ctx.run_ui(egui::RawInput::default(), |ui| {
                egui::CentralPanel::default().show(ui, |ui| {
                    egui::ScrollArea::vertical().show(ui, |ui| {
                        let cx = StackUi {
                            registry: &r,
                            error: Some("shade.dos: broken"),
                            histogram: &[1, 10, 100],
                            volume: None,
                            inputs: &[],
                            named: vwb_render::inputs::VolumeInputs::empty(),
                            auto_gradient: Some("precomputed_central"),
                        };
                        changed |= stack_editor(ui, &cx, &mut all).changed;
                    });
                });
            });
            // no renderer here: the font atlas upload is dropped on purpose
            out.textures_delta.clear();
        }
        assert!(!changed);
        for (i, b) in all.iter().zip(before) {
            assert_eq!(i.params, b, "{}", i.plugin.id());
        }
    }
}

/// Every built-in plugin's parameter UI, all sections open, drawn as a user sees it:
/// egui_kittest fails on glyphs the default fonts lack and on widgets without an
/// accessible name.
#[cfg(test)]
mod kittest_tests {
    use super::*;
    use egui_kittest::Harness;
    use egui_kittest::kittest::Queryable;

    /// The stack editor over `stack` with the demo volume (its histogram, its
    /// suggestion), in a scroll area `height` points tall.
    fn demo_harness(
        stack: Vec<PluginInstance>,
        height: f32,
    ) -> Harness<'static, Vec<PluginInstance>> {
        harness_with_inputs(stack, height, Vec::new(), Default::default())
    }

    /// [`demo_harness`] for a document with the named volumes `inputs`, of which
    /// `named` are loaded.
    fn harness_with_inputs(
        stack: Vec<PluginInstance>,
        height: f32,
        inputs: Vec<String>,
        named: vwb_render::inputs::VolumeInputs,
    ) -> Harness<'static, Vec<PluginInstance>> {
        let r = vwb_plugins::builtin_registry();
        let volume = std::sync::Arc::new(vwb_render::volume::demo());
        Harness::builder()
            .with_size([420.0, height])
            .build_ui_state(
                move |ui, stack: &mut Vec<PluginInstance>| {
                    let cx = StackUi {
                        registry: &r,
                        error: None,
                        histogram: &volume.histogram,
                        volume: Some(&volume),
                        inputs: &inputs,
                        named: &named,
                        auto_gradient: Some("precomputed_central"),
                    };
                    egui::ScrollArea::vertical().show(ui, |ui| {
                        stack_editor(ui, &cx, stack);
                    });
                },
                stack,
            )
    }

    #[test]
    fn every_builtin_plugin_ui_has_its_glyphs_and_accessible_names() {
        let stack: Vec<PluginInstance> = vwb_plugins::builtin_registry()
            .plugins()
            .iter()
            .map(|p| PluginInstance::new(p.clone()))
            .collect();
        let n = stack.len();
        let mut h = demo_harness(stack, 8000.0);
        // open every plugin's parameters (the first is open already)
        for i in 1..n {
            h.get_all_by_label("parameters").nth(i).unwrap().click();
            h.run();
        }
        // the widgets of later plugins are there: DOS's cone, the 2D TF editor
        assert!(
            h.query_by_role_and_label(egui::Role::Slider, "Cone aperture θ (°)")
                .is_some()
        );
        assert!(h.query_by_label("Add gaussian").is_some());
        assert_eq!(h.query_all_by_label("Add plugin").count(), 1);
    }

    /// Parameter groups: each element under its header, the elements switched off
    /// after the first left out, those past the limit hidden; switching one on lists
    /// the next spare.
    #[test]
    fn group_elements_in_use_are_listed_with_one_spare() {
        let r = vwb_plugins::builtin_registry();
        let stack: Vec<PluginInstance> = ["shade.blinn_phong", "clip.shapes", "shade.isosurface"]
            .iter()
            .map(|id| PluginInstance::new(r.get(id).unwrap()))
            .collect();
        let mut h = demo_harness(stack, 4000.0);
        for i in 1..3 {
            h.get_all_by_label("parameters").nth(i).unwrap().click();
            h.run();
        }
        let has =
            |h: &Harness<'_, Vec<PluginInstance>>, label: &str| h.query_by_label(label).is_some();
        for (shown, hidden) in [
            ("Light 0", "Light 2 · off"),
            ("Light 1 · off", "Light 1"),
            ("Shape 0", "Shape 2 · off"),
            ("Shape 1 · off", "Shape 1"),
            ("Isosurface 0", "Isosurface 1"),
        ] {
            assert!(has(&h, shown), "{shown} is listed");
            assert!(!has(&h, hidden), "{hidden} is not listed");
        }
        // light 0's members are open, its colour among them; an element switched off
        // shows only its switch
        assert!(has(&h, "Light colour"));
        assert_eq!(h.query_all_by_label("Light colour").count(), 1);
        // `gradient: auto` shows what the renderer resolves it to (Blinn–Phong's and
        // the isosurfaces' estimator)
        assert_eq!(
            h.query_all_by_value("auto (precomputed_central)").count(),
            2,
            "the estimator auto resolves to is shown"
        );
        h.get_by_label("Light 1 · off").click();
        h.run();
        assert_eq!(h.query_all_by_label("Light colour").count(), 1);
        h.get_all_by_label("Light on").nth(1).unwrap().click();
        h.run();
        assert!(h.state()[0].params.boolean("light1_on"));
        for label in ["Light 1", "Light 2 · off"] {
            assert!(has(&h, label), "{label} is listed once light 1 is on");
        }
        assert_eq!(h.query_all_by_label("Light colour").count(), 2);
    }

    /// A volume input is a list of the document's named volumes after its own: picking
    /// one names it in the parameter, and the document's own is the empty name.
    #[test]
    fn a_volume_input_picks_among_the_documents_volumes() {
        let r = vwb_plugins::builtin_registry();
        let stack = vec![PluginInstance::new(r.get("flow.lic3d").unwrap())];
        let mut h = harness_with_inputs(
            stack,
            1200.0,
            vec!["storm".into(), "wind".into()],
            Default::default(),
        );
        if h.query_by_label("Vector field").is_none() {
            h.get_by_label("parameters").click();
            h.run();
        }
        h.get_by_label("Vector field").click();
        h.run();
        assert!(h.query_by_label("storm").is_some(), "the names are listed");
        h.get_by_label("wind").click();
        h.run();
        assert_eq!(h.state()[0].params.volume("field"), "wind");
        h.get_by_label("Vector field").click();
        h.run();
        h.get_by_label("(the volume)").click();
        h.run();
        assert_eq!(h.state()[0].params.volume("field"), "");
    }

    /// A label plugin lists the labels its label volume holds above its parameters
    /// (from the volume's histogram), and says so when its input names no volume.
    #[test]
    fn a_label_plugin_lists_its_labels() {
        let r = vwb_plugins::builtin_registry();
        let mut inst = PluginInstance::new(r.get("clip.labels").unwrap());
        inst.params.set(
            "labels",
            vwb_render::params::ParamValue::Volume("labels".into()),
        );
        let named = vwb_plugins::label_input::demo_inputs();
        let mut h = harness_with_inputs(vec![inst], 900.0, vec!["labels".into()], named);
        h.run();
        assert!(
            h.query_by_label("labels in 'demo_labels': 0–3 (4 distinct)")
                .is_some(),
            "the demo's four labels are listed"
        );
        let mut inst = PluginInstance::new(r.get("classify.labels").unwrap());
        inst.params.set(
            "labels",
            vwb_render::params::ParamValue::Volume("seg".into()),
        );
        let mut h = harness_with_inputs(vec![inst], 900.0, Vec::new(), Default::default());
        h.run();
        assert!(
            h.query_by_label_contains("no volume named 'seg'").is_some(),
            "a missing input is named"
        );
    }

    /// "Suggest" beside the 1D TF editor puts the volume's suggestion into the curve,
    /// and says so.
    #[test]
    fn suggest_replaces_the_tf_by_the_volumes_suggestion() {
        let volume = vwb_render::volume::demo();
        let expected = vwb_render::suggest::suggest(&volume, &Default::default())
            .unwrap()
            .curve;
        let r = vwb_plugins::builtin_registry();
        let stack = vec![PluginInstance::new(r.get("classify.tf1d").unwrap())];
        assert_ne!(
            stack[0].params.get("tf"),
            Some(&ParamValue::Tf(expected.clone()))
        );
        let mut h = demo_harness(stack, 900.0);
        h.get_by_label("Suggest").click();
        h.run();
        assert_eq!(
            h.state()[0].params.get("tf"),
            Some(&ParamValue::Tf(expected))
        );
        assert!(h.query_by_label_contains("boundaries found").is_some());
    }
}
