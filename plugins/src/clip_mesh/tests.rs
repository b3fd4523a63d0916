use std::path::PathBuf;

use glam::DVec3;
use vwb_render::params::{ParamValue, ParamValues};
use vwb_render::plugin::Plugin;

use super::mesh;
use super::voxelize::{closest_point, voxelize};
use super::*;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vwb-clip-mesh-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn generated_shapes_are_closed_oriented_and_enclose_their_volume() {
    let pi = std::f64::consts::PI;
    for (name, mut m, exact, tol) in [
        ("sphere", mesh::sphere(96), 4.0 / 3.0 * pi, 2e-3),
        ("cube", mesh::cube(), 8.0, 1e-12),
        // inscribed polygons: about (2π/n)²/6 short for each of the two directions
        ("torus", mesh::torus(96, 0.35), 2.0 * pi * pi * 0.35 * 0.35, 5e-3),
    ] {
        let report = m.check(name).unwrap();
        assert_eq!(report.orientation, None, "{name}");
        assert_eq!(report.degenerate, 0, "{name}");
        let rel = (report.signed_volume - exact).abs() / exact;
        assert!(rel < tol, "{name}: volume {} against {exact}", report.signed_volume);
    }
}

#[test]
fn an_open_or_non_manifold_mesh_is_refused_with_its_first_bad_edge() {
    let mut open = mesh::cube();
    open.triangles.remove(3);
    let e = open.check("box.obj").unwrap_err();
    assert!(e.starts_with("box.obj: the mesh is not closed"), "{e}");
    assert!(e.contains("edge from vertex"), "{e}");

    let mut doubled = mesh::cube();
    doubled.triangles.push(doubled.triangles[0]);
    let e = doubled.check("twice.stl").unwrap_err();
    assert!(e.contains("not a manifold") && e.contains("3 triangles"), "{e}");

    let mut nan = mesh::cube();
    nan.positions[2].y = f64::NAN;
    assert!(nan.check("nan.ply").unwrap_err().contains("non-finite"));

    let mut flipped = mesh::cube();
    flipped.triangles[0].swap(1, 2);
    let report = flipped.check("flipped.obj").unwrap();
    let w = report.orientation.unwrap();
    assert!(w.starts_with("flipped.obj: the mesh is not consistently oriented"), "{w}");
}

