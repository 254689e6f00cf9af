//! Bidirectional path tracing (Veach 1997 ch. 10; pbrt-v4 `BDPTIntegrator`, read as a
//! specification): a camera subpath and a light subpath are traced for each pixel sample and
//! every pair of their prefixes is joined, the strategy (s, t) taking s light vertices and t
//! camera vertices. The strategies are combined by multiple importance sampling with the power
//! heuristic, its weight computed as pbrt-v4 computes its balance weights: from ratios of the
//! forward and reverse area densities of the vertices, walked outwards from the connection
//! (O(s + t) per strategy). Strategies with t = 1 land on another pixel and are splatted; the
//! others add to the sample's pixel.
//!
//! * s = 0: the camera subpath hits an emitter (an area light, or escapes to the lights at
//!   infinity); s = 1: a light point is sampled for the camera vertex (next-event estimation);
//!   t = 1: the light subpath vertex is joined to the lens (light tracing); (1, 1) is left out,
//!   as pbrt does (the light seen directly is (0, 2)).
//! * Specular vertices (Dirac BSDFs) cannot be joined: their strategies are skipped and they are
//!   left out of the weights, as are the strategies that would have to hit a delta light.
//! * Depth counts bounces, s + t − 2, as the path tracer's: `max_depth` bounds it.
//!
//! Participating media are not handled (the driver refuses them, `render/light.rs`).

use super::RayStats;
use super::settings::PathSettings;
use super::vertex::Vertex;
use crate::camera::CameraImportance;
use crate::geometry::Ray;
use crate::geometry::primitive::{NO_LIGHT, SurfaceHit};
use crate::light::EnvPdf;
use crate::material::bxdf::TransportMode;
use crate::math::{PI, Vec2, Vec3};
use crate::sampling::SampleStream;
use crate::world::World;

/// What a subpath vertex is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// The lens point of the camera subpath.
    Camera,
    /// A light's point: `light` indexes `World::lights`; a light at infinity has no position,
    /// only the direction its light travels in the scene (`dir`).
    Light { light: u32, infinite: bool },
    /// A scattering surface point.
    Surface,
}

/// A vertex of a subpath: where it is, what the subpath carried to it (`beta`), and the area
/// densities with which the subpath's own direction (`pdf_fwd`) and the other subpath's
/// (`pdf_rev`) would generate it.
pub struct PathVertex {
    pub kind: Kind,
    pub p: Vec3,
    /// Geometric normal for surfaces and area lights (as intersected, not oriented); zero for
    /// the lens, points and spots.
    pub ng: Vec3,
    /// For lights at infinity: the direction from the scene towards the light.
    pub dir: Vec3,
    pub beta: Vec3,
    /// A specular (Dirac) scattering was sampled here.
    pub delta: bool,
    pub pdf_fwd: f32,
    pub pdf_rev: f32,
    /// A surface vertex's shading (its hit, BSDF, frame, the direction it was reached from).
    pub v: Vertex,
}

impl PathVertex {
    fn new(kind: Kind, p: Vec3, ng: Vec3, beta: Vec3) -> PathVertex {
        PathVertex {
            kind,
            p,
            ng,
            dir: Vec3::ZERO,
            beta,
            delta: false,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
            v: Vertex::unshaded(SurfaceHit::EMPTY),
        }
    }

    #[inline]
    fn is_infinite_light(&self) -> bool {
        matches!(self.kind, Kind::Light { infinite: true, .. })
    }

    /// Whether densities arriving here are per unit of surface area (so carry the cosine).
    #[inline]
    fn on_surface(&self) -> bool {
        self.ng != Vec3::ZERO && !self.is_infinite_light()
    }

    /// The light this vertex emits as, if any (a light vertex, or a surface that is an area
    /// light).
    #[inline]
    fn light_index(&self) -> Option<usize> {
        match self.kind {
            Kind::Light { light, .. } => Some(light as usize),
            Kind::Surface if self.v.hit.light != NO_LIGHT => Some(self.v.hit.light as usize),
            _ => None,
        }
    }

    /// Whether a light at this vertex is a delta (point, spot, directional).
    #[inline]
    fn is_delta_light(&self, world: &World) -> bool {
        matches!(self.kind, Kind::Light { light, .. } if world.lights()[light as usize].is_delta())
    }

