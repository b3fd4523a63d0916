//! Data-driven transfer-function suggestion (Kindlmann and Durkin 1998, "Semi-automatic
//! generation of transfer functions for direct volume rendering").
//!
//! 1. The **histogram volume**: a 3D histogram of every interior voxel over its value
//!    v, gradient magnitude f' = |∇f| and second directional derivative along the
//!    gradient f'' = ĝᵀ H ĝ (central differences in voxel index units, on the
//!    normalised scalar).
//! 2. Per value bin, the mean first and second derivative g(v) and h(v) from the
//!    histogram volume.
//! 3. The **boundary function** p(v) = −σ²·h(v)/g(v): the signed distance (voxels) of a
//!    sample with value v from the nearest boundary, for boundaries blurred by a
//!    Gaussian of width σ. σ = g_max/(√e·h_max) (K&D §4, from the ideal boundary
//!    profile), with g_max and h_max the maxima of g(v) and |h(v)|.
//! 4. The **opacity** α(v) = α_max·b(p(v)), with the boundary emphasis function b a tent
//!    of half width `thickness` voxels around p = 0. Values whose mean gradient is below
//!    `min_gradient`·g_max are not on any boundary and get α = 0.
//!
//! Choices where the paper leaves room: derivatives in voxel index units (the spacing
//! is ignored, as K&D work on the sampled grid); ranges of f' and f'' are clipped at
//! their 99.5th percentile so that a few outliers do not squeeze the histogram; the
//! suggested curve has 128 evenly spaced points and a neutral colour ramp.

use rayon::prelude::*;

use crate::tf::{TfCurve, TfPoint};
use crate::volume::Volume;

/// Options of [`suggest`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SuggestOptions {
    /// Value bins of the histogram volume.
    pub value_bins: usize,
    /// Bins along f' and f''.
    pub derivative_bins: usize,
    /// Half width (voxels) of the boundary emphasis tent.
    pub thickness: f64,
    /// Peak opacity of the suggestion.
    pub max_opacity: f64,
    /// Share of g_max below which a value is not on a boundary.
    pub min_gradient: f64,
    /// Gaussian pre-filter width σ (voxels) applied before the derivatives, against
    /// noise (0: none).
    pub smoothing: f64,
    /// A value is on a boundary only where its mean gradient exceeds this multiple of
    /// the noise floor (the median gradient magnitude over all interior voxels, which
    /// lie mostly inside homogeneous regions).
    pub noise_factor: f64,
    /// Leave the values of the background and its noise transparent ([`background`]).
    pub drop_background: bool,
}

impl SuggestOptions {
    /// The suggestion as it was before the noise handling: no pre-filter, no noise
    /// floor, the background kept (for measuring the fog it left).
    pub fn unfiltered() -> Self {
        Self {
            smoothing: 0.0,
            noise_factor: 0.0,
            drop_background: false,
            ..Self::default()
        }
    }
}

impl Default for SuggestOptions {
    fn default() -> Self {
        Self {
            value_bins: 256,
            derivative_bins: 64,
            thickness: 1.0,
            max_opacity: 0.6,
            min_gradient: 0.05,
            smoothing: 1.0,
            noise_factor: 3.0,
            drop_background: true,
        }
    }
}

/// The histogram volume over (v, f', f'').
#[derive(Debug, Clone, PartialEq)]
pub struct HistogramVolume {
    pub value_bins: usize,
    pub derivative_bins: usize,
    /// f' range [0, g_hi] covered by the bins (values above land in the last bin).
    /// `derivative_bins` is odd, so that f'' = 0 falls on a bin centre.
    pub g_hi: f64,
    /// f'' range [−h_hi, h_hi].
    pub h_hi: f64,
    /// Counts, value fastest, then f', then f''.
    pub counts: Vec<u32>,
}

impl HistogramVolume {
    fn index(&self, v: usize, g: usize, h: usize) -> usize {
        (h * self.derivative_bins + g) * self.value_bins + v
    }

