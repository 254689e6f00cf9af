//! Spatial splits in the BVH build (SBVH: Stich, Friedrich & Dietrich 2009, "Spatial Splits in
//! Bounding Volume Hierarchies"). At each node, besides the binned object split of `bvh.rs`, the
//! build may cut the node's box by an axis-aligned plane and put every reference on the side(s)
//! it reaches: a reference straddling the plane becomes two, each with the box of its part of
//! the triangle (clipped, then intersected with the reference's box, §4.1). Where a long thin part
//! crosses a node, an object split's children overlap (both boxes hold the part's whole extent);
//! a spatial split's do not.
//!
//! - Spatial splits are only tried where the best object split's children overlap by more than
//!   α · (root area) (§4.4, α = 1e-5): elsewhere they rarely win and cost build time.
//! - Binning (§4.2): `BINS` equal bins over the node's box per axis; a reference counts as
//!   entering its first bin and leaving its last, and its clipped piece in each bin it spans grows
//!   that bin's box. The split's cost is the usual `n_L·A_L + n_R·A_R`.
//! - Reference unsplitting (§4.3): a straddling reference goes whole to one side where that is
//!   cheaper than duplicating it.
//! - A budget bounds the duplicates: `budget × references` extra references in the whole tree,
//!   handed down to the children in proportion to their sizes (so the tree depends on the input
//!   only, never on the order rayon runs the subtrees in: the same tree for any thread count). A
//!   subtree without budget is built by the object-split builder itself.
//! - A piece's box is padded by a few ulps and clamped to the reference's box (as in `split.rs`),
//!   so the pieces' boxes cover the part of the triangle the reference stands for: no hit is lost
//!   to rounding. Every reference tests the whole triangle, and a leaf keeps each primitive once.

use super::bvh::{
    BINS, BuildNode, BuildPrim, MEDIAN_SPLIT_DEPTH, PARALLEL_THRESHOLD, best_bin_split, bin_of,
    build_recursive, keep_leaf,
};
use super::split::{Polygon, padded_within};
use crate::geometry::{Bounds3, GeometryStore, PrimRef, PrimitiveKind};

/// Stich et al.'s overlap threshold, a share of the root's surface area.
const ALPHA: f32 = 1e-5;

/// Extra references the spatial splits may add, as a share of the references the build starts
/// from (0: no spatial splits, the build is `build_recursive` alone). Off by default: on ToyCar
/// (after the pre-split pass) budget 1.0 cut the closest-hit and shadow walks' instructions per
/// call by 9 % and 8 %, but made the build ~5× slower (160 → 820 ms), more than the time it
/// saves at 512², 4 spp, and the Stanford dragon's build 10× slower (871 k triangles: 1.3 →
/// 11.6 s) for no change of its SAH cost (BENCHMARKS.md "Session 19: spatial splits").
pub const DEFAULT_BUDGET: f32 = 0.0;

/// The spatial-split budget: `TRAYECTO_BVH_SPATIAL_BUDGET` (for benchmarking) or
/// [`DEFAULT_BUDGET`].
pub fn budget_from_env() -> f32 {
    std::env::var("TRAYECTO_BVH_SPATIAL_BUDGET")
        .ok()
        .and_then(|s| s.parse::<f32>().ok())
        .filter(|b| b.is_finite() && *b >= 0.0)
        .unwrap_or(DEFAULT_BUDGET)
}

/// What a spatial split needs besides the references: the triangles, to clip them.
pub(super) struct Spatial<'a> {
    pub geometry: &'a GeometryStore,
    /// α times the root box's surface area.
    pub min_overlap: f32,
}

impl<'a> Spatial<'a> {
    pub fn new(geometry: &'a GeometryStore, root: &Bounds3) -> Self {
        // `TRAYECTO_BVH_SPATIAL_ALPHA` overrides α (for benchmarking).
        let alpha = std::env::var("TRAYECTO_BVH_SPATIAL_ALPHA")
            .ok()
            .and_then(|s| s.parse::<f32>().ok())
            .filter(|a| a.is_finite() && *a >= 0.0)
            .unwrap_or(ALPHA);
        Spatial {
            geometry,
            min_overlap: alpha * root.surface_area(),
        }
    }

