//! The flat packets' kernels in explicit AVX-512 (one 16-lane register per component)
//! and AVX2 (two 8-lane halves). Compilers do not vectorise the 16-lane Moller-Trumbore
//! loop of `flat.rs` on their own (it is unrolled before the loop vectoriser sees it),
//! so these spell it out. Each operation is the scalar kernel's, in the same order and
//! without FMA, so every lane computes the same bits as `FlatTriangles::packet`; the
//! tests compare both on random rays.
//!
//! Callers must have checked that the CPU supports the instruction set
//! (`cpu::Isa::supported`).

#![cfg(target_arch = "x86_64")]

use super::flat::{BoxBlock, FlatTriangles, LaneBest, Nearest, Packet, BOX_LANES, LANES};
use glam::Vec3;
use std::arch::x86_64::*;

// ---------------------------------------------------------------- AVX-512

/// Moller-Trumbore on 16 lanes: (t or infinity, b1, b2).
#[target_feature(enable = "avx512f")]
#[inline]
fn packet_512(p: &Packet, o: [__m512; 3], d: [__m512; 3]) -> (__m512, __m512, __m512) {
    let ld = |a: &[f32; LANES]| {
        // SAFETY: each array has LANES = 16 f32.
        unsafe { _mm512_loadu_ps(a.as_ptr()) }
    };
    let (e1x, e1y, e1z) = (ld(&p.e1[0]), ld(&p.e1[1]), ld(&p.e1[2]));
    let (e2x, e2y, e2z) = (ld(&p.e2[0]), ld(&p.e2[1]), ld(&p.e2[2]));
    let mul = |a, b| _mm512_mul_ps(a, b);
    let sub = |a, b| _mm512_sub_ps(a, b);
    let add = |a, b| _mm512_add_ps(a, b);
    let [ox, oy, oz] = o;
    let [dx, dy, dz] = d;
    let px = sub(mul(dy, e2z), mul(dz, e2y));
    let py = sub(mul(dz, e2x), mul(dx, e2z));
    let pz = sub(mul(dx, e2y), mul(dy, e2x));
    let det = add(add(mul(e1x, px), mul(e1y, py)), mul(e1z, pz));
    let inv = _mm512_div_ps(_mm512_set1_ps(1.0), det);
    let tx = sub(ox, ld(&p.v0[0]));
    let ty = sub(oy, ld(&p.v0[1]));
    let tz = sub(oz, ld(&p.v0[2]));
    let u = mul(add(add(mul(tx, px), mul(ty, py)), mul(tz, pz)), inv);
    let qx = sub(mul(ty, e1z), mul(tz, e1y));
    let qy = sub(mul(tz, e1x), mul(tx, e1z));
    let qz = sub(mul(tx, e1y), mul(ty, e1x));
    let v = mul(add(add(mul(dx, qx), mul(dy, qy)), mul(dz, qz)), inv);
    let dist = mul(add(add(mul(e2x, qx), mul(e2y, qy)), mul(e2z, qz)), inv);
    let zero = _mm512_setzero_ps();
    let one = _mm512_set1_ps(1.0);
    let inf = _mm512_set1_ps(f32::INFINITY);
    let abs_det = _mm512_abs_ps(det);
    let hit = _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(det, zero)
        & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(abs_det, inf)
        & _mm512_cmp_ps_mask::<_CMP_GE_OQ>(u, zero)
        & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(u, one)
        & _mm512_cmp_ps_mask::<_CMP_GE_OQ>(v, zero)
        & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(add(u, v), one)
        & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(dist, zero);
    (_mm512_mask_blend_ps(hit, inf, dist), u, v)
}

#[target_feature(enable = "avx512f")]
#[inline]
fn splat3_512(v: Vec3) -> [__m512; 3] {
    [
        _mm512_set1_ps(v.x),
        _mm512_set1_ps(v.y),
        _mm512_set1_ps(v.z),
    ]
}

