//! Tests of the volume loaders on the shared real data, on files written here,
//! and on malformed input.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use flate2::Compression;
use flate2::write::{GzEncoder, ZlibEncoder};

use super::*;

// ---------------------------------------------------------------- helpers

/// The sample data files: `VWB_DATA_DIR`, else the shared copy beside the repository.
fn shared(name: &str) -> PathBuf {
    let dir = std::env::var_os(crate::samples::DATA_DIR_ENV)
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data")).to_path_buf()
        });
    let path = dir.join(name);
    assert!(
        path.is_file(),
        "test data {} is missing (set VWB_DATA_DIR to the sample files: vwb data list)",
        path.display()
    );
    path
}

/// A unique temporary folder, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir =
            std::env::temp_dir().join(format!("vwb-volume-test-{tag}-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create temp dir");
        TempDir(dir)
    }

    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let path = self.0.join(name);
        std::fs::write(&path, bytes).expect("write temp file");
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `NRRD0004`, the fields one per line, a blank line, then `data`.
fn nrrd(fields: &[&str], data: &[u8]) -> Vec<u8> {
    let mut out = b"NRRD0004\n".to_vec();
    for f in fields {
        out.extend_from_slice(f.as_bytes());
        out.push(b'\n');
    }
    out.push(b'\n');
    out.extend_from_slice(data);
    out
}

/// A detached header (no blank line needed).
fn nhdr(fields: &[&str]) -> Vec<u8> {
    let mut out = b"NRRD0005\n".to_vec();
    for f in fields {
        out.extend_from_slice(f.as_bytes());
        out.push(b'\n');
    }
    out
}

fn gzip(data: &[u8]) -> Vec<u8> {
    let mut enc = GzEncoder::new(Vec::new(), Compression::default());
    enc.write_all(data).expect("gzip");
    enc.finish().expect("gzip")
}

fn zlib(data: &[u8]) -> Vec<u8> {
    let mut enc = ZlibEncoder::new(Vec::new(), Compression::default());
    enc.write_all(data).expect("zlib");
    enc.finish().expect("zlib")
}

fn le_u16(values: &[u16]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn be_u16(values: &[u16]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_be_bytes()).collect()
}

fn le_f32(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn be_f32(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_be_bytes()).collect()
}

/// The error's message; fails the test if `r` is Ok.
fn err_text<T: std::fmt::Debug>(r: Result<T, VolumeError>) -> String {
    match r {
        Ok(v) => panic!("expected an error, got {v:?}"),
        Err(e) => e.to_string(),
    }
}

/// Asserts that the message names the file and contains every fragment.
fn assert_err(r: Result<Volume, VolumeError>, file: &Path, fragments: &[&str]) -> VolumeError {
    let e = match r {
        Ok(v) => panic!("expected an error mentioning {fragments:?}, got {v:?}"),
        Err(e) => e,
    };
    let msg = e.to_string();
    let name = file.file_name().expect("file name").to_string_lossy();
    assert!(msg.contains(name.as_ref()), "'{msg}' does not name {name}");
    for f in fragments {
        assert!(msg.contains(f), "'{msg}' does not contain '{f}'");
    }
    e
}

fn header(fields: &[&str]) -> Result<NrrdHeader, VolumeError> {
    parse_nrrd_header(
        &String::from_utf8_lossy(&nhdr(fields)),
        Some(Path::new("t.nhdr")),
    )
}

fn u16_samples(v: &Volume) -> &[u16] {
    match &v.data {
        VoxelData::U16(d) => d,
        other => panic!("expected u16 data, got {other:?}"),
    }
}

fn f32_samples(v: &Volume) -> &[f32] {
    match &v.data {
        VoxelData::F32(d) => d,
        other => panic!("expected f32 data, got {other:?}"),
    }
}

fn assert_close(a: f64, b: f64, what: &str) {
    assert!(
        (a - b).abs() <= 1e-6 * b.abs().max(1.0),
        "{what}: {a} != {b}"
    );
}

/// Common checks of the statistics of any volume.
fn check_stats(v: &Volume) {
    assert_eq!(v.histogram.len(), HISTOGRAM_BINS);
    let finite = v.voxel_count() as u64 - v.non_finite;
    assert_eq!(v.histogram.iter().sum::<u64>(), finite, "histogram total");
    assert!(v.range[0] <= v.range[1]);
    assert_eq!(v.data.len(), v.voxel_count() * v.components as usize);
}

// ---------------------------------------------------------------- real data

#[test]
fn shared_ct_cranium_int16() {
    let path = shared("ct_cranium_256x256x108_int16.nhdr");
    let v = load_nrrd(&path).expect("load CT");
    assert_eq!(v.name, "ct_cranium_256x256x108_int16");
    assert_eq!(v.dims, [256, 256, 108]);
    assert_eq!(v.components, 1);
    assert_eq!(v.scalar_type(), ScalarType::I16);
    assert_close(v.spacing[0], 0.9570312, "spacing x");
    assert_close(v.spacing[1], 0.9570312, "spacing y");
    assert_close(v.spacing[2], 1.5, "spacing z");
    assert_eq!(v.range, [-1024.0, 2986.0]);
    assert_eq!(v.non_finite, 0);
    assert_eq!(v.source.as_deref(), Some(path.as_path()));
    assert_eq!(v.size_bytes(), 14_155_776);
    check_stats(&v);
    // Air (about -1000 HU) dominates a head CT: the fullest bin is among the lowest.
    let fullest = v
        .histogram
        .iter()
        .enumerate()
        .max_by_key(|(_, c)| **c)
        .map(|(i, _)| i);
    assert!(fullest.is_some_and(|b| b < 8), "fullest bin {fullest:?}");

    // The content sniffing of `load` finds the same volume.
    let again = load(&path).expect("load() of the .nhdr");
    assert_eq!(again.data, v.data);

    // The same file through load_raw.
    let raw = load_raw(
        &shared("ct_cranium_256x256x108_int16.raw"),
        &RawDesc {
            spacing: v.spacing,
            ..RawDesc::new([256, 256, 108], ScalarType::I16)
        },
    )
    .expect("load_raw of the CT");
    assert_eq!(raw.data, v.data);
    assert_eq!(raw.range, v.range);
    assert_eq!(raw.histogram, v.histogram);
}

#[test]
fn shared_mri_head_uint8() {
    let v = load_nrrd(&shared("mri_head_volpack_128x128x84_uint8.nhdr")).expect("load MRI");
    assert_eq!(v.dims, [128, 128, 84]);
    assert_eq!(v.components, 1);
    assert_eq!(v.scalar_type(), ScalarType::U8);
    assert_eq!(v.spacing, [1.0; 3]);
    assert_eq!(v.range[0], 0.0);
    assert!(
        v.range[1] > 100.0 && v.range[1] <= 255.0,
        "range {:?}",
        v.range
    );
    check_stats(&v);
}

#[test]
fn shared_nuclei_uint16() {
    let v = load_nrrd(&shared("nuclei_fluo_256x256x60_uint16.nhdr")).expect("load nuclei");
    assert_eq!(v.dims, [256, 256, 60]);
    assert_eq!(v.components, 1);
    assert_eq!(v.scalar_type(), ScalarType::U16);
    assert_close(v.spacing[0], 0.26, "spacing x");
    assert_close(v.spacing[1], 0.26, "spacing y");
    assert_close(v.spacing[2], 0.29, "spacing z");
    assert!(v.range[1] > v.range[0] + 1000.0, "range {:?}", v.range);
    assert!(v.range[1] <= 65535.0);
    check_stats(&v);
}

#[test]
fn shared_ocean_float32() {
    let v = load_nrrd(&shared("ocean_temp_levitus_360x180x20_float32.nhdr")).expect("load ocean");
    assert_eq!(v.dims, [360, 180, 20]);
    assert_eq!(v.components, 1);
    assert_eq!(v.scalar_type(), ScalarType::F32);
    assert_eq!(v.spacing, [1.0; 3]);
    assert_eq!(v.range[0], -5.0, "land is -5");
    assert!(
        v.range[1] > 25.0 && v.range[1] < 40.0,
        "warmest sea {:?}",
        v.range
    );
    assert_eq!(v.non_finite, 0);
    check_stats(&v);
    // Normalised land is exactly 0, and every normalised value is in [0, 1].
    let n = v.normalized_scalars();
    assert_eq!(n.len(), v.voxel_count());
    assert!(n.iter().all(|s| (0.0..=1.0).contains(s)));
    let land = f32_samples(&v)
        .iter()
        .position(|&s| s == -5.0)
        .expect("some land");
    assert_eq!(n[land], 0.0);
}

