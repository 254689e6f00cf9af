//! The KHR_materials_sheen layer: a Charlie microfiber lobe over the glTF base, layered by albedo
//! scaling as the extension defines it:
//!
//! ```text
//! f = sheen_color · D_charlie(h) · V_sheen(L, V) + f_base · scale,
//! scale = min(1 − max3(sheen_color) · E(N·V), 1 − max3(sheen_color) · E(N·L))
//! ```
//!
//! * D (Estevez & Kulla 2017, "Production Friendly Microfacet Sheen BRDF", eq. 2; the extension's
//!   "sheen distribution"): D(h) = (2 + 1/α) sin(θh)^(1/α) / (2π), α = sheenRoughness².
//!   It is normalised: ∫ D(h) cos θh dh = 1.
//! * V: the extension's recommended visibility, Estevez & Kulla's fitted Λ (their table 1,
//!   interpolated in (1 − α)²) with V = 1/((1 + Λ(N·V) + Λ(N·L)) · 4 N·V N·L), clamped to [0, 1]
//!   as the extension's sample implementation does.
//! * E(μ) = ∫ D·V cos θl dl, the lobe's directional albedo for a white sheen, is tabulated at
//!   start-up by quadrature ([`albedo`], 32 μ × 32 roughness values, bilinear lookup).
//!
//! Both D·V and the scaling are symmetric in L and V, so the layer is reciprocal when the base
//! is, and the albedo stays ≤ 1 when the base's does: c·E(μo) + (1 − c·E(μo))·a_base ≤ 1.
//! Sampling: uniform over the upper hemisphere. f·cos of the Charlie lobe is bounded (no 1/cos
//! growth: V carries 1/(N·L) that the cosine cancels) and spread over the whole hemisphere with
//! its peak at grazing angles, so uniform sampling keeps the weight bounded where cosine or
//! half-vector sampling of D would waste most samples below the horizon.

use crate::math::{PI, Vec3};

/// The smallest sheen α: below it sin^(1/α) underflows everywhere except exactly at grazing.
pub const MIN_SHEEN_ALPHA: f32 = 1e-3;

/// A sheen layer: colour (linear RGB, each ≤ 1) and glTF roughness in [0, 1], with the terms of
/// its lobe that depend on the roughness alone ([`CharlieFit`]), computed once per hit instead
/// of in every evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sheen {
    pub color: Vec3,
    pub roughness: f32,
    fit: CharlieFit,
}

#[inline]
fn alpha_of(roughness: f32) -> f32 {
    let r = roughness.clamp(0.0, 1.0);
    (r * r).max(MIN_SHEEN_ALPHA)
}

/// Charlie distribution D(h) for α, given cos θh (Estevez & Kulla 2017 eq. 2).
#[inline]
pub fn charlie_d(alpha: f32, cos_h: f32) -> f32 {
    let inv = 1.0 / alpha;
    let sin2 = (1.0 - cos_h * cos_h).max(0.0);
    (2.0 + inv) * sin2.powf(0.5 * inv) / (2.0 * PI)
}

/// Estevez & Kulla's fitted L(x) (table 1) at one α: its five coefficients, interpolated between
/// α = 0 and 1 by (1 − α)², and L(½), which Λ uses for every cosine ≥ ½. All depend on α
/// only; ToyCar's fabric evaluated them (a `powf` among them) twice per lobe evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
struct CharlieFit {
    alpha: f32,
    a: f32,
    b: f32,
    c: f32,
    d: f32,
    e: f32,
    l_half: f32,
}

impl CharlieFit {
    #[inline]
    fn new(alpha: f32) -> CharlieFit {
        let t = (1.0 - alpha) * (1.0 - alpha);
        let mix = |a1: f32, a0: f32| a1 + (a0 - a1) * t;
        let mut fit = CharlieFit {
            alpha,
            a: mix(21.5473, 25.3245),
            b: mix(3.82987, 3.32435),
            c: mix(0.19823, 0.16801),
            d: mix(-1.97760, -1.27393),
            e: mix(-4.32054, -4.85967),
            l_half: 0.0,
        };
        fit.l_half = fit.l(0.5);
        fit
    }

    /// L(x).
    #[inline]
    fn l(&self, x: f32) -> f32 {
        self.a / (1.0 + self.b * x.powf(self.c)) + self.d * x + self.e
    }

    /// Λ(cos θ) of the Charlie distribution (Estevez & Kulla 2017 eq. 3 with the fit).
    #[inline]
    fn lambda(&self, cos: f32) -> f32 {
        let c = cos.abs();
        if c < 0.5 {
            self.l(c).exp()
        } else {
            (2.0 * self.l_half - self.l(1.0 - c)).exp()
        }
    }

