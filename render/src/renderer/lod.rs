//! Refining the bricks in view: beyond the GPU memory budget, the volume is shown at
//! once as a coarser level ([`super::level`]) and then, brick by brick, at the finest
//! levels that the budget holds for what the view shows.
//!
//! The volume is cut into bricks of at most [`LOD_BRICK`] voxels of the full volume a
//! side (`RendererOptions::lod_brick`), each an ordinary brick renderer of its own
//! voxels averaged over 2×2×2 blocks `l` times (its level), with [`BRICK_GHOST`] voxels
//! of that level beside every shared face. All bricks slice the whole volume's lattice
//! and composite front to back as bricks in core do ([`super::bricks`]); they share one
//! eye buffer, drawn and composited brick by brick, so that their number does not
//! multiply eye buffers.
//!
//! **Which bricks, which levels.** Every brick starts at the coarsest level L of the
//! whole-volume rule (the level whose texture takes at most half the budget). For a
//! view, the bricks whose box projects onto the image are "in view"; the others stay
//! at (or go back to) L. In view, the brick whose voxels at its present level cover
//! the most pixels (its footprint's longer side over its voxels along its longest axis)
//! is refined one level, then the next, greedily, while the bricks' textures fit in
//! what the budget leaves beside the eye buffers, instance resources and the compositor
//! (so [`Renderer::gpu_memory`] stays within the budget). That gives each frame a wanted
//! level per brick.
//!
//! **When.** With a refinement budget ([`Renderer::set_refinement_budget`], as the
//! window sets), the frame is drawn first and then at most [`BRICKS_PER_STEP`] bricks
//! per step are rebuilt (bricks to coarsen first, freeing memory), so the coarse image
//! comes at once and the window draws again while [`Renderer::refining`]. Without one
//! (headless: one image), every brick reaches its wanted level before the frame.
//!
//! **Where finer voxels come from.** An averaged level's bricks are cut from the full
//! volume in memory and averaged `l` times (level `l`). A stored level of an OME-Zarr
//! pyramid ([`crate::volume::zarr`]) refines through the finer stored levels instead,
//! each brick reading only its region of that level from the store
//! ([`crate::volume::zarr::load_region`]), so the full volume never has to be in
//! memory; its levels are the store's (level `l` is stored level `l`).
//!
//! **What is kept out.** A stack with a plugin whose state crosses the volume
//! ([`crate::plugin::Plugin::splits_into_bricks`]: per-slice occlusion, light volumes,
//! LIC) cannot be split: it is shown on the whole coarser level, as without
//! refinement, and refined again when such plugins are disabled.
//!
//! Choices, measured in docs/scale.md: bricks refine toward the eye's detail (pixels
//! per voxel), not toward opacity; the seams where neighbouring bricks differ in level
//! are those of their averaged values (each brick's ghosts are read at its own level).

use super::bricks;
use super::bricks::{Split, brick_own, ghosted, grid, split_volume};
use super::*;

/// Voxels of the full volume a refinable brick owns along an axis at most, unless
/// `RendererOptions::lod_brick` says otherwise: a quarter of the longest axis (a power
/// of two), from 64 to this. docs/scale.md measures 64 against 128 on the CT head.
pub const LOD_BRICK: u32 = 128;

/// The default brick side for a volume of `dims` voxels.
fn default_brick(dims: [u32; 3]) -> u32 {
    let longest = dims.into_iter().max().unwrap_or(1);
    (longest / 4)
        .max(1)
        .next_power_of_two()
        .clamp(64, LOD_BRICK)
}

/// Where a brick's voxels at a level come from.
enum Source {
    /// The full volume in memory: level `l` averages it `l` times.
    Memory(Arc<Volume>),
    /// An OME-Zarr image's stored levels, read region by region; the level shown lends
    /// its value range and histogram to every brick.
    Store(crate::volume::zarr::Pyramid, Arc<Volume>),
}

/// Bricks rebuilt (refined or coarsened) per refinement step of a frame.
pub const BRICKS_PER_STEP: usize = 2;

/// A volume beyond the budget, refinable in view.
pub(super) struct Lod {
    /// Where the bricks' voxels come from.
    source: Source,
    /// Voxels of the full volume (level 0).
    dims: [u32; 3],
    /// Pieces of each axis (owned voxel ranges of the full volume).
    pieces: [Vec<(u32, u32)>; 3],
    /// The whole-volume level L (times halved): every brick's coarsest.
    coarsest: u32,
    /// Bytes of one voxel as stored.
    texel: u64,
    /// Whether the bricks are drawn (the stack splits); else the whole level is.
    pub active: bool,
    /// The stack and target of the last update, for rebuilt bricks.
    pub stack: Vec<PluginInstance>,
    pub target: TargetFormat,
    /// The wanted level per brick for the last frame's view.
    wanted: Vec<u32>,
    /// Bricks were rebuilt after the last frame was drawn: it needs drawing again.
    pub redraw: bool,
}

