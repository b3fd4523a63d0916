//! Volumes beyond one 3D texture: bricked in core, rendered sort-last.
//!
//! An axis longer than the brick limit (the adapter's `max_texture_dimension_3d`, or
//! [`RendererOptions::brick_limit`]) is cut into pieces of at most
//! `limit − 2·BRICK_GHOST` voxels. Each brick owns the half-open voxel-edge range of its
//! piece and uploads it with [`BRICK_GHOST`] voxels more on every side that has a
//! neighbour, so that trilinear samples and gradients at its own samples read the same
//! voxels as the unbricked texture would.
//!
//! Every brick is an ordinary [`Renderer`] of its sub-volume (values normalised by the
//! whole volume's range, Δs0 of the whole volume) with two differences, both in
//! [`Region`]:
//! - its slices are planned on the whole volume's box (one global slice lattice, so the
//!   planes of neighbouring bricks are the same planes and no seam appears), and
//! - it takes only the samples inside its own box, half-open at faces it shares with
//!   the next brick (`slice_point_in` in `slice.wgsl`; the raster backend draws polygons
//!   clipped to that box, whose shared edges are bit-identical, so each pixel of a
//!   slice is covered once).
//!
//! Each brick renders its partial image (premultiplied, front to back) into its own
//! eye buffer; the bricks are then composited "under", in visibility order, into the
//! parent's eye buffer (`composite.wgsl`), all in one submission. Along any ray the
//! samples of one (convex) brick are contiguous and the order below is the ray's, so
//! the result is the unbricked image up to the rounding of the eye buffers. This is
//! the sort-last step a distributed engine (IceT-style) runs across machines.
//!
//! Plugins whose state crosses the volume (per-slice occlusion buffers, light volumes,
//! streamlines, grids of their own) cannot be split: a stack with one is refused by
//! name ([`Plugin::splits_into_bricks`]; docs/scale.md states what is exact).

use super::*;

/// Voxels a brick reads beyond its own region on every side that has a neighbour:
/// trilinear samples need one; central-difference and Sobel gradients (on the fly or
/// from the pre-pass) one more; the back sample of a pre-integrated slab up to 2 voxels
/// long two more.
pub const BRICK_GHOST: u32 = 4;

/// Smallest brick limit accepted: a brick owns at least 4 voxels beside its ghosts.
pub const MIN_BRICK_LIMIT: u32 = 2 * BRICK_GHOST + 4;

/// How a [`Renderer`] is built.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RendererOptions {
    /// GPU memory the renderer may hold ([`Renderer::set_gpu_memory_budget`]).
    pub gpu_memory_budget: Option<u64>,
    /// Largest extent of one 3D texture; a volume with a longer axis is split into
    /// bricks. `None`: the adapter's `max_texture_dimension_3d`. Values below
    /// [`MIN_BRICK_LIMIT`] count as that.
    pub brick_limit: Option<u32>,
    /// Most bytes of one volume texture; a larger volume is split into bricks.
    /// `None`: no cap, but a volume whose single texture the driver refuses (drivers
    /// cap one allocation; lavapipe refuses 2.2 GB) is split into bricks of half its
    /// size.
    pub max_brick_bytes: Option<u64>,
    /// How the volume is stored on the GPU (the preset's `render.volume_format`).
    pub volume_format: VolumeFormat,
    /// Workgroup shape (x, y) of the whole-frame compute passes (`cs_main`,
    /// `cs_main_skip`); `None`: [`crate::composer::main_workgroup`] for the adapter.
    pub workgroup: Option<[u32; 2]>,
    /// Beyond the GPU memory budget, refine the bricks in view from the full volume
    /// ([`super::lod`]) instead of showing one coarser level everywhere. Off in
    /// `Default`; [`RendererOptions::from_env`] turns it on unless `VWB_LOD_REFINE=0`.
    pub refine_in_view: bool,
    /// Voxels of the full volume a refinable brick owns along an axis at most
    /// (`None`: [`super::lod::LOD_BRICK`]).
    pub lod_brick: Option<u32>,
}

impl RendererOptions {
    /// `VWB_GPU_MEMORY_LIMIT` (bytes), `VWB_BRICK_LIMIT` (voxels),
    /// `VWB_MAX_BRICK_BYTES`, `VWB_WORKGROUP` (`XxY`, e.g. `16x4`) and `VWB_LOD_BRICK`
    /// (voxels) when set; refining the bricks in view on unless `VWB_LOD_REFINE=0`.
    pub fn from_env() -> Self {
        let var = |name: &str| std::env::var(name).ok();
        Self {
            gpu_memory_budget: var("VWB_GPU_MEMORY_LIMIT").and_then(|v| v.trim().parse().ok()),
            brick_limit: var("VWB_BRICK_LIMIT").and_then(|v| v.trim().parse().ok()),
            max_brick_bytes: var("VWB_MAX_BRICK_BYTES").and_then(|v| v.trim().parse().ok()),
            volume_format: VolumeFormat::Auto,
            workgroup: var("VWB_WORKGROUP").and_then(|v| {
                let (x, y) = v.trim().split_once('x')?;
                Some([x.parse().ok()?, y.parse().ok()?])
            }),
            refine_in_view: var("VWB_LOD_REFINE").is_none_or(|v| v.trim() != "0"),
            lod_brick: var("VWB_LOD_BRICK").and_then(|v| v.trim().parse().ok()),
        }
    }

