//! `<texture>` elements: `bitmap` and `checkerboard` (parameters documented in
//! `textures/bitmap.rs` and `textures/checkerboard.rs`), nested in a plugin as a named
//! parameter or defined at the top level with an `id` and referenced by `<ref>`.
//!
//! [`texture_param`] is what a plugin calls for a parameter that accepts a texture:
//! `<rgb>`/`<float name=...>` gives [`Texture::Constant`], `<texture name=...>` is
//! parsed in place, `<ref name=... id=...>` looks up a top-level texture.

use super::ctx::Ctx;
use super::error::SceneError;
use super::props::{Props, Value};
use crate::textures::image_file::load_image;
use crate::textures::{
    Bitmap, Checkerboard, FilterType, MeshAttributeTexture, Texture, UvTransform, WrapMode,
};
use glam::Vec3;
use roxmltree::Node;
use std::collections::HashMap;
use std::sync::Arc;

/// Top-level textures by id.
pub type NamedTextures = HashMap<String, Texture>;

fn to_uv(props: &mut Props) -> Result<UvTransform, SceneError> {
    Ok(props
        .transform("to_uv")?
        .map_or(UvTransform::IDENTITY, |m| UvTransform::from_mat4(&m)))
}

/// Parses one `<texture type="...">` element.
/// `named` holds the top-level textures a nested `<ref>` may name.
pub fn parse_texture(ctx: &Ctx, node: Node, named: &NamedTextures) -> Result<Texture, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    let mut props = Props::parse(ctx, node)?;
    let read = super::table::reader(TEXTURES, &kind).ok_or_else(|| {
        props.err(format!(
            "unknown texture type '{kind}' (supported: {})",
            super::table::names(TEXTURES).join(", ")
        ))
    })?;
    let texture = read(&mut props, named)?;
    if let Some(&obj) = props.objects.first() {
        return Err(ctx.err(
            obj,
            format!(
                "unexpected nested element in <texture type=\"{kind}\"> (a checkerboard takes textures only as color0 and color1)"
            ),
        ));
    }
    props.finish()?;
    Ok(texture)
}

/// The `texture` plugins and their readers (the plugin table's `texture` family,
/// [`super::plugins`]), in the order errors list them.
pub(super) const TEXTURES: &[(&str, ReadTexture)] = &[
    ("bitmap", read_bitmap),
    ("checkerboard", read_checkerboard),
    ("mesh_attribute", read_mesh_attribute),
    ("rawconstant", read_rawconstant),
];

/// Reads one `<texture>` plugin.
pub(super) type ReadTexture =
    fn(&mut Props<'_, '_, '_>, &NamedTextures) -> Result<Texture, SceneError>;

/// `<texture type="checkerboard">`.
fn read_checkerboard(props: &mut Props, named: &NamedTextures) -> Result<Texture, SceneError> {
    let colour = |props: &mut Props, name: &str, default: f32| {
        let t =
            texture_param(props, name, named)?.unwrap_or(Texture::Constant(Vec3::splat(default)));
        if let Texture::Constant(c) = t {
            if !c.is_finite() {
                return Err(props.err_at(name, format!("{name} must be finite")));
            }
        }
        refuse_mesh_attribute(props, name, &t, "a checkerboard's colour")?;
        Ok(Box::new(t))
    };
    let color0 = colour(props, "color0", 0.4)?;
    let color1 = colour(props, "color1", 0.2)?;
    Ok(Texture::Checkerboard(Checkerboard {
        color0,
        color1,
        to_uv: to_uv(props)?,
    }))
}

/// `<texture type="bitmap">`.
fn read_bitmap(props: &mut Props, _named: &NamedTextures) -> Result<Texture, SceneError> {
    Ok(Texture::Bitmap(Arc::new(parse_bitmap(props)?)))
}

/// `<texture type="mesh_attribute">`.
fn read_mesh_attribute(props: &mut Props, _named: &NamedTextures) -> Result<Texture, SceneError> {
    let name = props.string("name")?.ok_or_else(|| {
        props.err("missing parameter 'name' (the mesh attribute, e.g. vertex_color)")
    })?;
    // Mitsuba's test: the name contains one of the prefixes.
    if !name.contains("vertex_") && !name.contains("face_") {
        return Err(props.err_at(
            "name",
            format!(
                "invalid mesh attribute name '{name}': it must start with \"vertex_\" or \"face_\""
            ),
        ));
    }
    let scale = props.float_or("scale", 1.0)? as f32;
    Ok(Texture::MeshAttribute(MeshAttributeTexture {
        name: name.into(),
        scale,
    }))
}

/// `<texture type="rawconstant">`.
///
/// Mitsuba's `rawconstant`: the value as it is (no colour conversion), a float
/// in every channel or a 3-vector.
fn read_rawconstant(props: &mut Props, _named: &NamedTextures) -> Result<Texture, SceneError> {
    let value = match props.peek("value") {
        None => return Err(props.err("missing parameter 'value' (a <float> or <vector>)")),
        Some(Value::Point(_)) => {
            let v = props.point("value")?.unwrap_or_default();
            Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32)
        }
        Some(_) => Vec3::splat(
            props
                .float("value")?
                .ok_or_else(|| props.err("missing parameter 'value'"))? as f32,
        ),
    };
    Ok(Texture::Constant(value))
}

