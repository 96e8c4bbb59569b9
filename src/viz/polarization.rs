//! Pictures of a Stokes volume (H, W, T, 4: S0, S1, S2, S3, a `mono_polarized`
//! film), after mitransient's `polarized_visualization.py` (Wilkie and Weidlich's
//! false colours): for every shown bin k, in the folder given,
//!
//! - `aolp_dolp_NNNN.png`: HSV with hue the angle of linear polarization
//!   `AoLP = 0.5 atan2(S2, S1)` (a half turn of the polarization plane is a full turn
//!   of hue: 0 and 180 degrees, along the frame's basis vector, are red; 45 degrees
//!   yellow-green, 90 cyan, 135 violet), saturation the degree of linear polarization
//!   `DoLP = sqrt(S1^2 + S2^2) / S0` clamped to [0, 1], and value the tone-mapped
//!   intensity S0 (the frames' exposure, sRGB): unpolarized light is grey, fully
//!   polarized light a pure hue;
//! - `s1_NNNN.png`, `s2_NNNN.png`, `s3_NNNN.png`: the normalised components
//!   `S1 / S0`, `S2 / S0`, `S3 / S0` in a diverging map from blue (-1) through white
//!   (0) to red (+1).
//!
//! Where S0 is below a thousandth of the exposure's white (`exposure * S0 < 1e-3`:
//! no light, or too little for its ratios to mean anything) the ratios are not
//! formed: the HSV picture is black there (its value) and the component pictures
//! black too. Memory: one picture (3 bytes a pixel) at a time.
//!
//! A spectral Stokes volume (H, W, T, 12: S0..S3 of R, then of G, then of B) is shown
//! through its luminance Stokes vector, `S_j = 0.2126 S_j.R + 0.7152 S_j.G + 0.0722
//! S_j.B` ([`stokes_luminance`]; a linear map, so it is the Stokes vector of the
//! luminance of the light), an (H, W, T, 4) copy.

use super::tonemap::srgb8;
use super::VizError;
use crate::polarization::{aolp, dolp};
use crate::report::plot::save_png_rgb;
use glam::Vec4;
use ndarray::{Array4, ArrayView4};
use std::path::Path;

/// Below this `exposure * S0` the polarization ratios are not formed (see the module
/// docs).
pub const S0_MIN_DISPLAY: f32 = 1e-3;

/// The luminance Stokes vector (H, W, T, 4) of a spectral Stokes volume (H, W, T, 12,
/// RGB-major: channel `4 c + j` is component j of colour c), see the module docs.
pub fn stokes_luminance(v: ArrayView4<f32>) -> Array4<f32> {
    let (h, w, t, c) = v.dim();
    assert_eq!(c, 12, "a spectral Stokes volume has twelve channels");
    Array4::from_shape_fn((h, w, t, 4), |(y, x, k, j)| {
        super::tonemap::luminance(v[[y, x, k, j]], v[[y, x, k, 4 + j]], v[[y, x, k, 8 + j]])
    })
}

