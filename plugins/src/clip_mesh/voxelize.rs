//! Voxelisation of a closed mesh into a narrow-band signed-distance grid over the
//! volume box (`clip.mesh`'s mesh pass).
//!
//! - **Inside or outside** by crossing parity: a ray along +z through each column of
//!   voxel centres is intersected with every triangle whose projection covers it; a
//!   voxel centre is inside when an odd number of crossings lie below it. Parity needs
//!   neither orientation nor normals. The column is moved by about 10⁻⁷ of a voxel off
//!   the grid lines, so rays do not pass exactly through the shared edges and corners
//!   of meshes that are aligned with the grid (a box); a column that still crosses an
//!   odd number of times (a ray grazing a vertex) is counted in [`SdfGrid::odd_columns`].
//! - **Distance**: within a band of [`BAND`] voxels of the surface, the exact
//!   distance from the voxel centre to the nearest triangle (Ericson's closest point);
//!   beyond it, ±band. The value is stored in units of Δs0 (the volume's finest voxel,
//!   `frame.box_min.w`), negative inside, rounded to f16 as the GPU texture holds it,
//!   so the GPU and the CPU twin interpolate the same numbers.
//!
//! Trilinear interpolation of a signed distance reproduces a plane exactly and a
//! curved surface to second order, so the cut is smooth at any grid resolution, and
//! the soft edge and the shading at the cut read the distance directly.

use glam::DVec3;
use rayon::prelude::*;

use super::mesh::TriMesh;

/// Width of the exact-distance band, in voxels of the grid (at least in Δs0).
pub const BAND: f64 = 4.0;

/// A signed-distance grid over the volume box.
#[derive(Debug, Clone, PartialEq)]
pub struct SdfGrid {
    pub dims: [u32; 3],
    /// Signed distance in Δs0 (negative inside the mesh), x fastest, each value
    /// exactly representable in f16.
    pub values: Vec<f32>,
    /// The band in Δs0: values are clamped to ±band.
    pub band: f32,
    /// Columns with an odd number of crossings (grazing rays; 0 for a closed mesh in
    /// general position).
    pub odd_columns: usize,
}

