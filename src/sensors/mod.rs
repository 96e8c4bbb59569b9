//! What records the light: the camera models (`camera.rs`: perspective, thin lens,
//! orthographic rays and where their OPL starts), the film's time axis (`film.rs`) and
//! mitransient's temporal filter over it (`time_filter.rs`). Their XML readers live in
//! `scene/` (`sensors.rs`, `film.rs`, `integrator.rs`).

pub mod camera;
pub mod film;
pub mod relay_wall;
pub mod time_axis;
pub mod time_filter;
pub mod time_origin;
