//! TIFF stacks through the `tiff` crate: a multi-page file (each page one z slice), or a
//! folder of single- or multi-page files (`.tif`, `.tiff`) taken in name order.
//!
//! - Pages must share their size and sample type. Gray 8/16/32-bit integers and
//!   floats load; 8- and 16-bit keep their type, the others become f32; RGB 8-bit pages
//!   load as a 3-component u8 vector.
//! - Spacing: x and y are 1/XResolution and 1/YResolution where the file records them;
//!   z comes from an ImageJ description's `spacing=`, else 1. A note says where each
//!   came from.
//! - TIFF records no patient orientation: the axes stay as stored (x along a row, y
//!   down the page, z over the pages).
//! - Limits: the volume is checked against the memory budget page by page, before each
//!   page is added, so a stack too large fails before it is held.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use tiff::decoder::{Decoder, DecodingResult, ifd::Value};
use tiff::tags::Tag;

use super::{Volume, VolumeError, VoxelData, check_layout};

/// Whether `head` starts like a TIFF (classic or BigTIFF, either byte order).
pub fn is_tiff(head: &[u8]) -> bool {
    head.starts_with(b"II*\0")
        || head.starts_with(b"MM\0*")
        || head.starts_with(b"II+\0")
        || head.starts_with(b"MM\0+")
}

/// The TIFF files of a folder, in name order.
pub fn folder_pages(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|it| {
            it.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.is_file()
                        && p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                            e.eq_ignore_ascii_case("tif") || e.eq_ignore_ascii_case("tiff")
                        })
                })
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

fn tiff_err(file: &Path, e: impl std::fmt::Display) -> VolumeError {
    VolumeError::Unsupported {
        file: file.to_path_buf(),
        message: format!("cannot decode the TIFF: {e}"),
    }
}

/// The growing stack.
struct Stack {
    width: u32,
    height: u32,
    components: u32,
    pages: u32,
    data: Option<VoxelData>,
    spacing_xy: Option<[f64; 2]>,
    z_spacing: Option<f64>,
}

fn rational(v: Option<Value>) -> Option<f64> {
    match v? {
        Value::Rational(n, d) if d != 0 && n != 0 => Some(d as f64 / n as f64),
        Value::Float(f) if f > 0.0 => Some(1.0 / f as f64),
        Value::Double(f) if f > 0.0 => Some(1.0 / f),
        _ => None,
    }
}

impl Stack {
    fn add_file(&mut self, path: &Path) -> Result<(), VolumeError> {
        let f = File::open(path).map_err(|e| super::raw::io_error(path, "cannot open", e))?;
        let mut d = Decoder::new(BufReader::new(f)).map_err(|e| tiff_err(path, e))?;
        loop {
            let (w, h) = d.dimensions().map_err(|e| tiff_err(path, e))?;
            let components = match d.colortype().map_err(|e| tiff_err(path, e))? {
                tiff::ColorType::Gray(_) => 1,
                tiff::ColorType::RGB(8) => 3,
                other => {
                    return Err(VolumeError::Unsupported {
                        file: path.to_path_buf(),
                        message: format!(
                            "page {}: {other:?} pages are not read (gray, or 8-bit RGB)",
                            self.pages + 1
                        ),
                    });
                }
            };
            if self.pages == 0 {
                (self.width, self.height, self.components) = (w, h, components);
                let xr = rational(d.find_tag(Tag::XResolution).ok().flatten());
                let yr = rational(d.find_tag(Tag::YResolution).ok().flatten());
                if let (Some(x), Some(y)) = (xr, yr)
                    && x.is_finite()
                    && y.is_finite()
                {
                    self.spacing_xy = Some([x, y]);
                }
                if let Ok(Some(Value::Ascii(desc))) = d.find_tag(Tag::ImageDescription) {
                    self.z_spacing = desc
                        .lines()
                        .find_map(|l| l.strip_prefix("spacing="))
                        .and_then(|v| v.trim().parse::<f64>().ok())
                        .filter(|z| z.is_finite() && *z > 0.0);
                }
            } else if (w, h, components) != (self.width, self.height, self.components) {
                return Err(VolumeError::Invalid {
                    file: Some(path.to_path_buf()),
                    message: format!(
                        "page {} is {w}x{h} with {components} component(s), the first page {}x{} with {}",
                        self.pages + 1,
                        self.width,
                        self.height,
                        self.components
                    ),
                });
            }
            let bytes = match d.colortype().map_err(|e| tiff_err(path, e))? {
                tiff::ColorType::Gray(b) | tiff::ColorType::RGB(b) => (b as u64).div_ceil(8).max(1),
                _ => 4,
            };
            check_layout(
                [w as u64, h as u64, self.pages as u64 + 1],
                components as u64,
                bytes,
                Some(path),
            )?;
            let page = d.read_image().map_err(|e| tiff_err(path, e))?;
            self.push(page, path)?;
            self.pages += 1;
            if !d.more_images() {
                return Ok(());
            }
            d.next_image().map_err(|e| tiff_err(path, e))?;
        }
    }

