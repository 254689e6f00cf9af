#!/usr/bin/env python3
"""Texture filtering: error per sample and time x error of `--texture-filter
trilinear` against `none` on a textured model (DamagedHelmet: 2048^2 albedo, normal, emissive and
metal-roughness maps, so a small image minifies them strongly).

Two references, both at --ref-spp:
  * `none`: the box-filtered pixel integral of the unfiltered texture (what the image converges to
    without filtering; filtering blurs slightly against it, so its error has a floor);
  * `trilinear`: the same filtered model (what a filtered render converges to).
relMSE = mean((x - ref)^2 / (ref^2 + 1e-2)) over pixels and channels (compare.py's measure).
Renders are interleaved (none, trilinear, none, ...) for --rounds rounds; the table gives the
median and the spread (min-max) of render time and relMSE.

  python3 bench/texture_filter.py [--res 96] [--spp 1,4,16] [--ref-spp 512] [--rounds 2]
"""
import argparse
import os
import statistics
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402  (the trayecto build, EXR reading)

OUT = os.path.join(compare.OUT, "texture_filter")
SCENE = os.path.join(compare.ROOT, "..", "shared", "scenes", "gltf", "DamagedHelmet", "glTF-Binary",
                     "DamagedHelmet.glb")
MODES = ("none", "trilinear")


def relmse(x, ref):
    return float((((x - ref) ** 2) / (ref ** 2 + 1e-2)).mean())


def render(args, mode, spp, seed, name):
    out = os.path.join(OUT, f"{name}.exr")
    t, _ = compare.run_trayecto(args.exe, SCENE, out, args.res, spp, seed, args.threads,
                                extra=("--texture-filter", mode))
    return t, compare.read_exr_rgb(out).astype("float64")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--res", type=int, default=96)
    ap.add_argument("--spp", default="1,4,16")
    ap.add_argument("--ref-spp", type=int, default=512)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--trayecto-bin", help="use this binary instead of building one")
    args = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)
    args.exe = os.path.abspath(args.trayecto_bin) if args.trayecto_bin else compare.build_trayecto()[0]
    refs = {m: render(args, m, args.ref_spp, 1000, f"ref-{m}")[1] for m in MODES}
    print(f"DamagedHelmet {args.res}^2, references {args.ref_spp} spp; "
          f"relMSE(trilinear ref vs none ref) = {relmse(refs['trilinear'], refs['none']):.5f} (the blur)")
    print("| spp | filter | time s (median, min-max) | relMSE vs none ref | relMSE vs same-model ref "
          "| time x relMSE (same model) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for spp in [int(s) for s in args.spp.split(",")]:
        res = {m: ([], [], []) for m in MODES}
        for r in range(args.rounds):
            for m in MODES:
                t, img = render(args, m, spp, r + 1, f"{m}-{spp}-{r}")
                res[m][0].append(t)
                res[m][1].append(relmse(img, refs["none"]))
                res[m][2].append(relmse(img, refs[m]))
        for m in MODES:
            ts, e_pix, e_same = res[m]
            tm, es = statistics.median(ts), statistics.median(e_same)
            print(f"| {spp} | {m} | {tm:.3f} ({min(ts):.3f}-{max(ts):.3f}) "
                  f"| {statistics.median(e_pix):.5f} ({min(e_pix):.5f}-{max(e_pix):.5f}) "
                  f"| {es:.5f} ({min(e_same):.5f}-{max(e_same):.5f}) | {tm * es:.6f} |", flush=True)


if __name__ == "__main__":
    main()
