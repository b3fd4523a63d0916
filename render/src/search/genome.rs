//! The TF genome: up to [`MAX_PRIMITIVES`] primitives with colours, over a fully
//! transparent TF, in one of two spaces ([`Space`]):
//! - `classify.tf1d`: Gaussians, ramps and boxes over the value axis, each with a
//!   centre, a width, a height (opacity per Δs0) and an RGB colour. It maps exactly
//!   onto the plugin's `tf` curve ([`Genome::to_param`]) and back
//!   ([`Genome::from_curve`]) for every curve whose points are all transparent.
//! - `classify.tf2d`: rectangles, triangles and Gaussians over value × gradient
//!   magnitude (`crate::tf2d`), each with a centre, a size, a peak opacity and an RGB
//!   colour. It maps exactly onto the plugin's `tf` ([`Genome::to_param`]) and back
//!   ([`Genome::from_tf2d`]) for every 2D TF of at most [`MAX_PRIMITIVES`] primitives.
//!
//! The search (gallery and GA) moves genomes only through the operations here, which
//! are written once over [`Primitive`]: a new space is one more implementation.

use serde::{Deserialize, Serialize};

use crate::params::ParamValue;
use crate::plugin::PluginInstance;
use crate::rng::Rng;
use crate::tf::{PrimitiveShape, TfCurve, TfPoint, TfPrimitive};
use crate::tf2d::{Primitive2d, Shape2d, Tf2d};

/// The most primitives a genome holds.
pub const MAX_PRIMITIVES: usize = 8;

/// Which TF model a genome describes, and so which plugin it is searched through.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Space {
    /// `classify.tf1d`'s `tf`.
    #[default]
    Tf1d,
    /// `classify.tf2d`'s `tf`.
    Tf2d,
}

impl Space {
    /// The plugin whose `tf` a genome of this space sets.
    pub fn plugin_id(self) -> &'static str {
        match self {
            Space::Tf1d => "classify.tf1d",
            Space::Tf2d => "classify.tf2d",
        }
    }

    /// The space of a stack: that of its first enabled classify.tf1d or classify.tf2d.
    pub fn of_stack(stack: &[PluginInstance]) -> Result<Space, String> {
        stack
            .iter()
            .filter(|i| i.enabled)
            .find_map(|i| match i.plugin.id() {
                "classify.tf1d" => Some(Space::Tf1d),
                "classify.tf2d" => Some(Space::Tf2d),
                _ => None,
            })
            .ok_or_else(|| {
                "the stack has no enabled classify.tf1d or classify.tf2d to search".into()
            })
    }
}

/// A transfer function as a list of primitives, in its space.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Genome {
    Tf1d(Vec<TfPrimitive>),
    Tf2d(Vec<Primitive2d>),
}

/// Ranges random genomes are drawn from: widths along the value axis, ...
pub(crate) const WIDTH: (f64, f64) = (0.02, 0.35);
/// ... sizes along the gradient-magnitude axis (2D), ...
const GRADIENT_SIZE: (f64, f64) = (0.05, 1.0);
/// ... and heights (1D: opacity per Δs0; 2D: peak opacity per voxel).
const HEIGHT: (f64, f64) = (0.004, 0.6);
/// The least height a variation leaves a primitive (it keeps its place in the genome).
pub(crate) const MIN_HEIGHT: f64 = 1.0e-4;

/// A parameter of a primitive as variations move it, within radius r: the centre by
/// N(0, r/4), the size (width, and in 2D the extent along the gradient) and the height
/// (opacity) by a factor e^N(0, r), each colour channel by N(0, r/2); each clamped to
/// its range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Gene {
    Centre,
    Size,
    Height,
    Colour,
}

impl Gene {
    pub(crate) const ALL: [Gene; 4] = [Gene::Centre, Gene::Size, Gene::Height, Gene::Colour];
}

fn log_uniform((lo, hi): (f64, f64), u: f64) -> f64 {
    (lo.ln() + (hi.ln() - lo.ln()) * u).exp()
}

fn moved(x: f32, rng: &mut Rng, sd: f64, lo: f64, hi: f64) -> f32 {
    (x as f64 + rng.normal() * sd).clamp(lo, hi) as f32
}

