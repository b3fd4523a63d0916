//! `classify.tf2d`: a 2D transfer function over value × gradient magnitude (Kniss,
//! Kindlmann and Hansen 2001; Rezk-Salama 2001 §3), with rectangle, triangle and
//! Gaussian primitives (`vwb_render::tf2d`), baked into a 256 × 256 table.
//!
//! Gradient estimators (`estimator`, structural):
//! - `central`: central differences of the trilinear field at the sample, one voxel
//!   apart (six extra reads per sample, no memory).
//! - `precomputed`: a pre-pass stores |∇f| per voxel (central differences on the
//!   grid) in an r32float volume, interpolated at the sample (one read per sample,
//!   4 bytes per voxel; rerun only when the volume changes).
//!
//! |∇f| is in normalised value per voxel; the table's y axis is
//! clamp(|∇f|·`gradient_scale`, 0, 1). [`histogram2d`] gives the UI the log-count
//! histogram over the same axes.
//!
//! `y_axis: data` (structural) puts the volume's own normalised value at the sample on
//! the y axis instead (no gradient): after `flow.lic3d` has replaced the sample's value
//! by the LIC intensity, the table is over LIC × |v| (the field's magnitude), the
//! thesis's classification of LIC by speed (§9.3).

use std::sync::Arc;

use glam::{DVec3, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, PrepassDecl,
    ResourceDecl, ResourceKind, ShaderSource, StorageFormat, Transparency, Volumes,
};
use vwb_render::tf2d::{Primitive2d, Shape2d, Tf2d, eval_table, voxel_gradient};
use vwb_render::volume::Volume;

#[cfg(test)]
mod tests;

/// Table size along each axis.
pub const TABLE_SIZE: usize = 256;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Estimator {
    #[default]
    Central,
    Precomputed,
}

impl Estimator {
    pub const NAMES: [&'static str; 2] = ["central", "precomputed"];
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }
    pub fn from_name(s: &str) -> Option<Self> {
        [Self::Central, Self::Precomputed]
            .into_iter()
            .find(|e| e.name() == s)
    }
}

#[derive(Debug, Clone, Copy, Default)]
pub struct Tf2dPlugin {
    pub estimator: Estimator,
    /// `y_axis: data`: the y axis is the data's value at the sample, not |∇f|.
    pub y_data: bool,
}

const Y_AXES: [&str; 2] = ["gradient", "data"];

/// The default: a triangle on the demo's soft-tissue boundary and a rectangle on dense,
/// strongly varying tissue.
pub fn default_tf() -> Tf2d {
    Tf2d {
        primitives: vec![
            Primitive2d {
                shape: Shape2d::Triangle,
                centre: [0.22, 0.0],
                size: [0.25, 0.6],
                color: [0.95, 0.7, 0.55, 0.25],
            },
            Primitive2d {
                shape: Shape2d::Rectangle,
                centre: [0.6, 0.55],
                size: [0.4, 0.5],
                color: [1.0, 0.97, 0.9, 0.5],
            },
        ],
    }
}

fn tf(params: &ParamValues) -> Tf2d {
    params.tf2d("tf").cloned().unwrap_or_else(default_tf)
}

/// |∇f| per voxel by central differences with clamped neighbours (the pre-pass), f32
/// ([`vwb_render::tf2d::voxel_gradient`]).
pub fn voxel_gradients(volume: &Volume, scalars: &[f32]) -> Vec<f32> {
    use rayon::prelude::*;
    let d = volume.dims.map(|n| n.max(1) as usize);
    (0..scalars.len())
        .into_par_iter()
        .map(|i| voxel_gradient(scalars, d, [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])]))
        .collect()
}

/// The log-count histogram over (value, clamp(|∇f|·scale, 0, 1)), `bins` × `bins`,
/// value fastest: ln(1 + count) per bin, for the UI. Non-finite voxels are skipped.
pub fn histogram2d(volume: &Volume, gradient_scale: f64, bins: usize) -> Vec<f32> {
    let scalars = volume.normalized_scalars();
    let grads = voxel_gradients(volume, &scalars);
    let mut counts = vec![0u64; bins * bins];
    let bin = |x: f64| ((x.clamp(0.0, 1.0) * bins as f64) as usize).min(bins - 1);
    for (v, g) in scalars.iter().zip(&grads) {
        if v.is_finite() && g.is_finite() {
            counts[bin(*g as f64 * gradient_scale) * bins + bin(*v as f64)] += 1;
        }
    }
    counts.iter().map(|&c| (c as f32).ln_1p()).collect()
}

/// The editor's histogram for `y_axis: data`: the log counts of the volume's
/// normalised values along y (`bins` rows from 0 up), the same in every column, since x
/// is the value the stack's sample hooks give (the LIC intensity under `flow.lic3d`),
/// which only the stack computes. Laid out as [`histogram2d`] (x fastest).
pub fn histogram_data_rows(volume: &Volume, bins: usize) -> Vec<f32> {
    let mut counts = vec![0u64; bins];
    for v in volume.normalized_scalars() {
        if v.is_finite() {
            counts[((v.clamp(0.0, 1.0) * bins as f32) as usize).min(bins - 1)] += 1;
        }
    }
    counts
        .iter()
        .flat_map(|&c| std::iter::repeat_n((c as f32).ln_1p(), bins))
        .collect()
}

