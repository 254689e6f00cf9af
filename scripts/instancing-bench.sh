#!/usr/bin/env bash
# Peak memory and time of a scene of many instances of one mesh: 4000 pbrt ObjectInstances of an
# 8192-triangle object (a 64×64 height-field grid), rendered at 32×32, 1 spp, so the load and the
# world build dominate. Usage: scripts/instancing-bench.sh BINARY [BINARY...]
# Prints /usr/bin/time's peak resident set and wall time, and the render's own phase lines, per
# binary (BENCHMARKS.md, "Instancing").
set -euo pipefail
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
scene="$dir/instances.pbrt"
python3 - "$scene" <<'PY'
import math, sys
n = 64
pts, idx = [], []
for j in range(n + 1):
    for i in range(n + 1):
        x, z = i / n - 0.5, j / n - 0.5
        pts.append(f"{x:.5f} {0.05 * math.sin(9 * x) * math.cos(7 * z):.5f} {z:.5f}")
for j in range(n):
    for i in range(n):
        a = j * (n + 1) + i
        idx += [a, a + 1, a + n + 2, a, a + n + 2, a + n + 1]
with open(sys.argv[1], "w") as f:
    f.write('LookAt 0 40 90  0 0 0  0 1 0\nCamera "perspective" "float fov" 40\n')
    f.write('Film "rgb" "integer xresolution" 32 "integer yresolution" 32 "string filename" "x.exr"\n')
    f.write('Sampler "independent" "integer pixelsamples" 1\nWorldBegin\n')
    f.write('LightSource "infinite" "rgb L" [1 1 1]\n')
    f.write('ObjectBegin "tile"\nShape "trianglemesh" "point3 P" [\n' + "\n".join(pts) + ' ]\n')
    f.write('"integer indices" [\n' + " ".join(map(str, idx)) + " ]\nObjectEnd\n")
    for k in range(4000):
        x, z = k % 80 - 40, k // 80 - 25
        f.write(f"AttributeBegin\nTranslate {x} 0 {z}\nRotate {k * 37 % 360} 0 1 0\n"
                'ObjectInstance "tile"\nAttributeEnd\n')
PY
for bin in "$@"; do
    echo "== $bin"
    /usr/bin/time -v "$bin" "$scene" -o "$dir/out.exr" --quiet 2>"$dir/time.txt" || {
        tail -5 "$dir/time.txt"
        continue
    }
    grep -E "Maximum resident|Elapsed \(wall" "$dir/time.txt"
done
