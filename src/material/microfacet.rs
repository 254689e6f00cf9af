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

/// The GGX (Trowbridge–Reitz) distribution of normals with roughnesses `alpha_x` along the
/// shading frame's tangent (x) and `alpha_y` along the bitangent (y); isotropic when the two are
/// equal ([`Ggx::new`]). pbrt-v4's `TrowbridgeReitzDistribution` (`uroughness`/`vroughness`), glTF's
/// roughness (α = roughness²) and `KHR_materials_anisotropy` are this distribution.
///
/// D(m) = 1 / (π αx αy (mx²/αx² + my²/αy² + mz²)²) (Heitz 2014 eq. 85, written without angles);
/// Λ(w) = (√(1 + (αx² wx² + αy² wy²)/wz²) − 1)/2 (Heitz 2014 eq. 86); visible normals are sampled
/// by stretching with (αx, αy) (Heitz 2018, listing 1). With equal α, D and Λ take their
/// rotation-invariant forms (Walter et al. 2007 eq. 33, Heitz 2014 eq. 72): the same functions
/// with fewer divisions, and the rounding the isotropic materials were validated with.
///
/// The α are kept as given (no clamping): callers test [`Ggx::effectively_smooth`] first, as
/// pbrt-v4 does, and use a Dirac lobe in that case; evaluation raises them to [`MIN_ALPHA`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub alpha_x: f32,
    pub alpha_y: f32,
}

/// Below this α (both axes) pbrt-v4 treats a microfacet surface as a perfect specular one
/// (`TrowbridgeReitzDistribution::EffectivelySmooth`).
pub const SMOOTH_ALPHA: f32 = 1e-3;

/// pbrt-v4's `remaproughness` rule (`TrowbridgeReitzDistribution::RoughnessToAlpha`): the user's
/// roughness r ∈ [0, 1] becomes α = √r; with `remaproughness false` α = r. (glTF's rule is α = r².)
#[inline]
pub fn pbrt_roughness_to_alpha(roughness: f32, remap: bool) -> f32 {
    let r = roughness.max(0.0);
    if remap { r.sqrt() } else { r }
}

#[inline]
fn tan2_theta(w: Vec3) -> f32 {
    let cos2 = w.z * w.z;
    (1.0 - cos2).max(0.0) / cos2
}

impl Ggx {
    /// The isotropic distribution with roughness α.
    #[inline]
    pub fn new(alpha: f32) -> Ggx {
        Ggx::anisotropic(alpha, alpha)
    }

    /// The distribution with α `alpha_x` along the tangent and `alpha_y` along the bitangent.
    #[inline]
    pub fn anisotropic(alpha_x: f32, alpha_y: f32) -> Ggx {
        Ggx {
            alpha_x: alpha_x.max(0.0),
            alpha_y: alpha_y.max(0.0),
        }
    }

    #[inline]
    pub fn effectively_smooth(&self) -> bool {
        self.alpha_x.max(self.alpha_y) < SMOOTH_ALPHA
    }

    /// Both α raised to at least [`MIN_ALPHA`], safe to evaluate.
    #[inline]
    fn clamped(&self) -> (f32, f32) {
        (self.alpha_x.max(MIN_ALPHA), self.alpha_y.max(MIN_ALPHA))
    }

