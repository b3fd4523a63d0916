//! Command-line interface (clap). Failures return errors that name the file and the
//! cause; `main` prints them and exits non-zero.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use vwb_render::preset::{Document, VolumeSource};
use vwb_render::renderer::Backend;
use vwb_render::{GpuContext, TargetFormat};

use crate::headless;

#[derive(Debug, Parser)]
#[command(
    name = "vwb",
    version,
    about = "Exploration workbench for GPU slice-based direct volume rendering"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Preset to open in the window.
    #[arg(long, global = true)]
    pub preset: Option<PathBuf>,
    /// Volume to open in the window (NRRD).
    #[arg(long)]
    pub volume: Option<PathBuf>,
    /// Open the window, render, save a screenshot to this PNG and exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a preset headless to a PNG.
    Render(RenderArgs),
    /// Print the adapter, its limits and the registered plugin ids.
    Info,
}

#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// Volume file overriding the preset's (NRRD).
    #[arg(long)]
    pub volume: Option<PathBuf>,
    /// Image size WxH (default: the preset's).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<[u32; 2]>,
    /// Backend overriding the preset's.
    #[arg(long)]
    pub backend: Option<Backend>,
    /// Eye-buffer precision overriding the preset's: rgba16float or rgba32float.
    #[arg(long, value_parser = parse_target)]
    pub target: Option<TargetFormat>,
    /// Slice spacing in voxels overriding the preset's.
    #[arg(long)]
    pub spacing: Option<f32>,
    /// Print per-frame timings (median of --frames after warm-up).
    #[arg(long)]
    pub timings: bool,
    /// Frames to time with --timings.
    #[arg(long, default_value_t = 10)]
    pub frames: u32,
    /// Output PNG.
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn parse_size(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size '{s}' is not WxH"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|&x| (1..=16384).contains(&x))
            .ok_or_else(|| format!("size '{s}': '{v}' is not an integer in 1..=16384"))
    };
    Ok([p(w)?, p(h)?])
}

pub fn parse_target(s: &str) -> Result<TargetFormat, String> {
    match s {
        "rgba16float" => Ok(TargetFormat::Rgba16Float),
        "rgba32float" => Ok(TargetFormat::Rgba32Float),
        _ => Err(format!("unknown target '{s}' (rgba16float or rgba32float)")),
    }
}

/// Loads a preset (or the built-in default document) and prints its warnings.
pub fn load_document(preset: Option<&std::path::Path>) -> Result<Document> {
    let registry = vwb_plugins::builtin_registry();
    let Some(path) = preset else {
        return Ok(crate::window::default_document(&registry));
    };
    let loaded = Document::load(path, &registry)?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    Ok(loaded.document)
}

pub fn run_render(preset: Option<&std::path::Path>, a: &RenderArgs) -> Result<()> {
    let Some(preset) = preset else {
        bail!("vwb render needs --preset P.ron");
    };
    let mut doc = load_document(Some(preset))?;
    if let Some(v) = &a.volume {
        doc.volume = VolumeSource::File(v.clone());
    }
    if let Some(s) = a.size {
        doc.render.size = s;
    }
    if let Some(b) = a.backend {
        doc.render.backend = b;
    }
    if let Some(t) = a.target {
        doc.render.target = t;
    }
    if let Some(s) = a.spacing {
        doc.render.slice_spacing = s;
    }
    let volume = headless::load_volume(&doc.volume)?;
    let gpu = GpuContext::new_headless()?;
    eprintln!("adapter: {}", gpu.describe());
    let mut r = headless::renderer_for(&gpu, &doc, volume.clone())
        .with_context(|| format!("{}", preset.display()))?;
    let settings = doc.frame_settings();
    let (img, _, first) = headless::render_image(&mut r, &settings, doc.render.background)?;
    headless::save_png(&img, &a.output)?;
    eprintln!(
        "wrote {} ({}x{}, {} slices, {} backend, volume {} {:?})",
        a.output.display(),
        img.width(),
        img.height(),
        first.slices,
        settings.backend.name(),
        volume.name,
        volume.dims
    );
    if a.timings {
        let frames = a.frames.max(1);
        // warm-up
        for _ in 0..2 {
            r.render(&settings)?;
        }
        let mut gpu_ms = Vec::new();
        let mut wall_ms = Vec::new();
        let mut passes: std::collections::BTreeMap<String, Vec<f64>> = Default::default();
        for _ in 0..frames {
            let s = r.render(&settings)?;
            wall_ms.push(s.wall_ms);
            if let Some(g) = s.gpu_ms {
                gpu_ms.push(g);
            }
            for (name, ms) in s.gpu_passes {
                passes.entry(name).or_default().push(ms);
            }
        }
        let (wm, wmin, wmax) = headless::summarize(&wall_ms);
        println!(
            "timings: {} frames after 2 warm-up, {}x{}, {} slices, backend {}, adapter {}",
            frames,
            settings.width,
            settings.height,
            first.slices,
            settings.backend.name(),
            gpu.info.name
        );
        println!("wall_ms median {wm:.3} min {wmin:.3} max {wmax:.3}");
        if gpu_ms.is_empty() {
            println!("gpu_ms unavailable (adapter lacks timestamp queries; wall time above)");
        } else {
            let (gm, gmin, gmax) = headless::summarize(&gpu_ms);
            println!("gpu_ms median {gm:.3} min {gmin:.3} max {gmax:.3}");
            for (name, v) in passes {
                let (m, lo, hi) = headless::summarize(&v);
                println!("pass {name} median {m:.3} min {lo:.3} max {hi:.3}");
            }
        }
    }
    Ok(())
}

pub fn run_info() -> Result<()> {
    let gpu = GpuContext::new_headless()?;
    println!("adapter: {}", gpu.describe());
    println!("backend: {:?}", gpu.info.backend);
    let f = gpu.features;
    for (name, flag) in [
        ("FLOAT32_FILTERABLE", wgpu::Features::FLOAT32_FILTERABLE),
        ("FLOAT32_BLENDABLE", wgpu::Features::FLOAT32_BLENDABLE),
        ("TIMESTAMP_QUERY", wgpu::Features::TIMESTAMP_QUERY),
        (
            "TIMESTAMP_QUERY_INSIDE_ENCODERS",
            wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS,
        ),
    ] {
        println!(
            "feature {name}: {}",
            if f.contains(flag) { "yes" } else { "no" }
        );
    }
    let l = &gpu.limits;
    println!(
        "limit max_texture_dimension_2d: {}",
        l.max_texture_dimension_2d
    );
    println!(
        "limit max_texture_dimension_3d: {}",
        l.max_texture_dimension_3d
    );
    println!("limit max_bind_groups: {}", l.max_bind_groups);
    println!(
        "limit max_bindings_per_bind_group: {}",
        l.max_bindings_per_bind_group
    );
    println!(
        "limit max_sampled_textures_per_shader_stage: {}",
        l.max_sampled_textures_per_shader_stage
    );
    println!(
        "limit max_storage_textures_per_shader_stage: {}",
        l.max_storage_textures_per_shader_stage
    );
    println!(
        "limit max_uniform_buffers_per_shader_stage: {}",
        l.max_uniform_buffers_per_shader_stage
    );
    println!("limit max_buffer_size: {}", l.max_buffer_size);
    let registry = vwb_plugins::builtin_registry();
    for p in registry.plugins() {
        println!("plugin {} ({})", p.id(), p.display_name());
    }
    Ok(())
}
