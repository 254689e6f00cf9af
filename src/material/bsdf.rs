//! The BSDF at a shading point: an enum over the scattering functions of [`super::bxdf`] (one file
//! per variant), dispatched by `match`, never through trait objects. Everything is in the local
//! shading frame where the shading normal is +z. [`super::eval`] builds a `Bsdf` from a material
//! at a hit.
//!
//! Two-sided shading (docs/DESIGN.md §4): for opaque materials the integrator builds the frame around the
//! normal flipped to the side the ray arrived from, so `wo.z > 0` always and no `abs()` is taken.
//! Transmissive BSDFs keep the geometric orientation: `wo.z < 0` means the ray arrives from inside.

pub use super::bxdf::{BsdfSample, TransportMode};
use super::bxdf::{
    Conductor, Dielectric, Diffuse, DiffuseTransmission, GltfTransmission, Hair, Layered,
    MetallicRoughness, Mirror, ThinDielectric,
};
use crate::math::{Vec2, Vec3};

#[derive(Clone, Copy, Debug)]
pub enum Bsdf {
    Diffuse(Diffuse),
    MetallicRoughness(MetallicRoughness),
    Mirror(Mirror),
    Dielectric(Dielectric),
    ThinDielectric(ThinDielectric),
    /// pbrt-v4's conductor: exact complex Fresnel per channel, smooth or anisotropic GGX.
    Conductor(Conductor),
    /// Lambertian reflection + Lambertian transmission (pbrt-v4 `diffusetransmission`).
    DiffuseTransmission(DiffuseTransmission),
    /// pbrt-v4's stochastic layered BSDF (`coateddiffuse`, `coatedconductor`).
    Layered(Layered),
    /// The transmissive component of a glTF material under clearcoat, sheen, anisotropy or
    /// iridescence (thick or thin-walled).
    GltfTransmission(GltfTransmission),
    /// Chiang et al. 2016's hair fibre (pbrt-v4 `hair`), in the fibre's frame (+x along it).
    Hair(Hair),
}

