//! Instruction sets: one portable binary, the tracer compiled once per instruction set
//! and chosen at run time.
//!
//! `integrator::trace_path` is an `#[inline(always)]` body wrapped by one function per
//! instruction set (`#[target_feature]`), so everything it inlines (intersection, the
//! flat triangle packets, shading, sampling) is compiled for AVX-512, AVX2 + FMA or the
//! x86-64 baseline. Rust never contracts `a * b + c` into an FMA nor reorders float
//! sums, so every level computes the same bits; `tests/isa.rs` checks it by
//! forcing each level the CPU has.
//!
//! The level is detected once; [`force`] overrides it (tests, benchmarks), and so does
//! the environment variable `TSTAT_ISA` = `baseline` | `avx2` | `avx512` (any other
//! value, or a level the CPU lacks, is a `warning:` line and the widest level is used).

use std::sync::atomic::{AtomicU8, Ordering};

/// An instruction-set level the tracer is compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// x86-64 baseline (SSE2), or any other architecture.
    Baseline,
    /// AVX2 + FMA + BMI1/2 (x86-64-v3).
    Avx2,
    /// AVX-512 F/VL/DQ/BW/CD on top of AVX2 (x86-64-v4).
    Avx512,
}

impl Isa {
    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "baseline",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    pub fn parse(s: &str) -> Option<Isa> {
        [Isa::Baseline, Isa::Avx2, Isa::Avx512]
            .into_iter()
            .find(|i| i.name() == s)
    }

    /// Whether this CPU can run code compiled for `self`.
    pub fn supported(self) -> bool {
        match self {
            Isa::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => {
                std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                    && std::arch::is_x86_feature_detected!("bmi1")
                    && std::arch::is_x86_feature_detected!("bmi2")
                    && std::arch::is_x86_feature_detected!("lzcnt")
                    && std::arch::is_x86_feature_detected!("popcnt")
            }
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => {
                Isa::Avx2.supported()
                    && std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx512bw")
                    && std::arch::is_x86_feature_detected!("avx512cd")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The widest level this CPU supports.
    pub fn best() -> Isa {
        [Isa::Avx512, Isa::Avx2]
            .into_iter()
            .find(|i| i.supported())
            .unwrap_or(Isa::Baseline)
    }

    fn code(self) -> u8 {
        match self {
            Isa::Baseline => 1,
            Isa::Avx2 => 2,
            Isa::Avx512 => 3,
        }
    }
}

/// [`Isa`] as const-generic codes, for kernels specialised per level.
pub const ISA_BASELINE: u8 = 1;
pub const ISA_AVX2: u8 = 2;
pub const ISA_AVX512: u8 = 3;

/// 0: not chosen yet.
static LEVEL: AtomicU8 = AtomicU8::new(0);

/// The level the tracer runs at: forced, from `TSTAT_ISA` when the CPU supports it, or
/// the widest the CPU has.
#[inline]
pub fn current() -> Isa {
    match LEVEL.load(Ordering::Relaxed) {
        1 => Isa::Baseline,
        2 => Isa::Avx2,
        3 => Isa::Avx512,
        _ => {
            let best = Isa::best();
            let isa = match std::env::var("TSTAT_ISA") {
                Err(_) => best,
                Ok(s) => match Isa::parse(s.trim()) {
                    Some(i) if i.supported() => i,
                    Some(i) => {
                        eprintln!(
                            "warning: TSTAT_ISA={}: this CPU does not support it; using {}",
                            i.name(),
                            best.name()
                        );
                        best
                    }
                    None => {
                        eprintln!(
                            "warning: TSTAT_ISA={s:?} is not baseline, avx2 or avx512; using {}",
                            best.name()
                        );
                        best
                    }
                },
            };
            LEVEL.store(isa.code(), Ordering::Relaxed);
            isa
        }
    }
}

/// An instruction set this CPU lacks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("this CPU does not support {}", .0.name())]
pub struct UnsupportedIsa(pub Isa);

/// Runs the tracer at `isa` from now on (every level gives the same bits; this only
/// changes speed). Errors when the CPU lacks it.
pub fn force(isa: Isa) -> Result<(), UnsupportedIsa> {
    if !isa.supported() {
        return Err(UnsupportedIsa(isa));
    }
    LEVEL.store(isa.code(), Ordering::Relaxed);
    Ok(())
}
