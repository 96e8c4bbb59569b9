//! A BSDF's colour parameters mapped one by one (`Bsdf::map_colours`): the spectral
//! render mode turns each RGB parameter into its spectrum's values at a path's
//! wavelengths (`spectral::lift`) at every hit, and the models then compute with
//! those values exactly as they compute with RGB. Which parameters are reflectance-like
//! (bounded to [0, 1]) and which are optical constants (`eta`, `k`: unbounded) is
//! said here, once, for every model.

use super::{Bsdf, OneSided};
use crate::math::Rgb;

/// How a colour parameter becomes a spectrum (Mitsuba 3's `get_texture` and
/// `get_unbounded_texture`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourKind {
    /// Reflectances and transmittances: values in [0, 1].
    Bounded,
    /// A conductor's `eta` and `k`: any non-negative value.
    Unbounded,
}

impl Bsdf {
    /// Why the spectral mode cannot render this BSDF, if it cannot: the principled
    /// models tint by the luminance of their base colour, which a path that carries
    /// wavelengths does not have.
    pub fn spectral_support(&self) -> Result<(), &'static str> {
        match self {
            Bsdf::Principled(_) => Err("principled"),
            Bsdf::PrincipledThin(_) => Err("principledthin"),
            Bsdf::TwoSided(_) => Ok(()),
            Bsdf::Mask(m) => m.nested.spectral_support(),
            Bsdf::Separable(s) => s.inner.spectral_support(),
            Bsdf::Perturbed(p) => p.nested.spectral_support(),
            Bsdf::Composed(c) => c.first.spectral_support().and(c.second.spectral_support()),
            Bsdf::Blend(b) => b.first.spectral_support().and(b.second.spectral_support()),
            _ => Ok(()),
        }
    }

    /// The same BSDF with every colour parameter `c` of kind `k` replaced by `f(k, c)`
    /// (through `twosided`, `mask`, delays, mixtures and perturbed frames). Scalar
    /// parameters (roughness, IORs of dielectrics, weights) are kept. Models that
    /// [`Self::spectral_support`] refuses are returned unchanged.
    pub fn map_colours(&self, f: &impl Fn(ColourKind, Rgb) -> Rgb) -> Bsdf {
        use ColourKind::{Bounded, Unbounded};
        let mut b = self.clone();
        match &mut b {
            Bsdf::Diffuse(d) => d.reflectance = f(Bounded, d.reflectance),
            Bsdf::Dielectric(d) => {
                d.specular_reflectance = f(Bounded, d.specular_reflectance);
                d.specular_transmittance = f(Bounded, d.specular_transmittance);
            }
            Bsdf::ThinDielectric(d) => {
                d.specular_reflectance = f(Bounded, d.specular_reflectance);
                d.specular_transmittance = f(Bounded, d.specular_transmittance);
            }
            Bsdf::RoughDielectric(d) => {
                d.specular_reflectance = f(Bounded, d.specular_reflectance);
                d.specular_transmittance = f(Bounded, d.specular_transmittance);
            }
            Bsdf::Conductor(c) => {
                c.eta = f(Unbounded, c.eta);
                c.k = f(Unbounded, c.k);
                c.specular_reflectance = f(Bounded, c.specular_reflectance);
            }
            Bsdf::RoughConductor(c) => {
                c.eta = f(Unbounded, c.eta);
                c.k = f(Unbounded, c.k);
                c.specular_reflectance = f(Bounded, c.specular_reflectance);
            }
            Bsdf::Plastic(p) => {
                let (d, s) = p.reflectances();
                *p = p
                    .with_diffuse_reflectance(f(Bounded, d))
                    .with_specular_reflectance(f(Bounded, s));
            }
            Bsdf::RoughPlastic(p) => {
                let (d, s) = p.reflectances();
                *p = p
                    .with_diffuse_reflectance(f(Bounded, d))
                    .with_specular_reflectance(f(Bounded, s));
            }
            Bsdf::PPlastic(p) => {
                p.diffuse_reflectance = f(Bounded, p.diffuse_reflectance);
                p.specular_reflectance = f(Bounded, p.specular_reflectance);
            }
            Bsdf::Polarizer(p) => p.transmittance = f(Bounded, p.transmittance),
            Bsdf::Retarder(r) => r.transmittance = f(Bounded, r.transmittance),
            Bsdf::Circular(c) => c.transmittance = f(Bounded, c.transmittance),
            Bsdf::TwoSided(t) => {
                t.front = one_sided(&t.front, f);
                t.back = one_sided(&t.back, f);
            }
            Bsdf::Mask(m) => *m.nested = m.nested.map_colours(f),
            Bsdf::Separable(s) => *s.inner = s.inner.map_colours(f),
            Bsdf::Perturbed(p) => *p.nested = p.nested.map_colours(f),
            Bsdf::Composed(c) => {
                *c.first = c.first.map_colours(f);
                *c.second = c.second.map_colours(f);
            }
            Bsdf::Blend(c) => {
                *c.first = c.first.map_colours(f);
                *c.second = c.second.map_colours(f);
            }
            Bsdf::Null(_) | Bsdf::Principled(_) | Bsdf::PrincipledThin(_) => {}
        }
        b
    }
}

