//! Cubic Bézier curves (pbrt-v4's `curve` shape; PBRT-v4 §6.7): a piece [u_min, u_max] of one
//! Bézier segment swept with a width that varies linearly along it, as a `flat` ribbon that
//! always faces the ray, a `cylinder` (the flat ribbon shaded with the normals of a tube) or an
//! oriented `ribbon` (normals given at the segment's ends, interpolated spherically).
//!
//! The ray test is pbrt-v4's `Curve::IntersectRay` (Nakamaru and Ohno 2002): the control points
//! are projected into a frame whose z axis is the ray, the curve is subdivided at the midpoint
//! until each piece is nearly straight (a depth from its second differences), and each final
//! piece is hit where the ray passes within half the width of the closest point of the line
//! through its ends. Everything is on the stack (the depth is at most 10): no allocation per ray.

use super::{Bounds3, Ray};
use crate::math::Vec3;

/// How the curve's surface is oriented.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurveType {
    /// A ribbon that always faces the ray.
    Flat,
    /// A flat ribbon facing the ray whose normals turn across its width as a tube's do.
    Cylinder,
    /// A ribbon oriented by the normals given at its ends.
    Ribbon,
}

/// One piece of a cubic Bézier segment, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Curve {
    /// Control points of the piece (the segment's, blossomed to [u_min, u_max]).
    pub cp: [Vec3; 4],
    /// The piece's range of the segment's parameter u (the hit's u coordinate).
    pub u_range: [f32; 2],
    /// Width at the piece's ends.
    pub width: [f32; 2],
    pub kind: CurveType,
    /// Ribbon normals at the piece's ends (unit; unused for the other types).
    pub normals: [Vec3; 2],
}

/// A hit on a curve: the ray parameter, the segment's u and the coordinate v ∈ [0, 1] across
/// the width (0.5 on the centre line).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

/// The cubic Bézier through `cp` at `t` and its derivative.
#[inline]
pub fn bezier(cp: &[Vec3; 4], t: f32) -> (Vec3, Vec3) {
    let s = 1.0 - t;
    let a = cp[0] * s + cp[1] * t;
    let b = cp[1] * s + cp[2] * t;
    let c = cp[2] * s + cp[3] * t;
    let d = a * s + b * t;
    let e = b * s + c * t;
    let p = d * s + e * t;
    let dp = (e - d) * 3.0;
    // A derivative that vanishes at an end where two control points coincide: the chord.
    let dp = if dp.length_squared() > 0.0 {
        dp
    } else if t < 0.5 {
        cp[2] - cp[0]
    } else {
        cp[3] - cp[1]
    };
    (p, dp)
}

/// The control points of the part [t0, t1] of the cubic Bézier `cp` (blossoming).
pub fn bezier_part(cp: &[Vec3; 4], t0: f32, t1: f32) -> [Vec3; 4] {
    let blossom = |a: f32, b: f32, c: f32| {
        let l = |p: Vec3, q: Vec3, t: f32| p * (1.0 - t) + q * t;
        let a0 = l(cp[0], cp[1], a);
        let a1 = l(cp[1], cp[2], a);
        let a2 = l(cp[2], cp[3], a);
        let b0 = l(a0, a1, b);
        let b1 = l(a1, a2, b);
        l(b0, b1, c)
    };
    [
        blossom(t0, t0, t0),
        blossom(t0, t0, t1),
        blossom(t0, t1, t1),
        blossom(t1, t1, t1),
    ]
}

/// Splits a cubic Bézier at its midpoint: the two halves share the middle point.
#[inline]
fn subdivide(cp: &[Vec3; 4]) -> [Vec3; 7] {
    let m01 = (cp[0] + cp[1]) * 0.5;
    let m12 = (cp[1] + cp[2]) * 0.5;
    let m23 = (cp[2] + cp[3]) * 0.5;
    let a = (m01 + m12) * 0.5;
    let b = (m12 + m23) * 0.5;
    let mid = (a + b) * 0.5;
    [cp[0], m01, a, mid, b, m23, cp[3]]
}

