//! Hidden-geometry sampling (`nlos_hidden_geometry_sampling`): a path continues
//! towards a uniform point of the hidden geometry the scene listed at load
//! (`scene::nlos_setup::HiddenGeometry`: shapes chosen by area, then a uniform point on the
//! chosen one, so each point has density 1 / area), converted to solid angle.

use crate::geometry::accel::Hit;
use crate::geometry::shape::Shape;
use crate::scene::nlos_setup::HiddenGeometry;
use glam::Vec3;

/// The solid-angle density with which [`sample`] picks direction `dir` from point `p`
/// (geometric normal `ng`), taken at `hit`, where the ray first meets the scene: 0
/// unless that is hidden geometry facing `p` and `p`'s normal faces it (mitransient's
/// validity test of a sample).
#[inline]
pub fn pdf(hidden: &HiddenGeometry, p: Vec3, ng: Vec3, hit: &Hit, dir: Vec3) -> f32 {
    if !hidden.member[hit.shape as usize] {
        return 0.0;
    }
    let cos_i = ng.dot(dir);
    let cos_g = hit.surface.ng.dot(-dir);
    let eps = f32::EPSILON / 2.0;
    if !(cos_i > eps && cos_g > eps) {
        return 0.0;
    }
    let d2 = (hit.surface.p - p).length_squared();
    d2 / (hidden.total_area * cos_g)
}

/// A uniform point of the hidden geometry: (point, geometric normal); density
/// `1 / total_area`. `u1` picks the shape, `u2` the point.
#[inline]
pub fn sample(hidden: &HiddenGeometry, shapes: &[Shape], u1: f32, u2: [f32; 2]) -> (Vec3, Vec3) {
    let i = hidden
        .cdf
        .partition_point(|&c| c <= u1)
        .min(hidden.cdf.len() - 1);
    let shape = &shapes[hidden.shapes[i] as usize];
    // A second uniform for the triangle of a large mesh: the shape choice's own
    // number, rescaled within its share.
    let lo = if i == 0 { 0.0 } else { hidden.cdf[i - 1] };
    let share = hidden.cdf[i] - lo;
    let u_tri = if share > 0.0 {
        ((u1 - lo) / share).clamp(0.0, 1.0 - f32::EPSILON / 2.0)
    } else {
        0.0
    };
    let s = hidden.samplers[i].sample(shape, u_tri, u2);
    (s.p, s.ng)
}
