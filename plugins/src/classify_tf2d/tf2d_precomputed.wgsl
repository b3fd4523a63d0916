// classify.tf2d, gradients from the pre-pass: |∇f| per voxel (central differences
// on the voxel grid, tf2d_prepass.wgsl) in the 3D texture `gradient`, interpolated
// trilinearly at the sample.

// The table's size, `TABLE_SIZE` squared (mod.rs; a test keeps the two equal): a
// constant for `table_coord2`.
const TABLE_N: f32 = 256.0;

fn classify(s: Sample) -> Sample {
    var o = s;
    let g = textureSampleLevel(gradient, linear_clamp, s.tex, 0.0).r;
    let vg = clamp(vec2<f32>(s.value, g * params.gradient_scale), vec2<f32>(0.0), vec2<f32>(1.0));
    let c = textureSampleLevel(table, linear_clamp, table_coord2(vg, TABLE_N), 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
