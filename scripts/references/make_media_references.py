#!/usr/bin/env python3
"""Mitsuba 3 references for the participating-media scenes (tests/media_render.rs).

Usage (from the repository root):

    pip install mitsuba numpy            # mitsuba 3.9.1, drjit 1.5.0 were used
    python3 scripts/references/make_media_references.py               # all three scenes
    python3 scripts/references/make_media_references.py --only fog_cornell --spp 1024

It reads each Trayecto scene file scenes/media/NAME.toml and translates it into a Mitsuba scene
dictionary (reusing make_material_references.py's material translation), so the two descriptions
cannot drift apart. It also writes the cloud's density grid scenes/media/cloud.vol (32^3, a sum
of Gaussian blobs that is exactly zero on the border voxels, so the two renderers' different
conventions outside the outermost voxel centres cannot matter), with Python's struct in the
documented .vol layout, which Mitsuba then reads: a Trayecto reader that disagreed with Mitsuba's
would show in the comparison.

Translation of the media (Trayecto -> Mitsuba):
  [[medium]] homogeneous sigma_a, sigma_s, scale, g -> homogeneous, sigma_t = (sigma_a+sigma_s)*scale
                                                       (rgb), albedo = sigma_s/(sigma_a+sigma_s),
                                                       phase hg g
  [[medium]] grid, file, sigma_a+sigma_s grey       -> heterogeneous, sigma_t = gridvolume(file,
                                                       to_world = the file's box), scale =
                                                       sigma_a+sigma_s, albedo rgb as above
  fog = NAME                                        -> the sensor's medium
  medium_inside / medium_outside                    -> the shape's interior / exterior medium
  model = "interface"                               -> null bsdf
Integrator volpath, max_depth -1, rr_depth 5 (Mitsuba's default).

Output: tests/references/mitsuba_media_NAME.exr, linear RGB float32, 64x64.
"""
import argparse
import math
import os
import struct
import sys
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, HERE)
from make_references import pick_variant, render_chunked  # noqa: E402
from make_material_references import bsdf, look_at, mat4, rgb  # noqa: E402

SCENE_DIR = os.path.join(ROOT, "scenes", "media")
DEFAULT_OUT = os.path.join(ROOT, "tests", "references")
SCENES = {"fog_cornell": (64, 64), "absorbing_glass": (64, 64), "cloud": (64, 64)}
# Committed sample counts (docs/src/correctness.md, "Participating media against Mitsuba 3", has the timings).
DEFAULT_SPP = {"fog_cornell": 2048, "absorbing_glass": 4096, "cloud": 2048}


def write_cloud_vol(path, box_min, box_max, n=32):
    """A smooth cloud: three Gaussian blobs, zero on the border voxels, peak density ~1."""
    blobs = [((0.40, 0.45, 0.50), 0.20, 1.0), ((0.62, 0.55, 0.45), 0.16, 0.8),
             ((0.50, 0.38, 0.60), 0.12, 0.6)]
    data = []
    for z in range(n):
        for y in range(n):
            for x in range(n):
                if x in (0, n - 1) or y in (0, n - 1) or z in (0, n - 1):
                    data.append(0.0)
                    continue
                p = ((x + 0.5) / n, (y + 0.5) / n, (z + 0.5) / n)
                v = 0.0
                for c, r, a in blobs:
                    d2 = sum((p[i] - c[i]) ** 2 for i in range(3))
                    v += a * math.exp(-d2 / (2 * r * r))
                # Wispy edge: a gentle ripple so the majorant is not tight everywhere.
                v *= 0.85 + 0.15 * math.sin(23 * p[0]) * math.sin(17 * p[1] + 1) * math.sin(19 * p[2] + 2)
                data.append(max(0.0, min(1.0, v)))
    with open(path, "wb") as f:
        f.write(b"VOL")
        f.write(struct.pack("<B", 3))
        f.write(struct.pack("<iiiii", 1, n, n, n, 1))
        f.write(struct.pack("<6f", *box_min, *box_max))
        f.write(struct.pack(f"<{len(data)}f", *data))


def medium_dict(mi, np, m):
    sa = np.array(m.get("sigma_a", [0, 0, 0]), dtype=np.float64)
    ss = np.array(m.get("sigma_s", [0, 0, 0]), dtype=np.float64)
    scale = float(m.get("scale", 1.0))
    st = sa + ss
    albedo = np.where(st > 0, ss / np.where(st > 0, st, 1), 0)
    phase = {"type": "hg", "g": float(m.get("g", 0.0))}
    kind = m.get("type", "homogeneous")
    if kind == "homogeneous":
        # Mitsuba reads an RGB sigma_t as a reflectance (components in [0, 1]): pass it
        # normalised by its largest component and put that component into the scalar scale.
        smax = float(st.max()) if st.max() > 0 else 1.0
        return {"type": "homogeneous", "sigma_t": rgb(st / smax), "albedo": rgb(albedo),
                "scale": smax * scale, "phase": phase}
    if kind == "grid":
        if not np.allclose(st, st[0]):
            raise ValueError("grid media: sigma_a + sigma_s must be grey (Mitsuba's scale is scalar)")
        path = os.path.join(SCENE_DIR, m["file"])
        with open(path, "rb") as f:
            head = f.read(48)
        bmin = struct.unpack("<3f", head[24:36])
        bmax = struct.unpack("<3f", head[36:48])
        to_world = mi.ScalarTransform4f().translate(list(bmin)).scale(
            [bmax[i] - bmin[i] for i in range(3)])
        return {"type": "heterogeneous", "albedo": rgb(albedo), "scale": float(st[0] * scale),
                "sigma_t": {"type": "gridvolume", "filename": path, "filter_type": "trilinear",
                            "to_world": to_world},
                "phase": phase}
    raise ValueError(f"medium type {kind} not translated")


