//! Participating media (thesis §2.10, the radiative transfer equation): what a ray meets
//! between surfaces. A medium is described in the scene by [`crate::scene::MediumDesc`] and compiled
//! here into [`Medium`]: absorption and scattering coefficients σa, σs (RGB, per unit world length),
//! a Henyey–Greenstein phase function ([`phase`]) and, for heterogeneous media, a density grid
//! ([`grid`]) that scales σa and σs point by point.
//!
//! Distances are sampled by delta tracking against a majorant σ_maj ≥ σt (Woodcock et al. 1965;
//! the null-scattering formulation of Miller, Georgiev and Jarosz 2019 as pbrt-v4 §14.1 uses it):
//! a homogeneous medium's majorant is σt itself, a grid's is σt times the bound of its
//! [`grid::MajorantGrid`] cell: 16³ cells over the grid's box, walked by a DDA, each holding the
//! largest density the trilinear lookup can return inside it (pbrt-v4 §11.4.3), so empty and
//! thin regions cost few or no null collisions (none happen outside the box).
//! [`Medium::sample_t_maj`] walks those majorant segments and hands every tentative collision to
//! the caller, who decides between absorption, real and null scattering.

pub mod grid;
pub mod phase;
pub mod world;

pub use grid::{DensityGrid, GridError};
pub use phase::HenyeyGreenstein;

use crate::geometry::Ray;
use crate::math::Vec3;
use crate::sampling::rng::Pcg32;

/// Local coefficients at a point of a medium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MediumProperties {
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
}

/// A medium's coefficients as one path carries them ([`Medium::coefficients`]): its RGB values,
/// or in spectral mode their values at the path's three wavelengths (docs/DESIGN.md "Spectral
/// rendering"). Made once per ray segment, so that the tracker and the emission lookups do not
/// upsample per collision.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
    /// The homogeneous emission `le`.
    pub le: Vec3,
    /// The wavelengths (nm), in spectral mode: grid emission is evaluated at them.
    pub lambda: Option<Vec3>,
}

/// A compiled medium: RGB coefficients per unit world length (already multiplied by the
/// description's `scale`), the phase function and an optional density grid.
#[derive(Clone, Debug)]
pub struct Medium {
    pub name: String,
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
    pub phase: HenyeyGreenstein,
    pub grid: Option<DensityGrid>,
    /// Emitted radiance: the medium adds σa(p)·Le per unit length (the RTE's emission term,
    /// pbrt-v4 §11.1.4); zero for most media.
    pub le: Vec3,
    /// Emission varying over the grid, added to `le` (pbrt-v4 `uniformgrid` `Lescale` and
    /// `temperature`).
    pub grid_le: Option<GridLe>,
    /// σa and σs as spectra, already × the scene's `scale` (`MediumDesc::sigma_spectra`): what
    /// [`Medium::coefficients`] takes at a path's wavelengths instead of upsampling the RGB.
    pub sigma_spectra: [Option<(crate::spectrum::SpectrumTable, f32)>; 2],
    /// `Le` as a spectrum (`MediumDesc::le_spectrum`): spectral rendering takes it at the
    /// path's wavelengths, scaled by the luminance of `le` ([`crate::spectrum::Illuminant::at`]).
    pub le_spectrum: Option<crate::spectrum::Illuminant>,
}

/// Compiled grid emission: Le(p) = scale(p) × (an RGB radiance, or a blackbody at T(p)), the
/// grids looked up in the density grid's unit cube with its edge rule (pbrt-v4
/// `GridMedium::SamplePoint`).
#[derive(Clone, Debug)]
pub struct GridLe {
    scale: crate::scene::VoxelGrid,
    source: LeSource,
    /// The spectrum of an RGB `Le` given as one (`MediumDesc::le_spectrum`).
    spectrum: Option<crate::spectrum::Illuminant>,
}

#[derive(Clone, Debug)]
enum LeSource {
    Rgb(Vec3),
    Blackbody {
        temperature: crate::scene::VoxelGrid,
        temperature_scale: f32,
        offset: f32,
        table: BlackbodyTable,
    },
}

