//! Seeded, counter-based random numbers: splitmix64 of (seed, index), so that results
//! do not depend on thread order (Monte-Carlo references, noise volumes).

/// splitmix64's finaliser: a well-mixed 64-bit hash of `z`.
pub fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A splitmix64 stream.
#[derive(Debug, Clone)]
pub struct Rng(pub u64);

impl Rng {
    /// The stream of `seed` at position `index` (e.g. a voxel or a pixel).
    pub fn at(seed: u64, index: u64) -> Self {
        Self(mix(seed ^ mix(index)))
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 = mix(self.0);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u = self.uniform().max(f64::MIN_POSITIVE);
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// A xorshift64 stream (Marsaglia 2003): sequential and cheap, for fixed sequences
/// where a counter-based stream is not needed (test volumes, sample patterns, one
/// stream per pixel).
#[derive(Debug, Clone)]
pub struct XorShift(pub u64);

impl XorShift {
    /// The next state (never 0 from a state that is not 0).
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_and_normal_have_their_moments() {
        let mut r = Rng::at(7, 0);
        let n = 200_000;
        let (mut s, mut s2, mut g, mut g2) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..n {
            let u = r.uniform();
            assert!((0.0..1.0).contains(&u));
            s += u;
            s2 += u * u;
            let x = r.normal();
            g += x;
            g2 += x * x;
        }
        let n = n as f64;
        assert!((s / n - 0.5).abs() < 0.005 && (s2 / n - 1.0 / 3.0).abs() < 0.005);
        assert!((g / n).abs() < 0.01 && (g2 / n - 1.0).abs() < 0.02);
        // deterministic per (seed, index)
        assert_eq!(Rng::at(3, 9).uniform(), Rng::at(3, 9).uniform());
        assert_ne!(Rng::at(3, 9).uniform(), Rng::at(3, 10).uniform());
    }
}
