//! The document walk: `<scene>`, `<default>`, top-level plugins, ids and refs.

use super::camera::{Camera, FovAxis};
use super::error::SceneError;
use super::film::Film;
use super::props::{Ctx, Props};
use super::shapes::parse_geometry;
use super::{IntegratorSettings, Overrides, Scene};
use crate::geometry::accel::Accel;
use crate::geometry::shape::{AreaSampler, Shape};
use crate::lights::Emitter;
use crate::materials::parse::{parse_bsdf, resolve_bsdf};
use crate::materials::{Bsdf, Diffuse};
use crate::math::Rgb;
use glam::{DMat4, DVec3};
use roxmltree::Node;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::path::Path;

struct Sensor {
    to_world: DMat4,
    fov: f64,
    fov_axis: FovAxis,
    film: Film,
    spp: u32,
    seed: u64,
}

pub fn load(path: &Path, overrides: &Overrides) -> Result<Scene, SceneError> {
    let whole = |msg: String| SceneError::new(path, 0, "scene", msg);
    let bytes =
        std::fs::read(path).map_err(|e| whole(format!("cannot read the scene file: {e}")))?;
    let sha256 = format!("{:x}", Sha256::digest(&bytes));
    let text = String::from_utf8(bytes).map_err(|_| whole("the scene file is not UTF-8".into()))?;
    let doc = roxmltree::Document::parse(&text).map_err(|e| {
        let pos = e.pos();
        SceneError::new(path, pos.row, "xml", format!("malformed XML: {e}"))
    })?;
    let root = doc.root_element();

    // Defaults: the command line wins over the file.
    let mut defaults: HashMap<String, String> = overrides.defaults.iter().cloned().collect();
    let cli_keys: Vec<String> = defaults.keys().cloned().collect();
    for node in root.children().filter(|n| n.has_tag_name("default")) {
        let empty = HashMap::new();
        let ctx = Ctx {
            file: path,
            text: &text,
            defaults: &empty,
        };
        let name = ctx.required_attr(node, "name")?;
        let value = ctx.required_attr(node, "value")?;
        if !cli_keys.contains(&name) {
            defaults.insert(name, value);
        }
    }
    let ctx = Ctx {
        file: path,
        text: &text,
        defaults: &defaults,
    };
    if root.tag_name().name() != "scene" {
        return Err(ctx.err(root, "the root element must be <scene>"));
    }
    for (key, _) in &overrides.defaults {
        if !root
            .children()
            .any(|n| n.has_tag_name("default") && n.attribute("name") == Some(key))
        {
            return Err(ctx.err(
                root,
                format!("-D {key}=...: the scene has no <default name=\"{key}\">"),
            ));
        }
    }

    let mut named_bsdfs: HashMap<String, Bsdf> = HashMap::new();
    let mut bsdfs: Vec<Bsdf> = Vec::new();
    let mut shapes: Vec<Shape> = Vec::new();
    let mut emitters: Vec<Emitter> = Vec::new();
    let mut sensor: Option<Sensor> = None;
    let mut integrator: Option<IntegratorSettings> = None;

    for node in root.children().filter(|n| n.is_element()) {
        match node.tag_name().name() {
            "default" => {}
            "integrator" => {
                if integrator.is_some() {
                    return Err(ctx.err(node, "a scene has one <integrator>"));
                }
                integrator = Some(parse_integrator(&ctx, node)?);
            }
            "sensor" => {
                if sensor.is_some() {
                    return Err(ctx.err(node, "only one <sensor> is supported"));
                }
                sensor = Some(parse_sensor(&ctx, node)?);
            }
            "bsdf" => {
                let b = parse_bsdf(&ctx, node, &named_bsdfs)?;
                if let Some(id) = ctx.attr(node, "id")? {
                    if named_bsdfs.insert(id.clone(), b).is_some() {
                        return Err(ctx.err(node, format!("id '{id}' is defined twice")));
                    }
                }
            }
            "shape" => {
                let index = shapes.len() as u32;
                let (shape, bsdf, emission) = parse_shape(&ctx, node, index, &named_bsdfs)?;
                let bsdf_index = match bsdfs.iter().position(|b| *b == bsdf) {
                    Some(i) => i,
                    None => {
                        bsdfs.push(bsdf);
                        bsdfs.len() - 1
                    }
                };
                let mut shape = Shape {
                    bsdf: bsdf_index as u32,
                    ..shape
                };
                if let Some(radiance) = emission {
                    shape.emitter = Some(emitters.len() as u32);
                    emitters.push(Emitter::Area {
                        shape: index,
                        radiance,
                        sampler: AreaSampler::new(&shape),
                    });
                }
                shapes.push(shape);
            }
            "emitter" => emitters.push(parse_point_emitter(&ctx, node)?),
            other => {
                return Err(ctx.err(
                    node,
                    format!("<{other}> is not supported (supported at top level: default, integrator, sensor, bsdf, shape, emitter)"),
                ))
            }
        }
    }

    let s = sensor.ok_or_else(|| ctx.err(root, "the scene has no <sensor>"))?;
    let mut integrator = integrator.unwrap_or_default();
    let mut film = s.film;
    match (overrides.width, overrides.height) {
        (Some(w), Some(h)) => (film.width, film.height) = (w, h),
        (Some(w), None) => {
            film.height =
                ((w as f64 * film.height as f64 / film.width as f64).round() as usize).max(1);
            film.width = w;
        }
        (None, Some(h)) => {
            film.width =
                ((h as f64 * film.width as f64 / film.height as f64).round() as usize).max(1);
            film.height = h;
        }
        (None, None) => {}
    }
    if let Some(b) = overrides.bins {
        film.bins = b;
    }
    if let Some(t0) = overrides.start_opl {
        film.start_opl = t0;
    }
    if let Some(h) = overrides.bin_width_opl {
        film.bin_width_opl = h;
    }
    film.validate().map_err(whole)?;
    if let Some(d) = overrides.max_depth {
        integrator.max_depth = d;
    }
    if integrator.max_depth < -1 {
        return Err(whole(format!(
            "max_depth must be -1 (unbounded) or >= 0, got {}",
            integrator.max_depth
        )));
    }
    let spp = overrides.spp.unwrap_or(s.spp);
    crate::stats::estimators::check_spp(spp as u64).map_err(whole)?;
    if emitters.is_empty() {
        return Err(ctx.err(root, "the scene has no emitter; it would render black"));
    }
    let camera = Camera::new(s.to_world, s.fov, s.fov_axis, film.width, film.height);
    let accel = Accel::build(&shapes);
    Ok(Scene {
        file: path.to_path_buf(),
        sha256,
        camera,
        film,
        spp,
        seed: s.seed,
        integrator,
        bsdfs,
        shapes,
        emitters,
        accel,
    })
}

