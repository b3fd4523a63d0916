//! Volume loading: NRRD files (attached or detached headers, raw or gzip data),
//! headerless raw files, and an embedded demo volume.
//!
//! # Conventions
//!
//! - **Layout.** Voxels are stored x fastest, then y, then z: the value of voxel
//!   `(x, y, z)` starts at index `(x + dims[0] * (y + dims[1] * z)) * components`.
//!   Vector volumes (2 or 3 components) are interleaved, so the components of one
//!   voxel are adjacent (NRRD axis 0 is the component axis).
//! - **Spacing.** `spacing[a]` is the world-space size of one voxel along axis `a`
//!   (x, y, z), always finite and positive; it defaults to 1 when a file does not
//!   record it. For NRRD `space directions` it is the length of each axis vector
//!   (the orientation itself is not kept).
//! - **Scalar.** Every volume has one scalar per voxel: component 0 for scalar
//!   volumes, the Euclidean magnitude of the components for vector volumes. It is
//!   in raw data units and may be NaN or ±Inf for float data.
//! - **Range and histogram.** [`Volume::range`] is the minimum and maximum of the
//!   *finite* scalars (`[0, 0]` when none is finite) and [`Volume::histogram`] has
//!   [`HISTOGRAM_BINS`] equal bins over that range, also counting finite scalars
//!   only. Non-finite scalars are counted in [`Volume::non_finite`].
//! - **Normalised scalars.** [`Volume::normalized_scalars`] maps the scalar to
//!   `[0, 1]` with the range: `(s - min) / (max - min)`, clamped. NaN and -Inf map
//!   to 0, +Inf to 1, and everything maps to 0 when the range is degenerate
//!   (`max <= min`). This is what the renderer uploads as its scalar texture.
//! - **Limits.** Nothing is allocated for a volume with more than [`MAX_VOXELS`]
//!   voxels or whose data (on disk or in memory) exceeds [`MAX_BYTES`]. For raw
//!   data the file length is checked against the layout before any allocation.
//!
//! # Types
//!
//! In-memory samples are one of [`ScalarType`]. NRRD files may also hold 32- and
//! 64-bit integers and doubles: those are converted to `f32` on load (integers of
//! magnitude above 2^24 lose precision, doubles outside the `f32` range become
//! ±Inf and are then counted as non-finite).

mod demo;
pub mod dicom;
mod metaimage;
pub mod nifti;
mod nrrd;
pub mod orient;
pub mod phantom;
mod raw;
#[cfg(test)]
mod tests;
pub mod tiff;
pub mod zarr;

use std::fmt;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub use demo::{DEMO_SOURCE_PATH, demo};
pub use nrrd::{
    ByteSkip, NrrdEncoding, NrrdHeader, NrrdType, load_nrrd, load_nrrd_bytes, parse_nrrd_header,
};
pub use raw::{RawDesc, load_raw};

/// The largest number of voxels (product of the three dims) a volume may have.
pub const MAX_VOXELS: u64 = 1 << 31;

/// The largest size in bytes of a volume's data, on disk or in memory (16 GiB).
pub const MAX_BYTES: u64 = 16 << 30;

/// Number of bins of [`Volume::histogram`].
pub const HISTOGRAM_BINS: usize = 256;

/// The type of the samples held in memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ScalarType {
    U8,
    I8,
    U16,
    I16,
    F32,
}

impl ScalarType {
    /// Size of one sample in bytes.
    pub fn size_bytes(self) -> usize {
        match self {
            ScalarType::U8 | ScalarType::I8 => 1,
            ScalarType::U16 | ScalarType::I16 => 2,
            ScalarType::F32 => 4,
        }
    }

    /// Lower-case name as used in NRRD headers and file names (`uint8`, `float32`, ...).
    pub fn name(self) -> &'static str {
        match self {
            ScalarType::U8 => "uint8",
            ScalarType::I8 => "int8",
            ScalarType::U16 => "uint16",
            ScalarType::I16 => "int16",
            ScalarType::F32 => "float32",
        }
    }
}

impl fmt::Display for ScalarType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Byte order of multi-byte samples in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Endian {
    Little,
    Big,
}

impl Endian {
    /// `"little"` or `"big"`, as in NRRD headers.
    pub fn name(self) -> &'static str {
        match self {
            Endian::Little => "little",
            Endian::Big => "big",
        }
    }
}

