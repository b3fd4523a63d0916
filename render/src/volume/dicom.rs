//! DICOM series through dicom-rs (`dicom-object` reads the files, `dicom-pixeldata`
//! decodes the pixel data).
//!
//! - **What is a volume.** A folder: its DICOM files (any name; told by the `DICM` magic
//!   at byte 128), grouped by SeriesInstanceUID; the series with the most slices loads
//!   and a note names the others. A file: the series it belongs to, from the files
//!   beside it (a multi-frame file is a volume by itself). [`load_files`]: a list of
//!   files, one series.
//! - **Order and spacing.** Slices are sorted by ImagePositionPatient along the slice
//!   normal (ImageOrientationPatient's row × column direction), never by
//!   InstanceNumber. The z spacing is the mean distance between neighbours along the
//!   normal; x and y come from PixelSpacing (row spacing, then column spacing).
//!   *Unequal gaps* (any gap more than 1 % or 0.01 mm from the mean) and a *gantry tilt*
//!   (the line through the positions leaves the normal) are detected and reported in the
//!   volume's notes; the volume is shown on the mean spacing, unsheared, not resampled.
//!   Two slices at one position (several phases in one series) are refused, naming both
//!   files. Without positions the InstanceNumber order is used, with a note.
//! - **Multi-frame files** (enhanced CT/MR): frames are slices; positions, orientation
//!   and spacing come from the per-frame and shared functional groups where present,
//!   else from the top-level attributes.
//! - **Values.** RescaleSlope and RescaleIntercept are applied per slice. The samples
//!   keep an integer type where every rescaled value of the stored bit range fits (CT in
//!   Hounsfield units stays int16); otherwise they become f32. Stored bits beyond
//!   BitsStored are masked (unsigned) or sign-extended (signed).
//! - **Orientation.** DICOM's patient frame is LPS, so the row, column and normal
//!   directions snap to LPS through `orient.rs` like every other format: left stays left.
//! - **Transfer syntaxes**: what dicom-pixeldata's `native` feature decodes (implicit and
//!   explicit VR little endian, deflated, RLE lossless, JPEG baseline, extended and
//!   lossless). Others (JPEG 2000, JPEG-LS, JPEG XL) give an error naming the file and
//!   the syntax. Colour images (more than one sample per pixel) are refused.
//! - **Limits.** Before dicom-rs parses a file, every element length in it is checked
//!   against the bytes that remain, so a lying length fails before anything is
//!   allocated for it. The headers of all slices are read first (up to the pixel data)
//!   and the layout is checked against the memory budget before a pixel is decoded.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use dicom_core::value::{PixelFragmentSequence, Value};
use dicom_core::{DataElement, PrimitiveValue, Tag, VR};
use dicom_dictionary_std::{tags, uids};
use dicom_object::{DefaultDicomObject, FileMetaTableBuilder, InMemDicomObject, OpenFileOptions};
use dicom_pixeldata::PixelDecoder;
use dicom_transfer_syntax_registry::{TransferSyntaxIndex, TransferSyntaxRegistry};

use super::{Volume, VolumeError, VoxelData, check_layout, orient};

/// Whether `head` (the first 132 bytes or more of a file) carries the DICOM magic.
pub fn is_dicom(head: &[u8]) -> bool {
    head.len() >= 132 && &head[128..132] == b"DICM"
}

/// Whether the file at `path` is a regular file that starts like a DICOM file.
pub fn is_dicom_file(path: &Path) -> bool {
    // a pipe or FIFO is never opened here: reading it would consume or block
    if !path.metadata().is_ok_and(|m| m.is_file()) {
        return false;
    }
    let mut head = [0u8; 132];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && is_dicom(&head)
}

/// The DICOM files of a folder (by magic, whatever their names), in name order.
pub fn folder_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|it| {
            it.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| is_dicom_file(p))
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

fn invalid(file: &Path, message: impl Into<String>) -> VolumeError {
    VolumeError::Invalid {
        file: Some(file.to_path_buf()),
        message: message.into(),
    }
}

fn header_error(file: &Path, message: impl Into<String>) -> VolumeError {
    VolumeError::Header {
        file: Some(file.to_path_buf()),
        line: None,
        message: message.into(),
    }
}

/// Loads the series of a folder, or the series a file belongs to (see the module doc).
pub fn load(path: &Path) -> Result<Volume, VolumeError> {
    if path.is_dir() {
        let files = folder_files(path);
        if files.is_empty() {
            return Err(invalid(path, "the folder holds no DICOM file"));
        }
        return load_series(&files, path);
    }
    let first = read_header(path)?;
    let mut series = vec![first.clone()];
    if first.frames == 1 {
        // the series of `path`: its siblings with the same SeriesInstanceUID
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
        for f in dir.map(folder_files).unwrap_or_default() {
            if f != path
                && let Ok(h) = read_header(&f)
                && h.series == first.series
                && h.frames == 1
            {
                series.push(h);
            }
        }
    }
    from_headers(series, path)
}

/// Loads a list of files as one series (the largest series when they hold several).
pub fn load_files(files: &[PathBuf]) -> Result<Volume, VolumeError> {
    let Some(first) = files.first() else {
        return Err(VolumeError::Invalid {
            file: None,
            message: "no DICOM file given".into(),
        });
    };
    load_series(files, first)
}

/// What one file says before its pixel data.
#[derive(Debug, Clone)]
struct Header {
    file: PathBuf,
    series: String,
    description: String,
    transfer_syntax: String,
    rows: u32,
    cols: u32,
    frames: u32,
    bits_allocated: u16,
    bits_stored: u16,
    signed: bool,
    rescale: (f64, f64),
    instance: Option<i64>,
    /// ImagePositionPatient per frame (one for a single-frame file), when recorded.
    positions: Vec<Option<[f64; 3]>>,
    orientation: Option<[f64; 6]>,
    pixel_spacing: Option<[f64; 2]>,
    slice_spacing: Option<f64>,
}

