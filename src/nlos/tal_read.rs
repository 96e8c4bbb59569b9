//! Reading a y-tal HDF5 capture ([`Capture::from_tal`]) as hostile input: everything
//! the file declares is checked before anything is allocated from it.
//!
//! - The file: a regular file (a FIFO, a device, a socket or a directory is named as
//!   such; the metadata is checked before opening, and the open is non-blocking, so a
//!   FIFO never blocks), no larger than the memory budget: `hdf5-pure` parses a file
//!   held whole in memory (`File::from_bytes`; its `File::open` is a `std::fs::read`).
//! - The superblock's end-of-file address: not beyond the file's end (a truncated
//!   file is refused as such, as HDF5's library does).
//! - Every dataset: its declared shape (elements counted with overflow checks) against
//!   what the capture needs (H's shape against the grids' point counts, a scalar one
//!   value, a grid 3 per point), its datatype (numbers), its storage against the file
//!   (a contiguous block inside the file and of the declared size; every chunk of a
//!   chunked dataset stored, inside the file, and stored in at least its decoded size,
//!   or that divided by deflate's largest expansion, 1032, when the chunk may be
//!   deflated; virtual datasets refused), its filters (deflate, shuffle and fletcher32
//!   only), and what all of them decode to, with the file, against the memory budget.
//! - Every value: finite; H's values at most [`MAX_H`] in magnitude, coordinates and
//!   OPLs at most [`MAX_OPL`], and OPLs at most [`MAX_OPL`] bins of `delta_t` (so the
//!   reconstructions' arithmetic neither overflows nor loses whole bins).
//!
//! `hdf5-pure` itself bounds its parsing (object header continuations, B-tree depths,
//! decompression bombs against a chunk's size, `try_reserve` for outputs); a panic in
//! it would still be caught ([`std::panic::catch_unwind`], the last resort) and
//! reported as an error. The fuzz test `tests/it/fuzz_tal.rs` looks for both.

use super::capture::Capture;
use super::{NlosError, TalProblem};
use crate::sensors::time_axis::TimeAxis;
use hdf5_pure::{DType, Dataset, Layout};
use std::io::Read;
use std::path::Path;

impl Capture {
    /// A y-tal HDF5 capture (`tal.io.write_capture`'s layout, or `tstat export --tal`):
    /// H formats T_Sx_Sy and T_Lx_Ly_Sx_Sy, grids X_Y_3 or N_3; read within the
    /// default budget of 8 GiB (see [`Capture::from_tal_within`]).
    pub fn from_tal(path: &Path) -> Result<Capture, NlosError> {
        Capture::from_tal_within(path, 8 << 30)
    }

    /// [`Capture::from_tal`] within `budget` bytes of memory (the file, which the HDF5
    /// reader holds whole, and every dataset read), checking everything the file
    /// declares before allocating from it (this file).
    pub fn from_tal_within(path: &Path, budget: u64) -> Result<Capture, NlosError> {
        read(path, budget)
    }
}

/// The largest magnitude of an H value: a sum of 2^64 of them stays below f32's
/// largest (1e18 x 1.8e19 = 1.8e37 < 3.4e38).
pub const MAX_H: f32 = 1e18;
/// The largest magnitude of a coordinate, `t_start` or the time axis' end, and of any
/// of them in bins of `delta_t`: below 2^53 (9.0e15), so an OPL in bins is exact to
/// well under a bin in f64 and its squares stay far below f32's range.
pub const MAX_OPL: f64 = 1e15;
/// Deflate's largest expansion: a stream decodes to at most 1032 bytes per byte.
const DEFLATE_EXPANSION: u64 = 1032;

const FILTER_DEFLATE: u16 = 1;
const FILTER_SHUFFLE: u16 = 2;
const FILTER_FLETCHER32: u16 = 3;

/// What a file type is, for "not a regular file (...)".
fn file_kind(t: std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a FIFO"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a file"
    }
}

