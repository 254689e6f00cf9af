#!/usr/bin/env bash
# pbrt-v4 BDPT references of the light-path scenes (veach-bidir, water-caustic, volumetric-caustic
# from ../shared/scenes/pbrt), for tests/light_paths.rs and the BDPT benchmarks. Each scene file is
# copied with its Integrator replaced by pbrt-v4's "bdpt" (the file's maxdepth kept) and its film
# set to RES × RES; the copy sits in a temporary folder of symbolic links to the scene's own
# files, so relative paths resolve as in the original. Output: tests/references/pbrt/bdpt/NAME-RES.exr.
#
#   scripts/references/pbrt_bdpt_references.sh RES SPP [NAME...]
#
# Run with `nice`: the renders share the machine (e.g. RES 64, SPP 4096: a few minutes each).
set -euo pipefail
cd "$(dirname "$0")/../.."
PBRT=../shared/tools/pbrt-v4/pbrt
RES=${1:?resolution}
SPP=${2:?samples per pixel}
shift 2
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(veach-bidir water-caustic volumetric-caustic)
out=${OUT:-tests/references/pbrt/bdpt}
mkdir -p "$out"
for name in "${names[@]}"; do
  src=../shared/scenes/pbrt/$name
  tmp=$(mktemp -d)
  for f in "$src"/*; do ln -s "$(realpath "$f")" "$tmp/$(basename "$f")"; done
  rm "$tmp/scene-v4.pbrt"
  # The first Integrator line (commented alternatives are left alone) becomes bdpt, keeping its
  # maxdepth and dropping the parameters bdpt does not have (SPPM's radius: pbrt-v4 refuses
  # unused parameters); the film's resolution lines become RES.
  awk -v res="$RES" '
    /^Integrator / && !done { print "Integrator \"bdpt\""; done = 1; params = 1; next }
    params && /^[[:space:]]+"/ { if ($0 ~ /maxdepth/) print; next }
    { params = 0 }
    /^[[:space:]]*"integer (x|y)resolution"/ { sub(/\[ *[0-9]+ *\]/, "[ " res " ]") }
    { print }
  ' "$src/scene-v4.pbrt" >"$tmp/scene-v4.pbrt"
  echo "== $name: ${RES}x${RES}, $SPP spp"
  /usr/bin/time -f "   %e s wall, %U s user" \
    "$PBRT" --quiet --nthreads 2 --spp "$SPP" --outfile "$out/$name-$RES.exr" "$tmp/scene-v4.pbrt"
  rm -rf "$tmp"
done
