//! Sampling points on primitives, for area lights (thesis §5.4.2): every shape is sampled
//! uniformly by area (pdf 1/A, PBRT §6.1–6.5 `Shape::Sample` by area), which the light sampler
//! converts to solid angle (PBRT eq. 4.9). Spheres are sampled over their whole surface here; a
//! sphere light seen from outside is sampled over its cone instead ([`sample_sphere_cone`], below).
//! A box picks a face in proportion to area.

use super::motion::MotionStore;
use super::primitive::{GeometryStore, PrimRef, PrimitiveKind, SurfaceHit};
use super::sphere::Sphere;
use super::triangle::TriangleVerts;
use crate::math::{PI, Vec2, Vec3};
use crate::sampling::warp;

impl GeometryStore {
    /// A point on `prim` sampled uniformly by area from `u` ∈ [0, 1)², with what light sampling
    /// needs of it: position, error bound, geometric normal (the front side), texture
    /// coordinates (for emissive textures), material and light index. The shading normal equals
    /// the geometric one and no tangent frame is built. Its area pdf is `1 / self.area(prim)`.
    pub fn sample_point(&self, prim: PrimRef, u: Vec2) -> SurfaceHit {
        let i = prim.index();
        let mut hit = self.blank_hit(prim, 0.0);
        match prim.kind() {
            PrimitiveKind::Triangle => {
                let (b1, b2) = warp::uniform_triangle(u);
                self.emitter_point(prim, b1, b2, &mut hit);
            }
            PrimitiveKind::Quad => self.emitter_point(prim, u.x, u.y, &mut hit),
            PrimitiveKind::Sphere => sphere_point(&self.spheres[i].shape, u, &mut hit),
            PrimitiveKind::Cuboid => {
                // Pick a face in proportion to area, reusing u.x rescaled.
                let faces = self.cuboids[i].shape.faces();
                let areas = faces.map(|f| f.area());
                let total: f32 = areas.iter().sum();
                let mut target = u.x * total;
                let mut k = 0;
                while k < 5 && target >= areas[k] {
                    target -= areas[k];
                    k += 1;
                }
                let ux = if areas[k] > 0.0 {
                    (target / areas[k]).clamp(0.0, 1.0)
                } else {
                    0.5
                };
                let f = &faces[k];
                let (p, err) = f.point(ux, u.y);
                hit.p = p;
                hit.p_error = err;
                hit.ng = f.normal();
                hit.ns = hit.ng;
                hit.uv = [Vec2::new(ux, u.y); 2];
            }
            // Curves are not emitters (`world::area_lights` skips them, as pbrt-v4 cannot
            // sample them): the point on the centre line, facing nowhere in particular.
            PrimitiveKind::Curve => {
                let c = &self.curves[i].shape;
                let (p, dp) = super::curve::bezier(&c.cp, u.x);
                hit.p = p;
                hit.ng = dp.normalize_or_zero().any_orthonormal_vector();
                hit.ns = hit.ng;
                hit.uv = [Vec2::new(u.x, 0.5); 2];
            }
        }
        hit
    }

    /// The position and error bound of [`GeometryStore::sample_point`] for the flat shapes
    /// (triangles and quads), without building a [`SurfaceHit`]: the same arithmetic, so the same
    /// point. `None` for spheres and boxes.
    #[inline]
    pub fn sample_flat_position(&self, prim: PrimRef, u: Vec2) -> Option<(Vec3, Vec3)> {
        let i = prim.index();
        match prim.kind() {
            PrimitiveKind::Quad => Some(self.quads[i].shape.point(u.x, u.y)),
            PrimitiveKind::Triangle => {
                let (b1, b2) = warp::uniform_triangle(u);
                Some(self.triangles[i].point(b1, b2))
            }
            PrimitiveKind::Sphere | PrimitiveKind::Cuboid | PrimitiveKind::Curve => None,
        }
    }

