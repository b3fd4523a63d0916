//! The tiles that a frame's per-slice dispatches cover ([`Renderer::set_slice_exit`]).
//!
//! On the compute backend, a stack with per-slice state (`shade.dos`) runs one dispatch
//! per slice, over every pixel: its sample, and every state texel's update. Most of
//! those do nothing that reaches the image. The renderer lists, per slice, the tiles of
//! [`STATE_TILE`] × [`STATE_TILE`] pixels (the fused entry point's workgroups) where
//! something that matters can change, and dispatches those only. On llvmpipe a
//! workgroup whose invocations all return at once still runs its code under a mask, so
//! leaving tiles out of the dispatch is what saves the time.
//!
//! The tiles follow three regions per slice k, each bounded per tile by a lower bound
//! of its distance to the region, in pixels (0: the tile may meet it):
//!
//! - V_k, where a sample of slice k can be visible: the slice's polygon in the visible
//!   box, cut to the occupied bricks' hull, on the screen, rasterised per row of tiles
//!   with a margin. Elsewhere the sample is transparent (empty-space skipping's promise).
//! - F_k, where the state after slice k can differ from its clear value: V_k joined
//!   with F_{k−1} widened by the updates' reach R_k (the plugins'
//!   [`crate::plugin::Plugin::slice_state_reach`] times the slice spacing, mapped to
//!   pixels at the slice's depth as `state_uv_per_world` in shaders/common.wgsl, plus
//!   the bilinear footprint). Outside it both state textures still hold clear (slice 0
//!   writes every texel), and an update there would write clear again.
//! - D_k, where the state after slice k is read by anything that reaches the image:
//!   the shading of slice k + 1's visible samples, and the updates of D_{k+1}, i.e.
//!   V_{k+1} joined with D_{k+1} widened by R_{k+1}; empty after the last slice.
//!   Outside it the state may keep a stale value: no later visible sample reads one
//!   (the last frame's state, [`Renderer::read_state`], holds such values there).
//!
//! Slice k's tiles are those of V_k joined with those of F_k ∩ D_k; slice 0 covers the
//! whole eye buffer (it starts the accumulation and the state). The fused entry point
//! runs the tiles of V_k; the others need only the state updates, of a transparent
//! sample, and run in a second dispatch (`cs_slice_state_only`) that updates from the
//! pixel's placeholder sample without evaluating it ([`Plugin::slice_state_reach`]'s
//! promise). Updates in dispatches of their own (the raster backend's, and the
//! compute backend's without the fused entry point) split the same way where every
//! state has the eye buffer's size: the update entry points, which evaluate the
//! texel's sample, over V_k's tiles, and `cs_slice_state_only` over the others; else
//! they run both lists. Where every state has one size smaller than the eye buffer's
//! (`shade.dos`'s `buffer_scale` 0.5 or 0.25), or lies across the light (half-angle
//! slicing: `light: directional`), the three regions are taken on the state's grid of
//! tiles for its updates (a state texel's sample is the pixel's at the same point of the
//! screen, or the one on the light's ray through the texel, the slice's polygon then
//! projected along the light as the shader's `state_coord` does; the margins, R_k and
//! the bilinear footprint are in its texels) and the slice's own dispatch (`cs_slice`)
//! covers V_k's tiles of the eye buffer. The image is the same bit for bit.

use glam::{DVec2, Mat4};

use super::{
    FrameUniform, Occupied, Renderer, SLICE_INFO_STRIDE, STATE_TILE, SlicePlan, VolumeBox,
};
use crate::plugin::Plugin;
use std::sync::Arc;

/// Width of a row of workgroups of a listed dispatch: a per-slice entry point reads its
/// tile at `slice_info.tile_offset + wg.y · row + wg.x` (`slice_info.tile_row`).
pub(super) const LIST_ROW: u32 = 4096;

/// Pixels of margin around every bound, for rounding.
const MARGIN: f64 = 2.0;

