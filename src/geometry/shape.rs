//! Shapes in world space, as the renderer sees them: triangle meshes (rectangle, cube,
//! ply, obj), analytic spheres, disks and cylinders, and SDF grids, with their surface
//! data and area sampling.

use super::curve::CurveGeom;
use super::cylinder::CylinderGeom;
use super::disk::DiskGeom;
use super::mesh_attributes::MeshAttributes;
use super::sdfgrid::SdfGeom;
use super::sphere::SphereGeom;
use super::triangle::TriangleGeom;
use crate::math::sampling::{uniform_sphere, uniform_triangle};
use glam::{Mat3, Vec2, Vec3};
use std::sync::Arc;

#[derive(Clone, Debug)]
pub enum ShapeGeom {
    Mesh {
        positions: Vec<Vec3>,
        /// Per-vertex shading normals (unit length), when the mesh has them.
        normals: Option<Vec<Vec3>>,
        triangles: Vec<[u32; 3]>,
        /// Per-vertex texture coordinates, when the shape has them (the built-in
        /// rectangle and cube always; file meshes when the file gives them).
        uvs: Option<Vec<Vec2>>,
        /// Per-vertex and per-face attributes from the mesh file (PLY), when it has
        /// any (`mesh_attribute` textures read them).
        attributes: Option<Arc<MeshAttributes>>,
    },
    /// An analytic sphere and its `to_local` map: the linear part of the inverse of
    /// Mitsuba's `to_world * translate(center) * scale(radius)`, so that
    /// `to_local * (p - center)` is the hit on the unit sphere in object space (uv only).
    Sphere(SphereGeom, Mat3),
    /// An analytic disk (`disk.rs`).
    Disk(DiskGeom),
    /// An analytic open cylinder (`cylinder.rs`).
    Cylinder(CylinderGeom),
    /// Mitsuba's `linearcurve` or `bsplinecurve` (`curve.rs`): one BVH primitive per
    /// segment; `face` is the segment and `b1` the curve parameter of a hit on it.
    Curve(CurveGeom),
    /// A signed distance function grid (`sdfgrid.rs`): one primitive per non-empty
    /// voxel, its index the hit's `face`. Boxed: the enum keeps the size it has
    /// without it.
    Sdf(Box<SdfGeom>),
}

/// One shape of the scene.
#[derive(Clone, Debug)]
pub struct Shape {
    /// The id from the scene file, or `shape#N`.
    pub name: String,
    pub geom: ShapeGeom,
    /// Normals point inward (Mitsuba's `flip_normals`).
    pub flip_normals: bool,
    /// Index into the scene's BSDFs.
    pub bsdf: u32,
    /// Index into the scene's emitters, when the shape is an area light.
    pub emitter: Option<u32>,
    /// Indices into the scene's media: inside (against the geometric normal) and
    /// outside (along it), Mitsuba's `interior` / `exterior`.
    pub interior: Option<u32>,
    pub exterior: Option<u32>,
}

/// Where a ray met a surface.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub p: Vec3,
    /// Geometric normal (unit, oriented by winding / outward, flipped by flip_normals).
    pub ng: Vec3,
    /// Shading normal (unit), on the same side as `ng`.
    pub ns: Vec3,
}

impl Shape {
    /// Whether crossing this shape changes the medium (Mitsuba's
    /// `is_medium_transition`).
    #[inline]
    pub fn is_medium_transition(&self) -> bool {
        self.interior.is_some() || self.exterior.is_some()
    }

    /// The medium a ray leaving the surface along `d` enters: the exterior when `d`
    /// points along the geometric normal `ng`, else the interior (Mitsuba's
    /// `target_medium`).
    #[inline]
    pub fn target_medium(&self, d: Vec3, ng: Vec3) -> Option<u32> {
        if d.dot(ng) > 0.0 {
            self.exterior
        } else {
            self.interior
        }
    }

    pub fn triangle(&self, face: u32) -> TriangleGeom {
        match &self.geom {
            ShapeGeom::Mesh {
                positions,
                triangles,
                ..
            } => {
                let [a, b, c] = triangles[face as usize];
                TriangleGeom::new(
                    positions[a as usize],
                    positions[b as usize],
                    positions[c as usize],
                )
            }
            _ => unreachable!("analytic shapes have no faces"),
        }
    }

