//! The camera: pinhole or thin lens (PBRT §5.2), generating primary rays through the film.
//! Film coordinates are in pixels, (0, 0) at the top-left corner, x to the right, y down.

use crate::geometry::Ray;
use crate::math::{Mat4, Vec2, Vec3};
use crate::sampling::warp::concentric_disk;
use crate::scene::CameraDesc;

#[derive(Clone, Debug)]
pub struct Camera {
    pub camera_to_world: Mat4,
    pub width: u32,
    pub height: u32,
    /// tan(vfov / 2).
    tan_half_v: f32,
    aspect: f32,
    pub aperture_radius: f32,
    pub focus_distance: f32,
}

impl Camera {
    pub fn new(desc: &CameraDesc, width: u32, height: u32) -> Camera {
        Camera {
            camera_to_world: desc.camera_to_world,
            width,
            height,
            tan_half_v: desc.fitted_tan_half_v(width as f32 / height as f32),
            aspect: width as f32 / height as f32,
            aperture_radius: desc.aperture_radius,
            focus_distance: desc.focus_distance,
        }
    }

    /// Camera-space direction (not normalised) through film point `film` (in pixels).
    #[inline]
    fn direction(&self, film: Vec2) -> Vec3 {
        let ndc_x = 2.0 * film.x / self.width as f32 - 1.0;
        let ndc_y = 1.0 - 2.0 * film.y / self.height as f32;
        Vec3::new(
            ndc_x * self.tan_half_v * self.aspect,
            ndc_y * self.tan_half_v,
            -1.0,
        )
    }

    /// The primary ray through `film`; `lens` in [0,1)² picks the point on the aperture.
    #[inline]
    pub fn generate_ray(&self, film: Vec2, lens: Vec2) -> Ray {
        let d = self.direction(film);
        let (o_cam, d_cam) = if self.aperture_radius > 0.0 {
            // Thin lens: all rays through the film point converge at the plane of focus.
            let p_lens = concentric_disk(lens) * self.aperture_radius;
            let focus = d * self.focus_distance; // d.z = −1, so this point is at depth focus_distance
            let o = Vec3::new(p_lens.x, p_lens.y, 0.0);
            (o, focus - o)
        } else {
            (Vec3::ZERO, d)
        };
        let o = self.camera_to_world.transform_point3(o_cam);
        let dir = self.camera_to_world.transform_vector3(d_cam).normalize();
        Ray::new(o, dir)
    }

    /// Projects a world point to film coordinates, if it is in front of the camera (for tests).
    pub fn project(&self, p: Vec3) -> Option<Vec2> {
        let pc = self.camera_to_world.inverse().transform_point3(p);
        if pc.z >= 0.0 {
            return None;
        }
        let x = pc.x / -pc.z / (self.tan_half_v * self.aspect);
        let y = pc.y / -pc.z / self.tan_half_v;
        Some(Vec2::new(
            (x + 1.0) * 0.5 * self.width as f32,
            (1.0 - y) * 0.5 * self.height as f32,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_target_and_corners_match_fov() {
        let desc = CameraDesc::look_at("c", Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 90.0);
        let cam = Camera::new(&desc, 200, 100);
        let r = cam.generate_ray(Vec2::new(100.0, 50.0), Vec2::ZERO);
        assert!((r.d - (-Vec3::Z)).length() < 1e-6);
        // Top edge centre: 45° up.
        let top = cam.generate_ray(Vec2::new(100.0, 0.0), Vec2::ZERO);
        assert!((top.d.y - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-5);
        // Right edge: aspect 2 → tan = 2.
        let right = cam.generate_ray(Vec2::new(200.0, 50.0), Vec2::ZERO);
        assert!((right.d.x / -right.d.z - 2.0).abs() < 1e-5);
        let p = cam.project(Vec3::new(1.0, 0.5, 0.0)).unwrap();
        let back = cam.generate_ray(p, Vec2::ZERO);
        let expected = (Vec3::new(1.0, 0.5, 0.0) - Vec3::new(0.0, 0.0, 5.0)).normalize();
        assert!((back.d - expected).length() < 1e-5);
    }

    #[test]
    fn thin_lens_rays_converge_on_focus_plane() {
        let mut desc = CameraDesc::look_at("c", Vec3::ZERO, -Vec3::Z, Vec3::Y, 40.0);
        desc.aperture_radius = 0.5;
        desc.focus_distance = 10.0;
        let cam = Camera::new(&desc, 64, 64);
        let film = Vec2::new(20.0, 40.0);
        let a = cam.generate_ray(film, Vec2::new(0.1, 0.9));
        let b = cam.generate_ray(film, Vec2::new(0.8, 0.3));
        let pa = a.at(10.0 / -a.d.z);
        let pb = b.at(10.0 / -b.d.z);
        assert!((pa - pb).length() < 1e-4, "{pa} vs {pb}");
        assert!((a.o - b.o).length() > 0.01);
    }
}
