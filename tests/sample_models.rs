//! Every Khronos sample model under `shared/scenes/gltf/` against its `screenshot/`.
//!
//! The screenshot is a rasterizer's view with its own lighting, so only what lighting does not
//! change is compared: the silhouette and the surface colours' chromaticity.
//!
//! * Foreground of the screenshot: pixels that differ from its uniform background, estimated as the
//!   median of the border pixels. Foreground of the render: the ray caster's depth view (a miss is 0).
//! * Both are cropped to their foreground's bounding box and resampled onto a coarse grid, so the
//!   comparison does not depend on how large the viewer framed the model, only on its shape: the
//!   coverage of each cell must agree (intersection over union of the two masks).
//! * Colour: in each cell covered by both, the mean *linear* chromaticity `rgb / (r + g + b)` of the
//!   screenshot against that of the render's albedo view. A white light scales all three channels
//!   alike, so chromaticity is what a differently lit view still shares; decoding sRGB textures as
//!   linear, or swapping channels, moves it.
//!
//! Upside-down or mirrored renders move the silhouette and colours between cells. Run with
//! `TRAYECTO_SAMPLES_DUMP=DIR` to write each screenshot's and render's masks and colours as PNGs.

mod common;

use std::path::{Path, PathBuf};

use trayecto::film::Image;
use trayecto::integrator::IntegratorKind;
use trayecto::integrator::raycast::Aov;
use trayecto::integrator::whitted::ShadingModel;
use trayecto::math::Vec3;
use trayecto::render::RenderSettings;
use trayecto::world::{World, WorldOptions, orbit_camera};

/// One sample model: its folder, the file to load and its screenshot.
struct Model {
    name: String,
    file: PathBuf,
    screenshot: PathBuf,
}

/// Every folder under `scenes/gltf` that holds a model (a `glTF*` sub-folder or a README); the
/// licence-texts folder is the only one that holds neither. A model folder without a loadable file
/// or a screenshot is a failure, not a skip.
fn models() -> Vec<Model> {
    let root = common::shared_dir().join("scenes/gltf");
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap_or_else(|e| panic!("{}: {e}", root.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    let mut out = Vec::new();
    for dir in dirs {
        let name = dir.file_name().unwrap().to_string_lossy().into_owned();
        let entries: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        let is_model = entries.iter().any(|p| {
            let f = p.file_name().unwrap().to_string_lossy();
            f.starts_with("glTF") || f == "README.md"
        });
        if !is_model {
            assert!(
                entries
                    .iter()
                    .all(|p| p.extension().is_some_and(|e| e == "txt")),
                "{name}: a folder with neither a glTF sub-folder nor a README, but not only licence texts"
            );
            continue;
        }
        let file = ["glTF", "glTF-Binary", "glTF-Embedded"]
            .iter()
            .filter_map(|sub| first_with_ext(&dir.join(sub), &["gltf", "glb"]))
            .next()
            .unwrap_or_else(|| panic!("{name}: no .gltf or .glb file"));
        let screenshot = first_with_ext(&dir.join("screenshot"), &["png", "jpg", "jpeg"])
            .unwrap_or_else(|| panic!("{name}: no screenshot/"));
        out.push(Model {
            name,
            file,
            screenshot,
        });
    }
    assert!(out.len() >= 14, "only {} models found", out.len());
    out
}

fn first_with_ext(dir: &Path, exts: &[&str]) -> Option<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .ok()?
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.extension()
                .is_some_and(|e| exts.iter().any(|x| e.eq_ignore_ascii_case(x)))
        })
        .collect();
    files.sort();
    files.into_iter().next()
}

fn srgb_to_linear(c: f32) -> f32 {
    trayecto::material::texture::srgb_to_linear(c)
}

/// A linear RGB image with a foreground mask (1 = model, 0 = background, fractional at edges).
struct Layer {
    w: usize,
    h: usize,
    color: Vec<Vec3>,
    mask: Vec<f32>,
    /// At least 90 % of the border is within `BG_DIST` of its median: a plain background.
    uniform_background: bool,
}

/// The screenshot, decoded to linear, and its foreground: a pixel belongs to the model when it is
/// farther than `BG_DIST` (in sRGB units, max over channels) from the border's median colour.
fn screenshot_layer(path: &Path) -> Layer {
    const BG_DIST: f32 = 0.06;
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb32f();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let px: Vec<Vec3> = img.pixels().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
    let mut border: Vec<Vec3> = Vec::new();
    for x in 0..w {
        border.push(px[x]);
        border.push(px[(h - 1) * w + x]);
    }
    for y in 0..h {
        border.push(px[y * w]);
        border.push(px[y * w + w - 1]);
    }
    let median = |c: usize| {
        let mut v: Vec<f32> = border.iter().map(|p| p[c]).collect();
        v.sort_by(f32::total_cmp);
        v[v.len() / 2]
    };
    let bg = Vec3::new(median(0), median(1), median(2));
    let near_bg = |p: &Vec3| (*p - bg).abs().max_element() <= BG_DIST;
    let uniform_background = border.iter().filter(|p| near_bg(p)).count() * 10 >= border.len() * 9;
    let mask = px
        .iter()
        .map(|p| f32::from(!uniform_background || !near_bg(p)))
        .collect();
    let color = px
        .iter()
        .map(|p| {
            Vec3::new(
                srgb_to_linear(p.x),
                srgb_to_linear(p.y),
                srgb_to_linear(p.z),
            )
        })
        .collect();
    Layer {
        w,
        h,
        color,
        mask,
        uniform_background,
    }
}

fn raycast(world: &World, w: u32, h: u32, spp: u32, aov: Aov) -> Image {
    let settings = RenderSettings {
        width: w,
        height: h,
        spp,
        integrator: IntegratorKind::Raycast {
            aov,
            shading: ShadingModel::Pbr,
        },
        ..Default::default()
    };
    common::render_world(world, &settings)
}

/// The render's layer: the albedo view as colour, and as foreground the fraction of each pixel
/// covered by the model, counted at 4 × 4 sub-pixels with the depth view (0 where a ray misses).
fn render_layer(world: &World, w: u32, h: u32) -> Layer {
    let albedo = raycast(world, w, h, 4, Aov::Albedo);
    let mask = common::coverage(world, w, h, &RenderSettings::default());
    Layer {
        w: w as usize,
        h: h as usize,
        color: albedo.data,
        mask,
        uniform_background: true,
    }
}

