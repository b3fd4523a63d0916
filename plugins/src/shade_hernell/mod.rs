//! `shade.hernell`: global light by local piecewise integration (Hernell, Ljung &
//! Ynnerman 2008, "Interactive global light propagation in direct volume rendering
//! using local piecewise integration"), as three volume passes and a shade hook.
//!
//! - (A1) `alpha_lp`, eq 6: per voxel, the opacity of the segment of `segment` voxels
//!   towards the light, α_lp = 1 − Π(1 − α_i), with α_i the stack's classified
//!   opacity (per Δs0) at s0 + i·Δs0, i = 1..N. Clipped matter has α = 0
//!   (`stack_classify` runs the clip hooks), so it casts no light shadow.
//! - (A2) `alpha_g`, eq 7: the global opacity in the sparse shadow volume
//!   representation (SVR, 1:1 to 1:8 of the data resolution, structural), composed
//!   from the local pieces sampled (trilinearly) every segment length along the ray.
//! - (B) `light_volume`, eqs 8, 11 and 13: the direct light
//!   I_d = I0·(1 − α_g(s1))·(1 − α_lp(s0)) and first-order in-scattering: over
//!   directions ω_j, (1/(M+1))·Σ_m I_d(s_m)·Π_{0<i<m}(1 − α(s_i)), M = R_Ω in voxels,
//!   refined progressively, the light's own direction first, then the vertices of a
//!   subdivided tetrahedron, octahedron or icosahedron, each blended in by eq 13
//!   (I = I_new/j + (1 − 1/j)·I_old). Without scattering, I_d.
//! - (C) the shade hook, eq 12: rgb·(I_bias + (1 − I_bias)·I)·light colour; one
//!   lookup per sample.
//!
//! Choices where the paper is vague (docs/hernell.md): samples one voxel apart from
//! s0 + Δs0 on (a voxel does not shadow itself; consecutive segments tile the ray,
//! and an axis-aligned light samples voxel centres); eq 11's
//! sum over m is normalised by M + 1 so that an empty volume gets I = I0 and the
//! isotropic phase weights are 1/J; outside the box the light arrives unattenuated;
//! a point light ends the light ray at the light. The light is fixed to the volume
//! (world space), so camera moves rerun nothing. Light colour multiplies the
//! (achromatic) light field: extinction is from the TF's α, so the field is linear in
//! the light's colour. `mode = exact` integrates every voxel's whole path to the
//! light (no pieces, no SVR): the paper's reference.
//!
//! - Flat blocking (paper §4 after Ljung et al. 2004; `blocking: 16³`): a (block)
//!   pass classifies each 16³ block: empty when no voxel of it or of its one-voxel
//!   apron has α > 0 (the light passes skip it; eq 7's rays advance over it to the
//!   next non-empty block, Fig. 4), else the coarsest level of detail l ∈ 0…4 whose
//!   RMS error of α (TF domain: cells of 2^l voxels holding their mean) is at most
//!   `tolerance`. (A1) and (B) compute the light once per cell, at its centre, and
//!   lookups of α_lp and I stay inside their block (clamped, as the paper does after
//!   Ljung et al. 2006); α_g keeps its regular SVR grid, as the paper requires.
//!   Choice: the data reduction (voxels over stored cells, [`Blocks::reduction`]) is
//!   what the tolerance gives, measured, not a target the selection meets. The
//!   storage is emulated: the light volumes stay one texel per voxel (each cell's
//!   texels hold its value), so the GPU saves the empty blocks' work and the error is
//!   that of the reduced data, but not the memory or the per-cell work of a packed
//!   structure.

use std::sync::Arc;

use glam::{DVec3, DVec4};
use rayon::prelude::*;
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, PassOutputs, Plugin, PluginError,
    ResourceDecl, ResourceKind, ShaderSource, StackClassify, Statistic,
    Transparency, VolumePassDecl, trilinear_grid, Volumes,
};

#[cfg(test)]
mod tests;

