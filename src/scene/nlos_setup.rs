//! Non-line-of-sight captures (SPEC 11): mitransient 1.3.1's `transient_nlos_path`
//! integrator and `nlos_capture_meter` sensor, read from the scene and prepared at load
//! (the relay wall's grid, the laser and the points it lights, the hidden geometry's
//! area distribution). What the tracer does with it while rendering (the ends of a grid
//! point's paths, hidden-geometry sampling, the NLOS path loop) is `render/nlos/`; the
//! laser's light at a point is `lights/laser.rs`.
//!
//! `transient_nlos_path` takes `transient_path`'s parameters (max_depth, rr_depth,
//! temporal_filter, gaussian_stddev, hide_emitters) and these:
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | capture_type | integer or string | single | 1/`single`: one laser point (where the laser's axis meets the scene); 2/`confocal`: the laser lights the sensor point itself; 3/`exhaustive`: every point of the laser grid, one image each |
//! | nlos_laser_sampling | boolean | false | connect each vertex to the lit point, then the lit point to the laser ([Royo2022]'s laser sampling); false: next-event estimation to the laser |
//! | nlos_hidden_geometry_sampling | boolean | false | continue paths towards a uniform point of the hidden geometry (every shape but the relay wall) instead of sampling the BSDF |
//! | nlos_hidden_geometry_sampling_max_depth | integer | -1 | only at vertices of depth below this (-1: all) |
//! | nlos_hidden_geometry_sampling_do_rroulette | boolean | false | choose hidden-geometry or BSDF sampling with probability 1/2 each |
//! | nlos_hidden_geometry_sampling_includes_relay_wall | boolean | false | the relay wall is hidden geometry too |
//! | account_first_and_last_bounces | boolean | false | count the sensor-to-wall and wall-to-laser segments in the OPL |
//! | filter_depth / filter_bounces | integer | -1 | keep only light-sample contributions of this depth (bounces: depth - 1) |
//! | discard_direct_paths | boolean | false | drop light-sample contributions of depth <= 2 |
//! | force_equal_illumination_scanning | boolean | true | exhaustive: the laser grid is the sensor grid |
//! | illumination_scan_fov | float | 20 | exhaustive without equal grids: see below |
//! | block_size | integer | | Mitsuba's block size: no effect |
//!
//! The depth of a light-sample contribution is mitransient's: the vertex's depth (0 at
//! the first hit) for next-event estimation, that plus 2 through laser sampling.
//!
//! `nlos_capture_meter`, nested in the relay wall's `<shape type="rectangle">`:
//! `sensor_origin` (point, default 0) and a `transient_hdr_film` whose width x height
//! is the grid of points measured on the wall. Grid point (column x, row y) is the
//! rectangle's uv point ((x + 1/2) / W, (y + 1/2) / H), i.e. its local
//! (2u - 1, 2v - 1, 0) (Mitsuba's `sample_position`): row 0 lies along the local -y
//! edge. A path starts at `sensor_origin` towards that point. For exhaustive scans the
//! film also sets `exhaustive_scan` and `laser_scan_width`/`laser_scan_height`, and the
//! render is one image per laser point, stacked: film row `l H + y` is sensor row `y`
//! lit by laser point `l` (row-major in the laser grid, as sensor pixels are).
//!
//! Legacy meter parameters of mitransient <= 1.1's scenes (which 1.3.1 refuses to
//! load) are checked and named in one warning: `laser_origin` with
//! `laser_lookat_pixel` (uv = pixel / film size, when both are positive) or
//! `laser_lookat_3d` move and aim the scene's projector as those versions did; a
//! `<emitter>` nested in the meter is the scene's laser; a box `<rfilter>` there is
//! the film's; `confocal` = false and `account_first_and_last_bounces` (an integrator
//! setting in 1.3.1) are ignored.
//!
//! The laser is the scene's only emitter, a `projector` or a `spot`. With laser
//! sampling in confocal and exhaustive captures it is re-aimed at each lit point
//! (mitransient's `focus_laser`): the point receives the on-axis radiant intensity
//! over its squared distance, along the real direction to the laser.

use super::error::SceneError;
use super::props::Props;
use crate::geometry::accel::{Accel, Hit};
use crate::geometry::shape::{AreaSampler, Shape, ShapeGeom};
use crate::lights::laser::{laser_light, LaserLight};
use crate::lights::Emitter;
use crate::sensors::relay_wall::Wall;
use glam::Vec3;

/// What the laser lights (mitransient's `capture_type`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CaptureType {
    Single,
    Confocal,
    Exhaustive,
}

