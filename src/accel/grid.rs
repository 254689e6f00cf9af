//! The thesis's uniform grid ("Fujimoto grid", §5.3.6; Fujimoto, Tanaka & Iwata 1986, "ARTS:
//! Accelerated Ray-Tracing System") traversed with the 3D digital differential analyser of
//! Amanatides & Woo 1987 ("A Fast Voxel Traversal Algorithm for Ray Tracing").
//!
//! Resolution follows the thesis's `Grid::setCell` (annex, listing of the `Grid` class): with `N`
//! primitives in a box of extent `dim` and volume `V`, each axis gets `ceil(cbrt(λ·N / V) · dim_i)`
//! cells, λ = 7, i.e. about 7 cells per primitive with cubic cells. Two safeguards the thesis did not
//! need are added: flat scenes (zero volume) get a thin but non-zero extent, and the resolution is
//! scaled down when the cell count or the number of (primitive, cell) references would exceed a
//! budget, so hostile input (many huge triangles) cannot exhaust memory.
//!
//! Cells are stored compressed (one offset array and one reference array), so a cell lookup is two
//! loads and no allocation happens per ray. A primitive is put in every cell its bounding box
//! overlaps, enlarged by a small margin so that the rounding in the DDA (which may place a point
//! lying on a cell face in either neighbour) can never hide it: the result is exactly the brute-force
//! closest hit.

use crate::geometry::primitive::Intersection;
use crate::geometry::{Bounds3, GeometryStore, PrimRef, Ray};
use crate::math::{Vec3, gamma};

/// The thesis's density constant ("lambda = 7", cells per primitive).
pub const LAMBDA: f32 = 7.0;
/// Most cells along one axis.
pub const MAX_RES_AXIS: u32 = 1024;
/// Most cells overall (offsets are 4 bytes each).
pub const MAX_CELLS: u64 = 1 << 24;
/// Most (primitive, cell) references: a multiple of the primitive count, capped.
const REF_FACTOR: u64 = 32;
const MAX_REFS: u64 = 1 << 26;

pub struct Grid {
    /// The grid's box (the scene bounds, slightly padded).
    pub bounds: Bounds3,
    pub res: [u32; 3],
    cell_size: Vec3,
    inv_cell_size: Vec3,
    /// `cell_start[c]..cell_start[c + 1]` indexes `refs` for cell `c` (x fastest).
    cell_start: Vec<u32>,
    refs: Vec<PrimRef>,
}

/// Summary for reports and tests.
#[derive(Clone, Copy, Debug, Default)]
pub struct GridStats {
    pub res: [u32; 3],
    pub cells: usize,
    pub empty_cells: usize,
    pub references: usize,
    pub max_per_cell: usize,
}

impl Grid {
    pub fn build(geometry: &GeometryStore) -> Grid {
        Self::build_from(geometry.static_prims(), |p| geometry.bounds(p))
    }

