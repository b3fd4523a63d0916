// shade.hernell: global light by local piecewise integration (Hernell, Ljung &
// Ynnerman 2008). Three volume passes fill the light volumes, the shade hook reads
// the last one (one extra lookup per sample). CPU twin: mod.rs (`HernellTwin`).
//
// World space: the volume box (frame.box_min/max); h = Δs0 = frame.box_min.w, one
// voxel. Opacities along light and scattering rays are the stack's classified α per
// Δs0 (`stack_classify`), sampled every voxel length after the start point (the
// start voxel does not shadow itself; consecutive segments tile the ray).

fn hn_box_min() -> vec3<f32> {
    return frame.box_min.xyz;
}

fn hn_box_max() -> vec3<f32> {
    return frame.box_max.xyz;
}

fn hn_tex(p: vec3<f32>) -> vec3<f32> {
    return (p - hn_box_min()) / (hn_box_max() - hn_box_min());
}

fn hn_inside(p: vec3<f32>) -> bool {
    return all(p >= hn_box_min()) && all(p <= hn_box_max());
}

// Unit direction from p towards the light, and the distance to it (a directional
// light is infinitely far).
fn hn_to_light(p: vec3<f32>) -> vec4<f32> {
    if (params.light_type == 1u) {
        let d = params.light - p;
        let len = length(d);
        if (len < 1.0e-6) {
            return vec4<f32>(0.0, 0.0, 1.0, 0.0);
        }
        return vec4<f32>(d / len, len);
    }
    let l = params.light;
    let len = max(length(l), 1.0e-6);
    return vec4<f32>(l / len, 3.0e38);
}

// 1 − Π(1 − α_i) over the samples p + i·h·dir, i = 1..n, stopping at the box or
// past `limit` (world distance).
fn hn_opacity(p: vec3<f32>, dir: vec3<f32>, n: i32, limit: f32) -> f32 {
    let h = frame.box_min.w;
    var t = 1.0;
    for (var i = 0; i < n; i = i + 1) {
        let d = f32(i + 1) * h;
        if (d > limit) {
            break;
        }
        let q = p + dir * d;
        if (!hn_inside(q)) {
            break;
        }
        let a = clamp(stack_classify(hn_tex(q), dir).a, 0.0, 1.0);
        t = t * (1.0 - a);
    }
    return 1.0 - t;
}

// Steps a light ray may take inside the box: its diagonal in voxels, plus one.
fn hn_max_steps() -> i32 {
    return i32(ceil(length(hn_box_max() - hn_box_min()) / frame.box_min.w)) + 1;
}

fn hn_voxel_pos(voxel: vec3<u32>, dims: vec3<u32>) -> vec3<f32> {
    let t = (vec3<f32>(voxel) + 0.5) / vec3<f32>(dims);
    return hn_box_min() + t * (hn_box_max() - hn_box_min());
}

// Flat blocking (paper §4 after Ljung et al. 2004; `params.blocking == 1u`): blocks
// of 16³ voxels, each with a level of detail l (the light is computed once per cell
// of 2^l voxels, at the cell's centre) or empty (−1: no voxel of the block or its
// one-voxel apron has α > 0 under the stack's classification; the light passes skip
// it). `block_pass` chooses them.
const HN_BLOCK: i32 = 16;

fn hn_volume_dims() -> vec3<i32> {
    return vec3<i32>(frame.volume_dims.xyz);
}

fn hn_voxel_of(p: vec3<f32>) -> vec3<i32> {
    return vec3<i32>(floor(hn_tex(p) * vec3<f32>(hn_volume_dims())));
}

// Where a voxel's light is computed: the centre of its cell at the block's level (of
// the part inside the volume, for the blocks at its far faces).
fn hn_cell_pos(voxel: vec3<u32>, level: i32) -> vec3<f32> {
    let c = 1u << u32(level);
    let lo = (voxel / c) * c;
    let hi = min(lo + c, vec3<u32>(hn_volume_dims()));
    let t = 0.5 * vec3<f32>(lo + hi) / vec3<f32>(hn_volume_dims());
    return hn_box_min() + t * (hn_box_max() - hn_box_min());
}