    /// The brick limit on `gpu`: the option, capped by the adapter's limit.
    pub(super) fn limit(&self, gpu: &GpuContext) -> u32 {
        let adapter = gpu.limits.max_texture_dimension_3d;
        self.brick_limit
            .map_or(adapter, |l| l.min(adapter))
            .max(MIN_BRICK_LIMIT)
    }
}

/// Where a brick's renderer sits in the whole volume.
#[derive(Debug, Clone, Copy)]
pub(super) struct Region {
    /// The whole volume's box: the slice lattice is planned on it.
    pub lattice: VolumeBox,
    /// The brick's own part of the box: the samples it takes.
    pub own: VolumeBox,
    /// Bit a set when the own box's max face along axis a is shared with the next brick.
    pub open: u32,
}

/// One brick of a split volume.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BrickInfo {
    /// Position in the brick grid (x, y, z).
    pub index: [u32; 3],
    /// Voxels it owns per axis, [start, end).
    pub own: [[u32; 2]; 3],
    /// Voxels its texture holds per axis, [start, end): `own` and the ghosts.
    pub texture: [[u32; 2]; 3],
    /// Times its voxels were averaged over 2×2×2 blocks: 0 except for a brick refined
    /// in view ([`super::lod`]) that is not yet (or need not be) at full resolution.
    pub level: u32,
}

/// The pieces an axis of `dim` voxels is cut into for textures of at most `limit`
/// voxels: owned voxel ranges [start, end), near-equal, covering 0..dim. One piece when
/// the axis fits.
pub fn split_axis(dim: u32, limit: u32) -> Vec<(u32, u32)> {
    let limit = limit.max(MIN_BRICK_LIMIT);
    if dim <= limit {
        return vec![(0, dim)];
    }
    split_count(dim, dim.div_ceil(limit - 2 * BRICK_GHOST))
}

/// `dim` voxels in `k` near-equal pieces (owned ranges [start, end)).
fn split_count(dim: u32, k: u32) -> Vec<(u32, u32)> {
    let k = k.clamp(1, dim.max(1)) as u64;
    let at = |i: u64| (i * dim as u64 / k) as u32;
    (0..k).map(|i| (at(i), at(i + 1))).collect()
}

/// Texels of the largest brick of a split, ghosts included.
fn largest_brick_texels(dims: [u32; 3], pieces: &[Vec<(u32, u32)>; 3]) -> u64 {
    (0..3)
        .map(|a| {
            let ghosts = if pieces[a].len() > 1 {
                2 * BRICK_GHOST
            } else {
                0
            };
            let longest = pieces[a].iter().map(|(s, e)| e - s).max().unwrap_or(0);
            (longest + ghosts).min(dims[a]) as u64
        })
        .product()
}

/// The pieces of each axis: those of [`split_axis`], cut further along the longest
/// piece until the largest brick holds at most `max_bytes` at `texel` bytes a voxel.
pub(super) fn split_volume(
    dims: [u32; 3],
    limit: u32,
    max_bytes: Option<u64>,
    texel: u64,
) -> [Vec<(u32, u32)>; 3] {
    let mut pieces = dims.map(|d| split_axis(d, limit));
    let Some(cap) = max_bytes else {
        return pieces;
    };
    while largest_brick_texels(dims, &pieces) * texel > cap {
        let longest = |a: usize| pieces[a].iter().map(|(s, e)| e - s).max().unwrap_or(0);
        let a = (0..3).max_by_key(|&a| longest(a)).unwrap_or(0);
        if longest(a) <= MIN_BRICK_LIMIT {
            break;
        }
        pieces[a] = split_count(dims[a], pieces[a].len() as u32 + 1);
    }
    pieces
}

/// The sort-last operator on two premultiplied partial images, `front` nearer the eye:
/// `front + (1 − front.a)·back` per pixel, the slices' own "under" blend. It is
/// associative, so partial images combine pairwise in any grouping that keeps their
/// order (binary swap, radix-k), which is what lets a distributed engine composite them.
pub fn over(front: &[[f32; 4]], back: &[[f32; 4]]) -> Vec<[f32; 4]> {
    front
        .iter()
        .zip(back)
        .map(|(f, b)| std::array::from_fn(|c| f[c] + (1.0 - f[3]) * b[c]))
        .collect()
}

