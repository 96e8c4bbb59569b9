//! `tstat frames VOLUME --out DIR`: tone-mapped PNG frames with one global exposure, an
//! animated GIF and a streak image; for a Stokes volume (C = 4) also its polarization
//! pictures (`viz::polarization`).

use super::util::{arg, check_outputs, finite, int_flag, positive, Kind};
use crate::bundle::write::write_atomically;
use crate::bundle::{Bundle, BundleError};
use crate::report::volume::load_volume;
use crate::sensors::time_axis::TimeAxis;
use crate::viz::frames::{write_all, FramesRequest, TimeLabels};
use crate::viz::tonemap::global_exposure;
use anyhow::ensure;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct FramesArgs {
    /// A volume: .npy (H, W, T, C) (C = 3 RGB, 1 mono, 4 Stokes S0..S3) or a bundle (its
    /// noisy mean).
    pub volume: PathBuf,
    /// Output directory (frames/, propagation.gif, streak.png; polarization/ for a
    /// Stokes volume).
    #[arg(long)]
    pub out: PathBuf,
    /// Write every K-th bin.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub every: i64,
    /// Also write an animated GIF of the frames.
    #[arg(long)]
    pub gif: bool,
    /// Row of the streak image (default: the middle row).
    #[arg(long, allow_negative_numbers = true)]
    pub streak_row: Option<i64>,
    /// Take the time axis from this bundle (for .npy volumes).
    #[arg(long)]
    pub bundle: Option<PathBuf>,
    /// Time axis for .npy volumes without --bundle: OPL at the start of bin 0.
    #[arg(long, requires = "bin_width_opl", allow_negative_numbers = true)]
    pub start_opl: Option<f64>,
    /// Time axis for .npy volumes without --bundle: bin width in OPL.
    #[arg(long, requires = "start_opl", allow_negative_numbers = true)]
    pub bin_width_opl: Option<f64>,
    /// Metres per scene unit (for picoseconds).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub unit_m: f64,
    /// Exposure multiplier (default: 1 / the 99.5th percentile luminance of the whole volume).
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f64>,
    /// Replace an existing output directory.
    #[arg(long)]
    pub force: bool,
}

pub fn axis_of(bundle: &Bundle) -> TimeLabels {
    let m = &bundle.manifest;
    TimeLabels {
        time: m.time(),
        unit_m: m.unit_m,
        origin: Some(m.time_zero()),
    }
}

pub fn run(a: FramesArgs) -> anyhow::Result<()> {
    let every = int_flag("--every", a.every, 1, i64::MAX)? as usize;
    positive("--unit-m", a.unit_m)?;
    if let Some(e) = a.exposure {
        positive("--exposure", e)?;
        ensure!(
            (e as f32).is_finite() && e as f32 > 0.0,
            "--exposure {e:e}: beyond the range of f32"
        );
    }
    if let Some(h) = a.bin_width_opl {
        positive("--bin-width-opl", h)?;
    }
    if let Some(t0) = a.start_opl {
        finite("--start-opl", t0)?;
    }
    let streak_row = match a.streak_row {
        Some(r) => Some(int_flag("--streak-row", r, 0, i64::MAX)? as usize),
        None => None,
    };
    let mut inputs = vec![arg("volume", &a.volume)];
    if let Some(b) = &a.bundle {
        inputs.push(arg("--bundle", b));
    }
    check_outputs(&inputs, &[(arg("--out", &a.out), Kind::Dir)], a.force)?;
    let loaded = load_volume(&a.volume)?;
    let v = loaded.volume;
    let axis = if a.volume.is_dir() {
        Some(axis_of(&Bundle::open(&a.volume)?))
    } else if let Some(b) = &a.bundle {
        let b = Bundle::open(b)?;
        let m = &b.manifest;
        ensure!(
            m.bins == v.shape()[2],
            "--bundle has {} bins but the volume has {}",
            m.bins,
            v.shape()[2]
        );
        Some(axis_of(&b))
    } else {
        a.start_opl.zip(a.bin_width_opl).map(|(s, h)| TimeLabels {
            time: TimeAxis {
                start_opl: s,
                bin_width_opl: h,
                bins: v.shape()[2],
            },
            unit_m: a.unit_m,
            origin: None,
        })
    };
    let rows = v.shape()[0];
    let streak_row = streak_row.unwrap_or(rows / 2);
    ensure!(
        streak_row < rows,
        "--streak-row {streak_row}: the image has {rows} rows"
    );
    let req = FramesRequest {
        every,
        gif: a.gif,
        streak_row,
        exposure: a
            .exposure
            .map_or_else(|| global_exposure(v.view()), |e| e as f32),
        axis,
        caption: format!("streak image, row {streak_row}"),
    };
    let mut count = 0;
    write_atomically(&a.out, a.force, |tmp| -> Result<(), BundleError> {
        std::fs::create_dir(tmp).map_err(|e| BundleError::io(tmp, e))?;
        count = write_all(tmp, v.view(), &req).map_err(|e| BundleError::io(&a.out, e))?;
        Ok(())
    })?;
    let channels = v.shape()[3];
    say!(
        "wrote {} frames to {}/frames/{}, streak image of row {streak_row} at {}/streak.png (exposure {:.4}{}){}",
        count,
        a.out.display(),
        if a.gif { format!(", {}/propagation.gif", a.out.display()) } else { String::new() },
        a.out.display(),
        req.exposure,
        if axis.is_none() { "; time axis unknown: labelled in bins" } else { "" },
        match channels {
            1 => "; one channel (mono): shown as grey".to_string(),
            4 => format!(
                "; a Stokes volume: S0 as grey, and AoLP/DoLP and S1, S2, S3 / S0 pictures in {}/polarization/",
                a.out.display()
            ),
            12 => format!(
                "; a spectral Stokes volume: S0 in colour, and AoLP/DoLP and S1, S2, S3 / S0 pictures of its luminance in {}/polarization/",
                a.out.display()
            ),
            _ => String::new(),
        }
    );
    Ok(())
}
