//! Area lights: the emissive primitives themselves (pbrt-v4 `DiffuseAreaLight`), constant or
//! textured, one- or two-sided. Toward a receiver they are sampled uniformly by area and
//! converted to solid angle (PBRT eq. 4.9 / §12.2), spheres seen from outside over the cone they
//! subtend; emission is sampled as a point by area and a cosine-weighted direction.

use super::bvh::LightBounds;
use super::{LeSample, LightSample, LightScene};
use crate::geometry::primitive::{PrimRef, PrimitiveKind, SurfaceHit};
use crate::geometry::sample::{sample_sphere_cone, sphere_cone};
use crate::geometry::{GeometryStore, Ray};
use crate::material::eval::emitted;
use crate::material::{Material, Texture};
use crate::math::{Frame, PI, Vec2, Vec3, luminance};
use crate::sampling::warp;

/// An emissive primitive and what sampling it needs that does not change from sample to sample,
/// computed once by [`AreaLight::prepare`] when the light set is built. Before, every sample
/// rebuilt a whole [`SurfaceHit`], renormalised the normal and recomputed the area (a cross
/// product and a square root each) and looked the emission up through the material: callgrind
/// counted ~625 instructions per light sample on the Cornell box's quad, a sixth of all of them.
#[derive(Clone, Copy, Debug)]
pub struct AreaLight {
    pub prim: PrimRef,
    /// Index of the emitting material.
    pub material: u32,
    /// Surface area, for the area-to-solid-angle pdf d² / (cos θ_l · A) (PBRT eq. 4.9).
    area: f32,
    /// `Some` for a flat emitter (quad or triangle) whose emission is a constant: its unit front
    /// normal and radiance, enough to sample it without a [`SurfaceHit`]. Textured emitters,
    /// spheres and boxes take the general path.
    flat: Option<FlatEmitter>,
    /// A sphere's (centre, radius): sampled over the cone it subtends from outside, and
    /// [`AreaLight::pdf_li`] must give that pdf.
    sphere: Option<(Vec3, f32)>,
    /// True when the primitive moves during the shutter (continuous motion blur,
    /// `geometry::motion`): then nothing of its shape is precomputed, and every sample and
    /// density takes the primitive where it is at `time` ([`AreaLight::at`]; the light set's
    /// `posed`), or, for a density of a hit on it, at the hit's time.
    moving: bool,
    /// The shutter time this light is placed at ([`AreaLight::at`]); read only when `moving`.
    time: f32,
}

#[derive(Clone, Copy, Debug)]
struct FlatEmitter {
    normal: Vec3,
    radiance: Vec3,
    double_sided: bool,
}

/// What an area light reads from its material. Every read of a [`Material`]'s emission fields in
/// this module goes through here (and [`emitted`] for the radiance at a point).
#[derive(Clone, Copy, Debug)]
struct Emission {
    /// The emissive factor (times the texture, if any).
    radiance: Vec3,
    /// Index of the emissive texture, if any.
    texture: Option<usize>,
    emits: bool,
    double_sided: bool,
}

#[inline]
fn emission_of(material: &Material) -> Emission {
    Emission {
        radiance: material.emissive,
        texture: material.emissive_texture.as_ref().map(|t| t.texture),
        emits: material.is_emissive(),
        double_sided: material.double_sided,
    }
}

impl AreaLight {
    /// The light of primitive `prim` with emitting material `material`; [`AreaLight::prepare`]
    /// must run before it is sampled (the light set does it).
    pub fn new(prim: PrimRef, material: u32) -> AreaLight {
        AreaLight {
            prim,
            material,
            area: 0.0,
            flat: None,
            sphere: None,
            moving: false,
            time: 0.0,
        }
    }

    /// True when the light's primitive moves during the shutter.
    #[inline]
    pub fn moves(&self) -> bool {
        self.moving
    }

    /// This light placed at shutter time `time` (what [`AreaLight::sample_le`],
    /// [`AreaLight::pdf_le`] and [`AreaLight::sample_point`] of a moving light read).
    #[inline]
    pub fn at(&self, time: f32) -> AreaLight {
        AreaLight { time, ..*self }
    }

    /// A point uniform by area on the light from `u` (where it is at its time, if it moves):
    /// the point [`AreaLight::sample_le`] places with the same `u`, as a full hit.
    #[inline]
    pub fn sample_point(&self, geometry: &GeometryStore, u: Vec2) -> SurfaceHit {
        if self.moving {
            geometry.sample_point_at(self.prim, u, self.time)
        } else {
            geometry.sample_point(self.prim, u)
        }
    }

