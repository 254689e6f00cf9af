#!/usr/bin/env bash
# The pictures of a first render with no options (README "A first render", guide "View
# transform"): DamagedHelmet, the Stanford bunny and the Cornell box as `trayecto render FILE`
# makes them, and the helmet and bunny as the defaults before made them (a uniform white sky,
# `--default-light uniform`, and `--tonemap clamp`) for the before/after. Only `-o` and
# `--height 256` are given (the size, to keep the repository small; the width follows the
# camera). Then the measurements of docs/DESIGN.md, "The default light": each model rendered
# with `--transparent` (so that its pixels can be told from the background) under the uniform
# sky and the studio, read by scripts/png_stats.py (numpy).
# Usage: scripts/first-renders.sh [BINARY] [PYTHON]
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${1:-target/release/trayecto}"
py="${2:-python3}"
shared=../shared/scenes
helmet="$shared/gltf/DamagedHelmet/glTF-Binary/DamagedHelmet.glb"
bunny="$shared/ply/stanford-bunny/bun_zipper_res2.ply"
render() { nice -n 10 "$bin" render "$@" -q; }
render "$helmet" -o docs/first-helmet.png --height 256
render "$bunny" -o docs/first-bunny.png --height 256
render cornell -o docs/first-cornell.png --height 256
render "$helmet" -o docs/first-helmet-before.png --height 256 --default-light uniform --tonemap clamp
render "$bunny" -o docs/first-bunny-before.png --height 256 --default-light uniform --tonemap clamp
rm -f docs/first-helmet-clamp.png docs/first-bunny-clamp.png
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for model in "$helmet" "$bunny" \
  "$shared/gltf/MetalRoughSpheresNoTextures/glTF/MetalRoughSpheresNoTextures.gltf" \
  "$shared/gltf/BoxTextured/glTF-Binary/BoxTextured.glb" \
  "$shared/gltf-ext/SheenCloth/glTF/SheenCloth.gltf"; do
  name=$(basename "${model%.*}")
  for light in uniform auto; do
    render "$model" -o "$out/$name-$light.png" --height 128 --spp 16 --transparent --default-light "$light"
  done
done
"$py" scripts/png_stats.py "$out"/*.png | sed "s|$out/||"
