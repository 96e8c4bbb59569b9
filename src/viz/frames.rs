//! Pictures of a volume: one PNG per (every K-th) bin, an animated GIF, and a streak
//! image (x against t at one row) with the time axis labelled in OPL and picoseconds.
//! An (H, W, T, C) volume of C = 3 is shown in colour; C = 1 (mono: Y) and C = 4
//! (Stokes: S0, S1, S2, S3) show their first channel as grey
//! (`tonemap::shown_channels`), and a Stokes volume also gets its polarization
//! pictures (`viz::polarization`, in `polarization/`).

use super::tonemap::{shown_channels, srgb8};
use super::VizError;
use crate::report::plot::save_png_rgb;
use crate::sensors::time_axis::TimeAxis;
use image::{Delay, Frame, RgbaImage};
use ndarray::ArrayView4;
use plotters::prelude::*;
use std::path::Path;

/// How to label the time axis of a volume, when it is known: the axis itself, the
/// length unit for picoseconds, and where OPL 0 is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeLabels {
    pub time: TimeAxis,
    /// Metres per scene unit.
    pub unit_m: f64,
    /// Where OPL 0 is (`Manifest::time_zero`: "the near-clip plane", ...); `None`
    /// when not known (a volume given with `--start-opl`).
    pub origin: Option<&'static str>,
}

impl TimeLabels {
    pub fn opl(&self, bin: f64) -> f64 {
        self.time.opl(bin)
    }
    /// The axis's title: "time (OPL from the near-clip plane, scene units)".
    pub fn label(&self) -> String {
        match self.origin {
            Some(o) => format!("time (OPL from {o}, scene units)"),
            None => "time (OPL, scene units)".into(),
        }
    }

    pub fn picoseconds(&self, opl: f64) -> f64 {
        opl * self.unit_m / crate::bundle::manifest::C_M_PER_S * 1e12
    }
}

/// The RGB8 image of bin `k` with a fixed exposure.
pub fn frame_rgb(v: ArrayView4<f32>, k: usize, exposure: f32) -> Vec<u8> {
    let (h, w) = (v.shape()[0], v.shape()[1]);
    let shown = shown_channels(v.shape()[3]);
    let mut buf = Vec::with_capacity(h * w * 3);
    for y in 0..h {
        for x in 0..w {
            for c in shown {
                buf.push(srgb8(v[[y, x, k, c]] * exposure));
            }
        }
    }
    buf
}

/// The bins shown: 0, K, 2K, ...
pub fn shown_bins(bins: usize, every: usize) -> Vec<usize> {
    (0..bins).step_by(every.max(1)).collect()
}

/// Writes `DIR/frame_NNNN.png` for the shown bins; returns the file names.
pub fn write_frames(
    dir: &Path,
    v: ArrayView4<f32>,
    every: usize,
    exposure: f32,
) -> Result<Vec<String>, VizError> {
    let (h, w, t) = (v.shape()[0], v.shape()[1], v.shape()[2]);
    let digits = t.to_string().len().max(4);
    let mut names = Vec::new();
    for k in shown_bins(t, every) {
        let name = format!("frame_{k:0digits$}.png");
        save_png_rgb(
            &dir.join(&name),
            &frame_rgb(v, k, exposure),
            w as u32,
            h as u32,
        )?;
        names.push(name);
    }
    Ok(names)
}

/// Writes an animated GIF of the shown bins (looping, `delay_ms` per frame).
pub fn write_gif(
    path: &Path,
    v: ArrayView4<f32>,
    every: usize,
    exposure: f32,
    delay_ms: u32,
) -> Result<(), VizError> {
    let (h, w, t) = (v.shape()[0], v.shape()[1], v.shape()[2]);
    crate::bundle::write::replace_file(
        path,
        |tmp| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            let file = std::fs::File::create(tmp)?;
            let mut enc =
                image::codecs::gif::GifEncoder::new_with_speed(std::io::BufWriter::new(file), 10);
            enc.set_repeat(image::codecs::gif::Repeat::Infinite)?;
            for k in shown_bins(t, every) {
                let rgb = frame_rgb(v, k, exposure);
                let rgba: Vec<u8> = rgb
                    .chunks(3)
                    .flat_map(|p| [p[0], p[1], p[2], 255])
                    .collect();
                let img = RgbaImage::from_raw(w as u32, h as u32, rgba).expect("size matches");
                enc.encode_frame(Frame::from_parts(
                    img,
                    0,
                    0,
                    Delay::from_numer_denom_ms(delay_ms, 1),
                ))?;
            }
            Ok(())
        },
    )?;
    Ok(())
}

