//! Scenes: Mitsuba 3 XML files (the subset in SPEC 3) turned into a [`Scene`] ready to
//! render. `load` reads and checks the file, applies command-line overrides, and builds
//! the BVH. Every plugin documents its parameters in the file that reads it.

pub mod angular_area;
pub mod bsdfs;
pub mod check;
pub mod ctx;
pub mod curves;
mod emitters;
pub mod error;
pub mod film;
mod fingerprint;
mod fov;
pub mod infinite_emitters;
pub mod instance;
mod integrator;
pub mod limits;
pub mod media;
pub mod mesh;
pub mod mode;
pub mod nlos_setup;
pub mod plugins;
pub mod ply_attributes;
pub mod projector;
pub mod props;
mod sampler;
pub mod sdfgrid;
mod sensors;
pub mod serialized;
mod shape_element;
pub mod shapes;
pub mod spectrum;
pub mod table;
pub mod textures;
pub mod to_world;
mod xml;

use crate::geometry::accel::Accel;
use crate::geometry::shape::Shape;
use crate::lights::Emitter;
use crate::materials::Material;
use crate::sensors::camera::Camera;
use crate::sensors::film::Film;
pub use error::SceneError;
use std::path::{Path, PathBuf};

/// `transient_path` (surfaces only), `transient_prbvolpath` (participating media,
/// `render/volpath.rs`) and `transient_nlos_path` (NLOS captures, `nlos.rs`),
/// mitransient's names; all take these parameters.
///
/// | parameter | type | default | meaning |
/// |-----------|------|---------|---------|
/// | max_depth | integer | 6 (mitransient 1.3.1's default; -1 without an `<integrator>`) | longest path in segments; -1 unbounded, 1 = directly visible emitters only |
/// | rr_depth | integer | 5 | depth from which Russian roulette runs |
/// | hide_emitters | boolean | false | directly visible emitters render black |
/// | camera_unwarp | boolean | false | drop the camera segment from the path's OPL |
/// | discard_direct_light | boolean | false | as `hide_emitters` (mitransient 1.3.1 also drops the BSDF-sampled share of every later emitter hit; tstat keeps it) |
/// | temporal_filter | string | box | `box`, or `gaussian`: each contribution split over the nearby bins (`sensors/time_filter.rs`) |
/// | gaussian_stddev | float | 2.0 | the Gaussian's standard deviation in bins |
/// | temporal_bins, exposure, initial_time, progressive | | | mitransient before 1.0's time window and filter schedule: checked, and the film's window used (a warning) |
/// | samples_per_pass | integer | | Mitsuba's pass size: no effect |
#[derive(Clone, Debug, PartialEq)]
pub struct IntegratorSettings {
    pub max_depth: i32,
    pub rr_depth: u32,
    pub hide_emitters: bool,
    pub camera_unwarp: bool,
    /// `transient_prbvolpath`: the volumetric path tracer (media, null boundaries
    /// transparent to shadow rays).
    pub volumetric: bool,
    /// mitransient's `temporal_filter`: how a contribution reaches the time bins.
    pub time_filter: crate::sensors::time_filter::TimeFilter,
    /// `transient_nlos_path`: the NLOS tracer (`render/nlos/`) and its settings.
    pub nlos: Option<nlos_setup::NlosSettings>,
}

impl Default for IntegratorSettings {
    fn default() -> Self {
        IntegratorSettings {
            max_depth: -1,
            rr_depth: 5,
            hide_emitters: false,
            camera_unwarp: false,
            volumetric: false,
            time_filter: crate::sensors::time_filter::TimeFilter::Box,
            nlos: None,
        }
    }
}

