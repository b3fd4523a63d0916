use super::*;
use vwb_render::plugin::Plugin;
use crate::lighting::testing::{BASE, constant, ramp_x, shaded, world_light};
use vwb_render::params::ParamValue;

fn style(bands: i32) -> ToonStyle {
    let mut p = ParamValues::defaults(&Toon::default().params());
    p.set("bands", ParamValue::Int(bands));
    ToonStyle::from_params(&p)
}

/// Away from the thresholds the diffuse term takes exactly `bands` levels.
#[test]
fn diffuse_light_takes_band_levels() {
    for bands in [2, 3, 5] {
        let s = style(bands);
        for k in 0..bands {
            // the middle of band k
            let d = (k as f64 + 0.5) / bands as f64;
            let expect = k as f64 / (bands - 1) as f64;
            assert!((s.level(d) - expect).abs() < 1e-12, "{bands} bands, d {d}: {}", s.level(d));
        }
        // monotone and continuous: no jump larger than a smoothstep over 1/1000
        let mut prev = s.level(0.0);
        for i in 1..=1000 {
            let q = s.level(i as f64 / 1000.0);
            assert!(q >= prev && q - prev < 0.04, "{bands} bands at {i}: {prev} → {q}");
            prev = q;
        }
    }
}

/// Facing the viewer: banded light, no outline. Edge-on: the outline colour.
#[test]
fn outline_marks_edge_on_surfaces() {
    let t = Toon::default();
    let mut p = world_light(&t, [-1.0, 0.0, 0.0]);
    p.set("bands", ParamValue::Int(3));
    let st = ToonStyle::from_params(&p);
    // normal −x, viewer on −x looking +x, light head-on: top band, no outline
    let c = shaded(&t, &ramp_x(9), &p, DVec3::X);
    let expect = BASE.truncate() * (st.ka + st.kd);
    assert!((c.truncate() - expect).length() < 1e-9, "{c} vs {expect}");
    // seen edge-on (ray along y): the outline colour
    let c = shaded(&t, &ramp_x(9), &p, DVec3::Y);
    assert!((c.truncate() - st.outline.truncate()).length() < 1e-9, "{c}");
    assert_eq!(c.w, BASE.w, "opacity is unchanged");
    // an outline alpha of 0 turns it off
    p.set("outline_color", ParamValue::Color([0.0, 0.0, 0.0, 0.0]));
    let c = shaded(&t, &ramp_x(9), &p, DVec3::Y);
    assert!(c.x > 0.1, "{c}");
}

#[test]
fn no_gradient_is_unlit() {
    let t = Toon::default();
    let p = world_light(&t, [-1.0, 0.0, 0.0]);
    assert_eq!(shaded(&t, &constant(6), &p, DVec3::X), BASE);
}
