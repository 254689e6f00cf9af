//! The transmissive component of a glTF material (KHR_materials_transmission, with or without
//! KHR_materials_volume) when the BRDF extensions that the glTF specification layers over the
//! whole material are present: `KHR_materials_clearcoat`, `_sheen`, `_anisotropy` and
//! `_iridescence`. Without them the component is a plain [`super::Dielectric`] (thick, volume)
//! or [`super::ThinDielectric`] (thin-walled), unchanged; this variant is their generalisation:
//!
//! * **anisotropy** (extension text: "the specular BTDF uses the same anisotropic
//!   distribution"): the microfacet lobes, reflected and refracted, use [`Ggx`] with
//!   α_t = mix(α, 1, s²) along the anisotropy direction, sampled by visible normals in the
//!   rotated frame (Walter et al. 2007 for the refraction, Heitz 2018 for the sampling);
//! * **iridescence**: the interface's Fresnel term becomes mix(F, F_thin-film, factor), RGB
//!   (Belcour & Barla 2017, [`Iridescence`]), and the transmitted weight is 1 − that. The film
//!   lies on the outside; seen from inside, F_thin-film is taken at the outside cosine given by
//!   Snell's law (a lossless stack reflects the same from both sides at corresponding angles, so
//!   the BTDF stays reciprocal). Reflection vs refraction is chosen with the mean of the RGB
//!   Fresnel term, and the sample reports that probability;
//! * **sheen** and **clearcoat** layered by albedo scaling (glTF appendix B, the extension
//!   texts): f = f_coat + (1 − c·F_c(V))·(f_sheen + S·f_base), S = min(1 − s·E(N·V),
//!   1 − s·E(N·L)). Both layers sit on the outside of the surface, so they only reflect on the
//!   outside. At a closed volume's surface transmitted light crosses them once: its weight
//!   uses the direction on the outside (V for light entering, L for light leaving), which
//!   equals the specification's V-only weight for a view from outside and keeps transmission
//!   reciprocal; light through the volume is so weighed on entering and on leaving. Internal
//!   reflection never reaches them. A thin-walled sheet (no volume) is evaluated from the side
//!   it is seen from, mirrored, as the specification's double-sided thin surface: its layers
//!   are on both faces, so light through it crosses the coat of each face,
//!   (1 − c·F_c(V))·(1 − c·F_c(L)), as the metallic-roughness sheet's diffuse transmission
//!   does. The coat reflects about its own normal N_c (a clearcoat normal map, or the vertex
//!   normal under a base normal map), also into directions below the base's shading plane that
//!   are still outside the surface: the coat knows the geometric normal
//!   ([`Clearcoat::outside`]), and where the surface and the shading plane disagree on the side
//!   of a direction only the coat scatters (the interface and the sheen live in the base's
//!   frame).
//! * **dispersion** (thick only, as the extension says) combines with all of the above: one IOR
//!   per channel and the one-sample mixture over channels of [`super::dielectric`].
//!
//! The smooth interface keeps its Dirac lobes, mixed with the continuous coat and sheen lobes:
//! a sample is Dirac (`specular`) or continuous per sample, `eval`/`pdf` give the continuous
//! part only, and [`GltfTransmission::is_specular`] is true only without a coat or a sheen.
//! Sampling is one-sample MIS over coat, sheen and interface, and every continuous sample
//! reports the whole mixture's pdf and value.

use super::BsdfSample;
use super::dielectric::half_vector;
use super::metallic_roughness::{
    Anisotropy, coat_in_base_cosine, coat_probability, sheen_probability,
};
use crate::material::clearcoat::Clearcoat;
use crate::material::iridescence::Iridescence;
use crate::material::microfacet::{MIN_ALPHA, fresnel_dielectric, reflect, refract};
use crate::material::sheen::Sheen;
use crate::math::{Vec2, Vec3};
use crate::sampling::warp;

