//! The whole-frame march in parts, for llvmpipe's loop limiter.
//!
//! gallivm (llvmpipe's shader compiler) gives each shader invocation, or rather each
//! SIMD vector of 8 of them, one counter of 65 535 loop iterations over all its loops;
//! once it runs out, every loop ends after one more pass of its body, silently. A ray
//! of the whole-frame march (`march` in shaders/slice.wgsl) costs one or two per slice
//! (the loop that crosses empty bricks counts once per iteration of the march even
//! where no lane enters it), and its plugins' loops theirs per sample: flow.lic3d
//! integrating on the fly spends 2·(L/h + 1) per integral and one integral per read of
//! its scalar (7 a sample under central differences), so at its longest streamlines a
//! ray ran out after a few dozen samples and the image was wrong where nothing said so.
//!
//! So on a CPU device the renderer dispatches a frame's slices in parts of at most
//! [`part_slices`] each: every part marches its slices of each ray from the colour the
//! part before left in the accumulation buffer (`MarchPart` in shaders/slice.wgsl).
//! Between samples a ray carries nothing but that colour (the raster backend evaluates
//! each sample on its own), so the image is the whole march's bit for bit
//! (tests/integration/render.rs, `march_parts_render_the_whole_march`). The budget comes from what
//! the plugins declare ([`crate::plugin::Plugin::loop_iterations`]); what that
//! underestimates (a user plugin's loops), the shader notes (`note_loop_limit`: a loop
//! of two iterations that ends after one), and [`crate::renderer::Renderer::render`]
//! renders the frame again in parts of a quarter of its longest, down to one slice.
//! GPUs have no such limit and march each frame in one dispatch.

use crate::plugin::LoopIterations;

/// Loop iterations llvmpipe gives one shader invocation (gallivm's
/// `LP_MAX_TGSI_LOOP_ITERATIONS`).
pub const LOOP_LIMIT: u32 = 65_535;

/// What one part may spend of [`LOOP_LIMIT`]: the rest is room for the entry point's
/// other loops (the tile row's spread, the probe's two).
pub const LOOP_BUDGET: u32 = 60_000;

/// Loop iterations the march itself costs per slice (the nested empty-brick loop's
/// one per iteration of the march besides the march's own).
pub const MARCH_PER_SLICE: u32 = 2;

/// Reads of the shading scalar (`shading_value`) per sample that the gradient
/// estimators called in a composed module make: 26 per call of `gradient_sobel`, 6 per
/// call of `gradient_central` (their definitions aside); none for the precomputed
/// estimators (their pre-pass reads it, once per voxel).
pub fn scalar_reads(source: &str) -> u32 {
    let calls = |name: &str| {
        let all = source.matches(&format!("{name}(")).count();
        let defined = source.matches(&format!("fn {name}(")).count();
        all.saturating_sub(defined) as u32
    };
    calls("gradient_sobel")
        .saturating_mul(26)
        .saturating_add(calls("gradient_central").saturating_mul(6))
}

/// The loop iterations one sample of a stack costs: its plugins' `sample` ones, and
/// their `scalar` ones once for every read of the shading scalar that its estimators
/// make (`reads`).
pub fn per_sample(loops: &[LoopIterations], reads: u32) -> u32 {
    let sample = loops.iter().fold(0u32, |a, l| a.saturating_add(l.sample));
    let scalar = loops.iter().fold(0u32, |a, l| a.saturating_add(l.scalar));
    sample.saturating_add(scalar.saturating_mul(reads))
}

/// The most slices one part may hold for samples of `per_sample` loop iterations.
pub fn part_slices(per_sample: u32) -> u32 {
    (LOOP_BUDGET / MARCH_PER_SLICE.saturating_add(per_sample)).max(1)
}

