//! Vertex connection and merging (Georgiev, Křivánek, Davidovič & Slusallek 2012, "Light
//! transport simulation with vertex connection and merging", and the recursive MIS of its
//! technical report "Implementing vertex connection and merging", read as a specification; the
//! same combination as Hachisuka et al. 2012's unified path sampling).
//!
//! Each iteration traces one light subpath per pixel of the film window and stores its
//! non-specular vertices; then one camera subpath per pixel, which at each non-specular vertex
//! takes four kinds of strategies: the emitter it hits (s = 0), a light point sampled for it
//! (s = 1, next-event estimation), a connection to every vertex of the light subpath paired with
//! its pixel (s ≥ 2), and a merge with every stored light vertex of any pixel within the
//! iteration's radius (photon density estimation). Light subpath vertices are also joined to the
//! camera (t = 1, light tracing), splatted. All are weighted by the power heuristic over every
//! strategy that could have made the path, merges included, counted with the number of light
//! paths N and the kernel's disc (η = N π r², the ratio of a merge's density to a connection's).
//!
//! The weights are computed from three running quantities per subpath, dVCM, dVC and dVM,
//! updated at each vertex from the forward and reverse densities (the technical report's eqs.
//! for the light and camera subpaths): a strategy's weight then needs only the two vertices
//! being joined, O(1) per strategy.
//!
//! Radius: r_i = r_0 · i^((α−1)/2) for iteration i = 1, 2, … (α = 3/4, the paper's
//! suggestion), a function of the iteration's index alone, so iterations are independent: a
//! frame splits into sample ranges exactly. With merging off ([`Vcm::new`]'s `merge`) the
//! estimator is bidirectional path tracing with one light subpath per camera subpath, unbiased.
//!
//! Densities: area conversions use the geometric normal, the throughputs the shading normal (as
//! the path tracer's); Russian roulette is left out of the weights (they stay a partition of
//! one; the throughput divides by the survival probability). Lights at infinity follow the
//! technical report's background light: a light subpath leaves the scene's bounding disk (its
//! first segment's length and the disk's cosine take no part), next-event estimation and an
//! escaping camera subpath see a direction density, and each light at infinity is weighted
//! as a light of its own. A thin lens needs nothing more: the lens point has the same density
//! (uniform over the lens) whether the camera subpath or a join to the camera (t = 1) chose
//! it, so only the direction densities enter the weights, as for a pinhole.
//!
//! Spectral mode: a camera vertex merges with light vertices of other pixels' light subpaths, so
//! every subpath of an iteration carries the same wavelengths (the driver puts the iteration's on
//! `set`, as SPPM's; pbrt-v4's `SPPMIntegrator` shares one set per iteration the same way).
//! Emission, BSDFs, connections and merges are per wavelength in the lanes of the `Vec3`s; the
//! MIS densities are those of the hero wavelength's BSDFs, which are the RGB ones but for a
//! dispersive surface. A dispersive vertex keeps lane 0 alone, × 3, on the subpath that met it;
//! a join of two such subpaths counts the 3 once. Splats and pixel values reach the film
//! through `PathSettings::to_film`.

use super::RayStats;
use super::lighttracer::{Splat, sample_emission};
use super::photon_grid::PointGrid;
use super::settings::PathSettings;
use super::vertex::Vertex;
use crate::camera::CameraImportance;
use crate::geometry::Ray;
use crate::geometry::primitive::{NO_LIGHT, SurfaceHit};
use crate::light::EnvPdf;
use crate::material::bsdf::Bsdf;
use crate::material::bxdf::TransportMode;
use crate::math::{Frame, PI, Vec3};
use crate::sampling::SampleStream;
use crate::world::World;

/// The radius exponent α: r_i = r_0 · i^((α−1)/2).
pub const ALPHA: f32 = 0.75;

/// The power heuristic (exponent 2) applied to a density ratio.
#[inline]
fn mis(x: f32) -> f32 {
    x * x
}

