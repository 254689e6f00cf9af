#!/usr/bin/env python3
"""Writes scenes/pbrt/bump-curved.pbrt: pbrt-v4 `displacement` on a curved mesh with vertex
normals, where pbrt-v4's BumpMap adds d·∂n/∂u to ∂p/∂u (and d·∂n/∂v to ∂p/∂v). A UV sphere of
radius 0.5 as a trianglemesh (24 x 16 quads, normals p/r, uv = (φ/2π, θ/π) with v up) bump-mapped
by bump-waves.pfm scaled by 0.2 (heights up to 0.2, so d/r up to 0.4: the d·∂n/∂u term changes
the bump's tilt by a third, and grazing point lights show it). With the heights unscaled (d/r
about 2, as steep as Bitterli's bathroom foam) the uv parameterisation's ∂p/∂v and pbrt's shading
∂p/∂v = n × ∂p/∂u point opposite ways, the v term nearly cancels, and both renderers' normals
become hypersensitive to the finite differences: not a scene to compare them on. A flat floor
below carries the same map (∂n/∂u = 0 there). Reference: scripts/pbrt_references.sh 1024
bump-curved. Standard library only.
"""
import math
import pathlib

NU, NV, R = 24, 16, 0.5
root = pathlib.Path(__file__).resolve().parents[1]
P, N, UV, IDX = [], [], [], []
for j in range(NV + 1):
    theta = math.pi * j / NV
    for i in range(NU + 1):
        phi = 2 * math.pi * i / NU
        n = (math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
        N.append(n)
        P.append(tuple(R * c for c in n))
        UV.append((i / NU, 1 - j / NV))
for j in range(NV):
    for i in range(NU):
        a, b = j * (NU + 1) + i, j * (NU + 1) + i + 1
        c, d = a + NU + 1, b + NU + 1
        # Outward winding (counter-clockwise seen from outside).
        IDX += [a, b, d, a, d, c]


def fmt(vals):
    return " ".join(f"{x:.6g}" for v in vals for x in v)


text = f"""# pbrt-v4 `displacement` on a curved mesh with vertex normals: BumpMap adds d*dn/du to dp/du
# and d*dn/dv to dp/dv, which at d/r up to 0.4 changes the bump's tilt by a third (written by
# scripts/pbrt_make_bump_curved.py). Reference: scripts/pbrt_references.sh 1024 bump-curved.
LookAt 0 1.2 -3  0 0.35 0  0 1 0
Camera "perspective" "float fov" [ 35 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 48 ]
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 5 ]
WorldBegin
LightSource "point" "rgb I" [ 3 3 3 ] "point3 from" [ -2 1.2 -0.5 ]
LightSource "point" "rgb I" [ 1 1.5 2 ] "point3 from" [ 1.5 2 -1 ]
Texture "height" "float" "imagemap" "string filename" "bump-waves.pfm" "float scale" [ 0.2 ]
Material "diffuse" "rgb reflectance" [ 0.7 0.7 0.7 ] "texture displacement" "height"
Shape "trianglemesh" "point3 P" [ -2 0 -2  2 0 -2  2 0 2  -2 0 2 ] "integer indices" [ 0 2 1 0 3 2 ]
    "point2 uv" [ 0 0  1 0  1 1  0 1 ]
AttributeBegin
  Translate 0 0.5 0
  Shape "trianglemesh" "point3 P" [ {fmt(P)} ]
    "normal N" [ {fmt(N)} ]
    "point2 uv" [ {fmt(UV)} ]
    "integer indices" [ {" ".join(map(str, IDX))} ]
AttributeEnd
"""
out = root / "scenes/pbrt/bump-curved.pbrt"
out.write_text(text)
print("wrote", out.relative_to(root))