/// The parts [start, end) of a frame of `count` slices in parts of at most `part`
/// slices, the last one's end 0 (to the end of every ray): `[[0, 0]]`, one part, where
/// the frame fits.
pub fn parts(count: u32, part: u32) -> Vec<[u32; 2]> {
    let part = part.max(1);
    if count <= part {
        return vec![[0, 0]];
    }
    let n = count.div_ceil(part);
    (0..n)
        .map(|j| [j * part, if j + 1 == n { 0 } else { (j + 1) * part }])
        .collect()
}

/// Bytes between two parts' uniforms (the uniform offset alignment wgpu guarantees).
const STRIDE: u64 = 256;

/// A part's `MarchPart` uniform: start, end, the probe's 2, a pad word.
fn part_words(p: [u32; 2]) -> [u32; 4] {
    [p[0], p[1], 2, 0]
}

/// The renderer's buffers for marching in parts and noting the loop limiter.
pub struct MarchState {
    /// The uniform of a frame marched in one part.
    whole: wgpu::Buffer,
    /// `loop_limit` of shaders/slice.wgsl (one counter), and its readback copy.
    counter: wgpu::Buffer,
    read: wgpu::Buffer,
    /// Slices per part forced by [`crate::renderer::Renderer::set_march_part_slices`].
    pub forced: Option<u32>,
    /// Parts shrunk after the limiter ran out: (compiled stack, per-sample estimate,
    /// most slices a part), each applying while both stay the same ([`MarchState::shrunk`];
    /// an atlas's tiles may hold several estimates); the latest [`SHRINKS_KEPT`].
    shrink: Vec<(usize, u32, u32)>,
}

/// How many shrunk parts [`MarchState`] remembers.
const SHRINKS_KEPT: usize = 16;

