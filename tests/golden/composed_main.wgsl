// vwb shared WGSL: core uniforms, core bindings (group 0) and the Sample record
// that flows through the hooks clip -> sample -> classify -> shade -> composite.
//
// Conventions
// - World space: the volume box is centred on the origin; its longest side is 1.
// - `Sample.tex` is the volume texture coordinate in [0,1]^3 (texel centres at (i+0.5)/n).
// - `Sample.value` is the scalar normalised to [0,1] over the volume's finite value range.
// - `Sample.color` is straight (not premultiplied) RGBA; alpha is the opacity for one
//   reference step Δs0 (one voxel). The core applies opacity correction
//   α' = 1 − (1 − α)^(Δs/Δs0) after `shade` and premultiplies before `composite`.
// - Textures must be read with textureSampleLevel / textureLoad (the same code runs in
//   fragment and compute stages).

struct Frame {
    view_proj: mat4x4<f32>,
    // pixel rays, well conditioned (no inverse projection): perspective: direction
    // = normalize(ray_basis · (ndc, 1, 0)), origin = the eye; orthographic: origin =
    // ray_basis · (ndc, 0, 1), direction = column 2 (the view direction)
    ray_basis: mat4x4<f32>,
    // xyz: camera position; w: 1 perspective, 0 orthographic
    eye: vec4<f32>,
    // xyz: unit view direction (slice normal); w: slice spacing Δs in world units
    forward: vec4<f32>,
    // xyz: volume box min (world); w: Δs0, the world length of one voxel
    box_min: vec4<f32>,
    // xyz: volume box max (world); w: distance of slice 0 from the eye along `forward`
    box_max: vec4<f32>,
    // width, height, 1/width, 1/height of the eye buffer
    viewport: vec4<f32>,
    // volume dims (voxels) in xyz
    volume_dims: vec4<f32>,
    // data min, data max (raw units), 1/(max-min), 0
    value_range: vec4<f32>,
    // x: slice count, y: 1 when the eye buffer is fp16, z: 1 when early termination is
    // on, w: 1 when the compute backend's rays with skipping are cut to `hull`
    counts: vec4<u32>,
    // x: early-termination opacity threshold; y: brick size of empty-space skipping
    // (0: off); zw: first pixel of a compute dispatch (a brick's footprint)
    settings: vec4<f32>,
    // the part of the box whose samples this renderer takes (the whole box; on the
    // compute backend with empty-space skipping, the part the classification can show;
    // or a brick's own region when the volume is split into bricks); own_max.w: bit a set
    // when the max face along axis a is shared with the next brick (half-open there)
    own_min: vec4<f32>,
    own_max: vec4<f32>,
    // xyz: unit normal of the slice planes (`forward`, or the half-angle axis under
    // half-angle slicing, render/src/slicing.rs); w: 1 under half-angle slicing
    slicing: vec4<f32>,
    // half-angle slicing: xyz the unit direction the light travels, w the path length
    // along it between two slice planes
    light: vec4<f32>,
    // half-angle slicing: the per-slice state's rays, across the light: origin =
    // state_rays · (ndc, 0, 1), direction = column 2 (the light's)
    state_rays: mat4x4<f32>,
    // xyz: 1 / (box_max − box_min), world to volume texture coordinates (`tex_of`)
    inv_extent: vec4<f32>,
    // the occupied bricks' hull (render/src/slicing.rs `Dop`) along its ten diagonal
    // directions (`Dop::DIRS[3..]`; its axis slabs are the own box): hull[m] holds the
    // least and greatest n·p of direction 2m (xy) and of direction 2m + 1 (zw)
    hull: array<vec4<f32>, 5>,
    // x: the workgroup rows of the frame's whole-frame dispatch, y: the stride that
    // `spread_row` spreads them by (computed once per frame on the CPU:
    // `renderer::spread_stride`)
    spread: vec4<u32>,
    // empty-space skipping's brick grid (`occupancy` below): xyz its size in bricks, w
    // the word of `occupancy` where the bricks' bytes begin. The buffer's words 0–3 hold
    // the same; read here, they cost a ray no storage-buffer loads, which llvmpipe runs
    // one lane at a time in divergent control flow (docs/perf.md, "Storage-buffer words
    // one lane at a time")
    bricks: vec4<u32>,
}

// A sweep pass's geometry (render/src/sweep.rs): the axis its planes are normal to,
// whether they ascend, the world path length between two planes, the offset in texels
// of a texel's upstream point on the previous plane, and the value upstream of the
// first plane and outside the planes.
struct SweepInfo {
    axis: u32,
    ascending: u32,
    length: f32,
    boundary: f32,
    shift: vec2<f32>,
    pad: vec2<f32>,
}

// The texel with coordinate `a` along the sweep's axis and `bc` along the other two.
fn sweep_place(sw: SweepInfo, a: i32, bc: vec2<i32>) -> vec3<i32> {
    if (sw.axis == 0u) {
        return vec3<i32>(a, bc.x, bc.y);
    }
    if (sw.axis == 1u) {
        return vec3<i32>(bc.x, a, bc.y);
    }
    return vec3<i32>(bc.x, bc.y, a);
}

// Plane `plane`'s coordinate along the sweep's axis of a target of `n` planes.
fn sweep_plane(sw: SweepInfo, plane: u32, n: u32) -> i32 {
    if (sw.ascending != 0u) {
        return i32(plane);
    }
    return i32(n) - 1 - i32(plane);
}

// The target's size along the sweep's axis and along the other two.
fn sweep_sizes(sw: SweepInfo, dims: vec3<u32>) -> vec3<u32> {
    if (sw.axis == 0u) {
        return dims;
    }
    if (sw.axis == 1u) {
        return vec3<u32>(dims.y, dims.x, dims.z);
    }
    return vec3<u32>(dims.z, dims.x, dims.y);
}

