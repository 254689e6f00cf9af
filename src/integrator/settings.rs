//! The settings of the path tracers (`path.rs`, `volpath.rs`) and of the direct lighting they
//! share (`direct.rs`): depth, Russian roulette, NEE and MIS, first-hit splitting and the
//! camera's footprint. Below all three, so that none of them imports another for it.

use crate::light::EnvPdf;
use crate::math::Vec3;

/// The bounce limit every front end starts from (the command line, the web page, the library).
pub const DEFAULT_MAX_DEPTH: u32 = 64;

#[derive(Clone, Copy, Debug)]
pub struct PathSettings {
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Russian roulette keeps a path with probability min(1, rr_scale · max β · η²), so paths
    /// whose throughput is above 1/rr_scale always continue. PBRT-v4's q = max β (scale 1, §14.1.2)
    /// is calibrated for a pixel as bright as the light arriving at the path's vertex; a pixel is
    /// that light times the albedo of the surface the camera sees, so scale 1 cuts paths whose
    /// contribution still matters. On the Cornell box it added 60 % to the error of uncut paths
    /// (64 spp relMSE 0.00378 against 0.00235); scales 2–4 give the best error per ray traced
    /// (scale 3: 0.00252 at 6.5 rays per sample instead of 0.00378 at 5.5, 26 % more efficient),
    /// and the directly lit Veach scene does not change. Measured by `bench/rr_efficiency.py`.
    pub rr_scale: f32,
    pub nee: bool,
    pub mis: bool,
    /// Continuation paths split at the first hit (the thesis's "rayos secundarios").
    pub secondary: u32,
    /// The camera's pixel footprint for filtered texture lookups; set by the renderer when
    /// the world was built with `--texture-filter trilinear`, off (`Default`) otherwise.
    pub footprint: crate::camera::Footprint,
    /// Most a sample's direct light may add (per colour channel's largest value; infinity: no
    /// clamp): light seen by the camera or reaching it after one scattering event. Biased, like
    /// Cycles' *Clamp Direct*: it darkens what it cuts.
    pub clamp_direct: f32,
    /// The same for light that scattered two or more times (Cycles' *Clamp Indirect*): removes
    /// the fireflies of caustic paths through glass at preview sample counts; biased.
    pub clamp_indirect: f32,
    /// Camera rays that hit nothing add no radiance (Cycles' *Film › Transparent*): the image
    /// is then premultiplied by the coverage the `alpha` layer holds. Light from the
    /// environment still reaches the scene.
    pub transparent: bool,
    /// Render spectrally (`--spectral`, docs/DESIGN.md "Spectral rendering"): each camera sample
    /// carries three wavelengths in the lanes of its `Vec3` radiance, and RGB quantities are
    /// upsampled where they enter the path. Off: linear sRGB, as always.
    pub spectral: bool,
    /// The wavelengths of the sample being traced: set by the path tracers on their own copy of
    /// the settings at the start of each spectral sample, `None` in RGB mode (and in the
    /// settings the renderer hands them).
    pub wavelengths: Option<crate::spectrum::Wavelengths>,
}

impl Default for PathSettings {
    fn default() -> Self {
        PathSettings {
            max_depth: DEFAULT_MAX_DEPTH,
            rr_depth: 3,
            rr_scale: 3.0,
            nee: true,
            mis: true,
            secondary: 1,
            footprint: Default::default(),
            clamp_direct: f32::INFINITY,
            clamp_indirect: f32::INFINITY,
            transparent: false,
            spectral: false,
            wavelengths: None,
        }
    }
}

impl PathSettings {
    /// `c`, a contribution of a path that scattered `bounces` times before reaching the camera,
    /// scaled down (hue kept) so that its largest channel is at most the clamp for that depth:
    /// [`PathSettings::clamp_direct`] up to one bounce, [`PathSettings::clamp_indirect`] beyond.
    /// Unclamped (infinite) settings return `c` unchanged, bit for bit.
    #[inline(always)]
    pub fn clamp(&self, c: Vec3, bounces: u32) -> Vec3 {
        let max = if bounces <= 1 {
            self.clamp_direct
        } else {
            self.clamp_indirect
        };
        let m = c.max_element();
        if m > max { c * (max / m) } else { c }
    }

    /// Light `light`'s emission `rgb` (a light index of the world's [`crate::light::LightSet`],
    /// a hit's `light`, `u32::MAX` for none) as the path carries it: unchanged in RGB mode; in
    /// spectral mode at the sample's wavelengths, from the light's own spectrum when the scene
    /// gave one (a blackbody, a named or sampled illuminant), else upsampled as an RGB illuminant
    /// ([`crate::light::LightSet::emission_at`]).
    #[inline(always)]
    pub fn light_emission(&self, lights: &crate::light::LightSet, light: u32, rgb: Vec3) -> Vec3 {
        match &self.wavelengths {
            None => rgb,
            Some(w) => lights.emission_at(light, rgb, w),
        }
    }

    /// The lights at infinity along a camera ray's unit direction `d` as the path carries them
    /// ([`crate::world::World::escaped`] in RGB mode, each light at the sample's wavelengths in
    /// spectral mode).
    #[inline(always)]
    pub fn escaped(&self, world: &crate::world::World, d: Vec3) -> Vec3 {
        match &self.wavelengths {
            None => world.escaped(d),
            Some(w) => world.lights.escaped_at(d, w),
        }
    }

    /// The settings for one camera sample: in spectral mode, a copy carrying the wavelengths
    /// drawn from `s` (one extra sampler dimension, taken before the path's); in RGB mode `None`
    /// and nothing is drawn.
    #[inline(always)]
    pub fn for_sample(
        &self,
        s: &mut impl crate::sampling::mlt::UniformSource,
    ) -> Option<PathSettings> {
        self.spectral.then(|| PathSettings {
            wavelengths: Some(crate::spectrum::Wavelengths::sample(s.next_1d())),
            ..*self
        })
    }

    /// The RGB a sample's radiance `l` adds to the film: `l` in RGB mode, its wavelengths'
    /// projection in spectral mode ([`crate::spectrum::Wavelengths::to_rgb`]).
    #[inline(always)]
    pub fn to_film(&self, l: Vec3) -> Vec3 {
        match &self.wavelengths {
            None => l,
            Some(w) => w.to_rgb(l),
        }
    }

    /// The environment-map density next-event estimation draws from, and that BSDF-sampled
    /// escapes weigh their MIS against: the MIS-compensated one when light samples are combined
    /// with BSDF sampling by MIS (which then finds the directions it leaves out, with weight 1),
    /// the full one when light samples must reach every direction on their own (MIS off; with
    /// NEE off no light is sampled and the choice does not matter).
    #[inline]
    pub fn env_pdf(&self) -> EnvPdf {
        if self.nee && self.mis {
            EnvPdf::Compensated
        } else {
            EnvPdf::Full
        }
    }
}
