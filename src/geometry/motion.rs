//! Moving primitives of a motion-blurred world (docs/DESIGN.md, "Motion blur"): the world holds
//! every primitive once, posed at the shutter's middle, and for those that move during the
//! shutter their shape at `keys` evenly spaced times over it (key k at u = k / (keys − 1)). A
//! ray at time u ([`Ray::time`]) meets a moving primitive interpolated linearly between the two
//! keys around u: a triangle's vertices (and its vertex normals and tangents, which the hit
//! renormalises), a sphere's centre and radius, a quad's corner and edges. This is the
//! per-vertex motion of Embree's and Cycles' motion-blurred meshes (a deforming mesh's vertices
//! at time steps, linear between);
//! rigid motion is sampled the same way, so a translation is exact with two keys and a rotation
//! follows its arc by chords. Only the moving primitives are stored per key; the static ones,
//! and their BVH, are the still world's.

use super::bounds::Bounds3;
use super::cuboid::Cuboid;
use super::quad::Quad;
use super::sphere::Sphere;
use super::triangle::TriangleVerts;
use crate::math::{Mat3, Mat4, Vec3, Vec4, decompose};
use glam::Quat;

/// Marks a mesh or sphere that does not move.
pub const STILL: u32 = u32::MAX;

/// One flattened mesh's vertices at every key, in world space (the indices are the mesh's
/// [`super::mesh::MeshAttributes::indices`]).
#[derive(Clone, Debug, Default)]
pub struct MovingMesh {
    /// Vertices per key.
    pub verts: usize,
    /// Key k's vertex v at `k * verts + v`.
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub tangents: Option<Vec<Vec4>>,
}

impl MovingMesh {
    #[inline(always)]
    fn at<T>(&self, v: &[T], (k, f): (usize, f32), i: usize) -> T
    where
        T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
    {
        let a = v[k * self.verts + i];
        if f == 0.0 {
            return a;
        }
        a * (1.0 - f) + v[(k + 1) * self.verts + i] * f
    }

    /// Vertex `i`'s position at key segment `seg` ([`MotionStore::segment`]).
    #[inline]
    pub fn position(&self, seg: (usize, f32), i: usize) -> Vec3 {
        self.at(&self.positions, seg, i)
    }

    /// Vertex `i`'s normal (not renormalised) at `seg`, if the mesh has normals.
    #[inline]
    pub fn normal(&self, seg: (usize, f32), i: usize) -> Vec3 {
        self.normals
            .as_ref()
            .map_or(Vec3::Z, |n| self.at(n, seg, i))
    }

    /// Vertex `i`'s tangent at `seg` (the handedness of the earlier key).
    #[inline]
    pub fn tangent(&self, seg: (usize, f32), i: usize) -> Vec4 {
        let Some(t) = self.tangents.as_ref() else {
            return Vec4::X;
        };
        let v = self.at(t, seg, i);
        Vec4::new(v.x, v.y, v.z, t[seg.0 * self.verts + i].w)
    }

    /// Bytes held, for reports.
    pub fn heap_bytes(&self) -> usize {
        self.positions.len() * 12
            + self.normals.as_ref().map_or(0, |v| v.len() * 12)
            + self.tangents.as_ref().map_or(0, |v| v.len() * 16)
    }
}

/// The moving primitives of a world and their keys.
#[derive(Clone, Debug, Default)]
pub struct MotionStore {
    /// Keys over the shutter (at least 2).
    pub keys: usize,
    /// Per flattened mesh (`GeometryStore::meshes`): its index in `meshes`, or [`STILL`].
    pub mesh_slot: Vec<u32>,
    pub meshes: Vec<MovingMesh>,
    /// Per sphere (`GeometryStore::spheres`): its index in `spheres` / keys, or [`STILL`].
    pub sphere_slot: Vec<u32>,
    /// Moving sphere s's key k at `s * keys + k`.
    pub spheres: Vec<Sphere>,
    /// Per quad (`GeometryStore::quads`): its index in `quads` / keys, or [`STILL`].
    pub quad_slot: Vec<u32>,
    /// Moving quad q's key k at `q * keys + k`: its corner and edges, interpolated linearly
    /// (so its corners are, and it stays a parallelogram).
    pub quads: Vec<Quad>,
    /// Per box (`GeometryStore::cuboids`): its index in `cuboids`, or [`STILL`].
    pub cuboid_slot: Vec<u32>,
    /// Moving box b's object-to-world transform over the shutter (its object-space box is the
    /// world's `Cuboid::local`): a ray meets the box placed by the transform at its time, as
    /// a moving instance.
    pub cuboids: Vec<KeyedTransform>,
    /// Per instance (`InstanceStore::instances`, in order): its world-from-object transform
    /// over the shutter if it moves. The world moves these into `InstanceStore::motion`.
    pub instance_motion: Vec<Option<KeyedTransform>>,
}

