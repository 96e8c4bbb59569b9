//! The polarized path (`--mode mono_polarized` and `spectral_polarized`, issue 45):
//! what a path adds to the mono or spectral path to carry polarization, in Mitsuba 3's
//! conventions (`crate::polarization`, `materials::mueller`).
//!
//! The path keeps its scalar throughput `beta` for every sampling decision (lobe
//! choice, Russian roulette, MIS), exactly as the mono path. Beside it, it carries the
//! product `M` of the Mueller matrices of its vertices, each normalised by its [0][0]
//! element: a BSDF's matrix `B` (`Bsdf::mueller`) has `B[0][0]` equal to the scalar
//! value that `beta` already holds (eval, or a delta lobe's weight times its choice
//! probability), so the step is `B / B[0][0]`. Emitters are unpolarized: a
//! contribution `c` (what the mono path would record) becomes the Stokes vector
//! `c * M e0`, the first column of `M` scaled. This is Mitsuba's estimator (its
//! throughput is the unnormalised product) with the same samples; only Russian
//! roulette reads the scalar `beta` instead of the matrix's [0][0] element, which
//! changes no expectation.
//!
//! Frames: a Stokes vector travelling along `w` is expressed in Mitsuba's implicit
//! basis `stokes_basis(w)`; each step re-expresses the BSDF's local matrix in the
//! implicit bases of its world directions (`to_world_mueller`). The camera's matrix
//! starts as the rotation from the implicit basis of the camera ray's reversed
//! direction into the sensor's frame (basis `d x up`: Mitsuba's `stokes` integrator),
//! so S1 > 0 is light polarized along the image's horizontal axis.
//!
//! Lanes: a mono path carries one matrix; a spectral polarized path one per wavelength
//! (`Polarization::lanes` = 3), each normalised by its own lane of the throughput, as
//! Mitsuba's `spectral_polarized` variants carry a Mueller matrix per wavelength. Its
//! contribution is a Stokes vector per wavelength, and each Stokes component becomes
//! one linear sRGB sample exactly as the spectral path's radiance does
//! (`Wavelengths::to_srgb`, the `1 / p(l)` weights): the film's 12 channels, RGB-major
//! ([`deposit`]), which is what Mitsuba's `stokes` integrator writes per component.
//!
//! Cost: 192 bytes per path (`M` per lane), a 4 x 4 product per lane per BSDF sample
//! and a matrix-vector product per lane per contribution; paths of other modes carry
//! `None`.

use super::deposits::Deposit;
use crate::materials::mueller::to_world_mueller;
use crate::materials::{Bsdf, BsdfFlags};
use crate::math::frame::Frame;
use crate::math::Rgb;
use crate::polarization::elements::depolarizer;
use crate::polarization::frames::{rotate_stokes_basis, stokes_basis};
use crate::spectral::lift::Wavelengths;
use glam::{Mat4, Vec3, Vec4};

/// The polarization state of a path: the product of the normalised Mueller matrices
/// of its vertices (after the camera's rotation), one per lane it carries.
#[derive(Clone, Copy, Debug)]
pub struct Polarization {
    m: [Mat4; 3],
    /// 1 (mono: lane 0) or 3 (spectral: one per wavelength).
    lanes: usize,
}

impl Polarization {
    /// A camera path along unit `d` from a sensor whose up axis is `up`, carrying
    /// `lanes` matrices.
    #[inline]
    pub fn new(d: Vec3, up: Vec3, lanes: usize) -> Self {
        debug_assert!(lanes == 1 || lanes == 3);
        Polarization {
            m: [camera(d, up); 3],
            lanes,
        }
    }

    /// A scattering at `bsdf` from `-wi` to `wo` (local to `frame`; `delta` as
    /// [`step`] takes it): each lane's matrix times that lane's normalised step.
    #[inline]
    pub fn scatter(
        &mut self,
        bsdf: &Bsdf,
        frame: &Frame,
        wo: Vec3,
        wi: Vec3,
        delta: Option<BsdfFlags>,
    ) {
        for (k, m) in self.m[..self.lanes].iter_mut().enumerate() {
            *m *= step(bsdf, frame, wo, wi, delta, k);
        }
    }

    /// The Stokes vectors, one per lane, of a contribution `c` (its value per lane, as
    /// the scalar path computes it) of unpolarized light whose last step to the path
    /// has the normalised world matrix `n(lane)` (its first column is all that is
    /// read: the light is unpolarized), `M n e0 c`.
    #[inline]
    pub fn stokes(&self, c: Rgb, n: impl Fn(usize) -> Vec4) -> [Vec4; 3] {
        let mut s = [Vec4::ZERO; 3];
        for k in 0..self.lanes {
            s[k] = self.m[k] * n(k) * c[k];
        }
        s
    }

