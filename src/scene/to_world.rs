//! `<transform name="to_world">`: translate, rotate, scale, matrix and lookat, composed in
//! document order (each element applies after the previous ones), as in Mitsuba 3.

use super::ctx::{scene_number, scene_numbers, Ctx};
use super::error::SceneError;
use glam::{DMat4, DVec3, DVec4};
use roxmltree::Node;

fn number(ctx: &Ctx, node: Node, attr: &str, default: f64) -> Result<f64, SceneError> {
    match ctx.attr(node, attr)? {
        None => Ok(default),
        Some(v) => scene_number(&v).map_err(|e| ctx.err(node, format!("attribute '{attr}': {e}"))),
    }
}

/// Dr.Jit's `rotate` (Mitsuba's `<rotate>`): `c I + (1 - c) a a^T + s [a]x` with the
/// axis `a` as written, not normalised, so an axis such as (0, 1, 1) gives the same
/// (non-orthogonal) matrix as in Mitsuba 3.
pub fn rotation(a: DVec3, angle: f64) -> DMat4 {
    let (s, c) = angle.sin_cos();
    let cm = 1.0 - c;
    DMat4::from_cols(
        DVec4::new(
            a.x * a.x * cm + c,
            a.y * a.x * cm + a.z * s,
            a.z * a.x * cm - a.y * s,
            0.0,
        ),
        DVec4::new(
            a.x * a.y * cm - a.z * s,
            a.y * a.y * cm + c,
            a.z * a.y * cm + a.x * s,
            0.0,
        ),
        DVec4::new(
            a.x * a.z * cm + a.y * s,
            a.y * a.z * cm - a.x * s,
            a.z * a.z * cm + c,
            0.0,
        ),
        DVec4::W,
    )
}

fn vector(ctx: &Ctx, node: Node, attr: &str) -> Result<DVec3, SceneError> {
    let v = ctx.required_attr(node, attr)?;
    let f = scene_numbers(&v).map_err(|e| ctx.err(node, format!("attribute '{attr}': {e}")))?;
    if f.len() != 3 {
        return Err(ctx.err(
            node,
            format!("attribute '{attr}' needs three numbers, got '{v}'"),
        ));
    }
    Ok(DVec3::new(f[0], f[1], f[2]))
}

fn check_attrs(ctx: &Ctx, node: Node, allowed: &[&str]) -> Result<(), SceneError> {
    for a in node.attributes() {
        if !allowed.contains(&a.name()) {
            return Err(ctx.err(node, format!("unknown attribute '{}'", a.name())));
        }
    }
    Ok(())
}

/// Mitsuba's look-at: camera +z towards the target, +y up, +x = up x dir ("left").
pub fn look_at(origin: DVec3, target: DVec3, up: DVec3) -> Option<DMat4> {
    let dir = (target - origin).try_normalize()?;
    let left = up.cross(dir).try_normalize()?;
    let new_up = dir.cross(left);
    Some(DMat4::from_cols(
        left.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        origin.extend(1.0),
    ))
}