impl CaptureType {
    pub fn name(self) -> &'static str {
        match self {
            CaptureType::Single => "single",
            CaptureType::Confocal => "confocal",
            CaptureType::Exhaustive => "exhaustive",
        }
    }
}

/// `transient_nlos_path`'s own parameters (see the module notes).
#[derive(Clone, Debug, PartialEq)]
pub struct NlosSettings {
    pub capture: CaptureType,
    pub laser_sampling: bool,
    pub hg_sampling: bool,
    /// -1: no limit.
    pub hg_max_depth: i64,
    pub hg_rroulette: bool,
    pub hg_includes_relay_wall: bool,
    pub account_first_and_last_bounces: bool,
    /// -1: every depth.
    pub filter_depth: i64,
    pub discard_direct_paths: bool,
    pub force_equal_grids: bool,
    pub illumination_scan_fov: f64,
}

/// Reads `transient_nlos_path`'s own parameters from `p`.
pub fn parse_settings(p: &mut Props, max_depth: i64) -> Result<NlosSettings, SceneError> {
    let capture = match p.peek("capture_type") {
        None => CaptureType::Single,
        Some(super::props::Value::Integer(_)) => match p.integer("capture_type")? {
            Some(1) => CaptureType::Single,
            Some(2) => CaptureType::Confocal,
            Some(3) => CaptureType::Exhaustive,
            other => {
                return Err(p.err_at(
                    "capture_type",
                    format!(
                        "capture_type {} is not 1 (single), 2 (confocal) or 3 (exhaustive)",
                        other.unwrap_or_default()
                    ),
                ))
            }
        },
        Some(_) => {
            let s = p.string("capture_type")?.unwrap_or_default();
            match s.to_ascii_lowercase().as_str() {
                "single" => CaptureType::Single,
                "confocal" => CaptureType::Confocal,
                "exhaustive" => CaptureType::Exhaustive,
                _ => {
                    return Err(p.err_at(
                        "capture_type",
                        format!("capture_type '{s}' is not one of: single, confocal, exhaustive"),
                    ))
                }
            }
        }
    };
    let filter_depth = p.integer("filter_depth")?.unwrap_or(-1);
    let filter_bounces = p.integer("filter_bounces")?.unwrap_or(-1);
    if filter_depth != -1 && filter_bounces != -1 {
        return Err(p.err_at(
            "filter_bounces",
            "set only one of filter_depth and filter_bounces",
        ));
    }
    for (name, v) in [
        ("filter_depth", filter_depth),
        ("filter_bounces", filter_bounces),
    ] {
        if v < -1 || v > i32::MAX as i64 {
            return Err(p.err_at(name, format!("{name} must be -1 or >= 0, got {v}")));
        }
    }
    let filter_depth = if filter_bounces != -1 {
        filter_bounces + 1
    } else {
        filter_depth
    };
    if filter_depth != -1 && max_depth != -1 && filter_depth >= max_depth {
        p.warn_at(
            "filter_depth",
            format!("filter_depth {filter_depth} >= max_depth {max_depth}: every contribution is filtered out, the capture is all zero"),
        );
    }
    let hg_sampling = p.boolean_or("nlos_hidden_geometry_sampling", false)?;
    let hg_max_depth = p
        .integer("nlos_hidden_geometry_sampling_max_depth")?
        .unwrap_or(-1);
    if hg_max_depth == 0 || hg_max_depth < -1 {
        return Err(p.err_at(
            "nlos_hidden_geometry_sampling_max_depth",
            format!("nlos_hidden_geometry_sampling_max_depth must be -1 or positive, got {hg_max_depth}"),
        ));
    }
    let hg_rroulette = p.boolean_or("nlos_hidden_geometry_sampling_do_rroulette", false)?;
    let hg_wall = p.boolean_or("nlos_hidden_geometry_sampling_includes_relay_wall", false)?;
    let fov = p.float_or("illumination_scan_fov", 20.0)?;
    if !(fov > 0.0 && fov < 180.0) {
        return Err(p.err_at(
            "illumination_scan_fov",
            format!("illumination_scan_fov must be in (0, 180) degrees, got {fov}"),
        ));
    }
    // Mitsuba's image block size: how work is split, not what is computed.
    p.ignore("block_size");
    Ok(NlosSettings {
        capture,
        laser_sampling: p.boolean_or("nlos_laser_sampling", false)?,
        hg_sampling,
        hg_max_depth,
        hg_rroulette: hg_rroulette && hg_sampling,
        hg_includes_relay_wall: hg_wall && hg_sampling,
        account_first_and_last_bounces: p.boolean_or("account_first_and_last_bounces", false)?,
        filter_depth,
        discard_direct_paths: p.boolean_or("discard_direct_paths", false)?,
        force_equal_grids: p.boolean_or("force_equal_illumination_scanning", true)?,
        illumination_scan_fov: fov,
    })
}