impl Bsdf {
    /// The same BSDF at the three wavelengths `lambda` (nm) of a spectral path, one per `Vec3`
    /// lane (docs/DESIGN.md "Spectral rendering"): reflectance-like colours (albedos, tints,
    /// F0s, sheen) become their bounded Jakob–Hanika spectra, unbounded ones (a conductor's
    /// η and k, hair's σₐ, the layered medium's albedo) pbrt-v4's unbounded spectra, or a
    /// conductor's η/k spectra (named or sampled, ids into `spectra`, the world's
    /// [`crate::spectrum::BsdfSpectra`]) their exact values. A dispersive dielectric
    /// ([`Bsdf::disperses`]) takes the IOR of the hero wavelength `lambda.x` alone — its η
    /// spectrum (a named glass's Sellmeier law or a sampled η(λ)), or the Cauchy law
    /// n(λ) = A + B/λ² through KHR_materials_dispersion's per-channel IORs — and the path has
    /// dropped the other two wavelengths before it gets here. Thin-film iridescence takes the
    /// Airy reflectance at each wavelength ([`super::iridescence::Iridescence::wavelengths`]).
    ///
    /// In place: the path's vertex holds the BSDF, and a copy in and out of a function returning
    /// a new one was two `memcpy`s of the whole enum per spectral hit (~30 % of this call).
    pub fn make_spectral(&mut self, lambda: Vec3, spectra: &crate::spectrum::BsdfSpectra) {
        use crate::spectrum::rgb2spec::{reflectance as refl, unbounded};
        match self {
            Bsdf::Diffuse(d) => d.albedo = refl(d.albedo, lambda),
            Bsdf::MetallicRoughness(m) => {
                m.base = refl(m.base, lambda);
                m.f0_dielectric = refl(m.f0_dielectric, lambda);
                if let Some(sh) = m.ext.sheen.as_mut() {
                    sh.color = refl(sh.color, lambda);
                }
                m.ext.diffuse_transmission_color = refl(m.ext.diffuse_transmission_color, lambda);
                if let Some(ir) = m.ext.iridescence.as_mut() {
                    ir.wavelengths = Some(lambda);
                }
            }
            Bsdf::Mirror(m) => m.color = refl(m.color, lambda),
            Bsdf::Dielectric(d) => {
                d.tint = refl(d.tint, lambda);
                if let Some(id) = d.eta_spectrum {
                    d.eta = hero_eta(spectra, id, lambda);
                    d.dispersion = None;
                } else if let Some(e) = d.dispersion {
                    d.eta = cauchy_at(e, lambda.x);
                    d.dispersion = None;
                }
            }
            Bsdf::ThinDielectric(d) => {
                d.tint = refl(d.tint, lambda);
                if let Some(id) = d.eta_spectrum {
                    d.eta = hero_eta(spectra, id, lambda);
                }
            }
            Bsdf::Conductor(c) => conductor_at(c, lambda, spectra),
            Bsdf::DiffuseTransmission(d) => {
                d.reflectance = refl(d.reflectance, lambda);
                d.transmittance = refl(d.transmittance, lambda);
            }
            Bsdf::Layered(l) => {
                l.albedo = refl(l.albedo, lambda);
                // A dispersive coat (pbrt-v4 `CoatedDiffuseMaterial`/`CoatedConductorMaterial`
                // with a non-constant η): the interface takes η(λ₀) for the whole BSDF, the path
                // keeps λ₀ alone, and a conductor base is relative to that η as pbrt-v4 divides
                // its η and k by `interfaceEta(lambda[0])`.
                let rgb_coat_eta = l.coat.eta;
                if let Some(id) = l.coat.eta_spectrum {
                    l.coat.eta = hero_eta(spectra, id, lambda);
                }
                match &mut l.base {
                    super::bxdf::layered::Base::Diffuse { reflectance } => {
                        *reflectance = refl(*reflectance, lambda)
                    }
                    super::bxdf::layered::Base::Conductor(c) => {
                        conductor_at(c, lambda, spectra);
                        if l.coat.eta_spectrum.is_some() {
                            // conductor_at gave η/η_rgb, k/η_rgb (both linear in the
                            // divisor: a spectrum's values, or the unbounded upsampling of
                            // the relative RGB, whose scale is linear).
                            let to_hero = rgb_coat_eta / l.coat.eta;
                            c.eta *= to_hero;
                            c.k *= to_hero;
                        }
                    }
                }
            }
            Bsdf::GltfTransmission(t) => {
                t.tint = refl(t.tint, lambda);
                if let Some(e) = t.dispersion {
                    t.eta = cauchy_at(e, lambda.x);
                    t.dispersion = None;
                }
                if let Some(sh) = t.sheen.as_mut() {
                    sh.color = refl(sh.color, lambda);
                }
                if let Some(ir) = t.iridescence.as_mut() {
                    ir.wavelengths = Some(lambda);
                }
            }
            Bsdf::Hair(h) => h.sigma_a = unbounded(h.sigma_a, lambda),
        }
    }

    /// True if where the BSDF sends light depends on the wavelength: a dielectric, a thin
    /// dielectric or a layered coat with an η spectrum (a named glass, a sampled η that varies
    /// with λ) or a dielectric with KHR_materials_dispersion. A spectral path meeting one keeps only its hero
    /// wavelength, with thrice its weight (pbrt-v4 `SampledWavelengths::TerminateSecondary`: the
    /// hero alone is an unbiased estimate of the three, and one direction cannot serve three
    /// IORs); RGB rendering samples its per-channel mixture instead ([`Dielectric`]).
    #[inline]
    pub fn disperses(&self) -> bool {
        match self {
            Bsdf::Dielectric(d) => d.eta_spectrum.is_some() || d.dispersion.is_some(),
            Bsdf::ThinDielectric(d) => d.eta_spectrum.is_some(),
            Bsdf::Layered(l) => l.coat.eta_spectrum.is_some(),
            Bsdf::GltfTransmission(t) => t.dispersion.is_some(),
            _ => false,
        }
    }

