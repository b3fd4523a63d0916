//! Pre-integrated classification (Engel, Kraus and Ertl 2001) for the
//! emission–absorption model, with self-attenuation inside the segment.
//!
//! A slab between two slices is a ray segment of length d (voxels) along which the
//! scalar runs linearly from the front value s_f to the back value s_b. Its opacity
//! and colour are integrals over the transfer function between s_f and s_b; the
//! table holds them for every pair of the `n` values x_i = i/(n − 1).
//!
//! Optical model. The TF gives opacity a(v) per reference step Δs0 (one voxel), i.e.
//! extinction κ(v) = −ln(1 − a(v)) per voxel, and straight colour c(v). Over the
//! segment, with λ = d/|s_b − s_f| voxels per unit of value,
//!   α = 1 − exp(−∫κ dt),  C = ∫ c κ exp(−∫₀ᵗ κ) dt   (premultiplied).
//! Discretisation: the TF is the baked table with opacity linear between nodes, as
//! the GPU's filtered lookup holds it. Within each table cell [x_k, x_{k+1}] the
//! extinction is replaced by its exact cell mean for that linear opacity,
//! κ̄ = −(1/(u₁ − u₀))·[u ln u − u]_{u₀}^{u₁} with u = 1 − a, and the colour by the
//! κ-weighted mean of the two nodes' colours: a cell crossed over
//! length ℓ = d/|j − i| emits c̄_k(1 − e^{−κ̄_k ℓ}) and transmits e^{−κ̄_k ℓ}; cells
//! composite front to back. Where s_f = s_b the segment is homogeneous:
//! α = 1 − (1 − a)^d, C = c·α — the limit of the cell formula, so the table is smooth
//! across the diagonal (stable when front ≈ back).
//!
//! Cost. Entries with the same |j − i| share ℓ, so the table is built diagonal by
//! diagonal: C(i, i+m) = E_i + t_i·C(i+1, i+m) and C(i+1, i+m) = C(i+1, i+1+m) −
//! T(i+1, i+m)·E_{i+m}, with T from prefix sums of κ̄. That is O(n²) exponentials
//! (two per entry), not O(n³); the subtraction is of non-negative terms bounded by 1,
//! so its rounding stays at the 1e-16 level and is clamped at 0.
//!
//! Output per entry, as the `classify` hook passes it on: straight colour C/α and the
//! opacity per reference step α₀ = 1 − (1 − α)^(1/d) = 1 − exp(−τ/d). The core's
//! opacity correction 1 − (1 − α₀)^(step/Δs0) gives back α exactly where the ray's
//! step equals the slice spacing (orthographic views); in perspective the step grows
//! off-axis by 1/cos and the segment's opacity is corrected as a homogeneous one.
//! Colour inside the segment is still that of length d: a documented approximation
//! (≤ 1/cos² − 1 relative change of the self-attenuation, < 2% at 8° off-axis).
//!
//! Shading point. A second table holds, per entry, the opacity centroid of the slab:
//! the mean depth, as a fraction of the slab from its front, of where its opacity is
//! taken up (weights T(0, t)·κ(t), i.e. each cell's share of α). Shading there instead
//! of at the front sample removes the O(d) offset between where the gradient is read
//! and where the surface is (`shade_at: centroid`, [`crate::classify_tf1d`]). Inside
//! a cell crossed with optical depth τ the centroid of κ·e^{−κt} is
//! 1/τ − e^{−τ}/(1 − e^{−τ}) of the cell (½ for a thin cell); the recursion carries
//! Σ T·(1 − t_k)·(k + that) beside the colour. This extension is ours: Engel et al.
//! shade at the slice samples and interpolate.

use glam::DVec4;

/// Extinction cap per voxel: opacity 1 becomes 1 − 1e-9 per voxel.
const KAPPA_MAX: f64 = 20.723_265_836_946_41; // −ln(1e-9)

/// A pre-integration table: `n × n` entries, front value along x (fastest), back
/// value along y. Each entry is straight RGB and the opacity per reference step.
#[derive(Debug, Clone, PartialEq)]
pub struct PreintTable {
    pub n: usize,
    pub entries: Vec<[f64; 4]>,
    /// The slab's opacity centroid per entry, as a fraction of the slab from its front.
    pub depth: Vec<f64>,
}

