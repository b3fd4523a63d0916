//! `test.vector_passes`: the plugin contract's test of named vector inputs and chained
//! volume passes. Its `field` input (a named volume of the document, on a grid of its
//! own, its components kept) is uploaded as an rgba texture; three volume passes on the
//! document volume's grid follow (`passes.wgsl`): the speed |v| sampled from the field,
//! a 7-point blur of the speed, and the blurred speed's gradient magnitude. The `sample`
//! hook shows gain × that; with `view` on (structural), a fourth pass is a view pass
//! (`VolumePassDecl::camera`): the edges weighted by how much the gradient faces the
//! view ray, rerun whenever the camera moves. The hook (a scalar input's normalised value stands for the speed, so
//! the plugin also renders the demo volume: its edges). A change of the input reruns the chain; `gain` reruns
//! nothing. The twin computes the same three volumes in f64 (`prepare_passes`).

use std::sync::Arc;

use glam::{DVec3, DVec4};
use vwb_render::flow::GridField;
use vwb_render::params::{Components, ParamSpec, ParamValues};
use vwb_render::volume::Volume;
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, CpuView, GpuInit, GpuResource, Plugin, PluginError, ResourceDecl,
    ResourceKind, ShaderSource, StackClassify, VolumePassDecl, trilinear_grid,
};

#[cfg(test)]
mod tests;

/// `facing`: the view pass is built in (the `view` parameter).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct VectorPasses {
    pub facing: bool,
}

const FILE: &str = "plugins/src/test_vector_passes/passes.wgsl";
const SOURCE: &str = include_str!("passes.wgsl");

impl Plugin for VectorPasses {
    fn id(&self) -> &'static str {
        "test.vector_passes"
    }
    fn display_name(&self) -> &'static str {
        "Vector input, three passes (contract test)"
    }
    fn description(&self) -> &'static str {
        "Speed of a named vector input, blurred, then its gradient magnitude: three chained volume passes"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::volume("field", "Vector field", Components::Any).with_doc(
                "a named vector volume, or the document's own (a scalar one: its normalised value is the speed)",
            ),
            ParamSpec::float("gain", "Gain", 0.0, 64.0, 8.0),
            ParamSpec::boolean("view", "View pass", false)
                .structural()
                .with_doc("a fourth pass, rerun when the camera moves: the edges that face the viewer"),
        ]
    }
    fn shader(&self) -> ShaderSource {
        if self.facing {
            ShaderSource::new_static(FILE, SOURCE)
        } else {
            ShaderSource::without_region(FILE, SOURCE, "facing", "")
        }
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let c = VectorPasses {
            facing: params.boolean("view"),
        };
        (c != *self).then(|| Arc::new(c) as Arc<dyn Plugin>)
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![ResourceDecl {
            name: "field",
            kind: ResourceKind::Texture3d,
        }]
    }
    fn volume_passes(&self) -> Vec<VolumePassDecl> {
        let mut passes = vec![
            VolumePassDecl::new("speed", "speed_pass"),
            VolumePassDecl::new("blurred", "blur_pass"),
            VolumePassDecl::new("edges", "edge_pass"),
        ];
        if self.facing {
            passes.push(VolumePassDecl::new("facing", "facing_pass").view());
        }
        passes
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let field = input_field(gpu.input(params, "field")?);
        Ok(vec![crate::flow_lic3d::field_texture(
            gpu,
            "test.vector_passes field",
            Some(&field),
            false,
        )])
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(VectorPassesTwin {
            params: params.clone(),
            gain: params.float("gain") as f64,
            facing: self.facing,
            blurred: None,
            shown: None,
        }))
    }
}

/// The field the passes read, scaled to a top speed of 1: a vector volume's
/// components (per unit of its voxel size, [`GridField::from_volume`]), or a scalar
/// volume's normalised value as the x component.
pub fn input_field(volume: &Volume) -> GridField {
    let mut f = GridField::from_volume(volume).unwrap_or_else(|_| GridField {
        dims: volume.dims,
        components: 3,
        data: volume
            .normalized_scalars()
            .into_iter()
            .flat_map(|v| [v, 0.0, 0.0])
            .collect(),
    });
    f.to_unit_speed();
    f
}

/// A scalar volume on a grid, x fastest.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub dims: [u32; 3],
    pub data: Vec<f64>,
}

