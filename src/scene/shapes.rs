//! Shape plugins: `rectangle`, `cube`, `sphere`, `disk`, `cylinder`, `ply`, `obj`,
//! `serialized` (Mitsuba 3 semantics).
//!
//! | shape | parameters |
//! |-------|------------|
//! | rectangle | `to_world`; [-1, 1]^2 in the z = 0 plane, normal +z |
//! | cube | `to_world`; [-1, 1]^3, normals outward |
//! | sphere | `center` (point, 0), `radius` (float, 1), `to_world` (uniform scale only) |
//! | disk | `to_world` (any affine map); the unit disk in the z = 0 plane, normal +z (its normal transform); analytic ([`crate::geometry::disk`]) |
//! | cylinder | `p0` (point, 0), `p1` (point, (0, 0, 1)), `radius` (float, 1), `to_world` (its cross-section must stay a circle: no shear, equal x/y scale); open tube, normals outward; analytic ([`crate::geometry::cylinder`]) |
//! | ply, obj | `filename` (relative to the scene file), `to_world`, `face_normals` (bool, false: smooth normals from the file, or angle-weighted ones computed as Mitsuba does), `flip_tex_coords` (bool: v -> 1 - v of the file's texture coordinates; true for obj, false for ply, as Mitsuba) |
//! | linearcurve, bsplinecurve | `filename` (Mitsuba's curve file, [`super::curves`]), `to_world` (positions only: radii are not transformed); round linear or cubic B-spline tubes as Embree renders them for Mitsuba, back faces culled ([`crate::geometry::curve`]); no `flip_normals`, area emitters or media |
//! | serialized | as ply (no `flip_tex_coords`: uv as stored), plus `shape_index` (integer, 0: which mesh of the file); see [`super::serialized`] |
//! | sdfgrid | `filename` (a `.vol` grid), `normals` (`smooth` / `analytic`), `to_world`; no `flip_normals`, no emitter; see [`super::sdfgrid`] |
//!
//! Texture coordinates (`Shape::uv`) follow Mitsuba: rectangle (p + 1) / 2 in its local
//! square; cube [0, 1]^2 on every face, oriented as Mitsuba's cube; sphere
//! (phi / 2 pi, theta / pi) in object space; disk (r, phi / 2 pi); cylinder
//! (phi / 2 pi, z); meshes their per-vertex `u v` (`s t`,
//! `texture_u texture_v`) or `vt`, else the barycentrics.
//!
//! Every shape takes `flip_normals` (bool, false), an optional nested `<bsdf>` or
//! `<ref>` (default: diffuse 0.5) and an optional nested `<emitter type="area">`.

use super::curves::load_curves;
use super::error::SceneError;
use super::limits::{check_world_point, WorldPointError, MAX_COORDINATE};
use super::mesh::{load_obj, load_ply_with_attributes, vertex_normals, MeshData};
use super::props::Props;
use super::serialized::load_serialized;
use crate::geometry::curve::CurveKind;
use crate::geometry::cylinder::CylinderGeom;
use crate::geometry::disk::DiskGeom;
use crate::geometry::shape::ShapeGeom;
use crate::geometry::sphere::SphereGeom;
use glam::{DMat4, DVec3, Mat3, Vec2, Vec3};

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
        // Mitsuba's rectangle (`src/shapes/rectangle.cpp`): uv = (p + 1) / 2 in the
        // local [-1, 1]^2, so uv (0, 0) at local (-1, -1) and (1, 1) at (1, 1).
        uvs: Some(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ]),
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
    let uvs = positions
        .chunks_exact(4)
        .flat_map(|face| {
            let n = (face[1] - face[0]).cross(face[2] - face[0]).normalize();
            face.iter()
                .map(move |&p| mitsuba_cube_uv(n, p))
                .collect::<Vec<_>>()
        })
        .collect();
    MeshData {
        positions,
        normals: None,
        triangles,
        uvs: Some(uvs),
    }
}

/// The uv Mitsuba's cube (`src/shapes/cube.cpp`) gives corner `p` of its face with
/// outward normal `n`: its faces, in its order, by normal; each face's four vertices
/// as corner indices (bit k of a corner is the sign of axis k); and the uv of the
/// k-th vertex of every face.
fn mitsuba_cube_uv(n: Vec3, p: Vec3) -> Vec2 {
    const NORMALS: [[f32; 3]; 6] = [
        [0.0, -1.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [-1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],
    ];
    const CORNERS: [[u32; 4]; 6] = [
        [1, 5, 4, 0],
        [3, 2, 6, 7],
        [1, 3, 7, 5],
        [5, 7, 6, 4],
        [4, 6, 2, 0],
        [3, 1, 0, 2],
    ];
    const UV: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    let corner = |c: u32| {
        Vec3::new(
            if c & 1 != 0 { 1.0 } else { -1.0 },
            if c & 2 != 0 { 1.0 } else { -1.0 },
            if c & 4 != 0 { 1.0 } else { -1.0 },
        )
    };
    let s = NORMALS
        .iter()
        .position(|m| Vec3::from_array(*m) == n)
        .expect("cube faces are axis-aligned");
    let k = CORNERS[s]
        .iter()
        .position(|&c| corner(c) == p)
        .expect("cube vertices are corners");
    Vec2::from_array(UV[k])
}

/// An analytic shape's box must lie within [`MAX_COORDINATE`].
fn check_bounds((lo, hi): (Vec3, Vec3)) -> Result<(), WorldPointError> {
    check_world_point(lo.as_dvec3())?;
    check_world_point(hi.as_dvec3())
}

/// Why a mesh cannot be placed in the world.
#[derive(Debug, thiserror::Error)]
enum TransformMeshError {
    /// A transformed vertex is outside the single-precision world.
    #[error("vertex {0}: {1}")]
    Vertex(usize, WorldPointError),
    /// A triangle whose |e1 x e2| overflows single precision.
    #[error("triangle {triangle} is too large for single-precision arithmetic (edges of {edge:e} units; scale the scene down)")]
    TooLarge { triangle: usize, edge: f32 },
}

/// Applies `to_world` to a mesh. For the built-in shapes (`keep_facing`), a mirroring
/// transform reverses the winding so the normal stays the transformed +z (as Mitsuba's
/// analytic shapes do); file meshes keep their winding.
fn transform_mesh(
    mut m: MeshData,
    to_world: &DMat4,
    keep_facing: bool,
) -> Result<ShapeGeom, TransformMeshError> {
    let normal_m = to_world.inverse().transpose();
    for (i, p) in m.positions.iter_mut().enumerate() {
        let w = to_world.transform_point3(p.as_dvec3());
        check_world_point(w).map_err(|e| TransformMeshError::Vertex(i, e))?;
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
            return Err(TransformMeshError::TooLarge {
                triangle: f,
                edge: (b - a).length().max((c - a).length()),
            });
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
        uvs: m.uvs,
        attributes: None,
    })
}

