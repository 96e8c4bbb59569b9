//! Lobe flags: which kinds of scattering a BSDF has (pbrt's `BxDFFlags`, Mitsuba's
//! `BSDFFlags`), a lobe type (diffuse / glossy / delta) crossed with a side (reflection
//! / transmission). The integrator decides next-event estimation and MIS from these,
//! never from the BSDF's type.

use std::ops::BitOr;

/// A set of lobes, as a bit set.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct BsdfFlags(u8);

impl BsdfFlags {
    pub const EMPTY: Self = Self(0);
    pub const DIFFUSE_REFLECTION: Self = Self(1);
    pub const DIFFUSE_TRANSMISSION: Self = Self(1 << 1);
    pub const GLOSSY_REFLECTION: Self = Self(1 << 2);
    pub const GLOSSY_TRANSMISSION: Self = Self(1 << 3);
    pub const DELTA_REFLECTION: Self = Self(1 << 4);
    pub const DELTA_TRANSMISSION: Self = Self(1 << 5);

    pub const DIFFUSE: Self = Self::DIFFUSE_REFLECTION.union(Self::DIFFUSE_TRANSMISSION);
    pub const GLOSSY: Self = Self::GLOSSY_REFLECTION.union(Self::GLOSSY_TRANSMISSION);
    pub const DELTA: Self = Self::DELTA_REFLECTION.union(Self::DELTA_TRANSMISSION);
    pub const REFLECTION: Self = Self::DIFFUSE_REFLECTION
        .union(Self::GLOSSY_REFLECTION)
        .union(Self::DELTA_REFLECTION);
    pub const TRANSMISSION: Self = Self::DIFFUSE_TRANSMISSION
        .union(Self::GLOSSY_TRANSMISSION)
        .union(Self::DELTA_TRANSMISSION);

    #[inline(always)]
    pub const fn union(self, other: Self) -> Self {
        Self(self.0 | other.0)
    }

    /// True when the sets share a lobe.
    #[inline(always)]
    pub const fn intersects(self, other: Self) -> bool {
        self.0 & other.0 != 0
    }

    /// True when every lobe of `other` is in `self`.
    #[inline(always)]
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    #[inline(always)]
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// True when some lobe has a density (diffuse or glossy): `eval` and `pdf` can be
    /// non-zero, so next-event estimation and MIS apply.
    #[inline(always)]
    pub const fn has_non_delta(self) -> bool {
        self.0 & !Self::DELTA.0 != 0
    }

    /// True when there are lobes and all are deltas (`eval` and `pdf` are zero
    /// everywhere; only `sample` finds the directions).
    #[inline(always)]
    pub const fn is_delta(self) -> bool {
        !self.is_empty() && !self.has_non_delta()
    }
}

impl BitOr for BsdfFlags {
    type Output = Self;
    #[inline(always)]
    fn bitor(self, rhs: Self) -> Self {
        self.union(rhs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_partition_the_lobes() {
        assert_eq!(BsdfFlags::DIFFUSE | BsdfFlags::GLOSSY | BsdfFlags::DELTA, {
            BsdfFlags::REFLECTION | BsdfFlags::TRANSMISSION
        });
        assert!(!BsdfFlags::REFLECTION.intersects(BsdfFlags::TRANSMISSION));
        assert!(BsdfFlags::DELTA.contains(BsdfFlags::DELTA_TRANSMISSION));
        let glass = BsdfFlags::DELTA_REFLECTION | BsdfFlags::DELTA_TRANSMISSION;
        assert!(glass.is_delta() && !glass.has_non_delta());
        let mixed = BsdfFlags::DELTA_REFLECTION | BsdfFlags::DIFFUSE_REFLECTION;
        assert!(!mixed.is_delta() && mixed.has_non_delta());
        assert!(!BsdfFlags::EMPTY.is_delta() && !BsdfFlags::EMPTY.has_non_delta());
    }
}
