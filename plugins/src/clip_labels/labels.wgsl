// clip.labels — the label volume `labels` (r8unorm, or rg8unorm holding the low and the
// high byte of labels above 255; an r8 texture reads 0 for the high byte) is read at the
// nearest voxel, and the selection table `kept` (256 × 256, r = 1 where the label is
// kept; label l at row l / 256, column l % 256) says whether its sample stays. Samples
// in removed voxels are dropped before sampling.

fn clip(s: Sample) -> bool {
    let dims = vec3<i32>(textureDimensions(labels));
    let voxel = clamp(vec3<i32>(floor(s.tex * vec3<f32>(dims))), vec3<i32>(0), dims - vec3<i32>(1));
    let code = vec2<i32>(round(textureLoad(labels, voxel, 0).rg * 255.0));
    return textureLoad(kept, code, 0).r > 0.5;
}
