// classify.tf2d, gradients from the pre-pass: |∇f| per voxel (central differences
// on the voxel grid, tf2d_prepass.wgsl) in the 3D texture `gradient`, interpolated
// trilinearly at the sample.

fn classify(s: Sample) -> Sample {
    var o = s;
    let g = textureSampleLevel(gradient, linear_clamp, s.tex, 0.0).r;
    let n = vec2<f32>(textureDimensions(table));
    let vg = clamp(vec2<f32>(s.value, g * params.gradient_scale), vec2<f32>(0.0), vec2<f32>(1.0));
    let c = textureSampleLevel(table, linear_clamp, (vg * (n - 1.0) + 0.5) / n, 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
