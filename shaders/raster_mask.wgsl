// Early ray termination for the raster backend (issue 23, item 2).
//
// Every few slices this pass writes depth 0 where the eye buffer's opacity has reached
// the threshold. The slice pipeline tests depth `less` against a buffer cleared to 1,
// so the later slices' fragments there fail the depth test before they are shaded.
// No colour is written.

struct Mask {
    // x: the opacity at which a pixel stops taking slices
    threshold: vec4<f32>,
}

@group(0) @binding(0) var eye: texture_2d<f32>;
@group(0) @binding(1) var<uniform> mask: Mask;

// One triangle covering the viewport, at depth 0.
@vertex
fn vs_mask(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_mask(@builtin(position) p: vec4<f32>) {
    if (textureLoad(eye, vec2<i32>(p.xy), 0).a < mask.threshold.x) {
        discard;
    }
}
