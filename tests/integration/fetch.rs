//! Sample cost of the ways a shader can read a volume (issue 23, item 4): a 3D texture
//! sampled with the hardware's trilinear filter, against a storage buffer read with
//! eight loads and a trilinear interpolation written out in the shader, and against
//! layouts that bring the eight values in fewer filtered calls (the z-pairs of
//! `VolumeFormat::R32FloatPairs`: one bilinear sample and a mix in z).

use std::time::Instant;

use crate::common::{bench_doc, gpu, read_back};

const DIMS: [u32; 3] = [256, 256, 108];
const SIDE: u32 = 512;
const STEPS: u32 = 329;

/// One ray per pixel, orthographic, marched in STEPS samples along a fixed oblique
/// direction through the unit cube; front-to-back compositing with α = 0.02·v (no
/// early termination, so every variant takes every sample). `GRADIENT` adds the six
/// reads of a central-difference gradient per sample, as shading does.
#[derive(Clone, Copy, PartialEq)]
enum Fetch {
    /// `textureSampleLevel` with a linear sampler (what the renderer does).
    Sampler,
    /// Eight `textureLoad`s of the same texture, interpolated in the shader.
    Loads,
    /// Eight loads of an `array<f32>` storage buffer, interpolated in the shader.
    Buffer,
    /// Four loads of an `array<vec2<f32>>` holding each voxel with its +x neighbour
    /// (twice the memory), interpolated in the shader.
    Pairs,
    /// One `textureSampleLevel` of an rg32float 2D array texture (layer z holds each
    /// voxel with its +z neighbour, twice the memory) through the linear sampler: the
    /// sampler's bilinear filter interpolates both layers at once, the shader mixes
    /// them in z.
    Layers,
    /// Two nearest-filtered samples of an rgba32float 3D texture holding each voxel's
    /// 2 × 2 block in x and y (four times the memory), at z and z + 1, interpolated in
    /// the shader.
    Quads,
    /// Two bilinear samples of the same r32float data as a 2D array texture (layers z
    /// and z + 1; the same memory), mixed in z in the shader.
    Slices,
    /// The trilinear sampler on an rgba32float 3D texture (the precomputed gradient
    /// with the value in w, what shading reads on CPU devices).
    Rgba,
    /// Two bilinear samples of the same rgba32float texels as a 2D array texture.
    RgbaSlices,
}

impl Fetch {
    const ALL: [Fetch; 7] = [
        Fetch::Sampler,
        Fetch::Loads,
        Fetch::Buffer,
        Fetch::Pairs,
        Fetch::Layers,
        Fetch::Quads,
        Fetch::Slices,
    ];

    fn name(self) -> &'static str {
        match self {
            Fetch::Sampler => "texture, sampler",
            Fetch::Loads => "texture, 8 loads",
            Fetch::Buffer => "storage buffer, 8 loads",
            Fetch::Pairs => "storage buffer of x-pairs, 4 loads",
            Fetch::Layers => "2D array of z-pairs, bilinear sampler",
            Fetch::Quads => "texture of 2×2 blocks, 2 nearest samples",
            Fetch::Slices => "2D array, 2 bilinear samples",
            Fetch::Rgba => "rgba32float texture, sampler",
            Fetch::RgbaSlices => "rgba32float 2D array, 2 bilinear samples",
        }
    }
}

const TRILINEAR: &str = "fn value(tex: vec3<f32>) -> f32 {
    let p = tex * vec3<f32>(DIMS) - vec3<f32>(0.5);
    let f = floor(p);
    let w = p - f;
    let i = vec3<i32>(f);
    let c00 = row(i, w.x);
    let c10 = row(i + vec3<i32>(0, 1, 0), w.x);
    let c01 = row(i + vec3<i32>(0, 0, 1), w.x);
    let c11 = row(i + vec3<i32>(0, 1, 1), w.x);
    return mix(mix(c00, c10, w.y), mix(c01, c11, w.y), w.z);
}
fn clamped(v: vec3<i32>) -> vec3<u32> {
    return vec3<u32>(clamp(v, vec3<i32>(0), vec3<i32>(DIMS) - vec3<i32>(1)));
}";

