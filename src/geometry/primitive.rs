//! The flat, world-space store of every primitive the accelerators index. Triangles keep their
//! vertices inline for the intersection loop and their shading attributes (normals, UVs, tangents,
//! colours) in per-mesh arrays that are only read for the closest hit.

use super::cuboid::Cuboid;
use super::curve::{Curve, CurveHit};
use super::instance::{Instance, InstanceStore};
pub use super::mesh::MeshAttributes;
use super::motion::{MotionStore, MovingMesh};
use super::quad::Quad;
use super::sphere::Sphere;
use super::triangle::TriangleVerts;
use super::{Bounds3, Ray};
use crate::math::{Vec2, Vec3, Vec4};

/// Marker for "no area light attached".
pub const NO_LIGHT: u32 = u32::MAX;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum PrimitiveKind {
    Triangle = 0,
    Sphere = 1,
    Cuboid = 2,
    Quad = 3,
    /// A piece of a cubic Bézier curve ([`super::curve`]).
    Curve = 4,
}

/// A primitive's kind and index packed in 32 bits (kind in the top three bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PrimRef(pub u32);

impl PrimRef {
    const SHIFT: u32 = 29;
    const MASK: u32 = (1 << Self::SHIFT) - 1;
    /// Largest index a primitive of one kind may have.
    pub const MAX_INDEX: u32 = Self::MASK;

    #[inline]
    pub fn new(kind: PrimitiveKind, index: u32) -> PrimRef {
        debug_assert!(index <= Self::MASK);
        PrimRef(((kind as u32) << Self::SHIFT) | index)
    }

    #[inline]
    pub fn kind(self) -> PrimitiveKind {
        match self.0 >> Self::SHIFT {
            0 => PrimitiveKind::Triangle,
            1 => PrimitiveKind::Sphere,
            2 => PrimitiveKind::Cuboid,
            3 => PrimitiveKind::Quad,
            _ => PrimitiveKind::Curve,
        }
    }

    #[inline]
    pub fn index(self) -> usize {
        (self.0 & Self::MASK) as usize
    }
}

/// The closest hit found by an accelerator: enough to rebuild the full [`SurfaceHit`] later.
#[derive(Clone, Copy, Debug)]
pub struct Intersection {
    pub t: f32,
    pub prim: PrimRef,
    /// Barycentrics (b1, b2) for triangles, (u, v) for quads and curves; unused otherwise.
    pub u: f32,
    pub v: f32,
}

impl Intersection {
    /// A triangle's hit, its barycentrics kept.
    #[inline]
    fn triangle(prim: PrimRef, h: super::triangle::TriangleHit) -> Intersection {
        Intersection {
            t: h.t,
            prim,
            u: h.b1,
            v: h.b2,
        }
    }

    /// A hit at distance `t` of a shape that keeps no parameters (a sphere).
    #[inline]
    fn at(prim: PrimRef, t: f32) -> Intersection {
        Intersection {
            t,
            prim,
            u: 0.0,
            v: 0.0,
        }
    }
}

#[derive(Clone, Copy, Debug)]
pub struct AnalyticPrim<S> {
    pub shape: S,
    pub material: u32,
    pub light: u32,
}

/// The shading geometry's derivatives at a hit in pbrt-v4's convention
/// ([`GeometryStore::pbrt_shading_derivatives`]), which its bump mapping reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadingDerivatives {
    pub dpdu: Vec3,
    pub dpdv: Vec3,
    pub dndu: Vec3,
    pub dndv: Vec3,
}

/// Everything the integrator needs to know about the closest hit.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub t: f32,
    pub p: Vec3,
    pub p_error: Vec3,
    /// Unit geometric normal on the front side (counter-clockwise winding / outward).
    pub ng: Vec3,
    /// Unit shading normal (interpolated), in the same hemisphere as `ng`.
    pub ns: Vec3,
    /// Tangent (∂p/∂u direction, or the mesh's tangent) and the bitangent sign.
    pub tangent: Vec3,
    pub bitangent_sign: f32,
    pub uv: [Vec2; 2],
    /// Screen-space derivatives of each uv set, (∂u/∂x, ∂v/∂x, ∂u/∂y, ∂v/∂y) per pixel, for
    /// filtered texture lookups; zero (an unfiltered lookup) unless the integrator set them
    /// ([`crate::camera::Footprint`]).
    pub duv: [Vec4; 2],
    pub color: Vec4,
    pub material: u32,
    pub light: u32,
    pub prim: PrimRef,
    /// The shutter time of the ray that found the hit ([`super::Ray::time`]): rays spawned
    /// here, shadow rays included, see the scene at that moment.
    pub time: f32,
}

impl SurfaceHit {
    /// A hit with every field at a neutral value: storage for
    /// [`GeometryStore::surface_hit_into`] to overwrite.
    pub const EMPTY: SurfaceHit = SurfaceHit {
        t: 0.0,
        p: Vec3::ZERO,
        p_error: Vec3::ZERO,
        ng: Vec3::Z,
        ns: Vec3::Z,
        tangent: Vec3::X,
        bitangent_sign: 1.0,
        uv: [Vec2::ZERO; 2],
        duv: [Vec4::ZERO; 2],
        color: Vec4::ONE,
        material: 0,
        light: NO_LIGHT,
        prim: PrimRef(0),
        time: 0.0,
    };
}

