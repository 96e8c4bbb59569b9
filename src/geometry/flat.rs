//! Tiny scenes (a Cornell box has 36 triangles) are intersected without a tree: the
//! triangles are tested sixteen at a time in structure-of-arrays packets that the
//! compiler vectorises (one AVX-512 register per component, two AVX2 or four SSE ones;
//! `cpu` compiles the tracer once per instruction set). For such scenes this
//! beats walking the BVH; bigger scenes use the BVH.
//!
//! Packets hold whole groups (shapes) where they fit, and each packet has a bounding box:
//! a ray skips a packet whose box it misses or enters beyond the nearest hit so far
//! (packets are tested largest box first, so the walls of a room come before the
//! objects in it). The box is padded, so the skip is conservative.
//!
//! The nearest hit is kept per lane across packets and reduced across lanes once at the
//! end; among equal distances the lowest triangle index wins, so the result is the same
//! as testing the triangles one by one in order with a strict `<`.

use super::triangle::TriangleGeom;
use glam::Vec3;

/// Per-lane nearest hits: distance, triangle index (`u32::MAX`: none), barycentrics.
pub(super) struct LaneBest {
    pub(super) t: [f32; LANES],
    pub(super) index: [u32; LANES],
    pub(super) b1: [f32; LANES],
    pub(super) b2: [f32; LANES],
}

/// A hit: (triangle index, t, b1, b2).
pub type Nearest = (usize, f32, f32, f32);

impl LaneBest {
    /// Among the lanes in `mask` (all at the nearest distance), the lowest index.
    #[inline(always)]
    pub(super) fn pick(&self, mut mask: u32) -> Option<Nearest> {
        let mut best: Option<Nearest> = None;
        while mask != 0 {
            let k = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let index = self.index[k] as usize;
            if best.is_none_or(|b| index < b.0) {
                best = Some((index, self.t[k], self.b1[k], self.b2[k]));
            }
        }
        best
    }
}

/// Scenes with at most this many triangles (and spheres) skip the BVH.
pub const FLAT_MAX: usize = 64;

pub(super) const LANES: usize = 16;

/// Sixteen triangles, one component per array, with their padded bounding box.
#[derive(Clone, Copy, Debug)]
pub(super) struct Packet {
    pub(super) v0: [[f32; LANES]; 3],
    pub(super) e1: [[f32; LANES]; 3],
    pub(super) e2: [[f32; LANES]; 3],
    /// The caller's index of the triangle in each lane (`u32::MAX`: empty lane).
    pub(super) index: [u32; LANES],
    pub(super) lo: Vec3,
    pub(super) hi: Vec3,
}

/// The boxes of up to eight consecutive packets, one array per bound component, so that
/// the AVX2 kernels test a ray against eight boxes in one pass (`flat_simd.rs`). Lanes
/// past the last packet hold empty boxes (`lo = +inf`, `hi = -inf`) and are never
/// met (`lanes`).
#[derive(Clone, Copy, Debug)]
pub(super) struct BoxBlock {
    pub(super) lo: [[f32; BOX_LANES]; 3],
    pub(super) hi: [[f32; BOX_LANES]; 3],
    /// The lanes holding a packet's box (bit per lane).
    pub(super) lanes: u32,
}

/// Packets per [`BoxBlock`].
pub(super) const BOX_LANES: usize = 8;

#[derive(Clone, Debug)]
pub struct FlatTriangles {
    packets: Vec<Packet>,
    /// The packets' boxes, [`BOX_LANES`] per block, in packet order.
    boxes: Vec<BoxBlock>,
}

impl FlatTriangles {
    /// Packs `tris` in order, sixteen per packet; index `i` is `tris[i]`.
    pub fn new(tris: &[TriangleGeom]) -> Self {
        let groups: Vec<u32> = (0..tris.len() as u32).map(|i| i / LANES as u32).collect();
        Self::with_groups(tris, &groups)
    }

