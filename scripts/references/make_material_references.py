#!/usr/bin/env python3
"""Mitsuba 3 references for the material and light comparison scenes (tests/mitsuba_materials.rs).

Usage (from the repository root):

    pip install mitsuba numpy            # mitsuba 3.9.1, drjit 1.5.0 were used
    python3 scripts/references/make_material_references.py \
        --envmap ../shared/scenes/hdr/studio_small_03_1k.hdr
    python3 scripts/references/make_material_references.py --only metals --spp 4096

It reads each Trayecto scene file scenes/mitsuba/NAME.toml and translates it into a Mitsuba scene
dictionary, so the two descriptions cannot drift apart: only what these scenes use is translated
(cameras, a uniform background, diffuse / metallic-roughness with metallic = 1 / dielectric
materials, base-colour textures with a UV transform, spheres, quads, boxes with a transform, area,
point, spot and directional lights), anything else is an error. The script also writes the test
texture scenes/mitsuba/checker.png (16x16 sRGB, deterministic).

Output: tests/references/mitsuba_NAME.exr, linear RGB float32, row 0 at the top. Settings as in
make_references.py: rfilter box, sampler independent, integrator path with max_depth -1, the
sample budget rendered in chunks of --chunk spp with seeds 0, 1, ... and averaged in float64.

Translation (Trayecto -> Mitsuba):
  camera eye/target/up, vertical fov    -> perspective, fov_axis 'y', to_world look_at
  [background] color                    -> constant emitter, radiance
  environment map (the test adds it, rotated 90 deg about +y) -> envmap, to_world rotate(+y, 90)
  diffuse base_color                    -> diffuse reflectance (one-sided; Trayecto's two-sided
                                           shading only matters on back faces, which these scenes
                                           never show)
  metallic-roughness, metallic = 1      -> principled, metallic 1, base_color, roughness
                                           (alpha = roughness^2 and Schlick Fresnel on both sides;
                                           Mitsuba's Smith masking is the uncorrelated G1*G1,
                                           Trayecto's the height-correlated form)
  conductor eta, k (RGB), conductor_alpha a -> conductor (a = 0) / roughconductor (ggx, alpha a,
                                           isotropic only), eta and k per channel
  dielectric ior, roughness r           -> dielectric / roughdielectric (ggx, alpha = r^2),
                                           int_ior = ior, ext_ior = 1 (exact Fresnel on both)
  base_color_texture + uv_*             -> bitmap (sRGB decoded, bilinear, repeat), to_uv = the
                                           KHR_texture_transform matrix
  quad corner/e1/e2                     -> rectangle whose uv (u, v) lands on corner + u e1 + v e2
  box min/max + transform               -> cube with to_world = T R S . box
  emissive (one-sided)                  -> area emitter (one-sided)
  point intensity (W/sr)                -> point intensity (W/sr)
  spot intensity, inner/outer angles    -> spot intensity, beam_width = inner, cutoff_angle = outer
                                           (Mitsuba's falloff is linear in the angle, glTF's is
                                           the squared ramp in cos: equal only for a hard edge)
  directional irradiance (W/m^2)        -> directional irradiance (W/m^2)

Timings of the committed references (2-core x86-64 VM, llvm_ad_rgb, 32768 spp = 32 chunks of
1024, while a cargo build shared the cores): metals 41 s, glass 124 s, textured 9 s, point 83 s,
spot 134 s, spot_soft 145 s, directional 135 s, constant_env 123 s, envmap 38 s; 832 s in all.
The default --spp is the committed 32768.
"""
import argparse
import math
import os
import sys
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, HERE)
from make_references import pick_variant, render_chunked  # noqa: E402

SCENE_DIR = os.path.join(ROOT, "scenes", "mitsuba")
DEFAULT_OUT = os.path.join(ROOT, "tests", "references")

