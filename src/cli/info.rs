//! `tstat info NAME.tstats`: the manifest in a readable form.

use crate::bundle::manifest::SamplingRecord;
use crate::bundle::Bundle;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// A statistics bundle directory.
    pub bundle: PathBuf,
}

pub fn run(a: InfoArgs) -> anyhow::Result<()> {
    let b = Bundle::open(&a.bundle)?;
    let m = &b.manifest;
    say!("bundle      {}", a.bundle.display());
    say!(
        "format      {} v{} (written by {} {})",
        m.format,
        m.version,
        m.program.name,
        m.program.version
    );
    say!("scene       {} (sha256 {})", m.scene.path, m.scene.sha256);
    say!(
        "film        {} x {} px, {} bins, channels {} ({})",
        m.width,
        m.height,
        m.bins,
        m.channels.join(","),
        match m.mode {
            crate::scene::mode::RenderMode::Rgb => "rgb paths",
            crate::scene::mode::RenderMode::Spectral =>
                "spectral paths: each sample a path's linear sRGB, may be negative",
            crate::scene::mode::RenderMode::Mono => "mono paths: the luminance of every colour",
            crate::scene::mode::RenderMode::MonoPolarized =>
                "mono polarized paths: Stokes S0..S3 in the sensor's frame, S1..S3 signed",
            crate::scene::mode::RenderMode::SpectralPolarized =>
                "spectral polarized paths: Stokes S0..S3 of each linear sRGB channel in the sensor's frame, signed",
        }
    );
    say!(
        "time axis   start {} OPL, bin width {} OPL ({:.4} ps per bin at {} m/unit)",
        m.start_opl,
        m.bin_width_opl,
        m.bin_width_seconds * 1e12,
        m.unit_m
    );
    say!(
        "time origin {}: OPL counts from {}{}",
        m.time_origin.name(),
        m.time_zero(),
        m.near_clip.map_or(String::new(), |d| format!(
            ", {d} in front of the camera (as mitransient)"
        ))
    );
    say!(
        "samples     {} spp, seed {}, max_depth {}",
        m.spp,
        m.seed,
        m.max_depth
    );
    if let Some(a) = &m.adaptive {
        say!(
            "adaptive    {} spp on average, {} to {} per pixel (pixel_spp.npy), allocated to minimise {} from a {}-spp pilot ({:.2} s, not in the sums)",
            m.spp,
            a.min_spp,
            a.max_spp,
            a.measure.name(),
            a.pilot_spp,
            a.pilot_seconds
        );
    }
    if !m.merged_seeds.is_empty() {
        say!("merged      from renders with seeds {:?}", m.merged_seeds);
    }
    if let Some(s) = &m.shard {
        let held = if s.indices.len() as u64 == s.count {
            format!("all {} shards", s.count)
        } else if s.indices.len() == 1 {
            format!("shard {} of {}", s.indices[0], s.count)
        } else {
            format!("shards {:?} of {}", s.indices, s.count)
        };
        say!("job         {} ({held})", s.job);
    }
    say!("transform   {}", m.transform);
    say!(
        "pixels      {} sub-pixel sampling{}",
        m.pixel_sampling,
        match m.pixel_sampling {
            _ if m.replicates.is_some() => "",
            SamplingRecord::Independent => "",
            SamplingRecord::Stratified | SamplingRecord::Sobol if !m.merged_seeds.is_empty() => {
                " (per merged render; variances are over-estimates)"
            }
            _ => " (variances are over-estimates)",
        }
    );
    if let Some(b) = m.replicates {
        say!(
            "replicates  {b} of {} samples per pixel (variances from the replicates, {} degrees of freedom)",
            m.spp / b,
            b - 1
        );
    }
    if let Some(n) = &m.nlos {
        let [sx, sy] = n.sensor_grid;
        let [lx, ly] = n.laser_grid;
        let p = |v: [f64; 3]| format!("({}, {}, {})", v[0], v[1], v[2]);
        let lasers = if lx * ly > 1 {
            format!(" under each of {lx} x {ly} laser points (one image each, stacked)")
        } else {
            String::new()
        };
        say!(
            "nlos        {} capture: {sx} x {sy} relay-wall points{lasers}; sensor at {}, laser at {}; times {} the sensor and laser segments",
            n.capture.name(),
            p(n.sensor_origin),
            n.laser_origin.map_or("(none)".to_string(), p),
            if n.account_first_and_last_bounces { "include" } else { "exclude" }
        );
    }
    say!(
        "render      {:.3} s, {} non-finite contributions dropped",
        m.render_seconds,
        m.dropped_nonfinite
    );
    say!("arrays");
    for arr in &m.arrays {
        say!(
            "  {:<8} {:<12} {} {:?}",
            arr.name,
            arr.file,
            arr.dtype,
            arr.shape
        );
    }
    Ok(())
}
