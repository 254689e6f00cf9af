//! Tone mapping from linear radiance (after exposure) to display values in [0, 1] (docs/DESIGN.md §5).

use crate::math::{Mat3, Vec3};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Tonemap {
    /// Clamp to [0, 1], then the sRGB transfer curve.
    Clamp,
    /// The thesis's output: clamp, then a pure 1/2.2 power (§5.3.5).
    Gamma22,
    /// ACES filmic fit (Narkowicz 2015, "ACES Filmic Tone Mapping Curve"), then sRGB.
    Aces,
    /// Troy Sobotka's AgX (Blender 4's default view transform) in B. Wrensch's published minimal
    /// form: the AgX inset matrix, log2 encoding of −12.47 to +4.03 stops (middle grey 0.18 at
    /// 10 of 16.5 stops), the 6th-order polynomial fit of the AgX base contrast sigmoid, and the
    /// inverse inset matrix. The sigmoid's output is already display-encoded (middle grey lands
    /// at ≈ 0.497, a 2.2-power display value), so no sRGB curve is applied after it.
    Agx,
    /// Khronos PBR Neutral (the Khronos 3D Commerce group's tone mapper for product shots, as
    /// published with its GLSL reference, 2024), then sRGB. Base colours under a white light of
    /// radiance 1 come out as the colour itself (below 0.76 it is the identity but for a small
    /// black-level offset); brighter values are compressed towards white with a desaturation
    /// that keeps hues from skewing. The default for display formats: measured on the Khronos
    /// sample models it keeps the authored material contrast (docs/DESIGN.md §5, "View
    /// transform").
    #[default]
    PbrNeutral,
}

impl std::str::FromStr for Tonemap {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "clamp" => Ok(Tonemap::Clamp),
            "gamma2.2" => Ok(Tonemap::Gamma22),
            "aces" => Ok(Tonemap::Aces),
            "agx" => Ok(Tonemap::Agx),
            "pbr-neutral" => Ok(Tonemap::PbrNeutral),
            other => Err(format!(
                "unknown tone mapping '{other}' (expected clamp, gamma2.2, aces, agx or pbr-neutral)"
            )),
        }
    }
}

impl Tonemap {
    /// Maps a linear colour (exposure already applied) to display-referred [0, 1] values,
    /// including the output transfer curve.
    #[inline]
    pub fn apply(self, c: Vec3) -> Vec3 {
        let c = c.max(Vec3::ZERO);
        let c = if c.is_finite() { c } else { Vec3::ZERO };
        match self {
            Tonemap::Clamp => srgb(c.min(Vec3::ONE)),
            Tonemap::Gamma22 => c.min(Vec3::ONE).powf(1.0 / 2.2),
            Tonemap::Aces => {
                let (a, b, cc, d, e) = (2.51, 0.03, 2.43, 0.59, 0.14);
                let m = (c * (c * a + b)) / (c * (c * cc + d) + e);
                srgb(m.clamp(Vec3::ZERO, Vec3::ONE))
            }
            Tonemap::Agx => {
                // B. Wrensch, "Minimal AgX Implementation" (iolite-engine.com, 2023), the form
                // three.js, Godot and Filament follow; matrices column-major as published.
                const INSET: Mat3 = Mat3::from_cols_array(&[
                    0.842_479_06,
                    0.042_328_242,
                    0.042_375_655,
                    0.078_433_6,
                    0.878_468_6,
                    0.078_433_6,
                    0.079_223_745,
                    0.079_166_13,
                    0.879_143,
                ]);
                const OUTSET: Mat3 = Mat3::from_cols_array(&[
                    1.196_879,
                    -0.052_896_85,
                    -0.052_971_635,
                    -0.098_020_88,
                    1.151_903_1,
                    -0.098_043_45,
                    -0.099_029_74,
                    -0.098_961_18,
                    1.151_073_7,
                ]);
                let (min_ev, max_ev) = (-12.47393f32, 4.026069f32);
                let encode = |x: f32| {
                    (x.max(1e-10).log2().clamp(min_ev, max_ev) - min_ev) / (max_ev - min_ev)
                };
                let v = INSET * c;
                let v = Vec3::new(encode(v.x), encode(v.y), encode(v.z));
                // The 6th-order polynomial fit of the AgX base contrast curve (mean error² 3.7e-6).
                let (v2, v4) = (v * v, v * v * v * v);
                let s = 15.5 * v4 * v2 - 40.14 * v4 * v + 31.96 * v4 - 6.868 * v2 * v
                    + 0.4298 * v2
                    + 0.1191 * v
                    - Vec3::splat(0.00232);
                (OUTSET * s).clamp(Vec3::ZERO, Vec3::ONE)
            }
            Tonemap::PbrNeutral => srgb(pbr_neutral(c).clamp(Vec3::ZERO, Vec3::ONE)),
        }
    }
}

impl Tonemap {
    /// The name `--tonemap` takes.
    pub fn name(self) -> &'static str {
        match self {
            Tonemap::Clamp => "clamp",
            Tonemap::Gamma22 => "gamma2.2",
            Tonemap::Aces => "aces",
            Tonemap::Agx => "agx",
            Tonemap::PbrNeutral => "pbr-neutral",
        }
    }
}

