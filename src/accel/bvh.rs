//! Bounding volume hierarchy built with the binned surface-area heuristic (Wald 2007, "On fast
//! Construction of SAH-based Bounding Volume Hierarchies"; PBRT §4.3), built in parallel with rayon,
//! flattened depth-first into 32-byte nodes and traversed front-to-back.

use crate::geometry::primitive::Intersection;
use crate::geometry::{Bounds3, GeometryStore, PrimRef, Ray, RayInv};
use crate::math::Vec3;

const BINS: usize = 16;
const MAX_LEAF: usize = 8;
/// Cost of one traversal step relative to one primitive test (PBRT uses 1/8).
const TRAVERSAL_COST: f32 = 0.125;
/// Below this many primitives a subtree is built on the current thread.
const PARALLEL_THRESHOLD: usize = 4096;
/// Depth past which splits are by median; with at most 2^32 primitives the tree stays under
/// `STACK_SIZE` levels.
const MEDIAN_SPLIT_DEPTH: usize = 60;
const STACK_SIZE: usize = 96;

/// A flattened node: bounds plus either the first primitive and count (leaf) or the index of the
/// second child (interior; the first child follows immediately).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct BvhNode {
    pub min: [f32; 3],
    pub offset: u32,
    pub max: [f32; 3],
    pub count: u16,
    pub axis: u16,
}

pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    pub prims: Vec<PrimRef>,
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
        axis: usize,
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
}

impl Bvh {
    pub fn build(geometry: &GeometryStore) -> Bvh {
        Self::build_from(geometry.all_prims(), |p| geometry.bounds(p))
    }

    /// Builds over any set of primitives given their bounds. Primitives with empty or non-finite
    /// bounds (degenerate input) are left out: they can never be hit.
    pub fn build_from(prims: Vec<PrimRef>, bounds_of: impl Fn(PrimRef) -> Bounds3 + Sync) -> Bvh {
        let mut build: Vec<BuildPrim> = prims
            .into_iter()
            .filter_map(|prim| {
                let bounds = bounds_of(prim);
                let ok = !bounds.is_empty() && bounds.min.is_finite() && bounds.max.is_finite();
                ok.then(|| BuildPrim {
                    prim,
                    bounds,
                    centroid: bounds.centroid(),
                })
            })
            .collect();
        if build.is_empty() {
            return Bvh {
                nodes: Vec::new(),
                prims: Vec::new(),
            };
        }
        let root = build_recursive(&mut build, 0, 0);
        let mut nodes = Vec::with_capacity(2 * build.len() / 2 + 1);
        flatten(&root, &mut nodes);
        Bvh {
            nodes,
            prims: build.into_iter().map(|b| b.prim).collect(),
        }
    }

    pub fn bounds(&self) -> Bounds3 {
        match self.nodes.first() {
            Some(n) => Bounds3 {
                min: Vec3::from(n.min),
                max: Vec3::from(n.max),
            },
            None => Bounds3::EMPTY,
        }
    }

    pub fn stats(&self) -> BvhStats {
        let mut s = BvhStats {
            nodes: self.nodes.len(),
            ..Default::default()
        };
        if self.nodes.is_empty() {
            return s;
        }
        let mut stack = vec![(0usize, 1usize)];
        while let Some((i, depth)) = stack.pop() {
            let n = &self.nodes[i];
            s.max_depth = s.max_depth.max(depth);
            if n.count > 0 {
                s.leaves += 1;
                s.max_leaf_size = s.max_leaf_size.max(n.count as usize);
            } else {
                stack.push((i + 1, depth + 1));
                stack.push((n.offset as usize, depth + 1));
            }
        }
        s
    }

    #[inline]
    fn node_hit(n: &BvhNode, ray: &Ray, inv: &RayInv, t_max: f32) -> bool {
        let b = Bounds3 {
            min: Vec3::from(n.min),
            max: Vec3::from(n.max),
        };
        b.hit(ray, inv, t_max)
    }

