#!/usr/bin/env python3
"""Path guiding against Blender Cycles with its path guiding on, at equal wall-clock time.

Usage (from the repository root, after `cargo build --release`; needs a Python with `bpy` and
`numpy`, e.g. `python3 -m venv V && V/bin/pip install bpy==4.5.15 numpy`):

    V/bin/python bench/guiding_cycles.py --seconds 20 --reps 2
    V/bin/python bench/guiding_cycles.py --scenes gap-room --seconds 10 --reps 3

The scenes are Bitterli's veach-ajar (../shared/scenes/pbrt/veach-ajar) and the hard-indirect
rooms of scenes/guiding/ (written by scripts/guiding_scenes.py in a small subset of pbrt-v4's
format: LookAt, a perspective camera, diffuse triangle meshes, one-sided diffuse area lights, a
distant light, a uniform infinite light, a homogeneous medium; veach-ajar adds a Transform
camera, PLY meshes under transforms, image-textured diffuse, rough conductors and a smooth
dielectric: Cycles' Metallic BSDF as a physical conductor with GGX, α = roughness², and its
Glass BSDF). This script reads those files and builds the same scene in Blender with bpy: the meshes with
their winding (a one-sided emitter emits on the side of its right-handed normal, as in pbrt-v4:
the emission shader is masked by the back-facing output), a sun of the distant light's
irradiance and angle 0, the infinite light as the world colour, the fog as a homogeneous world
volume (pbrt-v4's closed rooms: the same medium everywhere the camera can see), the camera with
the same field of view across the image's shorter side. pbrt's image runs along its camera's +x,
which for a LookAt camera points to the viewer's left (pbrt's camera space is left-handed): the
Cycles render is then flipped left-right before comparing (veach-ajar's Transform camera needs
no flip).

Cycles runs on the CPU, one thread (as Trayecto here), with path guiding on (surface and volume,
its default parallax-aware von Mises–Fisher mixtures and training) and its defaults otherwise,
except where they would change the image the references converge to: the bounce limits are
raised to the pbrt files' maxdepth (Cycles' defaults of 4 diffuse and 0 volume bounces would cut
the light that reaches these rooms through several bounces) and the sample clamps are off
(Cycles clamps indirect samples at 10 by default: biased, and it would hide exactly the fireflies
guiding is there to remove), and Filter Glossy is off (its default 1 blurs glossy reflections
seen after a rough bounce: on veach-ajar's metal floor it darkens the converged image by 20 %;
the other scenes have no glossy surface). Adaptive sampling stays on (its default). No denoiser.

Each renderer's error is its relative variance, from a pair of renders with different seeds
(`guiding.pair_rel_var`: half the mean squared difference over (r^2 + 0.01), an unbiased
estimate of its relMSE against the exact image, without any reference's noise), normalised by
its own long reference (`--ref-spp`, unguided, cached in bench/out/guiding/). The two references
are also compared to each other (mean ratio and the relMSE between them), which says whether the
two renderers render the same scene. Repetitions are interleaved: Trayecto unguided, Trayecto
guided, Cycles unguided, Cycles guided, each with `--seconds`, twice (the pair), then the next
repetition with other seeds.
"""
import argparse
import math
import os
import re
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
OUT = os.path.join(HERE, "out", "guiding")
sys.path.insert(0, HERE)
from guiding import SCENES as SCENE_FILES, pair_rel_var, read_hdr, rel_mse, render as trayecto_render  # noqa: E402

SCENES = ["veach-ajar", "gap-room", "sunlit-interior", "bright-patch", "fog-gap"]


def mat4(vals):
    """pbrt's 16 Transform numbers (column-major: the last four are the translation) as rows."""
    v = [float(x) for x in vals]
    return [[v[c * 4 + r] for c in range(4)] for r in range(4)]


def mat_mul(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(4)) for c in range(4)] for r in range(4)]


def mat_inv(m):
    """Inverse of a 4×4 matrix by Gauss–Jordan elimination with partial pivoting."""
    a = [row[:] + [1.0 if r == c else 0.0 for c in range(4)] for r, row in enumerate(m)]
    for c in range(4):
        p = max(range(c, 4), key=lambda r: abs(a[r][c]))
        a[c], a[p] = a[p], a[c]
        d = a[c][c]
        a[c] = [x / d for x in a[c]]
        for r in range(4):
            if r != c:
                f = a[r][c]
                a[r] = [x - f * y for x, y in zip(a[r], a[c])]
    return [row[4:] for row in a]