/// A parsed `nlos_capture_meter`.
#[derive(Clone, Debug)]
pub struct CaptureMeter {
    pub origin: Vec3,
    /// The relay wall's shape index.
    pub shape: u32,
    pub wall: Wall,
    /// The film's `exhaustive_scan` laser grid (width, height).
    pub laser_scan: Option<[usize; 2]>,
    /// mitransient's older (<= 1.1) laser placement, when the meter gives one.
    pub legacy_laser: Option<LegacyLaser>,
}

/// mitransient <= 1.1 placed the laser from the meter: at `laser_origin`, looking at
/// the wall point of film position `laser_lookat_pixel` (uv = pixel / film size, used
/// when both coordinates are positive) or at `laser_lookat_3d`, up +y.
#[derive(Clone, Copy, Debug)]
pub struct LegacyLaser {
    pub origin: Vec3,
    pub lookat_pixel: Option<[f64; 2]>,
    pub lookat_3d: Option<Vec3>,
}

impl LegacyLaser {
    /// The laser's to_world on a `w` x `h` grid of `wall`, if it looks somewhere.
    pub fn to_world(&self, wall: &Wall, w: usize, h: usize) -> Option<glam::DMat4> {
        let target = match (self.lookat_pixel, self.lookat_3d) {
            (Some([px, py]), _) if px > 0.0 && py > 0.0 => {
                wall.corner + wall.du * (px / w as f64) as f32 + wall.dv * (py / h as f64) as f32
            }
            (_, Some(t)) => t,
            _ => return None,
        };
        super::to_world::look_at(self.origin.as_dvec3(), target.as_dvec3(), glam::DVec3::Y)
    }
}

/// Reads an `nlos_capture_meter`'s own parameters (the film and sampler are read by
/// the caller): `sensor_origin`, and the legacy laser. Legacy parameters: see the
/// module notes.
pub fn parse_meter_params(p: &mut Props) -> Result<(Vec3, Option<LegacyLaser>), SceneError> {
    let origin = p.point("sensor_origin")?.unwrap_or([0.0; 3]);
    let mut legacy = Vec::new();
    if p.peek("confocal").is_some() {
        if p.boolean_or("confocal", false)? {
            return Err(p.err_at("confocal", "confocal = true: mitransient's older confocal switch; use <string name=\"capture_type\" value=\"confocal\"/> in <integrator type=\"transient_nlos_path\">"));
        }
        legacy.push("confocal");
    }
    let point = |p: &mut Props, name: &str| -> Result<Option<Vec3>, SceneError> {
        let v = p
            .point(name)?
            .map(|v| Vec3::from_array(v.map(|x| x as f32)));
        if v.is_some_and(|v| !v.is_finite()) {
            return Err(p.err_at(name, format!("{name} must be finite")));
        }
        Ok(v)
    };
    let laser_origin = point(p, "laser_origin")?;
    let lookat_pixel = point(p, "laser_lookat_pixel")?;
    let lookat_3d = point(p, "laser_lookat_3d")?;
    for (name, v) in [
        ("laser_origin", laser_origin),
        ("laser_lookat_pixel", lookat_pixel),
        ("laser_lookat_3d", lookat_3d),
    ] {
        if v.is_some() {
            legacy.push(name);
        }
    }
    if p.peek("account_first_and_last_bounces").is_some() {
        p.boolean_or("account_first_and_last_bounces", false)?;
        legacy.push("account_first_and_last_bounces");
    }
    if let Some(first) = legacy.first() {
        p.warn_at(
            first,
            format!("{} on nlos_capture_meter: parameters of mitransient <= 1.1, which 1.3.1 refuses; tstat places the laser (the scene's projector) at laser_origin looking at laser_lookat_pixel / laser_lookat_3d as those versions did, and ignores the rest (account_first_and_last_bounces belongs to <integrator type=\"transient_nlos_path\">)", legacy.join(", ")),
        );
    }
    let legacy_laser = laser_origin.map(|origin| LegacyLaser {
        origin,
        lookat_pixel: lookat_pixel.map(|v| [v.x as f64, v.y as f64]),
        lookat_3d,
    });
    for name in ["original_film_width", "original_film_height"] {
        if p.peek(name).is_some() {
            return Err(p.err_at(name, format!("{name}: mitransient's one-point-per-render confocal mode is driven from Python (y-tal moves the laser between renders); use capture_type confocal with the whole grid as the film")));
        }
    }
    let o = Vec3::from_array(origin.map(|v| v as f32));
    if !o.is_finite() {
        return Err(p.err_at("sensor_origin", "sensor_origin must be finite"));
    }
    Ok((o, legacy_laser))
}

