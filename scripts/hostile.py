#!/usr/bin/env python3
"""Hostile inputs against the `trayecto` binary (docs/src/fuzzing.md, "Hostile inputs").

Crafts small files that name far more memory, files or time than they are (image headers
claiming 100000² pixels, accessor counts of 2²⁷, compressed zeros, include fan-outs, FIFOs,
subdivision levels, huge coordinates, ...), then runs `trayecto render` on each under a 3 GiB
address-space limit (RLIMIT_AS) and a 20 s timeout. Each must end with a clear error or a
render: no abort, no panic, no timeout.

    scripts/hostile.py [--bin target/release/trayecto] [--only NAME] [--keep DIR]
    scripts/hostile.py --serve [--bin ...]   # the same cases through `trayecto serve`

`--serve` starts `trayecto serve` (under the same limit) on a scenes folder holding every case,
uploads a few as .zip, asks a render and a scene view of each, and checks after every case that
the server still answers. Exit status 1 if any case fails. Python 3, standard library only.
"""

import argparse
import gzip
import io
import itertools
import json
import os
import resource
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
import zipfile
import zlib

AS_LIMIT = 3 << 30
TIMEOUT = 20.0


# ---------------------------------------------------------------- crafting


def png(w, h, raw_rows=None):
    """A grey 8-bit PNG of w×h. Without raw_rows its IDAT inflates to the full image of zeros,
    compressed as a stream (so 16384² costs ~260 KB here and nothing big in memory)."""

    def chunk(kind, data):
        c = kind + data
        return struct.pack(">I", len(data)) + c + struct.pack(">I", zlib.crc32(c) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)
    z = zlib.compressobj(9)
    out = []
    row = b"\0" * (w + 1)
    if raw_rows is None:
        block = row * max(1, (1 << 22) // len(row))
        rows_per_block = len(block) // len(row)
        left = h
        while left > 0:
            n = min(left, rows_per_block)
            out.append(z.compress(block[: n * len(row)]))
            left -= n
    else:
        out.append(z.compress(raw_rows))
    out.append(z.flush())
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", b"".join(out))
        + chunk(b"IEND", b"")
    )


def exr_claiming(w, h):
    """A scanline EXR header (ZIP, 16 lines a chunk, three float channels) claiming w×h
    pixels, with its offset table and no pixel data."""
    out = bytearray(b"\x76\x2f\x31\x01" + struct.pack("<I", 2))

    def attr(name, ty, value):
        out.extend(name.encode() + b"\0" + ty.encode() + b"\0")
        out.extend(struct.pack("<i", len(value)) + value)

    ch = b""
    for c in "BGR":
        ch += c.encode() + b"\0" + struct.pack("<iBBBBii", 2, 0, 0, 0, 0, 1, 1)
    ch += b"\0"
    window = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    attr("channels", "chlist", ch)
    attr("compression", "compression", b"\x03")
    attr("dataWindow", "box2i", window)
    attr("displayWindow", "box2i", window)
    attr("lineOrder", "lineOrder", b"\x00")
    attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
    attr("screenWindowCenter", "v2f", struct.pack("<ff", 0, 0))
    attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
    out.append(0)
    chunks = (h + 15) // 16
    end = len(out) + 8 * chunks
    out.extend(struct.pack("<Q", end) * chunks)
    return bytes(out)


def fbx_with_zlib_array(count):
    """A binary FBX 7.4 whose one node holds a zlib-compressed double array of `count` zeros
    (within deflate's ~1000:1 ratio, so the ratio check alone lets it through)."""
    z = zlib.compressobj(9)
    parts = []
    block = b"\0" * (1 << 22)
    left = count * 8
    while left > 0:
        n = min(left, len(block))
        parts.append(z.compress(block[:n]))
        left -= n
    parts.append(z.flush())
    data = b"".join(parts)
    prop = b"d" + struct.pack("<III", count, 1, len(data)) + data

    def node(name, props, nprops, children=b"", start=0):
        name = name.encode()
        body_len = 13 + len(name) + len(props) + len(children) + (13 if children else 0)
        end = start + body_len
        rec = struct.pack("<IIIB", end, nprops, len(props), len(name)) + name + props
        if children:
            rec += children + b"\0" * 13
        return rec

    head = b"Kaydara FBX Binary  \x00\x1a\x00" + struct.pack("<I", 7400)
    rec = node("Vertices", prop, 1, start=len(head))
    return head + rec + b"\0" * 13


def gz(data_iter):
    buf = io.BytesIO()
    with gzip.GzipFile(fileobj=buf, mode="wb", compresslevel=6) as g:
        for d in data_iter:
            g.write(d)
    return buf.getvalue()


PBRT_HEAD = (
    'LookAt 0 0 5  0 0 0  0 1 0\nCamera "perspective" "float fov" 45\n'
    'WorldBegin\nLightSource "infinite" "rgb L" [1 1 1]\n'
)


