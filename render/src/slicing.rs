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
//!
//! Half-angle slicing (Kniss, Premože, Hansen, Shirley and McPherson 2003;
//! [`HalfAngle`]) tilts the planes halfway between the view and a light, for per-slice
//! state that travels with the light rather than with the eye (shadows from a light
//! other than the viewer: the extension of directional occlusion shading that Schott
//! et al. 2009 name as future work).

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
        let spacing = spacing_voxels * vbox.voxel;
        Self::across(
            view,
            vbox,
            spacing_voxels,
            view.forward,
            spacing,
            Some(view.near),
        )
    }

    /// Planes normal to `n`, `spacing` world units apart, anchored at the box centre
    /// and covering the box (from eye depth `near` on, where given); `spacing_voxels`
    /// is the spacing the caller was asked for, checked here.
    fn across(
        view: &View,
        vbox: &VolumeBox,
        spacing_voxels: f32,
        n: Vec3,
        spacing: f32,
        near: Option<f32>,
    ) -> Result<Self, SliceError> {
        if !(spacing_voxels.is_finite() && spacing_voxels > 0.0) {
            return Err(SliceError::BadSpacing(spacing_voxels));
        }
        let depths = vbox.corners().map(|c| (c - view.eye).dot(n));
        let dmin = depths.iter().copied().fold(f32::INFINITY, f32::min);
        let dmax = depths.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let start = near.map_or(dmin, |near| dmin.max(near));
        let dc = (vbox.centre() - view.eye).dot(n);
        let m0 = ((start - dc) / spacing).ceil() as f64;
        let m1 = ((dmax - dc) / spacing).floor() as f64;
        let count = m1 - m0 + 1.0;
        if count > MAX_SLICES as f64 {
            return Err(SliceError::TooMany {
                spacing: spacing_voxels,
                count: count as u64,
            });
        }
        Ok(Self {
            eye: view.eye,
            forward: n,
            spacing,
            d0: dc + m0 as f32 * spacing,
            count: if count >= 1.0 { count as u32 } else { 0 },
        })
    }

    pub fn depth(&self, k: u32) -> f32 {
        self.d0 + k as f32 * self.spacing
    }

    /// Half-angle slicing for a light travelling along `light` (world space, any
    /// length): planes normal to the half-angle axis ([`HalfAngle::new`]), anchored at
    /// the box centre and ordered along the light, so that the light crosses plane k
    /// before plane k + 1. `spacing_voxels` is the spacing along the view's centre ray
    /// and along the light, as for view-aligned slices: the planes lie
    /// `spacing · |view · normal|` apart. The near plane drops no slice (a ray's
    /// samples behind the eye are skipped one by one).
    pub fn half_angle(
        view: &View,
        vbox: &VolumeBox,
        spacing_voxels: f32,
        light: Vec3,
    ) -> Result<(Self, HalfAngle), SliceError> {
        let h = HalfAngle::new(view, vbox, light, spacing_voxels * vbox.voxel);
        let plan = Self::across(view, vbox, spacing_voxels, h.normal, h.plane_spacing, None)?;
        Ok((plan, h))
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

    /// [`SlicePlan::triangles`] of the box cut to a polytope (the occupied bricks'
    /// [`Dop`]): per slice, box ∩ plane ∩ polytope as a fan, its slivers no wider than
    /// `tol` dropped ([`drop_slivers`]; the polytope's margin must cover them).
    pub fn triangles_in_dop(&self, vbox: &VolumeBox, dop: &Dop, tol: f32) -> Vec<(Vec3, u32)> {
        let mut out = Vec::with_capacity(self.count as usize * 24);
        for k in 0..self.count {
            push_fan(
                &mut out,
                &drop_slivers(dop.clip(self.polygon(vbox, k)), tol),
                k,
            );
        }
        out
    }

    /// The proxy polygon of the group of `n` slices from slice `k0` (Rezk-Salama 2001,
    /// §9.1: several slices per proxy polygon): a polygon on plane `k0` that covers,
    /// seen from the eye, every point of slices `k0 … k0 + n − 1` inside the box. Each
    /// slice's polygon is projected onto plane `k0` along the rays (through the eye
    /// when `perspective`, along `forward` otherwise) and the group's is the convex hull
    /// of them, ordered around it. Empty if no slice of the group meets the box.
    pub fn group_polygon(&self, vbox: &VolumeBox, k0: u32, n: u32, perspective: bool) -> Vec<Vec3> {
        let d0 = self.depth(k0);
        let u = self.forward.any_orthonormal_vector();
        let v = self.forward.cross(u);
        let mut pts: Vec<glam::DVec2> = Vec::with_capacity(6 * n as usize);
        for k in k0..k0.saturating_add(n).min(self.count) {
            let dk = self.depth(k);
            for p in self.polygon(vbox, k) {
                let q = if perspective {
                    self.eye + (p - self.eye) * (d0 / dk)
                } else {
                    p - self.forward * (dk - d0)
                };
                let r = q - self.eye;
                pts.push(glam::dvec2(r.dot(u) as f64, r.dot(v) as f64));
            }
        }
        let hull = convex_hull(pts);
        if hull.len() < 3 {
            return Vec::new();
        }
        // the hull runs counter-clockwise in (u, v), which is clockwise seen from the
        // eye (the order `plane_box_polygon` reverses); the fan does not mind
        let origin = self.eye + self.forward * d0;
        hull.iter()
            .rev()
            .map(|h| origin + u * h.x as f32 + v * h.y as f32)
            .collect()
    }

    /// [`SlicePlan::triangles`] with a polygon per group of `n` slices
    /// ([`SlicePlan::group_polygon`]), each tagged with its group's first slice.
    pub fn group_triangles(&self, vbox: &VolumeBox, n: u32, perspective: bool) -> Vec<(Vec3, u32)> {
        let n = n.max(1);
        let mut out = Vec::with_capacity(self.count.div_ceil(n) as usize * 12);
        for k0 in (0..self.count).step_by(n as usize) {
            push_fan(&mut out, &self.group_polygon(vbox, k0, n, perspective), k0);
        }
        out
    }

    /// [`SlicePlan::triangles`] over several disjoint boxes: each slice's polygons in
    /// every box (in the order given) before the next slice's.
    pub fn triangles_in(&self, boxes: &[VolumeBox]) -> Vec<(Vec3, u32)> {
        let mut out = Vec::with_capacity(self.count as usize * 12 * boxes.len());
        for k in 0..self.count {
            for vbox in boxes {
                push_fan(&mut out, &self.polygon(vbox, k), k);
            }
        }
        out
    }
}

