//! The hair scattering model of Chiang, Bitterli, Tappan and Burley 2016 ("A Practical and
//! Controllable Hair and Fur Model for Production Path Tracing", CGF 35(2)), as pbrt-v4's
//! `HairBxDF` specifies it (PBRT-v4 §9.9 of the online edition): the fibre is a dielectric
//! cylinder of index η filled with an absorbing medium σ_a; light leaves it after p internal
//! paths — R (p = 0), TT (1), TRT (2) and one residual lobe for every longer path (p ≥ 3) — each
//! the product of a longitudinal lobe M_p (d'Eon et al. 2011's von Mises–Fisher–like lobe of
//! variance v from the longitudinal roughness β_m), an attenuation A_p (Fresnel and σ_a along
//! the internal path) and an azimuthal lobe N_p (a trimmed logistic of scale s from the azimuthal
//! roughness β_n around the azimuth a smooth cylinder would send the light to), with the cuticle
//! scales tilting the longitudinal lobes by 2α, −α and −4α (paper §4.4).
//!
//! The local frame is the hair's: +x along the fibre (the curve's ∂p/∂u), +z the surface normal
//! the integrator frames around, so sin θ = w.x and φ = atan2(w.z, w.y). `h` ∈ [−1, 1] is where
//! across the fibre's width the ray struck it (the curve's v, h = 2v − 1). f·|cos θ_z| is the
//! model's scattering function, so `eval` divides by |w_i.z| (pbrt-v4 `HairBxDF::f`); the
//! integrator multiplies it back. Nothing refracts across the surface the integrator sees (the
//! fibre is entered and left within the BSDF), so both transport modes share `eval`.

use super::BsdfSample;
use crate::math::{PI, Vec2, Vec3};

/// Number of explicit lobes before the residual one (R, TT, TRT), pbrt-v4's `pMax`.
const P_MAX: usize = 3;

/// The hair BSDF at one hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hair {
    /// Offset across the fibre, in [−1, 1].
    pub h: f32,
    /// Index of refraction of the fibre's interior (1.55 for human hair).
    pub eta: f32,
    /// Absorption coefficient of the interior, per unit of the fibre's diameter.
    pub sigma_a: Vec3,
    /// Longitudinal variance of each lobe (paper eq. 7: v_0 from β_m; TT a quarter, TRT and the
    /// residual four times).
    v: [f32; P_MAX + 1],
    /// Logistic scale of the azimuthal lobes (paper eq. 8).
    s: f32,
    /// sin and cos of 2^k α, k = 0, 1, 2: the scale tilts of TT (α), R (2α) and TRT (4α).
    sin2k_alpha: [f32; P_MAX],
    cos2k_alpha: [f32; P_MAX],
}

impl Hair {
    /// The BSDF with longitudinal roughness `beta_m`, azimuthal roughness `beta_n` (both in
    /// [0, 1]) and scale angle `alpha_deg` (degrees). Inputs are clamped to their ranges.
    pub fn new(h: f32, eta: f32, sigma_a: Vec3, beta_m: f32, beta_n: f32, alpha_deg: f32) -> Hair {
        let h = if h.is_finite() {
            h.clamp(-1.0, 1.0)
        } else {
            0.0
        };
        let beta_m = beta_m.clamp(0.0, 1.0);
        let beta_n = beta_n.clamp(0.0, 1.0);
        // Paper eq. 7 (variance as a polynomial fit of β_m); a floor keeps 1/v finite.
        let sq = |x: f32| x * x;
        let v0 = sq(0.726 * beta_m + 0.812 * sq(beta_m) + 3.7 * beta_m.powi(20)).max(1e-4);
        let v = [v0, 0.25 * v0, 4.0 * v0, 4.0 * v0];
        // Paper eq. 8: the logistic scale from β_n, √(π/8) times a polynomial fit.
        let s = (0.626_657_07 * (0.265 * beta_n + 1.194 * sq(beta_n) + 5.372 * beta_n.powi(22)))
            .max(1e-4);
        let mut sin2k_alpha = [0.0; P_MAX];
        let mut cos2k_alpha = [1.0; P_MAX];
        sin2k_alpha[0] = alpha_deg.to_radians().sin();
        cos2k_alpha[0] = (1.0 - sq(sin2k_alpha[0])).max(0.0).sqrt();
        for i in 1..P_MAX {
            // Double-angle formulas: 2^k α from 2^(k−1) α.
            sin2k_alpha[i] = 2.0 * cos2k_alpha[i - 1] * sin2k_alpha[i - 1];
            cos2k_alpha[i] = sq(cos2k_alpha[i - 1]) - sq(sin2k_alpha[i - 1]);
        }
        Hair {
            h,
            eta: if eta.is_finite() && eta > 0.0 {
                eta
            } else {
                1.55
            },
            sigma_a: sigma_a.max(Vec3::ZERO),
            v,
            s,
            sin2k_alpha,
            cos2k_alpha,
        }
    }

