//! Bounding volume hierarchy built with the binned surface-area heuristic (Wald 2007, "On fast
//! Construction of SAH-based Bounding Volume Hierarchies"; PBRT §4.3), built in parallel with rayon,
//! then collapsed into an 8-wide BVH (Wald et al. 2008, "Getting Rid of Packets"; Dammertz et al.
//! 2008, "Shallow Bounding Volume Hierarchies"; Embree's BVH8) whose nodes keep their eight
//! children's boxes in structure-of-arrays form, so one node visit is a single 8-lane slab test.
//! Long triangles are first cut into several references with tighter boxes (`split.rs`), so the
//! build sees boxes it can separate; a leaf keeps each primitive once. A leaf of triangles holds
//! them in packets of four (`TriPacket`) tested in SSE lanes at once. Traversal is front-to-back:
//! hit children are pushed farthest first with their entry distance, and entries beyond the
//! current closest hit are skipped when popped. At equal `t` the lowest primitive wins (as in
//! brute force), so the reported hit does not depend on the tree: coincident triangles give the
//! same image whatever the tree's shape, leaf size or visiting order.
//!
//! Where the CPU has AVX2 (detected at run time, not `target-cpu=native`, so one binary runs
//! everywhere) the traversal is compiled a second time with AVX2 enabled and the slab test is
//! written with AVX2 intrinsics: the eight lanes are one 256-bit operation per step. Elsewhere it
//! is plain lane-wise arithmetic that the compiler vectorises (SSE on x86-64). Both compute the
//! same IEEE operations in the same order per lane (no FMA: Rust never contracts, and the
//! intrinsics are plain sub/mul/max/min), so they find the same hits bit for bit
//! (`tests::simd_and_portable_traversal_agree`). The intrinsics are there because the vectoriser
//! split the far-plane half of the 8-lane loop into 4-lane pieces and shuffles (see BENCHMARKS.md).
//!
//! Why wide: on the Cornell box the binary tree's node tests were 19 % of all instructions and
//! the traversal loop another 14 % (callgrind, see BENCHMARKS.md); a 4-wide node did the work of
//! about three binary nodes for the cost of one, and an 8-wide node that of about seven.

use super::split::Reference;
use crate::geometry::PrimitiveKind;
use crate::geometry::primitive::Intersection;
use crate::geometry::triangle::TriangleEdges;
use crate::geometry::{Bounds3, GeometryStore, PrimRef, Ray, RayInv};
use crate::math::{Vec3, gamma};

const BINS: usize = 16;
const MAX_LEAF: usize = 8;
/// Cost of one traversal step relative to one primitive test (PBRT uses 1/8).
const TRAVERSAL_COST: f32 = 0.125;
/// Below this many primitives a subtree is built on the current thread.
const PARALLEL_THRESHOLD: usize = 4096;
/// Depth past which splits are by median; with at most 2^32 primitives the binary tree stays under
/// `MAX_BINARY_DEPTH` levels, and the wide tree is no deeper (each of its levels spans at least
/// one binary level).
const MEDIAN_SPLIT_DEPTH: usize = 60;
const MAX_BINARY_DEPTH: usize = 96;
/// Children per node.
pub const WIDTH: usize = 8;
/// Each wide level leaves at most `WIDTH − 1` entries on the stack besides the one it continues
/// with.
const STACK_SIZE: usize = (WIDTH - 1) * MAX_BINARY_DEPTH + 1;
/// Marks an unused lane of a node (its box is also empty, so it is never hit).
const EMPTY_LANE: u32 = u32::MAX;
/// How many ulps above the closest hit's `t` a child's entry distance may be and still be
/// visited, so an equal-`t` hit of a lower primitive is found whatever the tree (see
/// `intersect_impl`): more than the entry distance's rounding (γ₃ relative, a few ulps) plus the
/// Möller–Trumbore `t`'s for rays that are not grazing. Only children entered within that sliver
/// beyond the hit are visited additionally.
const TIE_ULPS: u32 = 32;

/// A wide node: the boxes of up to `WIDTH` children, one array per axis and side so the slab test
/// runs on all lanes at once: `planes[axis]` holds the lanes' minima on `axis`, `planes[3 + axis]`
/// their maxima (one array, so a ray picks its near and far plane of each axis by an index it
/// computes once, not by a select per node). A child with `count[i] > 0` is a leaf holding the
/// primitives `first[i] .. first[i] + count[i]` of `Bvh::prims`; with `count[i] == 0`, `first[i]`
/// is the index of a child node (or `EMPTY_LANE`).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct BvhNode {
    pub planes: [[f32; WIDTH]; 6],
    pub first: [u32; WIDTH],
    pub count: [u32; WIDTH],
}

impl BvhNode {
    const EMPTY: BvhNode = BvhNode {
        planes: [
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
        ],
        first: [EMPTY_LANE; WIDTH],
        count: [0; WIDTH],
    };

    fn set_lane(&mut self, lane: usize, bounds: &Bounds3, first: u32, count: u32) {
        for axis in 0..3 {
            self.planes[axis][lane] = bounds.min[axis];
            self.planes[3 + axis][lane] = bounds.max[axis];
        }
        self.first[lane] = first;
        self.count[lane] = count;
    }

    /// The box of `lane`.
    fn lane_bounds(&self, lane: usize) -> Bounds3 {
        let p = &self.planes;
        Bounds3 {
            min: Vec3::new(p[0][lane], p[1][lane], p[2][lane]),
            max: Vec3::new(p[3][lane], p[4][lane], p[5][lane]),
        }
    }
}

#[derive(Clone, Debug)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    pub prims: Vec<PrimRef>,
    /// The triangles of every all-triangle leaf again, as vertex and edges in packets of
    /// [`PACKET`] lanes (structure of arrays), so a leaf test is one ray against a packet's lanes
    /// at once and the triangles are read from consecutive memory instead of from wherever the
    /// mesh put them (on a 1M-triangle mesh that indirection was a cache miss per triangle,
    /// BENCHMARKS.md). Such a leaf's lane has `count = PACKET_LEAF | packets` and `first` = its
    /// first packet; other leaves (any non-triangle primitive, or trees built by `build_from`)
    /// index `prims` and are tested one primitive at a time. 160 bytes per packet.
    packets: Vec<TriPacket>,
    bounds: Bounds3,
    /// References the tree was built over (primitives plus the extra pieces of split triangles).
    references: usize,
    /// AVX2 was detected when the tree was built: traverse with the AVX2 copy of the code.
    avx2: bool,
}

/// Lanes of a leaf's triangle packet (SSE width, the x86-64 baseline: every CPU runs the same
/// code, so the AVX2 and portable traversals share it and its bits).
const PACKET: usize = 4;
/// Marks a leaf lane whose `first` indexes `Bvh::packets` (its `count`'s low bits are the number
/// of packets) rather than `Bvh::prims`.
const PACKET_LEAF: u32 = 1 << 31;
/// The primitive of a packet lane that holds no triangle (its edges are zero, so it is never hit).
const NO_PRIM: u32 = u32::MAX;
/// Largest all-triangle leaf: two packets.
const MAX_TRI_LEAF: usize = 2 * PACKET;
/// Cost of one packet test in units of one scalar triangle test, for the SAH's leaf decision
/// (callgrind: see BENCHMARKS.md (leaf triangle packets)).
const PACKET_COST: f32 = 1.5;
/// Cost of a two-packet leaf in units of one packet test: the AVX2 traversal tests both packets
/// in one 8-lane pass ([`TriPacket::intersect_pair_avx`]), so it costs less than two packet
/// tests. 2 (the packets one by one) → 1.5 → 1.2: ToyCar 8 926 → 7 993 → 7 902 nodes, render
/// instructions per ray 3077 → 3071 → 3072 (BENCHMARKS.md (ToyCar's traversal cost)).
const PAIR_COST: f32 = 1.5;

/// Up to [`PACKET`] triangles of one leaf in structure-of-arrays form: `v[0..3]` are the lanes'
/// first vertices (x, y, z), `v[3..6]` their edges `p1 − p0` and `v[6..9]` their edges `p2 − p0`,
/// exactly the values [`TriangleEdges`] holds, so a lane's test is bit-identical to the scalar
/// one. Unused lanes have zero edges (a zero determinant: never hit) and `prim = NO_PRIM`.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct TriPacket {
    v: [[f32; PACKET]; 9],
    prim: [u32; PACKET],
}

/// The lanes of a packet the ray hits before `t_max` (bit `i` for lane `i`) and their `t` and
/// barycentrics (meaningless in the other lanes). `N = 2 · PACKET` for the two packets of a leaf
/// tested at once ([`TriPacket::intersect_pair_avx`]): lanes `0..4` are the first packet's.
struct PacketHits<const N: usize = PACKET> {
    mask: u32,
    t: [f32; N],
    b1: [f32; N],
    b2: [f32; N],
}

impl TriPacket {
    const EMPTY: TriPacket = TriPacket {
        v: [[0.0; PACKET]; 9],
        prim: [NO_PRIM; PACKET],
    };

    fn set_lane(&mut self, lane: usize, tri: &TriangleEdges, prim: PrimRef) {
        for axis in 0..3 {
            self.v[axis][lane] = tri.p0[axis];
            self.v[3 + axis][lane] = tri.e1[axis];
            self.v[6 + axis][lane] = tri.e2[axis];
        }
        self.prim[lane] = prim.0;
    }

    /// [`TriangleEdges::intersect`] (Möller & Trumbore 1997) on every lane at once, in plain
    /// per-lane arithmetic ([`Scalar4`]). Used where there is no SSE; on x86-64
    /// [`Self::intersect`] runs the same [`moller_trumbore`] in SSE lanes.
    #[cfg_attr(target_arch = "x86_64", allow(dead_code))]
    #[inline(always)]
    fn intersect_lanes(&self, ray: &Ray, t_max: f32) -> PacketHits {
        moller_trumbore(|k| Scalar4(self.v[k]), ray, t_max)
    }

    /// The packet test: [`moller_trumbore`] in SSE lanes ([`Sse4`], the x86-64 baseline, so the
    /// AVX2 and portable traversals run this same code). Intrinsics because LLVM kept the plain
    /// form's arithmetic in vectors but scalarised its eight acceptance compares (21 `ucomiss`
    /// and as many `set`s per packet; ToyCar's closest hit went 1337 → 1494 instructions per call
    /// with that form, BENCHMARKS.md).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn intersect(&self, ray: &Ray, t_max: f32) -> PacketHits {
        moller_trumbore(|k| Sse4::row(self, k), ray, t_max)
    }
    /// The packet test where there is no SSE: [`Self::intersect_lanes`].
    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    fn intersect(&self, ray: &Ray, t_max: f32) -> PacketHits {
        self.intersect_lanes(ray, t_max)
    }

    /// [`Self::intersect`] on both packets of a two-packet leaf at once, in 256-bit AVX lanes
    /// ([`Avx8`]): lanes `0..4` are `pair[0]`'s, `4..8` `pair[1]`'s. Both packets are tested
    /// against the same `t_max`, where the SSE loop tests the second against a bound the first's
    /// hits may have lowered; the ranking (`rank`) is the same either way, since a hit beyond the
    /// lowered bound has a larger key than the hit that lowered it. Why: one 8-lane test costs
    /// about what one 4-lane test does, and ToyCar's leaves are mostly of two packets
    /// (BENCHMARKS.md (ToyCar's traversal cost)).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    fn intersect_pair_avx(pair: &[TriPacket; 2], ray: &Ray, t_max: f32) -> PacketHits<8> {
        // SAFETY: this function only runs where AVX is enabled (`target_feature`), which is the
        // one thing an `Avx8` needs.
        moller_trumbore(
            |k| unsafe { Avx8::load_pair(&pair[0].v[k], &pair[1].v[k]) },
            ray,
            t_max,
        )
    }
}

/// The lane operations [`moller_trumbore`] is written in: one generic test serves the 4-lane SSE
/// packet test ([`Sse4`]), the 8-lane AVX test of a leaf's two packets ([`Avx8`]) and the plain
/// per-lane form where there is no SSE ([`Scalar4`]). Every implementation runs, per lane, the
/// IEEE operation its name says (no FMA), so all three give the scalar test's bits.
trait MtLanes: Copy {
    /// Lanes (bits of the hit mask).
    const N: usize;
    /// A per-lane comparison result.
    type Mask: Copy;
    fn splat(x: f32) -> Self;
    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn div(self, o: Self) -> Self;
    /// `|self|` (the sign bit cleared).
    fn abs(self) -> Self;
    /// `self != o`, true where either is NaN (unordered; SSE `cmpneq`).
    fn ne_unord(self, o: Self) -> Self::Mask;
    /// `!(self < o)`, true where either is NaN (SSE `cmpnlt`).
    fn nlt_unord(self, o: Self) -> Self::Mask;
    /// `!(self > o)`, true where either is NaN (SSE `cmpngt`).
    fn ngt_unord(self, o: Self) -> Self::Mask;
    /// The ordered comparisons: false where either is NaN.
    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Bit `i` set where lane `i` of `m` is true.
    fn bits(m: Self::Mask) -> u32;
    /// Writes the lanes to `out[..N]`.
    fn store(self, out: &mut [f32]);
}

