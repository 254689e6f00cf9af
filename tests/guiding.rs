//! Path guiding (`RenderSettings::guiding`, docs/DESIGN.md "Path guiding"): the guided estimate
//! has the unguided one's expectation (on the Cornell box, a glTF scene, pbrt's veach-mis and a
//! hard-indirect gap room, and a fog scene through the volumetric path tracer), and the image
//! does not depend on the thread count.

mod common;
use common::*;
use trayecto::film::Image;
use trayecto::render::RenderSettings;
use trayecto::world::{World, WorldOptions};

fn world_of(spec: &str) -> World {
    let scene = trayecto::scene::load(spec).expect("scene loads");
    World::build(
        scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .expect("scene builds")
}

fn settings(w: u32, h: u32, spp: u32, seed: u64, guiding: bool) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        spp,
        seed,
        threads: Some(2),
        guiding,
        ..Default::default()
    }
}

/// Luminance per pixel.
fn lum(img: &Image) -> Vec<f64> {
    img.data
        .iter()
        .map(|p| (0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z) as f64)
        .collect()
}

/// The guided and unguided renders estimate the same image: over the whole image and over each
/// block of 8 × 8 pixels, the mean of the per-pixel differences is within 4.5 standard errors
/// of zero (the differences of two independent estimates of a pixel have mean zero, so their
/// spread within a block gives the standard error).
fn assert_same_expectation(a: &Image, b: &Image, what: &str) {
    let (da, db) = (lum(a), lum(b));
    let w = a.width as usize;
    let h = a.height as usize;
    let z = |idx: &mut dyn Iterator<Item = usize>| {
        let d: Vec<f64> = idx.map(|i| da[i] - db[i]).collect();
        let n = d.len() as f64;
        let m = d.iter().sum::<f64>() / n;
        let var = d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
        let scale = da.iter().chain(&db).sum::<f64>() / (2.0 * da.len() as f64);
        // A block of identical pixels (both black) has no spread: compare with a floor.
        m.abs() / (var / n).sqrt().max(1e-4 * scale)
    };
    let all = z(&mut (0..w * h));
    assert!(
        all < 4.5,
        "{what}: image means differ by {all:.2} standard errors"
    );
    for by in (0..h).step_by(8) {
        for bx in (0..w).step_by(8) {
            let mut idx =
                (by..(by + 8).min(h)).flat_map(|y| (bx..(bx + 8).min(w)).map(move |x| y * w + x));
            let zb = z(&mut idx);
            assert!(
                zb < 4.5,
                "{what}: block at ({bx}, {by}) differs by {zb:.2} standard errors"
            );
        }
    }
}

fn agree(world: &World, w: u32, h: u32, spp: u32, what: &str) {
    let plain = render_world(world, &settings(w, h, spp, 1, false));
    let guided = render_world(world, &settings(w, h, spp, 2, true));
    assert_same_expectation(&guided, &plain, what);
}

#[test]
fn guided_renders_agree_with_unguided() {
    agree(&world_of("cornell"), 32, 32, 64, "cornell");
    agree(
        &world_of(scene_file("pbrt/veach-mis/scene-v4.pbrt").to_str().unwrap()),
        48,
        27,
        32,
        "veach-mis",
    );
    agree(
        &world_of(
            scene_file(
                "gltf/MetalRoughSpheresNoTextures/glTF-Binary/MetalRoughSpheresNoTextures.glb",
            )
            .to_str()
            .unwrap(),
        ),
        32,
        32,
        32,
        "glTF MetalRoughSpheresNoTextures",
    );
    let gap = repo_dir().join("scenes/guiding/gap-room.pbrt");
    agree(&world_of(gap.to_str().unwrap()), 32, 24, 64, "gap room");
}