/// SVR ratios (structural).
pub const SVR: [&str; 4] = ["1:1", "1:2", "1:4", "1:8"];
pub const SPHERES: [&str; 3] = ["tetrahedron", "octahedron", "icosahedron"];
/// Width of the direction table.
pub const MAX_DIRECTIONS: usize = 64;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hernell {
    /// SVR resolution relative to the volume (1, 1/2, 1/4, 1/8).
    pub svr: f32,
    /// Flat blocking of the light passes (16³ blocks).
    pub blocking: bool,
    /// `mode: exact`: the whole path to the light, so no pass depends on the segment
    /// length (editing it reruns nothing).
    pub exact: bool,
}

impl Default for Hernell {
    fn default() -> Self {
        Self {
            svr: 0.5,
            blocking: false,
            exact: false,
        }
    }
}

/// Side of a flat-blocking block in voxels.
pub const BLOCK: usize = 16;

fn svr_scale(params: &ParamValues) -> f32 {
    match params.enumeration("svr") {
        "1:1" => 1.0,
        "1:4" => 0.25,
        "1:8" => 0.125,
        _ => 0.5,
    }
}

/// The scattering directions after the light's own: the unit vertices of the chosen
/// polyhedron, its edges split `subdivisions` times (tetrahedron 4/10, octahedron
/// 6/18, icosahedron 12/42).
pub fn sphere_directions(sphere: &str, subdivisions: u32) -> Vec<DVec3> {
    let (mut verts, mut faces): (Vec<DVec3>, Vec<[usize; 3]>) = match sphere {
        "tetrahedron" => (
            vec![
                DVec3::new(1.0, 1.0, 1.0),
                DVec3::new(1.0, -1.0, -1.0),
                DVec3::new(-1.0, 1.0, -1.0),
                DVec3::new(-1.0, -1.0, 1.0),
            ],
            vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
        ),
        "octahedron" => (
            vec![
                DVec3::X,
                DVec3::NEG_X,
                DVec3::Y,
                DVec3::NEG_Y,
                DVec3::Z,
                DVec3::NEG_Z,
            ],
            vec![
                [0, 2, 4],
                [2, 1, 4],
                [1, 3, 4],
                [3, 0, 4],
                [2, 0, 5],
                [1, 2, 5],
                [3, 1, 5],
                [0, 3, 5],
            ],
        ),
        _ => {
            let t = (1.0 + 5f64.sqrt()) / 2.0;
            (
                vec![
                    DVec3::new(-1.0, t, 0.0),
                    DVec3::new(1.0, t, 0.0),
                    DVec3::new(-1.0, -t, 0.0),
                    DVec3::new(1.0, -t, 0.0),
                    DVec3::new(0.0, -1.0, t),
                    DVec3::new(0.0, 1.0, t),
                    DVec3::new(0.0, -1.0, -t),
                    DVec3::new(0.0, 1.0, -t),
                    DVec3::new(t, 0.0, -1.0),
                    DVec3::new(t, 0.0, 1.0),
                    DVec3::new(-t, 0.0, -1.0),
                    DVec3::new(-t, 0.0, 1.0),
                ],
                vec![
                    [0, 11, 5],
                    [0, 5, 1],
                    [0, 1, 7],
                    [0, 7, 10],
                    [0, 10, 11],
                    [1, 5, 9],
                    [5, 11, 4],
                    [11, 10, 2],
                    [10, 7, 6],
                    [7, 1, 8],
                    [3, 9, 4],
                    [3, 4, 2],
                    [3, 2, 6],
                    [3, 6, 8],
                    [3, 8, 9],
                    [4, 9, 5],
                    [2, 4, 11],
                    [6, 2, 10],
                    [8, 6, 7],
                    [9, 8, 1],
                ],
            )
        }
    };
    for v in &mut verts {
        *v = v.normalize();
    }
    for _ in 0..subdivisions {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::new();
        let mut midpoint = |a: usize, b: usize, verts: &mut Vec<DVec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                verts.push((verts[a] + verts[b]).normalize());
                verts.len() - 1
            })
        };
        for [a, b, c] in faces {
            let ab = midpoint(a, b, &mut verts);
            let bc = midpoint(b, c, &mut verts);
            let ca = midpoint(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    verts
}

/// The directions of the in-scattering steps after the light's own, as the GPU
/// table holds them (f32).
fn directions(params: &ParamValues) -> Vec<DVec3> {
    let mut d = sphere_directions(params.enumeration("sphere"), params.int("subdivisions").clamp(0, 1) as u32);
    d.truncate(MAX_DIRECTIONS - 1);
    d.into_iter().map(|v| v.as_vec3().as_dvec3()).collect()
}

/// Refinement steps of the light pass: the light's direction plus the sphere's, or
/// one without scattering.
fn light_steps(params: &ParamValues) -> u32 {
    if params.boolean("scattering") {
        1 + directions(params).len() as u32
    } else {
        1
    }
}

const LIGHT_DEPS: [&str; 7] = [
    "light_type",
    "light",
    "segment",
    "mode",
    "intensity",
    "scattering",
    "radius",
];

impl Plugin for Hernell {
    fn id(&self) -> &'static str {
        "shade.hernell"
    }
    fn display_name(&self) -> &'static str {
        "Global light (Hernell 2008)"
    }
    fn description(&self) -> &'static str {
        "Shadows and first-order scattering from local piecewise integration; light passes rerun only when the light, TF or clipping change"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::enumeration("light_type", "Light", &["directional", "point"], 0),
            ParamSpec::vec3("light", "Light direction / position", -4.0, 4.0, [0.6, 0.7, 0.4])
                .with_doc("world space, fixed to the volume (box centred at 0, longest side 1): directional: towards the light; point: its position (inside the box is allowed)"),
            ParamSpec::color("light_color", "Light colour", [1.0, 1.0, 1.0, 1.0]),
            ParamSpec::float("intensity", "Intensity I0", 0.0, 4.0, 1.0),
            ParamSpec::float("bias", "Minimum light I_bias", 0.0, 1.0, 0.1)
                .with_doc("eq 12: I_final = I_bias + (1 − I_bias)·I_s"),
            ParamSpec::int("segment", "Segment length (voxels)", 1, 64, 8)
                .with_doc("local piecewise integration length (eq 6); the paper finds 8–16 best"),
            ParamSpec::enumeration("svr", "Shadow volume resolution", &SVR, 1)
                .structural()
                .with_doc("resolution of the global opacity α_g relative to the data (§3.2)"),
            ParamSpec::enumeration("mode", "Integration", &["piecewise", "exact"], 0)
                .structural()
                .with_doc("exact: every voxel's whole path to the light (the reference, ≈ 10× slower in the paper)"),
            ParamSpec::boolean("scattering", "First-order scattering", true)
                .with_doc("off: I = I_d (eq 8); on: in-scattering over the sphere (eq 11), refined progressively"),
            ParamSpec::enumeration("sphere", "Scattering directions", &SPHERES, 1)
                .with_doc("vertices of the subdivided polyhedron, after the light's own direction"),
            ParamSpec::int("subdivisions", "Subdivisions", 0, 1, 0),
            ParamSpec::float("radius", "Scattering radius R_Ω (voxels)", 0.0, 32.0, 8.0),
            ParamSpec::enumeration("blocking", "Flat blocking", &["off", "16³"], 0)
                .structural()
                .with_doc("§4: 16³ blocks at a level of detail each, empty blocks skipped by the light passes"),
            ParamSpec::float("tolerance", "Block tolerance (RMS α)", 0.0, 0.5, 0.02)
                .shown_when("blocking", "16³")
                .with_doc("a block takes the coarsest level whose RMS error of the classified α is at most this; 0: only empty blocks are reduced"),
        ]
    }
    fn shader(&self) -> ShaderSource {
        const FILE: &str = "plugins/src/shade_hernell/hernell.wgsl";
        const SOURCE: &str = include_str!("hernell.wgsl");
        if self.blocking {
            ShaderSource::new_static(FILE, SOURCE)
        } else {
            // no `blocks` target, no block pass
            ShaderSource::without_region(
                FILE,
                SOURCE,
                "blocking",
                "fn hn_block_level(voxel: vec3<i32>) -> i32 { return 0; }",
            )
        }
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![ResourceDecl {
            name: "dirs",
            kind: ResourceKind::Texture2d,
        }]
    }
    fn volume_passes(&self) -> Vec<VolumePassDecl> {
        let pass = |target, scale, entry, depends_on: &[&'static str]| {
            VolumePassDecl::new(target, entry)
                .scale(scale)
                .depends_on(depends_on)
        };
        // exact integration ignores the segment length
        let deps: Vec<&'static str> = LIGHT_DEPS
            .into_iter()
            .filter(|k| !(self.exact && *k == "segment"))
            .collect();
        let opacity_deps: Vec<&'static str> = deps
            .iter()
            .copied()
            .filter(|k| LIGHT_DEPS[..4].contains(k))
            .collect();
        let mut light_deps = deps;
        light_deps.extend(["sphere", "subdivisions"]);
        let mut passes = Vec::new();
        if self.blocking {
            passes.push(pass("blocks", 1.0 / BLOCK as f32, "block_pass", &["tolerance"]));
        }
        passes.extend([
            pass("alpha_lp", 1.0, "local_pass", &opacity_deps),
            pass("alpha_g", self.svr, "global_pass", &opacity_deps),
            pass("light_volume", 1.0, "light_pass", &light_deps).progressive(light_steps),
        ]);
        passes
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let t = gpu.create_table("shade.hernell directions", MAX_DIRECTIONS as u32, 1);
        self.update_resources(gpu, params, std::slice::from_ref(&t))?;
        Ok(vec![t])
    }
    fn update_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
        resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        let mut texels = vec![[0.0f32; 4]; MAX_DIRECTIONS];
        for (t, d) in texels.iter_mut().zip(directions(params)) {
            *t = [d.x as f32, d.y as f32, d.z as f32, 0.0];
        }
        if let Some(table) = resources.first() {
            gpu.write_table(table, &texels);
        }
        Ok(())
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let c = Hernell {
            svr: svr_scale(params),
            blocking: params.enumeration("blocking") == "16³",
            exact: params.enumeration("mode") == "exact",
        };
        (c != *self).then(|| Arc::new(c) as Arc<dyn Plugin>)
    }
    /// The light scales colours, never opacity.
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        let mut twin = HernellTwin::new(params, self.svr);
        twin.blocking = self.blocking.then(|| params.float("tolerance") as f64);
        Some(Box::new(twin))
    }
    fn statistic_names(&self, _params: &ParamValues) -> Vec<&'static str> {
        STATISTICS.to_vec()
    }
    /// Flat blocking's figures from the (block) pass's target, the levels the GPU
    /// chose: the data reduction (voxels over stored cells), the share of empty
    /// blocks and the blocks per level (1 and 0 without blocking, its levels absent).
    fn statistics(&self, _params: &ParamValues, passes: &PassOutputs<'_>) -> Vec<Statistic> {
        let stat = |name, value| Statistic { name, value };
        if !self.blocking {
            return vec![stat("data_reduction", 1.0), stat("empty_blocks", 0.0)];
        }
        let Some((dims, levels)) = (passes.read)("blocks") else {
            return Vec::new();
        };
        let blocks = Blocks {
            dims: dims.map(|d| d as usize),
            volume: passes.volume.dims.map(|d| d.max(1) as usize),
            levels: levels.iter().map(|l| l.round() as i32).collect(),
        };
        let h = blocks.histogram();
        let mut out = vec![
            stat("data_reduction", blocks.reduction()),
            stat("empty_blocks", blocks.empty_share()),
        ];
        out.extend((0..5).map(|l| stat(STATISTICS[2 + l], h[l] as f64)));
        out
    }
}

