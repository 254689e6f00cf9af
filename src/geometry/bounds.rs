//! Axis-aligned bounding boxes and the robust slab test (Williams et al. 2005; PBRT §3.9.2 for the
//! γ(3) enlargement that keeps the test conservative under rounding).

use super::{Ray, RayInv};
use crate::math::{Vec3, gamma};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds3 {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Bounds3 {
    fn default() -> Self {
        Bounds3::EMPTY
    }
}

impl Bounds3 {
    pub const EMPTY: Bounds3 = Bounds3 {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    #[inline]
    pub fn new(a: Vec3, b: Vec3) -> Bounds3 {
        Bounds3 {
            min: a.min(b),
            max: a.max(b),
        }
    }

    #[inline]
    pub fn from_point(p: Vec3) -> Bounds3 {
        Bounds3 { min: p, max: p }
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    #[inline]
    pub fn union(&self, o: &Bounds3) -> Bounds3 {
        Bounds3 {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    #[inline]
    pub fn union_point(&self, p: Vec3) -> Bounds3 {
        Bounds3 {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    #[inline]
    pub fn diagonal(&self) -> Vec3 {
        self.max - self.min
    }

    #[inline]
    pub fn centroid(&self) -> Vec3 {
        let c = (self.min + self.max) * 0.5;
        if c.is_finite() || !(self.min.is_finite() && self.max.is_finite()) {
            return c;
        }
        // The sum overflowed (both sides beyond f32::MAX / 2): halve first.
        self.min * 0.5 + self.max * 0.5
    }

    /// Surface area; zero for an empty box.
    #[inline]
    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let d = self.diagonal();
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    /// Index of the longest axis.
    #[inline]
    pub fn max_extent(&self) -> usize {
        let d = self.diagonal();
        if d.x > d.y && d.x > d.z {
            0
        } else if d.y > d.z {
            1
        } else {
            2
        }
    }

    /// Position of `p` relative to the box: 0 at `min`, 1 at `max`, per axis.
    #[inline]
    pub fn offset(&self, p: Vec3) -> Vec3 {
        let mut o = p - self.min;
        let d = self.diagonal();
        for i in 0..3 {
            if d[i] > 0.0 {
                o[i] /= d[i];
            }
        }
        o
    }

    #[inline]
    pub fn corner(&self, i: usize) -> Vec3 {
        Vec3::new(
            if i & 1 == 0 { self.min.x } else { self.max.x },
            if i & 2 == 0 { self.min.y } else { self.max.y },
            if i & 4 == 0 { self.min.z } else { self.max.z },
        )
    }

    /// Smallest sphere containing the box: (centre, radius).
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        if self.is_empty() {
            return (Vec3::ZERO, 0.0);
        }
        let c = self.centroid();
        let d = self.max - c;
        let r = d.length();
        if r.is_finite() || !d.is_finite() {
            return (c, r);
        }
        // The squared length overflowed (half-extents beyond ~1.8e19): scale by the largest
        // component first, so finite bounds give a finite radius.
        let m = d.abs().max_element();
        (c, m * (d / m).length())
    }

    /// Slab test returning the parametric entry and exit distances clipped to `(0, ray.t_max)`, or
    /// `None` on a miss. NaNs from 0·∞ (ray in a slab's plane) are rejected by the comparisons'
    /// ordering.
    #[inline]
    pub fn intersect_p(&self, ray: &Ray, inv: &RayInv) -> Option<(f32, f32)> {
        let bounds = [self.min, self.max];
        let mut t0 = (bounds[inv.neg[0]].x - ray.o.x) * inv.inv_d.x;
        let mut t1 = (bounds[1 - inv.neg[0]].x - ray.o.x) * inv.inv_d.x;
        let ty0 = (bounds[inv.neg[1]].y - ray.o.y) * inv.inv_d.y;
        let mut ty1 = (bounds[1 - inv.neg[1]].y - ray.o.y) * inv.inv_d.y;
        // Enlarge the far distances so the test stays conservative under rounding (PBRT eq. 3.22).
        let g = 1.0 + 2.0 * gamma(3);
        t1 *= g;
        ty1 *= g;
        if t0 > ty1 || ty0 > t1 {
            return None;
        }
        if ty0 > t0 {
            t0 = ty0;
        }
        if ty1 < t1 {
            t1 = ty1;
        }
        let tz0 = (bounds[inv.neg[2]].z - ray.o.z) * inv.inv_d.z;
        let mut tz1 = (bounds[1 - inv.neg[2]].z - ray.o.z) * inv.inv_d.z;
        tz1 *= g;
        if t0 > tz1 || tz0 > t1 {
            return None;
        }
        if tz0 > t0 {
            t0 = tz0;
        }
        if tz1 < t1 {
            t1 = tz1;
        }
        if t0 < ray.t_max && t1 > 0.0 {
            Some((t0.max(0.0), t1.min(ray.t_max)))
        } else {
            None
        }
    }

    /// Same as [`Bounds3::intersect_p`] but only answers hit/miss; used by BVH traversal.
    #[inline]
    pub fn hit(&self, ray: &Ray, inv: &RayInv, t_max: f32) -> bool {
        let lo = self.min;
        let hi = self.max;
        let (bx0, bx1) = if inv.neg[0] == 0 {
            (lo.x, hi.x)
        } else {
            (hi.x, lo.x)
        };
        let (by0, by1) = if inv.neg[1] == 0 {
            (lo.y, hi.y)
        } else {
            (hi.y, lo.y)
        };
        let (bz0, bz1) = if inv.neg[2] == 0 {
            (lo.z, hi.z)
        } else {
            (hi.z, lo.z)
        };
        let g = 1.0 + 2.0 * gamma(3);
        let tx0 = (bx0 - ray.o.x) * inv.inv_d.x;
        let tx1 = (bx1 - ray.o.x) * inv.inv_d.x * g;
        let ty0 = (by0 - ray.o.y) * inv.inv_d.y;
        let ty1 = (by1 - ray.o.y) * inv.inv_d.y * g;
        let tz0 = (bz0 - ray.o.z) * inv.inv_d.z;
        let tz1 = (bz1 - ray.o.z) * inv.inv_d.z * g;
        // max/min written so that a NaN (0·∞) operand is ignored rather than propagated.
        let t0 = fmax(fmax(tx0, ty0), fmax(tz0, 0.0));
        let t1 = fmin(fmin(tx1, ty1), fmin(tz1, t_max));
        t0 <= t1
    }
}

#[inline(always)]
fn fmax(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

#[inline(always)]
fn fmin(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Bounds3 {
        Bounds3::new(Vec3::splat(-1.0), Vec3::splat(1.0))
    }

    fn both(b: &Bounds3, r: &Ray) -> (bool, bool) {
        let inv = RayInv::new(r.d);
        (b.intersect_p(r, &inv).is_some(), b.hit(r, &inv, r.t_max))
    }

    #[test]
    fn hits_and_misses() {
        let b = unit();
        let hit = Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z);
        assert_eq!(both(&b, &hit), (true, true));
        let (t0, t1) = b.intersect_p(&hit, &RayInv::new(hit.d)).unwrap();
        assert!((t0 - 4.0).abs() < 1e-5 && (t1 - 6.0).abs() < 1e-4);
        let miss = Ray::new(Vec3::new(2.0, 0.0, 5.0), -Vec3::Z);
        assert_eq!(both(&b, &miss), (false, false));
        let behind = Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::Z);
        assert_eq!(both(&b, &behind), (false, false));
    }

    #[test]
    fn inside_origin_hits() {
        let r = Ray::new(Vec3::ZERO, Vec3::new(0.3, -0.2, 1.0));
        assert_eq!(both(&unit(), &r), (true, true));
    }

    #[test]
    fn axis_parallel_ray_in_slab_plane() {
        // Ray travelling along the box's face plane x = 1: grazing; must not produce NaN hits
        // outside the box.
        let b = unit();
        let r = Ray::new(Vec3::new(5.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(both(&b, &r), (false, false));
        let r = Ray::new(Vec3::new(0.5, 0.0, -5.0), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(both(&b, &r), (true, true));
    }

    #[test]
    fn t_max_limits_hits() {
        let b = unit();
        let mut r = Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z);
        r.t_max = 3.0;
        assert_eq!(both(&b, &r), (false, false));
    }

    #[test]
    fn far_from_origin() {
        let b = Bounds3::new(Vec3::splat(1e6), Vec3::splat(1e6 + 1.0));
        let r = Ray::new(Vec3::new(1e6 + 0.5, 1e6 + 0.5, 0.0), Vec3::Z);
        assert_eq!(both(&b, &r), (true, true));
    }

    #[test]
    fn surface_area_and_union() {
        let b = unit();
        assert_eq!(b.surface_area(), 24.0);
        assert_eq!(Bounds3::EMPTY.surface_area(), 0.0);
        let u = Bounds3::EMPTY.union(&b);
        assert_eq!(u, b);
    }
}
