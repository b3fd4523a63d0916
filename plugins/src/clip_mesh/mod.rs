//! `clip.mesh`: clipping by a closed triangle mesh — a file (OBJ, PLY or STL) or a
//! generated sphere, box or torus — keeping its inside or its outside (thesis §9.2's
//! stencil clipping by arbitrary closed meshes).
//!
//! The thesis clips per slice with the stencil buffer, which gives up the depth
//! buffer. Here the mesh pass voxelises the placed mesh once by crossing parity into a
//! narrow-band signed-distance grid over the volume box ([`voxelize`]), uploaded as the
//! r16float texture `sdf`; the `clip` hook is then one filtered texture read per
//! sample, and every pass that evaluates the clip hooks (slices, DOS, the global-light
//! passes, thumbnails) sees the same cut.
//!
//! - **What reruns.** The grid depends on the mesh (its file and modification time,
//!   or the generated shape), its placement (`center`, `rotate`, `scale`, `size`,
//!   `units`), the grid resolution and the volume; it is built once per distinct set
//!   and uploaded once per change ([`mesh_pass_counts`]). Camera moves, the
//!   soft edge, the cut layer and `keep` rerun nothing (`keep` negates the distance
//!   in the shader).
//! - **Placement.** File vertices are in `units`: `world` (the volume box centred on
//!   the origin, longest side 1), `voxels` (index coordinates, voxel i's centre at i)
//!   or `mm` (voxels × spacing, from voxel 0's centre; the file's own origin is not
//!   kept by the loaders). Generated shapes are the unit sphere, the cube [−1, 1]³ or a
//!   torus of major radius 1 around z, scaled per axis by `size`. Then the mesh is
//!   scaled by `scale`, rotated by `rotate` (degrees about x, then y, then z) and moved
//!   to `center` (world).
//! - **Bad meshes.** A mesh that is not closed or not a manifold is refused with the
//!   file and the first bad edge; an inconsistent orientation is logged as a warning
//!   naming the edge (parity does not need orientation).
//! - **Resolution** (structural: it sizes the texture): the grid is the data's dims ×
//!   1/4, 1/2, 1 or 2, at most [`MAX_GRID`] per axis.
//! - Soft edge and shading at the cut as in `clip.shapes` (Weiskopf, Engel & Ertl
//!   2003), from the distance texture, within the band of [`voxelize::BAND`] voxels.

use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::path::Path;
use std::sync::{Arc, Mutex, OnceLock, Weak};

use glam::{DMat3, DVec3};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, RegionFn,
    ResourceDecl, ResourceKind, ShaderSource, Transparency, trilinear_grid, Volumes,
};
use vwb_render::shading::{safe_normalize, set_cut_gradient};
use vwb_render::slicing::VolumeBox;
use vwb_render::volume::Volume;

use crate::clip_shapes::cut::{CutShading, SubstituteTwin, substitute_wgsl};

pub mod mesh;
pub mod probes;
pub mod voxelize;

#[cfg(test)]
mod tests;

use mesh::TriMesh;
use voxelize::SdfGrid;

pub const SOURCES: [&str; 4] = ["sphere", "box", "torus", "file"];
pub const UNITS: [&str; 3] = ["world", "voxels", "mm"];
pub const KEEP: [&str; 2] = ["inside", "outside"];
pub const RESOLUTIONS: [&str; 4] = ["1:4", "1:2", "1:1", "2:1"];
/// Largest grid along an axis.
pub const MAX_GRID: u32 = 512;

/// The parameters the grid depends on (besides the volume).
const GRID_KEYS: [&str; 10] = [
    "source",
    "file",
    "units",
    "segments",
    "torus_ratio",
    "size",
    "center",
    "rotate",
    "scale",
    "resolution",
];

/// (grids built, uploads) by grid key, process-wide: tests count what reruns.
fn counts() -> &'static Mutex<HashMap<u64, (u64, u64)>> {
    static COUNTS: OnceLock<Mutex<HashMap<u64, (u64, u64)>>> = OnceLock::new();
    COUNTS.get_or_init(Default::default)
}

fn count(key: u64, build: u64, upload: u64) {
    if let Ok(mut c) = counts().lock() {
        let e = c.entry(key).or_default();
        e.0 += build;
        e.1 += upload;
    }
}

