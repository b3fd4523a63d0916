// vwb slice template: the hook runners and the entry points of both backends.
// The composer inserts generated declarations at `//!DECLS`, plugin code at `//!PLUGINS`
// and generated hook calls at each `//!HOOK name` marker, in the order of the user's
// plugin stack. Once per ray: setup; then per sample: clip -> sample -> classify ->
// shade -> composite; once per pixel after the loop: post.

//!DECLS

//!PLUGINS

// Once per ray (per pixel), before its samples: each `setup` hook fills its own
// instance's `ray_record`, which that instance's hooks then read for every sample of the
// ray (e.g. a per-pixel jitter). The raster backend runs it per fragment on the pixel's
// exact ray, which gives the same record since it depends on the ray alone.
fn run_setup(r: Ray, uv: vec2<f32>) {
//!HOOK setup
}

fn run_clip(s: Sample) -> bool {
//!HOOK clip
    return true;
}

fn run_sample(s_in: Sample) -> Sample {
    var s = s_in;
    s.value = sample_value(s.tex);
//!HOOK sample
    return s;
}

fn run_classify(s_in: Sample) -> Sample {
    var s = s_in;
    // Without a classification plugin: a grey ramp.
    s.color = vec4<f32>(s.value, s.value, s.value, s.value);
//!HOOK classify
    return s;
}

fn run_shade(s_in: Sample) -> Sample {
    var s = s_in;
//!HOOK shade
    return s;
}

fn run_composite(s: Sample, c_in: vec4<f32>) -> vec4<f32> {
    var c = c_in;
//!HOOK composite
    return c;
}

// Once per pixel after the loop: the accumulated premultiplied colour, before it is
// composited over the background (an image-space plugin: exposure, tone curves).
fn run_post(c_in: vec4<f32>, uv: vec2<f32>) -> vec4<f32> {
    var c = c_in;
//!HOOK post
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
    // half_angle: begin
    step = frame.forward.w / max(abs(dot(ray_dir, frame.slicing.xyz)), 1.0e-6);
    // half_angle: end
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
    //!VERTEX_PARAMS
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
    // half_angle: begin
    if (half_angle()) {
        z = c.z;
    }
    // half_angle: end
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
    // half_angle: begin
    keep = !half_angle() || ((dot(pixel_ray(uv).dir, frame.slicing.xyz) < 0.0) == behind);
    // half_angle: end
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

// half_angle: begin
@fragment
fn fs_main_behind(in: VsOut) -> @location(0) vec4<f32> {
    load_frame_fragment(in);
    return fragment_proxy(in, true);
}

@fragment
fn fs_exact_behind(in: VsOut) -> @location(0) vec4<f32> {
    load_frame_fragment(in);
    return fragment_exact(in, true);
}
// half_angle: end

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
    // half_angle: begin
    n = frame.slicing.xyz;
    // half_angle: end
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

@group(3) @binding(0) var out_tex: texture_storage_2d<{{TARGET_FORMAT}}, write>;
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
    // half_angle: begin
    ahead = dot(r.dir, frame.slicing.xyz) >= 0.0;
    // half_angle: end
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
    // half_angle: begin
    if (half_angle()) {
        let ndc = vec2<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
        var r: Ray;
        r.origin = (frame.state_rays * vec4<f32>(ndc, 0.0, 1.0)).xyz;
        r.dir = frame.state_rays[2].xyz;
        return r;
    }
    // half_angle: end
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

//!UPDATES
