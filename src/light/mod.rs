//! Lights and light sampling for next-event estimation (thesis §5.1.12, §5.4.2, §5.4.4).
//! Area lights are the emissive primitives themselves, sampled uniformly by area and converted to
//! solid angle (PBRT eq. 4.9 / §12.2); a light is first chosen in proportion to its power.

use crate::geometry::primitive::{PrimRef, PrimitiveKind, SurfaceHit};
use crate::geometry::sample::{sample_sphere_cone, sphere_cone};
use crate::geometry::{Bounds3, GeometryStore, Ray};
use crate::material::eval::emitted;
use crate::material::{Material, Texture};
use crate::math::{Frame, PI, Vec2, Vec3, luminance};
use crate::sampling::{Distribution1D, warp};
use crate::scene::SpotFalloff;
use std::sync::Arc;

pub mod bvh;
pub mod default_light;
pub mod emission;
pub mod envmap;
pub mod equal_area;
pub use bvh::{LightBounds, LightBvh, TreeWidth};
pub use envmap::{EnvMap, EnvMapping, EnvPdf};

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
    /// "Session 14: light choice" and "Session 15: defaults").
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

#[derive(Clone, Debug)]
pub enum Light {
    /// An emissive primitive.
    Area {
        prim: PrimRef,
        material: u32,
    },
    Point {
        position: Vec3,
        intensity: Vec3,
    },
    Spot {
        position: Vec3,
        /// Unit direction the spot points to.
        direction: Vec3,
        intensity: Vec3,
        cos_inner: f32,
        cos_outer: f32,
        falloff: SpotFalloff,
    },
    /// Light arriving from direction `-direction` with irradiance `irradiance` on a perpendicular plane.
    Directional {
        direction: Vec3,
        irradiance: Vec3,
    },
    /// Uniform radiance from all directions (ambient / default environment).
    Uniform {
        radiance: Vec3,
    },
    /// An importance-sampled equirectangular environment map.
    Environment {
        map: Arc<EnvMap>,
    },
}

impl Light {
    /// True for lights at infinity, which rays that escape the scene can "hit".
    pub fn is_infinite(&self) -> bool {
        matches!(
            self,
            Light::Uniform { .. } | Light::Directional { .. } | Light::Environment { .. }
        )
    }

    /// True for lights that no BSDF sample can hit (points, spots, directions).
    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Light::Point { .. } | Light::Spot { .. } | Light::Directional { .. }
        )
    }

    /// A light sample of a delta light (point, spot, directional) seen from `p` (error bound
    /// `p_error`, shadow rays offset along `n_offset`): the direction to it, its intensity / d²
    /// (with the spot falloff) or irradiance, pdf 1 and the shadow ray. `pmf` is 1, for the
    /// caller to set. `None` for other lights and for points the light does not reach.
    pub fn sample_delta(&self, p: Vec3, p_error: Vec3, n_offset: Vec3) -> Option<LightSample> {
        match self {
            Light::Point {
                position,
                intensity,
            } => {
                let (wi, d2) = toward(*position, p)?;
                Some(LightSample {
                    wi,
                    li: *intensity / d2,
                    pdf: 1.0,
                    pmf: 1.0,
                    delta: true,
                    shadow: Ray::spawn_to(p, p_error, n_offset, *position, Vec3::ZERO, wi),
                })
            }
            Light::Spot {
                position,
                direction,
                intensity,
                cos_inner,
                cos_outer,
                falloff,
            } => {
                let (wi, d2) = toward(*position, p)?;
                let falloff = falloff.eval(direction.dot(-wi), *cos_inner, *cos_outer);
                if falloff <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    li: *intensity * (falloff / d2),
                    pdf: 1.0,
                    pmf: 1.0,
                    delta: true,
                    shadow: Ray::spawn_to(p, p_error, n_offset, *position, Vec3::ZERO, wi),
                })
            }
            Light::Directional {
                direction,
                irradiance,
            } => {
                let wi = -*direction;
                let mut shadow = Ray::spawn(p, p_error, n_offset, wi);
                shadow.t_max = f32::INFINITY;
                Some(LightSample {
                    wi,
                    li: *irradiance,
                    pdf: 1.0,
                    pmf: 1.0,
                    delta: true,
                    shadow,
                })
            }
            Light::Area { .. } | Light::Uniform { .. } | Light::Environment { .. } => None,
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