/// Voxel samples: interleaved components, x fastest, then y, then z.
#[derive(Clone, PartialEq)]
pub enum VoxelData {
    U8(Vec<u8>),
    I8(Vec<i8>),
    U16(Vec<u16>),
    I16(Vec<i16>),
    F32(Vec<f32>),
}

/// Runs `$body` with `$v` bound to the typed vector of a [`VoxelData`].
macro_rules! with_samples {
    ($data:expr, $v:ident => $body:expr) => {
        match $data {
            VoxelData::U8($v) => $body,
            VoxelData::I8($v) => $body,
            VoxelData::U16($v) => $body,
            VoxelData::I16($v) => $body,
            VoxelData::F32($v) => $body,
        }
    };
}

impl VoxelData {
    /// Number of samples (voxels times components).
    pub fn len(&self) -> usize {
        with_samples!(self, v => v.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn scalar_type(&self) -> ScalarType {
        match self {
            VoxelData::U8(_) => ScalarType::U8,
            VoxelData::I8(_) => ScalarType::I8,
            VoxelData::U16(_) => ScalarType::U16,
            VoxelData::I16(_) => ScalarType::I16,
            VoxelData::F32(_) => ScalarType::F32,
        }
    }

    /// Sample `i` converted to f64, if it exists.
    pub fn get_f64(&self, i: usize) -> Option<f64> {
        with_samples!(self, v => v.get(i).map(|&s| f64::from(s)))
    }
}

/// Summarises instead of printing every sample.
impl fmt::Debug for VoxelData {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "VoxelData::{:?}([..; {}])",
            self.scalar_type(),
            self.len()
        )
    }
}

/// A loaded volume with its scalar statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct Volume {
    /// File stem of the source, or `"demo"`.
    pub name: String,
    pub dims: [u32; 3],
    /// 1 for a scalar volume, 2 or 3 for a vector volume.
    pub components: u32,
    /// World size of a voxel along x, y, z (finite, positive; 1 when unknown).
    pub spacing: [f64; 3],
    pub data: VoxelData,
    /// Min and max of the finite scalars; `[0, 0]` when none is finite.
    pub range: [f64; 2],
    /// [`HISTOGRAM_BINS`] bins over `range` of the finite scalars.
    pub histogram: Vec<u64>,
    /// Number of voxels whose scalar is NaN or ±Inf.
    pub non_finite: u64,
    /// The file the volume was loaded from (the header for detached NRRD).
    pub source: Option<PathBuf>,
    /// What the loader did beyond reading samples (orientation applied, scaling, the
    /// first volume of a series taken), for `vwb info --volume` and the window.
    pub notes: Vec<String>,
    /// The source's stored levels of detail (OME-Zarr multiscales) and which one this
    /// volume holds; the renderer reads a coarser one under a GPU memory budget.
    pub pyramid: Option<zarr::Pyramid>,
}

impl Volume {
    /// Builds a volume from its samples and computes range, histogram and the
    /// non-finite count (in parallel).
    ///
    /// Fails when a dim is zero, the layout exceeds [`MAX_VOXELS`] / [`MAX_BYTES`],
    /// `components` is not 1, 2 or 3, a spacing is not finite and positive, or
    /// `data` does not hold exactly `dims product * components` samples.
    pub fn new(
        name: impl Into<String>,
        dims: [u32; 3],
        components: u32,
        spacing: [f64; 3],
        data: VoxelData,
    ) -> Result<Volume, VolumeError> {
        let name = name.into();
        let layout = check_layout(
            dims.map(u64::from),
            u64::from(components),
            data.scalar_type().size_bytes() as u64,
            None,
        )?;
        check_spacing(spacing, None)?;
        if data.len() != layout.values {
            return Err(VolumeError::Invalid {
                file: None,
                message: format!(
                    "volume '{name}': data has {} samples but {} needs {}",
                    data.len(),
                    layout_desc(
                        dims.map(u64::from),
                        u64::from(components),
                        data.scalar_type().name()
                    ),
                    layout.values
                ),
            });
        }
        let stats = compute_stats(&data, components as usize);
        Ok(Volume {
            name,
            dims,
            components,
            spacing,
            data,
            range: stats.range,
            histogram: stats.histogram,
            non_finite: stats.non_finite,
            source: None,
            notes: Vec::new(),
            pyramid: None,
        })
    }

    /// Number of voxels (product of the dims).
    pub fn voxel_count(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }

    pub fn scalar_type(&self) -> ScalarType {
        self.data.scalar_type()
    }