/// Möller & Trumbore (1997) on every lane of `row(0..9)` (the packets' first vertices, edges
/// `p1 − p0` and edges `p2 − p0`, x, y, z each): per lane the same IEEE operations on the same
/// operands in the same order as the scalar [`TriangleEdges::intersect`] (glam's `cross` and
/// left-to-right `dot`; Rust never contracts to FMA), and the same acceptance conditions with the
/// same NaN behaviour, so a lane's hit is the scalar test's, bit for bit
/// (`tests::packet_test_matches_the_scalar_test` checks every form).
#[inline(always)]
fn moller_trumbore<L: MtLanes, const N: usize>(
    row: impl Fn(usize) -> L,
    ray: &Ray,
    t_max: f32,
) -> PacketHits<N> {
    debug_assert_eq!(L::N, N);
    let [ox, oy, oz] = ray.o.to_array().map(L::splat);
    let [dx, dy, dz] = ray.d.to_array().map(L::splat);
    let (zero, one) = (L::splat(0.0), L::splat(1.0));
    let (e1x, e1y, e1z) = (row(3), row(4), row(5));
    let (e2x, e2y, e2z) = (row(6), row(7), row(8));
    // pvec = d × e2
    let px = dy.mul(e2z).sub(e2y.mul(dz));
    let py = dz.mul(e2x).sub(e2z.mul(dx));
    let pz = dx.mul(e2y).sub(e2x.mul(dy));
    let det = e1x.mul(px).add(e1y.mul(py)).add(e1z.mul(pz));
    let inv_det = one.div(det);
    // tvec = o − p0
    let (tx, ty, tz) = (ox.sub(row(0)), oy.sub(row(1)), oz.sub(row(2)));
    let b1 = tx.mul(px).add(ty.mul(py)).add(tz.mul(pz)).mul(inv_det);
    // qvec = tvec × e1
    let qx = ty.mul(e1z).sub(e1y.mul(tz));
    let qy = tz.mul(e1x).sub(e1z.mul(tx));
    let qz = tx.mul(e1y).sub(e1x.mul(ty));
    let b2 = dx.mul(qx).add(dy.mul(qy)).add(dz.mul(qz)).mul(inv_det);
    let t = e2x.mul(qx).add(e2y.mul(qy)).add(e2z.mul(qz)).mul(inv_det);
    // The scalar test's rejections, negated: a non-zero finite determinant, b1 in [0, 1], not
    // (b2 < 0 or b1 + b2 > 1), 0 < t < t_max.
    let ok = [
        det.ne_unord(zero),
        det.abs().lt(L::splat(f32::INFINITY)),
        b1.ge(zero),
        b1.le(one),
        b2.nlt_unord(zero),
        b1.add(b2).ngt_unord(one),
        t.gt(zero),
        t.lt(L::splat(t_max)),
    ]
    .into_iter()
    .reduce(L::and)
    .unwrap_or_else(|| zero.lt(zero));
    let mut out = PacketHits {
        mask: L::bits(ok),
        t: [0.0; N],
        b1: [0.0; N],
        b2: [0.0; N],
    };
    if out.mask != 0 {
        t.store(&mut out.t);
        b1.store(&mut out.b1);
        b2.store(&mut out.b2);
    }
    out
}

/// Four lanes in plain per-lane arithmetic (the packet test where there is no SSE).
#[derive(Clone, Copy)]
struct Scalar4([f32; PACKET]);

impl Scalar4 {
    #[inline(always)]
    fn map2(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        Scalar4(std::array::from_fn(|i| f(self.0[i], o.0[i])))
    }
    #[inline(always)]
    fn test(self, o: Self, f: impl Fn(f32, f32) -> bool) -> [bool; PACKET] {
        std::array::from_fn(|i| f(self.0[i], o.0[i]))
    }
}

impl MtLanes for Scalar4 {
    const N: usize = PACKET;
    type Mask = [bool; PACKET];
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Scalar4([x; PACKET])
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self.map2(o, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self.map2(o, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.map2(o, |a, b| a * b)
    }
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        self.map2(o, |a, b| a / b)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Scalar4(self.0.map(f32::abs))
    }
    #[inline(always)]
    fn ne_unord(self, o: Self) -> Self::Mask {
        self.test(o, |a, b| a != b)
    }
    #[inline(always)]
    fn nlt_unord(self, o: Self) -> Self::Mask {
        self.test(o, |a, b| !(a < b))
    }
    #[inline(always)]
    fn ngt_unord(self, o: Self) -> Self::Mask {
        self.test(o, |a, b| !(a > b))
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self::Mask {
        self.test(o, |a, b| a < b)
    }
    #[inline(always)]
    fn le(self, o: Self) -> Self::Mask {
        self.test(o, |a, b| a <= b)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self::Mask {
        self.test(o, |a, b| a > b)
    }
    #[inline(always)]
    fn ge(self, o: Self) -> Self::Mask {
        self.test(o, |a, b| a >= b)
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        std::array::from_fn(|i| a[i] & b[i])
    }
    #[inline(always)]
    fn bits(m: Self::Mask) -> u32 {
        m.iter().enumerate().map(|(i, &x)| (x as u32) << i).sum()
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        out[..PACKET].copy_from_slice(&self.0);
    }
}

#[cfg(target_arch = "x86_64")]
use lanes_x86::{Avx8, Sse4};

/// The SSE and AVX forms of [`MtLanes`]. The compares map one to one: `cmpneq` / `_CMP_NEQ_UQ`
/// for `ne_unord`, `cmpnlt` / `_CMP_NLT_UQ` and `cmpngt` / `_CMP_NGT_UQ` for the negated ones,
/// and the ordered `cmplt`/`cmple`/`cmpgt`/`cmpge` / `_CMP_*_OQ` for the rest (the quiet and
/// signalling AVX predicates give the same result; only the exception flag differs, and nothing
/// reads it).
#[cfg(target_arch = "x86_64")]
mod lanes_x86 {
    use super::{MtLanes, PACKET, TriPacket};
    use std::arch::x86_64::*;

    /// Four SSE lanes. SSE and SSE2 are part of x86-64 itself (every x86-64 CPU has them and
    /// the build enables them), so every intrinsic below may run anywhere this compiles.
    #[derive(Clone, Copy)]
    pub(super) struct Sse4(__m128);

    impl Sse4 {
        /// Row `k` of `p`, by an aligned load: LLVM then folds it into the arithmetic, where an
        /// unaligned one costs a separate `movups` in the non-VEX SSE code of the portable
        /// traversal (ToyCar: +0.4 % render instructions with `_mm_loadu_ps` or `_mm_set_ps`).
        #[inline(always)]
        pub(super) fn row(p: &TriPacket, k: usize) -> Sse4 {
            let r = &p.v[k];
            // SAFETY: a `TriPacket` is 32-byte aligned and its rows are 16 bytes each, so row `k`
            // starts on a 16-byte boundary: 16 readable, aligned bytes. SSE: see `Sse4`.
            Sse4(unsafe { _mm_load_ps(r.as_ptr()) })
        }
    }

    /// Eight AVX lanes. Only made by `Avx8::load_pair`, whose callers run with AVX enabled
    /// (`TriPacket::intersect_pair_avx` is `#[target_feature(enable = "avx")]`), and every
    /// method is inlined into them: so every AVX intrinsic below runs where AVX is.
    #[derive(Clone, Copy)]
    pub(super) struct Avx8(__m256);

    impl Avx8 {
        /// `lo` in lanes `0..4`, `hi` in lanes `4..8`.
        ///
        /// # Safety
        /// The CPU must have AVX.
        #[inline(always)]
        pub(super) unsafe fn load_pair(lo: &[f32; PACKET], hi: &[f32; PACKET]) -> Avx8 {
            // SAFETY: each row is 16 readable bytes (unaligned loads); AVX: the caller's.
            Avx8(unsafe { _mm256_loadu2_m128(hi.as_ptr(), lo.as_ptr()) })
        }
    }

    /// One `MtLanes` implementation per register width: `$lanes` lanes of `$ty`, the
    /// intrinsics named by the rest.
    macro_rules! mt_lanes {
        ($(#[$attr:meta])* $ty:ident, $reg:ty, $lanes:expr, $set1:ident, $add:ident, $sub:ident, $mul:ident,
         $div:ident, $andnot:ident, $and:ident, $movemask:ident, $storeu:ident,
         $cmp:ident : $neq:expr, $nlt:expr, $ngt:expr, $lt:expr, $le:expr, $gt:expr, $ge:expr) => {
            $(#[$attr])*
            impl MtLanes for $ty {
                const N: usize = $lanes;
                type Mask = $reg;
                // SAFETY (every method): the instruction set is there, see the type's comment.
                #[inline(always)]
                fn splat(x: f32) -> Self {
                    $ty(unsafe { $set1(x) })
                }
                #[inline(always)]
                fn add(self, o: Self) -> Self {
                    $ty(unsafe { $add(self.0, o.0) })
                }
                #[inline(always)]
                fn sub(self, o: Self) -> Self {
                    $ty(unsafe { $sub(self.0, o.0) })
                }
                #[inline(always)]
                fn mul(self, o: Self) -> Self {
                    $ty(unsafe { $mul(self.0, o.0) })
                }
                #[inline(always)]
                fn div(self, o: Self) -> Self {
                    $ty(unsafe { $div(self.0, o.0) })
                }
                #[inline(always)]
                fn abs(self) -> Self {
                    $ty(unsafe { $andnot($set1(-0.0), self.0) })
                }
                #[inline(always)]
                fn ne_unord(self, o: Self) -> $reg {
                    unsafe { $cmp::<{ $neq }>(self.0, o.0) }
                }
                #[inline(always)]
                fn nlt_unord(self, o: Self) -> $reg {
                    unsafe { $cmp::<{ $nlt }>(self.0, o.0) }
                }
                #[inline(always)]
                fn ngt_unord(self, o: Self) -> $reg {
                    unsafe { $cmp::<{ $ngt }>(self.0, o.0) }
                }
                #[inline(always)]
                fn lt(self, o: Self) -> $reg {
                    unsafe { $cmp::<{ $lt }>(self.0, o.0) }
                }
                #[inline(always)]
                fn le(self, o: Self) -> $reg {
                    unsafe { $cmp::<{ $le }>(self.0, o.0) }
                }
                #[inline(always)]
                fn gt(self, o: Self) -> $reg {
                    unsafe { $cmp::<{ $gt }>(self.0, o.0) }
                }
                #[inline(always)]
                fn ge(self, o: Self) -> $reg {
                    unsafe { $cmp::<{ $ge }>(self.0, o.0) }
                }
                #[inline(always)]
                fn and(a: $reg, b: $reg) -> $reg {
                    unsafe { $and(a, b) }
                }
                #[inline(always)]
                fn bits(m: $reg) -> u32 {
                    unsafe { $movemask(m) as u32 }
                }
                #[inline(always)]
                fn store(self, out: &mut [f32]) {
                    let out = &mut out[..$lanes];
                    // SAFETY: `out` is `$lanes` writable f32 (unaligned store).
                    unsafe { $storeu(out.as_mut_ptr(), self.0) }
                }
            }
        };
    }

    /// SSE's compares as one const-generic function, like AVX's `_mm256_cmp_ps`, so both widths
    /// are spelled by the same macro; the predicate numbers are AVX's (`_CMP_*`), each mapped to
    /// the SSE compare with the same result.
    #[inline(always)]
    unsafe fn sse_cmp<const P: i32>(a: __m128, b: __m128) -> __m128 {
        // SAFETY: SSE, see `Sse4`.
        unsafe {
            match P {
                _CMP_NEQ_UQ => _mm_cmpneq_ps(a, b),
                _CMP_NLT_UQ => _mm_cmpnlt_ps(a, b),
                _CMP_NGT_UQ => _mm_cmpngt_ps(a, b),
                _CMP_LT_OQ => _mm_cmplt_ps(a, b),
                _CMP_LE_OQ => _mm_cmple_ps(a, b),
                _CMP_GT_OQ => _mm_cmpgt_ps(a, b),
                _CMP_GE_OQ => _mm_cmpge_ps(a, b),
                _ => unreachable!("no SSE compare for predicate {P}"),
            }
        }
    }

    mt_lanes!(
        Sse4, __m128, 4, _mm_set1_ps, _mm_add_ps, _mm_sub_ps, _mm_mul_ps, _mm_div_ps,
        _mm_andnot_ps, _mm_and_ps, _mm_movemask_ps, _mm_storeu_ps,
        sse_cmp: _CMP_NEQ_UQ, _CMP_NLT_UQ, _CMP_NGT_UQ, _CMP_LT_OQ, _CMP_LE_OQ, _CMP_GT_OQ,
        _CMP_GE_OQ);
    mt_lanes!(Avx8, __m256, 8, _mm256_set1_ps, _mm256_add_ps, _mm256_sub_ps, _mm256_mul_ps,
        _mm256_div_ps, _mm256_andnot_ps, _mm256_and_ps, _mm256_movemask_ps, _mm256_storeu_ps,
        _mm256_cmp_ps: _CMP_NEQ_UQ, _CMP_NLT_UQ, _CMP_NGT_UQ, _CMP_LT_OQ, _CMP_LE_OQ,
        _CMP_GT_OQ, _CMP_GE_OQ);
}

#[derive(Clone, Copy)]
struct BuildPrim {
    prim: PrimRef,
    bounds: Bounds3,
    centroid: Vec3,
}

enum BuildNode {
    Leaf {
        bounds: Bounds3,
        first: usize,
        count: usize,
    },
    Interior {
        bounds: Bounds3,
        children: Box<[BuildNode; 2]>,
    },
}

impl BuildNode {
    fn bounds(&self) -> Bounds3 {
        match self {
            BuildNode::Leaf { bounds, .. } | BuildNode::Interior { bounds, .. } => *bounds,
        }
    }
}

/// Summary of a BVH for reports and tests.
#[derive(Clone, Copy, Debug, Default)]
pub struct BvhStats {
    pub nodes: usize,
    pub leaves: usize,
    pub max_depth: usize,
    pub max_leaf_size: usize,
    /// References built over (primitives, plus the extra pieces of split triangles).
    pub references: usize,
    /// Primitive entries in the leaves (a split triangle may sit in several leaves).
    pub leaf_prims: usize,
    /// Triangle packets of the all-triangle leaves ([`PACKET`] lanes, 160 bytes each).
    pub packets: usize,
    /// Of those leaves, the ones of two packets (tested 8 lanes at once where AVX is there).
    pub two_packet_leaves: usize,
    /// The SAH cost of the wide tree (Goldsmith & Salmon 1987; MacDonald & Booth 1990): the
    /// expected number of wide-node tests plus primitive tests of a ray that crosses the root
    /// box, for uniformly distributed rays: Σ over nodes of A(node)/A(root) + Σ over leaves of
    /// A(leaf)/A(root) · primitives. Both tests are counted as cost 1 (an 8-lane node test and a
    /// triangle test take a similar number of instructions, see BENCHMARKS.md).
    pub sah_cost: f64,
}

/// Per-ray constants of the wide slab test: the origin, the inverse direction and, per axis, the
/// rows of [`BvhNode::planes`] holding the near and far planes (the max is near for a negative
/// direction).
struct SlabRay {
    o: [f32; 3],
    inv: [f32; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl SlabRay {
    #[inline(always)]
    fn new(ray: &Ray, inv: &RayInv) -> SlabRay {
        let neg = |a: usize| (inv.neg[a] == 1) as usize;
        SlabRay {
            o: ray.o.to_array(),
            inv: inv.inv_d.to_array(),
            near: [3 * neg(0), 1 + 3 * neg(1), 2 + 3 * neg(2)],
            far: [3 - 3 * neg(0), 4 - 3 * neg(1), 5 - 3 * neg(2)],
        }
    }

    /// Entry distances of the children and a bit mask of those the ray hits before `t_max`.
    /// Far distances are enlarged by 1 + 2γ₃ so the test stays conservative under rounding
    /// (PBRT-v4 eq. 6.17); min/max are written so a NaN (0·∞) operand is ignored, not propagated.
    #[inline(always)]
    fn test(&self, n: &BvhNode, t_max: f32) -> ([f32; WIDTH], u32) {
        let g = 1.0 + 2.0 * gamma(3);
        let mut t0 = [0.0f32; WIDTH];
        let mut t1 = [t_max; WIDTH];
        for axis in 0..3 {
            let (near, far) = (&n.planes[self.near[axis]], &n.planes[self.far[axis]]);
            let (o, inv) = (self.o[axis], self.inv[axis]);
            for lane in 0..WIDTH {
                let tn = (near[lane] - o) * inv;
                let tf = (far[lane] - o) * inv * g;
                t0[lane] = if tn > t0[lane] { tn } else { t0[lane] };
                t1[lane] = if tf < t1[lane] { tf } else { t1[lane] };
            }
        }
        let mut mask = 0u32;
        for lane in 0..WIDTH {
            mask |= ((t0[lane] <= t1[lane]) as u32) << lane;
        }
        (t0, mask)
    }
}

#[cfg(target_arch = "x86_64")]
impl SlabRay {
    /// [`SlabRay::test`] in AVX2 intrinsics: the same operations per lane in the same order
    /// (`MAXPS(a, b)` is `a > b ? a : b` and `MINPS(a, b)` is `a < b ? a : b`, exactly the
    /// selects of the portable code, NaN included; `≤` is the ordered compare).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn test_avx2(&self, n: &BvhNode, t_max: f32) -> ([f32; WIDTH], u32) {
        use std::arch::x86_64::*;
        let (t0, hit) = self.test_avx2_vectors(n, t_max);
        let mask = _mm256_movemask_ps(hit) as u32;
        let mut out = [0.0f32; WIDTH];
        // SAFETY: `out` is `[f32; 8]`: 32 writable bytes (unaligned store).
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), t0) };
        (out, mask)
    }

    /// [`SlabRay::test_avx2`] left in registers: the entry distances and the lanes' hit compare
    /// (all ones where the child is hit).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn test_avx2_vectors(
        &self,
        n: &BvhNode,
        t_max: f32,
    ) -> (std::arch::x86_64::__m256, std::arch::x86_64::__m256) {
        use std::arch::x86_64::*;
        let g = _mm256_set1_ps(1.0 + 2.0 * gamma(3));
        let mut t0 = _mm256_setzero_ps();
        let mut t1 = _mm256_set1_ps(t_max);
        let planes = n.planes.as_ptr();
        for axis in 0..3 {
            let o = _mm256_set1_ps(self.o[axis]);
            let inv = _mm256_set1_ps(self.inv[axis]);
            // SAFETY: `near` and `far` are row indices below 6 (`SlabRay::new` makes them
            // `axis` or `3 + axis`), so each row is a `[f32; 8]` of the node: 32 readable bytes
            // (unaligned load). Unchecked because the per-node bounds checks (or the select of
            // min/max this replaces) cost ~6 % of ToyCar's traversal instructions (callgrind).
            let (near, far) = unsafe {
                (
                    _mm256_loadu_ps((*planes.add(self.near[axis])).as_ptr()),
                    _mm256_loadu_ps((*planes.add(self.far[axis])).as_ptr()),
                )
            };
            let tn = _mm256_mul_ps(_mm256_sub_ps(near, o), inv);
            let tf = _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(far, o), inv), g);
            t0 = _mm256_max_ps(tn, t0);
            t1 = _mm256_min_ps(tf, t1);
        }
        (t0, _mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1))
    }
}

