//! The fuzz targets' proptest runner: a fixed seed so CI is reproducible, and the
//! environment's `TSTAT_FUZZ_CASES` / `TSTAT_FUZZ_SEED` for longer campaigns on other
//! inputs. Included by `tests/fuzz*.rs` with
//! `#[path = "common/fuzz_runner.rs"] mod fuzz_runner;`.

use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

/// Cases per target: `TSTAT_FUZZ_CASES` or the CI default.
pub fn cases(default: u32) -> u32 {
    std::env::var("TSTAT_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// A runner of `default_cases` cases (or `TSTAT_FUZZ_CASES`) seeded with
/// `default_seed` (or `TSTAT_FUZZ_SEED`).
pub fn runner(default_cases: u32, default_seed: u64) -> TestRunner {
    let seed: u64 = std::env::var("TSTAT_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default_seed);
    let mut bytes = [0u8; 32];
    bytes[..8].copy_from_slice(&seed.to_le_bytes());
    let config = Config {
        cases: cases(default_cases),
        failure_persistence: None,
        ..Config::default()
    };
    TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &bytes))
}
