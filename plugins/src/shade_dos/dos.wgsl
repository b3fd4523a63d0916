// shade.dos: directional occlusion shading (Schott, Pegoraro, Hansen, Boulanger and
// Bouatouch 2009) on the slice loop's per-slice state. `state_prev.r` is the
// occlusion buffer of the previous slice: the fractional visibility V (eq 10) of the
// ambient light L_a at the current slice, 1 before the first slice. With chromatic
// extinction (`extinction: chromatic`, structural) the buffer holds V per channel in
// .rgb, attenuated by σt·κ (κ: the `extinction_rgb` parameter). Achromatic, the plugin
// leaves the `chromatic` regions out (`ShaderSource::without_region`): the shader is
// the paper's scalar one (the RGB path costs lavapipe 6–10 % per frame even when
// its branches are not taken). CPU twin: mod.rs.

// The Poisson table's width (MAX_POISSON in mod.rs; a test keeps the two equal). A
// constant rather than `textureDimensions(poisson)`: lavapipe (Mesa 22.3.6) crashed
// running the Poisson kernel with the size query once the loop was no longer inside
// a branch.
const DOS_POISSON_MAX: i32 = 64;

// Eye pass (Algorithm 1): σs·(L_a·V + ambient), α unchanged (α = 1 − e^(−σt·d) is
// applied by the core's opacity correction of the TF's α per Δs0).
fn shade(s: Sample) -> Sample {
    var o = s;
    // chromatic: begin
    if (params.extinction == 1u) {
        let rgb = textureSampleLevel(state_prev, linear_clamp, state_coord(s.pos, s.uv), 0.0).rgb;
        o.color = vec4<f32>(s.color.rgb * (params.la * rgb + params.ambient), s.color.a);
        return o;
    }
    // chromatic: end
    let v = textureSampleLevel(state_prev, linear_clamp, state_coord(s.pos, s.uv), 0.0).r;
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
    // exact_distance: begin
    dist = sqrt(d * d + dot(p, p));
    // exact_distance: end
    return textureSampleLevel(state_prev, linear_clamp, pt, 0.0).r * exp(-sigma_t * dist);
}

// chromatic: begin
// Chromatic extinction: one kernel point's tap with σt·κ per channel.
fn chromatic_tap(q: vec2<f32>, uv: vec2<f32>, scale: vec2<f32>, extent: f32, d: f32, sigma_t: f32) -> vec3<f32> {
    let p = q * extent;
    let pt = uv + vec2<f32>(p.x, -p.y) * scale;
    var dist = d;
    // exact_distance: begin
    dist = sqrt(d * d + dot(p, p));
    // exact_distance: end
    let prev = textureSampleLevel(state_prev, linear_clamp, pt, 0.0).rgb;
    return prev * exp(-(sigma_t * params.extinction_rgb) * dist);
}

// The kernel's chromatic taps, averaged: the same points as the achromatic ones in
// `slice_update` (grid or Poisson, in the same order).
fn chromatic_taps(uv: vec2<f32>, scale: vec2<f32>, extent: f32, d: f32, sigma_t: f32) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    var n = 0.0;
    // poisson: begin
    for (var i = 0; i < min(params.poisson_count, DOS_POISSON_MAX); i = i + 1) {
        let q = textureLoad(poisson, vec2<i32>(i, 0), 0).xy;
        sum = sum + chromatic_tap(q, uv, scale, extent, d, sigma_t);
        n = n + 1.0;
    }
    // poisson: end
    // grid: begin
    // the grid's points written out by the plugin, as in `slice_update`
    // chromatic_grid_taps: begin
    // chromatic_grid_taps: end
    // grid: end
    return sum / max(n, 1.0);
}
// chromatic: end

// Occlusion pass (Algorithms 2 and 3): the next buffer at `uv` averages the previous
// one over the base of the cone, radius d·tan θ (eq 11), mapped to the screen at
// this slice's depth (eqs 12–15), with σt of the current slice at the cone's tip.
// With a directional light (`light: directional`) the frame is sliced halfway between
// the view and the light and the buffer lies across the light: d is the light's path
// between two slices and the cone opens towards the light (state_step,
// state_uv_per_world).
fn slice_update(s: Sample, c: vec4<f32>, uv: vec2<f32>) -> vec4<f32> {
    let a = clamp(s.color.a, 0.0, 1.0);
    let sigma_t = -log(max(1.0 - a, 1.0e-30)) / frame.box_min.w;
    let d = state_step();
    let extent = d * tan(radians(params.theta_deg));
    let scale = state_uv_per_world(s.slice);
    // clear_tiles: begin
    // An empty sample (σt = 0: every tap's transmittance is exactly 1) under a cone
    // whose taps all read the clear buffer (V = 1) gives V = 1 exactly, so its taps
    // can be skipped where the renderer tracks which tiles of the buffer are still
    // clear (SliceStateDecl::track_clear; the structural `clear_tiles`, off by
    // default). The image is the same. Since the per-slice dispatches leave out the
    // tiles whose state is still clear (renderer/slice_exit.rs), the check finds few
    // such texels, and on lavapipe its per-lane reads cost more than the taps it
    // skips: 0.51–0.81× the DOS frame without it (docs/perf.md, "Storage-buffer words
    // one lane at a time").
    if (sigma_t == 0.0 && state_prev_clear(uv, extent * abs(scale))) {
        // chromatic: begin
        if (params.extinction == 1u) {
            return vec4<f32>(1.0);
        }
        // chromatic: end
        return vec4<f32>(1.0, 0.0, 0.0, 1.0);
    }
    // clear_tiles: end
    // chromatic: begin
    if (params.extinction == 1u) {
        return vec4<f32>(chromatic_taps(uv, scale, extent, d, sigma_t), 1.0);
    }
    // chromatic: end
    var sum = 0.0;
    var n = 0.0;
    // poisson: begin
    for (var i = 0; i < min(params.poisson_count, DOS_POISSON_MAX); i = i + 1) {
        let q = textureLoad(poisson, vec2<i32>(i, 0), 0).xy;
        sum = sum + kernel_tap(q, uv, scale, extent, d, sigma_t);
        n = n + 1.0;
    }
    // poisson: end
    // grid: begin
    // The n × n grid's points inside the disk, q = (index + ½)·(2/n) − 1, row by row,
    // written out by the plugin for the chosen n on the next line (`grid` is structural;
    // `grid_taps_wgsl` in mod.rs): one `sum = sum + kernel_tap(q, …)` per point, then
    // `n = count`. No loop, no corner tests and no per-row bounds are left to run
    // (CPU time 0.79–0.88× the loop's on lavapipe; docs/perf.md, "The grid kernel's
    // taps written out").
    // grid_taps: begin
    // grid_taps: end
    // grid: end
    return vec4<f32>(sum / max(n, 1.0), 0.0, 0.0, 1.0);
}
