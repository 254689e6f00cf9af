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

/// An empty folder at each of `paths`, whatever was there before (a folder or a file).
fn fresh_dirs(paths: &[&Path]) {
    for p in paths {
        let _ = std::fs::remove_file(p);
        let _ = std::fs::remove_dir_all(p);
        std::fs::create_dir_all(p).unwrap();
    }
}

/// Waits until the running render `child` has written its first checkpoint `cp` (then its
/// passes are running and its signal handlers installed).
fn wait_for_checkpoint(cp: &Path, child: &mut std::process::Child) {
    let t0 = Instant::now();
    while !cp.exists() {
        assert!(t0.elapsed() < Duration::from_secs(60), "no checkpoint");
        assert!(child.try_wait().unwrap().is_none(), "render ended early");
        std::thread::sleep(Duration::from_millis(20));
    }
}

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

/// `trayecto merge PARTS… -o OUT`.
fn merge<P: AsRef<std::ffi::OsStr>>(
    parts: impl IntoIterator<Item = P>,
    out: &Path,
) -> std::process::Output {
    bin()
        .arg("merge")
        .args(parts)
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
    ok(merge(&parts, &d.join("merged.exr")));
    assert_eq!(
        std::fs::read(d.join("full.exr")).unwrap(),
        std::fs::read(d.join("merged.exr")).unwrap(),
        "merged EXR differs from the single render"
    );
    // Two parts merged into a longer part, then with the third: the same image.
    ok(merge(&parts[..2], &d.join("p4-11.trp")));
    ok(merge(
        [&d.join("p4-11.trp"), &parts[2]],
        &d.join("merged2.exr"),
    ));
    assert_eq!(
        std::fs::read(d.join("full.exr")).unwrap(),
        std::fs::read(d.join("merged2.exr")).unwrap()
    );

    // Refusals, with the file named and a non-zero exit.
    let refuse = |args: &[&Path], want: &str| {
        let o = merge(args, &d.join("bad.exr"));
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

    // Spectral parts merge to the spectral render bit for bit (each sample draws its wavelengths
    // from its own stream), and never with RGB parts of the same samples.
    ok(render(&["--spp", "6", "--spectral"], &d.join("sfull.exr")));
    let mut sparts = Vec::new();
    for (a, b) in [(0, 2), (2, 6)] {
        let p = d.join(format!("s{a}.trp"));
        let range = format!("{a}..{b}");
        ok(render(
            &["--spp", "6", "--spectral", "--samples", &range],
            &p,
        ));
        sparts.push(p);
    }
    ok(merge(&sparts, &d.join("smerged.exr")));
    assert_eq!(
        std::fs::read(d.join("sfull.exr")).unwrap(),
        std::fs::read(d.join("smerged.exr")).unwrap(),
        "merged spectral EXR differs from the single spectral render"
    );
    ok(render(
        &["--spp", "6", "--samples", "2..6"],
        &d.join("rgb.trp"),
    ));
    refuse(&[&sparts[0], &d.join("rgb.trp")], "spectral");

    // Guided parts too: each part learns the same guide (the training iterations are the
    // frame's first samples, which a part that does not own them traces for their records
    // alone), so they merge to the guided render bit for bit, and a part resumed to the frame's
    // end is that render as well.
    let guided = ["--spp", "8", "--guiding"];
    ok(render(&guided, &d.join("gfull.exr")));
    let mut gparts = Vec::new();
    for (a, b) in [(0, 3), (3, 8)] {
        let p = d.join(format!("g{a}.trp"));
        ok(render(
            &[&guided[..], &["--samples", &format!("{a}..{b}")]].concat(),
            &p,
        ));
        gparts.push(p);
    }
    ok(merge(&gparts, &d.join("gmerged.exr")));
    let gfull = std::fs::read(d.join("gfull.exr")).unwrap();
    assert!(
        gfull == std::fs::read(d.join("gmerged.exr")).unwrap(),
        "merged guided EXR differs from the single guided render"
    );
    ok(render(
        &[&guided[..], &["--resume", gparts[0].to_str().unwrap()]].concat(),
        &d.join("gresumed.exr"),
    ));
    assert!(
        gfull == std::fs::read(d.join("gresumed.exr")).unwrap(),
        "resumed guided EXR differs from the single guided render"
    );
    ok(render(
        &["--spp", "8", "--samples", "0..3"],
        &d.join("u.trp"),
    ));
    refuse(&[&d.join("u.trp"), &gparts[1]], "guiding");

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

/// The splatting integrators split as the path tracer does: the light tracer's and BDPT's parts
/// (sample ranges of the same paths, splatted into exact fixed-point sums) merge byte for byte to
/// the whole render. Metropolis light transport, whose chains run over the whole frame, refuses a
/// sample range and a checkpoint with the reason.
#[test]
fn light_tracer_and_bdpt_parts_merge_to_the_single_render_and_mlt_refuses_them() {
    let d = dir("light-paths");
    for integrator in ["lighttracer", "bdpt"] {
        let args = ["--integrator", integrator, "--spp", "6", "--max-depth", "4"];
        let full = d.join(format!("{integrator}-full.exr"));
        ok(render(&args, &full));
        let mut parts = Vec::new();
        for range in ["0..2", "2..6"] {
            let p = d.join(format!("{integrator}-{range}.trp"));
            ok(render(&[&args[..], &["--samples", range]].concat(), &p));
            parts.push(p);
        }
        let merged = d.join(format!("{integrator}-merged.exr"));
        ok(merge(&parts, &merged));
        assert_eq!(
            std::fs::read(&full).unwrap(),
            std::fs::read(&merged).unwrap(),
            "{integrator}: merged EXR differs from the single render"
        );
    }
    let mlt = ["--integrator", "mlt", "--spp", "6"];
    for (extra, out, want) in [
        (
            &["--samples", "0..2"][..],
            "mlt.trp",
            "not split into sample ranges",
        ),
        (
            &["--checkpoint", d.join("mlt-cp.trp").to_str().unwrap()],
            "mlt.exr",
            "cannot be resumed",
        ),
    ] {
        let o = render(&[&mlt[..], extra].concat(), &d.join(out));
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(want), "{extra:?}: {e}");
    }
    let _ = std::fs::remove_dir_all(&d);
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
    wait_for_checkpoint(&cp, &mut child);
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

/// Sends `signal` (a `kill` name: INT, TERM, HUP) to a child process.
fn signal(pid: u32, signal: &str) {
    let s = Command::new("kill")
        .args([&format!("-{signal}"), &pid.to_string()])
        .status()
        .unwrap();
    assert!(s.success());
}

/// Starts a render (not quiet) and waits until it prints its plan, the line just before the
/// passes start: from then on the signal handler is installed and the render is under way.
fn spawn_until_rendering(cmd: &mut Command) -> (std::process::Child, String) {
    use std::io::Read;
    let mut child = cmd.stderr(Stdio::piped()).spawn().unwrap();
    let mut err = child.stderr.take().unwrap();
    let mut seen = Vec::new();
    let t0 = Instant::now();
    let mut byte = [0u8; 1];
    while !String::from_utf8_lossy(&seen).contains("\nrendering ")
        && !String::from_utf8_lossy(&seen).starts_with("rendering ")
    {
        assert!(t0.elapsed() < Duration::from_secs(60), "no plan line");
        if err.read(&mut byte).unwrap() == 0 {
            panic!(
                "the render ended before rendering: {}",
                String::from_utf8_lossy(&seen)
            );
        }
        seen.push(byte[0]);
    }
    // The rest of stderr is read by wait_with_output: give the pipe back to the child handle.
    child.stderr = Some(err);
    (child, String::from_utf8_lossy(&seen).into_owned())
}

/// `-o` naming a folder is refused before anything is loaded or rendered, by render and merge.
#[test]
fn an_output_naming_a_folder_is_refused_before_rendering() {
    let d = dir("folder-output");
    let t0 = Instant::now();
    let o = render(&["--spp", "1000000"], &d);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("is a folder"), "{e}");
    // Refused before the 384-megasample render could start.
    assert!(t0.elapsed() < Duration::from_secs(20));
    let o = bin()
        .args(["render", "cornell", "-q", "--checkpoint"])
        .arg(&d)
        .arg("-o")
        .arg(d.join("x.png"))
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&o.stderr).contains("is a folder"));
    let o = merge([d.join("none.trp")], &d);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("is a folder"), "{e}");
}

