#!/usr/bin/env python3
"""Path guiding at equal SAMPLES: relMSE and the per-pixel tail of a guided (or unguided) render.

Usage (from the repository root, after `cargo build --release` and a reference made by
bench/guiding.py, which caches it in bench/out/guiding/):

    python3 bench/guiding_samples.py target/release/trayecto veach-ajar 64 1,2,3 amin3 \\
        TRAYECTO_GUIDING_ALPHA_MIN=0.3           # guided, with a knob
    python3 bench/guiding_samples.py target/release/trayecto veach-ajar 64 1,2,3 plain --plain

Options: --res WxH (96x72), --threads N (2), --refspp N (2048: the reference's samples),
--ref FILE (a reference of your own instead, e.g. one rendered with the same --max-depth),
--max-depth D (passed to every render: 2 keeps direct light and one indirect bounce).
For each seed: render --spp SPP --seed S [--guiding] with the KEY=VALUE environment, and print
relMSE (RGB, as bench/compare.py and bench/guiding.py) and the luminance relMSE's per-pixel
median, 90th and 99th percentiles, maximum and mean without the worst 0.5 % of pixels (the
mean is set by the top pixels), and the
share of the RGB relMSE in the ten worst pixels with the first three of them (x, y, error).
"""
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import guiding as G  # noqa: E402


def main():
    args = sys.argv[1:]
    plain = "--plain" in args
    args = [a for a in args if a != "--plain"]
    opts = {"--res": "96x72", "--threads": "2", "--refspp": "2048", "--ref": None,
            "--max-depth": None}
    for flag in list(opts):
        if flag in args:
            i = args.index(flag)
            opts[flag] = args[i + 1]
            del args[i:i + 2]
    if len(args) < 5:
        sys.exit(__doc__)
    exe, scene, spp, seeds, label = args[:5]
    env = dict(os.environ)
    for kv in args[5:]:
        k, v = kv.split("=", 1)
        env[k] = v
    res = opts["--res"]
    w, h = res.split("x")
    ref = G.read_hdr(opts["--ref"] or
                     os.path.join(G.OUT, f"ref_{scene}_{res}_{opts['--refspp']}.hdr"))

    def lum(img):
        return [0.2126 * img[i] + 0.7152 * img[i + 1] + 0.0722 * img[i + 2]
                for i in range(0, len(img), 3)]

    rl = lum(ref)
    for seed in seeds.split(","):
        out = os.path.join(G.OUT, f"samples_{scene}_{res}_{label}_{seed}.hdr")
        cmd = [exe, "render", G.SCENES.get(scene, scene), "-o", out, "--width", w, "--height", h,
               "--spp", spp, "--seed", seed, "--threads", opts["--threads"], "--quiet"]
        if not plain:
            cmd.append("--guiding")
        if opts["--max-depth"]:
            cmd += ["--max-depth", opts["--max-depth"]]
        t = time.time()
        subprocess.run(cmd, check=True, env=env)
        t = time.time() - t
        img = G.read_hdr(out)
        e = G.rel_mse(img, ref)
        per = [(x - r) ** 2 / (r * r + 0.01) for x, r in zip(lum(img), rl)]
        pp = sorted(per)

        def q(f):
            return pp[min(len(pp) - 1, int(f * len(pp)))]

        # The worst pixels by their RGB relMSE (the mean's terms).
        rgb = [sum((img[3 * i + c] - ref[3 * i + c]) ** 2 / (ref[3 * i + c] ** 2 + 0.01)
                   for c in range(3)) / 3 for i in range(len(rl))]
        width = int(w)
        worst = sorted(range(len(rgb)), key=lambda i: -rgb[i])[:10]
        share = sum(rgb[i] for i in worst) / max(sum(rgb), 1e-30)
        top = [(i % width, i // width, round(rgb[i])) for i in worst[:3]]
        print(f"{scene} {label} seed {seed}: relMSE {e:.4g} p50 {q(0.5):.3g} p90 {q(0.9):.3g} "
              f"p99 {q(0.99):.3g} max {pp[-1]:.3g} "
              f"mean without the top 0.5 % {sum(pp[:int(0.995 * len(pp))]) / int(0.995 * len(pp)):.3g} "
              f"top-10 share {share:.2f} {top} "
              f"time {t:.1f}s", flush=True)


if __name__ == "__main__":
    main()
