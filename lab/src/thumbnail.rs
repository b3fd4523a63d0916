//! Preset thumbnails: a preset rendered small, stored beside a user's preset as
//! `NAME.thumb.png` (the window's preset browser shows them; the window and
//! `vwb gallery --apply` write one whenever they save a preset).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use vwb_render::GpuContext;
use vwb_render::preset::Document;

use crate::headless;

/// Thumbnail side in pixels.
pub const THUMB: u32 = 96;

/// Where a preset's thumbnail is cached: in `cache` (shipped presets: the repository
/// stays untouched), else beside the preset (`NAME.thumb.png`).
pub fn thumbnail_path(preset: &Path, cache: Option<&Path>) -> PathBuf {
    let stem = preset
        .file_stem()
        .map_or_else(|| "preset".into(), |s| s.to_string_lossy().to_string());
    match cache {
        Some(dir) => dir.join(format!("{stem}.png")),
        None => preset.with_file_name(format!("{stem}.thumb.png")),
    }
}

/// Renders a preset at [`THUMB`]² (its own camera, stack and volume).
pub fn render_thumbnail(gpu: &GpuContext, preset: &Path) -> Result<image::RgbImage> {
    let registry = vwb_plugins::registry();
    let mut doc = Document::load(preset, &registry)?.document;
    doc.render.size = [THUMB, THUMB];
    let volume = headless::load_volume(&doc.volume)?;
    let mut r = headless::renderer_for(gpu, &doc, volume)
        .with_context(|| format!("{}", preset.display()))?;
    Ok(headless::render_image(&mut r, &doc.frame_settings(), doc.render.background)?.0)
}

/// Writes `image` scaled to [`THUMB`]² as `path` (atomically, creating its folder).
pub fn save_thumbnail(image: &image::RgbImage, path: &Path) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
    }
    let small = image::imageops::thumbnail(image, THUMB, THUMB);
    headless::save_png(&small, path)
}