#[derive(Clone, Copy, Debug)]
pub struct GltfTransmission {
    /// IOR inside / outside (the d-line IOR with dispersion).
    pub eta: f32,
    /// Multiplies transmitted light (the base colour).
    pub tint: Vec3,
    /// Thin-walled (no KHR_materials_volume): a symmetric sheet, no refraction.
    pub thin: bool,
    /// The microfacet distribution and its direction; `None` = smooth interface.
    pub rough: Option<Anisotropy>,
    /// Per-channel IORs (KHR_materials_dispersion, thick only).
    pub dispersion: Option<Vec3>,
    pub iridescence: Option<Iridescence>,
    pub coat: Option<Clearcoat>,
    pub sheen: Option<Sheen>,
}

#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

#[inline]
fn mirror_z(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, -w.z)
}

/// Reflectance and transmittance of a thin slab from its interface reflectance r, summing the
/// internal bounces: R' = r + t²r/(1 − r²) (PBRT-v4 §9.5.3), per channel.
#[inline]
fn slab(r: Vec3) -> (Vec3, Vec3) {
    let one = |r: f32| {
        if r < 1.0 {
            let t = 1.0 - r;
            r + t * t * r / (1.0 - r * r)
        } else {
            1.0
        }
    };
    let r = Vec3::new(one(r.x), one(r.y), one(r.z));
    (r, Vec3::ONE - r)
}

impl GltfTransmission {
    /// glTF roughness `roughness` (α = roughness²); `anisotropy` (strength, local direction)
    /// stretches it. Smooth when both α are below the GGX floor.
    pub fn new(eta: f32, roughness: f32, tint: Vec3, thin: bool) -> GltfTransmission {
        GltfTransmission {
            eta,
            tint,
            thin,
            rough: None,
            dispersion: None,
            iridescence: None,
            coat: None,
            sheen: None,
        }
        .with_roughness(roughness, 0.0, Vec2::X)
    }

    /// Sets the microfacet distribution: glTF roughness, anisotropy strength and direction.
    pub fn with_roughness(mut self, roughness: f32, strength: f32, dir: Vec2) -> Self {
        let a = Anisotropy::new(roughness, strength, dir);
        self.rough = (a.dist.alpha_x.max(a.dist.alpha_y) >= MIN_ALPHA).then_some(a);
        self
    }

    /// True if every lobe is a Dirac delta.
    #[inline]
    pub fn is_specular(&self) -> bool {
        self.rough.is_none() && self.coat.is_none() && self.sheen.is_none()
    }

    /// The configuration evaluated for `wo`: a thin sheet seen from behind is mirrored to the
    /// front, with its coat normal.
    #[inline]
    fn canonical(&self, wo: Vec3) -> (GltfTransmission, bool) {
        if self.thin && wo.z < 0.0 {
            let mut b = *self;
            if let Some(c) = &mut b.coat {
                *c = c.mirrored();
            }
            (b, true)
        } else {
            (*self, false)
        }
    }

    // ---- the interface (no layers) -------------------------------------------------------

    /// The interface's Fresnel reflectance for cos θ = `cos` (signed: < 0 seen from inside) and
    /// relative IOR `eta`, with the thin film mixed in (see the module notes).
    #[inline]
    fn fresnel(&self, cos: f32, eta: f32) -> Vec3 {
        let f = fresnel_dielectric(cos, eta);
        let Some(ir) = &self.iridescence else {
            return Vec3::splat(f);
        };
        if f >= 1.0 {
            return Vec3::ONE; // total internal reflection: nothing reaches the film
        }
        let c = cos.clamp(-1.0, 1.0);
        let cos_out = if c >= 0.0 {
            c
        } else {
            (1.0 - eta * eta * (1.0 - c * c)).max(0.0).sqrt()
        };
        let f0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
        ir.mix(Vec3::splat(f), cos_out, Vec3::splat(f0))
            .clamp(Vec3::ZERO, Vec3::ONE)
    }