    /// What light sampling needs of a point on a triangle or quad at (b1, b2): position, error
    /// bound, geometric normal and texture coordinates (for emissive textures). Skips the shading
    /// normal, vertex colour and tangent frame that [`GeometryStore::surface_hit`] builds, which
    /// made a light sample on a UV-mapped mesh cost as much as a full hit (callgrind).
    /// Spheres and boxes are left unchanged.
    #[inline]
    fn emitter_point(&self, prim: PrimRef, b1: f32, b2: f32, hit: &mut SurfaceHit) {
        let i = prim.index();
        match prim.kind() {
            PrimitiveKind::Triangle => {
                self.triangle_point(&self.triangles[i], i, b1, b2, hit);
            }
            PrimitiveKind::Quad => quad_point(&self.quads[i].shape, b1, b2, hit),
            // Spheres and boxes are sampled by `sample_point` directly.
            PrimitiveKind::Sphere | PrimitiveKind::Cuboid | PrimitiveKind::Curve => {}
        }
    }
    /// [`GeometryStore::emitter_point`] on flat triangle `i` with its vertices at `tri` (the
    /// stored ones, or a moving triangle's at a time): the texture coordinates are the mesh's.
    #[inline(always)]
    fn triangle_point(
        &self,
        tri: &TriangleVerts,
        i: usize,
        b1: f32,
        b2: f32,
        hit: &mut SurfaceHit,
    ) {
        let (p, err) = tri.point(b1, b2);
        hit.p = p;
        hit.p_error = err;
        hit.ng = tri.unit_normal();
        hit.ns = hit.ng;
        let (mesh_i, local) = self.tri_mesh[i];
        let mesh = &self.meshes[mesh_i as usize];
        if mesh.uv0.is_some() || mesh.uv1.is_some() {
            let [i0, i1, i2] = mesh.indices[local as usize].map(|x| x as usize);
            let b0 = 1.0 - b1 - b2;
            let lerp2 = |uv: &[Vec2]| uv[i0] * b0 + uv[i1] * b1 + uv[i2] * b2;
            if let Some(uv) = &mesh.uv0 {
                hit.uv[0] = lerp2(uv);
            }
            hit.uv[1] = mesh.uv1.as_deref().map_or(hit.uv[0], lerp2);
        }
    }

    /// True when `prim` moves during the shutter (it has keys in [`GeometryStore::motion`]):
    /// a moving triangle of a flattened mesh, a moving sphere or a moving quad.
    pub fn moves(&self, prim: PrimRef) -> bool {
        let Some(m) = &self.motion else {
            return false;
        };
        match prim.kind() {
            PrimitiveKind::Triangle => self.moving_triangle(prim.index()).is_some(),
            PrimitiveKind::Sphere => m
                .sphere_slot
                .get(prim.index())
                .is_some_and(|&s| s != super::motion::STILL),
            PrimitiveKind::Quad => m
                .quad_slot
                .get(prim.index())
                .is_some_and(|&s| s != super::motion::STILL),
            _ => false,
        }
    }

    /// Flat triangle `i` where it is at shutter time `time`, if it moves (the vertices a ray at
    /// that time meets, `GeometryStore::intersect_moving`).
    #[inline]
    pub fn triangle_at(&self, i: usize, time: f32) -> Option<TriangleVerts> {
        let m = self.motion.as_ref()?;
        let (mesh, idx) = self.moving_triangle(i)?;
        Some(MotionStore::triangle(mesh, idx, m.segment(time)))
    }

    /// The sphere `prim` where it is at shutter time `time`, if it is a moving sphere (`None`
    /// for a primitive of another kind: its index is not a sphere's).
    #[inline]
    pub fn sphere_at(&self, prim: PrimRef, time: f32) -> Option<Sphere> {
        if prim.kind() != PrimitiveKind::Sphere {
            return None;
        }
        self.motion.as_ref()?.sphere(prim.index(), time)
    }

    /// The area of `prim` at shutter time `time`: a moving triangle's changes as its vertices
    /// move independently (a deforming mesh; a rotation followed by chords), a moving sphere's
    /// with its radius; the stored area otherwise.
    #[inline]
    pub fn area_at(&self, prim: PrimRef, time: f32) -> f32 {
        let moved = match prim.kind() {
            PrimitiveKind::Triangle => self.triangle_at(prim.index(), time).map(|t| t.area()),
            PrimitiveKind::Sphere => self.sphere_at(prim, time).map(|s| s.area()),
            PrimitiveKind::Quad => self
                .motion
                .as_ref()
                .and_then(|m| m.quad(prim.index(), time))
                .map(|q| q.area()),
            _ => None,
        };
        moved.unwrap_or_else(|| self.area(prim))
    }

    /// [`GeometryStore::sample_point`] at shutter time `time`: on a moving primitive, a point
    /// uniform by area on its shape at that time (area pdf `1 / area_at(prim, time)`); the hit
    /// carries `time`. A primitive that does not move is sampled as a still's.
    pub fn sample_point_at(&self, prim: PrimRef, u: Vec2, time: f32) -> SurfaceHit {
        let i = prim.index();
        let mut hit = match prim.kind() {
            PrimitiveKind::Triangle => match self.triangle_at(i, time) {
                Some(tri) => {
                    let mut hit = self.blank_hit(prim, 0.0);
                    let (b1, b2) = warp::uniform_triangle(u);
                    self.triangle_point(&tri, i, b1, b2, &mut hit);
                    hit
                }
                None => self.sample_point(prim, u),
            },
            PrimitiveKind::Sphere => match self.sphere_at(prim, time) {
                Some(s) => {
                    let mut hit = self.blank_hit(prim, 0.0);
                    sphere_point(&s, u, &mut hit);
                    hit
                }
                None => self.sample_point(prim, u),
            },
            PrimitiveKind::Quad => match self.motion.as_ref().and_then(|m| m.quad(i, time)) {
                Some(q) => {
                    let mut hit = self.blank_hit(prim, 0.0);
                    quad_point(&q, u.x, u.y, &mut hit);
                    hit
                }
                None => self.sample_point(prim, u),
            },
            _ => self.sample_point(prim, u),
        };
        hit.time = time;
        hit
    }
}