/// HSV (each in [0, 1]; hue wraps) to RGB in [0, 1].
pub fn hsv_to_rgb(h: f32, s: f32, v: f32) -> [f32; 3] {
    let h6 = h.rem_euclid(1.0) * 6.0;
    let i = (h6.floor() as i32).rem_euclid(6);
    let f = h6 - h6.floor();
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match i {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

/// The diverging map at `x` in [-1, 1] (clamped; NaN as 0): blue, white, red.
pub fn diverging(x: f32) -> [u8; 3] {
    let x = if x.is_nan() { 0.0 } else { x.clamp(-1.0, 1.0) };
    let fade = |a: f32| (255.0 * (1.0 - a.abs()) + 0.5) as u8;
    if x >= 0.0 {
        [255, fade(x), fade(x)]
    } else {
        [fade(x), fade(x), 255]
    }
}

/// The HSV picture's pixel for Stokes vector `s` (see the module docs).
pub fn aolp_dolp_rgb(s: Vec4, exposure: f32) -> [u8; 3] {
    let lit = s.x * exposure >= S0_MIN_DISPLAY;
    if !lit {
        return [0, 0, 0];
    }
    let value = f32::from(srgb8(s.x * exposure)) / 255.0;
    let hue = aolp(s) / std::f32::consts::PI;
    let sat = dolp(s).clamp(0.0, 1.0);
    let sat = if sat.is_nan() { 0.0 } else { sat };
    hsv_to_rgb(hue, sat, value).map(|c| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
}

/// Writes the polarization pictures of the bins `frames` shows (every `every`-th)
/// into `dir` (which must exist); returns the number of bins written. `v` must have
/// four channels.
pub fn write_polarization(
    dir: &Path,
    v: ArrayView4<f32>,
    every: usize,
    exposure: f32,
) -> Result<usize, VizError> {
    let (h, w, t, c) = v.dim();
    assert_eq!(c, 4, "a Stokes volume has four channels");
    let digits = t.to_string().len().max(4);
    // The bins `frames` shows (`frames::shown_bins`; not imported: frames calls this).
    let bins: Vec<usize> = (0..t).step_by(every.max(1)).collect();
    let mut hsv = vec![0u8; h * w * 3];
    let mut comps = [
        vec![0u8; h * w * 3],
        vec![0u8; h * w * 3],
        vec![0u8; h * w * 3],
    ];
    for &k in &bins {
        for y in 0..h {
            for x in 0..w {
                let s = Vec4::new(
                    v[[y, x, k, 0]],
                    v[[y, x, k, 1]],
                    v[[y, x, k, 2]],
                    v[[y, x, k, 3]],
                );
                let o = (y * w + x) * 3;
                hsv[o..o + 3].copy_from_slice(&aolp_dolp_rgb(s, exposure));
                let lit = s.x * exposure >= S0_MIN_DISPLAY;
                for (i, img) in comps.iter_mut().enumerate() {
                    let px = if lit {
                        diverging(s[i + 1] / s.x)
                    } else {
                        [0, 0, 0]
                    };
                    img[o..o + 3].copy_from_slice(&px);
                }
            }
        }
        let (pw, ph) = (w as u32, h as u32);
        save_png_rgb(
            &dir.join(format!("aolp_dolp_{k:0digits$}.png")),
            &hsv,
            pw,
            ph,
        )?;
        for (i, img) in comps.iter().enumerate() {
            let name = format!("s{}_{k:0digits$}.png", i + 1);
            save_png_rgb(&dir.join(name), img, pw, ph)?;
        }
    }
    Ok(bins.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hsv_primaries_and_wrap() {
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6);
        assert!(close(hsv_to_rgb(0.0, 1.0, 1.0), [1.0, 0.0, 0.0]));
        assert!(close(hsv_to_rgb(1.0 / 3.0, 1.0, 1.0), [0.0, 1.0, 0.0]));
        assert!(close(hsv_to_rgb(2.0 / 3.0, 1.0, 1.0), [0.0, 0.0, 1.0]));
        assert!(close(hsv_to_rgb(-0.5, 1.0, 1.0), hsv_to_rgb(0.5, 1.0, 1.0)));
        assert!(close(hsv_to_rgb(0.3, 0.0, 0.5), [0.5, 0.5, 0.5]));
    }

    #[test]
    fn polarization_colours() {
        // Unpolarized: grey; fully polarized at 0 degrees: red, at 90: cyan.
        let grey = aolp_dolp_rgb(Vec4::new(1.0, 0.0, 0.0, 0.0), 1.0);
        assert!(grey[0] == grey[1] && grey[1] == grey[2] && grey[0] == 255);
        assert_eq!(
            aolp_dolp_rgb(Vec4::new(1.0, 1.0, 0.0, 0.0), 1.0),
            [255, 0, 0]
        );
        assert_eq!(
            aolp_dolp_rgb(Vec4::new(1.0, -1.0, 0.0, 0.0), 1.0),
            [0, 255, 255]
        );
        // No light: black.
        assert_eq!(aolp_dolp_rgb(Vec4::new(0.0, 0.0, 0.0, 0.0), 1.0), [0, 0, 0]);
        assert_eq!(diverging(0.0), [255, 255, 255]);
        assert_eq!(diverging(1.0), [255, 0, 0]);
        assert_eq!(diverging(-2.0), [0, 0, 255]);
        assert_eq!(diverging(f32::NAN), [255, 255, 255]);
    }
}
