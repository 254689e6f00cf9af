//! Warps from [0,1)² onto the integration domains, each with its pdf (PBRT §13.6).

use crate::math::{INV_PI, PI, Vec2, Vec3};

/// Concentric map of the square onto the unit disk (Shirley & Chiu 1997), area-preserving and
/// with low distortion.
#[inline]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = u * 2.0 - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    // θ = φ in the first case and π/2 − φ in the second, with φ ∈ [−π/4, π/4], so cos θ and
    // sin θ are cos φ and sin φ, possibly swapped: short Taylor polynomials on that interval
    // (errors below 3e-7 and 3e-8) instead of a libm `sincos` call.
    let (r, phi, swap) = if o.x.abs() > o.y.abs() {
        (o.x, (PI / 4.0) * (o.y / o.x), false)
    } else {
        (o.y, (PI / 4.0) * (o.x / o.y), true)
    };
    let (s, c) = sin_cos_quarter_pi(phi);
    if swap {
        Vec2::new(s, c) * r
    } else {
        Vec2::new(c, s) * r
    }
}

/// (sin x, cos x) for |x| ≤ π/4 from their Taylor series to degrees 7 and 8 (the first omitted
/// terms, x⁹/9! and x¹⁰/10!, are below 3e-7 and 3e-8 there).
#[inline]
fn sin_cos_quarter_pi(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let s = x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0))));
    let c = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40320.0))));
    (s, c)
}

/// Cosine-weighted direction on the +z hemisphere (Malley's method); pdf = cos θ / π.
#[inline]
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.x * d.x - d.y * d.y).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    if cos_theta > 0.0 {
        cos_theta * INV_PI
    } else {
        0.0
    }
}

/// Uniform direction on the unit sphere; pdf = 1 / 4π.
#[inline]
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

pub const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * PI);

/// Uniform barycentrics (b1, b2) on a triangle (the square-root parameterisation, PBRT §A.5.5).
#[inline]
pub fn uniform_triangle(u: Vec2) -> (f32, f32) {
    let su0 = u.x.sqrt();
    (1.0 - su0, u.y * su0)
}

/// Samples a direction in a cone of half-angle with cosine `cos_max` around +z; pdf is
/// 1 / (2π (1 − cos_max)).
#[inline]
pub fn uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    let cos_t = (1.0 - u.x) + u.x * cos_max;
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = u.y * 2.0 * PI;
    Vec3::new(phi.cos() * sin_t, phi.sin() * sin_t, cos_t)
}

#[inline]
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Veach's power heuristic with β = 2 (Veach 1997, eq. 9.13), for one sample from each strategy.
#[inline]
pub fn power_heuristic(pdf_f: f32, pdf_g: f32) -> f32 {
    let f = pdf_f * pdf_f;
    let g = pdf_g * pdf_g;
    if f.is_infinite() {
        return 1.0;
    }
    if f + g > 0.0 { f / (f + g) } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_pi_polynomials_match_libm() {
        for i in 0..=1000 {
            let x = (i as f32 / 1000.0 * 2.0 - 1.0) * PI / 4.0;
            let (s, c) = sin_cos_quarter_pi(x);
            assert!((s - x.sin()).abs() < 5e-7, "sin {x}");
            assert!((c - x.cos()).abs() < 5e-7, "cos {x}");
        }
    }

    #[test]
    fn disk_stays_in_unit_disk() {
        for i in 0..=20 {
            for j in 0..=20 {
                let p = concentric_disk(Vec2::new(i as f32 / 20.0, j as f32 / 20.0));
                assert!(p.length() <= 1.0 + 1e-5);
            }
        }
    }

    #[test]
    fn power_heuristic_weights_sum_to_one() {
        for (a, b) in [(1.0, 2.0), (0.3, 0.0), (5.0, 5.0)] {
            let s = power_heuristic(a, b) + power_heuristic(b, a);
            assert!((s - 1.0).abs() < 1e-6);
        }
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
    }
}
