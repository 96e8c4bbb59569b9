//! An NLOS capture in memory, in y-tal's terms, for reconstructions: H as (T, L, S)
//! (time, laser point, sensor point; y-tal's `convert_to_N_3` order: a grid's point
//! (i, j) of an X x Y grid is `i Y + j`), the grids, the origins and the time axis. It
//! comes from a tstat bundle of a capture or from a y-tal HDF5 capture.
//!
//! Memory: H is held whole, `T L S` f32 (a 64 x 64 confocal scan of 512 bins: 8 MB;
//! an exhaustive 16^4 of 512 bins: 134 MB).

use super::NlosError;
use crate::bundle::capture::CaptureRecord;
use crate::bundle::Bundle;
use crate::scene::nlos_setup::CaptureType;
use crate::sensors::time_axis::TimeAxis;

#[derive(Clone)]
pub struct Capture {
    /// The time axis: T bins of width h from t0 (OPL; a y-tal file's `t_start` and
    /// `delta_t`).
    pub time: TimeAxis,
    /// Laser points of H's laser axis (1 for single and confocal captures).
    pub lasers: usize,
    pub sensors: usize,
    /// The grids' shapes (X, Y) when they are X x Y grids (point (i, j) is `i Y + j`);
    /// (N, 1) for a y-tal N_3 grid.
    pub sensor_dims: [usize; 2],
    pub laser_dims: [usize; 2],
    /// The relay wall's unit normal, towards the hidden scene (a y-tal file's first
    /// `sensor_grid_normals` entry; +z when it has none).
    pub normal: [f32; 3],
    /// (T, L, S) row-major.
    pub h: Vec<f32>,
    /// One point per laser of H's laser axis, or, when `paired`, one per sensor point.
    pub laser_grid: Vec<[f32; 3]>,
    pub sensor_grid: Vec<[f32; 3]>,
    /// Confocal: sensor point s is lit by laser point s.
    pub paired: bool,
    pub laser_xyz: Option<[f32; 3]>,
    pub sensor_xyz: Option<[f32; 3]>,
    pub accounts_first_and_last_bounces: bool,
}

fn f32x3(p: [f64; 3]) -> [f32; 3] {
    p.map(|v| v as f32)
}

impl Capture {
    /// The capture of a tstat bundle (its `nlos` record), in scene units: H from the
    /// radiance sums alone (`tal::h_radiance`), the same values `tstat export --tal`
    /// writes.
    pub fn from_bundle(bundle: &Bundle) -> Result<Capture, NlosError> {
        let m = &bundle.manifest;
        let rec = m
            .nlos
            .as_ref()
            .ok_or_else(|| NlosError::NotACapture(bundle.dir.clone()))?;
        if !rec.lit_points_known() {
            return Err(NlosError::LitPointsUnknown(bundle.dir.clone()));
        }
        let len = super::tal::h_per_bin(rec)
            .checked_mul(m.bins)
            .ok_or(NlosError::HOverflow)?;
        let mut h = Vec::new();
        h.try_reserve_exact(len)
            .map_err(|_| NlosError::HMemory(len))?;
        h.resize(len, 0.0);
        super::tal::h_radiance(bundle, rec, &mut h)?;
        Ok(Capture::from_record(rec, m.time(), h))
    }

    /// The capture of a tstat render (its scene's `CaptureRecord`, the film's time
    /// axis) holding `h`, (T, L, S) as [`Capture::h`] (e.g. zeros, to be replaced by a
    /// volume with `denoised::replace_h`).
    pub fn from_record(rec: &CaptureRecord, time: TimeAxis, h: Vec<f32>) -> Capture {
        let [sx, sy] = rec.sensor_grid;
        let [lx, ly] = rec.laser_grid;
        assert_eq!(
            h.len(),
            time.bins * super::tal::h_per_bin(rec),
            "H's length"
        );
        let sensor_grid = (0..sx)
            .flat_map(|i| (0..sy).map(move |j| (i, j)))
            .map(|(i, j)| f32x3(rec.sensor_point(i, j)))
            .collect::<Vec<_>>();
        let paired = rec.capture == CaptureType::Confocal;
        let laser_grid = if paired {
            sensor_grid.clone()
        } else {
            (0..lx)
                .flat_map(|i| (0..ly).map(move |j| (i, j)))
                .map(|(i, j)| f32x3(rec.laser_point(i, j)))
                .collect()
        };
        let finite = |p: [f64; 3]| p.iter().all(|v| v.is_finite()).then(|| f32x3(p));
        Capture {
            time,
            lasers: lx * ly,
            sensors: sx * sy,
            sensor_dims: [sx, sy],
            laser_dims: [lx, ly],
            normal: f32x3(rec.wall_normal),
            h,
            laser_grid,
            sensor_grid,
            paired,
            laser_xyz: rec.laser_origin.map(f32x3),
            sensor_xyz: finite(rec.sensor_origin),
            accounts_first_and_last_bounces: rec.account_first_and_last_bounces,
        }
    }

    /// The time series `q` of `qs` (`q = l S + s`), one after the other, `bins` values
    /// each. H is time-major, so a block of neighbouring series reads H a row at a time.
    pub fn series(&self, qs: std::ops::Range<usize>) -> Vec<f32> {
        let (n, stride) = (qs.len(), self.lasers * self.sensors);
        let mut out = vec![0f32; n * self.time.bins];
        for t in 0..self.time.bins {
            let row = &self.h[t * stride + qs.start..t * stride + qs.end];
            for (k, &v) in row.iter().enumerate() {
                out[k * self.time.bins + t] = v;
            }
        }
        out
    }

    /// Series per block of [`Capture::series`] that keeps a block's reads in cache.
    pub const SERIES_BLOCK: usize = 64;

    /// H at (bin, laser, sensor).
    #[inline]
    pub fn at(&self, t: usize, l: usize, s: usize) -> f32 {
        self.h[(t * self.lasers + l) * self.sensors + s]
    }
}
