// composite.tonemap: exposure and display gamma of the volume's image, as a `post`
// hook: once per pixel, on the accumulated premultiplied colour (C, A) before the
// background, c = C / A, c' = min((2^EV · c)^(1/γ), 1), C' = A · c'. The opacity A
// stays, so the background shows through as before. Twin: mod.rs (`map`).

fn post(c: vec4<f32>, uv: vec2<f32>) -> vec4<f32> {
    if (!(c.a > 0.0)) {
        return c;
    }
    let straight = max(c.rgb / c.a, vec3<f32>(0.0)) * exp2(params.exposure);
    let mapped = min(pow(straight, vec3<f32>(1.0 / params.gamma)), vec3<f32>(1.0));
    return vec4<f32>(mapped * c.a, c.a);
}