# name -> (width, height); the test renders at the same sizes.
SCENES = {
    "metals": (96, 64),
    "conductors": (96, 64),
    "glass": (96, 64),
    "textured": (64, 64),
    "point": (64, 64),
    "spot": (64, 64),
    "spot_soft": (64, 64),
    "directional": (64, 64),
    "constant_env": (64, 64),
    "envmap": (64, 64),
}
ENVMAP_ROTATION_DEG = 90.0


def write_checker(mi, np, path):
    """A 16x16 sRGB texture that is asymmetric under every flip and rotation: 4x4-texel checker
    of orange and blue, a green ramp along u and a white texel block at (u, v) = (0, 0)."""
    n = 16
    img = np.zeros((n, n, 3), dtype=np.uint8)
    for y in range(n):
        for x in range(n):
            if ((x // 4) + (y // 4)) % 2 == 0:
                c = [230, 120, 30]
            else:
                c = [40, 70, 200]
            c[1] = min(255, c[1] + 8 * x)
            img[y, x] = c
    img[0:2, 0:2] = [255, 255, 255]
    bmp = mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB)
    bmp.set_srgb_gamma(True)  # 8-bit values are sRGB-encoded
    bmp.write(path)


def rgb(v):
    return {"type": "rgb", "value": [float(x) for x in v]}


def look_at(mi, eye, target, up):
    return mi.ScalarTransform4f().look_at(origin=eye, target=target, up=up)


def mat4(mi, np, m):
    return mi.ScalarTransform4f(np.array(m, dtype=np.float64))


def uv_matrix(np, mat):
    """KHR_texture_transform as Trayecto applies it: uv' = T R S uv with
    R = [[cos, sin], [-sin, cos]] (counter-clockwise in glTF's v-down UV space)."""
    sx, sy = mat.get("uv_scale", [1.0, 1.0])
    ox, oy = mat.get("uv_offset", [0.0, 0.0])
    r = math.radians(mat.get("uv_rotation", 0.0))
    c, s = math.cos(r), math.sin(r)
    return np.array([[c * sx, s * sy, 0, ox], [-s * sx, c * sy, 0, oy], [0, 0, 1, 0], [0, 0, 0, 1]])


def bsdf(mi, np, mat, scene_dir):
    model = mat.get("model", "diffuse")
    allowed = {"name", "model", "base_color", "base_color_texture", "metallic", "roughness", "ior",
               "emissive", "uv_scale", "uv_offset", "uv_rotation", "eta", "k", "conductor_alpha",
               "conductor_alpha_v"}
    extra = set(mat) - allowed
    if extra:
        raise ValueError(f"material {mat['name']}: keys not translated: {extra}")
    base = mat.get("base_color", [0.8, 0.8, 0.8])
    if model == "diffuse":
        if "base_color_texture" in mat:
            if base != [1.0, 1.0, 1.0]:
                raise ValueError("a textured base colour must have base_color 1")
            refl = {"type": "bitmap", "filename": os.path.join(scene_dir, mat["base_color_texture"]),
                    "filter_type": "bilinear", "wrap_mode": "repeat", "raw": False,
                    "to_uv": mat4(mi, np, uv_matrix(np, mat))}
        else:
            refl = rgb(base)
        return {"type": "diffuse", "reflectance": refl}
    if model == "metallic-roughness":
        if mat.get("metallic") != 1.0 or "base_color_texture" in mat:
            raise ValueError("only untextured metallic = 1 is translated")
        return {"type": "principled", "base_color": rgb(base), "metallic": 1.0,
                "roughness": float(mat.get("roughness", 0.5))}
    if model == "dielectric":
        if base != [1.0, 1.0, 1.0]:
            raise ValueError("dielectrics must have base_color 1")
        ior = float(mat.get("ior", 1.5))
        r = float(mat.get("roughness", 0.0))
        if r == 0.0:
            return {"type": "dielectric", "int_ior": ior, "ext_ior": 1.0}
        return {"type": "roughdielectric", "distribution": "ggx", "alpha": r * r,
                "int_ior": ior, "ext_ior": 1.0}
    if model == "conductor":
        # pbrt-v4's conductor with RGB eta/k (exact complex Fresnel per channel on both sides).
        if "eta" not in mat or "k" not in mat:
            raise ValueError("only conductors with explicit RGB eta and k are translated")
        ax = float(mat.get("conductor_alpha", 0.0))
        ay = float(mat.get("conductor_alpha_v", ax))
        if ax != ay:
            raise ValueError("anisotropic conductors are not translated (tangent conventions differ)")
        if ax < 1e-3:
            return {"type": "conductor", "eta": rgb(mat["eta"]), "k": rgb(mat["k"])}
        return {"type": "roughconductor", "distribution": "ggx", "alpha": ax,
                "sample_visible": True, "eta": rgb(mat["eta"]), "k": rgb(mat["k"])}
    raise ValueError(f"model {model} not translated")


def rot_xyz(np, deg):
    x, y, z = (math.radians(a) for a in deg)
    rx = np.array([[1, 0, 0], [0, math.cos(x), -math.sin(x)], [0, math.sin(x), math.cos(x)]])
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rz = np.array([[math.cos(z), -math.sin(z), 0], [math.sin(z), math.cos(z), 0], [0, 0, 1]])
    return rz @ ry @ rx  # x first, then y, then z (as Trayecto's TOML)


def scene_dict(mi, np, name, width, height, envmap):
    path = os.path.join(SCENE_DIR, f"{name}.toml")
    with open(path, "rb") as f:
        t = tomllib.load(f)
    cam = t["camera"][0]
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": -1},
        "sensor": {
            "type": "perspective",
            "fov": float(cam.get("fov", 39.6)),
            "fov_axis": "y",
            "near_clip": 1e-3,
            "to_world": look_at(mi, cam["eye"], cam["target"], cam.get("up", [0, 1, 0])),
            "sampler": {"type": "independent", "sample_count": 1},
            "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
        },
    }
    bg = t.get("background")
    if bg is not None:
        if "map" in bg or set(bg) - {"color", "strength"}:
            raise ValueError("only a uniform background colour is translated")
        d["background"] = {"type": "constant",
                           "radiance": rgb([c * bg.get("strength", 1.0) for c in bg["color"]])}
    if name == "envmap":
        if envmap is None:
            raise SystemExit("the envmap scene needs --envmap PATH (studio_small_03_1k.hdr)")
        d["envmap"] = {"type": "envmap", "filename": envmap, "scale": 1.0,
                       "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], ENVMAP_ROTATION_DEG)}
    mats = {m["name"]: m for m in t.get("material", [])}
    for i, o in enumerate(t.get("object", [])):
        m = mats[o["material"]]
        emissive = m.get("emissive")
        mb = dict(m)
        mb.pop("emissive", None)
        if emissive is not None and m.get("base_color") != [0.0, 0.0, 0.0]:
            raise ValueError("emitters must have a black base colour (Mitsuba's bsdf is set to black)")
        shape = {"bsdf": bsdf(mi, np, mb, SCENE_DIR)}
        if emissive is not None:
            shape["emitter"] = {"type": "area", "radiance": rgb(emissive)}
        has_xf = any(k in o for k in ("translate", "rotate", "scale", "matrix"))
        if o["type"] == "sphere":
            if has_xf:
                raise ValueError("transformed spheres are not translated")
            shape.update(type="sphere", center=[float(c) for c in o["center"]], radius=float(o["radius"]))
        elif o["type"] == "quad":
            if has_xf:
                raise ValueError("transformed quads are not translated")
            c, e1, e2 = (np.array(o[k], dtype=np.float64) for k in ("corner", "e1", "e2"))
            n = np.cross(e1, e2)
            n /= np.linalg.norm(n)
            # Mitsuba's rectangle is [-1,1]^2 at z = 0 with uv = ((x+1)/2, (y+1)/2) and normal +z.
            m4 = np.eye(4)
            m4[:3, 0], m4[:3, 1], m4[:3, 2], m4[:3, 3] = e1 / 2, e2 / 2, n, c + e1 / 2 + e2 / 2
            shape.update(type="rectangle", to_world=mat4(mi, np, m4))
        elif o["type"] == "box":
            if "matrix" in o or "scale" in o:
                raise ValueError("only translate/rotate are translated for boxes")
            lo, hi = np.array(o["min"], dtype=np.float64), np.array(o["max"], dtype=np.float64)
            box = np.eye(4)
            box[:3, :3] = np.diag((hi - lo) / 2)
            box[:3, 3] = (hi + lo) / 2
            xf = np.eye(4)
            xf[:3, :3] = rot_xyz(np, o.get("rotate", [0, 0, 0]))
            xf[:3, 3] = o.get("translate", [0, 0, 0])
            shape.update(type="cube", to_world=mat4(mi, np, xf @ box))
        else:
            raise ValueError(f"object type {o['type']} not translated")
        d[f"shape_{i}"] = shape
    for i, l in enumerate(t.get("light", [])):
        power = [c * l.get("intensity", 1.0) for c in l.get("color", [1, 1, 1])]
        if l["type"] == "point":
            d[f"light_{i}"] = {"type": "point", "position": [float(x) for x in l["position"]],
                               "intensity": rgb(power)}
        elif l["type"] == "spot":
            p = np.array(l["position"], dtype=np.float64)
            dirn = np.array(l["direction"], dtype=np.float64)
            up = [0, 0, 1] if abs(dirn[2]) < 0.9 * np.linalg.norm(dirn) else [1, 0, 0]
            d[f"light_{i}"] = {"type": "spot", "intensity": rgb(power),
                               "to_world": look_at(mi, p.tolist(), (p + dirn).tolist(), up),
                               "cutoff_angle": float(l["outer_angle"]),
                               "beam_width": float(l["inner_angle"])}
        elif l["type"] == "directional":
            d[f"light_{i}"] = {"type": "directional", "direction": [float(x) for x in l["direction"]],
                               "irradiance": rgb(power)}
        else:
            raise ValueError(f"light type {l['type']} not translated")
    return d


def render(mi, np, name, envmap, spp, chunk, out_dir):
    width, height = SCENES[name]
    scene = mi.load_dict(scene_dict(mi, np, name, width, height, envmap))
    img, seed, elapsed = render_chunked(mi, np, scene, spp, chunk, width, height)
    path = os.path.join(out_dir, f"mitsuba_{name}.exr")
    mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB).write(path)
    nonfinite = int((~np.isfinite(img)).sum())
    print(f"{name}: {width}x{height}, {spp} spp ({seed} chunks), {elapsed:.1f} s -> {path}; "
          f"mean RGB {img.reshape(-1, 3).mean(0).tolist()}, non-finite {nonfinite}", flush=True)
    return elapsed


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spp", type=int, default=32768, help="samples per pixel (default 32768)")
    ap.add_argument("--chunk", type=int, default=1024, help="spp per render call / seed (default 1024)")
    ap.add_argument("--only", choices=list(SCENES), action="append", help="render only these scenes")
    ap.add_argument("--envmap", help="path of studio_small_03_1k.hdr (needed for the envmap scene)")
    ap.add_argument("--variant", default="auto", help="mitsuba variant (auto: llvm_ad_rgb if LLVM>=16)")
    ap.add_argument("--out-dir", default=DEFAULT_OUT)
    args = ap.parse_args()

    variant = pick_variant(args.variant)
    import mitsuba as mi
    import numpy as np
    mi.set_variant(variant)
    os.makedirs(args.out_dir, exist_ok=True)
    print(f"mitsuba {mi.__version__}, variant {variant}, spp {args.spp}, chunk {args.chunk}")
    write_checker(mi, np, os.path.join(SCENE_DIR, "checker.png"))
    total = 0.0
    for name in args.only or SCENES:
        total += render(mi, np, name, args.envmap, args.spp, args.chunk, args.out_dir)
    print(f"total render time {total:.1f} s")


if __name__ == "__main__":
    sys.exit(main())