/// The node test a traversal copy uses: portable, or AVX2 (only in the copies compiled with it).
#[inline(always)]
fn node_test<const AVX2: bool>(slab: &SlabRay, n: &BvhNode, t_max: f32) -> ([f32; WIDTH], u32) {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: `AVX2 = true` is only instantiated by `intersect_avx2` / `occluded_avx2`, which
        // run only after `is_x86_feature_detected!("avx2")` (see `Bvh::intersect`).
        return unsafe { slab.test_avx2(n, t_max) };
    }
    slab.test(n, t_max)
}

/// The traversal stack, left uninitialised: zeroing it per ray was a `memset` that cost ~2% of all
/// instructions on the Cornell box (callgrind). Entries are only read below the stack pointer,
/// after having been written.
struct TraversalStack<T: Copy>([std::mem::MaybeUninit<T>; STACK_SIZE]);

impl<T: Copy> TraversalStack<T> {
    #[inline(always)]
    fn new() -> Self {
        TraversalStack([std::mem::MaybeUninit::uninit(); STACK_SIZE])
    }

    #[inline(always)]
    fn set(&mut self, i: usize, v: T) {
        self.0[i] = std::mem::MaybeUninit::new(v);
    }

    #[inline(always)]
    fn get(&self, i: usize) -> T {
        // SAFETY: traversal pops index `i` only after pushing it (the stack pointer counts pushes
        // minus pops), so the entry was written; indexing is bounds-checked.
        unsafe { self.0[i].assume_init() }
    }
}

/// A stack entry: a child lane's `first`, `count` and entry distance.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    first: u32,
    count: u32,
    t: f32,
}

/// Slots of the closest-hit stack: [`STACK_SIZE`] plus one node's worth, because the AVX2 walk
/// writes all `WIDTH` sorted lanes of a node at once (the missed ones land above the top and
/// are never read).
const ENTRY_STACK: usize = STACK_SIZE + WIDTH;

/// The closest-hit walk's stack of [`Entry`]s as three arrays (structure of arrays), so the AVX2
/// walk pushes a node's sorted children with one 8-lane store per field. Left uninitialised as
/// [`TraversalStack`] is; slots are read only below the stack pointer, after being written.
struct EntryStack {
    first: [std::mem::MaybeUninit<u32>; ENTRY_STACK],
    count: [std::mem::MaybeUninit<u32>; ENTRY_STACK],
    t: [std::mem::MaybeUninit<f32>; ENTRY_STACK],
}

impl EntryStack {
    #[inline(always)]
    fn new() -> Self {
        let u = std::mem::MaybeUninit::uninit();
        EntryStack {
            first: [u; ENTRY_STACK],
            count: [u; ENTRY_STACK],
            t: [std::mem::MaybeUninit::uninit(); ENTRY_STACK],
        }
    }

    #[inline(always)]
    fn set(&mut self, i: usize, e: Entry) {
        self.first[i] = std::mem::MaybeUninit::new(e.first);
        self.count[i] = std::mem::MaybeUninit::new(e.count);
        self.t[i] = std::mem::MaybeUninit::new(e.t);
    }

    #[inline(always)]
    fn get(&self, i: usize) -> Entry {
        // SAFETY: as in `TraversalStack::get`: slot `i` was written (by `set` or by the 8-lane
        // stores of `push_sorted_avx2`, which write every field of slots `sp .. sp + WIDTH`)
        // before the stack pointer moved above it; indexing is bounds-checked.
        unsafe {
            Entry {
                first: self.first[i].assume_init(),
                count: self.count[i].assume_init(),
                t: self.t[i].assume_init(),
            }
        }
    }
}

/// The order in which a node's hit children are visited, as one integer per child: the bits of
/// its entry distance `t` (a non-negative float, whose bits order as it does) with the low three
/// replaced by `7 − lane`. Children are visited by increasing key: nearest first, and among equal
/// `t` the higher lane first (the order of the earlier insertion sort). Only children whose `t`
/// differ in the last three bits alone (within 8 ulps) are ordered by lane instead of by `t`:
/// the reported hit does not depend on the order (hits are ranked by `t` and primitive, see
/// `intersect_impl`), only how many entries the shrinking bound culls. Unique keys let the AVX2
/// walk sort them with a plain min/max network ([`sort_desc_avx2`]).
#[inline(always)]
fn child_key(t: f32, lane: usize) -> u32 {
    (t.to_bits() & !7) | (7 - lane as u32)
}

/// The next child of a node to visit, if any hit: the one of smallest [`child_key`]; the other
/// hit children are pushed on `stack` above `*sp`, largest key deepest, so they pop in
/// increasing key order. Portable form: an insertion sort over the hit lanes.
#[inline(always)]
fn order_children(
    n: &BvhNode,
    t_enter: &[f32; WIDTH],
    mut mask: u32,
    stack: &mut EntryStack,
    sp: &mut usize,
) -> Option<Entry> {
    if mask == 0 {
        return None;
    }
    let entry = |lane: usize| Entry {
        first: n.first[lane],
        count: n.count[lane],
        t: t_enter[lane],
    };
    let lane = mask.trailing_zeros() as usize;
    if mask & (mask - 1) == 0 {
        // One child hit (most nodes): nothing to sort or push.
        return Some(entry(lane));
    }
    let mut keys = [0u32; WIDTH];
    let mut k = 0;
    while mask != 0 {
        let lane = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let key = child_key(t_enter[lane], lane);
        let mut i = k;
        while i > 0 && keys[i - 1] < key {
            keys[i] = keys[i - 1];
            i -= 1;
        }
        keys[i] = key;
        k += 1;
    }
    for &key in &keys[..k - 1] {
        stack.set(*sp, entry(7 - (key & 7) as usize));
        *sp += 1;
    }
    Some(entry(7 - (keys[k - 1] & 7) as usize))
}

/// Sorts eight signed 32-bit integers, largest in lane 0, with a bitonic network (Batcher 1968:
/// sorted pairs, merged to fours, merged to eight, each merge comparing lane `i` with its mirror
/// and then half-cleaning at distances 2 and 1): six compare-exchange stages of a shuffle, a
/// min, a max and a blend, and no branch.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn sort_desc_avx2(v: std::arch::x86_64::__m256i) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    // Each lane against the partner lane in `p`: the lanes set in `HI` keep the smaller value.
    macro_rules! exchange {
        ($v:expr, $p:expr, $hi:literal) => {{
            let (v, p) = ($v, $p);
            _mm256_blend_epi32::<$hi>(_mm256_max_epi32(v, p), _mm256_min_epi32(v, p))
        }};
    }
    // Partners: `i ^ 1` (shuffle 2301), `3 − i` within each four (0123), `i ^ 2` (1032),
    // `7 − i` (a full reversal).
    let v = exchange!(v, _mm256_shuffle_epi32::<0b10_11_00_01>(v), 0b1010_1010);
    let v = exchange!(v, _mm256_shuffle_epi32::<0b00_01_10_11>(v), 0b1100_1100);
    let v = exchange!(v, _mm256_shuffle_epi32::<0b10_11_00_01>(v), 0b1010_1010);
    let mirror = _mm256_setr_epi32(7, 6, 5, 4, 3, 2, 1, 0);
    let v = exchange!(v, _mm256_permutevar8x32_epi32(v, mirror), 0b1111_0000);
    let v = exchange!(v, _mm256_shuffle_epi32::<0b01_00_11_10>(v), 0b1100_1100);
    exchange!(v, _mm256_shuffle_epi32::<0b10_11_00_01>(v), 0b1010_1010)
}

