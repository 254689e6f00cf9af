#!/usr/bin/env python3
"""Light samplers compared by time x relMSE: each scene is rendered with
`--light-sampler power` and `--light-sampler bvh` at the same spp, against a reference rendered
with the light BVH at `--ref-factor` times the spp (another seed). Time is the CLI's `rendered`
phase. Needs `pip install mitsuba numpy` (Mitsuba only reads the EXR files).

    python3 bench/many_lights.py [--res 64] [--spp 16] [--ref-factor 16] [--threads 1]
"""
import argparse
import re
import subprocess
import tempfile
from pathlib import Path

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

ROOT = Path(__file__).resolve().parent.parent
SCENES = {
    "toycar-emitters": ["../shared/scenes/gltf-ext/ToyCar/glTF/ToyCar.gltf", "--default-light", "off"],
    "toycar": ["../shared/scenes/gltf-ext/ToyCar/glTF/ToyCar.gltf"],
    "cornell": ["cornell"],
}


def render(binary, args, out, spp, seed, res, threads, sampler):
    cmd = [binary, "render", *args, "-o", str(out), "--spp", str(spp), "--seed", str(seed),
           "--width", str(res), "--height", str(res), "--threads", str(threads),
           "--light-sampler", sampler]
    text = subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, text=True).stderr
    m = re.search(r"rendered \(path\)\s+([\d.]+) ms", text)
    return (float(m.group(1)) / 1000.0 if m else float("nan")), np.array(mi.Bitmap(str(out)))[..., :3]


def relmse(img, ref):
    return float(np.mean((img - ref) ** 2 / (ref ** 2 + 1e-2)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--ref-factor", type=int, default=16)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--binary", default=str(ROOT / "target/release/trayecto"))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        print(f"| scene | sampler | render s | relMSE | time x relMSE |")
        print(f"|---|---|---|---|---|")
        for name in a.scenes.split(","):
            args = SCENES[name]
            _, ref = render(a.binary, args, Path(tmp) / "ref.exr", a.spp * a.ref_factor, 12345,
                            a.res, a.threads, "bvh")
            for sampler in ["power", "bvh"]:
                t, img = render(a.binary, args, Path(tmp) / f"{sampler}.exr", a.spp, 1, a.res,
                                a.threads, sampler)
                e = relmse(img, ref)
                print(f"| {name} | {sampler} | {t:.2f} | {e:.4g} | {t * e:.4g} |", flush=True)


if __name__ == "__main__":
    main()