/// Linear sRGB of the peak-normalised Planck spectrum (pbrt-v4 `BlackbodySpectrum`) tabulated
/// over [100 K, `t_hi`], so a lookup costs a lerp rather than an integral over the CIE curves
/// (the curve is smooth in T: at 4096 steps the lerp is within 10⁻⁴ relative, see the test).
#[derive(Clone, Debug)]
struct BlackbodyTable {
    t_hi: f32,
    rgb: Vec<Vec3>,
}

/// pbrt-v4 emits nothing from voxels at or below 100 K.
const BLACKBODY_MIN_K: f32 = 100.0;

impl BlackbodyTable {
    const N: usize = 4096;

    fn new(t_hi: f32) -> Self {
        let t_hi = t_hi.max(BLACKBODY_MIN_K + 1.0);
        let rgb = (0..Self::N)
            .map(|i| {
                let t =
                    BLACKBODY_MIN_K + (t_hi - BLACKBODY_MIN_K) * i as f32 / (Self::N - 1) as f32;
                crate::spectrum::blackbody_peak_rgb(t)
            })
            .collect();
        BlackbodyTable { t_hi, rgb }
    }

    #[inline]
    fn lookup(&self, t: f32) -> Vec3 {
        if !(t > BLACKBODY_MIN_K) {
            return Vec3::ZERO;
        }
        let x = ((t.min(self.t_hi) - BLACKBODY_MIN_K) / (self.t_hi - BLACKBODY_MIN_K))
            * (Self::N - 1) as f32;
        let i = (x as usize).min(Self::N - 2);
        let f = x - i as f32;
        self.rgb[i] + (self.rgb[i + 1] - self.rgb[i]) * f
    }
}

impl GridLe {
    fn new(e: &crate::scene::GridEmission, spectrum: Option<crate::spectrum::Illuminant>) -> Self {
        use crate::scene::GridEmission;
        match e {
            GridEmission::Radiance { le, scale } => GridLe {
                scale: scale.clone(),
                source: LeSource::Rgb(*le),
                spectrum,
            },
            GridEmission::Blackbody {
                temperature,
                scale,
                temperature_scale,
                offset,
            } => {
                // The hottest T the trilinear lookup can return (lerps stay within the voxels'
                // range, and the edge rule's zeros are lower still).
                let (lo, hi) = temperature
                    .data
                    .iter()
                    .fold((0.0f32, 0.0f32), |(a, b), &v| (a.min(v), b.max(v)));
                let t_hi =
                    ((lo - offset) * temperature_scale).max((hi - offset) * temperature_scale);
                GridLe {
                    scale: scale.clone(),
                    source: LeSource::Blackbody {
                        temperature: temperature.clone(),
                        temperature_scale: *temperature_scale,
                        offset: *offset,
                        table: BlackbodyTable::new(t_hi),
                    },
                    spectrum: None,
                }
            }
        }
    }

    /// Le at unit-cube point `q` of the grid: RGB, or at the wavelengths `lambda` (an RGB `Le`
    /// as an illuminant spectrum, a temperature as Planck's law itself, as pbrt-v4's
    /// `GridMedium::SamplePoint` evaluates them).
    #[inline]
    fn at(&self, q: Vec3, edge: grid::GridEdge, lambda: Option<Vec3>) -> Vec3 {
        let look =
            |g: &crate::scene::VoxelGrid| grid::trilinear(g.nx, g.ny, g.nz, &g.data, q, edge);
        let s = look(&self.scale);
        if !(s > 0.0) {
            return Vec3::ZERO;
        }
        match (&self.source, lambda) {
            (LeSource::Rgb(le), None) => *le * s,
            (LeSource::Rgb(le), Some(l)) => match &self.spectrum {
                Some(sp) => sp.at(*le, l) * s,
                None => crate::spectrum::rgb2spec::illuminant(*le, l) * s,
            },
            (
                LeSource::Blackbody {
                    temperature,
                    temperature_scale,
                    offset,
                    table,
                },
                lambda,
            ) => {
                let t = (look(temperature) - offset) * temperature_scale;
                match lambda {
                    None => table.lookup(t) * s,
                    // As the table: nothing at or below its lowest temperature, and the
                    // hottest voxel's value above its top.
                    Some(_) if !(t > BLACKBODY_MIN_K) => Vec3::ZERO,
                    Some(l) => crate::spectrum::blackbody_peak_spectral(l, t.min(table.t_hi)) * s,
                }
            }
        }
    }
}

