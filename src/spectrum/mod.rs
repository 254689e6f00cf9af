//! Spectral data and its conversion to the linear-sRGB values Trayecto renders with, the way
//! pbrt-v4 sees spectra in its default sRGB colour space.
//!
//! Conventions (pbrt-v4 `spectrum.cpp`, `colorspace.cpp`, `lights.cpp`):
//! * XYZ of a spectrum s: X = Σλ x̄(λ) s(λ) / Σλ ȳ(λ) over 360–830 nm at 1 nm (so a constant 1 has
//!   Y = 1); linear sRGB from XYZ with the sRGB/D65 matrix (IEC 61966-2-1).
//! * A *reflectance-like* spectrum r(λ) (albedo, η, k) is seen under the colour space's illuminant,
//!   D65 normalised to Y = 1: rgb = sRGB(XYZ(r · D65ₙ)). A constant 1 maps to (1, 1, 1).
//! * An *illuminant* (a light's `L`): pbrt-v4 divides a light's `scale` by the spectrum's
//!   photometric value (`scale /= SpectrumToPhotometric(L)`; for an RGB `L` only its illuminant
//!   part, D65ₙ, counts), so an `rgb L` renders as that RGB and any other spectrum (a `blackbody`,
//!   a named illuminant) as its sRGB chromaticity with luminance Y = 1 before `scale`
//!   ([`illuminant_to_rgb`]). `blackbody` is Planck's law normalised to peak 1 (which the
//!   photometric division then cancels).
//! * A conductor's η(λ), k(λ) become one (η, k) per channel, each projected as a reflectance-like
//!   spectrum ([`named_conductor_rgb`]); [`conductor_rgb_error`] measures what that costs against
//!   the spectral Fresnel reflectance pbrt-v4 integrates, and `tests` bound it.
//! * A named glass (`glass-BK7`, …) becomes one IOR, the D65ₙ·ȳ-weighted mean of η(λ) (pbrt-v4
//!   disperses; Trayecto's RGB dielectric cannot).

mod data;
pub mod rgb2spec;

pub use rgb2spec::{SigmoidPolynomial, Wavelengths};

use crate::material::microfacet::fresnel_complex;
use crate::math::Vec3;

const LAMBDA_MIN: f32 = 360.0;
const LAMBDA_MAX: f32 = 830.0;

/// The CIE 1931 2° colour matching functions at `lambda` nm (0 outside 360–830 nm).
pub fn cie_xyz(lambda: f32) -> Vec3 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) {
        return Vec3::ZERO;
    }
    let x = lambda - LAMBDA_MIN;
    let i = (x as usize).min(469);
    let t = x - i as f32;
    let lerp = |a: &[f32; 471]| a[i] * (1.0 - t) + a[i + 1] * t;
    Vec3::new(lerp(&data::CIE_X), lerp(&data::CIE_Y), lerp(&data::CIE_Z))
}

/// Σ ȳ over the 1 nm grid (pbrt-v4's `CIE_Y_integral` for this table).
fn cie_y_integral() -> f32 {
    data::CIE_Y.iter().sum()
}

/// CIE D65 relative power at `lambda` (linear between the 5 nm samples), unnormalised.
fn d65_raw(lambda: f32) -> f32 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) {
        return 0.0;
    }
    let x = (lambda - LAMBDA_MIN) / 5.0;
    let i = (x as usize).min(data::D65.len() - 2);
    let t = x - i as f32;
    data::D65[i] * (1.0 - t) + data::D65[i + 1] * t
}

/// D65 scaled to luminance Y = 1 (pbrt-v4's `stdillum-D65`, the sRGB colour space's illuminant).
pub fn d65(lambda: f32) -> f32 {
    static NORM: std::sync::OnceLock<f32> = std::sync::OnceLock::new();
    let norm = *NORM.get_or_init(|| {
        let y: f32 = (360..=830)
            .map(|l| d65_raw(l as f32) * cie_xyz(l as f32).y)
            .sum();
        cie_y_integral() / y
    });
    d65_raw(lambda) * norm
}

/// XYZ of a spectrum (pbrt-v4 `SpectrumToXYZ`): Σ x̄ s / Σ ȳ at 1 nm.
pub fn spectrum_to_xyz(s: impl Fn(f32) -> f32) -> Vec3 {
    let mut xyz = Vec3::ZERO;
    for l in 360..=830 {
        let l = l as f32;
        xyz += cie_xyz(l) * s(l);
    }
    xyz / cie_y_integral()
}

