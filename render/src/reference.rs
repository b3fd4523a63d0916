//! CPU reference renderer: the optical model of the GPU compute backend (`cs_main` in
//! `shaders/slice.wgsl`) evaluated in f64, plus a "converged" mode that refines the
//! slice spacing until the image stops changing (an approximation of the continuous
//! emission–absorption integral of the same transfer functions).
//!
//! # What is mirrored
//!
//! For pixel (x, y) of a W×H image, `uv = ((x + ½)/W, (y + ½)/H)`; the ray runs from
//! the unprojection of NDC `(2·uv.x − 1, 1 − 2·uv.y)` at depth 0 towards depth 1.
//! The camera's f32 [`View`](crate::camera::View) (view and projection matrices, eye,
//! forward) is converted to f64 and the view-projection is multiplied and inverted in
//! f64; the slice planes are those of [`SlicePlan`] (f32 `d0` and `Δs`, as uploaded
//! to the GPU, converted to f64), plane k at eye depth `d_k = d0 + k·Δs` along
//! `forward`. A ray meets plane k at `t = (d_k − (origin − eye)·forward) / (dir·forward)`;
//! the point is dropped when `t < 0` or it lies outside the volume box (faces
//! included). Each sample runs the hook chain of `evaluate()`:
//! clip (every twin; one `false` drops the sample) → value = trilinear scalar
//! ([`CpuContext::value`]) → every twin's `sample` → grey ramp `(v, v, v, v)` →
//! every twin's `classify` → `shade` → opacity correction
//! `α' = 1 − (1 − clamp(α, 0, 1))^(step/Δs0)` with `step = Δs / max(dir·forward, 10⁻⁶)`
//! → rgb clamped to `[0, 10⁶]`, premultiplied → every twin's `composite` → front-to-back
//! "under": `acc += (1 − acc.a)·c`.
//!
//! Early termination applies exactly when the GPU applies it: compute backend and
//! `early_termination = Some(threshold)`; the ray stops after the slice that makes
//! `acc.a ≥ threshold`. With [`ReferenceOptions::emulate_fp16`] the accumulator is
//! rounded to fp16 after every slice, like the compute backend writing an
//! rgba16float eye buffer (`round_like_target`): the f64 value is first rounded to
//! f32 (the GPU computes in f32) and then to the nearest fp16.
//!
//! Deliberate differences from the GPU, all in degenerate cases: a NaN opacity or
//! colour from a twin is clamped to 0 (GPU `clamp` is `min(max(x, lo), hi)`, which
//! maps NaN to the lower bound on common hardware), and a non-finite ray parameter
//! (a ray parallel to the slices) drops the sample instead of passing NaNs on.
//!
//! Plugins take part through their [`CpuTwin`]s. A plugin with per-slice state
//! ([`Plugin::slice_state`](crate::plugin::Plugin::slice_state)) depends on the
//! previous slice's image and is not supported here.

use std::ops::Range;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use glam::{DMat4, DVec2, DVec3, DVec4};
use rayon::prelude::*;

use crate::metrics::{RgbImageF, compare};
use crate::plugin::{CpuContext, CpuSample, CpuTwin, PluginInstance};
use crate::renderer::{Backend, FrameSettings};
use crate::slicing::{SliceError, SlicePlan, VolumeBox};
use crate::volume::Volume;

/// Largest image side the reference renderer accepts.
pub const MAX_SIDE: u32 = 16384;

/// Default tolerance of [`render_converged`]: RMS CIE ΔE*uv between two refinements.
pub const DEFAULT_TOLERANCE_DELTA_E: f64 = 0.1;

/// Coarsest spacing (voxels) at which [`render_converged`] starts.
pub const CONVERGED_START_SPACING: f32 = 0.5;

/// Finest spacing (voxels) [`render_converged`] refines to (unless it starts below
/// twice this, in which case it halves once).
pub const CONVERGED_MIN_SPACING: f64 = 1.0 / 64.0;

