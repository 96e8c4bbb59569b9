//! Delta models: smooth dielectrics and conductors (exact directions, the Fresnel
//! choice by a binomial test), `thindielectric`, `polarizer`; and `mask`'s cases.

use crate::harness::{
    binomial_p_value, close, delta_p_value, diffuse, dir, glass, gold, mirror, reference_fresnel,
    two_sided, Case,
};
use crate::rough::rough;
use crate::LEVEL;
use glam::Vec3;
use tstat::materials::{
    Bsdf, BsdfFlags, BsdfModel, Mask, MicrofacetKind, OneSided, Polarizer, ThinDielectric,
};
use tstat::math::rng::Pcg32;
use tstat::math::Rgb;

/// A delta case and, for a dielectric, its relative IOR (a conductor always reflects).
type DeltaCase = (String, Box<dyn BsdfModel>, Vec3, Option<f64>);

/// Delta-only models and a `wo`.
pub(crate) fn delta_cases() -> Vec<DeltaCase> {
    let mut cases: Vec<DeltaCase> = Vec::new();
    for (name, eta) in [
        ("glass 1.5", 1.5f32),
        ("water 1.333", 1.333),
        ("diamond 2.419", 2.419),
        ("eta 0.7 (< 1)", 0.7),
    ] {
        for theta in [0.0, 40.0, 75.0, 150.0, 125.0] {
            // 150 and 125 deg: from inside; 125 deg is past the critical angle for
            // eta >= 1.333 (total internal reflection), not for eta 0.7.
            cases.push((
                format!("{name}, {theta} deg"),
                Box::new(glass(eta)),
                dir(theta, 77.0),
                Some(eta as f64),
            ));
        }
    }
    cases.push(("gold".into(), Box::new(gold()), dir(60.0, 10.0), None));
    cases.push(("mirror".into(), Box::new(mirror()), dir(20.0, 100.0), None));
    cases.push((
        "twosided gold, back".into(),
        Box::new(two_sided(
            OneSided::Diffuse(diffuse(0.5)),
            OneSided::Conductor(gold()),
        )),
        dir(110.0, 45.0),
        None,
    ));
    cases
}

#[test]
fn delta_lobes_are_exact_and_chosen_with_fresnel_probability() {
    let mut ps = Vec::new();
    for (i, (name, b, wo, eta)) in delta_cases().into_iter().enumerate() {
        assert!(b.flags(wo).is_delta(), "{name}");
        assert_eq!(b.eval(wo, -wo), Rgb::ZERO, "{name}");
        assert_eq!(b.pdf(wo, Vec3::new(-wo.x, -wo.y, wo.z)), 0.0, "{name}");
        let p = delta_p_value(b.as_ref(), wo, eta, 2000 + i as u64);
        assert!(p > LEVEL, "{name}: binomial p = {p:.3e} <= {LEVEL:.1e}");
        ps.push(p);
    }
    let (lo, hi) = ps
        .iter()
        .fold((1.0f64, 0.0f64), |(a, b), &p| (a.min(p), b.max(p)));
    eprintln!(
        "binomial p-values of {} delta cases in [{lo:.3}, {hi:.3}]",
        ps.len()
    );
}

/// Thin dielectric cases (eta, theta of wo in degrees), each a binomial test.
pub(crate) const THIN_CASES: [(f32, f64); 4] =
    [(1.5, 0.0), (1.5, 70.0), (1.333, 130.0), (2.419, 85.0)];

