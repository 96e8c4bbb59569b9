//! Curve shapes (`linearcurve`, `bsplinecurve`): intersection against slow references,
//! the straight constant-radius B-spline against the analytic cylinder, normals against
//! the surface, and a rendered silhouette against its closed-form area.

use crate::common;

use glam::{DVec3, DVec4, Vec3, Vec4};
use tstat::geometry::curve::{CurveGeom, CurveKind, Segment};
use tstat::math::rng::Pcg32;
use tstat::scene::Overrides;

fn curve(kind: CurveKind, points: &[Vec4]) -> CurveGeom {
    let span = kind.span();
    CurveGeom {
        kind,
        points: points.to_vec(),
        segments: (0..=(points.len() - span) as u32).collect(),
        first: (0..=points.len() - span).map(|i| i == 0).collect(),
    }
}

/// The nearest hit over all segments: (t, segment, v).
fn hit(g: &CurveGeom, o: Vec3, d: Vec3) -> Option<(f32, usize, f32)> {
    (0..g.segments.len())
        .filter_map(|i| g.segment(i).intersect(o, d, 0.0).map(|(t, v)| (t, i, v)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

fn unit(rng: &mut Pcg32) -> DVec3 {
    loop {
        let v = DVec3::new(
            rng.next_f32() as f64,
            rng.next_f32() as f64,
            rng.next_f32() as f64,
        ) * 2.0
            - DVec3::ONE;
        if v.length_squared() > 1e-3 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

/// A ray from a sphere of radius 6 around the origin towards a random point of the box
/// [-2, 2] x [-1, 1] x [-1, 1] (f32, unit direction).
fn random_ray(rng: &mut Pcg32) -> (Vec3, Vec3) {
    let o = unit(rng) * 6.0;
    let target = DVec3::new(
        rng.next_f32() as f64 * 4.0 - 2.0,
        rng.next_f32() as f64 * 2.0 - 1.0,
        rng.next_f32() as f64 * 2.0 - 1.0,
    );
    (o.as_vec3(), (target - o).normalize().as_vec3())
}

/// Distance from `p` to the round linear curve, minus the radius: the swept sphere's
/// signed distance bound (convex in v on each segment: golden-section search).
fn linear_sdf(points: &[DVec4], p: DVec3) -> f64 {
    let mut best = f64::INFINITY;
    for w in points.windows(2) {
        let f = |v: f64| {
            let c = w[0] + (w[1] - w[0]) * v;
            (p - c.truncate()).length() - c.w
        };
        let (mut a, mut b) = (0.0f64, 1.0f64);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..80 {
            let (x1, x2) = (b - g * (b - a), a + g * (b - a));
            if f(x1) < f(x2) {
                b = x2;
            } else {
                a = x1;
            }
        }
        best = best.min(f(0.5 * (a + b)));
    }
    best
}

/// Sphere tracing of the swept spheres (a lower bound of the distance, so no surface is
/// stepped over), then bisection: the first entry, or None; `Err` for rays that graze
/// (come within 1e-6 without entering), which no tolerance decides.
fn linear_reference(points: &[DVec4], o: DVec3, d: DVec3) -> Result<Option<f64>, ()> {
    let mut t = 0.0;
    let mut closest = f64::INFINITY;
    for _ in 0..100_000 {
        let s = linear_sdf(points, o + t * d);
        if s < 1e-9 {
            // Bisect between the last two points (outside at t - step, inside or on at t).
            let (mut lo, mut hi) = ((t - 1e-3).max(0.0), t);
            while linear_sdf(points, o + lo * d) <= 0.0 && lo > 0.0 {
                lo = (lo - 1e-3).max(0.0);
            }
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if linear_sdf(points, o + mid * d) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return Ok(Some(hi));
        }
        closest = closest.min(s);
        t += s.max(1e-7);
        if t > 20.0 {
            break;
        }
    }
    if closest < 1e-6 {
        Err(())
    } else {
        Ok(None)
    }
}

#[test]
fn linear_segments_match_the_swept_sphere_reference() {
    let mut rng = Pcg32::new(11, 3);
    let (mut agreed, mut hits, mut grazing) = (0, 0, 0);
    for curve_no in 0..6 {
        // A random 4-point curve with radii in [0.05, 0.4], one with equal radii, one
        // with a zero radius at an end.
        let pts: Vec<Vec4> = (0..4)
            .map(|i| {
                let p = DVec3::new(i as f64 - 1.5, 0.0, 0.0) + unit(&mut rng) * 0.6;
                let r = match curve_no {
                    0 => 0.2,
                    1 if i == 0 => 0.0,
                    _ => 0.05 + 0.35 * rng.next_f32() as f64,
                };
                p.as_vec3().extend(r as f32)
            })
            .collect();
        let g = curve(CurveKind::Linear, &pts);
        let ref_pts: Vec<DVec4> = pts.iter().map(|p| p.as_dvec4()).collect();
        for _ in 0..150 {
            let (o, d) = random_ray(&mut rng);
            let Ok(want) = linear_reference(&ref_pts, o.as_dvec3(), d.as_dvec3()) else {
                grazing += 1;
                continue;
            };
            let got = hit(&g, o, d);
            match (want, got) {
                (None, None) => agreed += 1,
                (Some(w), Some((t, seg, v))) => {
                    assert!(
                        (t as f64 - w).abs() < 2e-5,
                        "curve {curve_no}: t {t} vs reference {w}"
                    );
                    // The reported sphere is the one the point lies on: |p - c(v)| = r(v).
                    let p = o + d * t;
                    let (a, b) = (pts[seg], pts[seg + 1]);
                    let c = a + (b - a) * v;
                    assert!(((p - c.truncate()).length() - c.w).abs() < 1e-4);
                    agreed += 1;
                    hits += 1;
                }
                _ => {
                    panic!("curve {curve_no}: ray {o} {d}: reference {want:?}, intersector {got:?}")
                }
            }
        }
    }
    assert!(
        hits > 150 && grazing < 10,
        "{agreed} agreed, {hits} hits, {grazing} grazing"
    );
}

/// Is `p` inside the B-spline's circle sweep: some u in (0, 1) has `p` in its normal
/// plane within the radius? Dense sampling of `(p - c(u))·c'(u)` and bisection; the
/// witness u is returned.
fn bspline_inside(b: &[DVec4; 4], p: DVec3) -> Option<f64> {
    let eval = |u: f64| {
        let s = 1.0 - u;
        let c = b[0] * (s * s * s)
            + b[1] * (3.0 * s * s * u)
            + b[2] * (3.0 * s * u * u)
            + b[3] * (u * u * u);
        let dc = (b[1] - b[0]) * (3.0 * s * s)
            + (b[2] - b[1]) * (6.0 * s * u)
            + (b[3] - b[2]) * (3.0 * u * u);
        (c, dc)
    };
    let f = |u: f64| {
        let (c, dc) = eval(u);
        (p - c.truncate()).dot(dc.truncate())
    };
    const N: usize = 200;
    let mut prev = f(0.0);
    for k in 1..=N {
        let (mut lo, mut hi) = ((k - 1) as f64 / N as f64, k as f64 / N as f64);
        let cur = f(hi);
        if (prev <= 0.0) != (cur <= 0.0) {
            let flo = prev;
            for _ in 0..50 {
                let mid = 0.5 * (lo + hi);
                if (f(mid) <= 0.0) == (flo <= 0.0) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let u = 0.5 * (lo + hi);
            let (c, _) = eval(u);
            if (p - c.truncate()).length() < c.w {
                return Some(u);
            }
        }
        prev = cur;
    }
    None
}

/// The first front hit of the sweep along the ray: marching in steps of 2e-3, bisecting
/// each outside-to-inside change; an entry through an open end (witness u within 1e-3 of
/// 0 or 1) is no hit, and a ray whose first entry lies within 0.02 of an end in u is
/// ambiguous (`Err`).
fn bspline_reference(b: &[DVec4; 4], o: DVec3, d: DVec3) -> Result<Option<f64>, ()> {
    let h = 2e-3;
    // March only through the sphere around the control hull (widened by the radii).
    let centre = (b[0] + b[3]).truncate() * 0.5;
    let reach = b
        .iter()
        .map(|p| (p.truncate() - centre).length() + p.w)
        .fold(0.0, f64::max);
    let along = (centre - o).dot(d);
    let mut t = (along - reach).max(0.0);
    let end = along + reach;
    let mut inside = bspline_inside(b, o + t * d).is_some();
    while t < end {
        let next = t + h;
        let now = bspline_inside(b, o + next * d).is_some();
        if now && !inside {
            let (mut lo, mut hi) = (t, next);
            for _ in 0..50 {
                let mid = 0.5 * (lo + hi);
                if bspline_inside(b, o + mid * d).is_some() {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            let u = bspline_inside(b, o + hi * d).unwrap();
            if !(0.02..=0.98).contains(&u) {
                return Err(());
            }
            return Ok(Some(hi));
        }
        inside = now;
        t = next;
    }
    Ok(None)
}

#[test]
fn bspline_segments_match_the_circle_sweep_reference() {
    let mut rng = Pcg32::new(12, 5);
    let (mut agreed, mut hits, mut ambiguous, mut total) = (0, 0, 0, 0);
    for curve_no in 0..3 {
        let pts: Vec<Vec4> = (0..4)
            .map(|i| {
                let p = DVec3::new(i as f64 * 1.2 - 1.8, 0.0, 0.0) + unit(&mut rng) * 0.7;
                let r = if curve_no == 0 {
                    0.15
                } else {
                    0.05 + 0.3 * rng.next_f32() as f64
                };
                p.as_vec3().extend(r as f32)
            })
            .collect();
        let g = curve(CurveKind::BSpline, &pts);
        let Segment::BSpline(seg) = g.segment(0) else {
            unreachable!()
        };
        // Rays aimed at points near the curve, so that most of them hit or graze it.
        for _ in 0..60 {
            let u = rng.next_f32() as f64;
            let s = 1.0 - u;
            let c = seg.b[0] * (s * s * s)
                + seg.b[1] * (3.0 * s * s * u)
                + seg.b[2] * (3.0 * s * u * u)
                + seg.b[3] * (u * u * u);
            let target = c.truncate() + unit(&mut rng) * c.w * 1.5;
            let o = target + unit(&mut rng) * 5.0;
            let (o, d) = (o.as_vec3(), (target - o).normalize().as_vec3());
            total += 1;
            let Ok(want) = bspline_reference(&seg.b, o.as_dvec3(), d.as_dvec3()) else {
                ambiguous += 1;
                continue;
            };
            let got = hit(&g, o, d);
            match (want, got) {
                (None, None) => agreed += 1,
                (Some(w), Some((t, _, _))) => {
                    assert!(
                        (t as f64 - w).abs() < 2e-5,
                        "curve {curve_no}: t {t} vs reference {w}"
                    );
                    agreed += 1;
                    hits += 1;
                }
                // Rays that enter for less than the marching step are the reference's
                // blind spot: allowed only when the intersector's hit grazes.
                (None, Some((t, seg_i, v))) => {
                    let n = g.normal(seg_i, v, o + d * t);
                    assert!(n.dot(d).abs() < 0.05, "curve {curve_no}: ray {o} {d}: reference misses, intersector hits at {t} facing {}", n.dot(d));
                    ambiguous += 1;
                }
                (Some(w), None) => panic!(
                    "curve {curve_no}: ray {o} {d}: reference hit at {w}, intersector misses"
                ),
            }
        }
    }
    assert!(
        hits > 60 && ambiguous * 10 < total,
        "{agreed} agreed, {hits} hits, {ambiguous} ambiguous of {total}"
    );
}

#[test]
fn a_straight_constant_radius_bspline_is_a_cylinder() {
    // Control points evenly spaced on a line: c(v) runs along it at constant speed from
    // the second control point to the third.
    let (a, e) = (DVec3::new(-0.4, 0.2, 0.1), DVec3::new(0.7, -0.3, 0.5));
    let r = 0.3;
    let pts: Vec<Vec4> = (0..4)
        .map(|i| (a + (e - a) * (i as f64 - 1.0)).as_vec3().extend(r as f32))
        .collect();
    let g = curve(CurveKind::BSpline, &pts);
    let axis = (e - a).normalize();
    let len = (e - a).length();
    let mut rng = Pcg32::new(3, 9);
    let (mut hits, mut misses) = (0, 0);
    for _ in 0..4000 {
        let target = a + (e - a) * (rng.next_f32() as f64 * 1.4 - 0.2) + unit(&mut rng) * 0.4;
        let o = target + unit(&mut rng) * 4.0;
        let d = (target - o).normalize();
        let (o32, d32) = (o.as_vec3(), d.as_vec3());
        let (o, d) = (o32.as_dvec3(), d32.as_dvec3().normalize());
        // The infinite cylinder's entry, kept when its axial position lies in [0, len].
        let w = o - a;
        let (wp, dp) = (w - w.dot(axis) * axis, d - d.dot(axis) * axis);
        let (qa, qb, qc) = (
            dp.length_squared(),
            2.0 * wp.dot(dp),
            wp.length_squared() - r * r,
        );
        let disc = qb * qb - 4.0 * qa * qc;
        let want = (disc >= 0.0 && qa > 0.0)
            .then(|| (-qb - disc.sqrt()) / (2.0 * qa))
            .filter(|&t| t > 0.0);
        let axial = want.map(|t| (o + t * d - a).dot(axis));
        if axial.is_some_and(|s| (s.abs() < 1e-4) || ((s - len).abs() < 1e-4)) || disc.abs() < 1e-6
        {
            continue;
        }
        let want = want.filter(|_| axial.is_some_and(|s| (0.0..=len).contains(&s)));
        let got = hit(&g, o32, d32);
        match (want, got) {
            (Some(w), Some((t, _, v))) => {
                assert!(
                    (t as f64 - w).abs() < 1e-5 * (1.0 + w),
                    "t {t} vs cylinder {w}"
                );
                let s = (o + t as f64 * d - a).dot(axis) / len;
                assert!((s - v as f64).abs() < 1e-5, "v {v} vs axial {s}");
                hits += 1;
            }
            (None, None) => misses += 1,
            _ => panic!("ray {o32} {d32}: cylinder {want:?}, curve {got:?}"),
        }
    }
    assert!(hits > 500 && misses > 500, "{hits} {misses}");
}

#[test]
fn normals_are_perpendicular_to_the_surface() {
    let pts = [
        Vec4::new(-1.5, 0.0, 0.0, 0.1),
        Vec4::new(-0.5, 0.8, 0.2, 0.3),
        Vec4::new(0.5, -0.4, -0.3, 0.2),
        Vec4::new(1.5, 0.3, 0.4, 0.25),
        Vec4::new(2.0, 0.0, 0.9, 0.1),
    ];
    for kind in [CurveKind::Linear, CurveKind::BSpline] {
        let g = curve(kind, &pts);
        let mut rng = Pcg32::new(7, 1);
        let mut checked = 0;
        for _ in 0..3000 {
            let (o, d) = random_ray(&mut rng);
            let Some((t, seg, v)) = hit(&g, o, d) else {
                continue;
            };
            let p = o + d * t;
            let n = g.normal(seg, v, p);
            assert!(
                (n.length() - 1.0).abs() < 1e-5 && n.dot(d) < 0.0,
                "{kind:?}: n {n} d {d}"
            );
            // Neighbouring hits (rays moved by 1e-3 across the ray) lie in the tangent
            // plane to second order.
            let (s, u) = {
                let a = d.any_orthonormal_vector();
                (a, d.cross(a))
            };
            let mut ok = true;
            let mut seen = 0;
            for off in [s, -s, u, -u] {
                if let Some((t2, seg2, _)) = hit(&g, o + off * 1e-3, d) {
                    let q = o + off * 1e-3 + d * t2;
                    let dist = (q - p).length();
                    if seg2 != seg || dist > 1e-2 {
                        continue;
                    }
                    seen += 1;
                    // Second order: a curvature of at most 30 bends the surface from
                    // the tangent plane by 15 dist^2; the f32 hit points add 1e-6.
                    ok &= ((q - p).dot(n) / dist).abs() < 15.0 * dist + 1e-6 / dist;
                }
            }
            if seen >= 2 {
                assert!(
                    ok,
                    "{kind:?}: normal {n} at {p} is not perpendicular to the surface"
                );
                checked += 1;
            }
        }
        assert!(checked > 200, "{kind:?}: {checked}");
    }
}

/// An orthographic view of one straight linear segment (black) against a white sky:
/// the dark share of the image is the capsule's silhouette, 2 r · 2 L + pi r^2.
#[test]
fn a_straight_segment_renders_its_capsule_silhouette() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("c.txt"), "-0.6 0 0 0.15\n0.6 0 0 0.15\n").unwrap();
    let xml = r#"<scene version="3.0.0">
  <integrator type="transient_path"><integer name="max_depth" value="2"/></integrator>
  <sensor type="orthographic">
    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/><scale x="1" y="1"/></transform>
    <film type="transient_hdr_film"><integer name="width" value="64"/><integer name="height" value="64"/>
      <integer name="temporal_bins" value="4"/><float name="bin_width_opl" value="10"/><float name="start_opl" value="0"/></film>
    <sampler type="independent"><integer name="sample_count" value="64"/></sampler>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
  <shape type="linearcurve"><string name="filename" value="c.txt"/>
    <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf></shape>
</scene>"#;
    let path = dir.path().join("scene.xml");
    std::fs::write(&path, xml).unwrap();
    let scene = tstat::scene::Scene::load(&path, &Overrides::default()).unwrap();
    let out = common::run(&scene, 1);
    let px = out.steady.len() / 3;
    let sky: f64 = out.steady.iter().step_by(3).sum::<f64>() / px as f64;
    // Mitsuba's orthographic camera sees [-1, 1]^2 (scaled by to_world): area 4.
    let (r, half) = (0.15f64, 0.6f64);
    let want = 1.0 - (2.0 * r * 2.0 * half + std::f64::consts::PI * r * r) / 4.0;
    // 64 x 64 x 64 samples: the binomial standard error of the dark share is 1.7e-3.
    assert!(
        (sky - want).abs() < 6e-3,
        "lit share {sky}, closed form {want}"
    );
}
