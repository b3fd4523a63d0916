use super::*;
use vwb_render::params::ParamValue;
use vwb_render::tf::{PrimitiveShape, TfPrimitive};
use vwb_render::volume::{Volume, VoxelData};

/// A 4³ volume whose values rise along x (normalised 0, 1/3, 2/3, 1).
fn ramp_volume() -> Volume {
    let data = (0..64).map(|i| (i % 4) as u8).collect();
    Volume::new("ramp", [4, 4, 4], 1, [1.0; 3], VoxelData::U8(data)).unwrap()
}

fn classify_at(twin: &dyn CpuTwin, ctx: &CpuContext, value: f64) -> DVec4 {
    let mut s = CpuSample {
        value,
        ..Default::default()
    };
    twin.classify(ctx, &mut s);
    s.color
}

/// A sharp TF: a narrow opaque spike at 0.5 over a faint ramp.
fn sharp_curve() -> TfCurve {
    TfCurve::ramp(0.0, 1.0, [0.2, 0.4, 1.0, 0.05]).with_primitives(vec![TfPrimitive {
        shape: PrimitiveShape::Box,
        centre: 0.5,
        width: 0.02,
        height: 0.9,
        color: [1.0, 0.3, 0.1],
    }])
}

fn params_for(mode: Mode, curve: TfCurve) -> ParamValues {
    let mut params = ParamValues::defaults(&Tf1d::default().params());
    params.set("mode", ParamValue::Enum(mode.name().to_string()));
    params.set("tf", ParamValue::Tf(curve));
    params
}

#[test]
fn twin_follows_the_curve() {
    let volume = ramp_volume();
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(&volume, &scalars);
    let p = Tf1d::default();
    let mut params = ParamValues::defaults(&p.params());
    let c = TfCurve::ramp(0.2, 0.8, [1.0, 0.5, 0.0, 0.5]);
    params.set("tf", ParamValue::Tf(c.clone()));
    params.set("opacity", ParamValue::Float(2.0));
    let twin = p.cpu_twin(&params).unwrap();
    for v in [0.0, 0.1, 0.2, 0.5, 0.77, 1.0] {
        let color = classify_at(twin.as_ref(), &ctx, v);
        let want = c.eval(v);
        // table resolution: the curve is linear between its points, so the table is exact
        assert!((color.x - want[0]).abs() < 1e-6, "v {v}");
        assert!((color.w - (want[3] * 2.0).min(1.0)).abs() < 1e-6, "v {v}");
    }
}

#[test]
fn default_curve_is_valid() {
    assert!(default_curve().validate().is_ok());
}

/// The visibility promise is conservative: a value the twin classifies with α > 0 is
/// always inside a range reported visible, and ranges of fully transparent values are
/// reported empty.
#[test]
fn visibility_promise_is_conservative() {
    let volume = ramp_volume();
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(&volume, &scalars);
    let p = Tf1d::default();
    let mut params = ParamValues::defaults(&p.params());
    params.set(
        "tf",
        ParamValue::Tf(TfCurve::ramp(0.3, 0.6, [1.0, 1.0, 1.0, 0.7])),
    );
    let volumes = Volumes::of(&volume);
    let Transparency::ByValue(visible) = p.transparency(&params, &volumes) else {
        panic!("tf1d classifies by value");
    };
    let twin = p.cpu_twin(&params).unwrap();
    for i in 0..=2000 {
        let v = i as f64 / 2000.0;
        let alpha = classify_at(twin.as_ref(), &ctx, v).w;
        if alpha > 0.0 {
            assert!(visible(v, v), "α({v}) = {alpha} but reported empty");
            assert!(visible(v - 0.01, v + 0.01));
        }
    }
    // the ramp starts at 0.3: far below it nothing is visible
    assert!(!visible(0.0, 0.25));
    assert!(visible(0.0, 0.35));
    assert!(visible(0.9, 1.0));
    // a small opacity scale keeps the visible set
    params.set("opacity", ParamValue::Float(0.01));
    let Transparency::ByValue(visible) = p.transparency(&params, &volumes) else {
        panic!()
    };
    assert!(visible(0.5, 0.5));
}