/// `what` needs `bytes`, more than the renderer's GPU memory `budget` on its own.
fn over_budget(what: String, bytes: u64, budget: u64) -> RenderError {
    RenderError::OutOfMemory {
        what,
        bytes,
        reason: format!(
            "more than the renderer's GPU memory budget of {} MiB",
            budget >> 20
        ),
    }
}

/// A volume's GPU form: one texture (with its bytes), or bricks.
pub(super) enum Upload {
    Single(wgpu::TextureView, u64),
    Split(Split),
}

impl Upload {
    /// What a renderer holds for it: the volume texture and its bytes, the value ranges
    /// per skipping brick, and the bricks. A split volume has no texture of its own (a
    /// 1³ placeholder keeps the bind group whole) and no ranges (its bricks skip).
    pub(super) fn into_parts(
        self,
        gpu: &GpuContext,
        volume: &Volume,
    ) -> (wgpu::TextureView, u64, BrickRanges, Option<Split>) {
        match self {
            Upload::Single(view, bytes) => (
                view,
                bytes,
                BrickRanges::new(volume.dims, &volume.normalized_scalars()),
                None,
            ),
            Upload::Split(split) => (
                crate::gpu::upload_r8_3d(
                    &gpu.device,
                    &gpu.queue,
                    "vwb volume (split)",
                    [1, 1, 1],
                    &[0],
                )
                .1,
                0,
                BrickRanges::new([1, 1, 1], &[0.0]),
                Some(split),
            ),
        }
    }
}

/// Smallest brick the retry after a driver refusal goes down to.
const MIN_RETRY_BYTES: u64 = 64 << 20;

/// Uploads `volume` as one texture, or as bricks when an axis passes `limit` or the
/// texture passes `max_bytes`. Nothing is allocated for a volume beyond the GPU memory
/// `budget`. When the driver refuses a texture and no `max_bytes` was given (drivers
/// cap one allocation: lavapipe refuses 2.2 GB), it tries again with bricks of half
/// the largest texture tried, down to 64 MiB.
pub(super) fn upload_or_split(
    gpu: &GpuContext,
    volume: &Volume,
    whole: &VolumeBox,
    limit: u32,
    max_bytes: Option<u64>,
    budget: Option<u64>,
    volume_format: VolumeFormat,
) -> Result<Upload, RenderError> {
    let format = volume_format.texture_format(gpu)?;
    let single = volume_texture_bytes(format, volume);
    let what = format!("volume {} ({:?})", volume.name, volume.dims);
    if let Some(b) = budget
        && single > b
    {
        return Err(over_budget(what, single, b));
    }
    let texel = texel_bytes(format);
    let mut cap = max_bytes;
    loop {
        let bricked = volume.dims.iter().any(|&d| d > limit) || cap.is_some_and(|c| single > c);
        let (attempt, largest) = if bricked {
            let pieces = split_volume(volume.dims, limit, cap, texel);
            let largest = largest_brick_texels(volume.dims, &pieces) * texel;
            let split = Split::new(gpu, volume, whole, limit, pieces, budget, volume_format)
                .map(Upload::Split);
            (split, largest)
        } else {
            let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
            let view = upload_volume(gpu, volume, format);
            let attempt = match pollster::block_on(scope.pop()) {
                None => Ok(Upload::Single(view, single)),
                Some(e) => Err(RenderError::OutOfMemory {
                    what: what.clone(),
                    bytes: single,
                    reason: format!("and the device is out of memory ({e})"),
                }),
            };
            (attempt, single)
        };
        match attempt {
            Err(RenderError::OutOfMemory { bytes, .. })
                if max_bytes.is_none()
                    && budget.is_none_or(|b| bytes <= b)
                    && largest / 2 >= MIN_RETRY_BYTES =>
            {
                cap = Some(largest / 2);
            }
            other => return other,
        }
    }
}

pub(super) struct Child {
    pub info: BrickInfo,
    pub renderer: Renderer,
}

/// What a brick renderer takes from its parent before a stack change.
pub(super) struct ChildSettings {
    shader_overrides: std::collections::BTreeMap<String, String>,
    overrides_generation: u64,
    skipping_enabled: bool,
    occupied_proxy: bool,
    hull_proxy: super::HullProxy,
    fused_slices: bool,
    state_tracking: bool,
    refinement_budget: Option<u32>,
    table_format: super::TableFormat,
}

impl ChildSettings {
    pub(super) fn of(parent: &Renderer) -> Self {
        Self {
            shader_overrides: parent.shader_overrides.clone(),
            overrides_generation: parent.overrides_generation,
            skipping_enabled: parent.skipping_enabled,
            occupied_proxy: parent.occupied_proxy,
            hull_proxy: parent.hull_proxy,
            fused_slices: parent.fused_slices,
            state_tracking: parent.state_tracking,
            refinement_budget: parent.refinement_budget,
            table_format: parent.table_format,
        }
    }

