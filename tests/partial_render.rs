//! Split renders: sample ranges rendered apart and merged, and renders stopped and
//! resumed, give the film of a single run bit for bit; merge refuses parts that do not belong
//! together, overlap or leave gaps; hostile partial films are refused with a message.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use trayecto::film::Film;
use trayecto::render::{RangeStart, RenderObserver, RenderSettings, render, render_range};
use trayecto::sampling::SamplerKind;
use trayecto::split::partial::{Part, PartError, PartHeader, merge};
use trayecto::world::{World, WorldOptions};

const SPP: u32 = 13;

fn world() -> World {
    let scene = trayecto::scene::load("cornell").unwrap();
    World::build(
        scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap()
}

fn settings(sampler: SamplerKind) -> RenderSettings {
    RenderSettings {
        width: 20,
        height: 14,
        spp: SPP,
        seed: 7,
        sampler,
        threads: Some(2),
        ..RenderSettings::default()
    }
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trayecto-partial-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn part_of(world: &World, s: &RenderSettings, a: u32, b: u32) -> Part {
    let r = render_range(
        world,
        s,
        RangeStart {
            samples: a..b,
            resume: None,
        },
        &trayecto::render::NoObserver,
        &AtomicBool::new(false),
    )
    .unwrap();
    assert!(!r.cancelled && r.done == b && r.start == a);
    let header = PartHeader::new(
        "cornell",
        "digest",
        s,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
        world.lights.sampler_kind(),
        [a, b],
        r.film.discarded,
    );
    Part {
        header,
        film: r.film,
    }
}

fn single(world: &World, s: &RenderSettings) -> Film {
    part_of(world, s, 0, s.spp).film
}

/// Parts written to disk and read back, in a scrambled order, merge to the single run's film.
fn merged(world: &World, s: &RenderSettings, cuts: &[u32], tag: &str) -> Part {
    let mut parts = Vec::new();
    for w in cuts.windows(2) {
        let p = part_of(world, s, w[0], w[1]);
        let path = tmp(&format!("{tag}-{}-{}.trp", w[0], w[1]));
        p.write(&path).unwrap();
        parts.push((path.clone(), Part::read(&path).unwrap()));
    }
    parts.reverse();
    let half = parts.len() / 2;
    parts.rotate_left(half);
    merge(parts, true).unwrap()
}

#[test]
fn merging_1_3_and_7_uneven_ranges_is_bit_identical_to_a_single_render() {
    let world = world();
    for sampler in [
        SamplerKind::Stratified,
        SamplerKind::Sobol,
        SamplerKind::ZSobol,
    ] {
        let s = settings(sampler);
        let reference = single(&world, &s);
        let image = render(
            &world,
            &s,
            &trayecto::render::NoObserver,
            &AtomicBool::new(false),
        )
        .unwrap()
        .image;
        assert_eq!(reference.to_image(), image);
        for cuts in [&[0, SPP][..], &[0, 2, 9, SPP], &[0, 1, 3, 4, 8, 9, 12, SPP]] {
            let m = merged(&world, &s, cuts, &format!("{sampler:?}-{}", cuts.len()));
            assert_eq!(m.header.samples, [0, SPP]);
            assert!(
                m.film == reference,
                "{sampler:?}: {} parts differ from the single render",
                cuts.len() - 1
            );
            assert_eq!(m.film.to_image(), image);
        }
    }
}

fn merge_err(parts: Vec<(PathBuf, Part)>, complete: bool) -> String {
    match merge(parts, complete) {
        Err(PartError::Merge(m)) => m,
        Err(e) => panic!("unexpected error kind: {e}"),
        Ok(p) => panic!("merge accepted bad parts: {:?}", p.header.samples),
    }
}

#[test]
fn merge_refuses_mismatched_overlapping_and_missing_parts() {
    let world = world();
    let s = settings(SamplerKind::Stratified);
    let a = part_of(&world, &s, 0, 5);
    let b = part_of(&world, &s, 5, SPP);
    let named = |n: &str, p: &Part| (PathBuf::from(n), p.clone());

    // Another seed: a different frame.
    let other = part_of(
        &world,
        &RenderSettings {
            seed: 8,
            ..s.clone()
        },
        5,
        SPP,
    );
    let m = merge_err(vec![named("a.trp", &a), named("b.trp", &other)], true);
    assert!(m.contains("b.trp") && m.contains("'seed'"), "{m}");

    // Other scene content, other size, other frame spp, other version.
    let mut h = b.clone();
    h.header.scene_digest = "0123456789abcdef".into();
    let m = merge_err(vec![named("a.trp", &a), named("b.trp", &h)], true);
    assert!(m.contains("scene content"), "{m}");
    let mut h = b.clone();
    h.header.spp = 26;
    let m = merge_err(vec![named("a.trp", &a), named("b.trp", &h)], true);
    assert!(m.contains("samples per pixel"), "{m}");
    let mut h = b.clone();
    h.header.trayecto_version = "0.0.1".into();
    let m = merge_err(vec![named("a.trp", &a), named("b.trp", &h)], true);
    assert!(m.contains("version"), "{m}");
    // Another build of the same version (another render identity): refused, naming both.
    let mut h = b.clone();
    h.header.render_identity = "0badc0de".repeat(8);
    let m = merge_err(vec![named("a.trp", &a), named("b.trp", &h)], true);
    let ours = &trayecto::RENDER_IDENTITY[..16];
    assert!(
        m.contains("b.trp")
            && m.contains("another build")
            && m.contains("0badc0de0badc0de")
            && m.contains(ours),
        "{m}"
    );
    // Its header records this build's identity and the resolved light sampler (cornell's two
    // lights: `auto` is the power distribution), not `auto`.
    assert_eq!(a.header.render_identity, trayecto::RENDER_IDENTITY);
    assert_eq!(
        a.header.settings.get("light_sampler").map(|s| s.as_str()),
        Some("power")
    );
    let mut h = b.clone();
    h.header
        .settings
        .insert("light_sampler".into(), "bvh8".into());
    let m = merge_err(vec![named("a.trp", &a), named("b.trp", &h)], true);
    assert!(m.contains("'light_sampler'") && m.contains("bvh8"), "{m}");

    // Overlap: 0..5 and 4..13.
    let c = part_of(&world, &s, 4, SPP);
    let m = merge_err(vec![named("a.trp", &a), named("c.trp", &c)], true);
    assert!(m.contains("overlap on samples 4..5"), "{m}");
    // The same part twice.
    let m = merge_err(
        vec![named("a.trp", &a), named("a2.trp", &a), named("b.trp", &b)],
        true,
    );
    assert!(m.contains("overlap"), "{m}");

    // Gaps: inside, at the start, at the end.
    let d = part_of(&world, &s, 6, SPP);
    let m = merge_err(vec![named("a.trp", &a), named("d.trp", &d)], true);
    assert!(m.contains("samples 5..6 are missing"), "{m}");
    let m = merge_err(vec![named("b.trp", &b)], true);
    assert!(m.contains("samples 0..5 are missing"), "{m}");
    let m = merge_err(vec![named("a.trp", &a)], true);
    assert!(m.contains("samples 5..13 are missing"), "{m}");
    assert!(merge_err(vec![], true).contains("no parts"));

    // An incomplete but contiguous merge is allowed when asked for: 0..5 and 5..9 of the 13
    // samples give the longer part 0..9, the film of rendering 0..9 at once (merging is exact);
    // the same parts as a complete merge are refused, and a real gap is refused either way.
    let e = part_of(&world, &s, 5, 9);
    let ae = merge(vec![named("a.trp", &a), named("e.trp", &e)], false).unwrap();
    assert_eq!(ae.header.samples, [0, 9]);
    assert!(
        ae.film == part_of(&world, &s, 0, 9).film,
        "0..5 + 5..9 is not 0..9"
    );
    let m = merge_err(vec![named("a.trp", &a), named("e.trp", &e)], true);
    assert!(m.contains("samples 9..13 are missing"), "{m}");
    let m = merge_err(vec![named("a.trp", &a), named("d.trp", &d)], false);
    assert!(m.contains("samples 5..6 are missing"), "{m}");
    let ab = merge(vec![named("a.trp", &a), named("b.trp", &b)], false).unwrap();
    assert_eq!(ab.header.samples, [0, SPP]);
}

#[test]
fn hostile_partial_films_are_refused_with_a_message() {
    let world = world();
    let s = settings(SamplerKind::Stratified);
    let p = part_of(&world, &s, 0, 3);
    let good = tmp("good.trp");
    p.write(&good).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let check = |name: &str, data: &[u8], want: &str| {
        let path = tmp(name);
        std::fs::write(&path, data).unwrap();
        let e = Part::read(&path).unwrap_err().to_string();
        assert!(e.contains(name) && e.contains(want), "{name}: {e}");
    };
    check("empty.trp", b"", "too short");
    check("magic.trp", b"NOTAPARTxxxxxxxxxxxx", "TRAYPART");
    let mut huge = b"TRAYPART".to_vec();
    huge.extend_from_slice(&u32::MAX.to_le_bytes());
    check("huge.trp", &huge, "header is");
    check("cut.trp", &bytes[..bytes.len() - 9], "truncated or corrupt");
    let mut extra = bytes.clone();
    let n = extra.len();
    extra[n - 20] ^= 0x55;
    check("flipped.trp", &extra, "corrupt");
    // A header that lies: a sample range past the frame, a size too big for the data.
    let hlen = u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize;
    let header = std::str::from_utf8(&bytes[12..12 + hlen]).unwrap();
    let rewrite = |from: &str, to: &str| {
        let h = header.replacen(from, to, 1);
        assert_ne!(h, header, "{from} not in header");
        let mut out = b"TRAYPART".to_vec();
        out.extend_from_slice(&(h.len() as u32).to_le_bytes());
        out.extend_from_slice(h.as_bytes());
        out.extend_from_slice(&bytes[12 + hlen..]);
        out
    };
    // A format-1 part (before render identities): refused with a message saying why and what to
    // do, whether or not its header has the field.
    let v1 = rewrite("\"format\":2", "\"format\":1");
    check("format1.trp", &v1, "render it again");
    let no_id = {
        let id = format!(",\"render_identity\":\"{}\"", trayecto::RENDER_IDENTITY);
        let h = header
            .replacen("\"format\":2", "\"format\":1", 1)
            .replacen(&id, "", 1);
        assert!(!h.contains("render_identity"), "{h}");
        let mut out = b"TRAYPART".to_vec();
        out.extend_from_slice(&(h.len() as u32).to_le_bytes());
        out.extend_from_slice(h.as_bytes());
        out.extend_from_slice(&bytes[12 + hlen..]);
        out
    };
    check("format1-old.trp", &no_id, "before render identities");
    check(
        "range.trp",
        &rewrite("\"samples\":[0,3]", "\"samples\":[0,99]"),
        "sample range",
    );
    check(
        "size.trp",
        &rewrite("\"width\":20", "\"width\":21"),
        "truncated or corrupt",
    );
    check(
        "giant.trp",
        &rewrite("\"width\":20", "\"width\":1000000"),
        "out of range",
    );
    // Counts beyond the range: claim the part holds one sample while pixels have three.
    check(
        "counts.trp",
        &rewrite("\"samples\":[0,3]", "\"samples\":[2,3]"),
        "impossible values",
    );
}

/// Sets the cancel flag after `stop_after` passes: a real interruption through the public API.
struct StopAfter<'a> {
    passes: std::sync::atomic::AtomicU32,
    stop_after: u32,
    cancel: &'a AtomicBool,
}

impl RenderObserver for StopAfter<'_> {
    fn pass_done(&self, _film: &Film, _done: u32, _spp: u32) {
        if self.passes.fetch_add(1, Ordering::Relaxed) + 1 == self.stop_after {
            self.cancel.store(true, Ordering::Relaxed);
        }
    }
}

