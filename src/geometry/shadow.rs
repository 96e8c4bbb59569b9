//! The shadow-segment rule: every shadow ray in tstat (next-event estimation on
//! surfaces and in media, the NLOS laser connections) runs from its origin, already
//! moved off its surface, towards its target and stops a relative [`SHADOW_SHORTEN`]
//! short of it, as Mitsuba's shadow rays do, so the target's own surface never blocks
//! it.

use glam::Vec3;

/// The fraction of a shadow segment left out at its target end.
pub const SHADOW_SHORTEN: f32 = 1e-4;

/// The shadow ray from `from` to `to`: origin, unit direction and length (the last
/// [`SHADOW_SHORTEN`] left out); `None` when the ends coincide or are not finite
/// enough to give a length.
#[inline(always)]
pub fn shadow_segment(from: Vec3, to: Vec3) -> Option<(Vec3, Vec3, f32)> {
    let seg = to - from;
    let len = seg.length();
    (len > 0.0).then(|| (from, seg / len, len * (1.0 - SHADOW_SHORTEN)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_segment_stops_short_of_its_target_by_the_shared_fraction() {
        let (o, d, t) = shadow_segment(Vec3::ZERO, Vec3::new(0.0, 3.0, 4.0)).unwrap();
        assert_eq!(o, Vec3::ZERO);
        assert_eq!(d, Vec3::new(0.0, 0.6, 0.8));
        assert_eq!(t, 5.0 * (1.0 - 1e-4));
        assert!(t < 5.0);
    }

    #[test]
    fn coincident_or_nan_ends_give_no_segment() {
        assert!(shadow_segment(Vec3::ONE, Vec3::ONE).is_none());
        assert!(shadow_segment(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0)).is_none());
    }
}
