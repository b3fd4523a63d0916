//! Empty-space skipping: a coarse grid of bricks, each with the range of normalised
//! scalars any trilinear sample inside it can take, and per stack an occupancy bit per
//! brick: whether a sample in the brick can come out of the hook chain with α > 0.
//! The compute backend's single-pass loop (`march` in `shaders/slice.wgsl`, entry
//! point `cs_main_skip`) jumps over the slices a ray spends inside an empty brick; the
//! image is the same, since every skipped sample would have contributed exactly
//! nothing. (A per-fragment early-out in the raster backend measured 15 % slower on
//! lavapipe, whose fragment cost is dominated by rasterisation and blending.) Both
//! backends sample only inside the occupied bricks' bounding box ([`occupied_bounds`]:
//! the compute backend's rays, the raster backend's proxy polygons), and the raster
//! backend can cut its polygons further to [`occupied_cells`] (that box in cells of a
//! few bricks per axis, the empty cells left out), so that fragments are made only where
//! a sample can be visible.
//!
//! Exactness rests on the plugins' [`Transparency`] promises (see there): skipping is
//! on only when every enabled plugin makes one. A brick of [`brick()`]³ voxels covers the
//! samples whose voxel coordinate `tex · dims` lies in it; such a sample interpolates
//! voxels up to one beyond the brick on each side, so the range is taken over the brick
//! plus a one-voxel apron and widened by [`RANGE_MARGIN`] (more than the fp16 rounding
//! of an R16Float volume texture).

use std::sync::Arc;

use rayon::prelude::*;

use glam::DVec3;

use crate::plugin::{PluginInstance, RegionFn, Transparency, VisibleFn, Volumes};

/// Side of a brick in voxels, unless `VWB_SKIP_BRICK` says otherwise
/// (`bench/brick_size.py`, docs/perf.md "Brick size").
pub const BRICK: u32 = 8;

/// Side of a brick in voxels: `VWB_SKIP_BRICK` (≥ 1; a benchmark override, read once
/// per process so that every grid agrees) or [`BRICK`].
pub fn brick() -> u32 {
    static SIDE: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    *SIDE.get_or_init(|| crate::renderer::env_count("VWB_SKIP_BRICK", BRICK))
}

/// Widening of every brick's value range (normalised units).
pub const RANGE_MARGIN: f64 = 1.0e-3;

/// Value range per brick, x fastest.
#[derive(Debug, Clone, PartialEq)]
pub struct BrickRanges {
    /// Bricks per axis: ⌈dims / brick()⌉.
    pub dims: [u32; 3],
    pub ranges: Vec<[f32; 2]>,
}

impl BrickRanges {
    /// From the normalised scalars of a volume of `dims` voxels (x fastest), in bricks
    /// of [`brick()`] voxels.
    pub fn new(dims: [u32; 3], scalars: &[f32]) -> Self {
        Self::with_side(dims, scalars, brick())
    }

    /// [`BrickRanges::new`] in bricks of `side` voxels.
    pub fn with_side(dims: [u32; 3], scalars: &[f32], side: u32) -> Self {
        Self::with_apron(dims, scalars, side, 1)
    }

    /// [`BrickRanges::with_side`] with each brick's range taken over `apron` voxels
    /// beyond it on every side (1: what a trilinear sample inside it reads; more for
    /// samples that plugins move, [`move_apron`]).
    ///
    /// An apron wider than a brick (a long move or read ahead at a coarse spacing, or
    /// rays nearly along the slices) is not scanned voxel by voxel, which would cost
    /// each brick up to the whole volume: the one-voxel ranges are widened over the
    /// brick grid instead, by ⌈(apron − 1) / side⌉ bricks each way (a superset of the
    /// voxels, so the ranges stay conservative).
    pub fn with_apron(dims: [u32; 3], scalars: &[f32], side: u32, apron: u32) -> Self {
        let side = side.max(1);
        if apron > side {
            let mut r = Self::with_apron(dims, scalars, side, 1);
            r.widen((apron - 1).div_ceil(side));
            return r;
        }
        let bdims = dims.map(|d| d.div_ceil(side).max(1));
        let at = |x: u32, y: u32, z: u32| {
            scalars[((z as usize * dims[1] as usize) + y as usize) * dims[0] as usize + x as usize]
        };
        let span = |b: u32, axis: usize| {
            let lo = (b * side).saturating_sub(apron);
            let hi = ((b + 1) * side + apron - 1).min(dims[axis] - 1);
            lo..=hi
        };
        let count = (bdims[0] * bdims[1] * bdims[2]) as usize;
        let ranges = (0..count)
            .into_par_iter()
            .map(|i| {
                let bx = (i % bdims[0] as usize) as u32;
                let by = ((i / bdims[0] as usize) % bdims[1] as usize) as u32;
                let bz = (i / (bdims[0] as usize * bdims[1] as usize)) as u32;
                let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                for z in span(bz, 2) {
                    for y in span(by, 1) {
                        for x in span(bx, 0) {
                            let v = at(x, y, z);
                            lo = lo.min(v);
                            hi = hi.max(v);
                        }
                    }
                }
                [lo, hi]
            })
            .collect();
        Self {
            dims: bdims,
            ranges,
        }
    }

