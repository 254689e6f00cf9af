//! Lights and light sampling for next-event estimation (thesis §5.1.12, §5.4.2, §5.4.4).
//! Area lights are the emissive primitives themselves, sampled uniformly by area and converted to
//! solid angle (PBRT eq. 4.9 / §12.2); a light is first chosen in proportion to its power.

use crate::geometry::primitive::{PrimRef, PrimitiveKind, SurfaceHit};
use crate::geometry::{Bounds3, GeometryStore, Ray};
use crate::material::bsdf::emitted;
use crate::material::{Material, Texture};
use crate::math::{PI, Vec2, Vec3, luminance};
use crate::sampling::{Distribution1D, warp};
use std::sync::Arc;

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

/// All lights of a scene and the power-proportional distribution used to pick one.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    pub lights: Vec<Light>,
    pub distribution: Distribution1D,
    /// Indices of lights at infinity.
    pub infinite: Vec<u32>,
    /// Scene bounding sphere (for infinite light powers and far-away shadow rays).
    pub scene_center: Vec3,
    pub scene_radius: f32,
}

/// Point on an area light with its shading attributes (for the emitted radiance).
fn sample_area_point(geometry: &GeometryStore, prim: PrimRef, u: Vec2) -> SurfaceHit {
    let i = prim.index();
    let mut hit = SurfaceHit {
        t: 0.0,
        p: Vec3::ZERO,
        p_error: Vec3::ZERO,
        ng: Vec3::Z,
        ns: Vec3::Z,
        tangent: Vec3::X,
        bitangent_sign: 1.0,
        uv: [Vec2::ZERO; 2],
        color: crate::math::Vec4::ONE,
        material: geometry.material(prim),
        light: geometry.light(prim),
        prim,
    };
    match prim.kind() {
        PrimitiveKind::Triangle => {
            let (b1, b2) = warp::uniform_triangle(u);
            geometry.emitter_point(prim, b1, b2, &mut hit);
        }
        PrimitiveKind::Quad => geometry.emitter_point(prim, u.x, u.y, &mut hit),
        PrimitiveKind::Sphere => {
            let s = &geometry.spheres[i].shape;
            let n = warp::uniform_sphere(u);
            let local = n * s.radius;
            hit.p = s.center + local;
            hit.p_error =
                local.abs() * crate::math::gamma(5) + s.center.abs() * crate::math::gamma(1);
            hit.ng = n;
            hit.ns = n;
            let (su, sv) = s.uv(n);
            hit.uv = [Vec2::new(su, sv); 2];
        }
        PrimitiveKind::Cuboid => {
            // Pick a face in proportion to area, reusing u.x rescaled.
            let faces = geometry.cuboids[i].shape.faces();
            let areas = faces.map(|f| f.area());
            let total: f32 = areas.iter().sum();
            let mut target = u.x * total;
            let mut k = 0;
            while k < 5 && target >= areas[k] {
                target -= areas[k];
                k += 1;
            }
            let ux = if areas[k] > 0.0 {
                (target / areas[k]).clamp(0.0, 1.0)
            } else {
                0.5
            };
            let f = &faces[k];
            let (p, err) = f.point(ux, u.y);
            hit.p = p;
            hit.p_error = err;
            hit.ng = f.normal();
            hit.ns = hit.ng;
            hit.uv = [Vec2::new(ux, u.y); 2];
        }
    }
    hit
}

