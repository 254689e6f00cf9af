#!/usr/bin/env python3
"""Writes scenes/pbrt/bump-tiles.tga, the height map of scenes/pbrt/bump-tiles.pbrt: 128x128,
8-bit grey, tiles of 16 texels (value 200) with 2-texel grout lines (value 70) and a deterministic
per-texel grain of +-12, like the colour image of tiles Bitterli's bathroom reads as its floor's
displacement. Its edges are sharp at a pixel's scale, so the slope pbrt-v4's `BumpMap` measures
depends on its finite-difference step (the pixel footprint) and on the MIP level it reads.
Standard library only (an uncompressed TGA, rows top first).
Reference: scripts/pbrt_references.sh 1024 bump-tiles
"""
import pathlib
import struct

N, TILE, GROUT = 128, 16, 2
root = pathlib.Path(__file__).resolve().parents[1]
state = 12345


def grain():
    # A 32-bit LCG (Numerical Recipes constants): the same image on every machine.
    global state
    state = (1664525 * state + 1013904223) & 0xFFFFFFFF
    return (state >> 24) % 25 - 12


pixels = bytearray()
for y in range(N):
    for x in range(N):
        grout = x % TILE < GROUT or y % TILE < GROUT
        v = max(0, min(255, (70 if grout else 200) + grain()))
        pixels += bytes([v, v, v])
header = struct.pack("<BBBHHBHHHHBB", 0, 0, 2, 0, 0, 0, 0, 0, N, N, 24, 0x20)
out = root / "scenes/pbrt/bump-tiles.tga"
out.write_bytes(header + bytes(pixels))
print("wrote", out.relative_to(root))
