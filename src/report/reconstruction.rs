//! Reconstructions in the convergence experiment (NLOS scenes): every capture the
//! experiment measures (noisy, denoised, the reference) is also reconstructed with
//! each method asked for, on one voxel grid, and the reconstruction's error is its
//! relative L2 distance to the reconstruction of the reference capture,
//! `||V - V_ref|| / ||V_ref||` (fbp and pf: of the magnitudes).
//!
//! Memory: one capture's H (T L S f32) at a time, each method's working memory (checked
//! against a budget before the first render), and one reconstruction (NX NY NZ f32) per
//! method for the reference.

use super::ReportError;
use crate::bundle::capture::CaptureRecord;
use crate::nlos::capture::Capture;
use crate::nlos::denoised::replace_h;
use crate::nlos::reconstruct::bp::VoxelGrid;
use crate::nlos::reconstruct::Reconstruction;
use crate::nlos::tal::h_per_bin;
use crate::scene::Scene;
use crate::sensors::time_axis::TimeAxis;
use ndarray::Array4;

/// What to reconstruct: the methods, the grid, and the working memory allowed.
#[derive(Clone, Debug)]
pub struct NlosPlan {
    pub methods: Vec<Reconstruction>,
    pub grid: VoxelGrid,
    pub max_memory: u64,
}

/// One reconstruction's error and time.
#[derive(Clone, Copy, Debug)]
pub struct ReconstructionError {
    /// `||V - V_ref|| / ||V_ref||`.
    pub error: f64,
    /// The reconstruction's wall time.
    pub seconds: f64,
}

/// The methods of a plan bound to a scene's capture, with the reference's
/// reconstructions.
pub struct Reconstructor {
    plan: NlosPlan,
    record: CaptureRecord,
    time: TimeAxis,
    reference: Vec<Vec<f32>>,
}

/// `||x - r|| / ||r||` in f64.
pub fn relative_l2(x: &[f32], r: &[f32]) -> f64 {
    assert_eq!(x.len(), r.len());
    let (mut d, mut n) = (0f64, 0f64);
    for (&a, &b) in x.iter().zip(r) {
        d += (a as f64 - b as f64).powi(2);
        n += (b as f64).powi(2);
    }
    (d / n).sqrt()
}

impl Reconstructor {
    /// Binds `plan` to `scene` (an NLOS scene); refuses a scene that is no capture and
    /// a method that cannot run on it or needs more than the plan's memory.
    pub fn new(scene: &Scene, plan: NlosPlan) -> Result<Self, ReportError> {
        let record = CaptureRecord::of_scene(scene).ok_or(ReportError::NotAnNlosScene)?;
        let r = Reconstructor {
            plan,
            record,
            time: scene.film.time,
            reference: Vec::new(),
        };
        let h = vec![0f32; r.time.bins * h_per_bin(&r.record)];
        let c = Capture::from_record(&r.record, r.time, h);
        for m in &r.plan.methods {
            m.check(&c).map_err(|error| ReportError::Method {
                method: m.name(),
                error: Box::new(error),
            })?;
            let need = m.working_memory(&c, &r.plan.grid)?;
            if need > r.plan.max_memory {
                return Err(ReportError::ReconstructionMemory {
                    method: m.name(),
                    grid: r.plan.grid.n,
                    need,
                    allowed: r.plan.max_memory,
                });
            }
        }
        Ok(r)
    }

    /// Reconstructs the reference capture `v` ((rows, Sx, T, C), the film's shape) with
    /// every method; refuses a reconstruction that is zero everywhere (no error can be
    /// relative to it).
    pub fn set_reference(&mut self, v: &Array4<f32>) -> Result<(), ReportError> {
        let c = self.capture(v)?;
        let mut reference = Vec::new();
        for m in &self.plan.methods {
            let x = m.run(&c, &self.plan.grid)?;
            if x.iter().all(|&x| x == 0.0) {
                return Err(ReportError::ZeroReference(m.name()));
            }
            reference.push(x);
        }
        self.reference = reference;
        Ok(())
    }

    pub fn methods(&self) -> &[Reconstruction] {
        &self.plan.methods
    }

    pub fn grid(&self) -> &VoxelGrid {
        &self.plan.grid
    }

    /// The reference's reconstruction by method `k`.
    pub fn reference(&self, k: usize) -> &[f32] {
        &self.reference[k]
    }

