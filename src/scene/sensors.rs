//! `<sensor>` (perspective, thinlens, orthographic, nlos_capture_meter) with its film,
//! sampler and medium: the camera and the time axis of the render.

use super::ctx::Ctx;
use super::error::SceneError;
use super::film::{parse_film, parse_film_for_meter};
use super::fov::parse_fov;
use super::limits::{check_world_point, MAX_COORDINATE};
use super::media::medium_index;
use super::props::Props;
use super::sampler::parse_sampler;
use crate::geometry::shape::Shape;
use crate::lights::Emitter;
use crate::media::Medium;
use crate::scene::textures::NamedTextures;
use crate::sensors::camera::FovAxis;
use crate::sensors::film::Film;
use glam::{DMat4, DVec3};
use roxmltree::Node;
use std::collections::HashMap;

pub(super) struct Sensor {
    /// Line of the `<sensor>` element, for errors found after the overrides.
    pub(super) line: u32,
    /// The plugin name, for errors found after the overrides.
    pub(super) kind: String,
    pub(super) to_world: DMat4,
    pub(super) projection: SensorProjection,
    /// Where camera rays start with the time origin `near_clip` (`time_origin.rs`);
    /// 0 for the meter, which has no near plane.
    pub(super) near_clip: f64,
    pub(super) film: Film,
    pub(super) spp: u32,
    pub(super) seed: u64,
    /// The medium the camera sits in (Mitsuba's sensor `medium`).
    pub(super) medium: Option<u32>,
    /// A laser nested in an `nlos_capture_meter` (mitransient <= 1.1).
    pub(super) laser: Option<Emitter>,
}

/// What the sensor plugin needs besides `to_world` and the film.
pub(super) enum SensorProjection {
    Perspective {
        fov: f64,
        fov_axis: FovAxis,
    },
    ThinLens {
        fov: f64,
        fov_axis: FovAxis,
        aperture_radius: f32,
        focus_distance: f32,
    },
    Orthographic,
    /// `nlos_capture_meter` on a relay wall.
    Meter(super::nlos_setup::CaptureMeter),
}

/// Why a sensor's `to_world` is refused.
#[derive(Debug, thiserror::Error)]
pub(super) enum SensorTransformError {
    #[error("thinlens: scale factors in the camera's to_world are not allowed (as in Mitsuba)")]
    ThinlensScale,
    #[error("orthographic: to_world's axes {0:?} must be non-zero, independent and at most {MAX_COORDINATE:e} long (they set the view's extent)")]
    OrthographicAxes([[f64; 3]; 3]),
}

/// A sensor's `to_world`: thinlens refuses scale as Mitsuba does (`has_scale`: some
/// pair of the linear part's rows has a dot product off the identity's by more than
/// 1e-3); orthographic needs its x, y and z axes to span the view (finite, non-zero).
pub(super) fn check_sensor_transform(kind: &str, m: &DMat4) -> Result<(), SensorTransformError> {
    let cols = [
        m.x_axis.truncate(),
        m.y_axis.truncate(),
        m.z_axis.truncate(),
    ];
    if kind == "thinlens" {
        let rows = [0, 1, 2].map(|i| DVec3::new(cols[0][i], cols[1][i], cols[2][i]));
        for i in 0..3 {
            for j in i..3 {
                let want = if i == j { 1.0 } else { 0.0 };
                let off = (rows[i].dot(rows[j]) - want).abs();
                if off.is_nan() || off > 1e-3 {
                    return Err(SensorTransformError::ThinlensScale);
                }
            }
        }
    }
    if kind == "orthographic" {
        let ok = cols.iter().all(|c| {
            let l = c.length();
            l.is_finite() && l as f32 >= f32::MIN_POSITIVE && l <= MAX_COORDINATE
        });
        if !ok || m.determinant() == 0.0 {
            return Err(SensorTransformError::OrthographicAxes(
                cols.map(|c| c.to_array()),
            ));
        }
    }
    Ok(())
}

