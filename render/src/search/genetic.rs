//! Genetic search for a transfer function (He et al. 1996), against a target (the
//! images a known TF gives from the same viewpoints) or toward an image objective
//! (entropy, edge energy, histogram variance of the thumbnails). Every generation renders the whole population from every viewpoint in batched
//! atlases; fitness is the RMS ΔE*uv between a genome's descriptor and the target's
//! (lower is better). Selection is by tournaments of two, with elitism; children blend
//! their parents primitive by primitive and then mutate with a radius that anneals
//! geometrically. Every draw is counter-based on (seed, generation, individual), so a
//! run is bit-reproducible.

use crate::camera::Camera;
use crate::plugin::PluginInstance;
use crate::renderer::{RenderError, Renderer};
use crate::rng::Rng;
use crate::search::gallery::{descriptor, distance, thumbnails, viewpoints};
use crate::search::genome::{Genome, MAX_PRIMITIVES};
use crate::tf::TfPrimitive;

/// Settings of a run.
#[derive(Debug, Clone)]
pub struct GaOptions {
    pub population: usize,
    pub generations: usize,
    /// The best this many survive unchanged.
    pub elite: usize,
    pub seed: u64,
    /// Mutation radius of the first generation, and its factor per generation.
    pub radius: f64,
    pub decay: f64,
    pub tile: u32,
    pub views: usize,
    pub slice_spacing: f32,
    pub max_primitives: usize,
    pub batch: usize,
}

impl Default for GaOptions {
    fn default() -> Self {
        GaOptions {
            population: 32,
            generations: 20,
            elite: 2,
            seed: 1,
            radius: 0.5,
            decay: 0.85,
            tile: 48,
            views: 3,
            slice_spacing: 1.0,
            max_primitives: 3,
            batch: 96,
        }
    }
}

/// What a generation is scored by (lower scores are better).
#[derive(Debug, Clone, PartialEq)]
pub enum Fitness {
    /// RMS ΔE*uv to a target descriptor (the target's views from the run's viewpoints).
    Target(Vec<[f64; 3]>),
    /// An image objective to maximise, averaged over the views (its score is minus it).
    Objective(Objective),
}

/// Image objectives after He et al. (1996), on the thumbnails' L*.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Objective {
    /// Shannon entropy (bits) of the L* histogram (64 bins over 0–100).
    Entropy,
    /// Mean |∇L*| by forward differences: how much edge the image shows.
    EdgeEnergy,
    /// Variance of L* over the pixels: contrast.
    HistogramVariance,
}

impl Objective {
    pub const ALL: [Objective; 3] = [Self::Entropy, Self::EdgeEnergy, Self::HistogramVariance];

    pub fn name(self) -> &'static str {
        match self {
            Self::Entropy => "entropy",
            Self::EdgeEnergy => "edge_energy",
            Self::HistogramVariance => "histogram_variance",
        }
    }

    pub fn from_name(s: &str) -> Option<Objective> {
        Self::ALL.into_iter().find(|o| o.name() == s)
    }

    /// The objective of one view.
    pub fn of(self, img: &crate::metrics::RgbImageF) -> f64 {
        let l: Vec<f64> = img
            .pixels
            .iter()
            .map(|&p| crate::metrics::srgb_to_luv(p)[0])
            .collect();
        let n = l.len().max(1) as f64;
        match self {
            Self::Entropy => {
                let mut bins = [0u64; 64];
                for v in &l {
                    bins[((v / 100.0 * 64.0) as usize).min(63)] += 1;
                }
                -bins
                    .iter()
                    .filter(|&&c| c > 0)
                    .map(|&c| {
                        let p = c as f64 / n;
                        p * p.log2()
                    })
                    .sum::<f64>()
            }
            Self::EdgeEnergy => {
                let (w, h) = (img.width as usize, img.height as usize);
                let mut sum = 0.0;
                for y in 0..h.saturating_sub(1) {
                    for x in 0..w.saturating_sub(1) {
                        let c = l[y * w + x];
                        let (dx, dy) = (l[y * w + x + 1] - c, l[(y + 1) * w + x] - c);
                        sum += (dx * dx + dy * dy).sqrt();
                    }
                }
                sum / n
            }
            Self::HistogramVariance => {
                let mean = l.iter().sum::<f64>() / n;
                l.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n
            }
        }
    }
}

impl Fitness {
    /// The score of a genome's views (lower is better).
    pub fn score(&self, views: &[crate::metrics::RgbImageF]) -> f64 {
        match self {
            Fitness::Target(t) => distance(&descriptor(views), t),
            Fitness::Objective(o) => {
                -views.iter().map(|v| o.of(v)).sum::<f64>() / views.len().max(1) as f64
            }
        }
    }
}

/// One generation's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct Generation {
    pub best: Genome,
    /// The best score: RMS ΔE*uv to the target, or minus the objective.
    pub best_score: f64,
    pub mean_score: f64,
    pub radius: f64,
}

