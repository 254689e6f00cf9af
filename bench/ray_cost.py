#!/usr/bin/env python3
"""Issue #23's throughput bar: rays per second of ToyCar and DamagedHelmet against the built-in
Cornell box, by wall clock (interleaved rounds) and by callgrind instructions per ray.

    python3 bench/ray_cost.py wall [--bins A B ...] [--rounds 3]
    python3 bench/ray_cost.py callgrind [--bins A B ...]

wall: `trayecto render SCENE --spp 4` (512², 2 threads, no other options, as the issue measures
it), scenes and binaries alternated in each round; the CLI's last line gives `X Mrays/s` (all
rays traced over the `rendered` phase). Prints per binary and scene the median and min–max
Mrays/s and the share of Cornell's, computed per round (a round's three renders ran back to
back, so they saw a similar load), with its median and min–max.

callgrind: `valgrind --tool=callgrind BIN render SCENE --width 64 --height 64 --spp 4
--threads 1` (load-independent): the inclusive instructions of the render (`path::radiance`
and `Bvh::intersect*` / `Bvh::occluded*` separately) divided by the rays the CLI reports, and the
closest-hit / shadow traversal instructions per call.
"""
import argparse
import os
import re
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


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["wall", "callgrind"])
    ap.add_argument("--bins", nargs="+", default=[os.path.join(ROOT, "target", "release", "trayecto")])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--scenes", nargs="+", choices=list(SCENES), default=list(SCENES),
                    help="callgrind only: the scenes to run (wall always runs all three)")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        (wall if args.mode == "wall" else callgrind)(args, tmp)
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
