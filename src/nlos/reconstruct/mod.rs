//! One reconstruction of the hidden scene, with its parameters: the methods of
//! `tstat nlos reconstruct` and of `report convergence --reconstruct`, their checks
//! against a capture and their working memory, in one place. Each method is a file of
//! this folder; a new one is that file, its `pub mod` line and `Reconstruction` variant
//! here, and its `NlosMethod` value in `cli/nlos.rs`.

pub mod bp;
pub mod fk;
pub mod lct;
pub mod pf;
pub mod wave;

use super::capture::Capture;
use super::{filter, NlosError};
use bp::{backproject, filtered_backproject, VoxelGrid};

/// A reconstruction method and its parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reconstruction {
    /// Backprojection (y-tal's `tal.reconstruct.bp`).
    Bp,
    /// Filtered backprojection (y-tal's `tal.reconstruct.fbp`): the magnitude.
    Fbp { wl_mean: f64, wl_sigma: f64 },
    /// Phasor fields with Rayleigh-Sommerfeld propagation (y-tal's `pf_dev`): the
    /// magnitude.
    Pf { wl_mean: f64, wl_sigma: f64 },
    /// f-k migration (confocal N x N captures).
    Fk,
    /// The light-cone transform with its Wiener filter (confocal N x N captures).
    Lct { snr: f64 },
}

impl Reconstruction {
    /// The method's name as the command line spells it.
    pub fn name(&self) -> &'static str {
        match self {
            Reconstruction::Bp => "bp",
            Reconstruction::Fbp { .. } => "fbp",
            Reconstruction::Pf { .. } => "pf",
            Reconstruction::Fk => "fk",
            Reconstruction::Lct { .. } => "lct",
        }
    }

    /// The parameters, for reports ("wl_mean 0.2, wl_sigma 0.14").
    pub fn describe(&self) -> String {
        match self {
            Reconstruction::Fbp { wl_mean, wl_sigma }
            | Reconstruction::Pf { wl_mean, wl_sigma } => {
                format!("{}: wl_mean {wl_mean}, wl_sigma {wl_sigma:.4}", self.name())
            }
            Reconstruction::Lct { snr } => format!("lct: snr {snr}"),
            _ => self.name().to_string(),
        }
    }

    /// Refuses parameters the method cannot use on `c`: a pulse envelope so wide that
    /// the filter's padded series would not stay addressable, non-positive wavelengths
    /// or ratios.
    pub fn check(&self, c: &Capture) -> Result<(), NlosError> {
        match *self {
            Reconstruction::Fbp { wl_mean, wl_sigma }
            | Reconstruction::Pf { wl_mean, wl_sigma } => {
                if !(wl_mean > 0.0 && wl_mean.is_finite() && wl_sigma > 0.0 && wl_sigma.is_finite())
                {
                    return Err(NlosError::Wavelengths { wl_mean, wl_sigma });
                }
                let (n, _) = filter::padding(c.time.bins, wl_sigma, c.time.bin_width_opl);
                if wl_sigma / c.time.bin_width_opl > 1e6 || n > 1 << 26 {
                    return Err(NlosError::Envelope {
                        wl_sigma,
                        bins: wl_sigma / c.time.bin_width_opl,
                        padded: n,
                    });
                }
                Ok(())
            }
            Reconstruction::Lct { snr } if !(snr > 0.0 && snr.is_finite()) => {
                Err(NlosError::Snr(snr))
            }
            _ => Ok(()),
        }
    }

    /// The working memory of the reconstruction of `c` on `grid`, beyond the capture.
    pub fn working_memory(&self, c: &Capture, grid: &VoxelGrid) -> Result<u64, NlosError> {
        let out = grid.voxels() as u64 * 8;
        Ok(match *self {
            Reconstruction::Pf { wl_mean, wl_sigma } => {
                let p = pf::pulse(c.time.bins, c.time.bin_width_opl, wl_mean, wl_sigma)?;
                pf::memory_bytes(c, grid, &p) as u64
            }
            // The complex filtered capture and the two backprojected planes.
            Reconstruction::Fbp { .. } => c.h.len() as u64 * 8 + out * 2,
            Reconstruction::Fk => fk::memory_bytes(c) as u64 + out,
            Reconstruction::Lct { .. } => lct::memory_bytes(c) as u64 + out,
            Reconstruction::Bp => out,
        })
    }

    /// The energy `||L(c)||^2` of the reconstruction's linear field `L` (a linear map
    /// of the capture; `c` may be signed): bp's volume; fbp's and pf's complex field,
    /// from their magnitudes; fk's field before its squared magnitude and LCT's before
    /// its clamp, on their native grids (`shrink.rs`).
    pub fn linear_energy(&self, c: &Capture, grid: &VoxelGrid) -> Result<f64, NlosError> {
        self.check(c)?;
        let squares = |v: Vec<f32>| v.iter().map(|&x| f64::from(x).powi(2)).sum();
        Ok(match *self {
            Reconstruction::Bp | Reconstruction::Fbp { .. } | Reconstruction::Pf { .. } => {
                squares(self.run(c, grid)?)
            }
            Reconstruction::Fk => fk::fk_linear_energy(c)?,
            Reconstruction::Lct { snr } => lct::lct_linear_energy(c, snr)?,
        })
    }

    /// The reconstruction of `c` on `grid`: NX NY NZ values, row-major.
    pub fn run(&self, c: &Capture, grid: &VoxelGrid) -> Result<Vec<f32>, NlosError> {
        self.check(c)?;
        Ok(match *self {
            Reconstruction::Bp => backproject(c, grid),
            Reconstruction::Fbp { wl_mean, wl_sigma } => {
                filtered_backproject(c, grid, wl_mean, wl_sigma)
            }
            Reconstruction::Pf { wl_mean, wl_sigma } => {
                pf::phasor_field(c, grid, wl_mean, wl_sigma)?
            }
            Reconstruction::Fk => fk::fk_migration(c, grid)?,
            Reconstruction::Lct { snr } => lct::lct(c, grid, snr)?,
        })
    }
}
