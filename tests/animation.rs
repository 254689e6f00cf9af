//! Animation and motion blur: Khronos animated models posed at several times against an
//! independent reference of the glTF 2.0 sampling rules (scripts/gltf_anim_reference.py, whose
//! output is tests/data/gltf_anim_poses.json), and motion-blurred renders against the average
//! of renders at the shutter's times.

mod common;

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use trayecto::film::Image;
use trayecto::math::{Mat4, Vec3};
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene::animation::{Animation, MovingTransform, RigidMotion};
use trayecto::scene::{Scene, Shape};
use trayecto::world::motion::{TimeOptions, step_time};
use trayecto::world::{World, WorldOptions};

fn shared(rel: &str) -> String {
    format!("{}/../shared/scenes/{rel}", env!("CARGO_MANIFEST_DIR"))
}

/// Every model of the reference, at every time: each mesh object's sampled vertices in world
/// space agree with the script's to 1e-4 (relative to the model's size).
#[test]
fn poses_agree_with_the_spec_reference() {
    let text = std::fs::read_to_string(format!(
        "{}/tests/data/gltf_anim_poses.json",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    let reference: serde_json::Value = serde_json::from_str(&text).unwrap();
    let times: Vec<f64> = reference["times"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t.as_f64().unwrap())
        .collect();
    let models = reference["models"].as_object().unwrap();
    assert_eq!(models.len(), 5);
    for (name, model) in models {
        let scene = trayecto::scene::load(&shared(model["path"].as_str().unwrap())).unwrap();
        assert!(scene.animation.is_some(), "{name}: no animation was read");
        assert!(
            !scene
                .warnings
                .iter()
                .any(|w| w.contains("static pose") || w.contains("not supported")),
            "{name}: {:?}",
            scene.warnings
        );
        for (ti, &t) in times.iter().enumerate() {
            let mut s = scene.clone();
            s.pose(Some(t));
            let objects: Vec<_> = s
                .objects
                .iter()
                .filter_map(|o| match o.shape {
                    Shape::Mesh(m) => Some((m, o.transform)),
                    _ => None,
                })
                .collect();
            let expected = model["poses"][ti].as_array().unwrap();
            assert_eq!(objects.len(), expected.len(), "{name} at {t}: object count");
            let mut checked = 0;
            for ((mesh, transform), e) in objects.iter().zip(expected) {
                let stride = e["stride"].as_u64().unwrap() as usize;
                let positions = &s.meshes[*mesh].positions;
                for (k, v) in e["vertices"].as_array().unwrap().iter().enumerate() {
                    let r: Vec<f64> = v
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|c| c.as_f64().unwrap())
                        .collect();
                    let p = transform.transform_point3(positions[k * stride]);
                    let err = (p.as_dvec3() - glam::DVec3::new(r[0], r[1], r[2])).length();
                    assert!(
                        err < 1e-4 * (1.0 + glam::DVec3::new(r[0], r[1], r[2]).length()),
                        "{name} at t = {t}, node {}, vertex {}: {p} vs {r:?}",
                        e["node"],
                        k * stride
                    );
                    checked += 1;
                }
            }
            assert!(checked > 0);
        }
    }
}

/// The reference is not trivially satisfied: at different times the poses differ (a pose that
/// ignored the animation would pass only if nothing moved).
#[test]
fn the_reference_poses_move() {
    let scene = trayecto::scene::load(&shared("gltf-anim/CesiumMan/glTF/CesiumMan.gltf")).unwrap();
    let at = |t: f64| {
        let mut s = scene.clone();
        s.pose(Some(t));
        s.meshes[0].positions[100]
    };
    assert!((at(0.37) - at(1.0)).length() > 1e-3);
}

fn small(seed: u64, spp: u32) -> RenderSettings {
    RenderSettings {
        width: 24,
        height: 24,
        spp,
        seed,
        threads: Some(2),
        ..Default::default()
    }
}

fn render_with(scene: &Scene, time: TimeOptions, settings: &RenderSettings) -> Image {
    let options = WorldOptions {
        time,
        ..Default::default()
    };
    let world = World::build_posed(scene.clone(), &options).expect("builds");
    render(&world, settings, &NoObserver, &AtomicBool::new(false))
        .expect("renders")
        .image
}

fn mse(a: &Image, b: &Image) -> f64 {
    a.data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (*x - *y).length_squared() as f64)
        .sum::<f64>()
        / a.data.len() as f64
}

