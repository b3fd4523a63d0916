//! OME-Zarr reader (through the `zarrs` crate): a multiscale image's levels become a
//! level-of-detail [`Pyramid`].
//!
//! What is read:
//! - **Stores:** a folder on disk holding Zarr v2 (`.zgroup`, `.zattrs`, `.zarray`) or
//!   Zarr v3 (`zarr.json`) metadata. The codecs are those `zarrs` is built with here:
//!   blosc, gzip, zlib, zstd, sharding (with crc32c), and none.
//! - **OME-NGFF multiscales** (`multiscales` in the group's attributes, under `ome`
//!   since NGFF 0.5): every dataset is a level, finest first. Axes may be objects
//!   (`{"name": "z", "type": "space"}`, NGFF 0.4 on) or names (0.3); without axes (0.1,
//!   0.2) the array is t, c, z, y, x. Spacing is each level's `scale` transformation times
//!   the multiscale's own, for the three spatial axes; translations place the levels and
//!   are not needed for the voxels.
//! - **A plain array** (a store whose root is an array, or a group without multiscales
//!   that holds one array at `0`): one level, spacing 1.
//! - **Axes:** the last three spatial axes are z, y, x (NGFF orders them so, x fastest,
//!   which is vwb's voxel order: no transposition). Time and channel axes take their
//!   first index, with a note. Fewer than three spatial axes is refused.
//! - **Types:** uint8, int8, uint16, int16 and float32 load as they are; uint32, int32,
//!   uint64, int64, float16 and float64 become f32 (noted).
//! - **Orientation:** NGFF records none; the axes are shown as stored (noted).
//!
//! Levels load on their own ([`load_level`]): the renderer reads a coarser stored level
//! under a GPU memory budget instead of averaging the full one
//! (`renderer::level`), and [`load_within`] reads only the level a budget allows, so a
//! volume larger than memory shows at once.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::Value;
use zarrs::array::{Array, ArraySubset, ElementOwned, data_type as dt};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::Group;

use super::{Volume, VolumeError, VoxelData, check_layout, check_spacing, report_progress};

/// The stored levels of detail of an OME-Zarr image, finest first.
#[derive(Debug, Clone, PartialEq)]
pub struct Pyramid {
    /// The store (folder) the levels are read from.
    pub root: PathBuf,
    pub levels: Vec<PyramidLevel>,
    /// The level the volume holds (0: the finest).
    pub shown: usize,
}

/// One stored level: its array path in the store, voxel counts and spacing (x, y, z).
#[derive(Debug, Clone, PartialEq)]
pub struct PyramidLevel {
    pub path: String,
    pub dims: [u32; 3],
    pub spacing: [f64; 3],
}

impl Pyramid {
    /// Voxels of level 0 per voxel of level `i` along x (rounded; 1 for level 0).
    pub fn factor(&self, i: usize) -> u32 {
        let (full, level) = (self.levels[0].dims[0], self.levels[i].dims[0].max(1));
        ((f64::from(full) / f64::from(level)).round() as u32).max(1)
    }

    /// The finest level whose voxels, at `bytes_per_voxel`, take at most `bytes`.
    pub fn finest_within(&self, bytes: u64, bytes_per_voxel: u64) -> Option<usize> {
        self.levels.iter().position(|l| {
            l.dims.iter().map(|&d| u64::from(d)).product::<u64>() * bytes_per_voxel <= bytes
        })
    }
}

/// Whether `path` is a Zarr store (a folder with Zarr v2 or v3 metadata).
pub fn is_zarr(path: &Path) -> bool {
    path.is_dir()
        && [".zattrs", ".zgroup", ".zarray", "zarr.json"]
            .iter()
            .any(|f| path.join(f).is_file())
}

/// Every file in the store (metadata and chunks, of every level), for the size of a
/// load and for checks that an output never overwrites an input.
pub fn files(path: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut dirs = vec![path.to_path_buf()];
    while let Some(dir) = dirs.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            match e.file_type() {
                Ok(t) if t.is_dir() => dirs.push(e.path()),
                Ok(t) if t.is_file() => out.push(e.path()),
                _ => {}
            }
        }
    }
    out.sort();
    out
}

/// The image's levels, without reading any voxel.
pub fn pyramid(path: &Path) -> Result<Pyramid, VolumeError> {
    Ok(open(path)?.pyramid)
}

/// Loads level 0, the full resolution.
pub fn load(path: &Path) -> Result<Volume, VolumeError> {
    load_level(path, 0)
}

/// Loads level `level` (0: the finest) of the image.
pub fn load_level(path: &Path, level: usize) -> Result<Volume, VolumeError> {
    open(path)?.read(level, None)
}

