//! `clip.labels`: hides or shows a subset of the labels of a u8 or u16 label volume
//! beside the data (NRRD, the data's dims), with nearest-voxel lookup.
//!
//! Parameters: `labels` (the file; structural), `mode` (`hide`: the selected labels
//! are removed; `show`: only they stay) and [`RANGES`] label ranges `range<i>_from` …
//! `range<i>_to` (inclusive; a range with `from` = −1 is unused), so any subset of the
//! 65 536 labels is a handful of ranges. The selection is baked on the CPU into one
//! byte per voxel (255 = kept), the GPU resource `kept`, re-uploaded when the
//! selection changes; the twin reads the same bytes.

use std::path::Path;
use std::sync::{Arc, OnceLock};

use vwb_render::params::{Group, ParamSpec, ParamValue, ParamValues};
use vwb_render::plugin::{
    CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, ResourceDecl, ResourceKind,
    ShaderSource, Transparency,
};
use vwb_render::volume::VoxelData;

use crate::classify_labels::{cached_load, label_file, nearest_voxel};

#[cfg(test)]
mod tests;

/// Label ranges in the parameters.
pub const RANGES: usize = 8;

/// The label ranges, a parameter group: range i is `range{i}_from` … `range{i}_to`,
/// unused while its `from` is −1.
pub const RANGE_GROUP: Group = Group::new("Range", RANGES).switch("range{}_from");

/// The keys (from, to) of every range (made once).
pub fn range_keys() -> &'static [(&'static str, &'static str); RANGES] {
    static KEYS: OnceLock<[(&'static str, &'static str); RANGES]> = OnceLock::new();
    KEYS.get_or_init(|| {
        std::array::from_fn(|i| {
            (
                RANGE_GROUP.key("range{}_from", i),
                RANGE_GROUP.key("range{}_to", i),
            )
        })
    })
}

/// A loaded label volume (u8 or u16 widened).
#[derive(Debug, Clone, PartialEq)]
pub struct LabelVolume {
    pub dims: [u32; 3],
    pub labels: Vec<u16>,
}

/// Loads a u8 or u16 label volume (cached per path and modification time).
pub fn load_label_volume(path: &Path) -> Result<Arc<LabelVolume>, String> {
    cached_load(path, |path| {
        let v = vwb_render::volume::load(path).map_err(|e| e.to_string())?;
        let labels = match (v.components, v.data) {
            (1, VoxelData::U8(l)) => l.into_iter().map(u16::from).collect(),
            (1, VoxelData::U16(l)) => l,
            (c, d) => {
                return Err(format!(
                    "{}: a label volume must hold one u8 or u16 scalar per voxel, found {c} × {}",
                    path.display(),
                    d.scalar_type().name()
                ));
            }
        };
        Ok(LabelVolume {
            dims: v.dims,
            labels,
        })
    })
}

/// The selection of a parameter set: whether `label` is kept.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    pub show: bool,
    pub ranges: Vec<(u16, u16)>,
}

impl Selection {
    pub fn from_params(p: &ParamValues) -> Self {
        Self {
            show: p.enumeration("mode") == "show",
            ranges: range_keys()
                .iter()
                .filter(|(f, _)| p.int(f) >= 0)
                .map(|(f, t)| (p.int(f).clamp(0, 65535) as u16, p.int(t).clamp(0, 65535) as u16))
                .collect(),
        }
    }
    pub fn keeps(&self, label: u16) -> bool {
        let listed = self.ranges.iter().any(|&(a, b)| a <= label && label <= b);
        listed == self.show
    }
    /// One byte per voxel: 255 where the voxel's label is kept.
    pub fn mask(&self, v: &LabelVolume) -> Vec<u8> {
        let mut table = vec![0u8; 65536];
        for (l, t) in table.iter_mut().enumerate() {
            *t = if self.keeps(l as u16) { 255 } else { 0 };
        }
        v.labels.iter().map(|&l| table[l as usize]).collect()
    }
}