/// The point of quad `q` at (u, v), with its normal and texture coordinates.
#[inline(always)]
fn quad_point(q: &super::quad::Quad, u: f32, v: f32, hit: &mut SurfaceHit) {
    let (p, err) = q.point(u, v);
    hit.p = p;
    hit.p_error = err;
    hit.ng = q.normal();
    hit.ns = hit.ng;
    hit.uv = [Vec2::new(u, v); 2];
}

/// A point of sphere `s` uniform by area from `u`, with its normal and texture coordinates.
#[inline]
fn sphere_point(s: &Sphere, u: Vec2, hit: &mut SurfaceHit) {
    let n = warp::uniform_sphere(u);
    let local = n * s.radius;
    hit.p = s.center + local;
    hit.p_error = local.abs() * crate::math::gamma(5) + s.center.abs() * crate::math::gamma(1);
    hit.ng = n;
    hit.ns = n;
    let (su, sv) = s.uv(n);
    hit.uv = [Vec2::new(su, sv); 2];
}

/// Below this sin²θmax the cone of a sphere is so narrow that 1 − cos θmax loses its digits in f32:
/// pbrt-v4's threshold (sin² 1.5°) for switching to the Taylor expansion.
const SPHERE_SMALL_SIN2: f32 = 0.000_685_23;

/// The cone of directions a sphere (`center`, `radius`) subtends from `p`, as
/// (sin²θmax, 1 − cos θmax), or `None` when `p` is inside or on it.
#[inline]
pub(crate) fn sphere_cone(center: Vec3, radius: f32, p: Vec3) -> Option<(f32, f32)> {
    let d2 = (p - center).length_squared();
    // A margin above the surface: points on the sphere (its own shadow-ray origins) are inside.
    if !(d2 > radius * radius * 1.0001) {
        return None;
    }
    let sin2_max = radius * radius / d2;
    let one_minus = if sin2_max < SPHERE_SMALL_SIN2 {
        // 1 − √(1 − x) ≈ x/2 (+ x²/8), where the difference would cancel.
        sin2_max / 2.0 + sin2_max * sin2_max / 8.0
    } else {
        1.0 - (1.0 - sin2_max).max(0.0).sqrt()
    };
    Some((sin2_max, one_minus))
}

/// Samples a sphere light seen from outside uniformly over the solid angle it subtends
/// (pbrt-v4 §6.2.4, `Sphere::Sample(ctx, u)`; Shirley & Wang 1996): a direction in the cone
/// toward the centre, then the point where it meets the sphere (computed from the angle α at the
/// centre, which is stable where a ray–sphere intersection is not). Area sampling of the whole
/// sphere wastes the back half and weights the visible cap by distance and cosine; the cone's
/// pdf 1/(2π(1 − cos θmax)) is constant, so an unoccluded sphere of constant radiance gives
/// zero-variance estimates. Returns the point, its outward normal and the solid-angle pdf, or
/// `None` from inside the sphere (then it is sampled by area).
#[inline]
pub(crate) fn sample_sphere_cone(
    center: Vec3,
    radius: f32,
    p: Vec3,
    u: Vec2,
) -> Option<(Vec3, Vec3, f32)> {
    let (sin2_max, one_minus) = sphere_cone(center, radius, p)?;
    let (sin2_t, cos_t) = if sin2_max < SPHERE_SMALL_SIN2 {
        // sin²θ = sin²θmax · u: the small-cone form of cos θ = 1 − u (1 − cos θmax).
        let s2 = sin2_max * u.x;
        (s2, (1.0 - s2).sqrt())
    } else {
        let c = 1.0 - u.x * one_minus;
        ((1.0 - c * c).max(0.0), c)
    };
    // The angle α at the centre between the direction to p and the sampled point.
    let cos_a = sin2_t / sin2_max.sqrt() + cos_t * (1.0 - sin2_t / sin2_max).max(0.0).sqrt();
    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
    let phi = u.y * 2.0 * PI;
    let to_p = (p - center).normalize();
    let frame = crate::math::Frame::from_normal(to_p);
    let n = frame.to_world(Vec3::new(sin_a * phi.cos(), sin_a * phi.sin(), cos_a));
    let point = center + n * radius;
    Some((point, n, 1.0 / (2.0 * PI * one_minus)))
}
