//! Rows streamed to disk: the streamed bundle is byte-identical to the one written from
//! memory, every row reaches the sink once, memory is one row scratch per thread, and a
//! failing sink or an incomplete render leaves nothing that looks like a bundle.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use tstat::bundle::write::{bundle_bytes, write_bundle, BundleMeta, BundleWriter};
use tstat::bundle::{BundleError, Manifest};
use tstat::render::sink::{Row, RowSink};
use tstat::render::{render, render_into, PixelSampling, RenderSettings, StreamingMemory};
use tstat::scene::{Overrides, Scene};
use tstat::stats::Transform;

fn scene(name: &str, width: usize, bins: usize, spp: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    let overrides = Overrides {
        width: Some(width),
        bins: Some(bins),
        spp: Some(spp),
        ..Overrides::default()
    };
    Scene::load(&path, &overrides).unwrap()
}

fn settings(scene: &Scene, transform: Transform) -> RenderSettings {
    RenderSettings {
        spp: scene.spp,
        seed: 5,
        transform,
        pixel_sampling: PixelSampling::Stratified,
        replicates: 0,
        pixel_spp: None,
    }
}

fn meta(s: &RenderSettings) -> BundleMeta {
    BundleMeta {
        seed: s.seed,
        transform: s.transform,
        unit_m: 1.0,
        pixel_sampling: s.pixel_sampling,
        replicates: s.replicates,
        job: None,
        adaptive: None,
    }
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// Renders `scene` through a [`BundleWriter`] into `out` on `threads` threads.
fn stream(scene: &Scene, s: &RenderSettings, out: &Path, threads: usize) -> Manifest {
    let writer = BundleWriter::create(out, false, &scene.film, &s.transform).unwrap();
    let summary = pool(threads)
        .install(|| render_into(scene, s, &writer, &|_| {}))
        .unwrap();
    assert!(summary.row_scratches <= threads, "{summary:?}");
    writer.finish(scene, &meta(s), &summary).unwrap()
}

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn the_streamed_bundle_is_byte_identical_to_the_in_memory_one() {
    let dir = tempfile::tempdir().unwrap();
    for (name, transform) in [
        ("cbox_spheres.xml", Transform::Identity),
        ("cbox.xml", Transform::YeoJohnson { lambda: 0.5 }),
    ] {
        let sc = scene(name, 20, 60, 6);
        let s = settings(&sc, transform);
        let memory = dir.path().join(format!("{name}.memory.tstats"));
        let out = render(&sc, &s, &|_| {});
        let seconds = out.seconds;
        let mut want = write_bundle(&memory, false, &sc, &meta(&s), out).unwrap();
        for threads in [1, 2] {
            let streamed = dir.path().join(format!("{name}.{threads}.tstats"));
            let mut got = stream(&sc, &s, &streamed, threads);
            assert_eq!(files(&memory), files(&streamed));
            for f in files(&memory).iter().filter(|f| f.ends_with(".npy")) {
                let a = std::fs::read(memory.join(f)).unwrap();
                let b = std::fs::read(streamed.join(f)).unwrap();
                assert!(a == b, "{name}, {threads} threads: {f} differs");
            }
            // Equal manifests but for the render time.
            got.render_seconds = seconds;
            want.render_seconds = seconds;
            assert_eq!(got, want);
            let on_disk: Manifest =
                serde_json::from_slice(&std::fs::read(streamed.join("manifest.json")).unwrap())
                    .unwrap();
            assert_eq!(on_disk.arrays, want.arrays);
        }
    }
}

#[test]
fn bundle_bytes_are_the_npy_files_plus_room_for_the_manifest() {
    let dir = tempfile::tempdir().unwrap();
    for transform in [Transform::Identity, Transform::BoxCox { lambda: 0.5 }] {
        let sc = scene("cbox.xml", 12, 30, 2);
        let s = settings(&sc, transform);
        let out = dir.path().join(format!("{transform}.tstats"));
        stream(&sc, &s, &out, 2);
        let npy: u64 = files(&out)
            .iter()
            .filter(|f| f.ends_with(".npy"))
            .map(|f| std::fs::metadata(out.join(f)).unwrap().len())
            .sum();
        let manifest = std::fs::metadata(out.join("manifest.json")).unwrap().len();
        assert_eq!(bundle_bytes(&sc.film, &transform, false), npy + 65536);
        assert!(manifest < 65536);
    }
}

/// Records every row it gets and fails from the `fail_at`-th row on.
struct Recorder<'a> {
    inner: Option<&'a BundleWriter>,
    rows: Mutex<Vec<usize>>,
    fail_at: usize,
    calls: AtomicUsize,
}