    /// σ_a of a fibre with eumelanin and pheomelanin concentrations `ce`, `cp` (paper §4.2,
    /// the per-concentration absorption of d'Eon et al. 2011 in RGB, as pbrt-v4 tabulates it).
    pub fn sigma_a_from_concentration(ce: f32, cp: f32) -> Vec3 {
        Vec3::new(0.419, 0.697, 1.37) * ce + Vec3::new(0.187, 0.4, 1.05) * cp
    }

    /// σ_a giving a multiply-scattered colour `c` at azimuthal roughness `beta_n` (paper §4.2,
    /// eq. 9: the inverse of a fit of the colour of a volume of fibres).
    pub fn sigma_a_from_reflectance(c: Vec3, beta_n: f32) -> Vec3 {
        let b = beta_n;
        let d = 5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3)
            + 5.574 * b.powi(4)
            + 0.245 * b.powi(5);
        let one = |x: f32| {
            let l = x.clamp(1e-4, 1.0).ln() / d;
            l * l
        };
        Vec3::new(one(c.x), one(c.y), one(c.z))
    }

    /// sin and cos of θ_o for lobe `p`, tilted by its scale angle (paper §4.4: R by −2α, TT by
    /// α, TRT by 4α; the residual is not tilted). cos is made non-negative (a tilt past the pole).
    #[inline]
    fn tilted(&self, p: usize, sin_o: f32, cos_o: f32) -> (f32, f32) {
        let (s, c) = match p {
            0 => (
                sin_o * self.cos2k_alpha[1] - cos_o * self.sin2k_alpha[1],
                cos_o * self.cos2k_alpha[1] + sin_o * self.sin2k_alpha[1],
            ),
            1 => (
                sin_o * self.cos2k_alpha[0] + cos_o * self.sin2k_alpha[0],
                cos_o * self.cos2k_alpha[0] - sin_o * self.sin2k_alpha[0],
            ),
            2 => (
                sin_o * self.cos2k_alpha[2] + cos_o * self.sin2k_alpha[2],
                cos_o * self.cos2k_alpha[2] - sin_o * self.sin2k_alpha[2],
            ),
            _ => (sin_o, cos_o),
        };
        (s, c.abs())
    }

    /// γ_t, the azimuthal angle of the refracted ray inside the fibre, and the attenuation of
    /// each lobe for the outgoing direction with sin θ_o, cos θ_o.
    #[inline]
    fn attenuation(&self, sin_o: f32, cos_o: f32) -> (f32, [Vec3; P_MAX + 1]) {
        let sin_t = sin_o / self.eta;
        let cos_t = (1.0 - sin_t * sin_t).max(0.0).sqrt();
        // The modified index η' of the projection onto the normal plane (Bravais, paper §4.1).
        let etap = (self.eta * self.eta - sin_o * sin_o).max(0.0).sqrt() / cos_o;
        let sin_gt = self.h / etap;
        let cos_gt = (1.0 - sin_gt * sin_gt).max(0.0).sqrt();
        let gamma_t = sin_gt.clamp(-1.0, 1.0).asin();
        // Transmittance of one chord through the fibre (length 2 cos γ_t / cos θ_t diameters).
        let l = 2.0 * cos_gt / cos_t;
        let t = Vec3::new(
            (-self.sigma_a.x * l).exp(),
            (-self.sigma_a.y * l).exp(),
            (-self.sigma_a.z * l).exp(),
        );
        let cos_go = (1.0 - self.h * self.h).max(0.0).sqrt();
        let f = crate::material::microfacet::fresnel_dielectric(cos_o * cos_go, self.eta);
        let mut a = [Vec3::ZERO; P_MAX + 1];
        a[0] = Vec3::splat(f);
        a[1] = t * ((1.0 - f) * (1.0 - f));
        for p in 2..P_MAX {
            a[p] = a[p - 1] * t * f;
        }
        // Every longer path: the geometric series of one more internal reflection each.
        let tf = t * f;
        let denom = Vec3::ONE - tf;
        a[P_MAX] = Vec3::new(
            if denom.x > 0.0 {
                a[P_MAX - 1].x * tf.x / denom.x
            } else {
                0.0
            },
            if denom.y > 0.0 {
                a[P_MAX - 1].y * tf.y / denom.y
            } else {
                0.0
            },
            if denom.z > 0.0 {
                a[P_MAX - 1].z * tf.z / denom.z
            } else {
                0.0
            },
        );
        (gamma_t, a)
    }

    /// The probability of sampling each lobe: its share of the mean attenuation.
    #[inline]
    fn lobe_pdfs(a: &[Vec3; P_MAX + 1]) -> [f32; P_MAX + 1] {
        let mean = |v: Vec3| (v.x + v.y + v.z) / 3.0;
        let sum: f32 = a.iter().map(|&x| mean(x)).sum();
        let mut out = [0.0; P_MAX + 1];
        if sum > 0.0 {
            for (o, &x) in out.iter_mut().zip(a) {
                *o = mean(x) / sum;
            }
        }
        out
    }

    /// f(wo, wi), without the cosine (the model's value divided by |wi.z|).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let sin_o = wo.x.clamp(-1.0, 1.0);
        let cos_o = (1.0 - sin_o * sin_o).max(0.0).sqrt();
        let sin_i = wi.x.clamp(-1.0, 1.0);
        let cos_i = (1.0 - sin_i * sin_i).max(0.0).sqrt();
        let phi = wi.z.atan2(wi.y) - wo.z.atan2(wo.y);
        let gamma_o = self.h.clamp(-1.0, 1.0).asin();
        let (gamma_t, a) = self.attenuation(sin_o, cos_o);
        let mut sum = Vec3::ZERO;
        for (p, &ap) in a.iter().enumerate().take(P_MAX) {
            let (sp, cp) = self.tilted(p, sin_o, cos_o);
            let m = mp(cos_i, cp, sin_i, sp, self.v[p]);
            sum += ap * (m * np(phi, p, self.s, gamma_o, gamma_t));
        }
        sum += a[P_MAX] * (mp(cos_i, cos_o, sin_i, sin_o, self.v[P_MAX]) / (2.0 * PI));
        let c = wi.z.abs();
        let f = if c > 0.0 { sum / c } else { sum };
        if f.is_finite() { f } else { Vec3::ZERO }
    }

    /// Solid-angle pdf with which `sample` returns `wi`.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let sin_o = wo.x.clamp(-1.0, 1.0);
        let cos_o = (1.0 - sin_o * sin_o).max(0.0).sqrt();
        let sin_i = wi.x.clamp(-1.0, 1.0);
        let cos_i = (1.0 - sin_i * sin_i).max(0.0).sqrt();
        let phi = wi.z.atan2(wi.y) - wo.z.atan2(wo.y);
        self.pdf_angles(sin_o, cos_o, sin_i, cos_i, phi)
    }

    fn pdf_angles(&self, sin_o: f32, cos_o: f32, sin_i: f32, cos_i: f32, phi: f32) -> f32 {
        let gamma_o = self.h.clamp(-1.0, 1.0).asin();
        let (gamma_t, a) = self.attenuation(sin_o, cos_o);
        let w = Self::lobe_pdfs(&a);
        let mut pdf = 0.0;
        for (p, &wp) in w.iter().enumerate().take(P_MAX) {
            let (sp, cp) = self.tilted(p, sin_o, cos_o);
            pdf += wp * mp(cos_i, cp, sin_i, sp, self.v[p]) * np(phi, p, self.s, gamma_o, gamma_t);
        }
        pdf += w[P_MAX] * mp(cos_i, cos_o, sin_i, sin_o, self.v[P_MAX]) / (2.0 * PI);
        if pdf.is_finite() { pdf } else { 0.0 }
    }

    /// Samples a lobe with `u_lobe` (in proportion to its attenuation), then θ_i from its
    /// longitudinal lobe and φ_i from its azimuthal one (paper §4.3; pbrt-v4
    /// `HairBxDF::Sample_f`). The pdf returned is the mixture's over all lobes.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let sin_o = wo.x.clamp(-1.0, 1.0);
        let cos_o = (1.0 - sin_o * sin_o).max(0.0).sqrt();
        let gamma_o = self.h.clamp(-1.0, 1.0).asin();
        let (gamma_t, a) = self.attenuation(sin_o, cos_o);
        let w = Self::lobe_pdfs(&a);
        // Choose the lobe and rescale u_lobe to [0, 1) within it for the azimuth.
        let mut p = P_MAX;
        let mut lo = 0.0;
        for (k, &wk) in w.iter().enumerate() {
            if u_lobe < lo + wk || k == P_MAX {
                p = k;
                break;
            }
            lo += wk;
        }
        if !(w[p] > 0.0) {
            return None;
        }
        let uc = ((u_lobe - lo) / w[p]).clamp(0.0, 1.0 - f32::EPSILON);
        // θ_i from M_p (d'Eon et al. 2011's sampling of the spherical Gaussian about −θ_o').
        let (sp, cp) = self.tilted(p, sin_o, cos_o);
        let v = self.v[p];
        let cos_theta = 1.0 + v * (u.x.max(1e-5) + (1.0 - u.x) * (-2.0 / v).exp()).ln();
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let cos_phi = (2.0 * PI * u.y).cos();
        let sin_i = (-cos_theta * sp + sin_theta * cos_phi * cp).clamp(-1.0, 1.0);
        let cos_i = (1.0 - sin_i * sin_i).max(0.0).sqrt();
        // Δφ from N_p: the smooth cylinder's exit azimuth plus a trimmed logistic.
        let dphi = if p < P_MAX {
            phi_p(p, gamma_o, gamma_t) + sample_trimmed_logistic(uc, self.s, -PI, PI)
        } else {
            2.0 * PI * uc
        };
        let phi_i = wo.z.atan2(wo.y) + dphi;
        let wi = Vec3::new(sin_i, cos_i * phi_i.cos(), cos_i * phi_i.sin());
        let pdf = self.pdf_angles(sin_o, cos_o, sin_i, cos_i, dphi);
        BsdfSample::glossy(wi, pdf, 1.0, || self.eval(wo, wi))
    }

    /// The fraction of light the fibre returns: the sum of the lobes' attenuations at normal
    /// incidence, for the raycast views and heuristics.
    pub fn albedo(&self) -> Vec3 {
        let (_, a) = self.attenuation(0.0, 1.0);
        a.iter().fold(Vec3::ZERO, |s, &x| s + x).min(Vec3::ONE)
    }
}

