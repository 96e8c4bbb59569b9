//! Backprojection (`nlos reconstruct --method bp` and `fbp`) of a synthetic capture the
//! size of scenes/nlos_T_exhaustive.xml's (8 x 8 laser x 8 x 8 sensor points, 512 bins
//! of 0.004 from 1.902) and of a confocal 32 x 32 one, on y-tal's 40 x 40 x 20 volume
//! of scripts/tal_roundtrip.py. Throughput in voxel-pair evaluations.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use tstat::math::rng::Pcg32;
use tstat::nlos::capture::Capture;
use tstat::nlos::reconstruct::bp::{backproject, filtered_backproject, VoxelGrid};

/// An n x n grid of points on the wall [-1, 1]^2 at z = 0 (cell centres).
fn wall(n: usize) -> Vec<[f32; 3]> {
    let c = |k: usize| -1.0 + (2 * k + 1) as f32 / n as f32;
    (0..n)
        .flat_map(|i| (0..n).map(move |j| [c(i), c(j), 0.0]))
        .collect()
}

fn capture(lasers: usize, sensors: usize, paired: bool) -> Capture {
    let mut rng = Pcg32::new(7, 1);
    let (sensor_grid, laser_grid) = (wall(sensors), wall(lasers));
    let nl = if paired { 1 } else { laser_grid.len() };
    let bins = 512;
    let h = (0..bins * nl * sensor_grid.len())
        .map(|_| rng.next_f32())
        .collect();
    Capture {
        time: tstat::sensors::time_axis::TimeAxis {
            start_opl: 1.902,
            bin_width_opl: 0.004,
            bins,
        },
        lasers: nl,
        sensors: sensor_grid.len(),
        sensor_dims: [sensors, sensors],
        laser_dims: if paired { [1, 1] } else { [lasers, lasers] },
        normal: [0.0, 0.0, 1.0],
        h,
        laser_grid: if paired {
            sensor_grid.clone()
        } else {
            laser_grid
        },
        sensor_grid,
        paired,
        laser_xyz: None,
        sensor_xyz: None,
        accounts_first_and_last_bounces: false,
    }
}

fn bench_bp(c: &mut Criterion) {
    let grid = VoxelGrid {
        first: [-0.975, -0.975, 0.525],
        last: [0.975, 0.975, 1.475],
        n: [40, 40, 20],
    };
    for (name, cap) in [
        ("exhaustive_8x8x8x8", capture(8, 8, false)),
        ("confocal_32x32", capture(32, 32, true)),
    ] {
        let mut group = c.benchmark_group(format!("bp_{name}_40x40x20"));
        group.sample_size(10);
        group.throughput(Throughput::Elements(
            (grid.voxels() * cap.lasers * cap.sensors) as u64,
        ));
        group.bench_function("bp", |b| b.iter(|| backproject(&cap, &grid)));
        group.bench_function("fbp", |b| {
            b.iter(|| filtered_backproject(&cap, &grid, 0.4, 0.4 / 2f64.sqrt()))
        });
        group.finish();
    }
}

criterion_group!(benches, bench_bp);
criterion_main!(benches);
