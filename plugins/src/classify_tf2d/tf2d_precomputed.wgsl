// classify.tf2d, gradients from the pre-pass: |∇f| per voxel (central differences
// on the voxel grid, tf2d_prepass.wgsl) in the 3D texture `gradient`, interpolated
// trilinearly at the sample.

// N × N: the table's size, `TABLE_SIZE` in mod.rs (a test keeps the two equal). A
// constant power of two, so the division is a multiplication by the exact 1/N: the
// same bits as dividing by the table's size, without a division per sample, which
// llvmpipe would not hoist out of the march (docs/perf.md, "Divisions once per ray").
const TABLE_N: f32 = 256.0;

fn classify(s: Sample) -> Sample {
    var o = s;
    let g = textureSampleLevel(gradient, linear_clamp, s.tex, 0.0).r;
    let vg = clamp(vec2<f32>(s.value, g * params.gradient_scale), vec2<f32>(0.0), vec2<f32>(1.0));
    let c = textureSampleLevel(table, linear_clamp, (vg * (TABLE_N - 1.0) + 0.5) * (1.0 / TABLE_N), 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
