//! Mueller matrices of scattering events, for the mono-polarized render mode (Mitsuba
//! 3's `*_mono_polarized` variants): [`Bsdf::mueller`] gives, for every model, the 4 x
//! 4 matrix that Mitsuba's BSDF returns in a polarized variant, in the BSDF's local
//! shading frame. The path tracer keeps its scalar throughput for every sampling
//! decision and carries the product of these matrices, normalised by their [0][0]
//! element (which equals the scalar value, see below).
//!
//! Conventions (those of `crate::polarization`, i.e. Mitsuba's `mueller.h`):
//! - tstat's `wo` points back towards the camera (Mitsuba's `si.wi`), `wi` towards the
//!   light (Mitsuba's `bs.wo`): light arrives travelling along `-wi` and leaves
//!   travelling along `wo`. In Mitsuba's polarized BSDFs (radiance transport) that is
//!   `wo_hat = bs.wo` (our `wi`) and `wi_hat = si.wi` (our `wo`).
//! - The matrix maps a Stokes vector in the basis `stokes_basis(-wi)` to one in
//!   `stokes_basis(wo)`, both local vectors: what Mitsuba's BSDF returns before the
//!   integrator's `si.to_world_mueller(value, -wo, si.wi)` ([`to_world_mueller`]).
//! - Lanes: `mueller_lane(.., lane)` reads lane `lane` of every colour: the mono mode
//!   makes all lanes equal and asks lane 0 ([`Bsdf::mueller`]); a spectral polarized
//!   path asks each of its wavelengths' lanes (one matrix per wavelength, as Mitsuba's
//!   `spectral_polarized` variants, whose Mueller matrices are per wavelength).
//! - `delta = None`: the sum over the non-delta lobes; its [0][0] is the lane of
//!   `eval(wo, wi)` (f |cos|). `delta = Some(lobe)` for a pair `sample` produced
//!   through a delta lobe (`BsdfSample::lobe`): that lobe's matrix, before division by
//!   the lobe-choice probability, so [0][0] is the lane of `weight * pdf`. A delta model
//!   asked about a direction its lobe does not reach returns zero (what a wrapper
//!   needs to tell its children's lobes apart).
//!
//! Per model, from Mitsuba 3's `src/bsdfs/*.cpp` (their `is_polarized_v` branches):
//! - depolarizers (`diffuse`, `plastic`, `roughplastic`, `roughdielectric`,
//!   `thindielectric`, `principled`, `principledthin`): `depolarizer(value)`;
//! - `conductor`, `roughconductor`: `specular_reflection(cos, eta + ik)` in the s/p
//!   frame of the (micro)facet normal, turned into the implicit bases, times the
//!   reflectance and (rough) D G / (4 cos wo);
//! - `dielectric`: `specular_reflection` / `specular_transmission` at `cos(wi)` in the
//!   s/p frame of the normal, times the reflectance / transmittance and, transmitted,
//!   the radiance scaling `eta_ti^2` that tstat's `sample` applies;
//! - `pplastic`: the rough Fresnel reflection as for `roughconductor`, plus the diffuse
//!   base `T_out depolarizer(d) T_in cos(wi) / pi` in the s/p frame of the normal;
//! - `polarizer`, `retarder`, `circular`: Mitsuba's elements with their frame rules
//!   (see each function); `null` and `mask`'s pass-through: the identity (unchanged
//!   polarization), scaled;
//! - wrappers: `twosided` evaluates its side with z flipped and no correction of the
//!   bases, exactly as Mitsuba (a mirror reverses handedness, which Mitsuba ignores);
//!   `blendbsdf`, `Composed`, `mask`, `Separable` combine their children as their
//!   scalar code does; `normalmap`/`bumpmap` re-express the nested matrix from the
//!   perturbed frame's implicit bases into the outer frame's (Mitsuba does not: its
//!   integrator rotates the nested matrix as if it were in the unperturbed frame).
//!
//! Where two delta lobes of a BSDF reach the same direction (`mask` over a straight
//! transmission, a blend of two mirrors), `mueller` returns their sum, whose [0][0] is
//! the expected weight over the lobe choice rather than one sample's: normalised, it
//! is the right polarization state for either choice in expectation.

use super::fresnel::fresnel_dielectric;
use super::{
    Blend, Bsdf, BsdfFlags, BsdfModel, Circular, Composed, Conductor, Dielectric, Mask, OneSided,
    PPlastic, Perturbed, Polarizer, Retarder, RoughConductor, TwoSided,
};
use crate::math::frame::Frame;
use crate::polarization::elements::{
    circular_polarizer, depolarizer, linear_polarizer, linear_retarder, rotated_element,
};
use crate::polarization::frames::{
    rotate_mueller_basis, rotate_mueller_basis_collinear, stokes_basis,
};
use crate::polarization::fresnel::{specular_reflection, specular_transmission};
use glam::{Mat4, Vec3};
use num_complex::Complex64 as C64;

/// How far (per component) a queried direction may lie from a delta lobe's direction
/// and still be that lobe's.
const DIRECTION_TOLERANCE: f32 = 1e-4;

#[inline]
fn same_direction(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() <= DIRECTION_TOLERANCE
}

