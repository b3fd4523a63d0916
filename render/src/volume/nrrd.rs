//! NRRD reader (magic `NRRD0001` to `NRRD0005`).
//!
//! Supported: attached headers (data after the blank line that ends the header)
//! and detached headers (`data file:` / `datafile:` relative to the header's
//! folder); `raw`, `gzip`/`gz` (a zlib stream is accepted too), `bzip2`/`bz2` and
//! `ascii`/`text`/`txt` encodings (decimal samples separated by white space or commas)
//! and `hex` (the raw bytes as hexadecimal digit pairs, white space ignored);
//! either endianness; `line skip` (lines of the data file, before decompression),
//! `byte skip` (of the decompressed data for gzip; `-1` for raw means the data
//! ends the file); dimension 3 (scalar) or 4: the first axis holding 1, 2 or 3
//! interleaved components (the default), or, by its kind, the last axis holding
//! planar components (`vector`, `3-vector`, … with 1–3 entries) or a series
//! (`time`, `list`, …: the first volume is read, with a note). Spacing comes from `space directions` (the length of
//! each axis vector) when present, else from `spacings`, else it is 1.
//!
//! Sample types: 8- and 16-bit integers and `float` load as they are; 32/64-bit
//! integers and `double` are converted to f32.
//!
//! Not supported (with a clear error): `data file: LIST` and formatted file
//! lists, the `hex` encoding, `block` samples, 2D volumes, a non-spatial axis
//! in the middle, more than 3 components.
//!
//! Orientation: when `space` names an anatomical space (RAS, LAS, LPS) and `space
//! directions` are given, the axes are permuted and flipped to LPS like every other
//! format (`orient.rs`; scalar volumes only, a vector volume keeps its axes with a note).
//! Other spaces and headers without directions keep the stored order.
//!
//! Comments, `key:=value` pairs and the known descriptive fields (
//! `space origin`, `kinds` beyond their check, `units`, `labels`, ...) are
//! ignored; unrecognised fields are ignored too but listed in
//! [`NrrdHeader::unknown_fields`] so a caller can warn about typos.
//!
//! Raw data may be followed by trailing bytes (the header is authoritative, as in
//! teem); gzip data must decompress to exactly the size the header gives.

use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufRead, BufReader, Cursor, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use flate2::bufread::{GzDecoder, ZlibDecoder};

use super::raw::{ReadFail, io_error, read_samples};
use super::{Endian, ScalarType, Volume, VolumeError, check_layout, layout_desc, name_from_path};

/// The most header text read before giving up on finding its end.
const MAX_HEADER_BYTES: u64 = 1 << 20;

/// Deflate cannot expand data by more than about 1032:1; a header that claims
/// more than this times the compressed size is lying, which is caught before
/// allocating.
const MAX_DEFLATE_RATIO: u64 = 1100;

/// A sample type of an NRRD file (on disk).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum NrrdType {
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float,
    Double,
}

impl NrrdType {
    /// Parses any NRRD spelling of a type (`uchar`, `unsigned char`, `uint8`,
    /// `uint8_t`, `short`, `signed short int`, `float`, ...), case-insensitively.
    /// `None` for unknown names and for `block`.
    pub fn parse(text: &str) -> Option<NrrdType> {
        let norm = text
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
            .to_ascii_lowercase();
        Some(match norm.as_str() {
            "signed char" | "int8" | "int8_t" => NrrdType::Int8,
            "uchar" | "unsigned char" | "uint8" | "uint8_t" => NrrdType::UInt8,
            "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
                NrrdType::Int16
            }
            "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
                NrrdType::UInt16
            }
            "int" | "signed int" | "int32" | "int32_t" => NrrdType::Int32,
            "uint" | "unsigned int" | "uint32" | "uint32_t" => NrrdType::UInt32,
            "longlong"
            | "long long"
            | "long long int"
            | "signed long long"
            | "signed long long int"
            | "int64"
            | "int64_t" => NrrdType::Int64,
            "ulonglong"
            | "unsigned long long"
            | "unsigned long long int"
            | "uint64"
            | "uint64_t" => NrrdType::UInt64,
            "float" => NrrdType::Float,
            "double" => NrrdType::Double,
            _ => return None,
        })
    }

    /// Size of one sample on disk.
    pub fn size_bytes(self) -> usize {
        match self {
            NrrdType::Int8 | NrrdType::UInt8 => 1,
            NrrdType::Int16 | NrrdType::UInt16 => 2,
            NrrdType::Int32 | NrrdType::UInt32 | NrrdType::Float => 4,
            NrrdType::Int64 | NrrdType::UInt64 | NrrdType::Double => 8,
        }
    }

    /// Canonical name (`uint8`, `int16`, `float`, `double`, ...).
    pub fn name(self) -> &'static str {
        match self {
            NrrdType::Int8 => "int8",
            NrrdType::UInt8 => "uint8",
            NrrdType::Int16 => "int16",
            NrrdType::UInt16 => "uint16",
            NrrdType::Int32 => "int32",
            NrrdType::UInt32 => "uint32",
            NrrdType::Int64 => "int64",
            NrrdType::UInt64 => "uint64",
            NrrdType::Float => "float",
            NrrdType::Double => "double",
        }
    }

    /// The in-memory type the samples load as (wider types become f32).
    pub fn scalar_type(self) -> ScalarType {
        match self {
            NrrdType::Int8 => ScalarType::I8,
            NrrdType::UInt8 => ScalarType::U8,
            NrrdType::Int16 => ScalarType::I16,
            NrrdType::UInt16 => ScalarType::U16,
            NrrdType::Int32
            | NrrdType::UInt32
            | NrrdType::Int64
            | NrrdType::UInt64
            | NrrdType::Float
            | NrrdType::Double => ScalarType::F32,
        }
    }
}

impl From<ScalarType> for NrrdType {
    fn from(t: ScalarType) -> Self {
        match t {
            ScalarType::U8 => NrrdType::UInt8,
            ScalarType::I8 => NrrdType::Int8,
            ScalarType::U16 => NrrdType::UInt16,
            ScalarType::I16 => NrrdType::Int16,
            ScalarType::F32 => NrrdType::Float,
        }
    }
}

/// Data encoding of an NRRD file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NrrdEncoding {
    Raw,
    Gzip,
    /// bzip2-compressed samples (`bzip2` / `bz2`).
    Bzip2,
    /// Samples as decimal text separated by white space (`ascii` / `text` / `txt`).
    Ascii,
    /// The raw bytes as pairs of hexadecimal digits, white space ignored (`hex`).
    Hex,
}

/// Where the data starts after the line skip.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ByteSkip {
    /// Skip this many bytes (of the decompressed data for gzip).
    Bytes(u64),
    /// `byte skip: -1`: the raw data is the last bytes of the file.
    FromEnd,
}