// Per slice (bound with a dynamic offset): its index and, where `tile_row` is not 0,
// the tiles of 8 × 8 texels where anything that reaches the image can change at this
// slice, `tile_count` of them from `tile_offset` in `slice_tile_list`, which the
// per-slice entry points' dispatches cover in rows of `tile_row` workgroups
// (`slice_tile`; render/src/renderer/slice_exit.rs). The tiles are those of a grid of
// `list_size` texels (width | height << 16): the eye buffer's, or the per-slice
// state's where every state has one size and it is smaller or lies across the light
// (a state update uses the list where its state has that size).
struct SliceInfo {
    index: u32,
    tile_offset: u32,
    tile_count: u32,
    tile_row: u32,
    list_size: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> frame_uniform: Frame;
// The frame as the module's code reads it: a private copy that every entry point takes
// first, with each plugin instance's parameters (`params`, likewise a private copy of
// its uniform): `load_frame`, which the composer generates for each module (or on the
// raster backend `load_frame_fragment`; the composer refuses an entry point that does
// not begin with one, `composer::check_frame_loads`). llvmpipe (Mesa 22.3) reads a
// uniform inside control flow that may leave lanes idle (all of a fragment shader, the
// rest of a compute shader after its first `return`) one lane at a time, about 30
// instructions a word. The copy is read there as a register, and the slices' fragments
// take the frame's most read fields from flat vertex outputs (docs/perf.md, "The frame
// and the parameters as private copies").
var<private> frame: Frame;

// A vertex shader's `load_frame`: the frame alone (the parameters' uniforms are not
// bound to the vertex stage).
fn load_frame_vertex() {
    frame = frame_uniform;
}
// binding 1, the scalar volume `volume_tex`: with its reads below (`volume_value`)
@group(0) @binding(2) var linear_clamp: sampler;
@group(0) @binding(3) var nearest_clamp: sampler;
@group(0) @binding(4) var<uniform> slice_info: SliceInfo;
// Empty-space skipping: per brick of frame.settings.y voxels, a bit set where a sample
// can be visible (render/src/skipping.rs); the grid's dims in words 0–2, the bits from
// word 4, x fastest; from the word that word 3 names, eight bytes per brick (two
// words), one per octant of ray directions: bit 7 the same bit, bits 0–6 how far its
// pure box ahead reaches (`skipping::pure_boxes_ahead`; `upload_occupancy` in
// render/src/renderer.rs). The shaders take words 0–3 from `frame.bricks`.
@group(0) @binding(5) var<storage, read> occupancy: array<u32>;
// The tiles of every slice that `slice_info` lists, x | y << 16.
@group(0) @binding(6) var<storage, read> slice_tile_list: array<u32>;

// A pixel's ray (`pixel_ray`): `origin` is the eye for a perspective camera, the
// pixel's point on the plane through the eye for an orthographic one; `dir` is unit.
struct Ray {
    origin: vec3<f32>,
    dir: vec3<f32>,
}

struct Sample {
    // world position of the sample
    pos: vec3<f32>,
    // volume texture coordinate in [0,1]^3
    tex: vec3<f32>,
    // unit direction from the eye towards the sample
    ray_dir: vec3<f32>,
    // screen coordinate in [0,1]^2 (y down)
    uv: vec2<f32>,
    // normalised scalar value (set by the core sampler, may be replaced by `sample` hooks)
    value: f32,
    // world distance along the ray to the next slice plane; read-only for hooks (the
    // core's opacity correction takes the ray's value, computed once per ray)
    step: f32,
    // straight RGBA set by `classify` (alpha per reference step Δs0)
    color: vec4<f32>,
    // free for shading plugins (e.g. a gradient); zero by default
    normal: vec3<f32>,
    // index of the slice, front (0) to back
    slice: u32,
    // where shading evaluates the gradient, as a fraction of `step` ahead of the sample
    // along the ray: 0 (the sample) unless `classify` moved it (pre-integrated
    // classification with `shade_at: centroid` puts it at the slab's opacity centroid).
    // Read it through `shading_tex`.
    shade_at: f32,
}

// The texture coordinate where shading plugins evaluate the gradient (`shade_at`).
fn shading_tex(s: Sample) -> vec3<f32> {
    if (s.shade_at == 0.0) {
        return s.tex;
    }
    return s.tex + s.ray_dir * (s.step * s.shade_at) / (frame.box_max.xyz - frame.box_min.xyz);
}

// Shading at a clip cut (Weiskopf, Engel & Ertl 2003): a clip hook may set xyz to the
// gradient (∇f·Δs0 units) the cut has at the current sample, with w = 1; every shading
// plugin's `gradient_at` then returns it (`cut_gradient`). Reset before each sample's
// clip hooks (`evaluate` in shaders/slice.wgsl). CPU twin: vwb_render::shading.
var<private> clip_cut_gradient: vec4<f32>;

fn cut_gradient(g: vec3<f32>) -> vec3<f32> {
    if (clip_cut_gradient.w > 0.5) {
        return clip_cut_gradient.xyz;
    }
    return g;
}

// The brick grid of empty-space skipping (bricks of side frame.settings.y voxels), as
// values a ray computes once before its loop (`brick_grid`): written out per lookup,
// its quotients of uniforms stayed in the loop as divisions on lavapipe (the lookup
// runs in most iterations for some lane of a SIMD vector; docs/perf.md, "A ray's
// samples as one run").
struct BrickGrid {
    // grid coordinates per texture unit (volume_dims / side)
    scale: vec3<f32>,
    // a brick's side in texture units (side / volume_dims)
    side: vec3<f32>,
    // the occupancy grid's size in bricks
    dims: vec3<u32>,
    // the word of `occupancy` where the bricks' bytes begin
    cells: u32,
}

fn brick_grid() -> BrickGrid {
    var g: BrickGrid;
    g.scale = frame.volume_dims.xyz / frame.settings.y;
    g.side = frame.settings.y / frame.volume_dims.xyz;
    g.dims = frame.bricks.xyz;
    g.cells = frame.bricks.w;
    return g;
}

// The brick holding `tex` (while skipping is on), as grid coordinates: the one index
// `brick_visible` and the march's brick exit share. Rounding may put a sample on a
// brick's face into its neighbour, which is exact: a brick's range includes a
// one-voxel apron (render/src/skipping.rs).
fn brick_of(g: BrickGrid, tex: vec3<f32>) -> vec3<f32> {
    return floor(tex * g.scale);
}

// False where the brick holding `tex` cannot produce a visible sample (its hooks can
// be skipped: the contribution would be exactly zero). Always true while skipping is
// off (frame.settings.y = 0).
fn brick_visible(g: BrickGrid, tex: vec3<f32>) -> bool {
    if (frame.settings.y <= 0.0) {
        return true;
    }
    let i = brick_index(g, brick_of(g, tex));
    return (occupancy[4u + (i >> 5u)] & (1u << (i & 31u))) != 0u;
}

// The index of a brick of the grid (x fastest); bricks outside it (samples on the
// box's faces, within rounding) take the nearest one's.
fn brick_index(g: BrickGrid, brick: vec3<f32>) -> u32 {
    let b = vec3<u32>(clamp(brick, vec3<f32>(0.0), vec3<f32>(g.dims - vec3<u32>(1u))));
    return b.x + g.dims.x * (b.y + g.dims.y * b.z);
}

// A brick's byte for rays heading into `octant` (skipping on; bit 0: x decreasing,
// bit 1: y, bit 2: z): bit 7 set where a sample in it can be visible (the bit
// `brick_visible` reads), bits 0–6 the extent r of its pure box ahead, the (r + 1)³
// bricks from it towards the octant, all of its kind.
fn brick_cell(g: BrickGrid, brick: vec3<f32>, octant: u32) -> u32 {
    let i = brick_index(g, brick);
    return (occupancy[g.cells + 2u * i + (octant >> 2u)] >> ((octant & 3u) * 8u)) & 0xFFu;
}

// The scalar volume and its reads, in one of two layouts (the composer keeps one
// region: `VolumeLayout`, render/src/composer.rs). A filtered 3D texture; or, the
// `r32float_pairs` volume format (what CPU devices store), each voxel beside its +z
// neighbour in an rg32float 2D array texture: the sampler's bilinear filter reads
// both layers' values at once and a mix in z completes the trilinear value, one
// bilinear fetch in place of a trilinear one (docs/perf.md, "Sample fetch").
// volume_texture3d: begin
@group(0) @binding(1) var volume_tex: texture_3d<f32>;

// Scalar at a texture coordinate (trilinear).
fn volume_value(tex: vec3<f32>) -> f32 {
    return textureSampleLevel(volume_tex, linear_clamp, tex, 0.0).r;
}

// The volume's size in voxels.
fn volume_dims() -> vec3<u32> {
    return textureDimensions(volume_tex);
}

// Scalar at an integer voxel (no filtering); clamps to the volume.
fn volume_voxel(v: vec3<i32>) -> f32 {
    let c = clamp(v, vec3<i32>(0), vec3<i32>(volume_dims()) - vec3<i32>(1));
    return textureLoad(volume_tex, c, 0).r;
}
// volume_texture3d: end


























// Raw data value for a normalised value.
fn data_value(v: f32) -> f32 {
    return mix(frame.value_range.x, frame.value_range.y, v);
}

// Texture coordinate of a value x ∈ [0, 1] along a table axis of n entries, for a
// linear lookup: texel centres sit at (i + ½)/n, so x maps to (x·(n − 1) + ½)/n. The
// classification plugins pass their table's size as a constant power of two, so that
// once inlined the division is a multiplication by the exact 1/n: the bits of dividing
// by the size, without a division per sample, which llvmpipe would not hoist out of
// the march (docs/perf.md, "Divisions once per ray"). CPU twin: vwb_render::tf::table_coord
// (the texels and the weight this coordinate's linear filter reads).
fn table_coord(x: f32, n: f32) -> f32 {
    return (x * (n - 1.0) + 0.5) * (1.0 / n);
}

fn table_coord2(x: vec2<f32>, n: f32) -> vec2<f32> {
    return (x * (n - 1.0) + 0.5) * (1.0 / n);
}

// Opacity correction α' = 1 − (1 − α)^(Δs/Δs0), exact at α = 0 and α = 1.
fn correct_opacity(alpha: f32, step: f32) -> f32 {
    return correct_opacity_ratio(alpha, step_ratio(step));
}

// The opacity correction's exponent Δs/Δs0 for a step Δs.
fn step_ratio(step: f32) -> f32 {
    return step / frame.box_min.w;
}

// `correct_opacity` with its exponent Δs/Δs0 given, for callers that compute it once
// for many samples (a ray's: `RaySlices.ratio`).
fn correct_opacity_ratio(alpha: f32, ratio: f32) -> f32 {
    let a = clamp(alpha, 0.0, 1.0);
    if (a >= 1.0) {
        return 1.0;
    }
    return 1.0 - exp2(ratio * log2(1.0 - a));
}

// ---- Local illumination helpers shared by the shading plugins. CPU twin and the
// conventions (units, fade rule, light spaces): render/src/shading.rs.

// World size of a voxel along each axis.
fn voxel_size_world() -> vec3<f32> {
    return (frame.box_max.xyz - frame.box_min.xyz) / frame.volume_dims.xyz;
}

// The gradient estimators differentiate `shading_value(tex)`, the scalar the stack's
// `sample` hooks give at a texture coordinate, one texel of its grid `shading_grid()`
// apart. Both are generated with the composed module (render/src/composer.rs): the
// volume's value on the volume's grid, unless a plugin that replaces the value supplies
// its own through `scalar(tex)` and `scalar_grid()` (flow.lic3d: shading from LIC).

// precomputed_central's correction at the volume's faces (shading.rs,
// `central_edge_factor`). Central differences one texel apart are linear in the reads,
// so away from the faces the trilinear interpolation of the voxels' differences
// equals the difference of the interpolated reads. Within half a texel of a face the
// read beyond it clamps to the edge texel, so the difference across that face falls
// linearly to half at the face; the interpolated voxels' differences clamp to the edge
// voxel's instead. Scaling each component by this factor makes the two equal.
fn central_edge_factor(tex: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let beyond = abs(tex * n - 0.5 * n) - 0.5 * (n - vec3<f32>(1.0));
    return vec3<f32>(1.0) - clamp(beyond, vec3<f32>(0.0), vec3<f32>(1.0));
}

// ∇f·Δs0 by central differences one texel apart (6 reads of the scalar).
fn gradient_central(tex: vec3<f32>) -> vec3<f32> {
    let n = shading_grid();
    let d = 1.0 / n;
    let gx = shading_value(tex + vec3<f32>(d.x, 0.0, 0.0)) - shading_value(tex - vec3<f32>(d.x, 0.0, 0.0));
    let gy = shading_value(tex + vec3<f32>(0.0, d.y, 0.0)) - shading_value(tex - vec3<f32>(0.0, d.y, 0.0));
    let gz = shading_value(tex + vec3<f32>(0.0, 0.0, d.z)) - shading_value(tex - vec3<f32>(0.0, 0.0, d.z));
    return vec3<f32>(gx, gy, gz) * 0.5 * frame.box_min.w / ((frame.box_max.xyz - frame.box_min.xyz) / n);
}

// ∇f·Δs0 by the 3×3×3 Sobel operator (26 reads of the scalar).
fn gradient_sobel(tex: vec3<f32>) -> vec3<f32> {
    let n = shading_grid();
    let d = 1.0 / n;
    var g = vec3<f32>(0.0);
    for (var z = -1; z <= 1; z = z + 1) {
        for (var y = -1; y <= 1; y = y + 1) {
            for (var x = -1; x <= 1; x = x + 1) {
                if (x == 0 && y == 0 && z == 0) {
                    continue;
                }
                let o = vec3<f32>(f32(x), f32(y), f32(z));
                let f = shading_value(tex + o * d);
                let w = vec3<f32>(2.0) - abs(o);
                g = g + o * vec3<f32>(w.y * w.z, w.x * w.z, w.x * w.y) * f;
            }
        }
    }
    return g / 32.0 * frame.box_min.w / ((frame.box_max.xyz - frame.box_min.xyz) / n);
}

fn safe_normalize(v: vec3<f32>) -> vec3<f32> {
    let l = length(v);
    if (l > 0.0 && l < 3.0e38) {
        return v / l;
    }
    return vec3<f32>(0.0);
}

// (n, w): outward unit normal −g/|g| (flipped towards `v` when two-sided) and the lit
// weight w = clamp(|g|/fade, 0, 1). Zero for a zero or non-finite gradient.
fn shading_normal(g: vec3<f32>, fade: f32, v: vec3<f32>, two_sided: bool) -> vec4<f32> {
    let m = length(g);
    if (!(m > 0.0 && m < 3.0e38)) {
        return vec4<f32>(0.0);
    }
    var n = -g / m;
    if (two_sided && dot(n, v) < 0.0) {
        n = -n;
    }
    return vec4<f32>(n * shading_normal_scale, clamp(m / max(fade, 1.0e-12), 0.0, 1.0));
}

// The length of the normal `shading_normal` returns: 1, except after the
// `precomputed_normal_unnormalized` estimator's `gradient_at`, which sets the length of
// its interpolated normal (≤ 1; Rezk-Salama 2001, §7.5). Every estimator's `gradient_at`
// sets it. Twin: shading::Gradients::normal.
var<private> shading_normal_scale: f32 = 1.0;

// The thesis's normal texture (Rezk-Salama 2001, §7.2, eq 7.5): the unit gradient
// "scaled and biased" into [0, 1] (rgb = 0.5·ĝ + 0.5) and √|g| (clamped to |g| ≤ 1) in a,
// rounded here to k/255 so that the rgba8unorm store's conversion is exact. Twin:
// shading::normal_code.
fn normal_encode(g: vec3<f32>) -> vec4<f32> {
    let m = length(g);
    var d = vec3<f32>(0.0);
    var mm = 0.0;
    if (m > 0.0 && m < 3.0e38) {
        d = g / m;
        mm = min(m, 1.0);
    }
    let c = vec4<f32>(d * 0.5 + vec3<f32>(0.5), sqrt(mm));
    return round(clamp(c, vec4<f32>(0.0), vec4<f32>(1.0)) * 255.0) / 255.0;
}

// ∇f·Δs0 from an interpolated code of normal_encode: the decoded direction
// (2·rgb − 1) renormalised, times the magnitude a². Twin: shading::normal_code_gradient.
fn normal_code_gradient(c: vec4<f32>) -> vec3<f32> {
    let d = c.xyz * 2.0 - vec3<f32>(1.0);
    let l = length(d);
    if (!(l > 0.0)) {
        return vec3<f32>(0.0);
    }
    return d * (c.w * c.w / l);
}

// Octahedral map of a unit vector onto [-1, 1]² (Meyer et al. 2010); (0, 0) for the
// zero vector. Twin: shading::oct_encode.
fn oct_encode(n: vec3<f32>) -> vec2<f32> {
    let s = abs(n.x) + abs(n.y) + abs(n.z);
    if (!(s > 0.0 && s < 3.0e38)) {
        return vec2<f32>(0.0);
    }
    let p = n.xy / s;
    if (n.z < 0.0) {
        return (vec2<f32>(1.0) - abs(p.yx)) * select(vec2<f32>(-1.0), vec2<f32>(1.0), p >= vec2<f32>(0.0));
    }
    return p;
}

// The unit vector of an octahedral point. Twin: shading::oct_decode.
fn oct_decode(e: vec2<f32>) -> vec3<f32> {
    let z = 1.0 - abs(e.x) - abs(e.y);
    var xy = e;
    if (z < 0.0) {
        xy = (vec2<f32>(1.0) - abs(e.yx)) * select(vec2<f32>(-1.0), vec2<f32>(1.0), e >= vec2<f32>(0.0));
    }
    return safe_normalize(vec3<f32>(xy, z));
}

// The quantized estimator's code of a gradient (rgba8unorm: direction in 16 bits,
// √magnitude in 8), rounded here to k/255 so that the store's conversion is exact.
// Twin: shading::gradient_code.
fn gradient_encode(g: vec3<f32>) -> vec4<f32> {
    let m = length(g);
    var e = vec2<f32>(0.0);
    var mm = 0.0;
    if (m > 0.0 && m < 3.0e38) {
        e = oct_encode(g / m);
        mm = min(m, 1.0);
    }
    let c = vec3<f32>(e * 0.5 + vec2<f32>(0.5), sqrt(mm));
    return vec4<f32>(round(clamp(c, vec3<f32>(0.0), vec3<f32>(1.0)) * 255.0) / 255.0, 0.0);
}

// The gradient of a code of gradient_encode. Twin: shading::gradient_decode.
fn gradient_decode(c: vec4<f32>) -> vec3<f32> {
    return oct_decode(c.xy * 2.0 - vec2<f32>(1.0)) * (c.z * c.z);
}

fn view_right() -> vec3<f32> {
    return normalize(frame.ray_basis[0].xyz);
}

fn view_up() -> vec3<f32> {
    return normalize(frame.ray_basis[1].xyz);
}

// Unit direction from `pos` towards a light. kind: 0 directional (vector = direction
// towards the light), 1 point (vector = position); space: 0 view (x right, y up, z
// towards the viewer; points relative to the eye), 1 world.
fn light_dir(kind: u32, space: u32, vector: vec3<f32>, pos: vec3<f32>) -> vec3<f32> {
    let w = light_world_vector(kind, space, vector);
    if (kind == 1u) {
        return safe_normalize(w - pos);
    }
    return safe_normalize(w);
}

// What `light_dir` normalises: the light's direction (directional) or position (point)
// in world space. It reads only uniforms, so the lighting plugins compute it once per
// ray (`with_lights` in plugins/src/lighting.rs) and pass it to `light_dir` as a
// world-space vector: the same operations, out of the sample loop, which a CPU device
// does not hoist by itself (docs/perf.md, "Cheap shading").
fn light_world_vector(kind: u32, space: u32, vector: vec3<f32>) -> vec3<f32> {
    var w = vector;
    if (space == 0u) {
        w = view_right() * vector.x + view_up() * vector.y - frame.forward.xyz * vector.z;
        if (kind == 1u) {
            w = w + frame.eye.xyz;
        }
    }
    return w;
}

// (diffuse, specular) Blinn–Phong factors: max(n·l, 0) and max(n·h, 0)^shininess
// where n·l > 0.
fn blinn_phong_factors(n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, shininess: f32) -> vec2<f32> {
    let diff = max(dot(n, l), 0.0);
    let ndh = dot(n, safe_normalize(l + v));
    var spec = 0.0;
    if (diff > 0.0 && ndh > 0.0) {
        spec = pow(ndh, shininess);
    }
    return vec2<f32>(diff, spec);
}

// Whether the frame is sliced halfway between the view and a light, with per-slice
// state in the light's space (render/src/slicing.rs, `HalfAngle`). The composer keeps
// the `half_angle` regions (here and in slice.wgsl) only for stacks whose per-slice
// state may travel with a light (`SliceStateDecl::light`): a branch on a uniform costs
// a CPU device both of its sides.
fn half_angle() -> bool {
    return frame.slicing.w > 0.5;
}

// The state coordinate of a world point under half-angle slicing.
fn light_uv(p: vec3<f32>) -> vec2<f32> {
    let q = p - frame.state_rays[3].xyz;
    let a = frame.state_rays[0].xyz;
    let b = frame.state_rays[1].xyz;
    let ndc = vec2<f32>(dot(q, a) / dot(a, a), dot(q, b) / dot(b, b));
    return vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
}

// Where a sample at world point `pos` and coordinate `uv` reads per-slice state
// (`state_prev`; call it as `state_coord(s.pos, s.uv)`): `uv`, or under half-angle
// slicing its coordinate in the light's space (in a state update `uv` is the state
// texel's own coordinate either way). A function rather than a Sample field, since a
// larger Sample costs the CPU device in every hook call. Twin: CpuView::state_coord.
fn state_coord(pos: vec3<f32>, uv: vec2<f32>) -> vec2<f32> {
    var c = uv;



    return c;
}

// State-uv units per world unit across the per-slice state's rays on slice k's plane:
// the screen's at the slice's depth (Schott et al. 2009, eqs 12–15), or the light
// space's under half-angle slicing. Twin: CpuView::state_uv_per_world.
fn state_uv_per_world(k: u32) -> vec2<f32> {





    var depth = 1.0;
    if (frame.eye.w > 0.5) {
        depth = max(frame.box_max.w + f32(k) * frame.forward.w, 1.0e-9);
    }
    return 0.5 / (vec2<f32>(length(frame.ray_basis[0].xyz), length(frame.ray_basis[1].xyz)) * depth);
}

// The path length of the per-slice state's rays between two slice planes: the slice
// spacing, or the light's step under half-angle slicing. Twin: CpuView::state_step.
fn state_step() -> f32 {





    return frame.forward.w;
}
fn shading_value(tex: vec3<f32>) -> f32 {
    return volume_value(tex);
}
fn shading_grid() -> vec3<f32> {
    return frame.volume_dims.xyz;
}
fn sample_value(tex: vec3<f32>) -> f32 {
    return volume_value(tex);
}
// vwb slice template: the hook runners and the entry points of both backends.
// The composer inserts generated declarations at `//!DECLS`, plugin code at `//!PLUGINS`
// and generated hook calls at each `//!HOOK name` marker, in the order of the user's
// plugin stack. Once per ray: setup; then per sample: clip -> sample -> classify ->
// shade -> composite; once per pixel after the loop: post.

struct p0_smooth_Params {
    radius: i32,
    amount: f32,
}
@group(1) @binding(0) var<uniform> p0_smooth_params_uniform: p0_smooth_Params;
var<private> p0_smooth_params: p0_smooth_Params;
@group(1) @binding(1) var p0_smooth_smoothed: texture_3d<f32>;
struct p1_tf1d_Params {
    mode: u32,
    opacity: f32,
    shade_at: u32,
}
@group(1) @binding(2) var<uniform> p1_tf1d_params_uniform: p1_tf1d_Params;
var<private> p1_tf1d_params: p1_tf1d_Params;
@group(1) @binding(3) var p1_tf1d_lut: texture_1d<f32>;
struct p2_slice_shadow_Params {
    strength: f32,
}
@group(1) @binding(4) var<uniform> p2_slice_shadow_params_uniform: p2_slice_shadow_Params;
var<private> p2_slice_shadow_params: p2_slice_shadow_Params;
@group(2) @binding(0) var p2_slice_shadow_state_prev: texture_2d<f32>;
@group(2) @binding(1) var p2_slice_shadow_state_next: texture_storage_2d<rgba32float, write>;
struct p3_tf1d_Params {
    mode: u32,
    opacity: f32,
    shade_at: u32,
}
@group(1) @binding(5) var<uniform> p3_tf1d_params_uniform: p3_tf1d_Params;
var<private> p3_tf1d_params: p3_tf1d_Params;
@group(1) @binding(6) var p3_tf1d_lut: texture_1d<f32>;
// Every entry point's first call: the frame's and each plugin instance's parameters'
// private copies from their uniforms (shaders/common.wgsl, `frame`).
fn load_frame() {
    frame = frame_uniform;
    p0_smooth_params = p0_smooth_params_uniform;
    p1_tf1d_params = p1_tf1d_params_uniform;
    p2_slice_shadow_params = p2_slice_shadow_params_uniform;
    p3_tf1d_params = p3_tf1d_params_uniform;
}
// The plugin instances' parameters that the slice fragments read, as flat words of
// every vertex, and the frame's ray basis (where `FRAME_FROM_VERTEX`; as many as the
// device's inter-stage locations hold): written by `frame_to_vertex`, read by
// `load_frame_fragment`.
fn params_to_vertex(o: ptr<function, VsOut>) {
    (*o).params_0 = vec4<u32>(bitcast<u32>(p0_smooth_params_uniform.amount), bitcast<u32>(p1_tf1d_params_uniform.opacity), bitcast<u32>(p2_slice_shadow_params_uniform.strength), bitcast<u32>(p3_tf1d_params_uniform.opacity));
    (*o).params_1 = vec4<u32>(bitcast<u32>(frame_uniform.ray_basis[0].x), bitcast<u32>(frame_uniform.ray_basis[0].y), bitcast<u32>(frame_uniform.ray_basis[0].z), bitcast<u32>(frame_uniform.ray_basis[0].w));
}
fn params_from_vertex(in: VsOut) {
    p0_smooth_params.amount = bitcast<f32>(in.params_0.x);
    p1_tf1d_params.opacity = bitcast<f32>(in.params_0.y);
    p2_slice_shadow_params.strength = bitcast<f32>(in.params_0.z);
    p3_tf1d_params.opacity = bitcast<f32>(in.params_0.w);
    frame.ray_basis[0] = vec4<f32>(bitcast<f32>(in.params_1.x), bitcast<f32>(in.params_1.y), bitcast<f32>(in.params_1.z), bitcast<f32>(in.params_1.w));
}

// test.smooth — demonstrates a pre-pass that fills a 3D texture: the sample hook
// blends the interpolated value with the box-filtered volume `smoothed`.
fn p0_smooth_sample(s: Sample) -> Sample {
    var o = s;
    let sm = textureSampleLevel(p0_smooth_smoothed, linear_clamp, s.tex, 0.0).r;
    o.value = mix(s.value, sm, p0_smooth_params.amount);
    return o;
}
// classify.tf1d — post-classification: interpolate the scalar, then look up a
// piecewise-linear RGBA transfer function baked into the 256-entry 1D texture `lut`
// (a 1D texture, not a 256×1 2D one: the same linear lookup at half the texel reads,
// which is what it costs on CPU adapters; docs/perf.md).

// The table's entries, `vwb_render::tf::LUT_SIZE` (a test keeps the two equal): a
// constant for `table_coord`.
const p1_tf1d_LUT_N: f32 = 256.0;

fn p1_tf1d_classify(s: Sample) -> Sample {
    var o = s;
    let x = table_coord(clamp(s.value, 0.0, 1.0), p1_tf1d_LUT_N);
    let c = textureSampleLevel(p1_tf1d_lut, linear_clamp, x, 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * p1_tf1d_params.opacity, 0.0, 1.0));
    return o;
}
// test.slice_shadow — demonstrates per-slice state (ping-pong buffers).
// `state_prev.r` holds the opacity accumulated in front of the current slice, as seen
// from the eye; `shade` darkens the slice by it and `slice_update` adds the slice's
// own contribution for the next slice. With strength 1 every sample is attenuated by
// what lies in front of it a second time (a head-on "shadow").