#[inline]
fn lerp(t: f32, a: f32, b: f32) -> f32 {
    a + (b - a) * t
}

/// The ray's frame: its origin, and unit x, y, z (z along the ray).
struct RayFrame {
    o: Vec3,
    x: Vec3,
    y: Vec3,
    z: Vec3,
}

impl RayFrame {
    #[inline]
    fn to_ray(&self, p: Vec3) -> Vec3 {
        let q = p - self.o;
        Vec3::new(q.dot(self.x), q.dot(self.y), q.dot(self.z))
    }
}

impl Curve {
    /// Width at the segment parameter `u` (inside the piece's range).
    #[inline]
    fn width_at(&self, u: f32) -> f32 {
        let span = self.u_range[1] - self.u_range[0];
        let t = if span > 0.0 {
            (u - self.u_range[0]) / span
        } else {
            0.0
        };
        lerp(t, self.width[0], self.width[1])
    }

    #[inline]
    fn max_width(&self) -> f32 {
        self.width[0].max(self.width[1])
    }

    /// The ribbon's normal at segment parameter `u`: the spherical interpolation of the end
    /// normals.
    #[inline]
    fn ribbon_normal(&self, u: f32) -> Vec3 {
        let span = self.u_range[1] - self.u_range[0];
        let t = if span > 0.0 {
            (u - self.u_range[0]) / span
        } else {
            0.0
        };
        let [n0, n1] = self.normals;
        let angle = n0.dot(n1).clamp(-1.0, 1.0).acos();
        if angle.sin().abs() < 1e-5 {
            return n0;
        }
        let inv = 1.0 / angle.sin();
        (n0 * ((1.0 - t) * angle).sin() + n1 * (t * angle).sin()) * inv
    }

    /// A conservative box around the piece: its control points' hull grown by half its width.
    pub fn bounds(&self) -> Bounds3 {
        let b = Bounds3::from_point(self.cp[0])
            .union_point(self.cp[1])
            .union_point(self.cp[2])
            .union_point(self.cp[3]);
        let r = Vec3::splat(0.5 * self.max_width());
        Bounds3::new(b.min - r, b.max + r)
    }

    /// Approximate area: the control polygon's length times the mean width (pbrt-v4
    /// `Curve::Area`).
    pub fn area(&self) -> f32 {
        let len: f32 = (0..3).map(|i| (self.cp[i + 1] - self.cp[i]).length()).sum();
        len * 0.5 * (self.width[0] + self.width[1])
    }

    fn ray_frame(&self, ray: &Ray) -> Option<(RayFrame, f32)> {
        let len = ray.d.length();
        if !(len > 0.0) || !len.is_finite() {
            return None;
        }
        let z = ray.d / len;
        // The frame's x is perpendicular to the ray and to the piece's chord when it can be, so
        // the projected piece lies roughly along y.
        let up = z.cross(self.cp[3] - self.cp[0]);
        let up = if up.length_squared() > 0.0 {
            up.normalize()
        } else {
            z.any_orthonormal_vector()
        };
        let x = up.cross(z);
        let x = if x.length_squared() > 0.0 {
            x.normalize()
        } else {
            z.any_orthonormal_vector()
        };
        let y = z.cross(x);
        Some((RayFrame { o: ray.o, x, y, z }, len))
    }

