//! The thesis's first stage: a ray caster (§5.1.3–5.1.12). One ray per camera sample finds the
//! first hit, which is shown as one of several views (`--aov`):
//!
//! * `shaded` (default): emission plus the local shading of [`super::direct::shade_local`] with the
//!   chosen `--shading` model, ambient term and shadow rays, but no reflection or refraction;
//! * `normals`: the world-space shading normal of the front face mapped to colours, `(n + 1) / 2`;
//! * `barycentric`: the triangle's barycentric coordinates as colour, `(r, g, b) = (u, v, w)` with
//!   Möller–Trumbore's `u, v` and `w = 1 − u − v` (Fig. 5.11–5.12); quads show their `(u, v)`
//!   parameters the same way, spheres and boxes show blue;
//! * `depth`: the distance from the camera along the ray, in scene units (read it from an EXR);
//! * `albedo`: the base colour with textures and vertex colours applied;
//! * `uv`: the first texture-coordinate set as `(u, v, 0)`.
//!
//! Rays that miss show the background lights in `shaded` and black in every other view.

use super::RayStats;
use super::direct::shade_local;
use super::whitted::ShadingModel;
use crate::geometry::Ray;
use crate::math::Vec3;
use crate::sampling::SampleStream;
use crate::world::World;

/// What the ray caster shows (`--aov`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Aov {
    #[default]
    Shaded,
    Normals,
    Barycentric,
    Depth,
    Albedo,
    Uv,
}

impl std::str::FromStr for Aov {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "shaded" => Ok(Aov::Shaded),
            "normals" | "normal" => Ok(Aov::Normals),
            "barycentric" | "barycentrics" => Ok(Aov::Barycentric),
            "depth" => Ok(Aov::Depth),
            "albedo" => Ok(Aov::Albedo),
            "uv" | "uvs" => Ok(Aov::Uv),
            other => Err(format!(
                "unknown view '{other}' (expected shaded, normals, barycentric, depth, albedo or uv)"
            )),
        }
    }
}

impl Aov {
    pub fn name(self) -> &'static str {
        match self {
            Aov::Shaded => "shaded",
            Aov::Normals => "normals",
            Aov::Barycentric => "barycentric",
            Aov::Depth => "depth",
            Aov::Albedo => "albedo",
            Aov::Uv => "uv",
        }
    }
}

/// The value of view `aov` for the camera ray `ray`.
pub fn radiance(
    world: &World,
    ray: &Ray,
    s: &mut SampleStream,
    aov: Aov,
    model: ShadingModel,
    stats: &mut RayStats,
) -> Vec3 {
    stats.rays += 1;
    let Some(isect) = world.intersect_raw(ray) else {
        return match aov {
            Aov::Shaded => world.escaped(ray.d.normalize()),
            _ => Vec3::ZERO,
        };
    };
    let mut hit = world.surface_hit(ray, &isect);
    // Shading and the `normals` view use the normal-mapped shading normal, as the path tracer.
    world.apply_normal_map(&mut hit);
    match aov {
        Aov::Shaded => {
            let wo = -ray.d.normalize();
            world.emitted(&hit, wo) + shade_local(world, &hit, wo, model, s, stats)
        }
        Aov::Normals => (hit.ns + Vec3::ONE) * 0.5,
        Aov::Barycentric => {
            let (u, v) = match hit.prim.kind() {
                crate::geometry::PrimitiveKind::Triangle | crate::geometry::PrimitiveKind::Quad => {
                    (isect.u, isect.v)
                }
                _ => (0.0, 0.0),
            };
            Vec3::new(u, v, 1.0 - u - v)
        }
        Aov::Depth => Vec3::splat(isect.t * ray.d.length()),
        Aov::Albedo => world.base_color(&hit),
        Aov::Uv => Vec3::new(hit.uv[0].x, hit.uv[0].y, 0.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aov_names_round_trip() {
        for a in [
            Aov::Shaded,
            Aov::Normals,
            Aov::Barycentric,
            Aov::Depth,
            Aov::Albedo,
            Aov::Uv,
        ] {
            assert_eq!(a.name().parse::<Aov>().unwrap(), a);
        }
        assert!("wireframe".parse::<Aov>().is_err());
    }
}
