//! Monte-Carlo reference of directional occlusion shading: the single-scattering cone
//! integral of Schott et al. 2009 (eqs 7–10) evaluated on the CPU in f64 without
//! slicing and without kernel discretisation.
//!
//! Per pixel the eye ray (the same pixel ray as the GPU) is marched through the
//! volume box with step `eye_step`·Δs0 (midpoint rule, the exact per-step
//! transmittance e^(−σt·h)):
//!
//! `L = Σ T_eye · σs · (L_a·V + ambient) · (1 − e^(−σt·h))`,
//!
//! with σs the classified colour and σt = −ln(1 − α)/Δs0 from the classified opacity
//! per Δs0 (the stack's CPU twins: clip, sample, classify and the shading of every
//! other plugin; the DOS factor comes after them, which is the GPU's order when
//! `shade.dos` is the last shading plugin of the stack). The visibility `V(x) = ∫ T(x, x₀,ᵢ) Φθ dωᵢ` (eq 10) is estimated with
//! `directions` directions drawn uniformly in the cone of aperture θ around the
//! direction back along the pixel ray (uniform in solid angle, which is what Φθ
//! weights), or with `light: directional` around the direction towards the light
//! (the cone that half-angle slicing follows), each marched to the box exit with step
//! `cone_step`·Δs0. The eye ray stops
//! once T_eye < 10⁻⁴ and cone rays once T < 10⁻⁴ (bias below 10⁻⁴). With chromatic
//! extinction the cone rays' transmittance is per channel, e^(−κ_c·τ), and V is an
//! RGB visibility.
//!
//! Confidence: the directions are split into `replicas` independent streams; the
//! image is the mean of the replica images, and [`McImage::std_error`] holds the
//! per-pixel standard error of that mean (premultiplied RGB), so a pixel's 95 %
//! interval is ±1.96·std_error. Seeded and deterministic (per pixel and replica,
//! independent of thread order).

use std::sync::atomic::{AtomicBool, Ordering};

use glam::{DMat4, DVec2, DVec3, DVec4};
use rayon::prelude::*;
use vwb_render::plugin::{
    ConvergedReference, CpuContext, CpuSample, CpuTwin, PluginInstance, SuppliedReference,
};
use vwb_render::renderer::FrameSettings;
use vwb_render::rng::{Rng, mix};
use vwb_render::slicing::VolumeBox;
use vwb_render::volume::Volume;

#[derive(Debug, Clone)]
pub struct McOptions {
    /// Cone directions per eye sample (split over the replicas).
    pub directions: usize,
    pub replicas: usize,
    pub seed: u64,
    /// Eye-ray step in voxels (Δs0).
    pub eye_step: f64,
    /// Cone-ray step in voxels.
    pub cone_step: f64,
}

impl Default for McOptions {
    fn default() -> Self {
        Self {
            directions: 32,
            replicas: 4,
            seed: 1,
            eye_step: 0.5,
            cone_step: 1.0,
        }
    }
}

/// The Monte-Carlo cone integral as `shade.dos`'s converged reference
/// ([`vwb_render::plugin::ConvergedReference`]), with these options.
#[derive(Debug, Clone, Default)]
pub struct MonteCarloReference(pub McOptions);