/// The tiles a frame's per-slice dispatches cover.
pub(super) struct SliceExit {
    /// Three [`SLICE_INFO_STRIDE`] chunks per slice k, each with the slice's index and,
    /// from slice 1 on, an offset and count in `list` and [`LIST_ROW`]: chunk k lists
    /// the tiles where a sample can be visible (the fused dispatch), chunk `n` + k the
    /// others (the state-only dispatch), chunk 2`n` + k both (updates in dispatches of
    /// their own). `n` is at least the renderer's shared slice info's length (volume
    /// passes index that by step).
    pub info: wgpu::Buffer,
    /// Every slice's tiles, `x | y << 16`: its visible ones, then its others.
    pub list: wgpu::Buffer,
    /// Chunks per part of `info`.
    n: u32,
    /// Per slice, the number of its tiles of its slice dispatch (on the eye buffer's
    /// grid), of its state-only dispatch, and of its updates (on [`SliceExit::size`]).
    counts: Vec<[u32; 3]>,
    /// The grid the updates' tiles are of, in texels: the eye buffer's, or that of every
    /// per-slice state where all have one size and it is smaller or lies across the
    /// light ([`SliceExit::eye_space`] false).
    pub size: [u32; 2],
    /// Whether a state texel is the eye buffer's pixel (the fused and state-only entry
    /// points' lists); false for a smaller buffer or under half-angle slicing.
    pub eye_space: bool,
    /// The share of the (slice, tile) pairs left out.
    pub idle: f64,
}

/// Workgroups of a listed dispatch of `n` tiles.
fn listed(n: u32) -> (u32, u32) {
    (n.min(LIST_ROW), n.div_ceil(LIST_ROW))
}

impl SliceExit {
    /// The workgroups of slice `k`'s dispatch, fused or `cs_slice` (its tiles of the eye
    /// buffer where a sample can be visible; `info` chunk k), `None` where the eye
    /// buffer's (slice 0).
    pub fn workgroups(&self, k: u32) -> Option<(u32, u32)> {
        let [v, _, _] = *self.counts.get(k as usize).filter(|_| k > 0)?;
        Some(listed(v))
    }

    /// The dynamic offset and workgroups of slice `k`'s state-only dispatch (its other
    /// tiles; `info` chunk `n` + k), `None` where it has none.
    pub fn state_only(&self, k: u32) -> Option<(u32, (u32, u32))> {
        let [_, o, _] = *self.counts.get(k as usize).filter(|_| k > 0)?;
        (o > 0).then(|| ((self.n + k) * SLICE_INFO_STRIDE as u32, listed(o)))
    }

    /// Slice `k`'s state-only dispatch of `pipeline` (`cs_slice_state_only`) over its
    /// tiles where no sample can be visible, with `g0` at their chunk; none where it has
    /// no such tiles.
    pub fn encode_state_only(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        pipeline: &wgpu::ComputePipeline,
        g0: &wgpu::BindGroup,
        k: u32,
    ) {
        if let Some((offset, m)) = self.state_only(k) {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, g0, &[offset]);
            pass.dispatch_workgroups(m.0, m.1, 1);
        }
    }

    /// The dynamic offset of slice `k`'s updates in dispatches of their own that cover
    /// all its tiles on the grid of [`SliceExit::size`] (`info` chunk 2`n` + k), and
    /// their workgroups for a state of that size, `None` where the whole grid's (slice
    /// 0).
    pub fn updates(&self, k: u32) -> (u32, Option<(u32, u32)>) {
        let offset = (2 * self.n + k) * SLICE_INFO_STRIDE as u32;
        let n = self
            .counts
            .get(k as usize)
            .filter(|_| k > 0)
            .map(|&[_, _, u]| listed(u));
        (offset, n)
    }
}

/// A grid of tiles over the eye buffer.
#[derive(Clone, Copy)]
struct Grid {
    w: usize,
    h: usize,
}

impl Grid {
    fn of(size: [u32; 2]) -> Self {
        Self {
            w: size[0].div_ceil(STATE_TILE) as usize,
            h: size[1].div_ceil(STATE_TILE) as usize,
        }
    }

    fn len(&self) -> usize {
        self.w * self.h
    }
}

