//! Warps from the unit square to directions and points, with their densities.

use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, PI};

/// Cosine-weighted direction on the +z hemisphere (Malley's method); pdf = cos / pi.
#[inline]
pub fn cosine_hemisphere(u: [f32; 2]) -> Vec3 {
    let [x, y] = concentric_disk(u);
    let z = (1.0 - x * x - y * y).max(0.0).sqrt();
    Vec3::new(x, y, z)
}

#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Shirley-Chiu concentric map of the unit square to the unit disk.
#[inline]
pub fn concentric_disk(u: [f32; 2]) -> [f32; 2] {
    let a = 2.0 * u[0] - 1.0;
    let b = 2.0 * u[1] - 1.0;
    if a == 0.0 && b == 0.0 {
        return [0.0, 0.0];
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, (PI / 4.0) * (b / a))
    } else {
        (b, (PI / 2.0) - (PI / 4.0) * (a / b))
    };
    [r * phi.cos(), r * phi.sin()]
}

/// Uniform barycentrics (b1, b2) on a triangle (Heitz 2019's low-distortion map is not
/// needed here: the square-root map is exact and simple).
#[inline]
pub fn uniform_triangle(u: [f32; 2]) -> [f32; 2] {
    let su = u[0].sqrt();
    [1.0 - su, u[1] * su]
}

/// Uniform direction on the unit sphere; pdf = 1 / (4 pi).
#[inline]
pub fn uniform_sphere(u: [f32; 2]) -> Vec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Power heuristic with beta = 2 (Veach 1997).
#[inline]
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a + b > 0.0 {
        a / (a + b)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::Pcg32;

    #[test]
    fn cosine_hemisphere_has_cosine_moments() {
        // E[cos] under pdf cos/pi is 2/3; E[cos^2] is 1/2.
        let mut rng = Pcg32::new(3, 5);
        let n = 200_000;
        let (mut m1, mut m2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let d = cosine_hemisphere(rng.next_2d());
            assert!(d.z >= 0.0 && (d.length() - 1.0).abs() < 1e-4);
            m1 += d.z as f64;
            m2 += (d.z * d.z) as f64;
        }
        m1 /= n as f64;
        m2 /= n as f64;
        let se1 = (0.5 - 4.0 / 9.0f64).sqrt() / (n as f64).sqrt();
        assert!((m1 - 2.0 / 3.0).abs() < 5.0 * se1, "{m1}");
        assert!((m2 - 0.5).abs() < 0.005, "{m2}");
    }

    #[test]
    fn triangle_barycentrics_are_uniform() {
        let mut rng = Pcg32::new(9, 1);
        let n = 100_000;
        let mut mean = [0.0f64; 2];
        for _ in 0..n {
            let [b1, b2] = uniform_triangle(rng.next_2d());
            assert!(b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0 + 1e-6);
            mean[0] += b1 as f64;
            mean[1] += b2 as f64;
        }
        // The centroid has barycentrics (1/3, 1/3); sd of each is sqrt(1/18).
        for m in mean {
            let m = m / n as f64;
            assert!((m - 1.0 / 3.0).abs() < 5.0 * (1.0 / 18.0f64 / n as f64).sqrt());
        }
    }

    #[test]
    fn power_heuristic_is_a_partition_of_unity() {
        let (a, b) = (0.3, 1.7);
        assert!((power_heuristic(a, b) + power_heuristic(b, a) - 1.0).abs() < 1e-6);
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
    }
}