#[test]
fn mode_parameter_configures_the_plugin() {
    let base = Tf1d::default();
    assert!(
        base.configure(&params_for(Mode::Post, default_curve()))
            .is_none()
    );
    for mode in [Mode::Pre, Mode::Preintegrated] {
        let p = base.configure(&params_for(mode, default_curve())).unwrap();
        assert_eq!(p.id(), "classify.tf1d");
        assert_eq!(p.prepass().is_some(), mode == Mode::Pre);
        assert_eq!(p.uses_slice_spacing(), mode == Mode::Preintegrated);
        assert!(p.configure(&params_for(mode, default_curve())).is_none());
    }
    // pre-integration promises by value, reading one slice step ahead
    let pi = base
        .configure(&params_for(Mode::Preintegrated, default_curve()))
        .unwrap();
    assert!(matches!(
        pi.transparency(
            &params_for(Mode::Preintegrated, default_curve()),
            &Volumes::of(&vwb_render::volume::demo())
        ),
        Transparency::ByValueAhead(_, steps) if steps == 1.0
    ));
}

/// Pre-integration's promise holds for every slab: wherever the filtered table lookup
/// of a (front, back) pair mixes an entry with α > 0, the promise calls the range
/// between the two ends visible (narrow TF features, both slab directions, a small
/// opacity scale).
#[test]
fn preintegrated_promise_holds_for_every_slab() {
    let curves = [
        TfCurve::ramp(0.3, 0.6, [1.0, 1.0, 1.0, 0.7]),
        TfCurve::new(vec![
            TfPoint { x: 0.0, color: [0.0; 4] },
            TfPoint { x: 0.50, color: [1.0, 0.5, 0.2, 0.0] },
            TfPoint { x: 0.502, color: [1.0, 0.5, 0.2, 0.9] },
            TfPoint { x: 0.504, color: [1.0, 0.5, 0.2, 0.0] },
            TfPoint { x: 1.0, color: [0.0; 4] },
        ]),
    ];
    let base = Tf1d::default();
    for (k, curve) in curves.into_iter().enumerate() {
        for opacity in [1.0f32, 0.01] {
            let mut params = params_for(Mode::Preintegrated, curve.clone());
            params.set("opacity", ParamValue::Float(opacity));
            let pi = base.configure(&params).unwrap();
            let volume = vwb_render::volume::demo();
            let Transparency::ByValueAhead(visible, _) =
                pi.transparency(&params, &Volumes::of(&volume))
            else {
                panic!("pre-integration promises by value");
            };
            let lut = curve.bake(LUT_SIZE);
            let table = preint::build(&lut, opacity as f64, 1.0);
            let n = table.n;
            let alpha = |i: usize, j: usize| table.entries[j * n + i][3];
            let (mut opaque, mut checked) = (0, 0);
            for a in 0..=300 {
                for b in 0..=300 {
                    let (f, bk) = (a as f64 / 300.0, b as f64 / 300.0);
                    // the bilinear footprint of the lookup at (f, b)
                    let at = |v: f64| ((v * (n - 1) as f64).floor() as usize).min(n - 2);
                    let (i0, j0) = (at(f), at(bk));
                    let mixed = [(0, 0), (1, 0), (0, 1), (1, 1)]
                        .iter()
                        .any(|&(di, dj)| alpha(i0 + di, j0 + dj) > 0.0);
                    checked += 1;
                    if mixed {
                        opaque += 1;
                        assert!(
                            visible(f.min(bk), f.max(bk)),
                            "curve {k}, opacity {opacity}: slab {f} → {bk} is visible"
                        );
                    }
                }
            }
            // both kinds occur
            assert!(opaque > 0 && opaque < checked, "curve {k}: {opaque} of {checked}");
        }
    }
}

/// Pre-classification interpolates opacity-weighted colours: halfway between an
/// opaque red voxel and a transparent blue one the colour stays red (post would mix).
#[test]
fn pre_classification_weights_colours_by_opacity() {
    let volume = ramp_volume();
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(&volume, &scalars);
    let curve = TfCurve::new(vec![
        TfPoint {
            x: 0.0,
            color: [1.0, 0.0, 0.0, 0.8],
        },
        TfPoint {
            x: 1.0 / 3.0,
            color: [0.0, 0.0, 1.0, 0.0],
        },
    ]);
    let params = params_for(Mode::Pre, curve.clone());
    let twin = Tf1d {
        mode: Mode::Pre,
        centroid: false,
    }
    .cpu_twin(&params)
    .unwrap();
    // between voxel x = 0 (value 0) and x = 1 (value 1/3): tex.x = 1/4 of a 4-wide grid
    let mut s = CpuSample {
        tex: DVec3::new(0.25, 0.5, 0.5),
        ..Default::default()
    };
    s.value = ctx.value(s.tex);
    twin.classify(&ctx, &mut s);
    assert!(
        (s.color.x - 1.0).abs() < 2e-3 && s.color.z < 2e-3,
        "{:?}",
        s.color
    );
    assert!((s.color.w - 0.4).abs() < 2e-3, "{:?}", s.color);
    let post = Tf1d::default().cpu_twin(&params).unwrap();
    let mut q = s;
    post.classify(&ctx, &mut q);
    assert!((q.color.x - 0.5).abs() < 1e-2 && (q.color.z - 0.5).abs() < 1e-2);
}

