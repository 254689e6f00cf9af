#!/usr/bin/env python3
"""Variants of Bitterli's volumetric-caustic for the comparison with pbrt-v4 (docs/src/correctness.md, "pbrt-v4
import": volumetric-caustic against pbrt-v4), and optionally their renders by both renderers.

Writes into OUT: base (the file at SIZE²), nosphere (the glass sphere removed), iface (the sphere
an `interface`), vacuum (the gas with σs = 0), big (the 5 × 4 mm lamp made 10 × 10 cm, L scaled by
the area ratio to keep its power), and vac_d0 (vacuum at maxdepth 0: the lamp seen directly).
With --render, renders each with pbrt-v4 and `trayecto render` at --spp and --seed and prints the
luminance means, also with the lamp's window (rows 2–9, columns 27–35 of a 64² image) left out.

Needs numpy and OpenEXR (`pip install numpy OpenEXR`).
Usage: scripts/references/volumetric_caustic_variants.py OUT [--size 64] [--render --spp 1024
       --seed 0 --trayecto target/release/trayecto] [VARIANT...]
"""
import argparse
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENE = os.path.join(ROOT, "..", "shared", "scenes", "pbrt", "volumetric-caustic", "scene-v4.pbrt")
PBRT = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v4", "pbrt")
L_RGB = "541126.75 381971.8 127323.94"


def variants(size):
    src = open(SCENE).read()
    src = re.sub(r'"integer (x|y)resolution" \[ 512 \]', rf'"integer \1resolution" [ {size} ]', src)
    sphere = re.search(r'AttributeBegin\n    MediumInterface "" "gas"\n    NamedMaterial "Sphere".*?'
                       r'AttributeEnd\nAttributeEnd\n', src, re.S).group(0)
    lamp = re.search(r'"point3 P" \[ -0.0025 1.98 -0.028.*?\]', src, re.S).group(0)
    h, cx, cz = 0.05, -0.005, -0.03
    s = (0.005 * 0.004) / (2 * h) ** 2
    big = src.replace(lamp, f'"point3 P" [ {cx + h} 1.98 {cz + h} {cx - h} 1.98 {cz + h} '
                            f'{cx - h} 1.98 {cz - h} {cx + h} 1.98 {cz - h} ]')
    big = big.replace(f'"rgb L" [ {L_RGB} ]',
                      '"rgb L" [ ' + " ".join(f"{float(v) * s:.6g}" for v in L_RGB.split()) + " ]")
    vacuum = src.replace('"rgb sigma_s" [ 1 1 1 ]', '"rgb sigma_s" [ 0 0 0 ]')
    out = {
        "base": src,
        "nosphere": src.replace(sphere, ""),
        "iface": src.replace('"string type" [ "dielectric" ]', '"string type" [ "interface" ]'),
        "vacuum": vacuum,
        "big": big,
        "vac_d0": vacuum.replace('"integer maxdepth" [ 7 ]', '"integer maxdepth" [ 0 ]'),
    }
    for k, v in out.items():
        assert k == "base" or v != src, k
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--render", action="store_true")
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--trayecto", default=os.path.join(ROOT, "target", "release", "trayecto"))
    ap.add_argument("names", nargs="*")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    vs = variants(a.size)
    for name in a.names or vs:
        path = os.path.join(a.out, f"{name}.pbrt")
        with open(path, "w") as f:
            f.write(vs[name])
        if not a.render:
            continue
        p_out = os.path.join(a.out, f"{name}_pbrt_s{a.seed}.exr")
        t_out = os.path.join(a.out, f"{name}_trayecto_s{a.seed}.exr")
        subprocess.run([PBRT, "--spp", str(a.spp), "--seed", str(a.seed), "--quiet", "--outfile",
                        p_out, path], check=True)
        subprocess.run([a.trayecto, "render", path, "-o", t_out, "--spp", str(a.spp), "--seed",
                        str(a.seed), "-q"], check=True, stderr=subprocess.DEVNULL)
        (tm, tf), (pm, pf) = masked(t_out), masked(p_out)
        print(f"{name:9} Trayecto {tf:.4f} pbrt-v4 {pf:.4f} | lamp window left out: "
              f"Trayecto {tm:.4f} pbrt-v4 {pm:.4f} ({tm / pm - 1:+.2%})")
        sys.stdout.flush()


def masked(path):
    """(mean luminance outside the lamp's window, mean luminance of the whole image)."""
    import numpy as np
    import OpenEXR
    with OpenEXR.File(path) as f:
        ch = f.channels()
        rgb = ch["RGB"].pixels if "RGB" in ch else np.stack([ch[c].pixels for c in "RGB"], -1)
    lum = np.asarray(rgb, dtype=np.float64)[:, :, :3] @ np.array([0.2126, 0.7152, 0.0722])
    s = lum.shape[0] // 64
    window = np.zeros_like(lum, bool)
    window[2 * s:10 * s, 27 * s:36 * s] = True
    return lum[~window].mean(), lum.mean()


if __name__ == "__main__":
    main()
