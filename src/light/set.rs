//! The lights of a scene and how a light is chosen for next-event estimation: in proportion to
//! power, or by the light BVH's importance from the receiver (pbrt-v4 `PowerLightSampler`,
//! `BVHLightSampler`). Once chosen, the light samples and evaluates itself ([`Light`]).

use super::bvh::{LightBounds, LightBvh, TreeWidth};
use super::envmap::EnvPdf;
use super::{Light, LightSample, LightScene};
use crate::geometry::primitive::SurfaceHit;
use crate::geometry::{Bounds3, GeometryStore};
use crate::material::{Material, Texture};
use crate::math::{Vec2, Vec3};
use crate::sampling::Distribution1D;
use crate::spectrum::{Illuminant, Wavelengths};

/// How next-event estimation chooses a light (`--light-sampler`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LightSamplerKind {
    /// [`LightSamplerKind::Bvh8`] when the scene has more than [`BVH_AUTO_THRESHOLD`] bounded
    /// lights, else [`LightSamplerKind::Power`].
    #[default]
    Auto,
    /// In proportion to each light's power, wherever the shading point is.
    Power,
    /// The light BVH ([`bvh`]) for emitters, points and spots by their importance from the
    /// shading point; lights at infinity beside it in proportion to power. Four children per
    /// tree node ([`TreeWidth::Four`]).
    Bvh,
    /// [`LightSamplerKind::Bvh`] with eight children per tree node ([`TreeWidth::Eight`]):
    /// fewer, wider descent steps and tighter boxes per choice; `auto`'s tree (BENCHMARKS.md,
    /// light choice and defaults).
    Bvh8,
}

/// Above this many bounded lights (emissive primitives, points, spots) `auto` uses the light BVH.
/// See BENCHMARKS.md ("Many lights") for the measurement behind it.
pub const BVH_AUTO_THRESHOLD: usize = 16;

impl LightSamplerKind {
    pub const NAMES: [&'static str; 4] = ["auto", "power", "bvh", "bvh8"];

    pub fn name(self) -> &'static str {
        match self {
            LightSamplerKind::Auto => "auto",
            LightSamplerKind::Power => "power",
            LightSamplerKind::Bvh => "bvh",
            LightSamplerKind::Bvh8 => "bvh8",
        }
    }
}

impl std::str::FromStr for LightSamplerKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(LightSamplerKind::Auto),
            "power" => Ok(LightSamplerKind::Power),
            "bvh" => Ok(LightSamplerKind::Bvh),
            "bvh8" => Ok(LightSamplerKind::Bvh8),
            _ => Err(format!(
                "unknown light sampler '{s}' (expected one of: {})",
                Self::NAMES.join(", ")
            )),
        }
    }
}

/// All lights of a scene and how next-event estimation chooses one of them.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    pub lights: Vec<Light>,
    /// In proportion to power over all lights (the `power` sampler).
    pub distribution: Distribution1D,
    /// The light BVH and the lights at infinity beside it (the `bvh` sampler); `None` with the
    /// `power` sampler.
    tree: Option<TreeSelection>,
    /// Indices of lights at infinity.
    pub infinite: Vec<u32>,
    /// Scene bounding sphere (for infinite light powers and far-away shadow rays).
    pub scene_center: Vec3,
    pub scene_radius: f32,
    /// Each light's selection power, the weights of `distribution` and `tree` (kept so that
    /// [`LightSet::replace`] can choose again after one light changed).
    powers: Vec<f32>,
    /// The emission spectra of lights given as spectra ([`LightSet::set_spectra`]), and per light
    /// 1 + its index there, 0 for an RGB light; empty when every light is RGB.
    spectra: Vec<Illuminant>,
    spectrum_of: Vec<u16>,
    /// The moving point, spot and directional lights of a motion-blurred world
    /// ([`LightSet::set_motion`]); `None` for a still.
    motion: Option<Box<LightMotion>>,
}

