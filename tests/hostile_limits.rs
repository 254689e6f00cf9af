//! Hostile inputs that name more memory, files or time than they are: each is crafted here,
//! small, and must give a clear error (or a render) within the load's memory budget — never an
//! abort, a panic or a hang (docs/DESIGN.md §7, "Bounded loads"; `scripts/hostile.py` runs the
//! same cases through the binary under an address-space limit).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};
use trayecto::limits::{self, Budget, LoadContext};
use trayecto::scene::{self, Scene, SceneError};

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trayecto-hostile-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Loads `path` under a budget of `mib` MiB.
fn load_with(path: &Path, mib: u64) -> Result<Scene, SceneError> {
    let ctx = LoadContext::new(Budget::new(mib << 20), None);
    limits::scope(ctx, || scene::load_file(path))
}

/// Runs `f` on another thread and fails the test if it has not returned within `secs`.
fn within<T: Send + 'static>(secs: u64, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(secs))
        .expect("still running: the load hangs")
}

/// A scanline EXR header (ZIP, 16 lines a chunk, three float channels) claiming `w`×`h`
/// pixels, with its chunk offset table and no pixels: what the header promises, nothing more.
fn exr_claiming(w: i32, h: i32) -> Vec<u8> {
    let mut f = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
    let mut attr = |name: &str, ty: &str, value: &[u8]| {
        f.extend(name.as_bytes());
        f.push(0);
        f.extend(ty.as_bytes());
        f.push(0);
        f.extend((value.len() as i32).to_le_bytes());
        f.extend(value);
    };
    let mut channels = Vec::new();
    for c in ["B", "G", "R"] {
        channels.extend(c.as_bytes());
        channels.push(0);
        channels.extend(2i32.to_le_bytes()); // FLOAT
        channels.extend([0, 0, 0, 0]); // pLinear, reserved
        channels.extend(1i32.to_le_bytes());
        channels.extend(1i32.to_le_bytes());
    }
    channels.push(0);
    let window: Vec<u8> = [0, 0, w - 1, h - 1]
        .iter()
        .flat_map(|v: &i32| v.to_le_bytes())
        .collect();
    attr("channels", "chlist", &channels);
    attr("compression", "compression", &[3]); // ZIP: 16 scanlines a chunk
    attr("dataWindow", "box2i", &window);
    attr("displayWindow", "box2i", &window);
    attr("lineOrder", "lineOrder", &[0]);
    attr("pixelAspectRatio", "float", &1f32.to_le_bytes());
    attr("screenWindowCenter", "v2f", &[0; 8]);
    attr("screenWindowWidth", "float", &1f32.to_le_bytes());
    f.push(0);
    let chunks = (h as usize).div_ceil(16);
    let table_end = (f.len() + chunks * 8) as u64;
    for _ in 0..chunks {
        f.extend(table_end.to_le_bytes());
    }
    f
}

/// A grey 8-bit PNG whose header claims `w`×`h` (its data is one row's worth: the decoder is
/// never reached when the header is refused).
fn png_claiming(w: u32, h: u32) -> Vec<u8> {
    let mut png = Vec::new();
    image::GrayImage::new(1, 1)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    // IHDR data is bytes 16..29 (after the signature, length and type), its CRC 29..33.
    png[16..20].copy_from_slice(&w.to_be_bytes());
    png[20..24].copy_from_slice(&h.to_be_bytes());
    let mut crc = flate2::Crc::new();
    crc.update(&png[12..29]);
    png[29..33].copy_from_slice(&crc.sum().to_be_bytes());
    png
}

