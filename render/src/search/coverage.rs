//! Visible-boundary coverage, the genetic search's data-aware objective: how much of
//! each material boundary a TF makes visible, and how little fog it adds.
//!
//! The boundaries are the Kindlmann–Durkin suggestion's ([`crate::suggest`]): the
//! value bins where p(v) gives opacity, grouped into runs of neighbouring bins, a run
//! split where p(v) jumps from the far side of one boundary (p ≥ 0) to the near side
//! of the next (p < 0): one run per boundary. Visibility is a visibility histogram (Correa & Ma 2011): along
//! rays through the volume, each sample of value bin v adds its opacity times the
//! transmittance in front of it to V(v), so that V sums over the bins to the image's
//! opacity. The objective is
//!
//!   C = min(1, V / V₀) · [(1/K) Σ_k min(1, s_k / τ) − f],
//!
//! where V is the mean over rays of the image's opacity (Σ_v V(v)), s_k the share of
//! V given by boundary k's bins, f the share given by values on no boundary (fog), K
//! the number of boundaries, τ = [`COVERED`] (a boundary counts as covered once it
//! gives a tenth of what is seen) and V₀ = [`SHOWN`] (an image that shows less is
//! scaled down). C lies in [−1, 1]; higher is better. Colours do not enter it.
//!
//! Choices the literature leaves open, and ours: rays are orthographic, along each
//! viewpoint's direction through the box's centre, on a square grid over the box's
//! bounding sphere (perspective changes the weights of the rays, not which boundaries
//! are seen); one sample per voxel length at the nearest voxel, so that a genome's
//! histogram is a pass over precomputed bin indices; opacities are the TF's per voxel
//! length, as the renderer's Δs0.
//!
//! 2D TFs (`classify.tf2d`, value × gradient magnitude): each sample also keeps the bin
//! of its gradient magnitude on the TF's axis (central differences at its voxel, times
//! the plugin's `gradient_scale`, [`GRADIENT_BINS`] bins), and a genome's opacity is
//! read at both bins. The boundaries stay the value axis's: a 2D TF covers a boundary
//! when it shows the boundary's values, wherever on the gradient axis it does.

use crate::camera::Camera;
use crate::plugin::PluginInstance;
use crate::search::genome::{Genome, Space};
use crate::slicing::VolumeBox;
use crate::suggest::{SuggestError, SuggestOptions, suggest};
use crate::volume::{Volume, VoxelData};

/// The share of what is visible at which a boundary counts as covered.
pub const COVERED: f64 = 0.1;
/// The mean opacity over the rays at which an image counts as showing something
/// (the rays cover the box's bounding sphere; a cube fills about half of it).
pub const SHOWN: f64 = 0.05;

/// What the objective needs of the data and the viewpoints, computed once per run.
#[derive(Debug, Clone, PartialEq)]
pub struct Coverage {
    /// Value bins.
    bins: usize,
    /// The boundary each bin belongs to (None: no boundary).
    boundary_of: Vec<Option<usize>>,
    /// Boundaries (runs of bins), as bin ranges.
    pub boundaries: Vec<std::ops::Range<usize>>,
    /// Per ray, the value bins of its samples front to back.
    rays: Vec<Vec<u16>>,
    /// For 2D TFs: the scale from |∇f| to the TF's gradient axis, and per ray the
    /// gradient bin ([`GRADIENT_BINS`] over that axis) of each sample.
    gradients: Option<(f64, Vec<Vec<u8>>)>,
}

/// Bins along a 2D TF's gradient-magnitude axis.
pub const GRADIENT_BINS: usize = 64;

impl Coverage {
    /// What a stack's TF needs of the model: `None` for `classify.tf1d`; for
    /// `classify.tf2d` its `gradient_scale` (|∇f| per voxel to the table's gradient
    /// axis). A 2D TF over the data axis (`y_axis: data`) has no gradient axis to read
    /// and is refused with that reason.
    pub fn gradient_scale_of(stack: &[PluginInstance]) -> Result<Option<f64>, String> {
        match Space::of_stack(stack)? {
            Space::Tf1d => Ok(None),
            Space::Tf2d => {
                let tf = stack
                    .iter()
                    .find(|i| i.enabled && i.plugin.id() == Space::Tf2d.plugin_id())
                    .expect("of_stack found it");
                if tf.params.enumeration("y_axis") == "data" {
                    return Err(
                        "boundary coverage reads a 2D TF over value × gradient magnitude; \
                                this classify.tf2d reads the data along y (y_axis: data)"
                            .into(),
                    );
                }
                Ok(Some(tf.params.float("gradient_scale") as f64))
            }
        }
    }

