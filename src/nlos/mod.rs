//! What follows an NLOS capture's render (SPEC 11): its export to y-tal's HDF5 capture
//! format (`tal.rs`), the capture in memory in y-tal's terms (`capture.rs`, from a
//! bundle or a y-tal file) and reconstructions of the hidden scene (`bp.rs`, with the phasor-field filter of the
//! filtered backprojection in `filter.rs`; the wave-based confocal ones, f-k migration
//! in `fk.rs` and the light-cone transform in `lct.rs`, on the native grid of `wave.rs`;
//! their FFTs planned by `fft.rs`).
//! Rendering the capture is `scene/nlos_setup.rs` and `render/nlos/`; the bundle records its
//! geometry (`bundle/capture.rs`).

pub mod capture;
pub mod denoised;
pub mod fft;
pub mod filter;
pub mod reconstruct;
pub mod shrink;
pub mod tal;
mod tal_read;

use std::path::PathBuf;

/// Errors of the NLOS layer: captures that cannot be read or exported, and
/// reconstructions that cannot run on a capture (`method` names the reconstruction).
#[derive(Debug, thiserror::Error)]
pub enum NlosError {
    /// Reading the bundle behind a capture.
    #[error(transparent)]
    Bundle(#[from] crate::bundle::BundleError),

    // Captures in memory (`capture.rs`, `denoised.rs`).
    /// A bundle whose manifest has no `nlos` record.
    #[error("{} is not an NLOS capture (its scene's sensor is no nlos_capture_meter)", .0.display())]
    NotACapture(PathBuf),
    #[error("the capture's H does not fit the address space")]
    HOverflow,
    #[error("cannot hold H ({0} values) in memory")]
    HMemory(usize),
    /// A y-tal HDF5 capture that cannot be read.
    #[error("{}: {problem}", .path.display())]
    Tal { path: PathBuf, problem: TalProblem },
    /// A denoised volume that is not of the capture's film, (rows, Sx, T, C).
    #[error("the denoised volume is {shape:?}; the capture's film is ({rows}, {sx}, {bins}, C)")]
    DenoisedShape {
        shape: Vec<usize>,
        rows: usize,
        sx: usize,
        bins: usize,
    },
    #[error("the denoised volume holds non-finite values")]
    DenoisedNotFinite,

    // Exporting a capture (`tal.rs`); the path is the bundle's or the output's.
    #[error("{}: invalid bundle: not an NLOS capture: its scene's sensor is no nlos_capture_meter (y-tal's format holds relay-wall captures)", .0.display())]
    ExportNotACapture(PathBuf),
    #[error("{}: invalid bundle: its times include the laser's segment, but the scene has no positioned laser (a projector or spot) to record as laser_xyz", .0.display())]
    ExportNoLaser(PathBuf),
    /// A capture whose lit points are not known (`CaptureRecord::laser_points`).
    #[error("{}: the capture's lit points are not known (a transient_path render whose laser is not positioned or whose axis meets nothing): it cannot be reconstructed or exported", .0.display())]
    LitPointsUnknown(PathBuf),
    #[error("{}: invalid bundle: H of {values} values does not fit the address space", .dir.display())]
    ExportTooLarge { dir: PathBuf, values: u64 },
    #[error("{}: invalid bundle: {error}", .dir.display())]
    ExportLayout {
        dir: PathBuf,
        error: std::alloc::LayoutError,
    },
    #[error("{}: invalid bundle: cannot reserve {bytes} bytes of address space to lay out H", .dir.display())]
    ExportAddressSpace { dir: PathBuf, bytes: usize },
    /// Writing the output failed (the file system's or the HDF5 writer's error).
    #[error("{}: {}", .0.display(), .1)]
    Write(PathBuf, Box<dyn std::error::Error + Send + Sync>),
    #[error("{}: H was laid out as {layout:?}, not one contiguous block", .path.display())]
    HNotContiguous {
        path: PathBuf,
        layout: hdf5_pure::Layout,
    },

    // Parameters of a reconstruction (`reconstruct.rs`, `pf.rs`, `lct.rs`).
    #[error("wl_mean {wl_mean} and wl_sigma {wl_sigma} must be positive and finite")]
    Wavelengths { wl_mean: f64, wl_sigma: f64 },
    /// A pulse envelope spanning `bins` bins, which would pad each series to `padded`
    /// samples.
    #[error("wl_sigma {wl_sigma} spans {bins:.0} bins: the filter would pad each series to {padded} samples")]
    Envelope {
        wl_sigma: f64,
        bins: f64,
        padded: usize,
    },
    #[error("snr {0}: the signal-to-noise ratio must be positive and finite")]
    Snr(f64),
    #[error("lct: the Wiener filter's signal-to-noise ratio must be a positive number, got {0}")]
    LctSnr(f64),
    #[error("--wl-mean {wl_mean}: the pulse's frequencies lie above the capture's Nyquist frequency (wavelength at least 2 delta_t = {})", 2.0 * .delta_t)]
    Nyquist { wl_mean: f64, delta_t: f64 },

    // Captures the wave-based reconstructions cannot take (`wave.rs`).
    #[error("{method} reconstructs confocal captures only (each sensor point lit by its own laser point)")]
    NotConfocal { method: &'static str },
    #[error("{method} needs times from the wall (bin 0 at OPL 0 on every point); this capture's times include the first and last bounces, which differ from point to point by fractions of a bin")]
    BounceTimes { method: &'static str },
    #[error("{method} needs a square sensor grid of at least 2 x 2 points, got {sx} x {sy}")]
    NotSquare {
        method: &'static str,
        sx: usize,
        sy: usize,
    },
    #[error("{method}: the capture's H ({lasers} laser x {sensors} sensor points) does not match its {n} x {n} grid of {points} points")]
    GridMismatch {
        method: &'static str,
        lasers: usize,
        sensors: usize,
        n: usize,
        points: usize,
    },
    #[error("{method}: H holds {values} values for {bins} bins of {points} points")]
    HLength {
        method: &'static str,
        values: usize,
        bins: usize,
        points: usize,
    },
    #[error("{method} needs at least 2 time bins, got {bins}")]
    TooFewBins { method: &'static str, bins: usize },
    #[error("{method}: the time axis (t_start {t_start}, delta_t {delta_t}) is not finite with a positive bin width")]
    TimeAxis {
        method: &'static str,
        t_start: f64,
        delta_t: f64,
    },
    #[error("{method}: H holds a non-finite value (bin {bin}, point {point})")]
    NonFiniteH {
        method: &'static str,
        bin: usize,
        point: usize,
    },
    #[error("{method}: the sensor grid's points do not span a plane (steps {du:?}, {dv:?})")]
    NotPlanar {
        method: &'static str,
        du: [f64; 3],
        dv: [f64; 3],
    },
    #[error("{method} needs a square grid of square cells; steps {du:?} and {dv:?} are not perpendicular and of one length")]
    NotSquareCells {
        method: &'static str,
        du: [f64; 3],
        dv: [f64; 3],
    },
    #[error("{method} needs a regular planar grid; point ({i}, {j}) lies {off:.3e} from its place on it")]
    Irregular {
        method: &'static str,
        i: usize,
        j: usize,
        off: f64,
    },
    #[error("{method}: the wall normal {normal:?} is not a direction")]
    NormalNotDirection {
        method: &'static str,
        normal: [f64; 3],
    },
    #[error("{method}: the wall normal {normal:?} is not perpendicular to the sensor grid")]
    NormalNotPerpendicular {
        method: &'static str,
        normal: [f64; 3],
    },
    #[error("{method}: t_start is {bins} bins from OPL 0; at most {max} bins can be put in front", max = reconstruct::wave::MAX_DEPTHS)]
    StartTooEarly { method: &'static str, bins: f64 },
    #[error("{method}: the capture starts at OPL {t_start} < 0 and keeps {depths} bins from OPL 0 on; at least 2 are needed")]
    TooFewDepths {
        method: &'static str,
        t_start: f64,
        depths: usize,
    },
    #[error("{method}: {depths} bins from OPL 0 (t_start {t_start} = {pad} bins); at most {max}", max = reconstruct::wave::MAX_DEPTHS)]
    TooManyDepths {
        method: &'static str,
        depths: usize,
        t_start: f64,
        pad: usize,
    },
    #[error("{method}: the padded volume does not fit the address space")]
    PaddedOverflow { method: &'static str },
    /// A buffer (`what`) of `len` complex values that cannot be allocated.
    #[error("cannot hold {what} ({len} complex values, {} MB) in memory", .len.saturating_mul(16) >> 20)]
    Memory { what: &'static str, len: usize },
}

/// Why a y-tal HDF5 capture cannot be read (after "PATH: "); `tal_read.rs` lists
/// the checks.
#[derive(Debug, thiserror::Error)]
pub enum TalProblem {
    #[error("no such capture file")]
    Missing,
    #[error("{0}")]
    Io(std::io::Error),
    /// What the path names instead (`"a FIFO"`, `"a directory"`, ...).
    #[error("not a regular file ({0}); a y-tal capture is an HDF5 file")]
    NotRegular(&'static str),
    #[error("the file is {}, over the memory budget of {} (the HDF5 reader holds the whole file in memory; --max-memory sets the budget)", size_text(*.size), size_text(*.budget))]
    FileTooLarge { size: u64, budget: u64 },
    #[error("the file is truncated: {size} bytes of the {declared} its superblock declares")]
    Truncated { size: u64, declared: u64 },
    #[error("the file changed size while it was read")]
    Changed,
    /// The HDF5 reader's error on `what` (a dataset, or "not an HDF5 file").
    #[error("{what}: {error}")]
    Hdf5 {
        what: String,
        error: hdf5_pure::Error,
    },
    #[error("the HDF5 reader failed (an internal panic) on this file")]
    ReaderPanic,
    #[error("{0}: no such dataset")]
    MissingDataset(String),
    #[error("{name}: shape {shape:?} has more elements than 64 bits count")]
    ShapeOverflow { name: String, shape: Vec<u64> },
    #[error("{name}: shape {shape:?} declares {count} values; at most {max} fit the capture (H's shape)")]
    TooManyValues {
        name: String,
        shape: Vec<u64>,
        count: u64,
        max: u64,
    },
    #[error("{name}: datatype {dtype} is not a number")]
    NotNumbers { name: String, dtype: String },
    /// A dataset whose storage in the file cannot hold what it declares.
    #[error("{name}: its storage does not match its shape: {why}")]
    Storage { name: String, why: String },
    #[error("{name}: HDF5 filter {filter} is not supported (tstat reads deflate/gzip, shuffle and fletcher32)")]
    Filter { name: String, filter: u16 },
    #[error("reading {name} would take {} with the file and what was read before, over the memory budget of {} (--max-memory sets it)", size_text(*.bytes), size_text(*.budget))]
    OverBudget {
        name: String,
        bytes: u64,
        budget: u64,
    },
    #[error("{name}: {values} values read for shape {shape:?}")]
    ValueCount {
        name: String,
        values: usize,
        shape: Vec<u64>,
    },
    #[error("{0}: not one value")]
    NotAScalar(String),
    #[error("H of shape {shape:?} (H_format {format:?}): tstat reads T_Sx_Sy (1) and T_Lx_Ly_Sx_Sy (2) captures")]
    HFormat {
        shape: Vec<u64>,
        format: Option<f64>,
    },
    #[error("H of shape {0:?} is empty")]
    EmptyH(Vec<u64>),
    #[error("{name} of shape {shape:?} is not a grid of 3D points (X_Y_3 or N_3)")]
    Points { name: String, shape: Vec<u64> },
    #[error("{name} of shape {shape:?} is not one 3D point")]
    NotAPoint { name: String, shape: Vec<u64> },
    #[error("{got} sensor grid points for the {want} of H's shape {shape:?}")]
    SensorPoints {
        got: u64,
        want: usize,
        shape: Vec<u64>,
    },
    #[error("{got} laser grid points for the {want} of H's shape {shape:?}")]
    LaserPoints {
        got: u64,
        want: usize,
        shape: Vec<u64>,
    },
    /// A value that is not finite or too large, named by its index.
    #[error("{name} ({at}) is {what}")]
    BadValue {
        name: String,
        at: String,
        what: String,
    },
    #[error("{0} is not a finite number")]
    NotFinite(String),
    #[error("{what} is {value:e}, beyond {max:e} in magnitude")]
    TooLarge { what: String, value: f64, max: f64 },
    #[error("delta_t must be positive, got {0}")]
    DeltaT(f64),
    #[error("delta_t {delta_t:e} is too small for the capture's extent {extent:e}: more than {max:e} bins")]
    BinsTooSmall { delta_t: f64, extent: f64, max: f64 },
    #[error("sensor_grid_normals is not a grid of non-zero normals")]
    Normals,
    #[error("t_accounts_first_and_last_bounces is {0}, not a boolean")]
    NotABool(f64),
    #[error(
        "its times include the first and last bounces, but laser_xyz or sensor_xyz is missing"
    )]
    NoOrigins,
}

/// A byte count for messages: "2.40 GB", "3.86 MB", "12.4 kB".
fn size_text(b: u64) -> String {
    let b = b as f64;
    if b >= 1e9 {
        format!("{:.2} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.2} MB", b / 1e6)
    } else {
        format!("{:.1} kB", b / 1e3)
    }
}
