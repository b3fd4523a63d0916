// clip.labels — the per-voxel mask `kept` (r = 1 where the voxel's label is kept,
// baked on the CPU from a u8 or u16 label volume and the selected labels) is read at
// the nearest voxel; samples in removed voxels are dropped before sampling.

fn clip(s: Sample) -> bool {
    let dims = vec3<i32>(textureDimensions(kept));
    let voxel = clamp(vec3<i32>(floor(s.tex * vec3<f32>(dims))), vec3<i32>(0), dims - vec3<i32>(1));
    return textureLoad(kept, voxel, 0).r > 0.5;
}
