//! Vector fields, streamline integration and 3D line integral convolution on the CPU,
//! in f64: the reference twin of the flow plugins (Rezk-Salama 2001 §9.3, eqs 9.9–9.10).
//!
//! Coordinates are continuous voxel coordinates: voxel (i, j, k) is centred at
//! (i, j, k), and a gridded field is interpolated trilinearly between voxel centres
//! (clamped at the border, as the GPU's clamp-to-edge sampler does). Lengths (the step
//! h, the half length L of the convolution) are in voxels.
//!
//! Choices the thesis leaves open, measured in docs/flow.md (`bash bench/flow.sh`):
//! - integrators: explicit Euler, midpoint RK2 and classical RK4, on normalised
//!   vectors (unit speed: the step is arc length) or magnitude-scaled ones;
//! - the convolution is the discrete normalised sum I(x₀) = Σ k(sᵢ) T(σ(sᵢ)) / Σ k(sᵢ)
//!   over the samples sᵢ = i·h, i = −n…n, n = ⌊L/h⌋, of the streamline through x₀ traced
//!   both ways, stopping where it leaves the volume or the field vanishes;
//! - kernels: box, tent (1 − |s|/L) and Gaussian (σ = L/3).

use glam::DVec3;
use rayon::prelude::*;

use crate::rng::Rng;

/// A steady vector field in voxel coordinates.
pub trait Field: Sync {
    /// The vector at `p`; `None` outside the field's domain.
    fn at(&self, p: DVec3) -> Option<DVec3>;
}

/// Rigid rotation about the z axis through `center`: v = (−(y − cy), x − cx, 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rotation {
    pub center: DVec3,
}

impl Field for Rotation {
    fn at(&self, p: DVec3) -> Option<DVec3> {
        let d = p - self.center;
        Some(DVec3::new(-d.y, d.x, 0.0))
    }
}

/// No flow anywhere: what the flow plugins integrate over a scalar volume (the LIC is
/// the noise; only the seed box is ever reached).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoFlow;

impl Field for NoFlow {
    fn at(&self, _p: DVec3) -> Option<DVec3> {
        Some(DVec3::ZERO)
    }
}

/// Arnold–Beltrami–Childress flow with period `period` voxels:
/// v = (A sin z′ + C cos y′, B sin x′ + A cos z′, C sin y′ + B cos x′), x′ = 2πx/period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Abc {
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub period: f64,
}

impl Default for Abc {
    /// The classic A = √3, B = √2, C = 1.
    fn default() -> Self {
        Self {
            a: 3f64.sqrt(),
            b: 2f64.sqrt(),
            c: 1.0,
            period: 32.0,
        }
    }
}

impl Field for Abc {
    fn at(&self, p: DVec3) -> Option<DVec3> {
        let q = p * (std::f64::consts::TAU / self.period);
        Some(DVec3::new(
            self.a * q.z.sin() + self.c * q.y.cos(),
            self.b * q.x.sin() + self.a * q.z.cos(),
            self.c * q.y.sin() + self.b * q.x.cos(),
        ))
    }
}

/// A tornado-like vortex about the vertical axis through `center`: a Rankine swirl
/// (solid rotation inside `core` voxels, decaying as 1/r outside), inflow towards the
/// axis and an updraft that grows with height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tornado {
    pub center: DVec3,
    pub core: f64,
    pub inflow: f64,
    pub updraft: f64,
}

impl Field for Tornado {
    fn at(&self, p: DVec3) -> Option<DVec3> {
        let d = p - self.center;
        let r = (d.x * d.x + d.y * d.y).sqrt();
        let swirl = if r < self.core {
            r / self.core
        } else {
            self.core / r.max(1e-12)
        };
        let (t, radial) = if r > 0.0 {
            (
                DVec3::new(-d.y / r, d.x / r, 0.0),
                DVec3::new(-d.x / r, -d.y / r, 0.0),
            )
        } else {
            (DVec3::ZERO, DVec3::ZERO)
        };
        let inflow = self.inflow * (r / self.core).min(1.0);
        Some(
            t * swirl
                + radial * inflow
                + DVec3::Z * self.updraft * (1.0 + d.z.max(0.0) / self.core),
        )
    }
}

