//! Early ray termination and empty-space skipping for the raster backend (issue 23,
//! item 2), both by the depth test.
//!
//! The compute backend stops a ray after the slice that makes its opacity reach the
//! threshold, and jumps over the samples in empty bricks. The raster backend cannot
//! read the eye buffer while it blends into it, and a fragment cannot skip its shading
//! by branching (llvmpipe runs both sides of a branch under a mask); only a fragment
//! that fails the depth test before it is shaded costs next to nothing. So slice k's
//! fragments lie at depth (k + ½) / count (`slice_depth` in shaders/slice.wgsl) and pass
//! the test `greater`, and the slices are drawn in runs; before a run, a mask pass
//! (`shaders/raster_mask.wgsl`) raises each pixel's depth:
//! - to 1 where the eye buffer's opacity has reached the threshold, every
//!   [`interval`] slices (early termination);
//! - with skipping, to just in front of the pixel's next slice from the run's start
//!   that may hold a visible sample, or to 1 where none may: a per-frame pass
//!   (`fs_raster_chunks`) marks, per pixel, the chunks of slices where the ray crosses a
//!   visible brick, walking the bricks as the compute march does. Runs are
//!   [`skip_interval_for`] slices long (16; 32 where 8 or more slices share a
//!   polygon).
//!
//! The mask pass's own test `greater-equal` keeps the larger depth, so a pixel that
//! stopped stays stopped. The shader writes `frag_depth`, so llvmpipe shades every
//! pixel a mask covers before its depth test: a mask is scissored to the pixels that
//! the slices from its run on can cover, whose depth alone is tested again (session
//! 84: the raster frame with termination 0.88–0.97× by CPU time, images bit for bit).
//! A skipped fragment's sample lies in an empty brick and would have added exactly
//! nothing, so skipping leaves the image bit for bit as it was (test
//! `render::raster_skipping_keeps_the_image`).
//!
//! With termination, the image is that of a ray stopped at the end of the first run of
//! [`interval`] slices after which its opacity is at least the threshold: up to
//! `interval − 1` slices later than the compute backend stops it (the reference
//! renderer models both, see `reference::ReferenceOptions::raster_et_interval`). The
//! intervals trade the mask passes' cost against the slices drawn after a pixel is
//! opaque or before it reaches its next visible brick; docs/perf.md ("Early
//! termination and skipping in the raster backend") measures them.

use super::*;

/// The mask pass (`shaders/raster_mask.wgsl`).
pub const RASTER_MASK_WGSL: &str = include_str!("../../../shaders/raster_mask.wgsl");

/// Depth format of the termination mask.
pub(super) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Slices per run between termination checks, unless `VWB_RASTER_ET_INTERVAL` says
/// otherwise: chosen by `bench/raster_options.py` (docs/perf.md), where 32 cost least
/// on the CT head and added the least error (8 and 16 pay for more mask passes than
/// they save).
pub const RASTER_ET_INTERVAL: u32 = 32;

/// Slices per run between termination checks: `VWB_RASTER_ET_INTERVAL` (≥ 1) or
/// [`RASTER_ET_INTERVAL`].
pub fn interval() -> u32 {
    env_count("VWB_RASTER_ET_INTERVAL", RASTER_ET_INTERVAL)
}

/// Slices per run of empty-space skipping, unless `VWB_RASTER_SKIP_INTERVAL` says
/// otherwise: chosen by measurement (docs/perf.md, "Early termination and skipping in
/// the raster backend").
pub const RASTER_SKIP_INTERVAL: u32 = 16;

/// Slices per run of empty-space skipping in frames drawn [`GROUPED_FROM`] or more
/// slices per polygon, unless `VWB_RASTER_SKIP_INTERVAL` says otherwise: a group's
/// polygon costs less than its slices' polygons, so the masks weigh more. With
/// termination every 32 slices the skipping then needs no mask of its own: the
/// termination mask raises the depth for both (docs/perf.md, "Eight slices per polygon
/// where rays stop": 0.90–0.99× by CPU time with termination 0.99).
pub const RASTER_SKIP_INTERVAL_GROUPED: u32 = 32;

/// The slices per polygon from which [`RASTER_SKIP_INTERVAL_GROUPED`] applies.
pub const GROUPED_FROM: u32 = 8;