/// The factor a join of a camera and a light subpath takes in spectral mode: 1/3 when both kept
/// their hero wavelength alone, each × 3, since the 3 of the one set of wavelengths they share
/// counts once (pbrt-v4 terminates the secondary wavelengths of that set); else 1.
#[inline]
fn hero_once(camera: bool, light: bool) -> f32 {
    if camera && light { 1.0 / 3.0 } else { 1.0 }
}

/// The merge radius of iteration `index` (0-based): r_0 · (index + 1)^((α−1)/2).
pub fn radius(r0: f32, index: u32) -> f32 {
    r0 * ((index as f64 + 1.0).powf((ALPHA as f64 - 1.0) / 2.0)) as f32
}

/// A stored light subpath vertex: what its joins to the camera, its connections and its merges
/// read of its shading (position, normals, BSDF), the throughput that reached it, the segments
/// from the light (first hit: 1) and its MIS quantities. Not a whole [`Vertex`]: the surface
/// hit's texture coordinates, differentials and ids are spent once the BSDF is built, and every
/// light vertex of an iteration is stored and copied into one array, so its size is the store's
/// memory and copying (docs/DESIGN.md, "Photon mapping: SPPM and VCM").
pub struct LightVertex {
    pub p: Vec3,
    pub p_error: Vec3,
    /// The geometric normal, oriented as [`Vertex::ng`].
    pub ng: Vec3,
    pub frame: Frame,
    /// Toward where the light subpath came from, in `frame`.
    pub wo_local: Vec3,
    pub bsdf: Bsdf,
    pub beta: Vec3,
    /// Segments from the light (a light subpath is cut at `u16::MAX`, far beyond any
    /// `max_depth` that renders).
    pub len: u16,
    /// Spectral mode: the light subpath met a dispersive surface and kept its hero wavelength
    /// alone (lane 0, × 3 in `beta`).
    pub hero_only: bool,
    pub d_vcm: f32,
    pub d_vc: f32,
    pub d_vm: f32,
}

/// One iteration's constants.
pub struct Vcm<'a> {
    pub world: &'a World,
    pub camera: &'a CameraImportance,
    pub set: &'a PathSettings,
    /// The image's pixels over the window's (light tracing's splats and its density).
    pub scale: f32,
    pub radius: f32,
    /// 1 / η: the merges' kernel normalisation 1 / (N π r²).
    vm_norm: f32,
    /// mis(η) when merging, else 0.
    vm_weight: f32,
    /// mis(1 / η).
    vc_weight: f32,
    merge: bool,
    /// The iteration's shutter time (0 for a still): every subpath of the iteration, light and
    /// camera, and every join is at this moment, so merges join vertices of one scene
    /// (docs/DESIGN.md, "Vertex connection and merging" and motion blur).
    pub time: f32,
}

