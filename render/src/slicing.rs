//! View-aligned slicing: the volume box in world space, the slice planes and the
//! proxy polygons (box ∩ plane).
//!
//! Slice planes are perpendicular to the view direction `forward` (for perspective
//! cameras too: planes of constant eye depth, as in Rezk-Salama 2001, ch. 3, and
//! Schott et al. 2009). Plane k lies at eye depth d_k = d_0 + k·Δs. The set is
//! anchored at the box centre (one plane always passes through it), so slices
//! do not swim when the camera orbits, and runs front (k = 0) to back. Planes behind
//! the near plane are dropped, which lets the camera sit inside the volume.
//! Both backends use these planes: the raster backend draws the polygons, the
//! compute backend intersects each pixel's ray with the same planes.

use glam::Vec3;

use crate::camera::View;

/// The volume box in world space: centred on the origin, longest side 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VolumeBox {
    pub min: Vec3,
    pub max: Vec3,
    /// World length of one voxel along the axis with the smallest voxel size: the
    /// reference step Δs0 at which transfer-function opacities are defined.
    pub voxel: f32,
}

impl VolumeBox {
    /// Box for a grid of `dims` voxels of size `spacing`.
    pub fn new(dims: [u32; 3], spacing: [f64; 3]) -> Self {
        let ext = [
            dims[0].max(1) as f64 * spacing[0],
            dims[1].max(1) as f64 * spacing[1],
            dims[2].max(1) as f64 * spacing[2],
        ];
        let longest = ext[0].max(ext[1]).max(ext[2]);
        let scale = if longest > 0.0 && longest.is_finite() {
            1.0 / longest
        } else {
            1.0
        };
        let half = Vec3::new(
            (ext[0] * scale * 0.5) as f32,
            (ext[1] * scale * 0.5) as f32,
            (ext[2] * scale * 0.5) as f32,
        );
        let voxel = (spacing[0].min(spacing[1]).min(spacing[2]) * scale) as f32;
        Self {
            min: -half,
            max: half,
            voxel,
        }
    }

    pub fn centre(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    pub fn corners(&self) -> [Vec3; 8] {
        let (a, b) = (self.min, self.max);
        [
            Vec3::new(a.x, a.y, a.z),
            Vec3::new(b.x, a.y, a.z),
            Vec3::new(a.x, b.y, a.z),
            Vec3::new(b.x, b.y, a.z),
            Vec3::new(a.x, a.y, b.z),
            Vec3::new(b.x, a.y, b.z),
            Vec3::new(a.x, b.y, b.z),
            Vec3::new(b.x, b.y, b.z),
        ]
    }

    /// The 12 edges as pairs of corner indices.
    pub const EDGES: [(usize, usize); 12] = [
        (0, 1),
        (2, 3),
        (4, 5),
        (6, 7),
        (0, 2),
        (1, 3),
        (4, 6),
        (5, 7),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
    ];

    /// Texture coordinate of a world point.
    pub fn tex(&self, p: Vec3) -> Vec3 {
        (p - self.min) / (self.max - self.min)
    }

    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
}

/// Most slices one frame may have; beyond it the request is refused with an error.
pub const MAX_SLICES: u32 = 1 << 20;

#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum SliceError {
    #[error("slice spacing must be finite and > 0 voxels, got {0}")]
    BadSpacing(f32),
    #[error(
        "slice spacing {spacing} voxels needs {} slices, more than the limit of {MAX_SLICES}",
        slice_count_text(*.count)
    )]
    TooMany { spacing: f32, count: u64 },
}

/// A slice count for messages: exact, or "more than 10^15" where it saturated.
fn slice_count_text(count: u64) -> String {
    if count >= 1_000_000_000_000_000 {
        "more than 10^15".to_string()
    } else {
        count.to_string()
    }
}

/// The slice planes of one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlicePlan {
    pub eye: Vec3,
    pub forward: Vec3,
    /// World distance Δs between planes.
    pub spacing: f32,
    /// Eye depth of plane 0 (the front-most).
    pub d0: f32,
    pub count: u32,
}

impl SlicePlan {
    /// Plans slices `spacing_voxels` voxels apart (1 = one slice per voxel) for a view.
    pub fn new(view: &View, vbox: &VolumeBox, spacing_voxels: f32) -> Result<Self, SliceError> {
        if !(spacing_voxels.is_finite() && spacing_voxels > 0.0) {
            return Err(SliceError::BadSpacing(spacing_voxels));
        }
        let f = view.forward;
        let spacing = spacing_voxels * vbox.voxel;
        let depths = vbox.corners().map(|c| (c - view.eye).dot(f));
        let dmin = depths.iter().copied().fold(f32::INFINITY, f32::min);
        let dmax = depths.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let start = dmin.max(view.near);
        let dc = (vbox.centre() - view.eye).dot(f);
        let m0 = ((start - dc) / spacing).ceil() as f64;
        let m1 = ((dmax - dc) / spacing).floor() as f64;
        let n = m1 - m0 + 1.0;
        if n > MAX_SLICES as f64 {
            return Err(SliceError::TooMany {
                spacing: spacing_voxels,
                count: n as u64,
            });
        }
        let count = if n >= 1.0 { n as u32 } else { 0 };
        Ok(Self {
            eye: view.eye,
            forward: f,
            spacing,
            d0: dc + m0 as f32 * spacing,
            count,
        })
    }

