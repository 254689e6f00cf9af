//! Density grids of heterogeneous media: a 3D array of densities over a box, looked up with
//! trilinear interpolation between voxel centres (the texture convention of Mitsuba 3's
//! `gridvolume` and pbrt-v4's `SampledGrid`: voxel (i, j, k) sits at ((i+½)/nx, (j+½)/ny, (k+½)/nz)
//! of the box; between the outermost voxel centres and the box faces the edge values are held,
//! as Mitsuba's default `clamp` wrap mode does; outside the box the density is 0).
//!
//! Two sources: Mitsuba's binary `.vol` file (read by the loaders, [`crate::scene::vol::read_vol`]) and pbrt-v4's `uniformgrid` medium
//! (its `density` array, `nx ny nz` and bounds `p0 p1` — the importer builds a
//! [`crate::scene::MediumDesc`] directly). Both store x fastest: index = (z·ny + y)·nx + x.

use crate::geometry::Ray;
use crate::math::{Mat4, Vec3};
pub use crate::scene::GridEdge;
use crate::scene::vol::check_resolution;
pub use crate::scene::vol::{GridError, MAX_VOXELS};

/// A density grid placed in the world.
#[derive(Clone, Debug)]
pub struct DensityGrid {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    pub data: Vec<f32>,
    /// World → unit cube [0, 1]³ of the grid.
    world_to_unit: Mat4,
    /// The largest density: the majorant scale over the whole box.
    pub max_density: f32,
    /// Per-cell maxima of the density over a coarse grid of the box (see [`MajorantGrid`]).
    pub majorants: MajorantGrid,
    /// Lookups between the outermost voxel centres and the faces: held (Mitsuba) or fading to
    /// zero (pbrt-v4). The majorants hold for both: a blend with zeros is never larger.
    pub edge: GridEdge,
}

/// Cells per axis of the majorant grid (pbrt-v4's `MajorantGrid` uses 16³ for grid media).
pub const MAJORANT_RES: usize = 16;

/// A coarse grid over the density grid's unit cube, each cell holding a bound on the density
/// anywhere in it (pbrt-v4 §11.4.3, "Majorant grids"): delta and ratio tracking walk the cells
/// with a 3D DDA (Amanatides and Woo 1987) and sample free flights against each cell's own
/// majorant, so thin regions cost few null collisions.
#[derive(Clone, Debug)]
pub struct MajorantGrid {
    pub max: Vec<f32>,
}

impl MajorantGrid {
    #[inline]
    pub fn at(&self, x: usize, y: usize, z: usize) -> f32 {
        self.max[(z * MAJORANT_RES + y) * MAJORANT_RES + x]
    }
}

impl DensityGrid {
    /// `unit_to_world` maps the unit cube [0, 1]³ onto the grid's box in the world.
    pub fn new(
        nx: usize,
        ny: usize,
        nz: usize,
        data: Vec<f32>,
        unit_to_world: Mat4,
    ) -> Result<DensityGrid, GridError> {
        check_resolution(nx as i64, ny as i64, nz as i64)?;
        if data.len() != nx * ny * nz {
            return Err(GridError::Size {
                expected: (nx * ny * nz * 4) as u64,
                found: (data.len() * 4) as u64,
            });
        }
        if let Some((i, &v)) = data
            .iter()
            .enumerate()
            .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
        {
            return Err(GridError::Value(i, v));
        }
        let det = unit_to_world.determinant();
        if !crate::math::mat4_is_finite(&unit_to_world) || !det.is_normal() {
            return Err(GridError::Transform);
        }
        let world_to_unit = unit_to_world.inverse();
        if !crate::math::mat4_is_finite(&world_to_unit) {
            return Err(GridError::Transform);
        }
        let max_density = data.iter().copied().fold(0.0f32, f32::max);
        let majorants = majorant_grid(nx, ny, nz, &data);
        Ok(DensityGrid {
            nx,
            ny,
            nz,
            data,
            world_to_unit,
            max_density,
            majorants,
            edge: GridEdge::Hold,
        })
    }

    /// The same grid with lookups following `edge`.
    pub fn with_edge(mut self, edge: GridEdge) -> Self {
        self.edge = edge;
        self
    }

