//! `classify.tf1d`'s probes: the CPU work behind its tables, with no GPU and no image
//! (run by experiment files, `probe:`): rebuilding the pre-integration table, and the
//! transfer-function suggestion from the data's histogram volume.

use std::time::Instant;

use vwb_render::params::{Components, ParamSpec, ParamValues};
use vwb_render::plugin::{Plugin, Probe, Statistic};
use vwb_render::tf::LUT_SIZE;

use super::{Tf1d, preint};

fn figure(name: &'static str, value: f64) -> Statistic {
    Statistic { name, value }
}

/// `classify.tf1d.preint_table`: rebuilding the pre-integration table (256 × 256 from
/// the 256-entry lookup table of a TF, one thread) as a TF edit or a new slice spacing
/// costs it, `builds` times: the median, least and largest wall time. The TF is the
/// first `classify.tf1d` of `preset` (a path; relative to the experiment file), or the
/// plugin's default TF where `preset` is empty.
pub struct PreintTable;

impl Probe for PreintTable {
    fn name(&self) -> &'static str {
        "preint_table"
    }
    fn description(&self) -> &'static str {
        "the pre-integration table's rebuild (256 × 256 from a 256-entry TF, CPU, one thread)"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::path("preset", "Preset whose 1D TF is used (empty: the default TF)", ""),
            ParamSpec::int("builds", "Builds timed", 1, 1000, 50),
        ]
    }
    fn figures(&self) -> Vec<(&'static str, &'static str)> {
        vec![
            ("median_ms", "the median build, ms"),
            ("min_ms", "the fastest build, ms"),
            ("max_ms", "the slowest build, ms"),
        ]
    }
    fn run(&self, p: &ParamValues) -> Result<Vec<Statistic>, String> {
        let mut tf = ParamValues::defaults(&Tf1d::default().params());
        if let Some(path) = p.path("preset").filter(|p| !p.as_os_str().is_empty()) {
            let doc = vwb_render::preset::Document::load(path, &crate::builtin_registry())
                .map_err(|e| e.to_string())?
                .document;
            let inst = doc
                .stack
                .iter()
                .find(|i| i.plugin.id() == "classify.tf1d")
                .ok_or_else(|| format!("{}: no classify.tf1d in the stack", path.display()))?;
            tf = inst.params.clone();
        }
        let lut = tf.tf("tf").ok_or("the TF parameter is missing")?.bake(LUT_SIZE);
        let opacity = tf.float("opacity") as f64;
        let n = p.int("builds").max(1) as usize;
        let mut ms: Vec<f64> = (0..n)
            .map(|k| {
                let start = Instant::now();
                // a new slice spacing each time, as a spacing change rebuilds it
                let t = preint::build(&lut, opacity, 1.0 + k as f64 * 0.01);
                std::hint::black_box(&t);
                start.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        ms.sort_by(f64::total_cmp);
        Ok(vec![
            figure("median_ms", ms[n / 2]),
            figure("min_ms", ms[0]),
            figure("max_ms", ms[n - 1]),
        ])
    }
}

/// `classify.tf1d.suggest`: the transfer-function suggestion (`vwb suggest-tf`, Kindlmann
/// & Durkin's histogram volume) for a sample data set by name (`vwb data list`; empty:
/// the embedded demo volume) or for the synthetic tomogram
/// ([`vwb_render::suggest::noisy_ball`] at `ball_contrast` ≥ 0), with the noise handling
/// or without it (`filtered`): the time to load the data and to suggest, and what it
/// found.
pub struct Suggest;

impl Probe for Suggest {
    fn name(&self) -> &'static str {
        "suggest"
    }
    fn description(&self) -> &'static str {
        "the transfer-function suggestion from the histogram volume of a sample data set"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::volume(
                "sample",
                "Sample data set (empty: the demo volume)",
                Components::Scalar,
            ),
            ParamSpec::float("ball_contrast", "Synthetic tomogram's contrast (−1: the sample)", -1.0, 1.0, -1.0),
            ParamSpec::boolean("filtered", "Noise handling", true),
        ]
    }
    fn figures(&self) -> Vec<(&'static str, &'static str)> {
        vec![
            ("load_seconds", "reading the volume, s"),
            ("seconds", "the suggestion (histogram volume, derivatives, TF), s"),
            ("boundary_bins", "value bins on a boundary (of 256)"),
            ("noise_floor", "the median |∇f| over interior voxels"),
            ("sigma", "the boundary blur σ, voxels"),
            ("smoothing", "the pre-filter σ, voxels"),
            ("first_boundary", "the middle of the first boundary above the background (— where none)"),
            ("found", "1 where some value is on a boundary, 0 where the suggestion says none"),
        ]
    }
    fn run(&self, p: &ParamValues) -> Result<Vec<Statistic>, String> {
        let start = Instant::now();
        let contrast = p.float("ball_contrast");
        let volume = match p.volume("sample") {
            _ if contrast >= 0.0 => vwb_render::suggest::noisy_ball(contrast as f64),
            "" => vwb_render::volume::demo(),
            name => {
                let path = vwb_render::samples::resolve(name).map_err(|e| e.to_string())?;
                vwb_render::volume::load(&path).map_err(|e| format!("{}: {e}", path.display()))?
            }
        };
        let load_seconds = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let options = if p.boolean("filtered") {
            vwb_render::suggest::SuggestOptions::default()
        } else {
            vwb_render::suggest::SuggestOptions::unfiltered()
        };
        let s = vwb_render::suggest::suggest(&volume, &options).map_err(|e| e.to_string())?;
        let seconds = start.elapsed().as_secs_f64();
        Ok(vec![
            figure("load_seconds", load_seconds),
            figure("seconds", seconds),
            figure("boundary_bins", s.boundary_bins() as f64),
            figure("noise_floor", s.noise_floor),
            figure("sigma", s.sigma),
            figure("smoothing", s.smoothing),
            figure("first_boundary", s.first_boundary().unwrap_or(f64::NAN)),
            figure("found", if s.found() { 1.0 } else { 0.0 }),
        ])
    }
}
