//! Experiments of a plugin's probe ([`vwb_render::plugin::Probe`]): a study of its CPU
//! twin that needs no image and no GPU — an integrator's drift on an analytic field, a
//! twin's error against a finer twin of itself. The file names the probe instead of
//! scenes; variants `set` the probe's parameters, the grid sweeps them, and the probe's
//! figures are the table's columns, the Pareto front's axes and the assertions' terms:
//!
//! ```ron
//! Experiment(
//!     name: "flow_drift",
//!     probe: (id: "flow.lic3d.drift"),
//!     variants: [(name: "Euler", set: {"integrator": "euler"}), (name: "RK4", set: {"integrator": "rk4"})],
//!     grid: [(param: "step", values: [1.0, 0.5])],
//!     assertions: ["drift(RK4) < 1e-5"],
//! )
//! ```

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Result, anyhow, bail};
use vwb_render::params::{ParamKind, ParamSpec, ParamValue, ParamValues};
use vwb_render::plugin::Probe;

use super::{
    Assertion, Event, Experiment, Outcome, ProbeSpec, ReferenceSpec, Row, axis_values, described,
    finish, listed, mark_front, no_metrics, param_value,
};
use crate::measure::{self, Axis};

/// The `clock` of a probe's rows (they have no frame).
pub(super) const CLOCK: &str = "cpu";

/// The probe `<plugin id>.<probe name>` of the built-in plugins.
pub fn find(id: &str) -> Result<Arc<dyn Probe>, String> {
    let (plugin, name) = id
        .rsplit_once('.')
        .ok_or_else(|| format!("probe '{id}' is not of the form <plugin id>.<probe name>"))?;
    let registry = vwb_plugins::builtin_registry();
    let p = registry
        .get(plugin)
        .map_err(|_| format!("probe '{id}': no plugin '{plugin}'"))?;
    let probes = p.probes();
    let names: Vec<&str> = probes.iter().map(|p| p.name()).collect();
    probes
        .into_iter()
        .find(|p| p.name() == name)
        .ok_or_else(|| {
            format!(
                "plugin '{plugin}' has no probe '{name}' (it has: {})",
                listed(&names, "none")
            )
        })
}

/// A probe's parameter `key` (in errors: of probe `id`).
fn spec<'a>(specs: &'a [ParamSpec], id: &str, key: &str) -> Result<&'a ParamSpec, String> {
    specs.iter().find(|s| s.key == key).ok_or_else(|| {
        let keys: Vec<&str> = specs.iter().map(|s| s.key).collect();
        format!(
            "probe '{id}' has no parameter '{key}' (it has: {})",
            keys.join(", ")
        )
    })
}

/// The value of a grid axis on a float or int parameter.
fn axis_value(spec: &ParamSpec, v: f64) -> Result<ParamValue, String> {
    let value = match spec.kind {
        ParamKind::Float { .. } => ParamValue::Float(v as f32),
        ParamKind::Int { .. } => ParamValue::Int(v.round() as i32),
        _ => {
            return Err(format!(
                "only float and int parameters can be swept ('{}' is {})",
                spec.key,
                spec.kind_name()
            ));
        }
    };
    spec.check(&value)?;
    Ok(value)
}

