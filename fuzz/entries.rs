//! The fuzzing entry points: one function per target in `fuzz/Cargo.toml`, shared by the
//! cargo-fuzz targets (`fuzz/fuzz_targets/*.rs`, each a one-line call) and by the regression corpus
//! (`tests/hostile.rs` runs every file under `tests/hostile/<target>/` through the same
//! function), so an input that once crashed a target stays a test of exactly what crashed.
//!
//! Every entry takes what a user's file goes through and, when it loads, compiles the world
//! (`World::build`: geometry, lights, media, the BVH) — a parser that returns a scene the builder
//! cannot take is as much a crash as a parser that panics. Any input must give `Ok` or a clean
//! error; the memory limit is the fuzzer's (`scripts/fuzz.sh` passes `-rss_limit_mb` and
//! `-malloc_limit_mb`), so an input that asks for unbounded memory is a finding too.
//! docs/src/fuzzing.md says how to run the targets and how to add a regression case.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use trayecto::scene::{self, Scene, SceneError};
use trayecto::world::{World, WorldOptions};

/// A fuzzing entry point: any bytes, no result (a panic or an abort is the finding).
pub type Entry = fn(&[u8]);

/// The targets, by the names of their `[[bin]]`s in `fuzz/Cargo.toml` and of their regression
/// folders under `tests/hostile/`.
pub const TARGETS: &[(&str, Entry)] = &[
    ("gltf", gltf),
    ("obj", obj),
    ("ply", ply),
    ("toml", toml),
    ("fbx", fbx),
    ("pbrt", pbrt),
    ("mitsuba", mitsuba),
    ("meshopt", meshopt),
    ("trp", trp),
    ("envmap", envmap),
    ("mtl", mtl),
    ("vol", vol),
    ("upload", upload),
    ("request", request),
];

/// Compiles a loaded scene into a world (which builds the BVH), as `trayecto render` does; an
/// animated scene also at a moment and motion-blurred over a shutter (`--time 0.5`, `--shutter
/// 0,0.25 --shutter-steps 3`), so its keys, poses and per-segment BVHs are built from the
/// fuzzed file too.
fn build(scene: Result<Scene, SceneError>) {
    let Ok(scene) = scene else { return };
    if scene.animation.is_some() {
        for time in [
            trayecto::world::motion::TimeOptions {
                time: Some(0.5),
                ..Default::default()
            },
            trayecto::world::motion::TimeOptions {
                shutter: Some([0.0, 0.25]),
                steps: 3,
                ..Default::default()
            },
        ] {
            let options = WorldOptions {
                time,
                ..WorldOptions::default()
            };
            let _ = World::build(scene.clone(), &options);
        }
    }
    let _ = World::build(scene, &WorldOptions::default());
}

/// A fresh empty folder for one call (the process id and a counter: the regression test runs
/// cases on several threads), removed when dropped. Loaders resolve references against it, so
/// a fuzzed file naming another file finds nothing there.
struct Scratch(PathBuf);