    pub(super) fn apply(&self, r: &mut Renderer) {
        r.shader_overrides = self.shader_overrides.clone();
        r.overrides_generation = self.overrides_generation;
        r.skipping_enabled = self.skipping_enabled;
        r.occupied_proxy = self.occupied_proxy;
        r.hull_proxy = self.hull_proxy;
        r.fused_slices = self.fused_slices;
        r.set_state_tracking(self.state_tracking);
        r.refinement_budget = self.refinement_budget;
        r.set_table_format(self.table_format);
    }
}

/// The bricks of a split volume and the compositing pipeline.
pub(super) struct Split {
    pub children: Vec<Child>,
    dims: [u32; 3],
    pieces: [Vec<(u32, u32)>; 3],
    /// The last frame's bricks, front to back, with their pixel footprints.
    last: Vec<(usize, [u32; 4])>,
    composite: Option<(TargetFormat, wgpu::RenderPipeline, wgpu::BindGroupLayout)>,
    /// The bricks share one eye buffer: each is drawn and composited before the next
    /// (bricks refined in view, whose count would otherwise multiply eye buffers).
    pub shared: bool,
}

/// Brick grid indices (x, y, z) of `pieces`, x fastest: the order of
/// [`Split::children`].
pub(super) fn grid(pieces: &[Vec<(u32, u32)>; 3]) -> impl Iterator<Item = [u32; 3]> + '_ {
    (0..pieces[2].len()).flat_map(move |z| {
        (0..pieces[1].len())
            .flat_map(move |y| (0..pieces[0].len()).map(move |x| [x as u32, y as u32, z as u32]))
    })
}

/// The voxels [start, end) per axis that the brick at grid `index` owns.
pub(super) fn brick_own(pieces: &[Vec<(u32, u32)>; 3], index: [u32; 3]) -> [[u32; 2]; 3] {
    std::array::from_fn(|a| {
        let (s, e) = pieces[a][index[a] as usize];
        [s, e]
    })
}

/// The voxels [start, end) per axis a brick owning `own` holds: its own and `ghost`
/// more beside every face with a neighbour.
pub(super) fn ghosted(dims: [u32; 3], own: [[u32; 2]; 3], ghost: u32) -> [[u32; 2]; 3] {
    std::array::from_fn(|a| {
        [
            own[a][0].saturating_sub(ghost),
            (own[a][1] + ghost).min(dims[a]),
        ]
    })
}

/// The brick of `volume` (box `whole`) owning the voxels `own`, as a renderer of its
/// own: its voxels with [`BRICK_GHOST`] voxels of its level beside them, averaged over
/// 2×2×2 blocks `level` times.
#[allow(clippy::too_many_arguments)]
pub(super) fn make_child(
    gpu: &GpuContext,
    volume: &Volume,
    whole: &VolumeBox,
    index: [u32; 3],
    own: [[u32; 2]; 3],
    level: u32,
    limit: u32,
    volume_format: VolumeFormat,
) -> Result<Child, RenderError> {
    let dims = volume.dims;
    let texture = ghosted(dims, own, BRICK_GHOST << level);
    let [ix, iy, iz] = index;
    let mut brick = cut(
        volume,
        texture,
        format!("{} brick {ix},{iy},{iz}", volume.name),
    )?;
    for _ in 0..level {
        brick = super::level::halve(&brick)?;
    }
    let info = BrickInfo {
        index,
        own,
        texture,
        level,
    };
    let vbox = sub_box(whole, dims, texture);
    child_of(gpu, brick, vbox, whole, dims, info, limit, volume_format)
}

/// A brick renderer for the voxels `brick` filling `vbox`, slicing the lattice of
/// `whole` (a volume of `dims` voxels) and taking the samples of `info.own` only.
#[allow(clippy::too_many_arguments)]
pub(super) fn child_of(
    gpu: &GpuContext,
    brick: Volume,
    vbox: VolumeBox,
    whole: &VolumeBox,
    dims: [u32; 3],
    info: BrickInfo,
    limit: u32,
    volume_format: VolumeFormat,
) -> Result<Child, RenderError> {
    let mut renderer = Renderer::with_options(
        gpu,
        Arc::new(brick),
        RendererOptions {
            gpu_memory_budget: None,
            brick_limit: Some(limit),
            max_brick_bytes: Some(u64::MAX),
            volume_format,
            workgroup: RendererOptions::from_env().workgroup,
            refine_in_view: false,
            lod_brick: None,
        },
    )?;
    let own = info.own;
    let open = (0..3)
        .filter(|&a| own[a][1] < dims[a])
        .fold(0, |m, a| m | (1 << a));
    renderer.vbox = vbox;
    renderer.region = Some(Region {
        lattice: *whole,
        own: sub_box(whole, dims, own),
        open,
    });
    Ok(Child { info, renderer })
}

