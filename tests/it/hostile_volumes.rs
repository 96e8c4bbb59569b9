//! Hostile volumes given to the commands that read a user's `.npy` volume besides a
//! bundle (issue 41): `nlos mip VOLUME`, `nlos reconstruct --denoised D.npy` and
//! `view --denoised/--reference`. They all read through the hardened reader
//! (`bundle::float_rows`): headers checked against the file before anything is
//! allocated, non-regular files refused before they are opened, every value finite,
//! and the volume read a band at a time. Each case must exit 1 with one `error:` line,
//! no panic, nothing left behind, within 20 s and 2 GB of address space; and a valid
//! volume larger than the address space is projected, not refused.

use crate::common::hostile;

use hostile::{bin, check_failure, run};
use std::path::Path;
use std::process::Command;

/// A `.npy` file with header dictionary fields `descr` and `shape` and raw `data`.
fn npy(path: &Path, descr: &str, shape: &str, data: &[u8]) {
    let mut h = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    while !(10 + h.len() + 1).is_multiple_of(64) {
        h.push(' ');
    }
    h.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend((h.len() as u16).to_le_bytes());
    bytes.extend(h.as_bytes());
    bytes.extend(data);
    std::fs::write(path, bytes).unwrap();
}

fn f32s(v: impl IntoIterator<Item = f32>) -> Vec<u8> {
    v.into_iter().flat_map(f32::to_le_bytes).collect()
}