/// Point, spot and directional lights that move during the shutter: each one's position and
/// direction at `keys` evenly spaced times over it (key k at u = k / (keys − 1)), interpolated
/// linearly between the two keys around a sample's time, as a moving mesh's vertices are
/// (`geometry::motion`); a direction is renormalised (it follows a rotation's arc by chords).
/// A light is placed at the time of the ray that samples it ([`LightSet::posed`]); everything
/// else about it (intensity, cone, power) does not move, so choosing by power is unchanged and
/// the light BVH bounds a moving light by the union of its keys' bounds.
#[derive(Clone, Debug, Default)]
pub struct LightMotion {
    /// Keys over the shutter (at least 2).
    pub keys: usize,
    /// Per light of the set: its index into `poses` / `keys`, or `u32::MAX` if it does not move.
    pub slot: Vec<u32>,
    /// Moving light m's key k at `m * keys + k`: (position, unit direction); the direction of a
    /// point light and the position of a directional one are not read.
    pub poses: Vec<(Vec3, Vec3)>,
}

impl LightMotion {
    /// Light `index`'s position and direction at shutter time `u`, if it moves.
    #[inline]
    fn at(&self, index: usize, u: f32) -> Option<(Vec3, Vec3)> {
        let s = *self.slot.get(index)?;
        if s == u32::MAX {
            return None;
        }
        // The key segment holding u, as `MotionStore::segment`.
        let n = self.keys - 1;
        let x = u.clamp(0.0, 1.0) * n as f32;
        let k = (x as usize).min(n - 1);
        let f = x - k as f32;
        let a = self.poses[s as usize * self.keys + k];
        if f == 0.0 {
            return Some(a);
        }
        let b = self.poses[s as usize * self.keys + k + 1];
        let d = (a.1 * (1.0 - f) + b.1 * f).normalize_or(a.1);
        Some((a.0 * (1.0 - f) + b.0 * f, d))
    }

    /// `light` placed at key `k`'s pose (the light BVH's bounds take every key's).
    fn key(&self, light: &Light, index: usize, k: usize) -> Option<Light> {
        let s = *self.slot.get(index)?;
        (s != u32::MAX).then(|| place(light, self.poses[s as usize * self.keys + k]))
    }
}

/// `light` at position `p` facing `d` (points and spots at `p`, spots and directional lights
/// along `d`); other lights unchanged.
#[inline]
fn place(light: &Light, (p, d): (Vec3, Vec3)) -> Light {
    match light {
        Light::Point(l) => Light::Point(super::PointLight { position: p, ..*l }),
        Light::Spot(l) => Light::Spot(super::SpotLight {
            position: p,
            direction: d,
            ..*l
        }),
        Light::Directional(l) => Light::Directional(super::DirectionalLight { direction: d, ..*l }),
        other => other.clone(),
    }
}

/// Light selection with the light BVH (pbrt-v4's `BVHLightSampler`): a light at infinity with
/// probability `p_infinite` (their share of the power; pbrt splits evenly by count instead),
/// chosen among them by power; otherwise a bounded light by the tree.
#[derive(Clone, Debug)]
struct TreeSelection {
    bvh: LightBvh,
    /// Over `LightSet::infinite`, by power.
    infinite: Distribution1D,
    p_infinite: f32,
    /// Per light: its index in `LightSet::infinite`, or `u32::MAX`.
    infinite_slot: Vec<u32>,
}

/// The least choice probability for which [`LightSet::sample_reuse`] reuses the remapped choice
/// number: 2^-12, so the remapped number keeps at least 12 of u's 24 bits.
pub const MIN_REUSE_PMF: f32 = 1.0 / 4096.0;

