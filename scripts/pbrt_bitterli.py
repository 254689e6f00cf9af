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
                                [--pbrt] [--corpus DIR [--all] [--placeholders]] [--keep DIR]
                                [SCENE...]

--corpus DIR reads the scenes from DIR/NAME/scene-v4.pbrt (default ../shared/scenes/pbrt; the
whole corpus is Bitterli's pbrt-v4 scene pack, e.g. a copy of github.com/gonsolo/bitterli's
NAME/pbrt folders outside the repository); a scene without TungstenRender.exr takes its Film
size and is compared with pbrt-v4 only. --placeholders stands in for files the copy lacks (both
renderers read the same stand-ins, so the comparison still measures the rest of the scene).
"""
import re
import argparse
import os
import shutil
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
    ap.add_argument("--corpus", default=os.path.join(ROOT, "..", "shared", "scenes", "pbrt"),
                    help="folder of NAME/scene-v4.pbrt (Bitterli's pbrt-v4 scenes)")
    ap.add_argument("--all", action="store_true", help="every scene folder of the corpus")
    ap.add_argument("--placeholders", action="store_true",
                    help="stand in for files the scene names but the corpus lacks (grey images, "
                         "a tiny triangle for meshes, an empty file for an Include/Import), the "
                         "same for both renderers")
    ap.add_argument("--keep", metavar="DIR",
                    help="keep both renders as DIR/NAME-trayecto.exr and DIR/NAME-pbrt.exr; a kept "
                         "pbrt-v4 render of the same size is reused instead of rendering it again")
    ap.add_argument("--rgb", action="store_true",
                    help="render in RGB (trayecto --rgb; pbrt files render spectrally by default)")
    ap.add_argument("scenes", nargs="*")
    a = ap.parse_args()
    names = a.scenes or (sorted(d for d in os.listdir(a.corpus)
                                if os.path.exists(os.path.join(a.corpus, d, "scene-v4.pbrt")))
                         if a.all else SCENES)
    print(f"{'scene / reference':30} {'size':>9} {'mean T':>8} {'mean ref':>8} {'bias':>7} "
          f"{'ratio R/G/B':>18} {'block mean':>10} {'block max':>9}")
    for name in names:
        src = os.path.join(a.corpus, name)
        tungsten = os.path.join(src, "TungstenRender.exr")
        ref = read(tungsten) if os.path.exists(tungsten) else None
        fw, fh = film_size(os.path.join(src, "scene-v4.pbrt"))
        if ref is not None:
            fh, fw = ref.shape[0], ref.shape[1]
        h, w = max(fh // a.factor, 1), max(fw // a.factor, 1)
        with tempfile.TemporaryDirectory() as d:
            scene = overlay(src, d, w, h, a.placeholders)
            out = os.path.join(d, "out.exr")
            cmd = [a.trayecto, "render", scene, "-o", out,
                   "--width", str(w), "--height", str(h), "--spp", str(a.spp), "-q"]
            if a.rgb:
                cmd.append("--rgb")
            try:
                subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
            except subprocess.CalledProcessError:
                print(f"{name:30} Trayecto refused the file (run it by hand for the message)")
                continue
            img = read(out)
            if a.keep:
                os.makedirs(a.keep, exist_ok=True)
                shutil.copy(out, os.path.join(a.keep, name + "-trayecto.exr"))
            if ref is not None:
                report(name, w, h, img, downsample(ref, h, w), "Tungsten")
            if a.pbrt:
                kept = os.path.join(a.keep, name + "-pbrt.exr") if a.keep else None
                try:
                    if kept and os.path.exists(kept) and read(kept).shape == img.shape:
                        ref_pbrt = read(kept)
                    else:
                        ref_pbrt = render_pbrt(scene, d, a.spp)
                        if kept:
                            shutil.copy(os.path.join(d, "pbrt.exr"), kept)
                except subprocess.CalledProcessError:
                    print(f"{name + ' / pbrt-v4':30} pbrt-v4 refused the file (run it by hand for the message)")
                    continue
                report(name, w, h, img, ref_pbrt, "pbrt-v4")


def film_size(path):
    text = open(path, errors="replace").read()
    x = re.search(r'"integer xresolution"\s*\[?\s*(\d+)', text)
    y = re.search(r'"integer yresolution"\s*\[?\s*(\d+)', text)
    return (int(x.group(1)) if x else 1280), (int(y.group(1)) if y else 720)


def overlay(scene_dir, d, w, h, placeholders):
    """A copy of the scene's folder in `d` (links to its files) with the Film resolution set to
    w x h; with `placeholders`, files the scene names that are missing get stand-ins there."""
    text = open(os.path.join(scene_dir, "scene-v4.pbrt"), errors="replace").read()
    text = re.sub(r'"integer xresolution"\s*\[\s*\d+\s*\]', f'"integer xresolution" [ {w} ]', text)
    text = re.sub(r'"integer yresolution"\s*\[\s*\d+\s*\]', f'"integer yresolution" [ {h} ]', text)
    for entry in os.listdir(scene_dir):
        if entry != "scene-v4.pbrt":
            os.symlink(os.path.join(os.path.abspath(scene_dir), entry), os.path.join(d, entry))
    path = os.path.join(d, "scene-v4.pbrt")
    with open(path, "w") as out:
        out.write(text)
    if placeholders:
        names = re.findall(r'"string filename"\s*\[?\s*"([^"]+)"', text)
        # Included files too (the hair scenes' models/hair.pbrt): an empty stand-in.
        names += re.findall(r'(?m)^\s*(?:Include|Import)\s+"([^"]+)"', text)
        for f in sorted(set(names)):
            if not os.path.exists(os.path.join(d, f)):
                stand_in(os.path.join(d, f))
    return path


def stand_in(path):
    """A grey 8 x 8 image (TGA, PFM or EXR), a one-triangle PLY far below the scene, or an empty
    include; never written into the corpus itself."""
    # The overlay links whole sub-folders (textures/, models/): each linked folder on the way is
    # made a real folder of links, so the stand-in does not land in the corpus.
    # (From the file's own folder up: a missing file beside the scene, e.g. an environment
    # map, has the overlay itself as its folder.)
    d = os.path.dirname(path)
    while not os.path.exists(os.path.join(d, "scene-v4.pbrt")):
        if os.path.dirname(d) == d:
            raise RuntimeError(f"{path} is not inside a scene folder")
        d = os.path.dirname(d)
    cur = d
    for part in os.path.relpath(os.path.dirname(path), d).split(os.sep):
        if part in ("", "."):
            continue
        cur = os.path.join(cur, part)
        if os.path.islink(cur):
            target = os.path.realpath(cur)
            os.remove(cur)
            os.makedirs(cur)
            for e in os.listdir(target):
                os.symlink(os.path.join(target, e), os.path.join(cur, e))
        os.makedirs(cur, exist_ok=True)
    # ("x" + the name: living-room-3 includes "models/.pbrt", a name that is all extension.)
    ext = os.path.splitext("x" + os.path.basename(path))[1].lower()
    if ext == ".pfm":
        data = b"PF\n8 8\n-1.0\n" + np.full((8, 8, 3), 0.5, "<f4").tobytes()
    elif ext == ".ply":
        data = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                b"property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                b"end_header\n0 -1000 0\n0.001 -1000 0\n0 -1000 0.001\n3 0 1 2\n")
    elif ext == ".pbrt":
        data = b""
    elif ext == ".exr" and "OpenEXR" in sys.modules:
        # A grey EXR (an environment map beside the scene, e.g. bathroom's) both renderers read.
        px = np.full((8, 8, 3), 0.5, "float32")
        OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                     {"RGB": px}).write(path)
        return
    else:
        import struct
        # Any other image: an uncompressed grey TGA (a .png or .exr name with TGA bytes is
        # refused by both renderers alike, which the report then names).
        data = struct.pack("<BBBHHBHHHHBB", 0, 0, 2, 0, 0, 0, 0, 0, 8, 8, 24, 0x20) + bytes([128]) * 192
    with open(path, "wb") as f:
        f.write(data)


def render_pbrt(scene, d, spp):
    pbrt = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v4", "pbrt")
    out = os.path.join(d, "pbrt.exr")
    subprocess.run([pbrt, "--nthreads", "2", "--spp", str(spp), "--outfile", out, scene],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
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