    /// Builds over any set of primitives given their bounds. Primitives with empty or non-finite
    /// bounds can never be hit and are left out.
    pub fn build_from(prims: Vec<PrimRef>, bounds_of: impl Fn(PrimRef) -> Bounds3) -> Grid {
        let items: Vec<(PrimRef, Bounds3)> = prims
            .into_iter()
            .filter_map(|p| {
                let b = bounds_of(p);
                (!b.is_empty() && b.min.is_finite() && b.max.is_finite()).then_some((p, b))
            })
            .collect();
        let scene = items
            .iter()
            .fold(Bounds3::EMPTY, |acc, (_, b)| acc.union(b));
        if items.is_empty() {
            return Grid {
                bounds: Bounds3::EMPTY,
                res: [0; 3],
                cell_size: Vec3::ONE,
                inv_cell_size: Vec3::ONE,
                cell_start: vec![0],
                refs: Vec::new(),
            };
        }
        // A flat or point-like scene has no volume: give degenerate axes a thin extent so the
        // density formula stays finite; pad every axis a little so points on the scene's boundary
        // are strictly inside.
        let ext = scene.diagonal().max_element();
        let base = if ext > 0.0 { ext } else { 1.0 };
        let mut dim = scene.diagonal().max(Vec3::splat(base * 1e-3));
        let pad = dim * 1e-4 + (scene.min.abs() + scene.max.abs()) * 1e-6;
        let bounds = Bounds3 {
            min: scene.min - pad,
            max: scene.min - pad + dim + pad * 2.0,
        };
        dim = bounds.diagonal();

        let n = items.len() as f32;
        let volume = dim.x * dim.y * dim.z;
        let mut density = (LAMBDA * n / volume).cbrt();
        let ref_budget = (REF_FACTOR * items.len() as u64).clamp(1 << 20, MAX_REFS);
        loop {
            let res = resolution(dim, density);
            let cells = res.iter().map(|&r| r as u64).product::<u64>();
            let grid = Grid::with_res(bounds, res);
            let refs: u64 = if cells <= MAX_CELLS {
                items
                    .iter()
                    .map(|(_, b)| {
                        let (lo, hi) = grid.cell_range(b);
                        (0..3).map(|i| (hi[i] - lo[i] + 1) as u64).product::<u64>()
                    })
                    .sum()
            } else {
                u64::MAX
            };
            let coarsest = res == [1, 1, 1];
            if (cells <= MAX_CELLS && refs <= ref_budget) || coarsest {
                return grid.fill(&items, cells as usize, refs as usize);
            }
            density *= 0.75;
        }
    }

    fn with_res(bounds: Bounds3, res: [u32; 3]) -> Grid {
        let dim = bounds.diagonal();
        let cell_size = dim / Vec3::new(res[0] as f32, res[1] as f32, res[2] as f32);
        Grid {
            bounds,
            res,
            cell_size,
            inv_cell_size: Vec3::ONE / cell_size,
            cell_start: Vec::new(),
            refs: Vec::new(),
        }
    }

    /// Inclusive cell index range covered by `b`, enlarged by a margin that absorbs the rounding
    /// of both this computation and the traversal.
    fn cell_range(&self, b: &Bounds3) -> ([u32; 3], [u32; 3]) {
        let mut lo = [0u32; 3];
        let mut hi = [0u32; 3];
        for i in 0..3 {
            let margin = self.cell_size[i] * 1e-3
                + (self.bounds.min[i].abs() + self.bounds.max[i].abs()) * 1e-6;
            lo[i] = self.axis_cell(i, b.min[i] - margin);
            hi[i] = self.axis_cell(i, b.max[i] + margin);
        }
        (lo, hi)
    }

    #[inline]
    fn axis_cell(&self, axis: usize, x: f32) -> u32 {
        let c = ((x - self.bounds.min[axis]) * self.inv_cell_size[axis]).floor();
        // `as` saturates NaN to 0 and clamps out-of-range floats.
        (c.max(0.0) as u32).min(self.res[axis] - 1)
    }

