//! The AOV tracer (docs/DESIGN.md §5): for one camera sample, what the first visible surface is
//! (depth, position, shading normal, material and object) and, following perfect-specular chains
//! (mirrors, smooth glass, smooth metals), the reflectance and normal of the first non-specular
//! surface — the albedo and normal guides Intel Open Image Denoise expects ("for perfect specular
//! materials the albedo of the surface seen through/reflected in them", OIDN's documentation of
//! the `albedo` and `normal` images).
//!
//! It runs as its own pass over the same camera samples as the beauty image (the first four
//! numbers of each sample's stream are the pixel jitter and lens position, so each AOV sample
//! sees exactly the camera ray of the matching beauty sample), rather than inside the path
//! tracer: the beauty image is then bit-identical with AOVs on or off, and every integrator
//! (path, volumetric path, Whitted, raycast) gets the same layers. A specular chain picks
//! reflection or transmission at a dielectric with the stream's next numbers, like a path does,
//! and multiplies the sampled weight `f·|cos|/pdf` into the albedo, so a pixel's mean is the
//! Fresnel-weighted mix of what is reflected and what is seen through. Media are not scattered
//! in (the guides describe surfaces); index-matched interface surfaces are passed through.

use super::vertex::Vertex;
use crate::film::aov::{AovKind, Layer};
use crate::geometry::primitive::SurfaceHit;
use crate::geometry::{PrimitiveKind, Ray};
use crate::math::Vec3;
use crate::sampling::SampleStream;
use crate::world::World;

/// Perfect-specular bounces followed before the albedo/normal are taken where the chain is.
pub const MAX_SPECULAR_CHAIN: u32 = 16;
/// Interface (index-matched, medium boundary) surfaces passed through along one ray segment.
const MAX_PASSTHROUGH: u32 = 64;

/// What one camera sample sees.
#[derive(Clone, Copy, Debug, Default)]
pub struct AovSample {
    /// Reflectance at the end of the specular chain, times the chain's weights (0 on a miss).
    pub albedo: Vec3,
    /// Shading normal (facing the viewer) at the end of the specular chain (0 on a miss).
    pub normal: Vec3,
    /// The first visible surface, if any.
    pub first: Option<FirstHit>,
}

#[derive(Clone, Copy, Debug)]
pub struct FirstHit {
    /// Distance from the camera ray's origin, in scene units.
    pub depth: f32,
    pub position: Vec3,
    /// Normal-mapped shading normal facing the viewer.
    pub normal: Vec3,
    pub material: u32,
    pub object: u32,
}

/// The object id of a primitive: the mesh for triangles, else one id per analytic shape
/// (numbered after the meshes: spheres, then boxes, then quads).
pub fn object_of(world: &World, hit: &SurfaceHit) -> u32 {
    let g = &world.geometry;
    let i = hit.prim.index() as u32;
    let meshes = g.meshes.len() as u32;
    match hit.prim.kind() {
        // Instanced triangles: one id per instance, numbered after every other object.
        PrimitiveKind::Triangle => match g.tri_mesh.get(i as usize) {
            Some(&(mesh, _)) => mesh,
            None => {
                meshes
                    + (g.spheres.len() + g.cuboids.len() + g.quads.len()) as u32
                    + g.instances.instance_index(i as usize) as u32
            }
        },
        PrimitiveKind::Sphere => meshes + i,
        PrimitiveKind::Cuboid => meshes + g.spheres.len() as u32 + i,
        PrimitiveKind::Quad => meshes + (g.spheres.len() + g.cuboids.len()) as u32 + i,
        PrimitiveKind::Curve => {
            meshes + (g.spheres.len() + g.cuboids.len() + g.quads.len()) as u32 + i
        }
    }
}