impl LightSet {
    pub fn new(
        lights: Vec<Light>,
        geometry: &GeometryStore,
        materials: &[Material],
        textures: &[Texture],
        bounds: Bounds3,
        footprint_means: &[Option<Vec3>],
        kind: LightSamplerKind,
    ) -> LightSet {
        let (scene_center, scene_radius) = bounds.bounding_sphere();
        let scene_radius = scene_radius.max(1e-3);
        let mut lights = lights;
        for light in &mut lights {
            light.prepare(geometry, materials);
        }
        // Average of each emissive texture, once per texture rather than once per triangle.
        let mut texture_averages = vec![Vec3::ONE; textures.len()];
        for m in materials {
            if let Some(t) = &m.emissive_texture
                && let (Some(a), Some(tex)) =
                    (texture_averages.get_mut(t.texture), textures.get(t.texture))
            {
                *a = tex.average().truncate();
            }
        }
        let powers: Vec<f32> = lights
            .iter()
            .enumerate()
            .map(|(i, l)| {
                l.selection_power(
                    materials,
                    &texture_averages,
                    footprint_means.get(i).copied().flatten(),
                    scene_radius,
                )
            })
            .collect();
        let infinite: Vec<u32> = lights
            .iter()
            .enumerate()
            .filter(|(_, l)| l.is_infinite())
            .map(|(i, _)| i as u32)
            .collect();
        let bounded = lights.iter().filter(|l| !l.is_infinite()).count();
        let use_tree = match kind {
            LightSamplerKind::Power => false,
            LightSamplerKind::Bvh | LightSamplerKind::Bvh8 => true,
            LightSamplerKind::Auto => bounded > BVH_AUTO_THRESHOLD,
        };
        let width = match kind {
            LightSamplerKind::Bvh8 | LightSamplerKind::Auto => TreeWidth::Eight,
            LightSamplerKind::Bvh | LightSamplerKind::Power => TreeWidth::Four,
        };
        let tree = use_tree.then(|| {
            TreeSelection::over(
                &lights, &powers, &infinite, geometry, materials, width, None,
            )
        });
        LightSet {
            distribution: Distribution1D::new(&powers),
            tree,
            lights,
            infinite,
            scene_center,
            scene_radius,
            powers,
            spectra: Vec::new(),
            spectrum_of: Vec::new(),
            motion: None,
        }
    }

    /// Makes the lights `motion.slot` marks move over the shutter ([`LightMotion`]): they are
    /// placed at each sample's time, and the light BVH (if any) is rebuilt over the union of
    /// each moving light's bounds at its keys.
    pub fn set_motion(
        &mut self,
        motion: LightMotion,
        geometry: &GeometryStore,
        materials: &[Material],
    ) {
        debug_assert!(motion.keys >= 2 && motion.slot.len() == self.lights.len());
        self.motion = Some(Box::new(motion));
        self.rebuild_tree(geometry, materials);
    }

    /// True when a point, spot or directional light moves during the shutter
    /// ([`LightSet::set_motion`]; emitters on moving primitives move with the geometry).
    #[inline]
    pub fn moves(&self) -> bool {
        self.motion.is_some()
    }

    /// True when light `index` moves during the shutter (it has keys of its own).
    #[inline]
    pub fn light_moves(&self, index: usize) -> bool {
        self.motion
            .as_ref()
            .is_some_and(|m| m.slot.get(index).is_some_and(|&s| s != u32::MAX))
    }