impl Grid {
    fn index(&self, v: [i64; 3]) -> usize {
        let d = self.dims.map(|x| x as i64);
        let c = |a: usize| v[a].clamp(0, d[a] - 1) as usize;
        (c(2) * d[1] as usize + c(1)) * d[0] as usize + c(0)
    }
    /// The value at a voxel, its index clamped into the grid (`textureLoad` of a
    /// clamped index).
    pub fn at(&self, v: [i64; 3]) -> f64 {
        self.data[self.index(v)]
    }
    fn from_fn(dims: [u32; 3], f: impl Fn([i64; 3]) -> f64) -> Self {
        let mut data = Vec::with_capacity(dims.iter().map(|&d| d as usize).product());
        for z in 0..dims[2] as i64 {
            for y in 0..dims[1] as i64 {
                for x in 0..dims[0] as i64 {
                    data.push(f([x, y, z]));
                }
            }
        }
        Self { dims, data }
    }
}

/// The three pass volumes on the grid `dims` for a field (none: no flow), as the GPU
/// computes them: (speed, blurred, edges).
pub fn pass_volumes(dims: [u32; 3], field: Option<&GridField>) -> (Grid, Grid, Grid) {
    let speed = Grid::from_fn(dims, |v| {
        let Some(f) = field else { return 0.0 };
        let tex = DVec3::from(std::array::from_fn::<f64, 3, _>(|a| {
            (v[a] as f64 + 0.5) / dims[a] as f64
        }));
        let c = f.components as usize;
        trilinear_grid(f.dims, tex, |i| {
            let x = |k: usize| if k < c { f.data[i * c + k] as f64 } else { 0.0 };
            DVec4::new(x(0), x(1), x(2), 0.0)
        })
        .truncate()
        .length()
    });
    let blurred = Grid::from_fn(dims, |v| {
        let mut sum = speed.at(v);
        for a in 0..3 {
            let (mut hi, mut lo) = (v, v);
            hi[a] += 1;
            lo[a] -= 1;
            sum += speed.at(hi) + speed.at(lo);
        }
        sum / 7.0
    });
    let edges = Grid::from_fn(dims, |v| gradient(&blurred, v).length());
    (speed, blurred, edges)
}

/// The central (one-sided at the border) differences of a grid at a voxel.
fn gradient(grid: &Grid, v: [i64; 3]) -> DVec3 {
    let mut g = DVec3::ZERO;
    for a in 0..3 {
        let lo = (v[a] - 1).max(0);
        let hi = (v[a] + 1).min(grid.dims[a] as i64 - 1);
        let (mut vh, mut vl) = (v, v);
        vh[a] = hi;
        vl[a] = lo;
        g[a] = (grid.at(vh) - grid.at(vl)) / (hi - lo).max(1) as f64;
    }
    g
}

/// The view pass over `blurred` for a camera, the volume spanning `lo`..`hi`: the
/// gradient's length times |n · d| (d the unit ray from the eye through the voxel's
/// centre, or the view direction when orthographic).
pub fn facing_volume(blurred: &Grid, view: &CpuView, (lo, hi): (DVec3, DVec3)) -> Grid {
    let dims = blurred.dims;
    Grid::from_fn(dims, |v| {
        let g = gradient(blurred, v);
        let l = g.length();
        if l <= 0.0 {
            return 0.0;
        }
        let t = DVec3::from(std::array::from_fn::<f64, 3, _>(|a| {
            (v[a] as f64 + 0.5) / dims[a] as f64
        }));
        let p = lo + (hi - lo) * t;
        let d = if view.perspective {
            (p - view.eye).normalize()
        } else {
            view.forward
        };
        l * (g / l).dot(d).abs()
    })
}

/// CPU twin: the passes in `prepare_passes` (the camera's view pass again for every
/// camera), the hook as the GPU's.
pub struct VectorPassesTwin {
    pub params: ParamValues,
    pub gain: f64,
    pub facing: bool,
    /// The blurred speed and the edges (they do not depend on the camera).
    pub blurred: Option<(Arc<Grid>, Arc<Grid>)>,
    /// The volume the hook reads: the edges, or the facing edges of the last camera.
    pub shown: Option<Arc<Grid>>,
}

impl CpuTwin for VectorPassesTwin {
    fn prepare_passes(&mut self, ctx: &CpuContext, _classify: &StackClassify<'_>) {
        let chain = self.blurred.get_or_insert_with(|| {
            let field = input_field(ctx.input(&self.params, "field"));
            let (_, blurred, edges) = pass_volumes(ctx.volume.dims, Some(&field));
            (Arc::new(blurred), Arc::new(edges))
        });
        self.shown = Some(if self.facing {
            Arc::new(facing_volume(&chain.0, &ctx.view, ctx.volume_box()))
        } else {
            chain.1.clone()
        });
    }
    fn sample(&self, _ctx: &CpuContext, s: &mut CpuSample) {
        let Some(e) = &self.shown else { return };
        let v = trilinear_grid(e.dims, s.tex, |i| DVec4::splat(e.data[i])).x;
        s.value = (self.gain * v).clamp(0.0, 1.0);
    }
}