impl Scratch {
    fn new() -> Scratch {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("trayecto-fuzz-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("a scratch folder in the temp dir");
        Scratch(dir)
    }

    /// Writes `bytes` as `name` in the folder and returns its path.
    fn file(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, bytes).expect("a file in the scratch folder");
        p
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A scene file in memory, its format chosen by `label`'s extension, read as `scene::load_file`
/// reads it (parsed, named and validated) against an empty folder, then built.
fn scene_bytes(data: &[u8], label: &str) {
    let dir = Scratch::new();
    build(scene::load_bytes(data, &dir.0, label));
}

/// glTF, JSON or binary (the loader tells them apart by the GLB magic).
pub fn gltf(data: &[u8]) {
    scene_bytes(data, "fuzz.glb");
}

pub fn obj(data: &[u8]) {
    scene_bytes(data, "fuzz.obj");
}

pub fn ply(data: &[u8]) {
    scene_bytes(data, "fuzz.ply");
}

pub fn toml(data: &[u8]) {
    scene_bytes(data, "fuzz.toml");
}

/// Binary FBX.
pub fn fbx(data: &[u8]) {
    scene_bytes(data, "fuzz.fbx");
}

/// pbrt-v4 text. `Include`, `plymesh` and image files resolve against the empty folder.
pub fn pbrt(data: &[u8]) {
    scene_bytes(data, "fuzz.pbrt");
}

/// Mitsuba 3 XML. `include`, meshes, images and volumes resolve against the empty folder.
pub fn mitsuba(data: &[u8]) {
    scene_bytes(data, "fuzz.xml");
}

/// Meshopt-compressed buffer views (EXT_/KHR_meshopt_compression): the first four bytes choose
/// the extension, mode, filter, stride and count; the rest is the compressed stream, wrapped in
/// a GLB whose one buffer view carries it and whose accessor reads the decoded positions.
pub fn meshopt(data: &[u8]) {
    if data.len() < 4 {
        return;
    }
    let (head, stream) = data.split_at(4);
    let ext = ["EXT_meshopt_compression", "KHR_meshopt_compression"][(head[0] & 1) as usize];
    let mode = ["ATTRIBUTES", "TRIANGLES", "INDICES"][(head[0] >> 1) as usize % 3];
    let filter =
        ["NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL", "COLOR"][(head[1] % 5) as usize];
    let stride = match mode {
        "ATTRIBUTES" => 4 * (1 + (head[2] as usize % 64)),
        _ => 2 << (head[2] & 1),
    };
    let count = u16::from_le_bytes([head[3], head[0] >> 4]) as usize;
    let mut bin = stream.to_vec();
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["{ext}"],
 "buffers":[{{"byteLength":{bl}}}],
 "bufferViews":[{{"buffer":0,"byteLength":{vl},"byteStride":{stride},
   "extensions":{{"{ext}":{{"buffer":0,"byteLength":{sl},"byteStride":{stride},"count":{count},"mode":"{mode}","filter":"{filter}"}}}}}}],
 "accessors":[{{"bufferView":0,"componentType":5126,"count":{ac},"type":"VEC3","min":[-1,-1,-1],"max":[1,1,1]}}],
 "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
 "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}]}}"#,
        bl = bin.len(),
        vl = count * stride,
        sl = stream.len(),
        ac = if stride >= 12 { count } else { 0 },
    );
    let mut j = json.into_bytes();
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let total = 12 + 8 + j.len() + 8 + bin.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((j.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&j);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&bin);
    gltf(&glb);
}

/// A partial film (`.trp`), as `trayecto merge` reads it: checked, merged (alone, so an
/// incomplete range is allowed) and resolved to an image.
pub fn trp(data: &[u8]) {
    let dir = Scratch::new();
    let path = dir.file("fuzz.trp", data);
    if let Ok(part) = trayecto::split::partial::Part::read(&path)
        && let Ok(merged) = trayecto::split::partial::merge(vec![(path, part)], false)
    {
        let _ = merged.film.to_image();
    }
}

/// A small scene that reaches `file` (written next to it) through the loader that reads it.
fn scene_with(dir: &Scratch, scene_name: &str, text: &str) {
    let path = dir.file(scene_name, text.as_bytes());
    build(scene::load_file(&path));
}

/// An environment map (OpenEXR, Radiance HDR or PFM, by the file's magic bytes; EXR otherwise)
/// lighting a sphere: read, checked and turned into the light's sampling distribution.
pub fn envmap(data: &[u8]) {
    let ext = if data.starts_with(b"#?") {
        "hdr"
    } else if data.starts_with(b"PF") || data.starts_with(b"Pf") {
        "pfm"
    } else {
        "exr"
    };
    let dir = Scratch::new();
    dir.file(&format!("env.{ext}"), data);
    scene_with(
        &dir,
        "env.toml",
        &format!(
            "[[camera]]\neye = [0, 0, 3]\ntarget = [0, 0, 0]\n\n\
             [[object]]\nname = \"ball\"\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1.0\n\n\
             [[light]]\nname = \"sky\"\ntype = \"environment\"\nfile = \"env.{ext}\"\n"
        ),
    );
}

/// A Wavefront material library, named by an OBJ triangle that uses a material of it.
pub fn mtl(data: &[u8]) {
    let dir = Scratch::new();
    dir.file("fuzz.mtl", data);
    scene_with(
        &dir,
        "fuzz.obj",
        "mtllib fuzz.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n\
         usemtl m\nf 1/1/1 2/2/1 3/3/1\n",
    );
}

/// A Mitsuba `.vol` grid, as the density of a grid medium inside an index-matched box.
pub fn vol(data: &[u8]) {
    let dir = Scratch::new();
    dir.file("fuzz.vol", data);
    scene_with(
        &dir,
        "fuzz.toml",
        "[[camera]]\neye = [0, 0, 3]\ntarget = [0, 0, 0]\n\n\
         [[medium]]\nname = \"fog\"\ntype = \"grid\"\nfile = \"fuzz.vol\"\n\
         sigma_a = [0.5, 0.5, 0.5]\nsigma_s = [2, 2, 2]\n\n\
         [[material]]\nname = \"boundary\"\nmodel = \"interface\"\n\n\
         [[object]]\nname = \"box\"\ntype = \"box\"\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n\
         material = \"boundary\"\nmedium_inside = \"fog\"\n",
    );
}

/// The web server's upload checker: any bytes as a `.zip` upload are accepted or refused, and an
/// accepted archive never repeats a name (case-insensitively) or puts a file where a folder goes.
pub fn upload(data: &[u8]) {
    use trayecto::server::upload::{UploadLimits, check_zip};
    let limits = UploadLimits {
        max_file: 1 << 20,
        max_unpacked: 1 << 24,
        ..UploadLimits::default()
    };
    if let Ok((entries, _)) = check_zip(data, &limits) {
        let mut lower: Vec<String> = entries.iter().map(|e| e.to_lowercase()).collect();
        lower.sort();
        for w in lower.windows(2) {
            assert!(w[0] != w[1], "a repeated entry was accepted: {}", w[0]);
            assert!(
                !w[1].starts_with(&format!("{}/", w[0])),
                "a file where a folder must go was accepted: {}",
                w[0]
            );
        }
    }
}

/// The web server's render-request parser: any body is accepted or refused field by field, and
/// an accepted request passes the renderer's own checks. Built-in scenes only (no scenes folder),
/// so no file is ever resolved.
pub fn request(data: &[u8]) {
    use trayecto::server::request::{Limits, Policy, parse_request};
    let policy = Policy {
        scenes_dir: None,
        output_dir: std::env::temp_dir(),
        limits: Limits {
            max_size: 64,
            max_spp: 16,
            ..Limits::default()
        },
        threads: Some(1),
    };
    if let Ok(r) = parse_request(data, &policy) {
        assert!(r.settings.validate().is_ok(), "{:?}", r.settings);
    }
}
