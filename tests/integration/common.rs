use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use vwb_render::plugin::{PluginInstance, Registry};
use vwb_render::renderer::{Backend, FrameSettings};
use vwb_render::volume::{Volume, VoxelData};
use vwb_render::{Camera, GpuContext, Projection, Renderer, TargetFormat};

/// The repository root. Also points the sample data directory at the shared copy of
/// the sample files beside the repository when `VWB_DATA_DIR` is unset, so that
/// `cargo test` alone finds them (scripts/test sets `VWB_DATA_DIR` the same way).
pub fn repo() -> PathBuf {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    vwb_render::samples::set_default_data_dir(root.join("../shared/data"));
    root
}

/// The sample data directory the tests use (for child processes).
pub fn data_dir() -> PathBuf {
    repo();
    vwb_render::samples::data_dir().expect("a data directory")
}

/// A path in this test run's scratch directory.
pub fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vwb-test-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

pub fn bless() -> bool {
    std::env::var_os("VWB_BLESS").is_some()
}

/// The shared GPU context. Panics (fails the test) without a Vulkan adapter.
pub fn gpu() -> &'static GpuContext {
    static GPU: OnceLock<GpuContext> = OnceLock::new();
    GPU.get_or_init(|| {
        let g = GpuContext::new_headless().unwrap_or_else(|e| {
            panic!("GPU tests need a Vulkan adapter (lavapipe on the CPU is fine): {e}")
        });
        assert_eq!(
            g.info.backend,
            wgpu::Backend::Vulkan,
            "GPU tests must run on Vulkan, got {}",
            g.describe()
        );
        eprintln!("GPU tests on {}", g.describe());
        g
    })
}

/// Whether the tests run on a GPU (`VWB_TEST_GPU=1` on a machine with one) rather than
/// on a CPU adapter such as lavapipe.
pub fn on_gpu() -> bool {
    gpu().info.device_type != wgpu::DeviceType::Cpu
}

/// A bound on a GPU image against its f64 twin or a golden image: `lavapipe`'s on the
/// CPU device, where CI runs and which reproduces the twins within these bounds, and
/// `gpu` on a GPU adapter. GPUs filter textures with few fractional bits (NVIDIA: 8,
/// so a trilinear weight is off by up to 1/512), which gradients, LIC integrals and 2D
/// lookups amplify; docs/gpu/README.md gives what an H200 measured against each bound.
pub fn adapter_bound(lavapipe: f64, gpu: f64) -> f64 {
    if on_gpu() { gpu } else { lavapipe }
}

/// Asserts that an optimisation kept an image: bit for bit on the CPU device (where CI
/// runs, and where the tests hold every such claim exactly). On a GPU adapter, pixels
/// may differ by less than one 8-bit level (1/255) in at most 1 % of them: the two
/// variants compile to different code (the driver fuses and orders the arithmetic of
/// each as it likes), a sample point then moves by a rounding, and the GPU's 8-bit
/// trilinear weights turn that into a step of 1/256 of a voxel difference. The H200
/// measured at most 0.002 in 13 of 4096 pixels (docs/gpu/README.md).
pub fn assert_kept(a: &[[f32; 4]], b: &[[f32; 4]], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: sizes");
    if !on_gpu() {
        assert!(a == b, "{what}: the image changed");
        return;
    }
    let mut worst = 0.0f32;
    let mut differ = 0usize;
    for (p, q) in a.iter().zip(b) {
        let d = p
            .iter()
            .zip(q)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f32::max);
        worst = worst.max(if d.is_nan() { f32::INFINITY } else { d });
        differ += usize::from(d != 0.0);
    }
    assert!(
        worst < 1.0 / 255.0 && differ * 100 <= a.len(),
        "{what}: {differ} of {} pixels differ, by up to {worst}",
        a.len()
    );
}

/// The bound of a GPU image against its CPU twins, in RMS ΔE*uv: the compute backend
/// casts the same rays as the twins (0.01–0.09 measured on lavapipe); raster
/// interpolates positions over proxy polygons, and per-slice state (shade.dos) carries
/// those differences from slice to slice. On a GPU the sweeping twin tests
/// (`reference::`, `coverage::`) hold `delta_e_rms_near` (an edge may move by a pixel)
/// to these bounds; the H200's worst was storm_lic_tf2d on compute, 0.63 (a LIC
/// integral over a 2D lookup: a broad difference, not an edge).
pub fn twin_bound(backend: vwb_render::Backend, per_slice: bool) -> f64 {
    let (lavapipe, gpu) = twin_bounds(backend, per_slice);
    adapter_bound(lavapipe, gpu)
}

