//! Emitters: area lights on shapes, point and spot lights, and infinitely distant
//! lights (environment map, constant, directional). The light pulse is a delta at
//! t = 0 at every emitter (SPEC 2).
//!
//! `area` (nested in a `<shape>`): | radiance | rgb/float | 1 | emitted radiance, front side only |
//!
//! `point` (top level): | intensity | rgb/float | 1 | radiant intensity (W/sr) |
//! | position | point | — | or `to_world` (its translation) |
//!
//! `spot` (top level, Mitsuba 3's): a point light shining along the local +z of
//! `to_world`: | intensity | rgb/float | 1 | on the axis |
//! | cutoff_angle | float | 20 | degrees; no light beyond |
//! | beam_width | float | 3/4 cutoff_angle | degrees; full intensity within |
//! Between the two the intensity falls linearly in angle, as Mitsuba's `falloff_curve`.
//!
//! `angulararea` (nested in a `<shape>`, mitransient's): an area light emitting within
//! a cone about its normal (`angular_area.rs`).
//!
//! `projector` (top level, Mitsuba 3's): a delta-position light projecting a texture
//! through a perspective frustum (`projector.rs`).
//!
//! Infinitely distant emitters (top level; at most one `envmap` or `constant` per
//! scene, as Mitsuba's single environment emitter; any number of `directional`):
//!
//! `envmap`: see `envmap.rs`.
//!
//! `constant`: | radiance | rgb/float/spectrum | 1 | radiance arriving from every direction |
//! Light samples are uniform on the sphere (Mitsuba's `square_to_uniform_sphere`).
//!
//! `directional`: | irradiance | rgb/float/spectrum | 1 | irradiance on a surface facing the light |
//! | direction | vector | — | the direction the light travels, or `to_world` (its local +z) |
//! A delta in direction: reached by next-event estimation only, never by a ray.
//!
//! All three lie at distance `2 max(R, |x - c|)` from a reference point `x`
//! (`scene_sphere.rs`), for visibility and for time.

pub mod angular_area;
pub mod projector;
pub mod textured_area;
pub mod textured_spot;

pub use angular_area::AngularFalloff;
pub use projector::Projector;
pub use textured_area::TexturedArea;
pub use textured_spot::TexturedSpot;

pub mod distribution;
pub mod envmap;
pub mod laser;
pub mod scene_sphere;

use crate::geometry::shape::{AreaSampler, Shape};
use crate::math::sampling::uniform_sphere;
use crate::math::Rgb;
use envmap::EnvMap;
use glam::{Vec2, Vec3};
use scene_sphere::SceneSphere;
use std::sync::Arc;

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
        /// A spot light's cone (none: shines in every direction).
        spot: Option<Spot>,
    },
    /// An area light whose emission is restricted to a cone about its normal.
    AngularArea {
        shape: u32,
        radiance: Rgb,
        sampler: AreaSampler,
        falloff: AngularFalloff,
    },
    Projector(Box<Projector>),
    /// An `area` light whose radiance is a bitmap or checkerboard (`textured_area.rs`).
    TexturedArea(Box<TexturedArea>),
    /// A `spot` light projecting a texture (`textured_spot.rs`).
    TexturedSpot(Box<TexturedSpot>),
    /// An environment image (`envmap`).
    Envmap {
        map: Arc<EnvMap>,
        sphere: SceneSphere,
    },
    /// Uniform radiance from every direction (`constant`).
    Constant {
        radiance: Rgb,
        sphere: SceneSphere,
    },
    /// Parallel light travelling along `direction` (unit), `irradiance` on a surface
    /// facing it (`directional`).
    Directional {
        direction: Vec3,
        irradiance: Rgb,
        sphere: SceneSphere,
    },
}

/// The cone of a `spot` light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spot {
    /// The beam's axis in world space (unit).
    pub axis: Vec3,
    /// Angles in radians.
    pub cutoff: f32,
    pub beam_width: f32,
}

impl Spot {
    /// The fraction of the on-axis intensity emitted along unit direction `d` (from the
    /// light): 1 within `beam_width`, 0 beyond `cutoff`, linear in angle between.
    #[inline]
    pub fn falloff(&self, d: Vec3) -> f32 {
        let cos_theta = self.axis.dot(d);
        if cos_theta <= self.cutoff.cos() {
            return 0.0;
        }
        if cos_theta >= self.beam_width.cos() {
            return 1.0;
        }
        let theta = cos_theta.clamp(-1.0, 1.0).acos();
        ((self.cutoff - theta) / (self.cutoff - self.beam_width)).clamp(0.0, 1.0)
    }
}

