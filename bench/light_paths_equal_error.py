#!/usr/bin/env python3
"""Time to equal error of the light-path integrators on the pbrt scenes they are for: Trayecto's
BDPT, path tracer and MLT against pbrt-v4's `bdpt` and `mlt`, on the same files, interleaved.

    nice -n 10 python3 bench/light_paths_equal_error.py target/release/trayecto \
        [--scenes veach-bidir water-caustic] [--ladder 4 16 64] [--rounds 2] [--res 32] \
        [--mlt-scenes veach-bidir] [--ref-spp PBRT_SPP TRAYECTO_SPP]

Each scene is rendered at RES x RES (the file's filter and maxdepth) by every method at every
sample count of the ladder (MLT: mutations per pixel), the methods interleaved within a round and
the rounds repeated, each run with its own seed. Error: relative MSE, mean over pixels of
(x - r)^2 / (r^2 + 0.01) in luminance, against the pbrt-v4 BDPT reference of
tests/references/pbrt/bdpt/NAME-RES.exr (`scripts/references/pbrt_bdpt_references.sh RES 1024`),
or with --ref-spp the samples-weighted mean of it and Trayecto's BDPT render
NAME-RES-trayecto-SPP.exr (`trayecto render ... --integrator bdpt --spp SPP --seed 900001`), for
ladders whose errors a single reference's noise would not be well below,
leaving out pixels above 100 times the reference's median (water-caustic's lamp seen directly, a
lottery at any of these sample counts; with --ref-spp also those above 50 times the median of
either reference). Time: the process's wall time, scene loading included
(both renderers; 2 threads each). Prints per method and sample count the median error and time
over the rounds, and each method's time to reach Trayecto BDPT's error at the ladder's middle
count, estimated as the median over the ladder of error x time / target (relative MSE of an unbiased
estimator falls as 1 / time), per round: the spread is over rounds. Each method first renders once unmeasured (caches warm). Needs numpy and OpenEXR (`pip install OpenEXR`).
"""
import argparse
import os
import re
import shutil
import subprocess
import tempfile
import time

import numpy as np

from exr_compare import lum, read

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.join(ROOT, "..", "shared")
PBRT = os.path.join(SHARED, "tools", "pbrt-v4", "pbrt")


def pbrt_scene(name, res, integrator, spp, tmp):
    """The scene file with its Integrator replaced (maxdepth kept) and its film at res x res, in a
    folder of links to the scene's own files so that relative paths resolve."""
    src = os.path.join(SHARED, "scenes", "pbrt", name)
    d = os.path.join(tmp, f"{name}-{integrator}")
    if not os.path.isdir(d):
        os.makedirs(d)
        for f in os.listdir(src):
            if f != "scene-v4.pbrt":
                os.symlink(os.path.realpath(os.path.join(src, f)), os.path.join(d, f))
    out, in_params, done = [], False, False
    for line in open(os.path.join(src, "scene-v4.pbrt")):
        if line.startswith("Integrator ") and not done:
            out.append(f'Integrator "{integrator}"\n')
            if integrator == "mlt":
                out.append(f'    "integer mutationsperpixel" [ {spp} ]\n')
            done = in_params = True
            continue
        if in_params and re.match(r'^\s+"', line):
            if "maxdepth" in line:
                out.append(line)
            continue
        in_params = False
        line = re.sub(r'("integer [xy]resolution"\s*)\[\s*\d+\s*\]', rf"\1[ {res} ]", line)
        out.append(line)
    path = os.path.join(d, f"scene-{spp}.pbrt")
    open(path, "w").writelines(out)
    return path


def run(method, trayecto, name, res, spp, seed, tmp):
    """Renders and returns (image, wall seconds)."""
    out = os.path.join(tmp, "out.exr")
    if method.startswith("pbrt"):
        integ = method.split("-")[1]
        scene = pbrt_scene(name, res, integ, spp, tmp)
        cmd = [PBRT, "--quiet", "--nthreads", "2", "--seed", str(seed), "--outfile", out, scene]
        if integ != "mlt":
            cmd[1:1] = ["--spp", str(spp)]
    else:
        integ = method.split("-")[1]
        scene = os.path.join(SHARED, "scenes", "pbrt", name, "scene-v4.pbrt")
        cmd = [trayecto, "render", scene, "--integrator", integ, "--width", str(res), "--height",
               str(res), "--spp", str(spp), "--seed", str(seed), "--threads", "2", "-q", "-o", out]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return read(out), time.perf_counter() - t0


def rel_mse(img, ref, keep):
    x, r = lum(img)[keep], lum(ref)[keep]
    return float(np.mean((x - r) ** 2 / (r * r + 0.01)))


