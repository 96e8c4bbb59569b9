//! Hostile y-tal HDF5 captures (`tstat nlos reconstruct CAPTURE.hdf5`, read by
//! `src/nlos/tal_read.rs`): a corpus of malformed and malicious files -- huge declared
//! shapes, shapes that do not match the grids, storage that cannot hold what is
//! declared, NaN / infinite / huge values in H, the grids and the scalars, malformed
//! origins, truncated files, corrupt deflate streams, FIFOs, devices and directories --
//! each run through the real binary under a 2 GB address-space limit and a 20 s
//! timeout: exit 1, one first line starting "error:" that names the problem, no panic,
//! nothing left behind. And valid input: the h5py fixtures (contiguous, chunked, gzip,
//! gzip + shuffle, + fletcher32) read to the values h5py wrote and reconstruct to the
//! same volume.

use crate::common::hostile;
use crate::tal_common;

use hostile::{bin, limited, run, snapshot, TIME_LIMIT};
use std::process::Command;
use std::time::{Duration, Instant};
use tal_common::{
    bytes, capture, fixture, fixture_h, get, patch_chunk_dims, patch_dims, remove, replace, set,
    write, Ds, Values,
};
use tstat::nlos::capture::Capture;

/// The storage of H of the FileBuilder capture: chunked, deflated and shuffled.
fn gzip_h(c: &mut [Ds], chunks: &[u64]) {
    let h = get(c, "H");
    h.chunks = Some(chunks.to_vec());
    h.deflate = true;
    h.shuffle = true;
}

/// A built capture (`capture(16, 4)`, H (16, 4, 4)) edited by `edit`.
fn built(edit: impl FnOnce(&mut Vec<Ds>)) -> Vec<u8> {
    let mut c = capture(16, 4);
    edit(&mut c);
    bytes(&c)
}

/// A fixture's bytes edited by `edit`.
fn fixture_with(name: &str, edit: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let mut b = std::fs::read(fixture(name)).unwrap();
    edit(&mut b);
    b
}

/// `b` with its dataspace dimensions `from` patched to `to` (which must be there).
fn dims(mut b: Vec<u8>, from: &[u64], to: &[u64]) -> Vec<u8> {
    assert!(patch_dims(&mut b, from, to) > 0, "dims {from:?} not found");
    b
}

/// The gzip fixture with its first chunk's deflate stream corrupted (bytes 8.. of the
/// chunk overwritten), found through hdf5-pure's chunk list.
fn corrupt_deflate(name: &str) -> Vec<u8> {
    let mut b = std::fs::read(fixture(name)).unwrap();
    let f = hdf5_pure::File::from_bytes(b.clone()).unwrap();
    let c = &f.dataset("H").unwrap().chunks().unwrap()[0];
    let at = c.address as usize + 8;
    for x in &mut b[at..at + 16] {
        *x ^= 0x5a;
    }
    b
}

/// The chunked fixture with its first chunk's address pointing past the file's end.
fn chunk_past_end() -> Vec<u8> {
    let mut b = std::fs::read(fixture("chunked.hdf5")).unwrap();
    let f = hdf5_pure::File::from_bytes(b.clone()).unwrap();
    let c = &f.dataset("H").unwrap().chunks().unwrap()[0];
    let to = (b.len() as u64 + 4096).to_le_bytes();
    assert!(replace(&mut b, &c.address.to_le_bytes(), &to) > 0);
    b
}

/// What a case runs on: a file written into the fixture directory as `case.hdf5`,
/// or a path already there.
enum Input {
    Bytes(Vec<u8>),
    Path(&'static str),
}

/// One hostile capture: a label, the input, extra flags, and a piece of the first
/// stderr line.
struct Case {
    what: &'static str,
    input: Input,
    flags: &'static [&'static str],
    want: &'static str,
}

fn case(what: &'static str, input: Vec<u8>, want: &'static str) -> Case {
    Case {
        what,
        input: Input::Bytes(input),
        flags: &[],
        want,
    }
}

