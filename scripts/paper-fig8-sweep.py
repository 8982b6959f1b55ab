#!/usr/bin/env python3
"""The layout sweep of examples/paper-fig8.toml (docs/paper-fig8.md).

Runs `host-sim run examples/paper-fig8.toml --open-loop V` over a grid of the two
flat springs' stiffnesses and the actuator's preload against the element (its
spring's rest angle beyond the element), each with `--set`, and prints one
Markdown table row per layout: the mean travel velocity over the second half of
the run at each voltage, and, at the highest voltage, the impacts and the
actuator-element impact instants with those at which K3 and K4 struck together.
The layouts are sorted by their slowest velocity over the voltages. The best
layout, named on the last line, is the one whose slowest velocity is highest
among the layouts where K3 and K4 struck together at 10 % or more of their
impact instants (the paper's hypothesis of impacts that begin together).

    cargo build --release -p host-sim
    python3 scripts/paper-fig8-sweep.py [--voltages 5,6,7,8,9,10,11,12] [--t-end 3] [--jobs N]
        [--actuator K,...] [--element K,...] [--preloads RAD,...]

Standard library only; exit status 2 with a message for bad arguments.
"""

import argparse
import concurrent.futures
import csv
import itertools
import json
import math
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BINARY = os.path.join(ROOT, "target", "release", "host-sim")
MACHINE = os.path.join(ROOT, "examples", "paper-fig8.toml")

# The grid: the actuator's flat spring (N m/rad), the element's (N m/rad), the
# actuator's preload angle (rad: its spring relaxed that far to the right, beyond
# the element it rests against).
ACTUATOR_STIFFNESS = [10.0, 20.0, 40.0, 80.0, 160.0]
ELEMENT_STIFFNESS = [100.0, 400.0, 1600.0]
PRELOADS = [0.0, 0.005, 0.01, 0.02, 0.04]

# The least share of K3/K4 impact instants at which both struck, for a layout to
# be the best.
TOGETHER = 0.10


def together(events_csv):
    """Impact instants at which K3 or K4 struck, and of those the instants at
    which both did (same time in the events file)."""
    struck = {}
    with open(events_csv, newline="") as f:
        for row in csv.DictReader(f):
            if row["kind"] == "impact" and row["contact"] in ("K3", "K4"):
                struck.setdefault(row["t"], set()).add(row["contact"])
    both = sum(1 for s in struck.values() if s == {"K3", "K4"})
    return len(struck), both


def run(layout, voltage, t_end):
    k4, k3, preload = layout
    with tempfile.TemporaryDirectory() as d:
        events = os.path.join(d, "events.csv")
        args = [
            BINARY, "run", MACHINE,
            "--open-loop", f"{voltage}",
            "--t-end", f"{t_end}",
            "--format", "json",
            "--events", events,
            "--set", f"joints.spring4.stiffness={k4}",
            "--set", f"joints.spring3.stiffness={k3}",
            "--set", f"joints.spring4.rest_angle={-preload}",
        ]
        try:
            out = subprocess.run(args, capture_output=True, text=True)
            if out.returncode != 0:
                return layout, None, out.stderr.strip()
            summary = json.loads(out.stdout)
            instants, both = together(events)
        except (OSError, ValueError, KeyError) as e:
            return layout, None, f"{BINARY}: {e}"
        return layout, (summary, instants, both), None


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--voltages", default="5,6,7,8,9,10,11,12",
                   help="winding voltages, V, comma-separated")
    p.add_argument("--t-end", type=float, default=3.0, help="simulated time, s")
    p.add_argument("--actuator", help="the actuator spring's stiffnesses, N m/rad")
    p.add_argument("--element", help="the element spring's stiffnesses, N m/rad")
    p.add_argument("--preloads", help="the actuator's preload angles, rad")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    a = p.parse_args()
    def numbers(option, text, default):
        if text is None:
            return default
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            p.error(f"{option} {text}: give numbers separated by commas")
        if not all(v >= 0 and v < 1e9 for v in values):
            p.error(f"{option} {text}: each must be >= 0 and finite")
        return values

    voltages = sorted(set(numbers("--voltages", a.voltages, [])))
    springs4 = numbers("--actuator", a.actuator, ACTUATOR_STIFFNESS)
    springs3 = numbers("--element", a.element, ELEMENT_STIFFNESS)
    preloads = numbers("--preloads", a.preloads, PRELOADS)
    if not (math.isfinite(a.t_end) and a.t_end > 0 and a.jobs > 0 and voltages
            and all(0 < v <= 1000 for v in voltages)):
        p.error("--t-end must be a positive number of seconds, --jobs a positive count, "
                "each voltage in (0, 1000] V")
    if not os.path.exists(BINARY):
        print(f"error: {BINARY} not found: run `cargo build --release -p host-sim` first",
              file=sys.stderr)
        sys.exit(2)
    grid = list(itertools.product(springs4, springs3, preloads))
    jobs = list(itertools.product(grid, voltages))
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as pool:
        results = list(pool.map(lambda j: run(j[0], j[1], a.t_end), jobs))
    failed = [(l, e) for l, r, e in results if r is None]
    for l, e in failed:
        print(f"error: layout {l}: {e}", file=sys.stderr)
    if failed:
        sys.exit(1)
    by_layout = {}
    for (layout, voltage), (_, r, _) in zip(jobs, results):
        by_layout.setdefault(layout, {})[voltage] = r
    rows = sorted(by_layout.items(),
                  key=lambda kv: min(r[0]["mean_velocity"] for r in kv[1].values()))
    top = voltages[-1]
    print(f"open loop, {a.t_end} s; velocity: mean over the second half, mm/s; "
          f"rotor speed, impacts and K3/K4 instants at {top:g} V")
    print()
    print("| actuator spring, N m/rad | element spring, N m/rad | preload, rad | "
          + " | ".join(f"{v:g} V" for v in voltages)
          + " | rotor, rpm | impacts | K3/K4 instants | both together |")
    print("| ---: | ---: | ---: | " + " | ".join("---:" for _ in voltages)
          + " | ---: | ---: | ---: | ---: |")
    best = None
    for (k4, k3, preload), by_v in rows:
        s, instants, both = by_v[top]
        speeds = " | ".join(f"{by_v[v][0]['mean_velocity'] * 1e3:+.2f}" for v in voltages)
        print(f"| {k4:g} | {k3:g} | {preload:g} | {speeds} "
              f"| {s['rotor_speed_rpm'][0]:.0f} | {s['impacts']} | {instants} | {both} |")
        if instants > 0 and both >= TOGETHER * instants:
            best = (k4, k3, preload, min(r[0]["mean_velocity"] for r in by_v.values()))
    print()
    if best is None:
        print(f"best: none: K3 and K4 struck together at less than {TOGETHER:.0%} of their "
              "instants in every layout")
    else:
        print(f"best: actuator spring {best[0]:g} N m/rad, element spring {best[1]:g} N m/rad, "
              f"preload {best[2]:g} rad: at least {best[3] * 1e3:+.2f} mm/s over "
              + ", ".join(f"{v:g}" for v in voltages) + " V")


if __name__ == "__main__":
    main()
