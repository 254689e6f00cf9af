#!/usr/bin/env bash
# The pictures of a first render with no options (README "A first render", guide "View
# transform"): DamagedHelmet, the Stanford bunny and the Cornell box as `trayecto render FILE`
# makes them, and the helmet and bunny with the old default (`--tonemap clamp`) for the
# before/after. Only `-o` and `--height 256` are given (the size, to keep the repository small;
# the width follows the camera). Usage: scripts/first-renders.sh [BINARY]
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${1:-target/release/trayecto}"
shared=../shared/scenes
helmet="$shared/gltf/DamagedHelmet/glTF-Binary/DamagedHelmet.glb"
bunny="$shared/ply/stanford-bunny/bun_zipper_res2.ply"
for tm in pbr-neutral clamp; do
  suffix=""; [ "$tm" = clamp ] && suffix="-clamp"
  nice -n 10 "$bin" render "$helmet" -o "docs/first-helmet$suffix.png" --height 256 --tonemap "$tm" -q
  nice -n 10 "$bin" render "$bunny" -o "docs/first-bunny$suffix.png" --height 256 --tonemap "$tm" -q
done
nice -n 10 "$bin" render cornell -o docs/first-cornell.png --height 256 -q
