//! Genetic search for a transfer function (He et al. 1996), against a target (the
//! images a known TF gives from the same viewpoints) or toward an image objective
//! (entropy, edge energy, histogram variance of the thumbnails). Every generation renders the whole population from every viewpoint in batched
//! atlases; fitness is the RMS ΔE*uv between a genome's descriptor and the target's
//! (lower is better). Selection is by tournaments of two, with elitism; children blend
//! their parents primitive by primitive and then mutate with a radius that anneals
//! geometrically. Every draw is counter-based on (seed, generation, individual), so a
//! run is bit-reproducible.

use crate::camera::Camera;
use crate::metrics::RgbImageF;
use crate::plugin::PluginInstance;
use crate::renderer::{RenderError, Renderer};
use crate::rng::Rng;
use crate::search::gallery::{descriptor, distance, thumbnails, viewpoints};
use crate::search::genome::{Genome, Space};

/// Settings of a run.
#[derive(Debug, Clone, PartialEq)]
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
    /// The TF model searched ([`Space::of_stack`] gives the stack's).
    pub space: Space,
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
            space: Space::Tf1d,
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
    /// Visible-boundary coverage of the data's boundaries, to maximise (its score is
    /// minus it): [`crate::search::coverage`].
    Coverage(std::sync::Arc<crate::search::coverage::Coverage>),
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
    /// The score of a genome and its views (lower is better).
    pub fn score(&self, genome: &Genome, views: &[crate::metrics::RgbImageF]) -> f64 {
        match self {
            Fitness::Coverage(c) => -c.objective(genome).0,
            Fitness::Target(t) => distance(&descriptor(views), t),
            Fitness::Objective(o) => {
                -views.iter().map(|v| o.of(v)).sum::<f64>() / views.len().max(1) as f64
            }
        }
    }
}

/// A genome's views side by side, left to right in viewpoint order: what `vwb evolve`
/// writes as `best.png` and `target.png`, and reads as `--target`.
pub fn side_by_side(views: &[RgbImageF]) -> RgbImageF {
    let (w, h) = views.first().map_or((0, 0), |v| (v.width, v.height));
    let mut pixels = Vec::with_capacity(views.len() * (w * h) as usize);
    for y in 0..h as usize {
        for v in views {
            assert_eq!((v.width, v.height), (w, h), "views of one size");
            pixels.extend_from_slice(&v.pixels[y * w as usize..(y + 1) * w as usize]);
        }
    }
    RgbImageF::new(w * views.len() as u32, h, pixels)
}

