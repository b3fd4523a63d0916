//! MetaImage reader (`.mhd` with its data file, `.mha` with the data attached): our own
//! small parser, since no maintained crate reads it.
//!
//! Fields read: `NDims` (3, or 2 for a one-slice image), `DimSize`, `ElementType`
//! (`MET_UCHAR` … `MET_DOUBLE`), `ElementNumberOfChannels` (1–3), `ElementSpacing` (or
//! `ElementSize`), `ElementByteOrderMSB` / `BinaryDataByteOrderMSB`, `HeaderSize`
//! (bytes to skip in the data file; −1: the data ends the file), `CompressedData`
//! (zlib), `TransformMatrix` (the directions of the voxel axes in ITK's LPS world, one
//! axis after the other), `ElementDataFile` (`LOCAL`, a file name relative to the
//! header, or `LIST` followed by one file per slice). `Offset`/`Position`/`Origin`,
//! `CenterOfRotation`, `AnatomicalOrientation` and other descriptive fields are
//! accepted and not needed to place the voxels. The voxels are reordered to LPS
//! ([`super::orient`]).

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use super::nrrd::NrrdType;
use super::orient;
use super::raw::{ReadFail, io_error, read_samples};
use super::{Endian, Volume, VolumeError, check_layout};

/// Header bytes read at most before the data.
const MAX_HEADER: u64 = 1 << 20;

/// Whether the file is a MetaImage header: by extension, or by a first line that
/// starts with a MetaImage field.
pub fn is_metaimage(path: &Path, head: &[u8]) -> bool {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if matches!(ext.as_deref(), Some("mhd" | "mha")) {
        return true;
    }
    let first = head.split(|&b| b == b'\n').next().unwrap_or_default();
    ["ObjectType", "NDims"]
        .iter()
        .any(|k| first.starts_with(k.as_bytes()))
}

fn err(file: &Path, line: Option<usize>, message: impl Into<String>) -> VolumeError {
    VolumeError::Header {
        file: Some(file.to_path_buf()),
        line,
        message: message.into(),
    }
}

fn element_type(s: &str) -> Option<(NrrdType, u64)> {
    Some(match s {
        "MET_UCHAR" => (NrrdType::UInt8, 1),
        "MET_CHAR" => (NrrdType::Int8, 1),
        "MET_USHORT" => (NrrdType::UInt16, 2),
        "MET_SHORT" => (NrrdType::Int16, 2),
        "MET_UINT" | "MET_ULONG" => (NrrdType::UInt32, 4),
        "MET_INT" | "MET_LONG" => (NrrdType::Int32, 4),
        "MET_ULONG_LONG" => (NrrdType::UInt64, 8),
        "MET_LONG_LONG" => (NrrdType::Int64, 8),
        "MET_FLOAT" => (NrrdType::Float, 4),
        "MET_DOUBLE" => (NrrdType::Double, 8),
        _ => return None,
    })
}

