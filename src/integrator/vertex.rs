//! A scattering vertex of a path (its hit, BSDF, oriented normals and shading frame), shared by
//! the path loop (`path.rs`, `volpath.rs`), next-event estimation (`direct.rs`) and the AOVs
//! (`aov.rs`), below all of them.

use crate::geometry::primitive::SurfaceHit;
use crate::light::EnvPdf;
use crate::material::Bsdf;
use crate::material::bxdf::{BsdfSample, Diffuse, TransportMode};
use crate::math::{Frame, Vec2, Vec3};
use crate::sampling::Numbers;
use crate::world::World;

/// A direction sampled from `bsdf` at `wo_local` with the next numbers of the path's stream: one
/// for the lobe (drawn and skipped when the BSDF has one lobe, so that every bounce takes the
/// same three numbers) and two for the direction. The path tracers' unguided bounce: the surface
/// loop, its wavefront form and the volumetric loop draw identically through it.
#[inline]
pub fn sample_bsdf<S: Numbers>(bsdf: &Bsdf, wo_local: Vec3, s: &mut S) -> Option<BsdfSample> {
    let u_lobe = if bsdf.has_one_lobe() {
        s.skip(1);
        0.0
    } else {
        s.next_1d()
    };
    let u_dir = s.next_2d();
    bsdf.sample(wo_local, u_lobe, u_dir)
}

/// A scattering vertex of a path: the hit (normal-mapped), its BSDF, the normals oriented for
/// scattering and the local shading frame with the outgoing direction in it. NEE and BSDF
/// sampling at the vertex share it.
pub struct Vertex {
    pub hit: SurfaceHit,
    pub bsdf: Bsdf,
    /// Geometric normal oriented as [`oriented_normals`] says (the side rays are spawned from).
    pub ng: Vec3,
    pub frame: Frame,
    /// Direction toward where the path came from, in `frame`.
    pub wo_local: Vec3,
    /// `bsdf.is_transmissive()`, kept from [`Vertex::shade`] (which needs it for the normals)
    /// for [`Vertex::uniform_env_normal`], asked twice per vertex.
    pub transmissive: bool,
}

impl Vertex {
    /// The vertex at `hit`, reached with direction `-wo`.
    #[inline]
    pub fn new(world: &World, hit: SurfaceHit, wo: Vec3) -> Vertex {
        let mut v = Vertex::unshaded(hit);
        v.shade(world, wo);
        v
    }

    /// The normal NEE samples a uniform environment about from this vertex
    /// (`light::sample_uniform_env`), and that MIS of an escaping BSDF sample from it must weigh
    /// against: the oriented geometric normal when the BSDF only reflects and light samples are
    /// combined with BSDF sampling by MIS (`env` compensated), zero (the whole sphere)
    /// otherwise. A reflecting BSDF's integrand is zero below the geometric surface
    /// (`Bsdf::side_consistent`), so half of the sphere's samples were thrown away; a direction
    /// it can still reach below the plane (a normal-mapped edge case) gets light pdf 0 there and
    /// is left to BSDF sampling with full weight (Veach 1997 §9.2), which is why NEE on its own
    /// (MIS off) keeps the sphere. The geometric rather than the shading normal: the side test
    /// is on it, the shadow ray leaves along it, and under a normal map the shading normal's
    /// hemisphere reaches below the surface. Transmitting BSDFs need both hemispheres.
    #[inline]
    pub fn uniform_env_normal(&self, env: EnvPdf) -> Vec3 {
        if env == EnvPdf::Compensated && !self.transmissive {
            self.ng
        } else {
            Vec3::ZERO
        }
    }

