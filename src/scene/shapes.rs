//! Shape plugins: `rectangle`, `cube`, `sphere`, `ply`, `obj` (Mitsuba 3 semantics).
//!
//! | shape | parameters |
//! |-------|------------|
//! | rectangle | `to_world`; [-1, 1]^2 in the z = 0 plane, normal +z |
//! | cube | `to_world`; [-1, 1]^3, normals outward |
//! | sphere | `center` (point, 0), `radius` (float, 1), `to_world` (uniform scale only) |
//! | ply, obj | `filename` (relative to the scene file), `to_world`, `face_normals` (bool, false: smooth normals from the file, or angle-weighted ones computed as Mitsuba does) |
//!
//! Every shape takes `flip_normals` (bool, false), an optional nested `<bsdf>` or
//! `<ref>` (default: diffuse 0.5) and an optional nested `<emitter type="area">`.

use super::error::SceneError;
use super::mesh::{load_obj, load_ply, MeshData};
use super::props::Props;
use crate::geometry::shape::ShapeGeom;
use crate::geometry::sphere::SphereGeom;
use glam::{DMat4, DVec3, Vec3};

fn rectangle() -> MeshData {
    MeshData {
        positions: vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ],
        normals: None,
        triangles: vec![[0, 1, 2], [2, 3, 0]],
    }
}

fn cube() -> MeshData {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    // Each face: outward normal n and two in-plane axes with u x v = n.
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            let mut u = Vec3::ZERO;
            u[(axis + 1) % 3] = 1.0;
            let v = n.cross(u);
            let base = positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                positions.push(n + u * a + v * b);
            }
            triangles.push([base, base + 1, base + 2]);
            triangles.push([base + 2, base + 3, base]);
        }
    }
    MeshData {
        positions,
        normals: None,
        triangles,
    }
}

/// The largest world-space coordinate accepted. Geometry is single precision and its
/// arithmetic squares distances (edge cross products, sphere tests, 1/r^2 falloff), so
/// coordinates must stay far below sqrt(f32::MAX) ~ 1.8e19.
pub const MAX_COORDINATE: f64 = 1e15;

/// A world-space point must be finite in single precision and within [`MAX_COORDINATE`].
pub fn check_world_point(p: DVec3) -> Result<(), String> {
    if p.is_finite() && p.abs().max_element() <= MAX_COORDINATE {
        Ok(())
    } else {
        Err(format!(
            "world-space point {p} lies beyond +-{MAX_COORDINATE:e} (single-precision geometry would overflow)"
        ))
    }
}

/// Applies `to_world` to a mesh. For the built-in shapes (`keep_facing`), a mirroring
/// transform reverses the winding so the normal stays the transformed +z (as Mitsuba's
/// analytic shapes do); file meshes keep their winding.
fn transform_mesh(
    mut m: MeshData,
    to_world: &DMat4,
    keep_facing: bool,
) -> Result<ShapeGeom, String> {
    let normal_m = to_world.inverse().transpose();
    for (i, p) in m.positions.iter_mut().enumerate() {
        let w = to_world.transform_point3(p.as_dvec3());
        check_world_point(w).map_err(|e| format!("vertex {i}: {e}"))?;
        *p = w.as_vec3();
    }
    if let Some(ns) = m.normals.as_mut() {
        for n in ns.iter_mut() {
            *n = normal_m
                .transform_vector3(n.as_dvec3())
                .normalize_or_zero()
                .as_vec3();
        }
    }
    // The renderer takes |e1 x e2| in single precision (normals, areas): its square
    // must not overflow, which bounds the edges to about 4e9 units.
    for (f, t) in m.triangles.iter().enumerate() {
        let [a, b, c] = t.map(|i| m.positions[i as usize]);
        if !(b - a).cross(c - a).length_squared().is_finite() {
            return Err(format!(
                "triangle {f} is too large for single-precision arithmetic (edges of {:e} units; scale the scene down)",
                (b - a).length().max((c - a).length())
            ));
        }
    }
    if keep_facing && to_world.determinant() < 0.0 {
        for t in m.triangles.iter_mut() {
            t.swap(1, 2);
        }
    }
    Ok(ShapeGeom::Mesh {
        positions: m.positions,
        normals: m.normals,
        triangles: m.triangles,
    })
}

/// Smooth vertex normals for a file mesh without them, as Mitsuba computes them:
/// face normals weighted by the angle each face makes at the vertex.
pub fn vertex_normals(m: &MeshData) -> Vec<Vec3> {
    let mut acc = vec![glam::DVec3::ZERO; m.positions.len()];
    for t in &m.triangles {
        let p = t.map(|i| m.positions[i as usize].as_dvec3());
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let Some(n) = n.try_normalize() else { continue };
        for k in 0..3 {
            let e1 = p[(k + 1) % 3] - p[k];
            let e2 = p[(k + 2) % 3] - p[k];
            if let (Some(a), Some(b)) = (e1.try_normalize(), e2.try_normalize()) {
                acc[t[k] as usize] += n * a.dot(b).clamp(-1.0, 1.0).acos();
            }
        }
    }
    acc.into_iter()
        .map(|n| n.normalize_or_zero().as_vec3())
        .collect()
}

