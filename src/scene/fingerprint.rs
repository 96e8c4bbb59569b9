//! `Scene::fingerprint`: one hash of everything a loaded scene's image depends on, for
//! every cache keyed by a scene (today `report convergence`'s reference renders).
//!
//! A loaded scene is a deterministic function of the scene file's bytes, the bytes of
//! every file it read (includes, meshes, images, volumes, spectra: `Scene::identity`),
//! the command line's overrides (the `-D` values, also in the identity; film size, time
//! axis and depth, which end up in `film` and `integrator`; the render mode) and the
//! program. So the
//! fingerprint hashes those, plus the camera as loaded (belt and braces: it is already
//! a function of the above), and the tstat version.

use super::Scene;
use sha2::{Digest, Sha256};

impl Scene {
    /// Hex SHA-256 of what the scene's image depends on (see the module docs).
    pub fn fingerprint(&self) -> String {
        let mut h = Sha256::new();
        let mut part = |label: &str, text: &str| {
            h.update(label.as_bytes());
            h.update((text.len() as u64).to_le_bytes());
            h.update(text.as_bytes());
        };
        part("program", env!("CARGO_PKG_VERSION"));
        part("scene", &self.sha256);
        for (name, sha) in &self.identity.inputs {
            part("input", &format!("{name}\0{sha}"));
        }
        for (k, v) in &self.identity.defaults {
            part("define", &format!("{k}\0{v}"));
        }
        part("film", &format!("{:?}", self.film));
        part("camera", &format!("{:?}", self.camera));
        part("integrator", &format!("{:?}", self.integrator));
        part("spp", &self.spp.to_string());
        // The render mode changes the image (a spectral render's film has RGB's three
        // channels); left out for RGB, so that RGB keys stay what they were.
        if self.mode != super::mode::RenderMode::Rgb {
            part("mode", self.mode.name());
        }
        format!("{:x}", h.finalize())
    }
}
