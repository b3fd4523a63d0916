// classify.tf2d over value × the data's own value (`y_axis: data`): the table's y is
// the volume's normalised scalar at the sample, which a sample hook before (flow.lic3d)
// has not replaced. For a vector volume that is |v|: a 2D TF over LIC intensity × flow
// speed (Rezk-Salama 2001 §9.3's classification of LIC by the field's magnitude).

fn classify(s: Sample) -> Sample {
    var o = s;
    let n = vec2<f32>(textureDimensions(table));
    let vg = clamp(vec2<f32>(s.value, volume_value(s.tex)), vec2<f32>(0.0), vec2<f32>(1.0));
    let c = textureSampleLevel(table, linear_clamp, (vg * (n - 1.0) + 0.5) / n, 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
