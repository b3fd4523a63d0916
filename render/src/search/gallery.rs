//! Design galleries (Marks et al. 1997): a seeded pool of genomes, each described by its
//! thumbnails from several viewpoints in CIE L*u*v*, rendered in batched atlases (one
//! submission per batch); the K most dispersed chosen by greedy farthest-point
//! selection on the RMS ΔE*uv between descriptors; laid out on a grid by classical
//! multidimensional scaling, so that similar thumbnails sit close. A refinement draws
//! the pool around one genome with a smaller mutation radius.
//!
//! Against the thesis's criticisms of stochastic TF search (§6.3): the pool is seeded,
//! so a gallery is reproducible; every descriptor covers several viewpoints and the
//! rendered images (occlusion included), not the TF curve.

use std::time::Instant;

use crate::camera::Camera;
use crate::composer::TargetFormat;
use crate::metrics::{RgbImageF, srgb_to_luv};
use crate::plugin::PluginInstance;
use crate::renderer::{AtlasTile, Backend, FrameSettings, RenderError, Renderer};
use crate::rng::Rng;
use crate::search::genome::{Genome, Space};

/// What a gallery draws and keeps.
#[derive(Debug, Clone)]
pub struct GalleryOptions {
    /// Genomes drawn.
    pub pool: usize,
    /// Genomes kept.
    pub k: usize,
    /// Thumbnail side in pixels.
    pub tile: u32,
    /// Viewpoints per descriptor (yaw steps of 360°/views around the scene's camera).
    pub views: usize,
    pub slice_spacing: f32,
    pub seed: u64,
    /// Primitives per random genome, at most.
    pub max_primitives: usize,
    /// Refine around this genome with this mutation radius instead of drawing at random.
    pub around: Option<(Genome, f64)>,
    /// Tiles per atlas (one submission each).
    pub batch: usize,
}

impl Default for GalleryOptions {
    fn default() -> Self {
        GalleryOptions {
            pool: 256,
            k: 36,
            tile: 64,
            views: 3,
            slice_spacing: 1.0,
            seed: 1,
            max_primitives: 3,
            around: None,
            batch: 96,
        }
    }
}

/// A finished gallery.
#[derive(Debug, Clone)]
pub struct Gallery {
    pub pool: Vec<Genome>,
    /// Indices into `pool`, in selection order.
    pub chosen: Vec<usize>,
    /// The grid cell (column, row) of each chosen genome.
    pub cells: Vec<[u32; 2]>,
    pub cols: u32,
    /// The smallest pairwise descriptor distance (RMS ΔE*uv) among the chosen ...
    pub dispersion: f64,
    /// ... and among the first K of the pool (K drawn at random), for comparison.
    pub random_dispersion: f64,
    /// The chosen genomes' views (every viewpoint, the first first), composited.
    pub views: Vec<Vec<RgbImageF>>,
    /// Thumbnails rendered and the time it took (GPU and read-back), ms.
    pub rendered: usize,
    pub render_ms: f64,
}

/// `n` viewpoints: the camera turned by 360°/n steps of yaw.
pub fn viewpoints(base: &Camera, n: usize) -> Vec<Camera> {
    (0..n.max(1))
        .map(|i| {
            let mut c = *base;
            c.orbit(360.0 / n.max(1) as f32 * i as f32, 0.0);
            c
        })
        .collect()
}

/// The stack with its first `classify.tf1d` (or `classify.tf2d`, for a 2D genome)
/// showing the genome, on fresh instances (so that each genome keeps its own lookup
/// table in an atlas).
pub fn stack_with(stack: &[PluginInstance], g: &Genome) -> Result<Vec<PluginInstance>, String> {
    let mut out: Vec<PluginInstance> = stack.iter().map(PluginInstance::duplicate).collect();
    g.apply(&mut out)?;
    Ok(out)
}

