//! The light tracer (docs/DESIGN.md, integrators) against the Mitsuba 3 references the path
//! tracer is held to, and the splat film's determinism: the same image for any thread count, and
//! a frame split into sample ranges or resumed adds up to the single run bit for bit.

mod common;
use common::*;
use std::sync::atomic::AtomicBool;
use trayecto::film::Image;
use trayecto::film::output::read_exr;
use trayecto::integrator::{IntegratorKind, PathSettings};
use trayecto::math::Vec3;
use trayecto::render::{NoObserver, RangeStart, RenderSettings, render_range};
use trayecto::sampling::SamplerKind;
use trayecto::scene::builtin;
use trayecto::world::World;

fn lt(width: u32, height: u32, spp: u32, max_depth: u32) -> RenderSettings {
    RenderSettings {
        width,
        height,
        spp,
        seed: 5,
        sampler: SamplerKind::Stratified,
        integrator: IntegratorKind::LightTracer,
        path: PathSettings {
            max_depth,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// The Cornell box (area light, diffuse walls) lit by light paths alone: the image means match
/// Mitsuba's within 2 % and its 8 × 8 block means within 5 % RMS, for full global illumination
/// and for direct lighting (depth 1, against the direct-only reference). The error falls with
/// samples, so a bias of the size of the noise would fail.
#[test]
fn light_tracer_matches_mitsuba_on_the_cornell_box() {
    let scene = builtin::cornell();
    for (depth, file) in [(1024, "cornell_128.exr"), (1, "cornell_128_direct.exr")] {
        let reference = read_exr(&repo_dir().join("tests/references").join(file)).unwrap();
        let low = render_scene(&scene, &lt(128, 128, 1, depth));
        let high = render_scene(&scene, &lt(128, 128, 16, depth));
        assert_means_close(&high, &reference, 0.02, &format!("light tracer {file}"));
        let (e_low, e_high) = (
            block_error(&low, &reference),
            block_error(&high, &reference),
        );
        assert!(
            e_high < 0.05 && e_high < e_low / 2.5,
            "{file}: block error {e_low} at 1 spp, {e_high} at 16 spp"
        );
    }
}

/// The same frame rendered with 1 and 3 threads, in one range and in two ranges added together,
/// and resumed from a checkpoint of its first passes: every film is the same, bit for bit.
#[test]
fn light_tracer_film_is_a_function_of_seed_and_settings() {
    let world = World::build(builtin::cornell(), &Default::default()).unwrap();
    let base = RenderSettings {
        threads: Some(1),
        // A Gaussian filter: splats reach several pixels.
        filter: trayecto::film::filter::Filter::new(trayecto::film::filter::FilterKind::Gaussian),
        ..lt(24, 20, 5, 6)
    };
    let cancel = AtomicBool::new(false);
    let range = |s: &RenderSettings, samples: std::ops::Range<u32>, resume| {
        render_range(
            &world,
            s,
            RangeStart { samples, resume },
            &NoObserver,
            &cancel,
        )
        .unwrap()
    };
    let one = range(&base, 0..5, None).film;
    assert!(one.to_image().mean().max_element() > 0.0);
    let three = range(
        &RenderSettings {
            threads: Some(3),
            ..base.clone()
        },
        0..5,
        None,
    )
    .film;
    assert_eq!(one, three);
    let mut split = range(&base, 0..2, None).film;
    split.add_film(&range(&base, 2..5, None).film).unwrap();
    assert_eq!(one, split);
    let head = range(&base, 0..2, None).film;
    let resumed = range(&base, 0..5, Some((head, 2))).film;
    assert_eq!(one, resumed);
}

/// The Cornell box with its light over most of the ceiling, dimmed to keep the image's level.
fn cornell_wide_light() -> trayecto::scene::Scene {
    let mut scene = builtin::cornell();
    let light = scene
        .objects
        .iter_mut()
        .find(|o| o.name == "light")
        .unwrap();
    light.shape = trayecto::scene::Shape::Quad {
        corner: Vec3::new(-0.8, 0.99, -0.8),
        e1: Vec3::new(1.6, 0.0, 0.0),
        e2: Vec3::new(0.0, 0.0, 1.6),
    };
    for m in &mut scene.materials {
        m.emissive *= 0.07;
    }
    scene
}

/// Through a thin lens and a Gaussian filter (pbrt-v4's default, radius 1.5: camera samples of
/// the edge pixels land beyond the image), under an area light over most of the ceiling with an
/// emission texture (bright on one half, dim on the other: the walls and shadows it lights are
/// lopsided), the light tracer and BDPT give the path tracer's image: its 8 × 8 blocks within
/// noise (a lens importance W_e off by its cos⁴ or lens area would tilt or scale them; light
/// leaving the emitter without its texture evens the halves out, 9 % block error), and the
/// outermost ring of pixels within noise too.
#[test]
fn light_paths_match_the_path_tracer_through_a_lens_to_the_film_edge() {
    use trayecto::material::texture::{Texture, TextureRef};
    use trayecto::math::Vec4;
    let mut scene = cornell_wide_light();
    scene.cameras[0].aperture_radius = 0.2;
    scene.cameras[0].focus_distance = 3.9;
    scene.textures.push(Texture::image(
        "half",
        2,
        1,
        vec![Vec4::new(1.9, 1.9, 1.9, 1.0), Vec4::new(0.1, 0.1, 0.1, 1.0)],
    ));
    let texture = scene.textures.len() - 1;
    let light = scene
        .materials
        .iter_mut()
        .find(|m| m.emissive != Vec3::ZERO)
        .unwrap();
    light.emissive_texture = Some(TextureRef::new(texture));
    let world = World::build(scene, &Default::default()).unwrap();
    let settings = |integrator, spp| RenderSettings {
        integrator,
        filter: trayecto::film::filter::Filter::new(trayecto::film::filter::FilterKind::Gaussian),
        ..lt(32, 32, spp, 1024)
    };
    let reference = render_world(&world, &settings(IntegratorKind::Path, 64));
    let ring = |i: &Image| {
        let (w, h) = (i.width, i.height);
        let mut s = 0.0f64;
        let mut n = 0;
        for y in 0..h {
            for x in 0..w {
                if x == 0 || y == 0 || x == w - 1 || y == h - 1 {
                    s += trayecto::film::luminance(i.get(x, y)) as f64;
                    n += 1;
                }
            }
        }
        s / n as f64
    };
    // BDPT sees the emitter directly through the lens as the path tracer does (a bright blur
    // whose pixels are noisy at these sample counts in both); the light tracer joins light
    // points to the lens instead.
    for (integrator, spp, mean_bound, block_bound, edge_bound) in [
        (IntegratorKind::LightTracer, 256, 0.02, 0.04, 0.07),
        (IntegratorKind::Bdpt, 32, 0.04, 0.1, 0.1),
    ] {
        let img = render_world(&world, &settings(integrator, spp));
        let what = format!("{integrator:?} through a lens");
        let e = block_error(&img, &reference);
        let edge = ring(&img) / ring(&reference) - 1.0;
        println!(
            "{what}: block error {e:.4}, edge ring off by {:.2} %",
            edge * 100.0
        );
        assert_means_close(&img, &reference, mean_bound, &what);
        assert!(e < block_bound, "{what}: block error {e}");
        assert!(
            edge.abs() < edge_bound,
            "{what}: the edge ring is off by {edge}"
        );
    }
}

/// A wide filter reaches past the image: a path tracer's samples of an edge pixel land up to the
/// filter's radius outside it, so light paths must be able to land there too (W_e over the film
/// widened by radius − ½, pbrt-v4's `SampleBounds`) and their splats there must reach the pixels
/// inside. The Cornell box at a 30° field of view (walls to the side and bottom edges), through
/// a Gaussian of radius 2 and σ = 1 (an edge pixel's filter has over a quarter of its weight
/// outside): the side columns and the bottom row (the light at the top edge is inside the
/// image) over the walls inside is the path tracer's for the light tracer, BDPT and MLT (the
/// ratio takes MLT's bootstrap noise out).
#[test]
fn light_paths_fill_the_edge_pixels_through_a_wide_filter() {
    use trayecto::film::filter::{Filter, FilterKind};
    let mut scene = builtin::cornell();
    scene.cameras[0].vfov_deg = 30.0;
    let world = World::build(scene, &Default::default()).unwrap();
    let mut filter = Filter::new(FilterKind::Gaussian);
    filter.radius = [2.0, 2.0];
    filter.sigma = 1.0;
    let (w, h, depth) = (24, 24, 3);
    let settings = |base: RenderSettings| RenderSettings { filter, ..base };
    let edge = |i: &Image| {
        let lum = |x, y| trayecto::film::luminance(i.get(x, y)) as f64;
        let ring: f64 = (0..w)
            .map(|x| (x, h - 1))
            .chain((3..h - 1).flat_map(|y| [(0, y), (w - 1, y)]))
            .map(|(x, y)| lum(x, y))
            .sum::<f64>()
            / (w + 2 * (h - 4)) as f64;
        let inside: f64 = (3..h - 3)
            .flat_map(|y| (3..w - 3).map(move |x| lum(x, y)))
            .sum::<f64>()
            / ((w - 6) * (h - 6)) as f64;
        ring / inside
    };
    let path = settings(RenderSettings {
        integrator: IntegratorKind::Path,
        ..lt(w, h, 256, depth)
    });
    let reference = edge(&render_world(&world, &path));
    for (what, s, bound) in [
        ("light tracer", settings(lt(w, h, 64, depth)), 0.04),
        (
            "bdpt",
            settings(RenderSettings {
                integrator: IntegratorKind::Bdpt,
                ..lt(w, h, 16, depth)
            }),
            0.04,
        ),
        ("mlt", settings(mlt(w, h, 64, depth)), 0.1),
    ] {
        let off = edge(&render_world(&world, &s)) / reference - 1.0;
        println!(
            "{what}: edge pixels over inside off by {:.2} %",
            off * 100.0
        );
        assert!(
            off.abs() < bound,
            "{what}: edge pixels over inside off by {off}"
        );
    }
}

/// `img` and `reference` with the pixels above 100 times the reference's median luminance set
/// to black in both: lamps far smaller than a pixel seen directly, whose share of a pixel a
/// render at test sample counts catches or not (a lottery, not a bias).
fn without_lamps_seen_directly(img: &Image, reference: &Image) -> (Image, Image) {
    let mut sorted: Vec<f32> = reference
        .data
        .iter()
        .map(|&p| trayecto::film::luminance(p))
        .collect();
    sorted.sort_by(f32::total_cmp);
    let limit = 100.0 * sorted[sorted.len() / 2];
    let keep = |k: usize| {
        [img, reference]
            .iter()
            .all(|i| trayecto::film::luminance(i.data[k]) < limit)
    };
    let masked = |i: &Image| Image {
        data: (0..i.data.len())
            .map(|k| if keep(k) { i.data[k] } else { Vec3::ZERO })
            .collect(),
        ..i.clone()
    };
    (masked(img), masked(reference))
}

/// pbrt-v4's BDPT renders of `veach-bidir` and `water-caustic` (32 × 32, 1024 samples,
/// `scripts/references/pbrt_bdpt_references.sh 32 1024`) and `volumetric-caustic` (64 × 64, 512
/// samples, `… 64 512 volumetric-caustic`; tests/references/pbrt/bdpt/): Trayecto's BDPT of the
/// same files, their filter and depth, agrees with them within noise (image mean and the 8 × 8
/// blocks). The lamp of `veach-bidir` is seen through its glass shade, the caustic of
/// `water-caustic` is light refracted twice by the water's surface and that of
/// `volumetric-caustic` is focused by a glass sphere into fog: a wrong specular vertex, medium
/// vertex, MIS weight or importance shows as a block off by tens of per cent. Left out
/// of both images: pixels above 100 times the reference's median, `water-caustic`'s lamp seen
/// directly (a 5 × 4 mm emitter of radiance 5·10⁵ covering a per cent of one pixel: whether a
/// render at test sample counts catches it is a lottery, and it is a third of the reference's
/// mean).
#[test]
fn bdpt_agrees_with_pbrt_v4_on_veach_bidir_and_the_caustics() {
    for (name, size, spp, mean_bound, block_bound) in [
        ("veach-bidir", 32, 64, 0.03, 0.05),
        ("water-caustic", 32, 64, 0.06, 0.2),
        ("volumetric-caustic", 64, 32, 0.03, 0.1),
    ] {
        let t0 = std::time::Instant::now();
        let file = shared_scene(&format!("pbrt/{name}/scene-v4.pbrt"));
        let scene = trayecto::scene::load(file.to_str().unwrap()).unwrap();
        let mut settings = RenderSettings {
            integrator: IntegratorKind::Bdpt,
            filter: scene.hints.filter.unwrap_or_default(),
            ..lt(size, size, spp, scene.hints.max_depth.unwrap())
        };
        settings.seed = 1;
        let img = render_scene(&scene, &settings);
        let reference =
            read_exr(&repo_dir().join(format!("tests/references/pbrt/bdpt/{name}-{size}.exr")))
                .unwrap();
        let (img, reference) = without_lamps_seen_directly(&img, &reference);
        let lum = |i: &Image| trayecto::film::luminance(i.mean()) as f64;
        let off = lum(&img) / lum(&reference) - 1.0;
        let e = block_error(&img, &reference);
        println!(
            "{name}: mean off by {:.2} %, block error {e:.4} ({:.1} s)",
            off * 100.0,
            t0.elapsed().as_secs_f64()
        );
        assert!(off.abs() < mean_bound, "{name}: mean off by {off}");
        assert!(e < block_bound, "{name}: block error {e}");
    }
}

/// Cameras without an importance function are refused with the reason.
#[test]
fn light_tracer_refuses_cameras_without_importance() {
    let mut scene = builtin::cornell();
    scene.cameras[0].projection = trayecto::scene::Projection::Orthographic { half_height: 1.0 };
    let world = World::build(scene, &Default::default()).unwrap();
    let err = render_range(
        &world,
        &lt(8, 8, 1, 4),
        RangeStart {
            samples: 0..1,
            resume: None,
        },
        &NoObserver,
        &AtomicBool::new(false),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("orthographic"), "{err}");
}

/// The bidirectional path tracer on the Cornell box: within 2 % of Mitsuba's means and 5 % block
/// error on the centre of the image (a crop window, which also checks the splats' scaling).
#[test]
fn bdpt_matches_mitsuba_on_the_cornell_box() {
    let reference = read_exr(&repo_dir().join("tests/references/cornell_128.exr")).unwrap();
    let scene = builtin::cornell();
    let settings = RenderSettings {
        integrator: IntegratorKind::Bdpt,
        crop: Some(trayecto::render::Crop {
            x0: 32,
            x1: 96,
            y0: 32,
            y1: 96,
        }),
        ..lt(128, 128, 8, 1024)
    };
    let img = render_scene(&scene, &settings);
    assert_eq!((img.width, img.height), (64, 64));
    let mut data = Vec::new();
    for y in 32..96 {
        for x in 32..96 {
            data.push(reference.get(x, y));
        }
    }
    let crop = Image {
        width: 64,
        height: 64,
        data,
    };
    assert_means_close(&img, &crop, 0.02, "bdpt cornell");
    let e = block_error(&img, &crop);
    assert!(e < 0.05, "bdpt block error {e}");
}

/// BDPT's strategy layers (`--aov bdpt-sS-tT[-unweighted]`) on the diffuse Cornell box at depth
/// 2: the weighted layers of every strategy add up to the beauty image pixel by pixel (to the
/// rounding of separate sums); each strategy alone, unweighted, estimates the same image of the
/// paths of its depth (the box is diffuse, so every strategy can make every path), compared
/// with next-event estimation (s = 1) in the image mean and in 4 × 4 blocks; and the weighted
/// strategies of a depth add up to that image too, which they do only if the MIS weights of a
/// path's strategies sum to 1 (a weight sum off by a factor shows as that factor).
#[test]
fn bdpt_strategy_layers_add_up_and_agree_alone() {
    use trayecto::film::aov::{AovKind, Strategy};
    // The strategies that must hit the light (s = 0) converge at test sample counts.
    let world = World::build(cornell_wide_light(), &Default::default()).unwrap();
    let settings = RenderSettings {
        integrator: IntegratorKind::Bdpt,
        sampler: SamplerKind::Independent,
        path: PathSettings {
            max_depth: 2,
            // No Russian roulette before depth 2: every strategy's paths are complete.
            rr_depth: 8,
            ..Default::default()
        },
        ..lt(32, 32, 32, 2)
    };
    let beauty = render_world(&world, &settings);
    let kinds = AovKind::parse_list(
        "bdpt-depth0,bdpt-depth1,bdpt-depth2,bdpt-depth1-unweighted,bdpt-depth2-unweighted",
    )
    .unwrap();
    let layers = trayecto::render::light::render_strategies(
        &world,
        &settings,
        &kinds,
        settings.spp,
        &AtomicBool::new(false),
    )
    .unwrap();
    assert_eq!(layers.len(), kinds.len());
    let image = |k: Strategy| {
        let l = layers
            .iter()
            .find(|l| l.name == AovKind::Strategy(k).name())
            .unwrap();
        l.to_image().unwrap()
    };
    let sum = |ks: Vec<Strategy>| {
        let mut out = Image {
            data: vec![Vec3::ZERO; beauty.data.len()],
            ..beauty.clone()
        };
        for k in ks {
            for (o, p) in out.data.iter_mut().zip(&image(k).data) {
                *o += *p;
            }
        }
        out
    };
    let all = sum((0..=2).flat_map(|d| Strategy::of_depth(d, true)).collect());
    for (i, (a, b)) in all.data.iter().zip(&beauty.data).enumerate() {
        assert!(
            (*a - *b).abs().max_element() <= 1e-5 * b.max_element() + 1e-7,
            "pixel {i}: the weighted strategies add up to {a}, the image is {b}"
        );
    }
    let lum = |i: &Image| trayecto::film::luminance(i.mean()) as f64;
    for depth in 1..=2 {
        // Next-event estimation (s = 1) is the least noisy: the others are held to it.
        let reference = image(Strategy::new(1, depth + 1, false).unwrap());
        // (name, image, mean and block error bounds, about twice the largest of 9 seeds): a
        // strategy that joins two scattering vertices (s, t ≥ 2) has the 1 / d² of the
        // connection in its value, unbounded where walls meet, so it converges slowly (its
        // mean within 12 % of the others' at 32 samples; within 1 % at 512): only its mean is
        // held, and more loosely.
        let mut alone: Vec<(String, Image, f64, f64)> = Strategy::of_depth(depth, false)
            .into_iter()
            .map(|k| {
                let (mean, blocks) = if k.s >= 2 && k.t >= 2 {
                    (0.2, f64::INFINITY)
                } else {
                    (0.1, 0.3)
                };
                let name = AovKind::Strategy(k).name().to_string();
                (name, image(k), mean, blocks)
            })
            .collect();
        alone.push((
            format!("depth {depth} weighted"),
            sum(Strategy::of_depth(depth, true)),
            0.06,
            0.12,
        ));
        for (name, img, mean_bound, block_bound) in &alone {
            let off = lum(img) / lum(&reference) - 1.0;
            let e = block_error(img, &reference);
            println!(
                "{name}: mean off by {:.2} %, 8 x 8 block error {:.2} %",
                off * 100.0,
                e * 100.0
            );
            assert!(
                off.abs() < *mean_bound && e < *block_bound,
                "{name}: mean off by {off}, block error {e}, against next-event estimation"
            );
        }
    }
}

/// Participating media: the fog Cornell box (a chromatic homogeneous global fog, the camera in
/// it) and the cloud (a heterogeneous density grid inside index-matched interface faces, lit by
/// a quad light and a sky) rendered by BDPT, and the fog by the light tracer (the cloud's sky
/// is seen directly, which the light tracer leaves out), against Mitsuba 3's volpath references
/// that the volumetric path tracer is held to (tests/media_render.rs): channel means within
/// 3 % and 8 × 8 block error within 6 %, falling with samples as noise does (8 times the
/// samples: ideally 2.8 times less, at least 1.8 asked).
#[test]
fn light_paths_render_participating_media() {
    for (name, integrator, spp, tol) in [
        ("fog_cornell", IntegratorKind::Bdpt, 96, 0.03),
        ("fog_cornell", IntegratorKind::LightTracer, 128, 0.03),
        ("cloud", IntegratorKind::Bdpt, 64, 0.03),
    ] {
        let path = repo_dir().join(format!("scenes/media/{name}.toml"));
        let scene = trayecto::scene::load(path.to_str().unwrap()).unwrap();
        let reference =
            read_exr(&repo_dir().join(format!("tests/references/mitsuba_media_{name}.exr")))
                .unwrap();
        let (w, h) = (reference.width, reference.height);
        let settings = |spp| RenderSettings {
            integrator,
            ..lt(w, h, spp, 1024)
        };
        let low = render_scene(&scene, &settings(spp / 8));
        let high = render_scene(&scene, &settings(spp));
        let what = format!("{name} {integrator:?}");
        assert_means_close(&high, &reference, tol, &what);
        let (e_low, e_high) = (
            block_error(&low, &reference),
            block_error(&high, &reference),
        );
        println!(
            "{what}: block error {e_low:.4} at {} spp, {e_high:.4} at {spp} spp",
            spp / 8
        );
        assert!(
            e_high < 0.06 && e_high < e_low / 1.8,
            "{what}: block error {e_low} at {} spp, {e_high} at {spp} spp",
            spp / 8
        );
    }
}

/// BDPT, the light tracer and MLT where the path tracer converges, on files of the other
/// formats and in fog: pbrt-v4's
/// `veach-mis` (four glossy plates reflecting four spheres of different sizes, with the file's
/// filter and depth) and a glTF model (Khronos' MetalRoughSpheresNoTextures, a grid of metallic
/// and dielectric GGX spheres of every roughness, lit by the default studio environment that a
/// model without lights gets), BDPT, the light tracer and MLT on the first, BDPT and MLT on the second
/// (whose background is the environment seen directly, which paths from the lights never reach
/// the lens through, in pbrt-v4's light tracer as in Trayecto's), and MLT on the fog Cornell box (BDPT and the light tracer are held to Mitsuba there, in
/// `light_paths_render_participating_media`).
/// The reference is Trayecto's path tracer at many samples (held to pbrt-v4 and Mitsuba 3
/// elsewhere), the lamps seen directly left out of both (`without_lamps_seen_directly`: at
/// 48 × 27 the smallest of veach-mis' spheres is a fraction of a pixel); each BDPT image's mean is within 3 % and its 8 × 8 block error falls as noise
/// does over 8 times the samples and ends below 8 % (15 % for the light tracer and MLT, at four
/// times BDPT's samples; MLT on veach-mis at 1024 mutations per pixel, its fall over 8 times the
/// mutations held to 1.3, not 1.8: it fell 1.46–1.65× over four other seeds, to 0.07–0.10, the
/// chains being correlated and the bootstrap's per-depth shares of b fixed whatever the
/// mutations; BENCHMARKS.md); MLT's mean is its bootstrap's b, within
/// 3 standard errors of b plus 1 %, and its shape is compared with the mean scaled, as in the
/// Cornell test.
#[test]
fn light_paths_agree_with_the_path_tracer_on_veach_mis_gltf_and_fog() {
    let veach = shared_scene("pbrt/veach-mis/scene-v4.pbrt");
    let gltf = shared_scene(
        "gltf/MetalRoughSpheresNoTextures/glTF-Binary/MetalRoughSpheresNoTextures.glb",
    );
    let fog = repo_dir().join("scenes/media/fog_cornell.toml");
    use IntegratorKind::{Bdpt, LightTracer, Mlt};
    // MLT on veach-mis: the lamps seen directly and their glossy reflections are a few pixels
    // holding most of the image's light, and b's per-depth shares of them are the bootstrap's
    // estimate, off by ±12 % (100 000 states per depth, 48 × 27) to ±5 % (400 000) from seed to
    // seed whatever the mutations; with pbrt-v4's 1000 chains the 8 × 8 block error falls from
    // 0.12–0.15 at 128 mutations per pixel to 0.07–0.10 at 1024 (four seeds, BENCHMARKS.md).
    let veach_mlt = trayecto::sampling::mlt::MltSettings {
        bootstrap_samples: Some(400_000),
        chains: Some(1000),
        ..Default::default()
    };
    for (file, (w, h), ref_spp, bdpt_spp, integrators) in [
        (veach, (48, 27), 1024, 32, &[Bdpt, LightTracer, Mlt][..]),
        (gltf, (32, 32), 256, 16, &[Bdpt, Mlt][..]),
        (fog, (24, 24), 512, 32, &[Mlt][..]),
    ] {
        let scene = trayecto::scene::load(file.to_str().unwrap()).unwrap();
        let base = |integrator, spp| RenderSettings {
            integrator,
            filter: scene.hints.filter.unwrap_or_default(),
            ..lt(w, h, spp, scene.hints.max_depth.unwrap_or(8))
        };
        let name = file.file_stem().unwrap().to_string_lossy().into_owned();
        let is_veach = file.to_string_lossy().contains("veach-mis");
        let reference = render_scene(&scene, &base(IntegratorKind::Path, ref_spp));
        let lum = |i: &Image| trayecto::film::luminance(i.mean()) as f64;
        for &integrator in integrators {
            let settings = |spp| match integrator {
                IntegratorKind::Mlt if is_veach => RenderSettings {
                    filter: scene.hints.filter.unwrap_or_default(),
                    mlt: veach_mlt,
                    ..mlt(w, h, spp, scene.hints.max_depth.unwrap_or(8))
                },
                IntegratorKind::Mlt => RenderSettings {
                    filter: scene.hints.filter.unwrap_or_default(),
                    ..mlt(w, h, spp, scene.hints.max_depth.unwrap_or(8))
                },
                _ => base(integrator, spp),
            };
            let spp = if integrator == Bdpt {
                bdpt_spp
            } else if integrator == Mlt && is_veach {
                1024
            } else {
                4 * bdpt_spp
            };
            let (low, high) = (
                render_scene(&scene, &settings(spp / 8)),
                render_scene(&scene, &settings(spp)),
            );
            // MLT's whole image has the bootstrap's mean, lamps included; BDPT's is compared
            // without them (the lottery of a sub-pixel lamp's share would dominate it).
            let whole_off = lum(&high) / lum(&reference) - 1.0;
            let (low, ref_low) = without_lamps_seen_directly(&low, &reference);
            let (high, ref_high) = without_lamps_seen_directly(&high, &reference);
            let what = format!("{name} {integrator:?}");
            let off = match integrator {
                IntegratorKind::Mlt => whole_off,
                _ => lum(&high) / lum(&ref_high) - 1.0,
            };
            let scaled = |i: &Image, r: &Image| Image {
                data: i
                    .data
                    .iter()
                    .map(|&p| p * (lum(r) / lum(i)) as f32)
                    .collect(),
                ..i.clone()
            };
            let (low, high) = if integrator == IntegratorKind::Mlt {
                (scaled(&low, &ref_low), scaled(&high, &ref_high))
            } else {
                (low, high)
            };
            let (e_low, e_high) = (block_error(&low, &ref_low), block_error(&high, &ref_high));
            println!(
                "{what}: mean off by {:.2} %, block error {e_low:.4} at {} spp, {e_high:.4} at {spp}",
                off * 100.0,
                spp / 8
            );
            // MLT's mean is its bootstrap's b: within 3 of b's standard errors plus 1 %.
            let bound = match integrator {
                IntegratorKind::Mlt => {
                    let (_, err) = trayecto::render::mlt::normalisation(
                        &World::build(scene.clone(), &Default::default()).unwrap(),
                        &settings(1),
                    )
                    .unwrap();
                    3.0 * err + 0.01
                }
                _ => 0.03,
            };
            println!("{what}: mean bound {:.2} %", bound * 100.0);
            assert!(
                off.abs() < bound,
                "{what}: mean off by {off} (bound {bound})"
            );
            // The light tracer and MLT are noisier per sample than BDPT on these scenes: their
            // block error ends higher, but must fall as noise does all the same (MLT on
            // veach-mis more slowly: see above).
            let end = if integrator == Bdpt { 0.08 } else { 0.15 };
            let fall = if integrator == Mlt && is_veach {
                1.3
            } else {
                1.8
            };
            assert!(
                e_high < end && e_high < e_low / fall,
                "{what}: block error {e_low} at {} spp, {e_high} at {spp} spp",
                spp / 8
            );
        }
    }
}

/// Every light type on both ends of the paths: a point light, a spot, a directional light with a
/// small emissive sphere (an area light seen directly), an image environment (textured, lighting
/// metal and diffuse spheres), and smooth and rough glass spheres under a quad light and a sky
/// (caustics on the wall behind them: specular chains). BDPT on all of them and the light tracer
/// where no point light is seen directly, against the Mitsuba 3 references the path tracer is
/// held to (tests/mitsuba_materials.rs): channel means within 3 % and 8 × 8 block error below
/// 8 %, falling as noise does over 8 times the samples. The light tracer on the environment-lit
/// spheres is compared on the pixels wholly covered by them (`coverage`, 4 × 4 rays a pixel):
/// the environment seen directly is light no path from the lights reaches the lens with (as in
/// pbrt-v4's light tracer), the spheres' reflections of it are.
#[test]
fn light_paths_agree_with_mitsuba_for_every_light_type() {
    use trayecto::math::Mat4;
    use trayecto::scene::LightDesc;
    for (name, integrator, spp) in [
        ("point", IntegratorKind::Bdpt, 16),
        ("point", IntegratorKind::LightTracer, 256),
        ("spot", IntegratorKind::Bdpt, 16),
        ("spot", IntegratorKind::LightTracer, 128),
        ("directional", IntegratorKind::Bdpt, 16),
        ("directional", IntegratorKind::LightTracer, 128),
        ("envmap", IntegratorKind::Bdpt, 32),
        ("envmap", IntegratorKind::LightTracer, 1024),
        ("glass", IntegratorKind::Bdpt, 32),
    ] {
        let path = repo_dir().join(format!("scenes/mitsuba/{name}.toml"));
        let mut scene = trayecto::scene::load(path.to_str().unwrap()).unwrap();
        if name == "envmap" {
            // As tests/mitsuba_materials.rs adds it (scene files read only their own folder).
            scene.lights.push(LightDesc::Environment {
                name: "studio".into(),
                path: shared_scene("hdr/studio_small_03_1k.hdr"),
                scale: Vec3::ONE,
                mapping: Default::default(),
                transform: Mat4::from_rotation_y(90f32.to_radians()),
            });
        }
        let reference =
            read_exr(&repo_dir().join(format!("tests/references/mitsuba_{name}.exr"))).unwrap();
        let (w, h) = (reference.width, reference.height);
        let settings = |spp| RenderSettings {
            integrator,
            ..lt(w, h, spp, 1024)
        };
        let low = render_scene(&scene, &settings(spp / 8));
        let high = render_scene(&scene, &settings(spp));
        let what = format!("{name} {integrator:?}");
        let (low, high, reference) = if integrator == IntegratorKind::LightTracer
            && scene
                .lights
                .iter()
                .any(|l| matches!(l, LightDesc::Environment { .. }))
        {
            let world = World::build(scene.clone(), &Default::default()).unwrap();
            let covered = coverage(&world, w, h, &settings(1));
            let kept = covered.iter().filter(|&&c| c >= 1.0).count();
            assert!(kept > 500, "{what}: {kept} pixels wholly covered");
            let masked = |i: &Image| Image {
                data: (i.data.iter().zip(&covered))
                    .map(|(&p, &c)| if c >= 1.0 { p } else { Vec3::ZERO })
                    .collect(),
                ..i.clone()
            };
            (masked(&low), masked(&high), masked(&reference))
        } else {
            (low, high, reference)
        };
        assert_means_close(&high, &reference, 0.03, &what);
        let (e_low, e_high) = (
            block_error(&low, &reference),
            block_error(&high, &reference),
        );
        println!(
            "{what}: block error {e_low:.4} at {} spp, {e_high:.4} at {spp} spp",
            spp / 8
        );
        assert!(
            e_high < 0.08 && e_high < e_low / 1.8,
            "{what}: block error {e_low} at {} spp, {e_high} at {spp} spp",
            spp / 8
        );
    }
}

fn mlt(width: u32, height: u32, mutations: u32, max_depth: u32) -> RenderSettings {
    RenderSettings {
        integrator: IntegratorKind::Mlt,
        mlt: trayecto::sampling::mlt::MltSettings {
            bootstrap_samples: Some(20_000),
            chains: Some(64),
            ..Default::default()
        },
        ..lt(width, height, mutations, max_depth)
    }
}

/// Metropolis light transport on the Cornell box, on a window below the light (the light seen
/// directly is a few pixels whose share of b the bootstrap estimates with tens of per cent of
/// noise at test sizes): direct light (depth 1) against Mitsuba's direct-only reference, and
/// depth 4 against the path tracer at the same depth. The image mean is b, the
/// bootstrap's estimate, whatever the mutations: it must lie within 3 standard errors of the
/// bootstrap (`mlt::normalisation`) plus 1 %. The image's shape is the chains': with its mean
/// scaled to the reference's, the 8 × 8 block error falls as noise does over 8 times the
/// mutations (at least by 1.8) and ends below 20 % (MLT at 32 mutations per pixel is blotchy:
/// its chains are correlated).
#[test]
fn mlt_matches_the_path_tracer_on_the_cornell_box() {
    let world = World::build(builtin::cornell(), &Default::default()).unwrap();
    let direct = read_exr(&repo_dir().join("tests/references/cornell_128_direct.exr")).unwrap();
    let window = trayecto::render::Crop {
        x0: 0,
        x1: 64,
        y0: 16,
        y1: 64,
    };
    let path_4 = render_world(
        &world,
        &RenderSettings {
            integrator: IntegratorKind::Path,
            crop: Some(window),
            ..lt(64, 64, 256, 4)
        },
    );
    // The window of `direct` at half its size: each pixel the mean of its 2 × 2 pixels (what
    // a box-filtered render of half the size converges to).
    let direct = Image {
        width: 64,
        height: 48,
        data: (16..64)
            .flat_map(|y: u32| (0..64u32).map(move |x| (x, y)))
            .map(|(x, y)| {
                let p = |dx: u32, dy: u32| direct.get(2 * x + dx, 2 * y + dy);
                (p(0, 0) + p(1, 0) + p(0, 1) + p(1, 1)) * 0.25
            })
            .collect(),
    };
    for (depth, reference) in [(1, &direct), (4, &path_4)] {
        let mutations = 32;
        let settings = |m| RenderSettings {
            crop: Some(window),
            ..mlt(64, 64, m, depth)
        };
        let low = render_world(&world, &settings(mutations / 8));
        let high = render_world(&world, &settings(mutations));
        let (b, err) = trayecto::render::mlt::normalisation(&world, &settings(1)).unwrap();
        let what = format!("mlt depth {depth}");
        let lum = |i: &Image| trayecto::film::luminance(i.mean()) as f64;
        let off = lum(&high) / lum(reference) - 1.0;
        println!(
            "{what}: b {b:.5} ± {:.2} %, image mean off by {:.2} %",
            err * 100.0,
            off * 100.0
        );
        assert!(
            off.abs() < 3.0 * err + 0.01,
            "{what}: mean off by {off}, b's error {err}"
        );
        let scaled = |i: &Image| Image {
            data: i
                .data
                .iter()
                .map(|&p| p * (lum(reference) / lum(i)) as f32)
                .collect(),
            ..i.clone()
        };
        let (e_low, e_high) = (
            block_error(&scaled(&low), reference),
            block_error(&scaled(&high), reference),
        );
        println!(
            "{what}: block error {e_low:.4} at {} mutations per pixel, {e_high:.4} at {mutations}",
            mutations / 8
        );
        assert!(
            e_high < 0.2 && e_high < e_low / 1.8,
            "{what}: block error {e_low} at {} mutations per pixel, {e_high} at {mutations}",
            mutations / 8
        );
    }
}

/// MLT on veach-mis' lamps seen directly (maxdepth 0: the lamps alone, each a third of the light,
/// the smallest a fraction of a pixel at 48 × 27) against the path tracer: each lamp's columns
/// within 15 % and the image mean within 3 of b's standard errors plus 1 %. A lamp's share of b is
/// the bootstrap's count of hits on it, and the chains seldom move between lamps, so a bias or a
/// start-up error at a sub-pixel lamp stays in the image whatever the mutations; with 4·10⁶
/// bootstrap states the lamps read +1.5 / +1.2 / +0.9 % (standard deviations 3.1 / 4.7 / 4.8 %)
/// over seeds 1–6 (`bench/mlt_veach_mis.py --res 48 27 --mutations 64 --bootstrap 4000000`),
/// and at pbrt-v4's default 10⁵ the smallest lamp's spread is 27 % (BENCHMARKS.md, "MLT on
/// veach-mis").
#[test]
fn mlt_renders_veach_mis_lamps_seen_directly() {
    let scene = trayecto::scene::load(
        shared_scene("pbrt/veach-mis/scene-v4.pbrt")
            .to_str()
            .unwrap(),
    )
    .unwrap();
    let (w, h) = (48, 27);
    let filter = scene.hints.filter.unwrap_or_default();
    let reference = render_scene(
        &scene,
        &RenderSettings {
            integrator: IntegratorKind::Path,
            filter,
            ..lt(w, h, 1024, 0)
        },
    );
    let settings = RenderSettings {
        filter,
        mlt: trayecto::sampling::mlt::MltSettings {
            bootstrap_samples: Some(4_000_000),
            chains: Some(1000),
            ..Default::default()
        },
        ..mlt(w, h, 64, 0)
    };
    let image = render_scene(&scene, &settings);
    let column = |i: &Image, x: u32| -> f64 {
        (0..h)
            .map(|y| trayecto::film::luminance(i.get(x, y)) as f64)
            .sum()
    };
    // The lamps: runs of columns the reference's lamps (with their filter footprint) light.
    let mut lamps: Vec<(u32, u32)> = Vec::new();
    for x in 0..w {
        if column(&reference, x) > 0.0 {
            match lamps.last_mut() {
                Some((_, end)) if *end + 1 == x => *end = x,
                _ => lamps.push((x, x)),
            }
        }
    }
    assert_eq!(lamps.len(), 3, "lamps seen directly: {lamps:?}");
    for &(x0, x1) in &lamps {
        let sum = |i: &Image| (x0..=x1).map(|x| column(i, x)).sum::<f64>();
        let off = sum(&image) / sum(&reference) - 1.0;
        println!(
            "lamp at columns {x0}..={x1}: MLT off by {:.2} %",
            off * 100.0
        );
        assert!(
            off.abs() < 0.15,
            "lamp at columns {x0}..={x1}: MLT off by {off}"
        );
    }
    let lum = |i: &Image| trayecto::film::luminance(i.mean()) as f64;
    let off = lum(&image) / lum(&reference) - 1.0;
    let (_, err) = trayecto::render::mlt::normalisation(
        &World::build(scene.clone(), &Default::default()).unwrap(),
        &settings,
    )
    .unwrap();
    println!(
        "image mean off by {:.2} %, b's error {:.2} %",
        off * 100.0,
        err * 100.0
    );
    assert!(
        off.abs() < 3.0 * err + 0.01,
        "image mean off by {off}, b's error {err}"
    );
}

/// Metropolis light transport's film is a function of the seed and settings: 1 and 2 threads
/// give the same film bit for bit (the chains are independent, each with its own generators,
/// and splat into exact sums), through a Gaussian filter; and a sample range is refused with
/// the reason (a chain is not split); previews reach the observer while the chains run.
#[test]
fn mlt_film_is_a_function_of_seed_and_settings() {
    let world = World::build(builtin::cornell(), &Default::default()).unwrap();
    let base = RenderSettings {
        threads: Some(1),
        filter: trayecto::film::filter::Filter::new(trayecto::film::filter::FilterKind::Gaussian),
        mlt: trayecto::sampling::mlt::MltSettings {
            bootstrap_samples: Some(500),
            chains: Some(7),
            ..Default::default()
        },
        ..mlt(20, 16, 4, 4)
    };
    let cancel = AtomicBool::new(false);
    let range = |s: &RenderSettings, samples: std::ops::Range<u32>| {
        render_range(
            &world,
            s,
            RangeStart {
                samples,
                resume: None,
            },
            &NoObserver,
            &cancel,
        )
    };
    let one = range(&base, 0..4).unwrap().film;
    assert!(one.to_image().mean().max_element() > 0.0);
    let two = RenderSettings {
        threads: Some(2),
        ..base.clone()
    };
    assert_eq!(one, range(&two, 0..4).unwrap().film);
    let err = range(&base, 0..2).err().unwrap().to_string();
    assert!(err.contains("sample ranges"), "{err}");

    // Previews while the chains run: the film after each batch of chains, counted as the
    // mutations per pixel done, then the final film. The preview's mean is the final image's
    // (every mutation splats b in all; the batches hold each depth's share of the chains) up
    // to the rounding of the mutations per pixel (at most 1/16 once 8 of 32 are done).
    struct Previews(std::sync::Mutex<Vec<(u32, trayecto::film::Film)>>);
    impl trayecto::render::RenderObserver for Previews {
        fn pass_done(&self, film: &trayecto::film::Film, done: u32, _spp: u32) {
            self.0.lock().unwrap().push((done, film.clone()));
        }
    }
    let previews = Previews(Default::default());
    let settings = RenderSettings {
        mlt: trayecto::sampling::mlt::MltSettings {
            chains: Some(16),
            ..base.mlt
        },
        ..mlt(20, 16, 32, 4)
    };
    let out = render_range(
        &world,
        &settings,
        RangeStart {
            samples: 0..32,
            resume: None,
        },
        &previews,
        &cancel,
    )
    .unwrap();
    let passes = previews.0.into_inner().unwrap();
    assert_eq!(passes.last(), Some(&(32, out.film.clone())));
    let lum = |f: &trayecto::film::Film| trayecto::film::luminance(f.to_image().mean()) as f64;
    let done: Vec<u32> = passes.iter().map(|p| p.0).collect();
    assert!(
        done.len() >= 5 && done.windows(2).all(|w| w[0] <= w[1]),
        "previews at {done:?} mutations per pixel"
    );
    for (k, film) in passes.iter().filter(|p| p.0 >= 8) {
        let off = lum(film) / lum(&out.film) - 1.0;
        assert!(off.abs() < 0.1, "preview at {k} of 32 off by {off}");
    }
}

/// The path tracer's renders a motion-blur test measures light paths against, at `path`'s
/// settings: the motion-blurred `world` at seed 11 (a seed of its own: BDPT's camera subpaths
/// at the same seed would be its rays), the same at seed 6 (how far the reference's own noise
/// reaches) and the still `still` (which the blur must be far from, or the test cannot tell).
fn blur_references(world: &World, still: &World, path: RenderSettings) -> [Image; 3] {
    [
        render_world(
            world,
            &RenderSettings {
                seed: 11,
                ..path.clone()
            },
        ),
        render_world(
            world,
            &RenderSettings {
                seed: 6,
                ..path.clone()
            },
        ),
        render_world(still, &path),
    ]
}

/// Relative RMS difference of the `b` × `b`-pixel block means of `img` and `reference` (over the
/// reference's mean luminance): [`block_error`] at a finer grid, where a blur's shape shows.
fn block_error_at(img: &Image, reference: &Image, b: u32) -> f64 {
    let (a, r) = (block_rgb_means(img, b), block_rgb_means(reference, b));
    let s: f64 = a
        .iter()
        .zip(&r)
        .map(|(p, q)| (*p - *q).as_dvec3().length_squared() / 3.0)
        .sum();
    let m = reference.mean();
    (s / a.len() as f64).sqrt() / ((m.x + m.y + m.z) / 3.0) as f64
}

/// Motion blur through light paths: the Cornell box (light over most of the ceiling) with a
/// card crossing it during the shutter (keyed at three times and interpolated between: the one
/// world of continuous motion) seen by a camera that slides and turns 0.2 rad (about 9 pixels of
/// the 32). The light tracer (a time per light path, joined to the camera placed at that time),
/// BDPT (the light subpath at its camera sample's time) and MLT (the time one more number of a
/// state) give the motion-blurred path tracer's image: 4 × 4-pixel blocks (8 × 8 for MLT, whose
/// chains are blotchy at this size) within 3 times the path tracer's own seed-to-seed spread
/// (0.013), while the still at the shutter's middle, which a light path that ignored the time
/// of the camera or of the card would approach, is 2.4–6 times the bound away (measured: with
/// the camera's importance left unposed the light tracer's block error is 0.19, bound 0.04).
/// The blurred film is also the same for 1 and 2 threads.
#[test]
fn light_paths_render_motion_blur_as_the_path_tracer() {
    use std::sync::Arc;
    use trayecto::math::Mat4;
    use trayecto::scene::Shape;
    use trayecto::scene::animation::{Animation, MovingTransform, RigidMotion};
    use trayecto::world::motion::TimeOptions;
    let mut scene = cornell_wide_light();
    let (card, blue) = common::add_blue_card(&mut scene);
    let object = scene.objects.len();
    scene.add_object("card", Shape::Mesh(card), Mat4::IDENTITY, blue);
    let start = scene.cameras[0].camera_to_world;
    let end =
        start * Mat4::from_translation(Vec3::new(0.15, 0.0, 0.0)) * Mat4::from_rotation_y(0.2);
    scene.animation = Some(Arc::new(Animation {
        rigid: vec![
            RigidMotion::Object {
                object,
                motion: MovingTransform {
                    times: [0.0, 1.0],
                    start: Mat4::from_translation(Vec3::new(-0.6, 0.1, 0.5)),
                    end: Mat4::from_translation(Vec3::new(0.6, 0.1, 0.5)),
                },
            },
            RigidMotion::Camera {
                camera: 0,
                motion: MovingTransform {
                    times: [0.0, 1.0],
                    start,
                    end,
                },
            },
        ],
        ..Default::default()
    }));
    let build = |time| posed_world(&scene, time);
    let world = build(TimeOptions {
        shutter: Some([0.0, 1.0]),
        steps: 2,
        ..Default::default()
    });
    assert!(world.motion.is_empty() && world.geometry.motion.is_some());
    assert!(world.camera_motion.is_some());
    // Depth 4: MLT's bootstrap is per depth.
    let (w, h, depth) = (32, 32, 4);
    let with = |integrator, spp| RenderSettings {
        integrator,
        ..lt(w, h, spp, depth)
    };
    let [reference, other, still] = blur_references(
        &world,
        &build(TimeOptions {
            time: Some(0.5),
            ..Default::default()
        }),
        with(IntegratorKind::Path, 256),
    );
    println!(
        "motion blur: path tracer seeds {:.4} apart, the middle still {:.4} (4 x 4 blocks), {:.4} (8 x 8)",
        block_error_at(&other, &reference, 4),
        block_error_at(&still, &reference, 4),
        block_error_at(&still, &reference, 8)
    );
    // MLT's chains are blotchy at test sizes: it is judged on 8 × 8 blocks.
    let mut mlt = mlt(w, h, 1024, depth);
    mlt.mlt.chains = Some(1024);
    for (what, settings, b, bound) in [
        (
            "light tracer",
            with(IntegratorKind::LightTracer, 256),
            4,
            0.04,
        ),
        ("bdpt", with(IntegratorKind::Bdpt, 64), 4, 0.04),
        ("mlt", mlt, 8, 0.05),
    ] {
        let t0 = std::time::Instant::now();
        let img = render_world(&world, &settings);
        let e = block_error_at(&img, &reference, b);
        let far = block_error_at(&still, &reference, b);
        println!(
            "{what} motion blur: {b} x {b} block error {e:.4} ({:?})",
            t0.elapsed()
        );
        assert_means_close(&img, &reference, 0.03, &format!("{what} motion blur"));
        assert!(e < bound, "{what}: block error {e} (bound {bound})");
        assert!(
            far > 2.0 * bound,
            "the still is {far} from the blur: the test cannot tell"
        );
    }
    for integrator in [IntegratorKind::LightTracer, IntegratorKind::Bdpt] {
        let threads = |n| RenderSettings {
            threads: Some(n),
            ..with(integrator, 4)
        };
        assert_eq!(
            render_world(&world, &threads(1)).data,
            render_world(&world, &threads(2)).data,
            "{integrator:?}: 1 and 2 threads"
        );
    }
}

/// A moving emitter: the Cornell box's light sliding 0.9 across the ceiling during the
/// shutter, as its quad (keyed in the one world, `--shutter-steps 4`: its corner and edges
/// interpolated at each ray's time, its area light placed there) and as a thin box (which
/// motion blur renders with a world per shutter step, the scene posed at each step's middle; a
/// sample traces the world of its time). The light tracer and BDPT trace a light path at its
/// sample's time and agree with the motion-blurred path tracer in 8 × 8-pixel blocks within the
/// reference's noise (the light seen directly, 18 times the walls' radiance, dominates their
/// spread: two path tracer seeds 0.051 apart with the quad, 0.039 with the box; measured 0.033
/// and 0.069 (quad), 0.045 and 0.034 (box)), while the still at the shutter's opening (the
/// light at one end) is 1.6–1.7 away.
#[test]
fn light_paths_follow_a_moving_emitter_in_one_world_and_through_the_shutter_steps() {
    use std::sync::Arc;
    use trayecto::math::Mat4;
    use trayecto::scene::Shape;
    use trayecto::scene::animation::{Animation, MovingTransform, RigidMotion};
    use trayecto::world::motion::TimeOptions;
    let quad = builtin::cornell();
    let mut thin_box = quad.clone();
    let light = thin_box
        .objects
        .iter()
        .position(|o| o.name == "light")
        .unwrap();
    thin_box.objects[light].shape = Shape::Cuboid {
        min: Vec3::new(-0.23, 0.985, -0.18),
        max: Vec3::new(0.23, 0.99, 0.2),
    };
    for (mut scene, steps, what_light) in [(quad, 1, "quad"), (thin_box, 4, "box")] {
        let object = scene
            .objects
            .iter()
            .position(|o| o.name == "light")
            .unwrap();
        scene.animation = Some(Arc::new(Animation {
            rigid: vec![RigidMotion::Object {
                object,
                motion: MovingTransform {
                    times: [0.0, 1.0],
                    start: Mat4::from_translation(Vec3::new(-0.45, 0.0, 0.0)),
                    end: Mat4::from_translation(Vec3::new(0.45, 0.0, 0.0)),
                },
            }],
            ..Default::default()
        }));
        let build = |time| posed_world(&scene, time);
        let world = build(TimeOptions {
            shutter: Some([0.0, 1.0]),
            steps: 4,
            ..Default::default()
        });
        assert_eq!(world.time_steps(), steps, "{what_light}");
        let (w, h, depth) = (32, 32, 4);
        let with = |integrator, spp| RenderSettings {
            integrator,
            ..lt(w, h, spp, depth)
        };
        let [reference, other, still] = blur_references(
            &world,
            &build(TimeOptions {
                time: Some(0.0),
                ..Default::default()
            }),
            with(IntegratorKind::Path, 256),
        );
        let far = block_error(&still, &reference);
        let apart = block_error(&other, &reference);
        println!(
            "moving {what_light} emitter: path tracer seeds {apart:.4} apart, the still at the \
             opening {far:.4}"
        );
        // Within the reference's own noise: a light moving continuously smears across the
        // pixels that see it, and its blocks are noisier than a few sharp steps' (two path
        // tracer seeds 0.05 apart with the quad in one world, 0.015–0.025 with 4 steps).
        let bound = (1.6 * apart).max(0.04);
        for (what, settings) in [
            ("light tracer", with(IntegratorKind::LightTracer, 256)),
            ("bdpt", with(IntegratorKind::Bdpt, 256)),
        ] {
            let img = render_world(&world, &settings);
            let e = block_error(&img, &reference);
            println!("{what}, moving {what_light} emitter: block error {e:.4}");
            assert_means_close(
                &img,
                &reference,
                0.03,
                &format!("{what}, moving {what_light} emitter"),
            );
            assert!(e < bound, "{what}: block error {e} (bound {bound})");
            assert!(
                far > 2.0 * bound,
                "the still is {far} from the blur: the test cannot tell"
            );
        }
    }
}

/// Moving point and spot lights (`common::cornell_with_moving_lights`) in the one
/// motion-blurred world (no world per step): the light tracer and BDPT place the light where it
/// is at their sample's time (emission, BDPT's light densities and its light samples for camera
/// vertices) and agree with the motion-blurred path tracer, whose NEE places it at the
/// receiver's time, in 8 × 8-pixel blocks within noise (0.012 measured, two path-tracer seeds
/// 0.015 apart), as does the path tracer choosing lights by the light BVH (bounded over the
/// keys), while the still at the shutter's opening is 0.86 away.
#[test]
fn light_paths_follow_moving_lights_in_one_world() {
    use trayecto::world::WorldOptions;
    use trayecto::world::motion::TimeOptions;
    let scene = cornell_with_moving_lights();
    let build = |time| posed_world(&scene, time);
    let world = build(TimeOptions {
        shutter: Some([0.0, 1.0]),
        steps: 4,
        ..Default::default()
    });
    assert_eq!(world.time_steps(), 1, "one world");
    assert!(world.lights.moves());
    let (w, h, depth) = (32, 32, 4);
    let with = |integrator, spp| RenderSettings {
        integrator,
        ..lt(w, h, spp, depth)
    };
    let [reference, other, still] = blur_references(
        &world,
        &build(TimeOptions {
            time: Some(0.0),
            ..Default::default()
        }),
        with(IntegratorKind::Path, 256),
    );
    let far = block_error(&still, &reference);
    println!(
        "moving lights: path tracer seeds {:.4} apart, the still at the opening {far:.4}",
        block_error(&other, &reference)
    );
    // NEE choosing by the light BVH, which bounds each moving light over its keys.
    let bvh_world = World::build_posed(
        scene.clone(),
        &WorldOptions {
            time: TimeOptions {
                shutter: Some([0.0, 1.0]),
                steps: 4,
                ..Default::default()
            },
            light_sampler: trayecto::light::LightSamplerKind::Bvh,
            ..Default::default()
        },
    )
    .unwrap();
    for (what, w, settings, bound) in [
        (
            "light tracer",
            &world,
            with(IntegratorKind::LightTracer, 256),
            0.03,
        ),
        ("bdpt", &world, with(IntegratorKind::Bdpt, 256), 0.03),
        (
            "path, light BVH",
            &bvh_world,
            with(IntegratorKind::Path, 256),
            0.03,
        ),
    ] {
        let img = render_world(w, &settings);
        let e = block_error(&img, &reference);
        println!("{what}, moving lights: block error {e:.4}");
        assert_means_close(&img, &reference, 0.03, &format!("{what}, moving lights"));
        assert!(e < bound, "{what}: block error {e} (bound {bound})");
        assert!(
            far > 2.0 * bound,
            "the still is {far} from the blur: the test cannot tell"
        );
    }
}

/// Moving emitters (`common::cornell_with_moving_emitters`: a mesh panel sliding and turning,
/// a sphere crossing the box as it grows) in the one motion-blurred world: the light tracer and
/// BDPT start their light paths on the emitter where it is at their sample's time
/// (`AreaLight::at`: its point, area and emitted ray), BDPT's light densities and its light
/// samples for camera vertices take it there too, and they agree with the motion-blurred path
/// tracer in 8 × 8-pixel blocks within noise, as does the path tracer choosing lights by the
/// light BVH (each moving emitter boxed over the whole shutter): within 1.6 times the distance
/// of two path tracer seeds (0.056; measured 0.051, 0.079, 0.082), while the still at the
/// shutter's opening is 0.81 away.
#[test]
fn light_paths_follow_moving_emitters_in_one_world() {
    use trayecto::world::WorldOptions;
    use trayecto::world::motion::TimeOptions;
    let scene = cornell_with_moving_emitters();
    let build = |time, light_sampler| {
        World::build_posed(
            scene.clone(),
            &WorldOptions {
                time,
                light_sampler,
                ..Default::default()
            },
        )
        .unwrap()
    };
    let blur = || TimeOptions {
        shutter: Some([0.0, 1.0]),
        steps: 4,
        ..Default::default()
    };
    let world = build(blur(), Default::default());
    assert_eq!(world.time_steps(), 1, "one world");
    assert!(world.geometry.motion.is_some());
    let (w, h, depth) = (32, 32, 4);
    let with = |integrator, spp| RenderSettings {
        integrator,
        ..lt(w, h, spp, depth)
    };
    let [reference, other, still] = blur_references(
        &world,
        &build(
            TimeOptions {
                time: Some(0.0),
                ..Default::default()
            },
            Default::default(),
        ),
        with(IntegratorKind::Path, 256),
    );
    let far = block_error(&still, &reference);
    let apart = block_error(&other, &reference);
    println!(
        "moving emitters: path tracer seeds {apart:.4} apart, the still at the opening {far:.4}"
    );
    // Within the reference's own noise (the moving emitters seen directly smear over the
    // pixels: two path tracer seeds 0.05 apart).
    let bound = (1.6 * apart).max(0.04);
    let bvh_world = build(blur(), trayecto::light::LightSamplerKind::Bvh);
    for (what, w, settings) in [
        (
            "light tracer",
            &world,
            with(IntegratorKind::LightTracer, 256),
        ),
        ("bdpt", &world, with(IntegratorKind::Bdpt, 256)),
        (
            "path, light BVH",
            &bvh_world,
            with(IntegratorKind::Path, 256),
        ),
    ] {
        let img = render_world(w, &settings);
        let e = block_error(&img, &reference);
        println!("{what}, moving emitters: block error {e:.4}");
        assert_means_close(&img, &reference, 0.03, &format!("{what}, moving emitters"));
        assert!(e < bound, "{what}: block error {e} (bound {bound})");
        assert!(
            far > 2.0 * bound,
            "the still is {far} from the blur: the test cannot tell"
        );
    }
}