/// A parsed and checked NRRD header, resolved to the volume's layout.
#[derive(Debug, Clone, PartialEq)]
pub struct NrrdHeader {
    /// The `x` of the magic `NRRD000x`.
    pub version: u8,
    pub data_type: NrrdType,
    /// Spatial sizes (x, y, z).
    pub dims: [u32; 3],
    /// 1, or the size of the vector axis (axis 0) of a 4-dimensional NRRD.
    pub components: u32,
    /// Voxel size along x, y, z: the norms of `space directions`, else
    /// `spacings`, else 1.
    pub spacing: [f64; 3],
    /// The world direction of each spatial axis in LPS, when the header names an
    /// anatomical `space` (RAS, LAS, LPS or their long names) and gives `space
    /// directions` for it; the loader reorders the axes by it (see `orient.rs`).
    pub lps_directions: Option<[[f64; 3]; 3]>,
    /// The `space` field as written, if any.
    pub space: Option<String>,
    /// Volumes of a 4-dimensional series on the last axis (1 otherwise); the loader
    /// reads the first.
    pub volumes: u64,
    /// The components lie on the last axis (whole volumes one after another), not
    /// interleaved on the first.
    pub planar: bool,
    /// The kind of the non-spatial axis of a 4-dimensional NRRD, if given.
    pub extra_kind: Option<String>,
    /// Byte order (little when the header omits it for a 1-byte type).
    pub endian: Endian,
    pub encoding: NrrdEncoding,
    /// Detached data file as written in the header (relative to the header's
    /// folder unless absolute); `None` for attached data.
    pub data_file: Option<PathBuf>,
    pub line_skip: u64,
    pub byte_skip: ByteSkip,
    /// Unrecognised field names, in header order (possible typos).
    pub unknown_fields: Vec<String>,
}

impl NrrdHeader {
    /// Number of samples (voxels times components).
    pub fn value_count(&self) -> u64 {
        self.dims.iter().fold(u64::from(self.components), |n, &d| {
            n.saturating_mul(u64::from(d))
        })
    }

    /// Bytes of (decompressed) sample data the header describes.
    pub fn data_bytes(&self) -> u64 {
        self.value_count()
            .saturating_mul(self.data_type.size_bytes() as u64)
    }

    /// E.g. `256x256x108 int16`.
    fn layout_text(&self) -> String {
        layout_desc(
            self.dims.map(u64::from),
            u64::from(self.components),
            self.data_type.name(),
        )
    }
}

/// The header fields this reader interprets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Field {
    Type,
    Dimension,
    Sizes,
    Spacings,
    SpaceDirections,
    Space,
    Kinds,
    Endian,
    Encoding,
    DataFile,
    ByteSkip,
    LineSkip,
    /// Accepted and ignored.
    Ignored,
}

impl Field {
    fn from_name(name: &str) -> Option<Field> {
        Some(match name {
            "type" => Field::Type,
            "dimension" => Field::Dimension,
            "sizes" => Field::Sizes,
            "spacings" => Field::Spacings,
            "space directions" => Field::SpaceDirections,
            "space" => Field::Space,
            "kinds" => Field::Kinds,
            "endian" => Field::Endian,
            "encoding" => Field::Encoding,
            "data file" | "datafile" => Field::DataFile,
            "byte skip" | "byteskip" => Field::ByteSkip,
            "line skip" | "lineskip" => Field::LineSkip,
            "content" | "block size" | "blocksize" | "thicknesses" | "axis mins" | "axismins"
            | "axis maxs" | "axismaxs" | "centers" | "centerings" | "labels" | "units" | "min"
            | "max" | "old min" | "oldmin" | "old max" | "oldmax" | "number" | "sample units"
            | "sampleunits" | "space dimension" | "space units" | "space origin"
            | "measurement frame" => Field::Ignored,
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            Field::Type => "type",
            Field::Dimension => "dimension",
            Field::Sizes => "sizes",
            Field::Spacings => "spacings",
            Field::SpaceDirections => "space directions",
            Field::Space => "space",
            Field::Kinds => "kinds",
            Field::Endian => "endian",
            Field::Encoding => "encoding",
            Field::DataFile => "data file",
            Field::ByteSkip => "byte skip",
            Field::LineSkip => "line skip",
            Field::Ignored => "(ignored)",
        }
    }
}

/// Builds header errors that name the file.
struct Errs<'a> {
    file: Option<&'a Path>,
}

impl Errs<'_> {
    fn at(&self, line: usize, message: impl Into<String>) -> VolumeError {
        VolumeError::Header {
            file: self.file.map(Path::to_path_buf),
            line: Some(line),
            message: message.into(),
        }
    }

    fn general(&self, message: impl Into<String>) -> VolumeError {
        VolumeError::Header {
            file: self.file.map(Path::to_path_buf),
            line: None,
            message: message.into(),
        }
    }
}

/// Parses and checks an NRRD header: the magic line, then fields up to the first
/// blank line or the end of `text` (anything after a blank line is ignored).
/// `file` only names the header in errors.
pub fn parse_nrrd_header(text: &str, file: Option<&Path>) -> Result<NrrdHeader, VolumeError> {
    let errs = Errs { file };
    let mut lines = text
        .split('\n')
        .map(|l| l.strip_suffix('\r').unwrap_or(l))
        .enumerate()
        .map(|(i, l)| (i + 1, l));
    let magic = lines.next().map(|(_, l)| l.trim_end()).unwrap_or("");
    let version = parse_magic(magic).map_err(|m| errs.at(1, m))?;
    let fields = Fields::collect(lines, &errs)?;

    let data_type = fields.data_type()?;
    let dimension = fields.dimension()?;
    let axes = fields.axes(dimension)?;
    let encoding = fields.encoding()?;
    let endian = fields.endian(data_type)?;
    let spacing = if let Some((line, value)) = fields.get(Field::SpaceDirections) {
        let s = spacing_from_directions(&errs, line, value, dimension, axes.extra)?;
        check_spacing_line(&errs, line, "space directions", s)?
    } else if let Some((line, value)) = fields.get(Field::Spacings) {
        let s = spacing_from_spacings(&errs, line, value, dimension, axes.extra)?;
        check_spacing_line(&errs, line, "spacings", s)?
    } else {
        [1.0; 3]
    };
    let space = fields.get(Field::Space).map(|(_, v)| v.to_string());
    let lps_directions = match (&space, fields.get(Field::SpaceDirections)) {
        (Some(name), Some((line, value))) => {
            lps_directions(name, value, axes.extra).map_err(|m| errs.at(line, m))?
        }
        _ => None,
    };
    let data_file = fields.data_file()?;
    let line_skip = fields.line_skip()?;
    let byte_skip = fields.byte_skip(encoding)?;

    let bytes_per_value = data_type
        .size_bytes()
        .max(data_type.scalar_type().size_bytes()) as u64;
    let layout = check_layout(axes.sizes, axes.components, bytes_per_value, file)?;

    Ok(NrrdHeader {
        version,
        data_type,
        dims: layout.dims,
        components: layout.components,
        spacing,
        lps_directions,
        space,
        volumes: axes.volumes,
        planar: axes.planar,
        extra_kind: axes.extra_kind.clone(),
        endian,
        encoding,
        data_file,
        line_skip,
        byte_skip,
        unknown_fields: fields.unknown,
    })
}

