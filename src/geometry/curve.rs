//! Mitsuba 3's curve shapes, `linearcurve` and `bsplinecurve`
//! (`src/shapes/linearcurve.cpp`, `bsplinecurve.cpp`), with the geometry Embree gives
//! them on Mitsuba's CPU variants (`RTC_GEOMETRY_TYPE_ROUND_LINEAR_CURVE` and
//! `ROUND_BSPLINE_CURVE`, built with `EMBREE_BACKFACE_CULLING_CURVES`):
//!
//! - **Round linear segment** from `(p0, r0)` to `(p1, r1)`: the convex hull of the
//!   two spheres, i.e. the sphere of centre `c(v) = p0 + v (p1 - p0)` and radius
//!   `r(v) = r0 + v (r1 - r0)` swept over `v` in [0, 1]: the cone tangent to both
//!   spheres between its two tangent circles, plus the end sphere; the first segment
//!   of each curve also owns its begin sphere (Embree's `roundline_intersector.h`).
//!   A hit reports the parameter `v` of the sphere it lies on (`v = y / g` on the cone,
//!   1 on the end sphere, 0 on the begin sphere), so the normal is `p - c(v)`, as
//!   Mitsuba computes it. A joint's sphere belongs to the segment it ends.
//! - **Round B-spline segment** of a uniform cubic B-spline (control points
//!   `P_i, r_i`): the sweep of the circle of radius `r(v)` about `c(v)` in the plane
//!   normal to `c'(v)`, `v` in [0, 1], open at both ends (Embree's
//!   `curve_intersector_sweep.h` solves `(p - c)·c' = 0`, `|p - c| = r`). For a constant
//!   radius this is the swept sphere; for a varying one it is tilted from it by the
//!   radius's slope, and Mitsuba's normal is this surface's:
//!   `n ∝ (|c'|² - (p - c)·c'') (p - c) - r r' c'`.
//! - Only front faces are hit (`n·d < 0`): a ray from inside a curve, or one that enters
//!   an open B-spline end, passes through (Mitsuba's "backfaces of curves are always
//!   culled"), for closest hits and shadow rays alike.
//!
//! Intersection is in f64. Linear: the tangent cone's quadratic and two spheres,
//! closed form. B-spline: the segment is converted to its Bézier form (xyz and radius),
//! subdivided (de Casteljau, halving) while a piece's bounding capsule (its chord,
//! widened by the control points' distance from it plus the largest control radius)
//! meets the ray before the best hit so far, down to pieces whose control polygon
//! deviates from the chord, and whose radius from linear, by at most
//! [`BSPLINE_TOLERANCE`] of the segment's size; each such piece is intersected as the
//! straight circle sweep of its chord (a truncated cone), and every root seeds Newton's
//! method on the exact equations in `(v, t)`. A converged root is the exact surface to
//! rounding; the tolerance only decides rays that pass within about
//! `BSPLINE_TOLERANCE * size` of the silhouette (`size`: the largest distance of a
//! Bézier control point from the segment's centre plus its radius; at most 6.4e-6
//! scene units on the public B-spline scenes, whose pixels are 4e-3 wide at their
//! 960 x 720 and 0.045 at the 64-pixel-wide agreement renders). The subdivision also
//! seeds from sign changes of the ray's distance from the circle in each normal plane,
//! which the straight-tube roots alone miss where the tube bends by a radius-sized
//! amount over a piece.
//!
//! Parameterisation (Mitsuba's): `uv = (u, v)` with `u` the angle about the axis,
//! `atan2(n·rot, n·rad) / 2 pi` in Mitsuba's `local_frame` of the tangent (`rot` the
//! component of +z normal to it, `rad = rot × t`) and `v = (v_local + segment) / segments`
//! over all segments of the shape. dp/du and dp/dv as Mitsuba's (the B-spline's from its
//! Frenet frame, `partials`).

use glam::{DVec3, DVec4, Vec3, Vec4};
use std::f64::consts::TAU;