    /// The scalar of voxel `(x, y, z)` (component 0, or the magnitude of a vector)
    /// in raw data units; NaN or ±Inf possible for float data.
    ///
    /// # Panics
    /// When the voxel is outside the volume; see [`Volume::try_scalar`].
    pub fn scalar(&self, x: u32, y: u32, z: u32) -> f64 {
        self.try_scalar(x, y, z).unwrap_or_else(|| {
            panic!(
                "voxel ({x}, {y}, {z}) is outside the volume {}x{}x{}",
                self.dims[0], self.dims[1], self.dims[2]
            )
        })
    }

    /// Like [`Volume::scalar`], `None` outside the volume.
    pub fn try_scalar(&self, x: u32, y: u32, z: u32) -> Option<f64> {
        let [dx, dy, dz] = self.dims;
        if x >= dx || y >= dy || z >= dz {
            return None;
        }
        let c = self.components as usize;
        let voxel = x as usize + dx as usize * (y as usize + dy as usize * z as usize);
        let start = voxel * c;
        with_samples!(&self.data, v => v.get(start..start + c).map(voxel_scalar))
    }

    /// The scalars mapped to `[0, 1]` with [`Volume::range`] (see the module
    /// docs), one per voxel, x fastest. Always finite.
    pub fn normalized_scalars(&self) -> Vec<f32> {
        let c = self.components.max(1) as usize;
        let [lo, hi] = self.range;
        with_samples!(&self.data, v => v
            .par_chunks_exact(c)
            .map(|voxel| normalize(voxel_scalar(voxel), lo, hi))
            .collect())
    }

    /// All components as f32 (interleaved, x fastest) with non-finite samples
    /// replaced by 0, for uploading vector fields.
    pub fn components_f32(&self) -> Vec<f32> {
        with_samples!(&self.data, v => v
            .par_iter()
            .map(|&s| {
                let s = f64::from(s) as f32;
                if s.is_finite() { s } else { 0.0 }
            })
            .collect())
    }

    /// Size of the sample data in bytes.
    pub fn size_bytes(&self) -> usize {
        self.data.len() * self.scalar_type().size_bytes()
    }

    /// This volume physically cropped to the voxels `keep` ([start, end) per axis):
    /// every other voxel is removed, set to the lowest scalar of the volume (a vector
    /// to zero). The value range stays the volume's, so a transfer function maps both
    /// alike; the histogram counts the cropped voxels over it. What a clipped render is
    /// compared with (experiment variants' `crop`).
    pub fn cropped(&self, keep: [[u32; 2]; 3]) -> Result<Volume, VolumeError> {
        if (0..3).any(|a| keep[a][0] >= keep[a][1] || keep[a][1] > self.dims[a]) {
            return Err(VolumeError::Invalid {
                file: self.source.clone(),
                message: format!(
                    "volume '{}': crop {keep:?} must be non-empty and inside {:?}",
                    self.name, self.dims
                ),
            });
        }
        fn fill<T: Copy>(v: &mut [T], dims: [u32; 3], c: usize, keep: [[u32; 2]; 3], to: T) {
            let [w, h, _] = dims.map(|d| d as usize);
            for (i, voxel) in v.chunks_exact_mut(c).enumerate() {
                let at = [i % w, (i / w) % h, i / (w * h)];
                if (0..3).any(|a| at[a] < keep[a][0] as usize || at[a] >= keep[a][1] as usize) {
                    voxel.fill(to);
                }
            }
        }
        let c = self.components.max(1) as usize;
        let lo = if c == 1 { self.range[0] } else { 0.0 };
        let mut data = self.data.clone();
        match &mut data {
            VoxelData::U8(v) => fill(v, self.dims, c, keep, lo as u8),
            VoxelData::I8(v) => fill(v, self.dims, c, keep, lo as i8),
            VoxelData::U16(v) => fill(v, self.dims, c, keep, lo as u16),
            VoxelData::I16(v) => fill(v, self.dims, c, keep, lo as i16),
            VoxelData::F32(v) => fill(v, self.dims, c, keep, lo as f32),
        }
        let mut out = Volume::new(
            format!("{} cropped", self.name),
            self.dims,
            self.components,
            self.spacing,
            data,
        )?;
        out.histogram = with_samples!(&out.data, v => histogram_of(v, c, self.range));
        out.range = self.range;
        out.source = self.source.clone();
        out.notes = self.notes.clone();
        out.notes.push(format!("cropped to the voxels {keep:?}"));
        Ok(out)
    }

