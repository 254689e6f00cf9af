//! `--denoise`: Open Image Denoise, loaded at run time, runs when installed
//! (`./scripts/install-oidn.sh`, which scripts/test.sh runs) and brings a 16-spp Cornell box
//! closer to a reference; without it the render fails before any work, naming the install command.

use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::AtomicBool;
use trayecto::denoise::{DenoiseError, DenoiseOptions, INSTALL_COMMAND, Oidn};
use trayecto::film::Image;
use trayecto::film::output::read_exr;
use trayecto::film::tonemap::Tonemap;
use trayecto::pipeline::{GivenSettings, OutputSpec, PipelineError, RenderJob, Silent};
use trayecto::render::RenderSettings;
use trayecto::world::WorldOptions;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trayecto-denoise-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn job(out: PathBuf, spp: u32, threads: usize, denoise: Option<DenoiseOptions>) -> RenderJob {
    RenderJob {
        scene: "cornell".into(),
        world: WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
        settings: RenderSettings {
            width: 64,
            height: 64,
            spp,
            seed: 7,
            threads: Some(threads),
            ..Default::default()
        },
        given: GivenSettings::ALL,
        outputs: vec![OutputSpec {
            path: out,
            exposure: 1.0,
            tonemap: Tonemap::Clamp,
        }],
        split: Default::default(),
        aovs: Vec::new(),
        denoise,
        crop: None,
    }
}

/// relMSE as bench/compare.py computes it.
fn rel_mse(x: &Image, r: &Image) -> f64 {
    let mut s = 0.0;
    for (a, b) in x.data.iter().zip(&r.data) {
        for c in 0..3 {
            let (a, b) = (a[c] as f64, b[c] as f64);
            s += (a - b) * (a - b) / (b * b + 1e-2);
        }
    }
    s / (3 * x.data.len()) as f64
}

#[test]
fn denoising_runs_and_brings_the_image_closer_to_the_reference() {
    // scripts/test.sh installs Open Image Denoise before the tests: its absence is a failure.
    if let Err(e) = Oidn::load(None) {
        panic!("Open Image Denoise is not installed ({e}): run ./scripts/install-oidn.sh");
    }
    let dir = tmp("runs");
    let stop = AtomicBool::new(false);
    let raw = dir.join("raw.exr");
    let report = job(raw.clone(), 16, 2, Some(DenoiseOptions::default()))
        .run(&Silent, &stop)
        .unwrap();
    let denoised_path = dir.join("raw.denoised.exr");
    assert_eq!(report.written, vec![raw.clone(), denoised_path.clone()]);
    // The raw image is the plain render's, bit for bit.
    let plain = dir.join("plain.exr");
    job(plain.clone(), 16, 1, None).run(&Silent, &stop).unwrap();
    let raw = read_exr(&raw).unwrap();
    assert_eq!(raw, read_exr(&plain).unwrap());
    let denoised = read_exr(&denoised_path).unwrap();
    assert!(denoised.data.iter().all(|p| p.is_finite()));
    assert_ne!(denoised, raw);
    let reference = dir.join("ref.exr");
    job(reference.clone(), 256, 2, None)
        .run(&Silent, &stop)
        .unwrap();
    let reference = read_exr(&reference).unwrap();
    let (e_raw, e_den) = (rel_mse(&raw, &reference), rel_mse(&denoised, &reference));
    println!("relMSE raw {e_raw:.5}, denoised {e_den:.5}");
    // bench/denoise.py measures a factor of 5 at 96² px; at 64² px the walls' edges weigh more
    // (at 32² px the denoised image is no better), so this asks for a factor of 2.
    assert!(
        e_den * 2.0 < e_raw,
        "denoised relMSE {e_den} is not well below the raw {e_raw}"
    );
    std::fs::remove_dir_all(dir).ok();
}

/// A library path that was given but does not exist: the pipeline refuses before loading the
/// scene (no output written) and names the install command.
#[test]
fn a_missing_library_fails_before_rendering_with_the_install_command() {
    let dir = tmp("missing");
    let out = dir.join("out.png");
    let missing = dir.join("no/libOpenImageDenoise.so");
    let e = job(
        out.clone(),
        4,
        1,
        Some(DenoiseOptions {
            library: Some(missing.clone()),
        }),
    )
    .run(&Silent, &AtomicBool::new(false))
    .unwrap_err();
    assert!(
        matches!(&e, PipelineError::Denoise(DenoiseError::Missing { path, .. }) if *path == missing),
        "{e:?}"
    );
    assert!(e.to_string().contains(INSTALL_COMMAND), "{e}");
    assert!(!out.exists());

    // The CLI, with the library named by the environment: exit status 1, the command in the
    // message, nothing rendered or written.
    let r = Command::new(env!("CARGO_BIN_EXE_trayecto"))
        .args([
            "render", "cornell", "--width", "8", "--height", "8", "--spp", "1",
        ])
        .arg("-o")
        .arg(&out)
        .arg("--denoise")
        .env("TRAYECTO_OIDN", &missing)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains(INSTALL_COMMAND), "{stderr}");
    assert!(stderr.contains("TRAYECTO_OIDN"), "{stderr}");
    assert!(!stderr.contains("rendering"), "{stderr}");
    assert!(!out.exists());
    std::fs::remove_dir_all(dir).ok();
}

/// A file that is not a library: a load error naming it, not a crash.
#[test]
fn a_file_that_is_not_a_library_is_a_clear_error() {
    let dir = tmp("bogus");
    let bogus = dir.join("libOpenImageDenoise.so");
    std::fs::write(&bogus, b"not a shared library").unwrap();
    let e = Oidn::load(Some(&bogus)).err().expect("loading must fail");
    assert!(matches!(e, DenoiseError::Load { .. }), "{e:?}");
    assert!(e.to_string().contains(&*bogus.to_string_lossy()), "{e}");
    std::fs::remove_dir_all(dir).ok();
}