impl Lod {
    /// The averaged level `coarsest` of `full` (in memory), refinable in bricks of at
    /// most `brick` voxels a side (`None`: [`default_brick`]).
    pub(super) fn in_memory(
        full: Arc<Volume>,
        coarsest: u32,
        brick: Option<u32>,
        limit: u32,
        texel: u64,
    ) -> Self {
        let dims = full.dims;
        Self::new(Source::Memory(full), dims, coarsest, brick, limit, texel)
    }

    /// The stored level `shown` (read alone, or chosen by the budget) of an OME-Zarr
    /// `pyramid`, refinable through its finer stored levels.
    pub(super) fn stored(
        pyramid: crate::volume::zarr::Pyramid,
        shown: Arc<Volume>,
        level: u32,
        brick: Option<u32>,
        limit: u32,
        texel: u64,
    ) -> Self {
        let dims = pyramid.levels[0].dims;
        Self::new(
            Source::Store(pyramid, shown),
            dims,
            level,
            brick,
            limit,
            texel,
        )
    }

    fn new(
        source: Source,
        dims: [u32; 3],
        coarsest: u32,
        brick: Option<u32>,
        limit: u32,
        texel: u64,
    ) -> Self {
        let brick = brick.unwrap_or_else(|| default_brick(dims));
        let side = brick.clamp(MIN_BRICK_LIMIT, limit.max(MIN_BRICK_LIMIT));
        let pieces = split_volume(dims, side + 2 * BRICK_GHOST, None, texel);
        let n = pieces.iter().map(Vec::len).product();
        Self {
            source,
            dims,
            pieces,
            coarsest,
            texel,
            active: false,
            stack: Vec::new(),
            target: TargetFormat::default(),
            wanted: vec![coarsest; n],
            redraw: false,
        }
    }

    /// Voxels of the full volume per voxel of `level`.
    fn factor(&self, level: u32) -> u32 {
        match &self.source {
            Source::Memory(_) => 1 << level,
            Source::Store(p, _) => p.factor(level as usize),
        }
    }

    /// For the brick owning `own` at `level`: the voxels of that level it holds
    /// ([start, end) per axis, with [`BRICK_GHOST`] of them beside every shared face)
    /// and that level's voxel counts.
    fn region(&self, own: [[u32; 2]; 3], level: u32) -> ([[u32; 2]; 3], [u32; 3]) {
        let f = self.factor(level);
        let texture = ghosted(self.dims, own, BRICK_GHOST * f);
        match &self.source {
            Source::Memory(_) => (
                texture.map(|[s, e]| [s / f, s / f + (e - s).div_ceil(f)]),
                self.dims.map(|d| d.div_ceil(f)),
            ),
            Source::Store(p, _) => {
                let dl = p.levels[level as usize].dims;
                let r = std::array::from_fn(|a| {
                    let scale = |e: u32| u64::from(e) * u64::from(dl[a]);
                    let d0 = u64::from(self.dims[a]);
                    let lo = (scale(texture[a][0]) / d0) as u32;
                    let hi = (scale(texture[a][1]).div_ceil(d0) as u32).min(dl[a]);
                    [lo.min(hi.saturating_sub(1)), hi.max(1)]
                });
                (r, dl)
            }
        }
    }

    /// Texture bytes of the brick owning `own` at `level`.
    fn bytes(&self, own: [[u32; 2]; 3], level: u32) -> u64 {
        let (r, _) = self.region(own, level);
        r.iter().map(|[s, e]| u64::from(e - s)).product::<u64>() * self.texel
    }
}

impl Renderer {
    /// Draws the bricks from now on (every brick at the coarsest level), in place of
    /// the whole coarser level.
    pub(super) fn enter_lod(&mut self) -> Result<(), RenderError> {
        let lod = self.lod.as_ref().expect("refinable");
        let coarsest = lod.coarsest;
        let indices: Vec<[u32; 3]> = grid(&lod.pieces).collect();
        let children = indices
            .into_iter()
            .map(|index| self.lod_child(index, coarsest))
            .collect::<Result<Vec<_>, _>>()?;
        let n = children.len();
        let split = Split::shared(children, lod.dims, lod.pieces.clone());
        let volume = self.volume.clone();
        self.install(bricks::Upload::Split(split), &volume);
        self.rebuild_g0();
        let lod = self.lod.as_mut().expect("refinable");
        lod.active = true;
        lod.wanted = vec![coarsest; n];
        self.note_refinement();
        Ok(())
    }

