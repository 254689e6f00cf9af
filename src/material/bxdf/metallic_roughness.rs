//! The glTF 2.0 metallic-roughness BRDF (glTF spec, appendix B) with the KHR material extensions
//! that change its lobes:
//!
//! * `KHR_materials_clearcoat` ([`Clearcoat`], the top layer) and `KHR_materials_sheen`
//!   ([`Sheen`], under the coat), both layered by albedo scaling;
//! * `KHR_materials_anisotropy`: the specular lobes use [`Ggx`] with α_t = mix(α, 1, s²)
//!   along the anisotropy direction and α_b = α across it (extension text), sampled by visible
//!   normals in the rotated frame;
//! * `KHR_materials_iridescence`: the specular Fresnel terms become
//!   mix(F_schlick, F_thin-film, factor) ([`Iridescence`]);
//! * `KHR_materials_diffuse_transmission`: the dielectric's diffuse lobe becomes
//!   mix(diffuse_brdf(base), diffuse_btdf(colour), factor). The BSDF then transmits: its frame
//!   keeps the geometric orientation and a view from behind is evaluated mirrored (the sheet is
//!   thin and symmetric), the coat's normal mirrored with it. The BTDF's Fresnel weight uses the
//!   half vector of the mirrored light direction, as for reflection, so the BTDF is symmetric
//!   under exchanging the two sides.
//!
//! Sampling is one-sample MIS over the lobes (coat, sheen, specular, diffuse reflection, diffuse
//! transmission) and every sample reports the whole mixture's pdf and value, so each lobe can
//! produce any direction consistently.

use super::BsdfSample;
use crate::material::clearcoat::Clearcoat;
use crate::material::iridescence::Iridescence;
use crate::material::microfacet::{Ggx, reflect, schlick};
use crate::material::sheen::Sheen;
use crate::math::{INV_PI, Vec2, Vec3, luminance};
use crate::sampling::warp;

/// KHR_materials_anisotropy at a shading point: the anisotropic distribution (α_x along the
/// anisotropy direction, α_y across it) and that direction's unit (cos, sin) in the local
/// shading frame's xy plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Anisotropy {
    pub dist: Ggx,
    pub dir: Vec2,
}

impl Anisotropy {
    /// glTF roughness `roughness`, strength `strength` ∈ [0, 1] and direction `dir` (local xy):
    /// α = roughness², α_t = α + (1 − α)·strength², α_b = α (KHR_materials_anisotropy).
    pub fn new(roughness: f32, strength: f32, dir: Vec2) -> Anisotropy {
        let a = roughness.clamp(0.0, 1.0).powi(2);
        let s = strength.clamp(0.0, 1.0);
        let at = a + (1.0 - a) * s * s;
        let d = dir.normalize_or_zero();
        Anisotropy {
            dist: Ggx::anisotropic(at, a),
            dir: if d == Vec2::ZERO { Vec2::X } else { d },
        }
    }

    /// Local shading frame → the frame whose x axis is the anisotropy direction.
    #[inline]
    pub(crate) fn to_aniso(self, w: Vec3) -> Vec3 {
        let (c, s) = (self.dir.x, self.dir.y);
        Vec3::new(w.x * c + w.y * s, -w.x * s + w.y * c, w.z)
    }

    #[inline]
    pub(crate) fn to_local(self, w: Vec3) -> Vec3 {
        let (c, s) = (self.dir.x, self.dir.y);
        Vec3::new(w.x * c - w.y * s, w.x * s + w.y * c, w.z)
    }
}

/// The KHR extensions' state of a [`MetallicRoughness`] (all off by default).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Extensions {
    pub anisotropy: Option<Anisotropy>,
    pub sheen: Option<Sheen>,
    pub iridescence: Option<Iridescence>,
    /// KHR_materials_diffuse_transmission factor in [0, 1] and colour.
    pub diffuse_transmission: f32,
    pub diffuse_transmission_color: Vec3,
}

