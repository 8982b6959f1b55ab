#!/usr/bin/env bash
# Builds the firmware's binary `qemu`, runs it on QEMU's netduinoplus2 (STM32F405)
# and compares its decoded log with firmware/qemu/expected.txt.
#
#   bash scripts/firmware-qemu.sh            # build, run, compare
#   bash scripts/firmware-qemu.sh --bless    # build, run, rewrite the expected file
#
# Needs qemu-system-arm (7.2), defmt-print and flip-link (scripts/test-all.sh
# setup installs them). docs/firmware-qemu.md says what the run checks.
#
# Fails when the build fails, when the firmware exits non-zero (a failed check,
# a panic, a fault), when QEMU does not finish within 60 s, or when the log
# differs from the expected file. Lines with "measure:" (instruction counts and
# stack use, which change with the code) are printed but not compared, nor are
# the status lines' microseconds of lateness and busy time (see `compared`).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

BLESS=0
case "${1:-}" in
    --bless) BLESS=1 ;;
    "") ;;
    *) echo "usage: $0 [--bless]" >&2; exit 2 ;;
esac

EXPECTED="firmware/qemu/expected.txt"
ELF="${CARGO_TARGET_DIR:-$ROOT/firmware/target}/thumbv7em-none-eabihf/release/qemu"
case "$ELF" in /*) ;; *) ELF="$ROOT/$ELF" ;; esac

(cd firmware && cargo build --release --locked --features qemu --bin qemu)

# Run a copy, so that a build started meanwhile cannot swap the ELF under QEMU or
# defmt-print.
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
cp "$ELF" "$WORK/firmware-qemu"
ELF="$WORK/firmware-qemu"
LOG="$WORK/log.txt"

# -icount shift=0: every instruction advances virtual time by exactly 1 ns, so
# SysTick, hence the control ticks, and so every line of the log are the same on
# every run and every machine. sleep=off: while the core sleeps (WFI) virtual
# time jumps to the next tick instead of waiting in real time. (shift=auto ties
# virtual time to the host's real time: not reproducible.)
set +e
timeout 60 qemu-system-arm \
    -machine netduinoplus2 \
    -display none -serial null -monitor none \
    -semihosting-config enable=on,target=native \
    -icount shift=0,sleep=off \
    -kernel "$ELF" \
    | defmt-print -e "$ELF" --log-format '{t} {L} {s}' >"$LOG"
status=("${PIPESTATUS[@]}")
set -e

cat "$LOG"
if [[ ${status[0]} -ne 0 || ${status[1]} -ne 0 ]]; then
    echo "error: QEMU run failed (qemu/timeout status ${status[0]}, defmt-print status ${status[1]}; 124: timed out)" >&2
    exit 1
fi

# The comparison leaves out the measurements: the "measure:" lines, and the
# microseconds a tick was late and busy in the status lines (instruction counts
# too: a few instructions more in a tick can move them across a microsecond).
# The run's own checks hold what matters of them: no tick missed its deadline
# before the injected overrun, and the overrun tick was busy at least that long.
compared() {
    grep -v ' measure: ' "$1" | sed -E \
        -e 's/tick late [0-9]+ us busy [0-9]+ us/tick late _ us busy _ us/' \
        -e 's/the overrun tick busy [0-9]+ us/the overrun tick busy _ us/'
}

if [[ $BLESS -eq 1 ]]; then
    compared "$LOG" >"$EXPECTED"
    echo "wrote $EXPECTED"
    exit 0
fi

if ! diff -u "$EXPECTED" <(compared "$LOG"); then
    echo "error: the QEMU run's log differs from $EXPECTED (diff above: - expected, + this run)." >&2
    echo "If the change is intended: bash scripts/firmware-qemu.sh --bless, and review the diff." >&2
    exit 1
fi
echo "firmware qemu: log matches $EXPECTED"
