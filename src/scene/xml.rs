//! The document walk: `<scene>`, `<default>`, top-level plugins, ids and refs.

use super::camera::{Camera, FovAxis};
use super::error::SceneError;
use super::film::Film;
use super::limits;
use super::props::{Ctx, Props, OBJECT_TAGS};
use super::shapes::{check_world_point, parse_geometry};
use super::{IntegratorSettings, Overrides, Scene};
use crate::geometry::accel::Accel;
use crate::geometry::shape::{AreaSampler, Shape, ShapeGeom};
use crate::lights::Emitter;
use crate::materials::parse::{parse_bsdf, resolve_bsdf, Named};
use crate::materials::{Bsdf, Diffuse, Material};
use crate::math::Rgb;
use crate::scene::textures::{parse_texture, NamedTextures};
use glam::{DMat4, DVec3, Vec3};
use roxmltree::Node;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::path::Path;

struct Sensor {
    /// Line of the `<sensor>` element, for errors found after the overrides.
    line: u32,
    to_world: DMat4,
    fov: f64,
    fov_axis: FovAxis,
    film: Film,
    spp: u32,
    seed: u64,
}

pub fn load(path: &Path, overrides: &Overrides) -> Result<Scene, SceneError> {
    let whole = |msg: String| SceneError::new(path, 0, "scene", msg);
    let bytes = crate::io::read_regular(path, crate::io::MAX_SCENE_BYTES)
        .map_err(|e| whole(format!("cannot read the scene file: {e}")))?;
    let sha256 = format!("{:x}", Sha256::digest(&bytes));
    let text = String::from_utf8(bytes).map_err(|e| {
        let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = valid.iter().filter(|&&b| b == b'\n').count() + 1;
        SceneError::new(
            path,
            line as u32,
            "scene",
            format!(
                "the scene file is not UTF-8 (byte {} is invalid)",
                valid.len()
            ),
        )
    })?;
    limits::prescan(&text).map_err(|r| {
        let line = text[..r.offset].bytes().filter(|&b| b == b'\n').count() + 1;
        SceneError::new(path, line as u32, "xml", r.message)
    })?;
    let options = roxmltree::ParsingOptions {
        nodes_limit: limits::MAX_NODES,
        ..Default::default()
    };
    let doc = roxmltree::Document::parse_with_options(&text, options).map_err(|e| match e {
        roxmltree::Error::NodesLimitReached => whole(format!(
            "more than {} XML nodes (elements, text, comments): far beyond any real scene",
            limits::MAX_NODES
        )),
        e => SceneError::new(path, e.pos().row, "xml", format!("malformed XML: {e}")),
    })?;
    if let Some(node) = limits::too_deep(&doc) {
        let empty = HashMap::new();
        return Err(Ctx::new(path, &text, &empty).err(
            node,
            format!(
                "elements are nested more than {} deep (no scene needs that)",
                limits::MAX_DEPTH
            ),
        ));
    }
    let root = doc.root_element();

    // Defaults: the command line wins over the file.
    let mut defaults: HashMap<String, String> = overrides.defaults.iter().cloned().collect();
    let cli_keys: Vec<String> = defaults.keys().cloned().collect();
    // Nodes, not line numbers: finding a line scans the text, so only errors do it.
    let mut in_file: HashMap<String, Node> = HashMap::new();
    for node in root.children().filter(|n| n.has_tag_name("default")) {
        let empty = HashMap::new();
        let ctx = Ctx::new(path, &text, &empty);
        let name = ctx.required_attr(node, "name")?;
        let raw = node.attribute("value").unwrap_or_default();
        if raw.contains('$') {
            return Err(ctx.err(
                node,
                format!("the value '{raw}' refers to a default; a <default> value must be literal"),
            ));
        }
        let value = ctx.required_attr(node, "value")?;
        if let Some(first) = in_file.insert(name.clone(), node) {
            let first = ctx.line(first);
            return Err(ctx.err(
                node,
                format!("<default name=\"{name}\"> is given twice (first on line {first})"),
            ));
        }
        if !cli_keys.contains(&name) {
            defaults.insert(name, value);
        }
    }
    let ctx = Ctx::new(path, &text, &defaults);
    if root.tag_name().name() != "scene" {
        return Err(ctx.err(root, "the root element must be <scene>"));
    }
    for (key, _) in &overrides.defaults {
        if !in_file.contains_key(key) {
            return Err(ctx.err(
                root,
                format!("-D {key}=...: the scene has no <default name=\"{key}\">"),
            ));
        }
    }
    check_elements(&ctx, root)?;

    let mut named_bsdfs: HashMap<String, Material> = HashMap::new();
    let mut named_textures: NamedTextures = HashMap::new();
    let mut bsdfs: Vec<Material> = Vec::new();
    let mut bsdf_index: HashMap<String, usize> = HashMap::new();
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
            "texture" => {
                let t = parse_texture(&ctx, node, &named_textures)?;
                let Some(id) = ctx.attr(node, "id")? else {
                    return Err(ctx.err(node, "a top-level <texture> needs an id to be referenced"));
                };
                if named_textures.insert(id.clone(), t).is_some() {
                    return Err(ctx.err(node, format!("id '{id}' is defined twice")));
                }
            }
            "bsdf" => {
                let named = Named {
                    bsdfs: &named_bsdfs,
                    textures: &named_textures,
                };
                let b = parse_bsdf(&ctx, node, &named)?;
                if let Some(id) = ctx.attr(node, "id")? {
                    if named_bsdfs.insert(id.clone(), b).is_some() {
                        return Err(ctx.err(node, format!("id '{id}' is defined twice")));
                    }
                }
            }
            "shape" => {
                let index = shapes.len() as u32;
                let named = Named {
                    bsdfs: &named_bsdfs,
                    textures: &named_textures,
                };
                let (shape, bsdf, emission) = parse_shape(&ctx, node, index, &named)?;
                // Equal untextured BSDFs share an index; found by their exact Debug
                // text, so that many distinct BSDFs do not cost a quadratic search.
                // (Textured ones are not compared: an image's Debug text is its texels.)
                let bsdf_index = if bsdf.is_textured() {
                    bsdfs.push(bsdf);
                    bsdfs.len() - 1
                } else {
                    *bsdf_index.entry(format!("{bsdf:?}")).or_insert_with(|| {
                        bsdfs.push(bsdf);
                        bsdfs.len() - 1
                    })
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
                    format!("<{other}> is not supported (supported at top level: default, integrator, sensor, texture, bsdf, shape, emitter)"),
                ))
            }
        }
    }

    check_extent(&ctx, root, &shapes)?;
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
    let end = film.start_opl + film.bins as f64 * film.bin_width_opl;
    if end <= 0.0 {
        ctx.warn(
            root,
            format!("the time axis ends at OPL {end}, before any light can arrive (path lengths are positive): every bin stays empty"),
        );
    }
    if let Some(d) = overrides.max_depth {
        integrator.max_depth = d;
    }
    if integrator.max_depth == 0 {
        ctx.warn(
            root,
            "max_depth is 0: paths have no segments, so the render is black",
        );
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
    if !camera
        .tan_half
        .iter()
        .all(|&t| t >= f32::MIN_POSITIVE && t.is_finite())
    {
        return Err(SceneError::new(
            path,
            s.line,
            "sensor type=\"perspective\"",
            format!(
                "fov {:e} degrees at {}x{} px gives a field of view that is zero or infinite in single precision",
                s.fov, film.width, film.height
            ),
        ));
    }
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
        warnings: ctx.take_warnings(),
        mesh_files: ctx.take_mesh_files(),
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
    let mut seen_sampler = false;
    for obj in std::mem::take(&mut p.objects) {
        match obj.tag_name().name() {
            "film" if film.is_some() => return Err(ctx.err(obj, "a sensor has one <film>")),
            "sampler" if seen_sampler => return Err(ctx.err(obj, "a sensor has one <sampler>")),
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
                seen_sampler = true;
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
                    seed = u64::try_from(s).map_err(|_| {
                        sp.err_at("seed", format!("seed must be non-negative, got {s}"))
                    })?;
                }
                sp.finish()?;
            }
            other => return Err(ctx.err(obj, format!("unexpected <{other}> inside <sensor>"))),
        }
    }
    p.finish()?;
    let film = film.ok_or_else(|| ctx.err(node, "the sensor has no <film>"))?;
    check_world_point(to_world.transform_point3(DVec3::ZERO))
        .map_err(|e| ctx.err(node, format!("camera position: {e}")))?;
    Ok(Sensor {
        line: ctx.line(node),
        to_world,
        fov,
        fov_axis,
        film,
        spp,
        seed,
    })
}

