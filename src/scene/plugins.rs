//! The plugin table: every plugin type tstat reads, by element tag. The loader and
//! `tstat check` both read it, so a plugin is supported exactly when it is listed here.

use super::table::names;
use std::sync::LazyLock;

/// The plugin types of the family of elements `tag` (empty for an unknown tag).
pub fn family(tag: &str) -> Vec<&'static str> {
    SUPPORTED
        .iter()
        .find(|(t, _)| *t == tag)
        .map(|(_, types)| types.clone())
        .unwrap_or_default()
}

/// Plugin types each loader accepts, by element tag: each family's names come from the
/// table its reader dispatches on.
pub static SUPPORTED: LazyLock<Vec<(&str, Vec<&str>)>> = LazyLock::new(|| {
    let mut families = vec![
        ("bsdf", names(super::bsdfs::BSDFS)),
        ("shape", {
            let mut shapes = names(super::shapes::SHAPES);
            shapes.extend(super::shapes::GROUPING);
            shapes
        }),
    ];
    let emitters: Vec<&str> = super::emitters::AREA_KINDS
        .iter()
        .chain(super::emitters::POINT_KINDS)
        .chain([&super::projector::PROJECTOR])
        .chain(super::infinite_emitters::KINDS)
        .copied()
        .collect();
    let mut sensors = super::sensors::CAMERAS.to_vec();
    sensors.push(super::sensors::METER);
    families.extend([
        ("texture", names(super::textures::TEXTURES)),
        ("emitter", emitters),
        ("sensor", sensors),
        ("film", super::film::FILMS.to_vec()),
        ("sampler", super::sampler::SAMPLERS.to_vec()),
        ("rfilter", super::film::RFILTERS.to_vec()),
        ("integrator", super::integrator::INTEGRATORS.to_vec()),
        ("TemporalProfile", super::bsdfs::PROFILES.to_vec()),
        ("medium", super::media::MEDIA.to_vec()),
        ("volume", names(super::media::VOLUMES)),
        ("phase", names(super::media::PHASES)),
        ("spectrum", super::props::SPECTRA.to_vec()),
    ]);
    families
});

/// A plugin type as the loaders spell it: a supported plugin's name written in
/// another case ("Rectangle", "separable") becomes its spelling in [`SUPPORTED`], as
/// Mitsuba finds plugins on Windows and macOS, whose file systems ignore case; any
/// other name stays as written.
pub fn canonical_plugin_name(name: String) -> String {
    SUPPORTED
        .iter()
        .flat_map(|(_, types)| types.iter())
        .find(|t| t.eq_ignore_ascii_case(&name))
        .map_or(name, |t| t.to_string())
}