/// What [`Hernell::statistics`] reports.
const STATISTICS: [&str; 7] = [
    "data_reduction",
    "empty_blocks",
    "blocks_level_0",
    "blocks_level_1",
    "blocks_level_2",
    "blocks_level_3",
    "blocks_level_4",
];

/// A scalar grid with texel centres at (i + 0.5)/n, read trilinearly with
/// clamp-to-edge like `textureSampleLevel(.., linear_clamp, ..)`.
#[derive(Debug, Clone, Default)]
pub struct Grid {
    pub dims: [usize; 3],
    pub values: Vec<f64>,
}

impl Grid {
    pub fn at(&self, tex: DVec3) -> f64 {
        if self.values.is_empty() {
            return 0.0;
        }
        let dims = self.dims.map(|d| d as u32);
        trilinear_grid(dims, tex, |i| DVec4::splat(self.values[i])).x
    }
}

/// The light model's parameters, shared by the twin's passes.
#[derive(Debug, Clone)]
pub struct Light {
    pub point: bool,
    pub vector: DVec3,
    pub color: DVec3,
    pub intensity: f64,
    pub bias: f64,
    pub segment: i32,
    pub exact: bool,
    pub scattering: bool,
    pub radius: f64,
    pub directions: Vec<DVec3>,
}