fn p2_slice_shadow_shade(s: Sample) -> Sample {
    var o = s;
    let occ = textureSampleLevel(p2_slice_shadow_state_prev, linear_clamp, state_coord(s.pos, s.uv), 0.0).r;
    o.color = vec4<f32>(s.color.rgb * (1.0 - p2_slice_shadow_params.strength * occ), s.color.a);
    return o;
}

fn p2_slice_shadow_slice_update(s: Sample, c: vec4<f32>, uv: vec2<f32>) -> vec4<f32> {
    let prev = textureSampleLevel(p2_slice_shadow_state_prev, linear_clamp, uv, 0.0).r;
    return vec4<f32>(prev + (1.0 - prev) * c.a, 0.0, 0.0, 1.0);
}
// classify.tf1d — post-classification: interpolate the scalar, then look up a
// piecewise-linear RGBA transfer function baked into the 256-entry 1D texture `lut`
// (a 1D texture, not a 256×1 2D one: the same linear lookup at half the texel reads,
// which is what it costs on CPU adapters; docs/perf.md).

// The table's entries, `vwb_render::tf::LUT_SIZE` (a test keeps the two equal): a
// constant for `table_coord`.
const p3_tf1d_LUT_N: f32 = 256.0;

fn p3_tf1d_classify(s: Sample) -> Sample {
    var o = s;
    let x = table_coord(clamp(s.value, 0.0, 1.0), p3_tf1d_LUT_N);
    let c = textureSampleLevel(p3_tf1d_lut, linear_clamp, x, 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * p3_tf1d_params.opacity, 0.0, 1.0));
    return o;
}