/// The tiles that a convex polygon (`poly`, pixels; `None`: it reaches every pixel)
/// can touch, widened by [`MARGIN`]: per row of tiles, the x extent of the polygon's
/// part within the row's band.
fn polygon_tiles(poly: Option<&[DVec2]>, grid: Grid) -> Vec<bool> {
    let mut mask = vec![false; grid.len()];
    let Some(poly) = poly else {
        mask.fill(true);
        return mask;
    };
    if poly.len() < 3 {
        return mask;
    }
    let t = STATE_TILE as f64;
    for row in 0..grid.h {
        let band = [row as f64 * t - MARGIN, (row + 1) as f64 * t + MARGIN];
        let part = clip_band(poly, band);
        let (lo, hi) = part
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.x), hi.max(p.x))
            });
        // an empty part (both still infinite)
        if lo > hi {
            continue;
        }
        let x0 = ((lo - MARGIN) / t).floor().clamp(0.0, grid.w as f64) as usize;
        let x1 = ((hi + MARGIN) / t).ceil().clamp(0.0, grid.w as f64) as usize;
        mask[row * grid.w + x0..row * grid.w + x1.max(x0)].fill(true);
    }
    mask
}

/// The part of a convex polygon with `band[0] ≤ y ≤ band[1]` (Sutherland–Hodgman).
fn clip_band(poly: &[DVec2], band: [f64; 2]) -> Vec<DVec2> {
    let mut out = poly.to_vec();
    for (sign, bound) in [(1.0, band[0]), (-1.0, -band[1])] {
        // keep sign · y ≥ bound
        let inside = |p: DVec2| sign * p.y - bound;
        let src = std::mem::take(&mut out);
        for (i, &a) in src.iter().enumerate() {
            let b = src[(i + 1) % src.len()];
            let (da, db) = (inside(a), inside(b));
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                out.push(a + (b - a) * (da / (da - db)));
            }
        }
        if out.is_empty() {
            break;
        }
    }
    out
}

/// Per tile, a lower bound of the distance in pixels from its pixels to the tiles of
/// `mask` (0 on them, infinite without any): the chessboard distance transform in tiles
/// (two passes), less one, times the tile's side.
fn distance_lower_bound(mask: &[bool], grid: Grid) -> Vec<f32> {
    const FAR: u32 = u32::MAX / 2;
    let (w, h) = (grid.w, grid.h);
    let mut d: Vec<u32> = mask.iter().map(|&m| if m { 0 } else { FAR }).collect();
    for y in 0..h {
        for x in 0..w {
            let mut v = d[y * w + x];
            if x > 0 {
                v = v.min(d[y * w + x - 1] + 1);
            }
            if y > 0 {
                v = v.min(d[(y - 1) * w + x] + 1);
                if x > 0 {
                    v = v.min(d[(y - 1) * w + x - 1] + 1);
                }
                if x + 1 < w {
                    v = v.min(d[(y - 1) * w + x + 1] + 1);
                }
            }
            d[y * w + x] = v;
        }
    }
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            let mut v = d[y * w + x];
            if x + 1 < w {
                v = v.min(d[y * w + x + 1] + 1);
            }
            if y + 1 < h {
                v = v.min(d[(y + 1) * w + x] + 1);
                if x + 1 < w {
                    v = v.min(d[(y + 1) * w + x + 1] + 1);
                }
                if x > 0 {
                    v = v.min(d[(y + 1) * w + x - 1] + 1);
                }
            }
            d[y * w + x] = v;
        }
    }
    let t = STATE_TILE as f32;
    d.into_iter()
        .map(|c| match c {
            FAR.. => f32::INFINITY,
            0 => 0.0,
            c => (c - 1) as f32 * t,
        })
        .collect()
}

/// `polygon` (world, on one plane) on the screen of `vp` in a `size` frame, in pixels;
/// `None` where a vertex lies behind the eye (then it may reach any pixel).
fn on_screen(polygon: &[glam::Vec3], vp: Mat4, size: [u32; 2]) -> Option<Vec<DVec2>> {
    polygon
        .iter()
        .map(|p| crate::slicing::pixel_of(*p, vp, size))
        .collect()
}

