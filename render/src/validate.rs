//! Checks that turn silent wrong images into errors or warnings: cameras and
//! projections that give a flat or black frame, slice spacings that need more slices
//! than a frame may have, eye buffers too coarse for the accumulation, and volumes
//! with nothing to show (docs/reliability.md).

use crate::camera::{Camera, Projection};
use crate::composer::TargetFormat;
use crate::slicing::{SlicePlan, VolumeBox};
use crate::volume::Volume;

/// A bad value: the field (as named in a preset, e.g. `camera.projection.fov_y_deg`)
/// and what is wrong with it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct FieldError {
    pub field: String,
    pub message: String,
}

fn field(field: &str, message: String) -> FieldError {
    FieldError {
        field: field.to_string(),
        message,
    }
}

/// Checks every value of a camera: finite angles, target and distance, positive
/// distance and near plane, a perspective field of view strictly between 0° and 180°
/// and a positive orthographic height.
pub fn check_camera(c: &Camera) -> Result<(), FieldError> {
    for (name, v) in [
        ("camera.yaw_deg", c.yaw_deg),
        ("camera.pitch_deg", c.pitch_deg),
        ("camera.roll_deg", c.roll_deg),
        ("camera.target[0]", c.target[0]),
        ("camera.target[1]", c.target[1]),
        ("camera.target[2]", c.target[2]),
    ] {
        if !v.is_finite() {
            return Err(field(name, format!("{v} must be a finite number")));
        }
    }
    for (name, v) in [("camera.distance", c.distance), ("camera.near", c.near)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(field(name, format!("{v} must be finite and > 0")));
        }
    }
    match c.projection {
        Projection::Perspective { fov_y_deg } => {
            if !(fov_y_deg.is_finite() && fov_y_deg > 0.0 && fov_y_deg < 180.0) {
                return Err(field(
                    "camera.projection.fov_y_deg",
                    format!("{fov_y_deg} must be between 0 and 180 degrees (both excluded)"),
                ));
            }
        }
        Projection::Orthographic { height } => {
            if !(height.is_finite() && height > 0.0) {
                return Err(field(
                    "camera.projection.height",
                    format!("{height} must be finite and > 0 (world units)"),
                ));
            }
        }
    }
    Ok(())
}

/// Checks that a frame of `size` with this camera and slice spacing can be sliced
/// through `volume` (the slice count stays within [`crate::slicing::MAX_SLICES`]).
pub fn check_slices(
    camera: &Camera,
    size: [u32; 2],
    spacing: f32,
    volume: &Volume,
) -> Result<u32, FieldError> {
    check_camera(camera)?;
    let view = camera.view(size[0].max(1) as f32 / size[1].max(1) as f32);
    let vbox = VolumeBox::new(volume.dims, volume.spacing);
    SlicePlan::new(&view, &vbox, spacing)
        .map(|p| p.count)
        .map_err(|e| field("render.slice_spacing", e.to_string()))
}

/// Per-voxel opacity of the "typical dense matter" the eye-buffer check is made for.
pub const EYE_BUFFER_REFERENCE_ALPHA: f64 = 0.05;

/// The coverage (accumulated opacity) at which front-to-back compositing of a
/// constant per-slice opacity `alpha_slice` stops growing in an fp16 accumulator
/// that rounds to nearest: the increment α·(1 − A) falls below half an ulp of A.
/// 1.0 when it never stalls below full coverage.
pub fn fp16_stall_coverage(alpha_slice: f64) -> f64 {
    // binade [2^e, 2^(e+1)) of fp16 (10 mantissa bits): half an ulp is 2^(e−11);
    // subnormals (below 2^-14) have the fixed ulp 2^-24 (NaN also ends here)
    if alpha_slice.is_nan() || alpha_slice < 2f64.powi(-25) {
        return 0.0;
    }
    for e in -14..0 {
        let lo = 2f64.powi(e);
        let half_ulp = 2f64.powi(e - 11);
        // A stalls where alpha·(1 − A) < half_ulp, i.e. A > 1 − half_ulp/alpha
        let stall = 1.0 - half_ulp / alpha_slice;
        if stall < 2.0 * lo {
            // reached this binade but cannot climb through it
            return stall.max(lo);
        }
    }
    1.0
}

/// A warning when an rgba16float eye buffer cannot hold the accumulation at this slice
/// spacing (voxels): a sample of [`EYE_BUFFER_REFERENCE_ALPHA`] opacity per voxel then
/// adds so little per slice that the coverage stalls below 0.9 and the image turns
/// grey or dark (docs/accuracy.md measures the stall). `None` for rgba32float.
pub fn eye_buffer_warning(target: TargetFormat, spacing: f32) -> Option<String> {
    if target != TargetFormat::Rgba16Float || !(spacing.is_finite() && spacing > 0.0) {
        return None;
    }
    let alpha = 1.0 - (1.0 - EYE_BUFFER_REFERENCE_ALPHA).powf(spacing as f64);
    let stall = fp16_stall_coverage(alpha);
    (stall < 0.9).then(|| {
        format!(
            "slice spacing {spacing} voxels is too fine for the rgba16float eye buffer: a sample \
             of opacity {EYE_BUFFER_REFERENCE_ALPHA} per voxel adds {alpha:.2e} per slice, which \
             fp16 stops accumulating at opacity {stall:.2}, so the image darkens or turns grey; \
             use the rgba32float target (--target rgba32float, or render.target: Rgba32Float)"
        )
    })
}

