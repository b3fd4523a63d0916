//! Generated scalar phantoms: voxel-aligned boxes of constant value on a background,
//! for scenes whose every voxel is known (a block in front of a wall, a slab cut at a
//! voxel boundary). Presets and experiment scenes name one as
//! `volume: Phantom((size: (32, 32, 32), boxes: [(from: (0, 0, 20), to: (32, 32, 24), value: 1.0)]))`.

use serde::{Deserialize, Serialize};

use super::{Volume, VoxelData};

/// Most boxes a phantom holds.
pub const MAX_PHANTOM_BOXES: usize = 64;

/// A generated scalar volume (f32 voxels, unit spacing): `background` everywhere, then
/// each box in order sets its voxels to its value (a later box paints over an earlier).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Phantom {
    /// Voxels per axis, 2–512.
    pub size: [u32; 3],
    /// Value of the voxels no box covers.
    #[serde(default)]
    pub background: f32,
    #[serde(default)]
    pub boxes: Vec<PhantomBox>,
}

/// The voxels `from ≤ (x, y, z) < to` (per axis) take `value`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhantomBox {
    pub from: [u32; 3],
    pub to: [u32; 3],
    pub value: f32,
}

impl Phantom {
    /// Sides of 2–512 voxels, at most [`MAX_PHANTOM_BOXES`] boxes, each non-empty and
    /// inside the volume, finite values.
    pub fn check(&self) -> Result<(), String> {
        if !self.size.iter().all(|s| (2..=512).contains(s)) {
            return Err(format!(
                "a phantom's size must be 2–512 voxels per side, got {:?}",
                self.size
            ));
        }
        if !self.background.is_finite() {
            return Err(format!(
                "a phantom's background must be finite, got {}",
                self.background
            ));
        }
        if self.boxes.len() > MAX_PHANTOM_BOXES {
            return Err(format!(
                "a phantom holds at most {MAX_PHANTOM_BOXES} boxes, got {}",
                self.boxes.len()
            ));
        }
        for (i, b) in self.boxes.iter().enumerate() {
            if !b.value.is_finite() {
                return Err(format!(
                    "phantom box {i}: value must be finite, got {}",
                    b.value
                ));
            }
            if (0..3).any(|a| b.from[a] >= b.to[a] || b.to[a] > self.size[a]) {
                return Err(format!(
                    "phantom box {i}: from {:?} to {:?} must be non-empty and inside the size {:?}",
                    b.from, b.to, self.size
                ));
            }
        }
        Ok(())
    }

    /// Its name as a volume name, e.g. `phantom_32x32x32`.
    pub fn name(&self) -> String {
        let [x, y, z] = self.size;
        format!("phantom_{x}x{y}x{z}")
    }

    /// The volume (checked first).
    pub fn volume(&self) -> Result<Volume, String> {
        self.check()?;
        let [w, h, d] = self.size.map(|s| s as usize);
        let mut v = vec![self.background; w * h * d];
        for b in &self.boxes {
            for z in b.from[2] as usize..b.to[2] as usize {
                for y in b.from[1] as usize..b.to[1] as usize {
                    let row = (z * h + y) * w;
                    v[row + b.from[0] as usize..row + b.to[0] as usize].fill(b.value);
                }
            }
        }
        Volume::new(self.name(), self.size, 1, [1.0; 3], VoxelData::F32(v))
            .map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block_and_wall() -> Phantom {
        Phantom {
            size: [32, 32, 32],
            background: 0.0,
            boxes: vec![
                PhantomBox {
                    from: [10, 10, 5],
                    to: [22, 22, 10],
                    value: 1.0,
                },
                PhantomBox {
                    from: [0, 0, 20],
                    to: [32, 32, 24],
                    value: 1.0,
                },
            ],
        }
    }

    #[test]
    fn boxes_paint_their_voxels_in_order() {
        let mut p = block_and_wall();
        p.boxes.push(PhantomBox {
            from: [0, 0, 21],
            to: [4, 4, 22],
            value: 0.5,
        });
        let v = p.volume().unwrap();
        assert_eq!(v.name, "phantom_32x32x32");
        assert_eq!(v.range, [0.0, 1.0]);
        assert_eq!(v.scalar(15, 15, 7), 1.0);
        assert_eq!(v.scalar(15, 15, 10), 0.0);
        assert_eq!(v.scalar(9, 15, 7), 0.0);
        assert_eq!(v.scalar(31, 31, 23), 1.0);
        assert_eq!(v.scalar(31, 31, 24), 0.0);
        assert_eq!(v.scalar(3, 3, 21), 0.5, "the later box paints over");
        let ones = (0..32 * 32 * 32)
            .filter(|&i| v.data.get_f64(i) == Some(1.0))
            .count();
        assert_eq!(ones, 12 * 12 * 5 + 32 * 32 * 4 - 16);
    }

    #[test]
    fn bad_phantoms_are_refused_with_the_cause() {
        let mut p = block_and_wall();
        p.size = [32, 1, 32];
        assert!(p.check().unwrap_err().contains("2–512"));
        let mut p = block_and_wall();
        p.boxes[0].to = [22, 22, 40];
        assert!(p.volume().unwrap_err().contains("phantom box 0"));
        let mut p = block_and_wall();
        p.boxes[1].from[0] = 32;
        assert!(p.check().unwrap_err().contains("non-empty"));
        let mut p = block_and_wall();
        p.boxes[1].value = f32::NAN;
        assert!(p.check().unwrap_err().contains("finite"));
        let mut p = block_and_wall();
        p.background = f32::INFINITY;
        assert!(p.check().unwrap_err().contains("background"));
    }
}
