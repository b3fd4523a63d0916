//! Headerless raw volumes and the sample decoder shared with the NRRD reader.

use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::nrrd::NrrdType;
use super::{
    Endian, ScalarType, Volume, VolumeError, VoxelData, check_layout, check_spacing, layout_desc,
    name_from_path,
};

/// The layout of a headerless raw file, which [`load_raw`] cannot guess.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RawDesc {
    pub dims: [u32; 3],
    /// 1 for scalars, 2 or 3 for interleaved vectors.
    pub components: u32,
    pub scalar: ScalarType,
    pub endian: Endian,
    /// World size of a voxel along x, y, z (finite, positive).
    pub spacing: [f64; 3],
    /// Bytes to skip at the start of the file (a foreign header).
    pub header_bytes: u64,
}

impl RawDesc {
    /// A scalar, little-endian layout with unit spacing and no header.
    pub fn new(dims: [u32; 3], scalar: ScalarType) -> Self {
        RawDesc {
            dims,
            components: 1,
            scalar,
            endian: Endian::Little,
            spacing: [1.0; 3],
            header_bytes: 0,
        }
    }
}

/// Loads a headerless raw file: `header_bytes` of anything, then exactly the
/// samples `desc` describes (x fastest, components interleaved). The file length
/// must match exactly, which catches wrong dims or types; it is checked before
/// anything is allocated.
pub fn load_raw(path: &Path, desc: &RawDesc) -> Result<Volume, VolumeError> {
    let layout = check_layout(
        desc.dims.map(u64::from),
        u64::from(desc.components),
        desc.scalar.size_bytes() as u64,
        Some(path),
    )?;
    check_spacing(desc.spacing, Some(path))?;
    let needed = layout.values as u64 * desc.scalar.size_bytes() as u64;

    let file = File::open(path).map_err(|e| io_error(path, "cannot open", e))?;
    let file_len = file
        .metadata()
        .map_err(|e| io_error(path, "cannot read metadata", e))?
        .len();
    if desc.header_bytes.checked_add(needed) != Some(file_len) {
        return Err(VolumeError::DataSize {
            file: path.to_path_buf(),
            file_len,
            skip: desc.header_bytes,
            needed,
            needed_by: "the raw description",
            layout: layout_desc(
                desc.dims.map(u64::from),
                u64::from(desc.components),
                desc.scalar.name(),
            ),
        });
    }

    let mut reader = BufReader::new(file);
    reader
        .seek(SeekFrom::Start(desc.header_bytes))
        .map_err(|e| io_error(path, "cannot seek", e))?;
    let data = read_samples(
        &mut reader,
        NrrdType::from(desc.scalar),
        desc.endian,
        layout.values,
    )
    .map_err(|fail| match fail {
        ReadFail::Io(e) => io_error(path, "cannot read", e),
        ReadFail::Alloc(bytes) => VolumeError::OutOfMemory {
            file: Some(path.to_path_buf()),
            bytes,
        },
        // The length was checked: the file shrank while it was being read.
        ReadFail::Short(got) => VolumeError::DataSize {
            file: path.to_path_buf(),
            file_len: desc.header_bytes + got,
            skip: desc.header_bytes,
            needed,
            needed_by: "the raw description",
            layout: layout_desc(
                desc.dims.map(u64::from),
                u64::from(desc.components),
                desc.scalar.name(),
            ),
        },
    })?;

    let mut volume = Volume::new(
        name_from_path(path),
        layout.dims,
        layout.components,
        desc.spacing,
        data,
    )
    .map_err(|e| e.in_file(path))?;
    volume.source = Some(path.to_path_buf());
    Ok(volume)
}

pub(crate) fn io_error(path: &Path, context: &str, cause: io::Error) -> VolumeError {
    VolumeError::Io {
        file: path.to_path_buf(),
        context: context.to_owned(),
        cause,
    }
}

