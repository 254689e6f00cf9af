//! The equal-area octahedral mapping between the unit square and the unit sphere (Clarberg,
//! "Fast Equal-Area Mapping of the (Hemi)Sphere using SIMD", JGT 2008), which pbrt-v4 uses for
//! its image infinite lights (pbrt-v4 book §3.8.3, "Equal-Area Mapping"). Every region of the
//! square maps to a region of the sphere with 4π times its area, so a texel's solid angle is
//! 4π / (width · height) and a density p(u, v) over the square is p / 4π per steradian.
//!
//! The square [0,1]² is first taken to [−1,1]²; the diamond |u| + |v| ≤ 1 is the +z hemisphere,
//! its four corner triangles fold over to −z. Within a quadrant, r = 1 − |1 − |u| − |v|| is the
//! "radius" (z = ±(1 − r²)) and the position along the diamond's edge is the azimuth.

use crate::math::{PI, Vec2, Vec3};

/// The direction of square point `p` ∈ [0,1]² (unit length up to rounding).
#[inline]
pub fn square_to_sphere(p: Vec2) -> Vec3 {
    let (u, v) = (2.0 * p.x - 1.0, 2.0 * p.y - 1.0);
    let (up, vp) = (u.abs(), v.abs());
    // Signed distance from the diamond's edge: positive inside (the +z hemisphere).
    let signed = 1.0 - (up + vp);
    let r = 1.0 - signed.abs();
    // Azimuth within the quadrant, from 0 along +u to π/2 along +v.
    let phi = if r == 0.0 {
        PI / 4.0
    } else {
        ((vp - up) / r + 1.0) * (PI / 4.0)
    };
    let z = (1.0 - r * r).copysign(signed);
    let (sin_phi, cos_phi) = phi.sin_cos();
    let s = r * (2.0 - r * r).max(0.0).sqrt();
    Vec3::new(cos_phi.copysign(u) * s, sin_phi.copysign(v) * s, z)
}

/// The square point of unit direction `d` (the inverse of [`square_to_sphere`]).
#[inline]
pub fn sphere_to_square(d: Vec3) -> Vec2 {
    let (x, y, z) = (d.x.abs(), d.y.abs(), d.z.abs());
    let r = (1.0 - z).max(0.0).sqrt();
    let (a, b) = (x.max(y), x.min(y));
    let b = if a == 0.0 { 0.0 } else { b / a };
    // Fraction of the quadrant's right angle, measured from the nearer axis.
    let mut phi = b.atan() * (2.0 / PI);
    if x < y {
        phi = 1.0 - phi;
    }
    let mut v = phi * r;
    let mut u = r - v;
    if d.z < 0.0 {
        // The lower hemisphere is the folded-over corner triangle.
        std::mem::swap(&mut u, &mut v);
        u = 1.0 - u;
        v = 1.0 - v;
    }
    let u = u.copysign(d.x);
    let v = v.copysign(d.y);
    Vec2::new(
        (0.5 * (u + 1.0)).clamp(0.0, 1.0),
        (0.5 * (v + 1.0)).clamp(0.0, 1.0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_both_ways() {
        let n = 97;
        for i in 0..n {
            for j in 0..n {
                let p = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let d = square_to_sphere(p);
                assert!((d.length() - 1.0).abs() < 1e-5, "{p:?} -> {d:?}");
                let back = sphere_to_square(d);
                assert!((back - p).length() < 2e-5, "{p:?} -> {d:?} -> {back:?}");
            }
        }
        // Axes and poles.
        assert!((square_to_sphere(Vec2::splat(0.5)) - Vec3::Z).length() < 1e-6);
        assert!((square_to_sphere(Vec2::ZERO) - -Vec3::Z).length() < 1e-6);
        assert!((square_to_sphere(Vec2::new(1.0, 0.5)) - Vec3::X).length() < 1e-6);
        assert!((square_to_sphere(Vec2::new(0.5, 1.0)) - Vec3::Y).length() < 1e-6);
        assert!((sphere_to_square(-Vec3::Y) - Vec2::new(0.5, 0.0)).length() < 1e-6);
    }

    /// Equal area: the solid angle of a grid cell, from the spherical excess of its two
    /// triangles (Van Oosterom–Strackee), is 4π / cells for every cell (a fine grid, so the
    /// geodesic triangles approximate the mapped cells' curved edges closely).
    #[test]
    fn every_cell_subtends_the_same_solid_angle() {
        fn triangle(a: Vec3, b: Vec3, c: Vec3) -> f64 {
            let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
            let num = a.dot(b.cross(c)).abs();
            let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
            2.0 * num.atan2(den)
        }
        let n = 64;
        let sub = 8; // sub-cells per cell edge, for the curvature of the mapped edges
        let want = 4.0 * std::f64::consts::PI / (n * n) as f64;
        let mut total = 0.0;
        for i in 0..n {
            for j in 0..n {
                let mut omega = 0.0;
                for si in 0..sub {
                    for sj in 0..sub {
                        let f = |a: usize, b: usize| {
                            square_to_sphere(Vec2::new(
                                (i * sub + si + a) as f32 / (n * sub) as f32,
                                (j * sub + sj + b) as f32 / (n * sub) as f32,
                            ))
                            .normalize()
                        };
                        omega += triangle(f(0, 0), f(1, 0), f(1, 1))
                            + triangle(f(0, 0), f(1, 1), f(0, 1));
                    }
                }
                assert!(
                    (omega / want - 1.0).abs() < 2e-3,
                    "cell ({i}, {j}): {omega} sr, expected {want}"
                );
                total += omega;
            }
        }
        assert!((total / (4.0 * std::f64::consts::PI) - 1.0).abs() < 1e-4);
    }
}
