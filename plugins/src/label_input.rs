//! Label volumes as named volume inputs, shared by `classify.labels` and `clip.labels`.
//!
//! Both plugins read their labels through the volume input `labels`
//! ([`vwb_render::params::ParamKind::Volume`]): one of the document's named volumes
//! (`volumes: {"labels": File("data/demo_labels.nrrd")}` in a preset), or the
//! document's own volume when the name is empty (a segmentation opened as the volume).
//! The GPU resources and the CPU twin read the same volume
//! ([`vwb_render::plugin::GpuInit::input`], [`vwb_render::plugin::CpuContext::input`]).
//!
//! A label volume holds one non-negative integer per voxel: u8 or u16, or i8 / i16
//! without a negative value (NIfTI segmentations are often signed). Floating-point
//! volumes are refused: a label is read at the nearest voxel, never interpolated, and a
//! fractional label has no meaning.
//!
//! *Choice:* a label volume spans the document volume's box whatever its grid, as every
//! input does ([`vwb_render::inputs`]): the label of texture coordinate t is that of
//! the label voxel nearest to t on the label volume's own grid, so a coarser or finer
//! segmentation is read where it lies. (Before labels were named inputs, a label file
//! had to have the data's dims.)

use std::sync::{Arc, OnceLock};

use glam::DVec3;
use vwb_render::inputs::VolumeInputs;
use vwb_render::params::ParamValues;
use vwb_render::plugin::{GpuInit, PluginError};
use vwb_render::volume::{Volume, VoxelData};

/// The parameter key of both plugins' label input.
pub const KEY: &str = "labels";

/// The name the demo inputs give the demo's label volume.
pub const DEMO_NAME: &str = "labels";

/// Linear index (x fastest) of the voxel nearest to a texture coordinate, as the
/// shaders' `clamp(floor(tex·dims), 0, dims − 1)`.
pub fn nearest_voxel(dims: [u32; 3], tex: DVec3) -> usize {
    let d = dims.map(|n| n.max(1) as usize);
    let idx = |a: usize| {
        let f = (tex[a] * d[a] as f64).floor();
        if f.is_nan() {
            0
        } else {
            (f.max(0.0) as usize).min(d[a] - 1)
        }
    };
    (idx(2) * d[1] + idx(1)) * d[0] + idx(0)
}

/// How messages name a volume: its name and, where it came from a file, the file.
pub fn describe(volume: &Volume) -> String {
    match &volume.source {
        Some(file) => format!("'{}' ({})", volume.name, file.display()),
        None => format!("'{}'", volume.name),
    }
}

/// The labels of `volume`, one per voxel (x fastest), widened to u16; refused, naming
/// the volume and its file, unless it holds one non-negative integer per voxel.
pub fn label_values(volume: &Volume) -> Result<Vec<u16>, String> {
    let refuse = |what: String| {
        Err(format!(
            "the volume {} {what}; a label volume holds one non-negative integer per voxel \
             (u8 or u16, or i8 / i16 without negative values)",
            describe(volume)
        ))
    };
    if volume.components != 1 {
        return refuse(format!("has {} components", volume.components));
    }
    let negative = |min: i32| refuse(format!("holds a negative label ({min})"));
    match &volume.data {
        VoxelData::U8(v) => Ok(v.iter().map(|&l| u16::from(l)).collect()),
        VoxelData::U16(v) => Ok(v.clone()),
        VoxelData::I8(v) => match v.iter().copied().min() {
            Some(m) if m < 0 => negative(i32::from(m)),
            _ => Ok(v.iter().map(|&l| l as u16).collect()),
        },
        VoxelData::I16(v) => match v.iter().copied().min() {
            Some(m) if m < 0 => negative(i32::from(m)),
            _ => Ok(v.iter().map(|&l| l as u16).collect()),
        },
        VoxelData::F32(_) => refuse("holds floating-point values".into()),
    }
}