impl MarchState {
    pub fn new(device: &wgpu::Device) -> Self {
        use wgpu::util::DeviceExt;
        let whole = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vwb march part (whole frame)"),
            contents: bytemuck::cast_slice(&part_words([0, 0])),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let counter = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vwb loop limit"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let read = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vwb loop limit readback"),
            size: 16,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            whole,
            counter,
            read,
            // a benchmark switch: parts of this many slices on any device
            forced: std::env::var("VWB_MARCH_PART_SLICES")
                .ok()
                .and_then(|v| v.trim().parse::<u32>().ok())
                .map(|n| n.max(1)),
            shrink: Vec::new(),
        }
    }

    /// The most slices a part of a march of the compiled stack `key` with the per-sample
    /// estimate `estimate`, where the limiter made it shrink.
    pub fn shrunk(&self, key: usize, estimate: u32) -> Option<u32> {
        self.shrink
            .iter()
            .find(|(k, e, _)| (*k, *e) == (key, estimate))
            .map(|s| s.2)
    }

    /// Marches of `key` with `estimate` take parts of at most `most` slices from now on.
    pub fn set_shrunk(&mut self, key: usize, estimate: u32, most: u32) {
        self.shrink.retain(|(k, e, _)| (*k, *e) != (key, estimate));
        if self.shrink.len() >= SHRINKS_KEPT {
            self.shrink.remove(0);
        }
        self.shrink.push((key, estimate, most));
    }

    /// Group 3 of the compute entry points, once per part of `parts` (the eye buffer
    /// `view`, its accumulation buffer `accum`, the part's uniform, the counter).
    pub fn groups(
        &self,
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        view: &wgpu::TextureView,
        accum: &wgpu::Buffer,
        parts: &[[u32; 2]],
    ) -> Vec<wgpu::BindGroup> {
        use wgpu::util::DeviceExt;
        let uniforms = (parts.len() > 1).then(|| {
            let mut data = vec![0u8; parts.len() * STRIDE as usize];
            for (j, p) in parts.iter().enumerate() {
                let at = j * STRIDE as usize;
                data[at..at + 16].copy_from_slice(bytemuck::cast_slice(&part_words(*p)));
            }
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vwb march parts"),
                contents: &data,
                usage: wgpu::BufferUsages::UNIFORM,
            })
        });
        (0..parts.len())
            .map(|j| {
                let part = match &uniforms {
                    Some(b) => wgpu::BufferBinding {
                        buffer: b,
                        offset: j as u64 * STRIDE,
                        size: wgpu::BufferSize::new(16),
                    },
                    None => wgpu::BufferBinding {
                        buffer: &self.whole,
                        offset: 0,
                        size: wgpu::BufferSize::new(16),
                    },
                };
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("vwb group 3"),
                    layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: wgpu::BindingResource::TextureView(view),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: accum.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: wgpu::BindingResource::Buffer(part),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: self.counter.as_entire_binding(),
                        },
                    ],
                })
            })
            .collect()
    }

    /// Clears the counter (before a frame's first march).
    pub fn clear(&self, enc: &mut wgpu::CommandEncoder) {
        enc.clear_buffer(&self.counter, 0, None);
    }

    /// Copies the counter for [`MarchState::read`] (after the frame's march).
    pub fn copy_out(&self, enc: &mut wgpu::CommandEncoder) {
        enc.copy_buffer_to_buffer(&self.counter, 0, &self.read, 0, 16);
    }

    /// The invocations of the last copied frame that ran out of loop iterations.
    pub fn read(&self, gpu: &crate::gpu::GpuContext) -> u32 {
        let bytes = super::read_buffer(gpu, &self.read, 4);
        u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Parts tile [0, count) in order without gaps, none longer than asked, the last
    /// one's end 0; a frame that fits is one part [0, 0).
    #[test]
    fn parts_tile_the_slices() {
        assert_eq!(parts(10, 10), vec![[0, 0]]);
        assert_eq!(parts(0, 3), vec![[0, 0]]);
        assert_eq!(parts(10, 4), vec![[0, 4], [4, 8], [8, 0]]);
        assert_eq!(parts(12, 4), vec![[0, 4], [4, 8], [8, 0]]);
        assert_eq!(parts(3, 0), vec![[0, 1], [1, 2], [2, 0]]);
        for (count, part) in [(60_001u32, 30_000u32), (1 << 20, 7), (65_536, 65_535)] {
            let p = parts(count, part);
            assert_eq!(p.len() as u32, count.div_ceil(part));
            for w in p.windows(2) {
                assert_eq!(w[0][1], w[1][0]);
                assert!(w[0][1] - w[0][0] <= part);
            }
            let last = p[p.len() - 1];
            assert_eq!(last[1], 0);
            assert!(count - last[0] <= part);
        }
    }

    /// The budget: two iterations per slice alone, 30 000 slices a part; a plugin's
    /// loops shrink it; a sample beyond the budget still gets one slice per part.
    #[test]
    fn part_size_follows_the_loops() {
        assert_eq!(part_slices(0), 30_000);
        assert_eq!(part_slices(38), 1_500);
        assert_eq!(part_slices(u32::MAX), 1);
        let lic = LoopIterations {
            sample: 36,
            scalar: 36,
        };
        assert_eq!(
            per_sample(&[lic, LoopIterations::default()], 6),
            36 + 36 * 6
        );
        assert_eq!(per_sample(&[lic, lic], 0), 72);
        assert_eq!(
            scalar_reads("return cut_gradient(gradient_sobel(tex));"),
            26
        );
        assert_eq!(
            scalar_reads("return cut_gradient(gradient_central(tex));"),
            6
        );
        let module = "fn gradient_central(tex: vec3<f32>) -> vec3<f32> { }\n\
                      fn gradient_sobel(tex: vec3<f32>) -> vec3<f32> { }\n\
                      fn p1_gradient_at(t: vec3<f32>) { return gradient_central(t); }\n\
                      fn p2_gradient_at(t: vec3<f32>) { return gradient_central(t); }";
        assert_eq!(scalar_reads(module), 12);
        assert_eq!(
            scalar_reads("textureSampleLevel(gradient, linear_clamp, tex, 0.0)"),
            0
        );
        assert!(part_slices(per_sample(&[lic], 26)) * (2 + 36 + 36 * 26) <= LOOP_BUDGET);
    }
}
