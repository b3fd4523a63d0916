//! Template adaptation (thesis §6.4): a transfer function designed for volume A is
//! mapped onto volume B by a monotone warp of the normalised value axis, found by
//! dynamic programming (dynamic time warping) between A's and B's value signatures.
//!
//! Two signatures are tried and the better one is used:
//! - **histogram**: the cumulative histogram, which a monotone warp moves without
//!   changing its values (counts per bin would change with the warp's slope);
//! - **p(v)**: the Kindlmann–Durkin boundary profile (the mean gradient magnitude per
//!   value bin, scaled likewise), which marks where boundaries sit even when the amounts
//!   of material differ.
//!
//! The warp minimises the summed squared difference of the signatures along a monotone
//! path (steps (1,1), (1,0), (0,1); the diagonal is free of the 0.5 penalty the others
//! pay, so flat regions follow the identity-like slope). The per-bin cost normalised by
//! the path length says which signature fits better; the report names it.

use crate::tf::{TfCurve, TfPoint};
use crate::volume::Volume;

/// Bins of the value axis.
pub const BINS: usize = 256;

/// A monotone map from A's value bins to B's: `map[i]` is B's bin (fractional) for A's
/// bin `i`.
#[derive(Debug, Clone, PartialEq)]
pub struct Warp {
    pub map: Vec<f64>,
    /// `"histogram"` or `"p(v)"`.
    pub signature: &'static str,
    /// Mean squared signature difference along the path (lower fits better).
    pub cost: f64,
}

impl Warp {
    /// The warped normalised value x ∈ [0, 1] (linear between bin centres).
    pub fn apply(&self, x: f64) -> f64 {
        let f = (x * (BINS - 1) as f64).clamp(0.0, (BINS - 1) as f64);
        let i = (f.floor() as usize).min(BINS - 2);
        let t = f - i as f64;
        ((self.map[i] * (1.0 - t) + self.map[i + 1] * t) / (BINS - 1) as f64).clamp(0.0, 1.0)
    }

    /// The local slope dw/dx at x.
    pub fn slope(&self, x: f64) -> f64 {
        let h = 2.0 / (BINS - 1) as f64;
        let (a, b) = ((x - h).max(0.0), (x + h).min(1.0));
        ((self.apply(b) - self.apply(a)) / (b - a)).max(1e-3)
    }
}

fn scaled(v: Vec<f64>) -> Vec<f64> {
    let m = v.iter().cloned().fold(0.0, f64::max);
    if m > 0.0 {
        v.iter().map(|x| x / m).collect()
    } else {
        v
    }
}

/// The cumulative histogram (the share of voxels at or below each bin). A monotone warp
/// of the values leaves it unchanged up to the warp of its argument, whereas counts per
/// bin change with the warp's slope.
pub fn histogram_signature(v: &Volume) -> Vec<f64> {
    let total = v.histogram.iter().sum::<u64>().max(1) as f64;
    let mut acc = 0.0;
    v.histogram
        .iter()
        .map(|&c| {
            acc += c as f64;
            acc / total
        })
        .collect()
}

/// Mean gradient magnitude (central differences, voxel units of the normalised value)
/// per value bin, max 1: where the boundaries are.
pub fn boundary_signature(v: &Volume) -> Vec<f64> {
    let [nx, ny, nz] = v.dims.map(|d| d as usize);
    let (lo, hi) = (v.range[0], v.range[1]);
    let span = if hi > lo { hi - lo } else { 1.0 };
    let at = |x: usize, y: usize, z: usize| v.scalar(x as u32, y as u32, z as u32);
    let mut sum = vec![0.0; BINS];
    let mut count = vec![0u64; BINS];
    for z in 1..nz.saturating_sub(1) {
        for y in 1..ny.saturating_sub(1) {
            for x in 1..nx.saturating_sub(1) {
                let s = at(x, y, z);
                if !s.is_finite() {
                    continue;
                }
                let g = [
                    at(x + 1, y, z) - at(x - 1, y, z),
                    at(x, y + 1, z) - at(x, y - 1, z),
                    at(x, y, z + 1) - at(x, y, z - 1),
                ];
                let m = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt() / (2.0 * span);
                if !m.is_finite() {
                    continue;
                }
                let b = (((s - lo) / span) * (BINS - 1) as f64)
                    .round()
                    .clamp(0.0, (BINS - 1) as f64) as usize;
                sum[b] += m;
                count[b] += 1;
            }
        }
    }
    scaled(
        sum.iter()
            .zip(&count)
            .map(|(s, &c)| if c > 0 { s / c as f64 } else { 0.0 })
            .collect(),
    )
}

