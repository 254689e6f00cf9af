#!/usr/bin/env python3
"""Writes scenes/pbrt/media/emissive_grid.pbrt: pbrt-v4 `uniformgrid` media that emit.
Left box: a `temperature` grid (800-2600 K ramp, blackbody normalised to peak 1) weighted by an
`Lescale` grid, `temperaturescale`/`temperatureoffset` exercised. Right box: `rgb Le` weighted by
an `Lescale` grid. Grey sigma (so pbrt-v4's spectral rendering and Trayecto's RGB agree), black
background: the image is the media's own light, partly scattered. Both grids are 4x4x4, filling
their box, so pbrt-v4's zero-outside-the-samples lookup (density and Lescale fade to the faces)
matters. Reference: `scripts/pbrt_references.sh 1024 media/emissive_grid`
(tests/references/pbrt/media/emissive_grid.exr); test: tests/media_render.rs
`emissive_grid_matches_pbrt_v4`.
"""
import os

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
N = 4


def grid(fn):
    return " ".join(f"{fn(x, y, z):.5g}" for z in range(N) for y in range(N) for x in range(N))


def box(lo, hi):
    p = [[(hi if (i >> k) & 1 else lo)[k] for k in range(3)] for i in range(8)]
    faces = [(0, 4, 6, 2), (1, 3, 7, 5), (0, 1, 5, 4), (2, 6, 7, 3), (0, 2, 3, 1), (4, 5, 7, 6)]
    tris = [t for a, b, c, d in faces for t in ((a, b, c), (a, c, d))]
    pts = "  ".join(" ".join(f"{v:g}" for v in q) for q in p)
    return (f'Shape "trianglemesh" "point3 P" [ {pts} ] '
            f'"integer indices" [ {" ".join(str(i) for t in tris for i in t)} ]')


a_lo, a_hi = (-1.3, 0.0, -0.5), (-0.1, 1.2, 0.5)
b_lo, b_hi = (0.1, 0.0, -0.5), (1.3, 1.2, 0.5)
density = grid(lambda x, y, z: 0.5 + 0.5 * x + 0.25 * ((y + z) % 3))
lines = [
    "# emissive_grid: written by scripts/references/make_pbrt_emissive_grid.py (do not edit).",
    "Scale -1 1 1",
    "LookAt 0 0.6 4  0 0.6 0  0 1 0",
    'Camera "perspective" "float fov" [ 35 ]',
    'Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 48 ]',
    'Sampler "independent" "integer pixelsamples" [ 64 ]',
    'Integrator "volpath" "integer maxdepth" [ 100 ]',
    "WorldBegin",
    # A dim sky (written before Trayecto's default-light rule counted glowing grids as the
    # scene's lighting; kept so the committed reference stays valid).
    'LightSource "infinite" "rgb L" [ 0.02 0.02 0.02 ]',
    'MakeNamedMedium "flame" "string type" "uniformgrid"',
    '    "rgb sigma_a" [ 1.5 1.5 1.5 ] "rgb sigma_s" [ 0.5 0.5 0.5 ] "float g" [ 0.2 ]',
    f'    "integer nx" [ {N} ] "integer ny" [ {N} ] "integer nz" [ {N} ]',
    f'    "point3 p0" [ {" ".join(map(str, a_lo))} ] "point3 p1" [ {" ".join(map(str, a_hi))} ]',
    f'    "float density" [ {density} ]',
    # T = (t - 100) * 1.25: raw 740-2180 -> 800-2600 K, rising with height.
    f'    "float temperature" [ {grid(lambda x, y, z: 740 + 480 * y)} ]',
    '    "float temperatureoffset" [ 100 ] "float temperaturescale" [ 1.25 ]',
    f'    "float Lescale" [ {grid(lambda x, y, z: 2.0 + (x + z) % 2)} ]',
    'MakeNamedMedium "glow" "string type" "uniformgrid"',
    '    "rgb sigma_a" [ 1 1 1 ] "rgb sigma_s" [ 0.8 0.8 0.8 ]',
    f'    "integer nx" [ {N} ] "integer ny" [ {N} ] "integer nz" [ {N} ]',
    f'    "point3 p0" [ {" ".join(map(str, b_lo))} ] "point3 p1" [ {" ".join(map(str, b_hi))} ]',
    f'    "float density" [ {density} ]',
    '    "rgb Le" [ 1 0.6 0.3 ]',
    f'    "float Lescale" [ {grid(lambda x, y, z: 0.5 * (y + 1) * (1 + (x % 2)))} ]',
    "AttributeBegin",
    '  MediumInterface "flame" ""',
    '  Material "interface"',
    "  " + box(a_lo, a_hi),
    "AttributeEnd",
    "AttributeBegin",
    '  MediumInterface "glow" ""',
    '  Material "interface"',
    "  " + box(b_lo, b_hi),
    "AttributeEnd",
]
out = os.path.join(ROOT, "scenes", "pbrt", "media", "emissive_grid.pbrt")
with open(out, "w") as fh:
    fh.write("\n".join(lines) + "\n")
print("wrote", os.path.relpath(out, ROOT))