/// Loads a MetaImage file.
pub fn load(path: &Path) -> Result<Volume, VolumeError> {
    let file = File::open(path).map_err(|e| io_error(path, "cannot open", e))?;
    let mut r = BufReader::new(file);
    let mut fields: Vec<(usize, String, String)> = Vec::new();
    let mut consumed: u64 = 0;
    let mut line = String::new();
    let mut list: Vec<String> = Vec::new();
    let mut in_list = false;
    let mut lineno = 0;
    loop {
        line.clear();
        let n = (&mut r)
            .take(MAX_HEADER - consumed)
            .read_line(&mut line)
            .map_err(|e| err(path, Some(lineno + 1), format!("not text: {e}")))?;
        if n == 0 {
            break;
        }
        consumed += n as u64;
        lineno += 1;
        if consumed >= MAX_HEADER {
            return Err(err(path, None, "the header is longer than 1 MiB"));
        }
        let t = line.trim();
        if in_list {
            if !t.is_empty() {
                list.push(t.to_string());
            }
            continue;
        }
        if t.is_empty() {
            continue;
        }
        let (k, v) = t
            .split_once('=')
            .ok_or_else(|| err(path, Some(lineno), format!("'{t}' is not 'Field = value'")))?;
        let (k, v) = (k.trim().to_string(), v.trim().to_string());
        let data_file = k == "ElementDataFile";
        fields.push((lineno, k, v.clone()));
        if data_file {
            if v.split_whitespace().next() == Some("LIST") {
                in_list = true;
                continue;
            }
            break; // ElementDataFile ends the header
        }
    }
    let get = |k: &str| {
        fields
            .iter()
            .find(|(_, f, _)| f == k)
            .map(|(l, _, v)| (*l, v.as_str()))
    };
    let nums = |k: &str| -> Result<Option<(usize, Vec<f64>)>, VolumeError> {
        match get(k) {
            None => Ok(None),
            Some((l, v)) => v
                .split_whitespace()
                .map(|x| x.parse::<f64>())
                .collect::<Result<Vec<_>, _>>()
                .map(|n| Some((l, n)))
                .map_err(|_| {
                    err(
                        path,
                        Some(l),
                        format!("{k}: '{v}' is not a list of numbers"),
                    )
                }),
        }
    };
    let yes = |k: &str| get(k).is_some_and(|(_, v)| v.eq_ignore_ascii_case("true"));
    let (ndl, ndims) = nums("NDims")?.ok_or_else(|| err(path, None, "no NDims field"))?;
    let ndims = match ndims.as_slice() {
        [n] if *n == 2.0 || *n == 3.0 => *n as usize,
        _ => {
            return Err(err(
                path,
                Some(ndl),
                format!("NDims {ndims:?}: vwb reads 2 or 3 dimensions"),
            ));
        }
    };
    let (dl, dims) = nums("DimSize")?.ok_or_else(|| err(path, None, "no DimSize field"))?;
    if dims.len() != ndims
        || dims
            .iter()
            .any(|d| !(d.fract() == 0.0 && *d >= 1.0 && *d <= u32::MAX as f64))
    {
        return Err(err(
            path,
            Some(dl),
            format!("DimSize {dims:?}: needs {ndims} positive integers"),
        ));
    }
    let dims3 = [
        dims[0] as u64,
        dims[1] as u64,
        dims.get(2).copied().unwrap_or(1.0) as u64,
    ];
    let (tl, ty) = get("ElementType").ok_or_else(|| err(path, None, "no ElementType field"))?;
    let (ty, bytes) = element_type(ty).ok_or_else(|| {
        err(
            path,
            Some(tl),
            format!("ElementType '{ty}' is not supported (MET_UCHAR … MET_DOUBLE)"),
        )
    })?;
    let components = match nums("ElementNumberOfChannels")? {
        None => 1,
        Some((_, c)) if matches!(c.as_slice(), [x] if (1.0..=3.0).contains(x) && x.fract() == 0.0) => {
            c[0] as u32
        }
        Some((l, c)) => {
            return Err(err(
                path,
                Some(l),
                format!("ElementNumberOfChannels {c:?}: 1, 2 or 3"),
            ));
        }
    };
    let mut spacing = [1.0; 3];
    if let Some((l, s)) = nums("ElementSpacing")?.or(nums("ElementSize")?) {
        if s.len() != ndims || s.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(err(
                path,
                Some(l),
                format!("ElementSpacing {s:?}: needs {ndims} positive numbers"),
            ));
        }
        spacing[..ndims].copy_from_slice(&s);
    }
    let endian = if yes("ElementByteOrderMSB") || yes("BinaryDataByteOrderMSB") {
        Endian::Big
    } else {
        Endian::Little
    };
    let mut dirs: orient::Directions = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    if let Some((l, m)) = nums("TransformMatrix")?
        .or(nums("Rotation")?)
        .or(nums("Orientation")?)
    {
        if m.len() != ndims * ndims {
            return Err(err(
                path,
                Some(l),
                format!(
                    "TransformMatrix has {} numbers, needs {}",
                    m.len(),
                    ndims * ndims
                ),
            ));
        }
        for a in 0..ndims {
            for w in 0..ndims {
                dirs[a][w] = m[a * ndims + w];
            }
        }
    }
    let layout = check_layout(dims3, components as u64, bytes, Some(path))?;
    let need = layout.values as u64 * bytes;
    let (dfl, data_file) =
        get("ElementDataFile").ok_or_else(|| err(path, None, "no ElementDataFile field"))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let header_size = match nums("HeaderSize")? {
        None => 0i64,
        Some((_, h)) if matches!(h.as_slice(), [x] if x.fract() == 0.0 && *x >= -1.0) => {
            h[0] as i64
        }
        Some((l, h)) => {
            return Err(err(
                path,
                Some(l),
                format!("HeaderSize {h:?}: a byte count or -1"),
            ));
        }
    };
    let compressed = yes("CompressedData");
    // the data stream
    let mut reader: Box<dyn Read> = if data_file == "LOCAL" {
        r.seek(SeekFrom::Start(consumed))
            .map_err(|e| io_error(path, "cannot seek", e))?;
        Box::new(r)
    } else if data_file.split_whitespace().next() == Some("LIST") {
        if compressed {
            return Err(err(
                path,
                Some(dfl),
                "compressed LIST data is not supported",
            ));
        }
        if list.is_empty() {
            return Err(err(
                path,
                Some(dfl),
                "ElementDataFile = LIST names no files",
            ));
        }
        let mut chained: Box<dyn Read> = Box::new(std::io::empty());
        for name in &list {
            let p: PathBuf = base.join(name);
            let f = File::open(&p).map_err(|e| {
                io_error(
                    &p,
                    &format!("cannot open a slice file listed in {}", path.display()),
                    e,
                )
            })?;
            chained = Box::new(chained.chain(f));
        }
        chained
    } else {
        if data_file.contains('%') {
            return Err(err(
                path,
                Some(dfl),
                "file-name patterns in ElementDataFile are not supported; use LIST",
            ));
        }
        let p = base.join(data_file);
        let mut f = File::open(&p).map_err(|e| {
            io_error(
                &p,
                &format!("cannot open the data file named in {}", path.display()),
                e,
            )
        })?;
        let len = f
            .metadata()
            .map_err(|e| io_error(&p, "cannot read metadata", e))?
            .len();
        let skip = if header_size == -1 && !compressed {
            len.checked_sub(need).ok_or_else(|| VolumeError::DataSize {
                file: p.clone(),
                file_len: len,
                skip: 0,
                needed: need,
                needed_by: "the header",
                layout: format!("{}x{}x{}", dims3[0], dims3[1], dims3[2]),
            })?
        } else {
            header_size.max(0) as u64
        };
        if !compressed && len < skip.saturating_add(need) {
            return Err(VolumeError::DataSize {
                file: p,
                file_len: len,
                skip,
                needed: need,
                needed_by: "the header",
                layout: format!("{}x{}x{}", dims3[0], dims3[1], dims3[2]),
            });
        }
        f.seek(SeekFrom::Start(skip))
            .map_err(|e| io_error(&p, "cannot seek", e))?;
        Box::new(BufReader::new(f))
    };
    if compressed {
        reader = Box::new(flate2::read::ZlibDecoder::new(reader));
    }
    let data = read_samples(&mut reader, ty, endian, layout.values).map_err(|e| match e {
        ReadFail::Io(e) => io_error(path, "cannot read the samples", e),
        ReadFail::Short(got) => VolumeError::Compressed {
            file: path.to_path_buf(),
            message: format!("the data ends after {got} of {need} bytes"),
        },
        ReadFail::Alloc(bytes) => VolumeError::OutOfMemory {
            file: Some(path.to_path_buf()),
            bytes,
        },
    })?;
    let dims = dims3.map(|d| d as u32);
    let (reorder, angle) = orient::reorder_for(&dirs);
    let mut notes = Vec::new();
    if angle > 0.5 {
        notes.push(format!(
            "oblique by {angle:.1}°: snapped to the nearest axes without resampling"
        ));
    }
    notes.push(format!(
        "MetaImage, {} endian{}; axes to LPS: {}",
        endian.name(),
        if compressed { ", zlib" } else { "" },
        super::nifti::describe(&reorder)
    ));
    let data = super::nifti::reorder_data(data, &reorder, dims, components as usize);
    let mut v = Volume::new(
        super::name_from_path(path),
        reorder.apply(dims),
        components,
        reorder.apply(spacing),
        data,
    )
    .map_err(|e| e.in_file(path))?;
    v.source = Some(path.to_path_buf());
    v.notes = notes;
    Ok(v)
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    fn tmp(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("vwb-mhd-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d.join(name)
    }

    fn samples() -> Vec<u8> {
        (0..12u16).flat_map(|v| (v * 10).to_le_bytes()).collect()
    }

    #[test]
    fn detached_attached_compressed_and_list() {
        let raw = tmp("a.raw");
        std::fs::write(&raw, samples()).unwrap();
        let hdr = "ObjectType = Image\nNDims = 3\nDimSize = 3 2 2\nElementType = MET_USHORT\nElementSpacing = 0.5 0.5 2\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nElementDataFile = a.raw\n";
        let mhd = tmp("a.mhd");
        std::fs::write(&mhd, hdr).unwrap();
        let v = super::super::load(&mhd).unwrap();
        assert_eq!(v.dims, [3, 2, 2]);
        assert_eq!(v.spacing, [0.5, 0.5, 2.0]);
        assert_eq!(v.data.get_f64(11), Some(110.0));
        // attached and zlib-compressed
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
        z.write_all(&samples()).unwrap();
        let mut mha = hdr
            .replace(
                "ElementDataFile = a.raw",
                "CompressedData = True\nElementDataFile = LOCAL",
            )
            .into_bytes();
        mha.extend(z.finish().unwrap());
        let p = tmp("b.mha");
        std::fs::write(&p, mha).unwrap();
        let w = super::super::load(&p).unwrap();
        assert_eq!(w.data, v.data);
        // LIST of slices
        let (s0, s1) = (tmp("s0.raw"), tmp("s1.raw"));
        std::fs::write(&s0, &samples()[..12]).unwrap();
        std::fs::write(&s1, &samples()[12..]).unwrap();
        let l = tmp("c.mhd");
        std::fs::write(
            &l,
            hdr.replace(
                "ElementDataFile = a.raw",
                "ElementDataFile = LIST\ns0.raw\ns1.raw",
            ),
        )
        .unwrap();
        assert_eq!(super::super::load(&l).unwrap().data, v.data);
        // flipped y in the transform: reordered
        let f = tmp("f.mhd");
        std::fs::write(&f, hdr.replace("1 0 0 0 1 0 0 0 1", "1 0 0 0 -1 0 0 0 1")).unwrap();
        let fv = super::super::load(&f).unwrap();
        assert_eq!(fv.data.get_f64(0), Some(30.0));
    }

    #[test]
    fn bad_headers_name_the_file_and_line() {
        let m = tmp("bad.mhd");
        std::fs::write(tmp("short.raw"), [0u8; 24]).unwrap();
        for (text, expect) in [
            (
                "NDims = 3\nDimSize = 3 2\nElementType = MET_SHORT\nElementDataFile = x.raw\n",
                "DimSize",
            ),
            (
                "NDims = 3\nDimSize = 3 2 2\nElementType = MET_QUAD\nElementDataFile = x.raw\n",
                "MET_QUAD",
            ),
            (
                "NDims = 3\nDimSize = 3 2 2\nElementType = MET_SHORT\nElementDataFile = missing.raw\n",
                "missing.raw",
            ),
            (
                "NDims = 3\nDimSize = 90000 90000 90000\nElementType = MET_SHORT\nElementDataFile = x.raw\n",
                "90000",
            ),
            (
                "NDims = 3\nDimSize = 3 2 3\nElementType = MET_SHORT\nElementDataFile = short.raw\n",
                "36",
            ),
            ("just text\n", "Field = value"),
            // regression: a huge HeaderSize overflowed the size check
            (
                "NDims = 3\nDimSize = 3 2 2\nElementType = MET_SHORT\nHeaderSize = 1e300\nElementDataFile = short.raw\n",
                "short.raw",
            ),
        ] {
            std::fs::write(&m, text).unwrap();
            let e = super::super::load(&m).unwrap_err().to_string();
            assert!(e.contains(expect), "{text}: {e}");
        }
    }
}
