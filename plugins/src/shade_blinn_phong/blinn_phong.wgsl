// shade.blinn_phong: Blinn–Phong local illumination (Rezk-Salama 2001, eqs 7.1–7.4)
// with the gradient as the normal, up to four lights, modulated or additive (§7.3),
// and optional gradient-magnitude opacity (eq 5.12). Conventions and CPU twin:
// render/src/shading.rs. `gradient_at` is appended by the estimator, `light_table_terms`
// by the lighting mode (table.rs). Only the lights evaluated per sample are compiled
// in: a light that is off (or tabulated) has its region left out (mod.rs), and a light
// that is in has its kind fixed and its world-space vector computed once per ray
// (`with_lights` in plugins/src/lighting.rs).

struct LightTerms {
    diffuse: vec3<f32>,
    specular: vec3<f32>,
}

fn add_light(t: LightTerms, on: u32, kind: u32, space: u32, vector: vec3<f32>, color: vec4<f32>, pos: vec3<f32>, n: vec3<f32>, v: vec3<f32>) -> LightTerms {
    if (on == 0u) {
        return t;
    }
    let f = blinn_phong_factors(n, v, light_dir(kind, space, vector, pos), params.shininess);
    return LightTerms(t.diffuse + color.rgb * (params.kd * f.x), t.specular + color.rgb * (params.ks * f.y));
}

fn shade(s: Sample) -> Sample {
    var o = s;
    // a transparent sample contributes nothing whatever its colour: skip the lighting
    if (s.color.a <= 0.0) {
        return o;
    }
    let v = -s.ray_dir;
    let g = gradient_at(shading_tex(s));
    let nw = shading_normal(g, params.gradient_floor, v, params.two_sided != 0u);
    // the tabulated lights (none unless lighting is table), then the others one by one
    var t = light_table_terms(nw.xyz);
    // light0: begin
    t = add_light(t, params.light0_on, params.light0_type, params.light0_space, params.light0_vector, params.light0_color, s.pos, nw.xyz, v);
    // light0: end
    // light1: begin
    t = add_light(t, params.light1_on, params.light1_type, params.light1_space, params.light1_vector, params.light1_color, s.pos, nw.xyz, v);
    // light1: end
    // light2: begin
    t = add_light(t, params.light2_on, params.light2_type, params.light2_space, params.light2_vector, params.light2_color, s.pos, nw.xyz, v);
    // light2: end
    // light3: begin
    t = add_light(t, params.light3_on, params.light3_type, params.light3_space, params.light3_vector, params.light3_color, s.pos, nw.xyz, v);
    // light3: end
    var lit: vec3<f32>;
    if (params.mode == 1u) {
        lit = s.color.rgb * params.ka + t.diffuse + t.specular;
    } else {
        lit = s.color.rgb * (vec3<f32>(params.ka) + t.diffuse) + t.specular;
    }
    let gm = clamp(length(g) * params.gm_scale, 0.0, 1.0);
    o.color = vec4<f32>(mix(s.color.rgb, lit, nw.w), s.color.a * mix(1.0, gm, params.gm_opacity));
    o.normal = nw.xyz;
    return o;
}
