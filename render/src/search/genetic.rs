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
    /// Toward a target, fit the best genome's colours to it by least squares each
    /// generation of the pattern search ([`Ga::fit_colours`]).
    pub colour_fit: bool,
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
            colour_fit: true,
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
    /// A target's pixels as the thumbnails hold them (sRGB-encoded, view after view),
    /// from its L*u*v* descriptor; None for an objective.
    pub fn target_pixels(&self) -> Option<Vec<[f64; 3]>> {
        match self {
            Fitness::Target(t) => Some(t.iter().map(|&p| crate::metrics::luv_to_srgb(p)).collect()),
            _ => None,
        }
    }

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

/// Where a genome of a generation came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Origin {
    /// The seeded random first generation.
    Random,
    /// A survivor of the previous generation (elitism; the user's picks).
    Elite,
    /// The polled genome with its colours fitted to the target ([`Ga::fit_colours`]).
    ColourFit,
    /// The last poll's centre moved by its Newton step ([`Poll::newton_step`]).
    Newton,
    /// A genome of the colour basis (rendered for the fit, not meant to win).
    ColourBasis,
    /// The polled genome with one parameter moved by ± its step.
    Poll,
    /// The polled genome with one primitive in another shape.
    Shape,
    /// The polled genome with a primitive left out or one added.
    Structure,
    /// A child of two parents, blended and varied.
    Child,
}

impl Origin {
    pub fn name(self) -> &'static str {
        match self {
            Origin::Random => "random",
            Origin::Elite => "elite",
            Origin::ColourFit => "colour_fit",
            Origin::Newton => "newton",
            Origin::ColourBasis => "colour_basis",
            Origin::Poll => "poll",
            Origin::Shape => "shape",
            Origin::Structure => "structure",
            Origin::Child => "child",
        }
    }
}

/// One generation's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct Generation {
    pub best: Genome,
    /// Where the best came from (`Elite`: no genome of this generation beat the last
    /// generation's best).
    pub origin: Origin,
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
    /// Where each genome of `population` came from.
    pub origins: Vec<Origin>,
    /// The mutation radius the current population was bred with (`options.radius`
    /// for the first, then × `options.decay` per generation).
    pub radius: f64,
    /// The pattern search around the best genome (from a quarter of a run on).
    poll: Option<Poll>,
    /// Where the current population holds the colour basis of the genome polled
    /// around: its population index and that genome ([`Ga::fit_colours`]).
    basis: Option<(usize, Genome)>,
    /// The genome with fitted colours, for the next generation.
    fitted: Option<Genome>,
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
    /// The population index of the first poll child.
    offset: usize,
    /// For each poll child, in population order from `offset`: (parameter, sign).
    moves: Vec<(usize, f64)>,
}

impl Poll {
    /// The diagonal Newton step the finished poll's scores give: per parameter polled
    /// on both sides, the central-difference slope g = (f₊ − f₋)/2s and curvature
    /// h = (f₊ + f₋ − 2f₀)/s², and the step −g/h to the parabola's minimum where h > 0
    /// (else one step s toward the better side), limited to ±2s. The poll's own renders
    /// give it for free; the compass search alone takes only the single best of its
    /// moves per generation. `None` where no parameter would move.
    fn newton_step(&self, scores: &[f64]) -> Option<Vec<f64>> {
        let n = self.steps.len();
        let (mut plus, mut minus) = (vec![None; n], vec![None; n]);
        for (k, &(p, sign)) in self.moves.iter().enumerate() {
            let f = *scores.get(self.offset + k)?;
            if sign > 0.0 {
                plus[p] = Some(f);
            } else {
                minus[p] = Some(f);
            }
        }
        let f0 = self.score;
        let mut delta = vec![0.0; n];
        for p in 0..n {
            let (Some(fp), Some(fm)) = (plus[p], minus[p]) else {
                continue;
            };
            let s = self.steps[p];
            let g = (fp - fm) / (2.0 * s);
            let h = (fp + fm - 2.0 * f0) / (s * s);
            let d = if h > 0.0 {
                -g / h
            } else if fp < fm.min(f0) {
                s
            } else if fm < fp.min(f0) {
                -s
            } else {
                0.0
            };
            if d.is_finite() {
                delta[p] = d.clamp(-2.0 * s, 2.0 * s);
            }
        }
        delta.iter().any(|&d| d != 0.0).then_some(delta)
    }
}

/// The fractions of the diagonal Newton step tried from the last poll's centre
/// ([`Poll::newton_step`]): the parameters are coupled, so the full step can overshoot.
const NEWTON_FRACTIONS: [f64; 3] = [0.5, 1.0, 1.5];