    /// The light's area at its time (the precomputed one for a light that does not move).
    #[inline]
    fn area_now(&self, geometry: &GeometryStore) -> f32 {
        if self.moving {
            geometry.area_at(self.prim, self.time)
        } else {
            self.area
        }
    }

    /// Computes the precomputed part of sampling (see [`AreaLight`]).
    pub fn prepare(&mut self, geometry: &GeometryStore, materials: &[Material]) {
        let prim = self.prim;
        let emission = emission_of(&materials[self.material as usize]);
        self.moving = geometry.moves(prim);
        self.area = geometry.area(prim);
        if self.moving {
            // Its shape depends on the time: nothing to precompute.
            self.flat = None;
            self.sphere = None;
            return;
        }
        let normal = match prim.kind() {
            PrimitiveKind::Quad => Some(geometry.quads[prim.index()].shape.normal()),
            // The same normal `GeometryStore::sample_point` gives the light point.
            PrimitiveKind::Triangle => Some(geometry.triangles[prim.index()].unit_normal()),
            PrimitiveKind::Sphere | PrimitiveKind::Cuboid | PrimitiveKind::Curve => None,
        };
        self.flat = match normal {
            Some(normal) if emission.emits && emission.texture.is_none() => Some(FlatEmitter {
                normal,
                radiance: emission.radiance,
                double_sided: emission.double_sided,
            }),
            _ => None,
        };
        self.sphere = (prim.kind() == PrimitiveKind::Sphere).then(|| {
            let s = &geometry.spheres[prim.index()].shape;
            (s.center, s.radius)
        });
    }

    /// Surface area (after [`AreaLight::prepare`]).
    pub fn area(&self) -> f32 {
        self.area
    }

    /// A light sample toward `hit` (pbrt-v4 `SampleLi`), the shadow ray offset along `n_offset`;
    /// `pmf` 1 for the caller to set.
    #[inline]
    pub fn sample_li(
        &self,
        scene: &LightScene,
        hit: &SurfaceHit,
        n_offset: Vec3,
        u: Vec2,
    ) -> Option<LightSample> {
        let (geometry, prim, area) = (scene.geometry, self.prim, self.area);
        let material = &scene.materials[self.material as usize];
        let textures = scene.textures;
        if self.moving {
            // Where the primitive is at the receiver's moment: the shadow ray carries it.
            let t = hit.time;
            let area = geometry.area_at(prim, t);
            if let Some(s) = geometry.sphere_at(prim, t)
                && let Some(sample) =
                    sample_sphere_light(geometry, prim, &s, material, textures, hit, n_offset, u)
            {
                return sample;
            }
            return sample_area_general(
                geometry, prim, area, material, textures, hit, n_offset, u, t,
            );
        }
        match &self.flat {
            Some(flat) => sample_flat(geometry, prim, area, flat, hit, n_offset, u),
            None if prim.kind() == PrimitiveKind::Sphere => {
                let s = &geometry.spheres[prim.index()].shape;
                match sample_sphere_light(geometry, prim, s, material, textures, hit, n_offset, u) {
                    Some(sample) => sample,
                    // From inside the sphere: by area.
                    None => sample_area_general(
                        geometry, prim, area, material, textures, hit, n_offset, u, hit.time,
                    ),
                }
            }
            None => sample_area_general(
                geometry, prim, area, material, textures, hit, n_offset, u, hit.time,
            ),
        }
    }

    /// Solid-angle pdf with which [`AreaLight::sample_li`] from `p` gives the point `light_hit`
    /// (pbrt-v4 `PDF_Li`), times the probability `pmf()` of having chosen the light. The choice
    /// is folded in here, and asked for only when needed, so that the product is rounded as the
    /// light set always rounded it. A moving light is taken where it is at the hit's time.
    #[inline]
    pub fn pdf_li(
        &self,
        geometry: &GeometryStore,
        p: Vec3,
        light_hit: &SurfaceHit,
        pmf: impl FnOnce() -> f32,
    ) -> f32 {
        let (sphere, area) = if self.moving {
            let t = light_hit.time;
            let s = geometry.sphere_at(self.prim, t);
            (
                s.map(|s| (s.center, s.radius)),
                geometry.area_at(self.prim, t),
            )
        } else {
            (self.sphere, self.area)
        };
        if let Some((center, radius)) = sphere
            && let Some((_, one_minus)) = sphere_cone(center, radius, p)
        {
            // Seen from outside, a sphere is sampled over its cone (`sample_sphere_cone`).
            let pmf = pmf();
            return if pmf > 0.0 {
                pmf / (2.0 * PI * one_minus)
            } else {
                0.0
            };
        }
        let to = light_hit.p - p;
        let d2 = to.length_squared();
        let cos_l = light_hit.ng.dot(to).abs() / d2.sqrt();
        if !(cos_l > 0.0) {
            return 0.0;
        }
        let pmf = pmf();
        if !(pmf > 0.0) {
            return 0.0;
        }
        pmf * d2 / (cos_l * area)
    }

