#!/usr/bin/env python3
"""Writes the participating-media test scenes (scenes/media/NAME.toml) as pbrt-v4 files,
scenes/pbrt/media/NAME.pbrt, translated from the TOML files so the two cannot drift apart; then
`scripts/pbrt_references.sh SPP media/NAME` renders pbrt-v4's references (tests/media_render.rs
compares Trayecto's render of the pbrt file with them).

Translation (TOML -> pbrt-v4):
  camera eye/target/fov          -> Scale -1 1 1 (pbrt's camera space is left-handed), LookAt, fov;
                                    not for the fog scene (pbrt-v4 crashes with a camera medium and
                                    a mirroring camera transform), which is seen mirrored
  [background] color             -> LightSource "infinite" "rgb L"
  fog = NAME                     -> MediumInterface "NAME" "NAME" before Camera (the camera medium),
                                    bounded by an index-matched sphere of radius 50 (see below)
  [[medium]] homogeneous         -> MakeNamedMedium "homogeneous" rgb sigma_a / sigma_s, scale, g,
                                    emission -> rgb Le
  [[medium]] grid (Mitsuba .vol) -> MakeNamedMedium "uniformgrid" with the .vol's densities, p0/p1
                                    its bounding box (both renderers place samples at voxel centres)
  materials                      -> diffuse (base_color), dielectric (ior), interface; emissive ->
                                    AreaLightSource "diffuse" on a black diffuse material
  quad corner/e1/e2              -> a two-triangle trianglemesh, normal e1 x e2 (the emitting side)
  sphere, box                    -> Translate + sphere; a 12-triangle mesh with outward normals
  medium_inside / outside        -> MediumInterface "inside" "outside"
Integrator "volpath", maxdepth 100 (Trayecto's and Mitsuba's comparisons use unbounded depth with
Russian roulette). Output resolution 64 x 64, as the Mitsuba references.
"""
import os
import struct
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
SRC = os.path.join(ROOT, "scenes", "media")
DST = os.path.join(ROOT, "scenes", "pbrt", "media")
NAMES = ["fog_cornell", "absorbing_glass", "cloud", "emissive"]


def f(v):
    return " ".join(f"{x:.6g}" for x in v)


def add(a, b):
    return [x + y for x, y in zip(a, b)]


def read_vol(path):
    with open(path, "rb") as fh:
        b = fh.read()
    assert b[:3] == b"VOL" and b[3] == 3
    enc, nx, ny, nz, ch = struct.unpack("<iiiii", b[4:24])
    assert enc == 1 and ch == 1
    box = struct.unpack("<6f", b[24:48])
    data = struct.unpack(f"<{nx * ny * nz}f", b[48:48 + 4 * nx * ny * nz])
    return (nx, ny, nz), box[:3], box[3:], data


def medium(m, lines):
    sa = m.get("sigma_a", [0, 0, 0])
    ss = m.get("sigma_s", [0, 0, 0])
    common = (f'"rgb sigma_a" [ {f(sa)} ] "rgb sigma_s" [ {f(ss)} ] '
              f'"float scale" [ {m.get("scale", 1.0)} ] "float g" [ {m.get("g", 0.0)} ]')
    if any(m.get("emission", [0, 0, 0])):
        common += f' "rgb Le" [ {f(m["emission"])} ]'
    if m.get("type", "homogeneous") == "grid":
        (nx, ny, nz), p0, p1, data = read_vol(os.path.join(SRC, m["file"]))
        dens = " ".join(f"{v:.5g}" for v in data)
        lines.append(f'MakeNamedMedium "{m["name"]}" "string type" "uniformgrid" {common}\n'
                     f'    "integer nx" [ {nx} ] "integer ny" [ {ny} ] "integer nz" [ {nz} ]\n'
                     f'    "point3 p0" [ {f(p0)} ] "point3 p1" [ {f(p1)} ]\n'
                     f'    "float density" [ {dens} ]')
    else:
        lines.append(f'MakeNamedMedium "{m["name"]}" "string type" "homogeneous" {common}')


def mesh(points, tris):
    idx = " ".join(str(i) for t in tris for i in t)
    pts = "  ".join(f(p) for p in points)
    return f'Shape "trianglemesh" "point3 P" [ {pts} ] "integer indices" [ {idx} ]'