    /// The white sheen lobe D(h)·V(L, V), both directions above (cosines > 0). `lambda_o` is
    /// Λ(wo.z) when the caller has it ([`Sheen::lambda_of`]), else it is computed here.
    #[inline]
    fn lobe(&self, lambda_o: Option<f32>, wo: Vec3, wi: Vec3) -> f32 {
        let (no, ni) = (wo.z, wi.z);
        if no <= 0.0 || ni <= 0.0 {
            return 0.0;
        }
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return 0.0;
        }
        let h = h.normalize();
        let lambda_o = lambda_o.unwrap_or_else(|| self.lambda(no));
        let v = 1.0 / ((1.0 + lambda_o + self.lambda(ni)) * 4.0 * no * ni);
        charlie_d(self.alpha, h.z) * v.clamp(0.0, 1.0)
    }
}

/// The white sheen lobe D(h)·V(L, V) for α, both directions above (cosines > 0).
#[inline]
pub fn lobe(alpha: f32, wo: Vec3, wi: Vec3) -> f32 {
    CharlieFit::new(alpha).lobe(None, wo, wi)
}

const TABLE_MU: usize = 32;
const TABLE_R: usize = 32;

/// E(μ, r) by a midpoint rule over the hemisphere of incident directions: 128 cos θ × 64 φ on
/// [0, π] (the lobe is symmetric about the plane of incidence, so φ ∈ [π, 2π] mirrors it).
#[cfg(test)]
fn albedo_quadrature(mu: f32, roughness: f32) -> f32 {
    let alpha = alpha_of(roughness);
    let mu = mu.clamp(1e-4, 1.0);
    let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
    let (nt, np) = (128usize, 64usize);
    let mut sum = 0.0f64;
    for a in 0..nt {
        let c = (a as f32 + 0.5) / nt as f32;
        let s = (1.0 - c * c).sqrt();
        for b in 0..np {
            let phi = PI * (b as f32 + 0.5) / np as f32;
            let wi = Vec3::new(s * phi.cos(), s * phi.sin(), c);
            sum += (lobe(alpha, wo, wi) * c) as f64;
        }
    }
    (sum * 2.0 * PI as f64 / (nt * np) as f64) as f32
}

/// The quadrature at grid point (m, k): μ = m/31, r = k/31, clamped to [0, 1].
#[cfg(test)]
fn table_entry(m: usize, k: usize) -> f32 {
    let mu = m as f32 / (TABLE_MU - 1) as f32;
    let rough = k as f32 / (TABLE_R - 1) as f32;
    albedo_quadrature(mu, rough).clamp(0.0, 1.0)
}

/// [`table_entry`] for every grid point, row by row in r, stored in `sheen_table.rs`.
fn table() -> &'static [f32] {
    &super::sheen_table::SHEEN_ALBEDO
}

/// E(μ) of the white sheen lobe of glTF roughness `roughness`: bilinear in the table.
pub fn albedo(mu: f32, roughness: f32) -> f32 {
    let t = table();
    let x = mu.clamp(0.0, 1.0) * (TABLE_MU - 1) as f32;
    let y = roughness.clamp(0.0, 1.0) * (TABLE_R - 1) as f32;
    // Through i32: x and y are in [0, 31] (or NaN, which both conversions send to 0), where it
    // is the same truncation as `as usize`, in one instruction instead of the unsigned 64-bit
    // conversion's range checks.
    let (x0, y0) = (
        (x as i32 as usize).min(TABLE_MU - 2),
        (y as i32 as usize).min(TABLE_R - 2),
    );
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let at = |i: usize, j: usize| t[j * TABLE_MU + i];
    let a = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
    let b = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
    a * (1.0 - fy) + b * fy
}

impl Sheen {
    /// `None` when the colour is black (the extension's "no sheen").
    pub fn new(color: Vec3, roughness: f32) -> Option<Sheen> {
        let color = color.clamp(Vec3::ZERO, Vec3::ONE);
        let roughness = roughness.clamp(0.0, 1.0);
        (color.max_element() > 0.0).then(|| Sheen {
            color,
            roughness,
            fit: CharlieFit::new(alpha_of(roughness)),
        })
    }

