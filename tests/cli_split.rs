//! The command line of split renders: `render --samples A..B -o part.trp`, `merge`,
//! `--checkpoint` / `--resume`, and Ctrl-C (a real SIGINT to a child process).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use trayecto::split::partial::Part;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_trayecto"))
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trayecto-cli-split-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

const SIZE: [&str; 4] = ["--width", "24", "--height", "16"];

fn render(extra: &[&str], out: &Path) -> std::process::Output {
    bin()
        .args(["render", "cornell", "-q", "--seed", "5"])
        .args(SIZE)
        .args(extra)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap()
}

fn ok(o: std::process::Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn parts_rendered_by_separate_processes_merge_to_the_single_render() {
    let d = dir("merge");
    ok(render(&["--spp", "11"], &d.join("full.exr")));
    let mut parts = Vec::new();
    for (a, b) in [(0, 4), (4, 5), (5, 11)] {
        let p = d.join(format!("p{a}.trp"));
        ok(render(
            &["--spp", "11", "--samples", &format!("{a}..{b}")],
            &p,
        ));
        parts.push(p);
    }
    parts.reverse();
    ok(bin()
        .arg("merge")
        .args(&parts)
        .arg("-o")
        .arg(d.join("merged.exr"))
        .output()
        .unwrap());
    assert_eq!(
        std::fs::read(d.join("full.exr")).unwrap(),
        std::fs::read(d.join("merged.exr")).unwrap(),
        "merged EXR differs from the single render"
    );
    // Two parts merged into a longer part, then with the third: the same image.
    ok(bin()
        .arg("merge")
        .args(&parts[..2])
        .arg("-o")
        .arg(d.join("p4-11.trp"))
        .output()
        .unwrap());
    ok(bin()
        .arg("merge")
        .arg(d.join("p4-11.trp"))
        .arg(&parts[2])
        .arg("-o")
        .arg(d.join("merged2.exr"))
        .output()
        .unwrap());
    assert_eq!(
        std::fs::read(d.join("full.exr")).unwrap(),
        std::fs::read(d.join("merged2.exr")).unwrap()
    );

    // Refusals, with the file named and a non-zero exit.
    let refuse = |args: &[&Path], want: &str| {
        let o = bin()
            .arg("merge")
            .args(args)
            .arg("-o")
            .arg(d.join("bad.exr"))
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(want), "{e}");
    };
    refuse(&[&parts[0], &parts[2]], "samples 4..5 are missing");
    refuse(&[&parts[0], &parts[1]], "samples 0..4 are missing");
    ok(render(
        &["--spp", "11", "--samples", "3..5"],
        &d.join("o.trp"),
    ));
    refuse(&[&d.join("o.trp"), &parts[2], &parts[0]], "overlap");
    ok(render(
        &["--spp", "11", "--samples", "0..4", "--max-depth", "3"],
        &d.join("m.trp"),
    ));
    refuse(&[&d.join("m.trp"), &parts[1], &parts[0]], "max_depth");
    assert!(!d.join("bad.exr").exists());

    // Bad options.
    for (args, want) in [
        (&["--spp", "11", "--samples", "5..3"][..], "empty"),
        (
            &["--spp", "11", "--samples", "0..12"],
            "end at most at the frame's 11",
        ),
        (&["--spp", "11", "--samples", "x"], "not a sample range"),
    ] {
        let o = render(args, &d.join("x.trp"));
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(want), "{args:?}: {e}");
    }
    let o = render(&["--spp", "11", "--samples", "0..3"], &d.join("x.png"));
    assert!(String::from_utf8_lossy(&o.stderr).contains("name the output FILE.trp"));
}

