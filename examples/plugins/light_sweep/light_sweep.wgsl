// The sweep pass: the light's transmittance after each texel, T = T_upstream · (1 − α'),
// α' the stack's opacity corrected to the path length between two planes.
fn transmit(voxel: vec3<u32>, dims: vec3<u32>, plane: u32, prev: vec4<f32>, length: f32) -> vec4<f32> {
    let tex = (vec3<f32>(voxel) + 0.5) / vec3<f32>(dims);
    let a = correct_opacity(stack_classify(tex, -safe_normalize(params.light)).a, length);
    return vec4<f32>(prev.x * (1.0 - a), 0.0, 0.0, 1.0);
}

// The light arriving one voxel upstream of the sample, in the light's colour.
fn shade(s_in: Sample) -> Sample {
    var s = s_in;
    let up = s.tex + safe_normalize(params.light) * frame.box_min.w / (frame.box_max.xyz - frame.box_min.xyz);
    let t = textureSampleLevel(transmittance, linear_clamp, up, 0.0).r;
    let light = params.ambient + (1.0 - params.ambient) * t * params.tint.rgb;
    s.color = vec4<f32>(s.color.rgb * light, s.color.a);
    return s;
}
