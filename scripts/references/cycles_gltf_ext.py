#!/usr/bin/env python3
"""Trayecto vs Blender Cycles on the glTF material-extension sample models
(docs/src/correctness.md, "glTF extensions against Cycles").

Each model of ../shared/scenes/gltf-ext is given one camera (a glTF camera node looking at the
model's bounding box from a fixed direction, written into a copy of the .gltf next to copies of
its data: Trayecto rightly refuses symlinks that lead out of the scene folder) so both renderers see the same view. Both light it with a uniform white environment of
radiance 1 (Trayecto's default light; a Cycles world colour of 1.0), render linear EXR, and this
script prints the per-channel means over the model's pixels (those that are not the white
background in either image) and their relative difference.

Cycles runs from the `bpy` wheel (Blender as a Python module; Python 3.11). Install it once:

    python3 -m venv target/bpy-venv && target/bpy-venv/bin/pip install bpy numpy
    target/bpy-venv/bin/python scripts/references/cycles_gltf_ext.py [--spp 64] [--size 96]

Trayecto is run as `target/release/trayecto` (built if missing). Blender's glTF importer maps
the KHR extensions onto its Principled BSDF, whose lobes are not the glTF ones (see
docs/src/correctness.md, "glTF extensions against Cycles"): the numbers measure how far the two material models are apart,
not only errors.
"""

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

MODELS = {
    "clearcoat": "ClearcoatWicker/glTF/ClearcoatWicker.gltf",
    "sheen": "SheenCloth/glTF/SheenCloth.gltf",
    "anisotropy": "AnisotropyStrengthTest/glTF/AnisotropyStrengthTest.gltf",
    "transmission+volume": "GlassHurricaneCandleHolder/glTF/GlassHurricaneCandleHolder.gltf",
}

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def shared_dir():
    for d in [os.environ.get("TRAYECTO_SHARED"), os.path.join(ROOT, "..", "shared")]:
        if d and os.path.isdir(os.path.join(d, "scenes")):
            return d
    sys.exit("error: ../shared/scenes not found (set TRAYECTO_SHARED)")


def bounds(doc):
    """World-space bounds from the POSITION accessors' min/max (node transforms: translation
    and scale only, enough for these models; rotations are ignored)."""
    lo, hi = [math.inf] * 3, [-math.inf] * 3

    def visit(i, t, s):
        n = doc["nodes"][i]
        tr = n.get("translation", [0, 0, 0])
        sc = n.get("scale", [1, 1, 1])
        t2 = [t[k] + s[k] * tr[k] for k in range(3)]
        s2 = [s[k] * sc[k] for k in range(3)]
        if "mesh" in n:
            for p in doc["meshes"][n["mesh"]]["primitives"]:
                a = doc["accessors"][p["attributes"]["POSITION"]]
                for k in range(3):
                    for v in (a["min"][k], a["max"][k]):
                        w = t2[k] + s2[k] * v
                        lo[k], hi[k] = min(lo[k], w), max(hi[k], w)
        for c in n.get("children", []):
            visit(c, t2, s2)

    scene = doc["scenes"][doc.get("scene", 0)]
    for i in scene["nodes"]:
        visit(i, [0, 0, 0], [1, 1, 1])
    return lo, hi


def with_camera(src, workdir, edit=None):
    """A copy of `src` with one perspective camera (yfov 40°) framing the model from +z, slightly
    above; the other files are copied beside it. `edit(material)` changes every material first
    (the --diagnose-clearcoat variants)."""
    folder = os.path.dirname(src)
    for f in os.listdir(folder):
        if not f.endswith(".gltf"):
            shutil.copy(os.path.join(folder, f), os.path.join(workdir, f))
    doc = json.load(open(src))
    if edit:
        for m in doc.get("materials", []):
            edit(m)
    lo, hi = bounds(doc)
    c = [(lo[k] + hi[k]) / 2 for k in range(3)]
    r = 0.5 * math.dist(lo, hi)
    yfov = math.radians(40)
    d = r / math.sin(yfov / 2) * 1.05
    pitch = math.radians(-15)
    eye = [c[0], c[1] - d * math.sin(pitch), c[2] + d * math.cos(pitch)]
    # Rotation about x by `pitch` (the camera looks down -z).
    q = [math.sin(pitch / 2), 0.0, 0.0, math.cos(pitch / 2)]
    doc.setdefault("cameras", []).append(
        {"type": "perspective", "perspective": {"yfov": yfov, "znear": r * 0.01, "aspectRatio": 1.0}}
    )
    doc["nodes"].append({"camera": len(doc["cameras"]) - 1, "translation": eye, "rotation": q})
    doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(doc["nodes"]) - 1)
    out = os.path.join(workdir, os.path.basename(src))
    json.dump(doc, open(out, "w"))
    return out


