//! Tone mapping with ONE exposure for a whole volume, so light visibly arrives and
//! fades across frames (no per-frame renormalisation).
//!
//! exposure = 1 / (99.5th percentile of the luminance of the non-zero voxels); a voxel
//! maps to sRGB-encoded `clamp(exposure * rgb, 0, 1)`.
//!
//! Volumes of C channels: RGB (C = 3) as they are; a mono film's one channel Y
//! (C = 1) and a Stokes film's intensity S0 (C = 4: S0, S1, S2, S3) as grey, the
//! channel replicated into R, G and B ([`shown_channels`]), its luminance that
//! channel; a spectral Stokes film's (C = 12, RGB-major) intensity S0.R, S0.G, S0.B
//! in colour.

use ndarray::ArrayView4;

/// Rec. 709 luminance.
#[inline]
pub fn luminance(r: f32, g: f32, b: f32) -> f32 {
    0.2126 * r + 0.7152 * g + 0.0722 * b
}

/// The channels of a C-channel voxel shown as R, G, B: `[0, 1, 2]` for RGB; S0.R,
/// S0.G, S0.B of a spectral Stokes film (`[0, 4, 8]`); the first channel as grey
/// otherwise (Y of a mono film, S0 of a Stokes one).
#[inline]
pub fn shown_channels(c: usize) -> [usize; 3] {
    match c {
        3 => [0, 1, 2],
        12 => [0, 4, 8],
        _ => [0, 0, 0],
    }
}

/// Whether a C-channel volume is shown in colour ([`shown_channels`]).
#[inline]
pub fn in_colour(c: usize) -> bool {
    c == 3 || c == 12
}

/// The global exposure of an (H, W, T, C) volume (1 when it is all zero).
pub fn global_exposure(v: ArrayView4<f32>) -> f32 {
    let c = v.shape()[3];
    let [r, g, b] = shown_channels(c);
    let mut lum: Vec<f32> = v
        .rows()
        .into_iter()
        .map(|p| {
            if in_colour(c) {
                luminance(p[r], p[g], p[b])
            } else {
                p[r]
            }
        })
        .filter(|&l| l > 0.0 && l.is_finite())
        .collect();
    if lum.is_empty() {
        return 1.0;
    }
    let k = ((lum.len() as f64 * 0.995) as usize).min(lum.len() - 1);
    let (_, p, _) = lum.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    1.0 / *p
}

/// Linear to sRGB-encoded 8 bits.
#[inline]
pub fn srgb8(x: f32) -> u8 {
    let x = if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_endpoints_and_monotone() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        assert_eq!(srgb8(7.0), 255);
        assert_eq!(srgb8(f32::NAN), 0);
        assert!(srgb8(0.2) < srgb8(0.21));
        // 18% grey encodes to ~118.
        assert!((srgb8(0.18) as i32 - 118).abs() <= 1);
    }

    #[test]
    fn exposure_is_the_inverse_high_percentile() {
        let mut v = ndarray::Array4::<f32>::zeros((1, 10, 100, 3));
        // 1000 voxels; 200 non-zero with luminance 1..=200 (grey).
        for i in 0..200 {
            let (x, t) = (i % 10, i / 10);
            v[[0, x, t, 0]] = (i + 1) as f32;
            v[[0, x, t, 1]] = (i + 1) as f32;
            v[[0, x, t, 2]] = (i + 1) as f32;
        }
        let e = global_exposure(v.view());
        assert!((1.0 / e - 200.0).abs() < 1e-3, "{}", 1.0 / e);
        assert_eq!(
            global_exposure(ndarray::Array4::<f32>::zeros((1, 1, 1, 3)).view()),
            1.0
        );
        // Mono: the one channel; Stokes: S0 alone (S1..S3, signed, do not count).
        let mono = v.slice(ndarray::s![.., .., .., 0..1]).to_owned();
        assert_eq!(global_exposure(mono.view()), e);
        let mut stokes = ndarray::Array4::<f32>::zeros((1, 10, 100, 4));
        stokes
            .slice_mut(ndarray::s![.., .., .., 0..1])
            .assign(&mono);
        stokes.slice_mut(ndarray::s![.., .., .., 1]).fill(1e6);
        stokes.slice_mut(ndarray::s![.., .., .., 3]).fill(-1e6);
        assert_eq!(global_exposure(stokes.view()), e);
    }
}