/// The hidden geometry a path may aim at (hidden-geometry sampling): shapes chosen by
/// area, then a uniform point on the chosen one, so each point has density 1 / area.
#[derive(Clone, Debug)]
pub struct HiddenGeometry {
    pub shapes: Vec<u32>,
    /// Per scene shape: whether it is hidden geometry.
    pub member: Vec<bool>,
    /// Cumulative areas, normalised to end at 1.
    pub cdf: Vec<f32>,
    pub samplers: Vec<AreaSampler>,
    pub total_area: f32,
}

/// What a scene with `transient_nlos_path` renders with, prepared at load.
#[derive(Clone, Debug)]
pub struct NlosSetup {
    /// The laser's position (the scene's only emitter, `emitters[0]`).
    pub laser_origin: Vec3,
    /// The laser's axis (to_world's +z, unit).
    pub laser_axis: Vec3,
    /// The capture meter, when the sensor is one.
    pub meter: Option<CaptureMeter>,
    /// Sensor grid (width, height): the meter's film, or the camera's.
    pub sensor_grid: [usize; 2],
    /// Laser grid (width, height): 1 x 1 but for exhaustive scans.
    pub laser_grid: [usize; 2],
    /// The surface at each lit point, as the ray that found it met it (laser sampling
    /// connects to it with a shadow ray): single: one; confocal: one per sensor point
    /// (row-major); exhaustive: one per laser grid point (row-major). Empty without
    /// laser sampling; `None` where the ray meets nothing (that point lights nothing).
    pub laser_hits: Vec<Option<Hit>>,
    /// The laser's light at each lit point, aligned with `laser_hits`.
    pub lit_light: Vec<Option<LaserLight>>,
    /// With a capture meter: the first hit of each sensor point's ray (row-major),
    /// which every path of that point starts from (the ray does not depend on the
    /// sample).
    pub sensor_hits: Vec<Option<Hit>>,
    pub hidden: Option<HiddenGeometry>,
}

/// Where the ray (o, d) first meets the scene. The relay wall (`wall`: the meter's
/// rectangle and its shape index) is also met analytically, as Mitsuba's rectangle:
/// its two triangles share the diagonal u = v, and a ray aimed exactly at a point of
/// it (the meter's grid points on the diagonal, the laser aimed at the wall's centre)
/// can slip between them in single precision.
fn first_hit(
    accel: &Accel,
    shapes: &[Shape],
    wall: Option<(&Wall, u32)>,
    o: Vec3,
    d: Vec3,
) -> Option<Hit> {
    let hit = accel.intersect(shapes, o, d, f32::INFINITY);
    let Some((w, index)) = wall else {
        return hit;
    };
    let Some((t, u, v)) = w.intersect(o, d) else {
        return hit;
    };
    match hit {
        // Something nearer (or the wall itself, found by the triangles) comes first.
        Some(h) if h.t <= t * (1.0 + 1e-6) => Some(h),
        _ => Some(w.hit(&shapes[index as usize], index, t, u, v, o + d * t)),
    }
}

/// The most sensor (and laser) grid points a capture may have: each keeps its first
/// hit and its laser light, about 100 bytes (420 MB at this bound). NLOS captures are
/// at most a few hundred points on a side.
pub const MAX_GRID_POINTS: usize = 1 << 22;