/// CPU twin: the three passes in f64 (stored as f32, like the r32float targets) and
/// the shade hook.
pub struct HernellTwin {
    pub light: Light,
    pub svr: f32,
    /// Refinement steps to run (default: all); the GPU's progressive state after k
    /// frames of one step each is the twin with `steps = Some(k)`.
    pub steps: Option<u32>,
    pub alpha_lp: Grid,
    pub alpha_g: Grid,
    pub light_volume: Grid,
    /// Flat blocking's tolerance (RMS α) when it is on.
    pub blocking: Option<f64>,
    /// The block levels of the last passes (empty when blocking is off).
    pub blocks: Blocks,
}

/// Flat blocking's levels of detail: per 16³ block, l ∈ 0…4 (cells of 2^l voxels) or
/// −1 (empty).
#[derive(Debug, Clone, Default)]
pub struct Blocks {
    pub dims: [usize; 3],
    /// The volume's dims.
    pub volume: [usize; 3],
    pub levels: Vec<i32>,
}

impl Blocks {
    /// The level of the block holding a voxel (clamped into the volume).
    pub fn level(&self, v: [i64; 3]) -> i32 {
        if self.levels.is_empty() {
            return 0;
        }
        let b: [usize; 3] =
            std::array::from_fn(|a| v[a].clamp(0, self.volume[a] as i64 - 1) as usize / BLOCK);
        self.levels[(b[2] * self.dims[1] + b[1]) * self.dims[0] + b[0]]
    }
    /// Voxels over stored cells: each non-empty block stores (16/2^l)³ cells.
    pub fn reduction(&self) -> f64 {
        let cells: usize = self
            .levels
            .iter()
            .filter(|l| **l >= 0)
            .map(|l| (BLOCK >> *l as usize).pow(3))
            .sum();
        let voxels: usize = self.volume.iter().product();
        voxels as f64 / cells.max(1) as f64
    }
    /// Share of the blocks that are empty.
    pub fn empty_share(&self) -> f64 {
        self.levels.iter().filter(|l| **l < 0).count() as f64 / self.levels.len().max(1) as f64
    }
    /// Blocks per level 0…4, and empty ones last.
    pub fn histogram(&self) -> [usize; 6] {
        let mut h = [0; 6];
        for l in &self.levels {
            h[if *l < 0 { 5 } else { *l as usize }] += 1;
        }
        h
    }
}