    /// The volume on a grid of `dims` voxels over the same box, by nearest neighbour:
    /// voxel i of the new grid takes the old voxel ⌊i · old / new⌋ along each axis, and
    /// the spacing scales so that the box stays. A copy of a data set at another scale,
    /// for studies that depend on the grid's size (the light paths of global
    /// illumination, the cost per voxel; `VolumeSource::Resampled`).
    pub fn resampled(&self, dims: [u32; 3]) -> Result<Volume, VolumeError> {
        fn pick<T: Copy>(v: &[T], from: [u32; 3], to: [u32; 3], c: usize) -> Vec<T> {
            let axis = |a: usize| -> Vec<usize> {
                (0..to[a])
                    .map(|i| (u64::from(i) * u64::from(from[a]) / u64::from(to[a])) as usize)
                    .collect()
            };
            let (xs, ys, zs) = (axis(0), axis(1), axis(2));
            let [w, h, _] = from.map(|d| d as usize);
            let mut out = Vec::with_capacity(xs.len() * ys.len() * zs.len() * c);
            for &z in &zs {
                for &y in &ys {
                    let row = (z * h + y) * w;
                    for &x in &xs {
                        let i = (row + x) * c;
                        out.extend_from_slice(&v[i..i + c]);
                    }
                }
            }
            out
        }
        if dims.contains(&0) {
            return Err(VolumeError::Invalid {
                file: self.source.clone(),
                message: format!("volume '{}': cannot resample to {dims:?}", self.name),
            });
        }
        let c = self.components.max(1) as usize;
        let data = match &self.data {
            VoxelData::U8(v) => VoxelData::U8(pick(v, self.dims, dims, c)),
            VoxelData::I8(v) => VoxelData::I8(pick(v, self.dims, dims, c)),
            VoxelData::U16(v) => VoxelData::U16(pick(v, self.dims, dims, c)),
            VoxelData::I16(v) => VoxelData::I16(pick(v, self.dims, dims, c)),
            VoxelData::F32(v) => VoxelData::F32(pick(v, self.dims, dims, c)),
        };
        let spacing =
            std::array::from_fn(|a| self.spacing[a] * f64::from(self.dims[a]) / f64::from(dims[a]));
        let [x, y, z] = dims;
        let mut out = Volume::new(
            format!("{}_{x}x{y}x{z}", self.name),
            dims,
            self.components,
            spacing,
            data,
        )?;
        out.source = self.source.clone();
        out.notes = self.notes.clone();
        out.notes.push(format!(
            "resampled from {:?} to {dims:?} voxels (nearest neighbour)",
            self.dims
        ));
        Ok(out)
    }
}

/// Everything that can go wrong while loading or building a volume. The message
/// names the file (when there is one) and the cause.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VolumeError {
    /// Opening, reading or seeking a file failed. The cause is part of the message
    /// (not a `source`), so that error chains print it once.
    #[error("{}: {context}: {cause}", .file.display())]
    Io {
        file: PathBuf,
        context: String,
        cause: std::io::Error,
    },

    /// [`load`] was given a file without the NRRD magic.
    #[error(
        "{}: not an NRRD file (it does not start with \"NRRD000\"); headerless raw data \
         does not record its layout: describe it with a detached NRRD header (.nhdr) whose \
         'data file:' names it, with its sizes, type and endianness",
        .file.display()
    )]
    NotNrrd { file: PathBuf },

    /// A format vwb recognises but does not read (NIfTI), or a file that is not a
    /// regular file where one is needed.
    #[error("{}: {message}", .file.display())]
    Unsupported { file: PathBuf, message: String },

    /// The NRRD header is malformed, incomplete or asks for something unsupported.
    #[error("{}{}: {message}", file_prefix(.file), header_location(*.line))]
    Header {
        file: Option<PathBuf>,
        /// 1-based header line, when the problem belongs to one line.
        line: Option<usize>,
        message: String,
    },

    /// The dims overflow or exceed [`MAX_VOXELS`] / [`MAX_BYTES`].
    #[error("{}dims {} {reason}", file_prefix(.file), dims_text(.dims))]
    TooLarge {
        file: Option<PathBuf>,
        dims: [u64; 3],
        reason: String,
    },

    /// A raw data file is shorter than the layout needs (or, for [`load_raw`], not
    /// exactly as long).
    #[error(
        "{}: file has {file_len} bytes but {needed_by} needs {needed} ({layout}){}",
        .file.display(),
        skip_note(*.skip)
    )]
    DataSize {
        file: PathBuf,
        file_len: u64,
        /// Bytes before the data (attached header, line and byte skips).
        skip: u64,
        needed: u64,
        /// `"the header"` or `"the raw description"`.
        needed_by: &'static str,
        /// Dims and type, e.g. `256x256x108 int16`.
        layout: String,
    },

    /// Gzip data is corrupt, too short or too long.
    #[error("{}: {message}", .file.display())]
    Compressed { file: PathBuf, message: String },

    /// The sample buffer could not be allocated.
    #[error("{}cannot allocate {bytes} bytes for the voxel data", file_prefix(.file))]
    OutOfMemory { file: Option<PathBuf>, bytes: u64 },

    /// Invalid arguments (a raw description, the parts given to [`Volume::new`]),
    /// or data that does not fit its description in a way not covered above.
    #[error("{}{message}", file_prefix(.file))]
    Invalid {
        file: Option<PathBuf>,
        message: String,
    },
}