/// When the final write fails (here its folder is replaced by a file mid-render, which no user,
/// root included, can write under), the film is saved in the temporary folder as a partial film,
/// the message says how to recover it, and `merge` recovers the very image.
#[test]
fn a_failed_final_write_saves_the_film_and_merge_recovers_the_image() {
    let d = dir("rescue");
    let out_dir = d.join("gone");
    let tmp = d.join("tmp");
    fresh_dirs(&[&tmp, &out_dir]);
    let settings = ["--spp", "3000", "--max-depth", "3", "--threads", "1"];
    let (child, _) = spawn_until_rendering(
        bin()
            .args(["render", "cornell", "--seed", "5"])
            .args(SIZE)
            .args(settings)
            .arg("-o")
            .arg(out_dir.join("image.exr"))
            .env("TMPDIR", &tmp),
    );
    std::fs::remove_dir_all(&out_dir).unwrap();
    std::fs::write(&out_dir, b"a file where the folder was").unwrap();
    let o = child.wait_with_output().unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    let rescued = tmp.join("image.trp");
    assert!(rescued.is_file(), "nothing in {}: {e}", tmp.display());
    assert!(
        e.contains(&format!("trayecto merge {}", rescued.display())),
        "{e}"
    );
    ok(merge([&rescued], &d.join("recovered.exr")));
    ok(render(&settings, &d.join("straight.exr")));
    assert_eq!(
        std::fs::read(d.join("straight.exr")).unwrap(),
        std::fs::read(d.join("recovered.exr")).unwrap(),
        "the recovered image differs from the render's"
    );
}