    /// Count in bin (v, g, h).
    pub fn count(&self, v: usize, g: usize, h: usize) -> u32 {
        self.counts[self.index(v, g, h)]
    }

    /// Centre of f' bin `g`.
    pub fn g_centre(&self, g: usize) -> f64 {
        (g as f64 + 0.5) / self.derivative_bins as f64 * self.g_hi
    }

    /// Centre of f'' bin `h`.
    pub fn h_centre(&self, h: usize) -> f64 {
        ((h as f64 + 0.5) / self.derivative_bins as f64 * 2.0 - 1.0) * self.h_hi
    }
}

/// What [`suggest`] found, for the UI's plots and for tests.
#[derive(Debug, Clone, PartialEq)]
pub struct Suggestion {
    pub histogram: HistogramVolume,
    /// Mean f' per value bin (0 where the bin is empty).
    pub g: Vec<f64>,
    /// Mean f'' per value bin.
    pub h: Vec<f64>,
    /// Boundary function p(v) per value bin (voxels; NaN where no boundary).
    pub p: Vec<f64>,
    /// Boundary blur σ (voxels).
    pub sigma: f64,
    /// The noise floor: the median gradient magnitude over the interior voxels (after
    /// the pre-filter), in normalised value per voxel.
    pub noise_floor: f64,
    /// The background, where found: the value of the lowest histogram peak (normalised)
    /// and the value below which the suggestion is transparent ([`background`]).
    pub background: Option<(f64, f64)>,
    /// The pre-filter width (voxels) the derivatives were taken at.
    pub smoothing: f64,
    /// Opacity per value bin.
    pub alpha: Vec<f64>,
    /// The suggested transfer function.
    pub curve: TfCurve,
}

impl Suggestion {
    /// The value bins on a boundary (α > 0).
    pub fn boundary_bins(&self) -> usize {
        self.alpha.iter().filter(|&&a| a > 0.0).count()
    }

    /// Whether some value is on a boundary (else the suggestion is transparent).
    pub fn found(&self) -> bool {
        self.boundary_bins() > 0
    }

    /// The middle of the first boundary above the background: the first value above
    /// the background peak (0 without one) where p(v) crosses from negative to
    /// positive (K&D: the sign of −h/g flips at a boundary's middle value).
    pub fn first_boundary(&self) -> Option<f64> {
        let n = self.p.len();
        let start = self
            .background
            .map_or(1, |(peak, _)| ((peak * n as f64) as usize + 1).max(1));
        (start..n)
            .find(|&i| self.p[i - 1] < 0.0 && self.p[i] >= 0.0)
            .map(|i| i as f64 / n as f64)
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SuggestError {
    #[error(
        "volume '{0}' is smaller than 3 voxels along an axis: no interior voxel has central differences"
    )]
    TooSmall(String),
    #[error("volume '{0}' is a vector volume; suggestions need scalars")]
    NotScalar(String),
    #[error("invalid option {0}")]
    BadOption(String),
    #[error(
        "volume '{name}' is degenerate: {reason}; it has no boundaries to suggest a transfer \
         function from"
    )]
    Degenerate { name: String, reason: String },
    #[error(
        "volume '{name}': the suggestion needs about {bytes} bytes of working memory \
         ({voxels} interior voxels), more than {available} bytes are available"
    )]
    OutOfMemory {
        name: String,
        bytes: u64,
        voxels: u64,
        available: u64,
    },
}