    /// The point a ray from here must leave from.
    #[inline]
    fn spawn_toward(&self, to: Vec3) -> (Vec3, Vec3, Vec3) {
        match self.kind {
            Kind::Surface => (self.p, self.v.hit.p_error, self.v.ng),
            _ => (
                self.p,
                self.v.hit.p_error,
                self.ng * (self.ng.dot(to - self.p)).signum(),
            ),
        }
    }

    /// BSDF value towards `next` for a surface vertex reached from its predecessor, with the
    /// shading-normal correction of importance transport, times |cos| at the shading normal; 0
    /// where the BSDF's sides disagree.
    fn f_cos(&self, next: Vec3, mode: TransportMode) -> Vec3 {
        let d = next - self.p;
        let wi = d.normalize_or_zero();
        let v = &self.v;
        let wi_local = v.frame.to_local(wi);
        if wi == Vec3::ZERO || !v.bsdf.side_consistent(wi_local, wi.dot(v.ng)) {
            return Vec3::ZERO;
        }
        let corr =
            mode.shading_normal_correction(v.wo_local, wi_local, Vec3::Z, v.frame.to_local(v.ng));
        v.bsdf.eval_mode(v.wo_local, wi_local, mode) * (wi_local.z.abs() * corr)
    }
}

/// A solid-angle density at `from` towards `to`, as a density per unit area at `to` (per unit
/// of the disk for lights at infinity, whose densities are already so).
#[inline]
fn convert_density(pdf: f32, from: Vec3, to: &PathVertex) -> f32 {
    if to.is_infinite_light() {
        return pdf;
    }
    let d = to.p - from;
    let d2 = d.length_squared();
    if !(d2 > 0.0) {
        return 0.0;
    }
    let mut pdf = pdf / d2;
    if to.on_surface() {
        pdf *= to.ng.dot(d / d2.sqrt()).abs();
    }
    pdf
}

/// What a bidirectional sample needs from the frame.
pub struct Context<'a> {
    pub world: &'a World,
    pub camera: &'a CameraImportance,
    pub set: &'a PathSettings,
}