/// Thumbnails of every genome from every camera, composited over `background`, in
/// atlases of `batch` tiles: `out[g][v]`.
#[allow(clippy::too_many_arguments)]
pub fn thumbnails(
    r: &mut Renderer,
    stack: &[PluginInstance],
    genomes: &[Genome],
    cameras: &[Camera],
    tile: u32,
    slice_spacing: f32,
    background: [f64; 3],
    batch: usize,
) -> Result<Vec<Vec<RgbImageF>>, RenderError> {
    let stacks: Vec<Vec<PluginInstance>> = genomes
        .iter()
        .map(|g| stack_with(stack, g).map_err(RenderError::Atlas))
        .collect::<Result<_, _>>()?;
    let s = FrameSettings {
        camera: cameras[0],
        width: tile,
        height: tile,
        slice_spacing,
        backend: Backend::Compute,
        early_termination: None,
    };
    let mut out: Vec<Vec<RgbImageF>> = vec![Vec::new(); genomes.len()];
    let per = cameras.len();
    let all: Vec<(usize, Camera)> = (0..genomes.len())
        .flat_map(|g| cameras.iter().map(move |c| (g, *c)))
        .collect();
    for chunk in all.chunks(batch.max(per)) {
        let tiles: Vec<AtlasTile> = chunk
            .iter()
            .map(|(g, c)| AtlasTile {
                camera: *c,
                stack: &stacks[*g],
            })
            .collect();
        let cols = (tiles.len() as f64).sqrt().ceil() as u32;
        let atlas = r.render_atlas(&tiles, &s, TargetFormat::Rgba32Float, cols)?;
        for (i, (g, _)) in chunk.iter().enumerate() {
            out[*g].push(RgbImageF::from_rgba_f32_premultiplied_over(
                &atlas.tile_pixels(i),
                tile,
                tile,
                background,
            ));
        }
    }
    Ok(out)
}

/// A descriptor: the L*u*v* of every pixel of every view.
pub fn descriptor(views: &[RgbImageF]) -> Vec<[f64; 3]> {
    views
        .iter()
        .flat_map(|v| v.pixels.iter().map(|&p| srgb_to_luv(p)))
        .collect()
}

/// RMS ΔE*uv between two descriptors.
pub fn distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>())
        .sum();
    (sum / a.len().max(1) as f64).sqrt()
}

/// Greedy farthest-point selection of `k`: start at the descriptor farthest from the
/// pool's mean image, then repeatedly take the one farthest from those chosen.
pub fn farthest_points(desc: &[Vec<[f64; 3]>], k: usize) -> Vec<usize> {
    if desc.is_empty() || k == 0 {
        return Vec::new();
    }
    let n = desc[0].len();
    let mean: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let mut m = [0.0; 3];
            for d in desc {
                for c in 0..3 {
                    m[c] += d[i][c];
                }
            }
            m.map(|v| v / desc.len() as f64)
        })
        .collect();
    let first = (0..desc.len())
        .max_by(|&a, &b| distance(&desc[a], &mean).total_cmp(&distance(&desc[b], &mean)))
        .expect("not empty");
    let mut chosen = vec![first];
    let mut nearest: Vec<f64> = desc.iter().map(|d| distance(d, &desc[first])).collect();
    while chosen.len() < k.min(desc.len()) {
        let next = (0..desc.len())
            .filter(|i| !chosen.contains(i))
            .max_by(|&a, &b| nearest[a].total_cmp(&nearest[b]))
            .expect("more left");
        chosen.push(next);
        for (i, d) in desc.iter().enumerate() {
            nearest[i] = nearest[i].min(distance(d, &desc[next]));
        }
    }
    chosen
}

/// The smallest pairwise distance among `idx`.
pub fn min_pairwise(desc: &[Vec<[f64; 3]>], idx: &[usize]) -> f64 {
    let mut m = f64::INFINITY;
    for (a, &i) in idx.iter().enumerate() {
        for &j in &idx[a + 1..] {
            m = m.min(distance(&desc[i], &desc[j]));
        }
    }
    m
}

/// Classical MDS of a distance matrix to 2D (double centring, the two leading
/// eigenvectors by power iteration with deflation), then a grid: rows by the second
/// coordinate, columns by the first within each row. Returns (cell per item, columns).
pub fn mds_grid(d: &[Vec<f64>]) -> (Vec<[u32; 2]>, u32) {
    let n = d.len();
    if n == 0 {
        return (Vec::new(), 1);
    }
    let cols = (n as f64).sqrt().ceil() as usize;
    // B = −½ J D² J
    let sq: Vec<Vec<f64>> = d
        .iter()
        .map(|r| r.iter().map(|v| v * v).collect())
        .collect();
    let row: Vec<f64> = sq
        .iter()
        .map(|r| r.iter().sum::<f64>() / n as f64)
        .collect();
    let all = row.iter().sum::<f64>() / n as f64;
    let b: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| -0.5 * (sq[i][j] - row[i] - row[j] + all))
                .collect()
        })
        .collect();
    let mut coords = vec![[0.0f64; 2]; n];
    let mut deflated = b.clone();
    for (axis, _) in [0, 1].iter().enumerate() {
        // deterministic start
        let mut v: Vec<f64> = (0..n).map(|i| 1.0 + (i as f64 * 0.618).fract()).collect();
        let mut lambda = 0.0;
        for _ in 0..200 {
            let w: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| deflated[i][j] * v[j]).sum())
                .collect();
            let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm < 1e-12 {
                break;
            }
            lambda = norm;
            v = w.iter().map(|x| x / norm).collect();
        }
        for i in 0..n {
            coords[i][axis] = v[i] * lambda.max(0.0).sqrt();
        }
        for i in 0..n {
            for j in 0..n {
                deflated[i][j] -= lambda * v[i] * v[j];
            }
        }
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| coords[a][1].total_cmp(&coords[b][1]).then(a.cmp(&b)));
    let mut cells = vec![[0u32; 2]; n];
    for (r, chunk) in order.chunks(cols).enumerate() {
        let mut row: Vec<usize> = chunk.to_vec();
        row.sort_by(|&a, &b| coords[a][0].total_cmp(&coords[b][0]).then(a.cmp(&b)));
        for (c, &i) in row.iter().enumerate() {
            cells[i] = [c as u32, r as u32];
        }
    }
    (cells, cols as u32)
}