/// Builds the geometry of a `<shape>`; consumes its geometric parameters from `props`.
pub fn parse_geometry(kind: &str, props: &mut Props) -> Result<ShapeGeom, SceneError> {
    let to_world = props.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
    let read = super::table::reader(SHAPES, kind).ok_or_else(|| {
        props.err(format!(
            "unknown shape type '{kind}' (supported: {})",
            super::table::names(SHAPES)
                .into_iter()
                .chain(GROUPING)
                .collect::<Vec<_>>()
                .join(", ")
        ))
    })?;
    read(kind, props, &to_world)
}

/// The shape plugins that group other shapes, read by the scene's walk
/// (`xml.rs`, `GROUPING`).
pub(super) const GROUPING: [&str; 2] = ["shapegroup", "instance"];

/// The shape plugins that have geometry and their readers (the plugin table's `shape`
/// family with [`GROUPING`], [`super::plugins`]), in the order errors
/// list them.
pub(super) const SHAPES: &[(&str, ReadShape)] = &[
    ("rectangle", read_rectangle),
    ("cube", read_cube),
    ("sphere", read_sphere),
    ("disk", read_disk),
    ("cylinder", read_cylinder),
    ("linearcurve", read_curve),
    ("bsplinecurve", read_curve),
    ("ply", read_mesh_file),
    ("obj", read_mesh_file),
    ("serialized", read_mesh_file),
    ("sdfgrid", read_sdfgrid),
];

