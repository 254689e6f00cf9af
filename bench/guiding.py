#!/usr/bin/env python3
"""Path guiding at equal wall-clock time: relMSE of `--guiding` against the unguided path tracer.

Usage (from the repository root, after `cargo build --release`):

    nice -n 10 python3 bench/guiding.py                       # every scene, defaults below
    nice -n 10 python3 bench/guiding.py --scenes gap-room --seconds 10 --reps 5

Scenes: veach-ajar (Bitterli, ../shared/scenes/pbrt/veach-ajar) and the hard-indirect rooms of
scenes/guiding/ (scripts/guiding_scenes.py), plus the built-in Cornell box as the simple case.
Each scene gets a reference: a long unguided render (--ref-spp, cached in bench/out/guiding/).
Then, for each repetition, two unguided and two guided renders with the same --time-limit,
interleaved (unguided, guided, unguided, guided, so that machine load drifts affect both alike),
each with its own seed. A render's error is its relative variance, measured from its pair
without the reference's noise: the mean over pixels and channels of (a - b)^2 / 2 / (r^2 + 0.01)
for the pair's images a and b, which is an unbiased estimate of the relMSE of bench/compare.py
(mean of (x - r)^2 / (r^2 + 0.01)) against the exact image for an unbiased renderer (both modes
are: the agreement tests check it). The reference r only normalises. Scoring against the
reference instead would add the reference's own variance to every render's: a 512-spp reference
against 60-second renders of 2000 spp made both columns mostly reference noise and pulled every
ratio toward 1. Reported: the median over repetitions with its min-max spread, and the ratio of
medians.
Images are written as Radiance .hdr (RGBE, 8-bit mantissa: a relative quantization error of
~0.4 %, far below the noise compared here), read without extra Python modules.
"""
import argparse
import os
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
OUT = os.path.join(HERE, "out", "guiding")
SHARED = os.path.join(os.path.dirname(ROOT), "shared")
if not os.path.isdir(SHARED):
    SHARED = "/work/shared"
SCENES = {
    "cornell": "cornell",
    "veach-ajar": os.path.join(SHARED, "scenes/pbrt/veach-ajar/scene-v4.pbrt"),
    "gap-room": os.path.join(ROOT, "scenes/guiding/gap-room.pbrt"),
    "sunlit-interior": os.path.join(ROOT, "scenes/guiding/sunlit-interior.pbrt"),
    "bright-patch": os.path.join(ROOT, "scenes/guiding/bright-patch.pbrt"),
    "fog-gap": os.path.join(ROOT, "scenes/guiding/fog-gap.pbrt"),
}


