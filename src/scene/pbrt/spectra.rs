//! Spectral quantities of pbrt-v4 files turned into the linear sRGB values Trayecto renders with.
//!
//! * `rgb` values are used as they are: pbrt-v4 turns an RGB illuminant into `rgb × D65` and then
//!   divides the light's scale by the photometric value of D65 (lights.cpp, `SpectrumToPhotometric`),
//!   so on its sRGB film an `"rgb L" [a b c]` seen directly reads (a, b, c).
//! * `blackbody T` is Planck's law normalised, as in pbrt-v4, to luminance Y = 1 (the light's scale
//!   is divided by the spectrum's photometric value), then projected on the CIE 1931 matching
//!   functions and converted XYZ → linear sRGB. The matching functions are the multi-lobe Gaussian
//!   fit of Wyman, Sloan and Shirley, "Simple Analytic Approximations to the CIE XYZ Color Matching
//!   Functions", JCGT 2(2), 2013 (eq. 2); its error against the tabulated functions is below 1 %
//!   of the peak, well inside the RGB-versus-spectral difference documented in docs/src/correctness.md.
//! * Named metal spectra (`metal-Cu-eta`, …) become the RGB (η, k) triples used by Tungsten and
//!   Mitsuba's RGB mode (the same values the Bitterli scenes write as `rgb eta`/`rgb k`); named
//!   glasses become their refractive index at the helium d line (587.6 nm).

use crate::math::Vec3;

fn lobe(l: f64, mu: f64, s1: f64, s2: f64) -> f64 {
    let s = if l < mu { s1 } else { s2 };
    let t = (l - mu) / s;
    (-0.5 * t * t).exp()
}

/// CIE 1931 2° matching functions at wavelength `l` (nm), Wyman et al. 2013 eq. 2.
pub fn cie_xyz(l: f64) -> [f64; 3] {
    let x = 1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7)
        - 0.065 * lobe(l, 501.1, 20.4, 26.2);
    let y = 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
    let z = 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8);
    [x, y, z]
}

/// XYZ → linear sRGB (IEC 61966-2-1, D65 white).
pub fn xyz_to_srgb(xyz: [f64; 3]) -> Vec3 {
    let [x, y, z] = xyz;
    Vec3::new(
        (3.2404542 * x - 1.5371385 * y - 0.4985314 * z) as f32,
        (-0.9692660 * x + 1.8760108 * y + 0.0415560 * z) as f32,
        (0.0556434 * x - 0.2040259 * y + 1.0572252 * z) as f32,
    )
}

/// XYZ of a spectrum (a function of wavelength in nm) over 360–830 nm, 1 nm steps.
fn integrate(f: impl Fn(f64) -> f64) -> [f64; 3] {
    let mut xyz = [0.0; 3];
    for l in 360..=830 {
        let l = l as f64;
        let v = f(l);
        let c = cie_xyz(l);
        for k in 0..3 {
            xyz[k] += v * c[k];
        }
    }
    xyz
}

/// Planck's law (W·sr⁻¹·m⁻³), up to a constant factor (it is normalised afterwards).
fn planck(l_nm: f64, t: f64) -> f64 {
    const C: f64 = 299_792_458.0;
    const H: f64 = 6.626_070_15e-34;
    const KB: f64 = 1.380_649e-23;
    let l = l_nm * 1e-9;
    (2.0 * H * C * C) / (l.powi(5) * ((H * C / (l * KB * t)).exp() - 1.0))
}

/// Linear sRGB of a blackbody at `kelvin`, normalised to luminance 1 (pbrt-v4's convention for
/// `blackbody` light spectra). None for a non-positive or non-finite temperature.
pub fn blackbody_rgb(kelvin: f32) -> Option<Vec3> {
    if !(kelvin.is_finite() && kelvin > 0.0) {
        return None;
    }
    let t = kelvin as f64;
    let xyz = integrate(|l| planck(l, t));
    if !(xyz[1] > 0.0 && xyz[1].is_finite()) {
        return None;
    }
    let n = [xyz[0] / xyz[1], 1.0, xyz[2] / xyz[1]];
    Some(xyz_to_srgb(n))
}