/// The analytic fields a preset can name ([`AnalyticField`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum AnalyticKind {
    /// [`Rotation`] about the grid's vertical centre line.
    Rotation,
    /// [`Abc`] flow with the period of the grid's x side.
    Abc,
    /// A [`Tornado`] on the grid's centre line, its core a sixth of the x side.
    Tornado,
}

/// A generated vector volume: an analytic field sampled at the voxel centres of `size`
/// (3 components, voxels per unit time, unit spacing), for presets that need no data.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AnalyticField {
    pub field: AnalyticKind,
    pub size: [u32; 3],
}

impl AnalyticField {
    /// Sides from 2 to 512 voxels.
    pub fn check(&self) -> Result<(), String> {
        if self.size.iter().all(|s| (2..=512).contains(s)) {
            Ok(())
        } else {
            Err(format!(
                "an analytic field's size must be 2–512 voxels per side, got {:?}",
                self.size
            ))
        }
    }

    /// Its name as a volume name, e.g. `tornado_64x64x64`.
    pub fn name(&self) -> String {
        let [x, y, z] = self.size;
        format!("{}_{x}x{y}x{z}", format!("{:?}", self.field).to_lowercase())
    }

    /// The field itself, placed on the grid.
    pub fn field(&self) -> Box<dyn Field> {
        let s = DVec3::from(self.size.map(f64::from));
        let mid = s / 2.0 - DVec3::splat(0.5);
        match self.field {
            AnalyticKind::Rotation => Box::new(Rotation { center: mid }),
            AnalyticKind::Abc => Box::new(Abc {
                period: s.x,
                ..Default::default()
            }),
            AnalyticKind::Tornado => Box::new(Tornado {
                center: DVec3::new(mid.x, mid.y, s.z / 8.0),
                core: s.x / 6.0,
                inflow: 0.3,
                updraft: 0.4,
            }),
        }
    }

    /// The volume: the field sampled at the voxel centres.
    pub fn volume(&self) -> Result<crate::volume::Volume, String> {
        self.check()?;
        let g = GridField::sample(self.field().as_ref(), self.size);
        crate::volume::Volume::new(
            self.name(),
            self.size,
            3,
            [1.0; 3],
            crate::volume::VoxelData::F32(g.data),
        )
        .map_err(|e| e.to_string())
    }
}

/// A field on a grid: `components` (2 or 3; a missing w is 0) per voxel, x fastest,
/// interpolated trilinearly between voxel centres and clamped at the border.
#[derive(Debug, Clone, PartialEq)]
pub struct GridField {
    pub dims: [u32; 3],
    pub components: u32,
    pub data: Vec<f32>,
}

impl GridField {
    /// A field from a 2- or 3-component volume, in voxels per unit time: each
    /// component divided by the voxel size along its axis, so that streamlines in voxel
    /// coordinates follow the physical flow on anisotropic grids.
    pub fn from_volume(v: &crate::volume::Volume) -> Result<Self, String> {
        if !(2..=3).contains(&v.components) {
            return Err(format!(
                "{}: a vector field needs 2 or 3 components, the volume has {}",
                v.name, v.components
            ));
        }
        let c = v.components as usize;
        let data = v
            .components_f32()
            .iter()
            .enumerate()
            .map(|(i, x)| (*x as f64 / v.spacing[i % c]) as f32)
            .collect();
        Ok(Self {
            dims: v.dims,
            components: v.components,
            data,
        })
    }

