//! Reading a bundle that may be damaged or hostile. Three layers of checks, each
//! refusing with one line that names the file:
//!
//! 1. [`Bundle::open`]: the directory is a directory; `manifest.json` is a regular file
//!    of at most [`MAX_MANIFEST_BYTES`](crate::io::MAX_MANIFEST_BYTES), of this format
//!    and version, with valid fields (see [`validate`]); every array the format needs
//!    is listed once, with the dtype and shape the manifest's sizes imply, in a file
//!    that lies inside the bundle directory (no absolute paths, `..` or links leading
//!    out); and every such file's `.npy` header agrees with the manifest and with the
//!    file's size (so `info` refuses a truncated bundle, and nothing later allocates
//!    what a header merely claims); the per-pixel arrays (G-buffers, steady image,
//!    at most H x W x 3 values) are read and checked whole.
//! 2. Each array read checks its header again (the file may have changed), then its
//!    values, in the same pass that reads them (see [`Bundle::sum_array`] and the
//!    G-buffer readers); the first bad value is named by its voxel. The counts and
//!    sums can also be read a band of image rows at a time ([`Bundle::row_reader`],
//!    for denoising in bounded memory), with the same checks and messages.
//! 3. Cross-array rules that need the counts (a sum where no sample landed) are
//!    checked against `nonzero.npy`, which the readers of sums take as an argument.
//!
//! What is an error and what is not. Everything a correct render or merge can never
//! write is an error, because loading it would silently turn into wrong output:
//! - any NaN or infinity (SPEC 4: non-finite contributions never reach a sum; f32
//!   contributions cannot overflow the f64 sums of their cubes). One render does
//!   write infinities: Box-Cox with lambda so small that z(0)^2 = lambda^-2
//!   overflows (e.g. 1e-200, in a voxel where one channel is 0); its sums hold no
//!   information, and it is refused here naming the voxel;
//! - a negative `X2` (a sum of squares), a negative raw radiance sum `S`, steady image,
//!   albedo, depth or emitter fraction (radiance and reflectance are non-negative;
//!   the scene loader refuses negative ones);
//! - a negative `X1` or `X3` when `z(0) = 0` (identity, Yeo-Johnson: `z(x) >= 0` for
//!   `x >= 0`); under Box-Cox `z` ranges down to `-1/lambda`, so they may be negative;
//!   in a spectral bundle (`Manifest::signed_samples`) samples, sums and the steady
//!   image may be negative (a path's sRGB is signed);
//! - a radiance sum S (X1 under the identity) whose mean S / spp overflows f32, the
//!   type of every volume the bundle becomes (the filter turned it into infinities);
//! - a count above spp (a path adds at most one sample to a voxel, SPEC 4);
//! - a non-zero sum in a voxel whose count is 0 (sums are over the samples counted);
//! - a normal component outside [-1, 1] or an emitter fraction above 1 (beyond f32
//!   rounding of a renormalised or spp-weighted mean).
//!
//! Nothing is merely warned about: every rule above is a hard invariant of the
//! writer, and the legal-but-unusual (a voxel no path reached, a pixel that sees
//! nothing, unknown extra manifest fields, which are ignored for forward
//! compatibility) loads silently.

use super::bounds::{bad_value, check_magnitude, show_f64, MAX_MAGNITUDE};
use super::manifest::{
    ArrayInfo, Manifest, TimeOrigin, C_M_PER_S, FORMAT, VERSION, VERSION_UNIFORM,
};
use super::npy::{self, first_bad, show, Element};
use super::shard::MAX_SHARDS;
use super::{BundleError, Problem};
use crate::stats::estimators::check_spp;
use ndarray::{Array, Array2, Array3, Array4, Dimension, IntoDimension};
use std::path::{Path, PathBuf};

pub struct Bundle {
    pub dir: PathBuf,
    pub manifest: Manifest,
    /// Samples of each pixel (row-major, H x W) of an adaptive render (checked: each
    /// at least 2 and a multiple of the replicates, summing to spp x H x W); `None`:
    /// every pixel has `manifest.spp`.
    pub pixel_spp: Option<Vec<u32>>,
}

/// The four sum arrays of SPEC 5.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SumArray {
    X1,
    X2,
    X3,
    /// Raw radiance sums S (X1 itself for the identity transform).
    Radiance,
    /// Replicate statistics R2 = sum_b m_b^2 (bundles with replicates).
    R2,
}

const AXES4: [&str; 4] = ["y", "x", "t", "c"];
const AXES3T: [&str; 3] = ["y", "x", "t"];
const AXES3C: [&str; 3] = ["y", "x", "c"];
const AXES2: [&str; 2] = ["y", "x"];

/// Slack for f32 rounding of unit-range G-buffer values (normals renormalised in f64
/// and cast, spp-weighted means of fractions).
const UNIT_SLACK: f64 = 1e-3;

/// The arrays a bundle of this manifest must hold: name, dtype, shape.
pub fn required_arrays(m: &Manifest) -> Vec<(&'static str, &'static str, Vec<usize>)> {
    let (h, w, t) = (m.height, m.width, m.bins);
    let c = m.channel_count();
    let s4 = vec![h, w, t, c];
    let mut v = vec![
        ("x1", f64::DTYPE, s4.clone()),
        ("x2", f64::DTYPE, s4.clone()),
        ("x3", f64::DTYPE, s4.clone()),
    ];
    if !m.transform.is_identity() {
        v.push(("sum", f64::DTYPE, s4.clone()));
    }
    if m.replicates.is_some() {
        v.push(("r2", f64::DTYPE, s4));
    }
    v.extend([
        ("nonzero", u32::DTYPE, vec![h, w, t]),
        ("albedo", f32::DTYPE, vec![h, w, 3]),
        ("normal", f32::DTYPE, vec![h, w, 3]),
        ("depth", f32::DTYPE, vec![h, w]),
        ("emitter", f32::DTYPE, vec![h, w]),
        ("steady", f64::DTYPE, vec![h, w, c]),
    ]);
    if m.media {
        v.push(("medium", f32::DTYPE, vec![h, w]));
    }
    if m.adaptive.is_some() {
        v.push(("pixel_spp", u32::DTYPE, vec![h, w]));
    }
    v
}

/// The most entries `arrays` may list: the format has 12 arrays (unknown entries are
/// ignored, for forward compatibility, but not without bound).
pub const MAX_ARRAYS: usize = 64;

/// The most dimensions of a listed array (NumPy's own limit is 64; the format uses 4).
pub const MAX_DIMS: usize = 32;

