//! The settings of the path tracers (`path.rs`, `volpath.rs`) and of the direct lighting they
//! share (`direct.rs`): depth, Russian roulette, NEE and MIS, first-hit splitting and the
//! camera's footprint. Below all three, so that none of them imports another for it.

use crate::light::EnvPdf;

#[derive(Clone, Copy, Debug)]
pub struct PathSettings {
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Russian roulette keeps a path with probability min(1, rr_scale · max β · η²), so paths
    /// whose throughput is above 1/rr_scale always continue. PBRT-v4's q = max β (scale 1, §14.1.2)
    /// is calibrated for a pixel as bright as the light arriving at the path's vertex; a pixel is
    /// that light times the albedo of the surface the camera sees, so scale 1 cuts paths whose
    /// contribution still matters. On the Cornell box it added 60 % to the error of uncut paths
    /// (64 spp relMSE 0.00378 against 0.00235); scales 2–4 give the best error per ray traced
    /// (scale 3: 0.00252 at 6.5 rays per sample instead of 0.00378 at 5.5, 26 % more efficient),
    /// and the directly lit Veach scene does not change. Measured by `bench/rr_efficiency.py`.
    pub rr_scale: f32,
    pub nee: bool,
    pub mis: bool,
    /// Continuation paths split at the first hit (the thesis's "rayos secundarios").
    pub secondary: u32,
    /// The camera's pixel footprint for filtered texture lookups; set by the renderer when
    /// the world was built with `--texture-filter trilinear`, off (`Default`) otherwise.
    pub footprint: crate::camera::Footprint,
}

impl Default for PathSettings {
    fn default() -> Self {
        PathSettings {
            max_depth: 64,
            rr_depth: 3,
            rr_scale: 3.0,
            nee: true,
            mis: true,
            secondary: 1,
            footprint: Default::default(),
        }
    }
}

impl PathSettings {
    /// The environment-map density next-event estimation draws from, and that BSDF-sampled
    /// escapes weigh their MIS against: the MIS-compensated one when light samples are combined
    /// with BSDF sampling by MIS (which then finds the directions it leaves out, with weight 1),
    /// the full one when light samples must reach every direction on their own (MIS off; with
    /// NEE off no light is sampled and the choice does not matter).
    #[inline]
    pub fn env_pdf(&self) -> EnvPdf {
        if self.nee && self.mis {
            EnvPdf::Compensated
        } else {
            EnvPdf::Full
        }
    }
}