def time_to(errs, times, target):
    """Time to reach `target` for an unbiased estimator, whose relative MSE falls as 1 / time: the
    median over the ladder of error x time / target (robust to one ladder point's fireflies)."""
    return float(np.median([e * t / target for e, t in zip(errs, times)]))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("trayecto")
    ap.add_argument("--scenes", nargs="+", default=["veach-bidir", "water-caustic"])
    ap.add_argument("--ladder", nargs="+", type=int, default=[4, 16, 64])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--res", type=int, default=32)
    ap.add_argument("--mlt-scenes", nargs="*", default=["veach-bidir"],
                    help="scenes on which the two MLTs run too")
    ap.add_argument("--ref-spp", nargs=2, type=int, metavar=("PBRT", "TRAYECTO"),
                    help="reference = the samples-weighted mean of pbrt-v4's BDPT at PBRT spp "
                    "(NAME-RES.exr) and Trayecto's at TRAYECTO spp (NAME-RES-trayecto-TRAYECTO.exr)")
    args = ap.parse_args()
    tmp = tempfile.mkdtemp()
    try:
        for name in args.scenes:
            methods = ["trayecto-bdpt", "pbrt-bdpt", "trayecto-path"]
            if name in args.mlt_scenes:
                methods += ["trayecto-mlt", "pbrt-mlt"]
            res = {(m, s): [] for m in methods for s in args.ladder}
            for m in methods:
                run(m, args.trayecto, name, args.res, args.ladder[0], 7, tmp)
            for r in range(args.rounds):
                for s in args.ladder:
                    for m in methods:
                        res[(m, s)].append(run(m, args.trayecto, name, args.res, s, 100 * r + s, tmp))
            # The reference is read after the renders, so that it may be made meanwhile.
            refs = os.path.join(ROOT, "tests", "references", "pbrt", "bdpt")
            ref = read(os.path.join(refs, f"{name}-{args.res}.exr"))
            if args.ref_spp:
                # Both renderers are unbiased and agree within noise on these files
                # (tests/light_paths.rs), so weighting each by its sample count is the
                # minimum-variance combination; Trayecto's share biases the comparison toward it
                # only by its own noise, which is ~1/sqrt(total spp / ladder top) of the errors.
                p, t = args.ref_spp
                ours = read(os.path.join(refs, f"{name}-{args.res}-trayecto-{t}.exr"))
                ref = (p * ref + t * ours) / (p + t)
            keep = lum(ref) < 100 * np.median(lum(ref))
            if args.ref_spp:
                # The lamp seen directly is a sub-pixel lottery at these sizes, and the two
                # renderers put it in different pixels (16 x 16: pbrt-v4 one pixel, Trayecto its
                # neighbours): pixels above 50 times the median in either reference are left out.
                for r in (read(os.path.join(refs, f"{name}-{args.res}.exr")), ours):
                    keep &= lum(r) < 50 * np.median(lum(r))
            res = {k: [(rel_mse(img, ref, keep), t) for img, t in v] for k, v in res.items()}
            print(f"== {name} {args.res}x{args.res}, {args.rounds} rounds (median rel. MSE, median wall s)")
            for m in methods:
                row = [f"{s}: {np.median([e for e, _ in res[(m, s)]]):.4g} / "
                       f"{np.median([t for _, t in res[(m, s)]]):.2f} s" for s in args.ladder]
                print(f"  {m:14s} " + " | ".join(row))
            mid = args.ladder[len(args.ladder) // 2]
            for r in range(args.rounds):
                target = res[("trayecto-bdpt", mid)][r][0]
                times = {m: time_to([res[(m, s)][r][0] for s in args.ladder],
                                    [res[(m, s)][r][1] for s in args.ladder], target) for m in methods}
                # A method whose error stays above the target over the whole ladder is only
                # extrapolated (1 / time); its measured lower bound is its top count's time.
                unreached = {m for m in methods if min(res[(m, s)][r][0] for s in args.ladder) > target}
                print(f"  round {r}: time to Trayecto BDPT's error at {mid} ({target:.4g}): "
                      + ", ".join(f"{m} {t:.2f} s" + (f" (not reached: > {res[(m, args.ladder[-1])][r][1]:.2f} s)"
                                                      if m in unreached else "")
                                  for m, t in times.items())
                      + f"; pbrt-bdpt / trayecto-bdpt = {times['pbrt-bdpt'] / times['trayecto-bdpt']:.2f}"
                      + (f"; pbrt-mlt / trayecto-mlt = {times['pbrt-mlt'] / times['trayecto-mlt']:.2f}"
                         if "pbrt-mlt" in times else ""))
    finally:
        shutil.rmtree(tmp)


if __name__ == "__main__":
    main()
