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
//!
//! A fragment that fails the depth test still costs its rasterisation, interpolation
//! and depth test, more than half a shaded fragment on llvmpipe. So after each mask
//! pass a tile pass (`cs_tiles`) marks the screen tiles of [`tile`] pixels that still
//! hold a pixel below the threshold, and the next run draws each slice as one quad per
//! live tile its polygon's footprint meets (`vs_tile`/`fs_tile` in
//! `shaders/slice.wgsl`) rather than as its polygon: a tile whose rays have all
//! stopped makes no fragment. The first run, before any mask, draws the polygons.
//! [`Renderer::set_raster_tiles`] (`VWB_RASTER_TILES=0`) keeps the polygons for every
//! run.

use super::*;
use glam::Vec3;

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

/// Side of the termination tiles in pixels, unless `VWB_RASTER_ET_TILE` says otherwise:
/// chosen by `bench/raster_options.py` (docs/perf.md).
pub const RASTER_ET_TILE: u32 = 32;

/// Side of the termination tiles in pixels: `VWB_RASTER_ET_TILE` (≥ 1) or
/// [`RASTER_ET_TILE`].
pub fn tile() -> u32 {
    env_count("VWB_RASTER_ET_TILE", RASTER_ET_TILE)
}

/// The tiles of a `size` frame, `tile` pixels a side: per row and per column.
pub(super) fn tile_grid(size: [u32; 2], tile: u32) -> [u32; 2] {
    [size[0].div_ceil(tile), size[1].div_ceil(tile)]
}

/// Per slice, the tiles [lo, hi) that its polygon's footprint meets, packed as
/// `x | y << 16` (`slice_tiles` in `shaders/slice.wgsl`): the bounds of the projected
/// vertices of its triangles (`tris`, each vertex with its slice) with a pixel of
/// margin; every tile where a vertex lies behind the eye; none without triangles.
pub(super) fn slice_tile_rects(
    tris: &[(Vec3, u32)],
    count: u32,
    view_proj: Mat4,
    size: [u32; 2],
    tile: u32,
) -> Vec<[u32; 2]> {
    let grid = tile_grid(size, tile);
    let (w, h) = (size[0] as f32, size[1] as f32);
    let mut lo = vec![glam::Vec2::splat(f32::INFINITY); count as usize];
    let mut hi = vec![glam::Vec2::splat(f32::NEG_INFINITY); count as usize];
    for (p, k) in tris {
        let Some(k) = (*k < count).then_some(*k as usize) else {
            continue;
        };
        let c = view_proj * p.extend(1.0);
        let px = if c.w > 0.0 {
            glam::Vec2::new((c.x / c.w + 1.0) * 0.5 * w, (1.0 - c.y / c.w) * 0.5 * h)
        } else {
            glam::Vec2::NAN
        };
        if px.is_finite() {
            lo[k] = lo[k].min(px);
            hi[k] = hi[k].max(px);
        } else {
            lo[k] = glam::Vec2::NEG_INFINITY;
            hi[k] = glam::Vec2::INFINITY;
        }
    }
    let pack = |x: u32, y: u32| x | y << 16;
    lo.iter()
        .zip(&hi)
        .map(|(lo, hi)| {
            if lo.x > hi.x {
                return [0, 0];
            }
            // pixels to tiles, clamped to the grid (an infinite bound clamps too)
            let to_tile = |v: f32, n: u32, up: bool| {
                let t = if up {
                    ((v + 1.0) / tile as f32).ceil()
                } else {
                    ((v - 1.0) / tile as f32).floor()
                };
                t.clamp(0.0, n as f32) as u32
            };
            [
                pack(to_tile(lo.x, grid[0], false), to_tile(lo.y, grid[1], false)),
                pack(to_tile(hi.x, grid[0], true), to_tile(hi.y, grid[1], true)),
            ]
        })
        .collect()
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
    /// `Tiles` of shaders/slice.wgsl (the mask reads its threshold and grid).
    uniform: wgpu::Buffer,
    depth: Option<([u32; 2], wgpu::TextureView)>,
    /// The tile pass (`cs_tiles`), in the mask's bind group.
    tiles_pipeline: wgpu::ComputePipeline,
    /// Group 3 of the tile pipeline (`vs_tile`/`fs_tile`): `tiles`, `tile_live`,
    /// `slice_tiles`.
    pub(super) tile_layout: wgpu::BindGroupLayout,
    /// `tile_live` (a u32 per tile) and its tile count.
    live: Option<(u32, wgpu::Buffer)>,
    /// `slice_tiles` and its capacity in bytes.
    slice_tiles: Option<(u64, wgpu::Buffer)>,
}

/// A frame's bind groups: the mask pass and tile pass (group 0 of raster_mask.wgsl) and,
/// when the runs after the first draw tiles, the tile pipeline's group 3 with the grid.
pub(super) struct Prepared {
    pub(super) mask: wgpu::BindGroup,
    /// Tile side in pixels.
    tile: u32,
    pub(super) tiles: Option<(wgpu::BindGroup, [u32; 2])>,
}

/// Bytes of the `Tiles` uniform.
const TILES_UNIFORM: u64 = 48;

