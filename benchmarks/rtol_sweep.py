#!/usr/bin/env python3
"""The integrator's tolerance against the tuning sweep: does a looser rtol change
what a user gets from `host-sim tune`?

For each rtol the default sweep of MACHINE is run (`tune --format json --write`,
`--set simulation.rtol=R`); every grid point's travel speed is compared with the
first rtol's (the reference), the tables' offsets are compared, and the CPU and
wall time of each sweep are reported. The points that differ most are then run
alone at a ladder of tighter tolerances: where they differ as much between two
tight tolerances, the gait there is sensitive (chaotic), not the loose tolerance
inaccurate.

Usage (from the repository root, after `cargo build --release -p host-sim`):

  python3 benchmarks/rtol_sweep.py target/release/host-sim examples/vibro-driver.toml \
      [--rtols 1e-8,1e-5,1e-4,1e-3] [--ladder 1e-11,1e-10,1e-9,1e-8,1e-7] [--worst 2]

Standard library only. Exit status 2 on bad arguments or a failed run.
"""

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time


def fail(message):
    print(f"rtol_sweep: {message}", file=sys.stderr)
    sys.exit(2)


def floats(text, what):
    try:
        values = [float(v) for v in text.split(",") if v]
    except ValueError:
        fail(f"{what}: not a comma-separated list of numbers: {text!r}")
    if not values or any(not (v > 0) for v in values):
        fail(f"{what}: needs positive numbers, got {text!r}")
    return values


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def host_sim(binary, args):
    done = subprocess.run([binary, *args], capture_output=True, text=True)
    if done.returncode != 0:
        fail(f"{' '.join([binary, *args])} exited {done.returncode}: {done.stderr.strip()}")
    return done.stdout


def table_rows(path):
    """The table's data lines (comments hold the velocities to 7 digits)."""
    with open(path, encoding="utf-8") as f:
        return [line for line in f if line.strip() and not line.lstrip().startswith("#")]


def sweep(binary, machine, rtol, workdir):
    table = os.path.join(workdir, f"table-{rtol:g}.toml")
    cpu0, wall0 = children_cpu(), time.perf_counter()
    out = host_sim(
        binary,
        ["tune", machine, "--format", "json", "--write", table, "--set", f"simulation.rtol={rtol:g}"],
    )
    wall, cpu = time.perf_counter() - wall0, children_cpu() - cpu0
    grid = {(p["speed_rpm"], p["offset_deg"]): p["mean_velocity"] for p in json.loads(out)["grid"]}
    return grid, table_rows(table), wall, cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("host_sim")
    ap.add_argument("machine")
    ap.add_argument("--rtols", default="1e-8,1e-5,1e-4,1e-3")
    ap.add_argument("--ladder", default="1e-11,1e-10,1e-9,1e-8,1e-7")
    ap.add_argument("--worst", type=int, default=2)
    a = ap.parse_args()
    rtols, ladder = floats(a.rtols, "--rtols"), floats(a.ladder, "--ladder")
    if a.worst < 0:
        fail("--worst: needs a count >= 0")
    for path in (a.host_sim, a.machine):
        if not os.path.isfile(path):
            fail(f"{path}: no such file")

    with tempfile.TemporaryDirectory() as workdir:
        runs = [(r, *sweep(a.host_sim, a.machine, r, workdir)) for r in rtols]
    ref_rtol, ref_grid, ref_table = runs[0][0], runs[0][1], runs[0][2]
    print(f"reference rtol {ref_rtol:g}; {len(ref_grid)} grid points; speeds in mm/s\n")
    print("| rtol | sweep wall | sweep CPU | same table | median abs diff | max abs diff (point) |")
    print("|---|---|---|---|---|---|")
    worst = {}
    for rtol, grid, table, wall, cpu in runs:
        if grid.keys() != ref_grid.keys():
            fail(f"rtol {rtol:g}: another grid than the reference's")
        diffs = sorted(((abs(grid[k] - ref_grid[k]) * 1e3, k) for k in grid), reverse=True)
        median = statistics.median(d for d, _ in diffs)
        top, (speed, offset) = diffs[0]
        for d, k in diffs[: a.worst]:
            worst[k] = max(worst.get(k, 0.0), d)
        print(
            f"| {rtol:g} | {wall:.1f} s | {cpu:.1f} s | {'yes' if table == ref_table else 'NO'} "
            f"| {median:.2e} | {top:.4f} ({speed:g} rpm, {offset:g} deg) |"
        )
    if len(runs) == 1:
        return
    print("\nThe points that differ most, alone at tighter tolerances (`run --t-end 5`):\n")
    print("| point | " + " | ".join(f"{r:g}" for r in ladder) + " |")
    print("|---|" + "---|" * len(ladder))
    for speed, offset in sorted(worst):
        cells = []
        for r in ladder:
            out = host_sim(
                a.host_sim,
                ["run", a.machine, "--command", "right", "--speed", f"{speed:g}",
                 "--offset", f"{offset:g}", "--t-end", "5", "--format", "json",
                 "--set", f"simulation.rtol={r:g}"],
            )
            cells.append(f"{json.loads(out)['mean_velocity'] * 1e3:+.4f}")
        print(f"| {speed:g} rpm, {offset:g} deg | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
