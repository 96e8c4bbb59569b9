//! The document walk: `<scene>`, `<default>`, top-level plugins, ids and refs.

use super::bsdfs::{parse_bsdf, Named};
use super::ctx::Ctx;
use super::emitters::{parse_area_emission, parse_point_emitter, AreaEmission, AREA_KINDS};
use super::error::SceneError;
use super::infinite_emitters;
use super::integrator::parse_integrator;
use super::limits;
use super::media::parse_medium;
use super::mode::EmitterSpectrum;
use super::plugins::canonical_plugin_name;
use super::props::{Props, OBJECT_TAGS};
use super::sampler::parse_sampler;
use super::sensors::{parse_meter, parse_sensor, Sensor, SensorProjection};
use super::shape_element::parse_shape;
use super::{IntegratorSettings, Overrides, Scene, SceneIdentity};
use crate::geometry::accel::Accel;
use crate::geometry::shape::{AreaSampler, Shape};
use crate::lights::scene_sphere::SceneSphere;
use crate::lights::Emitter;
use crate::materials::{Bsdf, Material};
use crate::media::Medium;
use crate::scene::textures::{parse_texture, NamedTextures};
use crate::sensors::camera::Camera;
use crate::sensors::film::Film;
use crate::sensors::time_origin::TimeOrigin;
use crate::spectral::curve::Curve;
use glam::{DMat4, Vec3};
use roxmltree::Node;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::path::Path;

/// Loads the scene file at `path` with the command line's `overrides`, in named steps:
/// read and parse ([`read_text`], [`parse`]), the parameters ([`scene_defaults`],
/// [`check_overrides_are_used`]), the walk over the document (`walk`), the checks of
/// what it built, the film ([`resized_film`]), the camera ([`camera_of`]), the BVH
/// and the NLOS set-up.
pub fn load(path: &Path, overrides: &Overrides) -> Result<Scene, SceneError> {
    let whole = |msg: String| SceneError::new(path, 0, "scene", msg);
    let (text, sha256) = read_text(path)?;
    let doc = parse(path, &text)?;
    let root = doc.root_element();

    let (defaults, in_file) = scene_defaults(path, &text, root, overrides)?;
    let ctx = Ctx::new(path, &text, &defaults)
        .with_plugin_names(canonical_plugin_name)
        .with_search_paths(&overrides.search_paths)
        .with_mode(overrides.mode);
    if root.tag_name().name() != "scene" {
        return Err(ctx.err(root, "the root element must be <scene>"));
    }
    check_overrides_are_used(&ctx, root, &text, overrides, &in_file)?;
    check_elements(&ctx, root)?;

    let mut objects = Objects::default();
    walk(&ctx, root, &mut objects, 0)?;
    let Objects {
        bsdfs,
        shapes,
        mut emitters,
        emitter_spectra,
        sensor,
        integrator,
        media,
        first_medium,
        ..
    } = objects;
    // Infinitely distant emitters learn the scene's bounding sphere (Mitsuba's set_scene).
    let environment = emitters
        .iter()
        .position(|e| e.is_environment())
        .map(|i| i as u32);
    if emitters.iter().any(|e| e.is_infinite()) {
        let sphere = SceneSphere::of_shapes(&shapes);
        for e in &mut emitters {
            e.set_scene_sphere(sphere);
        }
    }

    check_extent(&ctx, root, &shapes)?;
    let s = sensor.ok_or_else(|| ctx.err(root, "the scene has no <sensor>"))?;
    let mut integrator = integrator.unwrap_or_default();
    let meter = match &s.projection {
        SensorProjection::Meter(m) => Some(m.clone()),
        _ => None,
    };
    if integrator.nlos.is_some() {
        if !media.is_empty() {
            return Err(ctx.err(root, "transient_nlos_path traces surfaces only (as mitransient 1.3.1's): the scene has participating media"));
        }
        if let Some(i) = bsdfs.iter().position(|m| m.bsdf.delays()) {
            return Err(ctx.err(
                root,
                format!("transient_nlos_path does not model delays (SPEC 6); material #{i} delays"),
            ));
        }
    }
    if let Some(m) = &meter {
        if let Some(to_world) = m
            .legacy_laser
            .and_then(|l| l.to_world(&m.wall, s.film.width, s.film.height))
        {
            let [laser] = emitters.as_mut_slice() else {
                return Err(ctx.err(root, format!("the capture meter's legacy laser_origin places the scene's one projector; the scene has {} emitters", emitters.len())));
            };
            if !laser.set_projector_frame(to_world) {
                return Err(ctx.err(root, "the capture meter's legacy laser_origin places a projector; the scene's emitter is not one"));
            }
        }
    }
    // Mitsuba's `path` integrator ignores media; a scene that has them means the
    // volumetric integrator, so rendering it without would be silently wrong.
    if let (Some(e), false) = (first_medium, integrator.volumetric) {
        return Err(e);
    }
    if integrator.volumetric {
        check_volumetric_materials(&ctx, root, &bsdfs)?;
    }
    let mut film = resized_film(&s.film, overrides);
    film.validate().map_err(|e| whole(e.to_string()))?;
    let end = film.time.start_opl + film.time.bins as f64 * film.time.bin_width_opl;
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
    crate::stats::estimators::check_spp(spp as u64).map_err(|e| whole(e.to_string()))?;
    if emitters.is_empty() {
        return Err(ctx.err(root, "the scene has no emitter; it would render black"));
    }
    // An exhaustive capture stacks one sensor image per laser point (`nlos.rs`). With
    // equal grids (the default) a film resized on the command line resizes both.
    let grid = [film.width, film.height];
    let mut meter = meter;
    if let (Some(m), Some(n)) = (meter.as_mut(), integrator.nlos.as_ref()) {
        let resized = [s.film.width, s.film.height] != grid;
        if resized && n.force_equal_grids && m.laser_scan == Some([s.film.width, s.film.height]) {
            m.laser_scan = Some(grid);
        }
    }
    if let Some([lw, lh]) = meter.as_ref().and_then(|m| m.laser_scan) {
        if integrator.nlos.as_ref().map(|n| n.capture)
            == Some(super::nlos_setup::CaptureType::Exhaustive)
        {
            film.height = lh
                .checked_mul(lw)
                .and_then(|l| l.checked_mul(film.height))
                .ok_or_else(|| {
                    whole("the exhaustive scan's film is too large to address".into())
                })?;
            film.validate().map_err(|e| whole(e.to_string()))?;
        }
    }
    let camera = camera_of(path, &s, &film, grid, overrides)?;
    let accel = Accel::build(&shapes);
    let nlos = match &integrator.nlos {
        Some(settings) => {
            let mut warnings = Vec::new();
            let setup = super::nlos_setup::prepare(
                settings,
                meter,
                grid,
                &shapes,
                &emitters,
                &accel,
                &mut |w| warnings.push(w),
            )
            .map_err(|e| e.to_string())
            .map_err(|e| SceneError::new(path, s.line, format!("sensor type=\"{}\"", s.kind), e))?;
            for w in warnings {
                ctx.warn(root, w);
            }
            Some(setup)
        }
        None => None,
    };
    let mesh_files = ctx.take_mesh_files();
    let mut scene = Scene {
        file: path.to_path_buf(),
        sha256,
        camera,
        film,
        spp,
        seed: s.seed,
        integrator,
        mode: super::mode::RenderMode::Rgb,
        bsdfs,
        shapes,
        emitter_spectra: emitter_spectra
            .into_iter()
            .map(|c| c.map(EmitterSpectrum::new))
            .collect(),
        emitters,
        environment,
        media,
        camera_medium: s.medium,
        nlos,
        accel,
        warnings: ctx.take_warnings(),
        identity: identity(&mesh_files, overrides).map_err(|(f, e)| {
            SceneError::new(
                path,
                0,
                "scene",
                format!("cannot read '{}' again to fingerprint it: {e}", f.display()),
            )
        })?,
        mesh_files,
    };
    scene
        .set_mode(overrides.mode)
        .map_err(|e| SceneError::new(path, 0, "scene", e))?;
    Ok(scene)
}

