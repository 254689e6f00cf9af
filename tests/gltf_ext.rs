//! glTF material extensions beyond the core: each is read (no "not supported"
//! warning), files that require it load, malformed values are errors naming the file, and a
//! rendered check fails when the extension is ignored.

mod common;

use std::path::Path;
use trayecto::material::Material;
use trayecto::math::{Vec3, luminance};
use trayecto::render::RenderSettings;
use trayecto::scene::{Scene, gltf};
use trayecto::world::{World, WorldOptions};

/// A one-triangle glTF (positions only, in a data URI) with `materials` and `extra` spliced in.
fn triangle(materials: &str, extra: &str) -> String {
    use base64::Engine;
    let mut buf = Vec::new();
    for c in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        buf.extend(c.to_le_bytes());
    }
    let b64 = base64::engine::general_purpose::STANDARD.encode(&buf);
    format!(
        r#"{{"asset":{{"version":"2.0"}},
 "buffers":[{{"byteLength":36,"uri":"data:application/octet-stream;base64,{b64}"}}],
 "bufferViews":[{{"buffer":0,"byteLength":36}}],
 "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
 "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"material":0}}]}}],
 "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],
 "materials":[{materials}]{extra}}}"#
    )
}

fn load(json: &str) -> Result<Scene, trayecto::scene::SceneError> {
    gltf::load_from_bytes(json.as_bytes(), Path::new("."), "test.gltf")
}

fn unsupported(scene: &Scene) -> Vec<&String> {
    scene
        .warnings
        .iter()
        .filter(|w| w.contains("not supported"))
        .collect()
}

#[test]
fn clearcoat_is_read_and_files_requiring_it_load() {
    let json = triangle(
        r#"{"name":"varnish","extensions":{"KHR_materials_clearcoat":
            {"clearcoatFactor":0.7,"clearcoatRoughnessFactor":0.2}}}"#,
        r#","extensionsUsed":["KHR_materials_clearcoat"],"extensionsRequired":["KHR_materials_clearcoat"]"#,
    );
    let scene = load(&json).expect("a file requiring KHR_materials_clearcoat loads");
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    let m: &Material = &scene.materials[0];
    assert_eq!(
        (
            m.metallic_roughness().clearcoat,
            m.metallic_roughness().clearcoat_roughness
        ),
        (0.7, 0.2)
    );
    assert!(
        m.metallic_roughness().clearcoat_texture.is_none()
            && m.metallic_roughness().clearcoat_normal_texture.is_none()
    );

    // A required extension that nothing reads blocks the file, by name.
    let json = triangle(
        r#"{"name":"m"}"#,
        r#","extensionsUsed":["EXT_made_up"],"extensionsRequired":["EXT_made_up"]"#,
    );
    let Err(err) = load(&json) else {
        panic!("EXT_made_up blocks the file");
    };
    let msg = err.to_string();
    assert!(
        msg.contains("test.gltf") && msg.contains("'EXT_made_up'") && msg.contains("requires"),
        "{msg}"
    );

    for (bad, what) in [
        (r#"{"clearcoatFactor":"much"}"#, "clearcoatFactor"),
        (
            r#"{"clearcoatRoughnessFactor":2.5}"#,
            "clearcoatRoughnessFactor",
        ),
        (
            r#"{"clearcoatFactor":1,"clearcoatTexture":{"index":7}}"#,
            "clearcoat texture",
        ),
        (
            r#"{"clearcoatFactor":1,"clearcoatNormalTexture":{}}"#,
            "clearcoatNormal texture",
        ),
    ] {
        let json = triangle(
            &format!(r#"{{"name":"m","extensions":{{"KHR_materials_clearcoat":{bad}}}}}"#),
            "",
        );
        let err = load(&json).err().unwrap_or_else(|| panic!("{bad} loads"));
        let msg = err.to_string();
        assert!(
            msg.contains("test.gltf") && msg.contains(what),
            "{bad}: {msg}"
        );
    }
}

/// Mean luminance over the pixels where the model is (the ray caster's depth view is 0 where a
/// camera ray escapes): the uniform background would dilute any difference.
fn model_luminance(scene: &Scene, n: u32, spp: u32) -> f32 {
    use trayecto::integrator::IntegratorKind;
    use trayecto::integrator::{Aov, ShadingModel};
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let settings = |spp, integrator| RenderSettings {
        width: n,
        height: n,
        spp,
        integrator,
        ..Default::default()
    };
    let depth = common::render_world(
        &world,
        &settings(
            1,
            IntegratorKind::Raycast {
                aov: Aov::Depth,
                shading: ShadingModel::Pbr,
            },
        ),
    );
    let img = common::render_world(&world, &settings(spp, IntegratorKind::default()));
    let on: Vec<usize> = (0..img.data.len())
        .filter(|&i| depth.data[i].x > 0.0)
        .collect();
    assert!(
        on.len() > img.data.len() / 10,
        "{} pixels on the model",
        on.len()
    );
    on.iter().map(|&i| luminance(img.data[i])).sum::<f32>() / on.len() as f32
}

/// ClearcoatWicker (README): "a wicker material covered with a wrinkled plastic clearcoat". The
/// coat, its roughness and its own normal map are read; under the default white environment the
/// coat reflects its Fresnel share c·fr of the sky where the brown wicker would have absorbed
/// most of it, so the sphere is measurably brighter than with the coat removed.
#[test]
fn clearcoat_wicker_is_coated() {
    let p = common::shared_scene("gltf-ext/ClearcoatWicker/glTF/ClearcoatWicker.gltf");
    let scene = trayecto::scene::load(p.to_str().unwrap()).unwrap();
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    let m = &scene.materials[0];
    assert_eq!(m.metallic_roughness().clearcoat, 1.0);
    assert!((m.metallic_roughness().clearcoat_roughness - 0.1).abs() < 1e-6);
    assert!(
        m.metallic_roughness().clearcoat_normal_texture.is_some() && m.normal_texture.is_some()
    );
    let mut bare = scene.clone();
    bare.materials[0]
        .metallic_roughness_mut()
        .unwrap()
        .clearcoat = 0.0;
    let (with, without) = (
        model_luminance(&scene, 32, 16),
        model_luminance(&bare, 32, 16),
    );
    eprintln!("ClearcoatWicker mean luminance: coated {with}, coat removed {without}");
    assert!(
        with > 1.05 * without,
        "coated {with} is not brighter than without the coat {without}"
    );
    // The file's coat, smooth, over a black base: its albedo is its Fresnel share exactly.
    assert_coat_closed_form(
        "ClearcoatWicker's coat on a black patch",
        m.metallic_roughness().clearcoat,
    );
    assert_coat_closed_form("a coat of factor 0.5 on a black patch", 0.5);
}

/// Linear RGB of the pixels where the model is, rendered by the path tracer under `opts`'
/// lighting (the ray caster's depth view masks the background, as in [`model_luminance`]).
fn model_pixels(
    scene: &Scene,
    opts: &WorldOptions,
    n: u32,
    spp: u32,
    seed: u64,
) -> Vec<trayecto::math::Vec3> {
    use trayecto::integrator::IntegratorKind;
    use trayecto::integrator::{Aov, ShadingModel};
    let world = World::build(scene.clone(), opts).unwrap();
    let settings = |spp, integrator| RenderSettings {
        width: n,
        height: n,
        spp,
        seed,
        integrator,
        ..Default::default()
    };
    // The mask does not depend on `seed`, so renders with different seeds compare pixel by pixel.
    let depth = common::render_world(
        &world,
        &RenderSettings {
            seed: 0,
            ..settings(
                1,
                IntegratorKind::Raycast {
                    aov: Aov::Depth,
                    shading: ShadingModel::Pbr,
                },
            )
        },
    );
    let img = common::render_world(&world, &settings(spp, IntegratorKind::default()));
    let on: Vec<_> = (0..img.data.len())
        .filter(|&i| depth.data[i].x > 0.0)
        .map(|i| img.data[i])
        .collect();
    assert!(
        on.len() > img.data.len() / 20,
        "{} pixels on the model",
        on.len()
    );
    on
}

/// The studio environment map: light that varies with direction, so lobe shapes show.
fn studio() -> WorldOptions {
    WorldOptions {
        env: Some(common::shared_scene("hdr/studio_small_03_1k.hdr")),
        ..WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..Default::default()
        }
    }
}