/// One stretch of a ray with a constant majorant, ending at `t1` in the ray's (unit-speed)
/// parameter (it starts where the tracker is).
#[derive(Clone, Copy, Debug)]
struct MajorantSegment {
    t1: f32,
    sigma_maj: Vec3,
}

impl Medium {
    pub fn homogeneous(name: &str, sigma_a: Vec3, sigma_s: Vec3, g: f32) -> Medium {
        Medium {
            name: name.to_string(),
            sigma_a,
            sigma_s,
            phase: HenyeyGreenstein::new(g),
            grid: None,
            le: Vec3::ZERO,
            grid_le: None,
            sigma_spectra: [None, None],
            le_spectrum: None,
        }
    }

    /// Compiles a scene description (validated by `Scene::validate`).
    pub fn from_desc(desc: &crate::scene::MediumDesc) -> Result<Medium, GridError> {
        let mut m = Medium::homogeneous(
            &desc.name,
            desc.sigma_a * desc.scale,
            desc.sigma_s * desc.scale,
            desc.g,
        );
        m.le = desc.le;
        m.sigma_spectra = desc
            .sigma_spectra
            .clone()
            .map(|t| t.map(|t| (t, desc.scale)));
        m.le_spectrum = desc.le_spectrum.clone();
        if let crate::scene::MediumKind::Grid {
            nx,
            ny,
            nz,
            density,
            min,
            max,
            transform,
            edge,
            emission,
        } = &desc.kind
        {
            m.grid = Some(
                DensityGrid::new(
                    *nx,
                    *ny,
                    *nz,
                    density.clone(),
                    *transform * grid::box_to_world(*min, *max),
                )?
                .with_edge(*edge),
            );
            m.grid_le = emission
                .as_ref()
                .map(|e| GridLe::new(e, desc.le_spectrum.clone()));
        }
        Ok(m)
    }

    /// True if the medium emits anywhere.
    #[inline]
    pub fn is_emissive(&self) -> bool {
        self.le != Vec3::ZERO || self.grid_le.is_some()
    }

    /// Emitted radiance Le at world point `p` (the medium adds σa(p)·Le(p) per unit length).
    #[inline]
    pub fn le_at(&self, p: Vec3) -> Vec3 {
        self.le_in(&self.coefficients(None), p)
    }

    /// [`Medium::le_at`] as the path carrying `c` sees it (RGB or at its wavelengths).
    #[inline]
    pub fn le_in(&self, c: &Coefficients, p: Vec3) -> Vec3 {
        match (&self.grid_le, &self.grid) {
            (Some(e), Some(g)) => c.le + e.at(g.unit(p), g.edge, c.lambda),
            _ => c.le,
        }
    }

