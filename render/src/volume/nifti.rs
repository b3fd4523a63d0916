//! NIfTI-1 and NIfTI-2 reader (`.nii`, `.nii.gz`; single-file `n+1` / `n+2`).
//!
//! Our own parser, not the `nifti` crate: that crate reads NIfTI-1 only, and it
//! allocates the whole volume before a caller can check the dims against the memory
//! budget. Here the header is checked first ([`super::check_layout`]), so a lying header
//! fails before anything large is allocated.
//!
//! - Either byte order (told by `sizeof_hdr`).
//! - Types: uint8, int8, uint16, int16 load as they are; int32, uint32, int64, uint64,
//!   float32 and float64 become f32. RGB24 becomes a 3-component u8 vector.
//! - `scl_slope`/`scl_inter` are applied when the slope is non-zero and not the identity
//!   (the samples become f32).
//! - 3D volumes; a 4D series loads its first volume (a note says so); 5D with
//!   `dim[4] = 1` and 2 or 3 vector components (`NIFTI_INTENT_VECTOR`) loads as a vector
//!   volume (the components are interleaved on load).
//! - Orientation: the sform when `sform_code > 0`, else the qform when
//!   `qform_code > 0`, else the axes as stored. The voxels are reordered to LPS
//!   ([`super::orient`]). The volume's notes record what was applied.
//! - `.hdr`/`.img` pairs are refused with a clear error.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use super::nrrd::NrrdType;
use super::orient::{self, Directions};
use super::raw::{ReadFail, io_error, read_fully, read_samples};
use super::{Endian, Volume, VolumeError, VoxelData, check_layout};

/// What the header says.
#[derive(Debug, Clone, PartialEq)]
pub struct NiftiHeader {
    pub version: u8,
    pub endian: Endian,
    /// `dim[0..8]`.
    pub dim: [i64; 8],
    pub datatype: i16,
    pub pixdim: [f64; 8],
    pub vox_offset: u64,
    pub scl_slope: f64,
    pub scl_inter: f64,
    pub qform_code: i32,
    pub sform_code: i32,
    /// quatern_b, c, d, qoffset_x, y, z.
    pub quatern: [f64; 6],
    pub srow: [[f64; 4]; 3],
    pub intent_code: i32,
}

/// Whether `head` (the first bytes of a file, decompressed) is a single-file NIfTI.
pub fn is_nifti(head: &[u8]) -> bool {
    head.len() >= 348 && matches!(&head[344..348], b"n+1\0" | b"ni1\0")
        || head.len() >= 12 && matches!(&head[4..8], b"n+2\0" | b"ni2\0")
}

fn hdr_err(file: &Path, message: impl Into<String>) -> VolumeError {
    VolumeError::Header {
        file: Some(file.to_path_buf()),
        line: None,
        message: message.into(),
    }
}

