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

/// Guiding composes with textures (the guide learns from, and the mixture weighs, the textured
/// BSDF at each hit) and with many emitters sampled through the light BVH (NEE's MIS weight uses
/// the mixture's density): the guided renders keep the unguided expectation.
#[test]
fn guided_renders_agree_with_textures_and_many_lights() {
    for (file, what) in [
        (
            "gltf/BoxTextured/glTF-Binary/BoxTextured.glb",
            "textured glTF",
        ),
        (
            "gltf/EmissiveStrengthTest/glTF-Binary/EmissiveStrengthTest.glb",
            "glTF with many emitters",
        ),
    ] {
        let world = world_of(scene_file(file).to_str().unwrap());
        if what.contains("emitters") {
            // Chosen by the light BVH, not by power alone.
            assert_ne!(
                world.lights.sampler_kind(),
                trayecto::light::LightSamplerKind::Power,
                "{what}: {} lights",
                world.lights.lights.len()
            );
        }
        agree(&world, 32, 32, 64, what);
    }
}

/// Guiding composes with the in-loop AOVs the denoiser is guided by: asking for them leaves the
/// guided image the same bit for bit, and the albedo and normal layers (functions of the camera
/// samples' first hits, which guiding does not change) are the unguided render's exactly, for
/// 1 and 2 threads.
#[test]
fn guided_renders_record_the_unguided_aovs() {
    use std::sync::atomic::AtomicBool;
    use trayecto::film::aov::AovKind;
    use trayecto::render::{NoObserver, RangeStart, aov_layers, render_range_aovs};
    let world = world_of("cornell");
    let (w, h, spp) = (20, 16, 16);
    let run = |guiding: bool, aovs: bool, threads: usize| {
        let mut s = settings(w, h, spp, 3, guiding);
        s.threads = Some(threads);
        let start = RangeStart {
            samples: 0..spp,
            resume: None,
        };
        render_range_aovs(
            &world,
            &s,
            start,
            aovs,
            &NoObserver,
            &AtomicBool::new(false),
        )
        .expect("renders")
    };
    let layers = |r: &trayecto::render::FilmRender| {
        let acc = r.aovs.as_ref().expect("the path loop recorded the AOVs");
        aov_layers(&[AovKind::Albedo, AovKind::Normal], w, h, acc)
            .into_iter()
            .map(|l| l.data.iter().map(|v| v.to_bits()).collect::<Vec<u32>>())
            .collect::<Vec<_>>()
    };
    let guided = run(true, true, 2);
    assert!(
        guided.film.to_image().data == run(true, false, 2).film.to_image().data,
        "recording the AOVs changed the guided image"
    );
    let plain = run(false, true, 2);
    assert!(guided.film.to_image().data != plain.film.to_image().data);
    assert!(
        layers(&guided) == layers(&plain),
        "guiding changed the AOVs"
    );
    let one = run(true, true, 1);
    assert!(one.film.to_image().data == guided.film.to_image().data);
    assert!(layers(&one) == layers(&guided));
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

/// The training budget: doubling iterations until the first whose records fill the budget of
/// one (at least four iterations), at most a quarter of the samples (the last takes the rest). A time-limited render (whose sample count is not known in advance) ends its training
/// by time instead, then samples with the last guide until the time is up: every pixel holds
/// the same number of samples, more than the training took, and the image estimates the
/// unguided one.
#[test]
fn guided_training_ends_by_records_samples_or_time() {
    use std::sync::atomic::AtomicBool;
    use trayecto::render::{
        GUIDE_RECORD_BUDGET, RangeStart, TIME_LIMIT_SPP, guide_training_passes, render_range,
    };
    assert_eq!(
        guide_training_passes(512, 96 * 72),
        vec![
            (0, 1),
            (1, 3),
            (3, 7),
            (7, 15),
            (15, 31),
            (31, 63),
            (63, 128)
        ]
    );
    assert_eq!(guide_training_passes(2, 96 * 72), vec![(0, 1)]);
    // Until the first iteration whose records fill the budget (here of 32 samples per pixel),
    // but never fewer than four iterations.
    let pixels = GUIDE_RECORD_BUDGET / 4 / 32;
    assert_eq!(
        guide_training_passes(4096, pixels),
        vec![(0, 1), (1, 3), (3, 7), (7, 15), (15, 31), (31, 63)]
    );
    assert_eq!(
        guide_training_passes(4096, 1280 * 720),
        vec![(0, 1), (1, 3), (3, 7), (7, 15)]
    );
    let world = world_of("cornell");
    let (w, h) = (16, 12);
    let mut s = settings(w, h, TIME_LIMIT_SPP, 5, true);
    let limit = 1.5;
    s.time_limit = Some(limit);
    let start = RangeStart {
        samples: 0..TIME_LIMIT_SPP,
        resume: None,
    };
    /// The samples per pixel after each committed pass.
    struct Passes(std::sync::Mutex<Vec<u32>>);
    impl trayecto::render::RenderObserver for Passes {
        fn pass_done(&self, _: &trayecto::film::Film, done: u32, _: u32) {
            self.0.lock().unwrap().push(done);
        }
    }
    let passes = Passes(Default::default());
    let t0 = std::time::Instant::now();
    let r = render_range(&world, &s, start, &passes, &AtomicBool::new(false)).expect("renders");
    let took = t0.elapsed().as_secs_f64();
    assert!(!r.cancelled && r.stopped_early);
    let counts = r.film.counts();
    assert!(counts.iter().all(|&n| n == r.done), "{:?}", &counts[..4]);
    assert!(took < limit + 1.0, "a {limit}-second render took {took} s");
    // The training iterations double (1, 2, 4, … samples); the passes after them start again
    // from one sample. Training ended where the passes first shrink, before the time did (a
    // training that ran until the time limit, as its sample budget of a quarter of
    // `TIME_LIMIT_SPP` would, has no such place).
    let done = passes.0.into_inner().unwrap();
    let step: Vec<u32> = std::iter::once(done[0])
        .chain(done.windows(2).map(|p| p[1] - p[0]))
        .collect();
    let trained = (1..step.len())
        .find(|&i| step[i] < step[i - 1])
        .map(|i| done[i - 1])
        .unwrap_or_else(|| panic!("the training never ended: passes {done:?}"));
    assert!(trained < r.done, "passes {done:?}");
    // Unbiased: the time-limited guided image estimates the unguided one.
    let plain = render_world(&world, &settings(w, h, 256, 9, false));
    let guided = r.film.to_image();
    assert_same_expectation(&guided, &plain, "time-limited guided Cornell box");
}