#[derive(Clone, Debug, Default)]
pub struct GeometryStore {
    pub triangles: Vec<TriangleVerts>,
    /// For each triangle: (mesh index, triangle index within the mesh).
    pub tri_mesh: Vec<(u32, u32)>,
    pub tri_light: Vec<u32>,
    pub meshes: Vec<MeshAttributes>,
    pub spheres: Vec<AnalyticPrim<Sphere>>,
    pub cuboids: Vec<AnalyticPrim<Cuboid>>,
    pub quads: Vec<AnalyticPrim<Quad>>,
    /// Shared meshes placed by several objects (a two-level hierarchy); their triangles have
    /// primitive indices past `triangles` ([`super::instance`]). Empty for most scenes.
    pub instances: InstanceStore,
    pub curves: Vec<AnalyticPrim<Curve>>,
    /// The moving primitives' keys over the shutter (continuous motion blur,
    /// [`super::motion`]); `None` for a still.
    pub motion: Option<Box<MotionStore>>,
    /// Every moving primitive (flat triangles of moving meshes, moving spheres), in `PrimRef`
    /// order: what the motion BVH is built over; the still BVH leaves them out. Empty for a
    /// still.
    pub moving_prims: Vec<PrimRef>,
}

impl GeometryStore {
    /// Every primitive reference, in a fixed order (triangles, spheres, boxes, quads, curves).
    pub fn all_prims(&self) -> Vec<PrimRef> {
        let mut v = Vec::with_capacity(self.len());
        v.extend(
            (0..self.triangles.len() as u32).map(|i| PrimRef::new(PrimitiveKind::Triangle, i)),
        );
        v.extend((0..self.spheres.len() as u32).map(|i| PrimRef::new(PrimitiveKind::Sphere, i)));
        v.extend((0..self.cuboids.len() as u32).map(|i| PrimRef::new(PrimitiveKind::Cuboid, i)));
        v.extend((0..self.quads.len() as u32).map(|i| PrimRef::new(PrimitiveKind::Quad, i)));
        v.extend((0..self.curves.len() as u32).map(|i| PrimRef::new(PrimitiveKind::Curve, i)));
        v
    }

    /// The primitives that do not move: all of them for a still. The still accelerator is
    /// built over these; the moving ones ([`GeometryStore::moving_prims`]) have their own.
    pub fn static_prims(&self) -> Vec<PrimRef> {
        let mut all = self.all_prims();
        if !self.moving_prims.is_empty() {
            let moving = &self.moving_prims;
            all.retain(|p| moving.binary_search_by_key(&p.0, |q| q.0).is_err());
        }
        all
    }

    /// The moving mesh of flat triangle `i` and the triangle's vertex indices in it, if it moves.
    #[inline]
    pub(super) fn moving_triangle(&self, i: usize) -> Option<(&MovingMesh, [usize; 3])> {
        let m = self.motion.as_ref()?;
        let &(mesh_i, local) = self.tri_mesh.get(i)?;
        let moving = m.mesh(mesh_i)?;
        let idx = self.meshes[mesh_i as usize].indices[local as usize].map(|x| x as usize);
        Some((moving, idx))
    }

    /// A moving primitive's box over key segment `seg` ([`MotionStore::triangle_sweep`]).
    pub fn sweep_bounds(&self, prim: PrimRef, seg: usize) -> Bounds3 {
        let Some(m) = &self.motion else {
            return self.bounds(prim);
        };
        match prim.kind() {
            PrimitiveKind::Triangle => match self.moving_triangle(prim.index()) {
                Some((mesh, idx)) => m.triangle_sweep(mesh, idx, seg),
                None => self.bounds(prim),
            },
            PrimitiveKind::Sphere if m.sphere_slot[prim.index()] != super::motion::STILL => {
                m.sphere_sweep(prim.index(), seg)
            }
            PrimitiveKind::Quad
                if m.quad_slot
                    .get(prim.index())
                    .is_some_and(|&s| s != super::motion::STILL) =>
            {
                m.quad_sweep(prim.index(), seg)
            }
            PrimitiveKind::Cuboid => m
                .cuboid_sweep(prim.index(), &self.cuboids[prim.index()].shape.local, seg)
                .unwrap_or_else(|| self.bounds(prim)),
            _ => self.bounds(prim),
        }
    }

    /// Tests a moving primitive ([`GeometryStore::moving_prims`]) where it is at `ray.time`.
    #[inline]
    pub fn intersect_moving(&self, prim: PrimRef, ray: &Ray, t_max: f32) -> Option<Intersection> {
        let m = self.motion.as_ref()?;
        match prim.kind() {
            PrimitiveKind::Triangle => {
                let (mesh, idx) = self.moving_triangle(prim.index())?;
                MotionStore::triangle(mesh, idx, m.segment(ray.time))
                    .intersect(ray, t_max)
                    .map(|h| Intersection::triangle(prim, h))
            }
            PrimitiveKind::Sphere => m
                .sphere(prim.index(), ray.time)?
                .intersect(ray, t_max)
                .map(|t| Intersection::at(prim, t)),
            PrimitiveKind::Quad => m
                .quad(prim.index(), ray.time)?
                .intersect(ray, t_max)
                .map(|(t, u, v)| Intersection { t, prim, u, v }),
            PrimitiveKind::Cuboid => m
                .cuboid(
                    prim.index(),
                    &self.cuboids[prim.index()].shape.local,
                    ray.time,
                )?
                .intersect_t(ray, t_max)
                .map(|t| Intersection {
                    t,
                    prim,
                    u: 0.0,
                    v: 0.0,
                }),
            _ => None,
        }
    }