// Once per ray (per pixel), before its samples: each `setup` hook fills its own
// instance's `ray_record`, which that instance's hooks then read for every sample of the
// ray (e.g. a per-pixel jitter). The raster backend runs it per fragment on the pixel's
// exact ray, which gives the same record since it depends on the ray alone.
fn run_setup(r: Ray, uv: vec2<f32>) {
}

fn run_clip(s: Sample) -> bool {
    return true;
}

fn run_sample(s_in: Sample) -> Sample {
    var s = s_in;
    s.value = sample_value(s.tex);
    s = p0_smooth_sample(s);
    return s;
}

fn run_classify(s_in: Sample) -> Sample {
    var s = s_in;
    // Without a classification plugin: a grey ramp.
    s.color = vec4<f32>(s.value, s.value, s.value, s.value);
    s = p1_tf1d_classify(s);
    s = p3_tf1d_classify(s);
    return s;
}

fn run_shade(s_in: Sample) -> Sample {
    var s = s_in;
    s = p2_slice_shadow_shade(s);
    return s;
}

fn run_composite(s: Sample, c_in: vec4<f32>) -> vec4<f32> {
    var c = c_in;
    return c;
}

// Once per pixel after the loop: the accumulated premultiplied colour, before it is
// composited over the background (an image-space plugin: exposure, tone curves).
fn run_post(c_in: vec4<f32>, uv: vec2<f32>) -> vec4<f32> {
    var c = c_in;
    return c;
}

struct Evaluated {
    s: Sample,
    // premultiplied, opacity-corrected contribution of this sample
    c: vec4<f32>,
}

// `ratio` is the opacity correction's exponent Δs/Δs0, `step_ratio(s_in.step)`, which
// callers take once per ray (`RaySlices.ratio`) or fragment: llvmpipe hoists nothing out
// of a loop and would divide per sample (docs/perf.md, "Divisions once per ray"). CPU
// twin: vwb_render::reference (`evaluate`, which takes the ratio likewise).
fn evaluate(s_in: Sample, ratio: f32) -> Evaluated {
    var e: Evaluated;
    e.s = s_in;
    e.c = vec4<f32>(0.0);
    clip_cut_gradient = vec4<f32>(0.0);
    if (!run_clip(s_in)) {
        e.s.color = vec4<f32>(0.0);
        return e;
    }
    var s = run_sample(s_in);
    s = run_classify(s);
    s = run_shade(s);
    let a = correct_opacity_ratio(s.color.a, ratio);
    let rgb = clamp(s.color.rgb, vec3<f32>(0.0), vec3<f32>(1.0e6));
    e.c = run_composite(s, vec4<f32>(rgb * a, a));
    e.s = s;
    return e;
}

// The stack's clip, sample and classify hooks at a volume texture coordinate, for
// volume passes (light, occlusion): straight RGBA with α per Δs0, zero where clipped.
// `dir` is the direction the pass integrates along (Sample.ray_dir); the step is one
// voxel. Shading and soft clip edges (shade hooks) do not apply.
// CPU twin: vwb_render::reference (`stack_classify`).
fn stack_classify(tex: vec3<f32>, dir: vec3<f32>) -> vec4<f32> {
    var s: Sample;
    s.tex = tex;
    s.pos = frame.box_min.xyz + tex * (frame.box_max.xyz - frame.box_min.xyz);
    s.ray_dir = dir;
    s.uv = vec2<f32>(0.0);
    s.value = 0.0;
    s.step = frame.box_min.w;
    s.color = vec4<f32>(0.0);
    s.normal = vec3<f32>(0.0);
    s.shade_at = 0.0;
    s.slice = 0u;
    clip_cut_gradient = vec4<f32>(0.0);
    if (!run_clip(s)) {
        return vec4<f32>(0.0);
    }
    s = run_sample(s);
    s = run_classify(s);
    return s.color;
}

// Volume texture coordinate of a world point: a product with the box's reciprocal
// extent (`frame.inv_extent`), which saves a division per coordinate.
fn tex_of(pos: vec3<f32>) -> vec3<f32> {
    return (pos - frame.box_min.xyz) * frame.inv_extent.xyz;
}

// The distance along a ray between two slice planes (under half-angle slicing a ray
// may advance against the planes' normal): `Sample.step`, the same for all of a
// ray's samples.
fn ray_step(ray_dir: vec3<f32>) -> f32 {
    var step = frame.forward.w / max(dot(ray_dir, frame.forward.xyz), 1.0e-6);



    return step;
}

fn make_sample(pos: vec3<f32>, ray_dir: vec3<f32>, uv: vec2<f32>, slice: u32) -> Sample {
    return sample_with_step(pos, tex_of(pos), ray_dir, uv, slice, ray_step(ray_dir));
}

fn sample_with_step(pos: vec3<f32>, tex: vec3<f32>, ray_dir: vec3<f32>, uv: vec2<f32>, slice: u32, step: f32) -> Sample {
    var s: Sample;
    s.pos = pos;
    s.tex = tex;
    s.ray_dir = ray_dir;
    s.uv = uv;
    s.value = 0.0;
    s.step = step;
    s.color = vec4<f32>(0.0);
    s.normal = vec3<f32>(0.0);
    s.shade_at = 0.0;
    s.slice = slice;
    return s;
}

// Front-to-back "under" compositing: C += (1 − A)·c (c premultiplied).
fn under(acc: vec4<f32>, c: vec4<f32>) -> vec4<f32> {
    return acc + (1.0 - acc.a) * c;
}

// Back-to-front "over" compositing: C = c + (1 − a)·C, for a ray that meets the
// half-angle slices from back to front.
fn over(acc: vec4<f32>, c: vec4<f32>) -> vec4<f32> {
    return c + (1.0 - c.a) * acc;
}

// Round to fp16 like an rgba16float blend target does, so that both backends
// accumulate with the same precision: round to nearest, ties to even, with integer
// operations (NVIDIA's compiler folds unpack2x16float(pack2x16float(v)) to v, which
// left the compute backend accumulating in fp32 there). Normal range: keep 10 of the
// 23 mantissa bits; fp16's subnormal range (|v| < 2^-14): multiples of 2^-24, where
// round() ties to even. Values beyond fp16's range (65504) are not made infinite.
fn round_like_target(v: vec4<f32>) -> vec4<f32> {
    if (frame.counts.y == 0u) {
        return v;
    }
    let b = bitcast<vec4<u32>>(v);
    let normal = bitcast<vec4<f32>>((b + vec4<u32>(0x0FFFu) + ((b >> vec4<u32>(13u)) & vec4<u32>(1u))) & vec4<u32>(0xFFFFE000u));
    let subnormal = round(v * 16777216.0) * (1.0 / 16777216.0);
    return select(normal, subnormal, abs(v) < vec4<f32>(6.103515625e-5));
}

// ---------------------------------------------------------------- raster backend
// Proxy polygons (box ∩ slice plane) are drawn front to back; the blend state
// implements `under` (src·(1 − dst.a) + dst).

