//! `transient_hdr_film` (mitransient's names): image size and the time axis.
//!
//! | parameter | type | default | meaning |
//! |-----------|------|---------|---------|
//! | width, height | integer | 768, 576 | image size in pixels |
//! | temporal_bins | integer | required | number of time bins T |
//! | start_opl | float | 0 | OPL of the start of bin 0 (t0, scene units) |
//! | bin_width_opl | float | required | bin width h in OPL (scene units) |
//! | rfilter | nested | box | only `box` (mitransient's transient block supports only it) |
//! | exhaustive_scan, laser_scan_width, laser_scan_height | boolean, integer | false, 0 | an `nlos_capture_meter`'s exhaustive laser grid (`nlos.rs`) |
//!
//! A contribution with path OPL `o` lands in bin `k = floor((o - t0) / h)` when
//! `0 <= k < T` and in no bin otherwise (it still counts in the steady image).

use super::error::SceneError;
use super::props::{Ctx, Props};
use roxmltree::Node;

#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: usize,
    pub height: usize,
    pub bins: usize,
    /// t0, OPL in scene units.
    pub start_opl: f64,
    /// h, OPL in scene units.
    pub bin_width_opl: f64,
}

impl Film {
    /// Time bin of a contribution arriving at optical path length `opl`.
    #[inline]
    pub fn bin(&self, opl: f64) -> Option<u32> {
        let k = ((opl - self.start_opl) / self.bin_width_opl).floor();
        if k >= 0.0 && k < self.bins as f64 {
            Some(k as u32)
        } else {
            None
        }
    }

    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// Checks the settings after overrides were applied.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!("film size {}x{} is empty", self.width, self.height));
        }
        if self.bins == 0 {
            return Err("temporal_bins must be at least 1".into());
        }
        // Every later size computation (sums, G-buffers, bytes) stays within usize.
        let bytes = [self.height, self.bins, 3, 8, 4]
            .iter()
            .try_fold(self.width, |n, &f| n.checked_mul(f));
        if bytes.is_none() {
            return Err(format!(
                "a film of {}x{} px and {} bins is too large to address",
                self.width, self.height, self.bins
            ));
        }
        if self.bins > u32::MAX as usize {
            return Err(format!(
                "temporal_bins {} is above the largest supported count {}",
                self.bins,
                u32::MAX
            ));
        }
        if !(self.bin_width_opl > 0.0 && self.bin_width_opl.is_finite()) {
            return Err(format!(
                "bin_width_opl must be positive, got {}",
                self.bin_width_opl
            ));
        }
        if !self.start_opl.is_finite() {
            return Err(format!("start_opl must be finite, got {}", self.start_opl));
        }
        // The window's end must be a number, and a bin must be wider than the f64
        // spacing of the OPLs it holds (else bins merge: k = floor((opl - t0) / h)).
        let end = self.start_opl + self.bins as f64 * self.bin_width_opl;
        if !end.is_finite() {
            return Err(format!(
                "the time window ends beyond the floating-point range: start_opl {:e} + {} bins x {:e}",
                self.start_opl, self.bins, self.bin_width_opl
            ));
        }
        let scale = self.start_opl.abs().max(end.abs());
        if self.bin_width_opl < scale * 1e-12 {
            return Err(format!(
                "bin_width_opl {:e} is too narrow to resolve OPLs near {scale:e} in double precision",
                self.bin_width_opl
            ));
        }
        Ok(())
    }

    pub fn parse(ctx: &Ctx, node: Node) -> Result<Film, SceneError> {
        Ok(Self::parse_with_scan(ctx, node, false)?.0)
    }

    /// The film of an `nlos_capture_meter`: also `exhaustive_scan` (boolean, default
    /// false) with `laser_scan_width` and `laser_scan_height` (the laser grid of an
    /// exhaustive capture, returned when `exhaustive_scan` is true).
    pub fn parse_for_meter(
        ctx: &Ctx,
        node: Node,
    ) -> Result<(Film, Option<[usize; 2]>), SceneError> {
        Self::parse_with_scan(ctx, node, true)
    }

    fn parse_with_scan(
        ctx: &Ctx,
        node: Node,
        meter: bool,
    ) -> Result<(Film, Option<[usize; 2]>), SceneError> {
        let kind = ctx.required_attr(node, "type")?;
        if kind != "transient_hdr_film" {
            return Err(ctx.err(
                node,
                format!("film type '{kind}' is not supported (use transient_hdr_film)"),
            ));
        }
        let mut p = Props::parse(ctx, node)?;
        let dim = |p: &mut Props, name: &str, default: Option<i64>| -> Result<usize, SceneError> {
            let v = match (p.integer(name)?, default) {
                (Some(v), _) | (None, Some(v)) => v,
                (None, None) => return Err(p.err(format!("missing parameter '{name}'"))),
            };
            if v <= 0 {
                return Err(p.err_at(name, format!("{name} must be positive, got {v}")));
            }
            Ok(v as usize)
        };
        let width = dim(&mut p, "width", Some(768))?;
        let height = dim(&mut p, "height", Some(576))?;
        let bins = dim(&mut p, "temporal_bins", None)?;
        let start_opl = p.float_or("start_opl", 0.0)?;
        let bin_width_opl = p
            .float("bin_width_opl")?
            .ok_or_else(|| p.err("missing parameter 'bin_width_opl'"))?;
        if bin_width_opl <= 0.0 {
            return Err(p.err_at(
                "bin_width_opl",
                format!("bin_width_opl must be positive, got {bin_width_opl}"),
            ));
        }
        // mitransient film flags that do not change what is computed here.
        p.ignore("auto_detect_bins");
        let mut scan = None;
        if p.peek("exhaustive_scan").is_some() || p.peek("laser_scan_width").is_some() {
            if !meter {
                return Err(p.err_at("exhaustive_scan", "exhaustive_scan and laser_scan_width/height belong to the film of an nlos_capture_meter"));
            }
            let on = p.boolean_or("exhaustive_scan", false)?;
            let lw = p.integer("laser_scan_width")?.unwrap_or(0);
            let lh = p.integer("laser_scan_height")?.unwrap_or(0);
            if on {
                for (name, v) in [("laser_scan_width", lw), ("laser_scan_height", lh)] {
                    if !(1..=1 << 16).contains(&v) {
                        return Err(p.err_at(
                            name,
                            format!("an exhaustive scan needs {name} in 1..=65536, got {v}"),
                        ));
                    }
                }
                scan = Some([lw as usize, lh as usize]);
            }
        }
        for obj in std::mem::take(&mut p.objects) {
            match (obj.tag_name().name(), ctx.attr(obj, "type")?.as_deref()) {
                ("rfilter", Some("box")) => Props::parse(ctx, obj)?.finish()?,
                ("rfilter", other) => {
                    return Err(ctx.err(obj, format!("reconstruction filter {other:?} is not supported; the transient film uses the box filter")))
                }
                (tag, _) => return Err(ctx.err(obj, format!("unexpected <{tag}> inside <film>"))),
            }
        }
        p.finish()?;
        let film = Film {
            width,
            height,
            bins,
            start_opl,
            bin_width_opl,
        };
        Ok((film, scan))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_are_half_open_boxes() {
        let f = Film {
            width: 1,
            height: 1,
            bins: 10,
            start_opl: 2.0,
            bin_width_opl: 0.5,
        };
        assert_eq!(f.bin(1.999), None);
        assert_eq!(f.bin(2.0), Some(0));
        assert_eq!(f.bin(2.49), Some(0));
        assert_eq!(f.bin(2.5), Some(1));
        assert_eq!(f.bin(6.99), Some(9));
        assert_eq!(f.bin(7.0), None);
        assert_eq!(f.bin(f64::NAN), None);
    }

    #[test]
    fn time_windows_beyond_double_precision_are_errors() {
        let film = |start_opl: f64, bin_width_opl: f64| Film {
            width: 2,
            height: 2,
            bins: 10,
            start_opl,
            bin_width_opl,
        };
        assert!(film(3.5, 0.04).validate().is_ok());
        assert!(film(-1e6, 1e-3).validate().is_ok());
        let e = film(1e308, 1e308).validate().unwrap_err();
        assert!(e.contains("beyond the floating-point range"), "{e}");
        let e = film(1e10, 1e-10).validate().unwrap_err();
        assert!(e.contains("too narrow"), "{e}");
    }
}