/// Largest colour component after clamping, as in `evaluate()`.
const RGB_MAX: f64 = 1.0e6;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    #[error("plugin '{0}' has no CPU twin, so the reference renderer cannot evaluate it")]
    NoTwin(String),
    #[error("plugin '{plugin}' is not supported by the reference renderer: {reason}")]
    Unsupported { plugin: String, reason: String },
    #[error("reference rendering was cancelled")]
    Cancelled,
    #[error(transparent)]
    Slices(#[from] SliceError),
    #[error("image size {0}x{1} is invalid (1..={MAX_SIDE} per side)")]
    BadSize(u32, u32),
    #[error("convergence tolerance must be a number >= 0, got {0}")]
    BadTolerance(f64),
}

/// Options of a reference render.
#[derive(Debug, Clone, Default)]
pub struct ReferenceOptions {
    /// Round the accumulator to fp16 after every slice (compare with an rgba16float
    /// GPU image). Off by default.
    pub emulate_fp16: bool,
    /// Incremented by one for every image row finished (in converged mode, the rows
    /// of every refinement pass add up).
    pub progress: Option<Arc<AtomicUsize>>,
    /// Checked before every row; when set, rendering stops with
    /// [`ReferenceError::Cancelled`].
    pub cancel: Option<Arc<AtomicBool>>,
}

impl ReferenceOptions {
    fn cancelled(&self) -> bool {
        self.cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
    }
}

/// A reference image: premultiplied RGBA in f64, row-major from the top.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f64; 4]>,
    /// Number of slice planes of the frame.
    pub slices: u32,
}

impl ReferenceImage {
    /// Pixel (x, y), y from the top.
    pub fn pixel(&self, x: u32, y: u32) -> [f64; 4] {
        self.pixels[y as usize * self.width as usize + x as usize]
    }
}

/// Result of [`render_converged`].
#[derive(Debug, Clone, PartialEq)]
pub struct Converged {
    /// The image at the finest spacing rendered.
    pub image: ReferenceImage,
    /// Slice spacing (voxels) of `image`.
    pub spacing: f64,
    /// RMS ΔE*uv between `image` and the image at twice its spacing (composited over
    /// the background); infinite when no refinement could be rendered.
    pub last_change_rms_delta_e: f64,
    /// Every refinement: (its spacing in voxels, RMS ΔE*uv against the previous image).
    /// The first entry is the first halving of the start spacing.
    pub steps: Vec<(f64, f64)>,
    /// Whether the last change is below the tolerance.
    pub converged: bool,
}

/// Renders the stack with the settings' camera, size and slice spacing.
///
/// Disabled instances are skipped; every enabled plugin needs a CPU twin
/// ([`ReferenceError::NoTwin`]) and must not have per-slice state
/// ([`ReferenceError::Unsupported`]). Rows are rendered in parallel; the cancel flag
/// is checked before every row.
pub fn render_reference(
    volume: &Volume,
    stack: &[PluginInstance],
    settings: &FrameSettings,
    opts: &ReferenceOptions,
) -> Result<ReferenceImage, ReferenceError> {
    check_size(settings)?;
    if opts.cancelled() {
        return Err(ReferenceError::Cancelled);
    }
    let prepared = Prepared::new(volume, stack)?;
    prepared.render(settings, settings.slice_spacing, opts)
}

