//! Pictures for people: tone-mapped frames with one global exposure, GIF animations,
//! streak images, maximum-intensity projections of NLOS reconstructions.

pub mod frames;
pub mod mip;
pub mod tonemap;
pub mod view;
