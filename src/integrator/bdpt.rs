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
//! * Participating media (as pbrt-v4's `bdpt`): both walks sample free flights by delta
//!   tracking with the volumetric path tracer's hero-channel scheme (`volpath.rs`), so a real
//!   collision becomes a medium vertex scattering by its phase function; index-matched interface
//!   surfaces are crossed without a vertex. Each subpath draws its own hero channel and its
//!   vertices carry β over the mean of the channels' pdf ratios (one-sample spectral MIS over
//!   the channels of that walk, which is why the two walks' channels are independent: their
//!   product stays unbiased). Connections carry the transmittance between their ends, estimated
//!   by ratio tracking through media and interface surfaces (`World::transmittance`) and
//!   weighted over the channels the same way. Medium vertices enter the MIS weights with
//!   solid-angle densities over d² and no cosine, and the free-flight probabilities are left
//!   out of every strategy's density alike (pbrt-v4 does the same): the weights still sum to 1
//!   for every path. A light's medium is found by following a segment from the lens to it
//!   through every surface's medium interface ([`medium_at`]): lights carry no medium of their
//!   own. Emissive media are refused by the driver (their emission is not sampled by either
//!   subpath).

use super::RayStats;
use super::settings::PathSettings;
use super::vertex::Vertex;
use crate::camera::CameraImportance;
use crate::geometry::Ray;
use crate::geometry::primitive::{NO_LIGHT, SurfaceHit};
use crate::light::EnvPdf;
use crate::material::bxdf::TransportMode;
use crate::math::{PI, Vec2, Vec3};
use crate::medium::{HenyeyGreenstein, TrackStep};
use crate::sampling::mlt::UniformSource;
use crate::sampling::rng::{Pcg32, hash_words};
use crate::world::World;

/// Interface crossings allowed per segment before a walk or a probe gives up (rays caught
/// between coincident interfaces must not loop for ever), as the volumetric path tracer.
const MAX_CROSSINGS: u32 = 256;

#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

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
    /// A scattering point in a participating medium (its phase function in `phase`, the
    /// direction back along its subpath in `dir`).
    Medium,
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
    /// The medium the vertex sits in: the one its subpath arrived through (surfaces, medium
    /// points), the lens's, or the light's (see [`medium_at`]); `None` is vacuum.
    pub medium: Option<usize>,
    /// A medium vertex's phase function.
    pub phase: HenyeyGreenstein,
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
            medium: None,
            phase: HenyeyGreenstein { g: 0.0 },
        }
    }

    /// A scattering vertex in `medium` at `p`, reached travelling along `d`.
    fn in_medium(p: Vec3, d: Vec3, beta: Vec3, medium: usize, phase: HenyeyGreenstein) -> Self {
        let mut v = PathVertex::new(Kind::Medium, p, Vec3::ZERO, beta);
        v.dir = -d;
        v.medium = Some(medium);
        v.phase = phase;
        v.v.hit.p = p;
        v
    }

    /// Whether the vertex scatters (a surface or a medium point): only those can be joined.
    #[inline]
    fn scatters(&self) -> bool {
        matches!(self.kind, Kind::Surface | Kind::Medium)
    }

    /// The medium a ray leaving this vertex in direction `d` travels in.
    #[inline]
    fn medium_toward(&self, world: &World, d: Vec3) -> Option<usize> {
        match self.kind {
            Kind::Surface => world.medium_after(self.v.hit.material, d, self.v.hit.ng, self.medium),
            // An area light's surface may itself separate media.
            Kind::Light {
                infinite: false, ..
            } if self.ng != Vec3::ZERO => {
                world.medium_after(self.v.hit.material, d, self.v.hit.ng, self.medium)
            }
            _ => self.medium,
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
            Kind::Medium => (self.p, Vec3::ZERO, Vec3::ZERO),
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
        if self.kind == Kind::Medium {
            // The phase function between the arriving travel direction (−dir) and wi: no
            // cosine, and the same in both transport modes (it is symmetric).
            return Vec3::splat(self.phase.eval(-self.dir, wi));
        }
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
    /// The world of the sample's time (a shutter step's, [`World::at_step`], where motion falls
    /// back to worlds per step).
    pub world: &'a World,
    /// The camera's importance, placed where the camera is at the sample's time.
    pub camera: &'a CameraImportance,
    pub set: &'a PathSettings,
    /// The sample's shutter time ([`Ray::time`]; 0 for a still): both subpaths and every
    /// connection see the scene at this one moment, so BDPT can join them (pbrt-v4 gives a
    /// light subpath its camera sample's time).
    pub time: f32,
}

impl<'a> Context<'a> {
    /// This context with the settings `set` (a spectral sample's copy carrying its wavelengths,
    /// [`PathSettings::for_sample`]).
    pub fn with_set<'b>(&self, set: &'b PathSettings) -> Context<'b>
    where
        'a: 'b,
    {
        Context {
            world: self.world,
            camera: self.camera,
            set,
            time: self.time,
        }
    }

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
        let (_, pdf_dir) = self
            .world
            .lights
            .posed(li, self.time)
            .pdf_le(&scene, v.ng, w);
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
        let (pos, _) = self
            .world
            .lights
            .posed(li, self.time)
            .pdf_le(&scene, v.ng, w);
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
            Kind::Medium => {
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
                convert_density(v.phase.eval(-wp, wn), v.p, next)
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
            let mut ray = Ray::spawn(p, e, n, b.dir).with_time(self.time);
            ray.t_max = f32::INFINITY;
            return !self.world.occluded(&ray);
        }
        let (pa, ea, na) = a.spawn_toward(b.p);
        let (pb, eb, nb) = b.spawn_toward(a.p);
        !self
            .world
            .occluded(&Ray::spawn_to(pa, ea, na, pb, eb, nb).with_time(self.time))
    }

    /// The connection factor between `from` (a vertex whose medium is known: a scattering
    /// vertex or a light) and `to`: visibility in a scene without media; otherwise the
    /// transmittance through media and interface surfaces by ratio tracking in a fresh hero
    /// channel, weighted over the channels (T / mean of the channels' tracking pdf ratios, the
    /// one-sample balance heuristic; `World::transmittance`). Zero if a surface blocks.
    fn transmittance(
        &self,
        from: &PathVertex,
        to: &PathVertex,
        media: &mut MediaState,
        stats: &mut RayStats,
    ) -> Vec3 {
        let Some(rng) = media.rng.as_mut() else {
            return if self.visible(from, to, stats) {
                Vec3::ONE
            } else {
                Vec3::ZERO
            };
        };
        let (shadow, d) = if to.is_infinite_light() {
            let (p, e, n) = from.spawn_toward(from.p + to.dir);
            let mut ray = Ray::spawn(p, e, n, to.dir);
            ray.t_max = f32::INFINITY;
            (ray, to.dir)
        } else {
            let (pa, ea, na) = from.spawn_toward(to.p);
            let (pb, eb, nb) = to.spawn_toward(from.p);
            let r = Ray::spawn_to(pa, ea, na, pb, eb, nb);
            (r, (to.p - from.p).normalize_or_zero())
        };
        let shadow = shadow.with_time(self.time);
        let lambda = self.set.wavelengths.map(|w| w.lambda);
        let channel = hero_channel(rng);
        let start = from.medium_toward(self.world, d);
        match self.world.transmittance_at(
            &shadow,
            start,
            channel,
            lambda,
            rng,
            &mut stats.shadow_rays,
        ) {
            Some((t, r_l, _)) if mean(r_l) > 0.0 => t / mean(r_l),
            _ => Vec3::ZERO,
        }
    }
}