/// Linear sRGB (D65 white) from CIE XYZ.
pub fn xyz_to_linear_srgb(xyz: Vec3) -> Vec3 {
    Vec3::new(
        3.240_454_2 * xyz.x - 1.537_138_5 * xyz.y - 0.498_531_4 * xyz.z,
        -0.969_266 * xyz.x + 1.876_010_8 * xyz.y + 0.041_556 * xyz.z,
        0.055_643_4 * xyz.x - 0.204_025_9 * xyz.y + 1.057_225_2 * xyz.z,
    )
}

/// A reflectance-like spectrum (albedo, η, k) as linear sRGB: seen under D65ₙ.
pub fn reflectance_to_rgb(s: impl Fn(f32) -> f32) -> Vec3 {
    xyz_to_linear_srgb(spectrum_to_xyz(|l| s(l) * d65(l)))
}

/// A light's emission spectrum as the linear-sRGB radiance pbrt-v4 renders for `scale` 1: its
/// chromaticity at luminance Y = 1 (pbrt-v4 `scale /= SpectrumToPhotometric(L)`). Zero for a
/// spectrum without luminance.
pub fn illuminant_to_rgb(s: impl Fn(f32) -> f32) -> Vec3 {
    let xyz = spectrum_to_xyz(s);
    if !(xyz.y > 0.0) {
        return Vec3::ZERO;
    }
    xyz_to_linear_srgb(xyz / xyz.y)
}

/// Planck's law: spectral radiance of a blackbody at `lambda` nm and temperature `t` K
/// (W·sr⁻¹·m⁻³).
pub fn planck(lambda: f32, t: f32) -> f32 {
    if t <= 0.0 {
        return 0.0;
    }
    let (c, h, kb) = (299_792_458.0f64, 6.626_069_57e-34f64, 1.380_648_8e-23f64);
    let l = lambda as f64 * 1e-9;
    ((2.0 * h * c * c) / (l.powi(5) * (((h * c) / (l * kb * t as f64)).exp() - 1.0))) as f32
}

/// pbrt-v4's `blackbody` spectrum: Planck normalised to 1 at its peak (Wien: λmax = b / T).
pub fn blackbody(lambda: f32, t: f32) -> f32 {
    if t <= 0.0 {
        return 0.0;
    }
    let peak = 2.897_772_1e-3 / t as f64 * 1e9;
    planck(lambda, t) / planck(peak as f32, t)
}

/// The linear-sRGB emission of pbrt-v4's `"blackbody L" [T]` for `scale` 1 (luminance 1).
pub fn blackbody_rgb(t: f32) -> Vec3 {
    illuminant_to_rgb(|l| blackbody(l, t))
}

/// Linear sRGB of pbrt-v4's `BlackbodySpectrum(t)` *without* the photometric normalisation of
/// lights: what a grid medium's `temperature` voxel emits per unit `Lescale` (pbrt-v4
/// `GridMedium::SamplePoint`). pbrt-v4's film takes XYZ = ∫ x̄·L dλ with the unnormalised CIE
/// curves (its `cie1931` sensor); every light and `Le` spectrum is divided by its
/// `SpectrumToPhotometric` = ∫ ȳ·L, which cancels that, but this spectrum is not, so its XYZ is
/// Σ x̄·B at 1 nm — Σ ȳ (≈ 106.9) times [`spectrum_to_xyz`]'s. Zero at t ≤ 0.
pub fn blackbody_peak_rgb(t: f32) -> Vec3 {
    if !(t > 0.0) {
        return Vec3::ZERO;
    }
    xyz_to_linear_srgb(spectrum_to_xyz(|l| blackbody(l, t)) * cie_y_integral())
}

/// pbrt-v4's unnormalised `BlackbodySpectrum(t)` (a grid medium's `temperature` voxel) at the
/// three wavelengths `lambda`, in the units of a spectral path: [`blackbody`] × Σ ȳ, so that the
/// film's projection ([`Wavelengths::to_rgb`]) gives [`blackbody_peak_rgb`]. Zero at t ≤ 0.
#[inline]
pub fn blackbody_peak_spectral(lambda: Vec3, t: f32) -> Vec3 {
    if !(t > 0.0) {
        return Vec3::ZERO;
    }
    Vec3::new(
        blackbody(lambda.x, t),
        blackbody(lambda.y, t),
        blackbody(lambda.z, t),
    ) * rgb2spec::CIE_Y_INTEGRAL
}