/// Why a `transient_nlos_path` render cannot be prepared from the scene ([`prepare`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum NlosSetupError {
    /// Not exactly one emitter.
    #[error(
        "transient_nlos_path needs exactly one emitter, the laser (a projector or spot), as mitransient 1.3.1; the scene has {emitters}"
    )]
    EmitterCount { emitters: usize },
    /// An emitter without a position and an axis.
    #[error(
        "transient_nlos_path: the laser must be a projector or a spot emitter (a positioned light with an axis)"
    )]
    LaserKind,
    /// A laser whose position is not finite (its `to_world` overflows).
    #[error("transient_nlos_path: the laser's position ({}, {}, {}) is not finite: its to_world overflows", .origin[0], .origin[1], .origin[2])]
    LaserOrigin { origin: [f32; 3] },
    /// A laser whose `to_world` maps its axis to zero.
    #[error("transient_nlos_path: the laser's to_world maps its axis to zero")]
    LaserAxis,
    /// A capture meter's grid (width, height) above [`MAX_GRID_POINTS`].
    #[error(
        "the capture meter's {}x{} grid has more than the {MAX_GRID_POINTS} points tstat prepares",
        .grid[0], .grid[1]
    )]
    MeterGrid { grid: [usize; 2] },
    /// A capture type that needs a capture meter, without one.
    #[error(
        "capture_type {} needs an nlos_capture_meter sensor on the relay wall",
        .capture.name()
    )]
    NoMeter { capture: CaptureType },
    /// An exhaustive capture without laser sampling.
    #[error(
        "capture_type exhaustive needs nlos_laser_sampling (without it mitransient 1.3.1 files every path under laser point 0)"
    )]
    ExhaustiveWithoutLaserSampling,
    /// An exhaustive capture without the film's laser scan.
    #[error(
        "capture_type exhaustive needs the film's exhaustive_scan with laser_scan_width and laser_scan_height"
    )]
    ExhaustiveWithoutScan,
    /// The film's laser scan with another capture type.
    #[error("the film has exhaustive_scan but capture_type is {}", .capture.name())]
    ScanWithoutExhaustive { capture: CaptureType },
    /// A laser grid (width, height) above [`MAX_GRID_POINTS`].
    #[error(
        "the {}x{} laser grid has more than the {MAX_GRID_POINTS} points tstat prepares",
        .grid[0], .grid[1]
    )]
    LaserGrid { grid: [usize; 2] },
    /// Equal grids asked for, and the laser grid differs from the film's.
    #[error(
        "force_equal_illumination_scanning (the default) needs laser_scan_width x laser_scan_height ({}x{}) equal to the film's {}x{}",
        .laser[0], .laser[1], .film[0], .film[1]
    )]
    UnequalGrids { laser: [usize; 2], film: [usize; 2] },
    /// No ray of the capture meter meets the scene.
    #[error(
        "no ray from sensor_origin towards the relay wall's grid meets the scene: aim the capture meter at its wall"
    )]
    MeterMissesScene,
    /// The laser's axis meets nothing (single capture with laser sampling).
    #[error(
        "nlos_laser_sampling: the laser's axis (its to_world's +z) meets nothing in the scene; aim it at the relay wall"
    )]
    LaserMissesScene,
    /// A laser scan whose emitter has no axes.
    #[error("illumination_scan_fov needs a projector or spot laser")]
    ScanLaserKind,
    /// No ray of the laser scan meets the scene.
    #[error("the laser's scan (illumination_scan_fov) meets nothing in the scene")]
    ScanMissesScene,
    /// Rays of the laser scan that meet nothing: their lit points would not exist
    /// (the bundle records every lit point).
    #[error("{missed} of the laser scan's {total} rays meet nothing (the first is laser point ({}, {})): narrow illumination_scan_fov so that every ray meets the relay wall", .first[0], .first[1])]
    ScanMisses {
        missed: usize,
        total: usize,
        first: [usize; 2],
    },
    /// Hidden-geometry sampling with a shape that has no area (a curve or an SDF grid).
    #[error(
        "nlos_hidden_geometry_sampling samples points on every shape by area; shape '{shape}' (a curve or an SDF grid) has no area to sample"
    )]
    HiddenShapeWithoutArea { shape: String },
    /// Hidden-geometry sampling without any area to sample.
    #[error(
        "nlos_hidden_geometry_sampling: the hidden geometry (every shape but the relay wall) has no area"
    )]
    HiddenGeometryWithoutArea,
}