    /// The brick at grid `index` at `level`, from the refinable volume's source.
    fn lod_child(&self, index: [u32; 3], level: u32) -> Result<bricks::Child, RenderError> {
        let lod = self.lod.as_ref().expect("refinable");
        let own = brick_own(&lod.pieces, index);
        let (limit, format) = (self.brick_limit, self.stored_format);
        match &lod.source {
            Source::Memory(full) => bricks::make_child(
                &self.gpu, full, &self.vbox, index, own, level, limit, format,
            ),
            Source::Store(p, shown) => {
                let (region, dl) = lod.region(own, level);
                let mut brick =
                    crate::volume::zarr::load_region(&p.root, level as usize, region)
                        .map_err(|e| RenderError::Bricks(format!("volume {}: {e}", shown.name)))?;
                brick.range = shown.range;
                brick.histogram = shown.histogram.clone();
                // the level's voxels in the full volume's (for BrickInfo)
                let d0 = lod.dims;
                let texture = std::array::from_fn(|a| {
                    let back = |e: u32| {
                        (u64::from(e) * u64::from(d0[a])).div_ceil(u64::from(dl[a])) as u32
                    };
                    [back(region[a][0]).min(d0[a]), back(region[a][1]).min(d0[a])]
                });
                let info = bricks::BrickInfo {
                    index,
                    own,
                    texture,
                    level,
                };
                let vbox = bricks::sub_box(&self.vbox, dl, region);
                bricks::child_of(&self.gpu, brick, vbox, &self.vbox, d0, info, limit, format)
            }
        }
    }

    /// Draws the whole coarser level again (one texture), in place of the bricks.
    pub(super) fn leave_lod(&mut self) -> Result<(), RenderError> {
        let upload = upload_or_split(
            &self.gpu,
            &self.volume,
            &self.vbox,
            self.brick_limit,
            self.max_brick_bytes,
            None,
            self.stored_format,
        )?;
        let volume = self.volume.clone();
        self.install(upload, &volume);
        self.rebuild_g0();
        if let Some(lod) = self.lod.as_mut() {
            lod.active = false;
        }
        self.note_refinement();
        Ok(())
    }

    /// Keeps the stack for bricks rebuilt later.
    pub(super) fn remember_lod_stack(&mut self, stack: &[PluginInstance], target: TargetFormat) {
        if let Some(lod) = self.lod.as_mut() {
            lod.stack = stack.to_vec();
            lod.target = target;
        }
    }

    /// The level each brick should have for a `size` frame of `view`.
    fn wanted_levels(&self, view: &crate::camera::View, size: [u32; 2]) -> Vec<u32> {
        let (Some(lod), Some(split), Some(budget)) = (&self.lod, &self.split, self.gpu_budget)
        else {
            return Vec::new();
        };
        let n = split.children.len();
        let textures: u64 = split.children.iter().map(|c| c.renderer.volume_bytes).sum();
        // what the budget leaves for brick textures: the rest of what is held now, with
        // the shared eye buffer and the compositor's counted for the frame's size
        let eye = target_bytes(size[0], size[1], lod.target);
        let held_eye = self.target.as_ref().map_or(0, Target::bytes)
            + split
                .children
                .iter()
                .find_map(|c| c.renderer.target.as_ref())
                .map_or(0, Target::bytes);
        let rest = self.gpu_memory().saturating_sub(textures + held_eye) + 2 * eye;
        let room = budget.saturating_sub(rest);
        let mut levels = vec![lod.coarsest; n];
        let own = |i: usize| split.children[i].info.own;
        let mut used: u64 = (0..n).map(|i| lod.bytes(own(i), lod.coarsest)).sum();
        // pixels per voxel of brick i at level l (0: not in view)
        let detail: Vec<f64> = split
            .children
            .iter()
            .map(|c| {
                let r = c.renderer.own_pixel_rect(view, size);
                if r[2] <= r[0] || r[3] <= r[1] {
                    return 0.0;
                }
                let px = f64::from((r[2] - r[0]).max(r[3] - r[1]));
                let voxels = c.info.own.iter().map(|[s, e]| e - s).max().unwrap_or(1);
                px / f64::from(voxels.max(1))
            })
            .collect();
        let mut open: Vec<usize> = (0..n).filter(|&i| detail[i] > 0.0).collect();
        while !open.is_empty() {
            // the brick in view whose voxels now cover the most pixels
            let (k, &i) = open
                .iter()
                .enumerate()
                .max_by(|a, b| {
                    let pa = detail[*a.1] * f64::from(lod.factor(levels[*a.1]));
                    let pb = detail[*b.1] * f64::from(lod.factor(levels[*b.1]));
                    pa.total_cmp(&pb).then(b.1.cmp(a.1))
                })
                .expect("not empty");
            let more = lod.bytes(own(i), levels[i] - 1) - lod.bytes(own(i), levels[i]);
            if used + more > room {
                open.swap_remove(k);
                continue;
            }
            used += more;
            levels[i] -= 1;
            if levels[i] == 0 {
                open.swap_remove(k);
            }
        }
        levels
    }