fn element(obj: &InMemDicomObject, tag: Tag) -> Option<&dicom_object::mem::InMemElement> {
    obj.element_opt(tag).ok().flatten()
}

fn floats(obj: &InMemDicomObject, tag: Tag) -> Option<Vec<f64>> {
    element(obj, tag)?
        .to_multi_float64()
        .ok()
        .filter(|v| v.iter().all(|x| x.is_finite()))
}

fn int(obj: &InMemDicomObject, tag: Tag) -> Option<i64> {
    element(obj, tag)?.to_int::<i64>().ok()
}

fn text(obj: &InMemDicomObject, tag: Tag) -> String {
    element(obj, tag)
        .and_then(|e| e.to_str().ok())
        .map(|s| {
            s.trim_matches(|c: char| c == '\0' || c.is_whitespace())
                .to_string()
        })
        .unwrap_or_default()
}

/// The first item of a sequence attribute.
fn first_item(obj: &InMemDicomObject, tag: Tag) -> Option<&InMemDicomObject> {
    element(obj, tag)?.items()?.first()
}

/// An attribute at the top level or inside a functional-group macro sequence of the
/// shared functional groups (enhanced multi-frame objects).
fn shared_floats(obj: &InMemDicomObject, macro_seq: Tag, tag: Tag) -> Option<Vec<f64>> {
    floats(obj, tag).or_else(|| {
        let shared = first_item(obj, tags::SHARED_FUNCTIONAL_GROUPS_SEQUENCE)?;
        floats(first_item(shared, macro_seq)?, tag)
    })
}

fn read_header(path: &Path) -> Result<Header, VolumeError> {
    check_lengths(path)?;
    let obj: DefaultDicomObject = OpenFileOptions::new()
        .read_until(tags::PIXEL_DATA)
        .open_file(path)
        .map_err(|e| header_error(path, format!("not a readable DICOM file: {e}")))?;
    let transfer_syntax = obj
        .meta()
        .transfer_syntax()
        .trim_end_matches('\0')
        .to_string();
    let need = |tag: Tag, name: &str| {
        int(&obj, tag)
            .ok_or_else(|| header_error(path, format!("{name} {tag} is missing or not a number")))
    };
    let rows = need(tags::ROWS, "Rows")?;
    let cols = need(tags::COLUMNS, "Columns")?;
    let bits_allocated = need(tags::BITS_ALLOCATED, "BitsAllocated")?;
    let bits_stored = int(&obj, tags::BITS_STORED).unwrap_or(bits_allocated);
    let frames = int(&obj, tags::NUMBER_OF_FRAMES).unwrap_or(1);
    let samples = int(&obj, tags::SAMPLES_PER_PIXEL).unwrap_or(1);
    if !(1..=65535).contains(&rows) || !(1..=65535).contains(&cols) {
        return Err(header_error(
            path,
            format!("Rows {rows} × Columns {cols}: each must be 1 … 65535"),
        ));
    }
    if !(1..=1_000_000).contains(&frames) {
        return Err(header_error(
            path,
            format!("NumberOfFrames {frames} is not 1 … 1000000"),
        ));
    }
    if ![8, 16, 32].contains(&bits_allocated) {
        return Err(header_error(
            path,
            format!("BitsAllocated {bits_allocated}: vwb reads 8, 16 or 32 bits per sample"),
        ));
    }
    if !(1..=bits_allocated).contains(&bits_stored) {
        return Err(header_error(
            path,
            format!("BitsStored {bits_stored} is not 1 … BitsAllocated ({bits_allocated})"),
        ));
    }
    if samples != 1 {
        return Err(VolumeError::Unsupported {
            file: path.to_path_buf(),
            message: format!(
                "{samples} samples per pixel ({}): vwb reads grey-level (one sample) DICOM images",
                text(&obj, tags::PHOTOMETRIC_INTERPRETATION)
            ),
        });
    }
    let slope = shared_floats(
        &obj,
        tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE,
        tags::RESCALE_SLOPE,
    )
    .and_then(|v| v.first().copied())
    .unwrap_or(1.0);
    let intercept = shared_floats(
        &obj,
        tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE,
        tags::RESCALE_INTERCEPT,
    )
    .and_then(|v| v.first().copied())
    .unwrap_or(0.0);
    if slope == 0.0 {
        return Err(header_error(path, "RescaleSlope is 0"));
    }
    let triple = |v: Vec<f64>| <[f64; 3]>::try_from(v).ok();
    let positions = if frames > 1 {
        let per_frame = element(&obj, tags::PER_FRAME_FUNCTIONAL_GROUPS_SEQUENCE)
            .and_then(|e| e.items())
            .unwrap_or(&[]);
        if per_frame.len() == frames as usize {
            per_frame
                .iter()
                .map(|item| {
                    first_item(item, tags::PLANE_POSITION_SEQUENCE)
                        .and_then(|p| floats(p, tags::IMAGE_POSITION_PATIENT))
                        .and_then(triple)
                })
                .collect()
        } else {
            vec![None; frames as usize]
        }
    } else {
        vec![floats(&obj, tags::IMAGE_POSITION_PATIENT).and_then(triple)]
    };
    let orientation = shared_floats(
        &obj,
        tags::PLANE_ORIENTATION_SEQUENCE,
        tags::IMAGE_ORIENTATION_PATIENT,
    )
    .and_then(|v| <[f64; 6]>::try_from(v).ok());
    let pixel_spacing = shared_floats(&obj, tags::PIXEL_MEASURES_SEQUENCE, tags::PIXEL_SPACING)
        .and_then(|v| <[f64; 2]>::try_from(v).ok())
        .filter(|s| s.iter().all(|x| *x > 0.0));
    let slice_spacing = shared_floats(
        &obj,
        tags::PIXEL_MEASURES_SEQUENCE,
        tags::SPACING_BETWEEN_SLICES,
    )
    .or_else(|| shared_floats(&obj, tags::PIXEL_MEASURES_SEQUENCE, tags::SLICE_THICKNESS))
    .and_then(|v| v.first().copied())
    .filter(|s| *s > 0.0);
    Ok(Header {
        file: path.to_path_buf(),
        series: text(&obj, tags::SERIES_INSTANCE_UID),
        description: text(&obj, tags::SERIES_DESCRIPTION),
        transfer_syntax,
        rows: rows as u32,
        cols: cols as u32,
        frames: frames as u32,
        bits_allocated: bits_allocated as u16,
        bits_stored: bits_stored as u16,
        signed: int(&obj, tags::PIXEL_REPRESENTATION) == Some(1),
        rescale: (slope, intercept),
        instance: int(&obj, tags::INSTANCE_NUMBER),
        positions,
        orientation,
        pixel_spacing,
        slice_spacing,
    })
}

