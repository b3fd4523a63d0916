//! Orbit camera with perspective or orthographic projection.
//!
//! The camera orbits `target` at `distance`; `yaw` turns about the world +y axis and
//! `pitch` lifts the eye above the xz plane. The basis is built from the angles
//! directly, so it stays well defined straight above or below the target (axis views).
//! The camera may sit inside the volume: the near plane is small and slices behind
//! it are dropped.

use glam::camera::rh::proj::directx as proj;
use glam::{Mat4, Vec3};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Projection {
    /// Vertical field of view in degrees.
    Perspective { fov_y_deg: f32 },
    /// Height of the visible region in world units (the volume's longest side is 1).
    Orthographic { height: f32 },
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Camera {
    pub target: [f32; 3],
    pub distance: f32,
    pub yaw_deg: f32,
    pub pitch_deg: f32,
    /// Rotation of the image about the view direction (degrees, counter-clockwise on
    /// screen). Image stacks often store rows top-down: roll 180 shows them upright.
    pub roll_deg: f32,
    pub projection: Projection,
    /// Near plane distance in world units.
    pub near: f32,
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            target: [0.0; 3],
            distance: 2.2,
            yaw_deg: 30.0,
            pitch_deg: 20.0,
            roll_deg: 0.0,
            projection: Projection::Perspective { fov_y_deg: 35.0 },
            near: 1.0e-3,
        }
    }
}

/// The camera's frame for one image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    pub eye: Vec3,
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    pub near: f32,
    pub far: f32,
    pub perspective: bool,
    pub view: Mat4,
    pub proj: Mat4,
}

impl View {
    pub fn view_proj(&self) -> Mat4 {
        self.proj * self.view
    }
}

impl Camera {
    pub fn target(&self) -> Vec3 {
        Vec3::from(self.target)
    }

    /// Unit vector from the target towards the eye.
    pub fn offset_dir(&self) -> Vec3 {
        let (sy, cy) = self.yaw_deg.to_radians().sin_cos();
        let (sp, cp) = self.pitch_deg.to_radians().sin_cos();
        Vec3::new(cp * sy, sp, cp * cy)
    }

    pub fn eye(&self) -> Vec3 {
        self.target() + self.offset_dir() * self.distance
    }