/// The render of `scene` has a different pattern from the render of `bare` (the extension
/// stripped), even where the mean over the model does not move: with three independent seeds,
/// the mean squared per-pixel difference of displayed luminance (clamped to [0, 1], as a screen
/// shows it, so that reflections of the map's lamps do not make it all fireflies) between `scene`
/// and `bare` exceeds the one between two seeds of `scene` (pure noise) by more than `z` standard
/// errors.
fn assert_extension_changes_the_pattern(
    what: &str,
    scene: &Scene,
    bare: &Scene,
    opts: &WorldOptions,
    n: u32,
    spp: u32,
    z: f64,
) {
    let a = model_pixels(scene, opts, n, spp, 0);
    let a2 = model_pixels(scene, opts, n, spp, 1);
    let b = model_pixels(bare, opts, n, spp, 2);
    let d = |c: &trayecto::math::Vec3| luminance(*c).clamp(0.0, 1.0) as f64;
    // Per pixel: (a − b)² − (a − a2)², whose mean is the squared change the extension makes.
    let x: Vec<f64> = (0..a.len())
        .map(|i| (d(&a[i]) - d(&b[i])).powi(2) - (d(&a[i]) - d(&a2[i])).powi(2))
        .collect();
    let m = x.iter().sum::<f64>() / x.len() as f64;
    let var = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (x.len() - 1) as f64;
    let se = (var / x.len() as f64).sqrt();
    eprintln!("{what}: squared change {m:.5}, standard error {se:.5}");
    assert!(
        m > z * se,
        "{what}: the extension changes the image by {m} (squared), within {z} standard errors ({se})"
    );
}

/// The render of `scene` differs from the render of `bare` (the extension stripped, rendered
/// with another seed): the mean over the model's pixels of the per-pixel difference of displayed
/// luminance is more than `z` standard errors from zero (the error from the spread of those
/// differences; pixels' noise is independent). Returns the mean difference (with − stripped).
fn assert_extension_changes_the_image(
    what: &str,
    scene: &Scene,
    bare: &Scene,
    opts: &WorldOptions,
    n: u32,
    spp: u32,
    z: f64,
) -> f64 {
    let a = model_pixels(scene, opts, n, spp, 0);
    let b = model_pixels(bare, opts, n, spp, 1);
    let d = |c: &trayecto::math::Vec3| luminance(*c).clamp(0.0, 1.0) as f64;
    let x: Vec<f64> = a.iter().zip(&b).map(|(p, q)| d(p) - d(q)).collect();
    let m = x.iter().sum::<f64>() / x.len() as f64;
    let var = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (x.len() - 1) as f64;
    let se = (var / x.len() as f64).sqrt();
    eprintln!("{what}: mean(with − stripped) {m:.5}, standard error {se:.5}");
    assert!(
        m.abs() > z * se,
        "{what}: the extension changes the mean by {m}, within {z} standard errors ({se})"
    );
    m
}

/// A flat patch (a 100 × 100 quad at z = 0: normal +z, tangent +x along its first edge) of
/// `material`, seen from `view_deg` off the normal (from +x) through a 2° field of view and lit
/// by `light`: per pixel linear RGB of the 8 × 8 image (`spp` samples). A white sky of
/// radiance 1 makes every pixel the material's directional albedo at that view; a directional
/// light of irradiance 1 makes it f(ωo, ωi)·cos θi.
fn patch(
    material: Material,
    light: trayecto::scene::LightDesc,
    view_deg: f32,
    spp: u32,
) -> Vec<Vec3> {
    patch_in(material, light, view_deg, spp, false)
}

