use super::*;
use vwb_render::params::ParamValue;
use vwb_render::volume::VoxelData;

/// f = x / (n − 1): |∇f| = 1/(n − 1) per voxel everywhere inside.
fn ramp(n: u32) -> Volume {
    let data = (0..n * n * n).map(|i| (i % n) as f32).collect();
    Volume::new("ramp", [n; 3], 1, [1.0; 3], VoxelData::F32(data)).unwrap()
}

#[test]
fn both_estimators_measure_a_linear_ramp() {
    let v = ramp(9);
    let scalars = v.normalized_scalars();
    let ctx = CpuContext::new(&v, &scalars);
    for estimator in [Estimator::Central, Estimator::Precomputed] {
        let mut params = ParamValues::defaults(&Tf2dPlugin::default().params());
        params.set("estimator", ParamValue::Enum(estimator.name().into()));
        let mut twin = Tf2dTwin {
            table: tf(&params).bake(TABLE_SIZE),
            gradient_scale: 1.0,
            opacity: 1.0,
            estimator,
            y_data: false,
            gradients: None,
        };
        twin.prepare(&ctx);
        let g = twin.gradient_magnitude(&ctx, DVec3::splat(0.5));
        assert!((g - 1.0 / 8.0).abs() < 1e-6, "{estimator:?}: {g}");
    }
}

#[test]
fn twin_reads_the_table_at_value_and_gradient() {
    let v = ramp(9);
    let scalars = v.normalized_scalars();
    let ctx = CpuContext::new(&v, &scalars);
    // a rectangle that only covers gradient magnitudes around 0.5
    let tf = Tf2d {
        primitives: vec![Primitive2d {
            shape: Shape2d::Rectangle,
            centre: [0.5, 0.5],
            size: [1.0, 0.2],
            color: [0.0, 1.0, 0.0, 0.5],
        }],
    };
    let mut params = ParamValues::defaults(&Tf2dPlugin::default().params());
    params.set("tf", ParamValue::Tf2d(tf));
    let classify = |scale: f32| {
        let mut p = params.clone();
        p.set("gradient_scale", ParamValue::Float(scale));
        let twin = Tf2dPlugin::default().cpu_twin(&p).unwrap();
        let mut s = CpuSample {
            tex: DVec3::splat(0.5),
            value: 0.5,
            ..Default::default()
        };
        twin.classify(&ctx, &mut s);
        s.color
    };
    // |∇f| = 1/8: scale 4 puts it at 0.5 (inside), scale 1 at 0.125 (outside)
    assert!((classify(4.0).w - 0.5).abs() < 1e-6);
    assert_eq!(classify(1.0).w, 0.0);
}

#[test]
fn histogram_puts_a_ramp_in_one_gradient_row() {
    let v = ramp(9);
    let h = histogram2d(&v, 4.0, 16);
    // interior voxels: gradient 0.5 → row 8; border voxels (one-sided) half that
    let row = |r: usize| h[r * 16..(r + 1) * 16].iter().sum::<f32>();
    assert!(row(8) > 0.0 && row(4) > 0.0);
    let total_rows: usize = (0..16).filter(|&r| row(r) > 0.0).count();
    assert_eq!(total_rows, 2, "{h:?}");
}

#[test]
fn estimator_configures_the_prepass() {
    let base = Tf2dPlugin::default();
    let mut params = ParamValues::defaults(&base.params());
    assert!(base.configure(&params).is_none());
    params.set("estimator", ParamValue::Enum("precomputed".into()));
    let p = base.configure(&params).unwrap();
    assert_eq!(p.prepass().unwrap().target, "gradient");
    assert!(base.prepass().is_none());
}

/// `y_axis: data`: the table's y is the data's own value at the sample, whatever the
/// sample's value has become (flow.lic3d replaces it), and it needs no gradients.
#[test]
fn the_data_axis_reads_the_volume_not_the_gradient() {
    let v = Volume::new("c", [4, 4, 4], 1, [1.0; 3], VoxelData::F32((0..64).map(|i| if i == 0 { 0.0 } else { 1.0 }).collect())).unwrap();
    let scalars = v.normalized_scalars();
    let ctx = CpuContext::new(&v, &scalars);
    let mut params = ParamValues::defaults(&Tf2dPlugin::default().params());
    params.set(
        "tf",
        ParamValue::Tf2d(Tf2d {
            primitives: vec![Primitive2d {
                shape: Shape2d::Rectangle,
                centre: [0.5, 0.85],
                size: [1.0, 0.5],
                color: [1.0, 0.5, 0.0, 0.8],
            }],
        }),
    );
    let configured = Tf2dPlugin::default().configure(&{
        let mut p = params.clone();
        p.set("y_axis", ParamValue::Enum("data".into()));
        p
    });
    let data = configured.expect("another mode");
    assert!(data.prepass().is_none());
    assert!(data.shader().source.contains("volume_value(s.tex)"));
    let tex = DVec3::splat(0.8);
    for (y_data, visible) in [(true, true), (false, false)] {
        let mut twin = Tf2dTwin {
            table: tf(&params).bake(TABLE_SIZE),
            gradient_scale: 1.0,
            opacity: 1.0,
            estimator: Estimator::Central,
            y_data,
            gradients: None,
        };
        twin.prepare(&ctx);
        let mut sample = CpuSample {
            tex,
            value: 0.5,
            ..Default::default()
        };
        twin.classify(&ctx, &mut sample);
        assert_eq!(sample.color.w > 0.5, visible, "y_data {y_data}: {:?}", sample.color);
    }
}

/// Each variant's table coordinate divides by its `TABLE_N`, a constant (a power of two,
/// so the division is an exact multiplication and no division per sample is left on a
/// CPU device): it must be the table's size.
#[test]
fn the_shaders_table_size_is_the_tables() {
    assert!(TABLE_SIZE.is_power_of_two());
    for src in [
        include_str!("tf2d_data.wgsl"),
        include_str!("tf2d_central.wgsl"),
        include_str!("tf2d_precomputed.wgsl"),
    ] {
        assert!(src.contains(&format!("const TABLE_N: f32 = {TABLE_SIZE}.0;")));
        assert!(!src.contains("textureDimensions(table)"));
    }
}