/// A reach of `px` texels per slice with the bilinear reads' footprint: the reads reach
/// texels within one of a tap along each axis; a part in 10⁴ and a thousandth of a
/// texel cover the shader's f32 rounding (not more: the growth adds up over hundreds of
/// slices).
fn with_footprint(px: f64) -> f32 {
    let r = px * (1.0 + 1.0e-4) + std::f64::consts::SQRT_2 + 1.0e-3;
    if r.is_finite() {
        r as f32
    } else {
        f32::INFINITY
    }
}

/// R_k of a view-aligned frame (frame uniform `u`, `n` slices) in a `size` grid over
/// the screen: the updates' `reach` at slice k in texels of that grid, at the slice's
/// depth, with the footprint ([`with_footprint`]).
fn screen_grow(u: &FrameUniform, size: [u32; 2], reach: f64, n: usize) -> Vec<f32> {
    let dims = [size[0] as f64, size[1] as f64];
    let basis = [0, 1].map(|c| {
        glam::Vec3::from_slice(&u.ray_basis[4 * c..4 * c + 3])
            .as_dvec3()
            .length()
    });
    let perspective = u.eye[3] > 0.5;
    (0..n)
        .map(|k| {
            let depth = if perspective {
                (u.box_max[3] as f64 + k as f64 * u.forward[3] as f64).max(1.0e-9)
            } else {
                1.0
            };
            let px = (0..2)
                .map(|i| reach * u.forward[3] as f64 * 0.5 / (basis[i] * depth) * dims[i])
                .fold(0.0, f64::max);
            with_footprint(px)
        })
        .collect()
}

/// A half-angle frame's state grid (`size` texels across the light, `h`): where a
/// world point lies in it, as the shader's `state_coord` maps it, in texels.
fn light_texel(h: &crate::slicing::HalfAngle, size: [u32; 2], p: glam::Vec3) -> DVec2 {
    let col = |i: usize| h.state_rays.col(i).truncate().as_dvec3();
    let (a, b, q) = (col(0), col(1), p.as_dvec3() - col(3));
    let ndc = DVec2::new(q.dot(a) / a.dot(a), q.dot(b) / b.dot(b));
    DVec2::new(
        (ndc.x * 0.5 + 0.5) * size[0] as f64,
        (0.5 - ndc.y * 0.5) * size[1] as f64,
    )
}

/// R_k of a half-angle frame (`h`) in its `size` state grid: the cone's `reach` over the
/// light's step, in texels (the same at every slice), with the footprint.
fn light_grow(h: &crate::slicing::HalfAngle, size: [u32; 2], reach: f64, n: usize) -> Vec<f32> {
    let px = (0..2)
        .map(|i| {
            let axis = h.state_rays.col(i).truncate().as_dvec3().length();
            reach * h.light_step as f64 * 0.5 / axis * size[i] as f64
        })
        .fold(0.0, f64::max);
    vec![with_footprint(px); n]
}

/// A tile of `grid` by its row-major index, `x | y << 16`.
fn tile_word(i: usize, grid: Grid) -> u32 {
    (i % grid.w) as u32 | ((i / grid.w) as u32) << 16
}

/// Per slice of `plan`, the tiles of V_k in a `size` grid, as a mask: `project` maps a
/// slice's polygon (world) into the grid's texels (`None`: it may reach any);
/// `visible`: the box whose samples can be visible (`None`: nothing can be); `hull`: the
/// occupied bricks' hull.
fn seen_tiles(
    plan: &SlicePlan,
    visible: Option<&VolumeBox>,
    hull: Option<&crate::slicing::Dop>,
    project: &dyn Fn(&[glam::Vec3]) -> Option<Vec<DVec2>>,
    size: [u32; 2],
) -> Vec<Vec<bool>> {
    let grid = Grid::of(size);
    (0..plan.count)
        .map(|k| match visible {
            Some(b) => {
                let poly = plan.polygon(b, k);
                let poly = match hull {
                    Some(h) => h.clip(poly),
                    None => poly,
                };
                polygon_tiles(project(&poly).as_deref(), grid)
            }
            None => vec![false; grid.len()],
        })
        .collect()
}