    /// The continuous interface lobe f(wo, wi) for IOR `eta` (zero when smooth).
    fn core_eval(&self, eta: f32, wo: Vec3, wi: Vec3) -> Vec3 {
        let Some(a) = &self.rough else {
            return Vec3::ZERO;
        };
        if self.thin {
            return self.thin_eval(a, wo, wi).0;
        }
        let Some((wm, etap, is_reflect)) = half_vector(eta, wo, wi) else {
            return Vec3::ZERO;
        };
        let (o, i, m) = (a.to_aniso(wo), a.to_aniso(wi), a.to_aniso(wm));
        let dg = a.dist.d(m) * a.dist.g2(o, i);
        let f = self.fresnel(wo.dot(wm), eta);
        if is_reflect {
            f * (dg / (4.0 * wi.z * wo.z).abs())
        } else {
            // Walter et al. 2007 eq. 21, with the 1/η² radiance scaling.
            let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2) * wi.z * wo.z;
            let ft = dg * (wi.dot(wm) * wo.dot(wm) / denom).abs() / (etap * etap);
            self.tint * (Vec3::ONE - f) * ft
        }
    }

    /// The solid-angle density with which [`Self::core_sample`] returns `wi` for IOR `eta`.
    fn core_pdf(&self, eta: f32, wo: Vec3, wi: Vec3) -> f32 {
        let Some(a) = &self.rough else {
            return 0.0;
        };
        if self.thin {
            return self.thin_eval(a, wo, wi).1;
        }
        let Some((wm, etap, is_reflect)) = half_vector(eta, wo, wi) else {
            return 0.0;
        };
        let p_r = mean(self.fresnel(wo.dot(wm), eta));
        let dv = a.dist.d_visible(a.to_aniso(wo), a.to_aniso(wm));
        if is_reflect {
            dv / (4.0 * wo.dot(wm).abs()) * p_r
        } else {
            // Jacobian of the refraction half-vector map, Walter et al. 2007 eq. 17.
            let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
            dv * (wi.dot(wm).abs() / denom) * (1.0 - p_r)
        }
    }

    /// The rough thin sheet (as [`super::ThinDielectric`]): `wo` above; a transmitted `wi` is
    /// mirrored back through the sheet, where the reflection lobe gives its value, split by the
    /// slab's R' and T' at the microfacet. Returns (f, pdf).
    fn thin_eval(&self, a: &Anisotropy, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z <= 0.0 || wi.z == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let transmit = wi.z < 0.0;
        let wr = Vec3::new(wi.x, wi.y, wi.z.abs());
        let h = (wo + wr).normalize();
        let (woh, wrh) = (wo.dot(h), wr.dot(h));
        if !(woh > 0.0 && wrh > 0.0) {
            return (Vec3::ZERO, 0.0);
        }
        let (r, t) = slab(self.fresnel(woh, self.eta));
        let (o, i, m) = (a.to_aniso(wo), a.to_aniso(wr), a.to_aniso(h));
        let spec = a.dist.d(m) * a.dist.g2(o, i) / (4.0 * wo.z * wr.z);
        let lobe_pdf = a.dist.d_visible(o, m) / (4.0 * woh);
        let p_r = mean(r);
        if transmit {
            (self.tint * t * spec, (1.0 - p_r) * lobe_pdf)
        } else {
            (r * spec, p_r * lobe_pdf)
        }
    }

    /// A direction from the interface for IOR `eta` (`wo` above for a thin sheet). Smooth: the
    /// Dirac sample itself, (wi, f, discrete probability); rough: `None` for f and pdf, which
    /// the caller takes from the mixture.
    fn core_sample(
        &self,
        eta: f32,
        wo: Vec3,
        u_lobe: f32,
        u: Vec2,
    ) -> Option<(Vec3, Option<(Vec3, f32)>)> {
        if wo.z == 0.0 {
            return None;
        }
        let Some(a) = &self.rough else {
            return self.smooth_sample(eta, wo, u_lobe);
        };
        let m = a.to_local(a.dist.sample_visible(a.to_aniso(wo), u));
        if self.thin {
            let mut wr = reflect(wo, m);
            if wr.z <= 0.0 {
                return None;
            }
            let (r, _) = slab(self.fresnel(wo.dot(m), self.eta));
            if u_lobe >= mean(r) {
                wr.z = -wr.z;
            }
            return Some((wr, None));
        }
        let p_r = mean(self.fresnel(wo.dot(m), eta));
        let wi = if u_lobe < p_r {
            let wi = reflect(wo, m);
            (wo.z * wi.z > 0.0).then_some(wi)?
        } else {
            let (wi, _) = refract(wo, m, eta)?;
            (wo.z * wi.z < 0.0).then_some(wi)?
        };
        Some((wi, None))
    }

    /// The smooth interface's Dirac lobes: reflection with probability mean(F), else
    /// refraction (straight through for a thin sheet).
    fn smooth_sample(
        &self,
        eta: f32,
        wo: Vec3,
        u_lobe: f32,
    ) -> Option<(Vec3, Option<(Vec3, f32)>)> {
        let cos = wo.z.abs();
        let (r, t) = if self.thin {
            slab(self.fresnel(cos, self.eta))
        } else {
            let r = self.fresnel(wo.z, eta);
            (r, Vec3::ONE - r)
        };
        let p_r = mean(r);
        if u_lobe < p_r {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            return Some((wi, Some((r / cos, p_r))));
        }
        if self.thin {
            let wi = -wo;
            return Some((wi, Some((self.tint * t / cos, 1.0 - p_r))));
        }
        let (wi, etap) = refract(wo, Vec3::Z, eta)?;
        if wi.z == 0.0 {
            return None;
        }
        let f = self.tint * t / (wi.z.abs() * etap * etap);
        Some((wi, Some((f, 1.0 - p_r))))
    }

    /// The interface's continuous f over all channels (per-channel IOR with dispersion).
    fn interface_eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self.dispersion {
            None => self.core_eval(self.eta, wo, wi),
            Some(e) => Vec3::new(
                self.core_eval(e.x, wo, wi).x,
                self.core_eval(e.y, wo, wi).y,
                self.core_eval(e.z, wo, wi).z,
            ),
        }
    }

    /// The interface's continuous pdf: with dispersion, the mean over the channel choices.
    fn interface_pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self.dispersion {
            None => self.core_pdf(self.eta, wo, wi),
            Some(e) => {
                (self.core_pdf(e.x, wo, wi)
                    + self.core_pdf(e.y, wo, wi)
                    + self.core_pdf(e.z, wo, wi))
                    / 3.0
            }
        }
    }

    /// A direction from the interface; with dispersion a channel is picked with probability
    /// 1/3 first. Dirac samples carry (f, discrete probability) of the whole interface.
    fn interface_sample(
        &self,
        wo: Vec3,
        u_lobe: f32,
        u: Vec2,
    ) -> Option<(Vec3, Option<(Vec3, f32)>)> {
        let Some(e) = self.dispersion else {
            return self.core_sample(self.eta, wo, u_lobe, u);
        };
        if self.rough.is_none() {
            return self.smooth_sample_dispersive(e, wo, u_lobe);
        }
        let x = u_lobe * 3.0;
        let c = (x as usize).min(2);
        let u_lobe = (x - c as f32).clamp(0.0, 1.0 - f32::EPSILON);
        self.core_sample([e.x, e.y, e.z][c], wo, u_lobe, u)
    }

    /// The smooth dispersive interface ([`super::dielectric`]'s scheme with RGB Fresnel):
    /// reflection with probability mean_c R_c (value R_c in channel c, each at its own IOR),
    /// else channel c's refraction with probability (1 − mean R)/3, carrying only channel c.
    fn smooth_sample_dispersive(
        &self,
        e: Vec3,
        wo: Vec3,
        u_lobe: f32,
    ) -> Option<(Vec3, Option<(Vec3, f32)>)> {
        let r = Vec3::new(
            self.fresnel(wo.z, e.x).x,
            self.fresnel(wo.z, e.y).y,
            self.fresnel(wo.z, e.z).z,
        );
        let p_r = mean(r);
        let cos = wo.z.abs();
        if u_lobe < p_r {
            return Some((Vec3::new(-wo.x, -wo.y, wo.z), Some((r / cos, p_r))));
        }
        let x = ((u_lobe - p_r) / (1.0 - p_r)).clamp(0.0, 1.0) * 3.0;
        let c = (x as usize).min(2);
        let eta_c = [e.x, e.y, e.z][c];
        let t_c = 1.0 - r[c];
        let (wi, etap) = refract(wo, Vec3::Z, eta_c)?;
        if wi.z == 0.0 || !(t_c > 0.0) {
            return None;
        }
        let mut f = Vec3::ZERO;
        f[c] = self.tint[c] * t_c / (wi.z.abs() * etap * etap);
        Some((wi, Some((f, (1.0 - p_r) / 3.0))))
    }

    // ---- the layers ------------------------------------------------------------------------

    /// What the coat and the sheen leave of the interface's f(wo, wi): both reflect on the
    /// outside only, and light crossing them is weighed by its direction on the outside. A
    /// thick surface is crossed once per hit (entering: V outside, leaving: L outside, so light
    /// through a closed volume is weighed on entering *and* on leaving, at its two hits); a
    /// thin sheet carries the coat on both faces, so light through it crosses two coats at one
    /// hit: (1 − c·fr(V))·(1 − c·fr(L)), the back face's normal being −N_c (fr takes |cos|).
    #[inline]
    fn layer_scale(&self, wo: Vec3, wi: Vec3) -> f32 {
        let out = if wo.z > 0.0 {
            wo
        } else if wi.z > 0.0 {
            wi
        } else {
            return 1.0; // internal reflection
        };
        let mut s = 1.0;
        if let Some(c) = &self.coat {
            s *= 1.0 - c.layer_weight(out);
            if self.thin && wo.z * wi.z < 0.0 {
                s *= 1.0 - c.layer_weight(wi);
            }
        }
        if let Some(sh) = &self.sheen {
            s *= sh.base_scale(wo, wi);
        }
        s
    }

    /// Probabilities of the coat and the sheen lobes for `wo` (zero from inside).
    #[inline]
    fn layer_probabilities(&self, wo: Vec3) -> (f32, f32) {
        if wo.z <= 0.0 {
            return (0.0, 0.0);
        }
        (
            self.coat.as_ref().map_or(0.0, |c| coat_probability(c, wo)),
            self.sheen
                .as_ref()
                .map_or(0.0, |s| sheen_probability(s, wo)),
        )
    }

    /// True if the base's shading frame and the surface agree on the side of `wi` (always
    /// without a coat, whose geometric normal tells; see [`Clearcoat::agrees`]). Where they do
    /// not, only the coat scatters.
    #[inline]
    fn agrees(&self, wi: Vec3) -> bool {
        self.coat.as_ref().is_none_or(|c| c.agrees(wi))
    }

    /// The coat lobe, reflecting about its own normal on the outside: `wo` outside (above the
    /// base's plane) and `wi` outside the surface, also below the base's plane. Weighed by the
    /// coat's own cosine as the opaque material's coat is ([`coat_in_base_cosine`]).
    #[inline]
    fn coat_eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        match &self.coat {
            Some(c) if wo.z > 0.0 && c.is_outside(wi) => coat_in_base_cosine(c, wo, wi),
            _ => 0.0,
        }
    }

    fn eval_canonical(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z == 0.0 || wi.z == 0.0 {
            return Vec3::ZERO;
        }
        let coat = Vec3::splat(self.coat_eval(wo, wi));
        if !self.agrees(wi) {
            return coat;
        }
        let mut f = self.interface_eval(wo, wi) * self.layer_scale(wo, wi);
        if wo.z > 0.0
            && wi.z > 0.0
            && let Some(s) = &self.sheen
        {
            let w = self.coat.as_ref().map_or(1.0, |c| 1.0 - c.layer_weight(wo));
            f += s.eval(wo, wi) * w;
        }
        f + coat
    }

    fn pdf_canonical(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z == 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        let (p_coat, p_sheen) = self.layer_probabilities(wo);
        let mut p = (1.0 - p_coat) * (1.0 - p_sheen) * self.interface_pdf(wo, wi);
        if let Some(c) = &self.coat
            && wo.z > 0.0
            && c.is_outside(wi)
        {
            p += p_coat * c.pdf(wo, wi);
        }
        if wo.z > 0.0 && wi.z > 0.0 && self.sheen.is_some() {
            p += (1.0 - p_coat) * p_sheen * warp::uniform_cone_pdf(0.0);
        }
        p
    }

    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let (b, flip) = self.canonical(wo);
        if flip {
            b.eval_canonical(mirror_z(wo), mirror_z(wi))
        } else {
            b.eval_canonical(wo, wi)
        }
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (b, flip) = self.canonical(wo);
        if flip {
            b.pdf_canonical(mirror_z(wo), mirror_z(wi))
        } else {
            b.pdf_canonical(wo, wi)
        }
    }

    /// Picks the coat, the sheen (uniform over the upper hemisphere) or the interface with
    /// `u_lobe`, the rest of which is rescaled for the next choice.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let (b, flip) = self.canonical(wo);
        let wo = if flip { mirror_z(wo) } else { wo };
        let s = b.sample_canonical(wo, u_lobe, u)?;
        Some(if flip {
            BsdfSample {
                wi: mirror_z(s.wi),
                ..s
            }
        } else {
            s
        })
    }

    fn sample_canonical(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let (p_coat, p_sheen) = self.layer_probabilities(wo);
        let mut u_lobe = u_lobe;
        let mut wi = None;
        if let Some(c) = &self.coat
            && p_coat > 0.0
        {
            if u_lobe < p_coat {
                // The coat reflects only: a direction below the surface is no sample.
                wi = Some(c.sample(wo, u).filter(|wi| c.is_outside(*wi))?);
            } else {
                u_lobe = ((u_lobe - p_coat) / (1.0 - p_coat)).min(1.0 - f32::EPSILON);
            }
        }
        if wi.is_none() && p_sheen > 0.0 {
            if u_lobe < p_sheen {
                wi = Some(warp::uniform_cone(u, 0.0));
            } else {
                u_lobe = ((u_lobe - p_sheen) / (1.0 - p_sheen)).min(1.0 - f32::EPSILON);
            }
        }
        let wi = match wi {
            Some(wi) => wi,
            None => {
                let (wi, dirac) = self.interface_sample(wo, u_lobe, u)?;
                if let Some((f, p)) = dirac {
                    // A Dirac lobe: its discrete probability within the mixture, its value
                    // under the layers. None where the surface disagrees with the shading
                    // frame on its side (there only the coat scatters).
                    let pdf = (1.0 - p_coat) * (1.0 - p_sheen) * p;
                    if !(pdf > 0.0) || !self.agrees(wi) {
                        return None;
                    }
                    return Some(BsdfSample {
                        wi,
                        f: f * self.layer_scale(wo, wi),
                        pdf,
                        specular: true,
                        eta: self.relative_eta(wo, wi),
                    });
                }
                wi
            }
        };
        let pdf = self.pdf_canonical(wo, wi);
        BsdfSample::glossy(wi, pdf, self.relative_eta(wo, wi), || {
            self.eval_canonical(wo, wi)
        })
    }

    /// Per channel, the relative IOR crossed from `wo` to `wi`: as [`Self::relative_eta`], with
    /// each channel's own IOR under dispersion.
    #[inline]
    pub fn eta_crossed(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if self.relative_eta(wo, wi) == 1.0 {
            Vec3::ONE
        } else {
            super::eta_crossed(self.dispersion.unwrap_or(Vec3::splat(self.eta)), wo, wi)
        }
    }

    /// The relative IOR crossed from `wo` to `wi` (1 for reflection and for a thin sheet; the
    /// d-line IOR with dispersion, which Russian roulette uses only as a scale).
    #[inline]
    fn relative_eta(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.thin || wo.z * wi.z > 0.0 || !self.agrees(wi) {
            1.0
        } else if wo.z > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        }
    }
}