/// Reads one shape's geometry from `props` under `to_world`; `kind` is its type.
pub(super) type ReadShape =
    fn(&str, &mut Props<'_, '_, '_>, &DMat4) -> Result<ShapeGeom, SceneError>;

/// `<shape type="rectangle">`.
fn read_rectangle(
    _kind: &str,
    props: &mut Props,
    to_world: &DMat4,
) -> Result<ShapeGeom, SceneError> {
    transform_mesh(rectangle(), to_world, true).map_err(|e| props.err_at("to_world", e.to_string()))
}

/// `<shape type="cube">`.
fn read_cube(_kind: &str, props: &mut Props, to_world: &DMat4) -> Result<ShapeGeom, SceneError> {
    transform_mesh(cube(), to_world, true).map_err(|e| props.err_at("to_world", e.to_string()))
}

/// `<shape type="sphere">`.
fn read_sphere(_kind: &str, props: &mut Props, to_world: &DMat4) -> Result<ShapeGeom, SceneError> {
    let c = props.point("center")?.unwrap_or([0.0; 3]);
    let r = props.float_or("radius", 1.0)?;
    if r <= 0.0 {
        return Err(props.err_at("radius", format!("sphere radius must be positive, got {r}")));
    }
    let lens = [
        to_world.x_axis.truncate().length(),
        to_world.y_axis.truncate().length(),
        to_world.z_axis.truncate().length(),
    ];
    if (lens[0] - lens[1]).abs() > 1e-6 * lens[0] || (lens[0] - lens[2]).abs() > 1e-6 * lens[0] {
        return Err(props.err_at("to_world", "a sphere's to_world must scale uniformly"));
    }
    let center = to_world.transform_point3(DVec3::from(c));
    check_world_point(center).map_err(|e| props.err_at("center", format!("center: {e}")))?;
    let radius = r * lens[0];
    if !(radius as f32 >= f32::MIN_POSITIVE && radius <= MAX_COORDINATE) {
        return Err(props.err_at(
            "radius",
            format!("the world-space radius {radius:e} is outside [{:e}, {MAX_COORDINATE:e}] (single-precision geometry)", f32::MIN_POSITIVE),
        ));
    }
    // World to the unit sphere's object space (uv only): the linear part of
    // the inverse of to_world * translate(center) * scale(radius).
    let to_local = (to_world * DMat4::from_scale(DVec3::splat(r))).inverse();
    let to_local = Mat3::from_mat4(to_local.as_mat4());
    Ok(ShapeGeom::Sphere(
        SphereGeom {
            center: center.as_vec3(),
            radius: radius as f32,
        },
        to_local,
    ))
}

/// `<shape type="disk">`.
fn read_disk(_kind: &str, props: &mut Props, to_world: &DMat4) -> Result<ShapeGeom, SceneError> {
    let g = DiskGeom::new(to_world).map_err(|e| props.err_at("to_world", e.to_string()))?;
    check_bounds(g.bounds()).map_err(|e| props.err_at("to_world", e.to_string()))?;
    Ok(ShapeGeom::Disk(g))
}

/// `<shape type="cylinder">`.
fn read_cylinder(
    _kind: &str,
    props: &mut Props,
    to_world: &DMat4,
) -> Result<ShapeGeom, SceneError> {
    let p0 = DVec3::from(props.point("p0")?.unwrap_or([0.0; 3]));
    let p1 = DVec3::from(props.point("p1")?.unwrap_or([0.0, 0.0, 1.0]));
    let r = props.float_or("radius", 1.0)?;
    if !(r > 0.0 && r.is_finite()) {
        return Err(props.err_at(
            "radius",
            format!("cylinder radius must be positive, got {r}"),
        ));
    }
    let length = (p1 - p0).length();
    if !(length > 0.0 && length.is_finite()) {
        return Err(props.err_at(
            "p1",
            format!(
                "the cylinder's p0 {p0} and p1 {p1} must differ (its axis has length {length})"
            ),
        ));
    }
    let m = CylinderGeom::object_to_world(to_world, p0, p1, r);
    let g = CylinderGeom::new(&m).map_err(|e| props.err_at("to_world", e.to_string()))?;
    check_bounds(g.bounds()).map_err(|e| props.err_at("to_world", e.to_string()))?;
    Ok(ShapeGeom::Cylinder(g))
}

/// `<shape type="linearcurve|bsplinecurve">`.
fn read_curve(kind: &str, props: &mut Props, to_world: &DMat4) -> Result<ShapeGeom, SceneError> {
    let kind = if kind == "linearcurve" {
        CurveKind::Linear
    } else {
        CurveKind::BSpline
    };
    let name = props
        .string("filename")?
        .ok_or_else(|| props.err("missing parameter 'filename'"))?;
    if name.trim().is_empty() {
        return Err(props.err_at("filename", "the filename is empty"));
    }
    let path = props.ctx.resolve(&name);
    props.ctx.read_mesh_file(&path);
    let g = load_curves(&path, kind, to_world)
        .map_err(|e| props.err_at("filename", format!("{} file '{name}': {e}", kind.name())))?;
    Ok(ShapeGeom::Curve(g))
}

/// `<shape type="sdfgrid">`.
fn read_sdfgrid(_kind: &str, props: &mut Props, to_world: &DMat4) -> Result<ShapeGeom, SceneError> {
    super::sdfgrid::parse_sdfgrid(props, to_world)
}

/// `<shape type="ply|obj|serialized">`.
fn read_mesh_file(
    kind: &str,
    props: &mut Props,
    to_world: &DMat4,
) -> Result<ShapeGeom, SceneError> {
    let name = props
        .string("filename")?
        .ok_or_else(|| props.err("missing parameter 'filename'"))?;
    if name.trim().is_empty() {
        return Err(props.err_at("filename", "the filename is empty"));
    }
    let path = props.ctx.resolve(&name);
    props.ctx.read_mesh_file(&path);
    // A version 5 serialized mesh may ask for face normals itself.
    let mut stored_face_normals = false;
    // Mesh attributes (PLY files only, as Mitsuba's loaders).
    let mut attributes = None;
    let mut mesh = if kind == "serialized" {
        let index = props.integer("shape_index")?.unwrap_or(0);
        let index = u64::try_from(index).map_err(|_| {
            props.err_at(
                "shape_index",
                format!("shape_index must be non-negative, got {index}"),
            )
        })?;
        let loaded = load_serialized(&path, index)
            .map_err(|e| props.err_at("filename", format!("{e} (shape_index {index})")))?;
        stored_face_normals = loaded.face_normals;
        loaded.mesh
    } else {
        let loaded = if kind == "ply" {
            load_ply_with_attributes(&path).map(|(m, a)| {
                attributes = a;
                m
            })
        } else {
            load_obj(&path)
        };
        let mut mesh = loaded.map_err(|e| props.err_at("filename", e.to_string()))?;
        // Mitsuba flips v of OBJ texture coordinates by default, not of PLY ones;
        // serialized meshes keep theirs as stored (no such parameter).
        if props.boolean_or("flip_tex_coords", kind == "obj")? {
            for uv in mesh.uvs.iter_mut().flatten() {
                uv.y = 1.0 - uv.y;
            }
        }
        mesh
    };
    if props.boolean_or("face_normals", stored_face_normals)? {
        mesh.normals = None;
    } else if mesh.normals.is_none() {
        mesh.normals = Some(vertex_normals(&mesh));
    }
    if mesh.triangles.is_empty() {
        return Err(props.err_at("filename", format!("mesh '{name}' has no triangles")));
    }
    let mut geom = transform_mesh(mesh, to_world, false)
        .map_err(|e| props.err_at("filename", format!("mesh '{name}': {e}")))?;
    if let ShapeGeom::Mesh { attributes: a, .. } = &mut geom {
        *a = attributes.map(std::sync::Arc::new);
    }
    Ok(geom)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::shape::Shape;
    use glam::DVec2;

    #[test]
    fn cube_faces_point_outward_and_cover_area_24() {
        let geom = transform_mesh(cube(), &DMat4::IDENTITY, true).unwrap();
        let shape = Shape {
            name: "c".into(),
            geom,
            flip_normals: false,
            bsdf: 0,
            emitter: None,
            interior: None,
            exterior: None,
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
            uvs: None,
        };
        for n in vertex_normals(&m) {
            assert!((n - Vec3::Z).length() < 1e-6);
        }
        // A vertex shared by two perpendicular faces gets the angle-weighted bisector.
        let m = MeshData {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            normals: None,
            triangles: vec![[0, 1, 2], [0, 3, 1]],
            uvs: None,
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
            interior: None,
            exterior: None,
        };
        let n = shape.surface(0, 0.2, 0.2, Vec3::ZERO).ng;
        assert!((n - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
    }

    fn shape(geom: ShapeGeom) -> Shape {
        Shape {
            name: "s".into(),
            geom,
            flip_normals: false,
            bsdf: 0,
            emitter: None,
            interior: None,
            exterior: None,
        }
    }

    /// The uv at world point `p` of a mesh shape, found through its barycentrics.
    fn mesh_uv_at(s: &Shape, p: Vec3) -> Option<Vec2> {
        let ShapeGeom::Mesh { triangles, .. } = &s.geom else {
            unreachable!()
        };
        (0..triangles.len() as u32).find_map(|f| {
            let t = s.triangle(f);
            // Solve p = v0 + b1 e1 + b2 e2 by least squares on the triangle's plane.
            let (d, e1, e2) = (p - t.v0, t.e1, t.e2);
            let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
            let (r1, r2) = (d.dot(e1), d.dot(e2));
            let det = a * c - b * b;
            let b1 = (c * r1 - b * r2) / det;
            let b2 = (a * r2 - b * r1) / det;
            let inside = b1 >= -1e-5 && b2 >= -1e-5 && b1 + b2 <= 1.0 + 1e-5;
            (inside && (t.point(b1, b2) - p).length() < 1e-4).then(|| s.uv(f, b1, b2, p))
        })
    }

    #[test]
    fn rectangle_uv_at_its_corners_after_to_world() {
        let m = DMat4::from_translation(DVec3::new(3.0, 0.0, 1.0))
            * DMat4::from_rotation_x(0.7)
            * DMat4::from_scale(DVec3::new(2.0, 0.5, 1.0));
        let s = shape(transform_mesh(rectangle(), &m, true).unwrap());
        for (local, want) in [
            ((-1.0, -1.0), (0.0, 0.0)),
            ((1.0, -1.0), (1.0, 0.0)),
            ((1.0, 1.0), (1.0, 1.0)),
            ((-1.0, 1.0), (0.0, 1.0)),
            ((0.0, 0.5), (0.5, 0.75)),
        ] {
            let p = m
                .transform_point3(DVec3::new(local.0, local.1, 0.0))
                .as_vec3();
            let uv = mesh_uv_at(&s, p).unwrap();
            assert!(
                (uv - Vec2::new(want.0, want.1)).length() < 1e-5,
                "{local:?}: {uv}"
            );
        }
        // A mirroring to_world swaps the winding but not the uv of a point.
        let mirror = DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0));
        let s = shape(transform_mesh(rectangle(), &mirror, true).unwrap());
        let uv = mesh_uv_at(&s, Vec3::new(-0.5, 0.0, 0.0)).unwrap();
        assert!((uv - Vec2::new(0.75, 0.5)).length() < 1e-5, "{uv}");
    }

    #[test]
    fn cube_uv_follows_mitsubas_faces() {
        let s = shape(transform_mesh(cube(), &DMat4::IDENTITY, true).unwrap());
        // Mitsuba's cube.cpp: on +z, corner 4 (-1,-1,+1) has uv (0, 0), corner 5
        // (+1,-1,+1) (0, 1), corner 6 (-1,+1,+1) (1, 0); on -y, corner 1 (+1,-1,-1)
        // has (0, 1) and corner 4 (1, 0).
        // A point of the face just inside the corner (the face's centre is n).
        let near = |p: Vec3, n: Vec3| p + (n - p) * 1e-3;
        let at = |p: [f32; 3], n: Vec3| mesh_uv_at(&s, near(Vec3::from_array(p), n)).unwrap();
        let close = |a: Vec2, b: [f32; 2]| (a - Vec2::from_array(b)).length() < 1e-2;
        assert!(close(at([-1.0, -1.0, 1.0], Vec3::Z), [0.0, 0.0]));
        assert!(close(at([1.0, -1.0, 1.0], Vec3::Z), [0.0, 1.0]));
        assert!(close(at([-1.0, 1.0, 1.0], Vec3::Z), [1.0, 0.0]));
        assert!(close(at([1.0, -1.0, -1.0], Vec3::NEG_Y), [0.0, 1.0]));
        assert!(close(at([-1.0, -1.0, 1.0], Vec3::NEG_Y), [1.0, 0.0]));
        // Every face covers the unit square once: its 4 vertices hold its 4 corners.
        let ShapeGeom::Mesh { uvs: Some(uvs), .. } = &s.geom else {
            unreachable!()
        };
        for face in uvs.chunks_exact(4) {
            let mut f: Vec<[u32; 2]> = face.iter().map(|u| [u.x as u32, u.y as u32]).collect();
            f.sort();
            assert_eq!(f, vec![[0, 0], [0, 1], [1, 0], [1, 1]]);
        }
    }

    #[test]
    fn sphere_uv_at_poles_and_equator_in_object_space() {
        use crate::scene::ctx::Ctx;
        let xml = r#"<shape type="sphere"><point name="center" x="1" y="2" z="3"/><float name="radius" value="2"/>
            <transform name="to_world"><rotate x="1" angle="90"/><scale value="0.5"/></transform></shape>"#;
        let defaults = std::collections::HashMap::new();
        let ctx = Ctx::new(std::path::Path::new("s.xml"), xml, &defaults);
        let doc = roxmltree::Document::parse(xml).unwrap();
        let mut props = Props::parse(&ctx, doc.root_element()).unwrap();
        let s = shape(parse_geometry("sphere", &mut props).unwrap());
        let ShapeGeom::Sphere(g, _) = &s.geom else {
            unreachable!()
        };
        // to_world = R_x(90) S(0.5): the centre (1, 2, 3) lands at (0.5, -1.5, 1), the
        // radius is 1, and object +z points along world -y, object +y along world +z.
        assert!((g.center - Vec3::new(0.5, -1.5, 1.0)).length() < 1e-5);
        assert!((g.radius - 1.0).abs() < 1e-6);
        let uv = |d: Vec3| s.uv(0, 0.0, 0.0, g.center + d);
        let close = |a: Vec2, b: [f32; 2]| (a - Vec2::from_array(b)).length() < 1e-5;
        assert!(uv(Vec3::NEG_Y).y.abs() < 1e-5, "north pole v = 0");
        assert!((uv(Vec3::Y).y - 1.0).abs() < 1e-5, "south pole v = 1");
        // Equator: object +x (world +x) is phi = 0, object +y (world +z) phi = pi / 2,
        // object -x phi = pi, object -y (world -z) phi = 3 pi / 2.
        assert!(close(uv(Vec3::X), [0.0, 0.5]), "{}", uv(Vec3::X));
        assert!(close(uv(Vec3::Z), [0.25, 0.5]), "{}", uv(Vec3::Z));
        assert!(close(uv(Vec3::NEG_X), [0.5, 0.5]), "{}", uv(Vec3::NEG_X));
        assert!(close(uv(Vec3::NEG_Z), [0.75, 0.5]), "{}", uv(Vec3::NEG_Z));
    }

    /// dp/du from finite differences: `at(a, b)` is the (point, uv) at two surface
    /// coordinates around (0, 0); the chain rule through their 2 x 2 Jacobians.
    fn fd_dpdu(at: impl Fn(f64, f64) -> (DVec3, DVec2)) -> DVec3 {
        fd_dpduv(at).0
    }

    /// dp/du and dp/dv from finite differences (see [`fd_dpdu`]).
    fn fd_dpduv(at: impl Fn(f64, f64) -> (DVec3, DVec2)) -> (DVec3, DVec3) {
        let h = 1e-4;
        let (pa1, ua1) = at(h, 0.0);
        let (pa0, ua0) = at(-h, 0.0);
        let (pb1, ub1) = at(0.0, h);
        let (pb0, ub0) = at(0.0, -h);
        let (dp_da, dp_db) = ((pa1 - pa0) / (2.0 * h), (pb1 - pb0) / (2.0 * h));
        let (duv_da, duv_db) = ((ua1 - ua0) / (2.0 * h), (ub1 - ub0) / (2.0 * h));
        // (a, b) -> uv is [duv_da duv_db]; its inverse's first column is d(a, b)/du.
        let det = duv_da.x * duv_db.y - duv_db.x * duv_da.y;
        (
            dp_da * (duv_db.y / det) - dp_db * (duv_da.y / det),
            dp_db * (duv_da.x / det) - dp_da * (duv_db.x / det),
        )
    }

    /// Shape::dpdu of every triangle against finite differences of the triangle's
    /// position and Shape::uv (in f64 from the shape's own f32 data).
    fn check_mesh_dpdu(s: &Shape) {
        let ShapeGeom::Mesh { triangles, .. } = &s.geom else {
            unreachable!()
        };
        for f in 0..triangles.len() as u32 {
            let t = s.triangle(f);
            let (b1, b2) = (0.3f64, 0.25f64);
            let fd = fd_dpdu(|a, b| {
                let (x, y) = (b1 + a, b2 + b);
                let p = t.v0.as_dvec3() + t.e1.as_dvec3() * x + t.e2.as_dvec3() * y;
                (p, s.uv(f, x as f32, y as f32, Vec3::ZERO).as_dvec2())
            });
            let got = s.dpdu(f, b1 as f32, b2 as f32, Vec3::ZERO).as_dvec3();
            assert!(
                (got - fd).length() < 2e-3 * fd.length(),
                "face {f}: dpdu {got} vs finite differences {fd}"
            );
            let fdv = fd_dpduv(|a, b| {
                let (x, y) = (b1 + a, b2 + b);
                let p = t.v0.as_dvec3() + t.e1.as_dvec3() * x + t.e2.as_dvec3() * y;
                (p, s.uv(f, x as f32, y as f32, Vec3::ZERO).as_dvec2())
            })
            .1;
            let got = s.dpdv(f, 0.0, Vec3::ZERO).as_dvec3();
            assert!(
                (got - fdv).length() < 2e-3 * fdv.length(),
                "face {f}: dpdv {got} vs finite differences {fdv}"
            );
        }
    }

    #[test]
    fn dpdu_is_the_derivative_of_position_along_u() {
        use crate::scene::ctx::Ctx;
        // Rectangle and cube under a rotation, a non-uniform scale and a mirror.
        let m = DMat4::from_translation(DVec3::new(3.0, 0.0, 1.0))
            * DMat4::from_rotation_x(0.7)
            * DMat4::from_rotation_y(-0.3)
            * DMat4::from_scale(DVec3::new(2.0, 0.5, 1.5));
        let mirror = DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0));
        for to_world in [DMat4::IDENTITY, m, m * mirror] {
            let r = shape(transform_mesh(rectangle(), &to_world, true).unwrap());
            check_mesh_dpdu(&r);
            // Mitsuba's rectangle: dp/du = to_world (2, 0, 0) on both triangles.
            let want = to_world.transform_vector3(DVec3::new(2.0, 0.0, 0.0));
            for f in 0..2 {
                let got = r.dpdu(f, 0.2, 0.2, Vec3::ZERO).as_dvec3();
                assert!(
                    (got - want).length() < 1e-5 * want.length(),
                    "{got} vs {want}"
                );
            }
            check_mesh_dpdu(&shape(transform_mesh(cube(), &to_world, true).unwrap()));
        }
        // Mitsuba's cube on +z: u runs from corner 4 (-1,-1,1) to corner 6 (-1,1,1).
        let c = shape(transform_mesh(cube(), &DMat4::IDENTITY, true).unwrap());
        let ShapeGeom::Mesh {
            triangles,
            positions,
            ..
        } = &c.geom
        else {
            unreachable!()
        };
        let top = (0..triangles.len())
            .find(|&f| triangles[f].iter().all(|&i| positions[i as usize].z == 1.0))
            .unwrap() as u32;
        assert!((c.dpdu(top, 0.2, 0.2, Vec3::ZERO) - Vec3::new(0.0, 2.0, 0.0)).length() < 1e-6);

        // File meshes: with uv (PLY as stored), without (the barycentrics: p1 - p0),
        // and with degenerate uv (the first axis of the face normal's frame).
        let dir = tempfile::tempdir().unwrap();
        let ply = |uvs: [[f32; 2]; 3]| {
            format!(
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                 property float s\nproperty float t\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
                 0 0 0 {} {}\n1 0.2 0 {} {}\n0.1 1 0.3 {} {}\n3 0 1 2\n",
                uvs[0][0], uvs[0][1], uvs[1][0], uvs[1][1], uvs[2][0], uvs[2][1]
            )
        };
        std::fs::write(
            dir.path().join("t.ply"),
            ply([[0.1, 0.2], [0.9, 0.3], [0.2, 0.8]]),
        )
        .unwrap();
        std::fs::write(
            dir.path().join("d.ply"),
            ply([[0.5, 0.5], [0.5, 0.5], [0.5, 0.5]]),
        )
        .unwrap();
        std::fs::write(
            dir.path().join("n.obj"),
            "v 0 0 0\nv 1 0.2 0\nv 0.1 1 0.3\nf 1 2 3\n",
        )
        .unwrap();
        let file = dir.path().join("scene.xml");
        let load = |kind: &str, name: &str| {
            let xml = format!(
                r#"<shape type="{kind}"><string name="filename" value="{name}"/><transform name="to_world"><rotate z="1" angle="30"/></transform></shape>"#
            );
            let defaults = std::collections::HashMap::new();
            let ctx = Ctx::new(&file, &xml, &defaults);
            let doc = roxmltree::Document::parse(&xml).unwrap();
            let mut props = Props::parse(&ctx, doc.root_element()).unwrap();
            shape(parse_geometry(kind, &mut props).unwrap())
        };
        check_mesh_dpdu(&load("ply", "t.ply"));
        let none = load("obj", "n.obj");
        check_mesh_dpdu(&none);
        assert_eq!(none.dpdu(0, 0.2, 0.2, Vec3::ZERO), none.triangle(0).e1);
        assert_eq!(none.dpdv(0, 0.0, Vec3::ZERO), none.triangle(0).e2);
        let degenerate = load("ply", "d.ply");
        let n = degenerate.triangle(0).cross().normalize();
        assert_eq!(
            degenerate.dpdu(0, 0.2, 0.2, Vec3::ZERO),
            crate::math::frame::Frame::from_normal(n).s
        );
        assert_eq!(
            degenerate.dpdv(0, 0.0, Vec3::ZERO),
            crate::math::frame::Frame::from_normal(n).t
        );

        // The sphere under a rotation and a scale, at points away from the poles and
        // the seam phi = 0; zero at the poles (the shading frame then falls back).
        let xml = r#"<shape type="sphere"><point name="center" x="1" y="2" z="3"/><float name="radius" value="2"/>
            <transform name="to_world"><rotate x="1" angle="-60"/><rotate z="1" angle="20"/><scale value="0.5"/></transform></shape>"#;
        let defaults = std::collections::HashMap::new();
        let ctx = Ctx::new(std::path::Path::new("s.xml"), xml, &defaults);
        let doc = roxmltree::Document::parse(xml).unwrap();
        let mut props = Props::parse(&ctx, doc.root_element()).unwrap();
        let s = shape(parse_geometry("sphere", &mut props).unwrap());
        let ShapeGeom::Sphere(g, to_local) = &s.geom else {
            unreachable!()
        };
        let (c, r) = (g.center.as_dvec3(), g.radius as f64);
        let mut checked = 0;
        for i in 0..40 {
            let d = DVec3::new(
                (i as f64 * 1.3).sin(),
                (i as f64 * 0.7).cos(),
                (i as f64 * 2.1).sin() - 0.2,
            )
            .normalize();
            let local = (*to_local * d.as_vec3()).normalize();
            // Away from the poles and from the seam, where u jumps from 1 to 0.
            if local.z.abs() > 0.95 || (local.y.abs() < 0.05 && local.x > 0.0) {
                continue;
            }
            let frame = crate::math::frame::Frame::from_normal(d.as_vec3());
            let (t1, t2) = (frame.s.as_dvec3(), frame.t.as_dvec3());
            let fd = fd_dpdu(|a, b| {
                let p = c + (d + t1 * a + t2 * b).normalize() * r;
                (p, s.uv(0, 0.0, 0.0, p.as_vec3()).as_dvec2())
            });
            let got = s.dpdu(0, 0.0, 0.0, (c + d * r).as_vec3()).as_dvec3();
            assert!(
                (got - fd).length() < 5e-3 * fd.length(),
                "sphere at {d}: dpdu {got} vs finite differences {fd}"
            );
            let fdv = fd_dpduv(|a, b| {
                let p = c + (d + t1 * a + t2 * b).normalize() * r;
                (p, s.uv(0, 0.0, 0.0, p.as_vec3()).as_dvec2())
            })
            .1;
            let got = s.dpdv(0, 0.0, (c + d * r).as_vec3()).as_dvec3();
            assert!(
                (got - fdv).length() < 5e-3 * fdv.length(),
                "sphere at {d}: dpdv {got} vs finite differences {fdv}"
            );
            checked += 1;
        }
        assert!(checked > 20);
        let pole = to_local.inverse() * Vec3::Z;
        let at_pole = s.dpdu(0, 0.0, 0.0, g.center + pole.normalize() * g.radius);
        assert!(at_pole.length() < 1e-5 * g.radius, "{at_pole}");
        // dp/dv stays finite and non-zero there (Mitsuba's pi (1, 0, 0) in object
        // space exactly on the axis; a rounded pole has some azimuth).
        let got = s.dpdv(0, 0.0, g.center + pole.normalize() * g.radius);
        assert!(got.is_finite() && got.length() > 0.1 * g.radius, "{got}");
    }

    /// A shape parsed from its XML element.
    fn parse_shape(kind: &str, inner: &str) -> Result<Shape, SceneError> {
        use crate::scene::ctx::Ctx;
        let xml = format!(r#"<shape type="{kind}">{inner}</shape>"#);
        let defaults = std::collections::HashMap::new();
        let ctx = Ctx::new(std::path::Path::new("s.xml"), &xml, &defaults);
        let doc = roxmltree::Document::parse(&xml).unwrap();
        let mut props = Props::parse(&ctx, doc.root_element())?;
        let s = shape(parse_geometry(kind, &mut props)?);
        props.finish()?;
        Ok(s)
    }

    #[test]
    fn disk_area_uv_and_dpdu_are_mitsubas() {
        // An ellipse: scale (2, 0.5), rotated and moved; area pi * 2 * 0.5.
        let s = parse_shape(
            "disk",
            r#"<transform name="to_world"><scale x="2" y="0.5"/><rotate x="1" angle="30"/><rotate z="1" angle="-50"/><translate x="1" y="2" z="-3"/></transform>"#,
        )
        .unwrap();
        let ShapeGeom::Disk(g) = s.geom else {
            unreachable!()
        };
        assert!((s.area() - std::f64::consts::PI).abs() < 1e-5);
        let m = DMat4::from_translation(DVec3::new(1.0, 2.0, -3.0))
            * DMat4::from_rotation_z((-50.0f64).to_radians())
            * DMat4::from_rotation_x(30.0f64.to_radians())
            * DMat4::from_scale(DVec3::new(2.0, 0.5, 1.0));
        // The object-space point at polar (r, phi) and its uv (r, phi / 2 pi).
        let at = |r: f64, phi: f64| {
            let p = m.transform_point3(DVec3::new(r * phi.cos(), r * phi.sin(), 0.0));
            (p, s.uv(0, 0.0, 0.0, p.as_vec3()).as_dvec2())
        };
        for (r, phi) in [(0.5, 0.3), (0.9, 2.0), (0.2, 4.0), (0.7, 6.0)] {
            let (p, uv) = at(r, phi);
            assert!(
                (uv - DVec2::new(r, phi / std::f64::consts::TAU)).length() < 1e-5,
                "{uv}"
            );
            let fd = fd_dpdu(|a, b| at(r + a, phi + b));
            let got = s.dpdu(0, 0.0, 0.0, p.as_vec3()).as_dvec3();
            assert!(
                (got - fd).length() < 1e-3 * fd.length(),
                "dpdu {got} vs {fd}"
            );
            // The surface point projects onto the plane; the normal is the transformed +z.
            let sp = s.surface(0, 0.0, 0.0, (p + DVec3::new(1e-4, 0.0, 0.0)).as_vec3());
            assert!((g.to_local(sp.p).z).abs() < 1e-5);
        }
        let n = m
            .inverse()
            .transpose()
            .transform_vector3(DVec3::Z)
            .normalize();
        let sp = s.surface(0, 0.0, 0.0, g.c);
        assert!((sp.ng.as_dvec3() - n).length() < 1e-6);
        // flip_normals turns the normal only (parse_shape reads it: here by hand).
        let mut flipped = s.clone();
        flipped.flip_normals = true;
        let fp = flipped.surface(0, 0.0, 0.0, g.c);
        assert!((fp.ng + sp.ng).length() < 1e-6);
        assert_eq!(
            flipped.uv(0, 0.0, 0.0, g.c + g.m.x_axis * 0.5),
            s.uv(0, 0.0, 0.0, g.c + g.m.x_axis * 0.5)
        );
        // The default: the unit disk at the origin facing +z.
        let d = parse_shape("disk", "").unwrap();
        assert!((d.area() - std::f64::consts::PI).abs() < 1e-6);
        assert!(
            (d.uv(0, 0.0, 0.0, Vec3::new(0.0, 0.5, 0.0)) - Vec2::new(0.5, 0.25)).length() < 1e-6
        );
        assert!((d.dpdu(0, 0.0, 0.0, Vec3::new(0.0, 0.5, 0.0)) - Vec3::Y).length() < 1e-6);
        // Mitsuba's disk has no radius: scale it instead.
        let e = parse_shape("disk", r#"<float name="radius" value="2"/>"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown parameter 'radius'"), "{e}");
    }

    #[test]
    fn cylinder_area_uv_and_dpdu_are_mitsubas() {
        let s = parse_shape(
            "cylinder",
            r#"<point name="p0" x="0.5" y="-1" z="0.2"/><point name="p1" x="1.5" y="1" z="-0.4"/>
            <float name="radius" value="0.3"/>
            <transform name="to_world"><rotate y="1" angle="40"/><scale value="1.5"/><translate x="2"/></transform>"#,
        )
        .unwrap();
        let ShapeGeom::Cylinder(g) = s.geom else {
            unreachable!()
        };
        let len = (DVec3::new(1.5, 1.0, -0.4) - DVec3::new(0.5, -1.0, 0.2)).length() * 1.5;
        let want = std::f64::consts::TAU * 0.45 * len;
        assert!(
            (s.area() - want).abs() < 1e-5 * want,
            "{} vs {want}",
            s.area()
        );
        let m = g.m.as_dmat3();
        let c = g.c.as_dvec3();
        // The object-space point at (phi, z) and its uv (phi / 2 pi, z).
        let at = |phi: f64, z: f64| {
            let p = c + m * DVec3::new(phi.cos(), phi.sin(), z);
            (p, s.uv(0, 0.0, 0.0, p.as_vec3()).as_dvec2())
        };
        for (phi, z) in [(0.3, 0.2), (2.0, 0.9), (4.0, 0.5), (6.0, 0.05)] {
            let (p, uv) = at(phi, z);
            assert!(
                (uv - DVec2::new(phi / std::f64::consts::TAU, z)).length() < 1e-5,
                "{uv}"
            );
            let fd = fd_dpdu(|a, b| at(phi + a, z + b));
            let got = s.dpdu(0, 0.0, 0.0, p.as_vec3()).as_dvec3();
            // uv comes from f32 points ~3 units out: ~3e-7 over steps of 2e-4.
            assert!(
                (got - fd).length() < 5e-3 * fd.length(),
                "dpdu {got} vs {fd}"
            );
            // Outward normal: from the axis to the point.
            let sp = s.surface(0, 0.0, 0.0, p.as_vec3());
            let axis = m.z_axis.normalize();
            let radial = (p - c) - axis * (p - c).dot(axis);
            assert!((sp.ng.as_dvec3() - radial.normalize()).length() < 1e-5);
            assert!((sp.p.as_dvec3() - p).length() < 1e-5);
        }
        // Mitsuba's frame for the default axis +z: phi = 0 along object +x.
        let d = parse_shape("cylinder", "").unwrap();
        assert!((d.area() - std::f64::consts::TAU).abs() < 1e-5);
        assert!(
            (d.uv(0, 0.0, 0.0, Vec3::new(0.0, 1.0, 0.25)) - Vec2::new(0.25, 0.25)).length() < 1e-6
        );
        assert!(
            (d.dpdu(0, 0.0, 0.0, Vec3::new(1.0, 0.0, 0.5)) - Vec3::Y * std::f32::consts::TAU)
                .length()
                < 1e-5
        );
        for (bad, want) in [
            (
                r#"<float name="radius" value="-1"/>"#,
                "cylinder radius must be positive, got -1",
            ),
            (
                r#"<float name="radius" value="nan"/>"#,
                "'nan' is not a finite number",
            ),
            (
                r#"<point name="p0" x="0" y="0" z="1"/>"#,
                "p0 [0, 0, 1] and p1 [0, 0, 1] must differ",
            ),
            (
                r#"<transform name="to_world"><scale x="2"/></transform>"#,
                "must scale its cross-section uniformly",
            ),
        ] {
            let e = parse_shape("cylinder", bad).unwrap_err().to_string();
            assert!(e.contains(want), "{bad}: {e}");
        }
    }

    #[test]
    fn mesh_file_uv_is_interpolated_and_obj_v_flipped() {
        use crate::scene::ctx::Ctx;
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("t.ply"),
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             property float s\nproperty float t\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
             0 0 0 0.1 0.2\n1 0 0 0.9 0.2\n0 1 0 0.1 0.8\n3 0 1 2\n",
        )
        .unwrap();
        std::fs::write(
            dir.path().join("t.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.1 0.2\nvt 0.9 0.2\nvt 0.1 0.8\nf 1/1 2/2 3/3\n",
        )
        .unwrap();
        std::fs::write(
            dir.path().join("n.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .unwrap();
        let file = dir.path().join("scene.xml");
        let load = |kind: &str, name: &str, extra: &str| {
            let xml = format!(
                r#"<shape type="{kind}"><string name="filename" value="{name}"/>{extra}</shape>"#
            );
            let defaults = std::collections::HashMap::new();
            let ctx = Ctx::new(&file, &xml, &defaults);
            let doc = roxmltree::Document::parse(&xml).unwrap();
            let mut props = Props::parse(&ctx, doc.root_element()).unwrap();
            let s = shape(parse_geometry(kind, &mut props).unwrap());
            props.finish().unwrap();
            s
        };
        let close = |a: Vec2, b: [f32; 2]| (a - Vec2::from_array(b)).length() < 1e-6;
        // PLY: as stored; at barycentrics (0.5, 0.25): 0.25 uv0 + 0.5 uv1 + 0.25 uv2.
        let ply = load("ply", "t.ply", "");
        assert!(close(ply.uv(0, 0.5, 0.25, Vec3::ZERO), [0.5, 0.35]));
        let flipped = load(
            "ply",
            "t.ply",
            r#"<boolean name="flip_tex_coords" value="true"/>"#,
        );
        assert!(close(flipped.uv(0, 0.5, 0.25, Vec3::ZERO), [0.5, 0.65]));
        // OBJ: v flipped by default (Mitsuba's obj.cpp), not with flip_tex_coords=false.
        let obj = load("obj", "t.obj", "");
        assert!(close(obj.uv(0, 0.0, 0.0, Vec3::ZERO), [0.1, 0.8]));
        assert!(close(obj.uv(0, 0.5, 0.25, Vec3::ZERO), [0.5, 0.65]));
        let kept = load(
            "obj",
            "t.obj",
            r#"<boolean name="flip_tex_coords" value="false"/>"#,
        );
        assert!(close(kept.uv(0, 0.5, 0.25, Vec3::ZERO), [0.5, 0.35]));
        // Without texture coordinates: the barycentrics.
        let none = load("obj", "n.obj", "");
        assert!(close(none.uv(0, 0.3, 0.6, Vec3::ZERO), [0.3, 0.6]));
    }
}
