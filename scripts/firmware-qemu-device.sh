#!/usr/bin/env bash
# The real `host-sim device` against the firmware in QEMU: builds the firmware's
# binary `qemu-uart` (the controller on the rotor model, as in the binary `qemu`,
# with the link served on the emulated USART2 instead of a scripted host), runs it
# on QEMU's netduinoplus2 (STM32F405) with USART2 on a TCP port, and runs a
# sequence of `host-sim device --port tcp:...` commands against it, checking each
# one's output:
#
#   status (idle), table write + table read (the example table, then one with the
#   right offsets +5 deg: read back equal), self-test (done, both rotors pass, 4096
#   counts per rev), travel right 3000 rpm --for 3 (accepted, no fault, at rest
#   when it returns),
#   travel + telemetry --count 40 --csv (40 frames in order, no fault, ending at
#   the steady state: speeds, the written table's offset), stop, status until idle.
#
# Every check holds at any load of the host: QEMU's clock follows the host's, but
# the firmware counts its time in control ticks, and a tick QEMU could not run in
# time is skipped, so under load the firmware's time runs slower than the host's.
# The checks therefore count frames and ticks of the firmware, never seconds of
# the host (docs/firmware-qemu.md, "Time"; docs/development.md says how to run
# the whole CI under load).
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
ELF="$FIRMWARE_TARGET_DIR/thumbv7em-none-eabihf/release/qemu-uart"
HOST_SIM="$TARGET_DIR/debug/host-sim"
TABLE="examples/vibro-driver.tuning.toml"
SPEED=3000

(cd firmware && cargo build --release --locked --features qemu --bin qemu-uart)
cargo build --locked -p host-sim

WORK="$(mktemp -d)"
# Run a copy, so that a build started meanwhile cannot swap the ELF under QEMU or
# defmt-print.
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
# (SysTick, hence the firmware's control ticks, uptime and link timeout) then
# follows real time, as the host's 100 ms answer timeout and 50 ms heartbeats do,
# except that ticks QEMU cannot run in time are skipped (the firmware's clock falls
# behind, never ahead). The timeout only bounds a run whose trap never came.
FAILED_STEP="start QEMU"
timeout 600 qemu-system-arm \
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

# 3. The self-test on the rotor model. --timeout only bounds a hung run: the
#    test takes about 1.5 s of firmware time.
run self-test self-test --timeout 120
expect self-test '^self-test +done$' "the self-test done"
count self-test '^rotor [12] +PASS$' 2 "both rotors pass"
count self-test '^ +counts per rev +4096$' 2 "4096 counts per rev on both rotors"
count self-test '^ +index offset +[0-9]+ counts$' 2 "an index offset on both rotors"

# 4. Travel for 3 s (heartbeats, then the last status and a stop). How far the
#    start has gone after 3 s of the host's clock depends on how much of the
#    host QEMU got (see "Time" above), so only what holds at any pace is checked:
#    the travel accepted, a status line with no fault in state starting or
#    running, the stop accepted. The steady state is step 5's, counted in frames.
run travel-for travel right --speed "$SPEED" --for 3
expect travel-for "^travel right at $SPEED rpm: accepted$" "the travel accepted"
expect travel-for '^after 3\.0 s: +[0-9.]+ s +(starting|running) .* faults none$' \
    "a status after 3 s, starting or running, no fault"
expect travel-for '^stop: accepted$' "the stop at the end accepted"
expect travel-for '^stop: at rest after [0-9.]+ s \(state idle, ' "at rest when the command returned"

# 5. Travel, kept alive by the telemetry stream (every 100 ms of firmware time,
#    heartbeats), 40 frames to CSV: 4 s of firmware time, whatever the host's
#    load, and the start takes under 1.5 s of it.
#    `travel` and `telemetry` are two host processes: the second must reach the
#    firmware within its link timeout (0.5 s of firmware time) after the first,
#    or the firmware stops the motors with `link_lost`, as it must. On a host too
#    busy to start a process in that time the first frame shows that fault; the
#    faults are then reset and the pair tried again, at most three times, each
#    attempt said. A firmware that faults otherwise, or every time, still fails.
FRAMES=40
for attempt in 1 2 3; do
    run travel travel right --speed "$SPEED"
    expect travel "^travel right at $SPEED rpm: accepted$" "the travel accepted"
    run telemetry telemetry --count "$FRAMES" --csv "$WORK/telemetry.csv"
    expect telemetry "^telemetry: $FRAMES frames written to " "the CSV written"
    # Column 3: the faults of the first frame.
    first_faults="$(awk -F, 'NR == 2 { print $3 }' "$WORK/telemetry.csv")"
    if [[ "$first_faults" != *link_lost* || $attempt -eq 3 ]]; then
        break
    fi
    echo "attempt $attempt: the telemetry came after the link timeout (faults link_lost in its first frame): the host was too busy between the two commands; reset and again"
    run "reset-$attempt" reset