/// Spatial sizes and component count from `sizes` and `kinds`.
struct Axes {
    sizes: [u64; 3],
    components: u64,
    /// The non-spatial axis of a 4-dimensional NRRD (0 or 3).
    extra: Option<usize>,
    /// Volumes in a series on the last axis (1 otherwise); only the first is read.
    volumes: u64,
    /// Components on the last axis (whole volumes one after another).
    planar: bool,
    extra_kind: Option<String>,
}

/// The interpreted fields of a header, each with its line number.
struct Fields<'t, 'e> {
    values: HashMap<Field, (usize, &'t str)>,
    unknown: Vec<String>,
    errs: &'e Errs<'e>,
}

impl<'t, 'e> Fields<'t, 'e> {
    /// Reads `field: value` lines up to the first blank line, skipping comments
    /// and `key:=value` pairs.
    fn collect(
        lines: impl Iterator<Item = (usize, &'t str)>,
        errs: &'e Errs<'e>,
    ) -> Result<Self, VolumeError> {
        let mut values: HashMap<Field, (usize, &str)> = HashMap::new();
        let mut unknown = Vec::new();
        for (n, line) in lines {
            if line.trim().is_empty() {
                break;
            }
            if line.starts_with('#') {
                continue;
            }
            let Some((name, value)) = line.split_once(':') else {
                return Err(errs.at(
                    n,
                    format!("expected 'field: value', found '{}'", shorten(line)),
                ));
            };
            if value.starts_with('=') {
                continue; // key:=value pair
            }
            let name = name.trim().to_ascii_lowercase();
            match Field::from_name(&name) {
                Some(Field::Ignored) => {}
                Some(field) => {
                    if let Some((first, _)) = values.insert(field, (n, value.trim())) {
                        return Err(errs.at(
                            n,
                            format!(
                                "duplicate field '{}' (first given on line {first})",
                                field.name()
                            ),
                        ));
                    }
                }
                None => unknown.push(name),
            }
        }
        Ok(Fields {
            values,
            unknown,
            errs,
        })
    }

    fn get(&self, field: Field) -> Option<(usize, &'t str)> {
        self.values.get(&field).copied()
    }

    fn require(&self, field: Field) -> Result<(usize, &'t str), VolumeError> {
        self.get(field).ok_or_else(|| {
            self.errs
                .general(format!("missing required field '{}'", field.name()))
        })
    }

    fn data_type(&self) -> Result<NrrdType, VolumeError> {
        let (line, value) = self.require(Field::Type)?;
        NrrdType::parse(value).ok_or_else(|| {
            if value.eq_ignore_ascii_case("block") {
                self.errs.at(line, "type 'block' is not supported")
            } else {
                self.errs.at(line, format!("unknown type '{value}'"))
            }
        })
    }

    fn dimension(&self) -> Result<usize, VolumeError> {
        let (line, value) = self.require(Field::Dimension)?;
        let dimension: usize = value.parse().map_err(|_| {
            self.errs
                .at(line, format!("dimension '{value}' is not a whole number"))
        })?;
        if dimension == 3 || dimension == 4 {
            Ok(dimension)
        } else {
            Err(self.errs.at(
                line,
                format!(
                    "dimension {dimension} is not supported: only 3D volumes (dimension 3) and 3D \
                     vector fields (dimension 4, components on the first axis) can be loaded"
                ),
            ))
        }
    }

    /// Sizes, checked against `kinds`: the last three axes are spatial, and a
    /// fourth (first) axis holds 1 to 3 components.
    fn axes(&self, dimension: usize) -> Result<Axes, VolumeError> {
        let errs = self.errs;
        let (sizes_line, value) = self.require(Field::Sizes)?;
        let tokens: Vec<&str> = value.split_whitespace().collect();
        check_count(errs, sizes_line, "sizes", tokens.len(), dimension)?;
        let mut sizes = Vec::with_capacity(dimension);
        for (axis, tok) in tokens.iter().enumerate() {
            let size: u64 = tok.parse().map_err(|_| {
                errs.at(
                    sizes_line,
                    format!("sizes: '{tok}' (axis {axis}) is not a whole number"),
                )
            })?;
            if size == 0 {
                return Err(errs.at(sizes_line, format!("sizes: axis {axis} has size 0")));
            }
            sizes.push(size);
        }

        // the one non-spatial axis of a 4-dimensional NRRD: the first (interleaved
        // components, the default without kinds) or the last (planar components, or a
        // series of volumes such as time steps)
        let kinds: Option<(usize, Vec<&str>)> = self
            .get(Field::Kinds)
            .map(|(line, value)| (line, value.split_whitespace().collect()));
        if let Some((line, k)) = &kinds {
            check_count(errs, *line, "kinds", k.len(), dimension)?;
        }
        let extra = if dimension == 4 {
            match &kinds {
                None => 0,
                Some((line, k)) => {
                    let non_spatial: Vec<usize> =
                        (0..4).filter(|&a| !is_spatial_kind(k[a])).collect();
                    match non_spatial.as_slice() {
                        [0] => 0,
                        [3] => 3,
                        [] if k[3].eq_ignore_ascii_case("time") => 3,
                        [] => {
                            return Err(errs.at(
                                *line,
                                "kinds: all four axes are spatial; a 4-dimensional NRRD \
                                 holds components or a series on its first or last axis",
                            ));
                        }
                        [a, ..] => {
                            return Err(errs.at(
                                *line,
                                format!(
                                    "kinds: axis {a} is '{}'; a 4-dimensional NRRD may hold \
                                     components or a series only on its first or last axis \
                                     (the other axes spatial)",
                                    k[*a]
                                ),
                            ));
                        }
                    }
                }
            }
        } else {
            if let Some((line, k)) = &kinds
                && let Some(a) = (0..3).find(|&a| !is_spatial_kind(k[a]))
            {
                return Err(errs.at(
                    *line,
                    format!(
                        "kinds: axis {a} is '{}', but a 3-dimensional NRRD must be spatial \
                         on every axis",
                        k[a]
                    ),
                ));
            }
            usize::MAX
        };
        let spatial: Vec<usize> = (0..dimension).filter(|&a| a != extra).collect();
        let extra_size = sizes.get(extra).copied().unwrap_or(1);
        let extra_kind = kinds
            .as_ref()
            .and_then(|(_, k)| k.get(extra))
            .map(|k| k.to_ascii_lowercase());
        // a last axis of vector kind with 1–3 entries holds planar components; any other
        // last axis is a series, whose first volume is read
        let vector_kind = extra_kind.as_deref().is_some_and(|k| {
            matches!(
                k,
                "vector"
                    | "2-vector"
                    | "3-vector"
                    | "covariant-vector"
                    | "normal"
                    | "3-normal"
                    | "3-color"
                    | "rgb-color"
                    | "point"
            )
        });
        let (components, volumes, planar) = match extra {
            0 => (sizes[0], 1, false),
            3 if vector_kind && extra_size <= 3 => (extra_size, 1, true),
            3 => (1, extra_size, false),
            _ => (1, 1, false),
        };
        if components > 3 {
            return Err(errs.at(
                sizes_line,
                format!(
                    "the vector axis has {components} components; only 1, 2 or 3 are supported"
                ),
            ));
        }
        Ok(Axes {
            sizes: [sizes[spatial[0]], sizes[spatial[1]], sizes[spatial[2]]],
            components,
            extra: (dimension == 4).then_some(extra),
            volumes,
            planar,
            extra_kind,
        })
    }

    fn encoding(&self) -> Result<NrrdEncoding, VolumeError> {
        let (line, value) = self.require(Field::Encoding)?;
        match value.to_ascii_lowercase().as_str() {
            "raw" => Ok(NrrdEncoding::Raw),
            "gzip" | "gz" => Ok(NrrdEncoding::Gzip),
            "bzip2" | "bz2" => Ok(NrrdEncoding::Bzip2),
            "ascii" | "text" | "txt" => Ok(NrrdEncoding::Ascii),
            "hex" => Ok(NrrdEncoding::Hex),
            _ => Err(self.errs.at(line, format!("unknown encoding '{value}'"))),
        }
    }

    /// The byte order; required for multi-byte types, little otherwise.
    fn endian(&self, data_type: NrrdType) -> Result<Endian, VolumeError> {
        match self.get(Field::Endian) {
            Some((line, value)) => match value.to_ascii_lowercase().as_str() {
                "little" => Ok(Endian::Little),
                "big" => Ok(Endian::Big),
                _ => Err(self
                    .errs
                    .at(line, format!("unknown endian '{value}' (little or big)"))),
            },
            None if data_type.size_bytes() == 1 => Ok(Endian::Little),
            None => Err(self.errs.general(format!(
                "missing required field 'endian' (needed for the {}-byte type {})",
                data_type.size_bytes(),
                data_type.name()
            ))),
        }
    }

    fn data_file(&self) -> Result<Option<PathBuf>, VolumeError> {
        let Some((line, value)) = self.get(Field::DataFile) else {
            return Ok(None);
        };
        if value.split_whitespace().next() == Some("LIST") {
            return Err(self.errs.at(
                line,
                "data file: LIST (data split over several files) is not supported",
            ));
        }
        if value.contains('%') && value.split_whitespace().count() >= 4 {
            return Err(self.errs.at(
                line,
                format!("data file: formatted file lists ('{value}') are not supported"),
            ));
        }
        if value.is_empty() {
            return Err(self.errs.at(line, "data file: no file name given"));
        }
        Ok(Some(PathBuf::from(value)))
    }

    fn line_skip(&self) -> Result<u64, VolumeError> {
        match self.get(Field::LineSkip) {
            None => Ok(0),
            Some((line, value)) => value.parse().map_err(|_| {
                self.errs.at(
                    line,
                    format!("line skip '{value}' is not a whole number >= 0"),
                )
            }),
        }
    }

    fn byte_skip(&self, encoding: NrrdEncoding) -> Result<ByteSkip, VolumeError> {
        let Some((line, value)) = self.get(Field::ByteSkip) else {
            return Ok(ByteSkip::Bytes(0));
        };
        match value.parse::<i64>() {
            Ok(-1) if encoding == NrrdEncoding::Raw => Ok(ByteSkip::FromEnd),
            Ok(-1) => Err(self.errs.at(
                line,
                "byte skip -1 (data at the end of the file) is only allowed with raw encoding",
            )),
            Ok(n) if n >= 0 => Ok(ByteSkip::Bytes(n.unsigned_abs())),
            _ => Err(self.errs.at(
                line,
                format!("byte skip '{value}' must be -1 or a whole number >= 0"),
            )),
        }
    }
}

fn parse_magic(line: &str) -> Result<u8, String> {
    match line.strip_prefix("NRRD000") {
        Some(v) => match v.parse::<u8>() {
            Ok(n @ 1..=5) => Ok(n),
            _ => Err(format!(
                "unsupported NRRD version '{}' (NRRD0001 to NRRD0005 are supported)",
                shorten(line)
            )),
        },
        None => Err(format!(
            "not an NRRD header: the first line is '{}', not NRRD000x",
            shorten(line)
        )),
    }
}

fn check_count(
    errs: &Errs<'_>,
    line: usize,
    field: &str,
    got: usize,
    dimension: usize,
) -> Result<(), VolumeError> {
    if got == dimension {
        Ok(())
    } else {
        Err(errs.at(
            line,
            format!("{field}: {got} values given but the dimension is {dimension}"),
        ))
    }
}

/// Kinds of axes that are sampled in space (or time), as opposed to component axes.
fn is_spatial_kind(kind: &str) -> bool {
    matches!(
        kind.to_ascii_lowercase().as_str(),
        "domain" | "space" | "time" | "???" | "none"
    )
}

/// The spacing of a header line, checked as a whole (range and axis ratio).
fn check_spacing_line(
    errs: &Errs<'_>,
    line: usize,
    field: &str,
    spacing: [f64; 3],
) -> Result<[f64; 3], VolumeError> {
    match super::spacing_problem(spacing) {
        None => Ok(spacing),
        Some(m) => Err(errs.at(line, format!("{field}: {m}"))),
    }
}

fn check_spacing_value(
    errs: &Errs<'_>,
    line: usize,
    field: &str,
    axis: usize,
    value: f64,
) -> Result<f64, VolumeError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(errs.at(
            line,
            format!(
                "{field}: axis {axis} has spacing {value}, which must be finite and greater than 0"
            ),
        ))
    }
}