    /// [`Polarization::stokes`] of light that reaches the path unchanged (an emitter
    /// seen along the path's ray): `M e0 c`.
    #[inline]
    pub fn unpolarized(&self, c: Rgb) -> [Vec4; 3] {
        self.stokes(c, |_| Vec4::X)
    }

    /// The film's channels of the Stokes vectors `s` (one per lane): S0..S3 of a mono
    /// path; of a spectral path (`wl`), each component's sRGB, RGB-major
    /// (`S0.R, S1.R, S2.R, S3.R, S0.G, ..`, `RenderMode::channel_names`).
    #[inline]
    pub fn deposit(&self, s: &[Vec4; 3], wl: Option<&Wavelengths>) -> Deposit {
        let mut d = [0.0; super::deposits::DEPOSIT_WIDTH];
        match wl {
            None => {
                for (j, v) in s[0].to_array().into_iter().enumerate() {
                    d[j] = f64::from(v);
                }
            }
            Some(wl) => {
                for j in 0..4 {
                    let rgb = wl.to_srgb(Vec3::new(s[0][j], s[1][j], s[2][j]));
                    for c in 0..3 {
                        d[4 * c + j] = f64::from(rgb[c]);
                    }
                }
            }
        }
        d
    }
}

/// The camera's matrix of a ray along unit `d` from a sensor whose up axis is `up`:
/// from the implicit basis of `-d` (the direction light arrives in) into the sensor's
/// frame, basis `d x up` (Mitsuba's `stokes` integrator).
#[inline]
pub fn camera(d: Vec3, up: Vec3) -> Mat4 {
    let target = d.cross(up);
    if target.length_squared() == 0.0 {
        return Mat4::IDENTITY;
    }
    rotate_stokes_basis(-d, stokes_basis(-d), target)
}