/// The first value of `v` that occurs twice, in O(n log n) time (a sorted copy).
pub(crate) fn first_repeated<T: Ord + Clone>(v: &[T]) -> Option<T> {
    let mut sorted = v.to_vec();
    sorted.sort_unstable();
    sorted
        .windows(2)
        .find(|w| w[0] == w[1])
        .map(|w| w[0].clone())
}

/// `channels` shortened for a message (a hostile list may be long).
fn show_channels(c: &[String]) -> String {
    let shown: Vec<String> = c.iter().take(4).map(|s| format!("{s:?}")).collect();
    let more = if c.len() > 4 {
        format!(", ... ({} in all)", c.len())
    } else {
        String::new()
    };
    format!("[{}{more}]", shown.join(", "))
}

/// Whether every voxel of `block` (C channels each, counts from `counts`) holds values
/// that pass `ok`, and zeros where no sample reached it unless `any_empty`; branch-free.
#[inline(always)]
fn voxels_ok<const C: usize>(
    block: &[f64],
    counts: &[u32],
    ok: impl Fn(f64) -> bool,
    any_empty: bool,
) -> bool {
    let (voxels, _) = block.as_chunks::<C>();
    voxels.iter().zip(counts).fold(true, |acc, (v, &k)| {
        let all_ok = v.iter().fold(true, |a, &x| a & ok(x));
        let zero = v.iter().fold(true, |a, &x| a & (x == 0.0));
        acc & all_ok & ((k != 0) | any_empty | zero)
    })
}

/// The manifest's own fields (after the format and version are known): sizes,
/// sample count, time axis, transform, capture geometry, lists, metadata. The error is
/// a short reason. Every check is linear (or n log n) in the length of any list, so a
/// manifest of [`crate::io::MAX_MANIFEST_BYTES`] is checked in well under a second.
///
/// Reading ([`Bundle::open`]) and writing ([`manifest_json`], which every writer of a
/// manifest calls, and `write::check_render`, before a render starts) share it: what
/// is written can be read back.
pub fn validate(m: &Manifest) -> Result<(), Problem> {
    m.transform.validate().map_err(Problem::Transform)?;
    if m.width == 0 || m.height == 0 || m.bins == 0 {
        return Err(Problem::EmptyFilm {
            width: m.width,
            height: m.height,
            bins: m.bins,
        });
    }
    // The largest array, in bytes, must be addressable (and the element count of
    // every array is a factor of it).
    [m.height, m.width, m.bins, m.channel_count(), 8]
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .filter(|&b| b <= isize::MAX as usize)
        .ok_or(Problem::FilmOverflow {
            width: m.width,
            height: m.height,
            bins: m.bins,
        })?;
    if let Some(n) = &m.nlos {
        n.validate(m.width, m.height)?;
    }
    if m.channels != m.mode.channel_names() {
        return Err(Problem::Channels(
            show_channels(&m.channels),
            m.mode.name(),
            m.mode.channel_names().join("\", \""),
        ));
    }
    let sha = &m.scene.sha256;
    if sha.len() != 64 || !sha.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(Problem::SceneHash(sha.chars().take(80).collect()));
    }
    if let Some(id) = &m.scene.identity {
        let names = |l: &[(String, String)]| l.iter().map(|(k, _)| k.clone()).collect::<Vec<_>>();
        if let Some(name) = first_repeated(&names(&id.inputs)) {
            return Err(Problem::IdentityTwice {
                list: "inputs",
                name,
            });
        }
        if let Some(name) = first_repeated(&names(&id.defaults)) {
            return Err(Problem::IdentityTwice {
                list: "defaults",
                name,
            });
        }
    }
    check_spp(m.spp).map_err(Problem::Spp)?;
    if let Some(b) = m.replicates {
        if b < 2 || !m.spp.is_multiple_of(b) {
            return Err(Problem::Replicates {
                replicates: b,
                spp: m.spp,
            });
        }
    }
    check_time_axis(m)?;
    check_time_origin(m)?;
    let adaptive_version = if m.adaptive.is_some() {
        VERSION
    } else {
        VERSION_UNIFORM
    };
    if m.version != adaptive_version {
        return Err(Problem::Version {
            found: format!(
                "{} ({} adaptive record)",
                m.version,
                if m.adaptive.is_some() {
                    "with an"
                } else {
                    "without an"
                }
            ),
        });
    }
    if let Some(a) = &m.adaptive {
        let counts = a.pilot_spp >= 2 && a.min_spp >= 2 && a.min_spp <= m.spp && m.spp <= a.max_spp;
        let finite = |v: f64| (0.0..MAX_MAGNITUDE).contains(&v);
        let goal = a.goal.as_ref().is_none_or(|g| {
            matches!(g.kind.as_str(), "time_budget_seconds" | "target_error")
                && finite(g.value)
                && g.value > 0.0
                && finite(g.predicted_error)
        });
        if !(counts && finite(a.pilot_seconds) && goal && a.estimated_error.is_none_or(finite)) {
            return Err(Problem::Adaptive(format!(
                "pilot_spp {}, min_spp {}, max_spp {}, pilot_seconds {} (need pilot_spp >= 2, 2 <= min_spp <= spp = {} <= max_spp, seconds >= 0)",
                a.pilot_spp, a.min_spp, a.max_spp, show_f64(a.pilot_seconds), m.spp
            )));
        }
    }
    if let Some(s) = m.time_filter_stddev_bins {
        if !(s > 0.0 && s < MAX_MAGNITUDE) {
            return Err(bad_value(
                "time_filter_stddev_bins",
                s,
                format!("must be positive, finite and below {MAX_MAGNITUDE:e} bins"),
            ));
        }
    }
    if !(m.render_seconds.is_finite() && m.render_seconds >= 0.0) {
        return Err(Problem::RenderSeconds(m.render_seconds));
    }
    if m.max_depth < -1 {
        return Err(Problem::MaxDepth(m.max_depth));
    }
    if let Some(s) = first_repeated(&m.merged_seeds) {
        return Err(Problem::MergedSeedTwice(s));
    }
    // Every merged render has at least 2 samples: that bounds the list.
    if m.merged_seeds.len() as u64 > m.spp / 2 {
        return Err(Problem::MergedSeedsTooMany {
            len: m.merged_seeds.len(),
            spp: m.spp,
        });
    }
    if let Some(s) = &m.shard {
        check_shard_record(s)?;
    }
    if m.arrays.len() > MAX_ARRAYS {
        return Err(Problem::TooManyArrays(m.arrays.len()));
    }
    if let Some(a) = m.arrays.iter().find(|a| a.shape.len() > MAX_DIMS) {
        return Err(Problem::TooManyDims {
            name: a.name.chars().take(80).collect(),
            dims: a.shape.len(),
        });
    }
    let names: Vec<&str> = m.arrays.iter().map(|a| a.name.as_str()).collect();
    if let Some(name) = first_repeated(&names) {
        return Err(Problem::ArrayTwice(name.to_string()));
    }
    Ok(())
}