/// NEE's direction toward a uniform environment ([`Light::Uniform`]) from a receiver whose
/// integrand can only be non-zero in the hemisphere of the unit normal `n`, and its solid-angle
/// pdf: cosine-weighted about `n` (Malley's method, pdf cos θ / π, PBRT §13.6.3), so no sample
/// points below the surface. With `n` zero (a point in a medium, a BSDF that transmits, or NEE
/// not combined with BSDF sampling by MIS) it is uniform over the whole sphere, pdf 1 / 4π.
/// `None` for the rare sample whose direction rounds onto the horizon (pdf 0 there).
/// [`uniform_env_pdf`] is its density, which MIS of escaping BSDF samples must use.
#[inline]
pub fn sample_uniform_env(n: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
    if n == Vec3::ZERO {
        return Some((warp::uniform_sphere(u), warp::UNIFORM_SPHERE_PDF));
    }
    let wi = Frame::from_normal(n).to_world(warp::cosine_hemisphere(u));
    let pdf = uniform_env_pdf(n, wi);
    (pdf > 0.0).then_some((wi, pdf))
}

/// The density of [`sample_uniform_env`] about `n` at the unit direction `wi`: cos θ / π above
/// the plane of `n` and 0 below it (a direction the light sampler never produces, so a BSDF
/// sample there takes the whole MIS weight, Veach 1997 §9.2); 1 / 4π everywhere for `n` zero.
#[inline]
pub fn uniform_env_pdf(n: Vec3, wi: Vec3) -> f32 {
    if n == Vec3::ZERO {
        warp::UNIFORM_SPHERE_PDF
    } else {
        warp::cosine_hemisphere_pdf(n.dot(wi))
    }
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
}

/// What a light sample on an area light needs that does not change from sample to sample,
/// computed once when the light set is built. Before, every sample rebuilt a whole
/// [`SurfaceHit`], renormalised the normal and recomputed the area (a cross product and a square
/// root each) and looked the emission up through the material: callgrind counted ~625
/// instructions per light sample on the Cornell box's quad, a sixth of all of them.
#[derive(Clone, Copy, Debug, Default)]
struct AreaLightInfo {
    /// Surface area, for the area-to-solid-angle pdf d² / (cos θ_l · A) (PBRT eq. 4.9).
    area: f32,
    /// `Some` for a flat emitter (quad or triangle) whose emission is a constant: its unit front
    /// normal and radiance, enough to sample it without a [`SurfaceHit`]. Textured emitters,
    /// spheres and boxes take the general path.
    flat: Option<FlatEmitter>,
    /// A sphere's (centre, radius): sampled over the cone it subtends from outside, and
    /// [`LightSet::pdf_area`] must give that pdf.
    sphere: Option<(Vec3, f32)>,
}

#[derive(Clone, Copy, Debug)]
struct FlatEmitter {
    normal: Vec3,
    radiance: Vec3,
    double_sided: bool,
}

/// All lights of a scene and how next-event estimation chooses one of them.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    pub lights: Vec<Light>,
    /// Per light (same index), the precomputed part of area light sampling; default for others.
    area_info: Vec<AreaLightInfo>,
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

/// [`LightSet::sample`] on a flat emitter of constant radiance: the same point, pdf and shadow ray
/// as the general path (the same arithmetic, so images do not change), without building a
/// [`SurfaceHit`] for the light point. `pmf` is left at 1 for the caller to set.
#[inline]
fn sample_flat(
    geometry: &GeometryStore,
    prim: PrimRef,
    area: f32,
    flat: &FlatEmitter,
    hit: &SurfaceHit,
    n_offset: Vec3,
    u: Vec2,
) -> Option<LightSample> {
    // `area_light_info` makes flat entries only for quads and triangles.
    let (lp, lp_error) = geometry.sample_flat_position(prim, u)?;
    let to = lp - hit.p;
    let d2 = to.length_squared();
    if !(d2 > 0.0) {
        return None;
    }
    let wi = to / d2.sqrt();
    let cos_front = flat.normal.dot(-wi);
    // A one-sided emitter seen from behind sends nothing (as `emitted` decides).
    let cos_l = cos_front.abs();
    if cos_l <= 0.0 || (!flat.double_sided && cos_front <= 0.0) {
        return None;
    }
    Some(LightSample {
        wi,
        li: flat.radiance,
        pdf: d2 / (cos_l * area),
        pmf: 1.0,
        delta: false,
        shadow: Ray::spawn_to(hit.p, hit.p_error, n_offset, lp, lp_error, flat.normal),
    })
}