/// Per-lane nearest hits over the packets whose boxes the ray meets.
#[target_feature(enable = "avx512f")]
#[inline]
pub fn intersect_avx512(f: &FlatTriangles, o: Vec3, d: Vec3, tmax: f32) -> Option<Nearest> {
    let inv_d = d.recip();
    let (ov, dv) = (splat3_512(o), splat3_512(d));
    let mut best_t = _mm512_set1_ps(tmax);
    let mut best_i = _mm512_set1_epi32(-1); // u32::MAX
    let mut best_b1 = _mm512_setzero_ps();
    let mut best_b2 = _mm512_setzero_ps();
    let mut nearest = tmax;
    for p in f.packets() {
        if !FlatTriangles::box_hit(p, o, inv_d, nearest) {
            continue;
        }
        let (t, b1, b2) = packet_512(p, ov, dv);
        // SAFETY: 16 u32.
        let idx = unsafe { _mm512_loadu_si512(p.index.as_ptr() as *const _) };
        let closer = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(t, best_t)
            | (_mm512_cmp_ps_mask::<_CMP_EQ_OQ>(t, best_t) & _mm512_cmplt_epu32_mask(idx, best_i));
        best_t = _mm512_mask_blend_ps(closer, best_t, t);
        best_i = _mm512_mask_blend_epi32(closer, best_i, idx);
        best_b1 = _mm512_mask_blend_ps(closer, best_b1, b1);
        best_b2 = _mm512_mask_blend_ps(closer, best_b2, b2);
        nearest = nearest.min(_mm512_reduce_min_ps(best_t));
    }
    let m = _mm512_reduce_min_ps(best_t);
    // Never NaN: lanes hold hit distances (> 0), tmax or infinity.
    if m >= tmax {
        return None;
    }
    let mask = _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(best_t, _mm512_set1_ps(m)) as u32;
    let mut out = LaneBest {
        t: [0.0; LANES],
        index: [0; LANES],
        b1: [0.0; LANES],
        b2: [0.0; LANES],
    };
    // SAFETY: 16 lanes each.
    unsafe {
        _mm512_storeu_si512(out.index.as_mut_ptr() as *mut _, best_i);
        _mm512_storeu_ps(out.b1.as_mut_ptr(), best_b1);
        _mm512_storeu_ps(out.b2.as_mut_ptr(), best_b2);
    }
    out.t = [m; LANES];
    out.pick(mask)
}

#[target_feature(enable = "avx512f")]
#[inline]
pub fn occluded_avx512(f: &FlatTriangles, o: Vec3, d: Vec3, tmax: f32) -> bool {
    let inv_d = d.recip();
    let (ov, dv) = (splat3_512(o), splat3_512(d));
    let limit = _mm512_set1_ps(tmax);
    for p in f.packets() {
        if !FlatTriangles::box_hit(p, o, inv_d, tmax) {
            continue;
        }
        let (t, _, _) = packet_512(p, ov, dv);
        if _mm512_cmp_ps_mask::<_CMP_LT_OQ>(t, limit) != 0 {
            return true;
        }
    }
    false
}

// ---------------------------------------------------------------- AVX2

const HALF: usize = LANES / 2;

/// Moller-Trumbore on lanes `h * 8 .. h * 8 + 8`: (t or infinity, b1, b2).
#[target_feature(enable = "avx2")]
#[inline]
fn packet_256(p: &Packet, h: usize, o: [__m256; 3], d: [__m256; 3]) -> (__m256, __m256, __m256) {
    let ld = |a: &[f32; LANES]| {
        // SAFETY: each array has 16 f32; h is 0 or 1.
        unsafe { _mm256_loadu_ps(a.as_ptr().add(h * HALF)) }
    };
    let v0 = [ld(&p.v0[0]), ld(&p.v0[1]), ld(&p.v0[2])];
    let e1 = [ld(&p.e1[0]), ld(&p.e1[1]), ld(&p.e1[2])];
    let e2 = [ld(&p.e2[0]), ld(&p.e2[1]), ld(&p.e2[2])];
    moller_trumbore_256(v0, e1, e2, o, d)
}

