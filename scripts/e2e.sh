#!/usr/bin/env bash
# Browser end-to-end test of the web UI (`trayecto serve`): installs Debian's chromium (if missing)
# and playwright-core (from e2e/package-lock.json), builds the binary with the `test` profile (the one
# `cargo test` and the farm test already built: no second optimised build in CI), starts the server on
# a free port with a temporary output folder, and runs e2e/webui.test.mjs with node's test runner.
# WEBUI_SCREENSHOT=docs/viewport.png also takes the screenshot the README shows (the viewport mid-orbit).
set -euo pipefail
cd "$(dirname "$0")/.."

if [ ! -x /usr/bin/chromium ]; then
  echo "== installing chromium"
  SUDO=""
  if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update
  $SUDO apt-get install -y chromium
fi

echo "== npm ci (e2e)"
(cd e2e && npm ci --no-audit --no-fund)

echo "== cargo build --profile test --bin trayecto"
cargo build --profile test --bin trayecto
bin="${CARGO_TARGET_DIR:-target}/debug/trayecto"

tmp="$(mktemp -d)"
pid=""
pid2=""
cleanup() {
  for p in $pid $pid2; do kill "$p" 2>/dev/null || true; wait "$p" 2>/dev/null || true; done
  rm -rf "$tmp"
}
trap cleanup EXIT

# Waits for the server logging to $1 (pid $2) to print its address; prints it.
address_of() {
  local a=""
  for _ in $(seq 1 200); do
    a="$(sed -n 's#^trayecto serve: listening on \(http://[^/]*\)/$#\1#p' "$1")"
    [ -n "$a" ] && break
    if ! kill -0 "$2" 2>/dev/null; then break; fi
    sleep 0.1
  done
  if [ -z "$a" ]; then
    echo "the server did not start:" >&2
    cat "$1" >&2
    exit 1
  fi
  echo "$a"
}

# The main server: one render at a time (the queue test needs it), an empty scenes folder to
# upload into.
mkdir -p "$tmp/scenes"
# An environment map to light the screenshot's model.
cp ../shared/scenes/hdr/studio_small_03_1k.hdr "$tmp/scenes/"
# A glTF quad with material variants (KHR_materials_variants) for the variant picker.
cp scenes/gltf-files/quad_variants.gltf "$tmp/scenes/"
# A pbrt-v4 scene with an orthographic camera (the viewport keeps its projection).
cp scenes/pbrt/orthographic.pbrt "$tmp/scenes/"
"$bin" serve --port 0 --max-jobs 1 --scenes "$tmp/scenes" --output "$tmp/out" >"$tmp/server.log" 2>&1 &
pid=$!
addr="$(address_of "$tmp/server.log" "$pid")" || exit 1
# A second one on 127.0.0.2, which is not 127.0.0.1 and so needs the token it prints.
"$bin" serve --host 127.0.0.2 --port 0 --output "$tmp/out2" >"$tmp/server2.log" 2>&1 &
pid2=$!
addr2="$(address_of "$tmp/server2.log" "$pid2")" || exit 1
for _ in $(seq 1 50); do grep -q '?token=' "$tmp/server2.log" && break; sleep 0.1; done
token_url="$(sed -n 's#^access token required; open the page at \(http://.*\)$#\1#p' "$tmp/server2.log")"
export TRAYECTO_TOKEN_SERVER="$addr2" TRAYECTO_TOKEN_URL="$token_url"
echo "== e2e against $addr (and $addr2 with a token)"
if [ -n "${WEBUI_SCREENSHOT:-}" ]; then
  WEBUI_SCREENSHOT="$(realpath -m "$WEBUI_SCREENSHOT")"
  export WEBUI_SCREENSHOT
fi
TRAYECTO_URL="$addr" node --test e2e/webui.test.mjs