type ParsedShape = (Shape, Material, Option<Rgb>);

/// The diagonal of the box around all shapes, in world units.
fn extent(shapes: &[Shape]) -> Option<f32> {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for shape in shapes {
        match &shape.geom {
            ShapeGeom::Mesh { positions, .. } => {
                for &p in positions {
                    (lo, hi) = (lo.min(p), hi.max(p));
                }
            }
            ShapeGeom::Sphere(s, _) => {
                lo = lo.min(s.center - Vec3::splat(s.radius));
                hi = hi.max(s.center + Vec3::splat(s.radius));
            }
        }
    }
    (lo.x <= hi.x).then(|| (hi - lo).length())
}

/// Ray origins leave surfaces with an offset of at least `ray_epsilon(0)` (1e-4) scene
/// units, whatever the scene's size: in a scene a few hundred offsets across that
/// offset measurably changes the result (2 mm Cornell box: 1 % brighter), and within
/// ten offsets the render is meaningless (0.02 mm box: half the light is lost).
fn check_extent(ctx: &Ctx, root: Node, shapes: &[Shape]) -> Result<(), SceneError> {
    let Some(size) = extent(shapes) else {
        return Ok(());
    };
    let eps = crate::geometry::accel::ray_epsilon(Vec3::ZERO);
    if size < 10.0 * eps {
        return Err(ctx.err(
            root,
            format!("the shapes span only {size:e} scene units, within ten ray offsets ({eps:e} units): scale the scene up (e.g. use millimetres)"),
        ));
    }
    if size < 1000.0 * eps {
        ctx.warn(
            root,
            format!("the shapes span only {size:e} scene units; ray offsets of {eps:e} units bias scenes this small: scale the scene up (e.g. use millimetres)"),
        );
    }
    Ok(())
}