/// Voxelises `mesh` (world coordinates) over the box (`lo`, `hi`) into a grid of
/// `dims` voxels; `step` is Δs0 (world), the unit of the stored distances.
pub fn voxelize(mesh: &TriMesh, lo: DVec3, hi: DVec3, dims: [u32; 3], step: f64) -> SdfGrid {
    let [gx, gy, gz] = dims.map(|d| d.max(1) as usize);
    let cell = (hi - lo) / DVec3::new(gx as f64, gy as f64, gz as f64);
    let band_world = BAND * cell.min_element().max(step);
    let tris: Vec<[DVec3; 3]> = (0..mesh.triangles.len()).map(|t| mesh.corners(t)).collect();
    let centre = |i: usize, a: usize| lo[a] + (i as f64 + 0.5) * cell[a];
    // index range of voxel centres within [a, b] along axis `a`
    let range = |a: f64, b: f64, axis: usize, n: usize| -> Option<(usize, usize)> {
        let first = ((a - lo[axis]) / cell[axis] - 0.5).ceil().max(0.0);
        let last = ((b - lo[axis]) / cell[axis] - 0.5).floor().min(n as f64 - 1.0);
        (first <= last).then_some((first as usize, last as usize))
    };

    // 1. crossings of each z column
    let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); gx * gy];
    for (t, c) in tris.iter().enumerate() {
        let (mn, mx) = (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]));
        let (Some((x0, x1)), Some((y0, y1))) = (
            range(mn.x - 1e-6 * cell.x, mx.x + 1e-6 * cell.x, 0, gx),
            range(mn.y - 1e-6 * cell.y, mx.y + 1e-6 * cell.y, 1, gy),
        ) else {
            continue;
        };
        for y in y0..=y1 {
            for x in x0..=x1 {
                buckets[y * gx + x].push(t as u32);
            }
        }
    }
    // off the grid lines by irrational fractions of a voxel
    let (ex, ey) = (1.0e-7 * std::f64::consts::SQRT_2 * cell.x, 1.0e-7 * 1.732_050_807_568_877_2 * cell.y);
    let crossings: Vec<Vec<f64>> = buckets
        .par_iter()
        .enumerate()
        .map(|(col, list)| {
            let (px, py) = (centre(col % gx, 0) + ex, centre(col / gx, 1) + ey);
            let mut zs: Vec<f64> = list
                .iter()
                .filter_map(|&t| column_hit(&tris[t as usize], px, py))
                .collect();
            zs.sort_by(f64::total_cmp);
            zs
        })
        .collect();
    let odd_columns = crossings.iter().filter(|z| z.len() % 2 == 1).count();

    // 2. distances within the band, slice by slice; the sign from the crossings
    let band = band_world / step;
    let mut values = vec![0.0f32; gx * gy * gz];
    values
        .par_chunks_mut(gx * gy)
        .enumerate()
        .for_each(|(z, slice)| {
            let zc = centre(z, 2);
            let mut d2 = vec![band_world * band_world; gx * gy];
            for c in &tris {
                let (mn, mx) = (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]));
                if zc < mn.z - band_world || zc > mx.z + band_world {
                    continue;
                }
                let (Some((x0, x1)), Some((y0, y1))) = (
                    range(mn.x - band_world, mx.x + band_world, 0, gx),
                    range(mn.y - band_world, mx.y + band_world, 1, gy),
                ) else {
                    continue;
                };
                for y in y0..=y1 {
                    let yc = centre(y, 1);
                    for x in x0..=x1 {
                        let p = DVec3::new(centre(x, 0), yc, zc);
                        let q = closest_point(p, c);
                        let d = (p - q).length_squared();
                        let cur = &mut d2[y * gx + x];
                        if d < *cur {
                            *cur = d;
                        }
                    }
                }
            }
            for (i, v) in slice.iter_mut().enumerate() {
                let zs = &crossings[i];
                let below = zs.partition_point(|&h| h < zc);
                let inside = below % 2 == 1;
                let d = (d2[i].sqrt() / step).min(band);
                let signed = if inside { -d } else { d };
                *v = half::f16::from_f64(signed).to_f32();
            }
        });
    SdfGrid {
        dims,
        values,
        band: half::f16::from_f64(band).to_f32(),
        odd_columns,
    }
}

/// The z where the vertical line through (px, py) crosses triangle `c`, if it does
/// (strictly inside its projection; a projection of zero area is never crossed).
fn column_hit(c: &[DVec3; 3], px: f64, py: f64) -> Option<f64> {
    let e = |a: DVec3, b: DVec3| (b.x - a.x) * (py - a.y) - (b.y - a.y) * (px - a.x);
    let (w0, w1, w2) = (e(c[1], c[2]), e(c[2], c[0]), e(c[0], c[1]));
    let area = w0 + w1 + w2;
    let inside = (w0 > 0.0 && w1 > 0.0 && w2 > 0.0) || (w0 < 0.0 && w1 < 0.0 && w2 < 0.0);
    (inside && area != 0.0).then(|| (w0 * c[0].z + w1 * c[1].z + w2 * c[2].z) / area)
}

/// The point of triangle `c` closest to `p` (Ericson, Real-Time Collision Detection,
/// §5.1.5).
pub fn closest_point(p: DVec3, c: &[DVec3; 3]) -> DVec3 {
    let [a, b, cc] = *c;
    let (ab, ac, ap) = (b - a, cc - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - cc;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cc;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (cc - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom == 0.0 {
        // a degenerate triangle: the nearest of its corners
        return [a, b, cc]
            .into_iter()
            .min_by(|x, y| (p - *x).length_squared().total_cmp(&(p - *y).length_squared()))
            .unwrap_or(a);
    }
    let (v, w) = (vb / denom, vc / denom);
    a + ab * v + ac * w
}