/// The first surface along `ray` that is not an index-matched medium interface.
fn intersect_solid(world: &World, mut ray: Ray) -> Option<(SurfaceHit, f32)> {
    let mut travelled = 0.0f32;
    let len = ray.d.length();
    for _ in 0..MAX_PASSTHROUGH {
        let hit = world.intersect(&ray)?;
        if !world.is_interface(hit.material) {
            return Some((hit, travelled + hit.t * len));
        }
        travelled += hit.t * len;
        // Continue on the far side, along the same direction.
        let n = if hit.ng.dot(ray.d) < 0.0 {
            -hit.ng
        } else {
            hit.ng
        };
        ray = Ray::spawn(hit.p, hit.p_error, n, ray.d).with_time(hit.time);
    }
    None
}

/// Whether the camera ray `ray` hits a solid surface (not only medium interfaces): the coverage a
/// `--transparent` film counts ([`crate::film::Film::track_coverage`]).
pub fn covers(world: &World, ray: &Ray) -> bool {
    intersect_solid(world, *ray).is_some()
}

/// Traces the AOVs of the camera ray `ray`, drawing the specular chain's choices from `s`.
pub fn trace(world: &World, ray: &Ray, s: &mut SampleStream) -> AovSample {
    let mut out = AovSample::default();
    let Some((hit, depth)) = intersect_solid(world, *ray) else {
        return out;
    };
    let mut wo = -ray.d.normalize();
    let mut v = Vertex::new(world, hit, wo);
    out.first = Some(FirstHit {
        depth,
        position: v.hit.p,
        normal: facing(&v, wo),
        material: v.hit.material,
        object: object_of(world, &v.hit),
    });
    let mut weight = Vec3::ONE;
    for _ in 0..MAX_SPECULAR_CHAIN {
        if !v.bsdf.is_specular() {
            break;
        }
        let u_lobe = s.next_1d();
        let u = s.next_2d();
        let Some(bs) = v.bsdf.sample(v.wo_local, u_lobe, u) else {
            return out;
        };
        let wi = v.frame.to_world(bs.wi);
        if !v.bsdf.side_consistent(bs.wi, wi.dot(v.ng)) || !(bs.pdf > 0.0) {
            return out;
        }
        weight *= bs.f * (bs.wi.z.abs() / bs.pdf);
        if !weight.is_finite() || !(weight.max_element() > 0.0) {
            return out;
        }
        let next = Ray::spawn(v.hit.p, v.hit.p_error, v.ng, wi).with_time(v.hit.time);
        let Some((hit, _)) = intersect_solid(world, next) else {
            // Reflected or seen through into the background: nothing to guide with.
            return out;
        };
        wo = -wi;
        v = Vertex::new(world, hit, wo);
    }
    out.albedo = weight * v.bsdf.albedo().clamp(Vec3::ZERO, Vec3::ONE);
    out.normal = facing(&v, wo);
    out
}

/// The AOVs of one camera sample as the path tracer records them along its own path
/// ([`super::path::radiance_aov`]): the same quantities as [`trace`], taken at the path's
/// vertices instead of a second tracing of the camera ray. The path's own choices at specular
/// vertices (from its own sampler dimensions) pick the chain, so the values differ from
/// [`trace`]'s sample by sample but have the same expectation; the path's radiance does not
/// depend on whether they are recorded (the recorder only reads the path's vertices).
#[derive(Clone, Copy, Debug, Default)]
pub struct AovPath {
    pub sample: AovSample,
    /// Product of the specular chain's sampled weights `f·|cos|/pdf` so far.
    weight: Vec3,
    /// The albedo and normal have been taken (or the chain was lost).
    done: bool,
}

impl AovPath {
    pub fn new() -> AovPath {
        AovPath {
            weight: Vec3::ONE,
            ..AovPath::default()
        }
    }

    /// The camera ray's first hit, the vertex `v` reached with direction `-wo`, at `depth` scene
    /// units from the camera.
    #[inline]
    pub fn first(&mut self, world: &World, v: &Vertex, wo: Vec3, depth: f32) {
        self.sample.first = Some(FirstHit {
            depth,
            position: v.hit.p,
            normal: facing(v, wo),
            material: v.hit.material,
            object: object_of(world, &v.hit),
        });
    }