/// The convex hull of points in the plane, counter-clockwise, without collinear points
/// (Andrew's monotone chain).
fn convex_hull(mut pts: Vec<glam::DVec2>) -> Vec<glam::DVec2> {
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: glam::DVec2, a: glam::DVec2, b: glam::DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<glam::DVec2> = Vec::with_capacity(2 * pts.len());
    // the lower chain left to right, then the upper one right to left; each pops the
    // points that do not turn left, down to the chain's own first point
    for &p in &pts {
        while hull.len() >= 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(p);
    }
    let lower = hull.len();
    for &p in pts.iter().rev().skip(1) {
        while hull.len() > lower && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(p);
    }
    // the last point is the first again
    hull.pop();
    hull
}

/// A convex polygon of slice k as a fan of triangles from its first vertex.
fn push_fan(out: &mut Vec<(Vec3, u32)>, poly: &[Vec3], k: u32) {
    for i in 1..poly.len().saturating_sub(1) {
        out.push((poly[0], k));
        out.push((poly[i], k));
        out.push((poly[i + 1], k));
    }
}

/// A frame's slices: view-aligned (`half` is `None`) or half-angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FramePlan {
    pub slices: SlicePlan,
    pub half: Option<HalfAngle>,
}

impl FramePlan {
    /// The slices of a frame of `view`: view-aligned, or half-angle for a light that
    /// travels along `light` ([`SlicePlan::half_angle`]).
    pub fn new(
        view: &View,
        vbox: &VolumeBox,
        spacing_voxels: f32,
        light: Option<Vec3>,
    ) -> Result<Self, SliceError> {
        Ok(match light {
            None => Self {
                slices: SlicePlan::new(view, vbox, spacing_voxels)?,
                half: None,
            },
            Some(l) => {
                let (slices, half) = SlicePlan::half_angle(view, vbox, spacing_voxels, l)?;
                Self {
                    slices,
                    half: Some(half),
                }
            }
        })
    }

    /// World distance between samples along the view's centre ray (what plugins that
    /// depend on the slice spacing are given): the planes' spacing for view-aligned
    /// slices, the light's step (the same along the view's centre ray) for half-angle
    /// ones.
    pub fn ray_spacing(&self) -> f32 {
        match &self.half {
            Some(h) => h.light_step,
            None => self.slices.spacing,
        }
    }

