use super::*;
use vwb_render::volume::{Volume, VoxelData};

fn twin(interleaved: bool, seed: u32) -> JitterTwin {
    JitterTwin {
        interleaved,
        amount: 1.0,
        seed,
    }
}

/// Interleaved: every 4×4 block of pixels holds each of the 16 offsets (k + ½)/16 once,
/// whatever the seed and wherever the block starts.
#[test]
fn interleaved_offsets_stratify_each_4x4_block() {
    for seed in [0, 1, 7, 123] {
        let t = twin(true, seed);
        for (bx, by) in [(0, 0), (4, 8), (1, 2), (13, 6)] {
            let mut seen: Vec<u32> = (0..16)
                .map(|i| (t.offset([bx + i % 4, by + i / 4]) * 16.0 - 0.5).round() as u32)
                .collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..16).collect::<Vec<u32>>(), "seed {seed} block ({bx},{by})");
        }
    }
    // the classic matrix for seed 0
    let t = twin(true, 0);
    let row0: Vec<f64> = (0..4).map(|x| t.offset([x, 0]) * 16.0 - 0.5).collect();
    assert_eq!(row0, vec![0.0, 8.0, 2.0, 10.0]);
}

/// Hash: offsets in [0,1), near uniform over a 64×64 image (each sixteenth within 25 %
/// of its share), different for another seed, and the same for the same seed.
#[test]
fn hashed_offsets_are_uniform_and_seeded() {
    let (a, b) = (twin(false, 1), twin(false, 2));
    let mut bins = [0u32; 16];
    let mut differ = 0;
    for y in 0..64 {
        for x in 0..64 {
            let u = a.offset([x, y]);
            assert!((0.0..1.0).contains(&u), "{u}");
            bins[(u * 16.0) as usize] += 1;
            assert_eq!(u, twin(false, 1).offset([x, y]));
            differ += (u != b.offset([x, y])) as u32;
        }
    }
    for (i, n) in bins.iter().enumerate() {
        assert!((192..=320).contains(n), "bin {i}: {n} of 4096");
    }
    assert!(differ > 4000, "{differ}");
}

/// `setup` gives amount·(u − ½) for the pixel under uv, and `sample` moves the sample by
/// that fraction of its step along the ray; amount 0 leaves it alone.
#[test]
fn the_ray_record_moves_samples_along_the_ray() {
    let t = JitterTwin {
        interleaved: true,
        amount: 0.5,
        seed: 0,
    };
    let ray = CpuRay {
        origin: glam::DVec3::ZERO,
        dir: glam::DVec3::Z,
        uv: DVec2::new(1.5 / 8.0, 0.5 / 8.0), // pixel (1, 0): offset 8.5/16
        size: DVec2::splat(8.0),
    };
    let data = (0..64).map(|i| (i * 4) as u8).collect();
    let volume = Volume::new("ramp", [4, 4, 4], 1, [1.0; 3], VoxelData::U8(data)).unwrap();
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(&volume, &scalars);
    let r = t.setup(&ctx, &ray);
    assert!((r.x - 0.5 * (8.5 / 16.0 - 0.5)).abs() < 1e-15, "{r}");
    let mut s = CpuSample {
        pos: glam::DVec3::ZERO,
        tex: glam::DVec3::splat(0.5),
        ray_dir: glam::DVec3::Z,
        step: 0.2,
        ray_record: r,
        ..Default::default()
    };
    let before = s;
    t.sample(&ctx, &mut s);
    assert!((s.pos.z - r.x * 0.2).abs() < 1e-15, "{:?}", s.pos);
    assert_eq!(s.value, ctx.value(s.tex));
    let mut still = before;
    still.ray_record = DVec4::ZERO;
    t.sample(&ctx, &mut still);
    assert_eq!(still, CpuSample { ray_record: DVec4::ZERO, ..before });
}
