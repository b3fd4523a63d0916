//! The Python package `vwb`: load a preset or a sample volume, change parameters,
//! render to a NumPy array, compute the converged reference, compare images and run
//! experiment files, all through the egui-free lab crate on the CPU Vulkan device or a
//! GPU.
//!
//! ```python
//! import vwb
//! s = vwb.Scene("presets/demo.ron")
//! s.set("classify.tf1d.mode", "preintegrated")
//! img = s.render(size=(128, 128), spacing=2.0)     # float32, (height, width, 3), sRGB in [0, 1]
//! ref = s.converged(size=(128, 128))
//! vwb.compare(img, ref)["rms_delta_e"]
//! rows = vwb.run_experiment("experiments/classification.ron", out="out/cls")
//! vwb.load_plugins("examples/plugins")              # WGSL plugins, no rebuild
//! s.add("shade.gooch")                              # or s.add(id, replace="shade.blinn_phong")
//! ```

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vwb_lab::experiment::{self, SetValue};
use vwb_lab::{document, headless, measure};
use vwb_render::metrics::{self, RgbImageF};
use vwb_render::preset::Document;
use vwb_render::reference::ReferenceOptions;
use vwb_render::slicing::VolumeBox;
use vwb_render::{GpuContext, Renderer, Volume};

/// A named volume's dims (x, y, z) and component count, as `Session.volumes` returns it.
type VolumeShape = ((u32, u32, u32), u32);

fn err(e: anyhow::Error) -> PyErr {
    PyRuntimeError::new_err(format!("{e:#}"))
}

/// The shared GPU context (created on first use).
fn gpu() -> PyResult<&'static GpuContext> {
    static GPU: OnceLock<Result<GpuContext, String>> = OnceLock::new();
    GPU.get_or_init(|| GpuContext::new_headless().map_err(|e| e.to_string()))
        .as_ref()
        .map_err(|e| PyRuntimeError::new_err(format!("no GPU adapter: {e}")))
}

/// The adapter vwb renders on (name, backend, driver).
#[pyfunction]
fn adapter() -> PyResult<String> {
    Ok(gpu()?.describe())
}

fn to_array<'py>(py: Python<'py>, img: &RgbImageF) -> Bound<'py, PyArray3<f32>> {
    let data: Vec<f32> = img.pixels.iter().flatten().map(|&c| c as f32).collect();
    Array3::from_shape_vec((img.height as usize, img.width as usize, 3), data)
        .expect("width·height·3 values")
        .into_pyarray(py)
}

fn from_array(a: &PyReadonlyArray3<f32>) -> PyResult<RgbImageF> {
    let shape = a.shape();
    if shape[2] != 3 {
        return Err(PyValueError::new_err(format!(
            "expected an (height, width, 3) image, got shape {shape:?}"
        )));
    }
    let flat: Vec<f32> = a.as_array().iter().copied().collect();
    let pixels = flat
        .chunks_exact(3)
        .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
        .collect();
    Ok(RgbImageF::new(shape[1] as u32, shape[0] as u32, pixels))
}

/// A scene: a document (volume, camera, plugin stack, render settings) and its volume.
#[pyclass(unsendable)]
struct Scene {
    doc: Document,
    volume: Arc<Volume>,
    renderer: Option<Renderer>,
}

impl Scene {
    fn frame(
        &self,
        size: Option<(u32, u32)>,
        spacing: Option<f32>,
        backend: Option<&str>,
    ) -> PyResult<Document> {
        let mut d = self.doc.clone();
        if let Some((w, h)) = size {
            if !((1..=16384).contains(&w) && (1..=16384).contains(&h)) {
                return Err(PyValueError::new_err(format!(
                    "size {w}x{h} is outside 1..=16384"
                )));
            }
            d.render.size = [w, h];
        }
        if let Some(s) = spacing {
            experiment::set_value(&mut d, "render.slice_spacing", &SetValue::Number(s as f64))
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
        }
        if let Some(b) = backend {
            d.render.backend = experiment::parse_backend(b).map_err(PyValueError::new_err)?;
        }
        headless::preflight(None, &d, &self.volume).map_err(err)?;
        Ok(d)
    }

    fn renderer(&mut self, d: &Document) -> PyResult<&mut Renderer> {
        if self.renderer.is_none() {
            self.renderer =
                Some(headless::renderer_for(gpu()?, d, self.volume.clone()).map_err(err)?);
        }
        let r = self.renderer.as_mut().expect("just made");
        r.set_volume_format(d.render.volume_format)
            .map_err(|e| err(e.into()))?;
        headless::apply_render_switches(r, d);
        r.update_stack(&d.stack, d.render.target)
            .map_err(|e| err(e.into()))?;
        Ok(r)
    }
}