/// `thindielectric`: reflection exact, transmission straight through (-wo) with the
/// current IOR unchanged, the reflect/transmit choice with the slab reflectance
/// R' = R + T^2 R / (1 - R^2) computed here in f64 from Snell's law, and a clear pane
/// lossless.
#[test]
fn thin_dielectric_reflects_the_slab_series_and_passes_straight_through() {
    for (i, &(eta, theta)) in THIN_CASES.iter().enumerate() {
        let b = ThinDielectric {
            eta,
            specular_reflectance: Rgb::ONE,
            specular_transmittance: Rgb::ONE,
        };
        let wo = dir(theta, 33.0);
        // One interface from outside, at the pane's angle.
        let (r, _) = reference_fresnel(Vec3::new(wo.x, wo.y, wo.z.abs()), eta as f64);
        let t = 1.0 - r;
        let r_slab = r + t * t * r / (1.0 - r * r);
        const N: u64 = 20_000;
        let mut rng = Pcg32::new(40 + i as u64, 0x7417);
        let mut n_reflect = 0;
        for _ in 0..N {
            let s = b.sample(wo, rng.next_f32(), rng.next_2d()).unwrap();
            assert_eq!(s.eta, 1.0);
            assert_eq!(s.weight, Rgb::ONE);
            if s.lobe == BsdfFlags::DELTA_REFLECTION {
                assert!(close(s.wi, [-wo.x as f64, -wo.y as f64, wo.z as f64], 1e-6));
                n_reflect += 1;
            } else {
                assert_eq!(s.lobe, BsdfFlags::DELTA_TRANSMISSION);
                assert_eq!(s.wi, -wo);
            }
        }
        let p = binomial_p_value(n_reflect, N, r_slab);
        assert!(
            p > LEVEL,
            "eta {eta} at {theta} deg: p = {p:.3e}, R' = {r_slab}"
        );
        assert!((b.albedo(wo) - Rgb::ONE).abs().max_element() < 1e-6);
    }
    // The series matters: a pane reflecting only one interface's R is rejected.
    let wo = dir(70.0, 0.0);
    let (r, _) = reference_fresnel(wo, 1.5);
    let b = ThinDielectric {
        eta: 1.5,
        specular_reflectance: Rgb::ONE,
        specular_transmittance: Rgb::ONE,
    };
    let mut rng = Pcg32::new(1, 2);
    let k = (0..20_000)
        .filter(|_| {
            b.sample(wo, rng.next_f32(), rng.next_2d()).unwrap().lobe == BsdfFlags::DELTA_REFLECTION
        })
        .count() as u64;
    assert!(
        binomial_p_value(k, 20_000, r) < LEVEL,
        "R' indistinguishable from R"
    );
}

/// `mask` over a few models: the nested lobes scaled by the opacity, plus a
/// straight-through delta lobe that the chi-square test leaves out.
pub(crate) fn mask(opacity: f32, nested: Bsdf) -> Mask {
    Mask {
        opacity,
        nested: Box::new(nested),
    }
}

pub(crate) fn mask_cases() -> Vec<Case> {
    let d = |r| OneSided::Diffuse(diffuse(r));
    vec![
        (
            "mask 0.3 over diffuse, 40 deg".into(),
            Box::new(mask(0.3, Bsdf::Diffuse(diffuse(0.8)))),
            dir(40.0, 70.0),
        ),
        (
            "mask 0.7 over twosided diffuse, back".into(),
            Box::new(mask(0.7, two_sided(d(0.8), d(0.2)))),
            dir(130.0, 250.0),
        ),
        (
            "mask 0.5 over roughconductor ggx 0.3, 55 deg".into(),
            Box::new(mask(
                0.5,
                Bsdf::RoughConductor(rough(MicrofacetKind::Ggx, 0.3, 0.3, true)),
            )),
            dir(55.0, 20.0),
        ),
    ]
}

/// `polarizer` without polarization: straight through, half the transmittance, nothing
/// to evaluate.
#[test]
fn polarizer_passes_half_the_transmittance_straight_through() {
    // The angle and `polarizing` change nothing here.
    let p = Polarizer {
        transmittance: Rgb::new(1.0, 0.8, 0.2),
        theta: 30.0,
        polarizing: false,
    };
    for wo in [dir(0.0, 0.0), dir(70.0, 30.0), dir(150.0, 200.0)] {
        let s = p.sample(wo, 0.4, [0.2, 0.9]).unwrap();
        assert_eq!(
            (s.wi, s.eta, s.lobe),
            (-wo, 1.0, BsdfFlags::DELTA_TRANSMISSION)
        );
        assert_eq!(s.weight, Rgb::new(0.5, 0.4, 0.1));
        assert!(p.flags(wo).is_delta());
        assert_eq!((p.eval(wo, -wo), p.pdf(wo, -wo)), (Rgb::ZERO, 0.0));
    }
}
