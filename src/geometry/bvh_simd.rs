//! The BVH's kernels in AVX2: the compressed wide node's test of its eight children in
//! one register, and the triangles of a node's leaves eight at a time.
//!
//! obvhs walks its 8-wide nodes with a 4-wide SSE test (two passes per node) and hands
//! the leaves' primitives to the caller one by one. Here:
//!
//! - [`node_hits_avx2`] tests the eight child boxes in one pass. Each operation is
//!   obvhs's (`CwBvhNode::intersect_ray_simd`), in the same order and without FMA, so
//!   the hit mask is the same bits;
//! - [`LeafTriangles`] keeps a triangle-only BVH's triangles in leaf order as structure
//!   of arrays, and [`LeafTriangles::nearest_avx2`] / [`LeafTriangles::any_avx2`] test
//!   all the primitives a node visit yields (at most 24, consecutive from the node's
//!   first primitive, padded by [`pad_node_groups`] to start a block) in registers of eight with `flat_simd`'s Moller-Trumbore. Among
//!   equal distances the highest primitive wins, which is what obvhs's order (highest
//!   bit first, strict `<`) gives one by one.
//!
//! So the walk visits the same nodes and returns the same hit, bit for bit, as the
//! baseline walk (`tests/it/isa.rs`, and the tests below against obvhs's own test).
//!
//! Callers must have checked that the CPU supports AVX2 (`cpu::Isa::supported`).

#![cfg(target_arch = "x86_64")]

use super::flat_simd::{hmin_256, moller_trumbore_256, splat3_256};
use super::triangle::TriangleGeom;
use glam::{Vec3, Vec3A};
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray;
use std::arch::x86_64::*;

/// The smallest entry distance of obvhs's node test (`cwbvh::node::EPSILON`, which it
/// does not export).
const NODE_TMIN: f32 = 0.0001;

/// The children of `node` that `ray` enters (within `ray.tmax`), as obvhs's
/// `CwBvhNode::intersect_ray` encodes them: the bits of inner children in the high
/// byte (by traversal priority under `oct_inv4`), the leaves' primitives in the low 24.
#[target_feature(enable = "avx2")]
#[inline]
pub fn node_hits_avx2(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    let dir_inv = node.compute_extent() * ray.inv_direction;
    let orig = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    // The eight quantised planes of one axis as f32 (exact: 0..=255).
    let q = |v: &[u8; 8]| {
        // SAFETY: 8 bytes.
        let b = unsafe { _mm_loadl_epi64(v.as_ptr() as *const __m128i) };
        _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(b))
    };
    let axis = |lo: &[u8; 8], hi: &[u8; 8], negative: bool, inv: f32, o: f32| {
        let (lo, hi) = (q(lo), q(hi));
        let (near, far) = if negative { (hi, lo) } else { (lo, hi) };
        let (inv, o) = (_mm256_set1_ps(inv), _mm256_set1_ps(o));
        (
            _mm256_add_ps(_mm256_mul_ps(near, inv), o),
            _mm256_add_ps(_mm256_mul_ps(far, inv), o),
        )
    };
    let planes = [
        (&node.child_min_x, &node.child_max_x),
        (&node.child_min_y, &node.child_max_y),
        (&node.child_min_z, &node.child_max_z),
    ];
    let [(tmin_x, tmax_x), (tmin_y, tmax_y), (tmin_z, tmax_z)] = std::array::from_fn(|k| {
        let (lo, hi) = planes[k];
        axis(lo, hi, ray.direction[k] < 0.0, dir_inv[k], orig[k])
    });
    let tmin = _mm256_max_ps(tmin_x, _mm256_max_ps(tmin_y, tmin_z));
    let tmax = _mm256_min_ps(tmax_x, _mm256_min_ps(tmax_y, tmax_z));
    let tmin = _mm256_max_ps(tmin, _mm256_set1_ps(NODE_TMIN));
    let tmax = _mm256_min_ps(tmax, _mm256_set1_ps(ray.tmax));
    let hit = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OQ>(tmin, tmax));
    // Child c contributes `child_bits[c] << bit_index[c]` when hit.
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let bytes = |x: u64| _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(x as i64));
    let bits = _mm256_and_si256(
        _mm256_sllv_epi32(bytes(child_bits8), bytes(bit_index8)),
        hit,
    );
    let x = _mm_or_si128(
        _mm256_castsi256_si128(bits),
        _mm256_extracti128_si256::<1>(bits),
    );
    let x = _mm_or_si128(x, _mm_shuffle_epi32::<0b01_00_11_10>(x));
    let x = _mm_or_si128(x, _mm_shuffle_epi32::<0b10_11_00_01>(x));
    _mm_cvtsi128_si32(x) as u32
}

