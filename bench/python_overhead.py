#!/usr/bin/env python3
"""The Python package's overhead over the command line (BENCHMARKS.md, "Python overhead"): a
64x64 1-spp render of the built-in Cornell box, each run in a fresh process. The CLI's cost is the
sum of its phases as it reports them (load, build, acceleration, render, write: its `total`
line, process start and argument parsing excluded); Python's is load_file + render + numpy() +
write of the same PNG, timed inside the process after `import trayecto` (interpreter start and
import excluded likewise). Medians of RUNS runs.

    python3 bench/python_overhead.py TRAYECTO_BIN [RUNS]   # with the package installed
"""

import re
import statistics
import subprocess
import sys
import tempfile

PY = """
import time, trayecto
t = time.perf_counter()
scene = trayecto.load_file("cornell")
img = trayecto.render(scene, width=64, height=64, spp=1)
img.numpy()
img.write({out!r})
print((time.perf_counter() - t) * 1e3)
"""


def main():
    binary = sys.argv[1]
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 15
    with tempfile.TemporaryDirectory() as d:
        cli, py = [], []
        for _ in range(runs):
            r = subprocess.run([binary, "render", "cornell", "--width", "64", "--height", "64",
                                "--spp", "1", "-o", f"{d}/cli.png"],
                               capture_output=True, text=True, check=True)
            cli.append(float(re.search(r"^total\s+([\d.]+) ms", r.stdout + r.stderr, re.M)[1]))
            r = subprocess.run([sys.executable, "-c", PY.format(out=f"{d}/py.png")],
                               capture_output=True, text=True, check=True)
            py.append(float(r.stdout.strip()))
    c, p = statistics.median(cli), statistics.median(py)
    print(f"CLI phases (median of {runs}): {c:.2f} ms")
    print(f"Python load+render+numpy+write (median of {runs}): {p:.2f} ms")
    print(f"Python / CLI: {p / c:.3f} ({(p / c - 1) * 100:+.1f} %)")


if __name__ == "__main__":
    main()