    /// Packs `tris`, keeping each run of equal `groups` (a shape) in one packet where it
    /// fits: groups go first-fit into packets, a group larger than a packet fills its
    /// own. Unused lanes hold degenerate triangles that never hit.
    pub fn with_groups(tris: &[TriangleGeom], groups: &[u32]) -> Self {
        assert_eq!(tris.len(), groups.len());
        // Runs of equal group ids, split into packet-sized pieces.
        let mut pieces: Vec<Vec<usize>> = Vec::new();
        let mut start = 0;
        while start < tris.len() {
            let mut end = start + 1;
            while end < tris.len() && groups[end] == groups[start] {
                end += 1;
            }
            let run: Vec<usize> = (start..end).collect();
            pieces.extend(run.chunks(LANES).map(|c| c.to_vec()));
            start = end;
        }
        // First fit.
        let mut bins: Vec<Vec<usize>> = Vec::new();
        for piece in pieces {
            match bins.iter_mut().find(|b| b.len() + piece.len() <= LANES) {
                Some(b) => b.extend(piece),
                None => bins.push(piece),
            }
        }
        let mut packets: Vec<Packet> = bins.iter().map(|b| Self::pack(tris, b)).collect();
        // Largest box first: the enclosing walls before the objects they enclose.
        let area = |p: &Packet| {
            let e = p.hi - p.lo;
            e.x * e.y + e.y * e.z + e.z * e.x
        };
        packets.sort_by(|a, b| area(b).total_cmp(&area(a)));
        let boxes = packets
            .chunks(BOX_LANES)
            .map(|chunk| {
                let mut b = BoxBlock {
                    lo: [[f32::INFINITY; BOX_LANES]; 3],
                    hi: [[f32::NEG_INFINITY; BOX_LANES]; 3],
                    lanes: (1u32 << chunk.len()) - 1,
                };
                for (k, p) in chunk.iter().enumerate() {
                    for a in 0..3 {
                        b.lo[a][k] = p.lo[a];
                        b.hi[a][k] = p.hi[a];
                    }
                }
                b
            })
            .collect();
        FlatTriangles { packets, boxes }
    }

    pub(super) fn packets(&self) -> &[Packet] {
        &self.packets
    }

    /// The packets' boxes in blocks of [`BOX_LANES`]: block `j` holds packets
    /// `j * BOX_LANES ..`.
    pub(super) fn boxes(&self) -> &[BoxBlock] {
        &self.boxes
    }

    fn pack(tris: &[TriangleGeom], members: &[usize]) -> Packet {
        let mut p = Packet {
            v0: [[0.0; LANES]; 3],
            e1: [[0.0; LANES]; 3],
            e2: [[0.0; LANES]; 3],
            index: [u32::MAX; LANES],
            lo: Vec3::splat(f32::INFINITY),
            hi: Vec3::splat(f32::NEG_INFINITY),
        };
        for (k, &i) in members.iter().enumerate() {
            let t = &tris[i];
            for a in 0..3 {
                p.v0[a][k] = t.v0[a];
                p.e1[a][k] = t.e1[a];
                p.e2[a][k] = t.e2[a];
            }
            p.index[k] = i as u32;
            for v in [t.v0, t.v0 + t.e1, t.v0 + t.e2] {
                p.lo = p.lo.min(v);
                p.hi = p.hi.max(v);
            }
        }
        // Pad by a relative margin so rounding in the box test never skips a hit.
        let pad = (p.hi - p.lo).max_element() * 1e-3
            + 1e-4 * p.lo.abs().max(p.hi.abs()).max_element()
            + 1e-6;
        p.lo -= Vec3::splat(pad);
        p.hi += Vec3::splat(pad);
        p
    }