/// Power of an area light's surface for light selection: π · A · L̄ (× 2 if it emits both ways).
fn area_power(
    geometry: &GeometryStore,
    prim: PrimRef,
    material: &Material,
    texture_averages: &[Vec3],
) -> f32 {
    let mut l = material.emissive;
    if let Some(t) = &material.emissive_texture {
        l *= texture_averages
            .get(t.texture)
            .copied()
            .unwrap_or(Vec3::ONE);
    }
    let sides = if material.double_sided { 2.0 } else { 1.0 };
    PI * sides * geometry.area(prim) * luminance(l)
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
        let powers: Vec<f32> = lights
            .iter()
            .map(|l| match l {
                Light::Area { prim, material } => area_power(
                    geometry,
                    *prim,
                    &materials[*material as usize],
                    &texture_averages,
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
        let infinite = lights
            .iter()
            .enumerate()
            .filter(|(_, l)| l.is_infinite())
            .map(|(i, _)| i as u32)
            .collect();
        LightSet {
            distribution: Distribution1D::new(&powers),
            lights,
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
                let lp = sample_area_point(geometry, *prim, u);
                let to = lp.p - p;
                let d2 = to.length_squared();
                if !(d2 > 0.0) {
                    return None;
                }
                let wi = to / d2.sqrt();
                let cos_l = lp.ng.dot(-wi).abs();
                if cos_l <= 0.0 {
                    return None;
                }
                let li = emitted(&materials[*material as usize], textures, &lp, -wi);
                if li == Vec3::ZERO {
                    return None;
                }
                let pdf = d2 / (cos_l * geometry.area(*prim));
                Some(LightSample {
                    wi,
                    li,
                    pdf,
                    pmf,
                    delta: false,
                    shadow: Ray::spawn_to(p, hit.p_error, n_offset, lp.p, lp.p_error, lp.ng),
                })
            }
            Light::Point {
                position,
                intensity,
            } => {
                let to = *position - p;
                let d2 = to.length_squared();
                if !(d2 > 0.0) {
                    return None;
                }
                let wi = to / d2.sqrt();
                Some(LightSample {
                    wi,
                    li: *intensity / d2,
                    pdf: 1.0,
                    pmf,
                    delta: true,
                    shadow: Ray::spawn_to(p, hit.p_error, n_offset, *position, Vec3::ZERO, wi),
                })
            }
            Light::Spot {
                position,
                direction,
                intensity,
                cos_inner,
                cos_outer,
            } => {
                let to = *position - p;
                let d2 = to.length_squared();
                if !(d2 > 0.0) {
                    return None;
                }
                let wi = to / d2.sqrt();
                let falloff = spot_falloff(direction.dot(-wi), *cos_inner, *cos_outer);
                if falloff <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    li: *intensity * (falloff / d2),
                    pdf: 1.0,
                    pmf,
                    delta: true,
                    shadow: Ray::spawn_to(p, hit.p_error, n_offset, *position, Vec3::ZERO, wi),
                })
            }
            Light::Directional {
                direction,
                irradiance,
            } => {
                let wi = -*direction;
                let mut shadow = Ray::spawn(p, hit.p_error, n_offset, wi);
                shadow.t_max = f32::INFINITY;
                Some(LightSample {
                    wi,
                    li: *irradiance,
                    pdf: 1.0,
                    pmf,
                    delta: true,
                    shadow,
                })
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
    pub fn pdf_area(
        &self,
        geometry: &GeometryStore,
        index: u32,
        p: Vec3,
        light_hit: &SurfaceHit,
    ) -> f32 {
        let Light::Area { prim, .. } = &self.lights[index as usize] else {
            return 0.0;
        };
        let to = light_hit.p - p;
        let d2 = to.length_squared();
        let cos_l = light_hit.ng.dot(to).abs() / d2.sqrt();
        if !(cos_l > 0.0) {
            return 0.0;
        }
        self.pmf(index) * d2 / (cos_l * geometry.area(*prim))
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

    #[test]
    fn spot_falloff_limits() {
        let (ci, co) = (0.9f32, 0.7f32);
        assert_eq!(spot_falloff(0.95, ci, co), 1.0);
        assert_eq!(spot_falloff(0.6, ci, co), 0.0);
        let mid = spot_falloff(0.8, ci, co);
        assert!(mid > 0.0 && mid < 1.0);
    }
}
