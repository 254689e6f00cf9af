//! The KHR_materials_clearcoat layer: a dielectric GGX coat (IOR 1.5, F0 = 0.04) over the glTF
//! metallic-roughness material, layered as the extension and glTF 2.0 appendix B define it:
//!
//! ```text
//! coated = fresnel_coat(clearcoat_normal, 1.5, clearcoat, base, clearcoat_brdf)
//!        = mix(base, specular_brdf(α_c = clearcoatRoughness²), clearcoat · fr),
//!   fr   = F0 + (1 − F0)(1 − |V · N_c|)⁵
//! ```
//!
//! so f = (1 − c·fr)·f_base + c·fr·D(h)·G2/(4 |N_c·L| |N_c·V|), with D and G2 in the frame of the
//! coat normal N_c (the clearcoat normal map, else the interpolated vertex normal — the base's
//! normal map does not apply to the coat). Since fr depends only on V, the layer's weights sum to
//! one and the albedo stays ≤ 1 whenever the base's does (the furnace test checks it). The
//! albedo-scaling is view-only, as in the specification, so the coated BRDF is not reciprocal —
//! a property of the glTF model, not of this implementation.
//!
//! Everything is in the base's local shading frame (normal +z); `normal` is N_c in that frame.

use super::microfacet::{Ggx, reflect, schlick_scalar};
use crate::math::{Frame, Vec2, Vec3};

/// F0 of the coat: ((1.5 − 1)/(1.5 + 1))² (the extension fixes the coat's IOR at 1.5).
pub const COAT_F0: f32 = 0.04;

#[derive(Clone, Copy, Debug)]
pub struct Clearcoat {
    /// clearcoatFactor × clearcoatTexture.r, in [0, 1].
    pub weight: f32,
    pub ggx: Ggx,
    /// The coat's unit normal in the base's local shading frame.
    pub normal: Vec3,
    /// The geometric normal on the coat's side, in the same frame (+z until
    /// [`crate::material::Bsdf::set_coat_normal`] places it): the coat reflects into directions
    /// `w` with `w · outside > 0`, also where its own normal sends them below the base's shading
    /// plane. A transmissive BSDF tells such a reflection from transmitted light by this normal
    /// (see [`Clearcoat::agrees`]).
    pub outside: Vec3,
}

impl Clearcoat {
    /// A coat of weight `weight` and glTF roughness `roughness` (α = roughness²) with normal
    /// `normal` (local frame; normalised here, +z when degenerate).
    pub fn new(weight: f32, roughness: f32, normal: Vec3) -> Clearcoat {
        let r = roughness.clamp(0.0, 1.0);
        let n = normal.normalize_or_zero();
        Clearcoat {
            weight: weight.clamp(0.0, 1.0),
            ggx: Ggx::new(r * r),
            normal: if n.z > 0.0 { n } else { Vec3::Z },
            outside: Vec3::Z,
        }
    }

    /// The same coat on a surface whose geometric normal on the coat's side is `ng` (local
    /// frame; +z when degenerate).
    #[inline]
    pub fn with_outside(mut self, ng: Vec3) -> Clearcoat {
        let n = ng.normalize_or_zero();
        self.outside = if n == Vec3::ZERO { Vec3::Z } else { n };
        self
    }

    /// The coat mirrored to the other face of a thin sheet, seen through `mirror_z` (a view from
    /// behind evaluated from the front): that face's outward normals are the negated ones, which
    /// the mirror turns into (−x, −y, z).
    #[inline]
    pub fn mirrored(self) -> Clearcoat {
        let flip = |n: Vec3| Vec3::new(-n.x, -n.y, n.z);
        let o = flip(self.outside);
        let mut c = self.with_normal(flip(self.normal));
        c.outside = o;
        c
    }

    /// True if `w` leaves on the coat's side of the surface (geometrically).
    #[inline]
    pub fn is_outside(&self, w: Vec3) -> bool {
        w.dot(self.outside) > 0.0
    }

    /// True if the base's shading frame and the surface agree on the side of `w` (both above or
    /// both below). Where they do not, `w` is a direction only the coat reaches: above the
    /// surface but below the base's normal-mapped plane (a reflection about the coat's normal),
    /// or the reverse, where nothing scatters.
    #[inline]
    pub fn agrees(&self, w: Vec3) -> bool {
        (w.z > 0.0) == self.is_outside(w)
    }

    /// The same coat with unit normal `normal` (local frame; +z when degenerate or below).
    #[inline]
    pub fn with_normal(mut self, normal: Vec3) -> Clearcoat {
        let n = normal.normalize_or_zero();
        self.normal = if n.z > 0.0 { n } else { Vec3::Z };
        self
    }

    #[inline]
    fn frame(&self) -> Frame {
        Frame::from_normal(self.normal)
    }

    /// c · fr(V): the share of the base the coat replaces when seen from `wo`.
    #[inline]
    pub fn layer_weight(&self, wo: Vec3) -> f32 {
        self.weight * schlick_scalar(COAT_F0, wo.dot(self.normal).abs().min(1.0))
    }