/// Walks the element headers of a DICOM file and refuses one whose defined length is
/// longer than the bytes left in the file, before dicom-rs allocates for it. Values of
/// defined length are skipped, undefined-length sequences and items are entered.
/// Deflated data sets are inflated by dicom-rs and not walked here.
/// The value representations of PS3.5 §6.2.
const VALID_VRS: [&[u8; 2]; 34] = [
    b"AE", b"AS", b"AT", b"CS", b"DA", b"DS", b"DT", b"FL", b"FD", b"IS", b"LO", b"LT", b"OB",
    b"OD", b"OF", b"OL", b"OV", b"OW", b"PN", b"SH", b"SL", b"SQ", b"SS", b"ST", b"SV", b"TM",
    b"UC", b"UI", b"UL", b"UN", b"UR", b"US", b"UT", b"UV",
];

fn check_lengths(path: &Path) -> Result<(), VolumeError> {
    let f = File::open(path).map_err(|e| super::raw::io_error(path, "cannot open", e))?;
    let len = f
        .metadata()
        .map_err(|e| super::raw::io_error(path, "cannot read the size of", e))?
        .len();
    let mut r = BufReader::new(f);
    let mut head = [0u8; 132];
    r.read_exact(&mut head)
        .map_err(|_| header_error(path, "shorter than a DICOM preamble (132 bytes)"))?;
    if !is_dicom(&head) {
        return Err(header_error(path, "no DICM magic at byte 128"));
    }
    let mut pos = 132u64;
    // the file meta group is explicit VR little endian; the data set follows the
    // transfer syntax it names
    let mut explicit = true;
    let mut big_endian = false;
    let mut in_meta = true;
    let mut syntax = String::new();
    let too_long = |tag: (u16, u16), at: u64, n: u64, left: u64| {
        header_error(
            path,
            format!(
                "element ({:04X},{:04X}) at byte {at} claims {n} bytes, but only {left} remain: \
                 a truncated or corrupt file",
                tag.0, tag.1
            ),
        )
    };
    loop {
        let mut t = [0u8; 4];
        match r.read_exact(&mut t) {
            Ok(()) => {}
            Err(_) if pos >= len => return Ok(()),
            Err(_) => {
                return Err(header_error(
                    path,
                    format!("the file ends inside an element header at byte {pos}"),
                ));
            }
        }
        let u16_at = |b: &[u8], be: bool| {
            if be {
                u16::from_be_bytes([b[0], b[1]])
            } else {
                u16::from_le_bytes([b[0], b[1]])
            }
        };
        let peek_group = u16::from_le_bytes([t[0], t[1]]);
        if in_meta && peek_group != 0x0002 {
            in_meta = false;
            match syntax.as_str() {
                uids::IMPLICIT_VR_LITTLE_ENDIAN => explicit = false,
                // explicit VR big endian (retired)
                "1.2.840.10008.1.2.2" => big_endian = true,
                uids::DEFLATED_EXPLICIT_VR_LITTLE_ENDIAN => return Ok(()),
                _ => {}
            }
        }
        let tag = (u16_at(&t[0..2], big_endian), u16_at(&t[2..4], big_endian));
        let at = pos;
        pos += 4;
        let mut word = [0u8; 4];
        let mut read4 = |r: &mut BufReader<File>, pos: &mut u64| {
            r.read_exact(&mut word).map_err(|_| {
                header_error(
                    path,
                    format!("the file ends inside an element header at byte {at}"),
                )
            })?;
            *pos += 4;
            Ok::<[u8; 4], VolumeError>(word)
        };
        let as_u32 = |w: [u8; 4]| {
            u64::from(if big_endian {
                u32::from_be_bytes(w)
            } else {
                u32::from_le_bytes(w)
            })
        };
        let length: u64 = if tag.0 == 0xFFFE || !explicit {
            as_u32(read4(&mut r, &mut pos)?)
        } else {
            let w = read4(&mut r, &mut pos)?;
            // an unknown VR makes the parser guess a length from other bytes (the
            // fuzzer found 4 GB allocations that way): refuse it here
            let vr = [w[0], w[1]];
            if !VALID_VRS.contains(&&vr) {
                return Err(header_error(
                    path,
                    format!(
                        "element ({:04X},{:04X}) at byte {at} has no valid value representation \
                         ({:?}): a corrupt file",
                        tag.0,
                        tag.1,
                        String::from_utf8_lossy(&vr)
                    ),
                ));
            }
            let long_vr = [
                b"OB", b"OD", b"OF", b"OL", b"OV", b"OW", b"SQ", b"UC", b"UR", b"UT", b"UN", b"SV",
                b"UV",
            ];
            if long_vr.contains(&&[w[0], w[1]]) {
                as_u32(read4(&mut r, &mut pos)?)
            } else {
                u64::from(u16_at(&w[2..4], big_endian))
            }
        };
        if length == 0xFFFF_FFFF || (tag.0 == 0xFFFE && tag.1 != 0xE000) {
            // an undefined length (enter it) or a delimiter (nothing follows)
            continue;
        }
        let left = len.saturating_sub(pos);
        if length > left {
            return Err(too_long(tag, at, length, left));
        }
        if tag == (0x0002, 0x0010) {
            let mut v = vec![0u8; length as usize];
            r.read_exact(&mut v)
                .map_err(|e| super::raw::io_error(path, "cannot read", e))?;
            syntax = String::from_utf8_lossy(&v)
                .trim_end_matches(['\0', ' '])
                .to_string();
        } else {
            r.seek_relative(length as i64)
                .map_err(|e| super::raw::io_error(path, "cannot seek in", e))?;
        }
        pos += length;
    }
}

