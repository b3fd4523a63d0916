// test.vector_passes: three chained volume passes over a named vector input (the
// plugin contract's test plugin). `field` is the input's vectors (its own grid, over
// the volume's box); the passes run on the volume's grid, each reading the one before:
//   speed   = |v| at the voxel centre, sampled from `field`;
//   blurred = the mean of `speed` over the voxel and its six neighbours (clamped);
//   edges   = |∇ blurred| by central differences (one-sided at the border).
// With `view` on, a fourth pass is a view pass (it reads the camera and reruns when it
// moves):
//   facing  = edges · |n · d|, n the unit gradient of `blurred`, d the unit view ray
//             through the voxel's centre (the view direction when orthographic).
// The sample hook replaces the value by gain · edges, or gain · facing (clamped to
// [0, 1]). Twin: plugins/src/test_vector_passes/mod.rs.

fn speed_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    let tex = (vec3<f32>(voxel) + vec3<f32>(0.5)) / vec3<f32>(dims);
    let v = textureSampleLevel(field, linear_clamp, tex, 0.0).xyz;
    return vec4<f32>(length(v), 0.0, 0.0, 1.0);
}

fn tvp_at(t: texture_3d<f32>, v: vec3<i32>, dims: vec3<u32>) -> f32 {
    return textureLoad(t, clamp(v, vec3<i32>(0), vec3<i32>(dims) - vec3<i32>(1)), 0).r;
}

fn blur_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    let v = vec3<i32>(voxel);
    var sum = tvp_at(speed, v, dims);
    for (var a = 0; a < 3; a = a + 1) {
        var e = vec3<i32>(0);
        e[a] = 1;
        sum = sum + tvp_at(speed, v + e, dims) + tvp_at(speed, v - e, dims);
    }
    return vec4<f32>(sum / 7.0, 0.0, 0.0, 1.0);
}

fn tvp_gradient(v: vec3<i32>, dims: vec3<u32>) -> vec3<f32> {
    var g = vec3<f32>(0.0);
    for (var a = 0; a < 3; a = a + 1) {
        var e = vec3<i32>(0);
        e[a] = 1;
        let lo = max(v[a] - 1, 0);
        let hi = min(v[a] + 1, i32(dims[a]) - 1);
        var vl = v;
        vl[a] = lo;
        var vh = v;
        vh[a] = hi;
        g[a] = (tvp_at(blurred, vh, dims) - tvp_at(blurred, vl, dims)) / f32(max(hi - lo, 1));
    }
    return g;
}

fn edge_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(length(tvp_gradient(vec3<i32>(voxel), dims)), 0.0, 0.0, 1.0);
}

// facing: begin
fn facing_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    let g = tvp_gradient(vec3<i32>(voxel), dims);
    let l = length(g);
    if (l <= 0.0) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    let t = (vec3<f32>(voxel) + vec3<f32>(0.5)) / vec3<f32>(dims);
    let p = mix(frame.box_min.xyz, frame.box_max.xyz, t);
    var d = frame.forward.xyz;
    if (frame.eye.w > 0.5) {
        d = normalize(p - frame.eye.xyz);
    }
    return vec4<f32>(l * abs(dot(g / l, d)), 0.0, 0.0, 1.0);
}
// facing: end

fn sample(s: Sample) -> Sample {
    var out = s;
    var e = textureSampleLevel(edges, linear_clamp, s.tex, 0.0).r;
    // facing: begin
    e = textureSampleLevel(facing, linear_clamp, s.tex, 0.0).r;
    // facing: end
    out.value = clamp(params.gain * e, 0.0, 1.0);
    return out;
}
