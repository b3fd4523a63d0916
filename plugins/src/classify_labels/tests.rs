use std::sync::Arc;

use glam::DVec3;
use vwb_render::inputs::VolumeInputs;
use vwb_render::params::ParamValue;
use vwb_render::volume::{Volume, VoxelData};

use super::*;

/// A label volume `name` (u8, x fastest) as the document's only named volume.
fn inputs_with(name: &str, dims: [u32; 3], f: impl Fn(u32, u32, u32) -> u8) -> VolumeInputs {
    let mut labels = Vec::new();
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                labels.push(f(x, y, z));
            }
        }
    }
    let v = Volume::new(name, dims, 1, [1.0; 3], VoxelData::U8(labels)).unwrap();
    let mut inputs = VolumeInputs::default();
    inputs.insert(name, Arc::new(v));
    inputs
}

fn params_naming(name: &str) -> ParamValues {
    let mut p = ParamValues::defaults(&Labels.params());
    p.set("labels", ParamValue::Volume(name.into()));
    p
}

/// The twin of `params`, prepared for a frame over `volume` with `inputs`.
fn prepared(params: &ParamValues, volume: &Volume, inputs: &VolumeInputs) -> Box<dyn CpuTwin> {
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(volume, &scalars).with_inputs(inputs);
    let mut twin = Labels.cpu_twin(params).unwrap();
    twin.prepare(&ctx);
    twin
}

#[test]
fn nearest_label_picks_its_own_transfer_function() {
    // label = x (0..4) on a 4×2×2 grid
    let inputs = inputs_with("by_x", [4, 2, 2], |x, _, _| x as u8);
    let mut params = params_naming("by_x");
    params.set(
        "tf_2",
        ParamValue::Tf(TfCurve::ramp(0.0, 1.0, [1.0, 0.0, 0.0, 0.8])),
    );
    params.set(
        "tf_3",
        ParamValue::Tf(TfCurve::ramp(0.0, 1.0, [0.0, 0.0, 1.0, 0.4])),
    );
    // the data has other dims than the labels: each spans the volume's box
    let volume = Volume::new("v", [8, 3, 5], 1, [1.0; 3], VoxelData::U8(vec![0; 120])).unwrap();
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(&volume, &scalars).with_inputs(&inputs);
    let twin = prepared(&params, &volume, &inputs);
    let classify = |twin: &dyn CpuTwin, x: f64| {
        let mut s = CpuSample {
            tex: DVec3::new(x, 0.5, 0.5),
            value: 1.0,
            ..Default::default()
        };
        twin.classify(&ctx, &mut s);
        s.color
    };
    // label voxel 2 spans tex.x ∈ [0.5, 0.75): nearest, not interpolated
    assert_eq!(
        classify(twin.as_ref(), 0.51),
        DVec4::new(1.0, 0.0, 0.0, 0.8f32 as f64)
    );
    assert_eq!(
        classify(twin.as_ref(), 0.74),
        DVec4::new(1.0, 0.0, 0.0, 0.8f32 as f64)
    );
    assert_eq!(classify(twin.as_ref(), 0.76).z, 1.0);
    // label 0 is transparent by default
    assert_eq!(classify(twin.as_ref(), 0.1).w, 0.0);
    // before prepare the twin has read no labels: every voxel is label 0
    let unprepared = Labels.cpu_twin(&params).unwrap();
    assert_eq!(classify(unprepared.as_ref(), 0.6).w, 0.0);
    // hiding label 2 removes it, and only it
    params.set("show_2", ParamValue::Bool(false));
    let hidden = prepared(&params, &volume, &inputs);
    assert_eq!(classify(hidden.as_ref(), 0.6).w, 0.0);
    assert_eq!(classify(hidden.as_ref(), 0.8).z, 1.0);
    let volumes = Volumes::new(&volume, &inputs);
    let Transparency::ByValue(visible) = Labels.transparency(&params, &volumes) else {
        panic!("labels classify by value")
    };
    assert!(visible(0.9, 1.0), "label 3 is still shown");
    // label 3's table starts at 0: visible everywhere; with labels 3 and 0 hidden, the
    // rows of absent labels (4–7, default ramps from 0.05) do not count
    params.set("show_3", ParamValue::Bool(false));
    params.set("show_0", ParamValue::Bool(true));
    params.set("tf_0", ParamValue::Tf(TfCurve::ramp(0.6, 0.7, [1.0; 4])));
    params.set("tf_1", ParamValue::Tf(TfCurve::ramp(0.6, 0.7, [1.0; 4])));
    let Transparency::ByValue(visible) = Labels.transparency(&params, &volumes) else {
        panic!("labels classify by value")
    };
    assert!(!visible(0.0, 0.55) && visible(0.0, 0.65));
    // every label hidden: nothing is visible, so skipping may drop every brick
    for l in 0..MAX_LABELS {
        params.set(LABELS.key("show_{}", l), ParamValue::Bool(false));
    }
    let Transparency::ByValue(visible) = Labels.transparency(&params, &volumes) else {
        panic!("labels classify by value")
    };
    assert!(!visible(0.0, 1.0));
}