    /// Radiance emitted at the light point `hit` toward `w` (pbrt-v4 `L`).
    #[inline]
    pub fn l(&self, scene: &LightScene, hit: &SurfaceHit, w: Vec3) -> Vec3 {
        emitted(
            &scene.materials[self.material as usize],
            scene.textures,
            hit,
            w,
        )
    }

    /// Emission sampling (pbrt-v4 `DiffuseAreaLight::SampleLe`): a point uniform by area with
    /// `u1` (pdf 1/A) and a cosine-weighted direction about the normal with `u2` (pdf cos θ/π);
    /// a two-sided emitter first picks its side with `u2.x` (each with probability ½). A moving
    /// light is sampled where it is at its time ([`AreaLight::at`]), and its ray carries that
    /// time.
    pub fn sample_le(&self, scene: &LightScene, u1: Vec2, u2: Vec2) -> Option<LeSample> {
        let material = &scene.materials[self.material as usize];
        let lp = self.sample_point(scene.geometry, u1);
        let area = self.area_now(scene.geometry);
        let (n, u2, side) = if emission_of(material).double_sided {
            if u2.x < 0.5 {
                (lp.ng, Vec2::new(remap_half(2.0 * u2.x), u2.y), 0.5)
            } else {
                (-lp.ng, Vec2::new(remap_half(2.0 * (u2.x - 0.5)), u2.y), 0.5)
            }
        } else {
            (lp.ng, u2, 1.0)
        };
        let local = warp::cosine_hemisphere(u2);
        let pdf_dir = warp::cosine_hemisphere_pdf(local.z) * side;
        if !(pdf_dir > 0.0 && area > 0.0) {
            return None;
        }
        let w = Frame::from_normal(n).to_world(local);
        Some(LeSample {
            ray: Ray::spawn(lp.p, lp.p_error, n, w).with_time(lp.time),
            le: emitted(material, scene.textures, &lp, w),
            n: lp.ng,
            pdf_pos: 1.0 / area,
            pdf_dir,
        })
    }

    /// Position and direction pdfs of [`AreaLight::sample_le`] for a ray leaving a point of
    /// normal `n` in direction `w` (pbrt-v4 `PDF_Le`); a moving light's area at its time.
    pub fn pdf_le(&self, scene: &LightScene, n: Vec3, w: Vec3) -> (f32, f32) {
        let cos = n.dot(w);
        let pdf_dir = if emission_of(&scene.materials[self.material as usize]).double_sided {
            0.5 * warp::cosine_hemisphere_pdf(cos.abs())
        } else {
            warp::cosine_hemisphere_pdf(cos)
        };
        (1.0 / self.area_now(scene.geometry), pdf_dir)
    }

    /// Emitted power (pbrt-v4 `Phi`): π · A · L (× 2 for two sides), with a textured emitter's
    /// texture taken at its mean (exact when the texture covers the surface uniformly).
    pub fn phi(&self, scene: &LightScene) -> Vec3 {
        let e = emission_of(&scene.materials[self.material as usize]);
        let mut l = e.radiance;
        if let Some(t) = e.texture {
            l *= scene
                .textures
                .get(t)
                .map_or(Vec3::ONE, |t| t.average().truncate());
        }
        let sides = if e.double_sided { 2.0 } else { 1.0 };
        l * (PI * sides * self.area)
    }

