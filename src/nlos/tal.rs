//! y-tal's HDF5 capture format (`tal.io.read_capture` of y-tal 0.20, SPEC 11),
//! written with the pure-Rust `hdf5-pure` crate: `tstat export BUNDLE --tal OUT.hdf5`.
//!
//! Root datasets (y-tal refuses any other name), positions and times in metres
//! (scene units times the bundle's `unit_m`):
//!
//! | name | type | shape | value |
//! |------|------|-------|-------|
//! | `H` | f32 | (T, Sx, Sy), exhaustive (T, Lx, Ly, Sx, Sy) | the noisy mean S / n summed over R, G, B |
//! | `H_format` | enum i32 | (1,) | T_Sx_Sy = 1, T_Lx_Ly_Sx_Sy = 2 |
//! | `sensor_grid_xyz`, `sensor_grid_normals` | f32 | (Sx, Sy, 3) | the relay wall's grid points and normal |
//! | `sensor_grid_format`, `laser_grid_format` | enum i32 | (1,) | X_Y_3 = 2 |
//! | `laser_grid_xyz`, `laser_grid_normals` | f32 | (Lx, Ly, 3) | confocal: the sensor grid; single: (1, 1, 3) |
//! | `sensor_xyz`, `laser_xyz` | f32 | (3,) | sensor_origin, the laser's position (absent if unknown) |
//! | `delta_t`, `t_start` | f64 | () | bin width and start of bin 0, OPL |
//! | `t_accounts_first_and_last_bounces` | bool (enum i8) | () | `account_first_and_last_bounces` |
//! | `scene_info` | variable-length UTF-8 string | () | YAML (a JSON mapping): tstat's version, capture, spp, scene |
//!
//! Grid point (sx, sy) is film column sx, sensor row sy (mitransient's film and y-tal's
//! `tal render` agree: column along the wall's u, row along v, no flip).
//!
//! Memory: H is written straight into the file. The file is first laid out with H as
//! a hole (zero pages never touched), then H is filled a block of time bins at a
//! time: each block, (bins x laser points x sensor points) f32, at most `max_bytes`,
//! is summed from the bundle's rows and written in one piece. A block smaller than
//! the whole capture reads the bundle once per block.

use super::NlosError;
use crate::bundle::capture::CaptureRecord;
use crate::bundle::read::RowSums;
use crate::bundle::{Bundle, BundleError, Problem};
use crate::scene::nlos_setup::CaptureType;
use hdf5_pure::{
    make_f32_type, make_i8_type, Datatype, EnumTypeBuilder, File, FileBuilder, Layout,
};
use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

/// Bytes of bundle rows read at once (one band of the sums).
const BAND_BYTES: usize = 64 << 20;

fn enum_type(values: &[(&str, i32)]) -> Datatype {
    let mut b = EnumTypeBuilder::i32_based();
    for &(name, v) in values {
        b = b.value(name, v);
    }
    b.build().expect("a valid enum type")
}

/// `tal.enums.HFormat`.
fn h_format_type() -> Datatype {
    enum_type(&[
        ("UNKNOWN", 0),
        ("T_Sx_Sy", 1),
        ("T_Lx_Ly_Sx_Sy", 2),
        ("T_Si", 3),
        ("T_Li_Si", 4),
    ])
}

/// `tal.enums.GridFormat`.
fn grid_format_type() -> Datatype {
    enum_type(&[("UNKNOWN", 0), ("N_3", 1), ("X_Y_3", 2)])
}

/// numpy's bool as h5py stores it: an enum {FALSE, TRUE} over int8.
fn bool_type() -> Datatype {
    EnumTypeBuilder::with_base(make_i8_type())
        .value("FALSE", 0)
        .value("TRUE", 1)
        .build()
        .expect("a valid enum type")
}

/// The shape of H and its element count.
fn h_shape(rec: &CaptureRecord, bins: usize) -> Vec<u64> {
    let [sx, sy] = rec.sensor_grid.map(|v| v as u64);
    let [lx, ly] = rec.laser_grid.map(|v| v as u64);
    if rec.capture == CaptureType::Exhaustive {
        vec![bins as u64, lx, ly, sx, sy]
    } else {
        vec![bins as u64, sx, sy]
    }
}

/// A grid of points (X, Y, 3) row-major, f32, scaled by `unit`.
fn grid(nx: usize, ny: usize, unit: f64, point: impl Fn(usize, usize) -> [f64; 3]) -> Vec<f32> {
    let mut out = Vec::with_capacity(nx * ny * 3);
    for x in 0..nx {
        for y in 0..ny {
            out.extend(point(x, y).map(|v| (v * unit) as f32));
        }
    }
    out
}

