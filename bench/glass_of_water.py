#!/usr/bin/env python3
"""Trayecto's SPPM, VCM and BDPT on Bitterli's glass-of-water against pbrt-v4's BDPT
(tests/references/pbrt/glass-of-water-bdpt.exr: 160x90, 1024 samples per pixel, made by this
script's --make-reference).

    python3 bench/glass_of_water.py target/release/trayecto --scene DIR [--spp 64]
    python3 bench/glass_of_water.py --make-reference --scene DIR [--spp 1024]

DIR is the scene's folder of Bitterli's pbrt-v4 pack (scene-v4.pbrt and models/), e.g. a copy of
github.com/gonsolo/bitterli's glass-of-water/pbrt; it is not in ../shared. The copies we found
lack models/Mesh000.ply (its largest mesh, a "WaterAir" surface: GitHub's snapshot lists the
file without its content), so when it is absent the shape is left out of the file for both
renderers: the comparison is of the same scene, less that surface. The file asks for
`Integrator "bdpt"` with maxdepth 33 (Bitterli's pbrt-v3 original asked for SPPM), so pbrt-v4's
BDPT is the reference, and the radius of Trayecto's photon methods is its default (1/200 of the
scene's diagonal). Film 1280x720 is rendered at 160x90.

Prints, per integrator: time, the luminance bias, the R/G/B ratio of means and the relative
error of the 4 x 4 blocks (mean and worst). Needs numpy and OpenEXR (or mitsuba) to read EXR.
"""
import argparse
import os
import subprocess
import tempfile
import time

from exr_compare import read, summary

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REF = os.path.join(ROOT, "tests", "references", "pbrt", "glass-of-water-bdpt.exr")
PBRT = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v4", "pbrt")
W, H = 160, 90


def report(what, t, p, secs):
    print(f"{what:>14}: {secs:7.1f} s, {summary(t, p)}")


def scene_copy(src, tmp):
    """The scene at W x H beside links to its models, without Mesh000 if the copy lacks it."""
    text = open(os.path.join(src, "scene-v4.pbrt")).read()
    for a, b in (('"integer yresolution" [ 720 ]', f'"integer yresolution" [ {H} ]'),
                 ('"integer xresolution" [ 1280 ]', f'"integer xresolution" [ {W} ]')):
        assert a in text, a
        text = text.replace(a, b)
    if not os.path.exists(os.path.join(src, "models", "Mesh000.ply")):
        shape = 'Shape "plymesh"\n    "string filename" [ "models/Mesh000.ply" ]\n'
        assert shape in text
        text = text.replace(shape, "")
        print("models/Mesh000.ply is absent: the scene is rendered without it")
    os.symlink(os.path.join(os.path.abspath(src), "models"), os.path.join(tmp, "models"))
    path = os.path.join(tmp, "scene.pbrt")
    open(path, "w").write(text)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("trayecto", nargs="?")
    ap.add_argument("--scene", required=True, help="the glass-of-water folder (scene-v4.pbrt, models/)")
    ap.add_argument("--spp", type=int, default=64, help="samples (iterations) per pixel")
    ap.add_argument("--integrators", default="sppm,vcm,bdpt")
    ap.add_argument("--make-reference", action="store_true",
                    help="render the pbrt-v4 BDPT reference into tests/references/pbrt")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        scene = scene_copy(args.scene, tmp)
        if args.make_reference:
            subprocess.run(["nice", "-n", "10", PBRT, "--quiet", "--nthreads", "2", "--seed", "0",
                            "--spp", str(args.spp), "--outfile", REF, scene], check=True)
            return
        p = read(REF)
        for integrator in args.integrators.split(","):
            out = os.path.join(tmp, f"{integrator}.exr")
            t0 = time.time()
            subprocess.run([args.trayecto, "render", scene, "--integrator", integrator, "--spp",
                            str(args.spp), "-q", "-o", out], check=True)
            report(f"{integrator} {args.spp}", read(out), p, time.time() - t0)


if __name__ == "__main__":
    main()
