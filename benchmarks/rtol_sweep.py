#!/usr/bin/env python3
"""The integrator's tolerance against the tuning sweep: does a looser rtol change
what a user gets from `host-sim tune`, and does it meet the accuracy the default
settings must have?

For each rtol the default sweep of MACHINE is run (`tune --format json --write`,
`--set simulation.rtol=R`); every grid point's travel speed is compared with the
first rtol's (the reference, 1e-10 by default), the tables' offsets are compared,
and the CPU and wall time of each sweep are reported.

The criterion (issue 24): at every grid point the travel speed at an rtol is within
1e-4 of the reference's, relative, or 0.01 mm/s, whichever is larger, except at
points shown to be chaotic, where it must land in the same gait band. Every point
that misses it at some rtol is run alone (`run --command right --speed S --offset O
--t-end 5`, the sweep's own run) at a ladder of tight tolerances, the reference's
included (its speed must be the sweep's to the bit: the premise that the lone run
is the grid point's). A point whose ladder spreads wider than the criterion's
limit is chaotic: tight tolerances disagree among themselves by more than the
accuracy asked for, so no tolerance can meet it there; its gait band is the range
of the ladder's speeds. The table then says per rtol and point: pass (within the
limit), band (chaotic, inside the band), or FAIL; and per rtol whether it meets
the criterion everywhere.

The ladder's spread cannot tell chaos from a reference not yet converged: a
point whose speed moves steadily with the tolerance spreads as wide. The ladder
table flags such a point (column "moves with rtol"): the ladder's steps from one
tolerance to the next that exceed the limit are two or more, all of one sign. Such
a point is still given its band; a band from an ensemble of perturbed initial
states at one tight tolerance would tell the two apart.

Usage (from the repository root, after `cargo build --release -p host-sim`):

  python3 benchmarks/rtol_sweep.py target/release/host-sim examples/vibro-driver.toml \
      [--rtols 1e-10,1e-8,1e-6,1e-5,1e-4,1e-3] \
      [--ladder 1e-12,3e-12,1e-11,3e-11,1e-10,3e-10,1e-9]

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
    ap.add_argument("--rtols", default="1e-10,1e-8,1e-6,1e-5,1e-4,1e-3")
    ap.add_argument("--ladder", default="1e-12,3e-12,1e-11,3e-11,1e-10,3e-10,1e-9")
    a = ap.parse_args()
    rtols, ladder = floats(a.rtols, "--rtols"), floats(a.ladder, "--ladder")
    if rtols[0] not in ladder:
        fail(f"--ladder: needs the reference rtol {rtols[0]:g} (the premise check)")
    for path in (a.host_sim, a.machine):
        if not os.path.isfile(path):
            fail(f"{path}: no such file")

    with tempfile.TemporaryDirectory() as workdir:
        runs = [(r, *sweep(a.host_sim, a.machine, r, workdir)) for r in rtols]
    ref_rtol, ref_grid, ref_table = runs[0][0], runs[0][1], runs[0][2]
    print(f"reference rtol {ref_rtol:g}; {len(ref_grid)} grid points; speeds in mm/s\n")
    print("| rtol | sweep wall | sweep CPU | same table | median abs diff | max abs diff (point) |")
    print("|---|---|---|---|---|---|")
    missed = set()
    for rtol, grid, table, wall, cpu in runs:
        if grid.keys() != ref_grid.keys():
            fail(f"rtol {rtol:g}: another grid than the reference's")
        diffs = sorted(((abs(grid[k] - ref_grid[k]) * 1e3, k) for k in grid), reverse=True)
        median = statistics.median(d for d, _ in diffs)
        top, (speed, offset) = diffs[0]
        missed |= {k for k in grid if abs(grid[k] - ref_grid[k]) > limit(ref_grid[k])}
        print(
            f"| {rtol:g} | {wall:.1f} s | {cpu:.1f} s | {'yes' if table == ref_table else 'NO'} "
            f"| {median:.2e} | {top:.4f} ({speed:g} rpm, {offset:g} deg) |"
        )
    if len(runs) == 1:
        return
    print(
        f"\nThe criterion: within max(1e-4 relative, 0.01 mm/s) of rtol {ref_rtol:g}, or, at a"
        "\nchaotic point (its ladder spreads wider than that), inside its gait band (the"
        "\nladder's range). The points that miss the limit at some rtol, alone at the ladder"
        "\n(mm/s):\n"
    )
    print(
        "| point | " + " | ".join(f"{r:g}" for r in ladder) + " | chaotic | band | moves with rtol |"
    )
    print("|---|" + "---|" * (len(ladder) + 3))
    bands = {}
    for speed, offset in sorted(missed):
        speeds = []
        for r in ladder:
            out = host_sim(
                a.host_sim,
                ["run", a.machine, "--command", "right", "--speed", f"{speed:g}",
                 "--offset", f"{offset:g}", "--t-end", "5", "--format", "json",
                 "--set", f"simulation.rtol={r:g}"],
            )
            speeds.append(json.loads(out)["mean_velocity"])
            if r == ref_rtol and speeds[-1] != ref_grid[(speed, offset)]:
                fail(
                    f"{speed:g} rpm, {offset:g} deg alone at rtol {r:g}: {speeds[-1]!r} m/s, "
                    f"the sweep's {ref_grid[(speed, offset)]!r}: not the grid point's run"
                )
        lo, hi = min(speeds), max(speeds)
        chaotic = hi - lo > limit(ref_grid[(speed, offset)])
        if chaotic:
            bands[(speed, offset)] = (lo, hi)
        cells = " | ".join(f"{v * 1e3:+.4f}" for v in speeds)
        band = f"{lo * 1e3:+.4f} to {hi * 1e3:+.4f}" if chaotic else ""
        drifts = "yes" if chaotic and moves_with_rtol(ladder, speeds, ref_grid[(speed, offset)]) else ""
        print(
            f"| {speed:g} rpm, {offset:g} deg | {cells} | {'yes' if chaotic else 'no'} | {band} "
            f"| {drifts} |"
        )
    print("\nPer rtol, the points that miss the limit (pass elsewhere):\n")
    print("| rtol | band (chaotic, inside its band) | FAIL | meets the criterion |")
    print("|---|---|---|---|")
    for rtol, grid, *_ in runs[1:]:
        inside, failed = [], []
        for k in sorted(missed):
            v = grid[k]
            if abs(v - ref_grid[k]) <= limit(ref_grid[k]):
                continue
            lo, hi = bands.get(k, (None, None))
            point = f"{k[0]:g}/{k[1]:g} ({v * 1e3:+.4f})"
            (inside if lo is not None and lo <= v <= hi else failed).append(point)
        print(
            f"| {rtol:g} | {', '.join(inside) or '-'} | {', '.join(failed) or '-'} "
            f"| {'yes' if not failed else 'no'} |"
        )


def moves_with_rtol(ladder, speeds, reference):
    """Whether the speeds at the ladder's tolerances move steadily with the
    tolerance: ordered by tolerance, the steps from one to the next larger than
    the limit are two or more and all of one sign (a reference perhaps not
    converged, rather than chaos: the tight runs then drift one way instead of
    scattering)."""
    ordered = [v for _, v in sorted(zip(ladder, speeds))]
    steps = [b - a for a, b in zip(ordered, ordered[1:]) if abs(b - a) > limit(reference)]
    return len(steps) >= 2 and (all(d > 0 for d in steps) or all(d < 0 for d in steps))


def limit(reference):
    """The criterion's limit at a point whose reference speed is `reference`, m/s:
    1e-4 of it, or 0.01 mm/s, whichever is larger."""
    return max(1e-4 * abs(reference), 1e-5)


if __name__ == "__main__":
    main()