done
FAILED_STEP="telemetry-csv"
# Columns: 1 uptime_ms, 2 state, 3 faults, 4-5 speeds, 9 phase_loop_closed,
# 10 phase offset, 12 target offset. Checked in the firmware's own time (uptime,
# counted in control ticks), so the same at any load:
# - exactly FRAMES frames, uptimes strictly increasing;
# - the period: a frame is due when 100 ms of the link's clock have passed since
#   the last, and carries the status of the latest control tick, which may be a
#   tick or two later than that clock's reading. So one gap can be 98 ms, but the
#   frames' span is at least 100 ms a gap less the first frame's lead (under a
#   tick): the mean gap is at least 99 ms. No gap is over two periods (no frame
#   missing);
# - no fault in any frame; the states starting (only at first), then running;
# - from some frame on, every frame at the steady state (running, phase loop
#   closed, both speeds within 30 rpm of SPEED, the phase offset within 5 deg of
#   the target, the target the written table's), and at least 10 such frames.
awk -F, -v speed="$SPEED" -v target="$TARGET" -v frames="$FRAMES" '
    NR == 1 { if ($1 != "uptime_ms" || $2 != "state" || $9 != "phase_loop_closed" || $12 != "target_offset_deg") { print "bad header: " $0; bad = 1 }; next }
    { n++; up[n] = $1; st[n] = $2; f[n] = $3; s1[n] = $4; s2[n] = $5; lc[n] = $9; off[n] = $10; tg[n] = $12 }
    function abs(x) { return x < 0 ? -x : x }
    function wrap(d) { while (d > 180) d -= 360; while (d < -180) d += 360; return d }
    function steady(i) {
        return st[i] == "running" && lc[i] == 1 && abs(s1[i] - speed) <= 30 && abs(s2[i] - speed) <= 30 &&
            abs(wrap(off[i] - target)) <= 5 && abs(tg[i] - target) <= 0.05
    }
    END {
        if (n != frames) { print "expected " frames " frames, got " n; bad = 1 }
        running = 0
        for (i = 1; i <= n; i++) {
            if (f[i] != "") { print "frame " i ": faults " f[i]; bad = 1 }
            if (st[i] == "running") running = 1
            else if (st[i] != "starting" || running) { print "frame " i ": state " st[i] " (expected starting, then running)"; bad = 1 }
            if (i > 1 && up[i] <= up[i - 1]) { print "frames " i - 1 " and " i ": uptime " up[i - 1] " then " up[i] " ms"; bad = 1 }
            if (i > 1 && up[i] - up[i - 1] > 200) { print "frames " i - 1 " and " i ": " up[i] - up[i - 1] " ms apart (over two periods)"; bad = 1 }
        }
        if (n > 1 && (up[n] - up[1]) / (n - 1) < 99) { printf "mean gap %.1f ms, under 99\n", (up[n] - up[1]) / (n - 1); bad = 1 }
        from = n + 1
        while (from > 1 && steady(from - 1)) from--
        if (n - from + 1 < 10) {
            print "only " n - from + 1 " frames at the end at the steady state (at least 10); the last: " st[n] " at " s1[n] " / " s2[n] " rpm, offset " off[n] " deg, loop closed " lc[n] ", target " tg[n] " deg"
            bad = 1
        }
        printf "telemetry CSV: %d frames over %d ms of firmware time (mean gap %.1f ms), steady from frame %d: %s at %s / %s rpm, offset %s deg, target %s deg\n",
            n, up[n] - up[1], (n > 1 ? (up[n] - up[1]) / (n - 1) : 0), from, st[n], s1[n], s2[n], off[n], tg[n]
        exit bad
    }' "$WORK/telemetry.csv" ||
    fail "expected $FRAMES frames in order, no fault, ending in at least 10 at the steady state ($SPEED rpm +-30, offset $TARGET deg +-5) (CSV above)"

# 6. Stop, then idle with both rotors at rest (below 10 rpm). The controller is
#    idle once its ramp is down (about 0.7 s of firmware time); the rotors then
#    coast to rest, so a status can read idle at 18 rpm. Polled until both hold;
#    the bound of 120 polls, about a minute, is only against a hang.
run stop stop
expect stop '^stop: accepted$' "the stop accepted"
for i in $(seq 120); do
    run "status-end-$i" status
    expect "status-end-$i" '^faults +none$' "no fault"
    if grep -Eq '^state +idle$' "$WORK/status-end-$i.out" &&
        grep -Eq '^speed +-?[0-9]\.[0-9] / -?[0-9]\.[0-9] rpm' "$WORK/status-end-$i.out"; then
        break
    fi
    [[ $i -lt 120 ]] || fail "expected state idle with both rotors below 10 rpm within 120 polls after the stop"
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
