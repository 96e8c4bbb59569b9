//! The wave-based confocal reconstructions (`nlos::reconstruct::fk`, `nlos::reconstruct::lct`, `nlos::reconstruct::wave`):
//! point scatterers in closed form (centred, off-centre, with bins starting late or
//! early), the native grid and its resampling, linearity and symmetries, refused
//! captures, and the kernels (3-D FFT, Stolt step, LCT's resampling operator) against
//! slow direct formulas.

use rustfft::num_complex::Complex;
use rustfft::FftDirection;
use tstat::nlos::capture::Capture;
use tstat::nlos::reconstruct::bp::VoxelGrid;
use tstat::nlos::reconstruct::fk::{fk_migration, fk_native, stolt};
use tstat::nlos::reconstruct::lct::{lct, lct_native, resampling_rows, DEFAULT_SNR};
use tstat::nlos::reconstruct::wave::{fft3, Native, C64};
use tstat::nlos::NlosError;

/// A confocal capture of an `n` x `n` grid of cell centres of the wall [-1, 1]^2 in the
/// plane z = 0 (normal +z), `bins` bins of `delta_t` from `t_start`, H (bin, point)
/// from `f`.
fn capture(n: usize, bins: usize, t_start: f64, delta_t: f64, h: Vec<f32>) -> Capture {
    let c = |k: usize| -1.0 + (2.0 * k as f32 + 1.0) / n as f32;
    let grid: Vec<[f32; 3]> = (0..n)
        .flat_map(|i| (0..n).map(move |j| [c(i), c(j), 0.0]))
        .collect();
    Capture {
        time: tstat::sensors::time_axis::TimeAxis {
            start_opl: t_start,
            bin_width_opl: delta_t,
            bins,
        },
        lasers: 1,
        sensors: n * n,
        sensor_dims: [n, n],
        laser_dims: [1, 1],
        normal: [0.0, 0.0, 1.0],
        h,
        laser_grid: grid.clone(),
        sensor_grid: grid,
        paired: true,
        laser_xyz: None,
        sensor_xyz: None,
        accounts_first_and_last_bounces: false,
    }
}

/// The confocal capture of a point scatterer at `p`: at the bin of the OPL 2 |s - p| of
/// every wall point s, H = 1 / |s - p|^2, the falloff of the retroreflective model LCT
/// inverts by default (flat data over-weights the cone's late tails, and LCT's peak
/// then wanders by several bins for points near the wall's edges).
fn point_capture(n: usize, bins: usize, t_start: f64, delta_t: f64, p: [f64; 3]) -> Capture {
    let mut c = capture(n, bins, t_start, delta_t, vec![0.0; bins * n * n]);
    for s in 0..n * n {
        let q = c.sensor_grid[s].map(f64::from);
        let d = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2)).sqrt();
        let b = ((2.0 * d - t_start) / delta_t).floor();
        if b >= 0.0 && (b as usize) < bins {
            c.h[b as usize * n * n + s] = (1.0 / (d * d)) as f32;
        }
    }
    c
}

/// (i, j, k) of the maximum of an (a, b, c) row-major volume.
fn argmax(v: &[f32], dims: [usize; 3]) -> [usize; 3] {
    let best = v
        .iter()
        .enumerate()
        .fold((0, f32::MIN), |b, (i, &x)| if x > b.1 { (i, x) } else { b })
        .0;
    [
        best / (dims[1] * dims[2]),
        best / dims[2] % dims[1],
        best % dims[2],
    ]
}

/// The index coordinates of world point `p` on the native grid.
fn native_coords(g: &Native, p: [f64; 3]) -> [f64; 3] {
    let l2 = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>();
    let r = [0, 1, 2].map(|a| p[a] - g.origin[a]);
    let d = |v: [f64; 3]| v.iter().zip(&r).map(|(a, b)| a * b).sum::<f64>();
    [
        d(g.du) / l2(g.du),
        d(g.dv) / l2(g.dv),
        (d(g.normal) - g.t0 / 2.0) / (g.delta_t / 2.0),
    ]
}

fn max_abs(v: &[f32]) -> f32 {
    v.iter().fold(0f32, |m, &x| m.max(x.abs()))
}

type Recon = fn(&Capture) -> Result<(Native, Vec<f32>), tstat::nlos::NlosError>;

