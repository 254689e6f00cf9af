#!/usr/bin/env python3
"""Writes src/spectrum/rgb2spec_srgb.bin: the sigmoid-polynomial table that turns a linear-sRGB
reflectance into a smooth, bounded spectrum (Jakob & Hanika, "A Low-Dimensional Function Space for
Efficient Spectral Upsampling", Computer Graphics Forum 38(2), 2019).

A reflectance is modelled as s(lambda) = S(c0 lambda^2 + c1 lambda + c2) with the sigmoid
S(x) = 1/2 + x / (2 sqrt(1 + x^2)), which stays in (0, 1) for any coefficients. For every RGB on a
grid the three coefficients are found by Gauss-Newton (paper section 3.3): the residual is the
CIELAB difference between the target and the RGB of the spectrum seen under D65 (the sRGB
illuminant), the Jacobian is taken by central differences, and each solve starts from the solution
of its neighbour on the grid (the paper's continuation), walking the brightness axis outwards from
a fifth of the way up, where the problem is easiest.

Grid (the paper's parameterisation, as pbrt-v4 stores it): for each channel m that is the largest,
z = rgb[m] on RES nodes spaced by smoothstep(smoothstep(k / (RES - 1))) (dense near 0 and 1, where
the coefficients change fastest), x = rgb[(m + 1) % 3] / z and y = rgb[(m + 2) % 3] / z on RES
uniform nodes in [0, 1]. Layout: f32 little endian, [m][z][y][x][coefficient], coefficients of the
polynomial in lambda in nm (c0 multiplies lambda^2).

The CIE 1931 functions and D65 are read from src/spectrum/data.rs, so the table inverts exactly the
projection src/spectrum uses (`reflectance_to_rgb`: 1 nm sums over 360-830 nm).

Run: python3 scripts/gen_rgb2spec.py [RES]  (numpy; a few seconds). It prints the round-trip error
over the gamut, which is also checked by the unit tests of src/spectrum/rgb2spec.rs.
"""
import os
import re
import sys

import numpy as np

RES = int(sys.argv[1]) if len(sys.argv) > 1 else 24
root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
src = open(os.path.join(root, "src", "spectrum", "data.rs")).read()


def table(name):
    m = re.search(r"pub const " + name + r": \[f32; \d+\] = \[(.*?)\];", src, re.S)
    return np.array([float(v) for v in m.group(1).replace("\n", " ").split(",") if v.strip()])


lam = np.arange(360.0, 831.0)
cie = np.stack([table("CIE_X"), table("CIE_Y"), table("CIE_Z")], axis=1)  # (471, 3)
d65_5nm = table("D65")
d65 = np.interp(lam, np.arange(360.0, 831.0, 5.0), d65_5nm)
d65 = d65 * cie[:, 1].sum() / (d65 * cie[:, 1]).sum()  # luminance Y = 1
XYZ_TO_RGB = np.array([
    [3.2404542, -1.5371385, -0.4985314],
    [-0.9692660, 1.8760108, 0.0415560],
    [0.0556434, -0.2040259, 1.0572252],
])
# Reflectance spectrum (sampled on `lam`) -> linear sRGB under D65.
W = (cie * d65[:, None]) / cie[:, 1].sum() @ XYZ_TO_RGB.T  # (471, 3)
RGB_TO_XYZ = np.linalg.inv(XYZ_TO_RGB)
WHITE = RGB_TO_XYZ @ np.ones(3)
t = (lam - 360.0) / 470.0  # the solver works on normalised wavelengths


def lab(rgb):
    xyz = rgb @ RGB_TO_XYZ.T / WHITE

    def f(v):
        d = 6.0 / 29.0
        return np.where(v > d ** 3, np.cbrt(v), v / (3 * d * d) + 4.0 / 29.0)

    fx, fy, fz = f(xyz[..., 0]), f(xyz[..., 1]), f(xyz[..., 2])
    return np.stack([116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz)], axis=-1)


def sigmoid(x):
    return 0.5 + x / (2.0 * np.sqrt(1.0 + x * x))


def spectrum_rgb(c):
    """(N, 3) normalised-wavelength coefficients -> (N, 3) RGB."""
    x = c[:, 0:1] * t * t + c[:, 1:2] * t + c[:, 2:3]
    return sigmoid(x) @ W


def residual(c, target_lab):
    return lab(spectrum_rgb(c)) - target_lab