/// World coordinate of voxel edge `e` (0..=dim) along an axis of the box.
fn edge_world(lo: f32, hi: f32, e: u32, dim: u32) -> f32 {
    if e == 0 {
        lo
    } else if e >= dim {
        hi
    } else {
        lo + (hi - lo) * (e as f32 / dim as f32)
    }
}

/// The box of voxel-edge ranges `r` (per axis) inside `whole`, with `whole`'s Δs0.
pub(super) fn sub_box(whole: &VolumeBox, dims: [u32; 3], r: [[u32; 2]; 3]) -> VolumeBox {
    let (lo, hi) = (whole.min.to_array(), whole.max.to_array());
    let at = |a: usize, e: u32| edge_world(lo[a], hi[a], e, dims[a]);
    VolumeBox {
        min: glam::Vec3::new(at(0, r[0][0]), at(1, r[1][0]), at(2, r[2][0])),
        max: glam::Vec3::new(at(0, r[0][1]), at(1, r[1][1]), at(2, r[2][1])),
        voxel: whole.voxel,
    }
}

/// Copies the voxels `r` (per axis, [start, end)) of a volume into a volume of their
/// own, keeping the whole volume's value range so that both normalise alike.
fn cut(volume: &Volume, r: [[u32; 2]; 3], name: String) -> Result<Volume, RenderError> {
    use crate::volume::VoxelData;
    let c = volume.components.max(1) as usize;
    let [w, h, _] = volume.dims.map(|d| d as usize);
    let dims = r.map(|[a, b]| b - a);
    fn copy<T: Copy>(v: &[T], r: [[u32; 2]; 3], w: usize, h: usize, c: usize) -> Vec<T> {
        let run = (r[0][1] - r[0][0]) as usize * c;
        let rows = (r[1][1] - r[1][0]) as usize * (r[2][1] - r[2][0]) as usize;
        let mut out = Vec::with_capacity(run * rows);
        for z in r[2][0] as usize..r[2][1] as usize {
            for y in r[1][0] as usize..r[1][1] as usize {
                let start = ((z * h + y) * w + r[0][0] as usize) * c;
                out.extend_from_slice(&v[start..start + run]);
            }
        }
        out
    }
    let data = match &volume.data {
        VoxelData::U8(v) => VoxelData::U8(copy(v, r, w, h, c)),
        VoxelData::I8(v) => VoxelData::I8(copy(v, r, w, h, c)),
        VoxelData::U16(v) => VoxelData::U16(copy(v, r, w, h, c)),
        VoxelData::I16(v) => VoxelData::I16(copy(v, r, w, h, c)),
        VoxelData::F32(v) => VoxelData::F32(copy(v, r, w, h, c)),
    };
    let mut brick = Volume::new(name, dims, volume.components, volume.spacing, data)
        .map_err(|e| RenderError::Bricks(format!("volume {}: {e}", volume.name)))?;
    brick.range = volume.range;
    brick.histogram = volume.histogram.clone();
    brick.source = volume.source.clone();
    Ok(brick)
}

impl Split {
    /// Cuts `volume` (box `whole`) into the bricks of `pieces` ([`split_volume`] at the
    /// brick `limit`) and uploads each. Fails, before anything is uploaded, when the
    /// bricks together pass the GPU memory `budget`.
    fn new(
        gpu: &GpuContext,
        volume: &Volume,
        whole: &VolumeBox,
        limit: u32,
        pieces: [Vec<(u32, u32)>; 3],
        budget: Option<u64>,
        volume_format: VolumeFormat,
    ) -> Result<Self, RenderError> {
        let dims = volume.dims;
        let texel = texel_bytes(volume_format.texture_format(gpu)?);
        let span = |a: usize, (s, e): (u32, u32)| {
            [
                s.saturating_sub(BRICK_GHOST),
                (e + BRICK_GHOST).min(dims[a]),
            ]
        };
        let bytes = texel
            * pieces
                .iter()
                .enumerate()
                .map(|(a, p)| {
                    p.iter()
                        .map(|&piece| {
                            let [s, e] = span(a, piece);
                            (e - s) as u64
                        })
                        .sum::<u64>()
                })
                .product::<u64>();
        if let Some(b) = budget
            && bytes > b
        {
            let what = format!("volume {} ({dims:?}) in bricks", volume.name);
            return Err(over_budget(what, bytes, b));
        }
        let mut children = Vec::new();
        for index in grid(&pieces) {
            let own = brick_own(&pieces, index);
            children.push(make_child(
                gpu,
                volume,
                whole,
                index,
                own,
                0,
                limit,
                volume_format,
            )?);
        }
        Ok(Self {
            children,
            dims,
            pieces,
            last: Vec::new(),
            composite: None,
            shared: false,
        })
    }

    /// `children` (in [`grid`] order of `pieces`, a volume of `dims` voxels) sharing
    /// one eye buffer: the bricks of a volume refined in view ([`super::lod`]).
    pub(super) fn shared(
        children: Vec<Child>,
        dims: [u32; 3],
        pieces: [Vec<(u32, u32)>; 3],
    ) -> Self {
        Self {
            children,
            dims,
            pieces,
            last: Vec::new(),
            composite: None,
            shared: true,
        }
    }