impl Context<'_> {
    /// The density (per solid angle) with which the lights at infinity emit along `-d` into
    /// the scene, over choosing them: Σ pmf · pdf (pbrt-v4 `InfiniteLightDensity`).
    fn infinite_density(&self, d: Vec3) -> f32 {
        let lights = &self.world.lights;
        lights
            .infinite
            .iter()
            .map(|&i| {
                let pmf = lights.distribution.discrete_pdf(i as usize);
                lights.lights[i as usize]
                    .le_pdf(d, EnvPdf::Full, Vec3::ZERO)
                    .map_or(0.0, |(_, pdf)| pmf * pdf)
            })
            .sum()
    }

    /// Area density with which the light at `v` emits towards `next` (pbrt-v4 `PdfLight`).
    fn pdf_light(&self, v: &PathVertex, next: &PathVertex) -> f32 {
        let Some(li) = v.light_index() else {
            return 0.0;
        };
        if v.is_infinite_light() {
            let r = self.world.lights.scene_radius;
            let mut pdf = 1.0 / (PI * r * r);
            if next.on_surface() {
                pdf *= next.ng.dot(v.dir).abs();
            }
            return pdf;
        }
        let d = next.p - v.p;
        let d2 = d.length_squared();
        if !(d2 > 0.0) {
            return 0.0;
        }
        let w = d / d2.sqrt();
        let scene = self.world.light_scene();
        let (_, pdf_dir) = self.world.lights()[li].pdf_le(&scene, v.ng, w);
        let mut pdf = pdf_dir / d2;
        if next.on_surface() {
            pdf *= next.ng.dot(w).abs();
        }
        pdf
    }

    /// Area density of `v` as the origin of a light subpath heading to `next` (pbrt-v4
    /// `PdfLightOrigin`): choosing its light times its position density.
    fn pdf_light_origin(&self, v: &PathVertex, next: &PathVertex) -> f32 {
        let Some(li) = v.light_index() else {
            return 0.0;
        };
        if v.is_infinite_light() {
            return self.infinite_density(v.dir);
        }
        let w = (next.p - v.p).normalize_or_zero();
        let scene = self.world.light_scene();
        let (pos, _) = self.world.lights()[li].pdf_le(&scene, v.ng, w);
        self.world.lights.distribution.discrete_pdf(li) * pos
    }

    /// Area density with which `v`, reached from `prev`, samples `next` (pbrt-v4 `Vertex::PDF`).
    fn pdf(&self, v: &PathVertex, prev: Option<&PathVertex>, next: &PathVertex) -> f32 {
        match v.kind {
            Kind::Light { .. } => self.pdf_light(v, next),
            Kind::Camera => {
                let d = next.p - v.p;
                let ray = Ray::new(v.p, d.normalize_or_zero());
                convert_density(self.camera.pdf_we(&ray).1, v.p, next)
            }
            Kind::Surface => {
                let Some(prev) = prev else { return 0.0 };
                let wn = if next.is_infinite_light() {
                    next.dir
                } else {
                    (next.p - v.p).normalize_or_zero()
                };
                let wp = if prev.is_infinite_light() {
                    prev.dir
                } else {
                    (prev.p - v.p).normalize_or_zero()
                };
                let f = &v.v.frame;
                let pdf = v.v.bsdf.pdf(f.to_local(wp), f.to_local(wn));
                convert_density(pdf, v.p, next)
            }
        }
    }

    /// Whether the segment between two vertices is free (a light at infinity: the ray from the
    /// other end escapes).
    fn visible(&self, a: &PathVertex, b: &PathVertex, stats: &mut RayStats) -> bool {
        stats.shadow_rays += 1;
        let (a, b) = if a.is_infinite_light() {
            (b, a)
        } else {
            (a, b)
        };
        if b.is_infinite_light() {
            let (p, e, n) = a.spawn_toward(a.p + b.dir);
            let mut ray = Ray::spawn(p, e, n, b.dir);
            ray.t_max = f32::INFINITY;
            return !self.world.occluded(&ray);
        }
        let (pa, ea, na) = a.spawn_toward(b.p);
        let (pb, eb, nb) = b.spawn_toward(a.p);
        !self.world.occluded(&Ray::spawn_to(pa, ea, na, pb, eb, nb))
    }
}

/// Per-worker storage of the two subpaths and the weights' scratch, allocated once.
#[derive(Default)]
pub struct Scratch {
    camera: Vec<PathVertex>,
    light: Vec<PathVertex>,
    fwd: Vec<f32>,
    rev: Vec<f32>,
    delta: Vec<bool>,
}

/// Where one (s, t) strategy's contribution goes, for the debugging outputs (pbrt-v4's
/// `visualizestrategies`/`visualizeweights`) and the tests: `(s, t, unweighted, weight)`.
pub trait StrategySink {
    fn strategy(&mut self, s: usize, t: usize, unweighted: Vec3, weight: f32, raster: Vec2);
}

/// No per-strategy output.
pub struct NoStrategies;
impl StrategySink for NoStrategies {
    #[inline]
    fn strategy(&mut self, _: usize, _: usize, _: Vec3, _: f32, _: Vec2) {}
}