fn scaled(x: f32, rng: &mut Rng, r: f64, lo: f64, hi: f64) -> f32 {
    (x as f64 * (rng.normal() * r).exp()).clamp(lo, hi) as f32
}

/// What the search needs of a primitive. The pattern-search coordinates are centres,
/// logarithms of sizes and heights, and colours.
pub(crate) trait Primitive: Copy + PartialEq + std::fmt::Debug {
    /// Pattern-search coordinates per primitive.
    const PARAMS: usize;
    /// Shapes the primitive can take.
    const SHAPES: usize = 3;
    fn random(rng: &mut Rng) -> Self;
    fn nudge(&mut self, gene: Gene, rng: &mut Rng, r: f64);
    fn param(&self, i: usize) -> f64;
    /// Sets coordinate `i`, clamped to its range.
    fn set_param(&mut self, i: usize, v: f64);
    /// The first pattern-search step of coordinate `i` at mutation radius `r`: the
    /// scales [`Primitive::nudge`] uses.
    fn initial_step(i: usize, r: f64) -> f64;
    /// The centre along the value axis (blends pair primitives by it).
    fn value_centre(&self) -> f32;
    /// Every number t of the way to `other`, with this shape or the other's.
    fn mix(&self, other: &Self, t: f32, own_shape: bool) -> Self;
    fn shape_index(&self) -> usize;
    fn set_shape(&mut self, k: usize);
}

impl Primitive for TfPrimitive {
    const PARAMS: usize = 6;

    fn random(rng: &mut Rng) -> Self {
        let shape = PrimitiveShape::ALL[(rng.uniform() * 3.0) as usize % 3];
        TfPrimitive {
            shape,
            centre: rng.uniform() as f32,
            width: log_uniform(WIDTH, rng.uniform()) as f32,
            // ramps and boxes cover more of the value axis: keep them fainter
            height: (log_uniform(HEIGHT, rng.uniform())
                * if shape == PrimitiveShape::Gaussian {
                    1.0
                } else {
                    0.3
                }) as f32,
            color: [
                rng.uniform() as f32,
                rng.uniform() as f32,
                rng.uniform() as f32,
            ],
        }
    }

    fn nudge(&mut self, gene: Gene, rng: &mut Rng, r: f64) {
        match gene {
            Gene::Centre => self.centre = moved(self.centre, rng, r * 0.25, 0.0, 1.0),
            Gene::Size => self.width = scaled(self.width, rng, r, WIDTH.0, 1.0),
            Gene::Height => self.height = scaled(self.height, rng, r, MIN_HEIGHT, 1.0),
            Gene::Colour => {
                for c in &mut self.color {
                    *c = moved(*c, rng, r * 0.5, 0.0, 1.0);
                }
            }
        }
    }

    fn param(&self, i: usize) -> f64 {
        match i {
            0 => self.centre as f64,
            1 => (self.width as f64).ln(),
            2 => (self.height as f64).ln(),
            c => self.color[c - 3] as f64,
        }
    }

    fn set_param(&mut self, i: usize, v: f64) {
        match i {
            0 => self.centre = v.clamp(0.0, 1.0) as f32,
            1 => self.width = v.exp().clamp(WIDTH.0, 1.0) as f32,
            2 => self.height = v.exp().clamp(MIN_HEIGHT, 1.0) as f32,
            c => self.color[c - 3] = v.clamp(0.0, 1.0) as f32,
        }
    }

    fn initial_step(i: usize, r: f64) -> f64 {
        match i {
            0 => r * 0.25,
            1 | 2 => r,
            _ => r * 0.5,
        }
    }

    fn value_centre(&self) -> f32 {
        self.centre
    }

    fn mix(&self, q: &Self, t: f32, own_shape: bool) -> Self {
        let mix = |x: f32, y: f32| x + (y - x) * t;
        TfPrimitive {
            shape: if own_shape { self.shape } else { q.shape },
            centre: mix(self.centre, q.centre),
            width: mix(self.width, q.width),
            height: mix(self.height, q.height),
            color: std::array::from_fn(|c| mix(self.color[c], q.color[c])),
        }
    }

    fn shape_index(&self) -> usize {
        PrimitiveShape::ALL
            .iter()
            .position(|s| *s == self.shape)
            .unwrap_or(0)
    }