    /// Brick indices front to back for a view of the box `whole`: by the sum over axes
    /// of the distance (in bricks) from the brick holding the eye. Along any ray the
    /// bricks it crosses step away from the eye one axis at a time, so the sum grows
    /// strictly and the order is the ray's for every ray, perspective or not.
    fn order(&self, view: &crate::camera::View, whole: &VolumeBox) -> Vec<usize> {
        let eye = if view.perspective {
            view.eye
        } else {
            whole.centre() - view.forward * 1.0e3
        };
        let (lo, hi, e) = (whole.min.to_array(), whole.max.to_array(), eye.to_array());
        let at: [i64; 3] = std::array::from_fn(|a| {
            let t = (e[a] - lo[a]) / (hi[a] - lo[a]) * self.dims[a] as f32;
            let p = &self.pieces[a];
            p.iter()
                .position(|&(_, end)| t < end as f32)
                .unwrap_or(p.len() - 1) as i64
        });
        let key =
            |c: &Child| -> i64 { (0..3).map(|a| (c.info.index[a] as i64 - at[a]).abs()).sum() };
        let mut order: Vec<usize> = (0..self.children.len()).collect();
        order.sort_by_key(|&i| key(&self.children[i]));
        order
    }

    /// The compositing pipeline for eye buffers of `format`.
    fn ensure_composite(&mut self, gpu: &GpuContext, format: TargetFormat) {
        if self.composite.as_ref().is_none_or(|c| c.0 != format) {
            let (pipeline, layout) = fullscreen_pipeline(
                &gpu.device,
                "vwb composite",
                COMPOSITE_WGSL,
                &[eye_texture_entry(0)],
                ("vs_main", "fs_main"),
                &[Some(under_target(format))],
                None,
            );
            self.composite = Some((format, pipeline, layout));
        }
    }
}

impl Renderer {
    /// The bricks of a split volume, in grid order (empty when the volume is one
    /// texture).
    pub fn bricks(&self) -> Vec<BrickInfo> {
        self.split
            .as_ref()
            .map(|s| s.children.iter().map(|c| c.info).collect())
            .unwrap_or_default()
    }

    /// The last frame's partial images, front to back: (index into
    /// [`Renderer::bricks`], premultiplied RGBA row-major from the top, zero outside
    /// the brick's footprint). What a sort-last engine would send between machines;
    /// bricks that covered no pixel are left out. Empty for a volume in one texture
    /// and for bricks refined in view (they share one eye buffer).
    pub fn brick_images(&self) -> Vec<(usize, Vec<[f32; 4]>)> {
        let Some(split) = self.split.as_ref().filter(|sp| !sp.shared) else {
            return Vec::new();
        };
        split
            .last
            .iter()
            .filter_map(|&(i, rect)| {
                let (w, _, mut px) = split.children[i].renderer.read_pixels()?;
                for (k, p) in px.iter_mut().enumerate() {
                    let (x, y) = (k as u32 % w, k as u32 / w);
                    if x < rect[0] || x >= rect[2] || y < rect[1] || y >= rect[3] {
                        *p = [0.0; 4];
                    }
                }
                Some((i, px))
            })
            .collect()
    }

    /// The stack change of a split volume: every brick gets the stack; the first
    /// brick composes, the others take its compiled pipelines from the cache. An
    /// error leaves every brick on its last good pipeline.
    pub(super) fn update_split_stack(
        &mut self,
        stack: &[PluginInstance],
        target: TargetFormat,
    ) -> Result<StackChange, RenderError> {
        let settings = ChildSettings::of(self);
        let split = self.split.as_mut().expect("split volume");
        if let Some(i) = stack
            .iter()
            .find(|i| i.enabled && !i.configured().splits_into_bricks())
        {
            return Err(RenderError::Bricks(format!(
                "plugin {} cannot render volume {} ({:?} voxels, split into {} bricks at the \
                 3D-texture limit of {} voxels): it carries information across the whole \
                 volume; disable it, or crop the volume (vwb crop) to fit one texture",
                i.plugin.id(),
                self.volume.name,
                self.volume.dims,
                split.children.len(),
                self.brick_limit
            )));
        }
        let mut change = StackChange::None;
        let mut cache: Vec<(u64, Arc<CompiledStack>)> = Vec::new();
        for (i, c) in split.children.iter_mut().enumerate() {
            let r = &mut c.renderer;
            settings.apply(r);
            for (h, compiled) in &cache {
                if !r.compiled.iter().any(|(k, _)| k == h) {
                    r.compiled.push((*h, compiled.clone()));
                }
            }
            let ch = r.update_stack(stack, target)?;
            if i == 0 {
                change = ch;
                cache = r.compiled.clone();
            }
        }
        Ok(change)
    }