/// Loads the voxels `region` ([start, end) per axis x, y, z, in that level's voxels)
/// of level `level`: a brick refined in view. Its spacing is the level's.
pub fn load_region(
    path: &Path,
    level: usize,
    region: [[u32; 2]; 3],
) -> Result<Volume, VolumeError> {
    open(path)?.read(level, Some(region))
}

/// Loads the finest level whose samples, at `bytes_per_voxel`, take at most `bytes`
/// (the coarsest when none does); level 0 when `bytes` is `None`.
pub fn load_within(
    path: &Path,
    bytes: Option<u64>,
    bytes_per_voxel: u64,
) -> Result<Volume, VolumeError> {
    let image = open(path)?;
    let level = match bytes {
        None => 0,
        Some(b) => image
            .pyramid
            .finest_within(b, bytes_per_voxel)
            .unwrap_or(image.pyramid.levels.len() - 1),
    };
    image.read(level, None)
}

/// An opened image: its store, pyramid and axes.
struct Image {
    store: Arc<FilesystemStore>,
    pyramid: Pyramid,
    /// NGFF version, or "none" for a plain array.
    version: String,
    /// Index of the z, y, x axes in the arrays' shape.
    spatial: [usize; 3],
    /// Names of the axes, for notes.
    axes: Vec<(String, String)>,
    unit: Option<String>,
}

fn invalid(path: &Path, message: impl Into<String>) -> VolumeError {
    VolumeError::Invalid {
        file: Some(path.to_path_buf()),
        message: message.into(),
    }
}