def render_cycles(gltf, exr, size, spp, single_scatter):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=gltf)
    if single_scatter:
        # Blender's Principled BSDF defaults to multiple-scattering GGX (energy-conserving);
        # glTF's and Trayecto's GGX is single-scattering.
        for mat in bpy.data.materials:
            for node in (mat.node_tree.nodes if mat.node_tree else []):
                if node.type == "BSDF_PRINCIPLED":
                    node.distribution = "GGX"
    sc = bpy.context.scene
    cams = [o for o in sc.objects if o.type == "CAMERA"]
    sc.camera = cams[-1]
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = spp
    sc.cycles.use_denoising = False
    sc.cycles.max_bounces = 64
    for k in ("diffuse", "glossy", "transmission", "volume"):
        setattr(sc.cycles, f"{k}_bounces", 64)
    sc.cycles.transparent_max_bounces = 64
    sc.render.resolution_x = sc.render.resolution_y = size
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = False
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0
    sc.view_settings.gamma = 1
    world = bpy.data.worlds.new("white")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs[0].default_value = (1, 1, 1, 1)
    bg.inputs[1].default_value = 1.0
    sc.world = world
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.filepath = exr
    bpy.ops.render.render(write_still=True)


def _no_coat(m):
    m.get("extensions", {}).pop("KHR_materials_clearcoat", None)


def _no_normal_maps(m):
    m.pop("normalTexture", None)
    m.get("extensions", {}).get("KHR_materials_clearcoat", {}).pop("clearcoatNormalTexture", None)


def _no_base_normal_map(m):
    m.pop("normalTexture", None)


def _no_coat_normal_map(m):
    m.get("extensions", {}).get("KHR_materials_clearcoat", {}).pop("clearcoatNormalTexture", None)


