//! The TF genome: up to [`MAX_PRIMITIVES`] primitives (Gaussian, ramp, box), each with a
//! centre, a width, a height (opacity per Δs0) and a colour, over a fully transparent
//! curve. It maps exactly onto `classify.tf1d`'s `tf` ([`Genome::to_curve`]) and back
//! ([`Genome::from_curve`]) for every curve whose points are all transparent.

use serde::{Deserialize, Serialize};

use crate::rng::Rng;
use crate::tf::{PrimitiveShape, TfCurve, TfPoint, TfPrimitive};

/// The most primitives a genome holds.
pub const MAX_PRIMITIVES: usize = 8;

/// A transfer function as a list of primitives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Genome {
    pub primitives: Vec<TfPrimitive>,
}

/// Ranges random genomes are drawn from.
pub(crate) const WIDTH: (f64, f64) = (0.02, 0.35);
const HEIGHT: (f64, f64) = (0.004, 0.6);
/// The least height a variation leaves a primitive (it keeps its place in the genome).
pub(crate) const MIN_HEIGHT: f64 = 1.0e-4;

/// A parameter of a primitive as variations move it, within radius r: the centre by
/// N(0, r/4), the width and the height by a factor e^N(0, r), each colour channel by
/// N(0, r/2); each clamped to its range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Gene {
    Centre,
    Width,
    Height,
    Colour,
}

impl Gene {
    pub(crate) const ALL: [Gene; 4] = [Gene::Centre, Gene::Width, Gene::Height, Gene::Colour];

    /// Moves this parameter of `p` within radius `r` (0–1).
    pub(crate) fn nudge(self, p: &mut TfPrimitive, rng: &mut Rng, r: f64) {
        match self {
            Gene::Centre => {
                p.centre = (p.centre as f64 + rng.normal() * r * 0.25).clamp(0.0, 1.0) as f32
            }
            Gene::Width => {
                p.width = (p.width as f64 * (rng.normal() * r).exp()).clamp(WIDTH.0, 1.0) as f32
            }
            Gene::Height => {
                p.height =
                    (p.height as f64 * (rng.normal() * r).exp()).clamp(MIN_HEIGHT, 1.0) as f32
            }
            Gene::Colour => {
                for c in &mut p.color {
                    *c = (*c as f64 + rng.normal() * r * 0.5).clamp(0.0, 1.0) as f32;
                }
            }
        }
    }
}

impl Genome {
    /// The `tf` curve: transparent end points and the primitives.
    pub fn to_curve(&self) -> TfCurve {
        let clear = |x| TfPoint { x, color: [0.0; 4] };
        TfCurve {
            points: vec![clear(0.0), clear(1.0)],
            primitives: self.primitives.clone(),
            log_opacity: false,
        }
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
        if c.primitives.len() > MAX_PRIMITIVES {
            return Err(format!(
                "{} primitives; a genome holds at most {MAX_PRIMITIVES}",
                c.primitives.len()
            ));
        }
        Ok(Genome {
            primitives: c.primitives.clone(),
        })
    }

    /// A random genome of 1 to `max` primitives (at most [`MAX_PRIMITIVES`]).
    pub fn random(rng: &mut Rng, max: usize) -> Genome {
        let n = 1 + (rng.uniform() * max.clamp(1, MAX_PRIMITIVES) as f64) as usize;
        Genome {
            primitives: (0..n.min(MAX_PRIMITIVES))
                .map(|_| random_primitive(rng))
                .collect(),
        }
    }

    /// A variation within `radius` (0–1): every parameter of every primitive moves
    /// ([`Gene::nudge`]: centres by about radius/4, widths and heights by a factor of
    /// about e^(±radius), colours by about radius/2); with probability radius/2 a
    /// primitive is added or removed.
    pub fn mutate(&self, rng: &mut Rng, radius: f64) -> Genome {
        let r = radius.clamp(0.0, 1.0);
        let mut out: Vec<TfPrimitive> = self
            .primitives
            .iter()
            .map(|p| {
                let mut q = *p;
                for gene in Gene::ALL {
                    gene.nudge(&mut q, rng, r);
                }
                q
            })
            .collect();
        if rng.uniform() < r * 0.5 {
            if out.len() < MAX_PRIMITIVES && (out.len() <= 1 || rng.uniform() < 0.5) {
                out.push(random_primitive(rng));
            } else if out.len() > 1 {
                let i = (rng.uniform() * out.len() as f64) as usize;
                out.remove(i.min(out.len() - 1));
            }
        }
        Genome { primitives: out }
    }
}

fn random_primitive(rng: &mut Rng) -> TfPrimitive {
    let shape = PrimitiveShape::ALL[(rng.uniform() * 3.0) as usize % 3];
    let log = |(lo, hi): (f64, f64), u: f64| (lo.ln() + (hi.ln() - lo.ln()) * u).exp();
    TfPrimitive {
        shape,
        centre: rng.uniform() as f32,
        width: log(WIDTH, rng.uniform()) as f32,
        // ramps and boxes cover more of the value axis: keep them fainter
        height: (log(HEIGHT, rng.uniform())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curve_round_trip_is_exact_and_refuses_what_it_cannot_hold() {
        let mut rng = Rng::at(7, 0);
        for _ in 0..200 {
            let g = Genome::random(&mut rng, MAX_PRIMITIVES);
            let c = g.to_curve();
            c.validate().unwrap();
            assert_eq!(Genome::from_curve(&c).unwrap(), g);
            // and through RON, as a preset stores it
            let text = ron::to_string(&c).unwrap();
            let back: TfCurve = ron::from_str(&text).unwrap();
            assert_eq!(Genome::from_curve(&back).unwrap(), g);
            let m = g.mutate(&mut rng, 0.5);
            m.to_curve().validate().unwrap();
            assert!(!m.primitives.is_empty() && m.primitives.len() <= MAX_PRIMITIVES);
        }
        let opaque = TfCurve::ramp(0.2, 0.8, [1.0, 1.0, 1.0, 0.5]);
        assert!(
            Genome::from_curve(&opaque)
                .unwrap_err()
                .contains("opaque point")
        );
        let mut many = Genome::random(&mut rng, 1).to_curve();
        many.primitives = vec![many.primitives[0]; 9];
        assert!(Genome::from_curve(&many).unwrap_err().contains("at most 8"));
    }

    #[test]
    fn seeded_and_radius_bounded() {
        let a = Genome::random(&mut Rng::at(3, 1), 4);
        let b = Genome::random(&mut Rng::at(3, 1), 4);
        assert_eq!(a, b);
        let still = a.mutate(&mut Rng::at(9, 9), 0.0);
        assert_eq!(still, a, "radius 0 changes nothing");
    }
}