    /// Each brick's range joined with its neighbours' within `r` bricks along every
    /// axis (a separable min/max over the brick grid).
    fn widen(&mut self, r: u32) {
        let d = self.dims.map(|v| v as usize);
        let r = r as usize;
        for axis in 0..3 {
            let stride = [1, d[0], d[0] * d[1]][axis];
            let n = d[axis];
            let before = self.ranges.clone();
            for (i, out) in self.ranges.iter_mut().enumerate() {
                let at = (i / stride) % n;
                let base = i - at * stride;
                let (a, b) = (at.saturating_sub(r), (at + r).min(n - 1));
                for k in a..=b {
                    let q = before[base + k * stride];
                    out[0] = out[0].min(q[0]);
                    out[1] = out[1].max(q[1]);
                }
            }
        }
    }

    /// One byte per brick: 255 where `visible` holds for its widened range, else 0.
    pub fn occupancy(&self, visible: &VisibleFn) -> Vec<u8> {
        self.ranges
            .par_iter()
            .map(|r| {
                let lo = r[0] as f64 - RANGE_MARGIN;
                let hi = r[1] as f64 + RANGE_MARGIN;
                if visible(lo, hi) { 255 } else { 0 }
            })
            .collect()
    }
}

/// Whether a sample with a value in [lo, hi] can be visible after the enabled
/// instances' hooks, or `None` when some plugin makes no promise. The last
/// [`Transparency::ByValue`] classifier decides; without one, the core's grey ramp
/// (α = value) does.
/// The promise of a classifier that reads a lookup table over the normalised value
/// (entries at i/(n − 1), linearly interpolated): `visible[i]` says whether entry i
/// has α > 0 (for a table per label, in any row). A value range can be visible when
/// any entry the GPU interpolates for it is, the entries around both ends included.
pub fn visible_by_table(visible: Vec<bool>) -> Transparency {
    Transparency::ByValue(table_visibility(visible))
}

/// The function of [`visible_by_table`], for promises that carry more than it
/// ([`Transparency::ByValueAhead`]).
pub fn table_visibility(visible: Vec<bool>) -> Arc<VisibleFn> {
    Arc::new(move |lo: f64, hi: f64| {
        let Some(last) = visible.len().checked_sub(1) else {
            return false;
        };
        let index = |v: f64| v.clamp(0.0, 1.0) * last as f64;
        let (a, b) = (index(lo).floor() as usize, index(hi).ceil() as usize);
        a <= b && visible[a..=b.min(last)].iter().any(|&v| v)
    })
}

/// The regions of the enabled instances that drop samples outside them, over
/// the document's volume ([`crate::plugin::Plugin::region`]).
pub fn stack_regions(stack: &[PluginInstance], volumes: &Volumes<'_>) -> Vec<Arc<RegionFn>> {
    stack
        .iter()
        .filter(|i| i.enabled)
        .filter_map(|i| i.configured().region(&i.params, volumes))
        .collect()
}

/// Bricks per axis of one proxy cell of the raster backend, unless
/// `VWB_RASTER_PROXY_CELL` says otherwise (`bench/raster_options.py`, docs/perf.md: 2
/// was the least slow on lavapipe, where no cell size pays).
pub const PROXY_CELL: u32 = 2;

/// Bricks per axis of one proxy cell: `VWB_RASTER_PROXY_CELL` (≥ 1) or [`PROXY_CELL`].
pub fn proxy_cell() -> u32 {
    crate::renderer::env_count("VWB_RASTER_PROXY_CELL", PROXY_CELL)
}

