// shade.isosurface: non-polygonal isosurfaces (Rezk-Salama 2001 §7.2, after Westermann
// and Ertl), shaded with Blinn–Phong under a view-space head light and composited with
// the DVR colour of the sample. CPU twin and the rules: mod.rs. `gradient_at` is
// appended by the estimator.

fn iso_value(i: u32) -> f32 {
    switch i {
        case 0u: { return params.iso0; }
        case 1u: { return params.iso1; }
        case 2u: { return params.iso2; }
        default: { return params.iso3; }
    }
}

fn iso_color(i: u32) -> vec4<f32> {
    switch i {
        case 0u: { return params.color0; }
        case 1u: { return params.color1; }
        case 2u: { return params.color2; }
        default: { return params.color3; }
    }
}

// Blinn–Phong colour of a surface of colour `c` at `tex`/`pos` (two-sided).
fn surface_rgb(c: vec3<f32>, tex: vec3<f32>, pos: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let nw = shading_normal(gradient_at(tex), params.gradient_floor, v, true);
    let f = blinn_phong_factors(nw.xyz, v, light_dir(0u, 1u, head_light, pos), params.shininess);
    let lit = c * (params.ka + params.kd * f.x) + vec3<f32>(params.ks * f.y);
    return mix(c, lit, nw.w);
}

fn shade(s: Sample) -> Sample {
    var o = s;
    let v = -s.ray_dir;
    let box_size = frame.box_max.xyz - frame.box_min.xyz;
    let dir_tex = s.ray_dir * s.step / box_size;
    let f0 = s.value;
    let f1 = volume_value(s.tex + dir_tex);
    let count = u32(clamp(params.count, 1, 4));
    // surfaces met in this step: parameter t in [0, 1] along it, sorted front to back
    var ts = array<f32, 4>(2.0, 2.0, 2.0, 2.0);
    var ids = array<u32, 4>(0u, 0u, 0u, 0u);
    var n = 0u;
    if (params.method == 1u) {
        // alpha test (GL_GEQUAL): the highest isovalue the sample passes, at t = 0
        for (var i = 0u; i < count; i = i + 1u) {
            if (f0 >= iso_value(i) && (n == 0u || iso_value(i) > iso_value(ids[0]))) {
                ts[0] = 0.0;
                ids[0] = i;
                n = 1u;
            }
        }
    } else {
        // crossing: exactly one of f0, f1 lies below the isovalue
        for (var i = 0u; i < count; i = i + 1u) {
            let iso = iso_value(i);
            if ((f0 < iso) != (f1 < iso)) {
                var t = clamp((iso - f0) / (f1 - f0), 0.0, 1.0);
                var j = n;
                while (j > 0u && ts[j - 1u] > t) {
                    ts[j] = ts[j - 1u];
                    ids[j] = ids[j - 1u];
                    j = j - 1u;
                }
                ts[j] = t;
                ids[j] = i;
                n = n + 1u;
            }
        }
    }
    if (n == 0u) {
        return o;
    }
    // front to back over this step: alpha test: surface then the sample's DVR colour;
    // crossing: the DVR colour (at the sample) then the surfaces
    let ratio = step_ratio(s.step);
    let a_d = correct_opacity_ratio(s.color.a, ratio);
    var acc = vec4<f32>(0.0);
    if (params.method != 1u) {
        acc = vec4<f32>(s.color.rgb * a_d, a_d);
    }
    for (var k = 0u; k < n; k = k + 1u) {
        let c = iso_color(ids[k]);
        let a = clamp(c.a, 0.0, 1.0);
        let rgb = surface_rgb(c.rgb, s.tex + ts[k] * dir_tex, s.pos + ts[k] * s.step * s.ray_dir, v);
        acc = acc + (1.0 - acc.a) * vec4<f32>(rgb * a, a);
    }
    if (params.method == 1u) {
        acc = acc + (1.0 - acc.a) * vec4<f32>(s.color.rgb * a_d, a_d);
    }
    // back to a straight colour with opacity per Δs0 (the core corrects it again)
    if (acc.a >= 1.0) {
        o.color = vec4<f32>(acc.rgb / max(acc.a, 1.0e-30), 1.0);
    } else if (acc.a > 0.0) {
        o.color = vec4<f32>(acc.rgb / acc.a, 1.0 - exp2(log2(1.0 - acc.a) / ratio));
    }
    return o;
}

// The head light's world-space direction, once per ray: `light_world_vector` reads only
// uniforms, and a CPU device would evaluate it at every sample (docs/perf.md, "Light
// vectors once per ray"); `light_dir` then reads it as a world-space vector.
var<private> head_light: vec3<f32>;

fn setup(r: Ray, uv: vec2<f32>) -> vec4<f32> {
    head_light = light_world_vector(0u, 0u, params.light_vector);
    return vec4<f32>(0.0);
}