/// [`patch`], rendered spectrally when `spectral` (a radiance-1 sky is then D65 at luminance 1).
fn patch_in(
    material: Material,
    light: trayecto::scene::LightDesc,
    view_deg: f32,
    spp: u32,
    spectral: bool,
) -> Vec<Vec3> {
    use trayecto::math::Mat4;
    use trayecto::scene::{CameraDesc, Shape};
    let mut s = Scene::default();
    s.textures.clear();
    let m = s.add_material(material);
    s.add_object(
        "patch",
        Shape::Quad {
            corner: Vec3::new(-50.0, -50.0, 0.0),
            e1: Vec3::new(100.0, 0.0, 0.0),
            e2: Vec3::new(0.0, 100.0, 0.0),
        },
        Mat4::IDENTITY,
        m,
    );
    s.lights.push(light);
    let a = view_deg.to_radians();
    s.cameras.push(CameraDesc::look_at(
        "c",
        Vec3::new(3.0 * a.sin(), 0.0, 3.0 * a.cos()),
        Vec3::ZERO,
        Vec3::Y,
        2.0,
    ));
    let world = World::build(
        s,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let mut settings = RenderSettings {
        width: 8,
        height: 8,
        spp,
        ..Default::default()
    };
    settings.path.spectral = spectral;
    common::render_world(&world, &settings).data
}

fn white_sky() -> trayecto::scene::LightDesc {
    trayecto::scene::LightDesc::Ambient {
        name: "sky".into(),
        radiance: Vec3::ONE,
    }
}

/// (mean, standard error of the mean) of the pixels: the pixels' spread is the render's own
/// measured noise, so a tolerance of a few standard errors is the noise floor of that render.
fn mean_se(px: &[Vec3]) -> (Vec3, Vec3) {
    let n = px.len() as f32;
    let m = px.iter().copied().sum::<Vec3>() / n;
    let var = px.iter().map(|p| (*p - m) * (*p - m)).sum::<Vec3>() / (n - 1.0);
    let v = var / n;
    (m, Vec3::new(v.x.sqrt(), v.y.sqrt(), v.z.sqrt()))
}

/// Asserts `got` = `want` per channel within 4 standard errors of the render's noise plus
/// `model` (the error of the prediction itself: a table's interpolation, a footprint's spread).
fn assert_close(what: &str, px: &[Vec3], want: Vec3, model: f32) {
    let (got, se) = mean_se(px);
    let tol = se * 4.0 + Vec3::splat(model);
    eprintln!("{what}: {got:?}, closed form {want:?}, standard error {se:?}");
    assert!(
        (got - want).abs().cmple(tol).all(),
        "{what}: rendered {got:?}, closed form {want:?} (tolerance {tol:?})"
    );
}

/// A metallic-roughness material from glTF `pbrMetallicRoughness` and `extensions` JSON (the
/// loader builds it, as for a file).
fn gltf_material(pbr: &str, extensions: &str, extra: &str) -> Material {
    let json = triangle(
        &format!(
            r#"{{"name":"m","doubleSided":true,"pbrMetallicRoughness":{pbr},"extensions":{{{extensions}}}{extra}}}"#
        ),
        "",
    );
    let scene = load(&json).unwrap();
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    scene.materials[0].clone()
}

/// A black base that reflects nothing (no diffuse, KHR_materials_specular 0): under it only the
/// layer under test shows.
const BLACK_BASE: &str = r#"{"baseColorFactor":[0,0,0,1],"metallicFactor":0,"roughnessFactor":1}"#;
const NO_SPECULAR: &str = r#""KHR_materials_specular":{"specularFactor":0}"#;

/// The coat's Fresnel share: glTF's c·(F0 + (1 − F0)(1 − cos θ)⁵), F0 = 0.04.
fn coat_share(c: f32, view_deg: f32) -> f32 {
    c * (0.04 + 0.96 * (1.0 - view_deg.to_radians().cos()).powi(5))
}

/// The smooth coat `coat` (factor, from a file or a test) over a black base under a white sky,
/// seen 60° off the normal: the coat's albedo is exactly its Fresnel share c·fr (the delta lobe
/// reflects the sky into the camera with weight c·fr; the base adds nothing). The path chooses
/// between the coat and the base at random: 4 standard errors of that noise, plus the 2°
/// footprint's spread of fr (< 2e-4).
fn assert_coat_closed_form(what: &str, c: f32) {
    let m = gltf_material(
        BLACK_BASE,
        &format!(
            r#"{NO_SPECULAR},"KHR_materials_clearcoat":{{"clearcoatFactor":{c},"clearcoatRoughnessFactor":0}}"#
        ),
        "",
    );
    assert_close(
        what,
        &patch(m, white_sky(), 60.0, 256),
        Vec3::splat(coat_share(c, 60.0)),
        2e-4,
    );
}

/// The sheen albedo c·E(μ) of a white Charlie lobe (`trayecto::material::sheen::albedo`, the
/// table the BSDF tests check against quadrature), and the closed form of the glTF layering
/// under a white sky over a white Lambertian base: c·E(μo) + 2∫₀¹ (1 − max(c)·max(E(μo), E(μ)))
/// μ dμ (the base scaled by min(1 − max(c)E(μo), 1 − max(c)E(μi)), integrated over a cosine).
fn sheen_closed_forms(color: Vec3, roughness: f32, view_deg: f32) -> (Vec3, Vec3) {
    let e = |mu: f32| trayecto::material::sheen::albedo(mu, roughness);
    let eo = e(view_deg.to_radians().cos());
    let cmax = color.max_element();
    let n = 2000;
    let base: f32 = (0..n)
        .map(|i| {
            let mu = (i as f32 + 0.5) / n as f32;
            2.0 * (1.0 - cmax * eo.max(e(mu))) * mu / n as f32
        })
        .sum();
    (color * eo, color * eo + Vec3::splat(base))
}

/// The anisotropic GGX reflection f·cos θi of a white metal (F = 1) lit by a directional light of
/// irradiance 1 from `wi`, seen along the normal: D(h)·G2/(4 cos θo) with α_t = mix(r², 1, s²)
/// along the rotated tangent and α_b = r² (KHR_materials_anisotropy), Smith height-correlated G2
/// (Heitz 2014 eq. 99), Trowbridge–Reitz D (Walter et al. 2007, anisotropic form).
fn anisotropic_metal(roughness: f32, strength: f32, rotation: f32, wi: Vec3) -> f32 {
    let ab = roughness * roughness;
    let at = ab + (1.0 - ab) * strength * strength;
    let (sr, cr) = rotation.sin_cos();
    // Into the frame whose x axis is the anisotropy direction.
    let to = |w: Vec3| Vec3::new(w.x * cr + w.y * sr, -w.x * sr + w.y * cr, w.z);
    let wo = Vec3::Z;
    let h = to((wo + wi).normalize());
    let t = (h.x / at).powi(2) + (h.y / ab).powi(2) + h.z * h.z;
    let d = 1.0 / (std::f32::consts::PI * at * ab * t * t);
    let l = to(wi);
    let lambda =
        0.5 * ((1.0 + ((at * l.x).powi(2) + (ab * l.y).powi(2)) / (l.z * l.z)).sqrt() - 1.0);
    d / (1.0 + lambda) / (4.0 * wo.z)
}

/// The direction towards a light θ off the normal at azimuth φ (degrees; 0 is the tangent +x).
fn towards(theta: f32, phi: f32) -> Vec3 {
    let (t, p) = (theta.to_radians(), phi.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

fn sun(towards_light: Vec3) -> trayecto::scene::LightDesc {
    trayecto::scene::LightDesc::Directional {
        name: "sun".into(),
        direction: -towards_light,
        irradiance: Vec3::ONE,
    }
}

/// Thin-film reflectance at normal incidence, in linear Rec.709: the exact Airy sum of a film of
/// IOR `n2` and thickness `d` nm between air and a base of IOR `n3` (amplitudes
/// r = (nᵢ − nⱼ)/(nᵢ + nⱼ), phase 4π n2 d/λ), integrated over 380–780 nm against the CIE 1931
/// colour-matching functions in Wyman, Sloan & Shirley's multi-lobe Gaussian fit (JCGT 2013,
/// eq. 2), each Rec.709 channel normalised so that a constant reflectance keeps its value. An
/// independent computation of what KHR_materials_iridescence's Fourier-space evaluation
/// approximates.
fn thin_film_rgb(n2: f64, n3: f64, d: f64) -> Vec3 {
    let g = |l: f64, mu: f64, s1: f64, s2: f64| {
        let s = if l < mu { s1 } else { s2 };
        (-0.5 * ((l - mu) / s).powi(2)).exp()
    };
    let cmf = |l: f64| {
        [
            1.056 * g(l, 599.8, 37.9, 31.0) + 0.362 * g(l, 442.0, 16.0, 26.7)
                - 0.065 * g(l, 501.1, 20.4, 26.2),
            0.821 * g(l, 568.8, 46.9, 40.5) + 0.286 * g(l, 530.9, 16.3, 31.1),
            1.217 * g(l, 437.0, 11.8, 36.0) + 0.681 * g(l, 459.0, 26.0, 13.8),
        ]
    };
    const M: [[f64; 3]; 3] = [
        [3.240_454_2, -1.537_138_5, -0.498_531_4],
        [-0.969_266_0, 1.876_010_8, 0.041_556_0],
        [0.055_643_4, -0.204_025_9, 1.057_225_2],
    ];
    let (mut num, mut den) = ([0.0f64; 3], [0.0f64; 3]);
    for l in 380..=780 {
        let l = l as f64;
        let r = thin_film_reflectance(n2, n3, d, l);
        let xyz = cmf(l);
        for ch in 0..3 {
            let w: f64 = (0..3).map(|k| M[ch][k] * xyz[k]).sum();
            num[ch] += r * w;
            den[ch] += w;
        }
    }
    Vec3::new(
        (num[0] / den[0]) as f32,
        (num[1] / den[1]) as f32,
        (num[2] / den[2]) as f32,
    )
}

/// The exact reflectance at normal incidence of a film of IOR `n2` and thickness `d` nm between
/// air and a base of IOR `n3`, at wavelength `l` nm: |r12 + r23 e^{iδ}|² / |1 + r12 r23 e^{iδ}|²
/// with r = (nᵢ − nⱼ)/(nᵢ + nⱼ) and δ = 4π n2 d/λ (Born & Wolf §1.6.4).
fn thin_film_reflectance(n2: f64, n3: f64, d: f64, l: f64) -> f64 {
    let (r12, r23) = ((1.0 - n2) / (1.0 + n2), (n2 - n3) / (n2 + n3));
    let phase = 4.0 * std::f64::consts::PI * n2 * d / l;
    let (c, s) = (phase.cos(), phase.sin());
    let top = (r12 + r23 * c).powi(2) + (r23 * s).powi(2);
    let bottom = (1.0 + r12 * r23 * c).powi(2) + (r12 * r23 * s).powi(2);
    top / bottom
}

fn shared_model(rel: &str) -> Scene {
    let p = common::shared_scene(rel);
    trayecto::scene::load(p.to_str().unwrap()).unwrap()
}

#[test]
fn bsdf_extensions_are_read_and_bad_values_name_the_file() {
    let json = triangle(
        r#"{"name":"all","extensions":{
            "KHR_materials_sheen":{"sheenColorFactor":[0.9,0.5,0.2],"sheenRoughnessFactor":0.4},
            "KHR_materials_anisotropy":{"anisotropyStrength":0.6,"anisotropyRotation":1.1},
            "KHR_materials_iridescence":{"iridescenceFactor":0.7,"iridescenceIor":1.6,
                "iridescenceThicknessMinimum":150,"iridescenceThicknessMaximum":450},
            "KHR_materials_diffuse_transmission":{"diffuseTransmissionFactor":0.3,
                "diffuseTransmissionColorFactor":[0.2,0.9,0.4]}}}"#,
        r#","extensionsUsed":["KHR_materials_sheen","KHR_materials_anisotropy","KHR_materials_iridescence","KHR_materials_diffuse_transmission"],
           "extensionsRequired":["KHR_materials_sheen","KHR_materials_anisotropy","KHR_materials_iridescence","KHR_materials_diffuse_transmission"]"#,
    );
    let scene = load(&json).expect("files requiring the BSDF extensions load");
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    let m = &scene.materials[0];
    assert_eq!(
        m.metallic_roughness().sheen_color,
        trayecto::math::Vec3::new(0.9, 0.5, 0.2)
    );
    assert_eq!(m.metallic_roughness().sheen_roughness, 0.4);
    assert_eq!(
        (
            m.metallic_roughness().anisotropy,
            m.metallic_roughness().anisotropy_rotation
        ),
        (0.6, 1.1)
    );
    assert_eq!(
        (
            m.metallic_roughness().iridescence,
            m.metallic_roughness().iridescence_ior,
            m.metallic_roughness().iridescence_thickness_min,
            m.metallic_roughness().iridescence_thickness_max
        ),
        (0.7, 1.6, 150.0, 450.0)
    );
    assert_eq!(m.metallic_roughness().diffuse_transmission, 0.3);
    assert_eq!(
        m.metallic_roughness().diffuse_transmission_color,
        trayecto::math::Vec3::new(0.2, 0.9, 0.4)
    );

    // Dispersion on volumetric glass is read; on a material without transmission it is a
    // warning (it has no effect there, by the extension text).
    let json = triangle(
        r#"{"name":"flint","extensions":{"KHR_materials_transmission":{"transmissionFactor":1},
            "KHR_materials_volume":{"thicknessFactor":1},"KHR_materials_dispersion":{"dispersion":0.5}}}"#,
        r#","extensionsUsed":["KHR_materials_transmission","KHR_materials_volume","KHR_materials_dispersion"]"#,
    );
    let scene = load(&json).unwrap();
    assert_eq!(scene.materials[0].metallic_roughness().dispersion, 0.5);
    assert!(
        scene.warnings.iter().all(|w| !w.contains("dispersion")),
        "{:?}",
        scene.warnings
    );
    let json = triangle(
        r#"{"name":"paper","extensions":{"KHR_materials_dispersion":{"dispersion":0.5}}}"#,
        r#","extensionsUsed":["KHR_materials_dispersion"]"#,
    );
    let scene = load(&json).unwrap();
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("KHR_materials_dispersion has no effect")),
        "{:?}",
        scene.warnings
    );

    for (ext, bad, what) in [
        (
            "KHR_materials_sheen",
            r#"{"sheenRoughnessFactor":2}"#,
            "sheenRoughnessFactor",
        ),
        (
            "KHR_materials_sheen",
            r#"{"sheenColorFactor":[1,2]}"#,
            "sheenColorFactor",
        ),
        (
            "KHR_materials_sheen",
            r#"{"sheenColorTexture":{"index":9}}"#,
            "sheenColor texture",
        ),
        (
            "KHR_materials_anisotropy",
            r#"{"anisotropyStrength":"x"}"#,
            "anisotropyStrength",
        ),
        (
            "KHR_materials_iridescence",
            r#"{"iridescenceIor":-1}"#,
            "iridescenceIor",
        ),
        (
            "KHR_materials_iridescence",
            r#"{"iridescenceThicknessMaximum":1e30}"#,
            "iridescenceThicknessMaximum",
        ),
        (
            "KHR_materials_dispersion",
            r#"{"dispersion":-3}"#,
            "dispersion",
        ),
        (
            "KHR_materials_diffuse_transmission",
            r#"{"diffuseTransmissionColorFactor":[0.5,0.5,"z"]}"#,
            "diffuseTransmissionColorFactor",
        ),
    ] {
        let json = triangle(
            &format!(r#"{{"name":"m","extensions":{{"{ext}":{bad}}}}}"#),
            "",
        );
        let err = load(&json).err().unwrap_or_else(|| panic!("{bad} loads"));
        let msg = err.to_string();
        assert!(
            msg.contains("test.gltf") && msg.contains(what),
            "{bad}: {msg}"
        );
    }
}