// blocking: begin (with `blocking: off` the plugin blanks these lines but the first,
// which becomes `fn hn_block_level(voxel: vec3<i32>) -> i32 { return 0; }`: no
// `blocks` target, no block pass)
// The block level at a voxel (clamped into the volume).
fn hn_block_level(voxel: vec3<i32>) -> i32 {
    let v = clamp(voxel, vec3<i32>(0), hn_volume_dims() - 1);
    return i32(textureLoad(blocks, v / HN_BLOCK, 0).r);
}

// Pass (block): per 16³ block, the largest α over its voxels and a one-voxel apron
// (empty when 0), and the RMS error of α when each cell of 2^l voxels holds its mean
// (l = 1…4); the coarsest level whose error is at most `tolerance` (the TF-domain
// criterion: the error is in classified opacity, not in data values). One pass over
// the voxels: the sums of 2³ cells feed the 4³, 8³ and 16³ cells.
fn block_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    let vd = hn_volume_dims();
    let origin = vec3<i32>(voxel) * HN_BLOCK;
    let dir = hn_to_light(hn_box_min() + (vec3<f32>(origin) + 8.0) / vec3<f32>(vd) * (hn_box_max() - hn_box_min())).xyz;
    var a_max = 0.0;
    // the apron: the faces of the 18³ shell
    for (var z = -1; z <= HN_BLOCK; z = z + 1) {
        for (var y = -1; y <= HN_BLOCK; y = y + 1) {
            for (var x = -1; x <= HN_BLOCK; x = x + 1) {
                let inner = x >= 0 && x < HN_BLOCK && y >= 0 && y < HN_BLOCK && z >= 0 && z < HN_BLOCK;
                if (inner) {
                    continue;
                }
                let v = clamp(origin + vec3<i32>(x, y, z), vec3<i32>(0), vd - 1);
                let t = (vec3<f32>(v) + 0.5) / vec3<f32>(vd);
                a_max = max(a_max, clamp(stack_classify(t, dir).a, 0.0, 1.0));
            }
        }
    }
    var s2: array<f32, 64>;
    var s3: array<f32, 8>;
    for (var i = 0; i < 64; i = i + 1) {
        s2[i] = 0.0;
    }
    for (var i = 0; i < 8; i = i + 1) {
        s3[i] = 0.0;
    }
    var sq = 0.0;
    var e1 = 0.0;
    var s4 = 0.0;
    for (var c = 0; c < 512; c = c + 1) {
        let cell = vec3<i32>(c % 8, (c / 8) % 8, c / 64) * 2;
        var sum = 0.0;
        for (var k = 0; k < 8; k = k + 1) {
            let v = clamp(origin + cell + vec3<i32>(k % 2, (k / 2) % 2, k / 4), vec3<i32>(0), vd - 1);
            let t = (vec3<f32>(v) + 0.5) / vec3<f32>(vd);
            let a = clamp(stack_classify(t, dir).a, 0.0, 1.0);
            a_max = max(a_max, a);
            sum = sum + a;
            sq = sq + a * a;
        }
        e1 = e1 + sum * sum / 8.0;
        let c2 = cell / 4;
        s2[c2.x + c2.y * 4 + c2.z * 16] = s2[c2.x + c2.y * 4 + c2.z * 16] + sum;
    }
    if (a_max <= 0.0) {
        return vec4<f32>(-1.0, 0.0, 0.0, 1.0);
    }
    var e2 = 0.0;
    for (var i = 0; i < 64; i = i + 1) {
        e2 = e2 + s2[i] * s2[i] / 64.0;
        let c3 = vec3<i32>(i % 4, (i / 4) % 4, i / 16) / 2;
        s3[c3.x + c3.y * 2 + c3.z * 4] = s3[c3.x + c3.y * 2 + c3.z * 4] + s2[i];
    }
    var e3 = 0.0;
    for (var i = 0; i < 8; i = i + 1) {
        e3 = e3 + s3[i] * s3[i] / 512.0;
        s4 = s4 + s3[i];
    }
    let e4 = s4 * s4 / 4096.0;
    // Σ(α − mean)² over cells = Σα² − Σ_cells (cell sum)²/n
    let err = sqrt(max(vec4<f32>(sq - e1, sq - e2, sq - e3, sq - e4), vec4<f32>(0.0)) / 4096.0);
    var level = 0;
    for (var l = 0; l < 4; l = l + 1) {
        if (err[l] <= params.tolerance) {
            level = l + 1;
        }
    }
    return vec4<f32>(f32(level), 0.0, 0.0, 1.0);
}
// blocking: end