    /// Power for light selection: π · A · L̄ (× 2 if it emits both ways) in luminance. L̄ uses
    /// the mean of the light's own texture footprint when it was read (`footprint_mean`, see
    /// [`super::emission`]), else the texture's mean (`texture_averages`, per texture).
    pub fn selection_power(
        &self,
        materials: &[Material],
        texture_averages: &[Vec3],
        footprint_mean: Option<Vec3>,
    ) -> f32 {
        let e = emission_of(&materials[self.material as usize]);
        let mut l = e.radiance;
        if let Some(t) = e.texture {
            l *= footprint_mean
                .unwrap_or_else(|| texture_averages.get(t).copied().unwrap_or(Vec3::ONE));
        }
        let sides = if e.double_sided { 2.0 } else { 1.0 };
        PI * sides * self.area * luminance(l)
    }

    /// The light BVH's bounds of this light of power `phi`: the normal cone of a flat emitter,
    /// all around for spheres and boxes (Lambertian emission reaches 90° from the normal). A
    /// moving light is boxed over the whole shutter (the union of its key segments' boxes,
    /// which hold it at every time) and emits all around: the normal of a triangle whose
    /// vertices move linearly between two keys is quadratic in the time and need not lie in the
    /// cone of the keys' normals, so a cone from the keys could exclude a receiver it lights.
    pub fn bounds(
        &self,
        geometry: &GeometryStore,
        materials: &[Material],
        phi: f32,
    ) -> LightBounds {
        let prim = self.prim;
        if self.moving {
            let segments = geometry.motion.as_ref().map_or(1, |m| m.keys.max(2) - 1);
            let swept = (0..segments).fold(crate::geometry::Bounds3::EMPTY, |b, seg| {
                b.union(&geometry.sweep_bounds(prim, seg))
            });
            return LightBounds::all_around(swept, phi);
        }
        let bounds = geometry.bounds(prim);
        let normal = match prim.kind() {
            PrimitiveKind::Quad => Some(geometry.quads[prim.index()].shape.normal()),
            PrimitiveKind::Triangle => Some(geometry.triangles[prim.index()].unit_normal()),
            PrimitiveKind::Sphere | PrimitiveKind::Cuboid | PrimitiveKind::Curve => None,
        };
        match normal {
            Some(w) if w.is_finite() && w != Vec3::ZERO => LightBounds {
                bounds,
                phi,
                w,
                cos_theta_o: 1.0,
                cos_theta_e: 0.0,
                two_sided: emission_of(&materials[self.material as usize]).double_sided,
            },
            _ => LightBounds::all_around(bounds, phi),
        }
    }
}

/// `2u` or `2(u − ½)` kept below 1 (a sample number must stay in [0, 1)).
#[inline]
fn remap_half(x: f32) -> f32 {
    x.min(1.0 - f32::EPSILON / 2.0)
}

/// [`AreaLight::sample_li`] on a flat emitter of constant radiance: the same point, pdf and
/// shadow ray as the general path (the same arithmetic, so images do not change), without
/// building a [`SurfaceHit`] for the light point. `pmf` is left at 1 for the caller to set.
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
    // `prepare` makes flat entries only for quads and triangles.
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
        light: u32::MAX,
    })
}

/// [`AreaLight::sample_li`] on any area light: a light point with its full shading attributes,
/// so textured emission, spheres and boxes work. `pmf` is left at 1 for the caller to set.
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
    time: f32,
) -> Option<LightSample> {
    // A still primitive's point is `sample_point`'s whatever the time.
    let lp = geometry.sample_point_at(prim, u, time);
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
        light: u32::MAX,
    })
}

/// [`sample_sphere_cone`] (in geometry, with the other shape sampling) for a sphere area light:
/// the light sample from `hit`; `None` from inside the sphere.
#[allow(clippy::too_many_arguments)]
#[inline]
fn sample_sphere_light(
    geometry: &GeometryStore,
    prim: PrimRef,
    s: &crate::geometry::sphere::Sphere,
    material: &Material,
    textures: &[Texture],
    hit: &SurfaceHit,
    n_offset: Vec3,
    u: Vec2,
) -> Option<Option<LightSample>> {
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
        light: u32::MAX,
    }))
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

    /// A prepared light of `material` on `prim` (what the light set builds).
    fn area_light_info(g: &GeometryStore, prim: PrimRef, material: &Material) -> AreaLight {
        let mut light = AreaLight::new(prim, 0);
        light.prepare(g, std::slice::from_ref(material));
        light
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
            time: 0.0,
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
                    let general = sample_area_general(
                        &g,
                        prim,
                        info.area,
                        &material,
                        &[],
                        &hit,
                        -dir,
                        u,
                        0.0,
                    );
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
}