impl VolumeError {
    /// The file the error is about, if any.
    pub fn file(&self) -> Option<&Path> {
        match self {
            VolumeError::Io { file, .. }
            | VolumeError::NotNrrd { file }
            | VolumeError::Unsupported { file, .. }
            | VolumeError::DataSize { file, .. }
            | VolumeError::Compressed { file, .. } => Some(file),
            VolumeError::Header { file, .. }
            | VolumeError::TooLarge { file, .. }
            | VolumeError::OutOfMemory { file, .. }
            | VolumeError::Invalid { file, .. } => file.as_deref(),
        }
    }

    /// Sets the file of an error that has none yet.
    pub(crate) fn in_file(mut self, path: &Path) -> Self {
        if let VolumeError::Header { file, .. }
        | VolumeError::TooLarge { file, .. }
        | VolumeError::OutOfMemory { file, .. }
        | VolumeError::Invalid { file, .. } = &mut self
        {
            file.get_or_insert_with(|| path.to_path_buf());
        }
        self
    }
}

fn file_prefix(file: &Option<PathBuf>) -> String {
    match file {
        Some(f) => format!("{}: ", f.display()),
        None => String::new(),
    }
}

fn header_location(line: Option<usize>) -> String {
    match line {
        Some(l) => format!("header line {l}"),
        None => "header".to_owned(),
    }
}

fn dims_text(dims: &[u64; 3]) -> String {
    format!("{}x{}x{}", dims[0], dims[1], dims[2])
}

fn skip_note(skip: u64) -> String {
    if skip == 0 {
        String::new()
    } else {
        format!(" after skipping the first {skip} bytes")
    }
}

/// Loads a volume, recognising the format by content. Only NRRD (magic
/// `NRRD000x`) is self-describing; headerless raw data must go through
/// [`load_raw`]. The path is opened once, so pipes (`--volume <(cat x.nrrd)`) and
/// FIFOs are read as streams; a FIFO nobody writes to gives an error, not a hang.
pub fn load(path: &Path) -> Result<Volume, VolumeError> {
    if zarr::is_zarr(path) {
        return zarr::load(path);
    }
    if path.is_dir() && !tiff::folder_pages(path).is_empty() {
        return tiff::load(path);
    }
    if path.is_dir() && !dicom::folder_files(path).is_empty() {
        return dicom::load(path);
    }
    let input = nrrd::Input::open(path)?;
    let head = input
        .head(348)
        .map_err(|e| raw::io_error(path, "cannot read", e))?;
    if head.starts_with(b"NRRD000") {
        return nrrd::load_input(input, path);
    }
    let regular = std::fs::metadata(path).is_ok_and(|m| m.is_file());
    if dicom::is_dicom(&head) && regular {
        return dicom::load(path);
    }
    if nifti::is_nifti(&head) {
        if !regular {
            return Err(VolumeError::Unsupported {
                file: path.to_path_buf(),
                message: "a NIfTI stream: vwb reads NIfTI from regular files".to_owned(),
            });
        }
        return nifti::load(path, false);
    }
    if head.starts_with(&[0x1f, 0x8b]) && regular {
        // a gzip-compressed file: NIfTI (.nii.gz) is the one format stored that way
        let mut inner = Vec::new();
        let f = std::fs::File::open(path).map_err(|e| raw::io_error(path, "cannot open", e))?;
        std::io::Read::read_to_end(
            &mut std::io::Read::take(flate2::read::MultiGzDecoder::new(f), 540),
            &mut inner,
        )
        .map_err(|e| VolumeError::Compressed {
            file: path.to_path_buf(),
            message: format!("not a readable gzip stream: {e}"),
        })?;
        if nifti::is_nifti(&inner) {
            return nifti::load(path, true);
        }
        return Err(VolumeError::Unsupported {
            file: path.to_path_buf(),
            message: "a gzip-compressed file that is not NIfTI (.nii.gz); vwb reads NRRD (gzip \
                      encoding inside), NIfTI and MetaImage"
                .to_owned(),
        });
    }
    if metaimage::is_metaimage(path, &head) {
        return metaimage::load(path);
    }
    if tiff::is_tiff(&head) && regular {
        return tiff::load(path);
    }
    Err(VolumeError::NotNrrd {
        file: path.to_path_buf(),
    })
}