/// KHR_materials_unlit, as Trayecto defines it for a path tracer: the surface shows its base
/// colour as radiance and reflects nothing, so under the default white environment every pixel
/// of an unlit triangle is exactly its base colour (a lit one would be shaded by it).
#[test]
fn unlit_shows_its_base_colour() {
    let json = triangle(
        r#"{"name":"flat","pbrMetallicRoughness":{"baseColorFactor":[0.8,0.3,0.1,1]},"doubleSided":true,
            "extensions":{"KHR_materials_unlit":{}}}"#,
        r#","extensionsUsed":["KHR_materials_unlit"]"#,
    );
    let scene = load(&json).unwrap();
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    assert_eq!(
        scene.materials[0].model,
        trayecto::material::MaterialModel::Unlit
    );
    // Pixels wholly inside the triangle are exactly the base colour (edge pixels blend with the
    // white sky through the pixel filter).
    let want = trayecto::math::Vec3::new(0.8, 0.3, 0.1);
    let exact = |px: &[trayecto::math::Vec3]| {
        px.iter()
            .filter(|c| (**c - want).abs().max_element() < 1e-3)
            .count() as f32
            / px.len() as f32
    };
    let px = model_pixels(
        &scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
        24,
        4,
        0,
    );
    assert!(
        exact(&px) > 0.5,
        "{} of the pixels show the base colour",
        exact(&px)
    );
    let mut lit = scene.clone();
    lit.materials[0].model = trayecto::material::MaterialModel::metallic_roughness();
    let px = model_pixels(
        &lit,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
        24,
        4,
        0,
    );
    assert!(
        exact(&px) < 0.05,
        "lit: {} of the pixels are the base colour",
        exact(&px)
    );
}

/// SheenCloth (README: a fabric with a sheen layer): the sheen colour and roughness textures are
/// read and change the render by far more than noise. (Brighter is not the extension's promise:
/// its albedo scaling removes max3(sheen colour)·E from the base, so a saturated sheen over a
/// brighter base can lower the luminance; the BSDF tests check the layer's energy directly.)
#[test]
fn sheen_cloth_is_sheened() {
    let scene = shared_model("gltf-ext/SheenCloth/glTF/SheenCloth.gltf");
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    let i = scene
        .materials
        .iter()
        .position(|m| m.metallic_roughness().sheen_color.max_element() > 0.0)
        .expect("a sheen material");
    let m = &scene.materials[i];
    assert!(
        m.metallic_roughness().sheen_color_texture.is_some()
            && m.metallic_roughness().sheen_roughness_texture.is_some()
    );
    let mut bare = scene.clone();
    bare.materials[i]
        .metallic_roughness_mut()
        .unwrap()
        .sheen_color = trayecto::math::Vec3::ZERO;
    assert_extension_changes_the_image(
        "SheenCloth",
        &scene,
        &bare,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
        40,
        64,
        4.0,
    );
    // The file's sheen roughness, in a saturated colour, on a flat patch under a white sky, 60°
    // off the normal: over a black base the albedo is c·E(μ); over a white one, the glTF
    // layering's closed form (see `sheen_closed_forms`). The table interpolates E to < 2e-3.
    let r = m.metallic_roughness().sheen_roughness;
    let color = Vec3::new(0.9, 0.5, 0.2);
    let (on_black, on_white) = sheen_closed_forms(color, r, 60.0);
    let sheen = format!(
        r#""KHR_materials_sheen":{{"sheenColorFactor":[0.9,0.5,0.2],"sheenRoughnessFactor":{r}}}"#
    );
    let black = gltf_material(BLACK_BASE, &format!("{NO_SPECULAR},{sheen}"), "");
    assert_close(
        "sheen on black",
        &patch(black, white_sky(), 60.0, 256),
        on_black,
        2e-3,
    );
    let white = gltf_material(
        r#"{"baseColorFactor":[1,1,1,1],"metallicFactor":0,"roughnessFactor":1}"#,
        &format!("{NO_SPECULAR},{sheen}"),
        "",
    );
    assert_close(
        "sheen on white",
        &patch(white, white_sky(), 60.0, 256),
        on_white,
        2e-3,
    );
}

