//! Ray–sphere intersection (thesis §5.1.5) with the numerically careful quadratic of Haines et al.,
//! "Precision Improvements for Ray/Sphere Intersection" (Ray Tracing Gems, ch. 7): the discriminant
//! is formed from the perpendicular distance to the centre, and the smaller root from the larger by
//! Vieta's formula to avoid cancellation. The hit point is re-projected onto the sphere (PBRT §3.9.4).

use super::Ray;
use crate::math::{Vec3, gamma};

#[derive(Clone, Copy, Debug)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

impl Sphere {
    /// Nearest `t ∈ (0, t_max)` where the ray meets the sphere, from outside or inside.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<f32> {
        let f = ray.o - self.center;
        let a = ray.d.length_squared();
        let b_half = -f.dot(ray.d);
        // |f − (f·d̂)d̂|², the squared distance from the centre to the line, computed without the
        // catastrophic cancellation of b² − 4ac.
        let l = f + ray.d * (b_half / a);
        let r2 = self.radius * self.radius;
        let disc = a * (r2 - l.length_squared());
        if !(disc >= 0.0) {
            return None;
        }
        let root = disc.sqrt();
        let q = if b_half >= 0.0 {
            b_half + root
        } else {
            b_half - root
        };
        let c = f.length_squared() - r2;
        let (mut t0, mut t1) = (c / q, q / a);
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        if t0 > 0.0 && t0 < t_max {
            Some(t0)
        } else if t1 > 0.0 && t1 < t_max {
            Some(t1)
        } else {
            None
        }
    }

    /// Hit point re-projected onto the surface, its error bound and the outward unit normal.
    #[inline]
    pub fn surface_point(&self, ray: &Ray, t: f32) -> (Vec3, Vec3, Vec3) {
        let mut local = ray.at(t) - self.center;
        let len = local.length();
        if len > 0.0 {
            local *= self.radius / len;
        }
        let p = self.center + local;
        let err = local.abs() * gamma(5) + self.center.abs() * gamma(1) + p.abs() * gamma(1);
        let n = if len > 0.0 {
            local / self.radius
        } else {
            Vec3::Z
        };
        (p, err, n)
    }

    /// Spherical (u, v) ∈ [0,1]² with v = 0 at the south pole (−y), u around the y axis.
    #[inline]
    pub fn uv(&self, n: Vec3) -> (f32, f32) {
        let phi = (-n.z).atan2(n.x);
        let u = (phi + std::f32::consts::PI) / (2.0 * std::f32::consts::PI);
        let v = n.y.clamp(-1.0, 1.0).acos();
        (u, 1.0 - v / std::f32::consts::PI)
    }

    pub fn area(&self) -> f32 {
        4.0 * std::f32::consts::PI * self.radius * self.radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s() -> Sphere {
        Sphere {
            center: Vec3::new(0.0, 0.0, -5.0),
            radius: 1.0,
        }
    }

    #[test]
    fn hit_from_outside() {
        let r = Ray::new(Vec3::ZERO, -Vec3::Z);
        let t = s().intersect(&r, f32::INFINITY).unwrap();
        assert!((t - 4.0).abs() < 1e-5);
        let (p, _, n) = s().surface_point(&r, t);
        assert!((p - Vec3::new(0.0, 0.0, -4.0)).length() < 1e-5);
        assert!((n - Vec3::Z).length() < 1e-5);
    }

    #[test]
    fn hit_from_inside_returns_far_root() {
        let r = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::X);
        let t = s().intersect(&r, f32::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-5);
    }

    #[test]
    fn misses_and_t_max() {
        let r = Ray::new(Vec3::ZERO, Vec3::Z);
        assert!(s().intersect(&r, f32::INFINITY).is_none());
        let r = Ray::new(Vec3::new(1.5, 0.0, 0.0), -Vec3::Z);
        assert!(s().intersect(&r, f32::INFINITY).is_none());
        let r = Ray::new(Vec3::ZERO, -Vec3::Z);
        assert!(s().intersect(&r, 3.0).is_none());
    }

    #[test]
    fn grazing_tangent_ray() {
        // Tangent at x = 1: a double root, which must be found (or at worst missed), never NaN.
        let r = Ray::new(Vec3::new(1.0, 0.0, 0.0), -Vec3::Z);
        if let Some(t) = s().intersect(&r, f32::INFINITY) {
            assert!((t - 5.0).abs() < 1e-2);
        }
        let r = Ray::new(Vec3::new(1.0001, 0.0, 0.0), -Vec3::Z);
        assert!(s().intersect(&r, f32::INFINITY).is_none());
    }

    #[test]
    fn small_sphere_far_away_is_accurate() {
        // The naive b² − 4ac loses all precision here; the robust form must still hit the centre.
        let sp = Sphere {
            center: Vec3::new(0.0, 0.0, -1e5),
            radius: 0.01,
        };
        let r = Ray::new(Vec3::ZERO, -Vec3::Z);
        let t = sp.intersect(&r, f32::INFINITY).expect("must hit");
        let (p, err, _) = sp.surface_point(&r, t);
        // At 1e5 f32 positions are spaced 0.0078 apart, coarser than the radius: the point can only
        // be as exact as its error bound says, and that bound must cover the true surface.
        assert!(((p - sp.center).length() - 0.01).abs() <= err.length());
        assert!(err.max_element() < 0.05);
        assert!(p.z > sp.center.z, "hit on the near side");
        let r = Ray::new(Vec3::new(0.0105, 0.0, 0.0), -Vec3::Z);
        assert!(sp.intersect(&r, f32::INFINITY).is_none());
    }

    #[test]
    fn unnormalised_direction_gives_parametric_t() {
        let r = Ray::new(Vec3::ZERO, -Vec3::Z * 2.0);
        let t = s().intersect(&r, f32::INFINITY).unwrap();
        assert!((t - 2.0).abs() < 1e-5);
    }
}