#[pymethods]
impl Scene {
    /// A preset file; `volume` (a file or a sample name) replaces the preset's.
    #[new]
    #[pyo3(signature = (preset=None, volume=None))]
    fn new(preset: Option<PathBuf>, volume: Option<String>) -> PyResult<Self> {
        let mut doc = document::load_document(preset.as_deref()).map_err(err)?;
        let fit = preset.is_none() || volume.is_some();
        if let Some(v) = volume {
            doc.volume = headless::volume_arg(std::path::Path::new(&v));
        }
        let vol = headless::load_volume(&doc.volume).map_err(err)?;
        if fit {
            let b = VolumeBox::new(vol.dims, vol.spacing);
            doc.camera.fit(b.min, b.max);
        }
        Ok(Scene {
            doc,
            volume: vol,
            renderer: None,
        })
    }

    /// Sets `<plugin id>.<key>` or `render.slice_spacing|backend|target|early_termination|
    /// skipping|occupied_proxy|hull_cut|slices_per_proxy|volume_format|table_format` (checked against the parameter's spec, as in experiment
    /// files).
    fn set(&mut self, key: &str, value: Bound<'_, PyAny>) -> PyResult<()> {
        let v = if let Ok(b) = value.extract::<bool>() {
            SetValue::Bool(b)
        } else if let Ok(x) = value.extract::<f64>() {
            SetValue::Number(x)
        } else if let Ok(s) = value.extract::<String>() {
            SetValue::Text(s)
        } else if let Ok(xs) = value.extract::<Vec<f64>>() {
            SetValue::Numbers(xs)
        } else {
            return Err(PyValueError::new_err(format!(
                "'{key}': use a bool, a number, a string or a sequence of numbers"
            )));
        };
        experiment::set_value(&mut self.doc, key, &v)
            .map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// Adds the plugin `id` (built in, or a user plugin from [`load_plugins`]) with
    /// its defaults: in place of the plugin `replace` where given (a swap, as
    /// experiment files' `swap:`), else at the end of the stack.
    #[pyo3(signature = (id, replace=None))]
    fn add(&mut self, id: &str, replace: Option<&str>) -> PyResult<()> {
        let plugin = vwb_plugins::registry()
            .get(id)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let inst = vwb_render::PluginInstance::new(plugin);
        match replace {
            Some(old) => {
                let at = self
                    .doc
                    .stack
                    .iter()
                    .position(|i| i.plugin.id() == old)
                    .ok_or_else(|| {
                        PyValueError::new_err(format!("the stack has no plugin '{old}' to replace"))
                    })?;
                self.doc.stack[at] = inst;
            }
            None => self.doc.stack.push(inst),
        }
        Ok(())
    }

    /// Removes the plugin `id` from the stack.
    fn remove(&mut self, id: &str) -> PyResult<()> {
        let before = self.doc.stack.len();
        self.doc.stack.retain(|i| i.plugin.id() != id);
        if self.doc.stack.len() == before {
            return Err(PyValueError::new_err(format!(
                "the stack has no plugin '{id}'"
            )));
        }
        Ok(())
    }

    /// Adds a named volume (a preset's `volumes:`) that plugins' volume inputs then
    /// name, e.g. a label volume for `classify.labels`: `source` is a file or a sample
    /// name, `name` a new name (empty: the file's stem). It loads now; a taken or
    /// invalid name, or a file that does not load, is refused and nothing changes.
    /// Returns the name.
    #[pyo3(signature = (source, name=""))]
    fn add_volume(&mut self, source: &str, name: &str) -> PyResult<String> {
        let mut doc = self.doc.clone();
        let (name, inputs) = document::add_named_volume(&mut doc, name, source)
            .map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
        if let Some(r) = &mut self.renderer {
            r.set_inputs(inputs);
        }
        self.doc = doc;
        Ok(name)
    }

    /// The named volumes: name → (dims (x, y, z), components).
    fn volumes(&self) -> PyResult<std::collections::BTreeMap<String, VolumeShape>> {
        let inputs = headless::inputs_for(&self.doc).map_err(err)?;
        Ok(inputs
            .names()
            .filter_map(|n| {
                let v = inputs.get(n)?;
                Some((
                    n.to_string(),
                    ((v.dims[0], v.dims[1], v.dims[2]), v.components),
                ))
            })
            .collect())
    }

    /// The enabled plugins' ids, in stack order.
    fn plugins(&self) -> Vec<String> {
        self.doc
            .stack
            .iter()
            .filter(|i| i.enabled)
            .map(|i| i.plugin.id().to_string())
            .collect()
    }

    /// Renders on the GPU: float32 array (height, width, 3), sRGB in [0, 1], composited
    /// over the scene's background.
    #[pyo3(signature = (size=None, spacing=None, backend=None))]
    fn render<'py>(
        &mut self,
        py: Python<'py>,
        size: Option<(u32, u32)>,
        spacing: Option<f32>,
        backend: Option<&str>,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let d = self.frame(size, spacing, backend)?;
        let r = self.renderer(&d)?;
        r.render(&d.frame_settings()).map_err(|e| err(e.into()))?;
        let img = measure::gpu_image(r, &d).map_err(err)?;
        Ok(to_array(py, &img))
    }