    /// A dielectric with glTF roughness `roughness` (α = roughness²); smooth below the GGX floor.
    pub fn dielectric(eta: f32, roughness: f32, tint: Vec3) -> Bsdf {
        Bsdf::Dielectric(Dielectric::new(eta, roughness, tint))
    }

    /// A thin-walled sheet with glTF roughness `roughness`; smooth below the GGX floor.
    pub fn thin_dielectric(eta: f32, roughness: f32, tint: Vec3) -> Bsdf {
        Bsdf::ThinDielectric(ThinDielectric::new(eta, roughness, tint))
    }

    /// Places the clearcoat's normal and the geometric normal on its side (the outside: the
    /// side the ray came from for an opaque BSDF, the surface's own for a transmissive one),
    /// both given in the local shading frame (the integrator knows the frame; see
    /// [`super::eval::clearcoat_normal`]). No effect on BSDFs without a coat.
    #[inline]
    pub fn set_coat_normal(&mut self, local: Vec3, outside: Vec3) {
        match self {
            Bsdf::MetallicRoughness(MetallicRoughness { coat: Some(c), .. })
            | Bsdf::GltfTransmission(GltfTransmission { coat: Some(c), .. }) => {
                *c = c.with_normal(local).with_outside(outside);
            }
            _ => {}
        }
    }

    /// Keeps what the BSDF computes from `wo` alone for the calls with this `wo` (the path
    /// vertex's): bit-identical results, fewer instructions ([`MetallicRoughness::prepare`]).
    /// Call it after the BSDF is final (coat normal placed, bitangent flipped).
    #[inline]
    pub fn prepare(&mut self, wo: Vec3) {
        if let Bsdf::MetallicRoughness(b) = self {
            b.prepare(wo);
        }
    }

    /// The local frame was built around the flipped shading normal (two-sided shading), whose
    /// bitangent is the negated one: mirrors the KHR_materials_anisotropy direction, which
    /// [`super::eval`] expresses in the unflipped frame.
    #[inline]
    pub fn flip_bitangent(&mut self) {
        match self {
            Bsdf::MetallicRoughness(MetallicRoughness { ext, .. }) => {
                if let Some(a) = &mut ext.anisotropy {
                    a.dir.y = -a.dir.y;
                }
            }
            Bsdf::GltfTransmission(GltfTransmission { rough: Some(a), .. }) => a.dir.y = -a.dir.y,
            _ => {}
        }
    }

    /// True if light may scatter between `wo` and `wi_local` (local frame) when `wi` lies on
    /// side `wi_dot_ng` of the geometric normal as the integrator oriented it (towards `wo` for
    /// opaque BSDFs). Shading and geometric normals must agree on the side of `wi`, or light
    /// would leak through the surface; that is the rule, except for a clearcoated glTF material:
    /// its coat reflects about its own normal (KHR_materials_clearcoat), possibly into
    /// directions below the base's normal-mapped shading plane, which are right whenever they
    /// are above the geometric surface. Without transmission the base's lobes are zero there;
    /// with transmission the BSDF knows the geometric normal ([`Bsdf::set_coat_normal`]) and
    /// gives only the coat's reflection wherever the two normals disagree (zero where the coat
    /// does not reach), so every direction is left to it.
    #[inline]
    pub fn side_consistent(&self, wi_local: Vec3, wi_dot_ng: f32) -> bool {
        match self {
            Bsdf::MetallicRoughness(b) if b.coat.is_some() && !b.transmits() => wi_dot_ng > 0.0,
            Bsdf::MetallicRoughness(MetallicRoughness { coat: Some(_), .. })
            | Bsdf::GltfTransmission(GltfTransmission { coat: Some(_), .. }) => true,
            _ => wi_dot_ng * wi_local.z > 0.0,
        }
    }

