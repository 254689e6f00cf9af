#!/usr/bin/env python3
"""Error per sample over many seeds: relMSE of K renders at N spp against one high-spp
reference, for one or more Trayecto binaries (the same seeds for each, so the comparison is
paired) and optionally Mitsuba 3 llvm_ad_rgb with a given sampler (scored against its own
reference).

Why: compare.py scores ONE render per ladder point against a 512-spp reference. Where fireflies
dominate the error (the envlit scene: caustics through the rough metal ball, diffuse -> glossy ->
studio lamp) a single render's relMSE is a heavy-tailed draw (0.03 to 0.18 for 64-spp renders of
the same scene with different seeds), and the 512-spp reference has fireflies of its own. The mean
over seeds, against a reference 16x deeper, is the error per sample; its standard error is
printed beside it.

Usage (after `python3 bench/compare.py --quick --scenes envlit ...` made bench/out/envlit/):

    bench/out/venv/bin/python bench/seed_error.py --scene envlit --bins OLD NEW --seeds 32 \
        --mitsuba multijitter

The relMSE is compare.py's: mean over pixels and channels of (x - ref)^2 / (ref^2 + 1e-2).
Every render is 64 x 64 pixels (compare.py's quick mode), 2 threads, box filter.
"""
import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402  (scene descriptions, the Trayecto command line, Mitsuba's scene dict)

OUT = os.path.join(HERE, "out", "seed_error")


def trayecto_render(binary, scene, spp, seed, res, out):
    import numpy as np
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    extra = []
    if scene == "envlit":
        extra = ["--env", compare.trayecto_env(mi, np)]
    path = "cornell" if scene == "cornell" else os.path.join(compare.OUT, scene, f"{scene}.glb")
    exr = out[:-4] + ".exr"
    compare.run_trayecto(binary, path, exr, (res, res), spp, seed, 2, extra)
    img = compare.read_exr_rgb(exr).astype(np.float64)
    np.save(out, img)
    return img


def mitsuba_renders(sampler, scene, spp, seeds, ref_spp, res):
    lib = compare.find_libllvm()
    if lib:
        os.environ["DRJIT_LIBLLVM_PATH"] = lib
    import drjit as dr
    import mitsuba as mi
    import numpy as np
    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(2)
    sc = mi.load_dict(compare.mitsuba_scene_dict(mi, scene, res, sampler))

    def render(seed, n_spp):
        acc, done = None, 0
        while done < n_spp:
            n = min(1024, n_spp - done)
            img = np.array(mi.render(sc, spp=n, seed=seed * 8191 + done), dtype=np.float64)[:, :, :3]
            acc = img * n if acc is None else acc + img * n
            done += n
        return acc / n_spp

    ref_path = os.path.join(OUT, f"{scene}_mitsuba_{sampler}_{res}px_{ref_spp}spp_ref.npy")
    if not os.path.exists(ref_path):
        np.save(ref_path, render(99_991, ref_spp))
    return np.load(ref_path), [render(s, spp) for s in seeds]


def rel_mse(x, ref):
    import numpy as np
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 1e-2)))


def summary(name, errs):
    import numpy as np
    e = np.array(errs)
    return {"name": name, "mean": float(e.mean()), "stderr": float(e.std(ddof=1) / np.sqrt(len(e))),
            "median": float(np.median(e)), "min": float(e.min()), "max": float(e.max())}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="envlit")
    ap.add_argument("--bins", nargs="+", required=True, help="Trayecto binaries; the first renders the reference")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--seeds", type=int, default=32)
    ap.add_argument("--ref-spp", type=int, default=8192)
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--mitsuba", default=None, help="also Mitsuba llvm_ad_rgb with this sampler")
    args = ap.parse_args()
    import numpy as np
    os.makedirs(OUT, exist_ok=True)
    seeds = list(range(1, args.seeds + 1))
    ref_path = os.path.join(OUT, f"{args.scene}_trayecto_{args.res}px_{args.ref_spp}spp_ref.npy")
    if not os.path.exists(ref_path):
        print(f"reference: {args.bins[0]} at {args.ref_spp} spp", flush=True)
        trayecto_render(args.bins[0], args.scene, args.ref_spp, 999_983, args.res, ref_path)
    ref = np.load(ref_path)
    rows = []
    for i, b in enumerate(args.bins):
        errs, total = [], None
        for s in seeds:
            img = trayecto_render(b, args.scene, args.spp, s, args.res, os.path.join(OUT, f"bin{i}_{s}.npy"))
            errs.append(rel_mse(img, ref))
            total = img if total is None else total + img
        row = summary(f"trayecto {b}", errs)
        # Bias check: the mean of all renders (K x spp samples) against the reference.
        row["mean_of_renders_relmse"] = rel_mse(total / len(seeds), ref)
        row["mean_rgb_ratio"] = [float(v) for v in (total / len(seeds)).mean(axis=(0, 1)) / ref.mean(axis=(0, 1))]
        row["per_seed"] = errs
        rows.append(row)
    if args.mitsuba:
        mref, imgs = mitsuba_renders(args.mitsuba, args.scene, args.spp, seeds, args.ref_spp, args.res)
        row = summary(f"mitsuba llvm_ad_rgb {args.mitsuba}", [rel_mse(x, mref) for x in imgs])
        row["mean_of_renders_relmse"] = rel_mse(sum(imgs) / len(imgs), mref)
        rows.append(row)
    print(f"\n{args.scene}, {args.res} px, {args.spp} spp, {len(seeds)} seeds (1..{len(seeds)}), "
          f"references {args.ref_spp} spp")
    print("| renderer | mean relMSE ± s.e. | median | min–max | relMSE of the mean of all renders |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['name']} | {r['mean']:.4f} ± {r['stderr']:.4f} | {r['median']:.4f} | "
              f"{r['min']:.4f}–{r['max']:.4f} | {r['mean_of_renders_relmse']:.5f} |")
    if len(args.bins) > 1:
        a, b = np.array(rows[0]["per_seed"]), np.array(rows[1]["per_seed"])
        d = b - a
        print(f"paired (bin1 - bin0): mean {d.mean():+.4f} ± {d.std(ddof=1) / np.sqrt(len(d)):.4f}, "
              f"bin1 lower on {(d < 0).sum()} of {len(d)} seeds")
    with open(os.path.join(OUT, f"{args.scene}_summary.json"), "w") as f:
        json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
