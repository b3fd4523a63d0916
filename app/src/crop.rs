//! `vwb crop --preset P [--box x0,y0,z0,x1,y1,z1] -o sub.nhdr`: sub-volume extraction
//! (Rezk-Salama 2001 §12.3's inner-ear case). Writes the voxels of the box — given in
//! voxel indices (x1, y1, z1 exclusive), or else the bounding box of the voxels whose
//! centres the preset's enabled `clip.shapes` and `clip.mesh` instances keep (the
//! camera slab is not considered: it depends on the view) — as a detached NRRD (`sub.nhdr` + `sub.raw`,
//! both written atomically) with the source's type, its spacing, and the space origin
//! of the first voxel: the source header's `space origin` (0 when it has none) plus the
//! box's offset times the spacing (axis-aligned directions, as the loader assumes).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use glam::DVec3;
use vwb_plugins::clip_shapes::ClipRegion;
use vwb_render::plugin::{CpuView, PluginInstance};
use vwb_render::volume::{Volume, VoxelData};

#[derive(Debug, clap::Args)]
pub struct CropArgs {
    /// Voxel box x0,y0,z0,x1,y1,z1 (the upper bounds exclusive); default: the bounding
    /// box of the voxels the preset's clip.shapes and clip.mesh instances keep.
    #[arg(long = "box", value_parser = parse_box)]
    pub region: Option<[u32; 6]>,
    /// Output header (.nhdr); the samples go beside it (.raw).
    #[arg(short, long)]
    pub output: PathBuf,
}

fn parse_box(s: &str) -> Result<[u32; 6], String> {
    let v: Vec<u32> = s
        .split(',')
        .map(|t| t.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("'{s}': {e} (expected six voxel indices x0,y0,z0,x1,y1,z1)"))?;
    <[u32; 6]>::try_from(v).map_err(|v| {
        format!(
            "'{s}': {} numbers, expected six (x0,y0,z0,x1,y1,z1)",
            v.len()
        )
    })
}

pub fn run_crop(preset: Option<&Path>, a: &CropArgs) -> Result<()> {
    let Some(preset) = preset else {
        bail!("vwb crop needs --preset P.ron");
    };
    let doc = vwb_lab::document::load_document(Some(preset))?;
    let volume = vwb_lab::headless::load_volume(&doc.volume)?;
    let b = match a.region {
        Some(b) => check_box(b, volume.dims)?,
        None => kept_bounds(&volume, &doc.stack)
            .with_context(|| preset.display().to_string())?
            .with_context(|| {
                format!(
                    "{}: no --box given and no enabled clip.shapes or clip.mesh keeps a voxel",
                    preset.display()
                )
            })?,
    };
    write_nhdr(&a.output, &volume, b)?;
    eprintln!(
        "wrote {} ({} × {} × {} voxels from {:?})",
        a.output.display(),
        b[3] - b[0],
        b[4] - b[1],
        b[5] - b[2],
        b
    );
    Ok(())
}

/// The box, checked against the volume's dims.
pub fn check_box(b: [u32; 6], dims: [u32; 3]) -> Result<[u32; 6]> {
    for a in 0..3 {
        if b[a] >= b[a + 3] || b[a + 3] > dims[a] {
            bail!(
                "--box {b:?}: axis {a} needs {} ≤ {} < {} ≤ {} (the volume has {dims:?} voxels)",
                0,
                b[a],
                b[a + 3],
                dims[a]
            );
        }
    }
    Ok(b)
}

