//! The acceleration structure: one `obvhs` compressed-wide BVH over every primitive
//! (triangles, analytic spheres, disks and cylinders, and the non-empty voxels of SDF
//! grids), with closest-hit and occlusion queries. Scenes of
//! at most [`FLAT_MAX`] primitives are tested exhaustively in SIMD packets instead.

#[cfg(target_arch = "x86_64")]
use super::bvh_simd::{self, node_hits_avx2, LeafTriangles};
use super::curve::Segment;
use super::cylinder::CylinderGeom;
use super::disk::DiskGeom;
use super::flat::{FlatTriangles, FLAT_MAX};
#[cfg(target_arch = "x86_64")]
use super::flat_simd;
use super::sdfgrid::SdfGeom;
use super::shape::{Shape, ShapeGeom, SurfacePoint};
use super::sphere::SphereGeom;
use super::triangle::TriangleGeom;
use crate::cpu::{Baseline, Level};
use glam::{UVec2, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::{Boundable, BvhBuildParams};

#[derive(Clone, Copy, Debug)]
enum PrimGeom {
    Triangle(TriangleGeom),
    Sphere(SphereGeom),
    /// An index into `Accel::quadrics` (kept out of line so a primitive stays the
    /// size of a triangle: scenes without these shapes keep their memory layout).
    /// An SDF grid's voxels share one entry; the primitive's `face` is the voxel.
    Quadric(u32),
}

/// The analytic shapes too large to store in a primitive (and curve segments).
#[derive(Clone, Copy, Debug)]
enum Quadric {
    Disk(DiskGeom),
    Cylinder(CylinderGeom),
    Curve(Segment),
    /// An index into `Accel::sdfs`.
    Sdf(u32),
}

/// A primitive in BVH leaf order.
#[derive(Clone, Copy, Debug)]
struct Prim {
    geom: PrimGeom,
    shape: u32,
    face: u32,
}

/// A primitive's box (quadrics' boxes come from their shapes), for the builder.
#[derive(Clone, Copy, Debug)]
struct Boxed {
    lo: Vec3,
    hi: Vec3,
}

/// Build boxes with the repeats of a box spread apart, conservatively.
///
/// obvhs's PLOC builder merges mutual nearest neighbours; among many identical boxes
/// every distance ties, so a pass merges almost nothing and the build turns quadratic
/// (a 2 kB mesh of 65,536 copies of one triangle took minutes). Each repeat after the
/// first gets its box moved by a small deterministic offset and grown by as much, so it
/// still contains its primitive: the builder sees a tiny cloud of distinct boxes and
/// stays O(n log n). Scenes without repeated boxes are untouched (same BVH, same bits).
fn spread_coincident(mut boxed: Vec<Boxed>) -> Vec<Boxed> {
    use std::collections::HashMap;
    let key = |b: &Boxed| [b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z].map(f32::to_bits);
    let mut seen: HashMap<[u32; 6], u32> = HashMap::with_capacity(boxed.len());
    for (i, b) in boxed.iter_mut().enumerate() {
        let repeat = seen.entry(key(b)).or_insert(0);
        *repeat += 1;
        if *repeat == 1 {
            continue;
        }
        // Offsets on the scale of the box (or of its position, for a point-like one),
        // from a hash of the index: distinct and reproducible.
        let size = (b.hi - b.lo)
            .max_element()
            .max(b.lo.abs().max(b.hi.abs()).max_element() * 1e-4);
        let size = if size > 0.0 && size.is_finite() {
            size
        } else {
            1e-6
        };
        let h = (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let unit = |k: u32| ((h >> (k * 20)) & 0xFFFFF) as f32 / 1_048_576.0 - 0.5;
        let d = Vec3::new(unit(0), unit(1), unit(2)) * (size * 1e-3);
        let grow = d.abs() * 2.0;
        b.lo = b.lo + d - grow;
        b.hi = b.hi + d + grow;
    }
    boxed
}

impl Boundable for Boxed {
    fn aabb(&self) -> Aabb {
        Aabb::new(Vec3A::from(self.lo), Vec3A::from(self.hi))
    }
}

impl Prim {
    fn bounds(&self) -> (Vec3, Vec3) {
        let b = match self.geom {
            PrimGeom::Triangle(t) => {
                let (a, b, c) = (t.v0, t.v0 + t.e1, t.v0 + t.e2);
                Aabb::new(Vec3A::from(a.min(b).min(c)), Vec3A::from(a.max(b).max(c)))
            }
            PrimGeom::Sphere(s) => Aabb::new(
                Vec3A::from(s.center - Vec3::splat(s.radius)),
                Vec3A::from(s.center + Vec3::splat(s.radius)),
            ),
            PrimGeom::Quadric(_) => unreachable!("boxed by their shapes"),
        };
        (b.min.into(), b.max.into())
    }
}

/// A closest hit.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    pub shape: u32,
    pub surface: SurfacePoint,
    /// The triangle of the shape that was hit (0 for spheres) and its barycentrics,
    /// for `Shape::uv` when a textured material asks.
    pub face: u32,
    pub b1: f32,
    pub b2: f32,
}

pub struct Accel {
    bvh: Option<CwBvh>,
    /// The primitives in leaf order (a triangle-only BVH's with padding slots, see
    /// `leaf_tris`).
    prims: Vec<Prim>,
    /// Primitives in the scene (without padding).
    count: usize,
    /// A triangle-only BVH's triangles in leaf order for the AVX2 leaf kernels (none
    /// when the tree holds other shapes, or off x86-64).
    #[cfg(target_arch = "x86_64")]
    leaf_tris: Option<LeafTriangles>,
    flat: Option<Flat>,
    /// The disks, cylinders and curve segments `PrimGeom::Quadric` indexes.
    quadrics: Vec<Quadric>,
    /// The SDF grids `Quadric::Sdf` indexes.
    sdfs: Vec<SdfGeom>,
}

/// The exhaustive path for tiny scenes: the triangles in packets, the analytic shapes
/// (spheres, disks, cylinders) in a list, both as indices into `prims`.
struct Flat {
    tris: FlatTriangles,
    tri_prims: Vec<usize>,
    sphere_prims: Vec<usize>,
}

impl Accel {
    /// The BVH, or the exhaustive packets for scenes of at most [`FLAT_MAX`] primitives.
    pub fn build(shapes: &[Shape]) -> Self {
        Self::build_with(shapes, FLAT_MAX)
    }

    /// As `build`, with the largest primitive count that skips the tree (0: always a BVH).
    pub fn build_with(shapes: &[Shape], flat_max: usize) -> Self {
        let mut prims = Vec::new();
        let mut quadrics = Vec::new();
        // Boxes of the curve segments (the other quadrics take their shape's).
        let mut segment_boxes: Vec<Option<(Vec3, Vec3)>> = Vec::new();
        let mut sdfs = Vec::new();
        for (si, shape) in shapes.iter().enumerate() {
            match &shape.geom {
                ShapeGeom::Mesh { triangles, .. } => {
                    for f in 0..triangles.len() as u32 {
                        let t = shape.triangle(f);
                        // Degenerate triangles can never be hit; keep them out of the tree.
                        if t.area() > 0.0 {
                            prims.push(Prim {
                                geom: PrimGeom::Triangle(t),
                                shape: si as u32,
                                face: f,
                            });
                        }
                    }
                }
                ShapeGeom::Sphere(s, _) => prims.push(Prim {
                    geom: PrimGeom::Sphere(*s),
                    shape: si as u32,
                    face: 0,
                }),
                ShapeGeom::Disk(g) => {
                    prims.push(Prim {
                        geom: PrimGeom::Quadric(quadrics.len() as u32),
                        shape: si as u32,
                        face: 0,
                    });
                    quadrics.push(Quadric::Disk(*g));
                }
                ShapeGeom::Cylinder(g) => {
                    prims.push(Prim {
                        geom: PrimGeom::Quadric(quadrics.len() as u32),
                        shape: si as u32,
                        face: 0,
                    });
                    quadrics.push(Quadric::Cylinder(*g));
                }
                ShapeGeom::Curve(g) => {
                    segment_boxes.resize(quadrics.len(), None);
                    for i in 0..g.segments.len() {
                        prims.push(Prim {
                            geom: PrimGeom::Quadric(quadrics.len() as u32),
                            shape: si as u32,
                            face: i as u32,
                        });
                        quadrics.push(Quadric::Curve(g.segment(i)));
                        segment_boxes.push(Some(g.segment_bounds(i)));
                    }
                }
                ShapeGeom::Sdf(g) => {
                    let q = quadrics.len() as u32;
                    quadrics.push(Quadric::Sdf(sdfs.len() as u32));
                    sdfs.push((**g).clone());
                    for k in 0..g.voxel_count() as u32 {
                        prims.push(Prim {
                            geom: PrimGeom::Quadric(q),
                            shape: si as u32,
                            face: k,
                        });
                    }
                }
            }
        }
        if prims.is_empty() {
            return Accel {
                bvh: None,
                count: prims.len(),
                prims,
                #[cfg(target_arch = "x86_64")]
                leaf_tris: None,
                flat: None,
                quadrics,
                sdfs,
            };
        }
        if prims.len() <= flat_max {
            let kind = |i: &usize| matches!(prims[*i].geom, PrimGeom::Triangle(_));
            let (tri_prims, sphere_prims): (Vec<usize>, Vec<usize>) =
                (0..prims.len()).partition(kind);
            let tris: Vec<TriangleGeom> = tri_prims
                .iter()
                .map(|&i| match prims[i].geom {
                    PrimGeom::Triangle(t) => t,
                    _ => unreachable!("partitioned"),
                })
                .collect();
            let groups: Vec<u32> = tri_prims.iter().map(|&i| prims[i].shape).collect();
            let flat = Flat {
                tris: FlatTriangles::with_groups(&tris, &groups),
                tri_prims,
                sphere_prims,
            };
            return Accel {
                bvh: None,
                count: prims.len(),
                prims,
                #[cfg(target_arch = "x86_64")]
                leaf_tris: None,
                flat: Some(flat),
                quadrics,
                sdfs,
            };
        }
        let boxed: Vec<Boxed> = prims
            .iter()
            .map(|&prim| {
                let (lo, hi) = match prim.geom {
                    PrimGeom::Quadric(q) => match quadrics[q as usize] {
                        Quadric::Sdf(g) => sdfs[g as usize].voxel_bounds(prim.face),
                        _ => segment_boxes
                            .get(q as usize)
                            .copied()
                            .flatten()
                            .unwrap_or_else(|| shapes[prim.shape as usize].bounds()),
                    },
                    _ => prim.bounds(),
                };
                Boxed { lo, hi }
            })
            .collect();
        let boxed = spread_coincident(boxed);
        #[allow(unused_mut)]
        let mut bvh = obvhs::cwbvh::builder::build_cwbvh(
            &boxed,
            BvhBuildParams::medium_build(),
            &mut std::time::Duration::default(),
        );
        // Reorder the primitives into leaf order so the closures index them directly.
        let mut ordered: Vec<Prim> = bvh
            .primitive_indices
            .iter()
            .map(|&i| prims[i as usize])
            .collect();
        // A triangle-only tree also gets its triangles in blocks for the AVX2 leaf
        // kernels, each node's starting a block of its own (`bvh_simd.rs`).
        #[cfg(target_arch = "x86_64")]
        let leaf_tris = if ordered
            .iter()
            .all(|p| matches!(p.geom, PrimGeom::Triangle(_)))
        {
            let slots = bvh_simd::pad_node_groups(&mut bvh);
            let padding = Prim {
                geom: PrimGeom::Triangle(TriangleGeom::new(Vec3::ZERO, Vec3::ZERO, Vec3::ZERO)),
                shape: 0,
                face: 0,
            };
            bvh.primitive_indices = slots
                .iter()
                .map(|s| s.map_or(u32::MAX, |i| bvh.primitive_indices[i as usize]))
                .collect();
            ordered = slots
                .iter()
                .map(|s| s.map_or(padding, |i| ordered[i as usize]))
                .collect();
            let tris: Vec<Option<TriangleGeom>> = slots
                .iter()
                .zip(&ordered)
                .map(|(s, p)| match (s, p.geom) {
                    (Some(_), PrimGeom::Triangle(t)) => Some(t),
                    _ => None,
                })
                .collect();
            Some(LeafTriangles::new(&tris))
        } else {
            None
        };
        Accel {
            bvh: Some(bvh),
            count: prims.len(),
            prims: ordered,
            #[cfg(target_arch = "x86_64")]
            leaf_tris,
            flat: None,
            quadrics,
            sdfs,
        }
    }

    /// The distance to an out-of-line primitive, quadric `q` (`face`: its SDF voxel),
    /// and for a curve segment its parameter `v` (else 0).
    #[inline(never)]
    fn quadric_hit(&self, q: u32, face: u32, o: Vec3, d: Vec3, tmin: f32) -> Option<(f32, f32)> {
        match &self.quadrics[q as usize] {
            Quadric::Disk(g) => g.intersect(o, d, tmin).map(|t| (t, 0.0)),
            Quadric::Cylinder(g) => g.intersect(o, d, tmin).map(|t| (t, 0.0)),
            Quadric::Curve(g) => g.intersect(o, d, tmin),
            Quadric::Sdf(i) => self.sdfs[*i as usize]
                .intersect_voxel(face, o, d, tmin)
                .map(|t| (t, 0.0)),
        }
    }

    #[inline(always)]
    fn prim_t(&self, id: usize, o: Vec3, d: Vec3, tmin: f32) -> f32 {
        self.prim_tv(id, o, d, tmin).0
    }

    /// The hit distance of primitive `id` (infinite when missed) and a curve
    /// segment's parameter there (0 for the other shapes).
    #[inline(always)]
    fn prim_tv(&self, id: usize, o: Vec3, d: Vec3, tmin: f32) -> (f32, f32) {
        let p = &self.prims[id];
        let t = match &p.geom {
            PrimGeom::Triangle(t) => t.intersect(o, d, tmin).map(|h| h.0),
            PrimGeom::Sphere(s) => s.intersect(o, d, tmin),
            PrimGeom::Quadric(q) => {
                return self
                    .quadric_hit(*q, p.face, o, d, tmin)
                    .unwrap_or((f32::INFINITY, 0.0))
            }
        };
        (t.unwrap_or(f32::INFINITY), 0.0)
    }

    /// The closest surface along the ray (unit direction `d`) with t in (0, tmax).
    #[inline(always)]
    pub fn intersect(&self, shapes: &[Shape], o: Vec3, d: Vec3, tmax: f32) -> Option<Hit> {
        self.intersect_with(Baseline, shapes, o, d, tmax)
    }

    /// [`Self::intersect`] with the kernels of the level `isa` proves.
    #[inline(always)]
    pub fn intersect_with<L: Level>(
        &self,
        isa: L,
        shapes: &[Shape],
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> Option<Hit> {
        if let Some(flat) = &self.flat {
            return self.intersect_flat(isa, flat, shapes, o, d, tmax);
        }
        let bvh = self.bvh.as_ref()?;
        #[cfg(target_arch = "x86_64")]
        if let (Some(_avx2), Some(leaf)) = (isa.avx2(), &self.leaf_tris) {
            // SAFETY: `_avx2` proves this CPU runs AVX2.
            return unsafe { self.intersect_triangles_avx2(bvh, leaf, shapes, o, d, tmax) };
        }
        // obvhs's `ray_traverse`, written out with its `traverse!` macro so that the
        // walk is inlined into (and compiled for the instruction set of) the tracer.
        let ray = Ray::new(Vec3A::from(o), Vec3A::from(d), 0.0, tmax);
        let mut hit = RayHit::none();
        let (mut best_t, mut best_b) = (f32::INFINITY, (0.0f32, 0.0f32));
        // The curve parameter of the nearest quadric hit so far (curves only).
        let mut curve_v = 0.0f32;
        let mut traverse_ray = ray;
        let mut state = bvh.new_traversal(ray.direction);
        let mut node;
        obvhs::traverse!(
            bvh,
            node,
            state,
            node_test(isa, node, &traverse_ray, state.oct_inv4),
            {
                let id = state.primitive_id as usize;
                let prim = &self.prims[id];
                let t = match &prim.geom {
                    PrimGeom::Triangle(tri) => match tri.intersect(o, d, 0.0) {
                        Some((t, b1, b2)) => {
                            if t < best_t {
                                best_t = t;
                                best_b = (b1, b2);
                            }
                            t
                        }
                        None => f32::INFINITY,
                    },
                    PrimGeom::Sphere(s) => s.intersect(o, d, 0.0).unwrap_or(f32::INFINITY),
                    PrimGeom::Quadric(q) => match self.quadric_hit(*q, prim.face, o, d, 0.0) {
                        Some((t, v)) => {
                            if t < traverse_ray.tmax {
                                curve_v = v;
                            }
                            t
                        }
                        None => f32::INFINITY,
                    },
                };
                if t < traverse_ray.tmax {
                    hit.primitive_id = state.primitive_id;
                    hit.t = t;
                    traverse_ray.tmax = t;
                }
            }
        );
        let found = hit.t < ray.tmax;
        if !found {
            return None;
        }
        let p = &self.prims[hit.primitive_id as usize];
        let shape = &shapes[p.shape as usize];
        let surface = match &p.geom {
            PrimGeom::Triangle(t) => shape.surface_of(t, p.face, best_b.0, best_b.1),
            PrimGeom::Quadric(_) => {
                best_b = (curve_v, 0.0);
                shape.surface(p.face, curve_v, 0.0, o + d * hit.t)
            }
            _ => shape.surface(0, 0.0, 0.0, o + d * hit.t),
        };
        Some(Hit {
            t: hit.t,
            shape: p.shape,
            surface,
            face: p.face,
            b1: best_b.0,
            b2: best_b.1,
        })
    }

    /// True when something blocks the segment from `o` along unit `d` before `tmax`.
    #[inline(always)]
    pub fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        self.occluded_with(Baseline, o, d, tmax)
    }

    /// [`Self::occluded`] with the kernels of the level `isa` proves.
    #[inline(always)]
    pub fn occluded_with<L: Level>(&self, isa: L, o: Vec3, d: Vec3, tmax: f32) -> bool {
        if let Some(flat) = &self.flat {
            // (The emptiness test keeps the call to `any` out of triangle-only scenes.)
            return flat_occluded_with(isa, &flat.tris, o, d, tmax)
                || (!flat.sphere_prims.is_empty()
                    && flat
                        .sphere_prims
                        .iter()
                        .any(|&i| self.prim_t(i, o, d, 0.0) < tmax));
        }
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        #[cfg(target_arch = "x86_64")]
        if let (Some(_avx2), Some(leaf)) = (isa.avx2(), &self.leaf_tris) {
            // SAFETY: `_avx2` proves this CPU runs AVX2.
            return unsafe { occluded_triangles_avx2(bvh, leaf, o, d, tmax) };
        }
        let ray = Ray::new(Vec3A::from(o), Vec3A::from(d), 0.0, tmax);
        let mut state = bvh.new_traversal(ray.direction);
        let mut node;
        let mut blocked = false;
        'walk: {
            obvhs::traverse!(
                bvh,
                node,
                state,
                node_test(isa, node, &ray, state.oct_inv4),
                {
                    if self.prim_t(state.primitive_id as usize, o, d, 0.0) < tmax {
                        blocked = true;
                        break 'walk;
                    }
                }
            );
        }
        blocked
    }

    /// [`Self::intersect_with`] for a triangle-only BVH in AVX2: eight children per node
    /// test and the leaves' triangles eight at a time (`bvh_simd.rs`), with the same
    /// walk, so the same hit to the bit.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    fn intersect_triangles_avx2(
        &self,
        bvh: &CwBvh,
        leaf: &LeafTriangles,
        shapes: &[Shape],
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> Option<Hit> {
        let mut ray = Ray::new(Vec3A::from(o), Vec3A::from(d), 0.0, tmax);
        // (primitive, t, b1, b2) of the nearest hit so far.
        let mut best: Option<(u32, f32, f32, f32)> = None;
        let mut state = bvh.new_traversal(ray.direction);
        let mut node;
        obvhs::traverse!(
            bvh,
            node,
            state,
            node_hits_avx2(node, &ray, state.oct_inv4),
            {
                let (first, group) = take_group(&mut state);
                if let Some((k, t, b1, b2)) = leaf.nearest_avx2(first, group, o, d, ray.tmax) {
                    best = Some((first + k, t, b1, b2));
                    ray.tmax = t;
                }
            }
        );
        let (id, t, b1, b2) = best?;
        let p = &self.prims[id as usize];
        let PrimGeom::Triangle(tri) = &p.geom else {
            unreachable!("a triangle-only BVH")
        };
        Some(Hit {
            t,
            shape: p.shape,
            surface: shapes[p.shape as usize].surface_of(tri, p.face, b1, b2),
            face: p.face,
            b1,
            b2,
        })
    }

    #[inline(always)]
    fn intersect_flat<L: Level>(
        &self,
        isa: L,
        flat: &Flat,
        shapes: &[Shape],
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> Option<Hit> {
        let mut best = flat_intersect_with(isa, &flat.tris, o, d, tmax)
            .map(|(k, t, b1, b2)| (flat.tri_prims[k], t, b1, b2));
        for &i in &flat.sphere_prims {
            let (t, v) = self.prim_tv(i, o, d, 0.0);
            if t < best.map_or(tmax, |b| b.1) {
                best = Some((i, t, v, 0.0));
            }
        }
        let (i, t, b1, b2) = best?;
        let p = &self.prims[i];
        let shape = &shapes[p.shape as usize];
        let surface = match &p.geom {
            PrimGeom::Triangle(tri) => shape.surface_of(tri, p.face, b1, b2),
            PrimGeom::Quadric(_) => shape.surface(p.face, b1, 0.0, o + d * t),
            _ => shape.surface(0, 0.0, 0.0, o + d * t),
        };
        Some(Hit {
            t,
            shape: p.shape,
            surface,
            face: p.face,
            b1,
            b2,
        })
    }

    pub fn primitive_count(&self) -> usize {
        self.count
    }
}

/// A ray origin moved off the surface to the side `d` leaves from, by an offset that
/// scales with the magnitude of the coordinates (f32 rounding grows with them).
#[inline]
pub fn offset_origin(p: Vec3, ng: Vec3, d: Vec3) -> Vec3 {
    let eps = ray_epsilon(p);
    if ng.dot(d) >= 0.0 {
        p + ng * eps
    } else {
        p - ng * eps
    }
}

#[inline]
pub fn ray_epsilon(p: Vec3) -> f32 {
    1e-4 * (1.0 + p.abs().max_element())
}

/// The children of a BVH node the ray enters, with the kernel of the level `isa` proves (the same
/// bits at every level).
#[inline(always)]
fn node_test<L: Level>(isa: L, node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if let Some(_avx2) = isa.avx2() {
        // SAFETY: `_avx2` proves this CPU runs AVX2.
        return unsafe { node_hits_avx2(node, ray, oct_inv4) };
    }
    node.intersect_ray(ray, oct_inv4)
}

/// In `traverse!`'s primitive block: the node visit's whole primitive group at once,
/// its first primitive and the bits of the one just taken and the ones left, which the
/// walk then skips.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn take_group(state: &mut obvhs::cwbvh::Traversal) -> (u32, u32) {
    let first = state.primitive_group.x;
    let group = state.primitive_group.y | (1 << (state.primitive_id - first));
    state.primitive_group.y = 0;
    (first, group)
}