    /// The longest world distance between two consecutive slices along a ray of
    /// `view`: the planes' spacing over the least |cos| between a ray and the slice
    /// normal, over the frustum's four edges (perspective; the extreme directions of
    /// its rays) or the view direction (orthographic). A sample's slab or move of k
    /// steps reaches at most k times this far (the skipping apron,
    /// [`crate::skipping::move_apron`]).
    pub fn max_ray_step(&self, view: &View) -> f32 {
        let n = self.slices.forward;
        let cos = if view.perspective {
            let inv = view.view_proj().inverse();
            [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
                .map(|(x, y)| {
                    let d = inv.project_point3(Vec3::new(x, y, 1.0))
                        - inv.project_point3(Vec3::new(x, y, 0.0));
                    d.normalize_or_zero().dot(n).abs()
                })
                .into_iter()
                .fold(1.0f32, f32::min)
        } else {
            view.forward.normalize_or_zero().dot(n).abs()
        };
        self.slices.spacing / cos.max(1.0e-3)
    }

    /// The order in which the rays of `view` that meet `vbox` cross the slices: `Some
    /// (false)` all front to back, `Some(true)` all back to front, `None` both (only
    /// under half-angle slicing, with a view wider than 90° across the slices, seen
    /// from inside the box or from close by). A ray's order is the sign of its
    /// direction along the slice normal, so one order holds where every direction in
    /// a cone that holds the rays has the same sign: the cone of the frustum's edges,
    /// or, from outside the box, that of its corners.
    pub fn back_to_front(&self, view: &View, vbox: &VolumeBox) -> Option<bool> {
        let n = self.slices.forward;
        if !view.perspective || self.half.is_none() {
            return Some(view.forward.dot(n) < 0.0);
        }
        let one_order = |dirs: &[Vec3]| {
            let behind = dirs[0].dot(n) < 0.0;
            dirs.iter()
                .all(|d| (d.dot(n) < 0.0) == behind)
                .then_some(behind)
        };
        let inv = view.view_proj().inverse();
        let edges = [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)].map(|(x, y)| {
            inv.project_point3(Vec3::new(x, y, 1.0)) - inv.project_point3(Vec3::new(x, y, 0.0))
        });
        one_order(&edges).or_else(|| {
            (!vbox.contains(view.eye))
                .then(|| one_order(&vbox.corners().map(|c| c - view.eye)))
                .flatten()
        })
    }
}

/// The geometry of half-angle slicing ([`SlicePlan::half_angle`]) for one view and
/// one directional light.
///
/// The slice normal is the half-angle axis: normalize(v + ℓ) when the light travels
/// away from the viewer's side (v·ℓ ≥ 0, v the view direction, ℓ the direction the
/// light travels), else normalize(ℓ − v), as Kniss et al. 2003 choose. Slice k + 1 lies
/// downstream of slice k for the light either way. A pixel whose ray advances along the
/// normal composites slices front to back ("under"); one whose ray advances against it
/// meets them back to front and composites "over" (the whole image when the light faces
/// the viewer; per pixel, a wide perspective view can hold both).
///
/// Per-slice state then lives in the light's space: an orthographic image across the
/// light (`state_rays`), whose texel (u, v) is the light ray through
/// `state_rays · (ndc, 0, 1)` along `state_rays` column 2, covering the box's shadow.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfAngle {
    /// Unit slice-plane normal.
    pub normal: Vec3,
    /// Unit direction the light travels.
    pub light: Vec3,
    /// World distance between two planes along `normal`.
    pub plane_spacing: f32,
    /// World path length along the light between two planes.
    pub light_step: f32,
    /// The state's rays: columns 0 and 1 step one NDC unit across the light (right and
    /// up in the state image), column 2 is `light`, column 3 the centre of the state
    /// image on a plane upstream of the box.
    pub state_rays: glam::Mat4,
}

impl HalfAngle {
    /// The half-angle geometry for `view` and a light travelling along `light`, with
    /// `spacing` world units between samples along the view's centre ray and along
    /// the light. A light that is zero or not finite is taken as the viewer's (along
    /// the view direction).
    pub fn new(view: &View, vbox: &VolumeBox, light: Vec3, spacing: f32) -> Self {
        let v = view.forward.as_dvec3().normalize();
        let l = light.as_dvec3();
        let l = if l.is_finite() && l.length_squared() > 0.0 {
            l.normalize()
        } else {
            v
        };
        let n = if v.dot(l) >= 0.0 {
            (v + l).normalize()
        } else {
            (l - v).normalize()
        };
        // the planes are spaced so that both the view's centre ray and the light
        // advance `spacing` from one to the next (|v·n| = |ℓ·n| ≥ cos 45°)
        let cos = l.dot(n).abs().max(1.0e-6);
        let plane_spacing = spacing as f64 * cos;
        // the state image: across the light, covering the box's projection
        let reference = if l.y.abs() < 0.9 {
            glam::DVec3::Y
        } else {
            glam::DVec3::X
        };
        let right = l.cross(reference).normalize();
        let up = right.cross(l);
        let c = vbox.centre().as_dvec3();
        let corners = vbox.corners().map(|p| p.as_dvec3() - c);
        let half = |axis: glam::DVec3| {
            corners
                .iter()
                .map(|p| p.dot(axis).abs())
                .fold(0.0, f64::max)
                .max(1.0e-9)
        };
        let reach = corners.iter().map(|p| p.length()).fold(0.0, f64::max);
        let state_rays = glam::DMat4::from_cols(
            (right * half(right)).extend(0.0),
            (up * half(up)).extend(0.0),
            l.extend(0.0),
            (c - l * (reach + spacing as f64)).extend(1.0),
        );
        Self {
            normal: n.as_vec3(),
            light: l.as_vec3(),
            plane_spacing: plane_spacing as f32,
            light_step: (plane_spacing / cos) as f32,
            state_rays: state_rays.as_mat4(),
        }
    }
}

