//! `clip.mesh`: every mode against its CPU twin on both backends; the mesh pass reruns
//! only when the mesh moves; files (OBJ, PLY, STL) clip as their generated shape does;
//! DOS casts no shadow from matter the mesh removes; a broken mesh file is refused with
//! its name and the last good stack keeps rendering. The twin scenes are
//! experiments/scenes/demo_mesh_*.ron; figures: `bash bench/clipping.sh` (experiment
//! files; the mesh pass's voxelisation is `clip.mesh`'s probe, clip_mesh_pass.ron).

use std::sync::Arc;
use std::time::Instant;

use vwb_plugins::clip_mesh::{self, mesh};
use vwb_render::params::ParamValue;
use vwb_render::{Backend, FrameSettings, PluginInstance, Renderer, TargetFormat, Volume};

use crate::clipping::{
    BLOCK_CUT_Z, block_removed_consistency_with, clip_twin_errors, dos_stack, skipped_bricks,
};
use crate::common::*;
use crate::reference::delta_e_rms;

pub fn mesh_clip(source: &str) -> PluginInstance {
    let mut c = instance("clip.mesh");
    c.params.set("source", ParamValue::Enum(source.into()));
    c
}

/// The `clip.mesh` instance of a scene of experiments/clip_mesh_twin.ron.
fn scene_mesh(name: &str) -> PluginInstance {
    let (doc, _) = preset_scene(&format!("experiments/scenes/demo_mesh_{name}.ron"));
    doc.stack
        .iter()
        .find(|i| i.plugin.id() == "clip.mesh")
        .expect("the scene clips by a mesh")
        .clone()
}

/// The modes of the twin comparison: (label, clip instance), from the scenes of
/// experiments/clip_mesh_twin.ron.
pub fn modes() -> Vec<(String, PluginInstance)> {
    let mut out = Vec::new();
    let ball = scene_mesh("ellipsoid");
    out.push((
        "ellipsoid, keep inside, soft edge".to_string(),
        ball.clone(),
    ));
    let mut coarse = ball;
    coarse
        .params
        .set("resolution", ParamValue::Enum("1:2".into()));
    out.push(("ellipsoid at 1:2".to_string(), coarse));
    for cut in ["off", "clip_normal", "substitute"] {
        let mut torus = scene_mesh("torus");
        torus
            .params
            .set("cut_shading", ParamValue::Enum(cut.into()));
        out.push((format!("torus, keep outside, cut shading {cut}"), torus));
    }
    out.push((
        "rotated box cut away, cut shading".to_string(),
        scene_mesh("box"),
    ));
    out
}

/// ΔE*uv RMS of GPU against twin for each mode and backend, with Blinn–Phong shading.
pub fn twin_errors() -> Vec<(String, Backend, f64)> {
    clip_twin_errors(modes())
}

#[test]
fn every_mesh_mode_matches_the_twin_on_both_backends() {
    for (label, backend, rms) in twin_errors() {
        eprintln!("clip.mesh {label} {}: ΔE*uv RMS {rms:.4}", backend.name());
        let bound = if backend == Backend::Compute {
            0.15
        } else {
            0.5
        };
        assert!(rms < bound, "{label} {}: {rms}", backend.name());
    }
}

/// A volume of its own, so that no other test shares its grid keys.
fn own_volume() -> Arc<Volume> {
    synthetic([40, 36, 30], |x, y, z| {
        ((x + 2 * y + 3 * z) % 17) as f32 / 16.0
    })
}

