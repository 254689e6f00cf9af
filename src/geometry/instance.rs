//! Instances: objects that place one shared mesh several times keep a single object-space copy
//! of it, so memory grows with the unique geometry instead of with the copies (pbrt-v4's
//! `ObjectInstance`, glTF meshes used by several nodes). This module holds the shared meshes and
//! their placements; the two-level hierarchy over them (a BVH per shared mesh, one over the
//! instances' world boxes) is the accelerator's (`accel::instance`). docs/DESIGN.md §5
//! (acceleration) says when a mesh is instanced.
//!
//! Bit-identical to the flattened scene by construction where it matters: an instanced triangle
//! is tested, and its hit expanded, on world-space vertices computed on the fly with the very
//! operations the flattening applies (`Mat4::transform_point3` of each vertex, the mirrored
//! winding of a negative-determinant transform, normals through the inverse transpose and
//! normalised per vertex, tangents likewise), so `t`, the barycentrics and every shading
//! attribute have the flattened scene's bits. Only the culling of the bottom level runs in object
//! space (the world ray taken through the inverse transform); its boxes are padded so that the
//! rounding of that ray cannot cull a triangle the world-space ray hits.
//!
//! An instanced triangle is named by a primitive index past the flat triangles (its *virtual*
//! index: the instance's `base` plus the triangle's index in the mesh), so hits, materials and
//! reports keep the one `PrimRef` form.

use std::borrow::Cow;

use super::mesh::MeshAttributes;
use super::motion::{KeyedTransform, STILL, key_segment};
use super::triangle::TriangleVerts;
use super::{Bounds3, Ray};
use crate::math::{Mat3, Mat4, Vec3, Vec4, transform_normal};

/// Relative padding of the bottom-level boxes (of the mesh's extent and its distance from the
/// object's origin): the object-space ray is the world ray through the inverse transform, a few
/// roundings off, and a triangle grazed by the world ray must still have its box entered.
const OBJECT_BOX_PADDING: f32 = 1e-4;

/// One shared mesh in object space: vertices and attributes as the file gave them (normals and
/// tangents untransformed).
#[derive(Clone, Debug)]
pub struct SharedMesh {
    pub positions: Vec<Vec3>,
    /// Indices in the file's winding; `material` is unused (each instance has its own).
    pub attrs: MeshAttributes,
    /// The padding of the boxes of its triangles in the bottom-level BVH.
    pub pad: f32,
    /// The box of its vertices (unpadded), which a moving instance's boxes hold over the
    /// shutter ([`KeyedTransform::segment_bounds`]).
    pub extent: Bounds3,
}

impl SharedMesh {
    /// A shared mesh of `positions` / `attrs` (object space).
    pub fn new(positions: Vec<Vec3>, attrs: MeshAttributes) -> SharedMesh {
        let extent = attrs
            .indices
            .iter()
            .flatten()
            .fold(Bounds3::EMPTY, |b, &v| b.union_point(positions[v as usize]));
        let pad = if extent.is_empty() {
            0.0
        } else {
            let reach = extent.min.abs().max(extent.max.abs()).max_element();
            OBJECT_BOX_PADDING * (reach + extent.diagonal().max_element())
        };
        SharedMesh {
            positions,
            attrs,
            pad,
            extent,
        }
    }

    /// The padded object-space box of triangle `j` (for the bottom-level BVH).
    pub fn triangle_bounds(&self, j: usize) -> Bounds3 {
        let [a, b, c] = self.attrs.indices[j].map(|v| self.positions[v as usize]);
        let bounds = Bounds3::from_point(a).union_point(b).union_point(c);
        Bounds3::new(
            bounds.min - Vec3::splat(self.pad),
            bounds.max + Vec3::splat(self.pad),
        )
    }

    /// Bytes held (vertices, attributes), for reports.
    pub fn heap_bytes(&self) -> usize {
        let a = &self.attrs;
        self.positions.len() * 12
            + a.indices.len() * 12
            + a.normals.as_ref().map_or(0, |v| v.len() * 12)
            + a.tangents.as_ref().map_or(0, |v| v.len() * 16)
            + a.uv0.as_ref().map_or(0, |v| v.len() * 8)
            + a.uv1.as_ref().map_or(0, |v| v.len() * 8)
            + a.colors.as_ref().map_or(0, |v| v.len() * 16)
    }
}

/// One placement of a shared mesh.
#[derive(Clone, Debug)]
pub struct Instance {
    pub mesh: u32,
    pub world_from_object: Mat4,
    /// The inverse, as the flattening computes it (`Mat4::inverse`), for normals and the
    /// object-space ray.
    pub object_from_world: Mat4,
    /// The transform mirrors (negative determinant): the winding is swapped, as flattened.
    pub flip: bool,
    pub material: u32,
    /// Virtual primitive index of the mesh's triangle 0.
    pub base: u32,
    /// World box: the union of the transformed vertices' boxes.
    pub bounds: Bounds3,
    /// Motion blur: its index in [`InstanceStore::motion`] if it moves during the shutter (the
    /// transforms above are then its pose at the shutter's middle), else [`STILL`].
    pub motion: u32,
}

impl Instance {
    pub fn new(mesh: &SharedMesh, mesh_index: u32, m: Mat4, material: u32) -> Instance {
        let mut bounds = Bounds3::EMPTY;
        for tri in &mesh.attrs.indices {
            for &v in tri {
                bounds = bounds.union_point(m.transform_point3(mesh.positions[v as usize]));
            }
        }
        Instance {
            mesh: mesh_index,
            world_from_object: m,
            object_from_world: m.inverse(),
            flip: Mat3::from_mat4(m).determinant() < 0.0,
            material,
            base: 0,
            bounds,
            motion: STILL,
        }
    }

