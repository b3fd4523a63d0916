//! Transfer-function search from the command line and scripts: design galleries on a
//! preset ([`run_gallery`]), their refinement around a pick, and applying a picked
//! genome to the preset ([`apply_pick`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use serde::{Deserialize, Serialize};
use serde_json::json;
use vwb_render::GpuContext;
use vwb_render::preset::Document;
use vwb_render::search::gallery::{self, Gallery, GalleryOptions};
use vwb_render::search::genome::{Genome, Space};

use crate::{headless, measure};

/// `genomes.ron`: the chosen genomes with their grid cells, and how they were drawn.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GalleryFile {
    pub preset: PathBuf,
    pub seed: u64,
    pub pool: usize,
    /// (cell [column, row], genome), in selection order.
    pub chosen: Vec<([u32; 2], Genome)>,
}

/// Reads `genomes.ron` and returns pick `i` (its selection index).
pub fn read_pick(file: &Path, i: usize) -> Result<Genome> {
    let text = std::fs::read_to_string(file)
        .with_context(|| format!("{}: cannot read", file.display()))?;
    let g: GalleryFile = ron::from_str(&text).map_err(|e| anyhow!("{}: {e}", file.display()))?;
    g.chosen.get(i).map(|(_, g)| g.clone()).ok_or_else(|| {
        anyhow!(
            "{}: no pick {i} (it holds {})",
            file.display(),
            g.chosen.len()
        )
    })
}

/// Renders a gallery of the preset's scene and writes `gallery.png` (the thumbnails on
/// their MDS grid, first viewpoint), `genomes.ron` and `gallery.json` into `out`.
pub fn run_gallery(preset: &Path, o: &GalleryOptions, out: &Path) -> Result<Gallery> {
    let doc = crate::document::load_document(Some(preset))?;
    let volume = headless::load_volume(&doc.volume)?;
    crate::outputs::check_output(&out.join("gallery.png"))?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let gpu = GpuContext::new_headless()?;
    eprintln!("adapter: {}", gpu.describe());
    let mut r = headless::renderer_for(&gpu, &doc, volume)?;
    let g = gallery::gallery(
        &mut r,
        &doc.stack,
        &doc.camera,
        measure::background(&doc),
        o,
    )
    .map_err(|e| anyhow!("{}: {e}", preset.display()))?;
    headless::save_png(&sheet(&g, o.tile), &out.join("gallery.png"))?;
    let file = GalleryFile {
        preset: preset.to_path_buf(),
        seed: o.seed,
        pool: o.pool,
        chosen: g
            .chosen
            .iter()
            .zip(&g.cells)
            .map(|(&i, c)| (*c, g.pool[i].clone()))
            .collect(),
    };
    let text = ron::ser::to_string_pretty(&file, ron::ser::PrettyConfig::default())?;
    measure::save_text(&out.join("genomes.ron"), &text)?;
    measure::save_json(
        &out.join("gallery.json"),
        &json!({
            "preset": preset,
            "adapter": gpu.describe(),
            "machine": measure::machine(),
            "pool": o.pool, "k": g.chosen.len(), "tile": o.tile, "views": o.views, "seed": o.seed,
            "refined_around": o.around.as_ref().map(|(_, r)| r),
            "thumbnails": g.rendered,
            "render_ms": g.render_ms,
            "thumbnails_per_s": g.rendered as f64 / (g.render_ms / 1e3),
            "dispersion_min_delta_e": g.dispersion,
            "random_dispersion_min_delta_e": g.random_dispersion,
        }),
    )?;
    Ok(g)
}

/// The gallery's sheet: the chosen thumbnails (first viewpoint, `tile` pixels) on their
/// MDS grid cells, one pixel apart.
pub fn sheet(g: &Gallery, tile: u32) -> image::RgbImage {
    let t = tile;
    let rows = g.cells.iter().map(|c| c[1]).max().map_or(1, |r| r + 1);
    let mut img = image::RgbImage::new(g.cols * (t + 2), rows * (t + 2));
    for (views, cell) in g.views.iter().zip(&g.cells) {
        let rgb = views[0].to_rgb8();
        image::imageops::replace(
            &mut img,
            &rgb,
            (cell[0] * (t + 2) + 1) as i64,
            (cell[1] * (t + 2) + 1) as i64,
        );
    }
    img
}

