//! Longitude–latitude environment maps: the procedural default, images read with the
//! `image` crate, the diffuse (irradiance) map, and the bilinear lookup that mirrors
//! `envmap.wgsl`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};

use glam::DVec3;

/// Size of the radiance (reflective) map every source is resampled to.
pub const RADIANCE_SIZE: (u32, u32) = (512, 256);
/// Size of the diffuse map.
pub const IRRADIANCE_SIZE: (u32, u32) = (64, 32);

/// An RGBA f32 longitude–latitude image, row 0 at the zenith (+y).
#[derive(Debug, Clone, PartialEq)]
pub struct LatLong {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[f32; 4]>,
}

/// The radiance map and its diffuse convolution.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvMaps {
    pub radiance: LatLong,
    pub irradiance: LatLong,
}

/// Direction of the centre of texel (x, y) of a w × h map (without rotation).
fn texel_dir(x: u32, y: u32, w: u32, h: u32) -> DVec3 {
    let u = (x as f64 + 0.5) / w as f64;
    let v = (y as f64 + 0.5) / h as f64;
    let theta = v * std::f64::consts::PI;
    let phi = (u - 0.5) * std::f64::consts::TAU;
    // inverse of latlong_uv: atan2(d.x, −d.z) = φ, acos(d.y) = θ
    DVec3::new(
        theta.sin() * phi.sin(),
        theta.cos(),
        -theta.sin() * phi.cos(),
    )
}

impl LatLong {
    pub fn from_fn(w: u32, h: u32, f: impl Fn(DVec3) -> DVec3) -> Self {
        let texels = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let c = f(texel_dir(x, y, w, h)).as_vec3();
                [c.x, c.y, c.z, 1.0]
            })
            .collect();
        Self {
            width: w,
            height: h,
            texels,
        }
    }

    /// `latlong_uv` with the rotation about +y in degrees.
    pub fn uv(d: DVec3, rotation_deg: f64) -> (f64, f64) {
        let u = 0.5 + (d.x.atan2(-d.z) + rotation_deg.to_radians()) / std::f64::consts::TAU;
        let v = d.y.clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
        (u - u.floor(), v)
    }

    /// `latlong`: bilinear lookup, u wraps, v clamps.
    pub fn lookup(&self, d: DVec3, rotation_deg: f64) -> DVec3 {
        let (w, h) = (self.width as i64, self.height as i64);
        let (u, v) = Self::uv(d, rotation_deg);
        let x = u * w as f64 - 0.5;
        let y = (v * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (xf, yf) = (x.floor(), y.floor());
        let (fx, fy) = (x - xf, y - yf);
        let x0 = (xf as i64).rem_euclid(w);
        let x1 = (x0 + 1) % w;
        let y0 = yf as i64;
        let y1 = (y0 + 1).min(h - 1);
        let at = |x: i64, y: i64| {
            let t = self.texels[(y * w + x) as usize];
            DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64)
        };
        at(x0, y0)
            .lerp(at(x1, y0), fx)
            .lerp(at(x0, y1).lerp(at(x1, y1), fx), fy)
    }

    /// Box-filtered down to w × h (integer factors).
    fn downsample(&self, w: u32, h: u32) -> LatLong {
        let (fx, fy) = (self.width / w, self.height / h);
        let mut texels = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                let mut c = [0.0f32; 4];
                for j in 0..fy {
                    for i in 0..fx {
                        let t = self.texels[((y * fy + j) * self.width + x * fx + i) as usize];
                        for k in 0..4 {
                            c[k] += t[k];
                        }
                    }
                }
                texels.push(c.map(|v| v / (fx * fy) as f32));
            }
        }
        LatLong {
            width: w,
            height: h,
            texels,
        }
    }

    /// The diffuse map: E(n) = Σ L(ω)·max(0, n·ω)·ΔΩ / Σ max(0, n·ω)·ΔΩ over the map
    /// (cosine-weighted average radiance; 1 for a constant white environment), from
    /// the map box-filtered to `IRRADIANCE_SIZE`.
    pub fn irradiance(&self) -> LatLong {
        let (w, h) = IRRADIANCE_SIZE;
        let small = self.downsample(w, h);
        let src: Vec<(DVec3, DVec3, f64)> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let d = texel_dir(x, y, w, h);
                let t = small.texels[(y * w + x) as usize];
                let solid = (((y as f64 + 0.5) / h as f64) * std::f64::consts::PI).sin();
                (d, DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64), solid)
            })
            .collect();
        LatLong::from_fn(w, h, |n| {
            let (mut sum, mut weight) = (DVec3::ZERO, 0.0);
            for (d, l, solid) in &src {
                let c = n.dot(*d).max(0.0) * solid;
                sum += *l * c;
                weight += c;
            }
            if weight > 0.0 {
                sum / weight
            } else {
                DVec3::ZERO
            }
        })
    }
}

/// The default environment: a sky (blue at the zenith, pale at the horizon), a warm
/// ground and a small sun up and to the right of −z.
pub fn procedural() -> Arc<EnvMaps> {
    static MAPS: OnceLock<Arc<EnvMaps>> = OnceLock::new();
    MAPS.get_or_init(|| {
        let sun = DVec3::new(0.5, 0.6, -0.6).normalize();
        let (w, h) = RADIANCE_SIZE;
        let radiance = LatLong::from_fn(w, h, |d| {
            let sky =
                DVec3::new(0.85, 0.9, 1.0).lerp(DVec3::new(0.25, 0.45, 0.85), d.y.max(0.0).sqrt());
            let ground = DVec3::new(0.45, 0.38, 0.3)
                .lerp(DVec3::new(0.2, 0.17, 0.14), (-d.y).max(0.0).sqrt());
            let base = if d.y >= 0.0 { sky } else { ground };
            base + DVec3::new(4.0, 3.6, 3.0) * d.dot(sun).max(0.0).powf(400.0)
        });
        let irradiance = radiance.irradiance();
        Arc::new(EnvMaps {
            radiance,
            irradiance,
        })
    })
    .clone()
}

/// Reads an image (any format the `image` crate reads; values as stored, i.e.
/// display-referred for 8-bit files, linear for HDR/EXR) as a longitude–latitude map,
/// resampled to `RADIANCE_SIZE`. Cached per path and modification time.
pub fn load(path: &Path) -> Result<Arc<EnvMaps>, String> {
    type Cache = Mutex<HashMap<(PathBuf, Option<std::time::SystemTime>), Arc<EnvMaps>>>;
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let modified = std::fs::metadata(path).and_then(|m| m.modified()).ok();
    let key = (path.to_path_buf(), modified);
    let cache = CACHE.get_or_init(Default::default);
    if let Some(m) = cache.lock().map_err(|e| e.to_string())?.get(&key) {
        return Ok(m.clone());
    }
    let img = image::open(path)
        .map_err(|e| format!("environment map {}: {e}", path.display()))?
        .to_rgba32f();
    let (w, h) = RADIANCE_SIZE;
    let img = image::imageops::resize(&img, w, h, image::imageops::FilterType::Triangle);
    let radiance = LatLong {
        width: w,
        height: h,
        texels: img
            .pixels()
            .map(|p| {
                let c = p.0.map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 });
                [c[0], c[1], c[2], 1.0]
            })
            .collect(),
    };
    let maps = Arc::new(EnvMaps {
        irradiance: radiance.irradiance(),
        radiance,
    });
    cache
        .lock()
        .map_err(|e| e.to_string())?
        .insert(key, maps.clone());
    Ok(maps)
}