/// The time axis: `unit_m`, `start_opl`, `bin_width_opl` and the bins' end (see
/// docs/bundle.md, "Bounds"), and the seconds that restate them.
fn check_time_axis(m: &Manifest) -> Result<(), Problem> {
    if !(m.unit_m > 0.0 && m.unit_m < MAX_MAGNITUDE) {
        return Err(bad_value(
            "unit_m",
            m.unit_m,
            format!("metres per scene unit must be positive, finite and below {MAX_MAGNITUDE:e}"),
        ));
    }
    check_magnitude("start_opl", m.start_opl)?;
    if !(m.bin_width_opl > 0.0 && m.bin_width_opl < MAX_MAGNITUDE) {
        return Err(bad_value(
            "bin_width_opl",
            m.bin_width_opl,
            format!("must be positive, finite and below {MAX_MAGNITUDE:e} scene units"),
        ));
    }
    // The end of the last bin: finite, bounded, and the first bin not lost to
    // rounding (start + width > start).
    let end = m.start_opl + m.bins as f64 * m.bin_width_opl;
    if !(end.is_finite() && end.abs() < MAX_MAGNITUDE) {
        return Err(bad_value(
            "start_opl + bins * bin_width_opl",
            end,
            format!(
                "the end of the last bin must be of magnitude below {MAX_MAGNITUDE:e} scene units"
            ),
        ));
    }
    if m.start_opl + m.bin_width_opl <= m.start_opl {
        return Err(bad_value(
            "bin_width_opl",
            m.bin_width_opl,
            format!(
                "too small to be added to start_opl = {} (the bins would not be distinct)",
                show_f64(m.start_opl)
            ),
        ));
    }
    // The seconds are derived (opl * unit_m / c); `info` shows them, so they must
    // agree with the OPL axis they restate.
    let seconds = |opl: f64| opl * m.unit_m / C_M_PER_S;
    let agrees = |s: f64, opl: f64| {
        s.is_finite()
            && (s - seconds(opl)).abs() <= 1e-9 * seconds(opl).abs().max(seconds(m.bin_width_opl))
    };
    if !(agrees(m.start_seconds, m.start_opl) && agrees(m.bin_width_seconds, m.bin_width_opl)) {
        return Err(Problem::Seconds {
            start_seconds: m.start_seconds,
            bin_width_seconds: m.bin_width_seconds,
            start: seconds(m.start_opl),
            bin_width: seconds(m.bin_width_opl),
            unit_m: m.unit_m,
        });
    }
    Ok(())
}

/// `time_origin` and `near_clip`: a near-clip distance (positive, bounded) exactly when
/// the origin is the near-clip plane, and never for an NLOS capture (its meter has no
/// near plane).
fn check_time_origin(m: &Manifest) -> Result<(), Problem> {
    match (m.time_origin, m.near_clip) {
        (TimeOrigin::NearClip, Some(d)) if m.nlos.is_some() => Err(bad_value(
            "near_clip",
            d,
            "an NLOS capture has no near plane (its time_origin is pinhole)",
        )),
        (TimeOrigin::NearClip, Some(d)) if !(d > 0.0 && d < MAX_MAGNITUDE) => Err(bad_value(
            "near_clip",
            d,
            format!("must be positive, finite and below {MAX_MAGNITUDE:e} scene units"),
        )),
        (TimeOrigin::NearClip, Some(_)) | (TimeOrigin::Pinhole, None) => Ok(()),
        (TimeOrigin::NearClip, None) => Err(Problem::TimeOrigin(
            "time_origin near_clip without a near_clip distance".into(),
        )),
        (TimeOrigin::Pinhole, Some(_)) => Err(Problem::TimeOrigin(
            "near_clip given with time_origin pinhole (which ignores it)".into(),
        )),
    }
}

/// A bundle's `shard` record: a 16-digit hexadecimal job, a count from 1 to
/// [`MAX_SHARDS`], and strictly increasing indices below count (so at most count of
/// them, and no index twice), in linear time.
pub fn check_shard_record(s: &super::shard::ShardRecord) -> Result<(), Problem> {
    let why = if !(s.job.len() == 16 && s.job.bytes().all(|b| b.is_ascii_hexdigit())) {
        format!(
            "job {:?} is not 16 hexadecimal digits",
            s.job.chars().take(40).collect::<String>()
        )
    } else if s.count == 0 || s.count > MAX_SHARDS {
        format!("count {} is not from 1 to 2^32", s.count)
    } else if s.indices.is_empty() {
        "no indices".to_string()
    } else if let Some(w) = s.indices.windows(2).find(|w| w[0] >= w[1]) {
        format!("indices {} then {} do not increase", w[0], w[1])
    } else if let Some(i) = s.indices.iter().find(|&&i| i >= s.count) {
        format!("index {i} is not below count {}", s.count)
    } else {
        return Ok(());
    };
    Err(Problem::ShardRecord(why))
}

/// The manifest in `text` (a `manifest.json`), checked: size, JSON, format and
/// version, no control characters in any string, then the fields ([`validate`]). The
/// one parser of manifests: [`Bundle::open`] reads with it and [`manifest_json`]
/// checks with it what every writer writes.
pub fn parse_manifest(text: &str) -> Result<Manifest, Problem> {
    let limit = crate::io::MAX_MANIFEST_BYTES;
    if text.len() as u64 > limit {
        return Err(Problem::ManifestTooLarge {
            bytes: text.len(),
            limit,
        });
    }
    let value: serde_json::Value = serde_json::from_str(text).map_err(Problem::NotJson)?;
    if value.get("format").and_then(|f| f.as_str()) != Some(FORMAT) {
        return Err(Problem::NotThisFormat);
    }
    let version = value.get("version").and_then(|v| v.as_u64());
    if !version.is_some_and(|v| (u64::from(VERSION_UNIFORM)..=u64::from(VERSION)).contains(&v)) {
        let found = value
            .get("version")
            .map_or("missing".to_string(), |v| v.to_string());
        return Err(Problem::Version { found });
    }
    if let Some((at, c)) = control_character(&value, &mut String::new()) {
        return Err(Problem::ControlCharacter { at, code: c as u32 });
    }
    // From the text, not the value: a key given twice ("spp": 4, "spp": 64) is an
    // error there, where a JSON value silently keeps the last one.
    let manifest: Manifest = serde_json::from_str(text).map_err(Problem::BadManifest)?;
    validate(&manifest)?;
    Ok(manifest)
}

