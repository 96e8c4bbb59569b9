//! The polarization calculus (src/polarization/) against closed forms: Malus's law,
//! rotators and frames, retarders turning linear into circular light, and the Fresnel
//! equations for s and p light (dielectric, conductor, total internal reflection)
//! against the textbook formulas and tstat's unpolarized Fresnel.

use glam::{Vec3, Vec4};
use num_complex::Complex64 as C64;
use tstat::materials::fresnel::{fresnel_conductor, fresnel_dielectric};
use tstat::polarization::elements::{
    circular_polarizer, depolarizer, linear_polarizer, linear_retarder, rotated_element, rotator,
};
use tstat::polarization::frames::{
    rotate_mueller_basis_collinear, rotate_stokes_basis, stokes_basis,
};
use tstat::polarization::fresnel::{amplitudes, specular_reflection, specular_transmission};
use tstat::polarization::{aolp, dolp, dop, unpolarized};

fn close(a: Vec4, b: Vec4, tol: f32) -> bool {
    (a - b).abs().max_element() <= tol
}

#[test]
fn malus_law_through_two_polarizers() {
    for deg in [0.0f32, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0] {
        let theta = deg.to_radians();
        let first = linear_polarizer(1.0) * unpolarized(1.0);
        assert!(close(first, Vec4::new(0.5, 0.5, 0.0, 0.0), 1e-7));
        let out = rotated_element(theta, linear_polarizer(1.0)) * first;
        let want = 0.5 * theta.cos().powi(2);
        assert!(
            (out.x - want).abs() < 1e-6,
            "{deg} deg: {} vs {want}",
            out.x
        );
        // What passes is polarized along the second polarizer's axis.
        if out.x > 1e-6 {
            assert!((dolp(out) - 1.0).abs() < 1e-5);
            assert!((aolp(out) - theta).abs() < 1e-4 || deg == 90.0);
        }
    }
    // The rotated polarizer in closed form (Collett ch. 5).
    let t = 0.4f32;
    let (s, c) = (2.0 * t).sin_cos();
    let m = rotated_element(t, linear_polarizer(1.0));
    let want = 0.5
        * glam::Mat4::from_cols_array_2d(&[
            [1.0, c, s, 0.0],
            [c, c * c, s * c, 0.0],
            [s, s * c, s * s, 0.0],
            [0.0; 4],
        ]);
    assert!(m.abs_diff_eq(want, 1e-6), "{m} vs {want}");
}

#[test]
fn rotators_turn_the_frame_and_depolarizers_keep_s0() {
    let h = Vec4::new(1.0, 1.0, 0.0, 0.0);
    let q = std::f32::consts::FRAC_PI_4;
    assert!(close(rotator(q) * h, Vec4::new(1.0, 0.0, -1.0, 0.0), 1e-6));
    assert!(close(rotator(-q) * h, Vec4::new(1.0, 0.0, 1.0, 0.0), 1e-6));
    assert!(close(
        rotator(2.0 * q) * h,
        Vec4::new(1.0, -1.0, 0.0, 0.0),
        1e-6
    ));
    // A rotator is orthogonal and R(a) R(b) = R(a + b).
    let (a, b) = (0.3f32, -1.1f32);
    assert!((rotator(a) * rotator(b)).abs_diff_eq(rotator(a + b), 1e-6));
    assert!((rotator(a) * rotator(a).transpose()).abs_diff_eq(glam::Mat4::IDENTITY, 1e-6));
    let s = Vec4::new(1.0, 0.5, -0.3, 0.2);
    assert!(close(
        depolarizer(0.8) * s,
        Vec4::new(0.8, 0.0, 0.0, 0.0),
        1e-7
    ));
}

#[test]
fn a_quarter_wave_plate_turns_linear_light_circular() {
    let qwp = linear_retarder(std::f32::consts::FRAC_PI_2);
    // Linear at +45 degrees to the fast axis: fully circular.
    let out = qwp * Vec4::new(1.0, 0.0, 1.0, 0.0);
    assert!(close(out, Vec4::new(1.0, 0.0, 0.0, -1.0), 1e-6), "{out}");
    assert!(dolp(out) < 1e-6 && (dop(out) - 1.0).abs() < 1e-6);
    // Horizontal light through the plate turned by 45 degrees: circular too.
    let out = rotated_element(std::f32::consts::FRAC_PI_4, qwp) * Vec4::new(1.0, 1.0, 0.0, 0.0);
    assert!(
        (out.w.abs() - 1.0).abs() < 1e-6 && dolp(out) < 1e-6,
        "{out}"
    );
    // Two quarter-wave plates make a half-wave plate: linear light at angle a comes
    // out at -a (mirrored about the fast axis).
    let hwp = qwp * qwp;
    assert!(hwp.abs_diff_eq(linear_retarder(std::f32::consts::PI), 1e-6));
    let a = 0.3f32;
    let lin = Vec4::new(1.0, (2.0 * a).cos(), (2.0 * a).sin(), 0.0);
    assert!((aolp(hwp * lin) + a).abs() < 1e-5);
    // A circular polarizer passes half of unpolarized light, circular of its hand.
    let out = circular_polarizer(true) * unpolarized(1.0);
    assert!(close(out, Vec4::new(0.5, 0.0, 0.0, 0.5), 1e-7));
    let out = circular_polarizer(false) * unpolarized(1.0);
    assert!(close(out, Vec4::new(0.5, 0.0, 0.0, -0.5), 1e-7));
}