/// The longitudinal lobe M_p (d'Eon et al. 2011, paper eq. 6): a density over θ_i with respect
/// to cos θ_i dθ_i. For small variances the form through log I_0 avoids the overflow of I_0 and
/// sinh (pbrt-v4 `HairBxDF::Mp`).
#[inline]
fn mp(cos_i: f32, cos_o: f32, sin_i: f32, sin_o: f32, v: f32) -> f32 {
    let a = cos_i * cos_o / v;
    let b = sin_i * sin_o / v;
    if v <= 0.1 {
        (log_i0(a) - b - 1.0 / v + std::f32::consts::LN_2 + (1.0 / (2.0 * v)).ln()).exp()
    } else {
        (-b).exp() * i0(a) / ((1.0 / v).sinh() * 2.0 * v)
    }
}

/// The modified Bessel function of the first kind of order zero, by its power series
/// Σ (x²/4)^k / (k!)², ten terms (enough for the arguments a v > 0.1 lobe produces).
#[inline]
fn i0(x: f32) -> f32 {
    let x2 = x * x / 4.0;
    let mut term = 1.0f32;
    let mut sum = 1.0f32;
    for k in 1..=10 {
        term *= x2 / (k * k) as f32;
        sum += term;
    }
    sum
}

/// ln I_0(x): the series for small x, the asymptotic expansion
/// I_0(x) ≈ e^x / √(2πx) · (1 + 1/(8x)) above 12.
#[inline]
fn log_i0(x: f32) -> f32 {
    if x > 12.0 {
        x + 0.5 * (-(2.0 * PI).ln() + (1.0 / x).ln() + 1.0 / (8.0 * x))
    } else {
        i0(x).ln()
    }
}