/// The inverse of [`side_by_side`]: a strip of square views, as many as it holds. A
/// strip that is not a whole number of square views is refused with its size.
pub fn split_side_by_side(strip: &RgbImageF) -> Result<Vec<RgbImageF>, String> {
    let (w, h) = (strip.width, strip.height);
    if h == 0 || w % h != 0 {
        return Err(format!(
            "a target is square views side by side (width a multiple of the height); this one is {w}×{h}"
        ));
    }
    Ok((0..w / h)
        .map(|i| {
            let pixels = (0..h as usize)
                .flat_map(|y| {
                    let row = y * w as usize + (i * h) as usize;
                    strip.pixels[row..row + h as usize].iter().copied()
                })
                .collect();
            RgbImageF::new(h, h, pixels)
        })
        .collect())
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

/// The GA's variation of a child with radius `radius`: half the time
/// [`Genome::mutate`] (every parameter moves, a primitive may come or go), half the
/// time one parameter of one primitive moves ([`Genome::vary_one`]: its centre, size,
/// height or colour by the same law, or its shape). Near an optimum a move of every
/// parameter at once is nearly always worse, which stalls the search; single moves
/// keep improving it.
fn vary(g: &Genome, rng: &mut Rng, radius: f64) -> Genome {
    if rng.uniform() < 0.5 {
        return g.mutate(rng, radius);
    }
    g.vary_one(rng, radius)
}

/// A search in progress, one generation at a time: the current population, bred from
/// the previous generation's scores. [`evolve`] runs it against a fitness; the window
/// runs it by the user's picks ([`Ga::breed_from_picks`]), one generation per click.
#[derive(Debug, Clone, PartialEq)]
pub struct Ga {
    pub options: GaOptions,
    /// The generation `population` belongs to (0: the seeded random one).
    pub generation: usize,
    pub population: Vec<Genome>,
    /// The mutation radius the current population was bred with (`options.radius`
    /// for the first, then × `options.decay` per generation).
    pub radius: f64,
    /// The pattern search around the best genome (from a quarter of a run on).
    poll: Option<Poll>,
}

/// A compass (pattern) search around the best genome, run inside the GA's
/// generations: each generation holds, after the elite, one child per parameter and
/// sign, the best moved by ± that parameter's step. A step that improved on the
/// best grows by 1.5, one that did not halves. The parameters are each primitive's
/// centre, ln sizes, ln height and RGB (`genome::Primitive`); then each primitive in
/// its other shapes; the number of primitives is left to the GA's children.
#[derive(Debug, Clone, PartialEq)]
struct Poll {
    /// The genome polled around, and its score.
    centre: Genome,
    score: f64,
    steps: Vec<f64>,
    /// For each poll child, in population order after the elite: (parameter, sign).
    moves: Vec<(usize, f64)>,
}

impl Ga {
    /// The seeded random first generation.
    pub fn new(o: &GaOptions) -> Ga {
        let pop = o.population.max(2);
        Ga {
            options: o.clone(),
            generation: 0,
            population: (0..pop)
                .map(|i| Genome::random(o.space, &mut Rng::at(o.seed, i as u64), o.max_primitives))
                .collect(),
            radius: o.radius,
            poll: None,
        }
    }

    /// Every genome's views from the run's viewpoints, in batched atlases.
    pub fn render(
        &self,
        r: &mut Renderer,
        stack: &[PluginInstance],
        camera: &Camera,
        background: [f64; 3],
    ) -> Result<Vec<Vec<RgbImageF>>, RenderError> {
        let o = &self.options;
        thumbnails(
            r,
            stack,
            &self.population,
            &viewpoints(camera, o.views),
            o.tile,
            o.slice_spacing,
            background,
            o.batch,
        )
    }

    /// The order of the population by score (best first; ties by index).
    fn ranking(&self, scores: &[f64]) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.population.len()).collect();
        order.sort_by(|&a, &b| scores[a].total_cmp(&scores[b]).then(a.cmp(&b)));
        order
    }

    /// This generation's outcome for its scores (lower is better).
    pub fn summary(&self, scores: &[f64]) -> Generation {
        let best = self.ranking(scores)[0];
        Generation {
            best: self.population[best].clone(),
            best_score: scores[best],
            mean_score: scores.iter().sum::<f64>() / scores.len().max(1) as f64,
            radius: self.radius,
        }
    }

    /// Breeds the next generation from this one's scores (lower is better): the
    /// `options.elite` best survive; the others are children of tournament winners,
    /// blended primitive by primitive and mutated with the current radius.
    pub fn breed(&mut self, scores: &[f64]) {
        let elite = self.options.elite;
        self.breed_with(scores, elite, None);
    }

    /// Breeds the next generation from the user's picks (indices into the
    /// population): every pick survives (up to half the population), and both
    /// parents of every child are picks. With no picks, every genome is as fit as any
    /// other.
    pub fn breed_from_picks(&mut self, picks: &[usize]) {
        let pop = self.population.len();
        let picks: Vec<usize> = (0..pop).filter(|i| picks.contains(i)).collect();
        let scores: Vec<f64> = (0..pop)
            .map(|i| if picks.contains(&i) { 0.0 } else { 1.0 })
            .collect();
        let elite = picks.len().min(pop / 2);
        let parents = (!picks.is_empty()).then_some(picks.as_slice());
        self.breed_with(&scores, elite, parents);
    }

    /// The next poll: around the best genome, with the steps the last poll's outcome
    /// gives (fresh steps when the best has another number of primitives), and as
    /// many moves as fit in three quarters of the children (the rest stay the GA's).
    fn next_poll(&self, scores: &[f64], order: &[usize]) -> Poll {
        let best = &self.population[order[0]];
        let n = best.param_count();
        let steps = match &self.poll {
            Some(last) if last.steps.len() == n => {
                // the last poll's children follow the elite in the population
                let first = self.options.elite.min(self.population.len());
                let mut improved = vec![false; n];
                for (k, &(p, _)) in last.moves.iter().enumerate() {
                    if scores.get(first + k).is_some_and(|&s| s < last.score) {
                        improved[p] = true;
                    }
                }
                last.steps
                    .iter()
                    .zip(&improved)
                    .map(|(&s, &up)| if up { s * 1.5 } else { s * 0.5 })
                    .collect()
            }
            _ => best.initial_steps(self.radius),
        };
        let room = (self.population.len() - self.options.elite.min(self.population.len())) * 3 / 4;
        // the parameters in turn, both signs, starting where the generation says, so
        // that a poll too large for the room still visits every parameter in turn
        let start = self.generation * (room / 2).max(1) % n.max(1);
        let moves = (0..n.min(room / 2))
            .map(|i| (start + i) % n)
            .flat_map(|p| [(p, 1.0), (p, -1.0)])
            .collect();
        Poll {
            centre: best.clone(),
            score: scores[order[0]],
            steps,
            moves,
        }
    }

    /// `parents`: where given, every parent is drawn from these; else from tournaments
    /// of two by score.
    fn breed_with(&mut self, scores: &[f64], elite: usize, parents: Option<&[usize]>) {
        let pop = self.population.len();
        assert_eq!(scores.len(), pop, "one score per genome");
        let order = self.ranking(scores);
        let (seed, generation, radius) = (self.options.seed, self.generation, self.radius);
        let mut next: Vec<Genome> = order
            .iter()
            .take(elite.min(pop))
            .map(|&i| self.population[i].clone())
            .collect();
        // the pattern search around the best, from a quarter of a run on
        let late = 4 * generation >= self.options.generations;
        self.poll = match (parents, late) {
            (None, true) => Some(self.next_poll(scores, &order)),
            _ => None,
        };
        if let Some(poll) = &self.poll {
            for &(p, sign) in &poll.moves {
                let mut g = poll.centre.clone();
                let v = g.param(p) + sign * poll.steps[p];
                g.set_param(p, v);
                next.push(g);
            }
            // and each primitive in the other shapes
            for g in poll.centre.shape_variants() {
                if next.len() < pop {
                    next.push(g);
                }
            }
            // and the structure: each primitive left out, a few random ones added
            let mut rng = Rng::at(seed ^ 0x5EED_57A7, generation as u64);
            for g in poll
                .centre
                .structure_variants(self.options.max_primitives, 4, &mut rng)
            {
                if next.len() < pop {
                    next.push(g);
                }
            }
        }
        let mut k = 0u64;
        while next.len() < pop {
            let mut rng = Rng::at(
                seed ^ 0xA5A5_5A5A,
                ((generation as u64 + 1) << 32) | (next.len() as u64) << 8 | k,
            );
            k += 1;
            let pick = |rng: &mut Rng| match parents {
                Some(p) => p[(rng.uniform() * p.len() as f64) as usize % p.len()],
                None => {
                    let a = (rng.uniform() * pop as f64) as usize % pop;
                    let b = (rng.uniform() * pop as f64) as usize % pop;
                    if scores[a] <= scores[b] { a } else { b }
                }
            };
            let (pa, pb) = (pick(&mut rng), pick(&mut rng));
            let child = vary(
                &Genome::blend(&self.population[pa], &self.population[pb], &mut rng),
                &mut rng,
                radius,
            );
            next.push(child);
        }
        self.population = next;
        self.generation += 1;
        self.radius *= self.options.decay;
    }
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
    let mut ga = Ga::new(o);
    let mut history = Vec::new();
    let generations = o.generations.max(1);
    loop {
        let thumbs = ga.render(r, stack, camera, background)?;
        let scores: Vec<f64> = ga
            .population
            .iter()
            .zip(&thumbs)
            .map(|(g, v)| fitness.score(g, v))
            .collect();
        let g = ga.summary(&scores);
        observer(ga.generation, &g);
        history.push(g);
        if ga.generation + 1 == generations {
            return Ok(history);
        }
        ga.breed(&scores);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_go_side_by_side_and_back() {
        let views: Vec<RgbImageF> = (0..3)
            .map(|v| {
                RgbImageF::new(
                    4,
                    4,
                    (0..16).map(|i| [v as f64, i as f64 / 16.0, 0.5]).collect(),
                )
            })
            .collect();
        let strip = side_by_side(&views);
        assert_eq!((strip.width, strip.height), (12, 4));
        assert_eq!(strip.pixels[4], [1.0, 0.0, 0.5], "row 0 of view 1");
        assert_eq!(split_side_by_side(&strip).unwrap(), views);
        let e = split_side_by_side(&RgbImageF::new(10, 4, vec![[0.0; 3]; 40])).unwrap_err();
        assert!(e.contains("10×4"), "{e}");
    }

    #[test]
    fn picks_survive_and_parent_the_next_generation() {
        let o = GaOptions {
            population: 8,
            ..Default::default()
        };
        let mut ga = Ga::new(&o);
        let first = ga.population.clone();
        let again = Ga::new(&o);
        assert_eq!(again, ga, "seeded");
        ga.breed_from_picks(&[5, 2]);
        assert_eq!(ga.generation, 1);
        assert!((ga.radius - o.radius * o.decay).abs() < 1e-12);
        // the picks survive, in index order (ties by index), and no other genome does
        assert_eq!(ga.population[0], first[2]);
        assert_eq!(ga.population[1], first[5]);
        for g in &ga.population[2..] {
            assert!(!first.contains(g), "a child, not a survivor");
        }
        // children descend from the picks: with a tiny radius, each is near one of them
        let mut ga = Ga::new(&GaOptions {
            radius: 1e-4,
            ..o.clone()
        });
        ga.breed_from_picks(&[3]);
        for g in &ga.population {
            assert!(
                (g.centre(0) - first[3].centre(0)).abs() < 0.01,
                "{g:?} against {:?}",
                first[3]
            );
        }
    }

    #[test]
    fn blends_stay_valid_and_seeded() {
        for space in [Space::Tf1d, Space::Tf2d] {
            let a = Genome::random(space, &mut Rng::at(1, 1), 4);
            let b = Genome::random(space, &mut Rng::at(1, 2), 2);
            let c1 = Genome::blend(&a, &b, &mut Rng::at(5, 5));
            let c2 = Genome::blend(&a, &b, &mut Rng::at(5, 5));
            assert_eq!(c1, c2);
            assert_eq!(c1.space(), space);
            c1.validate().unwrap();
            assert!(!c1.is_empty() && c1.len() <= 4);
            // blending a genome with itself gives it back, its primitives in value order
            let same = Genome::blend(&a, &a, &mut Rng::at(3, 3));
            let sorted = match a.clone() {
                Genome::Tf1d(mut p) => {
                    p.sort_by(|x, y| x.centre.total_cmp(&y.centre));
                    Genome::Tf1d(p)
                }
                Genome::Tf2d(mut p) => {
                    p.sort_by(|x, y| x.centre[0].total_cmp(&y.centre[0]));
                    Genome::Tf2d(p)
                }
            };
            assert_eq!(same, sorted);
        }
    }

    #[test]
    fn a_2d_search_breeds_2d_genomes() {
        let o = GaOptions {
            population: 12,
            generations: 4,
            space: Space::Tf2d,
            ..Default::default()
        };
        let mut ga = Ga::new(&o);
        for generation in 0..3 {
            let scores: Vec<f64> = ga.population.iter().map(|g| g.centre(0) as f64).collect();
            ga.breed(&scores);
            assert!(
                ga.population.iter().all(|g| g.space() == Space::Tf2d),
                "generation {generation}"
            );
        }
    }
}