fn spacing_from_spacings(
    errs: &Errs<'_>,
    line: usize,
    value: &str,
    dimension: usize,
    extra: Option<usize>,
) -> Result<[f64; 3], VolumeError> {
    let tokens: Vec<&str> = value.split_whitespace().collect();
    check_count(errs, line, "spacings", tokens.len(), dimension)?;
    let mut spacing = [1.0; 3];
    let mut next = 0;
    for (axis, tok) in tokens.iter().enumerate() {
        let v: f64 = tok.parse().map_err(|_| {
            errs.at(
                line,
                format!("spacings: '{tok}' (axis {axis}) is not a number"),
            )
        })?;
        if Some(axis) != extra {
            spacing[next] = check_spacing_value(errs, line, "spacings", axis, v)?;
            next += 1;
        }
    }
    Ok(spacing)
}

/// Spacing as the lengths of the `space directions` vectors. The component axis
/// must be `none`; spatial axes must have vectors, all of the same length.
fn spacing_from_directions(
    errs: &Errs<'_>,
    line: usize,
    value: &str,
    dimension: usize,
    extra: Option<usize>,
) -> Result<[f64; 3], VolumeError> {
    let field = "space directions";
    let dirs = parse_directions(value).map_err(|m| errs.at(line, format!("{field}: {m}")))?;
    check_count(errs, line, field, dirs.len(), dimension)?;
    let mut spacing = [1.0; 3];
    let mut next = 0;
    let mut space_dim = None;
    for (axis, dir) in dirs.iter().enumerate() {
        match (Some(axis) != extra, dir) {
            (false, None) => {}
            (false, Some(_)) => {
                return Err(errs.at(
                    line,
                    format!("{field}: axis {axis} holds components and must be 'none'"),
                ));
            }
            (true, None) => {
                return Err(errs.at(
                    line,
                    format!("{field}: axis {axis} is spatial and needs a vector, not 'none'"),
                ));
            }
            (true, Some(v)) => {
                if *space_dim.get_or_insert(v.len()) != v.len() {
                    return Err(
                        errs.at(line, format!("{field}: the vectors have different lengths"))
                    );
                }
                let norm = v.iter().map(|c| c * c).sum::<f64>().sqrt();
                spacing[next] = check_spacing_value(errs, line, field, axis, norm)?;
                next += 1;
            }
        }
    }
    Ok(spacing)
}