#[test]
fn labels_beyond_the_last_table_use_it() {
    let inputs = inputs_with("big", [2, 2, 2], |_, _, _| 200);
    let mut params = params_naming("big");
    params.set(
        "tf_7",
        ParamValue::Tf(TfCurve::ramp(0.0, 1.0, [0.0, 1.0, 0.0, 0.5])),
    );
    let grid = LabelGrid::read(inputs.get("big").unwrap());
    assert_eq!(grid.at(DVec3::splat(0.5)), 200);
    let table = bake(&params);
    assert_eq!(
        table[(MAX_LABELS - 1) * LUT_SIZE + LUT_SIZE - 1],
        [0.0, 1.0, 0.0, 0.5]
    );
    let volume = Volume::new("v", [2, 2, 2], 1, [1.0; 3], VoxelData::U8(vec![255; 8])).unwrap();
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(&volume, &scalars).with_inputs(&inputs);
    let twin = prepared(&params, &volume, &inputs);
    let mut s = CpuSample {
        tex: DVec3::splat(0.5),
        value: 1.0,
        ..Default::default()
    };
    twin.classify(&ctx, &mut s);
    assert_eq!(s.color, DVec4::new(0.0, 1.0, 0.0, 0.5));
}

#[test]
fn label_volumes_hold_non_negative_integers() {
    let v = |data: VoxelData, components: u32| {
        Volume::new("seg", [2, 1, 1], components, [1.0; 3], data).unwrap()
    };
    assert_eq!(
        label_input::label_values(&v(VoxelData::I16(vec![0, 300]), 1)).unwrap(),
        vec![0, 300]
    );
    assert_eq!(
        label_input::label_values(&v(VoxelData::U16(vec![7, 65535]), 1)).unwrap(),
        vec![7, 65535]
    );
    let e = label_input::label_values(&v(VoxelData::I16(vec![0, -1]), 1)).unwrap_err();
    assert!(e.contains("'seg'") && e.contains("negative label (-1)"), "{e}");
    let e = label_input::label_values(&v(VoxelData::F32(vec![0.0, 1.0]), 1)).unwrap_err();
    assert!(e.contains("floating-point"), "{e}");
    let e = label_input::label_values(&v(VoxelData::U8(vec![0; 4]), 2)).unwrap_err();
    assert!(e.contains("2 components"), "{e}");
    // which table rows occur, from the histogram: exact over a narrow label range …
    let rows = |data: VoxelData| label_input::rows_present(&v(data, 1), MAX_LABELS);
    assert_eq!(
        rows(VoxelData::U8(vec![1, 3])),
        [false, true, false, true, false, false, false, false]
    );
    // … labels from 7 up share the last row …
    assert_eq!(
        rows(VoxelData::U16(vec![9, 65535])),
        [false, false, false, false, false, false, false, true]
    );
    // … a superset over a wide one (bins wider than a label), all rows for no labels
    let wide = rows(VoxelData::I16(vec![0, 3000]));
    assert!(wide[0] && wide[7]);
    assert!(rows(VoxelData::F32(vec![0.0, 1.0])).iter().all(|&r| r));
}

#[test]
fn distinct_labels_are_listed_as_runs() {
    let v = |data: VoxelData| Volume::new("seg", [6, 1, 1], 1, [1.0; 3], data).unwrap();
    let labels = label_input::distinct_labels(&v(VoxelData::U16(vec![9, 0, 3, 1, 2, 9]))).unwrap();
    assert_eq!(labels, [0, 1, 2, 3, 9]);
    assert_eq!(label_input::label_runs(&labels, 8), "0–3, 9");
    assert_eq!(label_input::label_runs(&labels, 1), "0–3, …");
    assert_eq!(label_input::label_runs(&[65535], 8), "65535");
    assert!(label_input::distinct_labels(&v(VoxelData::F32(vec![0.0; 6]))).is_none());
}

/// The shader's table size is a constant (powers of two, so its divisions are exact
/// multiplications, none per sample on a CPU device): it must be the table's.
#[test]
fn the_shaders_table_size_is_the_tables() {
    use vwb_render::tf::LUT_SIZE;
    assert!(LUT_SIZE.is_power_of_two() && MAX_LABELS.is_power_of_two());
    let src = include_str!("labels.wgsl");
    assert!(src.contains(&format!(
        "const LUT_SIZE: vec2<f32> = vec2<f32>({LUT_SIZE}.0, {MAX_LABELS}.0);"
    )));
    assert!(!src.contains("textureDimensions(lut)"));
}
