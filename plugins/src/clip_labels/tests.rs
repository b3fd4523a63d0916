use std::sync::Arc;

use glam::DVec3;
use vwb_render::inputs::VolumeInputs;
use vwb_render::params::{ParamValue, ParamValues};
use vwb_render::plugin::{CpuSample, Plugin};
use vwb_render::volume::{Volume, VoxelData};

use super::*;

fn selection(mode: &str, ranges: &[(i32, i32)]) -> ParamValues {
    let mut p = ParamValues::defaults(&ClipLabels.params());
    p.set("mode", ParamValue::Enum(mode.into()));
    for (i, (f, t)) in range_keys().iter().enumerate() {
        let (a, b) = ranges.get(i).copied().unwrap_or((-1, 0));
        p.set(f, ParamValue::Int(a));
        p.set(t, ParamValue::Int(b));
    }
    p
}

#[test]
fn hide_and_show_select_label_ranges_up_to_65535() {
    let hide = Selection::from_params(&selection("hide", &[(3, 5), (60000, 65535)]));
    assert!(hide.keeps(0) && !hide.keeps(3) && !hide.keeps(5) && hide.keeps(6));
    assert!(!hide.keeps(65535) && hide.keeps(59999));
    let show = Selection::from_params(&selection("show", &[(300, 300)]));
    assert!(show.keeps(300) && !show.keeps(299) && !show.keeps(0));
    // the defaults hide the background label 0 only
    let d = Selection::from_params(&ParamValues::defaults(&ClipLabels.params()));
    assert!(!d.keeps(0) && d.keeps(1) && d.keeps(65535));
}

#[test]
fn u16_label_volume_masks_voxels_and_the_twin_reads_the_nearest() {
    let labels = vec![0u16, 1, 300, 40000, 1, 1, 300, 0];
    let seg = Volume::new("seg", [4, 2, 1], 1, [1.0; 3], VoxelData::U16(labels.clone())).unwrap();
    let mut inputs = VolumeInputs::default();
    inputs.insert("seg", Arc::new(seg));
    let mut p = selection("show", &[(300, 40000)]);
    p.set("labels", ParamValue::Volume("seg".into()));
    assert_eq!(
        Selection::from_params(&p).mask(&labels),
        vec![0, 0, 255, 255, 0, 0, 255, 0]
    );
    let data = Volume::new("v", [2, 2, 2], 1, [1.0; 3], VoxelData::U8(vec![0; 8])).unwrap();
    let scalars = data.normalized_scalars();
    let ctx = CpuContext::new(&data, &scalars).with_inputs(&inputs);
    let mut twin = ClipLabels.cpu_twin(&p).unwrap();
    // before prepare no labels are read: everything is dropped
    assert!(!twin.clip(&CpuSample::default()));
    twin.prepare(&ctx);
    let at = |x: f64, y: f64| {
        twin.clip(&CpuSample {
            tex: DVec3::new(x, y, 0.5),
            ..Default::default()
        })
    };
    // voxel (2, 0) holds 300: kept; (1, 0) holds 1: dropped; (3, 1) holds 0: dropped
    assert!(at(0.6, 0.2) && !at(0.4, 0.2) && !at(0.9, 0.9));
    // outside [0,1] clamps to the border voxels, as the GPU does
    assert!(at(0.6, -0.5) && !at(1.5, 0.9));
}