    /// The analytic `field` sampled at the voxel centres of `dims`.
    pub fn sample(field: &dyn Field, dims: [u32; 3]) -> Self {
        let mut data = Vec::with_capacity(dims.iter().map(|&d| d as usize).product::<usize>() * 3);
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let v = field
                        .at(DVec3::new(x as f64, y as f64, z as f64))
                        .unwrap_or(DVec3::ZERO);
                    data.extend([v.x as f32, v.y as f32, v.z as f32]);
                }
            }
        }
        Self {
            dims,
            components: 3,
            data,
        }
    }

    fn voxel(&self, x: usize, y: usize, z: usize) -> DVec3 {
        let d = self.dims.map(|v| v as usize);
        let i = ((z * d[1] + y) * d[0] + x) * self.components as usize;
        let c = |k: usize| {
            if k < self.components as usize {
                self.data[i + k] as f64
            } else {
                0.0
            }
        };
        DVec3::new(c(0), c(1), c(2))
    }

    /// Whether `p` lies in the volume box (voxel centres ± ½).
    pub fn contains(&self, p: DVec3) -> bool {
        (0..3).all(|a| p[a] >= -0.5 && p[a] <= self.dims[a] as f64 - 0.5)
    }

    /// Scales the vectors to a top speed of 1 (the largest finite speed); false, with
    /// the field unchanged, where it vanishes everywhere.
    pub fn to_unit_speed(&mut self) -> bool {
        let c = self.components as usize;
        let top = self
            .data
            .chunks_exact(c)
            .map(|v| v.iter().map(|x| (*x as f64).powi(2)).sum::<f64>().sqrt())
            .filter(|s| s.is_finite())
            .fold(0.0f64, f64::max);
        if top <= 0.0 {
            return false;
        }
        for x in &mut self.data {
            *x = (*x as f64 / top) as f32;
        }
        true
    }

    /// The same field with its vectors in voxels of the grid `to` over the same box
    /// (each component times `to / dims` along its axis), still on its own grid: the
    /// values a shader that samples it at texture coordinates of `to` integrates in
    /// `to`'s voxels. [`OnGrid`] gives its positions in `to`'s voxels. A field already
    /// on `to` is returned as it is.
    pub fn in_voxels_of(mut self, to: [u32; 3]) -> Self {
        if to != self.dims {
            let c = self.components as usize;
            for (i, x) in self.data.iter_mut().enumerate() {
                let a = i % c;
                *x = (*x as f64 * to[a] as f64 / self.dims[a] as f64) as f32;
            }
        }
        self
    }
}

/// A field on its own grid read at voxel coordinates of the grid `to` over the same
/// box (a named volume input on another grid than the document's volume): `at(p)` is
/// the inner field at the same point of the box; on `to` itself, the inner field at
/// `p` exactly. The vectors are the inner field's (see [`GridField::in_voxels_of`]).
#[derive(Debug, Clone, Copy)]
pub struct OnGrid<'a> {
    pub inner: &'a GridField,
    pub to: [u32; 3],
}

impl Field for OnGrid<'_> {
    fn at(&self, p: DVec3) -> Option<DVec3> {
        if self.inner.dims == self.to {
            return self.inner.at(p);
        }
        let scale = DVec3::from(std::array::from_fn::<f64, 3, _>(|a| {
            self.inner.dims[a] as f64 / self.to[a] as f64
        }));
        self.inner
            .at((p + DVec3::splat(0.5)) * scale - DVec3::splat(0.5))
    }
}

impl Field for GridField {
    fn at(&self, p: DVec3) -> Option<DVec3> {
        if !self.contains(p) {
            return None;
        }
        let mut i0 = [0usize; 3];
        let mut i1 = [0usize; 3];
        let mut t = [0.0f64; 3];
        for a in 0..3 {
            let n = self.dims[a].max(1) as f64;
            let x = p[a].clamp(0.0, n - 1.0);
            let f = x.floor();
            i0[a] = f as usize;
            i1[a] = (i0[a] + 1).min(self.dims[a].max(1) as usize - 1);
            t[a] = x - f;
        }
        let at = |x: usize, y: usize, z: usize| self.voxel(x, y, z);
        let c00 = at(i0[0], i0[1], i0[2]).lerp(at(i1[0], i0[1], i0[2]), t[0]);
        let c10 = at(i0[0], i1[1], i0[2]).lerp(at(i1[0], i1[1], i0[2]), t[0]);
        let c01 = at(i0[0], i0[1], i1[2]).lerp(at(i1[0], i0[1], i1[2]), t[0]);
        let c11 = at(i0[0], i1[1], i1[2]).lerp(at(i1[0], i1[1], i1[2]), t[0]);
        Some(c00.lerp(c10, t[1]).lerp(c01.lerp(c11, t[1]), t[2]))
    }
}

/// A field seen on a grid `factor` times finer (LIC at a noise frequency above the
/// field's resolution): `at(p)` is the inner field at `p / factor`, with vectors scaled
/// by `factor` so that streamlines keep their shape in the finer coordinates.
#[derive(Debug, Clone, Copy)]
pub struct Scaled<'a, F: Field> {
    pub inner: &'a F,
    pub factor: f64,
}