    /// Samples the BSDF at this vertex for the quantity `mode` carries (the adjoint for light
    /// paths): the sample, its direction in world space and its throughput weight
    /// f·|cos θ|·c/pdf, with c Veach's shading-normal correction (1 for radiance; Veach 1997
    /// §5.3). `None` without a sample, or when the sample leaves on the side the geometric
    /// normal forbids ([`Bsdf::side_consistent`]).
    #[inline]
    pub fn sample_scatter(
        &self,
        mode: TransportMode,
        u_lobe: f32,
        u_dir: Vec2,
    ) -> Option<(BsdfSample, Vec3, Vec3)> {
        let bs = self.bsdf.sample_mode(self.wo_local, u_lobe, u_dir, mode)?;
        let wi = self.frame.to_world(bs.wi);
        if !self.bsdf.side_consistent(bs.wi, wi.dot(self.ng)) {
            return None;
        }
        let corr = mode.shading_normal_correction(
            self.wo_local,
            bs.wi,
            Vec3::Z,
            self.frame.to_local(self.ng),
        );
        let weight = bs.f * (bs.wi.z.abs() * corr / bs.pdf);
        Some((bs, wi, weight))
    }

    /// A vertex holding `hit` whose shading is not built yet: storage that
    /// [`World::intersect_filtered_into`] and [`Vertex::shade`] fill in place along a path.
    #[inline]
    pub fn unshaded(hit: SurfaceHit) -> Vertex {
        Vertex {
            hit,
            bsdf: Bsdf::Diffuse(Diffuse { albedo: Vec3::ZERO }),
            ng: hit.ng,
            frame: Frame {
                x: Vec3::X,
                y: Vec3::Y,
                z: Vec3::Z,
            },
            wo_local: Vec3::Z,
            transmissive: false,
        }
    }

    /// Builds the vertex's shading at its hit (as intersected: not yet normal-mapped), reached
    /// with direction `-wo`: the normal map applied to `self.hit`, the BSDF, the oriented
    /// normals and the frame. Everything is written in place: a `SurfaceHit` (144 bytes) and a
    /// `Bsdf` are above the size LLVM copies inline, and building a vertex by value cost two
    /// `memcpy` calls per path vertex (callgrind, Cornell box). The material is resolved once for
    /// the coat normal, the normal map and the BSDF.
    #[inline]
    pub fn shade(&mut self, world: &World, wo: Vec3) {
        let material = world.surface_material(&self.hit);
        // The coat ignores the base's normal map: its normal is taken before the map is applied.
        let coat_normal = world.material_clearcoat_normal(material, &self.hit);
        // The normal map, then the BSDF's textures, sharing their texel addressing.
        self.bsdf = world.shade_surface(material, &mut self.hit);
        let hit = &self.hit;
        let transmissive = self.bsdf.is_transmissive();
        let (ng, ns) = oriented_normals(hit, wo, transmissive);
        let frame = Frame::from_normal_tangent(ns, hit.tangent);
        let wo_local = frame.to_local(wo);
        let flipped = ns.dot(hit.ns) < 0.0;
        if flipped {
            self.bsdf.flip_bitangent();
        }
        if let Some(n) = coat_normal {
            // Flipped with the shading normal (two-sided shading), then into the local frame,
            // with the geometric normal on the coat's side.
            let n = if flipped { -n } else { n };
            self.bsdf
                .set_coat_normal(frame.to_local(n), frame.to_local(ng));
        }
        self.bsdf.prepare(wo_local);
        self.ng = ng;
        self.frame = frame;
        self.wo_local = wo_local;
        self.transmissive = transmissive;
    }
}

/// Orients the geometric and shading normals for scattering. Opaque BSDFs see the side the ray
/// came from (two-sided shading by flipping the normals, docs/DESIGN.md §4); transmissive ones keep the
/// surface's own orientation so they know whether the ray enters or leaves.
#[inline]
pub fn oriented_normals(hit: &SurfaceHit, wo: Vec3, transmissive: bool) -> (Vec3, Vec3) {
    if !transmissive && hit.ng.dot(wo) < 0.0 {
        (-hit.ng, -hit.ns)
    } else {
        (hit.ng, hit.ns)
    }
}
