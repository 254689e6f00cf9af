#!/usr/bin/env python3
"""How a tone-mapped picture of a model reads: for each PNG (8-bit RGBA, as `trayecto render
--transparent` writes), over the model's pixels (alpha >= 250: edges excluded): the mean display luma, the
fraction of pixels with a channel at 255 (saturated: no detail left), and the contrast (the
standard deviation of luma over its mean: 0 for a flat silhouette). Used by
scripts/first-renders.sh for docs/DESIGN.md, "The default light". Needs numpy only (a small PNG
reader: the filters of the PNG specification, section 9)."""
import struct
import sys
import zlib

import numpy as np


def read_png(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, hdr = 8, b"", None
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            hdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h, depth, colour, _, _, interlace = hdr
    assert depth == 8 and interlace == 0 and colour in (2, 6), (path, hdr)
    bpp = 4 if colour == 6 else 3
    raw = zlib.decompress(idat)
    stride = w * bpp
    out = np.zeros((h, stride), np.int32)
    prev = np.zeros(stride, np.int32)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int32)
        cur = np.zeros(stride, np.int32)
        for x in range(stride):
            a = cur[x - bpp] if x >= bpp else 0
            b = prev[x]
            c = prev[x - bpp] if x >= bpp else 0
            if f == 0:
                p = 0
            elif f == 1:
                p = a
            elif f == 2:
                p = b
            elif f == 3:
                p = (a + b) // 2
            else:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[x] = (line[x] + p) & 255
        out[y], prev = cur, cur
    return out.reshape(h, w, bpp)


for path in sys.argv[1:]:
    px = read_png(path).astype(np.float64)
    mask = px[..., 3] >= 250 if px.shape[2] == 4 else np.ones(px.shape[:2], bool)
    rgb = px[..., :3][mask]
    luma = rgb @ np.array([0.2126, 0.7152, 0.0722])
    sat = (rgb >= 254.5).any(axis=1).mean()
    print(f"{path}: mean {luma.mean():.0f}/255, saturated {100 * sat:.1f} %, "
          f"contrast {luma.std() / max(luma.mean(), 1e-9):.3f}")
