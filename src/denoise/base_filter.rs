//! The base filter p of SPEC 8: a spatio-temporal Gaussian on pixel and bin offsets,
//! joint-bilateral on the G-buffers (albedo, normal) or plain Gaussian.
//!
//! `p_ij = exp(-0.5 * sum_k (f_ik - f_jk)^2 / sigma_k^2)`; the G-buffers are the same
//! for every bin of a pixel, so `p` factors into a pixel-pair part (offsets and
//! features, computed once per pair) and a bin-offset part (a table over dt).

/// Which base filter to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaseKind {
    /// Joint bilateral: offsets, albedo and normal.
    Jbf,
    /// Offsets only (media, or by choice).
    Gaussian,
}

/// Standard deviations of the base filter's features.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sigmas {
    /// Pixels, each of x and y (default sqrt(10)).
    pub xy: f64,
    /// Bins (default 1).
    pub t: f64,
    /// Per albedo channel (default sqrt(0.02)).
    pub albedo: f64,
    /// Per normal component (default sqrt(0.1)).
    pub normal: f64,
}

impl Default for Sigmas {
    fn default() -> Self {
        Sigmas {
            xy: 10f64.sqrt(),
            t: 1.0,
            albedo: 0.02f64.sqrt(),
            normal: 0.1f64.sqrt(),
        }
    }
}

impl Sigmas {
    pub fn validate(&self) -> Result<(), super::DenoiseError> {
        for (flag, value) in [
            ("--sigma-xy", self.xy),
            ("--sigma-t", self.t),
            ("--sigma-albedo", self.albedo),
            ("--sigma-normal", self.normal),
        ] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(super::DenoiseError::NotPositive { flag, value });
            }
        }
        Ok(())
    }
}

/// Per-pixel G-buffers, shared by all bins of the pixel. The base filter reads albedo
/// and normal; tstat's membership reads depth and emitter.
pub struct Features<'a> {
    /// (H, W, 3) row-major.
    pub albedo: &'a [f32],
    /// (H, W, 3) row-major.
    pub normal: &'a [f32],
    /// (H, W): mean camera distance to the first hit, 0 where nothing was hit.
    pub depth: &'a [f32],
    /// (H, W): fraction of samples whose first non-delta vertex is an emitter.
    pub emitter: &'a [f32],
}

#[derive(Clone, Copy, Debug)]
pub struct BaseFilter {
    pub kind: BaseKind,
    pub sigmas: Sigmas,
}

impl BaseFilter {
    /// The pixel-pair part of p for pixels `j` and `i` at offset (dy, dx).
    #[inline]
    pub fn pair_weight(&self, f: &Features, j: usize, i: usize, dy: i64, dx: i64) -> f64 {
        let s = &self.sigmas;
        let mut e = (dx * dx + dy * dy) as f64 / (s.xy * s.xy);
        if self.kind == BaseKind::Jbf {
            let (mut da, mut dn) = (0.0f64, 0.0f64);
            for c in 0..3 {
                let a = f.albedo[i * 3 + c] as f64 - f.albedo[j * 3 + c] as f64;
                let n = f.normal[i * 3 + c] as f64 - f.normal[j * 3 + c] as f64;
                da += a * a;
                dn += n * n;
            }
            e += da / (s.albedo * s.albedo) + dn / (s.normal * s.normal);
        }
        (-0.5 * e).exp()
    }

    /// The bin-offset part of p for dt in -r_t..=r_t (index dt + r_t).
    pub fn time_weights(&self, r_t: usize) -> Vec<f64> {
        (-(r_t as i64)..=r_t as i64)
            .map(|dt| (-0.5 * (dt * dt) as f64 / (self.sigmas.t * self.sigmas.t)).exp())
            .collect()
    }
}
