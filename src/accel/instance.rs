//! The two-level hierarchy over instanced meshes (`geometry::instance`): a BVH per shared mesh
//! over its triangles' padded object-space boxes (the bottom level) and a BVH over the instances'
//! world boxes (the top level). A world ray enters an instance through the inverse transform only
//! to cull boxes; each candidate triangle is then tested in world space, on the vertices the
//! flattening would store, so hits have the flattened scene's bits (see `geometry::instance`).
//! A moving instance (motion blur) is met where it is at the ray's time: its transform
//! interpolated at that time both takes the ray to object space and places the triangles, as
//! pbrt-v4 transforms a ray into an animated instance's space.

use super::Bvh;
use crate::geometry::instance::{InstanceStore, object_ray};
use crate::geometry::primitive::Intersection;
use crate::geometry::{PrimRef, PrimitiveKind, Ray};

/// The bottom- and top-level BVHs of an [`InstanceStore`]; empty when nothing is instanced.
#[derive(Clone, Debug, Default)]
pub struct InstanceBvh {
    /// One per shared mesh, over `PrimRef::Triangle(triangle index in the mesh)`.
    bottom: Vec<Bvh>,
    /// Over `PrimRef::Triangle(instance index)` with the instances' world boxes: one, or with
    /// moving instances one per key segment of the shutter, a moving instance boxed over its
    /// segment ([`InstanceStore::segment_bounds`]); a ray walks the one of its time's segment.
    top: Vec<Bvh>,
}

impl InstanceBvh {
    pub fn build(store: &InstanceStore) -> InstanceBvh {
        if store.is_empty() {
            return InstanceBvh::default();
        }
        let bottom = store
            .meshes
            .iter()
            .map(|mesh| {
                let prims = (0..mesh.attrs.indices.len() as u32)
                    .map(|j| PrimRef::new(PrimitiveKind::Triangle, j))
                    .collect();
                Bvh::build_from(prims, |p| mesh.triangle_bounds(p.index()))
            })
            .collect();
        let prims: Vec<PrimRef> = (0..store.instances.len() as u32)
            .map(|k| PrimRef::new(PrimitiveKind::Triangle, k))
            .collect();
        let top = match store.segments() {
            0 => vec![Bvh::build_from(prims, |p| {
                store.instances[p.index()].bounds
            })],
            n => (0..n)
                .map(|seg| Bvh::build_from(prims.clone(), |p| store.segment_bounds(p.index(), seg)))
                .collect(),
        };
        InstanceBvh { bottom, top }
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.top.is_empty()
    }

    /// The top level a ray at shutter time `u` walks.
    #[inline]
    fn top_at(&self, store: &InstanceStore, u: f32) -> Option<&Bvh> {
        if self.top.len() == 1 {
            return self.top.first();
        }
        self.top.get(store.segment(u))
    }

    /// Bytes held by both levels, for reports.
    pub fn heap_bytes(&self) -> usize {
        self.bottom.iter().map(Bvh::heap_bytes).sum::<usize>()
            + self.top.iter().map(Bvh::heap_bytes).sum::<usize>()
    }

    /// The closest instanced triangle along `ray` before `t_max`.
    #[inline]
    pub fn intersect(&self, store: &InstanceStore, ray: &Ray, t_max: f32) -> Option<Intersection> {
        let top = self.top_at(store, ray.time)?;
        top.closest_with(ray, t_max, |p, bound| {
            let inst = store.at(&store.instances[p.index()], ray.time);
            let inst = &*inst;
            let local = object_ray(inst, ray);
            self.bottom[inst.mesh as usize].closest_with(&local, bound, |tri, bound| {
                let (verts, _) = store.world_triangle(inst, tri.index());
                verts.intersect(ray, bound).map(|h| Intersection {
                    t: h.t,
                    prim: PrimRef::new(PrimitiveKind::Triangle, inst.base + tri.index() as u32),
                    u: h.b1,
                    v: h.b2,
                })
            })
        })
    }

    /// True if an instanced triangle lies on `ray` before `t_max`.
    #[inline]
    pub fn occluded(&self, store: &InstanceStore, ray: &Ray, t_max: f32) -> bool {
        let Some(top) = self.top_at(store, ray.time) else {
            return false;
        };
        top.any_with(ray, t_max, |p, bound| {
            let inst = store.at(&store.instances[p.index()], ray.time);
            let inst = &*inst;
            let local = object_ray(inst, ray);
            self.bottom[inst.mesh as usize].any_with(&local, bound, |tri, bound| {
                let (verts, _) = store.world_triangle(inst, tri.index());
                verts.intersect(ray, bound).is_some()
            })
        })
    }
}
