#!/usr/bin/env python3
"""The throughput bar (BENCHMARKS.md, "Rays per second on real models"): rays per second of
ToyCar and DamagedHelmet against the built-in Cornell box, by wall clock (interleaved rounds)
and by callgrind instructions per ray.

    python3 bench/ray_cost.py wall [--bins A B ...] [--rounds 3]
    python3 bench/ray_cost.py callgrind [--bins A B ...]
    python3 bench/ray_cost.py peers [--bins A] [--rounds 3] [--res 256] [--spp 4]

wall: `trayecto render SCENE --spp 4` (512², 2 threads, no other options, as the issue measures
it), scenes and binaries alternated in each round; the CLI's last line gives `X Mrays/s` (all
rays traced over the `rendered` phase). Prints per binary and scene the median and min–max
Mrays/s and the share of Cornell's, computed per round (a round's three renders ran back to
back, so they saw a similar load), with its median and min–max.

callgrind: `valgrind --tool=callgrind BIN render SCENE --width 64 --height 64 --spp 4
--threads 1` (load-independent): the inclusive instructions of the render (`path::radiance`
and `Bvh::intersect*` / `Bvh::occluded*` separately) divided by the rays the CLI reports, and the
closest-hit / shadow traversal instructions per call.

peers: what the bar means against a peer. Trayecto and pbrt-v4 (../shared/tools/pbrt-v4, its
default `zsobol` sampler, `--stats`) render the same edited copies of Bitterli's pbrt-v4 scenes
(bench/compare.py's `pbrt_copy`: `--res` pixels high, aspect kept, the file's integrator and max
depth), `--spp` samples, 2 threads, interleaved rounds; Trayecto also renders its built-in Cornell
box, ToyCar and DamagedHelmet at the same size. Rays: Trayecto's CLI count; pbrt-v4's "Regular ray
intersection tests" + "Shadow ray intersection tests" (every closest-hit and every shadow query,
camera rays included). Time: Trayecto's `rendered` phase; pbrt-v4's between its verbose log lines
"Memory used after scene creation" and "Writing image with spp" (as compare.py times it). Prints
each renderer's Mrays/s per scene and its share of the same renderer's Bitterli Cornell box
(and, for Trayecto, of its built-in one), per round: the two renderers trace different numbers of
rays per sample (their Russian roulette differs), so only each one's own ratios compare.
../shared's dining-room lacks textures/picture3.tga (pbrt-v4 refuses the file): the copy gets
textures/Teacup.tga under that name, which both renderers then read.
"""
import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, ".."))
SHARED = os.path.normpath(os.path.join(ROOT, "..", "shared", "scenes"))
SCENES = {
    "cornell": "cornell",
    "DamagedHelmet": os.path.join(SHARED, "gltf", "DamagedHelmet", "glTF", "DamagedHelmet.gltf"),
    "ToyCar": os.path.join(SHARED, "gltf-ext", "ToyCar", "glTF", "ToyCar.gltf"),
}
RAYS = re.compile(r"rays\s+(\d+) \((\d+) camera/bounce/reflection/refraction, (\d+) shadow\), ([0-9.]+) Mrays/s")


def render(exe, scene, extra, out):
    r = subprocess.run([exe, "render", scene, "-o", out, *extra], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{exe} {scene} failed: {r.stderr.strip()[-500:]}")
    m = RAYS.search(r.stderr)
    if not m:
        sys.exit(f"no rays line in the output of {exe} {scene}")
    return r.stderr, int(m.group(1)), int(m.group(2)), int(m.group(3)), float(m.group(4))


def spread(xs):
    return f"{statistics.median(xs):.3f} ({min(xs):.3f}–{max(xs):.3f})"


def wall(args, tmp):
    res = {(b, s): [] for b in args.bins for s in SCENES}
    for r in range(args.rounds):
        for b in args.bins:
            for s, path in SCENES.items():
                _, _, _, _, mr = render(b, path, ["--spp", "4"], os.path.join(tmp, "w.exr"))
                res[(b, s)].append(mr)
        print(f"round {r + 1}: load {os.getloadavg()[0]:.1f}: " +
              ", ".join(f"{os.path.basename(os.path.dirname(os.path.dirname(os.path.dirname(b))) or b)}"
                        f"/{s} {res[(b, s)][-1]:.2f}" for b in args.bins for s in SCENES), flush=True)
    print("\n| binary | scene | Mrays/s median (min–max) | share of Cornell, per round: median (min–max) |")
    print("|---|---|---|---|")
    for b in args.bins:
        for s in SCENES:
            share = [x / c for x, c in zip(res[(b, s)], res[(b, "cornell")])]
            print(f"| {b} | {s} | {spread(res[(b, s)])} | {spread([100 * x for x in share])} % |")


def inclusive(annotate, pattern):
    total = 0
    for line in annotate.splitlines():
        m = re.match(r"\s*([0-9,]+) \([^)]*\)\s+\*?\s*(\S.*)$", line)
        if m and re.search(pattern, m.group(2)):
            total = max(total, int(m.group(1).replace(",", "")))
    return total


def callgrind(args, tmp):
    print("| binary | scene | rays (shadow) | render Ir / ray | closest-hit Ir / call | shadow Ir / call |")
    print("|---|---|---|---|---|---|")
    for b in args.bins:
        for s in args.scenes:
            path = SCENES[s]
            out = os.path.join(tmp, f"cg.{s}.out")
            r = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", b, "render", path,
                                "--width", "64", "--height", "64", "--spp", "4", "--threads", "1",
                                "-o", os.path.join(tmp, "c.exr")], capture_output=True, text=True)
            m = RAYS.search(r.stderr)
            if r.returncode != 0 or not m:
                sys.exit(f"callgrind run of {b} {s} failed: {r.stderr[-500:]}")
            # One closest-hit query per camera/bounce ray and one occlusion query per shadow ray.
            rays, hit_n, occ_n = int(m.group(1)), int(m.group(2)), int(m.group(3))
            ann = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100", out],
                                 capture_output=True, text=True).stdout
            render_ir = inclusive(ann, r"path::radiance")
            hit_ir = inclusive(ann, r"Bvh>?::intersect_avx2|Bvh>?::intersect_portable")
            occ_ir = inclusive(ann, r"Bvh>?::occluded_avx2|Bvh>?::occluded_portable")
            print(f"| {b} | {s} | {rays} ({occ_n}) | {render_ir / rays:.0f} | "
                  f"{hit_ir / max(hit_n, 1):.0f} | {occ_ir / max(occ_n, 1):.0f} |", flush=True)


