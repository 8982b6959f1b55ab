#!/usr/bin/env bash
# The project's main job, from a fresh clone: build the host tool and simulate the
# reference machine (examples/vibro-driver.toml).
#
# 1. The machine with the controller in the loop (the `shared` controller the
#    firmware runs, stepped at the control rate, seeing simulated encoders, index
#    pulses and currents), commanded to travel right at 3000 rpm for 10 s: the
#    rotors ramp up through the platform's lift-off band, lock at the tuned phase
#    offset, and the platform travels right.
# 2. The same machine open loop, both motors at 12 V: the rotors synchronise by
#    themselves near 180 degrees (the vertical force), so it barely travels.
# 3. The paper's Fig. 5 impact, solved by `host-sim impact`.
#
# Writes out/ (traces, events, plots, animations) and prints the summaries.
# Needs only cargo; the first run compiles host-sim (well under a minute).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

MACHINE="examples/vibro-driver.toml"
CASE="examples/impact/fig5-rotating-body.toml"
OUT="out"

if ! command -v cargo >/dev/null; then
    echo "error: cargo not found: install Rust with rustup (https://rustup.rs)" >&2
    exit 1
fi

# Build once, quietly, so that the runs below print only their results.
cargo build --release -p host-sim
mkdir -p "$OUT"

echo "==== host-sim run $MACHINE --command right ===="
cargo run --quiet --release -p host-sim -- run "$MACHINE" --command right \
    --out "$OUT/vibro-driver-right.csv" --events "$OUT/vibro-driver-right-events.csv" \
    --plot "$OUT/vibro-driver-right.svg" --animate "$OUT/vibro-driver-right.html"
echo "wrote $OUT/vibro-driver-right.{csv,svg,html} and the events (open the SVG, and the"
echo "HTML page that plays the run, in a browser)"

echo
echo "==== host-sim run $MACHINE --open-loop 12,12 ===="
cargo run --quiet --release -p host-sim -- run "$MACHINE" --open-loop 12,12 \
    --out "$OUT/vibro-driver-open-loop.csv" --events "$OUT/vibro-driver-open-loop-events.csv" \
    --plot "$OUT/vibro-driver-open-loop.svg" --animate "$OUT/vibro-driver-open-loop.html"
echo "wrote $OUT/vibro-driver-open-loop.{csv,svg,html} and the events"

echo
echo "==== host-sim impact $CASE ===="
cargo run --quiet --release -p host-sim -- impact "$CASE"