/// The monotone warp of `a` onto `b` by dynamic time warping.
pub fn dtw(a: &[f64], b: &[f64]) -> (Vec<f64>, f64) {
    let (n, m) = (a.len(), b.len());
    let idx = |i: usize, j: usize| i * m + j;
    let mut cost = vec![f64::INFINITY; n * m];
    let mut len = vec![0u32; n * m];
    for i in 0..n {
        for j in 0..m {
            let d = (a[i] - b[j]).powi(2);
            if i == 0 && j == 0 {
                cost[0] = d;
                len[0] = 1;
                continue;
            }
            let mut best = (f64::INFINITY, 0u32);
            if i > 0 && j > 0 && cost[idx(i - 1, j - 1)] < best.0 {
                best = (cost[idx(i - 1, j - 1)], len[idx(i - 1, j - 1)]);
            }
            let pen = 0.5 * d + 1e-6;
            if i > 0 && cost[idx(i - 1, j)] + pen < best.0 {
                best = (cost[idx(i - 1, j)] + pen, len[idx(i - 1, j)]);
            }
            if j > 0 && cost[idx(i, j - 1)] + pen < best.0 {
                best = (cost[idx(i, j - 1)] + pen, len[idx(i, j - 1)]);
            }
            cost[idx(i, j)] = best.0 + d;
            len[idx(i, j)] = best.1 + 1;
        }
    }
    // backtrack, averaging the B bins each A bin meets
    let (mut i, mut j) = (n - 1, m - 1);
    let mut hits: Vec<Vec<usize>> = vec![Vec::new(); n];
    loop {
        hits[i].push(j);
        if i == 0 && j == 0 {
            break;
        }
        let d = (a[i] - b[j]).powi(2);
        let here = cost[idx(i, j)] - d;
        let pen = 0.5 * d + 1e-6;
        if i > 0 && j > 0 && (cost[idx(i - 1, j - 1)] - here).abs() <= 1e-12 * (1.0 + here.abs()) {
            i -= 1;
            j -= 1;
        } else if i > 0 && (cost[idx(i - 1, j)] + pen - here).abs() <= 1e-9 * (1.0 + here.abs()) {
            i -= 1;
        } else if j > 0 {
            j -= 1;
        } else {
            i -= 1;
        }
    }
    let map = hits
        .iter()
        .map(|h| h.iter().sum::<usize>() as f64 / h.len().max(1) as f64)
        .collect();
    (
        map,
        cost[idx(n - 1, m - 1)] / len[idx(n - 1, m - 1)].max(1) as f64,
    )
}

/// Sub-bin refinement of a histogram warp: where A's cumulative share at bin i falls
/// strictly inside B's rise from bin j − 1 to j, the position interpolates linearly
/// there; elsewhere (flat stretches, where any position fits) the DP's position stays.
fn refine_cdf(map: &mut [f64], ca: &[f64], cb: &[f64]) {
    for (i, m) in map.iter_mut().enumerate() {
        let target = ca[i];
        let j = cb.partition_point(|&c| c < target);
        if j == 0 || j >= cb.len() {
            continue;
        }
        let (c0, c1) = (cb[j - 1], cb[j]);
        if c1 > c0 && target > c0 && (*m - j as f64).abs() <= 3.0 {
            *m = (j - 1) as f64 + (target - c0) / (c1 - c0);
        }
    }
}

/// The warp from volume `a` to volume `b`: both signatures tried, the lower cost kept.
pub fn warp(a: &Volume, b: &Volume) -> Warp {
    let (ca, cb) = (histogram_signature(a), histogram_signature(b));
    let (mut hm, hc) = dtw(&ca, &cb);
    refine_cdf(&mut hm, &ca, &cb);
    let (pm, pc) = dtw(&boundary_signature(a), &boundary_signature(b));
    if pc < hc {
        Warp {
            map: pm,
            signature: "p(v)",
            cost: pc,
        }
    } else {
        Warp {
            map: hm,
            signature: "histogram",
            cost: hc,
        }
    }
}

/// The transfer function moved through the warp: control points to w(x), primitive
/// centres to w(c) and widths scaled by the local slope.
pub fn adapt_curve(tf: &TfCurve, w: &Warp) -> TfCurve {
    let mut points: Vec<TfPoint> = tf
        .points
        .iter()
        .map(|p| TfPoint {
            x: w.apply(p.x as f64) as f32,
            color: p.color,
        })
        .collect();
    // a flat stretch of the warp can merge points: keep them strictly increasing
    for i in 1..points.len() {
        if points[i].x <= points[i - 1].x {
            points[i].x = (points[i - 1].x + 1e-6).min(1.0);
        }
    }
    points.dedup_by(|b, a| b.x <= a.x);
    let primitives = tf
        .primitives
        .iter()
        .map(|p| {
            let mut q = *p;
            q.centre = w.apply(p.centre as f64) as f32;
            q.width = (p.width as f64 * w.slope(p.centre as f64)).max(1e-4) as f32;
            q
        })
        .collect();
    TfCurve {
        points,
        primitives,
        log_opacity: tf.log_opacity,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dtw_recovers_a_shift_and_an_identity() {
        let a: Vec<f64> = (0..BINS)
            .map(|i| ((i as f64 - 80.0) / 10.0).powi(2).neg_exp())
            .collect();
        let (m, c) = dtw(&a, &a);
        assert!(c < 1e-12);
        for (i, v) in m.iter().enumerate() {
            assert!((v - i as f64).abs() < 1e-9, "{i}: {v}");
        }
        let b: Vec<f64> = (0..BINS)
            .map(|i| ((i as f64 - 120.0) / 10.0).powi(2).neg_exp())
            .collect();
        let (m, _) = dtw(&a, &b);
        // the peak moves from 80 to 120
        assert!((m[80] - 120.0).abs() <= 1.0, "{}", m[80]);
    }

    trait NegExp {
        fn neg_exp(self) -> f64;
    }
    impl NegExp for f64 {
        fn neg_exp(self) -> f64 {
            (-self).exp()
        }
    }
}
