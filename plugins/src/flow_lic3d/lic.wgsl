// flow.lic3d: 3D line integral convolution, I(x₀) = Σ k(sᵢ)·T(σ(sᵢ)) / Σ k(sᵢ)
// (Rezk-Salama 2001, eqs 9.9–9.10), along the streamline σ through x₀ traced both ways
// with unit speed and step h over the noise `noise`. Coordinates are voxel coordinates
// of the LIC grid; `field` and `noise` cover the same box. Twin: vwb_render::flow::lic_at
// (f64). One file for both modes (mod.rs keeps the regions a shader needs); the
// modes differ only in `lic_here`, I at a texture coordinate, which the hooks read:
// - precomputed: the pre-pass writes I at every voxel of the LIC grid into `lic`, and
//   `lic_here` reads it;
// - on the fly: `lic_here` integrates at the sample itself, so only samples the slice
//   loop reaches (inside the clip region, before early termination, outside skipped
//   space) pay for it (Falk and Weiskopf 2008).
// In both, the sample's value becomes I, optionally modulated by the field's magnitude
// (the volume's normalised value), for the classification plugins after it.

// integral: begin
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

// One step of h from p (w = 0 when a stage left the field). The integrator is
// structural: its stages are compiled in (Euler: neither region below, RK2: the first,
// RK4: both), since a CPU device runs the code of a branch on a uniform whatever its
// value (docs/flow.md measures the difference).
fn lic_step(p: vec3<f32>, h: f32, d: vec3<f32>) -> vec4<f32> {
    let k1 = lic_dir(p, d);
    if (k1.w == 0.0) {
        return vec4<f32>(0.0);
    }
    var v = k1.xyz;
    var s = h;
    // rk2: begin
    let k2 = lic_dir(p + k1.xyz * (h * 0.5), d);
    if (k2.w == 0.0) {
        return vec4<f32>(0.0);
    }
    v = k2.xyz;
    // rk4: begin
    let k3 = lic_dir(p + k2.xyz * (h * 0.5), d);
    if (k3.w == 0.0) {
        return vec4<f32>(0.0);
    }
    let k4 = lic_dir(p + k3.xyz * h, d);
    if (k4.w == 0.0) {
        return vec4<f32>(0.0);
    }
    v = k1.xyz + 2.0 * k2.xyz + 2.0 * k3.xyz + k4.xyz;
    s = h / 6.0;
    // rk4: end
    // rk2: end
    return vec4<f32>(p + v * s, 1.0);
}

// The kernel weight at signed arc length s, downstream positive: box, tent 1 − |x|,
// Gaussian with σ = L/3, or periodic (Hann window × ripple shifted by the phase). The
// kernel is structural: only its line below is compiled in (box: none of them).
fn lic_weight(s: f32) -> f32 {
    let signed = s / max(params.length, 1.0e-12);
    let x = abs(signed);
    if (x > 1.0) {
        return 0.0;
    }
    var w = 1.0;
    // kernel_tent: begin
    w = 1.0 - x;
    // kernel_tent: end
    // kernel_gaussian: begin
    w = exp(-4.5 * x * x);
    // kernel_gaussian: end
    // kernel_periodic: begin
    let ripple = 6.283185307 * params.ripples * signed - radians(params.phase_deg);
    w = 0.25 * (1.0 + cos(3.141592654 * x)) * (1.0 + cos(ripple));
    // kernel_periodic: end
    return w;
}

fn lic_noise(p: vec3<f32>, d: vec3<f32>) -> f32 {
    return textureSampleLevel(noise, linear_clamp, (p + vec3<f32>(0.5)) / d, 0.0).x;
}

// I(x0) along the streamline through x0 (LIC-grid voxel coordinates): the integral of
// both the pre-pass (x0 a voxel centre) and the on-the-fly hook (x0 the sample).
fn lic_integral(x0: vec3<f32>, d: vec3<f32>) -> f32 {
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
            let w = lic_weight(f32(i) * h);
            sum += w * lic_noise(q, d);
            wsum += w;
        }
    }
    return sum / wsum;
}
// integral: end

// prepass: begin
fn prepass(voxel: vec3<u32>, dims: vec3<u32>) -> vec4<f32> {
    return vec4<f32>(lic_integral(vec3<f32>(voxel), vec3<f32>(dims)), 0.0, 0.0, 1.0);
}
// prepass: end

// precomputed: begin
// I at a texture coordinate: the LIC volume, read trilinearly.
fn lic_here(tex: vec3<f32>) -> f32 {
    return textureSampleLevel(lic, linear_clamp, tex, 0.0).r;
}

fn scalar_grid() -> vec3<f32> {
    return vec3<f32>(textureDimensions(lic));
}
// precomputed: end

// on_the_fly: begin
// I at a texture coordinate, integrated there: shading from LIC gradients costs one
// integral per read of the estimator (6 central, 26 Sobel).
fn lic_here(tex: vec3<f32>) -> f32 {
    let d = vec3<f32>(textureDimensions(noise));
    let x0 = clamp(tex * d - vec3<f32>(0.5), vec3<f32>(-0.5), d - vec3<f32>(0.5));
    return lic_integral(x0, d);
}

fn scalar_grid() -> vec3<f32> {
    return vec3<f32>(textureDimensions(noise));
}
// on_the_fly: end

// hooks: begin
fn sample(s: Sample) -> Sample {
    var o = s;
    let i = lic_here(s.tex);
    o.value = mix(i, i * s.value, params.modulate);
    return o;
}

// The value `sample` gives at tex, on the LIC grid: what the gradient estimators of the
// shading plugins differentiate (shading from LIC gradients).
fn scalar(tex: vec3<f32>) -> f32 {
    let i = lic_here(tex);
    return mix(i, i * volume_value(tex), params.modulate);
}
// hooks: end