/// Draws the pool (seeded; around a genome when refining; in the space of the stack's
/// first TF plugin, [`Space::of_stack`]), renders every genome from
/// `views` viewpoints, keeps the `k` most dispersed and lays them out.
pub fn gallery(
    r: &mut Renderer,
    stack: &[PluginInstance],
    camera: &Camera,
    background: [f64; 3],
    o: &GalleryOptions,
) -> Result<Gallery, RenderError> {
    let space = Space::of_stack(stack).map_err(RenderError::Atlas)?;
    let pool: Vec<Genome> = (0..o.pool.max(1))
        .map(|i| {
            let mut rng = Rng::at(o.seed, i as u64);
            match &o.around {
                // the picked genome itself is part of its refinement
                Some((g, _)) if i == 0 => g.clone(),
                Some((g, radius)) => g.mutate(&mut rng, *radius),
                None => Genome::random(space, &mut rng, o.max_primitives),
            }
        })
        .collect();
    let cameras = viewpoints(camera, o.views);
    let start = Instant::now();
    let thumbs = thumbnails(
        r,
        stack,
        &pool,
        &cameras,
        o.tile,
        o.slice_spacing,
        background,
        o.batch,
    )?;
    let render_ms = start.elapsed().as_secs_f64() * 1e3;
    let desc: Vec<Vec<[f64; 3]>> = thumbs.iter().map(|v| descriptor(v)).collect();
    let k = o.k.min(pool.len());
    let chosen = farthest_points(&desc, k);
    let dist: Vec<Vec<f64>> = chosen
        .iter()
        .map(|&i| {
            chosen
                .iter()
                .map(|&j| distance(&desc[i], &desc[j]))
                .collect()
        })
        .collect();
    let (cells, cols) = mds_grid(&dist);
    let random: Vec<usize> = (0..k).collect();
    Ok(Gallery {
        dispersion: min_pairwise(&desc, &chosen),
        random_dispersion: min_pairwise(&desc, &random),
        views: chosen.iter().map(|&i| thumbs[i].clone()).collect(),
        rendered: pool.len() * cameras.len(),
        render_ms,
        pool,
        chosen,
        cells,
        cols,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn desc(values: &[f64]) -> Vec<Vec<[f64; 3]>> {
        values.iter().map(|&v| vec![[v, 0.0, 0.0]; 4]).collect()
    }

    #[test]
    fn farthest_points_spread_out() {
        // values on a line: the extremes and the middle come first
        let d = desc(&[0.0, 1.0, 2.0, 3.0, 10.0, 5.0, 9.0, 4.0]);
        let c = farthest_points(&d, 3);
        assert!(c.contains(&0) && c.contains(&4), "{c:?}");
        assert!(min_pairwise(&d, &c) >= min_pairwise(&d, &[0, 1, 2]));
        assert_eq!(distance(&d[0], &d[4]), 10.0);
    }

    #[test]
    fn mds_keeps_neighbours_close() {
        // two clusters on a line
        let pts = [0.0f64, 0.1, 0.2, 10.0, 10.1, 10.2];
        let d: Vec<Vec<f64>> = pts
            .iter()
            .map(|a| pts.iter().map(|b| (a - b).abs()).collect())
            .collect();
        let (cells, cols) = mds_grid(&d);
        assert_eq!(cols, 3);
        // every cell used once
        let mut seen = cells.clone();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), 6);
        // the clusters land in different rows or at opposite ends of a row
        let side = |i: usize| cells[i];
        assert_ne!(side(0), side(3));
        let near = |a: usize, b: usize| {
            let (p, q) = (side(a), side(b));
            (p[0] as i32 - q[0] as i32).abs() + (p[1] as i32 - q[1] as i32).abs()
        };
        assert!(near(0, 1) <= near(0, 4), "{cells:?}");
    }
}