/// When a checkpoint cannot be written mid-render (its folder replaced by a file after the first
/// one was written), the render stops, the completed passes are saved in the temporary folder,
/// and `merge` turns them into exactly the image of a render of that many samples.
#[test]
fn a_failed_checkpoint_write_saves_the_completed_passes() {
    let d = dir("checkpoint-rescue");
    let cp_dir = d.join("cp");
    let tmp = d.join("tmp");
    fresh_dirs(&[&tmp, &cp_dir]);
    let cp = cp_dir.join("ck.trp");
    // The independent sampler's first k samples of 6000 are a render of k samples (a stratified
    // sampler's strata depend on the sample count).
    let settings = [
        "--max-depth",
        "3",
        "--threads",
        "1",
        "--sampler",
        "independent",
    ];
    let mut child = bin()
        .args(["render", "cornell", "-q", "--seed", "5", "--spp", "6000"])
        .args(SIZE)
        .args(settings)
        .args(["--checkpoint-interval", "0", "--checkpoint"])
        .arg(&cp)
        .arg("-o")
        .arg(d.join("image.exr"))
        .env("TMPDIR", &tmp)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for_checkpoint(&cp, &mut child);
    // Moved away in one step (the render may be writing the next checkpoint into it).
    let moved = d.join("cp-moved");
    let _ = std::fs::remove_dir_all(&moved);
    std::fs::rename(&cp_dir, &moved).unwrap();
    std::fs::write(&cp_dir, b"a file where the folder was").unwrap();
    let o = child.wait_with_output().unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    let rescued = tmp.join("ck.trp");
    assert!(rescued.is_file(), "nothing in {}: {e}", tmp.display());
    assert!(e.contains("nothing is lost"), "{e}");
    let part = Part::read(&rescued).unwrap();
    let [start, done] = part.header.samples;
    assert_eq!(start, 0);
    assert!(done > 0 && done < 6000, "{done} samples rescued");
    ok(merge([&rescued], &d.join("recovered.exr")));
    let spp = done.to_string();
    ok(bin()
        .args(["render", "cornell", "-q", "--seed", "5", "--spp", &spp])
        .args(SIZE)
        .args(settings)
        .arg("-o")
        .arg(d.join("straight.exr"))
        .output()
        .unwrap());
    assert!(
        std::fs::read(d.join("straight.exr")).unwrap()
            == std::fs::read(d.join("recovered.exr")).unwrap(),
        "the recovered image differs from a render of {done} samples"
    );
}

/// SIGTERM and SIGHUP stop a render as Ctrl-C does: the checkpoint is saved and the message says
/// it survived and how to resume it.
#[test]
fn sigterm_and_sighup_save_the_checkpoint_as_ctrl_c_does() {
    let d = dir("sigterm");
    for sig in ["TERM", "HUP"] {
        let cp = d.join(format!("{sig}.trp"));
        let _ = std::fs::remove_file(&cp);
        let mut child = bin()
            .args(["render", "cornell", "-q", "--seed", "5"])
            .args(SIZE)
            .args(["--spp", "6000", "--max-depth", "4"])
            .args(["--checkpoint-interval", "0", "--checkpoint"])
            .arg(&cp)
            .arg("-o")
            .arg(d.join(format!("{sig}.exr")))
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        wait_for_checkpoint(&cp, &mut child);
        signal(child.id(), sig);
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(130), "SIG{sig}: {err}");
        assert!(
            err.contains(&format!("saved in {}", cp.display())) && err.contains("--resume"),
            "SIG{sig}: {err}"
        );
        let [a, b] = Part::read(&cp).unwrap().header.samples;
        assert!(a == 0 && b > 0 && b < 6000, "SIG{sig}: {a}..{b}");
    }
}

