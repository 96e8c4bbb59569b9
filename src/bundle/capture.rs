//! `nlos` in a bundle's manifest: where an NLOS capture's sensor and laser points lie,
//! so that the bundle alone can be exported (`nlos/tal.rs`) or reconstructed.
//!
//! The film of a capture is the sensor grid (Sx = width columns, Sy rows); an
//! exhaustive capture stacks one such image per laser point: film row `l Sy + sy`
//! is sensor row `sy` lit by laser point `l = ly Lx + lx`. Positions are in scene
//! units.

use crate::scene::nlos_setup::CaptureType;
use crate::scene::Scene;
use crate::sensors::camera::Projection;
use crate::sensors::relay_wall::Wall;
use glam::Vec3;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CaptureRecord {
    pub capture: CaptureType,
    /// (Sx, Sy): the grid of points measured on the relay wall.
    pub sensor_grid: [usize; 2],
    /// (Lx, Ly): 1 x 1 for single and confocal captures.
    pub laser_grid: [usize; 2],
    pub sensor_origin: [f64; 3],
    /// The laser's position; `None` (JSON `null`) when the scene has no positioned
    /// laser (a `transient_path` render with a capture meter and another emitter).
    pub laser_origin: Option<[f64; 3]>,
    /// The relay wall: grid point (sx, sy) is `corner + du (sx + 1/2) / Sx + dv (sy +
    /// 1/2) / Sy`; `normal` its unit normal.
    pub wall_corner: [f64; 3],
    pub wall_du: [f64; 3],
    pub wall_dv: [f64; 3],
    pub wall_normal: [f64; 3],
    /// The lit points, row-major over the laser grid; empty when they are the sensor
    /// grid's points (confocal captures, exhaustive ones with equal grids). `None`
    /// (JSON `null`): not known, in a `transient_path` render whose laser is not
    /// positioned or whose axis meets nothing (a `transient_nlos_path` scene whose
    /// laser or scan misses the scene is refused when it loads).
    pub laser_points: Vec<Option<[f64; 3]>>,
    /// Whether times include the sensor-to-wall and wall-to-laser segments.
    pub account_first_and_last_bounces: bool,
}

fn arr(v: Vec3) -> [f64; 3] {
    v.as_dvec3().to_array()
}

impl CaptureRecord {
    /// The record of a scene whose sensor is an `nlos_capture_meter`; `None` otherwise.
    pub fn of_scene(scene: &Scene) -> Option<CaptureRecord> {
        let Projection::Meter { wall, grid_height } = scene.camera.projection else {
            return None;
        };
        let sensor_grid = [scene.camera.width, grid_height];
        let (capture, laser_grid, laser_origin, laser_points, account) =
            match (&scene.integrator.nlos, &scene.nlos) {
                (Some(n), Some(setup)) => {
                    let equal = n.capture == CaptureType::Confocal
                        || (n.capture == CaptureType::Exhaustive && n.force_equal_grids);
                    let points = if equal {
                        Vec::new()
                    } else {
                        let point =
                            |h: &Option<crate::geometry::accel::Hit>| h.map(|h| arr(h.surface.p));
                        setup.laser_hits.iter().map(point).collect()
                    };
                    (
                        n.capture,
                        setup.laser_grid,
                        Some(arr(setup.laser_origin)),
                        points,
                        n.account_first_and_last_bounces,
                    )
                }
                // `transient_path` with a meter: one laser (if the scene's only
                // emitter is positioned), every segment timed.
                _ => {
                    let frame = match scene.emitters.as_slice() {
                        [e] => e.laser_frame(),
                        _ => None,
                    };
                    let (origin, points) = match frame {
                        Some((o, axis)) => {
                            let hit = scene
                                .accel
                                .intersect(&scene.shapes, o, axis.normalize(), f32::INFINITY)
                                .map(|h| arr(h.surface.p));
                            (Some(arr(o)), vec![hit])
                        }
                        None => (None, vec![None]),
                    };
                    (
                        CaptureType::Single,
                        [1, 1],
                        origin,
                        points,
                        !scene.integrator.camera_unwarp,
                    )
                }
            };
        Some(CaptureRecord {
            capture,
            sensor_grid,
            laser_grid,
            sensor_origin: arr(scene.camera.origin),
            laser_origin,
            wall_corner: arr(wall.corner),
            wall_du: arr(wall.du),
            wall_dv: arr(wall.dv),
            wall_normal: arr(wall.normal),
            laser_points,
            account_first_and_last_bounces: account,
        })
    }