    fn push(&mut self, page: DecodingResult, path: &Path) -> Result<(), VolumeError> {
        let as_f32 = |v: Vec<f32>| VoxelData::F32(v);
        let page = match page {
            DecodingResult::U8(v) => VoxelData::U8(v),
            DecodingResult::I8(v) => VoxelData::I8(v),
            DecodingResult::U16(v) => VoxelData::U16(v),
            DecodingResult::I16(v) => VoxelData::I16(v),
            DecodingResult::F32(v) => as_f32(v),
            DecodingResult::F64(v) => as_f32(v.into_iter().map(|x| x as f32).collect()),
            DecodingResult::U32(v) => as_f32(v.into_iter().map(|x| x as f32).collect()),
            DecodingResult::I32(v) => as_f32(v.into_iter().map(|x| x as f32).collect()),
            DecodingResult::U64(v) => as_f32(v.into_iter().map(|x| x as f32).collect()),
            DecodingResult::I64(v) => as_f32(v.into_iter().map(|x| x as f32).collect()),
            DecodingResult::F16(v) => as_f32(v.into_iter().map(f32::from).collect()),
        };
        match (&mut self.data, page) {
            (None, p) => self.data = Some(p),
            (Some(VoxelData::U8(a)), VoxelData::U8(b)) => a.extend(b),
            (Some(VoxelData::I8(a)), VoxelData::I8(b)) => a.extend(b),
            (Some(VoxelData::U16(a)), VoxelData::U16(b)) => a.extend(b),
            (Some(VoxelData::I16(a)), VoxelData::I16(b)) => a.extend(b),
            (Some(VoxelData::F32(a)), VoxelData::F32(b)) => a.extend(b),
            (Some(a), b) => {
                return Err(VolumeError::Invalid {
                    file: Some(path.to_path_buf()),
                    message: format!(
                        "page {} holds {} samples, the first page {}",
                        self.pages + 1,
                        b.scalar_type().name(),
                        a.scalar_type().name()
                    ),
                });
            }
        }
        Ok(())
    }
}

/// Loads a multi-page TIFF, or every TIFF of a folder in name order.
pub fn load(path: &Path) -> Result<Volume, VolumeError> {
    let files = if path.is_dir() {
        let f = folder_pages(path);
        if f.is_empty() {
            return Err(VolumeError::Unsupported {
                file: path.to_path_buf(),
                message: "is a folder with no .tif or .tiff files".to_owned(),
            });
        }
        f
    } else {
        vec![path.to_path_buf()]
    };
    let mut s = Stack {
        width: 0,
        height: 0,
        components: 1,
        pages: 0,
        data: None,
        spacing_xy: None,
        z_spacing: None,
    };
    for f in &files {
        s.add_file(f)?;
    }
    let data = s.data.take().ok_or_else(|| VolumeError::Invalid {
        file: Some(path.to_path_buf()),
        message: "no pages".to_owned(),
    })?;
    let mut notes = vec![format!(
        "TIFF stack: {} page(s) from {} file(s); axes as stored (TIFF records no patient orientation)",
        s.pages,
        files.len()
    )];
    let [sx, sy] = s.spacing_xy.unwrap_or([1.0, 1.0]);
    let sz = s.z_spacing.unwrap_or(1.0);
    notes.push(format!(
        "spacing: x, y {}; z {}",
        if s.spacing_xy.is_some() {
            "from XResolution/YResolution"
        } else {
            "not recorded (1)"
        },
        if s.z_spacing.is_some() {
            "from the ImageJ description"
        } else {
            "not recorded (1)"
        }
    ));
    let name = if path.is_dir() {
        path.file_name()
            .map_or("stack".into(), |n| n.to_string_lossy().into_owned())
    } else {
        super::name_from_path(path)
    };
    let mut v = Volume::new(
        name,
        [s.width, s.height, s.pages],
        s.components,
        [sx, sy, sz],
        data,
    )
    .map_err(|e| e.in_file(path))?;
    v.source = Some(path.to_path_buf());
    v.notes = notes;
    Ok(v)
}

