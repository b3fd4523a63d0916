//! `classify.labels`: a label volume beside the data, one 1D transfer function per
//! label, nearest-neighbour label lookup, labels that can be hidden.
//!
//! Parameters: `labels` (the label volume: a named volume input, or the document's own
//! volume when empty; [`crate::label_input`]), `tf_0` … `tf_7` and `show_0` …
//! `show_7` (labels 0–7; labels above 7 use `tf_7` and `show_7`), `opacity` (global
//! scale). The tables are baked into one 256 × 8 texture, a hidden label's row all
//! zero. The labels go to the GPU as one byte per voxel (labels above 255 read as 255,
//! which uses the last row as any label above 7 does).

use glam::DVec4;
use vwb_render::params::{Components, Group, ParamSpec, ParamValue, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, ResourceDecl,
    ResourceKind, ShaderSource, Transparency, Volumes,
};
use vwb_render::tf::{LUT_SIZE, TfCurve, eval_lut};

use crate::label_input::{self, LabelGrid};

#[cfg(test)]
mod tests;

/// Labels with their own transfer function (0 … MAX_LABELS − 1).
pub const MAX_LABELS: usize = 8;

/// The labels' transfer functions, a parameter group: label i's curve `tf_{i}` and
/// its switch `show_{i}`.
pub const LABELS: Group = Group::new("Label", MAX_LABELS).switch("show_{}");

pub struct Labels;

fn error(message: String) -> PluginError {
    PluginError::Invalid {
        plugin: "classify.labels".into(),
        message,
    }
}

/// A distinct default colour per label; label 0 (background) transparent.
pub fn default_curve(label: usize) -> TfCurve {
    const PALETTE: [[f32; 3]; MAX_LABELS] = [
        [0.0, 0.0, 0.0],
        [0.95, 0.6, 0.35],
        [0.35, 0.6, 0.95],
        [0.95, 0.95, 0.9],
        [0.5, 0.9, 0.4],
        [0.9, 0.4, 0.8],
        [0.9, 0.85, 0.3],
        [0.4, 0.9, 0.9],
    ];
    let c = PALETTE[label];
    let alpha = if label == 0 { 0.0 } else { 0.3 };
    TfCurve::ramp(0.05, 0.5, [c[0], c[1], c[2], alpha])
}

/// The baked table: one row of LUT_SIZE entries per label, hidden rows zero.
pub fn bake(params: &ParamValues) -> Vec<[f32; 4]> {
    (0..MAX_LABELS)
        .flat_map(|l| {
            if params.boolean(LABELS.key("show_{}", l)) {
                params
                    .tf(LABELS.key("tf_{}", l))
                    .cloned()
                    .unwrap_or_else(|| default_curve(l))
                    .bake(LUT_SIZE)
            } else {
                vec![[0.0; 4]; LUT_SIZE]
            }
        })
        .collect()
}