struct VsOut {
    @builtin(position) clip_pos: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) slice: u32,
    // the frame's fields that a fragment reads most, as flat outputs of every vertex
    // (where `FRAME_FROM_VERTEX`): written by `frame_to_vertex`, read by
    // `load_frame_fragment`; a field added here goes into both
    @location(2) @interpolate(flat) eye: vec4<f32>,
    @location(3) @interpolate(flat) forward: vec4<f32>,
    @location(4) @interpolate(flat) slicing: vec4<f32>,
    @location(5) @interpolate(flat) box_min: vec4<f32>,
    @location(6) @interpolate(flat) box_max: vec4<f32>,
    @location(7) @interpolate(flat) inv_extent: vec4<f32>,
    @location(8) @interpolate(flat) viewport: vec4<f32>,
    @location(9) @interpolate(flat) volume_dims: vec4<f32>,
    @location(10) @interpolate(flat) own_min: vec4<f32>,
    @location(11) @interpolate(flat) own_max: vec4<f32>,
    @location(12) @interpolate(flat) settings: vec4<f32>,
    @location(13) @interpolate(flat) counts: vec4<u32>,
    // the plugin instances' parameters that the fragments read, as flat words (from the
    // next location, as many as the device allows; render/src/composer.rs
    // `vertex_params_wgsl`, which also writes `params_to_vertex` and `params_from_vertex`)
    @location(14) @interpolate(flat) params_0: vec4<u32>,
    @location(15) @interpolate(flat) params_1: vec4<u32>,
}

// Whether the slices' fragments take the frame's most read fields from their vertices'
// flat outputs rather than from the uniform buffer (a pipeline constant: the renderer
// sets it on CPU devices, `Renderer::set_frame_from_vertex`). llvmpipe reads a uniform
// in a fragment shader one lane at a time, about 30 instructions a word, and a flat
// input as one broadcast; the values and so the images are the same (docs/perf.md, "The
// frame and the parameters as private copies"). GPUs read uniforms at no such cost and
// keep the buffer.
override FRAME_FROM_VERTEX: bool = false;

// A slice fragment's `load_frame`: the uniform's copy, with the fields of `VsOut`
// taken from the vertices where `FRAME_FROM_VERTEX` (a uniform word left unread after
// this is never loaded).
fn load_frame_fragment(in: VsOut) {
    load_frame();
    if (FRAME_FROM_VERTEX) {
        frame.eye = in.eye;
        frame.forward = in.forward;
        frame.slicing = in.slicing;
        frame.box_min = in.box_min;
        frame.box_max = in.box_max;
        frame.inv_extent = in.inv_extent;
        frame.viewport = in.viewport;
        frame.volume_dims = in.volume_dims;
        frame.own_min = in.own_min;
        frame.own_max = in.own_max;
        frame.settings = in.settings;
        frame.counts = in.counts;
        params_from_vertex(in);
    }
}

// Slices per proxy polygon on the raster backend (Rezk-Salama 2001, §9.1; a pipeline
// constant, 1 unless the renderer is asked for more, `Renderer::set_raster_group`):
// with n > 1 each polygon stands for the n slices from its own (`SlicePlan::
// group_polygon`), a fragment takes their samples along its ray and composites them,
// and the target blends once per n slices. Its depth is that of the group's last slice,
// so that the depth masks kill it only where they would kill all n.
override RASTER_GROUP: u32 = 1u;

// The frame's fields of `VsOut` and the routed parameters (`params_to_vertex`) for the
// fragments' `load_frame_fragment`, where `FRAME_FROM_VERTEX`.
fn frame_to_vertex(o: ptr<function, VsOut>) {
    if (FRAME_FROM_VERTEX) {
        (*o).eye = frame.eye;
        (*o).forward = frame.forward;
        (*o).slicing = frame.slicing;
        (*o).box_min = frame.box_min;
        (*o).box_max = frame.box_max;
        (*o).inv_extent = frame.inv_extent;
        (*o).viewport = frame.viewport;
        (*o).volume_dims = frame.volume_dims;
        (*o).own_min = frame.own_min;
        (*o).own_max = frame.own_max;
        (*o).settings = frame.settings;
        (*o).counts = frame.counts;
        params_to_vertex(o);
    }
}

@vertex
fn vs_main(@location(0) pos: vec3<f32>, @location(1) slice: u32) -> VsOut {
    load_frame_vertex();
    var o: VsOut;
    frame_to_vertex(&o);
    o.clip_pos = frame.view_proj * vec4<f32>(pos, 1.0);
    o.clip_pos.z = slice_depth(o.clip_pos, min(slice + RASTER_GROUP - 1u, max(frame.counts.x, 1u) - 1u));
    o.world = pos;
    o.slice = slice;
    return o;
}

// The depth of slice k's fragments: (k + ½) / count, not the camera's, so that the
// raster backend's depth tests compare slice indices (`renderer/raster_et.rs`: a pixel
// stops taking slices where its ray has terminated, and skips those before its next
// slice that can be visible). A view-aligned slice lies at one eye depth, so its
// vertices are all inside the near and far planes or all outside; those outside keep
// the camera's depth and are clipped as before. Half-angle slices are not view aligned
// and keep the camera's depth (their frames skip no slices).
fn slice_depth(c: vec4<f32>, k: u32) -> f32 {
    var z = select(c.z, (f32(k) + 0.5) / f32(frame.counts.x) * c.w, c.z >= 0.0 && c.z <= c.w);





    return z;
}

fn ray_dir_to(pos: vec3<f32>) -> vec3<f32> {
    if (frame.eye.w > 0.5) {
        return normalize(pos - frame.eye.xyz);
    }
    return frame.forward.xyz;
}

// Half-angle frames on the raster backend: a pipeline blends one order, so each pixel
// is drawn only by the pipeline of its own order ("under" where the ray advances along
// the slice normal, "over" where it meets the slices from behind, `fs_*_behind`). A
// frame whose pixels hold both orders draws each slice with both pipelines.
fn in_order(uv: vec2<f32>, behind: bool) -> bool {
    var keep = true;



    return keep;
}

fn fragment_proxy(in: VsOut, behind: bool) -> vec4<f32> {
    let uv = in.clip_pos.xy * frame.viewport.zw;
    if (!in_order(uv, behind)) {
        discard;
    }
    run_setup(pixel_ray(uv), uv);
    let dir = ray_dir_to(in.world);
    let s = make_sample(in.world, dir, uv, in.slice);
    let ratio = step_ratio(s.step);
    if (RASTER_GROUP == 1u) {
        return evaluate(s, ratio).c;
    }
    // the group's slices front to back along the ray, composited as the blend would
    // ("under"). Written out rather than a loop over i < RASTER_GROUP: the driver
    // unrolls such a loop only while the body stays under its size limit (Mesa's NIR
    // unroller: llvmpipe unrolled 8 slices of the 3D texture's body but not of the
    // z-pairs', and the loop cost 1.03–1.18× the frame; docs/perf.md). The guards are
    // constants once the pipeline is made, so each group keeps its own n steps.
    // The steps written cover `renderer::RASTER_GROUPS` (1, 2, 4, 8, 16; asserted there).
    var acc = group_step(vec4<f32>(0.0), s, ratio, in.world, dir, in.slice, 0u);
    acc = group_step(acc, s, ratio, in.world, dir, in.slice, 1u);
    if (RASTER_GROUP > 2u) {
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 2u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 3u);
    }
    if (RASTER_GROUP > 4u) {
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 4u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 5u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 6u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 7u);
    }
    if (RASTER_GROUP > 8u) {
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 8u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 9u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 10u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 11u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 12u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 13u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 14u);
        acc = group_step(acc, s, ratio, in.world, dir, in.slice, 15u);
    }
    return acc;
}

// Slice i of a raster group: its sample on the fragment's ray composited under `acc`,
// or nothing where it lies outside the box (the group's polygon covers all n).
fn group_step(acc: vec4<f32>, s: Sample, ratio: f32, world: vec3<f32>, dir: vec3<f32>, slice: u32, i: u32) -> vec4<f32> {
    var si = s;
    si.pos = world + dir * (f32(i) * s.step);
    si.tex = tex_of(si.pos);
    si.slice = slice + i;
    if (in_own_box(si.pos)) {
        return under(acc, evaluate(si, ratio).c);
    }
    return acc;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    load_frame_fragment(in);
    return fragment_proxy(in, false);
}

// The sample at the pixel's exact ray–plane point, as the compute backend takes it,
// rather than at the position interpolated over the proxy polygon: used when the
// proxies are cut to the occupied cells, whose sliver triangles interpolate poorly.
fn fragment_exact(in: VsOut, behind: bool) -> vec4<f32> {
    let uv = in.clip_pos.xy * frame.viewport.zw;
    if (!in_order(uv, behind)) {
        discard;
    }
    let r = pixel_ray(uv);
    let rs = ray_slices(r);
    if (!slice_point_in(rs, in.slice)) {
        return vec4<f32>(0.0);
    }
    run_setup(r, uv);
    return evaluate(slice_sample(r, rs, uv, in.slice), rs.ratio).c;
}

@fragment
fn fs_exact(in: VsOut) -> @location(0) vec4<f32> {
    load_frame_fragment(in);
    return fragment_exact(in, false);
}















// Empty-space skipping on the raster backend. Fragments cannot skip work by branching
// (llvmpipe runs both sides of a branch under a mask), only by failing the depth test
// before they are shaded. So a full-screen pass first marks, per pixel, the chunks of
// slices where its ray may meet a visible sample: bit j of the 64 is set where one of
// slices j·c … j·c + c − 1 (c = ⌈count / 64⌉, `chunk_slices`) may. The ray walks the
// bricks as the compute backend's march does (a lookup per pure box of bricks ahead, a
// jump past its exit slice, `brick_lookup`) and marks each visible box's slices with
// one more on either side, for the fragments' interpolated positions. `renderer/raster_et.rs` turns the bits into a
// depth before every run of slices. Samples outside the box take their face's brick.
fn chunk_slices() -> u32 {
    return max((frame.counts.x + 63u) / 64u, 1u);
}

// `bits` with the chunks of slices a..=b (c slices per chunk) set: per 32-bit word,
// the ones from its first chunk in the range to its last (no dynamic indexing, which a
// SIMD vector of pixels pays per lane).
fn mark_slices(bits: vec2<u32>, a: u32, b: u32, c: u32) -> vec2<u32> {
    let base = vec2<u32>(0u, 32u);
    let lo = max(vec2<u32>(a / c), base);
    let hi = min(vec2<u32>(min(b / c, 63u)), base + vec2<u32>(31u));
    // ones from bit lo − base up to bit hi − base of each word (none where lo > hi)
    let from_lo = vec2<u32>(0xFFFFFFFFu) << ((lo - base) & vec2<u32>(31u));
    let to_hi = vec2<u32>(0xFFFFFFFFu) >> ((base + vec2<u32>(31u) - hi) & vec2<u32>(31u));
    return bits | select(vec2<u32>(0u), from_lo & to_hi, lo <= hi);
}

// Vertex i of a triangle that covers the whole target (the chunk bits', the post hooks').
fn fullscreen_vertex(i: u32) -> vec4<f32> {
    let xy = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(xy * 2.0 - 1.0, 0.0, 1.0);
}

