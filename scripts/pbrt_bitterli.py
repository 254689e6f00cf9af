#!/usr/bin/env python3
"""Measures Trayecto on the Bitterli pbrt-v4 scenes against their Tungsten references.

For each scene in ../shared/scenes/pbrt/NAME/scene-v4.pbrt, renders it with `trayecto render` at
the reference's resolution divided by --factor (same aspect ratio), box-filters TungstenRender.exr
down to that size and prints, per scene: the mean of each image (luminance), the bias (relative
difference of the means), the per-channel ratio of means, and the relative error of the 16 blocks of
a 4 x 4 grid (mean and worst). The scene file's own max depth is used (pbrt's `maxdepth`).

Needs numpy and, for reading EXR, mitsuba or OpenEXR: `pip install numpy OpenEXR` (or mitsuba).
With --pbrt, pbrt-v4 (../shared/tools/pbrt-v4/pbrt) also renders each scene at the same size and
samples (a copy of the file with the Film resolution changed, beside links to the scene's files),
and Trayecto is compared against it as well: where Tungsten and pbrt-v4 disagree, pbrt-v4 is the
authority on what the file means.

Usage: scripts/pbrt_bitterli.py [--trayecto target/release/trayecto] [--factor 8] [--spp 128]
                                [--pbrt] [SCENE...]
"""
import re
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

try:
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
except ImportError:
    mi = None
    try:
        import OpenEXR
    except ImportError:
        sys.exit("pbrt_bitterli.py needs OpenEXR or mitsuba to read EXR files: pip install OpenEXR")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = ["cornell-box", "veach-mis", "coffee", "dining-room", "volumetric-caustic"]


def read(path):
    if mi is not None:
        return np.array(mi.Bitmap(path), dtype=np.float64)[:, :, :3]
    with OpenEXR.File(path) as f:
        ch = f.channels()
        rgb = ch["RGB"].pixels if "RGB" in ch else np.stack([ch[c].pixels for c in "RGB"], -1)
    return np.asarray(rgb, dtype=np.float64)[:, :, :3]


def downsample(img, h, w):
    fh, fw = img.shape[0] // h, img.shape[1] // w
    return img[: h * fh, : w * fw].reshape(h, fh, w, fw, 3).mean(axis=(1, 3))


def lum(img):
    return img @ np.array([0.2126, 0.7152, 0.0722])


def blocks(l, n=4):
    h, w = l.shape
    return np.array([[l[i * h // n:(i + 1) * h // n, j * w // n:(j + 1) * w // n].mean()
                      for j in range(n)] for i in range(n)])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trayecto", default=os.path.join(ROOT, "target/release/trayecto"))
    ap.add_argument("--factor", type=int, default=8)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--pbrt", action="store_true", help="also compare against pbrt-v4 renders")
    ap.add_argument("scenes", nargs="*", default=SCENES)
    a = ap.parse_args()
    shared = os.path.join(ROOT, "..", "shared", "scenes", "pbrt")
    print(f"{'scene / reference':30} {'size':>9} {'mean T':>8} {'mean ref':>8} {'bias':>7} "
          f"{'ratio R/G/B':>18} {'block mean':>10} {'block max':>9}")
    for name in a.scenes:
        ref = read(os.path.join(shared, name, "TungstenRender.exr"))
        h, w = ref.shape[0] // a.factor, ref.shape[1] // a.factor
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "out.exr")
            cmd = [a.trayecto, "render", os.path.join(shared, name, "scene-v4.pbrt"), "-o", out,
                   "--width", str(w), "--height", str(h), "--spp", str(a.spp), "-q"]
            subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
            img = read(out)
        r = downsample(ref, h, w)
        report(name, w, h, img, r, "Tungsten")
        if a.pbrt:
            try:
                ref_pbrt = render_pbrt(os.path.join(shared, name), w, h, a.spp)
            except subprocess.CalledProcessError:
                print(f"{name + ' / pbrt-v4':30} pbrt-v4 refused the file (run it by hand for the message)")
                continue
            report(name, w, h, img, ref_pbrt, "pbrt-v4")


def render_pbrt(scene_dir, w, h, spp):
    pbrt = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v4", "pbrt")
    text = open(os.path.join(scene_dir, "scene-v4.pbrt")).read()
    text = re.sub(r'"integer xresolution"\s*\[\s*\d+\s*\]', f'"integer xresolution" [ {w} ]', text)
    text = re.sub(r'"integer yresolution"\s*\[\s*\d+\s*\]', f'"integer yresolution" [ {h} ]', text)
    with tempfile.TemporaryDirectory() as d:
        for entry in os.listdir(scene_dir):
            os.symlink(os.path.join(os.path.abspath(scene_dir), entry), os.path.join(d, entry))
        os.remove(os.path.join(d, "scene-v4.pbrt"))
        with open(os.path.join(d, "scene-v4.pbrt"), "w") as f:
            f.write(text)
        out = os.path.join(d, "pbrt.exr")
        subprocess.run([pbrt, "--nthreads", "2", "--spp", str(spp), "--outfile", out,
                        os.path.join(d, "scene-v4.pbrt")], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return read(out)


def report(name, w, h, img, r, against):
    lt, lr = lum(img), lum(r)
    bias = (lt.mean() - lr.mean()) / lr.mean()
    ratio = img.mean(axis=(0, 1)) / np.maximum(r.mean(axis=(0, 1)), 1e-9)
    bt, br = blocks(lt), blocks(lr)
    berr = np.abs(bt - br) / np.maximum(br, 0.02 * lr.mean())
    print(f"{name + ' / ' + against:30} {w:>4}x{h:<4} {lt.mean():8.4f} {lr.mean():8.4f} {bias:+7.3f} "
          f"{ratio[0]:6.3f}/{ratio[1]:5.3f}/{ratio[2]:5.3f} {berr.mean():10.3f} {berr.max():9.3f}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