/// The target descriptor: the views of `genome` (the hidden TF) from the run's
/// viewpoints.
#[allow(clippy::too_many_arguments)]
pub fn target_of(
    r: &mut Renderer,
    stack: &[PluginInstance],
    camera: &Camera,
    genome: &Genome,
    background: [f64; 3],
    o: &GaOptions,
) -> Result<Vec<[f64; 3]>, RenderError> {
    let cams = viewpoints(camera, o.views);
    let t = thumbnails(
        r,
        stack,
        std::slice::from_ref(genome),
        &cams,
        o.tile,
        o.slice_spacing,
        background,
        o.batch,
    )?;
    Ok(descriptor(&t[0]))
}

fn blend(a: &Genome, b: &Genome, rng: &mut Rng) -> Genome {
    let n = a
        .primitives
        .len()
        .max(b.primitives.len())
        .min(MAX_PRIMITIVES);
    let mut out: Vec<TfPrimitive> = Vec::new();
    for i in 0..n {
        match (a.primitives.get(i), b.primitives.get(i)) {
            (Some(p), Some(q)) => {
                let t = rng.uniform() as f32;
                let mix = |x: f32, y: f32| x + (y - x) * t;
                out.push(TfPrimitive {
                    shape: if rng.uniform() < 0.5 {
                        p.shape
                    } else {
                        q.shape
                    },
                    centre: mix(p.centre, q.centre),
                    width: mix(p.width, q.width),
                    height: mix(p.height, q.height),
                    color: std::array::from_fn(|c| mix(p.color[c], q.color[c])),
                });
            }
            (Some(p), None) | (None, Some(p)) => {
                if rng.uniform() < 0.5 {
                    out.push(*p);
                }
            }
            (None, None) => {}
        }
    }
    if out.is_empty() {
        out.push(a.primitives[0]);
    }
    Genome { primitives: out }
}

/// Runs the search from a seeded random population; `observer` sees every generation.
#[allow(clippy::too_many_arguments)]
pub fn evolve(
    r: &mut Renderer,
    stack: &[PluginInstance],
    camera: &Camera,
    background: [f64; 3],
    fitness: &Fitness,
    o: &GaOptions,
    observer: &mut dyn FnMut(usize, &Generation),
) -> Result<Vec<Generation>, RenderError> {
    let cams = viewpoints(camera, o.views);
    let pop = o.population.max(2);
    let mut population: Vec<Genome> = (0..pop)
        .map(|i| Genome::random(&mut Rng::at(o.seed, i as u64), o.max_primitives))
        .collect();
    let mut history = Vec::new();
    let mut radius = o.radius;
    for generation in 0..o.generations.max(1) {
        let thumbs = thumbnails(
            r,
            stack,
            &population,
            &cams,
            o.tile,
            o.slice_spacing,
            background,
            o.batch,
        )?;
        let scores: Vec<f64> = thumbs.iter().map(|v| fitness.score(v)).collect();
        let mut order: Vec<usize> = (0..pop).collect();
        order.sort_by(|&a, &b| scores[a].total_cmp(&scores[b]).then(a.cmp(&b)));
        let g = Generation {
            best: population[order[0]].clone(),
            best_score: scores[order[0]],
            mean_score: scores.iter().sum::<f64>() / pop as f64,
            radius,
        };
        observer(generation, &g);
        history.push(g);
        if generation + 1 == o.generations.max(1) {
            break;
        }
        // the next generation
        let mut next: Vec<Genome> = order
            .iter()
            .take(o.elite.min(pop))
            .map(|&i| population[i].clone())
            .collect();
        let mut k = 0u64;
        while next.len() < pop {
            let mut rng = Rng::at(
                o.seed ^ 0xA5A5_5A5A,
                ((generation as u64 + 1) << 32) | (next.len() as u64) << 8 | k,
            );
            k += 1;
            let pick = |rng: &mut Rng| {
                let a = (rng.uniform() * pop as f64) as usize % pop;
                let b = (rng.uniform() * pop as f64) as usize % pop;
                if scores[a] <= scores[b] { a } else { b }
            };
            let (pa, pb) = (pick(&mut rng), pick(&mut rng));
            let child = blend(&population[pa], &population[pb], &mut rng).mutate(&mut rng, radius);
            next.push(child);
        }
        population = next;
        radius *= o.decay;
    }
    Ok(history)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blends_stay_valid_and_seeded() {
        let a = Genome::random(&mut Rng::at(1, 1), 4);
        let b = Genome::random(&mut Rng::at(1, 2), 2);
        let c1 = blend(&a, &b, &mut Rng::at(5, 5));
        let c2 = blend(&a, &b, &mut Rng::at(5, 5));
        assert_eq!(c1, c2);
        c1.to_curve().validate().unwrap();
        assert!(!c1.primitives.is_empty() && c1.primitives.len() <= 4);
        // blending a genome with itself keeps it
        let same = blend(&a, &a, &mut Rng::at(3, 3));
        for (p, q) in same.primitives.iter().zip(&a.primitives) {
            assert!((p.centre - q.centre).abs() < 1e-6 && (p.height - q.height).abs() < 1e-6);
        }
    }
}
