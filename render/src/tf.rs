//! The transfer-function model: piecewise-linear RGBA control points plus primitives
//! (Gaussian, ramp, box), an optional logarithmic opacity axis, and the lookup-table
//! bake.
//!
//! Composition (our choice; the papers leave it open): the control-point curve and
//! every primitive are independent absorbers, so their opacities combine as
//! α = 1 − (1 − α_curve)·Π(1 − α_i) and the colour is the opacity-weighted mean of
//! their colours (the curve's colour where every opacity is 0). With `log_opacity`
//! the combined opacity a ∈ \[0,1\] is read on a logarithmic axis of three decades,
//! α = (10^(3a) − 1)/(10^3 − 1), so that the low opacities dense data needs get most
//! of the editor's range. The global opacity scale is the plugins' `opacity`
//! parameter.
//!
//! Control points live on the normalised value axis \[0,1\] (0 = the volume's finite
//! minimum, 1 = its maximum). Colours are straight RGBA in \[0,1\]; alpha is the
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

/// Shape of a [`TfPrimitive`] over the normalised value. In RON it is a string
/// (`"gaussian"`, `"ramp"`, `"box"`): parameter values pass through `ron::Value`,
/// which keeps no enum variant names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum PrimitiveShape {
    /// height·exp(−4 ln 2 ((x − centre)/width)²): `width` is the full width at half
    /// maximum.
    Gaussian,
    /// 0 below centre − width/2, rising linearly to `height` at centre + width/2,
    /// `height` above.
    Ramp,
    /// `height` on [centre − width/2, centre + width/2], 0 elsewhere.
    Box,
}

impl PrimitiveShape {
    pub const ALL: [PrimitiveShape; 3] = [Self::Gaussian, Self::Ramp, Self::Box];

    pub fn name(self) -> &'static str {
        match self {
            Self::Gaussian => "gaussian",
            Self::Ramp => "ramp",
            Self::Box => "box",
        }
    }
}

impl From<PrimitiveShape> for String {
    fn from(s: PrimitiveShape) -> String {
        s.name().to_string()
    }
}

impl TryFrom<String> for PrimitiveShape {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| format!("unknown primitive shape '{s}' (gaussian, ramp or box)"))
    }
}

/// A TF primitive: a shape with a straight colour (rgb) and a peak opacity.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TfPrimitive {
    pub shape: PrimitiveShape,
    pub centre: f32,
    pub width: f32,
    pub height: f32,
    pub color: [f32; 3],
}

impl TfPrimitive {
    /// Opacity of the primitive at x.
    pub fn alpha(&self, x: f64) -> f64 {
        let (c, w, h) = (self.centre as f64, self.width as f64, self.height as f64);
        match self.shape {
            PrimitiveShape::Gaussian => {
                let t = (x - c) / w;
                h * (-4.0 * std::f64::consts::LN_2 * t * t).exp()
            }
            PrimitiveShape::Ramp => h * ((x - (c - 0.5 * w)) / w).clamp(0.0, 1.0),
            PrimitiveShape::Box => {
                if (x - c).abs() <= 0.5 * w {
                    h
                } else {
                    0.0
                }
            }
        }
    }
}