impl ConvergedReference for MonteCarloReference {
    fn kind(&self) -> &'static str {
        "monte_carlo"
    }
    fn label(&self) -> &'static str {
        "Monte Carlo"
    }
    fn render(
        &self,
        volume: &Volume,
        stack: &[PluginInstance],
        settings: &FrameSettings,
        cancel: Option<&AtomicBool>,
    ) -> Result<SuppliedReference, String> {
        let o = &self.0;
        let mc = render_mc(volume, stack, settings, o, cancel)?;
        Ok(SuppliedReference {
            notes: vec![
                ("directions", o.directions as f64),
                ("replicas", o.replicas as f64),
                ("seed", o.seed as f64),
                ("eye_step_voxels", o.eye_step),
                ("cone_step_voxels", o.cone_step),
                ("rms_std_error", mc.rms_std_error()),
            ],
            width: mc.width,
            height: mc.height,
            pixels: mc.pixels,
        })
    }
    /// θ, L_a, the ambient term, κ and the light of `shade.dos`, the other enabled plugins and the
    /// options: the kernel, the distance mode and the buffers do not change the integral.
    fn key(&self, stack: &[PluginInstance]) -> Option<String> {
        let mut parts = Vec::new();
        for i in stack.iter().filter(|i| i.enabled) {
            if i.plugin.id() == "shade.dos" {
                parts.push(format!("shade.dos:{:?}", Integral::of(&i.params)));
            } else {
                parts.push(format!("{}:{:?}", i.plugin.id(), i.params));
            }
        }
        Some(format!("{}|{:?}", parts.join(";"), self.0))
    }
    /// `directions`, `replicas`, `seed`, `eye_step` and `cone_step` (voxels).
    fn with_options(
        &self,
        options: &std::collections::BTreeMap<String, f64>,
    ) -> Result<std::sync::Arc<dyn ConvergedReference>, String> {
        let mut o = self.0.clone();
        for (k, &v) in options {
            let count = |lo: f64, hi: f64| {
                if v.fract() == 0.0 && (lo..=hi).contains(&v) {
                    Ok(v)
                } else {
                    Err(format!("{k} must be a whole number in {lo}..={hi}, got {v}"))
                }
            };
            let step = || {
                if v.is_finite() && v > 0.0 && v <= 8.0 {
                    Ok(v)
                } else {
                    Err(format!("{k} must be in (0, 8] voxels, got {v}"))
                }
            };
            match k.as_str() {
                "directions" => o.directions = count(1.0, 65536.0)? as usize,
                "replicas" => o.replicas = count(1.0, 256.0)? as usize,
                "seed" => o.seed = count(0.0, 2f64.powi(53))? as u64,
                "eye_step" => o.eye_step = step()?,
                "cone_step" => o.cone_step = step()?,
                _ => {
                    return Err(format!(
                        "unknown Monte-Carlo option '{k}' (directions, replicas, seed, eye_step, cone_step)"
                    ));
                }
            }
        }
        if o.directions < o.replicas {
            return Err(format!(
                "directions ({}) must be at least replicas ({})",
                o.directions, o.replicas
            ));
        }
        Ok(std::sync::Arc::new(MonteCarloReference(o)))
    }
}

/// The Monte-Carlo image: premultiplied RGBA per pixel (row-major) and the standard
/// error of each pixel's RGB.
#[derive(Debug, Clone)]
pub struct McImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f64; 4]>,
    pub std_error: Vec<[f64; 3]>,
}

impl McImage {
    /// RMS over pixels and channels of the standard error.
    pub fn rms_std_error(&self) -> f64 {
        let n = (self.std_error.len() * 3).max(1) as f64;
        (self.std_error.iter().flatten().map(|e| e * e).sum::<f64>() / n).sqrt()
    }
}

/// The parameters of `shade.dos` the cone integral depends on (the kernel, the distance
/// mode and the buffers belong to the slice algorithm only): what the reference renders
/// with and what its cache key holds.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Integral {
    /// The cone aperture in radians.
    theta: f64,
    la: f64,
    ambient: f64,
    /// κ of the chromatic extinction ((1, 1, 1) when achromatic).
    kappa: DVec3,
    /// `light: directional`: whether `light_vector` is in world space, and the vector
    /// (towards the light); `None`: the viewer's light.
    light: Option<(bool, [f32; 3])>,
}

impl Integral {
    fn of(p: &vwb_render::params::ParamValues) -> Self {
        Self {
            theta: (p.float("theta_deg") as f64).to_radians(),
            la: p.float("la") as f64,
            ambient: p.float("ambient") as f64,
            kappa: super::extinction(p).unwrap_or(DVec3::ONE),
            light: (p.enumeration("light") == "directional")
                .then(|| (p.enumeration("light_space") == "world", p.vec3("light_vector"))),
        }
    }
}

/// The DOS parameters of the stack's enabled `shade.dos` and the twins of every other
/// enabled plugin.
struct Scene {
    integral: Integral,
    twins: Vec<Box<dyn CpuTwin>>,
    /// The unit direction towards a directional light in world space (`None`: the
    /// viewer's light, back along each eye ray).
    towards_light: Option<DVec3>,
}