    /// The relay wall as rendered.
    pub fn wall(&self) -> Wall {
        let v = |a: [f64; 3]| glam::DVec3::from_array(a).as_vec3();
        Wall {
            corner: v(self.wall_corner),
            du: v(self.wall_du),
            dv: v(self.wall_dv),
            normal: v(self.wall_normal),
        }
    }

    /// Sensor grid point (sx, sy).
    pub fn sensor_point(&self, sx: usize, sy: usize) -> [f64; 3] {
        let [w, h] = self.sensor_grid;
        let c = glam::DVec3::from_array(self.wall_corner);
        let du = glam::DVec3::from_array(self.wall_du);
        let dv = glam::DVec3::from_array(self.wall_dv);
        (c + du * ((sx as f64 + 0.5) / w as f64) + dv * ((sy as f64 + 0.5) / h as f64)).to_array()
    }

    /// Laser grid point (lx, ly); NaN where it is not known (see `laser_points`).
    pub fn laser_point(&self, lx: usize, ly: usize) -> [f64; 3] {
        if self.laser_points.is_empty() {
            self.sensor_point(lx, ly)
        } else {
            self.laser_points[ly * self.laser_grid[0] + lx].unwrap_or([f64::NAN; 3])
        }
    }

    /// Whether every lit point is known (a reconstruction or an export needs them).
    pub fn lit_points_known(&self) -> bool {
        self.laser_points.iter().all(Option::is_some)
    }

    /// Checks a record read from a manifest against the film it describes.
    pub fn validate(&self, width: usize, height: usize) -> Result<(), super::Problem> {
        use super::Problem;
        let [sx, sy] = self.sensor_grid;
        let [lx, ly] = self.laser_grid;
        let images = lx.checked_mul(ly).ok_or(Problem::LaserGridOverflow)?;
        if sx != width || sy == 0 || sy.checked_mul(images) != Some(height) {
            return Err(Problem::CaptureFilm {
                sensor_grid: self.sensor_grid,
                laser_grid: self.laser_grid,
                width,
                height,
            });
        }
        if self.capture != CaptureType::Exhaustive && images != 1 {
            return Err(Problem::CaptureLasers {
                capture: self.capture.name(),
                laser_grid: self.laser_grid,
            });
        }
        if !self.laser_points.is_empty() && self.laser_points.len() != images {
            return Err(Problem::LaserPoints {
                points: self.laser_points.len(),
                laser_grid: self.laser_grid,
            });
        }
        // Magnitudes, not only finiteness (docs/bundle.md, "Bounds"): a wall of 1e300
        // is finite, and its squared distances are not.
        use super::bounds::{bad_value, check_point, UNIT_TOLERANCE};
        check_point("nlos.sensor_origin", self.sensor_origin)?;
        if let Some(o) = self.laser_origin {
            check_point("nlos.laser_origin", o)?;
        }
        check_point("nlos.wall_corner", self.wall_corner)?;
        check_point("nlos.wall_du", self.wall_du)?;
        check_point("nlos.wall_dv", self.wall_dv)?;
        check_point("nlos.wall_normal", self.wall_normal)?;
        for (i, p) in self.laser_points.iter().enumerate() {
            if let Some(p) = p {
                check_point(&format!("nlos.laser_points[{i}]"), *p)?;
            }
        }
        let len = |v: [f64; 3]| glam::DVec3::from_array(v).length();
        for (at, v) in [
            ("nlos.wall_du", self.wall_du),
            ("nlos.wall_dv", self.wall_dv),
        ] {
            // Finite (checked above): the length is finite too.
            if len(v) == 0.0 {
                return Err(bad_value(
                    format!("|{at}|"),
                    len(v),
                    "the relay wall's edges must have a length",
                ));
            }
        }
        let n = len(self.wall_normal);
        if (n - 1.0).abs() > UNIT_TOLERANCE {
            return Err(bad_value(
                "|nlos.wall_normal|",
                n,
                format!("the relay wall's normal must be a unit vector (within {UNIT_TOLERANCE})"),
            ));
        }
        // The sensor points lie in the wall's parallelogram: with every component
        // below the bound, they are below 3 times it.
        Ok(())
    }
}
