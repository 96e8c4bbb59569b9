//! The FFT planner of every NLOS reconstruction, under the project's instruction-set
//! policy (`cpu`): rustfft's AVX kernels where `cpu` chose AVX2 or wider, its scalar
//! kernels otherwise. rustfft's own `FftPlanner` detects the CPU by itself and would take
//! its SSE4.1 kernels on a CPU without AVX2, which round differently from the scalar ones;
//! through this planner a reconstruction on such a CPU is the one `TSTAT_ISA=baseline`
//! computes anywhere (`scripts/isa_qemu.sh`).

use rustfft::{Fft, FftDirection, FftPlannerAvx, FftPlannerScalar};
use std::sync::Arc;

/// rustfft's AVX or scalar planner, as [`crate::cpu::detected`] says.
pub enum Planner {
    Avx(FftPlannerAvx<f64>),
    Scalar(FftPlannerScalar<f64>),
}

impl Default for Planner {
    fn default() -> Self {
        Self::new()
    }
}

impl Planner {
    pub fn new() -> Planner {
        let avx = crate::cpu::detected()
            .avx2()
            .and_then(|_| FftPlannerAvx::new().ok());
        match avx {
            Some(p) => Planner::Avx(p),
            None => Planner::Scalar(FftPlannerScalar::new()),
        }
    }

    pub fn plan_fft(&mut self, len: usize, direction: FftDirection) -> Arc<dyn Fft<f64>> {
        match self {
            Planner::Avx(p) => p.plan_fft(len, direction),
            Planner::Scalar(p) => p.plan_fft(len, direction),
        }
    }

    pub fn plan_fft_forward(&mut self, len: usize) -> Arc<dyn Fft<f64>> {
        self.plan_fft(len, FftDirection::Forward)
    }

    pub fn plan_fft_inverse(&mut self, len: usize) -> Arc<dyn Fft<f64>> {
        self.plan_fft(len, FftDirection::Inverse)
    }
}