    /// World point `p` in the grid's unit cube [0, 1]³ (outside it when `p` is outside the box).
    #[inline]
    pub fn unit(&self, p: Vec3) -> Vec3 {
        self.world_to_unit.transform_point3(p)
    }

    /// The ray in the grid's unit-cube space: same parameter `t` as the world ray (the map is
    /// affine), direction not normalised.
    #[inline]
    pub fn to_unit(&self, ray: &Ray) -> (Vec3, Vec3) {
        (
            self.world_to_unit.transform_point3(ray.o),
            self.world_to_unit.transform_vector3(ray.d),
        )
    }

    /// Density at world point `p` (0 outside the box).
    #[inline]
    pub fn density(&self, p: Vec3) -> f32 {
        trilinear(
            self.nx,
            self.ny,
            self.nz,
            &self.data,
            self.unit(p),
            self.edge,
        )
    }

    /// The part of `ray` over `[0, t_max)` inside the grid's box, as a parameter interval.
    pub fn clip(&self, ray: &Ray, t_max: f32) -> Option<(f32, f32)> {
        let (o, d) = self.to_unit(ray);
        clip_unit(o, d, t_max)
    }
}

/// Trilinear lookup of an `nx·ny·nz` grid (x fastest) at unit-cube point `q`, voxel (i, j, k)
/// sitting at ((i+½)/nx, (j+½)/ny, (k+½)/nz); 0 outside [0, 1]³. Between the outermost voxel
/// centres and the faces `edge` decides: [`GridEdge::Hold`] clamps the indices (Mitsuba's `clamp`
/// wrap mode), [`GridEdge::Zero`] blends with zeros beyond the grid (pbrt-v4 `SampledGrid::Lookup`).
#[inline]
pub fn trilinear(nx: usize, ny: usize, nz: usize, data: &[f32], q: Vec3, edge: GridEdge) -> f32 {
    if !(q.cmpge(Vec3::ZERO).all() && q.cmple(Vec3::ONE).all()) {
        return 0.0;
    }
    // Per axis: the two voxel indices blended and the weight of the second; an index of `n`
    // (or the wrapped −1) is a sample outside the grid, which reads as 0 under `Zero`.
    let coord = |v: f32, n: usize| -> (usize, usize, f32) {
        let x = v * n as f32 - 0.5;
        match edge {
            GridEdge::Hold => {
                let x = x.clamp(0.0, (n - 1) as f32);
                let i0 = (x.floor() as usize).min(n - 1);
                (i0, (i0 + 1).min(n - 1), x - i0 as f32)
            }
            GridEdge::Zero => {
                let f = x.floor();
                // f ≥ −1 since v ≥ 0; −1 is stored as `usize::MAX` (out of range).
                let i0 = if f < 0.0 { usize::MAX } else { f as usize };
                (i0, i0.wrapping_add(1), x - f)
            }
        }
    };
    let (x0, x1, fx) = coord(q.x, nx);
    let (y0, y1, fy) = coord(q.y, ny);
    let (z0, z1, fz) = coord(q.z, nz);
    let at = |x: usize, y: usize, z: usize| -> f32 {
        if x < nx && y < ny && z < nz {
            data[(z * ny + y) * nx + x]
        } else {
            0.0
        }
    };
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let c00 = lerp(at(x0, y0, z0), at(x1, y0, z0), fx);
    let c10 = lerp(at(x0, y1, z0), at(x1, y1, z0), fx);
    let c01 = lerp(at(x0, y0, z1), at(x1, y0, z1), fx);
    let c11 = lerp(at(x0, y1, z1), at(x1, y1, z1), fx);
    lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz)
}

