//! Image error metrics: CIE ΔE*uv (CIELUV, D65), its RMS, mean, maximum and the share
//! of pixels above 6 (the figures Hernell et al. 2008 report), PSNR and SSIM, and a
//! ΔE heatmap with a colour bar.
//!
//! # Conventions
//!
//! * **Colour space.** The renderer's colours are display values: transfer functions
//!   are specified in sRGB-encoded colours and slices are composited on those values,
//!   exactly as a classic slice renderer blends into the framebuffer. So an image here
//!   holds sRGB-encoded values in \[0,1\]; [`srgb_to_luv`] decodes them with the sRGB
//!   transfer curve, converts to CIE XYZ with the sRGB (D65) primaries and then to
//!   CIELUV relative to the D65 white (Yn = 1).
//! * **Alpha and background.** The eye buffer holds premultiplied RGBA. Before any
//!   metric, an image is composited over an opaque background,
//!   `rgb = clamp(C + (1 − A)·background, 0, 1)` (the `display.wgsl` convention);
//!   components that are NaN count as 0. The background is part of what is compared:
//!   use the preset's (black by default) so that the figures describe what the user
//!   sees.
//! * **PSNR** is over the three sRGB channels with peak 1; identical images give +∞
//!   (written as `null` in JSON).
//! * **SSIM** (Wang et al. 2004) on luma Y' = 0.299 R' + 0.587 G' + 0.114 B' of the
//!   sRGB values, Gaussian window 11×11 with σ = 1.5, K1 = 0.01, K2 = 0.03, L = 1,
//!   averaged over the window positions that fit in the image (a smaller window for
//!   images under 11 pixels).
//! * **Blurred ΔE*uv** ([`Metrics::rms_delta_e_blur`]): the RMS ΔE*uv of the two
//!   images after each is low-passed by a Gaussian of σ = 1 pixel (5 taps per axis,
//!   edges clamped, on the sRGB-encoded values). Fine per-pixel noise averages out and
//!   structured error (bands, rings, edges in the wrong place) stays: a cheap stand-in
//!   for the spatial filtering of S-CIELAB (Zhang & Wandell 1996), which models that the
//!   eye does not resolve single-pixel noise at a viewing distance. It tells stochastic
//!   sampling (jitter) apart from aliasing where the plain RMS cannot.

use std::path::Path;

use serde::Serialize;

/// D65 reference white: the sRGB matrix applied to (1, 1, 1), so that sRGB white is
/// exactly L* = 100, u* = v* = 0.
const WHITE_X: f64 = 0.4124564 + 0.3575761 + 0.1804375;
const WHITE_Y: f64 = 0.2126729 + 0.7151522 + 0.0721750;
const WHITE_Z: f64 = 0.0193339 + 0.1191920 + 0.9503041;

/// ΔE*uv threshold whose exceedance share is reported (Hernell et al. 2008).
pub const DELTA_E_NOTICEABLE: f64 = 6.0;

/// Default top of the heatmap scale (ΔE*uv); larger errors saturate.
pub const HEATMAP_DEFAULT_MAX: f64 = 12.0;

/// An opaque image of sRGB-encoded values in \[0,1\], row-major from the top.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImageF {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f64; 3]>,
}

impl RgbImageF {
    /// # Panics
    /// When `pixels.len() != width·height`.
    pub fn new(width: u32, height: u32, pixels: Vec<[f64; 3]>) -> Self {
        assert_eq!(
            pixels.len(),
            width as usize * height as usize,
            "pixel count does not match {width}x{height}"
        );
        Self {
            width,
            height,
            pixels,
        }
    }

    /// Composites premultiplied RGBA over an opaque background (module docs).
    pub fn from_rgba_premultiplied_over(
        rgba: &[[f64; 4]],
        width: u32,
        height: u32,
        background: [f64; 3],
    ) -> Self {
        let pixels = rgba.iter().map(|p| over(*p, background)).collect();
        Self::new(width, height, pixels)
    }