/// One slice of the volume: a frame of a file.
#[derive(Debug, Clone)]
struct SliceRef {
    file: usize,
    frame: u32,
    position: Option<[f64; 3]>,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// The sample type the rescaled values are stored in.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Out {
    U8,
    I8,
    U16,
    I16,
    F32,
}

fn choose_type(headers: &[Header]) -> Out {
    let integral = headers
        .iter()
        .all(|h| h.rescale.0 == 1.0 && h.rescale.1.fract() == 0.0);
    if !integral {
        return Out::F32;
    }
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for h in headers {
        let b = i32::from(h.bits_stored);
        let (l, u) = if h.signed {
            (-(2f64.powi(b - 1)), 2f64.powi(b - 1) - 1.0)
        } else {
            (0.0, 2f64.powi(b) - 1.0)
        };
        lo = lo.min(l + h.rescale.1);
        hi = hi.max(u + h.rescale.1);
    }
    let eight = headers.iter().all(|h| h.bits_allocated == 8);
    let fits = |l: f64, u: f64| lo >= l && hi <= u;
    if eight && fits(0.0, 255.0) {
        Out::U8
    } else if eight && fits(-128.0, 127.0) {
        Out::I8
    } else if fits(-32768.0, 32767.0) {
        Out::I16
    } else if fits(0.0, 65535.0) {
        Out::U16
    } else {
        Out::F32
    }
}

/// The stored value of sample `i` of a native little-endian frame.
fn stored(bytes: &[u8], i: usize, bits_allocated: u16, bits_stored: u16, signed: bool) -> i64 {
    let raw: u64 = match bits_allocated {
        8 => u64::from(bytes[i]),
        16 => u64::from(u16::from_le_bytes([bytes[2 * i], bytes[2 * i + 1]])),
        _ => u64::from(u32::from_le_bytes([
            bytes[4 * i],
            bytes[4 * i + 1],
            bytes[4 * i + 2],
            bytes[4 * i + 3],
        ])),
    };
    let b = u32::from(bits_stored);
    if signed {
        let shift = 64 - b;
        ((raw << shift) as i64) >> shift
    } else {
        (raw & ((1u64 << b) - 1)) as i64
    }
}

fn load_series(files: &[PathBuf], origin: &Path) -> Result<Volume, VolumeError> {
    let headers = files
        .iter()
        .map(|f| read_header(f))
        .collect::<Result<Vec<_>, _>>()?;
    from_headers(headers, origin)
}