/// The azimuth a smooth cylinder sends lobe p to (paper eq. 3): Φ(p, h) = 2pγ_t − 2γ_o + pπ.
#[inline]
fn phi_p(p: usize, gamma_o: f32, gamma_t: f32) -> f32 {
    let p = p as f32;
    2.0 * p * gamma_t - 2.0 * gamma_o + p * PI
}

/// The azimuthal lobe N_p: a logistic of scale `s` about Φ(p, h), trimmed to (−π, π].
#[inline]
fn np(phi: f32, p: usize, s: f32, gamma_o: f32, gamma_t: f32) -> f32 {
    let mut d = phi - phi_p(p, gamma_o, gamma_t);
    // Into [−π, π]: the lobe lives on the circle.
    d = (d + PI).rem_euclid(2.0 * PI) - PI;
    trimmed_logistic(d, s, -PI, PI)
}

#[inline]
fn logistic(x: f32, s: f32) -> f32 {
    let e = (-x.abs() / s).exp();
    e / (s * (1.0 + e) * (1.0 + e))
}

#[inline]
fn logistic_cdf(x: f32, s: f32) -> f32 {
    1.0 / (1.0 + (-x / s).exp())
}

#[inline]
fn trimmed_logistic(x: f32, s: f32, a: f32, b: f32) -> f32 {
    logistic(x, s) / (logistic_cdf(b, s) - logistic_cdf(a, s))
}