#[test]
fn shared_wind_uv_2_vector() {
    let v = load_nrrd(&shared("wind_uv_ncl_128x64x14_float32x2.nhdr")).expect("load wind");
    assert_eq!(v.dims, [128, 64, 14]);
    assert_eq!(v.components, 2);
    assert_eq!(v.scalar_type(), ScalarType::F32);
    assert_eq!(v.spacing, [1.0; 3]);
    // Magnitudes: non-negative, jet streams reach tens of m/s.
    assert!(v.range[0] >= 0.0);
    assert!(
        v.range[1] > 20.0 && v.range[1] < 200.0,
        "range {:?}",
        v.range
    );
    check_stats(&v);
    let d = f32_samples(&v);
    let (x, y, z) = (5u32, 40u32, 7u32);
    let i = (x as usize + 128 * (y as usize + 64 * z as usize)) * 2;
    let expected = f64::from(d[i]).hypot(f64::from(d[i + 1]));
    assert_close(v.scalar(x, y, z), expected, "magnitude");
    assert_eq!(v.components_f32().len(), v.voxel_count() * 2);
}

#[test]
fn shared_storm_wind_3_vector() {
    let v = load_nrrd(&shared("storm_wind_ncsa_25x14x8_float32x3.nhdr")).expect("load storm");
    assert_eq!(v.dims, [25, 14, 8]);
    assert_eq!(v.components, 3);
    assert_eq!(v.scalar_type(), ScalarType::F32);
    assert_close(v.spacing[0], 4166.667, "spacing x");
    assert_close(v.spacing[1], 4153.846, "spacing y");
    assert_close(v.spacing[2], 2214.286, "spacing z");
    assert!(v.range[0] >= 0.0);
    assert!(
        v.range[1] > 1.0 && v.range[1] < 200.0,
        "range {:?}",
        v.range
    );
    check_stats(&v);
    let d = f32_samples(&v);
    let expected = d[..3]
        .iter()
        .map(|&c| f64::from(c).powi(2))
        .sum::<f64>()
        .sqrt();
    assert_close(v.scalar(0, 0, 0), expected, "magnitude of voxel 0");
}

#[test]
fn demo_volume_is_the_mri_head() {
    let d = demo();
    assert_eq!(d.name, "demo");
    assert_eq!(d.dims, [128, 128, 84]);
    assert_eq!(d.components, 1);
    assert_eq!(d.scalar_type(), ScalarType::U8);
    assert_eq!(d.spacing, [1.0; 3]);
    assert_eq!(d.source, None);
    check_stats(&d);
    let mri = load_nrrd(&shared("mri_head_volpack_128x128x84_uint8.nhdr")).expect("load MRI");
    assert_eq!(d.data, mri.data, "the demo holds the VolPack MRI head");
    assert_eq!(d.histogram, mri.histogram);
}

// ---------------------------------------------------------------- format features

const SMALL_DIMS: [u32; 3] = [4, 3, 2];

fn small_u16() -> Vec<u16> {
    (0..24u16).map(|i| i * 1000 + 7).collect()
}

fn small_fields<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut f = vec![
        "type: uint16",
        "dimension: 3",
        "sizes: 4 3 2",
        "spacings: 0.5 1 2",
    ];
    f.extend_from_slice(extra);
    f
}

#[test]
fn attached_and_detached_headers_agree() {
    let dir = TempDir::new("attached");
    let values = small_u16();
    let attached = dir.write(
        "a.nrrd",
        &nrrd(
            &small_fields(&["endian: little", "encoding: raw"]),
            &le_u16(&values),
        ),
    );
    dir.write("a_data.raw", &le_u16(&values));
    let detached = dir.write(
        "d.nhdr",
        &nhdr(&small_fields(&[
            "endian: little",
            "encoding: raw",
            "data file: a_data.raw",
        ])),
    );
    // `datafile` spelling, and a data file in a subfolder.
    std::fs::create_dir_all(dir.0.join("sub")).expect("mkdir");
    dir.write("sub/x.raw", &le_u16(&values));
    let detached2 = dir.write(
        "d2.nhdr",
        &nhdr(&small_fields(&[
            "endian: little",
            "encoding: raw",
            "datafile: sub/x.raw",
        ])),
    );

    let a = load(&attached).expect("attached");
    let d = load(&detached).expect("detached");
    let d2 = load_nrrd(&detached2).expect("detached, datafile spelling");
    assert_eq!(a.dims, SMALL_DIMS);
    assert_eq!(a.spacing, [0.5, 1.0, 2.0]);
    assert_eq!(u16_samples(&a), values.as_slice());
    assert_eq!(a.data, d.data);
    assert_eq!(a.data, d2.data);
    assert_eq!(a.name, "a");
    assert_eq!(d.name, "d");
    assert_eq!(a.range, [7.0, 23007.0]);
    // x fastest: voxel (1,0,0) is sample 1, (0,1,0) sample 4, (0,0,1) sample 12.
    assert_eq!(a.scalar(1, 0, 0), 1007.0);
    assert_eq!(a.scalar(0, 1, 0), 4007.0);
    assert_eq!(a.scalar(0, 0, 1), 12007.0);

    // In-memory parsing of the same attached bytes.
    let bytes = std::fs::read(&attached).expect("read");
    let m = load_nrrd_bytes("mem.nrrd", &bytes, None).expect("bytes");
    assert_eq!(m.data, a.data);
    assert_eq!(m.name, "mem");
    // A detached header in memory finds its data through base_dir.
    let header = std::fs::read(&detached).expect("read");
    let m = load_nrrd_bytes("d.nhdr", &header, Some(&dir.0)).expect("detached bytes");
    assert_eq!(m.data, a.data);
    let e = err_text(load_nrrd_bytes("d.nhdr", &header, None));
    assert!(e.contains("d.nhdr") && e.contains("base folder"), "{e}");
}

#[test]
fn gzip_matches_raw() {
    let dir = TempDir::new("gzip");
    let values = small_u16();
    let raw = dir.write(
        "r.nrrd",
        &nrrd(
            &small_fields(&["endian: little", "encoding: raw"]),
            &le_u16(&values),
        ),
    );
    let gz = dir.write(
        "g.nrrd",
        &nrrd(
            &small_fields(&["endian: little", "encoding: gzip"]),
            &gzip(&le_u16(&values)),
        ),
    );
    let gz2 = dir.write(
        "g2.nrrd",
        &nrrd(
            &small_fields(&["endian: little", "encoding: gz"]),
            &gzip(&le_u16(&values)),
        ),
    );
    dir.write("g3.raw.gz", &gzip(&le_u16(&values)));
    let gz3 = dir.write(
        "g3.nhdr",
        &nhdr(&small_fields(&[
            "endian: little",
            "encoding: gzip",
            "data file: g3.raw.gz",
        ])),
    );
    // Some writers store a zlib stream under "gzip".
    let zl = dir.write(
        "z.nrrd",
        &nrrd(
            &small_fields(&["endian: little", "encoding: gzip"]),
            &zlib(&le_u16(&values)),
        ),
    );
    let reference = load(&raw).expect("raw");
    for path in [&gz, &gz2, &gz3, &zl] {
        let v = load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(v.data, reference.data, "{}", path.display());
        assert_eq!(v.range, reference.range);
    }
}

#[test]
fn big_and_little_endian_agree() {
    let dir = TempDir::new("endian");
    let u16s: Vec<u16> = (0..24).map(|i| 0x0102 + i * 0x0301).collect();
    let f32s: Vec<f32> = (0..24).map(|i| i as f32 * -1.25 + 0.1).collect();
    let i16s: Vec<i16> = (0..24).map(|i| -3000 + i * 257).collect();
    let cases: Vec<(&str, Vec<u8>, Vec<u8>)> = vec![
        ("uint16", le_u16(&u16s), be_u16(&u16s)),
        ("float", le_f32(&f32s), be_f32(&f32s)),
        (
            "int16",
            i16s.iter().flat_map(|v| v.to_le_bytes()).collect(),
            i16s.iter().flat_map(|v| v.to_be_bytes()).collect(),
        ),
    ];
    for (ty, le, be) in cases {
        let t = format!("type: {ty}");
        let fields = |endian: &'static str, enc: &'static str| {
            vec![t.as_str(), "dimension: 3", "sizes: 4 3 2", endian, enc]
        };
        let l = dir.write(
            &format!("{ty}_le.nrrd"),
            &nrrd(&fields("endian: little", "encoding: raw"), &le),
        );
        let b = dir.write(
            &format!("{ty}_be.nrrd"),
            &nrrd(&fields("endian: big", "encoding: raw"), &be),
        );
        let bg = dir.write(
            &format!("{ty}_beg.nrrd"),
            &nrrd(&fields("endian: big", "encoding: gzip"), &gzip(&be)),
        );
        let l = load(&l).expect("little");
        let b = load(&b).expect("big");
        let bg = load(&bg).expect("big gzip");
        assert_eq!(l.data, b.data, "{ty}");
        assert_eq!(l.data, bg.data, "{ty}");
        assert_ne!(
            le, be,
            "{ty}: the test data must differ between byte orders"
        );
    }
    // And the decoded values are the originals.
    let b = load(&dir.0.join("uint16_be.nrrd")).expect("big");
    assert_eq!(u16_samples(&b), u16s.as_slice());
    let b = load(&dir.0.join("float_be.nrrd")).expect("big");
    assert_eq!(f32_samples(&b), f32s.as_slice());
}