/// Bounding box `[x0, x1) × [y0, y1)` of the pixels with mask ≥ 0.5.
fn bbox(l: &Layer) -> Option<(usize, usize, usize, usize)> {
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for y in 0..l.h {
        for x in 0..l.w {
            if l.mask[y * l.w + x] >= 0.5 {
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x + 1);
                y1 = y1.max(y + 1);
            }
        }
    }
    (x0 < x1).then_some((x0, y0, x1, y1))
}

/// Per cell of a `g × g` grid over the layer's bounding box: mean mask, and mask-weighted mean
/// linear colour.
struct Cells {
    cover: Vec<f32>,
    color: Vec<Vec3>,
}

fn cells(l: &Layer, g: usize) -> Cells {
    let (x0, y0, x1, y1) = bbox(l).expect("empty foreground");
    let mut cover = vec![0.0f32; g * g];
    let mut color = vec![Vec3::ZERO; g * g];
    let mut count = vec![0.0f32; g * g];
    for y in y0..y1 {
        for x in x0..x1 {
            let cx = (x - x0) * g / (x1 - x0);
            let cy = (y - y0) * g / (y1 - y0);
            let i = cy * g + cx;
            let m = l.mask[y * l.w + x];
            count[i] += 1.0;
            cover[i] += m;
            color[i] += l.color[y * l.w + x] * m;
        }
    }
    for i in 0..g * g {
        if cover[i] > 0.0 {
            color[i] /= cover[i];
        }
        cover[i] /= count[i].max(1.0);
    }
    Cells { cover, color }
}

/// What a comparison measured.
struct Report {
    /// Intersection over union of the cells' coverage (silhouettes only).
    iou: Option<f32>,
    /// Largest colour difference ([`colour_diff`], degrees of hue) over the compared cells, and
    /// how many cells were compared.
    hue: f32,
    cells: usize,
    /// False for [`COLOUR_NOT_COMPARABLE`] models: only the silhouette counts.
    colour_compared: bool,
}

/// Least overlap of the bounding-box-aligned silhouettes.
const MIN_IOU: f32 = 0.6;
/// Largest hue difference of a cell, in degrees.
const MAX_HUE: f32 = 30.0;

impl Report {
    fn verdict(&self) -> Result<(), String> {
        if let Some(iou) = self.iou
            && iou < MIN_IOU
        {
            return Err(format!("silhouette overlap {iou:.3} < {MIN_IOU}"));
        }
        if !self.colour_compared {
            return Ok(());
        }
        if self.cells == 0 {
            return Err("no cell to compare colours in".into());
        }
        if self.hue > MAX_HUE {
            return Err(format!("hue off by {:.1}° > {MAX_HUE}°", self.hue));
        }
        Ok(())
    }
}

impl std::fmt::Display for Report {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        if let Some(iou) = self.iou {
            write!(f, "iou {iou:.3} ")?;
        }
        if !self.colour_compared {
            return write!(f, "(colour not comparable)");
        }
        write!(f, "hue {:.1}° over {} cells", self.hue, self.cells)
    }
}

/// Silhouettes on a `g × g` grid over each foreground's bounding box, and the colour of every cell
/// that both cover well and where the screenshot is not too dark to have a colour.
fn compare_silhouettes(shot: &Layer, render: &Layer, g: usize) -> Report {
    let (a, b) = (cells(shot, g), cells(render, g));
    let (mut inter, mut union) = (0.0, 0.0);
    for i in 0..g * g {
        inter += a.cover[i].min(b.cover[i]);
        union += a.cover[i].max(b.cover[i]);
    }
    let (mut worst, mut n) = (0.0f32, 0);
    for i in 0..g * g {
        if a.cover[i] > 0.5
            && b.cover[i] > 0.5
            && let Some(d) = colour_diff(a.color[i], b.color[i])
        {
            if std::env::var_os("TRAYECTO_SAMPLES_DUMP").is_some() && d > 15.0 {
                eprintln!(
                    "  cell {i}: shot {} render {} diff {d:.1}",
                    a.color[i], b.color[i]
                );
            }
            worst = worst.max(d);
            n += 1;
        }
    }
    Report {
        iou: Some(inter / union),
        hue: worst,
        cells: n,
        colour_compared: true,
    }
}

/// Mean colour of the central half (in each axis) of both frames: where the model is, whatever
/// is behind it. The render's misses are left out.
fn compare_centres(shot: &Layer, render: &Layer) -> Report {
    let centre_mean = |l: &Layer| {
        let mut sum = Vec3::ZERO;
        let mut wsum = 0.0;
        for y in l.h / 4..l.h * 3 / 4 {
            for x in l.w / 4..l.w * 3 / 4 {
                let m = l.mask[y * l.w + x];
                sum += l.color[y * l.w + x] * m;
                wsum += m;
            }
        }
        sum / wsum.max(1e-6)
    };
    let d = colour_diff(centre_mean(shot), centre_mean(render));
    Report {
        iou: None,
        hue: d.unwrap_or(0.0),
        cells: usize::from(d.is_some()),
        colour_compared: true,
    }
}

/// How far apart two linear colours are, as the thing lighting does not change: their hue.
/// Scaling by a white light keeps hue and saturation (`1 − min/max`); the white a rasterizer's
/// specular and tone mapping add keeps the hue and lowers the saturation. So two colours that are
/// both clearly saturated (> `SAT`) must have hues within the tolerance (the value returned is the
/// hue difference in degrees), and a saturated colour must not face a grey one (returned as 180°).
/// `None` if either colour is too dark to have a colour.
fn colour_diff(a: Vec3, b: Vec3) -> Option<f32> {
    const SAT: f32 = 0.4;
    let (sa, sb) = (saturation(a)?, saturation(b)?);
    if sa > SAT && sb > SAT {
        let d = (hue(a) - hue(b)).abs();
        Some(d.min(360.0 - d))
    } else if (sa - sb).abs() > 0.6 {
        Some(180.0)
    } else {
        // Both greyish: they agree as far as hue can tell.
        Some(0.0)
    }
}

fn saturation(c: Vec3) -> Option<f32> {
    (c.max_element() > 0.02).then(|| 1.0 - c.min_element().max(0.0) / c.max_element())
}

