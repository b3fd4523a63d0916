// classify.tf1d — post-classification: interpolate the scalar, then look up a
// piecewise-linear RGBA transfer function baked into the 256-entry 1D texture `lut`
// (a 1D texture, not a 256×1 2D one: the same linear lookup at half the texel reads,
// which is what it costs on CPU adapters; docs/perf.md).
// Texel centres sit at (i + 0.5)/N, so x ∈ [0,1] maps to (x·(N−1) + 0.5)/N.

// N: the table's entries, `vwb_render::tf::LUT_SIZE` (a test keeps the two equal). A
// constant power of two, so the division is a multiplication by the exact 1/N: the
// same bits as dividing by the table's size, without a division per sample, which
// llvmpipe would not hoist out of the march (docs/perf.md, "Divisions once per ray").
const LUT_N: f32 = 256.0;

fn classify(s: Sample) -> Sample {
    var o = s;
    let x = (clamp(s.value, 0.0, 1.0) * (LUT_N - 1.0) + 0.5) * (1.0 / LUT_N);
    let c = textureSampleLevel(lut, linear_clamp, x, 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
