#!/usr/bin/env python3
"""Writes scenes/pbrt/prism-bk7.pbrt: white light split by a BK7 prism, seen through it.

A pinhole camera at the origin looks along +z through an equilateral prism of pbrt-v4's named
glass "glass-BK7" (axis vertical, so every camera ray of the 1°-tall image refracts in the x-z
plane), entering its first face at 62° (away from minimum deviation, where the exit direction
would not depend on the camera ray's). Far behind the second face, along the exit direction of
the central ray at the helium d line (587.6 nm), a narrow vertical stripe (0.1° wide seen from the
prism) emits D65 white ("rgb L" [1 1 1]). A camera ray of wavelength λ reaches it only if Snell's
law with BK7's η(λ) turns it there, so each column of the image sees the band of wavelengths
aimed at the stripe from it: a spectrum, blue on the left. `maxdepth 2` keeps only the paths
through both faces. tests/pbrt_import.rs (`bk7_prism_splits_white_light_by_snells_law`) predicts
where each wavelength lands from the vertices below and Snell's law, and compares Trayecto's
spectral and RGB renders and pbrt-v4's (scripts/pbrt_references.sh 1024 prism-bk7).

Prints the vertices (x, z) the test uses. Deterministic; standard library only.
"""
import math
import pathlib

root = pathlib.Path(__file__).resolve().parents[2]
B = (1.03961212, 0.231792344, 1.01046945)  # Schott BK7 Sellmeier coefficients
C = (0.00600069867, 0.0200179144, 103.560653)


def n_bk7(lam):
    l2 = (lam * 1e-3) ** 2
    return math.sqrt(1 + sum(b * l2 / (l2 - c) for b, c in zip(B, C)))


def rot(v, a):
    c, s = math.cos(a), math.sin(a)
    return (c * v[0] - s * v[1], s * v[0] + c * v[1])


def refract(d, n, eta):
    """d: unit direction, n: unit normal against d, eta = n_t / n_i."""
    c = -(d[0] * n[0] + d[1] * n[1])
    k = 1 - (1 - c * c) / (eta * eta)
    t = c / eta - math.sqrt(k)
    return (d[0] / eta + t * n[0], d[1] / eta + t * n[1])


def hit(o, d, a, b):
    """Ray o + t d against segment a-b: the point, or None."""
    e = (b[0] - a[0], b[1] - a[1])
    det = -d[0] * e[1] + d[1] * e[0]
    w = (a[0] - o[0], a[1] - o[1])
    t = (-w[0] * e[1] + w[1] * e[0]) / det
    u = (d[0] * w[1] - d[1] * w[0]) / det
    return (o[0] + t * d[0], o[1] + t * d[1]) if t > 1e-6 and 0 <= u <= 1 else None


# Equilateral triangle, side 8, in a frame (u, v) with its apex up; face 1 is the left side.
s = 8.0
tri = [(-s / 2, 0.0), (0.0, s * math.sqrt(3) / 2), (s / 2, 0.0)]
# The incident direction at 62° from face 1's inward normal (which points at -30°), turned to +z.
a_in = math.radians(-30 + 62)
turn = math.pi / 2 - a_in
# (x, z) = rotate (u, v), then move face 1's midpoint to (0, 6).
tri = [rot(p, turn) for p in tri]
tri = [(x, z) for (z, x) in [(p[1], p[0]) for p in tri]]  # rot gives (x', y'); y' is world z
mid = ((tri[0][0] + tri[1][0]) / 2, (tri[0][1] + tri[1][1]) / 2)
tri = [(round(p[0] - mid[0], 4), round(p[1] - mid[1] + 6.0, 4)) for p in tri]


def through(d, lam):
    """The central camera ray through faces 1 (tri0-tri1) and 2 (tri1-tri2)."""
    n = n_bk7(lam)
    p = hit((0.0, 0.0), d, tri[0], tri[1])
    e = (tri[1][0] - tri[0][0], tri[1][1] - tri[0][1])
    nrm = (e[1], -e[0])
    ln = math.hypot(*nrm)
    nrm = (nrm[0] / ln, nrm[1] / ln)
    if nrm[0] * d[0] + nrm[1] * d[1] > 0:
        nrm = (-nrm[0], -nrm[1])
    d = refract(d, nrm, n)
    q = hit(p, d, tri[1], tri[2])
    e = (tri[2][0] - tri[1][0], tri[2][1] - tri[1][1])
    nrm = (e[1], -e[0])
    ln = math.hypot(*nrm)
    nrm = (nrm[0] / ln, nrm[1] / ln)
    if nrm[0] * d[0] + nrm[1] * d[1] > 0:
        nrm = (-nrm[0], -nrm[1])
    return q, refract(d, nrm, 1 / n)


q, e = through((0.0, 1.0), 587.56)
phi = math.atan2(e[0], e[1])
dist, half = 200.0, 200.0 * math.radians(0.05)
c = (q[0] + dist * math.sin(phi), q[1] + dist * math.cos(phi))
perp = (math.cos(phi), -math.sin(phi))
stripe = [
    (round(c[0] - half * perp[0], 4), round(c[1] - half * perp[1], 4)),
    (round(c[0] + half * perp[0], 4), round(c[1] + half * perp[1], 4)),
]


def v3(p, y):
    return f"{p[0]} {y} {p[1]}"


P = "  ".join([v3(p, -5) for p in tri] + [v3(p, 5) for p in tri])
text = f"""# White light split by a BK7 prism (written by scripts/references/make_pbrt_prism.py, which says
# what it shows). Reference: scripts/pbrt_references.sh 1024 prism-bk7
LookAt 0 0 0  0 0 1  0 1 0
Camera "perspective" "float fov" [ 1 ]
Film "rgb" "integer xresolution" [ 160 ] "integer yresolution" [ 8 ]
PixelFilter "box"
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 2 ]
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 1 1 1 ] "float scale" [ 50 ] "bool twosided" true
  Shape "trianglemesh" "point3 P" [ {v3(stripe[0], -20)}  {v3(stripe[1], -20)}  {v3(stripe[1], 20)}  {v3(stripe[0], 20)} ]
    "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
Material "dielectric" "spectrum eta" "glass-BK7"
Shape "trianglemesh" "point3 P" [ {P} ]
  "integer indices" [ 0 1 4 0 4 3  1 2 5 1 5 4  2 0 3 2 3 5  0 2 1  3 4 5 ]
"""
(root / "scenes/pbrt/prism-bk7.pbrt").write_text(text)
print("prism (x, z):", tri)
print("stripe (x, z):", stripe)