fn scene(
    stack: &[PluginInstance],
    ctx: &CpuContext,
    view: &vwb_render::camera::View,
) -> Result<Scene, String> {
    let dos = stack
        .iter()
        .find(|i| i.enabled && i.plugin.id() == "shade.dos")
        .ok_or("the stack has no enabled shade.dos")?;
    let mut twins = Vec::new();
    for i in stack
        .iter()
        .filter(|i| i.enabled && i.plugin.id() != "shade.dos")
    {
        let mut t = i
            .configured()
            .cpu_twin(&i.params)
            .ok_or_else(|| format!("{} has no CPU twin", i.plugin.id()))?;
        t.prepare(ctx);
        twins.push(t);
    }
    let towards_light = super::light_direction(&dos.params, view)
        .map(|l| -l.as_dvec3())
        .filter(|l| l.is_finite() && l.length_squared() > 0.0)
        .map(DVec3::normalize);
    Ok(Scene {
        integral: Integral::of(&dos.params),
        twins,
        towards_light,
    })
}

impl Scene {
    /// Classified (σs, σt per world unit) at `pos`, and the shaded colour for the eye.
    fn optics(
        &self,
        ctx: &CpuContext,
        b: &VolumeBox,
        pos: DVec3,
        dir: DVec3,
        shade: bool,
    ) -> (DVec3, f64) {
        let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
        let mut s = CpuSample {
            pos,
            tex: (pos - lo) / (hi - lo),
            ray_dir: dir,
            ..Default::default()
        };
        vwb_render::shading::set_cut_gradient(None);
        if !self.twins.iter().all(|t| t.clip(&s)) {
            return (DVec3::ZERO, 0.0);
        }
        s.value = ctx.value(s.tex);
        for t in &self.twins {
            t.sample(ctx, &mut s);
        }
        s.color = DVec4::splat(s.value);
        for t in &self.twins {
            t.classify(ctx, &mut s);
        }
        if shade {
            let ctx = ctx.with_scalar_of(&self.twins);
            for t in &self.twins {
                t.shade(&ctx, &mut s);
            }
        }
        let a = if s.color.w.is_nan() {
            0.0
        } else {
            s.color.w.clamp(0.0, 1.0)
        };
        let sigma_t = -(1.0 - a).max(1.0e-300).ln() / b.voxel as f64;
        let rgb = s
            .color
            .truncate()
            .map(|c| if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0e6) });
        (rgb, sigma_t)
    }
}

/// Ray–box interval (t_in, t_out), `None` when the ray misses.
fn slab(origin: DVec3, dir: DVec3, lo: DVec3, hi: DVec3) -> Option<(f64, f64)> {
    let inv = dir.recip();
    let ta = (lo - origin) * inv;
    let tb = (hi - origin) * inv;
    let t_in = ta.min(tb).max_element().max(0.0);
    let t_out = ta.max(tb).min_element();
    (t_in.is_finite() && t_out.is_finite() && t_out > t_in).then_some((t_in, t_out))
}

/// A direction uniform in solid angle within angle θ of the unit `axis`.
fn cone_direction(axis: DVec3, theta: f64, rng: &mut Rng) -> DVec3 {
    let cos_t = 1.0 - rng.uniform() * (1.0 - theta.cos());
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = rng.uniform() * std::f64::consts::TAU;
    let (u, v) = axis.any_orthonormal_pair();
    (u * phi.cos() + v * phi.sin()) * sin_t + axis * cos_t
}