#[test]
fn preintegration_recursion_matches_direct_compositing() {
    let lut = sharp_curve().bake(64);
    for d in [0.25, 1.0, 4.0] {
        let t = preint::build(&lut, 1.0, d);
        for i in (0..64).step_by(3) {
            for j in (0..64).step_by(5) {
                let (want, want_depth) = preint::entry_direct(&lut, 1.0, d, i, j);
                let got = t.entries[j * 64 + i];
                for c in 0..4 {
                    assert!(
                        (got[c] - want[c]).abs() < 1e-9,
                        "d {d} ({i},{j}) channel {c}: {} vs {}",
                        got[c],
                        want[c]
                    );
                }
                let depth = t.depth[j * 64 + i];
                assert!(
                    (depth - want_depth).abs() < 1e-7,
                    "d {d} ({i},{j}) centroid {depth} vs {want_depth}"
                );
            }
        }
    }
}

/// The table against the emission–absorption integral evaluated by brute force
/// (10⁵ steps along the slab of the TF as the GPU holds it: the baked table,
/// linearly interpolated).
#[test]
fn preintegration_table_matches_the_integral() {
    let curve = sharp_curve();
    let lut = curve.bake(LUT_SIZE);
    for d in [0.5, 1.0, 4.0] {
        let table = preint::build(&lut, 1.0, d);
        for (sf, sb) in [(0.3, 0.7), (0.7, 0.3), (0.45, 0.55), (0.1, 0.2), (0.5, 0.5)] {
            let steps = 100_000;
            let h = d / steps as f64;
            let (mut c, mut a, mut moment) = (DVec3::ZERO, 0.0f64, 0.0f64);
            for k in 0..steps {
                let t = (k as f64 + 0.5) / steps as f64;
                let v = sf + (sb - sf) * t;
                let e = eval_lut(&lut, v);
                let kappa = -(1.0 - e[3]).ln();
                let ak = 1.0 - (-kappa * h).exp();
                c += (1.0 - a) * ak * DVec3::new(e[0], e[1], e[2]);
                moment += (1.0 - a) * ak * t;
                a += (1.0 - a) * ak;
            }
            // the opacity centroid, where the slab takes up a visible share of light
            if a > 0.01 {
                let depth = table.lookup_depth(sf, sb);
                assert!(
                    (depth - moment / a).abs() < 0.01,
                    "d {d} ({sf},{sb}): centroid {depth} vs {}",
                    moment / a
                );
            }
            let got = table.lookup(sf, sb);
            let slab_alpha = 1.0 - (1.0 - got.w).powf(d);
            assert!(
                (slab_alpha - a).abs() < 0.01,
                "d {d} ({sf},{sb}): α {slab_alpha} vs {a}"
            );
            let rgb = got.truncate() * slab_alpha;
            assert!(
                (rgb - c).abs().max_element() < 0.01,
                "d {d} ({sf},{sb}): {rgb} vs {c}"
            );
        }
    }
}

