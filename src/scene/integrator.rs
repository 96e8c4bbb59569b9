//! `<integrator>` (transient_path, transient_prbvolpath, transient_nlos_path): the
//! path settings and the time window's legacy spellings.

use super::ctx::Ctx;
use super::error::SceneError;
use super::props::Props;
use super::IntegratorSettings;
use crate::sensors::film::check_bin_width;
use crate::sensors::time_filter::{TimeFilter, DEFAULT_STDDEV_BINS};
use roxmltree::Node;

/// The widest temporal Gaussian accepted, in bins: each contribution visits at most
/// 8 stddev + 1 bins.
pub(super) const MAX_STDDEV_BINS: f64 = 64.0;

/// `max_depth` of a `transient_path` / `transient_prbvolpath` that does not set it.
pub const MITRANSIENT_DEFAULT_MAX_DEPTH: i64 = 6;

/// The integrator plugins (the plugin table's `integrator` family): all read here.
pub(super) const INTEGRATORS: &[&str] = &[
    "transient_path",
    "transient_prbvolpath",
    "transient_nlos_path",
];

pub(super) fn parse_integrator(ctx: &Ctx, node: Node) -> Result<IntegratorSettings, SceneError> {
    let kind = ctx.required_attr(node, "type")?;
    if !INTEGRATORS.contains(&kind.as_str()) {
        return Err(ctx.err(
            node,
            format!("integrator '{kind}' is not supported (use transient_path, transient_prbvolpath for media, or transient_nlos_path for NLOS captures)"),
        ));
    }
    let mut p = Props::parse(ctx, node)?;
    let d = IntegratorSettings::default();
    // mitransient 1.3.1's integrators take Mitsuba's `ad` integrators' default,
    // `props.get('max_depth', 6)`, for both names (a scene without an <integrator>
    // keeps -1, as Mitsuba's default `path`).
    let max_depth = p
        .integer("max_depth")?
        .unwrap_or(MITRANSIENT_DEFAULT_MAX_DEPTH);
    if max_depth < -1 || max_depth > i32::MAX as i64 {
        return Err(p.err_at(
            "max_depth",
            format!("max_depth must be -1 or >= 0, got {max_depth}"),
        ));
    }
    let rr_depth = p.integer("rr_depth")?.unwrap_or(d.rr_depth as i64);
    if rr_depth <= 0 || rr_depth > u32::MAX as i64 {
        return Err(p.err_at(
            "rr_depth",
            format!("rr_depth must be positive, got {rr_depth}"),
        ));
    }
    // mitransient's time filter (mitransient 1.3.1 reads `temporal_filter` and
    // `gaussian_stddev` but bins every contribution as the box; its earlier versions,
    // whose scenes set them, splat with the Gaussian: tstat does).
    let time_filter = match p.string("temporal_filter")?.as_deref() {
        None | Some("" | "box") => {
            p.ignore("gaussian_stddev");
            TimeFilter::Box
        }
        Some("gaussian") => {
            let sd = p.float_or("gaussian_stddev", DEFAULT_STDDEV_BINS)?;
            if !(sd > 0.0 && sd <= MAX_STDDEV_BINS) {
                return Err(p.err_at(
                    "gaussian_stddev",
                    format!("gaussian_stddev must be positive and at most {MAX_STDDEV_BINS} bins, got {sd}"),
                ));
            }
            TimeFilter::gaussian(sd)
        }
        Some(other) => {
            return Err(p.err_at(
                "temporal_filter",
                format!("temporal_filter '{other}' is not one of: box, gaussian"),
            ))
        }
    };
    legacy_time_window(&mut p)?;
    // Mitsuba's samples per rendering pass: no effect on what is computed.
    p.ignore("samples_per_pass");
    let nlos = if kind == "transient_nlos_path" {
        if p.peek("camera_unwarp").is_some() && p.boolean_or("camera_unwarp", false)? {
            return Err(p.err_at("camera_unwarp", "transient_nlos_path does not take camera_unwarp (as mitransient 1.3.1): use account_first_and_last_bounces"));
        }
        Some(super::nlos_setup::parse_settings(&mut p, max_depth)?)
    } else {
        None
    };
    let s = IntegratorSettings {
        max_depth: max_depth as i32,
        rr_depth: rr_depth as u32,
        // mitransient's `discard_direct_light` drops emission found by BSDF
        // sampling; of that, only the emitters seen from the camera are direct light
        // (later vertices' emitter hits are the BSDF half of MIS, which mitransient
        // 1.3.1 also drops, losing energy): tstat hides the directly visible emitters.
        hide_emitters: p.boolean_or("hide_emitters", false)?
            | p.boolean_or("discard_direct_light", false)?,
        camera_unwarp: p.boolean_or("camera_unwarp", false)?,
        volumetric: kind == "transient_prbvolpath",
        time_filter,
        nlos,
    };
    if let Some(&obj) = p.objects.first() {
        return Err(ctx.err(obj, "unexpected nested element in <integrator>"));
    }
    p.finish()?;
    Ok(s)
}

/// mitransient before 1.0 held the time window in the integrator: `temporal_bins`
/// (default 128), `exposure` (the bin width in OPL, default 3.5) and `initial_time`
/// (the window's start in bins, default 0: a sample of OPL d falls in bin
/// d / exposure - initial_time), and `progressive`, how fast its Gaussian time filter
/// narrowed from pass to pass. Scenes written for it also carry a
/// `transient_hdr_film` (the film mitransient 1.x reads), whose window tstat uses: the
/// old one is checked and named in a warning, never silently mixed in.
pub(super) fn legacy_time_window(p: &mut Props) -> Result<(), SceneError> {
    let bins = p.integer("temporal_bins")?;
    let exposure = p.float("exposure")?;
    let initial = p.float("initial_time")?;
    if let Some(b) = bins {
        if b <= 0 {
            return Err(p.err_at(
                "temporal_bins",
                format!("temporal_bins must be positive, got {b}"),
            ));
        }
    }
    if let Some(e) = exposure {
        check_bin_width("exposure (the bin width of mitransient before 1.0)", e)
            .map_err(|e| p.err_at("exposure", e.to_string()))?;
    }
    if let Some(t) = initial {
        if !t.is_finite() {
            return Err(p.err_at(
                "initial_time",
                format!("initial_time must be finite, got {t}"),
            ));
        }
    }
    if let Some(r) = p.float("progressive")? {
        if !(r >= 0.0 && r.is_finite()) {
            return Err(p.err_at("progressive", format!("progressive must be >= 0, got {r}")));
        }
    }
    if bins.is_some() || exposure.is_some() || initial.is_some() {
        let (b, e, t) = (
            bins.unwrap_or(128),
            exposure.unwrap_or(3.5),
            initial.unwrap_or(0.0),
        );
        let name = ["temporal_bins", "exposure", "initial_time"]
            .into_iter()
            .zip([bins.is_some(), exposure.is_some(), initial.is_some()])
            .find(|(_, given)| *given)
            .map_or("exposure", |(n, _)| n);
        p.warn_at(
            name,
            format!(
                "temporal_bins/exposure/initial_time are the time window of mitransient before 1.0 ({b} bins of {e} OPL from {}); the transient_hdr_film's window is used",
                t * e
            ),
        );
    }
    Ok(())
}