    /// The surface point at barycentrics (b1, b2) of triangle `face`, or at `p` on a sphere.
    pub fn surface(&self, face: u32, b1: f32, b2: f32, p_hint: Vec3) -> SurfacePoint {
        let sign = if self.flip_normals { -1.0 } else { 1.0 };
        match &self.geom {
            ShapeGeom::Mesh { .. } => self.surface_of(&self.triangle(face), face, b1, b2),
            ShapeGeom::Sphere(s, _) => {
                let n = (p_hint - s.center).normalize_or_zero();
                // Project onto the surface to remove the hit's rounding error.
                let p = s.center + n * s.radius;
                SurfacePoint {
                    p,
                    ng: n * sign,
                    ns: n * sign,
                }
            }
            ShapeGeom::Disk(g) => SurfacePoint {
                p: g.project(p_hint),
                ng: g.n * sign,
                ns: g.n * sign,
            },
            ShapeGeom::Cylinder(g) => {
                let (p, n) = g.project(p_hint);
                SurfacePoint {
                    p,
                    ng: n * sign,
                    ns: n * sign,
                }
            }
            ShapeGeom::Curve(g) => {
                let n = g.normal(face as usize, b1, p_hint) * sign;
                SurfacePoint {
                    p: p_hint,
                    ng: n,
                    ns: n,
                }
            }
            // No flip_normals (Mitsuba's sdfgrid takes none); `face` is the voxel.
            ShapeGeom::Sdf(g) => {
                let (ng, ns) = g.normals(face, p_hint);
                SurfacePoint { p: p_hint, ng, ns }
            }
        }
    }

    /// The surface point on triangle `face` whose geometry `tri` the caller already has.
    #[inline(always)]
    pub fn surface_of(&self, tri: &TriangleGeom, face: u32, b1: f32, b2: f32) -> SurfacePoint {
        let sign = if self.flip_normals { -1.0 } else { 1.0 };
        let ng = tri.cross().normalize_or_zero() * sign;
        let ns = match &self.geom {
            ShapeGeom::Mesh {
                normals: Some(n),
                triangles,
                ..
            } => {
                let [a, b, c] = triangles[face as usize];
                let v = n[a as usize] * (1.0 - b1 - b2) + n[b as usize] * b1 + n[c as usize] * b2;
                v.try_normalize().map_or(ng, |v| v * sign)
            }
            _ => ng,
        };
        SurfacePoint {
            p: tri.point(b1, b2),
            ng,
            ns,
        }
    }

    /// Texture coordinates at a surface point, with Mitsuba 3's convention for each
    /// shape: a mesh's per-vertex uv interpolated at the barycentrics (b1, b2) of
    /// triangle `face` (`src/render/mesh.cpp`), or (b1, b2) themselves when the mesh has
    /// none; on a sphere, `(phi / 2 pi, theta / pi)` of the object-space point, phi
    /// measured from +x towards +y in [0, 2 pi) and theta from +z (`src/shapes/sphere.cpp`).
    /// Disks: (r, phi / 2 pi); cylinders: (phi / 2 pi, z) (`disk.rs`, `cylinder.rs`).
    /// `p` is the hit point (analytic shapes only). Computed only when a texture asks.
    pub fn uv(&self, face: u32, b1: f32, b2: f32, p: Vec3) -> Vec2 {
        match &self.geom {
            ShapeGeom::Mesh {
                uvs: Some(uv),
                triangles,
                ..
            } => {
                let [a, b, c] = triangles[face as usize];
                let uv0 = uv[a as usize];
                uv0 + (uv[b as usize] - uv0) * b1 + (uv[c as usize] - uv0) * b2
            }
            ShapeGeom::Mesh { uvs: None, .. } => Vec2::new(b1, b2),
            ShapeGeom::Sphere(s, to_local) => {
                let l = (*to_local * (p - s.center)).normalize_or_zero();
                // Dr.Jit's unit_angle_z: acos(l.z) computed without its loss of
                // precision near the poles.
                let theta = if l.z >= 0.0 {
                    2.0 * (0.5 * (l - Vec3::Z).length()).min(1.0).asin()
                } else {
                    std::f32::consts::PI - 2.0 * (0.5 * (l + Vec3::Z).length()).min(1.0).asin()
                };
                let mut phi = l.y.atan2(l.x);
                if phi < 0.0 {
                    phi += std::f32::consts::TAU;
                }
                Vec2::new(
                    phi * std::f32::consts::FRAC_1_PI * 0.5,
                    theta * std::f32::consts::FRAC_1_PI,
                )
            }
            ShapeGeom::Disk(g) => g.uv(p),
            ShapeGeom::Cylinder(g) => g.uv(p),
            ShapeGeom::Curve(g) => g.uv(face as usize, b1, p),
            // Mitsuba's sdfgrid emits no uv (zero).
            ShapeGeom::Sdf(_) => Vec2::ZERO,
        }
    }

