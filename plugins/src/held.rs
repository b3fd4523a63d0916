//! Which content each of a plugin's textures holds, so that a parameter change that
//! leaves the content as it is uploads nothing (the clipping mesh's distance grid, the
//! Blinn–Phong lighting table). Textures are told apart by their hash.

use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::sync::{Mutex, OnceLock};

/// A record of the content key each texture holds; one `static` per kind of content.
pub struct Held(OnceLock<Mutex<HashMap<u64, u64>>>);

impl Held {
    pub const fn new() -> Self {
        Self(OnceLock::new())
    }

    fn map(&self) -> &Mutex<HashMap<u64, u64>> {
        self.0.get_or_init(Default::default)
    }

    /// Whether `t` holds the content `key`.
    pub fn holds(&self, t: &wgpu::Texture, key: u64) -> bool {
        self.map()
            .lock()
            .is_ok_and(|m| m.get(&texture_id(t)) == Some(&key))
    }

    /// Records that `t` now holds the content `key`.
    pub fn record(&self, t: &wgpu::Texture, key: u64) {
        if let Ok(mut m) = self.map().lock() {
            m.insert(texture_id(t), key);
        }
    }
}

impl Default for Held {
    fn default() -> Self {
        Self::new()
    }
}

fn texture_id(t: &wgpu::Texture) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    t.hash(&mut h);
    h.finish()
}