fn cases() -> Vec<Case> {
    let f = |v: f32| Values::F32(vec![v; 3]);
    let mut out = vec![
        // Memory: declared shapes far beyond the grids, the storage or the budget,
        // refused before anything of that size is allocated.
        case(
            "H (600, 1000, 1000) against a 4 x 4 grid, chunked",
            dims(
                std::fs::read(fixture("chunked.hdf5")).unwrap(),
                &[16, 4, 4],
                &[600, 1000, 1000],
            ),
            "16 sensor grid points for the 1000000 of H's shape [600, 1000, 1000]",
        ),
        case(
            "H (600, 1000, 1000) against a 4 x 4 grid, gzip",
            dims(
                std::fs::read(fixture("gzip.hdf5")).unwrap(),
                &[16, 4, 4],
                &[600, 1000, 1000],
            ),
            "16 sensor grid points for the 1000000",
        ),
        case(
            "H of 1e9 bins, chunked",
            dims(
                std::fs::read(fixture("chunked.hdf5")).unwrap(),
                &[16, 4, 4],
                &[1_000_000_000, 4, 4],
            ),
            "H: its storage does not match its shape",
        ),
        case(
            "H of 1e9 bins, contiguous",
            dims(
                std::fs::read(fixture("contiguous.hdf5")).unwrap(),
                &[16, 4, 4],
                &[1_000_000_000, 4, 4],
            ),
            "H: its storage does not match its shape",
        ),
        case(
            "H of 1e9 bins, gzip",
            dims(
                std::fs::read(fixture("gzip.hdf5")).unwrap(),
                &[16, 4, 4],
                &[1_000_000_000, 4, 4],
            ),
            "H: its storage does not match its shape",
        ),
        case(
            "H's dimensions overflow 64 bits",
            dims(
                std::fs::read(fixture("contiguous.hdf5")).unwrap(),
                &[16, 4, 4],
                &[u64::MAX / 2, 4, 4],
            ),
            "H",
        ),
        case(
            "grids and H declaring 1e9 x 1e9 points",
            fixture_with("contiguous.hdf5", |b| {
                patch_dims(b, &[16, 4, 4], &[16, 1_000_000_000, 1_000_000_000]);
                patch_dims(b, &[4, 4, 3], &[1_000_000_000, 1_000_000_000, 3]);
            }),
            "sensor_grid_xyz: its storage does not match its shape",
        ),
        case(
            "a grid declaring 1e9 points against H's 16",
            fixture_with("contiguous.hdf5", |b| {
                patch_dims(b, &[4, 4, 3], &[1_000_000_000, 4, 3]);
            }),
            "sensor_grid_xyz: shape [1000000000, 4, 3] declares 12000000000 values; at most 48 fit",
        ),
        case(
            "a scalar of 2 values",
            built(|c| {
                let d = get(c, "t_start");
                d.values = Values::F64(vec![0.5, 0.6]);
                d.shape = vec![2];
            }),
            "t_start: shape [2] declares 2 values; at most 1 fit the capture",
        ),
        case(
            "a declared chunk larger than the file (gzip)",
            fixture_with("gzip.hdf5", |b| {
                assert!(patch_chunk_dims(b, &[16, 4, 4, 4], &[60000, 4, 4, 4]) > 0);
            }),
            "H: its storage does not match its shape: a chunk of 143 bytes cannot decode to its 3840000",
        ),
        case(
            "a chunk stored past the file's end",
            chunk_past_end(),
            "H: its storage does not match its shape: a chunk of 64 bytes at",
        ),
        case(
            "a corrupt deflate stream",
            corrupt_deflate("gzip.hdf5"),
            "H: ",
        ),
        case(
            "a corrupt deflate stream under fletcher32",
            corrupt_deflate("gzip_shuffle_fletcher32.hdf5"),
            "H: ",
        ),
        // Non-finite and huge values, named with their index.
        case(
            "H NaN",
            built(|c| set(c, "H", 3 * 16 + 4 + 2, f64::NAN)),
            "H (t 3, sx 1, sy 2) is NaN",
        ),
        case(
            "H inf",
            built(|c| set(c, "H", 0, f64::INFINITY)),
            "H (t 0, sx 0, sy 0) is inf",
        ),
        case(
            "H -inf",
            built(|c| set(c, "H", 255, f64::NEG_INFINITY)),
            "H (t 15, sx 3, sy 3) is -inf",
        ),
        case(
            "H 1e30",
            built(|c| set(c, "H", 17, 1e30)),
            "H (t 1, sx 0, sy 1) is 1e30, beyond 1e18",
        ),
        case(
            "H NaN, gzip",
            built(|c| {
                gzip_h(c, &[4, 2, 2]);
                set(c, "H", 200, f64::NAN)
            }),
            "H (t 12, sx 2, sy 0) is NaN",
        ),
        case(
            "sensor grid NaN",
            built(|c| set(c, "sensor_grid_xyz", 7, f64::NAN)),
            "sensor_grid_xyz (i 0, j 2, xyz 1) is NaN",
        ),
        case(
            "laser grid inf",
            built(|c| set(c, "laser_grid_xyz", 0, f64::INFINITY)),
            "laser_grid_xyz (i 0, j 0, xyz 0) is inf",
        ),
        case(
            "a wall coordinate of 1e30",
            built(|c| set(c, "sensor_grid_xyz", 5, 1e30)),
            "is 1e30, beyond 1e15",
        ),
        case(
            "normals NaN",
            built(|c| set(c, "sensor_grid_normals", 2, f64::NAN)),
            "sensor_grid_normals (i 0, j 0, xyz 2) is NaN",
        ),
        case(
            "normals zero",
            built(|c| get(c, "sensor_grid_normals").values = Values::F32(vec![0.0; 48])),
            "sensor_grid_normals is not a grid of non-zero normals",
        ),
        case(
            "t_start NaN",
            built(|c| set(c, "t_start", 0, f64::NAN)),
            "t_start is not a finite number",
        ),
        case(
            "t_start inf",
            built(|c| set(c, "t_start", 0, f64::INFINITY)),
            "t_start is not a finite number",
        ),
        case(
            "t_start 1e300",
            built(|c| set(c, "t_start", 0, 1e300)),
            "t_start is 1e300, beyond 1e15",
        ),
        case(
            "delta_t NaN",
            built(|c| set(c, "delta_t", 0, f64::NAN)),
            "delta_t is not a finite number",
        ),
        case(
            "delta_t 0",
            built(|c| set(c, "delta_t", 0, 0.0)),
            "delta_t must be positive, got 0",
        ),
        case(
            "delta_t -1",
            built(|c| set(c, "delta_t", 0, -1.0)),
            "delta_t must be positive, got -1",
        ),
        case(
            "delta_t 1e-300, t_start 1e3",
            built(|c| {
                set(c, "delta_t", 0, 1e-300);
                set(c, "t_start", 0, 1e3)
            }),
            "delta_t 1e-300 is too small for the capture's extent 1e3",
        ),
        case(
            "delta_t 1e14 over 16 bins",
            built(|c| set(c, "delta_t", 0, 1e14)),
            "the time axis' end (t_start + bins delta_t) is 1.6",
        ),
        case(
            "laser_xyz NaN",
            built(|c| set(c, "laser_xyz", 1, f64::NAN)),
            "laser_xyz (element 1) is NaN",
        ),
        case(
            "sensor_xyz 1e20",
            built(|c| get(c, "sensor_xyz").values = f(1e20)),
            "sensor_xyz (element 0) is 1e20, beyond 1e15",
        ),
        case(
            "laser_xyz of 2 values",
            built(|c| {
                let d = get(c, "laser_xyz");
                d.values = Values::F32(vec![0.0, 1.0]);
                d.shape = vec![2];
            }),
            "laser_xyz of shape [2] is not one 3D point",
        ),
        case(
            "sensor_xyz as strings",
            built(|c| {
                let d = get(c, "sensor_xyz");
                d.values = Values::Strings(vec!["a".into(), "b".into(), "c".into()]);
            }),
            "sensor_xyz: datatype",
        ),
        case(
            "t_accounts without laser_xyz",
            built(|c| {
                set(c, "t_accounts_first_and_last_bounces", 0, 1.0);
                remove(c, "laser_xyz")
            }),
            "laser_xyz or sensor_xyz is missing",
        ),
        case(
            "t_accounts 7",
            built(|c| set(c, "t_accounts_first_and_last_bounces", 0, 7.0)),
            "is 7, not a boolean",
        ),
        // Shapes and formats.
        case(
            "H_format 7",
            built(|c| set(c, "H_format", 0, 7.0)),
            "H_format Some(7.0)",
        ),
        case("no H", built(|c| remove(c, "H")), "H: no such dataset"),
        case(
            "no delta_t",
            built(|c| remove(c, "delta_t")),
            "delta_t: no such dataset",
        ),
        case(
            "no sensor grid",
            built(|c| remove(c, "sensor_grid_xyz")),
            "sensor_grid_xyz: no such dataset",
        ),
        case(
            "H as strings",
            built(|c| {
                let d = get(c, "H");
                d.values = Values::Strings(vec!["x".into(); 256]);
            }),
            "H: datatype",
        ),
        case(
            "H of 2 dimensions",
            built(|c| get(c, "H").shape = vec![16, 16]),
            "H of shape [16, 16] (H_format Some(1.0))",
        ),
        case(
            "a 5 x 4 laser grid for H's 1 laser",
            built(|c| {
                let d = get(c, "laser_grid_xyz");
                d.values = Values::F32(vec![0.5; 60]);
                d.shape = vec![5, 4, 3];
            }),
            "laser_grid_xyz: shape [5, 4, 3] declares 60 values; at most 48 fit",
        ),
        case(
            "a laser grid of 2 points for H's 1 laser",
            built(|c| {
                let d = get(c, "laser_grid_xyz");
                d.values = Values::F32(vec![0.5; 6]);
                d.shape = vec![2, 3];
            }),
            "2 laser grid points for the 1 of H's shape [16, 4, 4]",
        ),
        case(
            "a grid whose points are not triples",
            built(|c| {
                let d = get(c, "sensor_grid_xyz");
                d.values = Values::F32(vec![0.5; 48]);
                d.shape = vec![12, 4];
            }),
            "sensor_grid_xyz of shape [12, 4] is not a grid of 3D points",
        ),
        case(
            "every B-tree signature broken",
            fixture_with("chunked.hdf5", |b| {
                // Every v1 B-tree node signature broken (the root group's and H's chunks').
                assert!(replace(b, b"TREE", b"EERT") > 0);
            }),
            "invalid B-tree v1 signature",
        ),
        // Truncated and empty files.
        case("an empty file", Vec::new(), "not an HDF5 file"),
        case(
            "a text file",
            b"not hdf5 at all\n".to_vec(),
            "not an HDF5 file",
        ),
    ];
    for name in ["contiguous.hdf5", "gzip.hdf5", "gzip_shuffle.hdf5"] {
        let b = std::fs::read(fixture(name)).unwrap();
        for keep in [
            8,
            100,
            800,
            2048,
            4000,
            b.len() / 2,
            b.len() - 200,
            b.len() - 1,
        ] {
            out.push(case(
                "a truncated fixture",
                b[..keep].to_vec(),
                "case.hdf5: ",
            ));
        }
    }
    // The memory budget.
    out.push(Case {
        what: "a file over --max-memory",
        input: Input::Bytes(std::fs::read(fixture("contiguous.hdf5")).unwrap()),
        flags: &["--max-memory", "4k"],
        want: "the file is 12.4 kB, over the memory budget of 4.0 kB (the HDF5 reader holds the whole file in memory",
    });
    out.push(Case {
        what: "H over --max-memory (gzip: a small file)",
        input: Input::Bytes({
            let mut c = capture(512, 32);
            gzip_h(&mut c, &[64, 32, 32]);
            get(&mut c, "H").values = Values::F32(vec![0.0; 512 * 32 * 32]);
            bytes(&c)
        }),
        flags: &["--max-memory", "1M"],
        want: "reading H would take",
    });
    out.push(Case {
        what: "a chunk that decodes to more than --max-memory",
        input: Input::Bytes(fixture_with("gzip.hdf5", |b| {
            assert!(patch_chunk_dims(b, &[16, 4, 4, 4], &[60000, 4, 4, 4]) > 0);
        })),
        flags: &["--max-memory", "1M"],
        want: "reading H would take 3.86 MB with the file and what was read before, over the memory budget of 1.00 MB",
    });
    // Not regular files.
    for (what, path, want) in [
        (
            "a FIFO",
            "fifo.hdf5",
            "fifo.hdf5: not a regular file (a FIFO)",
        ),
        (
            "/dev/zero through a link",
            "zero.hdf5",
            "zero.hdf5: not a regular file (a character device)",
        ),
        (
            "a directory",
            "dir.hdf5",
            "dir.hdf5: not a regular file (a directory)",
        ),
        (
            "a directory .h5",
            "dir.h5",
            "dir.h5: not a regular file (a directory)",
        ),
        (
            "a dangling link",
            "dangling.hdf5",
            "dangling.hdf5: no such capture file",
        ),
        (
            "nothing",
            "missing.hdf5",
            "missing.hdf5: no such capture file",
        ),
    ] {
        out.push(Case {
            what,
            input: Input::Path(path),
            flags: &[],
            want,
        });
    }
    out
}