/// Flat blocking's levels for a volume under a stack's classification (`classify`,
/// straight RGBA at a texture coordinate, as [`StackClassify`]) and the light of
/// `params`: what the (block) pass chooses, for reporting the data reduction.
pub fn blocks_for(volume: &vwb_render::volume::Volume, params: &ParamValues, tolerance: f64, classify: &StackClassify<'_>) -> Blocks {
    let b = vwb_render::slicing::VolumeBox::new(volume.dims, volume.spacing);
    let sp = Space {
        lo: b.min.as_dvec3(),
        hi: b.max.as_dvec3(),
        h: b.voxel as f64,
    };
    let twin = HernellTwin::new(params, 1.0);
    twin.block_levels(&sp, volume.dims.map(|d| d.max(1) as usize), classify, tolerance)
}

/// The box and Δs0 of the frame, as `frame.box_min/max` hold them (f32).
#[derive(Debug, Clone, Copy)]
struct Space {
    lo: DVec3,
    hi: DVec3,
    h: f64,
}

impl Space {
    fn tex(&self, p: DVec3) -> DVec3 {
        (p - self.lo) / (self.hi - self.lo)
    }
    fn inside(&self, p: DVec3) -> bool {
        p.cmpge(self.lo).all() && p.cmple(self.hi).all()
    }
    fn voxel_pos(&self, i: usize, dims: [usize; 3]) -> DVec3 {
        let [x, y, z] = grid_index(i, dims);
        let t = (DVec3::new(x as f64, y as f64, z as f64) + 0.5)
            / DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64);
        self.lo + t * (self.hi - self.lo)
    }
    fn max_steps(&self) -> i32 {
        ((self.hi - self.lo).length() / self.h).ceil() as i32 + 1
    }
}

