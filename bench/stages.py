#!/usr/bin/env python3
"""Where a camera sample's time goes, per stage, on bench/compare.py's small scenes: Trayecto by
callgrind (instructions per sample, split by source file and function) and by wall clock, and
Mitsuba 3 `llvm_ad_rgb` by wall clock, both split by difference into "camera ray + first hit"
(a render that stops at the first surface: Trayecto `--max-depth 0`, Mitsuba `max_depth 1`) and
the rest of the path.

Usage (from the repository root, after `python3 bench/compare.py` has exported the scenes into
bench/out/, or with bench/out/venv's Python, which has bpy, numpy and mitsuba):

    bench/out/venv/bin/python bench/stages.py callgrind --bin target/release/trayecto
    bench/out/venv/bin/python bench/stages.py wall --bin target/release/trayecto --rounds 5
    bench/out/venv/bin/python bench/stages.py callgrind --bin A --bin B   # before / after

callgrind: one render per scene at --cg-res² and --cg-spp on one thread, instructions counted only
inside the render passes (`--toggle-collect` on the tile jobs, `TileWork::render`: scene loading, BVH build and
image output are left out). Every instruction is charged to a stage by the source file it comes
from (callgrind keeps the file of inlined code) or, for std/glam/core_arch lines, by the function
it was inlined into. The stages:

  camera        camera ray generation (src/camera*, render::camera_ray, render::film_and_lens)
  traversal     BVH traversal for closest hits and shadow rays (src/accel/, World::occluded,
                World::candidate)
  intersection  primitive tests and hit attributes (src/geometry/, World::complete_*)
  shading/BSDF  textures, normal maps, BSDF set-up, eval and sample (src/material/, src/texture*,
                integrator/vertex.rs, world/queries.rs and what is inlined into it, sampling/warp.rs
                under Bsdf)
  lights        light choice, light sampling and MIS (src/light/, integrator/direct.rs, the
                discrete and 2D distributions of sampling/distribution.rs, std code inlined there)
  sampler       the sample stream (src/sampling/sampler.rs, rng.rs, sobol*.rs)
  film          accumulating samples into pixels (src/film/)
  path logic    the rest of the integrator's loop (integrator/path.rs, settings.rs, math.rs)
  other         tiles, passes, the per-sample stream set-up, libc's memcpy and libm's trigonometry
                (the environment map's atan2/acos), and everything not matched above

wall: --rounds interleaved rounds over the scenes; each round runs Trayecto full and depth-limited
and Mitsuba full and depth-limited (its second render of a sample count, so JIT compilation is left
out; the sampler of BENCHMARKS.md's table, Mitsuba's best per scene), --res² pixels, --spp samples,
--threads threads. Medians with the lowest and highest round. The machine's load is printed.
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, ".."))
OUT = os.path.join(HERE, "out")
sys.path.insert(0, HERE)

SCENES = ["cornell", "textured", "veach", "manylight", "envlit"]
# Mitsuba's best sampler per scene (time to equal error, BENCHMARKS.md's table against Mitsuba).
MITSUBA_SAMPLER = {"cornell": "stratified", "textured": "multijitter", "veach": "stratified",
                   "manylight": "stratified", "envlit": "ldsampler"}
STAGES = ["camera", "traversal", "intersection", "shading/BSDF", "lights", "sampler", "film",
          "path logic", "other"]

# (substring of the source file, stage): the file an instruction comes from decides first.
FILE_RULES = [
    ("src/camera", "camera"),
    ("src/accel/", "traversal"),
    ("src/geometry/", "intersection"),
    ("src/material/", "shading/BSDF"),
    ("src/texture", "shading/BSDF"),
    ("src/integrator/vertex.rs", "shading/BSDF"),
    ("src/world/queries.rs", "shading/BSDF"),
    ("src/light/", "lights"),
    ("src/sampling/distribution.rs", "lights"),
    ("src/integrator/direct.rs", "lights"),
    ("src/sampling/sampler.rs", "sampler"),
    ("src/sampling/rng.rs", "sampler"),
    ("src/sampling/sobol", "sampler"),
    ("src/sampling/zsobol", "sampler"),
    ("src/film/", "film"),
]
# (substring of the function, stage): for lines of std, glam, core_arch, libc and the
# project's shared files (world.rs, math.rs, warp.rs), the function they were inlined into.
FUNC_RULES = [
    ("render::camera_ray", "camera"),
    ("render::film_and_lens", "camera"),
    ("camera::", "camera"),
    ("World::occluded", "traversal"),
    ("World::candidate", "traversal"),
    ("accel::", "traversal"),
    ("World::complete", "intersection"),
    ("geometry::", "intersection"),
    ("Vertex::shade", "shading/BSDF"),
    ("world::queries", "shading/BSDF"),
    ("material::", "shading/BSDF"),
    ("texture::", "shading/BSDF"),
    ("light::", "lights"),
    ("sampling::distribution", "lights"),
    ("sampling::sampler", "sampler"),
    ("film::", "film"),
    ("integrator::", "path logic"),
]
LINE = re.compile(r"^\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+(.*?):(.*?)(\s+\[.*\])?\s*$")


def classify(path, func):
    for key, stage in FILE_RULES:
        if key in path:
            return stage
    for key, stage in FUNC_RULES:
        if key in func:
            return stage
    return "other"


def scene_args(scene):
    """The scene argument and extra flags of a Trayecto render of `scene` (bench/out's export)."""
    if scene == "cornell":
        return "cornell", []
    target, *flags = scene.split()
    if os.path.isfile(target):
        # A scene file given by path, with its own flags ("FILE --rgb"), when bench/out's
        # exports are not at hand.
        return target, flags
    glb = os.path.join(OUT, scene, f"{scene}.glb")
    if not os.path.exists(glb):
        sys.exit(f"{glb} is missing: run bench/compare.py --scenes {scene} once to export it")
    extra = []
    if scene == "envlit":
        env = os.path.join(OUT, "envlit", "env_for_trayecto.exr")
        if not os.path.exists(env):
            # Written once with Mitsuba's scalar variant, in a process of its own: switching this
            # process's variant would invalidate the llvm scenes `wall` holds.
            subprocess.run([sys.executable, "-c", "import compare, mitsuba as mi, numpy as np; "
                            "mi.set_variant('scalar_rgb'); compare.trayecto_env(mi, np)"], cwd=HERE, check=True)
        extra = ["--env", env]
    return glb, extra


def callgrind_stages(exe, scene, res, spp):
    """Instructions per camera sample by stage, and the total, inside the render passes."""
    target, extra = scene_args(scene)
    with tempfile.TemporaryDirectory() as tmp:
        cg = os.path.join(tmp, "cg.out")
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={cg}",
               "--toggle-collect=trayecto::render::TileWork::render*",
               exe, "render", target, "-o", os.path.join(tmp, "x.exr"), "--width", str(res),
               "--height", str(res), "--spp", str(spp), "--threads", "1", "--quiet", *extra]
        subprocess.run(cmd, check=True, capture_output=True)
        ann = subprocess.run(["callgrind_annotate", "--inclusive=no", "--threshold=100", "--auto=no", cg],
                             check=True, capture_output=True, text=True).stdout
    by = dict.fromkeys(STAGES, 0)
    total = 0
    for line in ann.splitlines():
        m = LINE.match(line)
        if not m or m.group(2) == "PROGRAM TOTALS" or "PROGRAM TOTALS" in line:
            continue
        n = int(m.group(1).replace(",", ""))
        by[classify(m.group(2), m.group(3))] += n
        total += n
    samples = res * res * spp
    return {k: v / samples for k, v in by.items()}, total / samples


