//! Tone mapping from linear radiance (after exposure) to display values in [0, 1] (docs/DESIGN.md §5).

use crate::math::Vec3;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Tonemap {
    /// Clamp to [0, 1], then the sRGB transfer curve.
    #[default]
    Clamp,
    /// The thesis's output: clamp, then a pure 1/2.2 power (§5.3.5).
    Gamma22,
    /// ACES filmic fit (Narkowicz 2015, "ACES Filmic Tone Mapping Curve"), then sRGB.
    Aces,
    /// A compact AgX-style sigmoid in log space (Troy Sobotka's AgX, simplified), then sRGB.
    Agx,
}

impl std::str::FromStr for Tonemap {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "clamp" => Ok(Tonemap::Clamp),
            "gamma2.2" => Ok(Tonemap::Gamma22),
            "aces" => Ok(Tonemap::Aces),
            "agx" => Ok(Tonemap::Agx),
            other => Err(format!(
                "unknown tone mapping '{other}' (expected clamp, gamma2.2, aces or agx)"
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
                // Log2 encoding over [-12.47, 4.03] stops around 0.18, then a sigmoid contrast curve.
                let min_ev = -12.47393f32;
                let max_ev = 4.026069f32;
                let f = |x: f32| {
                    let v = ((x.max(1e-10) / 0.18).log2() - min_ev) / (max_ev - min_ev);
                    let v = v.clamp(0.0, 1.0);
                    // Smooth S-curve through (0,0), (1,1) with a steeper middle.
                    let s = v * v * (3.0 - 2.0 * v);
                    let s = s * s * (3.0 - 2.0 * s);
                    s.clamp(0.0, 1.0)
                };
                Vec3::new(f(c.x), f(c.y), f(c.z))
            }
        }
    }
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
}