    /// Light `index` where it is at shutter time `time` (itself unless it moves): every light
    /// sample, emitted ray and density of a motion-blurred sample takes its light from here, at
    /// the time its rays carry. An emitter on a moving primitive is the area light placed at
    /// `time` ([`super::AreaLight::at`]: its point, area and emitted rays are its shape's then).
    #[inline]
    pub fn posed(&self, index: usize, time: f32) -> std::borrow::Cow<'_, Light> {
        let light = &self.lights[index];
        if let Light::Area(a) = light {
            return if a.moves() {
                std::borrow::Cow::Owned(Light::Area(a.at(time)))
            } else {
                std::borrow::Cow::Borrowed(light)
            };
        }
        match self.motion.as_ref().and_then(|m| m.at(index, time)) {
            Some(pose) => std::borrow::Cow::Owned(place(light, pose)),
            None => std::borrow::Cow::Borrowed(light),
        }
    }

    fn rebuild_tree(&mut self, geometry: &GeometryStore, materials: &[Material]) {
        if let Some(t) = &self.tree {
            let width = t.bvh.width();
            self.tree = Some(TreeSelection::over(
                &self.lights,
                &self.powers,
                &self.infinite,
                geometry,
                materials,
                width,
                self.motion.as_deref(),
            ));
        }
    }

    /// Gives light `i` the emission spectrum `spectra[i]` (`None`: RGB). Spectral rendering then
    /// evaluates that spectrum at its wavelengths ([`LightSet::emission_at`]); RGB rendering does
    /// not read it.
    pub fn set_spectra(&mut self, spectra: &[Option<Illuminant>]) {
        self.spectra.clear();
        self.spectrum_of.clear();
        if spectra.iter().all(Option::is_none) {
            return;
        }
        for s in spectra {
            let tag = match s {
                None => 0,
                Some(s) => match self.spectra.iter().position(|t| t == s) {
                    Some(k) => k + 1,
                    None => {
                        self.spectra.push(s.clone());
                        self.spectra.len()
                    }
                },
            };
            self.spectrum_of.push(u16::try_from(tag).unwrap_or(0));
        }
    }

    /// The emission spectrum of light `light`, if it was given one.
    #[inline]
    pub fn spectrum(&self, light: u32) -> Option<&Illuminant> {
        let tag = *self.spectrum_of.get(light as usize)?;
        tag.checked_sub(1).map(|k| &self.spectra[k as usize])
    }

    /// Light `light`'s emission `rgb` at the wavelengths `w`: its spectrum scaled to `rgb`'s
    /// luminance when it has one ([`Illuminant::at`]), else `rgb` upsampled as an RGB illuminant
    /// (pbrt-v4 `RGBIlluminantSpectrum`).
    #[inline]
    pub fn emission_at(&self, light: u32, rgb: Vec3, w: &Wavelengths) -> Vec3 {
        match self.spectrum(light) {
            Some(s) => s.at(rgb, w.lambda),
            None => crate::spectrum::rgb2spec::illuminant(rgb, w.lambda),
        }
    }

    /// [`LightSet::escaped`] at the wavelengths `w`: each light at infinity's radiance taken
    /// through [`LightSet::emission_at`].
    #[inline]
    pub fn escaped_at(&self, d: Vec3, w: &Wavelengths) -> Vec3 {
        let mut l = Vec3::ZERO;
        for &i in &self.infinite {
            if let Some(le) = self.lights[i as usize].le(d) {
                l += self.emission_at(i, le, w);
            }
        }
        l
    }

    /// Replaces light `i`, a point, spot, directional or ambient light, by `light` (the same
    /// kind; another power, colour or place) and chooses lights by the new powers: the set is
    /// then the one [`LightSet::new`] makes with `light` in place, the sampler kind it resolved
    /// kept. Area lights are the world's triangles and are not replaced here.
    pub fn replace(
        &mut self,
        i: usize,
        light: Light,
        geometry: &GeometryStore,
        materials: &[Material],
    ) {
        debug_assert!(!matches!(light, Light::Area(_)), "area lights are geometry");
        // Only area lights read texture averages and footprints.
        self.powers[i] = light.selection_power(materials, &[], None, self.scene_radius);
        // The new light's RGB is all there is of it now.
        if let Some(tag) = self.spectrum_of.get_mut(i) {
            *tag = 0;
        }
        self.lights[i] = light;
        self.distribution = Distribution1D::new(&self.powers);
        self.rebuild_tree(geometry, materials);
    }

    /// What the lights need from the scene to sample and evaluate themselves.
    #[inline]
    pub fn scene<'a>(
        &self,
        geometry: &'a GeometryStore,
        materials: &'a [Material],
        textures: &'a [Texture],
    ) -> LightScene<'a> {
        LightScene {
            geometry,
            materials,
            textures,
            center: self.scene_center,
            radius: self.scene_radius,
        }
    }

    /// Which sampler chooses the lights: `Power`, `Bvh` or `Bvh8` (never `Auto`).
    pub fn sampler_kind(&self) -> LightSamplerKind {
        match &self.tree {
            Some(t) if t.bvh.width() == TreeWidth::Eight => LightSamplerKind::Bvh8,
            Some(_) => LightSamplerKind::Bvh,
            None => LightSamplerKind::Power,
        }
    }

    /// Chooses a light for a receiver at `p` with normal `n` (zero in a medium) with `u`: its
    /// index and the probability of having chosen it (positive).
    #[inline]
    pub fn choose(&self, p: Vec3, n: Vec3, u: f32) -> Option<(usize, f32)> {
        self.choose_remap(p, n, u)
            .map(|(index, pmf, _)| (index, pmf))
    }

    /// [`Self::choose`] that also returns `u` remapped within the chosen light's share of
    /// [0, 1): uniform again given the choice, so it can place the point on the light.
    #[inline]
    pub fn choose_remap(&self, p: Vec3, n: Vec3, u: f32) -> Option<(usize, f32, f32)> {
        match &self.tree {
            None => {
                let (index, pmf, rest) = self.distribution.sample_discrete_remap(u);
                (pmf > 0.0).then_some((index, pmf, rest))
            }
            Some(t) => t.choose(&self.infinite, p, n, u),
        }
    }

    /// Probability that [`LightSet::choose`] from (`p`, `n`) picks light `index`.
    #[inline]
    pub fn pmf(&self, index: u32, p: Vec3, n: Vec3) -> f32 {
        match &self.tree {
            None => self.distribution.discrete_pdf(index as usize),
            Some(t) => t.pmf(index, p, n),
        }
    }

    /// Probability of choosing light `index`, a light at infinity (which does not depend on the
    /// receiver).
    #[inline]
    fn pmf_infinite(&self, index: u32) -> f32 {
        match &self.tree {
            None => self.distribution.discrete_pdf(index as usize),
            Some(t) => t.pmf_infinite(index),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Picks a light (by power, or by the light BVH from `hit.p` and `n_offset`) and samples a
    /// point/direction on it as seen from `hit`. `n_offset` is also the receiver's normal for
    /// the light BVH's importance (zero for a point in a medium). A uniform environment is
    /// sampled over the whole sphere ([`Self::sample_reuse`] can take a hemisphere).
    #[allow(clippy::too_many_arguments)]
    pub fn sample(
        &self,
        scene: &LightScene,
        hit: &SurfaceHit,
        n_offset: Vec3,
        u_light: f32,
        u: Vec2,
        env: EnvPdf,
    ) -> Option<LightSample> {
        if self.lights.is_empty() {
            return None;
        }
        let (index, pmf) = self.choose(hit.p, n_offset, u_light)?;
        self.sample_chosen(scene, hit, n_offset, index, pmf, u, env, Vec3::ZERO)
    }

    /// [`Self::sample`] with the light chosen by `u.x` and the point placed on it by `u.x`
    /// remapped within the light's share of [0, 1), and `u.y` (sample reuse: Mitsuba 3's
    /// `Scene::sample_emitter_direction`; PBRT-v4 §A.1 `SampleDiscrete`'s `uRemapped`). A 2D
    /// stratified or low-discrepancy point is thereby split among the lights by the x-ranges
    /// they are chosen with, and each light gets a stratified set of points of its own; with the
    /// choice from a number of its own, a light gets a random subset of the 2D points, whose
    /// stratification is largely lost. Given the choice, the remapped x is uniform and
    /// independent of `u.y`, so the estimator is the same. A light chosen with probability under
    /// [`MIN_REUSE_PMF`] would get a remapped x of fewer than 12 bits (`u.x` has 24): it gets
    /// `u_spare` (an independent uniform number) instead, which is just as uniform. A uniform
    /// environment is sampled about `uniform_n` ([`super::sample_uniform_env`]; zero for the sphere).
    #[allow(clippy::too_many_arguments)]
    pub fn sample_reuse(
        &self,
        scene: &LightScene,
        hit: &SurfaceHit,
        n_offset: Vec3,
        u: Vec2,
        u_spare: f32,
        env: EnvPdf,
        uniform_n: Vec3,
    ) -> Option<LightSample> {
        if self.lights.is_empty() {
            return None;
        }
        let (index, pmf, rest) = self.choose_remap(hit.p, n_offset, u.x)?;
        let x = if pmf >= MIN_REUSE_PMF { rest } else { u_spare };
        let u = Vec2::new(x, u.y);
        self.sample_chosen(scene, hit, n_offset, index, pmf, u, env, uniform_n)
    }

    /// Samples light `index`, chosen with probability `pmf`, with `u`; an environment map
    /// from the density `env`, a uniform environment about `uniform_n` ([`super::sample_uniform_env`]).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn sample_chosen(
        &self,
        scene: &LightScene,
        hit: &SurfaceHit,
        n_offset: Vec3,
        index: usize,
        pmf: f32,
        u: Vec2,
        env: EnvPdf,
        uniform_n: Vec3,
    ) -> Option<LightSample> {
        // A moving light where it is at the receiver's moment.
        let ls = self
            .posed(index, hit.time)
            .sample_li(scene, hit, n_offset, u, env, uniform_n)?;
        Some(LightSample {
            pmf,
            light: index as u32,
            ..ls
        })
    }

    /// Solid-angle pdf with which NEE would have sampled the point `light_hit` on area light
    /// `index` from `p` with normal `n` (the `n_offset` given to [`LightSet::sample`]), selection
    /// probability included, for MIS of BSDF-sampled hits.
    /// A moving emitter is taken where it is at `light_hit`'s time.
    #[inline]
    pub fn pdf_area(
        &self,
        geometry: &GeometryStore,
        index: u32,
        p: Vec3,
        n: Vec3,
        light_hit: &SurfaceHit,
    ) -> f32 {
        self.lights[index as usize].pdf_li(geometry, p, light_hit, || self.pmf(index, p, n))
    }

    /// Radiance from the lights at infinity along an escaping ray direction `d` (unit), unweighted
    /// (what a camera ray or a path without NEE sees).
    #[inline]
    pub fn escaped(&self, d: Vec3) -> Vec3 {
        let mut l = Vec3::ZERO;
        for &i in &self.infinite {
            if let Some(le) = self.lights[i as usize].le(d) {
                l += le;
            }
        }
        l
    }

    /// The lights at infinity along an escaping BSDF- or phase-sampled direction `d` (unit), for
    /// MIS: `contribution(le, pdf)` is called once per light with that light's radiance and the
    /// solid-angle pdf with which NEE samples `d` from *that* light (selection included;
    /// environment maps from the density `env`), and the results are summed. Each light is
    /// weighed against its own NEE density because NEE estimates one light at a time (Veach
    /// 1997, §9.2: the weights of a direction must sum to one per integrand, here per light); the
    /// sum of the radiances weighed against the sum of the pdfs is biased when two lights at
    /// infinity overlap, e.g. a scene's uniform background and an `--env` map (−1.5 % on a
    /// diffuse quad). pbrt-v4's path integrator loops over its infinite lights the same way.
    /// A uniform environment's density is [`super::uniform_env_pdf`] about `uniform_n`: the normal NEE
    /// sampled it about at the vertex the direction left (zero: the sphere).
    #[inline]
    pub fn escaped_mis(
        &self,
        d: Vec3,
        env: EnvPdf,
        uniform_n: Vec3,
        mut contribution: impl FnMut(Vec3, f32) -> Vec3,
    ) -> Vec3 {
        self.escaped_mis_each(d, env, uniform_n, |_, le, pdf| contribution(le, pdf))
    }

    /// [`LightSet::escaped_mis`] with the index of each light passed to `contribution(light, le,
    /// pdf)` as well (spectral rendering looks its spectrum up, [`LightSet::emission_at`]).
    #[inline]
    pub fn escaped_mis_each(
        &self,
        d: Vec3,
        env: EnvPdf,
        uniform_n: Vec3,
        mut contribution: impl FnMut(u32, Vec3, f32) -> Vec3,
    ) -> Vec3 {
        let mut l = Vec3::ZERO;
        for &i in &self.infinite {
            let Some((le, pdf)) = self.lights[i as usize].le_pdf(d, env, uniform_n) else {
                continue;
            };
            let pdf = self.pmf_infinite(i) * pdf;
            if le != Vec3::ZERO {
                l += contribution(i, le, pdf);
            }
        }
        l
    }
}