    /// [`Self::from_rgba_premultiplied_over`] for an f32 eye buffer.
    pub fn from_rgba_f32_premultiplied_over(
        rgba: &[[f32; 4]],
        width: u32,
        height: u32,
        background: [f64; 3],
    ) -> Self {
        let wide: Vec<[f64; 4]> = rgba.iter().map(|p| p.map(f64::from)).collect();
        Self::from_rgba_premultiplied_over(&wide, width, height, background)
    }

    /// From an 8-bit image (as written to PNG).
    pub fn from_rgb8(img: &image::RgbImage) -> Self {
        let pixels = img
            .pixels()
            .map(|p| p.0.map(|c| c as f64 / 255.0))
            .collect();
        Self::new(img.width(), img.height(), pixels)
    }

    /// Reads a PNG (any colour type; alpha is dropped).
    pub fn load_png(path: &Path) -> Result<Self, String> {
        let img = image::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Self::from_rgb8(&img.to_rgb8()))
    }

    /// Rounds to 8 bits per channel.
    pub fn to_rgb8(&self) -> image::RgbImage {
        let mut img = image::RgbImage::new(self.width, self.height);
        for (dst, src) in img.pixels_mut().zip(&self.pixels) {
            dst.0 = src.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
        }
        img
    }
}

fn finite_or_zero(x: f64) -> f64 {
    if x.is_finite() { x } else { 0.0 }
}

fn over(p: [f64; 4], background: [f64; 3]) -> [f64; 3] {
    let a = finite_or_zero(p[3]).clamp(0.0, 1.0);
    std::array::from_fn(|i| (finite_or_zero(p[i]) + (1.0 - a) * background[i]).clamp(0.0, 1.0))
}