#[test]
fn wide_types_convert_to_f32() {
    let dir = TempDir::new("wide");
    let ints: Vec<i32> = (0..8).map(|i| i * 100_000 - 300_000).collect();
    let doubles: Vec<f64> = (0..8).map(|i| f64::from(i) * 0.5 - 1.0).collect();
    let cases: Vec<(&str, &str, Vec<u8>, Vec<f32>)> = vec![
        (
            "int",
            "big",
            ints.iter().flat_map(|v| v.to_be_bytes()).collect(),
            ints.iter().map(|&v| v as f32).collect(),
        ),
        (
            "uint32_t",
            "little",
            ints.iter()
                .flat_map(|v| (v.unsigned_abs()).to_le_bytes())
                .collect(),
            ints.iter().map(|&v| v.unsigned_abs() as f32).collect(),
        ),
        (
            "double",
            "little",
            doubles.iter().flat_map(|v| v.to_le_bytes()).collect(),
            doubles.iter().map(|&v| v as f32).collect(),
        ),
        (
            "long long",
            "big",
            ints.iter()
                .flat_map(|&v| i64::from(v).to_be_bytes())
                .collect(),
            ints.iter().map(|&v| v as f32).collect(),
        ),
    ];
    for (ty, endian, bytes, expected) in cases {
        let t = format!("type: {ty}");
        let e = format!("endian: {endian}");
        let path = dir.write(
            "w.nrrd",
            &nrrd(
                &[&t, "dimension: 3", "sizes: 2 2 2", &e, "encoding: raw"],
                &bytes,
            ),
        );
        let v = load(&path).unwrap_or_else(|e| panic!("{ty}: {e}"));
        assert_eq!(v.scalar_type(), ScalarType::F32, "{ty}");
        assert_eq!(f32_samples(&v), expected.as_slice(), "{ty}");
    }
}

/// An anatomical `space` with `space directions` reorders the axes to LPS (the same
/// rule as NIfTI and DICOM); LPS with positive diagonal directions (what `vwb crop`
/// writes) and spaces without a patient side keep the stored order.
#[test]
fn anatomical_nrrd_spaces_are_reoriented_to_lps() {
    let dir = TempDir::new("nrrdspace");
    // 2×2×2 voxels, value = 4z + 2y + x
    let data: Vec<u8> = (0..8).collect();
    let load_with = |space: &str, dirs: &str| {
        let s = format!("space: {space}");
        let d = format!("space directions: {dirs}");
        let path = dir.write(
            "o.nrrd",
            &nrrd(
                &[
                    "type: uint8",
                    "dimension: 3",
                    "sizes: 2 2 2",
                    &s,
                    &d,
                    "encoding: raw",
                ],
                &data,
            ),
        );
        load(&path).unwrap()
    };
    let u8s = |v: &Volume| match &v.data {
        VoxelData::U8(x) => x.clone(),
        other => panic!("{:?}", other.scalar_type()),
    };
    // RAS with positive diagonal directions: stored x runs to the right, y anterior,
    // so both flip
    let v = load_with("right-anterior-superior", "(0.5,0,0) (0,2,0) (0,0,3)");
    assert_eq!(u8s(&v), vec![3, 2, 1, 0, 7, 6, 5, 4]);
    assert_eq!(v.spacing, [0.5, 2.0, 3.0]);
    assert!(
        v.notes.iter().any(|n| n.contains("x→−x, y→−y, z→z")),
        "{:?}",
        v.notes
    );
    // the same voxels stored as LPS: unchanged
    let v = load_with("LPS", "(0.5,0,0) (0,2,0) (0,0,3)");
    assert_eq!(u8s(&v), data);
    // LAS, axes stored (z, x, y): stored axis 0 runs superior, 1 left, 2 anterior
    let v = load_with("left-anterior-superior", "(0,0,3) (0.5,0,0) (0,2,0)");
    assert_eq!(v.spacing, [0.5, 2.0, 3.0]);
    let got = u8s(&v);
    for z in 0..2usize {
        for y in 0..2usize {
            for x in 0..2usize {
                // canonical (x, y, z) = stored (x' = z, y' = x, z' = 1 − y)
                let stored = 4 * (1 - y) + 2 * x + z;
                assert_eq!(got[4 * z + 2 * y + x], stored as u8, "at {x} {y} {z}");
            }
        }
    }
    // a space without a patient side keeps the stored order
    let v = load_with("3D-right-handed", "(0,0,3) (0.5,0,0) (0,2,0)");
    assert_eq!(u8s(&v), data);
    assert_eq!(v.spacing, [3.0, 0.5, 2.0]);
}

/// 4-dimensional NRRDs whose non-spatial axis comes last: a series (time, list) loads
/// its first volume with a note, in every encoding and with `byte skip: -1`; a vector
/// axis with 1–3 entries holds planar components, which are interleaved.
#[test]
fn four_dimensional_nrrds_with_the_extra_axis_last() {
    let dir = TempDir::new("nrrd4d");
    // three 2×2×2 volumes: volume t holds 10·t + voxel index
    let series: Vec<u8> = (0..3u8)
        .flat_map(|t| (0..8).map(move |i| 10 * t + i))
        .collect();
    let first: Vec<u8> = (0..8).collect();
    let u8s = |v: &Volume| match &v.data {
        VoxelData::U8(x) => x.clone(),
        other => panic!("{:?}", other.scalar_type()),
    };
    let base = [
        "type: uint8",
        "dimension: 4",
        "sizes: 2 2 2 3",
        "spacings: 0.5 1 2 NaN",
    ];
    for (kind, extra) in [
        ("time", vec!["encoding: raw"]),
        ("list", vec!["encoding: raw", "byte skip: -1"]),
        ("time", vec!["encoding: gzip"]),
        ("time", vec!["encoding: ascii"]),
    ] {
        let kinds = format!("kinds: domain domain domain {kind}");
        let mut fields: Vec<&str> = base.to_vec();
        fields.push(&kinds);
        fields.extend(extra.iter().copied());
        let payload = if extra[0] == "encoding: gzip" {
            let mut e = GzEncoder::new(Vec::new(), Compression::fast());
            e.write_all(&series).unwrap();
            e.finish().unwrap()
        } else if extra[0] == "encoding: ascii" {
            series
                .iter()
                .map(|v| format!("{v} "))
                .collect::<String>()
                .into_bytes()
        } else {
            // a byte skip of −1 reads the series from the end of the file
            [b"junk".as_slice(), &series].concat()
        };
        let payload = if extra.len() == 1 && extra[0] == "encoding: raw" {
            series.clone()
        } else {
            payload
        };
        let path = dir.write("s.nrrd", &nrrd(&fields, &payload));
        let v = load(&path).unwrap_or_else(|e| panic!("{extra:?}: {e}"));
        assert_eq!(v.dims, [2, 2, 2], "{extra:?}");
        assert_eq!(v.spacing, [0.5, 1.0, 2.0], "{extra:?}");
        assert_eq!(u8s(&v), first, "{extra:?}");
        assert!(
            v.notes
                .iter()
                .any(|n| n.contains("series of 3 volumes") && n.contains(kind)),
            "{:?}",
            v.notes
        );
    }
    // planar 3-vectors on the last axis: component c of voxel i is 10·c + i
    let path = dir.write(
        "v.nrrd",
        &nrrd(
            &[
                "type: uint8",
                "dimension: 4",
                "sizes: 2 2 2 3",
                "kinds: domain domain domain 3-vector",
                "space directions: (1,0,0) (0,1,0) (0,0,1) none",
                "encoding: raw",
            ],
            &series,
        ),
    );
    let v = load(&path).unwrap();
    assert_eq!(v.components, 3);
    let want: Vec<u8> = (0..8u8).flat_map(|i| [i, 10 + i, 20 + i]).collect();
    assert_eq!(u8s(&v), want);
}