fn parse_integrator(ctx: &Ctx, node: Node) -> Result<IntegratorSettings, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    if kind != "transient_path" && kind != "transient_prbvolpath" {
        return Err(ctx.err(
            node,
            format!("integrator '{kind}' is not supported (use transient_path)"),
        ));
    }
    let mut p = Props::parse(ctx, node)?;
    let d = IntegratorSettings::default();
    let max_depth = p.integer("max_depth")?.unwrap_or(d.max_depth as i64);
    if max_depth < -1 || max_depth > i32::MAX as i64 {
        return Err(p.err_at(
            "max_depth",
            format!("max_depth must be -1 or >= 0, got {max_depth}"),
        ));
    }
    let rr_depth = p.integer("rr_depth")?.unwrap_or(d.rr_depth as i64);
    if rr_depth <= 0 || rr_depth > u32::MAX as i64 {
        return Err(p.err_at(
            "rr_depth",
            format!("rr_depth must be positive, got {rr_depth}"),
        ));
    }
    let s = IntegratorSettings {
        max_depth: max_depth as i32,
        rr_depth: rr_depth as u32,
        hide_emitters: p.boolean_or("hide_emitters", false)?,
        camera_unwarp: p.boolean_or("camera_unwarp", false)?,
    };
    if let Some(&obj) = p.objects.first() {
        return Err(ctx.err(obj, "unexpected nested element in <integrator>"));
    }
    p.finish()?;
    Ok(s)
}