#[test]
fn a_resumed_render_equals_an_uninterrupted_one() {
    let world = world();
    let s = RenderSettings {
        spp: 40,
        ..settings(SamplerKind::Stratified)
    };
    let reference = single(&world, &s);
    for stop_after in [1, 3, 4] {
        let cancel = AtomicBool::new(false);
        let obs = StopAfter {
            passes: 0.into(),
            stop_after,
            cancel: &cancel,
        };
        let start = RangeStart {
            samples: 0..s.spp,
            resume: None,
        };
        let stopped = render_range(&world, &s, start, &obs, &cancel).unwrap();
        assert!(stopped.cancelled);
        // Passes are 1, 1, 2, 4, ... samples: the film holds the passes before the stop.
        let expect_done = [1, 2, 4, 8][stop_after as usize - 1];
        assert_eq!(stopped.done, expect_done);
        // Through a checkpoint file, as the command line does it.
        let path = tmp(&format!("checkpoint-{stop_after}.trp"));
        let header = PartHeader::new(
            "cornell",
            "d",
            &s,
            &WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..WorldOptions::default()
            },
            world.lights.sampler_kind(),
            [0, stopped.done],
            stopped.film.discarded,
        );
        Part {
            header,
            film: stopped.film,
        }
        .write(&path)
        .unwrap();
        let cp = Part::read(&path).unwrap();
        let resumed = render_range(
            &world,
            &s,
            RangeStart {
                samples: 0..s.spp,
                resume: Some((cp.film, cp.header.samples[1])),
            },
            &trayecto::render::NoObserver,
            &AtomicBool::new(false),
        )
        .unwrap();
        assert!(!resumed.cancelled && resumed.done == s.spp);
        assert!(
            resumed.film == reference,
            "stopped after {stop_after} passes"
        );
    }
}

