//! `plastic` (its pdf's mass = its diffuse share), `roughplastic` (weights, furnace,
//! reciprocity, energy against quadrature) and `pplastic`'s models.

use crate::harness::{
    asymmetry, cell_integrals, diffuse, dir, furnace, reflected_energy, two_sided, weight_mismatch,
    Case, PDF_INTEGRAL_TOL,
};
use tstat::materials::{
    BsdfFlags, BsdfModel, Microfacet, MicrofacetKind, OneSided, PPlastic, Plastic, RoughPlastic,
};
use tstat::math::rng::Pcg32;
use tstat::math::Rgb;

pub(crate) fn rough_plastic(
    kind: MicrofacetKind,
    alpha: f32,
    eta: f32,
    d: Rgb,
    nonlinear: bool,
    sample_visible: bool,
) -> RoughPlastic {
    let distribution = Microfacet {
        kind,
        alpha_u: alpha,
        alpha_v: alpha,
        sample_visible,
    };
    RoughPlastic::new(distribution, eta, d, Rgb::ONE, nonlinear)
}

/// Rough plastics across distributions, roughness 0.1 and 0.4, eta 1.49 and 1.9, bright
/// and dark bases, each with the polar angle of a `wo` (grazing ones included) for the
/// chi-square test.
pub(crate) fn rough_plastic_models() -> Vec<(&'static str, RoughPlastic, f64)> {
    use MicrofacetKind::{Beckmann, Ggx};
    let bright = Rgb::new(0.8, 0.6, 0.4);
    let dark = Rgb::new(0.05, 0.1, 0.02);
    vec![
        (
            "beckmann 0.1, eta 1.49, bright",
            rough_plastic(Beckmann, 0.1, 1.49, bright, false, true),
            30.0,
        ),
        (
            "beckmann 0.4, eta 1.9, dark",
            rough_plastic(Beckmann, 0.4, 1.9, dark, false, true),
            60.0,
        ),
        (
            "ggx 0.1, eta 1.9, bright",
            rough_plastic(Ggx, 0.1, 1.9, bright, false, true),
            85.0,
        ),
        (
            "ggx 0.4, eta 1.49, dark",
            rough_plastic(Ggx, 0.4, 1.49, dark, false, true),
            10.0,
        ),
        (
            "ggx 0.1, eta 1.49, dark, nonlinear",
            rough_plastic(Ggx, 0.1, 1.49, dark, true, true),
            75.0,
        ),
        (
            "beckmann 0.1, eta 1.9, bright, nonlinear",
            rough_plastic(Beckmann, 0.1, 1.9, bright, true, true),
            88.0,
        ),
        (
            "ggx 0.4, eta 1.9, bright, all normals",
            rough_plastic(Ggx, 0.4, 1.9, bright, false, false),
            45.0,
        ),
        (
            "beckmann 0.4, eta 1.49, white",
            rough_plastic(Beckmann, 0.4, 1.49, Rgb::ONE, false, true),
            0.0,
        ),
    ]
}

/// The rough plastics, and one inside `twosided` seen from the back.
pub(crate) fn rough_plastic_cases() -> Vec<Case> {
    let mut cases: Vec<Case> = rough_plastic_models()
        .into_iter()
        .map(|(n, b, theta)| {
            let model: Box<dyn BsdfModel> = Box::new(b);
            (
                format!("roughplastic {n}, {theta} deg"),
                model,
                dir(theta, 40.0),
            )
        })
        .collect();
    let back = rough_plastic(
        MicrofacetKind::Ggx,
        0.2,
        1.6,
        Rgb::new(0.3, 0.5, 0.7),
        false,
        true,
    );
    cases.push((
        "twosided diffuse/roughplastic, back".into(),
        Box::new(two_sided(
            OneSided::Diffuse(diffuse(0.5)),
            OneSided::RoughPlastic(back),
        )),
        dir(130.0, 250.0),
    ));
    cases
}

fn pplastic(
    kind: MicrofacetKind,
    alpha_u: f32,
    alpha_v: f32,
    eta: f32,
    d: Rgb,
    s: Rgb,
) -> PPlastic {
    let (dm, sm) = (d.element_sum() / 3.0, s.element_sum() / 3.0);
    PPlastic {
        distribution: Microfacet {
            kind,
            alpha_u,
            alpha_v,
            sample_visible: true,
        },
        eta,
        diffuse_reflectance: d,
        specular_reflectance: s,
        specular_weight: sm / (dm + sm),
    }
}

