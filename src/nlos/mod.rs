//! What follows an NLOS capture's render (SPEC 11): its export to y-tal's HDF5 capture
//! format (`tal.rs`), the capture in memory in y-tal's terms (`capture.rs`, from a
//! bundle or a y-tal file) and reconstructions of the hidden scene (`bp.rs`, with the phasor-field filter of the
//! filtered backprojection in `filter.rs`; the wave-based confocal ones, f-k migration
//! in `fk.rs` and the light-cone transform in `lct.rs`, on the native grid of `wave.rs`).
//! Rendering the capture is `scene/nlos.rs` and `render/nlos.rs`; the bundle records its
//! geometry (`bundle/capture.rs`).

pub mod bp;
pub mod capture;
pub mod denoised;
pub mod filter;
pub mod fk;
pub mod lct;
pub mod pf;
pub mod reconstruct;
pub mod tal;
pub mod wave;