def xform_point(m, p):
    return [sum(m[r][k] * p[k] for k in range(3)) + m[r][3] for r in range(3)]


def xform_normal(m, n):
    """A normal by the inverse transpose of m's linear part."""
    inv = mat_inv(m)
    return [sum(inv[k][r] * n[k] for k in range(3)) for r in range(3)]


def read_ply(path):
    """A binary little-endian or ASCII PLY triangle/quad mesh: positions, optional normals and
    uvs, faces (quads split into two triangles, as pbrt-v4 does)."""
    import struct
    data = open(path, "rb").read()
    end = data.index(b"end_header") + len(b"end_header")
    end = data.index(b"\n", end) + 1
    header = data[:end].decode("ascii", "replace").splitlines()
    fmt = None
    elements = []
    for line in header:
        w = line.split()
        if not w:
            continue
        if w[0] == "format":
            fmt = w[1]
        elif w[0] == "element":
            elements.append((w[1], int(w[2]), []))
        elif w[0] == "property":
            elements[-1][2].append(w[1:])
    sizes = {"char": "b", "uchar": "B", "int8": "b", "uint8": "B", "short": "h", "ushort": "H",
             "int16": "h", "uint16": "H", "int": "i", "uint": "I", "int32": "i", "uint32": "I",
             "float": "f", "float32": "f", "double": "d", "float64": "d"}
    pos = end
    ascii_toks = data[end:].split() if fmt == "ascii" else None
    at = 0
    verts, faces = [], []
    names = []
    for name, count, props in elements:
        for _ in range(count):
            rec = {}
            for pr in props:
                if pr[0] == "list":
                    if fmt == "ascii":
                        n = int(ascii_toks[at]); at += 1
                        vals = [float(t) for t in ascii_toks[at:at + n]]; at += n
                    else:
                        cf, vf = "<" + sizes[pr[1]], "<" + sizes[pr[2]]
                        n = struct.unpack_from(cf, data, pos)[0]
                        pos += struct.calcsize(cf)
                        vals = list(struct.unpack_from("<" + sizes[pr[2]] * n, data, pos))
                        pos += struct.calcsize(vf) * n
                    rec[pr[3]] = vals
                else:
                    if fmt == "ascii":
                        rec[pr[1]] = float(ascii_toks[at]); at += 1
                    else:
                        f = "<" + sizes[pr[0]]
                        rec[pr[1]] = struct.unpack_from(f, data, pos)[0]
                        pos += struct.calcsize(f)
            if name == "vertex":
                verts.append(rec)
            elif name == "face":
                faces.append(rec.get("vertex_indices", rec.get("vertex_index")))
        names.append(name)
    if fmt not in ("binary_little_endian", "ascii"):
        raise SystemExit(f"{path}: PLY format {fmt} not supported here")
    P = [[v["x"], v["y"], v["z"]] for v in verts]
    N = [[v["nx"], v["ny"], v["nz"]] for v in verts] if verts and "nx" in verts[0] else None
    uk = next((k for k in (("u", "v"), ("s", "t"), ("texture_u", "texture_v")) if verts and k[0] in verts[0]), None)
    UV = [[v[uk[0]], v[uk[1]]] for v in verts] if uk else None
    tris = []
    for f in faces:
        f = [int(i) for i in f]
        for k in range(1, len(f) - 1):
            tris.append([f[0], f[k], f[k + 1]])
    return P, N, UV, tris