    fn fill(mut self, items: &[(PrimRef, Bounds3)], cells: usize, refs: usize) -> Grid {
        let mut count = vec![0u32; cells + 1];
        let ranges: Vec<([u32; 3], [u32; 3])> =
            items.iter().map(|(_, b)| self.cell_range(b)).collect();
        let (rx, ry) = (self.res[0] as usize, self.res[1] as usize);
        let for_cells = |lo: [u32; 3], hi: [u32; 3], f: &mut dyn FnMut(usize)| {
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        f((z as usize * ry + y as usize) * rx + x as usize);
                    }
                }
            }
        };
        for &(lo, hi) in &ranges {
            for_cells(lo, hi, &mut |c| count[c + 1] += 1);
        }
        for c in 0..cells {
            count[c + 1] += count[c];
        }
        let mut next = count.clone();
        let mut out = vec![PrimRef(0); refs];
        for ((prim, _), &(lo, hi)) in items.iter().zip(&ranges) {
            for_cells(lo, hi, &mut |c| {
                out[next[c] as usize] = *prim;
                next[c] += 1;
            });
        }
        self.cell_start = count;
        self.refs = out;
        self
    }

    pub fn stats(&self) -> GridStats {
        let cells = self.cell_start.len().saturating_sub(1);
        let sizes = self.cell_start.windows(2).map(|w| (w[1] - w[0]) as usize);
        GridStats {
            res: self.res,
            cells,
            empty_cells: sizes.clone().filter(|&s| s == 0).count(),
            references: self.refs.len(),
            max_per_cell: sizes.max().unwrap_or(0),
        }
    }

    #[inline]
    fn cell_prims(&self, c: [u32; 3]) -> &[PrimRef] {
        let i = (c[2] as usize * self.res[1] as usize + c[1] as usize) * self.res[0] as usize
            + c[0] as usize;
        let (a, b) = (self.cell_start[i] as usize, self.cell_start[i + 1] as usize);
        &self.refs[a..b]
    }

    /// Walks the cells the ray crosses within `(0, t_max)` in order, calling `visit(cell prims,
    /// t at which the ray leaves the cell)`; `visit` returns false to stop.
    #[inline]
    fn walk(&self, ray: &Ray, t_max: f32, mut visit: impl FnMut(&[PrimRef], f32) -> bool) {
        if self.refs.is_empty() {
            return;
        }
        let inv_d = Vec3::ONE / ray.d;
        // Clip the ray to the grid box (slab test; the far distance is enlarged by γ(3) as in
        // PBRT §3.9.2 so rounding cannot make the box look missed).
        let mut t0 = 0.0f32;
        let mut t1 = t_max;
        for i in 0..3 {
            let mut tn = (self.bounds.min[i] - ray.o[i]) * inv_d[i];
            let mut tf = (self.bounds.max[i] - ray.o[i]) * inv_d[i];
            if tn > tf {
                std::mem::swap(&mut tn, &mut tf);
            }
            tf *= 1.0 + 2.0 * gamma(3);
            // NaN (0 · ∞ when the origin lies on a slab plane of a parallel ray) leaves t0/t1 as is.
            if tn > t0 {
                t0 = tn;
            }
            if tf < t1 {
                t1 = tf;
            }
            if t0 > t1 {
                return;
            }
        }
        let p = ray.o + ray.d * t0;
        let mut cell = [0u32; 3];
        let mut step = [0i32; 3];
        let mut next_t = [f32::INFINITY; 3];
        for i in 0..3 {
            cell[i] = self.axis_cell(i, p[i]);
            if ray.d[i] > 0.0 {
                step[i] = 1;
                next_t[i] = self.boundary_t(ray, &inv_d, i, cell[i] + 1);
            } else if ray.d[i] < 0.0 {
                step[i] = -1;
                next_t[i] = self.boundary_t(ray, &inv_d, i, cell[i]);
            }
        }
        loop {
            // Axis whose cell face the ray crosses first (Amanatides & Woo's comparison).
            let axis = if next_t[0] < next_t[1] {
                if next_t[0] < next_t[2] { 0 } else { 2 }
            } else if next_t[1] < next_t[2] {
                1
            } else {
                2
            };
            let t_exit = next_t[axis];
            if !visit(self.cell_prims(cell), t_exit) {
                return;
            }
            // `step == 0` only when every direction component is zero (or NaN): nowhere to go.
            if !(t_exit <= t1) || step[axis] == 0 {
                return;
            }
            let c = cell[axis] as i64 + step[axis] as i64;
            if c < 0 || c >= self.res[axis] as i64 {
                return;
            }
            cell[axis] = c as u32;
            // Recomputed from the face position rather than accumulated, so the error does not
            // grow with the number of steps.
            let face = if step[axis] > 0 {
                cell[axis] + 1
            } else {
                cell[axis]
            };
            next_t[axis] = self.boundary_t(ray, &inv_d, axis, face);
        }
    }

    /// Ray parameter at which the ray meets face `k` of `axis`.
    #[inline]
    fn boundary_t(&self, ray: &Ray, inv_d: &Vec3, axis: usize, k: u32) -> f32 {
        let x = self.bounds.min[axis] + k as f32 * self.cell_size[axis];
        (x - ray.o[axis]) * inv_d[axis]
    }

    /// Closest hit within `(0, ray.t_max)`.
    pub fn intersect(&self, geometry: &GeometryStore, ray: &Ray) -> Option<Intersection> {
        let mut best: Option<Intersection> = None;
        let mut t_max = ray.t_max;
        self.walk(ray, ray.t_max, |prims, t_exit| {
            for &p in prims {
                if let Some(h) = geometry.intersect(p, ray, t_max) {
                    t_max = h.t;
                    best = Some(h);
                }
            }
            // A hit beyond this cell's exit may be beaten by a primitive in a later cell.
            !(t_max <= t_exit)
        });
        best
    }

    /// True if anything blocks the ray within `(0, ray.t_max)`.
    pub fn occluded(&self, geometry: &GeometryStore, ray: &Ray) -> bool {
        let mut hit = false;
        self.walk(ray, ray.t_max, |prims, _| {
            hit = prims
                .iter()
                .any(|&p| geometry.intersect(p, ray, ray.t_max).is_some());
            !hit
        });
        hit
    }
}