/// Warnings about a volume with nothing to show: a single voxel, only non-finite
/// values, or one value everywhere (the normalised scalars are then all 0).
pub fn volume_warnings(v: &Volume) -> Vec<String> {
    let mut w = Vec::new();
    let voxels = v.voxel_count() as u64;
    if let Some(reason) = degenerate_reason(v) {
        w.push(format!(
            "volume '{}' is degenerate: {reason}; it renders blank or uniform",
            v.name
        ));
    } else if v.non_finite > 0 {
        w.push(format!(
            "volume '{}': {} of {voxels} voxels are NaN or infinite; they render as the lowest value",
            v.name, v.non_finite
        ));
    }
    if voxels == 1 {
        w.push(format!(
            "volume '{}' has a single voxel {:?}",
            v.name, v.dims
        ));
    }
    w
}

/// Why a volume has no structure to render or classify, if it has none.
pub fn degenerate_reason(v: &Volume) -> Option<String> {
    let voxels = v.voxel_count() as u64;
    if v.non_finite >= voxels {
        Some(format!("all {voxels} voxels are NaN or infinite"))
    } else if v.range[0] >= v.range[1] {
        Some(format!(
            "every finite voxel holds the same value {}",
            v.range[0]
        ))
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::VoxelData;

    #[test]
    fn cameras() {
        let ok = Camera::default();
        assert!(check_camera(&ok).is_ok());
        let bad = |f: &dyn Fn(&mut Camera)| {
            let mut c = Camera::default();
            f(&mut c);
            check_camera(&c).unwrap_err().field
        };
        for fov in [0.0, -5.0, 180.0, 200.0, f32::NAN, f32::INFINITY] {
            assert_eq!(
                bad(&|c| c.projection = Projection::Perspective { fov_y_deg: fov }),
                "camera.projection.fov_y_deg",
                "{fov}"
            );
        }
        for h in [0.0, -1.0, f32::NAN] {
            assert_eq!(
                bad(&|c| c.projection = Projection::Orthographic { height: h }),
                "camera.projection.height"
            );
        }
        assert_eq!(bad(&|c| c.roll_deg = f32::NAN), "camera.roll_deg");
        assert_eq!(bad(&|c| c.yaw_deg = f32::INFINITY), "camera.yaw_deg");
        assert_eq!(bad(&|c| c.distance = 0.0), "camera.distance");
        assert_eq!(bad(&|c| c.target[1] = f32::NAN), "camera.target[1]");
        let c = Camera {
            projection: Projection::Perspective { fov_y_deg: 179.0 },
            ..Default::default()
        };
        assert!(check_camera(&c).is_ok());
    }

    #[test]
    fn fp16_stall_matches_the_measured_one() {
        // docs/accuracy.md: α' = 1 − 0.95^0.0016 stalls at 0.25 with round to nearest
        let a = 1.0 - 0.95f64.powf(0.0016);
        assert!(
            (fp16_stall_coverage(a) - 0.25).abs() < 0.02,
            "{}",
            fp16_stall_coverage(a)
        );
        assert!(fp16_stall_coverage(0.5) > 0.999);
        assert_eq!(fp16_stall_coverage(0.0), 0.0);
    }

    #[test]
    fn eye_buffer_warnings() {
        let f16 = TargetFormat::Rgba16Float;
        assert!(eye_buffer_warning(f16, 0.0005).is_some());
        assert!(eye_buffer_warning(f16, 0.002).is_some());
        assert!(eye_buffer_warning(f16, 0.25).is_none());
        assert!(eye_buffer_warning(f16, 1.0).is_none());
        assert!(eye_buffer_warning(TargetFormat::Rgba32Float, 0.0005).is_none());
    }

    #[test]
    fn degenerate_volumes() {
        let vol = |dims: [u32; 3], v: Vec<f32>| {
            Volume::new("t", dims, 1, [1.0; 3], VoxelData::F32(v)).unwrap()
        };
        let constant = vol([2, 2, 2], vec![7.0; 8]);
        assert!(
            degenerate_reason(&constant)
                .unwrap()
                .contains("same value 7")
        );
        let nan = vol([2, 1, 1], vec![f32::NAN, f32::INFINITY]);
        assert!(degenerate_reason(&nan).unwrap().contains("NaN"));
        let one = vol([1, 1, 1], vec![3.0]);
        assert_eq!(volume_warnings(&one).len(), 2);
        let fine = vol([2, 1, 1], vec![0.0, 1.0]);
        assert!(volume_warnings(&fine).is_empty());
        let some_nan = vol([3, 1, 1], vec![0.0, 1.0, f32::NAN]);
        assert!(volume_warnings(&some_nan)[0].contains("1 of 3"));
    }

    #[test]
    fn slice_limits_name_the_field() {
        let v = Volume::new("t", [8, 8, 8], 1, [1.0; 3], VoxelData::U8(vec![0; 512])).unwrap();
        let c = Camera::default();
        assert!(check_slices(&c, [64, 64], 1.0, &v).is_ok());
        let e = check_slices(&c, [64, 64], 1e-9, &v).unwrap_err();
        assert_eq!(e.field, "render.slice_spacing");
    }
}
