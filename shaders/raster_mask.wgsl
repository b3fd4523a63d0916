// Early ray termination for the raster backend (issue 23, item 2).
//
// Every few slices this pass writes depth 0 where the eye buffer's opacity has reached
// the threshold. The slice pipeline tests depth `less` against a buffer cleared to 1,
// so the later slices' fragments there fail the depth test before they are shaded.
// No colour is written.

// The layout of `Tiles` in shaders/slice.wgsl, which shares the buffer.
struct Mask {
    // the opacity at which a pixel stops taking slices
    threshold: f32,
    // tile side in pixels, tiles per row and per column (the tile pass)
    tile: u32,
    per_row: u32,
    rows: u32,
}

@group(0) @binding(0) var eye: texture_2d<f32>;
@group(0) @binding(1) var<uniform> mask: Mask;

// One triangle covering the viewport, at depth 0.
@vertex
fn vs_mask(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_mask(@builtin(position) p: vec4<f32>) {
    if (textureLoad(eye, vec2<i32>(p.xy), 0).a < mask.threshold) {
        discard;
    }
}

// The tile pass: after the mask, a tile of `tile` × `tile` pixels stays live while one
// of its pixels is below the threshold (`live` cleared to 0 before). One invocation
// scans one pixel row of a tile and marks the tile where it finds one, so a tile is
// written at most once per row.
@group(0) @binding(2) var<storage, read_write> live: array<atomic<u32>>;

@compute @workgroup_size(64)
fn cs_tiles(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let row = gid.x + gid.y * groups.x * 64u;
    let t = row / mask.tile;
    if (t >= mask.per_row * mask.rows) {
        return;
    }
    let size = textureDimensions(eye);
    let y = (t / mask.per_row) * mask.tile + row % mask.tile;
    let x0 = (t % mask.per_row) * mask.tile;
    if (y >= size.y) {
        return;
    }
    let x1 = min(x0 + mask.tile, size.x);
    for (var x = x0; x < x1; x++) {
        if (textureLoad(eye, vec2<u32>(x, y), 0).a < mask.threshold) {
            atomicOr(&live[t], 1u);
            return;
        }
    }
}