impl MotionStore {
    /// True if a mesh, sphere, box or quad moves (what the per-segment BVHs are built over).
    pub fn prims_move(&self) -> bool {
        !(self.meshes.is_empty()
            && self.spheres.is_empty()
            && self.quads.is_empty()
            && self.cuboids.is_empty())
    }

    /// The transform of box `i` over the shutter, if it moves.
    #[inline]
    fn cuboid_motion(&self, i: usize) -> Option<&KeyedTransform> {
        match self.cuboid_slot.get(i) {
            Some(&s) if s != STILL => Some(&self.cuboids[s as usize]),
            _ => None,
        }
    }

    /// Box `i` (its object-space box `local`) where it is at shutter time `u`, if it moves.
    #[inline]
    pub fn cuboid(&self, i: usize, local: &Bounds3, u: f32) -> Option<Cuboid> {
        Some(Cuboid::new(*local, self.cuboid_motion(i)?.at(u)))
    }

    /// The box of moving box `i` (object-space box `local`) over key segment `seg`.
    pub fn cuboid_sweep(&self, i: usize, local: &Bounds3, seg: usize) -> Option<Bounds3> {
        Some(self.cuboid_motion(i)?.segment_bounds(local, seg))
    }
}

/// Which of `segments` (≥ 1) equal key segments of the shutter holds time `u` (clamped to
/// [0, 1]), and the fraction into it: keys `k` and `k + 1` weighted `1 − f` and `f`. Every
/// keyed motion (moving vertices, transforms, the per-segment BVHs) splits the shutter so.
#[inline]
pub fn key_segment(u: f32, segments: usize) -> (usize, f32) {
    let x = u.clamp(0.0, 1.0) * segments as f32;
    let k = (x as usize).min(segments - 1);
    (k, x - k as f32)
}

impl MotionStore {
    /// The key segment holding shutter time `u` and the fraction into it: keys `k` and `k + 1`
    /// weighted `1 − f` and `f`.
    #[inline]
    pub fn segment(&self, u: f32) -> (usize, f32) {
        key_segment(u, self.keys - 1)
    }

    /// The moving mesh of flattened mesh `mesh`, if it moves.
    #[inline]
    pub fn mesh(&self, mesh: u32) -> Option<&MovingMesh> {
        match self.mesh_slot.get(mesh as usize) {
            Some(&s) if s != STILL => Some(&self.meshes[s as usize]),
            _ => None,
        }
    }

    /// Sphere `i` at shutter time `u`, if it moves.
    #[inline]
    pub fn sphere(&self, i: usize, u: f32) -> Option<Sphere> {
        let s = *self.sphere_slot.get(i)?;
        if s == STILL {
            return None;
        }
        let (k, f) = self.segment(u);
        let a = self.spheres[s as usize * self.keys + k];
        if f == 0.0 {
            return Some(a);
        }
        let b = self.spheres[s as usize * self.keys + k + 1];
        Some(Sphere {
            center: a.center * (1.0 - f) + b.center * f,
            radius: a.radius * (1.0 - f) + b.radius * f,
        })
    }

