//! A hashed uniform grid over points (photons, light-subpath vertices) for fixed-radius
//! queries: the density estimation of photon mapping (Jensen 1996; progressive and stochastic
//! progressive photon mapping, Hachisuka et al. 2008, Hachisuka & Jensen 2009) and the merges of
//! vertex connection and merging (Georgiev et al. 2012).
//!
//! Built by a counting sort of the point indices by the hash of their cell, in index order, so a
//! bucket lists its points in increasing index: the grid, and the order in which a query visits
//! the points, is a function of the point list alone (not of which thread stored which point),
//! which is what keeps the photon integrators' images a pure function of the seed.
//!
//! Distinct cells may share a bucket (the table is a hash, not a dense array): a query checks
//! each point's own cell against the cell it is visiting, so a point is reported once however
//! the cells of the query's box collide.

use crate::math::Vec3;

/// The grid over a list of points (kept by the caller; the grid holds their indices).
#[derive(Clone, Debug, Default)]
pub struct PointGrid {
    inv_cell: f32,
    /// Table size − 1 (a power of two).
    mask: usize,
    /// Bucket b's point indices are `indices[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    indices: Vec<u32>,
}

#[inline]
fn cell_of(p: Vec3, inv_cell: f32) -> [i32; 3] {
    [
        (p.x * inv_cell).floor() as i32,
        (p.y * inv_cell).floor() as i32,
        (p.z * inv_cell).floor() as i32,
    ]
}

/// Teschner et al. 2003's spatial hash of a cell.
#[inline]
fn hash_cell(c: [i32; 3]) -> usize {
    ((c[0] as u32).wrapping_mul(73_856_093)
        ^ (c[1] as u32).wrapping_mul(19_349_663)
        ^ (c[2] as u32).wrapping_mul(83_492_791)) as usize
}

impl PointGrid {
    /// A grid of cubic cells of side `cell` (> 0) over `points`. Non-finite points are left out.
    pub fn build(points: &[Vec3], cell: f32) -> PointGrid {
        let inv_cell = if cell > 0.0 && cell.is_finite() {
            1.0 / cell
        } else {
            1.0
        };
        let size = (2 * points.len()).next_power_of_two().max(1);
        let mask = size - 1;
        let bucket = |p: Vec3| hash_cell(cell_of(p, inv_cell)) & mask;
        let mut starts = vec![0u32; size + 1];
        for p in points.iter().filter(|p| p.is_finite()) {
            starts[bucket(*p) + 1] += 1;
        }
        for b in 0..size {
            starts[b + 1] += starts[b];
        }
        let mut fill = starts.clone();
        let mut indices = vec![0u32; starts[size] as usize];
        for (i, p) in points.iter().enumerate() {
            if p.is_finite() {
                let b = bucket(*p);
                indices[fill[b] as usize] = i as u32;
                fill[b] += 1;
            }
        }
        PointGrid {
            inv_cell,
            mask,
            starts,
            indices,
        }
    }

    /// Calls `f(i)` once for every point `points[i]` (the list the grid was built over) within
    /// distance `r` of `p` (`|points[i] − p|² ≤ r²`), cell by cell, in increasing index within a
    /// cell.
    #[inline]
    pub fn for_each_within(&self, points: &[Vec3], p: Vec3, r: f32, mut f: impl FnMut(usize)) {
        if self.indices.is_empty() || !(r >= 0.0) || !p.is_finite() {
            return;
        }
        let lo = cell_of(p - Vec3::splat(r), self.inv_cell);
        let hi = cell_of(p + Vec3::splat(r), self.inv_cell);
        let r2 = r * r;
        for cz in lo[2]..=hi[2] {
            for cy in lo[1]..=hi[1] {
                for cx in lo[0]..=hi[0] {
                    let c = [cx, cy, cz];
                    let b = hash_cell(c) & self.mask;
                    let (s, e) = (self.starts[b] as usize, self.starts[b + 1] as usize);
                    for &i in &self.indices[s..e] {
                        let q = points[i as usize];
                        // Another cell hashed to this bucket: its points are visited with it.
                        if cell_of(q, self.inv_cell) != c {
                            continue;
                        }
                        if (q - p).length_squared() <= r2 {
                            f(i as usize);
                        }
                    }
                }
            }
        }
    }
}