/// An `nlos_capture_meter` nested in shape `index` (`nlos.rs`).
pub(super) fn parse_meter(
    ctx: &Ctx,
    node: Node,
    named_samplers: &HashMap<String, (u32, u64)>,
    named_textures: &NamedTextures,
    index: u32,
    shape: &Shape,
) -> Result<Sensor, SceneError> {
    let mut p = Props::parse(ctx, node)?;
    let (origin, legacy_laser) = super::nlos_setup::parse_meter_params(&mut p)?;
    check_world_point(origin.as_dvec3())
        .map_err(|e| p.err_at("sensor_origin", format!("sensor_origin: {e}")))?;
    let wall = crate::sensors::relay_wall::Wall::of_rectangle(shape)
        .ok_or_else(|| ctx.err(node, "the relay wall is not a rectangle"))?;
    if !(wall.normal.is_finite() && wall.du.length() > 0.0 && wall.dv.length() > 0.0) {
        return Err(ctx.err(
            node,
            "the relay wall's rectangle is degenerate (its to_world collapses it)",
        ));
    }
    let mut film = None;
    let mut laser = None;
    let (mut spp, mut seed) = (4u32, 0u64);
    let mut seen_sampler = false;
    for obj in std::mem::take(&mut p.objects) {
        match obj.tag_name().name() {
            "film" if film.is_some() => return Err(ctx.err(obj, "a sensor has one <film>")),
            "sampler" | "ref" if seen_sampler => {
                return Err(ctx.err(obj, "a sensor has one <sampler>"))
            }
            "film" => film = Some(parse_film_for_meter(ctx, obj)?),
            "sampler" => {
                seen_sampler = true;
                (spp, seed) = parse_sampler(ctx, obj)?;
            }
            "ref" if named_samplers.contains_key(&ctx.required_attr(obj, "id")?) => {
                seen_sampler = true;
                (spp, seed) = named_samplers[&ctx.required_attr(obj, "id")?];
            }
            // mitransient <= 1.1: the laser nested in the meter, the filter beside the film.
            "emitter" if laser.is_some() => {
                return Err(ctx.err(obj, "a capture meter holds at most one (legacy) laser"))
            }
            "emitter" if ctx.attr(obj, "type")?.as_deref() == Some(super::projector::PROJECTOR) => {
                ctx.warn(obj, "a laser nested in nlos_capture_meter (mitransient <= 1.1's layout, which 1.3.1 refuses): it is the scene's emitter");
                laser = Some(super::projector::parse_projector(ctx, obj, named_textures)?);
            }
            "rfilter"
                if ctx
                    .attr(obj, "type")?
                    .is_some_and(|f| super::film::RFILTERS.contains(&f.as_str())) =>
            {
                ctx.warn(obj, "an <rfilter> in nlos_capture_meter (mitransient <= 1.1's layout): the film's box filter");
                Props::parse(ctx, obj)?.finish()?;
            }
            other => {
                return Err(ctx.err(
                    obj,
                    format!("unexpected <{other}> inside <sensor type=\"nlos_capture_meter\"> (it takes a film and a sampler; the laser is a top-level projector)"),
                ))
            }
        }
    }
    p.finish()?;
    let (film, laser_scan) = film.ok_or_else(|| ctx.err(node, "the sensor has no <film>"))?;
    Ok(Sensor {
        line: ctx.line(node),
        kind: "nlos_capture_meter".into(),
        to_world: DMat4::from_translation(origin.as_dvec3()),
        projection: SensorProjection::Meter(super::nlos_setup::CaptureMeter {
            origin,
            shape: index,
            wall,
            laser_scan,
            legacy_laser,
        }),
        near_clip: 0.0,
        film,
        spp,
        seed,
        medium: None,
        laser,
    })
}

/// The camera plugins (the plugin table's `sensor` family, with [`METER`]): all read by
/// [`parse_sensor`].
pub(super) const CAMERAS: &[&str] = &["perspective", "thinlens", "orthographic"];

/// The NLOS capture sensor, nested in the relay wall's shape ([`parse_meter`]).
pub(super) const METER: &str = "nlos_capture_meter";

