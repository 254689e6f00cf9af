#!/usr/bin/env python3
"""The surface path tracer's two bounce loops by wall clock: the scalar loop (one path at a time)
and the wavefront loop (integrator/wavefront.rs), selected by TRAYECTO_PATH_LOOP, optionally with
a baseline binary, in interleaved rounds; the render phase only (the "rendered" line of the log).

    python3 bench/path_loop.py --bin target/release/trayecto [--base BASE] \
        [--rounds 5] [--res 96] [--spp 32] [--threads 1] [--scenes cornell,FILE,...] \
        [--simd portable,avx2,avx512]

Prints per scene the median render time of each configuration (lowest–highest round) and the
wavefront's time over the scalar loop's, per round, as median (lowest–highest). With --simd, the
wavefront loop of --bin also runs at each named SIMD level (TRAYECTO_SIMD), and with --base every
configuration's time over the base's, per round.
"""
import argparse
import os
import re
import statistics
import subprocess
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, ".."))
SHARED = os.path.normpath(os.path.join(ROOT, "..", "shared", "scenes"))
SCENES = [
    "cornell",
    os.path.join(SHARED, "gltf/BoxTextured/glTF-Binary/BoxTextured.glb"),
    os.path.join(SHARED, "pbrt/veach-mis/scene-v4.pbrt") + " --rgb",
    "scenes/mitsuba/envmap.toml",
    os.path.join(SHARED, "gltf/EmissiveStrengthTest/glTF-Binary/EmissiveStrengthTest.glb"),
]
RENDERED = re.compile(r"^rendered \([^)]*\)\s+([\d.]+) (ms|s)\b", re.M)


def render_time(exe, scene, path_loop, args, simd=None):
    target, *extra = scene.split()
    env = dict(os.environ, TRAYECTO_PATH_LOOP=path_loop)
    env.pop("TRAYECTO_SIMD", None)
    if simd:
        env["TRAYECTO_SIMD"] = simd
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run([exe, "render", target, "-o", os.path.join(tmp, "x.exr"), "--width", str(args.res),
                              "--height", str(args.res), "--spp", str(args.spp), "--threads", str(args.threads),
                              *extra], cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    m = RENDERED.search(out.stderr)
    if not m:
        raise SystemExit(f"no render time in the log of {scene}:\n{out.stderr}")
    return float(m.group(1)) / (1000.0 if m.group(2) == "ms" else 1.0)


def spread(xs):
    return f"{statistics.median(xs):.3g} ({min(xs):.3g}–{max(xs):.3g})"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", required=True)
    ap.add_argument("--base", help="a baseline binary, run as it is")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--res", type=int, default=96)
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--scenes", default="|".join(SCENES), help="'|'-separated scene[ flags]")
    ap.add_argument("--simd", default="", help="comma-separated SIMD levels for extra wavefront runs")
    args = ap.parse_args()
    scenes = args.scenes.split("|")
    configs = [("scalar", args.bin, "scalar", None), ("wavefront", args.bin, "wavefront", None)]
    configs += [(f"wavefront {lv}", args.bin, "wavefront", lv) for lv in args.simd.split(",") if lv]
    if args.base:
        configs.insert(0, ("base", args.base, "", None))
    t = {(s, c): [] for s in scenes for c, _, _, _ in configs}
    loads = []
    for r in range(args.rounds):
        loads.append(os.getloadavg()[0])
        for s in scenes:
            for c, exe, loop, simd in configs:
                t[(s, c)].append(render_time(exe, s, loop, args, simd))
    print(f"Render seconds ({args.res}² px, {args.spp} spp, {args.threads} thread(s), {args.rounds} interleaved "
          f"rounds, median (lowest–highest); load {min(loads):.1f}–{max(loads):.1f})\n")
    print("| scene | " + " | ".join(c for c, _, _, _ in configs) + " | wavefront / scalar |")
    print("|---|" + "---|" * (len(configs) + 1))
    for s in scenes:
        ratio = [w / x for w, x in zip(t[(s, "wavefront")], t[(s, "scalar")])]
        name = os.path.basename(s.split()[0]) + "".join(" " + f for f in s.split()[1:])
        print(f"| {name} | " + " | ".join(spread(t[(s, c)]) for c, _, _, _ in configs) + f" | {spread(ratio)} |")
    if args.base:
        others = [c for c, _, _, _ in configs if c != "base"]
        print("\nTime over the base's, per round: median (lowest–highest)\n")
        print("| scene | " + " | ".join(others) + " |")
        print("|---|" + "---|" * len(others))
        for s in scenes:
            name = os.path.basename(s.split()[0]) + "".join(" " + f for f in s.split()[1:])
            cells = [spread([x / b for x, b in zip(t[(s, c)], t[(s, "base")])]) for c in others]
            print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
