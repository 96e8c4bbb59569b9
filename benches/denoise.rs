//! The statistical filter on a synthetic 64 x 64 x 100 bundle (r = 5, r_t = 1): tstat's
//! membership (emitter classes, depth alignment, patch test), the published Welch test,
//! and the base filter alone. Throughput in voxel-neighbour evaluations is printed by
//! `tstat denoise`; here criterion times the same kernel.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use tstat::denoise::base_filter::{BaseFilter, BaseKind, Features, Sigmas};
use tstat::denoise::estimates::{Estimates, SumsView};
use tstat::denoise::filter::{filter, FilterParams, Membership, Tiling, Welch};
use tstat::denoise::tstat::TstatParams;
use tstat::math::rng::Pcg32;

fn synthetic(h: usize, w: usize, t: usize, spp: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<u32>) {
    // A pulse sweeping across the image, sampled with zero-inflated noise.
    let mut rng = Pcg32::new(7, 1);
    let (mut x1, mut x2, mut x3) = (
        vec![0.0; h * w * t * 3],
        vec![0.0; h * w * t * 3],
        vec![0.0; h * w * t * 3],
    );
    let mut nonzero = vec![0u32; h * w * t];
    for y in 0..h {
        for x in 0..w {
            for k in 0..t {
                let centre = 20.0 + 0.5 * (x + y) as f64;
                let p = (-0.5 * ((k as f64 - centre) / 6.0).powi(2)).exp() * 0.5;
                let v = (y * w + x) * t + k;
                for _ in 0..spp {
                    if (rng.next_f32() as f64) < p {
                        nonzero[v] += 1;
                        for c in 0..3 {
                            let s = rng.next_f32() as f64 * (1.0 + c as f64);
                            x1[v * 3 + c] += s;
                            x2[v * 3 + c] += s * s;
                            x3[v * 3 + c] += s * s * s;
                        }
                    }
                }
            }
        }
    }
    (x1, x2, x3, nonzero)
}

fn bench_denoise(c: &mut Criterion) {
    let (h, w, t, spp) = (64, 64, 100, 32);
    let (x1, x2, x3, nonzero) = synthetic(h, w, t, spp);
    let est = Estimates::from_sums(&SumsView {
        height: h,
        width: w,
        bins: t,
        channels: 3,
        bin_width: 0.08,
        spp,
        stratified: false,
        image_rows: h,
        z0: 0.0,
        x1: &x1,
        x2: &x2,
        x3: &x3,
        sum: &x1,
        nonzero: &nonzero,
        replicates: None,
        pixel_spp: None,
    });
    let albedo: Vec<f32> = (0..h * w * 3)
        .map(|i| ((i / 3) % 7) as f32 / 10.0)
        .collect();
    let normal: Vec<f32> = (0..h * w * 3)
        .map(|i| if i % 3 == 2 { 1.0 } else { 0.0 })
        .collect();
    // A slanted plane (depth grows along x by about a bin per 4 pixels) with a light
    // in one corner.
    let depth: Vec<f32> = (0..h * w).map(|p| 3.0 + 0.02 * (p % w) as f32).collect();
    let emitter: Vec<f32> = (0..h * w)
        .map(|p| if p / w < 6 && p % w < 6 { 1.0 } else { 0.0 })
        .collect();
    let features = Features {
        albedo: &albedo,
        normal: &normal,
        depth: &depth,
        emitter: &emitter,
    };
    let base = BaseFilter {
        kind: BaseKind::Jbf,
        sigmas: Sigmas::default(),
    };
    let mut group = c.benchmark_group("denoise_64x64x100_r5_rt1");
    group.sample_size(10);
    group.throughput(Throughput::Elements((h * w * t) as u64 * 121 * 3));
    for (name, membership) in [
        ("tstat", Membership::Tstat(TstatParams::default())),
        (
            "published",
            Membership::Published(Welch {
                g2: 4.0,
                alpha: None,
            }),
        ),
        ("base-only", Membership::BaseOnly),
    ] {
        let params = FilterParams {
            radius: 5,
            temporal_radius: 1,
            base,
            membership,
            zero_border: false,
        };
        group.bench_function(name, |b| {
            b.iter(|| filter(&est, &features, &params, Tiling::default(), &|_| {}))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_denoise);
criterion_main!(benches);