    /// The closest hit of `ray` on the piece below `t_max`.
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<CurveHit> {
        let (frame, len) = self.ray_frame(ray)?;
        let cp = self.cp.map(|p| frame.to_ray(p));
        let z_max = len * t_max;
        if !overlaps_ray(&cp, 0.5 * self.max_width(), z_max) {
            return None;
        }
        // Subdivision depth: enough that the piece deviates from its chord by less than a
        // twentieth of its width (pbrt-v4's bound from the second differences L0).
        let mut l0 = 0.0f32;
        for i in 0..2 {
            let d = (cp[i] - cp[i + 1] * 2.0 + cp[i + 2]).abs();
            l0 = l0.max(d.max_element());
        }
        let mut depth = 0;
        if l0 > 0.0 {
            let eps = self.max_width() * 0.05;
            let r = std::f32::consts::SQRT_2 * 6.0 * l0 / (8.0 * eps);
            if r.is_finite() && r >= 1.0 {
                depth = ((r.log2().floor() as i32) / 2).clamp(0, 10);
            } else if !r.is_finite() {
                depth = 10;
            }
        }
        let mut best: Option<CurveHit> = None;
        self.recurse(
            &cp,
            self.u_range[0],
            self.u_range[1],
            depth,
            len,
            z_max,
            &frame,
            &mut best,
        );
        best
    }

    #[allow(clippy::too_many_arguments)]
    fn recurse(
        &self,
        cp: &[Vec3; 4],
        u0: f32,
        u1: f32,
        depth: i32,
        len: f32,
        z_max: f32,
        frame: &RayFrame,
        best: &mut Option<CurveHit>,
    ) {
        if depth > 0 {
            let split = subdivide(cp);
            let um = 0.5 * (u0 + u1);
            let us = [u0, um, u1];
            for seg in 0..2 {
                let half = [
                    split[3 * seg],
                    split[3 * seg + 1],
                    split[3 * seg + 2],
                    split[3 * seg + 3],
                ];
                let w = self.width_at(us[seg]).max(self.width_at(us[seg + 1]));
                let z = best.map_or(z_max, |b| b.t * len);
                if overlaps_ray(&half, 0.5 * w, z) {
                    self.recurse(
                        &half,
                        us[seg],
                        us[seg + 1],
                        depth - 1,
                        len,
                        z_max,
                        frame,
                        best,
                    );
                }
            }
            return;
        }
        // The ray (the origin of the xy plane) must lie between the perpendiculars to the
        // piece's tangents at its two ends, or the hit belongs to a neighbouring piece.
        let edge0 = (cp[1].y - cp[0].y) * -cp[0].y + cp[0].x * (cp[0].x - cp[1].x);
        if edge0 < 0.0 {
            return;
        }
        let edge1 = (cp[2].y - cp[3].y) * -cp[3].y + cp[3].x * (cp[3].x - cp[2].x);
        if edge1 < 0.0 {
            return;
        }
        // The closest point of the chord to the ray, as a parameter w along it.
        let (sx, sy) = (cp[3].x - cp[0].x, cp[3].y - cp[0].y);
        let denom = sx * sx + sy * sy;
        if denom == 0.0 {
            return;
        }
        let w = (-cp[0].x * sx - cp[0].y * sy) / denom;
        let u = lerp(w, u0, u1).clamp(u0, u1);
        let mut hit_width = self.width_at(u);
        if self.kind == CurveType::Ribbon {
            // A ribbon seen edge-on is narrower.
            hit_width *= self.ribbon_normal(u).dot(frame.z).abs();
        }
        let (pc, dpcdw) = bezier(cp, w.clamp(0.0, 1.0));
        let dist2 = pc.x * pc.x + pc.y * pc.y;
        if dist2 > hit_width * hit_width * 0.25 {
            return;
        }
        if pc.z < 0.0 || pc.z > z_max {
            return;
        }
        let t = pc.z / len;
        if best.is_some_and(|b| t > b.t) {
            return;
        }
        // v across the width, on the side of the centre line the ray passes.
        let dist = dist2.sqrt();
        let edge = dpcdw.x * -pc.y + pc.x * dpcdw.y;
        let off = if hit_width > 0.0 {
            dist / hit_width
        } else {
            0.0
        };
        let v = if edge > 0.0 { 0.5 + off } else { 0.5 - off };
        *best = Some(CurveHit {
            t,
            u,
            v: v.clamp(0.0, 1.0),
        });
    }

