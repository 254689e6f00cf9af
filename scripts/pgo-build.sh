#!/usr/bin/env bash
# Profile-guided release build of the `trayecto` binary.
#
#   ./scripts/pgo-build.sh            # prints the path of the optimised binary on its last line
#
# Three steps (rustc book, "Profile-guided Optimization"):
#   1. build an instrumented release binary (-Cprofile-generate) in target/pgo-gen;
#   2. train it on the repository's scenes (the Mitsuba test scenes: quads, boxes and spheres,
#      glass, metals, textures, environment and punctual lights; the example scene; the glTF/PLY
#      twin scene's triangle meshes; the path, Whitted and ray-cast integrators) and, when
#      ../shared/scenes is there, on glTF sample models and the original Cornell box data (an OBJ
#      triangle mesh: the one closed, diffusely inter-reflecting interior of the set). None of
#      bench/compare.py's scenes is among them (its Cornell box is the built-in one, quads and
#      boxes; BENCHMARKS.md, "Tried, did not pay", says why it is not trained on);
#   3. merge the profiles with llvm-profdata and rebuild with -Cprofile-use in target/pgo.
# The binary renders exactly the same images as `cargo build --release` (PGO only changes code
# layout, inlining and branch order); it is faster: see BENCHMARKS.md, "Other measurements".
#
# llvm-profdata must read the profiles of rustc's own LLVM. It is looked up as $LLVM_PROFDATA,
# then in rustup's llvm-tools component (installed with `rustup component add llvm-tools` when
# missing), then as llvm-profdata-<rustc's LLVM major> on the PATH (Debian's llvm-<major>).
# Without it the script stops with a message and exit code 2, and nothing is built.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)

llvm_major=$(rustc -vV | sed -n 's/^LLVM version: \([0-9]*\).*/\1/p')
host=$(rustc -vV | sed -n 's/^host: //p')
find_profdata() {
    if [[ -n "${LLVM_PROFDATA:-}" ]]; then
        echo "$LLVM_PROFDATA"
        return
    fi
    local tools
    tools="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-profdata"
    if [[ ! -x "$tools" ]] && command -v rustup >/dev/null; then
        rustup component add llvm-tools >&2 || true
    fi
    if [[ -x "$tools" ]]; then
        echo "$tools"
        return
    fi
    if command -v "llvm-profdata-$llvm_major" >/dev/null; then
        command -v "llvm-profdata-$llvm_major"
    fi
}
profdata=$(find_profdata)
if [[ -z "$profdata" || ! -x "$profdata" ]]; then
    echo "pgo-build: no usable llvm-profdata for LLVM $llvm_major (${profdata:-none found}; set LLVM_PROFDATA, or install rustup's llvm-tools or Debian's llvm-$llvm_major)" >&2
    exit 2
fi

profiles="$root/target/pgo-profiles"
rm -rf "$profiles"
mkdir -p "$profiles"
echo "[pgo] 1/3 instrumented build (target/pgo-gen)" >&2
RUSTFLAGS="-Cprofile-generate=$profiles/raw" \
    cargo build --release --quiet --bin trayecto --target-dir "$root/target/pgo-gen"

echo "[pgo] 2/3 training renders" >&2
# Only the training renders' profiles: the instrumented build scripts wrote theirs during step 1.
rm -rf "$profiles/raw"
gen="$root/target/pgo-gen/release/trayecto"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
train() { "$gen" render "$@" --threads 2 -q -o "$out/train.exr"; }
train scenes/example.toml --width 64 --height 64 --spp 16 --sampler sobol
train scenes/example.toml --width 64 --height 64 --spp 16 --integrator whitted
train scenes/example.toml --width 64 --height 64 --spp 4 --integrator raycast
for scene in scenes/mitsuba/*.toml scenes/twin/twin.toml scenes/twin/twin.gltf scenes/example.toml; do
    train "$scene" --width 64 --height 64 --spp 32
done
# Triangle meshes as artists export them (glTF metallic-roughness) and a closed interior (the
# original Cornell box OBJ): the third-party scenes beside the checkout (../shared/scenes, as the
# tests use them), when they are there. Without them the build gains less (BENCHMARKS.md).
shared="$root/../shared/scenes"
for scene in gltf/DamagedHelmet/glTF-Binary/DamagedHelmet.glb \
    gltf/MetalRoughSpheresNoTextures/glTF-Binary/MetalRoughSpheresNoTextures.glb \
    gltf/TransmissionTest/glTF-Binary/TransmissionTest.glb \
    gltf/NormalTangentTest/glTF-Binary/NormalTangentTest.glb \
    obj/cornell-box-original-data/cornell_box.obj; do
    if [[ -f "$shared/$scene" ]]; then
        train "$shared/$scene" --width 64 --height 64 --spp 32
    else
        echo "[pgo] not found, not trained on: $shared/$scene" >&2
    fi
done
"$profdata" merge -o "$profiles/merged.profdata" "$profiles/raw"
# Cargo does not fingerprint the profile's contents, only RUSTFLAGS: naming the file after its
# hash makes a new profile rebuild the binary instead of reusing one optimised for an old profile.
profile="$profiles/merged-$(sha256sum "$profiles/merged.profdata" | cut -c1-16).profdata"
mv "$profiles/merged.profdata" "$profile"

echo "[pgo] 3/3 optimised build (target/pgo)" >&2
RUSTFLAGS="-Cprofile-use=$profile -Cllvm-args=-pgo-warn-missing-function=false" \
    cargo build --release --quiet --bin trayecto --target-dir "$root/target/pgo"
echo "$root/target/pgo/release/trayecto"