    /// True if the BSDF is zero for every pair of directions: a black Lambertian surface, such
    /// as an emitter without a base colour (glTF emitters usually have none). Light sampling
    /// there can only return zero, so next-event estimation skips it (the choice of a light
    /// in a light BVH is the costly part of NEE).
    #[inline]
    pub fn is_black(&self) -> bool {
        matches!(self, Bsdf::Diffuse(d) if d.albedo == Vec3::ZERO)
    }

    /// True if every lobe is a Dirac delta (light sampling is pointless).
    #[inline]
    pub fn is_specular(&self) -> bool {
        match self {
            Bsdf::Diffuse(_) | Bsdf::MetallicRoughness(_) => false,
            Bsdf::Mirror(_) => true,
            Bsdf::Dielectric(b) => b.ggx.is_none(),
            Bsdf::ThinDielectric(b) => b.ggx.is_none(),
            Bsdf::Conductor(b) => b.is_specular(),
            Bsdf::DiffuseTransmission(_) => false,
            Bsdf::Layered(b) => b.is_specular(),
            Bsdf::GltfTransmission(b) => b.is_specular(),
            Bsdf::Hair(_) => false,
        }
    }

    /// True if some lobe is diffuse (pbrt-v4's `IsDiffuse(bsdf.Flags())`): a Lambertian base,
    /// reflected or transmitted, or a layer's scattering medium. Glossy-only and specular BSDFs
    /// (conductors, dielectrics, mirrors, hair) are not. SPPM places its visible points by it.
    #[inline]
    pub fn has_diffuse_lobe(&self) -> bool {
        match self {
            Bsdf::Diffuse(_) | Bsdf::DiffuseTransmission(_) => true,
            Bsdf::MetallicRoughness(b) => b.metallic < 1.0,
            Bsdf::Layered(b) => {
                matches!(b.base, super::bxdf::layered::Base::Diffuse { .. })
                    || b.albedo != Vec3::ZERO
            }
            Bsdf::Mirror(_)
            | Bsdf::Dielectric(_)
            | Bsdf::ThinDielectric(_)
            | Bsdf::Conductor(_)
            | Bsdf::GltfTransmission(_)
            | Bsdf::Hair(_) => false,
        }
    }

    /// True if `sample` ignores its lobe-choice number.
    #[inline]
    pub fn has_one_lobe(&self) -> bool {
        matches!(
            self,
            Bsdf::Diffuse(_) | Bsdf::Mirror(_) | Bsdf::Conductor(_)
        )
    }

    /// True if the BSDF transmits: its frame must keep the geometric orientation.
    #[inline]
    pub fn is_transmissive(&self) -> bool {
        match self {
            Bsdf::Dielectric(_)
            | Bsdf::ThinDielectric(_)
            | Bsdf::DiffuseTransmission(_)
            | Bsdf::GltfTransmission(_)
            | Bsdf::Hair(_) => true,
            Bsdf::MetallicRoughness(b) => b.transmits(),
            _ => false,
        }
    }

