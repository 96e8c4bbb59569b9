//! PNG line charts with `plotters` (no system fonts: DejaVu Sans is compiled in).

use super::ReportError;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: Once = Once::new();

pub fn register_font() {
    FONT.call_once(|| {
        plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            include_bytes!("../../assets/fonts/DejaVuSans.ttf"),
        )
        .unwrap_or_else(|_| panic!("the bundled DejaVu Sans font is valid"));
    });
}

/// One curve of a chart.
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

pub const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// Axis scale.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisScale {
    Linear,
    Log,
}

fn bounds(values: impl Iterator<Item = f64>, scale: AxisScale) -> Option<(f64, f64)> {
    let v: Vec<f64> = values
        .filter(|v| v.is_finite() && (scale == AxisScale::Linear || *v > 0.0))
        .collect();
    let (lo, hi) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    if v.is_empty() {
        return None;
    }
    Some(match scale {
        AxisScale::Log if lo == hi => (lo / 2.0, hi * 2.0),
        AxisScale::Log => (lo / 1.15, hi * 1.15),
        AxisScale::Linear if lo == hi => (lo - 1.0, hi + 1.0),
        AxisScale::Linear => (lo, hi),
    })
}

/// Draws `series` into a PNG at `path` (written via a temporary name and a rename).
/// Returns `Ok(false)` and writes nothing when no point can be drawn (e.g. every error
/// is 0 on a log axis).
pub fn line_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    x_scale: AxisScale,
    y_scale: AxisScale,
) -> Result<bool, ReportError> {
    register_font();
    let all = || series.iter().flat_map(|s| s.points.iter());
    let (Some(xb), Some(yb)) = (
        bounds(all().map(|p| p.0), x_scale),
        bounds(all().map(|p| p.1), y_scale),
    ) else {
        return Ok(false);
    };
    let (w, h) = (900u32, 600u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        // plotters labels a log axis at powers of its base: base 2 under two decades.
        let base = |(lo, hi): (f64, f64)| if hi / lo < 100.0 { 2.0 } else { 10.0 };
        let (xl, yl) = (
            (xb.0..xb.1).log_scale().base(base(xb)),
            (yb.0..yb.1).log_scale().base(base(yb)),
        );
        let r = match (x_scale, y_scale) {
            (AxisScale::Log, AxisScale::Log) => draw(
                &root, title, x_label, y_label, series, xl, yl, x_scale, y_scale,
            ),
            (AxisScale::Linear, AxisScale::Log) => draw(
                &root,
                title,
                x_label,
                y_label,
                series,
                xb.0..xb.1,
                yl,
                x_scale,
                y_scale,
            ),
            (AxisScale::Log, AxisScale::Linear) => draw(
                &root,
                title,
                x_label,
                y_label,
                series,
                xl,
                yb.0..yb.1,
                x_scale,
                y_scale,
            ),
            (AxisScale::Linear, AxisScale::Linear) => draw(
                &root,
                title,
                x_label,
                y_label,
                series,
                xb.0..xb.1,
                yb.0..yb.1,
                x_scale,
                y_scale,
            ),
        };
        let drawing = |reason: String| ReportError::Drawing {
            path: path.to_path_buf(),
            reason,
        };
        r.map_err(|e| drawing(e.to_string()))?;
        root.present().map_err(|e| drawing(e.to_string()))?;
    }
    save_png_rgb(path, &buf, w, h)?;
    Ok(true)
}

#[allow(clippy::too_many_arguments)]
fn draw<DB: DrawingBackend, X, Y>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    x: X,
    y: Y,
    x_scale: AxisScale,
    y_scale: AxisScale,
) -> Result<(), Box<dyn std::error::Error + 'static>>
where
    DB::ErrorType: 'static,
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 24))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(x, y)?;
    let fmt = |v: &f64| crate::report::table::num(*v);
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&fmt)
        .y_label_formatter(&fmt)
        .light_line_style(WHITE)
        .label_style(("sans-serif", 15))
        .draw()?;
    let ok = |v: f64, s: AxisScale| v.is_finite() && (s == AxisScale::Linear || v > 0.0);
    for (k, s) in series.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|&(a, b)| ok(a, x_scale) && ok(b, y_scale))
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
            .label(s.label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        if pts.len() <= 40 {
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 16))
        .draw()?;
    Ok(())
}

/// Saves an RGB8 buffer as PNG through a temporary sibling and a rename (an encoder's
/// error is the file's [`BundleError::Io`](crate::bundle::BundleError::Io)).
pub fn save_png_rgb(
    path: &Path,
    buf: &[u8],
    w: u32,
    h: u32,
) -> Result<(), crate::bundle::BundleError> {
    crate::bundle::write::replace_file(path, |tmp| {
        image::save_buffer_with_format(
            tmp,
            buf,
            w,
            h,
            image::ColorType::Rgb8,
            image::ImageFormat::Png,
        )
    })
}
