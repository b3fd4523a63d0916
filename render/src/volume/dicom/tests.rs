use super::*;

/// A scratch folder, removed when dropped.
struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn dir(name: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!("vwb-dicom-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    Scratch(d)
}

/// A 4×3 slice whose value is 100·z + 10·y + x (z = the slice's index along the normal).
fn slice_values(z: i32) -> Vec<i32> {
    (0..3)
        .flat_map(|y| (0..4).map(move |x| 100 * z + 10 * y + x))
        .collect()
}

/// Writes `n` axial slices 2.5 mm apart, files and instance numbers shuffled.
fn axial_series(d: &Path, n: i32, spec: impl Fn(i32) -> SliceSpec<'static>) {
    for z in 0..n {
        // file names (and, in `axial`, instance numbers) are shuffled against the positions
        write_slice(&d.join(format!("IM{:04}", (z * 5 + 2) % n)), &spec(z)).unwrap();
    }
}

fn leak<T>(v: Vec<T>) -> &'static [T] {
    Box::leak(v.into_boxed_slice())
}

fn axial(z: i32, n: i32) -> SliceSpec<'static> {
    SliceSpec {
        instance: (z * 7 + 3) % n + 1,
        rows: 3,
        cols: 4,
        samples: leak(slice_values(z)),
        positions: leak(vec![[-10.0, -20.0, 30.0 + 2.5 * z as f64]]),
        pixel_spacing: Some([0.7, 0.5]),
        ..SliceSpec::default()
    }
}

fn i16s(v: &Volume) -> Vec<i16> {
    match &v.data {
        VoxelData::I16(x) => x.clone(),
        other => panic!("expected int16, got {:?}", other.scalar_type()),
    }
}

#[test]
fn slices_are_sorted_by_position_not_by_instance_number_or_name() {
    let d = dir("sorted");
    axial_series(&d, 6, |z| axial(z, 6));
    let v = load(&d).unwrap();
    assert_eq!(v.dims, [4, 3, 6]);
    assert_eq!(v.spacing, [0.5, 0.7, 2.5]);
    let want: Vec<i16> = (0..6).flat_map(slice_values).map(|x| x as i16).collect();
    assert_eq!(i16s(&v), want);
    assert!(
        v.notes[0].contains("6 slice(s) from 6 file(s)"),
        "{:?}",
        v.notes
    );
    // one file of the series loads the whole series
    let one = load(&d.join("IM0002")).unwrap();
    assert_eq!(i16s(&one), want);
    // through the format dispatch, by folder and by file
    assert_eq!(i16s(&crate::volume::load(&d).unwrap()), want);
    assert_eq!(i16s(&crate::volume::load(&d.join("IM0003")).unwrap()), want);
}