/// ToyCar: clearcoat, transmission and sheen (red fabric) are all read without a warning.
#[test]
fn toy_car_loads_without_unsupported_material_warnings() {
    let scene = shared_model("gltf-ext/ToyCar/glTF/ToyCar.gltf");
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    let fabric = scene.materials.iter().find(|m| m.name == "Fabric").unwrap();
    assert_eq!(
        fabric.metallic_roughness().sheen_color,
        trayecto::math::Vec3::new(1.0, 0.0, 0.0)
    );
    assert_eq!(fabric.metallic_roughness().sheen_roughness, 0.5);
    let glass =
        shared_model("gltf-ext/GlassHurricaneCandleHolder/glTF/GlassHurricaneCandleHolder.gltf");
    assert!(unsupported(&glass).is_empty(), "{:?}", glass.warnings);
}

/// AnisotropyStrengthTest (README: spheres of increasing roughness × anisotropy strength). Under
/// the studio map, the render with the extension differs from the render with it stripped by
/// far more than the difference between two seeds of the same render.
#[test]
fn anisotropy_strength_test_stretches_reflections() {
    let scene = shared_model("gltf-ext/AnisotropyStrengthTest/glTF/AnisotropyStrengthTest.gltf");
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    assert!(
        scene
            .materials
            .iter()
            .any(|m| m.metallic_roughness().anisotropy == 1.0)
    );
    let mut bare = scene.clone();
    for m in &mut bare.materials {
        if let Some(x) = m.metallic_roughness_mut() {
            x.anisotropy = 0.0;
        }
    }
    assert_extension_changes_the_pattern(
        "AnisotropyStrengthTest",
        &scene,
        &bare,
        &studio(),
        96,
        64,
        4.0,
    );
    // The lobe itself: a white metal patch of roughness 0.5 at strength 1 and 0.6, rotated 0 and
    // 90°, lit 40° off the normal along the tangent and along the bitangent and seen along the
    // normal: f·cos θi against the closed form (one delta light, no sky: deterministic; the
    // 2° footprint moves h, < 1 % measured). A rotated tangent frame swaps the two azimuths.
    for strength in [1.0f32, 0.6] {
        for rotation in [0.0f32, std::f32::consts::FRAC_PI_2] {
            let m = gltf_material(
                r#"{"baseColorFactor":[1,1,1,1],"metallicFactor":1,"roughnessFactor":0.5}"#,
                &format!(
                    r#""KHR_materials_anisotropy":{{"anisotropyStrength":{strength},"anisotropyRotation":{rotation}}}"#
                ),
                "",
            );
            for phi in [0.0f32, 90.0] {
                let wi = towards(40.0, phi);
                let want = anisotropic_metal(0.5, strength, rotation, wi);
                let (got, _) = mean_se(&patch(m.clone(), sun(wi), 0.0, 4));
                eprintln!(
                    "anisotropic metal s {strength} rotation {rotation} light at {phi}°: {got:?}, closed form {want}"
                );
                assert!(
                    (got - Vec3::splat(want)).abs().max_element() < 0.01 * want,
                    "strength {strength}, rotation {rotation}, light at azimuth {phi}°: {got:?}, closed form {want}"
                );
            }
        }
    }
}

/// IridescenceSuzanne (README: thin-film iridescence on Suzanne). Under the studio map the film
/// colours the reflections: the mean chroma (max − min channel) of the model's pixels, as a
/// screen shows them (each channel clamped to [0, 1], so that reflections of the map's lamps do
/// not turn it into a count of fireflies: unclamped, one seed's chroma varied 0.13–0.52 at 32 spp),
/// rises over the render with the extension stripped, by a margin, on every one of four seeds.
#[test]
fn iridescence_suzanne_is_iridescent() {
    let scene = shared_model("gltf-ext/IridescenceSuzanne/glTF/IridescenceSuzanne.gltf");
    let mut bare = scene.clone();
    for m in &mut bare.materials {
        if let Some(x) = m.metallic_roughness_mut() {
            x.iridescence = 0.0;
        }
    }
    let chroma = |px: &[trayecto::math::Vec3]| {
        let one = trayecto::math::Vec3::ONE;
        px.iter()
            .map(|c| {
                let c = c.clamp(trayecto::math::Vec3::ZERO, one);
                c.max_element() - c.min_element()
            })
            .sum::<f32>()
            / px.len() as f32
    };
    let (n, spp) = (32, 32);
    let c = |s: &Scene, seed| chroma(&model_pixels(s, &studio(), n, spp, seed));
    let with: Vec<f32> = (0..4).map(|seed| c(&scene, seed)).collect();
    let without: Vec<f32> = (0..4).map(|seed| c(&bare, seed + 4)).collect();
    eprintln!("IridescenceSuzanne chroma: film {with:?}, stripped {without:?}");
    let (lo, hi) = (
        with.iter().cloned().fold(f32::INFINITY, f32::min),
        without.iter().cloned().fold(0.0, f32::max),
    );
    assert!(
        lo > 1.3 * hi,
        "the film does not colour the reflections: {with:?} vs stripped {without:?}"
    );
    // The film on a flat patch: a smooth black dielectric (F0 = 0.04, base IOR 1.5) under a
    // thin film seen head-on under a white sky reflects the thin-film reflectance exactly (one
    // delta path), which `thin_film_rgb` computes independently.
    assert_film_closed_form("IridescenceSuzanne's film model on a black patch", false);
}

