// shade.gooch: k = (1 + n·l)/2 mixes a cool tone (blue + α·colour) and a warm tone
// (yellow + β·colour); the light is a head light (l = v). Faded in with the gradient
// magnitude by `shading_normal` (shaders/common.wgsl), two-sided.
fn shade(s: Sample) -> Sample {
    var o = s;
    if (s.color.a <= 0.0) {
        return o;
    }
    let v = -s.ray_dir;
    let nw = shading_normal(gradient_central(s.tex), params.gradient_floor, v, true);
    let k = 0.5 * (1.0 + dot(nw.xyz, v));
    let cool = params.cool.rgb + params.alpha * s.color.rgb;
    let warm = params.warm.rgb + params.beta * s.color.rgb;
    let tone = clamp(mix(cool, warm, k), vec3<f32>(0.0), vec3<f32>(1.0));
    o.color = vec4<f32>(mix(s.color.rgb, tone, nw.w), s.color.a);
    o.normal = nw.xyz;
    return o;
}