/// sRGB electro-optical transfer: encoded value → linear light.
pub fn srgb_decode(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// sRGB-encoded colour in \[0,1\] → CIE XYZ (D65, Y of white = 1).
pub fn srgb_to_xyz(rgb: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = rgb.map(srgb_decode);
    [
        0.4124564 * r + 0.3575761 * g + 0.1804375 * b,
        0.2126729 * r + 0.7151522 * g + 0.0721750 * b,
        0.0193339 * r + 0.1191920 * g + 0.9503041 * b,
    ]
}

fn uv_prime(xyz: [f64; 3]) -> (f64, f64) {
    let d = xyz[0] + 15.0 * xyz[1] + 3.0 * xyz[2];
    if d <= 0.0 {
        (0.0, 0.0)
    } else {
        (4.0 * xyz[0] / d, 9.0 * xyz[1] / d)
    }
}

/// sRGB-encoded colour in \[0,1\] → CIELUV (L*, u*, v*) relative to D65.
pub fn srgb_to_luv(rgb: [f64; 3]) -> [f64; 3] {
    let xyz = srgb_to_xyz(rgb);
    let y = xyz[1] / WHITE_Y;
    let eps = (6.0f64 / 29.0).powi(3);
    let l = if y > eps {
        116.0 * y.cbrt() - 16.0
    } else {
        (29.0f64 / 3.0).powi(3) * y
    };
    let (u, v) = uv_prime(xyz);
    let (un, vn) = uv_prime([WHITE_X, WHITE_Y, WHITE_Z]);
    [l, 13.0 * l * (u - un), 13.0 * l * (v - vn)]
}

/// sRGB opto-electronic transfer: linear light → encoded value ([`srgb_decode`]'s inverse).
pub fn srgb_encode(c: f64) -> f64 {
    if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// CIELUV (D65) → sRGB-encoded colour, [`srgb_to_luv`]'s inverse (unclamped: a colour
/// outside the sRGB gamut comes back outside [0, 1]).
pub fn luv_to_srgb(luv: [f64; 3]) -> [f64; 3] {
    let [l, u, v] = luv;
    if l <= 0.0 {
        return [0.0; 3];
    }
    let y = WHITE_Y
        * if l > 8.0 {
            ((l + 16.0) / 116.0).powi(3)
        } else {
            l / (29.0f64 / 3.0).powi(3)
        };
    let (un, vn) = uv_prime([WHITE_X, WHITE_Y, WHITE_Z]);
    let (up, vp) = (u / (13.0 * l) + un, v / (13.0 * l) + vn);
    if vp <= 0.0 {
        return [0.0; 3];
    }
    let x = y * 9.0 * up / (4.0 * vp);
    let z = y * (12.0 - 3.0 * up - 20.0 * vp) / (4.0 * vp);
    let lin = [
        3.2404542 * x - 1.5371385 * y - 0.4985314 * z,
        -0.9692660 * x + 1.8760108 * y + 0.0415560 * z,
        0.0556434 * x - 0.2040259 * y + 1.0572252 * z,
    ];
    lin.map(|c| {
        if c < 0.0 {
            -srgb_encode(-c)
        } else {
            srgb_encode(c)
        }
    })
}

/// CIE 1976 ΔE*uv between two sRGB-encoded colours.
pub fn delta_e_uv(a: [f64; 3], b: [f64; 3]) -> f64 {
    let (p, q) = (srgb_to_luv(a), srgb_to_luv(b));
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

/// Error figures of one image against another.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Metrics {
    pub width: u32,
    pub height: u32,
    /// Root mean square of per-pixel ΔE*uv.
    pub rms_delta_e: f64,
    pub mean_delta_e: f64,
    pub max_delta_e: f64,
    /// Share of pixels (0..1) with ΔE*uv > 6.
    pub share_above_6: f64,
    /// dB over the sRGB channels; +∞ for identical images.
    pub psnr_db: f64,
    /// Mean SSIM of the luma, in [-1, 1]; 1 for identical images.
    pub ssim: f64,
    /// RMS ΔE*uv after a Gaussian blur of σ = 1 pixel of both images (module docs).
    pub rms_delta_e_blur: f64,
}

/// Per-pixel ΔE*uv, row-major.
///
/// # Panics
/// When the sizes differ.
pub fn delta_e_map(a: &RgbImageF, b: &RgbImageF) -> Vec<f64> {
    assert_same_size(a, b);
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| delta_e_uv(*p, *q))
        .collect()
}

fn assert_same_size(a: &RgbImageF, b: &RgbImageF) {
    assert!(
        a.width == b.width && a.height == b.height,
        "image sizes differ: {}x{} vs {}x{}",
        a.width,
        a.height,
        b.width,
        b.height
    );
}

/// All metrics of `a` against `b` (symmetric but for SSIM's rounding).
///
/// # Panics
/// When the sizes differ (see [`try_compare`]).
pub fn compare(a: &RgbImageF, b: &RgbImageF) -> Metrics {
    let map = delta_e_map(a, b);
    let n = map.len().max(1) as f64;
    Metrics {
        width: a.width,
        height: a.height,
        rms_delta_e: (map.iter().map(|d| d * d).sum::<f64>() / n).sqrt(),
        mean_delta_e: map.iter().sum::<f64>() / n,
        max_delta_e: map.iter().copied().fold(0.0, f64::max),
        share_above_6: map.iter().filter(|&&d| d > DELTA_E_NOTICEABLE).count() as f64 / n,
        psnr_db: psnr(a, b),
        ssim: ssim(a, b),
        rms_delta_e_blur: rms_delta_e_blurred(a, b),
    }
}

/// `img` low-passed by a Gaussian of σ = 1 pixel (5 taps per axis, edges clamped).
pub fn blurred(img: &RgbImageF) -> RgbImageF {
    let k = gaussian(5, 1.0);
    let (w, h) = (img.width as usize, img.height as usize);
    let at = |x: isize, y: isize, c: usize, src: &[[f64; 3]]| {
        let x = x.clamp(0, w as isize - 1) as usize;
        let y = y.clamp(0, h as isize - 1) as usize;
        src[y * w + x][c]
    };
    let pass = |src: &[[f64; 3]], dx: isize, dy: isize| -> Vec<[f64; 3]> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as isize, (i / w) as isize);
                std::array::from_fn(|c| {
                    (0..5)
                        .map(|t| {
                            k[t] * at(x + dx * (t as isize - 2), y + dy * (t as isize - 2), c, src)
                        })
                        .sum()
                })
            })
            .collect()
    };
    if w == 0 || h == 0 {
        return img.clone();
    }
    let rows = pass(&img.pixels, 1, 0);
    RgbImageF::new(img.width, img.height, pass(&rows, 0, 1))
}