def read_hdr(path):
    """A Radiance RGBE file (new-style run-length encoding or flat) as a flat list of floats."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"\n\n") + 2
    line_end = data.index(b"\n", end)
    dims = data[end:line_end].split()
    h, w = int(dims[1]), int(dims[3])
    pos = line_end + 1
    out = []
    for _ in range(h):
        if w >= 8 and w < 32768 and data[pos] == 2 and data[pos + 1] == 2:
            pos += 4
            chans = []
            for _c in range(4):
                row = []
                while len(row) < w:
                    n = data[pos]
                    pos += 1
                    if n > 128:
                        row += [data[pos]] * (n - 128)
                        pos += 1
                    else:
                        row += list(data[pos:pos + n])
                        pos += n
                chans.append(row)
            px = zip(*chans)
        else:
            px = [tuple(data[pos + 4 * i:pos + 4 * i + 4]) for i in range(w)]
            pos += 4 * w
        for r, g, b, e in px:
            if e == 0:
                out += [0.0, 0.0, 0.0]
            else:
                f = 2.0 ** (e - 136)
                out += [(r + 0.5) * f, (g + 0.5) * f, (b + 0.5) * f]
    return out


def render(exe, scene, out, res, seed, threads, extra, off="", env_extra=()):
    cmd = [exe, "render", scene, "-o", out, "--width", str(res[0]), "--height", str(res[1]),
           "--seed", str(seed), "--threads", str(threads), "--quiet"] + extra
    env = dict(os.environ, TRAYECTO_GUIDING_OFF=off) if off else dict(os.environ)
    env.update(kv.split("=", 1) for kv in env_extra)
    t = time.time()
    subprocess.run(cmd, check=True, env=env)
    return time.time() - t


def rel_sq(a, b, ref):
    """Mean over pixels and channels of (a - b)^2 / (ref^2 + 0.01)."""
    s = 0.0
    for x, y, r in zip(a, b, ref):
        s += (x - y) ** 2 / (r * r + 0.01)
    return s / len(ref)


def rel_mse(img, ref):
    return rel_sq(img, ref, ref)


def pair_rel_var(a, b, ref):
    """Relative variance of one render, from two independent renders a and b of the same
    settings: half the mean squared difference, normalised by the reference as `rel_mse`. For an
    unbiased renderer its expectation is the relMSE of one render against the exact image, with
    none of the reference's own noise in it. (The same difference estimate as
    compare.combine_reference_halves, there for a reference's own noise; this script reads its
    images without numpy.)"""
    return rel_sq(a, b, ref) / 2


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", nargs="*", default=list(SCENES))
    ap.add_argument("--seconds", type=float, default=8.0, help="wall-clock budget of each compared render")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--res", default="96x72")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--ref-spp", type=int, default=8192)
    ap.add_argument("--trayecto-bin", default=os.path.join(ROOT, "target/release/trayecto"))
    ap.add_argument("--ref-bin", default=None,
                    help="binary for the references (default: --trayecto-bin; unguided images "
                         "are the same with any build that renders them bit-identically)")
    ap.add_argument("--refs-only", action="store_true", help="make the missing references and stop")
    ap.add_argument("--off", default="",
                    help="TRAYECTO_GUIDING_OFF for the guided renders: refinements to leave out "
                         "(bins, filter, nee), to measure each one's share")
    ap.add_argument("--guided-env", nargs="*", default=[], metavar="KEY=VALUE",
                    help="environment of the guided renders only (the TRAYECTO_GUIDING_* knobs)")
    args = ap.parse_args()
    res = tuple(int(v) for v in args.res.split("x"))
    os.makedirs(OUT, exist_ok=True)
    exe = os.path.abspath(args.trayecto_bin)
    ref_exe = os.path.abspath(args.ref_bin or args.trayecto_bin)
    print(f"| scene | unguided relative variance (min-max) | guided relative variance (min-max) | unguided / guided |")
    print(f"| --- | --- | --- | --- |")
    for name in args.scenes:
        scene = SCENES.get(name, name)
        tag = f"{name}_{res[0]}x{res[1]}"
        ref_path = os.path.join(OUT, f"ref_{tag}_{args.ref_spp}.hdr")
        if not os.path.exists(ref_path):
            t = render(ref_exe, scene, ref_path, res, 999, args.threads, ["--spp", str(args.ref_spp)])
            print(f"[{name}] reference {args.ref_spp} spp: {t:.0f} s", file=sys.stderr, flush=True)
        if args.refs_only:
            continue
        ref = read_hdr(ref_path)
        errs = {"plain": [], "guided": []}
        for rep in range(args.reps):
            imgs = {"plain": [], "guided": []}
            for half in (0, 1):
                for mode in ("plain", "guided"):
                    extra = ["--time-limit", str(args.seconds)] + (["--guiding"] if mode == "guided" else [])
                    out = os.path.join(OUT, f"{tag}_{mode}_{rep}_{half}.hdr")
                    render(exe, scene, out, res, 1 + 2 * rep + half, args.threads, extra,
                           args.off if mode == "guided" else "",
                           args.guided_env if mode == "guided" else ())
                    imgs[mode].append(read_hdr(out))
            for mode in ("plain", "guided"):
                errs[mode].append(pair_rel_var(*imgs[mode], ref))
            print(f"[{name}] rep {rep}: plain {errs['plain'][-1]:.4g} guided {errs['guided'][-1]:.4g}",
                  file=sys.stderr, flush=True)
        mp, mg = statistics.median(errs["plain"]), statistics.median(errs["guided"])
        print(f"| {name} | {mp:.4g} ({min(errs['plain']):.4g}-{max(errs['plain']):.4g}) | "
              f"{mg:.4g} ({min(errs['guided']):.4g}-{max(errs['guided']):.4g}) | {mp / mg:.2f}x |",
              flush=True)


if __name__ == "__main__":
    sys.exit(main())