    /// The coefficients a path carries through this medium: the RGB ones (`lambda` `None`), or
    /// at the wavelengths `lambda`: σa and σs as pbrt-v4's unbounded spectra of their RGB
    /// (`RGBUnboundedSpectrum`; the scale is linear, so upsampling the scaled RGB is the same),
    /// `Le` as an illuminant spectrum (`RGBIlluminantSpectrum`) or the spectrum it was given as
    /// (`le_spectrum`; σa, σs likewise, `sigma_spectra`). A zero RGB stays zero, so an
    /// absorbing-only medium stays one.
    #[inline]
    pub fn coefficients(&self, lambda: Option<Vec3>) -> Coefficients {
        use crate::spectrum::rgb2spec::{illuminant, unbounded};
        match lambda {
            None => Coefficients {
                sigma_a: self.sigma_a,
                sigma_s: self.sigma_s,
                le: self.le,
                lambda: None,
            },
            Some(l) => Coefficients {
                sigma_a: match &self.sigma_spectra[0] {
                    Some((t, scale)) => t.eval3(l) * *scale,
                    None => unbounded(self.sigma_a, l),
                },
                sigma_s: match &self.sigma_spectra[1] {
                    Some((t, scale)) => t.eval3(l) * *scale,
                    None => unbounded(self.sigma_s, l),
                },
                le: match &self.le_spectrum {
                    Some(s) => s.at(self.le, l),
                    None => illuminant(self.le, l),
                },
                lambda: Some(l),
            },
        }
    }

    pub fn sigma_t(&self) -> Vec3 {
        self.sigma_a + self.sigma_s
    }

    /// True for a homogeneous medium that only absorbs: its transmittance is exact in closed
    /// form ([`Medium::analytic_transmittance`]) and the integrators never track through it.
    pub fn is_analytic(&self) -> bool {
        self.grid.is_none() && self.is_absorbing_only()
    }

    /// True if the medium only absorbs: then transmittance is applied analytically on every path
    /// (Beer–Lambert along the real path length), never sampled, so absorbing glass costs no noise.
    pub fn is_absorbing_only(&self) -> bool {
        self.sigma_s == Vec3::ZERO
    }

    /// Coefficients at world point `p`.
    #[inline]
    pub fn properties(&self, p: Vec3) -> MediumProperties {
        self.properties_in(self.sigma_a, self.sigma_s, p)
    }

    /// Coefficients at world point `p` of this medium's density with coefficients `sigma_a`,
    /// `sigma_s` (its own, or their spectral values).
    #[inline]
    fn properties_in(&self, sigma_a: Vec3, sigma_s: Vec3, p: Vec3) -> MediumProperties {
        match &self.grid {
            None => MediumProperties { sigma_a, sigma_s },
            Some(g) => {
                let d = g.density(p);
                MediumProperties {
                    sigma_a: sigma_a * d,
                    sigma_s: sigma_s * d,
                }
            }
        }
    }

    /// Transmittance along `ray` (unit direction) over `[0, t_max)` for an absorbing-only
    /// homogeneous medium, exp(−σt·d) per channel (Beer–Lambert). For other media the caller
    /// tracks (see [`Medium::sample_t_maj`]).
    #[inline]
    pub fn analytic_transmittance(&self, t_max: f32) -> Vec3 {
        self.analytic_transmittance_in(&self.coefficients(None), t_max)
    }

    /// [`Medium::analytic_transmittance`] with the coefficients `c` (RGB or spectral).
    #[inline]
    pub fn analytic_transmittance_in(&self, c: &Coefficients, t_max: f32) -> Vec3 {
        debug_assert!(self.grid.is_none());
        let st = c.sigma_a + c.sigma_s;
        if t_max.is_infinite() {
            return Vec3::select(st.cmpgt(Vec3::ZERO), Vec3::ZERO, Vec3::ONE);
        }
        (-st * t_max).exp()
    }

    /// Starts delta tracking against the majorant along `ray` (unit direction) over `[0, t_max)`,
    /// with distances sampled in channel `channel` (the hero channel); see [`Tracker`].
    #[inline]
    pub fn tracker(&self, ray: &Ray, t_max: f32, channel: usize) -> Tracker {
        self.tracker_in(&self.coefficients(None), ray, t_max, channel)
    }