/// The spatial axes' directions in LPS for an anatomical `space` (None for other
/// spaces, such as `scanner-xyz` or `3D-right-handed`, which name no patient side).
fn lps_directions(
    space: &str,
    directions: &str,
    extra: Option<usize>,
) -> Result<Option<[[f64; 3]; 3]>, String> {
    // sign of (x, y) that takes the space's axes to LPS
    let flip = match space.trim().to_ascii_lowercase().as_str() {
        "left-posterior-superior" | "lps" => [1.0, 1.0],
        "right-anterior-superior" | "ras" => [-1.0, -1.0],
        "left-anterior-superior" | "las" => [1.0, -1.0],
        _ => return Ok(None),
    };
    let dirs = parse_directions(directions).map_err(|m| format!("space directions: {m}"))?;
    let spatial: Vec<&Vec<f64>> = dirs
        .iter()
        .enumerate()
        .filter(|(a, _)| Some(*a) != extra)
        .filter_map(|(_, d)| d.as_ref())
        .collect();
    if spatial.len() != 3 || spatial.iter().any(|v| v.len() != 3) {
        return Err(format!(
            "space directions: the space '{space}' needs three 3-vectors for the spatial axes"
        ));
    }
    Ok(Some(std::array::from_fn(|a| {
        [
            spatial[a][0] * flip[0],
            spatial[a][1] * flip[1],
            spatial[a][2],
        ]
    })))
}

/// Parses `none` and `(x,y,z)` tokens (spaces allowed inside the parentheses).
fn parse_directions(value: &str) -> Result<Vec<Option<Vec<f64>>>, String> {
    let mut out = Vec::new();
    let mut rest = value.trim_start();
    while !rest.is_empty() {
        if let Some(after) = rest.strip_prefix('(') {
            let close = after
                .find(')')
                .ok_or_else(|| format!("missing ')' in '{}'", shorten(rest)))?;
            let inner = &after[..close];
            let v = inner
                .split(',')
                .map(|c| {
                    let c = c.trim();
                    c.parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| format!("'{c}' in '({inner})' is not a finite number"))
                })
                .collect::<Result<Vec<f64>, String>>()?;
            out.push(Some(v));
            rest = after[close + 1..].trim_start();
        } else {
            let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
            let word = &rest[..end];
            if word.eq_ignore_ascii_case("none") {
                out.push(None);
                rest = rest[end..].trim_start();
            } else {
                return Err(format!(
                    "expected '(x,y,z)' or 'none', found '{}'",
                    shorten(word)
                ));
            }
        }
    }
    Ok(out)
}

/// At most 60 characters of `s`, for error messages.
fn shorten(s: &str) -> String {
    const MAX: usize = 60;
    if s.chars().count() <= MAX {
        s.to_owned()
    } else {
        let mut t: String = s.chars().take(MAX).collect();
        t.push_str("...");
        t
    }
}

/// Loads an NRRD file (attached or detached header). The path is opened once; pipes
/// and FIFOs are read as streams.
pub fn load_nrrd(path: &Path) -> Result<Volume, VolumeError> {
    load_input(Input::open(path)?, path)
}

/// A volume path, opened once: a regular file, or the whole content of a pipe, FIFO
/// or device read as a stream.
pub(crate) enum Input {
    File { file: File, len: u64 },
    Stream(Vec<u8>),
}

impl Input {
    pub(crate) fn open(path: &Path) -> Result<Input, VolumeError> {
        let meta = std::fs::metadata(path).map_err(|e| io_error(path, "cannot open", e))?;
        if meta.is_dir() {
            return Err(VolumeError::Unsupported {
                file: path.to_path_buf(),
                message: "is a folder, not a volume file".to_owned(),
            });
        }
        if meta.is_file() {
            let file = File::open(path).map_err(|e| io_error(path, "cannot open", e))?;
            let len = file
                .metadata()
                .map_err(|e| io_error(path, "cannot read metadata", e))?
                .len();
            return Ok(Input::File { file, len });
        }
        let mut stream = open_stream(path).map_err(|e| io_error(path, "cannot open", e))?;
        let limit = super::MAX_BYTES + MAX_HEADER_BYTES;
        let mut bytes = Vec::new();
        let mut chunk = vec![0u8; 1 << 20];
        loop {
            let n = match stream.read(&mut chunk) {
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(io_error(path, "cannot read the stream", e)),
            };
            if n == 0 {
                break;
            }
            if bytes.len() as u64 + n as u64 > limit {
                return Err(VolumeError::Unsupported {
                    file: path.to_path_buf(),
                    message: format!("the stream is longer than {limit} bytes"),
                });
            }
            bytes.try_reserve(n).map_err(|_| VolumeError::OutOfMemory {
                file: Some(path.to_path_buf()),
                bytes: bytes.len() as u64 + n as u64,
            })?;
            bytes.extend_from_slice(&chunk[..n]);
        }
        if bytes.is_empty() {
            return Err(VolumeError::Unsupported {
                file: path.to_path_buf(),
                message: "is a pipe, FIFO or device that gave no data (is anything writing to \
                          it?)"
                    .to_owned(),
            });
        }
        Ok(Input::Stream(bytes))
    }

    /// Up to `n` bytes from the start, leaving the input at its start.
    pub(crate) fn head(&self, n: usize) -> io::Result<Vec<u8>> {
        match self {
            Input::File { file, .. } => {
                let mut f = file;
                let mut buf = vec![0u8; n];
                let got = super::raw::read_fully(&mut f, &mut buf)?;
                f.seek(SeekFrom::Start(0))?;
                buf.truncate(got);
                Ok(buf)
            }
            Input::Stream(bytes) => Ok(bytes[..n.min(bytes.len())].to_vec()),
        }
    }
}