/// Ctrl-C without --checkpoint writes the image of the passes completed so far and says so.
#[test]
fn ctrl_c_without_a_checkpoint_writes_the_image_of_the_completed_passes() {
    let d = dir("ctrl-c-image");
    let out = d.join("partial.exr");
    let _ = std::fs::remove_file(&out);
    let (child, _) = spawn_until_rendering(
        bin()
            .args(["render", "cornell", "--seed", "5", "--threads", "1"])
            .args(SIZE)
            .args(["--spp", "200000", "--max-depth", "4"])
            .arg("-o")
            .arg(&out),
    );
    // Long enough for a few passes of this small image, far from the 77 M samples of the whole.
    std::thread::sleep(Duration::from_millis(800));
    sigint(child.id());
    let o = child.wait_with_output().unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(130), "{e}");
    assert!(
        e.contains("image of the completed passes is in") && e.contains("partial.exr"),
        "{e}"
    );
    assert!(out.is_file(), "{e}");
}

/// `-q` prints errors only: not a scene's warnings either; `merge` has `-q` too.
#[test]
fn quiet_suppresses_warnings_and_merge_has_quiet() {
    let d = dir("quiet");
    let scene = d.join("warns.pbrt");
    std::fs::write(
        &scene,
        "Camera \"perspective\"\nWorldBegin\nShape \"sphere\" \"float radius\" 1 \"float bogus\" 2\n",
    )
    .unwrap();
    let run = |quiet: bool| {
        let mut c = bin();
        c.arg("render").arg(&scene).args(["--spp", "1"]).args(SIZE);
        if quiet {
            c.arg("-q");
        }
        let o = c.arg("-o").arg(d.join("w.png")).output().unwrap();
        assert!(o.status.success());
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    assert!(run(false).contains("bogus"));
    assert_eq!(run(true), "");
    ok(render(
        &["--spp", "2", "--samples", "0..2"],
        &d.join("q.trp"),
    ));
    let o = bin()
        .args(["merge", "-q"])
        .arg(d.join("q.trp"))
        .arg("-o")
        .arg(d.join("q.exr"))
        .output()
        .unwrap();
    assert!(o.status.success());
    assert_eq!(String::from_utf8_lossy(&o.stderr), "");
    assert!(d.join("q.exr").is_file());
}

/// Parts or a checkpoint rendered with another --texture-filter are refused by merge and by
/// --resume: every setting that reaches the renderer is compared.
#[test]
fn merge_and_resume_refuse_another_texture_filter() {
    let d = dir("texture-filter");
    ok(render(
        &["--spp", "4", "--samples", "0..2"],
        &d.join("a.trp"),
    ));
    ok(render(
        &[
            "--spp",
            "4",
            "--samples",
            "2..4",
            "--texture-filter",
            "trilinear",
        ],
        &d.join("b.trp"),
    ));
    let o = merge([d.join("a.trp"), d.join("b.trp")], &d.join("mixed.exr"));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("texture_filter") && e.contains("Trilinear"),
        "{e}"
    );
    assert!(!d.join("mixed.exr").exists());
    let o = render(
        &[
            "--spp",
            "4",
            "--texture-filter",
            "trilinear",
            "--resume",
            d.join("a.trp").to_str().unwrap(),
        ],
        &d.join("resumed.exr"),
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("another frame") && e.contains("texture_filter"),
        "{e}"
    );
}