/// The volume of the largest series among `all` (headers already read).
fn from_headers(all: Vec<Header>, origin: &Path) -> Result<Volume, VolumeError> {
    let mut notes = Vec::new();
    let mut by_series: BTreeMap<String, Vec<Header>> = BTreeMap::new();
    for h in all {
        by_series.entry(h.series.clone()).or_default().push(h);
    }
    let Some((series, headers)) = by_series
        .iter()
        .max_by_key(|(_, hs)| hs.iter().map(|h| h.frames as usize).sum::<usize>())
        .map(|(s, hs)| (s.clone(), hs.clone()))
    else {
        return Err(invalid(origin, "no DICOM file given"));
    };
    if by_series.len() > 1 {
        let others: Vec<String> = by_series
            .iter()
            .filter(|(s, _)| **s != series)
            .map(|(s, hs)| format!("{s} ({} files)", hs.len()))
            .collect();
        notes.push(format!(
            "{} series found; the largest loaded ({series}, {} files); not loaded: {}",
            by_series.len(),
            headers.len(),
            others.join(", ")
        ));
    }
    if headers.len() > 1 && headers.iter().any(|h| h.frames > 1) {
        return Err(invalid(
            &headers.iter().find(|h| h.frames > 1).expect("one").file,
            "a series of several multi-frame files: open one of the files",
        ));
    }
    let first = &headers[0];
    for h in &headers[1..] {
        if (h.rows, h.cols) != (first.rows, first.cols) {
            return Err(invalid(
                &h.file,
                format!(
                    "{}×{} pixels, but {} has {}×{}: the slices of a series must share their size",
                    h.cols,
                    h.rows,
                    first.file.display(),
                    first.cols,
                    first.rows
                ),
            ));
        }
        if (h.bits_allocated, h.signed) != (first.bits_allocated, first.signed) {
            return Err(invalid(
                &h.file,
                format!(
                    "{} bits {}, but {} has {} bits {}: the slices must share their sample type",
                    h.bits_allocated,
                    if h.signed { "signed" } else { "unsigned" },
                    first.file.display(),
                    first.bits_allocated,
                    if first.signed { "signed" } else { "unsigned" },
                ),
            ));
        }
        if let (Some(a), Some(b)) = (h.orientation, first.orientation)
            && a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-3)
        {
            return Err(invalid(
                &h.file,
                format!(
                    "ImageOrientationPatient {a:?} differs from {:?} in {}: the slices of a \
                     series must share their orientation",
                    b,
                    first.file.display()
                ),
            ));
        }
    }
    // directions: row (x), column (y), normal
    let (row, col) = match first.orientation {
        Some(o) => {
            let (r, c) = ([o[0], o[1], o[2]], [o[3], o[4], o[5]]);
            if norm(r) < 1e-6 || norm(c) < 1e-6 || norm(cross(r, c)) < 1e-6 {
                return Err(header_error(
                    &first.file,
                    format!("ImageOrientationPatient {o:?} does not span a plane"),
                ));
            }
            (r.map(|v| v / norm(r)), c.map(|v| v / norm(c)))
        }
        None => {
            notes.push("no ImageOrientationPatient: the axes are taken as LPS".into());
            ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        }
    };
    let normal = {
        let n = cross(row, col);
        n.map(|v| v / norm(n))
    };
    // slices in order along the normal
    let mut slices: Vec<SliceRef> = headers
        .iter()
        .enumerate()
        .flat_map(|(i, h)| {
            (0..h.frames).map(move |k| SliceRef {
                file: i,
                frame: k,
                position: h.positions.get(k as usize).copied().flatten(),
            })
        })
        .collect();
    let name = |s: &SliceRef| {
        let h = &headers[s.file];
        if h.frames > 1 {
            format!("{} frame {}", h.file.display(), s.frame + 1)
        } else {
            h.file.display().to_string()
        }
    };
    let default_dz = first.slice_spacing.unwrap_or(1.0);
    let dz = if slices.len() > 1 && slices.iter().all(|s| s.position.is_some()) {
        let d = |s: &SliceRef| dot(s.position.expect("checked"), normal);
        slices.sort_by(|a, b| d(a).total_cmp(&d(b)));
        let gaps: Vec<f64> = slices.windows(2).map(|w| d(&w[1]) - d(&w[0])).collect();
        if let Some(i) = gaps.iter().position(|g| g.abs() < 1e-4) {
            return Err(invalid(
                &headers[slices[i + 1].file].file,
                format!(
                    "{} and {} lie at the same position ({:.3} mm along the slice normal): \
                     more than one volume in one series (phases, echoes)? Load them as \
                     separate file lists",
                    name(&slices[i]),
                    name(&slices[i + 1]),
                    d(&slices[i])
                ),
            ));
        }
        let mean = (d(slices.last().expect("two")) - d(&slices[0])) / gaps.len() as f64;
        let (gmin, gmax) = gaps
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, u), g| {
                (l.min(*g), u.max(*g))
            });
        let tolerance = (0.01 * mean).max(0.01);
        if gmax - mean > tolerance || mean - gmin > tolerance {
            notes.push(format!(
                "unequal slice spacing: gaps from {gmin:.3} to {gmax:.3} mm; shown on the mean \
                 spacing {mean:.3} mm (not resampled)"
            ));
        }
        let travel = sub(
            slices.last().expect("two").position.expect("checked"),
            slices[0].position.expect("checked"),
        );
        let tilt = (dot(travel, normal).abs() / norm(travel))
            .clamp(0.0, 1.0)
            .acos()
            .to_degrees();
        if tilt > 0.01 {
            notes.push(format!(
                "gantry tilt: the slice positions run {tilt:.2}° off the slice normal; shown \
                 unsheared (not resampled), so anatomy shifts by up to {:.2} mm across the volume",
                norm(travel) * tilt.to_radians().sin()
            ));
        }
        mean
    } else {
        if slices.len() > 1 {
            slices.sort_by_key(|s| {
                (
                    headers[s.file].instance.unwrap_or(i64::MAX),
                    s.file,
                    s.frame,
                )
            });
            notes.push(format!(
                "no ImagePositionPatient on every slice: slices in InstanceNumber order, z \
                 spacing {default_dz} mm from {}",
                if first.slice_spacing.is_some() {
                    "SpacingBetweenSlices or SliceThickness"
                } else {
                    "nothing (1)"
                }
            ));
        }
        default_dz
    };
    let [sy, sx] = first.pixel_spacing.unwrap_or_else(|| {
        notes.push("no PixelSpacing: x and y spacing 1".into());
        [1.0, 1.0]
    });
    let stored_dims = [first.cols, first.rows, slices.len() as u32];
    let stored_spacing = [sx, sy, dz];
    let out = choose_type(&headers);
    let out_bytes = match out {
        Out::U8 | Out::I8 => 1,
        Out::U16 | Out::I16 => 2,
        Out::F32 => 4,
    };
    check_layout(
        stored_dims.map(u64::from),
        1,
        out_bytes.max(u64::from(first.bits_allocated) / 8),
        Some(origin),
    )?;
    // pixels, slice by slice in sorted order
    let plane = first.rows as usize * first.cols as usize;
    let total = (plane * slices.len()) as u64;
    let mut values: Vec<f32> = Vec::new();
    let mut data = match out {
        Out::U8 => VoxelData::U8(Vec::new()),
        Out::I8 => VoxelData::I8(Vec::new()),
        Out::U16 => VoxelData::U16(Vec::new()),
        Out::I16 => VoxelData::I16(Vec::new()),
        Out::F32 => VoxelData::F32(Vec::new()),
    };
    reserve(&mut data, plane * slices.len(), origin)?;
    let mut open: Option<(usize, DefaultDicomObject)> = None;
    let mut rescales = std::collections::BTreeSet::new();
    for (k, s) in slices.iter().enumerate() {
        let h = &headers[s.file];
        if open.as_ref().is_none_or(|(i, _)| *i != s.file) {
            let obj = OpenFileOptions::new()
                .open_file(&h.file)
                .map_err(|e| header_error(&h.file, format!("not a readable DICOM file: {e}")))?;
            open = Some((s.file, obj));
        }
        let obj = &open.as_ref().expect("opened").1;
        if h.transfer_syntax == uids::RLE_LOSSLESS {
            check_rle(obj, h)?;
        }
        // a single frame may span several fragments, which only the whole decode joins;
        // a decoder that panics on corrupt data (a bug there) becomes an error here
        let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            if h.frames == 1 {
                obj.decode_pixel_data()
            } else {
                obj.decode_pixel_data_frame(s.frame)
            }
        }))
        .map_err(|_| {
            invalid(
                &h.file,
                format!(
                    "the pixel data decoder failed on corrupt data (transfer syntax {})",
                    h.transfer_syntax
                ),
            )
        })?;
        let decoded = decoded.map_err(|e| VolumeError::Unsupported {
            file: h.file.clone(),
            message: format!(
                "cannot decode the pixel data (transfer syntax {}{}): {e}",
                h.transfer_syntax,
                TransferSyntaxRegistry
                    .get(&h.transfer_syntax)
                    .map(|ts| format!(", {}", ts.name()))
                    .unwrap_or_default()
            ),
        })?;
        if (decoded.rows(), decoded.columns()) != (h.rows, h.cols)
            || decoded.samples_per_pixel() != 1
        {
            return Err(invalid(
                &h.file,
                format!(
                    "the pixel data decodes to {}×{}×{} samples, the header says {}×{}×1",
                    decoded.columns(),
                    decoded.rows(),
                    decoded.samples_per_pixel(),
                    h.cols,
                    h.rows
                ),
            ));
        }
        let bytes = decoded.frame_data(0).map_err(|e| {
            invalid(
                &h.file,
                format!("the pixel data is shorter than {} frame(s): {e}", h.frames),
            )
        })?;
        let need = plane * usize::from(h.bits_allocated / 8);
        if bytes.len() < need {
            return Err(invalid(
                &h.file,
                format!(
                    "frame {} holds {} bytes, {need} needed",
                    s.frame + 1,
                    bytes.len()
                ),
            ));
        }
        let (m, c) = h.rescale;
        rescales.insert((m.to_bits(), c.to_bits()));
        let value =
            |i: usize| stored(bytes, i, h.bits_allocated, h.bits_stored, h.signed) as f64 * m + c;
        match &mut data {
            VoxelData::U8(v) => v.extend((0..plane).map(|i| value(i) as u8)),
            VoxelData::I8(v) => v.extend((0..plane).map(|i| value(i) as i8)),
            VoxelData::U16(v) => v.extend((0..plane).map(|i| value(i) as u16)),
            VoxelData::I16(v) => v.extend((0..plane).map(|i| value(i) as i16)),
            VoxelData::F32(v) => {
                values.clear();
                values.extend((0..plane).map(|i| value(i) as f32));
                v.extend_from_slice(&values);
            }
        }
        if !super::report_progress(((k + 1) * plane) as u64, total) {
            return Err(super::raw::io_error(
                origin,
                "cannot finish reading",
                std::io::Error::new(std::io::ErrorKind::Interrupted, "cancelled"),
            ));
        }
    }
    drop(open);
    if rescales.len() == 1 {
        let (m, c) = first.rescale;
        if (m, c) != (1.0, 0.0) {
            notes.push(format!("rescaled: value·{m} + {c}"));
        }
    } else {
        notes.push(format!(
            "rescaled per slice ({} different slopes and intercepts)",
            rescales.len()
        ));
    }
    let (reorder, angle) = orient::reorder_for(&[row, col, normal]);
    if angle > 0.5 {
        notes.push(format!(
            "oblique by {angle:.1}°: snapped to the nearest axes without resampling"
        ));
    }
    let ts_name = TransferSyntaxRegistry
        .get(&first.transfer_syntax)
        .map(|ts| ts.name().to_string())
        .unwrap_or_else(|| first.transfer_syntax.clone());
    notes.insert(
        0,
        format!(
            "DICOM series {series}{}: {} slice(s) from {} file(s), {} bits {}, {ts_name}; \
             sorted along the slice normal; axes to LPS: {}",
            if first.description.is_empty() {
                String::new()
            } else {
                format!(" \"{}\"", first.description)
            },
            slices.len(),
            headers.len(),
            first.bits_allocated,
            if first.signed { "signed" } else { "unsigned" },
            super::nifti::describe(&reorder)
        ),
    );
    let data = super::nifti::reorder_data(data, &reorder, stored_dims, 1);
    let name = if origin.is_dir() {
        super::name_from_path(origin)
    } else {
        origin
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .map(super::name_from_path)
            .unwrap_or_else(|| super::name_from_path(origin))
    };
    let mut volume = Volume::new(
        name,
        reorder.apply(stored_dims),
        1,
        reorder.apply(stored_spacing),
        data,
    )
    .map_err(|e| e.in_file(origin))?;
    volume.source = Some(origin.to_path_buf());
    volume.notes = notes;
    Ok(volume)
}

