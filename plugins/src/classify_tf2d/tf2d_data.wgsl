// classify.tf2d over value × the data's own value (`y_axis: data`): the table's y is
// the volume's normalised scalar at the sample, which a sample hook before (flow.lic3d)
// has not replaced. For a vector volume that is |v|: a 2D TF over LIC intensity × flow
// speed (Rezk-Salama 2001 §9.3's classification of LIC by the field's magnitude).

// The table's size, `TABLE_SIZE` squared (mod.rs; a test keeps the two equal): a
// constant for `table_coord2`.
const TABLE_N: f32 = 256.0;

fn classify(s: Sample) -> Sample {
    var o = s;
    let vg = clamp(vec2<f32>(s.value, volume_value(s.tex)), vec2<f32>(0.0), vec2<f32>(1.0));
    let c = textureSampleLevel(table, linear_clamp, table_coord2(vg, TABLE_N), 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
