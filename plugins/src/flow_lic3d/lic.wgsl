// flow.lic3d: the sample's value becomes the LIC intensity of the pre-pass volume `lic`,
// optionally modulated by the field's magnitude (the volume's normalised value), for
// the classification plugins after it.
fn sample(s: Sample) -> Sample {
    var o = s;
    let i = textureSampleLevel(lic, linear_clamp, s.tex, 0.0).r;
    o.value = mix(i, i * s.value, params.modulate);
    return o;
}
