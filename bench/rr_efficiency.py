#!/usr/bin/env python3
"""Russian-roulette efficiency: error and cost of `--rr-depth` / `--rr-scale` settings.

Usage (from the repository root):

    python3 bench/rr_efficiency.py                       # the built-in Cornell box
    python3 bench/rr_efficiency.py --scene bench/out/veach/veach.glb   # (made by bench/compare.py)
    python3 bench/rr_efficiency.py --configs "--rr-scale 1" "--rr-scale 3" "--rr-depth 64"

For each setting it renders the scene at 64x64, 64 spp (--spp), five seeds, and reports the mean relMSE
against a Trayecto reference of 8192 spp (made once per scene, cached in bench/out/), the rays
traced per sample (the CLI's count: deterministic, unaffected by machine load), the median render
time, and two efficiencies: 1 / (relMSE x rays per sample) and 1 / (relMSE x seconds). relMSE is the
same as bench/compare.py's. Every setting is unbiased; only variance and cost change.
"""
import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402  (the harness: module installs, the trayecto build, relMSE)

RES, SPP, SEEDS, REF_SPP = 64, 64, range(1, 6), 8192
DEFAULT_CONFIGS = ["--rr-scale 1", "--rr-scale 1 --rr-depth 5", "--rr-scale 1 --rr-depth 64",
                   "--rr-scale 2", "--rr-scale 3", "--rr-scale 4"]


def render(exe, scene, spp, seed, extra, out, threads):
    import numpy as np
    t, rays = compare.run_trayecto(exe, scene, out, RES, spp, seed, threads, extra)
    return compare.read_exr_rgb(out).astype(np.float64), t, rays


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="cornell")
    ap.add_argument("--configs", nargs="*", default=DEFAULT_CONFIGS)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--spp", type=int, default=SPP, help="samples per pixel of the compared renders")
    ap.add_argument("--trayecto-bin", default=None)
    args = ap.parse_args()
    if not (compare.ensure_module("numpy", "numpy") and compare.ensure_module("mitsuba", "mitsuba")):
        return 1
    import numpy as np
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    exe = os.path.abspath(args.trayecto_bin) if args.trayecto_bin else compare.build_trayecto()[0]
    if not exe:
        return 1
    os.makedirs(compare.OUT, exist_ok=True)
    tag = os.path.splitext(os.path.basename(args.scene))[0]
    ref_path = os.path.join(compare.OUT, f"rr_ref_{tag}.npy")
    if not os.path.exists(ref_path):
        print(f"[{tag}] reference: {REF_SPP} spp", flush=True)
        # The reference uses no Russian roulette at all, so it favours no setting.
        ref, _, _ = render(exe, args.scene, REF_SPP, 99999, ["--rr-depth", "64"],
                           os.path.join(compare.OUT, f"rr_ref_{tag}.exr"), args.threads)
        np.save(ref_path, ref)
    ref = np.load(ref_path)
    spp = args.spp
    print(f"| {tag}: setting | relMSE @{spp} spp | rays / sample | time | 1/(relMSE x rays) | 1/(relMSE x s) |")
    print("|---|---|---|---|---|---|")
    for cfg in args.configs:
        errs, times, rays = [], [], []
        for seed in SEEDS:
            img, t, n = render(exe, args.scene, spp, seed, cfg.split(), os.path.join(compare.OUT, "rr_x.exr"),
                               args.threads)
            errs.append(compare.rel_mse(img, ref))
            times.append(t)
            rays.append(n / (RES * RES * spp))
        e, r, t = float(np.mean(errs)), float(np.mean(rays)), float(np.median(times))
        print(f"| `{cfg}` | {e:.5f} | {r:.2f} | {t:.3f} s | {1 / (e * r):.1f} | {1 / (e * t):.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
