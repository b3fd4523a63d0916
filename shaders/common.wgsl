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
// volume_z_pairs: begin
@group(0) @binding(1) var volume_tex: texture_2d_array<f32>;

// Scalar at a texture coordinate (trilinear): layer k holds (v(k), v(k + 1)), the
// last its value twice; clamped to the edge as the 3D sampler is (below the first
// layer's centre the weight in z is 0).
fn volume_value(tex: vec3<f32>) -> f32 {
    let n = f32(textureNumLayers(volume_tex));
    let z = tex.z * n - 0.5;
    let k = floor(z);
    let pair = textureSampleLevel(volume_tex, linear_clamp, tex.xy, i32(clamp(k, 0.0, n - 1.0)), 0.0);
    return mix(pair.x, pair.y, select(z - k, 0.0, k < 0.0));
}

// The volume's size in voxels.
fn volume_dims() -> vec3<u32> {
    return vec3<u32>(textureDimensions(volume_tex), textureNumLayers(volume_tex));
}

// Scalar at an integer voxel (no filtering); clamps to the volume.
fn volume_voxel(v: vec3<i32>) -> f32 {
    let c = clamp(v, vec3<i32>(0), vec3<i32>(volume_dims()) - vec3<i32>(1));
    return textureLoad(volume_tex, c.xy, c.z, 0).r;
}
// volume_z_pairs: end

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
    // half_angle: begin
    c = select(uv, light_uv(pos), half_angle());
    // half_angle: end
    return c;
}

// State-uv units per world unit across the per-slice state's rays on slice k's plane:
// the screen's at the slice's depth (Schott et al. 2009, eqs 12–15), or the light
// space's under half-angle slicing. Twin: CpuView::state_uv_per_world.
fn state_uv_per_world(k: u32) -> vec2<f32> {
    // half_angle: begin
    if (half_angle()) {
        return 0.5 / vec2<f32>(length(frame.state_rays[0].xyz), length(frame.state_rays[1].xyz));
    }
    // half_angle: end
    var depth = 1.0;
    if (frame.eye.w > 0.5) {
        depth = max(frame.box_max.w + f32(k) * frame.forward.w, 1.0e-9);
    }
    return 0.5 / (vec2<f32>(length(frame.ray_basis[0].xyz), length(frame.ray_basis[1].xyz)) * depth);
}

// The path length of the per-slice state's rays between two slice planes: the slice
// spacing, or the light's step under half-angle slicing. Twin: CpuView::state_step.
fn state_step() -> f32 {
    // half_angle: begin
    if (half_angle()) {
        return frame.light.w;
    }
    // half_angle: end
    return frame.forward.w;
}
