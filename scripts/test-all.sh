#!/usr/bin/env bash
# Every gate of the vibro driver, in order, stopping at the first that fails.
#
#   scripts/test-all.sh              # set up, then run every step
#   scripts/test-all.sh STEP...      # run only these steps (names: see STEPS below)
#
# On a fresh machine it needs only what CI has: the Rust toolchain through rustup,
# gcc, python3 and apt (as root). It installs the firmware target, the rustfmt and
# clippy components, flip-link and defmt-print (cargo install),
# qemu-system-arm and chromium (apt) itself, each only when missing. CI runs it through .ci/run (see docs/development.md).
#
# To add a gate: write a function `step_NAME` below and add NAME to STEPS.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

# The STM32F405's core: Cortex-M4F with the single-precision FPU.
FIRMWARE_TARGET="thumbv7em-none-eabihf"
# The firmware is built from firmware/, so its target directory is firmware/target
# unless CARGO_TARGET_DIR says otherwise; the board's binary is `board`.
FIRMWARE_ELF="${CARGO_TARGET_DIR:-firmware/target}/$FIRMWARE_TARGET/release/board"

# The steps, in the order they run.
STEPS=(
    setup
    fmt
    clippy
    doc
    test
    run_main
    scripts
    slurm
    shared_no_std
    firmware_fmt
    firmware_clippy
    firmware_build
    firmware_size
    firmware_qemu
    firmware_qemu_device
    impact_m4
)

# ---------------------------------------------------------------------------
# Steps