    /// The mesh's attributes, if it has any.
    pub fn attributes(&self) -> Option<&MeshAttributes> {
        match &self.geom {
            ShapeGeom::Mesh { attributes, .. } => attributes.as_deref(),
            _ => None,
        }
    }

    /// The position's derivative along u, dp/du, at a surface point, with Mitsuba 3's
    /// convention for each shape (the direction anisotropic roughness's `alpha_u`
    /// follows, [`crate::math::frame::Frame::from_normal_tangent`]):
    /// - a mesh with uv: the derivative of the triangle's linear map from uv to
    ///   position (constant over the triangle, the same on both triangles of a planar
    ///   face with a linear uv), or, where the triangle's uvs are degenerate (zero
    ///   determinant), the first axis of `Frame::from_normal` of its unflipped face
    ///   normal, as `src/render/mesh.cpp` does;
    /// - a mesh without uv (the barycentrics are uv): `p1 - p0`;
    /// - a sphere: the world image of `2 pi (-y, x, 0)` at the object-space point
    ///   (`src/shapes/sphere.cpp`), zero at the poles.
    ///
    /// - a disk: to_world (cos phi, sin phi, 0); a cylinder: to_world 2 pi (-y, x, 0).
    ///
    /// Rectangles and cubes are meshes with Mitsuba's uv, so theirs is Mitsuba's too.
    /// `p` is the hit point (spheres only; a triangle's dp/du does not depend on the
    /// barycentrics). Computed only for anisotropic materials.
    pub fn dpdu(&self, face: u32, b1: f32, _b2: f32, p: Vec3) -> Vec3 {
        match &self.geom {
            ShapeGeom::Mesh { uvs, triangles, .. } => {
                let tri = self.triangle(face);
                let Some(uv) = uvs else {
                    return tri.e1;
                };
                let [a, b, c] = triangles[face as usize];
                let (uv0, uv1, uv2) = (uv[a as usize], uv[b as usize], uv[c as usize]);
                let (duv0, duv1) = (uv1 - uv0, uv2 - uv0);
                let det = duv0.x * duv1.y - duv0.y * duv1.x;
                let dpdu = (tri.e1 * duv1.y - tri.e2 * duv0.y) / det;
                if det != 0.0 && dpdu.is_finite() {
                    dpdu
                } else {
                    crate::math::frame::Frame::from_normal(tri.cross().normalize_or_zero()).s
                }
            }
            ShapeGeom::Sphere(s, to_local) => {
                let l = (*to_local * (p - s.center)).normalize_or_zero();
                to_local.inverse() * (Vec3::new(-l.y, l.x, 0.0) * std::f32::consts::TAU)
            }
            ShapeGeom::Disk(g) => g.dpdu(p),
            ShapeGeom::Cylinder(g) => g.dpdu(p),
            ShapeGeom::Curve(g) => g.dpduv(face as usize, b1, p).0,
            // Zero, as Mitsuba's sdfgrid leaves it: the frame is `Frame::from_normal`.
            ShapeGeom::Sdf(_) => Vec3::ZERO,
        }
    }

