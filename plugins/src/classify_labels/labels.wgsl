// classify.labels — one 1D transfer function per label. The label volume `labels`
// (one byte per voxel, r = min(label, 255)/255) is read at the nearest voxel; the value is interpolated as usual
// and looked up in row `label` of the table `lut` (one row per label, hidden labels
// all zero; labels beyond the last row use the last row).

fn classify(s: Sample) -> Sample {
    var o = s;
    let dims = vec3<i32>(textureDimensions(labels));
    let voxel = clamp(vec3<i32>(floor(s.tex * vec3<f32>(dims))), vec3<i32>(0), dims - vec3<i32>(1));
    let label = round(textureLoad(labels, voxel, 0).r * 255.0);
    let size = vec2<f32>(textureDimensions(lut));
    let row = min(label, size.y - 1.0);
    let x = (clamp(s.value, 0.0, 1.0) * (size.x - 1.0) + 0.5) / size.x;
    let c = textureSampleLevel(lut, linear_clamp, vec2<f32>(x, (row + 0.5) / size.y), 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