impl Plugin for Tf2dPlugin {
    fn id(&self) -> &'static str {
        "classify.tf2d"
    }
    fn display_name(&self) -> &'static str {
        "2D transfer function"
    }
    fn description(&self) -> &'static str {
        "Transfer function over value × gradient magnitude (rectangle, triangle, Gaussian)"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::tf2d("tf", "2D transfer function", default_tf()),
            ParamSpec::enumeration("estimator", "Gradient estimator", &Estimator::NAMES, 0)
                .structural()
                .with_doc("central: differences at the sample; precomputed: a pre-pass volume"),
            ParamSpec::float_log("gradient_scale", "Gradient scale", 0.1, 100.0, 4.0)
                .with_doc("|∇f| (normalised value per voxel) times this is the table's y"),
            ParamSpec::float_log("opacity", "Opacity scale", 0.01, 100.0, 1.0),
            ParamSpec::enumeration("y_axis", "Y axis", &Y_AXES, 0)
                .structural()
                .with_doc("gradient: |∇f| × the gradient scale; data: the volume's own value at the sample (|v| under flow.lic3d's LIC)"),
        ]
    }
    fn shader(&self) -> ShaderSource {
        if self.y_data {
            return ShaderSource::new_static(
                "plugins/src/classify_tf2d/tf2d_data.wgsl",
                include_str!("tf2d_data.wgsl"),
            );
        }
        match self.estimator {
            Estimator::Central => ShaderSource::new_static(
                "plugins/src/classify_tf2d/tf2d_central.wgsl",
                include_str!("tf2d_central.wgsl"),
            ),
            Estimator::Precomputed => ShaderSource::new_static(
                "plugins/src/classify_tf2d/tf2d_precomputed.wgsl",
                include_str!("tf2d_precomputed.wgsl"),
            ),
        }
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![ResourceDecl {
            name: "table",
            kind: ResourceKind::Texture2d,
        }]
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        (self.estimator == Estimator::Precomputed && !self.y_data).then(|| PrepassDecl {
            target: "gradient",
            format: StorageFormat::R32Float,
            scale: 1.0,
            shader: ShaderSource::new_static(
                "plugins/src/classify_tf2d/tf2d_prepass.wgsl",
                include_str!("tf2d_prepass.wgsl"),
            ),
            depends_on: vec![],
            holds_value: false,
        })
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let estimator = Estimator::from_name(params.enumeration("estimator")).unwrap_or_default();
        let y_data = params.enumeration("y_axis") == "data";
        (estimator != self.estimator || y_data != self.y_data)
            .then(|| Arc::new(Tf2dPlugin { estimator, y_data }) as Arc<dyn Plugin>)
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let res = gpu.create_sample_table("classify.tf2d table", TABLE_SIZE as u32, TABLE_SIZE as u32);
        self.update_resources(gpu, params, std::slice::from_ref(&res))?;
        Ok(vec![res])
    }
    fn update_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
        resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        let Some(res) = resources.first() else {
            return Err(PluginError::Invalid {
                plugin: self.id().into(),
                message: "table texture missing".into(),
            });
        };
        gpu.write_table(res, &tf(params).bake(TABLE_SIZE));
        Ok(())
    }
    /// A value range can be visible when the table has α > 0 for some value entry of
    /// the range at any gradient magnitude.
    fn transparency(&self, params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        vwb_render::skipping::visible_by_table(
            tf(params).visible_columns(TABLE_SIZE, params.float("opacity")),
        )
    }
    /// A classification drops values, not regions (and its promise, `transparency`,
    /// costs a pass over the table: not asked twice).
    fn region(
        &self,
        _params: &ParamValues,
        _volumes: &Volumes<'_>,
    ) -> Option<Arc<vwb_render::plugin::RegionFn>> {
        None
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(Tf2dTwin {
            table: tf(params).bake(TABLE_SIZE),
            gradient_scale: params.float("gradient_scale") as f64,
            opacity: params.float("opacity") as f64,
            estimator: self.estimator,
            y_data: self.y_data,
            gradients: None,
        }))
    }
}

/// CPU twin: the same gradient estimate and the same bilinear table lookup.
pub struct Tf2dTwin {
    pub table: Vec<[f32; 4]>,
    pub gradient_scale: f64,
    pub opacity: f64,
    pub estimator: Estimator,
    pub y_data: bool,
    /// Per-voxel |∇f| (precomputed estimator), built in `prepare`.
    pub gradients: Option<Vec<f32>>,
}

impl Tf2dTwin {
    /// |∇f| at the sample, as the GPU estimates it.
    pub fn gradient_magnitude(&self, ctx: &CpuContext, tex: DVec3) -> f64 {
        match (&self.gradients, self.estimator) {
            (Some(g), Estimator::Precomputed) => {
                ctx.trilinear(tex, |i| DVec4::splat(g[i] as f64)).x
            }
            _ => {
                let d = ctx.volume.dims.map(|n| 1.0 / n.max(1) as f64);
                let axis = |e: DVec3| ctx.value(tex + e) - ctx.value(tex - e);
                let g = DVec3::new(
                    axis(DVec3::new(d[0], 0.0, 0.0)),
                    axis(DVec3::new(0.0, d[1], 0.0)),
                    axis(DVec3::new(0.0, 0.0, d[2])),
                );
                0.5 * g.length()
            }
        }
    }
}

impl CpuTwin for Tf2dTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        if self.estimator == Estimator::Precomputed && !self.y_data && self.gradients.is_none() {
            self.gradients = Some(voxel_gradients(ctx.volume, ctx.scalars));
        }
    }
    fn classify(&self, ctx: &CpuContext, s: &mut CpuSample) {
        let g = if self.y_data {
            ctx.value(s.tex)
        } else {
            self.gradient_magnitude(ctx, s.tex) * self.gradient_scale
        };
        let c = eval_table(
            &self.table,
            TABLE_SIZE,
            s.value.clamp(0.0, 1.0),
            g.clamp(0.0, 1.0),
        );
        s.color = DVec4::new(c[0], c[1], c[2], (c[3] * self.opacity).clamp(0.0, 1.0));
    }
}
