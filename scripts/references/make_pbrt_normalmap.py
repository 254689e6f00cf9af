#!/usr/bin/env python3
"""Writes scenes/pbrt/normalmap-waves.pfm, the tangent-space normal map of the pbrt-v4 normalmap
feature scene (scenes/pbrt/normalmap.pbrt): 64x64, linear, texel = (n + 1) / 2 of a surface with
waves along u and, weaker, along v (rows top first, as pbrt-v4 reads images; v = 1 is the top).
Reference: scripts/pbrt_references.sh 1024 normalmap. numpy only.
"""
import math
import pathlib

import numpy as np

N = 64
root = pathlib.Path(__file__).resolve().parents[2]
img = np.zeros((N, N, 3), dtype=np.float32)
for row in range(N):
    v = 1 - (row + 0.5) / N  # pbrt's v of this row (the image's top row is v = 1)
    for x in range(N):
        u = (x + 0.5) / N
        # Height h = 0.06 sin(2π·3u) + 0.03 sin(2π·2v) in units of the [0,1]² patch: n ∝ (−∂h/∂u, −∂h/∂v, 1).
        du = 0.06 * 2 * math.pi * 3 * math.cos(2 * math.pi * 3 * u)
        dv = 0.03 * 2 * math.pi * 2 * math.cos(2 * math.pi * 2 * v)
        n = np.array([-du, -dv, 1.0])
        n /= np.linalg.norm(n)
        img[row, x] = (n + 1) / 2
out = root / "scenes/pbrt/normalmap-waves.pfm"
with open(out, "wb") as f:
    f.write(f"PF\n{N} {N}\n-1.0\n".encode())
    f.write(img[::-1].astype("<f4").tobytes())  # PFM rows run bottom to top
print("wrote", out.relative_to(root))