/// The guide is learned from records merged in tile order: the image is the same bit for bit
/// for 1 and 2 threads, also with adaptive sampling and with the in-loop AOVs.
#[test]
fn guided_images_do_not_depend_on_thread_count() {
    let world = world_of("cornell");
    let mut s = settings(24, 20, 32, 5, true);
    for noise in [None, Some(0.05)] {
        s.noise_threshold = noise;
        s.threads = Some(1);
        let one = render_world(&world, &s);
        s.threads = Some(2);
        let two = render_world(&world, &s);
        let bits = |i: &Image| -> Vec<u32> {
            i.data
                .iter()
                .flat_map(|p| p.to_array().map(f32::to_bits))
                .collect()
        };
        assert!(bits(&one) == bits(&two), "adaptive {noise:?}");
        // And guiding changed the samples (the guide was used).
        let plain = render_world(
            &world,
            &RenderSettings {
                guiding: false,
                ..s.clone()
            },
        );
        assert!(bits(&plain) != bits(&two));
    }
}

/// Volume path guiding: in a fog scene (the volumetric path tracer, medium vertices sampling
/// the phase–guide mixture) the guided render has the unguided expectation, is the same bit for
/// bit for 1 and 2 threads, and differs from the unguided render (the guide was used). With
/// the guide trained before the render, the medium tree guides enough samples that a mixture
/// weighed by the phase function's density alone (β unchanged) fails here (6.4 standard errors).
#[test]
fn guided_media_agree_with_unguided() {
    let world = world_of(
        repo_dir()
            .join("scenes/pbrt/media/fog_cornell.pbrt")
            .to_str()
            .unwrap(),
    );
    let plain = render_world(&world, &settings(24, 24, 64, 1, false));
    let mut s = settings(24, 24, 64, 2, true);
    let guided = render_world(&world, &s);
    assert_same_expectation(&guided, &plain, "fog");
    s.threads = Some(1);
    let one = render_world(&world, &s);
    assert!(one.data == guided.data, "1 and 2 threads differ");
    s.guiding = false;
    assert!(render_world(&world, &s).data != guided.data);
}

/// The training iterations are the render's own first samples, kept in the image: every pixel
/// of a guided film holds exactly `spp` samples (a training sample counted twice, or dropped,
/// changes the count), and a render split inside the training (each part re-traces the
/// training samples it does not own, to learn the same guide, and keeps its own samples only),
/// or resumed from such a part, is the whole render bit for bit, also with 1 thread.
#[test]
fn guided_training_samples_are_counted_once_whatever_the_split() {
    use std::sync::atomic::AtomicBool;
    use trayecto::render::{NoObserver, RangeStart, guide_training_passes, render_range};
    let world = world_of("cornell");
    let (w, h, spp) = (16, 12, 16);
    // The training takes samples 0..4 here (spp/4), in iterations 0..1 and 1..4.
    assert_eq!(
        guide_training_passes(spp, (w * h) as u64),
        vec![(0, 1), (1, 4)]
    );
    let film = |s: &RenderSettings, samples: std::ops::Range<u32>, resume| {
        let start = RangeStart { samples, resume };
        render_range(&world, s, start, &NoObserver, &AtomicBool::new(false))
            .expect("renders")
            .film
    };
    let s = settings(w, h, spp, 3, true);
    let whole = film(&s, 0..spp, None);
    assert!(
        whole.counts().iter().all(|&n| n == spp),
        "{:?}",
        whole.counts()
    );
    // Guided: the image differs from the unguided one.
    let plain = film(&settings(w, h, spp, 3, false), 0..spp, None);
    assert!(plain.raw() != whole.raw());
    // Split inside the second training iteration.
    let mut one = s.clone();
    one.threads = Some(1);
    let head = film(&one, 0..2, None);
    let mut merged = head.clone();
    merged
        .add_film(&film(&s, 2..spp, None))
        .expect("parts merge");
    assert!(merged.counts().iter().all(|&n| n == spp));
    assert!(merged.raw() == whole.raw(), "split at 2 differs");
    // A part inside the training, and a resume from the first part.
    let mut parts = film(&s, 0..1, None);
    for r in [1..3, 3..4, 4..9, 9..spp] {
        parts.add_film(&film(&one, r, None)).expect("parts merge");
    }
    assert!(parts.raw() == whole.raw(), "split at 1, 3, 9 differs");
    let resumed = film(&s, 0..spp, Some((head, 2)));
    assert!(resumed.raw() == whole.raw(), "resumed from 2 differs");
}