/// `mix(fresnel_mix(diffuse, specular), conductor(specular, F0 = base), metallic)` with a GGX
/// specular lobe, height-correlated Smith G2 and Schlick Fresnel.
#[derive(Clone, Copy, Debug)]
pub struct MetallicRoughness {
    pub base: Vec3,
    pub metallic: f32,
    pub ggx: Ggx,
    /// F0 of the dielectric layer: ((ior − 1)/(ior + 1))² × KHR specular colour, ≤ 1.
    pub f0_dielectric: Vec3,
    /// KHR_materials_specular strength (1 without the extension; 0 is pure Lambertian).
    pub specular: f32,
    /// KHR_materials_clearcoat layered on top (see [`Clearcoat`]): f = (1 − c·fr(V))·f_base +
    /// f_coat. Its normal is +z until [`crate::material::Bsdf::set_coat_normal`] places it.
    pub coat: Option<Clearcoat>,
    pub ext: Extensions,
    /// The terms that depend on the outgoing direction alone, for the one `wo` of the path
    /// vertex ([`MetallicRoughness::prepare`]); `None` computes them at every use.
    pub wo_terms: Option<WoTerms>,
}

/// What [`MetallicRoughness`] computes from `wo` alone, kept for one `wo`. A path vertex
/// evaluates, samples and takes pdfs with the same `wo` several times (NEE's eval and pdf, the
/// BSDF sample's lobe choice, pdf and value): ToyCar recomputed the specular-lobe probability
/// ~2.3 times per vertex, the sheen's albedo-table lookup of `wo` ~4 times and its Λ(wo) (a
/// `powf` and an `exp`) twice. The values are those the uncached code computes, from the same
/// inputs, so results are bit-identical; a different `wo` (bit for bit) falls back to computing.
#[derive(Clone, Copy, Debug)]
pub struct WoTerms {
    wo: [u32; 3],
    spec_probability: f32,
    /// E(N·V) and Λ(wo.z) of the sheen (0 without one).
    sheen_albedo: f32,
    sheen_lambda: f32,
}

/// Mirror through the surface plane (a view from behind a thin sheet, evaluated from the front).
#[inline]
fn mirror_z(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, -w.z)
}

impl MetallicRoughness {
    /// Keeps the terms that depend on `wo` alone ([`WoTerms`]) for the calls with this `wo`.
    #[inline]
    pub fn prepare(&mut self, wo: Vec3) {
        self.wo_terms = None;
        self.wo_terms = Some(WoTerms {
            wo: wo.to_array().map(f32::to_bits),
            spec_probability: self.spec_probability(wo),
            sheen_albedo: self.ext.sheen.map_or(0.0, |s| s.albedo_of(wo)),
            sheen_lambda: self.ext.sheen.map_or(0.0, |s| s.lambda_of(wo)),
        });
    }

    /// The kept [`WoTerms`] if they are `wo`'s.
    #[inline]
    fn terms(&self, wo: Vec3) -> Option<&WoTerms> {
        self.wo_terms
            .as_ref()
            .filter(|t| t.wo == wo.to_array().map(f32::to_bits))
    }

    /// The sheen's probability of being sampled from `wo` ([`sheen_probability`]).
    #[inline]
    fn sheen_probability(&self, s: &Sheen, wo: Vec3) -> f32 {
        sheen_share(s.weight_with(self.terms(wo).map(|t| t.sheen_albedo), wo))
    }

    /// True when the diffuse lobe transmits (KHR_materials_diffuse_transmission).
    #[inline]
    pub fn transmits(&self) -> bool {
        self.ext.diffuse_transmission > 0.0
    }

