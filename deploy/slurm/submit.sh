#!/bin/bash
# Submits a sweep (or a fit's multistart) in N parts and its merge, the merge to
# start only when every part succeeded (docs/scale-out.md). From the directory the
# paths are relative to:
#   deploy/slurm/submit.sh N MACHINE.toml [tune options...] -- [merge options...]
#   COMMAND=calibrate deploy/slurm/submit.sh N MACHINE.toml --measured FILE.csv --fit KEY \
#       [calibrate options...] -- [merge options...]
# e.g. deploy/slurm/submit.sh 8 examples/vibro-driver.toml --offsets 0:360:10 -- --write t.toml
#      deploy/slurm/submit.sh 8 examples/vibro-driver.toml --robust -- --write t.toml

# Stop at the first failing command, an unset variable or a failing pipe stage.
set -euo pipefail
# Where this script and the two batch scripts are.
here=$(dirname "$0")
# N, the number of parts, then the tune arguments up to `--`, the merge's after.
N=${1:?usage: submit.sh N MACHINE.toml [tune options...] -- [merge options...]}
shift
tune_args=()
while [ $# -gt 0 ] && [ "$1" != -- ]; do tune_args+=("$1"); shift; done
[ $# -gt 0 ] && shift
# The array job, tasks 1 to N; --parsable prints its id (and ";cluster" on some sites).
# COMMAND (tune by default, or calibrate) reaches the tasks with the environment.
array=$(sbatch --parsable --array=1-"$N" --export=ALL,COMMAND="${COMMAND:-tune}" \
    "$here/tune-array.sbatch" "${tune_args[@]}")
array=${array%%;*}
# The merge, held until every task of the array ended with exit 0.
merge=$(sbatch --parsable --dependency=afterok:"$array" --export=ALL,N="$N" "$here/merge.sbatch" "$@")
echo "tune array job $array (parts 1-$N), merge job ${merge%%;*}"