/// Builds the table for a baked TF (`lut`: straight RGBA per voxel at x_i = i/(n−1)),
/// an opacity scale (applied as in post-classification: min(a·scale, 1)) and the
/// segment length `d` in voxels (the slice spacing).
pub fn build(lut: &[[f32; 4]], opacity_scale: f64, d: f64) -> PreintTable {
    let n = lut.len();
    let d = if d.is_finite() && d > 0.0 { d } else { 1.0 };
    let (alpha, kappa, color) = nodes(lut, opacity_scale);
    let mut entries = vec![[0.0; 4]; n * n];
    let mut depth = vec![0.5; n * n];
    if n == 0 {
        return PreintTable { n, entries, depth };
    }
    // diagonal: homogeneous segments
    for i in 0..n {
        let tau = kappa[i] * d;
        let rgb = color[i].map(|v| v.clamp(0.0, 1.0));
        entries[i * n + i] = [rgb[0], rgb[1], rgb[2], 1.0 - (-tau / d).exp()];
        depth[i * n + i] = cell_centroid(tau);
    }
    // ascending (front < back) from the arrays as they are; descending from the
    // reversed arrays, mapped back
    let ascending =
        |alpha: &[f64], color: &[[f64; 3]], put: &mut dyn FnMut(usize, usize, [f64; 4], f64)| {
            let cells = cells(alpha, color);
            let mut prefix = vec![0.0; n];
            for k in 1..n {
                prefix[k] = prefix[k - 1] + cells[k - 1].0;
            }
            for m in 1..n {
                diagonal(&cells, &prefix, m, d, &mut *put);
            }
        };
    ascending(&alpha, &color, &mut |i, j, e, z| {
        entries[j * n + i] = e;
        depth[j * n + i] = z;
    });
    let ra: Vec<f64> = alpha.iter().rev().copied().collect();
    let rc: Vec<[f64; 3]> = color.iter().rev().copied().collect();
    ascending(&ra, &rc, &mut |i, j, e, z| {
        entries[(n - 1 - j) * n + (n - 1 - i)] = e;
        depth[(n - 1 - j) * n + (n - 1 - i)] = z;
    });
    PreintTable { n, entries, depth }
}

/// Opacity per voxel (scaled, clamped to [0, 1 − 1e-9]), extinction and straight
/// colour of each table node.
type Nodes = (Vec<f64>, Vec<f64>, Vec<[f64; 3]>);

fn nodes(lut: &[[f32; 4]], opacity_scale: f64) -> Nodes {
    let alpha: Vec<f64> = lut
        .iter()
        .map(|c| {
            let a = c[3] as f64 * opacity_scale;
            if a.is_nan() {
                0.0
            } else {
                a.clamp(0.0, 1.0 - 1e-9)
            }
        })
        .collect();
    let kappa = alpha
        .iter()
        .map(|a| (-(1.0 - a).ln()).clamp(0.0, KAPPA_MAX))
        .collect();
    let color = lut
        .iter()
        .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64])
        .collect();
    (alpha, kappa, color)
}

/// Centroid of the absorbed light κ·e^{−κt} over a homogeneous piece crossed with
/// optical depth `tau`, as a fraction of its length: ½ − τ/12 + … for a thin piece,
/// → 1/τ for a thick one.
fn cell_centroid(tau: f64) -> f64 {
    if tau < 1e-4 {
        return 0.5 - tau / 12.0;
    }
    let e = (-tau).exp();
    (1.0 / tau - e / (1.0 - e)).clamp(0.0, 1.0)
}

/// Mean of −ln(1 − a) over a cell where a runs linearly from a0 to a1.
fn mean_extinction(a0: f64, a1: f64) -> f64 {
    let (u0, u1) = (1.0 - a0, 1.0 - a1);
    if (u1 - u0).abs() < 1e-6 {
        return -(0.5 * (u0 + u1)).ln();
    }
    let f = |u: f64| u * u.ln() - u;
    (-(f(u1) - f(u0)) / (u1 - u0)).clamp(0.0, KAPPA_MAX)
}

