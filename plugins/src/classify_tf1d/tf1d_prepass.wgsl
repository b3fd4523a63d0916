// classify.tf1d pre-pass (pre-classification): each voxel's value through the
// table `lut`, stored opacity-weighted (rgb·α, α) so that interpolation between
// voxels weights colours by their opacity.

fn prepass(voxel: vec3<u32>, dims: vec3<u32>) -> vec4<f32> {
    let v = volume_voxel(vec3<i32>(voxel));
    let x = table_coord(clamp(v, 0.0, 1.0), f32(textureDimensions(lut)));
    let c = textureSampleLevel(lut, linear_clamp, x, 0.0);
    return vec4<f32>(c.rgb * c.a, c.a);
}