/// The bytes of the file at `path`: a regular file (checked before it is opened, and
/// again on the open handle) of at most `budget` bytes, opened non-blocking.
fn file_bytes(path: &Path, budget: u64) -> Result<Vec<u8>, TalProblem> {
    use std::os::unix::fs::OpenOptionsExt;
    let meta = std::fs::metadata(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => TalProblem::Missing,
        _ => TalProblem::Io(e),
    })?;
    if !meta.is_file() {
        return Err(TalProblem::NotRegular(file_kind(meta.file_type())));
    }
    let mut file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(rustix::fs::OFlags::NONBLOCK.bits() as i32)
        .open(path)
        .map_err(TalProblem::Io)?;
    let meta = file.metadata().map_err(TalProblem::Io)?;
    if !meta.is_file() {
        return Err(TalProblem::NotRegular(file_kind(meta.file_type())));
    }
    let size = meta.len();
    if size > budget {
        return Err(TalProblem::FileTooLarge { size, budget });
    }
    let len = usize::try_from(size).map_err(|_| TalProblem::FileTooLarge { size, budget })?;
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(len)
        .map_err(|_| TalProblem::FileTooLarge { size, budget })?;
    // One byte past the size seen: a file that grows while it is read is refused.
    (&mut file)
        .take(size.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(TalProblem::Io)?;
    if bytes.len() as u64 != size {
        return Err(TalProblem::Changed);
    }
    Ok(bytes)
}

/// One dataset's declaration, checked against the file: its shape, its element count
/// and how many bytes it decodes to as f32 or f64.
struct Declared {
    shape: Vec<u64>,
    count: u64,
}

/// The file and what the reads so far have taken of the memory budget.
struct Reader {
    file: hdf5_pure::File,
    names: Vec<String>,
    file_size: u64,
    budget: u64,
    /// Bytes taken: the file's and every dataset's read so far.
    taken: u64,
}

type Problem<T> = Result<T, TalProblem>;

fn hdf5(what: &str) -> impl FnOnce(hdf5_pure::Error) -> TalProblem + '_ {
    move |error| TalProblem::Hdf5 {
        what: what.to_string(),
        error,
    }
}

impl Reader {
    fn has(&self, name: &str) -> bool {
        self.names.iter().any(|n| n == name)
    }

    fn dataset(&self, name: &str) -> Problem<Dataset> {
        if !self.has(name) {
            return Err(TalProblem::MissingDataset(name.to_string()));
        }
        self.file.dataset(name).map_err(hdf5(name))
    }

    /// `name`'s shape and element count, refused above `max` elements, when its
    /// datatype is no number, or when its storage cannot hold what it declares.
    fn declared(&self, ds: &Dataset, name: &str, max: u64) -> Problem<Declared> {
        let shape = ds.shape().map_err(hdf5(name))?;
        let count = shape
            .iter()
            .try_fold(1u64, |a, &d| a.checked_mul(d))
            .ok_or_else(|| TalProblem::ShapeOverflow {
                name: name.to_string(),
                shape: shape.clone(),
            })?;
        if count > max {
            return Err(TalProblem::TooManyValues {
                name: name.to_string(),
                shape,
                count,
                max,
            });
        }
        let dtype = ds.dtype().map_err(hdf5(name))?;
        let numeric = matches!(
            dtype,
            DType::F32
                | DType::F64
                | DType::I8
                | DType::I16
                | DType::I32
                | DType::I64
                | DType::U8
                | DType::U16
                | DType::U32
                | DType::U64
                | DType::Enum(_)
        );
        let elem = ds.element_size().map_err(hdf5(name))?;
        if !numeric || !(1..=8).contains(&elem) {
            return Err(TalProblem::NotNumbers {
                name: name.to_string(),
                dtype: dtype.to_string(),
            });
        }
        self.check_storage(ds, name, &shape, count * elem, elem)?;
        Ok(Declared { shape, count })
    }

