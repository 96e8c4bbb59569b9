//! What follows an NLOS capture's render (SPEC 11): its export to y-tal's HDF5 capture
//! format (`tal.rs`). Rendering the capture is `scene/nlos.rs` and `render/nlos.rs`;
//! the bundle records its geometry (`bundle/capture.rs`).

pub mod tal;
