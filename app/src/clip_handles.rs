//! Drag handles for clip shapes over the viewport: a handle at the centre of every
//! active `clip.shapes` primitive and of every `clip.mesh`, dragged in the plane facing
//! the camera through the centre; an axis handle (planes, boxes, cylinders) that turns
//! the normal or axis towards the pointer, a radius handle (spheres, cylinders) and
//! three half-extent handles (boxes, on their local axes);
//! the shape's outline is drawn while a handle is hovered or dragged (a plane's cut through the volume box, a sphere's silhouette circle, a
//! box's and a cylinder's edges, a mesh's bounding box). The numeric fields of the
//! stack stay the exact way in; a handle writes the same `…center` parameter.

use glam::{DVec4, Mat4, Vec3};
use vwb_plugins::clip_shapes::{KINDS, slot_keys};
use vwb_render::camera::View;
use vwb_render::params::ParamValue;
use vwb_render::plugin::PluginInstance;
use vwb_render::slicing::{VolumeBox, plane_box_polygon};

/// Handle radius in points.
pub const RADIUS: f32 = 7.0;

/// One handle: which instance and parameter it moves, where it is, and the outline of
/// its shape (world segments).
#[derive(Debug, Clone, PartialEq)]
pub struct Handle {
    pub instance: usize,
    /// The parameter it writes.
    pub key: &'static str,
    pub kind: HandleKind,
    /// Where it is drawn (world).
    pub at: Vec3,
    /// The shape's centre (world).
    pub center: Vec3,
    pub label: String,
    pub outline: Outline,
}

/// The outline of a handle's shape.
#[derive(Debug, Clone, PartialEq)]
pub enum Outline {
    /// World segments.
    Segments(Vec<[Vec3; 2]>),
    /// The bounding box of the placed mesh, placed only when asked
    /// ([`Handle::outline`]): the mesh is loaded and transformed then.
    MeshBounds,
}

impl Handle {
    /// The outline's world segments (empty for a mesh that cannot be placed).
    pub fn outline(&self, stack: &[PluginInstance], volume: &vwb_render::Volume) -> Vec<[Vec3; 2]> {
        match &self.outline {
            Outline::Segments(s) => s.clone(),
            Outline::MeshBounds => stack
                .get(self.instance)
                .and_then(|inst| vwb_plugins::clip_mesh::placed_mesh(&inst.params, volume).ok())
                .map(|m| {
                    let (lo, hi) = m.bounds();
                    let (lo, hi) = (lo.as_vec3(), hi.as_vec3());
                    let h = (hi - lo) * 0.5;
                    box_edges(
                        (lo + hi) * 0.5,
                        [Vec3::X * h.x, Vec3::Y * h.y, Vec3::Z * h.z],
                    )
                })
                .unwrap_or_default(),
        }
    }
}

/// What dragging a handle changes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HandleKind {
    /// The centre (`…center`) follows the pointer.
    Center,
    /// The axis (`…axis`: a plane's normal, a box's or cylinder's z) points from the
    /// centre to the pointer.
    Axis,
    /// The radius (`…size`, x; y and z kept) is the pointer's distance from the centre.
    Radius { size: Vec3 },
    /// One half extent of a box (`…size`[axis]) is the pointer's distance from the
    /// centre along the box's local axis `dir`.
    Extent { axis: usize, dir: Vec3, size: Vec3 },
}

/// How far from the centre an axis handle is drawn (world).
pub const AXIS_LENGTH: f32 = 0.15;

fn vec3(p: &PluginInstance, key: &str) -> Vec3 {
    Vec3::from(p.params.vec3(key))
}

/// A unit vector orthogonal to the unit vector `a` (clip.shapes' `basis_u`).
fn basis_u(a: Vec3) -> Vec3 {
    let h = if a.x.abs() > 0.9 { Vec3::Y } else { Vec3::X };
    h.cross(a).normalize_or_zero()
}

fn circle(c: Vec3, u: Vec3, v: Vec3, r: f32) -> Vec<[Vec3; 2]> {
    let n = 48;
    let at = |i: usize| {
        let t = std::f32::consts::TAU * i as f32 / n as f32;
        c + (u * t.cos() + v * t.sin()) * r
    };
    (0..n).map(|i| [at(i), at(i + 1)]).collect()
}

fn box_edges(c: Vec3, axes: [Vec3; 3]) -> Vec<[Vec3; 2]> {
    let corner = |i: usize| {
        c + axes[0] * if i & 1 == 0 { -1.0 } else { 1.0 }
            + axes[1] * if i & 2 == 0 { -1.0 } else { 1.0 }
            + axes[2] * if i & 4 == 0 { -1.0 } else { 1.0 }
    };
    let mut out = Vec::new();
    for i in 0..8usize {
        for bit in [1, 2, 4] {
            if i & bit == 0 {
                out.push([corner(i), corner(i | bit)]);
            }
        }
    }
    out
}