    fn set_shape(&mut self, k: usize) {
        self.shape = PrimitiveShape::ALL[k % 3];
    }
}

/// 2D coordinates: value centre, gradient centre, ln width, ln gradient size, ln peak
/// opacity, RGB. A triangle ignores its gradient centre (its apex sits at |∇f| = 0).
impl Primitive for Primitive2d {
    const PARAMS: usize = 8;

    fn random(rng: &mut Rng) -> Self {
        let shape = Shape2d::ALL[(rng.uniform() * 3.0) as usize % 3];
        let v = rng.uniform() as f32;
        // most voxels have small gradients: draw the gradient centre toward them
        let g = rng.uniform().powi(2) as f32;
        let w = log_uniform(WIDTH, rng.uniform()) as f32;
        let h = log_uniform(GRADIENT_SIZE, rng.uniform()) as f32;
        // rectangles cover a whole block of the histogram: keep them fainter
        let a = log_uniform(HEIGHT, rng.uniform())
            * if shape == Shape2d::Rectangle {
                0.3
            } else {
                1.0
            };
        let rgb = [
            rng.uniform() as f32,
            rng.uniform() as f32,
            rng.uniform() as f32,
        ];
        Primitive2d {
            shape,
            centre: [v, if shape == Shape2d::Triangle { 0.0 } else { g }],
            size: [w, h],
            color: [rgb[0], rgb[1], rgb[2], a as f32],
        }
    }

    fn nudge(&mut self, gene: Gene, rng: &mut Rng, r: f64) {
        match gene {
            Gene::Centre => {
                for c in &mut self.centre {
                    *c = moved(*c, rng, r * 0.25, 0.0, 1.0);
                }
            }
            Gene::Size => {
                self.size[0] = scaled(self.size[0], rng, r, WIDTH.0, 1.0);
                self.size[1] = scaled(self.size[1], rng, r, GRADIENT_SIZE.0, 1.0);
            }
            Gene::Height => self.color[3] = scaled(self.color[3], rng, r, MIN_HEIGHT, 1.0),
            Gene::Colour => {
                for c in &mut self.color[..3] {
                    *c = moved(*c, rng, r * 0.5, 0.0, 1.0);
                }
            }
        }
    }

    fn param(&self, i: usize) -> f64 {
        match i {
            0 | 1 => self.centre[i] as f64,
            2 | 3 => (self.size[i - 2] as f64).ln(),
            4 => (self.color[3] as f64).ln(),
            c => self.color[c - 5] as f64,
        }
    }

    fn set_param(&mut self, i: usize, v: f64) {
        match i {
            0 | 1 => self.centre[i] = v.clamp(0.0, 1.0) as f32,
            2 => self.size[0] = v.exp().clamp(WIDTH.0, 1.0) as f32,
            3 => self.size[1] = v.exp().clamp(GRADIENT_SIZE.0, 1.0) as f32,
            4 => self.color[3] = v.exp().clamp(MIN_HEIGHT, 1.0) as f32,
            c => self.color[c - 5] = v.clamp(0.0, 1.0) as f32,
        }
    }

    fn initial_step(i: usize, r: f64) -> f64 {
        match i {
            0 | 1 => r * 0.25,
            2..=4 => r,
            _ => r * 0.5,
        }
    }

    fn value_centre(&self) -> f32 {
        self.centre[0]
    }

    fn mix(&self, q: &Self, t: f32, own_shape: bool) -> Self {
        let mix = |x: f32, y: f32| x + (y - x) * t;
        Primitive2d {
            shape: if own_shape { self.shape } else { q.shape },
            centre: std::array::from_fn(|c| mix(self.centre[c], q.centre[c])),
            size: std::array::from_fn(|c| mix(self.size[c], q.size[c])),
            color: std::array::from_fn(|c| mix(self.color[c], q.color[c])),
        }
    }

    fn shape_index(&self) -> usize {
        Shape2d::ALL
            .iter()
            .position(|s| *s == self.shape)
            .unwrap_or(0)
    }

    fn set_shape(&mut self, k: usize) {
        self.shape = Shape2d::ALL[k % 3];
    }
}