/// How often the mesh pass built the grid of `params` over `volume`, and how often
/// that grid was uploaded to the GPU (in this process).
pub fn mesh_pass_counts(params: &ParamValues, volume: &Volume) -> (u64, u64) {
    let key = grid_key(params, volume);
    counts()
        .lock()
        .ok()
        .and_then(|c| c.get(&key).copied())
        .unwrap_or_default()
}

fn error(message: String) -> PluginError {
    PluginError::Invalid {
        plugin: "clip.mesh".into(),
        message,
    }
}

/// The grid dims for `dims` at the parameters' resolution.
pub fn grid_dims(params: &ParamValues, dims: [u32; 3]) -> [u32; 3] {
    let f = match params.enumeration("resolution") {
        "1:4" => 0.25,
        "1:2" => 0.5,
        "2:1" => 2.0,
        _ => 1.0,
    };
    dims.map(|d| ((d.max(1) as f64 * f).round() as u32).clamp(2, MAX_GRID))
}

/// A mesh file loaded, welded and checked ([`TriMesh::check`]), with the warning of an
/// inconsistent orientation, if any.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckedMesh {
    pub mesh: TriMesh,
    pub warning: Option<String>,
}

/// Loads and checks a mesh file (cached per path and modification time, so a file is
/// read, checked and its warning logged once per version). Errors name the file.
pub fn load_checked(path: &Path) -> Result<Arc<CheckedMesh>, String> {
    type Key = (std::path::PathBuf, Option<std::time::SystemTime>);
    static CACHE: OnceLock<Mutex<HashMap<Key, Arc<CheckedMesh>>>> = OnceLock::new();
    let modified = std::fs::metadata(path).and_then(|m| m.modified()).ok();
    let key = (path.to_path_buf(), modified);
    let cache = CACHE.get_or_init(Default::default);
    if let Some(held) = cache.lock().ok().and_then(|c| c.get(&key).cloned()) {
        return Ok(held);
    }
    let mut mesh = mesh::load(path)?;
    let warning = mesh.check(&path.display().to_string())?.orientation;
    if let Some(w) = &warning {
        log::warn!("clip.mesh: {w}");
    }
    let checked = Arc::new(CheckedMesh { mesh, warning });
    if let Ok(mut c) = cache.lock() {
        c.insert(key, checked.clone());
    }
    Ok(checked)
}

/// The mesh in its own coordinates: the checked file, or a generated shape (closed and
/// consistently oriented by construction; the tests check each generator).
fn source_mesh(params: &ParamValues) -> Result<TriMesh, String> {
    let segments = params.int("segments").clamp(3, 512) as u32;
    Ok(match params.enumeration("source") {
        "file" => {
            let path = params
                .path("file")
                .ok_or("no mesh file set (parameter `file`)")?;
            load_checked(path)?.mesh.clone()
        }
        source => {
            let unit = match source {
                "box" => mesh::cube(),
                "torus" => mesh::torus(segments, params.float("torus_ratio").clamp(0.01, 0.99) as f64),
                _ => mesh::sphere(segments),
            };
            let size = DVec3::from(params.vec3("size").map(f64::from));
            unit.map_positions(|p| p * size)
        }
    })
}

/// The mesh placed in world space over `volume` as the parameters say.
pub fn placed_mesh(params: &ParamValues, volume: &Volume) -> Result<TriMesh, String> {
    let m = source_mesh(params)?;
    let vbox = VolumeBox::new(volume.dims, volume.spacing);
    let (lo, hi) = (vbox.min.as_dvec3(), vbox.max.as_dvec3());
    let dims = DVec3::from(volume.dims.map(|d| d.max(1) as f64));
    let spacing = DVec3::from(volume.spacing);
    let from_voxels = move |p: DVec3| lo + (p + 0.5) / dims * (hi - lo);
    let to_world: Box<dyn Fn(DVec3) -> DVec3> = match (params.enumeration("source"), params.enumeration("units")) {
        ("file", "voxels") => Box::new(from_voxels),
        ("file", "mm") => Box::new(move |p: DVec3| from_voxels(p / spacing)),
        _ => Box::new(|p| p),
    };
    let r = params.vec3("rotate").map(|d| (d as f64).to_radians());
    let rotation = DMat3::from_rotation_z(r[2]) * DMat3::from_rotation_y(r[1]) * DMat3::from_rotation_x(r[0]);
    let scale = params.float("scale") as f64;
    let center = DVec3::from(params.vec3("center").map(f64::from));
    Ok(m.map_positions(|p| center + rotation * (to_world(p) * scale)))
}