impl RowSink for Recorder<'_> {
    type Error = BundleError;

    fn put_row(&self, row: &Row<'_>) -> Result<(), BundleError> {
        if self.calls.fetch_add(1, Ordering::SeqCst) >= self.fail_at {
            return Err(BundleError::Io(
                PathBuf::from("sink"),
                "injected failure".into(),
            ));
        }
        assert_eq!(row.gbuffer.len(), row.sums.width);
        assert_eq!(row.steady.len(), row.sums.width * 3);
        assert_eq!(row.sums.height, 1);
        self.rows.lock().unwrap().push(row.y);
        match self.inner {
            Some(w) => w.put_row(row),
            None => Ok(()),
        }
    }
}

#[test]
fn every_row_reaches_the_sink_once_with_one_scratch_per_thread() {
    let sc = scene("cbox.xml", 16, 20, 2);
    let s = settings(&sc, Transform::BoxCox { lambda: 0.5 });
    for threads in [1, 2, 3] {
        let sink = Recorder {
            inner: None,
            rows: Mutex::new(Vec::new()),
            fail_at: usize::MAX,
            calls: AtomicUsize::new(0),
        };
        let summary = pool(threads)
            .install(|| render_into(&sc, &s, &sink, &|_| {}))
            .unwrap();
        let mut rows = sink.rows.into_inner().unwrap();
        rows.sort();
        assert_eq!(rows, (0..sc.film.height).collect::<Vec<_>>());
        assert!(summary.row_scratches >= 1 && summary.row_scratches <= threads);
        assert_eq!(summary.paths, sc.film.pixels() as u64 * sc.spp as u64);
        assert!(summary.voxel_samples > 0);
    }
    // The in-memory render counts the same samples as its non-zero counts.
    let out = render(&sc, &s, &|_| {});
    let counted: u64 = out.accum.nonzero.iter().map(|&k| k as u64).sum();
    let sink = Recorder {
        inner: None,
        rows: Mutex::new(Vec::new()),
        fail_at: usize::MAX,
        calls: AtomicUsize::new(0),
    };
    assert_eq!(
        render_into(&sc, &s, &sink, &|_| {}).unwrap().voxel_samples,
        counted
    );
}

#[test]
fn the_streaming_footprint_grows_with_threads_and_width_not_height() {
    let t = Transform::Identity;
    let small = scene("cbox.xml", 64, 100, 2).film;
    let tall = tstat::sensors::film::Film {
        height: small.height * 100,
        ..small.clone()
    };
    let (a, b) = (
        StreamingMemory::new(&small, &t, 2),
        StreamingMemory::new(&tall, &t, 2),
    );
    assert_eq!(a.per_row, b.per_row);
    // The per-pixel images grow with the height; they are small next to the volume.
    assert!(b.images < tall.pixels() as u64 * 200);
    assert_eq!(
        StreamingMemory::new(&small, &t, 4).bytes() - a.bytes(),
        2 * a.per_row
    );
    // One row: 76 bytes per voxel, plus the pixel's records and the row's G-buffer,
    // steady values and ray counts (72 bytes a pixel at most).
    assert!(a.per_row >= 64 * 100 * 76 && a.per_row < 64 * 100 * 76 + 100 * 80 + 64 * 72);
}

#[test]
fn a_failing_sink_stops_the_render_and_the_bundle_is_never_made() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene("cbox.xml", 16, 20, 2);
    let s = settings(&sc, Transform::Identity);
    let out = dir.path().join("b.tstats");
    let writer = BundleWriter::create(&out, false, &sc.film, &s.transform).unwrap();
    let sink = Recorder {
        inner: Some(&writer),
        rows: Mutex::new(Vec::new()),
        fail_at: 3,
        calls: AtomicUsize::new(0),
    };
    let e = pool(2)
        .install(|| render_into(&sc, &s, &sink, &|_| {}))
        .unwrap_err();
    assert!(e.to_string().contains("injected failure"), "{e}");
    // Rows not yet started when the error came are never rendered.
    assert!(sink.calls.load(Ordering::SeqCst) < sc.film.height);
    // While the writer lives its rows sit in a hidden temporary directory only.
    assert!(!out.exists());
    drop(sink);
    drop(writer);
    assert!(files(dir.path()).is_empty(), "{:?}", files(dir.path()));
}

