// classify.tf1d, pre-classification: the pre-pass classified every voxel into the
// opacity-weighted RGBA volume `classified` (rgb·α, α); trilinear interpolation of
// that volume gives (C, A), and the sample's straight colour is C/A.

fn classify(s: Sample) -> Sample {
    var o = s;
    let c = textureSampleLevel(classified, linear_clamp, s.tex, 0.0);
    var rgb = vec3<f32>(0.0);
    if (c.a > 0.0) {
        rgb = c.rgb / c.a;
    }
    o.color = vec4<f32>(rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
