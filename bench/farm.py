#!/usr/bin/env python3
"""Benchmark of the Dask farm driver on one machine (docs/src/farm.md).

1. Overhead: the same frame (same spp) rendered by one `trayecto render` process using every core,
   and by `trayecto-farm` on a LocalCluster of W single-threaded workers (W = cores) in K chunks.
   The difference is the farm's cost: cluster start-up, one scene load + BVH build per chunk,
   process launches, shipping the partial films, and the merge.
2. Scaling: throughput (camera samples per second) with 1, 2, ... workers. This machine's cores
   stand in for machines: every worker is a separate process whose renderer is limited to one
   thread (`--threads 1`), so W workers are W "one-core machines". Beyond the core count the
   workers share cores and throughput should flatten: that row shows the limit, not the farm.

Every farm image is checked to be bit-identical to the single render.

    python bench/farm.py [--trayecto target/release/trayecto] [--spp 256] [--size 160]
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python/trayecto_farm/src"))

from distributed import Client, LocalCluster  # noqa: E402

from trayecto_farm.farm import FarmJob, run_farm  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trayecto", default=str(ROOT / "target/release/trayecto"))
    ap.add_argument("--scene", default="cornell")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--size", type=int, default=160)
    ap.add_argument("--chunks", type=int, default=8)
    ap.add_argument("--max-workers", type=int, default=None)
    a = ap.parse_args()
    cores = os.cpu_count() or 1
    max_workers = a.max_workers or cores + 1
    args = ["--width", str(a.size), "--height", str(a.size), "--seed", "1"]
    samples = a.size * a.size * a.spp
    tmp = Path(tempfile.mkdtemp(prefix="trayecto-farm-bench-"))

    def single(threads):
        out = tmp / f"single{threads}.exr"
        t = time.perf_counter()
        subprocess.run(
            [a.trayecto, "render", a.scene, "-q", "--spp", str(a.spp), "--threads", str(threads),
             *args, "-o", str(out)],
            check=True,
        )
        return time.perf_counter() - t, out.read_bytes()

    def farm(workers, chunks):
        t0 = time.perf_counter()
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                          dashboard_address=None) as c, Client(c) as client:
            t1 = time.perf_counter()
            job = FarmJob(scenes=[a.scene], spp=a.spp, chunks=chunks,
                          output=tmp / f"farm{workers}.exr", render_args=args,
                          trayecto=a.trayecto, threads_per_task=1)
            [out] = run_farm(job, client)
            t2 = time.perf_counter()
        return t2 - t0, t2 - t1, out.read_bytes()

    print(f"scene {a.scene} {a.size}x{a.size} at {a.spp} spp ({samples / 1e6:.1f} M camera "
          f"samples), {cores} cores, binary {a.trayecto}", flush=True)
    t_single, ref = single(cores)
    t_single1, _ = single(1)
    print(f"one process, {cores} threads: {t_single:.2f} s; 1 thread: {t_single1:.2f} s", flush=True)

    rows = []
    for w in range(1, max_workers + 1):
        total, work, img = farm(w, max(a.chunks, w))
        assert img == ref, f"{w} workers: the farm image differs from the single render"
        rows.append((w, total, work))
        print(f"farm, {w} workers x 1 thread, {max(a.chunks, w)} chunks: {total:.2f} s "
              f"({work:.2f} s without cluster start-up)", flush=True)

    print()
    print("| run | wall s | Msamples/s | vs one process |")
    print("|---|---|---|---|")
    print(f"| one process, {cores} threads | {t_single:.2f} | {samples / t_single / 1e6:.2f} | 1.00 |")
    print(f"| one process, 1 thread | {t_single1:.2f} | {samples / t_single1 / 1e6:.2f} | "
          f"{t_single / t_single1:.2f} |")
    for w, total, work in rows:
        print(f"| farm, {w} worker(s) x 1 thread (incl. cluster start; without) | {total:.2f}; "
              f"{work:.2f} | {samples / work / 1e6:.2f} | {t_single / work:.2f} |")
    print()
    print("every farm image bit-identical to the single render: yes")


if __name__ == "__main__":
    main()