/// The bounding box of the voxels whose centres every enabled `clip.shapes` and
/// `clip.mesh` keeps, `None` when there is no such instance or no voxel is kept; an
/// error when a mesh cannot be loaded.
pub fn kept_bounds(volume: &Volume, stack: &[PluginInstance]) -> Result<Option<[u32; 6]>> {
    let view = CpuView::default();
    let mut kept: Vec<Box<dyn Fn(DVec3, DVec3) -> bool>> = Vec::new();
    for i in stack.iter().filter(|i| i.enabled) {
        match i.plugin.id() {
            "clip.shapes" => {
                let r = ClipRegion {
                    slab: None,
                    ..ClipRegion::from_params(&i.params)
                };
                kept.push(Box::new(move |p, _| r.sd(p, &view) <= 0.0));
            }
            "clip.mesh" => {
                let grid = vwb_plugins::clip_mesh::grid_for(&i.params, volume)
                    .map_err(|e| anyhow::anyhow!("clip.mesh: {e}"))?;
                let outside = i.params.enumeration("keep") == "outside";
                kept.push(Box::new(move |_, tex| {
                    vwb_plugins::clip_mesh::kept_distance(&grid, tex, outside) <= 0.0
                }));
            }
            _ => {}
        }
    }
    if kept.is_empty() {
        return Ok(None);
    }
    let vbox = vwb_render::slicing::VolumeBox::new(volume.dims, volume.spacing);
    let (lo, hi) = (vbox.min.as_dvec3(), vbox.max.as_dvec3());
    let d = volume.dims;
    let mut b: Option<[u32; 6]> = None;
    for z in 0..d[2] {
        for y in 0..d[1] {
            for x in 0..d[0] {
                let tex = (DVec3::new(x as f64, y as f64, z as f64) + 0.5)
                    / DVec3::from(d.map(f64::from));
                let p = lo + (hi - lo) * tex;
                if kept.iter().all(|k| k(p, tex)) {
                    let e = b.get_or_insert([x, y, z, x + 1, y + 1, z + 1]);
                    for (a, v) in [x, y, z].into_iter().enumerate() {
                        e[a] = e[a].min(v);
                        e[a + 3] = e[a + 3].max(v + 1);
                    }
                }
            }
        }
    }
    Ok(b)
}

/// `space origin` of the volume's source NRRD header, if it has one.
fn source_origin(volume: &Volume) -> DVec3 {
    let Some(text) = volume.source.as_ref().and_then(|p| std::fs::read(p).ok()) else {
        return DVec3::ZERO;
    };
    let head = String::from_utf8_lossy(&text[..text.len().min(8192)]).to_string();
    head.lines()
        .find_map(|l| l.strip_prefix("space origin:"))
        .and_then(|v| {
            let n: Vec<f64> = v
                .trim()
                .trim_start_matches('(')
                .trim_end_matches(')')
                .split(',')
                .filter_map(|t| t.trim().parse().ok())
                .collect();
            (n.len() == 3).then(|| DVec3::new(n[0], n[1], n[2]))
        })
        .unwrap_or(DVec3::ZERO)
}