/// [`Metrics::rms_delta_e_blur`]: RMS ΔE*uv of the two images blurred alike.
pub fn rms_delta_e_blurred(a: &RgbImageF, b: &RgbImageF) -> f64 {
    let map = delta_e_map(&blurred(a), &blurred(b));
    (map.iter().map(|d| d * d).sum::<f64>() / map.len().max(1) as f64).sqrt()
}

/// [`compare`] that reports a size mismatch instead of panicking.
pub fn try_compare(a: &RgbImageF, b: &RgbImageF) -> Result<Metrics, String> {
    if a.width != b.width || a.height != b.height {
        return Err(format!(
            "image sizes differ: {}x{} vs {}x{}",
            a.width, a.height, b.width, b.height
        ));
    }
    Ok(compare(a, b))
}

/// PSNR in dB over the sRGB channels with peak 1.
pub fn psnr(a: &RgbImageF, b: &RgbImageF) -> f64 {
    assert_same_size(a, b);
    let n = (a.pixels.len() * 3).max(1) as f64;
    let mse = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..3).map(move |i| (p[i] - q[i]).powi(2)))
        .sum::<f64>()
        / n;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

fn luma(img: &RgbImageF) -> Vec<f64> {
    img.pixels
        .iter()
        .map(|p| 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2])
        .collect()
}

/// Normalised Gaussian weights of a window of `size` taps.
fn gaussian(size: usize, sigma: f64) -> Vec<f64> {
    let c = (size as f64 - 1.0) / 2.0;
    let w: Vec<f64> = (0..size)
        .map(|i| (-((i as f64 - c).powi(2)) / (2.0 * sigma * sigma)).exp())
        .collect();
    let s: f64 = w.iter().sum();
    w.into_iter().map(|x| x / s).collect()
}

/// Separable "valid" filtering: output (w − k + 1) × (h − k + 1).
fn filter_valid(src: &[f64], w: usize, h: usize, k: &[f64]) -> Vec<f64> {
    let n = k.len();
    let (ow, oh) = (w + 1 - n, h + 1 - n);
    let mut rows = vec![0.0; ow * h];
    for y in 0..h {
        for x in 0..ow {
            rows[y * ow + x] = (0..n).map(|i| k[i] * src[y * w + x + i]).sum();
        }
    }
    let mut out = vec![0.0; ow * oh];
    for y in 0..oh {
        for x in 0..ow {
            out[y * ow + x] = (0..n).map(|i| k[i] * rows[(y + i) * ow + x]).sum();
        }
    }
    out
}

/// Mean SSIM of the luma (module docs for the constants).
pub fn ssim(a: &RgbImageF, b: &RgbImageF) -> f64 {
    assert_same_size(a, b);
    let (w, h) = (a.width as usize, a.height as usize);
    if w == 0 || h == 0 {
        return 1.0;
    }
    let size = 11.min(w).min(h);
    let k = gaussian(size, 1.5);
    let (x, y) = (luma(a), luma(b));
    let prod = |p: &[f64], q: &[f64]| p.iter().zip(q).map(|(u, v)| u * v).collect::<Vec<_>>();
    let mx = filter_valid(&x, w, h, &k);
    let my = filter_valid(&y, w, h, &k);
    let sxx = filter_valid(&prod(&x, &x), w, h, &k);
    let syy = filter_valid(&prod(&y, &y), w, h, &k);
    let sxy = filter_valid(&prod(&x, &y), w, h, &k);
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let n = mx.len() as f64;
    (0..mx.len())
        .map(|i| {
            let (ux, uy) = (mx[i], my[i]);
            let vx = sxx[i] - ux * ux;
            let vy = syy[i] - uy * uy;
            let cxy = sxy[i] - ux * uy;
            ((2.0 * ux * uy + c1) * (2.0 * cxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2))
        })
        .sum::<f64>()
        / n
}