    /// The coat lobe c·fr·D·G2/(4|N_c·L||N_c·V|) (zero unless both directions are above the coat).
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        let fr = self.layer_weight(wo);
        if fr <= 0.0 {
            return 0.0;
        }
        let f = self.frame();
        let (o, i) = (f.to_local(wo), f.to_local(wi));
        if o.z <= 0.0 || i.z <= 0.0 {
            return 0.0;
        }
        let h = o + i;
        if h.length_squared() == 0.0 {
            return 0.0;
        }
        let h = h.normalize();
        fr * self.ggx.d(h) * self.ggx.g2(o, i) / (4.0 * o.z * i.z)
    }

    /// Solid-angle density of [`Clearcoat::sample`]: visible-normal sampling in the coat's frame,
    /// D_v(h)/(4 V·h) (Heitz 2018 eq. 17 with the reflection Jacobian).
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let f = self.frame();
        let (o, i) = (f.to_local(wo), f.to_local(wi));
        if o.z <= 0.0 || i.z <= 0.0 {
            return 0.0;
        }
        let h = o + i;
        if h.length_squared() == 0.0 {
            return 0.0;
        }
        let h = h.normalize();
        let voh = o.dot(h);
        if voh <= 0.0 {
            return 0.0;
        }
        self.ggx.d_visible(o, h) / (4.0 * voh)
    }

    /// Reflects `wo` about a visible GGX normal of the coat; `None` if it leaves below the coat.
    #[inline]
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        let f = self.frame();
        let o = f.to_local(wo);
        if o.z <= 0.0 {
            return None;
        }
        let m = self.ggx.sample_visible(o, u);
        let i = reflect(o, m);
        (i.z > 0.0).then(|| f.to_world(i))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::PI;

    fn dir(theta_deg: f32, phi: f32) -> Vec3 {
        let t = theta_deg.to_radians();
        Vec3::new(t.sin() * phi.cos(), t.sin() * phi.sin(), t.cos())
    }

    /// ∫ f cos over the hemisphere by a fine midpoint rule in (cos θ, φ).
    fn albedo(c: &Clearcoat, wo: Vec3) -> f64 {
        let (nt, np) = (400, 400);
        let mut sum = 0.0f64;
        for a in 0..nt {
            let cos = (a as f32 + 0.5) / nt as f32;
            let sin = (1.0 - cos * cos).sqrt();
            for b in 0..np {
                let phi = 2.0 * PI * (b as f32 + 0.5) / np as f32;
                let wi = Vec3::new(sin * phi.cos(), sin * phi.sin(), cos);
                sum += (c.eval(wo, wi) * cos) as f64;
            }
        }
        sum * 2.0 * PI as f64 / (nt * np) as f64
    }

    #[test]
    fn the_coat_reflects_at_most_its_fresnel_share() {
        // Energy: the coat lobe's albedo is at most c·fr (G2 ≤ 1 loses a little at grazing and
        // rough), and close to it when smooth and viewed head-on. The quadrature below has cells
        // of ~4·10⁻⁵ sr: roughness 0.15 (α = 0.0225) is the smoothest lobe it resolves (at 0.05
        // the lobe is narrower than a cell and the midpoint rule misses half of it).
        for &(rough, theta) in &[(0.3f32, 0.0f32), (0.3, 60.0), (0.8, 30.0), (0.15, 45.0)] {
            let c = Clearcoat::new(1.0, rough, Vec3::Z);
            let wo = dir(theta, 0.3);
            let a = albedo(&c, wo);
            let share = c.layer_weight(wo) as f64;
            assert!(
                a <= share * 1.01,
                "rough {rough} θ {theta}: albedo {a} > c·fr {share}"
            );
            if rough <= 0.3 && theta <= 45.0 {
                assert!(
                    a >= share * 0.9,
                    "rough {rough} θ {theta}: albedo {a} ≪ c·fr {share}"
                );
            }
        }
    }

    #[test]
    fn weight_and_fresnel() {
        let c = Clearcoat::new(0.5, 0.2, Vec3::Z);
        assert!((c.layer_weight(Vec3::Z) - 0.5 * COAT_F0).abs() < 1e-6);
        let grazing = c.layer_weight(dir(89.9, 0.0));
        assert!(grazing > 0.49 && grazing <= 0.5, "{grazing}");
        assert_eq!(
            Clearcoat::new(0.0, 0.2, Vec3::Z).eval(Vec3::Z, Vec3::Z),
            0.0
        );
    }

    #[test]
    fn a_tilted_coat_normal_moves_the_highlight() {
        // With N_c tilted by 20° about y, the mirror direction of a head-on view is 40° away.
        let n = dir(20.0, 0.0);
        let c = Clearcoat::new(1.0, 0.1, n);
        let wo = Vec3::Z;
        let mirrored = reflect(wo, n);
        assert!(c.eval(wo, mirrored) > 100.0 * c.eval(wo, wo).max(1e-12));
        // Samples cluster around the coat's mirror direction, not the base's.
        let mut near = 0;
        for k in 0..256 {
            let u = Vec2::new((k % 16) as f32 / 16.0 + 0.03, (k / 16) as f32 / 16.0 + 0.03);
            if let Some(wi) = c.sample(wo, u)
                && wi.dot(mirrored) > 0.9
            {
                near += 1;
            }
        }
        assert!(near > 200, "{near} of 256 near the coat's mirror direction");
    }
}
