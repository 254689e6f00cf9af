#!/usr/bin/env python3
"""Render Mitsuba 3 reference images for Trayecto's test suite.

Usage (from the repository root):

    pip install mitsuba numpy            # mitsuba 3.9.1, drjit 1.5.0 were used
    python3 scripts/references/make_references.py                  # everything
    python3 scripts/references/make_references.py --only cornell --spp 1024
    python3 scripts/references/make_references.py --variant scalar_rgb

Targets (written to tests/references/ unless --out-dir is given):
    dict            cornell_box_dict.txt   exact dump of mitsuba.cornell_box()
    cornell         cornell_128.exr        path, max_depth -1 (unlimited), rr_depth 5 (default)
    cornell_direct  cornell_128_direct.exr path, max_depth 2 (emitters seen directly + 1 bounce)

Both images: mitsuba.cornell_box() unchanged except film 128x128, rfilter box,
sampler independent; linear RGB float32 EXR with 3 channels (R, G, B); row 0
is the top of the image (ceiling), the red wall (x = -1) is on the left.
The sample budget is rendered in chunks of --chunk spp with seeds 0, 1, 2, ...
and the chunks are averaged (in float64).

Variant: llvm_ad_rgb when a libLLVM >= 16 is found (DRJIT_LIBLLVM_PATH is set
automatically for Debian's libllvm19: `apt-get install -y libllvm19`; the
system's libLLVM-15 makes drjit abort), otherwise scalar_rgb. RGB variants only,
so the results are comparable with an RGB renderer.

Timings of the committed references (2-core x86-64 VM, no GPU, llvm_ad_rgb,
65536 spp, 64 chunks of 1024 spp): cornell 540 s, cornell_direct 179 s.
(scalar_rgb is ~4x slower: 64 spp of `cornell` take ~1.5 s.)
"""
import argparse
import glob
import os
import pprint
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_OUT = os.path.normpath(os.path.join(HERE, "..", "..", "tests", "references"))
SIZE = 128


def find_libllvm():
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return os.environ["DRJIT_LIBLLVM_PATH"]
    cands = []
    for pat in ("/usr/lib/x86_64-linux-gnu/libLLVM.so.*", "/usr/lib/x86_64-linux-gnu/libLLVM-*.so*",
                "/usr/lib/llvm-*/lib/libLLVM*.so*", "/usr/local/lib/libLLVM*.so*",
                "/opt/homebrew/opt/llvm/lib/libLLVM.dylib"):
        cands += glob.glob(pat)
    best = None
    for c in cands:
        digits = "".join(ch if ch.isdigit() else " " for ch in os.path.basename(c) + " " + c).split()
        major = max((int(d) for d in digits if 10 <= int(d) <= 40), default=0)
        if major >= 16 and (best is None or major > best[0]):
            best = (major, c)
    return best[1] if best else None


def pick_variant(requested):
    if requested != "auto":
        return requested
    lib = find_libllvm()
    if lib:
        os.environ["DRJIT_LIBLLVM_PATH"] = lib
        return "llvm_ad_rgb"
    return "scalar_rgb"


def scene_dict(mi, max_depth):
    d = mi.cornell_box()
    film = d["sensor"]["film"]
    film["width"] = SIZE
    film["height"] = SIZE
    film["rfilter"] = {"type": "box"}
    d["sensor"]["sampler"] = {"type": "independent", "sample_count": 1}
    d["integrator"] = {"type": "path", "max_depth": max_depth}  # rr_depth default (5)
    return d


def render_chunked(mi, np, scene, spp, chunk, width, height, name=None):
    """Renders `spp` samples in chunks of `chunk` spp with seeds 0, 1, ..., averaged in float64
    (shared with make_material_references.py). Returns (float32 image, chunks, seconds)."""
    acc = np.zeros((height, width, 3), dtype=np.float64)
    done, seed, t0 = 0, 0, time.time()
    while done < spp:
        n = min(chunk, spp - done)
        img = np.array(mi.render(scene, spp=n, seed=seed), dtype=np.float64)
        assert img.shape == (height, width, 3), img.shape
        acc += img * n
        done += n
        seed += 1
        if name is not None:
            el = time.time() - t0
            print(f"  [{name}] {done}/{spp} spp, {el:.1f} s, eta {el / done * (spp - done):.0f} s", flush=True)
    return (acc / spp).astype(np.float32), seed, time.time() - t0


