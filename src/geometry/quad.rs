//! Ray–parallelogram intersection: the plane hit followed by the parallelogram's own coordinates,
//! p = corner + u·e1 + v·e2 with (u, v) ∈ [0,1]². The normal e1 × e2 defines the front face.

use super::Ray;
use crate::math::{Vec3, gamma};

#[derive(Clone, Copy, Debug)]
pub struct Quad {
    pub corner: Vec3,
    pub e1: Vec3,
    pub e2: Vec3,
    /// e1 × e2 and (e1 × e2)/|e1 × e2|², precomputed by [`Quad::new`]: the intersection test needs
    /// both for every candidate and computing them there was a third of its instructions.
    n: Vec3,
    w: Vec3,
    /// The unit normal, the unit ∂p/∂u and the area, precomputed for the same reason: every hit
    /// and every light sample on the quad needs them, and each cost a square root and a division.
    unit_n: Vec3,
    unit_e1: Vec3,
    area: f32,
}

impl Quad {
    pub fn new(corner: Vec3, e1: Vec3, e2: Vec3) -> Quad {
        let n = e1.cross(e2);
        Quad {
            corner,
            e1,
            e2,
            n,
            w: n / n.length_squared(),
            unit_n: n.normalize(),
            unit_e1: e1.normalize(),
            area: n.length(),
        }
    }

    /// Distance and (u, v) of the hit, or `None`.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<(f32, f32, f32)> {
        let n = self.n;
        let denom = n.dot(ray.d);
        if denom == 0.0 || !denom.is_finite() {
            return None;
        }
        let t = n.dot(self.corner - ray.o) / denom;
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        let q = ray.at(t) - self.corner;
        let w = self.w;
        let u = w.dot(q.cross(self.e2));
        let v = w.dot(self.e1.cross(q));
        if !(0.0..=1.0).contains(&u) || !(0.0..=1.0).contains(&v) {
            return None;
        }
        Some((t, u, v))
    }

    /// Point at (u, v) and its error bound.
    #[inline]
    pub fn point(&self, u: f32, v: f32) -> (Vec3, Vec3) {
        let a = self.e1 * u;
        let b = self.e2 * v;
        let p = self.corner + a + b;
        let err = (self.corner.abs() + a.abs() + b.abs()) * gamma(5);
        (p, err)
    }

    /// Unit normal, the front side's (e1 × e2 normalised).
    #[inline]
    pub fn normal(&self) -> Vec3 {
        self.unit_n
    }

    /// Unit ∂p/∂u (e1 normalised): the tangent of the surface frame.
    #[inline]
    pub fn tangent(&self) -> Vec3 {
        self.unit_e1
    }

    #[inline]
    pub fn area(&self) -> f32 {
        self.area
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q() -> Quad {
        Quad::new(
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        )
    }

    #[test]
    fn hit_and_uv() {
        let r = Ray::new(Vec3::new(0.5, 0.0, 2.0), -Vec3::Z);
        let (t, u, v) = q().intersect(&r, f32::INFINITY).unwrap();
        assert!((t - 2.0).abs() < 1e-6);
        assert!((u - 0.75).abs() < 1e-6 && (v - 0.5).abs() < 1e-6);
        assert!((q().normal() - Vec3::Z).length() < 1e-6);
        let back = Ray::new(Vec3::new(0.5, 0.0, -2.0), Vec3::Z);
        assert!(q().intersect(&back, f32::INFINITY).is_some());
    }

    #[test]
    fn misses_grazing_and_t_max() {
        let r = Ray::new(Vec3::new(1.5, 0.0, 2.0), -Vec3::Z);
        assert!(q().intersect(&r, f32::INFINITY).is_none());
        let r = Ray::new(Vec3::new(-2.0, 0.0, 0.0), Vec3::X);
        assert!(q().intersect(&r, f32::INFINITY).is_none());
        let r = Ray::new(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z);
        assert!(q().intersect(&r, 1.0).is_none());
        let r = Ray::new(Vec3::new(0.0, 0.0, 2.0), Vec3::Z);
        assert!(q().intersect(&r, f32::INFINITY).is_none());
    }

    #[test]
    fn far_from_origin() {
        let mut quad = q();
        quad.corner += Vec3::new(3e5, 3e5, -4e5);
        let r = Ray::new(Vec3::new(3e5, 3e5, -4e5 + 10.0), -Vec3::Z);
        let (t, u, v) = quad.intersect(&r, f32::INFINITY).unwrap();
        let (p, err) = quad.point(u, v);
        assert!((t - 10.0).abs() < 0.1);
        assert!((p.z - (-4e5)).abs() <= err.z);
    }
}
