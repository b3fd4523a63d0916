//! Empty-space skipping: a coarse grid of bricks, each with the range of normalised
//! scalars any trilinear sample inside it can take, and per stack an occupancy bit per
//! brick: whether a sample in the brick can come out of the hook chain with α > 0.
//! The compute backend's single-pass loop (`march` in `shaders/slice.wgsl`, entry
//! point `cs_main_skip`) jumps over the slices a ray spends inside an empty brick; the
//! image is the same, since every skipped sample would have contributed exactly
//! nothing. (A per-fragment early-out in the raster backend measured 15 % slower on
//! lavapipe, whose fragment cost is dominated by rasterisation and blending, so the
//! raster and per-slice paths do not skip.)
//!
//! Exactness rests on the plugins' [`Transparency`] promises (see there): skipping is
//! on only when every enabled plugin makes one. A brick of `BRICK`³ voxels covers the
//! samples whose voxel coordinate `tex · dims` lies in it; such a sample interpolates
//! voxels up to one beyond the brick on each side, so the range is taken over the brick
//! plus a one-voxel apron and widened by [`RANGE_MARGIN`] (more than the fp16 rounding
//! of an R16Float volume texture).

use std::sync::Arc;

use rayon::prelude::*;

use glam::DVec3;

use crate::plugin::{PluginInstance, RegionFn, Transparency, VisibleFn};

/// Side of a brick in voxels.
pub const BRICK: u32 = 8;

/// Widening of every brick's value range (normalised units).
pub const RANGE_MARGIN: f64 = 1.0e-3;

/// Value range per brick, x fastest.
#[derive(Debug, Clone, PartialEq)]
pub struct BrickRanges {
    /// Bricks per axis: ⌈dims / BRICK⌉.
    pub dims: [u32; 3],
    pub ranges: Vec<[f32; 2]>,
}

impl BrickRanges {
    /// From the normalised scalars of a volume of `dims` voxels (x fastest).
    pub fn new(dims: [u32; 3], scalars: &[f32]) -> Self {
        let bdims = dims.map(|d| d.div_ceil(BRICK).max(1));
        let at = |x: u32, y: u32, z: u32| {
            scalars[((z as usize * dims[1] as usize) + y as usize) * dims[0] as usize + x as usize]
        };
        let span = |b: u32, axis: usize| {
            let lo = (b * BRICK).saturating_sub(1);
            let hi = ((b + 1) * BRICK).min(dims[axis] - 1);
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
    Transparency::ByValue(Arc::new(move |lo: f64, hi: f64| {
        let Some(last) = visible.len().checked_sub(1) else {
            return false;
        };
        let index = |v: f64| v.clamp(0.0, 1.0) * last as f64;
        let (a, b) = (index(lo).floor() as usize, index(hi).ceil() as usize);
        a <= b && visible[a..=b.min(last)].iter().any(|&v| v)
    }))
}

/// The regions of the enabled instances that drop samples outside them, over
/// `volume` ([`crate::plugin::Plugin::region`]).
pub fn stack_regions(
    stack: &[PluginInstance],
    volume: &crate::volume::Volume,
) -> Vec<Arc<RegionFn>> {
    stack
        .iter()
        .filter(|i| i.enabled)
        .filter_map(|i| i.configured().region(&i.params, volume))
        .collect()
}

/// Marks empty (0) every brick of `occupancy` that lies wholly outside one of the
/// `regions`: a brick of a volume of `dims` voxels in the world box `(lo, hi)` covers
/// the samples whose `tex · dims` lies in it, widened by [`REGION_MARGIN`] of the box.
pub fn clear_outside_regions(
    occupancy: &mut [u8],
    bricks: [u32; 3],
    dims: [u32; 3],
    (lo, hi): (DVec3, DVec3),
    regions: &[Arc<RegionFn>],
) {
    if regions.is_empty() {
        return;
    }
    let extent = hi - lo;
    let margin = extent * REGION_MARGIN;
    let d = DVec3::from(dims.map(|n| n.max(1) as f64));
    occupancy.par_iter_mut().enumerate().for_each(|(i, o)| {
        let b = DVec3::new(
            (i % bricks[0] as usize) as f64,
            ((i / bricks[0] as usize) % bricks[1] as usize) as f64,
            (i / (bricks[0] as usize * bricks[1] as usize)) as f64,
        );
        let t0 = (b * BRICK as f64 / d).min(DVec3::ONE);
        let t1 = ((b + 1.0) * BRICK as f64 / d).min(DVec3::ONE);
        let (a, z) = (lo + extent * t0 - margin, lo + extent * t1 + margin);
        if !regions.iter().all(|r| r(a, z)) {
            *o = 0;
        }
    });
}

/// Widening of a brick's world box against f32 rounding of sample positions, as a
/// share of the volume box.
pub const REGION_MARGIN: f64 = 1.0e-4;

pub fn stack_visibility(stack: &[PluginInstance]) -> Option<Arc<VisibleFn>> {
    let mut visible: Arc<VisibleFn> = Arc::new(|_lo: f64, hi: f64| hi > 0.0);
    for inst in stack.iter().filter(|i| i.enabled) {
        match inst.configured().transparency(&inst.params) {
            Transparency::Unknown => return None,
            Transparency::Keeps | Transparency::Region(_) => {}
            Transparency::ByValue(f) => visible = f,
        }
    }
    Some(visible)
}

#[cfg(test)]
mod tests {
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
        let bricks = BrickRanges::new(dims, &scalars);
        assert_eq!(bricks.dims, [3, 1, 2]);
        let ctx = CpuContext::new(&volume, &scalars);
        for i in 0..20_000u32 {
            let f = |k: u32| (i as f64 * 0.6180339887 * (k as f64 + 1.0)).fract();
            let tex = DVec3::new(f(0), f(1), f(2));
            let v = ctx.value(tex) as f32;
            let b = [0, 1, 2].map(|a| {
                ((tex[a] * dims[a] as f64 / BRICK as f64).floor() as u32).min(bricks.dims[a] - 1)
            });
            let r =
                bricks.ranges[((b[2] * bricks.dims[1] + b[1]) * bricks.dims[0] + b[0]) as usize];
            assert!(
                r[0] - 1e-6 <= v && v <= r[1] + 1e-6,
                "{tex:?}: {v} outside {r:?}"
            );
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
