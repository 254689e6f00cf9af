//! What integrators ask of the world, and all they may ask (Mitsuba's `Scene` interface, pbrt's
//! `SurfaceInteraction::GetBSDF` and `SampleLd`): the material and BSDF at a hit, emitted and
//! escaped radiance, a light sample seen from a hit and the pdf with which NEE would have chosen
//! a point on an emitter. Integrators do not reach into the light set, materials or textures.

use std::cell::Cell;

use super::World;
use crate::geometry::primitive::{Intersection, NO_LIGHT};
use crate::geometry::{Ray, SurfaceHit};
use crate::light::{EnvPdf, Light, LightSample, LightScene};
use crate::material::local_shading::LocalSurface;
use crate::material::texture::SharedFootprint;
use crate::material::{Bsdf, Material, eval, normal_map};
use crate::math::{Vec2, Vec3};

impl World {
    /// Expands an intersection found on `ray` (by [`World::intersect_raw`]) into full shading
    /// attributes.
    #[inline]
    pub fn surface_hit(&self, ray: &Ray, isect: &Intersection) -> SurfaceHit {
        self.geometry.surface_hit(ray, isect)
    }

    /// The material of the surface at `hit`.
    #[inline]
    pub fn material(&self, hit: &SurfaceHit) -> &Material {
        &self.materials[hit.material as usize]
    }

    /// The material that scatters light at `hit`: [`World::material`], or for a pbrt-v4 `mix`
    /// the component chosen at this hit ([`eval::resolve_mix`]). Emission, alpha and medium
    /// interfaces stay those of [`World::material`].
    #[inline]
    pub fn surface_material(&self, hit: &SurfaceHit) -> &Material {
        let m = self.material(hit);
        if m.mix().is_none() {
            return m;
        }
        eval::resolve_mix(&self.materials, &self.textures, hit.material, hit)
    }

    /// Replaces the shading normal and tangent of `hit` by its material's normal map, or its
    /// bump map (pbrt-v4 `displacement`), if any.
    #[inline]
    pub fn apply_normal_map(&self, hit: &mut SurfaceHit) {
        self.perturb_shading(self.surface_material(hit), hit);
    }

    /// pbrt-v4's `GetBSDF` order: a normal map if the material has one, else its bump map.
    /// `material` is [`World::surface_material`] of `hit`.
    #[inline]
    pub fn perturb_shading(&self, material: &Material, hit: &mut SurfaceHit) {
        self.perturb_shading_shared(material, hit, None);
    }

    /// [`World::perturb_shading`], the normal map's lookup keeping its addressing in `shared`.
    #[inline]
    fn perturb_shading_shared(
        &self,
        material: &Material,
        hit: &mut SurfaceHit,
        shared: Option<&Cell<SharedFootprint>>,
    ) {
        if material.normal_texture.is_some() {
            normal_map::apply_normal_map_shared(material, &self.textures, hit, shared);
        } else if material.displacement.is_some()
            && let Some(d) = self.geometry.pbrt_shading_derivatives(hit)
        {
            eval::bump(material, &self.textures, hit, &d);
        }
    }

    /// The BSDF at `hit` (pbrt's `GetBSDF`): applies the normal or bump map to `hit`'s shading
    /// frame, then evaluates the material's textures there.
    #[inline]
    pub fn bsdf(&self, hit: &mut SurfaceHit) -> Bsdf {
        self.shade_surface(self.surface_material(hit), hit)
    }

    /// [`World::perturb_shading`] then [`World::material_bsdf`]: the BSDF of `material`
    /// ([`World::surface_material`] of `hit`) after its normal or bump map, the two sharing
    /// the bilinear addressing of their texture lookups ([`eval::HitTextures`]; ToyCar's body
    /// reads four 1024² textures at the same uv).
    #[inline]
    pub fn shade_surface(&self, material: &Material, hit: &mut SurfaceHit) -> Bsdf {
        let shared = Cell::new(SharedFootprint::NONE);
        self.perturb_shading_shared(material, hit, Some(&shared));
        Bsdf::from_material_shared(material, &self.textures, hit, Some(&shared))
    }

    /// The BSDF of `material` ([`World::surface_material`] of `hit`) at `hit`, whose shading
    /// frame [`World::perturb_shading`] has already set: the second half of [`World::bsdf`],
    /// for a caller that resolves the material once for several queries.
    #[inline]
    pub fn material_bsdf(&self, material: &Material, hit: &SurfaceHit) -> Bsdf {
        Bsdf::from_material(material, &self.textures, hit)
    }

    /// KHR_materials_clearcoat: the coat's world-space normal at `hit`, `None` without a coat.
    /// Must be asked before [`World::bsdf`] applies the base's normal map, which the coat ignores.
    #[inline]
    pub fn clearcoat_normal(&self, hit: &SurfaceHit) -> Option<Vec3> {
        self.material_clearcoat_normal(self.surface_material(hit), hit)
    }

    /// [`World::clearcoat_normal`] with `material` = [`World::surface_material`] of `hit`.
    #[inline]
    pub fn material_clearcoat_normal(&self, material: &Material, hit: &SurfaceHit) -> Option<Vec3> {
        (material.metallic_roughness().clearcoat > 0.0)
            .then(|| eval::clearcoat_normal(material, &self.textures, hit))
    }

    /// The parameters of the raycast/Whitted local shading models at `hit`.
    #[inline]
    pub fn local_surface(&self, hit: &SurfaceHit) -> LocalSurface {
        LocalSurface::new(self.surface_material(hit), &self.textures, hit)
    }

