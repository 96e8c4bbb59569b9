//! Microfacet distributions (Mitsuba 3's `MicrofacetDistribution`): Beckmann and GGX,
//! anisotropic (`alpha_u` along the tangent x, `alpha_v` along y), with Smith's shadowing
//! and masking. `m` is a microfacet normal in the local frame (z up).
//!
//! Sampling: GGX samples the distribution of normals visible from `wo` (Heitz 2018),
//! as Mitsuba does by default; Beckmann, and GGX with `sample_visible = false`, sample
//! `D(m) cos(theta_m)`. Both are unbiased; only the noise differs from Mitsuba's
//! visible-normal Beckmann sampler.

use glam::Vec3;
use std::f32::consts::PI;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicrofacetKind {
    Beckmann,
    Ggx,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    pub kind: MicrofacetKind,
    pub alpha_u: f32,
    pub alpha_v: f32,
    /// Sample only the normals visible from `wo` (GGX).
    pub sample_visible: bool,
}

impl Microfacet {
    /// `alpha_u != alpha_v`: the lobe depends on the tangent frame's orientation.
    #[inline]
    pub fn is_anisotropic(&self) -> bool {
        self.alpha_u != self.alpha_v
    }

    fn visible(&self) -> bool {
        self.sample_visible && self.kind == MicrofacetKind::Ggx
    }