fn is_false(b: &bool) -> bool {
    !*b
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TfCurve {
    pub points: Vec<TfPoint>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub primitives: Vec<TfPrimitive>,
    /// Read the combined opacity on a logarithmic axis (module docs).
    #[serde(default, skip_serializing_if = "is_false")]
    pub log_opacity: bool,
}

/// Decades of the logarithmic opacity axis.
pub const LOG_OPACITY_DECADES: f64 = 3.0;

/// The logarithmic opacity axis: a ∈ \[0,1\] → (10^(3a) − 1)/(10^3 − 1).
pub fn log_opacity(a: f64) -> f64 {
    let top = 10f64.powf(LOG_OPACITY_DECADES) - 1.0;
    (10f64.powf(LOG_OPACITY_DECADES * a.clamp(0.0, 1.0)) - 1.0) / top
}

impl TfCurve {
    pub fn new(points: Vec<TfPoint>) -> Self {
        Self {
            points,
            primitives: Vec::new(),
            log_opacity: false,
        }
    }

    /// The curve with primitives added.
    pub fn with_primitives(mut self, primitives: Vec<TfPrimitive>) -> Self {
        self.primitives = primitives;
        self
    }

    /// A grey ramp from transparent at `lo` to `color` at `hi`.
    pub fn ramp(lo: f32, hi: f32, color: [f32; 4]) -> Self {
        let mut c0 = color;
        c0[3] = 0.0;
        Self::new(vec![TfPoint { x: lo, color: c0 }, TfPoint { x: hi, color }])
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
        for (i, p) in self.primitives.iter().enumerate() {
            let name = format!("primitive {i} ({:?})", p.shape);
            if !p.centre.is_finite() {
                return Err(format!("{name}: centre = {} is not finite", p.centre));
            }
            if !(p.width.is_finite() && p.width > 0.0) {
                return Err(format!("{name}: width = {} must be > 0", p.width));
            }
            if !(p.height.is_finite() && (0.0..=1.0).contains(&p.height)) {
                return Err(format!("{name}: height = {} is not in [0, 1]", p.height));
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

    /// The model's value at x (f64): the control-point curve combined with the
    /// primitives, on the chosen opacity axis (module docs).
    pub fn eval(&self, x: f64) -> [f64; 4] {
        let base = self.eval_points(x);
        let mut transmit = 1.0 - base[3];
        let mut weight = base[3];
        let mut rgb = [base[0] * base[3], base[1] * base[3], base[2] * base[3]];
        for p in &self.primitives {
            let a = p.alpha(x).clamp(0.0, 1.0);
            transmit *= 1.0 - a;
            weight += a;
            for (c, v) in rgb.iter_mut().enumerate() {
                *v += p.color[c] as f64 * a;
            }
        }
        let rgb = if weight > 0.0 && !self.primitives.is_empty() {
            rgb.map(|v| v / weight)
        } else {
            [base[0], base[1], base[2]]
        };
        let alpha = 1.0 - transmit;
        let alpha = if self.log_opacity {
            log_opacity(alpha)
        } else {
            alpha
        };
        [rgb[0], rgb[1], rgb[2], alpha]
    }

    /// The control-point curve alone at x: linear between points, constant outside.
    pub fn eval_points(&self, x: f64) -> [f64; 4] {
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

/// Linear interpolation of a baked table at x ∈ \[0,1\], as the GPU's filtered lookup does.
pub fn eval_lut(lut: &[[f32; 4]], x: f64) -> [f64; 4] {
    let n = lut.len();
    if n == 0 {
        return [0.0; 4];
    }
    let (i, j, t) = table_coord(x, n);
    std::array::from_fn(|c| lut[i][c] as f64 * (1.0 - t) + lut[j][c] as f64 * t)
}

/// Where x ∈ \[0,1\] falls in a table of n ≥ 1 entries at i/(n − 1): the two entries
/// around it and the weight of the second, as the GPU's linear filter at
/// (x·(n − 1) + 0.5)/n reads them.
pub fn table_coord(x: f64, n: usize) -> (usize, usize, f64) {
    let f = x.clamp(0.0, 1.0) * (n - 1) as f64;
    let i = (f.floor() as usize).min(n - 1);
    (i, (i + 1).min(n - 1), f - i as f64)
}

/// Bilinear lookup of an n × n table (`at(x, y)`, x fastest) at (u, v) ∈ \[0,1\]², as
/// `textureSampleLevel(…, linear_clamp, …)` at texel-centre coordinates.
pub fn bilinear(n: usize, u: f64, v: f64, at: impl Fn(usize, usize) -> [f64; 4]) -> [f64; 4] {
    let (x0, x1, tx) = table_coord(u, n);
    let (y0, y1, ty) = table_coord(v, n);
    let (a, b, c, d) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
    std::array::from_fn(|k| {
        let top = a[k] * (1.0 - tx) + b[k] * tx;
        let bottom = c[k] * (1.0 - tx) + d[k] * tx;
        top * (1.0 - ty) + bottom * ty
    })
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
        let prim = |width: f32, height: f32| TfPrimitive {
            shape: PrimitiveShape::Gaussian,
            centre: 0.5,
            width,
            height,
            color: [1.0, 0.0, 0.0],
        };
        let e = curve()
            .with_primitives(vec![prim(0.1, 0.5), prim(0.0, 0.5)])
            .validate()
            .unwrap_err();
        assert!(e.contains("primitive 1") && e.contains("width"), "{e}");
        let e = curve()
            .with_primitives(vec![prim(0.1, f32::NAN)])
            .validate()
            .unwrap_err();
        assert!(e.contains("primitive 0") && e.contains("height"), "{e}");
    }

    #[test]
    fn primitives_have_their_documented_shapes() {
        let p = |shape| TfPrimitive {
            shape,
            centre: 0.5,
            width: 0.25,
            height: 0.75,
            color: [0.0, 1.0, 0.0],
        };
        let g = p(PrimitiveShape::Gaussian);
        assert!((g.alpha(0.5) - 0.75).abs() < 1e-12);
        // full width at half maximum
        assert!((g.alpha(0.625) - 0.375).abs() < 1e-12);
        assert!((g.alpha(0.375) - 0.375).abs() < 1e-12);
        let r = p(PrimitiveShape::Ramp);
        assert_eq!(
            (r.alpha(0.3), r.alpha(0.5), r.alpha(0.9)),
            (0.0, 0.375, 0.75)
        );
        let b = p(PrimitiveShape::Box);
        assert_eq!(
            (b.alpha(0.37), b.alpha(0.38), b.alpha(0.63)),
            (0.0, 0.75, 0.0)
        );
    }

    #[test]
    fn primitives_combine_as_independent_absorbers() {
        // transparent curve + a box: the box alone
        let empty = TfCurve::ramp(0.0, 1.0, [0.0, 0.0, 1.0, 0.0]);
        let boxed = empty.clone().with_primitives(vec![TfPrimitive {
            shape: PrimitiveShape::Box,
            centre: 0.5,
            width: 0.2,
            height: 0.5,
            color: [1.0, 0.0, 0.0],
        }]);
        assert_eq!(boxed.eval(0.5), [1.0, 0.0, 0.0, 0.5]);
        assert_eq!(boxed.eval(0.9), [0.0, 0.0, 1.0, 0.0]);
        // curve α 0.5 blue + box α 0.5 red: α = 1 − 0.5², colour the even mix
        let mut both = boxed.clone();
        both.points = vec![TfPoint {
            x: 0.0,
            color: [0.0, 0.0, 1.0, 0.5],
        }];
        let c = both.eval(0.5);
        assert!(
            (c[3] - 0.75).abs() < 1e-12 && (c[0] - 0.5).abs() < 1e-12 && (c[2] - 0.5).abs() < 1e-12
        );
        // logarithmic axis: ends fixed, a = 2/3 → 10² − 1 over 10³ − 1
        let mut log = both;
        log.log_opacity = true;
        assert_eq!(log_opacity(0.0), 0.0);
        assert!((log_opacity(1.0) - 1.0).abs() < 1e-12);
        assert!((log_opacity(2.0 / 3.0) - 99.0 / 999.0).abs() < 1e-12);
        assert!((log.eval(0.5)[3] - log_opacity(0.75)).abs() < 1e-12);
    }

    #[test]
    fn model_round_trips_through_ron_and_old_files_still_load() {
        let mut c = curve().with_primitives(vec![TfPrimitive {
            shape: PrimitiveShape::Ramp,
            centre: 0.7,
            width: 0.1,
            height: 1.0,
            color: [1.0, 1.0, 1.0],
        }]);
        c.log_opacity = true;
        let text = ron::to_string(&c).unwrap();
        assert_eq!(ron::from_str::<TfCurve>(&text).unwrap(), c);
        let old = "(points: [(x: 0.0, color: (0.0, 0.0, 0.0, 0.0)), (x: 1.0, color: (1.0, 1.0, 1.0, 1.0))])";
        let t: TfCurve = ron::from_str(old).unwrap();
        assert!(t.primitives.is_empty() && !t.log_opacity);
    }
}
