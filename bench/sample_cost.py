#!/usr/bin/env python3
"""Time per sample on compare.py's small scenes, as compare.py runs Trayecto: the
built-in Cornell box and the exported textured, veach and envlit scenes
(bench/out/<scene>/<scene>.glb, written by `python3 bench/compare.py --quick --scenes
textured,veach,envlit`; envlit is lit by `--env bench/out/envlit/env_for_trayecto.exr`), default
settings.

    python3 bench/sample_cost.py callgrind [--bins A B ...] [--scenes ...] [--spp 16] [--top 12]
    python3 bench/sample_cost.py wall [--bins A B ...] [--scenes ...] [--rounds 5]
    python3 bench/sample_cost.py cpu [--bins A B ...] [--scenes ...] [--rounds 5]

callgrind: `valgrind --tool=callgrind --toggle-collect='trayecto::render::render_range_aovs::*'
BIN render SCENE --width 64 --height 64 --spp N --threads 1 --seed 1` (load-independent): the
render's instructions divided by the camera samples (64 x 64 x N), and the functions with the
most exclusive instructions per sample (inlined code counts in the function it was inlined into).

wall: `BIN render SCENE --width 64 --height 64 --spp 64 --threads 2` (compare.py's quick top
ladder point), binaries alternated inside every round so a slow spell of the shared machine falls
on all of them; the `rendered` phase the CLI prints. Prints per scene and binary the median and
min-max in ms, and each binary's time over the first's, computed per round (median, min-max).

cpu: the process CPU time (user + system) of `--spp 68` minus that of `--spp 4` renders (64 x 64,
1 thread), over the 64 x 64 x 64 samples between them: the time per sample with loading, world
building and start-up cancelled, counting only what the process ran (not the time it waited for
cores shared with other work). Binaries alternated as in wall mode.
"""
import argparse
import collections
import os
import re
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, ".."))
SCENES = {
    "cornell": ["cornell"],
    "textured": [os.path.join(HERE, "out", "textured", "textured.glb")],
    "veach": [os.path.join(HERE, "out", "veach", "veach.glb")],
    "envlit": [os.path.join(HERE, "out", "envlit", "envlit.glb"),
               "--env", os.path.join(HERE, "out", "envlit", "env_for_trayecto.exr")],
}
FUNC = re.compile(r"\s*([0-9,]+) \([^)]*\)\s+(\S+?):(.*?)( \[.*\])?$")


def scene_path(name):
    """The scene's command-line arguments (the scene, then any options it needs)."""
    args = SCENES[name]
    for path in args:
        if os.sep in path and not os.path.exists(path):
            sys.exit(f"{path} is missing: run `python3 bench/compare.py --quick --scenes {name}` once")
    return args


def render(exe, scene, out, spp, threads, wrap=(), cpu=False):
    cmd = [*wrap, exe, "render", *scene, "-o", out, "--width", "64", "--height", "64", "--spp", str(spp),
           "--threads", str(threads), "--seed", "1"]
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    err = p.stderr.read()
    _, status, use = os.wait4(p.pid, 0)
    if status != 0:
        sys.exit(f"{' '.join(cmd)} failed: {err.strip()[-500:]}")
    if cpu:
        return use.ru_utime + use.ru_stime
    for line in err.splitlines():
        words = line.split()
        if line.startswith("rendered") and "ms" in words:
            return float(words[words.index("ms") - 1])
    sys.exit(f"no render time in the output of {exe} {scene}")