/// A discrete oriented polytope with 26 faces: per direction of [`Dop::DIRS`] (the
/// axes, the face diagonals and the body diagonals, unit length), the least and the
/// greatest `n · p` over a set of points. It bounds their convex hull from outside, and
/// hugs rounded shapes far more closely than their bounding box: the raster backend's
/// proxy polygons cut to the occupied bricks' hull ([`SlicePlan::triangles_in_dop`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dop {
    /// Per direction: [least, greatest] of `n · p`.
    pub range: [[f32; 2]; 13],
}

impl Dop {
    pub const DIRS: [Vec3; 13] = {
        const A: f32 = std::f32::consts::FRAC_1_SQRT_2;
        const B: f32 = 0.577_350_26;
        [
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::new(A, A, 0.0),
            Vec3::new(A, -A, 0.0),
            Vec3::new(A, 0.0, A),
            Vec3::new(A, 0.0, -A),
            Vec3::new(0.0, A, A),
            Vec3::new(0.0, A, -A),
            Vec3::new(B, B, B),
            Vec3::new(B, B, -B),
            Vec3::new(B, -B, B),
            Vec3::new(B, -B, -B),
        ]
    };

    /// The polytope of the boxes, widened by `margin` along every direction; `None`
    /// without boxes.
    pub fn of_boxes(boxes: impl IntoIterator<Item = VolumeBox>, margin: f32) -> Option<Self> {
        let mut range = [[f32::INFINITY, f32::NEG_INFINITY]; 13];
        let mut any = false;
        for b in boxes {
            any = true;
            let (c, h) = ((b.min + b.max) * 0.5, (b.max - b.min) * 0.5);
            for (r, n) in range.iter_mut().zip(Self::DIRS) {
                // a box's support along n: its centre's projection ± the half extents'
                let (mid, reach) = (n.dot(c), n.abs().dot(h));
                r[0] = r[0].min(mid - reach);
                r[1] = r[1].max(mid + reach);
            }
        }
        any.then(|| Self {
            range: range.map(|[lo, hi]| [lo - margin, hi + margin]),
        })
    }

    /// Whether `p` lies inside the polytope (its faces included).
    pub fn contains(&self, p: Vec3) -> bool {
        Self::DIRS.iter().zip(self.range).all(|(n, [lo, hi])| {
            let d = n.dot(p);
            d >= lo && d <= hi
        })
    }

    /// The share of `b`'s volume inside the polytope, estimated as the share of the
    /// centres of an `n`³ grid of cells over `b` that it contains.
    pub fn share_of(&self, b: &VolumeBox, n: u32) -> f32 {
        let n = n.max(1);
        let cell = (b.max - b.min) / n as f32;
        let mut inside = 0u32;
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let f = glam::UVec3::new(i, j, k).as_vec3() + 0.5;
                    inside += self.contains(b.min + f * cell) as u32;
                }
            }
        }
        inside as f32 / (n * n * n) as f32
    }

    /// A convex polygon (ordered) cut to the polytope by Sutherland–Hodgman against its
    /// 26 half-spaces, in order; empty when nothing is left.
    pub fn clip(&self, mut poly: Vec<Vec3>) -> Vec<Vec3> {
        for (n, [lo, hi]) in Self::DIRS.iter().zip(self.range) {
            for (sign, bound) in [(1.0, lo), (-1.0, -hi)] {
                // keep sign · (n · p) ≥ bound
                let dist = |p: Vec3| sign * n.dot(p) - bound;
                if poly.iter().all(|&p| dist(p) >= 0.0) {
                    continue;
                }
                let mut out = Vec::with_capacity(poly.len() + 1);
                for (i, &a) in poly.iter().enumerate() {
                    let b = poly[(i + 1) % poly.len()];
                    let (da, db) = (dist(a), dist(b));
                    if da >= 0.0 {
                        out.push(a);
                    }
                    if (da >= 0.0) != (db >= 0.0) {
                        out.push(a.lerp(b, da / (da - db)));
                    }
                }
                poly = out;
                if poly.len() < 3 {
                    return Vec::new();
                }
            }
        }
        poly
    }
}

