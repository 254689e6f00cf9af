//! Lights and light sampling for next-event estimation (thesis §5.1.12, §5.4.2, §5.4.4).
//! Area lights are the emissive primitives themselves, sampled uniformly by area and converted to
//! solid angle (PBRT eq. 4.9 / §12.2); a light is first chosen in proportion to its power.

use crate::geometry::primitive::{PrimRef, PrimitiveKind, SurfaceHit};
use crate::geometry::{Bounds3, GeometryStore, Ray};
use crate::material::eval::emitted;
use crate::material::{Material, Texture};
use crate::math::{PI, Vec2, Vec3, luminance};
use crate::sampling::{Distribution1D, warp};
use std::sync::Arc;

pub mod default_light;
pub mod envmap;
pub use envmap::EnvMap;

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
            } => {
                let (wi, d2) = toward(*position, p)?;
                let falloff = spot_falloff(direction.dot(-wi), *cos_inner, *cos_outer);
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
}

#[derive(Clone, Copy, Debug)]
struct FlatEmitter {
    normal: Vec3,
    radiance: Vec3,
    double_sided: bool,
}

/// All lights of a scene and the power-proportional distribution used to pick one.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    pub lights: Vec<Light>,
    /// Per light (same index), the precomputed part of area light sampling; default for others.
    area_info: Vec<AreaLightInfo>,
    pub distribution: Distribution1D,
    /// Indices of lights at infinity.
    pub infinite: Vec<u32>,
    /// Scene bounding sphere (for infinite light powers and far-away shadow rays).
    pub scene_center: Vec3,
    pub scene_radius: f32,
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
    AreaLightInfo {
        area: geometry.area(prim),
        flat,
    }
}

/// Power of an area light's surface for light selection: π · A · L̄ (× 2 if it emits both ways).
fn area_power(area: f32, material: &Material, texture_averages: &[Vec3]) -> f32 {
    let mut l = material.emissive;
    if let Some(t) = &material.emissive_texture {
        l *= texture_averages
            .get(t.texture)
            .copied()
            .unwrap_or(Vec3::ONE);
    }
    let sides = if material.double_sided { 2.0 } else { 1.0 };
    PI * sides * area * luminance(l)
}

impl LightSet {
    pub fn new(
        lights: Vec<Light>,
        geometry: &GeometryStore,
        materials: &[Material],
        textures: &[Texture],
        bounds: Bounds3,
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
            .map(|(l, info)| match l {
                Light::Area { material, .. } => {
                    area_power(info.area, &materials[*material as usize], &texture_averages)
                }
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
        let infinite = lights
            .iter()
            .enumerate()
            .filter(|(_, l)| l.is_infinite())
            .map(|(i, _)| i as u32)
            .collect();
        LightSet {
            distribution: Distribution1D::new(&powers),
            lights,
            area_info,
            infinite,
            scene_center,
            scene_radius,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Probability that NEE picks light `index`.
    #[inline]
    pub fn pmf(&self, index: u32) -> f32 {
        self.distribution.discrete_pdf(index as usize)
    }

    /// Picks a light by power and samples a point/direction on it as seen from `hit`.
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
    ) -> Option<LightSample> {
        if self.lights.is_empty() {
            return None;
        }
        let (index, pmf) = self.distribution.sample_discrete(u_light);
        if pmf <= 0.0 {
            return None;
        }
        let p = hit.p;
        match &self.lights[index] {
            Light::Area { prim, material } => {
                let info = &self.area_info[index];
                let sample = match &info.flat {
                    Some(flat) => sample_flat(geometry, *prim, info.area, flat, hit, n_offset, u),
                    None => sample_area_general(
                        geometry,
                        *prim,
                        info.area,
                        &materials[*material as usize],
                        textures,
                        hit,
                        n_offset,
                        u,
                    ),
                };
                sample.map(|ls| LightSample { pmf, ..ls })
            }
            Light::Point { .. } | Light::Spot { .. } | Light::Directional { .. } => {
                let ls = self.lights[index].sample_delta(p, hit.p_error, n_offset)?;
                Some(LightSample { pmf, ..ls })
            }
            Light::Uniform { radiance } => {
                let wi = warp::uniform_sphere(u);
                let shadow = Ray::spawn(p, hit.p_error, n_offset, wi);
                Some(LightSample {
                    wi,
                    li: *radiance,
                    pdf: warp::UNIFORM_SPHERE_PDF,
                    pmf,
                    delta: false,
                    shadow,
                })
            }
            Light::Environment { map } => {
                let (wi, li, pdf) = map.sample(u)?;
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
    /// `index` from `p` (selection probability included), for MIS of BSDF-sampled hits.
    #[inline]
    pub fn pdf_area(&self, index: u32, p: Vec3, light_hit: &SurfaceHit) -> f32 {
        let Light::Area { .. } = &self.lights[index as usize] else {
            return 0.0;
        };
        let area = self.area_info[index as usize].area;
        let to = light_hit.p - p;
        let d2 = to.length_squared();
        let cos_l = light_hit.ng.dot(to).abs() / d2.sqrt();
        if !(cos_l > 0.0) {
            return 0.0;
        }
        self.pmf(index) * d2 / (cos_l * area)
    }

    /// Radiance from the lights at infinity along an escaping ray direction `d` (unit), and for
    /// each such light its NEE pdf (selection included), summed for MIS.
    #[inline]
    pub fn escaped(&self, d: Vec3) -> (Vec3, f32) {
        let mut l = Vec3::ZERO;
        let mut pdf = 0.0;
        for &i in &self.infinite {
            match &self.lights[i as usize] {
                Light::Uniform { radiance } => {
                    l += *radiance;
                    pdf += self.pmf(i) * warp::UNIFORM_SPHERE_PDF;
                }
                Light::Environment { map } => {
                    l += map.eval(d);
                    pdf += self.pmf(i) * map.pdf(d);
                }
                _ => {}
            }
        }
        (l, pdf)
    }
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