def cmd_callgrind(args):
    rows = {}
    for exe in args.bin:
        for scene in args.scenes:
            by, total = callgrind_stages(exe, scene, args.cg_res, args.cg_spp)
            rows[(exe, scene)] = (by, total)
            print(f"{exe} {scene}: {total:.0f} instructions per sample", file=sys.stderr, flush=True)
    print(f"Instructions per camera sample (callgrind, {args.cg_res}² px, {args.cg_spp} spp, 1 thread, "
          "render passes only); share of the total in parentheses\n")
    head = "| scene | build | total | " + " | ".join(STAGES) + " |"
    print(head)
    print("|" + "---|" * (3 + len(STAGES)))
    for scene in args.scenes:
        for exe in args.bin:
            by, total = rows[(exe, scene)]
            cells = [f"{by[s]:.0f} ({100 * by[s] / total:.0f} %)" for s in STAGES]
            print(f"| {scene} | {os.path.basename(exe)} | {total:.0f} | " + " | ".join(cells) + " |")
    if len(args.bin) == 2:
        print("\nChange of the total (second build / first): " + ", ".join(
            f"{s} {rows[(args.bin[1], s)][1] / rows[(args.bin[0], s)][1] - 1:+.2%}" for s in args.scenes))
    if args.json:
        json.dump({f"{e}|{s}": v for (e, s), v in rows.items()}, open(args.json, "w"), indent=1)