/// The text of `m` as `manifest.json`, refused (with the reader's reason) unless
/// [`parse_manifest`] reads it back as `m`: every writer of a manifest goes through
/// here, so nothing writes a manifest that the reader refuses. The fields are
/// checked first ([`validate`]), so that a NaN is named rather than written as
/// JSON's `null`.
pub fn manifest_json(m: &Manifest) -> Result<String, Problem> {
    validate(m)?;
    let json = serde_json::to_string_pretty(m).map_err(Problem::BadManifest)?;
    let back = parse_manifest(&json)?;
    if back != *m {
        return Err(Problem::NotRoundTrip);
    }
    Ok(json)
}

impl Bundle {
    pub fn open(dir: &Path) -> Result<Bundle, BundleError> {
        let mpath = dir.join("manifest.json");
        if !dir.is_dir() {
            let why = if dir.exists() {
                Problem::NotADirectory
            } else {
                Problem::NoSuchDirectory
            };
            return Err(BundleError::invalid(dir.to_path_buf(), why));
        }
        // The size is checked (from the file's metadata) before anything is read.
        let text = crate::io::read_regular_text(&mpath, crate::io::MAX_MANIFEST_BYTES)
            .map_err(|e| BundleError::invalid(mpath.clone(), Problem::Unreadable(e)))?;
        let manifest = parse_manifest(&text).map_err(|e| BundleError::invalid(mpath, e))?;
        let mut bundle = Bundle {
            dir: dir.to_path_buf(),
            manifest,
            pixel_spp: None,
        };
        bundle.pixel_spp = bundle.read_pixel_spp()?;
        bundle.check_arrays()?;
        Ok(bundle)
    }

    /// Samples of pixel `p` (row-major).
    #[inline]
    pub fn samples(&self, p: usize) -> u64 {
        self.pixel_spp
            .as_ref()
            .map_or(self.manifest.spp, |n| u64::from(n[p]))
    }

    /// The fewest samples of any pixel (`spp` for a uniform bundle).
    pub fn min_samples(&self) -> u64 {
        self.pixel_spp.as_ref().map_or(self.manifest.spp, |n| {
            n.iter().copied().min().map_or(self.manifest.spp, u64::from)
        })
    }

    /// `pixel_spp.npy` of an adaptive bundle, checked against the manifest.
    fn read_pixel_spp(&self) -> Result<Option<Vec<u32>>, BundleError> {
        let m = &self.manifest;
        let Some(rec) = &m.adaptive else {
            return Ok(None);
        };
        let b = m.replicates.unwrap_or(1);
        let (mut sum, mut lo, mut hi) = (0u64, u64::MAX, 0u64);
        let n: Array2<u32> = self.read_checked(
            "pixel_spp",
            [m.height, m.width].into_dimension(),
            &AXES2,
            |s, block: &[u32]| {
                for &v in block {
                    let v = u64::from(v);
                    sum = sum.saturating_add(v);
                    (lo, hi) = (lo.min(v), hi.max(v));
                }
                first_bad(
                    s,
                    block,
                    |_, v| v >= 2 && u64::from(v).is_multiple_of(b),
                    |_, v| {
                        format!("is {v}, but a pixel has at least 2 samples, a multiple of the replicates ({b})")
                    },
                )
            },
        )?;
        let pixels = (m.height * m.width) as u64;
        if Some(sum) != m.spp.checked_mul(pixels) || (lo, hi) != (rec.min_spp, rec.max_spp) {
            return Err(self.manifest_error(Problem::PixelSpp {
                sum,
                spp: m.spp,
                pixels,
                lo,
                hi,
            }));
        }
        Ok(Some(n.into_raw_vec_and_offset().0))
    }

    fn manifest_error(&self, problem: Problem) -> BundleError {
        BundleError::invalid(self.dir.join("manifest.json"), problem)
    }

    /// The listing of every required array, and each file's header (cheap: a few
    /// hundred bytes per file).
    fn check_arrays(&self) -> Result<(), BundleError> {
        // (`validate` refused an array listed twice and bounded the list.)
        let mut files: Vec<(PathBuf, &'static str)> = Vec::new();
        for (name, dtype, shape) in required_arrays(&self.manifest) {
            let info = self.info(name)?;
            if info.dtype != dtype || info.shape != shape {
                return Err(self.manifest_error(Problem::ArrayListing {
                    name,
                    dtype: info.dtype.clone(),
                    shape: info.shape.clone(),
                    want_dtype: dtype,
                    want_shape: shape,
                }));
            }
            let (path, f) = self.open_npy(name)?;
            check_header(&path, &f.header, dtype, &shape)?;
            // Two arrays read from one file (x2 listed in x1.npy, or links to one
            // target) would load without a complaint and mean nothing.
            let real = std::fs::canonicalize(&path).map_err(|e| unreadable(&path, e))?;
            if let Some((_, other)) = files.iter().find(|(p, _)| *p == real) {
                return Err(self.manifest_error(Problem::SharedFile {
                    other,
                    name,
                    file: real,
                }));
            }
            files.push((real, name));
        }
        // The per-pixel arrays are small (H x W x 3 at most): their values are checked
        // here too, so that no command starts writing before finding them damaged.
        self.albedo()?;
        self.normal()?;
        self.depth()?;
        self.emitter()?;
        self.medium()?;
        self.steady()?;
        Ok(())
    }

    fn info(&self, name: &str) -> Result<&ArrayInfo, BundleError> {
        self.manifest
            .array(name)
            .ok_or_else(|| self.manifest_error(Problem::NoArray(name.to_string())))
    }

    /// The path of an array's file, refused unless it is a plain file name whose
    /// target (after links) lies inside the bundle directory.
    pub fn array_path(&self, name: &str) -> Result<PathBuf, BundleError> {
        let info = self.info(name)?;
        let rel = Path::new(&info.file);
        let plain = matches!(
            rel.components().collect::<Vec<_>>().as_slice(),
            [std::path::Component::Normal(_)]
        );
        if !plain || info.file.contains('/') || info.file.contains('\\') {
            return Err(self.manifest_error(Problem::ArrayFile {
                name: name.to_string(),
                file: info.file.clone(),
            }));
        }
        let path = self.dir.join(rel);
        let real = match std::fs::canonicalize(&path) {
            Ok(r) => r,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(BundleError::invalid(path, Problem::Missing))
            }
            Err(e) => return Err(unreadable(&path, e)),
        };
        let dir = std::fs::canonicalize(&self.dir).map_err(|e| unreadable(&self.dir, e))?;
        if !real.starts_with(&dir) {
            return Err(BundleError::invalid(path, Problem::Outside(real)));
        }
        Ok(path)
    }