impl SuggestOptions {
    /// Checks every option; the error names the option, its value and the valid range.
    pub fn check(&self) -> Result<(), SuggestError> {
        let bad = |name: &str, value: String, want: &str| {
            Err(SuggestError::BadOption(format!(
                "{name} = {value}: must be {want}"
            )))
        };
        if self.value_bins < 2 {
            return bad("value_bins", self.value_bins.to_string(), "at least 2");
        }
        if self.derivative_bins < 2 {
            return bad(
                "derivative_bins",
                self.derivative_bins.to_string(),
                "at least 2",
            );
        }
        if !(self.thickness.is_finite() && self.thickness > 0.0) {
            return bad(
                "thickness",
                self.thickness.to_string(),
                "a finite number > 0 (voxels)",
            );
        }
        if !(0.0..=1.0).contains(&self.max_opacity) {
            return bad(
                "max_opacity",
                self.max_opacity.to_string(),
                "a number in [0, 1]",
            );
        }
        if !(0.0..1.0).contains(&self.min_gradient) {
            return bad(
                "min_gradient",
                self.min_gradient.to_string(),
                "a number in [0, 1)",
            );
        }
        if !(self.smoothing.is_finite() && (0.0..=8.0).contains(&self.smoothing)) {
            return bad(
                "smoothing",
                self.smoothing.to_string(),
                "a number in [0, 8] (voxels)",
            );
        }
        if !(self.noise_factor.is_finite() && self.noise_factor >= 0.0) {
            return bad(
                "noise_factor",
                self.noise_factor.to_string(),
                "a finite number ≥ 0",
            );
        }
        Ok(())
    }
}

/// Bins of the value histogram [`background`] reads: coarse enough that integer data
/// over a short range (u8 over 0–202 in the MRI demo) leaves no empty bins between
/// filled ones.
const BACKGROUND_BINS: usize = 64;

/// The background of a volume from its value histogram ([`BACKGROUND_BINS`] bins of the
/// normalised scalars `s`, a 3-bin running mean): the lowest peak that holds at least
/// 5 % of the finite voxels (air in CT and MRI, the dark of a micrograph, a fill value),
/// and where it ends: 2.6 half widths at half maximum above the peak (measured on its
/// upper side; for a Gaussian peak, where it falls to 1 %), or earlier where the count
/// falls below 1 % of the peak's or the histogram stops falling (a valley). Returns
/// (peak, end) as normalised values; None when no peak holds 5 %. Values below the end
/// are noise about the background, not a boundary: the suggestion leaves them
/// transparent (its fog otherwise).
pub fn background(s: &[f32]) -> Option<(f64, f64)> {
    let bins = BACKGROUND_BINS;
    let mut counts = vec![0u64; bins];
    for v in s.iter().filter(|v| v.is_finite()) {
        counts[((v.clamp(0.0, 1.0) * bins as f32) as usize).min(bins - 1)] += 1;
    }
    let total: u64 = counts.iter().sum();
    let smooth: Vec<f64> = (0..bins)
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(bins - 1));
            counts[a..=b].iter().sum::<u64>() as f64 / (b - a + 1) as f64
        })
        .collect();
    let peak = (0..bins).find(|&i| {
        let c = smooth[i];
        c >= 0.05 * total as f64 / 3.0
            && (i == 0 || c >= smooth[i - 1])
            && (i + 1 == bins || c >= smooth[i + 1])
    })?;
    let mut half = peak + 1;
    while half < bins && smooth[half] >= 0.5 * smooth[peak] {
        half += 1;
    }
    let mut end = peak + 1;
    while end < bins && smooth[end] >= 0.01 * smooth[peak] && smooth[end] <= smooth[end - 1] {
        end += 1;
    }
    let at = |i: f64| i / bins as f64;
    let end = (end as f64).min(peak as f64 + 2.6 * (half - peak) as f64);
    Some((at(peak as f64 + 0.5), at(end)))
}

/// An empty vector with room for `n` values, or `None` when it cannot be allocated.
fn try_with_capacity<T>(n: usize) -> Option<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).ok()?;
    Some(v)
}

