//! Acceleration structures: the thing that answers "what does this ray hit first?" and "is this
//! segment blocked?". A binned-SAH BVH is the default; brute force (`none`) is kept as the ground
//! truth every other structure must agree with.

pub mod bvh;
pub mod grid;
pub mod instance;
pub mod split;

pub use bvh::Bvh;
pub use grid::Grid;
pub use instance::InstanceBvh;

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

impl AccelKind {
    /// The name `--accel` takes (what `FromStr` parses back).
    pub fn name(self) -> &'static str {
        match self {
            AccelKind::Bvh => "bvh",
            AccelKind::None => "none",
            AccelKind::Grid => "grid",
        }
    }

    /// Every accelerator, for front ends that list the choices.
    pub const ALL: [AccelKind; 3] = [AccelKind::Bvh, AccelKind::Grid, AccelKind::None];
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

/// The structure over the flat primitives, and the two-level hierarchy over the instanced
/// meshes (empty for most scenes).
pub struct Accel {
    flat: FlatAccel,
    instances: InstanceBvh,
    /// Motion blur: per key segment of the shutter, a BVH over the moving primitives
    /// ([`GeometryStore::motion`]), each boxed over that segment, whose leaves test the
    /// primitive where it is at the ray's time; a ray walks its segment's. The still
    /// primitives keep the structure above, as in a still world. Empty for a still.
    moving: Vec<Bvh>,
}

enum FlatAccel {
    Bvh(Bvh),
    None(Vec<PrimRef>),
    Grid(Grid),
}

impl Accel {
    pub fn build(kind: AccelKind, geometry: &GeometryStore) -> Accel {
        let flat = match kind {
            AccelKind::Bvh => FlatAccel::Bvh(Bvh::build(geometry)),
            AccelKind::None => FlatAccel::None(geometry.static_prims()),
            AccelKind::Grid => FlatAccel::Grid(Grid::build(geometry)),
        };
        let segments = geometry.motion.as_ref().map_or(0, |m| m.keys - 1);
        let moving = (0..segments)
            .map(|k| {
                Bvh::build_from(geometry.moving_prims.clone(), |p| {
                    geometry.sweep_bounds(p, k)
                })
            })
            .collect();
        Accel {
            flat,
            instances: InstanceBvh::build(&geometry.instances),
            moving,
        }
    }

    /// One line for reports: the structure and its size.
    pub fn describe(&self) -> String {
        match &self.flat {
            FlatAccel::Bvh(b) => {
                let s = b.stats();
                format!(
                    "bvh ({} nodes, {} references, {} in leaves, {} packets ({} leaves of two), SAH cost {:.1})",
                    s.nodes, s.references, s.leaf_prims, s.packets, s.two_packet_leaves, s.sah_cost
                )
            }
            FlatAccel::None(p) => format!("none ({} primitives tested per ray)", p.len()),
            FlatAccel::Grid(g) => {
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
        let near = if self.instances.is_empty() {
            flat
        } else {
            // Strictly nearer only: at equal `t` the flat primitive, whose index is lower, wins,
            // as the ranking of one structure would decide.
            let t_max = flat.map_or(ray.t_max, |h| h.t);
            self.instances
                .intersect(&geometry.instances, ray, t_max)
                .or(flat)
        };
        match self.segment_bvh(geometry, ray) {
            None => near,
            Some(b) => {
                let t_max = near.map_or(ray.t_max, |h| h.t);
                b.closest_with(ray, t_max, |p, bound| {
                    geometry.intersect_moving(p, ray, bound)
                })
                .or(near)
            }
        }
    }

    /// The moving primitives' BVH of the key segment holding `ray`'s time, if any move.
    #[inline]
    fn segment_bvh(&self, geometry: &GeometryStore, ray: &Ray) -> Option<&Bvh> {
        let m = geometry.motion.as_ref()?;
        self.moving.get(m.segment(ray.time).0)
    }

    #[inline]
    fn intersect_flat(&self, geometry: &GeometryStore, ray: &Ray) -> Option<Intersection> {
        match &self.flat {
            FlatAccel::Bvh(b) => b.intersect(geometry, ray),
            FlatAccel::None(prims) => {
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
            FlatAccel::Grid(g) => g.intersect(geometry, ray),
        }
    }

    /// Any hit within `(0, ray.t_max)`: for shadow rays.
    #[inline]
    pub fn occluded(&self, geometry: &GeometryStore, ray: &Ray) -> bool {
        self.occluded_flat(geometry, ray)
            || (!self.instances.is_empty()
                && self.instances.occluded(&geometry.instances, ray, ray.t_max))
            || self.segment_bvh(geometry, ray).is_some_and(|b| {
                b.any_with(ray, ray.t_max, |p, bound| {
                    geometry.intersect_moving(p, ray, bound).is_some()
                })
            })
    }

    #[inline]
    fn occluded_flat(&self, geometry: &GeometryStore, ray: &Ray) -> bool {
        match &self.flat {
            FlatAccel::Bvh(b) => b.occluded(geometry, ray),
            FlatAccel::None(prims) => prims
                .iter()
                .any(|&p| geometry.intersect(p, ray, ray.t_max).is_some()),
            FlatAccel::Grid(g) => g.occluded(geometry, ray),
        }
    }
}