/// Renders the Monte-Carlo reference of the stack (which must hold an enabled
/// `shade.dos`). `cancel` stops it early with an error.
pub fn render_mc(
    volume: &Volume,
    stack: &[PluginInstance],
    settings: &FrameSettings,
    opts: &McOptions,
    cancel: Option<&AtomicBool>,
) -> Result<McImage, String> {
    let (w, h) = (settings.width, settings.height);
    if w == 0 || h == 0 || w > 4096 || h > 4096 {
        return Err(format!("image size {w}×{h} is out of range (1…4096)"));
    }
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(volume, &scalars);
    let view = settings.camera.view(w as f32 / h as f32);
    let sc = scene(stack, &ctx, &view)?;
    let inv_vp: DMat4 = (view.proj.as_dmat4() * view.view.as_dmat4()).inverse();
    let b = VolumeBox::new(volume.dims, volume.spacing);
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let voxel = b.voxel as f64;
    let replicas = opts.replicas.max(1);
    let per_replica = (opts.directions / replicas).max(1);
    let (he, hc) = (opts.eye_step * voxel, opts.cone_step * voxel);

    // T < 10⁻⁴ in every channel
    let tau_max = 9.3 / sc.integral.kappa.min_element().max(1.0e-9);
    let transmittance = |from: DVec3, dir: DVec3| -> DVec3 {
        let Some((_, t_out)) = slab(from, dir, lo, hi) else {
            return DVec3::ONE;
        };
        // midpoint rule with n equal steps of at most hc
        let n = (t_out / hc).ceil().max(1.0);
        let step = t_out / n;
        let mut tau = 0.0;
        for i in 0..n as usize {
            let (_, sigma) =
                sc.optics(&ctx, &b, from + dir * ((i as f64 + 0.5) * step), dir, false);
            tau += sigma * step;
            if tau > tau_max {
                return DVec3::ZERO;
            }
        }
        (-tau * sc.integral.kappa).exp()
    };

    let pixel = |x: u32, y: u32| -> ([f64; 4], [f64; 3]) {
        let uv = DVec2::new((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
        let ndc = DVec2::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
        let near = inv_vp * DVec4::new(ndc.x, ndc.y, 0.0, 1.0);
        let far = inv_vp * DVec4::new(ndc.x, ndc.y, 1.0, 1.0);
        let origin = near.truncate() / near.w;
        let dir = (far.truncate() / far.w - origin).normalize();
        let mut sums = vec![DVec4::ZERO; replicas];
        let Some((t_in, t_out)) = slab(origin, dir, lo, hi) else {
            return ([0.0; 4], [0.0; 3]);
        };
        let mut rngs: Vec<Rng> = (0..replicas)
            .map(|r| {
                Rng(mix(
                    opts.seed ^ mix(((y as u64) << 32 | x as u64) * 8 + r as u64)
                ))
            })
            .collect();
        let mut t_eye = 1.0;
        let mut t = t_in + 0.5 * he;
        while t < t_out && t_eye > 1.0e-4 {
            let pos = origin + dir * t;
            let (rgb, sigma) = sc.optics(&ctx, &b, pos, dir, true);
            let a = 1.0 - (-sigma * he).exp();
            if a > 0.0 {
                for (r, rng) in rngs.iter_mut().enumerate() {
                    let mut v = DVec3::ZERO;
                    for _ in 0..per_replica {
                        let axis = sc.towards_light.unwrap_or(-dir);
                        let omega = cone_direction(axis, sc.integral.theta, rng);
                        v += transmittance(pos, omega);
                    }
                    v /= per_replica as f64;
                    let c = rgb * (v * sc.integral.la + sc.integral.ambient) * a * t_eye;
                    sums[r] += c.extend(a * t_eye);
                }
            }
            t_eye *= 1.0 - a;
            t += he;
        }
        let k = replicas as f64;
        let mean = sums.iter().copied().sum::<DVec4>() / k;
        let se = if replicas > 1 {
            let var = sums
                .iter()
                .map(|s| (s.truncate() - mean.truncate()).powf(2.0))
                .sum::<DVec3>()
                / (k - 1.0);
            (var / k).map(f64::sqrt).to_array()
        } else {
            [0.0; 3]
        };
        (mean.to_array(), se)
    };

    let rows: Vec<Vec<([f64; 4], [f64; 3])>> = (0..h)
        .into_par_iter()
        .map(|y| {
            if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                return Err("cancelled".to_string());
            }
            Ok((0..w).map(|x| pixel(x, y)).collect())
        })
        .collect::<Result<_, _>>()?;
    let (pixels, std_error) = rows.into_iter().flatten().unzip();
    Ok(McImage {
        width: w,
        height: h,
        pixels,
        std_error,
    })
}
