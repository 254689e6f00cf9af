//! Boxes (thesis §5.1.6): an axis-aligned box in its own object space, placed in the world by an
//! affine transform, so rotated and sheared boxes are supported. The ray is carried into object space
//! (without renormalising, so `t` is shared) and tested with the Williams et al. slab test.

use super::{Bounds3, Ray, RayInv};
use crate::math::{Mat3, Mat4, Vec3, gamma};

#[derive(Clone, Copy, Debug)]
pub struct Cuboid {
    /// The box in object space.
    pub local: Bounds3,
    pub object_to_world: Mat4,
    pub world_to_object: Mat4,
}

/// A box hit: distance, object-space point and the axis/sign of the face hit.
#[derive(Clone, Copy, Debug)]
pub struct CuboidHit {
    pub t: f32,
    pub p_local: Vec3,
    pub axis: usize,
    pub positive: bool,
}

impl Cuboid {
    pub fn new(local: Bounds3, object_to_world: Mat4) -> Cuboid {
        Cuboid {
            local,
            object_to_world,
            world_to_object: object_to_world.inverse(),
        }
    }

    /// The ray in object space (not renormalised, so distances are shared with world space).
    #[inline]
    fn local_ray(&self, ray: &Ray, t_max: f32) -> Ray {
        Ray {
            o: self.world_to_object.transform_point3(ray.o),
            d: self.world_to_object.transform_vector3(ray.d),
            t_max,
            time: ray.time,
        }
    }

    /// Distance to the hit only: what the accelerator needs. The face is found later, once, by
    /// [`Cuboid::intersect`] for the closest hit (callgrind: snapping every candidate hit to its
    /// face was a third of the box test's cost).
    #[inline]
    pub fn intersect_t(&self, ray: &Ray, t_max: f32) -> Option<f32> {
        Self::slab_t(&self.local, &self.local_ray(ray, t_max), t_max)
    }

    #[inline]
    fn slab_t(local: &Bounds3, local_ray: &Ray, t_max: f32) -> Option<f32> {
        let inv = RayInv::new(local_ray.d);
        let (t0, t1) = local.intersect_p(local_ray, &inv)?;
        // From outside the nearest face is at t0; from inside (t0 clipped to 0) it is the exit face.
        let t = if t0 > 0.0 { t0 } else { t1 };
        (t > 0.0 && t < t_max).then_some(t)
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<CuboidHit> {
        let local_ray = self.local_ray(ray, t_max);
        let t = Self::slab_t(&self.local, &local_ray, t_max)?;
        Some(self.snap(&local_ray, t))
    }

    /// The hit at distance `t` along `ray`, where [`Cuboid::intersect_t`] found it: the same
    /// [`CuboidHit`] as [`Cuboid::intersect`] gives, without a second slab test.
    #[inline]
    pub fn hit_at(&self, ray: &Ray, t: f32) -> CuboidHit {
        self.snap(&self.local_ray(ray, f32::INFINITY), t)
    }

    /// The point at `t` along the object-space ray, snapped to the face it lies on.
    #[inline]
    fn snap(&self, local_ray: &Ray, t: f32) -> CuboidHit {
        let (o, d) = (local_ray.o, local_ray.d);
        let mut p = o + d * t;
        // Snap to the face that was hit: the coordinate closest (relative to size) to a face.
        let size = self.local.diagonal();
        let mut best = (0usize, false, f32::INFINITY);
        for axis in 0..3 {
            let dl = (p[axis] - self.local.min[axis]).abs() / size[axis].max(f32::MIN_POSITIVE);
            let dh = (p[axis] - self.local.max[axis]).abs() / size[axis].max(f32::MIN_POSITIVE);
            if dl < best.2 {
                best = (axis, false, dl);
            }
            if dh < best.2 {
                best = (axis, true, dh);
            }
        }
        let (axis, positive, _) = best;
        p[axis] = if positive {
            self.local.max[axis]
        } else {
            self.local.min[axis]
        };
        CuboidHit {
            t,
            p_local: p,
            axis,
            positive,
        }
    }

    /// World-space point, its error bound and the outward unit normal of a hit.
    #[inline]
    pub fn surface_point(&self, hit: &CuboidHit) -> (Vec3, Vec3, Vec3) {
        let p = self.object_to_world.transform_point3(hit.p_local);
        // Object-space error of the slab hit, carried through the transform (PBRT eq. 3.26).
        let m = Mat3::from_mat4(self.object_to_world);
        let abs_m = Mat3::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs());
        let err_local = hit.p_local.abs() * gamma(3);
        let err = abs_m * err_local
            + (abs_m * hit.p_local.abs() + self.object_to_world.w_axis.truncate().abs()) * gamma(3);
        let mut n_local = Vec3::ZERO;
        n_local[hit.axis] = if hit.positive { 1.0 } else { -1.0 };
        let n = crate::math::transform_normal(&self.world_to_object, n_local).normalize();
        (p, err, n)
    }

    /// Texture coordinates on a face: the two in-face object coordinates mapped to [0,1].
    #[inline]
    pub fn uv(&self, hit: &CuboidHit) -> (f32, f32) {
        let o = self.local.offset(hit.p_local);
        match hit.axis {
            0 => (o.z, o.y),
            1 => (o.x, o.z),
            _ => (o.x, o.y),
        }
    }