/// Value, f' and f'' of one interior voxel, or None where a neighbour is not finite.
fn derivatives(s: &[f32], d: [usize; 3], x: usize, y: usize, z: usize) -> Option<[f64; 3]> {
    let at = |x: usize, y: usize, z: usize| s[(z * d[1] + y) * d[0] + x] as f64;
    let c = at(x, y, z);
    let g = [
        0.5 * (at(x + 1, y, z) - at(x - 1, y, z)),
        0.5 * (at(x, y + 1, z) - at(x, y - 1, z)),
        0.5 * (at(x, y, z + 1) - at(x, y, z - 1)),
    ];
    let hxx = at(x + 1, y, z) - 2.0 * c + at(x - 1, y, z);
    let hyy = at(x, y + 1, z) - 2.0 * c + at(x, y - 1, z);
    let hzz = at(x, y, z + 1) - 2.0 * c + at(x, y, z - 1);
    let hxy = 0.25
        * (at(x + 1, y + 1, z) - at(x + 1, y - 1, z) - at(x - 1, y + 1, z) + at(x - 1, y - 1, z));
    let hxz = 0.25
        * (at(x + 1, y, z + 1) - at(x + 1, y, z - 1) - at(x - 1, y, z + 1) + at(x - 1, y, z - 1));
    let hyz = 0.25
        * (at(x, y + 1, z + 1) - at(x, y + 1, z - 1) - at(x, y - 1, z + 1) + at(x, y - 1, z - 1));
    let gm2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
    let hg = [
        hxx * g[0] + hxy * g[1] + hxz * g[2],
        hxy * g[0] + hyy * g[1] + hyz * g[2],
        hxz * g[0] + hyz * g[1] + hzz * g[2],
    ];
    let second = if gm2 > 1e-24 {
        (g[0] * hg[0] + g[1] * hg[1] + g[2] * hg[2]) / gm2
    } else {
        0.0
    };
    let r = [c, gm2.sqrt(), second];
    r.iter().all(|v| v.is_finite()).then_some(r)
}

/// The `q`-quantiles of `v` (0 for an empty one), in the order given; reorders `v`.
fn percentiles<const N: usize>(v: &mut [f64], q: [f64; N]) -> [f64; N] {
    q.map(|q| {
        if v.is_empty() {
            return 0.0;
        }
        let k = ((v.len() - 1) as f64 * q).round() as usize;
        let (_, x, _) = v.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
        *x
    })
}

/// `s` (x fastest, dims `d`) filtered by a Gaussian of width `sigma` voxels along each
/// axis in turn (radius ⌈3σ⌉, clamped at the faces). Non-finite voxels take no part:
/// each output is the weighted mean of its finite neighbours (NaN where it has none).
fn gaussian_smooth(s: &[f32], d: [usize; 3], sigma: f64) -> Vec<f32> {
    let r = (3.0 * sigma).ceil() as isize;
    let w: Vec<f64> = (-r..=r)
        .map(|i| (-0.5 * (i as f64 / sigma).powi(2)).exp())
        .collect();
    let mut cur = s.to_vec();
    for axis in 0..3 {
        let stride = [1, d[0], d[0] * d[1]][axis];
        let n = d[axis] as isize;
        let src = cur;
        cur = (0..src.len())
            .into_par_iter()
            .map(|i| {
                let pos = ((i / stride) % d[axis]) as isize;
                let (mut sum, mut weight) = (0.0, 0.0);
                for (k, wk) in (-r..=r).zip(&w) {
                    let p = (pos + k).clamp(0, n - 1);
                    let v = src[(i as isize + (p - pos) * stride as isize) as usize];
                    if v.is_finite() {
                        sum += wk * v as f64;
                        weight += wk;
                    }
                }
                if weight > 0.0 {
                    (sum / weight) as f32
                } else {
                    f32::NAN
                }
            })
            .collect();
    }
    cur
}

/// Largest pre-filter width (voxels) [`suggest`] widens to.
const MAX_SMOOTHING: f64 = 4.0;