/// One line per gallery for the terminal.
pub fn summary(g: &Gallery) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "{} thumbnails in {:.0} ms ({:.1}/s); {} chosen: min pairwise ΔE*uv {:.2} against {:.2} for {} drawn at random ({})",
        g.rendered,
        g.render_ms,
        g.rendered as f64 / (g.render_ms / 1e3),
        g.chosen.len(),
        g.dispersion,
        g.random_dispersion,
        g.chosen.len(),
        // two random draws that look alike (e.g. both empty) leave no ratio to give
        if g.random_dispersion > 1e-6 {
            format!("{:.2}×", g.dispersion / g.random_dispersion)
        } else {
            "no ratio: two of the random draws look alike".to_string()
        }
    );
    s
}

/// Writes the preset with its first `classify.tf1d` (`classify.tf2d` for a 2D genome)
/// showing the genome (atomically), and its thumbnail beside it (`NAME.thumb.png`,
/// [`crate::thumbnail`]).
pub fn apply_pick(preset: &Path, g: &Genome, out: &Path) -> Result<Document> {
    crate::outputs::check_extension(out, "ron", "a preset")?;
    if g.is_empty() {
        bail!("the pick has no primitives");
    }
    let mut doc = crate::document::load_document(Some(preset))?;
    g.apply(&mut doc.stack)
        .map_err(|e| anyhow!("{}: {e}", preset.display()))?;
    if doc.description.is_empty() {
        doc.description = "a TF picked from a design gallery".into();
    } else {
        doc.description = format!("{} (TF picked from a design gallery)", doc.description);
    }
    crate::outputs::check_output(out)?;
    doc.save(out)
        .with_context(|| format!("{}: cannot save", out.display()))?;
    // its thumbnail beside it, as the window writes one, for the preset browser
    let thumb = crate::thumbnail::thumbnail_path(out, None);
    let gpu = GpuContext::new_headless()?;
    crate::thumbnail::render_thumbnail(&gpu, out)
        .and_then(|img| crate::thumbnail::save_thumbnail(&img, &thumb))
        .with_context(|| format!("saved {}, but not its thumbnail", out.display()))?;
    Ok(doc)
}

/// What `vwb evolve` searches toward.
#[derive(Debug, Clone)]
pub enum EvolveTarget {
    /// The images a preset's stack gives from the run's viewpoints (same volume).
    Preset(PathBuf),
    /// An image: the run's views side by side (square tiles, left to right as
    /// `best.png` and `target.png` hold them), for example a render the user made.
    Image(PathBuf),
    /// An image objective to maximise.
    Objective(vwb_render::search::genetic::Objective),
    /// The data's visible-boundary coverage, to maximise
    /// (`vwb_render::search::coverage`).
    Coverage,
}

/// The name of the visible-boundary coverage objective (`--objective`).
pub const BOUNDARY_COVERAGE: &str = "boundary_coverage";

/// Genetic search on a preset's scene toward a target (a preset's images or an
/// objective): writes `best.ron` (the best genome), `history.csv` (per generation best
/// and mean score, radius), `best.png` (the best genome's views side by side) and, for
/// a target preset, `target.png` (its views, as `--target` reads them). A target image
/// sets the tile size (its height) and must hold as many views as the run takes.
pub fn run_evolve(
    preset: &Path,
    target: &EvolveTarget,
    o: &vwb_render::search::genetic::GaOptions,
    out: &Path,
) -> Result<Vec<vwb_render::search::genetic::Generation>> {
    use vwb_render::search::genetic;
    let doc = crate::document::load_document(Some(preset))?;
    let volume = headless::load_volume(&doc.volume)?;
    crate::outputs::check_output(&out.join("best.ron"))?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let gpu = GpuContext::new_headless()?;
    eprintln!("adapter: {}", gpu.describe());
    // the space of the stack's TF plugin: classify.tf1d or classify.tf2d
    let o = &genetic::GaOptions {
        space: Space::of_stack(&doc.stack).map_err(|e| anyhow!("{}: {e}", preset.display()))?,
        ..o.clone()
    };
    let mut r = headless::renderer_for(&gpu, &doc, volume.clone())?;
    let bg = measure::background(&doc);
    let cams = gallery::viewpoints(&doc.camera, o.views);
    let fitness = match target {
        EvolveTarget::Objective(obj) => genetic::Fitness::Objective(*obj),
        EvolveTarget::Coverage => {
            use vwb_render::search::coverage::Coverage;
            let cover = Coverage::for_stack(&volume, &cams, o.tile, &doc.stack)
                .map_err(|e| anyhow!("{}: {e}", preset.display()))?;
            genetic::Fitness::Coverage(std::sync::Arc::new(cover))
        }
        EvolveTarget::Image(file) => {
            let views = read_target(file, o)?;
            genetic::Fitness::Target(gallery::descriptor(&views))
        }
        EvolveTarget::Preset(target_preset) => {
            let target_doc = crate::document::load_document(Some(target_preset))?;
            // the target: the target preset's own stack from the run's viewpoints
            let views = views_of(&gpu, &target_doc, volume, &cams, o, bg)
                .with_context(|| target_preset.display().to_string())?;
            headless::save_png(
                &genetic::side_by_side(&views).to_rgb8(),
                &out.join("target.png"),
            )?;
            genetic::Fitness::Target(gallery::descriptor(&views))
        }
    };
    let history = genetic::evolve(
        &mut r,
        &doc.stack,
        &doc.camera,
        bg,
        &fitness,
        o,
        &mut |g, step| {
            eprintln!(
                "generation {g:>3}: best score {:.3}, mean {:.3}, radius {:.3}",
                step.best_score, step.mean_score, step.radius
            )
        },
    )
    .map_err(|e| anyhow!("{}: {e}", preset.display()))?;
    let best = history.last().expect("at least one generation");
    let text = ron::ser::to_string_pretty(&best.best, ron::ser::PrettyConfig::default())?;
    measure::save_text(&out.join("best.ron"), &text)?;
    let mut csv = String::from("generation,best_score,mean_score,radius\n");
    for (i, g) in history.iter().enumerate() {
        let _ = writeln!(csv, "{i},{},{},{}", g.best_score, g.mean_score, g.radius);
    }
    measure::save_text(&out.join("history.csv"), &csv)?;
    let thumb = gallery::thumbnails(
        &mut r,
        &doc.stack,
        std::slice::from_ref(&best.best),
        &cams,
        o.tile,
        o.slice_spacing,
        bg,
        cams.len(),
    )
    .map_err(|e| anyhow!("{e}"))?;
    headless::save_png(
        &genetic::side_by_side(&thumb[0]).to_rgb8(),
        &out.join("best.png"),
    )?;
    Ok(history)
}