/// Largest deviation, relative to a B-spline segment's size, of a subdivided piece from
/// the straight tube that seeds Newton's method.
pub const BSPLINE_TOLERANCE: f64 = 1e-5;
/// Halvings at most (a piece of 2^-24 of the segment).
const MAX_DEPTH: u32 = 24;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurveKind {
    Linear,
    BSpline,
}

impl CurveKind {
    /// The control points a segment spans.
    pub fn span(self) -> usize {
        match self {
            CurveKind::Linear => 2,
            CurveKind::BSpline => 4,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            CurveKind::Linear => "linearcurve",
            CurveKind::BSpline => "bsplinecurve",
        }
    }
}

/// One curve shape: all control points of its file, in world space.
#[derive(Clone, Debug)]
pub struct CurveGeom {
    pub kind: CurveKind,
    /// World-space position and radius (radii are not transformed, as Mitsuba's).
    pub points: Vec<Vec4>,
    /// The first control point of each segment (Mitsuba's `segment_indices`).
    pub segments: Vec<u32>,
    /// Whether each segment begins a curve (a linear one then owns its begin sphere).
    pub first: Vec<bool>,
}

/// One segment, as the BVH stores it (out of line).
#[derive(Clone, Copy, Debug)]
pub enum Segment {
    Linear(LinearSegment),
    BSpline(BSplineSegment),
}

#[derive(Clone, Copy, Debug)]
pub struct LinearSegment {
    pub p0: DVec3,
    pub r0: f64,
    pub p1: DVec3,
    pub r1: f64,
    /// The begin sphere is part of this segment (the curve's first).
    pub begin: bool,
}

#[derive(Clone, Copy, Debug)]
pub struct BSplineSegment {
    /// Bézier control points (xyz, radius) of the same cubic.
    pub b: [DVec4; 4],
}

fn p4(v: Vec4) -> DVec4 {
    v.as_dvec4()
}

impl CurveGeom {
    /// The segment `i`.
    pub fn segment(&self, i: usize) -> Segment {
        let k = self.segments[i] as usize;
        let pt = |j: usize| p4(self.points[k + j]);
        match self.kind {
            CurveKind::Linear => {
                let (a, b) = (pt(0), pt(1));
                Segment::Linear(LinearSegment {
                    p0: a.truncate(),
                    r0: a.w,
                    p1: b.truncate(),
                    r1: b.w,
                    begin: self.first[i],
                })
            }
            CurveKind::BSpline => {
                let (p0, p1, p2, p3) = (pt(0), pt(1), pt(2), pt(3));
                Segment::BSpline(BSplineSegment {
                    b: [
                        (p0 + 4.0 * p1 + p2) / 6.0,
                        (4.0 * p1 + 2.0 * p2) / 6.0,
                        (2.0 * p1 + 4.0 * p2) / 6.0,
                        (p1 + 4.0 * p2 + p3) / 6.0,
                    ],
                })
            }
        }
    }

    /// A box around segment `i` (its control points widened by their radii, as
    /// Mitsuba's and Embree's; the B-spline's Bézier hull lies inside its B-spline one).
    pub fn segment_bounds(&self, i: usize) -> (Vec3, Vec3) {
        let k = self.segments[i] as usize;
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for p in &self.points[k..k + self.kind.span()] {
            let p = p4(*p);
            let r = DVec3::splat(p.w.abs());
            lo = lo.min(p.truncate() - r);
            hi = hi.max(p.truncate() + r);
        }
        // Outward rounding to f32.
        let pad = (hi - lo).max_element() * 1e-6 + 1e-30;
        (
            (lo - DVec3::splat(pad)).as_vec3(),
            (hi + DVec3::splat(pad)).as_vec3(),
        )
    }