/// Index of brick `b` in an occupancy of `bdims` bricks (x fastest).
fn brick_index(b: [u32; 3], bdims: [u32; 3]) -> usize {
    ((b[2] * bdims[1] + b[1]) * bdims[0] + b[0]) as usize
}

/// Every brick of a grid of `bdims` bricks, x fastest.
fn bricks_of(bdims: [u32; 3]) -> impl Iterator<Item = [u32; 3]> {
    (0..bdims[2])
        .flat_map(move |z| (0..bdims[1]).flat_map(move |y| (0..bdims[0]).map(move |x| [x, y, z])))
}

/// The bricks of a grid of `bdims` whose `occupancy` byte is nonzero, x fastest.
fn occupied_bricks(occupancy: &[u8], bdims: [u32; 3]) -> impl Iterator<Item = [u32; 3]> + '_ {
    bricks_of(bdims).filter(move |&b| {
        occupancy
            .get(brick_index(b, bdims))
            .is_some_and(|&v| v != 0)
    })
}

/// The bounding box of the occupied bricks, [lo, hi) in bricks; `None` when none is.
fn occupied_brick_bounds(occupancy: &[u8], bdims: [u32; 3]) -> Option<[[u32; 3]; 2]> {
    let (mut lo, mut hi) = ([u32::MAX; 3], [0u32; 3]);
    for b in occupied_bricks(occupancy, bdims) {
        for a in 0..3 {
            lo[a] = lo[a].min(b[a]);
            hi[a] = hi[a].max(b[a] + 1);
        }
    }
    (lo[0] != u32::MAX).then_some([lo, hi])
}

/// The longest pure run the march uses, in bricks beyond its own: `VWB_RUN_BRICKS` (0
/// to [`RUN_BRICKS_MAX`]; a benchmark override, read once per process; 0 looks every
/// brick up, as the march did before) or [`RUN_BRICKS_MAX`].
pub fn run_bricks_cap() -> u8 {
    static CAP: std::sync::OnceLock<u8> = std::sync::OnceLock::new();
    *CAP.get_or_init(|| {
        std::env::var("VWB_RUN_BRICKS")
            .ok()
            .and_then(|v| v.trim().parse::<u8>().ok())
            .map_or(RUN_BRICKS_MAX, |r| r.min(RUN_BRICKS_MAX))
    })
}

/// Largest extent [`pure_boxes_ahead`] stores (7 bits beside the visible bit).
pub const RUN_BRICKS_MAX: u8 = 127;

/// For each brick of an occupancy grid (`bdims` bricks, x fastest; a byte above 127 may
/// be visible) and each octant of ray directions (bit 0: x decreasing, bit 1: y, bit 2:
/// z), the largest r ≤ [`RUN_BRICKS_MAX`] such that the box of (r + 1)³ bricks from it
/// towards that octant (b + s·δ, each δ in 0..=r, s the octant's signs) is all of the
/// brick's own kind: all empty after an empty brick, all possibly visible after a
/// visible one. Bricks outside the grid hold no samples and count as either kind.
///
/// A ray heading into that octant meets no brick of the other kind until it leaves the
/// box, so the compute march looks a brick up once per box rather than once per brick:
/// it jumps over an empty brick's whole box, and takes a visible brick's box's samples
/// without looking up the bricks inside it (docs/perf.md, "Pure boxes ahead of the
/// ray"). A box that reaches only forward is longer than a cube around the brick
/// where the kind changes behind it: the first bricks inside the matter and the last
/// ones before it. One pass per octant against its direction: the box of r + 1 from b
/// is b's brick and the seven boxes of r from its forward neighbours.
pub fn pure_boxes_ahead(occupancy: &[u8], bdims: [u32; 3]) -> Vec<[u8; 8]> {
    let [nx, ny, nz] = bdims.map(|d| d as i64);
    let count = (nx * ny * nz) as usize;
    assert_eq!(occupancy.len(), count, "one occupancy byte per brick");
    let index = |x: i64, y: i64, z: i64| ((z * ny + y) * nx + x) as usize;
    let inside = |x: i64, y: i64, z: i64| {
        (0..nx).contains(&x) && (0..ny).contains(&y) && (0..nz).contains(&z)
    };
    let mut per_octant: [Vec<u8>; 8] = std::array::from_fn(|_| vec![0u8; count]);
    for (octant, out) in per_octant.iter_mut().enumerate() {
        let s = [0, 1, 2].map(|a| if octant >> a & 1 == 1 { -1i64 } else { 1 });
        // against the octant's direction, so that the forward neighbours come first
        let order = |n: i64, sign: i64, i: i64| if sign > 0 { n - 1 - i } else { i };
        for zi in 0..nz {
            let z = order(nz, s[2], zi);
            for yi in 0..ny {
                let y = order(ny, s[1], yi);
                for xi in 0..nx {
                    let x = order(nx, s[0], xi);
                    let kind = occupancy[index(x, y, z)] > 127;
                    let mut r = RUN_BRICKS_MAX as u32;
                    for d in 1..8i64 {
                        let (a, b, c) = (
                            x + (d & 1) * s[0],
                            y + (d >> 1 & 1) * s[1],
                            z + (d >> 2 & 1) * s[2],
                        );
                        if !inside(a, b, c) {
                            continue;
                        }
                        let n = index(a, b, c);
                        r = if (occupancy[n] > 127) == kind {
                            r.min(u32::from(out[n]) + 1)
                        } else {
                            0
                        };
                        if r == 0 {
                            break;
                        }
                    }
                    out[index(x, y, z)] = r as u8;
                }
            }
        }
    }
    (0..count)
        .map(|i| std::array::from_fn(|octant| per_octant[octant][i]))
        .collect()
}