/// Prepares a `transient_nlos_path` render: checks the emitters and sensor the
/// settings need and computes the lit points and the hidden geometry. `grid` is the
/// sensor grid (the film's width and height before exhaustive stacking).
pub fn prepare(
    settings: &NlosSettings,
    meter: Option<CaptureMeter>,
    grid: [usize; 2],
    shapes: &[Shape],
    emitters: &[Emitter],
    accel: &Accel,
    warn: &mut dyn FnMut(String),
) -> Result<NlosSetup, NlosSetupError> {
    if emitters.len() != 1 {
        return Err(NlosSetupError::EmitterCount {
            emitters: emitters.len(),
        });
    }
    let (laser_origin, axis) = emitters[0].laser_frame().ok_or(NlosSetupError::LaserKind)?;
    if !laser_origin.is_finite() {
        return Err(NlosSetupError::LaserOrigin {
            origin: laser_origin.to_array(),
        });
    }
    let laser_axis = axis.normalize();
    if !laser_axis.is_finite() {
        return Err(NlosSetupError::LaserAxis);
    }
    let capture = settings.capture;
    let points = |[w, h]: [usize; 2]| w.saturating_mul(h);
    if meter.is_some() && points(grid) > MAX_GRID_POINTS {
        return Err(NlosSetupError::MeterGrid { grid });
    }
    if capture != CaptureType::Single && meter.is_none() {
        return Err(NlosSetupError::NoMeter { capture });
    }
    if capture == CaptureType::Exhaustive && !settings.laser_sampling {
        return Err(NlosSetupError::ExhaustiveWithoutLaserSampling);
    }
    let laser_grid = match (capture, meter.as_ref().and_then(|m| m.laser_scan)) {
        (CaptureType::Exhaustive, None) => return Err(NlosSetupError::ExhaustiveWithoutScan),
        (CaptureType::Exhaustive, Some(g)) => g,
        (_, Some(_)) => return Err(NlosSetupError::ScanWithoutExhaustive { capture }),
        (_, None) => [1, 1],
    };
    if points(laser_grid) > MAX_GRID_POINTS {
        return Err(NlosSetupError::LaserGrid { grid: laser_grid });
    }
    if capture == CaptureType::Exhaustive && settings.force_equal_grids && laser_grid != grid {
        return Err(NlosSetupError::UnequalGrids {
            laser: laser_grid,
            film: grid,
        });
    }
    // The points the sensor measures: where its rays first meet the scene (the rays
    // of `Camera::ray`, bit for bit).
    let sensor_hits = match &meter {
        None => Vec::new(),
        Some(m) => {
            let mut out = Vec::with_capacity(grid[0] * grid[1]);
            for y in 0..grid[1] {
                for x in 0..grid[0] {
                    let p = m.wall.grid_point(x, y, grid[0], grid[1]);
                    out.push(first_hit(
                        accel,
                        shapes,
                        Some((&m.wall, m.shape)),
                        m.origin,
                        (p - m.origin).normalize(),
                    ));
                }
            }
            let missed = out.iter().filter(|h| h.is_none()).count();
            if missed == out.len() {
                return Err(NlosSetupError::MeterMissesScene);
            }
            if missed > 0 {
                warn(format!("{missed} of the capture meter's {} rays meet nothing: those points measure nothing and, as lit points, light nothing", out.len()));
            }
            out
        }
    };
    let laser_hits = if !settings.laser_sampling {
        Vec::new()
    } else {
        match capture {
            CaptureType::Single => {
                let wall = meter.as_ref().map(|m| (&m.wall, m.shape));
                let hit = first_hit(accel, shapes, wall, laser_origin, laser_axis)
                    .ok_or(NlosSetupError::LaserMissesScene)?;
                vec![Some(hit)]
            }
            CaptureType::Confocal => sensor_hits.clone(),
            CaptureType::Exhaustive if settings.force_equal_grids => sensor_hits.clone(),
            CaptureType::Exhaustive => scan_targets(
                emitters,
                meter.as_ref().map(|m| (&m.wall, m.shape)),
                settings.illumination_scan_fov,
                laser_grid,
                shapes,
                accel,
            )?,
        }
    };
    let hidden = if settings.hg_sampling {
        let wall = meter.as_ref().map(|m| m.shape);
        let mut ids = Vec::new();
        let mut areas = Vec::new();
        for (i, s) in shapes.iter().enumerate() {
            if Some(i as u32) == wall && !settings.hg_includes_relay_wall {
                continue;
            }
            if matches!(s.geom, ShapeGeom::Curve(_) | ShapeGeom::Sdf(_)) {
                return Err(NlosSetupError::HiddenShapeWithoutArea {
                    shape: s.name.clone(),
                });
            }
            ids.push(i as u32);
            areas.push(s.area());
        }
        let total: f64 = areas.iter().sum();
        if ids.is_empty() || !(total > 0.0 && total.is_finite()) {
            return Err(NlosSetupError::HiddenGeometryWithoutArea);
        }
        let mut acc = 0.0;
        let cdf = areas
            .iter()
            .map(|a| {
                acc += a;
                (acc / total) as f32
            })
            .collect();
        let mut member = vec![false; shapes.len()];
        for &i in &ids {
            member[i as usize] = true;
        }
        Some(HiddenGeometry {
            member,
            samplers: ids
                .iter()
                .map(|&i| AreaSampler::new(&shapes[i as usize]))
                .collect(),
            shapes: ids,
            cdf,
            total_area: total as f32,
        })
    } else {
        None
    };
    let mut setup = NlosSetup {
        laser_origin,
        laser_axis,
        meter,
        sensor_grid: grid,
        laser_grid,
        laser_hits,
        lit_light: Vec::new(),
        sensor_hits,
        hidden,
    };
    // What the laser sends each lit point is the same for every path: found once.
    let focus = capture != CaptureType::Single;
    setup.lit_light = setup
        .laser_hits
        .iter()
        .map(|h| {
            let s = h.as_ref()?.surface;
            laser_light(
                &emitters[0],
                setup.laser_origin,
                setup.laser_axis,
                shapes,
                s.p,
                s.ng,
                focus,
                |o, d, t| accel.occluded(o, d, t),
            )
        })
        .collect();
    Ok(setup)
}