/// Khronos PBR Neutral on a linear, non-negative colour: subtract a small offset that lifts
/// near-black values off the toe (a parabola below 0.08, 0.04 above), leave peaks below the
/// compression start 0.76 alone, map larger peaks onto 1 − d²/(peak + d − 0.76) with
/// d = 0.24 (a hyperbola tangent to the identity), and blend towards the new peak's grey by
/// g = 1 − 1/(0.15·(peak − new peak) + 1).
#[inline]
fn pbr_neutral(c: Vec3) -> Vec3 {
    const START: f32 = 0.8 - 0.04;
    const DESATURATION: f32 = 0.15;
    let x = c.min_element();
    let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
    let c = c - Vec3::splat(offset);
    let peak = c.max_element();
    if peak < START {
        return c;
    }
    let d = 1.0 - START;
    let new_peak = 1.0 - d * d / (peak + d - START);
    let c = c * (new_peak / peak);
    let g = 1.0 - 1.0 / (DESATURATION * (peak - new_peak) + 1.0);
    c.lerp(Vec3::splat(new_peak), g)
}

#[inline]
fn srgb(c: Vec3) -> Vec3 {
    use crate::material::texture::linear_to_srgb;
    Vec3::new(
        linear_to_srgb(c.x),
        linear_to_srgb(c.y),
        linear_to_srgb(c.z),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_curve_maps_into_unit_range_and_is_monotonic() {
        for t in [
            Tonemap::Clamp,
            Tonemap::Gamma22,
            Tonemap::Aces,
            Tonemap::Agx,
            Tonemap::PbrNeutral,
        ] {
            let mut prev = -1.0;
            for i in 0..200 {
                let x = (i as f32 * 0.1).powf(2.0) * 0.01;
                let y = t.apply(Vec3::splat(x)).x;
                assert!((0.0..=1.0).contains(&y), "{t:?} {x} -> {y}");
                assert!(y >= prev - 1e-6, "{t:?} not monotonic at {x}");
                prev = y;
            }
            assert_eq!(t.apply(Vec3::splat(f32::NAN)), t.apply(Vec3::ZERO));
        }
        assert!((Tonemap::Gamma22.apply(Vec3::splat(0.5)).x - 0.5f32.powf(1.0 / 2.2)).abs() < 1e-6);
        assert!(Tonemap::Clamp.apply(Vec3::splat(2.0)).min_element() > 0.99999);
    }

    /// Spot values of the published curves, computed with numpy from the published formulas
    /// (not from this code): ACES = sRGB(Narkowicz's x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14)),
    /// AgX = Wrensch's minimal AgX (inset matrix, log2 over [−12.47393, 4.026069], the 6th-order
    /// polynomial, inverse inset matrix), display-encoded as it comes out of the sigmoid: an
    /// sRGB curve applied after it would move middle grey from 0.497 to 0.73.
    #[test]
    fn aces_and_agx_match_the_published_curves() {
        let aces = [
            (0.0, 0.0),
            (0.01, 0.048135),
            (0.18, 0.553458),
            (1.0, 0.908230),
            (4.0, 0.988223),
            (16.0, 1.0),
        ];
        for (x, want) in aces {
            let got = Tonemap::Aces.apply(Vec3::splat(x));
            assert!(
                (got - Vec3::splat(want)).abs().max_element() < 2e-5,
                "ACES({x}) = {got}, published {want}"
            );
        }
        // Khronos PBR Neutral before its sRGB curve, worked by hand from the published
        // formula: grey 0.5 only loses the 0.04 offset; 0.02 the parabola's 0.0175; grey 1 and
        // an orange are compressed (peak 0.96 -> 0.869091, blend 0.013453 towards grey).
        let neutral = [
            ([0.5; 3], [0.46; 3]),
            ([0.02; 3], [0.0025; 3]),
            ([1.0; 3], [0.869091; 3]),
            ([1.0, 0.5, 0.2], [0.869091, 0.422529, 0.154591]),
        ];
        for (x, want) in neutral {
            let got = pbr_neutral(Vec3::from(x));
            assert!(
                (got - Vec3::from(want)).abs().max_element() < 2e-5,
                "PBR Neutral({x:?}) = {got}, published {want:?}"
            );
        }
        let agx = [
            ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
            ([0.01; 3], [0.097700, 0.097704, 0.097705]),
            ([0.18; 3], [0.496676, 0.496745, 0.496749]),
            ([1.0; 3], [0.786745, 0.786885, 0.786893]),
            ([4.0; 3], [0.934048, 0.934236, 0.934248]),
            ([16.0; 3], [0.997610, 0.997816, 0.997829]),
            ([1.0, 0.2, 0.05], [0.824097, 0.536011, 0.363437]),
            ([0.02, 0.1, 0.5], [0.275006, 0.420440, 0.699123]),
        ];
        for (x, want) in agx {
            let got = Tonemap::Agx.apply(Vec3::from(x));
            assert!(
                (got - Vec3::from(want)).abs().max_element() < 1e-4,
                "AgX({x:?}) = {got}, published {want:?}"
            );
        }
    }
}