    /// The model for a stack's TF plugin ([`Coverage::gradient_scale_of`]).
    pub fn for_stack(
        volume: &Volume,
        viewpoints: &[Camera],
        rays: u32,
        stack: &[PluginInstance],
    ) -> Result<Coverage, String> {
        Self::build(volume, viewpoints, rays, Self::gradient_scale_of(stack)?)
    }

    /// The gradient scale the model was built for (`None`: 1D TFs only).
    pub fn gradient_scale(&self) -> Option<f64> {
        self.gradients.as_ref().map(|(s, _)| *s)
    }

    /// The boundaries of `volume` and `rays`² rays from each viewpoint, for 1D TFs.
    /// Fails when the suggestion finds no boundary (the objective would have nothing to
    /// cover).
    pub fn new(volume: &Volume, viewpoints: &[Camera], rays: u32) -> Result<Coverage, String> {
        Self::build(volume, viewpoints, rays, None)
    }

    /// With `gradient_scale`, each sample also keeps its gradient magnitude's bin on a
    /// 2D TF's axis: |∇f| at the sample's voxel as `classify.tf2d`'s pre-pass computes
    /// it ([`crate::tf2d::voxel_gradient`]), times the scale, clamped to [0, 1].
    fn build(
        volume: &Volume,
        viewpoints: &[Camera],
        rays: u32,
        gradient_scale: Option<f64>,
    ) -> Result<Coverage, String> {
        let s =
            suggest(volume, &SuggestOptions::default()).map_err(|e: SuggestError| e.to_string())?;
        if !s.found() {
            return Err(format!(
                "volume '{}': the boundary suggestion finds no boundary, so visible-boundary \
                 coverage has nothing to cover",
                volume.name
            ));
        }
        let bins = s.alpha.len();

        // runs of bins with opacity, split where p(v) jumps from the far side of one
        // boundary (p ≥ 0) to the near side of the next (p < 0)
        let mut boundaries: Vec<std::ops::Range<usize>> = Vec::new();
        for (i, &a) in s.alpha.iter().enumerate() {
            if a > 0.0 {
                let next_boundary = i > 0 && s.p[i - 1] >= 0.0 && s.p[i] < 0.0;
                match boundaries.last_mut() {
                    Some(r) if r.end == i && !next_boundary => r.end = i + 1,
                    _ => boundaries.push(i..i + 1),
                }
            }
        }
        let mut boundary_of = vec![None; bins];
        for (k, r) in boundaries.iter().enumerate() {
            for b in r.clone() {
                boundary_of[b] = Some(k);
            }
        }
        let scalars = volume.normalized_scalars();
        let d = volume.dims.map(|n| n as usize);
        let vbox = VolumeBox::new(volume.dims, volume.spacing);
        let size = vbox.max - vbox.min;
        let radius = vbox.max.length();
        let n = rays.max(1);
        let mut all = Vec::with_capacity(viewpoints.len() * (n * n) as usize);
        let mut all_g: Vec<Vec<u8>> = Vec::new();
        let gradient_bin = |at: [usize; 3], scale: f64| {
            let g = crate::tf2d::voxel_gradient(&scalars, d, at) as f64 * scale;
            if g.is_finite() {
                ((g.clamp(0.0, 1.0) * GRADIENT_BINS as f64) as usize).min(GRADIENT_BINS - 1) as u8
            } else {
                0
            }
        };
        for cam in viewpoints {
            let (forward, right, up) = cam.basis();
            for j in 0..n {
                for i in 0..n {
                    let x = ((i as f32 + 0.5) / n as f32 * 2.0 - 1.0) * radius;
                    let y = (1.0 - (j as f32 + 0.5) / n as f32 * 2.0) * radius;
                    let start = right * x + up * y - forward * radius;
                    let mut samples = Vec::new();
                    let mut grads = Vec::new();
                    let mut t = 0.0;
                    while t <= 2.0 * radius {
                        let p = start + forward * t;
                        t += vbox.voxel;
                        let tex = (p - vbox.min) / size;
                        if tex.min_element() < 0.0 || tex.max_element() >= 1.0 {
                            continue;
                        }
                        let v = [tex.x, tex.y, tex.z];
                        let idx: [usize; 3] =
                            std::array::from_fn(|a| ((v[a] * d[a] as f32) as usize).min(d[a] - 1));
                        let s = scalars[idx[0] + d[0] * (idx[1] + d[1] * idx[2])];
                        if s.is_finite() {
                            samples.push(((s as f64 * bins as f64) as usize).min(bins - 1) as u16);
                            if let Some(scale) = gradient_scale {
                                grads.push(gradient_bin(idx, scale));
                            }
                        }
                    }
                    all.push(samples);
                    if gradient_scale.is_some() {
                        all_g.push(grads);
                    }
                }
            }
        }
        Ok(Coverage {
            bins,
            boundary_of,
            boundaries,
            rays: all,
            gradients: gradient_scale.map(|scale| (scale, all_g)),
        })
    }

