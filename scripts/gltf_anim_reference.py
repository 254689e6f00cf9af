#!/usr/bin/env python3
"""Independent reference for glTF 2.0 animation: world-space vertex positions of animated models
at given times, computed straight from the specification (section 3.11 "Animations", Appendix C
"Interpolation", 3.7.2.2 morph targets, 3.7.3 skins), in plain Python (no numpy, nothing shared
with the Rust code). tests/animation.rs poses the same files with Trayecto and compares.

    python3 scripts/gltf_anim_reference.py > tests/data/gltf_anim_poses.json

Every channel of every animation plays at once; times outside the keyframes are clamped. For each
model and time the output lists, per mesh primitive instance in depth-first node order (the
order in which Trayecto's loader creates objects), up to 40 vertices (every k-th) in world space.
"""
import base64
import json
import math
import os
import struct
import sys

SHARED = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "scenes", "gltf-anim")
MODELS = {
    "BoxAnimated": "BoxAnimated/glTF/BoxAnimated.gltf",
    "InterpolationTest": "InterpolationTest/glTF/InterpolationTest.gltf",
    "AnimatedMorphCube": "AnimatedMorphCube/glTF/AnimatedMorphCube.gltf",
    "SimpleSkin": "SimpleSkin/glTF/SimpleSkin.gltf",
    "CesiumMan": "CesiumMan/glTF/CesiumMan.gltf",
}
TIMES = [0.0, 0.37, 1.0, 1.71, 2.5, 100.0]
MAX_VERTS = 40

COMP = {5120: ("b", 1, 127.0), 5121: ("B", 1, 255.0), 5122: ("h", 2, 32767.0),
        5123: ("H", 2, 65535.0), 5125: ("I", 4, None), 5126: ("f", 4, None)}
NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def load(path):
    doc = json.load(open(path))
    base = os.path.dirname(path)
    bufs = []
    for b in doc["buffers"]:
        uri = b["uri"]
        if uri.startswith("data:"):
            bufs.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            bufs.append(open(os.path.join(base, uri), "rb").read())
    return doc, bufs


def accessor(doc, bufs, i):
    a = doc["accessors"][i]
    fmt, size, norm = COMP[a["componentType"]]
    n = NCOMP[a["type"]]
    v = doc["bufferViews"][a["bufferView"]]
    data = bufs[v["buffer"]]
    stride = v.get("byteStride", size * n)
    start = v.get("byteOffset", 0) + a.get("byteOffset", 0)
    out = []
    for e in range(a["count"]):
        o = start + e * stride
        vals = list(struct.unpack_from("<%d%s" % (n, fmt), data, o))
        if a.get("normalized") and norm:
            vals = [max(x / norm, -1.0) for x in vals]
        out.append(vals)
    return out


def mat_mul(a, b):  # 4x4 row-major lists
    return [[sum(a[r][k] * b[k][c] for k in range(4)) for c in range(4)] for r in range(4)]


def mat_add(a, b, w):
    return [[a[r][c] + w * b[r][c] for c in range(4)] for r in range(4)]


def identity():
    return [[1.0 if r == c else 0.0 for c in range(4)] for r in range(4)]


def col_major(m):  # glTF column-major 16 floats -> row-major 4x4
    return [[m[c * 4 + r] for c in range(4)] for r in range(4)]