// The chunk bits' full-screen triangle, whose vertices carry the frame's fields to the
// fragments as the slices' do (`frame_to_vertex`).
@vertex
fn vs_chunks(@builtin(vertex_index) i: u32) -> VsOut {
    load_frame_vertex();
    var o: VsOut;
    frame_to_vertex(&o);
    o.clip_pos = fullscreen_vertex(i);
    return o;
}

@fragment
fn fs_raster_chunks(in: VsOut) -> @location(0) vec2<u32> {
    load_frame_fragment(in);
    let r = pixel_ray(in.clip_pos.xy * frame.viewport.zw);
    let range = slice_range(r, true);
    let rs = ray_slices(r);
    let c = chunk_slices();
    let tiny = vec3<f32>(1.0e-20);
    let inv_dtex = 1.0 / select(rs.dtex, tiny, abs(rs.dtex) < tiny);
    let grid = brick_grid();
    var bits = vec2<u32>(0u);
    var k = range.x;
    loop {
        if (k >= range.y) {
            break;
        }
        // the samples of the brick's pure box ahead end at its exit slice
        // (`brick_lookup`; the exit's margin keeps that one inside it), all of the
        // brick's kind; outside the box, one slice at a time
        var next = k + 1u;
        var visible: bool;
        if (in_own_box(rs.p0 + f32(k) * rs.dp)) {
            let b = brick_lookup(rs, inv_dtex, grid, k);
            next = max(b.x + 1u, next);
            visible = b.y != 0u;
        } else {
            let tex = rs.tex0 + f32(k) * rs.dtex;
            visible = brick_visible(grid, clamp(tex, vec3<f32>(0.0), vec3<f32>(1.0)));
        }
        if (visible) {
            bits = mark_slices(bits, max(k, 1u) - 1u, next, c);
        }
        k = next;
    }
    return bits;
}

// The post hooks on the raster backend: a full-screen triangle over the eye buffer,
// reading a copy of it (`post_src`), after the last slice.
@group(3) @binding(2) var post_src: texture_2d<f32>;

@vertex
fn vs_post(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    load_frame_vertex();
    return fullscreen_vertex(i);
}

@fragment
fn fs_post(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    load_frame();
    let c = textureLoad(post_src, vec2<i32>(pos.xy), 0);
    return run_post(c, pos.xy * frame.viewport.zw);
}

// ---------------------------------------------------------------- compute backend
// One invocation per pixel steps through the same slice planes: the sample of slice k
// is where the pixel's ray meets the plane at distance d_k = d_0 + k·Δs from the eye.

// The ray through a pixel. Built from the camera basis rather than by unprojecting
// with the inverse view-projection: with the near plane at 1e-3 that inverse is ill
// conditioned in f32 and put sample positions off by hundredths of a voxel.
fn pixel_ray(uv: vec2<f32>) -> Ray {
    let ndc = vec2<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
    var r: Ray;
    if (frame.eye.w > 0.5) {
        r.origin = frame.eye.xyz;
        r.dir = normalize((frame.ray_basis * vec4<f32>(ndc, 1.0, 0.0)).xyz);
    } else {
        r.origin = (frame.ray_basis * vec4<f32>(ndc, 0.0, 1.0)).xyz;
        r.dir = frame.ray_basis[2].xyz;
    }
    return r;
}

// Unit normal of the slice planes: the view's forward axis, or under half-angle
// slicing the half-angle axis (`frame.slicing`). Plain stacks read `forward`, as they
// did before half-angle slicing existed (reading `slicing` there cost lavapipe 2–4 %).
fn slice_normal() -> vec3<f32> {
    var n = frame.forward.xyz;



    return n;
}

// Where a ray meets the slice planes. Plane k lies at eye depth d_k = d_0 + k·Δs
// along the slice normal n, so the ray meets it at t_k = a + k·b with
// a = (d_0 − (origin − eye)·n) / (dir·n) and b = Δs / (dir·n): its point and texture
// coordinate are affine in k as well. A ray computes the three once; a sample then
// costs three multiply–adds each, where it cost a division for t and three for the
// texture coordinate (on lavapipe those divisions and the uniform loads around them
// were up to 15 % of an unshaded frame: docs/perf.md, "Per-sample overhead of the
// compute march"). Every path
// (the compute march, the per-slice dispatches, the raster backend's exact fragments)
// takes its points from here, so they agree on them to the bit, and so do the bricks
// of a split volume, which share the planes (`d_0`, `Δs`, k).
struct RaySlices {
    a: f32,
    b: f32,
    // world point and texture coordinate of plane 0 and their change per plane
    p0: vec3<f32>,
    dp: vec3<f32>,
    tex0: vec3<f32>,
    dtex: vec3<f32>,
    // the ray's `Sample.step` and its ratio to Δs0 (the opacity correction's exponent)
    step: f32,
    ratio: f32,
}

fn ray_slices(r: Ray) -> RaySlices {
    let n = slice_normal();
    let dd = dot(r.dir, n);
    var rs: RaySlices;
    rs.a = (frame.box_max.w - dot(r.origin - frame.eye.xyz, n)) / dd;
    rs.b = frame.forward.w / dd;
    rs.p0 = r.origin + r.dir * rs.a;
    rs.dp = r.dir * rs.b;
    rs.tex0 = tex_of(rs.p0);
    rs.dtex = rs.dp * frame.inv_extent.xyz;
    rs.step = ray_step(r.dir);
    rs.ratio = step_ratio(rs.step);
    return rs;
}

// Whether the ray's point on slice plane k is a sample: in front of the eye (t ≥ 0;
// not NaN, which a ray parallel to the planes could give) and inside this renderer's
// own box.
fn slice_point_in(rs: RaySlices, k: u32) -> bool {
    let t = rs.a + f32(k) * rs.b;
    return t >= 0.0 && in_own_box(rs.p0 + f32(k) * rs.dp);
}

// The slices of `range` that are samples (`slice_point_in`): [first, end). They are
// one run: each of the test's conditions is monotone in k (t and the point's
// coordinates are f32(k) times a constant plus a constant, and rounding keeps the
// order), so the samples of a range lie between its first and its last. The loops
// step over the range's rounding margins with the test alone, where the march would
// pay a whole iteration per slice (a SIMD vector of rays runs its body under a mask).
fn sample_run(rs: RaySlices, range: vec2<u32>) -> vec2<u32> {
    var first = range.x;
    while (first < range.y && !slice_point_in(rs, first)) {
        first = first + 1u;
    }
    var end = range.y;
    while (end > first && !slice_point_in(rs, end - 1u)) {
        end = end - 1u;
    }
    return vec2<u32>(first, end);
}

// The sample of slice k on the ray (at a point `slice_point_in` accepted).
fn slice_sample(r: Ray, rs: RaySlices, uv: vec2<f32>, k: u32) -> Sample {
    return sample_with_step(rs.p0 + f32(k) * rs.dp, rs.tex0 + f32(k) * rs.dtex, r.dir, uv, k, rs.step);
}

// Whether a world point is one of this renderer's samples: inside its own box, which
// is half-open at faces shared with the next brick so that a sample on a brick face
// belongs to one brick only.
fn in_own_box(p: vec3<f32>) -> bool {
    let m = u32(frame.own_max.w);
    let open = vec3<bool>((m & 1u) != 0u, (m & 2u) != 0u, (m & 4u) != 0u);
    let above = select(p > frame.own_max.xyz, p >= frame.own_max.xyz, open);
    return !(any(p < frame.own_min.xyz) || any(above));
}

// The ray's parameter interval `t` (x: entry, y: exit) narrowed to the slab
// lo ≤ n·p ≤ hi; a ray parallel to the slab keeps `t` inside it and empties it outside.
fn slab(t: vec2<f32>, r: Ray, n: vec3<f32>, lo: f32, hi: f32) -> vec2<f32> {
    let dn = dot(r.dir, n);
    let d = select(dn, 1.0e-20, abs(dn) < 1.0e-20);
    let o = dot(r.origin, n);
    let ta = (lo - o) / d;
    let tb = (hi - o) / d;
    return vec2<f32>(max(t.x, min(ta, tb)), min(t.y, max(ta, tb)));
}

// `t` narrowed to the occupied bricks' hull: its ten diagonal slabs (`frame.hull`, in
// the order of `Dop::DIRS[3..]`).
fn hull_slabs(r: Ray, t0: vec2<f32>) -> vec2<f32> {
    let a = 0.70710677;
    let b = 0.57735026;
    let h = frame.hull;
    var t = slab(t0, r, vec3<f32>(a, a, 0.0), h[0].x, h[0].y);
    t = slab(t, r, vec3<f32>(a, -a, 0.0), h[0].z, h[0].w);
    t = slab(t, r, vec3<f32>(a, 0.0, a), h[1].x, h[1].y);
    t = slab(t, r, vec3<f32>(a, 0.0, -a), h[1].z, h[1].w);
    t = slab(t, r, vec3<f32>(0.0, a, a), h[2].x, h[2].y);
    t = slab(t, r, vec3<f32>(0.0, a, -a), h[2].z, h[2].w);
    t = slab(t, r, vec3<f32>(b, b, b), h[3].x, h[3].y);
    t = slab(t, r, vec3<f32>(b, b, -b), h[3].z, h[3].w);
    t = slab(t, r, vec3<f32>(b, -b, b), h[4].x, h[4].y);
    return slab(t, r, vec3<f32>(b, -b, -b), h[4].z, h[4].w);
}

// Slices [first, last) that can meet the box along the ray: the ray's slab interval
// through the box mapped to slice indices, widened by two slices against rounding.
// Every slice in the range is still tested exactly by slice_point_in, so the samples are
// the same as looping over all slices; the range only skips planes the ray cannot hit
// inside the box (pixels that miss the box loop over none). With `hull` (a constant at
// each call site) and `frame.counts.w` set, the interval is also cut to the occupied
// bricks' hull: every sample it leaves out lies in an empty brick, where skipping would
// have jumped over it, so the samples evaluated are the same.
fn slice_range(r: Ray, hull: bool) -> vec2<u32> {
    let tiny = vec3<f32>(1.0e-20);
    let d = select(r.dir, tiny, abs(r.dir) < tiny);
    let ta = (frame.own_min.xyz - r.origin) / d;
    let tb = (frame.own_max.xyz - r.origin) / d;
    var t = vec2<f32>(
        max(max(min(ta.x, tb.x), min(ta.y, tb.y)), min(ta.z, tb.z)),
        min(min(max(ta.x, tb.x), max(ta.y, tb.y)), max(ta.z, tb.z)),
    );
    if (hull && frame.counts.w != 0u) {
        t = hull_slabs(r, t);
    }
    let t_in = t.x;
    let t_out = t.y;
    let count = frame.counts.x;
    if (t_out < t_in) {
        return vec2<u32>(0u, 0u);
    }
    let n = slice_normal();
    let dd = dot(r.dir, n);
    let depth0 = dot(r.origin - frame.eye.xyz, n);
    let ka = (depth0 + t_in * dd - frame.box_max.w) / frame.forward.w;
    let kb = (depth0 + t_out * dd - frame.box_max.w) / frame.forward.w;
    let lo = floor(min(ka, kb)) - 2.0;
    let hi = ceil(max(ka, kb)) + 3.0;
    // not finite (NaN fails both comparisons): fall back to every slice
    if (!(lo <= hi)) {
        return vec2<u32>(0u, count);
    }
    let first = u32(clamp(lo, 0.0, f32(count)));
    let last = u32(clamp(hi, 0.0, f32(count)));
    return vec2<u32>(first, last);
}

