// classify.tf1d — post-classification: interpolate the scalar, then look up a
// piecewise-linear RGBA transfer function baked into the 256-entry 1D texture `lut`
// (a 1D texture, not a 256×1 2D one: the same linear lookup at half the texel reads,
// which is what it costs on CPU adapters; docs/perf.md).

// The table's entries, `vwb_render::tf::LUT_SIZE` (a test keeps the two equal): a
// constant for `table_coord`.
const LUT_N: f32 = 256.0;

fn classify(s: Sample) -> Sample {
    var o = s;
    let x = table_coord(clamp(s.value, 0.0, 1.0), LUT_N);
    let c = textureSampleLevel(lut, linear_clamp, x, 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