/// Parses the children of a `<transform>` element into one matrix.
pub fn parse_transform(ctx: &Ctx, node: Node) -> Result<DMat4, SceneError> {
    let mut m = DMat4::IDENTITY;
    for child in node.children().filter(|c| c.is_element()) {
        let step = match child.tag_name().name() {
            "translate" => {
                check_attrs(ctx, child, &["x", "y", "z", "value"])?;
                let t = match ctx.attr(child, "value")? {
                    Some(_) => vector(ctx, child, "value")?,
                    None => DVec3::new(
                        number(ctx, child, "x", 0.0)?,
                        number(ctx, child, "y", 0.0)?,
                        number(ctx, child, "z", 0.0)?,
                    ),
                };
                DMat4::from_translation(t)
            }
            "scale" => {
                check_attrs(ctx, child, &["x", "y", "z", "value"])?;
                let s = match ctx.attr(child, "value")? {
                    Some(v) if !v.contains(',') && v.split_whitespace().count() == 1 => {
                        DVec3::splat(number(ctx, child, "value", 1.0)?)
                    }
                    Some(_) => vector(ctx, child, "value")?,
                    None => DVec3::new(
                        number(ctx, child, "x", 1.0)?,
                        number(ctx, child, "y", 1.0)?,
                        number(ctx, child, "z", 1.0)?,
                    ),
                };
                if s.x == 0.0 || s.y == 0.0 || s.z == 0.0 {
                    return Err(ctx.err(child, "a zero scale makes the transform singular"));
                }
                DMat4::from_scale(s)
            }
            "rotate" => {
                check_attrs(ctx, child, &["x", "y", "z", "value", "angle"])?;
                let axis = match ctx.attr(child, "value")? {
                    Some(_) => vector(ctx, child, "value")?,
                    None => DVec3::new(
                        number(ctx, child, "x", 0.0)?,
                        number(ctx, child, "y", 0.0)?,
                        number(ctx, child, "z", 0.0)?,
                    ),
                };
                if axis == DVec3::ZERO || !axis.is_finite() {
                    return Err(ctx.err(child, "rotation axis is zero"));
                }
                if ctx.attr(child, "angle")?.is_none() {
                    return Err(ctx.err(child, "<rotate> needs an angle"));
                }
                let angle = number(ctx, child, "angle", 0.0)?;
                rotation(axis, angle.to_radians())
            }
            "matrix" => {
                check_attrs(ctx, child, &["value"])?;
                let v = ctx.required_attr(child, "value")?;
                let f = scene_numbers(&v).map_err(|e| ctx.err(child, e.to_string()))?;
                if f.len() != 16 && f.len() != 9 {
                    return Err(ctx.err(
                        child,
                        format!("'{v}' is not 16 (or 9) numbers in row-major order"),
                    ));
                }
                if f.len() == 16 && f[12..] != [0.0, 0.0, 0.0, 1.0] {
                    return Err(ctx.err(
                        child,
                        format!(
                            "the last row is {}, not 0 0 0 1: projective transforms are not supported",
                            f[12..].iter().map(|x| x.to_string()).collect::<Vec<_>>().join(" ")
                        ),
                    ));
                }
                if f.len() == 16 {
                    // Row-major in the file; glam is column-major.
                    DMat4::from_cols_array(&[
                        f[0], f[4], f[8], f[12], f[1], f[5], f[9], f[13], f[2], f[6], f[10],
                        f[14], f[3], f[7], f[11], f[15],
                    ])
                } else {
                    DMat4::from_cols(
                        DVec4::new(f[0], f[3], f[6], 0.0),
                        DVec4::new(f[1], f[4], f[7], 0.0),
                        DVec4::new(f[2], f[5], f[8], 0.0),
                        DVec4::W,
                    )
                }
            }
            "lookat" | "look_at" => {
                check_attrs(ctx, child, &["origin", "target", "up"])?;
                let origin = vector(ctx, child, "origin")?;
                let target = vector(ctx, child, "target")?;
                let up = match ctx.attr(child, "up")? {
                    Some(_) => vector(ctx, child, "up")?,
                    None => DVec3::Y,
                };
                look_at(origin, target, up).ok_or_else(|| {
                    ctx.err(child, "origin equals target, or up is parallel to the view direction")
                })?
            }
            other => {
                return Err(ctx.err(
                    child,
                    format!("unknown transform '{other}' (supported: translate, rotate, scale, matrix, lookat)"),
                ))
            }
        };
        m = step * m;
        if !m.is_finite() {
            return Err(ctx.err(
                child,
                "the transform overflows (its entries are not finite)",
            ));
        }
    }
    check_invertible(&m).map_err(|e| ctx.err(node, e.to_string()))?;
    Ok(m)
}

