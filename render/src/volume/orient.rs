//! One orientation for every format: the voxel axes of a volume are permuted and
//! flipped so that +x points to the patient's left, +y to posterior and +z to superior
//! (LPS, the DICOM, ITK and NRRD `left-posterior-superior` convention), whatever order
//! the file stores them in. The renderer draws voxels in index order, so the same
//! anatomy from NIfTI (RAS world), MetaImage or DICOM lands in the same place: left stays
//! left.
//!
//! Only axis permutations and flips are applied (no resampling): an oblique volume is
//! snapped to its nearest axes and the loader reports by how much.

/// A direction matrix: `columns[a]` is the world direction (LPS) of voxel axis `a`.
pub type Directions = [[f64; 3]; 3];

/// How the stored axes map onto the canonical ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reorder {
    /// `to[a]`: the canonical axis that stored axis `a` becomes.
    pub to: [usize; 3],
    /// `flip[a]`: stored axis `a` runs against its canonical axis.
    pub flip: [bool; 3],
}

impl Reorder {
    pub const IDENTITY: Reorder = Reorder {
        to: [0, 1, 2],
        flip: [false; 3],
    };

    pub fn is_identity(&self) -> bool {
        *self == Self::IDENTITY
    }

    /// The canonical dims (or spacing) from the stored ones.
    pub fn apply<T: Copy>(&self, stored: [T; 3]) -> [T; 3] {
        let mut out = stored;
        for a in 0..3 {
            out[self.to[a]] = stored[a];
        }
        out
    }

    /// Stored samples (`components` interleaved, x fastest) in canonical order.
    pub fn samples<T: Copy>(&self, data: &[T], dims: [u32; 3], components: usize) -> Vec<T> {
        if self.is_identity() {
            return data.to_vec();
        }
        let d = dims.map(|x| x as usize);
        let out_dims = self.apply(d);
        let mut out = Vec::with_capacity(data.len());
        // walk the output in order and find each voxel's stored index
        let mut stored = [0usize; 3];
        let from: [usize; 3] = {
            let mut f = [0; 3];
            for a in 0..3 {
                f[self.to[a]] = a;
            }
            f
        };
        for z in 0..out_dims[2] {
            for y in 0..out_dims[1] {
                for x in 0..out_dims[0] {
                    let o = [x, y, z];
                    for (c, &a) in from.iter().enumerate() {
                        stored[a] = if self.flip[a] { d[a] - 1 - o[c] } else { o[c] };
                    }
                    let i = ((stored[2] * d[1] + stored[1]) * d[0] + stored[0]) * components;
                    out.extend_from_slice(&data[i..i + components]);
                }
            }
        }
        out
    }
}

/// The permutation and flips that bring `dirs` closest to LPS, and the largest angle
/// (degrees) between a stored axis and the canonical axis it is snapped to (0 for a
/// volume aligned with the axes). Columns need not be unit length; a zero or
/// non-finite matrix gives the identity.
pub fn reorder_for(dirs: &Directions) -> (Reorder, f64) {
    let unit: Vec<[f64; 3]> = dirs
        .iter()
        .map(|c| {
            let n = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            if n > 0.0 && n.is_finite() {
                c.map(|v| v / n)
            } else {
                [f64::NAN; 3]
            }
        })
        .collect();
    if unit.iter().flatten().any(|v| !v.is_finite()) {
        return (Reorder::IDENTITY, 0.0);
    }
    // greedy: the largest |component| claims its canonical axis first
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (a, u) in unit.iter().enumerate() {
        for (w, v) in u.iter().enumerate() {
            pairs.push((v.abs(), a, w));
        }
    }
    pairs.sort_by(|p, q| q.0.total_cmp(&p.0));
    let mut to = [usize::MAX; 3];
    let mut taken = [false; 3];
    for (_, a, w) in pairs {
        if to[a] == usize::MAX && !taken[w] {
            to[a] = w;
            taken[w] = true;
        }
    }
    let mut flip = [false; 3];
    let mut worst: f64 = 0.0;
    for a in 0..3 {
        let c = unit[a][to[a]];
        flip[a] = c < 0.0;
        worst = worst.max(c.abs().clamp(0.0, 1.0).acos().to_degrees());
    }
    (Reorder { to, flip }, worst)
}

/// RAS directions (NIfTI world) as LPS.
pub fn ras_to_lps(dirs: &Directions) -> Directions {
    dirs.map(|c| [-c[0], -c[1], c[2]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_aligned_permutations_and_flips() {
        let (r, angle) = reorder_for(&[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        assert!(r.is_identity());
        assert_eq!(angle, 0.0);
        // stored x runs right-to-left in RAS = +L in LPS: no flip; stored y is anterior
        let ras = [[-2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 3.0]];
        let (r, _) = reorder_for(&ras_to_lps(&ras));
        assert_eq!(r.to, [0, 1, 2]);
        assert_eq!(r.flip, [false, true, false]);
        // sagittal stacks: stored x is A→P, y is S→I, z is R→L
        let (r, _) = reorder_for(&[[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]);
        assert_eq!(r.to, [1, 2, 0]);
        assert_eq!(r.flip, [false, true, false]);
        assert_eq!(r.apply([10, 20, 30]), [30, 10, 20]);
    }

    #[test]
    fn oblique_volumes_snap_and_report_the_angle() {
        let t = 10f64.to_radians();
        let (r, angle) = reorder_for(&[
            [t.cos(), t.sin(), 0.0],
            [-t.sin(), t.cos(), 0.0],
            [0.0, 0.0, 1.0],
        ]);
        assert!(r.is_identity());
        assert!((angle - 10.0).abs() < 1e-9);
        let (r, _) = reorder_for(&[[0.0; 3], [0.0; 3], [0.0; 3]]);
        assert!(r.is_identity());
    }

    #[test]
    fn samples_move_with_their_axes() {
        // 3×2×1, two components; value = 10·x + y, component c adds 100·c
        let dims = [3, 2, 1];
        let mut data = Vec::new();
        for y in 0..2 {
            for x in 0..3 {
                for c in 0..2 {
                    data.push(10 * x + y + 100 * c);
                }
            }
        }
        let r = Reorder {
            to: [1, 0, 2],
            flip: [true, false, false],
        };
        let out = r.samples(&data, dims, 2);
        assert_eq!(r.apply(dims), [2, 3, 1]);
        // output (x', y') = (stored y, 2 − stored x)
        let at = |x: usize, y: usize, c: usize| out[(y * 2 + x) * 2 + c];
        assert_eq!(at(0, 0, 0), 20);
        assert_eq!(at(1, 0, 0), 21);
        assert_eq!(at(0, 2, 1), 100);
        assert_eq!(at(1, 1, 1), 111);
    }
}