/// Writes 16-bit gray pages as one multi-page TIFF (tests, conversions), with an ImageJ
/// description giving the z spacing and the x/y resolution.
pub fn write_u16_stack(
    path: &Path,
    dims: [u32; 3],
    spacing: [f64; 3],
    samples: &[u16],
) -> Result<(), String> {
    use tiff::encoder::{Rational, TiffEncoder, colortype};
    let mut bytes = std::io::Cursor::new(Vec::new());
    {
        let mut enc = TiffEncoder::new(&mut bytes).map_err(|e| e.to_string())?;
        let page = (dims[0] * dims[1]) as usize;
        for z in 0..dims[2] as usize {
            let mut img = enc
                .new_image::<colortype::Gray16>(dims[0], dims[1])
                .map_err(|e| e.to_string())?;
            let res = |s: f64| Rational {
                n: (1.0e6 / s).round() as u32,
                d: 1_000_000,
            };
            img.x_resolution(res(spacing[0]));
            img.y_resolution(res(spacing[1]));
            img.encoder()
                .write_tag(
                    Tag::ImageDescription,
                    format!(
                        "ImageJ=1.54f\nimages={}\nslices={}\nspacing={}\n",
                        dims[2], dims[2], spacing[2]
                    )
                    .as_str(),
                )
                .map_err(|e| e.to_string())?;
            img.write_data(&samples[z * page..(z + 1) * page])
                .map_err(|e| e.to_string())?;
        }
    }
    crate::preset::write_atomic(path, bytes.get_ref()).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("vwb-tiff-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d.join(name)
    }

    #[test]
    fn multipage_file_and_folder_of_pages() {
        let dims = [5, 4, 3];
        let samples: Vec<u16> = (0..60).map(|i| i * 7).collect();
        let p = tmp("stack.tif");
        write_u16_stack(&p, dims, [0.5, 0.5, 2.0], &samples).unwrap();
        let v = super::super::load(&p).unwrap();
        assert_eq!(v.dims, [5, 4, 3]);
        assert_eq!(v.spacing, [0.5, 0.5, 2.0]);
        assert_eq!(v.data, VoxelData::U16(samples.clone()));
        // the same pages as single files in a folder
        let dir = tmp("pages");
        std::fs::create_dir_all(&dir).unwrap();
        for z in 0..3usize {
            write_u16_stack(
                &dir.join(format!("slice_{z:03}.tif")),
                [5, 4, 1],
                [0.5, 0.5, 2.0],
                &samples[z * 20..(z + 1) * 20],
            )
            .unwrap();
        }
        let w = super::super::load(&dir).unwrap();
        assert_eq!(w.dims, [5, 4, 3]);
        assert_eq!(w.data, v.data);
        // a page of another size is refused, naming the file
        write_u16_stack(&dir.join("slice_999.tif"), [3, 3, 1], [1.0; 3], &[0; 9]).unwrap();
        let e = super::super::load(&dir).unwrap_err().to_string();
        assert!(e.contains("slice_999.tif") && e.contains("3x3"), "{e}");
        // truncated file
        let bytes = std::fs::read(&p).unwrap();
        let t = tmp("trunc.tif");
        std::fs::write(&t, &bytes[..bytes.len() / 2]).unwrap();
        let e = super::super::load(&t).unwrap_err().to_string();
        assert!(e.contains("trunc.tif"), "{e}");
    }
}