    /// Times `frames` frames after one untimed: a dict with frame_ms (GPU timestamps
    /// where the adapter has them, else wall), clock, slices.
    #[pyo3(signature = (size=None, spacing=None, backend=None, frames=3))]
    fn time<'py>(
        &mut self,
        py: Python<'py>,
        size: Option<(u32, u32)>,
        spacing: Option<f32>,
        backend: Option<&str>,
        frames: u32,
    ) -> PyResult<Bound<'py, PyDict>> {
        let d = self.frame(size, spacing, backend)?;
        let r = self.renderer(&d)?;
        let t = measure::time_frames(r, &d.frame_settings(), 1, frames.max(1)).map_err(err)?;
        let (ms, clock) = t.frame_ms();
        let out = PyDict::new(py);
        out.set_item("frame_ms", ms)?;
        out.set_item("clock", clock)?;
        out.set_item("slices", t.slices)?;
        Ok(out)
    }

    /// The converged reference of the scene's stack (the CPU twins refined until one
    /// halving changes the image by less than `tolerance` RMS ΔE*uv; the GPU for stacks
    /// without twins; a plugin's own reference where it supplies one).
    #[pyo3(signature = (size=None, tolerance=0.1))]
    fn converged<'py>(
        &self,
        py: Python<'py>,
        size: Option<(u32, u32)>,
        tolerance: f64,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let d = self.frame(size, None, None)?;
        let (img, _) = measure::converged_image(
            &self.volume,
            &d,
            &d.frame_settings(),
            tolerance,
            &ReferenceOptions::default(),
        )
        .map_err(err)?;
        Ok(to_array(py, &img))
    }
}

/// Compares two (height, width, 3) images in [0, 1]: a dict of rms_delta_e,
/// mean_delta_e, max_delta_e, share_above_6 (CIE 1976 ΔE*uv), psnr_db, ssim and
/// rms_delta_e_blur (ΔE*uv RMS after a σ = 1 pixel blur of both).
#[pyfunction]
fn compare<'py>(
    py: Python<'py>,
    a: PyReadonlyArray3<f32>,
    b: PyReadonlyArray3<f32>,
) -> PyResult<Bound<'py, PyDict>> {
    let (a, b) = (from_array(&a)?, from_array(&b)?);
    let m = metrics::try_compare(&a, &b).map_err(PyValueError::new_err)?;
    let out = PyDict::new(py);
    out.set_item("rms_delta_e", m.rms_delta_e)?;
    out.set_item("mean_delta_e", m.mean_delta_e)?;
    out.set_item("max_delta_e", m.max_delta_e)?;
    out.set_item("share_above_6", m.share_above_6)?;
    out.set_item("psnr_db", m.psnr_db)?;
    out.set_item("ssim", m.ssim)?;
    out.set_item("rms_delta_e_blur", m.rms_delta_e_blur)?;
    Ok(out)
}

/// Runs an experiment file and returns its rows as dicts (scene, variant, values,
/// slices, frame_ms, metrics, ...); writes the report into `out` (default
/// reports/<name>). Raises when an assertion fails (after writing the report).
#[pyfunction]
#[pyo3(signature = (path, out=None))]
fn run_experiment<'py>(
    py: Python<'py>,
    path: PathBuf,
    out: Option<PathBuf>,
) -> PyResult<Bound<'py, PyAny>> {
    let o = experiment::run_file(&path, out.as_deref()).map_err(err)?;
    let text = serde_json::to_string(&o.rows).map_err(|e| err(e.into()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// Loads user plugins (a folder with `plugin.ron` and its WGSL, or a folder of them)
/// and the user plugin folder ($VWB_PLUGINS, else ~/.config/vwb/plugins), so that
/// scenes, presets and experiment files can use them; returns the ids loaded. A plugin
/// that fails to load raises ValueError naming its file (and the WGSL line); the
/// others still load.
#[pyfunction]
#[pyo3(signature = (path=None))]
fn load_plugins(path: Option<PathBuf>) -> PyResult<Vec<String>> {
    let extra: Vec<PathBuf> = path.into_iter().collect();
    let (ids, errors) = vwb_plugins::user::install_from(&extra);
    if !errors.is_empty() {
        return Err(PyValueError::new_err(errors.join("\n")));
    }
    Ok(ids.into_iter().map(str::to_string).collect())
}

#[pymodule]
fn vwb(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(load_plugins, m)?)?;
    m.add_class::<Scene>()?;
    m.add_function(wrap_pyfunction!(adapter, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(run_experiment, m)?)?;
    Ok(())
}