/// The pixels [x, y, width, height] of a `size` frame that a polygon (or a box's
/// corners) can cover: its projected vertices' bounds with a pixel of margin, clamped
/// to the frame (width or height 0 when it covers none, or is empty); the whole frame
/// when a vertex lies behind the eye (or within 10⁻⁶ of its plane) or projects to no
/// finite point.
pub fn screen_rect(poly: &[Vec3], view_proj: glam::Mat4, size: [u32; 2]) -> [u32; 4] {
    let (w, h) = (size[0] as f64, size[1] as f64);
    let (mut lo, mut hi) = (glam::DVec2::INFINITY, glam::DVec2::NEG_INFINITY);
    for p in poly {
        // behind the eye, or not finite: every pixel
        let Some(px) = pixel_of(*p, view_proj, size) else {
            return [0, 0, size[0], size[1]];
        };
        lo = lo.min(px);
        hi = hi.max(px);
    }
    if !(lo.x <= hi.x && lo.y <= hi.y) {
        return [0, 0, 0, 0];
    }
    let x0 = (lo.x.floor() - 1.0).clamp(0.0, w) as u32;
    let y0 = (lo.y.floor() - 1.0).clamp(0.0, h) as u32;
    let x1 = (hi.x.ceil() + 1.0).clamp(0.0, w) as u32;
    let y1 = (hi.y.ceil() + 1.0).clamp(0.0, h) as u32;
    [x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0)]
}

/// World point `p` under `view_proj` in a `size` frame, in pixels (y down); `None`
/// where it lies behind the eye or does not project to a finite point.
pub fn pixel_of(p: Vec3, view_proj: glam::Mat4, size: [u32; 2]) -> Option<glam::DVec2> {
    let c = (view_proj * p.extend(1.0)).as_dvec4();
    let ndc = glam::DVec2::new(c.x, c.y) / c.w;
    let px = glam::DVec2::new(
        (ndc.x * 0.5 + 0.5) * size[0] as f64,
        (0.5 - ndc.y * 0.5) * size[1] as f64,
    );
    (c.w > 1.0e-6 && px.is_finite()).then_some(px)
}