/// Changes to a scene given on the command line.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    /// `-D name=value`: take precedence over the file's `<default>`s.
    pub defaults: Vec<(String, String)>,
    pub spp: Option<u32>,
    /// Changing only one of width/height keeps the aspect ratio.
    pub width: Option<usize>,
    pub height: Option<usize>,
    pub bins: Option<usize>,
    pub start_opl: Option<f64>,
    pub bin_width_opl: Option<f64>,
    pub max_depth: Option<i32>,
    /// `--time-origin`: where camera paths' OPL starts (default: `near_clip` for
    /// cameras; a meter has no near plane, so `near_clip` is refused there).
    pub time_origin: Option<crate::sensors::time_origin::TimeOrigin>,
    /// `-a DIR`: folders searched for the files a scene names, after the scene's own
    /// `<path>`s and folder (Mitsuba's `-a`).
    pub search_paths: Vec<PathBuf>,
    /// `--mode`: what a path carries (`mode.rs`); the scene is refused when the mode
    /// does not model something in it.
    pub mode: mode::RenderMode,
}

pub struct Scene {
    pub file: PathBuf,
    /// SHA-256 of the scene file's bytes, hex.
    pub sha256: String,
    pub camera: Camera,
    pub film: Film,
    pub spp: u32,
    /// The sampler's `seed` parameter (the CLI's `--seed` overrides it).
    pub seed: u64,
    pub integrator: IntegratorSettings,
    /// What a path carries (`mode.rs`): RGB unless `set_mode` says otherwise.
    pub mode: mode::RenderMode,
    pub bsdfs: Vec<Material>,
    pub shapes: Vec<Shape>,
    pub emitters: Vec<Emitter>,
    /// Per emitter, the spectrum its colour was given as (`<spectrum>`), which the
    /// spectral mode uses as given; `None`: an RGB or grey colour, lifted
    /// (`spectral::lift`). Ignored in RGB.
    pub emitter_spectra: Vec<Option<mode::EmitterSpectrum>>,
    /// The environment emitter (`envmap` or `constant`), the one a ray leaving the
    /// scene sees; `None` in scenes without one, where escaping rays end the path.
    pub environment: Option<u32>,
    /// Participating media (shapes' `interior` / `exterior` and `camera_medium` index it).
    pub media: Vec<crate::media::Medium>,
    /// The medium the camera sits in.
    pub camera_medium: Option<u32>,
    /// An NLOS capture's geometry (`transient_nlos_path`), prepared at load.
    pub nlos: Option<nlos_setup::NlosSetup>,
    pub accel: Accel,
    /// Legal but suspicious input (an emitter that contributes nothing, a shape with no
    /// area), one line each as `file:line: <element>: message`. The caller prints them
    /// (as `warning: ...` on stderr); loading goes on.
    pub warnings: Vec<String>,
    /// Every file the scene read besides itself (included files, meshes, images,
    /// volumes, spectra): inputs that no output may replace.
    pub mesh_files: Vec<PathBuf>,
    /// What the render depends on beyond the scene file's bytes: the SHA-256 of each
    /// file in `mesh_files` (by file name, sorted) and the `-D` values. Recorded in the
    /// bundle; `merge` refuses bundles whose identities differ.
    pub identity: SceneIdentity,
}

/// See [`Scene::identity`].
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct SceneIdentity {
    /// (file name, SHA-256 of its bytes), sorted; a file read twice is listed once.
    pub inputs: Vec<(String, String)>,
    /// The command line's `-D name=value`s, sorted by name.
    pub defaults: Vec<(String, String)>,
}

impl Scene {
    /// Reads, checks and prepares a scene for rendering.
    pub fn load(path: &Path, overrides: &Overrides) -> Result<Scene, SceneError> {
        xml::load(path, overrides)
    }

    /// Rows per independent image of the film: an exhaustive NLOS capture stacks one
    /// sensor image per laser point; any other film is one image.
    pub fn image_rows(&self) -> usize {
        match &self.nlos {
            Some(n) if n.laser_grid[0] * n.laser_grid[1] > 1 => n.sensor_grid[1],
            _ => self.film.height,
        }
    }
}