/// Exhaustive scans without equal grids: mitransient aims a projector of
/// `illumination_scan_fov` degrees (on x; its constant irradiance makes it square)
/// with the laser's to_world at the grid (i / Lw, j / Lh), i, j from 0 (the corners
/// of the cells, not their centres, as its `linspace(..., endpoint=False)`): the ray of
/// film point (u, v) leaves along local ((1 - 2u) t, (1 - 2v) t, 1), t = tan(fov / 2)
/// (Mitsuba's `projector.sample_ray`, checked with mitsuba 3.9.1), and lights where
/// it meets the scene.
fn scan_targets(
    emitters: &[Emitter],
    wall: Option<(&Wall, u32)>,
    fov: f64,
    grid: [usize; 2],
    shapes: &[Shape],
    accel: &Accel,
) -> Result<Vec<Option<Hit>>, NlosSetupError> {
    let (origin, axes) = emitters[0]
        .laser_axes()
        .ok_or(NlosSetupError::ScanLaserKind)?;
    let t = (0.5 * fov.to_radians()).tan() as f32;
    let mut out = Vec::with_capacity(grid[0] * grid[1]);
    let mut missed = 0;
    for j in 0..grid[1] {
        for i in 0..grid[0] {
            // Mitsuba's perspective mapping of film point (u, v): u = 0 on local +x.
            let u = i as f32 / grid[0] as f32;
            let v = j as f32 / grid[1] as f32;
            let sx = (1.0 - 2.0 * u) * t;
            let sy = (1.0 - 2.0 * v) * t;
            let d = (axes[0] * sx + axes[1] * sy + axes[2]).normalize();
            let hit = first_hit(accel, shapes, wall, origin, d);
            missed += usize::from(hit.is_none());
            out.push(hit);
        }
    }
    if missed == out.len() {
        return Err(NlosSetupError::ScanMissesScene);
    }
    if let Some(i) = out.iter().position(Option::is_none) {
        return Err(NlosSetupError::ScanMisses {
            missed,
            total: out.len(),
            first: [i % grid[0], i / grid[0]],
        });
    }
    Ok(out)
}