fn fk_n(c: &Capture) -> Result<(Native, Vec<f32>), tstat::nlos::NlosError> {
    fk_native(c)
}
fn lct_n(c: &Capture) -> Result<(Native, Vec<f32>), tstat::nlos::NlosError> {
    lct_native(c, DEFAULT_SNR)
}
const METHODS: [(&str, Recon); 2] = [("fk", fk_n), ("lct", lct_n)];

/// A point scatterer's reconstruction peaks at its native voxel (within one voxel on
/// every axis), for fk and LCT: centred and off-centre, with bins from OPL 0, from a
/// later start (zero bins put in front, a residual t0 of a fraction of a bin) and from
/// an earlier one (bins dropped). The peak on a coarse user grid lies at the
/// scatterer's voxel too.
#[test]
fn point_scatterers_peak_at_their_voxel() {
    let (n, dt) = (32, 0.016);
    // (scatterer, bins, t_start): depth 0.8024 is bin 100.3 from OPL 0.
    let cases = [
        ([0.0, 0.0, 0.8024], 256, 0.0),
        ([0.3, -0.2, 0.8024], 256, 0.0),
        ([0.3, -0.2, 0.8024], 200, 1.0013),
        ([-0.45, 0.5, 0.6], 300, -0.3),
    ];
    for (p, bins, t_start) in cases {
        let c = point_capture(n, bins, t_start, dt, p);
        for (name, f) in METHODS {
            let (g, vol) = f(&c).expect("a valid capture");
            let want = native_coords(&g, p);
            let got = argmax(&vol, [n, n, g.depths]);
            for a in 0..3 {
                assert!(
                    (got[a] as f64 - want[a]).abs() <= 1.0,
                    "{name}, scatterer {p:?}, t_start {t_start}: peak at native {got:?}, scatterer at {want:?}"
                );
            }
            if t_start > 0.0 {
                assert_eq!(g.pad, 63, "round(1.0013 / 0.016) zero bins in front");
                assert!((g.t0 - (1.0013 - 63.0 * dt)).abs() < 1e-12);
            }
            if t_start < 0.0 {
                assert_eq!((g.skip, g.depths), (19, 281));
            }
            // A coarse grid: 0.1 voxels around the scatterer.
            let grid = VoxelGrid {
                first: [p[0] - 0.5, p[1] - 0.5, p[2] - 0.3],
                last: [p[0] + 0.5, p[1] + 0.5, p[2] + 0.3],
                n: [11, 11, 7],
            };
            let v = if name == "fk" {
                fk_migration(&c, &grid)
            } else {
                lct(&c, &grid, DEFAULT_SNR)
            }
            .unwrap();
            let got = argmax(&v, grid.n);
            assert!(
                got.iter().zip([5, 5, 3]).all(|(&a, b)| a.abs_diff(b) <= 1),
                "{name}, scatterer {p:?}: coarse peak at {got:?}"
            );
        }
    }
}

/// On a voxel grid that coincides with the native grid the reconstruction is the
/// native volume, bit for bit; off the nodes the resampling is trilinear (exact on a
/// linear field), zero outside.
#[test]
fn native_grid_resampling_is_the_identity_and_trilinear() {
    let c = point_capture(16, 128, 0.5, 0.02, [0.1, 0.2, 0.5]);
    for (name, f) in METHODS {
        let (g, vol) = f(&c).unwrap();
        let grid = g.voxel_grid().expect("an axis-aligned wall");
        assert_eq!(grid.n, [16, 16, g.depths]);
        let out = if name == "fk" {
            fk_migration(&c, &grid)
        } else {
            lct(&c, &grid, DEFAULT_SNR)
        }
        .unwrap();
        assert!(
            out == vol,
            "{name}: the native grid reads the native volume"
        );
        assert!(max_abs(&vol) > 0.0);
    }
    // A linear field on the native grid, read between the nodes and outside.
    let g = Native::of(&c, "test").unwrap();
    let (n, m) = (g.n, g.depths);
    let lin = |i: f64, j: f64, k: f64| 10.0 + 0.5 * i - 0.25 * j + 0.125 * k;
    let mut vol = vec![0f32; n * n * m];
    for i in 0..n {
        for j in 0..n {
            for k in 0..m {
                vol[(i * n + j) * m + k] = lin(i as f64, j as f64, k as f64) as f32;
            }
        }
    }
    let a = g.point(10, 3, 4);
    let b = g.point(m - 1, n - 1, n - 1);
    let grid = VoxelGrid {
        first: a,
        last: [b[0] + 0.3, b[1], b[2]],
        n: [7, 5, 9],
    };
    let out = g.resample(&vol, &grid);
    for x in 0..7 {
        for y in 0..5 {
            for z in 0..9 {
                let p = [0, 1, 2].map(|ax| grid.coordinate(ax, [x, y, z][ax]) as f64);
                let f = native_coords(&g, p);
                let v = out[(x * 5 + y) * 9 + z] as f64;
                if f[0] > (n - 1) as f64 + 1e-3 {
                    assert_eq!(v, 0.0, "outside the native grid");
                } else {
                    let want = lin(f[0], f[1], f[2]);
                    assert!((v - want).abs() < 1e-4 * want, "{v} vs {want} at {f:?}");
                }
            }
        }
    }
}