/// [`order_children`] for the AVX2 walk, from the node test's registers. With two or more
/// children hit, the order is found without a data-dependent branch: the lanes' keys
/// ([`child_key`]; a missed lane gets a negative key, so it sorts last) are sorted in a register
/// ([`sort_desc_avx2`]), the lane numbers in their low bits permute the node's `first` and
/// `count` and the entry distances into stack order, and three 8-lane stores push them, the
/// stack pointer then advancing by the number of hits. The insertion sort it replaces
/// mispredicted ~3.7 times per ToyCar closest-hit call (cachegrind).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn order_children_avx2(
    n: &BvhNode,
    t0: std::arch::x86_64::__m256,
    hit: std::arch::x86_64::__m256,
    stack: &mut EntryStack,
    sp: &mut usize,
) -> Option<Entry> {
    use std::arch::x86_64::*;
    let mask = _mm256_movemask_ps(hit) as u32;
    if mask == 0 {
        return None;
    }
    let lane = mask.trailing_zeros() as usize & (WIDTH - 1);
    if mask & (mask - 1) == 0 {
        let t = _mm256_cvtss_f32(_mm256_permutevar8x32_ps(t0, _mm256_set1_epi32(lane as i32)));
        return Some(Entry {
            first: n.first[lane],
            count: n.count[lane],
            t,
        });
    }
    let code = _mm256_setr_epi32(7, 6, 5, 4, 3, 2, 1, 0);
    let bits = _mm256_and_si256(_mm256_castps_si256(t0), _mm256_set1_epi32(!7));
    let key = _mm256_blendv_epi8(
        _mm256_or_si256(code, _mm256_set1_epi32(i32::MIN)),
        _mm256_or_si256(bits, code),
        _mm256_castps_si256(hit),
    );
    // `key & 7` is `7 − lane`; the permutes read only an index's low three bits.
    let lanes = _mm256_xor_si256(sort_desc_avx2(key), _mm256_set1_epi32(7));
    // SAFETY: `BvhNode::first` / `count` are `[u32; 8]`: 32 readable bytes each.
    let (first, count) = unsafe {
        (
            _mm256_loadu_si256(n.first.as_ptr().cast()),
            _mm256_loadu_si256(n.count.as_ptr().cast()),
        )
    };
    let first = _mm256_permutevar8x32_epi32(first, lanes);
    let count = _mm256_permutevar8x32_epi32(count, lanes);
    let t = _mm256_permutevar8x32_ps(t0, lanes);
    assert!(*sp + WIDTH <= ENTRY_STACK, "traversal stack overflow");
    // SAFETY: slots `sp .. sp + WIDTH` lie in each array (checked above): 32 writable bytes.
    unsafe {
        _mm256_storeu_si256(stack.first.as_mut_ptr().add(*sp).cast(), first);
        _mm256_storeu_si256(stack.count.as_mut_ptr().add(*sp).cast(), count);
        _mm256_storeu_ps(stack.t.as_mut_ptr().add(*sp).cast(), t);
    }
    *sp += mask.count_ones() as usize - 1;
    Some(stack.get(*sp))
}

/// A node's test and [`order_children`] in the traversal copy's form.
#[inline(always)]
fn visit_node<const AVX2: bool>(
    slab: &SlabRay,
    n: &BvhNode,
    t_max: f32,
    stack: &mut EntryStack,
    sp: &mut usize,
) -> Option<Entry> {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: as in `node_test`.
        return unsafe {
            let (t0, hit) = slab.test_avx2_vectors(n, t_max);
            order_children_avx2(n, t0, hit, stack, sp)
        };
    }
    let (t_enter, mask) = slab.test(n, t_max);
    order_children(n, &t_enter, mask, stack, sp)
}

impl Bvh {
    /// Builds over every primitive of `geometry`, long triangles pre-split into several
    /// references (`split.rs`, budget [`super::split::budget_from_env`]).
    pub fn build(geometry: &GeometryStore) -> Bvh {
        Self::build_split(geometry, super::split::budget_from_env())
    }

    /// [`Self::build`] with an explicit pre-split budget (extra references as a share of the
    /// triangle count; 0 builds over one reference per primitive).
    pub fn build_split(geometry: &GeometryStore, budget: f32) -> Bvh {
        let refs = super::split::references(geometry, budget);
        let mut bvh = Self::build_references(refs);
        // Every all-triangle leaf becomes packets (nodes in order, so the packets keep the
        // leaves' depth-first order); the others keep their range of `prims`.
        let Bvh { nodes, prims, .. } = &mut bvh;
        let mut packets = Vec::with_capacity(prims.len() / PACKET + 1);
        for node in nodes.iter_mut() {
            for lane in 0..WIDTH {
                let (first, count) = (node.first[lane] as usize, node.count[lane] as usize);
                if count == 0 {
                    continue;
                }
                let leaf = &prims[first..first + count];
                if leaf.iter().any(|p| p.kind() != PrimitiveKind::Triangle) {
                    continue;
                }
                node.first[lane] = packets.len() as u32;
                node.count[lane] = PACKET_LEAF | count.div_ceil(PACKET) as u32;
                for chunk in leaf.chunks(PACKET) {
                    let mut packet = TriPacket::EMPTY;
                    for (i, &prim) in chunk.iter().enumerate() {
                        packet.set_lane(i, &geometry.triangles[prim.index()].edges(), prim);
                    }
                    packets.push(packet);
                }
            }
        }
        bvh.packets = packets;
        bvh
    }

    /// The primitives of leaf lane `(first, count)` (a packet leaf's or a `prims` range's).
    fn leaf_entries(&self, first: u32, count: u32) -> Vec<PrimRef> {
        let first = first as usize;
        if count & PACKET_LEAF == 0 {
            return self.prims[first..first + count as usize].to_vec();
        }
        let packets = &self.packets[first..first + (count & !PACKET_LEAF) as usize];
        packets
            .iter()
            .flat_map(|p| p.prim)
            .filter(|&p| p != NO_PRIM)
            .map(PrimRef)
            .collect()
    }

    /// The packets of packet leaf lane `(first, count)`.
    #[inline(always)]
    fn packet_leaf(&self, first: u32, count: u32) -> &[TriPacket] {
        let first = first as usize;
        &self.packets[first..first + (count & !PACKET_LEAF) as usize]
    }

    /// Builds over any set of primitives given their bounds (no splitting). Primitives with empty
    /// or non-finite bounds (degenerate input) are left out: they can never be hit.
    pub fn build_from(prims: Vec<PrimRef>, bounds_of: impl Fn(PrimRef) -> Bounds3 + Sync) -> Bvh {
        let refs = prims
            .into_iter()
            .filter_map(|prim| {
                let bounds = bounds_of(prim);
                let ok = !bounds.is_empty() && bounds.min.is_finite() && bounds.max.is_finite();
                ok.then_some(Reference { prim, bounds })
            })
            .collect();
        Self::build_references(refs)
    }

    /// Builds over references (a primitive and a box holding the part of it the reference
    /// stands for; a split triangle has several). A leaf holding two references of one primitive
    /// keeps one.
    fn build_references(refs: Vec<Reference>) -> Bvh {
        let references = refs.len();
        let mut build: Vec<BuildPrim> = refs
            .into_iter()
            .map(|r| BuildPrim {
                prim: r.prim,
                bounds: r.bounds,
                centroid: r.bounds.centroid(),
            })
            .collect();
        if build.is_empty() {
            return Bvh {
                nodes: Vec::new(),
                prims: Vec::new(),
                packets: Vec::new(),
                bounds: Bounds3::EMPTY,
                references: 0,
                avx2: false,
            };
        }
        let root = build_recursive(&mut build, 0, 0);
        let bounds = root.bounds();
        let mut nodes = Vec::with_capacity(build.len() / 2 + 1);
        let mut prims = Vec::with_capacity(build.len());
        nodes.push(BvhNode::EMPTY);
        match &root {
            BuildNode::Leaf { .. } => {
                let (first, count) = leaf_prims(&root, &build, &mut prims);
                nodes[0].set_lane(0, &bounds, first, count);
            }
            BuildNode::Interior { .. } => collapse(&root, 0, &build, &mut nodes, &mut prims),
        }
        Bvh {
            nodes,
            prims,
            packets: Vec::new(),
            bounds,
            references,
            avx2: crate::math::detect_avx2(),
        }
    }

    pub fn bounds(&self) -> Bounds3 {
        self.bounds
    }

