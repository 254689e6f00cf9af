#!/usr/bin/env python3
"""Writes scenes/pbrt/bump-waves.pfm, the height map of the pbrt-v4 `displacement` feature scene
(scenes/pbrt/bump.pbrt): 128x128, linear, one channel repeated in RGB, h = 0.5 + 0.35 sin(2π·2u)
+ 0.15 sin(2π·3v) (rows top first as pbrt-v4 reads images: the top row is v = 1). Smooth at the
scale of a pixel footprint, so pbrt-v4's finite differences (a step of the footprint) and
Trayecto's (a fixed 0.0005) measure the same slope. Reference:
scripts/pbrt_references.sh 1024 bump. numpy only.
"""
import math
import pathlib

import numpy as np

N = 128
root = pathlib.Path(__file__).resolve().parents[1]
img = np.zeros((N, N, 3), dtype=np.float32)
for row in range(N):
    v = 1 - (row + 0.5) / N
    for x in range(N):
        u = (x + 0.5) / N
        h = 0.5 + 0.35 * math.sin(2 * math.pi * 2 * u) + 0.15 * math.sin(2 * math.pi * 3 * v)
        img[row, x] = h
out = root / "scenes/pbrt/bump-waves.pfm"
with open(out, "wb") as f:
    f.write(f"PF\n{N} {N}\n-1.0\n".encode())
    f.write(img[::-1].astype("<f4").tobytes())  # PFM rows run bottom to top
print("wrote", out.relative_to(root))