/// Linearity (fk squares a linear map: 2H gives 4x; LCT is linear before its clamp at
/// 0: 2x) and symmetry: swapping the grid's axes transposes the volume, a capture
/// mirrored along i gives the mirrored volume (both).
#[test]
fn reconstructions_are_linear_and_symmetric() {
    let n = 16;
    let c = point_capture(n, 128, 0.0, 0.02, [0.23, -0.41, 0.5]);
    let mut c2 = point_capture(n, 128, 0.0, 0.02, [-0.3, 0.1, 0.7]);
    for (a, b) in c2.h.iter_mut().zip(&c.h) {
        *a = 0.7 * *a + b;
    }
    let c = c2;
    let m = c.time.bins;
    let remap = |f: &dyn Fn(usize, usize) -> (usize, usize)| {
        let mut d = c.clone_h();
        for t in 0..m {
            for i in 0..n {
                for j in 0..n {
                    let (a, b) = f(i, j);
                    d.h[t * n * n + i * n + j] = c.h[t * n * n + a * n + b];
                }
            }
        }
        d
    };
    let doubled = {
        let mut d = c.clone_h();
        d.h.iter_mut().for_each(|v| *v *= 2.0);
        d
    };
    let mirrored = remap(&|i, j| (n - 1 - i, j));
    let swapped = remap(&|i, j| (j, i));
    for (name, f) in METHODS {
        let (_, v) = f(&c).unwrap();
        let top = max_abs(&v);
        let close = |a: f32, b: f32, what: &str| {
            assert!(
                (a - b).abs() <= 1e-5 * top,
                "{name}, {what}: {a} vs {b} (max {top})"
            );
        };
        let at = |v: &[f32], i: usize, j: usize, k: usize| v[(i * n + j) * m + k];
        let (_, v2) = f(&doubled).unwrap();
        let gain = if name == "fk" { 4.0 } else { 2.0 };
        for (a, b) in v2.iter().zip(&v) {
            assert!(
                (a - gain * b).abs() <= 1e-5 * gain * top,
                "{name}: linearity"
            );
        }
        let (_, vs) = f(&swapped).unwrap();
        let (_, vm) = f(&mirrored).unwrap();
        for i in 0..n {
            for j in 0..n {
                for k in 0..m {
                    close(at(&vs, i, j, k), at(&v, j, i, k), "swapped axes");
                    close(at(&vm, i, j, k), at(&v, n - 1 - i, j, k), "mirrored");
                }
            }
        }
    }
}

trait CloneH {
    fn clone_h(&self) -> Capture;
}
impl CloneH for Capture {
    fn clone_h(&self) -> Capture {
        capture(
            self.sensor_dims[0],
            self.time.bins,
            self.time.start_opl,
            self.time.bin_width_opl,
            self.h.clone(),
        )
    }
}

