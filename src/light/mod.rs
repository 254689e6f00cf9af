//! Lights (thesis §5.1.12, §5.4.2, §5.4.4). Each light type owns its behaviour in its own file,
//! the way `material/bxdf/` does for BSDFs (pbrt-v4 `lights.h`): sampling toward a receiver and
//! its pdf (`sample_li`, `pdf_li`), the radiance it emits (`l` on a surface, `le` along an
//! escaping ray), emission sampling (`sample_le`, `pdf_le`: a ray leaving the light with its
//! position and direction densities) and its power (`phi`). [`Light`] is the dispatch enum;
//! [`LightSet`] ([`set`]) only chooses a light, by power or with the light BVH ([`bvh`]).

use crate::geometry::primitive::SurfaceHit;
use crate::geometry::{GeometryStore, Ray};
use crate::material::{Material, Texture};
use crate::math::{Frame, PI, Vec2, Vec3};
use crate::sampling::warp;

pub mod area;
pub mod bvh;
pub mod default_light;
pub mod directional;
pub mod emission;
pub mod environment;
pub mod envmap;
pub mod point;
pub mod set;
pub mod spot;
pub mod studio;
pub mod uniform;
pub use area::AreaLight;
pub use bvh::{LightBounds, LightBvh, TreeWidth};
pub use directional::DirectionalLight;
pub use environment::EnvironmentLight;
pub use envmap::{EnvMap, EnvMapping, EnvPdf};
pub use point::PointLight;
pub use set::{BVH_AUTO_THRESHOLD, LightSamplerKind, LightSet, MIN_REUSE_PMF};
pub use spot::{SpotLight, smoothstep, spot_falloff};
pub use uniform::{UniformLight, sample_uniform_env, uniform_env_pdf};

#[derive(Clone, Debug)]
pub enum Light {
    /// An emissive primitive.
    Area(AreaLight),
    Point(PointLight),
    Spot(SpotLight),
    /// Light arriving from direction `-direction` with irradiance `irradiance` on a perpendicular plane.
    Directional(DirectionalLight),
    /// Uniform radiance from all directions (ambient / default environment).
    Uniform(UniformLight),
    /// An importance-sampled environment map.
    Environment(EnvironmentLight),
}

/// What lights need from the scene to sample and evaluate themselves: area lights their
/// geometry, material and textures, lights at infinity the scene's bounding sphere (they emit
/// over its disk, pbrt-v4 `SampleLe`). [`LightSet::scene`] builds it.
#[derive(Clone, Copy)]
pub struct LightScene<'a> {
    pub geometry: &'a GeometryStore,
    pub materials: &'a [Material],
    pub textures: &'a [Texture],
    /// Bounding sphere of the scene.
    pub center: Vec3,
    pub radius: f32,
}

/// A sampled light point as seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point to the light.
    pub wi: Vec3,
    /// Incident radiance (or, for delta lights, intensity/d² or irradiance).
    pub li: Vec3,
    /// Solid-angle pdf of this sample given the chosen light (1 for delta lights).
    pub pdf: f32,
    /// Probability of having chosen this light.
    pub pmf: f32,
    pub delta: bool,
    /// Shadow ray from the shading point to the light point (or to infinity).
    pub shadow: Ray,
    /// Index of the light in its [`LightSet`], set by the set's sampling (`u32::MAX` from a
    /// light sampled on its own): what [`LightSet::emission_at`] finds the light's spectrum by.
    pub light: u32,
}

/// A ray leaving a light (pbrt-v4 `LightLeSample`): what light tracing, bidirectional methods
/// and photon mapping start their paths with.
#[derive(Clone, Copy, Debug)]
pub struct LeSample {
    /// Origin and unit direction of the emitted ray.
    pub ray: Ray,
    /// What the ray carries: radiance for area lights and lights at infinity, intensity (W/sr)
    /// for points and spots, irradiance for directional lights.
    pub le: Vec3,
    /// The normal at the origin: the emitting surface's geometric normal, the ray's direction
    /// for lights at infinity (their origin is on a disk facing it), zero for points and spots.
    pub n: Vec3,
    /// Density of the origin per unit area (1 for points and spots, a delta).
    pub pdf_pos: f32,
    /// Density of the direction per unit solid angle (1 for directional lights, a delta).
    pub pdf_dir: f32,
}

impl LeSample {
    /// |cos θ| between the ray and the normal at its origin (1 where the origin has none).
    #[inline]
    pub fn cos(&self) -> f32 {
        if self.n == Vec3::ZERO {
            1.0
        } else {
            self.n.dot(self.ray.d).abs()
        }
    }
}

/// What the raycast and Whitted models take from one light at a shading point
/// ([`Light::local_shading`]).
#[derive(Clone, Copy, Debug)]
pub enum LocalLight {
    /// Radiance from every direction, for an ambient term.
    Ambient(Vec3),
    /// A delta light's exact sample, to be shadow-tested.
    Direct(LightSample),
    /// Nothing from this light here (outside a spot's cone, at the light's position).
    None,
    /// An area light: estimated by sampling instead. Area lights come first in a scene's light
    /// list (`World::build`), so the lights before this one are all area lights too.
    Sampled,
}