/// Builds the histogram volume and the suggestion for a scalar volume. Where no value
/// is on a boundary at the pre-filter width `opts.smoothing`, the width is doubled (up to
/// [`MAX_SMOOTHING`] voxels): low-contrast boundaries in noisy data (a tomogram) stand
/// out of the noise only once it is averaged down. [`Suggestion::smoothing`] says which
/// width gave the result; with none, the suggestion is transparent and
/// [`Suggestion::found`] false.
pub fn suggest(volume: &Volume, opts: &SuggestOptions) -> Result<Suggestion, SuggestError> {
    if volume.components != 1 {
        return Err(SuggestError::NotScalar(volume.name.clone()));
    }
    opts.check()?;
    if let Some(reason) = crate::validate::degenerate_reason(volume) {
        return Err(SuggestError::Degenerate {
            name: volume.name.clone(),
            reason,
        });
    }
    let d = volume.dims.map(|v| v as usize);
    if d.iter().any(|&n| n < 3) {
        return Err(SuggestError::TooSmall(volume.name.clone()));
    }
    // working memory: the normalised scalars and their filtered copy (2 × 4 bytes per
    // voxel), (v, f', f'') per interior voxel (24 bytes, built in parallel parts and
    // then joined: twice) and one percentile column (8 bytes)
    let interior = d.iter().map(|&n| (n - 2) as u64).product::<u64>();
    let need = (volume.voxel_count() as u64)
        .saturating_mul(8)
        .saturating_add(interior.saturating_mul(2 * 24 + 8));
    let oom = |available: u64| SuggestError::OutOfMemory {
        name: volume.name.clone(),
        bytes: need,
        voxels: interior,
        available,
    };
    if let Some(available) = crate::volume::available_memory()
        && need > available
    {
        return Err(oom(available));
    }
    let raw = volume.normalized_scalars();
    let mut o = *opts;
    loop {
        let filtered;
        let s = if o.smoothing > 0.0 {
            filtered = gaussian_smooth(&raw, d, o.smoothing);
            &filtered
        } else {
            &raw
        };
        let found = suggest_filtered(s, d, interior, &o, &oom)?;
        if found.found() || o.smoothing <= 0.0 || o.smoothing * 2.0 > MAX_SMOOTHING {
            return Ok(found);
        }
        o.smoothing *= 2.0;
    }
}