/// Captures fk and LCT cannot take are errors, never panics; the memory they need is
/// the stated formula.
#[test]
fn unsuitable_captures_are_refused() {
    let good = || point_capture(8, 64, 0.0, 0.05, [0.0, 0.0, 0.5]);
    let grid = VoxelGrid {
        first: [-1.0; 3],
        last: [1.0; 3],
        n: [4, 4, 4],
    };
    // (what, the capture, words of the reason each method gives after its name)
    let mut cases: Vec<(&str, Capture, &str)> = Vec::new();
    let mut c = good();
    c.paired = false;
    cases.push(("not confocal", c, "reconstructs confocal captures only"));
    let mut c = good();
    c.sensor_dims = [4, 16];
    cases.push((
        "not square",
        c,
        "needs a square sensor grid of at least 2 x 2 points, got 4 x 16",
    ));
    let mut c = good();
    c.sensor_grid[9][0] += 0.01;
    cases.push((
        "irregular",
        c,
        "needs a regular planar grid; point (1, 1) lies",
    ));
    let mut c = good();
    for p in c.sensor_grid.iter_mut() {
        p[0] *= 2.0;
    }
    cases.push((
        "rectangular cells",
        c,
        "needs a square grid of square cells",
    ));
    let mut c = good();
    for p in c.sensor_grid.iter_mut() {
        p[0] += 0.1 * p[1];
    }
    cases.push(("sheared", c, "needs a square grid of square cells"));
    let mut c = good();
    c.normal = [0.0, 1.0, 0.0];
    cases.push((
        "normal in the wall",
        c,
        "is not perpendicular to the sensor grid",
    ));
    let mut c = good();
    c.accounts_first_and_last_bounces = true;
    cases.push((
        "first and last bounces",
        c,
        "this capture's times include the first and last bounces",
    ));
    let mut c = good();
    c.h.truncate(64);
    c.time.bins = 1;
    cases.push(("one bin", c, "needs at least 2 time bins, got 1"));
    let mut c = good();
    c.h.pop();
    cases.push(("short H", c, "H holds 4095 values for 64 bins of 64 points"));
    let mut c = good();
    c.h[5] = f32::NAN;
    cases.push(("NaN", c, "H holds a non-finite value (bin 0, point 5)"));
    let mut c = good();
    c.time.start_opl = 1e30;
    cases.push(("far start", c, "bins can be put in front"));
    let mut c = good();
    c.time.start_opl = -10.0;
    cases.push((
        "all bins before OPL 0",
        c,
        "keeps 0 bins from OPL 0 on; at least 2 are needed",
    ));
    let mut c = good();
    c.time.bin_width_opl = 0.0;
    cases.push((
        "zero bin width",
        c,
        "is not finite with a positive bin width",
    ));
    let mut c = capture(1, 64, 0.0, 0.05, vec![0.0; 64]);
    c.sensor_dims = [1, 1];
    cases.push((
        "one point",
        c,
        "needs a square sensor grid of at least 2 x 2 points, got 1 x 1",
    ));
    for (what, c, why) in &cases {
        for (method, r) in [
            ("fk", fk_migration(c, &grid)),
            ("lct", lct(c, &grid, DEFAULT_SNR)),
        ] {
            let Err(e) = r else {
                panic!("{method} takes a capture: {what}")
            };
            let e = e.to_string();
            assert!(
                e.starts_with(method) && e.contains(why),
                "{method}, {what}: {e}"
            );
        }
        // Estimates never panic either.
        let _ = (
            tstat::nlos::reconstruct::fk::memory_bytes(c),
            tstat::nlos::reconstruct::lct::memory_bytes(c),
        );
    }
    for snr in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let r = lct(&good(), &grid, snr);
        assert!(
            matches!(r, Err(NlosError::LctSnr(s)) if s.to_bits() == snr.to_bits()),
            "snr {snr}: {:?}",
            r.err()
        );
    }
    // Memory: (2M' 2N 2N) complex volumes (one for fk, two for lct) + the native f32.
    let mut c = good();
    c.time.start_opl = 0.5; // 10 bins in front: M' = 74
    let (n, m) = (8usize, 74usize);
    let vol = 2 * m * 2 * n * 2 * n * 16;
    assert_eq!(
        tstat::nlos::reconstruct::fk::memory_bytes(&c),
        vol + 4 * m * n * n
    );
    assert_eq!(
        tstat::nlos::reconstruct::lct::memory_bytes(&c),
        2 * vol + 4 * m * n * n + m * 48
    );
}

