#!/usr/bin/env bash
# The sweep in parts through a real Slurm (docs/scale-out.md), as CI runs it:
# a single-node cluster (Debian's slurm-wlm and munge, as root) is configured in
# a scratch directory and started, deploy/slurm/submit.sh submits a small grid as
# an array job of 3 parts and a dependent merge job, and the merged outputs (the
# JSON, the --write tuning table and the --plot SVG) must equal the unsharded
# sweep's byte for byte; likewise a small robust sweep (tune --robust, 3 parts)
# and a small fit's multistart (COMMAND=calibrate, 3 parts: its JSON and --write
# machine file). The daemons this script started are stopped on exit, whatever
# happened.
#
#   scripts/slurm-check.sh        # needs root (apt, munged, slurmd), or the
#                                 # packages installed and a running munged
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

HOST_SIM="$ROOT/target/release/host-sim"
# The grid: 2 speeds x 4 offsets, 2 s each (the tests' tiny grid, shorter).
GRID=(--speeds 2750:3000:250 --offsets 0:360:90 --t-end 2)
# The robust sweep: 1 speed x 4 offsets on 2 machines x 3 starts (24 runs of 2 s,
# the loosest tolerance; about a second of one core).
ROBUST=(--speeds 3000 --offsets 0:360:90 --t-end 2 --set simulation.rtol=1e-3
    --robust --samples 2)
# The fit: restitution from two measured points (7 starts; `calibrate` prints
# "26 evaluations (60 runs)": 2 runs of 2 s each and 8 for the numerical noise,
# at the loosest tolerance; a few seconds of one core).
FIT=(--measured measured.csv --fit 'contacts.*.restitution' --t-end 2
    --set simulation.rtol=1e-3)
MEASURED='speed_rpm,offset_deg,velocity_mps
3000,90,0.030
3000,270,-0.031
'

PARTS=3
TIMEOUT_S=300

WORK="$(mktemp -d)"
STARTED=()

cleanup() {
    local status=$?
    local pid
    for pid in "${STARTED[@]}"; do
        kill "$pid" 2>/dev/null || true
    done
    # The daemons write their pid files; give them a moment, then make sure.
    sleep 1
    for pid in "${STARTED[@]}"; do
        kill -9 "$pid" 2>/dev/null || true
    done
    if [[ $status -ne 0 && -d "$WORK/cluster" ]]; then
        echo "---- slurmctld.log" >&2
        tail -n 20 "$WORK/cluster/slurmctld.log" >&2 || true
        echo "---- slurmd.log" >&2
        tail -n 20 "$WORK/cluster/slurmd.log" >&2 || true
    fi
    rm -rf "$WORK"
    exit "$status"
}
trap cleanup EXIT

# 1. The packages (apt, as root; sudo when not root and sudo is there).
if ! command -v sbatch >/dev/null || ! command -v munged >/dev/null; then
    as_root=()
    if [[ $(id -u) -ne 0 ]] && command -v sudo >/dev/null; then
        as_root=(sudo)
    fi
    "${as_root[@]}" apt-get update
    "${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y slurm-wlm munge
fi
cargo build --release -p host-sim

# 2. munge: the key the package made (or a new one), the daemon unless running.
if ! munge -n </dev/null 2>/dev/null | unmunge >/dev/null 2>&1; then
    if [[ ! -s /etc/munge/munge.key ]]; then
        mkdir -p /etc/munge
        dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=1024 status=none
        chown munge:munge /etc/munge/munge.key 2>/dev/null || true
        chmod 400 /etc/munge/munge.key
    fi
    mkdir -p /run/munge /var/log/munge /var/lib/munge
    chown munge:munge /run/munge /var/log/munge /var/lib/munge 2>/dev/null || true
    munged --force
    STARTED+=("$(cat /run/munge/munged.pid)")
    munge -n </dev/null | unmunge >/dev/null
fi