    /// Mitsuba's bounding box: every control point widened by its radius.
    pub fn control_bounds(&self) -> (Vec3, Vec3) {
        self.points
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                let r = Vec3::splat(p.w);
                (lo.min(p.truncate() - r), hi.max(p.truncate() + r))
            })
    }

    /// A box around every segment (slightly padded: see [`Self::segment_bounds`]).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (0..self.segments.len()).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), i| {
            let (a, b) = self.segment_bounds(i);
            (lo.min(a), hi.max(b))
        })
    }

    /// Centre, tangent c', c'', c''', radius, r', r'' at `v` of segment `seg`
    /// (Mitsuba's `cubic_interpolation`; linear: the straight segment).
    fn eval(&self, seg: usize, v: f64) -> Eval {
        let k = self.segments[seg] as usize;
        let pt = |j: usize| p4(self.points[k + j]);
        match self.kind {
            CurveKind::Linear => {
                let (a, b) = (pt(0), pt(1));
                let c = a + (b - a) * v;
                Eval {
                    c: c.truncate(),
                    dc: (b - a).truncate(),
                    ddc: DVec3::ZERO,
                    dddc: DVec3::ZERO,
                    r: c.w,
                    dr: b.w - a.w,
                }
            }
            CurveKind::BSpline => {
                let (p0, p1, p2, p3) = (pt(0), pt(1), pt(2), pt(3));
                let (v2, v3) = (v * v, v * v * v);
                let c = ((-v3 + 3.0 * v2 - 3.0 * v + 1.0) * p0
                    + (3.0 * v3 - 6.0 * v2 + 4.0) * p1
                    + (-3.0 * v3 + 3.0 * v2 + 3.0 * v + 1.0) * p2
                    + v3 * p3)
                    / 6.0;
                let dc = ((-3.0 * v2 + 6.0 * v - 3.0) * p0
                    + (9.0 * v2 - 12.0 * v) * p1
                    + (-9.0 * v2 + 6.0 * v + 3.0) * p2
                    + (3.0 * v2) * p3)
                    / 6.0;
                let ddc = (1.0 - v) * p0 + (3.0 * v - 2.0) * p1 + (1.0 - 3.0 * v) * p2 + v * p3;
                let dddc = -p0 + 3.0 * p1 - 3.0 * p2 + p3;
                Eval {
                    c: c.truncate(),
                    dc: dc.truncate(),
                    ddc: ddc.truncate(),
                    dddc: dddc.truncate(),
                    r: c.w,
                    dr: dc.w,
                }
            }
        }
    }

    /// Mitsuba's geometric (= shading) normal at `p`, a hit of segment `seg` at `v`.
    pub fn normal(&self, seg: usize, v: f32, p: Vec3) -> Vec3 {
        let e = self.eval(seg, v as f64);
        let rv = p.as_dvec3() - e.c;
        let n = match self.kind {
            CurveKind::Linear => rv,
            CurveKind::BSpline => {
                (e.dc.length_squared() - rv.dot(e.ddc)) * rv - (e.dr * e.r) * e.dc
            }
        };
        n.normalize_or_zero().as_vec3()
    }

    /// Mitsuba's uv of a hit of segment `seg` at `v`.
    pub fn uv(&self, seg: usize, v: f32, p: Vec3) -> glam::Vec2 {
        let e = self.eval(seg, v as f64);
        let (rot, rad) = local_frame(e.dc.normalize_or_zero());
        let n = (p.as_dvec3() - e.c).normalize_or_zero();
        let mut u = n.dot(rot).atan2(n.dot(rad));
        if u < 0.0 {
            u += TAU;
        }
        glam::Vec2::new(
            (u / TAU) as f32,
            ((v as f64 + seg as f64) / self.segments.len() as f64) as f32,
        )
    }

    /// dp/du and dp/dv at a hit of segment `seg` at `v` (Mitsuba's).
    pub fn dpduv(&self, seg: usize, v: f32, p: Vec3) -> (Vec3, Vec3) {
        let count = self.segments.len() as f64;
        let e = self.eval(seg, v as f64);
        let rv = p.as_dvec3() - e.c;
        match self.kind {
            CurveKind::Linear => {
                let axis = e.dc.normalize_or_zero();
                let n = rv.normalize_or_zero();
                (
                    (TAU * axis.cross(rv)).as_vec3(),
                    (count * (e.dc + e.dr * n)).as_vec3(),
                )
            }
            CurveKind::BSpline => {
                let (du, dv) = bspline_partials(&e, self.uv(seg, v, p).x as f64);
                ((du * TAU).as_vec3(), (dv * count).as_vec3())
            }
        }
    }
}