    /// Renders every brick into its eye buffer and composites them front to back into
    /// this renderer's, in one submission.
    pub(super) fn render_split(&mut self, s: &FrameSettings) -> Result<FrameStats, RenderError> {
        let needs_stack = self
            .split
            .as_ref()
            .is_some_and(|sp| sp.children.iter().any(|c| c.renderer.pipelines.is_none()));
        if needs_stack {
            self.update_split_stack(&[], TargetFormat::default())?;
        }
        // bricks refined in view: all before the frame when nothing limits the steps
        if self.refinement_budget.is_none() {
            self.refine_bricks(s, true)?;
        }
        if let Some(lod) = self.lod.as_mut() {
            lod.redraw = false;
        }
        crate::validate::check_camera(&s.camera)?;
        let view = s.camera.view(s.width as f32 / s.height as f32);
        let plan = SlicePlan::new(&view, &self.vbox, s.slice_spacing)?;
        let format = self
            .split
            .as_ref()
            .and_then(|sp| sp.children[0].renderer.pipelines.as_ref())
            .map(|p| p.key.target)
            .unwrap_or_default();
        if format == TargetFormat::Rgba32Float
            && !self
                .gpu
                .features
                .contains(wgpu::Features::FLOAT32_BLENDABLE)
        {
            return Err(RenderError::NoFloat32Blending);
        }
        self.ensure_target(s.width, s.height, format)?;
        let gpu = self.gpu.clone();
        let timestamps = self.timestamps.as_ref();
        let target = self.target.as_ref().expect("target exists");
        let split = self.split.as_mut().expect("split volume");
        let order = split.order(&view, &self.vbox);
        let mut enc = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("vwb bricks"),
            });
        if let Some((qs, _, _)) = timestamps {
            enc.write_timestamp(qs, 0);
        }
        // bricks whose box covers no pixel are not drawn
        let size = [s.width, s.height];
        let order: Vec<(usize, [u32; 4])> = order
            .into_iter()
            .map(|i| (i, split.children[i].renderer.pixel_rect(&view, size)))
            .filter(|(_, r)| r[2] > r[0] && r[3] > r[1])
            .collect();
        split.ensure_composite(&gpu, format);
        if split.shared {
            // one eye buffer for every brick: the first in the order makes it
            if let Some(&(first, _)) = order.first() {
                split.children[first]
                    .renderer
                    .ensure_target(s.width, s.height, format)?;
                let scratch = split.children[first].renderer.target.clone();
                for c in &mut split.children {
                    c.renderer.target = scratch.clone();
                }
            }
        }
        let mut recorded = Vec::with_capacity(order.len());
        let (_, pipeline, layout) = split.composite.as_ref().expect("made above");
        // partial images (view, footprint), in order, under what is in the target (or
        // into the cleared target), in one pass
        let composite = |enc: &mut wgpu::CommandEncoder,
                         parts: &[(&wgpu::TextureView, [u32; 4])],
                         clear: bool| {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("vwb composite"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target.view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: if clear {
                            wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT)
                        } else {
                            wgpu::LoadOp::Load
                        },
                        store: wgpu::StoreOp::Store,
                    },
                })],
                ..Default::default()
            });
            pass.set_pipeline(pipeline);
            for &(part, rect) in parts {
                let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("vwb composite"),
                    layout,
                    entries: &[wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(part),
                    }],
                });
                pass.set_bind_group(0, &group, &[]);
                // only the brick's footprint: a compute brick writes no other pixel
                pass.set_scissor_rect(rect[0], rect[1], rect[2] - rect[0], rect[3] - rect[1]);
                pass.draw(0..3, 0..1);
            }
        };
        if split.shared {
            // draw a brick, composite it, then the next brick reuses the eye buffer
            if order.is_empty() {
                composite(&mut enc, &[], true);
            }
            for (k, &(i, rect)) in order.iter().enumerate() {
                let r = &mut split.children[i].renderer;
                recorded.push((i, r.record(s, &mut enc, false)?));
                let part = &r.target.as_ref().expect("drawn").view;
                composite(&mut enc, &[(part, rect)], k == 0);
            }
            if let Some((qs, _, _)) = timestamps {
                enc.write_timestamp(qs, 1);
            }
        } else {
            // every partial image stays in its own eye buffer (Renderer::brick_images)
            for &(i, _) in &order {
                recorded.push((i, split.children[i].renderer.record(s, &mut enc, false)?));
            }
            if let Some((qs, _, _)) = timestamps {
                enc.write_timestamp(qs, 1);
            }
            let parts: Vec<(&wgpu::TextureView, [u32; 4])> = order
                .iter()
                .map(|&(i, rect)| {
                    let t = split.children[i].renderer.target.as_ref();
                    (&t.expect("drawn").view, rect)
                })
                .collect();
            composite(&mut enc, &parts, true);
        }
        let start = recorded.first().map_or_else(Instant::now, |(_, r)| r.start);
        if let Some((qs, resolve, read)) = timestamps {
            enc.write_timestamp(qs, 2);
            enc.resolve_query_set(qs, 0..3, resolve, 0);
            enc.copy_buffer_to_buffer(resolve, 0, read, 0, 24);
        }
        gpu.queue.submit([enc.finish()]);
        split.last = order.clone();
        let mut stats = FrameStats {
            slices: plan.count,
            ..Default::default()
        };
        // the bricks that marched whole frames (their loop limiter's counters)
        let mut marched = Vec::new();
        for (i, rec) in recorded {
            let st = split.children[i].renderer.submitted(rec);
            if st.march_parts > 0 {
                marched.push(i);
            }
            stats.march_parts = stats.march_parts.max(st.march_parts);
            stats.per_slice_mode |= st.per_slice_mode;
            stats.fused_slices |= st.fused_slices;
            stats.prepasses.extend(st.prepasses);
            stats.spacing_updates += st.spacing_updates;
            stats.volume_passes_run.extend(st.volume_passes_run);
        }
        if let Some((_, _, read)) = timestamps {
            let t = read_ticks(&gpu, read, 3);
            let ms = |a: u64, b: u64| ticks_ms(&gpu, a, b);
            stats.gpu_passes = vec![
                (format!("{} bricks", order.len()), ms(t[0], t[1])),
                ("composite".to_string(), ms(t[1], t[2])),
            ];
            stats.gpu_ms = Some(ms(t[0], t[2]));
        } else {
            gpu.wait();
        }
        stats.wall_ms = start.elapsed().as_secs_f64() * 1e3;
        // the bricks whose march ran out of the CPU device's loop iterations
        if gpu.info.device_type == wgpu::DeviceType::Cpu {
            for i in &marched {
                let child = &split.children[*i].renderer;
                stats.loop_limited += child.march.read(&child.gpu);
            }
        }
        // else a few bricks after it, while the window shows it
        if self.refinement_budget.is_some() {
            self.refine_bricks(s, false)?;
        }
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_split_into_near_equal_pieces_that_fit_with_their_ghosts() {
        assert_eq!(split_axis(2048, 2048), vec![(0, 2048)]);
        assert_eq!(split_axis(2100, 2048), vec![(0, 1050), (1050, 2100)]);
        for (dim, limit) in [
            (256, 64),
            (108, 64),
            (50, 24),
            (2100, 2048),
            (1000, 8),
            (9, 8),
        ] {
            let p = split_axis(dim, limit);
            assert_eq!(p[0].0, 0);
            assert_eq!(p.last().unwrap().1, dim);
            for w in p.windows(2) {
                assert_eq!(w[0].1, w[1].0, "contiguous");
            }
            let sizes: Vec<u32> = p.iter().map(|(a, b)| b - a).collect();
            let (lo, hi) = (*sizes.iter().min().unwrap(), *sizes.iter().max().unwrap());
            assert!(hi - lo <= 1, "near equal: {sizes:?}");
            let limit = limit.max(MIN_BRICK_LIMIT);
            assert!(
                p.len() == 1 && dim <= limit || hi + 2 * BRICK_GHOST <= limit,
                "{dim} at {limit}: {sizes:?}"
            );
            assert!(lo >= 1);
        }
        // limits below the minimum count as the minimum
        assert_eq!(split_axis(100, 1), split_axis(100, MIN_BRICK_LIMIT));
    }

    #[test]
    fn over_is_associative_and_keeps_order() {
        let px = |r: f32, a: f32| vec![[r * a, 0.5 * a, 0.0, a]];
        let (a, b, c) = (px(1.0, 0.5), px(0.2, 0.7), px(0.9, 0.3));
        let left = over(&over(&a, &b), &c);
        let right = over(&a, &over(&b, &c));
        for k in 0..4 {
            assert!((left[0][k] - right[0][k]).abs() < 1e-6);
        }
        assert_ne!(over(&a, &b), over(&b, &a));
        // an opaque front hides the back
        assert_eq!(over(&px(1.0, 1.0), &b), px(1.0, 1.0));
    }

    #[test]
    fn brick_boxes_share_their_faces_exactly() {
        let whole = VolumeBox::new([100, 60, 30], [1.0, 1.0, 2.0]);
        let p = split_axis(100, 40);
        let a = sub_box(&whole, [100, 60, 30], [[p[0].0, p[0].1], [0, 60], [0, 30]]);
        let b = sub_box(&whole, [100, 60, 30], [[p[1].0, p[1].1], [0, 60], [0, 30]]);
        assert_eq!(a.max.x, b.min.x);
        assert_eq!(a.min, whole.min);
        let last = sub_box(&whole, [100, 60, 30], [[p[2].0, 100], [0, 60], [0, 30]]);
        assert_eq!(last.max, whole.max);
        assert_eq!(a.voxel, whole.voxel);
    }
}
