//! `vwb classification`: the classic classification result, measured. For each preset
//! (its first `classify.tf1d` instance), each mode (post / pre / pre-integrated) and
//! each slice spacing: the GPU frame time and the error against one converged
//! reference per preset — the converged CPU reference of post-classification, i.e.
//! the emission–absorption integral of the TF along the trilinearly interpolated
//! scalar, which all three modes approximate. Also the CPU time of rebuilding the
//! pre-integration table. Eye buffer rgba32float, so that fp16 accumulation does not
//! mix into the classification error.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Result, anyhow, bail};
use serde_json::json;
use vwb_plugins::classify_tf1d::{Mode, preint};
use vwb_render::metrics;
use vwb_render::params::ParamValue;
use vwb_render::preset::Document;
use vwb_render::tf::LUT_SIZE;
use vwb_render::{GpuContext, TargetFormat};

use crate::headless;
use crate::measure::{self, Summary};

/// One row of the table.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Row {
    pub preset: String,
    pub mode: &'static str,
    pub spacing: f32,
    pub slices: u32,
    pub gpu_ms: f64,
    pub rms_delta_e: f64,
    pub share_above_6: f64,
}

/// The document with the first `classify.tf1d` instance in `mode`.
fn with_mode(doc: &Document, mode: Mode) -> Result<Document> {
    let mut d = doc.clone();
    let inst = d
        .stack
        .iter_mut()
        .find(|i| i.enabled && i.plugin.id() == "classify.tf1d")
        .ok_or_else(|| anyhow!("the preset has no enabled classify.tf1d"))?;
    inst.params
        .set("mode", ParamValue::Enum(mode.name().to_string()));
    Ok(d)
}

/// CPU time (ms) of building the pre-integration table for the document's TF.
pub fn table_build_ms(doc: &Document, runs: usize) -> Result<Summary> {
    let inst = doc
        .stack
        .iter()
        .find(|i| i.plugin.id() == "classify.tf1d")
        .ok_or_else(|| anyhow!("the preset has no classify.tf1d"))?;
    let lut = inst
        .params
        .tf("tf")
        .ok_or_else(|| anyhow!("classify.tf1d has no tf"))?
        .bake(LUT_SIZE);
    let opacity = inst.params.float("opacity") as f64;
    let times: Vec<f64> = (0..runs.max(1))
        .map(|k| {
            let start = Instant::now();
            let t = preint::build(&lut, opacity, 1.0 + k as f64 * 0.01);
            std::hint::black_box(&t);
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    Summary::of(&times).ok_or_else(|| anyhow!("no timing"))
}

/// Runs the whole table; writes `classification.json` into `out`.
pub fn run(
    gpu: &GpuContext,
    presets: &[PathBuf],
    spacings: &[f32],
    size: [u32; 2],
    frames: u32,
    tolerance: f64,
    out: &Path,
) -> Result<Vec<Row>> {
    if presets.is_empty() || spacings.is_empty() {
        bail!("vwb classification needs at least one --preset and one spacing");
    }
    std::fs::create_dir_all(out).map_err(|e| anyhow!("{}: cannot create: {e}", out.display()))?;
    let mut rows = Vec::new();
    let mut references = Vec::new();
    let mut builds = Vec::new();
    for path in presets {
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        let mut doc = crate::document::load_document(Some(path))?;
        doc.render.size = size;
        doc.render.target = TargetFormat::Rgba32Float;
        doc.render.early_termination = None;
        let volume = headless::load_volume(&doc.volume)?;
        let post = with_mode(&doc, Mode::Post)?;
        let s = post.frame_settings();
        let (reference, c, secs) = measure::converged_reference(&volume, &post, &s, tolerance)?;
        references.push(json!({
            "preset": name,
            "spacing_voxels": c.spacing,
            "converged": c.converged,
            "last_change_rms_delta_e": c.last_change_rms_delta_e,
            "seconds": secs,
        }));
        let build = table_build_ms(&doc, 50)?;
        builds.push(json!({"preset": name, "table_build_ms": build}));
        for mode in [Mode::Post, Mode::Pre, Mode::Preintegrated] {
            for &spacing in spacings {
                let mut d = with_mode(&doc, mode)?;
                d.render.slice_spacing = spacing;
                let s = d.frame_settings();
                let mut r = headless::renderer_for(gpu, &d, volume.clone())?;
                let timing = measure::time_frames(&mut r, &s, 1, frames)?;
                let img = measure::gpu_image(&r, &d)?;
                let m = metrics::try_compare(&img, &reference).map_err(|e| anyhow!(e))?;
                let row = Row {
                    preset: name.clone(),
                    mode: mode.name(),
                    spacing,
                    slices: timing.slices,
                    gpu_ms: timing.gpu_ms.unwrap_or(timing.wall_ms).median,
                    rms_delta_e: m.rms_delta_e,
                    share_above_6: m.share_above_6,
                };
                eprintln!(
                    "{name} {:>13} spacing {spacing:>4}: {:>4} slices {:>8.2} ms  RMS ΔE*uv {:.3}  >6 {:.2}%",
                    row.mode,
                    row.slices,
                    row.gpu_ms,
                    row.rms_delta_e,
                    100.0 * row.share_above_6
                );
                rows.push(row);
            }
        }
    }
    measure::save_json(
        &out.join("classification.json"),
        &json!({
            "adapter": gpu.describe(),
            "size": size,
            "target": "rgba32float",
            "time": if gpu.has_timestamps() { "gpu timestamps, median" } else { "wall clock, median" },
            "frames": frames,
            "references": references,
            "table_builds": builds,
            "rows": rows,
        }),
    )?;
    Ok(rows)
}