/// Hue angle in degrees (the HSV hexcone).
fn hue(c: Vec3) -> f32 {
    let (mx, mn) = (c.max_element(), c.min_element());
    let d = (mx - mn).max(1e-9);
    let h = if mx == c.x {
        ((c.y - c.z) / d).rem_euclid(6.0)
    } else if mx == c.y {
        (c.z - c.x) / d + 2.0
    } else {
        (c.x - c.y) / d + 4.0
    };
    h * 60.0
}

fn to_srgb8(c: f32) -> u8 {
    (trayecto::material::texture::linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0).round() as u8
}

/// Writes `shot | shot mask | render | render mask`, each resampled to `render`'s size.
fn dump(dir: &Path, name: &str, shot: &Layer, render: &Layer) {
    let (w, h) = (render.w, render.h);
    let mut img = image::RgbImage::new(w as u32 * 4, h as u32);
    for (k, l) in [shot, render].into_iter().enumerate() {
        for y in 0..h {
            for x in 0..w {
                let j = (y * l.h / h) * l.w + x * l.w / w;
                let c = l.color[j];
                let px = image::Rgb([to_srgb8(c.x), to_srgb8(c.y), to_srgb8(c.z)]);
                img.put_pixel((2 * k * w + x) as u32, y as u32, px);
                let m = (l.mask[j] * 255.0) as u8;
                img.put_pixel(
                    ((2 * k + 1) * w + x) as u32,
                    y as u32,
                    image::Rgb([m, m, m]),
                );
            }
        }
    }
    img.save(dir.join(format!("{name}.png"))).unwrap();
}

/// How a screenshot was framed, judged by eye: yaw (about +y, from +z towards +x) and pitch (above
/// the horizon) in degrees of the orbit camera ([`orbit_camera`]) that sees the model as the
/// screenshot does. Models not listed are rendered with the camera a user gets: the file's, else
/// the automatic one.
const VIEWS: &[(&str, f32, f32)] = &[
    ("Box", 35.0, 30.0),
    ("BoxTextured", 35.0, 30.0),
    ("Cube", 30.0, 25.0),
    ("DamagedHelmet", -40.0, 10.0),
    ("EmissiveStrengthTest", 0.0, 20.0),
    ("TwoSidedPlane", 0.0, 35.0),
];

/// Screenshots whose background is not one colour, so the model's silhouette cannot be cut out:
/// only the colour of the frame's centre is compared. The border test must agree with this list.
const NOT_UNIFORM: &[(&str, &str)] = &[
    ("Cube", "a photograph behind the model"),
    ("TwoSidedPlane", "a photograph behind the model"),
    (
        "TransmissionTest",
        "the model's own checkerboard backdrop fills the frame",
    ),
];

/// Models whose screenshot does not show their base colours: metals mirror the viewer's
/// environment (and the render's albedo view shows their base colour). Their silhouette is still
/// compared.
const COLOUR_NOT_COMPARABLE: &[(&str, &str)] = &[
    (
        "DamagedHelmet",
        "metal, reflecting the viewer's environment",
    ),
    (
        "NormalTangentTest",
        "metal panels reflecting the viewer's sky and ground",
    ),
    (
        "NormalTangentMirrorTest",
        "metal panels reflecting the viewer's sky and ground",
    ),
];

