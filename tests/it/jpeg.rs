//! JPEG textures decode as libjpeg(-turbo) decodes them with its defaults (ISLOW IDCT,
//! fancy upsampling, jdcolor.c's tables), which is how Mitsuba 3 reads them. The
//! fixtures in `tests/data/jpeg/` and libjpeg's decodes of them (`NAME.raw`) are made
//! by `scripts/make_jpeg_fixtures.py` (Pillow on libjpeg-turbo).

use std::path::{Path, PathBuf};
use tstat::textures::image_file::{load_image, srgb_to_linear, ImageFileError};

const FIXTURES: &[(&str, usize, usize, usize)] = &[
    ("baseline_420", 33, 17, 3),
    ("baseline_422", 31, 19, 3),
    ("baseline_444", 17, 16, 3),
    ("progressive_420", 23, 21, 3),
    ("restart_420", 40, 24, 3),
    ("narrow_420", 3, 9, 3),
    ("grey", 19, 13, 1),
    ("grey_progressive", 18, 15, 1),
    ("rgb_adobe", 16, 16, 3),
];

fn fixture(name: &str, ext: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/jpeg")
        .join(format!("{name}.{ext}"))
}

/// (largest difference, how many samples differ) between two 8-bit decodes.
fn diff(a: &[u8], b: &[u8]) -> (u8, usize) {
    assert_eq!(a.len(), b.len());
    let d = a.iter().zip(b).map(|(x, y)| x.abs_diff(*y));
    (d.clone().max().unwrap_or(0), d.filter(|&v| v > 0).count())
}

/// tstat's decode through the scene loader's function, as 8-bit samples.
fn tstat_decode(name: &str) -> (usize, usize, usize, Vec<u8>) {
    let img = load_image(&fixture(name, "jpg"), true).unwrap();
    let bytes = img.data.iter().map(|v| (v * 255.0).round() as u8).collect();
    (img.width, img.height, img.channels, bytes)
}

#[test]
fn every_fixture_decodes_to_libjpegs_samples_exactly() {
    for &(name, w, h, c) in FIXTURES {
        let want = std::fs::read(fixture(name, "raw")).unwrap();
        let (gw, gh, gc, got) = tstat_decode(name);
        assert_eq!((gw, gh, gc), (w, h, c), "{name}: size or channels");
        let (max, count) = diff(&got, &want);
        assert_eq!(
            (max, count),
            (0, 0),
            "{name}: {count} samples differ from libjpeg's, by up to {max}"
        );
    }
}

#[test]
fn srgb_textures_decode_libjpegs_samples_through_the_srgb_curve() {
    let want = std::fs::read(fixture("baseline_420", "raw")).unwrap();
    let img = load_image(&fixture("baseline_420", "jpg"), false).unwrap();
    for (v, b) in img.data.iter().zip(&want) {
        assert_eq!(*v, srgb_to_linear(*b as f32 / 255.0));
    }
}

/// The `image` crate (the decoder tstat used before) does not give libjpeg's samples
/// on a 4:2:0 file: this is what the tests above guard against.
#[test]
fn the_image_crate_differs_from_libjpeg_on_420() {
    let want = std::fs::read(fixture("baseline_420", "raw")).unwrap();
    let old = image::open(fixture("baseline_420", "jpg"))
        .unwrap()
        .to_rgb8()
        .into_raw();
    let (max, count) = diff(&old, &want);
    assert!(max >= 2 && count > 10, "max {max}, {count} samples differ");
}

#[test]
fn cmyk_is_refused_with_one_line() {
    let err = load_image(&fixture("cmyk", "jpg"), true).unwrap_err();
    assert!(matches!(err, ImageFileError::Jpeg(_)), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("CMYK") && !msg.contains('\n'), "{msg}");
}

/// Cut and corrupted files end in an error or a decode, never a panic.
#[test]
fn cut_and_flipped_files_do_not_panic() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.jpg");
    for &(name, ..) in FIXTURES {
        let bytes = std::fs::read(fixture(name, "jpg")).unwrap();
        for cut in (0..bytes.len()).step_by(7) {
            std::fs::write(&path, &bytes[..cut]).unwrap();
            if let Err(e) = load_image(&path, true) {
                assert!(!e.to_string().contains('\n'));
            }
        }
        // A longer campaign: TSTAT_FUZZ_CASES=100000 (and TSTAT_FUZZ_SEED) as for the
        // other fuzz targets.
        let cases: usize = std::env::var("TSTAT_FUZZ_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(200);
        let mut s = std::env::var("TSTAT_FUZZ_SEED")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(0x9E37_79B9u32)
            | 1;
        for _ in 0..cases {
            let mut b = bytes.clone();
            for _ in 0..3 {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                let i = s as usize % b.len();
                b[i] ^= (s >> 8) as u8 | 1;
            }
            std::fs::write(&path, &b).unwrap();
            if let Err(e) = load_image(&path, true) {
                assert!(!e.to_string().contains('\n'), "{e}");
            }
        }
    }
}