    /// The sheen lobe's value f_sheen(wo, wi) (both above).
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_with(None, wo, wi)
    }

    /// [`Sheen::eval`] given Λ(wo.z) ([`Sheen::lambda_of`]) if the caller kept it for `wo`.
    #[inline]
    pub fn eval_with(&self, lambda_o: Option<f32>, wo: Vec3, wi: Vec3) -> Vec3 {
        self.color * self.fit.lobe(lambda_o, wo, wi)
    }

    /// What the sheen leaves of the base: min(1 − c·E(N·V), 1 − c·E(N·L)).
    #[inline]
    pub fn base_scale(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.base_scale_with(None, wo, wi)
    }

    /// [`Sheen::base_scale`] given E(N·V) ([`Sheen::albedo_of`]) if the caller kept it for `wo`.
    #[inline]
    pub fn base_scale_with(&self, e_o: Option<f32>, wo: Vec3, wi: Vec3) -> f32 {
        let c = self.color.max_element();
        let e_o = e_o.unwrap_or_else(|| self.albedo_of(wo));
        let e = e_o.max(albedo(wi.z.abs(), self.roughness));
        (1.0 - c * e).max(0.0)
    }

    /// The share of the base the sheen takes from `wo` (for choosing the lobe): c·E(N·V).
    #[inline]
    pub fn weight(&self, wo: Vec3) -> f32 {
        self.weight_with(None, wo)
    }

    /// [`Sheen::weight`] given E(N·V) if the caller kept it for `wo`.
    #[inline]
    pub fn weight_with(&self, e_o: Option<f32>, wo: Vec3) -> f32 {
        self.color.max_element() * e_o.unwrap_or_else(|| self.albedo_of(wo))
    }

    /// E(N·V) = E(|wo.z|): the one albedo-table lookup of `wo`.
    #[inline]
    pub fn albedo_of(&self, wo: Vec3) -> f32 {
        albedo(wo.z.abs(), self.roughness)
    }

    /// Λ(wo.z) of the lobe's visibility term (its value for `wo` above the surface).
    #[inline]
    pub fn lambda_of(&self, wo: Vec3) -> f32 {
        self.fit.lambda(wo.z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn charlie_is_normalised() {
        // ∫ D(h) cos θh dω_h = 1 for every α (midpoint rule in cos θh).
        for alpha in [0.05f32, 0.25, 1.0] {
            let n = 20_000;
            let mut s = 0.0f64;
            for i in 0..n {
                let c = (i as f32 + 0.5) / n as f32;
                s += (charlie_d(alpha, c) * c) as f64;
            }
            let integral = s * 2.0 * PI as f64 / n as f64;
            assert!(
                (integral - 1.0).abs() < 2e-3,
                "α {alpha}: ∫D cos = {integral}"
            );
        }
    }

    #[test]
    fn albedo_table_is_bounded_and_matches_quadrature() {
        for &(mu, r) in &[(0.1f32, 0.3f32), (0.5, 0.5), (0.9, 1.0), (0.33, 0.77)] {
            let e = albedo(mu, r);
            let q = albedo_quadrature(mu, r);
            assert!((0.0..=1.0).contains(&e), "E({mu}, {r}) = {e}");
            assert!(
                (e - q).abs() < 0.02,
                "table {e} vs quadrature {q} at μ {mu} r {r}"
            );
        }
        // A rough sheen reflects more than a smooth one seen head-on.
        assert!(albedo(1.0, 1.0) > albedo(1.0, 0.2));
    }

    #[test]
    fn lobe_is_reciprocal() {
        let a = Vec3::new(0.3, 0.2, 0.9).normalize();
        let b = Vec3::new(-0.6, 0.1, 0.4).normalize();
        for alpha in [0.04f32, 0.3, 1.0] {
            let (x, y) = (lobe(alpha, a, b), lobe(alpha, b, a));
            assert!((x - y).abs() <= 1e-6 * x.max(y), "{x} vs {y}");
        }
    }

    /// The stored table is the quadrature, bit for bit, at entries spread over both axes and
    /// at the four corners (a regenerated or hand-edited table that drifts fails).
    #[test]
    fn the_stored_table_is_the_quadrature() {
        let t = table();
        assert_eq!(t.len(), TABLE_MU * TABLE_R);
        let mut idx: Vec<usize> = (0..t.len()).step_by(37).collect();
        idx.extend([0, TABLE_MU - 1, t.len() - TABLE_MU, t.len() - 1]);
        for i in idx {
            let (m, k) = (i % TABLE_MU, i / TABLE_MU);
            assert_eq!(
                t[i].to_bits(),
                table_entry(m, k).to_bits(),
                "entry μ {m}/31 r {k}/31: stored {} vs quadrature {}",
                t[i],
                table_entry(m, k)
            );
        }
    }

    /// Writes the table's rows for `sheen_table.rs` (`-- --ignored --nocapture`).
    #[test]
    #[ignore]
    fn print_sheen_table() {
        for k in 0..TABLE_R {
            let row: Vec<String> = (0..TABLE_MU)
                .map(|m| format!("{:?}", table_entry(m, k)))
                .collect();
            println!("    {},", row.join(", "));
        }
    }
}