fn tstat_ok(dir: &Path, args: &[&str]) {
    let out = Command::new(bin())
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// An NLOS capture T.tstats (nlos_T.xml at 8 x 8 wall points, 16 bins, 2 spp) and its
/// noisy mean as a "denoised" volume, Cornell-box bundles b.tstats (4 x 4, 3 bins) and
/// long.tstats (2 x 2, 100 bins)
/// and a valid (4, 3, 2) volume; then the hostile files.
fn fixture() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = |n: &str| root.join("scenes").join(n).display().to_string();
    tstat_ok(
        d,
        &[
            "render",
            &scene("nlos_T.xml"),
            "--out",
            "T.tstats",
            "-D",
            "res=8",
            "-D",
            "bins=16",
            "--spp",
            "2",
        ],
    );
    tstat_ok(d, &["export", "T.tstats", "--out", "mean.npy"]);
    tstat_ok(
        d,
        &[
            "render",
            &scene("cbox.xml"),
            "--out",
            "b.tstats",
            "-D",
            "res=4",
            "-D",
            "temporal_bins=3",
            "--spp",
            "2",
        ],
    );
    tstat_ok(
        d,
        &[
            "render",
            &scene("cbox.xml"),
            "--out",
            "long.tstats",
            "-D",
            "res=2",
            "-D",
            "temporal_bins=100",
            "--spp",
            "2",
        ],
    );
    let f = |n: &str| d.join(n);
    npy(
        &f("ok3.npy"),
        "<f4",
        "(4, 3, 2)",
        &f32s((0..24).map(|i| i as f32)),
    );
    // Headers that claim far more than the file holds.
    npy(&f("huge3.npy"), "<f4", "(100000, 100000, 100000)", &[0; 64]);
    npy(
        &f("huge4.npy"),
        "<f4",
        "(100000, 100000, 100000, 4)",
        &[0; 64],
    );
    npy(
        &f("overflow.npy"),
        "<f4",
        "(4294967296, 4294967296, 4294967296)",
        &[0; 64],
    );
    npy(&f("truncated.npy"), "<f4", "(4, 3, 2)", &[0; 92]);
    npy(&f("trailing.npy"), "<f4", "(4, 3, 2)", &[0; 100]);
    // Values no picture or reconstruction can use.
    let mut v: Vec<f32> = (0..24).map(|i| i as f32).collect();
    v[7] = f32::NAN;
    npy(&f("nan3.npy"), "<f4", "(4, 3, 2)", &f32s(v.clone()));
    v[7] = f32::INFINITY;
    npy(&f("inf3.npy"), "<f4", "(4, 3, 2)", &f32s(v));
    let mut w = [1.0f64; 24];
    w[23] = 1e300;
    let wide: Vec<u8> = w.iter().flat_map(|x| x.to_le_bytes()).collect();
    npy(&f("big64.npy"), "<f8", "(4, 3, 2)", &wide);
    // Other element types and shapes.
    npy(&f("u32.npy"), "<u4", "(4, 3, 2)", &[0; 96]);
    npy(&f("bigendian.npy"), ">f4", "(4, 3, 2)", &[0; 96]);
    npy(&f("flat.npy"), "<f4", "(4, 6)", &[0; 96]);
    npy(&f("empty.npy"), "<f4", "(0, 3, 2)", &[]);
    npy(&f("wide.npy"), "<f4", "(20000, 1, 1)", &[0; 80000]);
    // Volumes of the capture's film with one bad value, or of another film.
    let film = |descr: &str, bad: Option<f32>, name: &str, shape: &str| {
        let n: usize = 8 * 8 * 16 * 3;
        let mut v = vec![0.5f32; n];
        if let Some(b) = bad {
            v[n - 2] = b;
        }
        npy(&f(name), descr, shape, &f32s(v));
    };
    film("<f4", Some(f32::NAN), "den_nan.npy", "(8, 8, 16, 3)");
    film(
        "<f4",
        Some(f32::NEG_INFINITY),
        "den_inf.npy",
        "(8, 8, 16, 3)",
    );
    npy(
        &f("den_bins.npy"),
        "<f4",
        "(8, 8, 8, 6)",
        &f32s(vec![0.5; 8 * 8 * 8 * 6]),
    );
    npy(
        &f("den_rows.npy"),
        "<f4",
        "(4, 16, 16, 3)",
        &f32s(vec![0.5; 4 * 16 * 16 * 3]),
    );
    let mut view = vec![0.5f32; 4 * 4 * 3 * 3];
    view[5] = f32::NAN;
    npy(&f("view_nan.npy"), "<f4", "(4, 4, 3, 3)", &f32s(view));
    npy(
        &f("view_shape.npy"),
        "<f4",
        "(4, 4, 4, 3)",
        &f32s(vec![0.5; 4 * 4 * 4 * 3]),
    );
    // Not regular files: a FIFO (reading would block forever), a device, a directory.
    let made = Command::new("mkfifo").arg(f("fifo.npy")).status().unwrap();
    assert!(made.success());
    std::os::unix::fs::symlink("/dev/zero", f("zero.npy")).unwrap();
    std::fs::create_dir(f("dir.npy")).unwrap();
    dir
}

const REC: &[&str] = &[
    "nlos",
    "reconstruct",
    "T.tstats",
    "--method",
    "bp",
    "--volume=-1,1,-1,1,0.5,1.5",
    "--voxels",
    "5,5,3",
    "--out",
    "r.npy",
    "--denoised",
];