/// [`Accel::occluded_with`] for a triangle-only BVH in AVX2 (see
/// `Accel::intersect_triangles_avx2`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn occluded_triangles_avx2(bvh: &CwBvh, leaf: &LeafTriangles, o: Vec3, d: Vec3, tmax: f32) -> bool {
    let ray = Ray::new(Vec3A::from(o), Vec3A::from(d), 0.0, tmax);
    let mut state = bvh.new_traversal(ray.direction);
    let mut node;
    let mut blocked = false;
    'walk: {
        obvhs::traverse!(
            bvh,
            node,
            state,
            node_hits_avx2(node, &ray, state.oct_inv4),
            {
                let (first, group) = take_group(&mut state);
                if leaf.any_avx2(first, group, o, d, tmax) {
                    blocked = true;
                    break 'walk;
                }
            }
        );
    }
    blocked
}

// The flat packets' kernel for an instruction set (`flat_simd.rs`, else the portable
// one in `flat.rs`).

/// [`FlatTriangles::intersect`] with the kernel of the level `isa` proves; the same
/// answer, bit for bit, at every level.
#[inline(always)]
pub(super) fn flat_intersect_with<L: Level>(
    isa: L,
    flat: &FlatTriangles,
    o: Vec3,
    d: Vec3,
    tmax: f32,
) -> Option<(usize, f32, f32, f32)> {
    #[cfg(target_arch = "x86_64")]
    {
        if let Some(_avx512) = isa.avx512() {
            // SAFETY: `_avx512` proves this CPU runs AVX-512.
            return unsafe { flat_simd::intersect_avx512(flat, o, d, tmax) };
        }
        if let Some(_avx2) = isa.avx2() {
            // SAFETY: `_avx2` proves this CPU runs AVX2.
            return unsafe { flat_simd::intersect_avx2(flat, o, d, tmax) };
        }
    }
    flat.intersect(o, d, tmax)
}