def gauss_newton(c, target_rgb):
    target = lab(target_rgb)
    for _ in range(40):
        r = residual(c, target)
        jac = np.empty(c.shape + (3,))
        for k in range(3):
            h = np.zeros(3)
            h[k] = 1e-4
            jac[:, :, k] = (residual(c + h, target) - residual(c - h, target)) / 2e-4
        # The normal equations with a vanishing ridge, so that a point whose sigmoid has
        # saturated (a singular Jacobian) takes a bounded step instead of stopping the batch.
        jt = np.swapaxes(jac, 1, 2)
        step = np.linalg.solve(jt @ jac + 1e-12 * np.eye(3), (jt @ r[..., None]))[..., 0]
        step = np.where(np.isfinite(step), step, 0.0)
        # A full Gauss-Newton step can jump into a region where the sigmoid has saturated and
        # every derivative vanishes (then it never returns): per point, take the longest of the
        # steps 1, 1/2, ..., 1/64 that reduces the residual most.
        best, best_norm = c, (r * r).sum(axis=1)
        for k in range(7):
            cand = c - step * 0.5 ** k
            big = cand.max(axis=1, keepdims=True)
            cand = np.where(big > 200.0, cand * 200.0 / np.maximum(big, 1e-30), cand)
            rc = residual(cand, target)
            norm = (rc * rc).sum(axis=1)
            better = norm < best_norm
            best = np.where(better[:, None], cand, best)
            best_norm = np.where(better, norm, best_norm)
        c = best
        if np.abs(r).max() < 1e-6:
            break
    return c


def smoothstep(x):
    return x * x * (3.0 - 2.0 * x)


scale = smoothstep(smoothstep(np.linspace(0.0, 1.0, RES)))
xs = np.linspace(0.0, 1.0, RES)
gx, gy = np.meshgrid(xs, xs)  # [y][x]
gx, gy = gx.reshape(-1), gy.reshape(-1)
out = np.zeros((3, RES, RES, RES, 3))
start = RES // 5
for m in range(3):
    for order in (range(start, RES), range(start, -1, -1)):
        c = np.zeros((RES * RES, 3))
        for zi in order:
            z = scale[zi]
            rgb = np.zeros((RES * RES, 3))
            rgb[:, m] = z
            rgb[:, (m + 1) % 3] = gx * z
            rgb[:, (m + 2) % 3] = gy * z
            c = gauss_newton(c, rgb)
            # Normalised wavelength -> nm: t = (lambda - 360) / 470.
            a, b, d = c[:, 0], c[:, 1], c[:, 2]
            s, o = 1.0 / 470.0, -360.0 / 470.0
            out[m, zi, :, :, 0] = (a * s * s).reshape(RES, RES)
            out[m, zi, :, :, 1] = (2 * a * s * o + b * s).reshape(RES, RES)
            out[m, zi, :, :, 2] = (a * o * o + b * o + d).reshape(RES, RES)

# Round trip through the stored (f32, nm) coefficients at the grid nodes (interpolation between
# nodes is measured by the unit tests).
worst = 0.0
for m in range(3):
    for zi in range(RES):
        z = scale[zi]
        rgb = np.zeros((RES * RES, 3))
        rgb[:, m] = z
        rgb[:, (m + 1) % 3] = gx * z
        rgb[:, (m + 2) % 3] = gy * z
        c = out[m, zi].reshape(-1, 3).astype(np.float32).astype(np.float64)
        x = c[:, 0:1] * lam * lam + c[:, 1:2] * lam + c[:, 2:3]
        worst = max(worst, np.abs(sigmoid(x) @ W - rgb).max())
print(f"RES {RES}: max |rgb - round trip| at the grid nodes = {worst:.2e}")
path = os.path.join(root, "src", "spectrum", "rgb2spec_srgb.bin")
out.astype("<f4").tofile(path)
print(f"wrote {path} ({out.size * 4} bytes)")

# Round trip between the nodes, as src/spectrum/rgb2spec.rs evaluates the table (trilinear in the
# coefficients), over random colours of the gamut.
rng = np.random.default_rng(1)
rgbs = rng.random((20000, 3)) ** 2
tab = out.astype(np.float32).astype(np.float64)
worst_all, worst_bright = 0.0, 0.0
for rgb in rgbs:
    m = int(np.argmax(rgb))
    z = rgb[m]
    x = rgb[(m + 1) % 3] / z * (RES - 1)
    y = rgb[(m + 2) % 3] / z * (RES - 1)
    xi, yi = min(int(x), RES - 2), min(int(y), RES - 2)
    zi = min(max(int(np.searchsorted(scale, z) - 1), 0), RES - 2)
    dx, dy, dz = x - xi, y - yi, (z - scale[zi]) / (scale[zi + 1] - scale[zi])
    c = np.zeros(3)
    for a in (0, 1):
        for b in (0, 1):
            for d in (0, 1):
                w = (dz if a else 1 - dz) * (dy if b else 1 - dy) * (dx if d else 1 - dx)
                c += w * tab[m, zi + a, yi + b, xi + d]
    s = sigmoid(c[0] * lam * lam + c[1] * lam + c[2])
    e = np.abs(s @ W - rgb).max()
    worst_all = max(worst_all, e)
    if z >= 0.05:
        worst_bright = max(worst_bright, e / z)
print(f"RES {RES}: random gamut colours: max abs error {worst_all:.2e}, "
      f"max error / max(rgb) for max(rgb) >= 0.05: {worst_bright:.2e}")