/// [`twin_bound`]'s (lavapipe, GPU) pair.
fn twin_bounds(backend: vwb_render::Backend, per_slice: bool) -> (f64, f64) {
    match (backend, per_slice) {
        (vwb_render::Backend::Compute, _) => (0.15, 0.75),
        (vwb_render::Backend::Raster, false) => (0.5, 1.0),
        (vwb_render::Backend::Raster, true) => (1.0, 1.5),
    }
}

/// Whether a plugin mode has the texture unit filter 8-bit codes: the
/// `precomputed_normal*` estimators' rgba8unorm normal texture (Rezk-Salama 2001, eq
/// 7.5). lavapipe filters unorm8 textures in 8-bit fixed point, as GPUs' texture units
/// do, where its twin interpolates in f64 (the same codes stored as rgba32float match
/// the twin as `precomputed_central` does: 0.0001 ΔE*uv), so such a mode is measured as
/// on a GPU on every adapter: [`twin_bound_of`].
pub fn filters_unorm8(values: &vwb_render::params::ParamValues) -> bool {
    use vwb_render::params::ParamValue;
    use vwb_render::shading::GradientEstimator;
    matches!(values.get("gradient"), Some(ParamValue::Enum(e))
        if GradientEstimator::from_name(e).is_some_and(GradientEstimator::is_normal_texture))
}

/// The twin bound and measure of a plugin mode: [`twin_bound`] with `delta_e_rms` on
/// lavapipe, the GPU's bound with `delta_e_rms_near` (an edge may move by a pixel) on a
/// GPU and for modes that filter 8-bit codes ([`filters_unorm8`]). Returns (bound, whether
/// to measure near).
pub fn twin_bound_of(backend: vwb_render::Backend, per_slice: bool, unorm8: bool) -> (f64, bool) {
    if unorm8 {
        (twin_bounds(backend, per_slice).1, true)
    } else {
        (twin_bound(backend, per_slice), on_gpu())
    }
}

/// Replaces the generated section `name` of the document at `path` (from
/// `<!-- name:begin` to `<!-- name:end -->`, markers included) with `section`.
pub fn replace_section(path: &Path, name: &str, section: &str) {
    let text = std::fs::read_to_string(path).unwrap();
    let (begin, end) = (format!("<!-- {name}:begin"), format!("<!-- {name}:end -->"));
    let doc = path.display();
    let a = text
        .find(&begin)
        .unwrap_or_else(|| panic!("{doc} has no {begin}"));
    let b = text
        .find(&end)
        .unwrap_or_else(|| panic!("{doc} has no {end}"));
    let out = format!("{}{section}{}", &text[..a], &text[b + end.len()..]);
    std::fs::write(path, out).unwrap();
}

/// Where a benchmark writes `name` (a path under docs/): docs/ on a CPU adapter
/// (lavapipe, the figures the documents cite), docs/gpu/ on a GPU, so that a run on a
/// GPU never overwrites them.
pub fn bench_doc(name: &str) -> PathBuf {
    let p = repo()
        .join(if on_gpu() { "docs/gpu" } else { "docs" })
        .join(name);
    std::fs::create_dir_all(p.parent().expect("a file under docs/")).unwrap();
    p
}

/// Bytes of one voxel of the renderer's volume texture on the test adapter (r32float
/// where it is filterable, else r16float).
pub fn texel_bytes() -> u64 {
    if gpu().float32_filterable() { 4 } else { 2 }
}

pub fn registry() -> Registry {
    vwb_plugins::builtin_registry()
}

/// A shipped preset or scene file (relative to the repository) and its volume.
pub fn preset_scene(path: &str) -> (vwb_render::preset::Document, Arc<Volume>) {
    let doc = vwb_render::preset::Document::load(&repo().join(path), &registry())
        .unwrap_or_else(|e| panic!("{e}"))
        .document;
    let volume =
        vwb_lab::headless::load_volume(&doc.volume).unwrap_or_else(|e| panic!("{path}: {e}"));
    (doc, volume)
}

pub fn instance(id: &str) -> PluginInstance {
    PluginInstance::new(registry().get(id).expect("registered"))
}

pub fn demo() -> Arc<Volume> {
    static DEMO: OnceLock<Arc<Volume>> = OnceLock::new();
    DEMO.get_or_init(|| Arc::new(vwb_render::volume::demo()))
        .clone()
}

/// A volume from a function of the voxel index, f32.
pub fn synthetic(dims: [u32; 3], f: impl Fn(u32, u32, u32) -> f32) -> Arc<Volume> {
    let mut v = Vec::with_capacity((dims[0] * dims[1] * dims[2]) as usize);
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                v.push(f(x, y, z));
            }
        }
    }
    Arc::new(Volume::new("synthetic", dims, 1, [1.0; 3], VoxelData::F32(v)).expect("valid volume"))
}

