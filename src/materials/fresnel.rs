//! Fresnel equations, as in Mitsuba 3's `fresnel.h`.

use glam::Vec3;

/// Dielectric Fresnel reflectance for unpolarised light.
///
/// `cos_theta_i` is the cosine of the incident direction with the normal (negative on
/// the inside), `eta` the relative IOR int/ext. Returns `(r, cos_theta_t, eta_it,
/// eta_ti)`: reflectance, the (signed) cosine of the transmitted direction, and the
/// relative IOR across the interface in both directions.
pub fn fresnel_dielectric(cos_theta_i: f32, eta: f32) -> (f32, f32, f32, f32) {
    let outside = cos_theta_i >= 0.0;
    let (eta_it, eta_ti) = if outside {
        (eta, 1.0 / eta)
    } else {
        (1.0 / eta, eta)
    };
    let cos_theta_t_sqr = 1.0 - eta_ti * eta_ti * (1.0 - cos_theta_i * cos_theta_i);
    let cos_i = cos_theta_i.abs();
    let cos_t = cos_theta_t_sqr.max(0.0).sqrt();
    let r = if eta == 1.0 {
        0.0
    } else if cos_i == 0.0 {
        1.0
    } else {
        let a_s = (eta_it * cos_t - cos_i) / (eta_it * cos_t + cos_i);
        let a_p = (eta_it * cos_i - cos_t) / (eta_it * cos_i + cos_t);
        0.5 * (a_s * a_s + a_p * a_p)
    };
    // The transmitted direction lies on the other side of the interface.
    let cos_theta_t = if cos_theta_i >= 0.0 { -cos_t } else { cos_t };
    (r, cos_theta_t, eta_it, eta_ti)
}

/// Conductor Fresnel reflectance per channel for complex IOR `eta + i k`
/// (exact for unpolarised light; Mitsuba's `fresnel_conductor`).
pub fn fresnel_conductor(cos_theta_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
    let one = |e: f32, k: f32| -> f32 {
        let c2 = cos_theta_i * cos_theta_i;
        let s2 = 1.0 - c2;
        let s4 = s2 * s2;
        let temp1 = e * e - k * k - s2;
        let a2pb2 = (temp1 * temp1 + 4.0 * k * k * e * e).max(0.0).sqrt();
        let a = (0.5 * (a2pb2 + temp1)).max(0.0).sqrt();
        let term1 = a2pb2 + c2;
        let term2 = 2.0 * cos_theta_i * a;
        let r_s = (term1 - term2) / (term1 + term2);
        let term3 = a2pb2 * c2 + s4;
        let term4 = term2 * s2;
        let r_p = r_s * (term3 - term4) / (term3 + term4);
        0.5 * (r_s + r_p)
    };
    Vec3::new(one(eta.x, k.x), one(eta.y, k.y), one(eta.z, k.z))
}

/// The diffuse Fresnel reflectance: Fresnel's reflectance averaged over the
/// cosine-weighted hemisphere for relative IOR `eta`, by the fits Mitsuba 3 uses
/// (`fresnel_diffuse_reflectance`): Egan and Hilgeman (1973) for eta < 1, d'Eon and
/// Irving (2011) above (0.1-0.2 % relative error).
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let inv = 1.0 / eta;
    if eta < 1.0 {
        0.0636 * inv + (eta * (eta * -1.4399 + 0.7099) + 0.6681)
    } else {
        let c = [0.919317f32, -3.4793, 6.75335, -7.80989, 4.98554, -1.36881];
        c.iter().rev().fold(0.0, |acc, &k| acc * inv + k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_normal_incidence_and_tir() {
        // R0 = ((n-1)/(n+1))^2 = 0.04 for n = 1.5, from both sides.
        let (r, ct, eta_it, eta_ti) = fresnel_dielectric(1.0, 1.5);
        assert!((r - 0.04).abs() < 1e-6);
        assert!((ct + 1.0).abs() < 1e-6);
        assert_eq!((eta_it, eta_ti), (1.5, 1.0 / 1.5));
        let (r, ct, ..) = fresnel_dielectric(-1.0, 1.5);
        assert!((r - 0.04).abs() < 1e-6);
        assert!((ct - 1.0).abs() < 1e-6);
        // Beyond the critical angle (sin > 1/1.5) from inside: total internal reflection.
        let (r, ..) = fresnel_dielectric(-0.5, 1.5);
        assert_eq!(r, 1.0);
        // Index matched: no reflection.
        assert_eq!(fresnel_dielectric(0.3, 1.0).0, 0.0);
    }

    #[test]
    fn dielectric_matches_textbook_at_45_degrees() {
        // n = 1.5, theta_i = 45 deg: Rs = 0.0920, Rp = 0.0085 (Hecht); R = 0.0503.
        let c = std::f32::consts::FRAC_1_SQRT_2;
        let (r, ..) = fresnel_dielectric(c, 1.5);
        assert!((r - 0.05028).abs() < 2e-4, "{r}");
    }

    #[test]
    fn conductor_limits() {
        // k = 0 reduces to the dielectric formula at normal incidence.
        let r = fresnel_conductor(1.0, Vec3::splat(1.5), Vec3::ZERO);
        assert!((r - Vec3::splat(0.04)).abs().max_element() < 1e-6);
        // eta = 0, k = 1 is a perfect mirror at every angle (Mitsuba's material "none").
        for c in [1.0, 0.7, 0.2] {
            let r = fresnel_conductor(c, Vec3::ZERO, Vec3::ONE);
            assert!((r - Vec3::ONE).abs().max_element() < 1e-6, "{r}");
        }
        // Normal incidence closed form ((n-1)^2 + k^2) / ((n+1)^2 + k^2).
        let (n, k) = (0.143119f32, 3.98316f32);
        let want = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
        let r = fresnel_conductor(1.0, Vec3::splat(n), Vec3::splat(k));
        assert!((r.x - want).abs() < 1e-5);
    }
}
