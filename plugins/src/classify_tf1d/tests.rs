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
