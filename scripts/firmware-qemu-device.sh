#!/usr/bin/env bash
# The real `host-sim device` against the firmware in QEMU: builds the firmware's
# `qemu-uart` build (the `qemu` build with the link served on the emulated USART2
# instead of the scripted host), runs it on QEMU's netduinoplus2 (STM32F405) with
# USART2 on a TCP port, and runs a sequence of `host-sim device --port tcp:...`
# commands against it, checking each one's output:
#
#   status (idle), table write + table read (the example table, then one with the
#   right offsets +5 deg: read back equal), self-test (done, both rotors pass, 4096
#   counts per rev), travel right 3000 rpm --for 3 (running at the written table's
#   offset, at rest when it returns), travel + telemetry --csv (running, speeds,
#   target offset), stop, status until idle.
#
#   bash scripts/firmware-qemu-device.sh
#
# Needs qemu-system-arm (7.2), flip-link, defmt-print (for the firmware's log) and
# python3 (to pick a free port); scripts/test-all.sh setup installs the first three.
# docs/firmware-qemu.md, "The link on the emulated USART", says how it works.
#
# Fails (non-zero, with a message naming the step) when a build fails, QEMU stops
# early, a command fails or prints something other than expected. QEMU is stopped
# at the end in every case (trap). Environment: VIBRO_QEMU_PORT (default: a free
# port), CARGO_TARGET_DIR (where the ELF and host-sim are found).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
FIRMWARE_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/firmware/target}"
case "$TARGET_DIR" in /*) ;; *) TARGET_DIR="$ROOT/$TARGET_DIR" ;; esac
case "$FIRMWARE_TARGET_DIR" in /*) ;; *) FIRMWARE_TARGET_DIR="$ROOT/$FIRMWARE_TARGET_DIR" ;; esac
ELF="$FIRMWARE_TARGET_DIR/thumbv7em-none-eabihf/release/firmware"
HOST_SIM="$TARGET_DIR/debug/host-sim"
TABLE="examples/vibro-driver.tuning.toml"
SPEED=3000

(cd firmware && cargo build --release --locked --features qemu-uart)
cargo build --locked -p host-sim

WORK="$(mktemp -d)"
# The board and qemu builds write the same path: run a copy.
cp "$ELF" "$WORK/firmware-qemu-uart"
ELF="$WORK/firmware-qemu-uart"

QEMU_PID=""
FAILED_STEP=""

# The firmware's log (defmt over semihosting, decoded), printed at the end.
print_log() {
    echo "---- firmware log (QEMU, decoded) ----"
    if command -v defmt-print >/dev/null; then
        defmt-print -e "$ELF" --log-format '{t} {L} {s}' <"$WORK/semihosting.bin" 2>&1 || true
    else
        echo "(defmt-print not installed: log not decoded)"
    fi
    sed 's/^/qemu: /' "$WORK/qemu.err" 2>/dev/null || true
    echo "---- end of firmware log ----"
}

stop_qemu() {
    if [[ -n "$QEMU_PID" ]] && kill -0 "$QEMU_PID" 2>/dev/null; then
        kill "$QEMU_PID" 2>/dev/null || true
        wait "$QEMU_PID" 2>/dev/null || true
    fi
    QEMU_PID=""
}

LOG_PRINTED=0
cleanup() {
    local status=$?
    stop_qemu
    if [[ $LOG_PRINTED -eq 0 && -f "$WORK/semihosting.bin" ]]; then
        print_log
    fi
    if [[ $status -ne 0 ]]; then
        echo "error: firmware qemu device: FAILED${FAILED_STEP:+ at step: $FAILED_STEP}" >&2
    fi
    rm -rf "$WORK"
    exit "$status"
}
trap cleanup EXIT

fail() {
    echo "error: [$FAILED_STEP] $*" >&2
    exit 1
}

if [[ -n "${VIBRO_QEMU_PORT:-}" ]]; then
    PORT="$VIBRO_QEMU_PORT"
    if ! [[ "$PORT" =~ ^[0-9]+$ ]] || ((PORT < 1 || PORT > 65535)); then
        FAILED_STEP="VIBRO_QEMU_PORT"
        fail "must be a TCP port, 1 to 65535 (got $PORT)"
    fi
else
    PORT="$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
fi
DEVICE=(--port "tcp:127.0.0.1:$PORT")

# USART1 is the first -serial, USART2 the second. No -icount: QEMU's virtual clock
# (SysTick, hence the firmware's uptime and the link's timeouts) then follows real
# time, as the host's 100 ms answer timeout and 50 ms heartbeats do. The timeout
# only bounds a run whose trap never came.
FAILED_STEP="start QEMU"
timeout 300 qemu-system-arm \
    -machine netduinoplus2 \
    -display none -monitor none \
    -serial null \
    -serial "tcp:127.0.0.1:$PORT,server=on,wait=off" \
    -semihosting-config enable=on,target=native \
    -kernel "$ELF" \
    >"$WORK/semihosting.bin" 2>"$WORK/qemu.err" &
QEMU_PID=$!
START=$SECONDS

# Wait for the port (QEMU listens before the firmware starts); a connection
# opened and closed here is one client come and gone for QEMU.
for i in $(seq 100); do
    if ! kill -0 "$QEMU_PID" 2>/dev/null; then
        fail "QEMU stopped before it listened on port $PORT"
    fi
    if (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null; then
        break
    fi
    [[ $i -lt 100 ]] || fail "QEMU did not listen on port $PORT within 10 s"
    sleep 0.1
done
echo "QEMU (pid $QEMU_PID) serves USART2 on tcp:127.0.0.1:$PORT"

# run NAME ARGS...: `host-sim device --port ... ARGS`; its output (stdout and
# stderr) in $WORK/NAME.out and printed; fails unless it exits 0.
run() {
    local name=$1
    shift
    FAILED_STEP="$name"
    echo "\$ host-sim device ${DEVICE[*]} $*"
    local status=0
    "$HOST_SIM" device "${DEVICE[@]}" "$@" >"$WORK/$name.out" 2>&1 || status=$?
    cat "$WORK/$name.out"
    if [[ $status -ne 0 ]]; then
        fail "host-sim device $* exited with status $status (output above)"
    fi
    if ! kill -0 "$QEMU_PID" 2>/dev/null; then
        fail "QEMU stopped during the step"
    fi
}

# expect NAME REGEX WHAT: the output of step NAME has a line matching REGEX.
expect() {
    if ! grep -Eq -- "$2" "$WORK/$1.out"; then
        fail "expected $3 (a line matching /$2/), got the output above"
    fi
}

# count NAME REGEX N WHAT: exactly N lines of step NAME's output match REGEX.
count() {
    local n
    n="$(grep -Ec -- "$2" "$WORK/$1.out" || true)"
    if [[ "$n" -ne "$3" ]]; then
        fail "expected $4 ($3 lines matching /$2/, got $n)"
    fi
}

# The rows of a tuning table file (comments and blank lines left out).
rows() {
    grep -Ev '^[[:space:]]*(#|$)' "$1"
}

# table_round_trip NAME FILE: write FILE, read it back, compare the rows.
table_round_trip() {
    local name=$1 file=$2 n
    n="$(grep -c '^\[\[rows\]\]' "$file")"
    run "$name-write" table write "$file"
    expect "$name-write" "^table write: $n rows from .* stored in the device's flash and in use$" "the table stored"
    run "$name-read" table read --out "$WORK/$name-read.toml"
    expect "$name-read" "^table read: $n rows written to " "the table read"
    FAILED_STEP="$name-compare"
    if ! diff -u <(rows "$file") <(rows "$WORK/$name-read.toml"); then
        fail "the table read back differs from $file (diff above: - written, + read)"
    fi
    echo "table read back equals $file ($n rows)"
}

# 1. At start: idle, no fault.
run status-start status
expect status-start '^state +idle$' "state idle"
expect status-start '^faults +none$' "no fault"

# 2. Tables: the example, then one with the right offsets +5 deg (the one in use
#    from here on: the travel below checks its target offset).
table_round_trip table-example "$TABLE"
awk '/^right_offset_deg *=/ { printf "right_offset_deg = %.1f\n", $3 + 5; next } { print }' \
    "$TABLE" >"$WORK/shifted.toml"
table_round_trip table-shifted "$WORK/shifted.toml"
TARGET="$(awk -v s="$SPEED" '/^speed_rpm/ { v = $3 } /^right_offset_deg/ && v == s { printf "%.1f", $3 }' "$WORK/shifted.toml")"
[[ -n "$TARGET" ]] || fail "no row at $SPEED rpm in $TABLE"

# 3. The self-test on the rotor model.
run self-test self-test --timeout 20
expect self-test '^self-test +done$' "the self-test done"
count self-test '^rotor [12] +PASS$' 2 "both rotors pass"
count self-test '^ +counts per rev +4096$' 2 "4096 counts per rev on both rotors"
count self-test '^ +index offset +[0-9]+ counts$' 2 "an index offset on both rotors"

# within VALUE REF TOL: |VALUE - REF| <= TOL.
within() {
    awk -v v="$1" -v r="$2" -v t="$3" 'BEGIN { d = v - r; if (d < 0) d = -d; exit !(v != "" && d <= t) }'
}

# 4. Travel for 3 s (heartbeats, then the last status and a stop).
run travel-for travel right --speed "$SPEED" --for 3
expect travel-for "^travel right at $SPEED rpm: accepted$" "the travel accepted"
expect travel-for '^stop: accepted$' "the stop at the end accepted"
expect travel-for '^stop: at rest after [0-9.]+ s \(state idle, ' "at rest when the command returned"
line="$(grep -E '^after 3\.0 s: ' "$WORK/travel-for.out" || true)"
read -r s1 s2 offset target faults < <(sed -E 's/.* running +speed +([-0-9.]+) +([-0-9.]+) rpm +offset +([-0-9.]+) deg \(target +([-0-9.]+)\).* faults (.*)$/\1 \2 \3 \4 \5/;t;s/.*/- - - - -/' <<<"$line")
within "$s1" "$SPEED" 30 && within "$s2" "$SPEED" 30 ||
    fail "expected running at $SPEED rpm (+-30) on both rotors after 3 s, got: $line"
