// shade.input_tint: w = strength · ramp(a), a the second volume's normalised value at
// the sample (`field.a`: a scalar's value by its range, a vector's magnitude), the ramp
// linear from `low` to `high`; the colour becomes mix(colour, tint, w), its opacity
// kept. `field` is the `Volume` parameter's texture (plugins/src/user.rs).
fn shade(s: Sample) -> Sample {
    var o = s;
    let a = textureSampleLevel(field, linear_clamp, s.tex, 0.0).a;
    let w = params.strength * clamp((a - params.low) / max(params.high - params.low, 1e-6), 0.0, 1.0);
    o.color = vec4<f32>(mix(s.color.rgb, params.tint.rgb, w), s.color.a);
    return o;
}