    /// The visibility histogram of a genome: per value bin, the mean over rays of
    /// opacity × transmittance. A 2D genome's opacity is read at each sample's value
    /// and gradient bins; on a model built without gradients (a 1D stack's) it shows
    /// nothing.
    pub fn visibility(&self, g: &Genome) -> Vec<f64> {
        let bin = |b: usize, n: usize| (b as f64 + 0.5) / n as f64;
        // opacity per (value bin, gradient bin), one gradient bin for a 1D TF
        let (alpha, per_value, grads): (Vec<f64>, usize, Option<&Vec<Vec<u8>>>) = match g {
            Genome::Tf1d(_) => {
                let curve = g.to_curve().expect("1D");
                let a = (0..self.bins)
                    .map(|b| curve.eval(bin(b, self.bins))[3].clamp(0.0, 1.0))
                    .collect();
                (a, 1, None)
            }
            Genome::Tf2d(p) => {
                let Some((_, grads)) = &self.gradients else {
                    return vec![0.0; self.bins];
                };
                let tf = crate::tf2d::Tf2d {
                    primitives: p.clone(),
                };
                let a = (0..self.bins * GRADIENT_BINS)
                    .map(|k| {
                        let (v, gb) = (k / GRADIENT_BINS, k % GRADIENT_BINS);
                        tf.eval(bin(v, self.bins), bin(gb, GRADIENT_BINS))[3].clamp(0.0, 1.0)
                    })
                    .collect();
                (a, GRADIENT_BINS, Some(grads))
            }
        };
        let mut v = vec![0.0; self.bins];
        for (r, ray) in self.rays.iter().enumerate() {
            let mut t = 1.0;
            for (i, &b) in ray.iter().enumerate() {
                let gb = grads.map_or(0, |g| g[r][i] as usize);
                let a = alpha[b as usize * per_value + gb];
                v[b as usize] += a * t;
                t *= 1.0 - a;
                if t < 1e-3 {
                    break;
                }
            }
        }
        let n = self.rays.len().max(1) as f64;
        v.iter_mut().for_each(|x| *x /= n);
        v
    }

    /// The objective C of a genome (higher is better), with the per-boundary shares
    /// of what is visible and the fog's share.
    pub fn objective(&self, g: &Genome) -> (f64, Vec<f64>, f64) {
        let v = self.visibility(g);
        let seen: f64 = v.iter().sum();
        if seen <= 0.0 {
            return (0.0, vec![0.0; self.boundaries.len()], 0.0);
        }
        let mut shares = vec![0.0; self.boundaries.len()];
        let mut fog = 0.0;
        for (b, &x) in v.iter().enumerate() {
            match self.boundary_of[b] {
                Some(k) => shares[k] += x / seen,
                None => fog += x / seen,
            }
        }
        let k = shares.len().max(1) as f64;
        let covered: f64 = shares.iter().map(|s| (s / COVERED).min(1.0)).sum::<f64>() / k;
        let shown = (seen / SHOWN).min(1.0);
        (shown * (covered - fog), shares, fog)
    }
}