/// `pplastic` across distributions and roughness, one anisotropic, one with a dark
/// specular scale, each with the polar angle of a `wo`.
pub(crate) fn pplastic_models() -> Vec<(&'static str, PPlastic, f64)> {
    use MicrofacetKind::{Beckmann, Ggx};
    vec![
        (
            "ggx 0.06, eta 1.49",
            pplastic(Ggx, 0.06, 0.06, 1.49, Rgb::new(0.05, 0.03, 0.1), Rgb::ONE),
            30.0,
        ),
        (
            "beckmann 0.3, eta 1.9",
            pplastic(Beckmann, 0.3, 0.3, 1.9, Rgb::new(0.8, 0.6, 0.4), Rgb::ONE),
            70.0,
        ),
        (
            "ggx 0.1 x 0.4, eta 1.3",
            pplastic(Ggx, 0.1, 0.4, 1.3, Rgb::new(0.3, 0.5, 0.2), Rgb::splat(0.5)),
            50.0,
        ),
        (
            "ggx 0.2, no specular",
            pplastic(Ggx, 0.2, 0.2, 1.49, Rgb::new(0.5, 0.5, 0.9), Rgb::ZERO),
            10.0,
        ),
    ]
}

/// `plastic` mixes a delta and a diffuse lobe: its pdf (the diffuse lobe's) integrates
/// to the fraction of samples that take the diffuse lobe, and those samples carry
/// weight eval / pdf (checked with every model above).
#[test]
fn plastic_pdf_integrates_to_its_diffuse_share() {
    let b = Plastic::new(1.49, Rgb::new(0.8, 0.3, 0.1), Rgb::ONE, false);
    for (i, theta) in [10.0, 60.0, 85.0].into_iter().enumerate() {
        let wo = dir(theta, 15.0);
        let total: f64 = cell_integrals(&b, wo).iter().sum();
        let n = 200_000;
        let mut rng = Pcg32::new(90, i as u64);
        let diffuse = (0..n)
            .filter(|_| {
                b.sample(wo, rng.next_f32(), rng.next_2d())
                    .is_some_and(|s| s.lobe == BsdfFlags::DIFFUSE_REFLECTION)
            })
            .count();
        let f = diffuse as f64 / n as f64;
        let tol = PDF_INTEGRAL_TOL + 5.0 * (f * (1.0 - f) / n as f64).sqrt();
        assert!((total - f).abs() < tol, "{theta} deg: {total} vs {f}");
        assert!(
            f > 0.05 && f < 0.999,
            "{theta} deg: both lobes are sampled ({f})"
        );
    }
}

/// The rough plastics, with more parameters than the chi-square cases (eta < 1 and
/// coloured specular reflectance).
fn rough_plastic_all() -> Vec<(String, RoughPlastic)> {
    let mut models: Vec<(String, RoughPlastic)> = rough_plastic_models()
        .into_iter()
        .map(|(n, b, _)| (n.to_string(), b))
        .collect();
    let distribution = Microfacet {
        kind: MicrofacetKind::Ggx,
        alpha_u: 0.3,
        alpha_v: 0.3,
        sample_visible: true,
    };
    models.push((
        "ggx 0.3, eta 0.8, tinted specular".into(),
        RoughPlastic::new(
            distribution,
            0.8,
            Rgb::new(0.2, 0.9, 0.5),
            Rgb::new(0.5, 0.5, 1.0),
            true,
        ),
    ));
    models.push((
        "beckmann 0.2, eta 1.6, black base".into(),
        RoughPlastic::new(
            Microfacet {
                kind: MicrofacetKind::Beckmann,
                alpha_u: 0.2,
                alpha_v: 0.2,
                ..distribution
            },
            1.6,
            Rgb::ZERO,
            Rgb::ONE,
            false,
        ),
    ));
    models
}

