//! The integration tests: one binary of modules, a file per concern (one link of the
//! library instead of one per file). `tests/sampling/` is its own binary: one
//! Bonferroni family over every BSDF, phase function and emitter.

mod common;
mod tal_common;

mod adaptive;
mod channels;
mod cli;
mod curves;
mod delays;
mod denoise;
mod denoise_arrays;
mod denoise_tstat;
mod dense_scene;
mod eval_pdf;
mod fingerprint;
mod fuzz;
mod fuzz_manifest;
mod fuzz_tal;
mod hostile_bundle;
mod hostile_cli;
mod hostile_cluster;
mod hostile_manifest;
mod hostile_scene;
mod hostile_tal;
mod hostile_volumes;
mod imports;
mod infinite_emitters;
mod instancing;
mod isa;
mod job;
mod jpeg;
mod media;
mod media_boundaries;
mod nlos;
mod nlos_convergence;
mod nlos_wave;
mod path_loop;
mod pixel_sampling;
mod polarization;
mod polarized_render;
mod render_physics;
mod report;
mod scene_compat;
mod sdfgrid;
mod sensors;
mod serialized;
mod shard;
mod sobol_sampling;
mod spectral;
mod spectral_polarized;
mod spectral_render;
mod stream_render;
mod textured;
mod view;
