//! A coarser level for a volume beyond the GPU memory budget: rather than refuse it,
//! the renderer shows the volume averaged over 2×2×2 blocks (repeatedly) until its
//! texture takes at most half the budget, and says so ([`Renderer::level`]).
//!
//! The level keeps the volume's box (its spacing grows so that the extents stay), its
//! value range (so the transfer function maps values as before) and Δs0, the world
//! length at which TF opacities are defined (so slices at "one voxel" are as many and
//! as opaque as on the full volume). What a coarser level loses is detail: structures
//! thinner than its voxels blur (docs/scale.md measures it). With
//! `RendererOptions::refine_in_view` the bricks in view are then refined from the full
//! volume ([`super::lod`]).
//!
//! A volume read from a multiscale OME-Zarr image ([`crate::volume::zarr`]) has its
//! coarser levels stored: the finest stored level that fits is read instead of
//! averaging, and a volume the loader already read at a coarser level
//! ([`crate::volume::zarr::load_within`]) is shown with the same notice.

use super::*;
use crate::volume::VoxelData;

/// The level a renderer shows instead of its volume.
#[derive(Debug, Clone, PartialEq)]
pub struct LevelInfo {
    /// Voxels of the full volume per level voxel along each axis (2, 4, …).
    pub factor: u32,
    pub full_dims: [u32; 3],
    pub level_dims: [u32; 3],
    /// Why: the full volume's texture bytes and the budget.
    pub full_bytes: u64,
    /// The budget in bytes; 0 when the loader chose a stored level without one.
    pub budget: u64,
    /// The stored level of the source's pyramid shown (OME-Zarr), or `None` when the
    /// level was averaged from the full volume.
    pub stored: Option<usize>,
    /// When the bricks in view are refined ([`super::lod`]): bricks at full
    /// resolution, all bricks, and bricks not yet at the level the view wants.
    pub refined: Option<[usize; 3]>,
}

impl LevelInfo {
    /// One line for the window and the command line.
    pub fn notice(&self) -> String {
        let what = match self.stored {
            Some(i) => format!("stored level {i}, "),
            None => String::new(),
        };
        let why = if self.budget == 0 {
            "; the level was chosen when loading".to_owned()
        } else {
            format!(
                ", more than half the GPU memory budget of {} MiB",
                self.budget >> 20
            )
        };
        let refined = match self.refined {
            Some([full, n, 0]) => {
                format!("; bricks in view refined: {full} of {n} at full resolution")
            }
            Some([full, n, pending]) => format!(
                "; refining the bricks in view: {full} of {n} at full resolution, {pending} to go"
            ),
            None => String::new(),
        };
        format!(
            "showing a 1/{} level ({what}{:?} of {:?} voxels): the volume needs {} MiB{why}{refined}",
            self.factor,
            self.level_dims,
            self.full_dims,
            self.full_bytes.div_ceil(1 << 20),
        )
    }
}

/// The volume averaged over 2×2×2 blocks (partial blocks at odd ends), as f32, with the
/// same box and value range. Non-finite samples are left out of a block's average (a
/// block of only non-finite samples stays NaN).
pub fn halve(volume: &Volume) -> Result<Volume, RenderError> {
    let [w, h, d] = volume.dims.map(|v| v as usize);
    let c = volume.components.max(1) as usize;
    let dims = volume.dims.map(|v| v.div_ceil(2));
    let [nw, nh, nd] = dims.map(|v| v as usize);
    let get: Box<dyn Fn(usize) -> f64 + Sync + '_> = match &volume.data {
        VoxelData::U8(v) => Box::new(move |i| f64::from(v[i])),
        VoxelData::I8(v) => Box::new(move |i| f64::from(v[i])),
        VoxelData::U16(v) => Box::new(move |i| f64::from(v[i])),
        VoxelData::I16(v) => Box::new(move |i| f64::from(v[i])),
        VoxelData::F32(v) => Box::new(move |i| f64::from(v[i])),
    };
    let mut out = vec![0.0f32; nw * nh * nd * c];
    use rayon::prelude::*;
    out.par_chunks_mut(nw * nh * c)
        .enumerate()
        .for_each(|(z, plane)| {
            for y in 0..nh {
                for x in 0..nw {
                    for k in 0..c {
                        let (mut sum, mut n) = (0.0f64, 0u32);
                        for zz in 2 * z..(2 * z + 2).min(d) {
                            for yy in 2 * y..(2 * y + 2).min(h) {
                                for xx in 2 * x..(2 * x + 2).min(w) {
                                    let v = get(((zz * h + yy) * w + xx) * c + k);
                                    if v.is_finite() {
                                        sum += v;
                                        n += 1;
                                    }
                                }
                            }
                        }
                        plane[(y * nw + x) * c + k] = if n > 0 {
                            (sum / f64::from(n)) as f32
                        } else {
                            f32::NAN
                        };
                    }
                }
            }
        });
    // the same extents: spacing × (dims / level dims)
    let spacing: [f64; 3] =
        std::array::from_fn(|a| volume.spacing[a] * volume.dims[a] as f64 / dims[a] as f64);
    let mut level = Volume::new(
        format!("{} (1/2)", volume.name),
        dims,
        volume.components,
        spacing,
        VoxelData::F32(out),
    )
    .map_err(|e| RenderError::Bricks(format!("volume {}: {e}", volume.name)))?;
    level.range = volume.range;
    level.histogram = volume.histogram.clone();
    level.source = volume.source.clone();
    level.notes = volume.notes.clone();
    Ok(level)
}