/// A forged partial film, zeros that claim a large frame, is a clear error in `merge` and in
/// `--resume` (whose header it matches), found before its arrays are allocated.
#[test]
fn a_forged_partial_film_is_refused_by_merge_and_resume() {
    use std::io::Write;
    let d = dir("forged");
    let real = d.join("real.trp");
    ok(render(
        &[
            "--spp",
            "4",
            "--samples",
            "0..2",
            "--checkpoint-interval",
            "0",
        ],
        &real,
    ));
    let mut h = Part::read(&real).unwrap().header;
    let side = 1024u32;
    h.width = side;
    h.height = side;
    h.settings.insert("width".into(), side.to_string());
    h.settings.insert("height".into(), side.to_string());
    let header = serde_json::to_vec(&h).unwrap();
    let mut f = Vec::new();
    f.extend_from_slice(b"TRAYPART");
    f.extend_from_slice(&(header.len() as u32).to_le_bytes());
    f.extend_from_slice(&header);
    let mut z = flate2::write::ZlibEncoder::new(f, flate2::Compression::best());
    let zeros = vec![0u8; 1 << 20];
    let mut left = side as usize * side as usize * 52;
    while left > 0 {
        let k = left.min(zeros.len());
        z.write_all(&zeros[..k]).unwrap();
        left -= k;
    }
    let forged = d.join("forged.trp");
    std::fs::write(&forged, z.finish().unwrap()).unwrap();
    // Merged into a longer part (an image would need the whole frame): the pixels are read.
    let o = merge([&forged], &d.join("forged-merged.trp"));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("forged.trp") && e.contains("discarded"),
        "{e}"
    );
    let o = bin()
        .args(["render", "cornell", "-q", "--seed", "5", "--spp", "4"])
        .args(["--width", &side.to_string(), "--height", &side.to_string()])
        .args(["--samples", "0..4", "--resume"])
        .arg(&forged)
        .arg("-o")
        .arg(d.join("resumed.trp"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("forged.trp") && e.contains("discarded"),
        "{e}"
    );
}

/// A `--transparent` frame rendered in parts keeps its alpha: the parts hold the film's exact
/// coverage counts, so the merged EXR (beauty and `A`) and a render resumed from a part equal the
/// single render bit for bit, and a merged PNG is RGBA.
#[test]
fn a_transparent_frame_merges_and_resumes_with_its_alpha() {
    let d = dir("alpha");
    // A ball in the middle of the frame: background at the corners, partly covered edges.
    let scene = d.join("ball.toml");
    std::fs::write(
        &scene,
        "[[camera]]\neye = [0.0, 0.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nfov = 40.0\n\
         [[object]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 0.8\n",
    )
    .unwrap();
    let render = |extra: &[&str], out: &Path| {
        ok(bin()
            .arg("render")
            .arg(&scene)
            .args(["-q", "--transparent", "--spp", "6"])
            .args(SIZE)
            .args(extra)
            .arg("-o")
            .arg(out)
            .output()
            .unwrap())
    };
    render(&[], &d.join("full.exr"));
    render(&["--samples", "0..2"], &d.join("a.trp"));
    render(&["--samples", "2..6"], &d.join("b.trp"));
    for out in ["merged.exr", "merged.png"] {
        ok(merge([d.join("b.trp"), d.join("a.trp")], &d.join(out)));
    }
    assert_eq!(
        std::fs::read(d.join("full.exr")).unwrap(),
        std::fs::read(d.join("merged.exr")).unwrap(),
        "merged EXR differs from the single render"
    );
    let (_, _, channels) = trayecto::film::output::read_exr_channels(&d.join("full.exr")).unwrap();
    let alpha = &channels
        .iter()
        .find(|(n, _)| n == "A")
        .expect("no A channel")
        .1;
    assert!(alpha.contains(&0.0) && alpha.contains(&1.0));
    assert!(
        alpha.iter().any(|&a| a > 0.0 && a < 1.0),
        "no partly covered pixel"
    );
    let png = image::open(d.join("merged.png")).unwrap();
    assert!(png.color().has_alpha(), "merged PNG without alpha");
    // `--aov alpha` counts the same coverage without leaving the background out.
    ok(bin()
        .args(["render", "-q", "--spp", "6", "--aov", "alpha"])
        .arg(&scene)
        .args(SIZE)
        .arg("-o")
        .arg(d.join("opaque.exr"))
        .output()
        .unwrap());
    let (_, _, opaque) = trayecto::film::output::read_exr_channels(&d.join("opaque.exr")).unwrap();
    assert_eq!(
        &opaque
            .iter()
            .find(|(n, _)| n == "A")
            .expect("no A channel")
            .1,
        alpha
    );
    // Resumed from the first part: the same frame.
    render(
        &["--resume", d.join("a.trp").to_str().unwrap()],
        &d.join("resumed.exr"),
    );
    assert_eq!(
        std::fs::read(d.join("full.exr")).unwrap(),
        std::fs::read(d.join("resumed.exr")).unwrap(),
        "resumed EXR differs from the single render"
    );
    // An opaque part does not merge with a transparent one.
    ok(bin()
        .args(["render", "-q", "--spp", "6", "--samples", "0..2"])
        .arg(&scene)
        .args(SIZE)
        .arg("-o")
        .arg(d.join("opaque.trp"))
        .output()
        .unwrap());
    let o = merge([d.join("opaque.trp"), d.join("b.trp")], &d.join("bad.exr"));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("path"), "{e}");
}