/// [`suggest`] over the normalised scalars `s` (dims `d`, `interior` interior voxels)
/// filtered at `opts.smoothing`.
fn suggest_filtered(
    s: &[f32],
    d: [usize; 3],
    interior: u64,
    opts: &SuggestOptions,
    oom: &dyn Fn(u64) -> SuggestError,
) -> Result<Suggestion, SuggestError> {
    let background = background(s);
    // every interior voxel's (v, f', f''), slab by slab in parallel
    let mut samples: Vec<[f64; 3]> = try_with_capacity(interior as usize).ok_or_else(|| oom(0))?;
    samples.par_extend((1..d[2] - 1).into_par_iter().flat_map_iter(|z| {
        (1..d[1] - 1)
            .flat_map(move |y| (1..d[0] - 1).filter_map(move |x| derivatives(s, d, x, y, z)))
    }));
    let mut column = try_with_capacity(samples.len()).ok_or_else(|| oom(0))?;
    column.extend(samples.iter().map(|r| r[1]));
    let [noise_floor, raw_g_hi] = percentiles(&mut column, [0.5, 0.995]);
    let g_hi = raw_g_hi.max(1e-12);
    column.clear();
    column.extend(samples.iter().map(|r| r[2].abs()));
    let [h_hi] = percentiles(&mut column, [0.995]);
    let h_hi = h_hi.max(1e-12);
    // an odd number of bins puts a bin centre on f'' = 0
    let (vb, db) = (opts.value_bins, opts.derivative_bins | 1);
    let mut histogram = HistogramVolume {
        value_bins: vb,
        derivative_bins: db,
        g_hi,
        h_hi,
        counts: vec![0; vb * db * db],
    };
    let bin = |x: f64, n: usize| ((x * n as f64).floor().max(0.0) as usize).min(n - 1);
    for r in &samples {
        let v = bin(r[0], vb);
        let g = bin(r[1] / g_hi, db);
        let h = bin((r[2] / h_hi + 1.0) * 0.5, db);
        let i = histogram.index(v, g, h);
        histogram.counts[i] = histogram.counts[i].saturating_add(1);
    }
    // mean f' and f'' per value bin, from the histogram volume
    let mut g_mean = vec![0.0; vb];
    let mut h_mean = vec![0.0; vb];
    let mut filled = vec![false; vb];
    let mut bin_counts = vec![0.0f64; vb];
    for v in 0..vb {
        let (mut n, mut gs, mut hs) = (0.0, 0.0, 0.0);
        for h in 0..db {
            for g in 0..db {
                let c = histogram.count(v, g, h) as f64;
                n += c;
                gs += c * histogram.g_centre(g);
                hs += c * histogram.h_centre(h);
            }
        }
        if n > 0.0 {
            g_mean[v] = gs / n;
            h_mean[v] = hs / n;
            filled[v] = true;
        }
        bin_counts[v] = n;
    }
    // a value bin no voxel fell into (quantised data, e.g. u8 over 256 bins or sparse
    // f32 values) takes g and h linearly from its nearest filled neighbours
    fill_gaps(&mut g_mean, &filled);
    fill_gaps(&mut h_mean, &filled);
    // σ from the maxima over value bins that hold enough voxels for a stable mean
    // (a twentieth of an even share): sparse bins at the ends of the range would
    // otherwise set both maxima from a handful of noisy voxels
    let reliable = (samples.len() as f64 / (vb as f64 * 20.0)).max(8.0);
    let max_over = |xs: &[f64]| {
        xs.iter()
            .zip(&bin_counts)
            .filter(|(_, n)| **n >= reliable)
            .map(|(x, _)| x.abs())
            .fold(0.0, f64::max)
    };
    // no variation at all (a constant volume): no boundary anywhere
    let g_max = if raw_g_hi > 1e-9 {
        max_over(&g_mean)
    } else {
        0.0
    };
    let h_max = max_over(&h_mean);
    let sigma = if h_max > 0.0 {
        g_max / (std::f64::consts::E.sqrt() * h_max)
    } else {
        0.0
    };
    let p: Vec<f64> = (0..vb)
        .map(|v| {
            let floor = (opts.min_gradient * g_max).max(opts.noise_factor * noise_floor);
            if g_max > 0.0 && g_mean[v] > floor {
                -sigma * sigma * h_mean[v] / g_mean[v]
            } else {
                f64::NAN
            }
        })
        .collect();
    let transparent_below = match background {
        Some((_, end)) if opts.drop_background => end,
        _ => 0.0,
    };
    let alpha: Vec<f64> = p
        .iter()
        .enumerate()
        .map(|(v, &p)| {
            if p.is_finite() && (v as f64 + 0.5) / vb as f64 >= transparent_below {
                opts.max_opacity * (1.0 - p.abs() / opts.thickness).max(0.0)
            } else {
                0.0
            }
        })
        .collect();
    let curve = curve_from(&alpha);
    Ok(Suggestion {
        histogram,
        g: g_mean,
        h: h_mean,
        p,
        sigma,
        noise_floor,
        background,
        smoothing: opts.smoothing,
        alpha,
        curve,
    })
}

/// Linear interpolation over the bins that are not `filled`, between the nearest filled
/// bins on either side (bins outside the first/last filled one stay as they are).
fn fill_gaps(v: &mut [f64], filled: &[bool]) {
    let known: Vec<usize> = (0..v.len()).filter(|&i| filled[i]).collect();
    for w in known.windows(2) {
        let (a, b) = (w[0], w[1]);
        for i in a + 1..b {
            let t = (i - a) as f64 / (b - a) as f64;
            v[i] = v[a] * (1.0 - t) + v[b] * t;
        }
    }
}

/// 128 evenly spaced points over the per-bin opacity, colour a neutral ramp from warm
/// grey to white.
fn curve_from(alpha: &[f64]) -> TfCurve {
    const POINTS: usize = 128;
    let n = alpha.len();
    TfCurve::new(
        (0..POINTS)
            .map(|i| {
                let x = i as f64 / (POINTS - 1) as f64;
                let f = x * n as f64 - 0.5;
                let j = (f.floor().max(0.0) as usize).min(n - 1);
                let k = (j + 1).min(n - 1);
                let t = (f - j as f64).clamp(0.0, 1.0);
                let a = alpha[j] * (1.0 - t) + alpha[k] * t;
                let c = (0.75 + 0.25 * x) as f32;
                TfPoint {
                    x: x as f32,
                    color: [
                        c,
                        (0.65 + 0.35 * x) as f32,
                        (0.55 + 0.45 * x) as f32,
                        a.clamp(0.0, 1.0) as f32,
                    ],
                }
            })
            .collect(),
    )
}