/// Parses the header from the first 540 (NIfTI-2) or 348 (NIfTI-1) bytes.
pub fn parse_header(h: &[u8], file: &Path) -> Result<NiftiHeader, VolumeError> {
    if h.len() < 348 {
        return Err(hdr_err(
            file,
            format!("NIfTI header truncated: {} of 348 bytes", h.len()),
        ));
    }
    let le = i32::from_le_bytes(h[0..4].try_into().expect("4 bytes"));
    let be = i32::from_be_bytes(h[0..4].try_into().expect("4 bytes"));
    let (version, endian) = match (le, be) {
        (348, _) => (1, Endian::Little),
        (_, 348) => (1, Endian::Big),
        (540, _) => (2, Endian::Little),
        (_, 540) => (2, Endian::Big),
        _ => {
            return Err(hdr_err(
                file,
                format!("sizeof_hdr is {le} (little-endian) / {be} (big-endian), not 348 or 540"),
            ));
        }
    };
    if version == 2 && h.len() < 540 {
        return Err(hdr_err(
            file,
            format!("NIfTI-2 header truncated: {} of 540 bytes", h.len()),
        ));
    }
    let at = |o: usize, n: usize| -> &[u8] { &h[o..o + n] };
    macro_rules! num {
        ($t:ty, $o:expr) => {{
            let b = at($o, size_of::<$t>()).try_into().expect("sized");
            match endian {
                Endian::Little => <$t>::from_le_bytes(b),
                Endian::Big => <$t>::from_be_bytes(b),
            }
        }};
    }
    // a single-file NIfTI has the magic n+1 / n+2; ni1 / ni2 is a .hdr/.img pair
    let magic = if version == 1 { at(344, 4) } else { at(4, 4) };
    if magic != [b'n', b'+', b'0' + version, 0] {
        return Err(VolumeError::Unsupported {
            file: file.to_path_buf(),
            message: format!(
                "a NIfTI-{version} header without its data (magic 'ni{version}': a .hdr/.img \
                 pair); convert it to a single .nii file"
            ),
        });
    }
    let hdr = if version == 1 {
        NiftiHeader {
            version,
            endian,
            dim: std::array::from_fn(|i| num!(i16, 40 + 2 * i) as i64),
            datatype: num!(i16, 70),
            pixdim: std::array::from_fn(|i| num!(f32, 76 + 4 * i) as f64),
            vox_offset: {
                let v = num!(f32, 108);
                if !(v.is_finite() && v >= 0.0) {
                    return Err(hdr_err(
                        file,
                        format!("vox_offset {v} is not a byte offset"),
                    ));
                }
                v as u64
            },
            scl_slope: num!(f32, 112) as f64,
            scl_inter: num!(f32, 116) as f64,
            qform_code: num!(i16, 252) as i32,
            sform_code: num!(i16, 254) as i32,
            quatern: std::array::from_fn(|i| num!(f32, 256 + 4 * i) as f64),
            srow: std::array::from_fn(|r| {
                std::array::from_fn(|c| num!(f32, 280 + 16 * r + 4 * c) as f64)
            }),
            intent_code: num!(i16, 68) as i32,
        }
    } else {
        let off = num!(i64, 168);
        if off < 0 {
            return Err(hdr_err(file, format!("vox_offset {off} is negative")));
        }
        NiftiHeader {
            version,
            endian,
            dim: std::array::from_fn(|i| num!(i64, 16 + 8 * i)),
            datatype: num!(i16, 12),
            pixdim: std::array::from_fn(|i| num!(f64, 104 + 8 * i)),
            vox_offset: off as u64,
            scl_slope: num!(f64, 176),
            scl_inter: num!(f64, 184),
            qform_code: num!(i32, 344),
            sform_code: num!(i32, 348),
            quatern: std::array::from_fn(|i| num!(f64, 352 + 8 * i)),
            srow: std::array::from_fn(|r| std::array::from_fn(|c| num!(f64, 400 + 32 * r + 8 * c))),
            intent_code: num!(i32, 504),
        }
    };
    Ok(hdr)
}

/// The sample type of a NIfTI datatype code, and the components per voxel it holds.
fn sample_type(code: i16) -> Option<(NrrdType, u32, &'static str)> {
    Some(match code {
        2 => (NrrdType::UInt8, 1, "uint8"),
        4 => (NrrdType::Int16, 1, "int16"),
        8 => (NrrdType::Int32, 1, "int32"),
        16 => (NrrdType::Float, 1, "float32"),
        64 => (NrrdType::Double, 1, "float64"),
        128 => (NrrdType::UInt8, 3, "RGB24"),
        256 => (NrrdType::Int8, 1, "int8"),
        512 => (NrrdType::UInt16, 1, "uint16"),
        768 => (NrrdType::UInt32, 1, "uint32"),
        1024 => (NrrdType::Int64, 1, "int64"),
        1280 => (NrrdType::UInt64, 1, "uint64"),
        _ => return None,
    })
}

fn nrrd_type_bytes(t: NrrdType) -> u64 {
    match t {
        NrrdType::UInt8 | NrrdType::Int8 => 1,
        NrrdType::UInt16 | NrrdType::Int16 => 2,
        NrrdType::UInt32 | NrrdType::Int32 | NrrdType::Float => 4,
        NrrdType::UInt64 | NrrdType::Int64 | NrrdType::Double => 8,
    }
}