/// The voxels ([start, end) per axis) of a volume of `dims` voxels where a sample can be
/// visible: the bounding box of its occupied bricks (`bdims` bricks, x fastest), `None`
/// when no brick is occupied. A brick renderer of a split volume draws and composites
/// only this box's footprint, and nothing when it is `None`.
pub fn occupied_bounds(occupancy: &[u8], bdims: [u32; 3], dims: [u32; 3]) -> Option<[[u32; 2]; 3]> {
    let [lo, hi] = occupied_brick_bounds(occupancy, bdims)?;
    Some(std::array::from_fn(|a| {
        [
            (lo[a] * brick()).min(dims[a]),
            (hi[a] * brick()).min(dims[a]),
        ]
    }))
}

/// The voxels ([start, end) per axis) of every occupied brick of a volume of `dims`
/// voxels (`bdims` bricks, x fastest, a nonzero `occupancy` byte per brick that can be
/// visible).
pub fn occupied_brick_voxels(
    occupancy: &[u8],
    bdims: [u32; 3],
    dims: [u32; 3],
) -> impl Iterator<Item = [[u32; 2]; 3]> + '_ {
    let b = brick();
    occupied_bricks(occupancy, bdims).map(move |i| {
        std::array::from_fn(|a| [(i[a] * b).min(dims[a]), ((i[a] + 1) * b).min(dims[a])])
    })
}

/// The occupied parts of a volume of `dims` voxels, as boxes of whole voxels
/// ([start, end) per axis). The bounding box of the occupied bricks (`bdims` bricks,
/// x fastest, a nonzero `occupancy` byte per brick that can be visible) is cut into
/// cells of `cell` bricks per axis from its low corner, and the cells holding an
/// occupied brick are kept whole. Every sample that can be visible lies in one of the
/// boxes (a sample belongs to the brick its voxel coordinate lies in), the boxes do not
/// overlap, and neighbouring boxes share whole faces, so their slice polygons meet
/// edge to edge without cracks or double cover (no T-junctions).
pub fn occupied_cells(
    occupancy: &[u8],
    bdims: [u32; 3],
    dims: [u32; 3],
    cell: u32,
) -> Vec<[[u32; 2]; 3]> {
    let cell = cell.max(1);
    let Some([lo, hi]) = occupied_brick_bounds(occupancy, bdims) else {
        return Vec::new();
    };
    let cells: [u32; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).div_ceil(cell));
    let mut keep = vec![false; (cells[0] * cells[1] * cells[2]) as usize];
    for b in occupied_bricks(occupancy, bdims) {
        let c: [u32; 3] = std::array::from_fn(|a| (b[a] - lo[a]) / cell);
        keep[((c[2] * cells[1] + c[1]) * cells[0] + c[0]) as usize] = true;
    }
    let mut out = Vec::new();
    for (i, _) in keep.iter().enumerate().filter(|(_, k)| **k) {
        let i = i as u32;
        let c = [
            i % cells[0],
            (i / cells[0]) % cells[1],
            i / (cells[0] * cells[1]),
        ];
        out.push(std::array::from_fn(|a| {
            let b0 = lo[a] + c[a] * cell;
            let b1 = (b0 + cell).min(hi[a]);
            [(b0 * brick()).min(dims[a]), (b1 * brick()).min(dims[a])]
        }));
    }
    out
}