impl Plugin for Labels {
    /// It reads a label volume over the whole volume, in the volume's texture coordinates.
    fn splits_into_bricks(&self) -> bool {
        false
    }
    fn id(&self) -> &'static str {
        "classify.labels"
    }
    fn display_name(&self) -> &'static str {
        "Labels"
    }
    fn description(&self) -> &'static str {
        "One 1D transfer function per label of a u8 label volume (nearest-neighbour lookup)"
    }
    fn params(&self) -> Vec<ParamSpec> {
        let mut v = vec![
            ParamSpec::volume(label_input::KEY, "Label volume", Components::Scalar).with_doc(
                "one non-negative integer label per voxel (u8, u16, i8, i16), on any grid over the volume's box",
            ),
            ParamSpec::float_log("opacity", "Opacity scale", 0.01, 100.0, 1.0),
        ];
        v.extend(LABELS.specs(|l| {
            vec![
                ParamSpec::boolean(LABELS.key("show_{}", l), "Show", true),
                ParamSpec::tf(LABELS.key("tf_{}", l), "Transfer function", default_curve(l)),
            ]
        }));
        v
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource::new_static(
            "plugins/src/classify_labels/labels.wgsl",
            include_str!("labels.wgsl"),
        )
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![
            ResourceDecl {
                name: "labels",
                kind: ResourceKind::Texture3d,
            },
            ResourceDecl {
                name: "lut",
                kind: ResourceKind::Texture2d,
            },
        ]
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let (dims, labels) = label_input::gpu_labels("classify.labels", gpu, params)?;
        let bytes: Vec<u8> = labels.iter().map(|&l| l.min(255) as u8).collect();
        let (texture, view) = vwb_render::gpu::upload_r8_3d(
            gpu.device,
            gpu.queue,
            "classify.labels labels",
            dims,
            &bytes,
        );
        let res = [
            GpuResource { texture, view },
            gpu.create_sample_table("classify.labels lut", LUT_SIZE as u32, MAX_LABELS as u32),
        ];
        self.update_resources(gpu, params, &res)?;
        Ok(res.to_vec())
    }
    fn update_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
        resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        let Some(lut) = resources.get(1) else {
            return Err(error("lookup texture missing".into()));
        };
        gpu.write_table(lut, &bake(params));
        Ok(())
    }
    /// Visible where the table of any shown label that occurs in the label volume is
    /// (the label is not known per brick; which labels occur comes from the volume's
    /// histogram, [`label_input::rows_present`]). Where the input does not resolve,
    /// every row counts.
    fn transparency(&self, params: &ParamValues, volumes: &Volumes<'_>) -> Transparency {
        let present = match volumes.input(params, label_input::KEY) {
            Ok(v) => label_input::rows_present(v, MAX_LABELS),
            Err(_) => vec![true; MAX_LABELS],
        };
        let opacity = params.float("opacity");
        let table = bake(params);
        vwb_render::skipping::visible_by_table(
            (0..LUT_SIZE)
                .map(|i| {
                    (0..MAX_LABELS)
                        .any(|l| present[l] && table[l * LUT_SIZE + i][3] * opacity > 0.0)
                })
                .collect(),
        )
    }
    /// A classification drops values, not regions (its promise bakes the tables: not
    /// asked twice).
    fn region(
        &self,
        _params: &ParamValues,
        _volumes: &Volumes<'_>,
    ) -> Option<std::sync::Arc<vwb_render::plugin::RegionFn>> {
        None
    }
    /// The demo's label volume, named [`label_input::DEMO_NAME`] ([`Plugin::demo_inputs`]).
    fn demo_params(&self) -> Option<ParamValues> {
        let mut p = ParamValues::defaults(&self.params());
        p.set(
            label_input::KEY,
            ParamValue::Volume(label_input::DEMO_NAME.into()),
        );
        Some(p)
    }
    fn demo_inputs(&self) -> vwb_render::inputs::VolumeInputs {
        label_input::demo_inputs()
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(LabelsTwin {
            table: bake(params),
            opacity: params.float("opacity") as f64,
            params: params.clone(),
            grid: LabelGrid::default(),
        }))
    }
}

/// CPU twin of `classify`: the same nearest label and the same table row. It reads
/// its label volume in [`CpuTwin::prepare`], where the frame's inputs are known.
pub struct LabelsTwin {
    pub table: Vec<[f32; 4]>,
    pub opacity: f64,
    pub params: ParamValues,
    pub grid: LabelGrid,
}

impl CpuTwin for LabelsTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        self.grid = LabelGrid::read(ctx.input(&self.params, label_input::KEY));
    }
    fn classify(&self, _ctx: &CpuContext, s: &mut CpuSample) {
        let row = (self.grid.at(s.tex) as usize).min(MAX_LABELS - 1);
        let c = eval_lut(
            &self.table[row * LUT_SIZE..(row + 1) * LUT_SIZE],
            s.value.clamp(0.0, 1.0),
        );
        s.color = DVec4::new(c[0], c[1], c[2], (c[3] * self.opacity).clamp(0.0, 1.0));
    }
}
