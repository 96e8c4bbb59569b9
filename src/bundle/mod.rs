//! The statistics bundle on disk (SPEC 9): a directory with `manifest.json` and NumPy
//! arrays. The only interface between rendering and everything after it.

pub mod bounds;
pub mod capture;
pub mod estimates;
pub mod float_rows;
pub mod manifest;
pub mod merge;
pub mod npy;
pub mod published;
pub mod read;
pub mod shard;
pub mod write;

pub use manifest::Manifest;
pub use read::{Bundle, RowReader, RowSums, SumArray};
use std::path::PathBuf;

/// Errors of the bundle layer: reading, validating, writing and merging bundles, and
/// the `--shard` argument. Each names the file or directory it concerns, or the
/// argument.
#[derive(Debug, thiserror::Error)]
pub enum BundleError {
    #[error("{}: already exists (use --force to replace it)", .0.display())]
    Exists(PathBuf),
    /// Reading or writing the path failed: the file system's error, or an encoder's
    /// (kept whole, but not as a `source`: the message already says it).
    #[error("{}: {}", .0.display(), .1)]
    Io(PathBuf, Box<dyn std::error::Error + Send + Sync>),
    /// An output whose parent directory does not exist.
    #[error("{}: the directory {} does not exist", .0.display(), .1.display())]
    NoParent(PathBuf, PathBuf),
    /// An output path without a file name (e.g. `..`).
    #[error("{}: not a file name", .0.display())]
    NotAFileName(PathBuf),
    /// `merge` with fewer than two inputs (the path is the output).
    #[error("{}: merge needs at least two bundles", .0.display())]
    TooFewToMerge(PathBuf),
    /// A band of rows of the wrong size for an array being streamed (refused rather
    /// than written over its neighbours).
    #[error("{}: a row of {len} bytes, expected {want} ({rows} rows of {row_bytes})", path.display())]
    RowSize {
        path: PathBuf,
        len: usize,
        want: u64,
        rows: usize,
        row_bytes: u64,
    },
    /// A band of rows with other arrays than the bundle being streamed (the path is
    /// its directory).
    #[error("{}: a row's arrays do not match the bundle's (transform)", .0.display())]
    RowArrays(PathBuf),
    /// A streamed render finished without every row (the path is the staged directory).
    #[error("{}: the render did not deliver every row of this film", .0.display())]
    Incomplete(PathBuf),
    /// The file or directory is not a bundle, or not a valid one, and why.
    #[error("{}: invalid bundle: {}", .0.display(), .1)]
    Invalid(PathBuf, Box<Problem>),
    /// A manifest the reader would refuse, refused before it is written (the path is
    /// the bundle to be written): the same check as reading ([`read::manifest_json`]).
    #[error("{}: refusing to write a bundle that could not be read back: {}", .0.display(), .1)]
    Unwritable(PathBuf, Box<Problem>),
    /// The `--shard` argument ([`shard::Shard::parse`], [`shard::Shard::share`]).
    #[error(transparent)]
    Shard(#[from] shard::ShardError),
}

impl BundleError {
    /// [`BundleError::Invalid`] of `path`.
    pub fn invalid(path: impl Into<PathBuf>, problem: Problem) -> Self {
        BundleError::Invalid(path.into(), Box::new(problem))
    }

    /// [`BundleError::Io`] of `path`.
    pub fn io(
        path: impl Into<PathBuf>,
        e: impl Into<Box<dyn std::error::Error + Send + Sync>>,
    ) -> Self {
        BundleError::Io(path.into(), e.into())
    }
}

/// What makes a bundle invalid (after "PATH: invalid bundle: "), or a set of bundles
/// unmergeable.
#[derive(Debug, thiserror::Error)]
pub enum Problem {
    // The directory and its manifest.
    #[error("not a bundle directory (a bundle is a directory holding manifest.json)")]
    NotADirectory,
    #[error("no such bundle directory")]
    NoSuchDirectory,
    #[error("cannot read: {0}")]
    Unreadable(crate::io::ReadError),
    #[error("not valid JSON: {}", short(.0))]
    NotJson(serde_json::Error),
    #[error("not a '{format}' manifest", format = manifest::FORMAT)]
    NotThisFormat,
    /// `found`: the manifest's version as JSON, or "missing".
    #[error("format version {} is not a supported version ({uniform} for uniform sampling, {version} for adaptive)", clip(.found), uniform = manifest::VERSION_UNIFORM, version = manifest::VERSION)]
    Version { found: String },
    /// A string holding a control character: where (a JSON path) and its code point.
    #[error("the text at {} holds the control character U+{code:04X} (a manifest's strings are printed as they are)", clip(.at))]
    ControlCharacter { at: String, code: u32 },
    #[error("bad manifest: {}", short(.0))]
    BadManifest(serde_json::Error),