fn parse_sensor(ctx: &Ctx, node: Node) -> Result<Sensor, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    if kind != "perspective" {
        return Err(ctx.err(
            node,
            format!("sensor '{kind}' is not supported (use perspective)"),
        ));
    }
    let mut p = Props::parse(ctx, node)?;
    let fov = p
        .float("fov")?
        .ok_or_else(|| p.err("missing parameter 'fov'"))?;
    if !(fov > 0.0 && fov < 180.0) {
        return Err(p.err_at("fov", format!("fov must be in (0, 180) degrees, got {fov}")));
    }
    let axis_name = p.string("fov_axis")?.unwrap_or_else(|| "x".into());
    let fov_axis = FovAxis::parse(&axis_name).ok_or_else(|| {
        p.err_at(
            "fov_axis",
            format!("fov_axis '{axis_name}' is not one of x, y, smaller, larger, diagonal"),
        )
    })?;
    // Rays start at the pinhole (SPEC 2); the clip planes do not change what is rendered.
    p.ignore("near_clip");
    p.ignore("far_clip");
    let to_world = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
    let mut film = None;
    let (mut spp, mut seed) = (4u32, 0u64);
    for obj in std::mem::take(&mut p.objects) {
        match obj.tag_name().name() {
            "film" => film = Some(Film::parse(ctx, obj)?),
            "sampler" => {
                // The sampler type only decides whether the scene loads: sub-pixel
                // positions are chosen by `--pixel-sampling` (default stratified), and
                // every other dimension of a path is always independent. Mitsuba's
                // stratified-like samplers are accepted as plain requests for spp/seed.
                let k = ctx.required_attr(obj, "type")?;
                const STRATIFIED_LIKE: [&str; 4] =
                    ["stratified", "multijitter", "orthogonal", "ldsampler"];
                if k != "independent" && !STRATIFIED_LIKE.contains(&k.as_str()) {
                    return Err(ctx.err(obj, format!("sampler '{k}' is not supported (use independent; sub-pixel positions are set by --pixel-sampling)")));
                }
                let mut sp = Props::parse(ctx, obj)?;
                if k != "independent" {
                    sp.ignore("jitter");
                    sp.ignore("strength");
                }
                if let Some(n) = sp.integer("sample_count")? {
                    if !(0..=u32::MAX as i64).contains(&n) {
                        return Err(
                            sp.err_at("sample_count", format!("sample_count {n} is out of range"))
                        );
                    }
                    spp = n as u32;
                }
                if let Some(s) = sp.integer("seed")? {
                    seed = s as u64;
                }
                sp.finish()?;
            }
            other => return Err(ctx.err(obj, format!("unexpected <{other}> inside <sensor>"))),
        }
    }
    p.finish()?;
    let film = film.ok_or_else(|| ctx.err(node, "the sensor has no <film>"))?;
    Ok(Sensor {
        to_world,
        fov,
        fov_axis,
        film,
        spp,
        seed,
    })
}

type ParsedShape = (Shape, Bsdf, Option<Rgb>);

fn parse_shape(
    ctx: &Ctx,
    node: Node,
    index: u32,
    named: &HashMap<String, Bsdf>,
) -> Result<ParsedShape, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    let mut p = Props::parse(ctx, node)?;
    let geom = parse_geometry(&kind, &mut p)?;
    let flip_normals = p.boolean_or("flip_normals", false)?;
    let mut bsdf = None;
    let mut emission = None;
    for obj in std::mem::take(&mut p.objects) {
        match obj.tag_name().name() {
            "bsdf" | "ref" => {
                if bsdf.is_some() {
                    return Err(ctx.err(obj, "a shape has at most one BSDF"));
                }
                bsdf = Some(resolve_bsdf(ctx, obj, named)?);
            }
            "emitter" => {
                let k = ctx.required_attr(obj, "type")?;
                if k != "area" {
                    return Err(ctx.err(obj, format!("emitter '{k}' cannot be attached to a shape (use area)")));
                }
                let mut ep = Props::parse(ctx, obj)?;
                let radiance = ep
                    .rgb("radiance")?
                    .ok_or_else(|| ep.err("missing parameter 'radiance'"))?;
                if radiance.min_element() < 0.0 {
                    return Err(ep.err_at("radiance", "radiance must be non-negative"));
                }
                if let Some(&o) = ep.objects.first() {
                    return Err(ctx.err(o, "unexpected nested element in <emitter>"));
                }
                ep.finish()?;
                emission = Some(radiance);
            }
            other => {
                return Err(ctx.err(
                    obj,
                    format!("<{other}> inside <shape> is not supported (media and textures are not implemented)"),
                ))
            }
        }
    }
    p.finish()?;
    let name = ctx
        .attr(node, "id")?
        .unwrap_or_else(|| format!("shape#{index}"));
    let shape = Shape {
        name,
        geom,
        flip_normals,
        bsdf: 0,
        emitter: None,
    };
    let bsdf = bsdf.unwrap_or(Bsdf::Diffuse(Diffuse {
        reflectance: Rgb::splat(0.5),
    }));
    Ok((shape, bsdf, emission))
}

fn parse_point_emitter(ctx: &Ctx, node: Node) -> Result<Emitter, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    if kind != "point" {
        return Err(ctx.err(
            node,
            format!("emitter '{kind}' is not supported at top level (supported: point; area lights go inside a <shape>)"),
        ));
    }
    let mut p = Props::parse(ctx, node)?;
    let intensity = p.rgb("intensity")?.unwrap_or(Rgb::ONE);
    if intensity.min_element() < 0.0 {
        return Err(p.err_at("intensity", "intensity must be non-negative"));
    }
    let position = match (p.point("position")?, p.transform("to_world")?) {
        (Some(_), Some(_)) => return Err(p.err("give either 'position' or 'to_world', not both")),
        (Some(pos), None) => DVec3::from(pos),
        (None, Some(m)) => m.transform_point3(DVec3::ZERO),
        (None, None) => DVec3::ZERO,
    };
    if let Some(&o) = p.objects.first() {
        return Err(ctx.err(o, "unexpected nested element in <emitter>"));
    }
    p.finish()?;
    Ok(Emitter::Point {
        position: position.as_vec3(),
        intensity,
    })
}
