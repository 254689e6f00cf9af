#!/bin/sh
# Regenerates README.md's options tables from clap's definitions (src/bin/trayecto/cli.rs and
# server/mod.rs); the test `readme::readme_options_tables_match_clap` fails until this is run.
set -e
cd "$(dirname "$0")/.."
TRAYECTO_REGENERATE_README=1 cargo test --bin trayecto readme_options_tables_match_clap -- --quiet