    /// The dataset's storage against the file: see the module's documentation.
    fn check_storage(
        &self,
        ds: &Dataset,
        name: &str,
        shape: &[u64],
        bytes: u64,
        elem: u64,
    ) -> Problem<()> {
        let bad = |why: String| TalProblem::Storage {
            name: name.to_string(),
            why,
        };
        let filters = ds.filters();
        if let Some(f) = filters
            .iter()
            .find(|f| ![FILTER_DEFLATE, FILTER_SHUFFLE, FILTER_FLETCHER32].contains(f))
        {
            return Err(TalProblem::Filter {
                name: name.to_string(),
                filter: *f,
            });
        }
        let deflated = filters.contains(&FILTER_DEFLATE);
        match ds.layout().map_err(hdf5(name))? {
            Layout::Compact { size } => {
                if size != bytes {
                    return Err(bad(format!("{size} compact bytes for {bytes}")));
                }
            }
            Layout::Contiguous { address, size } => {
                if size != bytes {
                    return Err(bad(format!("{size} stored bytes for {bytes}")));
                }
                match address {
                    None if bytes > 0 => return Err(bad("no data stored".into())),
                    None => {}
                    Some(a) if a.checked_add(size).is_none_or(|end| end > self.file_size) => {
                        return Err(bad(format!(
                            "{size} bytes at {a} run past the file's end ({} bytes)",
                            self.file_size
                        )))
                    }
                    Some(_) => {}
                }
            }
            Layout::Chunked { chunk_shape, index } => {
                if chunk_shape.len() != shape.len() || chunk_shape.contains(&0) {
                    return Err(bad(format!("chunks of shape {chunk_shape:?}")));
                }
                let chunk_bytes = chunk_shape
                    .iter()
                    .try_fold(elem, |a, &d| a.checked_mul(d))
                    .ok_or_else(|| bad(format!("chunks of shape {chunk_shape:?}")))?;
                if chunk_bytes > u64::from(u32::MAX) {
                    return Err(bad(format!(
                        "chunks of {chunk_bytes} bytes (HDF5's limit is 4 GiB)"
                    )));
                }
                // A chunk is decoded whole, even where it overhangs the dataset.
                if self.taken.saturating_add(chunk_bytes) > self.budget {
                    return Err(TalProblem::OverBudget {
                        name: name.to_string(),
                        bytes: self.taken.saturating_add(chunk_bytes),
                        budget: self.budget,
                    });
                }
                if bytes == 0 {
                    return Ok(());
                }
                // The chunks the shape needs: each stored chunk takes at least one byte
                // of the file, so more than the file's size cannot all be there.
                let chunks = shape
                    .iter()
                    .zip(&chunk_shape)
                    .try_fold(1u64, |a, (&d, &c)| a.checked_mul(d.div_ceil(c)))
                    .filter(|&n| n <= self.file_size)
                    .ok_or_else(|| {
                        bad(format!(
                            "chunks of shape {chunk_shape:?} over {shape:?} outnumber the file's {} bytes",
                            self.file_size
                        ))
                    })?;
                if index == hdf5_pure::ChunkIndex::BTreeV2 {
                    // hdf5-pure enumerates no v2 B-tree chunk index: the reads bound
                    // each chunk's decoding by its size, and the budget bounds the sum.
                    return Ok(());
                }
                let stored = ds.chunks().map_err(hdf5(name))?;
                if stored.len() as u64 != chunks {
                    return Err(bad(format!(
                        "{} chunks stored of the {chunks} its shape needs",
                        stored.len()
                    )));
                }
                let min = if deflated {
                    chunk_bytes.div_ceil(DEFLATE_EXPANSION)
                } else {
                    chunk_bytes
                };
                let mut offsets = Vec::with_capacity(stored.len());
                for c in &stored {
                    let end = c.address.checked_add(c.storage_size);
                    if end.is_none_or(|end| end > self.file_size) {
                        return Err(bad(format!(
                            "a chunk of {} bytes at {} runs past the file's end ({} bytes)",
                            c.storage_size, c.address, self.file_size
                        )));
                    }
                    if c.storage_size < min {
                        return Err(bad(format!(
                            "a chunk of {} bytes cannot decode to its {chunk_bytes}",
                            c.storage_size
                        )));
                    }
                    let aligned = c.offset.len() == shape.len()
                        && c.offset
                            .iter()
                            .zip(shape.iter().zip(&chunk_shape))
                            .all(|(&o, (&d, &k))| o < d && o % k == 0);
                    if !aligned {
                        return Err(bad(format!("a chunk at offset {:?}", c.offset)));
                    }
                    offsets.push(c.offset.clone());
                }
                offsets.sort_unstable();
                offsets.dedup();
                if offsets.len() != stored.len() {
                    return Err(bad("a chunk stored twice".into()));
                }
            }
            Layout::Virtual => return Err(bad("a virtual dataset (data in other files)".into())),
            other => return Err(bad(format!("an unknown layout {other:?}"))),
        }
        Ok(())
    }

    /// Takes `bytes` of the budget for a read of `name`.
    fn take(&mut self, name: &str, bytes: u64) -> Problem<()> {
        let taken = self.taken.saturating_add(bytes);
        if taken > self.budget {
            return Err(TalProblem::OverBudget {
                name: name.to_string(),
                bytes: taken,
                budget: self.budget,
            });
        }
        self.taken = taken;
        Ok(())
    }

