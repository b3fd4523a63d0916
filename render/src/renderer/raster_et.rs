//! Early ray termination for the raster backend (issue 23, item 2).
//!
//! The compute backend stops a ray after the slice that makes its opacity reach the
//! threshold. The raster backend cannot read the eye buffer while it blends into it,
//! so it draws the slices in runs of [`interval`] slices and, after each run, a mask
//! pass (`shaders/raster_mask.wgsl`) writes depth 0 wherever the eye buffer's opacity
//! has reached the threshold. The slices are drawn with depth test `less` against a
//! depth buffer cleared to 1 and do not write depth, so a fragment behind an opaque
//! pixel fails the depth test and is not shaded.
//!
//! The image is that of a ray stopped at the end of the first run after which its
//! opacity is at least the threshold: up to `interval − 1` slices later than the
//! compute backend stops it (the reference renderer models both, see
//! `reference::ReferenceOptions::raster_et_interval`). The interval trades the mask
//! passes' cost against the slices drawn after a pixel is opaque; docs/perf.md
//! ("Early termination in the raster backend") measures it.

use super::*;

/// The mask pass (`shaders/raster_mask.wgsl`).
pub const RASTER_MASK_WGSL: &str = include_str!("../../../shaders/raster_mask.wgsl");

/// Depth format of the termination mask.
pub(super) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Slices per run between mask passes, unless `VWB_RASTER_ET_INTERVAL` says otherwise:
/// chosen by `bench/raster_options.py` (docs/perf.md), where 32 cost least on the CT
/// head and added the least error (8 and 16 pay for more mask passes than they save).
pub const RASTER_ET_INTERVAL: u32 = 32;

/// Slices per run between mask passes: `VWB_RASTER_ET_INTERVAL` (≥ 1) or
/// [`RASTER_ET_INTERVAL`].
pub fn interval() -> u32 {
    env_count("VWB_RASTER_ET_INTERVAL", RASTER_ET_INTERVAL)
}

/// The depth test of the slice pipeline when early termination is on.
pub(super) fn slice_depth_state() -> wgpu::DepthStencilState {
    wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(false),
        depth_compare: Some(wgpu::CompareFunction::Less),
        stencil: Default::default(),
        bias: Default::default(),
    }
}

/// The mask pipeline, its threshold uniform and the depth buffer (sized to the eye
/// buffer), made on the first raster frame with early termination.
pub(super) struct RasterEt {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
    depth: Option<([u32; 2], wgpu::TextureView)>,
}

impl RasterEt {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        let (pipeline, layout) = fullscreen_pipeline(
            device,
            "vwb raster mask",
            RASTER_MASK_WGSL,
            &[
                eye_texture_entry(0),
                uniform_entry(1, wgpu::ShaderStages::FRAGMENT, false),
            ],
            ("vs_mask", "fs_mask"),
            &[],
            Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Always),
                stencil: Default::default(),
                bias: Default::default(),
            }),
        );
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vwb raster mask threshold"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            pipeline,
            layout,
            uniform,
            depth: None,
        }
    }

    /// Bytes of the depth buffer.
    pub(super) fn bytes(&self) -> u64 {
        self.depth
            .as_ref()
            .map_or(0, |([w, h], _)| *w as u64 * *h as u64 * 4)
    }

    /// Makes the depth buffer the eye buffer's size and writes the threshold; returns
    /// the mask pass's bind group for this eye buffer.
    pub(super) fn prepare(
        &mut self,
        gpu: &GpuContext,
        eye: &Target,
        threshold: f32,
    ) -> wgpu::BindGroup {
        let size = [eye.width, eye.height];
        if self.depth.as_ref().is_none_or(|(s, _)| *s != size) {
            let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("vwb raster termination depth"),
                size: wgpu::Extent3d {
                    width: size[0],
                    height: size[1],
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: DEPTH_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                view_formats: &[],
            });
            self.depth = Some((size, texture.create_view(&Default::default())));
        }
        gpu.queue.write_buffer(
            &self.uniform,
            0,
            bytemuck::cast_slice(&[threshold, 0.0, 0.0, 0.0]),
        );
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vwb raster mask"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&eye.view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.uniform.as_entire_binding(),
                },
            ],
        })
    }

    /// The depth attachment of a slice pass: cleared to 1 by the first, kept after.
    pub(super) fn attachment(&self, clear: bool) -> wgpu::RenderPassDepthStencilAttachment<'_> {
        wgpu::RenderPassDepthStencilAttachment {
            view: &self.depth.as_ref().expect("prepared").1,
            depth_ops: Some(wgpu::Operations {
                load: if clear {
                    wgpu::LoadOp::Clear(1.0)
                } else {
                    wgpu::LoadOp::Load
                },
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }
    }

    /// Encodes the mask pass: depth 0 where the eye buffer's opacity reached the threshold.
    pub(super) fn encode_mask(&self, enc: &mut wgpu::CommandEncoder, group: &wgpu::BindGroup) {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("vwb raster mask"),
            color_attachments: &[],
            depth_stencil_attachment: Some(self.attachment(false)),
            ..Default::default()
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.draw(0..3, 0..1);
    }
}