// The last slice whose sample may still lie in a box of bricks that the ray leaves
// through the faces `far` (texture coordinates; rounded down with a margin, so that no
// slice beyond the box is ever skipped). The ray's samples lie at tex0 + k·dtex
// (`RaySlices`), so it leaves at the least over the axes of (far − tex0) / dtex;
// `inv_dtex` is the ray's 1 / dtex (a tiny step in place of a zero one), so the exit
// costs no division. The far face is, per axis, the one ahead of the ray (its
// `ahead`: inv_dtex > 0), which is where the larger of the two faces' quotients lies:
// taking it alone gives that larger one to the bit, at half the work. All finite (no
// NaN), so `select` stands for min.
fn far_exit_slice(rs: RaySlices, inv_dtex: vec3<f32>, far: vec3<f32>) -> u32 {
    let kf = (far - rs.tex0) * inv_dtex;
    let kxy = select(kf.y, kf.x, kf.x < kf.y);
    let k = floor(select(kf.z, kxy, kxy < kf.z) - 0.01);
    // not finite: no jump
    if (!(k >= 0.0)) {
        return 0u;
    }
    return u32(min(k, f32(frame.counts.x)));
}

// The far faces (texture coordinates) of the box of bricks from `brick` reaching `r`
// bricks further along the ray on each axis: beyond the brick's own far face by r
// bricks; the faces ahead stop at the volume's (texture coordinate 1), and faces
// beyond the grid are as good as any, since no sample lies there.
fn far_faces(inv_dtex: vec3<f32>, g: BrickGrid, brick: vec3<f32>, r: f32) -> vec3<f32> {
    let ahead = inv_dtex > vec3<f32>(0.0);
    return select((brick - r) * g.side, min((brick + (r + 1.0)) * g.side, vec3<f32>(1.0)), ahead);
}

// The march's lookup at slice k's sample on the ray: (the last slice that may still lie
// in its brick's pure box ahead, `far_exit_slice`; 1 where the brick may be visible,
// else 0). Every brick of the box, the (r + 1)³ from it in the ray's direction
// (`brick_cell`), is of that kind, so the march jumps over an empty one's whole box and
// takes a visible one's samples up to the exit without looking up the bricks between
// (docs/perf.md, "Pure boxes ahead of the ray").
fn brick_lookup(rs: RaySlices, inv_dtex: vec3<f32>, g: BrickGrid, k: u32) -> vec2<u32> {
    if (frame.settings.y <= 0.0) {
        return vec2<u32>(0u, 1u);
    }
    let brick = brick_of(g, rs.tex0 + f32(k) * rs.dtex);
    let back = inv_dtex < vec3<f32>(0.0);
    let octant = select(0u, 1u, back.x) | select(0u, 2u, back.y) | select(0u, 4u, back.z);
    let cell = brick_cell(g, brick, octant);
    let far = far_faces(inv_dtex, g, brick, f32(cell & 127u));
    return vec2<u32>(far_exit_slice(rs, inv_dtex, far), cell >> 7u);
}

@group(3) @binding(0) var out_tex: texture_storage_2d<rgba16float, write>;
@group(3) @binding(1) var<storage, read_write> accum: array<vec4<f32>>;

// The whole-frame march in parts (render/src/renderer/march_parts.rs). llvmpipe stops a
// shader invocation after 65 535 loop iterations counted over all its loops (gallivm's
// loop limiter: one counter per SIMD vector of 8 invocations; a loop ends silently
// once it runs out, and after that every loop runs its body once). The march costs one
// or two per slice (an inner loop costs one per iteration of the loop around it even
// where no lane enters it: its branches run under masks), and a plugin's loops cost
// theirs per sample (flow.lic3d on the fly: hundreds). So on such a device the renderer
// dispatches a frame's slices in parts of a size its budget allows: part
// [start, end) marches those slices of each ray from the colour the part before left in
// `accum` (the first from 0), and the last (end 0: to the ray's end) stores the pixel.
// A ray is stateless between samples but for that colour (the raster backend evaluates
// every sample on its own), so the image is the whole march's bit for bit.
struct MarchPart {
    start: u32,
    // 0: the last part (to the end of every ray)
    end: u32,
    // 2 (`note_loop_limit`; a uniform, so that no compiler folds its loop)
    probe: u32,
    pad: u32,
}
@group(3) @binding(2) var<uniform> march_part: MarchPart;
// How many invocations ran out of loop iterations (`note_loop_limit`).
@group(3) @binding(3) var<storage, read_write> loop_limit: array<atomic<u32>>;

// Counts the invocation in `loop_limit` where the loop limiter has run out: a loop of
// `march_part.probe` (2) iterations ends after one when it has (and never on a GPU).
// The renderer then marches in smaller parts and renders again
// (`Renderer::render`).
fn note_loop_limit() {
    var i = 0u;
    loop {
        i = i + 1u;
        if (i >= march_part.probe) {
            break;
        }
    }
    if (i < march_part.probe) {
        atomicAdd(&loop_limit[0], 1u);
    }
}

// Front to back over the ray's samples (`sample_run`) within `part` (slices
// [part.x, part.y)), from `acc_in`. With `skipping`, a sample in an
// empty brick jumps to the last slice that may still lie in that brick: the skipped
// slices' samples would be transparent (render/src/skipping.rs). One brick lookup per
// brick the ray enters, not per sample: after a visible brick the samples up to its exit slice
// are evaluated without a lookup. Should the exit be off by rounding, the extra sample
// lies in an empty brick, adds exactly nothing and changes nothing either. Runs of
// empty bricks are crossed in an inner loop of lookups and jumps, so that a ray in
// empty space does not hold its SIMD vector's other rays in whole iterations of sample
// work (docs/perf.md, "A ray's samples as one run"); it costs llvmpipe's loop limiter
// up to one more iteration per slice (`MarchPart`). `skipping` is a constant at every
// call site, so each entry point compiles only its own loop.
fn march(r: Ray, uv: vec2<f32>, skipping: bool, acc_in: vec4<f32>, part: vec2<u32>) -> vec4<f32> {
    var acc = acc_in;
    let early = frame.counts.z != 0u;
    let range = slice_range(r, skipping);
    let rs = ray_slices(r);
    // the first slice whose brick is still to be looked up
    var lookup = 0u;
    let tiny = vec3<f32>(1.0e-20);
    let inv_dtex = 1.0 / select(rs.dtex, tiny, abs(rs.dtex) < tiny);
    let grid = brick_grid();
    run_setup(r, uv);
    let whole = sample_run(rs, range);
    var run = vec2<u32>(max(whole.x, part.x), min(whole.y, part.y));
    // a ray that terminated in an earlier part takes no more samples
    if (early && acc.a >= frame.settings.x) {
        run.y = run.x;
    }
    for (var k = run.x; k < run.y; k = k + 1u) {
        if (skipping && k >= lookup) {
            // over the empty bricks ahead: a lookup and a jump each, no sample work
            var exit = 0u;
            loop {
                let b = brick_lookup(rs, inv_dtex, grid, k);
                exit = b.x;
                if (b.y != 0u) {
                    break;
                }
                k = max(exit, k + 1u);
                if (k >= run.y) {
                    break;
                }
            }
            if (k >= run.y) {
                break;
            }
            lookup = exit + 1u;
        }
        let e = evaluate(slice_sample(r, rs, uv, k), rs.ratio);
        acc = round_like_target(under(acc, e.c));
        if (early && acc.a >= frame.settings.x) {
            break;
        }
    }
    return acc;
}

// The first pixel of the dispatch: a brick of a split volume dispatches only the
// pixels its own box can cover (frame.settings.zw; 0 for a whole volume).
fn dispatch_offset() -> vec2<u32> {
    return vec2<u32>(frame.settings.zw);
}

// The whole-frame entry points' workgroup shape (`composer::with_main_workgroup`
// rewrites it with their `@workgroup_size`).
const MAIN_WG: vec2<u32> = vec2<u32>(8u, 8u);

// The pixel of invocation `li` of workgroup `wg` in the whole-frame entry points. A CPU
// device runs a workgroup's invocations in SIMD vectors of consecutive `li` (8 on
// llvmpipe with AVX2) until the vector's last ray ends, so a vector costs its longest
// ray's iterations. Rows of 8 pixels make such vectors; here every 8 consecutive
// invocations cover a block of 4 × 2 pixels instead (every 32 an 8 × 4 block, a GPU
// warp's footprint as in rows), whose rays end more alike: early termination and the
// hull end them at the matter's silhouette, which a compact block crosses less often.
// The pixels and their rays are the same, and so is the image (docs/perf.md, "Pixel
// blocks per SIMD vector"). Shapes that 4 × 2 does not divide keep rows.
fn main_pixel(wg: vec3<u32>, groups: vec3<u32>, li: u32) -> vec2<u32> {
    var l = vec2<u32>(li % MAIN_WG.x, li / MAIN_WG.x);
    if (MAIN_WG.x % 4u == 0u && MAIN_WG.y % 2u == 0u) {
        let block = li / 8u;
        // (at least 1: a shape this branch never runs for must still not divide by 0)
        let row = max(MAIN_WG.x / 4u, 1u);
        l = vec2<u32>((block % row) * 4u + (li & 3u), (block / row) * 2u + ((li >> 2u) & 1u));
    }
    let tile = vec2<u32>(wg.x, spread_row(wg.y, groups.y));
    return tile * MAIN_WG + l + dispatch_offset();
}

// The tile row that the dispatch's workgroup row `q` of `rows` renders: (q · s) mod
// rows, with s the first integer from ⌊rows · (√5 − 1)/2⌋ up that is coprime to `rows`
// (so a permutation of the rows). A CPU device splits a dispatch's workgroups, in order (x
// fastest), into one contiguous run per thread (llvmpipe's compute thread pool), so in
// plain order each thread renders a band of the image, and the thread whose band holds
// more of the matter works on after the others have finished. Rows spread by the
// golden ratio give every contiguous run, whatever the number of threads, rows from all
// over the image. The pixels are the same, and so is the image (docs/perf.md, "Pixel
// blocks per SIMD vector"). The frame's uniform holds s for its dispatch's rows (the
// search below cost every invocation a dozen integer divisions, which a CPU device
// runs one lane at a time: docs/perf.md, "The rows' stride once per frame"); it runs
// only for another number of rows.
fn spread_row(q: u32, rows: u32) -> u32 {
    if (rows == frame.spread.x) {
        return (q * frame.spread.y) % max(rows, 1u);
    }
    var s = max(u32(f32(rows) * 0.618034), 1u);
    loop {
        var a = s;
        var b = rows;
        while (b != 0u) {
            let t = a % b;
            a = b;
            b = t;
        }
        if (a <= 1u) {
            break;
        }
        s = s + 1u;
    }
    return (q * s) % max(rows, 1u);
}