    fn read_f32(&mut self, ds: &Dataset, name: &str, d: &Declared) -> Problem<Vec<f32>> {
        self.read_as(name, d, 4, || ds.read_f32())
    }

    fn read_f64(&mut self, ds: &Dataset, name: &str, d: &Declared) -> Problem<Vec<f64>> {
        self.read_as(name, d, 8, || ds.read_f64())
    }

    /// Reads `d.count` values of `size` bytes with `read`, within the budget, and
    /// refuses any other count.
    fn read_as<T>(
        &mut self,
        name: &str,
        d: &Declared,
        size: u64,
        read: impl FnOnce() -> Result<Vec<T>, hdf5_pure::Error>,
    ) -> Problem<Vec<T>> {
        self.take(name, d.count.saturating_mul(size))?;
        let v = read().map_err(hdf5(name))?;
        if v.len() as u64 != d.count {
            return Err(TalProblem::ValueCount {
                name: name.to_string(),
                values: v.len(),
                shape: d.shape.clone(),
            });
        }
        Ok(v)
    }

    /// A scalar (one value, of shape () or (1,)): `None` when the file has no `name`.
    fn scalar(&mut self, name: &str) -> Problem<Option<f64>> {
        if !self.has(name) {
            return Ok(None);
        }
        let ds = self.dataset(name)?;
        let d = self.declared(&ds, name, 1)?;
        let v = self.read_f64(&ds, name, &d)?;
        match v.first() {
            Some(&x) => Ok(Some(x)),
            None => Err(TalProblem::NotAScalar(name.to_string())),
        }
    }

    /// A number of `name` that must be there, finite and at most [`MAX_OPL`].
    fn opl(&mut self, name: &str) -> Problem<f64> {
        let v = self
            .scalar(name)?
            .ok_or_else(|| TalProblem::MissingDataset(name.to_string()))?;
        if !v.is_finite() {
            return Err(TalProblem::NotFinite(name.to_string()));
        }
        if v.abs() > MAX_OPL {
            return Err(TalProblem::TooLarge {
                what: name.to_string(),
                value: v,
                max: MAX_OPL,
            });
        }
        Ok(v)
    }

    /// A grid of 3D points (shape (..., 3)) of at most `max` points: its declaration.
    fn grid_declared(&self, name: &str, max: u64) -> Problem<(Dataset, Declared)> {
        let ds = self.dataset(name)?;
        let d = self.declared(&ds, name, max.saturating_mul(3))?;
        if d.shape.last() != Some(&3) {
            return Err(TalProblem::Points {
                name: name.to_string(),
                shape: d.shape,
            });
        }
        Ok((ds, d))
    }

