//! Headless helpers shared by the CLI, the window and the tests: load a document's
//! volume, set up a renderer for it, render, and turn the eye buffer into a PNG.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use vwb_render::preset::{Document, VolumeSource};
use vwb_render::renderer::{FrameSettings, FrameStats};
use vwb_render::{GpuContext, Renderer, Volume};

/// Loads the volume a document names (the embedded demo or a file).
pub fn load_volume(src: &VolumeSource) -> Result<Arc<Volume>> {
    Ok(Arc::new(match src {
        VolumeSource::Demo => vwb_render::volume::demo(),
        VolumeSource::File(p) => load_volume_file(p)?,
    }))
}

/// Loads a volume file (NRRD, attached or detached header).
pub fn load_volume_file(path: &Path) -> Result<Volume> {
    Ok(vwb_render::volume::load(path)?)
}

/// A renderer with a document's plugin stack applied.
pub fn renderer_for(gpu: &GpuContext, doc: &Document, volume: Arc<Volume>) -> Result<Renderer> {
    let mut r = Renderer::new(gpu, volume)?;
    r.update_stack(&doc.stack, doc.render.target)?;
    Ok(r)
}

/// Premultiplied RGBA composited over an opaque background: C + (1 − A)·bg, clamped.
pub fn composite_over(pixels: &[[f32; 4]], background: [f32; 4]) -> Vec<[f64; 3]> {
    pixels
        .iter()
        .map(|p| {
            let a = p[3].clamp(0.0, 1.0) as f64;
            std::array::from_fn(|c| {
                let v = p[c] as f64 + (1.0 - a) * background[c] as f64;
                if v.is_finite() {
                    v.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            })
        })
        .collect()
}

/// 8-bit RGB image of composited pixels.
pub fn to_image(w: u32, h: u32, rgb: &[[f64; 3]]) -> image::RgbImage {
    let mut img = image::RgbImage::new(w, h);
    for (px, c) in img.pixels_mut().zip(rgb) {
        *px = image::Rgb(c.map(|v| (v * 255.0).round() as u8));
    }
    img
}

/// Writes a PNG atomically (the old file survives a failure).
pub fn save_png(img: &image::RgbImage, path: &Path) -> Result<()> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .with_context(|| format!("{}: cannot encode PNG", path.display()))?;
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

/// Median, min and max of a list of milliseconds.
pub fn summarize(ms: &[f64]) -> (f64, f64, f64) {
    let mut v: Vec<f64> = ms.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    v.sort_by(f64::total_cmp);
    let mid = v.len() / 2;
    let median = if v.len() % 2 == 1 {
        v[mid]
    } else {
        0.5 * (v[mid - 1] + v[mid])
    };
    (median, v[0], v[v.len() - 1])
}
