//! The tracer is compiled once per instruction set (`cpu`): every level this
//! CPU has must trace every path to the same bits as the portable baseline, on a flat
//! scene (triangle packets), one with spheres, one with a BVH (the bunny), one with
//! anisotropic materials (frames from dp/du on a cube and a sphere), one with a
//! participating medium (the path loop's media rules, `render/tracer.rs`) and the
//! `null` and `thindielectric` surfaces.
//! A separate test binary, since it switches the process-wide level.

mod common;

use tstat::cpu::{self, Isa};
use tstat::math::rng::Pcg32;
use tstat::render::deposits::PathDeposits;
use tstat::render::integrator::PathTally;
use tstat::render::tracer::trace_path;
use tstat::scene::{Overrides, Scene};

fn scene(name: &str) -> Scene {
    let o = Overrides {
        width: Some(24),
        bins: Some(64),
        ..Default::default()
    };
    common::bundled(name, &o)
}

/// Every path of a 24 x 24 image, 4 per pixel: deposits, steady sums, G-buffer samples
/// and ray counts, as bits.
fn trace_all(scene: &Scene) -> Vec<u64> {
    let mut out = Vec::new();
    let mut deposits = PathDeposits::default();
    let (w, h) = (scene.film.width, scene.film.height);
    for y in 0..h {
        for x in 0..w {
            let pixel = (y * w + x) as u64;
            for s in 0..4u64 {
                let mut rng = Pcg32::for_path(7, pixel, s);
                let [u, v] = rng.next_2d();
                let d = scene.camera.direction(x as f32 + u, y as f32 + v);
                let mut tally = PathTally::default();
                let g = trace_path(scene, d, &mut rng, &mut deposits, &mut tally);
                for (bin, c) in deposits.drain() {
                    out.push(bin as u64);
                    out.extend(c.iter().map(|v| v.to_bits()));
                }
                out.extend(tally.steady.iter().map(|v| v.to_bits()));
                out.push(tally.rays);
                out.extend(g.albedo.to_array().iter().map(|v| v.to_bits() as u64));
                out.extend(g.normal.to_array().iter().map(|v| v.to_bits() as u64));
                out.push(g.depth.map_or(u64::MAX, |d| d.to_bits() as u64));
                out.push(g.emitter as u64);
                out.push(g.medium as u64);
            }
        }
    }
    out
}

#[test]
fn every_instruction_set_traces_the_same_bits() {
    let levels: Vec<Isa> = [Isa::Avx2, Isa::Avx512]
        .into_iter()
        .filter(|i| i.supported())
        .collect();
    for name in [
        "cbox.xml",
        "cbox_spheres.xml",
        "bunny.xml",
        "cbox_aniso.xml",
        "cbox_fog.xml",
        "cbox_null.xml",
        "cbox_thin.xml",
    ] {
        let scene = scene(name);
        cpu::force(Isa::Baseline).unwrap();
        let reference = trace_all(&scene);
        assert!(
            reference.len() > 24 * 24 * 4 * 12,
            "{name}: paths deposited nothing"
        );
        for &isa in &levels {
            cpu::force(isa).unwrap();
            assert!(
                trace_all(&scene) == reference,
                "{name}: {isa:?} differs from baseline"
            );
        }
    }
    cpu::force(Isa::best()).unwrap();
    assert_eq!(cpu::current(), Isa::best());
}
