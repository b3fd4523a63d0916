// shade.dos: directional occlusion shading (Schott, Pegoraro, Hansen, Boulanger and
// Bouatouch 2009) on the slice loop's per-slice state. `state_prev.r` is the
// occlusion buffer of the previous slice: the fractional visibility V (eq 10) of the
// ambient light L_a at the current slice, 1 before the first slice. CPU twin: mod.rs.

// Eye pass (Algorithm 1): σs·(L_a·V + ambient), α unchanged (α = 1 − e^(−σt·d) is
// applied by the core's opacity correction of the TF's α per Δs0).
fn shade(s: Sample) -> Sample {
    var o = s;
    let v = textureSampleLevel(state_prev, linear_clamp, s.uv, 0.0).r;
    o.color = vec4<f32>(s.color.rgb * (params.la * v + params.ambient), s.color.a);
    return o;
}

// One kernel point (unit disk) of the occlusion pass: the previous buffer at the
// point's position on the base of the cone, attenuated by the transmittance over the
// slice distance (Algorithm 3) or the exact distance to the cone tip (Algorithm 2).
fn kernel_tap(q: vec2<f32>, uv: vec2<f32>, scale: vec2<f32>, extent: f32, d: f32, sigma_t: f32) -> f32 {
    let p = q * extent;
    let pt = uv + vec2<f32>(p.x, -p.y) * scale;
    var dist = d;
    if (params.distance == 1u) {
        dist = sqrt(d * d + dot(p, p));
    }
    return textureSampleLevel(state_prev, linear_clamp, pt, 0.0).r * exp(-sigma_t * dist);
}

// Occlusion pass (Algorithms 2 and 3): the next buffer at `uv` averages the previous
// one over the base of the cone, radius d·tan θ (eq 11), mapped to the screen at
// this slice's depth (eqs 12–15), with σt of the current slice at the cone's tip.
fn slice_update(s: Sample, c: vec4<f32>, uv: vec2<f32>) -> vec4<f32> {
    let a = clamp(s.color.a, 0.0, 1.0);
    let sigma_t = -log(max(1.0 - a, 1.0e-30)) / frame.box_min.w;
    let d = frame.forward.w;
    let extent = d * tan(radians(params.theta_deg));
    var depth = 1.0;
    if (frame.eye.w > 0.5) {
        depth = max(frame.box_max.w + f32(s.slice) * frame.forward.w, 1.0e-9);
    }
    let scale = 0.5 / (vec2<f32>(length(frame.ray_basis[0].xyz), length(frame.ray_basis[1].xyz)) * depth);
    var sum = 0.0;
    var n = 0.0;
    if (params.kernel == 1u) {
        let count = i32(textureDimensions(poisson).x);
        for (var i = 0; i < min(params.poisson_count, count); i = i + 1) {
            let q = textureLoad(poisson, vec2<i32>(i, 0), 0).xy;
            sum = sum + kernel_tap(q, uv, scale, extent, d, sigma_t);
            n = n + 1.0;
        }
    } else {
        let g = params.grid;
        for (var j = 0; j < g; j = j + 1) {
            for (var i = 0; i < g; i = i + 1) {
                let q = (vec2<f32>(f32(i), f32(j)) + 0.5) / f32(g) * 2.0 - 1.0;
                if (dot(q, q) <= 1.0) {
                    sum = sum + kernel_tap(q, uv, scale, extent, d, sigma_t);
                    n = n + 1.0;
                }
            }
        }
    }
    return vec4<f32>(sum / max(n, 1.0), 0.0, 0.0, 1.0);
}