/// `value` as two bilinear reads of a 2D array `texture`'s layers z and z + 1
/// (`read`: the value at layer `l`), mixed in z.
fn two_layers(texture: &str, read: &str) -> String {
    format!(
        "fn {texture}_at(tex: vec3<f32>, l: u32) -> f32 {{
    return {read};
}}
fn value(tex: vec3<f32>) -> f32 {{
    let z = tex.z * f32(DIMS.z) - 0.5;
    let k = floor(z);
    let a = {texture}_at(tex, u32(clamp(k, 0.0, f32(DIMS.z - 1u))));
    let b = {texture}_at(tex, u32(clamp(k + 1.0, 0.0, f32(DIMS.z - 1u))));
    return mix(a, b, z - k);
}}"
    )
}

/// How a sample's value becomes a colour.
#[derive(Clone, Copy, PartialEq)]
enum Lut {
    /// α = 0.02·v, colour v: no table.
    None,
    /// A 256×1 rgba32float 2D texture through the linear sampler (what classify.tf1d
    /// did before session 56).
    Texture,
    /// The same 256 entries as a 1D texture through the linear sampler (what
    /// classify.tf1d does).
    Texture1d,
    /// The same 256 entries in a storage buffer, two loads interpolated in the shader.
    Storage,
    /// The same 256 entries in a uniform buffer, two loads interpolated in the shader.
    Uniform,
}

impl Lut {
    fn name(self) -> &'static str {
        match self {
            Lut::None => "none",
            Lut::Texture => "256×1 2D texture, sampler",
            Lut::Texture1d => "256 1D texture, sampler",
            Lut::Storage => "storage buffer, 2 loads",
            Lut::Uniform => "uniform buffer, 2 loads",
        }
    }
}

/// The transfer function of the `Lut` variants: rgb (x, x², 1 − x), α = 0.02·x.
fn lut_entries() -> Vec<f32> {
    (0..256)
        .flat_map(|i| {
            let x = i as f32 / 255.0;
            [x, x * x, 1.0 - x, 0.02 * x]
        })
        .collect()
}

#[derive(Clone, Copy)]
struct Variant {
    fetch: Fetch,
    gradient: bool,
    lut: Lut,
}