/// Magma-like colour map, `t` in [0,1].
fn colormap(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] = [
        [0.0, 0.0, 4.0],
        [81.0, 18.0, 124.0],
        [183.0, 55.0, 121.0],
        [252.0, 137.0, 97.0],
        [252.0, 253.0, 191.0],
    ];
    let x = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f64;
    std::array::from_fn(|c| (STOPS[i][c] + (STOPS[i + 1][c] - STOPS[i][c]) * f).round() as u8)
}

/// 3×5 bitmap glyphs for the colour-bar labels (rows top to bottom, 3 bits each).
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        '+' => [0, 2, 7, 2, 0],
        _ => return None,
    })
}

/// Draws `text` with its top-left corner at (x, y), glyph pixels `scale`² each.
fn draw_text(img: &mut image::RgbImage, x: u32, y: u32, text: &str, scale: u32, color: [u8; 3]) {
    for (n, c) in text.chars().enumerate() {
        let Some(rows) = glyph(c) else { continue };
        let gx = x + n as u32 * 4 * scale;
        for (r, bits) in rows.iter().enumerate() {
            for col in 0..3u32 {
                if bits & (4 >> col) == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let (px, py) = (gx + col * scale + dx, y + r as u32 * scale + dy);
                        if px < img.width() && py < img.height() {
                            img.put_pixel(px, py, image::Rgb(color));
                        }
                    }
                }
            }
        }
    }
}

fn label(v: f64) -> String {
    if v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.1}")
    }
}