/// Orbits the camera in `steps`; returns the frames' wall times (ms).
pub fn orbit(
    r: &mut Renderer,
    stack: &[PluginInstance],
    s: &FrameSettings,
    steps: u32,
) -> Vec<f64> {
    (0..steps)
        .map(|i| {
            let mut s = *s;
            s.camera.yaw_deg += 360.0 * i as f32 / steps as f32;
            let start = Instant::now();
            render(r, stack, TargetFormat::Rgba16Float, &s);
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect()
}

#[test]
fn the_mesh_pass_reruns_only_when_the_mesh_moves() {
    let v = own_volume();
    let mut c = mesh_clip("torus");
    c.params.set("size", ParamValue::Vec3([0.3, 0.3, 0.3]));
    let mut stack = vec![instance("classify.tf1d"), c.clone()];
    let s = settings(32, 32, Backend::Compute);
    // the grids are held here, as a view's CPU twin holds its grid: tests running beside
    // this one fill the cache's recent grids, and a held grid is never built again
    let _held = clip_mesh::grid_for(&c.params, &v).unwrap();
    let mut r = Renderer::new(gpu(), v.clone()).unwrap();
    render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
    assert_eq!(clip_mesh::mesh_pass_counts(&c.params, &v), (1, 1));
    orbit(&mut r, &stack, &s, 8);
    assert_eq!(
        clip_mesh::mesh_pass_counts(&c.params, &v),
        (1, 1),
        "the camera reruns nothing"
    );

    // keep, soft edge and cut layer are read by the shader: nothing reruns
    let before = render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
    for (k, value) in [
        ("keep", ParamValue::Enum("outside".into())),
        ("soft_edge", ParamValue::Float(1.5)),
        ("cut_layer", ParamValue::Float(1.0)),
    ] {
        stack[1].params.set(k, value);
    }
    let after = render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
    assert_ne!(before, after, "keeping the outside changes the image");
    assert_eq!(clip_mesh::mesh_pass_counts(&stack[1].params, &v), (1, 1));

    // moving the mesh builds and uploads a new grid, once
    let moved = {
        stack[1]
            .params
            .set("center", ParamValue::Vec3([0.1, 0.0, 0.0]));
        let _held_moved = clip_mesh::grid_for(&stack[1].params, &v).unwrap();
        render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
        orbit(&mut r, &stack, &s, 4);
        stack[1].params.clone()
    };
    assert_eq!(clip_mesh::mesh_pass_counts(&moved, &v), (1, 1));
    // and moving it back takes the cached grid: one more upload, no build
    stack[1].params.set("center", ParamValue::Vec3([0.0; 3]));
    render(&mut r, &stack, TargetFormat::Rgba16Float, &s);
    assert_eq!(clip_mesh::mesh_pass_counts(&stack[1].params, &v), (1, 2));
}

#[test]
fn mesh_files_clip_as_their_generated_shape() {
    let dir = tmp("clip-mesh-files");
    std::fs::create_dir_all(&dir).unwrap();
    let mut generated = mesh_clip("torus");
    generated
        .params
        .set("size", ParamValue::Vec3([0.3, 0.3, 0.3]));
    generated
        .params
        .set("rotate", ParamValue::Vec3([70.0, 0.0, 0.0]));
    generated.params.set("segments", ParamValue::Int(32));
    // the same torus written in world units (its size applied, not its rotation)
    let torus = mesh::torus(32, 0.35).map_positions(|p| p * 0.3);
    let s = settings(48, 48, Backend::Compute);
    let tf = instance("classify.tf1d");
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let expected = render(
        &mut r,
        &[tf.clone(), generated.clone()],
        TargetFormat::Rgba32Float,
        &s,
    );
    for ext in ["obj", "ply", "stl"] {
        let path = dir.join(format!("torus.{ext}"));
        mesh::save(&torus, &path).unwrap();
        let mut file = generated.clone();
        file.params.set("source", ParamValue::Enum("file".into()));
        file.params.set("file", ParamValue::Path(path));
        let got = render(&mut r, &[tf.clone(), file], TargetFormat::Rgba32Float, &s);
        let reference: Vec<[f64; 4]> = expected.iter().map(|p| p.map(f64::from)).collect();
        let rms = delta_e_rms(&got, &reference, 48, 48);
        eprintln!("{ext}: ΔE*uv RMS {rms:.5} against the generated torus");
        assert!(rms < 0.05, "{ext}: {rms}");
    }
}

#[test]
fn a_broken_mesh_file_is_refused_and_the_last_stack_keeps_rendering() {
    let dir = tmp("clip-mesh-broken");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("open_box.obj");
    let mut open = mesh::cube().map_positions(|p| p * 0.3);
    open.triangles.pop();
    mesh::save(&open, &path).unwrap();
    let mut c = mesh_clip("file");
    c.params.set("file", ParamValue::Path(path.clone()));
    let tf = instance("classify.tf1d");
    let s = settings(32, 32, Backend::Compute);
    let mut r = Renderer::new(gpu(), demo()).unwrap();
    let good = render(
        &mut r,
        &[tf.clone(), mesh_clip("sphere")],
        TargetFormat::Rgba16Float,
        &s,
    );
    let e = r
        .update_stack(&[tf.clone(), c], TargetFormat::Rgba16Float)
        .expect_err("an open mesh is refused")
        .to_string();
    assert!(
        e.contains("open_box.obj") && e.contains("not closed"),
        "{e}"
    );
    // the last good stack keeps drawing
    r.render(&s).unwrap();
    assert_eq!(good, r.read_pixels().unwrap().2);
    let again = render(
        &mut r,
        &[tf, mesh_clip("sphere")],
        TargetFormat::Rgba16Float,
        &s,
    );
    assert_eq!(good, again);
}

#[test]
fn bricks_the_mesh_removes_are_skipped_without_changing_the_image() {
    let mut ball = mesh_clip("sphere");
    ball.params.set("size", ParamValue::Vec3([0.25; 3]));
    let (base, share) = skipped_bricks(ball);
    eprintln!("empty bricks: {base:.3} without the mesh, {share:.3} with a ball kept");
    // the TF already empties 70 % of the demo's bricks; the ball removes most of the head
    assert!(share > base + 0.1, "{base} → {share}");
}

/// The DOS consistency gate with the block removed by a mesh (a box whose face lies on
/// the voxel boundary) instead of a plane.
pub fn mesh_dos_consistency() -> (f64, f64) {
    let (tf, dos) = dos_stack();
    let mut c = mesh_clip("box");
    // keep the box z ∈ [BLOCK_CUT_Z, 1.5] (x, y beyond the volume)
    let half = (1.5 - BLOCK_CUT_Z) / 2.0;
    c.params.set("size", ParamValue::Vec3([1.0, 1.0, half]));
    c.params
        .set("center", ParamValue::Vec3([0.0, 0.0, BLOCK_CUT_Z + half]));
    block_removed_consistency_with(c, tf, dos)
}

#[test]
fn matter_removed_by_a_mesh_casts_no_occlusion_in_dos() {
    let (clipped, unclipped) = mesh_dos_consistency();
    eprintln!("DOS, mesh cut: clipped vs cropped ΔE*uv RMS {clipped:.4}; unclipped {unclipped:.4}");
    assert!(clipped < 0.15, "{clipped}");
    assert!(unclipped > 2.0, "{unclipped}");
}