/// [`load`], for a renderer with the GPU memory budget `budget`: an OME-Zarr image
/// whose full level would not fit reads only its finest stored level that takes at
/// most half the budget in 16-bit texels (what the renderer stores under a budget;
/// [`zarr::load_within`]), so a volume larger than memory shows at once. Other
/// formats, and no budget, load as [`load`] does (the renderer averages them down).
pub fn load_for_budget(path: &Path, budget: Option<u64>) -> Result<Volume, VolumeError> {
    match budget {
        Some(b) if zarr::is_zarr(path) => zarr::load_within(path, Some(b / 2), 2),
        _ => load(path),
    }
}

/// Progress of a volume load, shared with the thread that runs it: bytes of samples
/// decoded so far and in all, and a cancel request (checked between chunks).
#[derive(Debug, Default)]
pub struct LoadProgress {
    pub done: std::sync::atomic::AtomicU64,
    pub total: std::sync::atomic::AtomicU64,
    pub cancel: std::sync::atomic::AtomicBool,
}

impl LoadProgress {
    /// Share of the samples decoded, in [0, 1].
    pub fn fraction(&self) -> f32 {
        use std::sync::atomic::Ordering::Relaxed;
        let total = self.total.load(Relaxed);
        if total == 0 {
            0.0
        } else {
            (self.done.load(Relaxed) as f64 / total as f64).min(1.0) as f32
        }
    }
}

thread_local! {
    /// The progress of the load running on this thread, if one was asked for.
    static PROGRESS: std::cell::RefCell<Option<std::sync::Arc<LoadProgress>>> =
        const { std::cell::RefCell::new(None) };
}

/// [`load`], reporting progress to `progress` and stopping with an error once
/// `progress.cancel` is set.
pub fn load_with_progress(
    path: &Path,
    progress: std::sync::Arc<LoadProgress>,
) -> Result<Volume, VolumeError> {
    with_progress(progress, || load(path))
}

/// Runs `load` (any loader of this module) reporting progress to `progress` and
/// stopping with an error once `progress.cancel` is set.
pub fn with_progress<T>(progress: std::sync::Arc<LoadProgress>, load: impl FnOnce() -> T) -> T {
    PROGRESS.with(|p| *p.borrow_mut() = Some(progress));
    let result = load();
    PROGRESS.with(|p| *p.borrow_mut() = None);
    result
}

/// Reports decoded bytes to this thread's load progress; `false` when cancelled.
pub(crate) fn report_progress(done: u64, total: u64) -> bool {
    use std::sync::atomic::Ordering::Relaxed;
    PROGRESS.with(|p| match &*p.borrow() {
        Some(p) => {
            p.total.store(total, Relaxed);
            p.done.store(done, Relaxed);
            !p.cancel.load(Relaxed)
        }
        None => true,
    })
}

/// The files a volume path reads (for checks that an output never overwrites an
/// input, and for the size of a load): the path itself and, for a detached NRRD
/// header, its data file; for a folder, its TIFF pages or DICOM files; for a DICOM
/// file, the DICOM files beside it (its series is among them); for an OME-Zarr
/// store, every file in it (all levels: a load reads one). Unreadable or
/// non-regular files list only themselves.
pub fn input_files(path: &Path) -> Vec<PathBuf> {
    if zarr::is_zarr(path) {
        return zarr::files(path);
    }
    if path.is_dir() {
        let pages = tiff::folder_pages(path);
        return if pages.is_empty() {
            dicom::folder_files(path)
        } else {
            pages
        };
    }
    let mut files = vec![path.to_path_buf()];
    if let Some(data) = nrrd::detached_data_file(path) {
        files.push(data);
    } else if dicom::is_dicom_file(path)
        && let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
    {
        files.extend(dicom::folder_files(dir).into_iter().filter(|f| f != path));
    }
    files
}

