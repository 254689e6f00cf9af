#!/bin/sh
# Motion blur's cost: peak resident set and render time of blurred scenes (a skinned mesh, a
# moving object, the pbrt scene, a pbrt scene with a moving emitter, 16 moving instances of a
# shared 70 k-triangle mesh from bench/moving_instances.py) and of a still, for two binaries,
# runs interleaved
# (docs/DESIGN.md "Motion blur", BENCHMARKS.md "Continuous motion blur").
#   scripts/motion-bench.sh OLD_BINARY NEW_BINARY [ROUNDS] [CASE...]
# (no CASE: every case). Prints one line per run: binary, case, world compiled ms, rendered ms,
# peak RSS kB.
set -e
old=$1
new=$2
rounds=${3:-3}
shift 2
[ $# -gt 0 ] && shift
only="$*"
here=$(cd "$(dirname "$0")/.." && pwd)
shared="$here/../shared/scenes"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
python3 "$(dirname "$0")/../bench/moving_instances.py" "$out/instances.gltf"
run() {
    bin=$1
    name=$2
    shift 2
    case " $only " in
    "  " | *" $name "*) ;;
    *) return 0 ;;
    esac
    nice -n 10 /usr/bin/time -v "$bin" render "$@" --width 128 --height 128 --threads 2 \
        -o "$out/img.exr" >"$out/log" 2>&1 || { cat "$out/log"; exit 1; }
    compiled=$(sed -n 's/^world compiled *\([0-9.]*\) ms.*/\1/p' "$out/log")
    rendered=$(sed -n 's/^rendered ([a-z]*) *\([0-9.]*\) ms.*/\1/p' "$out/log")
    rss=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$out/log")
    echo "$(basename "$bin") $name $compiled $rendered $rss"
}
cases() {
    bin=$1
    run "$bin" skinned "$shared/gltf-anim/CesiumMan/glTF-Binary/CesiumMan.glb" \
        --shutter 0.2,0.9 --spp 64
    run "$bin" skinned-64keys "$shared/gltf-anim/CesiumMan/glTF-Binary/CesiumMan.glb" \
        --shutter 0.2,0.9 --shutter-steps 64 --spp 64
    run "$bin" moving-box "$shared/gltf-anim/BoxAnimated/glTF-Binary/BoxAnimated.glb" \
        --shutter 0.6,1.6 --spp 64
    run "$bin" pbrt "$here/scenes/pbrt/motion-blur.pbrt" --spp 64
    run "$bin" pbrt-emitter "$here/scenes/pbrt/motion-blur-emitter.pbrt" --spp 64
    run "$bin" instances "$out/instances.gltf" --shutter 0,1 --spp 64
    run "$bin" instances-still "$out/instances.gltf" --time 0.5 --spp 64
    run "$bin" still "$shared/gltf-anim/CesiumMan/glTF-Binary/CesiumMan.glb" --time 0.5 \
        --spp 64
}
i=0
while [ "$i" -lt "$rounds" ]; do
    cases "$old"
    cases "$new"
    i=$((i + 1))
done
