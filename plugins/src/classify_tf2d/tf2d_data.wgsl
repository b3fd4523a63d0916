// classify.tf2d over value × the data's own value (`y_axis: data`): the table's y is
// the volume's normalised scalar at the sample, which a sample hook before (flow.lic3d)
// has not replaced. For a vector volume that is |v|: a 2D TF over LIC intensity × flow
// speed (Rezk-Salama 2001 §9.3's classification of LIC by the field's magnitude).

// N × N: the table's size, `TABLE_SIZE` in mod.rs (a test keeps the two equal). A
// constant power of two, so the division is a multiplication by the exact 1/N: the
// same bits as dividing by the table's size, without a division per sample, which
// llvmpipe would not hoist out of the march (docs/perf.md, "Divisions once per ray").
const TABLE_N: f32 = 256.0;

fn classify(s: Sample) -> Sample {
    var o = s;
    let vg = clamp(vec2<f32>(s.value, volume_value(s.tex)), vec2<f32>(0.0), vec2<f32>(1.0));
    let c = textureSampleLevel(table, linear_clamp, (vg * (TABLE_N - 1.0) + 0.5) * (1.0 / TABLE_N), 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