/// Runs `$body` with `$p` bound to the genome's primitives, whichever the space.
macro_rules! each {
    ($g:expr, $p:ident => $body:expr) => {
        match $g {
            Genome::Tf1d($p) => $body,
            Genome::Tf2d($p) => $body,
        }
    };
}

/// The 1D genome's curve: transparent end points and the primitives.
fn curve_of(primitives: &[TfPrimitive]) -> TfCurve {
    let clear = |x| TfPoint { x, color: [0.0; 4] };
    TfCurve {
        points: vec![clear(0.0), clear(1.0)],
        primitives: primitives.to_vec(),
        log_opacity: false,
    }
}

fn tf2d_of(primitives: &[Primitive2d]) -> Tf2d {
    Tf2d {
        primitives: primitives.to_vec(),
    }
}

fn random_list<P: Primitive>(rng: &mut Rng, max: usize) -> Vec<P> {
    let n = 1 + (rng.uniform() * max.clamp(1, MAX_PRIMITIVES) as f64) as usize;
    (0..n.min(MAX_PRIMITIVES)).map(|_| P::random(rng)).collect()
}

fn mutate_list<P: Primitive>(ps: &[P], rng: &mut Rng, r: f64) -> Vec<P> {
    let mut out: Vec<P> = ps
        .iter()
        .map(|p| {
            let mut q = *p;
            for gene in Gene::ALL {
                q.nudge(gene, rng, r);
            }
            q
        })
        .collect();
    if rng.uniform() < r * 0.5 {
        if out.len() < MAX_PRIMITIVES && (out.len() <= 1 || rng.uniform() < 0.5) {
            out.push(P::random(rng));
        } else if out.len() > 1 {
            let i = (rng.uniform() * out.len() as f64) as usize;
            out.remove(i.min(out.len() - 1));
        }
    }
    out
}

fn vary_one<P: Primitive>(ps: &mut [P], rng: &mut Rng, r: f64) {
    let n = ps.len();
    let p = &mut ps[((rng.uniform() * n as f64) as usize).min(n - 1)];
    match Gene::ALL.get((rng.uniform() * 5.0) as usize) {
        Some(gene) => p.nudge(*gene, rng, r),
        None => p.set_shape((rng.uniform() * P::SHAPES as f64) as usize % P::SHAPES),
    }
}