/// The views a document's own stack gives from `cams` at the search's tile size and
/// slice spacing, over `background`: a search's target (`vwb evolve
/// --target-preset`, an experiment's `search: (target: ..)`).
pub fn views_of(
    gpu: &GpuContext,
    doc: &Document,
    volume: std::sync::Arc<vwb_render::Volume>,
    cams: &[vwb_render::camera::Camera],
    o: &vwb_render::search::genetic::GaOptions,
    background: [f64; 3],
) -> Result<Vec<vwb_render::metrics::RgbImageF>> {
    let s = vwb_render::FrameSettings {
        camera: doc.camera,
        width: o.tile,
        height: o.tile,
        slice_spacing: o.slice_spacing,
        backend: vwb_render::renderer::Backend::Compute,
        early_termination: None,
    };
    let tiles: Vec<vwb_render::renderer::AtlasTile> = cams
        .iter()
        .map(|c| vwb_render::renderer::AtlasTile {
            camera: *c,
            stack: &doc.stack,
        })
        .collect();
    let mut rt = headless::renderer_for(gpu, doc, volume)?;
    let atlas = rt
        .render_atlas(
            &tiles,
            &s,
            vwb_render::TargetFormat::Rgba32Float,
            cams.len() as u32,
        )
        .map_err(|e| anyhow!("{e}"))?;
    Ok((0..cams.len())
        .map(|i| {
            vwb_render::metrics::RgbImageF::from_rgba_f32_premultiplied_over(
                &atlas.tile_pixels(i),
                o.tile,
                o.tile,
                background,
            )
        })
        .collect())
}

/// A target image's views: `o.views` square tiles of side `o.tile` side by side.
pub fn read_target(
    file: &Path,
    o: &vwb_render::search::genetic::GaOptions,
) -> Result<Vec<vwb_render::metrics::RgbImageF>> {
    let strip = vwb_render::metrics::RgbImageF::load_png(file).map_err(|e| anyhow!("{e}"))?;
    let views = vwb_render::search::genetic::split_side_by_side(&strip)
        .map_err(|e| anyhow!("{}: {e}", file.display()))?;
    if views.len() != o.views || strip.height != o.tile {
        bail!(
            "{}: holds {} view(s) of {}², the search takes {} of {}² (fitness is taken over \
             every viewpoint: the views of `vwb evolve`'s target.png or best.png)",
            file.display(),
            views.len(),
            strip.height,
            o.views,
            o.tile
        );
    }
    Ok(views)
}

