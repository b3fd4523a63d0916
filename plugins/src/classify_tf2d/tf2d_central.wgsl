// classify.tf2d, gradients by central differences on the fly: six extra trilinear
// reads one voxel apart. |∇f| is in normalised value per voxel; times
// `params.gradient_scale`, clamped to [0,1], it indexes the table's y axis.

fn gradient_magnitude(tex: vec3<f32>) -> f32 {
    let d = 1.0 / vec3<f32>(volume_dims());
    let gx = volume_value(tex + vec3<f32>(d.x, 0.0, 0.0)) - volume_value(tex - vec3<f32>(d.x, 0.0, 0.0));
    let gy = volume_value(tex + vec3<f32>(0.0, d.y, 0.0)) - volume_value(tex - vec3<f32>(0.0, d.y, 0.0));
    let gz = volume_value(tex + vec3<f32>(0.0, 0.0, d.z)) - volume_value(tex - vec3<f32>(0.0, 0.0, d.z));
    return 0.5 * length(vec3<f32>(gx, gy, gz));
}

// The table's size, `TABLE_SIZE` squared (mod.rs; a test keeps the two equal): a
// constant for `table_coord2`.
const TABLE_N: f32 = 256.0;

fn classify(s: Sample) -> Sample {
    var o = s;
    let vg = clamp(vec2<f32>(s.value, gradient_magnitude(s.tex) * params.gradient_scale), vec2<f32>(0.0), vec2<f32>(1.0));
    let c = textureSampleLevel(table, linear_clamp, table_coord2(vg, TABLE_N), 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