/// Opens a FIFO or device without blocking (a FIFO nobody writes to would block
/// `open` forever), then switches it back to blocking reads: with no writer, reads end
/// at once.
fn open_stream(path: &Path) -> io::Result<File> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        use std::os::unix::io::AsRawFd;
        let f = std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path)?;
        let fd = f.as_raw_fd();
        // SAFETY: fcntl on a file descriptor this function owns.
        let flags = unsafe { libc::fcntl(fd, libc::F_GETFL) };
        if flags < 0 || unsafe { libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) } < 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(f)
    }
    #[cfg(not(unix))]
    {
        File::open(path)
    }
}

/// Loads an opened NRRD input.
pub(crate) fn load_input(input: Input, path: &Path) -> Result<Volume, VolumeError> {
    let base_dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut volume = match input {
        Input::File { file, len } => load_stream(BufReader::new(file), len, path, Some(base_dir))?,
        Input::Stream(bytes) => load_stream(
            Cursor::new(bytes.as_slice()),
            bytes.len() as u64,
            path,
            Some(base_dir),
        )?,
    };
    volume.source = Some(path.to_path_buf());
    Ok(volume)
}

/// The detached data file a regular NRRD header names, if it names one.
pub(crate) fn detached_data_file(path: &Path) -> Option<PathBuf> {
    if !std::fs::metadata(path).ok()?.is_file() {
        return None;
    }
    let mut r = BufReader::new(File::open(path).ok()?);
    let text = read_header(&mut r, path).ok()?;
    let header = parse_nrrd_header(&text.text, Some(path)).ok()?;
    let base = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    header.data_file.map(|d| base.join(d))
}

/// Loads an NRRD held in memory. `name` labels errors and gives the volume its
/// name (its file stem); a detached data file is looked up in `base_dir`, and is
/// an error without one.
pub fn load_nrrd_bytes(
    name: &str,
    bytes: &[u8],
    base_dir: Option<&Path>,
) -> Result<Volume, VolumeError> {
    load_stream(
        Cursor::new(bytes),
        bytes.len() as u64,
        Path::new(name),
        base_dir,
    )
}

/// The shared reader: header from `r`, data from `r` (attached) or from the
/// detached file.
fn load_stream<R: BufRead + Seek>(
    mut r: R,
    total_len: u64,
    file: &Path,
    base_dir: Option<&Path>,
) -> Result<Volume, VolumeError> {
    let header_text = read_header(&mut r, file)?;
    let header = parse_nrrd_header(&header_text.text, Some(file))?;
    let data = match &header.data_file {
        Some(data_file) => {
            let base = base_dir.ok_or_else(|| VolumeError::Header {
                file: Some(file.to_path_buf()),
                line: None,
                message: format!(
                    "detached data file '{}' cannot be opened without a base folder",
                    data_file.display()
                ),
            })?;
            let path = base.join(data_file);
            let context = format!("cannot open the data file named in {}", file.display());
            if let Ok(m) = std::fs::metadata(&path)
                && !m.is_file()
            {
                return Err(VolumeError::Unsupported {
                    file: path,
                    message: format!(
                        "the data file named in {} is not a regular file (a folder, FIFO or \
                         device); detached data must be a regular file",
                        file.display()
                    ),
                });
            }
            let f = File::open(&path).map_err(|e| io_error(&path, &context, e))?;
            let len = f
                .metadata()
                .map_err(|e| io_error(&path, "cannot read metadata", e))?
                .len();
            read_data(BufReader::new(f), 0, len, &header, &path)?
        }
        None => {
            if !header_text.ended_by_blank_line {
                return Err(VolumeError::Header {
                    file: Some(file.to_path_buf()),
                    line: None,
                    message: "no 'data file' field, and no blank line ending the header before \
                              attached data"
                        .to_owned(),
                });
            }
            read_data(r, header_text.len, total_len, &header, file)?
        }
    };
    let mut notes = Vec::new();
    if header.volumes > 1 {
        notes.push(format!(
            "a 4D series of {} volumes on the last axis ({}): the first is shown",
            header.volumes,
            header.extra_kind.as_deref().unwrap_or("no kind")
        ));
    }
    let data = if header.planar {
        notes.push(format!(
            "{} components stored on the last axis ({})",
            header.components,
            header.extra_kind.as_deref().unwrap_or("no kind")
        ));
        super::nifti::interleave(data, header.components as usize)
    } else {
        data
    };
    let mut reorder = super::orient::Reorder::IDENTITY;
    if let (Some(dirs), Some(space)) = (header.lps_directions, &header.space) {
        let (r, angle) = super::orient::reorder_for(&dirs);
        if header.components > 1 && !r.is_identity() {
            notes.push(format!(
                "space {space}: a vector volume keeps its stored axes (its components would \
                 have to turn with them)"
            ));
        } else {
            reorder = r;
            if angle > 0.5 {
                notes.push(format!(
                    "oblique by {angle:.1}°: snapped to the nearest axes without resampling"
                ));
            }
            notes.push(format!(
                "space {space}; axes to LPS: {}",
                super::nifti::describe(&reorder)
            ));
        }
    }
    let data = super::nifti::reorder_data(data, &reorder, header.dims, header.components as usize);
    let mut volume = Volume::new(
        name_from_path(file),
        reorder.apply(header.dims),
        header.components,
        reorder.apply(header.spacing),
        data,
    )
    .map_err(|e| e.in_file(file))?;
    volume.notes = notes;
    Ok(volume)
}

struct HeaderText {
    text: String,
    /// Bytes up to and including the blank line.
    len: u64,
    ended_by_blank_line: bool,
}

/// Reads header lines up to the blank line (or the end of the file), reading
/// no more than [`MAX_HEADER_BYTES`].
fn read_header<R: BufRead>(r: &mut R, file: &Path) -> Result<HeaderText, VolumeError> {
    let mut text = String::new();
    let mut len: u64 = 0;
    let mut line = Vec::new();
    let mut first = true;
    loop {
        line.clear();
        let n = r
            .by_ref()
            .take(MAX_HEADER_BYTES - len)
            .read_until(b'\n', &mut line)
            .map_err(|e| io_error(file, "cannot read the header", e))?;
        len += n as u64;
        if first {
            first = false;
            if !line.starts_with(b"NRRD000") {
                return Err(VolumeError::NotNrrd {
                    file: file.to_path_buf(),
                });
            }
        }
        if n == 0 {
            return Ok(HeaderText {
                text,
                len,
                ended_by_blank_line: false,
            });
        }
        if !line.ends_with(b"\n") && len >= MAX_HEADER_BYTES {
            return Err(VolumeError::Header {
                file: Some(file.to_path_buf()),
                line: None,
                message: format!(
                    "no end of header (a blank line) within the first {MAX_HEADER_BYTES} bytes"
                ),
            });
        }
        let content = String::from_utf8_lossy(&line);
        if content.trim().is_empty() {
            return Ok(HeaderText {
                text,
                len,
                ended_by_blank_line: true,
            });
        }
        text.push_str(&content);
        if !content.ends_with('\n') {
            // Last line of a file without a final newline.
            return Ok(HeaderText {
                text,
                len,
                ended_by_blank_line: false,
            });
        }
    }
}

