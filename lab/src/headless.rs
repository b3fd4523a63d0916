//! Headless helpers shared by the CLI, the window and the tests: load a document's
//! volume, set up a renderer for it, render, and turn the eye buffer into a PNG.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use vwb_render::metrics::RgbImageF;
use vwb_render::preset::{Document, VolumeSource};
use vwb_render::renderer::{FrameSettings, FrameStats};
use vwb_render::{GpuContext, Renderer, Volume};

/// Loads the volume a document names (the embedded demo, a file or a sample in the
/// data directory).
pub fn load_volume(src: &VolumeSource) -> Result<Arc<Volume>> {
    load_volume_within(src, env_budget())
}

/// [`load_volume`] for a renderer with the GPU memory `budget` (a window's own): an
/// OME-Zarr image reads only the stored level that fits it.
pub fn load_volume_within(src: &VolumeSource, budget: Option<u64>) -> Result<Arc<Volume>> {
    Ok(Arc::new(match src {
        VolumeSource::Demo => vwb_render::volume::demo(),
        VolumeSource::File(p) => load_volume_file_within(p, budget)?,
        VolumeSource::Sample(name) => {
            load_volume_file_within(&vwb_render::samples::resolve(name)?, budget)?
        }
        VolumeSource::Analytic(a) => a.volume().map_err(anyhow::Error::msg)?,
        VolumeSource::Phantom(p) => p.volume().map_err(anyhow::Error::msg)?,
        VolumeSource::Resampled(r) => load_volume_within(&r.source, budget)?.resampled(r.size)?,
    }))
}

/// What a file source looked like on disk: its modification time and length (`None`
/// for the embedded demo, samples, generated volumes, and a file that cannot be read).
/// For a header with a separate data file (NIfTI .hdr/.img, MetaImage .mhd/.raw) it is
/// the header's; for a resampled file, the file's ([`VolumeSource::file`]).
pub type Stamp = Option<(std::time::SystemTime, u64)>;

/// The [`Stamp`] of `source` now.
pub fn source_stamp(source: &VolumeSource) -> Stamp {
    let m = std::fs::metadata(source.file()?).ok()?;
    Some((m.modified().ok()?, m.len()))
}

/// A named volume loaded by [`inputs_for`], while anything holds it.
struct Held {
    source: VolumeSource,
    stamp: Stamp,
    volume: std::sync::Weak<Volume>,
}

static LOADED: std::sync::Mutex<Vec<Held>> = std::sync::Mutex::new(Vec::new());

/// The named volumes a document's `volumes:` lists ([`vwb_render::inputs`]), loaded.
///
/// Each source is loaded once while any renderer or reference still holds it: a
/// second document naming the same source (a reopened preset, an experiment's
/// variants, a reference beside a renderer) gets the same `Arc`, so the renderer sees
/// no change ([`Renderer::set_inputs`]) and nothing is uploaded or rerun again. A file
/// whose [`Stamp`] changed since it was loaded (edited on disk) is loaded again.
pub fn inputs_for(doc: &Document) -> Result<vwb_render::inputs::VolumeInputs> {
    let mut inputs = vwb_render::inputs::VolumeInputs::default();
    for (name, source) in &doc.volumes {
        let stamp = source_stamp(source);
        let held = LOADED.lock().ok().and_then(|mut loaded| {
            loaded.retain(|h| h.volume.strong_count() > 0);
            loaded
                .iter()
                .find(|h| h.source == *source && h.stamp == stamp)
                .and_then(|h| h.volume.upgrade())
        });
        let volume = match held {
            Some(v) => v,
            None => {
                let v = load_volume(source).with_context(|| format!("volumes.{name}"))?;
                if let Ok(mut loaded) = LOADED.lock() {
                    loaded.retain(|h| h.source != *source);
                    loaded.push(Held {
                        source: source.clone(),
                        stamp,
                        volume: Arc::downgrade(&v),
                    });
                }
                v
            }
        };
        inputs.insert(name, volume);
    }
    Ok(inputs)
}

/// The named volumes of `doc` that are held (loaded by [`inputs_for`]) but whose file
/// changed on disk since, each with its [`Stamp`] now: what [`inputs_for`] would load
/// again. The window checks this once a second.
pub fn changed_named_volumes(doc: &Document) -> Vec<(String, Stamp)> {
    let Ok(loaded) = LOADED.lock() else {
        return Vec::new();
    };
    doc.volumes
        .iter()
        .filter(|(_, source)| source.file().is_some())
        .filter_map(|(name, source)| {
            let held = loaded
                .iter()
                .find(|h| h.source == *source && h.volume.strong_count() > 0)?;
            let now = source_stamp(source);
            (held.stamp != now).then(|| (name.clone(), now))
        })
        .collect()
}

/// `VWB_GPU_MEMORY_LIMIT`, the budget of renderers made from the environment.
fn env_budget() -> Option<u64> {
    vwb_render::renderer::RendererOptions::from_env().gpu_memory_budget
}

/// A `--volume` argument: a sample name (`ct_head`, see `vwb data list`) unless a file
/// of that name exists, else a file.
pub fn volume_arg(arg: &Path) -> VolumeSource {
    match arg.to_str() {
        Some(n) if vwb_render::samples::manifest().get(n).is_ok() && !arg.exists() => {
            VolumeSource::Sample(n.to_string())
        }
        _ => VolumeSource::File(arg.to_path_buf()),
    }
}