/// `vwb adapt-tf`: moves a transfer function designed for the reference volume onto
/// another volume through the monotone value warp between them; returns the warp.
pub fn run_adapt(
    reference: &Path,
    tf_file: &Path,
    volume: &Path,
    out: &Path,
) -> Result<vwb_render::search::adapt::Warp> {
    use vwb_render::search::adapt;
    crate::outputs::check_extension(out, "ron", "a transfer function (RON)")?;
    let text = std::fs::read_to_string(tf_file)
        .with_context(|| format!("{}: cannot read", tf_file.display()))?;
    let tf: vwb_render::tf::TfCurve =
        ron::from_str(&text).map_err(|e| anyhow!("{}: {e}", tf_file.display()))?;
    tf.validate()
        .map_err(|e| anyhow!("{}: {e}", tf_file.display()))?;
    let a = headless::load_volume(&headless::volume_arg(reference))?;
    let b = headless::load_volume(&headless::volume_arg(volume))?;
    let w = adapt::warp(&a, &b);
    let adapted = adapt::adapt_curve(&tf, &w);
    adapted
        .validate()
        .map_err(|e| anyhow!("the adapted transfer function is invalid: {e}"))?;
    crate::outputs::check_output(out)?;
    let text = ron::ser::to_string_pretty(&adapted, ron::ser::PrettyConfig::default())?;
    measure::save_text(out, &text)?;
    Ok(w)
}

/// The pixels (straight RGBA) of `stack` with its first `classify.tf1d` showing `curve`
/// cut to the values `keep` accepts (α = 0 at every other point), rendered on `r` at
/// `s` (the TF suggestion's fog, [`fog_share`]).
pub fn cut_image(
    r: &mut vwb_render::Renderer,
    stack: &[vwb_render::PluginInstance],
    curve: &vwb_render::tf::TfCurve,
    keep: &dyn Fn(f64) -> bool,
    s: &vwb_render::FrameSettings,
) -> Result<Vec<[f32; 4]>> {
    let mut c = curve.clone();
    for p in &mut c.points {
        if !keep(p.x as f64) {
            p.color[3] = 0.0;
        }
    }
    let mut stack = stack.to_vec();
    let tf = stack
        .iter_mut()
        .find(|i| i.enabled && i.plugin.id() == "classify.tf1d")
        .ok_or_else(|| anyhow!("the stack has no classify.tf1d to show the suggestion"))?;
    tf.params.set("tf", vwb_render::params::ParamValue::Tf(c));
    r.update_stack(&stack, vwb_render::TargetFormat::Rgba32Float)?;
    r.render(s)?;
    let (_, _, px) = r
        .read_pixels()
        .ok_or_else(|| anyhow!("nothing was rendered"))?;
    Ok(px)
}

/// The fog of a suggested transfer function `curve`: the pixels whose only
/// contribution comes from values below `first` (the middle of the first boundary
/// above the background), those the TF cut to values below `first` covers (α ≥ 0.05)
/// and the TF cut to values from `first` up leaves clear. Their share of the image, and
/// the share of those more than 3 pixels from any pixel the upper values cover (away
/// from the silhouette, whose rim grazes the low side of the boundary).
pub fn fog_share(
    r: &mut vwb_render::Renderer,
    stack: &[vwb_render::PluginInstance],
    curve: &vwb_render::tf::TfCurve,
    first: f64,
    s: &vwb_render::FrameSettings,
) -> Result<(f64, f64)> {
    let below = cut_image(r, stack, curve, &|x| x < first, s)?;
    let above = cut_image(r, stack, curve, &|x| x >= first, s)?;
    let (w, h) = (s.width as i64, s.height as i64);
    let shown = |x: i64, y: i64| {
        x >= 0 && y >= 0 && x < w && y < h && above[(y * w + x) as usize][3] >= 0.05
    };
    let near = |i: usize| {
        let (x, y) = (i as i64 % w, i as i64 / w);
        (-3..=3).any(|dy| (-3..=3).any(|dx| shown(x + dx, y + dy)))
    };
    let fog: Vec<usize> = (0..below.len())
        .filter(|&i| below[i][3] >= 0.05 && above[i][3] < 0.05)
        .collect();
    let away = fog.iter().filter(|&&i| !near(i)).count();
    let n = below.len().max(1) as f64;
    Ok((fog.len() as f64 / n, away as f64 / n))
}

/// The share of pixels `curve` covers (α ≥ 0.05) in `stack`'s image on `r` at `s`.
pub fn covered(
    r: &mut vwb_render::Renderer,
    stack: &[vwb_render::PluginInstance],
    curve: &vwb_render::tf::TfCurve,
    s: &vwb_render::FrameSettings,
) -> Result<f64> {
    let px = cut_image(r, stack, curve, &|_| true, s)?;
    Ok(px.iter().filter(|p| p[3] >= 0.05).count() as f64 / px.len().max(1) as f64)
}