#[test]
fn space_directions_give_spacing() {
    let h = header(&[
        "type: float",
        "dimension: 4",
        "sizes: 3 5 6 7",
        "space: right-anterior-superior",
        "space directions: none (0.5,0,0) (0,2,0) (0,0,3)",
        "space origin: (10,20,30)",
        "kinds: vector domain domain domain",
        "endian: little",
        "encoding: raw",
    ])
    .expect("header");
    assert_eq!(h.components, 3);
    assert_eq!(h.dims, [5, 6, 7]);
    assert_eq!(h.spacing, [0.5, 2.0, 3.0]);

    // Oblique axes: the spacing is the vector length; spaces inside parentheses.
    let h = header(&[
        "type: uchar",
        "dimension: 3",
        "sizes: 2 2 2",
        "space dimension: 3",
        "space directions: ( 3, 4, 0 ) (0,0,2.5) (-1,0,0)",
        "encoding: raw",
    ])
    .expect("header");
    assert_eq!(h.spacing, [5.0, 2.5, 1.0]);
    assert_eq!(h.components, 1);

    // space directions win over spacings, end to end.
    let dir = TempDir::new("spacedir");
    let path = dir.write(
        "s.nrrd",
        &nrrd(
            &[
                "type: uint8",
                "dimension: 3",
                "sizes: 2 1 1",
                "space directions: (0.25,0,0) (0,0.5,0) (0,0,0.75)",
                "encoding: raw",
            ],
            &[1, 2],
        ),
    );
    let v = load(&path).expect("load");
    assert_eq!(v.spacing, [0.25, 0.5, 0.75]);

    // 'none' on a spatial axis, a vector on the component axis, a bad number.
    let bad = [
        (
            "space directions: none (1,0,0) (0,1,0)",
            "dimension: 3",
            "needs a vector",
        ),
        (
            "space directions: (1,0,0) (1,0,0) (0,1,0) (0,0,1)",
            "dimension: 4",
            "must be 'none'",
        ),
        (
            "space directions: (1,0,x) (0,1,0) (0,0,1)",
            "dimension: 3",
            "not a finite number",
        ),
        (
            "space directions: (0,0,0) (0,1,0) (0,0,1)",
            "dimension: 3",
            "finite and greater than 0",
        ),
        (
            "space directions: (1,0) (0,1,0) (0,0,1)",
            "dimension: 3",
            "different lengths",
        ),
        (
            "space directions: (1,0,0) (0,1,0",
            "dimension: 3",
            "missing ')'",
        ),
    ];
    for (field, dim, cause) in bad {
        let sizes = if dim.ends_with('4') {
            "sizes: 3 2 2 2"
        } else {
            "sizes: 2 2 2"
        };
        let e = err_text(header(&["type: uint8", dim, sizes, field, "encoding: raw"]));
        assert!(
            e.contains("t.nhdr: header line 5: space directions") && e.contains(cause),
            "{e}"
        );
    }
}

#[test]
fn byte_skip_and_line_skip() {
    let dir = TempDir::new("skip");
    let values = small_u16();
    let data = le_u16(&values);

    // Detached file with a 13-byte foreign header.
    let mut junk = b"JUNK-HEADER!!".to_vec();
    junk.extend_from_slice(&data);
    dir.write("skip.raw", &junk);
    let a = load(&dir.write(
        "a.nhdr",
        &nhdr(&small_fields(&[
            "endian: little",
            "encoding: raw",
            "byte skip: 13",
            "data file: skip.raw",
        ])),
    ))
    .expect("byte skip 13");
    assert_eq!(u16_samples(&a), values.as_slice());

    // byte skip -1: the data is the end of the file.
    let b = load(&dir.write(
        "b.nhdr",
        &nhdr(&small_fields(&[
            "endian: little",
            "encoding: raw",
            "byte skip: -1",
            "data file: skip.raw",
        ])),
    ))
    .expect("byte skip -1");
    assert_eq!(b.data, a.data);

    // Attached data with byte skip -1 and trailing-free layout.
    let c = load(&dir.write(
        "c.nrrd",
        &nrrd(
            &small_fields(&["endian: little", "encoding: raw", "byteskip: -1"]),
            &junk,
        ),
    ))
    .expect("attached, byte skip -1");
    assert_eq!(c.data, a.data);

    // line skip: two text lines, then 4 bytes, then the data.
    let mut lined = b"first line\nsecond line\nXXXX".to_vec();
    lined.extend_from_slice(&data);
    dir.write("lines.raw", &lined);
    let d = load(&dir.write(
        "d.nhdr",
        &nhdr(&small_fields(&[
            "endian: little",
            "encoding: raw",
            "line skip: 2",
            "byte skip: 4",
            "data file: lines.raw",
        ])),
    ))
    .expect("line skip");
    assert_eq!(d.data, a.data);

    // gzip: line skip applies to the file, byte skip to the decompressed data.
    let mut gz = b"a text line\n".to_vec();
    gz.extend_from_slice(&gzip(&junk));
    dir.write("g.raw.gz", &gz);
    let g = load(&dir.write(
        "g.nhdr",
        &nhdr(&small_fields(&[
            "endian: little",
            "encoding: gzip",
            "lineskip: 1",
            "byte skip: 13",
            "data file: g.raw.gz",
        ])),
    ))
    .expect("gzip skips");
    assert_eq!(g.data, a.data);

    // A byte skip beyond the data is a size error naming the data file.
    let path = dir.write(
        "e.nhdr",
        &nhdr(&small_fields(&[
            "endian: little",
            "encoding: raw",
            "byte skip: 14",
            "data file: skip.raw",
        ])),
    );
    assert_err(
        load(&path),
        &dir.0.join("skip.raw"),
        &[
            "file has 61 bytes but the header needs 48 (4x3x2 uint16) after skipping the first 14 bytes",
        ],
    );
    // More lines to skip than the file has.
    let path = dir.write(
        "f.nhdr",
        &nhdr(&small_fields(&[
            "endian: little",
            "encoding: raw",
            "line skip: 9",
            "data file: lines.raw",
        ])),
    );
    assert_err(
        load(&path),
        &dir.0.join("lines.raw"),
        &["line skip of 9 runs past the end of the file"],
    );
}

#[test]
fn load_raw_plain_files() {
    let dir = TempDir::new("raw");
    // uint8 scalar.
    let bytes: Vec<u8> = (0..24).collect();
    let path = dir.write("u8.raw", &bytes);
    let v = load_raw(&path, &RawDesc::new(SMALL_DIMS, ScalarType::U8)).expect("u8");
    assert_eq!(v.data, VoxelData::U8(bytes.clone()));
    assert_eq!(v.name, "u8");
    assert_eq!(v.range, [0.0, 23.0]);
    assert_eq!(v.source.as_deref(), Some(path.as_path()));

    // int8 with a 5-byte header.
    let mut with_header = vec![0xAAu8; 5];
    with_header.extend((0..24).map(|i: i8| (i - 12) as u8));
    let path = dir.write("i8.raw", &with_header);
    let desc = RawDesc {
        header_bytes: 5,
        ..RawDesc::new(SMALL_DIMS, ScalarType::I8)
    };
    let v = load_raw(&path, &desc).expect("i8");
    assert_eq!(v.range, [-12.0, 11.0]);

    // Big-endian float 3-vectors with spacing.
    let f: Vec<f32> = (0..72).map(|i| i as f32 / 4.0).collect();
    let path = dir.write("v.raw", &be_f32(&f));
    let desc = RawDesc {
        dims: SMALL_DIMS,
        components: 3,
        scalar: ScalarType::F32,
        endian: Endian::Big,
        spacing: [0.1, 0.2, 0.3],
        header_bytes: 0,
    };
    let v = load_raw(&path, &desc).expect("f32 x3");
    assert_eq!(f32_samples(&v), f.as_slice());
    assert_eq!(v.components, 3);
    assert_eq!(v.spacing, [0.1, 0.2, 0.3]);
    assert_close(
        v.scalar(1, 0, 0),
        (0.75f64 * 0.75 + 1.0 + 1.25 * 1.25).sqrt(),
        "magnitude",
    );

    // Wrong sizes both ways, bad spacing, zero dims, missing file.
    let short = RawDesc::new([4, 3, 3], ScalarType::U8);
    assert_err(
        load_raw(&dir.0.join("u8.raw"), &short),
        Path::new("u8.raw"),
        &["file has 24 bytes but the raw description needs 36 (4x3x3 uint8)"],
    );
    let long = RawDesc::new([4, 3, 1], ScalarType::U8);
    assert_err(
        load_raw(&dir.0.join("u8.raw"), &long),
        Path::new("u8.raw"),
        &["file has 24 bytes but the raw description needs 12 (4x3x1 uint8)"],
    )
    .file()
    .expect("names a file");
    let bad_spacing = RawDesc {
        spacing: [1.0, 0.0, 1.0],
        ..RawDesc::new(SMALL_DIMS, ScalarType::U8)
    };
    assert_err(
        load_raw(&dir.0.join("u8.raw"), &bad_spacing),
        Path::new("u8.raw"),
        &["spacing"],
    );
    let zero = RawDesc::new([4, 0, 2], ScalarType::U8);
    assert_err(
        load_raw(&dir.0.join("u8.raw"), &zero),
        Path::new("u8.raw"),
        &["4x0x2", "at least 1"],
    );
    let four = RawDesc {
        components: 4,
        ..RawDesc::new([1, 1, 6], ScalarType::U8)
    };
    assert_err(
        load_raw(&dir.0.join("u8.raw"), &four),
        Path::new("u8.raw"),
        &["4 components"],
    );
    assert_err(
        load_raw(
            &dir.0.join("missing.raw"),
            &RawDesc::new(SMALL_DIMS, ScalarType::U8),
        ),
        Path::new("missing.raw"),
        &["cannot open"],
    );
    let huge = RawDesc::new([100_000, 100_000, 100_000], ScalarType::U8);
    assert_err(
        load_raw(&dir.0.join("u8.raw"), &huge),
        Path::new("u8.raw"),
        &["dims 100000x100000x100000", "limit"],
    );
}

