//! `flow.arrival`'s probe: the accuracy of its f64 twin's arrival times on the analytic
//! rotation, where the exact time is known (run by experiment files, `probe:`).

use glam::DVec3;
use vwb_render::flow::{ArrivalParams, Integrator, Rotation, SeedBox, arrival_at};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{Probe, Statistic};

/// `flow.arrival.rotation`: on v = (−y, x, 0) (angular speed 1) with the seed a
/// one-voxel-thick box on the ray θ = 0, matter reaches angle θ at radius r at time
/// θ − asin(½/r) (it leaves the box's far face, half a voxel off the ray). The error is
/// |t − exact| / exact over r ∈ {8, 16, 32, 48} × θ ∈ {0.5, 1.5, 3, 4.5, 6} rad; a point
/// the twin never reaches counts as 1.
pub struct OnRotation;

impl Probe for OnRotation {
    fn name(&self) -> &'static str {
        "rotation"
    }
    fn description(&self) -> &'static str {
        "arrival time against the exact θ − asin(½/r) on the rotation v = (−y, x, 0), seed on the ray θ = 0"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::enumeration("integrator", "Integrator", &Integrator::KEYS, 2),
            ParamSpec::float_log("step", "Step h (voxels)", 0.05, 4.0, 0.5),
        ]
    }
    fn figures(&self) -> Vec<(&'static str, &'static str)> {
        vec![
            ("rms", "RMS of |t − exact| / exact over the 20 points"),
            ("worst", "the largest |t − exact| / exact"),
        ]
    }
    fn run(&self, p: &ParamValues) -> Result<Vec<Statistic>, String> {
        let c = DVec3::new(64.0, 64.0, 2.0);
        let rot = Rotation { center: c };
        let dims = [128, 128, 4];
        let seed = SeedBox {
            min: DVec3::new(64.5 / 128.0, 64.0 / 128.0, 0.0),
            max: DVec3::new(1.0, 65.0 / 128.0, 1.0),
        };
        let a = ArrivalParams {
            step: p.float("step") as f64,
            max_length: 1024.0,
            integrator: Integrator::from_key(p.enumeration("integrator")),
        };
        let (mut sq, mut worst, mut n) = (0.0f64, 0.0f64, 0);
        for r in [8.0f64, 16.0, 32.0, 48.0] {
            for theta in [0.5f64, 1.5, 3.0, 4.5, 6.0] {
                let at = c + DVec3::new(r * theta.cos(), r * theta.sin(), 0.0);
                let exact = theta - (0.5 / r).asin();
                let t = arrival_at(&rot, dims, &seed, at, &a);
                let e = if t.is_finite() {
                    (t - exact).abs() / exact
                } else {
                    1.0
                };
                sq += e * e;
                worst = worst.max(e);
                n += 1;
            }
        }
        Ok(vec![
            Statistic {
                name: "rms",
                value: (sq / n as f64).sqrt(),
            },
            Statistic {
                name: "worst",
                value: worst,
            },
        ])
    }
}