/// One byte per voxel of a label volume: `table[label]` (0 beyond the table), x
/// fastest, from the voxels as stored, with no widened copy of the labels (a single
/// thread: beside lavapipe's threads, rayon made it slower). For a volume
/// [`label_values`] has accepted (its negative values, which it refuses, would read
/// entry 0); where the volume holds no integer labels, [`label_values`]'s error.
pub fn map_labels(volume: &Volume, table: &[u8]) -> Result<Vec<u8>, String> {
    let at = |l: usize| table.get(l).copied().unwrap_or(0);
    Ok(match &volume.data {
        _ if volume.components != 1 => return label_values(volume).map(|_| Vec::new()),
        VoxelData::U8(v) => v.iter().map(|&l| at(l as usize)).collect(),
        VoxelData::U16(v) => v.iter().map(|&l| at(l as usize)).collect(),
        VoxelData::I8(v) => v.iter().map(|&l| at(l.max(0) as usize)).collect(),
        VoxelData::I16(v) => v.iter().map(|&l| at(l.max(0) as usize)).collect(),
        VoxelData::F32(_) => return label_values(volume).map(|_| Vec::new()),
    })
}

/// Which of `rows` table rows the labels of `volume` can use: row l (< rows − 1) for
/// label l, the last row for every label from rows − 1 up. Read from the volume's
/// range and histogram, without a pass over the voxels: exact when the labels span
/// fewer than [`vwb_render::volume::HISTOGRAM_BINS`] values (each integer then has a
/// bin of its own), a superset otherwise; every row where it is not a label volume.
pub fn rows_present(volume: &Volume, rows: usize) -> Vec<bool> {
    if !may_hold_labels(volume) || rows == 0 {
        return vec![true; rows];
    }
    let last = (rows - 1) as f64;
    (0..rows)
        .map(|row| {
            if row + 1 == rows {
                volume.range[1] >= last
            } else {
                may_occur(volume, row as f64)
            }
        })
        .collect()
}

/// Whether the integer `l` may occur in `volume`, by its range and histogram: exactly
/// when its values span fewer than [`vwb_render::volume::HISTOGRAM_BINS`] integers.
fn may_occur(volume: &Volume, l: f64) -> bool {
    let [lo, hi] = volume.range;
    l >= lo
        && l <= hi
        && vwb_render::volume::histogram_bin(l, lo, hi)
            .and_then(|b| volume.histogram.get(b))
            .is_some_and(|&n| n > 0)
}

/// What a label plugin's widget says of its label volume, from its range and
/// histogram (no pass over the voxels): its labels as runs where they span fewer than
/// 256 values, else their range; or why it holds no labels.
pub fn labels_summary(volume: &Volume) -> String {
    if !may_hold_labels(volume) {
        return format!(
            "'{}' holds no labels (one non-negative integer per voxel)",
            volume.name
        );
    }
    let [lo, hi] = volume.range.map(|x| x.round() as u32);
    if hi - lo < vwb_render::volume::HISTOGRAM_BINS as u32 {
        let labels: Vec<u16> = (lo..=hi)
            .filter(|&l| may_occur(volume, f64::from(l)))
            .map(|l| l as u16)
            .collect();
        format!(
            "labels in '{}': {} ({} distinct)",
            volume.name,
            label_runs(&labels, 12),
            labels.len()
        )
    } else {
        format!(
            "labels in '{}': {lo} … {hi} (`vwb info --volume` lists them)",
            volume.name
        )
    }
}

/// The label plugins' own widget (feature `ui`): which labels their label volume
/// holds, above the generated widgets, so that a user picks tables or ranges for
/// labels that exist.
#[cfg(feature = "ui")]
pub fn present_labels(
    ui: &mut egui::Ui,
    params: &mut ParamValues,
    volumes: Option<&vwb_render::inputs::Volumes<'_>>,
) -> bool {
    if let Some(v) = volumes {
        match v.input(params, KEY) {
            Ok(volume) => ui.weak(labels_summary(volume)),
            Err(e) => ui.colored_label(egui::Color32::from_rgb(230, 160, 40), e),
        };
    }
    false
}