    /// The points of a grid declared by [`Reader::grid_declared`], finite and at most
    /// [`MAX_OPL`] from the origin.
    fn points(&mut self, name: &str, ds: &Dataset, d: &Declared) -> Problem<Vec<[f32; 3]>> {
        let v = self.read_f32(ds, name, d)?;
        check_values(name, &d.shape, &v, MAX_OPL as f32)?;
        Ok(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
    }

    /// An optional point (`laser_xyz`, `sensor_xyz`): absent is `None`; present, it
    /// is 3 finite coordinates at most [`MAX_OPL`] from the origin.
    fn point(&mut self, name: &str) -> Problem<Option<[f32; 3]>> {
        if !self.has(name) {
            return Ok(None);
        }
        let ds = self.dataset(name)?;
        let d = self.declared(&ds, name, 3)?;
        let v = self.read_f32(&ds, name, &d)?;
        if v.len() != 3 {
            return Err(TalProblem::NotAPoint {
                name: name.to_string(),
                shape: d.shape,
            });
        }
        check_values(name, &d.shape, &v, MAX_OPL as f32)?;
        Ok(Some([v[0], v[1], v[2]]))
    }
}

/// The element at flat index `k` of `shape`, as "t 3, sx 1, sy 2" for H's axes and
/// "i, j, k" indices otherwise.
fn element(name: &str, shape: &[u64], k: usize) -> String {
    let labels: &[&str] = match (name, shape.len()) {
        ("H", 3) => &["t", "sx", "sy"],
        ("H", 5) => &["t", "lx", "ly", "sx", "sy"],
        (_, 3) => &["i", "j", "xyz"],
        (_, 2) => &["n", "xyz"],
        _ => &[],
    };
    let mut rest = k as u64;
    let mut idx = vec![0u64; shape.len()];
    for (a, &d) in shape.iter().enumerate().rev() {
        if d > 0 {
            idx[a] = rest % d;
            rest /= d;
        }
    }
    if labels.len() == shape.len() && !shape.is_empty() {
        labels
            .iter()
            .zip(&idx)
            .map(|(l, i)| format!("{l} {i}"))
            .collect::<Vec<_>>()
            .join(", ")
    } else {
        format!("element {k}")
    }
}

/// Refuses the first value of `v` that is not finite or above `max` in magnitude,
/// naming it by its index in `shape`.
fn check_values(name: &str, shape: &[u64], v: &[f32], max: f32) -> Problem<()> {
    if let Some(k) = v.iter().position(|x| !x.is_finite() || x.abs() > max) {
        let x = v[k];
        let what = if x.is_nan() {
            "NaN".to_string()
        } else if x.is_infinite() {
            format!("{x}")
        } else {
            format!("{x:e}, beyond {max:e} in magnitude")
        };
        return Err(TalProblem::BadValue {
            name: name.to_string(),
            at: element(name, shape, k),
            what,
        });
    }
    Ok(())
}

/// [`Capture::from_tal_within`]'s body: the checks of the module's documentation, in
/// the order that reads nothing large before it is known to fit.
fn read(path: &Path, budget: u64) -> Result<Capture, NlosError> {
    let fail = |problem: TalProblem| NlosError::Tal {
        path: path.to_path_buf(),
        problem,
    };
    let bytes = file_bytes(path, budget).map_err(fail)?;
    let file_size = bytes.len() as u64;
    // The last resort: a panic inside the HDF5 parser is an error like any other.
    let parsed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || {
        let file = hdf5_pure::File::from_bytes(bytes).map_err(hdf5("not an HDF5 file"))?;
        // A file shorter than its superblock says was cut short (HDF5's own check).
        let sb = file.superblock();
        let declared = sb.base_address.get().saturating_add(sb.eof_address);
        if declared > file_size {
            return Err(TalProblem::Truncated {
                size: file_size,
                declared,
            });
        }
        let names = file.root().datasets().map_err(hdf5("the root group"))?;
        let mut r = Reader {
            file,
            names,
            file_size,
            budget,
            taken: file_size,
        };
        capture(&mut r)
    }));
    match parsed {
        Ok(result) => result.map_err(fail),
        Err(_) => Err(fail(TalProblem::ReaderPanic)),
    }
}