/// The (x, y, z) of linear index `i` in a `dims` grid (x fastest).
fn grid_index(i: usize, dims: [usize; 3]) -> [usize; 3] {
    [i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1])]
}

fn f32r(x: f64) -> f64 {
    x as f32 as f64
}

impl HernellTwin {
    pub fn new(params: &ParamValues, svr: f32) -> Self {
        let c = params.color("light_color");
        Self {
            light: Light {
                point: params.enumeration("light_type") == "point",
                vector: DVec3::from(params.vec3("light").map(|v| v as f64)),
                color: DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64),
                intensity: params.float("intensity") as f64,
                bias: params.float("bias") as f64,
                segment: params.int("segment").max(1),
                exact: params.enumeration("mode") == "exact",
                scattering: params.boolean("scattering"),
                radius: params.float("radius") as f64,
                directions: directions(params),
            },
            svr,
            steps: None,
            alpha_lp: Grid::default(),
            alpha_g: Grid::default(),
            light_volume: Grid::default(),
            blocking: None,
            blocks: Blocks::default(),
        }
    }

    /// `block_pass`: the level of every 16³ block under the stack's classification.
    fn block_levels(&self, sp: &Space, dims: [usize; 3], classify: &StackClassify<'_>, tolerance: f64) -> Blocks {
        let bdims = dims.map(|d| d.div_ceil(BLOCK));
        let vd = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64);
        let levels = (0..bdims[0] * bdims[1] * bdims[2])
            .into_par_iter()
            .map(|i| {
                let origin = grid_index(i, bdims).map(|x| (x * BLOCK) as i64);
                let centre = DVec3::new(origin[0] as f64, origin[1] as f64, origin[2] as f64) + 8.0;
                let dir = self.to_light(sp.lo + centre / vd * (sp.hi - sp.lo)).0;
                let alpha = |x: i64, y: i64, z: i64| {
                    let v = [origin[0] + x, origin[1] + y, origin[2] + z];
                    let v: [f64; 3] = std::array::from_fn(|a| v[a].clamp(0, dims[a] as i64 - 1) as f64 + 0.5);
                    classify(DVec3::from(v) / vd, dir).w.clamp(0.0, 1.0)
                };
                let n = BLOCK as i64;
                let mut a_max = 0.0f64;
                let mut sums = vec![0.0f64; BLOCK * BLOCK * BLOCK];
                for z in -1..=n {
                    for y in -1..=n {
                        for x in -1..=n {
                            let a = alpha(x, y, z);
                            a_max = a_max.max(a);
                            if (0..n).contains(&x) && (0..n).contains(&y) && (0..n).contains(&z) {
                                sums[((z * n + y) * n + x) as usize] = a;
                            }
                        }
                    }
                }
                if a_max <= 0.0 {
                    return -1;
                }
                let sq: f64 = sums.iter().map(|a| a * a).sum();
                let mut level = 0;
                for l in 1..=4usize {
                    let c = 1usize << l;
                    let m = BLOCK / c;
                    let mut cells = vec![0.0f64; m * m * m];
                    for (j, a) in sums.iter().enumerate() {
                        let (x, y, z) = (j % BLOCK, (j / BLOCK) % BLOCK, j / (BLOCK * BLOCK));
                        cells[((z / c) * m + y / c) * m + x / c] += a;
                    }
                    let e: f64 = cells.iter().map(|s| s * s / (c * c * c) as f64).sum();
                    let err = ((sq - e).max(0.0) / (BLOCK * BLOCK * BLOCK) as f64).sqrt();
                    if err <= tolerance {
                        level = l as i32;
                    }
                }
                level
            })
            .collect();
        Blocks {
            dims: bdims,
            volume: dims,
            levels,
        }
    }

    /// `hn_block_tex`: with blocking, a lookup clamped into its own block.
    fn block_tex(&self, tex: DVec3) -> DVec3 {
        if self.blocking.is_none() {
            return tex;
        }
        let d = self.blocks.volume;
        let vd = DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64);
        let b = ((tex * vd).clamp(DVec3::ZERO, vd - 1.0) / BLOCK as f64).floor() * BLOCK as f64;
        let lo = (b + 0.5) / vd;
        let hi = ((b + BLOCK as f64).min(vd) - 0.5) / vd;
        tex.clamp(lo, hi)
    }

    fn voxel_of(&self, sp: &Space, p: DVec3) -> [i64; 3] {
        let d = self.blocks.volume;
        let t = sp.tex(p);
        std::array::from_fn(|a| (t[a] * d[a] as f64).floor() as i64)
    }

    /// `hn_cell_pos`: the centre of a voxel's cell at `level` (of the part inside the
    /// volume); at level 0 the voxel's centre, `voxel_pos`.
    fn cell_pos(&self, sp: &Space, i: usize, dims: [usize; 3], level: i32) -> DVec3 {
        let c = 1usize << level;
        let v = grid_index(i, dims);
        let t: [f64; 3] = std::array::from_fn(|a| {
            let lo = (v[a] / c) * c;
            0.5 * (lo + (lo + c).min(dims[a])) as f64 / dims[a] as f64
        });
        sp.lo + DVec3::from(t) * (sp.hi - sp.lo)
    }

    /// `hn_next_block`: from p along the unit `dir`, the world distance to the first
    /// point in a non-empty block; None when the ray leaves the volume first.
    fn next_block(&self, sp: &Space, p: DVec3, dir: DVec3) -> Option<f64> {
        let d = self.blocks.volume;
        let vd = DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64);
        let o = sp.tex(p) * vd;
        let v = (dir * vd / (sp.hi - sp.lo)).map(|x| if x.abs() < 1.0e-20 { 1.0e-20 } else { x });
        let bs = BLOCK as f64;
        let mut t = 0.0f64;
        let n = (vd.length() / bs).ceil() as usize * 3 + 3;
        for _ in 0..n {
            let lo = ((o + v * t) / bs).floor() * bs;
            let ta = (lo - o) / v;
            let tb = (lo + bs - o) / v;
            let t_exit = ta.max(tb).min_element();
            t = t_exit.max(t) + 1.0e-4 * sp.h;
            let y = o + v * t;
            if y.cmplt(DVec3::ZERO).any() || y.cmpge(vd).any() {
                return None;
            }
            if self.blocks.level([y.x.floor() as i64, y.y.floor() as i64, y.z.floor() as i64]) >= 0 {
                return Some(t);
            }
        }
        None
    }

    /// `hn_to_light`: unit direction from p to the light and the distance.
    fn to_light(&self, p: DVec3) -> (DVec3, f64) {
        if self.light.point {
            let d = self.light.vector - p;
            let len = d.length();
            if len < 1.0e-6 {
                return (DVec3::Z, 0.0);
            }
            return (d / len, len);
        }
        let l = self.light.vector;
        (l / l.length().max(1.0e-6), f64::MAX)
    }

    fn opacity(&self, sp: &Space, classify: &StackClassify<'_>, p: DVec3, dir: DVec3, n: i32, limit: f64) -> f64 {
        let mut t = 1.0;
        for i in 0..n {
            let d = (i + 1) as f64 * sp.h;
            if d > limit {
                break;
            }
            let q = p + dir * d;
            if !sp.inside(q) {
                break;
            }
            t *= 1.0 - classify(sp.tex(q), dir).w.clamp(0.0, 1.0);
        }
        1.0 - t
    }

    fn direct(&self, sp: &Space, p: DVec3) -> f64 {
        if !sp.inside(p) {
            return self.light.intensity;
        }
        let (l, dist) = self.to_light(p);
        let seg = self.light.segment as f64 * sp.h;
        let s1 = p + l * seg;
        let ag = if !self.light.exact && seg < dist && sp.inside(s1) {
            self.alpha_g.at(sp.tex(s1))
        } else {
            0.0
        };
        self.light.intensity * (1.0 - ag) * (1.0 - self.alpha_lp.at(self.block_tex(sp.tex(p))))
    }

    /// Runs the three passes for a volume of `dims` in the box `sp`.
    fn run_passes(&mut self, sp: Space, dims: [usize; 3], classify: &StackClassify<'_>) {
        let n_all = dims[0] * dims[1] * dims[2];
        let seg = self.light.segment;
        self.blocks = match self.blocking {
            Some(tolerance) => self.block_levels(&sp, dims, classify, tolerance),
            None => Blocks::default(),
        };
        // the level of voxel i (0 without blocking)
        let level_of = |i: usize| self.blocks.level(grid_index(i, dims).map(|x| x as i64));
        // (A1)
        let n = if self.light.exact { sp.max_steps() } else { seg };
        let lp: Vec<f64> = (0..n_all)
            .into_par_iter()
            .map(|i| {
                let level = level_of(i);
                if level < 0 {
                    return 0.0;
                }
                let p = self.cell_pos(&sp, i, dims, level);
                let (l, dist) = self.to_light(p);
                f32r(self.opacity(&sp, classify, p, l, n, dist))
            })
            .collect();
        self.alpha_lp = Grid { dims, values: lp };
        // (A2)
        let gdims = dims.map(|d| ((d as f32 * self.svr).ceil() as usize).max(1));
        let seg_w = seg as f64 * sp.h;
        let k_max = sp.max_steps() / seg + 2;
        let g: Vec<f64> = (0..gdims[0] * gdims[1] * gdims[2])
            .into_par_iter()
            .map(|i| {
                if self.light.exact {
                    return 0.0;
                }
                let p = sp.voxel_pos(i, gdims);
                let (l, dist) = self.to_light(p);
                let mut t = 1.0;
                // samples at base + j·seg: base moves when the ray skips empty blocks
                let (mut base, mut j) = (0.0, 0);
                for _ in 0..k_max {
                    let mut d = base + j as f64 * seg_w;
                    if d >= dist {
                        break;
                    }
                    let mut q = p + l * d;
                    if !sp.inside(q) {
                        break;
                    }
                    if self.blocking.is_some() && self.blocks.level(self.voxel_of(&sp, q)) < 0 {
                        // Fig. 4: advance to the next non-empty block
                        let Some(a) = self.next_block(&sp, q, l) else {
                            break;
                        };
                        base = d + a;
                        j = 0;
                        d = base;
                        if d >= dist {
                            break;
                        }
                        q = p + l * d;
                    }
                    t *= 1.0 - self.alpha_lp.at(self.block_tex(sp.tex(q)));
                    j += 1;
                }
                f32r(1.0 - t)
            })
            .collect();
        self.alpha_g = Grid {
            dims: gdims,
            values: g,
        };
        // (B)
        let total = if self.light.scattering {
            1 + self.light.directions.len() as u32
        } else {
            1
        };
        let steps = self.steps.unwrap_or(total).clamp(1, total);
        let m_max = self.light.radius.round() as i32;
        let light: Vec<f64> = (0..n_all)
            .into_par_iter()
            .map(|i| {
                let level = level_of(i);
                if level < 0 {
                    return f32r(self.light.intensity);
                }
                let p = self.cell_pos(&sp, i, dims, level);
                if !self.light.scattering {
                    return f32r(self.direct(&sp, p));
                }
                let mut stored = 0.0;
                for step in 0..steps {
                    let dir = if step == 0 {
                        self.to_light(p).0
                    } else {
                        self.light.directions[step as usize - 1]
                    };
                    let mut sum = 0.0;
                    let mut t = 1.0;
                    for m in 0..=m_max {
                        let q = p + dir * (m as f64 * sp.h);
                        sum += self.direct(&sp, q) * t;
                        if m > 0 && sp.inside(q) {
                            t *= 1.0 - classify(sp.tex(q), dir).w.clamp(0.0, 1.0);
                        }
                    }
                    let w = 1.0 / (step as f64 + 1.0);
                    stored = f32r(w * (sum / (m_max + 1) as f64) + (1.0 - w) * stored);
                }
                stored
            })
            .collect();
        self.light_volume = Grid { dims, values: light };
    }
}

impl CpuTwin for HernellTwin {
    fn prepare_passes(&mut self, ctx: &CpuContext, classify: &StackClassify<'_>) {
        let (lo, hi) = ctx.volume_box();
        let sp = Space {
            lo,
            hi,
            h: ctx.reference_step(),
        };
        let dims = ctx.volume.dims.map(|d| d.max(1) as usize);
        self.run_passes(sp, dims, classify);
    }
    fn shade(&self, _ctx: &CpuContext, s: &mut CpuSample) {
        let i = self.light_volume.at(self.block_tex(s.tex));
        let f = self.light.bias + (1.0 - self.light.bias) * i;
        s.color = DVec4::from(((s.color.truncate() * f) * self.light.color, s.color.w));
    }
}