impl<F: Field> Field for Scaled<'_, F> {
    fn at(&self, p: DVec3) -> Option<DVec3> {
        // voxel centres: fine (i + ½)/f − ½ lands on the coarse grid's centres
        let q = (p + DVec3::splat(0.5)) / self.factor - DVec3::splat(0.5);
        self.inner.at(q).map(|v| v * self.factor)
    }
}

/// A streamline integrator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Integrator {
    Euler,
    Rk2,
    Rk4,
}

impl Integrator {
    pub const ALL: [Integrator; 3] = [Integrator::Euler, Integrator::Rk2, Integrator::Rk4];
    /// The flow plugins' `integrator` options, in the order of [`Integrator::ALL`].
    pub const KEYS: [&'static str; 3] = ["euler", "rk2", "rk4"];
    /// The integrator an `integrator` option names (RK4 for anything else).
    pub fn from_key(key: &str) -> Self {
        Self::KEYS
            .iter()
            .position(|k| *k == key)
            .map_or(Integrator::Rk4, |i| Self::ALL[i])
    }
    /// The region a hook file written for every integrator leaves out for this one:
    /// such a file puts the second stage in an `rk2` region and the last two, inside it,
    /// in an `rk4` region, so that only the chosen integrator's stages are compiled in
    /// (a CPU device runs both sides of a branch on a uniform).
    pub fn region_left_out(self) -> Option<&'static str> {
        match self {
            Integrator::Euler => Some("rk2"),
            Integrator::Rk2 => Some("rk4"),
            Integrator::Rk4 => None,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Integrator::Euler => "Euler",
            Integrator::Rk2 => "RK2",
            Integrator::Rk4 => "RK4",
        }
    }
}

/// How the field's vectors drive the integration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Speed {
    /// Unit speed: the step h is arc length (the usual choice for LIC).
    Normalized,
    /// The vectors as they are: the step is h·|v|.
    Magnitude,
}

fn velocity(field: &dyn Field, p: DVec3, speed: Speed) -> Option<DVec3> {
    let v = field.at(p)?;
    match speed {
        Speed::Magnitude => Some(v),
        Speed::Normalized => {
            let l = v.length();
            (l > 1e-12 && l.is_finite()).then(|| v / l)
        }
    }
}

/// One step of `h` (negative: backwards) from `p`; `None` where the field is undefined or
/// vanishes (normalised speed).
pub fn step(
    field: &dyn Field,
    p: DVec3,
    h: f64,
    integrator: Integrator,
    speed: Speed,
) -> Option<DVec3> {
    let v = |q: DVec3| velocity(field, q, speed);
    Some(match integrator {
        Integrator::Euler => p + v(p)? * h,
        Integrator::Rk2 => {
            let k1 = v(p)?;
            p + v(p + k1 * (h / 2.0))? * h
        }
        Integrator::Rk4 => {
            let k1 = v(p)?;
            let k2 = v(p + k1 * (h / 2.0))?;
            let k3 = v(p + k2 * (h / 2.0))?;
            let k4 = v(p + k3 * h)?;
            p + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0)
        }
    })
}

/// `n` steps of `h` from `seed` (fewer where the line leaves the field), the seed first.
pub fn streamline(
    field: &dyn Field,
    seed: DVec3,
    h: f64,
    n: usize,
    integrator: Integrator,
    speed: Speed,
) -> Vec<DVec3> {
    let mut line = vec![seed];
    let mut p = seed;
    for _ in 0..n {
        match step(field, p, h, integrator, speed) {
            Some(q) => {
                line.push(q);
                p = q;
            }
            None => break,
        }
    }
    line
}

/// Distance off the exact streamline after one turn of [`Rotation`] about its centre at
/// `radius` voxels, with unit speed and step `h` (⌈2πr/h⌉ steps): | |p − c| − r |.
pub fn rotation_drift(
    field: &dyn Field,
    center: DVec3,
    radius: f64,
    h: f64,
    integrator: Integrator,
    steps: usize,
) -> f64 {
    let seed = center + DVec3::new(radius, 0.0, 0.0);
    let line = streamline(field, seed, h, steps, integrator, Speed::Normalized);
    let end = *line.last().expect("the seed");
    let d = end - center;
    ((d.x * d.x + d.y * d.y).sqrt() - radius).abs()
}