// The whole-frame entry points' work: invocation `li`'s pixel, its ray marched over
// `march_part` and stored (`skipping` as in `march`: a constant at every call site).
fn march_pixel(wg: vec3<u32>, groups: vec3<u32>, li: u32, skipping: bool) {
    let size = vec2<u32>(frame.viewport.xy);
    let px = main_pixel(wg, groups, li);
    if (px.x >= size.x || px.y >= size.y) {
        return;
    }
    let uv = (vec2<f32>(px) + 0.5) * frame.viewport.zw;
    let idx = px.y * size.x + px.x;
    var acc = vec4<f32>(0.0);
    if (march_part.start != 0u) {
        acc = accum[idx];
    }
    let last = march_part.end == 0u;
    let part = vec2<u32>(march_part.start, select(march_part.end, 0xffffffffu, last));
    acc = march(pixel_ray(uv), uv, skipping, acc, part);
    note_loop_limit();
    if (last) {
        textureStore(out_tex, vec2<i32>(px), run_post(acc, uv));
    } else {
        accum[idx] = acc;
    }
}

// Whole frame in one dispatch (no plugin needs per-slice passes).
@compute @workgroup_size(8, 8, 1)
fn cs_main(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    load_frame();
    march_pixel(wg, groups, li, false);
}

// `cs_main` with empty-space skipping (used while the occupancy grid is active).
@compute @workgroup_size(8, 8, 1)
fn cs_main_skip(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    load_frame();
    march_pixel(wg, groups, li, true);
}

// The samples `cs_main` takes, with one trilinear fetch of the volume each and nothing
// else (no hooks, skipping or early termination): the raw sampling rate that plain DVR
// is measured against (issue 23). Run instead of `cs_main` under the benchmark switch
// `VWB_RAW_SAMPLES=1` (`Renderer::set_raw_samples`); stores (Σ value, sample count, 0,
// 1), so a test can check that it takes exactly the march's samples.
@compute @workgroup_size(8, 8, 1)
fn cs_main_raw(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    load_frame();
    let size = vec2<u32>(frame.viewport.xy);
    let px = main_pixel(wg, groups, li);
    if (px.x >= size.x || px.y >= size.y) {
        return;
    }
    let uv = (vec2<f32>(px) + 0.5) * frame.viewport.zw;
    let r = pixel_ray(uv);
    let range = slice_range(r, false);
    let rs = ray_slices(r);
    var sum = 0.0;
    var n = 0.0;
    let run = sample_run(rs, range);
    for (var k = run.x; k < run.y; k = k + 1u) {
        sum = sum + volume_value(rs.tex0 + f32(k) * rs.dtex);
        n = n + 1.0;
    }
    textureStore(out_tex, vec2<i32>(px), vec4<f32>(sum, n, 0.0, 1.0));
}

// Slice `slice_info.index` at pixel `px`: composites its sample into `accum` (unless
// the pixel's ray has terminated early) and returns it. With `always`, the sample is
// evaluated even where the ray terminated, for the per-slice state updates of the
// fused entry point; `always` is a constant at both call sites.
fn slice_step(px: vec2<u32>, size: vec2<u32>, always: bool) -> Evaluated {
    let idx = px.y * size.x + px.x;
    // The eye buffer is read only where early termination needs it or the sample adds
    // something, and written only where it changes (and at the first slice, which
    // starts it at 0): a sample that adds exactly nothing leaves it as it is, since
    // under(acc, 0) = over(acc, 0) = acc and round_like_target is idempotent.
    let first = slice_info.index == 0u;
    let et = frame.counts.z != 0u;
    var acc = vec4<f32>(0.0);
    var read = first;
    if (et && !first) {
        acc = accum[idx];
        read = true;
    }
    let uv = (vec2<f32>(px) + 0.5) * frame.viewport.zw;
    let r = pixel_ray(uv);
    // front to back unless the ray meets the (half-angle) slices from behind
    var ahead = true;



    let early = ahead && et && acc.a >= frame.settings.x;
    let rs = ray_slices(r);
    let hit = slice_point_in(rs, slice_info.index);
    var e = placeholder(r, uv);
    var changed = first;
    if (hit && (always || !early)) {
        e = evaluate(slice_sample(r, rs, uv, slice_info.index), rs.ratio);
        if (!early && any(e.c != vec4<f32>(0.0))) {
            if (!read) {
                acc = accum[idx];
            }
            if (ahead) {
                acc = round_like_target(under(acc, e.c));
            } else {
                acc = round_like_target(over(acc, e.c));
            }
            changed = true;
        }
    }
    if (changed) {
        accum[idx] = acc;
    }
    return e;
}

// The tile (of 8 × 8 pixels) of workgroup `wg` of a per-slice entry point:
// where `slice_info` lists this slice's tiles, the listed one (beyond the list, one
// outside every eye buffer), else `wg` itself.
fn slice_tile(wg: vec2<u32>) -> vec2<u32> {
    if (slice_info.tile_row == 0u) {
        return wg;
    }
    let i = wg.y * slice_info.tile_row + wg.x;
    if (i >= slice_info.tile_count) {
        return vec2<u32>(0xffffu);
    }
    let t = slice_tile_list[slice_info.tile_offset + i];
    return vec2<u32>(t & 0xffffu, t >> 16u);
}

// The sample of slice `slice_info.index` at pixel `px` where it is known to be
// transparent (no visible sample lies under its tile): the ray's placeholder, colour 0,
// as `slice_step` starts it, handed to the state updates unevaluated.
fn slice_placeholder(px: vec2<u32>) -> Evaluated {
    let uv = (vec2<f32>(px) + 0.5) * frame.viewport.zw;
    return placeholder(pixel_ray(uv), uv);
}

// The placeholder sample of slice `slice_info.index` on ray `r` (pixel `uv`), after
// the ray's setup hooks: the ray's `make_sample`, colour 0.
fn placeholder(r: Ray, uv: vec2<f32>) -> Evaluated {
    run_setup(r, uv);
    var e: Evaluated;
    e.s = make_sample(r.origin, r.dir, uv, slice_info.index);
    e.c = vec4<f32>(0.0);
    return e;
}

// One slice per dispatch, accumulating in `accum` (used when a plugin has per-slice
// state whose resolution differs from the eye buffer's; otherwise `cs_slice_fused`),
// over the slice's tiles (`slice_tile`; where `slice_info` lists them, those where its
// sample can be visible: elsewhere it adds nothing).
@compute @workgroup_size(8, 8, 1)
fn cs_slice(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    load_frame();
    let size = vec2<u32>(frame.viewport.xy);
    let gid = slice_tile(wg.xy) * 8u + lid.xy;
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    slice_step(gid, size, false);
}

// Copy the accumulation buffer into the eye buffer.
@compute @workgroup_size(8, 8, 1)
fn cs_resolve(@builtin(global_invocation_id) gid: vec3<u32>) {
    load_frame();
    let size = vec2<u32>(frame.viewport.xy);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let uv = (vec2<f32>(gid.xy) + 0.5) * frame.viewport.zw;
    textureStore(out_tex, vec2<i32>(gid.xy), run_post(accum[gid.y * size.x + gid.x], uv));
}

// The ray of per-slice state coordinate `uv`: the pixel's, or under half-angle
// slicing the light's ray through the state texel (origin upstream of the box).
fn state_ray(uv: vec2<f32>) -> Ray {









    return pixel_ray(uv);
}

// Sample of the current slice under a state texel (for per-slice state updates), with
// the texel's coordinate as `s.uv` (the pixel's in view-aligned slicing; under
// half-angle slicing a light-space coordinate, which `state_coord` also gives).
fn state_texel_sample(texel: vec2<u32>, state_size: vec2<u32>) -> Evaluated {
    let uv = (vec2<f32>(texel) + 0.5) / vec2<f32>(state_size);
    let r = state_ray(uv);
    let k = slice_info.index;
    let rs = ray_slices(r);
    run_setup(r, uv);
    var e: Evaluated;
    if (!slice_point_in(rs, k)) {
        e.s = make_sample(r.origin, r.dir, uv, k);
        e.c = vec4<f32>(0.0);
        return e;
    }
    return evaluate(slice_sample(r, rs, uv, k), rs.ratio);
}

// The state update of one slice: over the slice's listed tiles where the
// state has the size of the list's grid (`slice_tile`), else over every texel.
@compute @workgroup_size(8, 8, 1)
fn cs_update_2(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    load_frame();
    let size = textureDimensions(p2_slice_shadow_state_next);
    var tile = wg.xy;
    let grid = vec2<u32>(slice_info.list_size & 0xffffu, slice_info.list_size >> 16u);
    if (all(size == grid)) {
        tile = slice_tile(wg.xy);
    }
    let gid = vec3<u32>(tile * 8u + lid.xy, 0u);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let e = state_texel_sample(gid.xy, size);
    textureStore(p2_slice_shadow_state_next, vec2<i32>(gid.xy), p2_slice_shadow_slice_update(e.s, e.c, e.s.uv));
}
// The slice and every state update in one dispatch, each sample evaluated once
// (used when every per-slice state has the eye buffer's resolution), over the
// slice's tiles (`slice_tile`).
@compute @workgroup_size(8, 8, 1)
fn cs_slice_fused(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    load_frame();
    let size = vec2<u32>(frame.viewport.xy);
    let gid = vec3<u32>(slice_tile(wg.xy) * 8u + lid.xy, 0u);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let e = slice_step(gid.xy, size, true);
    textureStore(p2_slice_shadow_state_next, vec2<i32>(gid.xy), p2_slice_shadow_slice_update(e.s, e.c, e.s.uv));
}
// The state updates alone over the slice's tiles where no sample can be visible
// (`slice_tile`): every update gets the pixel's transparent placeholder sample.
@compute @workgroup_size(8, 8, 1)
fn cs_slice_state_only(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    load_frame();
    let size = vec2<u32>(frame.viewport.xy);
    let gid = vec3<u32>(slice_tile(wg.xy) * 8u + lid.xy, 0u);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let e = slice_placeholder(gid.xy);
    textureStore(p2_slice_shadow_state_next, vec2<i32>(gid.xy), p2_slice_shadow_slice_update(e.s, e.c, e.s.uv));
}
