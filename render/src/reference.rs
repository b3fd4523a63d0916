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
//! f64; the slice planes are those of [`SlicePlan`](crate::slicing::SlicePlan) (f32
//! `d0` and `Δs`, as uploaded to the GPU, converted to f64), plane k at eye depth
//! `d_k = d0 + k·Δs` along `forward`. A ray meets plane k at `t = (d_k − (origin − eye)·forward) / (dir·forward)`;
//! the point is dropped when `t < 0` or it lies outside the volume box (faces
//! included). Each sample runs the hook chain of `evaluate()`:
//! clip (every twin; one `false` drops the sample) → value = trilinear scalar
//! ([`CpuContext::value`]) → every twin's `sample` → grey ramp `(v, v, v, v)` →
//! every twin's `classify` → `shade` → opacity correction
//! `α' = 1 − (1 − clamp(α, 0, 1))^(step/Δs0)` with `step = Δs / max(dir·forward, 10⁻⁶)`
//! → rgb clamped to `[0, 10⁶]`, premultiplied → every twin's `composite` → front-to-back
//! "under": `acc += (1 − acc.a)·c`.
//!
//! Early termination applies exactly as the GPU applies it, with
//! `early_termination = Some(threshold)`: the compute backend stops the ray after the
//! slice that makes `acc.a ≥ threshold`; the raster backend at the end of the run of
//! [`crate::renderer::raster_et_interval`] slices (counted from the frame's first
//! slice) in which it does. With [`ReferenceOptions::emulate_fp16`] the accumulator is
//! rounded to fp16 after every slice, like the compute backend writing an
//! rgba16float eye buffer (`round_like_target`): the f64 value is first rounded to
//! f32 (the GPU computes in f32) and then to the nearest fp16.
//!
//! Deliberate differences from the GPU, all in degenerate cases: a NaN opacity or
//! colour from a twin is clamped to 0 (GPU `clamp` is `min(max(x, lo), hi)`, which
//! maps NaN to the lower bound on common hardware), and a non-finite ray parameter
//! (a ray parallel to the slices) drops the sample instead of passing NaNs on.
//!
//! Plugins take part through their [`CpuTwin`]s. When a plugin has per-slice state
//! ([`Plugin::slice_state`](crate::plugin::Plugin::slice_state)) the frame is rendered
//! slice by slice, like the GPU's per-slice mode: every pixel's sample of slice k
//! (its twin reading the previous state through [`CpuContext::state_prev`]), then every
//! state texel's [`CpuTwin::slice_update`] from the sample under its centre (no
//! contribution where the ray misses slice k), the new state rounded to the declared
//! storage format (fp16 for rgba16float).
//!
//! Where a plugin with per-slice state names a light
//! ([`Plugin::slice_light`](crate::plugin::Plugin::slice_light)), the planes are those
//! of [`SlicePlan::half_angle`](crate::slicing::SlicePlan::half_angle) and `forward`
//! above reads as their normal n: a pixel whose ray advances along n composites
//! "under" as above, one advancing against it composites "over"
//! (`acc = c + (1 − c.a)·acc`) and never stops early; the state texels' rays are the
//! light's ([`crate::plugin::CpuLightSpace::ray`]) and a sample's state coordinate is
//! its light-space one ([`crate::plugin::CpuView::state_coord`]).

use std::ops::Range;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use glam::{DMat4, DVec2, DVec3, DVec4};
use rayon::prelude::*;

use crate::inputs::VolumeInputs;
use crate::metrics::{RgbImageF, compare};
use crate::plugin::{
    CpuContext, CpuRay, CpuSample, CpuTwin, CpuView, PluginInstance, SliceStateDecl, StateImage,
    StorageFormat,
};
use crate::renderer::{Backend, FrameSettings};
use crate::slicing::{FramePlan, SliceError, VolumeBox};
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
    #[error("reference rendering was cancelled")]
    Cancelled,
    #[error(transparent)]
    Slices(#[from] SliceError),
    #[error("image size {0}x{1} is invalid (1..={MAX_SIDE} per side)")]
    BadSize(u32, u32),
    #[error("convergence tolerance must be a number >= 0, got {0}")]
    BadTolerance(f64),
    #[error("plugin '{plugin}': {message}")]
    Input { plugin: String, message: String },
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
    /// The document's named volumes ([`crate::inputs`]), as the GPU renderer has them.
    pub inputs: VolumeInputs,
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
/// ([`ReferenceError::NoTwin`]). Rows are rendered in parallel; the cancel flag is
/// checked before every row.
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
    let mut prepared = Prepared::new(volume, stack, &opts.inputs)?;
    prepared.render(settings, settings.slice_spacing, opts)
}

/// Renders the stack with ever finer slice spacing until halving the spacing changes
/// the image, composited over `background` (linear RGB in \[0,1\]), by less than
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
    let mut prepared = Prepared::new(volume, stack, &opts.inputs)?;
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

/// The CPU twins of the enabled instances, in stack order, with their state decls.
type Twins = (Vec<Box<dyn CpuTwin>>, Vec<Option<SliceStateDecl>>);