/// The iridescent smooth black patch under a film of IOR 2.0 and 200 nm over an IOR-1.5 base,
/// seen head-on under a white sky, against [`thin_film_rgb`]'s reflectance R: the opaque patch
/// reflects R, thin-walled black glass reflects at both faces of its zero-thickness sheet,
/// 2R/(1 + R) (the tint acts on transmitted light only). Tolerance: the extension's evaluation
/// (Gaussian sensitivities in Fourier space, Airy terms m ≤ 2) differs from the exact sum by at
/// most 0.0047 per channel at this film (measured on the opaque patch, whose render is
/// deterministic; at 375 nm it is 0.031 in red, where both overshoot the film's physical maximum
/// 0.207, so that film is not used): FILM_GAP, doubled through the sheet's 2R/(1 + R), plus 4
/// standard errors of the render's noise (the glass chooses reflection or transmission at random).
/// A phase off by π, or an optical path without its factor 2, moves a channel by more than 0.04.
fn assert_film_closed_form(what: &str, glass: bool) {
    let pbr = r#"{"baseColorFactor":[0,0,0,1],"metallicFactor":0,"roughnessFactor":0}"#;
    let film = r#""KHR_materials_iridescence":{"iridescenceFactor":1,"iridescenceIor":2.0,"iridescenceThicknessMinimum":200,"iridescenceThicknessMaximum":200}"#;
    let r = thin_film_rgb(2.0, 1.5, 200.0);
    let (ext, want, gap, spp) = if glass {
        (
            format!(r#"{film},"KHR_materials_transmission":{{"transmissionFactor":1}}"#),
            r * 2.0 / (Vec3::ONE + r),
            2.0 * FILM_GAP,
            256,
        )
    } else {
        (film.to_string(), r, FILM_GAP, 4)
    };
    let m = gltf_material(pbr, &ext, "");
    assert!(m.thin_walled || !glass);
    assert_close(what, &patch(m, white_sky(), 0.0, spp), want, gap);
}

const FILM_GAP: f32 = 0.01;

/// Spectral mode evaluates the film's Airy reflectance at each sampled wavelength: the smooth
/// black patch under a film of IOR 2.0 over an IOR-1.5 base, seen head-on under a white sky
/// (D65 in spectral mode), must render the exact reflectance R(λ) ([`thin_film_reflectance`])
/// seen under D65 and projected to linear sRGB (`spectrum::reflectance_to_rgb`, the renderer's
/// CIE 1931 tables) within 4 standard errors of the render's colour noise plus 0.001 (f32
/// sums; measured at most 0.0004 off). The RGB evaluation (Fourier-space integration, m ≤ 2,
/// Gaussian sensitivity fits, the m = 0 term taken as white) is measured 0.0083 (200 nm),
/// 0.018 (375 nm) and 0.0098 (600 nm) off in its worst channel: it must stay more than 0.005
/// off, so that spectral mode falling back to it fails the test.
#[test]
fn iridescence_is_exact_per_wavelength_in_spectral_mode() {
    let pbr = r#"{"baseColorFactor":[0,0,0,1],"metallicFactor":0,"roughnessFactor":0}"#;
    for d in [200.0f64, 375.0, 600.0] {
        let film = format!(
            r#""KHR_materials_iridescence":{{"iridescenceFactor":1,"iridescenceIor":2.0,"iridescenceThicknessMinimum":{d},"iridescenceThicknessMaximum":{d}}}"#
        );
        let want = trayecto::spectrum::reflectance_to_rgb(|l| {
            thin_film_reflectance(2.0, 1.5, d, l as f64) as f32
        });
        let m = gltf_material(pbr, &film, "");
        let spectral = patch_in(m.clone(), white_sky(), 0.0, 64, true);
        let (rgb, _) = mean_se(&patch(m, white_sky(), 0.0, 4));
        let rgb_gap = (rgb - want).abs().max_element();
        eprintln!("film 2.0 / {d} nm: RGB evaluation {rgb:?}, off by {rgb_gap}");
        assert_close(
            &format!("spectral film 2.0 / {d} nm"),
            &spectral,
            want,
            0.001,
        );
        assert!(rgb_gap > 0.005, "film {d} nm: RGB {rgb:?} vs {want:?}");
    }
}

/// IridescenceSuzanne's right-hand Suzanne is glass (transmission 1, volume) under a thin film
/// of varying thickness: it loads without any unsupported-material warning, and the film colours
/// the glass. The other two Suzannes are made black (unlit, black), so the mean chroma of the
/// model's pixels comes from the glass alone; with the film it must beat the render with the
/// glass's film stripped on both seeds (the test fails if the transmissive component ignores
/// KHR_materials_iridescence).
#[test]
fn iridescence_suzanne_glass_is_iridescent() {
    let mut scene = shared_model("gltf-ext/IridescenceSuzanne/glTF/IridescenceSuzanne.gltf");
    assert!(
        unsupported(&scene).is_empty(),
        "IridescenceSuzanne: {:?}",
        scene.warnings
    );
    let mut glass = 0;
    for m in &mut scene.materials {
        if m.transmission > 0.0 {
            glass += 1;
            assert!(m.metallic_roughness().iridescence > 0.0 && !m.thin_walled);
        } else {
            m.model = trayecto::material::MaterialModel::Unlit;
            m.base_color = trayecto::math::Vec3::ZERO;
            m.base_color_texture = None;
        }
    }
    assert_eq!(glass, 1);
    let mut bare = scene.clone();
    for m in &mut bare.materials {
        if let Some(x) = m.metallic_roughness_mut() {
            x.iridescence = 0.0;
        }
    }
    let chroma = |px: &[trayecto::math::Vec3]| {
        px.iter()
            .map(|c| {
                let c = c.clamp(trayecto::math::Vec3::ZERO, trayecto::math::Vec3::ONE);
                c.max_element() - c.min_element()
            })
            .sum::<f32>()
            / px.len() as f32
    };
    let (n, spp) = (48, 128);
    let c = |s: &Scene, seed| chroma(&model_pixels(s, &studio(), n, spp, seed));
    let (with, with2, without, without2) = (c(&scene, 0), c(&scene, 1), c(&bare, 0), c(&bare, 1));
    eprintln!(
        "IridescenceSuzanne glass chroma: film {with} / {with2} (two seeds), stripped {without} / {without2}"
    );
    assert!(
        with.min(with2) > 1.8 * without.max(without2),
        "the film does not colour the glass: {with}, {with2} vs stripped {without}, {without2}"
    );
    assert_film_closed_form("the film on black thin-walled glass", true);
}

/// A double-sided, thin-walled dielectric triangle (transmission 1, metallic 0) with base colour
/// `base`, roughness `rough` and the extension JSON `ext`.
fn transmissive_triangle(base: &str, rough: f32, ext: &str) -> String {
    triangle(
        &format!(
            r#"{{"name":"glass","doubleSided":true,
            "pbrMetallicRoughness":{{"baseColorFactor":{base},"metallicFactor":0,"roughnessFactor":{rough}}},
            "extensions":{{"KHR_materials_transmission":{{"transmissionFactor":1}},{ext}}}}}"#
        ),
        "",
    )
}

/// Clearcoat and sheen on a transmissive material, rendered: a thin-walled glass
/// triangle under the studio map, with each extension and with it stripped, so each case fails
/// when the transmissive component ignores its extension. Black glass (nothing transmitted)
/// shows only reflections: a smooth coat adds its own reflection (F_c + (1 − F_c)·R' instead of
/// the sheet's R'; the exact ratio is checked on the BSDF in `tests/bsdf_chi2.rs`, since here
/// the coat's GGX tails also pick up the map's lamps), and a white rough sheen adds its own
/// lobe, so both raise the mean by more than 4 standard errors.
#[test]
fn coat_and_sheen_on_transmissive_glass_change_the_render() {
    let strip = |scene: &Scene| {
        let mut bare = scene.clone();
        let b = &mut bare.materials[0];
        if let Some(x) = b.metallic_roughness_mut() {
            x.clearcoat = 0.0;
        }
        if let Some(x) = b.metallic_roughness_mut() {
            x.sheen_color = trayecto::math::Vec3::ZERO;
        }
        if let Some(x) = b.metallic_roughness_mut() {
            x.anisotropy = 0.0;
        }
        bare
    };
    let black = "[0,0,0,1]";
    for (what, ext) in [
        (
            "clearcoat",
            r#""KHR_materials_clearcoat":{"clearcoatFactor":1,"clearcoatRoughnessFactor":0}"#,
        ),
        (
            "sheen",
            r#""KHR_materials_sheen":{"sheenColorFactor":[1,1,1],"sheenRoughnessFactor":0.6}"#,
        ),
    ] {
        let scene = load(&transmissive_triangle(black, 0.0, ext)).unwrap();
        assert!(
            unsupported(&scene).is_empty(),
            "{what}: {:?}",
            scene.warnings
        );
        let m = &scene.materials[0];
        assert!(m.transmission == 1.0 && m.metallic == 0.0 && m.thin_walled);
        let bare = strip(&scene);
        let d = assert_extension_changes_the_image(
            &format!("{what} on black glass"),
            &scene,
            &bare,
            &studio(),
            32,
            32,
            4.0,
        );
        assert!(d > 0.0, "{what} darkens black glass: {d}");
    }
    // Under a white sky, 60° off the normal, smooth black glass reflects R' (its bare render,
    // deterministic: one delta path); a layer of albedo a(μo) over it gives a + (1 − a)·R'
    // (the coat: a = c·fr exactly; the sheen: a = c·E(μo), whose scaling of a delta reflection
    // is 1 − c·E(μo) at both ends).
    let bare = load(&transmissive_triangle(
        black,
        0.0,
        r#""KHR_materials_ior":{"ior":1.5}"#,
    ))
    .unwrap()
    .materials[0]
        .clone();
    let (r, _) = mean_se(&patch(bare, white_sky(), 60.0, 4));
    let coat = load(&transmissive_triangle(
        black,
        0.0,
        r#""KHR_materials_clearcoat":{"clearcoatFactor":0.8,"clearcoatRoughnessFactor":0}"#,
    ))
    .unwrap()
    .materials[0]
        .clone();
    let a = coat_share(0.8, 60.0);
    assert_close(
        "coat on black glass",
        &patch(coat, white_sky(), 60.0, 256),
        Vec3::splat(a) + (Vec3::ONE - Vec3::splat(a)) * r,
        2e-4,
    );
    let sheen = load(&transmissive_triangle(
        black,
        0.0,
        r#""KHR_materials_sheen":{"sheenColorFactor":[1,1,1],"sheenRoughnessFactor":0.6}"#,
    ))
    .unwrap()
    .materials[0]
        .clone();
    let (a, _) = sheen_closed_forms(Vec3::ONE, 0.6, 60.0);
    assert_close(
        "sheen on black glass",
        &patch(sheen, white_sky(), 60.0, 256),
        a + (Vec3::ONE - a) * r,
        2e-3,
    );
}