#[inline]
fn mirror(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

#[inline]
fn flip_z(v: Vec3) -> Vec3 {
    Vec3::new(v.x, v.y, -v.z)
}

/// Re-expresses `m`, written in the s/p frame of an interaction about the normal `n`
/// (basis vector `n x (-wi)` in, `n x wo` out), in the implicit bases of `-wi` and
/// `wo`. As Mitsuba: where the incident beam is collinear with `n` both s axes
/// become (1, 0, 0).
fn sp_to_implicit(m: Mat4, n: Vec3, wo: Vec3, wi: Vec3) -> Mat4 {
    let (s_in, s_out) = match n.cross(-wi).try_normalize() {
        Some(s_in) => (s_in, n.cross(wo).try_normalize().unwrap_or(Vec3::X)),
        None => (Vec3::X, Vec3::X),
    };
    rotate_mueller_basis(m, -wi, s_in, stokes_basis(-wi), wo, s_out, stokes_basis(wo))
}

/// [`sp_to_implicit`] with each s axis falling back to (1, 0, 0) on its own (Mitsuba's
/// `pplastic` diffuse term).
fn sp_to_implicit_each(m: Mat4, n: Vec3, wo: Vec3, wi: Vec3) -> Mat4 {
    let s_in = n.cross(-wi).try_normalize().unwrap_or(Vec3::X);
    let s_out = n.cross(wo).try_normalize().unwrap_or(Vec3::X);
    rotate_mueller_basis(m, -wi, s_in, stokes_basis(-wi), wo, s_out, stokes_basis(wo))
}

/// Mitsuba's `SurfaceInteraction::to_world_mueller`: re-expresses `m`, which maps
/// Stokes vectors travelling along the local `in_forward` (in the basis
/// `stokes_basis(in_forward)`, local) to vectors along the local `out_forward`, in
/// the implicit bases of the world directions `frame.to_world(...)`. For a BSDF's
/// matrix, `in_forward = -wi` and `out_forward = wo`. Also re-expresses a matrix from
/// a perturbed frame into the frame it is given in (`frame` relative to it).
pub fn to_world_mueller(frame: &Frame, m: Mat4, in_forward: Vec3, out_forward: Vec3) -> Mat4 {
    let (in_world, out_world) = (frame.to_world(in_forward), frame.to_world(out_forward));
    rotate_mueller_basis(
        m,
        in_world,
        frame.to_world(stokes_basis(in_forward)),
        stokes_basis(in_world),
        out_world,
        frame.to_world(stokes_basis(out_forward)),
        stokes_basis(out_world),
    )
}

/// The value (lane `lane` of `weight * pdf`) of the delta lobe `lobe` of a model that
/// picks its lobes by `u1` in order, found by sampling it: exactly the scalar code's.
fn delta_value_by_sampling(
    b: &impl BsdfModel,
    wo: Vec3,
    wi: Vec3,
    lobe: BsdfFlags,
    lane: usize,
) -> f32 {
    for u1 in [0.0, 0.5, 1.0 - f32::EPSILON] {
        if let Some(s) = b.sample(wo, u1, [0.5, 0.5]) {
            if s.lobe == lobe && same_direction(s.wi, wi) {
                return s.weight[lane] * s.pdf;
            }
        }
    }
    0.0
}

/// A depolarizing model: `depolarizer(eval)` for the non-delta lobes and
/// `depolarizer(weight * pdf)` for its delta lobes.
fn depolarizing(
    b: &impl BsdfModel,
    wo: Vec3,
    wi: Vec3,
    delta: Option<BsdfFlags>,
    lane: usize,
) -> Mat4 {
    match delta {
        None => depolarizer(b.eval(wo, wi)[lane]),
        Some(lobe) if b.flags(wo).contains(lobe) => {
            depolarizer(delta_value_by_sampling(b, wo, wi, lobe, lane))
        }
        Some(_) => Mat4::ZERO,
    }
}

impl Bsdf {
    /// Whether every matrix of this model is an ideal depolarizer times its scalar
    /// value (the depolarizing models, and `twosided` / `Separable` of them): its
    /// normalised step is then `depolarizer(1)` in any bases, at every lane
    /// (`render::polarized::step` skips the matrices).
    pub fn depolarizes(&self) -> bool {
        match self {
            Bsdf::Diffuse(_)
            | Bsdf::Plastic(_)
            | Bsdf::RoughPlastic(_)
            | Bsdf::RoughDielectric(_)
            | Bsdf::ThinDielectric(_)
            | Bsdf::Principled(_)
            | Bsdf::PrincipledThin(_) => true,
            Bsdf::TwoSided(b) => b.front.depolarizes() && b.back.depolarizes(),
            Bsdf::Separable(s) => s.inner.depolarizes(),
            _ => false,
        }
    }

    /// [`Bsdf::mueller_lane`] of lane 0: the mono-polarized matrix.
    pub fn mueller(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>) -> Mat4 {
        self.mueller_lane(wo, wi, delta, 0)
    }

    /// The Mueller matrix of light arriving along `-wi` and leaving along `wo` (local
    /// frame), at lane `lane` of every colour, with input basis `stokes_basis(-wi)` and
    /// output basis `stokes_basis(wo)`: what Mitsuba's BSDF returns in a
    /// `mono_polarized` variant before `si.to_world_mueller(value, -wo_mitsuba,
    /// si.wi)`. `delta`: `Some(lobe)` when `(wo, wi)` came from `sample` through a
    /// delta lobe (`BsdfSample::lobe`): that lobe's matrix before division by the
    /// lobe-choice probability ([0][0] = the lane of `weight * pdf`); `None`: the sum
    /// over the non-delta lobes ([0][0] = the lane of `eval(wo, wi)`).
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        match self {
            Bsdf::Diffuse(b) => depolarizing(b, wo, wi, delta, lane),
            Bsdf::Plastic(b) => depolarizing(b, wo, wi, delta, lane),
            Bsdf::RoughPlastic(b) => depolarizing(b, wo, wi, delta, lane),
            Bsdf::RoughDielectric(b) => depolarizing(b, wo, wi, delta, lane),
            Bsdf::ThinDielectric(b) => depolarizing(b, wo, wi, delta, lane),
            Bsdf::Principled(b) => depolarizing(b, wo, wi, delta, lane),
            Bsdf::PrincipledThin(b) => depolarizing(b, wo, wi, delta, lane),
            Bsdf::Conductor(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::RoughConductor(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::Dielectric(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::PPlastic(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::Polarizer(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::Retarder(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::Circular(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::Null(_) => match delta {
                Some(BsdfFlags::DELTA_TRANSMISSION) if same_direction(wi, -wo) => Mat4::IDENTITY,
                _ => Mat4::ZERO,
            },
            Bsdf::TwoSided(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::Mask(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::Separable(s) => s.inner.mueller_lane(wo, wi, delta, lane),
            Bsdf::Composed(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::Blend(b) => b.mueller_lane(wo, wi, delta, lane),
            Bsdf::Perturbed(b) => b.mueller_lane(wo, wi, delta, lane),
        }
    }
}

impl OneSided {
    /// [`Bsdf::depolarizes`] of the wrapped model.
    pub fn depolarizes(&self) -> bool {
        matches!(
            self,
            OneSided::Diffuse(_) | OneSided::Plastic(_) | OneSided::RoughPlastic(_)
        )
    }

    /// [`Bsdf::mueller`] of the wrapped model.
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        match self {
            OneSided::Diffuse(b) => depolarizing(b, wo, wi, delta, lane),
            OneSided::Conductor(b) => b.mueller_lane(wo, wi, delta, lane),
            OneSided::RoughConductor(b) => b.mueller_lane(wo, wi, delta, lane),
            OneSided::Plastic(b) => depolarizing(b, wo, wi, delta, lane),
            OneSided::RoughPlastic(b) => depolarizing(b, wo, wi, delta, lane),
            OneSided::PPlastic(b) => b.mueller_lane(wo, wi, delta, lane),
        }
    }
}

impl Conductor {
    /// Mitsuba's `conductor`: Fresnel reflection at `cos(wi)` in the s/p frame of the
    /// normal, times `specular_reflectance`.
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        if delta != Some(BsdfFlags::DELTA_REFLECTION)
            || wo.z <= 0.0
            || !same_direction(wi, mirror(wo))
        {
            return Mat4::ZERO;
        }
        let eta = C64::new(self.eta[lane] as f64, self.k[lane] as f64);
        let f = specular_reflection(wi.z as f64, eta);
        sp_to_implicit(f, Vec3::Z, wo, wi) * self.specular_reflectance[lane]
    }
}

impl RoughConductor {
    /// Mitsuba's `roughconductor`: Fresnel reflection at `wi . m` in the s/p frame of
    /// the microfacet normal `m = normalize(wo + wi)`, times reflectance D G / (4 cos wo).
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        if delta.is_some() || wo.z <= 0.0 || wi.z <= 0.0 {
            return Mat4::ZERO;
        }
        let Some(m) = (wo + wi).try_normalize() else {
            return Mat4::ZERO;
        };
        let distr = &self.distribution;
        let d = distr.d(m);
        if d == 0.0 {
            return Mat4::ZERO;
        }
        let g = distr.g1(wi, m) * distr.g1(wo, m);
        let eta = C64::new(self.eta[lane] as f64, self.k[lane] as f64);
        let f = specular_reflection(wi.dot(m) as f64, eta);
        sp_to_implicit(f, m, wo, wi) * (self.specular_reflectance[lane] * (d * g / (4.0 * wo.z)))
    }
}

impl Dielectric {
    /// Mitsuba's `dielectric`: Fresnel reflection or transmission of light arriving
    /// along `-wi` (`cos(wi)`, either side) in the s/p frame of the normal, times the
    /// reflectance or transmittance; transmitted, times `eta_ti^2` (radiance).
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        let eta = self.eta as f64;
        match delta {
            Some(BsdfFlags::DELTA_REFLECTION) if same_direction(wi, mirror(wo)) => {
                let r = specular_reflection(wi.z as f64, C64::new(eta, 0.0));
                sp_to_implicit(r, Vec3::Z, wo, wi) * self.specular_reflectance[lane]
            }
            Some(BsdfFlags::DELTA_TRANSMISSION) => {
                let (_, cos_theta_t, _, eta_ti) = fresnel_dielectric(wo.z, self.eta);
                let refracted = Vec3::new(-eta_ti * wo.x, -eta_ti * wo.y, cos_theta_t);
                if cos_theta_t == 0.0 || !same_direction(wi, refracted) {
                    return Mat4::ZERO;
                }
                // Mitsuba evaluates at cos(wi), the light's side; the matrix depends
                // on the power transmittances T_s and T_p alone, which are the same
                // both ways (reciprocity), and at grazing `wo` its refracted cosine
                // carries an f32 error magnified some 30 times: evaluate at cos(wo).
                let t = specular_transmission(wo.z as f64, eta);
                sp_to_implicit(t, Vec3::Z, wo, wi)
                    * (self.specular_transmittance[lane] * (eta_ti * eta_ti))
            }
            _ => Mat4::ZERO,
        }
    }
}

impl PPlastic {
    /// Mitsuba's `pplastic`: the rough Fresnel reflection (as `roughconductor`, real
    /// `eta`) plus the diffuse base seen through the interface, `T(wo) depolarizer(d)
    /// T(wi) cos(wi) / pi` in the s/p frame of the normal (the light refracts in along
    /// `-wi`, is depolarized, and refracts out along `wo`).
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        if delta.is_some() || wo.z <= 0.0 || wi.z <= 0.0 {
            return Mat4::ZERO;
        }
        let eta = self.eta as f64;
        let mut out = Mat4::ZERO;
        if let Some(h) = (wo + wi).try_normalize() {
            let distr = &self.distribution;
            let d = distr.d(h);
            if d > 0.0 {
                let g = distr.g1(wi, h) * distr.g1(wo, h);
                let f = specular_reflection(wi.dot(h) as f64, C64::new(eta, 0.0));
                out += sp_to_implicit(f, h, wo, wi)
                    * (self.specular_reflectance[lane] * (d * g / (4.0 * wo.z)));
            }
        }
        // In through the interface along -wi, out along wo. Mitsuba evaluates the
        // way out from inside, at the refracted angle of wo; by reciprocity (the
        // matrix depends on T_s and T_p alone) that is the matrix at cos(wo) from
        // outside, without the f32 error of the refracted cosine.
        let t_in = specular_transmission(wi.z as f64, eta);
        let t_out = specular_transmission(wo.z as f64, eta);
        let diffuse = t_out * depolarizer(self.diffuse_reflectance[lane]) * t_in;
        out + sp_to_implicit_each(diffuse, Vec3::Z, wo, wi) * (wi.z * std::f32::consts::FRAC_1_PI)
    }
}

impl Polarizer {
    /// Mitsuba's `polarizer`: an ideal linear polarizer whose transmission axis is
    /// `forward x a` with `a = (sin theta, cos theta, 0)` made orthogonal to the beam
    /// (`forward = wo`, the direction the light travels), times `transmittance`; not
    /// `polarizing`: an absorber of 0.5 transmittance (the identity scaled).
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        if delta != Some(BsdfFlags::DELTA_TRANSMISSION) || !same_direction(wi, -wo) {
            return Mat4::ZERO;
        }
        let t = self.transmittance[lane];
        if !self.polarizing {
            return Mat4::IDENTITY * (0.5 * t);
        }
        let forward = wo;
        let (sin, cos) = self.theta.to_radians().sin_cos();
        let a = Vec3::new(sin, cos, 0.0);
        // Degenerate (a beam along the absorbing axis, in the pane's plane): any axis.
        let transmitting = match (a - a.dot(forward) * forward).try_normalize() {
            Some(a) => forward.cross(a),
            None => stokes_basis(forward),
        };
        rotate_mueller_basis_collinear(
            linear_polarizer(1.0),
            forward,
            transmitting,
            stokes_basis(forward),
        ) * t
    }
}

impl Retarder {
    /// Mitsuba's `retarder`: a linear retarder of retardance `delta |cos(wo)|` with its
    /// fast axis turned by `theta` (by `-theta` seen from the back) from the frame
    /// vector (1, 0, 0), re-expressed along `forward = wo`, times `transmittance`.
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        if delta != Some(BsdfFlags::DELTA_TRANSMISSION) || !same_direction(wi, -wo) {
            return Mat4::ZERO;
        }
        let cos = wo.z;
        let m = linear_retarder(self.delta.to_radians() * cos.abs());
        let side = if cos >= 0.0 { 1.0 } else { -1.0 };
        let m = rotated_element(side * self.theta.to_radians(), m);
        rotate_mueller_basis_collinear(m, wo, Vec3::X, stokes_basis(wo)) * self.transmittance[lane]
    }
}

impl Circular {
    /// Mitsuba's `circular`: an ideal right (or `left_handed`) circular polarizer,
    /// re-expressed along `forward = wo` from the frame vector (1, 0, 0) (which
    /// changes nothing: it is rotation invariant), times `transmittance`.
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        if delta != Some(BsdfFlags::DELTA_TRANSMISSION) || !same_direction(wi, -wo) {
            return Mat4::ZERO;
        }
        let m = circular_polarizer(!self.left_handed);
        rotate_mueller_basis_collinear(m, wo, Vec3::X, stokes_basis(wo)) * self.transmittance[lane]
    }
}

impl TwoSided {
    /// The side's matrix, the back side evaluated with z flipped and its matrix used
    /// as it comes, as Mitsuba's `twosided` does.
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        match self.side(wo) {
            (b, false) => b.mueller_lane(wo, wi, delta, lane),
            (b, true) => b.mueller_lane(flip_z(wo), flip_z(wi), delta, lane),
        }
    }
}

impl Mask {
    /// `opacity` times the nested matrix, plus (delta transmission straight through)
    /// `(1 - opacity)` times the identity.
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        let mut m = Mat4::ZERO;
        if self.opacity > 0.0 {
            m = self.nested.mueller_lane(wo, wi, delta, lane) * self.opacity;
        }
        if delta == Some(BsdfFlags::DELTA_TRANSMISSION)
            && self.opacity < 1.0
            && same_direction(wi, -wo)
        {
            m += Mat4::IDENTITY * (1.0 - self.opacity);
        }
        m
    }
}

