//! Ray–triangle intersection (Möller & Trumbore 1997, "Fast, Minimum Storage Ray/Triangle
//! Intersection"; the thesis §5.1.4). The hit point is rebuilt from barycentrics, whose error bound
//! is PBRT eq. 3.31, rather than from `o + t·d`, which carries the error of `t`.

use super::Ray;
use crate::math::{Vec3, gamma};

/// A triangle's world-space vertices, stored inline for the intersection loop.
#[derive(Clone, Copy, Debug)]
pub struct TriangleVerts {
    pub p0: Vec3,
    pub p1: Vec3,
    pub p2: Vec3,
}

/// Result of a triangle test: distance and the barycentrics of `p1` and `p2`.
#[derive(Clone, Copy, Debug)]
pub struct TriangleHit {
    pub t: f32,
    pub b1: f32,
    pub b2: f32,
}

/// A triangle as its first vertex and two edges, the form the Möller–Trumbore test reads. The BVH
/// keeps its triangles in this form so a leaf test skips the two edge subtractions; the edges are
/// the same `p1 − p0`, `p2 − p0` the test would compute, so the hit is bit-identical.
#[derive(Clone, Copy, Debug)]
pub struct TriangleEdges {
    pub p0: Vec3,
    pub e1: Vec3,
    pub e2: Vec3,
}

impl TriangleEdges {
    /// Möller–Trumbore. Both faces are hit (culling is a shading decision, not a geometric one).
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<TriangleHit> {
        let (e1, e2) = (self.e1, self.e2);
        let pvec = ray.d.cross(e2);
        let det = e1.dot(pvec);
        // A degenerate triangle or a ray in its plane: no hit. `!(x != 0)` also rejects NaN.
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv_det = 1.0 / det;
        let tvec = ray.o - self.p0;
        let b1 = tvec.dot(pvec) * inv_det;
        if !(0.0..=1.0).contains(&b1) {
            return None;
        }
        let qvec = tvec.cross(e1);
        let b2 = ray.d.dot(qvec) * inv_det;
        if b2 < 0.0 || b1 + b2 > 1.0 {
            return None;
        }
        let t = e2.dot(qvec) * inv_det;
        // Reject hits too close to the origin to be distinguished from it: the spawned origin is
        // already offset by its error bound, so t must only be positive beyond rounding of t.
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        Some(TriangleHit { t, b1, b2 })
    }
}

impl TriangleVerts {
    /// The vertex-and-edges form of this triangle.
    #[inline]
    pub fn edges(&self) -> TriangleEdges {
        TriangleEdges {
            p0: self.p0,
            e1: self.p1 - self.p0,
            e2: self.p2 - self.p0,
        }
    }

    /// Möller–Trumbore on the edge form (see [`TriangleEdges::intersect`]).
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<TriangleHit> {
        self.edges().intersect(ray, t_max)
    }

    /// Point on the triangle at barycentrics `(1−b1−b2, b1, b2)` and its absolute error bound.
    #[inline]
    pub fn point(&self, b1: f32, b2: f32) -> (Vec3, Vec3) {
        let b0 = 1.0 - b1 - b2;
        let a = self.p0 * b0;
        let b = self.p1 * b1;
        let c = self.p2 * b2;
        let p = a + b + c;
        let err = (a.abs() + b.abs() + c.abs()) * gamma(7);
        (p, err)
    }