/// Inverts the trimmed logistic's cdf at `u`.
#[inline]
fn sample_trimmed_logistic(u: f32, s: f32, a: f32, b: f32) -> f32 {
    let ca = logistic_cdf(a, s);
    let k = logistic_cdf(b, s) - ca;
    let x = -s * (1.0 / (u * k + ca) - 1.0).ln();
    if x.is_finite() { x.clamp(a, b) } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn uniform_sphere(r: &mut Pcg32) -> Vec3 {
        let z = 1.0 - 2.0 * r.next_f32();
        let s = (1.0 - z * z).max(0.0).sqrt();
        let p = 2.0 * PI * r.next_f32();
        Vec3::new(s * p.cos(), s * p.sin(), z)
    }

    /// The logistic lobe integrates to 1 over (−π, π] and its sampler inverts its cdf.
    #[test]
    fn trimmed_logistic_is_normalised_and_inverted() {
        for s in [0.05f32, 0.3, 1.0, 3.0] {
            let n = 20000;
            let mut sum = 0.0f64;
            for k in 0..n {
                let x = -PI + 2.0 * PI * (k as f32 + 0.5) / n as f32;
                sum += trimmed_logistic(x, s, -PI, PI) as f64 * (2.0 * PI as f64) / n as f64;
            }
            assert!((sum - 1.0).abs() < 1e-3, "s {s}: {sum}");
            for u in [0.1f32, 0.5, 0.9] {
                let x = sample_trimmed_logistic(u, s, -PI, PI);
                let c = (logistic_cdf(x, s) - logistic_cdf(-PI, s))
                    / (logistic_cdf(PI, s) - logistic_cdf(-PI, s));
                assert!((c - u).abs() < 1e-4, "s {s} u {u}: {c}");
            }
        }
    }

    /// White furnace (pbrt-v4's hair tests): without absorption the fibre scatters all light,
    /// so ∫ f |cos θ| dω = 1 for every outgoing direction, offset and roughness. Fails if a lobe
    /// is dropped, double counted, or a normalisation is wrong.
    #[test]
    fn white_furnace_without_absorption() {
        let mut r = Pcg32::new(7, 11);
        for &beta_m in &[0.2f32, 0.4, 0.7, 1.0] {
            for &beta_n in &[0.2f32, 0.5, 1.0] {
                let wo = uniform_sphere(&mut r);
                let h = -1.0 + 2.0 * r.next_f32();
                let hair = Hair::new(h, 1.55, Vec3::ZERO, beta_m, beta_n, 2.0);
                let n = 200_000;
                let mut sum = Vec3::ZERO;
                for _ in 0..n {
                    let wi = uniform_sphere(&mut r);
                    sum += hair.eval(wo, wi) * wi.z.abs();
                }
                let e = sum * (4.0 * PI / n as f32);
                assert!(
                    (e - Vec3::ONE).abs().max_element() < 0.05,
                    "β_m {beta_m} β_n {beta_n} h {h}: {e:?}"
                );
            }
        }
    }

    /// Importance-sampled furnace: the mean of the sampling weight f·|cos|/pdf is 1 without
    /// absorption, and each weight is close to 1 (the sampler follows f closely: pbrt-v4's
    /// `SamplingWeights` test), and the returned pdf and f are `pdf` and `eval`.
    #[test]
    fn sampling_weights_are_near_one() {
        let mut r = Pcg32::new(3, 5);
        for &beta_m in &[0.2f32, 0.5, 1.0] {
            for &beta_n in &[0.2f32, 0.6, 1.0] {
                let h = -1.0 + 2.0 * r.next_f32();
                let hair = Hair::new(h, 1.55, Vec3::ZERO, beta_m, beta_n, 2.0);
                let wo = uniform_sphere(&mut r);
                let n = 20000;
                let mut sum = 0.0f64;
                for _ in 0..n {
                    let u = Vec2::new(r.next_f32(), r.next_f32());
                    let Some(s) = hair.sample(wo, r.next_f32(), u) else {
                        continue;
                    };
                    let w = s.f.y * s.wi.z.abs() / s.pdf;
                    assert!(
                        (w - 1.0).abs() < 0.01,
                        "β_m {beta_m} β_n {beta_n} weight {w}"
                    );
                    let pdf = hair.pdf(wo, s.wi);
                    assert!(
                        (pdf - s.pdf).abs() <= 1e-3 * pdf.max(s.pdf),
                        "{pdf} {}",
                        s.pdf
                    );
                    let f = hair.eval(wo, s.wi);
                    assert!((f - s.f).abs().max_element() <= 1e-3 * f.max_element());
                    sum += w as f64;
                }
                assert!((sum / n as f64 - 1.0).abs() < 0.02, "{}", sum / n as f64);
            }
        }
    }

    /// The reflectance inversion gives absorption that darkens monotonically as the colour
    /// darkens, and none for white; concentrations add linearly.
    #[test]
    fn absorption_inputs() {
        assert_eq!(Hair::sigma_a_from_reflectance(Vec3::ONE, 0.3), Vec3::ZERO);
        let a = Hair::sigma_a_from_reflectance(Vec3::splat(0.5), 0.3);
        let b = Hair::sigma_a_from_reflectance(Vec3::splat(0.2), 0.3);
        assert!(b.x > a.x && a.x > 0.0);
        let c = Hair::sigma_a_from_concentration(1.3, 0.0);
        assert!((c - Vec3::new(0.5447, 0.9061, 1.781)).abs().max_element() < 1e-3);
    }
}
