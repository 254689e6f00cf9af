//! Integrators: where a light path's life is decided. The path tracer (`path`) is the default and
//! the only unbiased one.

pub mod path;

pub use path::PathSettings;

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
}

impl std::str::FromStr for IntegratorKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "path" => Ok(IntegratorKind::Path),
            other => Err(format!("unknown integrator '{other}' (expected path)")),
        }
    }
}