    fn open_npy(&self, name: &str) -> Result<(PathBuf, npy::NpyFile), BundleError> {
        let path = self.array_path(name)?;
        let f = npy::open(&path).map_err(|e| npy_error(&path, e))?;
        Ok((path, f))
    }

    /// Reads array `name` as `T` of `shape`, checking every value with `check` (see
    /// [`npy::NpyFile::read`]) in the same pass.
    fn read_checked<T: Element, D: Dimension>(
        &self,
        name: &str,
        shape: D,
        axes: &[&str],
        check: impl FnMut(usize, &[T]) -> npy::Bad,
    ) -> Result<Array<T, D>, BundleError> {
        let (path, f) = self.open_npy(name)?;
        check_header(&path, &f.header, T::DTYPE, shape.slice())?;
        let data = f.read(check, axes).map_err(|e| npy_error(&path, e))?;
        Array::from_shape_vec(shape, data).map_err(|e| npy_error(&path, npy::NpyError::Layout(e)))
    }

    fn shape4(&self) -> [usize; 4] {
        let m = &self.manifest;
        [m.height, m.width, m.bins, m.channel_count()]
    }

    /// The per-voxel counts of samples that deposited something; each at most spp.
    pub fn nonzero(&self) -> Result<Array3<u32>, BundleError> {
        let m = &self.manifest;
        self.read_checked(
            "nonzero",
            [m.height, m.width, m.bins].into_dimension(),
            &AXES3T,
            self.count_check(0),
        )
    }