/// Slices per run of empty-space skipping in a frame drawn `group` slices per polygon,
/// by default: [`RASTER_SKIP_INTERVAL_GROUPED`] from [`GROUPED_FROM`] slices per
/// polygon, else [`RASTER_SKIP_INTERVAL`]. Each of [`crate::renderer::RASTER_GROUPS`]
/// divides the interval it gets (a unit test checks it).
pub(super) fn skip_interval_default(group: u32) -> u32 {
    if group >= GROUPED_FROM {
        RASTER_SKIP_INTERVAL_GROUPED
    } else {
        RASTER_SKIP_INTERVAL
    }
}

/// Slices per run of empty-space skipping in a frame drawn `group` slices per polygon:
/// `VWB_RASTER_SKIP_INTERVAL` (≥ 1), else [`skip_interval_default`].
pub fn skip_interval_for(group: u32) -> u32 {
    env_count("VWB_RASTER_SKIP_INTERVAL", skip_interval_default(group))
}

/// The first slices of the runs a frame of `count` slices is drawn in: every
/// `skip` slices (with skipping) and every `et` slices (with termination), or one run.
pub(super) fn run_starts(count: u32, skip: Option<u32>, et: Option<u32>) -> Vec<u32> {
    let mut starts: Vec<u32> = (0..count.max(1))
        .filter(|&k| {
            k == 0
                || skip.is_some_and(|n| k.is_multiple_of(n.max(1)))
                || et.is_some_and(|n| k.is_multiple_of(n.max(1)))
        })
        .collect();
    starts.dedup();
    starts
}

/// The depth test of the slice pipeline when a depth mask is on: a slice's depth
/// (k + ½) / count above the pixel's.
pub(super) fn slice_depth_state() -> wgpu::DepthStencilState {
    wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(false),
        depth_compare: Some(wgpu::CompareFunction::Greater),
        stencil: Default::default(),
        bias: Default::default(),
    }
}

/// What a frame's mask passes do: its slice count, the early-termination threshold
/// and interval (`None`: no termination), and whether it skips empty space.
#[derive(Clone, Copy, Debug)]
pub(super) struct MaskPlan {
    pub count: u32,
    pub et: Option<(f32, u32)>,
    pub skip: bool,
}

/// The mask pipeline, its uniform, the depth buffer and the chunk bits (both sized to
/// the eye buffer; the bits only once a frame skips), made on the first raster frame
/// with termination or skipping.
pub(super) struct RasterEt {
    /// The mask as a pass of its own (it reads the eye buffer: early termination).
    pipeline: wgpu::RenderPipeline,
    /// The mask drawn inside a slice pass (it does not read the eye buffer: skipping
    /// alone), by the eye buffer's format, made on first use; no colour is written.
    in_pass: [std::sync::OnceLock<wgpu::RenderPipeline>; 2],
    module: wgpu::ShaderModule,
    pipeline_layout: wgpu::PipelineLayout,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
    /// Bound in place of the eye buffer where the mask is drawn inside a slice pass.
    no_eye: wgpu::TextureView,
    depth: Option<([u32; 2], wgpu::TextureView)>,
    /// The per-pixel chunk bits that `fs_raster_chunks` writes (rg32uint).
    chunks: Option<([u32; 2], wgpu::Texture, wgpu::TextureView)>,
    /// Bound in place of the bits while a frame does not skip.
    no_chunks: wgpu::TextureView,
}

/// Format of the chunk bits: 64 per pixel.
pub(super) const CHUNKS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg32Uint;