#[test]
fn stokes_frames_rotate_with_their_basis() {
    let w = Vec3::Z;
    let b0 = stokes_basis(w);
    assert!(b0.dot(w).abs() < 1e-6 && (b0.length() - 1.0).abs() < 1e-6);
    let turn = |v: Vec3, deg: f32| glam::Quat::from_axis_angle(w, deg.to_radians()) * v;
    let h = Vec4::new(1.0, 1.0, 0.0, 0.0);
    // Horizontal light seen in a basis turned by 90 degrees is vertical; by +45, at
    // -45 degrees; by -45, at +45.
    for (deg, want) in [
        (90.0, Vec4::new(1.0, -1.0, 0.0, 0.0)),
        (45.0, Vec4::new(1.0, 0.0, -1.0, 0.0)),
        (-45.0, Vec4::new(1.0, 0.0, 1.0, 0.0)),
        (180.0, h),
    ] {
        let s = rotate_stokes_basis(w, b0, turn(b0, deg)) * h;
        assert!(close(s, want, 1e-5), "{deg}: {s}");
    }
    // Turning an element is turning both of its frames the other way.
    let m = linear_polarizer(1.0);
    let theta = 0.7f32;
    let by_frames = rotate_mueller_basis_collinear(m, w, turn(b0, theta.to_degrees()), b0);
    assert!(by_frames.abs_diff_eq(rotated_element(theta, m), 1e-5));
    // The basis of any direction is a unit vector orthogonal to it.
    for d in [Vec3::X, -Vec3::Z, Vec3::new(0.3, -0.5, 0.8).normalize()] {
        let b = stokes_basis(d);
        assert!(b.dot(d).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
    }
}

/// Textbook amplitudes (Born and Wolf, Hecht) for light from index n1 into n2.
fn textbook(theta_i: f64, n1: f64, n2: f64) -> (f64, f64) {
    let sin_t = n1 / n2 * theta_i.sin();
    let (ci, ct) = (theta_i.cos(), (1.0 - sin_t * sin_t).sqrt());
    let r_s = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
    let r_p = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
    (r_s * r_s, r_p * r_p)
}

#[test]
fn dielectric_fresnel_matches_the_textbook_for_s_and_p() {
    for eta in [1.5f64, 1.33, 2.4] {
        for deg in [0.0f64, 20.0, 45.0, 60.0, 80.0, 89.0] {
            let th = deg.to_radians();
            let (rs, rp) = textbook(th, 1.0, eta);
            let f = amplitudes(th.cos(), C64::new(eta, 0.0));
            assert!((f.a_s.norm_sqr() - rs).abs() < 1e-12, "{eta} {deg}");
            assert!((f.a_p.norm_sqr() - rp).abs() < 1e-12, "{eta} {deg}");
            let m = specular_reflection(th.cos(), C64::new(eta, 0.0));
            let t = specular_transmission(th.cos(), eta);
            // M00 is the unpolarized reflectance, M01 the s/p difference.
            let unpol = fresnel_dielectric(th.cos() as f32, eta as f32).0;
            assert!((m.x_axis.x - unpol).abs() < 1e-6);
            assert!((m.y_axis.x as f64 - 0.5 * (rs - rp)).abs() < 1e-6);
            // Energy: R + T = 1 for s and for p.
            assert!((m.x_axis.x + t.x_axis.x - 1.0).abs() < 1e-6, "{eta} {deg}");
            assert!((m.y_axis.x + t.y_axis.x).abs() < 1e-6, "{eta} {deg}");
            // From the inside at the same transmitted geometry, the same reflectance.
            let sin_t = th.sin() / eta;
            let inside = specular_reflection(-(1.0 - sin_t * sin_t).sqrt(), C64::new(eta, 0.0));
            assert!((inside.x_axis.x - m.x_axis.x).abs() < 1e-6);
        }
        // Brewster's angle: p is not reflected, what is reflected is fully s-polarized.
        let brewster = eta.atan();
        let m = specular_reflection(brewster.cos(), C64::new(eta, 0.0));
        let out = m * unpolarized(1.0);
        assert!(amplitudes(brewster.cos(), C64::new(eta, 0.0)).a_p.norm() < 1e-12);
        assert!((dolp(out) - 1.0).abs() < 1e-5 && out.y > 0.0);
    }
    // Normal incidence: ((n - 1) / (n + 1))^2 for both, and a half-wave phase flip.
    let m = specular_reflection(1.0, C64::new(1.5, 0.0));
    assert!(
        m.abs_diff_eq(linear_retarder(std::f32::consts::PI) * 0.04, 1e-6),
        "{m}"
    );
}

#[test]
fn total_internal_reflection_keeps_all_light_and_shifts_its_phase() {
    let n = 1.5f64; // glass to air
    let critical = (1.0 / n).asin();
    for deg in [45.0f64, 50.0, 60.0, 75.0] {
        let th = deg.to_radians();
        assert!(th > critical);
        let m = specular_reflection(-th.cos(), C64::new(n, 0.0));
        assert!((m.x_axis.x - 1.0).abs() < 1e-6 && m.y_axis.x.abs() < 1e-6);
        // The relative phase of p and s (Born and Wolf 1.5.4): tan(delta / 2) =
        // cos(th) sqrt(sin^2(th) - (1/n)^2) / sin^2(th).
        let rel = 1.0 / n;
        let s2 = th.sin().powi(2);
        let delta = 2.0 * (th.cos() * (s2 - rel * rel).sqrt() / s2).atan();
        assert!(
            (m.z_axis.z as f64 - delta.cos()).abs() < 1e-5,
            "{deg}: cos {} vs {}",
            m.z_axis.z,
            delta.cos()
        );
        // Sign: Mitsuba's convention, M[3][2] = +sin(delta) (mitransient's S3).
        assert!(
            (m.z_axis.w as f64 - delta.sin()).abs() < 1e-5,
            "{deg}: {}",
            m.z_axis.w
        );
        assert!((m.w_axis.z as f64 + delta.sin()).abs() < 1e-5);
        assert!(specular_transmission(-th.cos(), n).abs_diff_eq(glam::Mat4::ZERO, 1e-7));
    }
    // The same light described with eta < 1 and cos > 0 (Mitsuba's own check): at the
    // angle of the largest phase shift, delta_max = 2 atan((1 - e^2) / (2 e)).
    let e = 1.0 / n;
    let c = ((1.0 - e * e) / (1.0 + e * e)).sqrt();
    let m = specular_reflection(c, C64::new(e, 0.0));
    let d = 2.0 * ((1.0 - e * e) / (2.0 * e)).atan();
    assert!(
        (m.z_axis.z as f64 - d.cos()).abs() < 1e-5 && (m.z_axis.w as f64 - d.sin()).abs() < 1e-5
    );
}

#[test]
fn conductor_fresnel_matches_the_closed_forms() {
    // Gold near 600 nm and aluminium near 550 nm (n, k).
    for (n, k) in [(0.25f64, 2.97f64), (0.96, 6.69)] {
        let eta = C64::new(n, k);
        // Normal incidence: ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2), and a half-wave flip
        // of the circular part's handedness (a_p = -a_s).
        let r0 = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
        let m = specular_reflection(1.0, eta);
        assert!((m.x_axis.x as f64 - r0).abs() < 1e-6);
        assert!((m.z_axis.z as f64 + r0).abs() < 1e-6 && (m.w_axis.w as f64 + r0).abs() < 1e-6);
        for deg in [0.0f64, 30.0, 60.0, 80.0, 88.0] {
            let c = deg.to_radians().cos();
            let m = specular_reflection(c, eta);
            // M00 is tstat's unpolarized conductor reflectance (Moeller's formula).
            let unpol = fresnel_conductor(c as f32, Vec3::splat(n as f32), Vec3::splat(k as f32)).x;
            assert!(
                (m.x_axis.x - unpol).abs() < 1e-5,
                "{n} {k} {deg}: {} vs {unpol}",
                m.x_axis.x
            );
            // s and p against the complex textbook amplitudes.
            let (sin2, ci) = (1.0 - c * c, C64::new(c, 0.0));
            let ct = (C64::new(1.0, 0.0) - sin2 / (eta * eta)).sqrt();
            let rs = ((ci - eta * ct) / (ci + eta * ct)).norm_sqr();
            let rp = ((eta * ci - ct) / (eta * ci + ct)).norm_sqr();
            assert!((m.x_axis.x as f64 - 0.5 * (rs + rp)).abs() < 1e-6);
            assert!((m.y_axis.x as f64 - 0.5 * (rs - rp)).abs() < 1e-6);
            // A mirror keeps the degree of polarization of fully polarized light.
            let out = m * Vec4::new(1.0, 0.0, 0.6, 0.8);
            assert!((dop(out) - 1.0).abs() < 1e-4, "{deg}: {}", dop(out));
        }
    }
}
