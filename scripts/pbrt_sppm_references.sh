#!/usr/bin/env bash
# Renders pbrt-v4 SPPM references of the scenes whose pbrt files ask for `Integrator "sppm"`, at a
# quarter of their resolution, with the pbrt-v4 build in ../shared/tools/pbrt-v4, into
# tests/references/pbrt/NAME-sppm.exr (docs/DESIGN.md, "Photon mapping: SPPM and VCM").
# The file's own integrator settings (radius, maxdepth) are kept; only the resolution and the
# iteration count change. Usage: scripts/pbrt_sppm_references.sh [ITERATIONS]   (default 512)
# Bitterli's glass-of-water is not in ../shared/scenes: its pbrt-v4 reference (BDPT, as its file asks) is
# made by `bench/glass_of_water.py --make-reference --scene DIR`.
set -euo pipefail
cd "$(dirname "$0")/.."
PBRT=$(realpath ../shared/tools/pbrt-v4/pbrt)
SPP=${1:-512}
if [ ! -x "$PBRT" ]; then
  echo "pbrt-v4 not found at $PBRT (see ../shared/tools/pbrt-v4/README.md)" >&2
  exit 2
fi
mkdir -p tests/references/pbrt
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for name in water-caustic; do
  src=$(realpath "../shared/scenes/pbrt/$name")
  mkdir -p "$tmp/$name"
  # The scene's models are read relative to the file: link them beside the edited copy.
  for f in "$src"/*; do ln -s "$f" "$tmp/$name/"; done
  rm "$tmp/$name/scene-v4.pbrt"
  sed -e 's/"integer yresolution" \[ 1024 \]/"integer yresolution" [ 256 ]/' \
      -e 's/"integer xresolution" \[ 1024 \]/"integer xresolution" [ 256 ]/' \
      "$src/scene-v4.pbrt" > "$tmp/$name/scene-v4.pbrt"
  grep -q '"integer xresolution" \[ 256 \]' "$tmp/$name/scene-v4.pbrt"
  echo "== $name (pbrt-v4 sppm, 256x256, $SPP iterations)"
  nice -n 19 "$PBRT" --nthreads 2 --spp "$SPP" --outfile "$PWD/tests/references/pbrt/$name-sppm.exr" \
    "$tmp/$name/scene-v4.pbrt"
done