    /// A scattering vertex of the path: takes the albedo and normal if it is the first
    /// non-specular one.
    #[inline]
    pub fn vertex(&mut self, v: &Vertex, wo: Vec3) {
        if !self.done && !v.bsdf.is_specular() {
            self.take(v, wo);
        }
    }

    /// The path continued from a specular vertex with the sampled weight `w` (`f·|cos|/pdf`).
    #[inline]
    pub fn specular_bounce(&mut self, w: Vec3) {
        if !self.done {
            self.weight *= w;
        }
    }

    /// The path ends at `v` (maximum depth or Russian roulette) while the chain is still
    /// specular: the albedo and normal are `v`'s, as [`trace`]'s are after
    /// [`MAX_SPECULAR_CHAIN`] bounces.
    #[inline]
    pub fn end_at(&mut self, v: &Vertex, wo: Vec3) {
        if !self.done {
            self.take(v, wo);
        }
    }

    /// The chain was lost (escaped or absorbed): nothing to guide with, as in [`trace`].
    #[inline]
    pub fn lost(&mut self) {
        self.done = true;
    }

    /// Whether the albedo and normal are settled (taken, or the chain lost).
    #[inline]
    pub fn is_done(&self) -> bool {
        self.done
    }

    fn take(&mut self, v: &Vertex, wo: Vec3) {
        self.done = true;
        if !self.weight.is_finite() || !(self.weight.max_element() > 0.0) {
            return;
        }
        self.sample.albedo = self.weight * v.bsdf.albedo().clamp(Vec3::ZERO, Vec3::ONE);
        self.sample.normal = facing(v, wo);
    }
}

/// The shading normal of `v` facing `wo`.
#[inline]
fn facing(v: &Vertex, wo: Vec3) -> Vec3 {
    let n = v.hit.ns;
    if n.dot(wo) < 0.0 { -n } else { n }
}

/// Per-pixel accumulator of [`AovSample`]s. One pixel's samples are added in sample order by one
/// thread, so the sums (and the layers) do not depend on the thread count.
#[derive(Clone, Debug, Default)]
pub struct PixelAovs {
    n: u32,
    hits: u32,
    albedo: [f64; 3],
    normal: [f64; 3],
    shading_normal: [f64; 3],
    position: [f64; 3],
    depth: f64,
    /// (id, samples) of the materials and objects seen; the pixel shows the most frequent.
    materials: Vec<(u32, u32)>,
    objects: Vec<(u32, u32)>,
}

fn add3(a: &mut [f64; 3], v: Vec3) {
    a[0] += v.x as f64;
    a[1] += v.y as f64;
    a[2] += v.z as f64;
}

fn vote(votes: &mut Vec<(u32, u32)>, id: u32) {
    vote_n(votes, id, 1);
}

fn vote_n(votes: &mut Vec<(u32, u32)>, id: u32, n: u32) {
    match votes.iter_mut().find(|(i, _)| *i == id) {
        Some(v) => v.1 += n,
        None => votes.push((id, n)),
    }
}

/// The most frequent id (+1), ties to the smaller id; 0 if there are none.
fn winner(votes: &[(u32, u32)]) -> f32 {
    votes
        .iter()
        .max_by(|a, b| a.1.cmp(&b.1).then(b.0.cmp(&a.0)))
        .map_or(0.0, |(id, _)| (*id as f64 + 1.0) as f32)
}

impl PixelAovs {
    pub fn clear(&mut self) {
        *self = PixelAovs {
            materials: std::mem::take(&mut self.materials),
            objects: std::mem::take(&mut self.objects),
            ..PixelAovs::default()
        };
        self.materials.clear();
        self.objects.clear();
    }

