#!/usr/bin/env python3
"""Mitsuba 3 white furnace of a rough glass sphere: the independent value `tests/furnace.rs` pins
its rough-dielectric furnace to.

Usage (from the repository root):

    pip install mitsuba numpy            # mitsuba 3.9.1, drjit 1.5.0 were used
    python3 scripts/references/furnace_rough_glass.py [--spp 8192] [--size 64]

The scene is exactly the one `furnace_mean` in tests/furnace.rs builds: a sphere of radius 1 at the
origin, inside a constant environment of radiance 1, seen by a perspective camera at (0, 0, 200)
looking at the origin whose frame spans +-1.5 at the sphere (vertical fov = 2 atan(1.5 / 200)).
Material: `roughdielectric`, GGX, alpha = roughness^2 = 0.25 (Trayecto's alpha = roughness^2),
int_ior 1.5, ext_ior 1.0, with `sample_visible`. Integrator `path`, max_depth -1 (unlimited: the
rough glass sphere keeps light bouncing inside), rfilter box, sampler independent.

It prints the image mean (the average of R, G, B; the scene is grey so they agree) and Ebar_disc =
1 - (1 - mean) / coverage, the mean energy returned over the sphere's disc, with coverage = pi / (4 *
1.5^2) the disc's share of the frame, and the standard error of the mean from the spread of the
chunks.

Mitsuba's roughdielectric uses the uncorrelated Smith masking G1 * G1 and Trayecto the
height-correlated G2 (Heitz 2014), never smaller: Trayecto may be brighter by that model
difference (tests/furnace.rs bounds it).

Results (mitsuba 3.9.1, scalar_rgb, 64x64, 16384 spp = 32 chunks of 512, seeds 0..31):
  --roughness 0.5: image mean 0.922012 +- 0.000030 (Ebar over the disc 0.77658), 159 s
  --roughness 0.3: image mean 0.981417 +- 0.000020 (Ebar over the disc 0.94676), 251 s
"""
import argparse
import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from make_references import pick_variant  # noqa: E402

HALF_FRAME = 1.5
DIST = 200.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int, default=8192)
    ap.add_argument("--chunk", type=int, default=512)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--roughness", type=float, default=0.5)
    ap.add_argument("--variant", default="auto")
    args = ap.parse_args()

    import numpy as np
    import mitsuba as mi

    mi.set_variant(pick_variant(args.variant))
    fov = 2.0 * math.degrees(math.atan(HALF_FRAME / DIST))
    alpha = args.roughness ** 2
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": -1},
        "sensor": {
            "type": "perspective",
            "fov": fov,
            "fov_axis": "y",
            "near_clip": 1.0,
            "far_clip": 1000.0,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, DIST], target=[0, 0, 0], up=[0, 1, 0]),
            "sampler": {"type": "independent"},
            "film": {"type": "hdrfilm", "width": args.size, "height": args.size,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
        "sphere": {
            "type": "sphere",
            "center": [0, 0, 0],
            "radius": 1.0,
            "bsdf": {"type": "roughdielectric", "distribution": "ggx", "alpha": alpha,
                     "int_ior": 1.5, "ext_ior": 1.0, "sample_visible": True},
        },
    })
    means = []
    t0 = time.time()
    seed = 0
    while seed * args.chunk < args.spp:
        img = np.array(mi.render(scene, spp=args.chunk, seed=seed), dtype=np.float64)
        means.append(img.mean())
        seed += 1
        print(f"  chunk {seed}: mean {means[-1]:.6f} ({time.time() - t0:.0f} s)", flush=True)
    means = np.array(means)
    mean = means.mean()
    sem = means.std(ddof=1) / math.sqrt(len(means))
    coverage = math.pi / (4.0 * HALF_FRAME ** 2)
    print(f"variant {mi.variant()}, roughness {args.roughness} (alpha {alpha}), {args.size}x{args.size}, "
          f"{len(means) * args.chunk} spp, {time.time() - t0:.0f} s")
    print(f"image mean {mean:.6f} +- {sem:.6f} (1 sigma)")
    print(f"Ebar over the disc {1 - (1 - mean) / coverage:.5f} +- {sem / coverage:.5f}")


if __name__ == "__main__":
    main()
