#!/bin/sh
# Regenerates the guide's options tables (docs/src/rendering.md for `render`, docs/src/web-ui.md for
# `serve`) from clap's definitions (src/bin/trayecto/cli.rs and server/mod.rs); the test
# `readme::readme_options_tables_match_clap` fails until this is run.
set -e
cd "$(dirname "$0")/.."
TRAYECTO_REGENERATE_README=1 cargo test --bin trayecto readme_options_tables_match_clap -- --quiet
