#!/usr/bin/env python3
"""Error per sample over many seeds against pbrt-v4, for one Bitterli scene of bench/compare.py.

Why: compare.py's time-to-equal-error ratio scores each ladder point by the mean relMSE of a few
renders (8 error seeds in quick mode). On scenes whose error is heavy-tailed (veach-mis: a pixel
whose one sample meets the small lamp directly through the pixel filter's tail, or through a
glossy plate, carries 99 % of a render's error) the mean of 8 draws depends on whether a draw
landed in the tail, for either renderer. This script renders K seeds with both and prints each
render's relMSE, the share of its worst pixel, and the mean and median over the seeds, each
against the renderer's own 512-spp reference from compare.py (so run compare.py on the scene
first: it writes the pbrt-v4 copies and the references under bench/out/).

    bench/out/venv/bin/python bench/pbrt_seed_error.py --scene pbrt-veach-mis --seeds 32 \
        --bin target/release/trayecto --pbrt-sampler zsobol [--trayecto-arg=--rgb]

Every render is one thread, 64 spp (change with --spp), compare.py's quick resolution (64 px
high); the relMSE is compare.py's.
"""
import argparse
import os
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402  (the pbrt-v4 copies, the references, the relMSE)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="pbrt-veach-mis", choices=sorted(compare.PBRT_FILES))
    ap.add_argument("--seeds", type=int, default=32)
    ap.add_argument("--first-seed", type=int, default=100)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--res", type=int, default=64, help="image height (compare.py's quick mode: 64)")
    ap.add_argument("--ref-spp", type=int, default=512)
    ap.add_argument("--bin", default=os.path.join(HERE, "..", "target", "release", "trayecto"))
    ap.add_argument("--pbrt-sampler", default="zsobol")
    ap.add_argument("--trayecto-arg", action="append", default=[], help="an extra Trayecto option")
    ap.add_argument("--only", choices=["trayecto", "pbrt"], help="render one renderer only")
    args = ap.parse_args()
    import numpy as np

    out_dir = os.path.join(compare.OUT, "pbrt_seed_error")
    os.makedirs(out_dir, exist_ok=True)
    file_copy, w, h = compare.pbrt_copy(args.scene, args.res, None)
    sampler_copy, _, _ = compare.pbrt_copy(args.scene, args.res, args.pbrt_sampler)
    kinds = [k for k in ("trayecto", "pbrt") if args.only in (None, k)]
    for kind in kinds:
        ref_path = compare.ref_path_of(args.scene, kind, args.res, args.ref_spp)
        if not os.path.exists(ref_path):
            sys.exit(f"{ref_path} is missing: run bench/compare.py --quick --scenes {args.scene} first")
        ref = np.load(ref_path).astype(np.float64)
        errors = []
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            out = os.path.join(out_dir, f"{args.scene}_{kind}_{seed}.exr")
            if kind == "pbrt":
                compare.run_pbrt(sampler_copy, out, args.spp, seed, 1)
            else:
                compare.run_trayecto(args.bin, file_copy, out, (w, h), args.spp, seed, 1, args.trayecto_arg)
            x = compare.read_exr_rgb(out).astype(np.float64)
            per_pixel = ((x - ref) ** 2 / (ref ** 2 + 1e-2)).mean(axis=2)
            e = compare.rel_mse(x, ref)
            errors.append(e)
            row, col = np.unravel_index(per_pixel.argmax(), per_pixel.shape)
            print(f"{kind} seed {seed}: relMSE {e:.4f}, worst pixel ({row}, {col}) carries "
                  f"{per_pixel.max() / per_pixel.sum():.0%}: {x[row, col].mean():.2f} against {ref[row, col].mean():.3f}",
                  flush=True)
        print(f"{kind}: {len(errors)} seeds, relMSE mean {statistics.mean(errors):.4f} "
              f"(standard error {statistics.stdev(errors) / len(errors) ** 0.5:.4f}), "
              f"median {statistics.median(errors):.4f}, highest {max(errors):.4f}", flush=True)


if __name__ == "__main__":
    main()
