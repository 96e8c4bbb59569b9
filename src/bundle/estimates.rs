//! The per-voxel estimates of SPEC 5 for a whole bundle: the skewness-corrected mean
//! `theta` and the variance of the estimate `V = sigma2 / n`, in the domain of the
//! bundle's transform (linear radiance for the identity; the published pipeline's
//! "estimand" and "estimand_variance" for Yeo-Johnson 0.5), each pixel with its own
//! sample count.
//!
//! Memory: the three f64 sum arrays are read whole (24 bytes a voxel) plus the two f32
//! outputs (8 bytes a voxel).

use super::read::{Bundle, SumArray};
use super::BundleError;
use crate::stats::estimators::{estimate, Sums};
use ndarray::Array4;

/// `theta` and `V` per voxel, f32 (H, W, T, C).
pub struct Estimates {
    pub theta: Array4<f32>,
    pub variance: Array4<f32>,
}

impl Bundle {
    /// [`estimate`] at every voxel and channel (see the module docs).
    pub fn estimates(&self) -> Result<Estimates, BundleError> {
        let m = &self.manifest;
        let counts = self.nonzero()?;
        let [x1, x2, x3] =
            [SumArray::X1, SumArray::X2, SumArray::X3].map(|w| self.sum_array(w, &counts));
        let (x1, x2, x3) = (x1?, x2?, x3?);
        let z0 = m.transform.at_zero();
        let shape = x1.raw_dim();
        let mut theta = Array4::<f32>::zeros(shape);
        let mut variance = Array4::<f32>::zeros(shape);
        let channels = m.channel_count();
        let per_pixel = m.bins * channels;
        let slices = [&x1, &x2, &x3].map(|a| a.as_slice().expect("standard layout"));
        let counts = counts.as_slice().expect("standard layout");
        let out_t = theta.as_slice_mut().expect("standard layout");
        let out_v = variance.as_slice_mut().expect("standard layout");
        for (i, (t, v)) in out_t.iter_mut().zip(out_v.iter_mut()).enumerate() {
            let sums = Sums {
                x1: slices[0][i],
                x2: slices[1][i],
                x3: slices[2][i],
            };
            let e = estimate(sums, counts[i / channels], self.samples(i / per_pixel), z0);
            (*t, *v) = (e.theta as f32, e.v as f32);
        }
        Ok(Estimates { theta, variance })
    }
}