    /// Position, error bound, unit normal and unit tangent (∂p/∂u) of the hit `h` of `ray`, as
    /// pbrt-v4's curve builds them: ∂p/∂v across the ribbon (perpendicular to the ray for flat
    /// and cylinder curves, turned by the angle of v across a tube for cylinders, along n × ∂p/∂u
    /// for ribbons), n = ∂p/∂u × ∂p/∂v.
    pub fn surface(&self, ray: &Ray, h: &CurveHit) -> (Vec3, Vec3, Vec3, Vec3) {
        let span = self.u_range[1] - self.u_range[0];
        let local = if span > 0.0 {
            ((h.u - self.u_range[0]) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (_, dpdu) = bezier(&self.cp, local);
        let dpdu = if dpdu.length_squared() > 0.0 {
            dpdu.normalize()
        } else {
            Vec3::X
        };
        let z = ray.d.normalize_or_zero();
        let mut hit_width = self.width_at(h.u);
        let dpdv = match self.kind {
            CurveType::Ribbon => {
                let n = self.ribbon_normal(h.u);
                hit_width *= n.dot(z).abs();
                n.cross(dpdu)
            }
            CurveType::Flat | CurveType::Cylinder => {
                let d = z.cross(dpdu);
                let d = if d.length_squared() > 0.0 {
                    d.normalize()
                } else {
                    dpdu.any_orthonormal_vector()
                };
                if self.kind == CurveType::Cylinder {
                    // Turned about the tangent by −θ, θ from −90° to 90° across the width, so the
                    // normals are a tube's.
                    let theta = (-lerp(h.v, -90.0, 90.0)).to_radians();
                    let (s, c) = theta.sin_cos();
                    d * c + dpdu.cross(d) * s + dpdu * (dpdu.dot(d) * (1.0 - c))
                } else {
                    d
                }
            }
        };
        let n = dpdu.cross(dpdv);
        let n = if n.length_squared() > 0.0 {
            n.normalize()
        } else {
            dpdu.any_orthonormal_vector()
        };
        let p = ray.at(h.t);
        let err = Vec3::splat(hit_width.max(0.0)) + p.abs() * crate::math::gamma(4);
        (p, err, n, dpdu)
    }
}

/// True if the box around the ray-space control points `cp`, grown by `r`, overlaps the ray
/// (the z axis from 0 to `z_max`).
#[inline]
fn overlaps_ray(cp: &[Vec3; 4], r: f32, z_max: f32) -> bool {
    let min = cp[0].min(cp[1]).min(cp[2].min(cp[3])) - Vec3::splat(r);
    let max = cp[0].max(cp[1]).max(cp[2].max(cp[3])) + Vec3::splat(r);
    min.x <= 0.0 && max.x >= 0.0 && min.y <= 0.0 && max.y >= 0.0 && max.z >= 0.0 && min.z <= z_max
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(kind: CurveType, w: f32) -> Curve {
        Curve {
            cp: [
                Vec3::new(-1.0, 0.0, 0.0),
                Vec3::new(-1.0 / 3.0, 0.0, 0.0),
                Vec3::new(1.0 / 3.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
            ],
            u_range: [0.0, 1.0],
            width: [w, w],
            kind,
            normals: [Vec3::Z, Vec3::Z],
        }
    }

    /// A straight flat curve along x of width 0.2 seen from +z: hit exactly within |y| < 0.1,
    /// at the ray's distance to the axis, with u along x and v across y (0.5 on the axis).
    #[test]
    fn straight_flat_curve_is_hit_within_its_width() {
        let c = straight(CurveType::Flat, 0.2);
        for k in 0..41 {
            let y = -0.2 + 0.01 * k as f32;
            let ray = Ray::new(Vec3::new(0.3, y, 5.0), Vec3::new(0.0, 0.0, -1.0));
            let hit = c.intersect(&ray, f32::INFINITY);
            if y.abs() < 0.099 {
                let h = hit.unwrap_or_else(|| panic!("miss at y {y}"));
                assert!((h.t - 5.0).abs() < 1e-4, "{h:?}");
                assert!((h.u - 0.65).abs() < 1e-3, "{h:?}");
                assert!(
                    (h.v - (0.5 + y.abs() / 0.2)).abs() < 1e-3
                        || (h.v - (0.5 - y.abs() / 0.2)).abs() < 1e-3
                );
            } else if y.abs() > 0.101 {
                assert!(hit.is_none(), "hit at y {y}: {hit:?}");
            }
        }
        // v runs monotonically across the width.
        let v = |y: f32| {
            c.intersect(&Ray::new(Vec3::new(0.0, y, 5.0), -Vec3::Z), f32::INFINITY)
                .unwrap()
                .v
        };
        assert!((v(-0.05) - v(0.05)).abs() > 0.9 * 0.5);
        // Behind the origin or past t_max: no hit.
        let ray = Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::Z);
        assert!(c.intersect(&ray, f32::INFINITY).is_none());
        let ray = Ray::new(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z);
        assert!(c.intersect(&ray, 4.0).is_none());
    }

    /// A curved (quarter-circle-like) Bézier: every hit lies within half the width of the curve
    /// (by a dense polyline distance), and rays aimed at points on the curve hit it.
    #[test]
    fn curved_curve_hits_lie_on_it() {
        let c = Curve {
            cp: [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.5, 0.0, 0.0),
                Vec3::new(1.0, 0.5, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
            ],
            u_range: [0.0, 1.0],
            width: [0.05, 0.02],
            kind: CurveType::Cylinder,
            normals: [Vec3::Z, Vec3::Z],
        };
        let poly: Vec<Vec3> = (0..=2000)
            .map(|i| bezier(&c.cp, i as f32 / 2000.0).0)
            .collect();
        let mut hits = 0;
        for i in 1..50 {
            let t = i as f32 / 50.0;
            let (p, _) = bezier(&c.cp, t);
            let o = p + Vec3::new(0.1, -0.2, 3.0);
            let ray = Ray::new(o, p - o);
            let h = c
                .intersect(&ray, f32::INFINITY)
                .unwrap_or_else(|| panic!("miss at {t}"));
            hits += 1;
            let q = ray.at(h.t);
            let d = poly
                .iter()
                .map(|x| (*x - q).length())
                .fold(f32::MAX, f32::min);
            assert!(d < 0.03, "t {t}: hit {d} from the curve");
            assert!((h.u - t).abs() < 0.02, "t {t}: u {}", h.u);
            assert!((h.v - 0.5).abs() < 0.1, "t {t}: v {}", h.v);
            let (_, err, n, dpdu) = c.surface(&ray, &h);
            assert!((n.length() - 1.0).abs() < 1e-4 && n.dot(dpdu).abs() < 1e-3);
            assert!(err.is_finite());
            // Near the centre line a cylinder's normal faces back along the ray.
            assert!(n.dot(ray.d.normalize()).abs() > 0.9, "{n:?}");
        }
        assert_eq!(hits, 49);
    }

    /// The blossomed parts of a segment trace the segment.
    #[test]
    fn bezier_part_is_the_segment() {
        let cp = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 2.0, 0.0),
            Vec3::new(2.0, -1.0, 1.0),
            Vec3::new(3.0, 0.0, 0.5),
        ];
        let part = bezier_part(&cp, 0.25, 0.75);
        for k in 0..=10 {
            let s = k as f32 / 10.0;
            let a = bezier(&part, s).0;
            let b = bezier(&cp, 0.25 + 0.5 * s).0;
            assert!((a - b).length() < 1e-5);
        }
    }
}