    /// Bytes held by the hierarchy (nodes, leaf order, the leaves' triangle packets).
    pub fn heap_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<BvhNode>()
            + self.prims.len() * std::mem::size_of::<PrimRef>()
            + self.packets.len() * std::mem::size_of::<TriPacket>()
    }

    pub fn stats(&self) -> BvhStats {
        let mut s = BvhStats {
            nodes: self.nodes.len(),
            references: self.references,
            ..Default::default()
        };
        if self.nodes.is_empty() {
            return s;
        }
        let root_area = (self.bounds.surface_area() as f64).max(f64::MIN_POSITIVE);
        // The root node is tested by every ray that enters the root box.
        s.sah_cost = 1.0;
        let mut stack = vec![(0usize, 1usize)];
        while let Some((i, depth)) = stack.pop() {
            let n = &self.nodes[i];
            s.max_depth = s.max_depth.max(depth);
            for lane in 0..WIDTH {
                let area = n.lane_bounds(lane).surface_area() as f64 / root_area;
                if n.count[lane] > 0 {
                    let size = self.leaf_entries(n.first[lane], n.count[lane]).len();
                    s.leaves += 1;
                    s.leaf_prims += size;
                    if n.count[lane] & PACKET_LEAF != 0 {
                        let packets = (n.count[lane] & !PACKET_LEAF) as usize;
                        s.packets += packets;
                        s.two_packet_leaves += (packets == 2) as usize;
                    }
                    s.max_leaf_size = s.max_leaf_size.max(size);
                    s.sah_cost += area * size as f64;
                } else if n.first[lane] != EMPTY_LANE {
                    s.sah_cost += area;
                    stack.push((n.first[lane] as usize, depth + 1));
                }
            }
        }
        s
    }

    /// Closest hit, visiting nearer children first so far subtrees are culled by the shrinking
    /// `t_max`.
    #[inline]
    pub fn intersect(&self, geometry: &GeometryStore, ray: &Ray) -> Option<Intersection> {
        if !ray.is_traceable() {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is only set when `is_x86_feature_detected!("avx2")` said the CPU
            // has it. Measured reason for the second copy: see the module comment / BENCHMARKS.md.
            return unsafe { self.intersect_avx2(geometry, ray) };
        }
        self.intersect_portable(geometry, ray)
    }

    /// True as soon as any primitive blocks the ray.
    #[inline]
    pub fn occluded(&self, geometry: &GeometryStore, ray: &Ray) -> bool {
        if !ray.is_traceable() {
            return false;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `intersect`.
            return unsafe { self.occluded_avx2(geometry, ray) };
        }
        self.occluded_portable(geometry, ray)
    }

    /// [`Self::intersect`] compiled for the build's baseline CPU (SSE2 on x86-64).
    pub fn intersect_portable(&self, geometry: &GeometryStore, ray: &Ray) -> Option<Intersection> {
        self.intersect_impl::<false>(geometry, ray)
    }

    /// [`Self::occluded`] compiled for the build's baseline CPU.
    pub fn occluded_portable(&self, geometry: &GeometryStore, ray: &Ray) -> bool {
        self.occluded_impl::<false>(geometry, ray)
    }

    /// [`Self::intersect`] compiled with AVX2: the slab test's eight lanes are one instruction.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub unsafe fn intersect_avx2(
        &self,
        geometry: &GeometryStore,
        ray: &Ray,
    ) -> Option<Intersection> {
        self.intersect_impl::<true>(geometry, ray)
    }

    /// [`Self::occluded`] compiled with AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub unsafe fn occluded_avx2(&self, geometry: &GeometryStore, ray: &Ray) -> bool {
        self.occluded_impl::<true>(geometry, ray)
    }

    #[inline(always)]
    fn intersect_impl<const AVX2: bool>(
        &self,
        geometry: &GeometryStore,
        ray: &Ray,
    ) -> Option<Intersection> {
        if self.nodes.is_empty() {
            return None;
        }
        let slab = SlabRay::new(ray, &RayInv::new(ray.d));
        let mut best: Option<Intersection> = None;
        // Ties are order-independent: at equal `t` the lowest primitive wins, as in brute force
        // (which tests primitives in `PrimRef` order and keeps the first). So the hit reported on
        // coincident triangles does not depend on the tree's shape or visiting order. A hit is
        // ranked by one integer, `t`'s bits above its primitive's (a positive float's bits order
        // as the float does), so "nearer, or as near and lower" is one compare. The leaf test's
        // bound and the culling bound `t_cull` lie `TIE_ULPS` above the closest hit: a hit at
        // exactly its `t` comes back to be ranked, and a child is visited if entered up to
        // `TIE_ULPS` beyond it, because a box's entry distance is rounded (γ₃, PBRT-v4 §6.8) and
        // the triangle test's `t` too, so a coincident triangle lying on its box's near face can
        // compute an entry a few ulps above the tie's `t`.
        let mut best_key = u64::MAX;
        let mut t_cull = ray.t_max;
        let mut stack = EntryStack::new();
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            // The next child to visit, if this node has one: the nearest hit child. The others
            // are pushed farthest first, so the nearest of them is popped next. This is the
            // order of pushing all of them and popping one, without the push and pop: the
            // nearest never waits on the stack, and with one child hit (most nodes) nothing is
            // sorted. Its `t ≤ t_max` holds (the mask requires entry ≤ exit ≤ t_max).
            let mut next =
                visit_node::<AVX2>(&slab, &self.nodes[node], t_cull, &mut stack, &mut sp);
            // Visit `next`, then pop, testing leaves on the way, until an interior node to
            // visit is found.
            loop {
                let e = match next.take() {
                    Some(e) => e,
                    None => {
                        if sp == 0 {
                            return best;
                        }
                        sp -= 1;
                        let e = stack.get(sp);
                        if e.t > t_cull {
                            continue;
                        }
                        e
                    }
                };
                if e.count == 0 {
                    node = e.first as usize;
                    break;
                }
                // A leaf: every hit is ranked (`rank`), a packet of triangles at a time or one
                // other primitive at a time.
                if e.count & PACKET_LEAF != 0 {
                    let packets = self.packet_leaf(e.first, e.count);
                    #[cfg(target_arch = "x86_64")]
                    if AVX2 && let Ok(pair) = <&[TriPacket; 2]>::try_from(packets) {
                        // SAFETY: `AVX2 = true` only runs after AVX2 (so AVX) was detected
                        // (see `node_test`).
                        let hits = unsafe { TriPacket::intersect_pair_avx(pair, ray, t_cull) };
                        let mut mask = hits.mask;
                        while mask != 0 {
                            let i = mask.trailing_zeros() as usize;
                            mask &= mask - 1;
                            rank(
                                &mut best,
                                &mut best_key,
                                &mut t_cull,
                                Intersection {
                                    t: hits.t[i],
                                    prim: PrimRef(pair[i / PACKET].prim[i % PACKET]),
                                    u: hits.b1[i],
                                    v: hits.b2[i],
                                },
                            );
                        }
                        continue;
                    }
                    for p in packets {
                        let hits = p.intersect(ray, t_cull);
                        let mut mask = hits.mask;
                        while mask != 0 {
                            let i = mask.trailing_zeros() as usize;
                            mask &= mask - 1;
                            rank(
                                &mut best,
                                &mut best_key,
                                &mut t_cull,
                                Intersection {
                                    t: hits.t[i],
                                    prim: PrimRef(p.prim[i]),
                                    u: hits.b1[i],
                                    v: hits.b2[i],
                                },
                            );
                        }
                    }
                } else {
                    let first = e.first as usize;
                    for &prim in &self.prims[first..first + e.count as usize] {
                        if let Some(h) = geometry.intersect(prim, ray, t_cull) {
                            rank(&mut best, &mut best_key, &mut t_cull, h);
                        }
                    }
                }
            }
        }
    }

    /// Closest hit over a tree of [`Self::build_from`] whose leaves `test` answers: `test(prim,
    /// bound)` returns the hit on `prim` before `bound`, if any. The nodes are tested with
    /// `node_ray`, the leaves with whatever ray `test` holds, so a tree built in an object's own
    /// space (a shared mesh's tree in [`super::instance`]) is walked with the ray taken into
    /// that space while its leaves test world-space triangles. Hits are ranked as
    /// [`Self::intersect`] ranks them (nearest, then lowest primitive), so the walk's order does
    /// not change the answer. A plain walk without the packet leaves and the AVX2 copy: it runs
    /// per instance and per mesh of a two-level hierarchy, and `test` does the expensive part.
    #[inline]
    pub fn closest_with(
        &self,
        node_ray: &Ray,
        t_max: f32,
        mut test: impl FnMut(PrimRef, f32) -> Option<Intersection>,
    ) -> Option<Intersection> {
        if self.nodes.is_empty() || !node_ray.is_traceable() {
            return None;
        }
        let slab = SlabRay::new(node_ray, &RayInv::new(node_ray.d));
        let mut best: Option<Intersection> = None;
        let mut best_key = u64::MAX;
        let mut t_cull = t_max;
        let mut stack = TraversalStack::<(u32, f32)>::new();
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            let (t_enter, mut mask) = slab.test(n, t_cull);
            while mask != 0 {
                let lane = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if n.count[lane] == 0 {
                    stack.set(sp, (n.first[lane], t_enter[lane]));
                    sp += 1;
                    continue;
                }
                let first = n.first[lane] as usize;
                for &prim in &self.prims[first..first + n.count[lane] as usize] {
                    if let Some(h) = test(prim, t_cull) {
                        rank(&mut best, &mut best_key, &mut t_cull, h);
                    }
                }
            }
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                let (next, t) = stack.get(sp);
                if t <= t_cull {
                    node = next as usize;
                    break;
                }
            }
        }
    }

    /// [`Self::closest_with`] for shadow rays: true as soon as `test(prim, t_max)` is.
    #[inline]
    pub fn any_with(
        &self,
        node_ray: &Ray,
        t_max: f32,
        mut test: impl FnMut(PrimRef, f32) -> bool,
    ) -> bool {
        if self.nodes.is_empty() || !node_ray.is_traceable() {
            return false;
        }
        let slab = SlabRay::new(node_ray, &RayInv::new(node_ray.d));
        let mut stack = TraversalStack::<u32>::new();
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            let (_, mut mask) = slab.test(n, t_max);
            while mask != 0 {
                let lane = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if n.count[lane] == 0 {
                    stack.set(sp, n.first[lane]);
                    sp += 1;
                    continue;
                }
                let first = n.first[lane] as usize;
                for &prim in &self.prims[first..first + n.count[lane] as usize] {
                    if test(prim, t_max) {
                        return true;
                    }
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            node = stack.get(sp) as usize;
        }
    }

    /// Any hit: leaves are tested as soon as their node is (cheaper than descending further), and
    /// the first blocker ends the walk.
    #[inline(always)]
    fn occluded_impl<const AVX2: bool>(&self, geometry: &GeometryStore, ray: &Ray) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let slab = SlabRay::new(ray, &RayInv::new(ray.d));
        let t_max = ray.t_max;
        let mut stack = TraversalStack::<u32>::new();
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let (_, mut mask) = node_test::<AVX2>(&slab, &self.nodes[node], t_max);
            let n = &self.nodes[node];
            while mask != 0 {
                let lane = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if n.count[lane] == 0 {
                    stack.set(sp, n.first[lane]);
                    sp += 1;
                } else if n.count[lane] & PACKET_LEAF != 0 {
                    let packets = self.packet_leaf(n.first[lane], n.count[lane]);
                    #[cfg(target_arch = "x86_64")]
                    if AVX2 && let Ok(pair) = <&[TriPacket; 2]>::try_from(packets) {
                        // SAFETY: as in `intersect_impl`.
                        if unsafe { TriPacket::intersect_pair_avx(pair, ray, t_max) }.mask != 0 {
                            return true;
                        }
                        continue;
                    }
                    for p in packets {
                        if p.intersect(ray, t_max).mask != 0 {
                            return true;
                        }
                    }
                } else {
                    let first = n.first[lane] as usize;
                    for &prim in &self.prims[first..first + n.count[lane] as usize] {
                        if geometry.intersect(prim, ray, t_max).is_some() {
                            return true;
                        }
                    }
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            node = stack.get(sp) as usize;
        }
    }
}

/// Ranks a closest-hit candidate (see `Bvh::intersect_impl`): it becomes `best` if nearer, or as
/// near and of a lower primitive, and the culling bound moves to `TIE_ULPS` above it. The bound
/// shrinks between a leaf's tests, and a hit that a shrunk bound rejects would have lost the
/// ranking anyway (its key is larger), so the order of the tests does not matter.
#[inline(always)]
fn rank(best: &mut Option<Intersection>, best_key: &mut u64, t_cull: &mut f32, h: Intersection) {
    // `h.t` is positive and finite (the tests require 0 < t < bound).
    let key = (u64::from(h.t.to_bits()) << 32) | u64::from(h.prim.0);
    if key < *best_key {
        *best_key = key;
        // A larger float, or past ∞ a NaN that `min` turns into ∞.
        *t_cull = f32::from_bits(h.t.to_bits() + TIE_ULPS).min(f32::INFINITY);
        *best = Some(h);
    }
}

/// Appends the primitives of the binary leaf `leaf` to `prims`, each once (two pieces of a split
/// triangle may share a leaf), and returns their range.
fn leaf_prims(leaf: &BuildNode, build: &[BuildPrim], prims: &mut Vec<PrimRef>) -> (u32, u32) {
    let BuildNode::Leaf { first, count, .. } = leaf else {
        unreachable!("leaf_prims is called on leaves")
    };
    let start = prims.len();
    for b in &build[*first..*first + *count] {
        if !prims[start..].contains(&b.prim) {
            prims.push(b.prim);
        }
    }
    (start as u32, (prims.len() - start) as u32)
}

/// Writes the wide node `index` for the binary interior node `node`: its children are gathered
/// by repeatedly opening the interior child of largest surface area (the SAH's proxy for the
/// probability of being visited) until there are `WIDTH`, then each interior child becomes a node.
/// Leaves' primitives are written to `prims` in the order the leaves are reached.
fn collapse(
    node: &BuildNode,
    index: usize,
    build: &[BuildPrim],
    nodes: &mut Vec<BvhNode>,
    prims: &mut Vec<PrimRef>,
) {
    let mut children: Vec<&BuildNode> = match node {
        BuildNode::Interior { children, .. } => vec![&children[0], &children[1]],
        BuildNode::Leaf { .. } => vec![node],
    };
    while children.len() < WIDTH {
        let open = children
            .iter()
            .enumerate()
            .filter(|(_, c)| matches!(c, BuildNode::Interior { .. }))
            .max_by(|a, b| {
                a.1.bounds()
                    .surface_area()
                    .total_cmp(&b.1.bounds().surface_area())
            })
            .map(|(i, _)| i);
        let Some(i) = open else { break };
        if let BuildNode::Interior {
            children: grand, ..
        } = children.swap_remove(i)
        {
            children.push(&grand[0]);
            children.push(&grand[1]);
        }
    }
    for (lane, child) in children.into_iter().enumerate() {
        match child {
            BuildNode::Leaf { bounds, .. } => {
                let (first, count) = leaf_prims(child, build, prims);
                nodes[index].set_lane(lane, bounds, first, count);
            }
            BuildNode::Interior { bounds, .. } => {
                let child_index = nodes.len();
                nodes.push(BvhNode::EMPTY);
                nodes[index].set_lane(lane, bounds, child_index as u32, 0);
                collapse(child, child_index, build, nodes, prims);
            }
        }
    }
}

/// The bin of centroid coordinate `c` among `BINS` equal bins over `[lo, lo + ext]`.
#[inline(always)]
fn bin_of(c: f32, lo: f32, ext: f32) -> usize {
    let b = ((c - lo) * (BINS as f32 / ext)) as usize;
    b.min(BINS - 1)
}

/// The cheapest binned split of `prims` along `axis` (centroids spanning `[lo, lo + ext]`, `ext >
/// 0`): its unnormalised SAH cost `n_L·A_L + n_R·A_R` and the last bin of the left side. Infinite
/// cost if every centroid falls in one bin.
fn best_bin_split(prims: &[BuildPrim], axis: usize, lo: f32, ext: f32) -> (f32, usize) {
    let mut bin_bounds = [Bounds3::EMPTY; BINS];
    let mut bin_count = [0usize; BINS];
    for p in prims {
        let b = bin_of(p.centroid[axis], lo, ext);
        bin_count[b] += 1;
        bin_bounds[b] = bin_bounds[b].union(&p.bounds);
    }
    let mut right_area = [0.0f32; BINS];
    let mut right_count = [0usize; BINS];
    let mut acc = Bounds3::EMPTY;
    let mut cnt = 0;
    for i in (1..BINS).rev() {
        acc = acc.union(&bin_bounds[i]);
        cnt += bin_count[i];
        right_area[i] = acc.surface_area();
        right_count[i] = cnt;
    }
    let mut best_cost = f32::INFINITY;
    let mut best_split = 0;
    let mut acc = Bounds3::EMPTY;
    let mut cnt = 0;
    for i in 0..BINS - 1 {
        acc = acc.union(&bin_bounds[i]);
        cnt += bin_count[i];
        if cnt == 0 || right_count[i + 1] == 0 {
            continue;
        }
        let cost = cnt as f32 * acc.surface_area() + right_count[i + 1] as f32 * right_area[i + 1];
        if cost < best_cost {
            best_cost = cost;
            best_split = i;
        }
    }
    (best_cost, best_split)
}