/// The normalised world-basis Mueller matrix of lane `lane` of the scattering from
/// `-wi` to `wo` (local directions in `frame`) at `bsdf` (`delta`: the delta lobe a
/// sample came through, as `Bsdf::mueller` takes it): `B / B[0][0]`, or an ideal
/// depolarizer where
/// `B[0][0]` is not positive (then the scalar path carries no light either, or the
/// two differ by rounding at a grazing direction).
#[inline]
pub fn step(
    bsdf: &Bsdf,
    frame: &Frame,
    wo: Vec3,
    wi: Vec3,
    delta: Option<BsdfFlags>,
    lane: usize,
) -> Mat4 {
    if bsdf.depolarizes() {
        // What the general branch gives such a model, exactly (tested), without the
        // matrices: the rotations of the bases keep S0 and drop the rest.
        return depolarizer(1.0);
    }
    let local = bsdf.mueller_lane(wo, wi, delta, lane);
    let a = local.x_axis.x;
    if !(a > 0.0 && a.is_finite()) {
        return depolarizer(1.0);
    }
    let mut n = local * (1.0 / a);
    // Exactly 1: a depolarizing step then keeps S0 bit for bit (the mono mode's).
    n.x_axis.x = 1.0;
    to_world_mueller(frame, n, -wi, wo)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Horizontal light (along the sensor's x axis) reads S1 = S0 for a camera looking
    /// down -z with up +y, whatever the implicit basis of the ray is.
    #[test]
    fn the_camera_matrix_expresses_stokes_vectors_in_the_sensor_frame() {
        for d in [
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.3, -0.2, -1.0).normalize(),
            Vec3::new(-0.5, 0.4, -0.8).normalize(),
        ] {
            let up = Vec3::Y;
            // Light travelling along -d polarized along the sensor's horizontal,
            // d x up, written in the implicit basis of -d: rotate it there.
            let horizontal = d.cross(up).normalize();
            let to_implicit = rotate_stokes_basis(-d, horizontal, stokes_basis(-d));
            let s_implicit = to_implicit * Vec4::new(1.0, 1.0, 0.0, 0.0);
            let s = camera(d, up) * s_implicit;
            assert!(
                (s - Vec4::new(1.0, 1.0, 0.0, 0.0)).abs().max_element() < 1e-5,
                "{d} {s}"
            );
            // Vertical light reads S1 = -S0.
            let v = camera(d, up) * (to_implicit * Vec4::new(1.0, -1.0, 0.0, 0.0));
            assert!((v - Vec4::new(1.0, -1.0, 0.0, 0.0)).abs().max_element() < 1e-5);
        }
    }

    /// The general branch of [`step`] on a depolarizing model: exactly
    /// `depolarizer(1)`, the shortcut [`step`] takes, for many frames and directions
    /// (delta lobes, zero values and grazing angles included).
    #[test]
    fn a_depolarizing_step_is_exactly_the_ideal_depolarizer() {
        use crate::materials::{Diffuse, ThinDielectric};
        use crate::math::rng::Pcg32;
        let models = [
            Bsdf::Diffuse(Diffuse {
                reflectance: Rgb::new(0.5, 0.3, 0.2),
            }),
            Bsdf::ThinDielectric(ThinDielectric {
                eta: 1.5,
                specular_reflectance: Rgb::ONE,
                specular_transmittance: Rgb::ONE,
            }),
        ];
        let mut rng = Pcg32::new(7, 1);
        for bsdf in &models {
            assert!(bsdf.depolarizes());
            for _ in 0..500 {
                let dir = |r: &mut Pcg32| {
                    Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32() - 0.5)
                        .try_normalize()
                        .unwrap_or(Vec3::Z)
                };
                let frame = Frame::from_normal(dir(&mut rng));
                let (wo, wi) = (dir(&mut rng), dir(&mut rng));
                for delta in [
                    None,
                    Some(BsdfFlags::DELTA_REFLECTION),
                    Some(BsdfFlags::DELTA_TRANSMISSION),
                ] {
                    for lane in 0..3 {
                        let local = bsdf.mueller_lane(wo, wi, delta, lane);
                        let a = local.x_axis.x;
                        let general = if a > 0.0 && a.is_finite() {
                            let mut n = local * (1.0 / a);
                            n.x_axis.x = 1.0;
                            to_world_mueller(&frame, n, -wi, wo)
                        } else {
                            depolarizer(1.0)
                        };
                        assert_eq!(general, depolarizer(1.0), "{bsdf:?} {wo} {wi} {delta:?}");
                        assert_eq!(step(bsdf, &frame, wo, wi, delta, lane), depolarizer(1.0));
                    }
                }
            }
        }
    }

    /// Each lane of a spectral path is scattered by its own lane's Fresnel matrix: a
    /// conductor whose optical constants differ per lane gives lane k the matrix a
    /// conductor with lane k's constants in every lane gives lane 0 (the mono path).
    #[test]
    fn each_lane_scatters_by_its_own_constants() {
        use crate::materials::Conductor;
        let eta = Rgb::new(0.2, 0.9, 1.6);
        let k = Rgb::new(3.9, 2.4, 1.1);
        let spectral = Bsdf::Conductor(Conductor {
            eta,
            k,
            specular_reflectance: Rgb::splat(0.8),
        });
        let frame = Frame::from_normal(Vec3::new(0.2, 0.3, 0.9).normalize());
        let wo = Vec3::new(0.5, -0.3, 0.8).normalize();
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        let (d, up) = (Vec3::new(0.1, 0.2, -1.0).normalize(), Vec3::Y);
        let delta = Some(BsdfFlags::DELTA_REFLECTION);
        let mut p = Polarization::new(d, up, 3);
        p.scatter(&spectral, &frame, wo, wi, delta);
        for lane in 0..3 {
            let mono = Bsdf::Conductor(Conductor {
                eta: Rgb::splat(eta[lane]),
                k: Rgb::splat(k[lane]),
                specular_reflectance: Rgb::splat(0.8),
            });
            let mut q = Polarization::new(d, up, 1);
            q.scatter(&mono, &frame, wo, wi, delta);
            assert_eq!(p.m[lane], q.m[0], "lane {lane}");
            // The lanes do differ: a conductor's polarization depends on eta and k.
            if lane > 0 {
                assert_ne!(p.m[lane], p.m[0]);
            }
        }
    }

    /// The film's channels of a spectral path: component j of colour c is the sRGB
    /// (`Wavelengths::to_srgb`) of the lanes' component j, at channel 4c + j; a mono
    /// path writes S0..S3 of lane 0 and zeros beyond.
    #[test]
    fn the_deposit_is_each_components_srgb_rgb_major() {
        let wl = Wavelengths::sample(0.37);
        let s = [
            Vec4::new(1.0, 0.5, -0.25, 0.125),
            Vec4::new(0.75, -0.5, 0.25, 0.0),
            Vec4::new(2.0, 1.0, 0.5, -1.5),
        ];
        let p = Polarization::new(Vec3::NEG_Z, Vec3::Y, 3);
        let d = p.deposit(&s, Some(&wl));
        for j in 0..4 {
            let rgb = wl.to_srgb(Vec3::new(s[0][j], s[1][j], s[2][j]));
            for c in 0..3 {
                assert_eq!(d[4 * c + j], f64::from(rgb[c]), "S{j} colour {c}");
            }
        }
        let mono = Polarization::new(Vec3::NEG_Z, Vec3::Y, 1).deposit(&s, None);
        assert_eq!(&mono[..4], &[1.0, 0.5, -0.25, 0.125]);
        assert!(mono[4..].iter().all(|&v| v == 0.0));
    }
}