    pub fn world_bounds(&self) -> Bounds3 {
        (0..8).fold(Bounds3::EMPTY, |b, i| {
            b.union_point(self.object_to_world.transform_point3(self.local.corner(i)))
        })
    }

    /// The six faces as world-space parallelograms (corner, e1, e2) with outward normals e1 × e2.
    pub fn faces(&self) -> [super::quad::Quad; 6] {
        let (lo, hi) = (self.local.min, self.local.max);
        let m = &self.object_to_world;
        let p = |x: f32, y: f32, z: f32| m.transform_point3(Vec3::new(x, y, z));
        let quad = |c: Vec3, a: Vec3, b: Vec3| super::quad::Quad::new(c, a - c, b - c);
        let mut faces = [
            quad(
                p(lo.x, lo.y, lo.z),
                p(lo.x, lo.y, hi.z),
                p(lo.x, hi.y, lo.z),
            ), // −x
            quad(
                p(hi.x, lo.y, lo.z),
                p(hi.x, hi.y, lo.z),
                p(hi.x, lo.y, hi.z),
            ), // +x
            quad(
                p(lo.x, lo.y, lo.z),
                p(hi.x, lo.y, lo.z),
                p(lo.x, lo.y, hi.z),
            ), // −y
            quad(
                p(lo.x, hi.y, lo.z),
                p(lo.x, hi.y, hi.z),
                p(hi.x, hi.y, lo.z),
            ), // +y
            quad(
                p(lo.x, lo.y, lo.z),
                p(lo.x, hi.y, lo.z),
                p(hi.x, lo.y, lo.z),
            ), // −z
            quad(
                p(lo.x, lo.y, hi.z),
                p(hi.x, lo.y, hi.z),
                p(lo.x, hi.y, hi.z),
            ), // +z
        ];
        // A mirroring transform flips e1 × e2 inwards; swap the edges to keep normals outward.
        if Mat3::from_mat4(*m).determinant() < 0.0 {
            for f in &mut faces {
                *f = super::quad::Quad::new(f.corner, f.e2, f.e1);
            }
        }
        faces
    }

    pub fn area(&self) -> f32 {
        self.faces().iter().map(|f| f.area()).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box(m: Mat4) -> Cuboid {
        Cuboid::new(Bounds3::new(Vec3::splat(-1.0), Vec3::splat(1.0)), m)
    }

    #[test]
    fn hit_outside_and_normal() {
        let b = unit_box(Mat4::IDENTITY);
        let r = Ray::new(Vec3::new(0.2, 0.3, 5.0), -Vec3::Z);
        let h = b.intersect(&r, f32::INFINITY).unwrap();
        assert!((h.t - 4.0).abs() < 1e-5);
        let (p, _, n) = b.surface_point(&h);
        assert!((p.z - 1.0).abs() < 1e-6);
        assert!((n - Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn hit_from_inside_is_exit_face() {
        let b = unit_box(Mat4::IDENTITY);
        let r = Ray::new(Vec3::ZERO, Vec3::X);
        let h = b.intersect(&r, f32::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-5);
        let (_, _, n) = b.surface_point(&h);
        assert!((n - Vec3::X).length() < 1e-6);
    }

    #[test]
    fn rotated_and_scaled() {
        // Scale x by 2 then rotate 90° about y: the local x extent [-2,2] maps onto world z.
        let m = Mat4::from_rotation_y(std::f32::consts::FRAC_PI_2)
            * Mat4::from_scale(Vec3::new(2.0, 1.0, 1.0));
        let b = unit_box(m);
        let r = Ray::new(Vec3::new(0.0, 0.0, 10.0), -Vec3::Z);
        let h = b.intersect(&r, f32::INFINITY).unwrap();
        assert!((h.t - 8.0).abs() < 1e-4, "{}", h.t);
        let (p, err, n) = b.surface_point(&h);
        assert!((p.z - 2.0).abs() <= err.z + 1e-5);
        assert!((n - Vec3::Z).length() < 1e-5);
        let miss = Ray::new(Vec3::new(1.5, 0.0, 10.0), -Vec3::Z);
        assert!(b.intersect(&miss, f32::INFINITY).is_none());
    }

    #[test]
    fn grazing_edge_and_miss() {
        let b = unit_box(Mat4::IDENTITY);
        let r = Ray::new(Vec3::new(2.0, 0.0, 5.0), -Vec3::Z);
        assert!(b.intersect(&r, f32::INFINITY).is_none());
        let r = Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::Z);
        assert!(b.intersect(&r, f32::INFINITY).is_none());
    }

    #[test]
    fn far_from_origin() {
        let m = Mat4::from_translation(Vec3::splat(1e5));
        let b = unit_box(m);
        let r = Ray::new(Vec3::new(1e5, 1e5, 1e5 + 20.0), -Vec3::Z);
        let h = b.intersect(&r, f32::INFINITY).unwrap();
        let (p, err, _) = b.surface_point(&h);
        assert!((p.z - (1e5 + 1.0)).abs() <= err.z + 0.01);
    }

    #[test]
    fn faces_point_outward_even_when_mirrored() {
        for m in [Mat4::IDENTITY, Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0))] {
            let b = unit_box(m);
            for f in b.faces() {
                let center = f.corner + (f.e1 + f.e2) * 0.5;
                assert!(f.normal().dot(center) > 0.0);
            }
            assert!((b.area() - 24.0).abs() < 1e-4);
        }
    }
}