/// `{name}_grid_xyz`, `{name}_grid_normals` (X, Y, 3) and `{name}_grid_format`
/// (X_Y_3) of an `nx` x `ny` grid of points on a wall of normal `normal`.
fn grid_datasets(
    b: &mut FileBuilder,
    name: &str,
    [nx, ny]: [usize; 2],
    unit: f64,
    normal: [f64; 3],
    point: impl Fn(usize, usize) -> [f64; 3],
) {
    let shape = [nx as u64, ny as u64, 3];
    b.create_dataset(&format!("{name}_grid_xyz"))
        .with_f32_data(&grid(nx, ny, unit, point))
        .with_shape(&shape);
    b.create_dataset(&format!("{name}_grid_normals"))
        .with_f32_data(&grid(nx, ny, 1.0, |_, _| normal))
        .with_shape(&shape);
    b.create_dataset(&format!("{name}_grid_format"))
        .with_enum_i32_data(grid_format_type(), &[2]);
}

/// Everything but H.
fn stage_meta(b: &mut FileBuilder, bundle: &Bundle, rec: &CaptureRecord) {
    let m = &bundle.manifest;
    let unit = m.unit_m;
    let exhaustive = rec.capture == CaptureType::Exhaustive;
    b.create_dataset("H_format")
        .with_enum_i32_data(h_format_type(), &[if exhaustive { 2 } else { 1 }]);
    let [sx, sy] = rec.sensor_grid;
    grid_datasets(b, "sensor", [sx, sy], unit, rec.wall_normal, |x, y| {
        rec.sensor_point(x, y)
    });
    // Confocal: y-tal pairs each sensor point with the laser at the same point.
    let confocal = rec.capture == CaptureType::Confocal;
    let laser_grid = if confocal { [sx, sy] } else { rec.laser_grid };
    grid_datasets(b, "laser", laser_grid, unit, rec.wall_normal, |x, y| {
        if confocal {
            rec.sensor_point(x, y)
        } else {
            rec.laser_point(x, y)
        }
    });
    let point = |p: [f64; 3]| p.map(|v| (v * unit) as f32);
    b.create_dataset("sensor_xyz")
        .with_f32_data(&point(rec.sensor_origin));
    if let Some(o) = rec.laser_origin {
        b.create_dataset("laser_xyz").with_f32_data(&point(o));
    }
    b.create_dataset("delta_t")
        .with_f64_data(&[m.bin_width_opl * unit])
        .with_shape(&[]);
    b.create_dataset("t_start")
        .with_f64_data(&[m.start_opl * unit])
        .with_shape(&[]);
    b.create_dataset("t_accounts_first_and_last_bounces")
        .with_raw_data(
            bool_type(),
            vec![u8::from(rec.account_first_and_last_bounces)],
            1,
        )
        .with_shape(&[]);
    let info = serde_json::json!({
        "tstat": {
            "version": env!("CARGO_PKG_VERSION"),
            "capture_type": rec.capture.name(),
            "spp": m.spp,
            "scene": m.scene.path,
            "scene_sha256": m.scene.sha256,
        }
    });
    b.create_dataset("scene_info")
        .with_vlen_strings(&[info.to_string().as_str()])
        .with_shape(&[]);
}

/// A write sink that turns long all-zero writes into holes: the file is new, so a
/// hole reads back as the zeros skipped.
struct SparseSink {
    file: std::fs::File,
    len: u64,
}