pub(super) fn parse_sensor(
    ctx: &Ctx,
    node: Node,
    named_samplers: &HashMap<String, (u32, u64)>,
    media: &mut Vec<Medium>,
    named_media: &HashMap<String, u32>,
) -> Result<Sensor, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    if !CAMERAS.contains(&kind.as_str()) {
        return Err(ctx.err(
            node,
            format!("sensor '{kind}' is not supported (use perspective, thinlens or orthographic; an nlos_capture_meter goes inside its relay wall's <shape>)"),
        ));
    }
    let mut p = Props::parse(ctx, node)?;
    // Mitsuba's ProjectiveCamera: near_clip > 0, near_clip < far_clip; focus_distance
    // defaults to far_clip.
    let near = p.float_or("near_clip", 1e-2)?;
    let far = p.float_or("far_clip", 1e4)?;
    if !(near > 0.0 && near <= MAX_COORDINATE) {
        return Err(p.err_at(
            "near_clip",
            format!("near_clip must be in (0, {MAX_COORDINATE:e}], got {near}"),
        ));
    }
    if !(far > near && far.is_finite()) {
        return Err(p.err_at(
            "far_clip",
            format!("far_clip must be finite and greater than near_clip ({near}), got {far}"),
        ));
    }
    let projection = if kind == "orthographic" {
        SensorProjection::Orthographic
    } else {
        let (fov, fov_axis) = parse_fov(&mut p)?;
        if kind == "perspective" {
            // A pinhole has no depth of field: Mitsuba's `perspective` accepts and ignores it.
            p.ignore("focus_distance");
            SensorProjection::Perspective { fov, fov_axis }
        } else {
            let aperture = p
                .float("aperture_radius")?
                .ok_or_else(|| p.err("missing parameter 'aperture_radius' (thinlens)"))?;
            if !(aperture >= 0.0 && aperture as f32 <= MAX_COORDINATE as f32) {
                return Err(p.err_at(
                    "aperture_radius",
                    format!("aperture_radius must be in [0, {MAX_COORDINATE:e}], got {aperture}"),
                ));
            }
            let aperture_radius = if aperture == 0.0 {
                // Mitsuba: "Can't have a zero aperture radius -- setting to 2^-24".
                p.warn_at(
                    "aperture_radius",
                    "a zero aperture radius is set to 2^-24 (as Mitsuba); use perspective for a pinhole",
                );
                f32::EPSILON / 2.0
            } else {
                aperture as f32
            };
            let focus = p.float_or("focus_distance", far)?;
            if !(focus > 0.0 && focus as f32 >= f32::MIN_POSITIVE && focus <= MAX_COORDINATE) {
                return Err(p.err_at(
                    "focus_distance",
                    format!("focus_distance must be in (0, {MAX_COORDINATE:e}], got {focus}"),
                ));
            }
            SensorProjection::ThinLens {
                fov,
                fov_axis,
                aperture_radius,
                focus_distance: focus as f32,
            }
        }
    };
    if kind != "orthographic" {
        for name in ["principal_point_offset_x", "principal_point_offset_y"] {
            if let Some(v) = p.float(name)? {
                if v != 0.0 {
                    return Err(p.err_at(
                        name,
                        format!(
                            "{name} = {v}: an off-centre principal point is not supported (only 0)"
                        ),
                    ));
                }
            }
        }
    }
    let to_world = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
    let mut film = None;
    let (mut spp, mut seed) = (4u32, 0u64);
    let mut seen_sampler = false;
    let mut medium = None;
    for obj in std::mem::take(&mut p.objects) {
        match obj.tag_name().name() {
            // The camera's medium: nested, or a <ref> to a top-level one (Mitsuba's
            // sensor takes any medium among its children).
            "medium" | "ref"
                if obj.has_tag_name("medium")
                    || named_media.contains_key(&ctx.required_attr(obj, "id")?) =>
            {
                if medium.is_some() {
                    return Err(ctx.err(obj, "a sensor has at most one medium"));
                }
                medium = Some(medium_index(ctx, obj, media, named_media)?);
            }
            "film" if film.is_some() => return Err(ctx.err(obj, "a sensor has one <film>")),
            "sampler" if seen_sampler => return Err(ctx.err(obj, "a sensor has one <sampler>")),
            "film" => film = Some(parse_film(ctx, obj)?),
            "sampler" => {
                seen_sampler = true;
                (spp, seed) = parse_sampler(ctx, obj)?;
            }
            // A sampler declared at the top level with an id.
            "ref" if named_samplers.contains_key(&ctx.required_attr(obj, "id")?) => {
                if seen_sampler {
                    return Err(ctx.err(obj, "a sensor has one <sampler>"));
                }
                seen_sampler = true;
                (spp, seed) = named_samplers[&ctx.required_attr(obj, "id")?];
            }
            other => return Err(ctx.err(obj, format!("unexpected <{other}> inside <sensor>"))),
        }
    }
    p.finish()?;
    let film = film.ok_or_else(|| ctx.err(node, "the sensor has no <film>"))?;
    check_world_point(to_world.transform_point3(DVec3::ZERO))
        .map_err(|e| ctx.err(node, format!("camera position: {e}")))?;
    check_sensor_transform(&kind, &to_world).map_err(|e| ctx.err(node, e.to_string()))?;
    Ok(Sensor {
        line: ctx.line(node),
        kind,
        to_world,
        projection,
        near_clip: near,
        film,
        spp,
        seed,
        medium,
        laser: None,
    })
}
