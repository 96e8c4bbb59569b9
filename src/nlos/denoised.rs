//! A denoised capture: the H of a tstat bundle's capture replaced by a denoised volume
//! of the same film (`tstat denoise`'s (rows, Sx, T, C) output), summed over the
//! channels and laid out as `nlos/tal.rs` lays out the bundle's means (film row
//! `l Sy + sy`, column `sx`; laser point `l = ly Lx + lx`).

use super::capture::Capture;
use super::NlosError;
use crate::bundle::capture::CaptureRecord;

/// Replaces `c.h` (read from the bundle of `rec`) by `v`, an (rows, Sx, T, C) volume.
pub fn replace_h(
    c: &mut Capture,
    rec: &CaptureRecord,
    v: &[f32],
    shape: [usize; 4],
) -> Result<(), NlosError> {
    let [sx_n, sy_n] = rec.sensor_grid;
    let [lx_n, ly_n] = rec.laser_grid;
    let rows = sy_n * lx_n * ly_n;
    let [h, w, t, ch] = shape;
    if h != rows || w != sx_n || t != c.bins || ch == 0 {
        return Err(NlosError::DenoisedShape {
            shape,
            rows,
            sx: sx_n,
            bins: c.bins,
        });
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err(NlosError::DenoisedNotFinite);
    }
    let sensors = sx_n * sy_n;
    let lasers = lx_n * ly_n;
    for r in 0..rows {
        let (l, sy) = (r / sy_n, r % sy_n);
        let laser = (l % lx_n) * ly_n + l / lx_n;
        for sx in 0..sx_n {
            let sensor = sx * sy_n + sy;
            for k in 0..t {
                let base = ((r * w + sx) * t + k) * ch;
                let sum: f64 = v[base..base + ch].iter().map(|&x| x as f64).sum();
                c.h[(k * lasers + laser) * sensors + sensor] = sum as f32;
            }
        }
    }
    Ok(())
}