    // The manifest's fields (see `read::validate`).
    #[error("transform: {0}")]
    Transform(crate::stats::StatsError),
    #[error("time origin: {0}")]
    TimeOrigin(String),
    #[error("adaptive record: {0}")]
    Adaptive(String),
    #[error("pixel_spp.npy sums to {sum} over {pixels} pixels (the manifest's spp {spp} each), from {lo} to {hi} samples a pixel: it does not match the manifest")]
    PixelSpp {
        sum: u64,
        spp: u64,
        pixels: u64,
        lo: u64,
        hi: u64,
    },
    #[error("empty film size ({width} x {height} px, {bins} bins)")]
    EmptyFilm {
        width: usize,
        height: usize,
        bins: usize,
    },
    #[error("film size {width} x {height} px x {bins} bins overflows the address space")]
    FilmOverflow {
        width: usize,
        height: usize,
        bins: usize,
    },
    #[error("nlos.laser_grid overflows")]
    LaserGridOverflow,
    #[error("nlos: a {}x{} sensor grid with a {}x{} laser grid does not make a film of {width}x{height}", .sensor_grid[0], .sensor_grid[1], .laser_grid[0], .laser_grid[1])]
    CaptureFilm {
        sensor_grid: [usize; 2],
        laser_grid: [usize; 2],
        width: usize,
        height: usize,
    },
    #[error("nlos: a {capture} capture has one laser point, not {}x{}", .laser_grid[0], .laser_grid[1])]
    CaptureLasers {
        capture: &'static str,
        laser_grid: [usize; 2],
    },
    #[error("nlos: {points} laser points for a {}x{} laser grid", .laser_grid[0], .laser_grid[1])]
    LaserPoints {
        points: usize,
        laser_grid: [usize; 2],
    },
    /// A number out of its range: where (a manifest field), the value and the rule
    /// (see `read::validate` and docs/bundle.md, "Bounds").
    #[error("{at} = {value}: {rule}")]
    Value {
        at: String,
        value: String,
        rule: String,
    },
    /// `channels`, shown shortened.
    #[error("channels {0}: a bundle of mode {1} holds [\"{2}\"]")]
    Channels(String, &'static str, String),
    #[error("scene.sha256 {0:?} is not a SHA-256 (64 hexadecimal digits); merge compares it")]
    SceneHash(String),
    #[error("{0}")]
    Spp(crate::stats::StatsError),
    #[error(
        "replicates = {replicates} with spp = {spp}: replicates are at least 2 and divide spp"
    )]
    Replicates { replicates: u64, spp: u64 },
    /// The seconds do not restate the OPL axis; `start` and `bin_width` are the
    /// seconds the OPL axis gives.
    #[error("start_seconds = {start_seconds} and bin_width_seconds = {bin_width_seconds} do not restate start_opl and bin_width_opl in seconds ({start} and {bin_width} at unit_m = {unit_m})")]
    Seconds {
        start_seconds: f64,
        bin_width_seconds: f64,
        start: f64,
        bin_width: f64,
        unit_m: f64,
    },
    #[error("render_seconds = {0} is not a duration")]
    RenderSeconds(f64),
    #[error("max_depth = {0} (-1 means unbounded)")]
    MaxDepth(i32),
    #[error("merged_seeds lists seed {0} twice")]
    MergedSeedTwice(u64),
    /// More merged renders than the spp allows (each render has at least 2 samples).
    #[error("merged_seeds lists {len} seeds, but spp = {spp} holds at most {} renders of at least 2 samples each", .spp / 2)]
    MergedSeedsTooMany { len: usize, spp: u64 },
    /// A `shard` record that breaks a rule: which one.
    #[error("shard: {0} (a shard record has a 16-digit hexadecimal job, a count from 1 to 2^32 and increasing indices below count)")]
    ShardRecord(String),
    /// A scene identity list (`inputs` or `defaults`) naming an entry twice.
    #[error("scene.identity.{list} lists '{}' twice", clip(.name))]
    IdentityTwice { list: &'static str, name: String },
    /// A manifest too large for the reader's limit (`io::MAX_MANIFEST_BYTES`).
    #[error("the manifest is {bytes} bytes, above the limit of {limit} bytes for manifests")]
    ManifestTooLarge { bytes: usize, limit: u64 },
    /// A manifest that does not read back as the one written (never expected: every
    /// field round-trips through JSON exactly).
    #[error("the manifest does not read back as written")]
    NotRoundTrip,

    // The arrays.
    #[error("lists the array '{}' twice", clip(.0))]
    ArrayTwice(String),
    #[error("lists {0} arrays; a bundle has at most {max}", max = read::MAX_ARRAYS)]
    TooManyArrays(usize),
    #[error("lists '{name}' with {dims} dimensions; an array has at most {max}", max = read::MAX_DIMS)]
    TooManyDims { name: String, dims: usize },
    #[error("lists '{name}' as {:?} {shape:?}; the film's sizes need {want_dtype:?} {want_shape:?}", clip(.dtype))]
    ArrayListing {
        name: &'static str,
        dtype: String,
        shape: Vec<usize>,
        want_dtype: &'static str,
        want_shape: Vec<usize>,
    },
    #[error("the arrays '{other}' and '{name}' are both in {}", .file.display())]
    SharedFile {
        other: &'static str,
        name: &'static str,
        file: PathBuf,
    },
    #[error("lists no array '{0}'")]
    NoArray(String),
    #[error("array '{name}' is in {:?}, which is not a file name inside the bundle", clip(.file))]
    ArrayFile { name: String, file: String },
    #[error("missing")]
    Missing,
    #[error("leads outside the bundle (to {}); a bundle's arrays live in its directory", .0.display())]
    Outside(PathBuf),
    /// The `.npy` file, its header or a value in it.
    #[error("{0}")]
    Npy(npy::NpyError),
    #[error("dtype {:?} is not the format's {want:?}", clip(.found))]
    HeaderDtype { found: String, want: String },
    #[error("shape {found:?} does not match the manifest's {want:?}")]
    HeaderShape { found: Vec<usize>, want: Vec<usize> },
    /// A value the f32 of an export cannot hold (`tstat export --steady`).
    #[error("steady value {value:e} at row {y}, column {x}, channel {c} does not fit in f32 (the export's type)")]
    SteadyBeyondF32 {
        value: f64,
        y: usize,
        x: usize,
        c: usize,
    },

    // Merging (the path is the bundle that does not fit, or the output).
    #[error("voxel (y {y}, x {x}, t {t}): the merged count exceeds the u32 range of nonzero.npy")]
    CountOverflow { y: usize, x: usize, t: usize },
    /// A setting (`what`) that differs from the first bundle's.
    #[error("its {0} differs from the first bundle's")]
    SettingDiffers(&'static str),
    /// Replicates of other sizes (samples per replicate; `None`: no replicates).
    #[error("it has {} where the first bundle has {}: only bundles with replicates of equal size (or none) merge", show_replicates(.it), show_replicates(.first))]
    ReplicateSizes { it: Option<u64>, first: Option<u64> },
    /// A `-D` value that differs from the first bundle's (`None`: unset).
    #[error("it was rendered with -D {} {} where the first bundle has {}", clip(.key), show_define(.it), show_define(.first))]
    Define {
        key: String,
        it: Option<String>,
        first: Option<String>,
    },
    #[error("the scene's file '{}' (an include, mesh, image, volume or spectrum) differs from the first bundle's, or only one of them read it", clip(.0))]
    SceneInput(String),
    /// Shards of a job missing, repeated, or of other jobs.
    #[error("{0}")]
    Shards(shard::ShardError),
    #[error("seed {0} appears twice: merging would count the same paths twice")]
    SeedTwice(u64),
    #[error("the merged spp would overflow a 64-bit count")]
    SppOverflow,
}

/// A JSON error, shortened: serde's messages quote the offending value, which in a
/// hostile manifest may be a string of megabytes.
fn short(e: &serde_json::Error) -> String {
    const MAX: usize = 200;
    let s = e.to_string();
    if s.len() <= MAX {
        return s;
    }
    let cut = (0..=MAX)
        .rev()
        .find(|&i| s.is_char_boundary(i))
        .unwrap_or(0);
    format!(
        "{}... (at line {}, column {})",
        &s[..cut],
        e.line(),
        e.column()
    )
}

fn show_replicates(size: &Option<u64>) -> String {
    match size {
        Some(k) => format!("replicates of {k} samples"),
        None => "no replicates".to_string(),
    }
}

fn show_define(v: &Option<String>) -> String {
    v.as_ref()
        .map_or("unset".to_string(), |v| format!("'{}'", clip(v)))
}

/// Text from a manifest, shortened for a message (a hostile manifest may hold strings
/// of megabytes): at most 80 characters, then "...".
pub(crate) fn clip(s: &str) -> String {
    const MAX: usize = 80;
    match s.char_indices().nth(MAX) {
        None => s.to_string(),
        Some((i, _)) => format!("{}...", &s[..i]),
    }
}
