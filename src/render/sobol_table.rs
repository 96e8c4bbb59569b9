//! The low-discrepancy numbers of one replicate of a pixel, one dimension at a time for
//! all of its samples (SPEC 4, "Sampling and replicates").
//!
//! [`SobolPath`] computes each number on its own: for every sample it hashes the
//! dimension's key again (three 64-bit hashes), walks Kensler's permutation and divides
//! by the replicate size. All of that but the sample index is the same for every
//! sample of the replicate. [`SobolTable`] computes a dimension (vertex, slot,
//! coordinate) for all the replicate's samples the first time a path asks for it: the
//! hashes once, then a loop over the sample indices that the compiler vectorises (for
//! replicate sizes that are powers of two the permutation needs no cycle walk and the
//! division is a mask). Paths then read their number from the column ([`TabledSobol`]).
//!
//! The numbers are [`SobolPath`]'s, bit for bit (integer arithmetic throughout; the
//! tests compare every dimension), so renders do not change.
//!
//! Memory: 4 bytes per sample and dimension used, per thread (a surface scene uses
//! about 11 dimensions: 11 x 4 x 512 = 22.5 kB at 512 spp), plus two scratch columns.
//! Replicates larger than [`TABLE_MAX_COUNT`] samples compute each number on its own
//! instead (same bits), so a table never exceeds (72 + 2) x 4 x 65536 = 19.4 MB per
//! thread for surface scenes (two low-discrepancy vertices of 36 dimensions each) and
//! 38.3 MB with media (four).

use super::sampler::PathSampler;
use super::sampler::{kensler_round, permute, randomise, scramble_index, sobol_1, to_unit};
use super::sampler::{vertex_key, SLOTS};
use crate::math::rng::{mix64, Pcg32};

/// The largest replicate kept in a table.
pub const TABLE_MAX_COUNT: u32 = 1 << 16;

/// The computed dimensions of one replicate of one pixel (reused from replicate to
/// replicate by one render task).
#[derive(Default)]
pub struct SobolTable {
    key: u64,
    count: u32,
    ld_vertices: u64,
    /// Per dimension (vertex, slot, coordinate): 1 + its column's offset in `values`,
    /// or 0 when not computed yet.
    at: Vec<u32>,
    values: Vec<f32>,
    /// Scratch of `fill`: the permuted indices and Sobol' dimension 1 of a column.
    index: Vec<u32>,
    digits: Vec<u32>,
    /// Off when the replicate is larger than [`TABLE_MAX_COUNT`].
    tabled: bool,
}

impl SobolTable {
    /// Starts replicate `key` of `count` samples, whose vertices `0..=ld_vertices` draw
    /// from the set; forgets the columns of the last one (keeping the memory).
    pub fn reset(&mut self, key: u64, count: u32, ld_vertices: u64) {
        self.key = key;
        self.count = count;
        self.ld_vertices = ld_vertices;
        self.tabled = count <= TABLE_MAX_COUNT;
        self.at.clear();
        self.at
            .resize((ld_vertices as usize + 1) * SLOTS as usize * 2, 0);
        self.values.clear();
    }

    /// The most a table holds for replicates of `count` samples whose vertices
    /// `0..=ld_vertices` draw from the set: every dimension's column.
    pub fn max_bytes(count: u32, ld_vertices: u64) -> u64 {
        if count > TABLE_MAX_COUNT {
            return 0;
        }
        let dims = (ld_vertices + 1) * u64::from(SLOTS) * 2;
        // The columns, their offsets and `fill`'s two scratch columns.
        (dims + 2) * u64::from(count) * 4 + dims * 4
    }

    /// Coordinate `coord` of `slot` at `vertex` for sample `index`.
    #[inline(always)]
    fn get(&mut self, vertex: u64, slot: u32, coord: usize, index: u32) -> f32 {
        debug_assert!(vertex <= self.ld_vertices && slot < SLOTS && index < self.count);
        if !self.tabled {
            return self.one(vertex, slot, coord, index);
        }
        let d = (vertex as usize * SLOTS as usize + slot as usize) * 2 + coord;
        let mut at = self.at[d];
        if at == 0 {
            at = self.fill(vertex, slot, coord);
            self.at[d] = at;
        }
        self.values[at as usize - 1 + index as usize]
    }