/// The scene file's text (UTF-8, within the size limit) and its SHA-256.
fn read_text(path: &Path) -> Result<(String, String), SceneError> {
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
    Ok((text, sha256))
}

/// The parsed document, after the pre-scan's limits and within the node and depth
/// limits (`limits.rs`).
fn parse<'t>(path: &Path, text: &'t str) -> Result<roxmltree::Document<'t>, SceneError> {
    let whole = |msg: String| SceneError::new(path, 0, "scene", msg);
    limits::prescan(text).map_err(|r| {
        let line = text[..r.offset].bytes().filter(|&b| b == b'\n').count() + 1;
        SceneError::new(path, line as u32, "xml", r.message)
    })?;
    let options = roxmltree::ParsingOptions {
        nodes_limit: limits::MAX_NODES,
        ..Default::default()
    };
    let doc = roxmltree::Document::parse_with_options(text, options).map_err(|e| match e {
        roxmltree::Error::NodesLimitReached => whole(format!(
            "more than {} XML nodes (elements, text, comments): far beyond any real scene",
            limits::MAX_NODES
        )),
        e => SceneError::new(path, e.pos().row, "xml", malformed(&e)),
    })?;
    if let Some(node) = limits::too_deep(&doc) {
        let empty = HashMap::new();
        return Err(Ctx::new(path, text, &empty).err(
            node,
            format!(
                "elements are nested more than {} deep (no scene needs that)",
                limits::MAX_DEPTH
            ),
        ));
    }
    Ok(doc)
}

