// flow.lic3d pre-pass: the LIC integral I(x₀) = Σ k(sᵢ)·T(σ(sᵢ)) / Σ k(sᵢ) (Rezk-Salama
// 2001, eqs 9.9–9.10) along the streamline σ through each voxel of the LIC grid, traced
// both ways with unit speed and step h, over the noise `noise`. Coordinates are voxel
// coordinates of the LIC grid; `field` and `noise` cover the same box. Twin:
// vwb_render::flow::lic_at (f64).

// The unit flow direction at p (w = 1), or w = 0 outside the box or where it vanishes.
fn lic_dir(p: vec3<f32>, d: vec3<f32>) -> vec4<f32> {
    if (any(p < vec3<f32>(-0.5)) || any(p > d - vec3<f32>(0.5))) {
        return vec4<f32>(0.0);
    }
    let v = textureSampleLevel(field, linear_clamp, (p + vec3<f32>(0.5)) / d, 0.0).xyz;
    let l = length(v);
    if (!(l > 1.0e-12 && l < 3.0e38)) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(v / l, 1.0);
}

// One step of h from p (w = 0 when a stage left the field). integrator: 0 Euler, 1 RK2
// (midpoint), 2 RK4.
fn lic_step(p: vec3<f32>, h: f32, d: vec3<f32>) -> vec4<f32> {
    let k1 = lic_dir(p, d);
    if (k1.w == 0.0) {
        return vec4<f32>(0.0);
    }
    if (params.integrator == 0u) {
        return vec4<f32>(p + k1.xyz * h, 1.0);
    }
    let k2 = lic_dir(p + k1.xyz * (h * 0.5), d);
    if (k2.w == 0.0) {
        return vec4<f32>(0.0);
    }
    if (params.integrator == 1u) {
        return vec4<f32>(p + k2.xyz * h, 1.0);
    }
    let k3 = lic_dir(p + k2.xyz * (h * 0.5), d);
    if (k3.w == 0.0) {
        return vec4<f32>(0.0);
    }
    let k4 = lic_dir(p + k3.xyz * h, d);
    if (k4.w == 0.0) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(p + (k1.xyz + 2.0 * k2.xyz + 2.0 * k3.xyz + k4.xyz) * (h / 6.0), 1.0);
}

// The kernel weight at arc length s (0 box, 1 tent, 2 Gaussian with σ = L/3).
fn lic_weight(s: f32) -> f32 {
    let x = abs(s / max(params.length, 1.0e-12));
    if (x > 1.0) {
        return 0.0;
    }
    if (params.kernel == 1u) {
        return 1.0 - x;
    }
    if (params.kernel == 2u) {
        return exp(-4.5 * x * x);
    }
    return 1.0;
}

fn lic_noise(p: vec3<f32>, d: vec3<f32>) -> f32 {
    return textureSampleLevel(noise, linear_clamp, (p + vec3<f32>(0.5)) / d, 0.0).x;
}

fn prepass(voxel: vec3<u32>, dims: vec3<u32>) -> vec4<f32> {
    let d = vec3<f32>(dims);
    let x0 = vec3<f32>(voxel);
    let n = i32(floor(params.length / params.step));
    let w0 = lic_weight(0.0);
    var sum = w0 * lic_noise(x0, d);
    var wsum = w0;
    for (var k = 0; k < 2; k++) {
        let h = select(-params.step, params.step, k == 0);
        var q = x0;
        for (var i = 1; i <= n; i++) {
            let next = lic_step(q, h, d);
            if (next.w == 0.0) {
                break;
            }
            q = next.xyz;
            if (any(q < vec3<f32>(-0.5)) || any(q > d - vec3<f32>(0.5))) {
                break;
            }
            let w = lic_weight(f32(i) * params.step);
            sum += w * lic_noise(q, d);
            wsum += w;
        }
    }
    return vec4<f32>(sum / wsum, 0.0, 0.0, 1.0);
}