/// Lanes of a leaf block.
const LANES: usize = 8;

/// Gives every node's primitives a range of its own that starts at a multiple of
/// [`LANES`], so the leaf kernels load whole aligned blocks: rewrites each node's
/// `primitive_base_idx` and returns, for each slot of the new layout, the leaf-order
/// index of the primitive there (`None`: padding, which no node refers to). The walk
/// visits the same nodes and the same primitives in the same order as before.
pub fn pad_node_groups(bvh: &mut CwBvh) -> Vec<Option<u32>> {
    let mut slots = Vec::with_capacity(bvh.primitive_indices.len() * 3 / 2);
    for node in &mut bvh.nodes {
        // The node's primitives: `primitive_base_idx + offset` for each leaf child,
        // `count` of them (unary in the meta byte's high bits).
        let mut end = 0u32;
        for (j, &meta) in node.child_meta.iter().enumerate() {
            if meta != 0 && node.imask & (1 << j) == 0 {
                end = end.max((meta & 0x1f) as u32 + (meta >> 5).count_ones());
            }
        }
        if end == 0 {
            continue;
        }
        let base = slots.len() as u32;
        slots.extend((0..end).map(|k| Some(node.primitive_base_idx + k)));
        slots.resize(slots.len().next_multiple_of(LANES), None);
        node.primitive_base_idx = base;
    }
    slots
}

/// A triangle-only BVH's triangles in the layout of [`pad_node_groups`], in blocks of
/// eight: each block holds one array of eight per component (vertex, edges), 288
/// contiguous bytes, so a node's triangles are read from at most three blocks of their
/// own. Padding slots hold degenerate triangles (never hit). 36 bytes per slot.
#[derive(Clone, Debug)]
pub struct LeafTriangles {
    /// Per block: v0.x of its eight triangles, v0.y, v0.z, e1.x, ..., e2.z.
    blocks: Vec<[[f32; LANES]; 9]>,
}

impl LeafTriangles {
    /// `tris[k]` is slot `k` (`None`: padding).
    pub fn new(tris: &[Option<TriangleGeom>]) -> Self {
        let mut blocks = vec![[[0.0f32; LANES]; 9]; tris.len().div_ceil(LANES)];
        for (k, t) in tris.iter().enumerate() {
            if let Some(t) = t {
                let c = [
                    t.v0.x, t.v0.y, t.v0.z, t.e1.x, t.e1.y, t.e1.z, t.e2.x, t.e2.y, t.e2.z,
                ];
                for (comp, v) in c.into_iter().enumerate() {
                    blocks[k / LANES][comp][k % LANES] = v;
                }
            }
        }
        LeafTriangles { blocks }
    }

    /// Slots stored.
    #[cfg(test)]
    fn len(&self) -> usize {
        self.blocks.len() * LANES
    }