    /// Barycentrics `[b0, b1, b2]` of `p` projected onto the triangle's plane (PBRT §6.5.3's
    /// inverse of [`Self::point`], by the normal equations of the two edges); equal thirds for a
    /// degenerate triangle.
    pub fn barycentrics(&self, p: Vec3) -> [f32; 3] {
        let (e1, e2, d) = (self.p1 - self.p0, self.p2 - self.p0, p - self.p0);
        let (a11, a12, a22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let (r1, r2) = (e1.dot(d), e2.dot(d));
        let det = a11 * a22 - a12 * a12;
        if !(det.abs() > 0.0) || !det.is_finite() {
            return [1.0 / 3.0; 3];
        }
        let b1 = (a22 * r1 - a12 * r2) / det;
        let b2 = (a11 * r2 - a12 * r1) / det;
        [1.0 - b1 - b2, b1, b2]
    }

    /// Unnormalised geometric normal; its direction follows the counter-clockwise winding
    /// (p0 → p1 → p2), which defines the front face.
    #[inline]
    pub fn normal_unnormalized(&self) -> Vec3 {
        (self.p1 - self.p0).cross(self.p2 - self.p0)
    }

    /// Unit geometric normal (front face as in [`Self::normal_unnormalized`]); +z for a degenerate
    /// triangle, which has no direction of its own, so shading and light sampling stay finite.
    #[inline]
    pub fn unit_normal(&self) -> Vec3 {
        let n = self.normal_unnormalized();
        if n.length_squared() > 0.0 {
            n.normalize()
        } else {
            Vec3::Z
        }
    }

    #[inline]
    pub fn area(&self) -> f32 {
        0.5 * self.normal_unnormalized().length()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> TriangleVerts {
        TriangleVerts {
            p0: Vec3::new(0.0, 0.0, 0.0),
            p1: Vec3::new(1.0, 0.0, 0.0),
            p2: Vec3::new(0.0, 1.0, 0.0),
        }
    }

    #[test]
    fn hit_front_and_back() {
        let t = tri();
        let front = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
        let h = t.intersect(&front, f32::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!((h.b1 - 0.25).abs() < 1e-6 && (h.b2 - 0.25).abs() < 1e-6);
        let back = Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z);
        assert!(t.intersect(&back, f32::INFINITY).is_some());
        // The normal follows the CCW winding: +z.
        assert!(t.normal_unnormalized().z > 0.0);
    }

    #[test]
    fn misses() {
        let t = tri();
        // Outside each edge.
        for o in [
            Vec3::new(-0.1, 0.5, 1.0),
            Vec3::new(0.5, -0.1, 1.0),
            Vec3::new(0.6, 0.6, 1.0),
        ] {
            assert!(t.intersect(&Ray::new(o, -Vec3::Z), f32::INFINITY).is_none());
        }
        // Behind the origin.
        let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), Vec3::Z);
        assert!(t.intersect(&r, f32::INFINITY).is_none());
        // Beyond t_max.
        let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
        assert!(t.intersect(&r, 0.5).is_none());
    }

    #[test]
    fn grazing_ray_in_plane_misses() {
        let t = tri();
        let r = Ray::new(Vec3::new(-1.0, 0.25, 0.0), Vec3::X);
        assert!(t.intersect(&r, f32::INFINITY).is_none());
    }

    #[test]
    fn degenerate_triangle_never_hits() {
        let t = TriangleVerts {
            p0: Vec3::ZERO,
            p1: Vec3::X,
            p2: Vec3::X * 2.0,
        };
        let r = Ray::new(Vec3::new(0.5, 0.0, 1.0), -Vec3::Z);
        assert!(t.intersect(&r, f32::INFINITY).is_none());
    }

    #[test]
    fn far_from_origin_hit_point_within_error_bound() {
        let off = Vec3::new(1e5, -2e5, 3e5);
        let t = TriangleVerts {
            p0: off,
            p1: off + Vec3::X * 10.0,
            p2: off + Vec3::Y * 10.0,
        };
        let r = Ray::new(off + Vec3::new(2.0, 3.0, 50.0), -Vec3::Z);
        let h = t.intersect(&r, f32::INFINITY).unwrap();
        let (p, err) = t.point(h.b1, h.b2);
        let exact = off + Vec3::new(2.0, 3.0, 0.0);
        for i in 0..3 {
            // The bound is conservative: the true plane (z = off.z exactly) lies within it.
            assert!(
                (p[i] - exact[i]).abs() <= err[i] + 0.05,
                "axis {i}: {p} vs {exact} ± {err}"
            );
        }
        assert!((p.z - exact.z).abs() <= err.z);
    }

    #[test]
    fn nan_ray_never_hits() {
        let r = Ray::new(Vec3::new(f32::NAN, 0.0, 1.0), -Vec3::Z);
        assert!(tri().intersect(&r, f32::INFINITY).is_none());
    }
}