/// The tracking state of one bidirectional sample in a scene with media: the generator of the
/// tracking decisions (seeded from the sample, as the volumetric path tracer seeds its own, so
/// the image stays a function of seed, pixel and sample index); `None` without media.
#[derive(Default)]
pub struct MediaState {
    rng: Option<Pcg32>,
    /// Spectral mode: a subpath met a dispersive surface, so the whole sample keeps its hero
    /// wavelength alone, weighted by the number of wavelengths (pbrt-v4's `TerminateSecondary`
    /// acts on the sample's wavelengths, shared by both subpaths and every strategy).
    pub(crate) hero_only: bool,
}

impl MediaState {
    /// The state for a sample of `world` whose stream is `s`: one number is drawn from the
    /// stream when the scene has media, none otherwise (media-free images keep their streams).
    pub fn new(world: &World, s: &mut impl UniformSource, salt: Vec3) -> MediaState {
        if !world.has_media() {
            return MediaState {
                rng: None,
                hero_only: false,
            };
        }
        let u = s.next_1d();
        let rng = Pcg32::new(
            hash_words(&[
                u64::from(u.to_bits()),
                u64::from(salt.x.to_bits()) << 32 | u64::from(salt.y.to_bits()),
                u64::from(salt.z.to_bits()),
            ]),
            0x6264_7074,
        );
        MediaState {
            rng: Some(rng),
            hero_only: false,
        }
    }
}

/// A hero channel, uniform over the three: over the channels in RGB mode, over the sample's
/// wavelengths in spectral mode. Not lane 0 there, as the volumetric path tracer takes: each
/// walk and each connection's transmittance is a one-sample MIS estimate of its own, unbiased
/// for a uniformly chosen channel, and their product stays unbiased only if the choices are
/// independent — the same lane for all of them (lane 0) measured 6–12 % too much red and 6–9 %
/// too little green on `scenes/pbrt/media/fog_bands.pbrt` against pbrt-v4.
#[inline]
fn hero_channel(rng: &mut Pcg32) -> usize {
    ((rng.next_f32() * 3.0) as usize).min(2)
}

