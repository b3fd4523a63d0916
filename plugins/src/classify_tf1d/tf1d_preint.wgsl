// classify.tf1d, pre-integrated classification (Engel et al. 2001): the slab from
// this slice to the next along the ray runs from the front value s.value to the back
// value read where the ray meets the next slice plane. The n×n table `preint`
// (built on the CPU for the current TF, opacity scale and slice spacing; see
// preint.rs) holds the slab's straight colour and its opacity per reference step,
// which the core's opacity correction turns back into the slab opacity. The table
// `preint_depth` holds where in the slab its opacity is taken up (`shade_at`).

// The table's size, `vwb_render::tf::LUT_SIZE` squared (a test keeps the two equal): a
// constant for `table_coord2`.
const PREINT_N: f32 = 256.0;

fn classify(s: Sample) -> Sample {
    var o = s;
    let back_pos = s.pos + s.ray_dir * s.step;
    let back_tex = (back_pos - frame.box_min.xyz) / (frame.box_max.xyz - frame.box_min.xyz);
    let back = volume_value(back_tex);
    let fb = clamp(vec2<f32>(s.value, back), vec2<f32>(0.0), vec2<f32>(1.0));
    let uv = table_coord2(fb, PREINT_N);
    o.color = textureSampleLevel(preint, linear_clamp, uv, 0.0);
    // shade_at: centroid — shading reads the gradient at the slab's opacity centroid
    // (left out at `front`: the structural parameter's other value, mod.rs)
    // centroid: begin
    o.shade_at = textureSampleLevel(preint_depth, linear_clamp, uv, 0.0).r;
    // centroid: end
    return o;
}