/// Random walk from `ray` (pbrt-v4 `RandomWalk`): appends up to `max_vertices` scattering
/// vertices to `path` (whose last vertex is the walk's start), with their forward densities
/// and the reverse densities of their predecessors. A camera walk that escapes ends in a
/// vertex for the lights at infinity.
#[allow(clippy::too_many_arguments)]
fn walk(
    ctx: &Context,
    mut ray: Ray,
    mut beta: Vec3,
    mut pdf_dir: f32,
    mode: TransportMode,
    max_vertices: usize,
    path: &mut Vec<PathVertex>,
    s: &mut SampleStream,
    stats: &mut RayStats,
) {
    let world = ctx.world;
    let set = ctx.set;
    let inv_beta0 = 1.0 / beta.max_element().max(1e-30);
    let start = path.len();
    loop {
        if path.len() - start >= max_vertices {
            return;
        }
        stats.rays += 1;
        let mut hit = SurfaceHit::EMPTY;
        let d = ray.d.normalize();
        if !world.intersect_filtered_into(&ray, &set.footprint, &mut hit) {
            if mode == TransportMode::Radiance && !world.lights.infinite.is_empty() {
                let mut v = PathVertex::new(
                    Kind::Light {
                        light: world.lights.infinite[0],
                        infinite: true,
                    },
                    ray.o,
                    Vec3::ZERO,
                    beta,
                );
                v.dir = d;
                v.pdf_fwd = pdf_dir;
                path.push(v);
            }
            return;
        }
        let mut v = PathVertex::new(Kind::Surface, hit.p, hit.ng, beta);
        v.v.hit = hit;
        v.v.shade(world, -d);
        let prev_p = path[path.len() - 1].p;
        v.pdf_fwd = if path[path.len() - 1].is_infinite_light() {
            pdf_dir
        } else {
            convert_density(pdf_dir, prev_p, &v)
        };
        path.push(v);
        if path.len() - start >= max_vertices {
            return;
        }
        let n = path.len();
        let v = &mut path[n - 1];
        let u_lobe = s.next_1d();
        let u_dir = s.next_2d();
        let u_rr = s.next_1d();
        let sv = &v.v;
        let Some(bs) = sv.bsdf.sample_mode(sv.wo_local, u_lobe, u_dir, mode) else {
            return;
        };
        let wi = sv.frame.to_world(bs.wi);
        if !sv.bsdf.side_consistent(bs.wi, wi.dot(sv.ng)) {
            return;
        }
        let corr =
            mode.shading_normal_correction(sv.wo_local, bs.wi, Vec3::Z, sv.frame.to_local(sv.ng));
        beta *= bs.f * (bs.wi.z.abs() * corr / bs.pdf);
        let (pdf_fwd, pdf_rev) = if bs.specular {
            v.delta = true;
            (0.0, 0.0)
        } else {
            (bs.pdf, sv.bsdf.pdf(bs.wi, sv.wo_local))
        };
        pdf_dir = pdf_fwd;
        let (p, p_error, ng) = (v.p, sv.hit.p_error, sv.ng);
        // The predecessor's reverse density: this vertex sampling it.
        let rev = {
            let prev = &path[n - 2];
            if prev.is_infinite_light() {
                pdf_rev
            } else {
                convert_density(pdf_rev, p, prev)
            }
        };
        path[n - 2].pdf_rev = rev;
        if !(beta.max_element() > 0.0) || !beta.is_finite() {
            return;
        }
        // Russian roulette on the throughput since the walk's start (see `lighttracer.rs`).
        if (n - start) as u32 >= set.rr_depth {
            let q = (beta.max_element() * inv_beta0 * set.rr_scale).min(1.0);
            if q < 1.0 {
                if u_rr >= q {
                    return;
                }
                beta /= q;
            }
        }
        ray = Ray::spawn(p, p_error, ng, wi);
    }
}

