// shade.toon: cel shading of the classified samples. The diffuse term of each light is
// quantised into `bands` levels with smooth steps of half-width `softness`, and an
// outline darkens samples whose iso-surface is seen edge-on (|n·v| < outline_width,
// n the gradient direction). Conventions and the f64 twin: mod.rs beside this file.
// `gradient_at` is appended by the estimator.

// The diffuse factor d ∈ [0, 1] quantised into `bands` levels 0, 1/(bands − 1), …, 1,
// with a smoothstep of half-width `softness` at each threshold k/bands.
fn toon_level(d: f32) -> f32 {
    let b = max(params.bands, 2);
    var q = 0.0;
    for (var k = 1; k < b; k++) {
        let t = f32(k) / f32(b);
        q += smoothstep(t - params.softness, t + params.softness, d);
    }
    return q / f32(b - 1);
}

fn add_light(t: vec3<f32>, on: u32, kind: u32, space: u32, vector: vec3<f32>, color: vec4<f32>, pos: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    if (on == 0u) {
        return t;
    }
    let d = max(dot(n, light_dir(kind, space, vector, pos)), 0.0);
    return t + color.rgb * (params.kd * toon_level(d));
}

fn shade(s: Sample) -> Sample {
    var o = s;
    if (s.color.a <= 0.0) {
        return o;
    }
    let v = -s.ray_dir;
    let nw = shading_normal(gradient_at(shading_tex(s)), params.gradient_floor, v, params.two_sided != 0u);
    var d = vec3<f32>(0.0);
    // light0: begin
    d = add_light(d, params.light0_on, params.light0_type, params.light0_space, params.light0_vector, params.light0_color, s.pos, nw.xyz);
    // light0: end
    // light1: begin
    d = add_light(d, params.light1_on, params.light1_type, params.light1_space, params.light1_vector, params.light1_color, s.pos, nw.xyz);
    // light1: end
    // light2: begin
    d = add_light(d, params.light2_on, params.light2_type, params.light2_space, params.light2_vector, params.light2_color, s.pos, nw.xyz);
    // light2: end
    // light3: begin
    d = add_light(d, params.light3_on, params.light3_type, params.light3_space, params.light3_vector, params.light3_color, s.pos, nw.xyz);
    // light3: end
    let banded = s.color.rgb * (vec3<f32>(params.ka) + d);
    let w = params.outline_width;
    let edge = 1.0 - smoothstep(w - params.softness, w + params.softness, abs(dot(nw.xyz, v)));
    let toon = mix(banded, params.outline_color.rgb, edge * params.outline_color.a);
    o.color = vec4<f32>(mix(s.color.rgb, toon, nw.w), s.color.a);
    o.normal = nw.xyz;
    return o;
}
