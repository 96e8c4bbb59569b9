//! Pictures for people: tone-mapped frames with one global exposure, GIF animations,
//! streak images.

pub mod frames;
pub mod tonemap;
pub mod view;
