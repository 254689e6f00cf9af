"""MLT on veach-mis against the path tracer, per lamp seen directly and over seeds: is MLT's
deficit beside the small bright lamps a bias or the bootstrap's and the chains' noise?

    python3 bench/mlt_veach_mis.py TRAYECTO [--pbrt PBRT] [--seeds 8]
        [--bootstrap 100000 1000000] [--depth 0] [--res 96 54] [--mutations 256]

Renders ../shared/scenes/pbrt/veach-mis at --res with Trayecto's path tracer (4096 spp, the
reference) and, for every seed and bootstrap count, Trayecto's MLT (and pbrt-v4's `mlt` with the
same maxdepth, mutations per pixel, bootstrap samples and 1000 chains, given --pbrt). Prints per
render the whole image's luminance error and that of each lamp seen directly (the columns of the
reference's depth-0 image: the lamps and their filter footprint), then per configuration the
mean and the standard deviation over the seeds. A bias shows as a mean off by more than its
standard deviation over √seeds; noise as a deviation that falls with the bootstrap count.
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from exr_compare import lum, read  # noqa: E402

SCENE = os.path.join(os.path.dirname(__file__), "../../shared/scenes/pbrt/veach-mis/scene-v4.pbrt")


def lamp_columns(direct):
    """Column ranges where the depth-0 reference is non-zero: one per lamp seen directly."""
    nz = np.nonzero(lum(direct).sum(axis=0) > 0)[0]
    out, start = [], nz[0]
    for a, b in zip(nz, nz[1:]):
        if b != a + 1:
            out.append((start, a))
            start = b
    out.append((start, nz[-1]))
    return out


def pbrt_file(tmp, w, h, depth, mutations, bootstrap):
    s = open(SCENE).read()
    s = s.replace('"integer yresolution" [ 720 ]', f'"integer yresolution" [ {h} ]')
    s = s.replace('"integer xresolution" [ 1280 ]', f'"integer xresolution" [ {w} ]')
    s = s.replace('"integer maxdepth" [ 3 ]', f'"integer maxdepth" [ {depth} ]')
    s = s.replace(
        'Integrator "path"',
        f'Integrator "mlt"\n    "integer mutationsperpixel" [ {mutations} ]\n'
        f'    "integer bootstrapsamples" [ {bootstrap} ]\n    "integer chains" [ 1000 ]',
    )
    path = os.path.join(tmp, f"mlt_{depth}_{mutations}_{bootstrap}.pbrt")
    open(path, "w").write(s)
    return path


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("trayecto")
    ap.add_argument("--pbrt")
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--bootstrap", type=int, nargs="+", default=[100000, 1000000])
    ap.add_argument("--depth", type=int, default=0)
    ap.add_argument("--res", type=int, nargs=2, default=[96, 54])
    ap.add_argument("--mutations", type=int, default=256)
    a = ap.parse_args()
    w, h = a.res
    tmp = tempfile.mkdtemp()
    size = ["--width", str(w), "--height", str(h), "-q"]

    def trayecto(out, *args):
        subprocess.run([a.trayecto, "render", SCENE, *size, "-o", out, *args], check=True)
        return read(out)

    ref = trayecto(f"{tmp}/ref.exr", "--integrator", "path", "--spp", "4096", "--max-depth", str(a.depth))
    direct = trayecto(f"{tmp}/direct.exr", "--integrator", "path", "--spp", "1024", "--max-depth", "0")
    lamps = lamp_columns(direct)
    r = lum(ref)
    print(f"veach-mis {w}x{h}, maxdepth {a.depth}, {a.mutations} mutations per pixel; lamp columns {lamps},"
          f" share of the image {[round(r[:, x0:x1 + 1].sum() / r.sum(), 3) for x0, x1 in lamps]}")

    def errors(img):
        t = lum(img)
        return [t.sum() / r.sum() - 1] + [t[:, x0:x1 + 1].sum() / r[:, x0:x1 + 1].sum() - 1 for x0, x1 in lamps]

    for b in a.bootstrap:
        for who in ["trayecto"] + (["pbrt"] if a.pbrt else []):
            rows = []
            for seed in range(1, a.seeds + 1):
                out = f"{tmp}/{who}_{b}_{seed}.exr"
                if who == "trayecto":
                    img = trayecto(out, "--integrator", "mlt", "--spp", str(a.mutations), "--seed", str(seed),
                                   "--max-depth", str(a.depth), "--mlt-bootstrap-samples", str(b),
                                   "--mlt-chains", "1000")
                else:
                    f = pbrt_file(tmp, w, h, a.depth, a.mutations, b)
                    subprocess.run([a.pbrt, "--nthreads", "2", "--seed", str(seed), "--outfile", out, f],
                                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                    img = read(out)
                rows.append(errors(img))
            e = np.array(rows)
            print(f"{who:8} bootstrap {b:>8}: image, lamps: mean {np.round(e.mean(0), 3)}  "
                  f"sd {np.round(e.std(0, ddof=1), 3)}  ({a.seeds} seeds)")


if __name__ == "__main__":
    main()