fn texture_2d(
    device: &wgpu::Device,
    label: &str,
    size: [u32; 2],
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

impl RasterEt {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("vwb raster mask"),
            source: wgpu::ShaderSource::Wgsl(RASTER_MASK_WGSL.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vwb raster mask"),
            entries: &[
                eye_texture_entry(0),
                uniform_entry(1, wgpu::ShaderStages::FRAGMENT, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Uint,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("vwb raster mask"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = mask_pipeline(device, &module, &pipeline_layout, None);
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vwb raster mask uniform"),
            size: 32,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let no_eye = texture_2d(
            device,
            "vwb raster mask without eye buffer",
            [1, 1],
            wgpu::TextureFormat::Rgba16Float,
            wgpu::TextureUsages::TEXTURE_BINDING,
        )
        .create_view(&Default::default());
        let no_chunks = texture_2d(
            device,
            "vwb raster no chunk bits",
            [1, 1],
            CHUNKS_FORMAT,
            wgpu::TextureUsages::TEXTURE_BINDING,
        )
        .create_view(&Default::default());
        Self {
            pipeline,
            in_pass: Default::default(),
            module,
            pipeline_layout,
            layout,
            uniform,
            no_eye,
            depth: None,
            chunks: None,
            no_chunks,
        }
    }

    /// Bytes of the depth buffer and the chunk bits.
    pub(super) fn bytes(&self) -> u64 {
        let texels = |size: Option<&[u32; 2]>| size.map_or(0, |[w, h]| *w as u64 * *h as u64);
        texels(self.depth.as_ref().map(|d| &d.0)) * 4
            + texels(self.chunks.as_ref().map(|c| &c.0)) * 8
    }

    /// Bytes of the depth buffer and, with skipping, the chunk bits for a `size` eye
    /// buffer.
    pub(super) fn bytes_for([w, h]: [u32; 2], skip: bool) -> u64 {
        w as u64 * h as u64 * if skip { 4 + 8 } else { 4 }
    }

    /// Frees the depth buffer and the chunk bits (a frame that needs neither).
    pub(super) fn release(&mut self) {
        self.depth = None;
        self.chunks = None;
    }

    /// Makes the depth buffer (and, when the frame skips, the chunk bits) the eye
    /// buffer's size and writes the uniform; returns the mask's bind groups for this
    /// eye buffer: with the eye buffer (a pass of its own) and without it (inside a
    /// slice pass).
    pub(super) fn prepare(&mut self, gpu: &GpuContext, eye: &Target, plan: MaskPlan) -> MaskGroups {
        let size = [eye.width, eye.height];
        if self.depth.as_ref().is_none_or(|(s, _)| *s != size) {
            let usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
            let texture = texture_2d(
                &gpu.device,
                "vwb raster depth mask",
                size,
                DEPTH_FORMAT,
                usage,
            );
            self.depth = Some((size, texture.create_view(&Default::default())));
        }
        if !plan.skip {
            self.chunks = None;
        } else if self.chunks.as_ref().is_none_or(|(s, _, _)| *s != size) {
            let usage = wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC;
            let texture = texture_2d(
                &gpu.device,
                "vwb raster chunk bits",
                size,
                CHUNKS_FORMAT,
                usage,
            );
            let view = texture.create_view(&Default::default());
            self.chunks = Some((size, texture, view));
        }
        // slices per chunk bit, as `chunk_slices` in shaders/slice.wgsl
        let per_chunk = if plan.skip {
            plan.count.div_ceil(64).max(1)
        } else {
            0
        };
        let (threshold, et) = plan.et.unwrap_or((1.0, 0));
        let mut bytes = Vec::with_capacity(32);
        bytes.extend_from_slice(bytemuck::cast_slice(&[threshold, 0.0, 0.0, 0.0]));
        bytes.extend_from_slice(bytemuck::cast_slice(&[plan.count, per_chunk, et, 0]));
        gpu.queue.write_buffer(&self.uniform, 0, &bytes);
        let chunks = match (&self.chunks, plan.skip) {
            (Some((_, _, view)), true) => view,
            _ => &self.no_chunks,
        };
        let group = |eye: &wgpu::TextureView| {
            gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vwb raster mask"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(eye),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: self.uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(chunks),
                    },
                ],
            })
        };
        let format = eye.format;
        self.in_pass[in_pass_index(format)].get_or_init(|| {
            let target = wgpu::ColorTargetState {
                format: format.wgpu(),
                blend: None,
                write_mask: wgpu::ColorWrites::empty(),
            };
            mask_pipeline(
                &gpu.device,
                &self.module,
                &self.pipeline_layout,
                Some(target),
            )
        });
        MaskGroups {
            eye: group(&eye.view),
            no_eye: group(&self.no_eye),
            format: eye.format,
        }
    }

    /// The depth attachment of a slice pass: cleared to 0 (every slice passes) by the
    /// first, kept after.
    pub(super) fn attachment(&self, clear: bool) -> wgpu::RenderPassDepthStencilAttachment<'_> {
        wgpu::RenderPassDepthStencilAttachment {
            view: &self.depth.as_ref().expect("prepared").1,
            depth_ops: Some(wgpu::Operations {
                load: if clear {
                    wgpu::LoadOp::Clear(0.0)
                } else {
                    wgpu::LoadOp::Load
                },
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }
    }

    /// Encodes the chunk bits of this frame in the pixels [x, y, w, h] that slices can
    /// cover (`fs_raster_chunks` of the stack's module, with its groups 0–2; elsewhere
    /// no bit is set, and no slice is drawn).
    pub(super) fn encode_chunks(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        groups: [&wgpu::BindGroup; 3],
        [x, y, w, h]: [u32; 4],
    ) {
        let view = &self.chunks.as_ref().expect("prepared with skipping").2;
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("vwb raster chunk bits"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            ..Default::default()
        });
        pass.set_scissor_rect(x, y, w, h);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, groups[0], &[0]);
        pass.set_bind_group(1, groups[1], &[]);
        pass.set_bind_group(2, groups[2], &[]);
        pass.draw(0..3, 0..1);
    }

    /// Draws the mask before the run of slices from `first` inside a slice pass (it
    /// reads no eye buffer: no termination at this run). The caller binds its own
    /// groups again after it.
    pub(super) fn draw_mask(&self, pass: &mut wgpu::RenderPass, groups: &MaskGroups, first: u32) {
        let pipeline = self.in_pass[in_pass_index(groups.format)]
            .get()
            .expect("made by prepare");
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &groups.no_eye, &[]);
        pass.draw(0..3, first..first + 1);
    }

    /// The chunk bits of the last frame that skipped (64 per pixel, row by row), read
    /// back: for tests and diagnostics.
    pub(super) fn chunk_bits(&self, gpu: &GpuContext) -> Option<(u32, u32, Vec<u64>)> {
        let ([w, h], texture, _) = self.chunks.as_ref()?;
        let bytes = read_texture(gpu, texture, 8);
        // rows padded to 256 bytes
        let row = (*w as usize * 8).div_ceil(256) * 256;
        let bits = bytes
            .chunks_exact(row)
            .flat_map(|r| r[..*w as usize * 8].chunks_exact(8))
            .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        Some((*w, *h, bits))
    }

    /// Encodes the mask pass before the run of slices from `first`, in the pixels
    /// [x, y, w, h] that the slices from `first` on can cover (elsewhere no later slice
    /// tests the depth).
    pub(super) fn encode_mask(
        &self,
        enc: &mut wgpu::CommandEncoder,
        group: &MaskGroups,
        first: u32,
        [x, y, w, h]: [u32; 4],
    ) {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("vwb raster mask"),
            color_attachments: &[],
            depth_stencil_attachment: Some(self.attachment(false)),
            ..Default::default()
        });
        pass.set_scissor_rect(x, y, w, h);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &group.eye, &[]);
        pass.draw(0..3, first..first + 1);
    }
}

