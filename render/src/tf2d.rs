//! The 2D transfer-function model over (value, gradient magnitude), both normalised
//! to \[0,1\] (Kniss, Kindlmann and Hansen 2001; Rezk-Salama 2001 §3): primitives
//! with a straight RGBA colour, combined like the 1D model's primitives (independent
//! absorbers, opacity-weighted colour; `crate::tf`), baked into an n × n table.
//!
//! Shapes (centre (v_c, g_c), size (w, h), peak opacity = colour alpha):
//! - `rectangle`: constant on |v − v_c| ≤ w/2, |g − g_c| ≤ h/2.
//! - `triangle` (Kniss et al.): apex at (v_c, 0), widening linearly to width w at
//!   gradient g = h; opacity falls linearly from the centre line to its edges. The
//!   classic boundary selector: at a boundary between two materials the gradient peaks
//!   at the mid value. `g_c` is unused.
//! - `gaussian`: exp(−4 ln 2 ((v − v_c)/w)² − 4 ln 2 ((g − g_c)/h)²): w and h are full
//!   widths at half maximum.

use serde::{Deserialize, Serialize};

/// Shape of a 2D primitive; a string in RON (parameter values pass through
/// `ron::Value`, which keeps no enum variant names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Shape2d {
    Rectangle,
    Triangle,
    Gaussian,
}

impl Shape2d {
    pub const ALL: [Shape2d; 3] = [Self::Rectangle, Self::Triangle, Self::Gaussian];
    pub fn name(self) -> &'static str {
        match self {
            Self::Rectangle => "rectangle",
            Self::Triangle => "triangle",
            Self::Gaussian => "gaussian",
        }
    }
}

impl From<Shape2d> for String {
    fn from(s: Shape2d) -> String {
        s.name().to_string()
    }
}

impl TryFrom<String> for Shape2d {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                format!("unknown 2D primitive shape '{s}' (rectangle, triangle or gaussian)")
            })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Primitive2d {
    pub shape: Shape2d,
    /// (value, gradient magnitude)
    pub centre: [f32; 2],
    /// (width along value, height along gradient magnitude)
    pub size: [f32; 2],
    /// Straight RGB and peak opacity per voxel.
    pub color: [f32; 4],
}