    /// Whether the ray `o + t d` (with `inv_d = 1 / d`) meets the packet's box at some
    /// `t` in `[0, tmax]`. Never skips a packet the ray can hit: rounding is covered by
    /// the box's padding, and a slab whose distance is NaN (the origin on a face's
    /// plane, that direction component zero) only arises for a ray that runs in that
    /// plane, outside the triangles' own box, so it hits none of them whatever the
    /// test says (`tests::a_ray_in_a_padded_face_plane_hits_no_triangle`).
    #[inline(always)]
    pub(super) fn box_hit(p: &Packet, o: Vec3, inv_d: Vec3, tmax: f32) -> bool {
        let t0 = (p.lo - o) * inv_d;
        let t1 = (p.hi - o) * inv_d;
        let near = t0.min(t1);
        let far = t0.max(t1);
        let enter = 0.0f32.max(near.x).max(near.y).max(near.z);
        let exit = tmax.min(far.x).min(far.y).min(far.z);
        enter <= exit
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
            // Non-short-circuit `&` keeps the lanes branch-free (vectorisable).
            let hit = (det != 0.0)
                & det.is_finite()
                & (0.0..=1.0).contains(&u)
                & (v >= 0.0)
                & (u + v <= 1.0)
                & (dist > 0.0);
            t[k] = if hit { dist } else { f32::INFINITY };
            b1[k] = u;
            b2[k] = v;
        }
        (t, b1, b2)
    }

    /// The nearest triangle hit before `tmax`: (index, t, b1, b2).
    #[inline(always)]
    pub fn intersect(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<(usize, f32, f32, f32)> {
        Self::reduce(self.lanes(o, d, tmax), tmax)
    }

    /// Per-lane nearest hits (portable kernel).
    #[inline(always)]
    fn lanes(&self, o: Vec3, d: Vec3, tmax: f32) -> LaneBest {
        let inv_d = d.recip();
        let mut best = LaneBest {
            t: [tmax; LANES],
            index: [u32::MAX; LANES],
            b1: [0.0; LANES],
            b2: [0.0; LANES],
        };
        let mut nearest = tmax;
        for p in &self.packets {
            if !Self::box_hit(p, o, inv_d, nearest) {
                continue;
            }
            let (t, b1, b2) = Self::packet(p, o, d);
            for k in 0..LANES {
                let closer = t[k] < best.t[k] || (t[k] == best.t[k] && p.index[k] < best.index[k]);
                if closer {
                    best.t[k] = t[k];
                    best.index[k] = p.index[k];
                    best.b1[k] = b1[k];
                    best.b2[k] = b2[k];
                }
            }
            nearest = best.t.iter().fold(nearest, |m, &t| m.min(t));
        }
        best
    }

    /// The nearest of the per-lane hits before `tmax`; among equal distances, the
    /// lowest index.
    #[inline(always)]
    fn reduce(lanes: LaneBest, tmax: f32) -> Option<(usize, f32, f32, f32)> {
        let mut best: Option<(usize, f32, f32, f32)> = None;
        for k in 0..LANES {
            let t = lanes.t[k];
            // t is never NaN: a lane's t is a hit distance (> 0) or tmax/infinity.
            if lanes.index[k] == u32::MAX || t >= tmax {
                continue;
            }
            let index = lanes.index[k] as usize;
            let better = match best {
                None => true,
                Some((i, bt, _, _)) => t < bt || (t == bt && index < i),
            };
            if better {
                best = Some((index, t, lanes.b1[k], lanes.b2[k]));
            }
        }
        best
    }

    /// True when any triangle is hit before `tmax`.
    #[inline(always)]
    pub fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        let inv_d = d.recip();
        for p in &self.packets {
            if !Self::box_hit(p, o, inv_d, tmax) {
                continue;
            }
            let t = Self::packet(p, o, d).0;
            if t.iter().fold(false, |any, &t| any | (t < tmax)) {
                return true;
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::{Avx2, Avx512, Isa};
    use crate::geometry::accel::{flat_intersect_with, flat_occluded_with};
    use crate::math::rng::Pcg32;

    #[test]
    fn matches_the_scalar_test_on_random_rays() {
        let mut rng = Pcg32::new(1, 2);
        let mut r = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
        // In order, and grouped in runs (first fit, boxes sorted): same answers.
        let groups: Vec<u32> = [
            2, 3, 5, 1, 7, 3, 2, 4, 2, 6, 1, 9, 8, 3, 2, 5, 9, 6, 1, 4, 3,
        ]
        .iter()
        .enumerate()
        .flat_map(|(g, &n)| std::iter::repeat_n(g as u32, n))
        .collect();
        // Each group clustered around its own centre, so that box tests skip packets.
        let centres: Vec<Vec3> = (0..21).map(|_| r()).collect();
        let tris: Vec<TriangleGeom> = groups
            .iter()
            .map(|&g| {
                let c = centres[g as usize];
                TriangleGeom::new(c + r() * 0.3, c + r() * 0.3, c + r() * 0.3)
            })
            .collect();
        let flats = [
            FlatTriangles::new(&tris),
            FlatTriangles::with_groups(&tris, &groups),
        ];
        for flat in &flats {
            check(&tris, flat);
        }
        // More than one block of eight boxes (runs of nine: a packet each), and a
        // single packet (its own path in the AVX2 kernels).
        let nines: Vec<u32> = (0..tris.len() as u32).map(|i| i / 9).collect();
        let blocks = FlatTriangles::with_groups(&tris, &nines);
        assert!(blocks.boxes().len() > 1, "{}", blocks.packets().len());
        check(&tris, &blocks);
        let one = FlatTriangles::new(&tris[..12]);
        assert_eq!(one.packets().len(), 1);
        check(&tris[..12], &one);
    }

    fn check(tris: &[TriangleGeom], flat: &FlatTriangles) {
        let mut rng = Pcg32::new(3, 4);
        let mut r = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
        let mut hits = 0;
        for i in 0..4000 {
            // From outside towards the cluster, and from inside it.
            let o = r() * if i % 2 == 0 { 3.0 } else { 0.8 };
            let d = (r() * 0.5 - o).normalize();
            let scalar = tris
                .iter()
                .enumerate()
                .filter_map(|(i, t)| t.intersect(o, d, 0.0).map(|h| (i, h.0)))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let got = flat.intersect(o, d, f32::INFINITY);
            assert_eq!(got.map(|g| g.0), scalar.map(|s| s.0));
            // The SIMD kernels give the same bits (where this CPU has them).
            for isa in [Isa::Avx2, Isa::Avx512] {
                for tmax in [f32::INFINITY, got.map_or(1.0, |g| g.1 * 1.5)] {
                    let (simd, blocked) = match (isa, Avx2::detect(), Avx512::detect()) {
                        (Isa::Avx2, Some(l), _) => (
                            flat_intersect_with(l, flat, o, d, tmax),
                            flat_occluded_with(l, flat, o, d, tmax),
                        ),
                        (Isa::Avx512, _, Some(l)) => (
                            flat_intersect_with(l, flat, o, d, tmax),
                            flat_occluded_with(l, flat, o, d, tmax),
                        ),
                        // This CPU lacks the level.
                        _ => continue,
                    };
                    let portable = flat.intersect(o, d, tmax);
                    let bits = |h: Option<Nearest>| {
                        h.map(|(i, t, b1, b2)| (i, t.to_bits(), b1.to_bits(), b2.to_bits()))
                    };
                    assert_eq!(bits(simd), bits(portable), "{isa:?}");
                    assert_eq!(blocked, flat.occluded(o, d, tmax), "{isa:?}");
                }
            }
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

    /// The box test's NaN case is harmless: a ray that starts on a padded face plane of
    /// a packet's box and runs in that plane hits none of the packet's triangles.
    #[test]
    fn a_ray_in_a_padded_face_plane_hits_no_triangle() {
        let mut rng = Pcg32::new(7, 8);
        let mut r = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
        for _ in 0..50 {
            let tris: Vec<TriangleGeom> =
                (0..16).map(|_| TriangleGeom::new(r(), r(), r())).collect();
            let flat = FlatTriangles::new(&tris);
            let p = &flat.packets()[0];
            for a in 0..3 {
                for face in [p.lo[a], p.hi[a]] {
                    for _ in 0..40 {
                        let mut o = r() * 1.5;
                        o[a] = face;
                        let mut d = r();
                        d[a] = 0.0;
                        let d = d.normalize();
                        for t in &tris {
                            assert!(t.intersect(o, d, 0.0).is_none());
                        }
                    }
                }
            }
        }
    }
}
