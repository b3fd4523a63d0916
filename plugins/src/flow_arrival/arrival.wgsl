// flow.arrival: the thesis's time surfaces (Rezk-Salama 2001 §9.3) as one arrival-time
// volume. The pre-pass traces every voxel's path backwards in time through `field` (the
// vector volume scaled to a top speed of 1, voxel coordinates) until it enters the
// seed box, and stores the time (voxels at the top speed), or NEVER. The clip hook
// keeps the samples reached by `time` (within `band` of it, where band > 0): advancing
// the time animates the flow and recomputes nothing. Twin: vwb_render::flow::
// arrival_at (f64).

// prepass: begin
const ARRIVAL_NEVER: f32 = 3.0e38;

fn arrival_velocity(p: vec3<f32>, d: vec3<f32>) -> vec4<f32> {
    if (any(p < vec3<f32>(-0.5)) || any(p > d - vec3<f32>(0.5))) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(textureSampleLevel(field, linear_clamp, (p + vec3<f32>(0.5)) / d, 0.0).xyz, 1.0);
}

// One step of dt backwards in time from p (w = 0 when a stage left the field). The
// integrator is structural: Euler compiles in neither region below, RK2 the first,
// RK4 both (Integrator::region_left_out).
fn arrival_step(p: vec3<f32>, dt: f32, d: vec3<f32>) -> vec4<f32> {
    let h = -dt;
    let k1 = arrival_velocity(p, d);
    if (k1.w == 0.0) {
        return vec4<f32>(0.0);
    }
    var v = k1.xyz;
    var s = h;
    // rk2: begin
    let k2 = arrival_velocity(p + k1.xyz * (h * 0.5), d);
    if (k2.w == 0.0) {
        return vec4<f32>(0.0);
    }
    v = k2.xyz;
    // rk4: begin
    let k3 = arrival_velocity(p + k2.xyz * (h * 0.5), d);
    if (k3.w == 0.0) {
        return vec4<f32>(0.0);
    }
    let k4 = arrival_velocity(p + k3.xyz * h, d);
    if (k4.w == 0.0) {
        return vec4<f32>(0.0);
    }
    v = k1.xyz + 2.0 * k2.xyz + 2.0 * k3.xyz + k4.xyz;
    s = h / 6.0;
    // rk4: end
    // rk2: end
    return vec4<f32>(p + v * s, 1.0);
}

fn arrival_in_seed(t: vec3<f32>) -> bool {
    return all(t >= params.seed_min) && all(t <= params.seed_max);
}

// Where the segment a → b (texture coordinates, a outside) first enters the seed box,
// as a fraction of the segment, or −1 (the slab method, as SeedBox::entry).
fn arrival_entry(a: vec3<f32>, b: vec3<f32>) -> f32 {
    var lo = 0.0;
    var hi = 1.0;
    for (var k = 0; k < 3; k++) {
        let d = b[k] - a[k];
        if (abs(d) < 1.0e-12) {
            if (a[k] < params.seed_min[k] || a[k] > params.seed_max[k]) {
                return -1.0;
            }
            continue;
        }
        let t0 = (params.seed_min[k] - a[k]) / d;
        let t1 = (params.seed_max[k] - a[k]) / d;
        lo = max(lo, min(t0, t1));
        hi = min(hi, max(t0, t1));
    }
    return select(-1.0, lo, lo <= hi);
}

fn prepass(voxel: vec3<u32>, dims: vec3<u32>) -> vec4<f32> {
    let d = vec3<f32>(dims);
    var q = vec3<f32>(voxel);
    if (arrival_in_seed((q + vec3<f32>(0.5)) / d)) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    let n = i32(ceil(params.max_length / params.step));
    var t = 0.0;
    for (var i = 0; i < n; i++) {
        let v = arrival_velocity(q, d);
        let speed = length(v.xyz);
        if (v.w == 0.0 || !(speed >= 1.0e-6)) {
            break;
        }
        let dt = params.step / speed;
        let next = arrival_step(q, dt, d);
        if (next.w == 0.0) {
            break;
        }
        let f = arrival_entry((q + vec3<f32>(0.5)) / d, (next.xyz + vec3<f32>(0.5)) / d);
        if (f >= 0.0) {
            return vec4<f32>(min(t + f * dt, ARRIVAL_NEVER), 0.0, 0.0, 1.0);
        }
        t += dt;
        q = next.xyz;
    }
    return vec4<f32>(ARRIVAL_NEVER, 0.0, 0.0, 1.0);
}
// prepass: end

// hook: begin
fn clip(s: Sample) -> bool {
    let t = textureSampleLevel(arrival, linear_clamp, s.tex, 0.0).r;
    return t <= params.time && (params.band <= 0.0 || t > params.time - params.band);
}
// hook: end