struct Eval {
    c: DVec3,
    dc: DVec3,
    ddc: DVec3,
    dddc: DVec3,
    r: f64,
    dr: f64,
}

/// Mitsuba's `local_frame`: `rot` is +z made normal to the tangent (+y where the
/// tangent is +-z), `rad = rot × t`.
fn local_frame(t: DVec3) -> (DVec3, DVec3) {
    let guide = DVec3::Z;
    let rot = if guide.dot(t).abs() == 1.0 {
        DVec3::Y
    } else {
        (guide - t * t.dot(guide)).normalize_or_zero()
    };
    (rot, rot.cross(t))
}

/// Mitsuba's `coordinate_system(n)` (Duff et al. 2017): the s and t axes of `Frame3f(n)`.
fn coordinate_system(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Mitsuba's `partials` (dp/du before the 2 pi and dp/dv before the segment count)
/// from the Frenet frame at a B-spline point and the angle `u` (in [0, 1)).
fn bspline_partials(e: &Eval, u: f64) -> (DVec3, DVec3) {
    let norm_dc = e.dc.length();
    let cross = e.dc.cross(e.ddc);
    let norm_cross = cross.length();
    let mut kappa = norm_cross / (norm_dc * norm_dc * norm_dc);
    let mut tau = e.dddc.dot(cross) / (norm_cross * norm_cross);
    if norm_cross < 1e-6 || e.dddc.length() < 1e-6 {
        tau = 0.0;
    }
    let t = e.dc / norm_dc;
    let (mut fn_, mut fb) = {
        let n = cross.cross(e.dc).normalize_or_zero();
        (n, t.cross(n).normalize_or_zero())
    };
    if kappa.is_nan() || kappa < f32::EPSILON as f64 {
        kappa = 0.0;
        tau = 0.0;
        (fn_, fb) = coordinate_system(t);
    }
    let (rot, rad_dir) = local_frame(t);
    let (s_, c_) = (u * TAU).sin_cos();
    let rad = c_ * rad_dir + s_ * rot;
    let (cos_t, sin_t) = (fn_.dot(rad), fb.dot(rad));
    let radu = -sin_t * fn_ + cos_t * fb;
    let radv = norm_dc * cos_t * (-kappa * t + tau * fb) + norm_dc * sin_t * (-tau * fn_);
    (e.r * radu, e.dc + e.dr * rad + e.r * radv)
}

impl Segment {
    /// The nearest front-face hit `(t, v)` with `t > tmin` (unit `d`).
    #[inline(never)]
    pub fn intersect(&self, o: Vec3, d: Vec3, tmin: f32) -> Option<(f32, f32)> {
        // The kernels take a unit direction in f64 (a unit f32 vector is only unit to
        // 1e-7, which moves the roots of nearly tangent rays by 1e-4); t is measured
        // back in units of the caller's `d`.
        let (o, d) = (o.as_dvec3(), d.as_dvec3());
        let len = d.length();
        let d = d / len;
        let hit = match self {
            Segment::Linear(s) => s.intersect(o, d, tmin as f64 * len),
            Segment::BSpline(s) => s.intersect(o, d, tmin as f64 * len),
        }?;
        let t = (hit.0 / len) as f32;
        (t > tmin && t.is_finite()).then_some((t, hit.1 as f32))
    }
}

/// The entering root of the sphere (centre `c`, radius `r`) beyond `tmin`.
fn sphere_entry(o: DVec3, d: DVec3, c: DVec3, r: f64, tmin: f64) -> Option<f64> {
    let oc = o - c;
    let b = oc.dot(d);
    // |oc - (oc·d) d|² is the squared distance of the line from the centre, without
    // the cancellation of b² - |oc|².
    let perp = oc - b * d;
    let disc = r * r - perp.length_squared();
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t > tmin).then_some(t)
}

