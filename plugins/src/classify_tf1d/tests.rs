use super::*;
use vwb_render::params::ParamValue;

#[test]
fn twin_follows_the_curve() {
    let p = Tf1d;
    let mut params = ParamValues::defaults(&p.params());
    let c = TfCurve::ramp(0.2, 0.8, [1.0, 0.5, 0.0, 0.5]);
    params.set("tf", ParamValue::Tf(c.clone()));
    params.set("opacity", ParamValue::Float(2.0));
    let twin = p.cpu_twin(&params).unwrap();
    for v in [0.0, 0.1, 0.2, 0.5, 0.77, 1.0] {
        let mut s = CpuSample {
            value: v,
            ..Default::default()
        };
        twin.classify(&mut s);
        let want = c.eval(v);
        // table resolution: the curve is linear between its points, so the table is exact
        assert!((s.color.x - want[0]).abs() < 1e-6, "v {v}");
        assert!((s.color.w - (want[3] * 2.0).min(1.0)).abs() < 1e-6, "v {v}");
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
    let p = Tf1d;
    let mut params = ParamValues::defaults(&p.params());
    params.set(
        "tf",
        ParamValue::Tf(TfCurve::ramp(0.3, 0.6, [1.0, 1.0, 1.0, 0.7])),
    );
    let Transparency::ByValue(visible) = p.transparency(&params) else {
        panic!("tf1d classifies by value");
    };
    let twin = p.cpu_twin(&params).unwrap();
    for i in 0..=2000 {
        let v = i as f64 / 2000.0;
        let mut s = CpuSample {
            value: v,
            ..Default::default()
        };
        twin.classify(&mut s);
        if s.color.w > 0.0 {
            assert!(visible(v, v), "α({v}) = {} but reported empty", s.color.w);
            assert!(visible(v - 0.01, v + 0.01));
        }
    }
    // the ramp starts at 0.3: far below it nothing is visible
    assert!(!visible(0.0, 0.25));
    assert!(visible(0.0, 0.35));
    assert!(visible(0.9, 1.0));
    // a small opacity scale keeps the visible set
    params.set("opacity", ParamValue::Float(0.01));
    let Transparency::ByValue(visible) = p.transparency(&params) else {
        panic!()
    };
    assert!(visible(0.5, 0.5));
}