    /// Quad `i` at shutter time `u`, if it moves: its corner and edges interpolated between the
    /// two keys around u.
    #[inline]
    pub fn quad(&self, i: usize, u: f32) -> Option<Quad> {
        let s = *self.quad_slot.get(i)?;
        if s == STILL {
            return None;
        }
        let (k, f) = self.segment(u);
        let a = &self.quads[s as usize * self.keys + k];
        if f == 0.0 {
            return Some(*a);
        }
        let b = &self.quads[s as usize * self.keys + k + 1];
        let lerp = |x: Vec3, y: Vec3| x * (1.0 - f) + y * f;
        Some(Quad::new(
            lerp(a.corner, b.corner),
            lerp(a.e1, b.e1),
            lerp(a.e2, b.e2),
        ))
    }

    /// The box of moving quad `i` over key segment `seg`: its corners at the segment's two keys
    /// (each corner moves linearly between them).
    pub fn quad_sweep(&self, i: usize, seg: usize) -> Bounds3 {
        let s = self.quad_slot[i] as usize * self.keys + seg;
        let mut b = Bounds3::EMPTY;
        for q in &self.quads[s..s + 2] {
            for p in [
                q.corner,
                q.corner + q.e1,
                q.corner + q.e2,
                q.corner + q.e1 + q.e2,
            ] {
                b = b.union_point(p);
            }
        }
        b
    }

    /// A moving triangle with vertex indices `idx` of `mesh` at time `u`.
    #[inline]
    pub fn triangle(mesh: &MovingMesh, idx: [usize; 3], seg: (usize, f32)) -> TriangleVerts {
        TriangleVerts {
            p0: mesh.position(seg, idx[0]),
            p1: mesh.position(seg, idx[1]),
            p2: mesh.position(seg, idx[2]),
        }
    }

    /// The box of a moving triangle (vertices `vs` of moving mesh `mesh`) over key segment
    /// `seg` (between keys `seg` and `seg + 1`): the union of its boxes at the two keys, which
    /// holds it at every time between (a point moving linearly between two keys stays in the
    /// box of its two ends).
    pub fn triangle_sweep(&self, mesh: &MovingMesh, vs: [usize; 3], seg: usize) -> Bounds3 {
        let mut b = Bounds3::EMPTY;
        for k in seg..seg + 2 {
            for v in vs {
                b = b.union_point(mesh.positions[k * mesh.verts + v]);
            }
        }
        b
    }

    /// The box of moving sphere `i` over key segment `seg`, as [`Self::triangle_sweep`].
    pub fn sphere_sweep(&self, i: usize, seg: usize) -> Bounds3 {
        let s = self.sphere_slot[i] as usize * self.keys + seg;
        let mut b = Bounds3::EMPTY;
        for sp in &self.spheres[s..s + 2] {
            b = b
                .union_point(sp.center - Vec3::splat(sp.radius))
                .union_point(sp.center + Vec3::splat(sp.radius));
        }
        b
    }

    /// Bytes held by the keys, for reports and measurements.
    pub fn heap_bytes(&self) -> usize {
        self.meshes
            .iter()
            .map(MovingMesh::heap_bytes)
            .sum::<usize>()
            + self.spheres.len() * std::mem::size_of::<Sphere>()
            + self.quads.len() * std::mem::size_of::<Quad>()
            + self
                .cuboids
                .iter()
                .map(KeyedTransform::heap_bytes)
                .sum::<usize>()
            + (self.mesh_slot.len()
                + self.sphere_slot.len()
                + self.quad_slot.len()
                + self.cuboid_slot.len())
                * 4
    }
}

/// A transform moving over the shutter: its matrices at `n + 1` evenly spaced times, each
/// decomposed into translation, rotation and scale, interpolated piecewise (pbrt-v4
/// `AnimatedTransform::Interpolate`: translation and scale linearly, the rotation by slerp), so
/// a turn at a steady rate about a fixed axis is followed on its arc, not by chords. The moving
/// camera's transform and a moving instance's world-from-object transform.
#[derive(Clone, Debug)]
pub struct KeyedTransform {
    keys: Vec<(Vec3, Quat, Mat3)>,
}

/// Sub-times per key segment at which [`KeyedTransform::segment_bounds`] places the box.
const BOUND_SUBSTEPS: usize = 8;