# 3. A one-node cluster in the scratch directory: this machine, all its CPUs.
mkdir -p "$WORK/cluster/state" "$WORK/cluster/spool"
node="$(hostname -s)"
export SLURM_CONF="$WORK/cluster/slurm.conf"
cat >"$SLURM_CONF" <<EOF
ClusterName=ci
SlurmctldHost=$node
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
SlurmctldPort=6817
SlurmdPort=6818
StateSaveLocation=$WORK/cluster/state
SlurmdSpoolDir=$WORK/cluster/spool
SlurmctldPidFile=$WORK/cluster/slurmctld.pid
SlurmdPidFile=$WORK/cluster/slurmd.pid
SlurmctldLogFile=$WORK/cluster/slurmctld.log
SlurmdLogFile=$WORK/cluster/slurmd.log
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
NodeName=$node CPUs=$(nproc) State=UNKNOWN
PartitionName=ci Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for _ in $(seq 1 30); do
    [[ -s "$WORK/cluster/slurmctld.pid" && -s "$WORK/cluster/slurmd.pid" ]] && break
    sleep 1
done
STARTED+=("$(cat "$WORK/cluster/slurmctld.pid")" "$(cat "$WORK/cluster/slurmd.pid")")
for _ in $(seq 1 30); do
    sinfo -h -o %t 2>/dev/null | grep -q idle && break
    sleep 1
done
sinfo

# 4. The sweeps and the fit in parts, through the scripts users submit, each from
# its own folder (its parts, logs and outputs apart), all submitted at once.
for run in parts-run whole-run robust-parts robust-whole fit-parts fit-whole; do
    mkdir -p "$WORK/$run"
    cp examples/vibro-driver.toml examples/vibro-driver.tuning.toml "$WORK/$run/"
    printf '%s' "$MEASURED" >"$WORK/$run/measured.csv"
done
(
    cd "$WORK/parts-run"
    HOST_SIM="$HOST_SIM" "$ROOT/deploy/slurm/submit.sh" "$PARTS" vibro-driver.toml "${GRID[@]}" \
        -- --write tuning.toml --plot tune.svg --format json
)
(
    cd "$WORK/robust-parts"
    HOST_SIM="$HOST_SIM" "$ROOT/deploy/slurm/submit.sh" "$PARTS" vibro-driver.toml "${ROBUST[@]}" \
        -- --write tuning.toml --plot tune.svg --format json
)
(
    cd "$WORK/fit-parts"
    COMMAND=calibrate HOST_SIM="$HOST_SIM" "$ROOT/deploy/slurm/submit.sh" "$PARTS" \
        vibro-driver.toml "${FIT[@]}" -- --write fitted.toml --format json
)
waited=0
while [[ -n "$(squeue -h)" ]]; do
    if ((waited >= TIMEOUT_S)); then
        echo "error: the Slurm jobs did not finish within $TIMEOUT_S s:" >&2
        squeue >&2
        exit 1
    fi
    sleep 1
    waited=$((waited + 1))
done
echo "the array jobs and the merge jobs finished in about $waited s"
ls "$WORK/parts-run" "$WORK/robust-parts" "$WORK/fit-parts"

# 5. The same unsharded, with the same relative names, and the merged outputs
# compared byte for byte.
(
    cd "$WORK/whole-run"
    "$HOST_SIM" tune vibro-driver.toml "${GRID[@]}" --write tuning.toml --plot tune.svg \
        --format json >tune.json
    cd "$WORK/robust-whole"
    "$HOST_SIM" tune vibro-driver.toml "${ROBUST[@]}" --write tuning.toml --plot tune.svg \
        --format json >tune.json
    cd "$WORK/fit-whole"
    "$HOST_SIM" calibrate vibro-driver.toml "${FIT[@]}" --write fitted.toml --format json \
        >tune.json
)
for pair in parts-run:whole-run robust-parts:robust-whole fit-parts:fit-whole; do
    parts=${pair%%:*}
    whole=${pair##*:}
    merge_log=("$WORK/$parts"/tune-merge-*.log)
    cmp "$WORK/$whole/tune.json" "${merge_log[0]}"
    for file in tuning.toml tune.svg fitted.toml; do
        if [[ -e "$WORK/$whole/$file" ]]; then
            cmp "$WORK/$whole/$file" "$WORK/$parts/$file"
        fi
    done
done
echo "slurm: $PARTS parts merged = unsharded, byte for byte: the sweep and the robust sweep (JSON, tuning table, plot), the fit (JSON, machine file)"