    /// A reader of the counts and sums a band of image rows at a time (for denoising
    /// in bounded memory): every array the denoiser needs is opened once and its
    /// header checked again.
    pub fn row_reader(&self) -> Result<RowReader<'_>, BundleError> {
        let m = &self.manifest;
        let open = |name: &str, dtype: &str, shape: &[usize]| {
            let (path, f) = self.open_npy(name)?;
            check_header(&path, &f.header, dtype, shape)?;
            Ok::<_, BundleError>((path, f))
        };
        let s4 = self.shape4();
        let sum = |which: SumArray| {
            let (path, file) = open(self.sum_name(which), f64::DTYPE, &s4)?;
            Ok::<_, BundleError>(SumFile { which, path, file })
        };
        Ok(RowReader {
            bundle: self,
            nonzero: open("nonzero", u32::DTYPE, &[m.height, m.width, m.bins])?,
            sums: [sum(SumArray::X1)?, sum(SumArray::X2)?, sum(SumArray::X3)?],
            radiance: if m.transform.is_identity() {
                None
            } else {
                Some(sum(SumArray::Radiance)?)
            },
            r2: match m.replicates {
                Some(_) => Some(sum(SumArray::R2)?),
                None => None,
            },
        })
    }

    /// One of the sum arrays, checked against the module's rules and against the
    /// counts (from [`Bundle::nonzero`]): no sum where no sample was counted.
    pub fn sum_array(
        &self,
        which: SumArray,
        counts: &Array3<u32>,
    ) -> Result<Array4<f64>, BundleError> {
        let counts = counts.as_slice().expect("counts in standard layout");
        let (name, check) = self.sum_check(which, counts);
        self.read_checked(name, self.shape4().into_dimension(), &AXES4, check)
    }

    /// The rule that a count is at most its pixel's samples, as a block check of a
    /// read whose first voxel is `first` of the whole (H, W, T) volume.
    fn count_check(&self, first: usize) -> impl Fn(usize, &[u32]) -> npy::Bad + '_ {
        let bins = self.manifest.bins;
        let spp = move |i: usize| self.samples((first + i) / bins);
        let whose = if self.pixel_spp.is_some() {
            "the pixel's "
        } else {
            ""
        };
        move |s, b: &[u32]| {
            first_bad(
                s,
                b,
                |i, v| u64::from(v) <= spp(i),
                |i, v| format!("counts {v} samples, more than {whose}spp = {}", spp(i)),
            )
        }
    }

    /// The array holding a sum: S is X1 itself under the identity transform.
    fn sum_name(&self, which: SumArray) -> &'static str {
        match which {
            SumArray::X1 => "x1",
            SumArray::X2 => "x2",
            SumArray::X3 => "x3",
            SumArray::Radiance if self.manifest.transform.is_identity() => "x1",
            SumArray::Radiance => "sum",
            SumArray::R2 => "r2",
        }
    }

    /// The file and value check of a sum array; `counts` are the counts of the voxels
    /// the check will see, in the same order (the whole array, or the rows read).
    fn sum_check<'a>(
        &self,
        which: SumArray,
        counts: &'a [u32],
    ) -> (&'static str, impl FnMut(usize, &[f64]) -> npy::Bad + 'a) {
        let m = &self.manifest;
        let radiance = "radiance is never negative".to_string();
        let name = self.sum_name(which);
        let rule = match which {
            SumArray::X2 | SumArray::R2 => Some("a sum of squares cannot be negative".into()),
            // A spectral path's sRGB sample may be negative (the sRGB matching curves
            // are), so its sums may be too.
            SumArray::X1 | SumArray::X3 | SumArray::Radiance if m.signed_samples() => None,
            SumArray::X1 | SumArray::X3 if m.transform.at_zero() == 0.0 => {
                Some(if m.transform.is_identity() {
                    radiance
                } else {
                    format!(
                        "the {} transform of radiance is never negative",
                        m.transform
                    )
                })
            }
            SumArray::X1 | SumArray::X3 => None,
            SumArray::Radiance => Some(radiance),
        };
        let nonneg = rule.is_some();
        // Radiance sums (S, which is X1 under the identity) become the f32 mean S / n
        // of every volume: a sum whose mean overflows f32 is refused here rather
        // than turned into infinities (and NaN neighbours) by the filter.
        // The pixel with the fewest samples bounds every mean (a hostile bound).
        let spp = self.min_samples();
        let is_radiance = name == "sum" || (name == "x1" && m.transform.is_identity());
        let max = if is_radiance {
            f64::from(f32::MAX) * spp as f64
        } else {
            f64::MAX
        };
        let ok = move |v: f64| v.is_finite() && (!nonneg || v >= 0.0) && v <= max;
        // A voxel no sample reached has zero sums, except R2 under a transform with
        // z(0) != 0: its replicate means are z(0).
        let any_empty = which == SumArray::R2 && m.transform.at_zero() != 0.0;
        let channels = m.channel_count();
        let check = move |start: usize, block: &[f64]| {
            // Blocks start at a voxel's first channel (npy::BLOCK_ELEMS is a multiple
            // of 3): check whole voxels against their counts, branch-free; look for
            // the culprit only when something fails.
            let k0 = start / channels;
            let all_ok = match channels {
                3 => voxels_ok::<3>(block, &counts[k0..], ok, any_empty),
                1 => voxels_ok::<1>(block, &counts[k0..], ok, any_empty),
                4 => voxels_ok::<4>(block, &counts[k0..], ok, any_empty),
                _ => voxels_ok::<12>(block, &counts[k0..], ok, any_empty),
            };
            if all_ok {
                return None;
            }
            let i = block
                .iter()
                .enumerate()
                .position(|(i, &v)| {
                    !ok(v) || (v != 0.0 && !any_empty && counts[k0 + i / channels] == 0)
                })
                .expect("a failing value");
            let v = block[i];
            let why = if !v.is_finite() {
                format!("is {}", show(v))
            } else if v > max {
                format!(
                    "is {}: its mean over {} samples is beyond the f32 range of a volume",
                    show(v),
                    spp
                )
            } else if v < 0.0 && nonneg {
                format!(
                    "is {}, but {}",
                    show(v),
                    rule.as_deref().unwrap_or_default()
                )
            } else {
                format!(
                    "is {} where nonzero.npy counts no samples (a sum without samples)",
                    show(v)
                )
            };
            Some((start + i, why))
        };
        (name, check)
    }

    /// `check` for G-buffers and the steady image: finite, within `[lo, hi]`.
    fn read_ranged<T: Element, D: Dimension>(
        &self,
        name: &str,
        shape: D,
        axes: &[&str],
        (lo, hi): (f64, f64),
    ) -> Result<Array<T, D>, BundleError> {
        let ok = move |_: usize, v: T| {
            let v = v.to_f64();
            v >= lo && v <= hi
        };
        let why = move |_: usize, v: T| {
            let v = v.to_f64();
            if !v.is_finite() {
                format!("is {}", show(v))
            } else {
                let range = if hi < f64::MAX {
                    format!("lie in [{lo}, {hi}]")
                } else {
                    format!("be at least {lo}")
                };
                format!("is {}, but {name} values must {range}", show(v))
            }
        };
        self.read_checked(name, shape, axes, |s, b| first_bad(s, b, ok, why))
    }

    pub fn albedo(&self) -> Result<Array3<f32>, BundleError> {
        let m = &self.manifest;
        self.read_ranged(
            "albedo",
            [m.height, m.width, 3].into_dimension(),
            &AXES3C,
            (0.0, f64::MAX),
        )
    }
    pub fn normal(&self) -> Result<Array3<f32>, BundleError> {
        let m = &self.manifest;
        let r = 1.0 + UNIT_SLACK;
        self.read_ranged(
            "normal",
            [m.height, m.width, 3].into_dimension(),
            &AXES3C,
            (-r, r),
        )
    }
    pub fn depth(&self) -> Result<Array2<f32>, BundleError> {
        let m = &self.manifest;
        self.read_ranged(
            "depth",
            [m.height, m.width].into_dimension(),
            &AXES2,
            (0.0, f64::MAX),
        )
    }
    pub fn emitter(&self) -> Result<Array2<f32>, BundleError> {
        let m = &self.manifest;
        self.read_ranged(
            "emitter",
            [m.height, m.width].into_dimension(),
            &AXES2,
            (0.0, 1.0 + UNIT_SLACK),
        )
    }
    /// Fraction of each pixel's samples whose first real interaction is a scattering in
    /// a medium; `None` for bundles of scenes without media.
    pub fn medium(&self) -> Result<Option<Array2<f32>>, BundleError> {
        let m = &self.manifest;
        if !m.media {
            return Ok(None);
        }
        self.read_ranged(
            "medium",
            [m.height, m.width].into_dimension(),
            &AXES2,
            (0.0, 1.0 + UNIT_SLACK),
        )
        .map(Some)
    }
    pub fn steady(&self) -> Result<Array3<f64>, BundleError> {
        let m = &self.manifest;
        let lo = if m.signed_samples() { f64::MIN } else { 0.0 };
        self.read_ranged(
            "steady",
            [m.height, m.width, m.channel_count()].into_dimension(),
            &AXES3C,
            (lo, f64::MAX),
        )
    }

    /// The noisy mean volume S / n as f32, (H, W, T, C), converted while reading (the
    /// f64 sums are never held whole).
    pub fn noisy_mean(&self) -> Result<Array4<f32>, BundleError> {
        let n = self.manifest.spp as f64;
        let counts = self.nonzero()?;
        let counts = counts.as_slice().expect("counts in standard layout");
        let (name, check) = self.sum_check(SumArray::Radiance, counts);
        let (path, f) = self.open_npy(name)?;
        let shape = self.shape4();
        check_header(&path, &f.header, f64::DTYPE, &shape)?;
        let data = match &self.pixel_spp {
            None => f
                .read_mapped(|s: f64| (s / n) as f32, check, &AXES4)
                .map_err(|e| npy_error(&path, e))?,
            // Each pixel's own count (the sums are read whole in f64 first).
            Some(counts) => {
                let per_pixel = self.manifest.bins * self.manifest.channel_count();
                let sums: Vec<f64> = f.read(check, &AXES4).map_err(|e| npy_error(&path, e))?;
                sums.chunks_exact(per_pixel)
                    .zip(counts)
                    .flat_map(|(s, &k)| s.iter().map(move |&v| (v / f64::from(k)) as f32))
                    .collect()
            }
        };
        Array::from_shape_vec(shape, data).map_err(|e| npy_error(&path, npy::NpyError::Layout(e)))
    }
}

/// Reads a bundle's counts and sums band by band; see [`Bundle::row_reader`].
pub struct RowReader<'a> {
    bundle: &'a Bundle,
    nonzero: (PathBuf, npy::NpyFile),
    sums: [SumFile; 3],
    radiance: Option<SumFile>,
    r2: Option<SumFile>,
}

/// An open sum array.
struct SumFile {
    which: SumArray,
    path: PathBuf,
    file: npy::NpyFile,
}