/// Moller-Trumbore on 8 triangles (vertex `v0`, edges `e1`, `e2`, one register per
/// component) against one ray: (t or infinity, b1, b2). Each lane computes the bits of
/// `TriangleGeom::intersect` with `tmin = 0`.
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn moller_trumbore_256(
    v0: [__m256; 3],
    e1: [__m256; 3],
    e2: [__m256; 3],
    o: [__m256; 3],
    d: [__m256; 3],
) -> (__m256, __m256, __m256) {
    let [e1x, e1y, e1z] = e1;
    let [e2x, e2y, e2z] = e2;
    let mul = |a, b| _mm256_mul_ps(a, b);
    let sub = |a, b| _mm256_sub_ps(a, b);
    let add = |a, b| _mm256_add_ps(a, b);
    let [ox, oy, oz] = o;
    let [dx, dy, dz] = d;
    let px = sub(mul(dy, e2z), mul(dz, e2y));
    let py = sub(mul(dz, e2x), mul(dx, e2z));
    let pz = sub(mul(dx, e2y), mul(dy, e2x));
    let det = add(add(mul(e1x, px), mul(e1y, py)), mul(e1z, pz));
    let inv = _mm256_div_ps(_mm256_set1_ps(1.0), det);
    let tx = sub(ox, v0[0]);
    let ty = sub(oy, v0[1]);
    let tz = sub(oz, v0[2]);
    let u = mul(add(add(mul(tx, px), mul(ty, py)), mul(tz, pz)), inv);
    let qx = sub(mul(ty, e1z), mul(tz, e1y));
    let qy = sub(mul(tz, e1x), mul(tx, e1z));
    let qz = sub(mul(tx, e1y), mul(ty, e1x));
    let v = mul(add(add(mul(dx, qx), mul(dy, qy)), mul(dz, qz)), inv);
    let dist = mul(add(add(mul(e2x, qx), mul(e2y, qy)), mul(e2z, qz)), inv);
    let zero = _mm256_setzero_ps();
    let one = _mm256_set1_ps(1.0);
    let inf = _mm256_set1_ps(f32::INFINITY);
    let abs_det = _mm256_andnot_ps(_mm256_set1_ps(-0.0), det);
    let and = |a, b| _mm256_and_ps(a, b);
    let hit = and(
        and(
            and(
                _mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero),
                _mm256_cmp_ps::<_CMP_LT_OQ>(abs_det, inf),
            ),
            and(
                _mm256_cmp_ps::<_CMP_GE_OQ>(u, zero),
                _mm256_cmp_ps::<_CMP_LE_OQ>(u, one),
            ),
        ),
        and(
            and(
                _mm256_cmp_ps::<_CMP_GE_OQ>(v, zero),
                _mm256_cmp_ps::<_CMP_LE_OQ>(add(u, v), one),
            ),
            _mm256_cmp_ps::<_CMP_GT_OQ>(dist, zero),
        ),
    );
    (_mm256_blendv_ps(inf, dist, hit), u, v)
}

#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn splat3_256(v: Vec3) -> [__m256; 3] {
    [
        _mm256_set1_ps(v.x),
        _mm256_set1_ps(v.y),
        _mm256_set1_ps(v.z),
    ]
}

#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn hmin_256(v: __m256) -> f32 {
    let m = _mm_min_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v));
    let m = _mm_min_ps(m, _mm_movehl_ps(m, m));
    let m = _mm_min_ss(m, _mm_shuffle_ps::<0b01>(m, m));
    _mm_cvtss_f32(m)
}

/// The boxes of block `b` that the ray (origin `o`, reciprocal direction `inv`) meets
/// within `[0, tmax]` (bit per lane), and its entry distance into each: the scalar
/// `FlatTriangles::box_hit` on eight boxes at once (the same decisions except on NaN
/// slabs, where neither can skip a packet the ray hits).
#[target_feature(enable = "avx2")]
#[inline]
fn box_entries(b: &BoxBlock, o: [__m256; 3], inv: [__m256; 3], tmax: f32) -> (__m256, u32) {
    let mut enter = _mm256_setzero_ps();
    let mut exit = _mm256_set1_ps(tmax);
    for a in 0..3 {
        // SAFETY: each row has BOX_LANES = 8 f32.
        let lo = unsafe { _mm256_loadu_ps(b.lo[a].as_ptr()) };
        // SAFETY: as above.
        let hi = unsafe { _mm256_loadu_ps(b.hi[a].as_ptr()) };
        let t0 = _mm256_mul_ps(_mm256_sub_ps(lo, o[a]), inv[a]);
        let t1 = _mm256_mul_ps(_mm256_sub_ps(hi, o[a]), inv[a]);
        enter = _mm256_max_ps(_mm256_min_ps(t0, t1), enter);
        exit = _mm256_min_ps(_mm256_max_ps(t0, t1), exit);
    }
    let met = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(enter, exit)) as u32;
    (enter, met & b.lanes)
}