fn one_sided(o: &OneSided, f: &impl Fn(ColourKind, Rgb) -> Rgb) -> OneSided {
    let mapped = Bsdf::from(o.clone()).map_colours(f);
    OneSided::try_from(mapped).unwrap_or_else(|_| o.clone())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials::{Conductor, Diffuse, Mask, Plastic};
    use glam::Vec3;

    /// Every colour is visited with its kind: a map that tags bounded colours with
    /// 0.25 and unbounded ones with 7 leaves no colour untouched.
    #[test]
    fn every_colour_is_mapped_with_its_kind() {
        let tag = |k: ColourKind, _c: Rgb| match k {
            ColourKind::Bounded => Vec3::splat(0.25),
            ColourKind::Unbounded => Vec3::splat(7.0),
        };
        let conductor = Bsdf::Conductor(Conductor {
            eta: Vec3::new(0.2, 0.9, 1.1),
            k: Vec3::new(3.0, 2.0, 1.0),
            specular_reflectance: Vec3::ONE,
        });
        let Bsdf::Conductor(c) = conductor.map_colours(&tag) else {
            panic!()
        };
        assert_eq!((c.eta, c.k), (Vec3::splat(7.0), Vec3::splat(7.0)));
        assert_eq!(c.specular_reflectance, Vec3::splat(0.25));

        let masked = Bsdf::Mask(Mask {
            opacity: 0.5,
            nested: Box::new(Bsdf::Diffuse(Diffuse {
                reflectance: Vec3::new(0.1, 0.2, 0.3),
            })),
        });
        let Bsdf::Mask(m) = masked.map_colours(&tag) else {
            panic!()
        };
        assert_eq!(m.opacity, 0.5);
        assert_eq!(
            *m.nested,
            Bsdf::Diffuse(Diffuse {
                reflectance: Vec3::splat(0.25)
            })
        );

        let plastic = Bsdf::Plastic(Plastic::new(
            1.5,
            Vec3::new(0.5, 0.1, 0.1),
            Vec3::ONE,
            false,
        ));
        let Bsdf::Plastic(p) = plastic.map_colours(&tag) else {
            panic!()
        };
        assert_eq!(p.reflectances(), (Vec3::splat(0.25), Vec3::splat(0.25)));
        // The derived quantities follow: the same as a plastic built with the colours.
        assert_eq!(
            p,
            Plastic::new(1.5, Vec3::splat(0.25), Vec3::splat(0.25), false)
        );
    }

    #[test]
    fn the_identity_map_changes_nothing() {
        let plastic = Bsdf::Plastic(Plastic::new(1.5, Vec3::new(0.5, 0.1, 0.1), Vec3::ONE, true));
        assert_eq!(plastic.map_colours(&|_, c| c), plastic);
    }
}
