#!/usr/bin/env python3
"""Denoising benefit: relMSE of raw and OIDN-denoised renders against a high-spp reference.

Usage (from the repository root; needs ./scripts/install-oidn.sh once):

    python3 bench/denoise.py                          # Cornell box and DamagedHelmet, 16 spp
    python3 bench/denoise.py --spp 16 --ref-spp 2048 --res 96 --seeds 3

For each scene it renders the reference (--ref-spp, seed 1000, cached in bench/out/denoise/),
then --seeds renders at --spp with `--denoise` (which writes out.exr and out.denoised.exr from
the same samples), and reports the mean relMSE of the raw and of the denoised images and their
ratio. relMSE is bench/compare.py's: mean((x - ref)^2 / (ref^2 + 0.01)). The reference's own
noise is estimated as relMSE(spp) x spp / ref_spp and printed: it floors what the denoised
number can show.
"""
import argparse
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402  (relMSE, the EXR reader, the trayecto build)

SCENES = {
    "cornell": "cornell",
    "DamagedHelmet": "../shared/scenes/gltf/DamagedHelmet/glTF-Binary/DamagedHelmet.glb",
    "BoxTextured": "../shared/scenes/gltf/BoxTextured/glTF-Binary/BoxTextured.glb",
}


def render(exe, scene, out, res, spp, seed, threads, extra=()):
    cmd = [exe, "render", scene, "-o", out, "--width", str(res), "--height", str(res),
           "--spp", str(spp), "--seed", str(seed), "--threads", str(threads), *extra]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(r.stderr.strip())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", nargs="*", default=list(SCENES))
    ap.add_argument("--res", type=int, default=96)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--trayecto-bin", default=None)
    args = ap.parse_args()
    if not (compare.ensure_module("numpy", "numpy") and compare.ensure_module("mitsuba", "mitsuba")):
        return 1
    import numpy as np
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    exe = os.path.abspath(args.trayecto_bin) if args.trayecto_bin else compare.build_trayecto()[0]
    out = os.path.join(HERE, "out", "denoise")
    os.makedirs(out, exist_ok=True)
    print(f"| scene | {args.res}² px, spp | raw relMSE | denoised relMSE | raw / denoised | reference noise (est.) |")
    print("|---|---|---|---|---|---|")
    for name in args.scenes:
        scene = SCENES.get(name, name)
        ref_path = os.path.join(out, f"{name}-ref-{args.res}-{args.ref_spp}.exr")
        if not os.path.exists(ref_path):
            render(exe, scene, ref_path, args.res, args.ref_spp, 1000, args.threads)
        ref = compare.read_exr_rgb(ref_path).astype(np.float64)
        raw, den = [], []
        for seed in range(1, args.seeds + 1):
            p = os.path.join(out, f"{name}-{args.spp}-{seed}.exr")
            render(exe, scene, p, args.res, args.spp, seed, args.threads, ["--denoise"])
            raw.append(compare.rel_mse(compare.read_exr_rgb(p), ref))
            den.append(compare.rel_mse(compare.read_exr_rgb(p[:-4] + ".denoised.exr"), ref))
        r, d = float(np.mean(raw)), float(np.mean(den))
        print(f"| {name} | {args.spp} | {r:.5f} | {d:.5f} | {r / d:.1f}x | {r * args.spp / args.ref_spp:.5f} |",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