    /// The boxes of the parts of reference `(prim, b)` at `≤ pos` and `≥ pos` along `axis`;
    /// `Bounds3::EMPTY` for a side the reference does not reach. A triangle is clipped
    /// (Sutherland–Hodgman), any other primitive keeps its box cut at the plane (it lies inside).
    fn split_ref(&self, prim: PrimRef, b: &Bounds3, axis: usize, pos: f32) -> (Bounds3, Bounds3) {
        if b.max[axis] <= pos {
            return (*b, Bounds3::EMPTY);
        }
        if b.min[axis] >= pos {
            return (Bounds3::EMPTY, *b);
        }
        let (mut lb, mut rb) = (*b, *b);
        if prim.kind() == PrimitiveKind::Triangle {
            let t = &self.geometry.triangles[prim.index()];
            let (l, r) = Polygon::triangle(t.p0, t.p1, t.p2).clip(axis, pos);
            let side = |p: &Polygon| {
                if p.n < 3 {
                    Bounds3::EMPTY
                } else {
                    padded_within(p.bounds(), b)
                }
            };
            (lb, rb) = (side(&l), side(&r));
        }
        lb.max[axis] = lb.max[axis].min(pos);
        rb.min[axis] = rb.min[axis].max(pos);
        // A side left with nothing (or only rounding): the other keeps the whole box, so the
        // triangle's part inside `b` stays covered.
        if lb.is_empty() {
            (Bounds3::EMPTY, *b)
        } else if rb.is_empty() {
            (*b, Bounds3::EMPTY)
        } else {
            (lb, rb)
        }
    }
}

/// A subtree whose leaves own their references (a spatial split can put one reference in both
/// children, so they cannot share one array partitioned in place).
pub(super) enum Node {
    Leaf(Bounds3, Vec<BuildPrim>),
    Interior(Bounds3, Box<[Node; 2]>),
}

impl Node {
    fn bounds(&self) -> Bounds3 {
        match self {
            Node::Leaf(b, _) | Node::Interior(b, _) => *b,
        }
    }

    /// The same tree as a [`BuildNode`] over `build` (its leaves' references appended in
    /// depth-first order).
    pub fn flatten(self, build: &mut Vec<BuildPrim>) -> BuildNode {
        match self {
            Node::Leaf(bounds, refs) => {
                let first = build.len();
                build.extend(refs);
                BuildNode::Leaf {
                    bounds,
                    first,
                    count: build.len() - first,
                }
            }
            Node::Interior(bounds, children) => {
                let [a, b] = *children;
                let a = a.flatten(build);
                let b = b.flatten(build);
                BuildNode::Interior {
                    bounds,
                    children: Box::new([a, b]),
                }
            }
        }
    }

    /// A subtree built by `build_recursive` over `refs`, its leaves' references copied out.
    fn from_plain(node: &BuildNode, refs: &[BuildPrim]) -> Node {
        match node {
            BuildNode::Leaf {
                bounds,
                first,
                count,
            } => Node::Leaf(*bounds, refs[*first..*first + *count].to_vec()),
            BuildNode::Interior { bounds, children } => Node::Interior(
                *bounds,
                Box::new([
                    Self::from_plain(&children[0], refs),
                    Self::from_plain(&children[1], refs),
                ]),
            ),
        }
    }
}

/// The cheapest spatial split found by binning: axis, plane, cost, the binned boxes and counts
/// of both sides.
struct SpatialSplit {
    axis: usize,
    pos: f32,
    cost: f32,
    left: Bounds3,
    right: Bounds3,
    n_left: usize,
    n_right: usize,
}

