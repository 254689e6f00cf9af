#!/usr/bin/env python3
"""Error per sample of every sampler: Trayecto's, Mitsuba 3's and pbrt-v4's, on the same scenes.

Usage (from the repository root):

    python3 bench/sampler_error.py                          # direct lighting (max depth 1), 64x64
    python3 bench/sampler_error.py --depth full             # whole paths
    python3 bench/sampler_error.py --scenes veach-mis --spp 4,16,64 --seeds 4 \
        --renderers trayecto:stratified,trayecto:zsobol,pbrt:zsobol

Scenes: `cornell` (Trayecto's built-in box = Mitsuba's `cornell_box()`; its light is one
rectangle in Mitsuba and a quad in Trayecto), `veach-mis` and `cornell-box` (the Bitterli pbrt-v4
files in ../shared/scenes/pbrt, rendered by Trayecto and by pbrt-v4 from the same edited copy:
resolution, box pixel filter of radius 0.5, the sampler, the max depth). A renderer that cannot
read a scene is skipped.

For each renderer:sampler, scene and spp it renders --seeds seeds and reports the mean relMSE
(bench/compare.py's: mean of (x - ref)^2 / (ref^2 + 1e-2)) against that renderer's OWN reference
(--ref-spp, its default sampler, another seed), so it measures noise, not model differences, and
relMSE x spp (lower is better; constant for a sampler whose error falls as 1/spp). Everything
generated goes to bench/out/sampler_error/ (gitignored). Render times are not reported: this
measures sample quality; speed is measured by callgrind (see BENCHMARKS.md).
"""
import argparse
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402  (module installs, the trayecto build, EXR reading, relMSE)

OUT = os.path.join(compare.OUT, "sampler_error")
PBRT = os.path.join(compare.ROOT, "..", "shared", "tools", "pbrt-v4", "pbrt")
PBRT_SCENES = {
    "veach-mis": os.path.join(compare.ROOT, "..", "shared", "scenes", "pbrt", "veach-mis", "scene-v4.pbrt"),
    "cornell-box": os.path.join(compare.ROOT, "..", "shared", "scenes", "pbrt", "cornell-box", "scene-v4.pbrt"),
}
# veach-mis with each light sphere tessellated into a triangle mesh (48 x 24 segments), so
# every light is ~2000 emitting triangles, as in a glTF scene (bench/compare.py's veach).
PBRT_SCENES["veach-mis-mesh"] = PBRT_SCENES["veach-mis"]


def sphere_mesh(radius, n_seg=48, n_ring=24):
    """A pbrt trianglemesh of a UV sphere (outward winding)."""
    verts, faces = compare.uv_sphere(n_seg, n_ring)
    tris = []
    for f in faces:
        tris += [(f[0], f[i], f[i + 1]) for i in range(1, len(f) - 1)]
    p = " ".join(f"{radius * x:.6g} {radius * y:.6g} {radius * z:.6g}" for x, y, z in verts)
    n = " ".join(f"{x:.6g} {y:.6g} {z:.6g}" for x, y, z in verts)
    idx = " ".join(f"{a} {c} {b}" for a, b, c in tris)
    return f'Shape "trianglemesh" "point3 P" [ {p} ] "normal N" [ {n} ] "integer indices" [ {idx} ]'

DEFAULT_RENDERERS = ("trayecto:independent,trayecto:stratified,trayecto:sobol,trayecto:zsobol,"
                     "mitsuba:independent,mitsuba:stratified,mitsuba:multijitter,mitsuba:ldsampler,"
                     "pbrt:independent,pbrt:pmj02bn,pbrt:sobol,pbrt:zsobol")


def pbrt_copy(scene, res, sampler, depth):
    """The pbrt file with the film, filter, sampler and depth replaced; written to OUT."""
    text = open(PBRT_SCENES[scene]).read()
    head, sep, world = text.partition("WorldBegin")
    # Drop the options the copy sets (each directive runs until the next capitalised directive).
    for d in ("Sampler", "PixelFilter", "Film", "Integrator"):
        head = re.sub(r'(?m)^\s*' + d + r'\b[^A-Z#]*(#[^\n]*\n[^A-Z#]*)*', "", head)
    maxdepth = 1 if depth == "direct" else 8
    opts = (f'Integrator "path" "integer maxdepth" [ {maxdepth} ]\n'
            f'Sampler "{sampler}" "integer pixelsamples" [ 16 ]\n'
            'PixelFilter "box" "float xradius" [ 0.5 ] "float yradius" [ 0.5 ]\n'
            f'Film "rgb" "string filename" [ "unused.exr" ] "integer xresolution" [ {res} ] '
            f'"integer yresolution" [ {res} ]\n')
    if scene.endswith("-mesh"):
        world = re.sub(r'Shape "sphere"\s*"float radius" \[ ([0-9.eE+-]+) \]',
                       lambda m: sphere_mesh(float(m.group(1))), world)
    path = os.path.join(OUT, f"{scene}-{sampler}-{depth}.pbrt")
    with open(path, "w") as f:
        f.write(opts + head + sep + world)
    return path