def make_cases(root):
    """Writes every case into root/<name>/ and returns [(name, scene file, extra args)]."""
    cases = []

    def case(name, files, scene, args=(), serve=True):
        d = os.path.join(root, name)
        os.makedirs(d, exist_ok=True)
        for rel, data in files.items():
            p = os.path.join(d, rel)
            os.makedirs(os.path.dirname(p), exist_ok=True)
            if data is None:
                os.mkfifo(p)
            else:
                with open(p, "wb") as f:
                    f.write(data.encode() if isinstance(data, str) else data)
        cases.append((name, os.path.join(d, scene), list(args), serve))

    huge_exr = exr_claiming(100000, 100000)
    big_png = png(16384, 16384)
    sphere = 'Shape "sphere"\n'

    # Images: EXR header claiming 100000² as --env, as an imagemap; PNG 16384²; as a normal map.
    case("exr-env", {"huge.exr": huge_exr, "s.pbrt": PBRT_HEAD + sphere}, "s.pbrt",
         ["--env", "huge.exr"])
    case("exr-imagemap", {"huge.exr": huge_exr, "s.pbrt": PBRT_HEAD
          + 'Texture "t" "spectrum" "imagemap" "string filename" "huge.exr"\n'
          'Material "diffuse" "texture reflectance" "t"\n' + sphere}, "s.pbrt")
    case("png-16384", {"big.png": big_png, "s.pbrt": PBRT_HEAD
          + 'Texture "t" "spectrum" "imagemap" "string filename" "big.png"\n'
          'Material "diffuse" "texture reflectance" "t"\n' + sphere}, "s.pbrt")
    case("png-normal-map", {"big.png": big_png, "s.pbrt": PBRT_HEAD
          + 'Material "diffuse" "string normalmap" "big.png"\n' + sphere}, "s.pbrt")
    case("png-env", {"big.png": big_png, "s.pbrt": PBRT_HEAD + sphere}, "s.pbrt",
         ["--env", "big.png"])
    spellings = ["t/a.png", "./t/a.png", "t/./a.png", "t//a.png", "./t/.//a.png", "t/././a.png"]
    text = PBRT_HEAD
    for i, s in enumerate(spellings):
        text += (f'Texture "t{i}" "spectrum" "imagemap" "string filename" "{s}"\n'
                 f'Material "diffuse" "texture reflectance" "t{i}"\n'
                 f'AttributeBegin\nTranslate {i - 2.5} 0 0\nShape "sphere" "float radius" 0.4\nAttributeEnd\n')
    case("png-six-spellings", {"t/a.png": png(8192, 8192), "s.pbrt": text}, "s.pbrt")
    hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n" + b"\0" * 64
    case("hdr-env-claiming", {"huge.hdr": hdr, "s.pbrt": PBRT_HEAD + sphere}, "s.pbrt",
         ["--env", "huge.hdr"])
    case("pfm-env-claiming", {"huge.pfm": b"PF\n16384 16384\n-1.0\n" + b"\0" * 64,
                              "s.pbrt": PBRT_HEAD + sphere}, "s.pbrt", ["--env", "huge.pfm"])

    # glTF: a POSITION accessor without a buffer view, count 2^27; a FIFO as a buffer.
    gltf = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}], "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"componentType": 5126, "count": 1 << 27, "type": "VEC3",
                       "min": [0, 0, 0], "max": [0, 0, 0]}],
    }
    case("gltf-viewless-accessor", {"s.gltf": json.dumps(gltf)}, "s.gltf")
    fifo_gltf = {"asset": {"version": "2.0"}, "buffers": [{"uri": "pipe.bin", "byteLength": 12}]}
    case("gltf-fifo-buffer", {"pipe.bin": None, "s.gltf": json.dumps(fifo_gltf)}, "s.gltf",
         serve=False)

    # Meshes: a .ply.gz of zeros; huge finite coordinates.
    ply_header = (b"ply\nformat binary_little_endian 1.0\nelement vertex 200000000\n"
                  b"property float x\nproperty float y\nproperty float z\nelement face 0\n"
                  b"property list uchar int vertex_indices\nend_header\n")
    block = b"\0" * (1 << 22)
    zeros = (block for _ in range(150))  # 600 MiB of zeros, ~600 KB compressed
    case("ply-gz-zeros", {"z.ply.gz": gz(itertools.chain([ply_header], zeros)), "s.pbrt": PBRT_HEAD
          + 'Shape "plymesh" "string filename" "z.ply.gz"\n' + sphere}, "s.pbrt")
    case("obj-huge-coordinates", {"s.obj": "v 1e20 0 0\nv 0 1e20 0\nv 0 0 1e20\nv -1 -1 0\n"
                                  "v 1 -1 0\nv 0 1 0\nf 1 2 3\nf 4 5 6\n"}, "s.obj")

    # pbrt: 30 M integers; 3000 loopsubdiv level 6; include fan-out; FIFO include; cuts.
    ints = "0 " * 30_000_000
    case("pbrt-30m-integers", {"s.pbrt": PBRT_HEAD + 'Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] '
                               '"integer indices" [' + ints + "]\n"}, "s.pbrt")
    loop = ('Shape "loopsubdiv" "integer levels" 6 "point3 P" [0 0 0 1 0 0 0 1 0 1 1 0] '
            '"integer indices" [0 1 2 2 1 3]\n')
    case("pbrt-loopsubdiv-3000", {"s.pbrt": PBRT_HEAD + loop * 3000}, "s.pbrt")
    fan = {f"f{i}.pbrt": (f'Include "f{i + 1}.pbrt"\nInclude "f{i + 1}.pbrt"\n' if i < 25 else "# leaf\n")
           for i in range(26)}
    fan["s.pbrt"] = PBRT_HEAD + 'Include "f0.pbrt"\n' + sphere
    case("pbrt-include-fan-out", fan, "s.pbrt")
    case("pbrt-fifo-include", {"pipe.pbrt": None, "s.pbrt": PBRT_HEAD + 'Include "pipe.pbrt"\n'},
         "s.pbrt", serve=False)
    case("pbrt-negative-radius", {"s.pbrt": PBRT_HEAD + 'Shape "sphere" "float radius" -1\n' + sphere},
         "s.pbrt")
    case("pbrt-int-2^31", {"s.pbrt": PBRT_HEAD + 'Shape "sphere" "integer x" 2147483648\n'}, "s.pbrt")
    case("pbrt-bom", {"s.pbrt": "\ufeff" + PBRT_HEAD + sphere}, "s.pbrt")
    case("pbrt-deep-attributes", {"s.pbrt": PBRT_HEAD + "AttributeBegin\n" * 100000 + sphere}, "s.pbrt")

    # FBX: a zlib array within the allowed ratio that inflates to 1.2 GB (2.4 GB as values).
    case("fbx-zlib-zeros", {"s.fbx": fbx_with_zlib_array(150_000_000)}, "s.fbx")

    # TOML: a .vol grid claiming 4096³ voxels.
    vol = b"VOL\x03" + struct.pack("<iiiii", 1, 4096, 4096, 4096, 1) + struct.pack("<6f", 0, 0, 0, 1, 1, 1)
    case("toml-vol-claiming", {"g.vol": vol, "s.toml": (
        '[[material]]\nname = "m"\nmodel = "interface"\n'
        '[[medium]]\nname = "fog"\ntype = "grid"\nfile = "g.vol"\nsigma_s = [1.0, 1.0, 1.0]\n'
        '[[object]]\ntype = "sphere"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = "m"\n'
        'medium_inside = "fog"\n')}, "s.toml")

    return cases