/// The counts and sums of a band of image rows, (rows, W, T) and (rows, W, T, C)
/// row-major like the files; the vectors are reused from band to band.
#[derive(Default)]
pub struct RowSums {
    /// The image rows held.
    pub rows: std::ops::Range<usize>,
    pub x1: Vec<f64>,
    pub x2: Vec<f64>,
    pub x3: Vec<f64>,
    /// Raw radiance sums, only for transforms other than the identity (else X1).
    pub sum: Vec<f64>,
    pub nonzero: Vec<u32>,
    /// R2, only for bundles with replicates (else empty).
    pub r2: Vec<f64>,
}

impl RowReader<'_> {
    /// Reads rows `rows` of every array into `into`, with the checks of
    /// [`Bundle::nonzero`] and [`Bundle::sum_array`]: the counts first, then each sum
    /// against them. An error names the file and the voxel by its place in the whole
    /// volume.
    pub fn read(
        &self,
        rows: std::ops::Range<usize>,
        into: &mut RowSums,
    ) -> Result<(), BundleError> {
        let b = self.bundle;
        let RowSums {
            rows: held,
            x1,
            x2,
            x3,
            sum,
            nonzero,
            r2,
        } = into;
        *held = rows.start..rows.start;
        let (path, f) = &self.nonzero;
        let first = rows.start * b.manifest.width * b.manifest.bins;
        f.read_rows(rows.clone(), nonzero, b.count_check(first), &AXES3T)
            .map_err(|e| npy_error(path, e))?;
        let mut arrays = vec![
            (&self.sums[0], x1),
            (&self.sums[1], x2),
            (&self.sums[2], x3),
        ];
        match &self.radiance {
            Some(r) => arrays.push((r, sum)),
            None => sum.clear(),
        }
        match &self.r2 {
            Some(r) => arrays.push((r, r2)),
            None => r2.clear(),
        }
        // The sums are read side by side (each its own file); the first error in
        // the arrays' order is the one reported, whichever thread meets it first.
        let nonzero: &[u32] = nonzero;
        let results: Vec<Result<(), BundleError>> = {
            use rayon::prelude::*;
            arrays
                .into_par_iter()
                .map(|(a, out)| {
                    let (_, check) = b.sum_check(a.which, nonzero);
                    a.file
                        .read_rows(rows.clone(), out, check, &AXES4)
                        .map_err(|e| npy_error(&a.path, e))
                })
                .collect()
        };
        results.into_iter().collect::<Result<(), _>>()?;
        *held = rows;
        Ok(())
    }
}

/// The first string (or object key) of `v` holding a control character (a newline or
/// an escape sequence that `info` would print into the terminal), with its location.
fn control_character(v: &serde_json::Value, at: &mut String) -> Option<(String, char)> {
    use serde_json::Value;
    let bad = |s: &str| s.chars().find(|c| c.is_control());
    match v {
        Value::String(s) => bad(s).map(|c| (at.clone(), c)),
        Value::Array(a) => a.iter().enumerate().find_map(|(i, x)| {
            let len = at.len();
            at.push_str(&format!("[{i}]"));
            let r = control_character(x, at);
            at.truncate(len);
            r
        }),
        Value::Object(o) => o.iter().find_map(|(k, x)| {
            let len = at.len();
            if !at.is_empty() {
                at.push('.');
            }
            at.push_str(&format!("{k:?}"));
            let r = bad(k)
                .map(|c| (at.clone(), c))
                .or_else(|| control_character(x, at));
            at.truncate(len);
            r
        }),
        _ => None,
    }
}

/// An array's header against what the manifest promises.
fn check_header(
    path: &Path,
    h: &npy::NpyHeader,
    dtype: &str,
    shape: &[usize],
) -> Result<(), BundleError> {
    let problem = if h.dtype != dtype {
        Problem::HeaderDtype {
            found: h.dtype.clone(),
            want: dtype.to_string(),
        }
    } else if h.shape != shape {
        Problem::HeaderShape {
            found: h.shape.clone(),
            want: shape.to_vec(),
        }
    } else {
        return Ok(());
    };
    Err(BundleError::invalid(path.to_path_buf(), problem))
}

/// A `.npy` file of the bundle that cannot be read, or a value in it.
fn npy_error(path: &Path, e: npy::NpyError) -> BundleError {
    BundleError::invalid(path.to_path_buf(), Problem::Npy(e))
}