/// KHR_materials_anisotropy on a transmissive material, rendered: black thin-walled glass of
/// roughness 0.2 (α = 0.04) reflects the studio map through a tight lobe; strength 1 stretches it
/// to α_t = 1 along the tangent, which spreads the reflection over the map and loses energy to
/// masking, so the mean over the triangle moves by more than 4 standard errors (fails when the
/// transmissive component ignores anisotropy).
#[test]
fn anisotropy_on_transmissive_glass_changes_the_render() {
    let ext = r#""KHR_materials_anisotropy":{"anisotropyStrength":1}"#;
    let scene = load(&transmissive_triangle("[0,0,0,1]", 0.2, ext)).unwrap();
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    let mut bare = scene.clone();
    bare.materials[0]
        .metallic_roughness_mut()
        .unwrap()
        .anisotropy = 0.0;
    assert_extension_changes_the_image(
        "anisotropy on black glass",
        &scene,
        &bare,
        &studio(),
        32,
        64,
        4.0,
    );
    // The glass's reflection lobe, seen along the normal and lit 40° off it by a directional
    // light along the tangent and along the bitangent: both see the same V·H, so the Fresnel
    // factor cancels and the ratio of the two is D·G2 along α_t over D·G2 along α_b (closed
    // form, deterministic renders; < 1 % from the 2° footprint). Rotated 90°, the two swap.
    let ratio_of = |rotation: f32| {
        let ext = format!(
            r#""KHR_materials_anisotropy":{{"anisotropyStrength":0.6,"anisotropyRotation":{rotation}}}"#
        );
        let m = load(&transmissive_triangle("[0,0,0,1]", 0.5, &ext))
            .unwrap()
            .materials[0]
            .clone();
        let l = |phi: f32| {
            mean_se(&patch(m.clone(), sun(towards(40.0, phi)), 0.0, 4))
                .0
                .y
        };
        l(0.0) / l(90.0)
    };
    for rotation in [0.0f32, std::f32::consts::FRAC_PI_2] {
        let got = ratio_of(rotation);
        let want = anisotropic_metal(0.5, 0.6, rotation, towards(40.0, 0.0))
            / anisotropic_metal(0.5, 0.6, rotation, towards(40.0, 90.0));
        eprintln!(
            "anisotropic glass, rotation {rotation}: tangent / bitangent light {got}, closed form {want}"
        );
        assert!(
            (got / want - 1.0).abs() < 0.01,
            "rotation {rotation}: tangent / bitangent lit ratio {got}, closed form {want}"
        );
    }
}