/// Checks a probe's experiment (`e.probe` is set) as [`super::parse`] checks others:
/// the probe exists; no scenes and nothing of an image (references, render overrides,
/// swaps, crops, searches); every `set` key and grid axis is a parameter of the probe,
/// with values in range; `statistics` are its figures (all of them when left out);
/// the Pareto figures and every assertion's terms and variants exist. The image
/// metrics are dropped.
pub(super) fn checked(mut e: Experiment, path: &Path) -> Result<Experiment> {
    let file = path.display();
    let spec_of = e.probe.clone().expect("a probe's experiment");
    let id = spec_of.id.as_str();
    let probe = find(id).map_err(|err| anyhow!("{file}: {err}"))?;
    if !e.scenes.is_empty() {
        bail!(
            "{file}: an experiment of probe '{id}' has no scenes (the probe computes without an image)"
        );
    }
    if e.reference != ReferenceSpec::default()
        || !e.reference_options.is_empty()
        || e.render.size.is_some()
        || e.render.target.is_some()
        || e.render.backend.is_some()
        || e.render.early_termination.is_some()
    {
        bail!(
            "{file}: an experiment of probe '{id}' renders nothing: leave out reference, reference_options and render"
        );
    }
    let specs = probe.params();
    let figures: Vec<String> = probe.figures().iter().map(|(n, _)| n.to_string()).collect();
    let mut names = std::collections::HashSet::new();
    for v in &e.variants {
        if !names.insert(v.name.as_str()) {
            bail!("{file}: two variants are named '{}'", v.name);
        }
        if !v.swap.is_empty()
            || !v.disable.is_empty()
            || !v.enable.is_empty()
            || v.reference.is_some()
            || v.crop.is_some()
            || v.search.is_some()
            || v.gallery.is_some()
            || v.suggest.is_some()
        {
            bail!(
                "{file}: variant '{}' of probe '{id}' may only `set` the probe's parameters",
                v.name
            );
        }
        for (key, value) in &v.set {
            let s = spec(&specs, id, key)
                .map_err(|err| anyhow!("{file}: variant '{}': {err}", v.name))?;
            param_value(key, s, value)
                .map_err(|err| anyhow!("{file}: variant '{}': {err}", v.name))?;
        }
    }
    for a in &e.grid {
        let s = spec(&specs, id, &a.param).map_err(|err| anyhow!("{file}: grid axis: {err}"))?;
        for v in axis_values(a).map_err(|err| anyhow!("{file}: grid axis '{}': {err}", a.param))? {
            axis_value(s, v).map_err(|err| anyhow!("{file}: grid axis '{}': {err}", a.param))?;
        }
    }
    if e.statistics.is_empty() {
        e.statistics = figures.clone();
    }
    let unknown = |f: &str| !figures.iter().any(|x| x == f);
    for st in &e.statistics {
        if unknown(st) {
            bail!(
                "{file}: probe '{id}' reports no '{st}' (it reports: {})",
                figures.join(", ")
            );
        }
    }
    if let Some((t, err)) = &spec_of.pareto {
        for f in [t, err] {
            if unknown(f) {
                bail!(
                    "{file}: pareto: probe '{id}' reports no '{f}' (it reports: {})",
                    figures.join(", ")
                );
            }
        }
    }
    for a in &e.assertions {
        let parsed = Assertion::parse_in(a, &figures)
            .map_err(|err| anyhow!("{file}: assertion '{a}': {err}"))?;
        for v in parsed.variants() {
            if !names.contains(v) {
                bail!(
                    "{file}: assertion '{a}' names variant '{v}', which the experiment does not declare"
                );
            }
        }
        if parsed
            .terms()
            .iter()
            .any(|t| matches!(t.metric, super::Measure::Metric(_)))
        {
            bail!(
                "{file}: assertion '{a}' reads an image metric; probe '{id}' reports only its figures ({})",
                figures.join(", ")
            );
        }
        for st in parsed.statistics() {
            if unknown(st) {
                bail!(
                    "{file}: assertion '{a}': probe '{id}' reports no '{st}' (it reports: {})",
                    figures.join(", ")
                );
            }
            if !e.statistics.iter().any(|x| x == st) {
                bail!("{file}: assertion '{a}' reads '{st}', which `statistics` does not list");
            }
        }
    }
    e.metrics.clear();
    Ok(e)
}

/// The parameters of one row: the probe's defaults, the experiment's seed (into a
/// parameter named `seed`), the variant's `set`, then the grid point; a relative path
/// is taken from `dir`, the experiment file's folder.
fn row_params(
    probe: &dyn Probe,
    e: &Experiment,
    dir: &Path,
    set: &BTreeMap<String, super::SetValue>,
    point: &[f64],
) -> Result<ParamValues> {
    let specs = probe.params();
    let mut p = ParamValues::defaults(&specs);
    if let Some(seed) = e.seed
        && specs
            .iter()
            .any(|s| s.key == "seed" && matches!(s.kind, ParamKind::Int { .. }))
    {
        p.set("seed", ParamValue::Int((seed % i32::MAX as u64) as i32));
    }
    for (key, value) in set {
        let s = spec(&specs, "", key).map_err(|err| anyhow!(err))?;
        let v = match param_value(key, s, value)? {
            ParamValue::Path(path) if path.is_relative() && !path.as_os_str().is_empty() => {
                ParamValue::Path(dir.join(path))
            }
            v => v,
        };
        p.set(key, v);
    }
    for (a, v) in e.grid.iter().zip(point) {
        let s = spec(&specs, "", &a.param).map_err(|err| anyhow!(err))?;
        p.set(&a.param, axis_value(s, *v).map_err(|err| anyhow!(err))?);
    }
    Ok(p)
}

