//! `<emitter type="envmap|constant|directional">` at the top level: Mitsuba 3's
//! infinitely distant emitters (parameters in `lights/mod.rs` and `lights/envmap.rs`).
//! Their bounding sphere is set once the shapes are known (`Emitter::set_scene_sphere`).

use super::ctx::Ctx;
use super::error::SceneError;
use super::props::Props;
use crate::lights::envmap::{EnvMap, EnvMapError};
use crate::lights::scene_sphere::SceneSphere;
use crate::lights::Emitter;
use crate::math::Rgb;
use crate::textures::image_file::load_image_within;
use glam::{DMat3, DMat4, DVec3, Vec3};
use roxmltree::Node;
use std::sync::Arc;

/// The infinitely distant emitter kinds.
pub const KINDS: &[&str] = &["envmap", "constant", "directional"];

/// The largest environment map, in texels (8192 x 4096): an envmap keeps about 32
/// bytes per texel while it is built (the decoded image, its RGB copy and the
/// sampling tables), so 2^25 texels peak near 1.1 GB. Checked from the image header
/// before decoding; a 16384 x 16384 map, which aborted on a 3.2 GB allocation, is an
/// error naming the limit.
pub const MAX_ENVMAP_TEXELS: u64 = 1 << 25;

pub fn parse_infinite_emitter(ctx: &Ctx, node: Node, kind: &str) -> Result<Emitter, SceneError> {
    let mut p = Props::parse(ctx, node)?;
    let emitter = match kind {
        "envmap" => parse_envmap(&mut p)?,
        "constant" => {
            let radiance = colour(&mut p, "radiance")?;
            Emitter::Constant {
                radiance,
                sphere: SceneSphere::default(),
            }
        }
        "directional" => {
            let irradiance = colour(&mut p, "irradiance")?;
            let direction = match (p.point("direction")?, p.transform("to_world")?) {
                (Some(_), Some(_)) => {
                    return Err(
                        p.err("give either 'direction' or 'to_world', not both (as Mitsuba)")
                    )
                }
                (Some(d), None) => DVec3::from(d),
                (None, Some(m)) => m.transform_vector3(DVec3::Z),
                (None, None) => DVec3::Z,
            };
            if !(direction.is_finite() && direction.length() > 0.0) {
                return Err(p.err_at(
                    if p.peek("direction").is_some() {
                        "direction"
                    } else {
                        "to_world"
                    },
                    "the light's direction is zero or not finite",
                ));
            }
            Emitter::Directional {
                direction: direction.normalize().as_vec3(),
                irradiance,
                sphere: SceneSphere::default(),
            }
        }
        other => unreachable!("not an infinite emitter: {other}"),
    };
    if let Some(&o) = p.objects.first() {
        return Err(ctx.err(
            o,
            format!("unexpected nested element in <emitter type=\"{kind}\"> (textured emission is not supported)"),
        ));
    }
    p.finish()?;
    Ok(emitter)
}

/// `radiance` / `irradiance`: non-negative, default 1; zero warns.
fn colour(p: &mut Props, name: &str) -> Result<Rgb, SceneError> {
    let c = p.emission(name)?.unwrap_or(Rgb::ONE);
    if c.is_nan() || c.min_element() < 0.0 {
        return Err(p.err_at(name, format!("{name} must be non-negative")));
    }
    if c.max_element() == 0.0 {
        p.warn_at(
            name,
            format!("{name} is zero (in single precision): this emitter contributes nothing"),
        );
    }
    Ok(c)
}

fn parse_envmap(p: &mut Props) -> Result<Emitter, SceneError> {
    if p.peek("filter_type").is_some() {
        return Err(p.err_at(
            "filter_type",
            "envmap has no parameter 'filter_type' in Mitsuba 3 (it always interpolates bilinearly); remove it",
        ));
    }
    let name = p
        .string("filename")?
        .ok_or_else(|| p.err("missing parameter 'filename' (the environment image)"))?;
    if name.trim().is_empty() {
        return Err(p.err_at("filename", "the filename is empty"));
    }
    let scale = p.float_or("scale", 1.0)?;
    if scale.is_nan() || scale < 0.0 {
        return Err(p.err_at("scale", format!("scale must be non-negative, got {scale}")));
    }
    let to_world = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
    let mis_compensation = p.boolean_or("mis_compensation", false)?;
    let path = p.ctx.resolve(&name);
    p.ctx.read_mesh_file(&path);
    let img = load_image_within(&path, false, MAX_ENVMAP_TEXELS, "an environment map")
        .map_err(|e| p.err_at("filename", format!("image '{name}' {e}")))?;
    let rgb: Vec<Vec3> = if img.channels == 1 {
        img.data.iter().map(|&v| Vec3::splat(v)).collect()
    } else {
        img.data
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect()
    };
    let negative = rgb
        .iter()
        .filter(|c| c.is_finite() && c.min_element() < 0.0)
        .count();
    if negative > 0 {
        p.warn_at(
            "filename",
            format!(
                "image '{name}' has {negative} texels with negative values; they are taken as 0"
            ),
        );
    }
    let (width, height) = (img.width, img.height);
    drop(img);
    let peak = rgb
        .iter()
        .filter(|c| c.is_finite())
        .fold(0.0f32, |m, c| m.max(c.max_element()));
    if !((scale * peak as f64) as f32).is_finite() {
        return Err(p.err_at(
            "scale",
            format!("scale {scale:e} times the image's largest value {peak:e} overflows single precision"),
        ));
    }
    let linear = DMat3::from_mat4(to_world);
    let map = EnvMap::new(
        width,
        height,
        rgb,
        scale as f32,
        linear,
        mis_compensation,
    )
    .map_err(|e| match e {
        EnvMapError::NonFinite(x, y) => p.err_at(
            "filename",
            format!("image '{name}' has a NaN or infinite value at texel ({x}, {y})"),
        ),
        EnvMapError::NotARotation => p.err_at(
            "to_world",
            "an envmap's to_world must be a rotation (or a reflection): Mitsuba does not renormalise directions through a scale or shear",
        ),
    })?;
    if map.is_black() {
        p.warn_at(
            "filename",
            format!(
                "image '{name}' times scale {scale} is black: this emitter contributes nothing"
            ),
        );
    }
    Ok(Emitter::Envmap {
        map: Arc::new(map),
        sphere: SceneSphere::default(),
    })
}