/// Writes the streak image of row `row`: time across (bottom axis in OPL, top axis in
/// picoseconds; bins when the axis is unknown), pixel column up the side.
pub fn write_streak(
    path: &Path,
    v: ArrayView4<f32>,
    row: usize,
    exposure: f32,
    axis: Option<TimeLabels>,
    caption: &str,
) -> Result<(), VizError> {
    let (h, w, t) = (v.shape()[0], v.shape()[1], v.shape()[2]);
    if row >= h {
        return Err(VizError::StreakRow { row, height: h });
    }
    crate::report::plot::register_font();
    let scale = (700.0 / t.max(w) as f64).clamp(1.0, 8.0);
    let (pw, ph) = ((t as f64 * scale) as u32, (w as f64 * scale) as u32);
    let (cw, ch) = (pw + 120, ph + 150);
    let mut buf = vec![255u8; (cw * ch * 3) as usize];
    let (t0, t1) = match axis {
        Some(a) => (a.opl(0.0), a.opl(t as f64)),
        None => (0.0, t as f64),
    };
    let bin_edge = |k: usize| t0 + (t1 - t0) * k as f64 / t as f64;
    let shown = shown_channels(v.shape()[3]);
    {
        let root = BitMapBackend::with_buffer(&mut buf, (cw, ch)).into_drawing_area();
        let draw = || -> Result<(), Box<dyn std::error::Error>> {
            root.fill(&WHITE)?;
            let mut chart = ChartBuilder::on(&root)
                .caption(caption, ("sans-serif", 18))
                .margin(10)
                .x_label_area_size(45)
                .top_x_label_area_size(45)
                .y_label_area_size(60)
                .build_cartesian_2d(t0..t1, 0.0..w as f64)?
                .set_secondary_coord(
                    axis.map_or(t0, |a| a.picoseconds(t0))..axis.map_or(t1, |a| a.picoseconds(t1)),
                    0.0..w as f64,
                );
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc(axis.map_or_else(|| "time (bin; axis unknown)".into(), |a| a.label()))
                .y_desc("pixel column")
                .label_style(("sans-serif", 14))
                .draw()?;
            if axis.is_some() {
                chart
                    .configure_secondary_axes()
                    .x_desc("time (ps)")
                    .label_style(("sans-serif", 14))
                    .draw()?;
            }
            chart.draw_series((0..w).flat_map(|x| {
                (0..t).map(move |k| {
                    let c = shown.map(|c| srgb8(v[[row, x, k, c]] * exposure));
                    Rectangle::new(
                        [(bin_edge(k), x as f64), (bin_edge(k + 1), x as f64 + 1.0)],
                        RGBColor(c[0], c[1], c[2]).filled(),
                    )
                })
            }))?;
            root.present()?;
            Ok(())
        };
        draw().map_err(|e| VizError::Drawing {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
    }
    save_png_rgb(path, &buf, cw, ch)?;
    Ok(())
}

/// Two volumes of one shape side by side along x, with a `gap`-pixel black seam.
pub fn side_by_side(a: ArrayView4<f32>, b: ArrayView4<f32>, gap: usize) -> ndarray::Array4<f32> {
    let (h, w, t, c) = (a.shape()[0], a.shape()[1], a.shape()[2], a.shape()[3]);
    assert_eq!(a.shape(), b.shape(), "side_by_side needs equal shapes");
    ndarray::Array4::from_shape_fn((h, 2 * w + gap, t, c), |(y, x, k, ch)| {
        if x < w {
            a[[y, x, k, ch]]
        } else if x >= w + gap {
            b[[y, x - w - gap, k, ch]]
        } else {
            0.0
        }
    })
}

/// What to write for a volume.
pub struct FramesRequest {
    pub every: usize,
    pub gif: bool,
    pub streak_row: usize,
    pub exposure: f32,
    pub axis: Option<TimeLabels>,
    /// Title of the streak image.
    pub caption: String,
}

/// Writes frames into `dir` (which must exist) plus `propagation.gif` and
/// `streak.png`, and for a Stokes volume (C = 4) its polarization pictures in
/// `dir/polarization/` ([`super::polarization::write_polarization`]; of a spectral
/// Stokes volume, C = 12, those of its luminance Stokes vector,
/// [`super::polarization::stokes_luminance`]); returns the number of frames.
pub fn write_all(dir: &Path, v: ArrayView4<f32>, req: &FramesRequest) -> Result<usize, VizError> {
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).map_err(|error| VizError::CreateDir {
        path: frames.clone(),
        error,
    })?;
    let names = write_frames(&frames, v, req.every, req.exposure)?;
    if matches!(v.shape()[3], 4 | 12) {
        let pol = dir.join("polarization");
        std::fs::create_dir_all(&pol).map_err(|error| VizError::CreateDir {
            path: pol.clone(),
            error,
        })?;
        if v.shape()[3] == 4 {
            super::polarization::write_polarization(&pol, v, req.every, req.exposure)?;
        } else {
            let y = super::polarization::stokes_luminance(v);
            super::polarization::write_polarization(&pol, y.view(), req.every, req.exposure)?;
        }
    }
    if req.gif {
        write_gif(&dir.join("propagation.gif"), v, req.every, req.exposure, 60)?;
    }
    write_streak(
        &dir.join("streak.png"),
        v,
        req.streak_row,
        req.exposure,
        req.axis,
        &req.caption,
    )?;
    Ok(names.len())
}