    pub fn depth(&self, k: u32) -> f32 {
        self.d0 + k as f32 * self.spacing
    }

    /// Proxy polygon of slice k: box ∩ plane, 3 to 6 vertices ordered around the
    /// polygon (counter-clockwise seen from the eye). Empty if the plane misses the box.
    pub fn polygon(&self, vbox: &VolumeBox, k: u32) -> Vec<Vec3> {
        plane_box_polygon(vbox, self.eye, self.forward, self.depth(k))
    }

    /// All polygons as a triangle list (fan per slice), front to back, with the slice
    /// index of each vertex.
    pub fn triangles(&self, vbox: &VolumeBox) -> Vec<(Vec3, u32)> {
        self.triangles_in(std::slice::from_ref(vbox))
    }

    /// [`SlicePlan::triangles`] over several disjoint boxes: each slice's polygons in
    /// every box (in the order given) before the next slice's.
    pub fn triangles_in(&self, boxes: &[VolumeBox]) -> Vec<(Vec3, u32)> {
        let mut out = Vec::with_capacity(self.count as usize * 12 * boxes.len());
        for k in 0..self.count {
            for vbox in boxes {
                let poly = self.polygon(vbox, k);
                for i in 1..poly.len().saturating_sub(1) {
                    out.push((poly[0], k));
                    out.push((poly[i], k));
                    out.push((poly[i + 1], k));
                }
            }
        }
        out
    }
}