/// [`LightSet::sample`] on any area light: a light point with its full shading attributes, so
/// textured emission, spheres and boxes work. `pmf` is left at 1 for the caller to set.
#[allow(clippy::too_many_arguments)]
fn sample_area_general(
    geometry: &GeometryStore,
    prim: PrimRef,
    area: f32,
    material: &Material,
    textures: &[Texture],
    hit: &SurfaceHit,
    n_offset: Vec3,
    u: Vec2,
) -> Option<LightSample> {
    let lp = geometry.sample_point(prim, u);
    let to = lp.p - hit.p;
    let d2 = to.length_squared();
    if !(d2 > 0.0) {
        return None;
    }
    let wi = to / d2.sqrt();
    let cos_l = lp.ng.dot(-wi).abs();
    if cos_l <= 0.0 {
        return None;
    }
    let li = emitted(material, textures, &lp, -wi);
    if li == Vec3::ZERO {
        return None;
    }
    Some(LightSample {
        wi,
        li,
        pdf: d2 / (cos_l * area),
        pmf: 1.0,
        delta: false,
        shadow: Ray::spawn_to(hit.p, hit.p_error, n_offset, lp.p, lp.p_error, lp.ng),
    })
}

/// [`sample_sphere_cone`] (in geometry, with the other shape sampling) for a sphere area light: the light sample from `hit`.
#[allow(clippy::too_many_arguments)]
#[inline]
fn sample_sphere_light(
    geometry: &GeometryStore,
    prim: PrimRef,
    material: &Material,
    textures: &[Texture],
    hit: &SurfaceHit,
    n_offset: Vec3,
    u: Vec2,
) -> Option<Option<LightSample>> {
    let s = &geometry.spheres[prim.index()].shape;
    let (point, n, pdf) = sample_sphere_cone(s.center, s.radius, hit.p, u)?;
    let mut lp = geometry.blank_hit(prim, 0.0);
    let local = n * s.radius;
    lp.p = point;
    lp.p_error = local.abs() * crate::math::gamma(5) + s.center.abs() * crate::math::gamma(1);
    lp.ng = n;
    lp.ns = n;
    let (su, sv) = s.uv(n);
    lp.uv = [Vec2::new(su, sv); 2];
    let to = point - hit.p;
    let d2 = to.length_squared();
    if !(d2 > 0.0 && pdf.is_finite() && pdf > 0.0) {
        return Some(None);
    }
    let wi = to / d2.sqrt();
    let li = emitted(material, textures, &lp, -wi);
    if li == Vec3::ZERO {
        return Some(None);
    }
    Some(Some(LightSample {
        wi,
        li,
        pdf,
        pmf: 1.0,
        delta: false,
        shadow: Ray::spawn_to(hit.p, hit.p_error, n_offset, lp.p, lp.p_error, lp.ng),
    }))
}

/// The precomputed part of sampling area light `prim` (see [`AreaLightInfo`]).
fn area_light_info(geometry: &GeometryStore, prim: PrimRef, material: &Material) -> AreaLightInfo {
    let normal = match prim.kind() {
        PrimitiveKind::Quad => Some(geometry.quads[prim.index()].shape.normal()),
        // The same normal `GeometryStore::sample_point` gives the light point.
        PrimitiveKind::Triangle => Some(geometry.triangles[prim.index()].unit_normal()),
        PrimitiveKind::Sphere | PrimitiveKind::Cuboid => None,
    };
    let flat = match normal {
        Some(normal) if material.is_emissive() && material.emissive_texture.is_none() => {
            Some(FlatEmitter {
                normal,
                radiance: material.emissive,
                double_sided: material.double_sided,
            })
        }
        _ => None,
    };
    let sphere = (prim.kind() == PrimitiveKind::Sphere).then(|| {
        let s = &geometry.spheres[prim.index()].shape;
        (s.center, s.radius)
    });
    AreaLightInfo {
        area: geometry.area(prim),
        flat,
        sphere,
    }
}

