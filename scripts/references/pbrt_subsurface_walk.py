#!/usr/bin/env python3
"""Would a volumetric random walk agree with pbrt-v4's `subsurface` material? Asks pbrt-v4 itself.

pbrt-v4's `subsurface` is a tabulated BSSRDF (photon beam diffusion, `ComputeBeamDiffusionBSSRDF`,
sampled by probe rays) behind a dielectric boundary. A random walk (as Cycles does) renders the
same coefficients as a homogeneous medium inside a dielectric boundary. This script writes both
forms of one sphere (radius 1, a disk light above, a dim sky) and renders them with pbrt-v4 alone
(`volpath`; the walk with an unbounded depth, since pbrt-v4 counts each scattering as a bounce):
the difference is what separates the two models, before any renderer's implementation enters.

Usage: scripts/references/pbrt_subsurface_walk.py OUTDIR [--spp 256] [--case a|b|c]
  a: pbrt-v4's default coefficients (sigma_a .0011 .0024 .014, sigma_s 2.55 3.21 3.77 per unit)
  b: the same, scale 10 (ten times denser)
  c: sigma_a 0.5 1 2, sigma_s 20 15 10
Measured (OUTDIR /tmp/sss, 64 x 48, 256 spp, case a): the walk's mean is +17.9 % of the BSSRDF's
(R/G/B 1.21/1.17/1.16), its worst 4 x 4 block +69 % (the sphere's lit core); case b's walk needs
~40 min at 256 spp on one core (thousands of scattering events per path).
"""
import argparse
import os
import subprocess

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PBRT = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v4", "pbrt")

CASES = {
    "a": ((0.0011, 0.0024, 0.014), (2.55, 3.21, 3.77), 1.0),
    "b": ((0.0011, 0.0024, 0.014), (2.55, 3.21, 3.77), 10.0),
    "c": ((0.5, 1.0, 2.0), (20.0, 15.0, 10.0), 1.0),
}

HEAD = """LookAt 0 0.5 -4  0 0 0  0 1 0
Camera "perspective" "float fov" [ 40 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 48 ]
Sampler "independent"
Integrator "volpath" "integer maxdepth" [ {depth} ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.1 0.1 0.1 ]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 8 8 8 ]
  Translate 1.5 2.5 1
  Rotate 90 1 0 0
  Shape "disk" "float radius" [ 0.7 ]
AttributeEnd
"""


def rgb(v):
    return " ".join(f"{x:g}" for x in v)


def scenes(sa, ss, scale):
    bssrdf = HEAD.format(depth=5) + (
        f'Material "subsurface" "rgb sigma_a" [ {rgb(sa)} ] "rgb sigma_s" [ {rgb(ss)} ] '
        f'"float scale" [ {scale:g} ] "float eta" [ 1.33 ]\nShape "sphere" "float radius" [ 1 ]\n')
    walk = HEAD.format(depth=100000) + (
        f'MakeNamedMedium "inside" "string type" "homogeneous" "rgb sigma_a" [ {rgb(sa)} ] '
        f'"rgb sigma_s" [ {rgb(ss)} ] "float scale" [ {scale:g} ]\n'
        'MediumInterface "inside" ""\nMaterial "dielectric" "float eta" [ 1.33 ]\n'
        'Shape "sphere" "float radius" [ 1 ]\n')
    return bssrdf, walk


def read(path):
    import OpenEXR
    with OpenEXR.File(path) as f:
        ch = f.channels()
        px = ch["RGB"].pixels if "RGB" in ch else np.stack([ch[c].pixels for c in "RGB"], -1)
    return np.asarray(px, dtype=np.float64)[:, :, :3]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--case", default="a", choices=sorted(CASES))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    images = {}
    for kind, text in zip(("bssrdf", "walk"), scenes(*CASES[a.case])):
        scene = os.path.join(a.out, f"{a.case}-{kind}.pbrt")
        with open(scene, "w") as f:
            f.write(text)
        exr = scene[:-5] + ".exr"
        subprocess.run([PBRT, "--nthreads", "1", "--spp", str(a.spp), "--outfile", exr, scene],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        images[kind] = read(exr)
    lum = np.array([0.2126, 0.7152, 0.0722])
    lb, lw = images["bssrdf"] @ lum, images["walk"] @ lum
    h, w = lb.shape
    blk = lambda x: np.array([[x[i * h // 4:(i + 1) * h // 4, j * w // 4:(j + 1) * w // 4].mean()
                               for j in range(4)] for i in range(4)])
    err = (blk(lw) - blk(lb)) / np.maximum(blk(lb), 0.02 * lb.mean())
    ratio = images["walk"].mean(axis=(0, 1)) / images["bssrdf"].mean(axis=(0, 1))
    print(f"case {a.case}: walk/BSSRDF mean {lw.mean() / lb.mean() - 1:+.3f}, R/G/B "
          f"{ratio[0]:.3f}/{ratio[1]:.3f}/{ratio[2]:.3f}, worst 4x4 block {np.abs(err).max():.3f}")


if __name__ == "__main__":
    main()