def scene_dict(mi, np, name, width, height):
    with open(os.path.join(SCENE_DIR, f"{name}.toml"), "rb") as f:
        t = tomllib.load(f)
    cam = t["camera"][0]
    media = {m["name"]: m for m in t.get("medium", [])}
    d = {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": -1},
        "sensor": {
            "type": "perspective", "fov": float(cam.get("fov", 39.6)), "fov_axis": "y",
            "near_clip": 1e-3,
            "to_world": look_at(mi, cam["eye"], cam["target"], cam.get("up", [0, 1, 0])),
            "sampler": {"type": "independent", "sample_count": 1},
            "film": {"type": "hdrfilm", "width": width, "height": height,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
    }
    for mname, m in media.items():
        d[f"medium_{mname}"] = dict(medium_dict(mi, np, m), id=f"medium_{mname}")

    def ref(n):
        return {"type": "ref", "id": f"medium_{n}"}

    fog = t.get("fog")
    if fog is not None:
        d["sensor"]["medium"] = ref(fog)
    bg = t.get("background")
    if bg is not None:
        d["background"] = {"type": "constant",
                           "radiance": rgb([c * bg.get("strength", 1.0) for c in bg["color"]])}
    mats = {m["name"]: m for m in t.get("material", [])}
    for i, o in enumerate(t.get("object", [])):
        m = dict(mats[o["material"]])
        emissive = m.pop("emissive", None)
        if m.get("model") == "interface":
            shape = {"bsdf": {"type": "null"}}
        else:
            shape = {"bsdf": bsdf(mi, np, m, SCENE_DIR)}
        if emissive is not None:
            shape["emitter"] = {"type": "area", "radiance": rgb(emissive)}
        if "medium_inside" in o or "medium_outside" in o:
            for key, mk in (("medium_inside", "interior"), ("medium_outside", "exterior")):
                n = o.get(key, fog)
                if n is not None and n != "none":
                    shape[mk] = ref(n)
        elif fog is not None and m.get("model") in ("dielectric", "interface"):
            raise ValueError("a refractive object in fog needs explicit media")
        if o["type"] == "sphere":
            shape.update(type="sphere", center=[float(c) for c in o["center"]],
                         radius=float(o["radius"]))
        elif o["type"] == "quad":
            c, e1, e2 = (np.array(o[k], dtype=np.float64) for k in ("corner", "e1", "e2"))
            n = np.cross(e1, e2)
            n /= np.linalg.norm(n)
            m4 = np.eye(4)
            m4[:3, 0], m4[:3, 1], m4[:3, 2], m4[:3, 3] = e1 / 2, e2 / 2, n, c + e1 / 2 + e2 / 2
            shape.update(type="rectangle", to_world=mat4(mi, np, m4))
        elif o["type"] == "box":
            if any(k in o for k in ("translate", "rotate", "scale", "matrix")):
                raise ValueError("transformed boxes are not translated here")
            lo, hi = np.array(o["min"], dtype=np.float64), np.array(o["max"], dtype=np.float64)
            box = np.eye(4)
            box[:3, :3] = np.diag((hi - lo) / 2)
            box[:3, 3] = (hi + lo) / 2
            shape.update(type="cube", to_world=mat4(mi, np, box))
        else:
            raise ValueError(f"object type {o['type']} not translated")
        d[f"shape_{i}"] = shape
    if t.get("light"):
        raise ValueError("[[light]] is not translated for the media scenes")
    return d


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spp", type=int, help="samples per pixel (default: the committed counts)")
    ap.add_argument("--chunk", type=int, default=512)
    ap.add_argument("--only", choices=list(SCENES), action="append")
    ap.add_argument("--variant", default="auto")
    ap.add_argument("--out-dir", default=DEFAULT_OUT)
    args = ap.parse_args()
    variant = pick_variant(args.variant)
    import mitsuba as mi
    import numpy as np
    mi.set_variant(variant)
    write_cloud_vol(os.path.join(SCENE_DIR, "cloud.vol"), (-0.8, -0.5, -0.6), (0.8, 0.5, 0.6))
    print(f"mitsuba {mi.__version__}, variant {variant}")
    total = 0.0
    for name in args.only or SCENES:
        w, h = SCENES[name]
        spp = args.spp or DEFAULT_SPP[name]
        scene = mi.load_dict(scene_dict(mi, np, name, w, h))
        img, chunks, el = render_chunked(mi, np, scene, spp, args.chunk, w, h)
        path = os.path.join(args.out_dir, f"mitsuba_media_{name}.exr")
        mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB).write(path)
        total += el
        print(f"{name}: {w}x{h}, {spp} spp, {el:.1f} s -> {path}; mean RGB "
              f"{img.reshape(-1, 3).mean(0).tolist()}, non-finite {int((~np.isfinite(img)).sum())}",
              flush=True)
    print(f"total {total:.1f} s")


if __name__ == "__main__":
    sys.exit(main())
