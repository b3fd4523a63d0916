//! The lighting table of `shade.blinn_phong` (`lighting: table`, issue 23 item 3): the
//! diffuse and specular sums of the view-space directional lights, tabulated over the
//! octahedral map of the view-space normal, so that a sample pays one rotation, one
//! encoding and two `textureLoad`s instead of a light loop. VTK's fixed-point ray
//! caster shades the same way (per-frame tables indexed by a quantised normal).
//!
//! - Layout: a `2N × N` table (N = [`SIZE`]); texel (i, j) holds k_d·Σ diffuse·L of
//!   the normal at the centre of octahedral cell (i, j), texel (i + N, j) k_s·Σ
//!   specular·L. A sample reads the cell its view-space normal falls in (nearest).
//! - The view vector is taken as (0, 0, 1) in view space for the whole image: exact
//!   for orthographic cameras; with perspective the half-vector ignores how far a
//!   ray is from the view axis (VTK's tables make the same choice). Two-sided normals
//!   are still flipped with each ray's own direction before the lookup.
//! - Only view-space directional lights are tabulated: world-space lights move with
//!   the camera and point lights with the sample, so those are still evaluated per
//!   sample. The table depends on k_d, k_s, the shininess and the lights, and is
//!   baked again only when one of those changes ([`bakes`] counts).

use std::hash::{Hash, Hasher};
use std::sync::atomic::{AtomicU64, Ordering};

use glam::{DVec2, DVec3};
use vwb_render::plugin::{GpuInit, GpuResource};
use vwb_render::shading::{
    light_terms, oct_decode, oct_encode, Light, LightKind, LightSpace, Material,
};

/// Octahedral cells per side (N): 256 keeps the direction error under 1°.
pub const SIZE: u32 = 256;

/// Whether a light is tabulated (directional, in view space).
pub fn tabulated(l: &Light) -> bool {
    l.kind == LightKind::Directional && l.space == LightSpace::View
}

/// The table's texels (row by row, `2N × N`, rgba with a = 1) for the lights (those
/// that are on) and the material.
pub fn bake(lights: &[Light], m: &Material) -> Vec<[f32; 4]> {
    let n = SIZE as usize;
    let dirs: Vec<_> = lights
        .iter()
        .filter(|l| tabulated(l))
        .map(|l| (vwb_render::shading::safe_normalize(l.vector), l.color))
        .collect();
    let v = DVec3::Z;
    let mut texels = vec![[0.0f32; 4]; 2 * n * n];
    for j in 0..n {
        for i in 0..n {
            let nv = cell_normal(i as u32, j as u32);
            let (d, s) = light_terms(nv, v, &dirs, m);
            texels[j * 2 * n + i] = [d.x as f32, d.y as f32, d.z as f32, 1.0];
            texels[j * 2 * n + n + i] = [s.x as f32, s.y as f32, s.z as f32, 1.0];
        }
    }
    texels
}

/// The unit normal at the centre of octahedral cell (i, j).
pub fn cell_normal(i: u32, j: u32) -> DVec3 {
    let e = (DVec2::new(i as f64, j as f64) + 0.5) / SIZE as f64;
    oct_decode(e * 2.0 - 1.0)
}

/// The cell a view-space unit normal falls in (`light_table_terms` in WGSL).
pub fn cell_of(nv: DVec3) -> (u32, u32) {
    let e = oct_encode(nv) * 0.5 + 0.5;
    let c = |x: f64| ((x * SIZE as f64).max(0.0) as u32).min(SIZE - 1);
    (c(e.x), c(e.y))
}

/// (diffuse, specular) of a baked table for a view-space unit normal.
pub fn lookup(texels: &[[f32; 4]], nv: DVec3) -> (DVec3, DVec3) {
    let (i, j) = cell_of(nv);
    let n = SIZE as usize;
    let at = |k: usize| {
        let t = texels[k];
        DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64)
    };
    let row = j as usize * 2 * n;
    (at(row + i as usize), at(row + n + i as usize))
}

/// What the table depends on.
fn key(lights: &[Light], m: &Material) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for x in [m.kd, m.ks, m.shininess] {
        x.to_bits().hash(&mut h);
    }
    for l in lights.iter().filter(|l| tabulated(l)) {
        for x in l.vector.to_array().iter().chain(&l.color.to_array()) {
            x.to_bits().hash(&mut h);
        }
    }
    h.finish()
}

static BAKES: AtomicU64 = AtomicU64::new(0);

/// Tables baked by this process (tests count them).
pub fn bakes() -> u64 {
    BAKES.load(Ordering::Relaxed)
}

/// Which lights and material each table texture holds.
static BAKED: crate::held::Held = crate::held::Held::new();

/// A new table texture for the lights and material.
pub fn create(gpu: &GpuInit, lights: &[Light], m: &Material) -> GpuResource {
    let t = gpu.create_table("shade.blinn_phong lighting table", 2 * SIZE, SIZE);
    upload(gpu, &t, lights, m);
    t
}

/// Bakes and uploads the table again unless it already holds these lights and material.
pub fn upload(gpu: &GpuInit, t: &GpuResource, lights: &[Light], m: &Material) {
    let k = key(lights, m);
    if BAKED.holds(&t.texture, k) {
        return;
    }
    gpu.write_table(t, &bake(lights, m));
    BAKES.fetch_add(1, Ordering::Relaxed);
    BAKED.record(&t.texture, k);
}

/// The WGSL appended in table mode: the table lookup.
pub const TABLE_WGSL: &str = "
// appended by shade.blinn_phong (lighting: table; plugins/src/shade_blinn_phong/table.rs)
fn light_table_terms(n: vec3<f32>) -> LightTerms {
    // the normal in view space: x right, y up, z towards the viewer
    let nv = vec3<f32>(dot(n, view_right()), dot(n, view_up()), -dot(n, frame.forward.xyz));
    let e = oct_encode(nv) * 0.5 + vec2<f32>(0.5);
    let size = i32(textureDimensions(light_table).y);
    let c = clamp(vec2<i32>(e * f32(size)), vec2<i32>(0), vec2<i32>(size - 1));
    let d = textureLoad(light_table, c, 0).rgb;
    let s = textureLoad(light_table, c + vec2<i32>(size, 0), 0).rgb;
    return LightTerms(d, s);
}
";

/// The WGSL appended in direct mode: nothing is tabulated.
pub const DIRECT_WGSL: &str = "
// appended by shade.blinn_phong (lighting: direct)
fn light_table_terms(n: vec3<f32>) -> LightTerms {
    return LightTerms(vec3<f32>(0.0), vec3<f32>(0.0));
}
";