impl Ga {
    /// The seeded random first generation.
    pub fn new(o: &GaOptions) -> Ga {
        let pop = o.population.max(2);
        Ga {
            options: o.clone(),
            origins: vec![Origin::Random; pop],
            generation: 0,
            population: (0..pop)
                .map(|i| Genome::random(o.space, &mut Rng::at(o.seed, i as u64), o.max_primitives))
                .collect(),
            radius: o.radius,
            poll: None,
            basis: None,
            fitted: None,
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
            origin: self.origins.get(best).copied().unwrap_or(Origin::Random),
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
        self.breed_with(scores, elite, None, false);
    }

    /// [`Ga::breed`] toward a target ([`Fitness::target_pixels`]) with this
    /// generation's views: with `options.colour_fit`, the colours of the genome the
    /// pattern search polls around are fitted to the target ([`Ga::fit_colours`]) and
    /// the next generation holds the colour basis of the next one.
    pub fn breed_toward(&mut self, scores: &[f64], views: &[Vec<RgbImageF>], target: &[[f64; 3]]) {
        self.fit_colours(views, target);
        let elite = self.options.elite;
        self.breed_with(scores, elite, None, true);
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
        self.breed_with(&scores, elite, parents, false);
    }

    /// Fits the colours of the genome whose colour basis this population holds to a
    /// target (its views' pixels, sRGB-encoded, in the order of the population's
    /// views): the views are linear in the primitives' colours (opacity-weighted
    /// colour, emission–absorption), so the least-squares colours for the target
    /// follow from the basis's renders, B₀ (every primitive black) and B_j (primitive
    /// j white alone), by the normal equations per channel, with a small ridge toward
    /// the genome's own colours (a primitive nothing shows keeps its colour), clamped
    /// to [0, 1]. The fitted genome joins the next generation; it is kept only if it
    /// scores better. The fit is on the encoded values, the score on ΔE*uv: close, not
    /// the same.
    fn fit_colours(&mut self, views: &[Vec<RgbImageF>], target: &[[f64; 3]]) {
        let Some((at, genome)) = self.basis.take() else {
            return;
        };
        let k = genome.len();
        let pixels = |i: usize| -> Option<Vec<[f64; 3]>> {
            let v = views.get(at + i)?;
            Some(
                v.iter()
                    .flat_map(|img| img.pixels.iter().copied())
                    .collect(),
            )
        };
        let Some(b0) = pixels(0) else { return };
        let Some(basis) = (1..=k).map(pixels).collect::<Option<Vec<_>>>() else {
            return;
        };
        if b0.len() != target.len() || basis.iter().any(|b| b.len() != target.len()) {
            return;
        }
        let mut fitted = genome.clone();
        for c in 0..3 {
            let mut a = vec![vec![0.0f64; k]; k];
            let mut rhs = vec![0.0f64; k];
            for p in 0..target.len() {
                let t = target[p][c] - b0[p][c];
                for j in 0..k {
                    let bj = basis[j][p][c] - b0[p][c];
                    rhs[j] += bj * t;
                    for l in 0..k {
                        a[j][l] += bj * (basis[l][p][c] - b0[p][c]);
                    }
                }
            }
            let trace: f64 = (0..k).map(|j| a[j][j]).sum();
            let ridge = 1e-6 * trace / k as f64 + 1e-12;
            for j in 0..k {
                a[j][j] += ridge;
                rhs[j] += ridge * genome.param(genome.colour_params(j).start + c);
            }
            if let Some(x) = solve(a, rhs) {
                for (j, v) in x.into_iter().enumerate() {
                    fitted.set_param(genome.colour_params(j).start + c, v.clamp(0.0, 1.0));
                }
            }
        }
        if fitted != genome {
            self.fitted = Some(fitted);
        }
    }

    /// The next poll: around the best genome, with the steps the last poll's outcome
    /// gives (fresh steps when the best has another number of primitives), and as
    /// many moves as fit in three quarters of the children (the rest stay the GA's).
    fn next_poll(&self, scores: &[f64], order: &[usize], offset: usize) -> Poll {
        let best = &self.population[order[0]];
        let n = best.param_count();
        let steps = match &self.poll {
            Some(last) if last.steps.len() == n => {
                let mut improved = vec![false; n];
                for (k, &(p, _)) in last.moves.iter().enumerate() {
                    if scores.get(last.offset + k).is_some_and(|&s| s < last.score) {
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
        let room = (self.population.len() - offset.min(self.population.len())) * 3 / 4;
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
            offset,
            moves,
        }
    }

    /// `parents`: where given, every parent is drawn from these; else from tournaments
    /// of two by score.
    /// `basis`: hold the colour basis of the best for [`Ga::fit_colours`].
    fn breed_with(&mut self, scores: &[f64], elite: usize, parents: Option<&[usize]>, basis: bool) {
        let pop = self.population.len();
        assert_eq!(scores.len(), pop, "one score per genome");
        let order = self.ranking(scores);
        let (seed, generation, radius) = (self.options.seed, self.generation, self.radius);
        let mut next: Vec<Genome> = order
            .iter()
            .take(elite.min(pop))
            .map(|&i| self.population[i].clone())
            .collect();
        let mut origins = vec![Origin::Elite; next.len()];
        // the best with its colours fitted to the target
        if let (Some(g), None) = (self.fitted.take(), parents)
            && next.len() < pop
        {
            next.push(g);
        }
        origins.resize(next.len(), Origin::ColourFit);
        // the last poll's Newton step from its centre, at a few lengths
        if let (Some(last), None) = (&self.poll, parents)
            && let Some(delta) = last.newton_step(scores)
        {
            for t in NEWTON_FRACTIONS {
                let mut g = last.centre.clone();
                for (p, d) in delta.iter().enumerate() {
                    g.set_param(p, g.param(p) + t * d);
                }
                if next.len() < pop {
                    next.push(g);
                }
            }
        }
        origins.resize(next.len(), Origin::Newton);
        // the pattern search around the best, from a quarter of a run on
        let late = 4 * generation >= self.options.generations;
        // the colour basis of the best: all its colours black, then each primitive
        // white alone (its render is linear in the colours; [`Ga::fit_colours`])
        self.basis = None;
        if basis && late && parents.is_none() && self.options.colour_fit {
            let best = &self.population[order[0]];
            let basis = colour_basis(best);
            if next.len() + basis.len() <= pop {
                self.basis = Some((next.len(), best.clone()));
                next.extend(basis);
            }
        }
        origins.resize(next.len(), Origin::ColourBasis);
        let offset = next.len();
        self.poll = match (parents, late) {
            (None, true) => Some(self.next_poll(scores, &order, offset)),
            _ => None,
        };
        if let Some(poll) = &self.poll {
            for &(p, sign) in &poll.moves {
                let mut g = poll.centre.clone();
                let v = g.param(p) + sign * poll.steps[p];
                g.set_param(p, v);
                next.push(g);
            }
            origins.resize(next.len(), Origin::Poll);
            // and each primitive in the other shapes
            for g in poll.centre.shape_variants() {
                if next.len() < pop {
                    next.push(g);
                }
            }
            origins.resize(next.len(), Origin::Shape);
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
            origins.resize(next.len(), Origin::Structure);
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
        origins.resize(next.len(), Origin::Child);
        self.population = next;
        self.origins = origins;
        self.generation += 1;
        self.radius *= self.options.decay;
    }
}

/// The colour basis of a genome: every primitive black, then each primitive white
/// with the others black.
fn colour_basis(g: &Genome) -> Vec<Genome> {
    let paint = |white: Option<usize>| {
        let mut b = g.clone();
        for j in 0..g.len() {
            let v = if Some(j) == white { 1.0 } else { 0.0 };
            for p in g.colour_params(j) {
                b.set_param(p, v);
            }
        }
        b
    };
    std::iter::once(paint(None))
        .chain((0..g.len()).map(|j| paint(Some(j))))
        .collect()
}

/// Solves a small linear system by Gaussian elimination with partial pivoting (None
/// where it is singular).
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for col in 0..n {
        let pivot = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let pivot_row = a[col].clone();
        for row in col + 1..n {
            let f = a[row][col] / pivot_row[col];
            for (x, p) in a[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *x -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = vec![0.0; n];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|c| a[row][c] * x[c]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
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
    let target = fitness.target_pixels();
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
        match &target {
            Some(t) => ga.breed_toward(&scores, &thumbs, t),
            None => ga.breed(&scores),
        }
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

    /// On a separable quadratic the poll's ± scores give its minimum in one Newton
    /// step; a parameter whose both sides are worse with no curvature stays.
    #[test]
    fn the_newton_step_reaches_a_quadratic_minimum() {
        let centre = Genome::random(Space::Tf1d, &mut Rng::at(4, 4), 2);
        let n = centre.param_count();
        // within two steps of the centre (a Newton step goes at most that far)
        let minimum: Vec<f64> = (0..n)
            .map(|p| centre.param(p) + 0.005 * (p as f64 - 5.0))
            .collect();
        let weight = |p: usize| 1.0 + p as f64;
        let f = |x: &[f64]| -> f64 {
            x.iter()
                .enumerate()
                .map(|(p, v)| weight(p) * (v - minimum[p]).powi(2))
                .sum()
        };
        let x0: Vec<f64> = (0..n).map(|p| centre.param(p)).collect();
        let steps: Vec<f64> = (0..n).map(|p| 0.02 + 0.001 * p as f64).collect();
        let moves: Vec<(usize, f64)> = (0..n).flat_map(|p| [(p, 1.0), (p, -1.0)]).collect();
        let offset = 3;
        let mut scores = vec![0.0; offset];
        for &(p, sign) in &moves {
            let mut x = x0.clone();
            x[p] += sign * steps[p];
            scores.push(f(&x));
        }
        let poll = Poll {
            centre,
            score: f(&x0),
            steps: steps.clone(),
            offset,
            moves: moves.clone(),
        };
        let delta = poll.newton_step(&scores).unwrap();
        for p in 0..n {
            assert!(
                (x0[p] + delta[p] - minimum[p]).abs() < 1e-9,
                "parameter {p}"
            );
        }
        // flat on both sides (no curvature, no better side): no move; a missing score: none
        let flat = vec![poll.score; offset + moves.len()];
        assert!(poll.newton_step(&flat).is_none());
        assert!(poll.newton_step(&scores[..offset + 3]).is_none());
    }

    /// Views linear in the primitives' colours (as emission–absorption renders them):
    /// the fit recovers the colours that made the target from the basis's views, and a
    /// primitive no view shows keeps its own colour.
    #[test]
    fn colours_are_fitted_from_the_basis() {
        let genome = Genome::random(Space::Tf1d, &mut Rng::at(9, 1), 3);
        let k = genome.len();
        assert!(k >= 2);
        let o = GaOptions {
            population: 2 + k + 1,
            views: 2,
            ..Default::default()
        };
        let mut ga = Ga::new(&o);
        let at = 2;
        ga.basis = Some((at, genome.clone()));
        let (side, bg) = (4u32, [0.1, 0.2, 0.3]);
        // primitive j covers the pixels i with i % (k + 1) == j; the last one nothing
        let cover = |j: usize, i: usize| {
            if j + 1 < k && i % (k + 1) == j {
                0.5 + 0.01 * i as f64
            } else {
                0.0
            }
        };
        let render = |colours: &dyn Fn(usize) -> [f64; 3]| -> Vec<RgbImageF> {
            (0..o.views)
                .map(|v| {
                    let pixels = (0..(side * side) as usize)
                        .map(|i| {
                            let i = i + v * 7;
                            std::array::from_fn(|c| {
                                bg[c] * 0.4
                                    + (0..k).map(|j| cover(j, i) * colours(j)[c]).sum::<f64>()
                            })
                        })
                        .collect();
                    RgbImageF::new(side, side, pixels)
                })
                .collect()
        };
        let truth = |j: usize| [0.2 + 0.3 * j as f64, 0.9 - 0.2 * j as f64, 0.5];
        let mut views = vec![render(&|_| [0.0; 3]); at];
        for b in colour_basis(&genome) {
            let c = |j: usize| std::array::from_fn(|ch| b.param(b.colour_params(j).start + ch));
            views.push(render(&c));
        }
        let target: Vec<[f64; 3]> = render(&truth)
            .iter()
            .flat_map(|v| v.pixels.iter().copied())
            .collect();
        ga.fit_colours(&views, &target);
        let fitted = ga.fitted.clone().expect("colours changed");
        for j in 0..k {
            let want = if j + 1 < k {
                truth(j)
            } else {
                std::array::from_fn(|ch| genome.param(genome.colour_params(j).start + ch))
            };
            for (ch, w) in want.iter().enumerate() {
                let got = fitted.param(fitted.colour_params(j).start + ch);
                assert!(
                    (got - w).abs() < 1e-4,
                    "primitive {j} channel {ch}: {got} for {w}"
                );
            }
        }
        // the fit is used once; without a basis there is nothing to fit
        assert!(ga.basis.is_none());
        ga.fitted = None;
        ga.fit_colours(&views, &target);
        assert!(ga.fitted.is_none());
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
        // where each came from: the picks survive, the others are children
        assert_eq!(ga.origins.len(), ga.population.len());
        assert_eq!(ga.origins[..2], [Origin::Elite, Origin::Elite]);
        assert!(ga.origins[2..].iter().all(|&o| o == Origin::Child));
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
