//! Closed triangle meshes for `clip.mesh`: loading (OBJ through `tobj`, STL through
//! `stl_io`, PLY through `ply-rs-bw`), generated shapes (sphere, box, torus), welding
//! and the check that a mesh bounds a volume (closed, manifold, consistently
//! oriented), with errors that name the file and the first bad edge.

use std::collections::HashMap;
use std::io::{BufRead, Read, Seek};
use std::path::Path;

use glam::DVec3;

/// Triangles at most (a file with more is refused before it is read whole).
pub const MAX_TRIANGLES: usize = 20_000_000;

/// A triangle mesh: positions and counter-clockwise (outward) vertex triples.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriMesh {
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// What [`TriMesh::check`] found that does not stop the mesh from being used.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeshReport {
    /// Triangles dropped because two of their corners are the same vertex.
    pub degenerate: usize,
    /// The first edge used twice in the same direction (inconsistent orientation),
    /// as a message; parity voxelisation does not need orientation, so it is a warning.
    pub orientation: Option<String>,
    /// The enclosed volume (positive when the triangles face outward).
    pub signed_volume: f64,
}

impl TriMesh {
    /// Merges vertices with identical coordinates (STL repeats every corner; OBJ and
    /// PLY exporters duplicate vertices at texture seams), so edges can be matched.
    pub fn welded(&self) -> TriMesh {
        let mut index = HashMap::new();
        let mut positions = Vec::new();
        let remap: Vec<u32> = self
            .positions
            .iter()
            .map(|p| {
                // −0.0 and 0.0 are the same point
                let key = (p + DVec3::ZERO).to_array().map(f64::to_bits);
                *index.entry(key).or_insert_with(|| {
                    positions.push(*p);
                    (positions.len() - 1) as u32
                })
            })
            .collect();
        TriMesh {
            positions,
            triangles: self
                .triangles
                .iter()
                .map(|t| t.map(|i| remap[i as usize]))
                .collect(),
        }
    }

    /// Applies `f` to every position.
    pub fn map_positions(&self, f: impl Fn(DVec3) -> DVec3) -> TriMesh {
        TriMesh {
            positions: self.positions.iter().map(|&p| f(p)).collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// (min, max) of the positions.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.positions.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// The corners of triangle `t`.
    pub fn corners(&self, t: usize) -> [DVec3; 3] {
        self.triangles[t].map(|i| self.positions[i as usize])
    }

    /// Checks that the (welded) mesh bounds a volume: finite coordinates, indices in
    /// range, at least one triangle, and every edge shared by exactly two triangles.
    /// Degenerate triangles are dropped (counted in the report). `what` names the
    /// mesh in messages (its file).
    pub fn check(&mut self, what: &str) -> Result<MeshReport, String> {
        let n = self.positions.len();
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(format!("{what}: vertex {i} has a non-finite coordinate {:?}", self.positions[i]));
        }
        if let Some((t, tri)) = self
            .triangles
            .iter()
            .enumerate()
            .find(|(_, tri)| tri.iter().any(|&i| i as usize >= n))
        {
            return Err(format!(
                "{what}: triangle {t} refers to vertex {:?}, but the mesh has {n} vertices",
                tri
            ));
        }
        let before = self.triangles.len();
        self.triangles
            .retain(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0]);
        let degenerate = before - self.triangles.len();
        if self.triangles.is_empty() {
            return Err(format!("{what}: the mesh has no triangles"));
        }
        // (undirected edge) → (uses, first triangle, uses in the direction lo → hi)
        let mut edges: HashMap<(u32, u32), (u32, usize, u32)> = HashMap::new();
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let e = edges.entry((a.min(b), a.max(b))).or_insert((0, t, 0));
                e.0 += 1;
                e.2 += u32::from(a < b);
            }
        }
        let describe = |a: u32, b: u32| {
            let (pa, pb) = (self.positions[a as usize], self.positions[b as usize]);
            format!(
                "the edge from vertex {a} ({:.6}, {:.6}, {:.6}) to vertex {b} ({:.6}, {:.6}, {:.6})",
                pa.x, pa.y, pa.z, pb.x, pb.y, pb.z
            )
        };
        let mut orientation = None;
        // the first bad edge in triangle order
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let (uses, first, forward) = edges[&(a.min(b), a.max(b))];
                if uses == 1 {
                    return Err(format!(
                        "{what}: the mesh is not closed: {} borders only triangle {t} (a hole); clip.mesh needs a closed surface",
                        describe(a, b)
                    ));
                }
                if uses > 2 {
                    return Err(format!(
                        "{what}: the mesh is not a manifold: {} is shared by {uses} triangles (the first is triangle {first})",
                        describe(a, b)
                    ));
                }
                if forward != 1 && orientation.is_none() {
                    orientation = Some(format!(
                        "{what}: the mesh is not consistently oriented: {} runs the same way in triangles {first} and {t}; inside and outside come from crossing parity, which does not need orientation",
                        describe(a, b)
                    ));
                }
            }
        }
        let signed_volume = (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.corners(t);
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        Ok(MeshReport {
            degenerate,
            orientation,
            signed_volume,
        })
    }
}