def trayecto_time(exe, scene, res, spp, threads, depth0):
    import compare
    target, extra = scene_args(scene)
    if depth0:
        extra = extra + ["--max-depth", "0"]
    with tempfile.TemporaryDirectory() as tmp:
        t, _ = compare.run_trayecto(exe, target, os.path.join(tmp, "x.exr"), (res, res), spp, 1, threads, extra)
    return t


class Mitsuba:
    """Scenes loaded once; `time` renders twice (compile, then timed) and returns seconds."""

    def __init__(self, threads, res):
        import compare
        if not compare.ensure_libllvm():
            sys.exit("no libLLVM >= 16 for Mitsuba's llvm_ad_rgb (apt-get install libllvm19)")
        import drjit as dr
        import mitsuba as mi
        mi.set_variant("llvm_ad_rgb")
        dr.set_thread_count(threads)
        self.dr, self.mi, self.res, self.scenes = dr, mi, res, {}

    def time(self, scene, spp, depth0):
        import compare
        import numpy as np
        key = (scene, depth0)
        if key not in self.scenes:
            d = compare.mitsuba_scene_dict(self.mi, scene, self.res, MITSUBA_SAMPLER[scene])
            if depth0:
                d["integrator"]["max_depth"] = 1
            self.scenes[key] = self.mi.load_dict(d)
            img = self.mi.render(self.scenes[key], spp=spp, seed=7919)
            np.array(img)
        t = time.perf_counter()
        img = self.mi.render(self.scenes[key], spp=spp, seed=1)
        np.array(img, dtype=np.float64)
        return time.perf_counter() - t


def spread(xs):
    return f"{statistics.median(xs):.3g} ({min(xs):.3g}–{max(xs):.3g})"


def cmd_wall(args):
    mi = Mitsuba(args.threads, args.res) if not args.no_mitsuba else None
    exe = args.bin[0]
    res = {s: {k: [] for k in ("t", "t0", "m", "m0")} for s in args.scenes}
    loads = []
    for r in range(args.rounds):
        loads.append(os.getloadavg()[0])
        for scene in args.scenes:
            res[scene]["t"].append(trayecto_time(exe, scene, args.res, args.spp, args.threads, False))
            res[scene]["t0"].append(trayecto_time(exe, scene, args.res, args.spp, args.threads, True))
            if mi:
                res[scene]["m"].append(mi.time(scene, args.spp, False))
                res[scene]["m0"].append(mi.time(scene, args.spp, True))
        print(f"round {r + 1}/{args.rounds} done", file=sys.stderr, flush=True)
    n = args.res * args.res * args.spp
    us = 1e6 * args.threads / n  # core-µs per camera sample, from seconds of wall time
    print(f"Core-µs per camera sample (wall × {args.threads} threads / samples; {args.res}² px, {args.spp} spp, "
          f"{args.rounds} interleaved rounds, median (lowest–highest); load {min(loads):.1f}–{max(loads):.1f})\n")
    print("| scene | Trayecto total | Trayecto first hit | Trayecto rest | Mitsuba total | Mitsuba first hit "
          "| Mitsuba rest | Trayecto / Mitsuba total (per-round spread) |")
    print("|---|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        d = res[scene]
        t = [x * us for x in d["t"]]
        t0 = [x * us for x in d["t0"]]
        tr = [a - b for a, b in zip(t, t0)]
        if mi:
            m = [x * us for x in d["m"]]
            m0 = [x * us for x in d["m0"]]
            mr = [a - b for a, b in zip(m, m0)]
            ratio = [a / b for a, b in zip(t, m)]
            mcells = f"{spread(m)} | {spread(m0)} | {spread(mr)} | {spread(ratio)}"
        else:
            mcells = "– | – | – | –"
        print(f"| {scene} | {spread(t)} | {spread(t0)} | {spread(tr)} | {mcells} |")
    if args.json:
        json.dump(res, open(args.json, "w"), indent=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["callgrind", "wall"])
    ap.add_argument("--bin", action="append", help="trayecto binary (callgrind: one or two)")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--cg-res", type=int, default=32)
    ap.add_argument("--cg-spp", type=int, default=16)
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--no-mitsuba", action="store_true")
    ap.add_argument("--json", help="also write the raw numbers here")
    args = ap.parse_args()
    args.bin = args.bin or [os.path.join(ROOT, "target", "release", "trayecto")]
    args.scenes = args.scenes.split(",")
    (cmd_callgrind if args.mode == "callgrind" else cmd_wall)(args)


if __name__ == "__main__":
    main()