/// Traces one bidirectional sample: the camera subpath from `ray` (of filter weight `weight`)
/// and a light subpath, joined by every strategy. Returns the sum of the strategies that land
/// on the sample's pixel; those with t = 1 are splatted into `out` times `scale`.
#[allow(clippy::too_many_arguments)]
pub fn trace(
    ctx: &Context,
    ray: &Ray,
    weight: f32,
    s: &mut SampleStream,
    scratch: &mut Scratch,
    stats: &mut RayStats,
    scale: f32,
    out: &mut impl super::lighttracer::Splat,
    strategies: &mut impl StrategySink,
) -> Vec3 {
    let world = ctx.world;
    let max_depth = ctx.set.max_depth as usize;
    let Scratch {
        camera,
        light,
        fwd,
        rev,
        delta,
    } = scratch;
    camera.clear();
    light.clear();
    // The camera subpath: the lens point, then up to max_depth + 1 scattering vertices.
    let d = ray.d.normalize();
    let mut c0 = PathVertex::new(Kind::Camera, ray.o, Vec3::ZERO, Vec3::splat(weight));
    c0.dir = d;
    camera.push(c0);
    let pdf_dir = ctx.camera.pdf_we(&Ray::new(ray.o, d)).1;
    walk(
        ctx,
        Ray::new(ray.o, d),
        Vec3::splat(weight),
        pdf_dir,
        TransportMode::Radiance,
        max_depth + 1,
        camera,
        s,
        stats,
    );
    // The light subpath: the light point, then up to max_depth scattering vertices.
    if let Some(em) = super::lighttracer::sample_emission(world, s) {
        let les = em.le;
        let infinite = world.lights()[em.index].is_infinite();
        let mut l0 = PathVertex::new(
            Kind::Light {
                light: em.index as u32,
                infinite,
            },
            les.ray.o,
            les.n,
            les.le,
        );
        if let Some(lp) = &em.point {
            l0.p = lp.p;
            l0.ng = lp.ng;
            l0.v.hit = *lp;
        }
        if infinite {
            l0.dir = -les.ray.d;
            l0.ng = Vec3::ZERO;
            l0.pdf_fwd = ctx.infinite_density(-les.ray.d);
        } else {
            l0.pdf_fwd = em.pmf * les.pdf_pos;
        }
        light.push(l0);
        let beta = les.le * (les.cos() / (em.pmf * les.pdf_pos * les.pdf_dir));
        let n_before = light.len();
        walk(
            ctx,
            les.ray,
            beta,
            les.pdf_dir,
            TransportMode::Importance,
            max_depth,
            light,
            s,
            stats,
        );
        // A light at infinity: its first vertex's density is over the disk its rays leave
        // from, with the cosine there (pbrt-v4 `GenerateLightSubpath`).
        if infinite && light.len() > n_before {
            let v1 = &mut light[n_before];
            v1.pdf_fwd = les.pdf_pos;
            if v1.on_surface() {
                v1.pdf_fwd *= v1.ng.dot(les.ray.d).abs();
            }
        }
    }

    let mut l_pixel = Vec3::ZERO;
    for t in 1..=camera.len() {
        for sl in 0..=light.len() {
            let depth = (t + sl) as isize - 2;
            if (sl == 1 && t == 1) || depth < 0 || depth as usize > max_depth {
                continue;
            }
            let c = connect(
                ctx, light, camera, sl, t, s, stats, fwd, rev, delta, strategies,
            );
            if let Some((l, raster)) = c {
                if t == 1 {
                    out.splat(raster, l * scale);
                } else {
                    l_pixel += l;
                }
            }
        }
    }
    l_pixel
}