within "$target" "$TARGET" 0.05 || fail "expected the target offset $TARGET deg (the written table's), got: $line"
within "$offset" "$TARGET" 5 || fail "expected the phase offset within 5 deg of $TARGET, got: $line"
[[ "$faults" == "none" ]] || fail "expected no fault, got: $line"

# 5. Travel, kept alive by the telemetry stream (every 100 ms, heartbeats), CSV.
run travel travel right --speed "$SPEED"
expect travel "^travel right at $SPEED rpm: accepted$" "the travel accepted"
run telemetry telemetry --duration 2 --csv "$WORK/telemetry.csv"
expect telemetry '^telemetry: [0-9]+ frames written to ' "the CSV written"
FAILED_STEP="telemetry-csv"
# Columns: 1 uptime_ms, 2 state, 3 faults, 4-5 speeds, 12 target offset. At least
# 15 frames of the 20 (period 100 ms for 2 s), 100 ms apart within one control
# tick (the link sends when 100 ms of its own clock have passed, and the frame
# carries the status of the last control tick, stamped up to a tick earlier: a
# loaded host saw 101, 99, 101 ms); the last 5 running at the speed and offset,
# no fault in any.
awk -F, -v speed="$SPEED" -v target="$TARGET" '
    NR == 1 { if ($1 != "uptime_ms" || $2 != "state") { print "bad header: " $0; bad = 1 }; next }
    { n++; up[n] = $1; st[n] = $2; f[n] = $3; s1[n] = $4; s2[n] = $5; tg[n] = $12 }
    function abs(x) { return x < 0 ? -x : x }
    END {
        if (n < 15) { print "only " n " frames"; bad = 1 }
        for (i = 1; i <= n; i++) {
            if (f[i] != "") { print "frame " i ": faults " f[i]; bad = 1 }
            if (i > 1 && up[i] - up[i - 1] < 99) { print "frames " i - 1 " and " i " less than 99 ms apart"; bad = 1 }
        }
        for (i = (n > 5 ? n - 4 : 1); i <= n; i++) {
            if (st[i] != "running" || abs(s1[i] - speed) > 30 || abs(s2[i] - speed) > 30 || abs(tg[i] - target) > 0.05) {
                print "frame " i ": " st[i] " at " s1[i] " / " s2[i] " rpm, target " tg[i] " deg"; bad = 1
            }
        }
        printf "telemetry CSV: %d frames, last: %s at %s / %s rpm, target %s deg\n", n, st[n], s1[n], s2[n], tg[n]
        exit bad
    }' "$WORK/telemetry.csv" ||
    fail "expected the last telemetry frames running at $SPEED rpm (+-30), target $TARGET deg, no fault (CSV above)"