#[test]
fn load_refuses_headerless_files() {
    let dir = TempDir::new("sniff");
    let path = dir.write("plain.raw", &[1, 2, 3, 4, 5, 6, 7, 8, 9]);
    let e = assert_err(
        load(&path),
        &path,
        &["not an NRRD file", "detached NRRD header"],
    );
    assert!(matches!(e, VolumeError::NotNrrd { .. }));
    let empty = dir.write("empty.nrrd", b"");
    assert_err(load(&empty), &empty, &["not an NRRD file"]);
    assert_err(load_nrrd(&empty), &empty, &["not an NRRD file"]);
    let shared_raw = shared("mri_head_volpack_128x128x84_uint8.raw");
    assert_err(load(&shared_raw), &shared_raw, &[".nhdr"]);
    assert_err(
        load(&dir.0.join("nope.nrrd")),
        Path::new("nope.nrrd"),
        &["cannot open"],
    );
}

#[test]
fn all_type_spellings_parse() {
    let cases: &[(&[&str], NrrdType)] = &[
        (&["signed char", "int8", "int8_t"], NrrdType::Int8),
        (
            &["uchar", "unsigned char", "uint8", "uint8_t", "UCHAR"],
            NrrdType::UInt8,
        ),
        (
            &[
                "short",
                "short int",
                "signed short",
                "signed short int",
                "int16",
                "int16_t",
            ],
            NrrdType::Int16,
        ),
        (
            &[
                "ushort",
                "unsigned short",
                "unsigned  short int",
                "uint16",
                "uint16_t",
            ],
            NrrdType::UInt16,
        ),
        (&["int", "signed int", "int32", "int32_t"], NrrdType::Int32),
        (
            &["uint", "unsigned int", "uint32", "uint32_t"],
            NrrdType::UInt32,
        ),
        (
            &[
                "longlong",
                "long long",
                "long long int",
                "signed long long",
                "int64",
            ],
            NrrdType::Int64,
        ),
        (
            &[
                "ulonglong",
                "unsigned long long",
                "unsigned long long int",
                "uint64_t",
            ],
            NrrdType::UInt64,
        ),
        (&["float"], NrrdType::Float),
        (&["double"], NrrdType::Double),
    ];
    for (names, ty) in cases {
        for name in *names {
            assert_eq!(NrrdType::parse(name), Some(*ty), "{name}");
            let t = format!("type: {name}");
            let h = header(&[
                &t,
                "dimension: 3",
                "sizes: 1 2 3",
                "endian: big",
                "encoding: raw",
            ])
            .unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(h.data_type, *ty);
            assert_eq!(h.endian, Endian::Big);
            assert_eq!(h.dims, [1, 2, 3]);
        }
    }
    assert_eq!(NrrdType::parse("int128"), None);
    assert_eq!(NrrdType::parse("block"), None);
    assert_eq!(NrrdType::Double.scalar_type(), ScalarType::F32);
    assert_eq!(NrrdType::from(ScalarType::I16), NrrdType::Int16);
}

#[test]
fn header_details() {
    let h = header(&[
        "# a comment",
        "type: short",
        "dimension: 4",
        "sizes: 2 8 9 10",
        "spacings: nan 1.5 2 2.5",
        "kinds: covariant-vector domain space ???",
        "endian: big",
        "encoding: gzip",
        "content: some text",
        "units: mm mm mm mm",
        "spacing: 9 9 9 9",
        "my key:=some: value",
        "line skip: 3",
        "byte skip: 7",
        "data file: ./sub dir/file name.raw.gz",
        "",
        "ignored after the blank line: 5",
    ])
    .expect("header");
    assert_eq!(h.version, 5);
    assert_eq!(h.data_type, NrrdType::Int16);
    assert_eq!(h.components, 2);
    assert_eq!(h.dims, [8, 9, 10]);
    assert_eq!(h.spacing, [1.5, 2.0, 2.5]);
    assert_eq!(h.endian, Endian::Big);
    assert_eq!(h.encoding, NrrdEncoding::Gzip);
    assert_eq!(h.line_skip, 3);
    assert_eq!(h.byte_skip, ByteSkip::Bytes(7));
    assert_eq!(
        h.data_file.as_deref(),
        Some(Path::new("./sub dir/file name.raw.gz"))
    );
    assert_eq!(h.unknown_fields, vec!["spacing".to_owned()]);
    assert_eq!(h.value_count(), 2 * 8 * 9 * 10);
    assert_eq!(h.data_bytes(), 2 * 2 * 8 * 9 * 10);

    // Every NRRD version 1..5 and CRLF line ends.
    for version in 1..=5 {
        let text = format!(
            "NRRD000{version}\r\ntype: uint8\r\ndimension: 3\r\nsizes: 1 1 1\r\nencoding: raw\r\n"
        );
        let h = parse_nrrd_header(&text, None).expect("version");
        assert_eq!(h.version, version);
        assert_eq!(h.spacing, [1.0; 3]);
        assert_eq!(h.endian, Endian::Little, "1-byte types need no endian");
    }
    // A 4-dimensional NRRD without kinds: the first axis holds the components.
    let h = header(&[
        "type: float",
        "dimension: 4",
        "sizes: 3 4 5 6",
        "endian: little",
        "encoding: raw",
    ])
    .expect("vector without kinds");
    assert_eq!((h.components, h.dims), (3, [4, 5, 6]));
}

// ---------------------------------------------------------------- bad input

/// Header fields of a valid 4x3x2 uint16 attached NRRD, with one replaced or removed.
fn fields_with(replace: &str, with: Option<&str>) -> Vec<String> {
    let base = [
        "type: uint16",
        "dimension: 3",
        "sizes: 4 3 2",
        "endian: little",
        "encoding: raw",
    ];
    let key = replace.split(':').next().unwrap_or(replace);
    let mut out: Vec<String> = Vec::new();
    let mut replaced = false;
    for f in base {
        if f.starts_with(key) {
            replaced = true;
            if let Some(w) = with {
                out.push(w.to_owned());
            }
        } else {
            out.push(f.to_owned());
        }
    }
    if !replaced && let Some(w) = with {
        out.push(w.to_owned());
    }
    out
}

#[test]
fn malformed_headers_give_clear_errors() {
    let dir = TempDir::new("badheader");
    let data = le_u16(&small_u16());
    let cases: &[(&str, Option<&str>, &[&str])] = &[
        (
            "type",
            Some("type: int128"),
            &["header line 2: unknown type 'int128'"],
        ),
        (
            "type",
            Some("type: block"),
            &["type 'block' is not supported"],
        ),
        ("type", None, &["missing required field 'type'"]),
        ("dimension", None, &["missing required field 'dimension'"]),
        ("sizes", None, &["missing required field 'sizes'"]),
        ("encoding", None, &["missing required field 'encoding'"]),
        (
            "endian",
            None,
            &["missing required field 'endian'", "uint16"],
        ),
        ("sizes", Some("sizes: 4 0 2"), &["sizes: axis 1 has size 0"]),
        (
            "sizes",
            Some("sizes: 4 abc 2"),
            &["'abc'", "not a whole number"],
        ),
        ("sizes", Some("sizes: 4 -3 2"), &["'-3'"]),
        (
            "sizes",
            Some("sizes: 4 3"),
            &["sizes: 2 values given but the dimension is 3"],
        ),
        (
            "dimension",
            Some("dimension: 2"),
            &["dimension 2 is not supported"],
        ),
        (
            "dimension",
            Some("dimension: 5"),
            &["dimension 5 is not supported"],
        ),
        (
            "dimension",
            Some("dimension: three"),
            &["dimension 'three'"],
        ),
        (
            "encoding",
            Some("encoding: zstd"),
            &["unknown encoding 'zstd'"],
        ),
        (
            "endian",
            Some("endian: middle"),
            &["unknown endian 'middle'"],
        ),
        (
            "spacings",
            Some("spacings: 1 0 1"),
            &["spacings: axis 1 has spacing 0"],
        ),
        (
            "spacings",
            Some("spacings: 1 1 -2"),
            &["axis 2 has spacing -2"],
        ),
        (
            "spacings",
            Some("spacings: nan 1 1"),
            &["axis 0 has spacing NaN"],
        ),
        (
            "spacings",
            Some("spacings: 1 inf 1"),
            &["axis 1 has spacing inf"],
        ),
        (
            "spacings",
            Some("spacings: 1 x 1"),
            &["'x' (axis 1) is not a number"],
        ),
        (
            "spacings",
            Some("spacings: 1 1"),
            &["spacings: 2 values given"],
        ),
        (
            "kinds",
            Some("kinds: domain vector domain"),
            &["kinds: axis 1 is 'vector'"],
        ),
        ("byte skip", Some("byte skip: -5"), &["byte skip '-5'"]),
        ("line skip", Some("line skip: -1"), &["line skip '-1'"]),
        (
            "data file",
            Some("data file: LIST"),
            &["LIST", "not supported"],
        ),
        (
            "data file",
            Some("data file: LIST 2"),
            &["LIST", "not supported"],
        ),
        (
            "data file",
            Some("data file: slice%03d.raw 1 10 1"),
            &["formatted file lists"],
        ),
        (
            "data file",
            Some("data file: missing.raw"),
            &["missing.raw", "cannot open the data file"],
        ),
        (
            "sizes",
            Some("sizes: 4294967295 4294967295 4294967295"),
            &["dims 4294967295x4294967295x4294967295", "overflow"],
        ),
        (
            "sizes",
            Some("sizes: 100000 100000 100000"),
            &["dims 100000x100000x100000", "limit of 2147483648 voxels"],
        ),
        (
            "sizes",
            Some("sizes: 99999999999999999999 1 1"),
            &["not a whole number"],
        ),
        ("sizes", Some("sizes: 4 3 2 "), &[]), // trailing space is fine: checked below
        (
            "garbage",
            Some("this line has no colon"),
            &["expected 'field: value'"],
        ),
        (
            "type",
            Some("type: uint16\ntype: uint8"),
            &["duplicate field 'type'"],
        ),
    ];
    for (i, (field, with, fragments)) in cases.iter().enumerate() {
        let fields = fields_with(field, *with);
        let refs: Vec<&str> = fields.iter().map(String::as_str).collect();
        let path = dir.write(&format!("bad{i}.nrrd"), &nrrd(&refs, &data));
        let r = load(&path);
        if fragments.is_empty() {
            assert!(r.is_ok(), "{with:?}: {r:?}");
            continue;
        }
        let e = r.expect_err(&format!("{with:?} should fail"));
        let msg = e.to_string();
        // The data file error names the data file; all others the header.
        let named = if msg.contains("missing.raw") {
            "missing.raw"
        } else {
            &*format!("bad{i}.nrrd")
        };
        assert!(
            msg.contains(named),
            "{with:?}: '{msg}' does not name {named}"
        );
        for f in *fragments {
            assert!(msg.contains(f), "{with:?}: '{msg}' does not contain '{f}'");
        }
    }

    // Vector-axis problems.
    let four = [
        "type: float",
        "dimension: 4",
        "sizes: 4 2 2 2",
        "endian: little",
        "encoding: raw",
    ];
    assert!(err_text(header(&four)).contains("4 components"));
    let middle = [
        "type: float",
        "dimension: 4",
        "sizes: 2 3 2 2",
        "kinds: domain list domain domain",
        "endian: little",
        "encoding: raw",
    ];
    assert!(err_text(header(&middle)).contains("axis 1 is 'list'"));
    let all_spatial = [
        "type: float",
        "dimension: 4",
        "sizes: 2 2 2 2",
        "kinds: domain domain domain space",
        "endian: little",
        "encoding: raw",
    ];
    assert!(err_text(header(&all_spatial)).contains("all four axes are spatial"));
    let gz_end = [
        "type: uint8",
        "dimension: 3",
        "sizes: 1 1 1",
        "encoding: gzip",
        "byte skip: -1",
    ];
    assert!(err_text(header(&gz_end)).contains("only allowed with raw encoding"));
}

