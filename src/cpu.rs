//! Instruction sets: one portable binary (built for the x86-64 baseline), its kernels
//! compiled once per instruction set and chosen at run time.
//!
//! Each entry point (`render::tracer::trace`, `render::nlos::trace_nlos`, the render's
//! row loop, the Sobol' table's fill, the denoiser's filter bands, NLOS backprojection's
//! pair sums, phasor fields' direct sums) matches on [`detected`] and calls a
//! `#[target_feature]` wrapper of an `#[inline(always)]` body generic over [`Level`],
//! so everything the body inlines (intersection, the flat triangle packets, shading,
//! sampling) is compiled for AVX-512, AVX2 + FMA or the baseline; `nlos::fft` picks
//! rustfft's kernels by the same level. Rust never contracts `a * b + c` into an FMA
//! nor reorders float sums, so every level computes the same bits (but for the FFT
//! methods' rounding); `tests/it/isa.rs` checks it by forcing each level the CPU has, and
//! `scripts/isa_qemu.sh` on an emulated CPU without AVX2.
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

/// A level the kernels are specialised for, as a value that proves the CPU has it:
/// [`Avx2`] and [`Avx512`] values exist only once detection found the instruction set
/// ([`detected`], or their own `detect`), so a kernel that takes one needs no
/// `unsafe` contract. Generic code asks the value which proofs it carries; the answer
/// is a constant of the type, so every branch folds away in each specialisation.
pub trait Level: Copy {
    /// The level's name.
    const ISA: Isa;
    /// The AVX2 + FMA + BMI1/2 proof this level carries, if it carries one.
    fn avx2(self) -> Option<Avx2>;
    /// The AVX-512 proof this level carries, if it carries one.
    fn avx512(self) -> Option<Avx512>;
}

/// The x86-64 baseline (or any other architecture): runs everywhere.
#[derive(Clone, Copy, Debug)]
pub struct Baseline;

/// Proof that this CPU runs AVX2, FMA, BMI1/2, LZCNT and POPCNT (x86-64-v3).
#[derive(Clone, Copy, Debug)]
pub struct Avx2(());

/// Proof that this CPU runs AVX-512 F/VL/DQ/BW/CD on top of [`Avx2`] (x86-64-v4).
#[derive(Clone, Copy, Debug)]
pub struct Avx512(());

impl Avx2 {
    /// The proof, when this CPU has the level.
    pub fn detect() -> Option<Avx2> {
        Isa::Avx2.supported().then_some(Avx2(()))
    }
}

impl Avx512 {
    /// The proof, when this CPU has the level.
    pub fn detect() -> Option<Avx512> {
        Isa::Avx512.supported().then_some(Avx512(()))
    }
}

impl Level for Baseline {
    const ISA: Isa = Isa::Baseline;
    #[inline(always)]
    fn avx2(self) -> Option<Avx2> {
        None
    }
    #[inline(always)]
    fn avx512(self) -> Option<Avx512> {
        None
    }
}

impl Level for Avx2 {
    const ISA: Isa = Isa::Avx2;
    #[inline(always)]
    fn avx2(self) -> Option<Avx2> {
        Some(self)
    }
    #[inline(always)]
    fn avx512(self) -> Option<Avx512> {
        None
    }
}

impl Level for Avx512 {
    const ISA: Isa = Isa::Avx512;
    #[inline(always)]
    fn avx2(self) -> Option<Avx2> {
        Some(Avx2(()))
    }
    #[inline(always)]
    fn avx512(self) -> Option<Avx512> {
        Some(self)
    }
}

/// The level [`current`] chose, with its proof.
#[derive(Clone, Copy, Debug)]
pub enum Detected {
    Baseline(Baseline),
    Avx2(Avx2),
    Avx512(Avx512),
}

impl Detected {
    /// The AVX2 proof this level carries, if it carries one.
    #[inline]
    pub fn avx2(self) -> Option<Avx2> {
        match self {
            Detected::Baseline(l) => l.avx2(),
            Detected::Avx2(l) => l.avx2(),
            Detected::Avx512(l) => l.avx2(),
        }
    }
}

/// [`current`] as a proof: the kernels' dispatch starts here.
#[inline]
pub fn detected() -> Detected {
    match current() {
        // `current` returns only levels this CPU supports (it checks the environment's
        // and `force`'s choices), so the proofs are sound.
        Isa::Avx512 => Detected::Avx512(Avx512(())),
        Isa::Avx2 => Detected::Avx2(Avx2(())),
        Isa::Baseline => Detected::Baseline(Baseline),
    }
}

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