/// Linear sRGB of a piecewise-linear sampled spectrum `(λ nm, value)`, as an emission spectrum
/// normalised so that a constant spectrum of 1 gives luminance 1 (an approximation of pbrt-v4's
/// spectral rendering of it).
pub fn sampled_rgb(samples: &[(f32, f32)]) -> Option<Vec3> {
    if samples.is_empty()
        || samples
            .iter()
            .any(|(l, v)| !l.is_finite() || !v.is_finite())
    {
        return None;
    }
    let mut s: Vec<(f64, f64)> = samples.iter().map(|&(l, v)| (l as f64, v as f64)).collect();
    s.sort_by(|a, b| a.0.total_cmp(&b.0));
    let xyz = integrate(|l| piecewise_linear(&s, l));
    let white = integrate(|_| 1.0)[1];
    let rgb = xyz_to_srgb([xyz[0] / white, xyz[1] / white, xyz[2] / white]);
    // Equal energy is not D65: scale each channel so that a flat spectrum maps to (1, 1, 1).
    let flat = xyz_to_srgb({
        let w = integrate(|_| 1.0);
        [w[0] / white, 1.0, w[2] / white]
    });
    Some(rgb / flat)
}

/// Linear sRGB of a piecewise-linear sampled *light* spectrum `(λ nm, value)`: like every pbrt-v4
/// light spectrum (`scale /= SpectrumToPhotometric(L)`, lights.cpp) it is normalised to luminance
/// Y = 1 — its magnitude does not matter, `scale`/`power` set the brightness — and, as pbrt-v4's
/// sRGB film does without white balancing, its XYZ goes to sRGB as it is (an equal-energy
/// spectrum is slightly red, not white). Checked against pbrt-v4 in
/// `tests/pbrt_import.rs::spectrum_files_and_sampled_lights_match_pbrt_v4`.
pub fn sampled_illuminant_rgb(samples: &[(f32, f32)]) -> Option<Vec3> {
    if samples.is_empty()
        || samples
            .iter()
            .any(|(l, v)| !l.is_finite() || !v.is_finite())
    {
        return None;
    }
    let mut s: Vec<(f64, f64)> = samples.iter().map(|&(l, v)| (l as f64, v as f64)).collect();
    s.sort_by(|a, b| a.0.total_cmp(&b.0));
    let xyz = integrate(|l| piecewise_linear(&s, l));
    if !(xyz[1] > 0.0) {
        return None;
    }
    Some(xyz_to_srgb([xyz[0] / xyz[1], 1.0, xyz[2] / xyz[1]]))
}

/// A sorted piecewise-linear spectrum at `l`, constant beyond its ends (pbrt-v4
/// `PiecewiseLinearSpectrum` is zero there; the difference only matters for spectra that stop
/// inside 360–830 nm, which measured spectra do not).
fn piecewise_linear(s: &[(f64, f64)], l: f64) -> f64 {
    if l <= s[0].0 {
        return s[0].1;
    }
    if l >= s[s.len() - 1].0 {
        return s[s.len() - 1].1;
    }
    let i = s.partition_point(|p| p.0 <= l);
    let (a, b) = (s[i - 1], s[i]);
    if b.0 == a.0 {
        return a.1;
    }
    a.1 + (b.1 - a.1) * (l - a.0) / (b.0 - a.0)
}

/// A pbrt-v4 spectrum file (`PiecewiseLinearSpectrum::Read`): whitespace-separated numbers,
/// `#` to the end of a line is a comment, read as (λ nm, value) pairs with increasing λ.
pub fn parse_spectrum_file(text: &str) -> Result<Vec<(f32, f32)>, String> {
    let mut nums = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or("");
        for w in line.split_whitespace() {
            let v: f32 = w.parse().map_err(|_| {
                format!(
                    "'{}' is not a number",
                    w.chars().take(20).collect::<String>()
                )
            })?;
            if !v.is_finite() {
                return Err(format!("'{w}' is not a finite number"));
            }
            nums.push(v);
        }
    }
    if nums.len() < 2 || nums.len() % 2 != 0 {
        return Err(format!(
            "{} numbers: a spectrum file holds (wavelength, value) pairs",
            nums.len()
        ));
    }
    let pairs: Vec<(f32, f32)> = nums.chunks_exact(2).map(|c| (c[0], c[1])).collect();
    if pairs.windows(2).any(|w| w[1].0 <= w[0].0) {
        return Err("the wavelengths do not increase".into());
    }
    Ok(pairs)
}

