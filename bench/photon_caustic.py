#!/usr/bin/env python3
"""Error against iterations for SPPM, VCM, BDPT and the path tracer on scenes/pbrt/caustic-through-glass.pbrt over
several seeds (BENCHMARKS.md, "Caustics seen through glass"). One seed's relative RMS error is
dominated by rare full-radiance samples (the small light seen through the sphere and the pane),
so a ladder from one seed can rise where the method converges; this reports, per method and
iteration count, the RMS over seeds of the relative RMS error against an independent SPPM
reference (seed 100), with and without the highlight's pixels, and the mean render time.

    python3 bench/photon_caustic.py target/release/trayecto [--seeds 6] [--ref-spp 512]

Renders to .hdr (the RLE reader below needs only numpy) in bench/out/photon_caustic/.
"""
import argparse, os, subprocess, time
import numpy as np

SCENE = "scenes/pbrt/caustic-through-glass.pbrt"
W, H = 160, 120


def read_hdr(path):
    data = open(path, "rb").read()
    i = 0
    while True:
        j = data.index(b"\n", i)
        line, i = data[i:j], j + 1
        if line.startswith(b"-Y"):
            parts = line.split()
            h, w = int(parts[1]), int(parts[3])
            break
    out = np.zeros((h, w, 4), np.uint8)
    for y in range(h):
        if data[i] == 2 and data[i + 1] == 2:  # new-style run-length encoding, per channel
            i += 4
            for c in range(4):
                x = 0
                while x < w:
                    n = data[i]
                    i += 1
                    if n > 128:
                        n -= 128
                        out[y, x:x + n, c] = data[i]
                        i += 1
                    else:
                        out[y, x:x + n, c] = np.frombuffer(data[i:i + n], np.uint8)
                        i += n
                    x += n
        else:
            out[y] = np.frombuffer(data[i:i + 4 * w], np.uint8).reshape(w, 4)
            i += 4 * w
    e = out[..., 3].astype(np.int32)
    f = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0)
    return out[..., :3].astype(np.float64) * f[..., None]


def render(binary, out, integrator, spp, seed):
    t = time.time()
    subprocess.run([binary, "render", SCENE, "--width", str(W), "--height", str(H), "--spp",
                    str(spp), "--integrator", integrator, "--seed", str(seed), "--threads", "1",
                    "--quiet", "-o", out], check=True)
    return time.time() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--ref-spp", type=int, default=512)
    a = ap.parse_args()
    d = "bench/out/photon_caustic"
    os.makedirs(d, exist_ok=True)
    ref_path = f"{d}/ref_sppm_{a.ref_spp}.hdr"
    if not os.path.exists(ref_path):
        render(a.binary, ref_path, "sppm", a.ref_spp, 100)
    ref = read_hdr(ref_path)
    # The sphere's reflection of the light (rows 38-49, columns 66-75 at 160 x 120).
    mask = np.ones(ref.shape[:2], bool)
    mask[38:50, 66:76] = False
    print("| method | spp | rel. RMS error (RMS over seeds) | without the highlight | mean s |")
    print("| --- | --- | --- | --- | --- |")
    for spp in (4, 16):
        for integrator in ("sppm", "vcm", "bdpt", "path"):
            e, em, ts = [], [], []
            for seed in range(1, a.seeds + 1):
                out = f"{d}/{integrator}_{spp}_{seed}.hdr"
                ts.append(render(a.binary, out, integrator, spp, seed))
                img = read_hdr(out)
                e.append(np.sqrt(((img - ref) ** 2).mean()) / ref.mean())
                em.append(np.sqrt(((img - ref) ** 2)[mask].mean()) / ref.mean())
            rms = lambda x: np.sqrt(np.mean(np.square(x)))
            print(f"| {integrator} | {spp} | {rms(e):.3f} | {rms(em):.3f} | {np.mean(ts):.1f} |")


if __name__ == "__main__":
    main()