/// Intersection of the box with the plane {p : (p − eye)·n = d}, ordered.
pub fn plane_box_polygon(vbox: &VolumeBox, eye: Vec3, n: Vec3, d: f32) -> Vec<Vec3> {
    let corners = vbox.corners();
    let dist = corners.map(|c| (c - eye).dot(n) - d);
    let mut pts: Vec<Vec3> = Vec::with_capacity(6);
    for (a, b) in VolumeBox::EDGES {
        let (da, db) = (dist[a], dist[b]);
        if (da < 0.0) != (db < 0.0) || da == 0.0 || db == 0.0 {
            let p = if da == db {
                corners[a]
            } else {
                let t = (da / (da - db)).clamp(0.0, 1.0);
                corners[a].lerp(corners[b], t)
            };
            if !pts.iter().any(|q| q.distance_squared(p) < 1e-12) {
                pts.push(p);
            }
        }
    }
    if pts.len() < 3 {
        return Vec::new();
    }
    let c = pts.iter().copied().sum::<Vec3>() / pts.len() as f32;
    let u = n.any_orthonormal_vector();
    let v = n.cross(u);
    // Seen from the eye (looking along n), angles increasing with atan2(v, u) run
    // clockwise; sort descending to get counter-clockwise on screen.
    pts.sort_by(|p, q| {
        let ap = (*p - c).dot(v).atan2((*p - c).dot(u));
        let aq = (*q - c).dot(v).atan2((*q - c).dot(u));
        aq.total_cmp(&ap)
    });
    pts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Projection};

    fn unit_box() -> VolumeBox {
        VolumeBox::new([64, 64, 64], [1.0; 3])
    }

    fn polygon_area(poly: &[Vec3]) -> f32 {
        let mut a = Vec3::ZERO;
        for i in 1..poly.len().saturating_sub(1) {
            a += (poly[i] - poly[0]).cross(poly[i + 1] - poly[0]);
        }
        a.length() * 0.5
    }

    #[test]
    fn box_is_normalised_and_anisotropic() {
        let b = VolumeBox::new([256, 256, 108], [0.957, 0.957, 1.5]);
        let ext = b.max - b.min;
        assert!((ext.x - 1.0).abs() < 1e-6 && (ext.y - 1.0).abs() < 1e-6);
        assert!((ext.z - 108.0 * 1.5 / (256.0 * 0.957)).abs() < 1e-5);
        assert!((b.voxel - 1.0 / 256.0).abs() < 1e-7);
    }

    #[test]
    fn axis_aligned_view_gives_squares() {
        let vbox = unit_box();
        let mut cam = Camera::default();
        cam.axis_view(2, false);
        let view = cam.view(1.0);
        let plan = SlicePlan::new(&view, &vbox, 1.0).unwrap();
        // 64 voxels deep, planes anchored at the centre: 64 or 65 planes
        assert!((64..=65).contains(&plan.count), "{}", plan.count);
        for k in [0, plan.count / 2, plan.count - 1] {
            let poly = plan.polygon(&vbox, k);
            assert_eq!(poly.len(), 4, "slice {k}");
            assert!((polygon_area(&poly) - 1.0).abs() < 1e-4);
        }
        // front to back
        assert!(plan.depth(1) > plan.depth(0));
    }

    #[test]
    fn corner_on_view_gives_hexagon_in_middle_and_triangles_at_ends() {
        let vbox = unit_box();
        let cam = Camera {
            yaw_deg: 45.0,
            pitch_deg: 35.264_39,
            projection: Projection::Orthographic { height: 2.0 },
            ..Default::default()
        };
        let view = cam.view(1.0);
        let plan = SlicePlan::new(&view, &vbox, 1.0).unwrap();
        // diagonal length sqrt(3) in units of 1/64
        let expect = (3f32.sqrt() * 64.0) as u32;
        assert!(
            plan.count.abs_diff(expect) <= 1,
            "{} vs {expect}",
            plan.count
        );
        let mid = plan.polygon(&vbox, plan.count / 2);
        assert_eq!(mid.len(), 6);
        assert_eq!(plan.polygon(&vbox, 0).len(), 3);
        assert_eq!(plan.polygon(&vbox, plan.count - 1).len(), 3);
    }

    #[test]
    fn polygons_are_convex_planar_and_ordered() {
        let vbox = VolumeBox::new([40, 30, 20], [1.0, 1.0, 2.0]);
        for (yaw, pitch) in [(10.0, 5.0), (70.0, -40.0), (200.0, 80.0), (0.0, 90.0)] {
            let cam = Camera {
                yaw_deg: yaw,
                pitch_deg: pitch,
                ..Default::default()
            };
            let view = cam.view(1.0);
            let plan = SlicePlan::new(&view, &vbox, 1.0).unwrap();
            for k in 0..plan.count {
                let poly = plan.polygon(&vbox, k);
                assert!(poly.len() >= 3 && poly.len() <= 6);
                for p in &poly {
                    assert!(((*p - plan.eye).dot(plan.forward) - plan.depth(k)).abs() < 1e-4);
                }
                // all turns have the same sign (convex, consistently ordered):
                // counter-clockwise seen from the eye means normals point at the eye.
                for i in 0..poly.len() {
                    let a = poly[i];
                    let b = poly[(i + 1) % poly.len()];
                    let c = poly[(i + 2) % poly.len()];
                    let turn = (b - a).cross(c - b).dot(plan.forward);
                    assert!(turn < 1e-7, "slice {k} turn {turn}");
                }
            }
        }
    }

    #[test]
    fn camera_inside_volume_drops_slices_behind_near() {
        let vbox = unit_box();
        let cam = Camera {
            distance: 0.1,
            ..Default::default()
        };
        let view = cam.view(1.0);
        let plan = SlicePlan::new(&view, &vbox, 1.0).unwrap();
        assert!(plan.count > 0);
        assert!(plan.depth(0) >= view.near);
        assert!(plan.depth(0) - view.near <= plan.spacing);
        // the eye is inside: the first polygon surrounds the view axis
        let poly = plan.polygon(&vbox, 0);
        assert!(poly.len() >= 3);
        let centre = plan.eye + plan.forward * plan.depth(0);
        let mut inside = true;
        for i in 0..poly.len() {
            let a = poly[i];
            let b = poly[(i + 1) % poly.len()];
            if (b - a).cross(centre - a).dot(plan.forward) > 1e-6 {
                inside = false;
            }
        }
        assert!(inside);
    }

    #[test]
    fn spacing_is_validated() {
        let vbox = unit_box();
        let view = Camera::default().view(1.0);
        assert!(SlicePlan::new(&view, &vbox, 0.0).is_err());
        assert!(SlicePlan::new(&view, &vbox, f32::NAN).is_err());
        assert!(matches!(
            SlicePlan::new(&view, &vbox, 1e-5),
            Err(SliceError::TooMany { .. })
        ));
        let half = SlicePlan::new(&view, &vbox, 0.5).unwrap();
        let one = SlicePlan::new(&view, &vbox, 1.0).unwrap();
        assert!(half.count.abs_diff(one.count * 2) <= 2);
        // a spacing so fine that the count saturates says so, not 18446744073709551615
        let e = SlicePlan::new(&view, &vbox, 1e-30).unwrap_err().to_string();
        assert!(e.contains("more than 10^15 slices"), "{e}");
    }
}