/// Reads the samples of `header` from `r`, whose data region starts at byte
/// `start` of a file of `total_len` bytes named `file`.
fn read_data<R: BufRead + Seek>(
    mut r: R,
    start: u64,
    total_len: u64,
    header: &NrrdHeader,
    file: &Path,
) -> Result<super::VoxelData, VolumeError> {
    let needed = header.data_bytes();
    let count = header.value_count() as usize; // checked against the limits
    let layout = header.layout_text();
    let size_error = |skip: u64| VolumeError::DataSize {
        file: file.to_path_buf(),
        file_len: total_len,
        skip,
        needed,
        needed_by: "the header",
        layout: layout.clone(),
    };
    let alloc_error = |bytes| VolumeError::OutOfMemory {
        file: Some(file.to_path_buf()),
        bytes,
    };

    r.seek(SeekFrom::Start(start))
        .map_err(|e| io_error(file, "cannot seek", e))?;
    let mut pos = start;
    for _ in 0..header.line_skip {
        let n = r
            .skip_until(b'\n')
            .map_err(|e| io_error(file, "cannot read", e))?;
        if n == 0 {
            return Err(VolumeError::Invalid {
                file: Some(file.to_path_buf()),
                message: format!(
                    "the header's line skip of {} runs past the end of the file",
                    header.line_skip
                ),
            });
        }
        pos += n as u64;
    }

    match header.encoding {
        NrrdEncoding::Raw => {
            let data_start = match header.byte_skip {
                ByteSkip::FromEnd => {
                    // a series ends the file: its first volume starts that far before
                    let all = needed.saturating_mul(header.volumes);
                    if total_len.saturating_sub(pos) < all {
                        return Err(size_error(pos));
                    }
                    total_len - all
                }
                ByteSkip::Bytes(skip) => {
                    let data_start = pos.saturating_add(skip);
                    if total_len.saturating_sub(data_start) < needed {
                        return Err(size_error(data_start));
                    }
                    data_start
                }
            };
            r.seek(SeekFrom::Start(data_start))
                .map_err(|e| io_error(file, "cannot seek", e))?;
            read_samples(&mut r, header.data_type, header.endian, count).map_err(|f| match f {
                ReadFail::Io(e) => io_error(file, "cannot read", e),
                ReadFail::Alloc(bytes) => alloc_error(bytes),
                ReadFail::Short(_) => size_error(data_start),
            })
        }
        NrrdEncoding::Gzip | NrrdEncoding::Bzip2 => {
            let skip = match header.byte_skip {
                ByteSkip::Bytes(skip) => skip,
                // Rejected by the header parser; kept total for safety.
                ByteSkip::FromEnd => 0,
            };
            let name = if header.encoding == NrrdEncoding::Gzip {
                "gzip"
            } else {
                "bzip2"
            };
            let corrupt = |e: io::Error| VolumeError::Compressed {
                file: file.to_path_buf(),
                message: format!("the {name} data is corrupt: {e}"),
            };
            let decoder: Box<dyn Read + '_> = if header.encoding == NrrdEncoding::Gzip {
                // Peeks at the stream type first, so that empty data gets its own message.
                open_decoder(r, file)?
            } else {
                Box::new(bzip2::read::MultiBzDecoder::new(r))
            };
            decompress(
                decoder,
                total_len.saturating_sub(pos),
                skip,
                needed,
                count,
                header,
                file,
                &layout,
                name,
                corrupt,
            )
        }
        NrrdEncoding::Ascii => {
            if header.byte_skip != ByteSkip::Bytes(0) {
                return Err(VolumeError::Invalid {
                    file: Some(file.to_path_buf()),
                    message: "byte skip is not allowed with ascii encoding (use line skip)".into(),
                });
            }
            read_ascii(r, total_len.saturating_sub(pos), header, file, count)
        }
        NrrdEncoding::Hex => {
            if header.byte_skip != ByteSkip::Bytes(0) {
                return Err(VolumeError::Invalid {
                    file: Some(file.to_path_buf()),
                    message: "byte skip is not allowed with hex encoding (use line skip)".into(),
                });
            }
            let bytes = read_hex(r, total_len.saturating_sub(pos), header, file, needed)?;
            read_samples(
                &mut io::Cursor::new(bytes),
                header.data_type,
                header.endian,
                count,
            )
            .map_err(|f| match f {
                ReadFail::Io(e) => io_error(file, "cannot read the hex data", e),
                ReadFail::Alloc(bytes) => alloc_error(bytes),
                ReadFail::Short(_) => size_error(pos),
            })
        }
    }
}

/// Reads the `needed` bytes of hex-encoded data (two digits per byte, either case,
/// white space anywhere), bounded by the file length; the later volumes of a series
/// are left unread.
fn read_hex<R: Read>(
    r: R,
    available: u64,
    header: &NrrdHeader,
    file: &Path,
    needed: u64,
) -> Result<Vec<u8>, VolumeError> {
    let invalid = |message: String| VolumeError::Invalid {
        file: Some(file.to_path_buf()),
        message,
    };
    if needed.saturating_mul(2) > available {
        return Err(invalid(format!(
            "hex data of {available} bytes cannot hold the {needed} bytes the header needs ({})",
            header.layout_text()
        )));
    }
    let mut out: Vec<u8> = Vec::new();
    out.try_reserve_exact(needed as usize)
        .map_err(|_| VolumeError::OutOfMemory {
            file: Some(file.to_path_buf()),
            bytes: needed,
        })?;
    let mut high: Option<u8> = None;
    let mut digits = 0u64;
    for byte in io::BufReader::new(r).take(available).bytes() {
        let c = byte.map_err(|e| io_error(file, "cannot read the hex data", e))?;
        if c.is_ascii_whitespace() {
            continue;
        }
        digits += 1;
        let Some(nibble) = (c as char).to_digit(16) else {
            return Err(invalid(format!(
                "hex digit {digits} ('{}') is not a hexadecimal digit",
                c.escape_ascii()
            )));
        };
        if out.len() as u64 == needed {
            if header.volumes > 1 {
                break; // the later volumes of a series
            }
            return Err(invalid(format!(
                "hex data holds more than the {needed} bytes the header needs ({})",
                header.layout_text()
            )));
        }
        match high.take() {
            None => high = Some(nibble as u8),
            Some(h) => out.push(h << 4 | nibble as u8),
        }
    }
    if (out.len() as u64) < needed || high.is_some() {
        return Err(invalid(format!(
            "hex data holds {} digits but the header needs {} ({} bytes: {})",
            digits,
            needed * 2,
            needed,
            header.layout_text()
        )));
    }
    Ok(out)
}

