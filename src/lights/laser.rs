//! The laser of an NLOS capture (SPEC 11): what it sends a surface point. The scene's
//! only emitter, a `projector` or a `spot` (`Emitter::laser_frame`), is the laser; the
//! scene works out where it points at load (`scene/nlos_setup.rs`), the NLOS tracer asks it
//! for light at every vertex (`render/nlos/`). Both go through [`laser_light`].

use super::Emitter;
use crate::geometry::accel::offset_origin;
use crate::geometry::shadow::shadow_segment;
use crate::geometry::shape::Shape;
use crate::math::Rgb;
use glam::Vec3;

/// The laser's light at a surface point: the unit direction and distance to the
/// laser, and the radiance arriving (`LightSample::li`).
#[derive(Clone, Copy, Debug)]
pub struct LaserLight {
    pub dir: Vec3,
    pub dist: f32,
    pub li: Rgb,
}

/// The laser `laser` (at `origin`, its axis the unit `axis`) seen from point `p`
/// (geometric normal `ng`): `None` where it is hidden (`occluded(origin, dir, tmax)`
/// on the shadow segment, `geometry/shadow.rs`) or dark. `focus`: the laser is re-aimed
/// at `p`, so it sends its on-axis intensity (mitransient's `focus_laser`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn laser_light(
    laser: &Emitter,
    origin: Vec3,
    axis: Vec3,
    shapes: &[Shape],
    p: Vec3,
    ng: Vec3,
    focus: bool,
    occluded: impl FnOnce(Vec3, Vec3, f32) -> bool,
) -> Option<LaserLight> {
    let to_laser = origin - p;
    let dist = to_laser.length();
    if dist.is_nan() || dist <= 0.0 {
        return None;
    }
    let dir = to_laser / dist;
    // At a point on the laser's axis at the same distance when it is re-aimed, else
    // at p itself (delta lights draw no numbers).
    let at = if focus { origin + axis * dist } else { p };
    let ls = laser.sample(shapes, at, 1.0, 0.0, [0.0; 2])?;
    let (o, d, tmax) = shadow_segment(offset_origin(p, ng, dir), origin)?;
    if occluded(o, d, tmax) {
        return None;
    }
    Some(LaserLight {
        dir,
        dist,
        li: ls.li,
    })
}