/// The handles of the stack's enabled clip instances, seen by `view`.
pub fn handles(stack: &[PluginInstance], vbox: &VolumeBox, view: &View) -> Vec<Handle> {
    let mut out = Vec::new();
    for (index, inst) in stack.iter().enumerate().filter(|(_, i)| i.enabled) {
        match inst.plugin.id() {
            "clip.shapes" => {
                for (slot, k) in slot_keys().iter().enumerate() {
                    let kind = inst.params.enumeration(k.kind);
                    if kind == KINDS[0] {
                        continue;
                    }
                    let c = vec3(inst, k.center);
                    let a = vec3(inst, k.axis).normalize_or(Vec3::Z);
                    let s = vec3(inst, k.size);
                    let (u, v) = (basis_u(a), a.cross(basis_u(a)));
                    let outline = match kind {
                        "plane" => {
                            let poly = plane_box_polygon(vbox, c, a, 0.0);
                            (0..poly.len())
                                .map(|i| [poly[i], poly[(i + 1) % poly.len()]])
                                .collect()
                        }
                        "sphere" => circle(c, view.right, view.up, s.x),
                        "box" => box_edges(c, [u * s.x, v * s.y, a * s.z]),
                        _ => {
                            // cylinder: both rims and four sides
                            let mut e = circle(c + a * s.z, u, v, s.x);
                            e.extend(circle(c - a * s.z, u, v, s.x));
                            for d in [u, -u, v, -v] {
                                e.push([c + a * s.z + d * s.x, c - a * s.z + d * s.x]);
                            }
                            e
                        }
                    };
                    let base = Handle {
                        instance: index,
                        key: k.center,
                        kind: HandleKind::Center,
                        at: c,
                        center: c,
                        label: format!("clip.shapes shape {slot} ({kind}) centre"),
                        outline: Outline::Segments(outline),
                    };
                    if kind != "sphere" {
                        // beyond a box's face, where its z extent handle sits
                        let reach = if kind == "box" {
                            s.z + AXIS_LENGTH
                        } else {
                            AXIS_LENGTH
                        };
                        out.push(Handle {
                            key: k.axis,
                            kind: HandleKind::Axis,
                            at: c + a * reach,
                            label: format!("clip.shapes shape {slot} ({kind}) axis"),
                            ..base.clone()
                        });
                    }
                    if kind == "sphere" || kind == "cylinder" {
                        out.push(Handle {
                            key: k.size,
                            kind: HandleKind::Radius { size: s },
                            at: c + view.right * s.x,
                            label: format!("clip.shapes shape {slot} ({kind}) radius"),
                            ..base.clone()
                        });
                    }
                    if kind == "box" {
                        for (axis, (dir, name)) in
                            [(u, "x"), (v, "y"), (a, "z")].into_iter().enumerate()
                        {
                            out.push(Handle {
                                key: k.size,
                                kind: HandleKind::Extent { axis, dir, size: s },
                                at: c + dir * s[axis],
                                label: format!("clip.shapes shape {slot} (box) {name} extent"),
                                ..base.clone()
                            });
                        }
                    }
                    out.push(base);
                }
            }
            "clip.mesh" => {
                let center = vec3(inst, "center");
                out.push(Handle {
                    instance: index,
                    key: "center",
                    kind: HandleKind::Center,
                    at: center,
                    center,
                    label: "clip.mesh centre".into(),
                    outline: Outline::MeshBounds,
                });
            }
            _ => {}
        }
    }
    out
}

/// Screen position (points in `rect`) of world point `p`, if it is in front of the eye.
pub fn project(view_proj: &Mat4, rect: egui::Rect, p: Vec3) -> Option<egui::Pos2> {
    let c = *view_proj * p.extend(1.0);
    if c.w <= 1.0e-6 {
        return None;
    }
    let n = c / c.w;
    Some(egui::pos2(
        rect.left() + (n.x * 0.5 + 0.5) * rect.width(),
        rect.top() + (0.5 - n.y * 0.5) * rect.height(),
    ))
}

/// The world point that moves with the pointer when `p` is dragged by `delta` points:
/// the same depth, shifted in the image plane.
pub fn dragged(view_proj: &Mat4, rect: egui::Rect, p: Vec3, delta: egui::Vec2) -> Vec3 {
    // in f64: a perspective depth near 1 leaves f32 too few digits to invert
    let vp = view_proj.as_dmat4();
    let c = vp * p.as_dvec3().extend(1.0);
    if c.w.abs() <= 1.0e-12 || rect.width() <= 0.0 || rect.height() <= 0.0 {
        return p;
    }
    let n = c / c.w;
    let moved = DVec4::new(
        n.x + 2.0 * delta.x as f64 / rect.width() as f64,
        n.y - 2.0 * delta.y as f64 / rect.height() as f64,
        n.z,
        1.0,
    );
    let w = vp.inverse() * moved;
    if w.w.abs() <= 1.0e-12 {
        return p;
    }
    (w / w.w).truncate().as_vec3()
}

