//! Spot lights (pbrt-v4 `SpotLight`): intensity `I` (W/sr) from one position inside a cone, full
//! inside the inner cone, none outside the outer, and a ramp ([`SpotFalloff`]) in between.

use super::bvh::LightBounds;
use super::{LeSample, LightSample, toward};
use crate::geometry::{Bounds3, Ray};
use crate::math::{Frame, PI, Vec2, Vec3, luminance};
use crate::sampling::warp;
pub use crate::scene::SpotFalloff;

#[derive(Clone, Copy, Debug)]
pub struct SpotLight {
    pub position: Vec3,
    /// Unit direction the spot points to.
    pub direction: Vec3,
    pub intensity: Vec3,
    pub cos_inner: f32,
    pub cos_outer: f32,
    pub falloff: SpotFalloff,
}

impl SpotLight {
    /// Intensity toward unit direction `w` (away from the light; pbrt-v4 `SpotLight::I`).
    #[inline]
    pub fn i(&self, w: Vec3) -> Vec3 {
        self.intensity
            * self
                .falloff
                .eval(self.direction.dot(w), self.cos_inner, self.cos_outer)
    }

    /// The light seen from `p`: direction to it, I · falloff / d², pdf 1 (a delta light);
    /// `None` outside the cone and at the light's position.
    #[inline]
    pub fn sample_li(&self, p: Vec3, p_error: Vec3, n_offset: Vec3) -> Option<LightSample> {
        let (wi, d2) = toward(self.position, p)?;
        let falloff = self
            .falloff
            .eval(self.direction.dot(-wi), self.cos_inner, self.cos_outer);
        if falloff <= 0.0 {
            return None;
        }
        Some(LightSample {
            wi,
            li: self.intensity * (falloff / d2),
            pdf: 1.0,
            pmf: 1.0,
            delta: true,
            shadow: Ray::spawn_to(p, p_error, n_offset, self.position, Vec3::ZERO, wi),
            light: u32::MAX,
        })
    }

    /// Emission sampling (pbrt-v4 `SpotLight::SampleLe`): the position (pdf 1, a delta) and a
    /// direction uniform in the outer cone (pdf 1 / 2π(1 − cos θ_outer)) carrying I · falloff.
    pub fn sample_le(&self, u: Vec2) -> Option<LeSample> {
        let local = warp::uniform_cone(u, self.cos_outer);
        let w = Frame::from_normal(self.direction).to_world(local);
        Some(LeSample {
            ray: Ray::new(self.position, w),
            le: self.i(w),
            n: Vec3::ZERO,
            pdf_pos: 1.0,
            pdf_dir: warp::uniform_cone_pdf(self.cos_outer),
        })
    }

    /// Position and direction pdfs of [`SpotLight::sample_le`] for direction `w`: position a
    /// delta (0 as a density), direction uniform in the outer cone.
    pub fn pdf_le(&self, w: Vec3) -> (f32, f32) {
        if self.direction.dot(w) >= self.cos_outer {
            (0.0, warp::uniform_cone_pdf(self.cos_outer))
        } else {
            (0.0, 0.0)
        }
    }

    /// Emitted power (pbrt-v4 `SpotLight::Phi`): I · 2π [(1 − cos inner) + (cos inner − cos
    /// outer) · k], k the mean of the ramp over cos θ: ∫₀¹ t² dt = 1/3 for the squared ramp,
    /// ∫₀¹ t²(3 − 2t) dt = 1/2 for the smoothstep.
    pub fn phi(&self) -> Vec3 {
        let k = match self.falloff {
            SpotFalloff::SquaredRamp => 1.0 / 3.0,
            SpotFalloff::Smoothstep => 0.5,
        };
        let ramp = (self.cos_inner - self.cos_outer).max(0.0);
        self.intensity * (2.0 * PI * ((1.0 - self.cos_inner) + ramp * k))
    }

    /// Power for light selection: the cone to half way between the two angles' cosines.
    pub fn selection_power(&self) -> f32 {
        2.0 * PI * (1.0 - 0.5 * (self.cos_inner + self.cos_outer)) * luminance(self.intensity)
    }

    /// pbrt-v4 `SpotLight::Bounds`: θo the inner cone, θe the ramp out to the outer one.
    pub fn bounds(&self, phi: f32) -> LightBounds {
        let (cos_inner, cos_outer) = (self.cos_inner, self.cos_outer);
        let theta_e =
            (cos_outer.clamp(-1.0, 1.0).acos() - cos_inner.clamp(-1.0, 1.0).acos()).max(0.0);
        LightBounds {
            bounds: Bounds3::from_point(self.position),
            phi,
            w: self.direction,
            cos_theta_o: cos_inner,
            cos_theta_e: theta_e.cos(),
            two_sided: false,
        }
    }
}

