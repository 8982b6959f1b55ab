#!/usr/bin/env bash
# Instructions of one 4-contact frictional impact of shared::impact on the
# Cortex-M4F, in f32 (hardware FPU) and f64 (soft-float), counted in QEMU's
# netduinoplus2 (STM32F405). benchmarks/impact.md has the results and the method.
#
#   bash benchmarks/impact-m4/run.sh            # count, check
#   bash benchmarks/impact-m4/run.sh --profile  # and the instructions by function
#
# 1. Builds the program (thumbv7em-none-eabihf, the firmware's release profile)
#    and runs it under `-icount shift=0`: its SysTick counts give instructions
#    per impact over many impacts, the empty loop subtracted.
# 2. Runs the same ELF again with an instruction trace (`-singlestep -d
#    exec,nochain`, one log line per executed instruction) and counts the lines
#    between the markers trace_begin and trace_end: one impact of each type,
#    exactly, less the markers around nothing.
# 3. Builds the same program for the host (dev profile) and checks that the target's outcomes
#    (energy change, impulses, cases) are the host's to the last bit.
#
# --profile also prints, from the trace, the functions that executed most of each
# impact's instructions (by the symbol of each instruction's address: inlined code
# counts to the function it was inlined into), demangled by c++filt if present.
#
# Needs the thumbv7em-none-eabihf target and qemu-system-arm (7.2);
# scripts/test-all.sh's setup installs both. Exits non-zero if a build or a run
# fails, a run takes more than 60 s, or the outcomes differ.
set -euo pipefail

PROFILE=0
case "${1:-}" in
    --profile) PROFILE=1 ;;
    "") ;;
    *) echo "usage: $0 [--profile]" >&2; exit 2 ;;
esac

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cd "$HERE"

TARGET_DIR="${CARGO_TARGET_DIR:-$HERE/target}"
case "$TARGET_DIR" in /*) ;; *) TARGET_DIR="$HERE/$TARGET_DIR" ;; esac
ELF="$TARGET_DIR/thumbv7em-none-eabihf/release/impact-m4"
HOST="$(rustc -vV | sed -n 's/^host: //p')"

cargo build --release --locked

WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT

qemu() {
    timeout 60 qemu-system-arm \
        -machine netduinoplus2 \
        -display none -serial null -monitor none \
        -kernel "$ELF" "$@"
}

# 1. SysTick under -icount shift=0: 1 instruction = 1 ns of virtual time.
qemu -semihosting-config enable=on,target=native -icount shift=0 >"$WORK/run.txt"
cat "$WORK/run.txt"

# 2. The instruction trace. The program prints the markers' addresses and exits
#    after the traced impacts when "trace" is on its command line.
qemu -semihosting-config enable=on,target=native,arg=impact-m4,arg=trace \
    -singlestep -d exec,nochain -D "$WORK/exec.log" >"$WORK/trace.txt"
read -r begin end < <(sed -n \
    's/^trace: trace_begin at 0x\([0-9a-f]*\), trace_end at 0x\([0-9a-f]*\)$/\1 \2/p' \
    "$WORK/trace.txt")
# Log lines: "Trace 0: HOSTPTR [FLAGS/PC/FLAGS/CFLAGS] SYMBOL". The stretches from
# trace_begin's entry to trace_end's: around nothing, around f32, around f64.
awk -v b="$begin" -v e="$end" '
    { split($4, f, "/"); pc = f[2] }
    pc == b { start[++nb] = NR }
    pc == e { stop[++ne] = NR }
    END {
        if (nb != 3 || ne != 3) {
            printf "error: %d trace_begin and %d trace_end in the trace, 3 each expected\n", nb, ne
            exit 1
        }
        empty = stop[1] - start[1]
        printf "trace: markers around nothing: %d instructions\n", empty
        printf "trace: f32: %d instructions for one impact\n", stop[2] - start[2] - empty
        printf "trace: f64: %d instructions for one impact\n", stop[3] - start[3] - empty
    }' "$WORK/exec.log"

if [[ $PROFILE -eq 1 ]]; then
    demangle=(cat)
    if command -v c++filt >/dev/null; then
        demangle=(c++filt)
    fi
    for stretch in 2:f32 3:f64; do
        echo "profile ${stretch#*:}: instructions, share, function"
        awk -v b="$begin" -v e="$end" -v want="${stretch%%:*}" '
            { split($4, f, "/"); pc = f[2] }
            pc == b { n++ }
            pc == e && n == want { n = -1 }
            n == want { count[$5]++; total++ }
            END {
                for (s in count) printf "%9d %5.1f %% %s\n", count[s], 100 * count[s] / total, s
            }' "$WORK/exec.log" | sort -rn | head -n 15 | "${demangle[@]}"
    done
fi

# 3. The same outcomes on the host, to the last bit. Built in the dev profile
#    (quicker): Rust does not fuse or reorder floating-point operations at any
#    optimisation level, so the host's bits do not depend on it.
cargo run --quiet --locked --target "$HOST" >"$WORK/host.txt"
grep '^outcome ' "$WORK/run.txt" >"$WORK/target-outcome.txt"
if ! diff -u --label host "$WORK/host.txt" --label target "$WORK/target-outcome.txt"; then
    echo "error: the target's outcomes differ from the host's" >&2
    exit 1
fi
echo "outcomes: the target's equal the host's ($HOST), f32 and f64"
