#!/usr/bin/env python3
"""Time x error of two Trayecto binaries on the models lit by the default uniform environment.

Why: Trayecto samples the uniform environment (`Light::Uniform`, the model-viewer default
light of glTF models without lamps) cosine-weighted over the hemisphere of an opaque vertex's
geometric normal instead of uniformly over the sphere (src/light/mod.rs `sample_uniform_env`).
That changes the noise, not the expected image, so it must be judged by error at equal time.

For each scene, resolution and spp it renders with every binary, interleaved (the order flips
every round), one seed per round shared by the binaries (paired), and scores the relMSE
(compare.py's: mean of (x - ref)^2 / (ref^2 + 1e-2)) against one reference made once with
`--ref-bin` at `--ref-spp` (cached under bench/out/env_hemi/). Reports the mean relMSE, the
median render time (the CLI's phase report), rays per sample, and the efficiency ratio
(time x relMSE of the first binary over that of each other one; > 1: the other is better),
as the median and range over the rounds' paired ratios.

Usage (bench/out/venv has numpy and Mitsuba, whose EXR reader compare.py uses):

    nice bench/out/venv/bin/python bench/env_hemi_error.py --bins BASE \
        target/release/trayecto --rounds 5
"""
import argparse
import os
import statistics
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402  (run_trayecto, read_exr_rgb, rel_mse)

SHARED = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "scenes"))
SCENES = {
    "toycar": os.path.join(SHARED, "gltf-ext", "ToyCar", "glTF", "ToyCar.gltf"),
    "helmet": os.path.join(SHARED, "gltf", "DamagedHelmet", "glTF", "DamagedHelmet.gltf"),
    # compare.py's many-light scenes (exported there into bench/out/), for the light BVH's width
    # (four or eight children per node: `--light-sampler bvh` or `bvh8`).
    "veach": os.path.join(HERE, "out", "veach", "veach.glb"),
    "manylight": os.path.join(HERE, "out", "manylight", "manylight.glb"),
}
OUT = os.path.join(HERE, "out", "env_hemi")


def render(exe, scene, res, spp, seed, threads, out):
    import numpy as np
    t, rays = compare.run_trayecto(exe, scene, out, (res, res), spp, seed, threads)
    return compare.read_exr_rgb(out).astype(np.float64), t, rays


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bins", nargs="+", required=True, help="binaries; the first is the baseline")
    ap.add_argument("--scenes", default="toycar,helmet")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spps", default="16,64")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--ref-bin", default=None,
                    help="binary of the references (default: the first of --bins)")
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    args.ref_bin = args.ref_bin or args.bins[0]
    import numpy as np
    os.makedirs(OUT, exist_ok=True)
    bins = [os.path.abspath(b) for b in args.bins]
    spps = [int(s) for s in args.spps.split(",")]
    for name in args.scenes.split(","):
        scene = SCENES[name]
        ref_path = os.path.join(OUT, f"ref_{name}_{args.res}_{args.ref_spp}.npy")
        if not os.path.exists(ref_path):
            print(f"[{name}] reference: {args.ref_spp} spp with {args.ref_bin}", flush=True)
            ref, t, _ = render(args.ref_bin, scene, args.res, args.ref_spp, 99991, args.threads,
                               os.path.join(OUT, f"ref_{name}.exr"))
            np.save(ref_path, ref)
            print(f"[{name}] reference took {t:.1f} s", flush=True)
        ref = np.load(ref_path)
        for spp in spps:
            # res[b] = list of (relMSE, time, rays per sample), one per round.
            res = {b: [] for b in bins}
            for r in range(args.rounds):
                order = bins if r % 2 == 0 else bins[::-1]
                for b in order:
                    img, t, rays = render(b, scene, args.res, spp, 1 + r, args.threads,
                                          os.path.join(OUT, "x.exr"))
                    res[b].append((compare.rel_mse(img, ref), t, rays / (args.res * args.res * spp)))
            base = res[bins[0]]
            print(f"\n{name} {args.res}x{args.res}, {spp} spp, {args.rounds} rounds (seeds 1..{args.rounds}), "
                  f"reference {args.ref_spp} spp")
            print("| binary | relMSE (mean) | time (median) | rays/sample | efficiency vs first (median, range) |")
            print("|---|---|---|---|---|")
            for b in bins:
                rows = res[b]
                ratios = sorted((bb[0] * bb[1]) / (x[0] * x[1]) for x, bb in zip(rows, base))
                e = statistics.fmean(x[0] for x in rows)
                t = statistics.median(x[1] for x in rows)
                rps = statistics.fmean(x[2] for x in rows)
                print(f"| {b} | {e:.5f} | {t:.3f} s | {rps:.2f} | {statistics.median(ratios):.2f}x "
                      f"({ratios[0]:.2f}-{ratios[-1]:.2f}) |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