impl TreeSelection {
    /// The light BVH over the bounded `lights` weighted by `powers`, and the lights at infinity;
    /// a light that moves (`motion`) bounded over all its keys (the union of their boxes and
    /// cones, its power counted once).
    fn over(
        lights: &[Light],
        powers: &[f32],
        infinite: &[u32],
        geometry: &GeometryStore,
        materials: &[Material],
        width: TreeWidth,
        motion: Option<&LightMotion>,
    ) -> TreeSelection {
        let lb: Vec<(u32, LightBounds)> = lights
            .iter()
            .enumerate()
            .zip(powers)
            .filter_map(|((i, l), &phi)| {
                let b = l.bounds(geometry, materials, phi)?;
                let Some(m) = motion.filter(|m| m.slot.get(i).is_some_and(|&s| s != u32::MAX))
                else {
                    return Some((i as u32, b));
                };
                let mut all: Option<LightBounds> = None;
                for k in 0..m.keys {
                    let kb = m.key(l, i, k)?.bounds(geometry, materials, phi)?;
                    all = Some(match all {
                        None => kb,
                        Some(a) => LightBounds {
                            phi,
                            ..a.union(&kb)
                        },
                    });
                }
                all.map(|a| (i as u32, a))
            })
            .collect();
        TreeSelection::new(
            LightBvh::with_width(&lb, lights.len(), width),
            infinite,
            powers,
        )
    }