/// One ray per pixel, orthographic, marched in STEPS samples along a fixed oblique
/// direction through the unit cube; front-to-back compositing (no early termination,
/// so every variant takes every sample). `gradient` adds the six reads of a
/// central-difference gradient per sample, as shading does; `lut` classifies.
fn shader(
    Variant {
        fetch,
        gradient,
        lut,
    }: Variant,
) -> String {
    let fetch = match fetch {
        Fetch::Sampler => "fn value(tex: vec3<f32>) -> f32 {
    return textureSampleLevel(vol_tex, lin, tex, 0.0).r;
}"
        .to_string(),
        Fetch::Loads => format!(
            "{TRILINEAR}
fn row(i: vec3<i32>, w: f32) -> f32 {{
    let a = textureLoad(vol_tex, clamped(i), 0).r;
    let b = textureLoad(vol_tex, clamped(i + vec3<i32>(1, 0, 0)), 0).r;
    return mix(a, b, w);
}}"
        ),
        Fetch::Buffer => format!(
            "{TRILINEAR}
fn index(c: vec3<u32>) -> u32 {{
    return c.x + DIMS.x * (c.y + DIMS.y * c.z);
}}
fn row(i: vec3<i32>, w: f32) -> f32 {{
    return mix(vol[index(clamped(i))], vol[index(clamped(i + vec3<i32>(1, 0, 0)))], w);
}}"
        ),
        Fetch::Pairs => format!(
            "{TRILINEAR}
fn row(i: vec3<i32>, w: f32) -> f32 {{
    // pairs[x] = (v[x], v[x + 1]); x = −1 reads (v[0], v[0]) through x = 0's w = 0.
    let c = clamped(i);
    let p = pairs[c.x + DIMS.x * (c.y + DIMS.y * c.z)];
    return mix(p.x, p.y, select(w, 0.0, i.x < 0));
}}"
        ),
        Fetch::Layers => "fn value(tex: vec3<f32>) -> f32 {
    // Layer k holds (v[k], v[k + 1]); below the first layer's centre w = 0 reads v[0].
    let z = tex.z * f32(DIMS.z) - 0.5;
    let k = floor(z);
    let layer = u32(clamp(k, 0.0, f32(DIMS.z - 1u)));
    let b = textureSampleLevel(layers, lin, tex.xy, layer, 0.0);
    return mix(b.x, b.y, select(z - k, 0.0, k < 0.0));
}"
        .to_string(),
        Fetch::Quads => "fn value(tex: vec3<f32>) -> f32 {
    let p = tex * vec3<f32>(DIMS) - vec3<f32>(0.5);
    let f = floor(p);
    let w = select(p - f, vec3<f32>(0.0), f < vec3<f32>(0.0));
    let d = 1.0 / vec3<f32>(DIMS);
    let c = (max(f, vec3<f32>(0.0)) + 0.5) * d;
    let q0 = textureSampleLevel(quads, near, c, 0.0);
    let q1 = textureSampleLevel(quads, near, c + vec3<f32>(0.0, 0.0, d.z), 0.0);
    let a = mix(mix(q0.x, q0.y, w.x), mix(q0.z, q0.w, w.x), w.y);
    let b = mix(mix(q1.x, q1.y, w.x), mix(q1.z, q1.w, w.x), w.y);
    return mix(a, b, w.z);
}"
        .to_string(),
        Fetch::Slices => two_layers(
            "slices",
            "textureSampleLevel(slices, lin, tex.xy, l, 0.0).r",
        ),
        Fetch::Rgba => "fn value(tex: vec3<f32>) -> f32 {
    return dot(textureSampleLevel(rgba, lin, tex, 0.0), vec4<f32>(0.25));
}"
        .to_string(),
        Fetch::RgbaSlices => two_layers(
            "rgba_slices",
            "dot(textureSampleLevel(rgba_slices, lin, tex.xy, l, 0.0), vec4<f32>(0.25))",
        ),
    };
    let sample = if gradient {
        "let d = 1.0 / vec3<f32>(DIMS);
        let g = vec3<f32>(
            value(p + vec3<f32>(d.x, 0.0, 0.0)) - value(p - vec3<f32>(d.x, 0.0, 0.0)),
            value(p + vec3<f32>(0.0, d.y, 0.0)) - value(p - vec3<f32>(0.0, d.y, 0.0)),
            value(p + vec3<f32>(0.0, 0.0, d.z)) - value(p - vec3<f32>(0.0, 0.0, d.z)));
        let lit = abs(dot(normalize(g + vec3<f32>(1e-6)), vec3<f32>(0.48, 0.64, 0.6)));
        let v = value(p) * (0.2 + 0.8 * lit);"
    } else {
        "let v = value(p);"
    };
    let classify = match lut {
        Lut::None => "let c = vec4<f32>(v, v, v, 0.02 * v);",
        Lut::Texture => {
            "let c = textureSampleLevel(lut_tex, lin, vec2<f32>((clamp(v, 0.0, 1.0) * 255.0 + 0.5) / 256.0, 0.5), 0.0);"
        }
        Lut::Texture1d => {
            "let c = textureSampleLevel(lut_1d, lin, (clamp(v, 0.0, 1.0) * 255.0 + 0.5) / 256.0, 0.0);"
        }
        Lut::Storage => {
            "let x = clamp(v, 0.0, 1.0) * 255.0;
        let i = u32(x);
        let c = mix(lut_buf[i], lut_buf[min(i + 1u, 255u)], x - f32(i));"
        }
        Lut::Uniform => {
            "let x = clamp(v, 0.0, 1.0) * 255.0;
        let i = u32(x);
        let c = mix(lut_uni[i], lut_uni[min(i + 1u, 255u)], x - f32(i));"
        }
    };
    format!(
        "const DIMS = vec3<u32>({}u, {}u, {}u);
const SIDE: u32 = {SIDE}u;
const STEPS: u32 = {STEPS}u;
@group(0) @binding(0) var vol_tex: texture_3d<f32>;
@group(0) @binding(1) var lin: sampler;
@group(0) @binding(2) var<storage, read> vol: array<f32>;
@group(0) @binding(3) var<storage, read_write> out: array<f32>;
@group(0) @binding(4) var<storage, read> pairs: array<vec2<f32>>;
@group(0) @binding(5) var lut_tex: texture_2d<f32>;
@group(0) @binding(6) var<storage, read> lut_buf: array<vec4<f32>>;
@group(0) @binding(7) var<uniform> lut_uni: array<vec4<f32>, 256>;
@group(0) @binding(8) var lut_1d: texture_1d<f32>;
@group(0) @binding(9) var layers: texture_2d_array<f32>;
@group(0) @binding(10) var quads: texture_3d<f32>;
@group(0) @binding(11) var near: sampler;
@group(0) @binding(12) var slices: texture_2d_array<f32>;
@group(0) @binding(13) var rgba: texture_3d<f32>;
@group(0) @binding(14) var rgba_slices: texture_2d_array<f32>;
{fetch}
@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {{
    if (id.x >= SIDE || id.y >= SIDE) {{ return; }}
    let uv = (vec2<f32>(id.xy) + 0.5) / f32(SIDE);
    let dir = normalize(vec3<f32>(0.3, 0.2, 1.0));
    let start = vec3<f32>(uv * 0.8 + 0.1 - dir.xy * 0.5 / dir.z, 0.0);
    let step = dir / dir.z / f32(STEPS);
    var acc = 0.0;
    var t = 1.0;
    for (var k = 0u; k < STEPS; k++) {{
        let p = start + step * (f32(k) + 0.5);
        {sample}
        {classify}
        acc += t * c.a * (c.r + c.g + c.b);
        t *= 1.0 - c.a;
    }}
    out[id.x + SIDE * id.y] = acc;
}}",
        DIMS[0], DIMS[1], DIMS[2]
    )
}