    /// [`Medium::tracker`] with the coefficients `c` (RGB or spectral): the majorant is σt of
    /// `c` times the grid's bound, so in spectral mode every wavelength has its own and the hero
    /// channel's samples the distances (pbrt-v4's `SampleT_maj` with its `SampledSpectrum`
    /// majorant, §14.2.1).
    #[inline]
    pub fn tracker_in(&self, c: &Coefficients, ray: &Ray, t_max: f32, channel: usize) -> Tracker {
        let mut tr = Tracker {
            o: ray.o,
            d: ray.d,
            t: 0.0,
            seg: None,
            dda: None,
            t_maj: Vec3::ONE,
            channel,
            sigma_a: c.sigma_a,
            sigma_s: c.sigma_s,
        };
        let sigma_t = c.sigma_a + c.sigma_s;
        match &self.grid {
            None => {
                tr.seg = Some(MajorantSegment {
                    t1: t_max,
                    sigma_maj: sigma_t,
                });
            }
            Some(g) => {
                let (o, d) = g.to_unit(ray);
                if let Some((t0, t1)) = grid::clip_unit(o, d, t_max) {
                    tr.t = t0;
                    let mut dda = grid::Dda::new(o, d, t0, t1);
                    tr.seg = next_segment(&mut dda, g, sigma_t);
                    tr.dda = Some(dda);
                }
            }
        }
        tr
    }

    /// Delta tracking with a callback, in the shape of pbrt-v4's `SampleT_maj` (§14.2.1): for each
    /// tentative collision the callback receives (point, local coefficients, σ_maj, T_maj since
    /// the previous collision) and returns whether to go on. Returns T_maj from the last
    /// collision to `t_max` (all ones if the callback stopped the walk).
    pub fn sample_t_maj(
        &self,
        ray: &Ray,
        t_max: f32,
        channel: usize,
        rng: &mut Pcg32,
        mut callback: impl FnMut(Vec3, MediumProperties, Vec3, Vec3) -> bool,
    ) -> Vec3 {
        let mut tr = self.tracker(ray, t_max, channel);
        loop {
            match tr.step(self, rng) {
                TrackStep::End { t_maj } => return t_maj,
                TrackStep::Collision {
                    p,
                    props,
                    sigma_maj,
                    t_maj,
                } => {
                    if !callback(p, props, sigma_maj, t_maj) {
                        return Vec3::ONE;
                    }
                }
            }
        }
    }
}

/// One step of delta tracking.
#[derive(Clone, Copy, Debug)]
pub enum TrackStep {
    /// A tentative collision at `p`; `t_maj` is exp(−σ_maj·s) over the free flight `s` that led
    /// to it (per channel).
    Collision {
        p: Vec3,
        props: MediumProperties,
        sigma_maj: Vec3,
        t_maj: Vec3,
    },
    /// The walk passed the end of the ray; `t_maj` is exp(−σ_maj·s) over the last stretch.
    End { t_maj: Vec3 },
}

/// Delta-tracking state along one ray: free flights s ~ σ_maj[h]·exp(−σ_maj[h]·s) in the hero
/// channel h, so the flight's pdf is σ_maj[h]·T_maj[h] and reaching the end has probability
/// T_maj[h]. The caller turns each collision into absorption, scattering or a null collision.
///
/// The majorant is piecewise constant along the ray: one segment for a homogeneous medium, one
/// per majorant-grid cell for a grid (walked by [`grid::Dda`]). At a segment's end the flight is
/// sampled afresh against the next segment's majorant (the exponential is memoryless, so this
/// is exact: pbrt-v4's `SampleT_maj`, §14.2.1), and T_maj accumulates over the segments crossed.
#[derive(Clone, Copy, Debug)]
pub struct Tracker {
    o: Vec3,
    d: Vec3,
    t: f32,
    seg: Option<MajorantSegment>,
    dda: Option<grid::Dda>,
    /// exp(−∫σ_maj) since the last collision, over the segments already left.
    t_maj: Vec3,
    channel: usize,
    /// The coefficients tracked with ([`Coefficients`]): the medium's RGB ones or their
    /// spectral values.
    sigma_a: Vec3,
    sigma_s: Vec3,
}

/// The next non-empty stretch of a grid's majorant walk.
#[inline]
fn next_segment(dda: &mut grid::Dda, g: &DensityGrid, sigma_t: Vec3) -> Option<MajorantSegment> {
    let (_, t1, bound) = dda.next(&g.majorants)?;
    Some(MajorantSegment {
        t1,
        sigma_maj: sigma_t * bound,
    })
}

