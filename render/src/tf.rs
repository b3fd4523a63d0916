//! Piecewise-linear RGBA transfer function and its lookup-table bake.
//!
//! Control points live on the normalised value axis [0,1] (0 = the volume's finite
//! minimum, 1 = its maximum). Colours are straight RGBA in [0,1]; alpha is the
//! opacity for one reference step Δs0 (one voxel). Between points the curve is
//! linear; outside the first/last point it is constant.
//!
//! The GPU reads a baked table of `LUT_SIZE` entries, sampled at x_i = i/(N−1), with
//! linear filtering at coordinate (x·(N−1) + 0.5)/N, which reproduces linear
//! interpolation between table entries. The CPU twin evaluates the same table the
//! same way ([`TfCurve::eval_lut`]), so the twin and the GPU agree to filtering
//! precision; the table itself differs from the exact curve by at most the curve's
//! change within 1/(N−1).

use serde::{Deserialize, Serialize};

pub const LUT_SIZE: usize = 256;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TfPoint {
    pub x: f32,
    pub color: [f32; 4],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TfCurve {
    pub points: Vec<TfPoint>,
}

impl TfCurve {
    pub fn new(points: Vec<TfPoint>) -> Self {
        Self { points }
    }

    /// A grey ramp from transparent at `lo` to `color` at `hi`.
    pub fn ramp(lo: f32, hi: f32, color: [f32; 4]) -> Self {
        let mut c0 = color;
        c0[3] = 0.0;
        Self {
            points: vec![TfPoint { x: lo, color: c0 }, TfPoint { x: hi, color }],
        }
    }

    /// Checks the curve; the message names the offending point.
    pub fn validate(&self) -> Result<(), String> {
        if self.points.is_empty() {
            return Err("transfer function has no control points".into());
        }
        for (i, p) in self.points.iter().enumerate() {
            if !p.x.is_finite() || !(0.0..=1.0).contains(&p.x) {
                return Err(format!("point {i}: x = {} is not in [0, 1]", p.x));
            }
            for (c, v) in p.color.iter().enumerate() {
                if !v.is_finite() || !(0.0..=1.0).contains(v) {
                    return Err(format!(
                        "point {i}: colour component {c} = {v} is not in [0, 1]"
                    ));
                }
            }
            if i > 0 {
                let prev = self.points[i - 1].x;
                if p.x < prev {
                    return Err(format!(
                        "point {i}: x = {} is smaller than point {}'s x = {prev} (points must be sorted)",
                        p.x,
                        i - 1
                    ));
                }
                if p.x == prev {
                    return Err(format!("point {i}: x = {} duplicates point {}", p.x, i - 1));
                }
            }
        }
        Ok(())
    }

    /// Exact curve value at x (f64).
    pub fn eval(&self, x: f64) -> [f64; 4] {
        let pts = &self.points;
        let to64 = |c: [f32; 4]| c.map(|v| v as f64);
        match pts.len() {
            0 => [0.0; 4],
            _ if x <= pts[0].x as f64 => to64(pts[0].color),
            _ if x >= pts[pts.len() - 1].x as f64 => to64(pts[pts.len() - 1].color),
            _ => {
                let i = pts.partition_point(|p| (p.x as f64) <= x);
                let (a, b) = (&pts[i - 1], &pts[i]);
                let t = (x - a.x as f64) / (b.x as f64 - a.x as f64);
                std::array::from_fn(|c| {
                    a.color[c] as f64 + (b.color[c] as f64 - a.color[c] as f64) * t
                })
            }
        }
    }

    /// The table uploaded to the GPU.
    pub fn bake(&self, n: usize) -> Vec<[f32; 4]> {
        (0..n)
            .map(|i| {
                let x = i as f64 / (n.max(2) - 1) as f64;
                self.eval(x).map(|v| v as f32)
            })
            .collect()
    }
}

/// Linear interpolation of a baked table at x ∈ [0,1], as the GPU's filtered lookup does.
pub fn eval_lut(lut: &[[f32; 4]], x: f64) -> [f64; 4] {
    let n = lut.len();
    if n == 0 {
        return [0.0; 4];
    }
    let f = (x.clamp(0.0, 1.0)) * (n - 1) as f64;
    let i = (f.floor() as usize).min(n - 1);
    let j = (i + 1).min(n - 1);
    let t = f - i as f64;
    std::array::from_fn(|c| lut[i][c] as f64 * (1.0 - t) + lut[j][c] as f64 * t)
}

impl TfCurve {
    /// The CPU twin of the GPU lookup: the baked table, linearly interpolated.
    pub fn eval_lut(&self, x: f64) -> [f64; 4] {
        eval_lut(&self.bake(LUT_SIZE), x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve() -> TfCurve {
        TfCurve::new(vec![
            TfPoint {
                x: 0.2,
                color: [0.0, 0.0, 0.0, 0.0],
            },
            TfPoint {
                x: 0.6,
                color: [1.0, 0.5, 0.25, 0.8],
            },
        ])
    }

    #[test]
    fn eval_is_piecewise_linear_and_clamped() {
        let c = curve();
        assert_eq!(c.eval(0.0), [0.0; 4]);
        assert_eq!(c.eval(1.0), [1.0, 0.5, 0.25, 0.8f32 as f64]);
        let m = c.eval(0.4);
        assert!((m[0] - 0.5).abs() < 1e-6 && (m[3] - 0.4).abs() < 1e-6);
    }

    #[test]
    fn lut_matches_curve_at_nodes() {
        let c = curve();
        let lut = c.bake(LUT_SIZE);
        for (i, e) in lut.iter().enumerate() {
            let x = i as f64 / (LUT_SIZE - 1) as f64;
            let want = c.eval(x);
            for k in 0..4 {
                assert!((e[k] as f64 - want[k]).abs() < 1e-6);
            }
            let got = eval_lut(&lut, x);
            assert!((got[3] - want[3]).abs() < 1e-6);
        }
    }

    #[test]
    fn validation_names_the_point() {
        let mut c = curve();
        c.points[1].x = 0.1;
        assert!(c.validate().unwrap_err().contains("point 1"));
        let mut c = curve();
        c.points[0].color[3] = f32::NAN;
        assert!(c.validate().unwrap_err().contains("point 0"));
        let mut c = curve();
        c.points[1].x = 0.2;
        assert!(c.validate().unwrap_err().contains("duplicates"));
        assert!(TfCurve::new(vec![]).validate().is_err());
        let mut c = curve();
        c.points[1].x = 1.5;
        assert!(c.validate().unwrap_err().contains("not in [0, 1]"));
        assert!(curve().validate().is_ok());
    }
}
