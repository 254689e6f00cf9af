//! Triangle pre-splitting for the BVH build: a long, thin or diagonal triangle has a bounding box
//! far larger than itself, which inflates every node above it (rays enter those boxes and find
//! nothing). Before the build, such triangles are cut by axis-aligned planes into several
//! *references* (the same triangle, each with the box of one piece), so the binned SAH sees small
//! boxes it can separate. This is the pre-process of Karras & Aila 2013 ("Fast Parallel
//! Construction of High-Quality Bounding Volume Hierarchies", §4.2) in a simplified form; Ernst &
//! Greiner 2007 ("Early Split Clipping") and Dammertz & Keller 2008 ("The Edge Volume Heuristic")
//! are the earlier versions. Spatial splits during the build (Stich et al. 2009, SBVH) would find
//! the planes per node, at a larger build cost.
//!
//! - Candidates are the triangles whose box diagonal is more than 4× the median triangle's (an
//!   evenly tessellated mesh has few or none: splitting it costs build time for nothing).
//! - A triangle's *excess* is its box's surface area minus twice its own area (a box around a
//!   piece of a triangle can shrink toward the piece, never below its two faces). Pieces are given
//!   out in proportion to excess^(1/3) (Karras & Aila's exponent: it spreads the budget over many
//!   triangles instead of cutting the few longest ones very finely), up to `budget × n` extra
//!   references in all.
//! - A triangle of `k` pieces is cut across its longest box axis at the coarsest plane of a global
//!   power-of-two grid over the scene that crosses the middle half of the box (so neighbouring
//!   triangles are cut at the same planes, which the build can then separate; Karras & Aila), the polygon is clipped
//!   (Sutherland–Hodgman), and the halves get ⌊k/2⌋ and ⌈k/2⌉ pieces, recursively.
//! - A piece's box is the box of its clipped polygon, padded by a few ulps and clamped to the
//!   parent box: the union of the pieces' boxes always covers the triangle, so no hit is lost to
//!   rounding. Every reference tests the whole triangle, so a hit is the same bits whichever
//!   reference finds it.
//!
//! The work is O(n + references · log k) and deterministic (one triangle at a time, in order).

use crate::geometry::{Bounds3, GeometryStore, PrimRef, PrimitiveKind};
use crate::math::Vec3;
use rayon::prelude::*;

/// Extra references as a share of the triangle count (Karras & Aila use 0.3).
pub const DEFAULT_BUDGET: f32 = 0.3;
/// A triangle is a candidate for splitting when its box's diagonal is more than this many times
/// the median triangle's.
const CANDIDATE_DIAGONAL: f32 = 4.0;
/// No triangle is cut into more pieces than this.
const MAX_PIECES: usize = 64;
/// A triangle ∩ box is convex with at most 3 + 6 vertices; one more clip plane adds one.
const MAX_POLY: usize = 10;

/// The references to build over: a primitive and the box of (a piece of) it.
#[derive(Clone, Copy, Debug)]
pub struct Reference {
    pub prim: PrimRef,
    pub bounds: Bounds3,
}

/// The pre-split budget: `TRAYECTO_BVH_SPLIT_BUDGET` (a share of the triangle count, `0` turns
/// splitting off; for benchmarking) or [`DEFAULT_BUDGET`].
pub fn budget_from_env() -> f32 {
    std::env::var("TRAYECTO_BVH_SPLIT_BUDGET")
        .ok()
        .and_then(|s| s.parse::<f32>().ok())
        .filter(|b| b.is_finite() && *b >= 0.0)
        .unwrap_or(DEFAULT_BUDGET)
}