/// A sampled light connection from a reference point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// The point on the light (for infinitely distant lights: at `dist` along `wi`).
    pub p: Vec3,
    /// The light's normal there (zero for point lights).
    pub n: Vec3,
    /// Unit direction from the reference point towards the light.
    pub wi: Vec3,
    pub dist: f32,
    /// Radiance (area, envmap, constant), intensity / dist^2 (point) or irradiance
    /// (directional) arriving along -wi.
    pub li: Rgb,
    /// Solid-angle density including the choice of this light (for point and
    /// directional lights: the choice probability only).
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
            } => sample_area(&shapes[*shape as usize], sampler, x, select_pdf, u1, u2).map(
                |(ls, _)| LightSample {
                    li: *radiance,
                    ..ls
                },
            ),
            Emitter::AngularArea {
                shape,
                radiance,
                sampler,
                falloff,
            } => {
                let (ls, cos_l) =
                    sample_area(&shapes[*shape as usize], sampler, x, select_pdf, u1, u2)?;
                let li = angular_area::angular_radiance(*radiance, falloff, cos_l)?;
                Some(LightSample { li, ..ls })
            }
            Emitter::Projector(p) => p.sample(x, select_pdf),
            Emitter::TexturedArea(t) => t.sample(shapes, x, select_pdf, u1, u2),
            Emitter::TexturedSpot(t) => t.sample(x, select_pdf),
            Emitter::Point {
                position,
                intensity,
                spot,
            } => {
                let d = *position - x;
                let dist2 = d.length_squared();
                if dist2 <= 0.0 {
                    return None;
                }
                let dist = dist2.sqrt();
                let wi = d / dist;
                let falloff = match spot {
                    None => 1.0,
                    Some(s) => s.falloff(-wi),
                };
                if falloff <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    p: *position,
                    n: Vec3::ZERO,
                    wi,
                    dist,
                    li: *intensity * (falloff / dist2),
                    pdf: select_pdf,
                    delta: true,
                })
            }
            Emitter::Envmap { map, sphere } => {
                let (wi, li, pdf) = map.sample(u2)?;
                Some(distant(sphere, x, wi, li, select_pdf * pdf, false))
            }
            Emitter::Constant { radiance, sphere } => {
                let wi = uniform_sphere(u2);
                let pdf = select_pdf * UNIFORM_SPHERE_PDF;
                Some(distant(sphere, x, wi, *radiance, pdf, false))
            }
            Emitter::Directional {
                direction,
                irradiance,
                sphere,
            } => Some(distant(
                sphere,
                x,
                -*direction,
                *irradiance,
                select_pdf,
                true,
            )),
        }
    }

    /// Whether this emitter is infinitely distant (`envmap`, `constant`, `directional`).
    pub fn is_infinite(&self) -> bool {
        matches!(
            self,
            Emitter::Envmap { .. } | Emitter::Constant { .. } | Emitter::Directional { .. }
        )
    }

    /// A laser's position and axis (to_world's origin and +z) for NLOS captures:
    /// `projector` and `spot` lights; `None` for every other kind.
    pub fn laser_frame(&self) -> Option<(Vec3, Vec3)> {
        match self {
            Emitter::Projector(p) => Some((p.position, p.axis)),
            Emitter::Point {
                position,
                spot: Some(s),
                ..
            } => Some((*position, s.axis)),
            Emitter::TexturedSpot(t) => Some((t.position, t.spot.axis)),
            _ => None,
        }
    }

    /// Moves and re-aims a projector to `to_world` (the legacy `laser_origin` of an
    /// `nlos_capture_meter`); false for every other kind.
    pub fn set_projector_frame(&mut self, to_world: glam::DMat4) -> bool {
        match self {
            Emitter::Projector(p) => {
                p.position = to_world.transform_point3(glam::DVec3::ZERO).as_vec3();
                p.to_local = to_world.inverse().as_mat4();
                p.axis = to_world.transform_vector3(glam::DVec3::Z).as_vec3();
                true
            }
            _ => false,
        }
    }

    /// A projector's position and world axes (to_world's x, y, z columns), for
    /// mitransient's exhaustive laser scan; `None` for every other kind.
    pub fn laser_axes(&self) -> Option<(Vec3, [Vec3; 3])> {
        match self {
            Emitter::Projector(p) => {
                let m = p.to_local.inverse();
                Some((
                    p.position,
                    [
                        m.transform_vector3(Vec3::X),
                        m.transform_vector3(Vec3::Y),
                        m.transform_vector3(Vec3::Z),
                    ],
                ))
            }
            _ => None,
        }
    }

    /// Whether a ray that leaves the scene sees this emitter (`envmap`, `constant`).
    pub fn is_environment(&self) -> bool {
        matches!(self, Emitter::Envmap { .. } | Emitter::Constant { .. })
    }

    /// An environment emitter's radiance arriving along `-d` for a ray leaving the
    /// scene in unit direction `d`, the solid-angle density (times `select_pdf`) with
    /// which `sample` picks `d`, and the ray's length to it from origin `o` (as a light
    /// sample's `dist`). Zero for other emitters.
    #[inline]
    pub fn escape(&self, select_pdf: f32, o: Vec3, d: Vec3) -> (Rgb, f32, f32) {
        match self {
            Emitter::Envmap { map, sphere } => (
                map.eval(d),
                select_pdf * map.pdf(d),
                sphere.distance_from(o),
            ),
            Emitter::Constant { radiance, sphere } => (
                *radiance,
                select_pdf * UNIFORM_SPHERE_PDF,
                sphere.distance_from(o),
            ),
            _ => (Rgb::ZERO, 0.0, 0.0),
        }
    }

    /// Tells an infinitely distant emitter the scene's bounding sphere (Mitsuba's
    /// `set_scene`).
    pub fn set_scene_sphere(&mut self, s: SceneSphere) {
        match self {
            Emitter::Envmap { sphere, .. }
            | Emitter::Constant { sphere, .. }
            | Emitter::Directional { sphere, .. } => *sphere = s,
            Emitter::Area { .. }
            | Emitter::Point { .. }
            | Emitter::AngularArea { .. }
            | Emitter::Projector(_)
            | Emitter::TexturedArea(_)
            | Emitter::TexturedSpot(_) => {}
        }
    }

    /// Solid-angle density with which `sample` would have produced a point at distance
    /// `dist` whose normal makes cosine `cos_l` with the direction back to the reference.
    /// An angular light's is 0 outside its cone (mitransient's `pdf_direction`).
    #[inline(always)]
    pub fn pdf_area_hit(&self, select_pdf: f32, dist: f32, cos_l: f32) -> f32 {
        match self {
            Emitter::Area { sampler, .. } if cos_l > 0.0 => {
                select_pdf * dist * dist / (cos_l * sampler.total_area)
            }
            Emitter::AngularArea {
                sampler, falloff, ..
            } if cos_l > 0.0 && falloff.eval(cos_l) > 0.0 => {
                select_pdf * dist * dist / (cos_l * sampler.total_area)
            }
            Emitter::TexturedArea(t) if cos_l > 0.0 => {
                select_pdf * dist * dist / (cos_l * t.sampler.total_area)
            }
            _ => 0.0,
        }
    }

    /// The radiance a shape's light emits towards cosine `cos_l` > 0 from its normal
    /// (front side); None for an angular light seen outside its cone. `uv` gives the
    /// hit's texture coordinates, asked for by textured lights only.
    #[inline(always)]
    pub fn emitted(&self, cos_l: f32, uv: impl FnOnce() -> Vec2) -> Option<Rgb> {
        match self {
            Emitter::Area { radiance, .. } => Some(*radiance),
            Emitter::TexturedArea(t) => Some(t.emitted(uv())),
            Emitter::AngularArea {
                radiance, falloff, ..
            } => angular_area::angular_radiance(*radiance, falloff, cos_l),
            _ => unreachable!("shape emitters are area lights"),
        }
    }
}