/// The scene's parameters: the command line's `-D`, the file's `<default>`s (each
/// literal, given once) and its included files' (which never override either); and
/// the file's own `<default>` nodes by name.
#[allow(clippy::type_complexity)]
fn scene_defaults<'a, 'i>(
    path: &Path,
    text: &str,
    root: Node<'a, 'i>,
    overrides: &Overrides,
) -> Result<(HashMap<String, String>, HashMap<String, Node<'a, 'i>>), SceneError> {
    // Defaults: the command line wins over the file.
    let mut defaults: HashMap<String, String> = overrides.defaults.iter().cloned().collect();
    let cli_keys: Vec<String> = defaults.keys().cloned().collect();
    // Nodes, not line numbers: finding a line scans the text, so only errors do it.
    let mut in_file: HashMap<String, Node> = HashMap::new();
    for node in root.children().filter(|n| n.has_tag_name("default")) {
        let empty = HashMap::new();
        let ctx = Ctx::new(path, text, &empty).with_plugin_names(canonical_plugin_name);
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
    // Mitsuba adds an included file's <default>s to the scene's parameters, so they
    // hold after the <include> too (mitsuba-data's media tests declare `res` and
    // `spp` in include/preamble.xml): the command line and the file's own win.
    let mut from_includes = Vec::new();
    {
        let ctx = Ctx::new(path, text, &defaults)
            .with_plugin_names(canonical_plugin_name)
            .with_search_paths(&overrides.search_paths);
        included_defaults(&ctx, root, 0, &mut 0, &mut from_includes);
    }
    for (name, value) in from_includes {
        defaults.entry(name).or_insert(value);
    }
    Ok((defaults, in_file))
}

/// Refuses a `-D` name the scene never mentions (a typo), unless an include could.
fn check_overrides_are_used(
    ctx: &Ctx,
    root: Node,
    text: &str,
    overrides: &Overrides,
    in_file: &HashMap<String, Node>,
) -> Result<(), SceneError> {
    // As Mitsuba's scene parameters: -D sets a <default>, or any `$name` the file uses
    // without one (public scenes leave e.g. `$spp` to the caller). A name the file never
    // mentions (and has no include that could) is a typo.
    for (key, _) in &overrides.defaults {
        let may_include = root.children().any(|n| n.has_tag_name("include"));
        if !in_file.contains_key(key) && !mentions(text, key) && !may_include {
            return Err(ctx.err(
                root,
                format!(
                    "-D {key}=...: the scene has no <default name=\"{key}\"> and never uses ${key}"
                ),
            ));
        }
    }
    Ok(())
}

/// The sensor's film with the command line's size and time axis (`-W`/`-H` keep the
/// aspect ratio when only one is given); validated by the caller.
fn resized_film(film: &Film, overrides: &Overrides) -> Film {
    let mut film = film.clone();
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
        film.time.bins = b;
    }
    if let Some(t0) = overrides.start_opl {
        film.time.start_opl = t0;
    }
    if let Some(h) = overrides.bin_width_opl {
        film.time.bin_width_opl = h;
    }
    film
}

/// The camera of the sensor `s` on `film` (a capture meter's over the wall grid
/// `grid`), with the time origin asked for; refuses a field of view or aspect ratio
/// that is zero or infinite in single precision.
fn camera_of(
    path: &Path,
    s: &Sensor,
    film: &Film,
    grid: [usize; 2],
    overrides: &Overrides,
) -> Result<Camera, SceneError> {
    let (w, h) = (film.width, film.height);
    let (camera, fov) = match s.projection {
        SensorProjection::Meter(ref m) => (Camera::meter(m.origin, m.wall, w, h, grid[1]), None),
        SensorProjection::Perspective { fov, fov_axis } => {
            (Camera::new(s.to_world, fov, fov_axis, w, h), Some(fov))
        }
        SensorProjection::ThinLens {
            fov,
            fov_axis,
            aperture_radius,
            focus_distance,
        } => (
            Camera::thin_lens(
                s.to_world,
                fov,
                fov_axis,
                w,
                h,
                aperture_radius,
                focus_distance,
            ),
            Some(fov),
        ),
        SensorProjection::Orthographic => (Camera::orthographic(s.to_world, w, h), None),
    };
    let camera = match (overrides.time_origin, &s.projection) {
        (Some(TimeOrigin::NearClip), SensorProjection::Meter(_)) => {
            return Err(SceneError::new(
                path,
                s.line,
                "sensor type=\"nlos_capture_meter\"",
                "--time-origin near_clip: the meter has no near plane (its capture counts from the sensor; use pinhole or leave it out)",
            ))
        }
        (origin, _) => {
            camera.with_time_origin(origin.unwrap_or(TimeOrigin::NearClip), s.near_clip as f32)
        }
    };
    if !camera
        .tan_half
        .iter()
        .all(|&t| t >= f32::MIN_POSITIVE && t.is_finite())
    {
        let what = match fov {
            Some(fov) => format!("fov {fov:e} degrees at {w}x{h} px gives a field of view that is zero or infinite in single precision"),
            None => format!("a {w}x{h} px film has an aspect ratio that is zero or infinite in single precision"),
        };
        return Err(SceneError::new(
            path,
            s.line,
            format!("sensor type=\"{}\"", s.kind),
            what,
        ));
    }
    Ok(camera)
}

/// The scene's identity beyond its own bytes (`Scene::identity`).
/// The error names the file that could not be read again.
fn identity<'f>(
    files: &'f [std::path::PathBuf],
    overrides: &Overrides,
) -> Result<SceneIdentity, (&'f std::path::Path, std::io::Error)> {
    let mut inputs = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for f in files {
        let Ok(canonical) = f.canonicalize() else {
            continue;
        };
        if !seen.insert(canonical.clone()) {
            continue;
        }
        let mut hasher = Sha256::new();
        let mut file = std::fs::File::open(&canonical).map_err(|e| (f.as_path(), e))?;
        std::io::copy(&mut file, &mut hasher).map_err(|e| (f.as_path(), e))?;
        let name = canonical
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        inputs.push((name, format!("{:x}", hasher.finalize())));
    }
    inputs.sort();
    let mut defaults = overrides.defaults.clone();
    defaults.sort();
    Ok(SceneIdentity { inputs, defaults })
}

/// Whether `text` refers to the parameter `$key` (not as the prefix of a longer name).
fn mentions(text: &str, key: &str) -> bool {
    let pat = format!("${key}");
    text.match_indices(&pat).any(|(i, _)| {
        !text[i + pat.len()..]
            .chars()
            .next()
            .is_some_and(|c| c.is_alphanumeric() || c == '_')
    })
}