/// Every primitive of `geometry` as one reference, and triangles with a large box cut into up to
/// `budget × triangles` extra references. Primitives with empty or non-finite bounds are left out.
pub fn references(geometry: &GeometryStore, budget: f32) -> Vec<Reference> {
    let prims = geometry.static_prims();
    let bounds: Vec<Bounds3> = prims.par_iter().map(|&p| geometry.bounds(p)).collect();
    let valid = |b: &Bounds3| !b.is_empty() && b.min.is_finite() && b.max.is_finite();
    let scene = bounds
        .iter()
        .filter(|b| valid(b))
        .fold(Bounds3::EMPTY, |a, b| a.union(b));
    // Only triangles much longer than the typical one are candidates: on an evenly tessellated
    // mesh (the Stanford dragon) splitting 30 % of the triangles left the SAH cost as it was
    // (20.8 → 20.7) and nearly doubled the build time (BENCHMARKS.md).
    let mut diagonals: Vec<f32> = prims
        .iter()
        .zip(&bounds)
        .filter(|(p, b)| p.kind() == PrimitiveKind::Triangle && valid(b))
        .map(|(_, b)| b.diagonal().length())
        .collect();
    if diagonals.is_empty() {
        return prims
            .iter()
            .zip(&bounds)
            .filter(|(_, b)| valid(b))
            .map(|(&prim, &bounds)| Reference { prim, bounds })
            .collect();
    }
    let mid = diagonals.len() / 2;
    let median = *diagonals.select_nth_unstable_by(mid, f32::total_cmp).1;
    let long = CANDIDATE_DIAGONAL * median;
    // Priority of each triangle (0 for everything else).
    let priority: Vec<f32> = prims
        .par_iter()
        .zip(&bounds)
        .map(|(&p, b)| {
            if p.kind() != PrimitiveKind::Triangle || !valid(b) || !(b.diagonal().length() > long) {
                return 0.0;
            }
            let t = &geometry.triangles[p.index()];
            let excess = b.surface_area() - t.normal_unnormalized().length();
            if excess > 0.0 && excess.is_finite() {
                excess.cbrt()
            } else {
                0.0
            }
        })
        .collect();
    let extra = (budget as f64 * geometry.triangles.len() as f64) as usize;
    let scale = pieces_scale(&priority, extra);
    let pieces = |p: f32| {
        ((p as f64 * scale) as usize)
            .saturating_add(1)
            .min(MAX_PIECES)
    };
    prims
        .par_iter()
        .zip(&bounds)
        .zip(&priority)
        .flat_map_iter(|((&prim, b), &pr)| {
            let mut out = Vec::new();
            if !valid(b) {
                return out;
            }
            let k = pieces(pr);
            if k <= 1 {
                out.push(Reference { prim, bounds: *b });
            } else {
                let t = &geometry.triangles[prim.index()];
                let poly = Polygon::triangle(t.p0, t.p1, t.p2);
                split(prim, &poly, *b, k, &scene, &mut out);
            }
            out
        })
        .collect()
}