/// A point sampled uniformly by area on a shape, as a connection from `x` (radiance
/// left zero for the caller), with the cosine at the light; None when the point faces
/// away from `x`.
#[inline(always)]
fn sample_area(
    shape: &Shape,
    sampler: &AreaSampler,
    x: Vec3,
    select_pdf: f32,
    u1: f32,
    u2: [f32; 2],
) -> Option<(LightSample, f32)> {
    connect(
        sampler.sample(shape, u1, u2),
        sampler.total_area,
        x,
        select_pdf,
    )
}

/// The connection from `x` to a point `s` sampled uniformly on a light of area
/// `total_area` (radiance left zero), with the cosine at the light; None when the
/// point faces away from `x`.
#[inline(always)]
fn connect(
    s: crate::geometry::shape::SurfacePoint,
    total_area: f32,
    x: Vec3,
    select_pdf: f32,
) -> Option<(LightSample, f32)> {
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
    Some((
        LightSample {
            p: s.p,
            n: s.ng,
            wi,
            dist,
            li: Rgb::ZERO,
            pdf: select_pdf * dist2 / (cos_l * total_area),
            delta: false,
        },
        cos_l,
    ))
}

/// `1 / (4 pi)`.
const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * std::f32::consts::PI);

/// A light sample of an infinitely distant emitter in direction `wi` from `x`.
#[inline]
fn distant(sphere: &SceneSphere, x: Vec3, wi: Vec3, li: Rgb, pdf: f32, delta: bool) -> LightSample {
    let dist = sphere.distance_from(x);
    LightSample {
        p: x + wi * dist,
        n: -wi,
        wi,
        dist,
        li,
        pdf,
        delta,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spot_falloff_is_mitsubas_linear_ramp_in_angle() {
        let s = Spot {
            axis: Vec3::Z,
            cutoff: 20f32.to_radians(),
            beam_width: 15f32.to_radians(),
        };
        let at = |deg: f32| {
            let t = deg.to_radians();
            s.falloff(Vec3::new(t.sin(), 0.0, t.cos()))
        };
        assert_eq!(at(0.0), 1.0);
        assert_eq!(at(14.9), 1.0);
        assert!((at(17.5) - 0.5).abs() < 1e-3, "{}", at(17.5));
        assert!((at(19.0) - 0.2).abs() < 1e-3);
        assert_eq!(at(20.1), 0.0);
        assert_eq!(at(90.0), 0.0);
    }
}