#[test]
fn bad_magic_and_header_framing() {
    let dir = TempDir::new("magic");
    let e = err_text(parse_nrrd_header(
        "NRRD0009\ntype: uint8\n",
        Some(Path::new("v.nrrd")),
    ));
    assert!(
        e.starts_with("v.nrrd: header line 1: unsupported NRRD version 'NRRD0009'"),
        "{e}"
    );
    let e = err_text(parse_nrrd_header("PNG\n", None));
    assert!(e.contains("not an NRRD header"), "{e}");

    let path = dir.write("v9.nrrd", b"NRRD0009\ntype: uint8\n\n\x01");
    assert_err(load(&path), &path, &["unsupported NRRD version"]);

    // No data file and no blank line: nothing says where attached data starts.
    let path = dir.write(
        "noblank.nrrd",
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n",
    );
    assert_err(load(&path), &path, &["no 'data file' field"]);

    // A header that never ends is not read past 1 MiB.
    let mut endless = b"NRRD0004\n# ".to_vec();
    endless.extend(std::iter::repeat_n(b'x', 1_200_000));
    let path = dir.write("endless.nrrd", &endless);
    assert_err(load(&path), &path, &["no end of header"]);
}

#[test]
fn short_and_lying_data_give_clear_errors() {
    let dir = TempDir::new("baddata");
    let values = small_u16();
    let data = le_u16(&values);
    let fields = |enc: &'static str| small_fields(&["endian: little", enc]);

    // Attached raw data cut short.
    let path = dir.write("trunc.nrrd", &nrrd(&fields("encoding: raw"), &data[..30]));
    let e = assert_err(
        load(&path),
        &path,
        &[
            "but the header needs 48 (4x3x2 uint16)",
            "after skipping the first",
        ],
    );
    assert!(matches!(e, VolumeError::DataSize { needed: 48, .. }));

    // Detached header claiming more than its data file holds.
    dir.write("small.raw", &data);
    let path = dir.write(
        "liar.nhdr",
        &nhdr(&[
            "type: int16",
            "dimension: 3",
            "sizes: 256 256 108",
            "endian: little",
            "encoding: raw",
            "data file: small.raw",
        ]),
    );
    let e = assert_err(
        load(&path),
        Path::new("small.raw"),
        &["small.raw: file has 48 bytes but the header needs 14155776 (256x256x108 int16)"],
    );
    assert_eq!(e.file(), Some(dir.0.join("small.raw").as_path()));

    // Raw data with trailing bytes is accepted (the header is authoritative).
    let mut longer = data.clone();
    longer.extend_from_slice(b"trailer");
    let path = dir.write("trailing.nrrd", &nrrd(&fields("encoding: raw"), &longer));
    assert_eq!(
        u16_samples(&load(&path).expect("trailing bytes")),
        values.as_slice()
    );

    // gzip: too short, too long, corrupt, not gzip, empty, impossible ratio.
    let path = dir.write(
        "gshort.nrrd",
        &nrrd(&fields("encoding: gzip"), &gzip(&data[..20])),
    );
    assert_err(
        load(&path),
        &path,
        &["gzip data ends after 20 bytes but the header needs 48"],
    );
    let path = dir.write(
        "glong.nrrd",
        &nrrd(&fields("encoding: gzip"), &gzip(&longer)),
    );
    assert_err(load(&path), &path, &["intact", "more than the 48 bytes"]);
    // a longer stream whose checksum fails is corrupt, not a header mistake
    let mut long_bad = gzip(&longer);
    let n = long_bad.len();
    long_bad[n - 6] ^= 0xFF; // the CRC-32 of the trailer
    let path = dir.write("glongbad.nrrd", &nrrd(&fields("encoding: gzip"), &long_bad));
    let e = assert_err(load(&path), &path, &["gzip data is corrupt"]);
    assert!(!e.to_string().contains("header"), "{e}");
    let mut corrupt = gzip(&data);
    let mid = corrupt.len() / 2;
    corrupt[mid..].iter_mut().for_each(|b| *b ^= 0x5A);
    let path = dir.write("gcorrupt.nrrd", &nrrd(&fields("encoding: gzip"), &corrupt));
    let e = assert_err(load(&path), &path, &[]);
    assert!(matches!(e, VolumeError::Compressed { .. }), "{e}");
    let truncated = gzip(&data);
    let path = dir.write(
        "gcut.nrrd",
        &nrrd(
            &fields("encoding: gzip"),
            &truncated[..truncated.len() - 12],
        ),
    );
    let e = assert_err(load(&path), &path, &[]);
    assert!(matches!(e, VolumeError::Compressed { .. }), "{e}");
    let path = dir.write("gnot.nrrd", &nrrd(&fields("encoding: gzip"), &data));
    assert_err(load(&path), &path, &["does not start with a gzip header"]);
    let path = dir.write("gempty.nrrd", &nrrd(&fields("encoding: gzip"), &[]));
    assert_err(load(&path), &path, &["no data after the header"]);
    let path = dir.write(
        "gbomb.nrrd",
        &nrrd(
            &[
                "type: float",
                "dimension: 3",
                "sizes: 1024 1024 1024",
                "endian: little",
                "encoding: gzip",
            ],
            &gzip(&[0; 64]),
        ),
    );
    assert_err(load(&path), &path, &["cannot decompress to that much"]);
    // A huge raw claim on a small file fails on the length check, before allocating.
    let path = dir.write(
        "rbomb.nrrd",
        &nrrd(
            &[
                "type: float",
                "dimension: 4",
                "sizes: 3 1024 1024 512",
                "endian: little",
                "encoding: raw",
            ],
            &data,
        ),
    );
    assert_err(
        load(&path),
        &path,
        &["but the header needs 6442450944 (1024x1024x512 x3 float)"],
    );
    let path = dir.write(
        "toobig.nrrd",
        &nrrd(
            &[
                "type: double",
                "dimension: 4",
                "sizes: 3 2048 1024 1024",
                "endian: little",
                "encoding: raw",
            ],
            &data,
        ),
    );
    let e = assert_err(load(&path), &path, &["dims 2048x1024x1024", "16 GiB"]);
    assert!(matches!(e, VolumeError::TooLarge { .. }));
}