/// The in-pass mask pipeline's index for an eye buffer's format.
fn in_pass_index(format: TargetFormat) -> usize {
    (format == TargetFormat::Rgba32Float) as usize
}

/// The mask's bind groups for one eye buffer (see [`RasterEt::prepare`]).
pub(super) struct MaskGroups {
    eye: wgpu::BindGroup,
    no_eye: wgpu::BindGroup,
    format: TargetFormat,
}

/// The mask pipeline: a pass of its own (`target` none) or inside a slice pass, whose
/// colour target it must name and does not write.
fn mask_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
    target: Option<wgpu::ColorTargetState>,
) -> wgpu::RenderPipeline {
    let target = target.map(Some);
    let depth = wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(true),
        depth_compare: Some(wgpu::CompareFunction::GreaterEqual),
        stencil: Default::default(),
        bias: Default::default(),
    };
    fullscreen_render_pipeline(
        device,
        "vwb raster mask",
        (module, layout),
        ("vs_mask", "fs_mask"),
        match &target {
            Some(t) => std::slice::from_ref(t),
            None => &[],
        },
        Some(depth),
        &[],
    )
}

/// The pipeline of the chunk bits (`fs_raster_chunks` over a full-screen triangle).
/// With `frame_from_vertex` its fragments take the frame's fields from the vertices, as
/// the slices' do (`FRAME_FROM_VERTEX`, [`super::Renderer::set_frame_from_vertex`]).
pub(super) fn chunks_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
    frame_from_vertex: bool,
) -> wgpu::RenderPipeline {
    let constants: &[(&str, f64)] = if frame_from_vertex {
        &[("FRAME_FROM_VERTEX", 1.0)]
    } else {
        &[]
    };
    fullscreen_render_pipeline(
        device,
        "vwb raster chunk bits",
        (module, layout),
        ("vs_chunks", "fs_raster_chunks"),
        &[Some(CHUNKS_FORMAT.into())],
        None,
        constants,
    )
}

#[cfg(test)]
mod tests {
    use super::run_starts;

    #[test]
    fn runs_start_at_every_interval_of_either_kind() {
        assert_eq!(run_starts(10, None, None), vec![0]);
        assert_eq!(run_starts(0, None, None), vec![0]);
        assert_eq!(run_starts(70, None, Some(32)), vec![0, 32, 64]);
        assert_eq!(run_starts(40, Some(16), None), vec![0, 16, 32]);
        assert_eq!(run_starts(70, Some(24), Some(32)), vec![0, 24, 32, 48, 64]);
    }
}