#[test]
fn a_series_against_the_normal_and_a_sagittal_series_land_in_lps() {
    // axial, x running right-to-left stored reversed (row direction −x), slices given
    // from head to feet: the loaded volume is the same as the plain axial series
    let d = dir("flipped");
    for z in 0..5 {
        let vals: Vec<i32> = (0..3)
            .flat_map(|y| (0..4).map(move |x| 100 * z + 10 * y + (3 - x)))
            .collect();
        write_slice(
            &d.join(format!("s{z}")),
            &SliceSpec {
                instance: z + 1,
                rows: 3,
                cols: 4,
                samples: &vals,
                positions: &[[3.0 * 0.5, 0.0, 2.5 * z as f64]],
                orientation: Some([-1.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
                pixel_spacing: Some([0.7, 0.5]),
                ..SliceSpec::default()
            },
        )
        .unwrap();
    }
    let v = load(&d).unwrap();
    let want: Vec<i16> = (0..5).flat_map(slice_values).map(|x| x as i16).collect();
    assert_eq!(i16s(&v), want);
    assert_eq!(v.spacing, [0.5, 0.7, 2.5]);
    // sagittal: rows run along +y (posterior), columns along −z (down), slices along +x
    let d = dir("sagittal");
    for x in 0..4 {
        // stored (col c, row r) = canonical (y = c, z = 2 − r)
        let vals: Vec<i32> = (0..3)
            .flat_map(|r| (0..5).map(move |c| 100 * (2 - r) + 10 * c + x))
            .collect();
        write_slice(
            &d.join(format!("s{x}")),
            &SliceSpec {
                instance: 4 - x,
                rows: 3,
                cols: 5,
                samples: &vals,
                positions: &[[0.8 * x as f64, 0.0, 0.0]],
                orientation: Some([0.0, 1.0, 0.0, 0.0, 0.0, -1.0]),
                pixel_spacing: Some([2.0, 0.6]),
                ..SliceSpec::default()
            },
        )
        .unwrap();
    }
    let v = load(&d).unwrap();
    assert_eq!(v.dims, [4, 5, 3]);
    // the z spacing is the mean gap of the decimal positions
    assert!((v.spacing[0] - 0.8).abs() < 1e-12, "{:?}", v.spacing);
    assert_eq!(&v.spacing[1..], &[0.6, 2.0]);
    let got = i16s(&v);
    for z in 0..3 {
        for y in 0..5 {
            for x in 0..4 {
                assert_eq!(got[(z * 5 + y) * 4 + x], (100 * z + 10 * y + x) as i16);
            }
        }
    }
}

#[test]
fn rescale_keeps_hounsfield_units_as_int16_or_goes_to_f32() {
    // 12-bit unsigned, intercept −1024: HU in int16
    let d = dir("rescale");
    for z in 0..3 {
        let vals: Vec<i32> = vec![0, 1024, 4095, 2000 + z];
        write_slice(
            &d.join(format!("s{z}")),
            &SliceSpec {
                instance: z + 1,
                rows: 2,
                cols: 2,
                samples: &vals,
                bits_stored: 12,
                signed: false,
                rescale: (1.0, -1024.0),
                positions: &[[0.0, 0.0, z as f64]],
                ..SliceSpec::default()
            },
        )
        .unwrap();
    }
    let v = load(&d).unwrap();
    assert_eq!(&i16s(&v)[0..4], &[-1024, 0, 3071, 976]);
    assert!(
        v.notes.iter().any(|n| n.contains("value·1 + -1024")),
        "{:?}",
        v.notes
    );
    // a fractional slope: f32
    let d = dir("slope");
    for z in 0..2 {
        write_slice(
            &d.join(format!("s{z}")),
            &SliceSpec {
                instance: z + 1,
                rows: 1,
                cols: 2,
                samples: &[-3, 5],
                rescale: (0.25, 10.0 * z as f64),
                positions: &[[0.0, 0.0, z as f64]],
                ..SliceSpec::default()
            },
        )
        .unwrap();
    }
    let v = load(&d).unwrap();
    let VoxelData::F32(x) = &v.data else {
        panic!("expected f32")
    };
    assert_eq!(x, &vec![-0.75, 1.25, 9.25, 11.25]);
    assert!(
        v.notes.iter().any(|n| n.contains("per slice")),
        "{:?}",
        v.notes
    );
    // bits above BitsStored are masked (unsigned) or sign-extended (signed)
    assert_eq!(stored(&[0xFF, 0xF0], 0, 16, 12, false), 0x0FF);
    assert_eq!(stored(&[0xFF, 0x0F], 0, 16, 12, true), -1);
    assert_eq!(stored(&[0x00, 0x08], 0, 16, 12, true), -2048);
}

#[test]
fn unequal_gaps_and_gantry_tilt_are_reported() {
    let d = dir("gaps");
    let zs = [0.0, 1.0, 2.0, 3.5, 4.5];
    for (i, z) in zs.iter().enumerate() {
        write_slice(
            &d.join(format!("s{i}")),
            &SliceSpec {
                instance: i as i32 + 1,
                rows: 1,
                cols: 1,
                samples: &[i as i32],
                // a tilt of 10°: each slice is also shifted along y
                positions: &[[0.0, z * 10f64.to_radians().tan(), *z]],
                ..SliceSpec::default()
            },
        )
        .unwrap();
    }
    let v = load(&d).unwrap();
    assert!((v.spacing[2] - 1.125).abs() < 1e-9, "{:?}", v.spacing);
    let notes = v.notes.join("\n");
    assert!(
        notes.contains("unequal slice spacing: gaps from 1.000 to 1.500"),
        "{notes}"
    );
    assert!(
        notes.contains("gantry tilt") && notes.contains("10.00°"),
        "{notes}"
    );
}

#[test]
fn rle_and_multi_frame_files_load_as_the_plain_series() {
    let plain: Vec<i16> = (0..4).flat_map(slice_values).map(|x| x as i16).collect();
    let d = dir("rle");
    axial_series(&d, 4, |z| SliceSpec {
        rle: true,
        ..axial(z, 4)
    });
    let v = load(&d).unwrap();
    assert_eq!(i16s(&v), plain);
    assert!(v.notes[0].contains("RLE"), "{:?}", v.notes);
    // one multi-frame file, frames stored top to bottom with per-frame positions
    let d = dir("multiframe");
    let samples: Vec<i32> = (0..4).rev().flat_map(slice_values).collect();
    let positions: Vec<[f64; 3]> = (0..4).rev().map(|z| [0.0, 0.0, 2.5 * z as f64]).collect();
    let f = d.join("enhanced.dcm");
    write_slice(
        &f,
        &SliceSpec {
            rows: 3,
            cols: 4,
            frames: 4,
            samples: &samples,
            positions: &positions,
            pixel_spacing: Some([0.7, 0.5]),
            ..SliceSpec::default()
        },
    )
    .unwrap();
    let v = load(&f).unwrap();
    assert_eq!(i16s(&v), plain);
    assert_eq!(v.spacing, [0.5, 0.7, 2.5]);
}

#[test]
fn bad_series_fail_with_the_file_and_the_cause() {
    let err = |p: &Path| crate::volume::load(p).unwrap_err().to_string();
    // two slices at one position
    let d = dir("duplicate");
    for i in 0..3 {
        write_slice(
            &d.join(format!("s{i}")),
            &SliceSpec {
                instance: i + 1,
                samples: &[i],
                positions: &[[0.0, 0.0, (i / 2) as f64]],
                ..SliceSpec::default()
            },
        )
        .unwrap();
    }
    let e = err(&d);
    assert!(
        e.contains("lie at the same position") && e.contains("s1"),
        "{e}"
    );
    // slices of different sizes
    let d = dir("sizes");
    for (i, cols) in [(0, 1u16), (1, 2)] {
        write_slice(
            &d.join(format!("s{i}")),
            &SliceSpec {
                instance: i + 1,
                cols,
                samples: &[0, 0][..cols as usize],
                positions: &[[0.0, 0.0, i as f64]],
                ..SliceSpec::default()
            },
        )
        .unwrap();
    }
    assert!(err(&d).contains("must share their size"), "{}", err(&d));
    // a truncated file: the pixel data's length lies
    let d = dir("truncated");
    let f = d.join("cut.dcm");
    write_slice(
        &f,
        &SliceSpec {
            rows: 64,
            cols: 64,
            samples: &vec![7; 64 * 64],
            positions: &[[0.0; 3]],
            ..SliceSpec::default()
        },
    )
    .unwrap();
    let bytes = std::fs::read(&f).unwrap();
    std::fs::write(&f, &bytes[..bytes.len() - 100]).unwrap();
    let e = err(&f);
    assert!(
        e.contains("cut.dcm") && e.contains("(7FE0,0010)") && e.contains("truncated"),
        "{e}"
    );
    // an element claiming 4 GB in a 1 kB file fails before it is read
    let mut lying = bytes.clone();
    let at = lying
        .windows(4)
        .position(|w| w == [0x28, 0x00, 0x10, 0x00])
        .expect("Rows");
    // explicit VR US: tag, "US", 2-byte length → make it a UN with a 4-byte length
    lying[at + 4..at + 6].copy_from_slice(b"UN");
    lying.splice(at + 6..at + 8, [0, 0, 0xFF, 0xFF, 0xFF, 0xF0]);
    std::fs::write(&f, &lying).unwrap();
    let e = err(&f);
    assert!(
        e.contains("(0028,0010)") && e.contains("claims 4043309055 bytes"),
        "{e}"
    );
    // no DICOM in a folder; a colour image
    let d = dir("colour");
    let mut obj = InMemDicomObject::new_empty();
    obj.put(DataElement::new(
        tags::ROWS,
        VR::US,
        PrimitiveValue::from(1u16),
    ));
    obj.put(DataElement::new(
        tags::COLUMNS,
        VR::US,
        PrimitiveValue::from(1u16),
    ));
    obj.put(DataElement::new(
        tags::BITS_ALLOCATED,
        VR::US,
        PrimitiveValue::from(8u16),
    ));
    obj.put(DataElement::new(
        tags::SAMPLES_PER_PIXEL,
        VR::US,
        PrimitiveValue::from(3u16),
    ));
    obj.put(DataElement::new(
        tags::PHOTOMETRIC_INTERPRETATION,
        VR::CS,
        PrimitiveValue::from("RGB"),
    ));
    obj.put(DataElement::new(
        tags::PIXEL_DATA,
        VR::OB,
        PrimitiveValue::U8(vec![1, 2, 3, 0].into()),
    ));
    let f = d.join("rgb.dcm");
    obj.with_meta(
        FileMetaTableBuilder::new()
            .transfer_syntax(uids::EXPLICIT_VR_LITTLE_ENDIAN)
            .media_storage_sop_class_uid(uids::CT_IMAGE_STORAGE)
            .media_storage_sop_instance_uid("1.2.3"),
    )
    .unwrap()
    .write_to_file(&f)
    .unwrap();
    let e = err(&f);
    assert!(
        e.contains("rgb.dcm") && e.contains("3 samples per pixel (RGB)"),
        "{e}"
    );
    let e = load(&dir("empty")).unwrap_err().to_string();
    assert!(e.contains("holds no DICOM file"), "{e}");
}
