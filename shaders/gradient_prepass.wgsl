// Gradient pre-pass shared by the shading plugins (render/src/shading.rs): the
// estimator's on-the-fly function evaluated at the voxel centre (where trilinear
// interpolation returns the voxel), stored as rgba32float: xyz = ∇f·Δs0, w = the voxel's
// value, which the main module's `sample_value` reads in the same fetch as the gradient
// (precomputed_*), or as the rgba8unorm code of `gradient_encode` (quantized).
fn prepass(voxel: vec3<u32>, dims: vec3<u32>) -> vec4<f32> {
    let tex = (vec3<f32>(voxel) + vec3<f32>(0.5)) / vec3<f32>(dims);
    let g = gradient_ESTIMATOR(tex);
    return STORED;
}