impl Primitive2d {
    /// Opacity at (v, g).
    pub fn alpha(&self, v: f64, g: f64) -> f64 {
        let (vc, gc) = (self.centre[0] as f64, self.centre[1] as f64);
        let (w, h) = (self.size[0] as f64, self.size[1] as f64);
        let a = self.color[3] as f64;
        match self.shape {
            Shape2d::Rectangle => {
                if (v - vc).abs() <= 0.5 * w && (g - gc).abs() <= 0.5 * h {
                    a
                } else {
                    0.0
                }
            }
            Shape2d::Triangle => {
                if !(0.0..=h).contains(&g) {
                    return 0.0;
                }
                let half = 0.5 * w * g / h;
                if half <= 0.0 {
                    return 0.0;
                }
                a * (1.0 - (v - vc).abs() / half).max(0.0)
            }
            Shape2d::Gaussian => {
                let k = 4.0 * std::f64::consts::LN_2;
                let (tv, tg) = ((v - vc) / w, (g - gc) / h);
                a * (-k * (tv * tv + tg * tg)).exp()
            }
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Tf2d {
    pub primitives: Vec<Primitive2d>,
}

impl Tf2d {
    /// Checks the primitives; the message names the offending one.
    pub fn validate(&self) -> Result<(), String> {
        for (i, p) in self.primitives.iter().enumerate() {
            let name = format!("primitive {i} ({})", p.shape.name());
            if !p.centre.iter().all(|c| c.is_finite()) {
                return Err(format!("{name}: centre {:?} is not finite", p.centre));
            }
            if !p.size.iter().all(|s| s.is_finite() && *s > 0.0) {
                return Err(format!("{name}: size {:?} must be > 0", p.size));
            }
            for (c, v) in p.color.iter().enumerate() {
                if !v.is_finite() || !(0.0..=1.0).contains(v) {
                    return Err(format!(
                        "{name}: colour component {c} = {v} is not in [0, 1]"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Straight RGBA at (v, g): independent absorbers, opacity-weighted colour.
    pub fn eval(&self, v: f64, g: f64) -> [f64; 4] {
        let (mut transmit, mut weight, mut rgb) = (1.0, 0.0, [0.0f64; 3]);
        for p in &self.primitives {
            let a = p.alpha(v, g).clamp(0.0, 1.0);
            transmit *= 1.0 - a;
            weight += a;
            for (c, x) in rgb.iter_mut().enumerate() {
                *x += p.color[c] as f64 * a;
            }
        }
        if weight > 0.0 {
            rgb = rgb.map(|x| x / weight);
        }
        [rgb[0], rgb[1], rgb[2], 1.0 - transmit]
    }

    /// Entry (i, j) of the n × n table: value i/(n − 1), gradient j/(n − 1).
    fn entry(&self, n: usize, i: usize, j: usize) -> [f32; 4] {
        let step = 1.0 / (n.max(2) - 1) as f64;
        self.eval(i as f64 * step, j as f64 * step)
            .map(|x| x as f32)
    }

    /// The n × n table (value along x, gradient magnitude along y), entries at
    /// i/(n − 1). Entries are independent and evaluated in parallel (a 256² table of
    /// a few Gaussians takes milliseconds serially, and a TF search bakes one per
    /// genome).
    pub fn bake(&self, n: usize) -> Vec<[f32; 4]> {
        use rayon::prelude::*;
        (0..n * n)
            .into_par_iter()
            .map(|k| self.entry(n, k % n, k / n))
            .collect()
    }

    /// Per value column of the n × n table, whether some entry's opacity × `opacity`
    /// is above 0: what `bake` would give, without baking the table (a column stops at
    /// its first visible entry).
    pub fn visible_columns(&self, n: usize, opacity: f32) -> Vec<bool> {
        use rayon::prelude::*;
        (0..n)
            .into_par_iter()
            .map(|i| (0..n).any(|j| self.entry(n, i, j)[3] * opacity > 0.0))
            .collect()
    }
}

/// |∇f| at voxel `at` of a scalar grid of `dims` (x fastest): central differences with
/// clamped neighbours, in value per voxel, f32 as the GPU's pre-pass stores it. The
/// 2D TF's gradient axis reads it (`classify.tf2d`'s pre-pass and histogram, the
/// coverage objective's samples).
pub fn voxel_gradient(scalars: &[f32], dims: [usize; 3], at: [usize; 3]) -> f32 {
    let idx = |p: [usize; 3]| (p[2] * dims[1] + p[1]) * dims[0] + p[0];
    let diff = |a: usize| {
        let (mut lo, mut hi) = (at, at);
        lo[a] = at[a].saturating_sub(1);
        hi[a] = (at[a] + 1).min(dims[a] - 1);
        scalars[idx(hi)] - scalars[idx(lo)]
    };
    let (gx, gy, gz) = (diff(0), diff(1), diff(2));
    0.5 * (gx * gx + gy * gy + gz * gz).sqrt()
}

/// Bilinear lookup of a baked n × n table at (v, g) ∈ \[0,1\]², as the GPU's filtered
/// read at ((v·(n−1) + 0.5)/n, (g·(n−1) + 0.5)/n).
pub fn eval_table(table: &[[f32; 4]], n: usize, v: f64, g: f64) -> [f64; 4] {
    if n == 0 || table.len() < n * n {
        return [0.0; 4];
    }
    crate::tf::bilinear(n, v, g, |x, y| table[y * n + x].map(f64::from))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prim(shape: Shape2d) -> Primitive2d {
        Primitive2d {
            shape,
            centre: [0.5, 0.5],
            size: [0.25, 0.5],
            color: [1.0, 0.5, 0.0, 0.75],
        }
    }

    #[test]
    fn shapes_follow_their_definitions() {
        let r = prim(Shape2d::Rectangle);
        assert_eq!(
            (r.alpha(0.5, 0.5), r.alpha(0.6, 0.7), r.alpha(0.7, 0.5)),
            (0.75, 0.75, 0.0)
        );
        let t = prim(Shape2d::Triangle);
        // apex at g = 0: nothing; at g = h the full width w
        assert_eq!(t.alpha(0.5, 0.0), 0.0);
        assert_eq!(t.alpha(0.5, 0.5), 0.75);
        assert!((t.alpha(0.5625, 0.5) - 0.375).abs() < 1e-12);
        // at half height, half the width: v = 0.5625 is on the edge
        assert_eq!(t.alpha(0.5625, 0.25), 0.0);
        assert_eq!(t.alpha(0.5, 0.6), 0.0);
        let g = prim(Shape2d::Gaussian);
        assert!((g.alpha(0.5, 0.5) - 0.75).abs() < 1e-12);
        assert!((g.alpha(0.625, 0.5) - 0.375).abs() < 1e-12);
        assert!((g.alpha(0.5, 0.75) - 0.375).abs() < 1e-12);
    }

    #[test]
    fn table_lookup_reproduces_the_model_at_nodes() {
        let tf = Tf2d {
            primitives: vec![prim(Shape2d::Gaussian), prim(Shape2d::Rectangle)],
        };
        let n = 64;
        let table = tf.bake(n);
        // the visible columns are the baked table's
        let mut sparse = tf.clone();
        sparse.primitives[1].shape = Shape2d::Triangle;
        for t in [&tf, &sparse] {
            let baked = t.bake(n);
            let columns: Vec<bool> = (0..n)
                .map(|i| (0..n).any(|j| baked[j * n + i][3] * 0.5 > 0.0))
                .collect();
            assert_eq!(t.visible_columns(n, 0.5), columns);
        }
        for (i, j) in [(0, 0), (10, 40), (32, 31), (63, 63)] {
            let (v, g) = (i as f64 / 63.0, j as f64 / 63.0);
            let got = eval_table(&table, n, v, g);
            let want = tf.eval(v, g);
            for c in 0..4 {
                assert!((got[c] - want[c]).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn validation_names_the_primitive_and_ron_round_trips() {
        let mut tf = Tf2d {
            primitives: vec![prim(Shape2d::Triangle), prim(Shape2d::Gaussian)],
        };
        assert!(tf.validate().is_ok());
        let text = ron::to_string(&tf).unwrap();
        assert!(text.contains("\"triangle\""), "{text}");
        assert_eq!(ron::from_str::<Tf2d>(&text).unwrap(), tf);
        tf.primitives[1].size[1] = 0.0;
        let e = tf.validate().unwrap_err();
        assert!(
            e.contains("primitive 1 (gaussian)") && e.contains("size"),
            "{e}"
        );
        tf.primitives[1].size[1] = 0.1;
        tf.primitives[0].color[3] = f32::NAN;
        assert!(tf.validate().unwrap_err().contains("primitive 0"));
    }
}