/// The key of the grid of `params` over `volume`.
fn grid_key(params: &ParamValues, volume: &Volume) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for k in GRID_KEYS {
        if let Some(v) = params.get(k) {
            v.hash_into(&mut h);
        }
    }
    if params.enumeration("source") == "file"
        && let Some(m) = params.path("file").and_then(|p| std::fs::metadata(p).ok())
    {
        m.len().hash(&mut h);
        m.modified().ok().hash(&mut h);
    }
    volume.dims.hash(&mut h);
    volume.spacing.map(f64::to_bits).hash(&mut h);
    h.finish()
}

/// Grids recently built (the last [`RECENT`]) and every grid still held elsewhere (a
/// CPU twin, a caller), by grid key.
#[derive(Default)]
struct GridCache {
    recent: Vec<(u64, Arc<SdfGrid>)>,
    held: HashMap<u64, Weak<SdfGrid>>,
}

/// Grids the cache keeps alive by itself.
const RECENT: usize = 8;

impl GridCache {
    fn get(&mut self, key: u64) -> Option<Arc<SdfGrid>> {
        if let Some((_, g)) = self.recent.iter().find(|(k, _)| *k == key) {
            return Some(g.clone());
        }
        let g = self.held.get(&key)?.upgrade()?;
        self.keep(key, g.clone());
        Some(g)
    }
    fn keep(&mut self, key: u64, g: Arc<SdfGrid>) {
        self.held.insert(key, Arc::downgrade(&g));
        self.recent.push((key, g));
        if self.recent.len() > RECENT {
            self.recent.remove(0);
            self.held.retain(|_, w| w.strong_count() > 0);
        }
    }
}

/// The grid of `params` over `volume`: built by the mesh pass on first use, then
/// served from a cache (the GPU upload, the skipping region and the CPU twin share
/// it): the last [`RECENT`] grids, and any grid still held elsewhere, are never built
/// again.
pub fn grid_for(params: &ParamValues, volume: &Volume) -> Result<Arc<SdfGrid>, String> {
    grid_of_key(params, volume, grid_key(params, volume))
}

/// [`grid_for`] with the grid's key already computed.
fn grid_of_key(params: &ParamValues, volume: &Volume, key: u64) -> Result<Arc<SdfGrid>, String> {
    static CACHE: OnceLock<Mutex<GridCache>> = OnceLock::new();
    let cache = CACHE.get_or_init(Default::default);
    if let Some(g) = cache.lock().ok().and_then(|mut c| c.get(key)) {
        return Ok(g);
    }
    let m = placed_mesh(params, volume)?;
    let vbox = VolumeBox::new(volume.dims, volume.spacing);
    let grid = Arc::new(voxelize::voxelize(
        &m,
        vbox.min.as_dvec3(),
        vbox.max.as_dvec3(),
        grid_dims(params, volume.dims),
        vbox.voxel as f64,
    ));
    count(key, 1, 0);
    if grid.odd_columns > 0 {
        log::warn!(
            "clip.mesh: {} of {} voxel columns cross the mesh an odd number of times (rays grazing a vertex or edge); their inside may be wrong",
            grid.odd_columns,
            grid.dims[0] * grid.dims[1]
        );
    }
    if let Ok(mut c) = cache.lock() {
        c.keep(key, grid.clone());
    }
    Ok(grid)
}

/// Which grid each texture holds, so that a parameter change that does not move the
/// mesh uploads nothing.
static UPLOADED: crate::held::Held = crate::held::Held::new();

/// Writes `grid` (of key `key`) into the distance texture and records which grid it
/// holds. The texture is r32float where the device filters it, else r16float
/// ([`GpuInit::create_volume_texture`]); the values are f16-exact, so both hold the
/// same numbers.
fn upload(gpu: &GpuInit, sdf: &GpuResource, grid: &SdfGrid, key: u64) {
    gpu.write_floats(sdf, &grid.values);
    count(key, 0, 1);
    UPLOADED.record(&sdf.texture, key);
}