    /// Camera basis (forward, right, up), right-handed, valid for every yaw/pitch.
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = -self.offset_dir();
        let (sy, cy) = self.yaw_deg.to_radians().sin_cos();
        let right0 = Vec3::new(cy, 0.0, -sy);
        let up0 = right0.cross(forward).normalize();
        let (sr, cr) = self.roll_deg.to_radians().sin_cos();
        let right = right0 * cr + up0 * sr;
        let up = up0 * cr - right0 * sr;
        (forward, right, up)
    }

    /// The view for an image of the given aspect ratio (width / height).
    pub fn view(&self, aspect: f32) -> View {
        let (forward, right, up) = self.basis();
        let eye = self.eye();
        let near = self.near.max(1.0e-6);
        // The volume fits in a unit-radius sphere around the target.
        let far = (self.distance + 2.0).max(near * 2.0);
        let view = glam::camera::rh::view::look_to_mat4(eye, forward, up);
        let (proj, perspective) = match self.projection {
            Projection::Perspective { fov_y_deg } => (
                proj::perspective(fov_y_deg.clamp(1.0, 170.0).to_radians(), aspect, near, far),
                true,
            ),
            Projection::Orthographic { height } => {
                let h = height.max(1.0e-6) * 0.5;
                let w = h * aspect;
                (proj::orthographic(-w, w, -h, h, near, far), false)
            }
        };
        View {
            eye,
            forward,
            right,
            up,
            near,
            far,
            perspective,
            view,
            proj,
        }
    }

    /// Orbit by angles in degrees; pitch is kept within ±90°.
    pub fn orbit(&mut self, d_yaw_deg: f32, d_pitch_deg: f32) {
        self.yaw_deg = (self.yaw_deg + d_yaw_deg).rem_euclid(360.0);
        self.pitch_deg = (self.pitch_deg + d_pitch_deg).clamp(-90.0, 90.0);
    }

    /// Zoom by a factor (> 1 moves closer); orthographic cameras shrink their height.
    pub fn zoom(&mut self, factor: f32) {
        let f = factor.max(1.0e-3);
        self.distance = (self.distance / f).clamp(1.0e-3, 100.0);
        if let Projection::Orthographic { height } = &mut self.projection {
            *height = (*height / f).clamp(1.0e-3, 100.0);
        }
    }

    /// Pan in the image plane by fractions of the view height.
    pub fn pan(&mut self, dx: f32, dy: f32) {
        let (_, right, up) = self.basis();
        let scale = match self.projection {
            Projection::Perspective { fov_y_deg } => {
                2.0 * self.distance * (fov_y_deg.to_radians() * 0.5).tan()
            }
            Projection::Orthographic { height } => height,
        };
        let t = self.target() - right * dx * scale + up * dy * scale;
        self.target = t.into();
    }

    /// Frames the box `[min, max]` from the current direction: the target moves to its
    /// centre and the distance (orthographic: the height) becomes the smallest at which
    /// all eight corners lie in a square image, plus a 5 % margin.
    pub fn fit(&mut self, min: Vec3, max: Vec3) {
        let centre = (min + max) * 0.5;
        self.target = centre.into();
        let (_, right, up) = self.basis();
        let o = self.offset_dir();
        let corners = (0..8).map(|i| {
            let p = Vec3::new(
                if i & 1 == 0 { min.x } else { max.x },
                if i & 2 == 0 { min.y } else { max.y },
                if i & 4 == 0 { min.z } else { max.z },
            ) - centre;
            (p.dot(o), p.dot(right).abs().max(p.dot(up).abs()))
        });
        const MARGIN: f32 = 1.05;
        match &mut self.projection {
            Projection::Perspective { fov_y_deg } => {
                let t = (fov_y_deg.clamp(1.0, 170.0).to_radians() * 0.5).tan();
                let d = corners
                    .map(|(along, lateral)| along + lateral * MARGIN / t)
                    .fold(0.0f32, f32::max);
                self.distance = d.clamp(1.0e-3, 100.0);
            }
            Projection::Orthographic { height } => {
                let (along, lateral) =
                    corners.fold((0.0f32, 0.0f32), |(a, l), (pa, pl)| (a.max(pa), l.max(pl)));
                *height = (2.0 * lateral * MARGIN).clamp(1.0e-3, 100.0);
                self.distance = (along + 1.0).clamp(1.0e-3, 100.0);
            }
        }
    }

    /// Looking along an axis: 0 = +x, 1 = +y, 2 = +z; `negative` flips the direction.
    pub fn axis_view(&mut self, axis: usize, negative: bool) {
        // The eye sits opposite the viewing direction.
        let (yaw, pitch) = match (axis, negative) {
            (0, false) => (-90.0, 0.0),
            (0, true) => (90.0, 0.0),
            (1, false) => (0.0, -90.0),
            (1, true) => (0.0, 90.0),
            (_, false) => (180.0, 0.0),
            (_, true) => (0.0, 0.0),
        };
        self.yaw_deg = yaw;
        self.pitch_deg = pitch;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_is_orthonormal_at_poles() {
        for pitch in [-90.0, -45.0, 0.0, 45.0, 90.0] {
            for (yaw, roll) in [(0.0, 0.0), (33.0, 10.0), (180.0, 180.0), (270.0, -75.0)] {
                let c = Camera {
                    yaw_deg: yaw,
                    pitch_deg: pitch,
                    roll_deg: roll,
                    ..Default::default()
                };
                let (f, r, u) = c.basis();
                assert!((f.length() - 1.0).abs() < 1e-5);
                assert!((r.length() - 1.0).abs() < 1e-5);
                assert!((u.length() - 1.0).abs() < 1e-5);
                assert!(f.dot(r).abs() < 1e-5 && f.dot(u).abs() < 1e-5 && r.dot(u).abs() < 1e-5);
                // right-handed: right × up = −forward
                assert!((r.cross(u) + f).length() < 1e-5);
            }
        }
    }

    #[test]
    fn fit_frames_every_corner_tightly() {
        let (min, max) = (Vec3::new(-0.5, -0.25, -0.05), Vec3::new(0.5, 0.25, 0.05));
        for projection in [
            Projection::Perspective { fov_y_deg: 35.0 },
            Projection::Orthographic { height: 0.2 },
        ] {
            for (yaw, pitch, roll) in [(235.0, -10.0, 180.0), (0.0, 90.0, 0.0), (30.0, 20.0, 45.0)]
            {
                let mut c = Camera {
                    distance: 0.3,
                    yaw_deg: yaw,
                    pitch_deg: pitch,
                    roll_deg: roll,
                    projection,
                    ..Default::default()
                };
                c.fit(min, max);
                let v = c.view(1.0);
                let mut widest = 0.0f32;
                for i in 0..8 {
                    let p = Vec3::new(
                        if i & 1 == 0 { min.x } else { max.x },
                        if i & 2 == 0 { min.y } else { max.y },
                        if i & 4 == 0 { min.z } else { max.z },
                    );
                    let ndc = (v.proj * v.view).project_point3(p);
                    assert!(ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0, "{c:?}: {ndc}");
                    assert!((0.0..=1.0).contains(&ndc.z), "{c:?}: behind: {ndc}");
                    widest = widest.max(ndc.x.abs()).max(ndc.y.abs());
                }
                // tight: the widest corner is near the edge, not lost in a small image
                assert!(widest > 0.8, "{c:?}: {widest}");
            }
        }
    }

    #[test]
    fn axis_views_look_along_axes() {
        let mut c = Camera::default();
        for axis in 0..3 {
            for neg in [false, true] {
                c.axis_view(axis, neg);
                let mut want = Vec3::ZERO;
                want[axis] = if neg { -1.0 } else { 1.0 };
                let (f, _, _) = c.basis();
                assert!((f - want).length() < 1e-5, "axis {axis} neg {neg}: {f}");
            }
        }
    }

    #[test]
    fn projection_maps_target_to_centre() {
        let c = Camera::default();
        let v = c.view(1.5);
        let p = v.view_proj().project_point3(c.target());
        assert!(p.x.abs() < 1e-5 && p.y.abs() < 1e-5 && (0.0..1.0).contains(&p.z));
    }
}