/// Lane `k` (0..8) of `v`.
#[target_feature(enable = "avx2")]
#[inline]
fn lane_ps(v: __m256, k: u32) -> f32 {
    _mm_cvtss_f32(_mm256_castps256_ps128(_mm256_permutevar8x32_ps(
        v,
        _mm256_set1_epi32(k as i32),
    )))
}

#[target_feature(enable = "avx2")]
#[inline]
pub fn intersect_avx2(f: &FlatTriangles, o: Vec3, d: Vec3, tmax: f32) -> Option<Nearest> {
    let (ov, dv) = (splat3_256(o), splat3_256(d));
    let inv_d = d.recip();
    let inv = splat3_256(inv_d);
    let mut best_t = [_mm256_set1_ps(tmax); 2];
    let mut best_i = [_mm256_set1_epi32(-1); 2]; // u32::MAX
    let mut best_b1 = [_mm256_setzero_ps(); 2];
    let mut best_b2 = [_mm256_setzero_ps(); 2];
    // Unsigned a < b as signed compares with the sign bit flipped.
    let flip = _mm256_set1_epi32(i32::MIN);
    // One packet's triangles against the ray; returns the nearest hit so far.
    let mut visit = |p: &Packet| {
        for h in 0..2 {
            let (t, b1, b2) = packet_256(p, h, ov, dv);
            // SAFETY: 16 u32; h is 0 or 1.
            let idx =
                unsafe { _mm256_loadu_si256(p.index.as_ptr().add(h * HALF) as *const __m256i) };
            let idx_lt = _mm256_castsi256_ps(_mm256_cmpgt_epi32(
                _mm256_xor_si256(best_i[h], flip),
                _mm256_xor_si256(idx, flip),
            ));
            let closer = _mm256_or_ps(
                _mm256_cmp_ps::<_CMP_LT_OQ>(t, best_t[h]),
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(t, best_t[h]), idx_lt),
            );
            best_t[h] = _mm256_blendv_ps(best_t[h], t, closer);
            best_i[h] = _mm256_castps_si256(_mm256_blendv_ps(
                _mm256_castsi256_ps(best_i[h]),
                _mm256_castsi256_ps(idx),
                closer,
            ));
            best_b1[h] = _mm256_blendv_ps(best_b1[h], b1, closer);
            best_b2[h] = _mm256_blendv_ps(best_b2[h], b2, closer);
        }
        hmin_256(_mm256_min_ps(best_t[0], best_t[1]))
    };
    let packets = f.packets();
    if let [p] = packets {
        // One packet: the scalar box test costs less than a pass over a block.
        if FlatTriangles::box_hit(p, o, inv_d, tmax) {
            visit(p);
        }
    } else {
        let mut nearest = tmax;
        for (j, b) in f.boxes().iter().enumerate() {
            let (entries, mut met) = box_entries(b, ov, inv, tmax);
            while met != 0 {
                let k = met.trailing_zeros();
                met &= met - 1;
                // The box test against the nearest hit so far (`FlatTriangles::box_hit`'s).
                if lane_ps(entries, k) <= nearest {
                    nearest = nearest.min(visit(&packets[j * BOX_LANES + k as usize]));
                }
            }
        }
    }
    let m = hmin_256(_mm256_min_ps(best_t[0], best_t[1]));
    // Never NaN: lanes hold hit distances (> 0), tmax or infinity.
    if m >= tmax {
        return None;
    }
    let mv = _mm256_set1_ps(m);
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(best_t[0], mv)) as u32
        | (_mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(best_t[1], mv)) as u32) << HALF;
    let mut out = LaneBest {
        t: [m; LANES],
        index: [0; LANES],
        b1: [0.0; LANES],
        b2: [0.0; LANES],
    };
    for h in 0..2 {
        // SAFETY: 16 lanes each; h is 0 or 1.
        unsafe {
            _mm256_storeu_si256(
                out.index.as_mut_ptr().add(h * HALF) as *mut __m256i,
                best_i[h],
            );
            _mm256_storeu_ps(out.b1.as_mut_ptr().add(h * HALF), best_b1[h]);
            _mm256_storeu_ps(out.b2.as_mut_ptr().add(h * HALF), best_b2[h]);
        }
    }
    out.pick(mask)
}