// Pass (A1), eq 6: α_lp of the segment of `segment` voxels from each voxel towards
// the light. Exact mode: the opacity of the whole path to the light.
fn local_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    var p = hn_voxel_pos(voxel, dims);
    if (params.blocking == 1u) {
        let level = hn_block_level(vec3<i32>(voxel));
        if (level < 0) {
            return vec4<f32>(0.0, 0.0, 0.0, 1.0);
        }
        p = hn_cell_pos(voxel, level);
    }
    let l = hn_to_light(p);
    var n = params.segment;
    if (params.mode == 1u) {
        n = hn_max_steps();
    }
    return vec4<f32>(hn_opacity(p, l.xyz, n, l.w), 0.0, 0.0, 1.0);
}

// With flat blocking, a lookup stays inside its own block (texel centres of the
// block's first and last voxels): blocks are stored apart, so interpolation does not
// cross their borders (the clamping of Ljung et al. 2006 that the paper uses for α_lp
// and I_final).
fn hn_block_tex(tex: vec3<f32>) -> vec3<f32> {
    if (params.blocking == 0u) {
        return tex;
    }
    let vd = vec3<f32>(hn_volume_dims());
    let b = floor(clamp(tex * vd, vec3<f32>(0.0), vd - 1.0) / f32(HN_BLOCK)) * f32(HN_BLOCK);
    let lo = (b + 0.5) / vd;
    let hi = (min(b + f32(HN_BLOCK), vd) - 0.5) / vd;
    return clamp(tex, lo, hi);
}

fn hn_alpha_lp(p: vec3<f32>) -> f32 {
    return textureSampleLevel(alpha_lp, linear_clamp, hn_block_tex(hn_tex(p)), 0.0).r;
}

// Pass (A2), eq 7: the global opacity at each SVR texel, composed from the local
// pieces α_lp sampled (trilinearly) every segment length along the light ray.
fn global_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    if (params.mode == 1u) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    let p = hn_voxel_pos(voxel, dims);
    let l = hn_to_light(p);
    let seg = f32(params.segment) * frame.box_min.w;
    let k_max = hn_max_steps() / params.segment + 2;
    var t = 1.0;
    // samples at base + j·seg: base moves when the ray skips empty blocks
    var base = 0.0;
    var j = 0;
    for (var k = 0; k < k_max; k = k + 1) {
        var d = base + f32(j) * seg;
        if (d >= l.w) {
            break;
        }
        var q = p + l.xyz * d;
        if (!hn_inside(q)) {
            break;
        }
        if (params.blocking == 1u && hn_block_level(hn_voxel_of(q)) < 0) {
            // Fig. 4: a piece starting in an empty block holds no opacity (it was
            // skipped), but its segment may reach matter: advance the ray to the next
            // non-empty block and tile the segments from there
            let a = hn_next_block(q, l.xyz);
            if (a < 0.0) {
                break;
            }
            base = d + a;
            j = 0;
            d = base;
            if (d >= l.w) {
                break;
            }
            q = p + l.xyz * d;
        }
        t = t * (1.0 - hn_alpha_lp(q));
        j = j + 1;
    }
    return vec4<f32>(1.0 - t, 0.0, 0.0, 1.0);
}

