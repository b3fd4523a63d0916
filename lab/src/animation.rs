//! Animated parameters headless: the parameters that `vwb render --time` and
//! `--sequence` drive ([`vwb_render::params::Animation`]), setting them, and the file
//! names of an image sequence. The window plays the same parameters
//! (`app/src/stack_ui.rs`).

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use vwb_render::params::{Animation, ParamKind, ParamValue};
use vwb_render::plugin::PluginInstance;

/// One animated parameter of a stack: the instance's index, its key and its range.
#[derive(Debug, Clone, PartialEq)]
pub struct Animated {
    pub instance: usize,
    pub plugin: &'static str,
    pub key: &'static str,
    pub range: [f32; 2],
}

/// The parameters a time drives: with `name` `None`, every clock parameter of the
/// stack's enabled instances (e.g. `flow.arrival`'s `time`); else the float
/// parameters named `key` or `plugin.id.key` (e.g. `flow.lic3d.phase_deg`). An error
/// names what the stack offers when nothing matches.
pub fn animated(stack: &[PluginInstance], name: Option<&str>) -> Result<Vec<Animated>> {
    let mut found = Vec::new();
    let mut offered = Vec::new();
    for (i, inst) in stack.iter().enumerate().filter(|(_, i)| i.enabled) {
        let plugin = inst.plugin.id();
        for spec in inst.plugin.params() {
            let ParamKind::Float { min, max, .. } = spec.kind else {
                continue;
            };
            if spec.animation.is_some() {
                offered.push(format!("{plugin}.{}", spec.key));
            }
            let wanted = match name {
                None => spec.animation == Some(Animation::Clock),
                Some(n) => n == spec.key || n == format!("{plugin}.{}", spec.key),
            };
            if wanted {
                found.push(Animated {
                    instance: i,
                    plugin,
                    key: spec.key,
                    range: [min, max],
                });
            }
        }
    }
    if found.is_empty() {
        let offered = if offered.is_empty() {
            "it has no animated parameter (flow.arrival's time, flow.lic3d's phase_deg)".to_string()
        } else {
            format!("its animated parameters: {}", offered.join(", "))
        };
        match name {
            None => bail!(
                "the stack has no clock parameter to set the time of; {offered}; name one with --animate"
            ),
            Some(n) => {
                bail!("no enabled plugin of the stack has a number parameter '{n}'; {offered}")
            }
        }
    }
    Ok(found)
}

/// An error when `value` lies outside the range of one of `params`.
pub fn check(params: &[Animated], value: f32) -> Result<()> {
    for a in params {
        let [lo, hi] = a.range;
        if !(value >= lo && value <= hi) {
            bail!(
                "{value} is outside {}'s {} range {lo}–{hi}",
                a.plugin,
                a.key
            );
        }
    }
    Ok(())
}

/// Sets each of `params` to `value` ([`check`]ed first: nothing is set when it fails).
pub fn set(stack: &mut [PluginInstance], params: &[Animated], value: f32) -> Result<()> {
    check(params, value)?;
    for a in params {
        stack[a.instance]
            .params
            .set(a.key, ParamValue::Float(value));
    }
    Ok(())
}

/// `count` values from `from` to `to`, both included (one value: `from`).
pub fn sequence_values(from: f32, to: f32, count: u32) -> Vec<f32> {
    if count <= 1 {
        return vec![from];
    }
    (0..count)
        .map(|i| from + (to - from) * i as f32 / (count - 1) as f32)
        .collect()
}

/// The file of frame `i` of `count`: `out_0007.png` for `out.png`, zero-padded to at
/// least four digits.
pub fn frame_path(output: &Path, i: u32, count: u32) -> PathBuf {
    let width = count.saturating_sub(1).to_string().len().max(4);
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    let name = match output.extension() {
        Some(ext) => format!("{stem}_{i:0width$}.{}", ext.to_string_lossy()),
        None => format!("{stem}_{i:0width$}"),
    };
    output.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stack(ids: &[&str]) -> Vec<PluginInstance> {
        let r = vwb_plugins::builtin_registry();
        ids.iter()
            .map(|id| PluginInstance::new(r.get(id).unwrap()))
            .collect()
    }

    #[test]
    fn the_clock_is_found_set_and_checked() {
        let mut s = stack(&["flow.arrival", "flow.lic3d", "classify.tf1d"]);
        let clocks = animated(&s, None).unwrap();
        assert_eq!(clocks.len(), 1);
        assert_eq!((clocks[0].instance, clocks[0].key), (0, "time"));
        set(&mut s, &clocks, 40.0).unwrap();
        assert_eq!(s[0].params.float("time"), 40.0);
        let e = set(&mut s, &clocks, 5000.0).unwrap_err().to_string();
        assert!(e.contains("outside flow.arrival's time range"), "{e}");
        // another parameter by name, with or without the plugin
        let phase = animated(&s, Some("flow.lic3d.phase_deg")).unwrap();
        assert_eq!(phase, animated(&s, Some("phase_deg")).unwrap());
        assert_eq!(phase[0].instance, 1);
        // nothing to drive: the error names what there is
        let e = animated(&stack(&["flow.lic3d"]), None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("flow.lic3d.phase_deg") && e.contains("--animate"),
            "{e}"
        );
        let e = animated(&s, Some("nope")).unwrap_err().to_string();
        assert!(e.contains("'nope'"), "{e}");
        // a disabled instance drives nothing
        s[0].enabled = false;
        assert!(animated(&s, None).is_err());
    }

    #[test]
    fn sequences_and_their_file_names() {
        assert_eq!(sequence_values(0.0, 10.0, 3), [0.0, 5.0, 10.0]);
        assert_eq!(sequence_values(2.0, 10.0, 1), [2.0]);
        assert_eq!(
            frame_path(Path::new("out/storm.png"), 7, 36),
            Path::new("out/storm_0007.png")
        );
        assert_eq!(
            frame_path(Path::new("a.png"), 12345, 20000),
            Path::new("a_12345.png")
        );
    }
}