    /// The position's derivative along v, dp/dv, with the conventions of
    /// [`Self::dpdu`] (Mitsuba 3's): a mesh with uv, the derivative of the triangle's
    /// map from uv (degenerate uv: the second axis of `Frame::from_normal` of its
    /// unflipped face normal); without uv, `p2 - p0`; a sphere, the world image of
    /// `pi (z cos phi, z sin phi, -r_xy)` at the object-space point (`pi (1, 0, 0)` at
    /// the poles); a curve's at its parameter `b1` (Mitsuba's). Computed only for bump
    /// maps.
    pub fn dpdv(&self, face: u32, b1: f32, p: Vec3) -> Vec3 {
        match &self.geom {
            ShapeGeom::Mesh { uvs, triangles, .. } => {
                let tri = self.triangle(face);
                let Some(uv) = uvs else {
                    return tri.e2;
                };
                let [a, b, c] = triangles[face as usize];
                let (uv0, uv1, uv2) = (uv[a as usize], uv[b as usize], uv[c as usize]);
                let (duv0, duv1) = (uv1 - uv0, uv2 - uv0);
                let det = duv0.x * duv1.y - duv0.y * duv1.x;
                let dpdv = (tri.e2 * duv0.x - tri.e1 * duv1.x) / det;
                if det != 0.0 && dpdv.is_finite() {
                    dpdv
                } else {
                    crate::math::frame::Frame::from_normal(tri.cross().normalize_or_zero()).t
                }
            }
            ShapeGeom::Sphere(s, to_local) => {
                let l = (*to_local * (p - s.center)).normalize_or_zero();
                let rd = (l.x * l.x + l.y * l.y).sqrt();
                let v = if rd == 0.0 {
                    Vec3::X
                } else {
                    Vec3::new(l.z * l.x / rd, l.z * l.y / rd, -rd)
                };
                to_local.inverse() * (v * std::f32::consts::PI)
            }
            ShapeGeom::Disk(g) => g.dpdv(p),
            ShapeGeom::Cylinder(g) => g.dpdv(),
            ShapeGeom::Curve(g) => g.dpduv(face as usize, b1, p).1,
            ShapeGeom::Sdf(_) => Vec3::ZERO,
        }
    }

    pub fn area(&self) -> f64 {
        match &self.geom {
            ShapeGeom::Mesh { triangles, .. } => (0..triangles.len() as u32)
                .map(|f| self.triangle(f).area() as f64)
                .sum(),
            ShapeGeom::Sphere(s, _) => s.area() as f64,
            ShapeGeom::Disk(g) => g.area as f64,
            ShapeGeom::Cylinder(g) => g.area() as f64,
            // Mitsuba defines no area for curves (they cannot emit).
            ShapeGeom::Curve(_) => f64::NAN,
            // Mitsuba's sdfgrid reports 0 (and cannot emit).
            ShapeGeom::Sdf(_) => 0.0,
        }
    }

    /// An axis-aligned box around the shape (world space).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        match &self.geom {
            ShapeGeom::Mesh { positions, .. } => positions
                .iter()
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                    (lo.min(p), hi.max(p))
                }),
            ShapeGeom::Sphere(s, _) => (
                s.center - Vec3::splat(s.radius),
                s.center + Vec3::splat(s.radius),
            ),
            ShapeGeom::Disk(g) => g.bounds(),
            ShapeGeom::Cylinder(g) => g.bounds(),
            ShapeGeom::Curve(g) => g.bounds(),
            ShapeGeom::Sdf(g) => g.bounds(),
        }
    }
}

/// Meshes of at most this many triangles choose the triangle with the 2D number
/// ([`AreaSampler::pick_face`]).
pub const REMAP_FACES: usize = 16;

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Uniform-by-area sampling of a shape's surface (for area lights).
#[derive(Clone, Debug)]
pub struct AreaSampler {
    /// Cumulative triangle areas normalised to end at 1 (empty for analytic shapes).
    cdf: Vec<f32>,
    /// The triangles, in face order (empty for analytic shapes).
    tris: Vec<TriangleGeom>,
    pub total_area: f32,
}