PEER_SCENES = ["pbrt-cornell-box", "pbrt-veach-mis", "pbrt-coffee", "pbrt-dining-room"]
PBRT_RAYS = re.compile(r"(Regular|Shadow) ray intersection tests\s+(\d+)")


def pbrt_render(compare, scene, spp, out):
    """One pbrt-v4 render of `scene` (an edited copy), timed as compare.py times it: (rays,
    seconds)."""
    try:
        sec, stats = compare.run_pbrt(scene, out, spp, 0, 2, extra=["--stats"])
    except RuntimeError as e:
        sys.exit(f"{scene}: {e}")
    rays = sum(int(m.group(2)) for m in PBRT_RAYS.finditer(stats))
    if rays == 0:
        sys.exit(f"{scene}: pbrt-v4's --stats printed no ray intersection counts")
    return rays, sec


def trayecto_render(exe, scene, extra, out):
    """One Trayecto render: (rays, seconds of the `rendered` phase)."""
    err, rays, _, _, _ = render(exe, scene, extra, out)
    m = re.search(r"rendered \([^)]*\)\s+([0-9.]+) ms", err)
    if not m:
        sys.exit(f"no rendered line in the output of {exe} {scene}")
    return rays, float(m.group(1)) / 1000


def peers(args, tmp):
    import compare  # bench/, the script's own folder, is on the import path
    if not os.path.exists(compare.PBRT_EXE):
        sys.exit(f"no pbrt-v4 binary at {compare.PBRT_EXE} (see ../shared/tools/pbrt-v4/README.md)")
    files = {}
    for s in PEER_SCENES:
        path, _, _ = compare.pbrt_copy(s, args.res, None)
        tex = os.path.join(os.path.dirname(path), "textures")
        if s == "pbrt-dining-room" and not os.path.exists(os.path.join(tex, "picture3.tga")):
            shutil.copyfile(os.path.join(tex, "Teacup.tga"), os.path.join(tex, "picture3.tga"))
        files[s] = path
    exe = args.bins[0]
    size = ["--width", str(args.res), "--height", str(args.res)]
    rows = {}  # (renderer, scene) -> [Mrays/s per round]
    out = os.path.join(tmp, "p.exr")
    for r in range(args.rounds):
        for s, path in files.items():
            for who in ("trayecto", "pbrt-v4"):
                rays, sec = (trayecto_render(exe, path, ["--spp", str(args.spp)], out) if who == "trayecto"
                             else pbrt_render(compare, path, args.spp, out))
                rows.setdefault((who, s), []).append(rays / sec / 1e6)
        for s in ("cornell", "DamagedHelmet", "ToyCar"):
            rays, sec = trayecto_render(exe, SCENES[s], ["--spp", str(args.spp), *size], out)
            rows.setdefault(("trayecto", s), []).append(rays / sec / 1e6)
        print(f"round {r + 1}: load {os.getloadavg()[0]:.1f}: " +
              ", ".join(f"{w}/{s} {v[-1]:.2f}" for (w, s), v in rows.items()), flush=True)
    print(f"\n{args.res} px high, {args.spp} spp, 2 threads, {args.rounds} rounds; Trayecto {exe}")
    print("\n| renderer | scene | Mrays/s median (min–max) | share of its pbrt-cornell-box, per round "
          "| share of the built-in Cornell box, per round |")
    print("|---|---|---|---|---|")
    for (who, s), v in rows.items():
        base = rows[(who, "pbrt-cornell-box")]
        own = spread([100 * x / c for x, c in zip(v, base)]) + " %"
        builtin = (spread([100 * x / c for x, c in zip(v, rows[("trayecto", "cornell")])]) + " %"
                   if who == "trayecto" else "—")
        print(f"| {who} | {s} | {spread(v)} | {own} | {builtin} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["wall", "callgrind", "peers"])
    ap.add_argument("--bins", nargs="+", default=[os.path.join(ROOT, "target", "release", "trayecto")])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--scenes", nargs="+", choices=list(SCENES), default=list(SCENES),
                    help="callgrind only: the scenes to run (wall always runs all three)")
    ap.add_argument("--res", type=int, default=256, help="peers only: image height in pixels")
    ap.add_argument("--spp", type=int, default=4, help="peers only: samples per pixel")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        {"wall": wall, "callgrind": callgrind, "peers": peers}[args.mode](args, tmp)
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