/// A UV sphere of radius 1 with `segments` around and `segments / 2` rings.
pub fn sphere(segments: u32) -> TriMesh {
    let (nu, nv) = (segments.max(3), (segments / 2).max(2));
    let mut m = TriMesh::default();
    m.positions.push(DVec3::new(0.0, 0.0, -1.0));
    for j in 1..nv {
        let theta = std::f64::consts::PI * j as f64 / nv as f64;
        let (z, r) = (-theta.cos(), theta.sin());
        for i in 0..nu {
            let phi = std::f64::consts::TAU * i as f64 / nu as f64;
            m.positions.push(DVec3::new(r * phi.cos(), r * phi.sin(), z));
        }
    }
    m.positions.push(DVec3::new(0.0, 0.0, 1.0));
    let ring = |j: u32, i: u32| 1 + (j - 1) * nu + i % nu;
    let top = m.positions.len() as u32 - 1;
    for i in 0..nu {
        m.triangles.push([0, ring(1, i + 1), ring(1, i)]);
        for j in 1..nv - 1 {
            let (a, b, c, d) = (ring(j, i), ring(j, i + 1), ring(j + 1, i + 1), ring(j + 1, i));
            m.triangles.push([a, b, c]);
            m.triangles.push([a, c, d]);
        }
        m.triangles.push([ring(nv - 1, i), ring(nv - 1, i + 1), top]);
    }
    m
}

/// The cube [−1, 1]³ (12 triangles).
pub fn cube() -> TriMesh {
    let positions = (0..8)
        .map(|i| DVec3::new(
            if i & 1 == 0 { -1.0 } else { 1.0 },
            if i & 2 == 0 { -1.0 } else { 1.0 },
            if i & 4 == 0 { -1.0 } else { 1.0 },
        ))
        .collect();
    // two triangles per face, counter-clockwise seen from outside
    let quads = [
        [0, 2, 3, 1], // z = −1
        [4, 5, 7, 6], // z = +1
        [0, 1, 5, 4], // y = −1
        [2, 6, 7, 3], // y = +1
        [0, 4, 6, 2], // x = −1
        [1, 3, 7, 5], // x = +1
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    TriMesh {
        positions,
        triangles,
    }
}

/// A torus around z with major radius 1 and minor radius `ratio`, `segments` around
/// the axis and `segments / 2` around the tube.
pub fn torus(segments: u32, ratio: f64) -> TriMesh {
    let (nu, nv) = (segments.max(3), (segments / 2).max(3));
    let mut m = TriMesh::default();
    for i in 0..nu {
        let phi = std::f64::consts::TAU * i as f64 / nu as f64;
        for j in 0..nv {
            let theta = std::f64::consts::TAU * j as f64 / nv as f64;
            let r = 1.0 + ratio * theta.cos();
            m.positions.push(DVec3::new(r * phi.cos(), r * phi.sin(), ratio * theta.sin()));
        }
    }
    let at = |i: u32, j: u32| (i % nu) * nv + j % nv;
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            m.triangles.push([a, b, c]);
            m.triangles.push([a, c, d]);
        }
    }
    m
}

/// The lowercase extension of `path` ("" when it has none).
fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default()
}

/// Whether `path` names a mesh file [`load`] reads (by extension: .obj, .ply, .stl).
pub fn is_mesh_file(path: &Path) -> bool {
    matches!(extension(path).as_str(), "obj" | "ply" | "stl")
}