/// A light's emission spectrum, kept so that spectral rendering evaluates it per wavelength
/// instead of upsampling its RGB projection (pbrt-v4 keeps a light's `L`/`I` spectrum and takes
/// it at the sampled wavelengths: `DiffuseAreaLight::L`, `PointLight::SampleLi`, …). Tabulated
/// at 1 nm over 360–830 nm and normalised to luminance Y = 1, the normalisation every pbrt-v4
/// light applies (`scale /= SpectrumToPhotometric(L)`): the emitter's RGB projection then has
/// luminance equal to its scale, which [`Illuminant::at`] reads back, so that whatever scaled the
/// RGB (`scale`, `power`, a scene-wide factor) scales the spectrum the same way.
#[derive(Clone)]
pub struct Illuminant {
    /// What it is, for messages and cache keys (`blackbody 2700 K`, `stdillum-A`, …).
    name: std::sync::Arc<str>,
    /// S(λ)/Y(S) at 360, 361, …, 830 nm.
    table: std::sync::Arc<[f32]>,
}

impl std::fmt::Debug for Illuminant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Illuminant({})", self.name)
    }
}

impl PartialEq for Illuminant {
    fn eq(&self, other: &Self) -> bool {
        self.table == other.table
    }
}

impl Illuminant {
    /// The spectrum `s` (any scale) named `name`; None when it has no luminance.
    pub fn new(name: &str, s: impl Fn(f32) -> f32) -> Option<Illuminant> {
        let y = spectrum_to_xyz(&s).y;
        if !(y > 0.0 && y.is_finite()) {
            return None;
        }
        let table: Vec<f32> = (360..=830).map(|l| s(l as f32) / y).collect();
        table.iter().all(|v| v.is_finite()).then(|| Illuminant {
            name: name.into(),
            table: table.into(),
        })
    }

    /// pbrt-v4's `blackbody` spectrum at `kelvin` (Planck's law; the peak normalisation cancels).
    pub fn blackbody(kelvin: f32) -> Option<Illuminant> {
        if !(kelvin.is_finite() && kelvin > 0.0) {
            return None;
        }
        Illuminant::new(&format!("blackbody {kelvin} K"), |l| blackbody(l, kelvin))
    }

    /// pbrt-v4's named light spectra that Trayecto has: `stdillum-D65` and `stdillum-A` (CIE
    /// illuminant A is by definition a Planckian radiator at 2856 K, with today's c₂).
    pub fn named(name: &str) -> Option<Illuminant> {
        match name {
            "stdillum-D65" => Illuminant::new(name, d65),
            "stdillum-A" => Illuminant::new(name, |l| blackbody(l, 2856.0)),
            _ => None,
        }
    }

    /// A sampled spectrum, (λ nm, value) pairs in increasing λ, piecewise linear and zero outside
    /// its range (pbrt-v4 `PiecewiseLinearSpectrum`).
    pub fn sampled(samples: &[(f32, f32)]) -> Option<Illuminant> {
        if samples.windows(2).any(|w| !(w[1].0 > w[0].0)) {
            return None;
        }
        let mut h = std::hash::DefaultHasher::new();
        for &(l, v) in samples {
            std::hash::Hash::hash(&(l.to_bits(), v.to_bits()), &mut h);
        }
        let name = format!(
            "sampled, {} points, {:016x}",
            samples.len(),
            std::hash::Hasher::finish(&h)
        );
        Illuminant::new(&name, |l| table(samples, l))
    }

    /// The same spectrum under another name (a spectrum file's).
    pub fn renamed(self, name: &str) -> Illuminant {
        Illuminant {
            name: name.into(),
            ..self
        }
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// The linear-sRGB projection of the spectrum (luminance 1), what RGB mode renders.
    pub fn rgb(&self) -> Vec3 {
        xyz_to_linear_srgb(spectrum_to_xyz(|l| self.value(l)))
    }

    /// S(λ)/Y(S) at `lambda` nm, linear between the 1 nm samples, 0 outside 360–830 nm.
    #[inline]
    pub fn value(&self, lambda: f32) -> f32 {
        at_1nm(&self.table, lambda)
    }

    /// The emission at the wavelengths `lambda` of an emitter whose RGB projection is `rgb`: the
    /// spectrum scaled by the luminance of `rgb` (the CIE Y row of sRGB → XYZ).
    #[inline]
    pub fn at(&self, rgb: Vec3, lambda: Vec3) -> Vec3 {
        let y = 0.212_672_9 * rgb.x + 0.715_152_2 * rgb.y + 0.072_175 * rgb.z;
        Vec3::new(
            self.value(lambda.x),
            self.value(lambda.y),
            self.value(lambda.z),
        ) * y
    }
}

/// A table of values at 360, 361, …, 830 nm at `lambda`: linear between the samples, 0 outside.
#[inline]
fn at_1nm(table: &[f32], lambda: f32) -> f32 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) || table.len() < 2 {
        return 0.0;
    }
    let x = lambda - LAMBDA_MIN;
    let i = (x as usize).min(table.len() - 2);
    let t = x - i as f32;
    table[i] * (1.0 - t) + table[i + 1] * t
}

