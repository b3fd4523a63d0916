// shade.cook_torrance: microfacet reflection (Cook & Torrance 1982) with the GGX /
// Trowbridge–Reitz distribution (Walter et al. 2007), the separable Smith masking for
// GGX and Schlick's Fresnel approximation, over a Lambertian base coloured by the
// transfer function. The gradient is the normal; four lights as in shade.blinn_phong.
// Conventions and the f64 twin: mod.rs beside this file. `gradient_at` is appended by
// the estimator.

const CT_PI: f32 = 3.14159265358979;

// GGX normal distribution D(h) for α = roughness².
fn ggx_d(ndh: f32, a: f32) -> f32 {
    let a2 = a * a;
    let t = ndh * ndh * (a2 - 1.0) + 1.0;
    return a2 / (CT_PI * t * t);
}

// Smith's masking for GGX, one direction: G1 = 2(n·x) / ((n·x) + sqrt(α² + (1 − α²)(n·x)²)).
fn smith_g1(ndx: f32, a: f32) -> f32 {
    let a2 = a * a;
    return 2.0 * ndx / (ndx + sqrt(a2 + (1.0 - a2) * ndx * ndx));
}

// (diffuse, specular) factors of one light: max(n·l, 0) and π·D·G·F / (4 n·v), the
// specular radiance for an irradiance π at normal incidence (so that k_d·diffuse is
// the Lambertian term of shade.blinn_phong). Zero where n·l ≤ 0 or n·v ≤ 0.
fn cook_torrance_factors(n: vec3<f32>, v: vec3<f32>, l: vec3<f32>) -> vec2<f32> {
    let ndl = dot(n, l);
    let ndv = dot(n, v);
    if (!(ndl > 0.0 && ndv > 0.0)) {
        return vec2<f32>(0.0);
    }
    let h = safe_normalize(l + v);
    let a = params.roughness * params.roughness;
    let ndh = max(dot(n, h), 0.0);
    let vdh = max(dot(v, h), 0.0);
    let f = params.f0 + (1.0 - params.f0) * pow(1.0 - vdh, 5.0);
    let g = smith_g1(ndl, a) * smith_g1(ndv, a);
    return vec2<f32>(ndl, CT_PI * ggx_d(ndh, a) * g * f / (4.0 * ndv));
}

struct LightTerms {
    diffuse: vec3<f32>,
    specular: vec3<f32>,
}

fn add_light(t: LightTerms, on: u32, kind: u32, space: u32, vector: vec3<f32>, color: vec4<f32>, pos: vec3<f32>, n: vec3<f32>, v: vec3<f32>) -> LightTerms {
    if (on == 0u) {
        return t;
    }
    let f = cook_torrance_factors(n, v, light_dir(kind, space, vector, pos));
    return LightTerms(t.diffuse + color.rgb * (params.kd * f.x), t.specular + color.rgb * (params.ks * f.y));
}

fn shade(s: Sample) -> Sample {
    var o = s;
    if (s.color.a <= 0.0) {
        return o;
    }
    let v = -s.ray_dir;
    let nw = shading_normal(gradient_at(shading_tex(s)), params.gradient_floor, v, params.two_sided != 0u);
    var t = LightTerms(vec3<f32>(0.0), vec3<f32>(0.0));
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
    let lit = s.color.rgb * (vec3<f32>(params.ka) + t.diffuse) + t.specular;
    o.color = vec4<f32>(mix(s.color.rgb, lit, nw.w), s.color.a);
    o.normal = nw.xyz;
    return o;
}