impl Blend {
    /// The children's matrices weighted by their shares. For a delta lobe, as tstat's
    /// (and Mitsuba's) `sample`: the delta matrix of the child that has the lobe plus
    /// the other child's non-delta matrix in that direction.
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        let mut m = Mat4::ZERO;
        for (b, w) in [
            (&self.first, 1.0 - self.weight),
            (&self.second, self.weight),
        ] {
            if w > 0.0 {
                let own = match delta {
                    Some(lobe) if !b.flags(wo).contains(lobe) => None,
                    d => d,
                };
                m += b.mueller_lane(wo, wi, own, lane) * w;
            }
        }
        m
    }
}

impl Composed {
    /// The mixture for non-delta lobes; for a delta lobe, as `sample` (which returns
    /// the child's sample unchanged), the matrix of the child that has it, or the
    /// weighted mixture of both when both do.
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        let w = self.weight;
        let first = |d| self.first.mueller_lane(wo, wi, d, lane);
        let second = |d| self.second.mueller_lane(wo, wi, d, lane);
        match delta {
            None => {
                let mut m = Mat4::ZERO;
                if w > 0.0 {
                    m += first(None) * w;
                }
                if w < 1.0 {
                    m += second(None) * (1.0 - w);
                }
                m
            }
            Some(lobe) => {
                let has_first = w > 0.0 && self.first.flags(wo).contains(lobe);
                let has_second = w < 1.0 && self.second.flags(wo).contains(lobe);
                match (has_first, has_second) {
                    (true, true) => first(delta) * w + second(delta) * (1.0 - w),
                    (true, false) => first(delta),
                    (false, true) => second(delta),
                    (false, false) => Mat4::ZERO,
                }
            }
        }
    }
}