/// Writes what dragging handle `h` to the world point `p` changes.
pub fn apply(stack: &mut [PluginInstance], h: &Handle, p: Vec3) {
    let Some(inst) = stack.get_mut(h.instance) else {
        return;
    };
    let value = match h.kind {
        HandleKind::Center => p.clamp(Vec3::splat(-2.0), Vec3::splat(2.0)),
        HandleKind::Axis => match (p - h.center).try_normalize() {
            Some(a) => a,
            None => return,
        },
        HandleKind::Radius { size } => {
            Vec3::new((p - h.center).length().clamp(0.0, 2.0), size.y, size.z)
        }
        HandleKind::Extent { axis, dir, size } => {
            let mut s = size;
            s[axis] = (p - h.center).dot(dir).abs().clamp(0.0, 2.0);
            s
        }
    };
    inst.params.set(h.key, ParamValue::Vec3(value.to_array()));
}

#[cfg(test)]
mod tests {
    use super::*;
    use vwb_render::Camera;

    #[test]
    fn a_dragged_point_follows_the_pointer_at_its_depth() {
        let view = Camera::default().view(1.5);
        let vp = view.view_proj();
        let rect = egui::Rect::from_min_size(egui::pos2(10.0, 20.0), egui::vec2(300.0, 200.0));
        let p = Vec3::new(0.1, -0.05, 0.2);
        let at = project(&vp, rect, p).unwrap();
        let q = dragged(&vp, rect, p, egui::vec2(30.0, -12.0));
        let moved = project(&vp, rect, q).unwrap();
        assert!(
            (moved - at - egui::vec2(30.0, -12.0)).length() < 1e-3,
            "{at:?} → {moved:?}"
        );
        // in the plane facing the camera
        assert!(((q - p).dot(view.forward)).abs() < 1e-4 * (q - p).length().max(1e-6) + 1e-5);
    }

    #[test]
    fn every_active_shape_and_mesh_has_a_handle_with_an_outline() {
        let registry = vwb_plugins::builtin_registry();
        let mut shapes = PluginInstance::new(registry.get("clip.shapes").unwrap());
        for (i, kind) in ["plane", "sphere", "box", "cylinder"].iter().enumerate() {
            shapes
                .params
                .set(slot_keys()[i].kind, ParamValue::Enum(kind.to_string()));
        }
        let mesh = PluginInstance::new(registry.get("clip.mesh").unwrap());
        let volume = vwb_render::volume::demo();
        let vbox = VolumeBox::new(volume.dims, volume.spacing);
        let view = Camera::default().view(1.0);
        let stack = [shapes, mesh];
        let hs = handles(&stack, &vbox, &view);
        // plane: centre, axis; sphere: centre, radius; box: centre, axis, 3 extents;
        // cylinder: centre, axis, radius; mesh: centre
        assert_eq!(hs.len(), 13);
        for h in &hs {
            let n = h.outline(&stack, &volume).len();
            assert!(n >= 3, "{}: {n} segments", h.label);
        }
        assert_eq!(hs[12].key, "center");
        let sphere: Vec<_> = hs.iter().filter(|h| h.label.contains("(sphere)")).collect();
        assert_eq!(sphere.len(), 2);
        assert!(sphere.iter().any(|h| h.key == slot_keys()[1].center));
        assert!(sphere.iter().any(|h| h.key == slot_keys()[1].size));
    }

    #[test]
    fn axis_and_radius_handles_turn_and_size_the_shape() {
        let registry = vwb_plugins::builtin_registry();
        let mut shapes = PluginInstance::new(registry.get("clip.shapes").unwrap());
        shapes
            .params
            .set(slot_keys()[1].kind, ParamValue::Enum("sphere".into()));
        let volume = vwb_render::volume::demo();
        let vbox = VolumeBox::new(volume.dims, volume.spacing);
        let view = Camera::default().view(1.0);
        let mut stack = vec![shapes];
        let hs = handles(&stack, &vbox, &view);
        let axis = hs.iter().find(|h| h.kind == HandleKind::Axis).unwrap();
        apply(&mut stack, axis, axis.center + Vec3::new(0.0, 0.3, 0.0));
        assert_eq!(stack[0].params.vec3(slot_keys()[0].axis), [0.0, 1.0, 0.0]);
        let radius = hs
            .iter()
            .find(|h| matches!(h.kind, HandleKind::Radius { .. }))
            .unwrap();
        apply(&mut stack, radius, radius.center + Vec3::new(0.0, 0.0, 0.4));
        assert!((stack[0].params.vec3(slot_keys()[1].size)[0] - 0.4).abs() < 1e-6);
        // a box's y extent follows the pointer along the box's local y only
        stack[0]
            .params
            .set(slot_keys()[2].kind, ParamValue::Enum("box".into()));
        let hs = handles(&stack, &vbox, &view);
        let y = hs
            .iter()
            .find(|h| matches!(h.kind, HandleKind::Extent { axis: 1, .. }))
            .unwrap();
        let HandleKind::Extent { dir, size, .. } = y.kind else {
            unreachable!()
        };
        apply(
            &mut stack,
            y,
            y.center + dir * 0.4 + Vec3::new(0.0, 0.0, 0.0),
        );
        let got = stack[0].params.vec3(slot_keys()[2].size);
        assert!((got[1] - 0.4).abs() < 1e-6, "{got:?}");
        assert_eq!([got[0], got[2]], [size.x, size.z]);
    }
}
