//! The integrator a frame is rendered with, decided once from the requested
//! [`IntegratorKind`] and the world, and what it can do. The driver (`render.rs`) asks the
//! resolved [`Integrator`] for its [`Capabilities`] instead of re-deriving them from the kind
//! (docs/DESIGN.md §1, integrators): a new integrator (light tracing, bidirectional path tracing,
//! photon mapping) is one more variant here and one more row of capabilities.

use super::{Aov, IntegratorKind, PathSettings, RayStats, ShadingModel};
use super::{path, raycast, volpath, whitted};
use crate::geometry::Ray;
use crate::math::Vec3;
use crate::sampling::SampleStream;
use crate::world::World;

/// An integrator resolved for one world.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// The surface path tracer (`path.rs`): media-free scenes.
    Path,
    /// The volumetric path tracer (`volpath.rs`): `--integrator path` in a scene with
    /// participating media or medium interfaces.
    VolPath,
    /// The thesis's ray caster: first hit only, shown as the view `aov`.
    Raycast { aov: Aov, shading: ShadingModel },
    /// The thesis's Whitted ray tracer.
    Whitted { shading: ShadingModel },
    /// The light tracer (`lighttracer.rs`): its paths splat onto the film, so the driver runs
    /// it through `render/light.rs` instead of per camera sample.
    LightTracer,
    /// Bidirectional path tracing (`bdpt.rs`); its t = 1 strategies splat, so it runs through
    /// `render/light.rs` too.
    Bdpt,
    /// Metropolis light transport (`mlt.rs`): Markov chains over BDPT's strategies, splatting;
    /// `render/light.rs` hands it the frame.
    Mlt,
    /// Stochastic progressive photon mapping (`sppm.rs`): iterations of visible points and
    /// photons, rendered by `render/photon.rs`.
    Sppm,
    /// Vertex connection and merging (`vcm.rs`): iterations of light and camera subpaths,
    /// rendered by `render/photon.rs`.
    Vcm,
}

/// What an integrator can do, as the driver and the pipeline need to know it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capabilities {
    /// Records AOVs in the render's own paths (`path::radiance_aov`); the others get them from
    /// a separate pass (`render::render_aovs_samples`).
    pub in_loop_aovs: bool,
    /// Its camera samples go through the driver's batched first hits (`render::Batch`).
    pub batched_first_hits: bool,
    /// Honours first-hit splitting (`PathSettings::secondary > 1`).
    pub splitting: bool,
    /// Renders participating media and medium interfaces.
    pub media: bool,
    /// Its contributions land anywhere on the film (splats), not on the sampled pixel: rendered
    /// by `render/light.rs`.
    pub splats: bool,
}

impl Integrator {
    /// The integrator that renders `kind` in a world with (`has_media`) or without media:
    /// `path` is the volumetric path tracer where there are media, and the surface path tracer
    /// (unchanged) everywhere else.
    pub fn resolve(kind: IntegratorKind, has_media: bool) -> Integrator {
        match kind {
            IntegratorKind::Path if has_media => Integrator::VolPath,
            IntegratorKind::Path => Integrator::Path,
            IntegratorKind::Raycast { aov, shading } => Integrator::Raycast { aov, shading },
            IntegratorKind::Whitted { shading } => Integrator::Whitted { shading },
            IntegratorKind::LightTracer => Integrator::LightTracer,
            IntegratorKind::Bdpt => Integrator::Bdpt,
            IntegratorKind::Sppm => Integrator::Sppm,
            IntegratorKind::Vcm => Integrator::Vcm,
            IntegratorKind::Mlt => Integrator::Mlt,
        }
    }

    /// [`Integrator::resolve`] for `world`.
    pub fn for_world(kind: IntegratorKind, world: &World) -> Integrator {
        Integrator::resolve(kind, world.has_media())
    }

    /// Whether this integrator carries sampled wavelengths (docs/DESIGN.md "Spectral
    /// rendering"): every one but raycast and Whitted, whose local shading is RGB.
    pub fn carries_wavelengths(self) -> bool {
        !matches!(
            self,
            Integrator::Raycast { .. } | Integrator::Whitted { .. }
        )
    }

    pub fn capabilities(self) -> Capabilities {
        match self {
            Integrator::Path => Capabilities {
                in_loop_aovs: true,
                batched_first_hits: true,
                splitting: true,
                media: false,
                splats: false,
            },
            // No first-hit splitting: the first vertex may be in a medium.
            Integrator::VolPath => Capabilities {
                in_loop_aovs: false,
                batched_first_hits: false,
                splitting: false,
                media: true,
                splats: false,
            },
            // They ignore `secondary`, as they always have.
            Integrator::Raycast { .. } | Integrator::Whitted { .. } => Capabilities {
                in_loop_aovs: false,
                batched_first_hits: false,
                splitting: true,
                media: false,
                splats: false,
            },
            Integrator::LightTracer | Integrator::Bdpt | Integrator::Mlt => Capabilities {
                in_loop_aovs: false,
                batched_first_hits: false,
                splitting: false,
                media: true,
                splats: true,
            },
            // Its own driver (`render/photon.rs`); no media, as pbrt-v4's SPPM.
            Integrator::Sppm | Integrator::Vcm => Capabilities {
                in_loop_aovs: false,
                batched_first_hits: false,
                splitting: false,
                media: false,
                splats: false,
            },
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Integrator::Path => "path",
            Integrator::VolPath => "volumetric path",
            Integrator::Raycast { .. } => "raycast",
            Integrator::Whitted { .. } => "whitted",
            Integrator::LightTracer => "light tracer",
            Integrator::Bdpt => "bidirectional path tracer",
            Integrator::Sppm => "stochastic progressive photon mapper",
            Integrator::Vcm => "vertex connection and merging",
            Integrator::Mlt => "Metropolis light transport",
        }
    }

    /// The radiance arriving along the camera ray `ray`, traced sample by sample (the batched
    /// path tracer goes through `render::Batch` instead, with the same result).
    #[inline]
    pub fn radiance(
        self,
        world: &World,
        ray: &Ray,
        stream: &mut SampleStream,
        settings: &PathSettings,
        stats: &mut RayStats,
    ) -> Vec3 {
        match self {
            Integrator::Path => path::radiance(world, ray, stream, settings, stats),
            Integrator::VolPath => volpath::radiance(world, ray, stream, settings, stats),
            Integrator::Raycast { aov, shading } => {
                raycast::radiance(world, ray, stream, aov, shading, stats)
            }
            Integrator::Whitted { shading } => {
                whitted::radiance(world, ray, stream, settings.max_depth, shading, stats)
            }
            // Splatting integrators have no radiance per camera ray: the driver never asks.
            Integrator::LightTracer
            | Integrator::Bdpt
            | Integrator::Sppm
            | Integrator::Vcm
            | Integrator::Mlt => Vec3::ZERO,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn path_is_volumetric_only_with_media() {
        let k = IntegratorKind::Path;
        assert_eq!(Integrator::resolve(k, false), Integrator::Path);
        assert_eq!(Integrator::resolve(k, true), Integrator::VolPath);
        assert!(!Integrator::VolPath.capabilities().splitting);
        assert!(Integrator::Path.capabilities().in_loop_aovs);
        let w = IntegratorKind::Whitted {
            shading: ShadingModel::default(),
        };
        assert_eq!(
            Integrator::resolve(w, true),
            Integrator::Whitted {
                shading: ShadingModel::default()
            }
        );
    }
}
