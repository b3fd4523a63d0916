// The raster backend's depth before a run of slices (issue 23, item 2): early ray
// termination and empty-space skipping.
//
// Slice k's fragments lie at depth (k + ½) / count (`slice_depth` in
// shaders/slice.wgsl) and pass the depth test `greater`, against a buffer cleared to 0.
// Before the run of slices starting at slice `first`, this pass writes per pixel:
// - 1 (no later slice passes) where the eye buffer's opacity has reached the threshold,
//   at the runs where termination is checked (every `counts.z` slices);
// - with the chunk bits of `fs_raster_chunks` (64 per pixel; counts.y slices per bit, 0: none), the
//   depth just in front of the first slice from `first` on that may be visible, or 1
//   where none may.
// The pass's own depth test `greater-equal` keeps the larger of the old and the new
// depth: a pixel that stopped stays stopped, and the skipped slices stay skipped.
// No colour is written.

struct Mask {
    // x: the opacity at which a pixel stops taking slices
    threshold: vec4<f32>,
    // x: slices in the frame, y: slices per chunk bit (0: no bits), z: slices per run
    // of early termination (0: none)
    counts: vec4<u32>,
}

@group(0) @binding(0) var eye: texture_2d<f32>;
@group(0) @binding(1) var<uniform> mask: Mask;
@group(0) @binding(2) var chunks: texture_2d<u32>;

struct MaskOut {
    @builtin(position) pos: vec4<f32>,
    // the first slice of the run this depth is for
    @location(0) @interpolate(flat) first: u32,
}

// One triangle covering the viewport; the run's first slice is the instance.
@vertex
fn vs_mask(@builtin(vertex_index) i: u32, @builtin(instance_index) first: u32) -> MaskOut {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    var o: MaskOut;
    o.pos = vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
    o.first = first;
    return o;
}

// The first set bit at or after bit `j` of the 64 (64: none), without dynamic
// indexing or a loop (a SIMD vector of pixels pays both per lane).
fn first_bit_from(bits: vec2<u32>, j: u32) -> u32 {
    let base = vec2<u32>(0u, 32u);
    let w = vec2<u32>((j / 32u) * 32u);
    let keep = select(vec2<u32>(0xFFFFFFFFu), vec2<u32>(0xFFFFFFFFu << (j % 32u)), base == w);
    let b = select(vec2<u32>(0u), bits & keep, base >= w);
    let first = base + countTrailingZeros(b);
    return select(select(64u, first.y, b.y != 0u), first.x, b.x != 0u);
}

@fragment
fn fs_mask(in: MaskOut) -> @builtin(frag_depth) f32 {
    let p = vec2<i32>(in.pos.xy);
    let et = mask.counts.z;
    if (et != 0u && in.first > 0u && in.first % et == 0u
        && textureLoad(eye, p, 0).a >= mask.threshold.x) {
        return 1.0;
    }
    let c = mask.counts.y;
    if (c == 0u) {
        discard;
    }
    let j = first_bit_from(textureLoad(chunks, p, 0).xy, in.first / c);
    if (j >= 64u) {
        return 1.0;
    }
    return f32(max(j * c, in.first)) / f32(mask.counts.x);
}
