//! y-tal 0.20's phasor-field filter of a capture (`tal.reconstruct.filter_H` with
//! `filter_name='pf'`, border 'zero'), the first half of its filtered backprojection:
//! every (laser, sensor) time series is convolved with a complex pulse of wavelength
//! `wl_mean` under a Gaussian envelope of deviation `wl_sigma`,
//!
//! ```text
//!   K(t) = g(t) / sum g * exp(2 pi i t / wl_mean),   g(t) = exp(-((t - t_max / 2) / wl_sigma)^2 / 2),
//! ```
//!
//! on `nt + 2 (p - 1)` samples of `delta_t` (`p = round(6 wl_sigma / delta_t)`, made
//! even; the series padded with `p - 1` zeros on each side), by FFT (`rustfft`), and the
//! padding cut off again. y-tal builds K in single precision and transforms in double;
//! so does this.
//!
//! Memory: the filtered capture, complex f32, twice the capture's H.

use super::capture::Capture;
use super::fft::Planner;
use rayon::prelude::*;
use rustfft::num_complex::Complex;

/// The capture's H filtered, complex: `re` and `im` as (T, L, S) like `Capture::h`.
pub struct Filtered {
    pub re: Vec<f32>,
    pub im: Vec<f32>,
}

/// numpy's `linspace(0, stop, n)` in double precision, then single.
fn linspace_f32(stop: f64, n: usize) -> Vec<f32> {
    if n == 1 {
        return vec![0.0];
    }
    let step = stop / (n - 1) as f64;
    (0..n)
        .map(|i| {
            if i == n - 1 {
                stop as f32
            } else {
                (i as f64 * step) as f32
            }
        })
        .collect()
}

/// The padded length and the padding on each side for `nt` bins.
pub fn padding(nt: usize, wl_sigma: f64, delta_t: f64) -> (usize, usize) {
    let mut p = (6.0 * wl_sigma / delta_t).round_ties_even() as usize;
    if p % 2 == 1 {
        p += 1;
    }
    let pad = p.saturating_sub(1);
    (nt + 2 * pad, pad)
}

/// How the pulse's samples are rotated to put its centre at t = 0: element `n / 2`
/// first (numpy's `ifftshift`, the fbp filter's) or element `n - n / 2` first
/// (`fftshift`, the phasor-field solver's); the same for even `n`.
#[derive(Clone, Copy)]
pub enum Shift {
    Ifft,
    Fft,
}

/// The pulse K (centred at t = 0 by `shift`, complex), `n` samples of `delta_t`.
pub fn kernel(
    n: usize,
    delta_t: f64,
    wl_mean: f64,
    wl_sigma: f64,
    shift: Shift,
) -> Vec<Complex<f64>> {
    let t_max = delta_t * (n as f64 - 1.0);
    let t = linspace_f32(t_max, n);
    let (half, sigma) = ((t_max / 2.0) as f32, wl_sigma as f32);
    let g: Vec<f32> = t
        .iter()
        .map(|&ti| {
            let x = (ti - half) / sigma;
            (-(x * x) / 2.0).exp()
        })
        .collect();
    let sum: f32 = g.iter().sum();
    let w = (2.0 * std::f64::consts::PI) as f32 / wl_mean as f32;
    let k: Vec<Complex<f64>> = g
        .iter()
        .zip(&t)
        .map(|(&gi, &ti)| {
            let (s, c) = (ti * w).sin_cos();
            let a = gi / sum;
            Complex::new((a * c) as f64, (a * s) as f64)
        })
        .collect();
    let front = match shift {
        Shift::Ifft => n / 2,
        Shift::Fft => n - n / 2,
    };
    let mut shifted = k[front..].to_vec();
    shifted.extend_from_slice(&k[..front]);
    shifted
}

/// The filtered capture (see the module notes).
pub fn pf_filter(c: &Capture, wl_mean: f64, wl_sigma: f64) -> Filtered {
    let nt = c.time.bins;
    let (n, pad) = padding(nt, wl_sigma, c.time.bin_width_opl);
    let mut planner = Planner::new();
    let fft = planner.plan_fft_forward(n);
    let ifft = planner.plan_fft_inverse(n);
    let mut kf = kernel(n, c.time.bin_width_opl, wl_mean, wl_sigma, Shift::Ifft);
    fft.process(&mut kf);
    let series = c.lasers * c.sensors;
    let mut re = vec![0f32; nt * series];
    let mut im = vec![0f32; nt * series];
    // Each (laser, sensor) series on its own; results gathered per series.
    let block = Capture::SERIES_BLOCK;
    let filtered: Vec<Vec<Complex<f32>>> = (0..series.div_ceil(block))
        .into_par_iter()
        .flat_map_iter(|b| {
            let qs = b * block..((b + 1) * block).min(series);
            let h = c.series(qs.clone());
            let mut buf = vec![Complex::new(0.0, 0.0); n];
            (0..qs.len())
                .map(|k| {
                    buf.iter_mut().for_each(|z| *z = Complex::new(0.0, 0.0));
                    for (t, &v) in h[k * nt..(k + 1) * nt].iter().enumerate() {
                        buf[pad + t] = Complex::new(v as f64, 0.0);
                    }
                    fft.process(&mut buf);
                    for (z, k) in buf.iter_mut().zip(&kf) {
                        // y-tal keeps H's spectrum in complex64 before the product.
                        let h = Complex::new(z.re as f32 as f64, z.im as f32 as f64);
                        let p = h * k;
                        *z = Complex::new(p.re as f32 as f64, p.im as f32 as f64);
                    }
                    ifft.process(&mut buf);
                    let scale = 1.0 / n as f64;
                    (0..nt)
                        .map(|t| {
                            let z = buf[pad + t] * scale;
                            Complex::new(z.re as f32, z.im as f32)
                        })
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>()
        })
        .collect();
    for (q, f) in filtered.iter().enumerate() {
        for (t, z) in f.iter().enumerate() {
            re[t * series + q] = z.re;
            im[t * series + q] = z.im;
        }
    }
    Filtered { re, im }
}