/// The memory a volume may take: `MemAvailable` of `/proc/meminfo` (Linux), or the
/// `VWB_MEMORY_LIMIT` environment variable (bytes) when set; `None` when unknown.
pub fn available_memory() -> Option<u64> {
    if let Some(v) = std::env::var_os("VWB_MEMORY_LIMIT") {
        return v.to_str().and_then(|s| s.trim().parse().ok());
    }
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    meminfo_available(&text)
}

/// `MemAvailable` of `/proc/meminfo` text, in bytes.
fn meminfo_available(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// A checked volume layout.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Layout {
    pub dims: [u32; 3],
    pub components: u32,
    /// Number of samples (voxels times components).
    pub values: usize,
}

/// Checks dims and components against the limits without allocating anything.
/// `bytes_per_value` is the largest size of one sample (on disk or in memory).
pub(crate) fn check_layout(
    dims: [u64; 3],
    components: u64,
    bytes_per_value: u64,
    file: Option<&Path>,
) -> Result<Layout, VolumeError> {
    let file = file.map(Path::to_path_buf);
    let too_large = |reason: String| VolumeError::TooLarge {
        file: file.clone(),
        dims,
        reason,
    };
    if dims.contains(&0) {
        return Err(VolumeError::Invalid {
            file: file.clone(),
            message: format!("dims {}: every size must be at least 1", dims_text(&dims)),
        });
    }
    if !(1..=3).contains(&components) {
        return Err(VolumeError::Invalid {
            file: file.clone(),
            message: format!(
                "{components} components per voxel: only 1 (scalar), 2 or 3 (vector) are supported"
            ),
        });
    }
    let voxels = dims
        .iter()
        .try_fold(1u64, |acc, &d| acc.checked_mul(d))
        .ok_or_else(|| too_large("overflow the voxel count".to_owned()))?;
    if voxels > MAX_VOXELS {
        return Err(too_large(format!(
            "hold {voxels} voxels, above the limit of {MAX_VOXELS} voxels"
        )));
    }
    let values = voxels * components;
    let bytes = values
        .checked_mul(bytes_per_value)
        .ok_or_else(|| too_large("overflow the byte count".to_owned()))?;
    if bytes > MAX_BYTES {
        return Err(too_large(format!(
            "with {components} component(s) of {bytes_per_value} bytes need {bytes} bytes, \
             above the limit of {MAX_BYTES} bytes (16 GiB)"
        )));
    }
    // in memory: the samples plus the normalised f32 scalars uploaded to the GPU
    let resident = bytes.saturating_add(voxels.saturating_mul(4));
    if let Some(available) = available_memory()
        && resident > available
    {
        return Err(too_large(format!(
            "need about {resident} bytes in memory ({bytes} for the samples, {} for the \
             scalars uploaded to the GPU), more than the {available} bytes this machine has \
             available",
            voxels * 4
        )));
    }
    let values = usize::try_from(values)
        .map_err(|_| too_large("do not fit in this platform's address space".to_owned()))?;
    // Each dim is <= MAX_VOXELS < u32::MAX here, so the conversions are exact.
    let dims32 = dims.map(|d| u32::try_from(d).unwrap_or(u32::MAX));
    Ok(Layout {
        dims: dims32,
        components: components as u32,
        values,
    })
}

/// The largest ratio between the voxel sizes of two axes. Slices are spaced in units
/// of the smallest voxel, so a larger ratio asks for millions of slices along the
/// long axes; real scans stay far below it.
pub const MAX_SPACING_RATIO: f64 = 1000.0;

/// Checks that every spacing is finite and positive, within 1e-12..=1e12 and within
/// [`MAX_SPACING_RATIO`] of the others.
pub(crate) fn check_spacing(spacing: [f64; 3], file: Option<&Path>) -> Result<(), VolumeError> {
    match spacing_problem(spacing) {
        None => Ok(()),
        Some(message) => Err(VolumeError::Invalid {
            file: file.map(Path::to_path_buf),
            message,
        }),
    }
}

