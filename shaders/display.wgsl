// Composites the premultiplied eye buffer over an opaque background into 8-bit RGBA
// for display: rgb = C + (1 − A)·background, clamped to [0,1].

@group(0) @binding(0) var src: texture_2d<f32>;
@group(0) @binding(1) var dst: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(2) var<uniform> background: vec4<f32>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = textureDimensions(dst);
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let c = textureLoad(src, vec2<i32>(gid.xy), 0);
    let a = clamp(c.a, 0.0, 1.0);
    let rgb = clamp(c.rgb + (1.0 - a) * background.rgb, vec3<f32>(0.0), vec3<f32>(1.0));
    textureStore(dst, vec2<i32>(gid.xy), vec4<f32>(rgb, 1.0));
}
