//! Where a camera path's optical path length starts (SPEC 2): the time origin.
//!
//! Mitsuba 3's projective sensors (`perspective`, `thinlens`, `orthographic`) start
//! every camera ray on the near-clip plane, and mitransient (like the Mitsuba 2
//! transient renderer) counts the OPL from there: a ray through the film at angle
//! theta to the view axis starts `near_clip / cos(theta)` past the pinhole (past the
//! lens point for `thinlens`; `near_clip` along the view axis for `orthographic`, as
//! its `to_world` scales it). Surfaces nearer than the near plane are not seen.
//!
//! - [`TimeOrigin::NearClip`] (the default for every camera): as Mitsuba.
//! - [`TimeOrigin::Pinhole`]: rays start at the camera's origin (the pinhole, the lens
//!   point, the orthographic sensor plane) and `near_clip` is ignored: the physical
//!   origin, and what tstat did before the time origin was recorded (bundles without
//!   the manifest field were rendered so).
//!
//! An `nlos_capture_meter` has no near plane: its capture is always `Pinhole`.

/// The time origin of a render (`--time-origin`, the manifest's `time_origin`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeOrigin {
    NearClip,
    Pinhole,
}

impl TimeOrigin {
    /// The manifest's and the command line's name.
    pub fn name(self) -> &'static str {
        match self {
            TimeOrigin::NearClip => "near_clip",
            TimeOrigin::Pinhole => "pinhole",
        }
    }

    /// Where time zero is, for labels ("OPL from ...").
    pub fn describe(self) -> &'static str {
        match self {
            TimeOrigin::NearClip => "the near-clip plane",
            TimeOrigin::Pinhole => "the camera",
        }
    }
}