    /// D(m): microfacet normal density, normalised so that ∫ D(m) cos θm dm = 1.
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let (ax, ay) = self.clamped();
        if ax == ay {
            // Walter et al. 2007 eq. 33.
            let a2 = ax * ax;
            let c2 = m.z * m.z;
            let t = c2 * (a2 - 1.0) + 1.0;
            return a2 / (PI * t * t);
        }
        let t = (m.x / ax).powi(2) + (m.y / ay).powi(2) + m.z * m.z;
        1.0 / (PI * ax * ay * t * t)
    }

    /// Smith Λ(w); symmetric in the sign of w.z.
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let (ax, ay) = self.clamped();
        if ax == ay {
            // Heitz 2014 eq. 72.
            let t2 = tan2_theta(w);
            if !t2.is_finite() {
                return 0.0;
            }
            return 0.5 * ((1.0 + ax * ax * t2).sqrt() - 1.0);
        }
        if w.z == 0.0 {
            return 0.0;
        }
        let a2t2 = ((ax * w.x).powi(2) + (ay * w.y).powi(2)) / (w.z * w.z);
        if !a2t2.is_finite() {
            return 0.0;
        }
        0.5 * ((1.0 + a2t2).sqrt() - 1.0)
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
        self.d_visible_given(w, m, self.d(m), self.lambda(w))
    }

    /// [`Self::d_visible`] given D(m) and Λ(w) already evaluated (`d_m = self.d(m)`,
    /// `lambda_w = self.lambda(w)`; Λ is even in w, so the mirrored w's is the same): the same
    /// operations in the same order, so the same bits.
    #[inline]
    pub fn d_visible_given(&self, w: Vec3, m: Vec3, d_m: f32, lambda_w: f32) -> f32 {
        let w = if w.z < 0.0 { -w } else { w };
        if w.z == 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + lambda_w) / w.z * d_m * w.dot(m).max(0.0)
    }

    /// Samples a visible normal as seen from `w` (Heitz 2018, listing 1). The returned normal is
    /// in the upper hemisphere; `w` below the surface is mirrored first.
    #[inline]
    pub fn sample_visible(&self, w: Vec3, u: Vec2) -> Vec3 {
        let w = if w.z < 0.0 { -w } else { w };
        let (ax, ay) = self.clamped();
        // Stretch the view vector to the configuration of the unit-roughness hemisphere.
        let vh = Vec3::new(ax * w.x, ay * w.y, w.z).normalize();
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
        Vec3::new(ax * nh.x, ay * nh.y, nh.z.max(1e-6)).normalize()
    }
}

/// Exact unpolarised Fresnel reflectance of a conductor with complex IOR η + i k (relative to the
/// outside medium), for one wavelength or colour channel: the Fresnel equations with a complex
/// refracted cosine (Born & Wolf §14.2; PBRT-v4 §9.3.6, eq. 9.6 with complex η). Computed in f64:
/// for large k the two terms nearly cancel in f32.
#[inline]
pub fn fresnel_complex(cos_theta_i: f32, eta: f32, k: f32) -> f32 {
    let c = (cos_theta_i.abs() as f64).min(1.0);
    let eta_c = C64::new(eta as f64, k as f64);
    let sin2_i = 1.0 - c * c;
    // sin²θt = sin²θi / η², cos θt = √(1 − sin²θt), both complex.
    let sin2_t = C64::new(sin2_i, 0.0).div(eta_c.mul(eta_c));
    let cos_t = C64::new(1.0 - sin2_t.re, -sin2_t.im).sqrt();
    let ec = eta_c.scale(c);
    let r_parl = ec.sub(cos_t).div(ec.add(cos_t));
    let ect = eta_c.mul(cos_t);
    let ci = C64::new(c, 0.0);
    let r_perp = ci.sub(ect).div(ci.add(ect));
    (0.5 * (r_parl.norm() + r_perp.norm())) as f32
}

/// [`fresnel_complex`] per RGB channel.
#[inline]
pub fn fresnel_conductor(cos_theta_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
    Vec3::new(
        fresnel_complex(cos_theta_i, eta.x, k.x),
        fresnel_complex(cos_theta_i, eta.y, k.y),
        fresnel_complex(cos_theta_i, eta.z, k.z),
    )
}

/// pbrt-v4's artist-friendly conductor (`conductor` with `reflectance`): η = 1 and
/// k = 2√r / √(1 − r) per channel, r clamped to [0, 0.9999], which makes the exact Fresnel
/// reflectance at normal incidence equal r (|(1 − (1 + ik))/(1 + (1 + ik))|² = k²/(4 + k²) = r).
#[inline]
pub fn conductor_from_reflectance(r: Vec3) -> (Vec3, Vec3) {
    let r = r.clamp(Vec3::ZERO, Vec3::splat(0.9999));
    let k = Vec3::new(
        2.0 * r.x.sqrt() / (1.0 - r.x).sqrt(),
        2.0 * r.y.sqrt() / (1.0 - r.y).sqrt(),
        2.0 * r.z.sqrt() / (1.0 - r.z).sqrt(),
    );
    (Vec3::ONE, k)
}