    /// f(wo, wi), without the cosine.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self {
            Bsdf::Diffuse(b) => b.eval(wo, wi),
            Bsdf::MetallicRoughness(b) => b.eval(wo, wi),
            Bsdf::Mirror(b) => b.eval(wo, wi),
            Bsdf::Dielectric(b) => b.eval(wo, wi),
            Bsdf::ThinDielectric(b) => b.eval(wo, wi),
            Bsdf::Conductor(b) => b.eval(wo, wi),
            Bsdf::DiffuseTransmission(b) => b.eval(wo, wi),
            Bsdf::Layered(b) => b.eval(wo, wi),
            Bsdf::GltfTransmission(b) => b.eval(wo, wi),
            Bsdf::Hair(b) => b.eval(wo, wi),
        }
    }

    /// Solid-angle pdf with which `sample` returns `wi` (0 for Dirac lobes).
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Bsdf::Diffuse(b) => b.pdf(wo, wi),
            Bsdf::MetallicRoughness(b) => b.pdf(wo, wi),
            Bsdf::Mirror(b) => b.pdf(wo, wi),
            Bsdf::Dielectric(b) => b.pdf(wo, wi),
            Bsdf::ThinDielectric(b) => b.pdf(wo, wi),
            Bsdf::Conductor(b) => b.pdf(wo, wi),
            Bsdf::DiffuseTransmission(b) => b.pdf(wo, wi),
            Bsdf::Layered(b) => b.pdf(wo, wi),
            Bsdf::GltfTransmission(b) => b.pdf(wo, wi),
            Bsdf::Hair(b) => b.pdf(wo, wi),
        }
    }

    /// Samples an incident direction. `u_lobe` chooses among lobes, `u` the direction.
    #[inline]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        match self {
            Bsdf::Diffuse(b) => b.sample(wo, u),
            Bsdf::MetallicRoughness(b) => b.sample(wo, u_lobe, u),
            Bsdf::Mirror(b) => b.sample(wo),
            Bsdf::Dielectric(b) => b.sample(wo, u_lobe, u),
            Bsdf::ThinDielectric(b) => b.sample(wo, u_lobe, u),
            Bsdf::Conductor(b) => b.sample(wo, u),
            Bsdf::DiffuseTransmission(b) => b.sample(wo, u_lobe, u),
            Bsdf::Layered(b) => b.sample(wo, u_lobe, u),
            Bsdf::GltfTransmission(b) => b.sample(wo, u_lobe, u),
            Bsdf::Hair(b) => b.sample(wo, u_lobe, u),
        }
    }

    /// Per channel, the relative IOR η' crossed from `wo` to `wi`: 1 for reflection and for
    /// every BSDF that does not refract (thin sheets, diffuse transmission, and the coated
    /// layers, whose light enters and leaves through the same interface so the η'² cancel).
    #[inline]
    pub fn eta_crossed(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self {
            Bsdf::Dielectric(b) => b.eta_crossed(wo, wi),
            Bsdf::GltfTransmission(b) => b.eta_crossed(wo, wi),
            Bsdf::Diffuse(_)
            | Bsdf::MetallicRoughness(_)
            | Bsdf::Mirror(_)
            | Bsdf::ThinDielectric(_)
            | Bsdf::Conductor(_)
            | Bsdf::DiffuseTransmission(_)
            | Bsdf::Layered(_)
            | Bsdf::Hair(_) => Vec3::ONE,
        }
    }

    /// f(wo, wi) for the quantity `mode` carries: [`Bsdf::eval`] for radiance, the adjoint
    /// f*(wo, wi) = f(wi, wo) for importance — the radiance value without the 1/η'² of
    /// refraction (Veach 1997 §5.2; pbrt-v4's BxDFs divide by η'² only in
    /// `TransportMode::Radiance`). The pdf does not depend on the mode.
    #[inline]
    pub fn eval_mode(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Vec3 {
        let f = self.eval(wo, wi);
        match mode {
            TransportMode::Radiance => f,
            TransportMode::Importance => {
                let e = self.eta_crossed(wo, wi);
                f * e * e
            }
        }
    }

    /// [`Bsdf::sample`] for the quantity `mode` carries: the same direction and pdf, with the
    /// value of [`Bsdf::eval_mode`] (for a Dirac lobe, its coefficient without the 1/η'²).
    #[inline]
    pub fn sample_mode(
        &self,
        wo: Vec3,
        u_lobe: f32,
        u: Vec2,
        mode: TransportMode,
    ) -> Option<BsdfSample> {
        let mut s = self.sample(wo, u_lobe, u)?;
        if mode == TransportMode::Importance {
            let e = self.eta_crossed(wo, s.wi);
            s.f *= e * e;
        }
        Some(s)
    }

    /// Hemispherical albedo estimate used by the raycast `albedo` view and RR heuristics.
    pub fn albedo(&self) -> Vec3 {
        match self {
            Bsdf::Diffuse(b) => b.albedo,
            Bsdf::MetallicRoughness(b) => b.base,
            Bsdf::Mirror(b) => b.color,
            Bsdf::Dielectric(b) => b.tint,
            Bsdf::ThinDielectric(b) => b.tint,
            Bsdf::Conductor(b) => b.albedo(),
            Bsdf::DiffuseTransmission(b) => b.reflectance + b.transmittance,
            Bsdf::Layered(b) => b.albedo(),
            Bsdf::GltfTransmission(b) => b.tint,
            Bsdf::Hair(b) => b.albedo(),
        }
    }
}

