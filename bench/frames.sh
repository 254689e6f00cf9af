#!/usr/bin/env bash
# A sequence of N frames in one run (`--frames 1..N`: the scene read once, posed and compiled per
# frame) against N separate runs (`--frame K` each: the scene read N times), wall time of each.
#   bench/frames.sh [TRAYECTO] [SCENE] [N]
# Run from the repository root; small renders, so loading is a visible share of the cost.
set -euo pipefail
bin=${1:-target/release/trayecto}
scene=${2:-../shared/scenes/gltf-anim/CesiumMan/glTF/CesiumMan.gltf}
n=${3:-12}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
opts=(--width 96 --height 96 --spp 4 --quiet --threads 2)
t0=$(date +%s.%N)
"$bin" render "$scene" "${opts[@]}" --frames "1..$n" -o "$tmp/seq.exr"
t1=$(date +%s.%N)
for k in $(seq 1 "$n"); do
  "$bin" render "$scene" "${opts[@]}" --frame "$k" -o "$tmp/one_$k.exr"
done
t2=$(date +%s.%N)
# The frames agree bit for bit either way.
for k in $(seq 1 "$n"); do
  cmp -s "$tmp/seq_$(printf %04d "$k").exr" "$tmp/one_$k.exr" || { echo "frame $k differs" >&2; exit 1; }
done
printf 'scene %s, %d frames: one run %.2f s, %d runs %.2f s (%.2fx)\n' "$(basename "$scene")" "$n" \
  "$(echo "$t1 - $t0" | bc)" "$n" "$(echo "$t2 - $t1" | bc)" "$(echo "($t2 - $t1) / ($t1 - $t0)" | bc -l)"
