#!/usr/bin/env python3
"""CPU time per camera sample, Trayecto against Mitsuba 3 `llvm_ad_rgb`, on bench/compare.py's
exported scenes: a measure that a loaded machine disturbs far less than wall clock (a process
is charged only for the CPU it got).

    bench/out/venv/bin/python bench/cpu_per_sample.py BIN [--rounds 5] [--scenes cornell,textured,envlit]

Both render 64², 64 spp on 2 threads, interleaved per round. Trayecto: the render process's
user + system time (`os.wait4`) minus that of the same scene at 1×1 pixel and 1 spp (loading,
building, writing; median of 3). Mitsuba: `time.process_time()` (every thread of the process)
around `mi.render` after a first render of the same scene and count (JIT compilation left out),
the sampler of bench/stages.py. Prints core-µs per sample, medians (lowest–highest round) and
the ratio Trayecto / Mitsuba per round.
"""
import argparse
import os
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import stages  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("bin")
ap.add_argument("--rounds", type=int, default=5)
ap.add_argument("--scenes", default="cornell,textured,envlit")
args = ap.parse_args()
B = os.path.abspath(args.bin)
RES, SPP, ROUNDS = 64, 64, args.rounds
scenes = args.scenes.split(",")
mi = stages.Mitsuba(2, RES)

def tray_cpu(scene, res, spp):
    target, extra = stages.scene_args(scene)
    p = subprocess.Popen([B, "render", target, "-o", os.path.join(stages.OUT, "cpu_per_sample.exr"), "--width", str(res), "--height", str(res),
                          "--spp", str(spp), "--threads", "2", "-q", *extra])
    _, _, ru = os.wait4(p.pid, 0)
    return ru.ru_utime + ru.ru_stime

base = {s: statistics.median(tray_cpu(s, 1, 1) for _ in range(3)) for s in scenes}
res = {s: {"t": [], "m": []} for s in scenes}
loads = []
for r in range(ROUNDS):
    loads.append(os.getloadavg()[0])
    for s in scenes:
        res[s]["t"].append((tray_cpu(s, RES, SPP) - base[s]) / (RES * RES * SPP) * 1e6)
        mi.time(s, SPP, False)  # the first call loads the scene and compiles the kernels
        c = time.process_time()
        mi.time(s, SPP, False)
        res[s]["m"].append((time.process_time() - c) / (RES * RES * SPP) * 1e6)
print("load", min(loads), max(loads))
for s in scenes:
    t, m = res[s]["t"], res[s]["m"]
    rat = [a / b for a, b in zip(t, m)]
    print(f"{s:9s} Trayecto {statistics.median(t):.2f} ({min(t):.2f}-{max(t):.2f}) core-us/sample, Mitsuba {statistics.median(m):.2f} ({min(m):.2f}-{max(m):.2f}); T/M {statistics.median(rat):.2f} ({min(rat):.2f}-{max(rat):.2f})")