impl Perturbed {
    /// The nested matrix in the perturbed frame (times the shadowing term, zero where
    /// `wi` changes side), re-expressed in the implicit bases of the outer frame.
    pub fn mueller_lane(&self, wo: Vec3, wi: Vec3, delta: Option<BsdfFlags>, lane: usize) -> Mat4 {
        let (po, pi) = (self.frame.to_local(wo), self.frame.to_local(wi));
        if wi.z * pi.z <= 0.0 {
            return Mat4::ZERO;
        }
        let shadow = if self.use_shadowing_function {
            super::perturbed::shadow_terminator(self.frame.n, wi)
        } else {
            1.0
        };
        let m = self.nested.mueller_lane(po, pi, delta, lane) * shadow;
        to_world_mueller(&self.frame, m, -pi, po)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials::{
        Diffuse, Microfacet, MicrofacetKind, Null, Plastic, Principled, PrincipledThin,
        RoughDielectric, RoughPlastic, Separable, TemporalProfile, ThinDielectric,
    };
    use crate::math::rng::Pcg32;
    use crate::math::Rgb;
    use crate::polarization::frames::rotate_mueller_basis;
    use glam::Vec4;

    fn ggx(alpha_u: f32, alpha_v: f32) -> Microfacet {
        Microfacet {
            kind: MicrofacetKind::Ggx,
            alpha_u,
            alpha_v,
            sample_visible: true,
        }
    }

    fn beckmann(alpha: f32) -> Microfacet {
        Microfacet {
            kind: MicrofacetKind::Beckmann,
            alpha_u: alpha,
            alpha_v: alpha,
            sample_visible: true,
        }
    }

    fn gold() -> Conductor {
        Conductor {
            eta: Rgb::new(0.143119, 0.374957, 1.44248),
            k: Rgb::new(3.98316, 2.38572, 1.60322),
            specular_reflectance: Rgb::new(0.9, 1.0, 0.8),
        }
    }

    fn rough_gold(distribution: Microfacet) -> RoughConductor {
        let c = gold();
        RoughConductor {
            distribution,
            eta: c.eta,
            k: c.k,
            specular_reflectance: c.specular_reflectance,
        }
    }

    fn glass(eta: f32) -> Dielectric {
        Dielectric {
            eta,
            specular_reflectance: Rgb::new(0.9, 1.0, 1.0),
            specular_transmittance: Rgb::new(0.8, 1.0, 1.0),
        }
    }

    fn pplastic() -> PPlastic {
        PPlastic {
            distribution: ggx(0.2, 0.35),
            eta: 1.49,
            diffuse_reflectance: Rgb::new(0.6, 0.3, 0.2),
            specular_reflectance: Rgb::new(0.9, 1.0, 1.0),
            specular_weight: 0.4,
        }
    }

    fn diffuse(r: f32) -> Diffuse {
        Diffuse {
            reflectance: Rgb::splat(r),
        }
    }

    fn polarizer(theta: f32) -> Polarizer {
        Polarizer {
            transmittance: Rgb::ONE,
            theta,
            polarizing: true,
        }
    }

    /// A frame tilted by `deg` about y and turned by `turn` about its normal.
    fn tilted_frame(deg: f32, turn: f32) -> Frame {
        let (a, b) = (deg.to_radians(), turn.to_radians());
        let n = Vec3::new(a.sin(), 0.0, a.cos());
        let s0 = Vec3::new(a.cos(), 0.0, -a.sin());
        let t0 = n.cross(s0);
        let s = s0 * b.cos() + t0 * b.sin();
        Frame {
            s,
            t: n.cross(s),
            n,
        }
    }

    fn perturbed(nested: Bsdf, frame: Frame) -> Bsdf {
        Bsdf::Perturbed(Perturbed {
            perturbation: crate::materials::Perturbation::NormalMap(
                crate::textures::Texture::Constant(Vec3::new(0.5, 0.5, 1.0)),
            ),
            flip_invalid_normals: true,
            use_shadowing_function: true,
            nested: Box::new(nested),
            frame,
        })
    }

    fn boxed(b: Bsdf) -> Box<Bsdf> {
        Box::new(b)
    }

    /// One model of every kind, and the wrappers around delta and non-delta models.
    fn models() -> Vec<(&'static str, Bsdf)> {
        let principled = Principled {
            spec_trans: 0.4,
            metallic: 0.3,
            roughness: 0.3,
            ..Principled::default()
        };
        vec![
            ("diffuse", Bsdf::Diffuse(diffuse(0.7))),
            (
                "plastic",
                Bsdf::Plastic(Plastic::new(1.49, Rgb::new(0.8, 0.3, 0.1), Rgb::ONE, false)),
            ),
            (
                "roughplastic",
                Bsdf::RoughPlastic(RoughPlastic::new(
                    beckmann(0.3),
                    1.5,
                    Rgb::new(0.2, 0.5, 0.8),
                    Rgb::ONE,
                    false,
                )),
            ),
            (
                "roughdielectric",
                Bsdf::RoughDielectric(RoughDielectric {
                    distribution: ggx(0.2, 0.2),
                    eta: 1.5,
                    specular_reflectance: Rgb::ONE,
                    specular_transmittance: Rgb::new(0.9, 1.0, 0.8),
                }),
            ),
            (
                "thindielectric",
                Bsdf::ThinDielectric(ThinDielectric {
                    eta: 1.5,
                    specular_reflectance: Rgb::new(0.7, 1.0, 1.0),
                    specular_transmittance: Rgb::new(0.9, 1.0, 1.0),
                }),
            ),
            ("principled", Bsdf::Principled(principled)),
            (
                "principledthin",
                Bsdf::PrincipledThin(PrincipledThin::default()),
            ),
            ("conductor", Bsdf::Conductor(gold())),
            (
                "roughconductor beckmann",
                Bsdf::RoughConductor(rough_gold(beckmann(0.25))),
            ),
            (
                "roughconductor ggx anisotropic",
                Bsdf::RoughConductor(rough_gold(ggx(0.1, 0.4))),
            ),
            ("dielectric 1.5", Bsdf::Dielectric(glass(1.5))),
            ("dielectric 0.7", Bsdf::Dielectric(glass(0.7))),
            ("pplastic", Bsdf::PPlastic(pplastic())),
            ("polarizer", Bsdf::Polarizer(polarizer(30.0))),
            (
                "polarizer not polarizing",
                Bsdf::Polarizer(Polarizer {
                    transmittance: Rgb::new(0.6, 0.7, 0.8),
                    theta: 10.0,
                    polarizing: false,
                }),
            ),
            (
                "retarder",
                Bsdf::Retarder(Retarder {
                    transmittance: Rgb::new(0.9, 0.8, 0.7),
                    theta: 20.0,
                    delta: 90.0,
                }),
            ),
            (
                "circular",
                Bsdf::Circular(Circular {
                    transmittance: Rgb::new(0.9, 0.8, 0.7),
                    left_handed: true,
                }),
            ),
            ("null", Bsdf::Null(Null)),
            (
                "twosided diffuse / roughconductor",
                Bsdf::TwoSided(TwoSided {
                    front: OneSided::Diffuse(diffuse(0.5)),
                    back: OneSided::RoughConductor(rough_gold(ggx(0.3, 0.1))),
                }),
            ),
            (
                "twosided conductor / pplastic",
                Bsdf::TwoSided(TwoSided {
                    front: OneSided::Conductor(gold()),
                    back: OneSided::PPlastic(pplastic()),
                }),
            ),
            (
                "mask dielectric",
                Bsdf::Mask(Mask {
                    opacity: 0.3,
                    nested: boxed(Bsdf::Dielectric(glass(1.5))),
                }),
            ),
            (
                "mask pplastic",
                Bsdf::Mask(Mask {
                    opacity: 0.6,
                    nested: boxed(Bsdf::PPlastic(pplastic())),
                }),
            ),
            (
                "blend diffuse conductor",
                Bsdf::Blend(Blend {
                    weight: 0.4,
                    first: boxed(Bsdf::Diffuse(diffuse(0.6))),
                    second: boxed(Bsdf::Conductor(gold())),
                }),
            ),
            (
                "blend roughconductor dielectric",
                Bsdf::Blend(Blend {
                    weight: 0.5,
                    first: boxed(Bsdf::RoughConductor(rough_gold(beckmann(0.2)))),
                    second: boxed(Bsdf::Dielectric(glass(1.5))),
                }),
            ),
            (
                "composed conductor diffuse",
                Bsdf::Composed(Composed {
                    weight: 0.3,
                    first: boxed(Bsdf::Conductor(gold())),
                    second: boxed(Bsdf::Diffuse(diffuse(0.4))),
                }),
            ),
            (
                "separable pplastic",
                Bsdf::Separable(Separable {
                    inner: boxed(Bsdf::PPlastic(pplastic())),
                    profile: TemporalProfile::Constant { delay: 1.0 },
                }),
            ),
            (
                "perturbed roughconductor",
                perturbed(
                    Bsdf::RoughConductor(rough_gold(ggx(0.1, 0.3))),
                    tilted_frame(20.0, 35.0),
                ),
            ),
            (
                "perturbed conductor",
                perturbed(Bsdf::Conductor(gold()), tilted_frame(15.0, -50.0)),
            ),
            (
                "perturbed dielectric",
                perturbed(Bsdf::Dielectric(glass(1.5)), tilted_frame(10.0, 70.0)),
            ),
        ]
    }

    fn sphere(rng: &mut Pcg32) -> Vec3 {
        let [u, v] = rng.next_2d();
        let z = 1.0 - 2.0 * u;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * std::f32::consts::PI * v;
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-5 * a.abs().max(b.abs()) + 1e-9
    }

    /// [0][0] of the matrix is the scalar value: `eval` for the non-delta lobes,
    /// `weight * pdf` of a delta sample, for every model, at random pairs.
    #[test]
    fn every_models_s0_element_is_its_scalar_value() {
        let mut rng = Pcg32::new(0x6d75656c, 7);
        for (name, b) in models() {
            let (mut evals, mut deltas) = (0, 0);
            for _ in 0..200 {
                let wo = sphere(&mut rng);
                let wi = sphere(&mut rng);
                let m = b.mueller_lane(wo, wi, None, 0);
                let e = b.eval(wo, wi).x;
                assert!(
                    close(m.x_axis.x, e),
                    "{name}: eval {e} vs M00 {} at wo {wo} wi {wi}",
                    m.x_axis.x
                );
                assert!(m.is_finite(), "{name}: {m}");
                evals += usize::from(e > 0.0);
                for k in 0..8 {
                    let u1 = (k as f32 + rng.next_f32()) / 8.0;
                    let Some(s) = b.sample(wo, u1, rng.next_2d()) else {
                        continue;
                    };
                    if !s.lobe.is_delta() {
                        continue;
                    }
                    let m = b.mueller_lane(wo, s.wi, Some(s.lobe), 0);
                    let want = s.weight.x * s.pdf;
                    assert!(
                        close(m.x_axis.x, want),
                        "{name}: {:?} weight * pdf {want} vs M00 {} at wo {wo} wi {}",
                        s.lobe,
                        m.x_axis.x,
                        s.wi
                    );
                    assert!(m.is_finite(), "{name}: {m}");
                    deltas += usize::from(want > 0.0);
                }
            }
            let flags = b.flags(Vec3::Z) | b.flags(-Vec3::Z);
            assert!(
                !flags.has_non_delta() || evals > 10,
                "{name}: {evals} evals"
            );
            assert!(
                !flags.intersects(BsdfFlags::DELTA) || deltas > 10,
                "{name}: {deltas} delta samples"
            );
        }
    }

    /// Textbook |r_s|^2 and |r_p|^2 for light from vacuum onto a medium of complex
    /// index `n` at incidence `theta` (Born and Wolf; the root with Im(n cos_t) >= 0).
    fn textbook(theta: f64, n: C64) -> (f64, f64) {
        let (sin, cos) = theta.sin_cos();
        let n_cos_t = (n * n - sin * sin).sqrt();
        let r_s = (cos - n_cos_t) / (cos + n_cos_t);
        let r_p = (n * n * cos - n_cos_t) / (n * n * cos + n_cos_t);
        (r_s.norm_sqr(), r_p.norm_sqr())
    }

    /// `m` (implicit bases) re-expressed with the s axis (y, normal to the xz plane of
    /// incidence) as the basis of both beams, applied to pure s and pure p light.
    fn s_and_p(m: Mat4, wo: Vec3, wi: Vec3) -> (f32, f32) {
        let sp = rotate_mueller_basis(
            m,
            -wi,
            stokes_basis(-wi),
            Vec3::Y,
            wo,
            stokes_basis(wo),
            Vec3::Y,
        );
        let s = sp * Vec4::new(1.0, 1.0, 0.0, 0.0);
        let p = sp * Vec4::new(1.0, -1.0, 0.0, 0.0);
        // Still s (p) polarized after reflection.
        assert!(
            (s.y - s.x).abs() < 1e-5 && s.z.abs() < 1e-5 && s.w.abs() < 1e-5,
            "{s}"
        );
        assert!(
            (p.y + p.x).abs() < 1e-5 && p.z.abs() < 1e-5 && p.w.abs() < 1e-5,
            "{p}"
        );
        (s.x, p.x)
    }

    #[test]
    fn fresnel_reflection_of_s_and_p_light_matches_the_textbook() {
        let eta = C64::new(0.2, 3.9);
        let metal = Conductor {
            eta: Rgb::splat(eta.re as f32),
            k: Rgb::splat(eta.im as f32),
            specular_reflectance: Rgb::ONE,
        };
        let glass = glass(1.5);
        let glass_plain = Dielectric {
            specular_reflectance: Rgb::ONE,
            specular_transmittance: Rgb::ONE,
            ..glass
        };
        for deg in [0.0f64, 30.0, 60.0, 80.0] {
            let th = deg.to_radians();
            // Seen from azimuths 0 and 180 degrees (the s axis is y either way).
            for side in [1.0f32, -1.0] {
                let wo = Vec3::new(side * th.sin() as f32, 0.0, th.cos() as f32);
                let wi = mirror(wo);
                let delta = Some(BsdfFlags::DELTA_REFLECTION);
                let (rs, rp) = textbook(th, eta);
                let (s, p) = s_and_p(metal.mueller_lane(wo, wi, delta, 0), wo, wi);
                assert!((s as f64 - rs).abs() < 2e-5, "{deg}: R_s {s} vs {rs}");
                assert!((p as f64 - rp).abs() < 2e-5, "{deg}: R_p {p} vs {rp}");
                let (rs, rp) = textbook(th, C64::new(1.5, 0.0));
                let (s, p) = s_and_p(glass_plain.mueller_lane(wo, wi, delta, 0), wo, wi);
                assert!((s as f64 - rs).abs() < 2e-6, "{deg}: R_s {s} vs {rs}");
                assert!((p as f64 - rp).abs() < 2e-6, "{deg}: R_p {p} vs {rp}");
                // Transmitted: T = 1 - R per component, times eta_ti^2 (radiance).
                let s_t = glass_plain.sample(wo, 0.9999, [0.5; 2]).unwrap();
                assert_eq!(s_t.lobe, BsdfFlags::DELTA_TRANSMISSION);
                let m = glass_plain.mueller_lane(wo, s_t.wi, Some(s_t.lobe), 0) * (1.5 * 1.5);
                let (s, p) = s_and_p(m, wo, s_t.wi);
                assert!((s as f64 - (1.0 - rs)).abs() < 1e-5, "{deg}: T_s {s}");
                assert!((p as f64 - (1.0 - rp)).abs() < 1e-5, "{deg}: T_p {p}");
            }
        }
    }

    #[test]
    fn malus_law_through_two_polarizers() {
        let unpolarized = Vec4::new(1.0, 0.0, 0.0, 0.0);
        for a in [0.0f32, 10.0, 45.0, 100.0] {
            for b in [0.0f32, 30.0, 60.0, 90.0, 135.0] {
                // Through a pane facing the camera and through one seen from behind.
                for wo in [Vec3::Z, -Vec3::Z] {
                    let d = Some(BsdfFlags::DELTA_TRANSMISSION);
                    let first = Bsdf::Polarizer(polarizer(a)).mueller_lane(wo, -wo, d, 0);
                    let second = Bsdf::Polarizer(polarizer(b)).mueller_lane(wo, -wo, d, 0);
                    let out = second * first * unpolarized;
                    let want = 0.5 * (a - b).to_radians().cos().powi(2);
                    assert!((out.x - want).abs() < 1e-6, "{a} {b}: {} vs {want}", out.x);
                }
            }
        }
        // Without `polarizing`: half of anything, its state kept.
        let mut p = polarizer(30.0);
        p.polarizing = false;
        let s = Vec4::new(1.0, 0.3, -0.2, 0.5);
        let m = p.mueller_lane(Vec3::Z, -Vec3::Z, Some(BsdfFlags::DELTA_TRANSMISSION), 0);
        assert!((m * s - 0.5 * s).abs().max_element() < 1e-7);
    }

    /// A quarter-wave plate at 45 degrees turns horizontal light (along the implicit
    /// basis, here x) into right circular light: S3 = +S0 in Mitsuba's convention
    /// (S3 > 0 right circular, the ellipse seen from the sensor).
    #[test]
    fn a_quarter_wave_retarder_at_45_degrees_makes_linear_light_circular() {
        let r = Retarder {
            transmittance: Rgb::ONE,
            theta: 45.0,
            delta: 90.0,
        };
        let d = Some(BsdfFlags::DELTA_TRANSMISSION);
        assert!((stokes_basis(Vec3::Z) - Vec3::X).length() < 1e-6);
        let horizontal = Vec4::new(1.0, 1.0, 0.0, 0.0);
        let out = r.mueller_lane(Vec3::Z, -Vec3::Z, d, 0) * horizontal;
        assert!(
            (out - Vec4::new(1.0, 0.0, 0.0, 1.0)).abs().max_element() < 1e-6,
            "{out}"
        );
        // From the back the angle flips (Mitsuba): left circular.
        let out = r.mueller_lane(-Vec3::Z, Vec3::Z, d, 0) * horizontal;
        assert!(
            (out - Vec4::new(1.0, 0.0, 0.0, -1.0)).abs().max_element() < 1e-6,
            "{out}"
        );
        // At 0 degrees the plate leaves horizontal light alone.
        let r0 = Retarder { theta: 0.0, ..r };
        let out = r0.mueller_lane(Vec3::Z, -Vec3::Z, d, 0) * horizontal;
        assert!((out - horizontal).abs().max_element() < 1e-6);
        // A circular polarizer passes half of unpolarized light, of its hand.
        let c = |left_handed| Circular {
            transmittance: Rgb::ONE,
            left_handed,
        };
        let unpolarized = Vec4::new(1.0, 0.0, 0.0, 0.0);
        let right = c(false).mueller_lane(Vec3::Z, -Vec3::Z, d, 0) * unpolarized;
        assert!((right - Vec4::new(0.5, 0.0, 0.0, 0.5)).abs().max_element() < 1e-7);
        let left = c(true).mueller_lane(Vec3::Z, -Vec3::Z, d, 0) * unpolarized;
        assert!((left - Vec4::new(0.5, 0.0, 0.0, -0.5)).abs().max_element() < 1e-7);
    }

    /// The same world geometry seen in two frames with the same normal and different
    /// tangents gives the same world matrix.
    #[test]
    fn world_matrices_do_not_depend_on_the_tangent() {
        let mut rng = Pcg32::new(0x7a11, 3);
        let n = Vec3::new(0.2, -0.5, 0.8).normalize();
        let frames = [
            Frame::from_normal(n),
            Frame::from_normal_tangent(n, Vec3::new(0.3, 0.9, 0.1)),
            Frame::from_normal_tangent(n, Vec3::new(-1.0, 0.2, 0.4)),
        ];
        let isotropic = [
            Bsdf::Conductor(gold()),
            Bsdf::RoughConductor(rough_gold(beckmann(0.3))),
            Bsdf::Dielectric(glass(1.5)),
            Bsdf::PPlastic(PPlastic {
                distribution: ggx(0.3, 0.3),
                ..pplastic()
            }),
        ];
        let mut compared = 0;
        for b in &isotropic {
            for _ in 0..50 {
                let wo_world = frames[0].to_world(sphere(&mut rng));
                let wo0 = frames[0].to_local(wo_world);
                let Some(s) = b.sample(wo0, rng.next_f32(), rng.next_2d()) else {
                    continue;
                };
                let wi_world = frames[0].to_world(s.wi);
                let delta = s.lobe.is_delta().then_some(s.lobe);
                let world: Vec<Mat4> = frames
                    .iter()
                    .map(|f| {
                        let (wo, wi) = (f.to_local(wo_world), f.to_local(wi_world));
                        to_world_mueller(f, b.mueller_lane(wo, wi, delta, 0), -wi, wo)
                    })
                    .collect();
                let scale = world[0]
                    .abs()
                    .to_cols_array()
                    .iter()
                    .fold(0.0f32, |a, &b| a.max(b));
                for w in &world[1..] {
                    assert!(
                        (*w - world[0])
                            .abs()
                            .to_cols_array()
                            .iter()
                            .all(|d| *d <= 1e-4 * scale),
                        "{b:?}: {w} vs {}",
                        world[0]
                    );
                }
                compared += usize::from(scale > 0.0);
            }
        }
        assert!(compared > 100, "{compared}");
        // And a conductor's world matrix does polarize (the test is not vacuous).
        let f = frames[1];
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let m = to_world_mueller(
            &f,
            gold().mueller_lane(wo, mirror(wo), Some(BsdfFlags::DELTA_REFLECTION), 0),
            -mirror(wo),
            wo,
        );
        assert!(m.x_axis.y.abs() > 1e-3);
    }

    /// A perturbed frame equal to the shading frame changes nothing; a turned one
    /// gives the nested matrix seen in the turned bases.
    #[test]
    fn an_identity_perturbation_keeps_the_nested_matrix() {
        let wo = Vec3::new(0.3, -0.4, 0.8).normalize();
        let wi = Vec3::new(-0.5, 0.1, 0.7).normalize();
        let nested = Bsdf::RoughConductor(rough_gold(beckmann(0.3)));
        let mut b = perturbed(nested.clone(), super::super::perturbed::IDENTITY);
        if let Bsdf::Perturbed(p) = &mut b {
            p.use_shadowing_function = false;
        }
        let (m, want) = (
            b.mueller_lane(wo, wi, None, 0),
            nested.mueller_lane(wo, wi, None, 0),
        );
        assert!(m.abs_diff_eq(want, 1e-6), "{m} vs {want}");
    }

    /// The scene reader: `retarder` and `circular` with their parameters, a
    /// polarizer's angle, and a textured angle (a retarder's) bound per hit.
    #[test]
    fn the_scene_reader_reads_the_polarization_plugins() {
        use crate::materials::material::Param;
        use crate::scene::{Overrides, Scene};
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let scene = Scene::load(&root.join("cbox_waveplates.xml"), &Overrides::default()).unwrap();
        let find = |f: &dyn Fn(&Bsdf) -> bool| scene.bsdfs.iter().any(|m| f(&m.bsdf));
        assert!(find(&|b| *b
            == Bsdf::Retarder(Retarder {
                transmittance: Rgb::splat(0.9),
                theta: 45.0,
                delta: 90.0,
            })));
        assert!(find(&|b| *b
            == Bsdf::Circular(Circular {
                transmittance: Rgb::splat(0.8),
                left_handed: true,
            })));
        let scene = Scene::load(&root.join("cbox_pplastic.xml"), &Overrides::default()).unwrap();
        assert!(scene.bsdfs.iter().any(|m| m.bsdf
            == Bsdf::Polarizer(Polarizer {
                transmittance: Rgb::splat(0.8),
                theta: 30.0,
                polarizing: true,
            })));
        // A textured angle: bound to Param::Theta and set per hit.
        let dir = tempfile::tempdir().unwrap();
        let xml = std::fs::read_to_string(root.join("cbox_waveplates.xml")).unwrap();
        let textured = r#"<texture type="checkerboard" name="theta"><float name="color0" value="10"/><float name="color1" value="50"/></texture>"#;
        let xml = xml.replace(r#"<float name="theta" value="45"/>"#, textured);
        let path = dir.path().join("s.xml");
        std::fs::write(&path, xml).unwrap();
        let scene = Scene::load(&path, &Overrides::default()).unwrap();
        let m = scene
            .bsdfs
            .iter()
            .find(|m| matches!(m.bsdf, Bsdf::Retarder(_)))
            .unwrap();
        assert_eq!(m.bindings.len(), 1);
        assert_eq!(m.bindings[0].param, Param::Theta);
    }
}
