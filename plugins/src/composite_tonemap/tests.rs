use super::*;

/// Exposure 0 and gamma 1 change nothing; one stop doubles a dark straight colour;
/// gamma 2 takes its square root; colours clamp at 1; opacity and empty pixels stay.
#[test]
fn exposure_and_gamma_map_the_straight_colour() {
    let c = DVec4::new(0.1, 0.2, 0.05, 0.5); // straight (0.2, 0.4, 0.1)
    let id = TonemapTwin {
        exposure: 0.0,
        gamma: 1.0,
    };
    assert!((id.map(c) - c).abs().max_element() < 1e-15);
    let stop = TonemapTwin {
        exposure: 1.0,
        gamma: 1.0,
    };
    let m = stop.map(c);
    assert!((m - DVec4::new(0.2, 0.4, 0.1, 0.5)).abs().max_element() < 1e-12, "{m}");
    let root = TonemapTwin {
        exposure: 0.0,
        gamma: 2.0,
    };
    let r = root.map(c);
    assert!((r.x - 0.5 * 0.2f64.sqrt()).abs() < 1e-12, "{r}");
    let bright = TonemapTwin {
        exposure: 4.0,
        gamma: 1.0,
    };
    assert_eq!(bright.map(c).truncate(), glam::DVec3::splat(0.5));
    assert_eq!(stop.map(DVec4::ZERO), DVec4::ZERO);
}