/// A transform whose linear part flattens space (or is not finite); `relative_determinant`
/// is its determinant over the product of its column lengths (0 when those are not
/// positive and finite).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error(
    "the transform is singular (it flattens space: relative determinant {relative_determinant:.1e})"
)]
pub struct SingularTransform {
    pub relative_determinant: f64,
}

/// A transform must map 3D onto 3D: its linear part may not flatten any direction.
/// Scale-invariant: compares the determinant with the product of the column lengths
/// (1 for any rotation or scaling, 0 for a matrix that collapses a direction), so a
/// tiny but uniform scale passes and a nearly flat one does not.
fn check_invertible(m: &DMat4) -> Result<(), SingularTransform> {
    let cols = [
        m.x_axis.truncate(),
        m.y_axis.truncate(),
        m.z_axis.truncate(),
    ];
    let lens = cols.map(|c| c.length());
    let det = cols[0].dot(cols[1].cross(cols[2]));
    let scale = lens[0] * lens[1] * lens[2];
    if !(scale > 0.0 && scale.is_finite() && det.is_finite()) || det.abs() < 1e-12 * scale {
        return Err(SingularTransform {
            relative_determinant: if scale > 0.0 { det.abs() / scale } else { 0.0 },
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;
    use std::path::Path;

    fn parse(xml: &str) -> Result<DMat4, SceneError> {
        let doc = roxmltree::Document::parse(xml).unwrap();
        let defaults = HashMap::new();
        let ctx = Ctx::new(Path::new("t.xml"), xml, &defaults);
        parse_transform(&ctx, doc.root_element())
    }

    #[test]
    fn elements_compose_in_document_order() {
        // scale by 2, then rotate 90 deg about z, then translate x by 1:
        // (1,0,0) -> (2,0,0) -> (0,2,0) -> (1,2,0).
        let m = parse(
            r#"<transform name="to_world"><scale value="2"/><rotate z="1" angle="90"/><translate x="1"/></transform>"#,
        )
        .unwrap();
        let p = m.transform_point3(DVec3::X);
        assert!((p - DVec3::new(1.0, 2.0, 0.0)).length() < 1e-12, "{p}");
    }

    #[test]
    fn rotate_keeps_the_axis_as_written_as_mitsuba_does() {
        // mitsuba.ScalarTransform4f().rotate([0, 1, 1], 15).matrix in Mitsuba 3.9.1
        // (also what its XML parser builds): the axis is not normalised.
        let want = [
            [0.965926, -0.258819, 0.258819],
            [0.258819, 1.0, 0.0340742],
            [-0.258819, 0.0340742, 1.0],
        ];
        let m = parse(r#"<transform name="t"><rotate x="0" y="1" z="1" angle="15"/></transform>"#)
            .unwrap();
        for (r, row) in want.iter().enumerate() {
            for (c, w) in row.iter().enumerate() {
                assert!(
                    (m.col(c)[r] - w).abs() < 1e-6,
                    "({r}, {c}): {} vs {w}",
                    m.col(c)[r]
                );
            }
        }
        // A unit axis is a rotation; no angle or a zero axis is an error, as in Mitsuba.
        let u = parse(r#"<transform name="t"><rotate z="1" angle="90"/></transform>"#).unwrap();
        assert!((u.transform_point3(DVec3::X) - DVec3::Y).length() < 1e-12);
        let e = message(r#"<transform name="t"><rotate z="1"/></transform>"#);
        assert!(e.contains("<rotate> needs an angle"), "{e}");
        let e = message(r#"<transform name="t"><rotate x="0" angle="3"/></transform>"#);
        assert!(e.contains("rotation axis is zero"), "{e}");
    }

    #[test]
    fn matrix_is_row_major() {
        let m = parse(r#"<transform name="t"><matrix value="1 0 0 5  0 1 0 6  0 0 1 7  0 0 0 1"/></transform>"#)
            .unwrap();
        assert_eq!(m.transform_point3(DVec3::ZERO), DVec3::new(5.0, 6.0, 7.0));
    }

    #[test]
    fn lookat_points_z_at_target_and_x_left() {
        let m = parse(r#"<transform name="t"><lookat origin="0,0,3.9" target="0,0,0" up="0,1,0"/></transform>"#)
            .unwrap();
        assert!((m.transform_vector3(DVec3::Z) - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
        assert!((m.transform_vector3(DVec3::Y) - DVec3::Y).length() < 1e-12);
        // Camera +x is "left" as seen by the camera: looking down -z with +y up, that is -x.
        assert!((m.transform_vector3(DVec3::X) - DVec3::new(-1.0, 0.0, 0.0)).length() < 1e-12);
        assert!((m.transform_point3(DVec3::ZERO) - DVec3::new(0.0, 0.0, 3.9)).length() < 1e-12);
    }

    #[test]
    fn bad_transforms_are_errors() {
        let e = message(r#"<transform name="t"><shear x="1"/></transform>"#);
        assert!(e.contains("unknown transform 'shear'"), "{e}");
        let e = message(r#"<transform name="t"><rotate angle="3"/></transform>"#);
        assert!(e.contains("rotation axis is zero"), "{e}");
        let e = message(r#"<transform name="t"><scale x="0"/></transform>"#);
        assert!(
            e.contains("a zero scale makes the transform singular"),
            "{e}"
        );
        let e = message(r#"<transform name="t"><translate x="abc"/></transform>"#);
        assert!(
            e.contains("attribute 'x'") && e.contains("'abc' is not a finite number"),
            "{e}"
        );
        let e = message(r#"<transform name="t"><matrix value="1 2 3"/></transform>"#);
        assert!(e.contains("'1 2 3' is not 16 (or 9) numbers"), "{e}");
    }

    fn message(xml: &str) -> String {
        parse(xml).unwrap_err().to_string()
    }

    #[test]
    fn projective_overflowing_and_flat_transforms_are_errors() {
        let e = message(
            r#"<transform name="t"><matrix value="1 0 0 0 0 1 0 0 0 0 1 0 0 0 1 1"/></transform>"#,
        );
        assert!(e.contains("projective") && e.contains("matrix"), "{e}");
        let e = message(r#"<transform name="t"><translate x="1e39"/></transform>"#);
        assert!(
            e.contains("overflows single precision") && e.contains("'x'"),
            "{e}"
        );
        let e = message(
            r#"<transform name="t"><scale value="1e30"/><scale value="1e30"/><scale value="1e30"/><scale value="1e30"/><scale value="1e30"/><scale value="1e30"/><scale value="1e30"/><scale value="1e30"/><scale value="1e30"/><scale value="1e30"/><scale value="1e30"/></transform>"#,
        );
        assert!(e.contains("overflows"), "{e}");
        assert!(parse(
            r#"<transform name="t"><matrix value="1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"/></transform>"#
        )
        .is_ok());
        // Flat: a z scale of 1e-200 passes an absolute determinant test but not ours.
        let e = message(
            r#"<transform name="t"><matrix value="1 0 0 0 0 1 0 0 0 0 1e-200 0 0 0 0 1"/></transform>"#,
        );
        assert!(e.contains("singular"), "{e}");
        let e = message(
            r#"<transform name="t"><matrix value="1 1 0 0 1 1 0 0 0 0 1 0 0 0 0 1"/></transform>"#,
        );
        assert!(e.contains("singular"), "{e}");
        // A tiny uniform scale is not singular.
        assert!(parse(r#"<transform name="t"><scale value="1e-30"/></transform>"#).is_ok());
        let e = message(r#"<transform name="t"><translate x="nan"/></transform>"#);
        assert!(
            e.contains("attribute 'x'") && e.contains("'nan' is not a finite number"),
            "{e}"
        );
        let e = message(r#"<transform name="t"><rotate x="1" angle="inf"/></transform>"#);
        assert!(
            e.contains("attribute 'angle'") && e.contains("'inf' is not a finite number"),
            "{e}"
        );
    }
}