/// Renders the stack with ever finer slice spacing until halving the spacing changes
/// the image, composited over `background` (linear RGB in [0,1]), by less than
/// `tolerance_delta_e` RMS ΔE*uv ([`DEFAULT_TOLERANCE_DELTA_E`] is the usual choice).
///
/// Starts at the smaller of the settings' spacing and [`CONVERGED_START_SPACING`] and
/// stops at [`CONVERGED_MIN_SPACING`] (or after one halving when the start is already
/// finer than twice that), or when the next spacing needs more slices than
/// [`crate::slicing::MAX_SLICES`]; then `converged` is false and the finest image is
/// returned with its last change. Early termination and fp16 emulation apply as in
/// [`render_reference`].
pub fn render_converged(
    volume: &Volume,
    stack: &[PluginInstance],
    settings: &FrameSettings,
    opts: &ReferenceOptions,
    tolerance_delta_e: f64,
    background: [f64; 3],
) -> Result<Converged, ReferenceError> {
    if tolerance_delta_e.is_nan() || tolerance_delta_e < 0.0 {
        return Err(ReferenceError::BadTolerance(tolerance_delta_e));
    }
    let requested = settings.slice_spacing;
    if !(requested.is_finite() && requested > 0.0) {
        return Err(SliceError::BadSpacing(requested).into());
    }
    check_size(settings)?;
    if opts.cancelled() {
        return Err(ReferenceError::Cancelled);
    }
    let prepared = Prepared::new(volume, stack)?;
    let start = requested.min(CONVERGED_START_SPACING);
    let finest = CONVERGED_MIN_SPACING.min(start as f64 / 2.0);
    let (w, h) = (settings.width, settings.height);
    let over = |img: &ReferenceImage| {
        RgbImageF::from_rgba_premultiplied_over(&img.pixels, w, h, background)
    };

    let mut image = prepared.render(settings, start, opts)?;
    let mut previous = over(&image);
    let mut spacing = start;
    let mut steps = Vec::new();
    let mut converged = false;
    loop {
        let next = spacing / 2.0;
        if (next as f64) < finest {
            break;
        }
        let finer = match prepared.render(settings, next, opts) {
            Err(ReferenceError::Slices(SliceError::TooMany { .. })) => break,
            other => other?,
        };
        let current = over(&finer);
        let change = compare(&previous, &current).rms_delta_e;
        steps.push((next as f64, change));
        image = finer;
        previous = current;
        spacing = next;
        if change < tolerance_delta_e {
            converged = true;
            break;
        }
    }
    Ok(Converged {
        image,
        spacing: spacing as f64,
        last_change_rms_delta_e: steps.last().map_or(f64::INFINITY, |s| s.1),
        steps,
        converged,
    })
}

fn check_size(settings: &FrameSettings) -> Result<(), ReferenceError> {
    let (w, h) = (settings.width, settings.height);
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(ReferenceError::BadSize(w, h));
    }
    Ok(())
}

/// The CPU twins of the enabled instances, in stack order.
fn twins_for(stack: &[PluginInstance]) -> Result<Vec<Box<dyn CpuTwin>>, ReferenceError> {
    stack
        .iter()
        .filter(|i| i.enabled)
        .map(|i| {
            let p = &i.plugin;
            if p.slice_state().is_some() {
                return Err(ReferenceError::Unsupported {
                    plugin: p.id().to_string(),
                    reason: "it has per-slice state, which needs a slice-by-slice reference"
                        .to_string(),
                });
            }
            p.cpu_twin(&i.params)
                .ok_or_else(|| ReferenceError::NoTwin(p.id().to_string()))
        })
        .collect()
}

/// What stays the same between the passes of one call: the volume, its normalised
/// scalars and the twins.
struct Prepared<'a> {
    volume: &'a Volume,
    scalars: Vec<f32>,
    twins: Vec<Box<dyn CpuTwin>>,
}

impl<'a> Prepared<'a> {
    fn new(volume: &'a Volume, stack: &[PluginInstance]) -> Result<Self, ReferenceError> {
        let twins = twins_for(stack)?;
        Ok(Self {
            volume,
            scalars: volume.normalized_scalars(),
            twins,
        })
    }

