//! Built-in scenes. `cornell` is geometrically identical to Mitsuba 3's `mitsuba.cornell_box()`
//! (docs/DESIGN.md §3), so it can be compared with a Mitsuba reference image.

use super::{CameraDesc, Scene, SceneError, Shape};
use crate::material::Material;
use crate::math::{Mat4, Vec3};

pub const NAMES: &[&str] = &["cornell"];

pub fn load(name: &str) -> Result<Scene, SceneError> {
    match name {
        "cornell" => Ok(cornell()),
        other => Err(SceneError::UnknownBuiltin(other.to_string())),
    }
}

/// A 4×4 transform from three row-major rows (the last row is 0 0 0 1).
fn rows(r: [[f32; 4]; 3]) -> Mat4 {
    Mat4::from_cols_array(&[
        r[0][0], r[1][0], r[2][0], 0.0, //
        r[0][1], r[1][1], r[2][1], 0.0, //
        r[0][2], r[1][2], r[2][2], 0.0, //
        r[0][3], r[1][3], r[2][3], 1.0,
    ])
}

pub fn cornell() -> Scene {
    let mut s = Scene {
        name: "cornell".into(),
        ..Default::default()
    };
    let white = s.add_material(Material::diffuse(
        "white",
        Vec3::new(0.885809, 0.698859, 0.666422),
    ));
    let red = s.add_material(Material::diffuse(
        "red",
        Vec3::new(0.570068, 0.0430135, 0.0443706),
    ));
    let green = s.add_material(Material::diffuse(
        "green",
        Vec3::new(0.105421, 0.37798, 0.076425),
    ));
    let mut light_mat = Material::diffuse("light", Vec3::new(0.885809, 0.698859, 0.666422));
    light_mat.emissive = Vec3::new(18.387, 13.9873, 6.75357);
    let light = s.add_material(light_mat);

    let quad = |corner: [f32; 3], e1: [f32; 3], e2: [f32; 3]| Shape::Quad {
        corner: Vec3::from(corner),
        e1: Vec3::from(e1),
        e2: Vec3::from(e2),
    };
    let id = Mat4::IDENTITY;
    // Each wall's front face (e1 × e2) points into the box.
    s.add_object(
        "floor",
        quad([-1.0, -1.0, -1.0], [0.0, 0.0, 2.0], [2.0, 0.0, 0.0]),
        id,
        white,
    );
    s.add_object(
        "ceiling",
        quad([-1.0, 1.0, -1.0], [2.0, 0.0, 0.0], [0.0, 0.0, 2.0]),
        id,
        white,
    );
    s.add_object(
        "back",
        quad([-1.0, -1.0, -1.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]),
        id,
        white,
    );
    s.add_object(
        "red-wall",
        quad([-1.0, -1.0, -1.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]),
        id,
        red,
    );
    s.add_object(
        "green-wall",
        quad([1.0, -1.0, -1.0], [0.0, 0.0, 2.0], [0.0, 2.0, 0.0]),
        id,
        green,
    );
    // The 0.46 × 0.38 light centred on (0, 0.99, 0.01), facing down.
    s.add_object(
        "light",
        quad(
            [-0.23, 0.99, 0.01 - 0.19],
            [0.46, 0.0, 0.0],
            [0.0, 0.0, 0.38],
        ),
        id,
        light,
    );
    let cube = Shape::Cuboid {
        min: Vec3::splat(-1.0),
        max: Vec3::splat(1.0),
    };
    s.add_object(
        "small-box",
        cube.clone(),
        rows([
            [0.286891, 0.0, -0.0877115, 0.335],
            [0.0, 0.3, 0.0, -0.7],
            [0.0877115, 0.0, 0.286891, 0.38],
        ]),
        white,
    );
    s.add_object(
        "large-box",
        cube,
        rows([
            [0.28491, 0.0, 0.0939491, -0.33],
            [0.0, 0.61, 0.0, -0.4],
            [-0.0939491, 0.0, 0.28491, -0.28],
        ]),
        white,
    );
    s.cameras.push(CameraDesc::look_at(
        "camera",
        Vec3::new(0.0, 0.0, 3.9),
        Vec3::ZERO,
        Vec3::Y,
        39.3077,
    ));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cornell_is_valid_and_matches_spec() {
        let s = cornell();
        s.validate().unwrap();
        assert_eq!(s.objects.len(), 8);
        let m = rows([
            [1.0, 2.0, 3.0, 4.0],
            [5.0, 6.0, 7.0, 8.0],
            [9.0, 10.0, 11.0, 12.0],
        ]);
        assert_eq!(m.transform_point3(Vec3::ZERO), Vec3::new(4.0, 8.0, 12.0));
        assert_eq!(m.transform_vector3(Vec3::X), Vec3::new(1.0, 5.0, 9.0));
        // Walls' front faces point inward (towards the origin).
        for o in &s.objects {
            if let Shape::Quad { corner, e1, e2 } = &o.shape {
                let c = *corner + (*e1 + *e2) * 0.5;
                assert!(e1.cross(*e2).dot(-c) > 0.0, "{}", o.name);
            }
        }
    }
}
