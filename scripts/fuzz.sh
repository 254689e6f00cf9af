#!/usr/bin/env bash
# Fuzzes every target in fuzz/Cargo.toml for a short fixed time (scripts/test.sh runs it): installs
# cargo-fuzz if missing, builds all targets once without a sanitizer, seeds each target's corpus
# with the regression cases under tests/hostile/<target>/ and a few small valid files, and runs
# it under a memory limit. Fails if any target finds a crash, an out-of-memory or a timeout; the
# input is left under target/fuzz/artifacts/<target>/ (add it to tests/hostile/<target>/ once fixed).
#
#   scripts/fuzz.sh                  every target, FUZZ_SECONDS (default 5) each
#   scripts/fuzz.sh pbrt 600         one target for ten minutes (its corpus is kept between runs)
#
# Needs a nightly toolchain for libFuzzer's instrumentation flags; without one it sets
# RUSTC_BOOTSTRAP=1 on the default toolchain (the same compiler, its unstable flags unlocked).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD

ONLY="${1:-}"
SECS="${2:-${FUZZ_SECONDS:-5}}"
# libFuzzer's limits: the process's resident memory, one allocation, one input's run time; a
# fixed seed (FUZZ_SEED) so that what a CI run finds, the same run finds again.
LIMITS=(-rss_limit_mb=3072 -malloc_limit_mb=2048 -timeout=20 -max_len=65536 -seed="${FUZZ_SEED:-1}")

if rustup toolchain list 2>/dev/null | grep -q '^nightly'; then
    TOOLCHAIN=(+nightly)
else
    echo "note: no nightly toolchain; building the fuzz targets with RUSTC_BOOTSTRAP=1" >&2
    export RUSTC_BOOTSTRAP=1
    TOOLCHAIN=()
fi
if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "== installing cargo-fuzz (crates.io)"
    cargo install cargo-fuzz --locked
fi

# Every [[bin]] of the fuzz crate, in file order.
mapfile -t TARGETS < <(awk '/^\[\[bin\]\]/{b=1; next} b && /^name *=/{gsub(/.*= *"|".*/, ""); print; b=0}' fuzz/Cargo.toml)
if [[ -n "$ONLY" ]]; then
    if ! printf '%s\n' "${TARGETS[@]}" | grep -qx "$ONLY"; then
        echo "error: no fuzz target '$ONLY' (targets: ${TARGETS[*]})" >&2
        exit 2
    fi
    TARGETS=("$ONLY")
fi

start=$(date +%s)
echo "== building ${#TARGETS[@]} fuzz target(s) (cargo fuzz build --sanitizer none)"
cargo "${TOOLCHAIN[@]}" fuzz build --sanitizer none ${ONLY:+"$ONLY"}
echo "   built in $(($(date +%s) - start)) s"
BIN="fuzz/target/x86_64-unknown-linux-gnu/release"

# Small valid inputs to start from (the regression cases are added to every run).
SHARED="$ROOT/../shared/scenes"
seeds() {
    case "$1" in
        # With three small animated models (node TRS, morph targets, every interpolation),
        # whose motion the entry builds at a moment and over a shutter.
        gltf) ls scenes/gltf_bsdf_extensions.gltf scenes/gltf-files/*.glb \
            "$SHARED"/gltf-anim/{AnimatedMorphCube,BoxAnimated,InterpolationTest}/glTF-Binary/*.glb ;;
        toml) ls scenes/*.toml scenes/media/*.toml ;;
        pbrt) ls scenes/pbrt/*.pbrt scenes/pbrt/media/*.pbrt ;;
        obj) ls "$SHARED"/mitsuba/common/meshes/cbox/*.obj ;;
        ply) ls "$SHARED"/ply/stanford-bunny/bun_zipper_res4.ply ;;
        mtl) ls "$SHARED"/obj/cornell-box-original-data/*.mtl ;;
    esac 2>/dev/null || true
}

failed=()
for t in "${TARGETS[@]}"; do
    corpus="target/fuzz/corpus/$t"
    artifacts="target/fuzz/artifacts/$t"
    mkdir -p "$corpus" "$artifacts"
    seeds "$t" | while read -r f; do cp "$f" "$corpus/"; done
    if [[ -d "tests/hostile/$t" ]]; then
        cp tests/hostile/"$t"/* "$corpus/" 2>/dev/null || true
    fi
    echo "== fuzz $t for ${SECS} s ($(find "$corpus" -type f | wc -l) inputs in the corpus)"
    if ! "$BIN/$t" "${LIMITS[@]}" -max_total_time="$SECS" -print_final_stats=0 \
        -artifact_prefix="$artifacts/" "$corpus" > "target/fuzz/$t.log" 2>&1; then
        tail -n 40 "target/fuzz/$t.log" >&2
        echo "FAILED: fuzz target $t (input under $artifacts/, log target/fuzz/$t.log)" >&2
        failed+=("$t")
    else
        grep -E '^#[0-9]+ *DONE' "target/fuzz/$t.log" || tail -n 1 "target/fuzz/$t.log"
    fi
done
echo "   fuzzing took $(($(date +%s) - start)) s in all"
if ((${#failed[@]})); then
    echo "error: fuzz targets failed: ${failed[*]}" >&2
    exit 1
fi