/// The cheapest spatial split of `refs` (node box `bounds`) over all three axes that adds at most
/// `budget` references (§4.2).
fn best_spatial_split(
    ctx: &Spatial,
    refs: &[BuildPrim],
    bounds: &Bounds3,
    budget: usize,
) -> Option<SpatialSplit> {
    let n = refs.len();
    let mut best: Option<SpatialSplit> = None;
    for axis in 0..3 {
        let (lo, ext) = (bounds.min[axis], bounds.max[axis] - bounds.min[axis]);
        if !(ext > 0.0) {
            continue;
        }
        let plane = |i: usize| lo + ext * (i as f32 / BINS as f32);
        let mut bin_bounds = [Bounds3::EMPTY; BINS];
        let mut entry = [0usize; BINS];
        let mut exit = [0usize; BINS];
        for r in refs {
            let b0 = bin_of(r.bounds.min[axis], lo, ext);
            let b1 = bin_of(r.bounds.max[axis], lo, ext).max(b0);
            entry[b0] += 1;
            exit[b1] += 1;
            let mut rest = r.bounds;
            for (b, bin) in bin_bounds.iter_mut().enumerate().take(b1).skip(b0) {
                let (l, rr) = ctx.split_ref(r.prim, &rest, axis, plane(b + 1));
                *bin = bin.union(&l);
                rest = rr;
                if rest.is_empty() {
                    break;
                }
            }
            bin_bounds[b1] = bin_bounds[b1].union(&rest);
        }
        let mut right_bounds = [Bounds3::EMPTY; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut cnt) = (Bounds3::EMPTY, 0);
        for i in (1..BINS).rev() {
            acc = acc.union(&bin_bounds[i]);
            cnt += exit[i];
            right_bounds[i] = acc;
            right_count[i] = cnt;
        }
        let (mut acc, mut cnt) = (Bounds3::EMPTY, 0);
        for i in 0..BINS - 1 {
            acc = acc.union(&bin_bounds[i]);
            cnt += entry[i];
            let (n_left, n_right) = (cnt, right_count[i + 1]);
            if n_left == 0 || n_right == 0 || n_left + n_right > n + budget {
                continue;
            }
            let cost = n_left as f32 * acc.surface_area()
                + n_right as f32 * right_bounds[i + 1].surface_area();
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(SpatialSplit {
                    axis,
                    pos: plane(i + 1),
                    cost,
                    left: acc,
                    right: right_bounds[i + 1],
                    n_left,
                    n_right,
                });
            }
        }
    }
    best
}

/// Partitions `refs` by the spatial split `s`, with reference unsplitting (§4.3). `None` if a
/// side ends up empty.
fn spatial_partition(
    ctx: &Spatial,
    refs: &[BuildPrim],
    s: &SpatialSplit,
) -> Option<(Vec<BuildPrim>, Vec<BuildPrim>)> {
    let (axis, pos) = (s.axis, s.pos);
    let (al, ar) = (s.left.surface_area(), s.right.surface_area());
    let (nl, nr) = (s.n_left as f32, s.n_right as f32);
    let c_split = al * nl + ar * nr;
    let mut left = Vec::with_capacity(s.n_left);
    let mut right = Vec::with_capacity(s.n_right);
    let piece = |prim, bounds: Bounds3| BuildPrim {
        prim,
        bounds,
        centroid: bounds.centroid(),
    };
    for r in refs {
        if r.bounds.max[axis] <= pos {
            left.push(*r);
        } else if r.bounds.min[axis] >= pos {
            right.push(*r);
        } else {
            let c_left = s.left.union(&r.bounds).surface_area() * nl + ar * (nr - 1.0);
            let c_right = al * (nl - 1.0) + s.right.union(&r.bounds).surface_area() * nr;
            if c_left < c_split && c_left <= c_right {
                left.push(*r);
            } else if c_right < c_split {
                right.push(*r);
            } else {
                let (lb, rb) = ctx.split_ref(r.prim, &r.bounds, axis, pos);
                if !lb.is_empty() {
                    left.push(piece(r.prim, lb));
                }
                if !rb.is_empty() {
                    right.push(piece(r.prim, rb));
                }
            }
        }
    }
    (!left.is_empty() && !right.is_empty()).then_some((left, right))
}