fn twins_for(stack: &[PluginInstance]) -> Result<Twins, ReferenceError> {
    stack
        .iter()
        .filter(|i| i.enabled)
        .map(|i| {
            let p = i.configured();
            let twin = p
                .cpu_twin(&i.params)
                .ok_or_else(|| ReferenceError::NoTwin(p.id().to_string()))?;
            Ok((twin, p.slice_state()))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(|v| v.into_iter().unzip())
}

/// What stays the same between the passes of one call: the volume, its normalised
/// scalars and the twins.
struct Prepared<'a> {
    volume: &'a Volume,
    inputs: VolumeInputs,
    scalars: Vec<f32>,
    twins: Vec<Box<dyn CpuTwin>>,
    states: Vec<Option<SliceStateDecl>>,
    /// Whether a plugin of the stack reads the slice spacing
    /// ([`crate::plugin::Plugin::uses_slice_spacing`], e.g. a pre-integration table).
    reads_spacing: bool,
    /// Whether a plugin of the stack has a `setup` hook (else no ray records are made).
    setup: bool,
    /// What the twins' volume passes last ran for: the camera, and the spacing and
    /// slices where a plugin reads them; a render with the same key reuses them (a
    /// converged reference's halvings).
    passes_for: Option<(CpuView, Option<f64>)>,
    /// The enabled plugins with per-slice state and their parameters, in stack order
    /// (the one naming a light decides the slicing).
    lights: Vec<(Arc<dyn crate::plugin::Plugin>, crate::params::ParamValues)>,
}

impl<'a> Prepared<'a> {
    fn new(
        volume: &'a Volume,
        stack: &[PluginInstance],
        inputs: &VolumeInputs,
    ) -> Result<Self, ReferenceError> {
        for inst in stack.iter().filter(|i| i.enabled) {
            inputs
                .check(volume, &inst.plugin.params(), &inst.params)
                .map_err(|message| ReferenceError::Input {
                    plugin: inst.plugin.id().to_string(),
                    message,
                })?;
        }
        let (twins, states) = twins_for(stack)?;
        Ok(Self {
            volume,
            inputs: inputs.clone(),
            scalars: volume.normalized_scalars(),
            twins,
            states,
            reads_spacing: stack
                .iter()
                .any(|i| i.enabled && i.configured().uses_slice_spacing()),
            setup: stack.iter().any(|i| {
                i.enabled && crate::composer::defines_fn(&i.configured().shader().source, "setup")
            }),
            lights: stack
                .iter()
                .filter(|i| i.enabled)
                .map(|i| (i.configured(), i.params.clone()))
                .filter(|(p, _)| p.slice_state().is_some_and(|st| st.light))
                .collect(),
            passes_for: None,
        })
    }

    /// The light the stack's per-slice state travels with, seen from `view`
    /// ([`crate::plugin::Plugin::slice_light`]; the renderer's choice).
    fn light(&self, view: &crate::camera::View) -> Option<glam::Vec3> {
        self.lights
            .iter()
            .find_map(|(p, params)| p.slice_light(params, view))
    }

    fn render(
        &mut self,
        settings: &FrameSettings,
        spacing_voxels: f32,
        opts: &ReferenceOptions,
    ) -> Result<ReferenceImage, ReferenceError> {
        check_size(settings)?;
        let frame = Frame {
            setup: self.setup,
            ..Frame::new(
                self.volume,
                settings,
                spacing_voxels,
                opts.emulate_fp16,
                &|v| self.light(v),
            )?
        };
        let ctx = CpuContext::new(self.volume, &self.scalars)
            .with_inputs(&self.inputs)
            .with_spacing(frame.spacing / frame.voxel)
            .with_view(frame.view);
        for t in &mut self.twins {
            t.prepare(&ctx);
        }
        // volume passes see the other twins' clip, sample and classify; they depend on
        // the camera (view-space clipping) and, where a twin's classification reads
        // it, on the spacing and the slices, and not otherwise on the frame
        let key = if self.reads_spacing {
            (ctx.view, Some(ctx.spacing))
        } else {
            let camera = CpuView {
                slice_depth0: 0.0,
                slice_spacing: 0.0,
                ..ctx.view
            };
            (camera, None)
        };
        let stale = self.passes_for != Some(key);
        self.passes_for = Some(key);
        for i in (0..self.twins.len()).filter(|_| stale) {
            let (before, rest) = self.twins.split_at_mut(i);
            let Some((me, after)) = rest.split_first_mut() else {
                continue;
            };
            let (before, after) = (&*before, &*after);
            let others = |tex: DVec3, dir: DVec3| stack_classify(&ctx, [before, after], tex, dir);
            me.prepare_passes(&ctx, &others);
        }
        let ctx = ctx.with_scalar_of(&self.twins);
        if self.states.iter().any(Option::is_some) {
            return self.render_slice_major(&frame, &ctx, opts);
        }
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

impl Prepared<'_> {
    /// Slice by slice, for stacks with per-slice state (module docs).
    fn render_slice_major(
        &self,
        frame: &Frame,
        ctx: &CpuContext,
        opts: &ReferenceOptions,
    ) -> Result<ReferenceImage, ReferenceError> {
        let (w, h) = (frame.width, frame.height);
        let mut acc = vec![DVec4::ZERO; w as usize * h as usize];
        let mut states: Vec<Option<StateImage>> = self
            .states
            .iter()
            .map(|d| {
                d.map(|d| {
                    let (sw, sh) = state_size(w, h, d.scale);
                    StateImage::new(sw, sh, DVec4::from_array(d.clear.map(f64::from)))
                })
            })
            .collect();
        let mut rows_done = 0u64;
        // pixels whose ray stopped (early termination), updated at every run boundary
        let mut stopped = vec![false; acc.len()];
        for k in 0..frame.count {
            if opts.cancelled() {
                return Err(ReferenceError::Cancelled);
            }
            if let Some((t, run)) = frame.early
                && k % run == 0
            {
                for (s, a) in stopped.iter_mut().zip(&acc) {
                    *s = a.w >= t;
                }
            }
            // rays that meet half-angle slices from behind composite "over" and never
            // stop early
            let ahead = |r: &PixelRay| frame.ahead(r.dir);
            acc.par_chunks_mut(w as usize)
                .zip(stopped.par_chunks(w as usize))
                .enumerate()
                .for_each(|(y, (row, stopped))| {
                    for (x, a) in row.iter_mut().enumerate() {
                        if stopped[x] && frame.view.light.is_none() {
                            continue;
                        }
                        let r = frame.pixel_ray(ctx, &self.twins, frame.uv(x as u32, y as u32));
                        let ahead = ahead(&r);
                        if stopped[x] && ahead {
                            continue;
                        }
                        if let Some((_, c)) = frame.slice_sample(ctx, &self.twins, &states, &r, k) {
                            *a = if ahead {
                                *a + (1.0 - a.w) * c
                            } else {
                                c + (1.0 - c.w) * *a
                            };
                            if frame.fp16 {
                                *a = round_f16(*a);
                            }
                        }
                    }
                });
            let next: Vec<Option<StateImage>> = states
                .iter()
                .enumerate()
                .map(|(i, st)| {
                    let st = st.as_ref()?;
                    let decl = self.states[i]?;
                    let ctx_i = CpuContext {
                        state: Some(st),
                        ..*ctx
                    };
                    let (sw, sh) = (st.width, st.height);
                    let texels = (0..sw as usize * sh as usize)
                        .into_par_iter()
                        .map(|n| {
                            let (tx, ty) = ((n % sw as usize) as f64, (n / sw as usize) as f64);
                            let uv = DVec2::new((tx + 0.5) / sw as f64, (ty + 0.5) / sh as f64);
                            let r = frame.state_ray(ctx, &self.twins, uv);
                            let (mut s, c) = frame
                                .slice_sample(ctx, &self.twins, &states, &r, k)
                                .unwrap_or_else(|| (frame.missed_sample(&r, k), DVec4::ZERO));
                            s.ray_record = r.records.get(i).copied().unwrap_or(DVec4::ZERO);
                            round_state(self.twins[i].slice_update(&ctx_i, &s, c, uv), decl.format)
                        })
                        .collect();
                    Some(StateImage {
                        width: sw,
                        height: sh,
                        texels,
                    })
                })
                .collect();
            states = next;
            let rows = (k as u64 + 1) * h as u64 / frame.count as u64;
            if let Some(p) = &opts.progress {
                p.fetch_add((rows - rows_done) as usize, Ordering::Relaxed);
            }
            rows_done = rows;
        }
        if let Some(p) = &opts.progress {
            p.fetch_add((h as u64 - rows_done) as usize, Ordering::Relaxed);
        }
        let pixels = acc
            .into_iter()
            .enumerate()
            .map(|(i, a)| {
                let uv = frame.uv(i as u32 % w, i as u32 / w);
                frame.post(&self.twins, a, uv).to_array()
            })
            .collect();
        Ok(ReferenceImage {
            width: w,
            height: h,
            pixels,
            slices: frame.count,
        })
    }
}

/// Size of a per-slice state texture for a `w`×`h` eye buffer (as the renderer
/// allocates it).
fn state_size(w: u32, h: u32, scale: f32) -> (u32, u32) {
    let side = |n: u32| ((n as f32 * scale).round() as u32).max(1);
    (side(w), side(h))
}

/// A state texel as the declared storage format holds it.
fn round_state(v: DVec4, format: StorageFormat) -> DVec4 {
    match format {
        StorageFormat::Rgba16Float => round_f16(v),
        StorageFormat::Rgba32Float => v.as_vec4().as_dvec4(),
        StorageFormat::R32Float => DVec4::new(v.x as f32 as f64, 0.0, 0.0, 1.0),
        StorageFormat::Rgba8Unorm => (v.clamp(DVec4::ZERO, DVec4::ONE) * 255.0).round() / 255.0,
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
    /// Early termination: (threshold, slices per run). A ray stops at the first run
    /// boundary (a slice index that is a multiple of the run length) at which its
    /// opacity is at least the threshold: every slice for the compute backend, every
    /// [`crate::renderer::raster_et_interval`] slices for the raster backend.
    early: Option<(f64, u32)>,
    fp16: bool,
    view: crate::plugin::CpuView,
    /// Whether to make ray records (`run_setup`): the stack has a `setup` hook.
    setup: bool,
    /// Unit normal of the slice planes: `forward`, or the half-angle axis.
    normal: DVec3,
}

/// A pixel's ray (`pixel_ray`) and its twins' `setup` records, in stack order (empty
/// when the stack has no `setup` hook: every record is then zero).
struct PixelRay {
    origin: DVec3,
    dir: DVec3,
    uv: DVec2,
    records: Vec<DVec4>,
}

impl Frame {
    /// The frame of `settings`, sliced halfway between the view and `light(view)`
    /// where that names a light (as the renderer does).
    fn new(
        volume: &Volume,
        settings: &FrameSettings,
        spacing_voxels: f32,
        fp16: bool,
        light: &dyn Fn(&crate::camera::View) -> Option<glam::Vec3>,
    ) -> Result<Self, ReferenceError> {
        let (w, h) = (settings.width, settings.height);
        let view = settings.camera.view(w as f32 / h as f32);
        let vbox = VolumeBox::new(volume.dims, volume.spacing);
        let FramePlan { slices: plan, half } =
            FramePlan::new(&view, &vbox, spacing_voxels, light(&view))?;
        let view_proj: DMat4 = view.proj.as_dmat4() * view.view.as_dmat4();
        let early = match (settings.backend, settings.early_termination) {
            (Backend::Compute, Some(t)) => Some((t as f64, 1)),
            (Backend::Raster, Some(t)) => Some((t as f64, crate::renderer::raster_et_interval())),
            (_, None) => None,
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
            view: crate::plugin::CpuView {
                light: half.as_ref().map(crate::plugin::CpuLightSpace::new),
                ..crate::plugin::CpuView::from_view(&view, plan.d0, plan.spacing)
            },
            setup: false,
            normal: plan.forward.as_dvec3(),
        })
    }

    /// The ray of state coordinate `uv` (`state_ray`): the pixel's, or the light's
    /// under half-angle slicing.
    fn state_ray(&self, ctx: &CpuContext, twins: &[Box<dyn CpuTwin>], uv: DVec2) -> PixelRay {
        let Some(l) = &self.view.light else {
            return self.pixel_ray(ctx, twins, uv);
        };
        let (origin, dir) = l.ray(uv);
        self.traced(ctx, twins, origin, dir, origin, uv)
    }

    /// The ray from `origin` along `dir` with coordinate `uv`, and its twins' `setup`
    /// records for the same ray starting at `setup_origin`.
    fn traced(
        &self,
        ctx: &CpuContext,
        twins: &[Box<dyn CpuTwin>],
        origin: DVec3,
        dir: DVec3,
        setup_origin: DVec3,
        uv: DVec2,
    ) -> PixelRay {
        let records = if self.setup {
            let ray = CpuRay {
                origin: setup_origin,
                dir,
                uv,
                size: DVec2::new(self.width as f64, self.height as f64),
            };
            twins.iter().map(|t| t.setup(ctx, &ray)).collect()
        } else {
            Vec::new()
        };
        PixelRay {
            origin,
            dir,
            uv,
            records,
        }
    }

    /// Whether the ray along `dir` meets the slices front to back (else it composites
    /// them "over", back to front).
    fn ahead(&self, dir: DVec3) -> bool {
        dir.dot(self.normal) >= 0.0
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

    fn uv(&self, x: u32, y: u32) -> DVec2 {
        DVec2::new(
            (x as f64 + 0.5) / self.width as f64,
            (y as f64 + 0.5) / self.height as f64,
        )
    }

    /// The sample of slice `k` on the ray through `uv` (`slice_sample`), before the
    /// hooks run; `None` where the ray misses the slice inside the box.
    fn make_sample(&self, origin: DVec3, dir: DVec3, uv: DVec2, k: u32) -> Option<CpuSample> {
        let dd = dir.dot(self.normal);
        let depth0 = (origin - self.eye).dot(self.normal);
        let d = self.d0 + k as f64 * self.spacing;
        let t = (d - depth0) / dd;
        let pos = origin + dir * t;
        if !(t >= 0.0 && t.is_finite() && self.inside(pos)) {
            return None;
        }
        Some(CpuSample {
            pos,
            tex: (pos - self.box_min) / (self.box_max - self.box_min),
            ray_dir: dir,
            uv,
            value: 0.0,
            step: self.step(dir),
            color: DVec4::ZERO,
            normal: DVec3::ZERO,
            slice: k,
            shade_at: 0.0,
            ray_record: DVec4::ZERO,
        })
    }

    /// The distance along a ray of direction `dir` between two slice planes
    /// (`s.step` in slice.wgsl's `make_sample`).
    fn step(&self, dir: DVec3) -> f64 {
        self.spacing / dir.dot(self.normal).abs().max(1.0e-6)
    }

    fn ratio(&self, dir: DVec3) -> f64 {
        self.step(dir) / self.voxel
    }

    /// Slice `k` on the ray `r` through all hooks: the shaded sample and its
    /// contribution.
    fn slice_sample(
        &self,
        ctx: &CpuContext,
        twins: &[Box<dyn CpuTwin>],
        states: &[Option<StateImage>],
        r: &PixelRay,
        k: u32,
    ) -> Option<(CpuSample, DVec4)> {
        let sample = self.make_sample(r.origin, r.dir, r.uv, k)?;
        Some(evaluate(
            ctx,
            twins,
            states,
            &r.records,
            sample,
            self.ratio(r.dir),
        ))
    }

    /// The ray through `uv` (`pixel_ray`) and, where the stack has a `setup` hook, each
    /// twin's record for it in stack order (`run_setup`). The ray `setup` sees starts at
    /// the eye, or on the plane through the eye for an orthographic camera, as on the
    /// GPU.
    fn pixel_ray(&self, ctx: &CpuContext, twins: &[Box<dyn CpuTwin>], uv: DVec2) -> PixelRay {
        let (origin, dir) = self.ray(uv);
        let back = (origin - self.eye).dot(self.forward) / dir.dot(self.forward);
        self.traced(ctx, twins, origin, dir, origin - dir * back, uv)
    }

    /// What `state_texel_sample` passes on where the ray `r` misses slice `k`.
    fn missed_sample(&self, r: &PixelRay, k: u32) -> CpuSample {
        CpuSample {
            pos: r.origin,
            tex: (r.origin - self.box_min) / (self.box_max - self.box_min),
            ray_dir: r.dir,
            uv: r.uv,
            step: self.step(r.dir),
            slice: k,
            ..Default::default()
        }
    }

    /// `cs_main` for one pixel: premultiplied RGBA.
    fn pixel(&self, ctx: &CpuContext, twins: &[Box<dyn CpuTwin>], x: u32, y: u32) -> [f64; 4] {
        let uv = self.uv(x, y);
        let r = self.pixel_ray(ctx, twins, uv);
        let (origin, dir) = (r.origin, r.dir);
        let dd = dir.dot(self.normal);
        let depth0 = (origin - self.eye).dot(self.normal);
        let ratio = self.ratio(dir);
        let mut acc = DVec4::ZERO;
        for k in self.slice_range(origin, dir, depth0, dd) {
            if let Some((threshold, run)) = self.early
                && k % run == 0
                && acc.w >= threshold
            {
                break;
            }
            let Some(sample) = self.make_sample(origin, dir, uv, k) else {
                continue;
            };
            let (_, c) = evaluate(ctx, twins, &[], &r.records, sample, ratio);
            acc += (1.0 - acc.w) * c;
            if self.fp16 {
                acc = round_f16(acc);
            }
        }
        self.post(twins, acc, uv).to_array()
    }

    /// `run_post`: every twin's `post` in stack order on a pixel's accumulated colour,
    /// stored as the eye buffer stores it.
    fn post(&self, twins: &[Box<dyn CpuTwin>], acc: DVec4, uv: DVec2) -> DVec4 {
        let mut c = acc;
        for t in twins {
            t.post(&mut c, uv);
        }
        if self.fp16 && c != acc {
            c = round_f16(c);
        }
        c
    }
}

/// `clamp(x, lo, hi)` that maps NaN to `lo`.
fn clamp_nan_low(x: f64, lo: f64, hi: f64) -> f64 {
    if x.is_nan() { lo } else { x.clamp(lo, hi) }
}

/// `correct_opacity` of `shaders/common.wgsl`: α' = 1 − (1 − α)^(Δs/Δs0) with
/// `ratio` = Δs/Δs0, exact at α = 0 and α = 1; NaN counts as 0. For twins that need
/// the core's correction inside a hook (e.g. `shade.isosurface`).
pub fn correct_opacity(alpha: f64, ratio: f64) -> f64 {
    let a = clamp_nan_low(alpha, 0.0, 1.0);
    if a >= 1.0 {
        return 1.0;
    }
    1.0 - (1.0 - a).powf(ratio)
}

/// `evaluate()`: the shaded sample and its premultiplied, opacity-corrected
/// contribution. `states[i]` is twin i's previous state (empty: no state anywhere).
fn evaluate(
    ctx: &CpuContext,
    twins: &[Box<dyn CpuTwin>],
    states: &[Option<StateImage>],
    records: &[DVec4],
    sample: CpuSample,
    ratio: f64,
) -> (CpuSample, DVec4) {
    crate::shading::set_cut_gradient(None);
    // each twin's hooks see its own ray record, as each instance reads its own
    let record = |i: usize| records.get(i).copied().unwrap_or(DVec4::ZERO);
    let kept = twins.iter().enumerate().all(|(i, t)| {
        t.clip(&CpuSample {
            ray_record: record(i),
            ..sample
        })
    });
    if !kept {
        let mut s = sample;
        s.color = DVec4::ZERO;
        return (s, DVec4::ZERO);
    }
    let with_state = |i: usize| CpuContext {
        state: states.get(i).and_then(Option::as_ref),
        ..*ctx
    };
    let mut s = sample;
    s.value = ctx.value(s.tex);
    for (i, t) in twins.iter().enumerate() {
        s.ray_record = record(i);
        t.sample(&with_state(i), &mut s);
    }
    s.color = DVec4::splat(s.value);
    for (i, t) in twins.iter().enumerate() {
        s.ray_record = record(i);
        t.classify(&with_state(i), &mut s);
    }
    for (i, t) in twins.iter().enumerate() {
        s.ray_record = record(i);
        t.shade(&with_state(i), &mut s);
    }
    let a = correct_opacity(s.color.w, ratio);
    let rgb = DVec3::new(
        clamp_nan_low(s.color.x, 0.0, RGB_MAX),
        clamp_nan_low(s.color.y, 0.0, RGB_MAX),
        clamp_nan_low(s.color.z, 0.0, RGB_MAX),
    );
    let mut c = (rgb * a).extend(a);
    for (i, t) in twins.iter().enumerate() {
        s.ray_record = record(i);
        t.composite(&s, &mut c);
    }
    (s, c)
}

/// Options of [`render_single_scattering`].
#[derive(Debug, Clone)]
pub struct ScatteringOptions {
    /// Unit direction towards the directional light, world space; None: a head light
    /// (towards the eye from the volume's centre).
    pub light: Option<DVec3>,
    /// Paths per pixel.
    pub samples: u32,
    pub seed: u64,
    /// Tracking step in voxels (σ is piecewise constant over it).
    pub step_voxels: f64,
    /// κ of a chromatic extinction on the light's paths: the shadow rays attenuate
    /// channel c by e^(−κ_c·τ) while the eye ray keeps the achromatic σ (what
    /// `shade.dos` does with `extinction: chromatic`). (1, 1, 1): achromatic.
    pub extinction: DVec3,
}

impl Default for ScatteringOptions {
    fn default() -> Self {
        Self {
            light: None,
            samples: 64,
            seed: 1,
            step_voxels: 0.5,
            extinction: DVec3::ONE,
        }
    }
}

/// A Monte-Carlo image with its statistical error.
#[derive(Debug, Clone, PartialEq)]
pub struct ScatteringImage {
    pub image: ReferenceImage,
    /// Per pixel, the half-width of the 95 % confidence interval of each RGB mean
    /// (1.96·s/√n), averaged over the pixels and channels, and its largest value.
    pub ci95_mean: f64,
    pub ci95_max: f64,
    /// The light direction used (world, towards the light).
    pub light: DVec3,
}

/// The illumination ground truth: single scattering of a directional light (white,
/// radiance 1) with shadows, by Monte Carlo on the CPU, for the stack's clip, sample
/// and classify plugins (shading plugins are ignored: this is what they approximate).
///
/// Extinction σ = −ln(1 − α)/Δs0 from the classified α per Δs0, the TF colour as the
/// albedo, an isotropic phase normalised so that a point the light reaches unoccluded
/// looks as it does unshaded (emission–absorption). Per path: free-flight sampling of a
/// scattering point along the eye ray with probability T·σ (ray marching in steps of
/// `step_voxels` with σ constant per step, from a random offset), then a shadow ray to
/// the box (transmittance by the same marching, its own random offset); the path
/// contributes colour·T_light, or nothing when it leaves the box. The pixel is the mean
/// over `samples` paths, premultiplied, with α the mean of "scattered" (1 − T_eye).
/// Unbiased up to σ being constant per step. Seeded (xorshift per pixel), so a run
/// repeats bit for bit; `ci95_*` state the statistical error.
pub fn render_single_scattering(
    volume: &Volume,
    stack: &[PluginInstance],
    settings: &FrameSettings,
    opts: &ScatteringOptions,
) -> Result<ScatteringImage, ReferenceError> {
    check_size(settings)?;
    let mut prepared = Prepared::new(volume, &classifying(stack), VolumeInputs::empty())?;
    let frame = Frame::new(volume, settings, settings.slice_spacing, false, &|_| None)?;
    let ctx = CpuContext::new(volume, &prepared.scalars)
        .with_spacing(frame.spacing / frame.voxel)
        .with_view(frame.view);
    for t in &mut prepared.twins {
        t.prepare(&ctx);
    }
    let twins = &prepared.twins;
    let light = opts
        .light
        .unwrap_or_else(|| {
            let c = (frame.box_min + frame.box_max) * 0.5;
            frame.eye - c
        })
        .normalize_or(DVec3::Z);
    let h = opts.step_voxels.max(1.0e-3) * frame.voxel;
    let n = opts.samples.max(2);
    let (w, hgt) = (settings.width, settings.height);
    // σ and colour at a world point (zero outside the box or where clipped)
    let medium = |p: DVec3, dir: DVec3| -> (f64, DVec3) {
        if !frame.inside(p) {
            return (0.0, DVec3::ZERO);
        }
        let tex = (p - frame.box_min) / (frame.box_max - frame.box_min);
        let c = stack_classify(&ctx, [twins, &[]], tex, dir);
        let a = clamp_nan_low(c.w, 0.0, 1.0 - 1.0e-12);
        (
            -(1.0 - a).ln() / frame.voxel,
            c.truncate().clamp(DVec3::ZERO, DVec3::splat(RGB_MAX)),
        )
    };
    // where a ray from `o` along `d` is inside the box: [t0, t1]
    let span = |o: DVec3, d: DVec3| -> Option<(f64, f64)> {
        let inv = d.recip();
        let ta = (frame.box_min - o) * inv;
        let tb = (frame.box_max - o) * inv;
        let t0 = ta.min(tb).max_element().max(0.0);
        let t1 = ta.max(tb).min_element();
        (t0.is_finite() && t1.is_finite() && t1 > t0).then_some((t0, t1))
    };
    let rows: Vec<Vec<([f64; 4], f64)>> = (0..hgt)
        .into_par_iter()
        .map(|y| {
            (0..w)
                .map(|x| {
                    let mut rng = crate::rng::XorShift(
                        opts.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(
                            ((y as u64) << 32 | x as u64).wrapping_mul(0xD1B5_4A32_D192_ED03),
                        ) | 1,
                    );
                    let mut rnd = || rng.uniform();
                    let (origin, dir) = frame.ray(frame.uv(x, y));
                    let Some((t0, t1)) = span(origin, dir) else {
                        return ([0.0; 4], 0.0);
                    };
                    let (mut sum, mut sum2, mut hits) = (DVec3::ZERO, DVec3::ZERO, 0.0);
                    for _ in 0..n {
                        // free flight: march until the optical depth passes −ln(1 − u)
                        let target = -(1.0 - rnd()).ln();
                        let mut depth = 0.0;
                        let mut t = t0 + rnd() * h - h;
                        let mut scattered = None;
                        while t < t1 {
                            let (a, b) = (t.max(t0), (t + h).min(t1));
                            let mid = origin + dir * ((a + b) * 0.5);
                            let (sigma, colour) = medium(mid, dir);
                            let step_depth = sigma * (b - a);
                            if depth + step_depth >= target && sigma > 0.0 {
                                let at = a + (target - depth) / sigma;
                                scattered = Some((origin + dir * at, colour));
                                break;
                            }
                            depth += step_depth;
                            t += h;
                        }
                        let Some((p, colour)) = scattered else {
                            continue;
                        };
                        hits += 1.0;
                        // shadow ray
                        let mut tl = DVec3::ONE;
                        if let Some((_, s1)) = span(p, light) {
                            let mut depth = 0.0;
                            let mut s = rnd() * h - h;
                            while s < s1 {
                                let (a, b) = (s.max(0.0), (s + h).min(s1));
                                depth += medium(p + light * ((a + b) * 0.5), light).0 * (b - a);
                                s += h;
                            }
                            tl = (-depth * opts.extinction).exp();
                        }
                        let v = colour * tl;
                        sum += v;
                        sum2 += v * v;
                    }
                    let nf = n as f64;
                    let mean = sum / nf;
                    let var = ((sum2 / nf - mean * mean) * nf / (nf - 1.0)).max(DVec3::ZERO);
                    let ci =
                        1.96 * (var / nf).to_array().iter().map(|v| v.sqrt()).sum::<f64>() / 3.0;
                    ([mean.x, mean.y, mean.z, hits / nf], ci)
                })
                .collect()
        })
        .collect();
    let flat: Vec<([f64; 4], f64)> = rows.into_iter().flatten().collect();
    let ci_mean = flat.iter().map(|p| p.1).sum::<f64>() / flat.len().max(1) as f64;
    let ci_max = flat.iter().map(|p| p.1).fold(0.0, f64::max);
    Ok(ScatteringImage {
        image: ReferenceImage {
            width: w,
            height: hgt,
            pixels: flat.into_iter().map(|p| p.0).collect(),
            slices: 0,
        },
        ci95_mean: ci_mean,
        ci95_max: ci_max,
        light,
    })
}

/// The stack's clip, sample and classify plugins (what `stack_classify` runs).
fn classifying(stack: &[PluginInstance]) -> Vec<PluginInstance> {
    use crate::plugin::Category;
    stack
        .iter()
        .filter(|i| {
            matches!(
                i.plugin.category(),
                Category::Clip | Category::Sample | Category::Classify
            )
        })
        .cloned()
        .collect()
}

/// Calls `f` with the stack's `stack_classify` over `volume` (the twins of its clip,
/// sample and classify plugins, prepared for a frame at one slice per voxel): what
/// volume passes see, for CPU-side analyses of a scene's classification such as
/// `shade.hernell`'s flat-blocking levels.
pub fn with_stack_classify<R>(
    volume: &Volume,
    stack: &[PluginInstance],
    f: impl FnOnce(&crate::plugin::StackClassify<'_>) -> R,
) -> Result<R, ReferenceError> {
    let mut prepared = Prepared::new(volume, &classifying(stack), VolumeInputs::empty())?;
    let ctx = CpuContext::new(volume, &prepared.scalars);
    for t in &mut prepared.twins {
        t.prepare(&ctx);
    }
    let twins = &prepared.twins;
    Ok(f(&|tex, dir| stack_classify(&ctx, [twins, &[]], tex, dir)))
}

/// `stack_classify` of shaders/slice.wgsl: the twins' clip, sample and classify at a
/// texture coordinate (straight RGBA; zero where clipped), one voxel's step along `dir`.
fn stack_classify(
    ctx: &CpuContext,
    groups: [&[Box<dyn CpuTwin>]; 2],
    tex: DVec3,
    dir: DVec3,
) -> DVec4 {
    let (lo, hi) = ctx.volume_box();
    let mut s = CpuSample {
        pos: lo + tex * (hi - lo),
        tex,
        ray_dir: dir,
        step: ctx.reference_step(),
        ..Default::default()
    };
    crate::shading::set_cut_gradient(None);
    let twins = || groups.iter().flat_map(|g| g.iter());
    if !twins().all(|t| t.clip(&s)) {
        return DVec4::ZERO;
    }
    s.value = ctx.value(s.tex);
    for t in twins() {
        t.sample(ctx, &mut s);
    }
    s.color = DVec4::splat(s.value);
    for t in twins() {
        t.classify(ctx, &mut s);
    }
    s.color
}

/// `round_like_target` for an rgba16float eye buffer (via f32, where the GPU computes).
fn round_f16(v: DVec4) -> DVec4 {
    let r = |x: f64| half::f16::from_f32(x as f32).to_f64();
    DVec4::new(r(v.x), r(v.y), r(v.z), r(v.w))
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use super::*;
    use crate::camera::{Camera, Projection};
    use crate::params::{ParamSpec, ParamValues};
    use crate::plugin::{Plugin, ShaderSource};
    use crate::tf::{LUT_SIZE, TfCurve, TfPoint, eval_lut};
    use crate::volume::VoxelData;

    /// Test classifier: colour `rgb`, opacity `alpha · value` (a linear ramp).
    struct Ramp {
        color: [f64; 4],
    }

    struct RampTwin {
        color: DVec4,
    }

    impl CpuTwin for RampTwin {
        fn classify(&self, _ctx: &CpuContext, s: &mut CpuSample) {
            s.color = self.color.truncate().extend(self.color.w * s.value);
        }
    }

    impl Plugin for Ramp {
        fn id(&self) -> &'static str {
            "classify.test_ramp"
        }
        fn display_name(&self) -> &'static str {
            "Test ramp"
        }
        fn params(&self) -> Vec<ParamSpec> {
            Vec::new()
        }
        fn shader(&self) -> ShaderSource {
            ShaderSource::new_static("test_ramp.wgsl", "")
        }
        fn cpu_twin(&self, _params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
            Some(Box::new(RampTwin {
                color: DVec4::from_array(self.color),
            }))
        }
    }

    /// Test classifier over a baked lookup table, like `classify.tf1d`.
    struct Lut {
        curve: TfCurve,
    }

    struct LutTwin {
        lut: Vec<[f32; 4]>,
    }

    impl CpuTwin for LutTwin {
        fn classify(&self, _ctx: &CpuContext, s: &mut CpuSample) {
            s.color = DVec4::from_array(eval_lut(&self.lut, s.value.clamp(0.0, 1.0)));
        }
    }

    impl Plugin for Lut {
        fn id(&self) -> &'static str {
            "classify.test_lut"
        }
        fn display_name(&self) -> &'static str {
            "Test LUT"
        }
        fn params(&self) -> Vec<ParamSpec> {
            Vec::new()
        }
        fn shader(&self) -> ShaderSource {
            ShaderSource::new_static("test_lut.wgsl", "")
        }
        fn cpu_twin(&self, _params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
            Some(Box::new(LutTwin {
                lut: self.curve.bake(LUT_SIZE),
            }))
        }
    }

    /// A plugin without a twin.
    struct Opaque {
        id: &'static str,
    }

    impl Plugin for Opaque {
        fn id(&self) -> &'static str {
            self.id
        }
        fn display_name(&self) -> &'static str {
            "Opaque"
        }
        fn params(&self) -> Vec<ParamSpec> {
            Vec::new()
        }
        fn shader(&self) -> ShaderSource {
            ShaderSource::new_static("opaque.wgsl", "")
        }
    }

    /// A plugin whose twin counts its volume passes; `reads_spacing` is its answer to
    /// [`Plugin::uses_slice_spacing`].
    struct PassCounter {
        runs: Arc<AtomicUsize>,
        reads_spacing: bool,
    }

    struct PassCounterTwin {
        runs: Arc<AtomicUsize>,
    }

    impl CpuTwin for PassCounterTwin {
        fn prepare_passes(
            &mut self,
            _ctx: &CpuContext,
            _classify: &crate::plugin::StackClassify<'_>,
        ) {
            self.runs.fetch_add(1, Ordering::Relaxed);
        }
    }

    impl Plugin for PassCounter {
        fn id(&self) -> &'static str {
            "shade.test_pass_counter"
        }
        fn display_name(&self) -> &'static str {
            "Test pass counter"
        }
        fn params(&self) -> Vec<ParamSpec> {
            Vec::new()
        }
        fn shader(&self) -> ShaderSource {
            ShaderSource::new_static("test_pass_counter.wgsl", "")
        }
        fn cpu_twin(&self, _params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
            Some(Box::new(PassCounterTwin {
                runs: self.runs.clone(),
            }))
        }
        fn uses_slice_spacing(&self) -> bool {
            self.reads_spacing
        }
    }

    fn instance(p: impl Plugin) -> PluginInstance {
        PluginInstance::new(Arc::new(p))
    }

    fn ramp(color: [f64; 4]) -> Vec<PluginInstance> {
        vec![instance(Ramp { color })]
    }

    /// A tissue-like curve (the points of `classify.tf1d`'s default).
    fn tissue_curve() -> TfCurve {
        let p = |x: f32, color: [f32; 4]| TfPoint { x, color };
        TfCurve::new(vec![
            p(0.0, [0.0, 0.0, 0.0, 0.0]),
            p(0.25, [0.8, 0.4, 0.3, 0.0]),
            p(0.45, [0.9, 0.6, 0.5, 0.08]),
            p(1.0, [1.0, 1.0, 0.95, 0.6]),
        ])
    }

    fn cube(n: u32, f: impl Fn(u32, u32, u32) -> f32) -> Volume {
        let mut data = Vec::with_capacity((n * n * n) as usize);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    data.push(f(x, y, z));
                }
            }
        }
        Volume::new("test", [n; 3], 1, [1.0; 3], VoxelData::F32(data)).unwrap()
    }

    /// 1 everywhere but the corner voxel (0, 0, 0), which is 0 (so the range is [0, 1]).
    fn homogeneous(n: u32) -> Volume {
        cube(n, |x, y, z| if x + y + z == 0 { 0.0 } else { 1.0 })
    }

    /// Orthographic view along +z, `size`² pixels.
    fn ortho_z(size: u32, spacing: f32) -> FrameSettings {
        let mut camera = Camera {
            projection: Projection::Orthographic { height: 1.5 },
            ..Default::default()
        };
        camera.axis_view(2, false);
        FrameSettings {
            camera,
            width: size,
            height: size,
            slice_spacing: spacing,
            ..Default::default()
        }
    }

    fn opts() -> ReferenceOptions {
        ReferenceOptions::default()
    }

    /// A converged reference renders one view at ever finer spacings: the twins'
    /// volume passes run once, unless a plugin reads the spacing (then
    /// once per spacing); a new camera reruns them, the same frame again does not.
    #[test]
    fn volume_passes_run_once_per_camera_unless_classification_reads_the_spacing() {
        let volume = cube(8, |x, _, _| x as f32 / 7.0);
        let settings = ortho_z(8, 1.0);
        for reads_spacing in [false, true] {
            let runs = Arc::new(AtomicUsize::new(0));
            let mut stack = ramp([0.8, 0.5, 0.3, 0.5]);
            stack.push(instance(PassCounter {
                runs: runs.clone(),
                reads_spacing,
            }));
            let c = render_converged(&volume, &stack, &settings, &opts(), 0.0, [0.0; 3]).unwrap();
            let renders = 1 + c.steps.len();
            assert!(renders >= 3, "{renders} renders");
            let want = if reads_spacing { renders } else { 1 };
            assert_eq!(
                runs.load(Ordering::Relaxed),
                want,
                "reads_spacing {reads_spacing}"
            );
            // one Prepared, two cameras: the passes follow the camera
            runs.store(0, Ordering::Relaxed);
            let mut prepared = Prepared::new(&volume, &stack, VolumeInputs::empty()).unwrap();
            let mut turned = settings;
            turned.camera.yaw_deg += 30.0;
            for s in [settings, settings, turned, turned] {
                prepared.render(&s, s.slice_spacing, &opts()).unwrap();
            }
            assert_eq!(
                runs.load(Ordering::Relaxed),
                2,
                "reads_spacing {reads_spacing}"
            );
        }
    }

    /// Single scattering in a homogeneous slab lit from the eye: a point at depth s
    /// is reached by the light through s, so L = c·σ∫₀ᴰ e^(−2σs) ds = c·(1 − e^(−2σD))/2,
    /// and the share of paths that scatter is 1 − e^(−σD).
    #[test]
    fn single_scattering_matches_the_closed_form_of_a_slab() {
        let volume = homogeneous(16);
        let c = [0.8, 0.4, 0.2, 0.1];
        let settings = ortho_z(33, 1.0);
        let opts = ScatteringOptions {
            samples: 256,
            ..Default::default()
        };
        let g = render_single_scattering(&volume, &ramp(c), &settings, &opts).unwrap();
        let sigma_d = -(1.0f64 - c[3]).ln() * 16.0;
        let expect_l = (1.0 - (-2.0 * sigma_d).exp()) / 2.0;
        let expect_a = 1.0 - (-sigma_d).exp();
        // the mean over the centre's 5 × 5 pixels
        let centre = |img: &ReferenceImage| {
            let mut mean = [0.0f64; 4];
            for y in 14..19 {
                for x in 14..19 {
                    let p = img.pixel(x, y);
                    for i in 0..4 {
                        mean[i] += p[i] / 25.0;
                    }
                }
            }
            mean
        };
        let mean = centre(&g.image);
        for i in 0..3 {
            let want = c[i] * expect_l;
            assert!(
                (mean[i] - want).abs() < 0.03 * want + 1e-3,
                "channel {i}: {} vs {want}",
                mean[i]
            );
        }
        assert!(
            (mean[3] - expect_a).abs() < 0.03,
            "{} vs {expect_a}",
            mean[3]
        );
        assert!(g.ci95_mean > 0.0 && g.ci95_mean < 0.05, "{}", g.ci95_mean);
        // outside the box nothing scatters
        assert_eq!(g.image.pixel(0, 0), [0.0; 4]);
        // seeded: the same seed repeats, another differs
        let again = render_single_scattering(&volume, &ramp(c), &settings, &opts).unwrap();
        assert_eq!(again.image, g.image);
        let other = render_single_scattering(
            &volume,
            &ramp(c),
            &settings,
            &ScatteringOptions { seed: 2, ..opts },
        )
        .unwrap();
        assert_ne!(other.image, g.image);
        // chromatic extinction on the shadow rays: channel c sees κ_c·σ towards the
        // light, L_c = c·(1 − e^(−(1 + κ_c)σD))/(1 + κ_c); the eye ray (α) is unchanged
        let kappa = DVec3::new(0.25, 1.0, 3.0);
        let chromatic = render_single_scattering(
            &volume,
            &ramp(c),
            &settings,
            &ScatteringOptions {
                extinction: kappa,
                ..opts
            },
        )
        .unwrap();
        let mean = centre(&chromatic.image);
        for i in 0..3 {
            let k = 1.0 + kappa[i];
            let want = c[i] * (1.0 - (-k * sigma_d).exp()) / k;
            assert!(
                (mean[i] - want).abs() < 0.03 * want + 1e-3,
                "chromatic channel {i}: {} vs {want}",
                mean[i]
            );
        }
        assert!((mean[3] - expect_a).abs() < 0.03, "{}", mean[3]);
    }

    #[test]
    fn homogeneous_slab_matches_closed_form() {
        let volume = homogeneous(16);
        let c = [0.8, 0.4, 0.2, 0.1];
        // planes at the centre ± m·0.75 voxels; the faces are 8 voxels away: 21 planes
        let settings = ortho_z(33, 0.75);
        let img = render_reference(&volume, &ramp(c), &settings, &opts()).unwrap();
        assert_eq!(img.slices, 21);
        let n = 21.0;
        let alpha = 1.0 - (1.0 - c[3]).powf(0.75);
        let coverage = 1.0 - (1.0 - alpha).powf(n);
        let got = img.pixel(16, 16);
        for i in 0..3 {
            assert!(
                (got[i] - c[i] * coverage).abs() < 1e-6,
                "channel {i}: {} vs {}",
                got[i],
                c[i] * coverage
            );
        }
        assert!((got[3] - coverage).abs() < 1e-6, "{} vs {coverage}", got[3]);
        // the image corners look past the box (view height 1.5 > 1)
        assert_eq!(img.pixel(0, 0), [0.0; 4]);
        assert_eq!(img.pixel(32, 32), [0.0; 4]);
    }

    #[test]
    fn empty_stack_is_the_grey_ramp() {
        let volume = homogeneous(16);
        let img = render_reference(&volume, &[], &ortho_z(33, 0.75), &opts()).unwrap();
        // value 1: colour (1, 1, 1, 1) per voxel, opaque after the first slice
        assert_eq!(img.pixel(16, 16), [1.0; 4]);
    }

    #[test]
    fn opacity_correction_makes_spacing_irrelevant() {
        // a soft-edged block in the middle: the integrand vanishes at the box faces,
        // so the slice sum is a trapezoid rule and differs from the integral by O(Δs²)
        let volume = cube(16, |x, y, z| {
            if [x, y, z].iter().all(|v| (4..12).contains(v)) {
                1.0
            } else {
                0.0
            }
        });
        let stack = ramp([0.9, 0.7, 0.3, 0.1]);
        let settings = |spacing| FrameSettings {
            width: 32,
            height: 32,
            slice_spacing: spacing,
            ..Default::default()
        };
        let coarse = render_reference(&volume, &stack, &settings(1.0), &opts()).unwrap();
        let fine = render_reference(&volume, &stack, &settings(0.5), &opts()).unwrap();
        let finer = render_reference(&volume, &stack, &settings(0.25), &opts()).unwrap();
        assert!(fine.slices >= 2 * coarse.slices - 2);
        let max_diff = |a: &ReferenceImage, b: &ReferenceImage| {
            a.pixels
                .iter()
                .zip(&b.pixels)
                .flat_map(|(p, q)| (0..4).map(move |i| (p[i] - q[i]).abs()))
                .fold(0.0, f64::max)
        };
        let max_alpha = fine.pixels.iter().map(|p| p[3]).fold(0.0, f64::max);
        assert!(max_alpha > 0.5, "the block is dense enough: {max_alpha}");
        let d1 = max_diff(&coarse, &fine);
        let d2 = max_diff(&fine, &finer);
        eprintln!("max |Δ| 1→½: {d1:.2e}, ½→¼: {d2:.2e}");
        // without the correction, halving the spacing would double the optical depth:
        // 1 − 0.9^10 = 0.65 against 1 − 0.9^20 = 0.88
        // and the slice sums converge to the integral at second order
        assert!(d1 < 2e-2, "{d1}");
        assert!(d2 < 5e-3, "{d2}");
        assert!(d2 < d1 / 2.5, "{d1} → {d2}");
    }

    #[test]
    fn fp16_emulation_rounds_the_accumulator() {
        let volume = homogeneous(16);
        let stack = ramp([0.8, 0.4, 0.2, 0.1]);
        let settings = ortho_z(33, 0.75);
        let exact = render_reference(&volume, &stack, &settings, &opts()).unwrap();
        let o = ReferenceOptions {
            emulate_fp16: true,
            ..Default::default()
        };
        let half = render_reference(&volume, &stack, &settings, &o).unwrap();
        for (p, q) in half.pixels.iter().zip(&exact.pixels) {
            for i in 0..4 {
                assert_eq!(half::f16::from_f64(p[i]).to_f64(), p[i]);
                assert!((p[i] - q[i]).abs() < 5e-3, "{} vs {}", p[i], q[i]);
            }
        }
        assert_ne!(half.pixel(16, 16), exact.pixel(16, 16));
    }

    #[test]
    fn early_termination_follows_each_backend() {
        let volume = homogeneous(64); // ≈ 85 slices: deeper than a raster run
        let stack = ramp([0.8, 0.4, 0.2, 0.1]);
        let full = render_reference(&volume, &stack, &ortho_z(33, 0.75), &opts()).unwrap();
        let early = FrameSettings {
            backend: Backend::Compute,
            early_termination: Some(0.5),
            ..ortho_z(33, 0.75)
        };
        let img = render_reference(&volume, &stack, &early, &opts()).unwrap();
        let alpha = 1.0 - 0.9f64.powf(0.75);
        // stops after the first slice that reaches 0.5
        let n = ((0.5f64).ln() / (1.0 - alpha).ln()).ceil();
        let want = 1.0 - (1.0 - alpha).powf(n);
        let a = img.pixel(16, 16)[3];
        assert!((a - want).abs() < 1e-9, "{a} vs {want}");
        assert!(a < full.pixel(16, 16)[3]);
        // the raster backend stops at the end of the run of slices that reaches 0.5:
        // m slices with n ≤ m < n + run
        let raster = FrameSettings {
            backend: Backend::Raster,
            ..early
        };
        let run = crate::renderer::raster_et_interval() as f64;
        let img = render_reference(&volume, &stack, &raster, &opts()).unwrap();
        let a = img.pixel(16, 16)[3];
        let m = (1.0 - a).ln() / (1.0 - alpha).ln();
        assert!((m - m.round()).abs() < 1e-6, "{m} slices");
        assert!(
            m.round() >= n && m.round() < n + run,
            "{m} slices, compute {n}, run {run}"
        );
        assert!(a < full.pixel(16, 16)[3], "{a}");
        // without a threshold both backends take every slice
        let none = FrameSettings {
            early_termination: None,
            ..raster
        };
        let img = render_reference(&volume, &stack, &none, &opts()).unwrap();
        assert_eq!(img.pixels, full.pixels);
    }

    #[test]
    fn cancel_and_progress() {
        let volume = homogeneous(8);
        let settings = ortho_z(12, 1.0);
        let cancel = Arc::new(AtomicBool::new(true));
        let o = ReferenceOptions {
            cancel: Some(cancel.clone()),
            ..Default::default()
        };
        assert_eq!(
            render_reference(&volume, &[], &settings, &o).unwrap_err(),
            ReferenceError::Cancelled
        );
        assert_eq!(
            render_converged(&volume, &[], &settings, &o, 0.1, [0.0; 3]).unwrap_err(),
            ReferenceError::Cancelled
        );
        cancel.store(false, Ordering::Relaxed);
        let progress = Arc::new(AtomicUsize::new(0));
        let o = ReferenceOptions {
            progress: Some(progress.clone()),
            ..o
        };
        render_reference(&volume, &[], &settings, &o).unwrap();
        assert_eq!(progress.load(Ordering::Relaxed), 12);
    }

    #[test]
    fn cancel_from_another_thread_stops_the_render() {
        let volume = crate::volume::demo();
        let stack = vec![instance(Lut {
            curve: tissue_curve(),
        })];
        let settings = FrameSettings {
            width: 256,
            height: 256,
            slice_spacing: 0.01,
            ..Default::default()
        };
        let cancel = Arc::new(AtomicBool::new(false));
        let progress = Arc::new(AtomicUsize::new(0));
        let o = ReferenceOptions {
            cancel: Some(cancel.clone()),
            progress: Some(progress.clone()),
            ..Default::default()
        };
        let start = Instant::now();
        let result = std::thread::scope(|scope| {
            let job = scope.spawn(|| render_reference(&volume, &stack, &settings, &o));
            // cancel once some rows are done (or right away on a very slow machine)
            while progress.load(Ordering::Relaxed) < 2 && start.elapsed().as_secs() < 30 {
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
            cancel.store(true, Ordering::Relaxed);
            job.join().unwrap()
        });
        assert_eq!(result.unwrap_err(), ReferenceError::Cancelled);
        assert!(progress.load(Ordering::Relaxed) < 256);
    }

    #[test]
    fn stack_errors() {
        let volume = homogeneous(8);
        let settings = ortho_z(8, 1.0);
        let no_twin = instance(Opaque {
            id: "shade.no_twin",
        });
        assert_eq!(
            render_reference(&volume, std::slice::from_ref(&no_twin), &settings, &opts())
                .unwrap_err(),
            ReferenceError::NoTwin("shade.no_twin".into())
        );
        // disabled instances are skipped
        let mut off = no_twin;
        off.enabled = false;
        let img = render_reference(&volume, &[off], &settings, &opts()).unwrap();
        let grey = render_reference(&volume, &[], &settings, &opts()).unwrap();
        assert_eq!(img, grey);
        // sizes and spacings
        for (w, h) in [(0, 8), (8, 0), (MAX_SIDE + 1, 1)] {
            let s = FrameSettings {
                width: w,
                height: h,
                ..settings
            };
            assert_eq!(
                render_reference(&volume, &[], &s, &opts()).unwrap_err(),
                ReferenceError::BadSize(w, h)
            );
        }
        for spacing in [0.0, -1.0, f32::NAN] {
            let s = FrameSettings {
                slice_spacing: spacing,
                ..settings
            };
            assert!(matches!(
                render_reference(&volume, &[], &s, &opts()),
                Err(ReferenceError::Slices(SliceError::BadSpacing(_)))
            ));
            assert!(matches!(
                render_converged(&volume, &[], &s, &opts(), 0.1, [0.0; 3]),
                Err(ReferenceError::Slices(SliceError::BadSpacing(_)))
            ));
        }
        assert!(matches!(
            render_converged(&volume, &[], &settings, &opts(), f64::NAN, [0.0; 3]),
            Err(ReferenceError::BadTolerance(t)) if t.is_nan()
        ));
        assert_eq!(
            render_converged(&volume, &[], &settings, &opts(), -1.0, [0.0; 3]).unwrap_err(),
            ReferenceError::BadTolerance(-1.0)
        );
    }

    #[test]
    fn nan_voxels_give_finite_images() {
        let volume = cube(12, |x, y, z| match (x + 2 * y + 3 * z) % 7 {
            0 => f32::NAN,
            1 => f32::INFINITY,
            2 => f32::NEG_INFINITY,
            v => v as f32,
        });
        assert!(volume.non_finite > 0);
        for stack in [
            Vec::new(),
            ramp([1.0, 0.5, 0.25, 0.3]),
            vec![instance(Lut {
                curve: tissue_curve(),
            })],
        ] {
            for settings in [
                FrameSettings {
                    width: 24,
                    height: 20,
                    ..Default::default()
                },
                ortho_z(16, 0.5),
            ] {
                let img = render_reference(&volume, &stack, &settings, &opts()).unwrap();
                for p in &img.pixels {
                    assert!(p.iter().all(|v| v.is_finite()), "{p:?}");
                    assert!((0.0..=1.0).contains(&p[3]), "{p:?}");
                }
                assert!(img.pixels.iter().any(|p| p[3] > 0.0));
            }
        }
    }

    #[test]
    fn converged_demo() {
        let volume = crate::volume::demo();
        let stack = vec![instance(Lut {
            curve: tissue_curve(),
        })];
        let settings = FrameSettings {
            width: 48,
            height: 48,
            ..Default::default()
        };
        let start = Instant::now();
        let c = render_converged(
            &volume,
            &stack,
            &settings,
            &opts(),
            DEFAULT_TOLERANCE_DELTA_E,
            [0.0; 3],
        )
        .unwrap();
        eprintln!(
            "converged demo 48x48: {:?} in {:.2} s, steps {:?}",
            c.converged,
            start.elapsed().as_secs_f64(),
            c.steps
        );
        assert!(c.converged);
        assert!(c.last_change_rms_delta_e < DEFAULT_TOLERANCE_DELTA_E);
        assert_eq!(c.last_change_rms_delta_e, c.steps.last().unwrap().1);
        assert_eq!(c.spacing, c.steps.last().unwrap().0);
        assert_eq!(c.steps[0].0, 0.25);
        for w in c.steps.windows(2) {
            assert_eq!(w[1].0, w[0].0 / 2.0);
            assert!(w[1].1 < w[0].1, "changes decrease: {:?}", c.steps);
        }
        assert!(c.image.pixels.iter().any(|p| p[3] > 0.5));
    }
}