#[test]
fn an_incomplete_render_is_not_committed() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene("cbox.xml", 8, 10, 2);
    let s = settings(&sc, Transform::Identity);
    let out = dir.path().join("b.tstats");
    let writer = BundleWriter::create(&out, false, &sc.film, &s.transform).unwrap();
    let sums = tstat::stats::accumulators::Accumulators::new(1, 8, 10, 3, &s.transform);
    let g = vec![tstat::render::gbuffer::GPixel::default(); 8];
    let steady = vec![0.0; 24];
    for y in [0, 2, 3] {
        let row = Row {
            y,
            sums: &sums,
            gbuffer: &g,
            steady: &steady,
            rays: &[0; 8],
        };
        writer.put_row(&row).unwrap();
    }
    let summary = tstat::render::RenderSummary::default();
    let e = writer.finish(&sc, &meta(&s), &summary).unwrap_err();
    assert!(e.to_string().contains("did not deliver every row"), "{e}");
    assert!(files(dir.path()).is_empty(), "{:?}", files(dir.path()));
    // A row of the wrong width is refused, not written over its neighbours.
    let writer = BundleWriter::create(&out, false, &sc.film, &s.transform).unwrap();
    let wide = tstat::stats::accumulators::Accumulators::new(1, 9, 10, 3, &s.transform);
    let row = Row {
        y: 0,
        sums: &wide,
        gbuffer: &g,
        steady: &steady,
        rays: &[0; 8],
    };
    let e = writer.put_row(&row).unwrap_err();
    assert!(e.to_string().contains("x1.npy: a row of"), "{e}");
}

fn prlimit() -> Option<&'static str> {
    ["/usr/bin/prlimit", "/bin/prlimit"]
        .into_iter()
        .find(|p| Path::new(p).exists())
}

/// The command renders a 175 MB bundle under a 100 MB address-space limit: the sums
/// stream to disk (the in-memory accumulators alone would need 175 MB). One malloc arena
/// keeps the address space of the threads' allocators predictable.
#[test]
fn a_bundle_larger_than_the_address_space_limit_renders() {
    let Some(prlimit) = prlimit() else {
        eprintln!("skipped: no prlimit");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("big.tstats");
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    let r = Command::new(prlimit)
        .arg(format!("--as={}", 100 << 20))
        .arg(env!("CARGO_BIN_EXE_tstat"))
        .args([
            "render",
            cbox.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .args([
            "--width",
            "48",
            "--bins",
            "1000",
            "--spp",
            "2",
            "--threads",
            "2",
        ])
        .env("MALLOC_ARENA_MAX", "1")
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let x1 = std::fs::metadata(out.join("x1.npy")).unwrap().len();
    assert_eq!(x1, 128 + 48 * 48 * 1000 * 3 * 8);
    let b = tstat::bundle::Bundle::open(&out).unwrap();
    assert_eq!(b.manifest.bins, 1000);
}

/// A write that fails (here: a file size limit, with SIGXFSZ ignored so the write
/// returns EFBIG) is one error line naming the file, and leaves nothing behind.
#[test]
fn a_failed_write_is_one_error_and_leaves_nothing() {
    let Some(prlimit) = prlimit() else {
        eprintln!("skipped: no prlimit");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let cbox = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cbox.xml");
    for cmd in ["render", "run"] {
        let out = dir.path().join(format!("{cmd}.out"));
        let r = Command::new("sh")
            .arg("-c")
            .arg("trap '' XFSZ; exec \"$@\"")
            .arg("sh")
            .arg(prlimit)
            .arg("--fsize=100000")
            .arg(env!("CARGO_BIN_EXE_tstat"))
            .args([cmd, cbox.to_str().unwrap(), "--out", out.to_str().unwrap()])
            .args(["--width", "16", "--bins", "200", "--spp", "2"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "{cmd}: {err}");
        let last = err.lines().last().unwrap();
        assert!(
            last.starts_with("error:") && last.contains("x1.npy") && last.contains("too large"),
            "{cmd}: {err}"
        );
        assert!(
            files(dir.path()).is_empty(),
            "{cmd}: {:?}",
            files(dir.path())
        );
    }
}