# ---------------------------------------------------------------- running


def limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (AS_LIMIT, AS_LIMIT))
    os.setsid()


def classify(code, err, timed_out):
    """'render', 'error' (a clear one) or a failure description."""
    if timed_out:
        return "FAIL: timeout"
    if "panicked" in err or "RUST_BACKTRACE" in err:
        return "FAIL: panic"
    if "memory allocation of" in err:
        return "FAIL: allocation abort"
    if code < 0:
        return f"FAIL: killed by signal {-code}"
    if code == 0:
        return "render"
    if code == 1 and "error:" in err:
        return "error"
    return f"FAIL: exit {code}"


def run_cli(binary, cases, out_dir):
    results = []
    for name, scene, extra, _ in cases:
        args = [binary, "render", scene, "-o", os.path.join(out_dir, name + ".png"),
                "--width", "16", "--height", "16", "--spp", "1", "--quiet"]
        for i, a in enumerate(extra):
            # --env FILE is relative to the case's folder.
            if i > 0 and extra[i - 1] == "--env":
                a = os.path.join(os.path.dirname(scene), a)
            args.append(a)
        t0 = time.time()
        try:
            p = subprocess.run(args, capture_output=True, text=True, timeout=TIMEOUT,
                               preexec_fn=limit_memory, errors="replace")
            code, err, timed_out = p.returncode, p.stderr, False
        except subprocess.TimeoutExpired as e:
            code, err, timed_out = None, (e.stderr or b"").decode(errors="replace"), True
        dt = time.time() - t0
        verdict = classify(code, err, timed_out)
        line = err.strip().splitlines()[-1] if err.strip() else ""
        results.append((name, verdict, dt, line))
        print(f"{name:28} {verdict:24} {dt:5.1f}s  {line[:150]}", flush=True)
    return results


