#!/usr/bin/env python3
"""Writes a glTF scene of one shared mesh placed by 16 moving nodes, the case of motion blur of
moving instances (BENCHMARKS.md "Continuous motion blur", scripts/motion-bench.sh).

A torus of 70 752 triangles used by 16 nodes in a 4 x 4 grid, each turning 120 degrees about a
tilted axis and sliding over [0, 1] s (LINEAR channels): 1.13 M triangles of copies, so
Trayecto's automatic instancing keeps one shared copy (world::AUTO_INSTANCE_TRIANGLES), and a
blurred render (--shutter 0,1) has 16 moving instances. A camera looks down at the grid; the
scene has no light (the studio environment lights it).

Usage: bench/moving_instances.py OUT.gltf   (standard library only)
"""

import base64
import json
import math
import struct
import sys


def torus(major, minor, nu, nv):
    pos, nrm, idx = [], [], []
    for i in range(nu):
        a = 2 * math.pi * i / nu
        for j in range(nv):
            b = 2 * math.pi * j / nv
            c = (math.cos(a), 0.0, math.sin(a))
            n = (math.cos(b) * c[0], math.sin(b), math.cos(b) * c[2])
            pos.append(tuple(major * c[k] + minor * n[k] for k in range(3)))
            nrm.append(n)
    for i in range(nu):
        for j in range(nv):
            a, b = i * nv + j, ((i + 1) % nu) * nv + j
            c, d = i * nv + (j + 1) % nv, ((i + 1) % nu) * nv + (j + 1) % nv
            idx += [a, c, b, b, c, d]
    return pos, nrm, idx


def quat(axis, angle):
    n = math.sqrt(sum(x * x for x in axis))
    s = math.sin(angle / 2) / n
    return [axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2)]


def main():
    pos, nrm, idx = torus(0.4, 0.15, 264, 134)
    blob = bytearray()
    views, accessors = [], []

    def add(data, fmt, count, ctype, kind, target=None, minmax=None):
        off = len(blob)
        blob.extend(struct.pack("<" + fmt * (len(data) // len(fmt)), *data))
        while len(blob) % 4:
            blob.append(0)
        view = {"buffer": 0, "byteOffset": off, "byteLength": len(blob) - off}
        if target:
            view["target"] = target
        views.append(view)
        acc = {"bufferView": len(views) - 1, "componentType": ctype, "count": count, "type": kind}
        if minmax:
            acc["min"], acc["max"] = minmax
        accessors.append(acc)
        return len(accessors) - 1

    flat = [c for p in pos for c in p]
    lo = [min(p[k] for p in pos) for k in range(3)]
    hi = [max(p[k] for p in pos) for k in range(3)]
    p_acc = add(flat, "f", len(pos), 5126, "VEC3", 34962, (lo, hi))
    n_acc = add([c for n in nrm for c in n], "f", len(nrm), 5126, "VEC3", 34962)
    i_acc = add(idx, "I", len(idx), 5125, "SCALAR", 34963)
    t_acc = add([0.0, 1.0], "f", 2, 5126, "SCALAR", None, ([0.0], [1.0]))
    nodes, channels, samplers = [], [], []
    for k in range(16):
        x, z = (k % 4 - 1.5) * 1.2, (k // 4 - 1.5) * 1.2
        axis = (math.sin(k), 1.0, math.cos(k))
        r0, r1 = quat(axis, 0.0), quat(axis, math.radians(120))
        rot = add(r0 + r1, "f", 2, 5126, "VEC4")
        tra = add([x, 0.0, z, x + 0.3, 0.1, z], "f", 2, 5126, "VEC3")
        nodes.append({"mesh": 0, "translation": [x, 0.0, z]})
        for path, out in (("rotation", rot), ("translation", tra)):
            samplers.append({"input": t_acc, "output": out, "interpolation": "LINEAR"})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": k, "path": path}})
    tilt = quat((1, 0, 0), -math.atan2(3.5, 5.5))
    nodes.append({"camera": 0, "translation": [0.0, 3.5, 5.5], "rotation": tilt})
    doc = {
        "asset": {"version": "2.0", "generator": "trayecto bench/moving_instances.py"},
        "scene": 0,
        "scenes": [{"nodes": list(range(17))}],
        "nodes": nodes,
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": p_acc, "NORMAL": n_acc},
                                    "indices": i_acc, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.3, 0.2, 1.0],
                                                "metallicFactor": 0.0, "roughnessFactor": 0.6}}],
        "animations": [{"channels": channels, "samplers": samplers}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/octet-stream;base64,"
                            + base64.b64encode(bytes(blob)).decode()}],
    }
    with open(sys.argv[1], "w") as f:
        json.dump(doc, f)


if __name__ == "__main__":
    main()