# Toolchain pieces a fresh machine lacks. rustup skips what is already there.
step_setup() {
    rustup --version 2>/dev/null | head -n 1 || true
    cargo --version
    rustc --version
    rustup target add "$FIRMWARE_TARGET"
    local installed
    installed="$(rustup component list --installed)"
    local component
    for component in rustfmt clippy; do
        if grep -q "^$component" <<<"$installed"; then
            echo "$component: installed"
        else
            rustup component add "$component"
        fi
    done
    # The firmware links through flip-link (firmware/.cargo/config.toml); the
    # qemu run needs defmt-print to decode its log.
    local tool
    for tool in flip-link defmt-print; do
        if command -v "$tool" >/dev/null; then
            echo "$tool: installed"
        else
            cargo install --locked "$tool"
        fi
    done
    # qemu-system-arm for the firmware's QEMU steps; chromium (headless) for the
    # browser tests of `cargo test` (host-sim/tests/browser).
    local missing=()
    for tool in qemu-system-arm chromium; do
        if command -v "$tool" >/dev/null; then
            echo "$tool: installed"
        else
            missing+=("$tool")
        fi
    done
    if [[ ${#missing[@]} -gt 0 ]]; then
        # apt needs root: sudo when not root and sudo is there.
        local as_root=()
        if [[ $(id -u) -ne 0 ]] && command -v sudo >/dev/null; then
            as_root=(sudo)
        fi
        "${as_root[@]}" apt-get update
        "${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y "${missing[@]}"
    fi
    qemu-system-arm --version | head -n 1
    chromium --version 2>/dev/null | head -n 1 || true
}

step_fmt() {
    cargo fmt --all -- --check
}

step_clippy() {
    cargo clippy --workspace --all-targets -- -D warnings
}

step_doc() {
    RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps || return 1
    # The firmware's documents, for the board and the QEMU binaries' features.
    local features
    for features in "" qemu pil; do
        (cd firmware && RUSTDOCFLAGS="-D warnings" \
            cargo doc --release --locked --no-deps ${features:+--features "$features"}) || return 1
    done
}

# The host tests. The output is kept to total the counts at the end of the run.
step_test() {
    # The processor in the loop's tests (host-sim/tests/pil.rs, pil_scenarios.rs,
    # pil_asks.rs)
    # run the firmware's binary `pil` on QEMU; in CI they fail without it, so it
    # is built first: for the other machines the tests run (the scenario
    # one-foot.toml's, wide-rotors-machine.toml, one-rotor-machine.toml) as
    # pil-STEM beside it, then for the reference machine.
    local elf="${CARGO_TARGET_DIR:-$ROOT/firmware/target}/thumbv7em-none-eabihf/release/pil"
    local stem
    for stem in one-foot-machine wide-rotors-machine one-rotor-machine; do
        (cd firmware && VIBRO_MACHINE="../tests/fixtures/$stem.toml" \
            cargo build --release --locked --features pil --bin pil &&
            cp "$elf" "$elf-$stem") || return 1
    done
    (cd firmware && cargo build --release --locked --features pil --bin pil)
    cargo test --workspace 2>&1 | tee "$TEST_LOG"
}

# The README's other command, the main job, must keep working.
step_run_main() {
    bash scripts/run.sh
}

# The Python scripts (docs/paper-fig8.md) compile, and the plot script draws a
# short run of the Fig. 8 machine (the sweep takes minutes: its pieces are the
# same `host-sim run` calls, checked by the tests).
step_scripts() {
    local dir
    dir="$(mktemp -d)"
    python3 -c 'import ast, sys; [ast.parse(open(f).read(), f) for f in sys.argv[1:]]' scripts/*.py benchmarks/*.py benchmarks/mujoco/*.py
    cargo run --quiet --release -p host-sim -- run examples/paper-fig8.toml \
        --command right --speed 3000 --t-end 0.5 --format json \
        --out "$dir/trace.csv" --events "$dir/events.csv" >/dev/null
    python3 scripts/paper-fig8-plot.py "$dir/trace.csv" "$dir/events.csv" "$dir/fig9.svg" \
        --from 0.3 --to 0.5
    grep -q '<polyline' "$dir/fig9.svg"
    python3 scripts/paper-fig8-sweep.py --voltages x 2>/dev/null && return 1
    # The benchmark scripts: the contacts' scaling, the random layouts and the
    # processor in the loop's cost on a short run (their files removed
    # afterwards), their refusal of a bad argument.
    python3 benchmarks/contacts_scaling.py target/release/host-sim examples/vibro-driver.toml \
        --feet 2,3 --t-end 0.2 --repeats 1 >"$dir/scaling.md"
    grep -q '^| 3 |' "$dir/scaling.md"
    if ls examples/.contacts-scaling-* 2>/dev/null; then return 1; fi
    python3 benchmarks/contacts_random.py target/release/host-sim examples/vibro-driver.toml \
        --layouts 1 --t-end 0.5 >"$dir/random.md"
    grep -q '^| 1 | 1 | 4 |' "$dir/random.md"
    grep -q '^| 1 | 2 | 5 (2 + 3) |' "$dir/random.md"
    if ls examples/.contacts-random-* 2>/dev/null; then return 1; fi
    # The processor in the loop's cost (benchmarks/pil.md), on the ELF the step
    # `test` built.
    python3 benchmarks/pil_cost.py target/release/host-sim examples/vibro-driver.toml \
        "${CARGO_TARGET_DIR:-$ROOT/firmware/target}/thumbv7em-none-eabihf/release/pil" \
        --t-end 0.2 --reps 1 >"$dir/pil.md"
    grep -q '^| firmware in the loop |' "$dir/pil.md"
    grep -q "^the firmware's control task: mean" "$dir/pil.md"
    local rc=0
    python3 benchmarks/pil_cost.py target/release/host-sim examples/vibro-driver.toml x \
        --reps 0 2>/dev/null || rc=$?
    [ "$rc" -eq 2 ] || return 1
    rc=0
    python3 benchmarks/rtol_sweep.py target/release/host-sim examples/vibro-driver.toml \
        --rtols x 2>/dev/null || rc=$?
    [ "$rc" -eq 2 ] || return 1
    rc=0
    python3 benchmarks/contacts_random.py target/release/host-sim examples/vibro-driver.toml \
        --feet 3,9x 2>/dev/null || rc=$?
    [ "$rc" -eq 2 ] || return 1
    rm -rf "$dir"
}

# A sweep in parts through a real single-node Slurm, merged = unsharded.
step_slurm() {
    bash scripts/slurm-check.sh
}

# shared must build for the firmware target: no_std, and no heap (no `alloc`).
step_shared_no_std() {
    if grep -rn "extern crate alloc" shared/src; then
        echo "error: shared must stay heap-free: remove \`extern crate alloc\`" >&2
        return 1
    fi
    cargo build -p shared --target "$FIRMWARE_TARGET"
}

# The firmware is outside the workspace (docs/development.md): its gates run from
# firmware/ so that firmware/.cargo/config.toml (target, linker scripts) applies.
step_firmware_fmt() {
    (cd firmware && cargo fmt --check)
}

step_firmware_clippy() {
    # The library and the board's binary; then with the feature `qemu`, which adds
    # the `qemu` module and the binaries `qemu` and `qemu-uart`.
    (cd firmware && cargo clippy --release --locked -- -D warnings)
    (cd firmware && cargo clippy --release --locked --features qemu -- -D warnings)
    # The feature `pil` adds the `pil` module and the binary `pil` (docs/pil.md).
    (cd firmware && cargo clippy --release --locked --features pil -- -D warnings)
    # A one-rotor machine compiles too (motor 2's bridge never driven), in its own
    # target folder so that the default build is not redone.
    (cd firmware && VIBRO_MACHINE=../tests/fixtures/one-rotor-machine.toml \
        CARGO_TARGET_DIR=target/one-rotor cargo clippy --release --locked -- -D warnings)
}

step_firmware_build() {
    (cd firmware && cargo build --release --locked)
    (cd firmware && cargo build --release --locked --features pil --bin pil)
}

# Flash and static RAM use of the release ELF, against the regions of memory.x.
# Purely informational: without a size tool it says so and passes.
step_firmware_size() {
    local size_tool
    if ! size_tool="$(find_size_tool)"; then
        echo "warning: no llvm-size or arm-none-eabi-size found; size not reported" >&2
        return 0
    fi
    # The sections that reach the chip (debug info stays in the ELF).
    "$size_tool" -A -x "$FIRMWARE_ELF" | grep -Ev '^(\.debug|\.comment|\.ARM|Total|$)' || true
    # Berkeley format: text (vector table, code, constants), data, bss (incl. .uninit).
    # Flash holds text and the initial values of data; RAM holds data and bss.
    local text data bss
    read -r text data bss _ < <("$size_tool" -B "$FIRMWARE_ELF" | awk 'NR == 2')
    local flash_k ram_k
    flash_k="$(region_kib FLASH)"
    ram_k="$(region_kib RAM)"
    awk -v t="$text" -v d="$data" -v b="$bss" -v fk="$flash_k" -v rk="$ram_k" 'BEGIN {
        printf "firmware flash: %d bytes (%.2f %% of %d KiB)\n", t + d, 100 * (t + d) / (fk * 1024), fk
        printf "firmware static RAM: %d bytes (%.2f %% of %d KiB; the stack uses the rest)\n", d + b, 100 * (d + b) / (rk * 1024), rk
    }'
}

# The binary `qemu` on QEMU's STM32F405 (netduinoplus2): the controller, the link
# and a scripted host; its checks and its log against firmware/qemu/expected.txt
# (docs/firmware-qemu.md).
step_firmware_qemu() {
    bash scripts/firmware-qemu.sh
}

# The real `host-sim device` against the binary `qemu-uart` in QEMU, over the
# emulated USART2 on a TCP port: status, table write/read, self-test, travel,
# telemetry CSV, stop (docs/firmware-qemu.md, "The link on the emulated USART").
step_firmware_qemu_device() {
    bash scripts/firmware-qemu-device.sh
}

# The benchmark impact on the Cortex-M4F in QEMU (benchmarks/impact-m4/run.sh),
# run once as a smoke check: it fails if the program does not build, does not
# exit 0, or its outcomes differ from the host's. The instruction counts it
# prints are not checked (benchmarks/impact.md records them). Its clippy gate
# (about 17 s cold) is left to whoever changes it (docs/development.md).
step_impact_m4() {
    (cd benchmarks/impact-m4 && cargo fmt --check && cargo clippy --release -- -D warnings)
    bash benchmarks/impact-m4/run.sh
}

# ---------------------------------------------------------------------------
# Helpers

# Prints the path of a size tool for ARM ELF files. The cheapest first: one already
# installed, else rustup's llvm-tools component (a few seconds to install).
find_size_tool() {
    local host rustup_bin
    host="$(rustc -vV | sed -n 's/^host: //p')"
    rustup_bin="$(rustc --print sysroot)/lib/rustlib/$host/bin"
    if [[ -x "$rustup_bin/llvm-size" ]]; then
        echo "$rustup_bin/llvm-size"
    elif command -v llvm-size >/dev/null; then
        command -v llvm-size
    elif command -v arm-none-eabi-size >/dev/null; then
        command -v arm-none-eabi-size
    elif rustup component add llvm-tools >&2 && [[ -x "$rustup_bin/llvm-size" ]]; then
        echo "$rustup_bin/llvm-size"
    else
        return 1
    fi
}

# The LENGTH of a memory.x region in KiB (written there as NNNK).
region_kib() {
    sed -n "s/^ *$1 *:.*LENGTH *= *\([0-9]*\)K.*/\1/p" memory.x
}

section() {
    printf '\n==== %s ====\n' "$*"
}

# Totals of every "test result:" line of cargo test, as one plain closing line.
test_totals() {
    awk '/^test result:/ {
            for (i = 1; i <= NF; i++) {
                if ($(i) ~ /^passed;?$/)  p += $(i - 1)
                if ($(i) ~ /^failed;?$/)  f += $(i - 1)
                if ($(i) ~ /^ignored;?$/) s += $(i - 1)
            }
        }
        END { printf "%d passed, %d failed, %d skipped\n", p, f, s }' "$TEST_LOG"
}

# Runs on every exit: the time of each step, where it stopped, the test totals.
summary() {
    local status=$?
    section "summary"
    local line
    for line in "${TIMES[@]}"; do
        echo "$line"
    done
    echo "total: $((SECONDS - START)) s"
    if [[ $status -ne 0 ]]; then
        echo "FAILED at step: ${CURRENT:-?} (exit status $status)"
    fi
    if [[ -s "$TEST_LOG" ]]; then
        echo "cargo test totals (host workspace):"
        echo "tests: $(test_totals)"
    fi
    rm -f "$TEST_LOG"
    exit "$status"
}

# ---------------------------------------------------------------------------
# Main

if [[ $# -gt 0 ]]; then
    for name in "$@"; do
        if ! declare -F "step_$name" >/dev/null; then
            echo "unknown step: $name (steps: ${STEPS[*]})" >&2
            exit 2
        fi
    done
    STEPS=("$@")
fi

START=$SECONDS
TIMES=()
CURRENT=""
TEST_LOG="$(mktemp)"
trap summary EXIT

for name in "${STEPS[@]}"; do
    CURRENT="$name"
    section "$name"
    step_start=$SECONDS
    "step_$name"
    TIMES+=("$(printf '%-16s %4d s' "$name" $((SECONDS - step_start)))")
done
CURRENT=""