/// What the top-level elements of a scene and its includes define.
#[derive(Default)]
pub(super) struct Objects {
    named_bsdfs: HashMap<String, Material>,
    named_textures: NamedTextures,
    bsdfs: Vec<Material>,
    bsdf_index: HashMap<String, usize>,
    shapes: Vec<Shape>,
    emitters: Vec<Emitter>,
    /// The spectrum each emitter's colour was given as, if any (`Scene::emitter_spectra`).
    emitter_spectra: Vec<Option<Curve>>,
    sensor: Option<Sensor>,
    integrator: Option<IntegratorSettings>,
    /// Samplers declared at the top level, by id (sample count, seed).
    named_samplers: HashMap<String, (u32, u64)>,
    /// Area emitters declared at the top level, by id.
    area_emitters: HashMap<String, AreaEmission>,
    /// The files being included, outermost first (to refuse cycles).
    including: Vec<std::path::PathBuf>,
    /// `<include>`s read so far in all (repeats count: a file included 8 times from
    /// each of 8 files is read 64 times), bounded by `MAX_INCLUDED_FILES`.
    included: usize,
    /// `shapegroup`s by id: their shapes (world space of the group) and materials.
    shapegroups: HashMap<String, Vec<(Shape, Material)>>,
    /// Triangles added by instances so far (bounded, `instance::MAX_INSTANCED_TRIANGLES`).
    instanced_triangles: usize,
    /// Participating media, referenced by index from shapes and the sensor.
    media: Vec<Medium>,
    /// Media declared at the top level, by id (index into `media`).
    named_media: HashMap<String, u32>,
    /// The error for the first `<medium>` element seen (any file), should the
    /// integrator not be the volumetric one.
    first_medium: Option<SceneError>,
}

/// Adds a parsed shape (and its area emitter) to the scene.
fn add_shape(o: &mut Objects, shape: Shape, bsdf: Material, emission: Option<AreaEmission>) {
    let index = o.shapes.len() as u32;
    // Equal untextured BSDFs share an index; found by their exact Debug
    // text, so that many distinct BSDFs do not cost a quadratic search.
    // (Textured ones are not compared: an image's Debug text is its texels.)
    let index_of_bsdf = if bsdf.is_textured() {
        o.bsdfs.push(bsdf);
        o.bsdfs.len() - 1
    } else {
        *o.bsdf_index.entry(format!("{bsdf:?}")).or_insert_with(|| {
            o.bsdfs.push(bsdf);
            o.bsdfs.len() - 1
        })
    };
    let mut shape = Shape {
        bsdf: index_of_bsdf as u32,
        ..shape
    };
    if let Some(emission) = emission {
        shape.emitter = Some(o.emitters.len() as u32);
        o.emitter_spectra.push(emission.spectrum.clone());
        o.emitters
            .push(emission.into_emitter(index, AreaSampler::new(&shape)));
    }
    o.shapes.push(shape);
}

/// The shape plugins that group other shapes, read by the walk itself (the plugin
/// table's `shape` family with [`super::shapes::SHAPES`]; the names are
/// [`super::shapes::GROUPING`]).
pub(super) const GROUPING: &[(&str, ReadGroup)] = &[
    (super::shapes::GROUPING[0], parse_shapegroup),
    (super::shapes::GROUPING[1], add_instance),
];

