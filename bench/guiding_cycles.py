#!/usr/bin/env python3
"""Path guiding against Blender Cycles with its path guiding on, at equal wall-clock time.

Usage (from the repository root, after `cargo build --release`; needs a Python with `bpy` and
`numpy`, e.g. `python3 -m venv V && V/bin/pip install bpy==4.5.15 numpy`):

    V/bin/python bench/guiding_cycles.py --seconds 20 --reps 2
    V/bin/python bench/guiding_cycles.py --scenes gap-room --seconds 10 --reps 3

The scenes are the hard-indirect rooms of scenes/guiding/ (written by scripts/guiding_scenes.py
in a small subset of pbrt-v4's format: LookAt, a perspective camera, diffuse triangle meshes,
one-sided diffuse area lights, a distant light, a uniform infinite light, a homogeneous medium).
This script reads those files and builds the same scene in Blender with bpy: the meshes with
their winding (a one-sided emitter emits on the side of its right-handed normal, as in pbrt-v4:
the emission shader is masked by the back-facing output), a sun of the distant light's
irradiance and angle 0, the infinite light as the world colour, the fog as a homogeneous world
volume (pbrt-v4's closed rooms: the same medium everywhere the camera can see), the camera with
the same vertical field of view. pbrt's image is the mirror of a right-handed camera's (pbrt's
camera space is left-handed), so the Cycles render is flipped left-right before comparing.

Cycles runs on the CPU, one thread (as Trayecto here), with path guiding on (surface and volume,
its default parallax-aware von Mises–Fisher mixtures and training) and its defaults otherwise,
except where they would change the image the references converge to: the bounce limits are
raised to the pbrt files' maxdepth (Cycles' defaults of 4 diffuse and 0 volume bounces would cut
the light that reaches these rooms through several bounces) and the sample clamps are off
(Cycles clamps indirect samples at 10 by default: biased, and it would hide exactly the fireflies
guiding is there to remove). Adaptive sampling stays on (its default). No denoiser.

Each renderer is scored against its own long reference (`--ref-spp`, unguided, cached in
bench/out/guiding/): relMSE as bench/compare.py. The two references are also compared to each
other (mean ratio and the relMSE between them), which says whether the two renderers render the
same scene. Repetitions are interleaved: Trayecto unguided, Trayecto guided, Cycles unguided,
Cycles guided, each with `--seconds`, then the next repetition with another seed.
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
from guiding import read_hdr, rel_mse, render as trayecto_render  # noqa: E402

SCENES = ["gap-room", "sunlit-interior", "bright-patch", "fog-gap"]


def parse_scene(path):
    """The subset of pbrt-v4 that scripts/guiding_scenes.py writes, as plain data. Anything else
    is an error: a silently dropped directive would make the two renderers render different
    scenes."""
    text = open(path).read()
    toks = re.findall(r'"[^"]*"|\[|\]|[^\s\[\]"]+', re.sub(r"#[^\n]*", "", text))
    scene = {"meshes": [], "lights": [], "medium": None, "lookat": None, "fov": None, "maxdepth": 5}
    i = 0
    material = None
    area = None

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

    while i < len(toks):
        t = toks[i]
        if t == "LookAt":
            scene["lookat"] = [float(v) for v in toks[i + 1:i + 10]]
            i += 10
        elif t in ("Camera", "Film", "Sampler", "Integrator", "Material", "AreaLightSource",
                   "LightSource", "Shape", "MakeNamedMedium"):
            kind = toks[i + 1].strip('"')
            p, i = params(i + 2)
            if t == "Camera":
                if kind != "perspective":
                    raise SystemExit(f"{path}: camera {kind} not supported here")
                scene["fov"] = float(p.get("fov", ["90"])[0])
            elif t == "Integrator":
                scene["maxdepth"] = int(p.get("maxdepth", ["5"])[0])
            elif t == "Material":
                material = kind
                refl = [float(v) for v in p.get("reflectance", ["0.5", "0.5", "0.5"])]
                scene["_refl"] = refl
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
                    if material not in ("diffuse",):
                        raise SystemExit(f"{path}: material {material} not supported here")
                    pts = [float(v) for v in p["P"]]
                    idx = [int(v) for v in p["indices"]]
                    scene["meshes"].append({
                        "P": [pts[k:k + 3] for k in range(0, len(pts), 3)],
                        "tris": [idx[k:k + 3] for k in range(0, len(idx), 3)],
                        "refl": scene["_refl"],
                        "emit": area,
                    })
                elif kind == "sphere" and material == "interface":
                    pass  # the medium's bound: the world volume below has none
                else:
                    raise SystemExit(f"{path}: shape {kind} with {material} not supported here")
        elif t in ("AttributeBegin", "WorldBegin"):
            i += 1
            if t == "AttributeBegin":
                area = None
        elif t == "AttributeEnd":
            area = None
            i += 1
        elif t == "MediumInterface":
            i += 3
        else:
            raise SystemExit(f"{path}: directive {t} not supported here")
    return scene


CYCLES_RENDER = r'''
import bpy, math, json, sys
args = json.loads(sys.argv[-1])
sc = args["scene"]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
def vec(a): return (a[0], a[1], a[2])
for k, m in enumerate(sc["meshes"]):
    me = bpy.data.meshes.new(f"m{k}")
    me.from_pydata([vec(p) for p in m["P"]], [], [tuple(t) for t in m["tris"]])
    me.update()
    ob = bpy.data.objects.new(f"o{k}", me)
    scene.collection.objects.link(ob)
    mat = bpy.data.materials.new(f"mat{k}")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    dif = nt.nodes.new("ShaderNodeBsdfDiffuse")
    dif.inputs["Color"].default_value = (*m["refl"], 1.0)
    if m["emit"]:
        # One-sided emitter, as pbrt-v4's area lights: emission on the front face only.
        dif.inputs["Color"].default_value = (0, 0, 0, 1)
        em = nt.nodes.new("ShaderNodeEmission")
        s = max(m["emit"])
        em.inputs["Color"].default_value = (*[c / s for c in m["emit"]], 1.0)
        em.inputs["Strength"].default_value = s
        geo = nt.nodes.new("ShaderNodeNewGeometry")
        mix = nt.nodes.new("ShaderNodeMixShader")
        nt.links.new(geo.outputs["Backfacing"], mix.inputs["Fac"])
        nt.links.new(em.outputs["Emission"], mix.inputs[1])
        nt.links.new(dif.outputs["BSDF"], mix.inputs[2])
        nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    else:
        nt.links.new(dif.outputs["BSDF"], out.inputs["Surface"])
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
c.use_guiding = args["guiding"]
c.use_surface_guiding = True
c.use_volume_guiding = True
bpy.ops.render.render(write_still=True)
'''


def cycles_render(py, scene, out, res, seed, threads, seconds, spp, guiding):
    import json
    # A reference (no time limit) renders every sample: adaptive sampling would stop it at
    # Cycles' default noise threshold, far above a reference's noise.
    arg = json.dumps({"scene": scene, "out": out, "res": list(res), "seed": seed,
                      "threads": threads, "seconds": seconds, "spp": spp, "guiding": guiding,
                      "adaptive": seconds > 0})
    t = time.time()
    r = subprocess.run([py, "-c", CYCLES_RENDER, arg], capture_output=True, text=True)
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
        path = os.path.join(ROOT, "scenes", "guiding", name + ".pbrt")
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
        cr = mirrored(read_hdr(cref), *res)
        agree = (sum(cr) / len(cr)) / (sum(tr) / len(tr))
        between = rel_mse(cr, tr)
        errs = {k: [] for k in ("t_plain", "t_guided", "c_plain", "c_guided")}
        for rep in range(args.reps):
            seed = 1 + rep
            for mode in ("plain", "guided"):
                out = os.path.join(OUT, f"{tag}_t_{mode}_{rep}.hdr")
                extra = ["--time-limit", str(args.seconds)] + (["--guiding"] if mode == "guided" else [])
                trayecto_render(exe, path, out, res, seed, args.threads, extra)
                errs["t_" + mode].append(rel_mse(read_hdr(out), tr))
            for mode in ("plain", "guided"):
                out = os.path.join(OUT, f"{tag}_c_{mode}_{rep}.hdr")
                cycles_render(py, scene, out, res, seed, args.threads, args.seconds, 1 << 24,
                              mode == "guided")
                errs["c_" + mode].append(rel_mse(mirrored(read_hdr(out), *res), cr))
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
