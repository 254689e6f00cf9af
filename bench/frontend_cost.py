#!/usr/bin/env python3
"""Where a ray's time goes beyond its instruction count: the instruction cache, branch prediction
and data misses (callgrind's simulations), and the process CPU time that decides (interleaved).
The throughput bar (BENCHMARKS.md, "Rays per second on real models") compares ToyCar and
DamagedHelmet with the built-in Cornell box.

    python3 bench/frontend_cost.py sim [--bins A B ...] [--scenes cornell ToyCar ...]
    python3 bench/frontend_cost.py cpu [--bins A B ...] [--rounds 6] [--spp 8]

sim: one `valgrind --tool=callgrind --cache-sim=yes --branch-sim=yes --dump-instr=yes` run per
binary and scene (128², 4 spp, 1 thread, collecting inside `path::radiance` only) with a 32 KB
8-way I1 (this machine's L1i), 64 KB D1 and 1 MB LL. Per ray: instructions, simulated I1 misses,
conditional + indirect branch mispredicts (callgrind's simple predictor: a relative measure) and
LL data misses; and the hot code's footprint: the 64-byte lines holding 99 % of the executed
instructions (bytes that must stay in the L1i for the render loop to run without misses).
Says whether each binary's image is bit-identical to the first binary's.

cpu: user + system CPU time of whole `render SCENE --spp N --threads 1` processes (512²), binaries
alternated in each round (order reversed every other round), with the per-round ratio to the
first binary: CPU time counts what the process ran, not the time it waited for the two cores
shared with other builds, so it resolves ~1 % where wall clock under load does not. It includes
scene loading (ToyCar ~0.3 s, DamagedHelmet ~0.7 s of texture decoding), which is the same code
in every binary and dilutes the ratio. The render phase's wall time is printed beside it.
"""
import argparse
import collections
import filecmp
import os
import re
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from ray_cost import ROOT, SCENES  # noqa: E402  (the throughput bar's scenes, one definition)

RAYS = re.compile(r"rays\s+(\d+) \(")
RENDERED = re.compile(r"rendered \(\w+\)\s+([0-9.]+) ms")


def hot_lines(path, share=0.99):
    """64-byte code lines covering `share` of the self instructions in a callgrind file written
    with --dump-instr=yes ("positions: instr line": address, line, then the events)."""
    per_line = collections.Counter()
    last_addr = last_line = 0
    skip = False

    def pos(s, last):
        if s.startswith("0x"):
            return int(s, 16)
        if s[0] in "+-":
            return last + int(s)
        return last if s == "*" else int(s)

    with open(path) as f:
        for row in f:
            if row.startswith("calls="):
                skip = True  # the next cost line is the call's inclusive cost
                continue
            if not row or row[0] not in "0123456789+-*":
                continue
            p = row.split()
            last_addr, last_line = pos(p[0], last_addr), pos(p[1], last_line)
            if skip:
                skip = False
                continue
            per_line[last_addr >> 6] += int(p[2]) if len(p) > 2 else 0
    total, acc = sum(per_line.values()), 0
    for n, (_, ir) in enumerate(per_line.most_common(), 1):
        acc += ir
        if acc >= share * total:
            return n
    return len(per_line)


def summary(log, name):
    m = re.search(rf"{name}:\s+([0-9,]+)", log)
    return int(m.group(1).replace(",", "")) if m else 0


def sim(args, tmp):
    print("| binary | scene | Ir / ray | I1 misses / ray | hot code (99 % of Ir) | "
          "mispredicts / ray | LL data misses / ray | image |")
    print("|---|---|---|---|---|---|---|---|")
    for s in args.scenes:
        first = None
        for i, b in enumerate(args.bins):
            out, img = os.path.join(tmp, f"cg.{i}.{s}"), os.path.join(tmp, f"{i}.{s}.exr")
            r = subprocess.run(["valgrind", "--tool=callgrind", "--cache-sim=yes", "--branch-sim=yes",
                                "--dump-instr=yes", "--I1=32768,8,64", "--D1=65536,4,64",
                                "--LL=1048576,16,64", "--toggle-collect=trayecto::integrator::path::radiance",
                                f"--callgrind-out-file={out}", b, "render", SCENES[s], "--width", "128",
                                "--height", "128", "--spp", "4", "--threads", "1", "-o", img],
                               capture_output=True, text=True)
            m = RAYS.search(r.stderr)
            if r.returncode != 0 or not m:
                sys.exit(f"callgrind run of {b} {s} failed: {r.stderr[-500:]}")
            rays = int(m.group(1))
            ir, i1 = summary(r.stderr, "I   refs"), summary(r.stderr, "I1  misses")
            bm, dl = summary(r.stderr, "Mispredicts"), summary(r.stderr, "LLd misses")
            lines = hot_lines(out)
            first = first or img
            same = "first" if img == first else ("identical" if filecmp.cmp(first, img, shallow=False)
                                                 else "DIFFERS")
            print(f"| {b} | {s} | {ir / rays:.0f} | {i1 / rays:.1f} | {lines * 64 / 1024:.1f} KB | "
                  f"{bm / rays:.1f} | {dl / rays:.2f} | {same} |", flush=True)


def cpu(args, tmp):
    res = {(b, s): [] for b in args.bins for s in args.scenes}
    wall = {(b, s): [] for b in args.bins for s in args.scenes}
    for r in range(args.rounds):
        for s in args.scenes:
            for b in args.bins if r % 2 == 0 else args.bins[::-1]:
                p = subprocess.Popen([b, "render", SCENES[s], "--spp", str(args.spp), "--threads", "1",
                                      "-o", os.path.join(tmp, "c.exr")],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                err = p.stderr.read()
                _, status, use = os.wait4(p.pid, 0)
                m = RENDERED.search(err)
                if status != 0 or not m:
                    sys.exit(f"{b} {s} failed: {err[-500:]}")
                res[(b, s)].append(use.ru_utime + use.ru_stime)
                wall[(b, s)].append(float(m.group(1)) / 1000)
        print(f"round {r + 1}: load {os.getloadavg()[0]:.1f}", flush=True)

    def spread(xs, fmt):
        return f"{statistics.median(xs):{fmt}} ({min(xs):{fmt}}–{max(xs):{fmt}})"

    print("\n| binary | scene | CPU s median (min–max) | CPU ratio to first, per round | "
          "render wall s | render wall ratio |")
    print("|---|---|---|---|---|---|")
    for s in args.scenes:
        for b in args.bins:
            c0, w0 = res[(args.bins[0], s)], wall[(args.bins[0], s)]
            print(f"| {b} | {s} | {spread(res[(b, s)], '.3f')} | "
                  f"{spread([x / y for x, y in zip(res[(b, s)], c0)], '.3f')} | "
                  f"{spread(wall[(b, s)], '.3f')} | {spread([x / y for x, y in zip(wall[(b, s)], w0)], '.3f')} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["sim", "cpu"])
    ap.add_argument("--bins", nargs="+", default=[os.path.join(ROOT, "target", "release", "trayecto")])
    ap.add_argument("--scenes", nargs="+", choices=list(SCENES), default=list(SCENES))
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--spp", type=int, default=8)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        (sim if args.mode == "sim" else cpu)(args, tmp)
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
