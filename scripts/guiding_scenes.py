#!/usr/bin/env python3
"""Writes the hard-indirect benchmark scenes of path guiding to scenes/guiding/ (pbrt-v4 format;
BENCHMARKS.md, "Path guiding"): a room lit through a door gap, a sunlit interior, a room lit by the
bounce off a small bright patch, and the gap room filled with fog. Small, closed rooms of grey
diffuse walls: the light that reaches most of what the camera sees arrives from a few directions
after one or more bounces, where a BSDF-and-NEE path tracer samples mostly the wrong ones."""
import os

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "guiding")


def quad(p0, p1, p2, p3, refl=(0.7, 0.7, 0.7), emit=None):
    pts = " ".join(f"{c:g}" for p in (p0, p1, p2, p3) for c in p)
    s = "AttributeBegin\n"
    if emit:
        s += f'  AreaLightSource "diffuse" "rgb L" [ {emit[0]} {emit[1]} {emit[2]} ]\n'
        refl = (0, 0, 0)
    s += f'  Material "diffuse" "rgb reflectance" [ {refl[0]} {refl[1]} {refl[2]} ]\n'
    s += f'  Shape "trianglemesh" "point3 P" [ {pts} ] "integer indices" [ 0 1 2 0 2 3 ]\n'
    return s + "AttributeEnd\n"


def xwall(x, y0, y1, z0, z1, **k):
    return quad((x, y0, z0), (x, y1, z0), (x, y1, z1), (x, y0, z1), **k)


def ywall(y, x0, x1, z0, z1, **k):
    return quad((x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1), **k)


def zwall(z, x0, x1, y0, y1, **k):
    return quad((x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z), **k)


def header(name, what, medium=None):
    s = f"# {name}: {what}\n# Written by scripts/guiding_scenes.py (do not edit by hand).\n\n"
    s += "LookAt -1.7 1.3 1.8  0.6 0.9 -1.2  0 1 0\n"
    if medium:
        s += medium + '\nMediumInterface "fog" "fog"\n'
    s += 'Camera "perspective" "float fov" [ 65 ]\n'
    s += 'Film "rgb" "integer xresolution" [ 128 ] "integer yresolution" [ 96 ]\n'
    s += 'Sampler "zsobol" "integer pixelsamples" [ 64 ]\n'
    s += 'Integrator "%s" "integer maxdepth" [ 32 ]\n' % ("volpath" if medium else "path")
    return s + "WorldBegin\n"


def room(skip_right=False, skip_left=False):
    """The main room: x in [-2, 2], y in [0, 2.5], z in [-2, 2]."""
    s = ywall(0, -2, 2, -2, 2, refl=(0.6, 0.6, 0.6))  # floor
    s += ywall(2.5, -2, 2, -2, 2)  # ceiling
    s += zwall(-2, -2, 2, 0, 2.5, refl=(0.65, 0.6, 0.5))  # back
    s += zwall(2, -2, 2, 0, 2.5)  # front (behind the camera)
    if not skip_left:
        s += xwall(-2, 0, 2.5, -2, 2, refl=(0.6, 0.2, 0.2))
    if not skip_right:
        s += xwall(2, 0, 2.5, -2, 2, refl=(0.2, 0.5, 0.25))
    return s


def gap_room(medium=None):
    """The right wall (x = 2) has a door 0.08 wide, ajar onto a second room with a ceiling lamp."""
    s = room(skip_right=True)
    g0, g1 = -0.6, -0.52
    s += xwall(2, 0, 2.5, -2, g0, refl=(0.2, 0.5, 0.25))
    s += xwall(2, 0, 2.5, g1, 2, refl=(0.2, 0.5, 0.25))
    # The lit room: x in [2, 4].
    s += ywall(0, 2, 4, -2, 2)
    s += ywall(2.5, 2, 4, -2, 2)
    s += zwall(-2, 2, 4, 0, 2.5)
    s += zwall(2, 2, 4, 0, 2.5)
    s += xwall(4, 0, 2.5, -2, 2)
    s += ywall(2.49, 2.6, 3.4, -1.4, -0.6, emit=(600, 550, 450))
    if medium:
        # The fog's end for pbrt-v4 (the rooms are closed, but a camera medium needs a bound).
        s = 'AttributeBegin\n  MediumInterface "fog" ""\n  Material "interface"\n  Shape "sphere" "float radius" [ 20 ]\nAttributeEnd\n' + s
    return s


def sunlit():
    """A window in the left wall (x = -2), sun and sky outside."""
    s = room(skip_left=True)
    w = dict(refl=(0.6, 0.2, 0.2))
    s += xwall(-2, 0, 1.0, -2, 2, **w)
    s += xwall(-2, 2.0, 2.5, -2, 2, **w)
    s += xwall(-2, 1.0, 2.0, -2, -1.0, **w)
    s += xwall(-2, 1.0, 2.0, -0.2, 2, **w)
    # The sun shines in from the upper left, onto the floor; a dim sky.
    s += 'LightSource "distant" "point3 from" [ -3 4 0.6 ] "point3 to" [ 0 0 0 ] "rgb L" [ 18 16 13 ]\n'
    s += 'LightSource "infinite" "rgb L" [ 0.15 0.2 0.3 ]\n'
    return s


def bright_patch():
    """A lamp inside a shade near the floor lights only a small patch below it."""
    s = room()
    # The shade: a box x in [0.4, 1.0], z in [-1.3, -0.7], y in [0.15, 0.6], open at the bottom.
    x0, x1, z0, z1, y0, y1 = 0.4, 1.0, -1.3, -0.7, 0.15, 0.6
    d = dict(refl=(0.3, 0.3, 0.3))
    s += ywall(y1, x0, x1, z0, z1, **d)
    s += xwall(x0, y0, y1, z0, z1, **d)
    s += xwall(x1, y0, y1, z0, z1, **d)
    s += zwall(z0, x0, x1, y0, y1, **d)
    s += zwall(z1, x0, x1, y0, y1, **d)
    s += ywall(y1 - 0.01, x0 + 0.15, x1 - 0.15, z0 + 0.15, z1 - 0.15, emit=(80, 75, 65))
    # The patch it lights: a bright white tile on the grey floor.
    s += ywall(0.002, x0 - 0.05, x1 + 0.05, z0 - 0.05, z1 + 0.05, refl=(0.9, 0.9, 0.9))
    return s


FOG = ('MakeNamedMedium "fog" "string type" "homogeneous" "rgb sigma_a" [ 0.02 0.02 0.02 ] '
       '"rgb sigma_s" [ 0.15 0.15 0.15 ] "float scale" [ 1.0 ] "float g" [ 0.2 ]')

os.makedirs(OUT, exist_ok=True)
scenes = {
    "gap-room": (header("gap-room", "a room lit only through a door ajar onto a lit room") + gap_room()),
    "sunlit-interior": (header("sunlit-interior", "sun and sky through a small window") + sunlit()),
    "bright-patch": (header("bright-patch", "a room lit by the bounce off a small patch under a shaded lamp") + bright_patch()),
    "fog-gap": (header("fog-gap", "the gap room filled with thin fog", FOG) + gap_room(medium=True)),
}
for name, text in scenes.items():
    with open(os.path.join(OUT, name + ".pbrt"), "w") as f:
        f.write(text)
    print("wrote", name)
