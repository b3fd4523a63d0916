// shade.oren_nayar: rough diffuse reflection (Oren & Nayar 1994, the qualitative
// model) over the classified colour; the gradient is the normal; four lights as in
// shade.blinn_phong. Conventions and the f64 twin: mod.rs beside this file.
// `gradient_at` is appended by the estimator.

// The Oren–Nayar diffuse factor cos θi·(A + B·max(0, cos(φi − φr))·sin α·tan β), with
// α = max(θi, θr), β = min(θi, θr); zero where n·l ≤ 0.
fn oren_nayar_factor(n: vec3<f32>, v: vec3<f32>, l: vec3<f32>) -> f32 {
    let ndl = dot(n, l);
    if (!(ndl > 0.0)) {
        return 0.0;
    }
    let ndv = clamp(dot(n, v), 0.0, 1.0);
    let s2 = params.sigma * params.sigma;
    let a = 1.0 - 0.5 * s2 / (s2 + 0.33);
    let b = 0.45 * s2 / (s2 + 0.09);
    // cos(φi − φr) from the projections of l and v onto the tangent plane
    let cos_phi = max(dot(safe_normalize(l - n * ndl), safe_normalize(v - n * ndv)), 0.0);
    let cos_alpha = min(ndl, ndv);
    let cos_beta = max(ndl, ndv);
    let sin_alpha = sqrt(max(1.0 - cos_alpha * cos_alpha, 0.0));
    let tan_beta = sqrt(max(1.0 - cos_beta * cos_beta, 0.0)) / max(cos_beta, 1.0e-4);
    return ndl * (a + b * cos_phi * sin_alpha * tan_beta);
}

fn add_light(t: vec3<f32>, on: u32, kind: u32, space: u32, vector: vec3<f32>, color: vec4<f32>, pos: vec3<f32>, n: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    if (on == 0u) {
        return t;
    }
    return t + color.rgb * (params.kd * oren_nayar_factor(n, v, light_dir(kind, space, vector, pos)));
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
    d = add_light(d, params.light0_on, params.light0_type, params.light0_space, params.light0_vector, params.light0_color, s.pos, nw.xyz, v);
    // light0: end
    // light1: begin
    d = add_light(d, params.light1_on, params.light1_type, params.light1_space, params.light1_vector, params.light1_color, s.pos, nw.xyz, v);
    // light1: end
    // light2: begin
    d = add_light(d, params.light2_on, params.light2_type, params.light2_space, params.light2_vector, params.light2_color, s.pos, nw.xyz, v);
    // light2: end
    // light3: begin
    d = add_light(d, params.light3_on, params.light3_type, params.light3_space, params.light3_vector, params.light3_color, s.pos, nw.xyz, v);
    // light3: end
    let lit = s.color.rgb * (vec3<f32>(params.ka) + d);
    o.color = vec4<f32>(mix(s.color.rgb, lit, nw.w), s.color.a);
    o.normal = nw.xyz;
    return o;
}
