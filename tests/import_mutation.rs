//! Deterministic mutation testing of every parser entry point (the in-CI stand-in for the
//! `cargo fuzz` targets under `fuzz/`): truncations and byte corruptions of real sample files must
//! give `Ok` or `Err`, never a panic. A fixed number of mutants per input (deterministic: the same
//! mutants on every machine, however loaded), sized so the whole test takes seconds.

mod common;

use std::panic::AssertUnwindSafe;
use std::path::Path;
use std::time::Instant;

/// Mutants per input file.
const MUTANTS: u64 = 3000;

/// xorshift64*: tiny, deterministic, good enough to pick positions and bytes.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// The i-th mutant of `data`: alternately a truncation, a burst of random bytes, a run of 0xff
/// (huge counts and offsets), or a digit/keyword edit for text formats.
fn mutate(data: &[u8], i: u64, rng: &mut Rng) -> Vec<u8> {
    let mut d = data.to_vec();
    match i % 4 {
        0 => d.truncate(rng.below(d.len())),
        1 => {
            for _ in 0..1 + rng.below(8) {
                let p = rng.below(d.len());
                if let Some(b) = d.get_mut(p) {
                    *b = rng.next() as u8;
                }
            }
        }
        2 => {
            let p = rng.below(d.len());
            for k in p..(p + 4).min(d.len()) {
                d[k] = 0xff;
            }
        }
        _ => {
            // Replace a digit with another (text formats: counts, indices, offsets).
            let digits: Vec<usize> = (0..d.len()).filter(|&k| d[k].is_ascii_digit()).collect();
            if !digits.is_empty() {
                let p = digits[rng.below(digits.len())];
                d[p] = b"0123456789-9e"[rng.below(13)];
            }
        }
    }
    d
}

type Parser = fn(&[u8], &Path) -> bool;

fn run(name: &str, file: &Path, parse: Parser) -> u64 {
    let data = std::fs::read(file).unwrap();
    let dir = file.parent().unwrap().to_path_buf();
    // The unmodified file must load.
    assert!(
        parse(&data, &dir),
        "{name}: the original file does not load"
    );
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15 ^ data.len() as u64);
    let start = Instant::now();
    let mut rejected = 0;
    for i in 0..MUTANTS {
        let m = mutate(&data, i, &mut rng);
        let r = std::panic::catch_unwind(AssertUnwindSafe(|| parse(&m, &dir)));
        match r {
            Ok(ok) => rejected += u64::from(!ok),
            Err(_) => panic!(
                "{name}: mutant {i} panicked (len {} of {})",
                m.len(),
                data.len()
            ),
        }
    }
    eprintln!(
        "{name}: {MUTANTS} mutants, {rejected} refused with an error, {:.2} s",
        start.elapsed().as_secs_f64()
    );
    // The mutations reach the parser: some of them must be refused.
    assert!(rejected > 0, "{name}: no mutant was refused");
    MUTANTS
}

#[test]
fn parsers_never_panic_on_mutated_inputs() {
    // scene::load_bytes parses, names and validates exactly as loading a file does.
    let gltf: Parser = |b, d| trayecto::scene::load_bytes(b, d, "m.gltf").is_ok();
    let obj: Parser = |b, d| trayecto::scene::load_bytes(b, d, "m.obj").is_ok();
    let ply: Parser = |b, d| trayecto::scene::load_bytes(b, d, "m.ply").is_ok();
    let toml: Parser = |b, d| trayecto::scene::load_bytes(b, d, "m.toml").is_ok();
    // pbrt from memory (no Include or plymesh read from disk), then the same validation.
    let pbrt: Parser = |b, _| {
        trayecto::scene::pbrt::load_from_bytes(b, "m.pbrt")
            .and_then(|s| s.validate())
            .is_ok()
    };
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/example.toml");
    let inputs: Vec<(&str, std::path::PathBuf, Parser)> = vec![
        (
            "Box.glb",
            common::scene_file("gltf/Box/glTF-Binary/Box.glb"),
            gltf,
        ),
        (
            "Box.gltf",
            common::scene_file("gltf/Box/glTF/Box.gltf"),
            gltf,
        ),
        (
            "BoxTextured.glb",
            common::scene_file("gltf/BoxTextured/glTF-Binary/BoxTextured.glb"),
            gltf,
        ),
        (
            // EXT_meshopt_compression (octahedral and exponential filters), KHR_mesh_quantization
            // and KHR_texture_transform: the meshopt decoders see corrupted streams and counts.
            "box_meshopt_filters.glb",
            Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gltf-files/box_meshopt_filters.glb"),
            gltf,
        ),
        (
            // KHR_draco_mesh_compression: the Draco decoder sees corrupted streams.
            "box_draco.glb",
            Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gltf-files/box_draco.glb"),
            gltf,
        ),
        (
            // KHR_texture_basisu: the KTX2 header checks and the UASTC/Zstandard transcoder.
            "box_ktx2_uastc.glb",
            Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gltf-files/box_ktx2_uastc.glb"),
            gltf,
        ),
        (
            "TextureCoordinateTest.gltf",
            common::scene_file("gltf/TextureCoordinateTest/glTF/TextureCoordinateTest.gltf"),
            gltf,
        ),
        (
            "gltf_bsdf_extensions.gltf",
            Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gltf_bsdf_extensions.gltf"),
            gltf,
        ),
        (
            "cornell_box.obj",
            common::scene_file("obj/cornell-box-original-data/cornell_box.obj"),
            obj,
        ),
        (
            "bun_zipper_res4.ply",
            common::scene_file("ply/stanford-bunny/bun_zipper_res4.ply"),
            ply,
        ),
        ("example.toml", example, toml),
        (
            "cornell-box/scene-v4.pbrt",
            common::scene_file("pbrt/cornell-box/scene-v4.pbrt"),
            pbrt,
        ),
    ];
    let mut total = 0;
    for (name, file, parse) in &inputs {
        total += run(name, file, *parse);
    }
    eprintln!("{total} mutants parsed without a panic");
    assert_eq!(total, MUTANTS * inputs.len() as u64);
}