/// Reads a grouping `<shape>` into the objects of the walk.
pub(super) type ReadGroup = fn(&Ctx<'_>, Node<'_, '_>, &mut Objects) -> Result<(), SceneError>;

/// The reader of a grouping `<shape>` (`None` for other shapes).
fn grouping(ctx: &Ctx, node: Node) -> Result<Option<ReadGroup>, SceneError> {
    Ok(ctx
        .attr(node, "type")?
        .and_then(|kind| super::table::reader(GROUPING, &kind)))
}

/// `<shape type="shapegroup" id=...>`: its shapes, kept for the instances that name it.
fn parse_shapegroup(ctx: &Ctx, node: Node, o: &mut Objects) -> Result<(), SceneError> {
    let Some(id) = ctx.attr(node, "id")? else {
        return Err(ctx.err(
            node,
            "a shapegroup needs an id (instances name it with <ref id=...>)",
        ));
    };
    let mut members = Vec::new();
    for child in node.children().filter(|n| n.is_element()) {
        if !child.has_tag_name("shape") {
            return Err(ctx.err(
                child,
                format!(
                    "<{}> inside a shapegroup is not supported (only <shape>s)",
                    child.tag_name().name()
                ),
            ));
        }
        let kind = ctx.required_attr(child, "type")?;
        if kind == "shapegroup" || kind == "instance" {
            return Err(ctx.err(
                child,
                format!(
                    "a {kind} inside a shapegroup is not permitted (nested instancing, as Mitsuba)"
                ),
            ));
        }
        let named = Named {
            bsdfs: &o.named_bsdfs,
            textures: &o.named_textures,
        };
        let (shape, bsdf, emission, sensor) = parse_shape(
            ctx,
            child,
            members.len() as u32,
            &named,
            &o.area_emitters,
            &mut o.media,
            &o.named_media,
        )?;
        if emission.is_some() {
            return Err(ctx.err(child, "instancing of emitters is not supported (as Mitsuba): a shape in a shapegroup cannot emit"));
        }
        if let Some(obj) = sensor {
            return Err(ctx.err(obj, "a relay wall in a shapegroup cannot hold the capture meter: attach it to a shape of the scene"));
        }
        members.push((shape, bsdf));
    }
    if o.shapegroups.insert(id.clone(), members).is_some() {
        return Err(ctx.err(node, format!("id '{id}' is defined twice")));
    }
    Ok(())
}

/// `<shape type="instance">`: world-space copies of a shapegroup's shapes under its
/// `to_world` (`instance.rs`).
fn add_instance(ctx: &Ctx, node: Node, o: &mut Objects) -> Result<(), SceneError> {
    let mut p = Props::parse(ctx, node)?;
    let to_world = p.transform("to_world")?.unwrap_or(DMat4::IDENTITY);
    let mut group = None;
    for obj in std::mem::take(&mut p.objects) {
        let id = match obj.tag_name().name() {
            "ref" => ctx.required_attr(obj, "id")?,
            other => {
                return Err(ctx.err(obj, format!("<{other}> inside an instance: only a <ref id> to a shapegroup can be specified (as Mitsuba)")))
            }
        };
        if group.is_some() {
            return Err(ctx.err(
                obj,
                "only a single shapegroup can be specified per instance (as Mitsuba)",
            ));
        }
        if !o.shapegroups.contains_key(&id) {
            return Err(ctx.err(
                obj,
                format!("'{id}' is not a shapegroup declared before this instance"),
            ));
        }
        group = Some(id);
    }
    p.finish()?;
    let id = group.ok_or_else(|| {
        ctx.err(
            node,
            "a reference to a 'shapegroup' must be specified (<ref id=...>)",
        )
    })?;
    let name = ctx
        .attr(node, "id")?
        .unwrap_or_else(|| format!("instance#{}", o.shapes.len()));
    let members = o.shapegroups[&id].clone();
    for (shape, bsdf) in members {
        let added = super::instance::triangle_count(&shape.geom);
        o.instanced_triangles = o.instanced_triangles.saturating_add(added);
        if o.instanced_triangles > super::instance::MAX_INSTANCED_TRIANGLES {
            return Err(ctx.err(
                node,
                format!(
                    "instances add more than {} triangles (each instance is a world-space copy of its group)",
                    super::instance::MAX_INSTANCED_TRIANGLES
                ),
            ));
        }
        let geom = super::instance::transformed(&shape.geom, &to_world).map_err(|e| {
            ctx.err(
                node,
                format!("shape '{}' of shapegroup '{id}': {e}", shape.name),
            )
        })?;
        let copy = Shape {
            name: format!("{name}/{}", shape.name),
            geom,
            ..shape
        };
        add_shape(o, copy, bsdf, None);
    }
    Ok(())
}

/// Nested `<include>`s deeper than this are refused (Mitsuba has no limit; cycles are
/// caught separately).
const MAX_INCLUDE_DEPTH: usize = 16;

/// The top-level elements of `root` (the scene file's or an included file's), in
/// document order.
fn walk(ctx: &Ctx, root: Node, o: &mut Objects, depth: usize) -> Result<(), SceneError> {
    // A `<scene>`'s children; an included file whose root is one object (a `<bsdf>`,
    // a `<shape>`, ...) is that object, as Mitsuba parses it.
    let nodes: Vec<Node> = if root.has_tag_name("scene") {
        root.children().filter(|n| n.is_element()).collect()
    } else {
        vec![root]
    };
    if o.first_medium.is_none() {
        if let Some(n) = root.descendants().find(|n| n.has_tag_name("medium")) {
            o.first_medium = Some(ctx.err(
                n,
                "the scene has participating media, which integrator 'transient_path' ignores (as Mitsuba's path integrator does): use <integrator type=\"transient_prbvolpath\">",
            ));
        }
    }
    // Area emitters declared at this level, attached to shapes by <ref id> anywhere in
    // the file, also before their declaration (Mitsuba resolves references after
    // reading the whole file).
    for &node in nodes.iter().filter(|n| n.has_tag_name("emitter")) {
        let Some(kind) = ctx
            .attr(node, "type")?
            .filter(|k| AREA_KINDS.contains(&k.as_str()))
        else {
            continue;
        };
        let Some(id) = ctx.attr(node, "id")? else {
            return Err(ctx.err(
                node,
                "a top-level area emitter needs an id (shapes attach it with <ref id=...>)",
            ));
        };
        let emission = parse_area_emission(ctx, node, &kind, &o.named_textures)?;
        if o.area_emitters.insert(id.clone(), emission).is_some() {
            return Err(ctx.err(node, format!("id '{id}' is defined twice")));
        }
    }
    for &node in &nodes {
        match node.tag_name().name() {
            "default" => {}
            "integrator" => {
                if o.integrator.is_some() {
                    return Err(ctx.err(node, "a scene has one <integrator>"));
                }
                o.integrator = Some(parse_integrator(ctx, node)?);
            }
            "sensor" => {
                if o.sensor.is_some() {
                    return Err(ctx.err(node, "only one <sensor> is supported"));
                }
                o.sensor = Some(parse_sensor(ctx, node, &o.named_samplers, &mut o.media, &o.named_media)?);
            }
            "medium" => {
                let m = parse_medium(ctx, node)?;
                let Some(id) = ctx.attr(node, "id")? else {
                    return Err(ctx.err(node, "a top-level <medium> needs an id (shapes and the sensor attach it with <ref name=\"interior\" id=...>)"));
                };
                o.media.push(m);
                if o.named_media.insert(id.clone(), (o.media.len() - 1) as u32).is_some() {
                    return Err(ctx.err(node, format!("id '{id}' is defined twice")));
                }
            }
            "texture" => {
                let t = parse_texture(ctx, node, &o.named_textures)?;
                let Some(id) = ctx.attr(node, "id")? else {
                    return Err(ctx.err(node, "a top-level <texture> needs an id to be referenced"));
                };
                if o.named_textures.insert(id.clone(), t).is_some() {
                    return Err(ctx.err(node, format!("id '{id}' is defined twice")));
                }
            }
            "bsdf" => {
                let named = Named {
                    bsdfs: &o.named_bsdfs,
                    textures: &o.named_textures,
                };
                let b = parse_bsdf(ctx, node, &named)?;
                // Mitsuba names every object with an id, nested ones too (a scene may
                // refer to the BSDF inside a `bumpmap`): those are parsed on their own.
                let mut found = Vec::new();
                for inner in node.descendants().skip(1) {
                    if inner.is_element() && inner.tag_name().name() == "bsdf" {
                        if let Some(id) = ctx.attr(inner, "id")? {
                            found.push((id, inner, parse_bsdf(ctx, inner, &named)?));
                        }
                    }
                }
                for (id, inner, m) in found {
                    if o.named_bsdfs.insert(id.clone(), m).is_some() {
                        return Err(ctx.err(inner, format!("id '{id}' is defined twice")));
                    }
                }
                if let Some(id) = ctx.attr(node, "id")? {
                    if o.named_bsdfs.insert(id.clone(), b).is_some() {
                        return Err(ctx.err(node, format!("id '{id}' is defined twice")));
                    }
                }
            }
            "shape" if grouping(ctx, node)?.is_some() => {
                grouping(ctx, node)?.expect("checked by the guard")(ctx, node, o)?
            }
            "shape" => {
                let index = o.shapes.len() as u32;
                let named = Named {
                    bsdfs: &o.named_bsdfs,
                    textures: &o.named_textures,
                };
                let (shape, bsdf, emission, sensor) = parse_shape(
                    ctx,
                    node,
                    index,
                    &named,
                    &o.area_emitters,
                    &mut o.media,
                    &o.named_media,
                )?;
                if let Some(obj) = sensor {
                    if o.sensor.is_some() {
                        return Err(ctx.err(obj, "only one <sensor> is supported"));
                    }
                    let mut meter = parse_meter(
                        ctx,
                        obj,
                        &o.named_samplers,
                        &o.named_textures,
                        index,
                        &shape,
                    )?;
                    if let Some(laser) = meter.laser.take() {
                        o.emitters.push(laser);
                        o.emitter_spectra.push(None);
                    }
                    o.sensor = Some(meter);
                }
                add_shape(o, shape, bsdf, emission);
            }
            // Area emitters declared here were read before the walk (below).
            "emitter"
                if ctx
                    .attr(node, "type")?
                    .is_some_and(|k| AREA_KINDS.contains(&k.as_str())) => {}
            "emitter" if ctx.attr(node, "type")?.as_deref() == Some(super::projector::PROJECTOR) => {
                ctx.take_emission_spectrum();
                let e = super::projector::parse_projector(ctx, node, &o.named_textures)?;
                o.emitters.push(e);
                o.emitter_spectra.push(ctx.take_emission_spectrum());
            }
            "emitter" => {
                ctx.take_emission_spectrum();
                let kind = ctx.required_attr(node, "type")?;
                if infinite_emitters::KINDS.contains(&kind.as_str()) {
                    let e = infinite_emitters::parse_infinite_emitter(ctx, node, &kind)?;
                    if e.is_environment() && o.emitters.iter().any(|e| e.is_environment()) {
                        return Err(ctx.err(
                            node,
                            "a scene has at most one environment emitter (envmap or constant), as in Mitsuba",
                        ));
                    }
                    o.emitters.push(e);
                } else {
                    o.emitters.push(parse_point_emitter(ctx, node, &o.named_textures)?);
                }
                o.emitter_spectra.push(ctx.take_emission_spectrum());
            }
            "sampler" => {
                let Some(id) = ctx.attr(node, "id")? else {
                    return Err(ctx.err(node, "a top-level <sampler> needs an id (a sensor attaches it with <ref id=...>)"));
                };
                let sampler = parse_sampler(ctx, node)?;
                if o.named_samplers.insert(id.clone(), sampler).is_some() {
                    return Err(ctx.err(node, format!("id '{id}' is defined twice")));
                }
            }
            "path" => add_search_path(ctx, node)?,
            "include" => include(ctx, node, o, depth)?,
            other => {
                return Err(ctx.err(
                    node,
                    format!("<{other}> is not supported (supported at top level: default, path, include, integrator, sensor, sampler, texture, bsdf, shape, emitter, medium)"),
                ))
            }
        }
    }

    Ok(())
}

/// `<path value="...">`: a folder searched for the files the scene names (meshes,
/// images, includes), ahead of the folders searched so far (Mitsuba's file resolver
/// `prepend`). A relative folder is taken from the folder of the file that names it,
/// and must exist.
fn add_search_path(ctx: &Ctx, node: Node) -> Result<(), SceneError> {
    let value = ctx.required_attr(node, "value")?;
    let mut dir = std::path::PathBuf::from(&value);
    if dir.is_relative() {
        dir = ctx.dir().join(&value);
        if !dir.exists() {
            dir = ctx.resolve(&value);
        }
    }
    // Mitsuba only checks that the path exists: a `<path>` naming a file is accepted
    // (nothing is ever found under it).
    if !dir.exists() {
        return Err(ctx.err(node, format!("folder '{value}' not found")));
    }
    ctx.prepend_search_path(dir);
    Ok(())
}

/// At most this many `<include>`s are read in all, repeats counted (also when
/// gathering included `<default>`s).
const MAX_INCLUDED_FILES: usize = 4096;

/// The literal `<default>`s of the files `root` includes, recursively, in document
/// order (a file's own before those of the files it includes). Files that cannot be
/// read or parsed are skipped here: the walk reports them with their context.
fn included_defaults(
    ctx: &Ctx,
    root: Node,
    depth: usize,
    files: &mut usize,
    out: &mut Vec<(String, String)>,
) {
    if depth >= MAX_INCLUDE_DEPTH {
        return;
    }
    for node in root.children() {
        // `<path>`s before an include may be where it is found (the walk adds them
        // again to the scene's own context).
        if node.has_tag_name("path") {
            let _ = add_search_path(ctx, node);
            continue;
        }
        if !node.has_tag_name("include") {
            continue;
        }
        *files += 1;
        if *files > MAX_INCLUDED_FILES {
            return;
        }
        let Ok(Some(name)) = ctx.attr(node, "filename") else {
            continue;
        };
        let path = ctx.resolve_near(&name);
        let Ok(bytes) = crate::io::read_regular(&path, crate::io::MAX_SCENE_BYTES) else {
            continue;
        };
        let Ok(text) = String::from_utf8(bytes) else {
            continue;
        };
        if limits::prescan(&text).is_err() {
            continue;
        }
        let options = roxmltree::ParsingOptions {
            nodes_limit: limits::MAX_NODES,
            ..Default::default()
        };
        let Ok(doc) = roxmltree::Document::parse_with_options(&text, options) else {
            continue;
        };
        if limits::too_deep(&doc).is_some() {
            continue;
        }
        let mut defaults = ctx.defaults.clone();
        for d in doc
            .root_element()
            .children()
            .filter(|n| n.has_tag_name("default"))
        {
            if let (Some(name), Some(value)) = (d.attribute("name"), d.attribute("value")) {
                if !value.contains('$') {
                    out.push((name.to_string(), value.to_string()));
                    defaults
                        .entry(name.to_string())
                        .or_insert(value.to_string());
                }
            }
        }
        let child = ctx.for_included_file_with(&path, &text, &defaults);
        included_defaults(&child, doc.root_element(), depth + 1, files, out);
    }
}

/// `<include filename="...">`: the top-level elements of another scene file, as if
/// written here (Mitsuba merges the included `<scene>`'s children). The file is looked
/// up next to the including file first, then as any other file; its `<path>`s stay in
/// effect afterwards, as with Mitsuba's global file resolver. `$name` defaults are the
/// including scene's, plus the included file's own `<default>`s for names not set yet
/// (Mitsuba adds them to its parameter list, so the command line and the including
/// scene win); they hold in the included file, the files it includes and, gathered
/// before the walk by [`included_defaults`], in the including scene too.
fn include(ctx: &Ctx, node: Node, o: &mut Objects, depth: usize) -> Result<(), SceneError> {
    let name = ctx.required_attr(node, "filename")?;
    let path = ctx.resolve_near(&name);
    // Checked before reading: a chain of small files that each include the next
    // several times stays under the depth limit but multiplies without end.
    o.included += 1;
    if o.included > MAX_INCLUDED_FILES {
        return Err(ctx.err(
            node,
            format!("more than {MAX_INCLUDED_FILES} <include>s in all (counting repeats): the includes fan out"),
        ));
    }
    if depth + 1 > MAX_INCLUDE_DEPTH {
        return Err(ctx.err(
            node,
            format!("includes nested more than {MAX_INCLUDE_DEPTH} deep"),
        ));
    }
    let canonical = path.canonicalize().map_err(|e| {
        ctx.err(
            node,
            format!("cannot read included file '{}': {e}", path.display()),
        )
    })?;
    if o.including.contains(&canonical) {
        return Err(ctx.err(
            node,
            format!(
                "'{}' includes itself (through {} files)",
                path.display(),
                o.including.len()
            ),
        ));
    }
    let bytes = crate::io::read_regular(&path, crate::io::MAX_SCENE_BYTES).map_err(|e| {
        ctx.err(
            node,
            format!("cannot read included file '{}': {e}", path.display()),
        )
    })?;
    let text = String::from_utf8(bytes).map_err(|_| {
        ctx.err(
            node,
            format!("included file '{}' is not UTF-8", path.display()),
        )
    })?;
    limits::prescan(&text).map_err(|r| {
        let line = text[..r.offset].bytes().filter(|&b| b == b'\n').count() + 1;
        SceneError::new(&path, line as u32, "xml", r.message)
    })?;
    let options = roxmltree::ParsingOptions {
        nodes_limit: limits::MAX_NODES,
        ..Default::default()
    };
    let doc = roxmltree::Document::parse_with_options(&text, options)
        .map_err(|e| SceneError::new(&path, e.pos().row, "xml", malformed(&e)))?;
    let mut defaults = ctx.defaults.clone();
    for d in doc
        .root_element()
        .children()
        .filter(|n| n.has_tag_name("default"))
    {
        let own = Ctx::new(&path, &text, ctx.defaults).with_plugin_names(canonical_plugin_name);
        let name = own.required_attr(d, "name")?;
        let raw = d.attribute("value").unwrap_or_default();
        if raw.contains('$') {
            return Err(own.err(
                d,
                format!("the value '{raw}' refers to a default; a <default> value must be literal"),
            ));
        }
        let value = own.required_attr(d, "value")?;
        defaults.entry(name).or_insert(value);
    }
    let child = ctx.for_included_file_with(&path, &text, &defaults);
    if let Some(deep) = limits::too_deep(&doc) {
        return Err(child.err(
            deep,
            format!("elements are nested more than {} deep", limits::MAX_DEPTH),
        ));
    }
    let root = doc.root_element();
    // Mitsuba parses an included file's root element: a `<scene>` merges its children,
    // any other element is one object (the walk refuses what is not top-level).
    check_elements(&child, root)?;
    ctx.read_mesh_file(&canonical);
    o.including.push(canonical);
    let walked = walk(&child, root, o, depth + 1);
    o.including.pop();
    ctx.adopt(child);
    walked
}

/// The volumetric integrator treats `null` surfaces as medium boundaries; `mask`
/// (Mitsuba's partly-null BSDF) would need its null part in shadow rays, which it does
/// not model: such scenes are refused rather than rendered differently from Mitsuba.
fn check_volumetric_materials(ctx: &Ctx, root: Node, bsdfs: &[Material]) -> Result<(), SceneError> {
    fn has_mask(b: &Bsdf) -> bool {
        match b {
            Bsdf::Mask(_) => true,
            Bsdf::Composed(c) => has_mask(&c.first) || has_mask(&c.second),
            Bsdf::Separable(s) => has_mask(&s.inner),
            _ => false,
        }
    }
    if bsdfs.iter().any(|m| has_mask(&m.bsdf)) {
        return Err(ctx.err(
            root,
            "bsdf 'mask' is not supported by transient_prbvolpath (its pass-through part is a null interface in Mitsuba's volumetric integrators); use transient_path or a 'null' BSDF",
        ));
    }
    Ok(())
}

/// The diagonal of the box around all shapes, in world units.
fn extent(shapes: &[Shape]) -> Option<f32> {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for shape in shapes {
        let (a, b) = shape.bounds();
        (lo, hi) = (lo.min(a), hi.max(b));
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
        "float" | "integer" | "boolean" | "string" | "rgb" | "color" => &["name", "value"],
        "spectrum" => &["name", "value", "filename", "type"],
        "path" => &["value"],
        "include" => &["filename"],
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

/// "malformed XML: ..." for a parser error, its control characters escaped: roxmltree
/// quotes the unexpected character as it is (`expected '>' not '\n'` would break the
/// one-line error).
pub(crate) fn malformed(e: &roxmltree::Error) -> String {
    let text: String = e
        .to_string()
        .chars()
        .flat_map(|c| {
            let escaped: Vec<char> = if c.is_control() {
                c.escape_default().collect()
            } else {
                vec![c]
            };
            escaped
        })
        .collect();
    format!("malformed XML: {text}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn malformed_xml_errors_stay_on_one_line() {
        let e = roxmltree::Document::parse("<a b='c'/\n>").unwrap_err();
        assert!(
            e.to_string().contains('\n'),
            "roxmltree quotes the newline as it is"
        );
        let m = malformed(&e);
        assert!(!m.contains('\n') && m.contains("\\n"), "{m}");
        assert!(m.starts_with("malformed XML: "), "{m}");
    }

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

    /// Mitsuba names nested objects too: a reference to the BSDF inside a top-level
    /// `bumpmap` gets that BSDF (the staircase scene's pattern), not the bump map; the
    /// normal/bump-mapped materials are flagged through wrappers, others are not.
    #[test]
    fn nested_bsdf_ids_are_named_and_perturbation_is_flagged() {
        use crate::materials::Bsdf;
        let scene = load_text(&with(&format!(
            r#"{LIGHT}<bsdf type="bumpmap"><texture type="checkerboard" name="h"/><bsdf type="twosided" id="inner"><bsdf type="diffuse"/></bsdf></bsdf>
               <shape type="sphere"><ref id="inner"/></shape>"#
        )))
        .unwrap();
        let m = &scene.bsdfs[scene.shapes[1].bsdf as usize];
        assert!(matches!(m.bsdf, Bsdf::TwoSided(_)) && !m.perturbs() && m.is_plain());
        let nm = r#"<bsdf type="normalmap"><texture type="checkerboard" name="normalmap"/><bsdf type="diffuse"/></bsdf>"#;
        for (bsdf, want) in [
            (nm.to_string(), true),
            (format!(r#"<bsdf type="mask">{nm}</bsdf>"#), true),
            (format!(r#"<bsdf type="blendbsdf"><float name="weight" value="0.2"/><bsdf type="diffuse"/>{nm}</bsdf>"#), true),
            (r#"<bsdf type="blendbsdf"><float name="weight" value="0.2"/><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf>"#.to_string(), false),
            (r#"<bsdf type="pplastic"/>"#.to_string(), false),
        ] {
            let scene = load_text(&with(&format!(
                r#"{LIGHT}<shape type="sphere">{bsdf}</shape>"#
            )))
            .unwrap_or_else(|e| panic!("{bsdf}: {e}"));
            let m = &scene.bsdfs[scene.shapes[1].bsdf as usize];
            assert_eq!(m.perturbs(), want, "{bsdf}");
            // Perturbing materials build Mitsuba's dp/du frame and are never plain.
            assert_eq!(m.is_anisotropic(), want, "{bsdf}");
            assert!(!(want && m.is_plain()), "{bsdf}");
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
