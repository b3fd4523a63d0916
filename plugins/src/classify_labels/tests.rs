use super::*;
use vwb_render::params::ParamValue;
use vwb_render::volume::Volume;

/// Writes a u8 NRRD (attached header, raw) and returns its path.
fn write_labels(name: &str, dims: [u32; 3], f: impl Fn(u32, u32, u32) -> u8) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("vwb-labels-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.nrrd"));
    let mut bytes = format!(
        "NRRD0004\ntype: uint8\ndimension: 3\nsizes: {} {} {}\nencoding: raw\n\n",
        dims[0], dims[1], dims[2]
    )
    .into_bytes();
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                bytes.push(f(x, y, z));
            }
        }
    }
    std::fs::write(&path, bytes).unwrap();
    path
}

fn params_with(path: &Path) -> ParamValues {
    let mut p = ParamValues::defaults(&Labels.params());
    p.set("labels", ParamValue::Path(path.to_path_buf()));
    p
}

#[test]
fn nearest_label_picks_its_own_transfer_function() {
    // label = x (0..4) on a 4×2×2 grid
    let path = write_labels("by_x", [4, 2, 2], |x, _, _| x as u8);
    let mut params = params_with(&path);
    params.set(
        "tf_2",
        ParamValue::Tf(TfCurve::ramp(0.0, 1.0, [1.0, 0.0, 0.0, 0.8])),
    );
    params.set(
        "tf_3",
        ParamValue::Tf(TfCurve::ramp(0.0, 1.0, [0.0, 0.0, 1.0, 0.4])),
    );
    let twin = Labels.cpu_twin(&params).unwrap();
    let volume = Volume::new("v", [4, 2, 2], 1, [1.0; 3], VoxelData::U8(vec![0; 16])).unwrap();
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(&volume, &scalars);
    let classify = |x: f64| {
        let mut s = CpuSample {
            tex: DVec3::new(x, 0.5, 0.5),
            value: 1.0,
            ..Default::default()
        };
        twin.classify(&ctx, &mut s);
        s.color
    };
    // voxel 2 spans tex.x ∈ [0.5, 0.75): nearest, not interpolated
    assert_eq!(classify(0.51), DVec4::new(1.0, 0.0, 0.0, 0.8f32 as f64));
    assert_eq!(classify(0.74), DVec4::new(1.0, 0.0, 0.0, 0.8f32 as f64));
    assert_eq!(classify(0.76).z, 1.0);
    // label 0 is transparent by default
    assert_eq!(classify(0.1).w, 0.0);
    // hiding label 2 removes it, and only it
    params.set("show_2", ParamValue::Bool(false));
    let hidden = Labels.cpu_twin(&params).unwrap();
    let mut s = CpuSample {
        tex: DVec3::new(0.6, 0.5, 0.5),
        value: 1.0,
        ..Default::default()
    };
    hidden.classify(&ctx, &mut s);
    assert_eq!(s.color.w, 0.0);
    let Transparency::ByValue(visible) = Labels.transparency(&params) else {
        panic!("labels classify by value")
    };
    assert!(visible(0.9, 1.0), "label 3 is still shown");
}

#[test]
fn labels_beyond_the_last_table_use_it() {
    let path = write_labels("big", [2, 2, 2], |_, _, _| 200);
    let mut params = params_with(&path);
    params.set(
        "tf_7",
        ParamValue::Tf(TfCurve::ramp(0.0, 1.0, [0.0, 1.0, 0.0, 0.5])),
    );
    let grid = load_labels(&path).unwrap();
    assert_eq!(grid.at(DVec3::splat(0.5)), 200);
    let table = bake(&params);
    assert_eq!(
        table[(MAX_LABELS - 1) * LUT_SIZE + LUT_SIZE - 1],
        [0.0, 1.0, 0.0, 0.5]
    );
}

#[test]
fn bad_label_volumes_are_refused_with_the_file_named() {
    // dims differ from the data
    let path = write_labels("small", [2, 2, 2], |_, _, _| 1);
    let e = grid_for(&params_with(&path), [4, 4, 4])
        .unwrap_err()
        .to_string();
    assert!(e.contains("small.nrrd") && e.contains("differ"), "{e}");
    // not u8
    let dir = path.parent().unwrap();
    let f32_path = dir.join("float.nrrd");
    let mut bytes =
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 1 1 1\nencoding: raw\nendian: little\n\n"
            .to_vec();
    bytes.extend_from_slice(&1.0f32.to_le_bytes());
    std::fs::write(&f32_path, bytes).unwrap();
    let e = load_labels(&f32_path).unwrap_err();
    assert!(e.contains("float.nrrd") && e.contains("u8"), "{e}");
    // missing file, and no file set
    let e = grid_for(&params_with(&dir.join("absent.nrrd")), [1, 1, 1])
        .unwrap_err()
        .to_string();
    assert!(e.contains("absent.nrrd"), "{e}");
    let e = grid_for(&ParamValues::defaults(&Labels.params()), [1, 1, 1])
        .unwrap_err()
        .to_string();
    assert!(e.contains("no label volume"), "{e}");
    assert!(
        Labels
            .cpu_twin(&ParamValues::defaults(&Labels.params()))
            .is_none()
    );
}