impl Tracker {
    #[inline]
    pub fn step(&mut self, medium: &Medium, rng: &mut Pcg32) -> TrackStep {
        loop {
            let Some(seg) = self.seg else {
                let t_maj = self.t_maj;
                self.t_maj = Vec3::ONE;
                return TrackStep::End { t_maj };
            };
            let sm = seg.sigma_maj;
            let sh = sm[self.channel];
            if sh > 0.0 {
                let u = rng.next_f32();
                // Exponential sample; 1 − u is in (0, 1].
                let step = -(1.0 - u).ln() / sh;
                let t_next = self.t + step;
                if t_next < seg.t1 {
                    self.t = t_next;
                    let p = self.o + self.d * t_next;
                    let t_maj = self.t_maj * (-sm * step).exp();
                    self.t_maj = Vec3::ONE;
                    return TrackStep::Collision {
                        p,
                        props: medium.properties_in(self.sigma_a, self.sigma_s, p),
                        sigma_maj: sm,
                        t_maj,
                    };
                }
            }
            // Past the segment's end (or nothing can happen in the hero channel there; the
            // other channels still attenuate by exp(−σ_maj·d)): on to the next segment.
            self.t_maj *= exp_segment(sm, seg.t1 - self.t);
            self.t = seg.t1;
            self.seg = match (&mut self.dda, &medium.grid) {
                (Some(dda), Some(g)) => next_segment(dda, g, self.sigma_a + self.sigma_s),
                _ => None,
            };
        }
    }
}

