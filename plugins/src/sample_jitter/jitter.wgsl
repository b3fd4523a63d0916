// sample.jitter: stochastic or interleaved slice jitter (Keller & Heidrich 2001,
// "Interleaved sampling"; Rezk-Salama 2001 §3 names the slicing artefact it removes).
// `setup` draws one offset per pixel, u in [0,1), from a hash of the pixel (white
// noise) or from a 4×4 ordered-dither matrix (interleaved: 16 offsets spread over
// every 4×4 block); the `sample` hook then moves every sample of that ray by
// amount·(u − ½) of its slice step along the ray, so the slices stay in place on
// average and the wood-grain pattern of coarse spacing turns into fine noise.
// Samples moved past the box read the volume's edge (the texture coordinate is
// clamped, as the sampler would). Put it first in the stack: later `sample` hooks
// and the shading gradients read the moved position. Twin: mod.rs.

fn jitter_hash(v: u32) -> u32 {
    // PCG output permutation (O'Neill 2014; the "pcg" hash of Jarzynski & Olano 2020)
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// The pixel's offset in [0,1).
fn jitter_offset(px: vec2<u32>) -> f32 {
    let seed = u32(params.seed);
    if (params.pattern == 1u) {
        // 4×4 ordered dither (Bayer), rotated by the seed
        let x = px.x & 3u;
        let y = px.y & 3u;
        let e = x ^ y;
        let b = ((e & 1u) << 3u) | ((y & 1u) << 2u) | (e & 2u) | ((y >> 1u) & 1u);
        return (f32((b + seed) & 15u) + 0.5) / 16.0;
    }
    let h = jitter_hash(px.x + jitter_hash(px.y + jitter_hash(seed)));
    return f32(h >> 8u) / 16777216.0;
}

fn setup(r: Ray, uv: vec2<f32>) -> vec4<f32> {
    let px = vec2<u32>(floor(uv * frame.viewport.xy));
    return vec4<f32>(params.amount * (jitter_offset(px) - 0.5), 0.0, 0.0, 0.0);
}

fn sample(s_in: Sample) -> Sample {
    var s = s_in;
    let d = ray_record.x * s.step;
    if (d == 0.0) {
        return s;
    }
    s.pos = s.pos + s.ray_dir * d;
    s.tex = clamp((s.pos - frame.box_min.xyz) / (frame.box_max.xyz - frame.box_min.xyz), vec3<f32>(0.0), vec3<f32>(1.0));
    s.value = volume_value(s.tex);
    return s;
}