fn capture(r: &mut Reader) -> Problem<Capture> {
    // H's declaration: its shape decides every other dataset's size.
    let h_ds = r.dataset("H")?;
    let h_shape = h_ds.shape().map_err(hdf5("H"))?;
    let format = match r.scalar("H_format")? {
        None => None,
        Some(f) if f == 1.0 || f == 2.0 => Some(f as i32),
        Some(f) => {
            return Err(TalProblem::HFormat {
                shape: h_shape,
                format: Some(f),
            })
        }
    };
    let dims: Vec<usize> = h_shape
        .iter()
        .map(|&d| usize::try_from(d).unwrap_or(usize::MAX))
        .collect();
    let (bins, laser_dims, sensor_dims) = match (format, dims.as_slice()) {
        (Some(1) | None, &[t, sx, sy]) => (t, [1, 1], [sx, sy]),
        (Some(2) | None, &[t, lx, ly, sx, sy]) => (t, [lx, ly], [sx, sy]),
        _ => {
            return Err(TalProblem::HFormat {
                shape: h_shape,
                format: format.map(f64::from),
            })
        }
    };
    let count = |d: [usize; 2]| d[0].checked_mul(d[1]);
    let (lasers, sensors) = match (count(laser_dims), count(sensor_dims)) {
        (Some(l), Some(s)) => (l, s),
        _ => {
            return Err(TalProblem::ShapeOverflow {
                name: "H".into(),
                shape: h_shape,
            })
        }
    };
    if bins == 0 || sensors == 0 || lasers == 0 {
        return Err(TalProblem::EmptyH(h_shape));
    }
    // The grids' declarations against H's: no point grid larger than H's axes.
    let (s_ds, s_decl) = r.grid_declared("sensor_grid_xyz", sensors as u64)?;
    let (l_ds, l_decl) = r.grid_declared("laser_grid_xyz", lasers.max(sensors) as u64)?;
    let sensor_points = s_decl.count / 3;
    let laser_points = l_decl.count / 3;
    if sensor_points != sensors as u64 {
        return Err(TalProblem::SensorPoints {
            got: sensor_points,
            want: sensors,
            shape: h_shape,
        });
    }
    // y-tal's `is_laser_paired_to_sensor`: a laser grid as large as the sensor's with
    // one laser axis entry.
    let paired = lasers == 1 && laser_points == sensors as u64 && sensors > 1;
    if !paired && laser_points != lasers as u64 {
        return Err(TalProblem::LaserPoints {
            got: laser_points,
            want: lasers,
            shape: h_shape,
        });
    }
    let h_count = (bins as u64)
        .checked_mul(lasers as u64)
        .and_then(|n| n.checked_mul(sensors as u64))
        .ok_or_else(|| TalProblem::ShapeOverflow {
            name: "H".into(),
            shape: h_shape.clone(),
        })?;
    let h_decl = r.declared(&h_ds, "H", h_count)?;
    // The budget for H (and the grids) before any of them is read.
    let grids = (s_decl.count + l_decl.count).saturating_mul(4);
    if r.taken
        .saturating_add(h_count.saturating_mul(4))
        .saturating_add(grids)
        > r.budget
    {
        return Err(TalProblem::OverBudget {
            name: "H".into(),
            bytes: r
                .taken
                .saturating_add(h_count.saturating_mul(4))
                .saturating_add(grids),
            budget: r.budget,
        });
    }

    let t_start = r.opl("t_start")?;
    let delta_t = r.opl("delta_t")?;
    if delta_t <= 0.0 {
        return Err(TalProblem::DeltaT(delta_t));
    }
    let sensor_grid = r.points("sensor_grid_xyz", &s_ds, &s_decl)?;
    let laser_grid = r.points("laser_grid_xyz", &l_ds, &l_decl)?;
    let laser_xyz = r.point("laser_xyz")?;
    let sensor_xyz = r.point("sensor_xyz")?;
    let normal = if r.has("sensor_grid_normals") {
        let ds = r.dataset("sensor_grid_normals")?;
        let d = r.declared(
            &ds,
            "sensor_grid_normals",
            (sensors as u64).saturating_mul(3),
        )?;
        let v = r.read_f32(&ds, "sensor_grid_normals", &d)?;
        check_values("sensor_grid_normals", &d.shape, &v, f32::MAX)?;
        let n = (v.len() >= 3).then(|| [v[0], v[1], v[2]]);
        let len = n.map_or(0.0, |n| (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt());
        match n {
            Some(n) if len.is_finite() && len > 0.0 => n.map(|x| x / len),
            _ => return Err(TalProblem::Normals),
        }
    } else {
        [0.0, 0.0, 1.0]
    };
    let accounts = match r.scalar("t_accounts_first_and_last_bounces")? {
        Some(v) if v == 0.0 || v == 1.0 => v == 1.0,
        Some(v) => return Err(TalProblem::NotABool(v)),
        None => false,
    };
    if accounts && (laser_xyz.is_none() || sensor_xyz.is_none()) {
        return Err(TalProblem::NoOrigins);
    }
    // The time axis and the geometry in bins (see MAX_OPL).
    let end = t_start + bins as f64 * delta_t;
    let extent = sensor_grid
        .iter()
        .chain(&laser_grid)
        .chain(laser_xyz.iter())
        .chain(sensor_xyz.iter())
        .flat_map(|p| p.iter().map(|&x| f64::from(x).abs()))
        .fold(t_start.abs().max(end.abs()), f64::max);
    if extent > MAX_OPL {
        return Err(TalProblem::TooLarge {
            what: "the time axis' end (t_start + bins delta_t)".into(),
            value: end,
            max: MAX_OPL,
        });
    }
    if extent / delta_t > MAX_OPL {
        return Err(TalProblem::BinsTooSmall {
            delta_t,
            extent,
            max: MAX_OPL,
        });
    }

    let h = r.read_f32(&h_ds, "H", &h_decl)?;
    check_values("H", &h_decl.shape, &h, MAX_H)?;
    Ok(Capture {
        time: TimeAxis {
            start_opl: t_start,
            bin_width_opl: delta_t,
            bins,
        },
        lasers,
        sensors,
        sensor_dims,
        laser_dims,
        normal,
        h,
        laser_grid,
        sensor_grid,
        paired,
        laser_xyz,
        sensor_xyz,
        accounts_first_and_last_bounces: accounts,
    })
}
