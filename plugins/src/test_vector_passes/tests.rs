use super::*;

/// The passes' twin on a linear speed: the blur keeps a linear ramp inside (the
/// 7-point mean of a linear function is its centre value), and the gradient magnitude
/// there is the ramp's slope.
#[test]
fn a_linear_speed_has_its_slope_as_edges() {
    let dims = [6, 5, 4];
    // v = (x/2, 0, 0) at voxel x: the speed at voxel centres is x/2
    let data: Vec<f32> = (0..4 * 5 * 6)
        .flat_map(|i| [(i % 6) as f32 / 2.0, 0.0, 0.0])
        .collect();
    let field = GridField {
        dims,
        components: 3,
        data,
    };
    let (speed, blurred, edges) = pass_volumes(dims, Some(&field));
    assert!((speed.at([3, 2, 1]) - 1.5).abs() < 1e-12);
    assert!((blurred.at([3, 2, 1]) - 1.5).abs() < 1e-12);
    assert!((edges.at([3, 2, 2]) - 0.5).abs() < 1e-12, "{}", edges.at([3, 2, 2]));
    // no field: nothing
    let (_, _, none) = pass_volumes(dims, None);
    assert!(none.data.iter().all(|x| *x == 0.0));
}