    /// The dimension's hashes: the permutation key and the scramble of `coord`.
    #[inline(always)]
    fn hashes(&self, vertex: u64, slot: u32, coord: usize) -> (u32, u64) {
        let vk = vertex_key(self.key, vertex);
        let h = mix64(vk ^ u64::from(slot + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15));
        let h2 = mix64(h);
        ((h >> 32) as u32, if coord == 0 { h2 } else { mix64(h2) })
    }

    /// One number without the table (as `SobolPath::get1` / `get2`).
    #[cold]
    fn one(&self, vertex: u64, slot: u32, coord: usize, index: u32) -> f32 {
        let (p, s) = self.hashes(vertex, slot, coord);
        number(permute(index, self.count, p), coord, s)
    }

    /// Appends the column of one dimension; returns 1 + its offset. Compiled for the
    /// instruction set `cpu` chose (its loops vectorise; the same bits at every level).
    #[inline(never)]
    fn fill(&mut self, vertex: u64, slot: u32, coord: usize) -> u32 {
        match crate::cpu::detected().avx2() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the proof says this CPU runs the wrapper's instruction set.
            Some(isa) => unsafe { self.fill_avx2(isa, vertex, slot, coord) },
            _ => self.fill_body(vertex, slot, coord),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn fill_avx2(&mut self, _isa: crate::cpu::Avx2, vertex: u64, slot: u32, coord: usize) -> u32 {
        self.fill_body(vertex, slot, coord)
    }

    #[inline(always)]
    fn fill_body(&mut self, vertex: u64, slot: u32, coord: usize) -> u32 {
        let (p, s) = self.hashes(vertex, slot, coord);
        let n = self.count;
        let start = self.values.len();
        self.values.resize(start + n as usize, 0.0);
        let column = &mut self.values[start..];
        if n.is_power_of_two() {
            // Kensler's permutation on a power of two never cycles, and `% n` is a mask.
            let w = n - 1;
            let bits = 32 - w.leading_zeros();
            if coord == 0 {
                for (index, out) in (0..n).zip(column.iter_mut()) {
                    *out = to_unit(scramble_index(permute_pow2(index, w, p), s));
                }
            } else {
                // Sobol' dimension 1 digit by digit over the whole column, so that the
                // loops over the samples have no inner loop (and vectorise).
                let (index, x) = (&mut self.index, &mut self.digits);
                index.clear();
                index.resize(n as usize, 0);
                for (i, out) in (0..n).zip(index.iter_mut()) {
                    *out = permute_pow2(i, w, p);
                }
                x.clear();
                x.resize(n as usize, 0);
                let mut v = 1u32 << 31;
                for j in 0..bits {
                    for (x, &i) in x.iter_mut().zip(index.iter()) {
                        *x ^= v & 0u32.wrapping_sub((i >> j) & 1);
                    }
                    v ^= v >> 1;
                }
                for (out, &x) in column.iter_mut().zip(x.iter()) {
                    *out = to_unit(randomise(x, s));
                }
            }
        } else {
            for (index, out) in (0..n).zip(column.iter_mut()) {
                *out = number(permute(index, n, p), coord, s);
            }
        }
        start as u32 + 1
    }
}

/// Coordinate `coord` of the permuted index `i`, scrambled by `s`.
#[inline(always)]
fn number(i: u32, coord: usize, s: u64) -> f32 {
    to_unit(if coord == 0 {
        scramble_index(i, s)
    } else {
        randomise(sobol_1(i), s)
    })
}

/// [`permute`] for `l = w + 1` a power of two: one round, no cycle walk (the masked
/// value is always below `l`), `% l` as a mask. Branch-free, so a loop over `i`
/// vectorises.
#[inline(always)]
fn permute_pow2(i: u32, w: u32, p: u32) -> u32 {
    if w == 0 {
        return 0;
    }
    kensler_round(i, w, p).wrapping_add(p) & w
}

/// The numbers of sample `index` of the table's replicate: vertices up to the table's
/// `ld_vertices` from the table, later ones from the path's stream (as [`SobolPath`]).
pub struct TabledSobol<'a> {
    table: &'a mut SobolTable,
    index: u32,
    vertex: u64,
    stream: Pcg32,
}