/// Weights, furnace and reciprocity of the rough plastics. The furnace compares the
/// mean sample weight with `albedo(wo)` within 5 standard errors plus 2e-3, the
/// accuracy of its tabulated specular energy (linear interpolation near grazing).
/// The model is reciprocal: both transmittance factors of its diffuse term come from
/// the same table, and the specular term is symmetric (f32 rounding only).
#[test]
fn rough_plastic_weights_furnace_and_reciprocity() {
    let mut rng = Pcg32::new(17, 3);
    let mut worst_furnace = 0.0f32;
    for (i, (name, b)) in rough_plastic_all().iter().enumerate() {
        for j in 0..32 {
            let mut wo = tstat::math::sampling::uniform_sphere(rng.next_2d());
            wo.z = wo.z.abs();
            let m = weight_mismatch(b, wo, 256, 600 + j);
            assert!(m < 1e-4, "{name} from {wo}: relative mismatch {m}");
            let (mean, se) = furnace(b, wo, 4096, 700 + j);
            let albedo = b.albedo(wo);
            for c in 0..3 {
                let dev = (mean[c] - albedo[c]).abs();
                assert!(
                    dev <= 5.0 * se[c] + 2e-3,
                    "{name} from {wo}: mean {mean} +- {se}, albedo {albedo}"
                );
                worst_furnace = worst_furnace.max(dev / (se[c] + 1e-6));
            }
            assert!(albedo.max_element() <= 1.0, "{name}: albedo {albedo}");
        }
        let a = asymmetry(b, 800 + i as u64);
        assert!(
            a < 1e-4,
            "{name}: eval(wo, wi) != eval(wi, wo), relative {a}"
        );
        // Seen from the back: black, no samples.
        let back = dir(120.0, 0.0);
        assert!(b.sample(back, 0.5, [0.5; 2]).is_none());
        assert_eq!(b.albedo(back), Rgb::ZERO);
    }
    eprintln!("roughplastic furnace: largest |mean - albedo| = {worst_furnace:.2} standard errors");
}

/// Energy: the mean sample weight equals the reflected energy integrated from `eval`
/// (independently of the sampler and of the pdf) and `albedo(wo)`, and a white base
/// under a coating of eta > 1 reflects at most what arrives. A coating that forgets the
/// eta^-2 of the light leaving it (the same model as a base d eta^2, without
/// `nonlinear`) creates energy and is rejected.
#[test]
fn rough_plastic_conserves_energy() {
    let mut models = rough_plastic_all();
    for (kind, alpha, eta) in [
        (MicrofacetKind::Beckmann, 0.1, 1.49),
        (MicrofacetKind::Ggx, 0.1, 1.9),
        (MicrofacetKind::Ggx, 0.4, 1.2),
    ] {
        models.push((
            format!("white {kind:?} {alpha}, eta {eta}"),
            rough_plastic(kind, alpha, eta, Rgb::ONE, false, true),
        ));
    }
    let mut report = Vec::new();
    for (i, (name, b)) in models.iter().enumerate() {
        for theta in [0.0, 45.0, 80.0] {
            let wo = dir(theta, 20.0 + 30.0 * i as f64);
            let quad = reflected_energy(b, wo);
            let (mean, se) = furnace(b, wo, 20_000, 900 + i as u64);
            let albedo = b.albedo(wo);
            for c in 0..3 {
                let (q, m, e, a) = (quad[c], mean[c] as f64, se[c] as f64, albedo[c] as f64);
                assert!(
                    (q - m).abs() <= 5.0 * e + 2e-3 * q,
                    "{name} at {theta} deg: quadrature {q}, sampled {m} +- {e}"
                );
                assert!(
                    (q - a).abs() <= 2e-3,
                    "{name} at {theta} deg: quadrature {q}, albedo {a}"
                );
                assert!(q <= 1.0 + 1e-3, "{name} at {theta} deg: reflects {q}");
            }
            if name.starts_with("white") {
                report.push(format!("{name} at {theta} deg: {:.4}", quad[0]));
            }
        }
    }
    eprintln!("white rough plastics reflect: {}", report.join("; "));
    let eta: f32 = 1.49;
    let forgot = rough_plastic(
        MicrofacetKind::Beckmann,
        0.1,
        eta,
        Rgb::splat(eta * eta),
        false,
        true,
    );
    let q = reflected_energy(&forgot, dir(20.0, 0.0));
    assert!(q.min_element() > 1.1, "no eta^-2 passed: reflects {q}");
}