/// Cells per axis for a density in cells per unit length, clamped to `[1, MAX_RES_AXIS]`.
fn resolution(dim: Vec3, density: f32) -> [u32; 3] {
    let mut res = [1u32; 3];
    for i in 0..3 {
        let r = (density * dim[i]).ceil();
        res[i] = if r.is_finite() {
            (r.max(1.0) as u32).min(MAX_RES_AXIS)
        } else {
            MAX_RES_AXIS
        };
    }
    res
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::PrimitiveKind;
    use crate::geometry::triangle::TriangleVerts;
    use crate::sampling::rng::Pcg32;

    fn random_soup(n: usize, seed: u64) -> GeometryStore {
        let mut g = GeometryStore::default();
        let mut r = Pcg32::new(seed, 7);
        let mut v = || Vec3::new(r.next_f32(), r.next_f32(), r.next_f32());
        for i in 0..n {
            let c = v() * 10.0;
            let s = if i % 17 == 0 { 4.0 } else { 0.5 };
            g.triangles.push(TriangleVerts {
                p0: c + (v() - 0.5) * s,
                p1: c + (v() - 0.5) * s,
                p2: c + (v() - 0.5) * s,
            });
            g.tri_mesh.push((0, i as u32));
            g.tri_light.push(crate::geometry::primitive::NO_LIGHT);
        }
        g.meshes.push(crate::geometry::primitive::MeshAttributes {
            indices: vec![[0, 0, 0]; n],
            ..Default::default()
        });
        g
    }

    #[test]
    fn resolution_follows_the_thesis_formula() {
        // 1000 primitives in a 2×1×1 box: cbrt(7000 / 2) ≈ 15.18 cells per unit.
        let dim = Vec3::new(2.0, 1.0, 1.0);
        let d = (LAMBDA * 1000.0 / 2.0).cbrt();
        assert_eq!(resolution(dim, d), [31, 16, 16]);
    }

    #[test]
    fn grid_agrees_with_brute_force_on_random_triangles() {
        let g = random_soup(2000, 3);
        let grid = Grid::build(&g);
        let st = grid.stats();
        assert!(st.cells > 1000, "{st:?}");
        let prims = g.all_prims();
        let mut r = Pcg32::new(11, 1);
        for k in 0..20000 {
            let o = Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 16.0 - 3.0;
            let d = Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) - 0.5;
            // Include axis-parallel rays, which exercise the zero-direction branches.
            let d = match k % 7 {
                0 => Vec3::new(d.x, 0.0, 0.0),
                1 => Vec3::new(0.0, d.y, d.z),
                _ => d,
            };
            if d == Vec3::ZERO {
                continue;
            }
            let mut ray = Ray::new(o, d);
            if k % 3 == 0 {
                ray.t_max = 5.0;
            }
            let brute = prims
                .iter()
                .fold((None, ray.t_max), |(best, t), &p| {
                    match g.intersect(p, &ray, t) {
                        Some(h) => (Some(h), h.t),
                        None => (best, t),
                    }
                })
                .0;
            let gh = grid.intersect(&g, &ray);
            assert_eq!(
                brute.map(|h| (h.t, h.prim)),
                gh.map(|h| (h.t, h.prim)),
                "ray {k}"
            );
            assert_eq!(brute.is_some(), grid.occluded(&g, &ray), "ray {k}");
        }
    }

    #[test]
    fn flat_and_empty_scenes_build() {
        let empty = Grid::build(&GeometryStore::default());
        assert!(
            empty
                .intersect(&GeometryStore::default(), &Ray::new(Vec3::ZERO, Vec3::Z))
                .is_none()
        );
        // All triangles in the plane z = 0.
        let mut g = random_soup(100, 5);
        for t in &mut g.triangles {
            t.p0.z = 0.0;
            t.p1.z = 0.0;
            t.p2.z = 0.0;
        }
        let grid = Grid::build(&g);
        assert!(grid.stats().cells >= 1);
        let hit = grid.intersect(&g, &Ray::new(Vec3::new(5.0, 5.0, 3.0), -Vec3::Z));
        let brute = g
            .all_prims()
            .iter()
            .filter_map(|&p| g.intersect(p, &Ray::new(Vec3::new(5.0, 5.0, 3.0), -Vec3::Z), 1e30))
            .map(|h| h.t)
            .fold(f32::INFINITY, f32::min);
        assert_eq!(hit.map(|h| h.t).unwrap_or(f32::INFINITY), brute);
        let _ = PrimitiveKind::Triangle;
    }

    #[test]
    fn degenerate_rays_terminate() {
        // They must end (the test would hang otherwise) and answer what brute force answers:
        // nothing for a zero or NaN direction, nothing for one denormal step along +x (the hit
        // distance overflows), and for +x with denormal y and z (the DDA's step per cell is then
        // astronomically large in y and z) the triangle it is aimed at (or one before it).
        let g = random_soup(200, 4);
        let grid = Grid::build(&g);
        let prims = g.all_prims();
        // From 5 units before the centroid of a triangle along −x: rays along +x meet it.
        let t = &g.triangles[0];
        let o = (t.p0 + t.p1 + t.p2) / 3.0 - Vec3::new(5.0, 0.0, 0.0);
        for (d, expect_hit) in [
            (Vec3::ZERO, Some(false)),
            (Vec3::splat(f32::NAN), Some(false)),
            (Vec3::new(f32::NAN, 1.0, 0.0), Some(false)),
            (Vec3::new(1e-45, 0.0, 0.0), None), // t = 5 / 1e-45 overflows: no hit either way
            (Vec3::new(1.0, 1e-45, -1e-45), Some(true)),
        ] {
            let r = Ray::new(o, d);
            let brute = prims
                .iter()
                .fold((None, r.t_max), |(best, t), &p| {
                    match g.intersect(p, &r, t) {
                        Some(h) => (Some(h), h.t),
                        None => (best, t),
                    }
                })
                .0;
            let hit = grid.intersect(&g, &r);
            assert_eq!(
                hit.map(|h| (h.t, h.prim)),
                brute.map(|h| (h.t, h.prim)),
                "direction {d}"
            );
            assert_eq!(grid.occluded(&g, &r), brute.is_some(), "direction {d}");
            if let Some(e) = expect_hit {
                assert_eq!(hit.is_some(), e, "direction {d}");
            }
        }
    }

    #[test]
    fn huge_overlapping_triangles_stay_within_the_reference_budget() {
        // Every triangle spans the whole scene: references would be N × cells without the budget.
        let mut g = random_soup(3000, 9);
        for (i, t) in g.triangles.iter_mut().enumerate() {
            let z = i as f32 * 0.003;
            t.p0 = Vec3::new(0.0, 0.0, z);
            t.p1 = Vec3::new(10.0, 0.0, z + 10.0);
            t.p2 = Vec3::new(0.0, 10.0, 10.0 - z);
        }
        let grid = Grid::build(&g);
        assert!(grid.stats().references as u64 <= (REF_FACTOR * 3000).max(1 << 20));
    }
}