    pub fn add(&mut self, s: &AovSample) {
        self.n += 1;
        add3(&mut self.albedo, s.albedo);
        add3(&mut self.normal, s.normal);
        if let Some(f) = s.first {
            self.hits += 1;
            add3(&mut self.shading_normal, f.normal);
            add3(&mut self.position, f.position);
            self.depth += f.depth as f64;
            vote(&mut self.materials, f.material);
            vote(&mut self.objects, f.object);
        }
    }

    /// Adds the samples of `o` (the same pixel's later samples) to these.
    pub fn merge(&mut self, o: &PixelAovs) {
        self.n += o.n;
        self.hits += o.hits;
        for k in 0..3 {
            self.albedo[k] += o.albedo[k];
            self.normal[k] += o.normal[k];
            self.shading_normal[k] += o.shading_normal[k];
            self.position[k] += o.position[k];
        }
        self.depth += o.depth;
        for &(id, n) in &o.materials {
            vote_n(&mut self.materials, id, n);
        }
        for &(id, n) in &o.objects {
            vote_n(&mut self.objects, id, n);
        }
    }

    /// Appends the pixel's value of `kind` to `out`. Albedo and normals average over all
    /// samples (a miss counts as 0: the guides are anti-aliased like the beauty image); depth
    /// and position over the samples that hit (edges get a surface's depth, not a blend with
    /// nothing), +∞ / 0 where no sample hit; ids are the most frequent one.
    pub fn push(&self, kind: AovKind, out: &mut Vec<f32>) {
        let all = self.n.max(1) as f64;
        let hits = self.hits.max(1) as f64;
        let mean3 = |a: &[f64; 3], d: f64, out: &mut Vec<f32>| {
            out.extend(a.iter().map(|v| (v / d) as f32));
        };
        match kind {
            AovKind::Albedo => mean3(&self.albedo, all, out),
            AovKind::Normal => mean3(&self.normal, all, out),
            AovKind::ShadingNormal => mean3(&self.shading_normal, all, out),
            AovKind::Position => mean3(&self.position, hits, out),
            AovKind::Depth => out.push(if self.hits == 0 {
                f32::INFINITY
            } else {
                (self.depth / hits) as f32
            }),
            AovKind::MaterialId => out.push(winner(&self.materials)),
            AovKind::ObjectId => out.push(winner(&self.objects)),
            // Not traced: they come from the film (`film::aov::film_layers`) or BDPT's own pass
            // (strategies), and every caller leaves them out of its rows, as `layers` does.
            AovKind::Samples | AovKind::Variance | AovKind::Alpha | AovKind::Strategy(_) => {}
        }
    }
}

/// Builds the layers of the traced kinds among `kinds` ([`AovKind::is_traced`]; the film's
/// statistics are not in the rows) from rows of per-pixel accumulators.
pub fn layers(kinds: &[AovKind], width: u32, height: u32, rows: &[Vec<f32>]) -> Vec<Layer> {
    let kinds = traced(kinds);
    // `rows[y]` holds, per pixel, the channels of every traced kind in `kinds` order.
    let per_pixel: usize = kinds.iter().map(|k| k.channels().len()).sum();
    let mut out = Vec::with_capacity(kinds.len());
    let mut offset = 0;
    for k in kinds {
        let c = k.channels().len();
        let mut data = Vec::with_capacity(width as usize * height as usize * c);
        for row in rows {
            for px in row.chunks_exact(per_pixel) {
                data.extend_from_slice(&px[offset..offset + c]);
            }
        }
        out.push(Layer::new(k, width, height, data));
        offset += c;
    }
    out
}

/// The kinds among `kinds` that are traced per hit, in order (the film's statistics, samples
/// and variance, are left out: [`crate::film::aov::film_layers`] builds them).
pub fn traced(kinds: &[AovKind]) -> Vec<AovKind> {
    kinds.iter().copied().filter(|k| k.is_traced()).collect()
}