    /// The density of normals per unit projected area, `D(m)`.
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let (au, av) = (self.alpha_u, self.alpha_v);
        let cos2 = m.z * m.z;
        let r = match self.kind {
            MicrofacetKind::Beckmann => {
                let e = ((m.x / au).powi(2) + (m.y / av).powi(2)) / cos2;
                // Beyond exp(-80) the value would be a denormal with no precision left.
                if e > 80.0 {
                    return 0.0;
                }
                (-e).exp() / (PI * au * av * cos2 * cos2)
            }
            MicrofacetKind::Ggx => {
                let t = (m.x / au).powi(2) + (m.y / av).powi(2) + cos2;
                1.0 / (PI * au * av * t * t)
            }
        };
        // Underflow at grazing normals: 0, never NaN.
        if r.is_finite() {
            r
        } else {
            0.0
        }
    }

    /// Smith's one-sided shadowing-masking `G1(v, m)`.
    #[inline]
    pub fn g1(&self, v: Vec3, m: Vec3) -> f32 {
        if v.dot(m) * v.z <= 0.0 {
            return 0.0;
        }
        let xy = (self.alpha_u * v.x).powi(2) + (self.alpha_v * v.y).powi(2);
        if xy <= 0.0 {
            return 1.0;
        }
        let tan2 = xy / (v.z * v.z);
        match self.kind {
            MicrofacetKind::Ggx => 2.0 / (1.0 + (1.0 + tan2).sqrt()),
            MicrofacetKind::Beckmann => {
                // Walter et al.'s rational approximation, as Mitsuba uses.
                let a = 1.0 / tan2.sqrt();
                if a >= 1.6 {
                    1.0
                } else {
                    let a2 = a * a;
                    (3.535 * a + 2.181 * a2) / (1.0 + 2.276 * a + 2.577 * a2)
                }
            }
        }
    }

    /// `G(wi, wo, m) = G1(wi, m) G1(wo, m)`.
    #[inline]
    pub fn g(&self, wi: Vec3, wo: Vec3, m: Vec3) -> f32 {
        self.g1(wi, m) * self.g1(wo, m)
    }

    /// Density (per solid angle of `m`) with which [`Self::sample`] returns `m` for `wo`.
    #[inline]
    pub fn pdf(&self, wo: Vec3, m: Vec3) -> f32 {
        if self.visible() {
            if wo.z <= 0.0 {
                return 0.0;
            }
            self.g1(wo, m) * wo.dot(m).max(0.0) * self.d(m) / wo.z
        } else {
            self.d(m) * m.z.max(0.0)
        }
    }

    /// [`Self::pdf`] given `d = self.d(m)` and `g1_wo = self.g1(wo, m)`, already
    /// computed by a caller that evaluates the lobe too: the same operations in the same
    /// order, so the same bits, without evaluating D and G1 again (`g1_wo` is not read
    /// unless the visible normals are sampled).
    #[inline]
    pub fn pdf_with(&self, wo: Vec3, m: Vec3, d: f32, g1_wo: f32) -> f32 {
        if self.visible() {
            if wo.z <= 0.0 {
                return 0.0;
            }
            g1_wo * wo.dot(m).max(0.0) * d / wo.z
        } else {
            d * m.z.max(0.0)
        }
    }

    /// A microfacet normal for `wo` from two uniform numbers in [0, 1).
    #[inline]
    pub fn sample(&self, wo: Vec3, u: [f32; 2]) -> Vec3 {
        if self.visible() {
            return self.sample_visible_ggx(wo, u);
        }
        let (au, av) = (self.alpha_u, self.alpha_v);
        // Azimuth: for anisotropic roughness the marginal in phi is not uniform.
        let (sin_phi, cos_phi, alpha2) = if au == av {
            let (s, c) = (2.0 * PI * u[1]).sin_cos();
            (s, c, au * au)
        } else {
            let phi = (av / au * (2.0 * PI * u[1]).tan()).atan() + PI * (2.0 * u[1] + 0.5).floor();
            let (s, c) = phi.sin_cos();
            let a2 = 1.0 / ((c / au).powi(2) + (s / av).powi(2));
            (s, c, a2)
        };
        let tan2 = match self.kind {
            MicrofacetKind::Beckmann => -alpha2 * (1.0 - u[0]).ln(),
            MicrofacetKind::Ggx => alpha2 * u[0] / (1.0 - u[0]),
        };
        let cos_theta = 1.0 / (1.0 + tan2).sqrt();
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
    }

    /// Heitz 2018, "Sampling the GGX distribution of visible normals".
    fn sample_visible_ggx(&self, wo: Vec3, u: [f32; 2]) -> Vec3 {
        let (au, av) = (self.alpha_u, self.alpha_v);
        let vh = Vec3::new(au * wo.x, av * wo.y, wo.z).normalize();
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        let r = u[0].sqrt();
        let phi = 2.0 * PI * u[1];
        let (s, c) = phi.sin_cos();
        let p1 = r * c;
        let mut p2 = r * s;
        let blend = 0.5 * (1.0 + vh.z);
        p2 = (1.0 - blend) * (1.0 - p1 * p1).max(0.0).sqrt() + blend * p2;
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        Vec3::new(au * nh.x, av * nh.y, nh.z.max(1e-6)).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `pdf_with` given D and G1 is `pdf` to the bit, for every kind and sampler, from
    /// above and below, normals on both sides.
    #[test]
    fn pdf_with_the_shared_terms_is_pdf() {
        let mut rng = crate::math::rng::Pcg32::new(11, 5);
        let mut dir = || {
            let [u, v] = rng.next_2d();
            let z = 1.0 - 2.0 * u;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let (s, c) = (2.0 * PI * v).sin_cos();
            Vec3::new(r * c, r * s, z)
        };
        for kind in [MicrofacetKind::Beckmann, MicrofacetKind::Ggx] {
            for (alpha_u, alpha_v) in [(0.3, 0.3), (0.05, 0.4), (1.0, 1.0)] {
                for sample_visible in [false, true] {
                    let d = Microfacet {
                        kind,
                        alpha_u,
                        alpha_v,
                        sample_visible,
                    };
                    for _ in 0..20_000 {
                        let (wo, wi) = (dir(), dir());
                        let m = (wo + wi).normalize_or_zero();
                        let shared = d.pdf_with(wo, m, d.d(m), d.g1(wo, m));
                        assert_eq!(shared.to_bits(), d.pdf(wo, m).to_bits(), "{d:?} {wo} {m}");
                    }
                }
            }
        }
    }
}
