// classify.labels — one 1D transfer function per label. The label volume `labels`
// (one byte per voxel, r = min(label, 255)/255) is read at the nearest voxel; the value is interpolated as usual
// and looked up in row `label` of the table `lut` (one row per label, hidden labels
// all zero; labels beyond the last row use the last row).

// The table's size: `vwb_render::tf::LUT_SIZE` entries by `MAX_LABELS` rows (mod.rs; a
// test keeps them equal). Constant powers of two, so the divisions by them are exact
// multiplications (`table_coord`; docs/perf.md, "Divisions once per ray").
const LUT_SIZE: vec2<f32> = vec2<f32>(256.0, 8.0);

fn classify(s: Sample) -> Sample {
    var o = s;
    let dims = vec3<i32>(textureDimensions(labels));
    let voxel = clamp(vec3<i32>(floor(s.tex * vec3<f32>(dims))), vec3<i32>(0), dims - vec3<i32>(1));
    let label = round(textureLoad(labels, voxel, 0).r * 255.0);
    let row = min(label, LUT_SIZE.y - 1.0);
    let x = table_coord(clamp(s.value, 0.0, 1.0), LUT_SIZE.x);
    let c = textureSampleLevel(lut, linear_clamp, vec2<f32>(x, (row + 0.5) * (1.0 / LUT_SIZE.y)), 0.0);
    o.color = vec4<f32>(c.rgb, clamp(c.a * params.opacity, 0.0, 1.0));
    return o;
}