#[test]
fn every_sample_model_matches_its_screenshot() {
    let dump_dir = std::env::var_os("TRAYECTO_SAMPLES_DUMP").map(PathBuf::from);
    let g = 4usize;
    let mut failures = Vec::new();
    for m in models() {
        let scene = match trayecto::scene::load(m.file.to_str().unwrap()) {
            Ok(s) => s,
            Err(e) => {
                failures.push(format!("{}: does not load: {e}", m.name));
                continue;
            }
        };
        let glb = m
            .file
            .parent()
            .unwrap()
            .parent()
            .unwrap()
            .join("glTF-Binary");
        if let Some(glb) = first_with_ext(&glb, &["glb"]) {
            match trayecto::scene::load(glb.to_str().unwrap()) {
                Ok(b)
                    if b.triangle_count() == scene.triangle_count()
                        && b.materials.len() == scene.materials.len() => {}
                Ok(b) => failures.push(format!(
                    "{}: the .glb has {} triangles and {} materials, the .gltf {} and {}",
                    m.name,
                    b.triangle_count(),
                    b.materials.len(),
                    scene.triangle_count(),
                    scene.materials.len()
                )),
                Err(e) => failures.push(format!("{}: the .glb does not load: {e}", m.name)),
            }
        }
        if scene.triangle_count() == 0 {
            failures.push(format!("{}: no triangles", m.name));
            continue;
        }
        let mut world = World::build(
            scene.clone(),
            &WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..WorldOptions::default()
            },
        )
        .unwrap();
        // The path tracer with the default lighting (or the file's lights) renders it: finite and
        // not black (LightsPunctualLamp, lit by its own dim lamps only, has a mean of ≈ 5e-4).
        let lit = common::render_world(
            &world,
            &RenderSettings {
                width: 24,
                height: 24,
                spp: 1,
                ..Default::default()
            },
        );
        let mean = lit.mean();
        if !(mean.is_finite() && mean.max_element() > 1e-4) {
            failures.push(format!("{}: path-traced mean {mean}", m.name));
        }
        if let Some(&(_, yaw, pitch)) = VIEWS.iter().find(|v| v.0 == m.name) {
            world.camera = orbit_camera(world.bounds, yaw, pitch);
        }
        let shot = screenshot_layer(&m.screenshot);
        // The render has the screenshot's aspect ratio, 64 pixels wide.
        let (w, h) = (64u32, ((64 * shot.h) as f32 / shot.w as f32).round() as u32);
        let render = render_layer(&world, w, h);
        if let Some(d) = &dump_dir {
            std::fs::create_dir_all(d).unwrap();
            dump(d, &m.name, &shot, &render);
        }
        let listed = NOT_UNIFORM.iter().any(|n| n.0 == m.name);
        if shot.uniform_background == listed {
            failures.push(format!(
                "{}: screenshot background uniform = {}, but NOT_UNIFORM says {}",
                m.name, shot.uniform_background, !listed
            ));
            continue;
        }
        let mut report = if shot.uniform_background {
            compare_silhouettes(&shot, &render, g)
        } else {
            compare_centres(&shot, &render)
        };
        if COLOUR_NOT_COMPARABLE.iter().any(|n| n.0 == m.name) {
            report.colour_compared = false;
        }
        eprintln!("{:28} {report}", m.name);
        if let Err(why) = report.verdict() {
            failures.push(format!("{}: {why}", m.name));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Writes a linear image as an sRGB PNG when `TRAYECTO_SAMPLES_DUMP` is set.
fn dump_image(name: &str, img: &Image) {
    let Some(d) = std::env::var_os("TRAYECTO_SAMPLES_DUMP").map(PathBuf::from) else {
        return;
    };
    std::fs::create_dir_all(&d).unwrap();
    let mut out = image::RgbImage::new(img.width, img.height);
    for (i, c) in img.data.iter().enumerate() {
        out.put_pixel(
            i as u32 % img.width,
            i as u32 / img.width,
            image::Rgb([to_srgb8(c.x), to_srgb8(c.y), to_srgb8(c.z)]),
        );
    }
    out.save(d.join(format!("{name}.png"))).unwrap();
}

fn sample_scene(model: &str) -> trayecto::scene::Scene {
    let p = common::shared_scene(&format!("gltf/{model}/glTF/{model}.gltf"));
    trayecto::scene::load(p.to_str().unwrap()).unwrap()
}

/// NormalTangentTest (README): "All of the test blocks show similar reflections": each pair of
/// cells, real bumps on the left and a normal-mapped flat quad on the right, must look lit from
/// the same direction. Lit by a directional light from above (and a little from the front), the
/// upper half of every bump is brighter than its lower half, in every cell.
#[test]
fn normal_tangent_test_bumps_are_lit_from_the_same_side() {
    bumps_are_lit_from_the_upper_right("NormalTangentTest", IntegratorKind::default());
}

/// The thesis's modes shade with the normal map too: the same check in the Whitted ray tracer
/// and in the ray caster's `shaded` view (local shading with the directional light's hard
/// shadow). Without normal mapping the flat right-hand cells are lit evenly and fail.
#[test]
fn normal_tangent_test_bumps_are_lit_from_the_same_side_in_the_thesis_modes() {
    bumps_are_lit_from_the_upper_right(
        "NormalTangentTest",
        IntegratorKind::Whitted {
            shading: ShadingModel::Pbr,
        },
    );
    bumps_are_lit_from_the_upper_right(
        "NormalTangentTest",
        IntegratorKind::Raycast {
            aov: Aov::Shaded,
            shading: ShadingModel::Pbr,
        },
    );
}

fn bumps_are_lit_from_the_upper_right(model: &str, integrator: IntegratorKind) {
    let mut scene = sample_scene(model);
    // Matte everywhere, so a single light shows the shape of every bump (a metal would show only
    // a highlight); the normal maps, what the model tests, are kept.
    for m in &mut scene.materials {
        m.metallic = 0.0;
        m.roughness = 1.0;
    }
    scene.lights.push(trayecto::scene::LightDesc::Directional {
        name: "sun".into(),
        // Travelling down, left and into the scene: light from the upper right, in front.
        direction: Vec3::new(-0.6, -1.0, -0.8).normalize(),
        irradiance: Vec3::splat(3.0),
    });
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let settings = RenderSettings {
        width: 240,
        height: 240,
        spp: 4,
        integrator,
        // Direct light only: the directional light is a delta light, sampled exactly.
        path: trayecto::integrator::path::PathSettings {
            max_depth: 1,
            ..Default::default()
        },
        ..Default::default()
    };
    let img = common::render_world(&world, &settings);
    dump_image(&format!("{model}_lit_{}", integrator.name()), &img);
    let n = 240usize;
    let lum = |x: usize, y: usize| {
        let c = img.data[y * n + x];
        0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
    };
    // The panels: runs of lit columns and rows (the background is black), separated by gaps.
    let runs = |count: &dyn Fn(usize) -> usize, min: usize| {
        let mut out = Vec::new();
        let mut start = None;
        for i in 0..=n {
            let on = i < n && count(i) >= min;
            match (on, start) {
                (true, None) => start = Some(i),
                (false, Some(s)) => {
                    out.push((s, i));
                    start = None;
                }
                _ => {}
            }
        }
        out
    };
    let lit = |x: usize, y: usize| lum(x, y) > 1e-3;
    // Rows first (the label row under the panels is much narrower: at least 40 % of the widest).
    let row_count = |y: usize| (0..n).filter(|&x| lit(x, y)).count();
    let widest = (0..n).map(row_count).max().unwrap();
    let rows: Vec<(usize, usize)> = runs(&row_count, widest * 2 / 5)
        .into_iter()
        .filter(|r| r.1 - r.0 > 4)
        .collect();
    let (y0, y1) = (rows[0].0, rows[rows.len() - 1].1);
    let col_count = |x: usize| (y0..y1).filter(|&y| lit(x, y)).count();
    // A panel's two cells may show a thin dark seam between them: runs closer than 4 pixels are
    // one panel.
    let mut cols: Vec<(usize, usize)> = Vec::new();
    for r in runs(&col_count, (y1 - y0) / 3) {
        match cols.last_mut() {
            Some(last) if r.0 - last.1 < 4 => last.1 = r.1,
            _ => cols.push(r),
        }
    }
    assert_eq!(
        (rows.len(), cols.len()),
        (5, 3),
        "rows {rows:?} columns {cols:?}"
    );
    let mut bad = Vec::new();
    for (r, &(ry0, ry1)) in rows.iter().enumerate() {
        for (c, &(cx0, cx1)) in cols.iter().enumerate() {
            // Each panel: real bump on the left half, normal-mapped quad on the right half.
            let half = (cx1 - cx0) / 2;
            for (k, hx0) in [cx0, cx0 + half].into_iter().enumerate() {
                // The bump fills the middle of its cell: compare the halves of the central 60 %.
                let (w, h) = (half, ry1 - ry0);
                let (bx0, bx1) = (hx0 + w / 5, hx0 + w * 4 / 5);
                let (by0, by1) = (ry0 + h / 5, ry0 + h * 4 / 5);
                let mean = |xa: usize, xb: usize, ya: usize, yb: usize| {
                    let mut s = 0.0;
                    for y in ya..yb {
                        for x in xa..xb {
                            s += lum(x, y);
                        }
                    }
                    s / ((xb - xa) * (yb - ya)) as f32
                };
                let (mx, my) = ((bx0 + bx1) / 2, (by0 + by1) / 2);
                let upper = mean(bx0, bx1, by0, my);
                let lower = mean(bx0, bx1, my, by1);
                let left = mean(bx0, mx, by0, by1);
                let right = mean(mx, bx1, by0, by1);
                let what = if k == 0 { "geometry" } else { "normal map" };
                eprintln!(
                    "row {r} column {c} {what:10}: upper/lower {:.2} right/left {:.2}",
                    upper / lower,
                    right / left
                );
                if !(upper > 1.15 * lower && right > 1.15 * left) {
                    bad.push(format!(
                        "row {r} column {c} ({what}): upper/lower {:.2}, right/left {:.2}",
                        upper / lower,
                        right / left
                    ));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "{model}: bumps not lit from the upper right: {bad:#?}"
    );
}

/// EmissiveStrengthTest (README): five cubes emit [0.1, 0.5, 0.9] × 1, 2, 4, 8, 16
/// (`KHR_materials_emissive_strength`), "progressively brighter to the right". Seen with emitted
/// light only (`max_depth` 0), each cube's radiance, left to right, must be in the ratios of the
/// strengths the file gives, and of the file's colour.
#[test]
fn emissive_strength_test_cubes_brighten_in_the_files_ratios() {
    let path = common::shared_scene("gltf/EmissiveStrengthTest/glTF/EmissiveStrengthTest.gltf");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    // The strengths the file gives its emissive materials (1 where the extension is absent).
    let mut strengths: Vec<f32> = json["materials"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m.get("emissiveFactor").is_some())
        .map(|m| {
            m["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"]
                .as_f64()
                .unwrap_or(1.0) as f32
        })
        .collect();
    strengths.sort_by(f32::total_cmp);
    assert_eq!(strengths, [1.0, 2.0, 4.0, 8.0, 16.0]);
    let scene = trayecto::scene::load(path.to_str().unwrap()).unwrap();
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let (w, h) = (160usize, 80usize);
    let settings = RenderSettings {
        width: w as u32,
        height: h as u32,
        spp: 4,
        path: trayecto::integrator::path::PathSettings {
            max_depth: 0,
            ..Default::default()
        },
        ..Default::default()
    };
    let img = common::render_world(&world, &settings);
    dump_image("EmissiveStrengthTest_emitted", &img);
    // Emitters only: the cubes are the only non-black pixels. Group them into runs of columns.
    let col_on = |x: usize| (0..h).any(|y| img.data[y * w + x].max_element() > 0.0);
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for x in 0..w {
        if col_on(x) {
            match runs.last_mut() {
                Some(r) if r.1 == x => r.1 = x + 1,
                _ => runs.push((x, x + 1)),
            }
        }
    }
    assert_eq!(runs.len(), 5, "cubes seen at columns {runs:?}");
    // The brightest pixel of each cube: one its face covers entirely (edge pixels are partly
    // background; a pixel cannot exceed the face's radiance).
    let cube = |(x0, x1): (usize, usize)| {
        (0..h)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .map(|(x, y)| img.data[y * w + x])
            .max_by(|a, b| a.z.total_cmp(&b.z))
            .unwrap()
    };
    let first = cube(runs[0]);
    let base = Vec3::new(0.1, 0.5, 0.9);
    for (i, r) in runs.iter().enumerate() {
        let c = cube(*r);
        let expect = base * strengths[i];
        assert!(
            (c - expect).abs().max_element() <= 0.01 * expect.max_element(),
            "cube {i} from the left: radiance {c}, expected {expect} (first {first})"
        );
    }
}

/// DamagedHelmet lit by the studio HDR (`--env`): its emissive panels glow on their own (seen with
/// emitted light only) and the whole helmet is lit by the environment.
#[test]
fn damaged_helmet_glows_and_is_lit_by_the_studio_hdr() {
    let scene = sample_scene("DamagedHelmet");
    let env = common::shared_scene("hdr/studio_small_03_1k.hdr");
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            env: Some(env),
            ..WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..Default::default()
            }
        },
    )
    .unwrap();
    assert!(
        !world.warnings.iter().any(|w| w.contains("no lights")),
        "{:?}",
        world.warnings
    );
    let n = 64u32;
    let on_helmet = raycast(&world, n, n, 1, Aov::Depth);
    let helmet: Vec<usize> = (0..(n * n) as usize)
        .filter(|&i| on_helmet.data[i].x > 0.0)
        .collect();
    assert!(
        helmet.len() > (n * n / 10) as usize,
        "{} pixels",
        helmet.len()
    );
    let render = |max_depth: u32, spp: u32| {
        let settings = RenderSettings {
            width: n,
            height: n,
            spp,
            path: trayecto::integrator::path::PathSettings {
                max_depth,
                ..Default::default()
            },
            ..Default::default()
        };
        common::render_world(&world, &settings)
    };
    // Emitted light only: the emissive texture's panels (a few per cent of the helmet) glow.
    let emitted = render(0, 1);
    dump_image("DamagedHelmet_emitted", &emitted);
    let glowing = helmet
        .iter()
        .filter(|&&i| emitted.data[i].max_element() > 0.1)
        .count();
    let frac = glowing as f32 / helmet.len() as f32;
    assert!((0.01..0.5).contains(&frac), "glowing fraction {frac}");
    // Fully lit: brighter than its own glow everywhere on average, and finite.
    let lit = render(8, 8);
    dump_image("DamagedHelmet_lit", &lit);
    let mean =
        |img: &Image| helmet.iter().map(|&i| img.data[i]).sum::<Vec3>() / helmet.len() as f32;
    let (m_lit, m_emitted) = (mean(&lit), mean(&emitted));
    assert!(m_lit.is_finite(), "{m_lit}");
    assert!(
        m_lit.element_sum() > 1.5 * m_emitted.element_sum() && m_lit.min_element() > 0.02,
        "lit {m_lit}, emitted only {m_emitted}"
    );
}

/// Pearson correlation of `a` and `b` over `idx`.
fn correlation(a: &[f32], b: &[f32], idx: &[usize]) -> f32 {
    let n = idx.len() as f64;
    let (ma, mb) = (
        idx.iter().map(|&i| a[i] as f64).sum::<f64>() / n,
        idx.iter().map(|&i| b[i] as f64).sum::<f64>() / n,
    );
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for &i in idx {
        let (x, y) = (a[i] as f64 - ma, b[i] as f64 - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    (sab / (saa * sbb).sqrt().max(1e-30)) as f32
}

/// Least-squares slope of `a` against `b` through the origin over `idx`: how much of the pattern
/// `b` shows up in `a`.
fn slope(a: &[f32], b: &[f32], idx: &[usize]) -> f32 {
    let (mut sab, mut sbb) = (0.0f64, 0.0f64);
    for &i in idx {
        sab += a[i] as f64 * b[i] as f64;
        sbb += b[i] as f64 * b[i] as f64;
    }
    (sab / sbb.max(1e-30)) as f32
}

/// TransmissionTest (README): "The grid of spheres demonstrate different combinations of uniform
/// transmission and textured transmission and how they should render in conjunction with opacity
/// (`baseColor.a`) and surface roughness/metalicity." Columns, left to right: transmission,
/// transmission with an alpha-masked base colour, transmissionTexture, both; rows, top to bottom:
/// smooth, rough, metallic (the last two through metallicRoughness textures, in stripes). The
/// labels are emissive text, the spheres stand before a checkered cloth backdrop.
///
/// What a sphere lets through is measured by swapping the backdrop's checker squares (its texture
/// inverted about its mean, so the lighting barely changes): the difference D of the renders
/// before and after the swap is the backdrop pattern as seen at each pixel, through whatever lies
/// in front; D0, the same difference without the spheres, is the pattern itself. Both renders use
/// the same random numbers, so most of their noise cancels. Per pixel, what the sphere's front
/// surface is there (transmissive, opaque or metallic, or a hole) is read from the ray caster's
/// `uv` and `depth` views of the sphere alone and the material's textures.
///
/// The file's lights are its emissive labels only (so no default environment is added, and the
/// scene is dark, image mean ≈ 0.02); the viewer that made the screenshot lights it with an
/// environment, so a uniform white one is added here.
#[test]
fn transmission_test_spheres_transmit_blur_and_cut_out_as_described() {
    use trayecto::material::AlphaMode;
    use trayecto::scene::LightDesc;
    let mut scene = sample_scene("TransmissionTest");
    scene.lights.push(LightDesc::Ambient {
        name: "white environment".into(),
        radiance: Vec3::ONE,
    });
    let mat_id = |name: &str| {
        scene
            .materials
            .iter()
            .position(|m| m.name == name)
            .unwrap_or_else(|| panic!("no material {name}"))
    };
    let backdrop = mat_id("Cloth Backdrop");
    let labels = mat_id("LabelMaterial");
    // The backdrop's checker, inverted about its mean: dark squares become light and vice versa.
    let mut swapped = scene.clone();
    let tex = swapped.materials[backdrop]
        .base_color_texture
        .as_ref()
        .unwrap()
        .texture;
    let t = &mut swapped.textures[tex];
    let (lo, hi) = t.texels.iter().fold((f32::MAX, f32::MIN), |(lo, hi), c| {
        (lo.min(c.x), hi.max(c.x))
    });
    assert!(
        hi > 2.0 * lo,
        "backdrop texture from {lo} to {hi}: not a checker"
    );
    t.map_texels(|c| {
        let mut s = trayecto::math::Vec4::splat(lo + hi) - c;
        s.w = c.w;
        s
    });
    let without_spheres = |s: &trayecto::scene::Scene| {
        let mut s = s.clone();
        s.objects
            .retain(|o| o.material == backdrop || o.material == labels);
        s
    };
    let (w, h) = (240usize, 180usize);
    let settings = RenderSettings {
        width: w as u32,
        height: h as u32,
        spp: 8,
        path: trayecto::integrator::path::PathSettings {
            max_depth: 8,
            ..Default::default()
        },
        ..Default::default()
    };
    let render = |s: &trayecto::scene::Scene| {
        let world = World::build(
            s.clone(),
            &WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..WorldOptions::default()
            },
        )
        .unwrap();
        common::render_world(&world, &settings)
    };
    // And with the backdrop black: what reaches the camera from the backdrop at all, blurred or not.
    let mut black = scene.clone();
    black.materials[backdrop].base_color = Vec3::ZERO;
    let (a, b, c) = (render(&scene), render(&swapped), render(&black));
    let (a0, b0) = (
        render(&without_spheres(&scene)),
        render(&without_spheres(&swapped)),
    );
    dump_image("TransmissionTest_lit", &a);
    dump_image("TransmissionTest_swapped", &b);
    let lum = |c: Vec3| 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
    // Channel `ch` (3: luminance) of p − q.
    let diff = |p: &Image, q: &Image, ch: usize| -> Vec<f32> {
        p.data
            .iter()
            .zip(&q.data)
            .map(|(x, y)| {
                let d = *x - *y;
                if ch < 3 { d[ch] } else { lum(d) }
            })
            .collect()
    };
    let d_ch: Vec<Vec<f32>> = (0..4).map(|ch| diff(&a, &b, ch)).collect();
    let d0_ch: Vec<Vec<f32>> = (0..4).map(|ch| diff(&a0, &b0, ch)).collect();
    let from_backdrop = diff(&a, &c, 3);
    let grid: [[&str; 4]; 3] = [
        [
            "YellowTrans",
            "GreenMask",
            "RedTransTexture",
            "BlueTransWithMask",
        ],
        [
            "YellowTransRough",
            "GreenMaskRough",
            "RedTransTextureRough",
            "BlueTransWithMask",
        ],
        [
            "YellowTransMetal",
            "GreenMaskMetal",
            "RedTransTextureMetal",
            "BlueTransWithMask",
        ],
    ];
    // The three "BlueTransWithMask" materials, top to bottom (the file names them alike).
    let blue: Vec<usize> = (0..scene.materials.len())
        .filter(|&i| scene.materials[i].name == "BlueTransWithMask")
        .collect();
    assert_eq!(blue.len(), 3);
    let mut failures = Vec::new();
    let mut check = |ok: bool, what: String| {
        eprintln!("{} {what}", if ok { "  ok  " } else { "FAILED" });
        if !ok {
            failures.push(what);
        }
    };
    // Pattern slope and backdrop light of the smooth yellow sphere, for the rough one.
    let mut yellow_smooth = (0.0, 0.0);
    for (row, names) in grid.iter().enumerate() {
        for (col, name) in names.iter().enumerate() {
            let m = if col == 3 { blue[row] } else { mat_id(name) };
            let mat = scene.materials[m].clone();
            // The sphere alone: its disc and front-surface UVs with holes filled, and where rays
            // pass through holes in both of its walls.
            let mut alone = scene.clone();
            alone.objects.retain(|o| o.material == m);
            alone.lights.clear();
            let world = World::build(
                alone.clone(),
                &WorldOptions {
                    default_light: Some(trayecto::scene::DefaultLight::Uniform),
                    ..WorldOptions::default()
                },
            )
            .unwrap();
            let holes_depth = raycast(&world, w as u32, h as u32, 1, Aov::Depth);
            alone.materials[m].alpha_mode = AlphaMode::Opaque;
            let world = World::build(
                alone.clone(),
                &WorldOptions {
                    default_light: Some(trayecto::scene::DefaultLight::Uniform),
                    ..WorldOptions::default()
                },
            )
            .unwrap();
            let disc_depth = raycast(&world, w as u32, h as u32, 1, Aov::Depth);
            let uv = raycast(&world, w as u32, h as u32, 1, Aov::Uv);
            // The inner 70 % of the disc's radius (the rim is mostly Fresnel reflection).
            let disc: Vec<usize> = (0..w * h).filter(|&i| disc_depth.data[i].x > 0.0).collect();
            let (cx, cy) = disc.iter().fold((0.0, 0.0), |(x, y), &i| {
                (x + (i % w) as f32, y + (i / w) as f32)
            });
            let (cx, cy) = (cx / disc.len() as f32, cy / disc.len() as f32);
            let radius = (disc.len() as f32 / std::f32::consts::PI).sqrt();
            let inner: Vec<usize> = disc
                .iter()
                .copied()
                .filter(|&i| {
                    let (dx, dy) = ((i % w) as f32 - cx, (i / w) as f32 - cy);
                    dx * dx + dy * dy < (0.7 * radius).powi(2)
                })
                .collect();
            let look = |r: &Option<trayecto::material::TextureRef>, i: usize| {
                r.as_ref().map_or(trayecto::math::Vec4::ONE, |r| {
                    let p = uv.data[i];
                    scene.textures[r.texture].lookup(trayecto::math::Vec2::new(p.x, p.y))
                })
            };
            // The front surface at each pixel: there (alpha), transmitting ((1 − metallic)·t).
            let present = |i: usize| {
                mat.alpha_mode == AlphaMode::Opaque
                    || mat.alpha * look(&mat.base_color_texture, i).w >= mat.alpha_cutoff
            };
            let transmit = |i: usize| {
                let mr = look(&mat.metallic_roughness_texture, i);
                mat.transmission
                    * look(&mat.transmission_texture, i).x
                    * (1.0 - mat.metallic * mr.z)
            };
            let select = |f: &dyn Fn(usize) -> bool| -> Vec<usize> {
                inner.iter().copied().filter(|&i| f(i)).collect()
            };
            let clear = select(&|i| present(i) && transmit(i) > 0.9);
            let opaque = select(&|i| present(i) && transmit(i) < 0.1);
            let through = select(&|i| holes_depth.data[i].x == 0.0);
            // Measured in the sphere's own colour channel (a red glass passes little green).
            let ch = (0..3)
                .max_by(|&p, &q| mat.base_color[p].total_cmp(&mat.base_color[q]))
                .unwrap();
            let (d, d0) = (&d_ch[ch], &d0_ch[ch]);
            let what = format!("row {row} column {col} ({name})");
            let n_min = inner.len() / 10;
            eprintln!("{what}: {} inner pixels, channel {ch}", inner.len());
            // From the grid's layout (its labels), not from the loaded material: a loader that
            // dropped transmissionTexture or the metallicRoughness texture must fail below.
            let textured = col == 2 || col == 3;
            let metal = row == 2;
            // The "w/ Opacity" columns (the labels say so, not the loaded material).
            let masked = col == 1 || col == 3;
            if row == 0 && !textured {
                // Smooth and uniformly transmissive: the backdrop's pattern, sharp, through the
                // clear parts (textured spheres' back walls are striped, which lowers it).
                let (k, r) = (slope(d, d0, &clear), correlation(d, d0, &clear));
                check(
                    clear.len() >= n_min && k > 0.25 && r > 0.85,
                    format!(
                        "{what}: backdrop seen through the smooth clear parts ({} px): slope {k:.2} > 0.25, correlation {r:.2} > 0.85",
                        clear.len()
                    ),
                );
                if col == 0 {
                    let mean =
                        clear.iter().map(|&i| from_backdrop[i]).sum::<f32>() / clear.len() as f32;
                    yellow_smooth = (slope(&d_ch[3], &d0_ch[3], &clear), mean);
                }
            }
            if row == 1 && col == 0 {
                // Rough: the pattern blurred away, but the backdrop's light still comes through.
                let k = slope(&d_ch[3], &d0_ch[3], &clear);
                let mean =
                    clear.iter().map(|&i| from_backdrop[i]).sum::<f32>() / clear.len() as f32;
                check(
                    k < 0.35 * yellow_smooth.0 && mean > 0.5 * yellow_smooth.1,
                    format!(
                        "{what}: rough transmission blurs: pattern slope {k:.3} < 0.35 × smooth {:.3}; backdrop light {mean:.3} > 0.5 × smooth {:.3}",
                        yellow_smooth.0, yellow_smooth.1
                    ),
                );
            }
            if (textured || metal) && row != 1 {
                // transmissionTexture (R) and metalness (B) stripes: opaque where the texture is
                // dark or the surface metallic, clear elsewhere. (An opaque metal front still
                // mirrors other parts of the backdrop, which correlate a little by chance.)
                let (kc, ko) = (slope(d, d0, &clear), slope(d, d0, &opaque));
                if textured && metal {
                    // Both stripe patterns: light passes only where both walls are clear, about a
                    // quarter of the clear front pixels, too few here for a robust slope. The
                    // opaque front must still hide the backdrop.
                    check(
                        opaque.len() >= n_min && ko.abs() < 0.1,
                        format!(
                            "{what}: hides the backdrop where opaque or metallic ({} px, |slope| {:.3} < 0.1)",
                            opaque.len(),
                            ko.abs()
                        ),
                    );
                } else {
                    check(
                        clear.len() >= n_min
                            && opaque.len() >= n_min
                            && kc > 0.1
                            && ko.abs() < 0.4 * kc,
                        format!(
                            "{what}: transmits where its texture lets it ({} px, slope {kc:.3} > 0.1), not elsewhere ({} px, |slope| {:.3} < 0.4 × that)",
                            clear.len(),
                            opaque.len(),
                            ko.abs()
                        ),
                    );
                }
            }
            if masked {
                // Alpha MASK: where both walls are holes the backdrop shows untinted.
                let per: Vec<f32> = (0..3)
                    .map(|c| slope(&d_ch[c], &d0_ch[c], &through))
                    .collect();
                let r = correlation(&d_ch[3], &d0_ch[3], &through);
                let (lo, hi) = per
                    .iter()
                    .fold((f32::MAX, 0.0f32), |(l, h), &v| (l.min(v), h.max(v)));
                check(
                    through.len() >= n_min && lo > 0.45 && lo > 0.6 * hi && r > 0.85,
                    format!(
                        "{what}: backdrop through the cut-out holes ({} px): slopes per channel {per:.2?} > 0.45, untinted (min/max > 0.6), correlation {r:.2} > 0.85",
                        through.len()
                    ),
                );
            } else {
                check(
                    through.is_empty(),
                    format!(
                        "{what}: opaque alpha mode, {} pixels see through",
                        through.len()
                    ),
                );
            }
        }
    }
    assert!(failures.is_empty(), "TransmissionTest: {failures:#?}");
}

/// DamagedHelmet under the studio HDR: its smooth metal (the visor, the metal plates) mirrors the
/// environment. At each pixel the mirror direction of the camera ray about the (normal-mapped)
/// shading normal of the ray caster's `normals` view is looked up in the HDR: over the smooth
/// metal, the rendered radiance follows that radiance (log-log correlation), while over the rough
/// dielectric, which averages the environment over a hemisphere, it hardly does. Pixels are
/// classed by the metallicRoughness texture at the ray caster's `uv`; glowing pixels (emissive
/// texture) are left out.
#[test]
fn damaged_helmet_metal_mirrors_the_studio_hdr() {
    use trayecto::light::EnvMap;
    use trayecto::math::{Mat3, Vec2};
    let scene = sample_scene("DamagedHelmet");
    let env_path = common::shared_scene("hdr/studio_small_03_1k.hdr");
    let map = EnvMap::load(&env_path, Vec3::ONE, Mat3::IDENTITY).unwrap();
    let mut world = World::build(
        scene.clone(),
        &WorldOptions {
            env: Some(env_path),
            ..WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..Default::default()
            }
        },
    )
    .unwrap();
    // Face on and closer than the automatic camera, which leaves most of the frame to the
    // background.
    let n = 128u32;
    world.camera = orbit_camera(world.bounds, 0.0, 0.0);
    world.camera.vfov_deg *= 0.6;
    let settings = RenderSettings {
        width: n,
        height: n,
        spp: 16,
        path: trayecto::integrator::path::PathSettings {
            max_depth: 6,
            ..Default::default()
        },
        ..Default::default()
    };
    let img = common::render_world(&world, &settings);
    dump_image("DamagedHelmet_hdr", &img);
    let uv = raycast(&world, n, n, 1, Aov::Uv);
    let normals = raycast(&world, n, n, 1, Aov::Normals);
    let depth = raycast(&world, n, n, 1, Aov::Depth);
    let camera = trayecto::camera::Camera::new(&world.camera, n, n);
    let mat = &scene.materials[0];
    let look = |r: &Option<trayecto::material::TextureRef>, i: usize| {
        let p = uv.data[i];
        scene.textures[r.as_ref().unwrap().texture].lookup(Vec2::new(p.x, p.y))
    };
    let lum = |c: Vec3| 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
    // (ln rendered, ln HDR in the mirror direction) per class.
    let (mut mirror, mut diffuse) = (Vec::new(), Vec::new());
    for i in 0..(n * n) as usize {
        if depth.data[i].x <= 0.0 || look(&mat.emissive_texture, i).truncate().max_element() > 0.02
        {
            continue;
        }
        let mr = look(&mat.metallic_roughness_texture, i);
        let (rough, metal) = (mat.roughness * mr.y, mat.metallic * mr.z);
        let film = Vec2::new((i as u32 % n) as f32 + 0.5, (i as u32 / n) as f32 + 0.5);
        let d = camera.generate_ray(film, Vec2::splat(0.5)).d.normalize();
        let mut ns = (normals.data[i] * 2.0 - Vec3::ONE).normalize();
        if ns.dot(d) > 0.0 {
            ns = -ns;
        }
        let r = d - ns * (2.0 * d.dot(ns));
        let pair = (
            (lum(img.data[i]) + 1e-3).ln(),
            (lum(map.eval(r)) + 1e-3).ln(),
        );
        if metal > 0.8 && rough < 0.35 {
            mirror.push(pair);
        } else if metal < 0.2 && rough > 0.6 {
            diffuse.push(pair);
        }
    }
    let corr = |v: &[(f32, f32)]| {
        let a: Vec<f32> = v.iter().map(|p| p.0).collect();
        let b: Vec<f32> = v.iter().map(|p| p.1).collect();
        let idx: Vec<usize> = (0..v.len()).collect();
        correlation(&a, &b, &idx)
    };
    let (cm, cd) = (corr(&mirror), corr(&diffuse));
    eprintln!(
        "log-log correlation of radiance with the HDR in the mirror direction: {cm:.3} over {} smooth-metal pixels, {cd:.3} over {} rough-dielectric pixels",
        mirror.len(),
        diffuse.len()
    );
    assert!(
        mirror.len() > 200 && diffuse.len() > 100,
        "{} smooth-metal, {} rough-dielectric pixels",
        mirror.len(),
        diffuse.len()
    );
    assert!(
        cm > 0.4 && cm > cd + 0.25,
        "the smooth metal does not mirror the environment: correlation {cm:.3} (rough dielectric {cd:.3})"
    );
}