impl Light {
    /// True for lights at infinity, which rays that escape the scene can "hit".
    pub fn is_infinite(&self) -> bool {
        matches!(
            self,
            Light::Uniform(_) | Light::Directional(_) | Light::Environment(_)
        )
    }

    /// True for lights that no BSDF sample can hit (points, spots, directions).
    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Light::Point(_) | Light::Spot(_) | Light::Directional(_)
        )
    }

    /// The area light, if this is one.
    #[inline]
    pub fn as_area(&self) -> Option<&AreaLight> {
        match self {
            Light::Area(a) => Some(a),
            _ => None,
        }
    }

    /// Precomputes what sampling needs (area lights, [`AreaLight::prepare`]).
    pub fn prepare(&mut self, geometry: &GeometryStore, materials: &[Material]) {
        if let Light::Area(a) = self {
            a.prepare(geometry, materials);
        }
    }

    /// A sample of this light seen from `hit` (pbrt-v4 `SampleLi`): the direction to it, the
    /// radiance arriving (intensity / d² or irradiance for delta lights), its solid-angle pdf
    /// and the shadow ray, offset along `n_offset`. An environment map is sampled from the
    /// density `env`, a uniform environment about `uniform_n` ([`sample_uniform_env`]). `pmf`
    /// is 1, for the caller that chose the light to set.
    #[inline]
    pub fn sample_li(
        &self,
        scene: &LightScene,
        hit: &SurfaceHit,
        n_offset: Vec3,
        u: Vec2,
        env: EnvPdf,
        uniform_n: Vec3,
    ) -> Option<LightSample> {
        match self {
            Light::Area(a) => a.sample_li(scene, hit, n_offset, u),
            Light::Point(l) => l.sample_li(hit.p, hit.p_error, n_offset),
            Light::Spot(l) => l.sample_li(hit.p, hit.p_error, n_offset),
            Light::Directional(l) => l.sample_li(hit.p, hit.p_error, n_offset),
            Light::Uniform(l) => l.sample_li(hit, n_offset, u, uniform_n),
            Light::Environment(l) => l.sample_li(hit, n_offset, u, env),
        }
    }

    /// The solid-angle pdf with which [`Light::sample_li`] from `p` gives the point `light_hit`
    /// on this light, times the probability `pmf()` of having chosen it (asked only when
    /// needed); 0 for lights that are not surfaces. A moving area light is taken where it is
    /// at `light_hit`'s time.
    #[inline]
    pub fn pdf_li(
        &self,
        geometry: &GeometryStore,
        p: Vec3,
        light_hit: &SurfaceHit,
        pmf: impl FnOnce() -> f32,
    ) -> f32 {
        match self {
            Light::Area(a) => a.pdf_li(geometry, p, light_hit, pmf),
            _ => 0.0,
        }
    }

    /// Radiance an area light emits at its point `hit` toward `w` (pbrt-v4 `L`); zero for the
    /// others.
    #[inline]
    pub fn l(&self, scene: &LightScene, hit: &SurfaceHit, w: Vec3) -> Vec3 {
        match self {
            Light::Area(a) => a.l(scene, hit, w),
            _ => Vec3::ZERO,
        }
    }

    /// Radiance arriving along an escaping ray's unit direction from `d` (pbrt-v4 `Le`), for
    /// the lights at infinity a ray can reach (uniform and image environments); `None` for the
    /// others.
    #[inline]
    pub fn le(&self, d: Vec3) -> Option<Vec3> {
        match self {
            Light::Uniform(l) => Some(l.radiance),
            Light::Environment(l) => Some(l.le(d)),
            _ => None,
        }
    }

    /// [`Light::le`] and the solid-angle pdf with which [`Light::sample_li`] (environment maps
    /// from `env`, a uniform environment about `uniform_n`) gives the direction `d`.
    #[inline]
    pub fn le_pdf(&self, d: Vec3, env: EnvPdf, uniform_n: Vec3) -> Option<(Vec3, f32)> {
        match self {
            Light::Uniform(l) => Some(l.le_pdf(d, uniform_n)),
            Light::Environment(l) => Some(l.le_pdf(d, env)),
            _ => None,
        }
    }

    /// Emission sampling (pbrt-v4 `SampleLe`): a ray leaving the light, its origin placed with
    /// `u1` and its direction with `u2` (for lights at infinity the other way round: direction
    /// with `u1`, origin on the scene's bounding disk with `u2`), with what it carries and the
    /// densities of both.
    pub fn sample_le(&self, scene: &LightScene, u1: Vec2, u2: Vec2) -> Option<LeSample> {
        match self {
            Light::Area(a) => a.sample_le(scene, u1, u2),
            Light::Point(l) => l.sample_le(u2),
            Light::Spot(l) => l.sample_le(u2),
            Light::Directional(l) => l.sample_le(scene, u2),
            Light::Uniform(l) => l.sample_le(scene, u1, u2),
            Light::Environment(l) => l.sample_le(scene, u1, u2),
        }
    }

    /// Position and direction densities (pbrt-v4 `PDF_Le`) with which [`Light::sample_le`]
    /// gives a ray leaving in direction `w` from a point of normal `n` (the emitter's normal
    /// for area lights; not used by the others). A delta in position or direction is reported
    /// as density 0.
    pub fn pdf_le(&self, scene: &LightScene, n: Vec3, w: Vec3) -> (f32, f32) {
        match self {
            Light::Area(a) => a.pdf_le(scene, n, w),
            Light::Point(l) => l.pdf_le(),
            Light::Spot(l) => l.pdf_le(w),
            Light::Directional(l) => l.pdf_le(scene),
            Light::Uniform(l) => l.pdf_le(scene),
            Light::Environment(l) => l.pdf_le(scene, w),
        }
    }

    /// Emitted power (pbrt-v4 `Phi`), RGB; lights at infinity through the scene's bounding disk.
    pub fn phi(&self, scene: &LightScene) -> Vec3 {
        match self {
            Light::Area(a) => a.phi(scene),
            Light::Point(l) => l.phi(),
            Light::Spot(l) => l.phi(),
            Light::Directional(l) => l.phi(scene),
            Light::Uniform(l) => l.phi(scene),
            Light::Environment(l) => l.phi(scene),
        }
    }

    /// The power the light sampler chooses lights by (luminance; a cheaper estimate than
    /// [`Light::phi`] for spots and textured emitters, kept as the sampler has always had it).
    /// An area light's texture is taken at `footprint_mean` if it was read, else at its mean in
    /// `texture_averages`.
    pub fn selection_power(
        &self,
        materials: &[Material],
        texture_averages: &[Vec3],
        footprint_mean: Option<Vec3>,
        scene_radius: f32,
    ) -> f32 {
        match self {
            Light::Area(a) => a.selection_power(materials, texture_averages, footprint_mean),
            Light::Point(l) => l.selection_power(),
            Light::Spot(l) => l.selection_power(),
            Light::Directional(l) => l.selection_power(scene_radius),
            Light::Uniform(l) => l.selection_power(scene_radius),
            Light::Environment(l) => l.selection_power(scene_radius),
        }
    }

    /// The light BVH's bounds of a bounded light of power `phi` (`None` for lights at infinity).
    pub fn bounds(
        &self,
        geometry: &GeometryStore,
        materials: &[Material],
        phi: f32,
    ) -> Option<LightBounds> {
        match self {
            Light::Area(a) => Some(a.bounds(geometry, materials, phi)),
            Light::Point(l) => Some(l.bounds(phi)),
            Light::Spot(l) => Some(l.bounds(phi)),
            Light::Directional(_) | Light::Uniform(_) | Light::Environment(_) => None,
        }
    }

    /// What the raycast and Whitted local models take from this light at `hit` with shading
    /// normal `ns` (shadow rays offset along `ng`): an ambient radiance for a uniform
    /// environment, and for an environment map the radiance it has along `ns` (a cheap stand-in
    /// for its irradiance: those models have no hemisphere integration); the exact sample of a
    /// delta light; [`LocalLight::Sampled`] for area lights.
    #[inline]
    pub fn local_shading(&self, hit: &SurfaceHit, ng: Vec3, ns: Vec3) -> LocalLight {
        let delta = |s: Option<LightSample>| s.map_or(LocalLight::None, LocalLight::Direct);
        match self {
            Light::Area(_) => LocalLight::Sampled,
            Light::Uniform(l) => LocalLight::Ambient(l.radiance),
            Light::Environment(l) => LocalLight::Ambient(l.le(ns)),
            Light::Point(l) => delta(l.sample_li(hit.p, hit.p_error, ng)),
            Light::Spot(l) => delta(l.sample_li(hit.p, hit.p_error, ng)),
            Light::Directional(l) => delta(l.sample_li(hit.p, hit.p_error, ng)),
        }
    }
}

/// Unit direction from `p` to `position` and the squared distance; `None` if they coincide.
#[inline]
fn toward(position: Vec3, p: Vec3) -> Option<(Vec3, f32)> {
    let to = position - p;
    let d2 = to.length_squared();
    if !(d2 > 0.0) {
        return None;
    }
    Some((to / d2.sqrt(), d2))
}

/// The origin of a ray of unit direction `d` emitted by a light at infinity: a point uniform on
/// the disk of the scene's bounding sphere (`center`, `radius`) perpendicular to `d`, moved
/// back by the radius so the ray starts outside the sphere (pbrt-v4
/// `UniformInfiniteLight::SampleLe`), and that point's density 1/πr².
#[inline]
fn disk_origin(center: Vec3, radius: f32, d: Vec3, u: Vec2) -> (Vec3, f32) {
    let frame = Frame::from_normal(d);
    let c = warp::concentric_disk(u);
    let on_disk = center + (frame.x * c.x + frame.y * c.y) * radius;
    (on_disk - d * radius, 1.0 / (PI * radius * radius))
}