/// (arguments, a piece of the error line); every case runs in the fixture directory.
fn cases() -> Vec<(Vec<&'static str>, &'static str)> {
    let mip = |v: &'static str| vec!["nlos", "mip", v, "--out", "m.png"];
    let den = |v: &'static str| {
        let mut a = REC.to_vec();
        a.push(v);
        a
    };
    let view =
        |flag: &'static str, v: &'static str| vec!["view", "b.tstats", flag, v, "--out", "v.html"];
    let mut c = vec![
        // nlos mip
        (mip("huge3.npy"), "huge3.npy: not an (NX, NY, NZ) f32 or f64 .npy volume (truncated: shape [100000, 100000, 100000]"),
        (mip("overflow.npy"), "more elements than memory can address"),
        (mip("truncated.npy"), "truncated: shape [4, 3, 2]"),
        (mip("trailing.npy"), "bytes after the data"),
        (mip("nan3.npy"), "nan3.npy: element (x 1, y 0, z 1) is NaN"),
        (mip("inf3.npy"), "inf3.npy: element (x 1, y 0, z 1) is +inf"),
        (mip("big64.npy"), "element (x 3, y 2, z 1) is 1e300, beyond the f32 range"),
        (mip("u32.npy"), "dtype \"<u4\""),
        (mip("bigendian.npy"), "dtype \">f4\""),
        (mip("flat.npy"), "shape [4, 6] is not a non-empty (NX, NY, NZ) volume"),
        (mip("empty.npy"), "shape [0, 3, 2] is not a non-empty"),
        (mip("wide.npy"), "a projection of 20000 x 1 cells at 1 pixels per cell would be over 16384 pixels across"),
        (vec!["nlos", "mip", "ok3.npy", "--scale", "5000", "--out", "m.png"], "over 16384 pixels across (--scale)"),
        (vec!["nlos", "mip", "ok3.npy", "--max-memory", "1K", "--out", "m.png"], "over --max-memory"),
        (vec!["nlos", "mip", "ok3.npy", "--max-memory", "lots", "--out", "m.png"], "--max-memory"),
        (mip("fifo.npy"), "fifo.npy: not an (NX, NY, NZ) f32 or f64 .npy volume (is not a regular file"),
        (mip("zero.npy"), "is not a regular file"),
        (mip("dir.npy"), "is a directory"),
        (mip("missing.npy"), "missing.npy"),
        // nlos reconstruct --denoised
        (den("huge4.npy"), "--denoised huge4.npy: not an f32 (rows, Sx, T, C) .npy volume (truncated: shape [100000, 100000, 100000, 4]"),
        (den("den_nan.npy"), "--denoised den_nan.npy: voxel (y 7, x 7, t 15, c 1) is NaN"),
        (den("den_inf.npy"), "is -inf"),
        (den("den_bins.npy"), "--denoised den_bins.npy: the denoised volume is [8, 8, 8, 6]; the capture's film is (8, 8, 16, C)"),
        (den("den_rows.npy"), "the capture's film is (8, 8, 16, C)"),
        (den("ok3.npy"), "the denoised volume is [4, 3, 2]"),
        (den("fifo.npy"), "--denoised fifo.npy: not an f32 (rows, Sx, T, C) .npy volume (is not a regular file"),
        (den("zero.npy"), "is not a regular file"),
        (den("dir.npy"), "is a directory"),
        (den("u32.npy"), "dtype \"<u4\""),
        (den("r.npy"), "r.npy"),
        // view --denoised / --reference
        (view("--denoised", "huge4.npy"), "--denoised huge4.npy: truncated"),
        (view("--reference", "fifo.npy"), "--reference fifo.npy: is not a regular file"),
        (view("--denoised", "zero.npy"), "is not a regular file"),
        (view("--denoised", "view_nan.npy"), "--denoised view_nan.npy: voxel (y 0, x 0, t 1, c 2) is NaN"),
        (view("--denoised", "view_shape.npy"), "shape [4, 4, 4, 3] does not match the bundle's (H, W, T, C) = (4, 4, 3, 3)"),
        (view("--reference", "T.tstats"), "--reference T.tstats: shape [8, 8, 16, 3] does not match"),
        (vec!["view", "b.tstats", "--max-memory", "1K", "--out", "v.html"], "over --max-memory"),
        (vec!["view", "b.tstats", "--max-bytes", "2K", "--denoised", "mean.npy", "--out", "v.html"], "mean.npy"),
    ];
    // A page whose bins do not fit the byte budget even as one pixel block:
    c.push((
        vec!["view", "long.tstats", "--max-bytes", "1KiB", "--out", "v.html"],
        "--max-bytes 1KiB: too small for 100 bins of 2 volumes even averaged over the whole image (at least 1.2 kB)",
    ));
    c
}

