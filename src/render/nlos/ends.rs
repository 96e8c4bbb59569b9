//! What every path of one NLOS grid point shares, looked up per pixel from the setup
//! the scene prepared at load (`scene/nlos_setup.rs`): which laser point and sensor point a
//! film row holds, the surface laser sampling aims at, the laser's light there, and a
//! capture meter's first hit.

use crate::geometry::accel::Hit;
use crate::lights::laser::LaserLight;
use crate::scene::nlos_setup::{CaptureType, NlosSetup};

/// The ends of the paths of one sensor point under one laser point ([`path_ends`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct PathEnds {
    /// The surface laser sampling aims at (`None` without laser sampling, or where the
    /// laser's ray meets nothing).
    pub lit: Option<Hit>,
    /// The laser's light at the lit point (the same for every path; `None`: blocked
    /// or dark, the lit point contributes nothing).
    pub lit_light: Option<LaserLight>,
    /// With a capture meter, the first hit of the sensor point's ray (`Some(None)`:
    /// it meets nothing); `None` for a camera.
    pub first: Option<Option<Hit>>,
}

/// Laser point and sensor row of film row `row` (exhaustive scans stack one image
/// per laser point).
#[inline]
pub fn film_row(setup: &NlosSetup, row: usize) -> (usize, usize) {
    let h = setup.sensor_grid[1];
    (row / h, row % h)
}

/// The ends of the paths of sensor point (x, y) under laser point `l`.
#[inline]
pub fn path_ends(
    setup: &NlosSetup,
    capture: CaptureType,
    x: usize,
    y: usize,
    l: usize,
) -> PathEnds {
    let pixel = y * setup.sensor_grid[0] + x;
    let i = match capture {
        CaptureType::Single => 0,
        CaptureType::Confocal => pixel,
        CaptureType::Exhaustive => l,
    };
    PathEnds {
        lit: setup.laser_hits.get(i).copied().flatten(),
        lit_light: setup.lit_light.get(i).copied().flatten(),
        first: setup.sensor_hits.get(pixel).copied(),
    }
}
