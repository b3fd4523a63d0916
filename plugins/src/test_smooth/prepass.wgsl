// test.smooth pre-pass: a (2r+1)³ box filter of the volume into `smoothed`.
fn prepass(voxel: vec3<u32>, dims: vec3<u32>) -> vec4<f32> {
    let v = vec3<i32>(voxel);
    let r = params.radius;
    var sum = 0.0;
    for (var z = -r; z <= r; z = z + 1) {
        for (var y = -r; y <= r; y = y + 1) {
            for (var x = -r; x <= r; x = x + 1) {
                sum = sum + volume_voxel(v + vec3<i32>(x, y, z));
            }
        }
    }
    let n = f32((2 * r + 1) * (2 * r + 1) * (2 * r + 1));
    return vec4<f32>(sum / n, 0.0, 0.0, 1.0);
}