/// The convolution kernel of LIC.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kernel {
    Box,
    Tent,
    Gaussian,
    /// The animation kernel of Cabral and Leedom (1993): a Hann window times a ripple
    /// of `ripples` periods per half length, shifted by `phase` (radians) along the
    /// streamline, ¼·(1 + cos πx)·(1 + cos(2π·ripples·x − phase)) with x = s/L signed
    /// (downstream positive). Advancing the phase moves the ripple downstream, so a
    /// sequence of phases animates the flow over one noise.
    Periodic {
        ripples: f64,
        phase: f64,
    },
}

impl Kernel {
    /// The weight at signed arc length `s` (downstream positive) of a kernel of half
    /// length `l`.
    pub fn weight(self, s: f64, l: f64) -> f64 {
        let signed = s / l.max(1e-12);
        let x = signed.abs();
        if x > 1.0 {
            return 0.0;
        }
        match self {
            Kernel::Box => 1.0,
            Kernel::Tent => 1.0 - x,
            // σ = L/3
            Kernel::Gaussian => (-4.5 * x * x).exp(),
            Kernel::Periodic { ripples, phase } => {
                0.25 * (1.0 + (std::f64::consts::PI * x).cos())
                    * (1.0 + (std::f64::consts::TAU * ripples * signed - phase).cos())
            }
        }
    }
}

/// A noise volume T for LIC.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Noise {
    /// Uniform in [0, 1].
    White,
    /// Normal, mean ½, standard deviation ⅙, clamped to [0, 1].
    Gaussian,
    /// Sparse spots: a voxel is 1 with probability `density`, else 0.
    Sparse { density: f64 },
}

/// Noise on the voxel grid of `dims`, one value per voxel, seeded.
pub fn noise_volume(dims: [u32; 3], noise: Noise, seed: u64) -> GridField {
    let n: usize = dims.iter().map(|&d| d as usize).product();
    let data = (0..n)
        .into_par_iter()
        .map(|i| {
            let mut r = Rng::at(seed, i as u64);
            let v = match noise {
                Noise::White => r.uniform(),
                Noise::Gaussian => (0.5 + r.normal() / 6.0).clamp(0.0, 1.0),
                Noise::Sparse { density } => f64::from(u8::from(r.uniform() < density)),
            };
            v as f32
        })
        .collect();
    GridField {
        dims,
        components: 1,
        data,
    }
}

/// Parameters of the LIC integral.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LicParams {
    pub kernel: Kernel,
    /// Half length L of the convolution, voxels.
    pub length: f64,
    /// Step h, voxels.
    pub step: f64,
    pub integrator: Integrator,
    pub speed: Speed,
}

impl Default for LicParams {
    /// Our defaults: a tent of half length 8 voxels, RK4 at half a voxel, unit speed.
    fn default() -> Self {
        Self {
            kernel: Kernel::Tent,
            length: 8.0,
            step: 0.5,
            integrator: Integrator::Rk4,
            speed: Speed::Normalized,
        }
    }
}

/// The scalar noise value (first component) at `p`, trilinear.
fn noise_at(noise: &GridField, p: DVec3) -> Option<f64> {
    noise.at(p).map(|v| v.x)
}

/// I(x₀) at one point: the kernel-weighted mean of the noise along the streamline
/// through `x0` (module docs).
pub fn lic_at(field: &dyn Field, noise: &GridField, x0: DVec3, p: &LicParams) -> f64 {
    let n = (p.length / p.step).floor() as usize;
    let Some(t0) = noise_at(noise, x0) else {
        return 0.0;
    };
    let w0 = p.kernel.weight(0.0, p.length);
    let (mut sum, mut wsum) = (w0 * t0, w0);
    for dir in [1.0, -1.0] {
        let mut q = x0;
        for i in 1..=n {
            let Some(next) = step(field, q, dir * p.step, p.integrator, p.speed) else {
                break;
            };
            q = next;
            let Some(t) = noise_at(noise, q) else { break };
            let w = p.kernel.weight(dir * i as f64 * p.step, p.length);
            sum += w * t;
            wsum += w;
        }
    }
    sum / wsum
}

/// The centre of voxel `i` (x fastest) of a grid of `dims`, in voxel coordinates.
pub fn voxel_centre(i: usize, dims: [u32; 3]) -> DVec3 {
    let (nx, ny) = (dims[0] as usize, dims[1] as usize);
    DVec3::new(
        (i % nx) as f64,
        ((i / nx) % ny) as f64,
        (i / (nx * ny)) as f64,
    )
}