/// The coarsest-needed level of `volume` for `budget`: `None` when its texture takes
/// at most the budget; else the volume halved until its texture takes at most half of
/// it (the rest is for eye buffers and plugins), with what was done.
pub(super) fn level_for(
    volume: &Arc<Volume>,
    budget: Option<u64>,
    format: wgpu::TextureFormat,
) -> Result<Option<(Arc<Volume>, LevelInfo)>, RenderError> {
    let per_voxel = texel_bytes(format);
    if let Some(info) = stored_level_info(volume, budget, format) {
        // the loader read a coarser stored level already
        return Ok(Some((volume.clone(), info)));
    }
    let Some(budget) = budget else {
        return Ok(None);
    };
    let full_bytes = volume_texture_bytes(format, volume);
    if full_bytes <= budget {
        return Ok(None);
    }
    if let Some(p) = &volume.pyramid
        && let Some(i) = p.finest_within(budget / 2, per_voxel)
    {
        // a stored level of the source's pyramid: read it rather than average
        let mut level = crate::volume::zarr::load_level(&p.root, i)
            .map_err(|e| RenderError::Bricks(format!("volume {}: {e}", volume.name)))?;
        level.range = volume.range;
        level.histogram = volume.histogram.clone();
        let info = LevelInfo {
            factor: p.factor(i),
            full_dims: volume.dims,
            level_dims: level.dims,
            full_bytes,
            budget,
            stored: Some(i),
            refined: None,
        };
        return Ok(Some((Arc::new(level), info)));
    }
    let mut level = volume.clone();
    let mut factor = 1;
    while volume_texture_bytes(format, &level) > budget / 2 {
        if level.dims.iter().all(|&d| d <= 1) {
            return Err(RenderError::OutOfMemory {
                what: format!("volume {} ({:?})", volume.name, volume.dims),
                bytes: full_bytes,
                reason: format!(
                    "more than the renderer's GPU memory budget of {} MiB at any level",
                    budget >> 20
                ),
            });
        }
        level = Arc::new(halve(&level)?);
        factor *= 2;
    }
    let info = LevelInfo {
        factor,
        full_dims: volume.dims,
        level_dims: level.dims,
        full_bytes,
        budget,
        stored: None,
        refined: None,
    };
    Ok(Some((level, info)))
}

/// What a volume that is itself a coarser stored level of its source's pyramid (read
/// alone by [`crate::volume::zarr::load_within`]) shows; `None` for any other volume.
pub(super) fn stored_level_info(
    volume: &Volume,
    budget: Option<u64>,
    format: wgpu::TextureFormat,
) -> Option<LevelInfo> {
    let p = volume.pyramid.as_ref().filter(|p| p.shown > 0)?;
    let full = p.levels[0].dims;
    Some(LevelInfo {
        factor: p.factor(p.shown),
        full_dims: full,
        level_dims: volume.dims,
        full_bytes: dims_texture_bytes(format, full),
        budget: budget.unwrap_or(0),
        stored: Some(p.shown),
        refined: None,
    })
}

/// The voxels of the full volume a volume stands for: for a coarser stored level read
/// alone, its pyramid's level 0; else its own.
pub(super) fn full_dims(volume: &Volume) -> [u32; 3] {
    match volume.pyramid.as_ref().filter(|p| p.shown > 0) {
        Some(p) => p.levels[0].dims,
        None => volume.dims,
    }
}

/// The box a volume renders in: for a coarser stored level read alone, the full
/// level's (so its slices are as many and as opaque as the full volume's, as for an
/// averaged level); else its own.
pub(super) fn full_box(volume: &Volume) -> VolumeBox {
    match volume.pyramid.as_ref().filter(|p| p.shown > 0) {
        Some(p) => VolumeBox::new(p.levels[0].dims, p.levels[0].spacing),
        None => VolumeBox::new(volume.dims, volume.spacing),
    }
}
