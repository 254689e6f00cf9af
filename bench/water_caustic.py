#!/usr/bin/env python3
"""Trayecto's SPPM on Bitterli's water-caustic against pbrt-v4's SPPM reference
(tests/references/pbrt/water-caustic-sppm.exr, made by `scripts/pbrt_sppm_references.sh 256`:
256x256, 256 iterations, the file's radius 0.01 and maxdepth 9).

    python3 bench/water_caustic.py target/release/trayecto [--spp 64]

Renders the scene at 256x256 with `--integrator sppm` and prints the luminance bias and the
relative error of the 4 x 4 blocks, with and without the pixels where either image sees the
lamp directly (a 5 x 4 mm emitter of radiance 5.4e5 spans a few per cent of one pixel: which pixel
catches it at a few hundred samples is a lottery, and those pixels carry a tenth of the image's
mean). Needs numpy and mitsuba (`pip install mitsuba`) or OpenEXR to read EXR.
"""
import argparse
import os
import subprocess
import tempfile

import numpy as np

from exr_compare import lum, read, summary

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "..", "shared", "scenes", "pbrt", "water-caustic", "scene-v4.pbrt")
REF = os.path.join(ROOT, "tests", "references", "pbrt", "water-caustic-sppm.exr")


def report(what, t, p):
    print(f"{what}: {summary(t, p)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("trayecto")
    ap.add_argument("--spp", type=int, default=64, help="SPPM iterations")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "wc.exr")
        subprocess.run([args.trayecto, "render", SCENE, "--integrator", "sppm", "--width", "256",
                        "--height", "256", "--spp", str(args.spp), "-q", "-o", out], check=True)
        t = read(out)
    p = read(REF)
    report("whole image", t, p)
    keep = ((lum(t) < 100) & (lum(p) < 100))[..., None]
    print(f"lamp pixels left out: {int((~keep).sum())}")
    report("without the lamp's pixels", np.where(keep, t, 0), np.where(keep, p, 0))


if __name__ == "__main__":
    main()