def parse_scene(path):
    """The subset of pbrt-v4 that scripts/guiding_scenes.py writes and that Bitterli's
    veach-ajar uses, as plain data: LookAt or a Transform camera, perspective camera, diffuse
    (constant or image-textured), conductor and dielectric materials (inline or named),
    triangle and PLY meshes under a transform, one-sided diffuse area lights, a distant light, a
    uniform infinite light, a homogeneous medium. Anything else is an error: a silently dropped
    directive would make the two renderers render different scenes. A texture file that is
    missing is the constant magenta Trayecto's loader substitutes (with its warning)."""
    base = os.path.dirname(os.path.abspath(path))
    text = open(path).read()
    toks = re.findall(r'"[^"]*"|\[|\]|[^\s\[\]"]+', re.sub(r"#[^\n]*", "", text))
    scene = {"meshes": [], "lights": [], "medium": None, "lookat": None, "fov": None, "maxdepth": 5,
             "mirror": True}
    i = 0
    ident = [[1.0 if r == c else 0.0 for c in range(4)] for r in range(4)]
    ctm = ident
    stack = []
    material = {"type": "diffuse", "refl": [0.5, 0.5, 0.5]}
    area = None
    textures = {}
    named = {}

    def params(j):
        """Parameter list starting at token j: {name: [values]}, and the index after it."""
        out = {}
        while j < len(toks) and toks[j].startswith('"'):
            name = toks[j].strip('"').split()[-1]
            j += 1
            if toks[j] == "[":
                j += 1
                vals = []
                while toks[j] != "]":
                    vals.append(toks[j].strip('"'))
                    j += 1
                j += 1
            else:
                vals = [toks[j].strip('"')]
                j += 1
            out[name] = vals
        return out, j

    def make_material(kind, p):
        if kind == "diffuse":
            if "reflectance" in p and p["reflectance"][0] in textures:
                return {"type": "diffuse", "refl": [1.0, 1.0, 1.0], "tex": textures[p["reflectance"][0]]}
            return {"type": "diffuse", "refl": [float(v) for v in p.get("reflectance", ["0.5"] * 3)]}
        if kind == "conductor":
            if p.get("remaproughness", ["true"])[0] != "false":
                raise SystemExit(f"{path}: conductor with remapped roughness not supported here")
            rough = float(p.get("roughness", ["0"])[0])
            return {"type": "conductor", "eta": [float(v) for v in p["eta"]],
                    "k": [float(v) for v in p["k"]],
                    "alpha_u": float(p.get("uroughness", [rough])[0]),
                    "alpha_v": float(p.get("vroughness", [rough])[0])}
        if kind == "dielectric":
            if float(p.get("roughness", p.get("uroughness", ["0"]))[0]) != 0.0:
                raise SystemExit(f"{path}: rough dielectric not supported here")
            return {"type": "dielectric", "eta": float(p.get("eta", ["1.5"])[0])}
        if kind == "interface":
            return {"type": "interface"}
        raise SystemExit(f"{path}: material {kind} not supported here")

    def add_mesh(P, tris, N=None, UV=None):
        if material["type"] == "interface":
            return
        Pw = [xform_point(ctm, p) for p in P]
        Nw = [xform_normal(ctm, n) for n in N] if N else None
        scene["meshes"].append({"P": Pw, "tris": tris, "N": Nw, "UV": UV, "mat": material,
                                "emit": area})

    while i < len(toks):
        t = toks[i]
        if t == "LookAt":
            scene["lookat"] = [float(v) for v in toks[i + 1:i + 10]]
            i += 10
        elif t == "Transform":
            j = i + 1 + (toks[i + 1] == "[")
            ctm = mat4(toks[j:j + 16])
            i = j + 16 + (toks[i + 1] == "[")
        elif t in ("Camera", "Film", "Sampler", "Integrator", "Material", "AreaLightSource",
                   "LightSource", "Shape", "MakeNamedMedium", "MakeNamedMaterial",
                   "NamedMaterial", "PixelFilter"):
            kind = toks[i + 1].strip('"')
            p, i = params(i + 2)
            if t == "Camera":
                if kind != "perspective":
                    raise SystemExit(f"{path}: camera {kind} not supported here")
                scene["fov"] = float(p.get("fov", ["90"])[0])
                if scene["lookat"] is None:
                    # The CTM is camera-from-world; pbrt's camera looks down +z with +y up, and
                    # its +x is the image's right.
                    c2w = mat_inv(ctm)
                    eye = [c2w[r][3] for r in range(3)]
                    fwd = [c2w[r][2] for r in range(3)]
                    up = [c2w[r][1] for r in range(3)]
                    xr = [c2w[r][0] for r in range(3)]
                    scene["lookat"] = eye + [eye[k] + fwd[k] for k in range(3)] + up
                    # Blender's camera has +x = fwd × up (its image's right); pbrt's image is
                    # mirrored when its +x points the other way.
                    right = [fwd[1] * up[2] - fwd[2] * up[1], fwd[2] * up[0] - fwd[0] * up[2],
                             fwd[0] * up[1] - fwd[1] * up[0]]
                    scene["mirror"] = sum(a * b for a, b in zip(right, xr)) < 0
                ctm = ident
            elif t == "Integrator":
                scene["maxdepth"] = int(p.get("maxdepth", ["5"])[0])
            elif t == "Material":
                material = make_material(kind, p)
            elif t == "MakeNamedMaterial":
                named[kind] = make_material(p["type"][0], p)
            elif t == "NamedMaterial":
                material = named[kind]
            elif t == "AreaLightSource":
                area = [float(v) for v in p["L"]]
            elif t == "LightSource":
                if kind == "distant":
                    scene["lights"].append(("distant", [float(v) for v in p["from"]],
                                            [float(v) for v in p["to"]], [float(v) for v in p["L"]]))
                elif kind == "infinite":
                    scene["lights"].append(("infinite", [float(v) for v in p["L"]]))
                else:
                    raise SystemExit(f"{path}: light {kind} not supported here")
            elif t == "MakeNamedMedium":
                if p.get("type", [""])[0] != "homogeneous":
                    raise SystemExit(f"{path}: medium {p.get('type')} not supported here")
                scale = float(p.get("scale", ["1"])[0])
                scene["medium"] = {
                    "sigma_a": [scale * float(v) for v in p["sigma_a"]],
                    "sigma_s": [scale * float(v) for v in p["sigma_s"]],
                    "g": float(p.get("g", ["0"])[0]),
                }
            elif t == "Shape":
                if kind == "trianglemesh":
                    pts = [float(v) for v in p["P"]]
                    idx = [int(v) for v in p["indices"]]
                    P = [pts[k:k + 3] for k in range(0, len(pts), 3)]
                    N = None
                    if "N" in p:
                        n = [float(v) for v in p["N"]]
                        N = [n[k:k + 3] for k in range(0, len(n), 3)]
                    UV = None
                    if "uv" in p:
                        u = [float(v) for v in p["uv"]]
                        UV = [u[k:k + 2] for k in range(0, len(u), 2)]
                    add_mesh(P, [idx[k:k + 3] for k in range(0, len(idx), 3)], N, UV)
                elif kind == "plymesh":
                    P, N, UV, tris = read_ply(os.path.join(base, p["filename"][0]))
                    add_mesh(P, tris, N, UV)
                elif kind == "sphere" and material["type"] == "interface":
                    pass  # the medium's bound: the world volume below has none
                else:
                    raise SystemExit(f"{path}: shape {kind} not supported here")
        elif t == "Texture":
            name, _, kind = (x.strip('"') for x in toks[i + 1:i + 4])
            p, i = params(i + 4)
            if kind != "imagemap":
                raise SystemExit(f"{path}: texture {kind} not supported here")
            f = os.path.join(base, p["filename"][0])
            textures[name] = f if os.path.exists(f) else None  # None: the magenta fallback
        elif t in ("AttributeBegin", "WorldBegin"):
            i += 1
            if t == "AttributeBegin":
                stack.append((ctm, material, area))
            else:
                ctm = ident
        elif t == "AttributeEnd":
            ctm, material, area = stack.pop()
            i += 1
        elif t == "MediumInterface":
            i += 3
        else:
            raise SystemExit(f"{path}: directive {t} not supported here")
    return scene