/// Stable when front ≈ back: entries next to the diagonal approach the homogeneous
/// ones, and extreme TFs give finite values.
#[test]
fn preintegration_is_stable_at_the_extremes() {
    let lut = sharp_curve().bake(LUT_SIZE);
    let t = preint::build(&lut, 1.0, 1.0);
    for v in [0.0, 0.2, 0.5, 0.9, 1.0] {
        let on = t.lookup(v, v);
        let near = t.lookup(v, v + 1e-6);
        assert!(
            (on - near).abs().max_element() < 1e-3,
            "v {v}: {on} vs {near}"
        );
        // the homogeneous slab has the TF's own opacity per reference step (exactly at
        // table nodes; between them bilinear filtering mixes in the neighbours)
        let want = eval_lut(&lut, v);
        assert!(
            (on.w - want[3]).abs() < 1e-3,
            "v {v}: {} vs {}",
            on.w,
            want[3]
        );
        let node = (v * 255.0).round() as usize;
        assert!((t.entries[node * 256 + node][3] - lut[node][3] as f64).abs() < 1e-9);
    }
    for (opacity, d) in [
        (0.0, 1.0),
        (1e6, 1.0),
        (1.0, 1e-4),
        (1.0, 1e4),
        (1.0, f64::NAN),
    ] {
        let t = preint::build(&lut, opacity, d);
        let bad = t.entries.iter().position(|e| {
            e.iter()
                .any(|v| !(v.is_finite() && (0.0..=1.0).contains(v)))
        });
        assert!(
            bad.is_none(),
            "opacity {opacity} d {d}: {:?}",
            bad.map(|i| (i, t.entries[i]))
        );
        assert!(
            t.depth.iter().all(|z| z.is_finite() && (0.0..=1.0).contains(z)),
            "opacity {opacity} d {d}: centroid outside [0, 1]"
        );
    }
    assert!(
        preint::build(&lut, 0.0, 1.0)
            .entries
            .iter()
            .all(|e| e[3] == 0.0)
    );
}

/// The pre-integrated twin with `shade_at`, applied on the ramp volume to the sample
/// at x = 0.375 whose slab reaches x = 0.625 (a ray along +x, one voxel per slice):
/// the classified sample, its (front, back) values and where shading reads.
fn classify_across_the_shell(shade_at: &str) -> (CpuSample, (f64, f64), DVec3) {
    let volume = ramp_volume();
    let scalars = volume.normalized_scalars();
    let ctx = CpuContext::new(&volume, &scalars).with_spacing(1.0);
    let mut params = params_for(Mode::Preintegrated, sharp_curve());
    params.set("shade_at", ParamValue::Enum(shade_at.into()));
    let mut twin = Tf1d {
        mode: Mode::Preintegrated,
        centroid: shade_at == "centroid",
    }
    .cpu_twin(&params)
    .unwrap();
    twin.prepare(&ctx);
    let (lo, hi) = ctx.volume_box();
    let tex = DVec3::new(0.375, 0.5, 0.5);
    let mut s = CpuSample {
        tex,
        pos: lo + (hi - lo) * tex,
        ray_dir: DVec3::X,
        step: (hi.x - lo.x) / 4.0,
        ..Default::default()
    };
    s.value = ctx.value(s.tex);
    twin.classify(&ctx, &mut s);
    let back = ctx.value(tex + DVec3::new(0.25, 0.0, 0.0));
    let at = s.shading_tex(&ctx);
    (s, (s.value, back), at)
}

/// The twin reads the back value where the ray meets the next slice.
#[test]
fn preintegrated_twin_reads_front_and_back() {
    let (s, (front, back), _) = classify_across_the_shell("front");
    let table = preint::build(&sharp_curve().bake(LUT_SIZE), 1.0, 1.0);
    let want = table.lookup(front, back);
    assert!(
        (s.color - want).abs().max_element() < 1e-6,
        "{} vs {want}",
        s.color
    );
}

/// `shade_at: centroid` moves the shading point to where the slab's opacity is: a
/// thin opaque shell (the TF's spike at 0.5) lies halfway between the front sample
/// (value 1/3) and the back (2/3), so the gradient is read halfway, at the shell;
/// `front` leaves it at the sample.
#[test]
fn centroid_shading_reads_the_gradient_at_the_shell() {
    for (shade_at, want_x) in [("front", 0.375), ("centroid", 0.5)] {
        let (_, _, at) = classify_across_the_shell(shade_at);
        assert!(
            (at.x - want_x).abs() < 0.02 && (at.y - 0.5).abs() < 1e-12,
            "{shade_at}: shading at {at}, want x = {want_x}"
        );
    }
}

/// The post-classified and pre-integrated lookups divide by constant table sizes
/// (powers of two, so exact multiplications, no division per sample on a CPU device):
/// they must be the tables' `LUT_SIZE`.
#[test]
fn the_shaders_table_sizes_are_the_tables() {
    assert!(LUT_SIZE.is_power_of_two());
    let post = include_str!("tf1d.wgsl");
    assert!(post.contains(&format!("const LUT_N: f32 = {LUT_SIZE}.0;")));
    let preint = include_str!("tf1d_preint.wgsl");
    assert!(preint.contains(&format!("const PREINT_N: f32 = {LUT_SIZE}.0;")));
    for src in [post, preint] {
        assert!(!src.contains("textureDimensions"));
    }
}