/// A spectrum given by a scene as a sampled list (pbrt's `"spectrum sigma_a" [λ v …]` or a
/// spectrum file), kept as it is for spectral rendering where its RGB projection is what RGB
/// mode uses: a medium's σa and σs. Tabulated at 1 nm over 360–830 nm, piecewise linear between
/// the given samples and zero outside them (pbrt-v4 `PiecewiseLinearSpectrum`).
#[derive(Clone)]
pub struct SpectrumTable {
    table: std::sync::Arc<[f32]>,
}

impl std::fmt::Debug for SpectrumTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SpectrumTable({} nm..)", LAMBDA_MIN)
    }
}

impl PartialEq for SpectrumTable {
    fn eq(&self, other: &Self) -> bool {
        self.table == other.table
    }
}

impl SpectrumTable {
    /// (λ nm, value) pairs in increasing λ; None if λ does not increase or a value is not finite.
    pub fn sampled(samples: &[(f32, f32)]) -> Option<SpectrumTable> {
        if samples.is_empty()
            || samples.windows(2).any(|w| !(w[1].0 > w[0].0))
            || samples.iter().any(|p| !p.1.is_finite())
        {
            return None;
        }
        let table: Vec<f32> = (360..=830).map(|l| table(samples, l as f32)).collect();
        Some(SpectrumTable {
            table: table.into(),
        })
    }

    /// The value at `lambda` nm.
    #[inline]
    pub fn value(&self, lambda: f32) -> f32 {
        at_1nm(&self.table, lambda)
    }

    /// The values at the three wavelengths `lambda`.
    #[inline]
    pub fn eval3(&self, lambda: Vec3) -> Vec3 {
        Vec3::new(
            at_1nm(&self.table, lambda.x),
            at_1nm(&self.table, lambda.y),
            at_1nm(&self.table, lambda.z),
        )
    }
}

/// A piecewise-linear tabulated spectrum; 0 outside its range (pbrt-v4 `PiecewiseLinearSpectrum`).
fn table(tab: &[(f32, f32)], lambda: f32) -> f32 {
    let (Some(first), Some(last)) = (tab.first(), tab.last()) else {
        return 0.0;
    };
    if lambda < first.0 || lambda > last.0 {
        return 0.0;
    }
    if tab.len() == 1 {
        // One sample: the spectrum is that value at that wavelength alone.
        return first.1;
    }
    let i = tab
        .partition_point(|p| p.0 <= lambda)
        .clamp(1, tab.len() - 1)
        - 1;
    let (a, b) = (tab[i], tab[i + 1]);
    a.1 + (b.1 - a.1) * (lambda - a.0) / (b.0 - a.0)
}

/// Schott Sellmeier coefficients (B1, B2, B3, C1, C2, C3 in µm²) of pbrt-v4's named glasses;
/// n²(λ) = 1 + Σ Bᵢ λ² / (λ² − Cᵢ), λ in µm.
const GLASSES: [(&str, [f64; 6]); 7] = [
    (
        "glass-BK7",
        [
            1.039_612_12,
            0.231_792_344,
            1.010_469_45,
            0.006_000_698_67,
            0.020_017_914_4,
            103.560_653,
        ],
    ),
    (
        "glass-BAF10",
        [
            1.585_149_5,
            0.143_559_385,
            1.085_212_69,
            0.009_266_812_82,
            0.042_448_980_5,
            105.613_573,
        ],
    ),
    (
        "glass-FK51A",
        [
            0.971_247_817,
            0.216_901_417,
            0.904_651_666,
            0.004_723_019_95,
            0.015_357_561_2,
            168.681_33,
        ],
    ),
    (
        "glass-LASF9",
        [
            2.000_295_47,
            0.298_926_886,
            1.806_918_43,
            0.012_142_601_7,
            0.053_873_623_6,
            156.530_829,
        ],
    ),
    (
        "glass-F5",
        [
            1.524_818_89,
            0.187_085_527,
            1.427_290_15,
            0.011_254_756,
            0.058_899_539_2,
            129.141_675,
        ],
    ),
    (
        "glass-F10",
        [
            1.621_539_02,
            0.256_287_842,
            1.644_475_52,
            0.012_224_145_7,
            0.059_573_677_5,
            147.468_793,
        ],
    ),
    (
        "glass-F11",
        [
            1.737_596_95,
            0.313_747_346,
            1.898_781_01,
            0.013_188_707,
            0.062_306_814_2,
            155.236_29,
        ],
    ),
];

