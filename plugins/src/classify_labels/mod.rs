//! `classify.labels`: a u8 label volume beside the data (NRRD, same dims), one 1D
//! transfer function per label, nearest-neighbour label lookup, labels that can be
//! hidden.
//!
//! Parameters: `labels` (the label file; structural: a new file recreates the
//! resources), `tf_0` … `tf_7` and `show_0` … `show_7` (labels 0–7; labels above 7
//! use `tf_7` and `show_7`), `opacity` (global scale). The tables are baked into one
//! 256 × 8 texture, a hidden label's row all zero. Label files are loaded once per
//! path and modification time and shared by the GPU resources and the CPU twin.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use glam::{DVec3, DVec4};
use vwb_render::params::{Group, ParamSpec, ParamValue, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, ResourceDecl,
    ResourceKind, ShaderSource, Transparency,
};
use vwb_render::tf::{LUT_SIZE, TfCurve, eval_lut};
use vwb_render::volume::{ScalarType, VoxelData};

#[cfg(test)]
mod tests;

/// Labels with their own transfer function (0 … MAX_LABELS − 1).
pub const MAX_LABELS: usize = 8;

/// The labels' transfer functions, a parameter group: label i's curve `tf_{i}` and
/// its switch `show_{i}`.
pub const LABELS: Group = Group::new("Label", MAX_LABELS).switch("show_{}");

pub struct Labels;

/// A loaded label volume.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelGrid {
    pub file: PathBuf,
    pub dims: [u32; 3],
    pub labels: Vec<u8>,
    /// Which of the table rows occur (labels above the last row count for it).
    pub present: [bool; MAX_LABELS],
}

impl LabelGrid {
    /// Nearest-voxel label at a texture coordinate, as the shader's `floor(tex·dims)`.
    pub fn at(&self, tex: DVec3) -> u8 {
        self.labels[nearest_voxel(self.dims, tex)]
    }
}

/// Linear index (x fastest) of the voxel nearest to a texture coordinate, as the
/// shaders' `clamp(floor(tex·dims), 0, dims − 1)`.
pub fn nearest_voxel(dims: [u32; 3], tex: DVec3) -> usize {
    let d = dims.map(|n| n.max(1) as usize);
    let idx = |a: usize| {
        let f = (tex[a] * d[a] as f64).floor();
        if f.is_nan() {
            0
        } else {
            (f.max(0.0) as usize).min(d[a] - 1)
        }
    };
    (idx(2) * d[1] + idx(1)) * d[0] + idx(0)
}

/// `load(path)`, cached per value type, path and modification time (label volumes are
/// read once and shared by the GPU resources and the CPU twin).
pub fn cached_load<T: Send + Sync + 'static>(
    path: &Path,
    load: impl FnOnce(&Path) -> Result<T, String>,
) -> Result<Arc<T>, String> {
    type Key = (std::any::TypeId, PathBuf, Option<std::time::SystemTime>);
    type Cache = Mutex<HashMap<Key, Arc<dyn std::any::Any + Send + Sync>>>;
    static CACHE: std::sync::OnceLock<Cache> = std::sync::OnceLock::new();
    let modified = std::fs::metadata(path).and_then(|m| m.modified()).ok();
    let key = (std::any::TypeId::of::<T>(), path.to_path_buf(), modified);
    let cache = CACHE.get_or_init(Default::default);
    if let Some(v) = cache.lock().ok().and_then(|c| c.get(&key).cloned())
        && let Ok(v) = v.downcast::<T>()
    {
        return Ok(v);
    }
    let v = Arc::new(load(path)?);
    if let Ok(mut c) = cache.lock() {
        c.insert(key, v.clone());
    }
    Ok(v)
}

/// Loads a u8 label volume (cached per path and modification time).
pub fn load_labels(path: &Path) -> Result<Arc<LabelGrid>, String> {
    cached_load(path, |path| {
        let v = vwb_render::volume::load(path).map_err(|e| e.to_string())?;
        let file = path.display();
        if v.components != 1 || v.scalar_type() != ScalarType::U8 {
            return Err(format!(
                "{file}: a label volume must hold u8 scalars, found {} × {}",
                v.components,
                v.scalar_type().name()
            ));
        }
        let VoxelData::U8(labels) = v.data else {
            return Err(format!("{file}: a label volume must hold u8 scalars"));
        };
        let mut present = [false; MAX_LABELS];
        for &l in &labels {
            present[(l as usize).min(MAX_LABELS - 1)] = true;
        }
        Ok(LabelGrid {
            file: path.to_path_buf(),
            dims: v.dims,
            labels,
            present,
        })
    })
}

/// The label file named by the `labels` parameter, loaded by `load` and checked
/// against the data's dims; errors name `plugin` and the file.
pub fn label_file<T>(
    plugin: &str,
    params: &ParamValues,
    data_dims: [u32; 3],
    load: impl FnOnce(&Path) -> Result<Arc<T>, String>,
    dims_of: impl FnOnce(&T) -> [u32; 3],
) -> Result<Arc<T>, PluginError> {
    let error = |message: String| PluginError::Invalid {
        plugin: plugin.into(),
        message,
    };
    let path = params
        .path("labels")
        .ok_or_else(|| error("no label volume set (parameter `labels`)".into()))?;
    let grid = load(path).map_err(error)?;
    let dims = dims_of(&grid);
    if dims != data_dims {
        return Err(error(format!(
            "{}: label volume dims {:?} differ from the data's {:?}",
            path.display(),
            dims,
            data_dims
        )));
    }
    Ok(grid)
}

fn error(message: String) -> PluginError {
    PluginError::Invalid {
        plugin: "classify.labels".into(),
        message,
    }
}