/// Drops the vertices of a convex polygon that lie within `tol` of the line through
/// their neighbours (and so repeated ones), until none does: the polygon loses slivers
/// no wider than `tol`, and a fan over it has no triangle thinner than that (a
/// rasteriser interpolates across a near-degenerate triangle with large errors).
pub fn drop_slivers(mut poly: Vec<Vec3>, tol: f32) -> Vec<Vec3> {
    let mut i = 0;
    while poly.len() >= 3 && i < poly.len() {
        let n = poly.len();
        let (a, v, b) = (poly[(i + n - 1) % n], poly[i], poly[(i + 1) % n]);
        let ab = b - a;
        let off = if ab.length_squared() > 0.0 {
            (v - a).cross(ab).length() / ab.length()
        } else {
            (v - a).length()
        };
        if off < tol {
            poly.remove(i);
            i = i.saturating_sub(1);
        } else {
            i += 1;
        }
    }
    if poly.len() < 3 { Vec::new() } else { poly }
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

    /// The hull drops repeated, inner and collinear points and runs counter-clockwise.
    #[test]
    fn convex_hull_keeps_the_corners_only() {
        let p = |x: f64, y: f64| glam::dvec2(x, y);
        let pts = vec![
            p(0.0, 0.0),
            p(1.0, 0.0),
            p(0.5, 0.0),
            p(1.0, 1.0),
            p(0.0, 1.0),
            p(0.5, 0.5),
            p(1.0, 1.0),
            p(0.0, 0.5),
        ];
        let h = convex_hull(pts);
        assert_eq!(h, vec![p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]);
        assert_eq!(
            convex_hull(vec![p(0.0, 0.0), p(1.0, 1.0), p(2.0, 2.0)]).len(),
            2
        );
    }

    /// A group's polygon (§9.1) lies on its first plane and covers every slice of the
    /// group as seen from the eye: each vertex of slices k0 … k0 + n − 1, carried along
    /// its ray onto plane k0, lies inside it, and its own vertices are such points (a
    /// hull, no larger than it must be); a group of one is the slice's polygon.
    #[test]
    fn group_polygons_cover_their_slices_along_the_rays() {
        let vbox = VolumeBox::new([64, 48, 40], [1.0, 1.0, 1.5]);
        let inside = |poly: &[Vec3], n: Vec3, q: Vec3| {
            let m = poly.len();
            let c = poly.iter().copied().sum::<Vec3>() / m as f32;
            let turn = |i: usize| (poly[(i + 1) % m] - poly[i]).cross(q - poly[i]).dot(n);
            let side = (poly[1] - poly[0]).cross(c - poly[0]).dot(n).signum();
            (0..m).all(|i| turn(i) * side >= -1e-6)
        };
        for (yaw, pitch, perspective) in [
            (30.0, 20.0, true),
            (200.0, -50.0, true),
            (75.0, 10.0, false),
        ] {
            let cam = Camera {
                yaw_deg: yaw,
                pitch_deg: pitch,
                projection: if perspective {
                    Projection::Perspective { fov_y_deg: 60.0 }
                } else {
                    Projection::Orthographic { height: 2.0 }
                },
                ..Default::default()
            };
            let view = cam.view(1.0);
            assert_eq!(view.perspective, perspective);
            let plan = SlicePlan::new(&view, &vbox, 2.0).unwrap();
            let f = plan.forward;
            for n in [1, 4, 16] {
                let mut covered = 0;
                for k0 in (0..plan.count).step_by(n as usize) {
                    let g = plan.group_polygon(&vbox, k0, n, perspective);
                    let d0 = plan.depth(k0);
                    for v in &g {
                        assert!(((*v - plan.eye).dot(f) - d0).abs() < 1e-5, "on plane k0");
                    }
                    if n == 1 && !g.is_empty() {
                        let a = polygon_area(&plan.polygon(&vbox, k0));
                        assert!((polygon_area(&g) - a).abs() < 1e-5 * a.max(1e-3));
                    }
                    let mut hull_points = 0;
                    for k in k0..(k0 + n).min(plan.count) {
                        let dk = plan.depth(k);
                        for p in plan.polygon(&vbox, k) {
                            let q = if perspective {
                                plan.eye + (p - plan.eye) * (d0 / dk)
                            } else {
                                p - f * (dk - d0)
                            };
                            assert!(inside(&g, f, q), "n {n} k0 {k0} k {k}: {q} outside");
                            covered += 1;
                            hull_points += g.iter().any(|v| v.distance(q) < 1e-5) as usize;
                        }
                    }
                    assert!(
                        g.is_empty() || hull_points >= g.len(),
                        "a vertex of no slice"
                    );
                }
                assert!(covered > 0);
            }
        }
    }

    /// The half-angle axis bisects the view and the light (or the light and the
    /// reversed view when the light faces the viewer), the planes keep the requested
    /// spacing along the view's centre ray and along the light, the state's rays start
    /// upstream of the box and its image covers the box's shadow, and a headlight
    /// slices as the view does.
    #[test]
    fn half_angle_planes_bisect_the_view_and_the_light() {
        let vbox = VolumeBox::new([64, 48, 40], [1.0, 1.0, 1.5]);
        let cam = Camera {
            yaw_deg: 30.0,
            pitch_deg: 20.0,
            ..Default::default()
        };
        let view = cam.view(1.0);
        let v = view.forward;
        let spacing = 0.5;
        let ds = spacing * vbox.voxel;
        for light in [
            v,
            v + view.right,
            view.up - v * 0.3,
            -v + view.right * 0.2,
            -v,
        ] {
            let (plan, h) = SlicePlan::half_angle(&view, &vbox, spacing, light).unwrap();
            let l = light.normalize();
            let n = h.normal;
            assert!((n.length() - 1.0).abs() < 1e-5 && plan.forward == n);
            if v.dot(l) >= 0.0 {
                assert!((n.dot(v) - n.dot(l)).abs() < 1e-5, "{light}");
            } else {
                assert!((n.dot(l) + n.dot(v)).abs() < 1e-5, "{light}");
            }
            assert!(
                n.dot(l) > 0.7,
                "the light crosses the planes in order: {light}"
            );
            // Δs between planes along the view's centre ray and along the light
            assert!(
                (plan.spacing / n.dot(v).abs() - ds).abs() < 1e-5 * ds,
                "{light}"
            );
            assert!(
                (h.light_step - ds).abs() < 1e-5 * ds
                    && (h.plane_spacing - plan.spacing).abs() < 1e-9
            );
            // the planes span the box along n
            let depths = vbox.corners().map(|c| (c - view.eye).dot(n));
            let (lo, hi) = depths
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &d| {
                    (a.min(d), b.max(d))
                });
            assert!(plan.d0 >= lo - 1e-6 && plan.d0 < lo + plan.spacing);
            let last = plan.depth(plan.count - 1);
            assert!(last <= hi + 1e-6 && last > hi - plan.spacing);
            // every corner lies on a state ray, inside the state image, downstream of
            // the rays' origins
            let m = h.state_rays;
            for c in vbox.corners() {
                let q = c - m.w_axis.truncate();
                let ndc = [m.x_axis.truncate(), m.y_axis.truncate()]
                    .map(|a| q.dot(a) / a.length_squared());
                assert!(ndc.iter().all(|x| x.abs() <= 1.0 + 1e-5), "{light} {ndc:?}");
                assert!(q.dot(m.z_axis.truncate()) > 0.0);
            }
        }
        let (plan, _) = SlicePlan::half_angle(&view, &vbox, spacing, v * 3.0).unwrap();
        assert!((plan.forward - v).length() < 1e-6);
        // a zero light is the viewer's; bad spacings are refused as for view slicing
        let (plan, _) = SlicePlan::half_angle(&view, &vbox, spacing, Vec3::ZERO).unwrap();
        assert!((plan.forward - v).length() < 1e-6);
        assert!(SlicePlan::half_angle(&view, &vbox, 0.0, v).is_err());
        assert!(SlicePlan::half_angle(&view, &vbox, 1e-9, v).is_err());
    }

    /// The order a frame's rays meet the planes in: one order for a view in front of
    /// the box, none for half-angle slices with the eye inside it.
    #[test]
    fn frames_know_the_order_their_rays_meet_the_slices() {
        let vbox = unit_box();
        let view = Camera::default().view(1.0);
        let v = view.forward;
        let plan =
            |light: Option<Vec3>, view: &View| FramePlan::new(view, &vbox, 1.0, light).unwrap();
        assert_eq!(plan(None, &view).back_to_front(&view, &vbox), Some(false));
        assert_eq!(
            plan(Some(v + view.up), &view).back_to_front(&view, &vbox),
            Some(false)
        );
        assert_eq!(
            plan(Some(-v + view.up), &view).back_to_front(&view, &vbox),
            Some(true)
        );
        // from inside the box, a 35° view across the light meets the slices in one
        // order (the half-angle normal is at most 45° off the view), a 120° one in both
        let inside = |fov_y_deg: f32| {
            Camera {
                distance: 0.2,
                projection: crate::camera::Projection::Perspective { fov_y_deg },
                ..Default::default()
            }
            .view(1.0)
        };
        let (narrow, wide) = (inside(35.0), inside(120.0));
        assert_eq!(
            plan(Some(narrow.right + 0.2 * narrow.forward), &narrow).back_to_front(&narrow, &vbox),
            Some(false)
        );
        assert_eq!(
            plan(Some(wide.right), &wide).back_to_front(&wide, &vbox),
            None
        );
        assert_eq!(
            plan(Some(-wide.forward), &wide).back_to_front(&wide, &vbox),
            Some(true)
        );
        assert_eq!(plan(None, &wide).back_to_front(&wide, &vbox), Some(false));
        assert!((plan(Some(v), &view).ray_spacing() - vbox.voxel).abs() < 1e-6);
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

    /// The 26-DOP of two boxes on a diagonal bounds both (every corner within each
    /// direction's range, the margin included) and leaves out the empty corner of their
    /// bounding box, which the box cannot: a plane through that corner keeps less of its
    /// polygon, every vertex of the cut inside the polytope; a polygon inside is kept
    /// as it is.
    #[test]
    fn dop_bounds_its_boxes_and_cuts_polygons_to_them() {
        let b = |min: [f32; 3], max: [f32; 3]| VolumeBox {
            min: Vec3::from(min),
            max: Vec3::from(max),
            voxel: 0.01,
        };
        let boxes = [b([0.0; 3], [0.4; 3]), b([0.6; 3], [1.0; 3])];
        let margin = 0.005;
        let dop = Dop::of_boxes(boxes, margin).unwrap();
        assert!(Dop::of_boxes([], margin).is_none());
        let inside = |p: Vec3, eps: f32| {
            Dop::DIRS
                .iter()
                .zip(dop.range)
                .all(|(n, [lo, hi])| n.dot(p) >= lo - eps && n.dot(p) <= hi + eps)
        };
        for c in boxes.iter().flat_map(|b| b.corners()) {
            assert!(inside(c, -0.9 * margin), "{c}: within the margin");
        }
        // the bounding box's corner (1, 0, 0), nearest the eye below, lies far from both
        assert!(!inside(Vec3::new(1.0, 0.0, 0.0), 0.0));
        let whole = b([0.0; 3], [1.0; 3]);
        let eye = Vec3::new(2.0, -1.0, -1.0);
        let n = (Vec3::new(1.0, 0.0, 0.0) - eye).normalize();
        let d = (Vec3::splat(0.5) - eye).dot(n);
        let poly = plane_box_polygon(&whole, eye, n, d);
        let cut = dop.clip(poly.clone());
        assert!(cut.len() >= 3, "the plane meets the boxes' hull");
        assert!(polygon_area(&cut) < 0.8 * polygon_area(&poly));
        for p in &cut {
            assert!(inside(*p, 1e-5), "{p}");
            assert!(((*p - eye).dot(n) - d).abs() < 1e-5, "{p}: on the plane");
        }
        // a polygon inside the polytope is kept as it is
        let small = plane_box_polygon(
            &b([0.1; 3], [0.3; 3]),
            eye,
            n,
            (Vec3::splat(0.2) - eye).dot(n),
        );
        assert_eq!(dop.clip(small.clone()), small);
        // a plane through the box's corner nearest the eye, away from both boxes,
        // keeps nothing
        let far = plane_box_polygon(
            &whole,
            eye,
            n,
            (Vec3::new(1.0, 0.0, 0.0) - eye).dot(n) + 0.02,
        );
        assert!(!far.is_empty() && dop.clip(far).is_empty());
        // `contains` and `share_of`: a box's own hull holds all of it; the two boxes'
        // hull holds more than their volumes (0.128 of the whole box) and leaves out the
        // corners far from the diagonal
        assert!(dop.contains(Vec3::splat(0.5)) && !dop.contains(Vec3::new(1.0, 0.0, 0.0)));
        assert_eq!(
            Dop::of_boxes([whole], 0.0).unwrap().share_of(&whole, 8),
            1.0
        );
        let share = dop.share_of(&whole, 16);
        assert!(share > 0.128 && share < 0.8, "{share}");
    }

    /// `drop_slivers` removes vertices on or within `tol` of their neighbours' line
    /// (midpoints, repeats) and keeps real corners.
    #[test]
    fn drop_slivers_removes_flat_vertices_only() {
        let v = |x: f32, y: f32| Vec3::new(x, y, 0.0);
        let square = vec![v(0.0, 0.0), v(1.0, 0.0), v(1.0, 1.0), v(0.0, 1.0)];
        assert_eq!(drop_slivers(square.clone(), 1e-3), square);
        let noisy = vec![
            v(0.0, 0.0),
            v(0.5, 1e-5),
            v(1.0, 0.0),
            v(1.0, 0.0),
            v(1.0, 1.0),
            v(0.0, 1.0),
        ];
        assert_eq!(drop_slivers(noisy, 1e-3), square);
        // a corner off the line by more than tol stays
        let kite = vec![v(0.0, 0.0), v(0.5, -0.01), v(1.0, 0.0), v(0.5, 1.0)];
        assert_eq!(drop_slivers(kite.clone(), 1e-3), kite);
        // a polygon thinner than tol vanishes
        assert!(drop_slivers(vec![v(0.0, 0.0), v(1.0, 1e-5), v(2.0, 0.0)], 1e-3).is_empty());
    }

    /// `screen_rect` bounds a polygon's projection with a pixel of margin within the
    /// frame, gives the whole frame for a vertex behind the eye and nothing for an
    /// empty polygon or one off the frame.
    #[test]
    fn screen_rects_bound_the_projection() {
        let cam = Camera {
            projection: Projection::Orthographic { height: 2.0 },
            ..Default::default()
        };
        let view = cam.view(1.0);
        let vp = view.view_proj();
        let (r, u, c) = (view.right, view.up, view.eye + view.forward);
        // a square of half the view's height, centred: pixels 25..75 of 100
        let square = [
            c - 0.5 * r - 0.5 * u,
            c + 0.5 * r - 0.5 * u,
            c + 0.5 * r + 0.5 * u,
            c - 0.5 * r + 0.5 * u,
        ];
        // (bounds within rounding of 25 − 1 and 75 + 1)
        let near = |v: u32, want: u32| v.abs_diff(want) <= 1;
        let [x, y, w, h] = screen_rect(&square, vp, [100, 100]);
        assert!(
            near(x, 24) && near(y, 24) && near(x + w, 76) && near(y + h, 76),
            "{x} {y} {w} {h}"
        );
        assert!(
            x <= 24 && y <= 24 && x + w >= 76 && y + h >= 76,
            "covers the square"
        );
        // off to the side: clamped to the frame
        let shifted = square.map(|p| p + 1.0 * r);
        let [x, _, w, _] = screen_rect(&shifted, vp, [100, 100]);
        assert!(near(x, 74) && x + w == 100, "{x} {w}");
        let gone = square.map(|p| p + 3.0 * r);
        assert_eq!(screen_rect(&gone, vp, [100, 100])[2], 0);
        assert_eq!(screen_rect(&[], vp, [100, 100]), [0, 0, 0, 0]);
        let persp = Camera::default().view(1.0);
        let behind = [persp.eye - persp.forward, persp.eye + persp.forward];
        assert_eq!(
            screen_rect(&behind, persp.view_proj(), [64, 32]),
            [0, 0, 64, 32]
        );
    }
}