/// A smooth field with detail at several scales, so that neighbouring rays read
/// neighbouring voxels as a CT scan's would.
fn field() -> Vec<f32> {
    let [nx, ny, nz] = DIMS;
    let mut v = Vec::with_capacity((nx * ny * nz) as usize);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let (x, y, z) = (x as f32, y as f32, z as f32);
                let s = (x * 0.05).sin() * (y * 0.07).cos() + (z * 0.11 + x * 0.013).sin();
                v.push(0.5 + 0.25 * s);
            }
        }
    }
    v
}

fn bytes_of(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Renders every variant in interleaved rounds and writes the medians, the ratios to
/// the first row of each group and the largest difference from its image to the
/// `fetch` block of docs/perf.md (docs/gpu/perf.md on a GPU).
/// Run: `bash bench/ignored_test.sh fetch_benchmark`.
#[test]
#[ignore = "benchmark: bash bench/ignored_test.sh fetch_benchmark"]
fn fetch_benchmark() {
    use wgpu::util::DeviceExt;
    let g = gpu();
    let (device, queue) = (&g.device, &g.queue);
    let data = field();
    let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..Default::default()
    });
    let vol = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("fetch volume buffer"),
        contents: &bytes_of(&data),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let nx = DIMS[0] as usize;
    let paired: Vec<f32> = data
        .iter()
        .enumerate()
        .flat_map(|(i, &v)| {
            let x = i % nx;
            [v, data[if x + 1 < nx { i + 1 } else { i }]]
        })
        .collect();
    let pairs = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("fetch volume pairs"),
        contents: &bytes_of(&paired),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let [nx3, ny3, nz3] = DIMS.map(|d| d as usize);
    let at = |x: usize, y: usize, z: usize| {
        data[x.min(nx3 - 1) + nx3 * (y.min(ny3 - 1) + ny3 * z.min(nz3 - 1))]
    };
    let texture_of = |label, dimension, format, texels: Vec<f32>| {
        device
            .create_texture_with_data(
                queue,
                &wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d {
                        width: DIMS[0],
                        height: DIMS[1],
                        depth_or_array_layers: DIMS[2],
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: if dimension == wgpu::TextureViewDimension::D3 {
                        wgpu::TextureDimension::D3
                    } else {
                        wgpu::TextureDimension::D2
                    },
                    format,
                    usage: wgpu::TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                },
                wgpu::util::TextureDataOrder::LayerMajor,
                &bytes_of(&texels),
            )
            .create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(dimension),
                ..Default::default()
            })
    };
    let view = texture_of(
        "fetch volume",
        wgpu::TextureViewDimension::D3,
        wgpu::TextureFormat::R32Float,
        data.clone(),
    );
    let mut layered = Vec::with_capacity(data.len() * 2);
    let mut blocks = Vec::with_capacity(data.len() * 4);
    for z in 0..nz3 {
        for y in 0..ny3 {
            for x in 0..nx3 {
                layered.extend([at(x, y, z), at(x, y, z + 1)]);
                blocks.extend([
                    at(x, y, z),
                    at(x + 1, y, z),
                    at(x, y + 1, z),
                    at(x + 1, y + 1, z),
                ]);
            }
        }
    }
    let layers = texture_of(
        "fetch z-pairs",
        wgpu::TextureViewDimension::D2Array,
        wgpu::TextureFormat::Rg32Float,
        layered,
    );
    let quads = texture_of(
        "fetch 2x2 blocks",
        wgpu::TextureViewDimension::D3,
        wgpu::TextureFormat::Rgba32Float,
        blocks,
    );
    let near = device.create_sampler(&Default::default());
    let slices = texture_of(
        "fetch slices",
        wgpu::TextureViewDimension::D2Array,
        wgpu::TextureFormat::R32Float,
        data.clone(),
    );
    let quadruple: Vec<f32> = data.iter().flat_map(|&v| [v; 4]).collect();
    let rgba = texture_of(
        "fetch rgba",
        wgpu::TextureViewDimension::D3,
        wgpu::TextureFormat::Rgba32Float,
        quadruple.clone(),
    );
    let rgba_slices = texture_of(
        "fetch rgba slices",
        wgpu::TextureViewDimension::D2Array,
        wgpu::TextureFormat::Rgba32Float,
        quadruple,
    );
    let bytes = (SIDE * SIDE * 4) as u64;
    let out = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("fetch out"),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let read = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("fetch read"),
        size: bytes,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let lut_data = lut_entries();
    let lut_texture = |dimension| {
        device
            .create_texture_with_data(
                queue,
                &wgpu::TextureDescriptor {
                    label: Some("fetch lut"),
                    size: wgpu::Extent3d {
                        width: 256,
                        height: 1,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension,
                    format: wgpu::TextureFormat::Rgba32Float,
                    usage: wgpu::TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                },
                wgpu::util::TextureDataOrder::LayerMajor,
                &bytes_of(&lut_data),
            )
            .create_view(&Default::default())
    };
    let (lut_tex, lut_1d) = (
        lut_texture(wgpu::TextureDimension::D2),
        lut_texture(wgpu::TextureDimension::D1),
    );
    let lut_buffer = |usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("fetch lut buffer"),
            contents: &bytes_of(&lut_data),
            usage,
        })
    };
    let (lut_storage, lut_uniform) = (
        lut_buffer(wgpu::BufferUsages::STORAGE),
        lut_buffer(wgpu::BufferUsages::UNIFORM),
    );
    // Groups of rows; each group's first row is the one its others are compared with.
    let plain = |fetch, gradient| Variant {
        fetch,
        gradient,
        lut: Lut::None,
    };
    let groups: Vec<Vec<Variant>> = vec![
        Fetch::ALL.map(|f| plain(f, false)).to_vec(),
        Fetch::ALL.map(|f| plain(f, true)).to_vec(),
        [Fetch::Rgba, Fetch::RgbaSlices]
            .map(|f| plain(f, false))
            .to_vec(),
        [Lut::Texture, Lut::Texture1d, Lut::Storage, Lut::Uniform]
            .map(|lut| Variant {
                fetch: Fetch::Sampler,
                gradient: false,
                lut,
            })
            .to_vec(),
    ];
    let variants: Vec<Variant> = groups.iter().flatten().copied().collect();
    let pipelines: Vec<(wgpu::ComputePipeline, wgpu::BindGroup)> = variants
        .iter()
        .map(|&v| {
            let label = Some(v.fetch.name());
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label,
                source: wgpu::ShaderSource::Wgsl(shader(v).into()),
            });
            let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label,
                layout: None,
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            });
            // Auto layouts keep only the bindings the shader uses.
            let entry = |binding, resource| wgpu::BindGroupEntry { binding, resource };
            let mut entries = vec![entry(3, out.as_entire_binding())];
            let sampled = matches!(
                v.fetch,
                Fetch::Sampler | Fetch::Layers | Fetch::Slices | Fetch::Rgba | Fetch::RgbaSlices
            ) || matches!(v.lut, Lut::Texture | Lut::Texture1d);
            if sampled {
                entries.push(entry(1, wgpu::BindingResource::Sampler(&sampler)));
            }
            entries.push(match v.fetch {
                Fetch::Sampler | Fetch::Loads => {
                    entry(0, wgpu::BindingResource::TextureView(&view))
                }
                Fetch::Buffer => entry(2, vol.as_entire_binding()),
                Fetch::Pairs => entry(4, pairs.as_entire_binding()),
                Fetch::Layers => entry(9, wgpu::BindingResource::TextureView(&layers)),
                Fetch::Quads => entry(10, wgpu::BindingResource::TextureView(&quads)),
                Fetch::Slices => entry(12, wgpu::BindingResource::TextureView(&slices)),
                Fetch::Rgba => entry(13, wgpu::BindingResource::TextureView(&rgba)),
                Fetch::RgbaSlices => entry(14, wgpu::BindingResource::TextureView(&rgba_slices)),
            });
            if v.fetch == Fetch::Quads {
                entries.push(entry(11, wgpu::BindingResource::Sampler(&near)));
            }
            match v.lut {
                Lut::None => {}
                Lut::Texture => {
                    entries.push(entry(5, wgpu::BindingResource::TextureView(&lut_tex)))
                }
                Lut::Texture1d => {
                    entries.push(entry(8, wgpu::BindingResource::TextureView(&lut_1d)))
                }
                Lut::Storage => entries.push(entry(6, lut_storage.as_entire_binding())),
                Lut::Uniform => entries.push(entry(7, lut_uniform.as_entire_binding())),
            }
            let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label,
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            });
            (pipeline, bind)
        })
        .collect();
    let run = |i: usize, readback: bool| -> (f64, Vec<f32>) {
        let mut enc = device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipelines[i].0);
            pass.set_bind_group(0, &pipelines[i].1, &[]);
            pass.dispatch_workgroups(SIDE.div_ceil(8), SIDE.div_ceil(8), 1);
        }
        if readback {
            enc.copy_buffer_to_buffer(&out, 0, &read, 0, bytes);
        }
        g.wait();
        let start = Instant::now();
        queue.submit([enc.finish()]);
        g.wait();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if !readback {
            return (ms, Vec::new());
        }
        (ms, read_back(g, &read, f32::from_le_bytes))
    };
    let images: Vec<Vec<f32>> = (0..variants.len()).map(|i| run(i, true).1).collect();
    let mut times = vec![Vec::new(); variants.len()];
    for _ in 0..5 {
        for (i, t) in times.iter_mut().enumerate() {
            t.push(run(i, false).0);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let medians: Vec<f64> = times.iter_mut().map(median).collect();
    let samples = (SIDE * SIDE * STEPS) as f64;
    let mut body = format!(
        "Command: `bash bench/ignored_test.sh fetch_benchmark` — {SIDE}², {STEPS} samples per ray through a \
         {}×{}×{} r32float field (every sample taken: no early termination), median of 5 interleaved \
         rounds (wall ms of one dispatch).\n\n- Machine: {}\n- Adapter: {}{}\n\n\
         | volume fetch | reads per sample | classification | ms | ns per sample | time / first row's | max abs. difference from the first row's image |\n\
         |---|---|---|---:|---:|---:|---:|\n",
        DIMS[0],
        DIMS[1],
        DIMS[2],
        vwb_lab::measure::machine(),
        g.describe(),
        std::env::var("LP_NUM_THREADS")
            .map(|t| format!(" (LP_NUM_THREADS={t})"))
            .unwrap_or_default(),
    );
    let mut i = 0;
    for group in &groups {
        let base = i;
        for v in group {
            let diff = images[base]
                .iter()
                .zip(&images[i])
                .map(|(a, b)| (a - b).abs())
                .fold(0f32, f32::max);
            body += &format!(
                "| {} | {} | {} | {:.1} | {:.2} | {:.2} | {:.1e} |\n",
                v.fetch.name(),
                if v.gradient {
                    "7 (value + central gradient)"
                } else {
                    "1"
                },
                v.lut.name(),
                medians[i],
                medians[i] * 1e6 / samples,
                medians[i] / medians[base],
                diff
            );
            assert!(
                images[i].iter().all(|x| x.is_finite() && *x > 0.0),
                "{}: every ray accumulates",
                v.fetch.name()
            );
            assert!(
                diff < 1e-2,
                "{}: differs from the first row by {diff}",
                v.fetch.name()
            );
            i += 1;
        }
        body += "|  |  |  |  |  |  |  |\n";
    }
    body.truncate(body.len() - "|  |  |  |  |  |  |  |\n".len());
    print!("{body}");
    vwb_lab::experiment::write_or_add_block(
        &bench_doc("perf.md"),
        "# Performance on a GPU\n",
        "fetch",
        "## Sample fetch: texture sampler against manual trilinear",
        &body,
    )
    .expect("write the fetch block");
}