/// Per slice of a frame with per-slice state (`plan`), its tiles in a `size` grid
/// (`x | y << 16`, row by row) as the module's documentation defines them: those of
/// V_k, and the others; slice 0's lists are empty (it covers the grid). `grow`: R_k per
/// slice, in texels; the others as [`seen_tiles`] takes them.
pub(super) fn slice_tiles(
    plan: &SlicePlan,
    visible: Option<&VolumeBox>,
    hull: Option<&crate::slicing::Dop>,
    project: &dyn Fn(&[glam::Vec3]) -> Option<Vec<DVec2>>,
    size: [u32; 2],
    grow: &[f32],
) -> Vec<[Vec<u32>; 2]> {
    let grid = Grid::of(size);
    let n = plan.count as usize;
    // V_k, and the distances to it
    let seen = seen_tiles(plan, visible, hull, project, size);
    let near: Vec<Vec<f32>> = seen.iter().map(|m| distance_lower_bound(m, grid)).collect();
    // D_k, from the back: whether each tile may meet it
    let mut read = vec![vec![false; grid.len()]; n];
    let mut d = vec![f32::INFINITY; grid.len()];
    for k in (0..n.saturating_sub(1)).rev() {
        for (i, v) in d.iter_mut().enumerate() {
            *v = near[k + 1][i].min((*v - grow[k + 1]).max(0.0));
            read[k][i] = *v <= 0.0;
        }
    }
    // F_k, from the front, and the tiles
    let mut f = vec![f32::INFINITY; grid.len()];
    (0..n)
        .map(|k| {
            let [mut visible, mut other] = [Vec::new(), Vec::new()];
            for (i, v) in f.iter_mut().enumerate() {
                *v = near[k][i].min((*v - grow[k]).max(0.0));
                let tile = tile_word(i, grid);
                if k == 0 {
                    continue;
                }
                if seen[k][i] {
                    visible.push(tile);
                } else if *v <= 0.0 && read[k][i] {
                    other.push(tile);
                }
            }
            [visible, other]
        })
        .collect()
}

/// The size every per-slice state of `scales` (each
/// [`crate::plugin::SliceStateDecl::scale`]) has in a `size` eye buffer, `None` where
/// they differ.
fn common_size(scales: &[f32], size: [u32; 2]) -> Option<[u32; 2]> {
    let sizes: Vec<[u32; 2]> = scales
        .iter()
        .map(|&s| super::state_extent(size, s))
        .collect();
    let first = *sizes.first()?;
    sizes.iter().all(|&s| s == first).then_some(first)
}