impl SpotFalloff {
    /// The falloff at `cos_theta` (the cosine of the angle to the spot's axis): 1 inside the
    /// inner cone, 0 outside the outer, this ramp in between.
    #[inline]
    pub fn eval(self, cos_theta: f32, cos_inner: f32, cos_outer: f32) -> f32 {
        match self {
            SpotFalloff::SquaredRamp => spot_falloff(cos_theta, cos_inner, cos_outer),
            SpotFalloff::Smoothstep => smoothstep(cos_theta, cos_outer, cos_inner),
        }
    }
}

/// pbrt-v4's `SmoothStep(x, a, b)` (util/math.h): 0 below `a`, 1 above `b`, the cubic Hermite
/// t²(3 − 2t), t = (x − a)/(b − a), between; a step at `a` when the two coincide.
#[inline]
pub fn smoothstep(x: f32, a: f32, b: f32) -> f32 {
    if a == b {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Smooth spot cone falloff: 1 inside the inner cone, 0 outside the outer, and the squared linear
/// ramp of the glTF `KHR_lights_punctual` reference implementation in between.
#[inline]
pub fn spot_falloff(cos_theta: f32, cos_inner: f32, cos_outer: f32) -> f32 {
    if cos_theta >= cos_inner {
        return 1.0;
    }
    if cos_theta <= cos_outer {
        return 0.0;
    }
    let t = (cos_theta - cos_outer) / (cos_inner - cos_outer).max(1e-6);
    t * t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spot_falloff_limits() {
        let (ci, co) = (0.9f32, 0.7f32);
        assert_eq!(spot_falloff(0.95, ci, co), 1.0);
        assert_eq!(spot_falloff(0.6, ci, co), 0.0);
        let mid = spot_falloff(0.8, ci, co);
        assert!(mid > 0.0 && mid < 1.0);
    }

    /// pbrt-v4's spot ramp is `SmoothStep(cos θ, cos outer, cos inner)`: t²(3 − 2t), so 0.5 half
    /// way in cos θ (the glTF ramp gives 0.25 there), 0.15625 at t = 1/4 and 0.84375 at 3/4,
    /// and a step when the cones coincide (pbrt-v4 conedeltaangle 0).
    #[test]
    fn pbrt_spot_falloff_is_a_smoothstep_in_cos() {
        let (ci, co) = (0.9f32, 0.7f32);
        let f = |c: f32| SpotFalloff::Smoothstep.eval(c, ci, co);
        assert_eq!(f(0.95), 1.0);
        assert_eq!(f(0.6), 0.0);
        for (t, want) in [(0.25f32, 0.15625f32), (0.5, 0.5), (0.75, 0.84375)] {
            let got = f(co + t * (ci - co));
            assert!((got - want).abs() < 1e-5, "t = {t}: {got}, want {want}");
        }
        assert_eq!(SpotFalloff::Smoothstep.eval(0.8, 0.8, 0.8), 1.0);
        assert_eq!(SpotFalloff::Smoothstep.eval(0.79, 0.8, 0.8), 0.0);
        assert!((SpotFalloff::SquaredRamp.eval(0.8, ci, co) - 0.25).abs() < 1e-5);
    }

    /// The formula itself, at the soft spot of `scenes/mitsuba/spot_soft.toml` (inner 10°, outer
    /// 30°): glTF KHR_lights_punctual's reference, t = saturate((cos θ − cos outer) / (cos inner
    /// − cos outer)), falloff t². Values computed by hand (Python) from that formula; the Mitsuba
    /// comparison of `spot_soft` rests on it.
    #[test]
    fn spot_falloff_is_the_gltf_squared_ramp_in_cos() {
        let (ci, co) = (10f32.to_radians().cos(), 30f32.to_radians().cos());
        for (deg, want) in [
            (5.0f32, 1.0f32),
            (10.0, 1.0),
            (15.0, 0.707344),
            (20.0, 0.384631),
            (25.0, 0.115008),
            (29.9, 0.000054),
            (30.0, 0.0),
            (31.0, 0.0),
            (90.0, 0.0),
        ] {
            let got = spot_falloff(deg.to_radians().cos(), ci, co);
            assert!(
                (got - want).abs() < 2e-5,
                "falloff at {deg}° = {got}, glTF formula {want}"
            );
        }
        // Its solid-angle integral: 2π [(1 − cos inner) + (cos inner − cos outer) / 3] for t².
        let n = 200_000;
        let mut sum = 0.0f64;
        for i in 0..n {
            let c = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
            sum += spot_falloff(c as f32, ci, co) as f64;
        }
        let integral = 2.0 * std::f64::consts::PI * sum * 2.0 / n as f64;
        let (ci, co) = (ci as f64, co as f64);
        let closed = 2.0 * std::f64::consts::PI * ((1.0 - ci) + (ci - co) / 3.0);
        assert!(
            (integral / closed - 1.0).abs() < 1e-3,
            "∫ falloff dω = {integral}, closed form {closed}"
        );
    }
}