/// The attributes an element may have (as in Mitsuba, which also rejects others: a
/// misspelt attribute must not be skipped silently). `None`: checked elsewhere
/// (transform steps) or an element that is an error anyway.
fn allowed_attributes(tag: &str) -> Option<&'static [&'static str]> {
    Some(match tag {
        "scene" => &["version"],
        "default" => &["name", "value"],
        "ref" => &["id", "name"],
        "float" | "integer" | "boolean" | "string" | "rgb" | "spectrum" | "color" => {
            &["name", "value"]
        }
        "point" | "vector" => &["name", "value", "x", "y", "z"],
        "transform" => &["name"],
        t if OBJECT_TAGS.contains(&t) => &["type", "id", "name"],
        _ => return None,
    })
}

/// Checks every element's attributes, and that one id names one object in the file
/// (ids name objects for `<ref>`s; Mitsuba has the same rule).
fn check_elements(ctx: &Ctx, root: Node) -> Result<(), SceneError> {
    let mut seen: HashMap<String, Node> = HashMap::new();
    for node in root.descendants().filter(|n| n.is_element()) {
        let tag = node.tag_name().name();
        if let Some(allowed) = allowed_attributes(tag) {
            if let Some(a) = node
                .attributes()
                .find(|a| a.namespace().is_none() && !allowed.contains(&a.name()))
            {
                return Err(ctx.err(
                    node,
                    format!(
                        "unknown attribute '{}' (<{tag}> takes {})",
                        a.name(),
                        allowed.join(", ")
                    ),
                ));
            }
        }
        if tag == "ref" || !OBJECT_TAGS.contains(&tag) {
            continue;
        }
        if let Some(id) = ctx.attr(node, "id")? {
            if let Some(first) = seen.insert(id.clone(), node) {
                let first = ctx.line(first);
                return Err(ctx.err(node, format!("id '{id}' is already used on line {first}")));
            }
        }
    }
    Ok(())
}