/// Builds the subtree over `refs` with object and spatial splits, adding at most `budget`
/// references. Leaf rules and object splits are `build_recursive`'s.
pub(super) fn build(ctx: &Spatial, mut refs: Vec<BuildPrim>, depth: usize, budget: usize) -> Node {
    let n = refs.len();
    if budget == 0 || depth > MEDIAN_SPLIT_DEPTH || n <= 2 {
        let node = build_recursive(&mut refs, 0, depth);
        return Node::from_plain(&node, &refs);
    }
    let bounds = refs.iter().fold(Bounds3::EMPTY, |b, p| b.union(&p.bounds));
    let centroid_bounds = refs
        .iter()
        .fold(Bounds3::EMPTY, |b, p| b.union_point(p.centroid));
    // The best object split, as `build_recursive` finds it.
    let mut object = (f32::INFINITY, 0usize, 0usize);
    for ax in 0..3 {
        let ext = centroid_bounds.max[ax] - centroid_bounds.min[ax];
        if !(ext > 0.0) {
            continue;
        }
        let (cost, split) = best_bin_split(&refs, ax, centroid_bounds.min[ax], ext);
        if cost < object.0 {
            object = (cost, ax, split);
        }
    }
    let (object_cost, axis, split) = object;
    let (lo, ext) = (
        centroid_bounds.min[axis],
        centroid_bounds.max[axis] - centroid_bounds.min[axis],
    );
    let on_left = |p: &BuildPrim| bin_of(p.centroid[axis], lo, ext) <= split;
    // Try spatial splits where the object split's children overlap (§4.4); always where every
    // centroid falls in one bin (no object split exists).
    let overlap = if object_cost.is_finite() {
        let (mut l, mut r) = (Bounds3::EMPTY, Bounds3::EMPTY);
        for p in &refs {
            if on_left(p) {
                l = l.union(&p.bounds);
            } else {
                r = r.union(&p.bounds);
            }
        }
        let mut both = l;
        for a in 0..3 {
            both.min[a] = l.min[a].max(r.min[a]);
            both.max[a] = l.max[a].min(r.max[a]);
        }
        both.surface_area()
    } else {
        f32::INFINITY
    };
    let spatial = if overlap > ctx.min_overlap {
        best_spatial_split(ctx, &refs, &bounds, budget).filter(|s| s.cost < object_cost)
    } else {
        None
    };
    let best_cost = spatial.as_ref().map_or(object_cost, |s| s.cost);
    if !best_cost.is_finite() {
        // No split plane at all (coincident centroids, no spatial plane): `build_recursive`
        // makes a leaf or splits by count.
        let node = build_recursive(&mut refs, 0, depth);
        return Node::from_plain(&node, &refs);
    }
    if keep_leaf(&refs, &bounds, best_cost) {
        return Node::Leaf(bounds, refs);
    }
    let (left, right) = match spatial.and_then(|s| spatial_partition(ctx, &refs, &s)) {
        Some(sides) => sides,
        None => {
            let mut l = 0;
            for i in 0..n {
                if on_left(&refs[i]) {
                    refs.swap(i, l);
                    l += 1;
                }
            }
            let mid = if l == 0 || l == n { n / 2 } else { l };
            let right = refs.split_off(mid);
            (refs, right)
        }
    };
    // The budget left, shared in proportion to the children's sizes.
    let rest = (n + budget).saturating_sub(left.len() + right.len());
    let left_budget = rest * left.len() / (left.len() + right.len());
    let right_budget = rest - left_budget;
    let big = left.len() + right.len() > PARALLEL_THRESHOLD;
    let (a, b) = if big {
        rayon::join(
            || build(ctx, left, depth + 1, left_budget),
            || build(ctx, right, depth + 1, right_budget),
        )
    } else {
        (
            build(ctx, left, depth + 1, left_budget),
            build(ctx, right, depth + 1, right_budget),
        )
    };
    Node::Interior(a.bounds().union(&b.bounds()), Box::new([a, b]))
}
