//! Fuzzing the y-tal HDF5 capture reader (`Capture::from_tal_within`,
//! `src/nlos/tal_read.rs`) on the stable toolchain: byte-level mutations of small valid
//! captures -- the h5py fixtures (gzip, gzip + shuffle + fletcher32, contiguous) and
//! one written by hdf5-pure's `FileBuilder` the way `tstat export --tal` writes -- with
//! words overwritten by nasty integers (addresses, sizes, dimensions) and floats (NaN,
//! infinities, huge values). Each mutated file must give a clean one-line error or a
//! capture whose H is finite and of its shape's length; a panic (caught by the reader's
//! last-resort `catch_unwind`, or escaping it) fails the property, and proptest shrinks
//! the mutation list.
//!
//! CI runs 400 cases per base, 2000 in all (a few seconds); a longer campaign:
//! `TSTAT_FUZZ_CASES=50000 TSTAT_FUZZ_SEED=$RANDOM cargo test --release --test fuzz_tal`.

use crate::tal_common;

use crate::common::fuzz_runner;

use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use std::path::Path;
use tal_common::{bytes, capture, fixture, get};
use tstat::nlos::capture::Capture;

/// This target's runner (see `common/fuzz_runner.rs`).
fn runner(default_cases: u32) -> proptest::test_runner::TestRunner {
    fuzz_runner::runner(default_cases, 20261206)
}

/// Integers that break addresses, sizes, counts and dimensions.
const NASTY_INTS: &[u64] = &[
    0,
    1,
    2,
    3,
    7,
    0xff,
    0xffff,
    0x7fff_ffff,
    0xffff_ffff,
    0x1_0000_0000,
    1_000_000_000,
    600,
    1000,
    u64::MAX,
    u64::MAX - 1,
    i64::MAX as u64,
];

/// Floats that break the arithmetic behind a capture.
const NASTY_FLOATS: &[f64] = &[
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    1e30,
    -1e30,
    1e300,
    1e-300,
    0.0,
    -0.0,
    3.4e38,
    1e-45,
];