/// Minimal complex arithmetic for [`fresnel_complex`].
#[derive(Clone, Copy)]
struct C64 {
    re: f64,
    im: f64,
}

impl C64 {
    fn new(re: f64, im: f64) -> C64 {
        C64 { re, im }
    }
    fn add(self, o: C64) -> C64 {
        C64::new(self.re + o.re, self.im + o.im)
    }
    fn sub(self, o: C64) -> C64 {
        C64::new(self.re - o.re, self.im - o.im)
    }
    fn mul(self, o: C64) -> C64 {
        C64::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
    fn scale(self, s: f64) -> C64 {
        C64::new(self.re * s, self.im * s)
    }
    fn norm(self) -> f64 {
        self.re * self.re + self.im * self.im
    }
    fn div(self, o: C64) -> C64 {
        let d = o.norm();
        C64::new(
            (self.re * o.re + self.im * o.im) / d,
            (self.im * o.re - self.re * o.im) / d,
        )
    }
    /// Principal square root.
    fn sqrt(self) -> C64 {
        let n = self.norm().sqrt();
        if n == 0.0 {
            return C64::new(0.0, 0.0);
        }
        let t1 = (0.5 * (n + self.re.abs())).sqrt();
        let t2 = 0.5 * self.im / t1;
        if self.re >= 0.0 {
            C64::new(t1, t2)
        } else {
            C64::new(t2.abs(), t1.copysign(self.im))
        }
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

    #[test]
    fn aniso_ggx_matches_isotropic_and_normalises() {
        // The isotropic forms of D and Λ are the anisotropic ones at equal α: compare them with
        // α pairs a rounding apart, which take the anisotropic branch.
        let iso = Ggx::new(0.3);
        let an = Ggx::anisotropic(0.3, 0.3f32.next_up());
        for m in [
            Vec3::new(0.3, 0.2, 0.9).normalize(),
            Vec3::new(-0.7, 0.1, 0.2).normalize(),
            Vec3::Z,
        ] {
            assert!((iso.d(m) - an.d(m)).abs() <= 1e-4 * iso.d(m));
            assert!((iso.lambda(m) - an.lambda(m)).abs() < 1e-5);
        }
        // ∫ D(m) cos θm dω = 1 for an anisotropic pair, midpoint quadrature in (cos θ, φ).
        let g = Ggx::anisotropic(0.1, 0.5);
        let (nc, np) = (2000, 400);
        let mut s = 0.0f64;
        for i in 0..nc {
            let c = (i as f64 + 0.5) / nc as f64;
            let st = (1.0 - c * c).sqrt();
            for j in 0..np {
                let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / np as f64;
                let m = Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, c as f32);
                s += g.d(m) as f64 * c;
            }
        }
        let integral = s / nc as f64 * 2.0 * std::f64::consts::PI / np as f64;
        assert!((integral - 1.0).abs() < 5e-3, "{integral}");
    }

    #[test]
    fn complex_fresnel_limits() {
        // k = 0 reduces to the dielectric formula.
        for c in [1.0f32, 0.7, 0.2] {
            assert!((fresnel_complex(c, 1.5, 0.0) - fresnel_dielectric(c, 1.5)).abs() < 1e-5);
        }
        // Normal incidence: ((η−1)² + k²)/((η+1)² + k²); grazing: 1.
        let (n, k) = (0.27f32, 3.6f32);
        let r0 = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
        assert!((fresnel_complex(1.0, n, k) - r0).abs() < 1e-5);
        assert!((fresnel_complex(0.0, n, k) - 1.0).abs() < 1e-5);
        // The reflectance parameterisation reproduces r at normal incidence.
        let (eta, kk) = conductor_from_reflectance(Vec3::new(0.0, 0.3, 0.95));
        let f = fresnel_conductor(1.0, eta, kk);
        assert!(
            (f - Vec3::new(0.0, 0.3, 0.95)).abs().max_element() < 1e-5,
            "{f:?}"
        );
        assert_eq!(pbrt_roughness_to_alpha(0.25, true), 0.5);
        assert_eq!(pbrt_roughness_to_alpha(0.25, false), 0.25);
    }
}