/// Loads a volume file (any format [`vwb_render::volume::load`] reads) and registers
/// it (and its data files) as an input no output may overwrite. Under a GPU memory
/// budget (`VWB_GPU_MEMORY_LIMIT`) an OME-Zarr image reads only the stored level that
/// fits ([`vwb_render::volume::load_for_budget`]).
pub fn load_volume_file(path: &Path) -> Result<Volume> {
    load_volume_file_within(path, env_budget())
}

/// [`load_volume_file`] for a renderer with the GPU memory `budget`.
pub fn load_volume_file_within(path: &Path, budget: Option<u64>) -> Result<Volume> {
    crate::outputs::protect_volume(path);
    Ok(vwb_render::volume::load_for_budget(path, budget)?)
}

/// The document's render switches that live on the renderer rather than in each
/// frame's settings: empty-space skipping, the occupied cells and the hull's fit
/// (`render.empty_space_skipping`, `render.occupied_proxy`, `render.hull_cut`,
/// `render.slices_per_proxy`) and the classification tables' format (`render.table_format`). Every
/// renderer made for a document takes them (`vwb render`, galleries, Python, the
/// window).
pub fn apply_render_switches(r: &mut Renderer, doc: &Document) {
    r.set_empty_space_skipping(doc.render.empty_space_skipping);
    r.set_occupied_proxy(doc.render.occupied_proxy);
    r.set_hull_proxy(doc.render.hull_proxy());
    r.set_raster_group(doc.render.raster_group());
    r.set_table_format(doc.render.table_format);
}

/// The options of a renderer made for a document: the environment's
/// ([`vwb_render::renderer::RendererOptions::from_env`]) with the document's volume format.
pub fn renderer_options(doc: &Document) -> vwb_render::renderer::RendererOptions {
    vwb_render::renderer::RendererOptions {
        volume_format: doc.render.volume_format,
        ..vwb_render::renderer::RendererOptions::from_env()
    }
}

/// A renderer with a document's plugin stack applied.
pub fn renderer_for(gpu: &GpuContext, doc: &Document, volume: Arc<Volume>) -> Result<Renderer> {
    let mut r = Renderer::with_options(gpu, volume, renderer_options(doc))?;
    if let Some(level) = r.level() {
        eprintln!("note: {}", level.notice());
    }
    if let Some(notice) = r.storage_notice() {
        eprintln!("note: {notice}");
    }
    apply_render_switches(&mut r, doc);
    r.set_inputs(inputs_for(doc)?);
    r.update_stack(&doc.stack, doc.render.target)?;
    Ok(r)
}

/// Premultiplied RGBA composited over an opaque background: C + (1 − A)·bg, clamped
/// (the convention of `vwb_render::metrics`).
pub fn composite_over(pixels: &[[f32; 4]], background: [f32; 4]) -> Vec<[f64; 3]> {
    let bg = std::array::from_fn(|i| background[i] as f64);
    RgbImageF::from_rgba_f32_premultiplied_over(pixels, pixels.len() as u32, 1, bg).pixels
}

/// 8-bit RGB image of composited pixels.
pub fn to_image(w: u32, h: u32, rgb: &[[f64; 3]]) -> image::RgbImage {
    RgbImageF::new(w, h, rgb.to_vec()).to_rgb8()
}

/// Writes an image atomically (the old file survives a failure) in the format of its
/// extension (`.png`, `.jpg`); other extensions are refused.
pub fn save_png(img: &image::RgbImage, path: &Path) -> Result<()> {
    let format = crate::outputs::image_format(path)?;
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), format)
        .with_context(|| format!("{}: cannot encode the image", path.display()))?;
    vwb_render::preset::write_atomic(path, &bytes)
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// Renders one frame and returns the composited image and the frame's stats.
pub fn render_image(
    r: &mut Renderer,
    settings: &FrameSettings,
    background: [f32; 4],
) -> Result<(image::RgbImage, Vec<[f32; 4]>, FrameStats)> {
    let stats = r.render(settings)?;
    let Some((w, h, px)) = r.read_pixels() else {
        bail!("nothing was rendered");
    };
    let img = to_image(w, h, &composite_over(&px, background));
    Ok((img, px, stats))
}

/// What a user should know before looking at a document's image: an eye buffer too
/// coarse for the slice spacing, a volume with nothing to show.
pub fn frame_warnings(doc: &Document, volume: &Volume) -> Vec<String> {
    let mut w = vwb_render::validate::volume_warnings(volume);
    w.extend(vwb_render::validate::eye_buffer_warning(
        doc.render.target,
        doc.render.slice_spacing,
    ));
    w
}

/// Checks a document's camera and slice count against its volume, with an error
/// naming the preset and the field (`p.ron: render.slice_spacing: …`).
pub fn check_frame(preset: Option<&Path>, doc: &Document, volume: &Volume) -> Result<()> {
    let name = preset.map_or_else(|| "the scene".to_string(), |p| p.display().to_string());
    vwb_render::validate::check_slices(
        &doc.camera,
        doc.render.size,
        doc.render.slice_spacing,
        volume,
    )
    .with_context(|| name)?;
    Ok(())
}

/// Checks a document's frame against its volume before any GPU work (camera, slice
/// count) with errors naming the preset and the field, and prints the warnings of
/// [`frame_warnings`].
pub fn preflight(preset: Option<&Path>, doc: &Document, volume: &Volume) -> Result<()> {
    check_frame(preset, doc, volume)?;
    let name = preset.map_or_else(|| "the scene".to_string(), |p| p.display().to_string());
    for w in frame_warnings(doc, volume) {
        eprintln!("warning: {name}: {w}");
    }
    Ok(())
}