/// Why [`read_samples`] stopped.
#[derive(Debug)]
pub(crate) enum ReadFail {
    /// The reader failed.
    Io(io::Error),
    /// The reader ended after this many bytes.
    Short(u64),
    /// The output buffer of this many bytes could not be allocated.
    Alloc(u64),
}

/// Values decoded per read.
const CHUNK_VALUES: usize = 64 * 1024;

/// Reads exactly `count` samples of type `ty` and converts them to the in-memory
/// type ([`NrrdType::scalar_type`]). Reads in chunks, so the only large
/// allocation is the output, reserved up front with `try_reserve_exact`.
pub(crate) fn read_samples<R: Read>(
    r: &mut R,
    ty: NrrdType,
    endian: Endian,
    count: usize,
) -> Result<VoxelData, ReadFail> {
    let le = endian == Endian::Little;
    // Picks the byte order once per call; the branch inside is loop-invariant.
    macro_rules! conv {
        ($t:ty) => {
            move |b| {
                if le {
                    <$t>::from_le_bytes(b)
                } else {
                    <$t>::from_be_bytes(b)
                }
            }
        };
    }
    Ok(match ty {
        NrrdType::UInt8 => VoxelData::U8(read_vec(r, count, |[b]: [u8; 1]| b)?),
        NrrdType::Int8 => VoxelData::I8(read_vec(r, count, |b: [u8; 1]| i8::from_le_bytes(b))?),
        NrrdType::UInt16 => VoxelData::U16(read_vec(r, count, conv!(u16))?),
        NrrdType::Int16 => VoxelData::I16(read_vec(r, count, conv!(i16))?),
        NrrdType::Float => VoxelData::F32(read_vec(r, count, conv!(f32))?),
        NrrdType::UInt32 => {
            let c = conv!(u32);
            VoxelData::F32(read_vec(r, count, move |b| c(b) as f32)?)
        }
        NrrdType::Int32 => {
            let c = conv!(i32);
            VoxelData::F32(read_vec(r, count, move |b| c(b) as f32)?)
        }
        NrrdType::UInt64 => {
            let c = conv!(u64);
            VoxelData::F32(read_vec(r, count, move |b| c(b) as f32)?)
        }
        NrrdType::Int64 => {
            let c = conv!(i64);
            VoxelData::F32(read_vec(r, count, move |b| c(b) as f32)?)
        }
        NrrdType::Double => {
            let c = conv!(f64);
            VoxelData::F32(read_vec(r, count, move |b| c(b) as f32)?)
        }
    })
}

fn read_vec<R: Read, T, const N: usize>(
    r: &mut R,
    count: usize,
    conv: impl Fn([u8; N]) -> T,
) -> Result<Vec<T>, ReadFail> {
    let mut out = Vec::new();
    out.try_reserve_exact(count)
        .map_err(|_| ReadFail::Alloc((count as u64).saturating_mul(size_of::<T>() as u64)))?;
    let mut buf = vec![0u8; CHUNK_VALUES.min(count) * N];
    let mut remaining = count;
    let mut total: u64 = 0;
    let all = (count as u64).saturating_mul(N as u64);
    while remaining > 0 {
        if !super::report_progress(total, all) {
            return Err(ReadFail::Io(io::Error::new(
                io::ErrorKind::Interrupted,
                "cancelled",
            )));
        }
        let want = remaining.min(CHUNK_VALUES) * N;
        let got = read_fully(r, &mut buf[..want]).map_err(ReadFail::Io)?;
        total += got as u64;
        let (samples, _) = buf[..got].as_chunks::<N>();
        out.extend(samples.iter().map(|&b| conv(b)));
        if got < want {
            return Err(ReadFail::Short(total));
        }
        remaining -= want / N;
    }
    Ok(out)
}

/// Reads until `buf` is full or the reader ends; returns the bytes read.
pub(crate) fn read_fully<R: Read + ?Sized>(r: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match r.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}