    /// The configuration evaluated for (wo, wi): a view from behind a transmitting sheet is
    /// mirrored to the front, with its coat normal.
    #[inline]
    fn canonical(&self, wo: Vec3, wi: Vec3) -> (MetallicRoughness, Vec3, Vec3, bool) {
        if self.transmits() && wo.z < 0.0 {
            let mut b = *self;
            if let Some(c) = &mut b.coat {
                *c = c.mirrored();
            }
            (b, mirror_z(wo), mirror_z(wi), true)
        } else {
            (*self, wo, wi, false)
        }
    }

    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if !self.transmits() {
            // Each layer checks its own hemisphere: the coat reflects about its own normal.
            return self.eval_coated(wo, wi);
        }
        let (b, wo, wi, _) = self.canonical(wo, wi);
        b.eval_front(wo, wi)
    }

    /// f for `wo` above, `wi` on either side (diffuse transmission only below). Where the
    /// surface and the base's shading plane disagree on the side of `wi`, only the coat can
    /// scatter: a reflection about its own normal that stays outside the surface
    /// ([`Clearcoat::agrees`]); the base's lobes, in the shading frame, see none of it.
    #[inline]
    fn eval_front(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z == 0.0 {
            return Vec3::ZERO;
        }
        if let Some(c) = &self.coat
            && !c.agrees(wi)
        {
            return if c.is_outside(wi) {
                Vec3::splat(coat_in_base_cosine(c, wo, wi))
            } else {
                Vec3::ZERO
            };
        }
        if wi.z > 0.0 {
            self.eval_coated(wo, wi)
        } else {
            self.eval_transmitted(wo, wi)
        }
    }

    /// The base, scaled by what the sheen and the coat leave of it, plus the sheen and the coat.
    /// The base and the sheen live in the hemisphere of the (normal-mapped) shading normal, the
    /// coat in that of its own normal N_c (glTF appendix B: `fresnel_coat(clearcoat_normal, …)`),
    /// so where N_c tilts away from the base normal the coat still reflects about N_c, also into
    /// directions below the base's shading plane (the integrators accept those when they are
    /// above the geometric surface, [`crate::material::Bsdf::side_consistent`]).
    #[inline]
    fn eval_coated(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let under = if wo.z > 0.0 && wi.z > 0.0 {
            match &self.ext.sheen {
                None => self.eval_above(wo, wi),
                Some(s) => {
                    let t = self.terms(wo);
                    s.eval_with(t.map(|t| t.sheen_lambda), wo, wi)
                        + self.eval_above(wo, wi)
                            * s.base_scale_with(t.map(|t| t.sheen_albedo), wo, wi)
                }
            }
        } else {
            Vec3::ZERO
        };
        match &self.coat {
            None => under,
            Some(c) => {
                under * (1.0 - c.layer_weight(wo)) + Vec3::splat(coat_in_base_cosine(c, wo, wi))
            }
        }
    }

    /// Diffuse transmission to `wi` below: (1 − metallic)·(1 − F)·factor·colour/π, under the
    /// sheen's and the coat's albedo scaling (neither transmits itself). The sheet is thin and
    /// both its faces carry the coat, so transmitted light crosses it twice, on entering and on
    /// leaving: (1 − c·fr(V))·(1 − c·fr(L)), each with that face's normal (the back face's is
    /// −N_c, and fr takes |cos|). This keeps the BTDF reciprocal.
    #[inline]
    fn eval_transmitted(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let wm = mirror_z(wi);
        let h = wo + wm;
        if h.length_squared() == 0.0 {
            return Vec3::ZERO;
        }
        let voh = wo.dot(h.normalize());
        let f_d = self.dielectric_fresnel(voh);
        let e = &self.ext;
        let mut t = e.diffuse_transmission_color
            * (e.diffuse_transmission * (1.0 - self.metallic) * INV_PI * (1.0 - f_d.max_element()));
        if let Some(s) = &e.sheen {
            t *= s.base_scale(wo, wm);
        }
        if let Some(c) = &self.coat {
            t *= (1.0 - c.layer_weight(wo)) * (1.0 - c.layer_weight(wi));
        }
        t
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !self.transmits() {
            return self.pdf_front(wo, wi);
        }
        let (b, wo, wi, _) = self.canonical(wo, wi);
        if wo.z <= 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        b.pdf_front(wo, wi)
    }

    /// The mixture pdf for `wo` above (above the base's or, without transmission, the coat's
    /// plane).
    #[inline]
    fn pdf_front(&self, wo: Vec3, wi: Vec3) -> f32 {
        let p_coat = self.coat_share(wo);
        if p_coat >= 1.0 {
            // Only the coat is sampled (`wo` is below the base's shading plane).
            return self.coat.as_ref().map_or(0.0, |c| c.pdf(wo, wi));
        }
        if wo.z <= 0.0 {
            return 0.0;
        }
        let base = if wi.z > 0.0 {
            let p_spec = self.spec_probability(wo);
            let h = (wo + wi).normalize();
            let spec = self.spec_d_visible(wo, h) / (4.0 * wo.dot(h));
            let diffuse = warp::cosine_hemisphere_pdf(wi.z);
            let diffuse = if self.transmits() {
                diffuse * (1.0 - self.transmit_probability())
            } else {
                diffuse
            };
            p_spec * spec + (1.0 - p_spec) * diffuse
        } else {
            (1.0 - self.spec_probability(wo))
                * self.transmit_probability()
                * warp::cosine_hemisphere_pdf(-wi.z)
        };
        let under = match &self.ext.sheen {
            None => base,
            Some(s) => {
                let p = self.sheen_probability(s, wo);
                let sheen = if wi.z > 0.0 {
                    warp::uniform_cone_pdf(0.0)
                } else {
                    0.0
                };
                p * sheen + (1.0 - p) * base
            }
        };
        match &self.coat {
            None => under,
            Some(c) => {
                // With diffuse transmission a direction below the base's plane is a transmitted
                // one, which the coat does not produce ([`Self::sample_front`]), unless it is
                // still outside the surface.
                let coat = if wi.z > 0.0 || !self.transmits() || c.is_outside(wi) {
                    c.pdf(wo, wi)
                } else {
                    0.0
                };
                p_coat * coat + (1.0 - p_coat) * under
            }
        }
    }

    /// Probability of sampling the coat lobe: [`coat_probability`], or 1 when the base cannot
    /// scatter (`wo` below its shading plane: only the coat, about its own normal, can), 0
    /// without a coat.
    #[inline]
    fn coat_share(&self, wo: Vec3) -> f32 {
        match &self.coat {
            None => 0.0,
            Some(_) if wo.z <= 0.0 && !self.transmits() => 1.0,
            Some(c) => coat_probability(c, wo),
        }
    }

    /// Picks the coat, the sheen, the specular lobe (visible normals, Heitz 2018) or the diffuse
    /// one (reflected or transmitted) with `u_lobe`.
    #[inline]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if self.transmits() && wo.z < 0.0 {
            let (b, wo, _, flipped) = self.canonical(wo, wo);
            return b.sample_canonical(wo, u_lobe, u, flipped);
        }
        // Not mirrored: `canonical` would only copy the BSDF (200 bytes, a `memcpy` call).
        self.sample_canonical(wo, u_lobe, u, false)
    }

    /// [`MetallicRoughness::sample`] for the configuration [`MetallicRoughness::canonical`]
    /// gives; `flipped` mirrors the sampled direction back.
    #[inline]
    fn sample_canonical(
        &self,
        wo: Vec3,
        u_lobe: f32,
        u: Vec2,
        flipped: bool,
    ) -> Option<BsdfSample> {
        let b = self;
        if wo.z <= 0.0 && (b.transmits() || b.coat.is_none()) {
            return None;
        }
        let wi = b.sample_front(wo, u_lobe, u)?;
        // The sample's pdf and value are those of the whole mixture (one-sample MIS over
        // lobes), so either lobe can produce any direction consistently.
        let pdf = b.pdf_front(wo, wi);
        let out = if flipped { mirror_z(wi) } else { wi };
        BsdfSample::glossy(out, pdf, 1.0, || {
            if b.transmits() {
                b.eval_front(wo, wi)
            } else {
                b.eval_coated(wo, wi)
            }
        })
    }

    /// A direction from one lobe, for `wo` above (`None` if it leaves on the wrong side).
    #[inline]
    fn sample_front(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<Vec3> {
        // The coat first, with probability p_coat; the rest of `u_lobe`, rescaled to [0, 1),
        // chooses between the lower layers' lobes.
        let mut u_lobe = u_lobe;
        if let Some(c) = &self.coat {
            let p_coat = self.coat_share(wo);
            if u_lobe < p_coat {
                // The coat reflects about its own normal. With diffuse transmission a direction
                // below the surface would be a transmitted one: no sample.
                return c
                    .sample(wo, u)
                    .filter(|wi| wi.z > 0.0 || !self.transmits() || c.is_outside(*wi));
            }
            u_lobe = ((u_lobe - p_coat) / (1.0 - p_coat)).min(1.0 - f32::EPSILON);
        }
        if let Some(s) = &self.ext.sheen {
            let p = self.sheen_probability(s, wo);
            if u_lobe < p {
                return Some(warp::uniform_cone(u, 0.0));
            }
            u_lobe = ((u_lobe - p) / (1.0 - p)).min(1.0 - f32::EPSILON);
        }
        let p_spec = self.spec_probability(wo);
        let wi = if u_lobe < p_spec {
            let m = self.spec_sample_visible(wo, u);
            reflect(wo, m)
        } else {
            let mut wi = warp::cosine_hemisphere(u);
            if self.transmits() {
                let u_t = ((u_lobe - p_spec) / (1.0 - p_spec)).min(1.0 - f32::EPSILON);
                if u_t < self.transmit_probability() {
                    wi = mirror_z(wi);
                    return (wi.z < 0.0).then_some(wi);
                }
            }
            wi
        };
        (wi.z > 0.0).then_some(wi)
    }

    /// D(h)·G2(wo, wi) of the specular lobes: isotropic GGX, or anisotropic GGX in the frame of
    /// the anisotropy direction.
    #[inline]
    fn spec_dg2(&self, wo: Vec3, wi: Vec3, h: Vec3) -> f32 {
        match &self.ext.anisotropy {
            None => self.ggx.d(h) * self.ggx.g2(wo, wi),
            Some(a) => {
                let (o, i, m) = (a.to_aniso(wo), a.to_aniso(wi), a.to_aniso(h));
                a.dist.d(m) * a.dist.g2(o, i)
            }
        }
    }

    #[inline]
    fn spec_d_visible(&self, wo: Vec3, h: Vec3) -> f32 {
        match &self.ext.anisotropy {
            None => self.ggx.d_visible(wo, h),
            Some(a) => a.dist.d_visible(a.to_aniso(wo), a.to_aniso(h)),
        }
    }

    #[inline]
    fn spec_sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        match &self.ext.anisotropy {
            None => self.ggx.sample_visible(wo, u),
            Some(a) => a.to_local(a.dist.sample_visible(a.to_aniso(wo), u)),
        }
    }

    /// The dielectric layer's Fresnel term at V·H (× the KHR specular weight), with the thin film
    /// mixed in.
    #[inline]
    fn dielectric_fresnel(&self, voh: f32) -> Vec3 {
        let f = schlick(self.f0_dielectric, voh);
        let f = match &self.ext.iridescence {
            None => f,
            Some(ir) => ir.mix(f, voh, self.f0_dielectric),
        };
        f * self.specular
    }

    /// The BRDF for wo, wi both above the surface.
    #[inline]
    fn eval_above(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return Vec3::ZERO;
        }
        let h = h.normalize();
        let voh = wo.dot(h);
        let spec = self.spec_dg2(wo, wi, h) / (4.0 * wo.z * wi.z);
        // glTF appendix B: fresnel_mix for the dielectric layer (with KHR_materials_specular's
        // weight), conductor Fresnel with F0 = base colour for the metal.
        let f_d = self.dielectric_fresnel(voh);
        let diffuse = if self.transmits() {
            self.base * (1.0 - self.ext.diffuse_transmission)
        } else {
            self.base
        };
        let dielectric = diffuse * (INV_PI * (1.0 - f_d.max_element())) + f_d * spec;
        let f_m = schlick(self.base, voh);
        let f_m = match &self.ext.iridescence {
            None => f_m,
            Some(ir) => ir.mix(f_m, voh, self.base),
        };
        let metal = f_m * spec;
        dielectric * (1.0 - self.metallic) + metal * self.metallic
    }

    /// Probability of sampling the specular lobe: its estimated share of the reflected energy,
    /// with Fresnel evaluated at the viewing angle.
    #[inline]
    fn spec_probability(&self, wo: Vec3) -> f32 {
        if let Some(t) = self.terms(wo) {
            return t.spec_probability;
        }
        let (base, metallic) = (self.base, self.metallic);
        let f_d = schlick(self.f0_dielectric, wo.z) * self.specular;
        let w_spec = luminance(f_d * (1.0 - metallic) + schlick(base, wo.z) * metallic);
        let diffuse = if self.transmits() {
            let e = &self.ext;
            luminance(base) * (1.0 - e.diffuse_transmission)
                + luminance(e.diffuse_transmission_color) * e.diffuse_transmission
        } else {
            luminance(base)
        };
        let w_diff = (1.0 - metallic) * (1.0 - f_d.max_element()) * diffuse;
        if !(w_diff > 0.0) {
            1.0
        } else if !(w_spec > 0.0) {
            0.0
        } else {
            // Keep both lobes reachable so the mixture pdf never under-covers f.
            (w_spec / (w_spec + w_diff)).clamp(0.05, 0.95)
        }
    }

    /// Probability that a diffuse sample transmits: the transmitted share of the diffuse lobe's
    /// luminance, kept in [0.05, 0.95] when both sides carry light.
    #[inline]
    fn transmit_probability(&self) -> f32 {
        let e = &self.ext;
        let t = luminance(e.diffuse_transmission_color) * e.diffuse_transmission;
        let r = luminance(self.base) * (1.0 - e.diffuse_transmission);
        if !(t > 0.0) {
            0.0
        } else if !(r > 0.0) {
            1.0
        } else {
            (t / (t + r)).clamp(0.05, 0.95)
        }
    }
}