/// The voxel-axis directions in LPS world, and which transform gave them.
fn directions(h: &NiftiHeader) -> (Directions, &'static str) {
    let ras: Directions = if h.sform_code > 0 {
        std::array::from_fn(|a| [h.srow[0][a], h.srow[1][a], h.srow[2][a]])
    } else if h.qform_code > 0 {
        let [b, c, d, ..] = h.quatern;
        let a = (1.0 - (b * b + c * c + d * d)).max(0.0).sqrt();
        let r = [
            [
                a * a + b * b - c * c - d * d,
                2.0 * (b * c - a * d),
                2.0 * (b * d + a * c),
            ],
            [
                2.0 * (b * c + a * d),
                a * a + c * c - b * b - d * d,
                2.0 * (c * d - a * b),
            ],
            [
                2.0 * (b * d - a * c),
                2.0 * (c * d + a * b),
                a * a + d * d - c * c - b * b,
            ],
        ];
        let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
        std::array::from_fn(|col| {
            let s = if col == 2 { qfac } else { 1.0 };
            [r[0][col] * s, r[1][col] * s, r[2][col] * s]
        })
    } else {
        // Analyze orientation: the axes as stored; keep them
        return (
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            "none (no sform or qform: the axes as stored)",
        );
    };
    let how = if h.sform_code > 0 { "sform" } else { "qform" };
    (orient::ras_to_lps(&ras), how)
}

