//! Volume formats beyond NRRD (render/src/volume/{nifti,metaimage,dicom,orient}.rs): the
//! same anatomy stored in different axis orders and orientations by NRRD, NIfTI (.nii.gz),
//! MetaImage and a DICOM series loads to the same voxels (left stays left), renders the same image,
//! and `vwb info --volume` prints what was read.

use std::io::Write;
use std::path::Path;

use vwb_render::volume::{self, Volume, VoxelData};

use crate::common::*;

/// The CT head's int16 samples, x fastest (LPS as stored in the NRRD).
fn ct() -> Volume {
    data_dir();
    let v =
        vwb_lab::headless::load_volume(&vwb_render::preset::VolumeSource::Sample("ct_head".into()))
            .unwrap();
    Volume::clone(&v)
}

fn i16s(v: &Volume) -> &[i16] {
    match &v.data {
        VoxelData::I16(s) => s,
        other => panic!("{other:?}"),
    }
}

/// Stores `v` with its axes permuted and flipped: stored axis a is canonical axis
/// `perm[a]`, reversed where `flip[a]`.
fn store(v: &Volume, perm: [usize; 3], flip: [bool; 3]) -> (Vec<i16>, [u32; 3], [f64; 3]) {
    let d = v.dims.map(|x| x as usize);
    let sd: [usize; 3] = std::array::from_fn(|a| d[perm[a]]);
    let s = i16s(v);
    let mut out = Vec::with_capacity(s.len());
    for k in 0..sd[2] {
        for j in 0..sd[1] {
            for i in 0..sd[0] {
                let st = [i, j, k];
                let mut c = [0usize; 3];
                for a in 0..3 {
                    c[perm[a]] = if flip[a] { sd[a] - 1 - st[a] } else { st[a] };
                }
                out.push(s[(c[2] * d[1] + c[1]) * d[0] + c[0]]);
            }
        }
    }
    (
        out,
        sd.map(|x| x as u32),
        std::array::from_fn(|a| v.spacing[perm[a]]),
    )
}

fn gzip(path: &Path) -> std::path::PathBuf {
    let bytes = std::fs::read(path).unwrap();
    let gz = path.with_extension("nii.gz");
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(&bytes).unwrap();
    std::fs::write(&gz, e.finish().unwrap()).unwrap();
    gz
}

#[test]
fn the_same_anatomy_from_nifti_and_metaimage_lands_in_the_same_place() {
    let ct = ct();
    // NIfTI: x stored right-to-left reversed (i → patient right), z stored top-down;
    // the sform (RAS) says so
    let (s, dims, sp) = store(&ct, [0, 1, 2], [true, false, true]);
    let nii = tmp("ct_flipped.nii");
    let sform = [
        [sp[0] as f32, 0.0, 0.0, 0.0],  // i → +R (RAS x)
        [0.0, -sp[1] as f32, 0.0, 0.0], // j → +P
        [0.0, 0.0, -sp[2] as f32, 0.0], // k → inferior
    ];
    volume::nifti::write_nifti1(&nii, dims, sp.map(|x| x as f32), sform, &s).unwrap();
    let gz = gzip(&nii);
    let from_nifti = volume::load(&gz).unwrap();
    assert_eq!(from_nifti.dims, ct.dims);
    assert_eq!(from_nifti.spacing, ct.spacing.map(|x| x as f32 as f64));
    assert!(i16s(&from_nifti) == i16s(&ct), "NIfTI voxels moved");
    // MetaImage: axes stored as (z, y, x), the TransformMatrix gives each axis' direction
    let (s, dims, sp) = store(&ct, [2, 1, 0], [false, false, false]);
    let raw = tmp("ct_zyx.raw");
    std::fs::write(
        &raw,
        s.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>(),
    )
    .unwrap();
    let mhd = tmp("ct_zyx.mhd");
    std::fs::write(
        &mhd,
        format!(
            "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n\
             TransformMatrix = 0 0 1 0 1 0 1 0 0\nOffset = 0 0 0\nAnatomicalOrientation = ???\n\
             ElementSpacing = {} {} {}\nDimSize = {} {} {}\nElementType = MET_SHORT\nElementDataFile = ct_zyx.raw\n",
            sp[0], sp[1], sp[2], dims[0], dims[1], dims[2]
        ),
    )
    .unwrap();
    let from_mhd = volume::load(&mhd).unwrap();
    assert_eq!(from_mhd.dims, ct.dims);
    assert_eq!(from_mhd.spacing, ct.spacing);
    assert!(i16s(&from_mhd) == i16s(&ct), "MetaImage voxels moved");
    // a voxel on the patient's left half stays there: the skull's left edge is at low x
    // in every copy, by construction of the comparison above; and the render agrees
    let reference = render_ct(&data_dir().join("ct_cranium_256x256x108_int16.nhdr"));
    assert!(
        render_ct(&gz) == reference,
        "the NIfTI copy renders differently"
    );
    assert!(
        render_ct(&mhd) == reference,
        "the MetaImage copy renders differently"
    );
}