# 6. Stop, then idle (the ramp down takes about 0.7 s of firmware time).
run stop stop
expect stop '^stop: accepted$' "the stop accepted"
for i in $(seq 20); do
    run "status-end-$i" status
    if grep -Eq '^state +idle$' "$WORK/status-end-$i.out"; then
        expect "status-end-$i" '^faults +none$' "no fault"
        expect "status-end-$i" '^speed +-?[0-9]\.[0-9] / -?[0-9]\.[0-9] rpm' "both rotors at rest (below 10 rpm)"
        break
    fi
    [[ $i -lt 20 ]] || fail "expected state idle within 10 s after the stop"
    sleep 0.5
done

FAILED_STEP="QEMU still running"
kill -0 "$QEMU_PID" 2>/dev/null || fail "QEMU stopped before the end"
ELAPSED=$((SECONDS - START))

# 7. The firmware's log: no error (a panic or a fault would have stopped QEMU).
stop_qemu
FAILED_STEP="firmware log"
print_log | tee "$WORK/log.txt"
LOG_PRINTED=1
if grep -E '^[0-9]+ ERROR ' "$WORK/log.txt"; then
    fail "the firmware logged an error (above)"
fi
echo "firmware qemu device: every step passed (${ELAPSED} s with QEMU running)"
