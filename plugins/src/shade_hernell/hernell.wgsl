// shade.hernell: global light by local piecewise integration (Hernell, Ljung &
// Ynnerman 2008). Three volume passes fill the light volumes, the shade hook reads
// the last one (one extra lookup per sample). CPU twin: mod.rs (`HernellTwin`).
//
// World space: the volume box (frame.box_min/max); h = Δs0 = frame.box_min.w, one
// voxel. Opacities along light and scattering rays are the stack's classified α per
// Δs0 (`stack_classify`), sampled every voxel length after the start point (the
// start voxel does not shadow itself; consecutive segments tile the ray).

fn hn_box_min() -> vec3<f32> {
    return frame.box_min.xyz;
}

fn hn_box_max() -> vec3<f32> {
    return frame.box_max.xyz;
}

fn hn_tex(p: vec3<f32>) -> vec3<f32> {
    return (p - hn_box_min()) / (hn_box_max() - hn_box_min());
}

fn hn_inside(p: vec3<f32>) -> bool {
    return all(p >= hn_box_min()) && all(p <= hn_box_max());
}

// Unit direction from p towards the light, and the distance to it (a directional
// light is infinitely far).
fn hn_to_light(p: vec3<f32>) -> vec4<f32> {
    if (params.light_type == 1u) {
        let d = params.light - p;
        let len = length(d);
        if (len < 1.0e-6) {
            return vec4<f32>(0.0, 0.0, 1.0, 0.0);
        }
        return vec4<f32>(d / len, len);
    }
    let l = params.light;
    let len = max(length(l), 1.0e-6);
    return vec4<f32>(l / len, 3.0e38);
}

// 1 − Π(1 − α_i) over the samples p + i·h·dir, i = 1..n, stopping at the box or
// past `limit` (world distance).
fn hn_opacity(p: vec3<f32>, dir: vec3<f32>, n: i32, limit: f32) -> f32 {
    let h = frame.box_min.w;
    var t = 1.0;
    for (var i = 0; i < n; i = i + 1) {
        let d = f32(i + 1) * h;
        if (d > limit) {
            break;
        }
        let q = p + dir * d;
        if (!hn_inside(q)) {
            break;
        }
        let a = clamp(stack_classify(hn_tex(q), dir).a, 0.0, 1.0);
        t = t * (1.0 - a);
    }
    return 1.0 - t;
}

// Steps a light ray may take inside the box: its diagonal in voxels, plus one.
fn hn_max_steps() -> i32 {
    return i32(ceil(length(hn_box_max() - hn_box_min()) / frame.box_min.w)) + 1;
}

fn hn_voxel_pos(voxel: vec3<u32>, dims: vec3<u32>) -> vec3<f32> {
    let t = (vec3<f32>(voxel) + 0.5) / vec3<f32>(dims);
    return hn_box_min() + t * (hn_box_max() - hn_box_min());
}

// Pass (A1), eq 6: α_lp of the segment of `segment` voxels from each voxel towards
// the light. Exact mode: the opacity of the whole path to the light.
fn local_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    let p = hn_voxel_pos(voxel, dims);
    let l = hn_to_light(p);
    var n = params.segment;
    if (params.mode == 1u) {
        n = hn_max_steps();
    }
    return vec4<f32>(hn_opacity(p, l.xyz, n, l.w), 0.0, 0.0, 1.0);
}

fn hn_alpha_lp(p: vec3<f32>) -> f32 {
    return textureSampleLevel(alpha_lp, linear_clamp, hn_tex(p), 0.0).r;
}

// Pass (A2), eq 7: the global opacity at each SVR texel, composed from the local
// pieces α_lp sampled (trilinearly) every segment length along the light ray.
fn global_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    if (params.mode == 1u) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    let p = hn_voxel_pos(voxel, dims);
    let l = hn_to_light(p);
    let seg = f32(params.segment) * frame.box_min.w;
    let k_max = hn_max_steps() / params.segment + 2;
    var t = 1.0;
    for (var k = 0; k < k_max; k = k + 1) {
        let d = f32(k) * seg;
        if (d >= l.w) {
            break;
        }
        let q = p + l.xyz * d;
        if (!hn_inside(q)) {
            break;
        }
        t = t * (1.0 - hn_alpha_lp(q));
    }
    return vec4<f32>(1.0 - t, 0.0, 0.0, 1.0);
}

// Eq 8: direct light at p, I_d = I0·(1 − α_g(s1))·(1 − α_lp(s0)), s1 one segment
// towards the light (α_g trilinear from the SVR; 0 outside the box or past the
// light). Outside the box the light arrives unattenuated.
fn hn_direct(p: vec3<f32>) -> f32 {
    if (!hn_inside(p)) {
        return params.intensity;
    }
    let l = hn_to_light(p);
    let seg = f32(params.segment) * frame.box_min.w;
    let s1 = p + l.xyz * seg;
    var ag = 0.0;
    if (params.mode == 0u && seg < l.w && hn_inside(s1)) {
        ag = textureSampleLevel(alpha_g, linear_clamp, hn_tex(s1), 0.0).r;
    }
    return params.intensity * (1.0 - ag) * (1.0 - hn_alpha_lp(p));
}

// Pass (B), eqs 11 and 13: step 0 is the light's own direction, step j the j-th
// direction of the subdivided polyhedron (`dirs`); each is blended into the stored
// value with weight 1/(j + 1). Without scattering: I_d at the voxel.
fn light_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    let p = hn_voxel_pos(voxel, dims);
    if (params.scattering == 0u) {
        return vec4<f32>(hn_direct(p), 0.0, 0.0, 1.0);
    }
    var dir = hn_to_light(p).xyz;
    if (step > 0u) {
        dir = textureLoad(dirs, vec2<i32>(i32(step) - 1, 0), 0).xyz;
    }
    let h = frame.box_min.w;
    let m_max = i32(round(params.radius));
    var sum = 0.0;
    var t = 1.0;
    for (var m = 0; m <= m_max; m = m + 1) {
        let q = p + dir * (f32(m) * h);
        sum = sum + hn_direct(q) * t;
        // the transmittance to s_(m+1) passes the sample s_m (not s_0)
        if (m > 0 && hn_inside(q)) {
            t = t * (1.0 - clamp(stack_classify(hn_tex(q), dir).a, 0.0, 1.0));
        }
    }
    let i_new = sum / f32(m_max + 1);
    let w = 1.0 / f32(step + 1u);
    return vec4<f32>(w * i_new + (1.0 - w) * prev.x, 0.0, 0.0, 1.0);
}

// Pass (C), eq 12: g = (I_bias + (1 − I_bias)·I_s)·c·α, with the light's colour.
fn shade(s: Sample) -> Sample {
    var o = s;
    let i_s = textureSampleLevel(light_volume, linear_clamp, s.tex, 0.0).r;
    let f = params.bias + (1.0 - params.bias) * i_s;
    o.color = vec4<f32>(s.color.rgb * f * params.light_color.rgb, s.color.a);
    return o;
}
