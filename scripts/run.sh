#!/usr/bin/env bash
# The project's main job, from a fresh clone: build the host tool and run it.
#
# For now the main job is the impact model of the reference paper on its Fig. 5
# example (a pinned body whose corner strikes a wall): first as a table for a person,
# then as the JSON document other tools read (docs/cli-impact.md). Later issues
# make it simulate the machine.
#
# Needs only cargo; the first run compiles host-sim (well under a minute).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

CASE="examples/impact/fig5-rotating-body.toml"

if ! command -v cargo >/dev/null; then
    echo "error: cargo not found: install Rust with rustup (https://rustup.rs)" >&2
    exit 1
fi

# Build once, quietly, so that the two runs below print only their results.
cargo build --release -p host-sim

echo "==== host-sim impact $CASE ===="
cargo run --quiet --release -p host-sim -- impact "$CASE"

echo
echo "==== host-sim impact $CASE --format json ===="
cargo run --quiet --release -p host-sim -- impact "$CASE" --format json
