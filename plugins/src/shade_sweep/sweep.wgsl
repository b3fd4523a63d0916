// shade.sweep_shadows: shadows from a directional light by one light-aligned sweep
// (Behrens & Ratering 1998; Rezk-Salama 2001 §5): the volume pass `transmit` runs
// plane by plane in the light's direction of travel (VolumePassDecl::sweep) and
// stores the transmittance T after each texel, T = T_upstream · (1 − α'), with α' the
// stack's classified opacity corrected to the path length between two planes. The
// shade hook scales the colour by the light arriving at the sample, read one voxel
// upstream, one texel of the light volume (so that a sample does not shadow itself):
// c·(ambient + (1 − ambient)·T).
// Twin: mod.rs.

// Unit direction the light travels in, world space (params.light points to the light).
fn travel() -> vec3<f32> {
    return -safe_normalize(params.light);
}

fn transmit(voxel: vec3<u32>, dims: vec3<u32>, plane: u32, prev: vec4<f32>, length: f32) -> vec4<f32> {
    let tex = (vec3<f32>(voxel) + 0.5) / vec3<f32>(dims);
    let a = correct_opacity(stack_classify(tex, travel()).a, length);
    return vec4<f32>(prev.x * (1.0 - a), 0.0, 0.0, 1.0);
}

fn shade(s_in: Sample) -> Sample {
    var s = s_in;
    let extent = frame.box_max.xyz - frame.box_min.xyz;
    // one texel of the light volume upstream (one voxel at 1:1)
    let ratio = frame.volume_dims.x / f32(textureDimensions(transmittance).x);
    let up = s.tex - travel() * (frame.box_min.w * ratio) / extent;
    let t = textureSampleLevel(transmittance, linear_clamp, up, 0.0).r;
    let f = params.ambient + (1.0 - params.ambient) * t;
    s.color = vec4<f32>(s.color.rgb * f, s.color.a);
    return s;
}