/// A file or directory of the bundle that cannot be read.
fn unreadable(path: &Path, e: std::io::Error) -> BundleError {
    BundleError::invalid(path.to_path_buf(), Problem::Unreadable(e.into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A valid manifest of a 4 x 4 confocal capture, 8 bins, 4 spp.
    fn manifest() -> Manifest {
        let text = r#"{"format":"tstats","version":1,"width":4,"height":4,"bins":8,
            "channels":["R","G","B"],"spp":4,"start_opl":1.902,"bin_width_opl":0.004,
            "unit_m":1.0,"start_seconds":6.344389090668851e-9,
            "bin_width_seconds":1.3342563807926083e-11,"transform":{"kind":"identity"},
            "pixel_sampling":"sobol","seed":0,
            "nlos":{"capture":"confocal","sensor_grid":[4,4],"laser_grid":[1,1],
              "sensor_origin":[-2.0,0.0,2.0],"laser_origin":[-2.0,0.0,2.0],
              "wall_corner":[-1.0,-1.0,0.0],"wall_du":[2.0,0.0,0.0],"wall_dv":[0.0,2.0,0.0],
              "wall_normal":[0.0,0.0,1.0],"laser_points":[],
              "account_first_and_last_bounces":false},
            "scene":{"path":"s.xml","sha256":"6d0d7fcb6b2916efc8a4e20145184a6daa1094f452468e19c198f5264ace0288",
              "identity":{"inputs":[],"defaults":[["bins","8"],["res","4"]]}},
            "max_depth":-1,"render_seconds":0.5,"dropped_nonfinite":0,
            "program":{"name":"tstat","version":"0.1.0"},"arrays":[]}"#;
        parse_manifest(text).unwrap()
    }

    /// A million merged seeds (and the same with one repeated at the end) validate in
    /// well under a second: the check is a sort. The quadratic check it replaces
    /// takes about a minute on this list (and any quadratic check would exceed the
    /// corpus's 20 s limit), so this test is its regression test without a timer.
    #[test]
    fn a_million_merged_seeds_validate_in_linear_time() {
        let mut m = manifest();
        m.spp = 4_000_000;
        m.merged_seeds = (1..=1_000_000).rev().collect();
        validate(&m).unwrap();
        let text = serde_json::to_string(&m).unwrap();
        assert_eq!(parse_manifest(&text).unwrap(), m);
        m.merged_seeds.push(777_777);
        assert!(matches!(
            validate(&m),
            Err(Problem::MergedSeedTwice(777_777))
        ));
        m.merged_seeds.pop();
        m.spp = 4;
        assert!(matches!(
            validate(&m),
            Err(Problem::MergedSeedsTooMany {
                len: 1_000_000,
                spp: 4
            })
        ));
    }

    /// The other lists: a million shard indices, -D values, scene inputs and channels
    /// are checked in linear (or n log n) time, and the messages stay one short line.
    #[test]
    fn a_million_entries_in_any_list_validate_quickly_with_short_messages() {
        let mut m = manifest();
        m.shard = Some(super::super::shard::ShardRecord {
            job: "0123456789abcdef".into(),
            count: 1 << 32,
            indices: (0..1_000_000).collect(),
        });
        validate(&m).unwrap();
        m.shard.as_mut().unwrap().indices.push(3);
        let e = validate(&m).unwrap_err().to_string();
        assert!(e.contains("indices 999999 then 3 do not increase"), "{e}");
        assert!(e.len() < 300, "{e}");
        m.shard = None;
        let id = m.scene.identity.as_mut().unwrap();
        id.defaults = (0..1_000_000)
            .map(|i| (format!("d{i:07}"), "1".into()))
            .collect();
        id.inputs = (0..1_000_000)
            .map(|i| (format!("f{i:07}"), "0".into()))
            .collect();
        validate(&m).unwrap();
        let id = m.scene.identity.as_mut().unwrap();
        id.inputs.push(("f0000042".into(), "1".into()));
        let e = validate(&m).unwrap_err().to_string();
        assert!(e.contains("inputs lists 'f0000042' twice"), "{e}");
        m.scene.identity = None;
        m.channels = vec!["R".to_string(); 1_000_000];
        let e = validate(&m).unwrap_err().to_string();
        assert!(e.contains("(1000000 in all)") && e.len() < 300, "{e}");
    }

    /// What the writer writes reads back as written, and what the reader refuses the
    /// writer refuses, with the reader's reason (never JSON's `null` for a NaN).
    #[test]
    fn the_writer_refuses_what_the_reader_refuses() {
        let m = manifest();
        let json = manifest_json(&m).unwrap();
        assert_eq!(parse_manifest(&json).unwrap(), m);
        let refused = |edit: &dyn Fn(&mut Manifest), want: &str| {
            let mut bad = manifest();
            edit(&mut bad);
            let e = manifest_json(&bad).unwrap_err().to_string();
            assert!(e.contains(want), "{want}: {e}");
            // The reader refuses the same manifest, written as serde writes it: for the
            // same reason, but for a NaN or an infinity, which serde writes as `null`.
            let text = serde_json::to_string(&bad).unwrap();
            let back = parse_manifest(&text).unwrap_err().to_string();
            let back_want = if want.ends_with("= NaN") || want.ends_with("= +inf") {
                "invalid type: null, expected f64"
            } else {
                want
            };
            assert!(back.contains(back_want), "{want}: read back: {back}");
        };
        refused(&|m| m.start_opl = f64::NAN, "start_opl = NaN");
        refused(&|m| m.bin_width_opl = 0.0, "bin_width_opl = 0e0");
        refused(&|m| m.unit_m = f64::INFINITY, "unit_m = +inf");
        let nlos = |f: fn(&mut super::super::capture::CaptureRecord)| {
            move |m: &mut Manifest| f(m.nlos.as_mut().unwrap())
        };
        refused(
            &nlos(|n| n.wall_corner[0] = 1e300),
            "nlos.wall_corner[0] = 1e300",
        );
        refused(
            &nlos(|n| n.laser_origin = Some([f64::NAN; 3])),
            "nlos.laser_origin[0] = NaN",
        );
        refused(
            &nlos(|n| n.wall_normal = [0.0, 0.0, 2.0]),
            "|nlos.wall_normal| = 2e0",
        );
        refused(
            &|m| m.scene.path = "a\nb.xml".into(),
            "control character U+000A",
        );
        refused(
            &|m| m.scene.identity.as_mut().unwrap().defaults[0].1 = "\u{1b}[2J".into(),
            "control character U+001B",
        );
        refused(&|m| m.merged_seeds = vec![1, 1], "seed 1 twice");
        // An unknown laser is representable: null, read back as None.
        let mut m = manifest();
        let n = m.nlos.as_mut().unwrap();
        n.capture = crate::scene::nlos_setup::CaptureType::Single;
        n.laser_origin = None;
        n.laser_points = vec![None];
        let json = manifest_json(&m).unwrap();
        assert!(json.contains("\"laser_origin\": null"), "{json}");
        assert_eq!(parse_manifest(&json).unwrap(), m);
    }

    /// `time_origin` and `near_clip` go together; a manifest without them (written
    /// before the time origin was recorded) reads as `pinhole`.
    #[test]
    fn time_origin_and_near_clip_go_together() {
        let legacy = manifest();
        assert_eq!(legacy.time_origin, TimeOrigin::Pinhole);
        assert_eq!(legacy.near_clip, None);
        let mut camera = manifest();
        camera.nlos = None;
        camera.time_origin = TimeOrigin::NearClip;
        camera.near_clip = Some(0.5);
        assert!(validate(&camera).is_ok());
        let text = serde_json::to_string(&camera).unwrap();
        assert!(
            text.contains(r#""time_origin":"near_clip","near_clip":0.5"#),
            "{text}"
        );
        assert_eq!(parse_manifest(&text).unwrap().near_clip, Some(0.5));
        let refused = |m: &Manifest, why: &str| {
            let e = validate(m).unwrap_err().to_string();
            assert!(e.contains(why), "{e}");
        };
        for bad in [0.0, -1.0, f64::NAN, 1e300] {
            refused(
                &Manifest {
                    near_clip: Some(bad),
                    ..camera.clone()
                },
                "near_clip",
            );
        }
        refused(
            &Manifest {
                near_clip: None,
                ..camera.clone()
            },
            "without a near_clip",
        );
        refused(
            &Manifest {
                time_origin: TimeOrigin::Pinhole,
                ..camera.clone()
            },
            "near_clip given with time_origin pinhole",
        );
        // An NLOS capture (the test manifest) has no near plane.
        refused(
            &Manifest {
                time_origin: TimeOrigin::NearClip,
                near_clip: Some(0.5),
                ..manifest()
            },
            "no near plane",
        );
    }
}
