#!/usr/bin/env bash
# Browser end-to-end test of the web UI (`trayecto serve`): installs Debian's chromium (if missing)
# and playwright-core (from e2e/package-lock.json), builds the release binary, starts the server on
# a free port with a temporary output folder, and runs e2e/webui.test.mjs with node's test runner.
# WEBUI_SCREENSHOT=docs/webui.png also takes the README's screenshot.
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

echo "== cargo build --release"
cargo build --release
bin="${CARGO_TARGET_DIR:-target}/release/trayecto"

tmp="$(mktemp -d)"
pid=""
cleanup() {
  if [ -n "$pid" ]; then kill "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; fi
  rm -rf "$tmp"
}
trap cleanup EXIT

"$bin" serve --port 0 --output "$tmp/out" >"$tmp/server.log" 2>&1 &
pid=$!
addr=""
for _ in $(seq 1 200); do
  addr="$(sed -n 's#^trayecto serve: listening on \(http://[^/]*\)/$#\1#p' "$tmp/server.log")"
  [ -n "$addr" ] && break
  if ! kill -0 "$pid" 2>/dev/null; then break; fi
  sleep 0.1
done
if [ -z "$addr" ]; then
  echo "the server did not start:" >&2
  cat "$tmp/server.log" >&2
  exit 1
fi
echo "== e2e against $addr"
if [ -n "${WEBUI_SCREENSHOT:-}" ]; then
  WEBUI_SCREENSHOT="$(realpath -m "$WEBUI_SCREENSHOT")"
  export WEBUI_SCREENSHOT
fi
TRAYECTO_URL="$addr" node --test e2e/webui.test.mjs