/// The coat lobe as the integrators weigh it. They multiply f by the cosine to the base's shading
/// normal, |wi.z|; the coat's radiance is weighed by its own cosine N_c·L (glTF appendix B; Cycles
/// evaluates its coat closure with its own normal too), so f carries (N_c·L)/|wi.z|. Zero on the
/// base's plane and wherever the coat lobe is. Directions within 10⁻⁶ of the base's plane are
/// dropped (a solid angle of ~6·10⁻⁶ sr) so that f stays finite.
#[inline]
pub(crate) fn coat_in_base_cosine(c: &Clearcoat, wo: Vec3, wi: Vec3) -> f32 {
    let cos_base = wi.z.abs();
    if cos_base < 1e-6 {
        return 0.0;
    }
    let f = c.eval(wo, wi);
    if f == 0.0 {
        return 0.0;
    }
    f * wi.dot(c.normal).max(0.0) / cos_base
}

/// Probability of sampling the clearcoat lobe: its Fresnel share c·fr(V) against what the base
/// keeps, (1 − c·fr)·½, clamped so both stay reachable (the mixture pdf must cover f).
#[inline]
pub(crate) fn coat_probability(c: &Clearcoat, wo: Vec3) -> f32 {
    let w = c.layer_weight(wo);
    (w / (w + 0.5 * (1.0 - w))).clamp(0.05, 0.95)
}