/// Reads `count` decimal samples separated by white space (or commas) and converts them
/// to the type's in-memory type; the text is bounded by the file length.
fn read_ascii<R: Read>(
    r: R,
    available: u64,
    header: &NrrdHeader,
    file: &Path,
    count: usize,
) -> Result<super::VoxelData, VolumeError> {
    // a sample takes at least 2 bytes of text (a digit and a separator; the last one 1)
    if (count as u64).saturating_mul(2).saturating_sub(1) > available {
        return Err(VolumeError::Invalid {
            file: Some(file.to_path_buf()),
            message: format!(
                "ascii data of {available} bytes cannot hold the {count} samples the header needs ({})",
                header.layout_text()
            ),
        });
    }
    let mut text = String::new();
    io::BufReader::new(r)
        .take(available)
        .read_to_string(&mut text)
        .map_err(|e| io_error(file, "cannot read the ascii data", e))?;
    let mut values: Vec<f64> = Vec::new();
    values
        .try_reserve_exact(count)
        .map_err(|_| VolumeError::OutOfMemory {
            file: Some(file.to_path_buf()),
            bytes: count as u64 * 8,
        })?;
    for (i, tok) in text
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty())
        .enumerate()
    {
        if i >= count && header.volumes > 1 {
            break; // the later volumes of a series
        }
        if i >= count {
            return Err(VolumeError::Invalid {
                file: Some(file.to_path_buf()),
                message: format!(
                    "ascii data holds more than the {count} samples the header needs ({})",
                    header.layout_text()
                ),
            });
        }
        let v: f64 = tok.parse().map_err(|_| VolumeError::Invalid {
            file: Some(file.to_path_buf()),
            message: format!("ascii sample {} ('{tok}') is not a number", i + 1),
        })?;
        values.push(v);
    }
    if values.len() < count {
        return Err(VolumeError::Invalid {
            file: Some(file.to_path_buf()),
            message: format!(
                "ascii data holds {} samples but the header needs {count} ({})",
                values.len(),
                header.layout_text()
            ),
        });
    }
    let out_of_range = |i: usize, v: f64| VolumeError::Invalid {
        file: Some(file.to_path_buf()),
        message: format!(
            "ascii sample {} = {v} does not fit the header's type {}",
            i + 1,
            header.data_type.name()
        ),
    };
    macro_rules! ints {
        ($t:ty, $variant:ident) => {{
            let mut out = Vec::with_capacity(count);
            for (i, &v) in values.iter().enumerate() {
                if v.fract() != 0.0 || v < <$t>::MIN as f64 || v > <$t>::MAX as f64 {
                    return Err(out_of_range(i, v));
                }
                out.push(v as $t);
            }
            super::VoxelData::$variant(out)
        }};
    }
    Ok(match header.data_type {
        NrrdType::UInt8 => ints!(u8, U8),
        NrrdType::Int8 => ints!(i8, I8),
        NrrdType::UInt16 => ints!(u16, U16),
        NrrdType::Int16 => ints!(i16, I16),
        _ => super::VoxelData::F32(values.iter().map(|&v| v as f32).collect()),
    })
}

/// Decompressed samples after `skip` bytes: exactly `needed` bytes must follow, and a
/// stream that decodes longer is checked to its end so that its checksum decides between
/// a corrupt stream and a wrong header.
#[allow(clippy::too_many_arguments)]
fn decompress<'a>(
    mut decoder: Box<dyn Read + 'a>,
    compressed: u64,
    skip: u64,
    needed: u64,
    count: usize,
    header: &NrrdHeader,
    file: &Path,
    layout: &str,
    name: &str,
    corrupt: impl Fn(io::Error) -> VolumeError,
) -> Result<super::VoxelData, VolumeError> {
    let alloc_error = |bytes| VolumeError::OutOfMemory {
        file: Some(file.to_path_buf()),
        bytes,
    };
    let wanted = skip.saturating_add(needed);
    if wanted > compressed.saturating_mul(MAX_DEFLATE_RATIO) {
        return Err(VolumeError::Compressed {
            file: file.to_path_buf(),
            message: format!(
                "the header needs {needed} bytes ({layout}) but {compressed} bytes of \
                 {name} data cannot decompress to that much"
            ),
        });
    }
    if skip > 0 {
        let skipped =
            io::copy(&mut decoder.by_ref().take(skip), &mut io::sink()).map_err(&corrupt)?;
        if skipped < skip {
            return Err(VolumeError::Compressed {
                file: file.to_path_buf(),
                message: format!(
                    "{name} data ends after {skipped} bytes, before the byte skip of {skip}"
                ),
            });
        }
    }
    let mut limited = decoder.take(needed + 1);
    let data =
        read_samples(&mut limited, header.data_type, header.endian, count).map_err(
            |f| match f {
                ReadFail::Io(e) => corrupt(e),
                ReadFail::Alloc(bytes) => alloc_error(bytes),
                ReadFail::Short(got) => VolumeError::Compressed {
                    file: file.to_path_buf(),
                    message: format!(
                        "{name} data ends after {got} bytes but the header needs {needed} \
                     ({layout}): the {name} stream is truncated or the header's sizes \
                     or type are wrong"
                    ),
                },
            },
        )?;
    let mut extra = [0u8; 1];
    // a series goes on after its first volume
    if header.volumes == 1
        && super::raw::read_fully(&mut limited, &mut extra).map_err(&corrupt)? > 0
    {
        // Decompress the rest (bounded by deflate's ratio) so that the stream's
        // checksum decides between a corrupt stream and a wrong header.
        let mut rest = limited.into_inner();
        let bound = compressed.saturating_mul(MAX_DEFLATE_RATIO);
        let more = io::copy(&mut rest.by_ref().take(bound), &mut io::sink()).map_err(&corrupt)?;
        return Err(VolumeError::Compressed {
            file: file.to_path_buf(),
            message: format!(
                "the {name} data is intact but decompresses to {} bytes, more than the \
                 {needed} bytes the header needs ({layout}); the header's sizes or \
                 type are probably wrong",
                skip + needed + 1 + more
            ),
        });
    }
    Ok(data)
}

/// A gzip decoder, or a zlib one for writers that store zlib streams.
fn open_decoder<'a, R: BufRead + 'a>(
    mut r: R,
    file: &Path,
) -> Result<Box<dyn Read + 'a>, VolumeError> {
    let head = r.fill_buf().map_err(|e| io_error(file, "cannot read", e))?;
    match head {
        [0x1f, 0x8b, ..] => Ok(Box::new(GzDecoder::new(r))),
        [cmf, flg, ..] if cmf & 0x0f == 8 && (u16::from(*cmf) << 8 | u16::from(*flg)) % 31 == 0 => {
            Ok(Box::new(ZlibDecoder::new(r)))
        }
        [] => Err(VolumeError::Compressed {
            file: file.to_path_buf(),
            message: "encoding is gzip but there is no data after the header".to_owned(),
        }),
        _ => Err(VolumeError::Compressed {
            file: file.to_path_buf(),
            message: "encoding is gzip but the data does not start with a gzip header".to_owned(),
        }),
    }
}