/// A part's header names the light sampler the render used, resolved from `auto` by the scene's
/// light count (power for cornell, the 8-wide light BVH above 16 lights), and the build's render
/// identity; `auto` itself never appears.
#[test]
fn parts_record_the_resolved_light_sampler_and_the_render_identity() {
    let d = dir("identity");
    ok(render(
        &["--spp", "4", "--samples", "0..2"],
        &d.join("cornell.trp"),
    ));
    let p = Part::read(&d.join("cornell.trp")).unwrap();
    assert_eq!(p.header.render_identity, trayecto::RENDER_IDENTITY);
    assert_eq!(p.header.render_identity.len(), 64);
    assert_eq!(p.header.settings["light_sampler"], "power");
    // 17 point lights: more than `auto`'s threshold of 16.
    let mut text = String::from(
        "Camera \"perspective\"\nFilm \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\nWorldBegin\n",
    );
    for i in 0..17 {
        text += &format!(
            "LightSource \"point\" \"point3 from\" [ {} 0.5 -1 ]\n",
            i as f32 * 0.1 - 0.8
        );
    }
    text += "Shape \"trianglemesh\" \"point3 P\" [ -1 -1 2 1 -1 2 1 1 2 ] \"integer indices\" [ 0 1 2 ]\n";
    let scene = d.join("many.pbrt");
    std::fs::write(&scene, text).unwrap();
    for (extra, want) in [(&[][..], "bvh8"), (&["--light-sampler", "bvh"][..], "bvh")] {
        let out = d.join(format!("many-{want}.trp"));
        ok(bin()
            .arg("render")
            .arg(&scene)
            .args(["-q", "--spp", "2", "--samples", "0..1"])
            .args(extra)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap());
        let p = Part::read(&out).unwrap();
        assert_eq!(p.header.settings["light_sampler"], want, "{extra:?}");
    }
}

/// Sends SIGINT (what Ctrl-C sends) to a child process.
fn sigint(pid: u32) {
    let s = Command::new("kill")
        .args(["-INT", &pid.to_string()])
        .status()
        .unwrap();
    assert!(s.success());
}

#[test]
fn ctrl_c_saves_a_checkpoint_and_the_resumed_render_equals_an_uninterrupted_one() {
    let d = dir("resume");
    // Long enough (hundreds of passes of 64 samples) to be interrupted mid-way.
    let settings = ["--spp", "6000", "--max-depth", "4"];
    let cp = d.join("cp.trp");
    let mut child = bin()
        .args(["render", "cornell", "-q", "--seed", "5"])
        .args(SIZE)
        .args(settings)
        .args(["--checkpoint-interval", "0", "--checkpoint"])
        .arg(&cp)
        .arg("-o")
        .arg(d.join("resumed.exr"))
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The first checkpoint means the Ctrl-C handler is installed and passes are running.
    let t0 = Instant::now();
    while !cp.exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "no checkpoint appeared"
        );
        assert!(
            child.try_wait().unwrap().is_none(),
            "render ended too early"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    sigint(child.id());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(
        err.contains("interrupted") && err.contains("--resume"),
        "{err}"
    );
    assert!(!d.join("resumed.exr").exists());
    let saved = Part::read(&cp).unwrap();
    let [a, b] = saved.header.samples;
    assert!(a == 0 && b > 0 && b < 6000, "checkpoint holds {a}..{b}");

    // Resume with other thread counts; checkpoints go on into the same file.
    let o = bin()
        .args(["render", "cornell", "-q", "--seed", "5", "--threads", "1"])
        .args(SIZE)
        .args(settings)
        .arg("--resume")
        .arg(&cp)
        .arg("-o")
        .arg(d.join("resumed.exr"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(Part::read(&cp).unwrap().header.samples, [0, 6000]);
    ok(render(&settings, &d.join("straight.exr")));
    assert_eq!(
        std::fs::read(d.join("straight.exr")).unwrap(),
        std::fs::read(d.join("resumed.exr")).unwrap(),
        "the resumed render differs from the uninterrupted one (interrupted at sample {b})"
    );

    // A checkpoint of another frame is refused.
    let o = render(
        &[
            "--spp",
            "6000",
            "--max-depth",
            "5",
            "--resume",
            cp.to_str().unwrap(),
        ],
        &d.join("other.exr"),
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("another frame") && e.contains("max_depth"),
        "{e}"
    );
}