fn parse_shape(
    ctx: &Ctx,
    node: Node,
    index: u32,
    named: &Named,
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
            "emitter" if emission.is_some() => {
                return Err(ctx.err(obj, "a shape has at most one emitter"));
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
                if radiance.max_element() == 0.0 {
                    ctx.warn(
                        obj,
                        "radiance is zero (in single precision): this emitter contributes nothing",
                    );
                }
                if let Some(&o) = ep.objects.first() {
                    return Err(ctx.err(o, "unexpected nested element in <emitter>"));
                }
                ep.finish()?;
                emission = Some((radiance, obj));
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
    // Areas are summed from single-precision triangles, as the light sampler does.
    let area = shape.area() as f32;
    match emission {
        Some((_, obj)) if !(area > 0.0 && area.is_finite()) => {
            return Err(ctx.err(
                obj,
                format!("the emitting shape's area is {area} (in single precision): it cannot be sampled as a light"),
            ))
        }
        None if area == 0.0 => ctx.warn(node, "the shape has zero area: it is invisible"),
        _ => {}
    }
    let bsdf = bsdf.unwrap_or(Material::plain(Bsdf::Diffuse(Diffuse {
        reflectance: Rgb::splat(0.5),
    })));
    Ok((shape, bsdf, emission.map(|(radiance, _)| radiance)))
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
    if intensity.max_element() == 0.0 {
        ctx.warn(
            node,
            "intensity is zero (in single precision): this emitter contributes nothing",
        );
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
    check_world_point(position).map_err(|e| ctx.err(node, format!("position: {e}")))?;
    Ok(Emitter::Point {
        position: position.as_vec3(),
        intensity,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small valid scene; `{shape}` is replaced by the test's shapes and emitters,
    /// `{sensor}` by extra sensor content.
    const BASE: &str = r#"<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
        <film type="transient_hdr_film">
            <integer name="width" value="8"/><integer name="height" value="8"/>
            <integer name="temporal_bins" value="4"/>
            <float name="bin_width_opl" value="1"/>
        </film>
    </sensor>
    SHAPES
</scene>"#;
    const LIGHT: &str = r#"<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#;

    fn load_text(xml: &str) -> Result<Scene, SceneError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.xml");
        std::fs::write(&path, xml).unwrap();
        load(&path, &Overrides::default())
    }

    fn with(shapes: &str) -> String {
        BASE.replace("SHAPES", shapes)
    }

    /// The error message of a scene that must fail, checked to be one line.
    fn fails(xml: &str) -> String {
        let e = load_text(xml)
            .err()
            .expect("the scene should fail")
            .to_string();
        assert!(!e.contains('\n'), "{e}");
        e
    }

    fn warnings(xml: &str) -> Vec<String> {
        load_text(xml).unwrap().warnings
    }

    #[test]
    fn a_valid_scene_loads_without_warnings() {
        assert!(warnings(&with(LIGHT)).is_empty());
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        for name in [
            "cbox.xml",
            "cbox_confocal.xml",
            "cbox_spheres.xml",
            "bunny.xml",
        ] {
            let s = load(&root.join(name), &Overrides::default()).unwrap();
            assert!(s.warnings.is_empty(), "{name}: {:?}", s.warnings);
        }
    }

    #[test]
    fn anisotropy_is_flagged_through_every_wrapper_and_textures_set_each_axis() {
        use crate::materials::Bsdf;
        let aniso = r#"<bsdf type="roughconductor"><float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.3"/></bsdf>"#;
        let iso = r#"<bsdf type="roughconductor"><float name="alpha_u" value="0.2"/><float name="alpha_v" value="0.2"/></bsdf>"#;
        let tp = r#"<TemporalProfile type="ConstantTP" name="tp"><float name="delay" value="1"/></TemporalProfile>"#;
        let cases = [
            (aniso.to_string(), true),
            (iso.to_string(), false),
            (r#"<bsdf type="roughdielectric"><float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.3"/></bsdf>"#.to_string(), true),
            (r#"<bsdf type="roughconductor"><float name="alpha" value="0.3"/></bsdf>"#.to_string(), false),
            (r#"<bsdf type="roughplastic"><float name="alpha" value="0.3"/></bsdf>"#.to_string(), false),
            (format!(r#"<bsdf type="twosided"><bsdf type="diffuse"/>{aniso}</bsdf>"#), true),
            (format!(r#"<bsdf type="twosided">{iso}</bsdf>"#), false),
            (format!(r#"<bsdf type="mask"><float name="opacity" value="0.7"/>{aniso}</bsdf>"#), true),
            (format!(r#"<bsdf type="Separable">{aniso}{tp}</bsdf>"#), true),
            (format!(r#"<bsdf type="Composed"><bsdf type="diffuse"/><bsdf type="mask"><bsdf type="twosided">{aniso}</bsdf></bsdf></bsdf>"#), true),
            (format!(r#"<bsdf type="Composed"><bsdf type="diffuse"/>{iso}</bsdf>"#), false),
            // Textured axes: anisotropic wherever they may differ.
            (r#"<bsdf type="roughconductor"><texture type="checkerboard" name="alpha_u"/><float name="alpha_v" value="0.1"/></bsdf>"#.to_string(), true),
            (r#"<bsdf type="twosided"><bsdf type="roughconductor"><float name="alpha_u" value="0.1"/><texture type="checkerboard" name="alpha_v"/></bsdf></bsdf>"#.to_string(), true),
            (r#"<bsdf type="roughconductor"><texture type="checkerboard" name="alpha"/></bsdf>"#.to_string(), false),
        ];
        for (bsdf, want) in cases {
            let scene = load_text(&with(&format!(
                r#"{LIGHT}<shape type="sphere">{bsdf}</shape>"#
            )))
            .unwrap_or_else(|e| panic!("{bsdf}: {e}"));
            let m = &scene.bsdfs[scene.shapes[1].bsdf as usize];
            assert_eq!(m.is_anisotropic(), want, "{bsdf}");
        }
        // A textured alpha_u sets alpha_u only (checkerboard eval_1 at (0.25, 0.25):
        // color1's 0.2), a textured alpha_v alpha_v only.
        for (params, want) in [
            (
                r#"<texture type="checkerboard" name="alpha_u"/><float name="alpha_v" value="0.7"/>"#,
                (0.2, 0.7),
            ),
            (
                r#"<float name="alpha_u" value="0.7"/><texture type="checkerboard" name="alpha_v"/>"#,
                (0.7, 0.2),
            ),
        ] {
            let scene = load_text(&with(&format!(
                r#"{LIGHT}<shape type="sphere"><bsdf type="roughdielectric"><string name="distribution" value="ggx"/>{params}</bsdf></shape>"#
            )))
            .unwrap();
            let m = &scene.bsdfs[scene.shapes[1].bsdf as usize];
            let Bsdf::RoughDielectric(d) = m.at(glam::Vec2::new(0.25, 0.25)) else {
                panic!()
            };
            let (u, v) = (d.distribution.alpha_u, d.distribution.alpha_v);
            assert!(
                (u - want.0).abs() < 1e-6 && (v - want.1).abs() < 1e-6,
                "{u} {v}"
            );
        }
    }

    #[test]
    fn deep_nesting_is_an_error_not_a_stack_overflow() {
        let n = 100_000;
        let deep = format!(
            "<shape type=\"rectangle\">{}<bsdf type=\"diffuse\"/>{}<emitter type=\"area\"><rgb name=\"radiance\" value=\"1\"/></emitter></shape>",
            "<bsdf type=\"twosided\">".repeat(n),
            "</bsdf>".repeat(n)
        );
        let e = fails(&with(&deep));
        assert!(e.contains("nested more than 64"), "{e}");
        assert!(e.contains("s.xml:11: <bsdf type=\"twosided\">"), "{e}");
    }

    #[test]
    fn only_regular_files_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let mut paths = vec![dir.path().to_path_buf(), "/dev/zero".into()];
        #[cfg(unix)]
        {
            let link = dir.path().join("zero.xml");
            std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
            paths.push(link);
        }
        for p in paths {
            let e = load(&p, &Overrides::default()).err().unwrap().to_string();
            assert!(e.contains("cannot read the scene file: is "), "{e}");
        }
    }

    #[test]
    fn attribute_and_node_floods_are_refused_before_parsing() {
        let attrs: String = (0..10_000).map(|k| format!(" a{k}=\"1\"")).collect();
        let e = fails(&with(&format!("<shape{attrs}/>")));
        assert!(
            e.contains("s.xml:11: <xml>: an element with 10000 attributes"),
            "{e}"
        );
    }

    #[test]
    fn numbers_beyond_single_precision_are_errors_naming_the_parameter() {
        let sphere = |p: &str| with(&format!("{LIGHT}<shape type=\"sphere\">{p}</shape>"));
        for (xml, want) in [
            (
                sphere(r#"<float name="radius" value="1e39"/>"#),
                r#"<float name="radius">: '1e39' overflows"#,
            ),
            (
                sphere(r#"<float name="radius" value="inf"/>"#),
                r#"<float name="radius">: 'inf' is not a finite"#,
            ),
            (
                sphere(r#"<float name="radius" value="NaN"/>"#),
                r#"<float name="radius">: 'NaN' is not a finite"#,
            ),
            (
                sphere(r#"<point name="center" x="1e39"/>"#),
                r#"<point name="center">: attribute 'x': '1e39' overflows"#,
            ),
            (
                sphere(r#"<point name="center" value="0 0 -1e39"/>"#),
                r#"<point name="center">: '-1e39' overflows"#,
            ),
            (
                sphere(r#"<bsdf type="dielectric"><float name="int_ior" value="1e39"/></bsdf>"#),
                r#"<float name="int_ior">: '1e39' overflows"#,
            ),
            (
                sphere(r#"<transform name="to_world"><scale value="1e39"/></transform>"#),
                r#"<scale>: attribute 'value': '1e39' overflows"#,
            ),
            (
                with(&LIGHT.replace("value=\"1\"", "value=\"1, 1e39, 1\"")),
                r#"<rgb name="radiance">: '1e39' overflows"#,
            ),
            (
                with(LIGHT).replace(r#"value="40""#, r#"value="1e39""#),
                r#"<float name="fov">: '1e39' overflows"#,
            ),
        ] {
            let e = fails(&xml);
            assert!(e.contains(want), "want {want} in: {e}");
        }
    }

    #[test]
    fn products_that_overflow_single_precision_are_errors() {
        // Each number fits, the world-space result does not.
        let e = fails(&with(&format!(
            "{LIGHT}<shape type=\"sphere\"><float name=\"radius\" value=\"1e30\"/><transform name=\"to_world\"><scale value=\"1e30\"/></transform></shape>"
        )));
        assert!(
            e.contains("<float name=\"radius\">: the world-space radius"),
            "{e}"
        );
        let e = fails(&with(&format!(
            "{LIGHT}<shape type=\"sphere\"><float name=\"radius\" value=\"1e-30\"/><transform name=\"to_world\"><scale value=\"1e-30\"/></transform></shape>"
        )));
        assert!(e.contains("the world-space radius"), "{e}");
        let e = fails(&with(&format!(
            "{LIGHT}<shape type=\"cube\"><transform name=\"to_world\"><scale value=\"1e20\"/></transform></shape>"
        )));
        assert!(
            e.contains("<transform name=\"to_world\">: vertex 0: world-space point"),
            "{e}"
        );
        let e = fails(&with(&format!(
            "{LIGHT}<emitter type=\"point\"><point name=\"position\" x=\"1e30\"/></emitter>"
        )));
        assert!(
            e.contains("<emitter type=\"point\">: position: world-space point"),
            "{e}"
        );
        let e = fails(&with(LIGHT).replace("origin=\"0,0,4\"", "origin=\"0,0,1e20\""));
        assert!(
            e.contains("<sensor type=\"perspective\">: camera position"),
            "{e}"
        );
        let e = fails(&with(LIGHT).replace(r#"value="40""#, r#"value="1e-40""#));
        assert!(e.contains("field of view that is zero"), "{e}");
        for (ior, want) in [
            (
                r#"<float name="int_ior" value="1e7"/>"#,
                "int_ior must be positive and at most",
            ),
            (
                r#"<float name="int_ior" value="1e-5"/><float name="ext_ior" value="100"/>"#,
                "relative IOR",
            ),
        ] {
            let e = fails(&with(&format!(
                "{LIGHT}<shape type=\"sphere\"><bsdf type=\"dielectric\">{ior}</bsdf></shape>"
            )));
            assert!(e.contains(want), "{e}");
        }
        let e = fails(&with(&format!(
            "{LIGHT}<shape type=\"sphere\"><bsdf type=\"conductor\"><rgb name=\"eta\" value=\"1e30\"/><rgb name=\"k\" value=\"1\"/></bsdf></shape>"
        )));
        assert!(e.contains("<rgb name=\"eta\">: conductor eta"), "{e}");
    }

    #[test]
    fn emitters_that_contribute_nothing_warn_once_each() {
        for radiance in ["0", "1e-300", "0, 0, 1e-46"] {
            let w = warnings(&with(&format!(
                "{LIGHT}<shape type=\"sphere\"><emitter type=\"area\"><rgb name=\"radiance\" value=\"{radiance}\"/></emitter></shape>"
            )));
            assert_eq!(w.len(), 1, "{w:?}");
            assert!(
                w[0].contains("s.xml:11: <emitter type=\"area\">: radiance is zero"),
                "{w:?}"
            );
        }
        let w = warnings(&with(&format!(
            "{LIGHT}<emitter type=\"point\"><rgb name=\"intensity\" value=\"0\"/></emitter>"
        )));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("<emitter type=\"point\">: intensity is zero"),
            "{w:?}"
        );
    }

    #[test]
    fn shapes_without_area_warn_and_emitters_without_area_fail() {
        let flat = r#"<transform name="to_world"><scale value="1e-30"/></transform>"#;
        let e = fails(&with(&format!(
            "<shape type=\"rectangle\">{flat}<emitter type=\"area\"><rgb name=\"radiance\" value=\"1\"/></emitter></shape>"
        )));
        assert!(
            e.contains("<emitter type=\"area\">: the emitting shape's area is 0"),
            "{e}"
        );
        let w = warnings(&with(&format!(
            "{LIGHT}<shape type=\"cube\">{flat}</shape>"
        )));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("<shape type=\"cube\">: the shape has zero area"),
            "{w:?}"
        );
    }

    #[test]
    fn scenes_too_large_or_small_for_single_precision_are_refused_or_warned() {
        // Every coordinate within 1e15, but edges of 2e10 overflow |e1 x e2|^2 in f32.
        let e = fails(&with(&format!(
            "{LIGHT}<shape type=\"cube\"><transform name=\"to_world\"><scale value=\"1e10\"/></transform></shape>"
        )));
        assert!(
            e.contains("<transform name=\"to_world\">: triangle 0 is too large"),
            "{e}"
        );
        // Scenes within a few ray offsets: an error, within a thousand: a warning.
        let tiny = |s: &str| {
            with(&format!(
                "<shape type=\"rectangle\"><transform name=\"to_world\"><scale value=\"{s}\"/></transform><emitter type=\"area\"><rgb name=\"radiance\" value=\"1\"/></emitter></shape>"
            ))
        };
        let e = fails(&tiny("1e-5"));
        assert!(e.contains("s.xml:1: <scene>: the shapes span only"), "{e}");
        let w = warnings(&tiny("1e-3"));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("ray offsets"), "{w:?}");
        assert!(warnings(&tiny("0.1")).is_empty());
    }

    #[test]
    fn default_substitution_cannot_blow_up_a_small_file() {
        let big = "x".repeat(100_000);
        let refs = "$a".repeat(20);
        let head = format!("<scene version=\"3.0.0\"><default name=\"a\" value=\"{big}\"/>");
        let e = fails(
            &with(&LIGHT.replace("<shape ", &format!("<shape id=\"{refs}\" ")))
                .replace("<scene version=\"3.0.0\">", &head),
        );
        assert!(e.contains("longer than 1048576 bytes"), "{e}");
        // Each attribute within the limit, the document as a whole not.
        let ids: String = (0..700)
            .map(|k| format!("<bsdf type=\"diffuse\" id=\"$a-{k}\"/>"))
            .collect();
        let e = fails(&with(&format!("{LIGHT}{ids}")).replace("<scene version=\"3.0.0\">", &head));
        assert!(e.contains("substitutions add more than"), "{e}");
    }

    #[test]
    fn invalid_utf8_names_its_line() {
        let mut bytes = with(LIGHT).into_bytes();
        let at = bytes.windows(6).position(|w| w == b"<shape").unwrap();
        bytes.insert(at, 0xff);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.xml");
        std::fs::write(&path, bytes).unwrap();
        let e = load(&path, &Overrides::default())
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("s.xml:11: <scene>: the scene file is not UTF-8"),
            "{e}"
        );
    }

    #[test]
    fn warnings_beyond_ten_are_counted() {
        let silent = "<shape type=\"cube\"><emitter type=\"area\"><rgb name=\"radiance\" value=\"0\"/></emitter></shape>";
        let w = warnings(&with(&format!("{LIGHT}{}", silent.repeat(25))));
        assert_eq!(w.len(), 11, "{w:?}");
        assert!(w[9].contains("radiance is zero"), "{w:?}");
        assert!(
            w[10].ends_with("s.xml: 15 more warnings not shown"),
            "{w:?}"
        );
    }

    #[test]
    fn suspicious_settings_warn() {
        let w = warnings(&with(&format!(
            "{LIGHT}<shape type=\"cube\"><bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0.5, 1.5, 0.5\"/></bsdf></shape>"
        )));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("<rgb name=\"reflectance\">: reflectance") && w[0].contains("exceeds 1"),
            "{w:?}"
        );
        let w = warnings(&with(&format!(
            "{LIGHT}<integrator type=\"transient_path\"><integer name=\"max_depth\" value=\"0\"/></integrator>"
        )));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("max_depth is 0"), "{w:?}");
        let w = warnings(&with(LIGHT).replace(
            "<float name=\"bin_width_opl\" value=\"1\"/>",
            "<float name=\"bin_width_opl\" value=\"1\"/><float name=\"start_opl\" value=\"-4\"/>",
        ));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("the time axis ends at OPL 0"), "{w:?}");
    }

    #[test]
    fn ambiguous_documents_are_errors() {
        let xml = with(LIGHT);
        for (xml, want) in [
            (
                xml.replace("<scene version=\"3.0.0\">", "<scene><default name=\"a\" value=\"1\"/><default name=\"a\" value=\"2\"/>"),
                "<default name=\"a\">: <default name=\"a\"> is given twice",
            ),
            (
                xml.replace("<scene version=\"3.0.0\">", "<scene><default name=\"a\" value=\"$a\"/>"),
                "a <default> value must be literal",
            ),
            (
                with(&format!("<bsdf type=\"diffuse\" id=\"x\"/><shape type=\"cube\" id=\"x\"/>{LIGHT}")),
                "<shape type=\"cube\">: id 'x' is already used on line 11",
            ),
            (
                xml.replace("</film>", "</film><film type=\"transient_hdr_film\"/>"),
                "a sensor has one <film>",
            ),
            (
                xml.replace("</film>", "</film><sampler type=\"independent\"/><sampler type=\"independent\"/>"),
                "a sensor has one <sampler>",
            ),
            (
                with(&LIGHT.replace("</emitter>", "</emitter><emitter type=\"area\"><rgb name=\"radiance\" value=\"2\"/></emitter>")),
                "a shape has at most one emitter",
            ),
            (
                with(&LIGHT.replace("<rgb name=\"radiance\"", "<rgb name=\"radiance\" vlaue=\"3\"")),
                "<rgb name=\"radiance\">: unknown attribute 'vlaue'",
            ),
            (
                with(&LIGHT.replace("<shape type=\"rectangle\"", "<shape type=\"rectangle\" flip=\"true\"")),
                "unknown attribute 'flip'",
            ),
            (
                xml.replace("</film>", "</film><sampler type=\"independent\"><integer name=\"seed\" value=\"-1\"/></sampler>"),
                "seed must be non-negative",
            ),
            (
                xml.replace("name=\"temporal_bins\" value=\"4\"", "name=\"temporal_bins\" value=\"5000000000\""),
                "temporal_bins 5000000000 is above",
            ),
            (
                xml.replace("name=\"width\" value=\"8\"", "name=\"width\" value=\"4000000000000\"").replace("name=\"height\" value=\"8\"", "name=\"height\" value=\"4000000000000\""),
                "too large to address",
            ),
            (
                with(&format!("{LIGHT}<shape type=\"obj\"><string name=\"filename\" value=\"\"/></shape>")),
                "<string name=\"filename\">: the filename is empty",
            ),
        ] {
            let e = fails(&xml);
            assert!(e.contains(want), "want {want} in: {e}");
        }
    }
}
