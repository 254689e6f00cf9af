//! The GGX (Trowbridge–Reitz) microfacet distribution with the height-correlated Smith masking–
//! shadowing function and visible-normal sampling, plus the Fresnel terms used by the BSDFs.
//!
//! Everything is in the local shading frame (normal = +z). References:
//! * Walter, Marschner, Li, Torrance 2007, "Microfacet Models for Refraction through Rough
//!   Surfaces" (eq. 33 for D, eq. 16 for the transmission Jacobian).
//! * Heitz 2014, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs"
//!   (eq. 72 for Λ of GGX, eq. 99 for the height-correlated G2).
//! * Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4) (listing 1).

use crate::math::{PI, Vec2, Vec3};

/// The smallest GGX α we use: below this D exceeds f32 comfort and the lobe is a mirror in all
/// but name. Mitsuba's `principled` clamps to the same value.
pub const MIN_ALPHA: f32 = 1e-3;

/// Isotropic GGX distribution of normals with roughness α (glTF: α = roughness²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub alpha: f32,
}

#[inline]
fn tan2_theta(w: Vec3) -> f32 {
    let cos2 = w.z * w.z;
    (1.0 - cos2).max(0.0) / cos2
}

impl Ggx {
    #[inline]
    pub fn new(alpha: f32) -> Ggx {
        Ggx {
            alpha: alpha.max(MIN_ALPHA),
        }
    }

    /// D(m): microfacet normal density, normalised so that ∫ D(m) cos θm dm = 1 (Walter eq. 33).
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let c2 = m.z * m.z;
        let t = c2 * (a2 - 1.0) + 1.0;
        a2 / (PI * t * t)
    }

    /// Smith Λ(w) for GGX (Heitz 2014 eq. 72); symmetric in the sign of w.z.
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let t2 = tan2_theta(w);
        if !t2.is_finite() {
            return 0.0;
        }
        0.5 * ((1.0 + self.alpha * self.alpha * t2).sqrt() - 1.0)
    }

    /// Smith masking G1(w).
    #[inline]
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking–shadowing G2 (Heitz 2014 eq. 99).
    #[inline]
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of visible normals seen from `w`: D_w(m) = G1(w) max(0, w·m) D(m) / |cos θw|
    /// (Heitz 2018 eq. 3). Handles w below the surface by mirroring it, as the sampler does.
    #[inline]
    pub fn d_visible(&self, w: Vec3, m: Vec3) -> f32 {
        let w = if w.z < 0.0 { -w } else { w };
        if w.z == 0.0 {
            return 0.0;
        }
        self.g1(w) / w.z * self.d(m) * w.dot(m).max(0.0)
    }

    /// Samples a visible normal as seen from `w` (Heitz 2018, listing 1). The returned normal is
    /// in the upper hemisphere; `w` below the surface is mirrored first.
    #[inline]
    pub fn sample_visible(&self, w: Vec3, u: Vec2) -> Vec3 {
        let w = if w.z < 0.0 { -w } else { w };
        let a = self.alpha;
        // Stretch the view vector to the configuration of the unit-roughness hemisphere.
        let vh = Vec3::new(a * w.x, a * w.y, w.z).normalize();
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 1e-14 {
            Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        // Uniform point on the disk, warped onto the projected visible half of the hemisphere.
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let mut p2 = r * phi.sin();
        let s = 0.5 * (1.0 + vh.z);
        p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        // Unstretch.
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(1e-6)).normalize()
    }
}

/// Schlick's approximation of Fresnel reflectance, F0 + (1 − F0)(1 − cos)^5, the glTF choice.
#[inline]
pub fn schlick(f0: Vec3, cos_theta: f32) -> Vec3 {
    let m = (1.0 - cos_theta.abs()).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (Vec3::ONE - f0) * (m2 * m2 * m)
}

/// Scalar Schlick, for the dielectric layer of glTF materials.
#[inline]
pub fn schlick_scalar(f0: f32, cos_theta: f32) -> f32 {
    let m = (1.0 - cos_theta.abs()).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (1.0 - f0) * (m2 * m2 * m)
}

/// Exact unpolarised Fresnel reflectance of a dielectric interface (thesis §5.3.4; PBRT eq. 9.5).
/// `cos_theta_i` is measured against the normal on the side of the medium with relative IOR
/// `eta` = η_inside / η_outside; a negative cosine means the ray arrives from inside.
#[inline]
pub fn fresnel_dielectric(cos_theta_i: f32, eta: f32) -> f32 {
    let mut cos_i = cos_theta_i.clamp(-1.0, 1.0);
    let mut eta = eta;
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
    }
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0; // total internal reflection
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
}

/// Mirror reflection of `w` about `n`.
#[inline]
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    -w + n * (2.0 * w.dot(n))
}

/// Refracts `w` (pointing away from the surface) through the interface with normal `n` and
/// relative IOR `eta` (Snell's law, thesis §5.3.4). Returns the refracted direction and the relative
/// IOR actually crossed (1/eta when arriving from inside), or `None` on total internal reflection.
#[inline]
pub fn refract(w: Vec3, n: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let mut cos_i = n.dot(w);
    let (mut n, mut eta) = (n, eta);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-w / eta + n * (cos_i / eta - cos_t), eta))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ggx_projected_area_is_one() {
        // ∫ D(m) cos θm dω = 1, by midpoint quadrature in (cos θ, φ); D is isotropic so φ is 2π.
        for alpha in [0.05f32, 0.3, 1.0] {
            let g = Ggx::new(alpha);
            let n = 200_000;
            let mut s = 0.0f64;
            for i in 0..n {
                let c = (i as f64 + 0.5) / n as f64;
                let m = Vec3::new((1.0 - c * c).sqrt() as f32, 0.0, c as f32);
                s += (g.d(m) as f64) * c;
            }
            let integral = s / n as f64 * 2.0 * std::f64::consts::PI;
            assert!((integral - 1.0).abs() < 2e-3, "alpha {alpha}: {integral}");
        }
    }

    #[test]
    fn fresnel_limits() {
        let r0 = ((1.5f32 - 1.0) / 2.5).powi(2);
        assert!((fresnel_dielectric(1.0, 1.5) - r0).abs() < 1e-6);
        assert!((fresnel_dielectric(-1.0, 1.5) - r0).abs() < 1e-6);
        assert_eq!(fresnel_dielectric(-0.1, 1.5), 1.0); // TIR from inside at grazing
        assert!((fresnel_dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn refraction_obeys_snell() {
        let w = Vec3::new(0.6, 0.0, 0.8);
        let (t, eta) = refract(w, Vec3::Z, 1.5).unwrap();
        assert_eq!(eta, 1.5);
        assert!((t.length() - 1.0).abs() < 1e-5);
        assert!((0.6 - 1.5 * (-t.x)).abs() < 1e-5 && t.z < 0.0);
        // The same pair of directions seen from inside: refraction is reciprocal.
        let (back, eta_back) = refract(t, Vec3::Z, 1.5).unwrap();
        assert!((eta_back - 1.0 / 1.5).abs() < 1e-6);
        assert!((back - w).length() < 1e-5, "{back:?}");
        assert!(refract(Vec3::new(0.9, 0.0, -0.436), Vec3::Z, 1.5).is_none());
    }
}