def render(renderer, sampler, scene, spp, seed, args):
    """One image as a float64 (h, w, 3) array, or raises."""
    import numpy as np
    out = os.path.join(OUT, f"{renderer}-{sampler}-{scene}.exr")
    if renderer == "trayecto":
        if scene in PBRT_SCENES:
            src = pbrt_copy(scene, args.res, "independent", args.depth)
        elif scene == "cornell":
            src = "cornell"
        else:
            raise RuntimeError("unknown scene")
        extra = ["--sampler", sampler, "--filter", "box"]
        if args.depth == "direct":
            extra += ["--max-depth", "1"]
        elif scene == "cornell":
            extra += ["--max-depth", "8"]
        compare.run_trayecto(args.exe, src, out, args.res, spp, seed, args.threads, extra)
        return compare.read_exr_rgb(out).astype(np.float64)
    if renderer == "pbrt":
        if scene not in PBRT_SCENES:
            raise RuntimeError("pbrt-v4 reads pbrt files only")
        src = pbrt_copy(scene, args.res, sampler, args.depth)
        r = subprocess.run([PBRT, "--nthreads", str(args.threads), "--spp", str(spp), "--seed", str(seed),
                            "--outfile", out, "--quiet", src], capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError((r.stderr.strip().splitlines() or ["exit %d" % r.returncode])[-1])
        return compare.read_exr_rgb(out).astype(np.float64)
    if renderer == "mitsuba":
        if scene != "cornell":
            raise RuntimeError("Mitsuba: only the built-in Cornell box")
        import mitsuba as mi
        d = mi.cornell_box()
        d["sensor"]["film"].update({"width": args.res, "height": args.res, "rfilter": {"type": "box"}})
        d["sensor"]["sampler"] = {"type": sampler, "sample_count": spp}
        d["integrator"] = {"type": "path", "max_depth": 2 if args.depth == "direct" else 9}
        sc = mi.load_dict(d)
        if sc.sensors()[0].sampler().sample_count() != spp:
            raise RuntimeError(f"{sampler} rounds {spp} spp")
        return np.array(mi.render(sc, spp=spp, seed=seed), dtype=np.float64)[:, :, :3]
    raise RuntimeError(f"unknown renderer {renderer}")


DEFAULT_SAMPLER = {"trayecto": "independent", "pbrt": "independent", "mitsuba": "independent"}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="cornell,veach-mis,veach-mis-mesh,cornell-box")
    ap.add_argument("--renderers", default=DEFAULT_RENDERERS)
    ap.add_argument("--depth", choices=["direct", "full"], default="direct")
    ap.add_argument("--spp", default="4,16,64")
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--trayecto-bin", default=None)
    args = ap.parse_args()
    if not (compare.ensure_module("numpy", "numpy") and compare.ensure_module("mitsuba", "mitsuba")):
        return 1
    import numpy as np
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    os.makedirs(OUT, exist_ok=True)
    args.exe = os.path.abspath(args.trayecto_bin) if args.trayecto_bin else compare.build_trayecto()[0]
    ladder = [int(s) for s in args.spp.split(",")]
    rows = []
    for scene in args.scenes.split(","):
        refs = {}
        for rs in args.renderers.split(","):
            renderer, sampler = rs.split(":")
            if (renderer == "pbrt") != (scene in PBRT_SCENES) and renderer != "trayecto":
                continue  # pbrt-v4 reads only the pbrt files, Mitsuba only the built-in box
            try:
                if renderer not in refs:
                    rp = os.path.join(OUT, f"ref-{renderer}-{scene}-{args.depth}-{args.res}-{args.ref_spp}.npy")
                    if not os.path.exists(rp):
                        print(f"[{scene}] {renderer} reference, {args.ref_spp} spp", flush=True)
                        np.save(rp, render(renderer, DEFAULT_SAMPLER[renderer], scene, args.ref_spp, 99991, args))
                    refs[renderer] = np.load(rp)
                errs = []
                for spp in ladder:
                    e = [compare.rel_mse(render(renderer, sampler, scene, spp, seed, args), refs[renderer])
                         for seed in range(1, args.seeds + 1)]
                    errs.append(float(np.mean(e)))
                rows.append((scene, rs, errs))
                print(f"| {scene} | {rs} | " + " | ".join(f"{e:.3g} ({e * s:.3g})" for e, s in zip(errs, ladder))
                      + " |", flush=True)
            except Exception as ex:  # noqa: BLE001  (a renderer that cannot do a scene is skipped)
                print(f"| {scene} | {rs} | n/a: {ex} |", flush=True)
    print(f"\nrelMSE (relMSE x spp) at {args.res}x{args.res}, depth {args.depth}, mean of {args.seeds} seeds, "
          f"against each renderer's own {args.ref_spp}-spp reference")
    print("| scene | renderer:sampler | " + " | ".join(f"{s} spp" for s in ladder) + " |")
    print("|---|---|" + "---|" * len(ladder))
    for scene, rs, errs in rows:
        print(f"| {scene} | {rs} | " + " | ".join(f"{e:.3g} ({e * s:.3g})" for e, s in zip(errs, ladder)) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