    /// Base colour at `hit` (factor × texture × vertex colour): the `albedo` view.
    #[inline]
    pub fn base_color(&self, hit: &SurfaceHit) -> Vec3 {
        eval::base_color(self.surface_material(hit), &self.textures, hit)
    }

    /// Radiance the surface at `hit` emits toward `wo` (unit, away from the surface).
    #[inline]
    pub fn emitted(&self, hit: &SurfaceHit, wo: Vec3) -> Vec3 {
        // Every primitive that can emit is an area light (`World::build`): the others are of a
        // material that does not emit, of zero area, or triangles whose emissive texture is
        // black over their whole footprint (`light::emission`), where the lookup would be zero.
        // The exception is an unlit surface (KHR_materials_unlit): it shows its base colour but
        // is not a light (NEE never samples it), so it is looked up here too.
        let material = self.material(hit);
        if hit.light == NO_LIGHT && !material.is_unlit() {
            return Vec3::ZERO;
        }
        eval::emitted(material, &self.textures, hit, wo)
    }

    /// Radiance from the lights at infinity along an escaping ray's unit direction `d`,
    /// unweighted (camera rays, paths without NEE).
    #[inline]
    pub fn escaped(&self, d: Vec3) -> Vec3 {
        self.lights.escaped(d)
    }

    /// The lights at infinity along a sampled escaping direction `d`, each light's radiance
    /// passed to `contribution(le, pdf)` with the solid-angle pdf with which NEE (drawing
    /// environment directions from `env`, a uniform environment about `uniform_n`) would have
    /// sampled `d` from that light, selection included; the results summed (see
    /// `LightSet::escaped_mis`).
    #[inline]
    pub fn escaped_mis(
        &self,
        d: Vec3,
        env: EnvPdf,
        uniform_n: Vec3,
        contribution: impl FnMut(Vec3, f32) -> Vec3,
    ) -> Vec3 {
        self.lights.escaped_mis(d, env, uniform_n, contribution)
    }

    /// Next-event estimation from `hit` (Mitsuba's `sample_emitter_direction`, pbrt's
    /// `SampleLd`): picks a light with `u_light` (by power, or by the light BVH's importance from
    /// `hit.p` and `n_offset`) and a point or direction on it with `u`. The shadow ray leaves
    /// `hit` offset along `n_offset` (the geometric normal on the side the light is sampled
    /// from, zero in a medium); it is not traced here. An environment map is sampled from the
    /// density `env`: [`EnvPdf::Compensated`] only when the sample is combined by MIS with a
    /// strategy that reaches every direction (it leaves directions dimmer than the map's mean
    /// to that strategy).
    #[inline]
    pub fn sample_light(
        &self,
        hit: &SurfaceHit,
        n_offset: Vec3,
        u_light: f32,
        u: Vec2,
        env: EnvPdf,
    ) -> Option<LightSample> {
        let mut ls = self
            .lights
            .sample(&self.light_scene(), hit, n_offset, u_light, u, env)?;
        // The shadow ray sees the scene at the hit's moment.
        ls.shadow.time = hit.time;
        Some(ls)
    }

    /// [`World::sample_light`] with one 2D number for both the choice and the point (sample
    /// reuse, see `LightSet::sample_reuse`); `u_spare` stands in for the remapped x of lights
    /// chosen too rarely for it to keep enough bits. A uniform environment is sampled about
    /// `uniform_n` (`light::sample_uniform_env`; zero for the whole sphere), which MIS of the
    /// vertex's escaping BSDF samples must pass to [`World::escaped_mis`] too. The path
    /// tracer's NEE uses this.
    #[inline]
    pub fn sample_light_reuse(
        &self,
        hit: &SurfaceHit,
        n_offset: Vec3,
        u: Vec2,
        u_spare: f32,
        env: EnvPdf,
        uniform_n: Vec3,
    ) -> Option<LightSample> {
        let mut ls = self.lights.sample_reuse(
            &self.light_scene(),
            hit,
            n_offset,
            u,
            u_spare,
            env,
            uniform_n,
        )?;
        ls.shadow.time = hit.time;
        Some(ls)
    }

    /// Solid-angle pdf with which [`World::sample_light`] from `p` with `n_offset` = `n` would
    /// have chosen the point `emitter` (a hit on an area light, selection included), for MIS of a
    /// BSDF-sampled hit. 0 if `emitter` is not on an area light. `n` must be the `n_offset` the
    /// light sample at `p` was (or would have been) drawn with: the light BVH's choice depends
    /// on it.
    #[inline]
    pub fn emitter_pdf(&self, p: Vec3, n: Vec3, emitter: &SurfaceHit) -> f32 {
        if emitter.light == NO_LIGHT {
            return 0.0;
        }
        self.lights
            .pdf_area(&self.geometry, emitter.light, p, n, emitter)
    }

    /// Number of lights [`World::sample_light`] chooses from.
    #[inline]
    pub fn light_count(&self) -> usize {
        self.lights.lights.len()
    }

    /// What the lights need from the world to sample and evaluate themselves
    /// ([`Light::sample_le`], [`Light::phi`], ...).
    #[inline]
    pub fn light_scene(&self) -> LightScene<'_> {
        self.lights
            .scene(&self.geometry, &self.materials, &self.textures)
    }

    /// All lights; area lights come first (see `World::build`).
    #[inline]
    pub fn lights(&self) -> &[Light] {
        &self.lights.lights
    }
}
