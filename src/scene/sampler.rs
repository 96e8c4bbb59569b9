//! `<sampler>`: the sample count and the seed (every Mitsuba sampler type is read as
//! tstat's own sampler with that count).

use super::ctx::Ctx;
use super::error::SceneError;
use super::props::Props;
use roxmltree::Node;

/// A `<sampler>`: its sample count and seed (defaults 4 and 0).
/// The sampler plugins (the plugin table's `sampler` family): all read here.
pub(super) const SAMPLERS: &[&str] = &[
    "independent",
    "stratified",
    "multijitter",
    "orthogonal",
    "ldsampler",
];

pub(super) fn parse_sampler(ctx: &Ctx, obj: Node) -> Result<(u32, u64), SceneError> {
    let (mut spp, mut seed) = (4u32, 0u64);
    // The sampler type only decides whether the scene loads: sub-pixel
    // positions are chosen by `--pixel-sampling` (default stratified), and
    // every other dimension of a path is always independent. Mitsuba's
    // stratified-like samplers are accepted as plain requests for spp/seed.
    let k = ctx.required_attr(obj, "type")?;
    if !SAMPLERS.contains(&k.as_str()) {
        return Err(ctx.err(obj, format!("sampler '{k}' is not supported (use independent; sub-pixel positions are set by --pixel-sampling)")));
    }
    let mut sp = Props::parse(ctx, obj)?;
    if k != "independent" {
        sp.ignore("jitter");
        sp.ignore("strength");
    }
    if let Some(n) = sp.integer("sample_count")? {
        if !(0..=u32::MAX as i64).contains(&n) {
            return Err(sp.err_at("sample_count", format!("sample_count {n} is out of range")));
        }
        spp = n as u32;
    }
    if let Some(s) = sp.integer("seed")? {
        seed = u64::try_from(s)
            .map_err(|_| sp.err_at("seed", format!("seed must be non-negative, got {s}")))?;
    }
    sp.finish()?;
    Ok((spp, seed))
}