/// A test volume with two boundaries: nested balls of 100 and 200 on 0 (u8, `n`³),
/// each edge a ramp two voxels wide, as a scanner's blur gives.
pub fn nested_balls(n: usize) -> Volume {
    let c = (n as f64 - 1.0) / 2.0;
    let (outer, inner) = (0.4 * n as f64, 0.2 * n as f64);
    let mut data = vec![0u8; n * n * n];
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let r = ((x as f64 - c).powi(2) + (y as f64 - c).powi(2) + (z as f64 - c).powi(2))
                    .sqrt();
                let step = |edge: f64| ((edge + 1.0 - r) / 2.0).clamp(0.0, 1.0);
                data[x + n * (y + n * z)] = (100.0 * step(outer) + 100.0 * step(inner)) as u8;
            }
        }
    }
    let d = n as u32;
    Volume::new("nested balls", [d; 3], 1, [1.0; 3], VoxelData::U8(data)).expect("a valid volume")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::search::gallery::viewpoints;
    use crate::tf::{PrimitiveShape, TfPrimitive};

    fn balls() -> Volume {
        nested_balls(40)
    }

    fn gauss(centre: f32, width: f32, height: f32) -> TfPrimitive {
        TfPrimitive {
            shape: PrimitiveShape::Gaussian,
            centre,
            width,
            height,
            color: [1.0; 3],
        }
    }

    #[test]
    fn coverage_rewards_every_boundary_seen_and_punishes_fog() {
        let v = balls();
        let cams = viewpoints(&Camera::default(), 3);
        let c = Coverage::new(&v, &cams, 24).unwrap();
        assert!(c.boundaries.len() >= 2, "{:?}", c.boundaries);
        let centre = |r: &std::ops::Range<usize>| (r.start + r.end) as f32 / 2.0 / c.bins as f32;
        let (b0, b1) = (centre(&c.boundaries[0]), centre(&c.boundaries[1]));
        // the visibility histogram sums to the image's opacity, at most 1
        let both = Genome::Tf1d(vec![gauss(b0, 0.03, 0.05), gauss(b1, 0.03, 0.5)]);
        let vis: f64 = c.visibility(&both).iter().sum();
        assert!(vis > 0.0 && vis <= 1.0 + 1e-9, "{vis}");
        let (both_c, shares, fog) = c.objective(&both);
        assert!(shares.iter().take(2).all(|&s| s > 0.0), "{shares:?}");
        // one boundary only covers half as much
        let one = Genome::Tf1d(vec![gauss(b0, 0.03, 0.05)]);
        let (one_c, ..) = c.objective(&one);
        assert!(both_c > one_c, "{both_c} vs {one_c}");
        // an opaque outer shell hides the inner boundary
        let shell = Genome::Tf1d(vec![gauss(b0, 0.03, 1.0), gauss(b1, 0.03, 0.5)]);
        let (_, hidden, _) = c.objective(&shell);
        assert!(hidden[1] < shares[1], "{hidden:?} vs {shares:?}");
        // fog: opacity on the outer ball's plateau (100 of 200), on no boundary
        let foggy = Genome::Tf1d(vec![
            gauss(b0, 0.03, 0.05),
            gauss(b1, 0.03, 0.5),
            gauss(0.5, 0.02, 0.05),
        ]);
        let (fog_c, _, f) = c.objective(&foggy);
        assert!(
            f > fog && fog_c < both_c,
            "fog {f} vs {fog}: {fog_c} vs {both_c}"
        );
        // a 2D TF: triangles over each boundary's values (the boundary's voxels have
        // large gradients) cover both; a rectangle at small gradients over the outer
        // ball's plateau adds fog; a 1D model shows a 2D genome nothing
        use crate::tf2d::{Primitive2d, Shape2d};
        let c2 = Coverage::build(&v, &cams, 24, Some(4.0)).unwrap();
        assert_eq!(c2.boundaries, c.boundaries);
        assert_eq!(c2.gradient_scale(), Some(4.0));
        let tri = |centre: f32, a: f32| Primitive2d {
            shape: Shape2d::Triangle,
            centre: [centre, 0.0],
            size: [0.1, 1.0],
            color: [1.0, 1.0, 1.0, a],
        };
        let both2 = Genome::Tf2d(vec![tri(b0, 0.1), tri(b1, 0.6)]);
        let (both2_c, shares2, fog2) = c2.objective(&both2);
        assert!(shares2.iter().take(2).all(|&s| s > 0.0), "{shares2:?}");
        let one2 = Genome::Tf2d(vec![tri(b0, 0.1)]);
        assert!(c2.objective(&one2).0 < both2_c);
        let plateau = Primitive2d {
            shape: Shape2d::Rectangle,
            centre: [0.5, 0.02],
            size: [0.1, 0.04],
            color: [1.0, 1.0, 1.0, 0.05],
        };
        let foggy2 = Genome::Tf2d(vec![tri(b0, 0.1), tri(b1, 0.6), plateau]);
        let (fog2_c, _, f2) = c2.objective(&foggy2);
        assert!(f2 > fog2 && fog2_c < both2_c, "fog {f2} vs {fog2}");
        assert!(c.visibility(&both2).iter().all(|&x| x == 0.0));

        // nothing to cover on a constant volume
        let flat = Volume::new("flat", [8; 3], 1, [1.0; 3], VoxelData::U8(vec![7; 512])).unwrap();
        assert!(Coverage::new(&flat, &cams, 8).is_err());
    }
}
