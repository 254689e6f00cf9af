//! A tiny render of the FBX Cornell box: the ceiling is lit by the light whose material is named
//! `emissive_ceiling_light` (thesis convention), seen directly at the top centre of the image.

mod common;

use common::shared_scene;
use std::sync::atomic::AtomicBool;
use trayecto::integrator::PathSettings;
use trayecto::math::Vec3;
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene;
use trayecto::world::{World, WorldOptions};

#[test]
fn emissive_by_name_light_lights_the_box() {
    let p = shared_scene("fbx/cornell_seed_conventions.fbx");
    let s = scene::load(p.to_str().unwrap()).unwrap();
    let world = World::build(
        s.clone(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    // The light quad is two emissive triangles, and it is the only light (no default one).
    assert_eq!(world.area_light_count(), 2);
    assert_eq!(world.lights.lights.len(), 2);
    let settings = RenderSettings {
        width: 64,
        height: 64,
        spp: 4,
        seed: 1,
        path: PathSettings {
            max_depth: 3,
            ..Default::default()
        },
        ..Default::default()
    };
    let img = render(&world, &settings, &NoObserver, &AtomicBool::new(false))
        .unwrap()
        .image;
    // Pixel (32, 9) sees the light directly: its emission, (0.92, 0.70, 0.34) × 5, plus the little
    // light the quad's own diffuse face reflects from the box below.
    let e = Vec3::new(0.92, 0.70, 0.34) * 5.0;
    let l = img.get(32, 9);
    assert!(
        l.cmpge(e * 0.999).all() && l.cmple(e * 1.1).all(),
        "light pixel {l}, emission {e}"
    );
    // The floor left of the boxes is lit (not black), and the image has no NaNs.
    let mut floor = Vec3::ZERO;
    for y in 56..62 {
        for x in 12..24 {
            floor += img.get(x, y) / 72.0;
        }
    }
    assert!(floor.min_element() > 0.01, "floor {floor}");
    assert!(img.data.iter().all(|p| p.is_finite()));
}
