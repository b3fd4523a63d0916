use std::path::PathBuf;

use glam::DVec3;
use vwb_render::params::{ParamValue, ParamValues};
use vwb_render::plugin::{CpuSample, Plugin};

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

/// A 4×2×1 u16 label volume written as NRRD.
fn write_u16(name: &str, labels: &[u16; 8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("vwb_clip_labels_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    let mut bytes = b"NRRD0004\ntype: uint16\ndimension: 3\nsizes: 4 2 1\nendian: little\nencoding: raw\n\n".to_vec();
    bytes.extend(labels.iter().flat_map(|l| l.to_le_bytes()));
    std::fs::write(&path, bytes).unwrap();
    path
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
    let path = write_u16("l16.nhdr", &[0, 1, 300, 40000, 1, 1, 300, 0]);
    let v = load_label_volume(&path).unwrap();
    assert_eq!(v.dims, [4, 2, 1]);
    let mut p = selection("show", &[(300, 40000)]);
    p.set("labels", ParamValue::Path(path.clone()));
    assert_eq!(
        Selection::from_params(&p).mask(&v),
        vec![0, 0, 255, 255, 0, 0, 255, 0]
    );
    let twin = ClipLabels.cpu_twin(&p).unwrap();
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

#[test]
fn a_float_or_missing_label_volume_is_an_error_naming_the_file() {
    let dir = std::env::temp_dir().join(format!("vwb_clip_labels_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("float.nhdr");
    let mut bytes = b"NRRD0004\ntype: float\ndimension: 3\nsizes: 1 1 1\nendian: little\nencoding: raw\n\n".to_vec();
    bytes.extend(1.5f32.to_le_bytes());
    std::fs::write(&path, bytes).unwrap();
    let e = load_label_volume(&path).unwrap_err();
    assert!(e.contains("float.nhdr") && e.contains("u8 or u16"), "{e}");
    let e = load_label_volume(&dir.join("missing.nhdr")).unwrap_err();
    assert!(e.contains("missing.nhdr"), "{e}");
}
