//! Why a shape's geometry cannot be built from its parameters: the message names the
//! shape and the offending value (the scene reader adds the file, line and element).

/// A shape whose map or values cannot make single-precision geometry.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GeometryError {
    /// A disk whose `to_world` is singular or whose area overflows.
    #[error("the disk's to_world is singular or too large (area {area:e})")]
    DiskMap { area: f64 },
    /// A cylinder of zero, infinite or below-single-precision size.
    #[error(
        "the cylinder's radius {radius:e} or length {length:e} is zero, not finite or beyond single precision"
    )]
    CylinderSize { radius: f64, length: f64 },
    /// A cylinder map that does not scale its cross-section uniformly or shears it.
    #[error(
        "a cylinder's to_world must scale its cross-section uniformly, without shear (Mitsuba warns and then uses a wrong area)"
    )]
    CylinderShear,
    /// An SDF grid with fewer than 2 values along some axis.
    #[error(
        "the grid is {} x {} x {} values: an SDF grid needs at least 2 along each axis",
        .res[0], .res[1], .res[2]
    )]
    SdfGridTooSmall { res: [usize; 3] },
    /// An SDF grid whose value count is not the product of its sizes.
    #[error("{values} values for a {} x {} x {} grid", .res[0], .res[1], .res[2])]
    SdfGridValueCount { values: usize, res: [usize; 3] },
    /// An SDF grid of more voxels than 32-bit indices address.
    #[error(
        "the grid has {voxels} voxels, more than 2^32 - 1 (Mitsuba's voxel indices are 32-bit)"
    )]
    SdfGridTooManyVoxels { voxels: u128 },
    /// A NaN or infinite SDF value (index `index`, at grid point `at`).
    #[error(
        "value {index} (x {}, y {}, z {}) is {value}: an SDF grid needs finite values",
        .at[0], .at[1], .at[2]
    )]
    SdfGridNonFinite {
        index: usize,
        at: [usize; 3],
        value: f32,
    },
    /// An SDF grid without a voxel whose corners change sign.
    #[error(
        "the SDF has no zero crossing: no voxel has corners of both signs (Mitsuba: \"SDFGrid should at least have one non-empty voxel\")"
    )]
    SdfGridEmpty,
    /// An SDF grid's `to_world` that is singular or not finite.
    #[error("the sdfgrid's to_world is singular or not finite (determinant {determinant:e})")]
    SdfMap { determinant: f64 },
    /// An SDF grid's `to_world` whose inverse overflows.
    #[error("the sdfgrid's to_world cannot be inverted in finite numbers")]
    SdfMapInverse,
}