/// The LIC volume of `field` over `noise`'s grid: I at every voxel centre, x fastest.
pub fn lic_volume(field: &dyn Field, noise: &GridField, p: &LicParams) -> Vec<f32> {
    let d = noise.dims;
    let n: usize = d.iter().map(|&v| v as usize).product();
    (0..n)
        .into_par_iter()
        .map(|i| lic_at(field, noise, voxel_centre(i, d), p) as f32)
        .collect()
}

/// The arrival time of voxels that the flow from the seed never reaches (within the
/// path length, or because it stagnates or leaves the volume first), as stored in the
/// arrival volume (an f32 the GPU writes and interpolates without overflow).
pub const NEVER: f32 = 3.0e38;

/// The seed region of an arrival-time volume: a box in texture coordinates ([0, 1]³
/// over the volume box), e.g. a flat box across the flow (the thesis's start mesh).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeedBox {
    pub min: DVec3,
    pub max: DVec3,
}

impl SeedBox {
    pub fn contains(&self, t: DVec3) -> bool {
        (0..3).all(|a| t[a] >= self.min[a] && t[a] <= self.max[a])
    }

    /// Where the segment from `a` to `b` (texture coordinates, `a` outside) first
    /// enters the box, as a fraction of the segment in [0, 1]; `None` if it does not.
    /// The slab method, axis by axis; the GPU's `arrival_entry` mirrors it.
    pub fn entry(&self, a: DVec3, b: DVec3) -> Option<f64> {
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for k in 0..3 {
            let d = b[k] - a[k];
            if d.abs() < 1e-12 {
                if a[k] < self.min[k] || a[k] > self.max[k] {
                    return None;
                }
                continue;
            }
            let t0 = (self.min[k] - a[k]) / d;
            let t1 = (self.max[k] - a[k]) / d;
            lo = lo.max(t0.min(t1));
            hi = hi.min(t0.max(t1));
        }
        (lo <= hi).then_some(lo)
    }
}

/// Parameters of the arrival-time volume.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArrivalParams {
    /// Path length per step, voxels: each step's time is `step / |v|`.
    pub step: f64,
    /// The longest path traced back from a voxel, voxels.
    pub max_length: f64,
    pub integrator: Integrator,
}

impl Default for ArrivalParams {
    fn default() -> Self {
        Self {
            step: 0.5,
            max_length: 256.0,
            integrator: Integrator::Rk4,
        }
    }
}

/// The arrival time at `p` (voxel coordinates of a grid of `dims`) of matter released
/// from `seed` at t = 0 and carried by `field` (Rezk-Salama's time surfaces, §9.3, as
/// one volume: the surface at time t is its level set t). Traced backwards in time from
/// `p` until the path enters the seed, with steps of `dt = step / |v(q)|` (a path
/// length of about `step` each) and the integrator on the vectors as they are; the
/// entry is interpolated along the last step. Time is in the field's units (voxels
/// per unit time; `flow.arrival` scales the field to a top speed of 1, so its times
/// are in voxels at the top speed). [`f64::INFINITY`] where the path leaves the
/// volume, stagnates (|v| < 1e-6) or exceeds `max_length` first.
pub fn arrival_at(
    field: &dyn Field,
    dims: [u32; 3],
    seed: &SeedBox,
    p: DVec3,
    a: &ArrivalParams,
) -> f64 {
    let d = DVec3::from(dims.map(f64::from));
    let tex = |q: DVec3| (q + DVec3::splat(0.5)) / d;
    if seed.contains(tex(p)) {
        return 0.0;
    }
    let n = (a.max_length / a.step).ceil() as usize;
    let (mut t, mut q) = (0.0, p);
    for _ in 0..n {
        let Some(v) = field.at(q) else {
            return f64::INFINITY;
        };
        let speed = v.length();
        if !(speed >= 1e-6 && speed.is_finite()) {
            return f64::INFINITY;
        }
        let dt = a.step / speed;
        let Some(next) = step(field, q, -dt, a.integrator, Speed::Magnitude) else {
            return f64::INFINITY;
        };
        if let Some(f) = seed.entry(tex(q), tex(next)) {
            return t + f * dt;
        }
        t += dt;
        q = next;
    }
    f64::INFINITY
}