    /// Slots `first + 8 chunk ..+ 8` (`first` a multiple of 8) against the ray:
    /// (t or infinity, b1, b2).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn chunk(
        &self,
        first: usize,
        chunk: usize,
        o: [__m256; 3],
        d: [__m256; 3],
    ) -> (__m256, __m256, __m256) {
        debug_assert!(first.is_multiple_of(LANES), "a node's group starts a block");
        let block = &self.blocks[first / LANES + chunk];
        // SAFETY: 8 f32 each.
        let ld = |k: usize| unsafe { _mm256_loadu_ps(block[k].as_ptr()) };
        moller_trumbore_256(
            [ld(0), ld(1), ld(2)],
            [ld(3), ld(4), ld(5)],
            [ld(6), ld(7), ld(8)],
            o,
            d,
        )
    }

    /// The nearest hit closer than `tmax` among triangles `first + k` for the bits `k`
    /// of `group` (below 24): (k, t, b1, b2). Among equal distances the highest `k`.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub fn nearest_avx2(
        &self,
        first: u32,
        group: u32,
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> Option<(u32, f32, f32, f32)> {
        let (ov, dv) = (splat3_256(o), splat3_256(d));
        let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let inf = _mm256_set1_ps(f32::INFINITY);
        let mut best: Option<(u32, f32, f32, f32)> = None;
        let mut limit = tmax;
        // Highest chunk first: with a strict `<` across chunks and the highest lane
        // within one, ties go to the highest primitive.
        for (chunk, bits) in chunks(group).rev() {
            let (t, b1, b2) = self.chunk(first as usize, chunk, ov, dv);
            let wanted = _mm256_cmpeq_epi32(
                _mm256_and_si256(_mm256_set1_epi32(bits as i32), lane_bits),
                lane_bits,
            );
            let t = _mm256_blendv_ps(inf, t, _mm256_castsi256_ps(wanted));
            let m = hmin_256(t);
            if m < limit {
                let at_m = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(t, _mm256_set1_ps(m)));
                let lane = 31 - (at_m as u32).leading_zeros();
                let mut b = [[0.0f32; 8]; 2];
                // SAFETY: 8 f32 each.
                unsafe {
                    _mm256_storeu_ps(b[0].as_mut_ptr(), b1);
                    _mm256_storeu_ps(b[1].as_mut_ptr(), b2);
                }
                best = Some((
                    8 * chunk as u32 + lane,
                    m,
                    b[0][lane as usize],
                    b[1][lane as usize],
                ));
                limit = m;
            }
        }
        best
    }

    /// Whether any triangle `first + k` for the bits `k` of `group` is hit before `tmax`.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub fn any_avx2(&self, first: u32, group: u32, o: Vec3, d: Vec3, tmax: f32) -> bool {
        let (ov, dv) = (splat3_256(o), splat3_256(d));
        let limit = _mm256_set1_ps(tmax);
        for (chunk, bits) in chunks(group) {
            let (t, _, _) = self.chunk(first as usize, chunk, ov, dv);
            let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(t, limit)) as u32;
            if hit & bits != 0 {
                return true;
            }
        }
        false
    }
}

