#!/usr/bin/env python3
"""Writes the equal-area environment map used by the pbrt-v4 envmap feature scenes
(scenes/pbrt/envmap-*.pbrt): scenes/pbrt/envmap-sky.pfm, 64×64, in pbrt-v4's equal-area octahedral
square parameterisation (Clarberg 2008; pbrt-v4 book §3.8.3). In the map's own frame +z is "up":
a blue sky gradient above, a brown ground below, a small bright sun, and coloured patches toward
+x (red) and +y (green) so that a mirrored or rotated lookup shows. Deterministic; numpy only.

The references are then rendered by pbrt-v4: scripts/pbrt_references.sh envmap-sky envmap-illuminance
"""
import math
import pathlib
import struct

import numpy as np

N = 64
root = pathlib.Path(__file__).resolve().parents[2]


def square_to_sphere(u, v):
    """Clarberg's equal-area square-to-sphere map, u, v in [0, 1]."""
    u, v = 2 * u - 1, 2 * v - 1
    up, vp = abs(u), abs(v)
    signed = 1 - (up + vp)
    r = 1 - abs(signed)
    phi = math.pi / 4 if r == 0 else ((vp - up) / r + 1) * math.pi / 4
    z = math.copysign(1 - r * r, signed)
    s = r * math.sqrt(max(0.0, 2 - r * r))
    return (math.copysign(math.cos(phi), u) * s, math.copysign(math.sin(phi), v) * s, z)


sun = np.array([0.5, -0.3, 0.6])
sun /= np.linalg.norm(sun)
img = np.zeros((N, N, 3), dtype=np.float32)  # row 0 is the top row (v = 0), as pbrt-v4 stores it
for y in range(N):
    for x in range(N):
        d = np.array(square_to_sphere((x + 0.5) / N, (y + 0.5) / N))
        if d[2] >= 0:
            c = np.array([0.35, 0.55, 1.0]) * (0.4 + 0.8 * d[2]) + np.array([0.6, 0.5, 0.4]) * (1 - d[2]) ** 4
        else:
            c = np.array([0.25, 0.18, 0.1]) * (0.5 + 0.5 * (1 + d[2]))
        if d[0] > 0.85:
            c = np.array([1.5, 0.1, 0.1])
        if d[1] > 0.85:
            c = np.array([0.1, 1.2, 0.2])
        if np.dot(d, sun) > 0.985:
            c = np.array([30.0, 26.0, 20.0])
        img[y, x] = c

out = root / "scenes/pbrt/envmap-sky.pfm"
with open(out, "wb") as f:
    f.write(f"PF\n{N} {N}\n-1.0\n".encode())
    # PFM rows run bottom to top.
    f.write(img[::-1].astype("<f4").tobytes())
print(f"wrote {out.relative_to(root)} ({N}×{N}, mean {img.mean(axis=(0, 1))})")
