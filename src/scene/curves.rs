//! The curve file of Mitsuba 3's `linearcurve` and `bsplinecurve` (the reader both
//! plugins share): one control point per line, `x y z radius` (further numbers on a
//! line are ignored, as Mitsuba's `strtof` loop does), a blank line (only spaces, tabs,
//! `\r`) between curves, at least 2 (linear) or 4 (B-spline) points per curve, lines
//! under 1024 characters, every value finite. Positions go through `to_world`; radii do
//! not (Mitsuba: "the control points' radii are invariant to this transformation").
//! Segments: `n - 1` (linear) or `n - 3` (B-spline) per curve of `n` points, numbered
//! over the whole file (Mitsuba's `segment_indices`).
//!
//! tstat also refuses negative radii (Mitsuba passes them to Embree, whose round curves
//! are then undefined).

use super::limits::WorldPointError;
use crate::geometry::curve::{CurveGeom, CurveKind};
use glam::{DMat4, DVec3, Vec4};
use std::path::Path;

/// Why a curve file cannot be read. Lines count from 1; the message does not name the
/// file (the caller adds it).
#[derive(Debug, thiserror::Error)]
pub enum CurveError {
    /// The file could not be read (missing, not a regular file, too large, ...).
    #[error(transparent)]
    Read(std::io::Error),
    /// A curve of fewer control points than its kind's segment spans.
    #[error(
        "the curve ending before line {line} has {points} control point{}; a {} needs at least {} per curve",
        plural(*.points),
        .kind.name(),
        .kind.span()
    )]
    TooFewPoints {
        line: usize,
        points: usize,
        kind: CurveKind,
    },
    /// A line of 1024 bytes or more.
    #[error("line {line} is too long ({bytes} characters; Mitsuba reads at most 1023)")]
    LineTooLong { line: usize, bytes: usize },
    /// A line that is not UTF-8.
    #[error("line {line} is not UTF-8 text")]
    NotUtf8 { line: usize },
    /// A line of fewer than four numbers (`text` trimmed).
    #[error(
        "line {line} ('{text}') has {numbers} number{}; a control point is 'x y z radius'",
        plural(*.numbers)
    )]
    TooFewNumbers {
        line: usize,
        text: String,
        numbers: usize,
    },
    /// A token that is not a number.
    #[error("line {line}: '{token}' is not a number (a control point is 'x y z radius')")]
    NotANumber { line: usize, token: String },
    /// A control point whose position is NaN or infinite.
    #[error("line {line}: the position ({}, {}, {}) is not finite", .position[0], .position[1], .position[2])]
    Position { line: usize, position: [f32; 3] },
    /// A negative, NaN or infinite radius.
    #[error("line {line}: the radius {radius} must be finite and non-negative")]
    Radius { line: usize, radius: f32 },
    /// A control point that `to_world` maps beyond the world's limits.
    #[error("line {line}: {point}")]
    WorldPoint { line: usize, point: WorldPointError },
    /// A file without control points.
    #[error("the file has no control points")]
    Empty,
    /// More control points than 32-bit segment indices address.
    #[error("too many control points ({points})")]
    TooManyPoints { points: usize },
}

/// The plural ending of `n` things.
fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// Reads the curve file at `path` into world space, or says why not (without the
/// file name: the caller adds it).
pub fn load_curves(
    path: &Path,
    kind: CurveKind,
    to_world: &DMat4,
) -> Result<CurveGeom, CurveError> {
    let text = crate::io::read_regular(path, crate::io::MAX_MESH_BYTES)
        .map_err(|e| CurveError::Read(std::io::Error::other(e)))?;
    parse_curves(&text, kind, to_world)
}