/// Truncations and bit flips of valid files must give errors or volumes, never panics.
#[test]
fn damaged_files_never_panic() {
    let dir = TempDir::new("fuzz");
    let values = small_u16();
    let raw = nrrd(
        &small_fields(&["endian: little", "encoding: raw"]),
        &le_u16(&values),
    );
    let gz = nrrd(
        &small_fields(&["endian: big", "encoding: gzip"]),
        &gzip(&be_u16(&values)),
    );
    let mut rng = crate::rng::XorShift(0x9E37_79B9_7F4A_7C15);
    let mut next = move || rng.next_u64();
    let mut outcomes = [0usize; 2];
    for original in [&raw, &gz] {
        for cut in 0..original.len() {
            let path = dir.write("cut.nrrd", &original[..cut]);
            outcomes[usize::from(load(&path).is_ok())] += 1;
        }
        for _ in 0..300 {
            let mut damaged = original.clone();
            for _ in 0..1 + next() % 4 {
                let i = (next() % damaged.len() as u64) as usize;
                damaged[i] = (next() & 0xFF) as u8;
            }
            let r = load_nrrd_bytes("damaged.nrrd", &damaged, None);
            outcomes[usize::from(r.is_ok())] += 1;
        }
    }
    // Every truncation of a file cut before its last byte fails.
    assert!(outcomes[0] >= raw.len() + gz.len() - 2, "{outcomes:?}");
}

// ---------------------------------------------------------------- statistics

#[test]
fn range_histogram_and_normalization_by_hand() {
    let v = Volume::new(
        "tiny",
        [2, 2, 2],
        1,
        [1.0; 3],
        VoxelData::U8((0..8).map(|i| i * 10).collect()),
    )
    .expect("tiny volume");
    assert_eq!(v.range, [0.0, 70.0]);
    assert_eq!(v.non_finite, 0);
    // bin = floor((s - 0) / 70 * 256), the maximum in the last bin.
    let mut expected = vec![0u64; HISTOGRAM_BINS];
    for bin in [0, 36, 73, 109, 146, 182, 219, 255] {
        expected[bin] += 1;
    }
    assert_eq!(v.histogram, expected);
    let n = v.normalized_scalars();
    for (i, s) in n.iter().enumerate() {
        assert!((f64::from(*s) - i as f64 / 7.0).abs() < 1e-6, "{i}: {s}");
    }
    assert_eq!(v.scalar(1, 0, 0), 10.0);
    assert_eq!(v.scalar(0, 1, 0), 20.0);
    assert_eq!(v.scalar(1, 1, 1), 70.0);
    assert_eq!(v.try_scalar(2, 0, 0), None);
    assert_eq!(v.voxel_count(), 8);
    assert_eq!(v.size_bytes(), 8);
    assert_eq!(
        v.components_f32(),
        (0..8).map(|i| i as f32 * 10.0).collect::<Vec<_>>()
    );

    // Signed values and a degenerate range.
    let v = Volume::new(
        "neg",
        [3, 1, 1],
        1,
        [1.0; 3],
        VoxelData::I16(vec![-300, 0, 100]),
    )
    .expect("i16");
    assert_eq!(v.range, [-300.0, 100.0]);
    assert_eq!(v.histogram[0], 1);
    assert_eq!(v.histogram[192], 1); // (0 + 300) / 400 * 256
    assert_eq!(v.histogram[255], 1);
    let flat =
        Volume::new("flat", [2, 2, 1], 1, [2.0; 3], VoxelData::U16(vec![5; 4])).expect("flat");
    assert_eq!(flat.range, [5.0, 5.0]);
    assert_eq!(flat.histogram[0], 4);
    assert_eq!(flat.normalized_scalars(), vec![0.0; 4]);
    assert_eq!(flat.size_bytes(), 8);

    // Vectors use the magnitude.
    let vec2 = Volume::new(
        "vec",
        [2, 1, 1],
        2,
        [1.0; 3],
        VoxelData::F32(vec![3.0, -4.0, 0.0, 1.0]),
    )
    .expect("vectors");
    assert_eq!(vec2.range, [1.0, 5.0]);
    assert_eq!(vec2.scalar(0, 0, 0), 5.0);
    assert_eq!(vec2.normalized_scalars(), vec![1.0, 0.0]);
    assert_eq!(vec2.components_f32(), vec![3.0, -4.0, 0.0, 1.0]);
}

#[test]
fn non_finite_floats_are_excluded_and_counted() {
    let data = vec![
        1.0,
        f32::NAN,
        3.0,
        f32::INFINITY,
        f32::NEG_INFINITY,
        2.0,
        0.0,
        f32::NAN,
    ];
    let v = Volume::new("nan", [2, 2, 2], 1, [1.0; 3], VoxelData::F32(data)).expect("volume");
    assert_eq!(v.range, [0.0, 3.0]);
    assert_eq!(v.non_finite, 4);
    assert_eq!(v.histogram.iter().sum::<u64>(), 4);
    assert!(v.scalar(1, 0, 0).is_nan());
    let n = v.normalized_scalars();
    assert!(n.iter().all(|s| s.is_finite() && (0.0..=1.0).contains(s)));
    let third = 1.0 / 3.0;
    let expected = [third, 0.0, 1.0, 1.0, 0.0, 2.0 * third, 0.0, 0.0];
    for (got, want) in n.iter().zip(expected) {
        assert!((f64::from(*got) - want).abs() < 1e-6, "{n:?}");
    }
    assert_eq!(
        v.components_f32(),
        vec![1.0, 0.0, 3.0, 0.0, 0.0, 2.0, 0.0, 0.0]
    );

    // A NaN component makes the vector's magnitude NaN.
    let v = Volume::new(
        "vnan",
        [2, 1, 1],
        2,
        [1.0; 3],
        VoxelData::F32(vec![f32::NAN, 1.0, 6.0, 8.0]),
    )
    .expect("vector volume");
    assert_eq!((v.range, v.non_finite), ([10.0, 10.0], 1));

    // Nothing finite at all.
    let v = Volume::new(
        "allnan",
        [2, 1, 1],
        1,
        [1.0; 3],
        VoxelData::F32(vec![f32::NAN, f32::INFINITY]),
    )
    .expect("volume");
    assert_eq!(v.range, [0.0, 0.0]);
    assert_eq!(v.non_finite, 2);
    assert!(v.histogram.iter().all(|&c| c == 0));
    assert_eq!(v.normalized_scalars(), vec![0.0, 1.0]);

    // Through a file too: NaN and Inf survive loading.
    let dir = TempDir::new("nanfile");
    let path = dir.write(
        "n.nrrd",
        &nrrd(
            &[
                "type: float",
                "dimension: 3",
                "sizes: 2 1 1",
                "endian: big",
                "encoding: raw",
            ],
            &be_f32(&[f32::NAN, -2.5]),
        ),
    );
    let v = load(&path).expect("load");
    assert_eq!((v.range, v.non_finite), ([-2.5, -2.5], 1));
}

#[test]
fn volume_new_validates_its_parts() {
    let e = err_text(Volume::new(
        "v",
        [2, 2, 2],
        1,
        [1.0; 3],
        VoxelData::U8(vec![0; 7]),
    ));
    assert!(
        e.contains("volume 'v'") && e.contains("7 samples") && e.contains("needs 8"),
        "{e}"
    );
    let e = err_text(Volume::new(
        "v",
        [2, 2, 2],
        4,
        [1.0; 3],
        VoxelData::U8(vec![0; 32]),
    ));
    assert!(e.contains("4 components"), "{e}");
    let e = err_text(Volume::new(
        "v",
        [0, 2, 2],
        1,
        [1.0; 3],
        VoxelData::U8(vec![]),
    ));
    assert!(e.contains("0x2x2"), "{e}");
    let e = err_text(Volume::new(
        "v",
        [1, 1, 1],
        1,
        [1.0, f64::NAN, 1.0],
        VoxelData::U8(vec![0]),
    ));
    assert!(e.contains("spacing"), "{e}");
    let e = err_text(Volume::new(
        "v",
        [u32::MAX; 3],
        1,
        [1.0; 3],
        VoxelData::U8(vec![]),
    ));
    assert!(e.contains("dims 4294967295x4294967295x4294967295"), "{e}");
    assert!(Volume::new("v", [1, 1, 1], 1, [1.0; 3], VoxelData::U8(vec![0])).is_ok());
}

#[test]
fn public_types_have_their_traits() {
    fn serde_roundtrip<T: serde::Serialize + for<'de> serde::Deserialize<'de>>() {}
    serde_roundtrip::<ScalarType>();
    serde_roundtrip::<Endian>();
    serde_roundtrip::<RawDesc>();
    let sizes: Vec<usize> = [
        ScalarType::U8,
        ScalarType::I8,
        ScalarType::U16,
        ScalarType::I16,
        ScalarType::F32,
    ]
    .iter()
    .map(|t| t.size_bytes())
    .collect();
    assert_eq!(sizes, [1, 1, 2, 2, 4]);
    assert_eq!(ScalarType::I16.name(), "int16");
    assert_eq!(ScalarType::F32.to_string(), "float32");
    assert_eq!(
        format!("{:?}", VoxelData::U8(vec![0; 5])),
        "VoxelData::U8([..; 5])"
    );
    fn send_sync<T: Send + Sync>() {}
    send_sync::<Volume>();
    send_sync::<VolumeError>();
}

