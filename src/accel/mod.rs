//! Acceleration structures: the thing that answers "what does this ray hit first?" and "is this
//! segment blocked?". A binned-SAH BVH is the default; brute force (`none`) is kept as the ground
//! truth every other structure must agree with.

pub mod bvh;
pub mod grid;
pub mod split;

pub use bvh::Bvh;
pub use grid::Grid;

use crate::geometry::primitive::Intersection;
use crate::geometry::{GeometryStore, PrimRef, Ray};

/// Which acceleration structure to build (`--accel`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AccelKind {
    #[default]
    Bvh,
    /// Test every primitive: slow, but trivially correct.
    None,
    /// The thesis's uniform grid with 3D-DDA traversal (§5.3.6).
    Grid,
}

impl std::str::FromStr for AccelKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "bvh" => Ok(AccelKind::Bvh),
            "none" => Ok(AccelKind::None),
            "grid" => Ok(AccelKind::Grid),
            other => Err(format!(
                "unknown accelerator '{other}' (expected bvh, grid or none)"
            )),
        }
    }
}

pub enum Accel {
    Bvh(Bvh),
    None(Vec<PrimRef>),
    Grid(Grid),
}

impl Accel {
    pub fn build(kind: AccelKind, geometry: &GeometryStore) -> Accel {
        match kind {
            AccelKind::Bvh => Accel::Bvh(Bvh::build(geometry)),
            AccelKind::None => Accel::None(geometry.all_prims()),
            AccelKind::Grid => Accel::Grid(Grid::build(geometry)),
        }
    }

    /// One line for reports: the structure and its size.
    pub fn describe(&self) -> String {
        match self {
            Accel::Bvh(b) => {
                let s = b.stats();
                format!(
                    "bvh ({} nodes, {} references, {} in leaves, {} packets ({} leaves of two), SAH cost {:.1})",
                    s.nodes, s.references, s.leaf_prims, s.packets, s.two_packet_leaves, s.sah_cost
                )
            }
            Accel::None(p) => format!("none ({} primitives tested per ray)", p.len()),
            Accel::Grid(g) => {
                let s = g.stats();
                format!(
                    "grid {}x{}x{} ({} cells, {} empty, {} references)",
                    s.res[0], s.res[1], s.res[2], s.cells, s.empty_cells, s.references
                )
            }
        }
    }

    /// Closest hit along the ray within `(0, ray.t_max)`: the structure's over the flat
    /// primitives, then the instanced meshes' two-level hierarchy (if any) up to that hit.
    #[inline]
    pub fn intersect(&self, geometry: &GeometryStore, ray: &Ray) -> Option<Intersection> {
        let flat = self.intersect_flat(geometry, ray);
        if geometry.instances.is_empty() {
            return flat;
        }
        // Strictly nearer only: at equal `t` the flat primitive, whose index is lower, wins, as
        // the ranking of one structure would decide.
        let t_max = flat.map_or(ray.t_max, |h| h.t);
        geometry.instances.intersect(ray, t_max).or(flat)
    }

    #[inline]
    fn intersect_flat(&self, geometry: &GeometryStore, ray: &Ray) -> Option<Intersection> {
        match self {
            Accel::Bvh(b) => b.intersect(geometry, ray),
            Accel::None(prims) => {
                let mut best: Option<Intersection> = None;
                let mut t_max = ray.t_max;
                for &p in prims {
                    if let Some(h) = geometry.intersect(p, ray, t_max) {
                        t_max = h.t;
                        best = Some(h);
                    }
                }
                best
            }
            Accel::Grid(g) => g.intersect(geometry, ray),
        }
    }

    /// Any hit within `(0, ray.t_max)`: for shadow rays.
    #[inline]
    pub fn occluded(&self, geometry: &GeometryStore, ray: &Ray) -> bool {
        self.occluded_flat(geometry, ray)
            || (!geometry.instances.is_empty() && geometry.instances.occluded(ray, ray.t_max))
    }

    #[inline]
    fn occluded_flat(&self, geometry: &GeometryStore, ray: &Ray) -> bool {
        match self {
            Accel::Bvh(b) => b.occluded(geometry, ray),
            Accel::None(prims) => prims
                .iter()
                .any(|&p| geometry.intersect(p, ray, ray.t_max).is_some()),
            Accel::Grid(g) => g.occluded(geometry, ray),
        }
    }
}
