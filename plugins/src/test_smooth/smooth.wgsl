// test.smooth — demonstrates a pre-pass that fills a 3D texture: the sample hook
// blends the interpolated value with the box-filtered volume `smoothed`.
fn sample(s: Sample) -> Sample {
    var o = s;
    let sm = textureSampleLevel(smoothed, linear_clamp, s.tex, 0.0).r;
    o.value = mix(s.value, sm, params.amount);
    return o;
}