#[test]
fn render_range_refuses_bad_ranges() {
    let world = world();
    let s = settings(SamplerKind::Stratified);
    let run = |a: u32, b: u32, resume: Option<(Film, u32)>| {
        render_range(
            &world,
            &s,
            RangeStart {
                samples: a..b,
                resume,
            },
            &trayecto::render::NoObserver,
            &AtomicBool::new(false),
        )
        .map(|_| ())
        .unwrap_err()
        .to_string()
    };
    assert!(run(3, 3, None).contains("sample range 3..3"));
    assert!(run(0, SPP + 1, None).contains("within 0..13"));
    assert!(run(4, 8, Some((Film::new(20, 14), 2))).contains("outside"));
    assert!(run(0, 8, Some((Film::new(3, 3), 2))).contains("3x3"));
}

/// Records every film `pass_done` is shown.
struct Record(std::sync::Mutex<Vec<(u32, Film)>>);

impl RenderObserver for Record {
    fn pass_done(&self, film: &Film, done: u32, _spp: u32) {
        self.0.lock().unwrap().push((done, film.clone()));
    }
}

/// Passes are pipelined (workers start the next pass's tiles while the last ones of a pass
/// finish): `pass_done` still sees every pass once, in order, with a film that holds exactly
/// the samples of the passes done (none of the next pass's), and the same films for 1, 2 and 3
/// threads. 48×40 pixels make 9 tiles; 20 spp make passes of 1, 1, 2, 4, 8, 4 samples.
#[test]
fn pass_done_sees_each_complete_pass_in_order_for_any_thread_count() {
    let world = world();
    let ends: Vec<u32> = trayecto::render::pass_schedule(20)
        .iter()
        .map(|p| p.1)
        .collect();
    assert_eq!(ends, [1, 2, 4, 8, 16, 20]);
    let mut seen = Vec::new();
    for threads in [1, 2, 3] {
        let s = RenderSettings {
            width: 48,
            height: 40,
            spp: 20,
            threads: Some(threads),
            ..settings(SamplerKind::Stratified)
        };
        let rec = Record(Default::default());
        let start = RangeStart {
            samples: 0..s.spp,
            resume: None,
        };
        let r = render_range(&world, &s, start, &rec, &AtomicBool::new(false)).unwrap();
        assert!(!r.cancelled && !r.stopped_early && r.done == 20);
        let films = rec.0.into_inner().unwrap();
        assert_eq!(films.iter().map(|f| f.0).collect::<Vec<_>>(), ends);
        for (done, film) in &films {
            assert!(
                film.counts().iter().all(|&c| c == *done),
                "{threads} threads: the film shown after {done} samples holds other counts"
            );
        }
        assert_eq!(films.last().unwrap().1, r.film);
        seen.push(films);
    }
    assert!(
        seen[0] == seen[1] && seen[1] == seen[2],
        "films differ between thread counts"
    );
}