def trs(t, r, s):
    x, y, z, w = r
    rot = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
           [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
           [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    m = identity()
    for i in range(3):
        for j in range(3):
            m[i][j] = rot[i][j] * s[j]
        m[i][3] = t[i]
    return m


def apply(m, p):
    return [sum(m[r][c] * p[c] for c in range(3)) + m[r][3] for r in range(3)]


def slerp(a, b, s):
    d = sum(x * y for x, y in zip(a, b))
    if d < 0:
        b = [-x for x in b]
        d = -d
    if d > 0.9995:
        q = [x * (1 - s) + y * s for x, y in zip(a, b)]
    else:
        th = math.acos(min(d, 1.0))
        sa, sb = math.sin((1 - s) * th) / math.sin(th), math.sin(s * th) / math.sin(th)
        q = [sa * x + sb * y for x, y in zip(a, b)]
    n = math.sqrt(sum(x * x for x in q))
    return [x / n for x in q]


def sample(times, values, interp, t, rotation):
    """values: per keyframe one list (three lists per keyframe for CUBICSPLINE)."""
    cubic = interp == "CUBICSPLINE"
    val = (lambda k: values[3 * k + 1]) if cubic else (lambda k: values[k])
    if t <= times[0]:
        return list(val(0))
    if t >= times[-1]:
        return list(val(len(times) - 1))
    k = max(i for i in range(len(times)) if times[i] <= t)
    td = times[k + 1] - times[k]
    s = (t - times[k]) / td
    if interp == "STEP":
        return list(val(k))
    if interp == "LINEAR":
        if rotation:
            return slerp(val(k), val(k + 1), s)
        return [x * (1 - s) + y * s for x, y in zip(val(k), val(k + 1))]
    v0, b0 = values[3 * k + 1], values[3 * k + 2]
    a1, v1 = values[3 * (k + 1)], values[3 * (k + 1) + 1]
    s2, s3 = s * s, s * s * s
    out = [(2 * s3 - 3 * s2 + 1) * p0 + td * (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1
           + td * (s3 - s2) * m1 for p0, m0, p1, m1 in zip(v0, b0, v1, a1)]
    if rotation:
        n = math.sqrt(sum(x * x for x in out))
        out = [x / n for x in out]
    return out


def pose(doc, bufs, t):
    nodes = doc["nodes"]
    local = []
    weights = []
    for n in nodes:
        local.append([n.get("translation", [0, 0, 0]), n.get("rotation", [0, 0, 0, 1]),
                      n.get("scale", [1, 1, 1])])
        mesh_w = doc["meshes"][n["mesh"]].get("weights") if "mesh" in n else None
        weights.append(list(n.get("weights", mesh_w or [])))
    for anim in doc.get("animations", []):
        for ch in anim["channels"]:
            smp = anim["samplers"][ch["sampler"]]
            interp = smp.get("interpolation", "LINEAR")
            times = [x[0] for x in accessor(doc, bufs, smp["input"])]
            out = accessor(doc, bufs, smp["output"])
            node, path = ch["target"]["node"], ch["target"]["path"]
            if path == "weights":
                flat = [x[0] for x in out]
                per = len(flat) // (len(times) * (3 if interp == "CUBICSPLINE" else 1))
                out = [flat[i:i + per] for i in range(0, len(flat), per)]
            v = sample(times, out, interp, t, path == "rotation")
            if path == "weights":
                weights[node] = v
            else:
                local[node][{"translation": 0, "rotation": 1, "scale": 2}[path]] = v
    world = [None] * len(nodes)

    def visit(i, parent):
        n = nodes[i]
        m = col_major(n["matrix"]) if "matrix" in n else trs(*local[i])
        world[i] = mat_mul(parent, m)
        order.append(i)
        for c in n.get("children", []):
            visit(c, world[i])

    order = []
    scene = doc["scenes"][doc.get("scene", 0)]
    for r in scene["nodes"]:
        visit(r, identity())
    objects = []
    for i in order:
        n = nodes[i]
        if "mesh" not in n:
            continue
        for prim in doc["meshes"][n["mesh"]]["primitives"]:
            pos = accessor(doc, bufs, prim["attributes"]["POSITION"])
            for k, tgt in enumerate(prim.get("targets", [])):
                w = weights[i][k] if k < len(weights[i]) else 0.0
                if w and "POSITION" in tgt:
                    d = accessor(doc, bufs, tgt["POSITION"])
                    pos = [[p[c] + w * d[j][c] for c in range(3)] for j, p in enumerate(pos)]
            step = max(1, (len(pos) + MAX_VERTS - 1) // MAX_VERTS)
            picked = list(range(0, len(pos), step))
            if "skin" in n:
                skin = doc["skins"][n["skin"]]
                ibm = [col_major(m) for m in accessor(doc, bufs, skin["inverseBindMatrices"])]
                jm = [mat_mul(world[j], ibm[k]) for k, j in enumerate(skin["joints"])]
                sets = []
                k = 0
                while "JOINTS_%d" % k in prim["attributes"]:
                    sets.append((accessor(doc, bufs, prim["attributes"]["JOINTS_%d" % k]),
                                 accessor(doc, bufs, prim["attributes"]["WEIGHTS_%d" % k])))
                    k += 1
                out = []
                for v in picked:
                    m = [[0.0] * 4 for _ in range(4)]
                    for js, ws in sets:
                        for c in range(4):
                            if ws[v][c]:
                                m = mat_add(m, jm[int(js[v][c])], ws[v][c])
                    out.append(apply(m, pos[v]))
            else:
                out = [apply(world[i], pos[v]) for v in picked]
            objects.append({"node": i, "stride": step, "vertices": out})
    return objects


def main():
    result = {"times": TIMES, "max_vertices": MAX_VERTS, "models": {}}
    for name, rel in MODELS.items():
        doc, bufs = load(os.path.join(SHARED, rel))
        result["models"][name] = {
            "path": "gltf-anim/" + rel,
            "poses": [pose(doc, bufs, t) for t in TIMES],
        }
    json.dump(result, sys.stdout, separators=(",", ":"))
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