impl LinearSegment {
    fn intersect(&self, o: DVec3, d: DVec3, tmin: f64) -> Option<(f64, f64)> {
        let mut best: Option<(f64, f64)> = None;
        let mut take = |t: f64, v: f64| {
            if best.is_none_or(|b| t < b.0) {
                best = Some((t, v));
            }
        };
        if let Some(t) = sphere_entry(o, d, self.p1, self.r1, tmin) {
            take(t, 1.0);
        }
        if self.begin {
            if let Some(t) = sphere_entry(o, d, self.p0, self.r0, tmin) {
                take(t, 0.0);
            }
        }
        // The tangent cone (Embree's notation): y = (h - p0)·dP + r0 dr runs from 0 to
        // g = dP² - dr² between its tangent circles; v = y / g.
        let dp = self.p1 - self.p0;
        let dr = self.r1 - self.r0;
        let g = dp.length_squared() - dr * dr;
        if g > 0.0 {
            let oo = o - self.p0;
            let (odp, ddp) = (oo.dot(dp), d.dot(dp));
            let yp = odp + self.r0 * dr;
            let a = g - ddp * ddp;
            let b = 2.0 * (g * oo.dot(d) - ddp * yp);
            let c = g * oo.length_squared()
                - odp * odp
                - self.r0 * self.r0 * dp.length_squared()
                - 2.0 * self.r0 * dr * odp;
            let mut roots = [f64::NAN; 2];
            if a.abs() > 1e-12 * g {
                let disc = b * b - 4.0 * a * c;
                if disc >= 0.0 {
                    let q = -0.5 * (b + disc.sqrt().copysign(b));
                    roots = [q / a, c / q];
                }
            } else if b != 0.0 {
                roots[0] = -c / b;
            }
            for t in roots {
                if t.is_nan() || t <= tmin {
                    continue;
                }
                let y = yp + t * ddp;
                if !(0.0..=g).contains(&y) {
                    continue;
                }
                let v = y / g;
                let h = oo + t * d;
                let n = h - v * dp;
                // The other nappe has a negative radius; back faces are culled.
                if self.r0 + v * dr >= 0.0 && n.dot(d) < 0.0 {
                    take(t, v);
                }
            }
        }
        best
    }
}

/// A point on a cubic Bézier in 4D and its first two derivatives.
fn bezier(b: &[DVec4; 4], u: f64) -> (DVec4, DVec4, DVec4) {
    let s = 1.0 - u;
    let p = b[0] * (s * s * s)
        + b[1] * (3.0 * s * s * u)
        + b[2] * (3.0 * s * u * u)
        + b[3] * (u * u * u);
    let d1 = (b[1] - b[0]) * (3.0 * s * s)
        + (b[2] - b[1]) * (6.0 * s * u)
        + (b[3] - b[2]) * (3.0 * u * u);
    let d2 = (b[2] - 2.0 * b[1] + b[0]) * (6.0 * s) + (b[3] - 2.0 * b[2] + b[1]) * (6.0 * u);
    (p, d1, d2)
}

/// Halves of a Bézier (de Casteljau at 1/2).
fn split(b: &[DVec4; 4]) -> ([DVec4; 4], [DVec4; 4]) {
    let ab = (b[0] + b[1]) * 0.5;
    let bc = (b[1] + b[2]) * 0.5;
    let cd = (b[2] + b[3]) * 0.5;
    let abc = (ab + bc) * 0.5;
    let bcd = (bc + cd) * 0.5;
    let m = (abc + bcd) * 0.5;
    ([b[0], ab, abc, m], [m, bcd, cd, b[3]])
}