    /// Rebuilds at most `most` bricks toward the levels `wanted` (bricks to coarsen
    /// first, then to refine by their order in `wanted`'s computation); returns how
    /// many were rebuilt.
    fn rebuild_bricks(&mut self, wanted: &[u32], most: usize) -> Result<usize, RenderError> {
        let (Some(lod), Some(split)) = (self.lod.as_ref(), self.split.as_ref()) else {
            return Ok(0);
        };
        let now: Vec<u32> = split.children.iter().map(|c| c.info.level).collect();
        if wanted.len() != now.len() {
            return Ok(0);
        }
        let mut todo: Vec<usize> = (0..now.len()).filter(|&i| wanted[i] > now[i]).collect();
        todo.extend((0..now.len()).filter(|&i| wanted[i] < now[i]));
        todo.truncate(most);
        let (stack, target) = (lod.stack.clone(), lod.target);
        for &i in &todo {
            let index = self.split.as_ref().expect("split").children[i].info.index;
            let mut child = self.lod_child(index, wanted[i])?;
            let r = &mut child.renderer;
            bricks::ChildSettings::of(self).apply(r);
            let split = self.split.as_mut().expect("split");
            // compiled stacks do not depend on the volume: take the other bricks'
            for (h, compiled) in split.children.iter().flat_map(|c| &c.renderer.compiled) {
                if !r.compiled.iter().any(|(k, _)| k == h) {
                    r.compiled.push((*h, compiled.clone()));
                }
            }
            r.update_stack(&stack, target)?;
            split.children[i] = child;
        }
        Ok(todo.len())
    }

    /// The refinement of a frame of `s`: the wanted levels for its view; all of them
    /// reached now when `all`, else at most the refinement budget's steps of
    /// [`BRICKS_PER_STEP`] bricks.
    pub(super) fn refine_bricks(
        &mut self,
        s: &FrameSettings,
        all: bool,
    ) -> Result<(), RenderError> {
        if !self.lod.as_ref().is_some_and(|l| l.active) || self.split.is_none() {
            return Ok(());
        }
        let view = s.camera.view(s.width as f32 / s.height.max(1) as f32);
        let wanted = self.wanted_levels(&view, [s.width, s.height]);
        if wanted.is_empty() {
            return Ok(());
        }
        let most = if all {
            usize::MAX
        } else {
            self.refinement_budget.unwrap_or(1).max(1) as usize * BRICKS_PER_STEP
        };
        let rebuilt = self.rebuild_bricks(&wanted, most)?;
        let lod = self.lod.as_mut().expect("refinable");
        lod.wanted = wanted;
        // after the frame (a step budget): the next frame shows the rebuilt bricks
        lod.redraw = !all && rebuilt > 0;
        self.note_refinement();
        Ok(())
    }

    /// Whether bricks are still to be rebuilt for the last frame's view, or were
    /// rebuilt after it was drawn ([`Renderer::refining`]).
    pub(super) fn lod_refining(&self) -> bool {
        self.lod.as_ref().is_some_and(|l| l.redraw)
            || self.brick_refinement().is_some_and(|(done, n)| done < n)
    }

    /// Bricks at their wanted level for the last frame's view, and all bricks (`None`
    /// unless the bricks of a volume beyond the budget are refined in view).
    pub fn brick_refinement(&self) -> Option<(usize, usize)> {
        let lod = self.lod.as_ref().filter(|l| l.active)?;
        let split = self.split.as_ref()?;
        let done = split
            .children
            .iter()
            .zip(&lod.wanted)
            .filter(|(c, w)| c.info.level == **w)
            .count();
        Some((done, split.children.len()))
    }

    /// Updates the level notice with the bricks' levels.
    fn note_refinement(&mut self) {
        let active = self.lod.as_ref().is_some_and(|l| l.active);
        let levels = self.split.as_ref().filter(|_| active).map(|sp| {
            let full = sp.children.iter().filter(|c| c.info.level == 0).count();
            (full, sp.children.len())
        });
        let pending = self.brick_refinement().map_or(0, |(d, n)| n - d);
        if let Some(info) = self.level.as_mut() {
            info.refined = levels.map(|(full, n)| [full, n, pending]);
        }
    }
}