/// KHR_materials_dispersion, rendered: a pinhole camera looks through a tilted slab of
/// dispersive glass (thickness 1, tilted 45°, IOR 1.5, Abbe number V = 10) at a thin white
/// emitting strip 10 units away. A slab displaces rays sideways by d(n) = t·sin θ·(1 − cos θ /
/// √(n² − sin² θ)), more for a larger n, so each channel sees the strip at its own place: the
/// centroid of each channel along the image row must be where a 2D Snell's-law trace of that
/// channel's IOR puts it (IORs from the extension's Abbe law at the channels' wavelengths,
/// computed here from the formula, not by the renderer's function), within 0.3 px for green and
/// 3 % of the predicted red–blue separation (≈ 11 px; measured: 10.87 px against 10.93 px),
/// blue displaced the most. With dispersion
/// off the separation is zero, so the test fails. (No independent renderer is compared: Cycles
/// has no dispersion and Mitsuba 3's `dielectric` takes a wavelength-independent IOR.)
#[test]
fn dispersion_separates_colours_as_the_abbe_law_predicts() {
    use trayecto::material::{Material, MaterialModel};
    use trayecto::math::{Mat4, Vec3};
    use trayecto::scene::{CameraDesc, Shape};
    let (t, tilt, n_d, abbe) = (1.0f64, 45f64.to_radians(), 1.5f64, 10.0f64);
    let (z_slab, z_strip) = (-3.0f64, -10.0f64);
    // KHR_materials_dispersion: n(λ) = n_d + (n_d − 1)/V · (523655/λ² − 1.5168); the channels'
    // wavelengths are the dominant wavelengths of the sRGB primaries.
    let ior = |lambda: f64| n_d + (n_d - 1.0) / abbe * (523_655.0 / (lambda * lambda) - 1.5168);
    let iors = [ior(611.3), ior(549.1), ior(464.3)];
    // Where a camera ray at angle φ (x = sin φ, z = −cos φ) meets the strip's plane after the
    // slab (normal N = (sin β, 0, cos β) through (0, 0, z_slab)).
    let strip_x = |phi: f64, n: f64| {
        let d = [phi.sin(), -phi.cos()];
        let nn = [tilt.sin(), tilt.cos()];
        let dot = |a: [f64; 2], b: [f64; 2]| a[0] * b[0] + a[1] * b[1];
        let c0 = z_slab * nn[1];
        let s1 = (c0 + t / 2.0) / dot(d, nn);
        let p1 = [d[0] * s1, d[1] * s1];
        let cos_i = -dot(d, nn);
        let eta = 1.0 / n;
        let cos_t = (1.0 - eta * eta * (1.0 - cos_i * cos_i)).sqrt();
        let k = eta * cos_i - cos_t;
        let dt = [eta * d[0] + k * nn[0], eta * d[1] + k * nn[1]];
        let s2 = ((c0 - t / 2.0) - dot(p1, nn)) / dot(dt, nn);
        let p2 = [p1[0] + dt[0] * s2, p1[1] + dt[1] * s2];
        let s3 = (z_strip - p2[1]) / d[1];
        p2[0] + d[0] * s3
    };
    // The strip is centred where green, looking straight ahead, sees it.
    let x_strip = strip_x(0.0, iors[1]);
    let (w, h, tan_h) = (256u32, 8u32, 0.02f64);
    let px_of = |n: f64| {
        // Bisection for the angle at which the channel sees the strip's centre.
        let (mut lo, mut hi) = (-0.1f64, 0.1f64);
        let f = |phi: f64| strip_x(phi, n) - x_strip;
        let rising = f(hi) > f(lo);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if (f(mid) > 0.0) == rising {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        (0.5 * (lo + hi)).tan() / tan_h * 0.5 * w as f64 + 0.5 * w as f64
    };
    let predicted = [px_of(iors[0]), px_of(iors[1]), px_of(iors[2])];

    let mut scene = Scene::default();
    let glass = scene.add_material(Material {
        model: MaterialModel::MetallicRoughness(trayecto::material::MetallicRoughness {
            dispersion: (20.0 / abbe) as f32,
            ..Default::default()
        }),
        base_color: Vec3::ONE,
        metallic: 0.0,
        roughness: 0.0,
        transmission: 1.0,
        ior: n_d as f32,
        ..Default::default()
    });
    let strip = scene.add_material(Material {
        model: MaterialModel::Diffuse,
        base_color: Vec3::ZERO,
        emissive: Vec3::ONE,
        ..Default::default()
    });
    scene.add_object(
        "slab",
        Shape::Cuboid {
            min: Vec3::new(-3.0, -3.0, -0.5 * t as f32),
            max: Vec3::new(3.0, 3.0, 0.5 * t as f32),
        },
        Mat4::from_translation(Vec3::new(0.0, 0.0, z_slab as f32))
            * Mat4::from_rotation_y(tilt as f32),
        glass,
    );
    let width = 0.003f32;
    scene.add_object(
        "strip",
        Shape::Quad {
            corner: Vec3::new(x_strip as f32 - 0.5 * width, -2.0, z_strip as f32),
            e1: Vec3::new(width, 0.0, 0.0),
            e2: Vec3::new(0.0, 4.0, 0.0),
        },
        Mat4::IDENTITY,
        strip,
    );
    let vfov = 2.0 * (tan_h * h as f64 / w as f64).atan().to_degrees();
    scene.cameras.push(CameraDesc::look_at(
        "cam",
        Vec3::ZERO,
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::Y,
        vfov as f32,
    ));
    scene.default_light = Some(trayecto::light::default_light::DefaultLight::Off);
    let render = |scene: &Scene| {
        let img = common::render_scene(
            scene,
            &RenderSettings {
                width: w,
                height: h,
                spp: 64,
                ..Default::default()
            },
        );
        let mut centroid = [0.0f64; 3];
        let mut total = [0.0f64; 3];
        for y in 0..h {
            for x in 0..w {
                let c = img.data[(y * w + x) as usize];
                for k in 0..3 {
                    centroid[k] += (x as f64 + 0.5) * c[k] as f64;
                    total[k] += c[k] as f64;
                }
            }
        }
        assert!(
            total.iter().all(|t| *t > 0.0),
            "the strip is not seen: {total:?}"
        );
        [
            centroid[0] / total[0],
            centroid[1] / total[1],
            centroid[2] / total[2],
        ]
    };
    let got = render(&scene);
    let (sep, want_sep) = (got[2] - got[0], predicted[2] - predicted[0]);
    eprintln!("dispersion: centroids R G B {got:?}, predicted {predicted:?}; IORs {iors:?}");
    assert!(
        (got[1] - predicted[1]).abs() < 0.3,
        "green at {} px, predicted {}",
        got[1],
        predicted[1]
    );
    assert!(
        want_sep.abs() > 5.0,
        "the set-up separates too little: {want_sep}"
    );
    assert!(
        want_sep > 0.0 && (sep - want_sep).abs() < 0.03 * want_sep,
        "blue − red centroid {sep} px, predicted {want_sep} px"
    );
    // Without dispersion every channel sees the strip where green does.
    let mut plain = scene.clone();
    plain.materials[glass]
        .metallic_roughness_mut()
        .unwrap()
        .dispersion = 0.0;
    let got = render(&plain);
    assert!(
        (got[2] - got[0]).abs() < 0.5,
        "without dispersion blue − red is {} px",
        got[2] - got[0]
    );
}

/// KHR_materials_clearcoat: the coat reflects about its own normal, whatever the base's normal
/// map does (glTF appendix B: `fresnel_coat(clearcoat_normal, …)`; the base's normal map does not
/// apply to the coat). A plane with a black, non-specular base under a clearcoat, lit by a
/// uniform sky of radiance 1, shows only the coat, so tilting the **base's** normal map by 50°
/// must not change the image. Before the coat had its own hemisphere it did: the coated BSDF
/// lived in the hemisphere of the base's normal-mapped normal and was weighed by that normal's
/// cosine, so coat reflections below the tilted base plane were lost, and a view from behind the
/// tilted base saw nothing.
#[test]
fn a_tilted_base_normal_map_leaves_the_coat_unchanged() {
    use trayecto::integrator::IntegratorKind;
    use trayecto::material::{MaterialModel, Texture, TextureRef};
    use trayecto::math::{Mat4, Vec3, Vec4};
    use trayecto::scene::{CameraDesc, LightDesc, Shape};
    let plane = |tilt_deg: f32| {
        let mut s = Scene::default();
        let mut m = Material {
            model: MaterialModel::MetallicRoughness(trayecto::material::MetallicRoughness {
                clearcoat: 1.0,
                clearcoat_roughness: 0.3,
                ..Default::default()
            }),
            base_color: Vec3::ZERO,
            metallic: 0.0,
            roughness: 1.0,
            specular: 0.0,
            ..Default::default()
        };
        if tilt_deg != 0.0 {
            // A tangent-space normal tilted towards the tangent (+x, the quad's first edge).
            let t = tilt_deg.to_radians();
            let n = Vec3::new(t.sin(), 0.0, t.cos());
            let texel = (n + Vec3::ONE) * 0.5;
            s.textures.push(Texture::constant(
                "tilt",
                Vec4::new(texel.x, texel.y, texel.z, 1.0),
            ));
            m.normal_texture = Some(TextureRef::new(0));
            m.normal_scale = 1.0;
        }
        let m = s.add_material(m);
        s.add_object(
            "plane",
            Shape::Quad {
                corner: Vec3::new(-50.0, -50.0, 0.0),
                e1: Vec3::new(100.0, 0.0, 0.0),
                e2: Vec3::new(0.0, 100.0, 0.0),
            },
            Mat4::IDENTITY,
            m,
        );
        s.lights.push(LightDesc::Ambient {
            name: "sky".into(),
            radiance: Vec3::ONE,
        });
        // Seen from 50° off the normal, from the side the base normal tilts away from.
        let a = 50f32.to_radians();
        s.cameras.push(CameraDesc::look_at(
            "c",
            Vec3::new(-3.0 * a.sin(), 0.0, 3.0 * a.cos()),
            Vec3::ZERO,
            Vec3::Z,
            20.0,
        ));
        let world = World::build(
            s,
            &WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..WorldOptions::default()
            },
        )
        .unwrap();
        let img = common::render_world(
            &world,
            &RenderSettings {
                width: 16,
                height: 16,
                spp: 64,
                integrator: IntegratorKind::default(),
                ..Default::default()
            },
        );
        img.data.iter().map(|p| luminance(*p)).sum::<f32>() / img.data.len() as f32
    };
    let flat = plane(0.0);
    // The coat's albedo at 50°: c·fr ≈ 0.04 + 0.96·(1 − cos 50°)⁵ ≈ 0.046, a little less for G2.
    assert!(flat > 0.03 && flat < 0.06, "flat {flat}");
    // 25°: the base is seen from the front, part of the coat's lobe is below its plane; 50°: the
    // base is seen from behind (only the coat can reflect).
    for tilt in [25.0, 50.0] {
        let tilted = plane(tilt);
        eprintln!("coat over a black base: flat base normal {flat}, tilted {tilt}° {tilted}");
        assert!(
            (tilted - flat).abs() < 0.02 * flat,
            "the base's normal map tilted {tilt}° changed the coat: {tilted} vs {flat}"
        );
    }
}