/// [`FlatTriangles::occluded`] with the kernel of the level `isa` proves.
#[inline(always)]
pub(super) fn flat_occluded_with<L: Level>(
    isa: L,
    flat: &FlatTriangles,
    o: Vec3,
    d: Vec3,
    tmax: f32,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        if let Some(_avx512) = isa.avx512() {
            // SAFETY: `_avx512` proves this CPU runs AVX-512.
            return unsafe { flat_simd::occluded_avx512(flat, o, d, tmax) };
        }
        if let Some(_avx2) = isa.avx2() {
            // SAFETY: `_avx2` proves this CPU runs AVX2.
            return unsafe { flat_simd::occluded_avx2(flat, o, d, tmax) };
        }
    }
    flat.occluded(o, d, tmax)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::Pcg32;
    use crate::scene::{Overrides, Scene};

    /// The exhaustive path and the BVH find the same surfaces on the bundled scenes.
    #[test]
    fn flat_packets_and_the_bvh_agree() {
        for name in ["cbox.xml", "cbox_spheres.xml"] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("scenes")
                .join(name);
            let scene = Scene::load(&path, &Overrides::default()).unwrap();
            let flat = Accel::build_with(&scene.shapes, FLAT_MAX);
            let bvh = Accel::build_with(&scene.shapes, 0);
            assert!(flat.flat.is_some() && bvh.bvh.is_some());
            let mut rng = Pcg32::new(5, 6);
            let mut v =
                || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
            let (mut hits, mut blocked) = (0, 0);
            for _ in 0..20_000 {
                let (o, d) = (v() * 0.95, v().normalize_or(Vec3::Z));
                let (a, b) = (
                    flat.intersect(&scene.shapes, o, d, f32::INFINITY),
                    bvh.intersect(&scene.shapes, o, d, f32::INFINITY),
                );
                match (a, b) {
                    (Some(a), Some(b)) => {
                        assert!(
                            (a.t - b.t).abs() <= 1e-5 * a.t.max(1.0),
                            "{name}: {} vs {}",
                            a.t,
                            b.t
                        );
                        if (a.t - b.t).abs() < 1e-7 {
                            assert_eq!(a.shape, b.shape);
                        }
                        hits += 1;
                        // Origins that sit on a surface (t below the ray offset) are not
                        // real queries: obvhs's node test is conservative there.
                        if a.t < 1e-3 {
                            continue;
                        }
                        // Blocked just beyond the first hit, free just before it.
                        let (beyond, before) = (a.t * 1.001, a.t * 0.999);
                        assert!(
                            flat.occluded(o, d, beyond) && bvh.occluded(o, d, beyond),
                            "{name} t {} flat {} bvh {} o {o} d {d}",
                            a.t,
                            flat.occluded(o, d, beyond),
                            bvh.occluded(o, d, beyond)
                        );
                        assert!(!flat.occluded(o, d, before) && !bvh.occluded(o, d, before));
                        blocked += 1;
                    }
                    (None, None) => {}
                    _ => panic!("{name}: one path hit, the other missed"),
                }
            }
            assert!(
                hits > 15_000 && blocked > hits * 99 / 100,
                "{name}: {hits} {blocked}"
            );
        }
    }
}