/// Power of an area light's surface for light selection: π · A · L̄ (× 2 if it emits both ways).
/// L̄ uses the mean of the light's own texture footprint when it was read (`footprint_mean`,
/// see [`emission`]), else the texture's mean.
fn area_power(
    area: f32,
    material: &Material,
    texture_averages: &[Vec3],
    footprint_mean: Option<Vec3>,
) -> f32 {
    let mut l = material.emissive;
    if let Some(t) = &material.emissive_texture {
        l *= footprint_mean.unwrap_or_else(|| {
            texture_averages
                .get(t.texture)
                .copied()
                .unwrap_or(Vec3::ONE)
        });
    }
    let sides = if material.double_sided { 2.0 } else { 1.0 };
    PI * sides * area * luminance(l)
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
        let area_info = lights
            .iter()
            .map(|l| match l {
                Light::Area { prim, material } => {
                    area_light_info(geometry, *prim, &materials[*material as usize])
                }
                _ => AreaLightInfo::default(),
            })
            .collect::<Vec<_>>();
        let powers: Vec<f32> = lights
            .iter()
            .zip(&area_info)
            .enumerate()
            .map(|(i, (l, info))| match l {
                Light::Area { material, .. } => area_power(
                    info.area,
                    &materials[*material as usize],
                    &texture_averages,
                    footprint_means.get(i).copied().flatten(),
                ),
                Light::Point { intensity, .. } => 4.0 * PI * luminance(*intensity),
                Light::Spot {
                    intensity,
                    cos_inner,
                    cos_outer,
                    ..
                } => 2.0 * PI * (1.0 - 0.5 * (cos_inner + cos_outer)) * luminance(*intensity),
                Light::Directional { irradiance, .. } => {
                    PI * scene_radius * scene_radius * luminance(*irradiance)
                }
                Light::Uniform { radiance } => {
                    4.0 * PI * PI * scene_radius * scene_radius * luminance(*radiance)
                }
                // Like a uniform environment of the map's mean radiance.
                Light::Environment { map } => {
                    4.0 * PI * PI * scene_radius * scene_radius * map.mean_luminance
                }
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
            let lb: Vec<(u32, LightBounds)> = lights
                .iter()
                .enumerate()
                .zip(&powers)
                .filter_map(|((i, l), &phi)| {
                    light_bounds(l, geometry, materials, phi).map(|b| (i as u32, b))
                })
                .collect();
            TreeSelection::new(
                LightBvh::with_width(&lb, lights.len(), width),
                &infinite,
                &powers,
            )
        });
        LightSet {
            distribution: Distribution1D::new(&powers),
            tree,
            lights,
            area_info,
            infinite,
            scene_center,
            scene_radius,
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
        geometry: &GeometryStore,
        materials: &[Material],
        textures: &[Texture],
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
        self.sample_chosen(
            geometry,
            materials,
            textures,
            hit,
            n_offset,
            index,
            pmf,
            u,
            env,
            Vec3::ZERO,
        )
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
    /// environment is sampled about `uniform_n` ([`sample_uniform_env`]; zero for the sphere).
    #[allow(clippy::too_many_arguments)]
    pub fn sample_reuse(
        &self,
        geometry: &GeometryStore,
        materials: &[Material],
        textures: &[Texture],
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
        self.sample_chosen(
            geometry, materials, textures, hit, n_offset, index, pmf, u, env, uniform_n,
        )
    }

    /// Samples light `index`, chosen with probability `pmf`, with `u`; an environment map
    /// from the density `env`, a uniform environment about `uniform_n` ([`sample_uniform_env`]).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn sample_chosen(
        &self,
        geometry: &GeometryStore,
        materials: &[Material],
        textures: &[Texture],
        hit: &SurfaceHit,
        n_offset: Vec3,
        index: usize,
        pmf: f32,
        u: Vec2,
        env: EnvPdf,
        uniform_n: Vec3,
    ) -> Option<LightSample> {
        let p = hit.p;
        match &self.lights[index] {
            Light::Area { prim, material } => {
                let info = &self.area_info[index];
                let material = &materials[*material as usize];
                let sample = match &info.flat {
                    Some(flat) => sample_flat(geometry, *prim, info.area, flat, hit, n_offset, u),
                    None if prim.kind() == PrimitiveKind::Sphere => {
                        match sample_sphere_light(
                            geometry, *prim, material, textures, hit, n_offset, u,
                        ) {
                            Some(sample) => sample,
                            // From inside the sphere: by area.
                            None => sample_area_general(
                                geometry, *prim, info.area, material, textures, hit, n_offset, u,
                            ),
                        }
                    }
                    None => sample_area_general(
                        geometry, *prim, info.area, material, textures, hit, n_offset, u,
                    ),
                };
                sample.map(|ls| LightSample { pmf, ..ls })
            }
            Light::Point { .. } | Light::Spot { .. } | Light::Directional { .. } => {
                let ls = self.lights[index].sample_delta(p, hit.p_error, n_offset)?;
                Some(LightSample { pmf, ..ls })
            }
            Light::Uniform { radiance } => {
                let (wi, pdf) = sample_uniform_env(uniform_n, u)?;
                let shadow = Ray::spawn(p, hit.p_error, n_offset, wi);
                Some(LightSample {
                    wi,
                    li: *radiance,
                    pdf,
                    pmf,
                    delta: false,
                    shadow,
                })
            }
            Light::Environment { map } => {
                let (wi, li, pdf) = map.sample(u, env)?;
                if li == Vec3::ZERO {
                    return None;
                }
                let shadow = Ray::spawn(p, hit.p_error, n_offset, wi);
                Some(LightSample {
                    wi,
                    li,
                    pdf,
                    pmf,
                    delta: false,
                    shadow,
                })
            }
        }
    }

    /// Solid-angle pdf with which NEE would have sampled the point `light_hit` on area light
    /// `index` from `p` with normal `n` (the `n_offset` given to [`LightSet::sample`]), selection
    /// probability included, for MIS of BSDF-sampled hits.
    #[inline]
    pub fn pdf_area(&self, index: u32, p: Vec3, n: Vec3, light_hit: &SurfaceHit) -> f32 {
        let Light::Area { .. } = &self.lights[index as usize] else {
            return 0.0;
        };
        let info = &self.area_info[index as usize];
        if let Some((center, radius)) = info.sphere
            && let Some((_, one_minus)) = sphere_cone(center, radius, p)
        {
            // Seen from outside, a sphere is sampled over its cone (`sample_sphere_cone`).
            let pmf = self.pmf(index, p, n);
            return if pmf > 0.0 {
                pmf / (2.0 * PI * one_minus)
            } else {
                0.0
            };
        }
        let area = info.area;
        let to = light_hit.p - p;
        let d2 = to.length_squared();
        let cos_l = light_hit.ng.dot(to).abs() / d2.sqrt();
        if !(cos_l > 0.0) {
            return 0.0;
        }
        let pmf = self.pmf(index, p, n);
        if !(pmf > 0.0) {
            return 0.0;
        }
        pmf * d2 / (cos_l * area)
    }

    /// Radiance from the lights at infinity along an escaping ray direction `d` (unit), unweighted
    /// (what a camera ray or a path without NEE sees).
    #[inline]
    pub fn escaped(&self, d: Vec3) -> Vec3 {
        let mut l = Vec3::ZERO;
        for &i in &self.infinite {
            match &self.lights[i as usize] {
                Light::Uniform { radiance } => l += *radiance,
                Light::Environment { map } => l += map.eval(d),
                _ => {}
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
    /// A uniform environment's density is [`uniform_env_pdf`] about `uniform_n`: the normal NEE
    /// sampled it about at the vertex the direction left (zero: the sphere).
    #[inline]
    pub fn escaped_mis(
        &self,
        d: Vec3,
        env: EnvPdf,
        uniform_n: Vec3,
        mut contribution: impl FnMut(Vec3, f32) -> Vec3,
    ) -> Vec3 {
        let mut l = Vec3::ZERO;
        for &i in &self.infinite {
            let (le, pdf) = match &self.lights[i as usize] {
                Light::Uniform { radiance } => (
                    *radiance,
                    self.pmf_infinite(i) * uniform_env_pdf(uniform_n, d),
                ),
                Light::Environment { map } => {
                    let (le, pdf) = map.eval_pdf(d, env);
                    (le, self.pmf_infinite(i) * pdf)
                }
                _ => continue,
            };
            if le != Vec3::ZERO {
                l += contribution(le, pdf);
            }
        }
        l
    }
}

impl TreeSelection {
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

/// The light BVH's bounds of a bounded light of power `phi` (`None` for lights at infinity).
fn light_bounds(
    light: &Light,
    geometry: &GeometryStore,
    materials: &[Material],
    phi: f32,
) -> Option<LightBounds> {
    // Lambertian emission reaches 90° from the normal; points emit everywhere.
    let all_around = |bounds: Bounds3| LightBounds {
        bounds,
        phi,
        w: Vec3::Z,
        cos_theta_o: -1.0,
        cos_theta_e: 0.0,
        two_sided: false,
    };
    match light {
        Light::Area { prim, material } => {
            let bounds = geometry.bounds(*prim);
            let normal = match prim.kind() {
                PrimitiveKind::Quad => Some(geometry.quads[prim.index()].shape.normal()),
                PrimitiveKind::Triangle => Some(geometry.triangles[prim.index()].unit_normal()),
                PrimitiveKind::Sphere | PrimitiveKind::Cuboid => None,
            };
            match normal {
                Some(w) if w.is_finite() && w != Vec3::ZERO => Some(LightBounds {
                    bounds,
                    phi,
                    w,
                    cos_theta_o: 1.0,
                    cos_theta_e: 0.0,
                    two_sided: materials[*material as usize].double_sided,
                }),
                _ => Some(all_around(bounds)),
            }
        }
        Light::Point { position, .. } => Some(all_around(Bounds3::from_point(*position))),
        Light::Spot {
            position,
            direction,
            cos_inner,
            cos_outer,
            ..
        } => {
            // pbrt-v4 `SpotLight::Bounds`: θo the inner cone, θe the ramp out to the outer one.
            let theta_e =
                (cos_outer.clamp(-1.0, 1.0).acos() - cos_inner.clamp(-1.0, 1.0).acos()).max(0.0);
            Some(LightBounds {
                bounds: Bounds3::from_point(*position),
                phi,
                w: *direction,
                cos_theta_o: *cos_inner,
                cos_theta_e: theta_e.cos(),
                two_sided: false,
            })
        }
        Light::Directional { .. } | Light::Uniform { .. } | Light::Environment { .. } => None,
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
    use crate::geometry::primitive::{AnalyticPrim, MeshAttributes};
    use crate::geometry::quad::Quad;
    use crate::geometry::triangle::TriangleVerts;
    use crate::math::Vec4;

    /// A tilted quad and a triangle far from the origin (so the error bounds are not zero).
    fn emitters() -> GeometryStore {
        let mut g = GeometryStore::default();
        g.quads.push(AnalyticPrim {
            shape: Quad::new(
                Vec3::new(-0.3, 0.99, -0.2),
                Vec3::new(0.6, 0.05, 0.0),
                Vec3::new(0.0, -0.02, 0.45),
            ),
            material: 0,
            light: 0,
        });
        g.triangles.push(TriangleVerts {
            p0: Vec3::new(101.0, 3.0, -7.0),
            p1: Vec3::new(101.5, 3.2, -6.0),
            p2: Vec3::new(100.2, 4.0, -6.5),
        });
        g.tri_mesh.push((0, 0));
        g.tri_light.push(1);
        g.meshes.push(MeshAttributes {
            indices: vec![[0, 1, 2]],
            ..Default::default()
        });
        g
    }

    fn shading_point(p: Vec3, n: Vec3) -> SurfaceHit {
        SurfaceHit {
            t: 1.0,
            p,
            p_error: p.abs() * crate::math::gamma(5),
            ng: n,
            ns: n,
            tangent: crate::math::Frame::from_normal(n).x,
            bitangent_sign: 1.0,
            uv: [Vec2::ZERO; 2],
            duv: [Vec4::ZERO; 2],
            color: Vec4::ONE,
            material: 0,
            light: crate::geometry::primitive::NO_LIGHT,
            prim: PrimRef::new(PrimitiveKind::Quad, 0),
        }
    }

    fn same(a: Option<LightSample>, b: Option<LightSample>) -> bool {
        match (a, b) {
            (None, None) => true,
            (Some(a), Some(b)) => {
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                bits(a.wi) == bits(b.wi)
                    && bits(a.li) == bits(b.li)
                    && a.pdf.to_bits() == b.pdf.to_bits()
                    && a.pmf == b.pmf
                    && a.delta == b.delta
                    && bits(a.shadow.o) == bits(b.shadow.o)
                    && bits(a.shadow.d) == bits(b.shadow.d)
                    && a.shadow.t_max.to_bits() == b.shadow.t_max.to_bits()
            }
            _ => false,
        }
    }

    /// The precomputed path for flat, constant emitters must give exactly what the general path
    /// gives (point, direction, radiance, pdf, shadow ray), on both sides of one- and two-sided
    /// quads and triangles: it is an optimisation, not a second model.
    #[test]
    fn flat_emitter_path_matches_general_path() {
        let g = emitters();
        let mut checked = [0usize; 2];
        for double_sided in [false, true] {
            let material = Material {
                emissive: Vec3::new(4.0, 3.0, 2.5),
                double_sided,
                ..Default::default()
            };
            for prim in [
                PrimRef::new(PrimitiveKind::Quad, 0),
                PrimRef::new(PrimitiveKind::Triangle, 0),
            ] {
                let info = area_light_info(&g, prim, &material);
                let flat = info
                    .flat
                    .expect("a constant quad or triangle emitter is flat");
                assert!((info.area - g.area(prim)).abs() <= 1e-6 * info.area);
                let centre = if prim.kind() == PrimitiveKind::Quad {
                    Vec3::ZERO
                } else {
                    Vec3::new(100.5, 3.5, -6.5)
                };
                for k in 0..400u32 {
                    // Shading points all around the emitter, so both of its sides are seen.
                    let a = (k as f32 + 0.5) * 0.618_034 * std::f32::consts::TAU;
                    let z = 1.0 - 2.0 * ((k as f32 + 0.5) / 400.0);
                    let r = (1.0 - z * z).sqrt();
                    let dir = Vec3::new(r * a.cos(), z, r * a.sin());
                    let hit = shading_point(centre + dir * 2.5, -dir);
                    let u = Vec2::new(
                        ((k * 7919) % 1000) as f32 / 1000.0,
                        ((k * 104_729) % 997) as f32 / 997.0,
                    );
                    let fast = sample_flat(&g, prim, info.area, &flat, &hit, -dir, u);
                    let general =
                        sample_area_general(&g, prim, info.area, &material, &[], &hit, -dir, u);
                    assert!(
                        same(fast, general),
                        "{prim:?} k={k}: {fast:?} vs {general:?}"
                    );
                    checked[fast.is_some() as usize] += 1;
                }
            }
        }
        // Both outcomes occurred: samples from the back of one-sided emitters are refused.
        assert!(checked[0] > 100 && checked[1] > 800, "{checked:?}");
    }

    /// Textured emission, spheres and boxes keep the general path.
    #[test]
    fn textured_and_curved_emitters_are_not_flat() {
        let g = emitters();
        let textured = Material {
            emissive: Vec3::ONE,
            emissive_texture: Some(crate::material::texture::TextureRef::new(0)),
            ..Default::default()
        };
        let quad = PrimRef::new(PrimitiveKind::Quad, 0);
        assert!(area_light_info(&g, quad, &textured).flat.is_none());
        let constant = Material {
            emissive: Vec3::ONE,
            ..Default::default()
        };
        assert!(area_light_info(&g, quad, &constant).flat.is_some());
    }

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
