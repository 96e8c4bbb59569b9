//! The media's phase functions as whole-sphere models in the chi-square family.

use crate::harness::{dir, Case};
use glam::Vec3;
use tstat::materials::{BsdfFlags, BsdfModel, BsdfSample};
use tstat::math::Rgb;
use tstat::media::Phase;

/// A phase function seen as a BSDF over the whole sphere: the BSDF's `wo` is the
/// phase function's `wi` (back along the incoming ray) and the BSDF's sampled `wi` its
/// `wo`; eval = pdf = the phase function, weight 1, nothing absorbed.
struct PhaseAsBsdf(Phase);

impl BsdfModel for PhaseAsBsdf {
    fn flags(&self, _wo: Vec3) -> BsdfFlags {
        BsdfFlags::DIFFUSE
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        Rgb::splat(self.0.eval(wo, wi))
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.eval(wo, wi)
    }
    fn sample(&self, wo: Vec3, _u1: f32, u2: [f32; 2]) -> Option<BsdfSample> {
        let s = self.0.sample(wo, u2);
        Some(BsdfSample {
            wi: s.wo,
            weight: Rgb::ONE,
            pdf: s.pdf,
            lobe: if s.wo.z >= 0.0 {
                BsdfFlags::DIFFUSE_REFLECTION
            } else {
                BsdfFlags::DIFFUSE_TRANSMISSION
            },
            eta: 1.0,
        })
    }
    fn albedo(&self, _wo: Vec3) -> Rgb {
        Rgb::ONE
    }
}

/// The media's phase functions (`isotropic`, `hg` forward and backward).
pub(crate) fn phase_cases() -> Vec<Case> {
    [
        ("phase isotropic", Phase::Isotropic, dir(30.0, 20.0)),
        ("phase hg 0.7", Phase::Hg { g: 0.7 }, dir(50.0, 80.0)),
        ("phase hg -0.4", Phase::Hg { g: -0.4 }, dir(120.0, 250.0)),
    ]
    .into_iter()
    .map(|(n, p, wo)| {
        let model: Box<dyn BsdfModel> = Box::new(PhaseAsBsdf(p));
        (n.to_string(), model, wo)
    })
    .collect()
}