/// A synthetic tomogram, for tests and measurements: a ball of radius 14 voxels and
/// value `contrast` (its edge a logistic of width 1.5 voxels) on 0, in seeded Gaussian
/// noise of σ 0.1, on 48³ voxels (f32). At contrast 0.15 its boundary is hidden in the
/// noise, as in a low-dose cryo-electron tomogram.
pub fn noisy_ball(contrast: f64) -> Volume {
    let n = 48u32;
    let mut rng = crate::rng::XorShift(0x2545_f491_4f6c_dd1d);
    let mut uniform = || rng.uniform();
    let c = (n as f64 - 1.0) / 2.0;
    let mut v = Vec::with_capacity(n.pow(3) as usize);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let r = ((x as f64 - c).powi(2) + (y as f64 - c).powi(2) + (z as f64 - c).powi(2))
                    .sqrt();
                let ball = contrast / (1.0 + ((r - 14.0) / 1.5).exp());
                // Box–Muller
                let g = (-2.0 * uniform().max(1e-300).ln()).sqrt()
                    * (std::f64::consts::TAU * uniform()).cos();
                v.push((ball + 0.1 * g) as f32);
            }
        }
    }
    Volume::new(
        "noisy ball",
        [n; 3],
        1,
        [1.0; 3],
        crate::volume::VoxelData::F32(v),
    )
    .expect("a valid volume")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::VoxelData;

    /// A ball of value 0.8 in a background of 0.2, the step blurred (logistic of width
    /// ~1.5 voxels): one boundary, whose middle value is 0.5.
    fn blurred_ball() -> Volume {
        let n = 40u32;
        let mut v = Vec::new();
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let c = (n as f64 - 1.0) / 2.0;
                    let r =
                        ((x as f64 - c).powi(2) + (y as f64 - c).powi(2) + (z as f64 - c).powi(2))
                            .sqrt();
                    let t = 1.0 / (1.0 + ((r - 12.0) / 1.5).exp());
                    v.push((0.2 + 0.6 * t) as f32);
                }
            }
        }
        // pin the normalisation to [0, 1] with two corner voxels
        v[0] = 0.0;
        let last = v.len() - 1;
        v[last] = 1.0;
        Volume::new("ball", [n; 3], 1, [1.0; 3], VoxelData::F32(v)).unwrap()
    }

    #[test]
    fn boundary_gets_the_opacity_and_the_plateaus_do_not() {
        let s = suggest(&blurred_ball(), &SuggestOptions::default()).unwrap();
        assert!(s.curve.validate().is_ok());
        let at = |v: f64| s.curve.eval(v)[3];
        // the boundary's middle value is the most opaque
        assert!(at(0.5) > 0.4, "α(0.5) = {}", at(0.5));
        // inside and outside (constant regions) are transparent
        assert!(at(0.2) < 0.05 && at(0.8) < 0.05, "{} {}", at(0.2), at(0.8));
        // p(v) changes sign across the boundary: negative on the low side… per K&D
        // the sign follows −h/g; on a rising profile h > 0 below the middle
        let bin = |v: f64| (v * 256.0) as usize;
        assert!(
            s.p[bin(0.35)] < 0.0 && s.p[bin(0.65)] > 0.0,
            "{} {}",
            s.p[bin(0.35)],
            s.p[bin(0.65)]
        );
        assert!(s.sigma > 0.5 && s.sigma < 5.0, "σ = {}", s.sigma);
        // the histogram volume holds every interior voxel
        let total: u64 = s.histogram.counts.iter().map(|&c| c as u64).sum();
        assert_eq!(total, 38u64.pow(3));
    }

    /// In noise, the unfiltered suggestion marks nearly every value bin as a boundary
    /// (a solid block); the pre-filter, widened until it finds something, marks only
    /// the ball's boundary values. Pure noise has no boundary, and says so.
    #[test]
    fn noise_is_filtered_and_a_boundary_is_found_or_none_is_claimed() {
        let v = noisy_ball(0.15);
        let old = suggest(&v, &SuggestOptions::unfiltered()).unwrap();
        let bins = Suggestion::boundary_bins;
        assert!(bins(&old) > 200, "unfiltered: {} of 256", bins(&old));
        let s = suggest(&v, &SuggestOptions::default()).unwrap();
        assert!(s.found(), "the ball's boundary is found");
        assert!(bins(&s) < 26, "{} of 256 bins", bins(&s));
        assert!(s.smoothing >= 1.0 && s.noise_floor > 0.0);
        // its opaque values lie between the background and the ball (normalised: the
        // background's mean and the ball's, 0.15 apart in a range of about 1.1)
        let (peak, _) = s.background.expect("the noise is the background peak");
        let opaque: Vec<f64> = (0..256)
            .filter(|&i| s.alpha[i] > 0.0)
            .map(|i| (i as f64 + 0.5) / 256.0)
            .collect();
        assert!(
            opaque.iter().all(|&x| x > peak && x < peak + 0.2),
            "{peak} {opaque:?}"
        );
        let nothing = suggest(&noisy_ball(0.0), &SuggestOptions::default()).unwrap();
        assert!(!nothing.found(), "{} bins in pure noise", bins(&nothing));
        assert_eq!(nothing.smoothing, MAX_SMOOTHING);
    }

    /// The background of the MRI demo: the lowest peak (air, values near 0) and its
    /// noise end well below the skin.
    #[test]
    fn the_background_is_the_lowest_peak_and_its_noise() {
        let demo = crate::volume::demo();
        let (peak, end) = background(&demo.normalized_scalars()).unwrap();
        assert!(peak < 0.02 && end > 0.04 && end < 0.12, "{peak} {end}");
        let s = suggest(&demo, &SuggestOptions::default()).unwrap();
        let first = s.first_boundary().expect("the skin");
        assert!(first > end && first < 0.3, "{first}");
        // no background peak in a volume without one
        let ramp: Vec<f32> = (0..1000).map(|i| i as f32 / 999.0).collect();
        assert_eq!(background(&ramp), None);
    }

    #[test]
    fn constant_and_degenerate_volumes_give_clear_results() {
        let flat =
            Volume::new("flat", [8, 8, 8], 1, [1.0; 3], VoxelData::U8(vec![7; 512])).unwrap();
        let e = suggest(&flat, &SuggestOptions::default()).unwrap_err();
        assert!(matches!(e, SuggestError::Degenerate { .. }), "{e}");
        assert!(e.to_string().contains("same value 7"), "{e}");
        let thin = Volume::new(
            "thin",
            [8, 8, 2],
            1,
            [1.0; 3],
            VoxelData::U8((0..128).collect()),
        )
        .unwrap();
        assert_eq!(
            suggest(&thin, &SuggestOptions::default()).unwrap_err(),
            SuggestError::TooSmall("thin".into())
        );
        let mut nan = vec![0.5f32; 512];
        nan[100] = f32::NAN;
        nan[200] = 1.0;
        let v = Volume::new("nan", [8, 8, 8], 1, [1.0; 3], VoxelData::F32(nan)).unwrap();
        let s = suggest(&v, &SuggestOptions::default()).unwrap();
        assert!(s.alpha.iter().all(|a| a.is_finite()));
        assert!(s.curve.validate().is_ok());
        let bad = SuggestOptions {
            thickness: 0.0,
            ..Default::default()
        };
        let e = suggest(&flat, &bad).unwrap_err();
        assert!(matches!(e, SuggestError::BadOption(_)));
        assert_eq!(
            e.to_string(),
            "invalid option thickness = 0: must be a finite number > 0 (voxels)"
        );
    }
}