/// The medium at `p`, found by following the segment from the lens centre `lens` (in the camera's
/// medium) to just short of `p` through every surface, each switching the medium as its
/// interface says (surfaces without one leave it: pbrt-v4's rule). Lights carry no medium of
/// their own in a scene, and this is where their light starts travelling.
pub fn medium_at(world: &World, lens: Vec3, p: Vec3, time: f32) -> Option<usize> {
    let mut medium = world.camera_medium();
    let mut o = lens;
    for _ in 0..MAX_CROSSINGS {
        let d = p - o;
        let len = d.length();
        if !(len > 0.0) {
            break;
        }
        let dir = d / len;
        let ray = Ray {
            o,
            d: dir,
            t_max: len * (1.0 - crate::geometry::SHADOW_EPSILON),
            time,
        };
        let Some(h) = world.intersect(&ray) else {
            break;
        };
        medium = world.medium_after(h.material, dir, h.ng, medium);
        o = Ray::spawn(h.p, h.p_error, h.ng, dir).o;
    }
    medium
}

/// Per-worker storage of the two subpaths and the weights' scratch, allocated once.
#[derive(Default)]
pub struct Scratch {
    pub(crate) camera: Vec<PathVertex>,
    pub(crate) light: Vec<PathVertex>,
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
/// vertex for the lights at infinity. The ray starts in `medium`; with media (`media.rng` set)
/// free flights are sampled in hero channel `channel` as the volumetric path tracer does, and
/// every vertex's β is over the mean of the walk's channel pdf ratios r_u.
#[allow(clippy::too_many_arguments)]
fn walk(
    ctx: &Context,
    mut ray: Ray,
    mut beta: Vec3,
    mut pdf_dir: f32,
    mode: TransportMode,
    max_vertices: usize,
    path: &mut Vec<PathVertex>,
    s: &mut impl UniformSource,
    stats: &mut RayStats,
    mut medium: Option<usize>,
    media: &mut MediaState,
) {
    let world = ctx.world;
    let set = ctx.set;
    let inv_beta0 = 1.0 / beta.max_element().max(1e-30);
    let start = path.len();
    // Without media none of the tracking state is touched, so media-free images are unchanged.
    // Spectral mode: the media's coefficients at the sample's wavelengths, a majorant per
    // wavelength and distances in the channel's wavelength ([`hero_channel`]).
    let lambda = set.wavelengths.map(|w| w.lambda);
    let channel = media.rng.as_mut().map_or(0, hero_channel);
    let mut r_u = Vec3::ONE;
    let mut crossings = 0u32;
    loop {
        if path.len() - start >= max_vertices {
            return;
        }
        // Every ray of the walk, from the lens or the light and after each vertex, is at the
        // sample's time (0 for a still: the rays are unchanged).
        ray.time = ctx.time;
        stats.rays += 1;
        let mut hit = SurfaceHit::EMPTY;
        let d = ray.d.normalize();
        let found = world.intersect_filtered_into(&ray, &set.footprint, &mut hit);
        let mut scattered: Option<(Vec3, HenyeyGreenstein)> = None;
        if let (Some(mi), Some(rng)) = (medium, media.rng.as_mut()) {
            let m = world.medium(mi);
            let t_max = if found {
                hit.t * ray.d.length()
            } else {
                f32::INFINITY
            };
            let c = m.coefficients(lambda);
            if m.is_analytic() {
                beta *= m.analytic_transmittance_in(&c, t_max);
            } else {
                let mut tracker = m.tracker_in(&c, &Ray::new(ray.o, d), t_max, channel);
                loop {
                    match tracker.step(m, rng) {
                        TrackStep::End { t_maj } => {
                            let th = t_maj[channel];
                            if !(th > 0.0) {
                                return;
                            }
                            beta *= t_maj / th;
                            r_u *= t_maj / th;
                            break;
                        }
                        TrackStep::Collision {
                            p,
                            props,
                            sigma_maj,
                            t_maj,
                        } => {
                            let sm = sigma_maj[channel];
                            let p_absorb = props.sigma_a[channel] / sm;
                            let p_scatter = props.sigma_s[channel] / sm;
                            let u = rng.next_f32();
                            if u < p_absorb {
                                return;
                            }
                            if u < p_absorb + p_scatter {
                                let pdf = t_maj[channel] * props.sigma_s[channel];
                                beta *= t_maj * props.sigma_s / pdf;
                                r_u *= t_maj * props.sigma_s / pdf;
                                scattered = Some((p, m.phase));
                                break;
                            }
                            let sigma_n =
                                (sigma_maj - props.sigma_a - props.sigma_s).max(Vec3::ZERO);
                            let pdf = t_maj[channel] * sigma_n[channel];
                            if !(pdf > 0.0) {
                                return;
                            }
                            beta *= t_maj * sigma_n / pdf;
                            r_u *= t_maj * sigma_n / pdf;
                            if !(beta.max_element() > 0.0 && r_u.max_element() > 0.0) {
                                return;
                            }
                        }
                    }
                }
            }
            if !(beta.max_element() > 0.0 && mean(r_u) > 0.0 && beta.is_finite()) {
                return;
            }
        }
        // β as the vertex keeps it: over the channels' mean pdf ratio when media are tracked.
        let beta_v = if media.rng.is_some() {
            beta / mean(r_u)
        } else {
            beta
        };
        if let Some((p, phase)) = scattered {
            // A real collision: a medium vertex.
            crossings = 0;
            let mut v = PathVertex::in_medium(p, d, beta_v, medium.unwrap_or(0), phase);
            let prev = &path[path.len() - 1];
            v.pdf_fwd = if prev.is_infinite_light() {
                pdf_dir
            } else {
                convert_density(pdf_dir, prev.p, &v)
            };
            path.push(v);
            if path.len() - start >= max_vertices {
                return;
            }
            let _u_lobe = s.next_1d();
            let u_dir = s.next_2d();
            let u_rr = s.next_1d();
            let ps = phase.sample(d, u_dir);
            if !(ps.pdf > 0.0) {
                return;
            }
            // The phase function is its own pdf (β unchanged) and symmetric (the reverse
            // density is the same value).
            pdf_dir = ps.pdf;
            let n = path.len();
            let rev = if path[n - 2].is_infinite_light() {
                ps.pdf
            } else {
                convert_density(ps.pdf, p, &path[n - 2])
            };
            path[n - 2].pdf_rev = rev;
            if roulette(n - start, beta_v, inv_beta0, set, u_rr, &mut beta) {
                return;
            }
            ray = Ray::new(p, ps.d_out);
            continue;
        }
        if !found {
            if mode == TransportMode::Radiance && !world.lights.infinite.is_empty() {
                let mut v = PathVertex::new(
                    Kind::Light {
                        light: world.lights.infinite[0],
                        infinite: true,
                    },
                    ray.o,
                    Vec3::ZERO,
                    beta_v,
                );
                v.dir = d;
                v.pdf_fwd = pdf_dir;
                v.medium = medium;
                path.push(v);
            }
            return;
        }
        if media.rng.is_some() && world.is_interface(hit.material) {
            // A boundary between media only: no vertex, the ray carries on.
            medium = world.medium_after(hit.material, d, hit.ng, medium);
            ray = Ray::spawn(hit.p, hit.p_error, hit.ng, d);
            crossings += 1;
            if crossings > MAX_CROSSINGS {
                return;
            }
            continue;
        }
        crossings = 0;
        let mut v = PathVertex::new(Kind::Surface, hit.p, hit.ng, beta_v);
        v.v.hit = hit;
        v.v.shade(world, -d);
        // Spectral mode: the BSDF at the sample's wavelengths (as the path tracer's vertices).
        if let Some(w) = &set.wavelengths {
            media.hero_only |= v.v.bsdf.disperses();
            v.v.bsdf.make_spectral(w.lambda, &world.bsdf_spectra);
        }
        v.medium = medium;
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
        let Some((bs, wi, scatter)) = sv.sample_scatter(mode, u_lobe, u_dir) else {
            return;
        };
        beta *= scatter;
        let (pdf_fwd, pdf_rev) = if bs.specular {
            v.delta = true;
            (0.0, 0.0)
        } else {
            (bs.pdf, sv.bsdf.pdf(bs.wi, sv.wo_local))
        };
        pdf_dir = pdf_fwd;
        let (p, p_error, ng) = (v.p, sv.hit.p_error, sv.ng);
        let (material, ng_front) = (sv.hit.material, sv.hit.ng);
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
        let beta_rr = if media.rng.is_some() {
            beta / mean(r_u)
        } else {
            beta
        };
        if roulette(n - start, beta_rr, inv_beta0, set, u_rr, &mut beta) {
            return;
        }
        if media.rng.is_some() {
            medium = world.medium_after(material, wi, ng_front, medium);
        }
        ray = Ray::spawn(p, p_error, ng, wi);
    }
}

/// Russian roulette after the `k`-th vertex of a walk on the throughput since the walk's start
/// (`judged`, see `lighttracer.rs`), one number `u` always drawn; divides `beta` by the survival
/// probability. True if the walk ends.
#[inline]
fn roulette(
    k: usize,
    judged: Vec3,
    inv_beta0: f32,
    set: &PathSettings,
    u: f32,
    beta: &mut Vec3,
) -> bool {
    if k as u32 >= set.rr_depth {
        let q = (judged.max_element() * inv_beta0 * set.rr_scale).min(1.0);
        if q < 1.0 {
            if u >= q {
                return true;
            }
            *beta /= q;
        }
    }
    false
}

/// Traces one bidirectional sample: the camera subpath from `ray` (of filter weight `weight`)
/// and a light subpath, joined by every strategy. Returns the sum of the strategies that land
/// on the sample's pixel; those with t = 1 are splatted into `out` times `scale`.
#[allow(clippy::too_many_arguments)]
pub fn trace(
    ctx: &Context,
    ray: &Ray,
    weight: f32,
    s: &mut impl UniformSource,
    scratch: &mut Scratch,
    stats: &mut RayStats,
    scale: f32,
    out: &mut impl super::lighttracer::Splat,
    strategies: &mut impl StrategySink,
) -> Vec3 {
    // Spectral mode: the sample's wavelengths, drawn first, ride on a copy of the settings that
    // both subpaths and every connection read; each strategy reaches the film through the CIE
    // curves (docs/DESIGN.md "Spectral rendering").
    let spectral_set = ctx.set.for_sample(s);
    let spectral_ctx = spectral_set.as_ref().map(|set| ctx.with_set(set));
    let ctx = spectral_ctx.as_ref().unwrap_or(ctx);
    let set = ctx.set;
    let world = ctx.world;
    let max_depth = ctx.set.max_depth as usize;
    let Scratch {
        camera,
        light,
        fwd,
        rev,
        delta,
    } = scratch;
    light.clear();
    let d = ray.d.normalize();
    let mut media = MediaState::new(world, s, d);
    // The camera subpath: the lens point, then up to max_depth + 1 scattering vertices.
    camera_subpath(
        ctx,
        ray,
        weight,
        max_depth + 1,
        s,
        stats,
        camera,
        &mut media,
    );
    light_subpath(ctx, ray.o, s, stats, light, &mut media, max_depth);

    let mut l_pixel = Vec3::ZERO;
    for t in 1..=camera.len() {
        for sl in 0..=light.len() {
            let depth = (t + sl) as isize - 2;
            if (sl == 1 && t == 1) || depth < 0 || depth as usize > max_depth {
                continue;
            }
            let c = connect(
                ctx, light, camera, sl, t, s, stats, fwd, rev, delta, strategies, &mut media,
            );
            if let Some((l, raster)) = c {
                let l = if media.hero_only {
                    Vec3::new(3.0 * l.x, 0.0, 0.0)
                } else {
                    l
                };
                if t == 1 {
                    out.splat(raster, set.to_film(l * scale));
                } else {
                    l_pixel += l;
                }
            }
        }
    }
    set.to_film(l_pixel)
}

/// The camera subpath (pbrt-v4 `GenerateCameraSubpath`) into `camera` (emptied first): the
/// lens point of `ray` with filter weight `weight`, then up to `max_vertices` scattering
/// vertices.
#[allow(clippy::too_many_arguments)]
pub(crate) fn camera_subpath(
    ctx: &Context,
    ray: &Ray,
    weight: f32,
    max_vertices: usize,
    s: &mut impl UniformSource,
    stats: &mut RayStats,
    camera: &mut Vec<PathVertex>,
    media: &mut MediaState,
) {
    let world = ctx.world;
    camera.clear();
    let d = ray.d.normalize();
    let mut c0 = PathVertex::new(Kind::Camera, ray.o, Vec3::ZERO, Vec3::splat(weight));
    c0.dir = d;
    c0.medium = world.camera_medium();
    camera.push(c0);
    let pdf_dir = ctx.camera.pdf_we(&Ray::new(ray.o, d)).1;
    walk(
        ctx,
        Ray::new(ray.o, d),
        Vec3::splat(weight),
        pdf_dir,
        TransportMode::Radiance,
        max_vertices,
        camera,
        s,
        stats,
        world.camera_medium(),
        media,
    );
}

/// The light subpath (pbrt-v4 `GenerateLightSubpath`): a light point chosen by power, then up
/// to `max_vertices` scattering vertices. `lens` is where [`medium_at`] starts looking for the
/// light's medium in a scene with media.
pub(crate) fn light_subpath(
    ctx: &Context,
    lens: Vec3,
    s: &mut impl UniformSource,
    stats: &mut RayStats,
    light: &mut Vec<PathVertex>,
    media: &mut MediaState,
    max_vertices: usize,
) {
    let world = ctx.world;
    let Some(em) = super::lighttracer::sample_emission(world, s, ctx.time) else {
        return;
    };
    let les = em.le;
    let infinite = world.lights()[em.index].is_infinite();
    // The light's emission as the path carries it (at the sample's wavelengths when spectral).
    let le = ctx
        .set
        .light_emission(&world.lights, em.index as u32, les.le);
    let mut l0 = PathVertex::new(
        Kind::Light {
            light: em.index as u32,
            infinite,
        },
        les.ray.o,
        les.n,
        le,
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
    if media.rng.is_some() {
        l0.medium = medium_at(world, lens, les.ray.o, ctx.time);
    }
    let start_medium = l0.medium_toward(world, les.ray.d);
    light.push(l0);
    let beta = le * (les.cos() / (em.pmf * les.pdf_pos * les.pdf_dir));
    let n_before = light.len();
    walk(
        ctx,
        les.ray,
        beta,
        les.pdf_dir,
        TransportMode::Importance,
        max_vertices,
        light,
        s,
        stats,
        start_medium,
        media,
    );
    // A light at infinity: its first vertex's density is over the disk its rays leave from,
    // with the cosine there (pbrt-v4 `GenerateLightSubpath`).
    if infinite && light.len() > n_before {
        let v1 = &mut light[n_before];
        v1.pdf_fwd = les.pdf_pos;
        if v1.on_surface() {
            v1.pdf_fwd *= v1.ng.dot(les.ray.d).abs();
        }
    }
}

/// The light tracer in a scene with media: a light subpath as BDPT's (medium vertices and all),
/// every vertex joined to the lens with the transmittance between (the strategies (s, 1),
/// unweighted) and an area light's own point too (s = 1, t = 1). Contributions are splatted
/// into `out` times `scale`. The media-free light tracer is `lighttracer::trace`.
pub fn trace_light(
    ctx: &Context,
    s: &mut impl UniformSource,
    scratch: &mut Scratch,
    stats: &mut RayStats,
    scale: f32,
    out: &mut impl super::lighttracer::Splat,
) {
    // Spectral mode: the sample's wavelengths, drawn first as `lighttracer::trace` draws them,
    // on a copy of the settings the subpath and its joins read.
    let spectral_set = ctx.set.for_sample(s);
    let spectral_ctx = spectral_set.as_ref().map(|set| ctx.with_set(set));
    let ctx = spectral_ctx.as_ref().unwrap_or(ctx);
    let world = ctx.world;
    let light = &mut scratch.light;
    light.clear();
    let lens = ctx.camera.lens_center();
    let mut media = MediaState::new(world, s, lens);
    light_subpath(
        ctx,
        lens,
        s,
        stats,
        light,
        &mut media,
        ctx.set.max_depth as usize,
    );
    for (i, qs) in light.iter().enumerate() {
        let u = s.next_2d();
        let area_light = i == 0 && qs.ng != Vec3::ZERO && !qs.is_infinite_light();
        if (!qs.scatters() || qs.delta) && !area_light {
            continue;
        }
        let Some(cs) = ctx.camera.sample_wi(qs.p, u) else {
            continue;
        };
        let mut cv = PathVertex::new(Kind::Camera, cs.p_lens, Vec3::ZERO, Vec3::ZERO);
        cv.dir = -cs.wi;
        let l = if area_light {
            let li = qs.light_index().unwrap_or(0);
            let scene = world.light_scene();
            let light_ref = world.lights.posed(li, ctx.time);
            if !(light_ref.pdf_le(&scene, qs.ng, cs.wi).1 > 0.0) {
                continue;
            }
            // β of the light vertex is Le / (pmf · pdf_pos) over the chosen direction's Le:
            // the emitted radiance towards the lens is looked up again.
            let le = light_ref.l(&scene, &qs.v.hit, cs.wi);
            let le = ctx.set.light_emission(&world.lights, li as u32, le);
            le * (qs.ng.dot(cs.wi).abs() / qs.pdf_fwd)
        } else {
            qs.beta * qs.f_cos(cs.p_lens, TransportMode::Importance)
        };
        let l = l * (cs.we / cs.pdf);
        if l == Vec3::ZERO || !l.is_finite() {
            continue;
        }
        let tr = ctx.transmittance(qs, &cv, &mut media, stats);
        if tr != Vec3::ZERO {
            let l = l * tr * scale;
            // A dispersive vertex anywhere on the subpath keeps the hero wavelength alone for
            // the whole sample (as `trace`).
            let l = if media.hero_only {
                Vec3::new(3.0 * l.x, 0.0, 0.0)
            } else {
                l
            };
            out.splat(cs.raster, ctx.set.to_film(l));
        }
    }
}

/// Strategy (s, t) alone on the subpaths in `scratch` (at least s light and t camera
/// vertices; the light subpath may be empty for s = 1, which samples its own light point): its
/// MIS-weighted contribution and, for t = 1, the film point it lands on. Metropolis light
/// transport evaluates one strategy per path this way (`mlt.rs`).
pub(crate) fn connect_strategy(
    ctx: &Context,
    scratch: &mut Scratch,
    s: usize,
    t: usize,
    stream: &mut impl UniformSource,
    stats: &mut RayStats,
    media: &mut MediaState,
) -> Option<(Vec3, Vec2)> {
    let Scratch {
        camera,
        light,
        fwd,
        rev,
        delta,
    } = scratch;
    connect(
        ctx,
        light,
        camera,
        s,
        t,
        stream,
        stats,
        fwd,
        rev,
        delta,
        &mut NoStrategies,
        media,
    )
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
    stream: &mut impl UniformSource,
    stats: &mut RayStats,
    fwd: &mut Vec<f32>,
    rev: &mut Vec<f32>,
    delta: &mut Vec<bool>,
    sink: &mut impl StrategySink,
    media: &mut MediaState,
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
            Kind::Light { infinite: true, .. } => pt.beta * ctx.set.escaped(world, pt.dir),
            Kind::Surface if pt.v.hit.light != NO_LIGHT => {
                let wo = (camera[t - 2].p - pt.p).normalize_or_zero();
                let le = world.emitted(&pt.v.hit, wo);
                pt.beta * ctx.set.light_emission(&world.lights, pt.v.hit.light, le)
            }
            _ => return None,
        }
    } else if t == 1 {
        // Join the light vertex to the lens.
        let qs = &light[s - 1];
        let u = stream.next_2d();
        if qs.delta || !qs.scatters() {
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
        if l == Vec3::ZERO {
            return None;
        }
        let l = l * ctx.transmittance(qs, &cv, media, stats);
        sampled = Some(cv);
        l
    } else if s == 1 {
        // Sample a light point for the camera vertex (next-event estimation), choosing the
        // light by power as light subpaths do.
        let u_light = stream.next_1d();
        let u = stream.next_2d();
        if pt.delta || !pt.scatters() || world.lights.is_empty() {
            return None;
        }
        let (li, pmf) = world.lights.distribution.sample_discrete(u_light);
        if !(pmf > 0.0) {
            return None;
        }
        // A moving light where it is at the sample's moment.
        let light_ref = world.lights.posed(li, ctx.time);
        let scene = world.light_scene();
        let lv = if let Some(area) = light_ref.as_area() {
            // A point uniform by area, so that its density is the light subpaths' origin one.
            let lp = area.sample_point(&world.geometry, u);
            let w = (pt.p - lp.p).normalize_or_zero();
            let (pos, _) = light_ref.pdf_le(&scene, lp.ng, w);
            let le = light_ref.l(&scene, &lp, w);
            if !(pos > 0.0) || le == Vec3::ZERO {
                return None;
            }
            let le = ctx.set.light_emission(&world.lights, li as u32, le);
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
            // A medium point has no normal: the light is sampled over the whole sphere.
            let n = if pt.kind == Kind::Medium {
                Vec3::ZERO
            } else {
                pt.v.ng
            };
            let ls = light_ref.sample_li(&scene, &pt.v.hit, n, u, EnvPdf::Full, Vec3::ZERO)?;
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
            v.beta =
                ctx.set.light_emission(&world.lights, li as u32, ls.li) * (g_undo / (pmf * ls.pdf));
            v
        };
        let mut lv = lv;
        lv.pdf_fwd = ctx.pdf_light_origin(&lv, pt);
        let l = pt.beta * pt.f_cos(light_target(&lv, pt), TransportMode::Radiance) * lv.beta;
        if l == Vec3::ZERO {
            return None;
        }
        let l = l * ctx.transmittance(pt, &lv, media, stats) * light_geometry(&lv, pt);
        sampled = Some(lv);
        l
    } else {
        let qs = &light[s - 1];
        if qs.delta || pt.delta || !qs.scatters() || !pt.scatters() {
            return None;
        }
        let l = qs.beta
            * qs.f_cos(pt.p, TransportMode::Importance)
            * pt.f_cos(qs.p, TransportMode::Radiance)
            * pt.beta;
        if l == Vec3::ZERO {
            return None;
        }
        let l = l * ctx.transmittance(qs, pt, media, stats);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::material::Bsdf;
    use crate::material::bxdf::{Diffuse, Mirror};
    use crate::math::{Frame, Vec2};
    use crate::scene::{LightDesc, builtin};

    /// A vertex of a hand-made path: where it is and how it scatters.
    #[derive(Clone, Copy)]
    enum Node {
        AreaLight,
        PointLight,
        Diffuse(Vec3, Vec3),
        Mirror(Vec3, Vec3),
        Medium(Vec3),
        Camera,
    }

    fn vertex(world: &World, camera: &CameraImportance, node: Node) -> PathVertex {
        let surface = |p: Vec3, n: Vec3, bsdf: Bsdf, delta: bool| {
            let mut v = PathVertex::new(Kind::Surface, p, n, Vec3::ONE);
            v.v.hit.p = p;
            v.v.hit.ng = n;
            v.v.hit.ns = n;
            v.v.bsdf = bsdf;
            v.v.ng = n;
            v.v.frame = Frame::from_normal(n);
            v.delta = delta;
            v
        };
        let light = |want_delta: bool| {
            (0..world.lights().len())
                .find(|&i| world.lights()[i].is_delta() == want_delta)
                .unwrap()
        };
        match node {
            Node::AreaLight => {
                let li = light(false);
                let area = world.lights()[li].as_area().unwrap();
                let lp = world.geometry.sample_point(area.prim, Vec2::new(0.3, 0.6));
                let kind = Kind::Light {
                    light: li as u32,
                    infinite: false,
                };
                let mut v = PathVertex::new(kind, lp.p, lp.ng, Vec3::ONE);
                v.v.hit = lp;
                v
            }
            Node::PointLight => {
                let li = light(true);
                let kind = Kind::Light {
                    light: li as u32,
                    infinite: false,
                };
                PathVertex::new(kind, Vec3::new(0.2, 0.8, 0.1), Vec3::ZERO, Vec3::ONE)
            }
            Node::Diffuse(p, n) => surface(
                p,
                n,
                Bsdf::Diffuse(Diffuse {
                    albedo: Vec3::splat(0.5),
                }),
                false,
            ),
            Node::Mirror(p, n) => surface(p, n, Bsdf::Mirror(Mirror { color: Vec3::ONE }), true),
            Node::Medium(p) => {
                PathVertex::in_medium(p, Vec3::X, Vec3::ONE, 0, HenyeyGreenstein::new(0.4))
            }
            Node::Camera => {
                PathVertex::new(Kind::Camera, camera.lens_center(), Vec3::ZERO, Vec3::ONE)
            }
        }
    }

    /// Whether `connect` evaluates strategy (s, t) of the path (its joined ends can be joined).
    fn evaluated(nodes: &[Node], s: usize) -> bool {
        let n = nodes.len();
        let t = n - s;
        let scatters = |k: usize| matches!(nodes[k], Node::Diffuse(..) | Node::Medium(_));
        if t < 1 || (s == 1 && t == 1) {
            return false;
        }
        if s == 0 {
            return matches!(nodes[0], Node::AreaLight);
        }
        // Light end: the light itself (s = 1) or a scattering vertex; camera end likewise.
        (s == 1 || scatters(s - 1)) && (t == 1 || scatters(s))
    }

    /// The MIS weights of every strategy that can make the path, for the path split at each s
    /// with the densities its two walks would have given its vertices.
    fn weights(ctx: &Context, nodes: &[Node]) -> Vec<(usize, f32)> {
        let n = nodes.len();
        let make = || -> Vec<PathVertex> {
            nodes
                .iter()
                .map(|&k| vertex(ctx.world, ctx.camera, k))
                .collect()
        };
        // Densities along the path: from the light (towards the camera) and from the camera.
        let xs = make();
        let mut from_light = vec![0.0f32; n];
        let mut from_camera = vec![0.0f32; n];
        from_light[0] = ctx.pdf_light_origin(&xs[0], &xs[1]);
        for i in 1..n {
            from_light[i] = ctx.pdf(&xs[i - 1], (i >= 2).then(|| &xs[i - 2]), &xs[i]);
        }
        for i in (0..n - 1).rev() {
            from_camera[i] = ctx.pdf(&xs[i + 1], xs.get(i + 2), &xs[i]);
        }
        let (mut fwd, mut rev, mut delta) = (Vec::new(), Vec::new(), Vec::new());
        (0..n)
            .filter(|&s| evaluated(nodes, s))
            .map(|s| {
                let mut xs = make();
                for (i, v) in xs.iter_mut().enumerate() {
                    let (f, r) = (from_light[i], from_camera[i]);
                    (v.pdf_fwd, v.pdf_rev) = if i < s { (f, r) } else { (r, f) };
                }
                let mut camera: Vec<PathVertex> = xs.drain(s..).collect();
                camera.reverse();
                let w = mis_weight(
                    ctx,
                    &xs,
                    &camera,
                    None,
                    s,
                    n - s,
                    &mut fwd,
                    &mut rev,
                    &mut delta,
                );
                (s, w)
            })
            .collect()
    }

    /// For one path of each shape — all diffuse, through a mirror, from a point light, through
    /// a medium point, and a point light's light through a medium and a mirror — the weights
    /// of all strategies that can make it add up to 1 (Veach 1997 §9.2: the weights partition
    /// unity), and every one of them is in [0, 1].
    #[test]
    fn mis_weights_of_a_path_sum_to_one() {
        let mut scene = builtin::cornell();
        scene.lights.push(LightDesc::Point {
            name: "bulb".into(),
            position: Vec3::new(0.2, 0.8, 0.1),
            intensity: Vec3::splat(2.0),
        });
        let world = World::build(scene, &Default::default()).unwrap();
        let importance = Camera::new(&world.camera, 32, 32).importance().unwrap();
        let set = PathSettings::default();
        let ctx = Context {
            world: &world,
            camera: &importance,
            set: &set,
            time: 0.0,
        };
        let floor = Node::Diffuse(Vec3::new(-0.3, -1.0, 0.2), Vec3::Y);
        let back = Node::Diffuse(Vec3::new(0.2, 0.1, -1.0), Vec3::Z);
        let left = Node::Diffuse(Vec3::new(-1.0, 0.3, -0.2), Vec3::X);
        let mirror = Node::Mirror(Vec3::new(1.0, -0.2, 0.1), -Vec3::X);
        let fog = Node::Medium(Vec3::new(0.1, 0.2, 0.3));
        use Node::{AreaLight, Camera as Cam, PointLight};
        let paths: [(&str, Vec<Node>); 6] = [
            ("diffuse", vec![AreaLight, floor, left, back, Cam]),
            ("specular", vec![AreaLight, floor, mirror, left, back, Cam]),
            ("delta light", vec![PointLight, floor, left, back, Cam]),
            ("medium", vec![AreaLight, floor, fog, back, Cam]),
            (
                "medium, delta light",
                vec![PointLight, fog, left, mirror, back, Cam],
            ),
            ("direct", vec![AreaLight, back, Cam]),
        ];
        for (what, nodes) in paths {
            let w = weights(&ctx, &nodes);
            let sum: f32 = w.iter().map(|&(_, w)| w).sum();
            assert!(w.len() >= 2, "{what}: only {} strategies", w.len());
            assert!(
                w.iter().all(|&(_, w)| (0.0..=1.0).contains(&w)),
                "{what}: weights {w:?}"
            );
            assert!(
                (sum - 1.0).abs() < 1e-4,
                "{what}: the weights {w:?} sum to {sum}"
            );
        }
    }
}