#[test]
fn hostile_volumes_fail_cleanly_and_leave_nothing() {
    let fx = fixture();
    let dir = fx.path();
    let mut failures = Vec::new();
    let all = cases();
    for (k, (args, want)) in all.iter().enumerate() {
        let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        let problems = check_failure(&args, dir, 1, want);
        if !problems.is_empty() {
            failures.push(format!(
                "case {k}: tstat {}\n  {}",
                args.join(" "),
                problems.join("\n  ")
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        all.len(),
        failures.join("\n")
    );
}

/// The same commands on valid input succeed: an f64 volume projects like its f32
/// copy, and the capture's own noisy mean as `--denoised` gives the bundle's
/// reconstruction bit for bit (read a band at a time).
#[test]
fn valid_volumes_are_read_band_by_band() {
    let fx = fixture();
    let d = fx.path();
    let mut v = Vec::new();
    for i in 0..24 {
        v.push(((i * 7) % 11) as f64 - 3.0);
    }
    npy(
        &d.join("v64.npy"),
        "<f8",
        "(4, 3, 2)",
        &v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>(),
    );
    npy(
        &d.join("v32.npy"),
        "<f4",
        "(4, 3, 2)",
        &f32s(v.iter().map(|&x| x as f32)),
    );
    for axis in ["x", "y", "z"] {
        tstat_ok(
            d,
            &[
                "nlos", "mip", "v64.npy", "--axis", axis, "--out", "a.png", "--force",
            ],
        );
        tstat_ok(
            d,
            &[
                "nlos", "mip", "v32.npy", "--axis", axis, "--out", "b.png", "--force",
            ],
        );
        assert_eq!(
            std::fs::read(d.join("a.png")).unwrap(),
            std::fs::read(d.join("b.png")).unwrap(),
            "axis {axis}"
        );
    }
    let mut with = REC.to_vec();
    with.push("mean.npy");
    tstat_ok(d, &with);
    let mut plain = REC[..REC.len() - 1].to_vec();
    plain[9] = "plain.npy";
    tstat_ok(d, &plain);
    assert_eq!(
        std::fs::read(d.join("r.npy")).unwrap(),
        std::fs::read(d.join("plain.npy")).unwrap()
    );
    tstat_ok(
        d,
        &[
            "view",
            "b.tstats",
            "--reference",
            "b.tstats",
            "--out",
            "v.html",
        ],
    );
}

/// A valid volume of 1.07 GB (a sparse file of zeros but one voxel) is projected
/// under a 1 GB address-space limit: it is read a band at a time, never held whole.
#[test]
fn a_volume_larger_than_memory_is_projected() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = d.join("big.npy");
    npy(&path, "<f4", "(512, 512, 1024)", &[]);
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    let header = f.metadata().unwrap().len();
    f.set_len(header + 512 * 512 * 1024 * 4).unwrap();
    // Voxel (300, 100, 1000) = 2.
    use std::os::unix::fs::FileExt;
    let at = header + (((300 * 512 + 100) * 1024 + 1000) * 4) as u64;
    f.write_all_at(&2f32.to_le_bytes(), at).unwrap();
    drop(f);
    let args: Vec<String> = ["nlos", "mip", "big.npy", "--out", "big.png"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    // Tighter than the corpus's limit: below the volume's own size.
    let mut cmd = Command::new("sh");
    cmd.arg("-c")
        .arg("ulimit -v 1000000; exec \"$0\" \"$@\"")
        .arg(bin())
        .args(&args)
        .current_dir(d);
    let r = run(cmd);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    let img = image::open(d.join("big.png")).unwrap().to_rgb8();
    // 512 x 512 cells at one pixel each; the lit voxel's cell (x 300, y 100 from the
    // bottom) is the brightest, every other cell black.
    assert_eq!(img.dimensions(), (512, 512));
    let lit = img.get_pixel(300, 511 - 100);
    assert_eq!(lit.0, [252, 255, 164]);
    let black = img.pixels().filter(|p| p.0 == [0, 0, 4]).count();
    assert_eq!(black, 512 * 512 - 1);
}