/// The curves of a file's bytes.
pub fn parse_curves(
    text: &[u8],
    kind: CurveKind,
    to_world: &DMat4,
) -> Result<CurveGeom, CurveError> {
    let min_points = kind.span();
    let mut points: Vec<Vec4> = Vec::new();
    let mut starts: Vec<usize> = Vec::new();
    let mut new_curve = true;
    let finish = |points: &Vec<Vec4>, starts: &Vec<usize>, line: usize| {
        if let Some(&s) = starts.last() {
            let n = points.len() - s;
            if n < min_points {
                return Err(CurveError::TooFewPoints {
                    line,
                    points: n,
                    kind,
                });
            }
        }
        Ok(())
    };
    let mut line_no = 0;
    for raw in text.split(|&b| b == b'\n') {
        line_no += 1;
        if raw.len() >= 1024 {
            return Err(CurveError::LineTooLong {
                line: line_no,
                bytes: raw.len(),
            });
        }
        let line = std::str::from_utf8(raw).map_err(|_| CurveError::NotUtf8 { line: line_no })?;
        if line.trim_matches([' ', '\t', '\r']).is_empty() {
            if !new_curve {
                finish(&points, &starts, line_no)?;
            }
            new_curve = true;
            continue;
        }
        let mut values = [0.0f32; 4];
        let mut tokens = line.split_ascii_whitespace();
        for (i, v) in values.iter_mut().enumerate() {
            let Some(tok) = tokens.next() else {
                return Err(CurveError::TooFewNumbers {
                    line: line_no,
                    text: line.trim().to_string(),
                    numbers: i,
                });
            };
            *v = tok.parse::<f32>().map_err(|_| CurveError::NotANumber {
                line: line_no,
                token: tok.to_string(),
            })?;
        }
        let [x, y, z, r] = values;
        if !(x.is_finite() && y.is_finite() && z.is_finite()) {
            return Err(CurveError::Position {
                line: line_no,
                position: [x, y, z],
            });
        }
        if !r.is_finite() || r < 0.0 {
            return Err(CurveError::Radius {
                line: line_no,
                radius: r,
            });
        }
        let p = to_world.transform_point3(DVec3::new(x as f64, y as f64, z as f64));
        super::limits::check_world_point(p).map_err(|point| CurveError::WorldPoint {
            line: line_no,
            point,
        })?;
        if new_curve {
            starts.push(points.len());
            new_curve = false;
        }
        points.push(p.as_vec3().extend(r));
    }
    if starts.is_empty() {
        return Err(CurveError::Empty);
    }
    if !new_curve {
        finish(&points, &starts, line_no + 1)?;
    }
    let (mut segments, mut first) = (Vec::new(), Vec::new());
    for (c, &s) in starts.iter().enumerate() {
        let end = starts.get(c + 1).copied().unwrap_or(points.len());
        for j in 0..(end - s + 1 - min_points) {
            segments.push((s + j) as u32);
            first.push(j == 0);
        }
    }
    if points.len() > u32::MAX as usize / 2 {
        return Err(CurveError::TooManyPoints {
            points: points.len(),
        });
    }
    Ok(CurveGeom {
        kind,
        points,
        segments,
        first,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str, kind: CurveKind) -> Result<CurveGeom, String> {
        parse_curves(text.as_bytes(), kind, &DMat4::IDENTITY).map_err(|e| e.to_string())
    }

    #[test]
    fn mitsubas_documentation_example() {
        let text = "-1.0 0.1 0.1 0.5\n 1.0 1.4 1.2 0.5\n\n-1.0 5.0 2.2 1\n-2.3 4.0 2.3 2\n 4.0 1.0 2.2 5\n 4.0 0.0 2.3 6\n";
        let g = parse(text, CurveKind::Linear).unwrap();
        assert_eq!(g.points.len(), 6);
        assert_eq!(g.segments, vec![0, 2, 3, 4]);
        assert_eq!(g.first, vec![true, true, false, false]);
        // Too few points for a B-spline in the first curve.
        let e = parse(text, CurveKind::BSpline).unwrap_err();
        assert!(e.contains("at least 4"), "{e}");
        // Several blank lines, \r\n endings and trailing numbers are accepted.
        let g = parse(
            "0 0 0 1 9\r\n\r\n\n1 0 0 1\r\n2 0 0 1\r\n3 0 0 1\r\n4 0 0 1",
            CurveKind::BSpline,
        );
        let e = g.unwrap_err();
        assert!(e.contains("1 control point;"), "{e}");
        let g = parse(
            "\n1 0 0 1\r\n2 0 0 1\r\n3 0 0 1\r\n4 0 0 1 7\r\n5 0 0 2\n\n",
            CurveKind::BSpline,
        )
        .unwrap();
        assert_eq!(g.segments, vec![0, 1]);
        assert_eq!(g.points[4], Vec4::new(5.0, 0.0, 0.0, 2.0));
    }

    #[test]
    fn radii_do_not_scale_and_positions_do() {
        let m = DMat4::from_scale(DVec3::new(2.0, 3.0, 4.0));
        let g = parse_curves(b"1 1 1 0.5\n2 2 2 0.25\n", CurveKind::Linear, &m).unwrap();
        assert_eq!(
            g.points,
            vec![
                Vec4::new(2.0, 3.0, 4.0, 0.5),
                Vec4::new(4.0, 6.0, 8.0, 0.25)
            ]
        );
    }

    #[test]
    fn hostile_files_are_refused() {
        for (text, want) in [
            ("", "no control points"),
            ("\n\n  \n", "no control points"),
            ("0 0 0 1\n", "at least 2"),
            ("0 0 0 1\n1 0 0 1\n\n5 5 5 1\n", "at least 2"),
            ("0 0 0\n1 0 0 1\n", "has 3 numbers"),
            ("0 0 zero 1\n1 0 0 1\n", "'zero' is not a number"),
            ("0 0 0 -1\n1 0 0 1\n", "non-negative"),
            ("0 0 0 nan\n1 0 0 1\n", "finite"),
            ("0 inf 0 1\n1 0 0 1\n", "not finite"),
            ("1e30 0 0 1\n1 0 0 1\n", "beyond"),
        ] {
            let e = parse(text, CurveKind::Linear).unwrap_err();
            assert!(e.contains(want), "{text:?}: {e}");
        }
        let long = format!("0 0 0 1{}\n1 0 0 1\n", " ".repeat(2000));
        assert!(parse(&long, CurveKind::Linear)
            .unwrap_err()
            .contains("too long"));
        assert!(
            parse_curves(b"0 0 0 1\n\xff\n", CurveKind::Linear, &DMat4::IDENTITY)
                .unwrap_err()
                .to_string()
                .contains("UTF-8")
        );
    }
}
