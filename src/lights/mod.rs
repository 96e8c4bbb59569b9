//! Emitters: area lights on shapes and point lights. The light pulse is a delta at
//! t = 0 at every emitter (SPEC 2).
//!
//! `area` (nested in a `<shape>`): | radiance | rgb/float | required | emitted radiance, front side only |
//!
//! `point` (top level): | intensity | rgb/float | 1 | radiant intensity (W/sr) |
//! | position | point | — | or `to_world` (its translation) |

use crate::geometry::shape::{AreaSampler, Shape};
use crate::math::Rgb;
use glam::Vec3;

#[derive(Clone, Debug)]
pub enum Emitter {
    Area {
        shape: u32,
        radiance: Rgb,
        sampler: AreaSampler,
    },
    Point {
        position: Vec3,
        intensity: Rgb,
    },
}

/// A sampled light connection from a reference point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// The point on the light.
    pub p: Vec3,
    /// The light's normal there (zero for point lights).
    pub n: Vec3,
    /// Unit direction from the reference point towards the light.
    pub wi: Vec3,
    pub dist: f32,
    /// Radiance (area) or intensity / dist^2 (point) arriving along -wi.
    pub li: Rgb,
    /// Solid-angle density including the choice of this light (for point lights: the
    /// choice probability only).
    pub pdf: f32,
    pub delta: bool,
}

impl Emitter {
    /// Samples a connection from `x` to this light; `select_pdf` is the probability of
    /// having chosen this light.
    #[inline(always)]
    pub fn sample(
        &self,
        shapes: &[Shape],
        x: Vec3,
        select_pdf: f32,
        u1: f32,
        u2: [f32; 2],
    ) -> Option<LightSample> {
        match self {
            Emitter::Area {
                shape,
                radiance,
                sampler,
            } => {
                let s = sampler.sample(&shapes[*shape as usize], u1, u2);
                let d = s.p - x;
                let dist2 = d.length_squared();
                let dist = dist2.sqrt();
                if dist <= 0.0 {
                    return None;
                }
                let wi = d / dist;
                let cos_l = -s.ns.dot(wi);
                if cos_l <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    p: s.p,
                    n: s.ng,
                    wi,
                    dist,
                    li: *radiance,
                    pdf: select_pdf * dist2 / (cos_l * sampler.total_area),
                    delta: false,
                })
            }
            Emitter::Point {
                position,
                intensity,
            } => {
                let d = *position - x;
                let dist2 = d.length_squared();
                if dist2 <= 0.0 {
                    return None;
                }
                let dist = dist2.sqrt();
                Some(LightSample {
                    p: *position,
                    n: Vec3::ZERO,
                    wi: d / dist,
                    dist,
                    li: *intensity / dist2,
                    pdf: select_pdf,
                    delta: true,
                })
            }
        }
    }

    /// Solid-angle density with which `sample` would have produced a point at distance
    /// `dist` whose normal makes cosine `cos_l` with the direction back to the reference.
    #[inline(always)]
    pub fn pdf_area_hit(&self, select_pdf: f32, dist: f32, cos_l: f32) -> f32 {
        match self {
            Emitter::Area { sampler, .. } if cos_l > 0.0 => {
                select_pdf * dist * dist / (cos_l * sampler.total_area)
            }
            _ => 0.0,
        }
    }
}