def render(mi, np, name, max_depth, spp, chunk, out_dir):
    scene = mi.load_dict(scene_dict(mi, max_depth))
    img, seed, elapsed = render_chunked(mi, np, scene, spp, chunk, SIZE, SIZE, name)
    nonfinite = int((~np.isfinite(img)).sum())
    path = os.path.join(out_dir, f"{name}.exr")
    mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB).write(path)
    print(f"{name}: wrote {path} ({os.path.getsize(path)} bytes)")
    print(f"  variant {mi.variant()}, max_depth {max_depth}, spp {spp} ({seed} chunks), render {elapsed:.1f} s")
    print(f"  channel mean R G B = {img.reshape(-1, 3).mean(0).tolist()}  non-finite: {nonfinite}")
    for (x, y) in [(64, 64), (10, 64), (117, 64), (64, 10), (64, 120)]:
        print(f"  pixel (x={x}, y={y}) = {img[y, x].tolist()}")
    left, right = img[32:96, 2:8].mean((0, 1)), img[32:96, 120:126].mean((0, 1))
    top, bottom = img[0:3, 40:88].mean((0, 1)), img[124:128, 40:88].mean((0, 1))
    print(f"  left cols mean {left.tolist()}  right cols mean {right.tolist()}")
    print(f"  top rows mean {top.tolist()}  bottom rows mean {bottom.tolist()}")
    print(f"  red wall on the left: {bool(left[0] > left[1] and right[1] > right[0])}; "
          f"row 0 is the ceiling (dimmer than floor): {bool(top.sum() < bottom.sum())}")
    return img


def fmt_transform(t):
    import numpy as np
    m = np.array(t.matrix, dtype=np.float64).reshape(4, 4)
    return "[" + ",\n     ".join("[" + ", ".join(f"{v:.9g}" for v in row) + "]" for row in m) + "]"