#[target_feature(enable = "avx2")]
#[inline]
pub fn occluded_avx2(f: &FlatTriangles, o: Vec3, d: Vec3, tmax: f32) -> bool {
    let (ov, dv) = (splat3_256(o), splat3_256(d));
    let inv_d = d.recip();
    let inv = splat3_256(inv_d);
    let limit = _mm256_set1_ps(tmax);
    // Whether one packet's triangles block the ray.
    let blocks = |p: &Packet| {
        (0..2).any(|h| {
            let (t, _, _) = packet_256(p, h, ov, dv);
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(t, limit)) != 0
        })
    };
    let packets = f.packets();
    if let [p] = packets {
        // As in `intersect_avx2`.
        return FlatTriangles::box_hit(p, o, inv_d, tmax) && blocks(p);
    }
    for (j, b) in f.boxes().iter().enumerate() {
        let (_, mut met) = box_entries(b, ov, inv, tmax);
        while met != 0 {
            let k = met.trailing_zeros();
            met &= met - 1;
            if blocks(&packets[j * BOX_LANES + k as usize]) {
                return true;
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::Isa;
    use crate::geometry::triangle::TriangleGeom;
    use crate::math::rng::Pcg32;

    /// The AVX2 pass over eight boxes decides as the scalar `box_hit` does, and its
    /// entries lie in [0, tmax].
    #[test]
    fn box_entries_match_the_scalar_box_test() {
        if !Isa::Avx2.supported() {
            return;
        }
        let mut rng = Pcg32::new(5, 6);
        let mut r = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
        // Eleven clusters of nine triangles, one packet each (two do not fit in one):
        // two blocks of boxes, the second partial.
        let groups: Vec<u32> = (0..11 * 9).map(|i| i / 9).collect();
        let centres: Vec<Vec3> = (0..11).map(|_| r()).collect();
        let tris: Vec<TriangleGeom> = groups
            .iter()
            .map(|&g| {
                let c = centres[g as usize];
                TriangleGeom::new(c + r() * 0.2, c + r() * 0.2, c + r() * 0.2)
            })
            .collect();
        let flat = FlatTriangles::with_groups(&tris, &groups);
        assert_eq!(flat.packets().len(), 11);
        assert_eq!(flat.boxes().len(), 2);
        // Half towards a cluster, half anywhere.
        let rays: Vec<(Vec3, Vec3)> = (0..3000)
            .map(|i| {
                let o = r() * 2.0;
                let towards = centres[i % 11] + r() * 0.1 - o;
                (
                    o,
                    if i % 2 == 0 {
                        towards.normalize()
                    } else {
                        r().normalize()
                    },
                )
            })
            .collect();
        let mut met = 0;
        for (o, d) in rays {
            let inv_d = d.recip();
            for tmax in [f32::INFINITY, 0.7] {
                // SAFETY: AVX2 is checked above.
                let lanes: Vec<(f32, bool)> = unsafe {
                    let (ov, inv) = (splat3_256(o), splat3_256(inv_d));
                    flat.boxes()
                        .iter()
                        .flat_map(|b| {
                            let (entries, met) = box_entries(b, ov, inv, tmax);
                            (0..BOX_LANES as u32)
                                .map(move |k| (lane_ps(entries, k), met >> k & 1 == 1))
                        })
                        .collect()
                };
                for (k, p) in flat.packets().iter().enumerate() {
                    let scalar = FlatTriangles::box_hit(p, o, inv_d, tmax);
                    assert_eq!(lanes[k].1, scalar, "{o} {d} {tmax}");
                    met += scalar as usize;
                    // The entry distance: where the ray enters the box (0 when it
                    // starts inside), never beyond tmax.
                    if scalar {
                        assert!(lanes[k].0 >= 0.0 && lanes[k].0 <= tmax);
                    }
                }
                // Lanes past the last packet are never met.
                assert!(lanes[flat.packets().len()..].iter().all(|l| !l.1));
            }
        }
        assert!(met > 2000 && met < 60_000, "{met}");
    }
}
