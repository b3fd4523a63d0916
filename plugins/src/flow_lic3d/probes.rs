//! `flow.lic3d`'s probes: studies of its f64 twin that need no image, run by experiment
//! files (`probe:`, docs/experiments.md) — the streamline integrators' drift on the
//! analytic rotation, and the twin LIC's CPU time against its error to a finer twin.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::DVec3;
use vwb_render::flow::{Abc, Integrator, LicParams, Noise, Rotation, lic_volume, noise_volume};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{Probe, Statistic};

/// The integrator option every probe takes (the plugin's keys, RK4 by default).
fn integrator_spec() -> ParamSpec {
    ParamSpec::enumeration("integrator", "Integrator", &Integrator::KEYS, 2)
}

/// RMS difference of two scalar volumes in 1/255 (the LIC's unit in docs/flow.md).
pub fn rms_255(a: &[f32], b: &[f32]) -> f64 {
    let n = a.len().min(b.len()).max(1);
    (a.iter()
        .zip(b)
        .map(|(x, y)| ((x - y) as f64 * 255.0).powi(2))
        .sum::<f64>()
        / n as f64)
        .sqrt()
}

/// `flow.lic3d.drift`: the streamline integrators' own error. On the rotation
/// v = (−y, x, 0) every streamline is a circle; seeded at `radius` voxels from the
/// centre and integrated at unit speed (the step is arc length), the drift is how far
/// off that circle the path ends: | |p − c| − r | voxels. The field is linear, so a grid
/// samples it exactly and the drift is the integrator's alone.
pub struct Drift;

impl Probe for Drift {
    fn name(&self) -> &'static str {
        "drift"
    }
    fn description(&self) -> &'static str {
        "streamline drift off the circle after one turn of the rotation v = (−y, x, 0), unit speed"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            integrator_spec(),
            ParamSpec::float_log("step", "Step h (voxels)", 0.01, 4.0, 0.5),
            ParamSpec::float("radius", "Radius (voxels)", 1.0, 64.0, 8.0),
            ParamSpec::int("steps", "Steps (0: one turn, ⌈2πr/h⌉)", 0, 1_000_000, 0),
        ]
    }
    fn figures(&self) -> Vec<(&'static str, &'static str)> {
        vec![
            ("steps", "steps taken"),
            ("drift", "| |p − c| − r | at the end, voxels"),
        ]
    }
    fn run(&self, p: &ParamValues) -> Result<Vec<Statistic>, String> {
        let (h, r) = (p.float("step") as f64, p.float("radius") as f64);
        let steps = match p.int("steps") {
            0 => (std::f64::consts::TAU * r / h).ceil() as usize,
            n => n as usize,
        };
        let c = DVec3::splat(128.0);
        let drift = vwb_render::flow::rotation_drift(
            &Rotation { center: c },
            c,
            r,
            h,
            Integrator::from_key(p.enumeration("integrator")),
            steps,
        );
        Ok(vec![
            Statistic {
                name: "steps",
                value: steps as f64,
            },
            Statistic {
                name: "drift",
                value: drift,
            },
        ])
    }
}

/// The inputs of the finer twin a [`TwinLic`] row is measured against: grid side,
/// half length and step (as bits) and seed.
type ReferenceKey = (u32, u32, u32, u64);

/// That twin's LIC volume and CPU time, once computed (rows of one run share it).
type Reference = (Arc<Vec<f32>>, f64);

/// `flow.lic3d.twin_lic`: the f64 twin's LIC volume of the ABC flow (period = the grid's
/// side) over white noise, tent kernel, against the same LIC with RK4 at a finer step:
/// its CPU time and its RMS difference in 1/255. The GPU's own trade is the
/// `flow_integrators` experiment's.
#[derive(Default)]
pub struct TwinLic {
    references: Mutex<HashMap<ReferenceKey, Reference>>,
}

impl TwinLic {
    fn lic(size: u32, seed: u64, p: &LicParams) -> (Vec<f32>, f64) {
        let abc = Abc {
            period: size as f64,
            ..Default::default()
        };
        let noise = noise_volume([size; 3], Noise::White, seed);
        let t = Instant::now();
        let lic = lic_volume(&abc, &noise, p);
        (lic, t.elapsed().as_secs_f64())
    }
}

impl Probe for TwinLic {
    fn name(&self) -> &'static str {
        "twin_lic"
    }
    fn description(&self) -> &'static str {
        "the f64 twin's LIC of the ABC flow on white noise (tent kernel): CPU time, and RMS error against RK4 at a finer step"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            integrator_spec(),
            ParamSpec::float_log("step", "Step h (voxels)", 0.05, 4.0, 0.5),
            ParamSpec::float("length", "Half length L (voxels)", 1.0, 32.0, 8.0),
            ParamSpec::int("size", "Grid side (voxels)", 8, 256, 64),
            ParamSpec::float_log("reference_step", "Reference step (voxels)", 0.02, 1.0, 0.125),
            ParamSpec::int("seed", "Noise seed", 0, 1_000_000, 7),
        ]
    }
    fn figures(&self) -> Vec<(&'static str, &'static str)> {
        vec![
            ("seconds", "the twin's wall time on this machine's CPUs (rayon), s"),
            ("rms_255", "RMS difference to the reference LIC, 1/255"),
            ("reference_seconds", "the reference's wall time, s"),
        ]
    }
    fn run(&self, p: &ParamValues) -> Result<Vec<Statistic>, String> {
        let size = p.int("size") as u32;
        let seed = p.int("seed") as u64;
        let length = p.float("length");
        let reference_step = p.float("reference_step");
        let lic = |step: f64, integrator: Integrator| LicParams {
            step,
            integrator,
            length: length as f64,
            ..Default::default()
        };
        let key = (size, length.to_bits(), reference_step.to_bits(), seed);
        let cached = self
            .references
            .lock()
            .map_err(|_| "a previous run panicked".to_string())?
            .get(&key)
            .cloned();
        let (reference, reference_seconds) = match cached {
            Some(r) => r,
            None => {
                let (v, s) = Self::lic(size, seed, &lic(reference_step as f64, Integrator::Rk4));
                let r = (Arc::new(v), s);
                self.references
                    .lock()
                    .map_err(|_| "a previous run panicked".to_string())?
                    .insert(key, r.clone());
                r
            }
        };
        let (v, seconds) = Self::lic(
            size,
            seed,
            &lic(
                p.float("step") as f64,
                Integrator::from_key(p.enumeration("integrator")),
            ),
        );
        Ok(vec![
            Statistic {
                name: "seconds",
                value: seconds,
            },
            Statistic {
                name: "rms_255",
                value: rms_255(&v, &reference),
            },
            Statistic {
                name: "reference_seconds",
                value: reference_seconds,
            },
        ])
    }
}