    /// This instance placed by `m` instead (a moving instance at a ray's time): the inverse and
    /// the mirroring taken as [`Instance::new`] takes them; the box is left as it was (the
    /// traversal does not read it).
    #[inline]
    pub fn placed(&self, m: Mat4) -> Instance {
        Instance {
            world_from_object: m,
            object_from_world: m.inverse(),
            flip: Mat3::from_mat4(m).determinant() < 0.0,
            ..*self
        }
    }

    /// A vertex normal in world space, as the flattening stores it.
    #[inline]
    pub fn normal(&self, n: Vec3) -> Vec3 {
        transform_normal(&self.object_from_world, n).normalize_or_zero()
    }

    /// A vertex tangent in world space, as the flattening stores it.
    #[inline]
    pub fn tangent(&self, t: Vec4) -> Vec4 {
        let v = self
            .world_from_object
            .transform_vector3(t.truncate())
            .normalize_or_zero();
        // Mirroring flips the bitangent's handedness.
        Vec4::new(v.x, v.y, v.z, if self.flip { -t.w } else { t.w })
    }
}

/// Every shared mesh and instance.
#[derive(Clone, Debug, Default)]
pub struct InstanceStore {
    pub meshes: Vec<SharedMesh>,
    /// In increasing `base` order.
    pub instances: Vec<Instance>,
    /// The first virtual index (the number of flat triangles).
    pub first: u32,
    /// Motion blur: the world-from-object transform over the shutter of every instance that
    /// moves ([`Instance::motion`]), all with the same keys. Empty for a still.
    pub motion: Vec<KeyedTransform>,
}

impl InstanceStore {
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.instances.is_empty()
    }

    /// Numbers the instances' triangles from `first` (the count of flat triangles) on.
    pub fn finish(&mut self, first: u32) {
        self.first = first;
        let mut base = first;
        for inst in &mut self.instances {
            inst.base = base;
            base += self.meshes[inst.mesh as usize].attrs.indices.len() as u32;
        }
    }

    /// Triangles the instances stand for (what flattening them would store).
    pub fn triangle_count(&self) -> usize {
        self.instances
            .iter()
            .map(|i| self.meshes[i.mesh as usize].attrs.indices.len())
            .sum()
    }

    /// Bytes held by the shared meshes and the instances.
    pub fn heap_bytes(&self) -> usize {
        self.meshes
            .iter()
            .map(SharedMesh::heap_bytes)
            .sum::<usize>()
            + self.instances.len() * std::mem::size_of::<Instance>()
            + self
                .motion
                .iter()
                .map(KeyedTransform::heap_bytes)
                .sum::<usize>()
    }

    /// Key segments of the instances' motion over the shutter: 0 when none moves.
    pub fn segments(&self) -> usize {
        self.motion.first().map_or(0, |m| m.keys() - 1)
    }

    /// The key segment holding shutter time `u` (as `MotionStore::segment`); 0 when no
    /// instance moves.
    #[inline]
    pub fn segment(&self, u: f32) -> usize {
        match self.segments() {
            0 => 0,
            n => key_segment(u, n).0,
        }
    }

    /// `inst` where it is at shutter time `u`: itself if it does not move, else placed by its
    /// world-from-object transform interpolated at `u` (pbrt-v4 transforms a ray into an
    /// animated instance's space by the instance's transform at the ray's time).
    #[inline]
    pub fn at<'a>(&self, inst: &'a Instance, u: f32) -> Cow<'a, Instance> {
        match self.motion.get(inst.motion as usize) {
            None => Cow::Borrowed(inst),
            Some(m) => Cow::Owned(inst.placed(m.at(u))),
        }
    }

    /// The box of instance `k` over key segment `seg` (its world box if it does not move).
    pub fn segment_bounds(&self, k: usize, seg: usize) -> Bounds3 {
        let inst = &self.instances[k];
        match self.motion.get(inst.motion as usize) {
            None => inst.bounds,
            Some(m) => m.segment_bounds(&self.meshes[inst.mesh as usize].extent, seg),
        }
    }

    /// The instance and mesh-local triangle of virtual index `v`.
    #[inline]
    pub fn locate(&self, v: usize) -> (&Instance, usize) {
        let k = self.instances.partition_point(|i| i.base as usize <= v) - 1;
        let inst = &self.instances[k];
        (inst, v - inst.base as usize)
    }

    /// The index of the instance of virtual index `v`.
    pub fn instance_index(&self, v: usize) -> usize {
        self.instances.partition_point(|i| i.base as usize <= v) - 1
    }

    /// Triangle `j` of `inst` in world space, in the flattened winding, with its vertex indices.
    #[inline]
    pub fn world_triangle(&self, inst: &Instance, j: usize) -> (TriangleVerts, [u32; 3]) {
        let mesh = &self.meshes[inst.mesh as usize];
        let t = mesh.attrs.indices[j];
        let t = if inst.flip { [t[0], t[2], t[1]] } else { t };
        let m = &inst.world_from_object;
        let p = |v: u32| m.transform_point3(mesh.positions[v as usize]);
        (
            TriangleVerts {
                p0: p(t[0]),
                p1: p(t[1]),
                p2: p(t[2]),
            },
            t,
        )
    }
}

/// `ray` in the object space of `inst`, with the same parameter `t` (the direction is not
/// normalised).
#[inline]
pub fn object_ray(inst: &Instance, ray: &Ray) -> Ray {
    let m = &inst.object_from_world;
    Ray {
        o: m.transform_point3(ray.o),
        d: m.transform_vector3(ray.d),
        t_max: ray.t_max,
        time: ray.time,
    }
}