impl Renderer {
    /// The tiles of a frame of `stack` that its per-slice dispatches cover
    /// ([`Renderer::set_slice_exit`], [`slice_tiles`]), with group 0's buffers for
    /// them. `None` where the exit is off, a plugin of `stack` with per-slice state
    /// states no reach, or, under half-angle slicing, the states differ in size. The
    /// updates' tiles are on the states' own grid where it is not the eye buffer's
    /// ([`SliceExit::eye_space`]): a smaller buffer's, the texel's sample being the
    /// pixel's at the same screen point, or under half-angle slicing the buffer across
    /// the light, the texel's sample on the light's ray through it.
    pub(super) fn slice_exit_info(
        &self,
        stack: &[(u64, Arc<dyn Plugin>)],
        plan: &crate::slicing::FramePlan,
        view: &crate::camera::View,
        u: &FrameUniform,
        size: [u32; 2],
        occupied: Option<Occupied>,
    ) -> Option<SliceExit> {
        if !self.slice_exit {
            return None;
        }
        let mut reach = 0.0_f64;
        let mut scales = Vec::new();
        for (uid, plugin) in stack {
            if let Some(decl) = plugin.slice_state() {
                let r = plugin.slice_state_reach(&self.instances.get(uid)?.params)?;
                reach = reach.max(r);
                scales.push(decl.scale);
            }
        }
        // The updates' tiles are those of the states' own grid where every state has
        // one size and it is not the eye buffer's pixels: a smaller buffer, or any
        // buffer under half-angle slicing (it lies across the light).
        let half = plan.half.as_ref();
        let grid = match (half, common_size(&scales, size)) {
            (_, Some(common)) => common,
            (None, None) => size,
            (Some(_), None) => return None,
        };
        let own = half.is_some() || grid != size;
        let visible = self.visible_box_in(occupied.map(|o| o.bytes));
        let visible = visible.as_ref();
        let hull = occupied.and_then(|o| o.hull.map(|(h, _)| h));
        let slices = &plan.slices;
        let n = slices.count as usize;
        let vp = view.view_proj();
        let screen = |grid: [u32; 2]| move |poly: &[glam::Vec3]| on_screen(poly, vp, grid);
        // the eye buffer's; where the updates have their own grid, only V_k (the
        // slices' own dispatch)
        let lists = if own {
            let eye = Grid::of(size);
            seen_tiles(slices, visible, hull, &screen(size), size)
                .iter()
                .map(|mask| {
                    let tiles = (0..eye.len()).filter(|&i| mask[i]);
                    [tiles.map(|i| tile_word(i, eye)).collect(), Vec::new()]
                })
                .collect()
        } else {
            let grow = screen_grow(u, size, reach, n);
            slice_tiles(slices, visible, hull, &screen(size), size, &grow)
        };
        let state_lists = own.then(|| match half {
            Some(h) => {
                let light = |poly: &[glam::Vec3]| {
                    Some(poly.iter().map(|&p| light_texel(h, grid, p)).collect())
                };
                let grow = light_grow(h, grid, reach, n);
                slice_tiles(slices, visible, hull, &light, grid, &grow)
            }
            None => {
                let grow = screen_grow(u, grid, reach, n);
                slice_tiles(slices, visible, hull, &screen(grid), grid, &grow)
            }
        });
        let all = Grid::of(grid).len() as u32;
        let [eye, packed] = [size, grid].map(|s| s[0] | s[1] << 16);
        // as long as the shared slice info (volume passes index it by step)
        let n = lists.len().max(self.slice_info_slices as usize).max(1);
        let stride = SLICE_INFO_STRIDE as usize;
        let mut info = vec![0u8; 3 * n * stride];
        let mut flat: Vec<u32> = Vec::new();
        let mut counts = Vec::with_capacity(lists.len());
        let mut put = |chunk: usize, words: [u32; 5]| {
            info[chunk * stride..chunk * stride + 20].copy_from_slice(bytemuck::cast_slice(&words));
        };
        for k in 0..n {
            let index = k as u32;
            let mut words = [[index, 0, 0, 0, 0]; 3];
            match (lists.get(k), &state_lists) {
                (Some([visible, other]), None) if k > 0 => {
                    let (v, o, at) = (visible.len() as u32, other.len() as u32, flat.len() as u32);
                    words = [
                        [index, at, v, LIST_ROW, eye],
                        [index, at + v, o, LIST_ROW, eye],
                        [index, at, v + o, LIST_ROW, eye],
                    ];
                    flat.extend_from_slice(visible);
                    flat.extend_from_slice(other);
                    counts.push([v, o, v + o]);
                }
                // the slice's dispatch over its eye tiles where a sample can be visible,
                // the updates over the state's tiles (no state-only dispatch: that
                // entry point works in pixels)
                (Some([visible, _]), Some(state)) if k > 0 => {
                    let [sv, so] = &state[k];
                    let (v, at) = (visible.len() as u32, flat.len() as u32);
                    let updates = (sv.len() + so.len()) as u32;
                    words[0] = [index, at, v, LIST_ROW, eye];
                    words[2] = [index, at + v, updates, LIST_ROW, packed];
                    flat.extend_from_slice(visible);
                    flat.extend_from_slice(sv);
                    flat.extend_from_slice(so);
                    counts.push([v, 0, updates]);
                }
                (Some(_), _) => counts.push([Grid::of(size).len() as u32, 0, all]),
                (None, _) => {}
            }
            for (part, w) in words.into_iter().enumerate() {
                put(part * n + k, w);
            }
        }
        let idle = counts
            .iter()
            .map(|&[_, _, updates]| (all - updates) as f64)
            .sum::<f64>()
            / (all as f64 * counts.len().max(1) as f64);
        if flat.is_empty() {
            flat.push(0);
        }
        let device = &self.gpu.device;
        use wgpu::util::DeviceExt;
        let info = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vwb slice info (listed tiles)"),
            contents: &info,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let list = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vwb slice tiles"),
            contents: bytemuck::cast_slice(&flat),
            usage: wgpu::BufferUsages::STORAGE,
        });
        Some(SliceExit {
            info,
            list,
            n: n as u32,
            counts,
            size: grid,
            eye_space: !own,
            idle,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygon_tiles_cover_the_polygon_per_row() {
        let grid = Grid { w: 8, h: 8 };
        // a triangle with its tip up
        let poly = [
            DVec2::new(4.0, 60.0),
            DVec2::new(60.0, 60.0),
            DVec2::new(32.0, 4.0),
        ];
        let m = polygon_tiles(Some(&poly), grid);
        // every pixel centre inside the triangle lies in a listed tile
        let inside = |p: DVec2| {
            (0..3).all(|i| {
                let (a, b) = (poly[i], poly[(i + 1) % 3]);
                (b - a).perp_dot(p - a) >= 0.0
            }) || (0..3).all(|i| {
                let (a, b) = (poly[i], poly[(i + 1) % 3]);
                (b - a).perp_dot(p - a) <= 0.0
            })
        };
        for y in 0..64 {
            for x in 0..64 {
                let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                if inside(p) {
                    assert!(m[(y / 8) * 8 + x / 8], "pixel ({x}, {y})");
                }
            }
        }
        // the tip's row is narrower than the base's, and the corners are left out
        let row = |r: usize| m[r * 8..r * 8 + 8].iter().filter(|&&v| v).count();
        assert!(row(0) < row(7), "{} {}", row(0), row(7));
        assert!(!m[0] && !m[7]);
        assert!(polygon_tiles(None, grid).iter().all(|&v| v));
        assert!(!polygon_tiles(Some(&poly[..2]), grid).iter().any(|&v| v));
    }

    #[test]
    fn distance_bounds_are_below_the_true_distances() {
        let grid = Grid { w: 9, h: 7 };
        let mut mask = vec![false; grid.len()];
        mask[3 * 9 + 2] = true;
        mask[9 + 7] = true;
        let d = distance_lower_bound(&mask, grid);
        let t = STATE_TILE as f64;
        for (i, &v) in d.iter().enumerate() {
            let (x, y) = ((i % 9) as f64, (i / 9) as f64);
            // the true distance between the tiles' squares
            let truth = mask
                .iter()
                .enumerate()
                .filter(|(_, m)| **m)
                .map(|(j, _)| {
                    let (sx, sy) = ((j % 9) as f64, (j / 9) as f64);
                    let gap = |a: f64, b: f64| ((a - b).abs() - 1.0).max(0.0) * t;
                    gap(x, sx).hypot(gap(y, sy))
                })
                .fold(f64::INFINITY, f64::min);
            assert!(v as f64 <= truth, "tile {i}: {v} > {truth}");
            assert_eq!(v == 0.0, truth == 0.0, "tile {i}");
        }
        assert!(
            distance_lower_bound(&vec![false; grid.len()], grid)
                .iter()
                .all(|v| v.is_infinite())
        );
    }

    #[test]
    fn a_band_clip_keeps_the_part_between_its_lines() {
        let square = [
            DVec2::new(0.0, 0.0),
            DVec2::new(10.0, 0.0),
            DVec2::new(10.0, 10.0),
            DVec2::new(0.0, 10.0),
        ];
        let part = clip_band(&square, [2.0, 5.0]);
        assert!(part.iter().all(|p| (2.0..=5.0).contains(&p.y)));
        let xs: Vec<f64> = part.iter().map(|p| p.x).collect();
        assert_eq!(xs.iter().cloned().fold(f64::INFINITY, f64::min), 0.0);
        assert_eq!(xs.iter().cloned().fold(f64::NEG_INFINITY, f64::max), 10.0);
        assert!(clip_band(&square, [11.0, 12.0]).is_empty());
    }
}
