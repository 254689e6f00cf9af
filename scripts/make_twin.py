#!/usr/bin/env python3
"""Writes scenes/twin/: one scene twice, as glTF (twin.gltf) and as Trayecto TOML (twin.toml with
floor.ply and cube.ply), for the test that both formats give the same image. Re-run to regenerate."""
import base64, json, os, struct, sys

out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "twin")
os.makedirs(out, exist_ok=True)

floor_v = [(-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2)]
floor_i = [(0, 2, 1), (0, 3, 2)]  # faces +y
cube_v = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
idx = {v: i for i, v in enumerate(cube_v)}
cube_i = []
for axis in range(3):
    for s in (-0.5, 0.5):
        quad = [v for v in cube_v if v[axis] == s]
        # order the 4 corners around the face, counter-clockwise seen from outside
        u, w = [a for a in range(3) if a != axis]
        ring = sorted(quad, key=lambda v: {(-0.5, -0.5): 0, (0.5, -0.5): 1, (0.5, 0.5): 2, (-0.5, 0.5): 3}[(v[u], v[w])])
        a, b, c, d = (idx[v] for v in ring)
        tris = [(a, b, c), (a, c, d)]
        # outward normal check via cross product of the first triangle
        p = [cube_v[k] for k in tris[0]]
        e1 = [p[1][k] - p[0][k] for k in range(3)]
        e2 = [p[2][k] - p[0][k] for k in range(3)]
        n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
        if n[axis] * s < 0:
            tris = [(a, c, b), (a, d, c)]
        cube_i += tris

def ply(path, verts, tris):
    with open(path, "w") as f:
        f.write("ply\nformat ascii 1.0\ncomment made by scripts/make_twin.py\n")
        f.write(f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n")
        f.write(f"element face {len(tris)}\nproperty list uchar uint vertex_indices\nend_header\n")
        for v in verts:
            f.write(" ".join(repr(float(c)) for c in v) + "\n")
        for t in tris:
            f.write("3 " + " ".join(str(i) for i in t) + "\n")

ply(os.path.join(out, "floor.ply"), floor_v, floor_i)
ply(os.path.join(out, "cube.ply"), cube_v, cube_i)

buf = b""
views, accessors = [], []
def add(data, fmt, count, typ, ctype, minmax=None):
    global buf
    off = len(buf)
    buf += struct.pack("<" + fmt * (len(data)), *data)
    while len(buf) % 4:
        buf += b"\0"
    views.append({"buffer": 0, "byteOffset": off, "byteLength": len(data) * 4})
    a = {"bufferView": len(views) - 1, "componentType": ctype, "count": count, "type": typ}
    if minmax:
        a["min"], a["max"] = minmax
    accessors.append(a)
    return len(accessors) - 1

def mesh(verts, tris):
    flat = [c for v in verts for c in v]
    mn = [min(v[k] for v in verts) for k in range(3)]
    mx = [max(v[k] for v in verts) for k in range(3)]
    p = add(flat, "f", len(verts), "VEC3", 5126, (mn, mx))
    i = add([k for t in tris for k in t], "I", len(tris) * 3, "SCALAR", 5125)
    return p, i

fp, fi = mesh(floor_v, floor_i)
cp, ci = mesh(cube_v, cube_i)
doc = {
    "asset": {"version": "2.0", "generator": "scripts/make_twin.py"},
    "extensionsUsed": ["KHR_lights_punctual"],
    "extensions": {"KHR_lights_punctual": {"lights": [
        {"name": "key", "type": "point", "color": [1, 1, 1], "intensity": 6830.0}]}},
    "buffers": [{"byteLength": len(buf), "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}],
    "bufferViews": views,
    "accessors": accessors,
    "materials": [
        {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 0, "roughnessFactor": 1}},
        {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.1, 1], "metallicFactor": 0, "roughnessFactor": 1}},
    ],
    "meshes": [
        {"name": "floor", "primitives": [{"attributes": {"POSITION": fp}, "indices": fi, "material": 0}]},
        {"name": "cube", "primitives": [{"attributes": {"POSITION": cp}, "indices": ci, "material": 1}]},
    ],
    "cameras": [{"name": "main", "type": "perspective", "perspective": {"yfov": 0.6981317007977318, "znear": 0.01}}],
    "nodes": [
        {"name": "floor", "mesh": 0},
        {"name": "cube", "mesh": 1, "translation": [0, 0.5, 0]},
        {"name": "main", "camera": 0, "translation": [0, 0.5, 4]},
        {"name": "key", "extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [1, 3, 2]},
    ],
    "scenes": [{"nodes": [0, 1, 2, 3]}],
    "scene": 0,
}
with open(os.path.join(out, "twin.gltf"), "w") as f:
    json.dump(doc, f, indent=1)