/// What is wrong with a spacing (see [`check_spacing`]), if anything.
pub(crate) fn spacing_problem(spacing: [f64; 3]) -> Option<String> {
    if !spacing.iter().all(|s| s.is_finite() && *s > 0.0) {
        return Some(format!(
            "spacing {spacing:?}: every spacing must be finite and greater than 0"
        ));
    }
    if !spacing.iter().all(|s| (1e-12..=1e12).contains(s)) {
        return Some(format!(
            "spacing {spacing:?}: every voxel size must lie within 1e-12..=1e12 (the spacings \
             or space directions are probably in the wrong unit or corrupt)"
        ));
    }
    let lo = spacing.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = spacing.iter().copied().fold(0.0, f64::max);
    (hi / lo > MAX_SPACING_RATIO).then(|| {
        format!(
            "spacing {spacing:?}: voxels are {:.3e} times longer along one axis than along \
             another (at most {MAX_SPACING_RATIO} is accepted; slices are spaced by the \
             smallest voxel, so this would need billions of slices); the spacings or space \
             directions are probably wrong",
            hi / lo
        )
    })
}

/// Human description of a layout, e.g. `256x256x108 int16` or `128x64x14 x2 float32`.
pub(crate) fn layout_desc(dims: [u64; 3], components: u64, type_name: &str) -> String {
    if components == 1 {
        format!("{} {type_name}", dims_text(&dims))
    } else {
        format!("{} x{components} {type_name}", dims_text(&dims))
    }
}

/// Volume name from a path: its file stem, or the whole file name.
pub(crate) fn name_from_path(path: &Path) -> String {
    path.file_stem()
        .or_else(|| path.file_name())
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "volume".to_owned())
}

/// The scalar of one voxel: component 0, or the Euclidean magnitude.
fn voxel_scalar<T: Copy + Into<f64>>(voxel: &[T]) -> f64 {
    match voxel {
        [s] => (*s).into(),
        _ => voxel
            .iter()
            .map(|&s| {
                let s: f64 = s.into();
                s * s
            })
            .sum::<f64>()
            .sqrt(),
    }
}

/// Maps a scalar to `[0, 1]` with the finite range `[lo, hi]`.
fn normalize(s: f64, lo: f64, hi: f64) -> f32 {
    if s.is_nan() || s == f64::NEG_INFINITY {
        0.0
    } else if s == f64::INFINITY {
        1.0
    } else if hi > lo {
        ((s - lo) / (hi - lo)).clamp(0.0, 1.0) as f32
    } else {
        0.0
    }
}

/// The histogram bin of a scalar over `lo`…`hi` ([`Volume::histogram`]), `None` for
/// non-finite ones.
pub fn histogram_bin(s: f64, lo: f64, hi: f64) -> Option<usize> {
    if !s.is_finite() {
        return None;
    }
    if hi <= lo {
        return Some(0);
    }
    // `as` saturates, so rounding past either end stays in range.
    let bin = ((s - lo) / (hi - lo) * HISTOGRAM_BINS as f64) as usize;
    Some(bin.min(HISTOGRAM_BINS - 1))
}

struct Stats {
    range: [f64; 2],
    histogram: Vec<u64>,
    non_finite: u64,
}

fn compute_stats(data: &VoxelData, components: usize) -> Stats {
    with_samples!(data, v => stats_of(v, components.max(1)))
}

fn stats_of<T: Copy + Into<f64> + Sync>(samples: &[T], components: usize) -> Stats {
    let (lo, hi, non_finite) = samples
        .par_chunks_exact(components)
        .map(voxel_scalar)
        .fold(
            || (f64::INFINITY, f64::NEG_INFINITY, 0u64),
            |(lo, hi, n), s| {
                if s.is_finite() {
                    (lo.min(s), hi.max(s), n)
                } else {
                    (lo, hi, n + 1)
                }
            },
        )
        .reduce(
            || (f64::INFINITY, f64::NEG_INFINITY, 0u64),
            |a, b| (a.0.min(b.0), a.1.max(b.1), a.2 + b.2),
        );
    let range = if lo <= hi { [lo, hi] } else { [0.0, 0.0] };
    Stats {
        range,
        histogram: histogram_of(samples, components, range),
        non_finite,
    }
}

/// [`HISTOGRAM_BINS`] bins over `range` of the finite scalars of `samples`.
fn histogram_of<T: Copy + Into<f64> + Sync>(
    samples: &[T],
    components: usize,
    range: [f64; 2],
) -> Vec<u64> {
    samples
        .par_chunks_exact(components)
        .fold(
            || vec![0u64; HISTOGRAM_BINS],
            |mut h, voxel| {
                if let Some(bin) = histogram_bin(voxel_scalar(voxel), range[0], range[1]) {
                    h[bin] += 1;
                }
                h
            },
        )
        .reduce(
            || vec![0u64; HISTOGRAM_BINS],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                a
            },
        )
}
