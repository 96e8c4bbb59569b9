//! `shapegroup` and `instance` (Mitsuba 3's instancing), by flattening: every instance
//! adds world-space copies of its group's shapes, each child's geometry mapped by the
//! instance's `to_world` (after the child's own), with the child's BSDF.
//!
//! | shape | parameters |
//! |-------|------------|
//! | shapegroup | `id` (required); nested `<shape>`s of any kind but shapegroup and instance, without emitters (Mitsuba: "Instancing of emitters is not supported") |
//! | instance | `to_world` (identity); one `<ref id>` naming a shapegroup declared before it |
//!
//! Orientation follows Mitsuba's instance, which maps the child's normal by the normal
//! transform of `to_world`: a mirroring instance (negative determinant) keeps the
//! mapped normal, so mesh triangles swap their winding (their normal would otherwise
//! flip with the mirror); analytic shapes already take their normal from the map.
//!
//! Memory: the copies cost what the same shapes written out would (about 150 bytes per
//! triangle with its BVH share); instances may add at most [`MAX_INSTANCED_TRIANGLES`]
//! triangles to a scene (about 3 GB), beyond which loading fails.

use crate::geometry::curve::CurveKind;
use crate::geometry::cylinder::CylinderGeom;
use crate::geometry::disk::DiskGeom;
use crate::geometry::error::GeometryError;
use crate::geometry::shape::ShapeGeom;
use crate::geometry::sphere::SphereGeom;
use crate::scene::limits::{check_world_point, WorldPointError};
use glam::{DMat3, DMat4, DVec3, Mat3};

/// Why a shape of a shapegroup cannot be placed by an instance's `to_world`.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum InstanceError {
    /// The instance's `to_world` is singular or not finite.
    #[error("the instance's to_world is singular")]
    Singular,
    /// A mesh vertex mapped beyond the world's limits.
    #[error("vertex {vertex}: {point}")]
    Vertex {
        vertex: usize,
        point: WorldPointError,
    },
    /// A mapped mesh triangle whose area overflows single precision.
    #[error("triangle {triangle} is too large for single-precision arithmetic")]
    TriangleTooLarge { triangle: usize },
    /// A sphere mapped by a non-uniform scale.
    #[error("an instance of a sphere must scale uniformly")]
    SphereScale,
    /// A sphere whose mapped radius is below single precision or beyond the limits.
    #[error("the instanced sphere's radius {radius:e} is out of range")]
    SphereRadius { radius: f64 },
    /// A curve (tstat keeps curves in world space only).
    #[error(
        "a {} cannot be instanced (shapegroup): tstat supports curves at the top level only",
        .kind.name()
    )]
    Curve { kind: CurveKind },
    /// The mapped analytic shape cannot be built.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// A point of the mapped shape (its centre or box) lies beyond the world's limits.
    #[error(transparent)]
    WorldPoint(#[from] WorldPointError),
}

/// The most triangles instances may add to one scene.
pub const MAX_INSTANCED_TRIANGLES: usize = 20_000_000;

/// The number of primitives a geometry adds: its triangles, an SDF grid's non-empty
/// voxels, 1 for the other analytic shapes.
pub fn triangle_count(g: &ShapeGeom) -> usize {
    match g {
        ShapeGeom::Mesh { triangles, .. } => triangles.len(),
        ShapeGeom::Sdf(g) => g.voxel_count(),
        _ => 1,
    }
}