/// The connection strategy (s, t): its MIS-weighted contribution and, for t = 1, the film point
/// it lands on (pbrt-v4 `ConnectBDPT`).
#[allow(clippy::too_many_arguments)]
fn connect(
    ctx: &Context,
    light: &[PathVertex],
    camera: &[PathVertex],
    s: usize,
    t: usize,
    stream: &mut SampleStream,
    stats: &mut RayStats,
    fwd: &mut Vec<f32>,
    rev: &mut Vec<f32>,
    delta: &mut Vec<bool>,
    sink: &mut impl StrategySink,
) -> Option<(Vec3, Vec2)> {
    let world = ctx.world;
    let pt = &camera[t - 1];
    // A camera vertex at infinity can only be an s = 0 end.
    if pt.is_infinite_light() && s > 0 {
        return None;
    }
    let mut raster = Vec2::ZERO;
    // A vertex made for this strategy (s = 1: a light point; t = 1: a lens point).
    let mut sampled: Option<PathVertex> = None;
    let l: Vec3 = if s == 0 {
        // The camera subpath reached an emitter.
        match pt.kind {
            Kind::Light { infinite: true, .. } => pt.beta * world.escaped(pt.dir),
            Kind::Surface if pt.v.hit.light != NO_LIGHT => {
                let wo = (camera[t - 2].p - pt.p).normalize_or_zero();
                pt.beta * world.emitted(&pt.v.hit, wo)
            }
            _ => return None,
        }
    } else if t == 1 {
        // Join the light vertex to the lens.
        let qs = &light[s - 1];
        let u = stream.next_2d();
        if qs.delta || qs.kind != Kind::Surface {
            return None;
        }
        let cs = ctx.camera.sample_wi(qs.p, u)?;
        raster = cs.raster;
        let mut cv = PathVertex::new(
            Kind::Camera,
            cs.p_lens,
            Vec3::ZERO,
            Vec3::splat(cs.we / cs.pdf),
        );
        cv.dir = -cs.wi;
        let l = qs.beta * qs.f_cos(cs.p_lens, TransportMode::Importance) * cv.beta;
        if l == Vec3::ZERO || !ctx.visible(qs, &cv, stats) {
            return None;
        }
        sampled = Some(cv);
        l
    } else if s == 1 {
        // Sample a light point for the camera vertex (next-event estimation), choosing the
        // light by power as light subpaths do.
        let u_light = stream.next_1d();
        let u = stream.next_2d();
        if pt.delta || pt.kind != Kind::Surface || world.lights.is_empty() {
            return None;
        }
        let (li, pmf) = world.lights.distribution.sample_discrete(u_light);
        if !(pmf > 0.0) {
            return None;
        }
        let light_ref = &world.lights()[li];
        let scene = world.light_scene();
        let lv = if let Some(area) = light_ref.as_area() {
            // A point uniform by area, so that its density is the light subpaths' origin one.
            let lp = world.geometry.sample_point(area.prim, u);
            let w = (pt.p - lp.p).normalize_or_zero();
            let (pos, _) = light_ref.pdf_le(&scene, lp.ng, w);
            let le = light_ref.l(&scene, &lp, w);
            if !(pos > 0.0) || le == Vec3::ZERO {
                return None;
            }
            let mut v = PathVertex::new(
                Kind::Light {
                    light: li as u32,
                    infinite: false,
                },
                lp.p,
                lp.ng,
                le / (pmf * pos),
            );
            v.v.hit = lp;
            v
        } else {
            let ls =
                light_ref.sample_li(&scene, &pt.v.hit, pt.v.ng, u, EnvPdf::Full, Vec3::ZERO)?;
            if !(ls.pdf > 0.0) || ls.li == Vec3::ZERO {
                return None;
            }
            let infinite = light_ref.is_infinite();
            let p = ls.shadow.o + ls.shadow.d;
            let mut v = PathVertex::new(
                Kind::Light {
                    light: li as u32,
                    infinite,
                },
                p,
                Vec3::ZERO,
                Vec3::ZERO,
            );
            if infinite {
                v.dir = ls.wi;
            }
            // `li` is already per solid angle at `pt` (intensity / d² for points and spots):
            // the geometric term below must then leave out 1 / d², so it is put back here.
            let g_undo = if infinite {
                1.0
            } else {
                (p - pt.p).length_squared()
            };
            v.beta = ls.li * (g_undo / (pmf * ls.pdf));
            v
        };
        let mut lv = lv;
        lv.pdf_fwd = ctx.pdf_light_origin(&lv, pt);
        let l = pt.beta * pt.f_cos(light_target(&lv, pt), TransportMode::Radiance) * lv.beta;
        if l == Vec3::ZERO || !ctx.visible(pt, &lv, stats) {
            return None;
        }
        let l = l * light_geometry(&lv, pt);
        sampled = Some(lv);
        l
    } else {
        let qs = &light[s - 1];
        if qs.delta || pt.delta || qs.kind != Kind::Surface || pt.kind != Kind::Surface {
            return None;
        }
        let l = qs.beta
            * qs.f_cos(pt.p, TransportMode::Importance)
            * pt.f_cos(qs.p, TransportMode::Radiance)
            * pt.beta;
        if l == Vec3::ZERO || !ctx.visible(qs, pt, stats) {
            return None;
        }
        // f_cos took the cosines at both ends; the rest of G is 1 / d².
        l / (qs.p - pt.p).length_squared().max(1e-30)
    };
    if l == Vec3::ZERO || !l.is_finite() {
        return None;
    }
    let w = mis_weight(ctx, light, camera, sampled.as_ref(), s, t, fwd, rev, delta);
    sink.strategy(s, t, l, w, raster);
    Some((l * w, raster))
}

/// Subpath vertex `i`, or the strategy's own vertex in place of vertex 0 when `replace`.
#[inline]
fn pick<'a>(
    path: &'a [PathVertex],
    sampled: Option<&'a PathVertex>,
    i: usize,
    replace: bool,
) -> &'a PathVertex {
    match sampled {
        Some(v) if i == 0 && replace => v,
        _ => &path[i],
    }
}

/// The point a camera vertex joins to when it samples the light vertex `lv`: its position, or
/// far along its direction for a light at infinity.
#[inline]
fn light_target(lv: &PathVertex, pt: &PathVertex) -> Vec3 {
    if lv.is_infinite_light() {
        pt.p + lv.dir
    } else {
        lv.p
    }
}