fn sellmeier(c: &[f64; 6], lambda_nm: f32) -> f32 {
    let l2 = (lambda_nm as f64 * 1e-3).powi(2);
    let n2 = 1.0 + c[0] * l2 / (l2 - c[3]) + c[1] * l2 / (l2 - c[4]) + c[2] * l2 / (l2 - c[5]);
    n2.sqrt() as f32
}

/// pbrt-v4's name of a glass the pbrt importer also accepts under Schott's name (`glass-SF5` is
/// pbrt-v4's `glass-F5`, …) for a dielectric's η, which spectral rendering disperses
/// ([`glass_id`]; RGB takes `scene::pbrt`'s index at 587.56 nm for either name).
fn glass_alias(name: &str) -> &str {
    match name {
        "glass-SF5" => "glass-F5",
        "glass-SF10" => "glass-F10",
        "glass-SF11" => "glass-F11",
        n => n,
    }
}

/// η(λ) of a named glass (`glass-BK7`, `glass-BAF10`, `glass-FK51A`, `glass-LASF9`, `glass-F5`,
/// `glass-F10`, `glass-F11`).
pub fn glass_eta(name: &str, lambda: f32) -> Option<f32> {
    GLASSES
        .iter()
        .find(|g| g.0 == name)
        .map(|g| sellmeier(&g.1, lambda))
}

/// The single IOR Trayecto uses for a named glass: η weighted by D65ₙ ȳ over the visible range.
pub fn named_glass_ior(name: &str) -> Option<f32> {
    glass_eta(name, 550.0)?;
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for l in 360..=830 {
        let l = l as f32;
        let w = (d65(l) * cie_xyz(l).y) as f64;
        num += w * glass_eta(name, l)? as f64;
        den += w;
    }
    Some((num / den) as f32)
}

/// The metals pbrt-v4 names `metal-<X>-eta` / `metal-<X>-k` that Trayecto has tables for.
/// (pbrt-v4 also has `metal-CuZn`, not included: a scene using it gets a warning from the importer.)
pub const METALS: [&str; 6] = [
    "metal-Ag",
    "metal-Al",
    "metal-Au",
    "metal-Cu",
    "metal-MgO",
    "metal-TiO2",
];

/// A tabulated spectrum: (wavelength in nm, value) pairs in increasing wavelength.
type Table = &'static [(f32, f32)];

/// η and k tables of [`METALS`], in its order.
const METAL_TABLES: [(Table, Table); 6] = [
    (&data::AG_ETA, &data::AG_K),
    (&data::AL_ETA, &data::AL_K),
    (&data::AU_ETA, &data::AU_K),
    (&data::CU_ETA, &data::CU_K),
    (&data::MGO_ETA, &data::MGO_K),
    (&data::TIO2_ETA, &data::TIO2_K),
];

fn metal_tables(metal: &str) -> Option<(Table, Table)> {
    let i = METALS.iter().position(|&m| m == metal)?;
    Some(METAL_TABLES[i])
}

/// The id of a named metal spectrum (`metal-Au-eta`, `metal-Au-k`, …) in the id space of
/// [`BsdfSpectra`]: 2 · the metal's index in [`METALS`], + 1 for k.
pub fn tabulated_id(name: &str) -> Option<u16> {
    let (metal, part) = name.rsplit_once('-')?;
    let i = METALS.iter().position(|&m| m == metal)?;
    let k = match part {
        "eta" => 0,
        "k" => 1,
        _ => return None,
    };
    Some((2 * i + k) as u16)
}

/// The value at `lambda` nm of the named metal spectrum with id `id` ([`tabulated_id`]); 0 for
/// another id.
#[inline]
pub fn tabulated(id: u16, lambda: f32) -> f32 {
    match METAL_TABLES.get(id as usize / 2) {
        Some(&(eta, k)) => table(if id.is_multiple_of(2) { eta } else { k }, lambda),
        None => 0.0,
    }
}

/// First id of the named glasses in [`BsdfSpectra`]'s id space (after the metals' η and k).
const GLASS_BASE: u16 = 2 * METALS.len() as u16;
/// First id of the spectra a scene gives ([`BsdfSpectra::tables`]).
pub const TABLE_BASE: u16 = GLASS_BASE + GLASSES.len() as u16;