/// Checks RLE lossless fragments before dicom-rs decodes them (its decoder indexes
/// and unwraps without checks): one segment per byte of a sample, offsets inside the
/// fragment, and every segment's PackBits runs complete up to a plane of samples.
fn check_rle(obj: &DefaultDicomObject, h: &Header) -> Result<(), VolumeError> {
    let bad = |m: String| invalid(&h.file, format!("corrupt RLE pixel data: {m}"));
    let Some(Value::PixelSequence(seq)) = obj
        .element_opt(tags::PIXEL_DATA)
        .ok()
        .flatten()
        .map(|e| e.value())
    else {
        return Err(bad("the pixel data is not encapsulated".into()));
    };
    let fragments = seq.fragments();
    if fragments.is_empty() {
        return Err(bad("no fragments".into()));
    }
    let plane = h.rows as usize * h.cols as usize;
    let segments = usize::from(h.bits_allocated / 8);
    for (i, f) in fragments.iter().enumerate() {
        if f.len() < 64 {
            return Err(bad(format!(
                "fragment {} is shorter than its 64-byte header",
                i + 1
            )));
        }
        let word = |k: usize| {
            u32::from_le_bytes([f[4 * k], f[4 * k + 1], f[4 * k + 2], f[4 * k + 3]]) as usize
        };
        if word(0) != segments {
            return Err(bad(format!(
                "fragment {} has {} segments, {} bits per sample need {segments}",
                i + 1,
                word(0),
                h.bits_allocated
            )));
        }
        let mut offsets: Vec<usize> = (1..=segments).map(word).collect();
        offsets.push(f.len());
        for k in 0..segments {
            let (a, b) = (offsets[k], offsets[k + 1]);
            if a < 64 || a > b || b > f.len() {
                return Err(bad(format!(
                    "fragment {}: segment {} runs from byte {a} to {b} of {}",
                    i + 1,
                    k + 1,
                    f.len()
                )));
            }
            // PackBits: n < 128 copies n + 1 bytes, n > 128 repeats the next byte
            // 257 − n times, 128 is a no-op
            let seg = &f[a..b];
            let (mut at, mut out) = (0usize, 0usize);
            while out < plane {
                let Some(&n) = seg.get(at) else { break };
                let (take, produce) = match n {
                    0..=127 => (1 + usize::from(n) + 1, usize::from(n) + 1),
                    128 => (1, 0),
                    _ => (2, 257 - usize::from(n)),
                };
                if at + take > seg.len() {
                    break;
                }
                at += take;
                out += produce;
            }
            if out < plane {
                return Err(bad(format!(
                    "fragment {}: segment {} decodes to {out} of the {plane} bytes a frame needs",
                    i + 1,
                    k + 1
                )));
            }
        }
    }
    Ok(())
}