/// The label grid for the parameters, checked against the data's dims.
fn grid_for(params: &ParamValues, data_dims: [u32; 3]) -> Result<Arc<LabelGrid>, PluginError> {
    label_file("classify.labels", params, data_dims, load_labels, |g| g.dims)
}

/// A distinct default colour per label; label 0 (background) transparent.
pub fn default_curve(label: usize) -> TfCurve {
    const PALETTE: [[f32; 3]; MAX_LABELS] = [
        [0.0, 0.0, 0.0],
        [0.95, 0.6, 0.35],
        [0.35, 0.6, 0.95],
        [0.95, 0.95, 0.9],
        [0.5, 0.9, 0.4],
        [0.9, 0.4, 0.8],
        [0.9, 0.85, 0.3],
        [0.4, 0.9, 0.9],
    ];
    let c = PALETTE[label];
    let alpha = if label == 0 { 0.0 } else { 0.3 };
    TfCurve::ramp(0.05, 0.5, [c[0], c[1], c[2], alpha])
}

/// The baked table: one row of LUT_SIZE entries per label, hidden rows zero.
pub fn bake(params: &ParamValues) -> Vec<[f32; 4]> {
    (0..MAX_LABELS)
        .flat_map(|l| {
            if params.boolean(LABELS.key("show_{}", l)) {
                params
                    .tf(LABELS.key("tf_{}", l))
                    .cloned()
                    .unwrap_or_else(|| default_curve(l))
                    .bake(LUT_SIZE)
            } else {
                vec![[0.0; 4]; LUT_SIZE]
            }
        })
        .collect()
}

impl Plugin for Labels {
    /// It reads a label volume over the whole volume, in the volume's texture coordinates.
    fn splits_into_bricks(&self) -> bool {
        false
    }
    fn id(&self) -> &'static str {
        "classify.labels"
    }
    fn display_name(&self) -> &'static str {
        "Labels"
    }
    fn description(&self) -> &'static str {
        "One 1D transfer function per label of a u8 label volume (nearest-neighbour lookup)"
    }
    fn params(&self) -> Vec<ParamSpec> {
        let mut v = vec![
            ParamSpec::path("labels", "Label volume", "")
                .structural()
                .with_doc("u8 NRRD with the data's dims; relative to the preset"),
            ParamSpec::float_log("opacity", "Opacity scale", 0.01, 100.0, 1.0),
        ];
        v.extend(LABELS.specs(|l| {
            vec![
                ParamSpec::boolean(LABELS.key("show_{}", l), "Show", true),
                ParamSpec::tf(LABELS.key("tf_{}", l), "Transfer function", default_curve(l)),
            ]
        }));
        v
    }
    fn shader(&self) -> ShaderSource {
        ShaderSource::new_static(
            "plugins/src/classify_labels/labels.wgsl",
            include_str!("labels.wgsl"),
        )
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        vec![
            ResourceDecl {
                name: "labels",
                kind: ResourceKind::Texture3d,
            },
            ResourceDecl {
                name: "lut",
                kind: ResourceKind::Texture2d,
            },
        ]
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let grid = grid_for(params, gpu.volume.dims)?;
        let (texture, view) = vwb_render::gpu::upload_r8_3d(
            gpu.device,
            gpu.queue,
            "classify.labels labels",
            grid.dims,
            &grid.labels,
        );
        let res = [
            GpuResource { texture, view },
            gpu.create_table("classify.labels lut", LUT_SIZE as u32, MAX_LABELS as u32),
        ];
        self.update_resources(gpu, params, &res)?;
        Ok(res.to_vec())
    }
    fn update_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
        resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        let Some(lut) = resources.get(1) else {
            return Err(error("lookup texture missing".into()));
        };
        gpu.write_table(lut, &bake(params));
        Ok(())
    }
    /// Visible where the table of any shown label that occurs in the label volume is
    /// (the label is not known per brick). No promise when the labels cannot be read.
    fn transparency(&self, params: &ParamValues) -> Transparency {
        let Some(grid) = params.path("labels").and_then(|p| load_labels(p).ok()) else {
            return Transparency::Unknown;
        };
        let present = grid.present;
        let opacity = params.float("opacity");
        let table = bake(params);
        vwb_render::skipping::visible_by_table(
            (0..LUT_SIZE)
                .map(|i| {
                    (0..MAX_LABELS)
                        .any(|l| present[l] && table[l * LUT_SIZE + i][3] * opacity > 0.0)
                })
                .collect(),
        )
    }
    /// The demo's label volume (`presets/data/demo_labels.nrrd`, in this checkout).
    fn demo_params(&self) -> Option<ParamValues> {
        let mut p = ParamValues::defaults(&self.params());
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../presets/data/demo_labels.nrrd");
        p.set("labels", ParamValue::Path(path.into()));
        Some(p)
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        let grid = params.path("labels").and_then(|p| load_labels(p).ok())?;
        Some(Box::new(LabelsTwin {
            table: bake(params),
            opacity: params.float("opacity") as f64,
            grid,
        }))
    }
}

/// CPU twin of `classify`: the same nearest label and the same table row.
pub struct LabelsTwin {
    pub table: Vec<[f32; 4]>,
    pub opacity: f64,
    pub grid: Arc<LabelGrid>,
}

impl CpuTwin for LabelsTwin {
    fn classify(&self, _ctx: &CpuContext, s: &mut CpuSample) {
        let row = (self.grid.at(s.tex) as usize).min(MAX_LABELS - 1);
        let c = eval_lut(
            &self.table[row * LUT_SIZE..(row + 1) * LUT_SIZE],
            s.value.clamp(0.0, 1.0),
        );
        s.color = DVec4::new(c[0], c[1], c[2], (c[3] * self.opacity).clamp(0.0, 1.0));
    }
}