/// The spectra that BSDFs evaluate per wavelength in spectral rendering (a conductor's η and k,
/// a dielectric's η), each named by a `u16` id a `Copy` BSDF can carry: the built-in named
/// spectra first — the metals' η and k ([`tabulated_id`]), then the glasses ([`glass_id`],
/// their Sellmeier laws) — and from [`TABLE_BASE`] on the sampled spectra the scene gave
/// (pbrt's `"spectrum eta" [λ v …]`, a spectrum file), held by the world
/// ([`crate::world::World::bsdf_spectra`]) and added by the loader with
/// [`crate::scene::Scene::add_bsdf_spectrum`]. RGB rendering never reads it: the BSDFs carry
/// the RGB projections beside the ids.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BsdfSpectra {
    pub tables: std::sync::Arc<[SpectrumTable]>,
}

impl BsdfSpectra {
    /// The value of spectrum `id` at `lambda` nm; 0 for an id it does not hold.
    #[inline]
    pub fn value(&self, id: u16, lambda: f32) -> f32 {
        if id < GLASS_BASE {
            tabulated(id, lambda)
        } else if id < TABLE_BASE {
            sellmeier(&GLASSES[(id - GLASS_BASE) as usize].1, lambda)
        } else {
            self.tables
                .get((id - TABLE_BASE) as usize)
                .map_or(0.0, |t| at_1nm(&t.table, lambda))
        }
    }

    /// The values of spectrum `id` at the three wavelengths `lambda`.
    #[inline]
    pub fn eval3(&self, id: u16, lambda: Vec3) -> Vec3 {
        Vec3::new(
            self.value(id, lambda.x),
            self.value(id, lambda.y),
            self.value(id, lambda.z),
        )
    }
}

/// A conductor's η and k as spectra, which spectral rendering evaluates per wavelength
/// (pbrt-v4's conductor takes its `eta`/`k` spectra at the sampled wavelengths; the RGB path uses
/// their projections, [`named_conductor_rgb`]): each an id of [`BsdfSpectra`] (a named metal
/// spectrum or a sampled one), or `None` for one given as RGB, which is then upsampled from the
/// conductor's RGB value as pbrt-v4's `RGBUnboundedSpectrum`. `outside_ior` divides the
/// spectra, as under a coat (pbrt-v4 `CoatedConductorMaterial`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConductorSpectra {
    pub eta: Option<u16>,
    pub k: Option<u16>,
    pub outside_ior: f32,
}

impl ConductorSpectra {
    /// The spectra of `eta_name` and `k_name`, both named metal spectra, over air.
    pub fn named(eta_name: &str, k_name: &str) -> Option<ConductorSpectra> {
        Some(ConductorSpectra {
            eta: Some(tabulated_id(eta_name)?),
            k: Some(tabulated_id(k_name)?),
            outside_ior: 1.0,
        })
    }

    /// η and k at the three wavelengths `lambda`, relative to the outside medium; `rgb_eta` and
    /// `rgb_k` are the conductor's RGB values (already relative), upsampled for a part without
    /// a spectrum.
    #[inline]
    pub fn eta_k(
        &self,
        lambda: Vec3,
        spectra: &BsdfSpectra,
        rgb_eta: Vec3,
        rgb_k: Vec3,
    ) -> (Vec3, Vec3) {
        let at = |id: Option<u16>, rgb: Vec3| match id {
            Some(id) => spectra.eval3(id, lambda) / self.outside_ior,
            None => rgb2spec::unbounded(rgb, lambda),
        };
        (at(self.eta, rgb_eta), at(self.k, rgb_k))
    }
}

/// The id of a named glass (`glass-BK7`, …) in [`BsdfSpectra`]'s id space. pbrt-v4's
/// `glass-F5`/`-F10`/`-F11` are Schott's dense flints SF5, SF10, SF11, so the SF names
/// (which the pbrt importer accepts as well) are the same glasses.
pub fn glass_id(name: &str) -> Option<u16> {
    let name = glass_alias(name);
    GLASSES
        .iter()
        .position(|g| g.0 == name)
        .map(|i| GLASS_BASE + i as u16)
}

/// Value at `lambda` of a pbrt-v4 named spectrum: `metal-X-eta`, `metal-X-k`, `glass-*`,
/// `stdillum-D65`. None for a name Trayecto does not have.
pub fn named_spectrum(name: &str, lambda: f32) -> Option<f32> {
    if name == "stdillum-D65" {
        return Some(d65(lambda));
    }
    if let Some(eta) = glass_eta(name, lambda) {
        return Some(eta);
    }
    let (metal, part) = name.rsplit_once('-')?;
    let (eta, k) = metal_tables(metal)?;
    match part {
        "eta" => Some(table(eta, lambda)),
        "k" => Some(table(k, lambda)),
        _ => None,
    }
}