fn reserve(data: &mut VoxelData, n: usize, file: &Path) -> Result<(), VolumeError> {
    let r = match data {
        VoxelData::U8(v) => v.try_reserve_exact(n),
        VoxelData::I8(v) => v.try_reserve_exact(n),
        VoxelData::U16(v) => v.try_reserve_exact(n),
        VoxelData::I16(v) => v.try_reserve_exact(n),
        VoxelData::F32(v) => v.try_reserve_exact(n),
    };
    r.map_err(|_| VolumeError::TooLarge {
        file: Some(file.to_path_buf()),
        dims: [n as u64, 1, 1],
        reason: "do not fit in memory".into(),
    })
}

/// One slice to write with [`write_slice`]: for tests, benchmarks and converters.
#[derive(Debug, Clone)]
pub struct SliceSpec<'a> {
    pub series: &'a str,
    pub instance: i32,
    pub rows: u16,
    pub cols: u16,
    /// Stored values, row by row (`rows × cols`, or a multiple for several frames).
    pub samples: &'a [i32],
    pub frames: u32,
    /// 8 or 16.
    pub bits_allocated: u16,
    pub bits_stored: u16,
    pub signed: bool,
    pub rescale: (f64, f64),
    /// ImagePositionPatient, one per frame (written per frame in the per-frame
    /// functional groups when there are several); empty: none.
    pub positions: &'a [[f64; 3]],
    pub orientation: Option<[f64; 6]>,
    /// PixelSpacing: (between rows, between columns).
    pub pixel_spacing: Option<[f64; 2]>,
    pub slice_thickness: Option<f64>,
    /// Encode the pixel data as RLE lossless (else explicit VR little endian).
    pub rle: bool,
}

