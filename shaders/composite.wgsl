// vwb sort-last compositing: draws one brick's partial image (premultiplied RGBA, its
// own front-to-back result) over the eye buffer with the slices' blend state, "under"
// (src·(1 − dst.a) + dst). Bricks are drawn front to back, so the eye buffer ends as
// the unbricked volume's image. A full-screen triangle; one texel per pixel.

@group(0) @binding(0) var part: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    return textureLoad(part, vec2<i32>(p.xy), 0);
}