/// The plugin as its structural parameter `cut_shading` configures it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClipMesh {
    /// How the cut is shaded.
    pub cut: CutShading,
}

/// The generated `mesh_cut(tex, d)`: within the layer behind the cut, the cut's normal
/// (−∇sd in world space, central differences half a grid voxel apart) replaces the
/// data gradient; or clipped-value substitution within the stencil's reach of the cut;
/// empty when off.
fn cut_wgsl(cut: CutShading) -> String {
    match cut {
        CutShading::Off => "\nfn mesh_cut(tex: vec3<f32>, d: f32) {}\n".into(),
        CutShading::ClipNormal => "
fn mesh_cut(tex: vec3<f32>, d: f32) {
    if (-d < params.cut_layer * frame.box_min.w) {
        let h = 0.5 / vec3<f32>(textureDimensions(sdf));
        let w = 2.0 * h * (frame.box_max.xyz - frame.box_min.xyz);
        let g = vec3<f32>(
            (mesh_sd(tex + vec3<f32>(h.x, 0.0, 0.0)) - mesh_sd(tex - vec3<f32>(h.x, 0.0, 0.0))) / w.x,
            (mesh_sd(tex + vec3<f32>(0.0, h.y, 0.0)) - mesh_sd(tex - vec3<f32>(0.0, h.y, 0.0))) / w.y,
            (mesh_sd(tex + vec3<f32>(0.0, 0.0, h.z)) - mesh_sd(tex - vec3<f32>(0.0, 0.0, h.z))) / w.z,
        );
        clip_cut_gradient = vec4<f32>(-safe_normalize(g), 1.0);
    }
}
"
        .into(),
        CutShading::Substitute => {
            substitute_wgsl("mesh_sd(q) > 0.0")
                + "
fn mesh_cut(tex: vec3<f32>, d: f32) {
    if (-d < substitute_reach()) {
        substitute_cut(tex);
    }
}
"
        }
    }
}