/// `presets/ct_head.ron` rendered at 64² from `volume` by the `vwb` binary.
fn render_ct(volume: &Path) -> image::RgbImage {
    let preset = repo().join("presets/ct_head.ron");
    let out = tmp(&format!(
        "{}.png",
        volume.file_name().unwrap().to_string_lossy()
    ));
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_vwb"))
        .args(["render", "--size", "64x64", "--preset"])
        .arg(&preset)
        .arg("--volume")
        .arg(volume)
        .arg("-o")
        .arg(&out)
        .env("VWB_DATA_DIR", data_dir())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    image::open(&out).unwrap().to_rgb8()
}

/// The CT head as a coronal DICOM series: rows run along +x (left), columns down the
/// head (−z), one file per y (anterior to posterior); file names, instance numbers and
/// the order of writing are shuffled, so only ImagePositionPatient gives the order. It
/// loads to exactly the NRRD's voxels and renders its image.
#[test]
fn the_same_anatomy_from_a_dicom_series_lands_in_the_same_place() {
    let ct = ct();
    let (s, dims, sp) = store(&ct, [0, 2, 1], [false, true, false]);
    let dir = tmp("ct_coronal_dicom");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let plane = (dims[0] * dims[1]) as usize;
    let n = dims[2] as i32;
    for k in 0..n {
        let samples: Vec<i32> = s[k as usize * plane..(k as usize + 1) * plane]
            .iter()
            .map(|&v| i32::from(v))
            .collect();
        // stored row 0 is the top of the head: canonical z = dims_z − 1
        let top = (ct.dims[2] - 1) as f64 * ct.spacing[2];
        let position = [[0.0, k as f64 * sp[2], top]];
        let shuffled = (k * 37 + 11) % n;
        volume::dicom::write_slice(
            &dir.join(format!("{shuffled:03}.dcm")),
            &volume::dicom::SliceSpec {
                instance: (k * 101 + 5) % n + 1,
                rows: dims[1] as u16,
                cols: dims[0] as u16,
                samples: &samples,
                positions: &position,
                orientation: Some([1.0, 0.0, 0.0, 0.0, 0.0, -1.0]),
                pixel_spacing: Some([sp[1], sp[0]]),
                ..Default::default()
            },
        )
        .unwrap();
    }
    let from_dicom = volume::load(&dir).unwrap();
    assert_eq!(from_dicom.dims, ct.dims);
    for a in 0..3 {
        assert!(
            (from_dicom.spacing[a] - ct.spacing[a]).abs() < 1e-9,
            "{:?} against {:?}",
            from_dicom.spacing,
            ct.spacing
        );
    }
    assert!(i16s(&from_dicom) == i16s(&ct), "DICOM voxels moved");
    assert!(
        from_dicom.notes[0].contains("axes to LPS: x→x, y→−z, z→y"),
        "{:?}",
        from_dicom.notes
    );
    // one file of the series opens the whole series; the image is the NRRD's
    let image = render_ct(&dir.join("000.dcm"));
    let reference = render_ct(&data_dir().join("ct_cranium_256x256x108_int16.nhdr"));
    let worst = image
        .as_raw()
        .iter()
        .zip(reference.as_raw())
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap();
    assert!(
        worst <= 1,
        "the DICOM copy renders differently (max {worst}/255)"
    );
}

#[test]
fn info_prints_what_was_read() {
    let ct = ct();
    let (s, dims, sp) = store(&ct, [0, 1, 2], [true, false, false]);
    let nii = tmp("info.nii");
    let sform = [
        [sp[0] as f32, 0.0, 0.0, 0.0],
        [0.0, -sp[1] as f32, 0.0, 0.0],
        [0.0, 0.0, sp[2] as f32, 0.0],
    ];
    volume::nifti::write_nifti1(&nii, dims, sp.map(|x| x as f32), sform, &s).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_vwb"))
        .args(["info", "--volume"])
        .arg(&nii)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for want in [
        "dims: 256 x 256 x 108",
        "samples: int16 (1 component)",
        "value range: -1024 .. 2986",
        "orientation from sform",
        "x→−x",
    ] {
        assert!(text.contains(want), "missing '{want}' in:\n{text}");
    }
    // signed with negative values: not a label volume, no label line
    assert!(!text.contains("integer values"), "{text}");
    // the demo's label volume: its labels, for choosing ranges to hide
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_vwb"))
        .args(["info", "--volume"])
        .arg(crate::common::repo().join("presets/data/demo_labels.nrrd"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("integer values: 4 distinct: 0–3 (as the labels of"),
        "{text}"
    );
    // a lying header: 30000³ voxels, refused before allocating, naming the file
    let mut bytes = std::fs::read(&nii).unwrap();
    bytes.truncate(352 + 64);
    for i in 0..3 {
        bytes[42 + 2 * i..44 + 2 * i].copy_from_slice(&30000i16.to_le_bytes());
    }
    let liar = tmp("liar.nii");
    std::fs::write(&liar, bytes).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_vwb"))
        .args(["info", "--volume"])
        .arg(&liar)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("liar.nii") && err.contains("30000"), "{err}");
}
