//! The Henyey–Greenstein phase function (Henyey and Greenstein 1941), in the direction-of-travel
//! convention: `cos θ` is the cosine between the direction the light travelled in (`d_in`) and the
//! direction it leaves in (`d_out`), so `g > 0` scatters forward, `g < 0` backward, `g = 0` is
//! isotropic.
//!
//!   p(cos θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2})
//!
//! Sampling inverts the CDF of cos θ in closed form:
//!   cos θ = (1 + g² − ((1 − g²) / (1 − g + 2g u))²) / (2g),  cos θ = 1 − 2u for g → 0,
//! and φ is uniform, so the sample's pdf is p itself (the phase function is its own pdf).

use crate::math::{Frame, PI, Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HenyeyGreenstein {
    pub g: f32,
}

/// A sampled scattering direction; `pdf` equals the phase function value.
#[derive(Clone, Copy, Debug)]
pub struct PhaseSample {
    pub d_out: Vec3,
    pub pdf: f32,
}

impl HenyeyGreenstein {
    /// `g` is clamped to (−0.99, 0.99): at |g| → 1 the function becomes a Dirac delta, which the
    /// float formulas cannot represent.
    pub fn new(g: f32) -> HenyeyGreenstein {
        HenyeyGreenstein {
            g: if g.is_finite() {
                g.clamp(-0.99, 0.99)
            } else {
                0.0
            },
        }
    }

    /// Phase function value for the cosine between the incoming travel direction and the outgoing
    /// one.
    #[inline]
    pub fn p_cos(&self, cos_theta: f32) -> f32 {
        let g = self.g;
        let denom = (1.0 + g * g - 2.0 * g * cos_theta).max(1e-12);
        (1.0 - g * g) / (4.0 * PI * denom * denom.sqrt())
    }

    /// Phase function value for unit travel directions `d_in` (arriving) and `d_out` (leaving).
    #[inline]
    pub fn eval(&self, d_in: Vec3, d_out: Vec3) -> f32 {
        self.p_cos(d_in.dot(d_out))
    }

    /// Samples `d_out` for light travelling along unit `d_in`.
    #[inline]
    pub fn sample(&self, d_in: Vec3, u: Vec2) -> PhaseSample {
        let g = self.g;
        let cos_theta = if g.abs() < 1e-3 {
            1.0 - 2.0 * u.x
        } else {
            let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u.x);
            (1.0 + g * g - s * s) / (2.0 * g)
        }
        .clamp(-1.0, 1.0);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let local = Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta);
        let d_out = Frame::from_normal(d_in).to_world(local).normalize();
        PhaseSample {
            d_out,
            pdf: self.p_cos(cos_theta),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hg_integrates_to_one_and_has_mean_cosine_g() {
        for g in [-0.8f32, -0.3, 0.0, 0.5, 0.9] {
            let hg = HenyeyGreenstein::new(g);
            // ∫ p dω = 2π ∫ p(μ) dμ, and ∫ μ p dω = g (the definition of the asymmetry parameter).
            let n = 200_000;
            let (mut total, mut mean) = (0.0f64, 0.0f64);
            for i in 0..n {
                let mu = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                let p = hg.p_cos(mu as f32) as f64 * 2.0 * std::f64::consts::PI * (2.0 / n as f64);
                total += p;
                mean += mu * p;
            }
            assert!((total - 1.0).abs() < 2e-3, "g={g}: ∫p = {total}");
            assert!((mean - g as f64).abs() < 2e-3, "g={g}: mean cosine {mean}");
        }
    }
}