// From p (in an empty block) along the unit `dir`: the world distance to the first
// point in a non-empty block, crossing block by block; −1 when the ray leaves the
// volume first.
fn hn_next_block(p: vec3<f32>, dir: vec3<f32>) -> f32 {
    let vd = vec3<f32>(hn_volume_dims());
    // voxel coordinates along the ray: o + v·t, t the world distance
    let o = hn_tex(p) * vd;
    var v = dir * vd / (hn_box_max() - hn_box_min());
    v = select(v, vec3<f32>(1.0e-20), abs(v) < vec3<f32>(1.0e-20));
    var t = 0.0;
    let n = i32(ceil(length(vd) / f32(HN_BLOCK))) * 3 + 3;
    for (var i = 0; i < n; i = i + 1) {
        let lo = floor((o + v * t) / f32(HN_BLOCK)) * f32(HN_BLOCK);
        let ta = (lo - o) / v;
        let tb = (lo + f32(HN_BLOCK) - o) / v;
        let t_exit = min(min(max(ta.x, tb.x), max(ta.y, tb.y)), max(ta.z, tb.z));
        t = max(t_exit, t) + 1.0e-4 * frame.box_min.w;
        let y = o + v * t;
        if (any(y < vec3<f32>(0.0)) || any(y >= vd)) {
            return -1.0;
        }
        if (hn_block_level(vec3<i32>(floor(y))) >= 0) {
            return t;
        }
    }
    return -1.0;
}

// Eq 8: direct light at p, I_d = I0·(1 − α_g(s1))·(1 − α_lp(s0)), s1 one segment
// towards the light (α_g trilinear from the SVR; 0 outside the box or past the
// light). Outside the box the light arrives unattenuated.
fn hn_direct(p: vec3<f32>) -> f32 {
    if (!hn_inside(p)) {
        return params.intensity;
    }
    let l = hn_to_light(p);
    let seg = f32(params.segment) * frame.box_min.w;
    let s1 = p + l.xyz * seg;
    var ag = 0.0;
    if (params.mode == 0u && seg < l.w && hn_inside(s1)) {
        ag = textureSampleLevel(alpha_g, linear_clamp, hn_tex(s1), 0.0).r;
    }
    return params.intensity * (1.0 - ag) * (1.0 - hn_alpha_lp(p));
}

// Pass (B), eqs 11 and 13: step 0 is the light's own direction, step j the j-th
// direction of the subdivided polyhedron (`dirs`); each is blended into the stored
// value with weight 1/(j + 1). Without scattering: I_d at the voxel.
fn light_pass(voxel: vec3<u32>, dims: vec3<u32>, step: u32, prev: vec4<f32>) -> vec4<f32> {
    var p = hn_voxel_pos(voxel, dims);
    if (params.blocking == 1u) {
        let level = hn_block_level(vec3<i32>(voxel));
        if (level < 0) {
            // never shaded (nothing visible there); the unattenuated light
            return vec4<f32>(params.intensity, 0.0, 0.0, 1.0);
        }
        p = hn_cell_pos(voxel, level);
    }
    if (params.scattering == 0u) {
        return vec4<f32>(hn_direct(p), 0.0, 0.0, 1.0);
    }
    var dir = hn_to_light(p).xyz;
    if (step > 0u) {
        dir = textureLoad(dirs, vec2<i32>(i32(step) - 1, 0), 0).xyz;
    }
    let h = frame.box_min.w;
    let m_max = i32(round(params.radius));
    var sum = 0.0;
    var t = 1.0;
    for (var m = 0; m <= m_max; m = m + 1) {
        let q = p + dir * (f32(m) * h);
        sum = sum + hn_direct(q) * t;
        // the transmittance to s_(m+1) passes the sample s_m (not s_0)
        if (m > 0 && hn_inside(q)) {
            t = t * (1.0 - clamp(stack_classify(hn_tex(q), dir).a, 0.0, 1.0));
        }
    }
    let i_new = sum / f32(m_max + 1);
    let w = 1.0 / f32(step + 1u);
    return vec4<f32>(w * i_new + (1.0 - w) * prev.x, 0.0, 0.0, 1.0);
}

// Pass (C), eq 12: g = (I_bias + (1 − I_bias)·I_s)·c·α, with the light's colour.
fn shade(s: Sample) -> Sample {
    var o = s;
    let i_s = textureSampleLevel(light_volume, linear_clamp, hn_block_tex(s.tex), 0.0).r;
    let f = params.bias + (1.0 - params.bias) * i_s;
    o.color = vec4<f32>(s.color.rgb * f * params.light_color.rgb, s.color.a);
    return o;
}