/// Runs a probe's experiment (checked by [`checked`]): every variant at every grid
/// point, first axis slowest; then the front, the assertions and the report, as
/// [`super::run`] does for images.
pub(super) fn run(
    e: &Experiment,
    file: &Path,
    out: &Path,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Outcome> {
    let fname = file.display();
    let dir = file.parent().unwrap_or(Path::new("."));
    let spec = e.probe.as_ref().expect("a probe's experiment");
    let probe = find(&spec.id).map_err(|err| anyhow!("{fname}: {err}"))?;
    let axes: Vec<Axis> = e
        .grid
        .iter()
        .map(|a| {
            Ok(Axis {
                name: a.param.clone(),
                target: measure::AxisTarget::Spacing,
                values: axis_values(a)
                    .map_err(|err| anyhow!("{fname}: grid '{}': {err}", a.param))?,
            })
        })
        .collect::<Result<_>>()?;
    let points = measure::grid(&axes);
    let as_is = [super::Variant {
        name: "defaults".into(),
        ..Default::default()
    }];
    let variants = if e.variants.is_empty() {
        &as_is[..]
    } else {
        &e.variants[..]
    };
    let mut rows: Vec<Row> = Vec::new();
    for v in variants {
        for point in &points {
            let params = row_params(probe.as_ref(), e, dir, &v.set, point)
                .map_err(|err| anyhow!("{fname}: variant '{}': {err}", v.name))?;
            let figures = probe.run(&params).map_err(|err| {
                anyhow!("{fname}: probe '{}', variant '{}': {err}", spec.id, v.name)
            })?;
            let mut statistics = BTreeMap::new();
            for st in &e.statistics {
                let value = figures
                    .iter()
                    .find(|f| f.name == st)
                    .ok_or_else(|| anyhow!("{fname}: probe '{}' did not report '{st}'", spec.id))?
                    .value;
                statistics.insert(st.clone(), value);
            }
            rows.push(Row {
                scene: spec.id.clone(),
                variant: v.name.clone(),
                values: point.clone(),
                slices: 0,
                frame_ms: f64::NAN,
                clock: CLOCK,
                update_ms: f64::NAN,
                update_gpu_ms: f64::NAN,
                apply_ms: f64::NAN,
                update_passes: Vec::new(),
                gpu_memory_bytes: 0,
                empty_brick_share: f64::NAN,
                coverage: f64::NAN,
                metrics: no_metrics(0, 0),
                statistics,
                image: String::new(),
                reference: None,
                pareto: false,
                search: None,
                gallery: None,
            });
            observer(Event::Row {
                index: rows.len() - 1,
                row: rows.last().expect("just pushed"),
            });
        }
    }
    if let Some((time, error)) = &spec.pareto {
        mark_front(&mut rows, |r| (r.statistics[time], r.statistics[error]));
    }
    std::fs::create_dir_all(out)
        .map_err(|err| anyhow!("{}: cannot create: {err}", out.display()))?;
    finish(e, file, None, out, rows, Vec::new())
}

/// The report's first lines for a probe: the run, the probe and its figures.
pub(super) fn header(e: &Experiment, file: &Path, spec: &ProbeSpec) -> String {
    let mut s = String::new();
    let (description, figures) = match find(&spec.id) {
        Ok(p) => (p.description(), p.figures()),
        Err(_) => ("", Vec::new()),
    };
    let _ = writeln!(
        s,
        "Experiment `{}` ({}), run by `vwb run {}`. Machine: {}; vwb {}; seed {}. Probe `{}`: {description}; \
         the plugin's CPU twin (f64) alone, no GPU and no image.",
        e.name,
        described(e),
        file.display(),
        measure::machine(),
        measure::build(),
        e.seed
            .map_or_else(|| "the probe's".to_string(), |s| s.to_string()),
        spec.id,
    );
    let _ = writeln!(s);
    for (name, what) in figures
        .iter()
        .filter(|(n, _)| e.statistics.iter().any(|s| s == n))
    {
        let _ = writeln!(s, "- `{name}`: {what}.");
    }
    if let Some((t, err)) = &spec.pareto {
        let _ = writeln!(
            s,
            "- Pareto: `{t}` against `{err}` (lower is better in both)."
        );
    }
    s
}
