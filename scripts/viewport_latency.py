#!/usr/bin/env python3
"""Measures the web viewport's latency: for each model, the time from a camera move (a POST of a
new view to a session whose scene is already built) to the first image (quarter size, 1 spp) and
to the first full-size pass, as the server reports them (`first_ms`, `full_ms`), plus the
client-side time until the status shows them. Starts `trayecto serve` (release build) itself.

    python3 scripts/viewport_latency.py [--size 400] [--moves 5] [MODEL.glb ...]
"""
import argparse, json, os, shutil, subprocess, sys, tempfile, time, urllib.request, statistics

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.join(os.path.dirname(ROOT), "shared", "scenes", "gltf")
DEFAULT = ["Box/glTF-Binary/Box.glb", "BoxTextured/glTF-Binary/BoxTextured.glb",
           "DamagedHelmet/glTF-Binary/DamagedHelmet.glb"]


def call(base, path, body=None):
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(base + path, data=data,
                                 headers={"Content-Type": "application/json"} if data else {})
    with urllib.request.urlopen(req) as r:
        return json.loads(r.read())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=400)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--moves", type=int, default=5)
    ap.add_argument("models", nargs="*")
    a = ap.parse_args()
    models = a.models or [os.path.join(SHARED, m) for m in DEFAULT]
    tmp = tempfile.mkdtemp()
    scenes = os.path.join(tmp, "scenes")
    os.makedirs(scenes)
    for m in models:
        shutil.copy(m, scenes)
    exe = os.path.join(ROOT, "target", "release", "trayecto")
    srv = subprocess.Popen([exe, "serve", "--port", "0", "--scenes", scenes, "--output",
                            os.path.join(tmp, "out")], stdout=subprocess.PIPE, text=True)
    try:
        line = srv.stdout.readline()
        base = line.strip().split("listening on ")[1].rstrip("/")
        print(f"load average {os.getloadavg()[0]:.1f}, view {a.size}x{a.size}, {a.spp} spp")
        for m in models:
            name = os.path.basename(m)
            view = {"scene": name, "width": a.size, "height": a.size, "spp": a.spp, "max_depth": 6}
            sid = "lat" + str(abs(hash(name)) % 10**8)
            g = call(base, f"/api/viewport?session={sid}", view)["generation"]
            while True:
                st = call(base, f"/api/viewport/{sid}")
                if st["generation"] == g and st["state"] in ("done", "failed"):
                    break
                time.sleep(0.01)
            build = st["build_ms"]
            cam = st["view"]["camera"]
            firsts, fulls = [], []
            for i in range(a.moves):
                v = dict(view)
                eye = list(cam["eye"])
                eye[0] += 0.05 * (i + 1) * (abs(eye[2]) + 1)
                v["camera"] = {"eye": eye, "target": cam["target"], "up": cam["up"], "fov": cam["fov"]}
                g = call(base, f"/api/viewport?session={sid}", v)["generation"]
                while True:
                    st = call(base, f"/api/viewport/{sid}")
                    if st["generation"] == g and st["full_ms"] is not None:
                        break
                    time.sleep(0.005)
                firsts.append(st["first_ms"])
                fulls.append(st["full_ms"])
            print(f"{name:28s} build {build:7.0f} ms | after a move: first image median "
                  f"{statistics.median(firsts):6.1f} ms (max {max(firsts):6.1f}), first full-size pass "
                  f"median {statistics.median(fulls):6.1f} ms (max {max(fulls):6.1f})")
    finally:
        srv.kill()
        srv.wait()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
