//! The library's render job (`tstat::job::render`, what `tstat render`, `tstat run` and
//! the Python package call): it stops cleanly when its progress asks, reports every
//! path, and the bundle's per-voxel estimates (`Bundle::estimates`) are SPEC 5's.

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use tstat::bundle::Bundle;
use tstat::job::{self, AdaptiveRequest, Progress, RenderJob, Stage};
use tstat::render::adaptive::ErrorMeasure;
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

fn scene(spp: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let overrides = Overrides {
        width: Some(12),
        bins: Some(24),
        bin_width_opl: Some(0.5),
        spp: Some(spp),
        ..Overrides::default()
    };
    Scene::load(&path, &overrides).unwrap()
}

/// Counts the paths reported; asks to stop once `stop_after` render paths are done.
struct Counting {
    render_paths: AtomicU64,
    render_total: AtomicU64,
    stop_after: u64,
}

impl Progress for Counting {
    fn start(&self, stage: Stage, total: u64) {
        if stage == Stage::Render {
            self.render_total.store(total, Ordering::SeqCst);
        }
    }
    fn advance(&self, n: u64) {
        self.render_paths.fetch_add(n, Ordering::SeqCst);
    }
    fn note(&self, _: &str) {}
    fn cancelled(&self) -> bool {
        self.render_paths.load(Ordering::SeqCst) >= self.stop_after
    }
}

fn counting(stop_after: u64) -> Counting {
    Counting {
        render_paths: AtomicU64::new(0),
        render_total: AtomicU64::new(0),
        stop_after,
    }
}

#[test]
fn a_cancelled_render_is_the_cancelled_error_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("b.tstats");
    let job = RenderJob {
        threads: Some(1),
        ..RenderJob::new(&out)
    };
    let progress = counting(1);
    let e = job::render(scene(4), &job, &progress).unwrap_err();
    assert!(e.downcast_ref::<job::Cancelled>().is_some(), "{e:#}");
    assert!(
        progress.render_paths.load(Ordering::SeqCst) < progress.render_total.load(Ordering::SeqCst)
    );
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn a_finished_render_reports_every_path() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("b.tstats");
    let progress = counting(u64::MAX);
    let report = job::render(scene(4), &RenderJob::new(&out), &progress).unwrap();
    let paths = progress.render_paths.load(Ordering::SeqCst);
    assert_eq!(paths, report.summary.paths);
    assert_eq!(paths, 12 * 12 * 4);
    assert!(Bundle::open(&out).is_ok());
}

/// SPEC 5 written out from the zero-filled sums, as the specification states it.
fn spec5(x: [f64; 3], nonzero: u32, n: u64, z0: f64) -> (f64, f64) {
    let k = (n - u64::from(nonzero)) as f64;
    let nf = n as f64;
    let (x1, x2, x3) = (x[0] + k * z0, x[1] + k * z0 * z0, x[2] + k * z0 * z0 * z0);
    let mu = x1 / nf;
    let s2 = (x2 / nf - mu * mu).max(0.0);
    let sigma2 = s2 * nf / (nf - 1.0);
    let m3 = x3 / nf - 3.0 * mu * s2 - mu * mu * mu;
    let theta = if sigma2 > 0.0 {
        mu + m3 / (6.0 * sigma2 * nf)
    } else {
        mu
    };
    (theta, sigma2 / nf)
}

#[test]
fn the_estimates_of_an_adaptive_box_cox_bundle_are_spec_5_with_each_pixels_count() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("b.tstats");
    let transform: Transform = "box-cox:0.5".parse().unwrap();
    let job = RenderJob {
        transform,
        adaptive: Some(AdaptiveRequest {
            measure: ErrorMeasure::Mse,
            pilot_spp: Some(4),
            goal: None,
        }),
        ..RenderJob::new(&out)
    };
    job::render(scene(64), &job, &job::Silent).unwrap();
    let b = Bundle::open(&out).unwrap();
    let n = b.pixel_spp.clone().expect("adaptive counts");
    assert!(n.iter().min() != n.iter().max(), "the counts should differ");
    let e = b.estimates().unwrap();
    let read = |name: &str| -> ndarray::Array4<f64> {
        ndarray_npy::read_npy(out.join(format!("{name}.npy"))).unwrap()
    };
    let (x1, x2, x3) = (read("x1"), read("x2"), read("x3"));
    let nz: ndarray::Array3<u32> = ndarray_npy::read_npy(out.join("nonzero.npy")).unwrap();
    let z0 = -2.0; // Box-Cox 0.5 at 0: (0^0.5 - 1) / 0.5
    let mut checked = 0;
    for ((y, x, t, c), &theta) in e.theta.indexed_iter() {
        let spp = u64::from(n[y * 12 + x]);
        let sums = [x1[[y, x, t, c]], x2[[y, x, t, c]], x3[[y, x, t, c]]];
        let (want_t, want_v) = spec5(sums, nz[[y, x, t]], spp, z0);
        let v = e.variance[[y, x, t, c]];
        assert!(
            (f64::from(theta) - want_t).abs() <= 1e-5 * (1.0 + want_t.abs()),
            "theta at {y} {x} {t} {c}: {theta} vs {want_t}"
        );
        assert!(
            (f64::from(v) - want_v).abs() <= 1e-5 * want_v.abs() + 1e-9,
            "V at {y} {x} {t} {c}: {v} vs {want_v}"
        );
        checked += usize::from(want_v > 0.0);
    }
    assert!(checked > 100, "only {checked} voxels with a variance");
}
