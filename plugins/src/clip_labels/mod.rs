//! `clip.labels`: hides or shows a subset of the labels of a label volume beside the
//! data, with nearest-voxel lookup.
//!
//! Parameters: `labels` (the label volume: a named volume input, or the document's own
//! volume when empty; [`crate::label_input`]), `mode` (`hide`: the selected labels
//! are removed; `show`: only they stay) and [`RANGES`] label ranges `range<i>_from` …
//! `range<i>_to` (inclusive; a range with `from` = −1 is unused), so any subset of the
//! 65 536 labels is a handful of ranges. The selection is baked on the CPU into one
//! byte per voxel (255 = kept), the GPU resource `kept`, so that a sample costs one
//! texel load; a selection change maps the voxels through the selection's table of
//! 65 536 bytes and re-uploads the mask. The twin bakes the same bytes from
//! the same volume.

use std::sync::OnceLock;

use vwb_render::params::{Components, Group, ParamSpec, ParamValue, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, ResourceDecl,
    ResourceKind, ShaderSource, Transparency, Volumes,
};

use crate::label_input::{self, LabelGrid, nearest_voxel};

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
    /// One byte per label, 0 … 65535: 255 where the label is kept.
    pub fn table(&self) -> Vec<u8> {
        (0..=u16::MAX)
            .map(|l| if self.keeps(l) { 255 } else { 0 })
            .collect()
    }
    /// One byte per voxel: 255 where the voxel's label is kept.
    pub fn mask(&self, labels: &[u16]) -> Vec<u8> {
        let table = self.table();
        labels.iter().map(|&l| table[l as usize]).collect()
    }
}

fn error(message: String) -> PluginError {
    PluginError::Invalid {
        plugin: "clip.labels".into(),
        message,
    }
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
            ParamSpec::volume(label_input::KEY, "Label volume", Components::Scalar).with_doc(
                "one non-negative integer label per voxel (u8, u16, i8, i16), on any grid over the volume's box",
            ),
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
    /// The mask of the selection over the label volume, which this checks (a new volume
    /// under the name makes a new instance).
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let (dims, labels) = label_input::gpu_labels("clip.labels", gpu, params)?;
        let (texture, view) = vwb_render::gpu::upload_r8_3d(
            gpu.device,
            gpu.queue,
            "clip.labels kept",
            dims,
            &Selection::from_params(params).mask(&labels),
        );
        Ok(vec![GpuResource { texture, view }])
    }
    /// A selection change maps the volume's voxels through the selection's table
    /// ([`label_input::map_labels`]: from the labels as stored, with no widened copy)
    /// and uploads the mask.
    fn update_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
        resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        let Some(kept) = resources.first() else {
            return Err(error("mask texture missing".into()));
        };
        let volume = gpu
            .inputs
            .resolve(gpu.volume, params, label_input::KEY)
            .map_err(error)?;
        let mask = label_input::map_labels(volume, &Selection::from_params(params).table())
            .map_err(|m| error(format!("{}: {m}", label_input::KEY)))?;
        let dims = volume.dims;
        gpu.queue.write_texture(
            kept.texture.as_image_copy(),
            &mask,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(dims[0]),
                rows_per_image: Some(dims[1]),
            },
            kept.texture.size(),
        );
        Ok(())
    }
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
    /// The demo's label volume (named [`label_input::DEMO_NAME`],
    /// [`Plugin::demo_inputs`]) with label 1 (left soft tissue) hidden.
    fn demo_params(&self) -> Option<ParamValues> {
        let mut p = ParamValues::defaults(&self.params());
        p.set(
            label_input::KEY,
            ParamValue::Volume(label_input::DEMO_NAME.into()),
        );
        p.set(range_keys()[0].0, ParamValue::Int(1));
        p.set(range_keys()[0].1, ParamValue::Int(1));
        Some(p)
    }
    fn demo_inputs(&self) -> vwb_render::inputs::VolumeInputs {
        label_input::demo_inputs()
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(ClipLabelsTwin {
            selection: Selection::from_params(params),
            params: params.clone(),
            mask: Vec::new(),
            dims: [1; 3],
        }))
    }
}

/// CPU twin of `clip`: the same mask at the same nearest voxel, baked in
/// [`CpuTwin::prepare`] from the frame's label volume (everything dropped where the
/// volume holds no labels: the GPU refuses it).
pub struct ClipLabelsTwin {
    pub selection: Selection,
    pub params: ParamValues,
    pub mask: Vec<u8>,
    pub dims: [u32; 3],
}

impl CpuTwin for ClipLabelsTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        let grid = LabelGrid::read(ctx.input(&self.params, label_input::KEY));
        self.mask = self.selection.mask(&grid.labels);
        self.dims = grid.dims;
    }
    fn clip(&self, s: &CpuSample) -> bool {
        !self.mask.is_empty() && self.mask[nearest_voxel(self.dims, s.tex)] > 127
    }
}