/// Loads an OBJ, PLY or STL file (by extension), welded but not yet checked.
pub fn load(path: &Path) -> Result<TriMesh, String> {
    let file = path.display();
    let ext = extension(path);
    let mesh = match ext.as_str() {
        "obj" => load_obj(path),
        "stl" => load_stl(path),
        "ply" => load_ply(path),
        _ => Err(format!("not a mesh file: the extension must be .obj, .ply or .stl, found '{ext}'")),
    }
    .map_err(|e| format!("{file}: {e}"))?;
    if mesh.triangles.len() > MAX_TRIANGLES {
        return Err(format!(
            "{file}: {} triangles, more than the {MAX_TRIANGLES} clip.mesh accepts",
            mesh.triangles.len()
        ));
    }
    Ok(mesh.welded())
}

fn load_obj(path: &Path) -> Result<TriMesh, String> {
    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    // materials are irrelevant: a missing .mtl is not an error
    let (models, _) = tobj::load_obj(path, &options).map_err(|e| format!("OBJ: {e}"))?;
    let mut m = TriMesh::default();
    for model in models {
        let base = m.positions.len() as u32;
        let p = &model.mesh.positions;
        m.positions.extend(
            p.chunks_exact(3)
                .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)),
        );
        let count = (p.len() / 3) as u32;
        for t in model.mesh.indices.chunks_exact(3) {
            if let Some(&bad) = t.iter().find(|&&i| i >= count) {
                return Err(format!(
                    "OBJ: a face refers to vertex {} of object '{}', which has {count}",
                    bad + 1,
                    model.name
                ));
            }
            m.triangles.push([base + t[0], base + t[1], base + t[2]]);
        }
    }
    Ok(m)
}

fn load_stl(path: &Path) -> Result<TriMesh, String> {
    let mut f = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let len = f.metadata().map_err(|e| e.to_string())?.len();
    let mut head = [0u8; 84];
    let got = read_up_to(&mut f, &mut head).map_err(|e| e.to_string())?;
    let ascii = head[..got].starts_with(b"solid")
        && head[..got].iter().skip(5).take(79).all(|b| b.is_ascii());
    if !ascii {
        // binary: an 80-byte header, a triangle count and 50 bytes per triangle
        if got < 84 {
            return Err(format!("STL: truncated: {len} bytes, shorter than the 84-byte binary header"));
        }
        let count = u32::from_le_bytes([head[80], head[81], head[82], head[83]]) as u64;
        let expected = 84 + 50 * count;
        if expected != len {
            return Err(format!(
                "STL: the header says {count} triangles ({expected} bytes), but the file has {len} bytes (truncated or not STL)"
            ));
        }
        if count as usize > MAX_TRIANGLES {
            return Err(format!("STL: {count} triangles, more than the {MAX_TRIANGLES} clip.mesh accepts"));
        }
    }
    f.rewind().map_err(|e| e.to_string())?;
    let mut reader = std::io::BufReader::new(f);
    let stl = stl_io::read_stl(&mut reader).map_err(|e| format!("STL: {e}"))?;
    Ok(TriMesh {
        positions: stl
            .vertices
            .iter()
            .map(|v| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64))
            .collect(),
        triangles: stl
            .faces
            .iter()
            .map(|f| f.vertices.map(|i| i as u32))
            .collect(),
    })
}

fn read_up_to(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..])? {
            0 => break,
            n => got += n,
        }
    }
    Ok(got)
}