/// The registers of eight a group of at most 24 primitives needs: (chunk, its 8 bits),
/// the empty ones left out.
#[inline(always)]
fn chunks(group: u32) -> impl DoubleEndedIterator<Item = (usize, u32)> {
    (0..3usize)
        .map(move |chunk| (chunk, (group >> (8 * chunk)) & 0xff))
        .filter(|&(_, bits)| bits != 0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::Isa;
    use crate::math::rng::Pcg32;

    fn avx2() -> bool {
        Isa::Avx2.supported()
    }

    /// A cloud of random triangles and its obvhs BVH.
    fn cloud(n: usize, seed: u64) -> (Vec<TriangleGeom>, obvhs::cwbvh::CwBvh) {
        let mut rng = Pcg32::new(seed, 3);
        let mut v = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let tris: Vec<TriangleGeom> = (0..n)
            .map(|_| {
                let a = v() * 4.0 - Vec3::splat(2.0);
                TriangleGeom::new(a, a + (v() - 0.5) * 0.6, a + (v() - 0.5) * 0.6)
            })
            .collect();
        let aabbs: Vec<obvhs::aabb::Aabb> = tris
            .iter()
            .map(|t| {
                let (a, b, c) = (t.v0, t.v0 + t.e1, t.v0 + t.e2);
                obvhs::aabb::Aabb::new(a.min(b).min(c).into(), a.max(b).max(c).into())
            })
            .collect();
        let bvh = obvhs::cwbvh::builder::build_cwbvh(
            &aabbs,
            obvhs::BvhBuildParams::medium_build(),
            &mut std::time::Duration::default(),
        );
        (tris, bvh)
    }

    #[test]
    fn the_node_test_is_obvhs_bit_for_bit() {
        if !avx2() {
            eprintln!("no AVX2: skipped");
            return;
        }
        let (_, bvh) = cloud(3000, 1);
        let mut rng = Pcg32::new(9, 9);
        let mut tested = 0;
        let mut some_hit = 0;
        for _ in 0..2000 {
            let o = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
            let d = (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
                .normalize_or(Vec3A::Z);
            // Axis-aligned directions too (infinite inverses).
            let d = if rng.next_f32() < 0.1 { Vec3A::X } else { d };
            let tmax = if rng.next_f32() < 0.5 {
                f32::INFINITY
            } else {
                rng.next_f32() * 4.0
            };
            let ray = Ray::new(o, d, 0.0, tmax);
            let oct = bvh.new_traversal(d).oct_inv4;
            for node in &bvh.nodes {
                let want = node.intersect_ray(&ray, oct);
                // SAFETY: AVX2 checked above.
                let got = unsafe { node_hits_avx2(node, &ray, oct) };
                assert_eq!(got, want, "node {node:?} o {o} d {d} tmax {tmax}");
                tested += 1;
                some_hit += (want != 0) as usize;
            }
        }
        // Most nodes are small and missed: about 1.5% of the tests hit something.
        assert!(tested > 100_000 && some_hit > 5_000, "{tested} {some_hit}");
    }

    /// A slow reference: each wanted triangle by `TriangleGeom::intersect`, highest
    /// first with a strict `<` (obvhs's order).
    fn nearest_ref(
        tris: &[TriangleGeom],
        first: u32,
        group: u32,
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> Option<(u32, f32, f32, f32)> {
        let mut best = None;
        let mut limit = tmax;
        for k in (0..24u32).rev() {
            if group & (1 << k) == 0 {
                continue;
            }
            if let Some((t, b1, b2)) = tris[(first + k) as usize].intersect(o, d, 0.0) {
                if t < limit {
                    best = Some((k, t, b1, b2));
                    limit = t;
                }
            }
        }
        best
    }

    #[test]
    fn leaf_groups_match_the_triangles_one_by_one() {
        if !avx2() {
            eprintln!("no AVX2: skipped");
            return;
        }
        let (mut tris, _) = cloud(200, 2);
        // Ties: a duplicate of triangle 8 at 8 + 13 and of 40 at 40 + 8.
        tris[21] = tris[8];
        tris[48] = tris[40];
        let slots: Vec<Option<TriangleGeom>> = tris.iter().copied().map(Some).collect();
        let leaf = LeafTriangles::new(&slots);
        assert_eq!(leaf.len(), 200);
        let mut rng = Pcg32::new(4, 4);
        let (mut hits, mut ties) = (0, 0);
        for i in 0..40_000 {
            let first = match i % 3 {
                0 => 8,
                1 => 40,
                _ => 8 * (rng.next_u32() % 25),
            };
            let group = rng.next_u32() & 0x00ff_ffff;
            let group = if first + 24 > 200 {
                group & ((1 << (200 - first)) - 1)
            } else {
                group
            };
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - 3.0;
            let target = tris[(first + rng.next_u32() % 24).min(199) as usize].point(0.3, 0.3);
            let d = (target - o).normalize_or(Vec3::Z);
            let tmax = if i % 2 == 0 {
                f32::INFINITY
            } else {
                rng.next_f32() * 5.0
            };
            let want = nearest_ref(&tris, first, group, o, d, tmax);
            // SAFETY: AVX2 checked above.
            let got = unsafe { leaf.nearest_avx2(first, group, o, d, tmax) };
            let bits = |h: Option<(u32, f32, f32, f32)>| {
                h.map(|(k, t, b1, b2)| (k, t.to_bits(), b1.to_bits(), b2.to_bits()))
            };
            assert_eq!(
                bits(got),
                bits(want),
                "first {first} group {group:#x} o {o} d {d}"
            );
            // SAFETY: AVX2 checked above.
            let any = unsafe { leaf.any_avx2(first, group, o, d, tmax) };
            assert_eq!(any, want.is_some());
            if let Some((k, ..)) = want {
                hits += 1;
                ties += ((first == 8 && k == 13 && group & 1 != 0)
                    || (first == 40 && k == 8 && group & 1 != 0)) as usize;
            }
        }
        assert!(hits > 5_000 && ties > 50, "hits {hits} ties {ties}");
    }

    #[test]
    fn padding_keeps_every_node_s_primitives_in_order() {
        let (_, mut bvh) = cloud(5000, 7);
        let before: Vec<CwBvhNode> = bvh.nodes.clone();
        let slots = pad_node_groups(&mut bvh);
        let mut seen = vec![0u32; 5000];
        for (old, new) in before.iter().zip(&bvh.nodes) {
            let mut end = 0;
            for (j, &meta) in old.child_meta.iter().enumerate() {
                if meta != 0 && old.imask & (1 << j) == 0 {
                    end = end.max((meta & 0x1f) as u32 + (meta >> 5).count_ones());
                }
            }
            if end == 0 {
                continue;
            }
            assert_eq!(new.primitive_base_idx % 8, 0);
            for k in 0..end {
                let slot = slots[(new.primitive_base_idx + k) as usize];
                assert_eq!(slot, Some(old.primitive_base_idx + k));
                seen[bvh.primitive_indices[(old.primitive_base_idx + k) as usize] as usize] += 1;
            }
        }
        // Every primitive in exactly one node; padding under a third of the slots.
        assert!(seen.iter().all(|&c| c == 1));
        assert!(
            slots.len().is_multiple_of(8) && slots.len() < 5000 * 3 / 2,
            "{}",
            slots.len()
        );
    }
}