    fn render(
        &self,
        settings: &FrameSettings,
        spacing_voxels: f32,
        opts: &ReferenceOptions,
    ) -> Result<ReferenceImage, ReferenceError> {
        check_size(settings)?;
        let frame = Frame::new(self.volume, settings, spacing_voxels, opts.emulate_fp16)?;
        let ctx = CpuContext {
            volume: self.volume,
            scalars: &self.scalars,
        };
        let (w, h) = (settings.width, settings.height);
        let rows: Vec<Vec<[f64; 4]>> = (0..h)
            .into_par_iter()
            .map(|y| {
                if opts.cancelled() {
                    return Err(ReferenceError::Cancelled);
                }
                let row = (0..w)
                    .map(|x| frame.pixel(&ctx, &self.twins, x, y))
                    .collect();
                if let Some(p) = &opts.progress {
                    p.fetch_add(1, Ordering::Relaxed);
                }
                Ok(row)
            })
            .collect::<Result<_, _>>()?;
        Ok(ReferenceImage {
            width: w,
            height: h,
            pixels: rows.into_iter().flatten().collect(),
            slices: frame.count,
        })
    }
}

/// The frame uniform of `write_frame`, in f64.
struct Frame {
    inv_view_proj: DMat4,
    eye: DVec3,
    forward: DVec3,
    box_min: DVec3,
    box_max: DVec3,
    /// Δs0: world length of one voxel.
    voxel: f64,
    /// Δs: world distance between slice planes.
    spacing: f64,
    d0: f64,
    count: u32,
    width: u32,
    height: u32,
    early: Option<f64>,
    fp16: bool,
}

impl Frame {
    fn new(
        volume: &Volume,
        settings: &FrameSettings,
        spacing_voxels: f32,
        fp16: bool,
    ) -> Result<Self, ReferenceError> {
        let (w, h) = (settings.width, settings.height);
        let view = settings.camera.view(w as f32 / h as f32);
        let vbox = VolumeBox::new(volume.dims, volume.spacing);
        let plan = SlicePlan::new(&view, &vbox, spacing_voxels)?;
        let view_proj: DMat4 = view.proj.as_dmat4() * view.view.as_dmat4();
        let early = match (settings.backend, settings.early_termination) {
            (Backend::Compute, Some(t)) => Some(t as f64),
            _ => None,
        };
        Ok(Self {
            inv_view_proj: view_proj.inverse(),
            eye: view.eye.as_dvec3(),
            forward: view.forward.as_dvec3(),
            box_min: vbox.min.as_dvec3(),
            box_max: vbox.max.as_dvec3(),
            voxel: vbox.voxel as f64,
            spacing: plan.spacing as f64,
            d0: plan.d0 as f64,
            count: plan.count,
            width: w,
            height: h,
            early,
            fp16,
        })
    }

    /// `pixel_ray`: origin on the near plane and unit direction.
    fn ray(&self, uv: DVec2) -> (DVec3, DVec3) {
        let ndc = DVec2::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
        let near = self.inv_view_proj * DVec4::new(ndc.x, ndc.y, 0.0, 1.0);
        let far = self.inv_view_proj * DVec4::new(ndc.x, ndc.y, 1.0, 1.0);
        let origin = near.truncate() / near.w;
        let dir = (far.truncate() / far.w - origin).normalize();
        (origin, dir)
    }

    fn inside(&self, p: DVec3) -> bool {
        // written so that NaN counts as outside
        p.cmpge(self.box_min).all() && p.cmple(self.box_max).all()
    }

    /// Slices that may hit the box along the ray: the box's slab interval mapped to
    /// slice indices, widened by two slices against rounding (every slice in the range
    /// is still tested exactly). All slices when the interval is not well defined.
    fn slice_range(&self, origin: DVec3, dir: DVec3, depth0: f64, dd: f64) -> Range<u32> {
        let all = 0..self.count;
        let inv = dir.recip();
        let ta = (self.box_min - origin) * inv;
        let tb = (self.box_max - origin) * inv;
        let t_in = ta.min(tb).max_element();
        let t_out = ta.max(tb).min_element();
        if !(t_in.is_finite() && t_out.is_finite() && dd.abs() > 1.0e-12) {
            return all;
        }
        let span = t_out - t_in;
        if span < -1.0e-9 * (t_in.abs() + t_out.abs() + 1.0) {
            return 0..0;
        }
        let to_k = |t: f64| (depth0 + t * dd - self.d0) / self.spacing;
        let (ka, kb) = (to_k(t_in), to_k(t_out));
        let lo = (ka.min(kb).floor() - 2.0).max(0.0);
        let hi = (ka.max(kb).ceil() + 3.0).min(self.count as f64);
        if !(lo.is_finite() && hi.is_finite()) {
            return all;
        }
        if hi <= lo {
            return 0..0;
        }
        lo as u32..hi as u32
    }