/// exp(−σ·d) per channel, with an infinite `d` giving 0 where σ > 0 and 1 where σ = 0.
#[inline]
fn exp_segment(sigma: Vec3, d: f32) -> Vec3 {
    if d.is_infinite() {
        Vec3::select(sigma.cmpgt(Vec3::ZERO), Vec3::ZERO, Vec3::ONE)
    } else {
        (-sigma * d).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ratio tracking (Novák et al. 2014) built on `sample_t_maj`: T = Π σn/σ_maj × T_maj(end)/…,
    /// here in the single-channel form, to check the walk against the analytic transmittance.
    fn ratio_tracking(m: &Medium, ray: &Ray, t_max: f32, channel: usize, rng: &mut Pcg32) -> f32 {
        let mut tr = 1.0f32;
        m.sample_t_maj(ray, t_max, channel, rng, |_, mp, sm, _| {
            let sn = sm[channel] - mp.sigma_a[channel] - mp.sigma_s[channel];
            tr *= (sn / sm[channel]).max(0.0);
            tr > 0.0
        });
        tr
    }

    #[test]
    fn homogeneous_slab_transmittance_is_beer_lambert_per_channel() {
        // Chromatic: each channel has its own σt; analytic exp(−σt d).
        let m = Medium::homogeneous(
            "slab",
            Vec3::new(0.2, 0.5, 1.5),
            Vec3::new(0.1, 0.0, 0.5),
            0.3,
        );
        let d = 1.7;
        let want = (-m.sigma_t() * d).exp();
        // Probability of crossing without a collision, estimated by the free-flight sampler of
        // each channel: the fraction of walks that reach the end must be exp(−σt[c]·d).
        let ray = Ray::new(Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.0, 0.6, 0.8));
        let mut rng = Pcg32::new(7, 1);
        let n = 200_000;
        for c in 0..3 {
            let mut passed = 0u32;
            for _ in 0..n {
                let mut hit = false;
                m.sample_t_maj(&ray, d, c, &mut rng, |_, _, _, _| {
                    hit = true;
                    false
                });
                passed += u32::from(!hit);
            }
            let est = passed as f32 / n as f32;
            let sd = (want[c] * (1.0 - want[c]) / n as f32).sqrt();
            assert!(
                (est - want[c]).abs() < 5.0 * sd + 1e-6,
                "channel {c}: crossing fraction {est}, Beer–Lambert {}",
                want[c]
            );
        }
        // The T_maj returned for an event-free walk is the analytic transmittance of the rest.
        let absorbing = Medium::homogeneous("abs", Vec3::new(0.3, 0.9, 2.0), Vec3::ZERO, 0.0);
        let t = absorbing.analytic_transmittance(d);
        assert!(
            (t - (-Vec3::new(0.3, 0.9, 2.0) * d).exp())
                .abs()
                .max_element()
                < 1e-6
        );
    }

    /// With the majorant grid, a ray through the empty part of a grid that is dense elsewhere
    /// meets no tentative collisions at all (a global majorant would give about σt·max·length
    /// of them), and the walk still ends with T_maj = 1 there.
    #[test]
    fn empty_cells_cost_no_collisions() {
        let n = 16;
        let mut data = vec![0.0f32; n * n * n];
        // A dense block in the corner x, y, z < 4/16 of the box.
        for z in 0..4 {
            for y in 0..4 {
                for x in 0..4 {
                    data[(z * n + y) * n + x] = 50.0;
                }
            }
        }
        let mut m = Medium::homogeneous("g", Vec3::splat(0.5), Vec3::splat(1.5), 0.0);
        m.grid = Some(DensityGrid::new(n, n, n, data, crate::math::Mat4::IDENTITY).unwrap());
        let mut rng = Pcg32::new(9, 2);
        // Along x at y = z = 0.7: far from the block.
        let ray = Ray::new(Vec3::new(-1.0, 0.7, 0.7), Vec3::X);
        let mut collisions = 0;
        let t = m.sample_t_maj(&ray, 3.0, 1, &mut rng, |_, _, _, _| {
            collisions += 1;
            true
        });
        assert_eq!(collisions, 0);
        assert_eq!(t, Vec3::ONE);
        // Through the block: collisions do happen (σt·density = 100 per unit length).
        let ray = Ray::new(Vec3::new(-1.0, 0.1, 0.1), Vec3::X);
        let mut collisions = 0;
        m.sample_t_maj(&ray, 3.0, 1, &mut rng, |_, _, _, _| {
            collisions += 1;
            collisions < 1000
        });
        assert!(
            collisions > 5,
            "{collisions} collisions through the dense block"
        );
    }

    #[test]
    fn grid_ratio_tracking_matches_quadrature_of_the_density() {
        // A 4×3×5 grid with a ramp in x: ratio tracking's mean must equal exp(−∫σt ds) computed by
        // fine quadrature of the same trilinear density.
        let (nx, ny, nz) = (4, 3, 5);
        let mut data = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    data.push(0.2 + 0.3 * x as f32 + 0.1 * ((y + z) % 2) as f32);
                }
            }
        }
        let grid = DensityGrid::new(
            nx,
            ny,
            nz,
            data,
            crate::math::Mat4::from_scale_rotation_translation(
                Vec3::new(2.0, 1.0, 1.5),
                glam::Quat::IDENTITY,
                Vec3::new(-1.0, -0.5, -0.75),
            ),
        )
        .unwrap();
        let mut m = Medium::homogeneous("g", Vec3::splat(0.8), Vec3::splat(0.6), 0.0);
        m.grid = Some(grid);
        let ray = Ray::new(
            Vec3::new(-2.0, -0.2, 0.1),
            Vec3::new(1.0, 0.1, -0.05).normalize(),
        );
        let t_max = 3.5;
        // Quadrature: midpoint rule with 20 000 steps.
        let steps = 20_000;
        let dt = t_max / steps as f32;
        let mut tau = 0.0f64;
        for i in 0..steps {
            let p = ray.at((i as f32 + 0.5) * dt);
            tau += (m.properties(p).sigma_a.x + m.properties(p).sigma_s.x) as f64 * dt as f64;
        }
        let want = (-tau).exp();
        assert!(
            want > 0.05 && want < 0.9,
            "test needs a mid-range T, got {want}"
        );
        let mut rng = Pcg32::new(3, 5);
        let n = 100_000;
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let t = ratio_tracking(&m, &ray, t_max, 0, &mut rng) as f64;
            sum += t;
            sum2 += t * t;
        }
        let mean = sum / n as f64;
        let sd = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
        assert!(
            (mean - want).abs() < 5.0 * sd + 1e-4,
            "ratio tracking {mean} ± {sd}, quadrature {want}"
        );
    }

    /// The blackbody table against the direct CIE integral, across the range a flame uses.
    #[test]
    fn blackbody_table_matches_the_integral() {
        let table = BlackbodyTable::new(6000.0);
        assert_eq!(table.lookup(100.0), Vec3::ZERO);
        assert_eq!(table.lookup(50.0), Vec3::ZERO);
        for t in [450.0f32, 900.0, 1234.5, 1800.0, 2500.0, 4000.0, 5999.0] {
            let want = crate::spectrum::blackbody_peak_rgb(t);
            let got = table.lookup(t);
            let err = ((got - want).abs() / want.abs().max(Vec3::splat(1e-12))).max_element();
            assert!(err < 1e-3, "{t} K: table {got} vs integral {want}");
        }
        // Peak-normalised, not luminance-normalised: 1000 K is far dimmer than 3000 K (pbrt-v4
        // `BlackbodySpectrum` is 1 at its peak, which moves into the infrared as T falls).
        let y = |c: Vec3| 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
        assert!(y(table.lookup(1000.0)) < 0.01 * y(table.lookup(3000.0)));
    }

    /// Grid emission: Le(p) = Lescale(p)·Le, read in the density grid's unit cube with its edge
    /// rule; a temperature grid gives the blackbody of T = (t − offset)·scale.
    #[test]
    fn grid_emission_follows_the_scale_and_temperature_grids() {
        use crate::scene::{GridEdge, GridEmission, MediumDesc, MediumKind, VoxelGrid};
        let mut desc = MediumDesc::homogeneous("e", Vec3::ONE, Vec3::ZERO, 1.0, 0.0);
        desc.kind = MediumKind::Grid {
            nx: 1,
            ny: 1,
            nz: 1,
            density: vec![1.0],
            min: Vec3::ZERO,
            max: Vec3::splat(2.0),
            transform: crate::math::Mat4::IDENTITY,
            edge: GridEdge::Zero,
            emission: Some(GridEmission::Radiance {
                le: Vec3::new(1.0, 2.0, 3.0),
                scale: VoxelGrid {
                    nx: 2,
                    ny: 1,
                    nz: 1,
                    data: vec![0.0, 4.0],
                },
            }),
        };
        let m = Medium::from_desc(&desc).unwrap();
        assert!(m.is_emissive());
        // World (1.5, 1, 1) is unit (0.75, 0.5, 0.5): the second voxel's centre.
        assert!(
            (m.le_at(Vec3::new(1.5, 1.0, 1.0)) - Vec3::new(4.0, 8.0, 12.0))
                .abs()
                .max_element()
                < 1e-5
        );
        assert_eq!(m.le_at(Vec3::new(0.5, 1.0, 1.0)), Vec3::ZERO);
        assert_eq!(m.le_at(Vec3::new(3.0, 1.0, 1.0)), Vec3::ZERO);
        if let MediumKind::Grid { emission, .. } = &mut desc.kind {
            *emission = Some(GridEmission::Blackbody {
                temperature: VoxelGrid::single(1100.0),
                scale: VoxelGrid::single(2.0),
                temperature_scale: 2.0,
                offset: 100.0,
            });
        }
        let m = Medium::from_desc(&desc).unwrap();
        // At the centre: T = (1100 − 100)·2 = 2000 K, scale 2 (both 1×1×1 grids are 1 there).
        let want = crate::spectrum::blackbody_peak_rgb(2000.0) * 2.0;
        let got = m.le_at(Vec3::splat(1.0));
        assert!(
            ((got - want).abs() / want).max_element() < 1e-3,
            "{got} vs {want}"
        );
    }
}