/// Loads a `.nii` or `.nii.gz` (`gzip`: the whole file is gzip-compressed).
pub fn load(path: &Path, gzip: bool) -> Result<Volume, VolumeError> {
    let file = File::open(path).map_err(|e| io_error(path, "cannot open", e))?;
    let mut r: Box<dyn Read> = if gzip {
        Box::new(flate2::read::MultiGzDecoder::new(BufReader::new(file)))
    } else {
        Box::new(BufReader::new(file))
    };
    let mut head = vec![0u8; 540];
    let n =
        read_fully(&mut r, &mut head).map_err(|e| io_error(path, "cannot read the header", e))?;
    head.truncate(n);
    let h = parse_header(&head, path)?;
    let (ty, per_voxel, type_name) =
        sample_type(h.datatype).ok_or_else(|| VolumeError::Unsupported {
            file: path.to_path_buf(),
            message: format!(
                "NIfTI datatype {} is not supported (integers, float32/64 and RGB24 are)",
                h.datatype
            ),
        })?;
    let ndim = h.dim[0];
    if !(1..=7).contains(&ndim) {
        return Err(hdr_err(
            path,
            format!("dim[0] = {ndim}: not a number of dimensions in 1..=7"),
        ));
    }
    let d = |i: usize| if (i as i64) <= ndim { h.dim[i] } else { 1 };
    for i in 1..=ndim as usize {
        if d(i) < 1 {
            return Err(hdr_err(
                path,
                format!("dim[{i}] = {} is not a positive size", d(i)),
            ));
        }
    }
    let mut notes = Vec::new();
    let mut components = per_voxel;
    if d(5) > 1 {
        if per_voxel != 1 || d(4) != 1 || !(2..=3).contains(&d(5)) || d(6) > 1 || d(7) > 1 {
            return Err(VolumeError::Unsupported {
                file: path.to_path_buf(),
                message: format!(
                    "dims {:?}: vwb reads 3D volumes, 4D series and 3D fields of 2 or 3 vector components (dim[5])",
                    &h.dim[1..=ndim as usize]
                ),
            });
        }
        components = d(5) as u32;
    } else if d(4) > 1 {
        notes.push(format!(
            "a 4D series of {} volumes: vwb shows the first",
            d(4)
        ));
    }
    if d(6) > 1 || d(7) > 1 {
        return Err(VolumeError::Unsupported {
            file: path.to_path_buf(),
            message: format!(
                "dims {:?}: more than 5 dimensions",
                &h.dim[1..=ndim as usize]
            ),
        });
    }
    let dims_u64 = [d(1) as u64, d(2) as u64, d(3) as u64];
    let layout = check_layout(dims_u64, components as u64, nrrd_type_bytes(ty), Some(path))?;
    let dims = dims_u64.map(|x| x as u32);
    let mut spacing = [1.0; 3];
    for (a, s) in spacing.iter_mut().enumerate() {
        let p = h.pixdim[a + 1].abs();
        if p.is_finite() && p > 0.0 {
            *s = p;
        } else {
            notes.push(format!(
                "pixdim[{}] = {} is not a voxel size: 1 is used",
                a + 1,
                h.pixdim[a + 1]
            ));
        }
    }
    // skip to the data: the header read may already hold its first bytes
    let min_offset = if h.version == 1 { 348 } else { 540 };
    if h.vox_offset < min_offset {
        return Err(hdr_err(
            path,
            format!("vox_offset {} lies inside the header", h.vox_offset),
        ));
    }
    if !gzip {
        // seekable: check the file holds the data before reading it
        let len = std::fs::metadata(path)
            .map_err(|e| io_error(path, "cannot read metadata", e))?
            .len();
        let need = layout.values as u64 * nrrd_type_bytes(ty);
        if len < h.vox_offset.saturating_add(need) {
            return Err(VolumeError::DataSize {
                file: path.to_path_buf(),
                file_len: len,
                skip: h.vox_offset,
                needed: need,
                needed_by: "the header",
                layout: format!(
                    "{}x{}x{} {type_name}",
                    dims_u64[0], dims_u64[1], dims_u64[2]
                ),
            });
        }
    }
    let read = head.len() as u64;
    let (prefix, skip) = if h.vox_offset <= read {
        (head[h.vox_offset as usize..].to_vec(), 0)
    } else {
        (Vec::new(), h.vox_offset - read)
    };
    let copied = std::io::copy(&mut (&mut r).take(skip), &mut std::io::sink())
        .map_err(|e| io_error(path, "cannot read up to vox_offset", e))?;
    if copied < skip {
        return Err(hdr_err(
            path,
            format!("the file ends before vox_offset {}", h.vox_offset),
        ));
    }
    let mut r = std::io::Cursor::new(prefix).chain(r);
    let data = read_samples(&mut r, ty, h.endian, layout.values).map_err(|e| match e {
        ReadFail::Io(e) => io_error(path, "cannot read the samples", e),
        ReadFail::Short(got) => VolumeError::Compressed {
            file: path.to_path_buf(),
            message: format!(
                "the data ends after {got} of {} bytes",
                layout.values as u64 * nrrd_type_bytes(ty)
            ),
        },
        ReadFail::Alloc(bytes) => VolumeError::OutOfMemory {
            file: Some(path.to_path_buf()),
            bytes,
        },
    })?;
    // vector components are stored as the slowest axis: interleave them
    let data = if components > 1 && per_voxel == 1 {
        interleave(data, components as usize)
    } else {
        data
    };
    // scaling
    let data = if h.scl_slope != 0.0
        && h.scl_slope.is_finite()
        && h.scl_inter.is_finite()
        && (h.scl_slope != 1.0 || h.scl_inter != 0.0)
    {
        notes.push(format!("scaled: value·{} + {}", h.scl_slope, h.scl_inter));
        let (m, c) = (h.scl_slope, h.scl_inter);
        VoxelData::F32(
            (0..data.len())
                .map(|i| (data.get_f64(i).unwrap_or(f64::NAN) * m + c) as f32)
                .collect(),
        )
    } else {
        data
    };
    let (dirs, how) = directions(&h);
    let (reorder, angle) = orient::reorder_for(&dirs);
    if angle > 0.5 {
        notes.push(format!(
            "oblique by {angle:.1}°: snapped to the nearest axes without resampling"
        ));
    }
    notes.push(format!(
        "NIfTI-{} {type_name}, {} endian; orientation from {how}; axes to LPS: {}",
        h.version,
        h.endian.name(),
        describe(&reorder)
    ));
    let data = reorder_data(data, &reorder, dims, components as usize);
    let mut volume = Volume::new(
        super::name_from_path(path)
            .trim_end_matches(".nii")
            .to_string(),
        reorder.apply(dims),
        components,
        reorder.apply(spacing),
        data,
    )
    .map_err(|e| e.in_file(path))?;
    volume.source = Some(path.to_path_buf());
    volume.notes = notes;
    Ok(volume)
}