impl Write for SparseSink {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if buf.len() >= 4096 && buf.iter().all(|&b| b == 0) {
            self.file.seek(SeekFrom::Current(buf.len() as i64))?;
        } else {
            self.file.write_all(buf)?;
        }
        self.len += buf.len() as u64;
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

/// `n` zero bytes from the allocator's zeroed pages (never touched, so not resident),
/// or an error (naming the bundle `dir`) when the address space cannot hold them.
fn zeroed(n: usize, dir: &Path) -> Result<Vec<u8>, NlosError> {
    if n == 0 {
        return Ok(Vec::new());
    }
    let layout = std::alloc::Layout::array::<u8>(n).map_err(|error| NlosError::ExportLayout {
        dir: dir.to_path_buf(),
        error,
    })?;
    // SAFETY: the layout has a non-zero size; a non-null pointer owns n zeroed bytes
    // with u8's alignment, which `Vec::from_raw_parts` takes over with that capacity.
    unsafe {
        let p = std::alloc::alloc_zeroed(layout);
        if p.is_null() {
            return Err(NlosError::ExportAddressSpace {
                dir: dir.to_path_buf(),
                bytes: n,
            });
        }
        Ok(Vec::from_raw_parts(p, n, n))
    }
}

/// What [`write_capture`] wrote.
pub struct Written {
    pub h_shape: Vec<u64>,
    /// Blocks of time bins (passes over the bundle).
    pub blocks: usize,
}

/// Writes `bundle`'s capture to `path` (a new file) as y-tal's HDF5 capture, holding at
/// most `max_bytes` of H at a time (at least one time bin's worth).
pub fn write_capture(bundle: &Bundle, path: &Path, max_bytes: u64) -> Result<Written, NlosError> {
    let m = &bundle.manifest;
    let dir = &bundle.dir;
    let io = |e: Box<dyn std::error::Error + Send + Sync>| NlosError::Write(path.to_path_buf(), e);
    let rec = m
        .nlos
        .as_ref()
        .ok_or_else(|| NlosError::ExportNotACapture(dir.clone()))?;
    if rec.account_first_and_last_bounces && rec.laser_origin.is_none() {
        return Err(NlosError::ExportNoLaser(dir.clone()));
    }
    if !rec.lit_points_known() {
        return Err(NlosError::LitPointsUnknown(dir.clone()));
    }
    let shape = h_shape(rec, m.bins);
    let n = shape
        .iter()
        .try_fold(1u64, |a, &d| a.checked_mul(d))
        .unwrap_or(u64::MAX);
    let bytes = usize::try_from(n.saturating_mul(4))
        .ok()
        .filter(|&b| b <= isize::MAX as usize)
        .ok_or_else(|| NlosError::ExportTooLarge {
            dir: dir.clone(),
            values: n,
        })?;
    let mut b = FileBuilder::new();
    b.create_dataset("H")
        .with_raw_data(make_f32_type(), zeroed(bytes, dir)?, n)
        .with_shape(&shape);
    stage_meta(&mut b, bundle, rec);
    let file = std::fs::File::create(path).map_err(|e| io(e.into()))?;
    let mut sink = SparseSink { file, len: 0 };
    b.finish_to(&mut sink).map_err(|e| io(e.into()))?;
    sink.file.set_len(sink.len).map_err(|e| io(e.into()))?;
    let file = sink.file;
    let offset = match File::open_streaming(path)
        .and_then(|f| f.dataset("H")?.layout())
        .map_err(|e| io(e.into()))?
    {
        Layout::Contiguous {
            address: Some(a),
            size,
        } if size == n * 4 => a,
        layout => {
            return Err(NlosError::HNotContiguous {
                path: path.to_path_buf(),
                layout,
            })
        }
    };
    let blocks = fill_h(bundle, rec, &file, offset, max_bytes)?;
    file.sync_all().map_err(|e| io(e.into()))?;
    Ok(Written {
        h_shape: shape,
        blocks,
    })
}

/// Sums the bundle's noisy means over the channels into H, a block of time bins at a
/// time, each block written at its place (H is time first, so a block is contiguous).
fn fill_h(
    bundle: &Bundle,
    rec: &CaptureRecord,
    file: &std::fs::File,
    offset: u64,
    max_bytes: u64,
) -> Result<usize, NlosError> {
    use std::os::unix::fs::FileExt;
    let t = bundle.manifest.bins;
    let per_bin = h_per_bin(rec);
    let block = ((max_bytes / (per_bin as u64 * 4)).max(1) as usize).min(t);
    let mut buf = vec![0f32; block * per_bin];
    let mut blocks = 0;
    for t0 in (0..t).step_by(block) {
        let t1 = (t0 + block).min(t);
        let part = &mut buf[..(t1 - t0) * per_bin];
        h_block(bundle, rec, t0..t1, part)?;
        let bytes: &[u8] = bytemuck::cast_slice(part);
        file.write_all_at(bytes, offset + (t0 * per_bin) as u64 * 4)
            .map_err(|e| NlosError::Write("H".into(), e.into()))?;
        blocks += 1;
    }
    Ok(blocks)
}

/// Values of H per time bin: laser points x sensor points.
pub fn h_per_bin(rec: &CaptureRecord) -> usize {
    let [sx, sy] = rec.sensor_grid;
    let [lx, ly] = rec.laser_grid;
    lx * ly * sx * sy
}

/// Bins `bins` of H from the bundle's rows into `out` ((bins, Lx, Ly, Sx, Sy) row-major,
/// y-tal's order; the laser axes are 1 x 1 but for exhaustive scans): the noisy mean
/// summed over the channels. Reads every array of the bundle's rows (the export
/// checks them all); [`h_radiance`] reads the radiance sums alone.
pub fn h_block(
    bundle: &Bundle,
    rec: &CaptureRecord,
    bins: std::ops::Range<usize>,
    out: &mut [f32],
) -> Result<(), BundleError> {
    let m = &bundle.manifest;
    let (w, h, t) = (m.width, m.height, m.bins);
    let c = m.channels.len();
    assert_eq!(out.len(), bins.len() * h_per_bin(rec));
    let band = (BAND_BYTES / (w * t * c * 8 * 4).max(1)).clamp(1, h);
    let reader = bundle.row_reader()?;
    let mut sums = RowSums::default();
    out.fill(0.0);
    for r0 in (0..h).step_by(band) {
        let r1 = (r0 + band).min(h);
        reader.read(r0..r1, &mut sums)?;
        let s = if sums.sum.is_empty() {
            &sums.x1
        } else {
            &sums.sum
        };
        let first = r0 * m.width;
        let means = band_means(s, c, m.bins, |p| bundle.samples(first + p));
        scatter_band(m, rec, r0..r1, bins.clone(), &means, out);
    }
    Ok(())
}

/// The noisy means of a band of radiance sums `s` ((rows, W, T, C)), summed over the
/// channels: (rows, W, T).
/// `samples(p)`: the samples of the band's pixel `p` (row-major within the band).
fn band_means(s: &[f64], c: usize, bins: usize, samples: impl Fn(usize) -> u64) -> Vec<f32> {
    s.chunks_exact(c)
        .enumerate()
        .map(|(k, v)| (v.iter().sum::<f64>() / samples(k / bins) as f64) as f32)
        .collect()
}

/// Bins `bins` of a band of image rows' means ((rows, W, T), from [`band_means`]) into
/// their places in `out` (bins `bins` of H).
fn scatter_band(
    m: &crate::bundle::Manifest,
    rec: &CaptureRecord,
    rows: std::ops::Range<usize>,
    bins: std::ops::Range<usize>,
    means: &[f32],
    out: &mut [f32],
) {
    let (w, t) = (m.width, m.bins);
    let [sx_n, sy_n] = rec.sensor_grid;
    let [lx_n, ly_n] = rec.laser_grid;
    for r in rows.clone() {
        let (l, sy) = (r / sy_n, r % sy_n);
        let (lx, ly) = (l % lx_n, l / lx_n);
        for sx in 0..sx_n {
            let base = ((r - rows.start) * w + sx) * t;
            let sensor = sx * sy_n + sy;
            for k in bins.clone() {
                let i = (((k - bins.start) * lx_n + lx) * ly_n + ly) * (sx_n * sy_n) + sensor;
                out[i] = means[base + k];
            }
        }
    }
}

/// [`h_block`] of every bin from the radiance sums S alone (`x1.npy` under the identity
/// transform, else `sum.npy`), the only array the mean needs: a band of rows per
/// thread at a time, each value checked as it is read (finite, not negative, its mean
/// within f32). The other sums and the counts are not read (so a sum where
/// `nonzero.npy` counts no samples goes unnoticed here; `Bundle::open` has checked
/// every array's listing and header, the export checks every value).
pub fn h_radiance(
    bundle: &Bundle,
    rec: &CaptureRecord,
    out: &mut [f32],
) -> Result<(), BundleError> {
    use crate::bundle::npy::{first_bad, show};
    use rayon::prelude::*;
    let m = &bundle.manifest;
    let (w, h, c) = (m.width, m.height, m.channels.len());
    assert_eq!(out.len(), m.bins * h_per_bin(rec));
    let name = if m.transform.is_identity() {
        "x1"
    } else {
        "sum"
    };
    let path = bundle.array_path(name)?;
    let bad = |e| BundleError::invalid(path.clone(), Problem::Npy(e));
    let file = crate::bundle::npy::open(&path).map_err(bad)?;
    file.header
        .expect::<f64>(Some(&[h, w, m.bins, c]))
        .map_err(bad)?;
    let spp = bundle.min_samples();
    let max = f64::from(f32::MAX) * spp as f64;
    let ok = move |_: usize, v: f64| v.is_finite() && v >= 0.0 && v <= max;
    let why = move |_: usize, v: f64| {
        if !v.is_finite() {
            format!("is {}", show(v))
        } else if v > max {
            format!(
                "is {}: its mean over {spp} samples is beyond the f32 range of a volume",
                show(v)
            )
        } else {
            format!("is {}, but radiance is never negative", show(v))
        }
    };
    // Bands of at most BAND_BYTES / 4 of sums, as many at once as there are threads.
    let band = (BAND_BYTES / 4 / (w * m.bins * c * 8).max(1)).clamp(1, h);
    let bands: Vec<_> = (0..h)
        .step_by(band)
        .map(|r0| r0..(r0 + band).min(h))
        .collect();
    out.fill(0.0);
    for group in bands.chunks(rayon::current_num_threads().max(1)) {
        let means: Vec<Result<Vec<f32>, BundleError>> = group
            .par_iter()
            .map(|rows| {
                let mut s = Vec::new();
                file.read_rows(
                    rows.clone(),
                    &mut s,
                    |i, b| first_bad(i, b, ok, why),
                    &["y", "x", "t", "c"],
                )
                .map_err(bad)?;
                let first = rows.start * m.width;
                Ok(band_means(&s, c, m.bins, |p| bundle.samples(first + p)))
            })
            .collect();
        for (rows, means) in group.iter().zip(means) {
            scatter_band(m, rec, rows.clone(), 0..m.bins, &means?, out);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bundle::write::{write_bundle, BundleMeta};
    use crate::render::{render, PixelSampling, RenderSettings};
    use crate::scene::{Overrides, Scene};
    use crate::stats::Transform;

    /// The bundled exhaustive scan at 4 spp and 256 bins (film 8 x 512: two bands of
    /// rows for `h_radiance`), rendered with `transform` into `dir`.
    fn bundle(dir: &Path, transform: Transform) -> Bundle {
        let xml = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/nlos_T_exhaustive.xml");
        let overrides = Overrides {
            spp: Some(4),
            bins: Some(256),
            bin_width_opl: Some(0.008),
            ..Overrides::default()
        };
        let scene = Scene::load(&xml, &overrides).unwrap();
        let settings = RenderSettings {
            spp: scene.spp,
            seed: 3,
            transform,
            pixel_sampling: PixelSampling::Independent,
            replicates: 0,
            pixel_spp: None,
        };
        let output = render(&scene, &settings, &|_| {});
        let meta = BundleMeta {
            seed: 3,
            transform,
            unit_m: 1.0,
            pixel_sampling: PixelSampling::Independent,
            replicates: 0,
            job: None,
            adaptive: None,
        };
        let out = dir.join("b.tstats");
        write_bundle(&out, true, &scene, &meta, output).unwrap();
        Bundle::open(&out).unwrap()
    }

    /// H read from the radiance sums alone is the export's H (every array read), to
    /// the bit, under the identity (S in x1.npy) and under a transform (S in sum.npy);
    /// a bad radiance sum is refused, naming the file and the voxel.
    #[test]
    fn radiance_alone_gives_the_exports_h() {
        let dir = tempfile::tempdir().unwrap();
        for transform in [Transform::Identity, Transform::YeoJohnson { lambda: 0.5 }] {
            let b = bundle(dir.path(), transform);
            let rec = b.manifest.nlos.clone().unwrap();
            let row = b.manifest.width * b.manifest.bins * 3 * 8;
            assert!(b.manifest.height > BAND_BYTES / 4 / row, "one band");
            let n = b.manifest.bins * h_per_bin(&rec);
            let (mut all, mut alone) = (vec![0f32; n], vec![1f32; n]);
            h_block(&b, &rec, 0..b.manifest.bins, &mut all).unwrap();
            h_radiance(&b, &rec, &mut alone).unwrap();
            assert!(all.iter().any(|&v| v > 0.0));
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert!(bits(&all) == bits(&alone), "{transform:?}");
        }
        // A NaN in x1.npy (identity) at voxel (y 300, x 5, t 7, c 1).
        let b = bundle(dir.path(), Transform::Identity);
        let rec = b.manifest.nlos.clone().unwrap();
        let path = b.dir.join("x1.npy");
        let header = crate::bundle::npy::open(&path).unwrap().header;
        let flat = ((300 * b.manifest.width + 5) * b.manifest.bins + 7) * 3 + 1;
        let mut bytes = std::fs::read(&path).unwrap();
        let at = header.data_offset as usize + flat * 8;
        bytes[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        std::fs::write(&path, bytes).unwrap();
        let mut h = vec![0f32; b.manifest.bins * h_per_bin(&rec)];
        let e = h_radiance(&b, &rec, &mut h).unwrap_err().to_string();
        assert!(
            e.contains("x1.npy") && e.contains("y 300, x 5, t 7, c 1") && e.contains("NaN"),
            "{e}"
        );
    }
}