/// The rest of the geometric term of an s = 1 connection after the camera vertex's cosine:
/// |cos| at an area light over d² (the others' `beta` is already per solid angle).
#[inline]
fn light_geometry(lv: &PathVertex, pt: &PathVertex) -> f32 {
    if lv.is_infinite_light() {
        return 1.0;
    }
    let d = pt.p - lv.p;
    let d2 = d.length_squared();
    if !(d2 > 0.0) {
        return 0.0;
    }
    if lv.on_surface() {
        lv.ng.dot(d / d2.sqrt()).abs() / d2
    } else {
        1.0 / d2
    }
}

/// The power-heuristic weight of strategy (s, t) for the path it made (pbrt-v4 `MISWeight`,
/// with squared ratios): Σ over the other strategies of (p_i / p_(s,t))², each ratio obtained
/// from its neighbour's by one vertex's reverse over forward density, walking away from the
/// connection on both subpaths. `sampled` replaces light[0] (s = 1) or camera[0] (t = 1).
#[allow(clippy::too_many_arguments)]
fn mis_weight(
    ctx: &Context,
    light: &[PathVertex],
    camera: &[PathVertex],
    sampled: Option<&PathVertex>,
    s: usize,
    t: usize,
    fwd: &mut Vec<f32>,
    rev: &mut Vec<f32>,
    delta: &mut Vec<bool>,
) -> f32 {
    if s + t == 2 {
        return 1.0;
    }
    // The vertices of the path, light end first: light[0..s], camera[t-1..=0].
    let lv = |i: usize| pick(light, sampled, i, s == 1);
    let cv = |i: usize| pick(camera, sampled, i, t == 1);
    let n = s + t;
    fwd.clear();
    rev.clear();
    delta.clear();
    // Index k along the path: k < s is light vertex k, else camera vertex n - 1 - k.
    for k in 0..n {
        let v = if k < s { lv(k) } else { cv(n - 1 - k) };
        fwd.push(v.pdf_fwd);
        rev.push(v.pdf_rev);
        delta.push(v.delta);
    }
    let pt = cv(t - 1);
    let pt_minus = (t >= 2).then(|| cv(t - 2));
    let qs = (s >= 1).then(|| lv(s - 1));
    let qs_minus = (s >= 2).then(|| lv(s - 2));
    let kpt = s; // pt's index
    // The connection makes its two ends non-specular for this path.
    delta[kpt] = false;
    if s >= 1 {
        delta[s - 1] = false;
    }
    // pt's reverse density: from qs, or as a light's origin.
    rev[kpt] = match qs {
        Some(q) => ctx.pdf(q, qs_minus, pt),
        None => pt_minus.map_or(0.0, |m| ctx.pdf_light_origin(pt, m)),
    };
    if let Some(m) = pt_minus {
        rev[kpt + 1] = match qs {
            Some(q) => ctx.pdf(pt, Some(q), m),
            None => ctx.pdf_light(pt, m),
        };
    }
    if let Some(q) = qs {
        rev[s - 1] = ctx.pdf(pt, pt_minus, q);
        if let Some(qm) = qs_minus {
            rev[s - 2] = ctx.pdf(q, Some(pt), qm);
        }
    }
    let remap = |x: f32| if x != 0.0 { x } else { 1.0 };
    let mut sum = 0.0f32;
    // Camera side: moving the connection towards the camera (strategies (s + j, t - j)).
    let mut ri = 1.0f32;
    for k in s..n - 1 {
        // Camera vertex index n - 1 - k ≥ 1.
        ri *= remap(rev[k]) / remap(fwd[k]);
        if !delta[k] && !delta[k + 1] {
            sum += ri * ri;
        }
    }
    // Light side: strategies (s - j, t + j).
    let mut ri = 1.0f32;
    for k in (0..s).rev() {
        ri *= remap(rev[k]) / remap(fwd[k]);
        let delta_light = if k > 0 {
            delta[k - 1]
        } else {
            lv(0).is_delta_light(ctx.world)
        };
        if !delta[k] && !delta_light {
            sum += ri * ri;
        }
    }
    1.0 / (1.0 + sum)
}
