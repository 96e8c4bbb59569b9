//! The path loop's two rule sets (`render/tracer.rs`) estimate the same thing.
//!
//! Mitsuba's `path` rules (`transient_path`) and `volpath` rules
//! (`transient_prbvolpath`) differ in where Russian roulette falls (after BSDF sampling
//! from `depth >= rr_depth`, or before the ray from `depth > rr_depth`) and in the order
//! of the depth test, not in the light paths they count, as long as the scene has no
//! media and no null events (which `volpath` does not count as vertices). So on such
//! scenes the two instantiations of the loop, rendered with independent seeds, must
//! agree voxel block by voxel block: a Welch test per block of 8 x 8 pixels at one
//! time bin and channel (the pixels' paths are independent, so the block's mean and
//! its variance are sums of the pixels'), with the mean of t^2 not above 1 by more
//! than chance allows and the rejections at |t| > 3.29 (two-sided 0.1%) near their
//! binomial expectation. (The mean of t^2 comes out below 1, ~0.8: on skewed samples
//! the sample mean and variance rise together, which makes t conservative; only a
//! mean above 1 says the expectations differ.) The same comparison must reject one
//! render scaled by 1.05, so it can fail.

use crate::common;

use tstat::render::RenderOutput;
use tstat::scene::{Overrides, Scene};

const SPP: u32 = 1024;
const BLOCK: usize = 8;
/// Blocks with fewer non-zero samples than this in either render are skipped (their t
/// is far from normal).
const MIN_NONZERO: u32 = 64;

fn scene(name: &str) -> Scene {
    let o = Overrides {
        width: Some(32),
        height: Some(32),
        bins: Some(40),
        spp: Some(SPP),
        ..Default::default()
    };
    common::bundled(name, &o)
}

/// Per block (8 x 8 pixels, one bin, one channel): the sum of the pixels' means, the
/// sum of the variances of those means, and the non-zero samples.
fn blocks(out: &RenderOutput, scale: f64) -> Vec<(f64, f64, u32)> {
    let a = &out.accum;
    let (w, h, t) = (a.width, a.height, a.bins);
    let n = SPP as f64;
    let mut v = Vec::new();
    for by in 0..h / BLOCK {
        for bx in 0..w / BLOCK {
            for bin in 0..t {
                for c in 0..3 {
                    let (mut mean, mut var, mut nonzero) = (0.0, 0.0, 0);
                    for y in by * BLOCK..(by + 1) * BLOCK {
                        for x in bx * BLOCK..(bx + 1) * BLOCK {
                            let voxel = (y * w + x) * t + bin;
                            let (x1, x2) = (a.x1[voxel * 3 + c] * scale, a.x2[voxel * 3 + c]);
                            let x2 = x2 * scale * scale;
                            let m = x1 / n;
                            let s2 = (x2 / n - m * m).max(0.0) * n / (n - 1.0);
                            mean += m;
                            var += s2 / n;
                            nonzero += a.nonzero[voxel];
                        }
                    }
                    v.push((mean, var, nonzero));
                }
            }
        }
    }
    v
}

/// The Welch statistics of the blocks both renders fill: (blocks, mean t^2,
/// rejections at |t| > 3.29).
fn welch(a: &[(f64, f64, u32)], b: &[(f64, f64, u32)]) -> (usize, f64, usize) {
    let (mut count, mut t2, mut rejected) = (0, 0.0, 0);
    for (&(ma, va, na), &(mb, vb, nb)) in a.iter().zip(b) {
        if na < MIN_NONZERO || nb < MIN_NONZERO || va + vb <= 0.0 {
            continue;
        }
        let t = (ma - mb) / (va + vb).sqrt();
        count += 1;
        t2 += t * t;
        rejected += (t.abs() > 3.29) as usize;
    }
    (count, t2 / count.max(1) as f64, rejected)
}

/// Whether the statistics say "the same expectation": the mean of t^2 at most 5
/// standard deviations above 1 (t^2 ~ chi^2(1): variance 2), and the rejections within
/// 4 standard deviations (+3) of their binomial expectation.
fn agree(count: usize, mean_t2: f64, rejected: usize) -> bool {
    let expected = 0.001 * count as f64;
    mean_t2 - 1.0 <= 5.0 * (2.0 / count as f64).sqrt()
        && (rejected as f64) <= expected + 4.0 * expected.sqrt() + 3.0
}

#[test]
fn surface_and_media_rules_agree_without_media() {
    for name in [
        "cbox.xml",
        "cbox_spheres.xml",
        "cbox_rough.xml",
        "cbox_materials.xml",
    ] {
        let surface = scene(name);
        assert!(
            !surface.integrator.volumetric,
            "{name}: not a transient_path scene"
        );
        let mut media_rules = scene(name);
        media_rules.integrator.volumetric = true;
        let a = blocks(&common::run(&surface, 1), 1.0);
        let b_out = common::run(&media_rules, 2);
        let b = blocks(&b_out, 1.0);
        let (count, mean_t2, rejected) = welch(&a, &b);
        eprintln!("{name}: {count} blocks, mean t^2 {mean_t2:.3}, {rejected} beyond 3.29");
        assert!(count >= 150, "{name}: only {count} blocks to compare");
        assert!(
            agree(count, mean_t2, rejected),
            "{name}: the rule sets disagree: {count} blocks, mean t^2 {mean_t2:.3}, \
             {rejected} beyond 3.29"
        );
        // The same comparison against a render 5% too bright must fail.
        let scaled = blocks(&b_out, 1.05);
        let (count, mean_t2, rejected) = welch(&a, &scaled);
        assert!(
            !agree(count, mean_t2, rejected),
            "{name}: a 5% error passes: {count} blocks, mean t^2 {mean_t2:.3}, \
             {rejected} beyond 3.29"
        );
        eprintln!(
            "{name}: {count} blocks; scaled by 1.05: mean t^2 {mean_t2:.2}, {rejected} beyond 3.29"
        );
    }
}

#[test]
fn without_roulette_the_depth_rules_agree() {
    // Russian roulette off (rr_depth beyond any path): what is left of the difference
    // is the order of the `max_depth` test (before NEE at the last vertex, or at the
    // next top), which must not change the expectation either.
    let mut surface = scene("cbox.xml");
    surface.integrator.rr_depth = 1000;
    let mut media_rules = scene("cbox.xml");
    media_rules.integrator.rr_depth = 1000;
    media_rules.integrator.volumetric = true;
    let a = blocks(&common::run(&surface, 3), 1.0);
    let b = blocks(&common::run(&media_rules, 4), 1.0);
    let (count, mean_t2, rejected) = welch(&a, &b);
    assert!(count >= 150, "only {count} blocks to compare");
    assert!(
        agree(count, mean_t2, rejected),
        "without roulette: {count} blocks, mean t^2 {mean_t2:.3}, {rejected} beyond 3.29"
    );
}