/// Builds the geometry of a `<shape>`; consumes its geometric parameters from `props`.
pub fn parse_geometry(kind: &str, props: &mut Props) -> Result<ShapeGeom, SceneError> {
    let to_world = props.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
    let at_transform = |props: &Props, e: String| props.err_at("to_world", e);
    match kind {
        "rectangle" => {
            transform_mesh(rectangle(), &to_world, true).map_err(|e| at_transform(props, e))
        }
        "cube" => transform_mesh(cube(), &to_world, true).map_err(|e| at_transform(props, e)),
        "sphere" => {
            let c = props.point("center")?.unwrap_or([0.0; 3]);
            let r = props.float_or("radius", 1.0)?;
            if r <= 0.0 {
                return Err(
                    props.err_at("radius", format!("sphere radius must be positive, got {r}"))
                );
            }
            let lens = [
                to_world.x_axis.truncate().length(),
                to_world.y_axis.truncate().length(),
                to_world.z_axis.truncate().length(),
            ];
            if (lens[0] - lens[1]).abs() > 1e-6 * lens[0]
                || (lens[0] - lens[2]).abs() > 1e-6 * lens[0]
            {
                return Err(props.err_at("to_world", "a sphere's to_world must scale uniformly"));
            }
            let center = to_world.transform_point3(DVec3::from(c));
            check_world_point(center)
                .map_err(|e| props.err_at("center", format!("center: {e}")))?;
            let radius = r * lens[0];
            if !(radius as f32 >= f32::MIN_POSITIVE && radius <= MAX_COORDINATE) {
                return Err(props.err_at(
                    "radius",
                    format!("the world-space radius {radius:e} is outside [{:e}, {MAX_COORDINATE:e}] (single-precision geometry)", f32::MIN_POSITIVE),
                ));
            }
            Ok(ShapeGeom::Sphere(SphereGeom {
                center: center.as_vec3(),
                radius: radius as f32,
            }))
        }
        "ply" | "obj" => {
            let name = props
                .string("filename")?
                .ok_or_else(|| props.err("missing parameter 'filename'"))?;
            if name.trim().is_empty() {
                return Err(props.err_at("filename", "the filename is empty"));
            }
            let path = props
                .ctx
                .file
                .parent()
                .unwrap_or(std::path::Path::new("."))
                .join(&name);
            props.ctx.read_mesh_file(&path);
            let loaded = if kind == "ply" {
                load_ply(&path)
            } else {
                load_obj(&path)
            };
            let mut mesh = loaded.map_err(|e| props.err_at("filename", e.to_string()))?;
            if props.boolean_or("face_normals", false)? {
                mesh.normals = None;
            } else if mesh.normals.is_none() {
                mesh.normals = Some(vertex_normals(&mesh));
            }
            if mesh.triangles.is_empty() {
                return Err(props.err_at("filename", format!("mesh '{name}' has no triangles")));
            }
            transform_mesh(mesh, &to_world, false)
                .map_err(|e| props.err_at("filename", format!("mesh '{name}': {e}")))
        }
        other => Err(props.err(format!(
            "unknown shape type '{other}' (supported: rectangle, cube, sphere, ply, obj)"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::shape::Shape;

    #[test]
    fn cube_faces_point_outward_and_cover_area_24() {
        let geom = transform_mesh(cube(), &DMat4::IDENTITY, true).unwrap();
        let shape = Shape {
            name: "c".into(),
            geom,
            flip_normals: false,
            bsdf: 0,
            emitter: None,
        };
        assert!((shape.area() - 24.0).abs() < 1e-5);
        for f in 0..12 {
            let t = shape.triangle(f);
            let centroid = t.point(1.0 / 3.0, 1.0 / 3.0);
            assert!(t.cross().dot(centroid) > 0.0, "face {f} points inward");
        }
    }

    #[test]
    fn vertex_normals_of_a_flat_fan_are_the_face_normal() {
        let m = MeshData {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            normals: None,
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        };
        for n in vertex_normals(&m) {
            assert!((n - Vec3::Z).length() < 1e-6);
        }
        // A vertex shared by two perpendicular faces gets the angle-weighted bisector.
        let m = MeshData {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            normals: None,
            triangles: vec![[0, 1, 2], [0, 3, 1]],
        };
        let n0 = vertex_normals(&m)[0];
        assert!(
            (n0 - Vec3::new(0.0, 1.0, 1.0).normalize()).length() < 1e-6,
            "{n0}"
        );
    }

    #[test]
    fn mirrored_rectangle_keeps_transformed_normal() {
        let m = DMat4::from_scale(DVec3::new(1.0, 1.0, -1.0));
        let geom = transform_mesh(rectangle(), &m, true).unwrap();
        let shape = Shape {
            name: "r".into(),
            geom,
            flip_normals: false,
            bsdf: 0,
            emitter: None,
        };
        let n = shape.surface(0, 0.2, 0.2, Vec3::ZERO).ng;
        assert!((n - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
    }
}