impl Plugin for ClipMesh {
    /// It reads a voxelised mesh over the whole volume box, in the volume's texture coordinates.
    fn splits_into_bricks(&self) -> bool {
        false
    }
    /// The voxelisation on its own ([`probes::Voxelise`]).
    fn probes(&self) -> Vec<Arc<dyn vwb_render::plugin::Probe>> {
        vec![Arc::new(probes::Voxelise)]
    }
    /// `grid_builds` and `grid_uploads`: how often the mesh pass has built the grid of
    /// these parameters over this volume, and uploaded it, in this process
    /// ([`mesh_pass_counts`]): a camera orbit leaves both where the first frame put them.
    fn statistic_names(&self, _params: &ParamValues) -> Vec<&'static str> {
        vec!["grid_builds", "grid_uploads"]
    }
    fn statistics(
        &self,
        params: &ParamValues,
        passes: &vwb_render::plugin::PassOutputs<'_>,
    ) -> Vec<vwb_render::plugin::Statistic> {
        let (builds, uploads) = mesh_pass_counts(params, passes.volume);
        vec![
            vwb_render::plugin::Statistic {
                name: "grid_builds",
                value: builds as f64,
            },
            vwb_render::plugin::Statistic {
                name: "grid_uploads",
                value: uploads as f64,
            },
        ]
    }
    fn id(&self) -> &'static str {
        "clip.mesh"
    }
    fn display_name(&self) -> &'static str {
        "Clip mesh"
    }
    fn description(&self) -> &'static str {
        "Clipping by a closed triangle mesh (OBJ, PLY, STL, or a generated sphere, box or torus), voxelised into a signed-distance grid"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::enumeration("source", "Mesh", &SOURCES, 0)
                .with_doc("a generated sphere, box or torus, or a file"),
            ParamSpec::path("file", "Mesh file", "")
                .with_doc("a closed OBJ, PLY or STL mesh; relative to the preset"),
            ParamSpec::enumeration("units", "File units", &UNITS, 0).with_doc(
                "world: the volume box centred on the origin, longest side 1; voxels: index coordinates; mm: voxels × spacing",
            ),
            ParamSpec::enumeration("keep", "Keep", &KEEP, 0)
                .with_doc("keep the inside of the mesh, or cut it away and keep the outside"),
            ParamSpec::vec3("size", "Shape size", 0.0, 2.0, [0.3; 3]).with_doc(
                "generated shapes: sphere radii, box half extents, torus major radius (x, y) and height (z)",
            ),
            ParamSpec::int("segments", "Shape segments", 3, 512, 48)
                .with_doc("generated sphere and torus: facets around"),
            ParamSpec::float("torus_ratio", "Torus tube ratio", 0.01, 0.99, 0.35)
                .with_doc("tube radius / major radius"),
            ParamSpec::vec3("center", "Centre", -2.0, 2.0, [0.0; 3])
                .with_doc("world units: where the mesh's origin goes"),
            ParamSpec::vec3("rotate", "Rotation (°)", -360.0, 360.0, [0.0; 3])
                .with_doc("about x, then y, then z, in degrees"),
            ParamSpec::float("scale", "Scale", 0.0, 10.0, 1.0).with_doc("uniform scale of the mesh"),
            ParamSpec::enumeration("resolution", "Grid resolution", &RESOLUTIONS, 2)
                .structural()
                .with_doc("voxelisation grid against the data's dims"),
        ]
        .into_iter()
        // within the band of exact distances
        .chain(crate::clip_shapes::cut::cut_params(voxelize::BAND as f32))
        .collect()
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource {
            file: "plugins/src/clip_mesh/mesh.wgsl".into(),
            source: format!("{}{}", include_str!("mesh.wgsl"), cut_wgsl(self.cut)).into(),
        }
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let configured = ClipMesh {
            cut: CutShading::from_params(params),
        };
        (configured != *self).then(|| Arc::new(configured) as Arc<dyn Plugin>)
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![ResourceDecl {
            name: "sdf",
            kind: ResourceKind::Texture3d,
        }]
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let key = grid_key(params, gpu.volume);
        let grid = grid_of_key(params, gpu.volume, key).map_err(error)?;
        let sdf = gpu.create_volume_texture("clip.mesh sdf", grid.dims, 1);
        upload(gpu, &sdf, &grid, key);
        Ok(vec![sdf])
    }
    fn update_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
        resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        let Some(sdf) = resources.first() else {
            return Err(error("distance texture missing".into()));
        };
        let key = grid_key(params, gpu.volume);
        if UPLOADED.holds(&sdf.texture, key) {
            return Ok(());
        }
        let grid = grid_of_key(params, gpu.volume, key).map_err(error)?;
        let size = sdf.texture.size();
        if [size.width, size.height, size.depth_or_array_layers] != grid.dims {
            return Err(error(format!(
                "the distance texture is {}×{}×{} but the grid is {:?}",
                size.width, size.height, size.depth_or_array_layers, grid.dims
            )));
        }
        upload(gpu, sdf, &grid, key);
        Ok(())
    }
    /// Keeps transparent samples transparent (a clip hook only removes samples); the
    /// region it keeps depends on the volume ([`Plugin::region`]).
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
    /// The world boxes some point of which the grid keeps: a trilinear value is a
    /// convex blend of its eight texels, so a box none of whose texels (those any
    /// point in it blends) is kept keeps nothing. `None` (no skipping) when the mesh
    /// cannot be voxelised.
    fn region(&self, params: &ParamValues, volumes: &Volumes<'_>) -> Option<Arc<RegionFn>> {
        let volume = volumes.main;
        let grid = grid_for(params, volume).ok()?;
        let outside = params.enumeration("keep") == "outside";
        let vbox = VolumeBox::new(volume.dims, volume.spacing);
        let (lo, hi) = (vbox.min.as_dvec3(), vbox.max.as_dvec3());
        Some(Arc::new(move |a: DVec3, z: DVec3| {
            may_keep_box(&grid, outside, (lo, hi), a, z)
        }))
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(ClipMeshTwin {
            params: params.clone(),
            grid: None,
            keep_outside: params.enumeration("keep") == "outside",
            soft_edge: params.float("soft_edge") as f64,
            cut_layer: (CutShading::from_params(params) == CutShading::ClipNormal)
                .then(|| params.float("cut_layer") as f64),
            substitute: (CutShading::from_params(params) == CutShading::Substitute)
                .then(|| SubstituteTwin::new(params)),
            step: 1.0,
            extent: DVec3::ONE,
        }))
    }
}