/// Writes the voxels of `b` as `path` (header) and its `.raw` beside it.
pub fn write_nhdr(path: &Path, volume: &Volume, b: [u32; 6]) -> Result<()> {
    let (type_name, bytes_per) = match &volume.data {
        VoxelData::U8(_) => ("uint8", 1),
        VoxelData::I8(_) => ("int8", 1),
        VoxelData::U16(_) => ("uint16", 2),
        VoxelData::I16(_) => ("int16", 2),
        VoxelData::F32(_) => ("float", 4),
    };
    let c = volume.components as usize;
    let d = volume.dims.map(|n| n as usize);
    let mut out = Vec::new();
    for z in b[2] as usize..b[5] as usize {
        for y in b[1] as usize..b[4] as usize {
            let row = ((z * d[1] + y) * d[0] + b[0] as usize) * c;
            let n = (b[3] - b[0]) as usize * c;
            match &volume.data {
                VoxelData::U8(v) => out.extend_from_slice(&v[row..row + n]),
                VoxelData::I8(v) => out.extend(v[row..row + n].iter().map(|s| *s as u8)),
                VoxelData::U16(v) => {
                    out.extend(v[row..row + n].iter().flat_map(|s| s.to_le_bytes()))
                }
                VoxelData::I16(v) => {
                    out.extend(v[row..row + n].iter().flat_map(|s| s.to_le_bytes()))
                }
                VoxelData::F32(v) => {
                    out.extend(v[row..row + n].iter().flat_map(|s| s.to_le_bytes()))
                }
            }
        }
    }
    debug_assert_eq!(
        out.len(),
        (b[3] - b[0]) as usize * (b[4] - b[1]) as usize * (b[5] - b[2]) as usize * c * bytes_per
    );
    let raw = path.with_extension("raw");
    let raw_name = raw
        .file_name()
        .context("output has no file name")?
        .to_string_lossy()
        .to_string();
    let s = volume.spacing;
    let origin = source_origin(volume)
        + DVec3::new(b[0] as f64 * s[0], b[1] as f64 * s[1], b[2] as f64 * s[2]);
    let sizes = format!("{} {} {}", b[3] - b[0], b[4] - b[1], b[5] - b[2]);
    let dirs = format!("({},0,0) (0,{},0) (0,0,{})", s[0], s[1], s[2]);
    let (dimension, sizes, dirs, kinds) = if c > 1 {
        (
            4,
            format!("{c} {sizes}"),
            format!("none {dirs}"),
            "kinds: vector domain domain domain\n",
        )
    } else {
        (3, sizes, dirs, "")
    };
    let header = format!(
        "NRRD0004\n# vwb crop of {} (voxels {:?}..{:?})\ntype: {type_name}\ndimension: {dimension}\nspace dimension: 3\nsizes: {sizes}\nspace directions: {dirs}\n{kinds}space origin: ({},{},{})\nendian: little\nencoding: raw\ndata file: {raw_name}\n",
        volume
            .source
            .as_deref()
            .map_or_else(|| volume.name.clone(), |p| p.display().to_string()),
        &b[..3],
        &b[3..],
        origin.x,
        origin.y,
        origin.z,
    );
    vwb_render::preset::write_atomic(&raw, &out)
        .with_context(|| format!("{}: cannot write", raw.display()))?;
    vwb_render::preset::write_atomic(path, header.as_bytes())
        .with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use vwb_render::params::ParamValue;

    fn ramp() -> Volume {
        let d = [6u32, 5, 4];
        let data = (0..d[0] * d[1] * d[2]).map(|i| i as u16).collect();
        Volume::new("ramp", d, 1, [0.5, 1.0, 2.0], VoxelData::U16(data)).unwrap()
    }

    fn tmp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("vwb_crop_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn a_box_round_trips_with_spacing_origin_and_values() {
        let v = ramp();
        let out = tmp("sub.nhdr");
        write_nhdr(&out, &v, [1, 2, 1, 4, 5, 3]).unwrap();
        let back = vwb_render::volume::load(&out).unwrap();
        assert_eq!(back.dims, [3, 3, 2]);
        assert_eq!(back.spacing, [0.5, 1.0, 2.0]);
        let VoxelData::U16(s) = &back.data else {
            panic!("u16 expected")
        };
        // voxel (0,0,0) of the crop is (1,2,1) of the source: 1 + 2·6 + 1·30
        assert_eq!(s[0], 43);
        assert_eq!(s[s.len() - 1], (3 + 4 * 6 + 2 * 30) as u16);
        let header = std::fs::read_to_string(&out).unwrap();
        assert!(header.contains("space origin: (0.5,2,2)"), "{header}");
    }

    #[test]
    fn bad_boxes_are_errors() {
        assert!(check_box([0, 0, 0, 7, 1, 1], [6, 5, 4]).is_err());
        assert!(check_box([2, 0, 0, 2, 1, 1], [6, 5, 4]).is_err());
        assert!(parse_box("1,2,3").unwrap_err().contains("six"));
        assert!(parse_box("1,2,3,4,5,x").is_err());
        assert_eq!(parse_box("0,1,2,3,4,5"), Ok([0, 1, 2, 3, 4, 5]));
    }

    #[test]
    fn the_default_box_bounds_what_the_clip_shapes_keep() {
        let v = ramp();
        let registry = vwb_plugins::builtin_registry();
        let mut clip = PluginInstance::new(registry.get("clip.shapes").unwrap());
        assert_eq!(kept_bounds(&v, &[]).unwrap(), None);
        // the default plane keeps x ≤ 0: the world box is 3 × 5 × 8 scaled to longest
        // side 1, so x ≤ 0 holds the first three of six voxel columns
        assert_eq!(
            kept_bounds(&v, std::slice::from_ref(&clip)).unwrap(),
            Some([0, 0, 0, 3, 5, 4])
        );
        // a small sphere around the centre voxel row
        let k = vwb_plugins::clip_shapes::slot_keys()[0];
        clip.params.set(k.kind, ParamValue::Enum("sphere".into()));
        clip.params.set(k.size, ParamValue::Vec3([0.15, 0.0, 0.0]));
        assert_eq!(
            kept_bounds(&v, std::slice::from_ref(&clip)).unwrap(),
            Some([2, 2, 1, 4, 3, 3])
        );
        // the same sphere as a mesh: the same voxels
        let mut mesh = PluginInstance::new(registry.get("clip.mesh").unwrap());
        mesh.params.set("size", ParamValue::Vec3([0.15; 3]));
        mesh.params.set("segments", ParamValue::Int(64));
        assert_eq!(
            kept_bounds(&v, std::slice::from_ref(&mesh)).unwrap(),
            Some([2, 2, 1, 4, 3, 3])
        );
        // a mesh file that cannot be read is an error naming it
        mesh.params.set("source", ParamValue::Enum("file".into()));
        mesh.params
            .set("file", ParamValue::Path("/nonexistent/cutter.stl".into()));
        let e = kept_bounds(&v, &[mesh]).unwrap_err().to_string();
        assert!(e.contains("cutter.stl"), "{e}");
    }
}