def shape(o):
    t = o["type"]
    if t == "quad":
        c, e1, e2 = o["corner"], o["e1"], o["e2"]
        return mesh([c, add(c, e1), add(add(c, e1), e2), add(c, e2)], [(0, 1, 2), (0, 2, 3)])
    if t == "sphere":
        return (f'Translate {f(o["center"])}\n  Shape "sphere" "float radius" [ {o["radius"]} ]')
    if t == "box":
        lo, hi = o["min"], o["max"]
        p = [[(hi if (i >> k) & 1 else lo)[k] for k in range(3)] for i in range(8)]
        # Faces as quads (a, b, c, d) counter-clockwise seen from outside.
        faces = [(0, 4, 6, 2), (1, 3, 7, 5), (0, 1, 5, 4), (2, 6, 7, 3), (0, 2, 3, 1), (4, 5, 7, 6)]
        tris = [tri for a, b, c, d in faces for tri in ((a, b, c), (a, c, d))]
        return mesh(p, tris)
    raise SystemExit(f"shape type {t} not translated")


def material(m):
    model = m.get("model", "diffuse")
    if model == "interface":
        return 'Material "interface"'
    if model == "dielectric":
        return f'Material "dielectric" "float eta" [ {m.get("ior", 1.5)} ]'
    return f'Material "diffuse" "rgb reflectance" [ {f(m.get("base_color", [0.8] * 3))} ]'


def translate(name):
    with open(os.path.join(SRC, name + ".toml"), "rb") as fh:
        s = tomllib.load(fh)
    cam = s["camera"][0]
    lines = [f"# {name}: pbrt-v4 translation of scenes/media/{name}.toml by",
             "# scripts/references/make_pbrt_media_scenes.py (do not edit by hand).",
             # pbrt-v4 crashes (segmentation fault) when the camera has a medium and its
             # transform swaps handedness, so the fog scene is seen mirrored.
             "" if "fog" in s else "Scale -1 1 1",
             f'LookAt {f(cam["eye"])}  {f(cam["target"])}  0 1 0']
    # A medium's transform is the CTM where it is made: before WorldBegin that is the camera's,
    # so only the (homogeneous, placement-free) camera medium is made there.
    for m in s.get("medium", []):
        if m["name"] == s.get("fog"):
            medium(m, lines)
    if "fog" in s:
        lines.append(f'MediumInterface "{s["fog"]}" "{s["fog"]}"')
    lines += [f'Camera "perspective" "float fov" [ {cam["fov"]} ]',
              'Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 64 ]',
              # pbrt-v4 crashed on the fog scene with "independent" at 1024 spp (not with zsobol).
              f'Sampler "{"zsobol" if "fog" in s else "independent"}" "integer pixelsamples" [ 64 ]',
              'Integrator "volpath" "integer maxdepth" [ 100 ]',
              "WorldBegin"]
    for m in s.get("medium", []):
        if m["name"] != s.get("fog"):
            medium(m, lines)
    if "background" in s:
        lines.append(f'LightSource "infinite" "rgb L" [ {f(s["background"]["color"])} ]')
    if "fog" in s:
        # pbrt-v4 crashes (segmentation fault) on rays that leave the scene inside a medium, so
        # the fog ends at an index-matched sphere of radius 50: past it, light from the lamp is
        # attenuated by e^(-0.25 * 50) and spread over 50^2, a difference far below the noise.
        lines += ["# the fog's end (pbrt-v4 cannot trace rays to infinity inside a medium)",
                  "AttributeBegin", f'  MediumInterface "{s["fog"]}" ""', '  Material "interface"',
                  '  Shape "sphere" "float radius" [ 50 ]', "AttributeEnd"]
    mats = {m["name"]: m for m in s.get("material", [])}
    for o in s.get("object", []):
        m = mats[o["material"]]
        lines.append(f'# {o["name"]}')
        lines.append("AttributeBegin")
        if "medium_inside" in o or "medium_outside" in o:
            lines.append(f'  MediumInterface "{o.get("medium_inside", "")}" '
                         f'"{o.get("medium_outside", "")}"')
        if "emissive" in m:
            lines.append(f'  AreaLightSource "diffuse" "rgb L" [ {f(m["emissive"])} ]')
        lines.append("  " + material(m))
        lines.append("  " + shape(o))
        lines.append("AttributeEnd")
    os.makedirs(DST, exist_ok=True)
    out = os.path.join(DST, name + ".pbrt")
    with open(out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("wrote", os.path.relpath(out, ROOT))


for n in NAMES:
    translate(n)