def _black_coat_only(m):
    """Base black, no specular, no textures but the normal maps: only the coat reflects."""
    pbr = m.setdefault("pbrMetallicRoughness", {})
    for k in ("baseColorTexture", "metallicRoughnessTexture"):
        pbr.pop(k, None)
    pbr.update({"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0, "roughnessFactor": 1.0})
    m.setdefault("extensions", {})["KHR_materials_specular"] = {"specularFactor": 0.0}


def _flat(base, metallic, roughness, specular=True, coat=True, coat_roughness=None):
    """Every texture off: a uniform material on the wicker's geometry, coat kept (or removed)."""

    def edit(m):
        cc = m.get("extensions", {}).get("KHR_materials_clearcoat")
        m.clear()
        m["pbrMetallicRoughness"] = {
            "baseColorFactor": [base, base, base, 1.0],
            "metallicFactor": metallic,
            "roughnessFactor": roughness,
        }
        ext = {}
        if coat and cc is not None:
            ext["KHR_materials_clearcoat"] = {
                "clearcoatFactor": cc.get("clearcoatFactor", 0.0),
                "clearcoatRoughnessFactor": cc.get("clearcoatRoughnessFactor", 0.0)
                if coat_roughness is None
                else coat_roughness,
            }
        if not specular:
            ext["KHR_materials_specular"] = {"specularFactor": 0.0}
        if ext:
            m["extensions"] = ext

    return edit


def _both(*edits):
    def edit(m):
        for e in edits:
            e(m)

    return edit


# ClearcoatWicker variants that isolate the terms of the clearcoat gap (--diagnose-clearcoat).
CLEARCOAT_DIAGNOSIS = [
    ("wicker as is", None),
    ("wicker, no coat", _no_coat),
    ("wicker, no normal maps", _no_normal_maps),
    ("wicker, no normal maps, no coat", _both(_no_coat, _no_normal_maps)),
    ("wicker, no base normal map", _no_base_normal_map),
    ("wicker, no coat normal map", _no_coat_normal_map),
    ("black + coat, both normal maps", _black_coat_only),
    ("black + coat, coat normal map only", _both(_black_coat_only, _no_base_normal_map)),
    ("black + coat, base normal map only", _both(_black_coat_only, _no_coat_normal_map)),
    ("black, no specular + coat r0.1 (coat lobe alone)", _flat(0.0, 0.0, 1.0, specular=False)),
    ("black, no specular + coat r0.5", _flat(0.0, 0.0, 1.0, specular=False, coat_roughness=0.5)),
    ("white diffuse, no specular + coat", _flat(1.0, 0.0, 1.0, specular=False)),
    ("white diffuse, no specular, no coat", _flat(1.0, 0.0, 1.0, specular=False, coat=False)),
    ("white metal r0.3 + coat", _flat(1.0, 1.0, 0.3)),
    ("white metal r0.3, no coat", _flat(1.0, 1.0, 0.3, coat=False)),
    ("white metal r1 + coat", _flat(1.0, 1.0, 1.0)),
    ("white metal r1, no coat", _flat(1.0, 1.0, 1.0, coat=False)),
]


def _aniso_as_cycles(m):
    """glTF roughness r' and anisotropy strength s' whose α_t = mix(r'², 1, s'²), α_b = r'²
    (KHR_materials_anisotropy) equal the α_x, α_y Cycles' Principled BSDF gives the material as
    Blender's importer maps it (Anisotropic = strength, Roughness = r): aspect = √(1 − 0.9 s),
    α_x = r²/aspect, α_y = r²·aspect (intern/cycles/kernel/svm/closure.h). α_x is capped at 1,
    the most glTF can express (it is reached only at r ≥ 0.97)."""
    pbr = m.setdefault("pbrMetallicRoughness", {})
    ext = m.get("extensions", {}).get("KHR_materials_anisotropy")
    if ext is None:
        return
    r = pbr.get("roughnessFactor", 1.0)
    s = ext.get("anisotropyStrength", 0.0)
    aspect = math.sqrt(1.0 - 0.9 * s)
    ax, ay = min(r * r / aspect, 1.0), r * r * aspect
    pbr["roughnessFactor"] = math.sqrt(ay)
    ext["anisotropyStrength"] = math.sqrt((ax - ay) / (1.0 - ay)) if ay < 1.0 else 0.0


# AnisotropyStrengthTest with Trayecto given Cycles' α mapping (--diagnose-anisotropy): the
# edit applies to Trayecto's copy only; Cycles renders the file as it is.
ANISOTROPY_DIAGNOSIS = [
    ("anisotropy as is", None),
    ("anisotropy, Trayecto with Cycles' alpha mapping", _aniso_as_cycles),
]


def read_exr(path):
    import bpy
    import numpy as np

    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], 4)[..., :3]
    bpy.data.images.remove(img)
    return px


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--keep", help="folder to keep the EXRs in")
    ap.add_argument(
        "--single-scatter",
        action="store_true",
        help="set Cycles' Principled BSDFs to single-scattering GGX (as glTF and Trayecto)",
    )
    ap.add_argument(
        "--diagnose-clearcoat",
        action="store_true",
        help="render ClearcoatWicker variants that isolate the clearcoat gap's terms",
    )
    ap.add_argument(
        "--diagnose-anisotropy",
        action="store_true",
        help="render AnisotropyStrengthTest as is and with Trayecto given Cycles' roughness mapping",
    )
    a = ap.parse_args()
    exe = os.environ.get("TRAYECTO_EXE") or os.path.join(
        os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target")), "release", "trayecto"
    )
    if not os.path.exists(exe):
        subprocess.run(["cargo", "build", "--release"], cwd=ROOT, check=True)
    shared = shared_dir()
    tmp = tempfile.mkdtemp(prefix="trayecto-cycles-")
    print(f"{'case':50} {'Trayecto mean RGB':>28} {'Cycles mean RGB':>28} {'rel. diff (lum)':>16}")
    try:
        # (name, model, edit of both renderers' copy, edit of Trayecto's copy only)
        if a.diagnose_clearcoat:
            runs = [(n, MODELS["clearcoat"], e, None) for n, e in CLEARCOAT_DIAGNOSIS]
        elif a.diagnose_anisotropy:
            runs = [(n, MODELS["anisotropy"], None, e) for n, e in ANISOTROPY_DIAGNOSIS]
        else:
            runs = [(n, rel, None, None) for n, rel in MODELS.items()]
        for k, (name, rel, edit, edit_trayecto) in enumerate(runs):
            work = os.path.join(tmp, f"run{k}")
            os.makedirs(work)
            src = os.path.join(shared, "scenes", "gltf-ext", rel)
            g = with_camera(src, work, edit)
            g_t = g
            if edit_trayecto:
                os.makedirs(os.path.join(work, "t"))
                g_t = with_camera(src, os.path.join(work, "t"), edit_trayecto)
            t_exr, c_exr = os.path.join(work, "trayecto.exr"), os.path.join(work, "cycles.exr")
            subprocess.run(
                [exe, g_t, "--spp", str(a.spp), "--width", str(a.size), "--height", str(a.size),
                 "--max-depth", "64", "-q", "-o", t_exr],
                check=True,
            )
            render_cycles(g, c_exr, a.size, a.spp, a.single_scatter)
            t, c = read_exr(t_exr), read_exr(c_exr)
            # The model's pixels: where either image is not the white background.
            import numpy as np

            on = (np.abs(t - 1).max(-1) > 1e-3) | (np.abs(c - 1).max(-1) > 1e-3)
            tm, cm = t[on].mean(0), c[on].mean(0)
            lum = lambda m: 0.2126 * m[0] + 0.7152 * m[1] + 0.0722 * m[2]
            rel_diff = (lum(tm) - lum(cm)) / lum(cm)
            fmt = lambda m: "(" + ", ".join(f"{x:.4f}" for x in m) + ")"
            print(f"{name:50} {fmt(tm):>28} {fmt(cm):>28} {rel_diff:>+15.2%}", flush=True)
            if a.keep:
                os.makedirs(a.keep, exist_ok=True)
                tag = name.replace("+", "_").replace(",", "").replace(" ", "-")
                shutil.copy(t_exr, os.path.join(a.keep, f"{tag}-trayecto.exr"))
                shutil.copy(c_exr, os.path.join(a.keep, f"{tag}-cycles.exr"))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