def callgrind(args, tmp):
    samples = 64 * 64 * args.spp
    for s in args.scenes:
        for b in args.bins:
            out = os.path.join(tmp, "cg.out")
            render(b, scene_path(s), os.path.join(tmp, "c.exr"), args.spp, 1,
                   ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                    "--toggle-collect=trayecto::render::render_range_aovs::*"])
            ann = subprocess.run(["callgrind_annotate", "--threshold=100", out], capture_output=True,
                                 text=True).stdout
            total = 0
            per_fn = collections.Counter()
            for line in ann.splitlines():
                if "PROGRAM TOTALS" in line:
                    # callgrind_annotate prints "." for a zero count.
                    word = line.split()[0].replace(",", "")
                    total = int(word) if word.isdigit() else 0
                    continue
                m = FUNC.match(line)
                if m:
                    per_fn[m.group(3).strip()] += int(m.group(1).replace(",", ""))
            if total == 0:
                # The toggle matched no call: LLVM inlined the render closure in this build (it
                # has happened in some builds). Say so instead of dividing nothing.
                sys.exit(f"callgrind collected nothing for {b}: `trayecto::render::render_range_aovs::*` "
                         "is inlined in this build; measure with --toggle-collect="
                         "'trayecto::integrator::path::radiance' as bench/ray_cost.py does")
            print(f"\n{s}, {b}: {total / samples:.0f} instructions per sample ({total:,} over {samples} samples)")
            for name, ir in per_fn.most_common(args.top):
                print(f"  {ir / samples:7.0f} {100 * ir / max(total, 1):5.1f} %  {name[:110]}")


def table(args, per, what, ratio_what, fmt):
    """Prints the interleaved rounds `per[(scene, binary)]` as a table: each binary's median
    (min-max) in `fmt`, and its ratio to the first binary's, taken per round."""
    print(f"\n| scene | binary | {what}, median (min-max) | {ratio_what}, per round: median (min-max) |")
    print("|---|---|---|---|")
    for s in args.scenes:
        base = per[(s, args.bins[0])]
        for b in args.bins:
            t = per[(s, b)]
            ratio = [x / y for x, y in zip(t, base)]
            print(f"| {s} | {b} | {statistics.median(t):{fmt}} ({min(t):{fmt}}-{max(t):{fmt}}) | "
                  f"{statistics.median(ratio):.3f} ({min(ratio):.3f}-{max(ratio):.3f}) |")


def wall(args, tmp):
    times = {(s, b): [] for s in args.scenes for b in args.bins}
    for r in range(args.rounds):
        for s in args.scenes:
            for b in (args.bins if r % 2 == 0 else args.bins[::-1]):
                times[(s, b)].append(render(b, scene_path(s), os.path.join(tmp, "w.exr"), 64, 2))
        print(f"round {r + 1}: load {os.getloadavg()[0]:.1f}", flush=True)
    table(args, times, "render ms", "time / first binary's", ".1f")


def cpu(args, tmp):
    lo, hi = 4, 68
    per = {(s, b): [] for s in args.scenes for b in args.bins}
    for r in range(args.rounds):
        for s in args.scenes:
            for b in (args.bins if r % 2 == 0 else args.bins[::-1]):
                out = os.path.join(tmp, "c.exr")
                t = render(b, scene_path(s), out, hi, 1, cpu=True) - render(b, scene_path(s), out, lo, 1, cpu=True)
                per[(s, b)].append(t / (64 * 64 * (hi - lo)) * 1e9)
        print(f"round {r + 1}: load {os.getloadavg()[0]:.1f}", flush=True)
    table(args, per, "CPU ns / sample", "/ first binary's", ".0f")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["wall", "callgrind", "cpu"])
    ap.add_argument("--bins", nargs="+", default=[os.path.join(ROOT, "target", "release", "trayecto")])
    ap.add_argument("--scenes", nargs="+", choices=list(SCENES), default=list(SCENES))
    ap.add_argument("--spp", type=int, default=16, help="callgrind: samples per pixel")
    ap.add_argument("--top", type=int, default=12, help="callgrind: functions listed per run")
    ap.add_argument("--rounds", type=int, default=5, help="wall, cpu: interleaved rounds")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        {"wall": wall, "callgrind": callgrind, "cpu": cpu}[args.mode](args, tmp)
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