fn parse_bitmap(props: &mut Props) -> Result<Bitmap, SceneError> {
    let filter = match props.string("filter_type")?.as_deref() {
        None | Some("bilinear") => FilterType::Bilinear,
        Some("nearest") => FilterType::Nearest,
        Some(other) => {
            return Err(props.err_at(
                "filter_type",
                format!("filter_type '{other}' is not one of: bilinear, nearest"),
            ))
        }
    };
    let wrap = match props.string("wrap_mode")?.as_deref() {
        None | Some("repeat") => WrapMode::Repeat,
        Some("mirror") => WrapMode::Mirror,
        Some("clamp") => WrapMode::Clamp,
        Some(other) => {
            return Err(props.err_at(
                "wrap_mode",
                format!("wrap_mode '{other}' is not one of: repeat, mirror, clamp"),
            ))
        }
    };
    // Storage precision and GPU texture units: we keep f32 texels on the CPU, which
    // matches `variant` exactly and the others to their rounding.
    match props.string("format")?.as_deref() {
        None | Some("auto" | "variant" | "float16" | "fp16" | "uint8") => {}
        Some(other) => {
            return Err(props.err_at(
                "format",
                format!("format '{other}' is not one of: auto, variant, float16, uint8"),
            ))
        }
    }
    props.boolean_or("accel", true)?;
    let raw = props.boolean_or("raw", false)?;
    let to_uv = to_uv(props)?;
    let name = props
        .string("filename")?
        .ok_or_else(|| props.err("missing parameter 'filename'"))?;
    if name.trim().is_empty() {
        return Err(props.err_at("filename", "the filename is empty"));
    }
    let path = props.ctx.resolve(&name);
    props.ctx.read_mesh_file(&path);
    let img = load_image(&path, raw)
        .map_err(|e| props.err_at("filename", format!("image '{name}' {e}")))?;
    Ok(Bitmap {
        width: img.width,
        height: img.height,
        channels: img.channels,
        data: img.data,
        filter,
        wrap,
        to_uv,
    })
}

/// Refuses a `mesh_attribute` texture (or a checkerboard holding one) given as
/// parameter `name` of a plugin that looks textures up by uv only (`what` names it).
pub fn refuse_mesh_attribute(
    props: &Props,
    name: &str,
    t: &Texture,
    what: &str,
) -> Result<(), SceneError> {
    if t.uses_mesh_attributes() {
        return Err(props.err_at(
            name,
            format!("a mesh_attribute texture cannot be {what} (it is read only by materials on meshes)"),
        ));
    }
    Ok(())
}