impl Default for SliceSpec<'_> {
    fn default() -> Self {
        SliceSpec {
            series: "1.2.826.0.1.3680043.2.1125.1",
            instance: 1,
            rows: 1,
            cols: 1,
            samples: &[],
            frames: 1,
            bits_allocated: 16,
            bits_stored: 16,
            signed: true,
            rescale: (1.0, 0.0),
            positions: &[],
            orientation: Some([1.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
            pixel_spacing: Some([1.0, 1.0]),
            slice_thickness: None,
            rle: false,
        }
    }
}

/// Decimal strings (at most 16 characters each, as DICOM's DS allows).
fn ds(values: &[f64]) -> PrimitiveValue {
    PrimitiveValue::Strs(
        values
            .iter()
            .map(|v| {
                let s = format!("{v}");
                if s.len() <= 16 {
                    return s;
                }
                // fewer decimals until it fits
                (0..=10)
                    .rev()
                    .map(|d| format!("{v:.d$}"))
                    .find(|s| s.len() <= 16)
                    .unwrap_or_else(|| format!("{v:.3e}"))
            })
            .collect(),
    )
}

/// PackBits with literal runs only (valid RLE, not the smallest).
fn packbits(bytes: &[u8], out: &mut Vec<u8>) {
    for chunk in bytes.chunks(128) {
        out.push((chunk.len() - 1) as u8);
        out.extend_from_slice(chunk);
    }
    if out.len() % 2 == 1 {
        out.push(0x80); // a no-op run byte pads the segment to even length
    }
}

/// Writes one DICOM file (CT image storage) from `s`.
pub fn write_slice(path: &Path, s: &SliceSpec) -> Result<(), String> {
    let mut obj = InMemDicomObject::new_empty();
    let uid = format!("{}.{}", s.series, s.instance);
    let mut put = |tag: Tag, vr: VR, v: PrimitiveValue| {
        obj.put(DataElement::new(tag, vr, v));
    };
    put(tags::SOP_CLASS_UID, VR::UI, uids::CT_IMAGE_STORAGE.into());
    put(tags::SOP_INSTANCE_UID, VR::UI, uid.as_str().into());
    put(tags::MODALITY, VR::CS, "CT".into());
    put(tags::SERIES_INSTANCE_UID, VR::UI, s.series.into());
    put(tags::SERIES_DESCRIPTION, VR::LO, "vwb test series".into());
    put(
        tags::INSTANCE_NUMBER,
        VR::IS,
        format!("{}", s.instance).into(),
    );
    put(tags::SAMPLES_PER_PIXEL, VR::US, PrimitiveValue::from(1u16));
    put(
        tags::PHOTOMETRIC_INTERPRETATION,
        VR::CS,
        "MONOCHROME2".into(),
    );
    put(tags::ROWS, VR::US, PrimitiveValue::from(s.rows));
    put(tags::COLUMNS, VR::US, PrimitiveValue::from(s.cols));
    put(
        tags::BITS_ALLOCATED,
        VR::US,
        PrimitiveValue::from(s.bits_allocated),
    );
    put(
        tags::BITS_STORED,
        VR::US,
        PrimitiveValue::from(s.bits_stored),
    );
    put(
        tags::HIGH_BIT,
        VR::US,
        PrimitiveValue::from(s.bits_stored - 1),
    );
    put(
        tags::PIXEL_REPRESENTATION,
        VR::US,
        PrimitiveValue::from(u16::from(s.signed)),
    );
    put(tags::RESCALE_SLOPE, VR::DS, ds(&[s.rescale.0]));
    put(tags::RESCALE_INTERCEPT, VR::DS, ds(&[s.rescale.1]));
    if let Some(o) = s.orientation {
        put(tags::IMAGE_ORIENTATION_PATIENT, VR::DS, ds(&o));
    }
    if let Some(p) = s.pixel_spacing {
        put(tags::PIXEL_SPACING, VR::DS, ds(&p));
    }
    if let Some(t) = s.slice_thickness {
        put(tags::SLICE_THICKNESS, VR::DS, ds(&[t]));
    }
    if s.frames > 1 {
        put(
            tags::NUMBER_OF_FRAMES,
            VR::IS,
            format!("{}", s.frames).into(),
        );
        if s.positions.len() == s.frames as usize {
            let items: Vec<InMemDicomObject> = s
                .positions
                .iter()
                .map(|p| {
                    let position = InMemDicomObject::from_element_iter([DataElement::new(
                        tags::IMAGE_POSITION_PATIENT,
                        VR::DS,
                        ds(p),
                    )]);
                    InMemDicomObject::from_element_iter([DataElement::new(
                        tags::PLANE_POSITION_SEQUENCE,
                        VR::SQ,
                        Value::new_sequence(vec![position], dicom_core::Length::UNDEFINED),
                    )])
                })
                .collect();
            obj.put(DataElement::new(
                tags::PER_FRAME_FUNCTIONAL_GROUPS_SEQUENCE,
                VR::SQ,
                Value::new_sequence(items, dicom_core::Length::UNDEFINED),
            ));
        }
    } else if let Some(p) = s.positions.first() {
        put(tags::IMAGE_POSITION_PATIENT, VR::DS, ds(p));
    }
    let bytes: Vec<u8> = match s.bits_allocated {
        8 => s.samples.iter().map(|&v| v as u8).collect(),
        16 => s
            .samples
            .iter()
            .flat_map(|&v| (v as u16).to_le_bytes())
            .collect(),
        other => return Err(format!("write_slice writes 8 or 16 bits, not {other}")),
    };
    let syntax = if s.rle {
        // one fragment per frame: a 64-byte header, then one PackBits segment per byte
        // plane, most significant first
        let per_frame = usize::from(s.rows) * usize::from(s.cols);
        let planes = usize::from(s.bits_allocated / 8);
        let fragments: Vec<Vec<u8>> = bytes
            .chunks(per_frame * planes)
            .map(|frame| {
                let mut segments = Vec::new();
                let mut offsets = Vec::new();
                for p in (0..planes).rev() {
                    offsets.push(64 + segments.len() as u32);
                    let plane: Vec<u8> = frame.iter().skip(p).step_by(planes).copied().collect();
                    packbits(&plane, &mut segments);
                }
                let mut out = vec![0u8; 64];
                out[0..4].copy_from_slice(&(planes as u32).to_le_bytes());
                for (i, o) in offsets.iter().enumerate() {
                    out[4 + 4 * i..8 + 4 * i].copy_from_slice(&o.to_le_bytes());
                }
                out.extend(segments);
                out
            })
            .collect();
        obj.put(DataElement::new(
            tags::PIXEL_DATA,
            VR::OB,
            Value::PixelSequence(PixelFragmentSequence::new(Vec::<u32>::new(), fragments)),
        ));
        uids::RLE_LOSSLESS
    } else {
        let vr = if s.bits_allocated == 8 {
            VR::OB
        } else {
            VR::OW
        };
        obj.put(DataElement::new(
            tags::PIXEL_DATA,
            vr,
            PrimitiveValue::U8(bytes.into()),
        ));
        uids::EXPLICIT_VR_LITTLE_ENDIAN
    };
    let file = obj
        .with_meta(
            FileMetaTableBuilder::new()
                .transfer_syntax(syntax)
                .media_storage_sop_class_uid(uids::CT_IMAGE_STORAGE)
                .media_storage_sop_instance_uid(uid.as_str()),
        )
        .map_err(|e| format!("{}: {e}", path.display()))?;
    file.write_to_file(path)
        .map_err(|e| format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests;
