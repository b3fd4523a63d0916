//! `classify.tf1d`: a piecewise-linear RGBA transfer function over the normalised
//! scalar, baked into a lookup texture (post-classification).
//!
//! Parameters: `tf` (the curve), `opacity` (a global opacity scale, clamped to 1 per
//! reference step). The CPU twin evaluates the same baked table with the same linear
//! interpolation as the GPU sampler.

use std::sync::Arc;

use glam::DVec4;
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, ResourceDecl, ResourceKind,
    ShaderSource, Transparency,
};
use vwb_render::tf::{LUT_SIZE, TfCurve, TfPoint, eval_lut};

#[cfg(test)]
mod tests;

pub struct Tf1d;

/// The default curve: soft tissue faint, dense matter bright.
pub fn default_curve() -> TfCurve {
    TfCurve::new(vec![
        TfPoint {
            x: 0.0,
            color: [0.0, 0.0, 0.0, 0.0],
        },
        TfPoint {
            x: 0.25,
            color: [0.8, 0.4, 0.3, 0.0],
        },
        TfPoint {
            x: 0.45,
            color: [0.9, 0.6, 0.5, 0.08],
        },
        TfPoint {
            x: 1.0,
            color: [1.0, 1.0, 0.95, 0.6],
        },
    ])
}

fn curve(params: &ParamValues) -> TfCurve {
    params.tf("tf").cloned().unwrap_or_else(default_curve)
}

fn bake_bytes(params: &ParamValues, format: wgpu::TextureFormat) -> Vec<u8> {
    let lut = curve(params).bake(LUT_SIZE);
    match format {
        wgpu::TextureFormat::Rgba32Float => bytemuck::cast_slice(&lut).to_vec(),
        _ => lut
            .iter()
            .flat_map(|c| c.iter().flat_map(|v| half::f16::from_f32(*v).to_le_bytes()))
            .collect(),
    }
}

impl Plugin for Tf1d {
    fn id(&self) -> &'static str {
        "classify.tf1d"
    }
    fn display_name(&self) -> &'static str {
        "1D transfer function"
    }
    fn description(&self) -> &'static str {
        "Piecewise-linear RGBA transfer function over the scalar (post-classification)"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::tf("tf", "Transfer function", default_curve())
                .with_doc("control points over the normalised value [0,1]"),
            ParamSpec::float_log("opacity", "Opacity scale", 0.01, 100.0, 1.0)
                .with_doc("multiplies every opacity (per reference step, clamped to 1)"),
        ]
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource::new_static(
            "plugins/src/classify_tf1d/tf1d.wgsl",
            include_str!("tf1d.wgsl"),
        )
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![ResourceDecl {
            name: "lut",
            kind: ResourceKind::Texture2d,
        }]
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let format = gpu.lut_format();
        let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("classify.tf1d lut"),
            size: wgpu::Extent3d {
                width: LUT_SIZE as u32,
                height: 1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        let res = GpuResource { texture, view };
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
                message: "lookup texture missing".into(),
            });
        };
        let format = res.texture.format();
        let bytes = bake_bytes(params, format);
        let bpp = format.block_copy_size(None).unwrap_or(16);
        gpu.queue.write_texture(
            res.texture.as_image_copy(),
            &bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(LUT_SIZE as u32 * bpp),
                rows_per_image: Some(1),
            },
            res.texture.size(),
        );
        Ok(())
    }
    /// Colour from the value alone: a value range can be visible when any table entry
    /// the GPU interpolates for it has α > 0 (the entries around both ends included).
    fn transparency(&self, params: &ParamValues) -> Transparency {
        let opacity = params.float("opacity");
        let visible: Vec<bool> = curve(params)
            .bake(LUT_SIZE)
            .iter()
            .map(|c| c[3] * opacity > 0.0)
            .collect();
        Transparency::ByValue(Arc::new(move |lo: f64, hi: f64| {
            let last = visible.len() - 1;
            let index = |v: f64| v.clamp(0.0, 1.0) * last as f64;
            let (a, b) = (index(lo).floor() as usize, index(hi).ceil() as usize);
            a <= b && visible[a..=b.min(last)].iter().any(|&v| v)
        }))
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(Tf1dTwin {
            lut: curve(params).bake(LUT_SIZE),
            opacity: params.float("opacity") as f64,
        }))
    }
}

/// CPU twin of `classify`.
pub struct Tf1dTwin {
    pub lut: Vec<[f32; 4]>,
    pub opacity: f64,
}

impl CpuTwin for Tf1dTwin {
    fn classify(&self, s: &mut CpuSample) {
        let c = eval_lut(&self.lut, s.value.clamp(0.0, 1.0));
        s.color = DVec4::new(c[0], c[1], c[2], (c[3] * self.opacity).clamp(0.0, 1.0));
    }
}
