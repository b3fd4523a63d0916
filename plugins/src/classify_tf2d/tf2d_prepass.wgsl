// classify.tf2d pre-pass: gradient magnitude per voxel by central differences
// (neighbours clamped at the border), normalised value per voxel.

fn prepass(voxel: vec3<u32>, dims: vec3<u32>) -> vec4<f32> {
    let v = vec3<i32>(voxel);
    let gx = volume_voxel(v + vec3<i32>(1, 0, 0)) - volume_voxel(v - vec3<i32>(1, 0, 0));
    let gy = volume_voxel(v + vec3<i32>(0, 1, 0)) - volume_voxel(v - vec3<i32>(0, 1, 0));
    let gz = volume_voxel(v + vec3<i32>(0, 0, 1)) - volume_voxel(v - vec3<i32>(0, 0, 1));
    return vec4<f32>(0.5 * length(vec3<f32>(gx, gy, gz)), 0.0, 0.0, 1.0);
}