/// A ΔE heatmap: the map in a magma-like scale from 0 (black) to `max_delta_e` (pale
/// yellow; larger values saturate, non-finite ones are pure green), with a colour bar
/// on the right labelled at 0, 6 (the noticeability threshold, also marked by a white
/// tick) and the maximum.
pub fn heatmap(map: &[f64], width: u32, height: u32, max_delta_e: f64) -> image::RgbImage {
    assert_eq!(map.len(), width as usize * height as usize);
    let top = if max_delta_e.is_finite() && max_delta_e > 0.0 {
        max_delta_e
    } else {
        HEATMAP_DEFAULT_MAX
    };
    let scale = if height >= 96 { 2 } else { 1 };
    let bar_x = width + 6;
    let bar_w = 12;
    let text_x = bar_x + bar_w + 3;
    let labels = [0.0, DELTA_E_NOTICEABLE.min(top), top];
    let text_w = labels
        .iter()
        .map(|&v| (label(v).len() as u32 + 1) * 4 * scale)
        .max()
        .unwrap_or(0);
    let out_h = height.max(5 * scale + 2);
    let mut img = image::RgbImage::from_pixel(text_x + text_w + 2, out_h, image::Rgb([40; 3]));
    for y in 0..height {
        for x in 0..width {
            let d = map[(y * width + x) as usize];
            let c = if d.is_finite() {
                colormap(d / top)
            } else {
                [0, 255, 0]
            };
            img.put_pixel(x, y, image::Rgb(c));
        }
    }
    // bar: top of the image is the maximum
    let row_value = |y: u32| top * (1.0 - y as f64 / (out_h - 1).max(1) as f64);
    for y in 0..out_h {
        let c = colormap(row_value(y) / top);
        for x in bar_x..bar_x + bar_w {
            img.put_pixel(x, y, image::Rgb(c));
        }
    }
    let glyph_h = 5 * scale;
    for (i, &v) in labels.iter().enumerate() {
        let y = ((1.0 - v / top) * (out_h - 1) as f64).round() as u32;
        for x in bar_x + bar_w..text_x {
            img.put_pixel(x, y.min(out_h - 1), image::Rgb([255; 3]));
        }
        let text_y = y.saturating_sub(glyph_h / 2).min(out_h - glyph_h);
        let text = if i == 2 && v == top {
            format!("{}+", label(v))
        } else {
            label(v)
        };
        draw_text(&mut img, text_x, text_y, &text, scale, [255; 3]);
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solid(w: u32, h: u32, c: [f64; 3]) -> RgbImageF {
        RgbImageF::new(w, h, vec![c; (w * h) as usize])
    }

    /// The blurred ΔE keeps structured error and drops per-pixel noise of the same
    /// size: a ±0.06 checkerboard on grey nearly vanishes, a band of +0.06 eight
    /// pixels wide keeps most of its error; a uniform offset keeps all of it.
    #[test]
    fn the_blurred_delta_e_drops_noise_and_keeps_structure() {
        let (w, h) = (32u32, 32u32);
        let grey = solid(w, h, [0.5; 3]);
        let shifted = |f: &dyn Fn(u32, u32) -> f64| {
            let px = (0..w * h).map(|i| [0.5 + f(i % w, i / w); 3]).collect();
            RgbImageF::new(w, h, px)
        };
        let noise = shifted(&|x, y| if (x + y) % 2 == 0 { 0.06 } else { -0.06 });
        let band = shifted(&|x, _| if (12..20).contains(&x) { 0.06 } else { 0.0 });
        let offset = shifted(&|_, _| 0.06);
        let (n, b, o) = (
            compare(&noise, &grey),
            compare(&band, &grey),
            compare(&offset, &grey),
        );
        assert!(n.rms_delta_e > 3.0, "{n:?}");
        assert!(n.rms_delta_e_blur < 0.1 * n.rms_delta_e, "{n:?}");
        assert!(b.rms_delta_e_blur > 0.75 * b.rms_delta_e, "{b:?}");
        assert!((o.rms_delta_e_blur - o.rms_delta_e).abs() < 1e-9, "{o:?}");
        assert_eq!(compare(&grey, &grey).rms_delta_e_blur, 0.0);
    }

    #[test]
    fn identical_images_have_no_error() {
        let pixels = (0..24 * 16)
            .map(|i| {
                let t = i as f64 / 383.0;
                [t, 1.0 - t, (t * 7.0).fract()]
            })
            .collect();
        let a = RgbImageF::new(24, 16, pixels);
        let m = compare(&a, &a);
        assert_eq!(m.rms_delta_e, 0.0);
        assert_eq!(m.max_delta_e, 0.0);
        assert_eq!(m.share_above_6, 0.0);
        assert_eq!(m.psnr_db, f64::INFINITY);
        assert!((m.ssim - 1.0).abs() < 1e-12, "{}", m.ssim);
    }

    #[test]
    fn luv_goes_back_to_srgb() {
        for rgb in [
            [0.0, 0.0, 0.0],
            [1.0, 1.0, 1.0],
            [0.85, 0.55, 0.45],
            [0.02, 0.9, 0.3],
            [0.001, 0.002, 0.0015],
            [0.3, 0.1, 0.95],
        ] {
            let back = luv_to_srgb(srgb_to_luv(rgb));
            for c in 0..3 {
                assert!((back[c] - rgb[c]).abs() < 1e-6, "{rgb:?} → {back:?}");
            }
        }
    }

    #[test]
    fn luv_of_known_colours() {
        // white is L* = 100, u* = v* = 0
        let w = srgb_to_luv([1.0; 3]);
        assert!(
            (w[0] - 100.0).abs() < 1e-9 && w[1].abs() < 1e-9 && w[2].abs() < 1e-9,
            "{w:?}"
        );
        assert_eq!(srgb_to_luv([0.0; 3]), [0.0; 3]);
        // sRGB red: L* 53.2408, u* 175.0151, v* 37.7564 (Lindbloom's calculator, D65)
        let r = srgb_to_luv([1.0, 0.0, 0.0]);
        for (got, want) in r.iter().zip([53.2408, 175.0151, 37.7564]) {
            assert!((got - want).abs() < 2e-3, "{r:?}");
        }
        // black–white is 100 exactly
        assert!((delta_e_uv([0.0; 3], [1.0; 3]) - 100.0).abs() < 1e-9);
    }

    #[test]
    fn hand_computed_grey_pair() {
        // Two greys differ only in L*: ΔE*uv = |L1 − L2|. Grey 0.5 decodes to
        // ((0.5 + 0.055)/1.055)^2.4 = 0.214041; L* = 116·0.214041^(1/3) − 16 = 53.3890.
        // Grey 0.25 decodes to 0.050876; L* = 116·0.050876^(1/3) − 16 = 26.9829.
        let d = delta_e_uv([0.5; 3], [0.25; 3]);
        assert!((d - (53.3890 - 26.9829)).abs() < 1e-3, "{d}");
        let a = solid(8, 8, [0.5; 3]);
        let b = solid(8, 8, [0.25; 3]);
        let m = compare(&a, &b);
        assert!((m.rms_delta_e - d).abs() < 1e-12);
        assert_eq!(m.share_above_6, 1.0);
        // MSE 0.0625 → PSNR = 10·log10(16) = 12.0412 dB
        assert!(
            (m.psnr_db - 12.041199826559248).abs() < 1e-9,
            "{}",
            m.psnr_db
        );
    }

    #[test]
    fn share_above_six_and_max() {
        let mut b = solid(10, 10, [0.5; 3]);
        // 7 pixels far off, the rest equal
        for p in b.pixels.iter_mut().take(7) {
            *p = [0.9, 0.5, 0.5];
        }
        let m = compare(&solid(10, 10, [0.5; 3]), &b);
        assert!((m.share_above_6 - 0.07).abs() < 1e-12);
        let d = delta_e_uv([0.5; 3], [0.9, 0.5, 0.5]);
        assert!(d > 6.0);
        assert!((m.max_delta_e - d).abs() < 1e-12);
        assert!((m.rms_delta_e - (0.07 * d * d).sqrt()).abs() < 1e-9);
    }

    #[test]
    fn ssim_drops_with_structure_loss() {
        let w = 32;
        let stripes: Vec<[f64; 3]> = (0..w * w)
            .map(|i| {
                if (i % w / 2) % 2 == 0 {
                    [0.9; 3]
                } else {
                    [0.1; 3]
                }
            })
            .collect();
        let a = RgbImageF::new(w, w, stripes);
        let flat = solid(w, w, [0.5; 3]);
        let s = ssim(&a, &flat);
        assert!(s < 0.1, "{s}");
        // a small brightness offset keeps the structure
        let shifted = RgbImageF::new(w, w, a.pixels.iter().map(|p| p.map(|c| c + 0.02)).collect());
        assert!(ssim(&a, &shifted) > 0.95);
    }

    #[test]
    fn compositing_convention() {
        let img =
            RgbImageF::from_rgba_premultiplied_over(&[[0.2, 0.1, 0.0, 0.5]], 1, 1, [1.0, 0.0, 0.4]);
        assert_eq!(img.pixels[0], [0.7, 0.1, 0.2]);
        let nan = RgbImageF::from_rgba_premultiplied_over(
            &[[f64::NAN, 2.0, 0.0, f64::NAN]],
            1,
            1,
            [0.5; 3],
        );
        assert_eq!(nan.pixels[0], [0.5, 1.0, 0.5]);
        assert!(try_compare(&img, &solid(2, 1, [0.0; 3])).is_err());
    }

    #[test]
    fn heatmap_has_a_colour_bar() {
        let map: Vec<f64> = (0..64 * 64).map(|i| (i % 64) as f64 / 4.0).collect();
        let img = heatmap(&map, 64, 64, 12.0);
        assert!(img.width() > 64 + 12);
        assert_eq!(img.height(), 64);
        assert_eq!(img.get_pixel(0, 0).0, colormap(0.0));
        // saturates above the maximum
        assert_eq!(img.get_pixel(63, 0).0, colormap(1.0));
        // the bar runs from the maximum at the top to 0 at the bottom
        assert_eq!(img.get_pixel(64 + 6, 0).0, colormap(1.0));
        assert_eq!(img.get_pixel(64 + 6, 63).0, colormap(0.0));
        // labels are drawn in white
        let white = img.pixels().filter(|p| p.0 == [255; 3]).count();
        assert!(white > 10, "{white}");
    }
}
