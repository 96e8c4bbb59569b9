//! Tiny scenes (a Cornell box has 36 triangles) are intersected without a tree: every
//! triangle is tested, eight at a time in structure-of-arrays packets that the compiler
//! vectorises. For such scenes this beats walking the BVH; bigger scenes use the BVH.

use super::triangle::TriangleGeom;
use glam::Vec3;

/// Scenes with at most this many triangles (and spheres) skip the BVH.
pub const FLAT_MAX: usize = 64;

const LANES: usize = 8;

/// Eight triangles, one component per array.
#[derive(Clone, Copy, Debug)]
struct Packet {
    v0: [[f32; LANES]; 3],
    e1: [[f32; LANES]; 3],
    e2: [[f32; LANES]; 3],
}

#[derive(Clone, Debug)]
pub struct FlatTriangles {
    packets: Vec<Packet>,
}

impl FlatTriangles {
    /// Packs `tris`; unused lanes hold degenerate triangles that never hit.
    pub fn new(tris: &[TriangleGeom]) -> Self {
        let packets = tris
            .chunks(LANES)
            .map(|chunk| {
                let mut p = Packet {
                    v0: [[0.0; LANES]; 3],
                    e1: [[0.0; LANES]; 3],
                    e2: [[0.0; LANES]; 3],
                };
                for (k, t) in chunk.iter().enumerate() {
                    for a in 0..3 {
                        p.v0[a][k] = t.v0[a];
                        p.e1[a][k] = t.e1[a];
                        p.e2[a][k] = t.e2[a];
                    }
                }
                p
            })
            .collect();
        FlatTriangles { packets }
    }

    /// Moller-Trumbore on one packet: t per lane (infinity on a miss) and barycentrics.
    #[inline(always)]
    fn packet(p: &Packet, o: Vec3, d: Vec3) -> ([f32; LANES], [f32; LANES], [f32; LANES]) {
        let (mut t, mut b1, mut b2) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
        for k in 0..LANES {
            let (e1x, e1y, e1z) = (p.e1[0][k], p.e1[1][k], p.e1[2][k]);
            let (e2x, e2y, e2z) = (p.e2[0][k], p.e2[1][k], p.e2[2][k]);
            // pvec = d x e2
            let (px, py, pz) = (
                d.y * e2z - d.z * e2y,
                d.z * e2x - d.x * e2z,
                d.x * e2y - d.y * e2x,
            );
            let det = e1x * px + e1y * py + e1z * pz;
            let inv = 1.0 / det;
            let (tx, ty, tz) = (o.x - p.v0[0][k], o.y - p.v0[1][k], o.z - p.v0[2][k]);
            let u = (tx * px + ty * py + tz * pz) * inv;
            // qvec = tvec x e1
            let (qx, qy, qz) = (
                ty * e1z - tz * e1y,
                tz * e1x - tx * e1z,
                tx * e1y - ty * e1x,
            );
            let v = (d.x * qx + d.y * qy + d.z * qz) * inv;
            let dist = (e2x * qx + e2y * qy + e2z * qz) * inv;
            let hit = det != 0.0
                && det.is_finite()
                && (0.0..=1.0).contains(&u)
                && v >= 0.0
                && u + v <= 1.0
                && dist > 0.0;
            t[k] = if hit { dist } else { f32::INFINITY };
            b1[k] = u;
            b2[k] = v;
        }
        (t, b1, b2)
    }

    /// The nearest triangle hit before `tmax`: (index, t, b1, b2).
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<(usize, f32, f32, f32)> {
        let mut best: Option<(usize, f32, f32, f32)> = None;
        let mut best_t = tmax;
        for (pi, p) in self.packets.iter().enumerate() {
            let (t, b1, b2) = Self::packet(p, o, d);
            for k in 0..LANES {
                if t[k] < best_t {
                    best_t = t[k];
                    best = Some((pi * LANES + k, t[k], b1[k], b2[k]));
                }
            }
        }
        best
    }

    /// True when any triangle is hit before `tmax`.
    #[inline]
    pub fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        self.packets
            .iter()
            .any(|p| Self::packet(p, o, d).0.iter().any(|&t| t < tmax))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::Pcg32;

    #[test]
    fn matches_the_scalar_test_on_random_rays() {
        let mut rng = Pcg32::new(1, 2);
        let mut r = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
        let tris: Vec<TriangleGeom> = (0..21).map(|_| TriangleGeom::new(r(), r(), r())).collect();
        let flat = FlatTriangles::new(&tris);
        let mut hits = 0;
        for _ in 0..2000 {
            // From outside, towards the cluster of triangles.
            let o = r() * 3.0;
            let d = (r() * 0.5 - o).normalize();
            let scalar = tris
                .iter()
                .enumerate()
                .filter_map(|(i, t)| t.intersect(o, d, 0.0).map(|h| (i, h.0)))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let got = flat.intersect(o, d, f32::INFINITY);
            assert_eq!(got.map(|g| g.0), scalar.map(|s| s.0));
            if let (Some(g), Some(s)) = (got, scalar) {
                assert!((g.1 - s.1).abs() <= 1e-5 * s.1.max(1.0));
                hits += 1;
                assert!(flat.occluded(o, d, s.1 * 1.001));
                assert!(!flat.occluded(o, d, s.1 * 0.999));
            } else {
                assert!(!flat.occluded(o, d, f32::INFINITY));
            }
        }
        assert!(hits > 200, "{hits}");
    }
}