/// Marks empty (0) every brick of `occupancy` that lies wholly outside one of the
/// `regions`: a brick of a volume of `dims` voxels in the world box `(lo, hi)` covers
/// the samples whose `tex · dims` lies in it, widened by [`REGION_MARGIN`] of the box
/// and by `widen` (world units: how far a plugin moves samples).
pub fn clear_outside_regions(
    occupancy: &mut [u8],
    bricks: [u32; 3],
    dims: [u32; 3],
    (lo, hi): (DVec3, DVec3),
    regions: &[Arc<RegionFn>],
    widen: f64,
) {
    if regions.is_empty() {
        return;
    }
    let extent = hi - lo;
    let margin = extent * REGION_MARGIN + DVec3::splat(widen.max(0.0));
    let d = DVec3::from(dims.map(|n| n.max(1) as f64));
    occupancy.par_iter_mut().enumerate().for_each(|(i, o)| {
        let b = DVec3::new(
            (i % bricks[0] as usize) as f64,
            ((i / bricks[0] as usize) % bricks[1] as usize) as f64,
            (i / (bricks[0] as usize * bricks[1] as usize)) as f64,
        );
        let side = brick() as f64;
        let t0 = (b * side / d).min(DVec3::ONE);
        let t1 = ((b + 1.0) * side / d).min(DVec3::ONE);
        let (a, z) = (lo + extent * t0 - margin, lo + extent * t1 + margin);
        if !regions.iter().all(|r| r(a, z)) {
            *o = 0;
        }
    });
}

/// Widening of a brick's world box against f32 rounding of sample positions, as a
/// share of the volume box.
pub const REGION_MARGIN: f64 = 1.0e-4;

/// What the enabled instances' classifications show ([`Transparency::ByValue`] of the
/// last classifier, joined with every [`Transparency::Adds`]), `None` when one
/// promises nothing.
pub fn stack_visibility(stack: &[PluginInstance], volumes: &Volumes<'_>) -> Option<Arc<VisibleFn>> {
    let mut visible: Arc<VisibleFn> = Arc::new(|_lo: f64, hi: f64| hi > 0.0);
    let mut adds: Vec<Arc<VisibleFn>> = Vec::new();
    for inst in stack.iter().filter(|i| i.enabled) {
        match inst.configured().transparency(&inst.params, volumes) {
            Transparency::Unknown => return None,
            Transparency::Keeps | Transparency::Region(_) | Transparency::Moves(_) => {}
            Transparency::ByValue(f) | Transparency::ByValueAhead(f, _) => visible = f,
            Transparency::Adds(f, _) => adds.push(f),
        }
    }
    if adds.is_empty() {
        return Some(visible);
    }
    Some(Arc::new(move |lo: f64, hi: f64| {
        visible(lo, hi) || adds.iter().any(|f| f(lo, hi))
    }))
}

/// How far the enabled instances move samples along their rays, or read ahead of
/// them, in slice steps: the largest [`Transparency::Moves`] plus the largest
/// [`Transparency::ByValueAhead`] or [`Transparency::Adds`] (0 when none does). Moves
/// and reads add up: a moved sample's slab reads ahead of where it was moved to.
pub fn stack_moves(stack: &[PluginInstance], volumes: &Volumes<'_>) -> f64 {
    let (mut moves, mut ahead) = (0.0f64, 0.0f64);
    for i in stack.iter().filter(|i| i.enabled) {
        match i.configured().transparency(&i.params, volumes) {
            Transparency::Moves(steps) => moves = moves.max(steps.max(0.0)),
            Transparency::ByValueAhead(_, steps) | Transparency::Adds(_, steps) => {
                ahead = ahead.max(steps.max(0.0))
            }
            _ => {}
        }
    }
    moves + ahead
}