impl<'a> TabledSobol<'a> {
    pub fn new(table: &'a mut SobolTable, index: u32, stream: Pcg32) -> Self {
        TabledSobol {
            table,
            index,
            vertex: 0,
            stream,
        }
    }

    #[inline(always)]
    fn beyond(&self) -> bool {
        self.vertex > self.table.ld_vertices
    }
}

impl PathSampler for TabledSobol<'_> {
    #[inline(always)]
    fn next_vertex(&mut self) {
        self.vertex += 1;
    }

    #[inline(always)]
    fn get1(&mut self, slot: u32) -> f32 {
        if self.beyond() {
            return self.stream.next_f32();
        }
        self.table.get(self.vertex, slot, 0, self.index)
    }

    #[inline(always)]
    fn get2(&mut self, slot: u32) -> [f32; 2] {
        if self.beyond() {
            return self.stream.next_2d();
        }
        [
            self.table.get(self.vertex, slot, 0, self.index),
            self.table.get(self.vertex, slot, 1, self.index),
        ]
    }

    #[inline(always)]
    fn stream(&mut self) -> &mut Pcg32 {
        &mut self.stream
    }
}

#[cfg(test)]
mod tests {
    use super::super::sampler::{replicate_key, SobolPath, LD_VERTICES_VOLUMETRIC};
    use super::*;

    /// Every dimension of every sample, through the table and through `SobolPath`, for
    /// power-of-two replicate sizes and others, with the stream's numbers after the
    /// low-discrepancy vertices.
    #[test]
    fn the_table_gives_sobol_path_s_bits() {
        let mut table = SobolTable::default();
        for count in [1u32, 2, 3, 8, 12, 64, 100, 512] {
            for (pixel, replicate) in [(0u64, 0u32), (77, 3)] {
                let key = replicate_key(5, pixel, replicate);
                let ld = LD_VERTICES_VOLUMETRIC;
                table.reset(key, count, ld);
                for index in 0..count {
                    let stream = Pcg32::for_path(5, pixel, u64::from(index));
                    let mut want = SobolPath::with_depth(key, index, count, stream.clone(), ld);
                    let mut got = TabledSobol::new(&mut table, index, stream);
                    for vertex in 0..ld + 3 {
                        if vertex > 0 {
                            want.next_vertex();
                            got.next_vertex();
                        }
                        for slot in 0..SLOTS {
                            let (a, b) = if slot % 2 == 0 {
                                (
                                    want.get2(slot).map(f32::to_bits),
                                    got.get2(slot).map(f32::to_bits),
                                )
                            } else {
                                (
                                    [want.get1(slot).to_bits(), 0],
                                    [got.get1(slot).to_bits(), 0],
                                )
                            };
                            assert_eq!(
                                a, b,
                                "count {count} index {index} vertex {vertex} slot {slot}"
                            );
                        }
                    }
                    assert_eq!(want.stream().next_u32(), got.stream().next_u32());
                }
            }
        }
    }

    #[test]
    fn large_replicates_skip_the_table_with_the_same_bits() {
        let mut table = SobolTable::default();
        let count = TABLE_MAX_COUNT + 5;
        let key = replicate_key(1, 2, 0);
        table.reset(key, count, 1);
        for index in [0, 1, 70_000] {
            let stream = Pcg32::new(3, 4);
            let mut want = SobolPath::with_depth(key, index, count, stream.clone(), 1);
            let mut got = TabledSobol::new(&mut table, index, stream);
            want.next_vertex();
            got.next_vertex();
            assert_eq!(
                want.get2(9).map(f32::to_bits),
                got.get2(9).map(f32::to_bits)
            );
        }
        assert!(table.values.is_empty());
    }

    #[test]
    fn the_power_of_two_permutation_is_kensler_s() {
        for bits in 0..=12u32 {
            let n = 1u32 << bits;
            for p in [0u32, 1, 0xdead_beef, 0x8000_0001] {
                for i in 0..n {
                    assert_eq!(
                        permute_pow2(i, n - 1, p),
                        permute(i, n, p),
                        "n {n} p {p} i {i}"
                    );
                }
            }
        }
    }
}
