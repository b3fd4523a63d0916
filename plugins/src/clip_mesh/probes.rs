//! `clip.mesh`'s probe: the mesh pass's voxelisation on its own (no GPU, no image), run
//! by experiment files (`probe:`, docs/experiments.md).

use std::sync::{Arc, OnceLock};
use std::time::Instant;

use vwb_render::params::{ParamSpec, ParamValue, ParamValues};
use vwb_render::plugin::{Plugin, Probe, Statistic};
use vwb_render::slicing::VolumeBox;
use vwb_render::volume::Volume;

use super::{ClipMesh, RESOLUTIONS, grid_dims, placed_mesh, voxelize::voxelize};

/// The generated meshes a probe may voxelise (a file is the window's business).
const SHAPES: [&str; 3] = ["sphere", "box", "torus"];

/// The embedded demo volume (128×128×84), built once.
fn demo() -> Arc<Volume> {
    static DEMO: OnceLock<Arc<Volume>> = OnceLock::new();
    DEMO.get_or_init(|| Arc::new(vwb_render::volume::demo()))
        .clone()
}

/// `clip.mesh.voxelise`: a generated mesh placed over the embedded demo volume and
/// voxelised into the plugin's signed-distance grid at a resolution, `repeats` times on
/// this machine's cores (rayon): the least wall time, the mesh's triangles, the grid's
/// cells, and the z columns that cross the mesh an odd number of times (grazing rays,
/// whose inside may be wrong).
pub struct Voxelise;

impl Probe for Voxelise {
    fn name(&self) -> &'static str {
        "voxelise"
    }
    fn description(&self) -> &'static str {
        "the mesh pass's voxelisation of a generated mesh over the embedded demo volume (128×128×84), least of `repeats` runs"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::enumeration("source", "Mesh", &SHAPES, 0),
            ParamSpec::int("segments", "Shape segments", 3, 512, 48),
            ParamSpec::float("torus_ratio", "Torus tube ratio", 0.01, 0.99, 0.35),
            ParamSpec::vec3("size", "Shape size", 0.0, 2.0, [0.3; 3]),
            ParamSpec::enumeration("resolution", "Grid resolution", &RESOLUTIONS, 2),
            ParamSpec::int("repeats", "Runs (the least is kept)", 1, 20, 3),
        ]
    }
    fn figures(&self) -> Vec<(&'static str, &'static str)> {
        vec![
            ("triangles", "the placed mesh's triangles"),
            ("cells", "the grid's cells"),
            ("ms", "the least wall time of the runs, ms"),
            ("odd_columns", "z columns crossing the mesh an odd number of times"),
        ]
    }
    fn run(&self, p: &ParamValues) -> Result<Vec<Statistic>, String> {
        // the plugin's own parameters, with the probe's set
        let mut params = ParamValues::defaults(&ClipMesh::default().params());
        for key in ["source", "segments", "torus_ratio", "size", "resolution"] {
            if let Some(v) = p.get(key) {
                params.set(key, v.clone());
            }
        }
        params.set("keep", ParamValue::Enum("inside".into()));
        let v = demo();
        let placed = placed_mesh(&params, &v)?;
        let dims = grid_dims(&params, v.dims);
        let vbox = VolumeBox::new(v.dims, v.spacing);
        let (mut best, mut odd) = (f64::INFINITY, 0);
        for _ in 0..p.int("repeats").max(1) {
            let start = Instant::now();
            let g = voxelize(
                &placed,
                vbox.min.as_dvec3(),
                vbox.max.as_dvec3(),
                dims,
                vbox.voxel as f64,
            );
            best = best.min(start.elapsed().as_secs_f64() * 1e3);
            odd = g.odd_columns;
        }
        let cells: f64 = dims.iter().map(|&d| d as f64).product();
        Ok(vec![
            Statistic {
                name: "triangles",
                value: placed.triangles.len() as f64,
            },
            Statistic {
                name: "cells",
                value: cells,
            },
            Statistic {
                name: "ms",
                value: best,
            },
            Statistic {
                name: "odd_columns",
                value: odd as f64,
            },
        ])
    }
}