/// A parameter that accepts a texture: an `<rgb>`/`<float>` constant, a nested
/// `<texture name=...>` or a `<ref name=... id=...>` to a top-level texture. `None`
/// when absent (the caller applies its default). The nested element is taken out of
/// `props.objects`, so the caller's check for unexpected nested elements still holds.
pub fn texture_param(
    props: &mut Props,
    name: &str,
    named: &NamedTextures,
) -> Result<Option<Texture>, SceneError> {
    let ctx = props.ctx;
    let mut found: Option<Texture> = None;
    let mut nested: Option<Node> = None;
    let mut i = 0;
    while i < props.objects.len() {
        let obj = props.objects[i];
        let tag = obj.tag_name().name();
        if (tag == "texture" || tag == "ref") && ctx.attr(obj, "name")?.as_deref() == Some(name) {
            if nested.is_some() {
                return Err(ctx.err(obj, format!("parameter '{name}' given twice")));
            }
            nested = Some(props.objects.remove(i));
        } else {
            i += 1;
        }
    }
    if let Some(obj) = nested {
        if props.peek(name).is_some() {
            return Err(ctx.err(obj, format!("parameter '{name}' given twice")));
        }
        found = Some(if obj.tag_name().name() == "ref" {
            let id = ctx.required_attr(obj, "id")?;
            named.get(&id).cloned().ok_or_else(|| {
                ctx.err(
                    obj,
                    format!("no <texture id=\"{id}\"> before this reference"),
                )
            })?
        } else {
            parse_texture(ctx, obj, named)?
        });
    }
    if found.is_none() {
        if let Some(c) = props.rgb(name)? {
            found = Some(Texture::Constant(c));
        }
    }
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;
    use std::path::Path;

    /// Runs `f` on the root element of `xml`, a file in `dir`.
    fn with_node<T>(
        dir: &Path,
        xml: &str,
        f: impl FnOnce(&Ctx, Node) -> Result<T, SceneError>,
    ) -> Result<T, SceneError> {
        let file = dir.join("scene.xml");
        let defaults = HashMap::new();
        let ctx = Ctx::new(&file, xml, &defaults);
        let doc = roxmltree::Document::parse(xml).unwrap();
        f(&ctx, doc.root_element())
    }

    fn texture(dir: &Path, xml: &str) -> Result<Texture, SceneError> {
        with_node(dir, xml, |c, n| parse_texture(c, n, &NamedTextures::new()))
    }

    /// A 2 x 2 PNG: (0, 0) = 0, (1, 0) = 64, (0, 1) = 128, (1, 1) = 255 in every channel.
    fn png_2x2(dir: &Path) {
        let bytes = [0u8, 64, 128, 255].iter().flat_map(|&v| [v; 3]).collect();
        image::RgbImage::from_raw(2, 2, bytes)
            .unwrap()
            .save(dir.join("t.png"))
            .unwrap();
    }

    fn bitmap(dir: &Path, params: &str) -> Texture {
        texture(
            dir,
            &format!(r#"<texture type="bitmap"><string name="filename" value="t.png"/>{params}</texture>"#),
        )
        .unwrap()
    }

    fn srgb(v: u8) -> f32 {
        crate::textures::image_file::srgb_to_linear(v as f32 / 255.0)
    }

    #[test]
    fn bitmap_nearest_and_bilinear_on_a_png() {
        let dir = tempfile::tempdir().unwrap();
        png_2x2(dir.path());
        let near = bitmap(
            dir.path(),
            r#"<string name="filter_type" value="nearest"/><boolean name="raw" value="true"/>"#,
        );
        // v = 0 is the image's first row.
        assert_eq!(near.eval_float(Vec2::new(0.1, 0.1)), 0.0);
        assert_eq!(near.eval_float(Vec2::new(0.9, 0.1)), 64.0 / 255.0);
        assert_eq!(near.eval_float(Vec2::new(0.1, 0.9)), 128.0 / 255.0);
        assert_eq!(near.eval_float(Vec2::new(0.9, 0.9)), 1.0);
        // Bilinear at the image centre: the mean of the four linear texels.
        let lin = bitmap(dir.path(), "");
        let mean = (srgb(0) + srgb(64) + srgb(128) + srgb(255)) / 4.0;
        let c = lin.eval_rgb(Vec2::new(0.5, 0.5));
        assert!((c - Vec3::splat(mean)).abs().max_element() < 1e-6, "{c}");
        // At (0.5, 0.25) (the first row's centre line): halfway between 0 and 64.
        let c = lin.eval_rgb(Vec2::new(0.5, 0.25)).x;
        assert!((c - (srgb(0) + srgb(64)) / 2.0).abs() < 1e-6);
        // Float lookups of RGB images are luminances (grey here: the value).
        assert!((lin.eval_float(Vec2::new(0.5, 0.5)) - mean).abs() < 1e-6);
    }

    #[test]
    fn bitmap_wrap_modes_outside_the_unit_square() {
        let dir = tempfile::tempdir().unwrap();
        png_2x2(dir.path());
        let raw =
            r#"<boolean name="raw" value="true"/><string name="filter_type" value="nearest"/>"#;
        let at = |wrap: &str, u: f32| {
            bitmap(
                dir.path(),
                &format!(r#"{raw}<string name="wrap_mode" value="{wrap}"/>"#),
            )
            .eval_float(Vec2::new(u, 0.1))
                * 255.0
        };
        // u = -0.25 is texel -1; u = 1.25 texel 2; u = 1.75 texel 3.
        assert_eq!(at("repeat", -0.25), 64.0);
        assert_eq!(at("mirror", -0.25), 0.0);
        assert_eq!(at("clamp", -0.25), 0.0);
        assert_eq!(at("repeat", 1.25), 0.0);
        assert_eq!(at("mirror", 1.25), 64.0);
        assert_eq!(at("mirror", 1.75), 0.0);
        assert_eq!(at("clamp", 1.75), 64.0);
        // Bilinear with clamp at u = 0: only texel 0 (sRGB 0).
        let b = bitmap(dir.path(), r#"<string name="wrap_mode" value="clamp"/>"#);
        assert_eq!(b.eval_float(Vec2::new(0.0, 0.25)), 0.0);
        // Bilinear with repeat at u = 0: halfway between texels 1 and 0.
        let b = bitmap(dir.path(), "");
        assert!((b.eval_rgb(Vec2::new(0.0, 0.25)).x - srgb(64) / 2.0).abs() < 1e-6);
    }

    #[test]
    fn bitmap_on_an_exr_and_to_uv() {
        let dir = tempfile::tempdir().unwrap();
        exr::prelude::write_rgb_file(dir.path().join("t.exr"), 2, 2, |x, y| {
            let v = (x + 2 * y) as f32;
            (v, 2.0 * v, 0.5f32)
        })
        .unwrap();
        let t = texture(
            dir.path(),
            r#"<texture type="bitmap"><string name="filename" value="t.exr"/>
                 <transform name="to_uv"><scale x="0.5" y="0.5"/></transform></texture>"#,
        )
        .unwrap();
        // to_uv halves uv: (1.5, 0.5) looks up (0.75, 0.25), texel (1, 0) = 1 (no sRGB).
        assert_eq!(t.eval_rgb(Vec2::new(1.5, 0.5)), Vec3::new(1.0, 2.0, 0.5));
        // Bilinear between (0, 1) = 2 and (1, 1) = 3.
        assert!((t.eval_rgb(Vec2::new(1.0, 1.5)).x - 2.5).abs() < 1e-6);
    }

    #[test]
    fn checkerboard_parameters() {
        let dir = tempfile::tempdir().unwrap();
        let t = texture(
            dir.path(),
            r#"<texture type="checkerboard"><rgb name="color0" value="1, 0, 0"/><float name="color1" value="0.5"/>
                 <transform name="to_uv"><scale x="2" y="2"/></transform></texture>"#,
        )
        .unwrap();
        assert_eq!(t.eval_rgb(Vec2::new(0.1, 0.1)), Vec3::X);
        assert_eq!(t.eval_rgb(Vec2::new(0.3, 0.1)), Vec3::splat(0.5));
        let d = texture(dir.path(), r#"<texture type="checkerboard"/>"#).unwrap();
        assert_eq!(d.eval_rgb(Vec2::new(0.6, 0.6)), Vec3::splat(0.4));
    }

    #[test]
    fn errors_name_the_element_and_fit_one_line() {
        let dir = tempfile::tempdir().unwrap();
        png_2x2(dir.path());
        std::fs::write(
            dir.path().join("bad.png"),
            b"\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR",
        )
        .unwrap();
        let cases = [
            (
                r#"<texture type="checkerboard"><float name="colour0" value="1"/></texture>"#,
                "unknown parameter 'colour0'",
            ),
            (
                r#"<texture type="marble"/>"#,
                "unknown texture type 'marble'",
            ),
            (
                r#"<texture type="bitmap"/>"#,
                "missing parameter 'filename'",
            ),
            (
                r#"<texture type="bitmap"><string name="filename" value="none.png"/></texture>"#,
                "image 'none.png'",
            ),
            (
                r#"<texture type="bitmap"><string name="filename" value="bad.png"/></texture>"#,
                "image 'bad.png'",
            ),
            (
                r#"<texture type="bitmap"><string name="filename" value="t.png"/><string name="wrap_mode" value="tile"/></texture>"#,
                "wrap_mode 'tile'",
            ),
            (
                r#"<texture type="bitmap"><string name="filename" value="t.png"/><string name="filter_type" value="cubic"/></texture>"#,
                "filter_type 'cubic'",
            ),
            (
                r#"<texture type="checkerboard"><texture name="color2" type="checkerboard"/></texture>"#,
                "unexpected nested element",
            ),
            (
                r#"<texture type="checkerboard"><ref name="color0" id="nowhere"/></texture>"#,
                "no <texture id=\"nowhere\">",
            ),
        ];
        for (xml, want) in cases {
            let e = texture(dir.path(), xml).unwrap_err().to_string();
            assert!(e.contains(want), "{xml}: {e}");
            assert!(e.contains("scene.xml:1: <"), "{e}");
            assert!(!e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn texture_params_from_constants_nested_textures_and_refs() {
        let dir = tempfile::tempdir().unwrap();
        let mut named = NamedTextures::new();
        named.insert(
            "checks".into(),
            Texture::Checkerboard(Checkerboard::default()),
        );
        let param = |xml: &str, named: &NamedTextures| {
            with_node(dir.path(), xml, |ctx, node| {
                let mut p = Props::parse(ctx, node)?;
                let t = texture_param(&mut p, "reflectance", named)?;
                assert!(p.objects.is_empty());
                p.finish()?;
                Ok(t)
            })
        };
        let c = param(
            r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.1 0.2 0.3"/></bsdf>"#,
            &named,
        );
        assert_eq!(
            c.unwrap(),
            Some(Texture::Constant(Vec3::new(0.1, 0.2, 0.3)))
        );
        let n = param(
            r#"<bsdf type="diffuse"><texture type="checkerboard" name="reflectance"/></bsdf>"#,
            &named,
        );
        assert_eq!(
            n.unwrap(),
            Some(Texture::Checkerboard(Checkerboard::default()))
        );
        let r = param(
            r#"<bsdf type="diffuse"><ref name="reflectance" id="checks"/></bsdf>"#,
            &named,
        );
        assert_eq!(
            r.unwrap(),
            Some(Texture::Checkerboard(Checkerboard::default()))
        );
        assert_eq!(param(r#"<bsdf type="diffuse"/>"#, &named).unwrap(), None);
        let e = param(
            r#"<bsdf type="diffuse"><ref name="reflectance" id="nope"/></bsdf>"#,
            &named,
        );
        assert!(e
            .unwrap_err()
            .to_string()
            .contains("no <texture id=\"nope\">"));
        let e = param(
            r#"<bsdf type="diffuse"><rgb name="reflectance" value="1"/><texture type="checkerboard" name="reflectance"/></bsdf>"#,
            &named,
        );
        assert!(e.unwrap_err().to_string().contains("given twice"));
    }
}