def dump_dict(mi, np, out_dir):
    d = mi.cornell_box()
    lines = []
    w = lines.append
    w(f"# mitsuba.cornell_box() as returned by mitsuba {mi.__version__} (variant {mi.variant()})")
    w("# Generated by scripts/references/make_references.py. Matrices are row-major 4x4 (to_world, applied to")
    w("# column vectors: p_world = M * p_local).")
    w("")
    w("## Raw dict (pprint)")
    w(pprint.pformat(d, width=110))
    w("")
    w("## Derived facts")
    s = d["sensor"]
    w(f"sensor: type {s['type']}, fov {s['fov']} deg, fov_axis {s['fov_axis']}, near_clip {s['near_clip']}, "
      f"far_clip {s['far_clip']}, focus_distance {s['focus_distance']}")
    w(f"sensor to_world = {fmt_transform(s['to_world'])}")
    C = np.array(s["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    w(f"camera origin (world) = {C[:3, 3].tolist()}; view direction = {C[:3, 2].tolist()} (local +z); "
      f"up = {C[:3, 1].tolist()} (local +y); local +x -> {C[:3, 0].tolist()}")
    w("  square film with fov_axis 'smaller' -> vertical fov = horizontal fov = 39.3077 deg.")
    w("  Verified by rendering: red wall (x=-1) appears on the LEFT, image row 0 is the TOP (ceiling).")
    w(f"default film: {s['film']['width']}x{s['film']['height']}, rfilter {s['film']['rfilter']['type']}; "
      f"default sampler {s['sampler']}; default integrator {d['integrator']}")
    w("  (the references override: 128x128, rfilter box, sampler independent, integrator path max_depth -1 / 2)")
    w("")
    w("BSDFs (all 'diffuse', i.e. Lambertian, ONE-SIDED in Mitsuba: back-face hits reflect nothing):")
    for k in ("white", "red", "green"):
        w(f"  {k}: reflectance rgb {d[k]['reflectance']['value']}")
    w("")
    w("Shapes. 'rectangle' = the square [-1,1]^2 in the local z=0 plane, normal +z (analytic shape).")
    w("        'cube' = mesh of [-1,1]^3 with outward normals.")
    for k, v in d.items():
        if not isinstance(v, dict) or "to_world" not in v or k == "sensor":
            continue
        t = v["to_world"]
        M = np.array(t.matrix, dtype=np.float64).reshape(4, 4)
        c = M[:3, 3]
        n = np.linalg.inv(M[:3, :3]).T @ np.array([0.0, 0.0, 1.0])
        n = n / np.linalg.norm(n)
        bsdf = v.get("bsdf", {}).get("id")
        w(f"{k}: type {v['type']}, bsdf {bsdf}")
        w(f"  to_world = {fmt_transform(t)}")
        if v["type"] == "rectangle":
            ex, ey = np.linalg.norm(M[:3, 0]) * 2, np.linalg.norm(M[:3, 1]) * 2
            w(f"  centre {c.round(9).tolist()}, normal {n.round(6).tolist()}, size {ex:.6g} x {ey:.6g} "
              f"(local x axis -> {M[:3, 0].round(9).tolist()}, local y axis -> {M[:3, 1].round(9).tolist()})")
        if "emitter" in v:
            e = v["emitter"]
            w(f"  emitter: type {e['type']} (one-sided, emits on the +normal side), "
              f"radiance rgb {e['radiance']['value']}")
            w(f"  the light rectangle ALSO has a BSDF: '{bsdf}' (one-sided diffuse, so its front reflects"
              f" like the white walls; its back, facing the ceiling 0.01 above, is black)")
    w("")
    w("Notes:")
    w("  - The light is a separate rectangle hanging 0.01 below the ceiling (the ceiling has no hole).")
    w("  - All walls face inward; boxes face outward. The only back face that paths can reach is the top of")
    w("    the light rectangle (facing the ceiling 0.01 above; that gap is nearly unlit), so Trayecto's")
    w("    two-sided shading vs Mitsuba's one-sided diffuse makes a negligible difference on this scene.")
    w("  - Mitsuba path max_depth counts path vertices incl. the emitter: max_depth 1 = emitters seen")
    w("    directly, 2 = direct lighting, -1 = unlimited. Trayecto --max-depth N <-> Mitsuba max_depth N+1.")
    path = os.path.join(out_dir, "cornell_box_dict.txt")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"dict: wrote {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spp", type=int, default=65536, help="samples per pixel (default 65536)")
    ap.add_argument("--chunk", type=int, default=1024, help="spp per render call / seed (default 1024)")
    ap.add_argument("--only", choices=["dict", "cornell", "cornell_direct"], help="render a single target")
    ap.add_argument("--variant", default="auto", help="mitsuba variant (auto: llvm_ad_rgb if LLVM>=16 else scalar_rgb)")
    ap.add_argument("--out-dir", default=DEFAULT_OUT)
    args = ap.parse_args()

    variant = pick_variant(args.variant)
    import mitsuba as mi
    import numpy as np
    mi.set_variant(variant)
    os.makedirs(args.out_dir, exist_ok=True)
    print(f"mitsuba {mi.__version__}, variant {variant}, spp {args.spp}, chunk {args.chunk}")

    want = lambda n: args.only in (None, n)
    if want("dict"):
        dump_dict(mi, np, args.out_dir)
    if want("cornell"):
        render(mi, np, "cornell_128", -1, args.spp, args.chunk, args.out_dir)
    if want("cornell_direct"):
        render(mi, np, "cornell_128_direct", 2, args.spp, args.chunk, args.out_dir)


if __name__ == "__main__":
    sys.exit(main())