/// True if `name` is a spectrum [`named_spectrum`] knows.
pub fn is_named_spectrum(name: &str) -> bool {
    named_spectrum(name, 550.0).is_some()
}

/// A named spectrum as a reflectance-like RGB (how η, k, albedo spectra become RGB).
pub fn named_spectrum_rgb(name: &str) -> Option<Vec3> {
    is_named_spectrum(name).then(|| reflectance_to_rgb(|l| named_spectrum(name, l).unwrap_or(0.0)))
}

/// RGB η and k of a named metal (`metal-Cu`, …): each spectrum projected as a reflectance-like
/// spectrum under D65ₙ.
pub fn named_conductor_rgb(metal: &str) -> Option<(Vec3, Vec3)> {
    let (eta, k) = metal_tables(metal)?;
    Some((
        reflectance_to_rgb(|l| table(eta, l)),
        reflectance_to_rgb(|l| table(k, l)),
    ))
}

/// The RGB of the spectral Fresnel reflectance of η(λ) + i k(λ) at incidence cosine `cos`, seen
/// under D65ₙ: what pbrt-v4 renders for a smooth patch of that metal lit by white (rgb 1) light.
pub fn spectral_conductor_reflectance_rgb(
    eta: impl Fn(f32) -> f32,
    k: impl Fn(f32) -> f32,
    cos: f32,
) -> Vec3 {
    reflectance_to_rgb(|l| fresnel_complex(cos, eta(l), k(l)))
}