/// The parameter interval of the unit-space ray `o + t·d`, `t` in `[0, t_max)`, inside [0, 1]³.
#[inline]
pub fn clip_unit(o: Vec3, d: Vec3, t_max: f32) -> Option<(f32, f32)> {
    let (mut t0, mut t1) = (0.0f32, t_max);
    for a in 0..3 {
        let inv = 1.0 / d[a];
        let (mut ta, mut tb) = ((0.0 - o[a]) * inv, (1.0 - o[a]) * inv);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        if ta.is_nan() || tb.is_nan() {
            // Parallel to the slab: inside it or not.
            if o[a] < 0.0 || o[a] > 1.0 {
                return None;
            }
            continue;
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
        if t0 >= t1 {
            return None;
        }
    }
    Some((t0, t1))
}

/// Builds the majorant grid of a density grid: the bound of a cell is the largest voxel among
/// those the trilinear lookup can blend anywhere in the cell (voxel centres at (i+½)/n, so a
/// point at unit coordinate u blends voxels ⌊u·n − ½⌋ and the next, clamped to the grid — the
/// range pbrt-v4's `SampledGrid::MaxValue` takes). The cell is widened by 10⁻⁴ of the box on
/// each side first: a collision point computed in world space and mapped back can land a
/// rounding error outside the cell the DDA is in, and its density must still be under the
/// bound (a density above the majorant would make a negative null coefficient, i.e. bias).
fn majorant_grid(nx: usize, ny: usize, nz: usize, data: &[f32]) -> MajorantGrid {
    const PAD: f32 = 1e-4;
    let range = |c: usize, n: usize| -> (usize, usize) {
        let lo = (c as f32 / MAJORANT_RES as f32 - PAD) * n as f32 - 0.5;
        let hi = ((c + 1) as f32 / MAJORANT_RES as f32 + PAD) * n as f32 - 0.5;
        let clamp = |v: f32| (v.floor().max(0.0) as usize).min(n - 1);
        (clamp(lo), (clamp(hi) + 1).min(n - 1))
    };
    let mut max = vec![0.0f32; MAJORANT_RES * MAJORANT_RES * MAJORANT_RES];
    for cz in 0..MAJORANT_RES {
        let (z0, z1) = range(cz, nz);
        for cy in 0..MAJORANT_RES {
            let (y0, y1) = range(cy, ny);
            for cx in 0..MAJORANT_RES {
                let (x0, x1) = range(cx, nx);
                let mut m = 0.0f32;
                for z in z0..=z1 {
                    for y in y0..=y1 {
                        let row = (z * ny + y) * nx;
                        for &v in &data[row + x0..=row + x1] {
                            m = m.max(v);
                        }
                    }
                }
                max[(cz * MAJORANT_RES + cy) * MAJORANT_RES + cx] = m;
            }
        }
    }
    MajorantGrid { max }
}

/// A 3D DDA through the majorant grid's cells along a unit-space ray (Amanatides and Woo 1987;
/// pbrt-v4's `DDAMajorantIterator`): each call to [`Dda::next`] gives the next cell's parameter
/// interval and its density bound.
#[derive(Clone, Copy, Debug)]
pub struct Dda {
    t_min: f32,
    t_max: f32,
    next_crossing: [f32; 3],
    delta_t: [f32; 3],
    step: [i32; 3],
    limit: [i32; 3],
    cell: [i32; 3],
}

impl Dda {
    /// The walk over `[t0, t1]`, the part of the unit-space ray `o + t·d` inside [0, 1]³.
    pub fn new(o: Vec3, d: Vec3, t0: f32, t1: f32) -> Dda {
        let res = MAJORANT_RES as f32;
        let p = (o + d * t0) * res;
        let mut dda = Dda {
            t_min: t0,
            t_max: t1,
            next_crossing: [f32::INFINITY; 3],
            delta_t: [f32::INFINITY; 3],
            step: [1; 3],
            limit: [MAJORANT_RES as i32; 3],
            cell: [0; 3],
        };
        for a in 0..3 {
            let c = (p[a].floor() as i32).clamp(0, MAJORANT_RES as i32 - 1);
            dda.cell[a] = c;
            // A zero component (either sign) never crosses a plane on this axis.
            if d[a] == 0.0 {
                continue;
            }
            dda.delta_t[a] = 1.0 / (d[a].abs() * res);
            if d[a] > 0.0 {
                dda.next_crossing[a] = t0 + ((c + 1) as f32 - p[a]) / (d[a] * res);
            } else {
                dda.next_crossing[a] = t0 + (c as f32 - p[a]) / (d[a] * res);
                dda.step[a] = -1;
                dda.limit[a] = -1;
            }
        }
        dda
    }

    /// The next cell: its parameter interval `[t0, t1)` and its density bound.
    #[inline]
    pub fn next(&mut self, grid: &MajorantGrid) -> Option<(f32, f32, f32)> {
        if !(self.t_min < self.t_max) {
            return None;
        }
        let nc = self.next_crossing;
        let axis = if nc[0] < nc[1] {
            if nc[0] < nc[2] { 0 } else { 2 }
        } else if nc[1] < nc[2] {
            1
        } else {
            2
        };
        let t0 = self.t_min;
        let t1 = self.t_max.min(nc[axis]);
        let bound = grid.at(
            self.cell[0] as usize,
            self.cell[1] as usize,
            self.cell[2] as usize,
        );
        self.t_min = t1;
        self.cell[axis] += self.step[axis];
        if self.cell[axis] == self.limit[axis] {
            self.t_min = self.t_max;
        }
        self.next_crossing[axis] += self.delta_t[axis];
        Some((t0, t1, bound))
    }
}

/// The matrix mapping the unit cube onto the axis-aligned box [min, max].
pub fn box_to_world(min: Vec3, max: Vec3) -> Mat4 {
    Mat4::from_translation(min) * Mat4::from_scale(max - min)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The DDA's cells tile the ray's part inside the box without gaps, and every cell's bound is
    /// at least the density anywhere along the ray in it (a density above its majorant would
    /// bias tracking); a grid that is empty but for one voxel has only the cells around it
    /// non-zero (a single global majorant would fail this).
    #[test]
    fn majorant_cells_bound_the_density_and_tile_the_ray() {
        let (nx, ny, nz) = (7, 5, 19);
        let mut rng = crate::sampling::rng::Pcg32::new(11, 3);
        let data: Vec<f32> = (0..nx * ny * nz)
            .map(|_| {
                let u = rng.next_f32();
                if u < 0.3 { 0.0 } else { u * u * 4.0 }
            })
            .collect();
        let to_world = Mat4::from_scale_rotation_translation(
            Vec3::new(1.5, 0.7, 2.2),
            glam::Quat::from_rotation_y(0.4),
            Vec3::new(-0.3, 0.2, 0.1),
        );
        let g = DensityGrid::new(nx, ny, nz, data, to_world).unwrap();
        let mut cells_seen = 0;
        for _ in 0..400 {
            let o = Vec3::new(
                rng.next_f32() * 8.0 - 4.0,
                rng.next_f32() * 8.0 - 4.0,
                rng.next_f32() * 8.0 - 4.0,
            );
            let target = to_world.transform_point3(Vec3::new(
                rng.next_f32(),
                rng.next_f32(),
                rng.next_f32(),
            ));
            let ray = Ray::new(o, (target - o).normalize());
            let Some((t0, t1)) = g.clip(&ray, f32::INFINITY) else {
                continue;
            };
            let (uo, ud) = g.to_unit(&ray);
            let mut dda = Dda::new(uo, ud, t0, t1);
            let mut t = t0;
            while let Some((a, b, bound)) = dda.next(&g.majorants) {
                assert!(
                    (a - t).abs() <= 1e-5 * t1.abs().max(1.0),
                    "gap at {t}: next cell at {a}"
                );
                assert!(b >= a);
                for k in 0..=8 {
                    let s = a + (b - a) * k as f32 / 8.0;
                    let d = g.density(ray.at(s));
                    assert!(d <= bound, "density {d} above its cell's majorant {bound}");
                }
                t = b;
                cells_seen += 1;
            }
            assert!(
                (t - t1).abs() <= 1e-5 * t1.abs().max(1.0),
                "walk ends at {t}, not {t1}"
            );
        }
        assert!(cells_seen > 2000, "too few cells walked ({cells_seen})");

        let n = 32;
        let mut data = vec![0.0f32; n * n * n];
        data[(17 * n + 9) * n + 22] = 5.0;
        let g = DensityGrid::new(n, n, n, data, Mat4::IDENTITY).unwrap();
        let nonzero = g.majorants.max.iter().filter(|&&m| m > 0.0).count();
        assert!(
            (1..=27).contains(&nonzero),
            "{nonzero} of 4096 majorant cells are non-zero for one voxel"
        );
        assert_eq!(g.majorants.max.iter().copied().fold(0.0, f32::max), 5.0);
    }

    #[test]
    fn trilinear_lookup_hits_voxel_centres_and_is_zero_outside() {
        let v = crate::scene::vol::VolFile {
            nx: 2,
            ny: 3,
            nz: 2,
            data: (0..12).map(|i| i as f32 * 0.5).collect(),
            bbox_min: Vec3::new(-1.0, 0.0, 2.0),
            bbox_max: Vec3::new(1.0, 3.0, 4.0),
        };
        let g = DensityGrid::new(
            v.nx,
            v.ny,
            v.nz,
            v.data.clone(),
            box_to_world(v.bbox_min, v.bbox_max),
        )
        .unwrap();
        let ext = v.bbox_max - v.bbox_min;
        for z in 0..2 {
            for y in 0..3 {
                for x in 0..2 {
                    let q = Vec3::new(
                        (x as f32 + 0.5) / 2.0,
                        (y as f32 + 0.5) / 3.0,
                        (z as f32 + 0.5) / 2.0,
                    );
                    let p = v.bbox_min + q * ext;
                    let want = v.data[(z * 3 + y) * 2 + x];
                    assert!((g.density(p) - want).abs() < 1e-5, "voxel {x},{y},{z}");
                }
            }
        }
        // Halfway between two x-neighbours: the mean.
        let p = v.bbox_min + Vec3::new(0.5, 0.5 / 3.0, 0.25) * ext;
        assert!((g.density(p) - 0.25).abs() < 1e-5);
        assert_eq!(g.density(Vec3::new(5.0, 1.0, 3.0)), 0.0);
        assert_eq!(g.max_density, 5.5);
        let r = Ray::new(Vec3::new(-3.0, 1.0, 3.0), Vec3::X);
        let (t0, t1) = g.clip(&r, f32::INFINITY).unwrap();
        assert!((t0 - 2.0).abs() < 1e-5 && (t1 - 4.0).abs() < 1e-5);
        assert!(g.clip(&r, 1.5).is_none());
        assert!(
            DensityGrid::new(1, 1, 1, vec![f32::NAN], Mat4::IDENTITY).is_err(),
            "NaN density"
        );
        assert!(DensityGrid::new(1, 1, 1, vec![1.0], Mat4::ZERO).is_err());
    }

    /// pbrt-v4's `SampledGrid::Lookup` reads voxels outside the grid as 0: a 1×1×1 grid of 1
    /// (pbrt-v4's default `Lescale`) is 1 at the centre, ½ at a face's centre, ⅛ at a corner,
    /// (1 − |u − ½|)(…)(…) in between; `Hold` keeps it 1 up to the faces. Expected values are
    /// computed from pbrt-v4's formula by hand, not by the code under test.
    #[test]
    fn zero_edge_fades_to_the_faces_as_pbrt_v4() {
        let one = [1.0f32];
        let tent = |u: f32| 1.0 - (u - 0.5).abs();
        for q in [
            Vec3::splat(0.5),
            Vec3::new(0.5, 0.5, 1.0),
            Vec3::ZERO,
            Vec3::new(0.1, 0.7, 0.35),
            Vec3::new(0.95, 0.2, 0.5),
        ] {
            let z = trilinear(1, 1, 1, &one, q, GridEdge::Zero);
            let want = tent(q.x) * tent(q.y) * tent(q.z);
            assert!((z - want).abs() < 1e-6, "{q}: {z} vs {want}");
            assert_eq!(trilinear(1, 1, 1, &one, q, GridEdge::Hold), 1.0);
        }
        // A 2×1×1 ramp [2, 4]: between the centres (¼, ¾) both rules lerp; outside them Zero
        // blends with 0 (at u = 0.1: x = −0.3 → 0.7·2·(tent in y, z = 1)), Hold keeps 2.
        let d = [2.0f32, 4.0];
        let at = |u: f32, e| trilinear(2, 1, 1, &d, Vec3::new(u, 0.5, 0.5), e);
        assert!((at(0.5, GridEdge::Zero) - 3.0).abs() < 1e-6);
        assert!((at(0.5, GridEdge::Hold) - 3.0).abs() < 1e-6);
        assert!((at(0.1, GridEdge::Zero) - 0.7 * 2.0).abs() < 1e-5);
        assert!((at(0.9, GridEdge::Zero) - 0.7 * 4.0).abs() < 1e-5);
        assert_eq!(at(0.1, GridEdge::Hold), 2.0);
        assert_eq!(at(1.0, GridEdge::Zero), 2.0); // half of the edge voxel at the face
        assert_eq!(at(1.01, GridEdge::Zero), 0.0);
    }
}
