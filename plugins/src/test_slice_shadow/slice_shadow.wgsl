// test.slice_shadow — demonstrates per-slice state (ping-pong buffers).
// `state_prev.r` holds the opacity accumulated in front of the current slice, as seen
// from the eye; `shade` darkens the slice by it and `slice_update` adds the slice's
// own contribution for the next slice. With strength 1 every sample is attenuated by
// what lies in front of it a second time (a head-on "shadow").

fn shade(s: Sample) -> Sample {
    var o = s;
    let occ = textureSampleLevel(state_prev, linear_clamp, state_coord(s.pos, s.uv), 0.0).r;
    o.color = vec4<f32>(s.color.rgb * (1.0 - params.strength * occ), s.color.a);
    return o;
}

fn slice_update(s: Sample, c: vec4<f32>, uv: vec2<f32>) -> vec4<f32> {
    let prev = textureSampleLevel(state_prev, linear_clamp, uv, 0.0).r;
    return vec4<f32>(prev + (1.0 - prev) * c.a, 0.0, 0.0, 1.0);
}