CYCLES_RENDER = r'''
import bpy, math, json, sys
args = json.load(open(sys.argv[-1]))
sc = args["scene"]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
def vec(a): return (a[0], a[1], a[2])
images = {}
def surface(nt, m):
    """The shader node of a mesh's material."""
    mt = m["mat"]
    if mt["type"] == "conductor":
        n = nt.nodes.new("ShaderNodeBsdfMetallic")
        # pbrt's conductor: GGX (single scattering), Fresnel from the complex index η + ik, the
        # roughness given as α (remaproughness false); Cycles' roughness r is α = r².
        n.distribution = "GGX"
        n.fresnel_type = "PHYSICAL_CONDUCTOR"
        n.inputs["IOR"].default_value = tuple(mt["eta"])
        n.inputs["Extinction"].default_value = tuple(mt["k"])
        au, av = mt["alpha_u"], mt["alpha_v"]
        if abs(au - av) > 1e-6:
            raise SystemExit("anisotropic conductor roughness not supported here")
        n.inputs["Roughness"].default_value = math.sqrt(au)
        return n.outputs["BSDF"]
    if mt["type"] == "dielectric":
        n = nt.nodes.new("ShaderNodeBsdfGlass")
        n.distribution = "SHARP" if "SHARP" in [e.identifier for e in n.bl_rna.properties["distribution"].enum_items] else "GGX"
        n.inputs["Roughness"].default_value = 0.0
        n.inputs["IOR"].default_value = mt["eta"]
        n.inputs["Color"].default_value = (1, 1, 1, 1)
        return n.outputs["BSDF"]
    dif = nt.nodes.new("ShaderNodeBsdfDiffuse")
    dif.inputs["Color"].default_value = (*mt["refl"], 1.0)
    if "tex" in mt:
        if mt["tex"] is None:
            dif.inputs["Color"].default_value = (1, 0, 1, 1)  # Trayecto's missing-texture magenta
        else:
            f = mt["tex"]
            if f not in images:
                images[f] = bpy.data.images.load(f)
            tex = nt.nodes.new("ShaderNodeTexImage")
            tex.image = images[f]
            tex.interpolation = "Linear"
            nt.links.new(tex.outputs["Color"], dif.inputs["Color"])
    return dif.outputs["BSDF"]
for k, m in enumerate(sc["meshes"]):
    me = bpy.data.meshes.new(f"m{k}")
    me.from_pydata([vec(p) for p in m["P"]], [], [tuple(t) for t in m["tris"]])
    me.update()
    if m.get("UV"):
        uv = me.uv_layers.new(name="UVMap")
        for loop in me.loops:
            uv.data[loop.index].uv = m["UV"][loop.vertex_index]
    if m.get("N"):
        for poly in me.polygons:
            poly.use_smooth = True
        me.normals_split_custom_set_from_vertices([vec(n) for n in m["N"]])
    ob = bpy.data.objects.new(f"o{k}", me)
    scene.collection.objects.link(ob)
    mat = bpy.data.materials.new(f"mat{k}")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    bsdf = surface(nt, m)
    if m["emit"]:
        # One-sided emitter, as pbrt-v4's area lights: emission on the front face only.
        em = nt.nodes.new("ShaderNodeEmission")
        s = max(m["emit"])
        em.inputs["Color"].default_value = (*[c / s for c in m["emit"]], 1.0)
        em.inputs["Strength"].default_value = s
        geo = nt.nodes.new("ShaderNodeNewGeometry")
        mix = nt.nodes.new("ShaderNodeMixShader")
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(em.outputs["Emission"], add.inputs[0])
        nt.links.new(bsdf, add.inputs[1])
        nt.links.new(geo.outputs["Backfacing"], mix.inputs["Fac"])
        nt.links.new(add.outputs["Shader"], mix.inputs[1])
        nt.links.new(bsdf, mix.inputs[2])
        nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    else:
        nt.links.new(bsdf, out.inputs["Surface"])
    me.materials.append(mat)
world = bpy.data.worlds.new("w")
scene.world = world
world.use_nodes = True
wn = world.node_tree
wn.nodes.clear()
wout = wn.nodes.new("ShaderNodeOutputWorld")
bg = wn.nodes.new("ShaderNodeBackground")
bg.inputs["Color"].default_value = (0, 0, 0, 1)
bg.inputs["Strength"].default_value = 1.0
wn.links.new(bg.outputs["Background"], wout.inputs["Surface"])
for l in sc["lights"]:
    if l[0] == "infinite":
        bg.inputs["Color"].default_value = (*l[1], 1.0)
    else:
        _, fr, to, L = l
        d = [to[i] - fr[i] for i in range(3)]
        n = math.sqrt(sum(c * c for c in d))
        d = [c / n for c in d]
        sun = bpy.data.lights.new("sun", "SUN")
        s = max(L)
        sun.color = tuple(c / s for c in L)
        sun.energy = s  # W/m^2: irradiance on a surface facing the sun, pbrt-v4's distant L
        sun.angle = 0.0
        ob = bpy.data.objects.new("sun", sun)
        scene.collection.objects.link(ob)
        # A sun shines along its local -Z.
        import mathutils
        ob.rotation_euler = mathutils.Vector(d).to_track_quat("-Z", "Y").to_euler()
if sc["medium"]:
    m = sc["medium"]
    sca = wn.nodes.new("ShaderNodeVolumeScatter")
    sca.inputs["Color"].default_value = (1, 1, 1, 1)
    sca.inputs["Density"].default_value = m["sigma_s"][0]
    sca.inputs["Anisotropy"].default_value = m["g"]
    ab = wn.nodes.new("ShaderNodeVolumeAbsorption")
    ab.inputs["Color"].default_value = (0, 0, 0, 1)
    ab.inputs["Density"].default_value = m["sigma_a"][0]
    add = wn.nodes.new("ShaderNodeAddShader")
    wn.links.new(sca.outputs[0], add.inputs[0])
    wn.links.new(ab.outputs[0], add.inputs[1])
    wn.links.new(add.outputs[0], wout.inputs["Volume"])
    world.cycles.homogeneous_volume = True
la = sc["lookat"]
eye, target, up = la[0:3], la[3:6], la[6:9]
import mathutils
cam = bpy.data.cameras.new("cam")
cam.sensor_fit = "VERTICAL" if args["res"][1] <= args["res"][0] else "HORIZONTAL"
cam.angle = math.radians(sc["fov"])
cob = bpy.data.objects.new("cam", cam)
scene.collection.objects.link(cob)
cob.location = eye
# The camera's local -Z looks at the target and its local +Y is the file's up (not Blender's +Z).
fwd = (mathutils.Vector(target) - mathutils.Vector(eye)).normalized()
right = fwd.cross(mathutils.Vector(up)).normalized()
cup = right.cross(fwd)
cob.rotation_euler = mathutils.Matrix((right, cup, -fwd)).transposed().to_euler()
scene.camera = cob
r = scene.render
r.engine = "CYCLES"
r.resolution_x, r.resolution_y = args["res"]
r.resolution_percentage = 100
r.threads_mode = "FIXED"
r.threads = args["threads"]
r.image_settings.file_format = "HDR"
r.filepath = args["out"]
scene.view_settings.view_transform = "Standard"
c = scene.cycles
c.device = "CPU"
c.samples = args["spp"]
c.time_limit = args["seconds"]
c.seed = args["seed"]
c.use_denoising = False
c.use_adaptive_sampling = args["adaptive"]
d = sc["maxdepth"]
c.max_bounces = d
c.diffuse_bounces = d
c.glossy_bounces = d
c.transmission_bounces = d
c.volume_bounces = d
c.sample_clamp_direct = 0.0
c.sample_clamp_indirect = 0.0
c.blur_glossy = 0.0
c.use_guiding = args["guiding"]
c.use_surface_guiding = True
c.use_volume_guiding = True
bpy.ops.render.render(write_still=True)
'''