    /// `cs_main` for one pixel: premultiplied RGBA.
    fn pixel(&self, ctx: &CpuContext, twins: &[Box<dyn CpuTwin>], x: u32, y: u32) -> [f64; 4] {
        let uv = DVec2::new(
            (x as f64 + 0.5) / self.width as f64,
            (y as f64 + 0.5) / self.height as f64,
        );
        let (origin, dir) = self.ray(uv);
        let dd = dir.dot(self.forward);
        let depth0 = (origin - self.eye).dot(self.forward);
        let step = self.spacing / dd.max(1.0e-6);
        let ratio = step / self.voxel;
        let extent = self.box_max - self.box_min;
        let mut acc = DVec4::ZERO;
        for k in self.slice_range(origin, dir, depth0, dd) {
            let d = self.d0 + k as f64 * self.spacing;
            let t = (d - depth0) / dd;
            let pos = origin + dir * t;
            if !(t >= 0.0 && t.is_finite()) || !self.inside(pos) {
                continue;
            }
            let sample = CpuSample {
                pos,
                tex: (pos - self.box_min) / extent,
                ray_dir: dir,
                uv,
                value: 0.0,
                step,
                color: DVec4::ZERO,
                normal: DVec3::ZERO,
                slice: k,
            };
            let c = evaluate(ctx, twins, sample, ratio);
            acc += (1.0 - acc.w) * c;
            if self.fp16 {
                acc = round_f16(acc);
            }
            if self.early.is_some_and(|threshold| acc.w >= threshold) {
                break;
            }
        }
        acc.to_array()
    }
}

/// `clamp(x, lo, hi)` that maps NaN to `lo`.
fn clamp_nan_low(x: f64, lo: f64, hi: f64) -> f64 {
    if x.is_nan() { lo } else { x.clamp(lo, hi) }
}

/// `correct_opacity`: α' = 1 − (1 − α)^(Δs/Δs0), exact at α = 0 and α = 1.
fn correct_opacity(alpha: f64, ratio: f64) -> f64 {
    let a = clamp_nan_low(alpha, 0.0, 1.0);
    if a >= 1.0 {
        return 1.0;
    }
    1.0 - (1.0 - a).powf(ratio)
}

/// `evaluate()`: the premultiplied, opacity-corrected contribution of one sample.
fn evaluate(
    ctx: &CpuContext,
    twins: &[Box<dyn CpuTwin>],
    sample: CpuSample,
    ratio: f64,
) -> DVec4 {
    if !twins.iter().all(|t| t.clip(&sample)) {
        return DVec4::ZERO;
    }
    let mut s = sample;
    s.value = ctx.value(s.tex);
    for t in twins {
        t.sample(ctx, &mut s);
    }
    s.color = DVec4::splat(s.value);
    for t in twins {
        t.classify(&mut s);
    }
    for t in twins {
        t.shade(ctx, &mut s);
    }
    let a = correct_opacity(s.color.w, ratio);
    let rgb = DVec3::new(
        clamp_nan_low(s.color.x, 0.0, RGB_MAX),
        clamp_nan_low(s.color.y, 0.0, RGB_MAX),
        clamp_nan_low(s.color.z, 0.0, RGB_MAX),
    );
    let mut c = (rgb * a).extend(a);
    for t in twins {
        t.composite(&s, &mut c);
    }
    c
}

/// `round_like_target` for an rgba16float eye buffer (via f32, where the GPU computes).
fn round_f16(v: DVec4) -> DVec4 {
    let r = |x: f64| half::f16::from_f32(x as f32).to_f64();
    DVec4::new(r(v.x), r(v.y), r(v.z), r(v.w))
}

#[cfg(test)]
mod tests {
//TESTS
}