/// CPU twin of `clip` and `shade`: the same grid (built or taken from the cache in
/// `prepare`), interpolated as the GPU sampler does.
pub struct ClipMeshTwin {
    params: ParamValues,
    grid: Option<Arc<SdfGrid>>,
    keep_outside: bool,
    soft_edge: f64,
    cut_layer: Option<f64>,
    substitute: Option<SubstituteTwin>,
    /// Δs0 (world).
    step: f64,
    /// The volume box's size (world).
    extent: DVec3,
}

/// Whether some point of the world box (`a`, `z`) can be kept by `grid` over the
/// volume box `(lo, hi)`: whether one of the texels any point of the box blends has a
/// kept distance ≤ 0.
pub fn may_keep_box(
    grid: &SdfGrid,
    keep_outside: bool,
    (lo, hi): (DVec3, DVec3),
    a: DVec3,
    z: DVec3,
) -> bool {
    let n = grid.dims.map(|d| d.max(1) as i64);
    let range = |axis: usize| {
        let cell = (hi[axis] - lo[axis]) / n[axis] as f64;
        let at = |p: f64| ((p - lo[axis]) / cell - 0.5).floor() as i64;
        let first = at(a[axis]).clamp(0, n[axis] - 1);
        let last = (at(z[axis]) + 1).clamp(0, n[axis] - 1);
        first..=last
    };
    let (rx, ry, rz) = (range(0), range(1), range(2));
    for k in rz {
        for j in ry.clone() {
            for i in rx.clone() {
                let v = grid.values[((k * n[1] + j) * n[0] + i) as usize];
                if (if keep_outside { -v } else { v }) <= 0.0 {
                    return true;
                }
            }
        }
    }
    false
}

/// The grid's signed distance at texture coordinate `tex` in Δs0, ≤ 0 where kept
/// (negated when the outside is kept), interpolated as the GPU does (`mesh_sd`).
pub fn kept_distance(grid: &SdfGrid, tex: DVec3, keep_outside: bool) -> f64 {
    let d = trilinear_grid(grid.dims, tex, |i| glam::DVec4::splat(grid.values[i] as f64)).x;
    if keep_outside { -d } else { d }
}

impl ClipMeshTwin {
    /// `mesh_sd`: the signed distance at `tex` (world units, ≤ 0 kept).
    fn sd(&self, grid: &SdfGrid, tex: DVec3) -> f64 {
        kept_distance(grid, tex, self.keep_outside) * self.step
    }
}

impl CpuTwin for ClipMeshTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        self.grid = grid_for(&self.params, ctx.volume).ok();
        self.step = ctx.reference_step();
        let (lo, hi) = ctx.volume_box();
        self.extent = hi - lo;
        if let Some(sub) = &mut self.substitute {
            sub.prepare(ctx);
        }
    }
    fn clip(&self, s: &CpuSample) -> bool {
        let Some(grid) = &self.grid else {
            return true;
        };
        let d = self.sd(grid, s.tex);
        if d > 0.0 {
            return false;
        }
        if let Some(layer) = self.cut_layer
            && -d < layer * self.step
        {
            let h = DVec3::from(grid.dims.map(|n| 0.5 / n as f64));
            let w = 2.0 * h * self.extent;
            let diff = |e: DVec3| self.sd(grid, s.tex + e) - self.sd(grid, s.tex - e);
            let g = DVec3::new(
                diff(DVec3::X * h.x) / w.x,
                diff(DVec3::Y * h.y) / w.y,
                diff(DVec3::Z * h.z) / w.z,
            );
            set_cut_gradient(Some(-safe_normalize(g)));
        }
        if let Some(sub) = &self.substitute
            && -d < sub.reach()
        {
            set_cut_gradient(Some(sub.gradient(s.tex, |q| self.sd(grid, q) > 0.0)));
        }
        true
    }
    /// The soft edge: α × clamp(−sd / w, 0, 1) (the GPU computes the factor in `clip`).
    fn shade(&self, _ctx: &CpuContext, s: &mut CpuSample) {
        let w = self.soft_edge * self.step;
        if w > 0.0
            && let Some(grid) = &self.grid
        {
            s.color.w *= (-self.sd(grid, s.tex) / w).clamp(0.0, 1.0);
        }
    }
}