fn load_ply(path: &Path) -> Result<TriMesh, String> {
    use ply_rs_bw::ply::Property;
    let f = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let len = f.metadata().map_err(|e| e.to_string())?.len();
    let mut reader = std::io::BufReader::new(f);
    // element counts are checked against the file size before anything is read whole
    let mut total: u64 = 0;
    let mut line = String::new();
    for _ in 0..10_000 {
        line.clear();
        if reader.read_line(&mut line).map_err(|e| format!("PLY header: {e}"))? == 0 {
            break;
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        if let ["element", _, n] = words.as_slice() {
            total = total.saturating_add(n.parse::<u64>().map_err(|_| format!("PLY header: bad element count in '{}'", line.trim()))?);
        }
        if words.first() == Some(&"end_header") {
            break;
        }
    }
    if total > len {
        return Err(format!(
            "PLY: the header declares {total} elements, more than the file's {len} bytes can hold (truncated or lying header)"
        ));
    }
    reader.rewind().map_err(|e| e.to_string())?;
    let parser = ply_rs_bw::parser::Parser::<ply_rs_bw::ply::DefaultElement>::new();
    let ply = parser
        .read_ply(&mut reader)
        .map_err(|e| format!("PLY: {e}"))?;
    let scalar = |p: Option<&Property>| -> Option<f64> {
        Some(match p? {
            Property::Float(v) => *v as f64,
            Property::Double(v) => *v,
            Property::Int(v) => *v as f64,
            Property::UInt(v) => *v as f64,
            Property::Short(v) => *v as f64,
            Property::UShort(v) => *v as f64,
            Property::Char(v) => *v as f64,
            Property::UChar(v) => *v as f64,
            _ => return None,
        })
    };
    let mut m = TriMesh::default();
    let vertices = ply.payload.get("vertex").ok_or("PLY: no 'vertex' element")?;
    for (i, v) in vertices.iter().enumerate() {
        let c = ["x", "y", "z"].map(|k| scalar(v.get(k)));
        let [Some(x), Some(y), Some(z)] = c else {
            return Err(format!("PLY: vertex {i} lacks a numeric x, y or z"));
        };
        m.positions.push(DVec3::new(x, y, z));
    }
    let faces = ply.payload.get("face").ok_or("PLY: no 'face' element")?;
    for (t, f) in faces.iter().enumerate() {
        let list = f.get("vertex_indices").or_else(|| f.get("vertex_index"));
        let idx: Vec<i64> = match list {
            Some(Property::ListInt(v)) => v.iter().map(|&i| i as i64).collect(),
            Some(Property::ListUInt(v)) => v.iter().map(|&i| i as i64).collect(),
            Some(Property::ListShort(v)) => v.iter().map(|&i| i as i64).collect(),
            Some(Property::ListUShort(v)) => v.iter().map(|&i| i as i64).collect(),
            Some(Property::ListChar(v)) => v.iter().map(|&i| i as i64).collect(),
            Some(Property::ListUChar(v)) => v.iter().map(|&i| i as i64).collect(),
            _ => return Err(format!("PLY: face {t} has no integer 'vertex_indices' list")),
        };
        if let Some(&bad) = idx.iter().find(|&&i| i < 0 || i as usize >= m.positions.len()) {
            return Err(format!(
                "PLY: face {t} refers to vertex {bad}, but there are {} vertices",
                m.positions.len()
            ));
        }
        // polygons as fans
        for k in 1..idx.len().saturating_sub(1) {
            m.triangles
                .push([idx[0] as u32, idx[k] as u32, idx[k + 1] as u32]);
        }
    }
    Ok(m)
}

/// Writes `mesh` as OBJ, ASCII PLY or binary STL (by extension), for tests and for
/// saving a generated shape; atomically (a temporary file beside it, then a rename).
pub fn save(mesh: &TriMesh, path: &Path) -> Result<(), String> {
    use std::fmt::Write as _;
    let ext = extension(path);
    let bytes = match ext.as_str() {
        "obj" => {
            let mut s = String::from("# written by vwb (clip.mesh)\n");
            for p in &mesh.positions {
                let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
            }
            for t in &mesh.triangles {
                let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
            }
            s.into_bytes()
        }
        "ply" => {
            let mut s = format!(
                "ply\nformat ascii 1.0\ncomment written by vwb (clip.mesh)\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
                mesh.positions.len(),
                mesh.triangles.len()
            );
            for p in &mesh.positions {
                let _ = writeln!(s, "{} {} {}", p.x, p.y, p.z);
            }
            for t in &mesh.triangles {
                let _ = writeln!(s, "3 {} {} {}", t[0], t[1], t[2]);
            }
            s.into_bytes()
        }
        "stl" => {
            let triangles: Vec<stl_io::Triangle> = (0..mesh.triangles.len())
                .map(|t| {
                    let c = mesh.corners(t);
                    let n = (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero();
                    stl_io::Triangle {
                        normal: stl_io::Normal::new(n.as_vec3().to_array()),
                        vertices: c.map(|p| stl_io::Vertex::new(p.as_vec3().to_array())),
                    }
                })
                .collect();
            let mut out = Vec::new();
            stl_io::write_stl(&mut out, triangles.iter()).map_err(|e| e.to_string())?;
            out
        }
        _ => return Err(format!("{}: the extension must be .obj, .ply or .stl", path.display())),
    };
    let tmp = path.with_extension(format!("{ext}.tmp~"));
    std::fs::write(&tmp, bytes)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            format!("{}: {e}", path.display())
        })
}
