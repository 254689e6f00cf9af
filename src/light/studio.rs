//! The studio environment: the default light of scenes that bring none (docs/DESIGN.md,
//! "The default light").
//!
//! A uniform white sky lights every point of a convex model the same way: a white model on a
//! white background comes out as a flat silhouette with no form. Product viewers (the Khronos
//! glTF sample viewer's neutral studio IBL, Blender's studio MatCap lights, three.js'
//! `RoomEnvironment`) light from a large soft *key* area above and in front, a dimmer *fill*
//! from the other side, a *rim* from behind for the silhouette, and a darker ground, so that
//! shading shows the shape while no part is black.
//!
//! This is that, as a small equirectangular map computed from a formula (no file, the same
//! texels every run) and handed to [`EnvMap::from_texels`]: the existing environment light
//! samples it by importance (its bright key and rim get most light samples) and MIS combines
//! it with BSDF sampling, as any environment map.
//!
//! The map is oriented to the camera: "up" is the picture's up, "front" is toward the viewer,
//! so the key comes from the viewer's upper left whatever way the model's file is oriented
//! (+y or +z up) and whichever side the automatic camera faces. It is fixed in the world once
//! built (moving the view later turns the model in its light, as in a viewer).

use super::envmap::EnvMap;
use crate::math::{Mat3, Mat4, Vec2, Vec3};

/// Texels across (the map is twice as wide as high). The lights are 20–50° wide, so 2.8° texels
/// resolve them with smooth edges; 32k texels build in well under a millisecond.
pub const STUDIO_WIDTH: u32 = 128;

/// Radiance of the studio in its own frame: +y is up, +z toward the viewer, +x to the right.
/// Grey, so a white model stays neutral; the numbers are chosen for contrast and measured in
/// docs/DESIGN.md ("The default light"): a white Lambertian surface facing the key has
/// radiance ≈ 1.2, one facing away ≈ 0.45, the background behind the model ≈ 0.5.
pub fn studio_radiance(d: Vec3) -> f32 {
    // A soft-edged round lamp: 1 inside `inner` degrees of `centre`, 0 beyond `outer`.
    let lamp = |centre: Vec3, inner: f32, outer: f32| {
        let c = d.dot(centre.normalize());
        let (ci, co) = (inner.to_radians().cos(), outer.to_radians().cos());
        let t = ((c - co) / (ci - co)).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    };
    // Walls: brighter toward the top; the floor is darker, with a soft horizon (a hard edge
    // would alias in glossy reflections).
    let sky = 0.45 + 0.3 * d.y.max(0.0);
    let floor = 0.15;
    let t = ((d.y + 0.15) / 0.2).clamp(0.0, 1.0);
    let walls = floor + (sky - floor) * t * t * (3.0 - 2.0 * t);
    let key = 4.0 * lamp(Vec3::new(-0.5, 0.75, 0.6), 15.0, 35.0);
    let fill = 0.8 * lamp(Vec3::new(0.85, 0.2, 0.5), 20.0, 50.0);
    let rim = 2.0 * lamp(Vec3::new(0.4, 0.5, -0.75), 8.0, 22.0);
    walls + key + fill + rim
}

/// The studio map turned to the camera `camera_to_world` (camera space: -z forward, +y up).
pub fn studio_environment(camera_to_world: &Mat4) -> EnvMap {
    let (w, h) = (STUDIO_WIDTH, STUDIO_WIDTH / 2);
    let texels = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let uv = Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            Vec3::splat(studio_radiance(EnvMap::uv_to_dir(uv)))
        })
        .collect();
    EnvMap::from_texels(w, h, texels, Vec3::ONE, studio_frame(camera_to_world))
}

/// A rotation from the studio's frame to the world: +z toward the viewer (against the camera's
/// forward), +y the camera's up made orthogonal to it. Falls back to the identity for a
/// degenerate camera matrix.
fn studio_frame(camera_to_world: &Mat4) -> Mat3 {
    let back = camera_to_world
        .transform_vector3(Vec3::Z)
        .normalize_or_zero();
    let up = camera_to_world.transform_vector3(Vec3::Y);
    let up = (up - back * up.dot(back)).normalize_or_zero();
    if back == Vec3::ZERO || up == Vec3::ZERO {
        return Mat3::IDENTITY;
    }
    Mat3::from_cols(up.cross(back), up, back)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_key_is_above_in_front_and_the_floor_darker() {
        let key = studio_radiance(Vec3::new(-0.5, 0.75, 0.6).normalize());
        let behind = studio_radiance(Vec3::new(0.0, 0.0, -1.0));
        let floor = studio_radiance(-Vec3::Y);
        assert!(
            key > 4.0 && behind < 0.6 && floor < 0.2,
            "{key} {behind} {floor}"
        );
        // Nowhere black: the shadow side of a model keeps some light.
        let mut min = f32::MAX;
        for i in 0..64 {
            for j in 0..32 {
                let uv = Vec2::new((i as f32 + 0.5) / 64.0, (j as f32 + 0.5) / 32.0);
                min = min.min(studio_radiance(EnvMap::uv_to_dir(uv)));
            }
        }
        assert!(min >= 0.15, "{min}");
    }

    #[test]
    fn the_map_turns_with_the_camera() {
        // A camera looking down -x with +z up (a pbrt-style file): the key must be above (+z)
        // and toward the camera (+x).
        let cam = Mat4::look_at_rh(Vec3::new(5.0, 0.0, 0.0), Vec3::ZERO, Vec3::Z).inverse();
        let map = studio_environment(&cam);
        let up_front = map.eval(Vec3::new(0.6, -0.5, 0.75).normalize());
        let down_back = map.eval(Vec3::new(-0.6, 0.0, -0.8).normalize());
        assert!(
            up_front.x > 3.0 && down_back.x < 0.2,
            "{up_front} {down_back}"
        );
    }
}
