#!/usr/bin/env bash
# Renders the pbrt-v4 reference images of the importer's feature scenes (scenes/pbrt/*.pbrt) with
# the pbrt-v4 build in ../shared/tools/pbrt-v4 and writes them to tests/references/pbrt/NAME.exr.
# The resolution and sample count are the scenes' own (small, for fast tests) unless SPP is set.
# Usage: scripts/pbrt_references.sh [SPP] [NAME...]   (default 1024 samples per pixel, every scene;
# NAMEs are scenes/pbrt/NAME.pbrt, e.g. envmap-sky or media/fog_cornell)
set -euo pipefail
cd "$(dirname "$0")/.."
PBRT=../shared/tools/pbrt-v4/pbrt
SPP=${1:-1024}
shift || true
if [ ! -x "$PBRT" ]; then
  echo "pbrt-v4 not found at $PBRT (see ../shared/tools/pbrt-v4/README.md)" >&2
  exit 2
fi
mkdir -p tests/references/pbrt
if [ $# -gt 0 ]; then
  scenes=()
  for n in "$@"; do scenes+=("scenes/pbrt/$n.pbrt"); done
else
  scenes=(scenes/pbrt/*.pbrt)
fi
for scene in "${scenes[@]}"; do
  name=${scene#scenes/pbrt/}
  name=${name%.pbrt}
  mkdir -p "$(dirname "tests/references/pbrt/$name.exr")"
  echo "== $name ($SPP spp)"
  "$PBRT" --nthreads 2 --spp "$SPP" --outfile "tests/references/pbrt/$name.exr" "$scene"
done