/// A motion-blurred render is an unbiased estimate of the average over the shutter's steps:
/// its distance to the average of `--time` renders at the steps is that of two independent
/// blurred renders (noise only), while the still at the opening is far (the motion shows).
fn blur_is_the_average_over_the_shutter(scene: &Scene, shutter: [f64; 2], what: &str) {
    let steps = 4;
    let blur = |seed| {
        render_with(
            scene,
            TimeOptions {
                shutter: Some(shutter),
                steps,
                ..Default::default()
            },
            &small(seed, 256),
        )
    };
    let (a, b) = (blur(1), blur(2));
    let mut average: Option<Image> = None;
    for k in 0..steps {
        let t = step_time(shutter[0], shutter[1], k, steps);
        let img = render_with(
            scene,
            TimeOptions {
                time: Some(t),
                ..Default::default()
            },
            &small(10 + k as u64, 256),
        );
        match average.as_mut() {
            None => average = Some(img),
            Some(acc) => acc
                .data
                .iter_mut()
                .zip(&img.data)
                .for_each(|(x, y)| *x += *y),
        }
    }
    let mut average = average.unwrap();
    average.data.iter_mut().for_each(|p| *p /= steps as f32);
    let still = render_with(
        scene,
        TimeOptions {
            time: Some(shutter[0]),
            ..Default::default()
        },
        &small(3, 256),
    );
    let noise = mse(&a, &b);
    let to_average = mse(&a, &average);
    let to_still = mse(&a, &still);
    eprintln!(
        "{what}: noise {noise:.3e}, to the average {to_average:.3e}, to the still {to_still:.3e}"
    );
    assert!(noise > 0.0);
    assert!(
        to_average < 1.2 * noise,
        "{what}: the blurred render is {to_average:.3e} from the average, two blurred renders {noise:.3e} apart"
    );
    assert!(
        to_still > 3.0 * noise,
        "{what}: the blurred render is as close to the still ({to_still:.3e}) as to another blurred one ({noise:.3e}): nothing moved"
    );
}

#[test]
fn motion_blur_of_a_moving_object() {
    let scene = trayecto::scene::load(&shared("gltf-anim/BoxAnimated/glTF-Binary/BoxAnimated.glb"))
        .unwrap();
    blur_is_the_average_over_the_shutter(&scene, [0.6, 1.6], "BoxAnimated");
}

#[test]
fn motion_blur_of_a_skinned_mesh() {
    let scene =
        trayecto::scene::load(&shared("gltf-anim/CesiumMan/glTF-Binary/CesiumMan.glb")).unwrap();
    blur_is_the_average_over_the_shutter(&scene, [0.2, 0.9], "CesiumMan");
}

#[test]
fn motion_blur_of_a_moving_camera() {
    let mut scene = trayecto::scene::builtin::load("cornell").unwrap();
    let start = scene.cameras[0].camera_to_world;
    let end =
        start * Mat4::from_translation(Vec3::new(0.15, 0.0, 0.0)) * Mat4::from_rotation_y(0.2);
    scene.animation = Some(Arc::new(Animation {
        rigid: vec![RigidMotion::Camera {
            camera: 0,
            motion: MovingTransform {
                times: [0.0, 1.0],
                start,
                end,
            },
        }],
        ..Default::default()
    }));
    blur_is_the_average_over_the_shutter(&scene, [0.0, 1.0], "cornell, moving camera");
}

/// Without a shutter nothing is drawn for time: a still of an animated file at a time is the
/// image of the scene posed there, built as a still.
#[test]
fn a_still_at_a_time_is_the_posed_scene() {
    let scene = trayecto::scene::load(&shared("gltf-anim/BoxAnimated/glTF-Binary/BoxAnimated.glb"))
        .unwrap();
    let via_options = render_with(
        &scene,
        TimeOptions {
            time: Some(1.1),
            ..Default::default()
        },
        &small(0, 4),
    );
    let mut posed = scene.clone();
    posed.pose(Some(1.1));
    let direct = common::render_world(
        &World::build(posed, &WorldOptions::default()).unwrap(),
        &small(0, 4),
    );
    assert_eq!(via_options.data, direct.data);
}