def cycles_render(py, scene, out, res, seed, threads, seconds, spp, guiding):
    import json
    # A reference (no time limit) renders every sample: adaptive sampling would stop it at
    # Cycles' default noise threshold, far above a reference's noise.
    # The scene goes through a file: a mesh of 10⁵ triangles is beyond the argument list's limit.
    arg = out + ".json"
    with open(arg, "w") as f:
        json.dump({"scene": scene, "out": out, "res": list(res), "seed": seed,
                   "threads": threads, "seconds": seconds, "spp": spp, "guiding": guiding,
                   "adaptive": seconds > 0}, f)
    t = time.time()
    r = subprocess.run([py, "-c", CYCLES_RENDER, arg], capture_output=True, text=True)
    os.remove(arg)
    if r.returncode != 0 or not os.path.exists(out):
        sys.stderr.write(r.stdout[-3000:] + r.stderr[-3000:])
        raise SystemExit(f"Cycles failed on {out}")
    return time.time() - t


def mirrored(img, w, h):
    """The image flipped left-right (pbrt's left-handed camera against Blender's)."""
    out = []
    for y in range(h):
        row = img[3 * w * y:3 * w * (y + 1)]
        for x in range(w - 1, -1, -1):
            out += row[3 * x:3 * x + 3]
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", nargs="*", default=SCENES)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--reps", type=int, default=2)
    ap.add_argument("--res", default="96x72")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--trayecto-bin", default=os.path.join(ROOT, "target/release/trayecto"))
    args = ap.parse_args()
    res = tuple(int(v) for v in args.res.split("x"))
    os.makedirs(OUT, exist_ok=True)
    exe = os.path.abspath(args.trayecto_bin)
    py = sys.executable
    rows = []
    for name in args.scenes:
        path = SCENE_FILES[name]
        scene = parse_scene(path)
        tag = f"{name}_{res[0]}x{res[1]}"
        tref = os.path.join(OUT, f"ref_{tag}_{args.ref_spp}.hdr")
        if not os.path.exists(tref):
            t = trayecto_render(exe, path, tref, res, 999, args.threads, ["--spp", str(args.ref_spp)])
            print(f"[{name}] Trayecto reference: {t:.0f} s", file=sys.stderr, flush=True)
        cref = os.path.join(OUT, f"cycles_ref_{tag}_{args.ref_spp}.hdr")
        if not os.path.exists(cref):
            t = cycles_render(py, scene, cref, res, 999, args.threads, 0, args.ref_spp, False)
            print(f"[{name}] Cycles reference: {t:.0f} s", file=sys.stderr, flush=True)
        tr = read_hdr(tref)
        flip = (lambda img: mirrored(img, *res)) if scene["mirror"] else (lambda img: img)
        cr = flip(read_hdr(cref))
        agree = (sum(cr) / len(cr)) / (sum(tr) / len(tr))
        between = rel_mse(cr, tr)
        errs = {k: [] for k in ("t_plain", "t_guided", "c_plain", "c_guided")}
        for rep in range(args.reps):
            imgs = {k: [] for k in errs}
            for half in (0, 1):
                seed = 1 + 2 * rep + half
                for mode in ("plain", "guided"):
                    out = os.path.join(OUT, f"{tag}_t_{mode}_{rep}_{half}.hdr")
                    extra = ["--time-limit", str(args.seconds)] + (["--guiding"] if mode == "guided" else [])
                    trayecto_render(exe, path, out, res, seed, args.threads, extra)
                    imgs["t_" + mode].append(read_hdr(out))
                for mode in ("plain", "guided"):
                    out = os.path.join(OUT, f"{tag}_c_{mode}_{rep}_{half}.hdr")
                    cycles_render(py, scene, out, res, seed, args.threads, args.seconds, 1 << 24,
                                  mode == "guided")
                    imgs["c_" + mode].append(flip(read_hdr(out)))
            for k in errs:
                errs[k].append(pair_rel_var(*imgs[k], tr if k.startswith("t_") else cr))
            print(f"[{name}] rep {rep}: " + ", ".join(f"{k} {v[-1]:.4g}" for k, v in errs.items()),
                  file=sys.stderr, flush=True)
        rows.append((name, agree, between, errs))

    def cell(v):
        return f"{statistics.median(v):.4g} ({min(v):.4g}–{max(v):.4g})"

    print("| scene | refs: Cycles/Trayecto mean, relMSE between | Trayecto unguided | Trayecto guided "
          "| Cycles unguided | Cycles guided | Cycles guided / Trayecto guided |")
    print("|---|---|---|---|---|---|---|")
    for name, agree, between, e in rows:
        ratio = statistics.median(e["c_guided"]) / statistics.median(e["t_guided"])
        print(f"| {name} | {agree:.3f}, {between:.4f} | {cell(e['t_plain'])} | {cell(e['t_guided'])} "
              f"| {cell(e['c_plain'])} | {cell(e['c_guided'])} | {ratio:.2f}× |", flush=True)


if __name__ == "__main__":
    sys.exit(main())