/// The apron (voxels) of the brick ranges that keeps skipping exact when samples move
/// (or read ahead) by up to `steps` slice steps of at most `step` voxels along a ray
/// (the frame's longest step between two slices, [`crate::slicing::FramePlan::max_ray_step`]):
/// a move of d voxels along the ray changes each voxel coordinate by at most d, so a
/// sample tested in brick B reads voxels up to ⌈d⌉ beyond B's usual one-voxel apron.
pub fn move_apron(steps: f64, step: f32) -> u32 {
    let d = steps * step.max(0.0) as f64;
    1 + if d > 0.0 {
        d.ceil().min(1.0e6) as u32
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    /// Aprons wider than a brick widen the ranges over the brick grid: each range
    /// holds the exact range over its apron (a superset), for aprons from one brick to
    /// more than the volume; aprons up to a brick are exact.
    #[test]
    fn wide_aprons_hold_the_exact_ranges() {
        let dims = [21u32, 13, 9];
        let mut rng = crate::rng::Rng::at(5, 0);
        let scalars: Vec<f32> = (0..dims.iter().product::<u32>())
            .map(|_| rng.uniform() as f32)
            .collect();
        let side = 4;
        let exact = |apron: u32| {
            let bdims = dims.map(|d| d.div_ceil(side));
            let mut out = Vec::new();
            for bz in 0..bdims[2] {
                for by in 0..bdims[1] {
                    for bx in 0..bdims[0] {
                        let span = |b: u32, a: usize| {
                            (b * side).saturating_sub(apron)
                                ..=((b + 1) * side + apron - 1).min(dims[a] - 1)
                        };
                        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                        for z in span(bz, 2) {
                            for y in span(by, 1) {
                                for x in span(bx, 0) {
                                    let v = scalars[((z * dims[1] + y) * dims[0] + x) as usize];
                                    lo = lo.min(v);
                                    hi = hi.max(v);
                                }
                            }
                        }
                        out.push([lo, hi]);
                    }
                }
            }
            out
        };
        for apron in [1, 3, 4, 5, 9, 30] {
            let r = super::BrickRanges::with_apron(dims, &scalars, side, apron);
            let e = exact(apron);
            assert_eq!(r.ranges.len(), e.len());
            for (got, want) in r.ranges.iter().zip(&e) {
                assert!(
                    got[0] <= want[0] && got[1] >= want[1],
                    "apron {apron}: {got:?} ⊉ {want:?}"
                );
                if apron <= side {
                    assert_eq!(got, want, "apron {apron}");
                }
            }
        }
    }

    /// Each brick's extent towards each octant is the largest r whose box of (r + 1)³
    /// bricks from it that way (cut to the grid) holds only its own kind, by brute force
    /// over random grids of a few sizes and densities; a grid of one kind reaches the cap.
    #[test]
    fn pure_boxes_ahead_are_the_largest_pure_boxes() {
        let mut rng = crate::rng::Rng::at(11, 0);
        let cases = [
            ([1u32, 1, 1], 0.5),
            ([7, 5, 3], 0.1),
            ([6, 6, 6], 0.5),
            ([9, 4, 8], 0.9),
            ([12, 3, 1], 0.02),
            ([9, 8, 7], 0.01),
        ];
        for (bdims, density) in cases {
            let [nx, ny, nz] = bdims.map(|d| d as i64);
            let count = bdims.iter().product::<u32>() as usize;
            let occupancy: Vec<u8> = (0..count)
                .map(|_| if rng.uniform() < density { 255 } else { 0 })
                .collect();
            let boxes = super::pure_boxes_ahead(&occupancy, bdims);
            let at = |x: i64, y: i64, z: i64| occupancy[((z * ny + y) * nx + x) as usize] > 127;
            let mut longer = 0;
            for (i, extents) in boxes.iter().enumerate() {
                let (x, y, z) = (i as i64 % nx, i as i64 / nx % ny, i as i64 / (nx * ny));
                let kind = at(x, y, z);
                for (octant, r) in extents.iter().enumerate() {
                    let s = [0, 1, 2].map(|a| if octant >> a & 1 == 1 { -1i64 } else { 1 });
                    // (no brick lies further than the grid's size away)
                    let pure = |r: i64| {
                        (0..=r.min(nz)).all(|c| {
                            (0..=r.min(ny)).all(|b| {
                                (0..=r.min(nx)).all(|a| {
                                    let (p, q, w) = (x + a * s[0], y + b * s[1], z + c * s[2]);
                                    !((0..nx).contains(&p)
                                        && (0..ny).contains(&q)
                                        && (0..nz).contains(&w))
                                        || at(p, q, w) == kind
                                })
                            })
                        })
                    };
                    let r = *r as i64;
                    assert!(pure(r), "{bdims:?} brick {i} octant {octant}: {r} not pure");
                    if r < super::RUN_BRICKS_MAX as i64 {
                        assert!(
                            !pure(r + 1),
                            "{bdims:?} brick {i} octant {octant}: {r} not the largest"
                        );
                    }
                    longer += usize::from(r > 0);
                }
            }
            if bdims == [9, 8, 7] {
                assert!(longer > count * 4, "sparse: boxes of several bricks");
            }
        }
        let boxes = super::pure_boxes_ahead(&[0u8; 600], [300, 2, 1]);
        assert!(boxes.iter().flatten().all(|r| *r == super::RUN_BRICKS_MAX));
    }

    #[test]
    fn a_wider_apron_covers_moved_samples() {
        assert_eq!(super::move_apron(0.0, 4.0), 1);
        assert_eq!(super::move_apron(0.5, 1.0), 2);
        assert_eq!(super::move_apron(0.5, 3.0), 3);
        let dims = [20u32, 18, 17];
        let mut rng = crate::rng::Rng::at(7, 0);
        let scalars: Vec<f32> = (0..dims.iter().product::<u32>())
            .map(|_| rng.uniform() as f32)
            .collect();
        let side = 8;
        let at = |v: [i64; 3]| {
            let c = |a: usize| v[a].clamp(0, dims[a] as i64 - 1) as usize;
            scalars[(c(2) * dims[1] as usize + c(1)) * dims[0] as usize + c(0)]
        };
        // the voxels a trilinear sample at voxel coordinate x reads
        let read = |x: [f64; 3]| {
            let f = x.map(|c| (c - 0.5).floor() as i64);
            let mut out = Vec::new();
            for k in 0..8 {
                out.push(at([
                    f[0] + (k & 1),
                    f[1] + ((k >> 1) & 1),
                    f[2] + ((k >> 2) & 1),
                ]));
            }
            out
        };
        for (d, apron, covered) in [(0.0, 1, true), (1.5, 1, false), (1.5, 3, true)] {
            let ranges = super::BrickRanges::with_apron(dims, &scalars, side, apron);
            let mut all = true;
            for _ in 0..4000 {
                let x: [f64; 3] = std::array::from_fn(|a| rng.uniform() * dims[a] as f64);
                let b: [u32; 3] = std::array::from_fn(|a| (x[a] as u32) / side);
                let bi = ((b[2] * ranges.dims[1] + b[1]) * ranges.dims[0] + b[0]) as usize;
                let [lo, hi] = ranges.ranges[bi];
                let moved: [f64; 3] = std::array::from_fn(|a| {
                    (x[a] + (rng.uniform() * 2.0 - 1.0) * d).clamp(0.0, dims[a] as f64)
                });
                all &= read(moved).iter().all(|v| *v >= lo && *v <= hi);
            }
            assert_eq!(all, covered, "move {d}, apron {apron}");
        }
    }

    /// Every occupied brick lies in exactly one box, the boxes are disjoint, cells
    /// without an occupied brick give none, and one cell over the grid is the bounding box.
    #[test]
    fn occupied_cells_cover_the_occupied_bricks_once() {
        let dims = [70u32, 45, 33]; // partial bricks at the far ends
        let bdims = dims.map(|d| d.div_ceil(super::brick()));
        let n = (bdims[0] * bdims[1] * bdims[2]) as usize;
        let mut rng = crate::rng::Rng::at(12345, 0);
        let occupancy: Vec<u8> = (0..n)
            .map(|_| if rng.uniform() < 0.2 { 255 } else { 0 })
            .collect();
        let inside =
            |b: &[[u32; 2]; 3], v: [u32; 3]| (0..3).all(|a| b[a][0] <= v[a] && v[a] < b[a][1]);
        for cell in [1, 2, 3, 100] {
            let boxes = occupied_cells(&occupancy, bdims, dims, cell);
            for (i, &o) in occupancy.iter().enumerate() {
                let i = i as u32;
                let b = [
                    i % bdims[0],
                    (i / bdims[0]) % bdims[1],
                    i / (bdims[0] * bdims[1]),
                ];
                let voxel = b.map(|x| x * super::brick()); // the brick's first voxel
                let holders = boxes.iter().filter(|x| inside(x, voxel)).count();
                if o != 0 {
                    assert_eq!(holders, 1, "cell {cell}: brick {b:?} in {holders} boxes");
                } else {
                    assert!(holders <= 1, "cell {cell}: boxes overlap at {b:?}");
                }
            }
            for x in &boxes {
                assert!(
                    (0..3).all(|a| x[a][0] < x[a][1] && x[a][1] <= dims[a]),
                    "{x:?}"
                );
                // a box touching another along axis a has the same extent on the others
                for y in &boxes {
                    for a in 0..3 {
                        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
                        let overlap = |p: usize| x[p][0] < y[p][1] && y[p][0] < x[p][1];
                        if x[a][1] == y[a][0] && overlap(b) && overlap(c) {
                            assert_eq!((x[b], x[c]), (y[b], y[c]), "T-junction {x:?} {y:?}");
                        }
                    }
                }
            }
        }
        // one cell over the whole grid: the bounding box of the occupied bricks
        let one = occupied_cells(&occupancy, bdims, dims, 100);
        assert_eq!(one.len(), 1);
        assert_eq!(one[0], [[0, 70], [0, 45], [0, 33]]);
        let sparse: Vec<u8> = (0..n)
            .map(|i| if i == 7 || i == n - 1 { 1 } else { 0 })
            .collect();
        let one = occupied_cells(&sparse, bdims, dims, 100);
        assert_eq!(one, vec![[[56, 70], [0, 45], [0, 33]]]);
        assert_eq!(
            occupied_cells(&sparse, bdims, dims, 2),
            vec![[[56, 70], [0, 16], [0, 16]], [[56, 70], [32, 45], [32, 33]]]
        );
        let single: Vec<u8> = (0..n).map(|i| (i == 7) as u8).collect();
        assert_eq!(
            occupied_cells(&single, bdims, dims, 2),
            vec![[[56, 64], [0, 8], [0, 8]]]
        );
        assert!(occupied_cells(&vec![0; n], bdims, dims, 2).is_empty());
    }

    use super::*;
    use crate::plugin::CpuContext;
    use crate::volume::{Volume, VoxelData};
    use glam::DVec3;

    #[test]
    fn ranges_cover_every_trilinear_sample() {
        let dims = [19u32, 8, 11];
        let n = (dims[0] * dims[1] * dims[2]) as usize;
        // a deterministic pseudo-random field
        let mut s = 12345u64;
        let data: Vec<f32> = (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 40) as f32 / (1u64 << 24) as f32
            })
            .collect();
        let volume = Volume::new("r", dims, 1, [1.0; 3], VoxelData::F32(data)).unwrap();
        let scalars = volume.normalized_scalars();
        let ctx = CpuContext::new(&volume, &scalars);
        // every side bench/brick_size.py measures
        for (side, bdims) in [
            (4, [5, 2, 3]),
            (8, [3, 1, 2]),
            (16, [2, 1, 1]),
            (32, [1, 1, 1]),
        ] {
            let bricks = BrickRanges::with_side(dims, &scalars, side);
            assert_eq!(bricks.dims, bdims);
            for i in 0..20_000u32 {
                let f = |k: u32| (i as f64 * 0.6180339887 * (k as f64 + 1.0)).fract();
                let tex = DVec3::new(f(0), f(1), f(2));
                let v = ctx.value(tex) as f32;
                let b = [0, 1, 2].map(|a| {
                    ((tex[a] * dims[a] as f64 / side as f64).floor() as u32).min(bricks.dims[a] - 1)
                });
                let r = bricks.ranges
                    [((b[2] * bricks.dims[1] + b[1]) * bricks.dims[0] + b[0]) as usize];
                assert!(
                    r[0] - 1e-6 <= v && v <= r[1] + 1e-6,
                    "side {side}, {tex:?}: {v} outside {r:?}"
                );
            }
        }
    }

    #[test]
    fn occupancy_marks_bricks() {
        let bricks = BrickRanges {
            dims: [3, 1, 1],
            ranges: vec![[0.0, 0.1], [0.2, 0.6], [0.9, 1.0]],
        };
        let visible: Arc<VisibleFn> = Arc::new(|lo, hi| hi >= 0.5 && lo <= 0.95);
        assert_eq!(bricks.occupancy(&*visible), vec![0, 255, 255]);
    }
}
