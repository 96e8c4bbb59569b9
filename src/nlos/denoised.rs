//! A denoised capture: the H of a tstat bundle's capture replaced by a denoised volume
//! of the same film (`tstat denoise`'s (rows, Sx, T, C) output), summed over the
//! channels and laid out as `nlos/tal.rs` lays out the bundle's means (film row
//! `l Sy + sy`, column `sx`; laser point `l = ly Lx + lx`). The volume may arrive a
//! band of film rows at a time ([`replace_rows`]), so that it is never held whole.

use super::capture::Capture;
use super::NlosError;
use crate::bundle::capture::CaptureRecord;
use std::ops::Range;

/// Refuses a volume `shape` that is not (rows, Sx, T, C) of the capture `c` of `rec`.
pub fn check_shape(c: &Capture, rec: &CaptureRecord, shape: &[usize]) -> Result<(), NlosError> {
    let [sx_n, sy_n] = rec.sensor_grid;
    let [lx_n, ly_n] = rec.laser_grid;
    let rows = sy_n * lx_n * ly_n;
    match *shape {
        [h, w, t, ch] if h == rows && w == sx_n && t == c.time.bins && ch > 0 => Ok(()),
        _ => Err(NlosError::DenoisedShape {
            shape: shape.to_vec(),
            rows,
            sx: sx_n,
            bins: c.time.bins,
        }),
    }
}

/// Replaces `c.h` (read from the bundle of `rec`) by `v`, an (rows, Sx, T, C) volume.
pub fn replace_h(
    c: &mut Capture,
    rec: &CaptureRecord,
    v: &[f32],
    shape: [usize; 4],
) -> Result<(), NlosError> {
    check_shape(c, rec, &shape)?;
    if v.iter().any(|x| !x.is_finite()) {
        return Err(NlosError::DenoisedNotFinite);
    }
    replace_rows(c, rec, 0..shape[0], v, shape[3]);
    Ok(())
}

/// Replaces the part of `c.h` that film rows `rows` hold by `band`, those rows of a
/// volume of [`check_shape`]'s shape with `ch` channels (finite values).
pub fn replace_rows(
    c: &mut Capture,
    rec: &CaptureRecord,
    rows: Range<usize>,
    band: &[f32],
    ch: usize,
) {
    let [sx_n, sy_n] = rec.sensor_grid;
    let [lx_n, ly_n] = rec.laser_grid;
    let t = c.time.bins;
    assert_eq!(band.len(), rows.len() * sx_n * t * ch, "whole film rows");
    let sensors = sx_n * sy_n;
    let lasers = lx_n * ly_n;
    for (dr, r) in rows.enumerate() {
        let (l, sy) = (r / sy_n, r % sy_n);
        let laser = (l % lx_n) * ly_n + l / lx_n;
        for sx in 0..sx_n {
            let sensor = sx * sy_n + sy;
            for k in 0..t {
                let base = ((dr * sx_n + sx) * t + k) * ch;
                let sum: f64 = band[base..base + ch].iter().map(|&x| x as f64).sum();
                c.h[(k * lasers + laser) * sensors + sensor] = sum as f32;
            }
        }
    }
}