#[test]
fn obj_ply_and_stl_round_trip_to_the_same_mesh() {
    let dir = temp_dir("round-trip");
    let sphere = mesh::sphere(24).map_positions(|p| p * 0.4);
    for ext in ["obj", "ply", "stl"] {
        let path = dir.join(format!("sphere.{ext}"));
        mesh::save(&sphere, &path).unwrap();
        let mut back = mesh::load(&path).unwrap();
        back.check(ext).unwrap();
        assert_eq!(back.triangles.len(), sphere.triangles.len(), "{ext}");
        assert_eq!(back.positions.len(), sphere.positions.len(), "{ext}");
        // STL stores f32
        let worst = sphere
            .positions
            .iter()
            .map(|p| back.positions.iter().map(|q| (*p - *q).length()).fold(f64::INFINITY, f64::min))
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{ext}: {worst}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn bad_mesh_files_are_refused_with_the_file_and_the_cause() {
    let dir = temp_dir("bad");
    let cube = mesh::cube();
    let stl = dir.join("cube.stl");
    mesh::save(&cube, &stl).unwrap();
    let bytes = std::fs::read(&stl).unwrap();
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("truncated.stl", bytes[..bytes.len() - 7].to_vec(), "the header says 12 triangles"),
        ("short.stl", bytes[..40].to_vec(), "shorter than the 84-byte binary header"),
        (
            "lying.ply",
            b"ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n".to_vec(),
            "more than the file's",
        ),
        ("index.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n".to_vec(), "OBJ"),
        (
            "index.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n".to_vec(),
            "refers to vertex 7",
        ),
        ("mesh.xyz", b"1 2 3".to_vec(), "must be .obj, .ply or .stl"),
        ("empty.obj", Vec::new(), ""),
    ];
    for (name, content, cause) in cases {
        let path = dir.join(name);
        std::fs::write(&path, content).unwrap();
        let e = mesh::load(&path).and_then(|mut m| m.check(&path.display().to_string()).map(|_| ()));
        let e = e.expect_err(name);
        assert!(e.contains(name), "{name}: {e}");
        assert!(e.contains(cause), "{name}: {e}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn closest_point_is_the_nearest_point_of_the_triangle() {
    let c = [DVec3::new(0.1, 0.0, 0.0), DVec3::new(1.0, 0.2, 0.1), DVec3::new(0.3, 0.9, -0.2)];
    let mut rng = vwb_render::rng::Rng::at(7, 0);
    for _ in 0..200 {
        let p = DVec3::new(rng.uniform() * 3.0 - 1.0, rng.uniform() * 3.0 - 1.0, rng.uniform() * 2.0 - 1.0);
        let q = closest_point(p, &c);
        let best = (0..=60)
            .flat_map(|i| (0..=60 - i).map(move |j| (i, j)))
            .map(|(i, j)| {
                let (u, v) = (i as f64 / 60.0, j as f64 / 60.0);
                (p - (c[0] + (c[1] - c[0]) * u + (c[2] - c[0]) * v)).length()
            })
            .fold(f64::INFINITY, f64::min);
        let d = (p - q).length();
        assert!(d <= best + 1e-12 && d > best - 0.03, "{d} {best}");
    }
}

/// A sphere of radius 0.3 in the box [−0.5, 0.5]³ at 40³: the sign agrees with the
/// analytic sphere wherever the voxel centre is more than the f16 step from the
/// surface, and the distance within the band with the analytic one to the facets'
/// sagitta.
#[test]
fn a_voxelised_sphere_has_the_sphere_distance() {
    let n = 40u32;
    let r = 0.3;
    let m = mesh::sphere(128).map_positions(|p| p * r + DVec3::new(0.013, -0.021, 0.007));
    let step = 1.0 / n as f64;
    let g = voxelize(&m, DVec3::splat(-0.5), DVec3::splat(0.5), [n; 3], step);
    assert_eq!(g.odd_columns, 0);
    assert_eq!(g.band, 4.0);
    let sagitta = r * (1.0 - (std::f64::consts::PI / 128.0).cos()) / step;
    let mut worst = 0.0f64;
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let p = (DVec3::new(x as f64, y as f64, z as f64) + 0.5) * step - 0.5;
                let exact = ((p - DVec3::new(0.013, -0.021, 0.007)).length() - r) / step;
                let v = g.values[((z * n + y) * n + x) as usize] as f64;
                let band = g.band as f64;
                worst = worst.max((v - exact.clamp(-band, band)).abs());
                if exact.abs() > 0.01 {
                    assert_eq!(v < 0.0, exact < 0.0, "sign at {p}");
                }
            }
        }
    }
    // the facets of a UV sphere cut in by up to about twice the sagitta of a segment
    // between rings, plus half an f16 step near the band
    assert!(worst < 2.0 * sagitta + 2e-3, "worst {worst} voxels, sagitta {sagitta}");
}

/// A box whose faces lie on voxel boundaries: no grazing column, and exactly the
/// voxels inside it are inside.
#[test]
fn a_grid_aligned_box_is_voxelised_exactly() {
    let n = 16u32;
    let m = mesh::cube().map_positions(|p| p * 0.25);
    let g = voxelize(&m, DVec3::splat(-0.5), DVec3::splat(0.5), [n; 3], 1.0 / n as f64);
    assert_eq!(g.odd_columns, 0);
    let inside = g.values.iter().filter(|&&v| v < 0.0).count();
    assert_eq!(inside, 8 * 8 * 8);
    // the centre voxels of the face layer lie half a voxel inside
    assert_eq!(g.values[((8 * n + 8) * n + 4) as usize], -0.5);
}