/// Deterministic pseudo-random numbers in [-1, 1).
fn noise(k: usize) -> f64 {
    let mut x = (k as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    x ^= x >> 29;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 32;
    (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// The 3-D FFT against the direct triple sum, both directions, odd and even sizes.
#[test]
fn fft3_is_the_dft() {
    for dims in [[3, 4, 5], [2, 6, 1], [1, 1, 7], [4, 2, 6]] {
        let [d0, d1, d2] = dims;
        let x: Vec<C64> = (0..d0 * d1 * d2)
            .map(|k| Complex::new(noise(2 * k), noise(2 * k + 1)))
            .collect();
        for (dir, sign) in [(FftDirection::Forward, -1.0), (FftDirection::Inverse, 1.0)] {
            let mut y = x.clone();
            fft3(&mut y, dims, dir);
            for k0 in 0..d0 {
                for k1 in 0..d1 {
                    for k2 in 0..d2 {
                        let mut s = C64::new(0.0, 0.0);
                        for n0 in 0..d0 {
                            for n1 in 0..d1 {
                                for n2 in 0..d2 {
                                    let ph = sign
                                        * 2.0
                                        * std::f64::consts::PI
                                        * ((k0 * n0) as f64 / d0 as f64
                                            + (k1 * n1) as f64 / d1 as f64
                                            + (k2 * n2) as f64 / d2 as f64);
                                    s += x[(n0 * d1 + n1) * d2 + n2] * C64::from_polar(1.0, ph);
                                }
                            }
                        }
                        let got = y[(k0 * d1 + k1) * d2 + k2];
                        assert!((got - s).norm() < 1e-12, "{dims:?} {dir:?}: {got} vs {s}");
                    }
                }
            }
        }
    }
}

/// The Stolt step against y-tal's formula written out directly: fftshift, for every
/// frequency (z, y, x) the linear interpolation along z at sqrt(s^2 (x^2 + y^2) + z^2)
/// (the interval found by a scan, zero beyond the last sample), times [z > 0] |z| /
/// max S, ifftshift.
#[test]
fn stolt_matches_the_direct_formula() {
    for (n, m, s) in [(2usize, 3usize, 0.7), (3, 4, 1.9), (2, 5, 0.05)] {
        let (n2, m2) = (2 * n, 2 * m);
        let f: Vec<C64> = (0..n2 * n2 * m2)
            .map(|k| Complex::new(noise(3 * k), noise(3 * k + 7)))
            .collect();
        let mut got = f.clone();
        stolt(&mut got, n, m, s);
        // Shifted views: frequency index q in [0, 2L) is (q - L) / L.
        let unshift = |q: usize, l: usize| (q + l) % (2 * l);
        let at = |zq: usize, yq: usize, xq: usize| {
            f[(unshift(yq, n) * n2 + unshift(xq, n)) * m2 + unshift(zq, m)]
        };
        let zg: Vec<f64> = (0..m2).map(|q| (q as f64 - m as f64) / m as f64).collect();
        let fr = |q: usize| (q as f64 - n as f64) / n as f64;
        let mut smax = 0f64;
        for &z in &zg {
            for yq in 0..n2 {
                for xq in 0..n2 {
                    let (y, x) = (fr(yq), fr(xq));
                    smax = smax.max((s * s * (x * x + y * y) + z * z).sqrt());
                }
            }
        }
        for zq in 0..m2 {
            for yq in 0..n2 {
                for xq in 0..n2 {
                    let (z, y, x) = (
                        zg[zq],
                        (yq as f64 - n as f64) / n as f64,
                        (xq as f64 - n as f64) / n as f64,
                    );
                    let sq = (s * s * (x * x + y * y) + z * z).sqrt();
                    let mut want = C64::new(0.0, 0.0);
                    if z > 0.0 && sq <= zg[m2 - 1] {
                        let i = (0..m2 - 1)
                            .rev()
                            .find(|&i| zg[i] <= sq)
                            .expect("inside the samples");
                        let t = (sq - zg[i]) / (zg[i + 1] - zg[i]);
                        want =
                            (at(i, yq, xq) * (1.0 - t) + at(i + 1, yq, xq) * t) * (z.abs() / smax);
                    }
                    let g = got[(unshift(yq, n) * n2 + unshift(xq, n)) * m2 + unshift(zq, m)];
                    assert!((g - want).norm() <= 1e-14, "n {n} m {m}: {g} vs {want}");
                }
            }
        }
    }
}

/// LCT's resampling operator against the reference's construction: the M^2 x M matrix
/// with 1 / sqrt(x) at (x, ceil(sqrt x)), rows averaged in pairs log2 M times. Dense for
/// small M; row by row (the pairwise means of each block) for M = 1024, where the
/// closed-form sums of long ranges take over.
#[test]
fn lct_resampling_operator_matches_the_reference() {
    fn ceil_sqrt(x: usize) -> usize {
        let mut r = (x as f64).sqrt() as usize;
        while r * r > x {
            r -= 1;
        }
        while (r + 1) * (r + 1) <= x {
            r += 1;
        }
        if r * r == x {
            r
        } else {
            r + 1
        }
    }
    for m in [2usize, 8, 64, 1024] {
        let rows = resampling_rows(m);
        assert_eq!(rows.len(), m);
        for (r, row) in rows.iter().enumerate() {
            // The block of rows x = r M + 1 ..= (r + 1) M as sparse (column, value) lists,
            // averaged pairwise as the reference halves the matrix.
            let mut level: Vec<Vec<(usize, f64)>> = (r * m + 1..=(r + 1) * m)
                .map(|x| vec![(ceil_sqrt(x) - 1, 1.0 / (x as f64).sqrt())])
                .collect();
            while level.len() > 1 {
                level = level
                    .chunks(2)
                    .map(|p| {
                        let mut out: Vec<(usize, f64)> = Vec::new();
                        let mut add = |c: usize, v: f64| match out.iter_mut().find(|e| e.0 == c) {
                            Some(e) => e.1 += v,
                            None => out.push((c, v)),
                        };
                        for e in p[0].iter().chain(p[1].iter()) {
                            add(e.0, 0.5 * e.1);
                        }
                        out.sort_by_key(|e| e.0);
                        out
                    })
                    .collect();
            }
            let want = &level[0];
            assert_eq!(
                row.iter().map(|e| e.0).collect::<Vec<_>>(),
                want.iter().map(|e| e.0).collect::<Vec<_>>(),
                "M {m}, row {r}: columns"
            );
            for (a, b) in row.iter().zip(want) {
                assert!(
                    (a.1 - b.1).abs() <= 1e-13 * b.1,
                    "M {m}, row {r}, column {}: {} vs {}",
                    a.0,
                    a.1,
                    b.1
                );
            }
        }
    }
}

/// End to end on the bundled hidden letter (`scenes/nlos_T.xml`, its wall [-1, 1]^2 in
/// z = 0, the T at depth 1): a 16 x 16 render with bins from OPL 1.0 (63 zero bins put
/// in front), read from the bundle and from its y-tal export alike (the same volumes,
/// bit for bit); fk and LCT both put the maximum at depth 1 (within one 0.05 voxel) and
/// over the letter.
#[test]
fn the_hidden_letter_from_a_bundle_and_its_export() {
    use std::process::Command;
    let dir = tempfile::tempdir().unwrap();
    let bundle = dir.path().join("T.tstats");
    let h5 = dir.path().join("T.hdf5");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/nlos_T.xml");
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_tstat"))
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let (b, h) = (bundle.to_str().unwrap(), h5.to_str().unwrap());
    run(&[
        "render",
        scene,
        "--out",
        b,
        "-D",
        "res=16",
        "--spp",
        "16",
        "--bins",
        "256",
        "--start-opl",
        "1.0",
        "--bin-width-opl",
        "0.008",
    ]);
    run(&["export", b, "--tal", h]);
    let from_bundle = Capture::from_bundle(&tstat::bundle::Bundle::open(&bundle).unwrap()).unwrap();
    let from_tal = Capture::from_tal(&h5).unwrap();
    let grid = VoxelGrid {
        first: [-1.0, -1.0, 0.5],
        last: [1.0, 1.0, 1.5],
        n: [41, 41, 21],
    };
    for name in ["fk", "lct"] {
        let rec = |c: &Capture| {
            if name == "fk" {
                fk_migration(c, &grid)
            } else {
                lct(c, &grid, DEFAULT_SNR)
            }
            .unwrap()
        };
        let v = rec(&from_bundle);
        assert!(v == rec(&from_tal), "{name}: bundle and export");
        let [i, j, k] = argmax(&v, grid.n);
        let p = [
            -1.0 + 0.05 * i as f64,
            -1.0 + 0.05 * j as f64,
            0.5 + 0.05 * k as f64,
        ];
        // The letter: bar |x| <= 0.4, y in [0.24, 0.4]; stem |x| <= 0.08, y in [-0.56, 0.24].
        let on_letter = (p[0].abs() <= 0.45 && (0.19..=0.45).contains(&p[1]))
            || (p[0].abs() <= 0.13 && (-0.61..=0.29).contains(&p[1]));
        assert!(
            (p[2] - 1.0).abs() <= 0.05 + 1e-9 && on_letter,
            "{name}: maximum at {p:?}"
        );
    }
}