fn storage_entry(
    binding: u32,
    vis: wgpu::ShaderStages,
    read_only: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl RasterEt {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        let fc = wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE;
        let mut eye = eye_texture_entry(0);
        eye.visibility = fc;
        let (pipeline, layout) = fullscreen_pipeline(
            device,
            "vwb raster mask",
            RASTER_MASK_WGSL,
            &[
                eye,
                uniform_entry(1, fc, false),
                storage_entry(2, wgpu::ShaderStages::COMPUTE, false),
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
            label: Some("vwb raster termination tiles"),
            size: TILES_UNIFORM,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("vwb raster tile pass"),
            source: wgpu::ShaderSource::Wgsl(RASTER_MASK_WGSL.into()),
        });
        let tiles_pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("vwb raster tile pass"),
            layout: Some(
                &device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("vwb raster tile pass"),
                    bind_group_layouts: &[Some(&layout)],
                    immediate_size: 0,
                }),
            ),
            module: &module,
            entry_point: Some("cs_tiles"),
            compilation_options: Default::default(),
            cache: None,
        });
        let vf = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let tile_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vwb group 3 (termination tiles)"),
            entries: &[
                uniform_entry(3, vf, false),
                storage_entry(4, wgpu::ShaderStages::VERTEX, true),
                storage_entry(5, wgpu::ShaderStages::VERTEX, true),
            ],
        });
        Self {
            pipeline,
            layout,
            uniform,
            depth: None,
            tiles_pipeline,
            tile_layout,
            live: None,
            slice_tiles: None,
        }
    }

    /// Bytes of the depth buffer and the tiles' buffers.
    pub(super) fn bytes(&self) -> u64 {
        self.depth
            .as_ref()
            .map_or(0, |([w, h], _)| *w as u64 * *h as u64 * 4)
            + self.live.as_ref().map_or(0, |(_, b)| b.size())
            + self.slice_tiles.as_ref().map_or(0, |(cap, _)| *cap)
    }

    /// Makes the depth buffer the eye buffer's size and writes the threshold; with
    /// `tiles` (tile side, the visible box, the slices' tile rects from
    /// [`slice_tile_rects`]) also the tile buffers. Returns the frame's bind groups.
    pub(super) fn prepare(
        &mut self,
        gpu: &GpuContext,
        eye: &Target,
        threshold: f32,
        tiles: Option<(u32, &VolumeBox, &[[u32; 2]])>,
    ) -> Prepared {
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
        let tile = tiles.map_or(RASTER_ET_TILE, |t| t.0);
        let grid = tile_grid(size, tile);
        let (vis_min, vis_max) = tiles.map_or((Vec3::ZERO, Vec3::ZERO), |t| (t.1.min, t.1.max));
        let mut uniform = [0u32; 12];
        uniform[0] = threshold.to_bits();
        uniform[1..4].copy_from_slice(&[tile, grid[0], grid[1]]);
        for (i, v) in vis_min
            .to_array()
            .iter()
            .chain(&vis_max.to_array())
            .enumerate()
        {
            uniform[4 + i + i / 3] = v.to_bits();
        }
        gpu.queue
            .write_buffer(&self.uniform, 0, bytemuck::cast_slice(&uniform));
        let count = grid[0] * grid[1];
        if self.live.as_ref().is_none_or(|(n, _)| *n != count) {
            let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vwb raster live tiles"),
                size: count as u64 * 4,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.live = Some((count, buffer));
        }
        let live = &self.live.as_ref().expect("made above").1;
        let mask = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
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
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: live.as_entire_binding(),
                },
            ],
        });
        let tiles = tiles.map(|(_, _, rects)| {
            let data: &[u8] = bytemuck::cast_slice(rects);
            let need = (data.len() as u64).max(16);
            if self.slice_tiles.as_ref().is_none_or(|(cap, _)| *cap < need) {
                let cap = need.next_power_of_two();
                let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("vwb raster slice tiles"),
                    size: cap,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                self.slice_tiles = Some((cap, buffer));
            }
            let rects = &self.slice_tiles.as_ref().expect("made above").1;
            if !data.is_empty() {
                gpu.queue.write_buffer(rects, 0, data);
            }
            let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vwb raster termination tiles"),
                layout: &self.tile_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: self.uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: live.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 5,
                        resource: rects.as_entire_binding(),
                    },
                ],
            });
            (group, grid)
        });
        Prepared { mask, tile, tiles }
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
    /// With `tiles`, the tile pass follows: `tile_live` for the next run.
    pub(super) fn encode_mask(&self, enc: &mut wgpu::CommandEncoder, frame: &Prepared) {
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("vwb raster mask"),
                color_attachments: &[],
                depth_stencil_attachment: Some(self.attachment(false)),
                ..Default::default()
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &frame.mask, &[]);
            pass.draw(0..3, 0..1);
        }
        if let (Some((_, grid)), Some((_, live))) = (&frame.tiles, &self.live) {
            enc.clear_buffer(live, 0, None);
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("vwb raster tiles"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.tiles_pipeline);
            pass.set_bind_group(0, &frame.mask, &[]);
            // one invocation per pixel row of a tile, in rows of at most 65535 workgroups
            let groups = (grid[0] * grid[1] * frame.tile).div_ceil(64);
            let x = groups.min(65535);
            pass.dispatch_workgroups(x, groups.div_ceil(x), 1);
        }
    }
}