    /// Closest hit, visiting the nearer child first so far subtrees are culled by the shrinking
    /// `t_max`.
    pub fn intersect(&self, geometry: &GeometryStore, ray: &Ray) -> Option<Intersection> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = RayInv::new(ray.d);
        let mut best: Option<Intersection> = None;
        let mut t_max = ray.t_max;
        let mut stack = TraversalStack::new();
        let mut sp = 0usize;
        let mut current = 0usize;
        loop {
            let node = &self.nodes[current];
            if Self::node_hit(node, ray, &inv, t_max) {
                if node.count > 0 {
                    let first = node.offset as usize;
                    for &p in &self.prims[first..first + node.count as usize] {
                        if let Some(h) = geometry.intersect(p, ray, t_max) {
                            t_max = h.t;
                            best = Some(h);
                        }
                    }
                    if sp == 0 {
                        break;
                    }
                    sp -= 1;
                    current = stack.get(sp) as usize;
                } else if inv.neg[node.axis as usize] == 1 {
                    stack.set(sp, current as u32 + 1);
                    sp += 1;
                    current = node.offset as usize;
                } else {
                    stack.set(sp, node.offset);
                    sp += 1;
                    current += 1;
                }
            } else {
                if sp == 0 {
                    break;
                }
                sp -= 1;
                current = stack.get(sp) as usize;
            }
        }
        best
    }

    /// True as soon as any primitive blocks the ray.
    pub fn occluded(&self, geometry: &GeometryStore, ray: &Ray) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let inv = RayInv::new(ray.d);
        let mut stack = TraversalStack::new();
        let mut sp = 0usize;
        let mut current = 0usize;
        loop {
            let node = &self.nodes[current];
            if Self::node_hit(node, ray, &inv, ray.t_max) {
                if node.count > 0 {
                    let first = node.offset as usize;
                    for &p in &self.prims[first..first + node.count as usize] {
                        if geometry.intersect(p, ray, ray.t_max).is_some() {
                            return true;
                        }
                    }
                    if sp == 0 {
                        return false;
                    }
                    sp -= 1;
                    current = stack.get(sp) as usize;
                } else {
                    stack.set(sp, node.offset);
                    sp += 1;
                    current += 1;
                }
            } else {
                if sp == 0 {
                    return false;
                }
                sp -= 1;
                current = stack.get(sp) as usize;
            }
        }
    }
}

/// The traversal stack, left uninitialised: zeroing `STACK_SIZE` words per ray was a `memset` that
/// cost ~2% of all instructions on the Cornell box (callgrind). Entries are only read below `sp`,
/// after having been written.
struct TraversalStack([std::mem::MaybeUninit<u32>; STACK_SIZE]);

impl TraversalStack {
    #[inline(always)]
    fn new() -> Self {
        TraversalStack([std::mem::MaybeUninit::uninit(); STACK_SIZE])
    }

    #[inline(always)]
    fn set(&mut self, i: usize, v: u32) {
        self.0[i] = std::mem::MaybeUninit::new(v);
    }

    #[inline(always)]
    fn get(&self, i: usize) -> u32 {
        // SAFETY: traversal pops index `i` only after pushing it (`sp` counts pushes minus pops),
        // so the entry was written; indexing is bounds-checked.
        unsafe { self.0[i].assume_init() }
    }
}

fn build_recursive(prims: &mut [BuildPrim], first: usize, depth: usize) -> BuildNode {
    let bounds = prims.iter().fold(Bounds3::EMPTY, |b, p| b.union(&p.bounds));
    let n = prims.len();
    let leaf = || BuildNode::Leaf {
        bounds,
        first,
        count: n,
    };
    if n <= 2 {
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
        // Binned SAH: bucket centroids, sweep to find the cheapest split plane.
        let mut bin_bounds = [Bounds3::EMPTY; BINS];
        let mut bin_count = [0usize; BINS];
        let scale = BINS as f32 / extent;
        let bin_of = |c: Vec3| -> usize {
            let b = ((c[axis] - centroid_bounds.min[axis]) * scale) as usize;
            b.min(BINS - 1)
        };
        for p in prims.iter() {
            let b = bin_of(p.centroid);
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
            let cost =
                cnt as f32 * acc.surface_area() + right_count[i + 1] as f32 * right_area[i + 1];
            if cost < best_cost {
                best_cost = cost;
                best_split = i;
            }
        }
        let total_area = bounds.surface_area().max(f32::MIN_POSITIVE);
        let split_cost = TRAVERSAL_COST + best_cost / total_area;
        if n <= MAX_LEAF && split_cost >= n as f32 {
            return leaf();
        }
        // Partition in place around the chosen bin boundary.
        let mut left = 0;
        for i in 0..n {
            if bin_of(prims[i].centroid) <= best_split {
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
        axis,
        children: Box::new([a, b]),
    }
}

fn flatten(node: &BuildNode, nodes: &mut Vec<BvhNode>) -> usize {
    let index = nodes.len();
    let b = node.bounds();
    nodes.push(BvhNode {
        min: b.min.into(),
        offset: 0,
        max: b.max.into(),
        count: 0,
        axis: 0,
    });
    match node {
        BuildNode::Leaf { first, count, .. } => {
            nodes[index].offset = *first as u32;
            nodes[index].count = *count as u16;
        }
        BuildNode::Interior { axis, children, .. } => {
            flatten(&children[0], nodes);
            let second = flatten(&children[1], nodes);
            nodes[index].offset = second as u32;
            nodes[index].axis = *axis as u16;
        }
    }
    index
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::primitive::MeshAttributes;
    use crate::geometry::triangle::TriangleVerts;

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

    #[test]
    fn bvh_structure_is_sound() {
        let g = soup(20_000, 2);
        let bvh = Bvh::build(&g);
        let s = bvh.stats();
        assert_eq!(bvh.prims.len(), 20_000);
        assert!(s.max_leaf_size <= MAX_LEAF, "{s:?}");
        assert!(s.max_depth < STACK_SIZE, "{s:?}");
        // Every primitive appears exactly once.
        let mut seen = vec![false; 20_000];
        for p in &bvh.prims {
            assert!(!seen[p.index()]);
            seen[p.index()] = true;
        }
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
        assert!(bvh.stats().max_depth < STACK_SIZE);
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