    pub fn len(&self) -> usize {
        self.triangles.len()
            + self.spheres.len()
            + self.cuboids.len()
            + self.quads.len()
            + self.curves.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn bounds(&self, prim: PrimRef) -> Bounds3 {
        let i = prim.index();
        match prim.kind() {
            PrimitiveKind::Triangle => {
                let t = self.tri_parts(i).0;
                Bounds3::from_point(t.p0)
                    .union_point(t.p1)
                    .union_point(t.p2)
            }
            PrimitiveKind::Sphere => {
                let s = &self.spheres[i].shape;
                Bounds3::new(
                    s.center - Vec3::splat(s.radius),
                    s.center + Vec3::splat(s.radius),
                )
            }
            PrimitiveKind::Cuboid => self.cuboids[i].shape.world_bounds(),
            PrimitiveKind::Quad => {
                let q = &self.quads[i].shape;
                Bounds3::from_point(q.corner)
                    .union_point(q.corner + q.e1)
                    .union_point(q.corner + q.e2)
                    .union_point(q.corner + q.e1 + q.e2)
            }
            PrimitiveKind::Curve => self.curves[i].shape.bounds(),
        }
    }

    pub fn scene_bounds(&self) -> Bounds3 {
        let flat = self
            .all_prims()
            .iter()
            .fold(Bounds3::EMPTY, |b, &p| b.union(&self.bounds(p)));
        // An instance's box is the union of its transformed vertices, as its flattened
        // triangles' boxes would be.
        self.instances
            .instances
            .iter()
            .fold(flat, |b, i| b.union(&i.bounds))
    }

    /// Tests one primitive; returns the hit if it is closer than `t_max`.
    #[inline]
    pub fn intersect(&self, prim: PrimRef, ray: &Ray, t_max: f32) -> Option<Intersection> {
        let i = prim.index();
        match prim.kind() {
            PrimitiveKind::Triangle => self.triangles[i]
                .intersect(ray, t_max)
                .map(|h| Intersection::triangle(prim, h)),
            PrimitiveKind::Sphere => self.spheres[i]
                .shape
                .intersect(ray, t_max)
                .map(|t| Intersection::at(prim, t)),
            PrimitiveKind::Cuboid => {
                self.cuboids[i]
                    .shape
                    .intersect_t(ray, t_max)
                    .map(|t| Intersection {
                        t,
                        prim,
                        u: 0.0,
                        v: 0.0,
                    })
            }
            PrimitiveKind::Quad => self.quads[i]
                .shape
                .intersect(ray, t_max)
                .map(|(t, u, v)| Intersection { t, prim, u, v }),
            PrimitiveKind::Curve => {
                self.curves[i]
                    .shape
                    .intersect(ray, t_max)
                    .map(|h| Intersection {
                        t: h.t,
                        prim,
                        u: h.u,
                        v: h.v,
                    })
            }
        }
    }

    /// Material index of a primitive.
    #[inline]
    pub fn material(&self, prim: PrimRef) -> u32 {
        let i = prim.index();
        match prim.kind() {
            PrimitiveKind::Triangle => match self.tri_mesh.get(i) {
                Some(&(mesh, _)) => self.meshes[mesh as usize].material,
                None => self.instances.locate(i).0.material,
            },
            PrimitiveKind::Sphere => self.spheres[i].material,
            PrimitiveKind::Cuboid => self.cuboids[i].material,
            PrimitiveKind::Quad => self.quads[i].material,
            PrimitiveKind::Curve => self.curves[i].material,
        }
    }

    /// Area light index attached to a primitive, or [`NO_LIGHT`].
    #[inline]
    pub fn light(&self, prim: PrimRef) -> u32 {
        let i = prim.index();
        match prim.kind() {
            // Instanced triangles are never lights (emissive objects are not instanced).
            PrimitiveKind::Triangle => self.tri_light.get(i).copied().unwrap_or(NO_LIGHT),
            PrimitiveKind::Sphere => self.spheres[i].light,
            PrimitiveKind::Cuboid => self.cuboids[i].light,
            PrimitiveKind::Quad => self.quads[i].light,
            PrimitiveKind::Curve => self.curves[i].light,
        }
    }

    pub fn set_light(&mut self, prim: PrimRef, light: u32) {
        let i = prim.index();
        match prim.kind() {
            PrimitiveKind::Triangle => self.tri_light[i] = light,
            PrimitiveKind::Sphere => self.spheres[i].light = light,
            PrimitiveKind::Cuboid => self.cuboids[i].light = light,
            PrimitiveKind::Quad => self.quads[i].light = light,
            PrimitiveKind::Curve => self.curves[i].light = light,
        }
    }

    /// Surface area of a primitive in world space.
    pub fn area(&self, prim: PrimRef) -> f32 {
        let i = prim.index();
        match prim.kind() {
            PrimitiveKind::Triangle => self.tri_parts(i).0.area(),
            PrimitiveKind::Sphere => self.spheres[i].shape.area(),
            PrimitiveKind::Cuboid => self.cuboids[i].shape.area(),
            PrimitiveKind::Quad => self.quads[i].shape.area(),
            PrimitiveKind::Curve => self.curves[i].shape.area(),
        }
    }

    /// A hit on `prim` at ray distance `t` with its material and light index set and every
    /// geometric attribute at a neutral default, for the caller to fill in.
    #[inline]
    pub(crate) fn blank_hit(&self, prim: PrimRef, t: f32) -> SurfaceHit {
        SurfaceHit {
            t,
            material: self.material(prim),
            light: self.light(prim),
            prim,
            ..SurfaceHit::EMPTY
        }
    }

    /// Expands an accelerator's closest hit into full shading information.
    #[inline]
    pub fn surface_hit(&self, ray: &Ray, isect: &Intersection) -> SurfaceHit {
        let mut hit = SurfaceHit::EMPTY;
        self.surface_hit_into(ray, isect, &mut hit);
        hit
    }

    /// [`GeometryStore::surface_hit`] written into `hit` (every field), for a caller that keeps
    /// one hit's storage along a path: a `SurfaceHit` is 144 bytes, above the size LLVM copies
    /// inline, so each move of a returned hit was a `memcpy` call (callgrind: 5.9 % of a
    /// Cornell box render's instructions were such calls).
    pub fn surface_hit_into(&self, ray: &Ray, isect: &Intersection, out: &mut SurfaceHit) {
        let i = isect.prim.index();
        // Built in a local and stored once: written field by field into `out`, the blank
        // values below were all stored and then overwritten (~40 instructions per Cornell hit).
        let mut hit = self.blank_hit(isect.prim, isect.t);
        match isect.prim.kind() {
            PrimitiveKind::Triangle => match self.triangles.get(i) {
                Some(tri) => {
                    let (mesh_i, local) = self.tri_mesh[i];
                    let mesh = &self.meshes[mesh_i as usize];
                    let idx = mesh.indices[local as usize].map(|x| x as usize);
                    match self.moving_triangle(i) {
                        None => {
                            triangle_hit(tri, mesh, idx, Vertices::Flat, isect.u, isect.v, &mut hit)
                        }
                        Some((moving, _)) => {
                            let seg = self
                                .motion
                                .as_ref()
                                .map_or((0, 0.0), |m| m.segment(ray.time));
                            let tri = MotionStore::triangle(moving, idx, seg);
                            let v = Vertices::Moving(moving, seg);
                            triangle_hit(&tri, mesh, idx, v, isect.u, isect.v, &mut hit);
                        }
                    }
                }
                None => {
                    let (inst, j) = self.instances.locate(i);
                    // A moving instance where it is at the ray's time.
                    let inst = self.instances.at(inst, ray.time);
                    let inst = &*inst;
                    let (tri, idx) = self.instances.world_triangle(inst, j);
                    let mesh = &self.instances.meshes[inst.mesh as usize].attrs;
                    let idx = idx.map(|x| x as usize);
                    let v = Vertices::Instance(inst);
                    triangle_hit(&tri, mesh, idx, v, isect.u, isect.v, &mut hit);
                }
            },
            PrimitiveKind::Sphere => {
                let moved = self.motion.as_ref().and_then(|m| m.sphere(i, ray.time));
                let s = moved.as_ref().unwrap_or(&self.spheres[i].shape);
                let (p, err, n) = s.surface_point(ray, isect.t);
                let (u, v) = s.uv(n);
                hit.p = p;
                hit.p_error = err;
                hit.ng = n;
                hit.ns = n;
                // ∂p/∂u runs around the y axis (east).
                let t = Vec3::new(-n.z, 0.0, n.x);
                hit.tangent = if t.length_squared() > 1e-12 {
                    t.normalize()
                } else {
                    Vec3::X
                };
                hit.uv = [Vec2::new(u, v); 2];
            }
            PrimitiveKind::Cuboid => {
                // The face is found at the accelerator's distance, not by a second slab test:
                // the accelerator's `intersect_t` gave `isect.t` for this very ray, and the slab
                // test's distance does not depend on `t_max` once it is below it.
                let moved = self
                    .motion
                    .as_ref()
                    .and_then(|m| m.cuboid(i, &self.cuboids[i].shape.local, ray.time));
                let c = moved.as_ref().unwrap_or(&self.cuboids[i].shape);
                let h = c.hit_at(ray, isect.t);
                let (p, err, n) = c.surface_point(&h);
                let (u, v) = c.uv(&h);
                hit.p = p;
                hit.p_error = err;
                hit.ng = n;
                hit.ns = n;
                hit.tangent = crate::math::Frame::from_normal(n).x;
                hit.uv = [Vec2::new(u, v); 2];
            }
            PrimitiveKind::Quad => {
                let moved = self.motion.as_ref().and_then(|m| m.quad(i, ray.time));
                let q = moved.as_ref().unwrap_or(&self.quads[i].shape);
                let (p, err) = q.point(isect.u, isect.v);
                let n = q.normal();
                hit.p = p;
                hit.p_error = err;
                hit.ng = n;
                hit.ns = n;
                hit.tangent = q.tangent();
                hit.uv = [Vec2::new(isect.u, isect.v); 2];
            }
            PrimitiveKind::Curve => {
                // uv = (u along the curve, v across its width): the hair BSDF's offset is
                // h = 2v − 1 (pbrt-v4 `HairMaterial`).
                let h = CurveHit {
                    t: isect.t,
                    u: isect.u,
                    v: isect.v,
                };
                let (p, err, n, dpdu) = self.curves[i].shape.surface(ray, &h);
                hit.p = p;
                hit.p_error = err;
                hit.ng = n;
                hit.ns = n;
                hit.tangent = dpdu;
                hit.uv = [Vec2::new(isect.u, isect.v); 2];
            }
        }
        // Field by field: a whole-struct assignment of this size may become a `memcpy` call.
        *out = SurfaceHit {
            t: hit.t,
            p: hit.p,
            p_error: hit.p_error,
            ng: hit.ng,
            ns: hit.ns,
            tangent: hit.tangent,
            bitangent_sign: hit.bitangent_sign,
            uv: hit.uv,
            duv: hit.duv,
            color: hit.color,
            material: hit.material,
            light: hit.light,
            prim: hit.prim,
            time: ray.time,
        };
    }

    /// ∂p/∂u, ∂p/∂v, ∂n/∂u and ∂n/∂v of the shading geometry at a triangle hit, as pbrt-v4's
    /// `Triangle` builds them (for bump mapping): v grows up the image (pbrt's convention; stored
    /// uvs grow down, so this is −∂p/∂v of the stored ones); on a mesh with normals, ∂p/∂u is
    /// projected onto the shading normal's plane and ∂p/∂v is n × ∂p/∂u (pbrt-v4 `ss`, `ts`),
    /// and ∂n/∂u, ∂n/∂v are the vertex normals' differences solved in the same uv system (PBRT
    /// §6.5.3, eq. 6.7 with n for p) — zero on a mesh without normals, which is flat. They are
    /// the derivatives of the normal on the side [`SurfaceHit::ns`] faces (negated where the
    /// vertex normals face the other way), so that the bumped surface p + d·n and its derivatives
    /// describe one surface. `None` for other primitives and for triangles without a usable uv
    /// parameterisation.
    pub fn pbrt_shading_derivatives(&self, hit: &SurfaceHit) -> Option<ShadingDerivatives> {
        if hit.prim.kind() != PrimitiveKind::Triangle {
            return None;
        }
        let (tri, mesh, [i0, i1, i2]) = self.tri_parts_at(hit.prim.index(), hit.time);
        let uv = mesh.uv0.as_ref()?;
        let flip = |t: Vec2| Vec2::new(t.x, -t.y);
        let duv02 = flip(uv[i0] - uv[i2]);
        let duv12 = flip(uv[i1] - uv[i2]);
        let dp02 = tri.p0 - tri.p2;
        let dp12 = tri.p1 - tri.p2;
        let det = duv02.x * duv12.y - duv02.y * duv12.x;
        if !(det.abs() > 1e-12) {
            return None;
        }
        let inv = 1.0 / det;
        // The derivatives along u and v of a quantity given at the vertices by its differences
        // d02 = x0 − x2, d12 = x1 − x2 (PBRT eq. 3.33 for p; pbrt-v4 `Triangle` does the same
        // for the normals).
        let solve = |d02: Vec3, d12: Vec3| {
            (
                (d02 * duv12.y - d12 * duv02.y) * inv,
                (d12 * duv02.x - d02 * duv12.x) * inv,
            )
        };
        let (dpdu, dpdv) = solve(dp02, dp12);
        if !(dpdu.is_finite() && dpdv.is_finite()) {
            return None;
        }
        let Some(normals) = &mesh.normals else {
            return Some(ShadingDerivatives {
                dpdu,
                dpdv,
                dndu: Vec3::ZERO,
                dndv: Vec3::ZERO,
            });
        };
        let n = hit.ns;
        let ts = n.cross(dpdu);
        if !(ts.length_squared() > 0.0) {
            return None;
        }
        // The vertex normals as the hit interpolated them (an instance's taken to the world, a
        // moving triangle's at the hit's time).
        let i = hit.prim.index();
        let [n0, n1, n2] = if i < self.triangles.len() {
            match self.moving_triangle(i) {
                None => [normals[i0], normals[i1], normals[i2]],
                Some((moving, _)) => {
                    let seg = self
                        .motion
                        .as_ref()
                        .map_or((0, 0.0), |m| m.segment(hit.time));
                    [i0, i1, i2].map(|v| moving.normal(seg, v))
                }
            }
        } else {
            let x = self.instances.locate(i).0;
            let x = self.instances.at(x, hit.time);
            [
                x.normal(normals[i0]),
                x.normal(normals[i1]),
                x.normal(normals[i2]),
            ]
        };
        let (mut dndu, mut dndv) = solve(n0 - n2, n1 - n2);
        if !(dndu.is_finite() && dndv.is_finite()) {
            (dndu, dndv) = (Vec3::ZERO, Vec3::ZERO);
        }
        // `triangle_hit` turns the interpolated normal to the winding's side; its derivatives
        // turn with it. (The hit keeps no barycentrics: they are solved again from its point.)
        let [b0, b1, b2] = tri.barycentrics(hit.p);
        if (n0 * b0 + n1 * b1 + n2 * b2).dot(n) < 0.0 {
            (dndu, dndv) = (-dndu, -dndv);
        }
        Some(ShadingDerivatives {
            dpdu: ts.cross(n),
            dpdv: ts,
            dndu,
            dndv,
        })
    }

    /// Screen-space uv derivatives ([`SurfaceHit::duv`]) of each uv set at a triangle hit from
    /// the point's screen-space derivatives `dpdx`, `dpdy`: the least-squares solution of
    /// dp = ∂p/∂u·du + ∂p/∂v·dv (pbrt-v4 `SurfaceInteraction::ComputeDifferentials`), with
    /// ∂p/∂u, ∂p/∂v of the triangle's uv parameterisation (PBRT eq. 3.33). Zero for other
    /// primitives and degenerate uvs (an unfiltered lookup).
    pub fn uv_derivatives(&self, hit: &SurfaceHit, dpdx: Vec3, dpdy: Vec3) -> [Vec4; 2] {
        let mut out = [Vec4::ZERO; 2];
        if hit.prim.kind() != PrimitiveKind::Triangle {
            return out;
        }
        let (tri, mesh, [i0, i1, i2]) = self.tri_parts_at(hit.prim.index(), hit.time);
        let set = |uv: &[Vec2]| -> Vec4 {
            let (duv02, duv12) = (uv[i0] - uv[i2], uv[i1] - uv[i2]);
            let (dp02, dp12) = (tri.p0 - tri.p2, tri.p1 - tri.p2);
            let det = duv02.x * duv12.y - duv02.y * duv12.x;
            if !(det.abs() > 1e-20) {
                return Vec4::ZERO;
            }
            let inv = 1.0 / det;
            let dpdu = (dp02 * duv12.y - dp12 * duv02.y) * inv;
            let dpdv = (dp12 * duv02.x - dp02 * duv12.x) * inv;
            let (a00, a01, a11) = (dpdu.dot(dpdu), dpdu.dot(dpdv), dpdv.dot(dpdv));
            let inv_det = 1.0 / (a00 * a11 - a01 * a01);
            if !inv_det.is_finite() {
                return Vec4::ZERO;
            }
            let solve = |d: Vec3| {
                let (b0, b1) = (dpdu.dot(d), dpdv.dot(d));
                Vec2::new(a11 * b0 - a01 * b1, a00 * b1 - a01 * b0) * inv_det
            };
            let (x, y) = (solve(dpdx), solve(dpdy));
            let v = Vec4::new(x.x, x.y, y.x, y.y);
            if v.is_finite() {
                v.clamp(Vec4::splat(-1e8), Vec4::splat(1e8))
            } else {
                Vec4::ZERO
            }
        };
        if let Some(uv) = &mesh.uv0 {
            out[0] = set(uv);
        }
        out[1] = match &mesh.uv1 {
            Some(uv) => set(uv),
            None => out[0],
        };
        out
    }

    /// [`GeometryStore::tri_parts`] at shutter time `u`: a moving triangle's vertices
    /// interpolated there, a moving instance's placed there (the same as `tri_parts` for a
    /// still).
    #[inline]
    pub fn tri_parts_at(&self, i: usize, u: f32) -> (TriangleVerts, &MeshAttributes, [usize; 3]) {
        match self.triangles.get(i) {
            Some(_) => {
                let parts = self.tri_parts(i);
                match (self.moving_triangle(i), self.motion.as_ref()) {
                    (Some((moving, idx)), Some(m)) => (
                        MotionStore::triangle(moving, idx, m.segment(u)),
                        parts.1,
                        parts.2,
                    ),
                    _ => parts,
                }
            }
            None => {
                let (inst, j) = self.instances.locate(i);
                let inst = self.instances.at(inst, u);
                let (tri, idx) = self.instances.world_triangle(&inst, j);
                let mesh = &self.instances.meshes[inst.mesh as usize].attrs;
                (tri, mesh, idx.map(|x| x as usize))
            }
        }
    }

    /// Triangle `i` (flat or instanced) in world space, the attributes of its mesh and its
    /// vertex indices in them. An instanced triangle's normals and tangents in those attributes
    /// are in object space ([`Instance::normal`] takes them to the world).
    #[inline]
    pub fn tri_parts(&self, i: usize) -> (TriangleVerts, &MeshAttributes, [usize; 3]) {
        match self.triangles.get(i) {
            Some(tri) => {
                let (mesh_i, local) = self.tri_mesh[i];
                let mesh = &self.meshes[mesh_i as usize];
                (*tri, mesh, mesh.indices[local as usize].map(|x| x as usize))
            }
            None => {
                let (inst, j) = self.instances.locate(i);
                let (tri, idx) = self.instances.world_triangle(inst, j);
                let mesh = &self.instances.meshes[inst.mesh as usize].attrs;
                (tri, mesh, idx.map(|x| x as usize))
            }
        }
    }
}

/// Where a triangle's vertex normals and tangents come from ([`triangle_hit`]).
#[derive(Clone, Copy)]
enum Vertices<'a> {
    /// A flat triangle: its mesh's world-space attributes.
    Flat,
    /// An instanced triangle: its mesh's object-space attributes, taken to the world per vertex
    /// as the flattening takes them (so the interpolation sees the same values).
    Instance(&'a Instance),
    /// A moving triangle: its moving mesh's keys, interpolated at the segment.
    Moving(&'a MovingMesh, (usize, f32)),
}

/// The shading attributes of a triangle hit at barycentrics (b1, b2): `tri` in world space,
/// `mesh` its attributes and `[i0, i1, i2]` its vertices in them; `inst` says where its vertex
/// normals and tangents come from ([`Vertices`]).
/// Always inlined: the hit it fills must stay a local of [`GeometryStore::surface_hit_into`].
#[inline(always)]
fn triangle_hit(
    tri: &TriangleVerts,
    mesh: &MeshAttributes,
    [i0, i1, i2]: [usize; 3],
    inst: Vertices,
    b1: f32,
    b2: f32,
    hit: &mut SurfaceHit,
) {
    {
        let (p, err) = tri.point(b1, b2);
        hit.p = p;
        hit.p_error = err;
        let ng = tri.unit_normal();
        hit.ng = ng;
        let b0 = 1.0 - b1 - b2;
        let lerp3 = |a: Vec3, b: Vec3, c: Vec3| a * b0 + b * b1 + c * b2;
        let lerp2 = |a: Vec2, b: Vec2, c: Vec2| a * b0 + b * b1 + c * b2;
        hit.ns = match &mesh.normals {
            Some(n) => {
                let ns = match inst {
                    Vertices::Flat => lerp3(n[i0], n[i1], n[i2]),
                    Vertices::Instance(x) => {
                        lerp3(x.normal(n[i0]), x.normal(n[i1]), x.normal(n[i2]))
                    }
                    Vertices::Moving(m, s) => {
                        lerp3(m.normal(s, i0), m.normal(s, i1), m.normal(s, i2))
                    }
                };
                if ns.length_squared() > 1e-20 && ns.is_finite() {
                    let ns = ns.normalize();
                    // Shading normals must describe the same side as the winding: a flipped
                    // normal would make front-face emission and refraction disagree.
                    if ns.dot(ng) < 0.0 { -ns } else { ns }
                } else {
                    ng
                }
            }
            None => ng,
        };
        if let Some(uv) = &mesh.uv0 {
            hit.uv[0] = lerp2(uv[i0], uv[i1], uv[i2]);
        }
        hit.uv[1] = match &mesh.uv1 {
            Some(uv) => lerp2(uv[i0], uv[i1], uv[i2]),
            None => hit.uv[0],
        };
        if let Some(c) = &mesh.colors {
            hit.color = c[i0] * b0 + c[i1] * b1 + c[i2] * b2;
        }
        // Tangent frame: the mesh's own tangents, else ∂p/∂u from the UV parameterisation
        // (PBRT eq. 3.33), else any vector perpendicular to the normal.
        let mut tangent = None;
        if let Some(t) = &mesh.tangents {
            let [t0, t1, t2] = match inst {
                Vertices::Flat => [t[i0], t[i1], t[i2]],
                Vertices::Instance(x) => [x.tangent(t[i0]), x.tangent(t[i1]), x.tangent(t[i2])],
                Vertices::Moving(m, s) => [m.tangent(s, i0), m.tangent(s, i1), m.tangent(s, i2)],
            };
            let t4 = t0 * b0 + t1 * b1 + t2 * b2;
            let t3 = t4.truncate();
            if t3.length_squared() > 1e-20 && t3.is_finite() {
                tangent = Some(t3.normalize());
                hit.bitangent_sign = if t0.w < 0.0 { -1.0 } else { 1.0 };
            }
        } else if let Some(uv) = &mesh.uv0 {
            let duv02 = uv[i0] - uv[i2];
            let duv12 = uv[i1] - uv[i2];
            let dp02 = tri.p0 - tri.p2;
            let dp12 = tri.p1 - tri.p2;
            let det = duv02.x * duv12.y - duv02.y * duv12.x;
            if det.abs() > 1e-12 {
                let inv = 1.0 / det;
                let dpdu = (dp02 * duv12.y - dp12 * duv02.y) * inv;
                let dpdv = (dp12 * duv02.x - dp02 * duv12.x) * inv;
                if dpdu.length_squared() > 1e-20 && dpdu.is_finite() {
                    tangent = Some(dpdu.normalize());
                    // Handedness of (T, B, N): a normal map's +y (green) is "up" in the image
                    // (glTF §3.9.3, the OpenGL convention), and glTF's v grows downwards, so B
                    // must align with −∂p/∂v (as MikkTSpace gives for glTF's flipped v).
                    hit.bitangent_sign = if hit.ns.cross(dpdu).dot(dpdv) > 0.0 {
                        -1.0
                    } else {
                        1.0
                    };
                }
            }
        }
        hit.tangent = tangent.unwrap_or_else(|| crate::math::Frame::from_normal(hit.ns).x);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Mat4;

    /// One primitive of each kind: a triangle with normals, uvs and vertex colours, a sphere, a
    /// rotated box and a quad, each with its own material and light.
    fn store() -> GeometryStore {
        let mut g = GeometryStore::default();
        g.triangles.push(TriangleVerts {
            p0: Vec3::new(-1.0, -1.0, 0.0),
            p1: Vec3::new(1.0, -1.0, 0.2),
            p2: Vec3::new(0.0, 1.0, -0.1),
        });
        g.tri_mesh.push((0, 0));
        g.tri_light.push(NO_LIGHT);
        g.meshes.push(MeshAttributes {
            indices: vec![[0, 1, 2]],
            normals: Some(vec![
                Vec3::new(0.1, 0.0, 1.0),
                Vec3::new(0.0, 0.2, 1.0),
                Vec3::new(-0.1, 0.1, 1.0),
            ]),
            uv0: Some(vec![Vec2::ZERO, Vec2::X, Vec2::new(0.5, 1.0)]),
            colors: Some(vec![
                Vec4::ONE,
                Vec4::splat(0.5),
                Vec4::new(0.2, 0.4, 0.6, 0.8),
            ]),
            material: 3,
            ..Default::default()
        });
        g.spheres.push(AnalyticPrim {
            shape: Sphere {
                center: Vec3::new(0.0, 0.0, -3.0),
                radius: 1.5,
            },
            material: 1,
            light: 7,
        });
        let m = Mat4::from_rotation_y(0.4) * Mat4::from_rotation_x(-0.3);
        g.cuboids.push(AnalyticPrim {
            shape: Cuboid::new(Bounds3::new(Vec3::splat(-0.7), Vec3::splat(0.7)), m),
            material: 2,
            light: NO_LIGHT,
        });
        g.quads.push(AnalyticPrim {
            shape: Quad::new(Vec3::new(-2.0, -2.0, -1.0), Vec3::X * 4.0, Vec3::Y * 4.0),
            material: 4,
            light: 5,
        });
        g
    }

    /// `surface_hit_into` leaves nothing of the hit its storage held before: on storage holding
    /// another hit (every field different, uv derivatives and colour included), each primitive
    /// kind's hit is the one `surface_hit` builds from fresh storage, field by field and bit for
    /// bit (compared through `Debug`, which prints every float exactly). Fails if a field the
    /// primitive does not set (a triangle's colour without vertex colours, a sphere's derivatives)
    /// is left over from the previous hit.
    #[test]
    fn surface_hit_into_overwrites_every_field() {
        let g = store();
        let stale = SurfaceHit {
            t: 9.0,
            p: Vec3::splat(9.0),
            p_error: Vec3::splat(0.5),
            ng: Vec3::X,
            ns: Vec3::Y,
            tangent: Vec3::Z,
            bitangent_sign: -1.0,
            uv: [Vec2::splat(0.3), Vec2::splat(0.7)],
            duv: [Vec4::splat(0.01), Vec4::splat(0.02)],
            color: Vec4::splat(0.25),
            material: 99,
            light: 42,
            prim: PrimRef::new(PrimitiveKind::Quad, 5),
            time: 0.0,
        };
        let mut kinds = 0;
        for prim in g.all_prims() {
            for k in 0..16 {
                let (x, y) = ((k % 4) as f32 * 0.1 - 0.15, (k / 4) as f32 * 0.1 - 0.15);
                let ray = Ray::new(Vec3::new(x, y, 5.0), Vec3::new(-x * 0.1, y * 0.05, -1.0));
                let Some(isect) = g.intersect(prim, &ray, f32::INFINITY) else {
                    continue;
                };
                let fresh = g.surface_hit(&ray, &isect);
                let mut reused = stale;
                g.surface_hit_into(&ray, &isect, &mut reused);
                assert_eq!(format!("{reused:?}"), format!("{fresh:?}"), "{prim:?}");
                assert_eq!(fresh.material, g.material(prim));
                assert_eq!(fresh.light, g.light(prim));
                if k == 0 {
                    kinds += 1;
                }
            }
        }
        assert_eq!(kinds, 4, "every primitive kind is hit");
    }

    /// A box hit expanded at the accelerator's distance (`Cuboid::hit_at`, what `surface_hit`
    /// uses) is the hit a full box test finds, bit for bit, for rays from outside and from
    /// inside a rotated box, whatever `t_max` the accelerator's test had. Fails if the face is
    /// placed at another distance or in another frame.
    #[test]
    fn a_box_hit_at_the_accelerators_distance_is_the_full_test() {
        let g = store();
        let c = &g.cuboids[0].shape;
        let mut tested = 0;
        for k in 0..200 {
            let a = k as f32 * 0.61;
            let b = k as f32 * 0.23;
            let d = Vec3::new(a.cos() * b.sin(), a.sin() * b.sin(), b.cos());
            let o = if k % 2 == 0 {
                -d * 4.0 + Vec3::new(0.1, -0.2, 0.05)
            } else {
                Vec3::new(0.1, -0.2, 0.05)
            };
            let ray = Ray::new(o, d * (1.0 + (k % 3) as f32));
            let Some(full) = c.intersect(&ray, f32::INFINITY) else {
                continue;
            };
            for t_max in [f32::INFINITY, full.t * 1.5, full.t * 1.0001] {
                let t = c.intersect_t(&ray, t_max).expect("hit below t_max");
                assert_eq!(t.to_bits(), full.t.to_bits());
                assert_eq!(format!("{:?}", c.hit_at(&ray, t)), format!("{full:?}"));
            }
            tested += 1;
        }
        assert!(tested > 150, "{tested}");
    }

    #[test]
    fn prim_ref_round_trips() {
        for kind in [
            PrimitiveKind::Triangle,
            PrimitiveKind::Sphere,
            PrimitiveKind::Cuboid,
            PrimitiveKind::Quad,
            PrimitiveKind::Curve,
        ] {
            for idx in [0u32, 1, 12345, PrimRef::MAX_INDEX] {
                let r = PrimRef::new(kind, idx);
                assert_eq!(r.kind(), kind);
                assert_eq!(r.index(), idx as usize);
            }
        }
    }
}