pub fn settings(w: u32, h: u32, backend: Backend) -> FrameSettings {
    FrameSettings {
        camera: Camera {
            distance: 1.6,
            yaw_deg: 235.0,
            pitch_deg: -10.0,
            roll_deg: 180.0,
            ..Default::default()
        },
        width: w,
        height: h,
        slice_spacing: 1.0,
        backend,
        early_termination: None,
    }
}

pub fn ortho_axis(w: u32, h: u32, backend: Backend) -> FrameSettings {
    let mut camera = Camera {
        projection: Projection::Orthographic { height: 1.2 },
        ..Default::default()
    };
    camera.axis_view(2, false);
    FrameSettings {
        camera,
        width: w,
        height: h,
        slice_spacing: 1.0,
        backend,
        early_termination: None,
    }
}

/// `classify.tf1d` with one colour for every value.
pub fn tf_constant(color: [f32; 4]) -> PluginInstance {
    use vwb_render::params::ParamValue;
    use vwb_render::tf::{TfCurve, TfPoint};
    let mut tf = instance("classify.tf1d");
    let p = |x| TfPoint { x, color };
    tf.params
        .set("tf", ParamValue::Tf(TfCurve::new(vec![p(0.0), p(1.0)])));
    tf
}

/// A mappable buffer's contents (after the copies into it have been submitted), read
/// as 4-byte little-endian words by `word` (e.g. `f32::from_le_bytes`); left unmapped.
pub fn read_back<T>(g: &GpuContext, buffer: &wgpu::Buffer, word: fn([u8; 4]) -> T) -> Vec<T> {
    let slice = buffer.slice(..);
    slice.map_async(wgpu::MapMode::Read, |r| r.expect("map"));
    g.wait();
    let words = slice
        .get_mapped_range()
        .expect("mapped")
        .chunks_exact(4)
        .map(|b| word([b[0], b[1], b[2], b[3]]))
        .collect();
    buffer.unmap();
    words
}

/// Runs the compute shader `source` (entry point `main`, its one binding
/// `@group(0) @binding(0)` a storage array of `count` u32 words, all set to
/// 0xFFFFFFFF first) over `groups` workgroups and returns the words it leaves.
pub fn run_compute_words(g: &GpuContext, source: &str, count: usize, groups: [u32; 3]) -> Vec<u32> {
    use wgpu::util::DeviceExt;
    let module = g.device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("test kernel"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = g
        .device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("test kernel"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
    let bytes = (count * 4) as u64;
    let out = g
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("test kernel out"),
            contents: &vec![0xffu8; count * 4],
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
    let read = g.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("test kernel read"),
        size: bytes,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let bind = g.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: out.as_entire_binding(),
        }],
    });
    let mut enc = g.device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(groups[0], groups[1], groups[2]);
    }
    enc.copy_buffer_to_buffer(&out, 0, &read, 0, bytes);
    g.queue.submit([enc.finish()]);
    read_back(g, &read, u32::from_le_bytes)
}

/// Renders and returns premultiplied pixels.
pub fn render(
    r: &mut Renderer,
    stack: &[PluginInstance],
    target: TargetFormat,
    s: &FrameSettings,
) -> Vec<[f32; 4]> {
    r.update_stack(stack, target).expect("stack composes");
    r.render(s).expect("renders");
    r.read_pixels().expect("pixels").2
}

/// Composites over black, in [0,1].
pub fn rgb(px: &[[f32; 4]]) -> Vec<[f64; 3]> {
    vwb_lab::headless::composite_over(px, [0.0, 0.0, 0.0, 1.0])
}

/// RMS and max difference over all channels.
pub fn diff(a: &[[f64; 3]], b: &[[f64; 3]]) -> (f64, f64) {
    assert_eq!(a.len(), b.len());
    let mut sum = 0.0;
    let mut max = 0.0f64;
    for (p, q) in a.iter().zip(b) {
        for c in 0..3 {
            let d = p[c] - q[c];
            sum += d * d;
            max = max.max(d.abs());
        }
    }
    ((sum / (a.len() * 3) as f64).sqrt(), max)
}

pub fn mean_luma(a: &[[f64; 3]]) -> f64 {
    a.iter().map(|p| (p[0] + p[1] + p[2]) / 3.0).sum::<f64>() / a.len() as f64
}

pub fn write_or_compare_text(path: &Path, actual: &str) {
    if bless() || !path.exists() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, actual).unwrap();
        if !bless() {
            panic!("{} did not exist; wrote it — rerun", path.display());
        }
        return;
    }
    let expected = std::fs::read_to_string(path).unwrap();
    if expected != actual {
        let line = expected
            .lines()
            .zip(actual.lines())
            .position(|(a, b)| a != b)
            .map_or(
                expected.lines().count().min(actual.lines().count()) + 1,
                |i| i + 1,
            );
        panic!(
            "{} differs from the composed output at line {line}; rerun with VWB_BLESS=1 if the change is intended",
            path.display()
        );
    }
}