impl KeyedTransform {
    /// From the transforms at the shutter's opening, `keys.len() − 2` times between and its
    /// closing (at least two).
    pub fn new(keys: &[Mat4]) -> KeyedTransform {
        assert!(keys.len() >= 2, "a moving transform needs two keys");
        let mut out: Vec<(Vec3, Quat, Mat3)> = Vec::with_capacity(keys.len());
        for &m in keys {
            let (s, mut r, t) = decompose(m);
            // q and −q are one rotation: keep each key on the previous one's side, so every
            // interval turns the short way.
            if let Some(prev) = out.last()
                && prev.1.dot(r) < 0.0
            {
                r = -r;
            }
            out.push((t, r, s));
        }
        KeyedTransform { keys: out }
    }

    /// Keys over the shutter.
    #[inline]
    pub fn keys(&self) -> usize {
        self.keys.len()
    }

    /// The transform at fraction `u` in [0, 1] of the shutter.
    #[inline]
    pub fn at(&self, u: f32) -> Mat4 {
        let (i, f) = key_segment(u, self.keys.len() - 1);
        self.interpolate(i, f)
    }

    /// The transform at fraction `f` of key segment `i` (between keys `i` and `i + 1`).
    #[inline]
    fn interpolate(&self, i: usize, f: f32) -> Mat4 {
        let (t0, r0, s0) = self.keys[i];
        let (t1, r1, s1) = self.keys[i + 1];
        let r = if f == 0.0 {
            r0
        } else {
            r0.slerp(r1, f).normalize()
        };
        let s = s0 * (1.0 - f) + s1 * f;
        Mat4::from_translation(t0.lerp(t1, f)) * Mat4::from_quat(r) * Mat4::from_mat3(s)
    }

    /// A box holding `object` (an object-space box) under the transform at every time of key
    /// segment `seg`. The box is placed at [`BOUND_SUBSTEPS`] + 1 times across the segment (an
    /// affine image of a box lies in the box of its corners' images) and grown by how far any
    /// of its points can move between two of those times: a point x moves as
    /// T(f) + R(f)·S(f)·x, at a speed (in f) of at most |ΔT| + θ·|S|·|x| + |ΔS|·|x|, θ the
    /// segment's rotation angle (slerp turns at a steady rate), |S| the larger key's Frobenius
    /// norm (a bound of the spectral norm, convex along the lerp), so within half a sub-step
    /// of one of the times. Rotation makes the points leave the box of the two keys, which
    /// holds only straight-line motion (pbrt-v4 `AnimatedTransform::MotionBounds` solves for
    /// the extrema instead).
    pub fn segment_bounds(&self, object: &Bounds3, seg: usize) -> Bounds3 {
        if object.is_empty() {
            return *object;
        }
        let (t0, r0, s0) = self.keys[seg];
        let (t1, r1, s1) = self.keys[seg + 1];
        let reach = (0..8)
            .map(|c| object.corner(c).length())
            .fold(0.0f32, f32::max);
        let frob = |m: Mat3| {
            (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared())
                .sqrt()
        };
        let theta = 2.0 * r0.dot(r1).abs().min(1.0).acos();
        let speed =
            (t1 - t0).length() + theta * frob(s0).max(frob(s1)) * reach + frob(s1 - s0) * reach;
        // A margin for the rounding of the interpolation and of slerp's near-parallel lerp.
        let pad = speed * 0.5 / BOUND_SUBSTEPS as f32 * 1.01 + 1e-6 * (reach + t0.length());
        let mut b = Bounds3::EMPTY;
        for i in 0..=BOUND_SUBSTEPS {
            let m = self.interpolate(seg, i as f32 / BOUND_SUBSTEPS as f32);
            for c in 0..8 {
                b = b.union_point(m.transform_point3(object.corner(c)));
            }
        }
        Bounds3::new(b.min - Vec3::splat(pad), b.max + Vec3::splat(pad))
    }

    /// Bytes held, for reports.
    pub fn heap_bytes(&self) -> usize {
        self.keys.len() * std::mem::size_of::<(Vec3, Quat, Mat3)>()
    }
}