/// The arrival time at every voxel centre of `dims`, x fastest, as f32 with [`NEVER`]
/// for the voxels never reached.
pub fn arrival_volume(
    field: &dyn Field,
    dims: [u32; 3],
    seed: &SeedBox,
    a: &ArrivalParams,
) -> Vec<f32> {
    let n: usize = dims.iter().map(|&v| v as usize).product();
    (0..n)
        .into_par_iter()
        .map(|i| {
            let t = arrival_at(field, dims, seed, voxel_centre(i, dims), a);
            if t.is_finite() {
                (t as f32).min(NEVER)
            } else {
                NEVER
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrival_in_a_uniform_flow_is_the_distance_from_the_seed() {
        // v = (2, 0, 0) voxels per unit time from a slab at x ∈ [0, 0.1] of 40 voxels:
        // the slab's far face is at x = 3.5 voxels, so voxel x arrives at (x − 3.5) / 2
        struct Uniform;
        impl Field for Uniform {
            fn at(&self, _p: DVec3) -> Option<DVec3> {
                Some(DVec3::new(2.0, 0.0, 0.0))
            }
        }
        let dims = [40, 4, 4];
        let seed = SeedBox {
            min: DVec3::ZERO,
            max: DVec3::new(0.1, 1.0, 1.0),
        };
        for integrator in Integrator::ALL {
            let a = ArrivalParams {
                integrator,
                ..Default::default()
            };
            for x in [0u32, 3, 4, 10, 39] {
                let t = arrival_at(&Uniform, dims, &seed, DVec3::new(x as f64, 1.0, 1.0), &a);
                let want = ((x as f64 - 3.5) / 2.0).max(0.0);
                assert!(
                    (t - want).abs() < 1e-9,
                    "{integrator:?} x {x}: {t} vs {want}"
                );
            }
        }
        // upstream of the seed nothing arrives; a short path does not reach
        let v = arrival_volume(&Uniform, dims, &seed, &ArrivalParams::default());
        assert_eq!(v[0], 0.0);
        let short = ArrivalParams {
            max_length: 4.0,
            ..Default::default()
        };
        assert!(
            arrival_at(&Uniform, dims, &seed, DVec3::new(20.0, 1.0, 1.0), &short).is_infinite()
        );
        assert_eq!(
            arrival_volume(&Uniform, dims, &seed, &short)[20 + 40 * (1 + 4)],
            NEVER
        );
    }

    #[test]
    fn arrival_on_the_rotation_is_the_angle_over_the_angular_speed() {
        // v = (−y, x, 0) about c: angular speed 1, so the arrival from a thin seed
        // on the ray θ = 0 is θ (any radius); RK4 at half a voxel within 1e-3
        let c = DVec3::new(32.0, 32.0, 2.0);
        let field = Rotation { center: c };
        let dims = [64, 64, 4];
        let seed = SeedBox {
            min: DVec3::new(32.5 / 64.0, 32.0 / 64.0, 0.0),
            max: DVec3::new(1.0, 33.0 / 64.0, 1.0),
        };
        for (r, theta) in [(10.0f64, 1.0f64), (20.0, 2.5), (25.0, 4.0)] {
            let p = c + DVec3::new(r * theta.cos(), r * theta.sin(), 0.0);
            let t = arrival_at(&field, dims, &seed, p, &ArrivalParams::default());
            // the seed spans y ∈ [31.5, 32.5] voxels: the path enters its upper face
            let want = theta - (0.5 / r).asin();
            assert!((t - want).abs() < 2e-2, "r {r} θ {theta}: {t} vs {want}");
        }
    }

    #[test]
    fn rk4_follows_the_rotation_and_euler_spirals_out() {
        let c = DVec3::new(32.0, 32.0, 8.0);
        let field = Rotation { center: c };
        let steps = |h: f64| (std::f64::consts::TAU * 8.0 / h).ceil() as usize;
        let rk4 = rotation_drift(&field, c, 8.0, 0.5, Integrator::Rk4, steps(0.5));
        let rk2 = rotation_drift(&field, c, 8.0, 0.5, Integrator::Rk2, steps(0.5));
        let euler = rotation_drift(&field, c, 8.0, 0.5, Integrator::Euler, steps(0.5));
        assert!(rk4 < 1e-5, "{rk4}");
        assert!(rk2 < euler && rk4 < rk2, "{euler} {rk2} {rk4}");
        // Euler with unit speed: r² grows by h² per step
        let n = steps(0.5) as f64;
        let expect = (64.0 + n * 0.25).sqrt() - 8.0;
        assert!((euler - expect).abs() < 1e-9, "{euler} vs {expect}");
        // a linear field is interpolated exactly by a grid
        let grid = GridField::sample(&field, [64, 64, 16]);
        let g = rotation_drift(&grid, c, 8.0, 0.5, Integrator::Rk4, steps(0.5));
        assert!((g - rk4).abs() < 1e-4, "{g} vs {rk4}");
    }

    #[test]
    fn kernels_and_noise() {
        for k in [Kernel::Box, Kernel::Tent, Kernel::Gaussian] {
            assert_eq!(k.weight(0.0, 4.0), 1.0);
            assert_eq!(k.weight(4.5, 4.0), 0.0);
            assert!(k.weight(2.0, 4.0) <= 1.0 && k.weight(2.0, 4.0) > 0.0);
        }
        // the periodic kernel: 1 at the centre with phase 0, 0 at ±L, within [0, 1];
        // symmetric at phase 0; a phase advance of 2π·r·δ moves the ripple δ (in units
        // of L) downstream under the fixed window
        let periodic = |phase: f64| Kernel::Periodic {
            ripples: 2.0,
            phase,
        };
        assert!((periodic(0.0).weight(0.0, 4.0) - 1.0).abs() < 1e-12);
        assert!(periodic(0.7).weight(4.0, 4.0).abs() < 1e-12);
        let window = |x: f64| 0.5 * (1.0 + (std::f64::consts::PI * x).cos());
        for i in -20..=20 {
            let x = i as f64 / 20.0;
            let w = periodic(1.3).weight(4.0 * x, 4.0);
            assert!((0.0..=1.0).contains(&w), "{x}: {w}");
            assert!(
                (periodic(0.0).weight(4.0 * x, 4.0) - periodic(0.0).weight(-4.0 * x, 4.0)).abs()
                    < 1e-12
            );
            let delta = 0.1;
            let shifted =
                periodic(std::f64::consts::TAU * 2.0 * delta).weight(4.0 * x, 4.0) / window(x);
            let ripple = periodic(0.0).weight(4.0 * (x - delta), 4.0) / window(x - delta);
            if (x - delta).abs() < 1.0 && window(x) > 1e-6 && window(x - delta) > 1e-6 {
                assert!(
                    (shifted - ripple).abs() < 1e-9,
                    "{x}: {shifted} vs {ripple}"
                );
            }
        }
        let sparse = noise_volume([32; 3], Noise::Sparse { density: 0.02 }, 5);
        let share =
            sparse.data.iter().filter(|v| **v > 0.5).count() as f64 / sparse.data.len() as f64;
        assert!((share - 0.02).abs() < 0.003, "{share}");
        assert_eq!(
            noise_volume([8; 3], Noise::White, 1),
            noise_volume([8; 3], Noise::White, 1)
        );
    }

    /// LIC smears the noise along the flow: neighbours along a streamline of the
    /// rotation are far more alike than neighbours across it; a box kernel of L = 0 is
    /// the noise itself.
    #[test]
    fn lic_correlates_along_the_flow() {
        let dims = [48, 48, 8];
        let c = DVec3::new(23.5, 23.5, 3.5);
        let field = Rotation { center: c };
        let noise = noise_volume(dims, Noise::White, 3);
        let p = LicParams::default();
        let lic = lic_volume(&field, &noise, &p);
        let at = |x: usize, y: usize| lic[(4 * 48 + y) * 48 + x] as f64;
        // on the ray y = 23 (x from 30 to 44): along the flow is ±y, across is ±x
        let (mut along, mut across) = (0.0, 0.0);
        for x in 30..44 {
            along += (at(x, 23) - at(x, 24)).powi(2);
            across += (at(x, 23) - at(x + 1, 23)).powi(2);
        }
        assert!(along * 4.0 < across, "along {along} across {across}");
        let none = lic_volume(
            &field,
            &noise,
            &LicParams {
                length: 0.1,
                kernel: Kernel::Box,
                ..p
            },
        );
        assert_eq!(none, noise.data);
    }
}
