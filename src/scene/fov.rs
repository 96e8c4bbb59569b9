//! The field of view of perspective sensors and projectors: `fov` with `fov_axis`, or
//! `focal_length` (Mitsuba's `parse_fov`).

use super::error::SceneError;
use super::props::Props;
use crate::sensors::camera::FovAxis;

/// `fov` (on `fov_axis`), or Mitsuba's `focal_length` (35 mm equivalent, default
/// "50mm", on the diagonal of a 36 x 24 mm frame), as `parse_fov` in Mitsuba 3: the
/// field of view in degrees, in (0, 180), and the extent it spans. Shared by the
/// `perspective` sensor and the `projector` emitter.
pub(super) fn parse_fov(p: &mut Props) -> Result<(f64, FovAxis), SceneError> {
    let (fov, axis_name) = match (p.float("fov")?, p.string("focal_length")?) {
        (Some(_), Some(_)) => {
            return Err(p.err("give either 'fov' or 'focal_length', not both"));
        }
        (Some(fov), None) => (fov, p.string("fov_axis")?.unwrap_or_else(|| "x".into())),
        (None, f) => {
            let f = f.unwrap_or_else(|| "50mm".into());
            let mm: f64 = f
                .trim()
                .trim_end_matches("mm")
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite() && *v > 0.0)
                .ok_or_else(|| {
                    p.err_at(
                        "focal_length",
                        format!("focal_length '{f}' is not of the form <x>mm with x > 0"),
                    )
                })?;
            let fov = 2.0
                * ((36.0f64 * 36.0 + 24.0 * 24.0).sqrt() / (2.0 * mm))
                    .atan()
                    .to_degrees();
            if p.string("fov_axis")?.is_some() {
                p.warn_at("fov_axis", "fov_axis has no effect with focal_length (the diagonal is used), as in Mitsuba");
            }
            (fov, "diagonal".to_string())
        }
    };
    if !(fov > 0.0 && fov < 180.0) {
        return Err(p.err_at("fov", format!("fov must be in (0, 180) degrees, got {fov}")));
    }
    let fov_axis = FovAxis::parse(&axis_name).ok_or_else(|| {
        p.err_at(
            "fov_axis",
            format!("fov_axis '{axis_name}' is not one of x, y, smaller, larger, diagonal"),
        )
    })?;
    Ok((fov, fov_axis))
}