/// Probability of sampling the sheen lobe: its albedo share c·E(N·V) against what the base
/// keeps, (1 − c·E)·½, clamped like the coat's.
#[inline]
pub(crate) fn sheen_probability(s: &Sheen, wo: Vec3) -> f32 {
    sheen_share(s.weight(wo))
}

/// [`sheen_probability`] from the sheen's weight c·E(N·V).
#[inline]
fn sheen_share(w: f32) -> f32 {
    (w / (w + 0.5 * (1.0 - w))).clamp(0.05, 0.95)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// A prepared BSDF ([`MetallicRoughness::prepare`]) gives the same bits as an unprepared one
    /// for eval, pdf and sample at the prepared `wo`, and at other `wo` (where the kept terms do
    /// not apply), for a sheen + clearcoat material like ToyCar's fabric and body, with and
    /// without diffuse transmission. Fails if a kept term is computed from anything but what
    /// the uncached code uses (checked: Λ of a cosine scaled by 0.9999, the specular
    /// probability of `wo` scaled by 0.97; the mirrored `wo` is no test, Schlick takes |cos|).
    #[test]
    fn prepared_terms_change_no_bit() {
        let mut h = 0x2545_f491u32;
        fn next(h: &mut u32) -> f32 {
            *h ^= *h << 13;
            *h ^= *h >> 17;
            *h ^= *h << 5;
            *h as f32 / u32::MAX as f32
        }
        fn dir(h: &mut u32, upper: bool) -> Vec3 {
            let (a, b) = (next(h), next(h));
            let z = if upper { a.max(1e-3) } else { 2.0 * a - 1.0 };
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * std::f32::consts::PI * b;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        }
        for case in 0..6 {
            let mut ext = Extensions {
                sheen: Sheen::new(Vec3::new(0.8, 0.5, 0.3), 0.2 + 0.15 * case as f32),
                ..Default::default()
            };
            if case % 3 == 2 {
                ext.diffuse_transmission = 0.4;
                ext.diffuse_transmission_color = Vec3::new(0.9, 0.7, 0.5);
            }
            let coat = (case % 2 == 1).then(|| {
                Clearcoat::new(0.9, 0.3, Vec3::new(0.2, -0.1, 1.0))
                    .with_outside(Vec3::new(0.05, 0.1, 1.0))
            });
            let plain = MetallicRoughness {
                base: Vec3::new(0.6, 0.3, 0.2),
                metallic: 0.1 * case as f32,
                ggx: Ggx::new(0.2 + 0.05 * case as f32),
                f0_dielectric: Vec3::splat(0.04),
                specular: 1.0,
                coat,
                ext,
                wo_terms: None,
            };
            for _ in 0..300 {
                let wo = dir(&mut h, case % 3 != 2);
                let mut prepared = plain;
                prepared.prepare(wo);
                for _ in 0..8 {
                    let wi = dir(&mut h, false);
                    let other = dir(&mut h, false);
                    for w in [wo, other] {
                        assert_eq!(bits(prepared.eval(w, wi)), bits(plain.eval(w, wi)));
                        assert_eq!(prepared.pdf(w, wi).to_bits(), plain.pdf(w, wi).to_bits());
                        let (ul, uv) = (next(&mut h), Vec2::new(next(&mut h), next(&mut h)));
                        let (a, b) = (prepared.sample(w, ul, uv), plain.sample(w, ul, uv));
                        assert_eq!(a.is_some(), b.is_some(), "case {case}");
                        if let (Some(a), Some(b)) = (a, b) {
                            assert_eq!(bits(a.wi), bits(b.wi));
                            assert_eq!(bits(a.f), bits(b.f), "case {case} wo {w:?}");
                            assert_eq!(a.pdf.to_bits(), b.pdf.to_bits());
                        }
                    }
                }
            }
        }
    }
}
