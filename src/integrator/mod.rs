//! Integrators: where a light path's life is decided. The path tracer (`path`) is the default and
//! the only unbiased one.

pub mod aov;
pub mod bdpt;
pub mod direct;
pub mod guiding;
pub mod lighttracer;
pub mod path;
pub mod photon_grid;
pub mod raycast;
pub mod select;
pub mod settings;
pub mod sppm;
pub mod vcm;
pub mod vertex;
pub mod volpath;
pub mod wavefront;
pub mod whitted;

pub use raycast::Aov;
pub use select::{Capabilities, Integrator};
pub use settings::PathSettings;
pub use whitted::ShadingModel;

/// Counters kept per tile (never shared per ray) and summed at the end.
#[derive(Clone, Copy, Debug, Default)]
pub struct RayStats {
    /// Closest-hit rays (camera and bounce).
    pub rays: u64,
    /// Any-hit shadow rays.
    pub shadow_rays: u64,
}

impl std::ops::AddAssign for RayStats {
    fn add_assign(&mut self, o: RayStats) {
        self.rays += o.rays;
        self.shadow_rays += o.shadow_rays;
    }
}

/// Which integrator renders the image (`--integrator`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum IntegratorKind {
    #[default]
    Path,
    /// The thesis's ray caster: first hit only, shown as the view `aov`.
    Raycast { aov: Aov, shading: ShadingModel },
    /// The thesis's Whitted ray tracer: local shading plus mirror reflection and refraction.
    Whitted { shading: ShadingModel },
    /// Forward path tracing from the lights, splatted onto the film (`lighttracer.rs`).
    LightTracer,
    /// Bidirectional path tracing, every (s, t) strategy weighted by MIS (`bdpt.rs`).
    Bdpt,
    /// Stochastic progressive photon mapping (`sppm.rs`, driven by `render/photon.rs`).
    Sppm,
    /// Metropolis light transport over BDPT's strategies (`mlt.rs`).
    Mlt,
    /// Vertex connection and merging (`vcm.rs`, driven by `render/photon.rs`).
    Vcm,
}

impl IntegratorKind {
    /// Whether the integrator carries sampled wavelengths (`--spectral`): every one but the
    /// thesis's raycast and Whitted modes, whose local shading models are RGB
    /// (docs/DESIGN.md "Spectral rendering"; `render::has_spectral_path` for the resolved one).
    pub fn carries_wavelengths(self) -> bool {
        // Media or not, the resolved integrator carries wavelengths or not alike.
        select::Integrator::resolve(self, false).carries_wavelengths()
    }

    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::Path => "path",
            IntegratorKind::Raycast { .. } => "raycast",
            IntegratorKind::Whitted { .. } => "whitted",
            IntegratorKind::LightTracer => "lighttracer",
            IntegratorKind::Bdpt => "bdpt",
            IntegratorKind::Sppm => "sppm",
            IntegratorKind::Vcm => "vcm",
            IntegratorKind::Mlt => "mlt",
        }
    }

    /// The same mode with the raycast/Whitted options `--aov` and `--shading` applied.
    pub fn with_options(self, aov: Aov, shading: ShadingModel) -> IntegratorKind {
        match self {
            IntegratorKind::Path => IntegratorKind::Path,
            IntegratorKind::Raycast { .. } => IntegratorKind::Raycast { aov, shading },
            IntegratorKind::Whitted { .. } => IntegratorKind::Whitted { shading },
            IntegratorKind::LightTracer => IntegratorKind::LightTracer,
            IntegratorKind::Bdpt => IntegratorKind::Bdpt,
            IntegratorKind::Sppm => IntegratorKind::Sppm,
            IntegratorKind::Vcm => IntegratorKind::Vcm,
            IntegratorKind::Mlt => IntegratorKind::Mlt,
        }
    }
}

impl std::str::FromStr for IntegratorKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "path" => Ok(IntegratorKind::Path),
            "raycast" => Ok(IntegratorKind::Raycast {
                aov: Aov::default(),
                shading: ShadingModel::default(),
            }),
            "whitted" => Ok(IntegratorKind::Whitted {
                shading: ShadingModel::default(),
            }),
            "lighttracer" => Ok(IntegratorKind::LightTracer),
            "bdpt" => Ok(IntegratorKind::Bdpt),
            "sppm" => Ok(IntegratorKind::Sppm),
            "vcm" => Ok(IntegratorKind::Vcm),
            "mlt" => Ok(IntegratorKind::Mlt),
            other => Err(format!(
                "unknown integrator '{other}' (expected path, raycast, whitted, lighttracer, bdpt, sppm, vcm or mlt)"
            )),
        }
    }
}