impl<'a> Vcm<'a> {
    /// The constants of an iteration of radius `radius` with `light_paths` light subpaths, at
    /// shutter time `time` (0 for a still; `world` and `camera` are the scene and the camera's
    /// importance at that time).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        world: &'a World,
        camera: &'a CameraImportance,
        set: &'a PathSettings,
        scale: f32,
        radius: f32,
        light_paths: u64,
        merge: bool,
        time: f32,
    ) -> Vcm<'a> {
        let eta = light_paths as f32 * PI * radius * radius;
        Vcm {
            world,
            camera,
            set,
            scale,
            radius,
            vm_norm: 1.0 / eta,
            vm_weight: if merge { mis(eta) } else { 0.0 },
            vc_weight: mis(1.0 / eta),
            merge,
            time,
        }
    }

    /// Traces one light subpath, pushing its stored vertices onto `out` (and their positions
    /// onto `points`) and splatting its joins to the camera into `film`.
    pub fn light_path(
        &self,
        s: &mut SampleStream,
        stats: &mut RayStats,
        out: &mut Vec<LightVertex>,
        points: &mut Vec<Vec3>,
        film: &mut impl Splat,
    ) {
        let world = self.world;
        let Some(em) = sample_emission(world, s, self.time) else {
            return;
        };
        // A moving light where it is at the iteration's time.
        let light = world.lights.posed(em.index, self.time);
        // A light at infinity: its "position" is the direction it shines from, which next-event
        // estimation samples per solid angle; its origin on the scene's disk is no vertex of
        // the path, so the first segment's length takes no part in the densities (the
        // technical report's background light).
        let infinite = light.is_infinite();
        let emission_pdf_w = em.pmf * em.le.pdf_pos * em.le.pdf_dir;
        let direct_pdf_a = if infinite {
            em.pmf * self.infinite_direct_pdf(em.index, -em.le.ray.d.normalize())
        } else {
            em.pmf * em.le.pdf_pos
        };
        let cos_light = em.le.cos();
        // The light's emission at the iteration's wavelengths in spectral mode.
        let le = self
            .set
            .light_emission(&world.lights, em.index as u32, em.le.le);
        let mut beta = le * (cos_light / emission_pdf_w);
        if !(beta.max_element() > 0.0) || !beta.is_finite() {
            return;
        }
        let inv_beta0 = 1.0 / beta.max_element();
        let mut d_vcm = mis(direct_pdf_a / emission_pdf_w);
        let mut d_vc = if light.is_delta() {
            0.0
        } else {
            mis(cos_light / emission_pdf_w)
        };
        let mut d_vm = d_vc * self.vc_weight;
        let mut ray = em.le.ray.with_time(self.time);
        let mut v = Vertex::unshaded(SurfaceHit::EMPTY);
        let mut len = 0u32;
        let max_len = self.set.max_depth.min(u16::MAX as u32);
        let mut hero_only = false;
        loop {
            stats.rays += 1;
            if !world.intersect_filtered_into(&ray, &self.set.footprint, &mut v.hit) {
                return;
            }
            len += 1;
            let wo = -ray.d.normalize();
            v.shade(world, wo);
            // Spectral mode: the BSDF at the iteration's wavelengths; a dispersive one keeps the
            // hero wavelength alone, weighted by the number of wavelengths (as the path tracer).
            if let Some(w) = &self.set.wavelengths {
                if !hero_only && v.bsdf.disperses() {
                    hero_only = true;
                    beta = Vec3::new(3.0 * beta.x, 0.0, 0.0);
                }
                v.bsdf.make_spectral(w.lambda, &world.bsdf_spectra);
            }
            let cos_in = mis(v.ng.dot(wo).abs());
            let g = if infinite && len == 1 {
                1.0
            } else {
                mis((v.hit.p - ray.o).length_squared())
            };
            d_vcm *= g / cos_in;
            d_vc /= cos_in;
            d_vm /= cos_in;
            let u_cam = s.next_2d();
            if !v.bsdf.is_specular() && !v.bsdf.is_black() {
                out.push(LightVertex {
                    p: v.hit.p,
                    p_error: v.hit.p_error,
                    ng: v.ng,
                    frame: v.frame,
                    wo_local: v.wo_local,
                    bsdf: v.bsdf,
                    beta,
                    len: len as u16,
                    hero_only,
                    d_vcm,
                    d_vc,
                    d_vm,
                });
                points.push(v.hit.p);
                self.to_camera(out.last().expect("just pushed"), u_cam, stats, film);
            }
            if len >= max_len {
                return;
            }
            let u_lobe = s.next_1d();
            let u_dir = s.next_2d();
            let Some((bs, wi, weight)) = v.sample_scatter(TransportMode::Importance, u_lobe, u_dir)
            else {
                return;
            };
            beta *= weight;
            if !(beta.max_element() > 0.0) || !beta.is_finite() {
                return;
            }
            let rev = if bs.specular {
                bs.pdf
            } else {
                v.bsdf.pdf(bs.wi, v.wo_local)
            };
            (d_vcm, d_vc, d_vm) = self.scatter(
                (d_vcm, d_vc, d_vm),
                v.ng.dot(wi).abs(),
                bs.pdf,
                rev,
                bs.specular,
            );
            if len >= self.set.rr_depth {
                let u_rr = s.next_1d();
                let q = (beta.max_element() * inv_beta0 * self.set.rr_scale).min(1.0);
                if q < 1.0 {
                    if u_rr >= q {
                        return;
                    }
                    beta /= q;
                }
            }
            ray = Ray::spawn(v.hit.p, v.hit.p_error, v.ng, wi).with_time(self.time);
        }
    }

    /// The technical report's update of (dVCM, dVC, dVM) for a direction sampled at a vertex
    /// with density `pdf` (reverse density `rev`), leaving at |cos| `cos_out` of the geometric
    /// normal. A Dirac sample cancels its own densities.
    #[inline]
    fn scatter(
        &self,
        (d_vcm, d_vc, d_vm): (f32, f32, f32),
        cos_out: f32,
        pdf: f32,
        rev: f32,
        specular: bool,
    ) -> (f32, f32, f32) {
        if specular {
            (0.0, d_vc * mis(cos_out), d_vm * mis(cos_out))
        } else {
            let k = mis(cos_out / pdf);
            (
                mis(1.0 / pdf),
                k * (d_vc * mis(rev) + d_vcm + self.vm_weight),
                k * (d_vm * mis(rev) + d_vcm * self.vc_weight + 1.0),
            )
        }
    }

    /// The solid-angle density with which a light sample ([`Vcm::light_sample`]) picks the
    /// direction `d` (towards the light) from the light at infinity `index`, its choice not
    /// included: 1 for a direction's delta.
    fn infinite_direct_pdf(&self, index: usize, d: Vec3) -> f32 {
        let light = self.world.lights.posed(index, self.time);
        if light.is_delta() {
            1.0
        } else {
            light
                .le_pdf(d, EnvPdf::Full, Vec3::ZERO)
                .map_or(0.0, |(_, pdf)| pdf)
        }
    }

    /// What the lights at infinity send along the escaping camera ray direction `d` (unit),
    /// each weighted against the strategies that could have made its path (s = 0 of the
    /// technical report's background light), from the camera subpath's quantities after its
    /// last scattering. Not yet multiplied by the throughput.
    fn escaped(&self, d: Vec3, d_vcm: f32, d_vc: f32) -> Vec3 {
        let world = self.world;
        let scene = world.light_scene();
        let mut l = Vec3::ZERO;
        for &i in &world.lights.infinite {
            let i = i as usize;
            let light = world.lights.posed(i, self.time);
            let Some(le) = light.le(d) else {
                continue;
            };
            if le == Vec3::ZERO {
                continue;
            }
            let le = self.set.light_emission(&world.lights, i as u32, le);
            let pmf = world.lights.distribution.discrete_pdf(i);
            let (pos, dir) = light.pdf_le(&scene, Vec3::ZERO, -d);
            let w_camera =
                mis(pmf * self.infinite_direct_pdf(i, d)) * d_vcm + mis(pmf * pos * dir) * d_vc;
            l += le / (1.0 + w_camera);
        }
        l
    }

    /// Joins the light vertex `lv` to the camera (t = 1) and splats it, weighted.
    fn to_camera(
        &self,
        lv: &LightVertex,
        u_cam: crate::math::Vec2,
        stats: &mut RayStats,
        film: &mut impl Splat,
    ) {
        let v = lv;
        if lv.len as u32 > self.set.max_depth {
            return;
        }
        let Some(cs) = self.camera.sample_wi(v.p, u_cam) else {
            return;
        };
        let wi_local = v.frame.to_local(cs.wi);
        if !v.bsdf.side_consistent(wi_local, cs.wi.dot(v.ng)) {
            return;
        }
        let f = v
            .bsdf
            .eval_mode(v.wo_local, wi_local, TransportMode::Importance);
        let corr = TransportMode::Importance.shading_normal_correction(
            v.wo_local,
            wi_local,
            Vec3::Z,
            v.frame.to_local(v.ng),
        );
        let c = lv.beta * f * (wi_local.z.abs() * corr * cs.we / cs.pdf);
        if !(c.max_element() > 0.0) {
            return;
        }
        let (_, camera_pdf_w) = self.camera.pdf_we(&Ray::new(cs.p_lens, -cs.wi));
        let camera_pdf_a = camera_pdf_w * v.ng.dot(cs.wi).abs() / (cs.dist * cs.dist) * self.scale;
        let rev = v.bsdf.pdf(wi_local, v.wo_local);
        let w_light = mis(camera_pdf_a) * (self.vm_weight + lv.d_vcm + lv.d_vc * mis(rev));
        let weight = 1.0 / (1.0 + w_light);
        stats.shadow_rays += 1;
        let shadow = Ray::spawn_to(v.p, v.p_error, v.ng, cs.p_lens, Vec3::ZERO, Vec3::ZERO)
            .with_time(self.time);
        if !self.world.occluded(&shadow) {
            film.splat(cs.raster, self.set.to_film(c * (self.scale * weight)));
        }
    }

    /// Traces the camera subpath of `ray` (filter weight `weight`) and returns what it gathers
    /// for its pixel: emitters hit, light samples, connections to `paired` (its pixel's light
    /// subpath) and merges with the vertices in `grid` (over `all`, positions `points`): RGB, or
    /// in spectral mode the lanes of `self.set`'s wavelengths (for `PathSettings::to_film`).
    #[allow(clippy::too_many_arguments)]
    pub fn camera_path(
        &self,
        ray: &Ray,
        weight: f32,
        s: &mut SampleStream,
        stats: &mut RayStats,
        paired: &[LightVertex],
        grid: &PointGrid,
        all: &[LightVertex],
        points: &[Vec3],
    ) -> Vec3 {
        let world = self.world;
        let set = self.set;
        let (_, camera_pdf_w) = self.camera.pdf_we(ray);
        if !(camera_pdf_w > 0.0) {
            return Vec3::ZERO;
        }
        let mut beta = Vec3::splat(weight);
        let mut d_vcm = mis(1.0 / (camera_pdf_w * self.scale));
        let (mut d_vc, mut d_vm) = (0.0f32, 0.0f32);
        let mut l = Vec3::ZERO;
        let mut ray = *ray;
        let mut v = Vertex::unshaded(SurfaceHit::EMPTY);
        let mut len = 0u32;
        let mut hero_only = false;
        let scene = world.light_scene();
        loop {
            stats.rays += 1;
            if !world.intersect_filtered_into(&ray, &set.footprint, &mut v.hit) {
                if !world.lights.infinite.is_empty() {
                    let d = ray.d.normalize();
                    if len > 0 {
                        l += beta * self.escaped(d, d_vcm, d_vc);
                    } else if !set.transparent {
                        l += beta * set.escaped(world, d);
                    }
                }
                return l;
            }
            len += 1;
            let wo = -ray.d.normalize();
            let dist2 = (v.hit.p - ray.o).length_squared();
            let cos_in = mis(v.hit.ng.dot(wo).abs());
            d_vcm *= mis(dist2) / cos_in;
            d_vc /= cos_in;
            d_vm /= cos_in;
            // An emitter hit (s = 0).
            let le = world.emitted(&v.hit, wo);
            if le != Vec3::ZERO {
                let le = set.light_emission(&world.lights, v.hit.light, le);
                let w = if len == 1 || v.hit.light == NO_LIGHT {
                    1.0
                } else {
                    let li = v.hit.light as usize;
                    let pmf = world.lights.distribution.discrete_pdf(li);
                    let (pos, dir) = world
                        .lights
                        .posed(li, self.time)
                        .pdf_le(&scene, v.hit.ng, wo);
                    let w_camera = mis(pmf * pos) * d_vcm + mis(pmf * pos * dir) * d_vc;
                    1.0 / (1.0 + w_camera)
                };
                l += beta * le * w;
            }
            if len > set.max_depth {
                return l;
            }
            v.shade(world, wo);
            if let Some(w) = &set.wavelengths {
                if !hero_only && v.bsdf.disperses() {
                    hero_only = true;
                    beta = Vec3::new(3.0 * beta.x, 0.0, 0.0);
                }
                v.bsdf.make_spectral(w.lambda, &world.bsdf_spectra);
            }
            let u_light = s.next_1d();
            let u_point = s.next_2d();
            if !v.bsdf.is_specular() && !v.bsdf.is_black() {
                let d = (d_vcm, d_vc, d_vm);
                l += beta * self.light_sample(&v, d, u_light, u_point, stats);
                for lv in paired {
                    if len + lv.len as u32 > set.max_depth {
                        break;
                    }
                    l += beta * self.connect(&v, d, lv, hero_only, stats);
                }
                if self.merge {
                    l += beta * self.merge_at(&v, len, hero_only, d, grid, all, points);
                }
            }
            let u_lobe = s.next_1d();
            let u_dir = s.next_2d();
            let Some(bs) = v.bsdf.sample(v.wo_local, u_lobe, u_dir) else {
                return l;
            };
            let wi = v.frame.to_world(bs.wi);
            if !v.bsdf.side_consistent(bs.wi, wi.dot(v.ng)) {
                return l;
            }
            beta *= bs.f * (bs.wi.z.abs() / bs.pdf);
            if !(beta.max_element() > 0.0) || !beta.is_finite() {
                return l;
            }
            let rev = if bs.specular {
                bs.pdf
            } else {
                v.bsdf.pdf(bs.wi, v.wo_local)
            };
            (d_vcm, d_vc, d_vm) = self.scatter(
                (d_vcm, d_vc, d_vm),
                v.ng.dot(wi).abs(),
                bs.pdf,
                rev,
                bs.specular,
            );
            if len >= set.rr_depth {
                let u_rr = s.next_1d();
                let q = (beta.max_element() * set.rr_scale).min(1.0);
                if q < 1.0 {
                    if u_rr >= q {
                        return l;
                    }
                    beta /= q;
                }
            }
            ray = Ray::spawn(v.hit.p, v.hit.p_error, v.ng, wi).with_time(self.time);
        }
    }

    /// A light point sampled for the camera vertex `v` (s = 1), the light chosen by power as
    /// light subpaths choose it and an area light's point uniform by area, so the densities
    /// are the light subpaths' own. Weighted; not yet multiplied by the camera throughput.
    fn light_sample(
        &self,
        v: &Vertex,
        (d_vcm, d_vc, _): (f32, f32, f32),
        u_light: f32,
        u: crate::math::Vec2,
        stats: &mut RayStats,
    ) -> Vec3 {
        let world = self.world;
        if world.lights.is_empty() {
            return Vec3::ZERO;
        }
        let (li, pmf) = world.lights.distribution.sample_discrete(u_light);
        if !(pmf > 0.0) {
            return Vec3::ZERO;
        }
        // A moving light where it is at the iteration's time.
        let light = world.lights.posed(li, self.time);
        let scene = world.light_scene();
        // The light's emission at the iteration's wavelengths in spectral mode.
        let emission = |rgb: Vec3| self.set.light_emission(&world.lights, li as u32, rgb);
        // (direction, radiance or intensity / d², solid-angle density with the choice, the
        // emission density with the choice, |cos| at the light, shadow ray, delta)
        let (wi, li_val, direct_pdf_w, emission_pdf_w, cos_light, shadow, delta) =
            if let Some(area) = light.as_area() {
                let lp = area.sample_point(&world.geometry, u);
                let to = lp.p - v.hit.p;
                let dist2 = to.length_squared();
                if !(dist2 > 0.0) {
                    return Vec3::ZERO;
                }
                let wi = to / dist2.sqrt();
                let (pos, dir) = light.pdf_le(&scene, lp.ng, -wi);
                let cos_light = lp.ng.dot(wi).abs();
                let le = light.l(&scene, &lp, -wi);
                if !(pos > 0.0 && cos_light > 0.0) || le == Vec3::ZERO {
                    return Vec3::ZERO;
                }
                let shadow = Ray::spawn_to(v.hit.p, v.hit.p_error, v.ng, lp.p, lp.p_error, lp.ng);
                (
                    wi,
                    emission(le),
                    pmf * pos * dist2 / cos_light,
                    pmf * pos * dir,
                    cos_light,
                    shadow,
                    false,
                )
            } else if light.is_infinite() {
                // A direction, sampled per solid angle (a delta's weight for a distant light);
                // emitted from the scene's disk, whose cosine is 1.
                let Some(ls) = light.sample_li(&scene, &v.hit, v.ng, u, EnvPdf::Full, Vec3::ZERO)
                else {
                    return Vec3::ZERO;
                };
                if ls.li == Vec3::ZERO {
                    return Vec3::ZERO;
                }
                let (pos, dir) = light.pdf_le(&scene, Vec3::ZERO, -ls.wi);
                let dir = if ls.delta { 1.0 } else { dir };
                (
                    ls.wi,
                    emission(ls.li),
                    pmf * ls.pdf,
                    pmf * pos * dir,
                    1.0,
                    ls.shadow,
                    ls.delta,
                )
            } else {
                let Some(ls) = light.sample_li(&scene, &v.hit, v.ng, u, EnvPdf::Full, Vec3::ZERO)
                else {
                    return Vec3::ZERO;
                };
                if ls.li == Vec3::ZERO || !ls.delta {
                    return Vec3::ZERO;
                }
                let p = ls.shadow.o + ls.shadow.d;
                let dist2 = (p - v.hit.p).length_squared();
                let (_, dir) = light.pdf_le(&scene, Vec3::ZERO, -ls.wi);
                // A point's area density is a delta of weight 1: per solid angle, d².
                (
                    ls.wi,
                    emission(ls.li) * dist2,
                    pmf * dist2,
                    pmf * dir,
                    1.0,
                    ls.shadow,
                    true,
                )
            };
        let wi_local = v.frame.to_local(wi);
        if !v.bsdf.side_consistent(wi_local, wi.dot(v.ng)) {
            return Vec3::ZERO;
        }
        let f = v.bsdf.eval(v.wo_local, wi_local);
        if f == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let pdf_dir = v.bsdf.pdf(v.wo_local, wi_local);
        let pdf_rev = v.bsdf.pdf(wi_local, v.wo_local);
        let w_light = if delta {
            0.0
        } else {
            mis(pdf_dir / direct_pdf_w)
        };
        let cos_here = v.ng.dot(wi).abs();
        let w_camera = mis(emission_pdf_w * cos_here / (direct_pdf_w * cos_light))
            * (self.vm_weight + d_vcm + d_vc * mis(pdf_rev));
        let weight = 1.0 / (w_light + 1.0 + w_camera);
        stats.shadow_rays += 1;
        if world.occluded(&shadow.with_time(self.time)) {
            return Vec3::ZERO;
        }
        f * li_val * (wi_local.z.abs() * weight / direct_pdf_w)
    }

    /// Joins the camera vertex `v` to the light vertex `lv` (s ≥ 2), weighted. `hero_only`:
    /// the camera subpath kept its hero wavelength alone (spectral mode).
    fn connect(
        &self,
        v: &Vertex,
        (d_vcm, d_vc, _): (f32, f32, f32),
        lv: &LightVertex,
        hero_only: bool,
        stats: &mut RayStats,
    ) -> Vec3 {
        let q = lv;
        let to = q.p - v.hit.p;
        let dist2 = to.length_squared();
        if !(dist2 > 0.0) {
            return Vec3::ZERO;
        }
        let dir = to / dist2.sqrt();
        let wc = v.frame.to_local(dir);
        let wl = q.frame.to_local(-dir);
        if !v.bsdf.side_consistent(wc, dir.dot(v.ng)) || !q.bsdf.side_consistent(wl, -dir.dot(q.ng))
        {
            return Vec3::ZERO;
        }
        let corr = TransportMode::Importance.shading_normal_correction(
            q.wo_local,
            wl,
            Vec3::Z,
            q.frame.to_local(q.ng),
        );
        let f = v.bsdf.eval(v.wo_local, wc)
            * q.bsdf.eval_mode(q.wo_local, wl, TransportMode::Importance)
            * (wc.z.abs() * wl.z.abs() * corr / dist2);
        if !(f.max_element() > 0.0) {
            return Vec3::ZERO;
        }
        let (cam_dir, cam_rev) = (v.bsdf.pdf(v.wo_local, wc), v.bsdf.pdf(wc, v.wo_local));
        let (light_dir, light_rev) = (q.bsdf.pdf(q.wo_local, wl), q.bsdf.pdf(wl, q.wo_local));
        let cam_dir_a = cam_dir * q.ng.dot(dir).abs() / dist2;
        let light_dir_a = light_dir * v.ng.dot(dir).abs() / dist2;
        let w_light = mis(cam_dir_a) * (self.vm_weight + lv.d_vcm + lv.d_vc * mis(light_rev));
        let w_camera = mis(light_dir_a) * (self.vm_weight + d_vcm + d_vc * mis(cam_rev));
        let weight = 1.0 / (w_light + 1.0 + w_camera);
        stats.shadow_rays += 1;
        let shadow =
            Ray::spawn_to(v.hit.p, v.hit.p_error, v.ng, q.p, q.p_error, q.ng).with_time(self.time);
        if self.world.occluded(&shadow) {
            return Vec3::ZERO;
        }
        f * lv.beta * (weight * hero_once(hero_only, lv.hero_only))
    }

    /// Merges the camera vertex `v` (`len` segments from the camera) with every stored light
    /// vertex within the radius, weighted, over N π r². `hero_only` as [`Vcm::connect`]'s.
    #[allow(clippy::too_many_arguments)]
    fn merge_at(
        &self,
        v: &Vertex,
        len: u32,
        hero_only: bool,
        (d_vcm, _, d_vm): (f32, f32, f32),
        grid: &PointGrid,
        all: &[LightVertex],
        points: &[Vec3],
    ) -> Vec3 {
        let mut sum = Vec3::ZERO;
        let max_depth = self.set.max_depth;
        grid.for_each_within(points, v.hit.p, self.radius, |i| {
            let lv = &all[i];
            if len + lv.len as u32 > max_depth + 1 {
                return;
            }
            let wi = lv.frame.to_world(lv.wo_local);
            let wl = v.frame.to_local(wi);
            if !v.bsdf.side_consistent(wl, wi.dot(v.ng)) {
                return;
            }
            let f = v.bsdf.eval(v.wo_local, wl);
            if f == Vec3::ZERO {
                return;
            }
            let pdf_dir = v.bsdf.pdf(v.wo_local, wl);
            let pdf_rev = v.bsdf.pdf(wl, v.wo_local);
            let w_light = lv.d_vcm * self.vc_weight + lv.d_vm * mis(pdf_dir);
            let w_camera = d_vcm * self.vc_weight + d_vm * mis(pdf_rev);
            let c = f * lv.beta * hero_once(hero_only, lv.hero_only) / (w_light + 1.0 + w_camera);
            if c.is_finite() {
                sum += c;
            }
        });
        sum * self.vm_norm
    }
}