fn build_recursive(prims: &mut [BuildPrim], first: usize, depth: usize) -> BuildNode {
    let bounds = prims.iter().fold(Bounds3::EMPTY, |b, p| b.union(&p.bounds));
    let n = prims.len();
    let leaf = || BuildNode::Leaf {
        bounds,
        first,
        count: n,
    };
    // Two triangles share a leaf (half the nodes on big meshes; on small ones the same work as
    // splitting them), and up to `MAX_TRI_LEAF` where the SAH prefers it (they are tested a
    // packet at a time, see below). Other primitives are split down to one per leaf: a quad, box or sphere test
    // (~100 instructions with its dispatch) costs about two 4-wide node tests, and the walls of a
    // room have thin, barely overlapping boxes that the node test culls, where a shared leaf would
    // test every wall its combined box lets through (callgrind, built-in Cornell box: primitive
    // tests per closest-hit ray 3.17 → 1.09, −14 % of all instructions).
    if n <= 1
        || (n == 2
            && prims
                .iter()
                .all(|p| p.prim.kind() == PrimitiveKind::Triangle))
    {
        return leaf();
    }
    let centroid_bounds = prims
        .iter()
        .fold(Bounds3::EMPTY, |b, p| b.union_point(p.centroid));
    let axis = centroid_bounds.max_extent();
    let extent = centroid_bounds.max[axis] - centroid_bounds.min[axis];

    let mid = if depth > MEDIAN_SPLIT_DEPTH {
        // Adversarial inputs can make SAH splits very unbalanced; below this depth fall back to
        // median splits, which bound the remaining depth by log2(n) and so fit the traversal stack.
        if n <= MAX_LEAF {
            return leaf();
        }
        prims.select_nth_unstable_by(n / 2, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
        n / 2
    } else if !(extent > 0.0) {
        // All centroids coincide: no spatial split exists. Split by count if the leaf would be
        // too large, so the depth stays bounded.
        if n <= MAX_LEAF {
            return leaf();
        }
        n / 2
    } else {
        // Binned SAH on all three axes (Wald 2007 bins only the widest; trying each axis finds
        // planes the widest misses, e.g. across a thin, long part): bucket centroids, sweep each
        // axis for its cheapest split plane, keep the cheapest of all.
        let mut best = (f32::INFINITY, axis, 0usize);
        for ax in 0..3 {
            let ext = centroid_bounds.max[ax] - centroid_bounds.min[ax];
            if !(ext > 0.0) {
                continue;
            }
            let (cost, split) = best_bin_split(prims, ax, centroid_bounds.min[ax], ext);
            if cost < best.0 {
                best = (cost, ax, split);
            }
        }
        let (best_cost, axis, best_split) = best;
        let total_area = bounds.surface_area().max(f32::MIN_POSITIVE);
        let split_cost = TRAVERSAL_COST + best_cost / total_area;
        if n <= MAX_LEAF && split_cost >= n as f32 {
            return leaf();
        }
        // Triangles are tested a packet at a time: up to `PACKET` of them in a leaf cost one
        // packet test, up to `2 · PACKET` one 8-lane pair test, so a leaf of a few triangles is
        // kept where splitting it costs more.
        if n <= MAX_TRI_LEAF
            && split_cost >= PACKET_COST * if n <= PACKET { 1.0 } else { PAIR_COST }
            && prims
                .iter()
                .all(|p| p.prim.kind() == PrimitiveKind::Triangle)
        {
            return leaf();
        }
        // Partition in place around the chosen bin boundary.
        let (lo, ext) = (
            centroid_bounds.min[axis],
            centroid_bounds.max[axis] - centroid_bounds.min[axis],
        );
        let mut left = 0;
        for i in 0..n {
            if bin_of(prims[i].centroid[axis], lo, ext) <= best_split {
                prims.swap(i, left);
                left += 1;
            }
        }
        if left == 0 || left == n { n / 2 } else { left }
    };

    let (lo, hi) = prims.split_at_mut(mid);
    let (a, b) = if n > PARALLEL_THRESHOLD {
        rayon::join(
            || build_recursive(lo, first, depth + 1),
            || build_recursive(hi, first + mid, depth + 1),
        )
    } else {
        (
            build_recursive(lo, first, depth + 1),
            build_recursive(hi, first + mid, depth + 1),
        )
    };
    BuildNode::Interior {
        bounds: a.bounds().union(&b.bounds()),
        children: Box::new([a, b]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::primitive::MeshAttributes;
    use crate::geometry::triangle::{TriangleHit, TriangleVerts};

    /// A soup of random small triangles.
    fn soup(n: usize, seed: u64) -> GeometryStore {
        let mut rng = crate::sampling::rng::Pcg32::new(seed, 7);
        let mut g = GeometryStore::default();
        let mut mesh = MeshAttributes::default();
        for i in 0..n {
            let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0 - 5.0;
            let r = |rng: &mut crate::sampling::rng::Pcg32| {
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5
            };
            g.triangles.push(TriangleVerts {
                p0: c + r(&mut rng),
                p1: c + r(&mut rng),
                p2: c + r(&mut rng),
            });
            g.tri_mesh.push((0, i as u32));
            g.tri_light.push(crate::geometry::primitive::NO_LIGHT);
            mesh.indices.push([0, 0, 0]);
        }
        g.meshes.push(mesh);
        g
    }

    #[test]
    fn bvh_agrees_with_brute_force() {
        let g = soup(3000, 1);
        let bvh = Bvh::build(&g);
        let brute = crate::accel::Accel::build(crate::accel::AccelKind::None, &g);
        let mut rng = crate::sampling::rng::Pcg32::new(99, 3);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 20.0 - 10.0;
            let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            let ray = Ray::new(o, d);
            let a = bvh.intersect(&g, &ray);
            let b = brute.intersect(&g, &ray);
            match (a, b) {
                (Some(a), Some(b)) => {
                    hits += 1;
                    assert_eq!(a.t, b.t);
                    assert_eq!(a.prim, b.prim);
                }
                (None, None) => {}
                _ => panic!("BVH and brute force disagree"),
            }
            assert_eq!(bvh.occluded(&g, &ray), brute.occluded(&g, &ray));
        }
        assert!(hits > 200, "test rays should hit something: {hits}");
    }

    /// The AVX2 copy of the traversal and the portable one find the same hits, bit for bit (t,
    /// primitive and barycentrics), closest and any; both agree with brute force. Rays start inside
    /// the soup (boxes overlap, many entry distances are 0) and outside it. Fails if the AVX2 code
    /// rounds differently (e.g. an FMA) or culls a child the portable code keeps. On a CPU without
    /// AVX2 only the portable half runs (said on stderr).
    #[test]
    fn simd_and_portable_traversal_agree() {
        let g = soup(5000, 11);
        let bvh = Bvh::build(&g);
        let brute = crate::accel::Accel::build(crate::accel::AccelKind::None, &g);
        let has_avx2 = cfg!(target_arch = "x86_64") && crate::math::detect_avx2();
        if !has_avx2 {
            eprintln!("no AVX2 on this CPU: only the portable traversal is checked");
        }
        let key = |h: Option<Intersection>| {
            h.map(|h| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()))
        };
        let mut rng = crate::sampling::rng::Pcg32::new(7, 5);
        let (mut hits, mut blocked) = (0, 0);
        for i in 0..3000 {
            let spread = if i % 2 == 0 { 8.0 } else { 30.0 };
            let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * spread;
            let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            let mut ray = Ray::new(o, d);
            if i % 3 == 0 {
                ray.t_max = 2.0 * rng.next_f32();
            }
            let portable = key(bvh.intersect_portable(&g, &ray));
            assert_eq!(portable, key(brute.intersect(&g, &ray)), "ray {i}");
            let occluded = bvh.occluded_portable(&g, &ray);
            assert_eq!(occluded, brute.occluded(&g, &ray), "ray {i}");
            #[cfg(target_arch = "x86_64")]
            if has_avx2 {
                // SAFETY: AVX2 was detected above.
                unsafe {
                    assert_eq!(portable, key(bvh.intersect_avx2(&g, &ray)), "ray {i}");
                    assert_eq!(occluded, bvh.occluded_avx2(&g, &ray), "ray {i}");
                }
            }
            hits += portable.is_some() as usize;
            blocked += occluded as usize;
        }
        assert!(
            hits > 500 && blocked > 300,
            "{hits} hits, {blocked} blocked"
        );
        // The tree really is wide: some node uses all its lanes.
        assert!(
            bvh.nodes
                .iter()
                .any(|n| n.first.iter().all(|&f| f != EMPTY_LANE)),
            "no full {WIDTH}-wide node"
        );
    }

    /// The six walls of a room and a light under its ceiling: every quad gets its own leaf, so
    /// the wide box test culls the walls a ray does not reach (a shared leaf's box would span
    /// the room and every ray would test both walls). Hits agree with brute force.
    #[test]
    fn quads_of_a_room_get_a_leaf_each() {
        use crate::geometry::primitive::AnalyticPrim;
        use crate::geometry::quad::Quad;
        let mut g = GeometryStore::default();
        let (x, y, z) = (Vec3::X * 2.0, Vec3::Y * 2.0, Vec3::Z * 2.0);
        let lo = Vec3::splat(-1.0);
        let hi = Vec3::splat(1.0);
        for (corner, e1, e2) in [
            (lo, z, x),
            (lo, x, y),
            (lo, y, z),
            (hi, -x, -z),
            (hi, -y, -x),
            (hi, -z, -y),
            (Vec3::new(-0.2, 0.98, -0.2), Vec3::X * 0.4, Vec3::Z * 0.4),
        ] {
            g.quads.push(AnalyticPrim {
                shape: Quad::new(corner, e1, e2),
                material: 0,
                light: crate::geometry::primitive::NO_LIGHT,
            });
        }
        let bvh = Bvh::build(&g);
        let s = bvh.stats();
        assert_eq!((s.leaves, s.max_leaf_size), (7, 1), "{s:?}");
        let brute = crate::accel::Accel::build(crate::accel::AccelKind::None, &g);
        let mut rng = crate::sampling::rng::Pcg32::new(5, 1);
        for _ in 0..2000 {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 1.8 - 0.9;
            let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            let ray = Ray::new(o, d);
            let (a, b) = (bvh.intersect(&g, &ray), brute.intersect(&g, &ray));
            assert_eq!(a.map(|h| (h.t, h.prim)), b.map(|h| (h.t, h.prim)));
            assert!(a.is_some(), "a ray inside a closed room hits a wall");
        }
    }

    /// Long slivers crossing the scene in all directions among small triangles: the pre-split
    /// tree (many references per sliver) finds exactly the brute-force hits, closest (t,
    /// primitive, barycentrics) and any, and its SAH cost is lower than the unsplit tree's.
    /// Fails if a piece's box misses part of its triangle, or if a leaf loses a primitive.
    #[test]
    fn split_slivers_agree_with_brute_force() {
        let mut g = soup(2000, 21);
        let mut rng = crate::sampling::rng::Pcg32::new(21, 4);
        let mut point =
            |s: f32| (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * s;
        for i in 0..300 {
            let (a, b) = (point(10.0), point(10.0));
            let w = point(0.05);
            g.triangles.push(TriangleVerts {
                p0: a,
                p1: b,
                p2: b + w,
            });
            g.tri_mesh.push((0, 2000 + i));
            g.tri_light.push(crate::geometry::primitive::NO_LIGHT);
            g.meshes[0].indices.push([0, 0, 0]);
        }
        let plain = Bvh::build_split(&g, 0.0);
        let split = Bvh::build_split(&g, 0.5);
        let (ps, ss) = (plain.stats(), split.stats());
        assert_eq!(ps.references, 2300);
        assert!(ss.references > 2300 + 500, "{ss:?}");
        assert!(
            ss.sah_cost < 0.8 * ps.sah_cost,
            "split {ss:?} vs plain {ps:?}"
        );
        let brute = crate::accel::Accel::build(crate::accel::AccelKind::None, &g);
        let key = |h: Option<Intersection>| {
            h.map(|h| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()))
        };
        let mut rng = crate::sampling::rng::Pcg32::new(8, 2);
        let (mut hits, mut sliver_hits) = (0, 0);
        for i in 0..6000 {
            let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 14.0;
            let mut d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            if i % 2 == 0 {
                // Aim at a uniform point of a random sliver: its ends and edges get hit too.
                let t = g.triangles[2000 + (rng.next_f32() * 300.0) as usize % 300];
                let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                d = t.p0 + (t.p1 - t.p0) * u + (t.p2 - t.p0) * v - o;
            }
            let mut ray = Ray::new(o, d);
            if i % 3 == 0 {
                ray.t_max = 3.0 * rng.next_f32();
            }
            let want = key(brute.intersect(&g, &ray));
            assert_eq!(key(split.intersect(&g, &ray)), want, "ray {i}");
            assert_eq!(key(split.intersect_portable(&g, &ray)), want, "ray {i}");
            assert_eq!(
                split.occluded(&g, &ray),
                brute.occluded(&g, &ray),
                "ray {i}"
            );
            hits += want.is_some() as usize;
            sliver_hits += want.is_some_and(|w| w.1.index() >= 2000) as usize;
        }
        assert!(
            hits > 2000 && sliver_hits > 1000,
            "{hits} hits, {sliver_hits} on slivers"
        );
        // Every primitive is in some leaf.
        let mut seen = vec![false; 2300];
        for p in &split.prims {
            seen[p.index()] = true;
        }
        assert!(seen.iter().all(|&s| s));
    }

    /// Coincident triangles (three identical copies of two sheets of quads, one axis-aligned and
    /// one tilted, their copies at scattered positions of the triangle list, among a random soup):
    /// every tree shape and build order reports, at equal `t`, the lowest primitive, as brute
    /// force does, in both traversal copies, and so does the grid. Fails if the first leaf
    /// visited wins a tie: the tree then decides which copy is reported.
    #[test]
    fn coincident_triangles_report_the_lowest_primitive_whatever_the_tree() {
        let mut g = soup(600, 31);
        let mut rng = crate::sampling::rng::Pcg32::new(31, 9);
        // Two sheets: z = 0.3 (axis-aligned, its triangles lie on their boxes' faces) and a tilted
        // one, 6×6 quads each.
        let mut sheet = Vec::new();
        for (origin, du, dv) in [
            (
                Vec3::new(-4.0, -4.0, 0.3),
                Vec3::X * (8.0 / 6.0),
                Vec3::Y * (8.0 / 6.0),
            ),
            (
                Vec3::new(-4.0, -4.0, -3.0),
                Vec3::new(8.0 / 6.0, 0.0, 0.4),
                Vec3::new(0.0, 8.0 / 6.0, 0.7),
            ),
        ] {
            for i in 0..6 {
                for j in 0..6 {
                    let p = origin + du * i as f32 + dv * j as f32;
                    sheet.push(TriangleVerts {
                        p0: p,
                        p1: p + du,
                        p2: p + du + dv,
                    });
                    sheet.push(TriangleVerts {
                        p0: p,
                        p1: p + du + dv,
                        p2: p + dv,
                    });
                }
            }
        }
        // Three copies of every sheet triangle, inserted at random positions: `group[id]` is the
        // sheet triangle a primitive copies (or none).
        let mut tris: Vec<(TriangleVerts, Option<usize>)> =
            g.triangles.iter().map(|&t| (t, None)).collect();
        for _ in 0..3 {
            for (s, &t) in sheet.iter().enumerate() {
                let at = (rng.next_f32() * tris.len() as f32) as usize % (tris.len() + 1);
                tris.insert(at, (t, Some(s)));
            }
        }
        let mut g2 = GeometryStore::default();
        let mut mesh = MeshAttributes::default();
        for (i, (t, _)) in tris.iter().enumerate() {
            g2.triangles.push(*t);
            g2.tri_mesh.push((0, i as u32));
            g2.tri_light.push(crate::geometry::primitive::NO_LIGHT);
            mesh.indices.push([0, 0, 0]);
        }
        g2.meshes.push(mesh);
        g = g2;
        let mut lowest = vec![usize::MAX; sheet.len()];
        for (i, (_, s)) in tris.iter().enumerate() {
            if let Some(s) = s {
                lowest[*s] = lowest[*s].min(i);
            }
        }
        let all = g.all_prims();
        let bounds = |p: PrimRef| g.bounds(p);
        let mut reversed = all.clone();
        reversed.reverse();
        let mut shuffled = all.clone();
        for i in (1..shuffled.len()).rev() {
            let j = (rng.next_f32() * (i + 1) as f32) as usize % (i + 1);
            shuffled.swap(i, j);
        }
        let trees = [
            Bvh::build_split(&g, 0.0),
            Bvh::build_split(&g, 1.0),
            Bvh::build_from(all, bounds),
            Bvh::build_from(reversed, bounds),
            Bvh::build_from(shuffled, bounds),
        ];
        let brute = crate::accel::Accel::build(crate::accel::AccelKind::None, &g);
        // The grid needs no rule of its own: a cell lists its primitives in ascending order (a
        // counting sort of `all_prims`), so the first equal-`t` hit in a cell is the lowest, and
        // identical copies share their cells.
        let grid = crate::accel::Accel::build(crate::accel::AccelKind::Grid, &g);
        let key = |h: Option<Intersection>| {
            h.map(|h| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()))
        };
        let has_avx2 = cfg!(target_arch = "x86_64") && crate::math::detect_avx2();
        let mut sheet_hits = 0;
        for i in 0..4000 {
            let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 12.0;
            // Half the rays aim at a random point of the sheets' area.
            let d = if i % 2 == 0 {
                Vec3::new(rng.next_f32() * 8.0 - 4.0, rng.next_f32() * 8.0 - 4.0, 0.3) - o
            } else {
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0
            };
            let ray = Ray::new(o, d);
            let want = brute.intersect(&g, &ray);
            if let Some(h) = want
                && let Some(s) = tris[h.prim.index()].1
            {
                assert_eq!(h.prim.index(), lowest[s], "brute force keeps the lowest");
                sheet_hits += 1;
            }
            assert_eq!(key(grid.intersect(&g, &ray)), key(want), "grid, ray {i}");
            for (n, bvh) in trees.iter().enumerate() {
                assert_eq!(
                    key(bvh.intersect_portable(&g, &ray)),
                    key(want),
                    "tree {n}, ray {i}"
                );
                #[cfg(target_arch = "x86_64")]
                if has_avx2 {
                    // SAFETY: AVX2 was detected above.
                    let h = unsafe { bvh.intersect_avx2(&g, &ray) };
                    assert_eq!(key(h), key(want), "tree {n}, ray {i}, AVX2");
                }
            }
        }
        assert!(sheet_hits > 1000, "{sheet_hits} rays hit a sheet");
    }

    /// A hostile set of triangles for the packet test: random ones, ones sharing edges and
    /// vertices with them, duplicates, degenerate ones (a point, collinear vertices), huge and
    /// tiny ones, and ones with NaN or infinite coordinates.
    fn hostile_triangles(rng: &mut crate::sampling::rng::Pcg32) -> Vec<TriangleVerts> {
        let mut p = |s: f32| (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * s;
        let mut tris = Vec::new();
        for _ in 0..40 {
            let (a, b, c) = (p(4.0), p(4.0), p(4.0));
            tris.push(TriangleVerts {
                p0: a,
                p1: b,
                p2: c,
            });
            // Sharing the edge a–b (opposite winding) and the vertex c.
            tris.push(TriangleVerts {
                p0: b,
                p1: a,
                p2: p(4.0),
            });
            tris.push(TriangleVerts {
                p0: c,
                p1: p(4.0),
                p2: p(4.0),
            });
        }
        let a = p(2.0);
        tris.push(tris[0]);
        tris.push(TriangleVerts {
            p0: a,
            p1: a,
            p2: a,
        });
        tris.push(TriangleVerts {
            p0: a,
            p1: a + Vec3::X,
            p2: a + Vec3::X * 2.0,
        });
        tris.push(TriangleVerts {
            p0: p(1e6),
            p1: p(1e6),
            p2: p(1e6),
        });
        tris.push(TriangleVerts {
            p0: a,
            p1: a + p(1e-5),
            p2: a + p(1e-5),
        });
        tris.push(TriangleVerts {
            p0: Vec3::new(f32::NAN, 0.0, 0.0),
            p1: Vec3::X,
            p2: Vec3::Y,
        });
        tris.push(TriangleVerts {
            p0: Vec3::ZERO,
            p1: Vec3::new(f32::INFINITY, 0.0, 0.0),
            p2: Vec3::Y,
        });
        tris.push(TriangleVerts {
            p0: Vec3::ZERO,
            p1: Vec3::X,
            p2: Vec3::new(0.0, f32::NEG_INFINITY, 1.0),
        });
        tris
    }

    /// One ray against packets of hostile triangles: every lane reports exactly the scalar
    /// Möller–Trumbore's answer (hit or not, and `t` and barycentrics bit for bit). Rays are
    /// random, aimed at vertices, edge points and the centre, lying in a triangle's plane
    /// (parallel), with NaN, infinite or zero direction components, NaN origins, and with `t_max`
    /// at the hit's exact `t` (which must reject it) or one ulp above. The SSE, lane-wise and
    /// (with AVX) 8-lane two-packet forms alike. Fails if a lane rounds differently (an
    /// operation reordered or fused) or any acceptance condition differs.
    #[test]
    fn packet_test_matches_the_scalar_test() {
        let mut rng = crate::sampling::rng::Pcg32::new(17, 23);
        let tris = hostile_triangles(&mut rng);
        let prims: Vec<PrimRef> = (0..tris.len() as u32).map(PrimRef).collect();
        let packets: Vec<TriPacket> = tris
            .chunks(PACKET)
            .zip(prims.chunks(PACKET))
            .map(|(ts, ps)| {
                let mut packet = TriPacket::EMPTY;
                for (i, (t, &p)) in ts.iter().zip(ps).enumerate() {
                    packet.set_lane(i, &t.edges(), p);
                }
                packet
            })
            .collect();
        let has_avx = cfg!(target_arch = "x86_64") && crate::math::detect_avx2();
        if !has_avx {
            eprintln!("no AVX2 on this CPU: the 8-lane pair test is not checked");
        }
        let (mut hits, mut edge_cases, mut pair_lanes) = (0, 0, 0);
        let mut check = |ray: &Ray, t_max: f32| {
            // The 8-lane test of two consecutive packets (every pair, so each packet is tested
            // as a first and as a second half): lane `i` is packet `k + i / 4`'s lane `i % 4`.
            #[cfg(target_arch = "x86_64")]
            if has_avx {
                for k in 0..packets.len() - 1 {
                    let pair = <&[TriPacket; 2]>::try_from(&packets[k..k + 2]).unwrap();
                    // SAFETY: AVX2 (so AVX) was detected above.
                    let got = unsafe { TriPacket::intersect_pair_avx(pair, ray, t_max) };
                    for lane in 0..2 * PACKET {
                        let index = k * PACKET + lane;
                        let Some(tri) = tris.get(index) else {
                            assert_eq!(got.mask >> lane & 1, 0, "empty lane {lane} hit");
                            continue;
                        };
                        let want = tri.edges().intersect(ray, t_max);
                        let lane_hit = (got.mask >> lane & 1 == 1).then(|| TriangleHit {
                            t: got.t[lane],
                            b1: got.b1[lane],
                            b2: got.b2[lane],
                        });
                        let bits = |h: Option<TriangleHit>| {
                            h.map(|h| (h.t.to_bits(), h.b1.to_bits(), h.b2.to_bits()))
                        };
                        assert_eq!(
                            bits(lane_hit),
                            bits(want),
                            "8-lane: triangle {index} {tri:?}, ray {ray:?}, t_max {t_max}",
                        );
                        pair_lanes += want.is_some() as usize;
                    }
                }
            }
            for (k, packet) in packets.iter().enumerate() {
                // The SSE form (x86-64) and the lane-wise form (elsewhere) alike.
                for got in [
                    packet.intersect(ray, t_max),
                    packet.intersect_lanes(ray, t_max),
                ] {
                    for lane in 0..PACKET {
                        let Some(tri) = tris.get(k * PACKET + lane) else {
                            assert_eq!(got.mask >> lane & 1, 0, "empty lane {lane} hit");
                            continue;
                        };
                        let want = tri.edges().intersect(ray, t_max);
                        let lane_hit = (got.mask >> lane & 1 == 1).then(|| TriangleHit {
                            t: got.t[lane],
                            b1: got.b1[lane],
                            b2: got.b2[lane],
                        });
                        let bits = |h: Option<TriangleHit>| {
                            h.map(|h| (h.t.to_bits(), h.b1.to_bits(), h.b2.to_bits()))
                        };
                        assert_eq!(
                            bits(lane_hit),
                            bits(want),
                            "triangle {} {tri:?}, ray {ray:?}, t_max {t_max}",
                            k * PACKET + lane
                        );
                        hits += want.is_some() as usize;
                    }
                }
            }
        };
        let specials = [
            0.0,
            -0.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e-30,
            1e30,
        ];
        for i in 0..6000 {
            let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 8.0;
            let tri = tris[(rng.next_f32() * tris.len() as f32) as usize % tris.len()];
            // A target on the triangle: a vertex, an edge point, its centre, or a random point.
            let (u, v) = match i % 5 {
                0 => [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)][i / 5 % 3],
                1 => {
                    let s = rng.next_f32();
                    [(s, 0.0), (0.0, s), (s, 1.0 - s)][i / 5 % 3]
                }
                2 => (1.0 / 3.0, 1.0 / 3.0),
                _ => (rng.next_f32(), rng.next_f32()),
            };
            let target = tri.p0 + (tri.p1 - tri.p0) * u + (tri.p2 - tri.p0) * v;
            let mut d = target - o;
            match i % 7 {
                // In the triangle's plane: along an edge from a vertex.
                0 => {
                    d = tri.p1 - tri.p0;
                    let ray = Ray::new(tri.p0 - d * 0.5, d);
                    check(&ray, f32::INFINITY);
                }
                1 => d[i % 3] = specials[i / 7 % specials.len()],
                2 => d = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 2.0,
                _ => {}
            }
            let mut ray = Ray::new(o, d);
            if i % 11 == 0 {
                ray.o[i % 3] = specials[i / 11 % specials.len()];
            }
            check(&ray, f32::INFINITY);
            check(&ray, 1.0);
            // `t_max` at a hit's exact `t` (rejected: t < t_max is strict), and one ulp above.
            if let Some(h) = tri.edges().intersect(&ray, f32::INFINITY) {
                edge_cases += 1;
                check(&ray, h.t);
                check(&ray, f32::from_bits(h.t.to_bits() + 1));
            }
        }
        assert!(
            hits > 5000 && edge_cases > 1500,
            "{hits} hits, {edge_cases} aimed hits"
        );
        assert!(!has_avx || pair_lanes > 5000, "{pair_lanes} 8-lane hits");
    }

    /// A closed, finely tessellated mesh (a bumpy sphere: every edge shared by two triangles,
    /// every vertex by six) with a few quads among its triangles: the packet leaves and the mixed
    /// ones find exactly the brute-force hits (t, primitive, barycentrics) and blockers, in both
    /// traversal copies, for rays aimed at vertices, edge midpoints and random directions. The
    /// tree really has packet leaves of several triangles, of one packet and of two (which the
    /// AVX2 copies test 8 lanes at once). Fails if a packet lane is dropped or misranked, or a
    /// shadow ray misses a blocker in a packet.
    #[test]
    fn packet_leaves_agree_with_brute_force_on_a_mesh() {
        use crate::geometry::primitive::AnalyticPrim;
        use crate::geometry::quad::Quad;
        let (rings, segs) = (60usize, 90usize);
        let vertex = |i: usize, j: usize| {
            let th = std::f32::consts::PI * i as f32 / rings as f32;
            let ph = 2.0 * std::f32::consts::PI * j as f32 / segs as f32;
            let r = 2.0 + 0.1 * (5.0 * ph).sin() * (4.0 * th).cos();
            Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()) * r
        };
        let mut g = GeometryStore::default();
        let mut mesh = MeshAttributes::default();
        for i in 0..rings {
            for j in 0..segs {
                let (a, b) = (vertex(i, j), vertex(i, (j + 1) % segs));
                let (c, d) = (vertex(i + 1, j), vertex(i + 1, (j + 1) % segs));
                for t in [[a, c, b], [b, c, d]] {
                    g.tri_mesh.push((0, g.triangles.len() as u32));
                    g.triangles.push(TriangleVerts {
                        p0: t[0],
                        p1: t[1],
                        p2: t[2],
                    });
                    g.tri_light.push(crate::geometry::primitive::NO_LIGHT);
                    mesh.indices.push([0, 0, 0]);
                }
            }
        }
        g.meshes.push(mesh);
        for k in 0..6 {
            let c = vertex(10 * k, 15 * k) * 1.02;
            g.quads.push(AnalyticPrim {
                shape: Quad::new(c, Vec3::X * 0.3, Vec3::Y * 0.3),
                material: 0,
                light: crate::geometry::primitive::NO_LIGHT,
            });
        }
        let bvh = Bvh::build(&g);
        let s = bvh.stats();
        assert!(s.max_leaf_size > 2, "no leaf of several triangles: {s:?}");
        // Leaves of two packets (the AVX copies test them 8 lanes at once) and of one.
        assert!(
            s.two_packet_leaves > 100 && s.packets > 2 * s.two_packet_leaves + 100,
            "{s:?}"
        );
        assert!(
            bvh.packets
                .iter()
                .any(|p| p.prim.iter().all(|&q| q != NO_PRIM))
        );
        let brute = crate::accel::Accel::build(crate::accel::AccelKind::None, &g);
        let has_avx2 = cfg!(target_arch = "x86_64") && crate::math::detect_avx2();
        let key = |h: Option<Intersection>| {
            h.map(|h| (h.t.to_bits(), h.prim, h.u.to_bits(), h.v.to_bits()))
        };
        let mut rng = crate::sampling::rng::Pcg32::new(3, 14);
        let (mut hits, mut blocked) = (0, 0);
        for i in 0..6000 {
            let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 10.0;
            let (ri, rj) = (
                (rng.next_f32() * rings as f32) as usize % rings,
                (rng.next_f32() * segs as f32) as usize,
            );
            let d = match i % 3 {
                0 => vertex(ri, rj) - o,
                1 => (vertex(ri, rj) + vertex(ri + 1, rj + 1)) * 0.5 - o,
                _ => Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5,
            };
            let mut ray = Ray::new(o, d);
            if i % 4 == 0 {
                ray.t_max = 1.2 * rng.next_f32();
            }
            let want = key(brute.intersect(&g, &ray));
            let any = brute.occluded(&g, &ray);
            assert_eq!(key(bvh.intersect_portable(&g, &ray)), want, "ray {i}");
            assert_eq!(bvh.occluded_portable(&g, &ray), any, "ray {i}");
            #[cfg(target_arch = "x86_64")]
            if has_avx2 {
                // SAFETY: AVX2 was detected above.
                unsafe {
                    assert_eq!(key(bvh.intersect_avx2(&g, &ray)), want, "ray {i}, AVX2");
                    assert_eq!(bvh.occluded_avx2(&g, &ray), any, "ray {i}, AVX2");
                }
            }
            hits += want.is_some() as usize;
            blocked += any as usize;
        }
        assert!(
            hits > 3000 && blocked > 2000,
            "{hits} hits, {blocked} blocked"
        );
    }

    /// The AVX2 sorting network puts any eight signed integers in descending order: random
    /// keys, keys drawn from a few values (many equal), and negative ones (missed lanes).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn sort_network_sorts_any_eight_keys() {
        use std::arch::x86_64::*;
        if !crate::math::detect_avx2() {
            eprintln!("no AVX2 on this CPU: the sorting network is not checked");
            return;
        }
        let mut rng = crate::sampling::rng::Pcg32::new(5, 9);
        for round in 0..20_000 {
            let mut keys = [0i32; WIDTH];
            for k in keys.iter_mut() {
                let r = rng.next_u32();
                *k = match round % 3 {
                    0 => r as i32,
                    1 => (r % 4) as i32 - 1,
                    _ => (r % 1000) as i32,
                };
            }
            let mut sorted = [0i32; WIDTH];
            // SAFETY: AVX2 was detected above; `keys` and `sorted` are 32 bytes each.
            unsafe {
                let v = sort_desc_avx2(_mm256_loadu_si256(keys.as_ptr().cast()));
                _mm256_storeu_si256(sorted.as_mut_ptr().cast(), v);
            }
            let mut want = keys;
            want.sort_unstable_by(|a, b| b.cmp(a));
            assert_eq!(sorted, want, "keys {keys:?}");
        }
    }

    /// Both forms of the closest-hit walk's child ordering give the same next child and push the
    /// same entries in the same order, and that order is the hit lanes by increasing
    /// `child_key` (nearest first; equal `t`: higher lane first): random nodes with empty lanes,
    /// rays from inside (entry distances 0, the common tie) and outside, and short rays that hit
    /// few children. Fails if the network, the key or the lane permutation is wrong (the
    /// traversal tests would not notice a wrong order: the hit does not depend on it).
    #[test]
    fn child_order_is_by_key_in_both_walks() {
        let mut rng = crate::sampling::rng::Pcg32::new(3, 4);
        let has_avx2 = cfg!(target_arch = "x86_64") && crate::math::detect_avx2();
        let (mut multi, mut ties) = (0, 0);
        for round in 0..20_000 {
            let mut n = BvhNode::EMPTY;
            for lane in 0..WIDTH {
                if rng.next_u32().is_multiple_of(5) {
                    continue;
                }
                // Overlapping boxes around the origin, as near the root of a real tree.
                let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                let h = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0;
                let b = Bounds3 {
                    min: c - h,
                    max: c + h,
                };
                n.set_lane(lane, &b, rng.next_u32() >> 1, rng.next_u32() % 3);
            }
            let spread = if round % 2 == 0 { 1.0 } else { 8.0 };
            let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * spread;
            let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            let mut ray = Ray::new(o, d);
            if round % 3 == 0 {
                ray.t_max = 3.0 * rng.next_f32();
            }
            let slab = SlabRay::new(&ray, &RayInv::new(ray.d));
            let (t_enter, mask) = slab.test(&n, ray.t_max);
            // Expected: the hit lanes by increasing key, as stack entries (next last).
            let mut lanes: Vec<usize> = (0..WIDTH).filter(|&l| mask & (1 << l) != 0).collect();
            lanes.sort_by_key(|&l| std::cmp::Reverse(child_key(t_enter[l], l)));
            let want: Vec<Entry> = lanes
                .iter()
                .map(|&l| Entry {
                    first: n.first[l],
                    count: n.count[l],
                    t: t_enter[l],
                })
                .collect();
            multi += (want.len() > 1) as usize;
            ties += (lanes.iter().filter(|&&l| t_enter[l] == 0.0).count() > 1) as usize;
            let base = 5;
            let check = |got: Option<Entry>, stack: &EntryStack, sp: usize, walk: &str| {
                let mut all: Vec<Entry> = (base..sp).map(|i| stack.get(i)).collect();
                all.extend(got);
                assert_eq!(all, want, "{walk} walk, round {round}");
            };
            // A stack already holding `base` entries, so the pushes must land above them.
            let below = || {
                let mut stack = EntryStack::new();
                for i in 0..base {
                    stack.set(
                        i,
                        Entry {
                            first: 0,
                            count: 0,
                            t: 0.0,
                        },
                    );
                }
                (stack, base)
            };
            let (mut stack, mut sp) = below();
            let got = order_children(&n, &t_enter, mask, &mut stack, &mut sp);
            check(got, &stack, sp, "portable");
            #[cfg(target_arch = "x86_64")]
            if has_avx2 {
                let (mut stack, mut sp) = below();
                // SAFETY: AVX2 was detected above.
                let got = unsafe {
                    let (t0, hit) = slab.test_avx2_vectors(&n, ray.t_max);
                    order_children_avx2(&n, t0, hit, &mut stack, &mut sp)
                };
                check(got, &stack, sp, "AVX2");
            }
        }
        assert!(
            multi > 5000 && ties > 1000,
            "{multi} multi-hit nodes, {ties} with ties"
        );
    }

    #[test]
    fn bvh_structure_is_sound() {
        let g = soup(20_000, 2);
        let bvh = Bvh::build_split(&g, 0.0);
        let s = bvh.stats();
        assert_eq!(bvh.prims.len(), 20_000);
        assert!(s.max_leaf_size <= MAX_LEAF, "{s:?}");
        assert!(s.max_depth < MAX_BINARY_DEPTH, "{s:?}");
        // Without splitting every primitive appears exactly once.
        let mut seen = vec![false; 20_000];
        for p in &bvh.prims {
            assert!(!seen[p.index()]);
            seen[p.index()] = true;
        }
        // With splitting (a few long triangles added to the soup), each at least once, and never
        // twice in one leaf.
        let mut g = g;
        for i in 0..200u32 {
            let a = Vec3::new(i as f32 * 0.05 - 5.0, -5.0, 0.0);
            g.triangles.push(TriangleVerts {
                p0: a,
                p1: a + Vec3::new(0.0, 10.0, 0.1),
                p2: a + Vec3::new(0.02, 10.0, 0.0),
            });
            g.tri_mesh.push((0, 20_000 + i));
            g.tri_light.push(crate::geometry::primitive::NO_LIGHT);
            g.meshes[0].indices.push([0, 0, 0]);
        }
        let bvh = Bvh::build_split(&g, 0.3);
        let s = bvh.stats();
        assert!(
            s.references > 20_200 + 1000 && s.max_leaf_size <= MAX_LEAF,
            "{s:?}"
        );
        let mut seen = vec![false; 20_200];
        for n in &bvh.nodes {
            for lane in 0..WIDTH {
                if n.count[lane] == 0 {
                    continue;
                }
                let leaf = &bvh.leaf_entries(n.first[lane], n.count[lane]);
                for (i, p) in leaf.iter().enumerate() {
                    assert!(!leaf[..i].contains(p), "{p:?} twice in one leaf");
                    seen[p.index()] = true;
                }
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn identical_primitives_do_not_recurse_forever() {
        let mut g = soup(1, 3);
        let t = g.triangles[0];
        for i in 1..1000 {
            g.triangles.push(t);
            g.tri_mesh.push((0, i));
            g.tri_light.push(crate::geometry::primitive::NO_LIGHT);
            g.meshes[0].indices.push([0, 0, 0]);
        }
        let bvh = Bvh::build(&g);
        assert!(bvh.stats().max_depth < MAX_BINARY_DEPTH);
        let c = (t.p0 + t.p1 + t.p2) / 3.0;
        let n = t.normal_unnormalized().normalize();
        let ray = Ray::new(c + n, -n);
        assert!(bvh.intersect(&g, &ray).is_some());
    }

    #[test]
    fn empty_scene() {
        let g = GeometryStore::default();
        let bvh = Bvh::build(&g);
        let ray = Ray::new(Vec3::ZERO, Vec3::Z);
        assert!(bvh.intersect(&g, &ray).is_none());
        assert!(!bvh.occluded(&g, &ray));
    }
}