/// `g` (world space of the group) mapped by the instance's `m`.
pub fn transformed(g: &ShapeGeom, m: &DMat4) -> Result<ShapeGeom, InstanceError> {
    let lin = DMat3::from_mat4(*m);
    let det = lin.determinant();
    if !(det != 0.0 && det.is_finite()) {
        return Err(InstanceError::Singular);
    }
    let affine = |c: DVec3, l: DMat3| -> DMat4 {
        let l = lin * l;
        let c = m.transform_point3(c);
        DMat4::from_cols(
            l.x_axis.extend(0.0),
            l.y_axis.extend(0.0),
            l.z_axis.extend(0.0),
            c.extend(1.0),
        )
    };
    Ok(match g {
        ShapeGeom::Mesh {
            positions,
            normals,
            triangles,
            uvs,
            attributes,
        } => {
            let normal_m = lin.inverse().transpose();
            let mut ps = Vec::with_capacity(positions.len());
            for (i, p) in positions.iter().enumerate() {
                let w = m.transform_point3(p.as_dvec3());
                check_world_point(w).map_err(|point| InstanceError::Vertex { vertex: i, point })?;
                ps.push(w.as_vec3());
            }
            for (f, t) in triangles.iter().enumerate() {
                let [a, b, c] = t.map(|i| ps[i as usize]);
                if !(b - a).cross(c - a).length_squared().is_finite() {
                    return Err(InstanceError::TriangleTooLarge { triangle: f });
                }
            }
            let mut tris = triangles.clone();
            if det < 0.0 {
                for t in tris.iter_mut() {
                    t.swap(1, 2);
                }
            }
            // Swapping vertices 1 and 2 changes which barycentric is which, not the
            // per-vertex data: uv and normals stay with their vertices.
            ShapeGeom::Mesh {
                positions: ps,
                normals: normals.as_ref().map(|ns| {
                    ns.iter()
                        .map(|n| (normal_m * n.as_dvec3()).normalize_or_zero().as_vec3())
                        .collect()
                }),
                triangles: tris,
                uvs: uvs.clone(),
                attributes: attributes.clone(),
            }
        }
        ShapeGeom::Sphere(s, to_local) => {
            let lens = [
                lin.x_axis.length(),
                lin.y_axis.length(),
                lin.z_axis.length(),
            ];
            if (lens[0] - lens[1]).abs() > 1e-6 * lens[0]
                || (lens[0] - lens[2]).abs() > 1e-6 * lens[0]
            {
                return Err(InstanceError::SphereScale);
            }
            let center = m.transform_point3(s.center.as_dvec3());
            check_world_point(center)?;
            let radius = s.radius as f64 * lens[0];
            if !(radius as f32 >= f32::MIN_POSITIVE
                && radius <= crate::scene::limits::MAX_COORDINATE)
            {
                return Err(InstanceError::SphereRadius { radius });
            }
            let new_local: Mat3 = (to_local.as_dmat3() * lin.inverse()).as_mat3();
            ShapeGeom::Sphere(
                SphereGeom {
                    center: center.as_vec3(),
                    radius: radius as f32,
                },
                new_local,
            )
        }
        ShapeGeom::Disk(d) => {
            let full = affine(d.c.as_dvec3(), d.m.as_dmat3());
            let g = DiskGeom::new(&full)?;
            let (lo, hi) = g.bounds();
            check_world_point(lo.as_dvec3())?;
            check_world_point(hi.as_dvec3())?;
            ShapeGeom::Disk(g)
        }
        ShapeGeom::Cylinder(c) => {
            let full = affine(c.c.as_dvec3(), c.m.as_dmat3());
            let g = CylinderGeom::new(&full)?;
            let (lo, hi) = g.bounds();
            check_world_point(lo.as_dvec3())?;
            check_world_point(hi.as_dvec3())?;
            ShapeGeom::Cylinder(g)
        }
        ShapeGeom::Curve(g) => {
            // Embree instances a curve with its radii in object space; tstat keeps
            // curves in world space only.
            return Err(InstanceError::Curve { kind: g.kind });
        }
        // The grid is shared; only its to_world changes (rotations are exact).
        ShapeGeom::Sdf(g) => {
            let g = g.transformed(m)?;
            let (lo, hi) = g.bounds();
            check_world_point(lo.as_dvec3())?;
            check_world_point(hi.as_dvec3())?;
            ShapeGeom::Sdf(Box::new(g))
        }
    })
}
