//! What the polarizing panes (`polarizer`, `retarder`, `circular`) share without
//! polarization: light passes straight through (`wi = -wo`, a delta transmission, IOR 1)
//! with a fixed weight, as Mitsuba's unpolarized variants do. As `null` in Mitsuba's
//! `path` integrator, the crossing is a vertex of the path (it counts towards
//! `max_depth`) and shadow rays are blocked by the surface. Their polarized behaviour
//! is in `mueller.rs`.

/// Implements `BsdfModel` for a pane type whose unpolarized weight is `$weight(self)`.
macro_rules! straight_through_pane {
    ($t:ty, $weight:expr) => {
        impl $crate::materials::BsdfModel for $t {
            #[inline]
            fn flags(&self, _wo: glam::Vec3) -> $crate::materials::BsdfFlags {
                $crate::materials::BsdfFlags::DELTA_TRANSMISSION
            }

            #[inline]
            fn eval(&self, _wo: glam::Vec3, _wi: glam::Vec3) -> $crate::math::Rgb {
                $crate::math::Rgb::ZERO
            }

            #[inline]
            fn pdf(&self, _wo: glam::Vec3, _wi: glam::Vec3) -> f32 {
                0.0
            }

            #[inline]
            fn sample(
                &self,
                wo: glam::Vec3,
                _u1: f32,
                _u2: [f32; 2],
            ) -> Option<$crate::materials::BsdfSample> {
                Some($crate::materials::BsdfSample {
                    wi: -wo,
                    weight: ($weight)(self),
                    pdf: 1.0,
                    lobe: $crate::materials::BsdfFlags::DELTA_TRANSMISSION,
                    eta: 1.0,
                })
            }

            fn albedo(&self, _wo: glam::Vec3) -> $crate::math::Rgb {
                ($weight)(self)
            }
        }
    };
}

pub(super) use straight_through_pane;
