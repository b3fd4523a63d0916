// shade.toon_lite: d = n·v quantised into `bands` levels, plus ambient; samples seen
// edge-on (|n·v| < outline) are drawn black. Head light, two-sided normals.
fn shade(s: Sample) -> Sample {
    var o = s;
    if (s.color.a <= 0.0) {
        return o;
    }
    let v = -s.ray_dir;
    let nw = shading_normal(gradient_central(s.tex), params.gradient_floor, v, true);
    let d = max(dot(nw.xyz, v), 0.0);
    let b = f32(max(params.bands, 2));
    let level = min(floor(d * b), b - 1.0) / (b - 1.0);
    var rgb = s.color.rgb * (params.ambient + (1.0 - params.ambient) * level);
    if (abs(dot(nw.xyz, v)) < params.outline) {
        rgb = vec3<f32>(0.0);
    }
    o.color = vec4<f32>(mix(s.color.rgb, rgb, nw.w), s.color.a);
    o.normal = nw.xyz;
    return o;
}