/// One edit of the file's bytes; positions are fractions of its length.
#[derive(Clone, Debug)]
enum Mutation {
    Delete {
        at: f64,
        len: usize,
    },
    Duplicate {
        at: f64,
        len: usize,
        to: f64,
    },
    Insert {
        at: f64,
        bytes: Vec<u8>,
    },
    Flip {
        at: f64,
        bit: u8,
    },
    /// Overwrite `width` bytes (1, 2, 4 or 8) with a nasty integer, little-endian.
    Int {
        at: f64,
        value: usize,
        width: usize,
    },
    /// Overwrite 4 or 8 bytes with a nasty float.
    Float {
        at: f64,
        value: usize,
        wide: bool,
    },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let at = 0.0..1.0f64;
    prop_oneof![
        (at.clone(), 1..64usize).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (at.clone(), 1..64usize, 0.0..1.0f64).prop_map(|(at, len, to)| Mutation::Duplicate {
            at,
            len,
            to
        }),
        (at.clone(), prop::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        (at.clone(), 0..8u8).prop_map(|(at, bit)| Mutation::Flip { at, bit }),
        (
            at.clone(),
            0..NASTY_INTS.len(),
            prop::sample::select(vec![1usize, 2, 4, 8])
        )
            .prop_map(|(at, value, width)| Mutation::Int { at, value, width }),
        (at, 0..NASTY_FLOATS.len(), any::<bool>()).prop_map(|(at, value, wide)| Mutation::Float {
            at,
            value,
            wide
        }),
    ]
}

fn pos(at: f64, len: usize) -> usize {
    ((at * len as f64) as usize).min(len)
}

fn overwrite(b: &mut [u8], at: f64, word: &[u8]) {
    if b.len() >= word.len() {
        let s = pos(at, b.len() - word.len());
        b[s..s + word.len()].copy_from_slice(word);
    }
}

/// The mutated file: `base` with `muts` applied in order.
fn apply(base: &[u8], muts: &[Mutation]) -> Vec<u8> {
    let mut b = base.to_vec();
    for m in muts {
        let n = b.len();
        match m {
            Mutation::Delete { at, len } => {
                let s = pos(*at, n);
                b.drain(s..(s + len).min(n));
            }
            Mutation::Duplicate { at, len, to } => {
                let s = pos(*at, n);
                let piece = b[s..(s + len).min(n)].to_vec();
                let t = pos(*to, n);
                b.splice(t..t, piece);
            }
            Mutation::Insert { at, bytes } => {
                let s = pos(*at, n);
                b.splice(s..s, bytes.iter().copied());
            }
            Mutation::Flip { at, bit } => {
                if n > 0 {
                    let s = pos(*at, n - 1);
                    b[s] ^= 1 << bit;
                }
            }
            Mutation::Int { at, value, width } => {
                let v = NASTY_INTS[*value].to_le_bytes();
                overwrite(&mut b, *at, &v[..*width]);
            }
            Mutation::Float { at, value, wide } => {
                let v = NASTY_FLOATS[*value];
                if *wide {
                    overwrite(&mut b, *at, &v.to_le_bytes());
                } else {
                    overwrite(&mut b, *at, &(v as f32).to_le_bytes());
                }
            }
        }
    }
    b
}

/// Within this budget a mutated file allocates at most what it stores.
const BUDGET: u64 = 256 << 20;

/// Reads `path`: a clean one-line error, or a capture with a finite H of its shape.
fn read(path: &Path) -> Result<(), TestCaseError> {
    let r = std::panic::catch_unwind(|| Capture::from_tal_within(path, BUDGET));
    let r = r.map_err(|_| TestCaseError::fail("the reader panicked"))?;
    match r {
        Ok(c) => {
            prop_assert_eq!(c.h.len(), c.time.bins * c.lasers * c.sensors);
            prop_assert!(c.h.iter().all(|v| v.is_finite()), "non-finite H");
            prop_assert!(c.time.start_opl.is_finite() && c.time.bin_width_opl > 0.0);
            prop_assert_eq!(c.sensor_grid.len(), c.sensors);
        }
        Err(e) => {
            let msg = e.to_string();
            prop_assert!(!msg.is_empty() && !msg.contains('\n'), "{msg:?}");
            prop_assert!(!msg.contains("panic"), "the HDF5 reader panicked: {msg}");
        }
    }
    Ok(())
}

/// The bases: the h5py fixtures and a FileBuilder capture with a gzip + shuffle H.
fn bases() -> Vec<(&'static str, Vec<u8>)> {
    let mut built = capture(8, 3);
    let h = get(&mut built, "H");
    h.chunks = Some(vec![4, 3, 3]);
    h.deflate = true;
    h.shuffle = true;
    vec![
        ("gzip.hdf5", std::fs::read(fixture("gzip.hdf5")).unwrap()),
        (
            "gzip_shuffle_fletcher32.hdf5",
            std::fs::read(fixture("gzip_shuffle_fletcher32.hdf5")).unwrap(),
        ),
        (
            "contiguous.hdf5",
            std::fs::read(fixture("contiguous.hdf5")).unwrap(),
        ),
        ("FileBuilder", bytes(&capture(8, 3))),
        ("FileBuilder gzip", bytes(&built)),
    ]
}

#[test]
fn mutated_tal_captures_are_read_cleanly_or_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("case.hdf5");
    for (name, base) in bases() {
        // Each base reads unmutated.
        std::fs::write(&path, &base).unwrap();
        Capture::from_tal_within(&path, BUDGET)
            .unwrap_or_else(|e| panic!("{name}: the base is refused: {e}"));
        let mut runner = runner(400);
        runner
            .run(&prop::collection::vec(mutation(), 1..=4), |muts| {
                std::fs::write(&path, apply(&base, &muts)).unwrap();
                read(&path)
            })
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}