#[test]
fn an_exr_header_claiming_100000_squared_pixels_is_refused() {
    let d = dir("exr");
    let exr = d.join("huge.exr");
    std::fs::write(&exr, exr_claiming(100_000, 100_000)).unwrap();
    assert!(std::fs::metadata(&exr).unwrap().len() < 60_000);
    // As --env.
    let options = trayecto::world::WorldOptions {
        env: Some(exr.clone()),
        ..Default::default()
    };
    let cornell = scene::load("cornell").unwrap();
    let e = trayecto::world::World::build(cornell, &options)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("huge.exr") && e.contains("100000×100000") && e.contains("memory budget"),
        "{e}"
    );
    // As a pbrt imagemap: the texture is a warning naming it and the scene loads.
    let pbrt = d.join("s.pbrt");
    std::fs::write(
        &pbrt,
        "WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"huge.exr\"\n\
         Material \"diffuse\" \"texture reflectance\" \"t\"\nShape \"sphere\"\n",
    )
    .unwrap();
    let s = scene::load_file(&pbrt).unwrap();
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("huge.exr") && w.contains("memory budget")),
        "{:?}",
        s.warnings
    );
    // A header whose chunk table is longer than the file is refused without a budget check.
    let mut cut = exr_claiming(64, 1 << 20);
    cut.truncate(cut.len() / 2);
    std::fs::write(&exr, cut).unwrap();
    let e = trayecto::image_io::read_exr(&exr).unwrap_err().to_string();
    assert!(e.contains("chunks"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

/// A 16384² PNG is within the size limit but not within a small budget: the header is
/// checked against the budget before decoding, for a texture and for a normal map (which used
/// to panic inside the float conversion when memory ran out).
#[test]
fn a_huge_png_is_checked_against_the_budget_before_decoding() {
    let d = dir("png");
    std::fs::write(d.join("big.png"), png_claiming(16384, 16384)).unwrap();
    let pbrt = d.join("s.pbrt");
    std::fs::write(
        &pbrt,
        "WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"big.png\"\n\
         Material \"diffuse\" \"texture reflectance\" \"t\" \"string normalmap\" \"big.png\"\n\
         Shape \"sphere\"\n",
    )
    .unwrap();
    let s = load_with(&pbrt, 128).unwrap();
    let refused: Vec<&String> = s
        .warnings
        .iter()
        .filter(|w| w.contains("16384×16384") && w.contains("memory budget"))
        .collect();
    assert_eq!(refused.len(), 2, "{:?}", s.warnings);
    let _ = std::fs::remove_dir_all(&d);
}

/// One file named through six spellings is one texture, decoded once.
#[test]
fn one_image_through_six_spellings_is_decoded_once() {
    let d = dir("spellings");
    std::fs::create_dir_all(d.join("t")).unwrap();
    image::RgbImage::from_pixel(4, 4, image::Rgb([200, 100, 50]))
        .save(d.join("t/a.png"))
        .unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(d.join("t/a.png"), d.join("link.png")).unwrap();
    let mut text = String::from("WorldBegin\n");
    for (i, f) in [
        "t/a.png",
        "./t/a.png",
        "t/./a.png",
        "t//a.png",
        "./t/.//a.png",
        "link.png",
    ]
    .iter()
    .enumerate()
    {
        text += &format!(
            "Texture \"t{i}\" \"spectrum\" \"imagemap\" \"string filename\" \"{f}\"\n\
             Material \"diffuse\" \"texture reflectance\" \"t{i}\"\nShape \"sphere\" \"float radius\" {}\n",
            i + 1
        );
    }
    std::fs::write(d.join("s.pbrt"), text).unwrap();
    let s = scene::load_file(&d.join("s.pbrt")).unwrap();
    let images = s.textures.iter().filter(|t| t.width == 4).count();
    assert_eq!(images, 1, "{} textures", s.textures.len());
    let _ = std::fs::remove_dir_all(&d);
}

/// A POSITION accessor with no buffer view and a count of 2²⁷ (zeros, 4 GiB as decoded) from a
/// file of a few hundred bytes.
#[test]
fn a_view_less_accessor_is_bounded_like_any_other() {
    let d = dir("gltf");
    let gltf = d.join("zeros.gltf");
    std::fs::write(
        &gltf,
        r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
"accessors":[{"componentType":5126,"count":134217728,"type":"VEC3","min":[0,0,0],"max":[0,0,0]}]}"#,
    )
    .unwrap();
    let e = load_with(&gltf, 1024).expect_err("refused").to_string();
    assert!(
        e.contains("zeros.gltf") && e.contains("134217728 elements") && e.contains("budget"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// A `.ply.gz` of zeros inflates a thousand times: refused by the ratio bound, and a stream
/// within the ratio by the budget.
#[test]
fn a_gzip_bomb_mesh_is_bounded_by_ratio_and_budget() {
    let d = dir("plygz");
    let gz = |n: usize| {
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        let header = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n\
             property float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n"
        );
        e.write_all(header.as_bytes()).unwrap();
        e.write_all(&vec![0u8; n * 12]).unwrap();
        e.finish().unwrap()
    };
    std::fs::write(d.join("zeros.ply.gz"), gz(4 << 20)).unwrap();
    std::fs::write(
        d.join("s.pbrt"),
        "WorldBegin\nShape \"plymesh\" \"string filename\" \"zeros.ply.gz\"\nShape \"sphere\"\n",
    )
    .unwrap();
    let e = load_with(&d.join("s.pbrt"), 1024)
        .expect_err("refused")
        .to_string();
    assert!(
        e.contains("zeros.ply.gz") && e.contains("decompresses to more than"),
        "{e}"
    );
    // 1 MiB of noise and 24 MiB of zeros: within the ratio, over an 8 MiB budget.
    let mut data = Vec::with_capacity(25 << 20);
    let mut x = 0x2545_f491_4f6c_dd1du64;
    while data.len() < 1 << 20 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        data.extend(x.to_le_bytes());
    }
    data.resize(25 << 20, 0);
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(&data).unwrap();
    std::fs::write(d.join("zeros.ply.gz"), e.finish().unwrap()).unwrap();
    let e = load_with(&d.join("s.pbrt"), 8)
        .expect_err("refused")
        .to_string();
    assert!(
        e.contains("zeros.ply.gz") && e.contains("decompressing") && e.contains("budget"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// A pbrt scene of `copies` triangles, each subdivided 6 levels by `loopsubdiv` (4096 triangles).
fn write_subdivided_triangles(path: &Path, copies: usize) {
    let shape = "Shape \"loopsubdiv\" \"integer levels\" 6 \"point3 P\" [0 0 0 1 0 0 0 1 0] \
                 \"integer indices\" [0 1 2]\n";
    std::fs::write(path, format!("WorldBegin\n{}", shape.repeat(copies))).unwrap();
}

/// 300 level-6 `loopsubdiv` shapes become 1.2 M triangles: charged before subdividing.
#[test]
fn subdivision_is_charged_for_the_triangles_it_will_make() {
    let d = dir("loop");
    write_subdivided_triangles(&d.join("s.pbrt"), 300);
    let e = load_with(&d.join("s.pbrt"), 16)
        .expect_err("refused")
        .to_string();
    assert!(
        e.contains("levels of subdivision (4096 triangles)") && e.contains("budget"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// The world compiled from a scene costs several times the scene's meshes (transformed copies,
/// the BVH): it is charged to the same budget before it is built, so a scene whose meshes fit
/// but whose world would not is refused by name instead of exhausting memory mid-build.
#[test]
fn the_world_is_charged_before_it_is_built() {
    let d = dir("world");
    // 100 × 4096 triangles: ~19 MiB as scene meshes, ~63 MiB more as a world.
    write_subdivided_triangles(&d.join("s.pbrt"), 100);
    let build = |mib: u64| {
        let ctx = LoadContext::new(Budget::new(mib << 20), None);
        limits::scope(ctx, || {
            let s = scene::load_file(&d.join("s.pbrt"))?;
            trayecto::world::World::build(
                s,
                &trayecto::world::WorldOptions {
                    default_light: Some(trayecto::scene::DefaultLight::Uniform),
                    ..Default::default()
                },
            )
            .map(drop)
        })
    };
    let e = build(48).expect_err("refused").to_string();
    assert!(
        e.contains("the world of 409600 triangles") && e.contains("budget"),
        "{e}"
    );
    build(160).expect("fits");
    let _ = std::fs::remove_dir_all(&d);
}

/// Shape parameters are validated where they are read; the small parser cuts.
#[test]
fn pbrt_parameter_cuts() {
    let d = dir("params");
    let p = d.join("s.pbrt");
    // A negative sphere radius used to cross the bounds of a clamp (a panic).
    std::fs::write(
        &p,
        "\u{feff}WorldBegin\nShape \"sphere\" \"float radius\" -2\nShape \"sphere\" \"integer big\" 2147483647\n",
    )
    .unwrap();
    let s = scene::load_file(&p).unwrap();
    assert!(
        s.warnings.iter().any(|w| w.contains("empty sphere")),
        "{:?}",
        s.warnings
    );
    // 2³¹ − 1 is an integer (warned as unused, not refused); 2³¹ is out of range, not
    // "non-integer".
    assert!(
        s.warnings.iter().any(|w| w.contains("big")),
        "{:?}",
        s.warnings
    );
    std::fs::write(
        &p,
        "WorldBegin\nShape \"sphere\" \"integer big\" 2147483648\n",
    )
    .unwrap();
    let e = scene::load_file(&p).expect_err("refused").to_string();
    assert!(e.contains("outside the 32-bit range"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

/// 26 files each including the next twice read 2²⁶ files with no cycle and little depth: the
/// include budget ends it quickly with an error naming Include.
#[test]
fn include_fan_out_ends_quickly() {
    let d = dir("fanout");
    for i in 0..26 {
        let body = if i < 25 {
            format!("Include \"f{}.pbrt\"\nInclude \"f{}.pbrt\"\n", i + 1, i + 1)
        } else {
            "# leaf\n".to_string()
        };
        std::fs::write(d.join(format!("f{i}.pbrt")), body).unwrap();
    }
    std::fs::write(d.join("s.pbrt"), "WorldBegin\nInclude \"f0.pbrt\"\n").unwrap();
    let p = d.join("s.pbrt");
    let t = Instant::now();
    let e = within(60, move || {
        scene::load_file(&p).err().map(|e| e.to_string())
    })
    .expect("refused");
    assert!(e.contains("Include") && e.contains("included files"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(20), "{:?}", t.elapsed());
    let _ = std::fs::remove_dir_all(&d);
}

/// A FIFO named as an Include or a glTF buffer is refused, not opened (opening blocks until a
/// writer comes).
#[cfg(unix)]
#[test]
fn a_fifo_is_never_opened() {
    let d = dir("fifo");
    let ok = std::process::Command::new("mkfifo")
        .arg(d.join("pipe"))
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        eprintln!("no mkfifo: skipped");
        return;
    }
    std::fs::write(d.join("s.pbrt"), "WorldBegin\nInclude \"pipe\"\n").unwrap();
    std::fs::write(
        d.join("s.gltf"),
        r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"pipe","byteLength":12}]}"#,
    )
    .unwrap();
    for f in ["s.pbrt", "s.gltf"] {
        let p = d.join(f);
        let e = within(10, move || {
            scene::load_file(&p).err().map(|e| e.to_string())
        })
        .expect("refused");
        assert!(e.contains("not a regular file"), "{f}: {e}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// A load checks its cancel flag at every file read and in long loops.
#[test]
fn a_cancelled_load_stops() {
    let d = dir("cancel");
    std::fs::write(d.join("s.pbrt"), "WorldBegin\nShape \"sphere\"\n").unwrap();
    let ctx = LoadContext::new(Budget::new(1 << 30), Some(Arc::new(|| true)));
    let e = limits::scope(ctx, || scene::load_file(&d.join("s.pbrt")))
        .expect_err("cancelled")
        .to_string();
    assert!(e.contains("cancelled"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}