fn open(path: &Path) -> Result<Image, VolumeError> {
    if !is_zarr(path) {
        return Err(invalid(
            path,
            "not a Zarr store: a folder with .zattrs/.zgroup/.zarray (Zarr v2) or zarr.json \
             (Zarr v3) is expected",
        ));
    }
    let store = Arc::new(
        FilesystemStore::new(path).map_err(|e| invalid(path, format!("cannot open: {e}")))?,
    );
    let root_is_array = path.join(".zarray").is_file()
        || std::fs::read_to_string(path.join("zarr.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<Value>(&t).ok())
            .is_some_and(|v| v["node_type"] == "array");
    let attributes = if root_is_array {
        serde_json::Map::new()
    } else {
        Group::open(store.clone(), "/")
            .map_err(|e| invalid(path, format!("cannot read the group's metadata: {e}")))?
            .attributes()
            .clone()
    };
    let (version, multiscale) = match (
        attributes.get("multiscales"),
        attributes.get("ome").and_then(|o| o.get("multiscales")),
    ) {
        (Some(m), _) => (
            m[0]["version"].as_str().unwrap_or("0.4").to_owned(),
            Some(m),
        ),
        (None, Some(m)) => (
            attributes["ome"]["version"]
                .as_str()
                .unwrap_or("0.5")
                .to_owned(),
            Some(m),
        ),
        (None, None) => ("none".to_owned(), None),
    };
    let Some(multiscale) = multiscale else {
        // a plain array: at the root, or at "0"
        let at = if root_is_array { "/" } else { "/0" };
        let array = open_array(&store, path, at)?;
        let n = array.shape().len();
        if n < 3 {
            return Err(invalid(
                path,
                format!("a {n}-dimensional array: vwb renders 3D volumes (3 to 5 axes)"),
            ));
        }
        let dims = zyx_dims(path, array.shape(), [n - 3, n - 2, n - 1])?;
        return Ok(Image {
            store,
            pyramid: Pyramid {
                root: path.to_path_buf(),
                levels: vec![PyramidLevel {
                    path: at.to_owned(),
                    dims,
                    spacing: [1.0; 3],
                }],
                shown: 0,
            },
            version,
            spatial: [n - 3, n - 2, n - 1],
            axes: Vec::new(),
            unit: None,
        });
    };
    let ms = multiscale
        .get(0)
        .ok_or_else(|| invalid(path, "'multiscales' lists no image"))?;
    let datasets = ms["datasets"]
        .as_array()
        .filter(|d| !d.is_empty())
        .ok_or_else(|| invalid(path, "the multiscale image lists no datasets (levels)"))?;
    // axes: objects (0.4+), names (0.3), or absent (0.1/0.2: t, c, z, y, x)
    let axes: Vec<(String, String)> = match ms.get("axes").and_then(Value::as_array) {
        Some(list) => list
            .iter()
            .map(|a| match a {
                Value::String(name) => (name.clone(), kind_of_name(name).to_owned()),
                other => {
                    let name = other["name"].as_str().unwrap_or("").to_owned();
                    let kind = other["type"]
                        .as_str()
                        .map(str::to_owned)
                        .unwrap_or_else(|| kind_of_name(&name).to_owned());
                    (name, kind)
                }
            })
            .collect(),
        None => ["t", "c", "z", "y", "x"]
            .iter()
            .map(|n| (n.to_string(), kind_of_name(n).to_owned()))
            .collect(),
    };
    let space: Vec<usize> = (0..axes.len()).filter(|&i| axes[i].1 == "space").collect();
    if space.len() < 3 {
        return Err(invalid(
            path,
            format!(
                "{} spatial axes ({}): vwb renders 3D volumes",
                space.len(),
                axes.iter()
                    .map(|a| a.0.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    let spatial = [
        space[space.len() - 3],
        space[space.len() - 2],
        space[space.len() - 1],
    ];
    let unit = ms["axes"]
        .get(spatial[2])
        .and_then(|a| a["unit"].as_str())
        .map(str::to_owned);
    let global = scale_of(&ms["coordinateTransformations"], axes.len());
    let mut levels = Vec::with_capacity(datasets.len());
    for (i, d) in datasets.iter().enumerate() {
        let at = d["path"]
            .as_str()
            .ok_or_else(|| invalid(path, format!("dataset {i} has no 'path'")))?;
        let at = format!("/{}", at.trim_start_matches('/'));
        let array = open_array(&store, path, &at)?;
        if array.shape().len() != axes.len() {
            return Err(invalid(
                path,
                format!(
                    "level {at}: {} dimensions where the image has {} axes",
                    array.shape().len(),
                    axes.len()
                ),
            ));
        }
        let dims = zyx_dims(path, array.shape(), spatial)?;
        let scale = scale_of(&d["coordinateTransformations"], axes.len());
        let s = |k: usize| scale[spatial[k]] * global[spatial[k]];
        let spacing = [s(2), s(1), s(0)];
        check_spacing(spacing, Some(path)).map_err(|e| match e {
            VolumeError::Invalid { file, message } => VolumeError::Invalid {
                file,
                message: format!("level {at}: {message}"),
            },
            other => other,
        })?;
        levels.push(PyramidLevel {
            path: at,
            dims,
            spacing,
        });
    }
    Ok(Image {
        store,
        pyramid: Pyramid {
            root: path.to_path_buf(),
            levels,
            shown: 0,
        },
        version,
        spatial,
        axes,
        unit,
    })
}

/// The NGFF axis type implied by a name (for axes given by name only).
fn kind_of_name(name: &str) -> &'static str {
    match name {
        "t" => "time",
        "c" => "channel",
        "x" | "y" | "z" => "space",
        _ => "",
    }
}

/// The product of the `scale` transformations in a `coordinateTransformations` list
/// (1 per axis when there is none).
fn scale_of(transforms: &Value, n: usize) -> Vec<f64> {
    let mut scale = vec![1.0; n];
    for t in transforms.as_array().into_iter().flatten() {
        if t["type"] == "scale"
            && let Some(s) = t["scale"].as_array()
            && s.len() == n
        {
            for (a, v) in scale.iter_mut().zip(s) {
                *a *= v.as_f64().unwrap_or(f64::NAN);
            }
        }
    }
    scale
}

fn open_array(
    store: &Arc<FilesystemStore>,
    path: &Path,
    at: &str,
) -> Result<Array<FilesystemStore>, VolumeError> {
    Array::open(store.clone(), at)
        .map_err(|e| invalid(path, format!("cannot open the array {at}: {e}")))
}

/// The x, y, z voxel counts of a shape whose z, y, x axes are `spatial`.
fn zyx_dims(path: &Path, shape: &[u64], spatial: [usize; 3]) -> Result<[u32; 3], VolumeError> {
    let dims = [shape[spatial[2]], shape[spatial[1]], shape[spatial[0]]];
    // checked without allocating: a lying shape fails here
    Ok(check_layout(dims, 1, 4, Some(path))?.dims)
}

impl Image {
    /// Reads level `level`, or its voxels `region` (x, y, z ranges) only.
    fn read(mut self, level: usize, region: Option<[[u32; 2]; 3]>) -> Result<Volume, VolumeError> {
        let path = self.pyramid.root.clone();
        let Some(info) = self.pyramid.levels.get(level).cloned() else {
            return Err(invalid(
                &path,
                format!(
                    "level {level}: the image has {} level(s)",
                    self.pyramid.levels.len()
                ),
            ));
        };
        let array = open_array(&self.store, &path, &info.path)?;
        let shape = array.shape().to_vec();
        let mut notes = Vec::new();
        for (i, &n) in shape.iter().enumerate() {
            if !self.spatial.contains(&i) && n > 1 {
                let (name, kind) = self
                    .axes
                    .get(i)
                    .cloned()
                    .unwrap_or_else(|| (format!("axis {i}"), String::new()));
                let what = if kind.is_empty() {
                    "axis"
                } else {
                    kind.as_str()
                };
                notes.push(format!(
                    "the first {what} index of {n} read ({what} axis '{name}')"
                ));
            }
        }
        let region = region.unwrap_or(info.dims.map(|n| [0, n]));
        if (0..3).any(|a| region[a][0] >= region[a][1] || region[a][1] > info.dims[a]) {
            return Err(invalid(
                &path,
                format!(
                    "level {level}: region {region:?} outside {:?} voxels",
                    info.dims
                ),
            ));
        }
        let dims = region.map(|[a, b]| b - a);
        let [w, h, d] = dims.map(u64::from);
        let origin = region.map(|[a, _]| u64::from(a));
        let z = self.spatial[0];
        // read slabs of whole chunks along z, so progress shows and a cancel stops it
        let chunk: Vec<u64> = array
            .chunk_shape(&vec![0; shape.len()])
            .map(|c| c.iter().map(|n| n.get()).collect())
            .unwrap_or_else(|_| vec![1; shape.len()]);
        let chunk_z = chunk[z].max(1);
        // a chunk decodes whole: a lying chunk shape must fail before it allocates
        let chunk_bytes = chunk
            .iter()
            .try_fold(8u64, |acc, &n| acc.checked_mul(n))
            .unwrap_or(u64::MAX);
        let limit = super::available_memory()
            .unwrap_or(u64::MAX)
            .min(super::MAX_BYTES);
        if chunk_bytes > limit {
            return Err(VolumeError::TooLarge {
                file: Some(path.clone()),
                dims: [w, h, d],
                reason: format!(
                    "are stored in chunks of {chunk:?} samples, about {chunk_bytes} bytes to \
                     decode each (at most 8 bytes a sample), more than the {limit} bytes \
                     available"
                ),
            });
        }
        let subset = |z0: u64, z1: u64| {
            let ranges: Vec<std::ops::Range<u64>> = (0..shape.len())
                .map(|i| {
                    if i == z {
                        origin[2] + z0..origin[2] + z1
                    } else if i == self.spatial[1] {
                        origin[1]..origin[1] + h
                    } else if i == self.spatial[2] {
                        origin[0]..origin[0] + w
                    } else {
                        0..1
                    }
                })
                .collect();
            ArraySubset::new_with_ranges(&ranges)
        };
        let ty = array.data_type();
        // one slab reader per element type, converting with `$conv`
        macro_rules! read {
            ($conv:expr) => {
                slabs(&array, &path, d, chunk_z, &subset, $conv)?
            };
        }
        let data = if ty.is::<dt::UInt8DataType>() {
            VoxelData::U8(read!(|v: u8| v))
        } else if ty.is::<dt::Int8DataType>() {
            VoxelData::I8(read!(|v: i8| v))
        } else if ty.is::<dt::UInt16DataType>() {
            VoxelData::U16(read!(|v: u16| v))
        } else if ty.is::<dt::Int16DataType>() {
            VoxelData::I16(read!(|v: i16| v))
        } else if ty.is::<dt::Float32DataType>() {
            VoxelData::F32(read!(|v: f32| v))
        } else if ty.is::<dt::UInt32DataType>() {
            VoxelData::F32(read!(|v: u32| v as f32))
        } else if ty.is::<dt::Int32DataType>() {
            VoxelData::F32(read!(|v: i32| v as f32))
        } else if ty.is::<dt::UInt64DataType>() {
            VoxelData::F32(read!(|v: u64| v as f32))
        } else if ty.is::<dt::Int64DataType>() {
            VoxelData::F32(read!(|v: i64| v as f32))
        } else if ty.is::<dt::Float64DataType>() {
            VoxelData::F32(read!(|v: f64| v as f32))
        } else if ty.is::<dt::Float16DataType>() {
            VoxelData::F32(read!(|v: half::f16| v.to_f32()))
        } else {
            return Err(VolumeError::Unsupported {
                file: path.clone(),
                message: format!(
                    "array {}: data type {:?}: vwb reads integers and floats",
                    info.path,
                    ty.name(zarrs::plugin::ZarrVersion::V3)
                ),
            });
        };
        // every type without a voxel type of its own became f32
        if matches!(data, VoxelData::F32(_)) && !ty.is::<dt::Float32DataType>() {
            notes.push(format!(
                "data type {} converted to float32",
                ty.name(zarrs::plugin::ZarrVersion::V3).unwrap_or_default()
            ));
        }
        let name = store_name(&path);
        let mut volume =
            Volume::new(name, dims, 1, info.spacing, data).map_err(|e| e.in_file(&path))?;
        let sizes: Vec<String> = self
            .pyramid
            .levels
            .iter()
            .map(|l| format!("{}x{}x{}", l.dims[0], l.dims[1], l.dims[2]))
            .collect();
        let mut head = vec![format!(
            "OME-Zarr (NGFF {}): level {} of {} read ({}), array {}",
            self.version,
            level,
            sizes.len(),
            sizes.join(", "),
            info.path
        )];
        if self.version != "none" {
            let unit = self
                .unit
                .as_deref()
                .map(|u| format!(" in {u}"))
                .unwrap_or_default();
            head.push(format!(
                "no anatomical orientation in OME-Zarr: x, y, z as stored; spacing{unit} from \
                 the level's scale"
            ));
        }
        head.extend(notes);
        volume.notes = head;
        volume.source = Some(path);
        self.pyramid.shown = level;
        volume.pyramid = Some(self.pyramid);
        Ok(volume)
    }
}

/// The volume's name: the folder's name without `.zarr` / `.ome.zarr`.
fn store_name(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "volume".to_owned());
    let lower = name.to_ascii_lowercase();
    for ext in [".ome.zarr", ".zarr"] {
        if lower.ends_with(ext) && name.len() > ext.len() {
            return name[..name.len() - ext.len()].to_owned();
        }
    }
    name
}

/// Reads `depth` z planes in slabs of `chunk_z`, converting each sample with `conv`.
fn slabs<T: ElementOwned + Copy, U>(
    array: &Array<FilesystemStore>,
    path: &Path,
    depth: u64,
    chunk_z: u64,
    subset: &dyn Fn(u64, u64) -> ArraySubset,
    conv: impl Fn(T) -> U,
) -> Result<Vec<U>, VolumeError> {
    let mut out: Vec<U> = Vec::new();
    let plane = subset(0, 1).num_elements_usize();
    out.try_reserve_exact(plane * depth as usize)
        .map_err(|_| VolumeError::OutOfMemory {
            file: Some(path.to_path_buf()),
            bytes: (plane as u64 * depth).saturating_mul(std::mem::size_of::<U>() as u64),
        })?;
    let mut z0 = 0;
    while z0 < depth {
        let z1 = (z0 + chunk_z).min(depth);
        let slab: Vec<T> =
            array
                .retrieve_array_subset(&subset(z0, z1))
                .map_err(|e| VolumeError::Compressed {
                    file: path.to_path_buf(),
                    message: format!("planes {z0}..{z1}: {e}"),
                })?;
        out.extend(slab.into_iter().map(&conv));
        if !report_progress(z1 * plane as u64, depth * plane as u64) {
            return Err(super::raw::io_error(
                path,
                "cannot finish reading",
                std::io::Error::new(std::io::ErrorKind::Interrupted, "cancelled"),
            ));
        }
        z0 = z1;
    }
    Ok(out)
}

/// Writes `levels` (finest first, scalar volumes) as an OME-Zarr image (NGFF 0.5, Zarr
/// v3, gzip, chunks of up to 64³) at `path`, a new folder. For tests and conversions:
/// vwb itself only reads.
pub fn write(path: &Path, levels: &[&Volume]) -> Result<(), VolumeError> {
    use zarrs::array::ArrayBuilder;
    use zarrs::array::codec::GzipCodec;
    use zarrs::group::GroupBuilder;
    let fail = |what: &str, e: &dyn std::fmt::Display| invalid(path, format!("{what}: {e}"));
    std::fs::create_dir_all(path).map_err(|e| super::raw::io_error(path, "cannot create", e))?;
    let store =
        Arc::new(FilesystemStore::new(path).map_err(|e| fail("cannot open the store", &e))?);
    let mut datasets = Vec::new();
    for (i, v) in levels.iter().enumerate() {
        if v.components != 1 {
            return Err(invalid(path, "OME-Zarr output is for scalar volumes"));
        }
        let shape = vec![
            u64::from(v.dims[2]),
            u64::from(v.dims[1]),
            u64::from(v.dims[0]),
        ];
        let chunks: Vec<u64> = shape.iter().map(|&n| n.min(64)).collect();
        let builder = |ty: zarrs::array::DataType, fill: zarrs::array::FillValue| {
            let mut b = ArrayBuilder::new(shape.clone(), chunks.clone(), ty, fill);
            b.bytes_to_bytes_codecs(vec![Arc::new(GzipCodec::new(5).expect("level 5"))])
                .dimension_names(["z", "y", "x"].into());
            b
        };
        let at = format!("/{i}");
        let all = ArraySubset::new_with_shape(shape.clone());
        let stored = match &v.data {
            VoxelData::U8(d) => {
                store_level(&builder(dt::uint8(), 0u8.into()), &store, &at, &all, d)
            }
            VoxelData::I8(d) => store_level(&builder(dt::int8(), 0i8.into()), &store, &at, &all, d),
            VoxelData::U16(d) => {
                store_level(&builder(dt::uint16(), 0u16.into()), &store, &at, &all, d)
            }
            VoxelData::I16(d) => {
                store_level(&builder(dt::int16(), 0i16.into()), &store, &at, &all, d)
            }
            VoxelData::F32(d) => {
                store_level(&builder(dt::float32(), 0f32.into()), &store, &at, &all, d)
            }
        };
        stored.map_err(|e| fail(&format!("level {i}"), &e))?;
        let [sx, sy, sz] = v.spacing;
        datasets.push(serde_json::json!({
            "path": i.to_string(),
            "coordinateTransformations": [{"type": "scale", "scale": [sz, sy, sx]}]
        }));
    }
    let attributes = serde_json::json!({"ome": {"version": "0.5", "multiscales": [{
        "name": levels.first().map(|v| v.name.as_str()).unwrap_or("volume"),
        "axes": [
            {"name": "z", "type": "space"},
            {"name": "y", "type": "space"},
            {"name": "x", "type": "space"}
        ],
        "datasets": datasets
    }]}});
    let Value::Object(attributes) = attributes else {
        unreachable!("a JSON object literal")
    };
    GroupBuilder::new()
        .attributes(attributes)
        .build(store.clone(), "/")
        .map_err(|e| fail("the group", &e))?
        .store_metadata()
        .map_err(|e| fail("the group's metadata", &e))
}

fn store_level<T: zarrs::array::Element>(
    builder: &zarrs::array::ArrayBuilder,
    store: &Arc<FilesystemStore>,
    at: &str,
    all: &ArraySubset,
    data: &[T],
) -> Result<(), zarrs::array::ArrayError> {
    let array = builder
        .build(store.clone(), at)
        .map_err(|e| zarrs::array::ArrayError::Other(e.to_string()))?;
    array.store_metadata()?;
    array.store_array_subset(all, data)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write as _;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("vwb-zarr-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    fn ramp() -> Volume {
        let dims = [10u32, 7, 5];
        let data = (0..350u32)
            .map(|i| (i % 10 + 10 * ((i / 10) % 7) + 100 * (i / 70)) as u16)
            .collect();
        Volume::new("ramp", dims, 1, [0.5, 0.75, 2.0], VoxelData::U16(data)).unwrap()
    }

    #[test]
    fn a_written_pyramid_reads_back_level_by_level() {
        let full = ramp();
        let mut half = crate::renderer::halve(&full).unwrap();
        half.spacing = [1.0, 1.5, 4.0];
        let dir = scratch("pyramid").join("ramp.ome.zarr");
        write(&dir, &[&full, &half]).unwrap();
        assert!(is_zarr(&dir));
        // through the format-sniffing entry point
        let v = super::super::load(&dir).unwrap();
        assert_eq!(
            (v.name.as_str(), v.dims, v.spacing),
            ("ramp", full.dims, full.spacing)
        );
        assert_eq!(v.data, full.data);
        assert_eq!(v.range, full.range);
        assert!(v.notes[0].contains("NGFF 0.5") && v.notes[0].contains("level 0 of 2"));
        let p = v.pyramid.as_ref().unwrap();
        assert_eq!(p.levels.len(), 2);
        assert_eq!(
            (p.levels[1].dims, p.levels[1].spacing),
            ([5, 4, 3], half.spacing)
        );
        assert_eq!((p.shown, p.factor(1)), (0, 2));
        let l1 = load_level(&dir, 1).unwrap();
        assert_eq!((l1.dims, &l1.data), (half.dims, &half.data));
        assert_eq!(l1.pyramid.as_ref().unwrap().shown, 1);
        // the finest level that fits: 350 voxels × 4 bytes do not fit 1000, 60 × 4 do
        assert_eq!(load_within(&dir, Some(1000), 4).unwrap().dims, [5, 4, 3]);
        assert_eq!(load_within(&dir, Some(1400), 4).unwrap().dims, full.dims);
        assert_eq!(load_within(&dir, Some(1), 4).unwrap().dims, [5, 4, 3]);
        assert!(
            load_level(&dir, 2)
                .unwrap_err()
                .to_string()
                .contains("2 level(s)")
        );
        // every file of the store counts as an input
        let files = super::super::input_files(&dir);
        assert!(files.len() > 3 && files.iter().all(|f| f.starts_with(&dir)));
        std::fs::remove_dir_all(dir.parent().unwrap()).unwrap();
    }

    /// An NGFF 0.4 image written by hand as Zarr v2 (independently of zarrs): a channel
    /// axis, zlib chunks with "/" keys, partial edge chunks, and scales on the dataset
    /// and on the multiscale.
    fn v2_image(dir: &Path, shape_zyx: [u64; 3], zarray_extra: &str) {
        std::fs::create_dir_all(dir.join("0")).unwrap();
        std::fs::write(dir.join(".zgroup"), r#"{"zarr_format": 2}"#).unwrap();
        std::fs::write(
            dir.join(".zattrs"),
            r#"{"multiscales": [{"version": "0.4", "axes": [
                {"name": "c", "type": "channel"},
                {"name": "z", "type": "space", "unit": "micrometer"},
                {"name": "y", "type": "space", "unit": "micrometer"},
                {"name": "x", "type": "space", "unit": "micrometer"}],
              "datasets": [{"path": "0", "coordinateTransformations":
                [{"type": "scale", "scale": [1, 2.0, 0.5, 0.25]}]}],
              "coordinateTransformations": [{"type": "scale", "scale": [1, 1, 2, 2]}]}]}"#,
        )
        .unwrap();
        let [d, h, w] = shape_zyx;
        std::fs::write(
            dir.join("0/.zarray"),
            format!(
                r#"{{"zarr_format": 2, "shape": [2, {d}, {h}, {w}], "chunks": [1, 2, 4, 5],
                "dtype": "<i2", "compressor": {{"id": "zlib", "level": 1}}, "fill_value": 0,
                "order": "C", "filters": null, "dimension_separator": "/"{zarray_extra}}}"#
            ),
        )
        .unwrap();
        // value of (c, z, y, x): ±(x + 10 y + 100 z), negative in channel 1
        for c in 0..2u64 {
            for cz in 0..d.div_ceil(2) {
                for cy in 0..h.div_ceil(4) {
                    for cx in 0..w.div_ceil(5) {
                        let mut raw = Vec::new();
                        for z in 2 * cz..2 * cz + 2 {
                            for y in 4 * cy..4 * cy + 4 {
                                for x in 5 * cx..5 * cx + 5 {
                                    let v = (x + 10 * y + 100 * z) as i16;
                                    raw.extend(if c == 0 { v } else { -v }.to_le_bytes());
                                }
                            }
                        }
                        let key = dir.join(format!("0/{c}/{cz}/{cy}"));
                        std::fs::create_dir_all(&key).unwrap();
                        let mut z = flate2::write::ZlibEncoder::new(
                            Vec::new(),
                            flate2::Compression::fast(),
                        );
                        z.write_all(&raw).unwrap();
                        std::fs::write(key.join(cx.to_string()), z.finish().unwrap()).unwrap();
                    }
                }
            }
        }
    }

    /// Types without a voxel type of their own (float64, int32) are read as float32
    /// with a note; a region of a level reads just those voxels.
    #[test]
    fn other_types_read_as_float32_with_a_note_and_regions_read_alone() {
        use zarrs::array::ArrayBuilder;
        let root = scratch("types");
        for (name, ty) in [("f64", "float64"), ("i32", "int32")] {
            let dir = root.join(format!("{name}.zarr"));
            std::fs::create_dir_all(&dir).unwrap();
            let store = Arc::new(FilesystemStore::new(&dir).unwrap());
            let (shape, all) = (
                vec![5u64, 7, 10],
                ArraySubset::new_with_shape(vec![5, 7, 10]),
            );
            let values: Vec<f64> = (0..350).map(|i| f64::from(i) - 100.0).collect();
            if name == "f64" {
                let b = ArrayBuilder::new(
                    shape,
                    vec![5, 7, 10],
                    dt::float64(),
                    zarrs::array::FillValue::from(0f64),
                );
                store_level(&b, &store, "/", &all, &values).unwrap();
            } else {
                let ints: Vec<i32> = values.iter().map(|&v| v as i32).collect();
                let b = ArrayBuilder::new(
                    shape,
                    vec![5, 7, 10],
                    dt::int32(),
                    zarrs::array::FillValue::from(0i32),
                );
                store_level(&b, &store, "/", &all, &ints).unwrap();
            }
            let v = load(&dir).unwrap();
            assert_eq!(v.dims, [10, 7, 5]);
            let VoxelData::F32(d) = &v.data else {
                panic!("{name}: not read as float32")
            };
            assert_eq!(d[0], -100.0);
            assert_eq!(d[349], 249.0);
            assert!(
                v.notes
                    .iter()
                    .any(|n| n.contains(&format!("{ty} converted to float32"))),
                "{name}: {:?}",
                v.notes
            );
            // x 2..6, y 1..3, z 4..5 alone
            let r = load_region(&dir, 0, [[2, 6], [1, 3], [4, 5]]).unwrap();
            assert_eq!(r.dims, [4, 2, 1]);
            let VoxelData::F32(rd) = &r.data else {
                panic!("{name}")
            };
            let at = |x: usize, y: usize, z: usize| d[(z * 7 + y) * 10 + x];
            assert_eq!(
                rd[..],
                [
                    at(2, 1, 4),
                    at(3, 1, 4),
                    at(4, 1, 4),
                    at(5, 1, 4),
                    at(2, 2, 4),
                    at(3, 2, 4),
                    at(4, 2, 4),
                    at(5, 2, 4)
                ]
            );
            assert!(load_region(&dir, 0, [[2, 11], [0, 1], [0, 1]]).is_err());
            assert!(load_region(&dir, 1, [[0, 1], [0, 1], [0, 1]]).is_err());
        }
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn an_ngff_04_image_in_zarr_v2_reads_its_first_channel_and_scales() {
        let dir = scratch("v2").join("cells.zarr");
        v2_image(&dir, [3, 4, 5], "");
        let v = load(&dir).unwrap();
        assert_eq!((v.name.as_str(), v.dims), ("cells", [5, 4, 3]));
        assert_eq!(v.spacing, [0.5, 1.0, 2.0]);
        let want: Vec<i16> = (0..60)
            .map(|i| (i % 5 + 10 * ((i / 5) % 4) + 100 * (i / 20)) as i16)
            .collect();
        assert_eq!(v.data, VoxelData::I16(want));
        let notes = v.notes.join("\n");
        assert!(notes.contains("NGFF 0.4"), "{notes}");
        assert!(notes.contains("first channel index of 2"), "{notes}");
        assert!(notes.contains("in micrometer"), "{notes}");
        std::fs::remove_dir_all(dir.parent().unwrap()).unwrap();
    }

    #[test]
    fn lying_corrupt_and_flat_stores_are_refused_naming_the_store() {
        let root = scratch("bad");
        // a shape of 10¹² voxels fails before anything is allocated
        let lying = root.join("lying.zarr");
        v2_image(&lying, [3, 4, 5], "");
        let zarray = std::fs::read_to_string(lying.join("0/.zarray")).unwrap();
        std::fs::write(
            lying.join("0/.zarray"),
            zarray.replace("[2, 3, 4, 5]", "[2, 10000, 10000, 10000]"),
        )
        .unwrap();
        let e = load(&lying).unwrap_err();
        assert!(matches!(e, VolumeError::TooLarge { .. }), "{e}");
        assert_eq!(e.file(), Some(lying.as_path()));
        // chunks far larger than the array fail before one is decoded
        let huge = root.join("huge.zarr");
        v2_image(&huge, [3, 4, 5], "");
        let zarray = std::fs::read_to_string(huge.join("0/.zarray")).unwrap();
        std::fs::write(
            huge.join("0/.zarray"),
            zarray.replace("[1, 2, 4, 5]", "[1, 2000000, 4000000, 5000000]"),
        )
        .unwrap();
        let e = load(&huge).unwrap_err();
        assert!(matches!(e, VolumeError::TooLarge { .. }), "{e}");
        assert!(e.to_string().contains("chunks of"), "{e}");
        // a chunk cut short
        let cut = root.join("cut.zarr");
        v2_image(&cut, [3, 4, 5], "");
        let chunk = cut.join("0/0/1/0/0");
        let bytes = std::fs::read(&chunk).unwrap();
        std::fs::write(&chunk, &bytes[..bytes.len() / 2]).unwrap();
        let e = load(&cut).unwrap_err();
        assert_eq!(e.file(), Some(cut.as_path()), "{e}");
        assert!(e.to_string().contains("planes 2..3"), "{e}");
        // two spatial axes
        let flat = root.join("flat.zarr");
        v2_image(&flat, [3, 4, 5], "");
        let attrs = std::fs::read_to_string(flat.join(".zattrs")).unwrap();
        std::fs::write(
            flat.join(".zattrs"),
            attrs.replace(
                r#""name": "z", "type": "space""#,
                r#""name": "t", "type": "time""#,
            ),
        )
        .unwrap();
        let e = load(&flat).unwrap_err();
        assert!(e.to_string().contains("2 spatial axes (c, t, y, x)"), "{e}");
        // not a store at all
        std::fs::create_dir_all(root.join("empty")).unwrap();
        assert!(!is_zarr(&root.join("empty")));
        std::fs::remove_dir_all(root).unwrap();
    }
}