/// The IOR at `lambda` of the Cauchy law n(λ) = A + B/λ² through per-channel IORs `rgb` given at
/// [`super::bxdf::dielectric::CHANNEL_WAVELENGTHS`] (fitted through red and blue). The
/// KHR_materials_dispersion law is of this form, so its IOR is recovered exactly; never below 1.
fn cauchy_at(rgb: Vec3, lambda: f32) -> f32 {
    let [lr, _, lb] = super::bxdf::dielectric::CHANNEL_WAVELENGTHS;
    let (ir, ib) = (1.0 / (lr * lr), 1.0 / (lb * lb));
    let b = (rgb.z - rgb.x) / (ib - ir);
    let a = rgb.x - b * ir;
    (a + b / (lambda * lambda)).max(1.0)
}

/// η of the spectrum `id` at the hero wavelength `lambda.x`; pbrt-v4's dielectric, thin
/// dielectric and coated materials take a sampled η that is 0 beyond its wavelengths as an
/// index-matched interface (η = 1).
#[inline]
fn hero_eta(spectra: &crate::spectrum::BsdfSpectra, id: u16, lambda: Vec3) -> f32 {
    let e = spectra.value(id, lambda.x);
    if e == 0.0 { 1.0 } else { e }
}

/// A conductor at three wavelengths: its named η/k spectra where it has them, else its RGB η and
/// k upsampled as unbounded spectra (pbrt-v4 `RGBUnboundedSpectrum`).
#[inline]
fn conductor_at(
    c: &mut super::bxdf::Conductor,
    lambda: Vec3,
    spectra: &crate::spectrum::BsdfSpectra,
) {
    use crate::spectrum::rgb2spec::unbounded;
    (c.eta, c.k) = match c.spectra {
        Some(s) => s.eta_k(lambda, spectra, c.eta, c.k),
        None => (unbounded(c.eta, lambda), unbounded(c.k, lambda)),
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// NEE skips vertices whose BSDF `is_black` (the image must not change): such a BSDF must
    /// be zero for every pair of directions, and a BSDF that reflects anything is not black.
    #[test]
    fn a_black_bsdf_is_zero_everywhere_and_no_other_is_black() {
        let dir = |k: u32| {
            let (a, b) = (k as f32 * 0.37, k as f32 * 0.11);
            Vec3::new(a.cos() * b.sin(), a.sin() * b.sin(), b.cos()).normalize()
        };
        let black = Bsdf::Diffuse(Diffuse { albedo: Vec3::ZERO });
        assert!(black.is_black());
        for i in 0..40 {
            for j in 0..40 {
                assert_eq!(black.eval(dir(i), dir(j)), Vec3::ZERO);
            }
        }
        for b in [
            Bsdf::Diffuse(Diffuse {
                albedo: Vec3::new(0.0, 0.0, 1e-6),
            }),
            Bsdf::dielectric(1.5, 0.3, Vec3::ONE),
            Bsdf::thin_dielectric(1.5, 0.0, Vec3::ONE),
        ] {
            assert!(!b.is_black(), "{b:?}");
        }
    }

    /// A deterministic stream of directions: on the whole sphere, or above the surface.
    struct Dirs(u64);

    impl Dirs {
        fn next_f32(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 40) as f32) / (1u64 << 24) as f32
        }

        fn dir(&mut self, upper: bool) -> Vec3 {
            let z = 2.0 * self.next_f32() - 1.0;
            let z = if upper { z.abs().max(0.02) } else { z };
            let phi = 2.0 * std::f32::consts::PI * self.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        }
    }

    /// The adjoint that light paths use, f*(wo, wi) = f(wi, wo) (Veach 1997 §3.7.6), holds for
    /// every reciprocal BSDF: the transmitting ones differ from their transpose in radiance by the
    /// η'² of refraction, and `eval_mode(Importance)` restores it.
    #[test]
    fn importance_is_the_adjoint_of_radiance() {
        let dispersive = Dielectric::new(1.5, 0.4, Vec3::new(0.9, 0.8, 0.7))
            .with_dispersion(Vec3::new(1.45, 1.5, 1.6));
        let rough_gltf = GltfTransmission::new(1.4, 0.5, Vec3::new(0.8, 0.9, 1.0), false)
            .with_roughness(0.5, 0.4, Vec2::new(0.6, 0.8));
        let mut gltf_dispersive = GltfTransmission::new(1.5, 0.4, Vec3::ONE, false);
        gltf_dispersive.dispersion = Some(Vec3::new(1.45, 1.5, 1.58));
        let glossy = MetallicRoughness {
            base: Vec3::new(0.6, 0.3, 0.2),
            metallic: 0.3,
            ggx: crate::material::microfacet::Ggx::new(0.2),
            f0_dielectric: Vec3::splat(0.04),
            specular: 1.0,
            coat: None,
            ext: Default::default(),
            wo_terms: None,
        };
        let cases: [(Bsdf, bool); 10] = [
            (
                Bsdf::Diffuse(Diffuse {
                    albedo: Vec3::new(0.7, 0.5, 0.2),
                }),
                true,
            ),
            (Bsdf::MetallicRoughness(glossy), true),
            (
                Bsdf::Conductor(Conductor::new(
                    Vec3::new(0.2, 0.9, 1.1),
                    Vec3::new(3.9, 2.4, 2.2),
                    0.1,
                    0.4,
                )),
                true,
            ),
            (Bsdf::dielectric(1.5, 0.5, Vec3::new(0.9, 0.8, 0.7)), false),
            (Bsdf::dielectric(1.0 / 1.33, 0.3, Vec3::ONE), false),
            (Bsdf::Dielectric(dispersive), false),
            (
                Bsdf::thin_dielectric(1.5, 0.4, Vec3::new(0.9, 0.8, 0.7)),
                false,
            ),
            (
                Bsdf::DiffuseTransmission(DiffuseTransmission {
                    reflectance: Vec3::new(0.3, 0.4, 0.5),
                    transmittance: Vec3::new(0.6, 0.2, 0.1),
                }),
                false,
            ),
            (Bsdf::GltfTransmission(rough_gltf), false),
            (Bsdf::GltfTransmission(gltf_dispersive), false),
        ];
        let mut d = Dirs(7);
        for (b, opaque) in cases {
            let mut checked = 0;
            let mut asymmetric = 0;
            for _ in 0..4000 {
                let (wo, wi) = (d.dir(opaque), d.dir(opaque));
                let adjoint = b.eval_mode(wo, wi, TransportMode::Importance);
                let transpose = b.eval_mode(wi, wo, TransportMode::Radiance);
                let scale = adjoint.max_element().max(transpose.max_element());
                if !(scale > 1e-4) || !scale.is_finite() {
                    continue;
                }
                checked += 1;
                // f32 rounding of the half vector at grazing angles reaches a few 1e-3; a
                // missing or doubled η'² is a factor 1.8 to 2.3.
                assert!(
                    (adjoint - transpose).abs().max_element() <= 1e-2 * scale,
                    "{b:?}\nwo {wo} wi {wi}: f* {adjoint} vs f(wi, wo) {transpose}"
                );
                let f = b.eval(wo, wi);
                if (f - transpose).abs().max_element() > 0.05 * scale {
                    asymmetric += 1;
                }
            }
            assert!(checked > 500, "{b:?}: only {checked} nonzero pairs");
            // Refraction makes radiance's f asymmetric: the adjoint is not f itself there.
            if matches!(b, Bsdf::Dielectric(_) | Bsdf::GltfTransmission(_)) {
                assert!(asymmetric > 50, "{b:?}: {asymmetric}");
            }
            // Sampling carries the same value as evaluation in each mode.
            for _ in 0..200 {
                let wo = d.dir(opaque);
                let (ul, u) = (d.next_f32(), Vec2::new(d.next_f32(), d.next_f32()));
                let (Some(r), Some(i)) = (
                    b.sample_mode(wo, ul, u, TransportMode::Radiance),
                    b.sample_mode(wo, ul, u, TransportMode::Importance),
                ) else {
                    continue;
                };
                assert_eq!((r.wi, r.pdf), (i.wi, i.pdf));
                let e = b.eta_crossed(wo, r.wi);
                assert!((i.f - r.f * e * e).abs().max_element() <= 1e-5 * i.f.max_element());
            }
        }
        // The smooth interface's Dirac refraction: radiance carries T/η'², importance T.
        let glass = Bsdf::dielectric(1.5, 0.0, Vec3::ONE);
        let wo = Vec3::new(0.3, 0.1, 0.8).normalize();
        let r = glass.sample_mode(wo, 0.99, Vec2::ZERO, TransportMode::Radiance);
        let i = glass.sample_mode(wo, 0.99, Vec2::ZERO, TransportMode::Importance);
        let (r, i) = (r.unwrap(), i.unwrap());
        assert!(r.specular && r.wi.z < 0.0 && r.eta == 1.5);
        let t = 1.0 - crate::material::microfacet::fresnel_dielectric(wo.z, 1.5);
        assert!((i.f.x * i.wi.z.abs() - t).abs() < 1e-5);
        assert!((r.f.x * r.wi.z.abs() - t / 2.25).abs() < 1e-5);
    }

    /// Veach's shading-normal correction turns f·|wi·ns| into the adjoint's throughput: with
    /// shading normals the BSDF against the geometric measure is f_s(wo, wi) = f(wo, wi)
    /// |wi·ns| / |wi·ng|, and importance must carry f_s(wi, wo)·|wi·ng| (Veach 1997 §5.3).
    #[test]
    fn shading_normal_correction_gives_the_adjoint() {
        let b = Bsdf::Diffuse(Diffuse {
            albedo: Vec3::new(0.8, 0.6, 0.4),
        });
        let mut d = Dirs(3);
        let ns = Vec3::Z;
        let mut n = 0;
        for _ in 0..500 {
            let ng = (Vec3::Z + d.dir(false) * 0.4).normalize();
            let (wo, wi) = (d.dir(true), d.dir(true));
            if wo.dot(ng) <= 0.01 || wi.dot(ng) <= 0.01 {
                continue;
            }
            n += 1;
            let f_s = |a: Vec3, b_: Vec3| b.eval(a, b_) * (b_.dot(ns).abs() / b_.dot(ng).abs());
            let corr = TransportMode::Importance.shading_normal_correction(wo, wi, ns, ng);
            let carried = b.eval_mode(wo, wi, TransportMode::Importance) * wi.z.abs() * corr;
            let adjoint = f_s(wi, wo) * wi.dot(ng).abs();
            assert!(
                (carried - adjoint).abs().max_element() < 1e-4,
                "{carried} vs {adjoint}"
            );
            assert_eq!(
                TransportMode::Radiance.shading_normal_correction(wo, wi, ns, ng),
                1.0
            );
        }
        assert!(n > 100);
    }
}