/// The distinct labels of `volume` in increasing order, or `None` where it is not a
/// label volume ([`label_values`]); one pass over the voxels.
pub fn distinct_labels(volume: &Volume) -> Option<Vec<u16>> {
    let labels = label_values(volume).ok()?;
    let mut seen = vec![false; 1 << 16];
    for l in labels {
        seen[l as usize] = true;
    }
    Some(
        seen.iter()
            .enumerate()
            .filter(|(_, s)| **s)
            .map(|(l, _)| l as u16)
            .collect(),
    )
}

/// Sorted labels as runs, `0–3, 7, 9–12`; after `max_runs` runs, `…`.
pub fn label_runs(labels: &[u16], max_runs: usize) -> String {
    let mut runs: Vec<(u16, u16)> = Vec::new();
    for &l in labels {
        match runs.last_mut() {
            Some((_, hi)) if u32::from(*hi) + 1 == u32::from(l) => *hi = l,
            _ => runs.push((l, l)),
        }
    }
    let mut parts: Vec<String> = runs
        .iter()
        .take(max_runs)
        .map(|&(a, b)| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}–{b}")
            }
        })
        .collect();
    if runs.len() > max_runs {
        parts.push("…".into());
    }
    parts.join(", ")
}

/// Whether `volume` can be a label volume by its type and range (one integer
/// component, nothing below 0; [`label_values`] checks the voxels themselves).
fn may_hold_labels(volume: &Volume) -> bool {
    !matches!(volume.data, VoxelData::F32(_)) && volume.components == 1 && volume.range[0] >= 0.0
}

/// The label volume the `labels` input of `params` names, for the GPU: its dims and
/// labels, or an error naming `plugin`, the input and the volume.
pub fn gpu_labels(
    plugin: &str,
    gpu: &GpuInit,
    params: &ParamValues,
) -> Result<([u32; 3], Vec<u16>), PluginError> {
    let error = |message: String| PluginError::Invalid {
        plugin: plugin.into(),
        message,
    };
    let volume = gpu.inputs.resolve(gpu.volume, params, KEY).map_err(error)?;
    let labels = label_values(volume).map_err(|m| error(format!("{KEY}: {m}")))?;
    Ok((volume.dims, labels))
}

/// A label volume as a twin holds it after [`LabelGrid::read`]: empty (every voxel
/// label 0) until read, and where the GPU refuses the volume.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LabelGrid {
    pub dims: [u32; 3],
    pub labels: Vec<u16>,
}

impl LabelGrid {
    /// The labels of `volume` (none where it is not a label volume: the GPU refuses
    /// such a stack, and the reference renderer draws nothing to compare with).
    pub fn read(volume: &Volume) -> Self {
        match label_values(volume) {
            Ok(labels) => Self {
                dims: volume.dims,
                labels,
            },
            Err(_) => Self::default(),
        }
    }

    /// The label of the voxel nearest to a texture coordinate, as the shaders read it.
    pub fn at(&self, tex: DVec3) -> u16 {
        if self.labels.is_empty() {
            return 0;
        }
        self.labels[nearest_voxel(self.dims, tex)]
    }
}

/// The demo's label volume (`presets/data/demo_labels.nrrd` in this checkout, written
/// by bench/make_demo_labels.py), loaded once.
pub fn demo_labels() -> Result<Arc<Volume>, String> {
    static DEMO: OnceLock<Result<Arc<Volume>, String>> = OnceLock::new();
    DEMO.get_or_init(|| {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../presets/data/demo_labels.nrrd"
        );
        vwb_render::volume::load(std::path::Path::new(path))
            .map(Arc::new)
            .map_err(|e| e.to_string())
    })
    .clone()
}

/// The demo's named volumes for the label plugins: the demo label volume as
/// [`DEMO_NAME`] (none where this checkout lacks the file; the coverage test then
/// fails on the missing labels).
pub fn demo_inputs() -> VolumeInputs {
    let mut inputs = VolumeInputs::default();
    match demo_labels() {
        Ok(v) => inputs.insert(DEMO_NAME, v),
        Err(e) => log::error!("{e}"),
    }
    inputs
}