/// Per cell [x_k, x_{k+1}]: mean extinction and κ-weighted mean colour. The colour is
/// linear in the cell, so its κ-weighted mean is c0 + (c1 − c0)·w with w the centroid
/// of κ over the cell (4-point Gauss–Legendre; the mid-cell colour where κ = 0).
fn cells(alpha: &[f64], color: &[[f64; 3]]) -> Vec<(f64, [f64; 3])> {
    const GAUSS: [(f64, f64); 4] = [
        (0.069_431_844_202_973_7, 0.173_927_422_568_726_9),
        (0.330_009_478_207_571_9, 0.326_072_577_431_273_1),
        (0.669_990_521_792_428_1, 0.326_072_577_431_273_1),
        (0.930_568_155_797_026_3, 0.173_927_422_568_726_9),
    ];
    (0..alpha.len().saturating_sub(1))
        .map(|k| {
            let (a0, a1) = (alpha[k], alpha[k + 1]);
            let mean = mean_extinction(a0, a1);
            let (mut num, mut den) = (0.0, 0.0);
            for (t, w) in GAUSS {
                let kappa = -(1.0 - (a0 + (a1 - a0) * t)).ln();
                num += w * t * kappa;
                den += w * kappa;
            }
            let centroid = if den > 0.0 {
                (num / den).clamp(0.0, 1.0)
            } else {
                0.5
            };
            let c = std::array::from_fn(|c| {
                (color[k][c] + (color[k + 1][c] - color[k][c]) * centroid).clamp(0.0, 1.0)
            });
            (mean, c)
        })
        .collect()
}

fn mean_color(cells: &[(f64, [f64; 3])]) -> [f64; 3] {
    let mut mean = [0.0; 3];
    for cell in cells {
        for (c, v) in mean.iter_mut().enumerate() {
            *v += cell.1[c] / cells.len() as f64;
        }
    }
    mean.map(|v| v.clamp(0.0, 1.0))
}

/// All entries (i, i+m) for one m, from the back of the value axis to the front.
fn diagonal(
    cells: &[(f64, [f64; 3])],
    prefix: &[f64],
    m: usize,
    d: f64,
    put: &mut dyn FnMut(usize, usize, [f64; 4], f64),
) {
    let n = prefix.len();
    let ell = d / m as f64;
    // emission E_k (premultiplied rgb) and transmittance t_k of each cell over ell
    let (emit, trans): (Vec<[f64; 3]>, Vec<f64>) = cells
        .iter()
        .map(|(kappa, c)| {
            let t = (-kappa * ell).exp();
            (c.map(|v| v * (1.0 - t)), t)
        })
        .unzip();
    // where in cell k (absolute, in cells) its absorption is centred
    let centre: Vec<f64> = cells
        .iter()
        .enumerate()
        .map(|(k, (kappa, _))| k as f64 + cell_centroid(kappa * ell))
        .collect();
    let transmit = |a: usize, b: usize| (-(prefix[b] - prefix[a]) * ell).exp();
    // the last window directly; `moment` = Σ T·(1 − t_k)·centre_k over the window
    let last = n - 1 - m;
    let mut acc = [0.0f64; 3];
    let mut moment = 0.0f64;
    for k in (last..last + m).rev() {
        acc = std::array::from_fn(|c| emit[k][c] + trans[k] * acc[c]);
        moment = (1.0 - trans[k]) * centre[k] + trans[k] * moment;
    }
    let mut emit_entry = |i: usize, acc: [f64; 3], moment: f64| {
        let tau = prefix[i + m] - prefix[i]; // optical depth per ell
        let alpha = 1.0 - (-tau * ell).exp();
        let rgb = if alpha > 1e-12 {
            acc.map(|v| (v / alpha).clamp(0.0, 1.0))
        } else {
            // transparent segment: the mean colour of its cells (its limit)
            mean_color(&cells[i..i + m])
        };
        let depth = if alpha > 1e-12 {
            ((moment / alpha - i as f64) / m as f64).clamp(0.0, 1.0)
        } else {
            0.5
        };
        // opacity per reference step: 1 − exp(−τ_total/d) with τ_total = tau·ell
        put(
            i,
            i + m,
            [rgb[0], rgb[1], rgb[2], 1.0 - (-tau / m as f64).exp()],
            depth,
        );
    };
    emit_entry(last, acc, moment);
    for i in (0..last).rev() {
        // drop the back cell of window (i+1, i+1+m), then put cell i in front
        let back = transmit(i + 1, i + m);
        let mid: [f64; 3] = std::array::from_fn(|c| (acc[c] - back * emit[i + m][c]).max(0.0));
        acc = std::array::from_fn(|c| emit[i][c] + trans[i] * mid[c]);
        let mid_moment = (moment - back * (1.0 - trans[i + m]) * centre[i + m]).max(0.0);
        moment = (1.0 - trans[i]) * centre[i] + trans[i] * mid_moment;
        emit_entry(i, acc, moment);
    }
}