/// "x→x, y→−y, z→z" style: where each stored axis went.
pub(crate) fn describe(r: &orient::Reorder) -> String {
    if r.is_identity() {
        return "as stored".into();
    }
    let n = ["x", "y", "z"];
    (0..3)
        .map(|a| {
            format!(
                "{}→{}{}",
                n[a],
                if r.flip[a] { "−" } else { "" },
                n[r.to[a]]
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The samples in canonical order.
pub(crate) fn reorder_data(
    data: VoxelData,
    r: &orient::Reorder,
    dims: [u32; 3],
    components: usize,
) -> VoxelData {
    if r.is_identity() {
        return data;
    }
    match data {
        VoxelData::U8(v) => VoxelData::U8(r.samples(&v, dims, components)),
        VoxelData::I8(v) => VoxelData::I8(r.samples(&v, dims, components)),
        VoxelData::U16(v) => VoxelData::U16(r.samples(&v, dims, components)),
        VoxelData::I16(v) => VoxelData::I16(r.samples(&v, dims, components)),
        VoxelData::F32(v) => VoxelData::F32(r.samples(&v, dims, components)),
    }
}

/// Planar components (all of component 0, then 1, ...) to interleaved.
pub(crate) fn interleave(data: VoxelData, components: usize) -> VoxelData {
    fn go<T: Copy>(v: Vec<T>, c: usize) -> Vec<T> {
        let n = v.len() / c;
        let mut out = Vec::with_capacity(v.len());
        for i in 0..n {
            for k in 0..c {
                out.push(v[k * n + i]);
            }
        }
        out
    }
    match data {
        VoxelData::U8(v) => VoxelData::U8(go(v, components)),
        VoxelData::I8(v) => VoxelData::I8(go(v, components)),
        VoxelData::U16(v) => VoxelData::U16(go(v, components)),
        VoxelData::I16(v) => VoxelData::I16(go(v, components)),
        VoxelData::F32(v) => VoxelData::F32(go(v, components)),
    }
}

/// Writes a NIfTI-1 `.nii` (little-endian, float32 or int16 samples, the given sform in
/// RAS) — for tests and for converting the sample data.
pub fn write_nifti1(
    path: &Path,
    dims: [u32; 3],
    spacing: [f32; 3],
    sform_ras: [[f32; 4]; 3],
    samples: &[i16],
) -> std::io::Result<()> {
    let mut h = vec![0u8; 352];
    let put = |h: &mut Vec<u8>, o: usize, b: &[u8]| h[o..o + b.len()].copy_from_slice(b);
    put(&mut h, 0, &348i32.to_le_bytes());
    let dim: [i16; 8] = [
        3,
        dims[0] as i16,
        dims[1] as i16,
        dims[2] as i16,
        1,
        1,
        1,
        1,
    ];
    for (i, v) in dim.iter().enumerate() {
        put(&mut h, 40 + 2 * i, &v.to_le_bytes());
    }
    put(&mut h, 70, &4i16.to_le_bytes()); // int16
    put(&mut h, 72, &16i16.to_le_bytes());
    let pixdim = [
        1.0f32, spacing[0], spacing[1], spacing[2], 0.0, 0.0, 0.0, 0.0,
    ];
    for (i, v) in pixdim.iter().enumerate() {
        put(&mut h, 76 + 4 * i, &v.to_le_bytes());
    }
    put(&mut h, 108, &352f32.to_le_bytes());
    put(&mut h, 112, &1f32.to_le_bytes());
    put(&mut h, 254, &1i16.to_le_bytes()); // sform_code scanner
    for (r, row) in sform_ras.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            put(&mut h, 280 + 16 * r + 4 * c, &v.to_le_bytes());
        }
    }
    put(&mut h, 344, b"n+1\0");
    for s in samples {
        h.extend_from_slice(&s.to_le_bytes());
    }
    crate::preset::write_atomic(path, &h).map_err(|e| std::io::Error::other(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("vwb-nifti-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d.join(name)
    }

    /// value = 100·z + 10·y + x over 3×2×2
    fn ramp() -> Vec<i16> {
        let mut v = Vec::new();
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..3 {
                    v.push(100 * z + 10 * y + x);
                }
            }
        }
        v
    }

    #[test]
    fn reads_samples_spacing_and_reorients_to_lps() {
        // stored x runs to the right (RAS +x): LPS flips it; y anterior: flipped too
        let p = tmp("ras.nii");
        let sform = [
            [2.0, 0.0, 0.0, 0.0],
            [0.0, 3.0, 0.0, 0.0],
            [0.0, 0.0, 4.0, 0.0],
        ];
        write_nifti1(&p, [3, 2, 2], [2.0, 3.0, 4.0], sform, &ramp()).unwrap();
        let v = super::super::load(&p).unwrap();
        assert_eq!(v.dims, [3, 2, 2]);
        assert_eq!(v.spacing, [2.0, 3.0, 4.0]);
        // canonical (0,0,0) is stored (2,1,0)
        assert_eq!(v.data.get_f64(0), Some(12.0));
        assert_eq!(v.data.get_f64(1), Some(11.0));
        assert!(v.notes.iter().any(|n| n.contains("sform")), "{:?}", v.notes);
        // the same voxels in LPS storage: identity
        let p2 = tmp("lps.nii");
        let sform = [
            [-2.0, 0.0, 0.0, 0.0],
            [0.0, -3.0, 0.0, 0.0],
            [0.0, 0.0, 4.0, 0.0],
        ];
        write_nifti1(&p2, [3, 2, 2], [2.0, 3.0, 4.0], sform, &ramp()).unwrap();
        let w = super::super::load(&p2).unwrap();
        assert_eq!(w.data.get_f64(0), Some(0.0));
        assert_eq!(w.data.get_f64(11), Some(112.0));
    }

    #[test]
    fn gzip_and_lying_headers() {
        let p = tmp("g.nii");
        let sform = [
            [-1.0, 0.0, 0.0, 0.0],
            [0.0, -1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ];
        write_nifti1(&p, [3, 2, 2], [1.0; 3], sform, &ramp()).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let gz = tmp("g.nii.gz");
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut enc, &bytes).unwrap();
        std::fs::write(&gz, enc.finish().unwrap()).unwrap();
        let v = super::super::load(&gz).unwrap();
        assert_eq!(v.dims, [3, 2, 2]);
        assert_eq!(v.name, "g");
        // truncated data
        let t = tmp("t.nii");
        std::fs::write(&t, &bytes[..bytes.len() - 4]).unwrap();
        let e = super::super::load(&t).unwrap_err().to_string();
        assert!(e.contains("t.nii"), "{e}");
        // a patched copy is refused with its name and the cause
        let refused = |name: &str, patch: &dyn Fn(&mut Vec<u8>), cause: &str| {
            let mut b = bytes.clone();
            patch(&mut b);
            let p = tmp(name);
            std::fs::write(&p, &b).unwrap();
            let e = super::super::load(&p).unwrap_err().to_string();
            assert!(e.contains(name) && e.contains(cause), "{e}");
        };
        // a header claiming 30000³ voxels fails before allocating
        refused(
            "huge.nii",
            &|b| {
                for i in 0..3 {
                    b[42 + 2 * i..44 + 2 * i].copy_from_slice(&30000i16.to_le_bytes());
                }
            },
            "30000",
        );
        refused(
            "bad.nii",
            &|b| b[70..72].copy_from_slice(&2048i16.to_le_bytes()),
            "datatype 2048",
        );
        refused(
            "pair.nii",
            &|b| b[344..348].copy_from_slice(b"ni1\0"),
            "NIfTI-1 header without its data",
        );
        // regression (the fuzzer's find): a vox_offset of 3·10³⁸ overflowed the size check
        refused(
            "far.nii",
            &|b| b[108..112].copy_from_slice(&3.0e38f32.to_le_bytes()),
            "",
        );
        // scaling
        let mut s = bytes.clone();
        s[112..116].copy_from_slice(&2f32.to_le_bytes());
        s[116..120].copy_from_slice(&(-5f32).to_le_bytes());
        let sp = tmp("scaled.nii");
        std::fs::write(&sp, &s).unwrap();
        let v = super::super::load(&sp).unwrap();
        assert_eq!(v.data.get_f64(1), Some(-3.0));
        assert!(v.notes.iter().any(|n| n.contains("scaled")));
    }
}