/// The fixture directory: a FIFO, a link to /dev/zero, directories named like
/// captures, a dangling link, a precious file.
fn fixture_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fifo = std::ffi::CString::new(d.join("fifo.hdf5").to_str().unwrap()).unwrap();
    rustix::fs::mkfifoat(
        rustix::fs::CWD,
        fifo.as_c_str(),
        rustix::fs::Mode::from_raw_mode(0o644),
    )
    .unwrap();
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.hdf5")).unwrap();
    std::os::unix::fs::symlink("nowhere.hdf5", d.join("dangling.hdf5")).unwrap();
    std::fs::create_dir(d.join("dir.hdf5")).unwrap();
    std::fs::create_dir(d.join("dir.h5")).unwrap();
    std::fs::write(d.join("file.txt"), "precious").unwrap();
    dir
}

#[test]
fn hostile_tal_captures_fail_cleanly() {
    let fx = fixture_dir();
    let dir = fx.path();
    let started = Instant::now();
    let cases = cases();
    let mut failures = Vec::new();
    for (k, c) in cases.iter().enumerate() {
        let input = match &c.input {
            Input::Bytes(b) => {
                std::fs::write(dir.join("case.hdf5"), b).unwrap();
                "case.hdf5"
            }
            Input::Path(p) => p,
        };
        let mut args: Vec<String> = [
            "nlos",
            "reconstruct",
            input,
            "--method",
            "bp",
            "--volume",
            "0,0.3,0,0.3,0.2,0.5",
            "--voxels",
            "4,4,4",
            "--out",
            "v.npy",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        args.extend(c.flags.iter().map(|s| s.to_string()));
        let before = snapshot(dir);
        let r = run(limited(&args, dir));
        let after = snapshot(dir);
        let _ = std::fs::remove_file(dir.join("v.npy"));
        let first = r.stderr.lines().next().unwrap_or_default();
        let mut problems = Vec::new();
        if r.timed_out {
            problems.push(format!("killed after {TIME_LIMIT:?}"));
        }
        if r.code != Some(1) {
            problems.push(format!("exit {:?}, expected 1", r.code));
        }
        if !first.starts_with("error: ") || !first.contains(c.want) {
            problems.push(format!("first stderr line {first:?} lacks {:?}", c.want));
        }
        if r.stderr.contains("panick") {
            problems.push("panicked".into());
        }
        if r.stderr.lines().count() != 1 {
            problems.push("more than one stderr line".into());
        }
        if before != after {
            problems.push("the directory changed".into());
        }
        if !problems.is_empty() {
            failures.push(format!(
                "case {k} ({}): {}\n  stderr: {}",
                c.what,
                problems.join("; "),
                r.stderr
            ));
        }
    }
    let _ = std::fs::remove_file(dir.join("case.hdf5"));
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
    assert!(
        started.elapsed() < Duration::from_secs(60),
        "the corpus took {:?}",
        started.elapsed()
    );
}

/// Every h5py fixture reads to the values h5py wrote, and its grids and scalars.
#[test]
fn h5py_fixtures_read_to_their_values() {
    let want = fixture_h();
    for name in [
        "contiguous.hdf5",
        "chunked.hdf5",
        "gzip.hdf5",
        "gzip_shuffle.hdf5",
        "gzip_shuffle_fletcher32.hdf5",
    ] {
        let c = Capture::from_tal(&fixture(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((c.time.bins, c.lasers, c.sensors), (16, 1, 16), "{name}");
        assert!(c.paired, "{name}: confocal");
        assert_eq!(c.h, want, "{name}: H");
        assert_eq!(
            (c.time.start_opl, c.time.bin_width_opl),
            (0.6, 0.1),
            "{name}"
        );
        // numpy.linspace(-0.25, 0.25, 4)[1], stored as f32.
        let x = (-0.25f64 + 0.5 / 3.0) as f32;
        let p = c.sensor_grid[5];
        assert!(
            (p[0] - x).abs() < 1e-7 && (p[1] - x).abs() < 1e-7 && p[2] == 0.0,
            "{name}: {p:?}"
        );
        assert_eq!(c.normal, [0.0, 0.0, 1.0]);
        assert_eq!(c.laser_xyz, Some([0.0, 0.0, 1.0]));
        assert!(!c.accounts_first_and_last_bounces);
    }
    // The compressed fixtures are compressed.
    let f = hdf5_pure::File::open(fixture("gzip_shuffle_fletcher32.hdf5")).unwrap();
    assert_eq!(f.dataset("H").unwrap().filters(), vec![2, 1, 3]);
}

/// A gzip capture and its uncompressed twin reconstruct to the same volume (the
/// binary's output, bit for bit); a FileBuilder gzip capture reads as its contiguous one.
#[test]
fn gzip_captures_reconstruct_as_uncompressed_ones() {
    let dir = tempfile::tempdir().unwrap();
    let mut volumes = Vec::new();
    for name in [
        "contiguous.hdf5",
        "gzip.hdf5",
        "gzip_shuffle.hdf5",
        "gzip_shuffle_fletcher32.hdf5",
    ] {
        let out = dir.path().join(format!("{name}.npy"));
        let r = Command::new(bin())
            .args(["nlos", "reconstruct"])
            .arg(fixture(name))
            .args([
                "--method",
                "fbp",
                "--wl-mean",
                "0.4",
                "--volume",
                "-0.2,0.2,-0.2,0.2,0.4,0.8",
                "--voxels",
                "5,5,5",
                "--out",
            ])
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            r.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        volumes.push(std::fs::read(&out).unwrap());
    }
    assert!(volumes.iter().all(|v| v == &volumes[0]));
    let plain = capture(16, 4);
    let mut gz = plain.clone();
    gzip_h(&mut gz, &[5, 3, 2]);
    let (a, b) = (dir.path().join("a.hdf5"), dir.path().join("b.hdf5"));
    write(&a, &plain);
    write(&b, &gz);
    let (a, b) = (
        Capture::from_tal(&a).unwrap(),
        Capture::from_tal(&b).unwrap(),
    );
    assert_eq!(a.h, b.h);
    assert_eq!(a.h.len(), 256);
}