fn error(message: String) -> PluginError {
    PluginError::Invalid {
        plugin: "clip.labels".into(),
        message,
    }
}

/// The label volume of the parameters, checked against the data's dims.
fn volume_for(params: &ParamValues, data_dims: [u32; 3]) -> Result<Arc<LabelVolume>, PluginError> {
    label_file("clip.labels", params, data_dims, load_label_volume, |v| v.dims)
}

pub struct ClipLabels;

impl Plugin for ClipLabels {
    /// It reads a label volume over the whole volume, in the volume's texture coordinates.
    fn splits_into_bricks(&self) -> bool {
        false
    }
    fn id(&self) -> &'static str {
        "clip.labels"
    }
    fn display_name(&self) -> &'static str {
        "Clip labels"
    }
    fn description(&self) -> &'static str {
        "Hide or show label subsets of a u8 or u16 label volume (nearest-voxel lookup)"
    }
    fn params(&self) -> Vec<ParamSpec> {
        let mut v = vec![
            ParamSpec::path("labels", "Label volume", "")
                .structural()
                .with_doc("u8 or u16 NRRD with the data's dims; relative to the preset"),
            ParamSpec::enumeration("mode", "Mode", &["hide", "show"], 0)
                .with_doc("hide: the labels in the ranges are removed; show: only they stay"),
        ];
        v.extend(RANGE_GROUP.specs(|i| {
            let (f, t) = range_keys()[i];
            let from = if i == 0 { 0 } else { -1 };
            vec![
                ParamSpec::int(f, "From", -1, 65535, from)
                    .with_doc("first label of the range; −1: range unused"),
                ParamSpec::int(t, "To", 0, 65535, from.max(0)).with_doc("last label (inclusive)"),
            ]
        }));
        v
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource::new_static(
            "plugins/src/clip_labels/labels.wgsl",
            include_str!("labels.wgsl"),
        )
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![ResourceDecl {
            name: "kept",
            kind: ResourceKind::Texture3d,
        }]
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let v = volume_for(params, gpu.volume.dims)?;
        let (texture, view) = vwb_render::gpu::upload_r8_3d(
            gpu.device,
            gpu.queue,
            "clip.labels kept",
            v.dims,
            &Selection::from_params(params).mask(&v),
        );
        Ok(vec![GpuResource { texture, view }])
    }
    fn update_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
        resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        let v = volume_for(params, gpu.volume.dims)?;
        let Some(kept) = resources.first() else {
            return Err(error("mask texture missing".into()));
        };
        gpu.queue.write_texture(
            kept.texture.as_image_copy(),
            &Selection::from_params(params).mask(&v),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(v.dims[0]),
                rows_per_image: Some(v.dims[1]),
            },
            kept.texture.size(),
        );
        Ok(())
    }
    fn transparency(&self, _params: &ParamValues) -> Transparency {
        Transparency::Keeps
    }
    /// The demo's label volume with label 1 (left soft tissue) hidden.
    fn demo_params(&self) -> Option<ParamValues> {
        let mut p = ParamValues::defaults(&self.params());
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../presets/data/demo_labels.nrrd");
        p.set("labels", ParamValue::Path(path.into()));
        p.set(range_keys()[0].0, ParamValue::Int(1));
        p.set(range_keys()[0].1, ParamValue::Int(1));
        Some(p)
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        let v = params.path("labels").and_then(|p| load_label_volume(p).ok())?;
        Some(Box::new(ClipLabelsTwin {
            mask: Selection::from_params(params).mask(&v),
            dims: v.dims,
        }))
    }
}

/// CPU twin of `clip`: the same mask at the same nearest voxel.
pub struct ClipLabelsTwin {
    pub mask: Vec<u8>,
    pub dims: [u32; 3],
}

impl CpuTwin for ClipLabelsTwin {
    fn clip(&self, s: &CpuSample) -> bool {
        self.mask[nearest_voxel(self.dims, s.tex)] > 127
    }
}