/// RGB (η, k) of pbrt-v4's named metal spectra.
pub fn named_metal(name: &str) -> Option<(Vec3, Vec3)> {
    let m = name.strip_prefix("metal-")?;
    let (metal, which) = m.rsplit_once('-')?;
    let (eta, k) = match metal {
        "Ag" => (
            Vec3::new(0.155, 0.117, 0.138),
            Vec3::new(4.828, 3.122, 2.147),
        ),
        "Al" => (
            Vec3::new(1.657, 0.880, 0.521),
            Vec3::new(9.224, 6.270, 4.837),
        ),
        "Au" => (
            Vec3::new(0.143, 0.375, 1.442),
            Vec3::new(3.983, 2.386, 1.603),
        ),
        "Cu" => (
            Vec3::new(0.200, 0.924, 1.102),
            Vec3::new(3.913, 2.453, 2.142),
        ),
        "CuZn" => (
            Vec3::new(0.444, 0.527, 1.094),
            Vec3::new(3.695, 2.765, 1.829),
        ),
        "MgO" => (Vec3::new(1.732, 1.737, 1.745), Vec3::ZERO),
        "TiO2" => (Vec3::new(2.745, 2.856, 3.082), Vec3::ZERO),
        _ => return None,
    };
    match which {
        "eta" => Some((eta, Vec3::ZERO)),
        "k" => Some((Vec3::ZERO, k)),
        _ => None,
    }
}

/// Refractive index of pbrt-v4's named glass spectra at the d line (587.6 nm).
pub fn named_glass_eta(name: &str) -> Option<f32> {
    Some(match name {
        "glass-BK7" => 1.5168,
        "glass-BAF10" => 1.6700,
        "glass-FK51A" => 1.4866,
        "glass-LASF9" => 1.8503,
        // pbrt-v4's `glass-F5`/`-F10`/`-F11` are its tables of Schott's dense flints SF5, SF10,
        // SF11 (spectrum.cpp `GlassSF5_eta`, …); the SF names are accepted as well.
        "glass-F5" | "glass-SF5" => 1.6727,
        "glass-F10" | "glass-SF10" => 1.7283,
        "glass-F11" | "glass-SF11" => 1.7847,
        _ => return None,
    })
}

/// Named illuminant spectra, normalised to luminance 1 like every pbrt-v4 light spectrum.
pub fn named_illuminant(name: &str) -> Option<Vec3> {
    match name {
        "stdillum-D65" => Some(Vec3::ONE),
        // CIE illuminant A is a 2856 K Planckian radiator by definition.
        "stdillum-A" => blackbody_rgb(2856.0),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn d65_like_blackbody_is_near_white_and_luminance_is_one() {
        // 6504 K is close to D65's correlated colour temperature: near-neutral in sRGB.
        let c = blackbody_rgb(6504.0).unwrap();
        assert!((c - Vec3::ONE).abs().max_element() < 0.08, "{c}");
        let warm = blackbody_rgb(2700.0).unwrap();
        assert!(warm.x > warm.y && warm.y > warm.z, "{warm}");
        let y = 0.2126 * warm.x + 0.7152 * warm.y + 0.0722 * warm.z;
        assert!((y - 1.0).abs() < 0.02, "{y}");
        assert!(blackbody_rgb(0.0).is_none() && blackbody_rgb(f32::NAN).is_none());
    }

    #[test]
    fn flat_spectrum_is_white_and_names_resolve() {
        let c = sampled_rgb(&[(400.0, 2.0), (700.0, 2.0)]).unwrap();
        assert!((c - Vec3::splat(2.0)).abs().max_element() < 1e-4, "{c}");
        assert!(named_metal("metal-Cu-eta").is_some());
        assert!(named_metal("metal-Xx-eta").is_none());
        assert_eq!(named_glass_eta("glass-BK7"), Some(1.5168));
    }
}