    /// The capture of a film volume (rows, Sx, T, C).
    fn capture(&self, v: &Array4<f32>) -> Result<Capture, ReportError> {
        let h = vec![0f32; self.time.bins * h_per_bin(&self.record)];
        let mut c = Capture::from_record(&self.record, self.time, h);
        let s = v.shape();
        let values: Vec<f32> = v.iter().copied().collect();
        replace_h(&mut c, &self.record, &values, [s[0], s[1], s[2], s[3]])?;
        Ok(c)
    }

    /// Reconstructs the capture `v` with every method: each error against the
    /// reference's reconstruction (set first), and the reconstructions themselves.
    pub fn measure(
        &self,
        v: &Array4<f32>,
    ) -> Result<(Vec<ReconstructionError>, Vec<Vec<f32>>), ReportError> {
        assert_eq!(
            self.reference.len(),
            self.plan.methods.len(),
            "reference set"
        );
        let c = self.capture(v)?;
        let mut errors = Vec::new();
        let mut volumes = Vec::new();
        for (m, r) in self.plan.methods.iter().zip(&self.reference) {
            let start = std::time::Instant::now();
            let x = m.run(&c, &self.plan.grid)?;
            let seconds = start.elapsed().as_secs_f64();
            errors.push(ReconstructionError {
                error: relative_l2(&x, r),
                seconds,
            });
            volumes.push(x);
        }
        Ok((errors, volumes))
    }
}

impl Reconstructor {
    /// `nlos reconstruct --denoise-with`'s reconstructions (`nlos/shrink.rs`): the
    /// denoised capture `denoised` of the noisy film `noisy` shrunk toward it, per
    /// method, by the weight cross-validated between two independent half captures
    /// (`halves`: each one's noisy and denoised film, of half the samples); each
    /// method's error against the reference, time, and weight b. `radius_one`: on an
    /// exhaustive scan denoised with its default radius 0, the denoised film and
    /// halves at radius 1, which the methods [`radius_for`] gives radius 1 take, as
    /// `nlos reconstruct --denoise-with` does.
    pub fn measure_cross_validated(
        &self,
        noisy: &Array4<f32>,
        denoised: &Array4<f32>,
        halves: [(&Array4<f32>, &Array4<f32>); 2],
        radius_one: Option<(&Array4<f32>, [&Array4<f32>; 2])>,
    ) -> Result<Vec<(ReconstructionError, f64)>, ReportError> {
        use crate::nlos::shrink::{applied, blend, cross_validated_beta, for_merge, radius_for};
        assert_eq!(
            self.reference.len(),
            self.plan.methods.len(),
            "reference set"
        );
        let n = self.capture(noisy)?;
        let (na, nb) = (self.capture(halves[0].0)?, self.capture(halves[1].0)?);
        // A denoised film and its halves, as captures.
        let set = |d: &Array4<f32>, h: [&Array4<f32>; 2]| -> Result<[Capture; 3], ReportError> {
            Ok([self.capture(d)?, self.capture(h[0])?, self.capture(h[1])?])
        };
        let own = set(denoised, [halves[0].1, halves[1].1])?;
        let one = radius_one.map(|(d, h)| set(d, h)).transpose()?;
        let mut out = Vec::new();
        for (m, r) in self.plan.methods.iter().zip(&self.reference) {
            let [d, da, db] = match (&one, radius_for(m, true)) {
                (Some(one), Some(1)) => one,
                _ => &own,
            };
            let start = std::time::Instant::now();
            let b = applied(for_merge(cross_validated_beta(
                m,
                &self.plan.grid,
                [&na, &nb],
                [da, db],
            )?));
            let mut c = d.clone();
            blend(&mut c, &n, b);
            let x = m.run(&c, &self.plan.grid)?;
            let seconds = start.elapsed().as_secs_f64();
            out.push((
                ReconstructionError {
                    error: relative_l2(&x, r),
                    seconds,
                },
                b,
            ));
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::relative_l2;

    #[test]
    fn relative_l2_is_the_distance_over_the_references_norm() {
        // ||(3, 4) - (0, 0)|| / ||(0, 0)||: undefined; ||(1, 2) - (1, 0)|| / ||(1, 0)|| = 2.
        assert_eq!(relative_l2(&[1.0, 2.0], &[1.0, 0.0]), 2.0);
        assert_eq!(relative_l2(&[3.0, 4.0], &[3.0, 4.0]), 0.0);
        // (0.5 (3, 4)): half of the reference's norm away.
        assert!((relative_l2(&[1.5, 2.0], &[3.0, 4.0]) - 0.5).abs() < 1e-15);
    }
}