/// Largest per-channel absolute difference, over incidence angles 0–85°, between the spectral
/// reflectance of a named metal and the RGB Fresnel of its converted (η, k).
pub fn conductor_rgb_error(metal: &str) -> Option<f32> {
    let (eta, k) = metal_tables(metal)?;
    let (e_rgb, k_rgb) = named_conductor_rgb(metal)?;
    let mut worst = 0.0f32;
    for deg in (0..=85).step_by(5) {
        let c = (deg as f32).to_radians().cos();
        let spectral = spectral_conductor_reflectance_rgb(|l| table(eta, l), |l| table(k, l), c);
        let rgb = crate::material::microfacet::fresnel_conductor(c, e_rgb, k_rgb);
        worst = worst.max((spectral - rgb).abs().max_element());
    }
    Some(worst)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tabulated spectrum of one sample is that value at its wavelength and 0 elsewhere (as
    /// pbrt-v4's `PiecewiseLinearSpectrum`, which warns of it), not a panic.
    #[test]
    fn one_sample_table_is_nonzero_at_its_wavelength_only() {
        let t = [(360.0, 0.4)];
        assert_eq!(table(&t, 360.0), 0.4);
        assert_eq!(table(&t, 361.0), 0.0);
        assert_eq!(table(&t, 359.0), 0.0);
        assert_eq!(table(&[], 500.0), 0.0);
    }

    #[test]
    fn white_maps_to_white() {
        let w = reflectance_to_rgb(|_| 1.0);
        assert!((w - Vec3::ONE).abs().max_element() < 2e-3, "{w:?}");
        let d = illuminant_to_rgb(d65);
        assert!((d - Vec3::ONE).abs().max_element() < 2e-3, "{d:?}");
        // Equal-energy white has Y = 1 by the normalisation.
        assert!((spectrum_to_xyz(|_| 1.0).y - 1.0).abs() < 1e-5);
    }

    #[test]
    fn blackbody_is_planck_with_unit_peak() {
        for t in [2700.0f32, 6500.0] {
            let peak = 2.897_772e-3 / t * 1e9;
            assert!((blackbody(peak, t) - 1.0).abs() < 1e-4);
            assert!(blackbody(peak * 0.9, t) < 1.0 && blackbody(peak * 1.1, t) < 1.0);
        }
        // 2700 K is orange (r > g > b), 6500 K close to D65's white, 10000 K bluish.
        let warm = blackbody_rgb(2700.0);
        assert!(warm.x > warm.y && warm.y > warm.z, "{warm:?}");
        let d = blackbody_rgb(6504.0);
        assert!((d - Vec3::ONE).abs().max_element() < 0.06, "{d:?}");
        let cool = blackbody_rgb(10000.0);
        assert!(cool.z > cool.x, "{cool:?}");
    }

    #[test]
    fn glasses_match_their_catalogue_nd() {
        // Schott catalogue n_d at the helium d line, 587.56 nm.
        for (name, nd) in [
            ("glass-BK7", 1.5168),
            ("glass-BAF10", 1.6700),
            ("glass-FK51A", 1.4866),
            ("glass-LASF9", 1.8503),
            ("glass-F5", 1.6727),
            ("glass-F10", 1.7283),
            ("glass-F11", 1.7847),
        ] {
            let n = glass_eta(name, 587.56).unwrap();
            assert!((n - nd).abs() < 2e-4, "{name}: {n} vs {nd}");
            let ior = named_glass_ior(name).unwrap();
            assert!((ior - nd).abs() < 0.01, "{name}: {ior}");
        }
        assert!(glass_eta("glass-nope", 500.0).is_none());
    }

    #[test]
    fn named_metals_are_known_and_plausible() {
        for m in METALS {
            assert!(is_named_spectrum(&format!("{m}-eta")) && is_named_spectrum(&format!("{m}-k")));
        }
        // Copper and gold reflect red more than blue; silver and aluminium are nearly neutral.
        for m in ["metal-Cu", "metal-Au"] {
            let (e, k) = named_conductor_rgb(m).unwrap();
            let f0 = crate::material::microfacet::fresnel_conductor(1.0, e, k);
            assert!(f0.x > f0.y && f0.y > f0.z && f0.x > 0.85, "{m}: {f0:?}");
        }
        let (e, k) = named_conductor_rgb("metal-Ag").unwrap();
        let f0 = crate::material::microfacet::fresnel_conductor(1.0, e, k);
        assert!(f0.min_element() > 0.85, "{f0:?}");
        assert!(named_conductor_rgb("metal-CuZn").is_none());
    }

    /// Every id of the BSDF spectra names the spectrum it stands for: the metals' tables, the
    /// glasses' Sellmeier laws, then the scene's tables; an id past them is 0, not a panic.
    #[test]
    fn bsdf_spectra_ids_name_their_spectra() {
        let table = SpectrumTable::sampled(&[(400.0, 1.0), (700.0, 2.0)]).unwrap();
        let s = BsdfSpectra {
            tables: vec![table].into(),
        };
        for l in [380.0f32, 455.5, 550.0, 701.0, 829.0] {
            for m in METALS {
                for part in ["eta", "k"] {
                    let name = format!("{m}-{part}");
                    let id = tabulated_id(&name).unwrap();
                    assert!(id < GLASS_BASE);
                    assert_eq!(s.value(id, l), named_spectrum(&name, l).unwrap(), "{name}");
                }
            }
            for (sf, f) in [
                ("glass-SF5", "glass-F5"),
                ("glass-SF10", "glass-F10"),
                ("glass-SF11", "glass-F11"),
            ] {
                assert_eq!(glass_id(sf), glass_id(f), "{sf}");
            }
            for (g, _) in GLASSES {
                let id = glass_id(g).unwrap();
                assert!((GLASS_BASE..TABLE_BASE).contains(&id));
                assert_eq!(s.value(id, l), glass_eta(g, l).unwrap(), "{g}");
            }
            let want = if (400.0..=700.0).contains(&l) {
                1.0 + (l - 400.0) / 300.0
            } else {
                0.0
            };
            assert!((s.value(TABLE_BASE, l) - want).abs() < 1e-3, "{l}");
            assert_eq!(s.value(TABLE_BASE + 1, l), 0.0);
        }
        // One named and one RGB part: the RGB part is upsampled, the named one exact.
        let c = ConductorSpectra {
            eta: tabulated_id("metal-Au-eta"),
            k: None,
            outside_ior: 1.0,
        };
        let lambda = Vec3::new(450.0, 550.0, 650.0);
        let k = Vec3::new(2.0, 3.0, 4.0);
        let (e, kk) = c.eta_k(lambda, &s, Vec3::ONE, k);
        assert_eq!(e, s.eval3(tabulated_id("metal-Au-eta").unwrap(), lambda));
        assert_eq!(kk, rgb2spec::unbounded(k, lambda));
    }

    #[test]
    fn conductor_conversion_error_is_bounded() {
        for m in METALS {
            let e = conductor_rgb_error(m).unwrap();
            println!("{m}: max |spectral - rgb| reflectance = {e:.4}");
        }
        for m in ["metal-Cu", "metal-Au", "metal-Ag", "metal-Al"] {
            let e = conductor_rgb_error(m).unwrap();
            assert!(e < 0.05, "{m}: {e}");
        }
    }
}