/// The largest `s` with Σ ⌊s·pᵢ⌋ ≤ `extra` (each capped at `MAX_PIECES − 1`), by bisection: the
/// sum is non-decreasing in `s`.
fn pieces_scale(priority: &[f32], extra: usize) -> f64 {
    let max_p = priority.iter().cloned().fold(0.0f32, f32::max) as f64;
    if extra == 0 || max_p <= 0.0 {
        return 0.0;
    }
    let total = |s: f64| -> usize {
        priority
            .par_iter()
            .map(|&p| ((p as f64 * s) as usize).min(MAX_PIECES - 1))
            .sum()
    };
    // At s = (MAX_PIECES − 1)/min_positive every triangle is capped; start from a scale that
    // gives the largest triangle one extra piece and grow.
    let mut lo = 0.0f64;
    let mut hi = 1.0 / max_p;
    while total(hi) <= extra {
        lo = hi;
        hi *= 2.0;
        if hi > 1e30 {
            return lo;
        }
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if total(mid) <= extra {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// A convex polygon, at most `MAX_POLY` vertices, inline.
#[derive(Clone, Copy)]
struct Polygon {
    v: [Vec3; MAX_POLY],
    n: usize,
}

impl Polygon {
    fn triangle(a: Vec3, b: Vec3, c: Vec3) -> Polygon {
        let mut v = [Vec3::ZERO; MAX_POLY];
        v[0] = a;
        v[1] = b;
        v[2] = c;
        Polygon { v, n: 3 }
    }

    fn push(&mut self, p: Vec3) {
        // Cannot overflow for a triangle clipped by axis-aligned planes; if it did, dropping a
        // vertex would only be a tighter box for this piece, so clamp instead of panicking and
        // let the caller's padding and the parent clamp keep the result conservative.
        if self.n < MAX_POLY {
            self.v[self.n] = p;
            self.n += 1;
        }
    }

    fn bounds(&self) -> Bounds3 {
        self.v[..self.n]
            .iter()
            .fold(Bounds3::EMPTY, |b, &p| b.union_point(p))
    }

    /// The parts at `coordinate ≤ pos` and `≥ pos` along `axis` (Sutherland–Hodgman against one
    /// plane, both sides at once). Crossing points are put exactly on the plane along `axis`.
    fn clip(&self, axis: usize, pos: f32) -> (Polygon, Polygon) {
        let mut left = Polygon {
            v: [Vec3::ZERO; MAX_POLY],
            n: 0,
        };
        let mut right = left;
        for i in 0..self.n {
            let a = self.v[i];
            let b = self.v[(i + 1) % self.n];
            let (da, db) = (a[axis], b[axis]);
            if da <= pos {
                left.push(a);
            }
            if da >= pos {
                right.push(a);
            }
            if (da < pos && db > pos) || (da > pos && db < pos) {
                let t = (pos - da) / (db - da);
                let mut p = a + (b - a) * t;
                p[axis] = pos;
                left.push(p);
                right.push(p);
            }
        }
        (left, right)
    }
}

/// Pads `b` outward by a few ulps per coordinate (the clipped vertices are interpolated, so they
/// may be rounded inward), then clamps it to `parent`, which already covers the piece.
fn padded_within(b: Bounds3, parent: &Bounds3) -> Bounds3 {
    let pad = |x: f32| x.abs() * (4.0 * f32::EPSILON) + f32::MIN_POSITIVE;
    let mut out = b;
    for axis in 0..3 {
        out.min[axis] = (b.min[axis] - pad(b.min[axis])).max(parent.min[axis]);
        out.max[axis] = (b.max[axis] + pad(b.max[axis])).min(parent.max[axis]);
    }
    out
}

/// The split position along `axis` for the box `[lo, hi]`: the coarsest plane of the power-of-two
/// grid over `scene` inside the middle half of the box (so the two pieces are at least a quarter
/// of it each), or the midpoint when no level up to 24 has one (a box that small is not worth
/// aligning).
fn grid_plane(lo: f32, hi: f32, axis: usize, scene: &Bounds3) -> f32 {
    let (s0, ext) = (scene.min[axis], scene.max[axis] - scene.min[axis]);
    let quarter = 0.25 * (hi - lo);
    if ext > 0.0 {
        let (a, c) = ((lo + quarter - s0) / ext, (hi - quarter - s0) / ext);
        for level in 1..=24 {
            let cells = (1u32 << level) as f32;
            let j = (a * cells).ceil();
            if j / cells <= c {
                let pos = s0 + ext * (j / cells);
                if pos > lo && pos < hi {
                    return pos;
                }
            }
        }
    }
    0.5 * (lo + hi)
}

/// Cuts the piece `poly` (box `b`) into `k` references appended to `out`.
fn split(
    prim: PrimRef,
    poly: &Polygon,
    b: Bounds3,
    k: usize,
    scene: &Bounds3,
    out: &mut Vec<Reference>,
) {
    let axis = b.max_extent();
    let (lo, hi) = (b.min[axis], b.max[axis]);
    let pos = grid_plane(lo, hi, axis, scene);
    if k <= 1 || !(pos > lo && pos < hi) {
        out.push(Reference { prim, bounds: b });
        return;
    }
    let (left, right) = poly.clip(axis, pos);
    let side = |p: &Polygon, low: bool| {
        let mut pb = padded_within(p.bounds(), &b);
        if low {
            pb.max[axis] = pb.max[axis].min(pos);
        } else {
            pb.min[axis] = pb.min[axis].max(pos);
        }
        pb
    };
    // A side with fewer than three vertices holds no area of the triangle (or only rounding):
    // the other side keeps the whole box, so nothing can be lost.
    match (left.n >= 3, right.n >= 3) {
        (true, true) => {
            let (lb, rb) = (side(&left, true), side(&right, false));
            if lb.is_empty() || rb.is_empty() {
                out.push(Reference { prim, bounds: b });
                return;
            }
            split(prim, &left, lb, k / 2, scene, out);
            split(prim, &right, rb, k - k / 2, scene, out);
        }
        _ => out.push(Reference { prim, bounds: b }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::primitive::{MeshAttributes, NO_LIGHT};
    use crate::geometry::triangle::TriangleVerts;

    fn store(tris: &[[Vec3; 3]]) -> GeometryStore {
        let mut g = GeometryStore::default();
        let mut mesh = MeshAttributes::default();
        for (i, t) in tris.iter().enumerate() {
            g.triangles.push(TriangleVerts {
                p0: t[0],
                p1: t[1],
                p2: t[2],
            });
            g.tri_mesh.push((0, i as u32));
            g.tri_light.push(NO_LIGHT);
            mesh.indices.push([0, 0, 0]);
        }
        g.meshes.push(mesh);
        g
    }

    /// A long diagonal sliver among small triangles gets the budget; its pieces' boxes cover it
    /// (points sampled on it lie in some piece's box) and are much smaller in total than its box.
    #[test]
    fn a_diagonal_sliver_is_cut_and_still_covered() {
        let sliver = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(10.0, 10.0, 10.0),
            Vec3::new(10.0, 10.1, 10.0),
        ];
        let mut tris = vec![sliver];
        for i in 0..20 {
            let c = Vec3::splat(i as f32 * 0.5);
            tris.push([c, c + Vec3::X * 0.1, c + Vec3::Y * 0.1]);
        }
        let g = store(&tris);
        let refs = references(&g, 0.5);
        let pieces: Vec<&Reference> = refs.iter().filter(|r| r.prim.index() == 0).collect();
        assert!(pieces.len() >= 8, "{} pieces", pieces.len());
        assert_eq!(refs.len() - pieces.len(), 20, "small triangles stay whole");
        let whole = g.bounds(PrimRef::new(PrimitiveKind::Triangle, 0));
        let sum: f32 = pieces.iter().map(|r| r.bounds.surface_area()).sum();
        assert!(
            sum < 0.5 * whole.surface_area(),
            "{sum} vs {}",
            whole.surface_area()
        );
        let mut rng = crate::sampling::rng::Pcg32::new(3, 9);
        for _ in 0..20_000 {
            let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let p = sliver[0] + (sliver[1] - sliver[0]) * u + (sliver[2] - sliver[0]) * v;
            // The sample point itself is rounded: allow 1e-5 (a millionth of the sliver's length).
            let covered = pieces.iter().any(|r| {
                (0..3).all(|a| r.bounds.min[a] - 1e-5 <= p[a] && p[a] <= r.bounds.max[a] + 1e-5)
            });
            assert!(covered, "{p:?} is in no piece's box");
        }
        // Budget 0: one reference per triangle, the triangle's own box.
        let plain = references(&g, 0.0);
        assert_eq!(plain.len(), 21);
        assert_eq!(plain[0].bounds, whole);
    }
}