fn blend_lists<P: Primitive>(a: &[P], b: &[P], rng: &mut Rng) -> Vec<P> {
    let by_centre = |g: &[P]| {
        let mut g = g.to_vec();
        g.sort_by(|p, q| p.value_centre().total_cmp(&q.value_centre()));
        g
    };
    let (a, b) = (by_centre(a), by_centre(b));
    let n = a.len().max(b.len()).min(MAX_PRIMITIVES);
    let mut out = Vec::new();
    for i in 0..n {
        match (a.get(i), b.get(i)) {
            (Some(p), Some(q)) => {
                let t = rng.uniform() as f32;
                out.push(p.mix(q, t, rng.uniform() < 0.5));
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
        out.push(a[0]);
    }
    out
}

/// Pattern-search coordinates of a list of primitives.
fn coordinates<P: Primitive>(ps: &[P]) -> usize {
    ps.len() * P::PARAMS
}

fn coordinate<P: Primitive>(ps: &[P], i: usize) -> f64 {
    ps[i / P::PARAMS].param(i % P::PARAMS)
}

fn set_coordinate<P: Primitive>(ps: &mut [P], i: usize, v: f64) {
    ps[i / P::PARAMS].set_param(i % P::PARAMS, v)
}

fn initial_steps<P: Primitive>(ps: &[P], r: f64) -> Vec<f64> {
    (0..coordinates(ps))
        .map(|i| P::initial_step(i % P::PARAMS, r))
        .collect()
}

fn shape_variants<P: Primitive>(ps: &[P]) -> Vec<Vec<P>> {
    let mut out = Vec::new();
    for (i, q) in ps.iter().enumerate() {
        for k in 0..P::SHAPES {
            if k != q.shape_index() {
                let mut g = ps.to_vec();
                g[i].set_shape(k);
                out.push(g);
            }
        }
    }
    out
}

/// The list without each of its primitives in turn (none for a single primitive), then
/// with `adds` random primitives added one at a time (below `max`).
fn structure_variants<P: Primitive>(
    ps: &[P],
    max: usize,
    adds: usize,
    rng: &mut Rng,
) -> Vec<Vec<P>> {
    let mut out = Vec::new();
    if ps.len() > 1 {
        for i in 0..ps.len() {
            let mut g = ps.to_vec();
            g.remove(i);
            out.push(g);
        }
    }
    if ps.len() < max.min(MAX_PRIMITIVES) {
        for _ in 0..adds {
            let mut g = ps.to_vec();
            g.push(P::random(rng));
            out.push(g);
        }
    }
    out
}

impl Genome {
    pub fn space(&self) -> Space {
        match self {
            Genome::Tf1d(_) => Space::Tf1d,
            Genome::Tf2d(_) => Space::Tf2d,
        }
    }

    /// The number of primitives.
    pub fn len(&self) -> usize {
        each!(self, p => p.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The `tf` curve of `classify.tf1d` (transparent end points and the primitives);
    /// `None` for a 2D genome.
    pub fn to_curve(&self) -> Option<TfCurve> {
        match self {
            Genome::Tf1d(p) => Some(curve_of(p)),
            Genome::Tf2d(_) => None,
        }
    }

    /// The value of its plugin's `tf` parameter.
    pub fn to_param(&self) -> ParamValue {
        match self {
            Genome::Tf1d(p) => ParamValue::Tf(curve_of(p)),
            Genome::Tf2d(p) => ParamValue::Tf2d(tf2d_of(p)),
        }
    }

    /// Puts the genome into the `tf` of the stack's first enabled instance of its
    /// space's plugin.
    pub fn apply(&self, stack: &mut [PluginInstance]) -> Result<(), String> {
        let id = self.space().plugin_id();
        let tf = stack
            .iter_mut()
            .find(|i| i.enabled && i.plugin.id() == id)
            .ok_or_else(|| format!("the stack has no enabled {id} to apply the TF to"))?;
        tf.params.set("tf", self.to_param());
        Ok(())
    }

    /// The genome of a curve whose points are all transparent (any number of them), on
    /// a linear opacity axis, with at most [`MAX_PRIMITIVES`] primitives.
    pub fn from_curve(c: &TfCurve) -> Result<Genome, String> {
        if let Some(p) = c.points.iter().find(|p| p.color[3] != 0.0) {
            return Err(format!(
                "the curve has an opaque point at x = {} (a genome holds primitives only)",
                p.x
            ));
        }
        if c.log_opacity {
            return Err("the curve reads opacity on a log axis; genomes use a linear one".into());
        }
        Self::at_most(c.primitives.len())?;
        Ok(Genome::Tf1d(c.primitives.clone()))
    }

    /// The genome of a 2D TF of at most [`MAX_PRIMITIVES`] primitives.
    pub fn from_tf2d(t: &Tf2d) -> Result<Genome, String> {
        Self::at_most(t.primitives.len())?;
        Ok(Genome::Tf2d(t.primitives.clone()))
    }

    fn at_most(n: usize) -> Result<(), String> {
        if n > MAX_PRIMITIVES {
            return Err(format!(
                "{n} primitives; a genome holds at most {MAX_PRIMITIVES}"
            ));
        }
        Ok(())
    }

    /// A random genome of `space` with 1 to `max` primitives (at most
    /// [`MAX_PRIMITIVES`]).
    pub fn random(space: Space, rng: &mut Rng, max: usize) -> Genome {
        match space {
            Space::Tf1d => Genome::Tf1d(random_list(rng, max)),
            Space::Tf2d => Genome::Tf2d(random_list(rng, max)),
        }
    }

    /// A variation within `radius` (0–1): every parameter of every primitive moves
    /// ([`Gene`]: centres by about radius/4, sizes and heights by a factor of about
    /// e^(±radius), colours by about radius/2); with probability radius/2 a primitive
    /// is added or removed.
    pub fn mutate(&self, rng: &mut Rng, radius: f64) -> Genome {
        let r = radius.clamp(0.0, 1.0);
        match self {
            Genome::Tf1d(p) => Genome::Tf1d(mutate_list(p, rng, r)),
            Genome::Tf2d(p) => Genome::Tf2d(mutate_list(p, rng, r)),
        }
    }

    /// One parameter of one primitive moved within `radius` (its centre, size,
    /// height or colour by the law of [`Gene`], or its shape).
    pub(crate) fn vary_one(&self, rng: &mut Rng, radius: f64) -> Genome {
        let r = radius.clamp(0.0, 1.0);
        let mut out = self.clone();
        each!(&mut out, p => vary_one(p, rng, r));
        out
    }

    /// Blends two parents of one space primitive by primitive, after ordering each
    /// parent's primitives by their value centre so that a primitive meets the other
    /// parent's nearest in value. Parents of different spaces give the first.
    pub(crate) fn blend(a: &Genome, b: &Genome, rng: &mut Rng) -> Genome {
        match (a, b) {
            (Genome::Tf1d(p), Genome::Tf1d(q)) => Genome::Tf1d(blend_lists(p, q, rng)),
            (Genome::Tf2d(p), Genome::Tf2d(q)) => Genome::Tf2d(blend_lists(p, q, rng)),
            _ => a.clone(),
        }
    }

    /// The number of pattern-search coordinates.
    pub(crate) fn param_count(&self) -> usize {
        each!(self, p => coordinates(p))
    }

    /// Pattern-search coordinate `i` ([`Primitive`]).
    pub(crate) fn param(&self, i: usize) -> f64 {
        each!(self, p => coordinate(p, i))
    }

    /// Sets coordinate `i` (clamped to the genome's ranges).
    pub(crate) fn set_param(&mut self, i: usize, v: f64) {
        each!(self, p => set_coordinate(p, i, v))
    }

    /// Primitive `j`'s colour coordinates: the last three of its pattern-search
    /// coordinates, in both spaces (RGB; a 2D primitive's peak opacity is not one).
    pub(crate) fn colour_params(&self, j: usize) -> std::ops::Range<usize> {
        let per = self.param_count() / self.len().max(1);
        j * per + per - 3..(j + 1) * per
    }

    /// First steps of the pattern search at mutation radius `r`.
    pub(crate) fn initial_steps(&self, r: f64) -> Vec<f64> {
        each!(self, p => initial_steps(p, r))
    }

    /// The genome with one primitive in another shape, for every primitive and shape.
    pub(crate) fn shape_variants(&self) -> Vec<Genome> {
        match self {
            Genome::Tf1d(p) => shape_variants(p).into_iter().map(Genome::Tf1d).collect(),
            Genome::Tf2d(p) => shape_variants(p).into_iter().map(Genome::Tf2d).collect(),
        }
    }

    /// The genome's structural neighbours: without each primitive in turn, and with
    /// `adds` random primitives added (while it has fewer than `max`).
    pub(crate) fn structure_variants(&self, max: usize, adds: usize, rng: &mut Rng) -> Vec<Genome> {
        match self {
            Genome::Tf1d(p) => structure_variants(p, max, adds, rng)
                .into_iter()
                .map(Genome::Tf1d)
                .collect(),
            Genome::Tf2d(p) => structure_variants(p, max, adds, rng)
                .into_iter()
                .map(Genome::Tf2d)
                .collect(),
        }
    }

    /// Checks the genome as its plugin checks its `tf` (the message names the
    /// offending part).
    pub fn validate(&self) -> Result<(), String> {
        match self {
            Genome::Tf1d(p) => curve_of(p).validate(),
            Genome::Tf2d(p) => tf2d_of(p).validate(),
        }
    }

    /// The value centre of primitive `i` (tests look at it).
    pub fn centre(&self, i: usize) -> f32 {
        each!(self, p => p[i].value_centre())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Structure variants leave out each primitive in turn and add random ones while
    /// there is room; the same draws give the same variants.
    #[test]
    fn structure_variants_drop_and_add_primitives() {
        for space in [Space::Tf1d, Space::Tf2d] {
            let mut rng = Rng::at(9, 0);
            let g = loop {
                let g = Genome::random(space, &mut rng, 3);
                if g.len() == 3 {
                    break g;
                }
            };
            let v = g.structure_variants(4, 2, &mut Rng::at(1, 1));
            assert_eq!(v.len(), 3 + 2);
            for (i, d) in v[..3].iter().enumerate() {
                assert_eq!(d.len(), 2);
                let mut want = g.clone();
                each!(&mut want, p => { p.remove(i); });
                assert_eq!(d, &want);
            }
            for a in &v[3..] {
                assert_eq!(a.len(), 4);
                a.validate().unwrap();
            }
            assert_eq!(v, g.structure_variants(4, 2, &mut Rng::at(1, 1)));
            // at the most primitives: drops only
            assert_eq!(g.structure_variants(3, 2, &mut Rng::at(1, 1)).len(), 3);
        }
    }

    #[test]
    fn curve_round_trip_is_exact_and_refuses_what_it_cannot_hold() {
        let mut rng = Rng::at(7, 0);
        for _ in 0..200 {
            let g = Genome::random(Space::Tf1d, &mut rng, MAX_PRIMITIVES);
            let c = g.to_curve().unwrap();
            c.validate().unwrap();
            assert_eq!(Genome::from_curve(&c).unwrap(), g);
            // and through RON, as a preset stores it
            let text = ron::to_string(&c).unwrap();
            let back: TfCurve = ron::from_str(&text).unwrap();
            assert_eq!(Genome::from_curve(&back).unwrap(), g);
            let m = g.mutate(&mut rng, 0.5);
            m.to_curve().unwrap().validate().unwrap();
            assert!(!m.is_empty() && m.len() <= MAX_PRIMITIVES);
        }
        let opaque = TfCurve::ramp(0.2, 0.8, [1.0, 1.0, 1.0, 0.5]);
        assert!(
            Genome::from_curve(&opaque)
                .unwrap_err()
                .contains("opaque point")
        );
        let mut many = Genome::random(Space::Tf1d, &mut rng, 1).to_curve().unwrap();
        many.primitives = vec![many.primitives[0]; 9];
        assert!(Genome::from_curve(&many).unwrap_err().contains("at most 8"));
    }

    #[test]
    fn tf2d_round_trip_is_exact_and_every_variation_stays_valid() {
        let mut rng = Rng::at(11, 0);
        let mut shapes = [0usize; 3];
        for _ in 0..200 {
            let g = Genome::random(Space::Tf2d, &mut rng, MAX_PRIMITIVES);
            let ParamValue::Tf2d(t) = g.to_param() else {
                panic!("a 2D genome sets a 2D TF")
            };
            t.validate().unwrap();
            assert_eq!(Genome::from_tf2d(&t).unwrap(), g);
            // through RON, as a preset stores it
            let back: Tf2d = ron::from_str(&ron::to_string(&t).unwrap()).unwrap();
            assert_eq!(Genome::from_tf2d(&back).unwrap(), g);
            let Genome::Tf2d(ps) = &g else { unreachable!() };
            for p in ps {
                shapes[p.shape_index()] += 1;
            }
            let other = Genome::random(Space::Tf2d, &mut rng, 3);
            for v in [
                g.mutate(&mut rng, 0.7),
                g.vary_one(&mut rng, 0.7),
                Genome::blend(&g, &other, &mut rng),
            ] {
                assert_eq!(v.space(), Space::Tf2d);
                v.validate().unwrap();
                assert!(!v.is_empty() && v.len() <= MAX_PRIMITIVES);
            }
            // the pattern search's coordinates read back what they set
            let mut h = g.clone();
            for i in 0..g.param_count() {
                h.set_param(i, g.param(i));
                assert!(
                    (h.param(i) - g.param(i)).abs() < 1e-5,
                    "coordinate {i} of {g:?}"
                );
            }
        }
        assert!(
            shapes.iter().all(|&n| n > 50),
            "every shape drawn: {shapes:?}"
        );
        let nine = Tf2d {
            primitives: vec![Primitive2d::random(&mut rng); 9],
        };
        assert!(Genome::from_tf2d(&nine).unwrap_err().contains("at most 8"));
        assert_eq!(Genome::Tf2d(vec![]).to_curve(), None);
    }

    #[test]
    fn seeded_and_radius_bounded() {
        for space in [Space::Tf1d, Space::Tf2d] {
            let a = Genome::random(space, &mut Rng::at(3, 1), 4);
            let b = Genome::random(space, &mut Rng::at(3, 1), 4);
            assert_eq!(a, b);
            assert_eq!(a.space(), space);
            let still = a.mutate(&mut Rng::at(9, 9), 0.0);
            assert_eq!(still, a, "radius 0 changes nothing");
        }
    }
}