/// Distance of `p` from the segment [a, e].
fn segment_distance(p: DVec3, a: DVec3, e: DVec3) -> f64 {
    let w = e - a;
    let l2 = w.length_squared();
    let s = if l2 > 0.0 {
        ((p - a).dot(w) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - a - s * w).length()
}

impl BSplineSegment {
    fn intersect(&self, o: DVec3, d: DVec3, tmin: f64) -> Option<(f64, f64)> {
        // Work about the segment's centre (f64 leaves ample room; this keeps the
        // tolerances relative to the segment).
        let mid = (self.b[0] + self.b[3]).truncate() * 0.5;
        let b = self.b.map(|p| p - mid.extend(0.0));
        let o = o - mid;
        let size = b
            .iter()
            .map(|p| p.truncate().length() + p.w.abs())
            .fold(0.0f64, f64::max);
        if size.is_nan() || size <= 0.0 {
            return None;
        }
        let tol = BSPLINE_TOLERANCE * size;
        let mut best: Option<(f64, f64)> = None;
        let mut stack: Vec<([DVec4; 4], f64, f64, u32)> =
            Vec::with_capacity(2 * MAX_DEPTH as usize);
        stack.push((b, 0.0, 1.0, 0));
        while let Some((piece, u0, u1, depth)) = stack.pop() {
            let (a, e) = (piece[0].truncate(), piece[3].truncate());
            let dev = segment_distance(piece[1].truncate(), a, e).max(segment_distance(
                piece[2].truncate(),
                a,
                e,
            ));
            let rmax = piece.iter().map(|p| p.w.abs()).fold(0.0f64, f64::max);
            // Bounding sphere of the capsule: the ray must meet it before the best hit.
            let centre = (a + e) * 0.5;
            let reach = (e - a).length() * 0.5 + dev + rmax;
            let Some((t_in, t_out)) = sphere_span(o, d, centre, reach) else {
                continue;
            };
            if t_out <= tmin || best.is_some_and(|h| t_in >= h.0) {
                continue;
            }
            // The capsule itself.
            if line_segment_distance(o, d, a, e) > dev + rmax {
                continue;
            }
            let rdev = (piece[1].w - (2.0 * piece[0].w + piece[3].w) / 3.0)
                .abs()
                .max((piece[2].w - (piece[0].w + 2.0 * piece[3].w) / 3.0).abs());
            if (dev <= tol && rdev <= tol) || depth >= MAX_DEPTH {
                let mut seeds: Vec<(f64, f64)> =
                    straight_tube_roots(o, d, a, e, piece[0].w, piece[3].w)
                        .into_iter()
                        .map(|(t, s)| (u0 + s.clamp(0.0, 1.0) * (u1 - u0), t))
                        .collect();
                plane_sweep_roots(&b, o, d, u0, u1, &mut seeds);
                for seed in seeds {
                    if let Some((t, u)) = newton(&b, o, d, seed, size) {
                        if t > tmin && best.is_none_or(|h| t < h.0) && front(&b, o, d, t, u) {
                            best = Some((t, u));
                        }
                    }
                }
                continue;
            }
            let (l, r) = split(&piece);
            let um = 0.5 * (u0 + u1);
            // Nearer half last, so it is popped first.
            let dl = (l[0] + l[3]).truncate() * 0.5 - o;
            let dr = (r[0] + r[3]).truncate() * 0.5 - o;
            if dl.dot(d) <= dr.dot(d) {
                stack.push((r, um, u1, depth + 1));
                stack.push((l, u0, um, depth + 1));
            } else {
                stack.push((l, u0, um, depth + 1));
                stack.push((r, um, u1, depth + 1));
            }
        }
        best
    }
}

/// Where the ray is inside the sphere, if it meets it.
fn sphere_span(o: DVec3, d: DVec3, c: DVec3, r: f64) -> Option<(f64, f64)> {
    let oc = o - c;
    let b = oc.dot(d);
    let perp = oc - b * d;
    let disc = r * r - perp.length_squared();
    if disc < 0.0 {
        return None;
    }
    let q = disc.sqrt();
    Some((-b - q, -b + q))
}

/// Distance between the ray's line and the segment [a, e]: a lower bound of the
/// ray's distance from it, exact over s in [0, 1] (a convex quadratic).
fn line_segment_distance(o: DVec3, d: DVec3, a: DVec3, e: DVec3) -> f64 {
    let perp = |v: DVec3| v - v.dot(d) * d;
    let (rp, wp) = (perp(a - o), perp(e - a));
    let ww = wp.length_squared();
    let s = if ww > 0.0 {
        (-rp.dot(wp) / ww).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (rp + s * wp).length()
}

/// Roots `(t, s)` of the ray with the straight circle sweep from `(a, ra)` to `(e, re)`
/// (a truncated cone: radius `ra + s (re - ra)` in the plane normal to the chord at
/// `s`), for `s` a little beyond [0, 1] (neighbouring pieces overlap).
fn straight_tube_roots(
    o: DVec3,
    d: DVec3,
    a: DVec3,
    e: DVec3,
    ra: f64,
    re: f64,
) -> Vec<(f64, f64)> {
    let w = e - a;
    let l2 = w.length_squared();
    let mut out = Vec::with_capacity(2);
    if l2.is_nan() || l2 <= 0.0 {
        // A point-like piece: seed at the ray's closest approach.
        out.push(((a - o).dot(d), 0.5));
        return out;
    }
    let oo = o - a;
    let (ow, dw) = (oo.dot(w) / l2, d.dot(w) / l2);
    let dr = re - ra;
    // |h|² - (h·w)²/l2 - (ra + dr s)², s = ow + t dw, h = oo + t d.
    let qa = 1.0 - dw * dw * l2 - dr * dr * dw * dw;
    let qb = 2.0 * (oo.dot(d) - ow * dw * l2 - (ra + dr * ow) * dr * dw);
    let qc = oo.length_squared() - ow * ow * l2 - (ra + dr * ow) * (ra + dr * ow);
    let mut roots = [f64::NAN; 2];
    if qa.abs() > 1e-12 {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            let q = -0.5 * (qb + disc.sqrt().copysign(qb));
            roots = [q / qa, qc / q];
        }
    } else if qb != 0.0 {
        roots[0] = -qc / qb;
    }
    for t in roots {
        let s = ow + t * dw;
        if t.is_finite() && (-0.25..=1.25).contains(&s) && ra + dr * s >= 0.0 {
            out.push((t, s));
        }
    }
    out
}

/// Where the ray meets the plane normal to the curve at `u`, and how far outside the
/// circle there it passes: `(|o + t d - c| - r, t)`, `t = (c - o)·c' / (d·c')` (none
/// when the ray is parallel to the plane). A root in `u` is an exact surface point.
fn plane_excess(b: &[DVec4; 4], o: DVec3, d: DVec3, u: f64) -> Option<(f64, f64)> {
    let (c, dc, _) = bezier(b, u);
    let dcc = dc.truncate();
    let den = d.dot(dcc);
    if den.is_nan() || den.abs() <= 1e-9 * dcc.length() {
        return None;
    }
    let t = (c.truncate() - o).dot(dcc) / den;
    Some(((o + t * d - c.truncate()).length() - c.w, t))
}

/// Seeds from sign changes of [`plane_excess`] over 8 steps of [u0, u1], each narrowed
/// by bisection (where the ray crosses the normal planes; the straight tube's roots
/// cover rays nearly parallel to them, whose two hits may share a step).
fn plane_sweep_roots(
    b: &[DVec4; 4],
    o: DVec3,
    d: DVec3,
    u0: f64,
    u1: f64,
    seeds: &mut Vec<(f64, f64)>,
) {
    const STEPS: usize = 8;
    let at = |k: usize| u0 + (u1 - u0) * k as f64 / STEPS as f64;
    let mut prev = (u0, plane_excess(b, o, d, u0));
    for k in 1..=STEPS {
        let u = at(k);
        let cur = (u, plane_excess(b, o, d, u));
        if let ((mut lo, Some((mut elo, _))), (mut hi, Some((ehi, _)))) = (prev, cur) {
            // The plane's t must stay finite between the two (no pole): d·c' keeps its
            // sign, which the finite excess at both ends and a common sign of
            // (e + r) do not guarantee; a spurious change only costs a Newton run.
            if (elo <= 0.0) != (ehi <= 0.0) {
                for _ in 0..30 {
                    let mid = 0.5 * (lo + hi);
                    match plane_excess(b, o, d, mid) {
                        Some((em, _)) if (em <= 0.0) == (elo <= 0.0) => {
                            lo = mid;
                            elo = em;
                        }
                        Some(_) => hi = mid,
                        None => break,
                    }
                }
                let u = 0.5 * (lo + hi);
                if let Some((_, t)) = plane_excess(b, o, d, u) {
                    seeds.push((u, t));
                }
            }
        }
        prev = cur;
    }
}

/// Newton's method on `(p - c)·c' = 0`, `|p - c|² = r²` with `p = o + t d`, from
/// `(u, t)`; the root, if it converges.
fn newton(
    b: &[DVec4; 4],
    o: DVec3,
    d: DVec3,
    (mut u, mut t): (f64, f64),
    size: f64,
) -> Option<(f64, f64)> {
    for _ in 0..20 {
        let (c, dc, ddc) = bezier(b, u);
        let (cc, dcc, ddcc) = (c.truncate(), dc.truncate(), ddc.truncate());
        let q = o + t * d - cc;
        let f1 = q.dot(dcc);
        let f2 = q.length_squared() - c.w * c.w;
        let j11 = -dcc.length_squared() + q.dot(ddcc);
        let j12 = d.dot(dcc);
        let j21 = -2.0 * f1 - 2.0 * c.w * dc.w;
        let j22 = 2.0 * q.dot(d);
        let det = j11 * j22 - j12 * j21;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let du = (f1 * j22 - f2 * j12) / det;
        let dt = (j11 * f2 - j21 * f1) / det;
        u -= du;
        t -= dt;
        if !(u.is_finite() && t.is_finite() && (-0.5..=1.5).contains(&u)) {
            return None;
        }
        if du.abs() < 1e-14 && dt.abs() < 1e-13 * size {
            break;
        }
    }
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    // Converged: the residuals of the exact equations at the root.
    let (c, dc, _) = bezier(b, u);
    let q = o + t * d - c.truncate();
    let tangent = dc.truncate().normalize_or_zero();
    let radial = (q - q.dot(tangent) * tangent).length();
    let eps = 1e-9 * size;
    (q.dot(tangent).abs() <= eps && (radial - c.w).abs() <= eps).then_some((t, u))
}

/// Whether the ray meets the B-spline surface's front at `(t, u)` (Mitsuba's normal).
fn front(b: &[DVec4; 4], o: DVec3, d: DVec3, t: f64, u: f64) -> bool {
    let (c, dc, ddc) = bezier(b, u);
    let q = o + t * d - c.truncate();
    let (dcc, ddcc) = (dc.truncate(), ddc.truncate());
    let n = (dcc.length_squared() - q.dot(ddcc)) * q - (dc.w * c.w) * dcc;
    n.dot(d) < 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Bézier form is the same cubic as Mitsuba's B-spline interpolation.
    #[test]
    fn bezier_form_equals_the_bspline() {
        let pts = [
            Vec4::new(-1.0, 0.3, 2.0, 0.1),
            Vec4::new(0.5, -1.0, 0.0, 0.3),
            Vec4::new(1.5, 2.0, -1.0, 0.2),
            Vec4::new(3.0, 0.0, 1.0, 0.05),
        ];
        let g = CurveGeom {
            kind: CurveKind::BSpline,
            points: pts.to_vec(),
            segments: vec![0],
            first: vec![true],
        };
        let Segment::BSpline(s) = g.segment(0) else {
            unreachable!()
        };
        for k in 0..=10 {
            let v = k as f64 / 10.0;
            let e = g.eval(0, v);
            let (p, d1, d2) = bezier(&s.b, v);
            assert!((p.truncate() - e.c).length() < 1e-12 && (p.w - e.r).abs() < 1e-12);
            assert!((d1.truncate() - e.dc).length() < 1e-12 && (d1.w - e.dr).abs() < 1e-12);
            assert!((d2.truncate() - e.ddc).length() < 1e-12);
        }
    }
}