class Server:
    def __init__(self, binary, scenes, out):
        self.proc = subprocess.Popen(
            [binary, "serve", "--port", "0", "--scenes", scenes, "--output", out, "--no-token",
             "--max-jobs", "2", "--threads", "2"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=limit_memory)
        line = self.proc.stdout.readline()
        if "listening on" not in line:
            raise SystemExit(f"trayecto serve did not start: {line}{self.proc.stderr.read()}")
        self.base = line.split("listening on ")[1].strip().rstrip("/")

    def call(self, method, path, body=None, ctype="application/json", timeout=30):
        req = urllib.request.Request(self.base + path, data=body, method=method)
        if body is not None:
            req.add_header("Content-Type", ctype)
        try:
            with urllib.request.urlopen(req, timeout=timeout) as r:
                return r.status, r.read()
        except urllib.error.HTTPError as e:
            return e.code, e.read()

    def alive(self):
        try:
            return self.proc.poll() is None and self.call("GET", "/api/renders", timeout=10)[0] == 200
        except Exception:
            return False

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()


def zip_folder(folder):
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for base, _, files in os.walk(folder):
            for f in files:
                p = os.path.join(base, f)
                if os.path.isfile(p):
                    z.write(p, os.path.relpath(p, folder))
    return buf.getvalue()


def run_serve(binary, cases, root, out_dir):
    server = Server(binary, root, out_dir)
    results = []
    try:
        for name, scene, extra, serve in cases:
            t0 = time.time()
            rel = os.path.relpath(scene, root)
            notes = []
            if serve:
                data = zip_folder(os.path.dirname(scene))
                if len(data) < 100 << 20:
                    st, _ = server.call("POST", f"/api/uploads?name={name}.zip", data,
                                        "application/zip", timeout=60)
                    notes.append(f"upload {st}")
            req = {"scene": rel, "width": 16, "height": 16, "spp": 1, "output": name}
            if "--env" in extra:
                req["environment"] = os.path.join(os.path.dirname(rel), extra[extra.index("--env") + 1])
            st, body = server.call("POST", "/api/renders", json.dumps(req).encode())
            state = f"request {st}"
            if st in (200, 201, 202):
                job = json.loads(body)
                jid = job["id"]
                while time.time() - t0 < TIMEOUT:
                    st2, b2 = server.call("GET", f"/api/renders/{jid}")
                    if st2 != 200:
                        break
                    j = json.loads(b2)
                    state = j["state"]
                    if not j["active"]:
                        break
                    time.sleep(0.2)
                else:
                    server.call("POST", f"/api/renders/{jid}/cancel")
                    state = "FAIL: timeout"
            notes.append(state)
            try:
                st3, _ = server.call("GET", f"/api/scene-view?scene={urllib.request.quote(rel)}",
                                     timeout=TIMEOUT)
                notes.append(f"view {st3}")
            except Exception as e:  # a timeout or a dropped connection
                notes.append(f"FAIL: view {e}")
            ok = server.alive()
            verdict = "ok" if ok and not any(n.startswith("FAIL") for n in notes) else "FAIL"
            if not ok:
                verdict = "FAIL: server died"
            dt = time.time() - t0
            results.append((name, verdict, dt, ", ".join(notes)))
            print(f"{name:28} {verdict:20} {dt:5.1f}s  {', '.join(notes)}", flush=True)
            if not ok:
                break
    finally:
        server.stop()
    return results


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(os.path.dirname(__file__), "..", "target", "release", "trayecto"))
    ap.add_argument("--serve", action="store_true", help="run the cases through `trayecto serve`")
    ap.add_argument("--only", help="run only the cases whose name contains this")
    ap.add_argument("--keep", help="write the cases into this folder and keep them")
    a = ap.parse_args()
    binary = os.path.abspath(a.bin)
    root = a.keep or tempfile.mkdtemp(prefix="trayecto-hostile-")
    os.makedirs(root, exist_ok=True)
    out_dir = tempfile.mkdtemp(prefix="trayecto-hostile-out-")
    try:
        cases = make_cases(root)
        if a.only:
            cases = [c for c in cases if a.only in c[0]]
        print(f"{len(cases)} cases, {AS_LIMIT >> 30} GiB address space, {TIMEOUT:.0f} s each"
              + (" (through trayecto serve)" if a.serve else ""), flush=True)
        results = run_serve(binary, cases, root, out_dir) if a.serve else run_cli(binary, cases, out_dir)
        failed = [r for r in results if r[1].startswith("FAIL")]
        print(f"\n{len(results) - len(failed)}/{len(results)} passed"
              + (f"; failed: {', '.join(r[0] for r in failed)}" if failed else ""))
        return 1 if failed else 0
    finally:
        shutil.rmtree(out_dir, ignore_errors=True)
        if not a.keep:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