fn params() -> ParamValues {
    ParamValues::defaults(&ClipMesh::default().params())
}

#[test]
fn only_the_mesh_its_placement_and_the_grid_change_the_grid() {
    let v = vwb_render::volume::demo();
    let base = grid_key(&params(), &v);
    let mut p = params();
    p.set("keep", ParamValue::Enum("outside".into()));
    p.set("soft_edge", ParamValue::Float(2.0));
    p.set("cut_layer", ParamValue::Float(1.0));
    assert_eq!(grid_key(&p, &v), base, "keep, soft edge and cut layer move nothing");
    for (k, value) in [
        ("center", ParamValue::Vec3([0.1, 0.0, 0.0])),
        ("rotate", ParamValue::Vec3([0.0, 10.0, 0.0])),
        ("scale", ParamValue::Float(0.9)),
        ("source", ParamValue::Enum("torus".into())),
        ("resolution", ParamValue::Enum("1:2".into())),
    ] {
        let mut p = params();
        p.set(k, value);
        assert_ne!(grid_key(&p, &v), base, "{k}");
    }
}

#[test]
fn file_units_place_the_mesh_over_the_volume() {
    let mut v = vwb_render::volume::demo();
    v.spacing = [1.0, 2.0, 0.5];
    let dir = temp_dir("units");
    let path = dir.join("corner.obj");
    // a small cube around voxel (0, 0, 0) in voxel units
    mesh::save(&mesh::cube().map_positions(|p| p * 0.5), &path).unwrap();
    let mut p = params();
    p.set("source", ParamValue::Enum("file".into()));
    p.set("file", ParamValue::Path(path.clone()));
    p.set("units", ParamValue::Enum("voxels".into()));
    let placed = placed_mesh(&p, &v).unwrap();
    let (lo, hi) = placed.bounds();
    let vbox = VolumeBox::new(v.dims, v.spacing);
    let voxel = (vbox.max - vbox.min).as_dvec3() / DVec3::from(v.dims.map(f64::from));
    assert!((lo - vbox.min.as_dvec3()).length() < 1e-6, "{lo}");
    assert!((hi - (vbox.min.as_dvec3() + voxel)).length() < 1e-6, "{hi}");
    p.set("units", ParamValue::Enum("mm".into()));
    let mm = placed_mesh(&p, &v).unwrap().bounds();
    let spacing = DVec3::from(v.spacing);
    let expect_hi = vbox.min.as_dvec3() + voxel * (0.5 + 0.5 / spacing);
    assert!((mm.1 - expect_hi).length() < 1e-6, "{:?}", mm);
    p.set("file", ParamValue::Path(dir.join("missing.obj")));
    let e = placed_mesh(&p, &v).unwrap_err();
    assert!(e.contains("missing.obj"), "{e}");
    let _ = std::fs::remove_dir_all(dir);
}


#[test]
fn boxes_outside_the_kept_region_are_reported_empty() {
    let n = 16u32;
    let (lo, hi) = (DVec3::splat(-0.5), DVec3::splat(0.5));
    let g = voxelize(&mesh::cube().map_positions(|p| p * 0.2), lo, hi, [n; 3], 1.0 / n as f64);
    let corner = (DVec3::splat(0.35), DVec3::splat(0.5));
    let straddles = (DVec3::splat(0.1), DVec3::splat(0.3));
    // keep the inside: the corner box holds nothing, a box across the face does
    assert!(!may_keep_box(&g, false, (lo, hi), corner.0, corner.1));
    assert!(may_keep_box(&g, false, (lo, hi), straddles.0, straddles.1));
    // keep the outside: the centre holds nothing
    assert!(!may_keep_box(&g, true, (lo, hi), DVec3::splat(-0.05), DVec3::splat(0.05)));
    assert!(may_keep_box(&g, true, (lo, hi), corner.0, corner.1));
}