impl PreintTable {
    /// Bilinear lookup at (front, back) ∈ [0,1]², texel centres at (i + 0.5)/n and
    /// clamp-to-edge, as `textureSampleLevel(table, linear_clamp, …)`.
    pub fn lookup(&self, front: f64, back: f64) -> DVec4 {
        let n = self.n;
        if n == 0 {
            return DVec4::ZERO;
        }
        DVec4::from_array(vwb_render::tf::bilinear(n, front, back, |x, y| {
            self.entries[y * n + x]
        }))
    }

    /// Bilinear lookup of the opacity centroid (`depth`), as [`PreintTable::lookup`].
    pub fn lookup_depth(&self, front: f64, back: f64) -> f64 {
        let n = self.n;
        if n == 0 {
            return 0.0;
        }
        vwb_render::tf::bilinear(n, front, back, |x, y| [self.depth[y * n + x], 0.0, 0.0, 0.0])[0]
    }

    /// Texel data for an rgba32float or rgba16float texture (n × n).
    pub fn texels_f32(&self) -> Vec<[f32; 4]> {
        self.entries.iter().map(|e| e.map(|v| v as f32)).collect()
    }

    /// The centroid table's texels (in the red channel).
    pub fn depth_texels_f32(&self) -> Vec<[f32; 4]> {
        self.depth.iter().map(|&z| [z as f32, 0.0, 0.0, 0.0]).collect()
    }
}

/// Direct evaluation of one entry and its centroid by compositing its cells one by
/// one (O(m)): the definition the diagonal recursion must reproduce (tests).
#[cfg(test)]
pub fn entry_direct(
    lut: &[[f32; 4]],
    opacity_scale: f64,
    d: f64,
    i: usize,
    j: usize,
) -> ([f64; 4], f64) {
    let n = lut.len();
    let (alpha, kappa, color) = nodes(lut, opacity_scale);
    if i == j {
        let entry = [
            color[i][0],
            color[i][1],
            color[i][2],
            1.0 - (-kappa[i]).exp(),
        ];
        return (entry, cell_centroid(kappa[i] * d));
    }
    let (alpha, color, i, j) = if i < j {
        (alpha, color, i, j)
    } else {
        let ra = alpha.iter().rev().copied().collect();
        let rc = color.iter().rev().copied().collect();
        (ra, rc, n - 1 - i, n - 1 - j)
    };
    let cells = cells(&alpha, &color);
    let m = j - i;
    let ell = d / m as f64;
    let (mut rgb, mut alpha, mut tau, mut moment) = ([0.0f64; 3], 0.0f64, 0.0f64, 0.0f64);
    for (k, cell) in cells[i..j].iter().enumerate() {
        let a = 1.0 - (-cell.0 * ell).exp();
        for (v, c) in rgb.iter_mut().zip(cell.1) {
            *v += (1.0 - alpha) * c * a;
        }
        moment += (1.0 - alpha) * a * (k as f64 + cell_centroid(cell.0 * ell));
        alpha += (1.0 - alpha) * a;
        tau += cell.0;
    }
    let depth = if alpha > 1e-12 {
        (moment / alpha / m as f64).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let straight = if alpha > 1e-12 {
        rgb.map(|v| (v / alpha).clamp(0.0, 1.0))
    } else {
        mean_color(&cells[i..j])
    };
    let entry = [
        straight[0],
        straight[1],
        straight[2],
        1.0 - (-tau / m as f64).exp(),
    ];
    (entry, depth)
}