impl AreaSampler {
    pub fn new(shape: &Shape) -> Self {
        match &shape.geom {
            ShapeGeom::Mesh { triangles, .. } => {
                let mut acc = 0.0f64;
                let mut cdf: Vec<f32> = (0..triangles.len() as u32)
                    .map(|f| {
                        acc += shape.triangle(f).area() as f64;
                        acc as f32
                    })
                    .collect();
                for c in cdf.iter_mut() {
                    *c /= acc as f32;
                }
                AreaSampler {
                    cdf,
                    tris: (0..triangles.len() as u32)
                        .map(|f| shape.triangle(f))
                        .collect(),
                    total_area: acc as f32,
                }
            }
            ShapeGeom::Sphere(..)
            | ShapeGeom::Disk(_)
            | ShapeGeom::Cylinder(_)
            | ShapeGeom::Curve(_)
            | ShapeGeom::Sdf(_) => AreaSampler {
                cdf: Vec::new(),
                tris: Vec::new(),
                total_area: shape.area() as f32,
            },
        }
    }

    /// The triangle a sample lands on, and the 2D number for the point in it. A mesh of
    /// at most [`REMAP_FACES`] triangles (a `rectangle` is two, a `cube` twelve) picks
    /// the triangle with `u2[0]` and rescales it to [0, 1) within the triangle's share,
    /// so that a stratified `u2` stays stratified over the whole surface (with `u1`
    /// picking, a low-discrepancy `u2` is split between the triangles at random); the
    /// rescaled number keeps at least 20 of its 24 bits. Larger meshes pick with `u1`.
    #[inline(always)]
    fn pick_face(&self, u1: f32, u2: [f32; 2]) -> (usize, [f32; 2]) {
        let last = self.cdf.len() - 1;
        if self.cdf.len() <= REMAP_FACES {
            let face = self.cdf.partition_point(|&c| c <= u2[0]).min(last);
            let lo = if face == 0 { 0.0 } else { self.cdf[face - 1] };
            let share = self.cdf[face] - lo;
            let u = if share > 0.0 {
                ((u2[0] - lo) / share).clamp(0.0, ONE_MINUS_EPSILON)
            } else {
                0.0
            };
            (face, [u, u2[1]])
        } else {
            (self.cdf.partition_point(|&c| c <= u1).min(last), u2)
        }
    }

    /// [`Self::sample`] and the point's uv (`Shape::uv`), for textured lights.
    pub fn sample_with_uv(&self, shape: &Shape, u1: f32, u2: [f32; 2]) -> (SurfacePoint, Vec2) {
        match &shape.geom {
            ShapeGeom::Mesh { .. } => {
                let (face, u2) = self.pick_face(u1, u2);
                let [b1, b2] = uniform_triangle(u2);
                let s = shape.surface_of(&self.tris[face], face as u32, b1, b2);
                (s, shape.uv(face as u32, b1, b2, s.p))
            }
            _ => {
                let s = self.sample(shape, u1, u2);
                (s, shape.uv(0, 0.0, 0.0, s.p))
            }
        }
    }

    /// A point uniformly distributed by area; pdf (per unit area) = 1 / total_area.
    #[inline(always)]
    pub fn sample(&self, shape: &Shape, u1: f32, u2: [f32; 2]) -> SurfacePoint {
        match &shape.geom {
            ShapeGeom::Mesh { .. } => {
                let (face, u2) = self.pick_face(u1, u2);
                let [b1, b2] = uniform_triangle(u2);
                shape.surface_of(&self.tris[face], face as u32, b1, b2)
            }
            ShapeGeom::Sphere(s, _) => {
                let p = s.center + uniform_sphere(u2) * s.radius;
                shape.surface(0, 0.0, 0.0, p)
            }
            ShapeGeom::Disk(g) => shape.surface(0, 0.0, 0.0, g.sample(u2)),
            ShapeGeom::Cylinder(g) => shape.surface(0, 0.0, 0.0, g.sample(u2)),
            ShapeGeom::Curve(_) => unreachable!("the scene parser refuses emitters on curves"),
            ShapeGeom::Sdf(_) => unreachable!("an sdfgrid cannot emit: refused when loading"),
        }
    }
}