#[test]
fn progress_is_reported_and_cancel_stops_the_load() {
    use std::sync::Arc;
    use std::sync::atomic::Ordering::Relaxed;
    let dir = TempDir::new("progress");
    let fields = [
        "type: uint16",
        "dimension: 3",
        "sizes: 64 64 40",
        "endian: little",
        "encoding: raw",
    ];
    let path = dir.write("p.nrrd", &nrrd(&fields, &vec![3u8; 64 * 64 * 40 * 2]));
    let progress = Arc::new(LoadProgress::default());
    let v = load_with_progress(&path, progress.clone()).unwrap();
    assert_eq!(v.dims, [64, 64, 40]);
    // reported before each chunk: the last report is the start of the last chunk
    assert_eq!(progress.total.load(Relaxed), 64 * 64 * 40 * 2);
    assert!(progress.done.load(Relaxed) > 0 && progress.fraction() > 0.5);
    let cancelled = Arc::new(LoadProgress::default());
    cancelled.cancel.store(true, Relaxed);
    let e = load_with_progress(&path, cancelled).unwrap_err();
    assert!(e.to_string().contains("cancelled"), "{e}");
    // without a progress object, loads on this thread are not affected
    assert!(load(&path).is_ok());
}

/// The ascii, bzip2 and hex encodings (Teem reads all three): the same samples load the
/// same, and bad text names the sample or the digit.
#[test]
fn ascii_bzip2_and_hex_encodings() {
    use std::io::Write;
    let d = std::env::temp_dir().join(format!("vwb-enc-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let head = |enc: &str| {
        format!(
            "NRRD0004\ntype: short\ndimension: 3\nsizes: 3 2 2\nendian: little\nencoding: {enc}\n\n"
        )
    };
    let values: Vec<i16> = (0..12).map(|i| i * 100 - 300).collect();
    let text: String = values.iter().map(|v| format!("{v}\n")).collect();
    let a = d.join("a.nrrd");
    std::fs::write(&a, format!("{}{text}", head("ascii"))).unwrap();
    let va = super::load(&a).unwrap();
    assert_eq!(va.data, VoxelData::I16(values.clone()));
    let raw: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let mut enc = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::best());
    enc.write_all(&raw).unwrap();
    let b = d.join("b.nrrd");
    std::fs::write(
        &b,
        [head("bzip2").into_bytes(), enc.finish().unwrap()].concat(),
    )
    .unwrap();
    assert_eq!(super::load(&b).unwrap().data, va.data);
    for (body, expect) in [
        ("1 2 3", "cannot hold the 12 samples"),
        (
            "1 2 3                                   ",
            "holds 3 samples but the header needs 12",
        ),
        ("1 2 x 4 5 6 7 8 9 10 11 12", "sample 3 ('x')"),
        ("1 2 3 4 5 6 7 8 9 10 11 70000", "70000 does not fit"),
    ] {
        std::fs::write(&a, format!("{}{body}", head("ascii"))).unwrap();
        let e = super::load(&a).unwrap_err().to_string();
        assert!(e.contains("a.nrrd") && e.contains(expect), "{e}");
    }
    std::fs::write(
        &b,
        [head("bzip2").into_bytes(), b"BZh9 not really".to_vec()].concat(),
    )
    .unwrap();
    let e = super::load(&b).unwrap_err().to_string();
    assert!(e.contains("b.nrrd") && e.contains("bzip2"), "{e}");
    // hex: the little-endian bytes as digit pairs, any case, lines of any length
    let digits: String = raw.iter().map(|b| format!("{b:02x}")).collect();
    let h = d.join("h.nrrd");
    let body = format!("{}\n  {}\n", &digits[..10].to_uppercase(), &digits[10..]);
    std::fs::write(&h, format!("{}{body}", head("hex"))).unwrap();
    assert_eq!(super::load(&h).unwrap().data, va.data);
    for (body, expect) in [
        (digits[..20].to_string(), "cannot hold the 24 bytes"),
        (
            format!("{}{}", &digits[..47], " ".repeat(10)),
            "holds 47 digits but the header needs 48",
        ),
        (
            format!("{}zz{}", &digits[..4], &digits[6..]),
            "hex digit 5 ('z')",
        ),
        (format!("{digits}00"), "more than the 24 bytes"),
    ] {
        std::fs::write(&h, format!("{}{body}", head("hex"))).unwrap();
        let e = super::load(&h).unwrap_err().to_string();
        assert!(e.contains("h.nrrd") && e.contains(expect), "{e}");
    }
}

/// A vector field of two voxels along x: (3, 4) and (1, 1).
fn wind_pair() -> Volume {
    Volume::new(
        "wind",
        [2, 1, 1],
        2,
        [1.0; 3],
        VoxelData::F32(vec![3.0, 4.0, 1.0, 1.0]),
    )
    .unwrap()
}

/// Cropping removes every voxel outside the box (the lowest scalar; a vector's zero),
/// keeps the value range so that a TF maps both alike, counts the histogram over it,
/// and refuses a box outside the volume naming the volume.
#[test]
fn cropping_removes_the_voxels_outside_and_keeps_the_range() {
    let data: Vec<i16> = (0..4 * 3 * 2).map(|i| 100 + i as i16).collect();
    let v = Volume::new("ramp", [4, 3, 2], 1, [1.0; 3], VoxelData::I16(data)).unwrap();
    let c = v.cropped([[1, 3], [0, 3], [1, 2]]).unwrap();
    assert_eq!(c.range, v.range);
    assert_eq!(c.dims, v.dims);
    for z in 0..2 {
        for y in 0..3 {
            for x in 0..4 {
                let inside = (1..3).contains(&x) && z == 1;
                let want = if inside { v.scalar(x, y, z) } else { 100.0 };
                assert_eq!(c.scalar(x, y, z), want, "({x}, {y}, {z})");
            }
        }
    }
    assert_eq!(c.histogram.iter().sum::<u64>(), 24);
    assert_eq!(
        c.histogram[0],
        24 - 6,
        "removed voxels count as the lowest value"
    );
    assert!(c.notes.iter().any(|n| n.contains("cropped")));
    // a vector field's removed voxels are zero vectors
    let w = wind_pair();
    let wc = w.cropped([[1, 2], [0, 1], [0, 1]]).unwrap();
    assert_eq!(wc.data, VoxelData::F32(vec![0.0, 0.0, 1.0, 1.0]));
    assert_eq!(wc.range, w.range);
    let e = v.cropped([[0, 5], [0, 3], [0, 2]]).unwrap_err().to_string();
    assert!(
        e.contains("'ramp'") && e.contains("inside [4, 3, 2]"),
        "{e}"
    );
    let e = v.cropped([[2, 2], [0, 3], [0, 2]]).unwrap_err().to_string();
    assert!(e.contains("non-empty"), "{e}");
}

/// Resampling by nearest neighbour keeps the box (the spacing scales), takes voxel
/// ⌊i · old / new⌋ along each axis, keeps every component of a vector, and doubling
/// then halving gives the volume back.
#[test]
fn resampling_takes_the_nearest_voxel_and_keeps_the_box() {
    let data: Vec<i16> = (0..4 * 3 * 2).map(|i| 100 + i as i16).collect();
    let v = Volume::new("ramp", [4, 3, 2], 1, [1.0, 2.0, 3.0], VoxelData::I16(data)).unwrap();
    let r = v.resampled([8, 6, 5]).unwrap();
    assert_eq!(r.dims, [8, 6, 5]);
    for a in 0..3 {
        let (old, new) = (
            v.spacing[a] * v.dims[a] as f64,
            r.spacing[a] * r.dims[a] as f64,
        );
        assert!((old - new).abs() < 1e-12, "axis {a}: box {old} → {new}");
    }
    for z in 0..5 {
        for y in 0..6 {
            for x in 0..8 {
                let want = v.scalar(x / 2, y / 2, z * 2 / 5);
                assert_eq!(r.scalar(x, y, z), want, "({x}, {y}, {z})");
            }
        }
    }
    assert_eq!(r.name, "ramp_8x6x5");
    assert!(r.notes.iter().any(|n| n.contains("resampled")));
    let back = v
        .resampled([8, 6, 4])
        .unwrap()
        .resampled([4, 3, 2])
        .unwrap();
    assert_eq!(back.data, v.data);
    let w = wind_pair();
    let wr = w.resampled([4, 1, 1]).unwrap();
    assert_eq!(
        wr.data,
        VoxelData::F32(vec![3.0, 4.0, 3.0, 4.0, 1.0, 1.0, 1.0, 1.0])
    );
    let e = v.resampled([0, 3, 2]).unwrap_err().to_string();
    assert!(e.contains("'ramp'") && e.contains("[0, 3, 2]"), "{e}");
}