    fn new(bvh: LightBvh, infinite: &[u32], powers: &[f32]) -> TreeSelection {
        let inf_powers: Vec<f32> = infinite.iter().map(|&i| powers[i as usize]).collect();
        let p_inf_power: f64 = inf_powers
            .iter()
            .filter(|p| p.is_finite() && **p > 0.0)
            .map(|&p| p as f64)
            .sum();
        let tree_power = bvh.total_power as f64;
        let p_infinite = if infinite.is_empty() {
            0.0
        } else if bvh.is_empty() {
            1.0
        } else if p_inf_power + tree_power > 0.0 {
            (p_inf_power / (p_inf_power + tree_power)) as f32
        } else {
            0.5
        };
        let mut infinite_slot = vec![u32::MAX; powers.len()];
        for (k, &i) in infinite.iter().enumerate() {
            infinite_slot[i as usize] = k as u32;
        }
        TreeSelection {
            bvh,
            infinite: Distribution1D::new(&inf_powers),
            p_infinite,
            infinite_slot,
        }
    }

    #[inline]
    fn choose(&self, infinite: &[u32], p: Vec3, n: Vec3, u: f32) -> Option<(usize, f32, f32)> {
        if u < self.p_infinite {
            let u = (u / self.p_infinite).min(1.0 - f32::EPSILON / 2.0);
            let (k, pmf, rest) = self.infinite.sample_discrete_remap(u);
            let pmf = pmf * self.p_infinite;
            return (pmf > 0.0).then_some((infinite[k] as usize, pmf, rest));
        }
        let p_tree = 1.0 - self.p_infinite;
        let u = ((u - self.p_infinite) / p_tree).min(1.0 - f32::EPSILON / 2.0);
        let (light, pmf, rest) = self.bvh.sample_remap(p, n, u)?;
        let pmf = pmf * p_tree;
        (pmf > 0.0).then_some((light as usize, pmf, rest))
    }

    #[inline]
    fn pmf_infinite(&self, index: u32) -> f32 {
        match self.infinite_slot.get(index as usize) {
            Some(&k) if k != u32::MAX => self.p_infinite * self.infinite.discrete_pdf(k as usize),
            _ => 0.0,
        }
    }

    #[inline]
    fn pmf(&self, index: u32, p: Vec3, n: Vec3) -> f32 {
        match self.infinite_slot.get(index as usize) {
            Some(&k) if k != u32::MAX => self.p_infinite * self.infinite.discrete_pdf(k as usize),
            Some(_) => (1.0 - self.p_infinite) * self.bvh.pmf(index, p, n),
            None => 0.0,
        }
    }
}
