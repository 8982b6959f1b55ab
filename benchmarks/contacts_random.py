#!/usr/bin/env python3
"""Closed-loop runs on random layouts of feet, on one body and on two.

Each layout replaces the machine file's two feet K1, K2 with N feet K1 .. KN,
drawn from the layout's seed (the same seed writes the same file):

- one body: the platform on N = 3 to 8 feet at random points along its length,
  x in [-0.10, 0.10] m (the reference platform is 0.20 m long, centred on x = 0);
- two bodies: the platform and a second body, "sled", a steel block 0.10 m long
  and 0.03 m high (0.5 kg, I = M (a^2 + b^2) / 12 = 4.5e-4 kg m^2) right of it,
  x in [0.105, 0.205] m, its centre of mass at [0.155, 0.015], joined to the
  platform by a revolute joint "hitch" at [0.1025, 0.015] with a torsional
  spring-damper (stiffness log-uniform in [10, 1e4] N m/rad, damping in
  [1e-3, 1] N m s/rad: at most 3 600 rad/s and 1 300 1/s on the joint's least
  inertia, 7.66e-4 kg m^2 as the reader computes it, far within its 100 000), at rest at
  t = 0; N = 4 to 8 feet, split at random between the two bodies, at least two
  on each (each body then stands on its own feet and the spring carries nothing
  at rest; three feet on two bodies are not drawn).

On each body two feet stand on the floor (height 0) at x = a and x = b, one on
each side of its centre of mass and at least 1 cm from it and from the body's
ends, so the body rests on them at t = 0; its other feet are at random x outside
[a, b] (at least 1 mm from a and b), raised on the parabola y = k (x - a) (x - b),
k drawn log-uniform in [1e-4, 0.1] 1/m: heights from 2 nanometres to 1.7
millimetres, no three feet collinear, every foot a corner of the lower convex hull
of the feet. A foot above that hull (between a and b, or higher than the parabola)
could never touch the floor while the other feet hold the body up, and one raised
by millimetres never does in the reference gait (the platform's hops and rocking
are tens of micrometres and hundredths of a degree): such feet would leave the
two standing ones the only contacts in play. Every foot has its own restitution,
uniform in [0.1, 0.6], and friction, uniform in [0.2, 0.8].

Layout `seed` has N = LO + seed mod (HI - LO + 1) feet (`--feet LO,HI`, from 3 to
8 by default; at least 4 on two bodies), so consecutive seeds take every count.
Each layout is run once as a closed loop (`host-sim run FILE --command right
--t-end T --format json --events FILE`), and so is the machine file itself (its
two feet: the reference of the CPU column). Reported per layout: its seed, the
feet (on the platform + on the sled), the CPU time (user + system of the child),
its ratio to the reference's, the mean velocity, the impact instants, how many
feet took an impact (a normal impulse > 0 in the events file), the impact rows
outside their foot's friction cone (`P_n < 0`, or `|P_t| > mu P_n` beyond
rounding), the steps the plant took past an event (its warning "a step was taken
past an event": the same event handled again and again at one instant), the
other warnings (the two-body machines' note that the controller's constants are a
single platform's aside), and notes: a controller state other than running, a
fault, or the run's `not_a_travel` (a body through the floor or tipped over).
Under the table, each layout's warnings by kind: how many, and the first in full.
With `--forces` each run writes its trace too (`--out`, the reference's as well,
so the CPU column includes writing it), and the table counts the trace's rows
where a closed foot pulls: a normal force below -eps_F, 1e-6 of the machine's
weight, which docs/cli-run.md says a closed contact never passes.

Usage (from the repository root, after `cargo build --release -p host-sim`):

  python3 benchmarks/contacts_random.py target/release/host-sim examples/vibro-driver.toml \\
      [--bodies 1,2] [--layouts 10] [--seed 1] [--feet 3,8] [--t-end 10] \\
      [--timeout 300] [--keep] [--forces]

`--seed S --layouts L` runs the seeds S .. S + L - 1 on each count of bodies;
`--seed 7 --layouts 1 --bodies 2` reruns one layout alone. The layouts are
written beside the machine file (its relative paths, the tuning table, then hold)
as .contacts-random-B-body-SEED.toml and removed at the end, except those of runs
that did not finish (kept, with the command that reproduces them) and every one
with `--keep`.

A run that ends with exit 1 (the plant's progress guard) or outlasts `--timeout`
wall seconds is not finished: the table says so, the tool's whole message and the
command follow it, and the script exits 1 after the table. Standard library only
(Python >= 3.11 for tomllib). Exit status 2 on bad arguments, a machine file it
cannot vary, or a run that fails otherwise (a layout the reader refuses included).
"""

import argparse
import csv
import math
import os
import random
import re
import sys
import tempfile
import tomllib

from contacts_scaling import MAX_CONTACTS, fail, read_machine, run

# The platform's extent along x (m) and its centre of mass's x; the sled's.
PLATFORM = (-0.10, 0.10, 0.0)
SLED = (0.105, 0.205, 0.155)
SLED_MASS = 0.5
SLED_TEXT = """
# The second body of contacts_random.py's two-body layouts.
[[bodies]]
name = "sled"
mass = {mass!r}
inertia = 4.5e-4
position = [0.155, 0.015]

[[joints]]
name = "hitch"
kind = "revolute"
bodies = ["platform", "sled"]
point = [0.1025, 0.015]
stiffness = {stiffness!r}
damping = {damping!r}
"""
# The warning every run of a two-body layout gives (the controller's constants
# are a single platform's); the table counts the others.
SEVERAL_BODIES = "the controller's constants (lift-off band, resonance) are a single platform's"
# The end of the warning of a step taken past an event (the same event handled
# again and again at one instant without effect).
PAST_AN_EVENT = "a step was taken past an event"
# A standing foot's least distance from its body's centre of mass and ends along
# x (m); a raised foot's least distance from a standing one.
STANCE = 0.01
APART = 0.001
# The curvature of the line the feet lie on, drawn log-uniform (1/m).
CURVATURE = (1e-4, 0.1)


def log_uniform(rng, low, high):
    return math.exp(rng.uniform(math.log(low), math.log(high)))


def foot(rng, body, x, height):
    """One [[contacts]] table's keys but its name: a foot of `body` at (x, height)."""
    return {"body": body, "x": x, "y": float(f"{height:.3g}"),
            "restitution": round(rng.uniform(0.1, 0.6), 2),
            "friction": round(rng.uniform(0.2, 0.8), 2)}


def body_feet(rng, body, extent, count):
    """`count` >= 2 feet of `body` over `extent` = (x_min, x_max, x_c): two
    standing at a < x_c < b, the others outside [a, b] on the parabola
    y = k (x - a) (x - b) (k > 0: every foot a corner of the lower convex hull)."""
    x_min, x_max, x_c = extent
    a = round(rng.uniform(x_min + STANCE, x_c - STANCE), 4)
    b = round(rng.uniform(x_c + STANCE, x_max - STANCE), 4)
    k = log_uniform(rng, *CURVATURE)
    feet = [foot(rng, body, a, 0.0), foot(rng, body, b, 0.0)]
    left, right = a - APART - x_min, x_max - b - APART
    for _ in range(count - 2):
        u = rng.uniform(0.0, left + right)
        x = round(x_min + u if u < left else b + APART + (u - left), 4)
        feet.append(foot(rng, body, x, k * (x - a) * (x - b)))
    return feet


def layout(seed, bodies, low, high):
    """Layout `seed` on `bodies` bodies: its feet (in file order, by x) and, on
    two bodies, the hitch's stiffness and damping."""
    rng = random.Random(f"contacts_random {bodies} {seed}")
    n = low + seed % (high - low + 1)
    if bodies == 1:
        feet, spring = body_feet(rng, "platform", PLATFORM, n), None
    else:
        on_sled = 2 + sum(rng.random() < 0.5 for _ in range(n - 4))
        feet = (body_feet(rng, "platform", PLATFORM, n - on_sled)
                + body_feet(rng, "sled", SLED, on_sled))
        spring = (float(f"{log_uniform(rng, 10.0, 1e4):.3g}"),
                  float(f"{log_uniform(rng, 1e-3, 1.0):.3g}"))
    return sorted(feet, key=lambda f: f["x"]), spring


def machine_text(text, machine, feet, spring):
    """The machine file's text with its feet replaced by `feet` and, with a
    `spring`, the sled and its hitch appended."""
    names = [c.get("name") for c in machine.get("contacts", [])]
    if names != ["K1", "K2"] or machine.get("bodies") or machine.get("joints"):
        fail("needs a single platform on exactly two contacts named K1 and K2")
    start, end = text.find("[[contacts]]"), text.find("[[rotors]]")
    if start < 0 or end < start or text.count("[[contacts]]", end) != 0:
        fail("needs its [[contacts]] tables together, before its first [[rotors]]")
    tables = "".join(
        f'[[contacts]]\nname = "K{i + 1}"\nbody = "{f["body"]}"\n'
        f'point = [{f["x"]!r}, {f["y"]!r}]\nrestitution = {f["restitution"]!r}\n'
        f'friction = {f["friction"]!r}\n\n'
        for i, f in enumerate(feet)
    )
    out = text[:start] + tables + text[end:]
    if spring:
        out += SLED_TEXT.format(mass=SLED_MASS, stiffness=spring[0], damping=spring[1])
    written = tomllib.loads(out)
    if len(written["contacts"]) != len(feet) or written["rotors"] != machine["rotors"]:
        fail("the feet replaced did not read back as written: is the file laid out as "
             "examples/vibro-driver.toml is?")
    return out


def struck(events, feet):
    """From an events file: the names of the contacts that took a normal impulse
    > 0 in an impact, and the count of impact rows outside their foot's friction
    cone (`P_n >= 0` exactly, `|P_t| <= mu P_n` to rounding)."""
    mu = {f"K{i + 1}": f["friction"] for i, f in enumerate(feet)}
    names, outside = set(), 0
    with open(events, newline="", encoding="utf-8") as f:
        for row in csv.DictReader(f):
            if row["kind"] != "impact":
                continue
            p_n, p_t = float(row["normal_impulse"]), float(row["tangential_impulse"])
            if p_n < 0 or abs(p_t) > mu[row["contact"]] * p_n * (1 + 1e-12) + 1e-300:
                outside += 1
            if p_n > 0:
                names.add(row["contact"])
    return names, outside


def weight(machine, spring):
    """The machine's weight (N): the platform, the eccentric masses and, on two
    bodies (a `spring`), the sled, times the magnitude of gravity."""
    g = machine.get("fundament", {}).get("gravity", [0.0, -9.81])
    mass = machine["platform"]["mass"] + sum(r["eccentric_mass"] for r in machine["rotors"])
    return math.hypot(*g) * (mass + (SLED_MASS if spring else 0.0))


def pulling(trace, w):
    """From a trace: how many rows have a closed foot pulling, its normal force
    below -eps_F = -1e-6 of the weight `w` (docs/cli-run.md, `--out`: a closed
    contact never pulls beyond it; the row just before a lift-off is at it, to
    the lift-off's location: the reference machine's own 10 s closed loop reaches
    1.00016 eps_F, so 1 % more is allowed), and the least normal force of all
    rows (N)."""
    limit = -1e-6 * w * 1.01
    count, least = 0, 0.0
    with open(trace, newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        columns = [i for i, name in enumerate(next(reader)) if name.startswith("fn_")]
        for row in reader:
            low = min(float(row[i]) for i in columns)
            least = min(least, low)
            count += low < limit
    return count, least


def kinds(warnings):
    """The warnings grouped by their text with every number in it replaced,
    in the order of each kind's first."""
    told = {}
    for w in warnings:
        told.setdefault(re.sub(r"[0-9]+(\.[0-9]+)?", "#", w), []).append(w)
    return told


def numbers(text, name, low, high, count=None):
    try:
        values = [int(v) for v in text.split(",") if v]
    except ValueError:
        fail(f"{name}: not a comma-separated list of integers: {text!r}")
    if not values or (count and len(values) != count) or any(v < low or v > high for v in values):
        size = f"{count} integers" if count else "integers"
        fail(f"{name}: {size} from {low} to {high}, got {text!r}")
    return values


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("host_sim")
    ap.add_argument("machine")
    ap.add_argument("--bodies", default="1,2", help="1, 2 or 1,2 (default)")
    ap.add_argument("--layouts", type=int, default=10, help="layouts per count of bodies")
    ap.add_argument("--seed", type=int, default=1, help="the first layout's seed")
    ap.add_argument("--feet", default="3,8", help="LO,HI: the counts of feet drawn")
    ap.add_argument("--t-end", type=float, default=10.0)
    ap.add_argument("--timeout", type=float, default=300.0,
                    help="wall seconds after which a run is stopped and reported")
    ap.add_argument("--keep", action="store_true", help="keep every layout's file")
    ap.add_argument("--forces", action="store_true",
                    help="write each run's trace too and count its rows where a closed foot pulls")
    a = ap.parse_args()
    bodies = sorted(set(numbers(a.bodies, "--bodies", 1, 2)))
    low, high = numbers(a.feet, "--feet", 3, MAX_CONTACTS, count=2)
    if low > high:
        fail(f"--feet: LO,HI with LO <= HI, got {a.feet!r}")
    if 2 in bodies and high < 4:
        fail(f"--feet: two bodies need at least 4 feet (two on each), got {a.feet!r}")
    if a.layouts < 1 or a.seed < 0:
        fail("--layouts must be >= 1 and --seed >= 0")
    if not (a.t_end > 0) or not (a.timeout > 0):
        fail("--t-end and --timeout must be > 0")
    text, machine, folder = read_machine(a.host_sim, a.machine)
    rows, written, kept = [], [], []
    with tempfile.TemporaryDirectory() as scratch:
        events, trace = os.path.join(scratch, "events.csv"), os.path.join(scratch, "trace.csv")
        extra = ("--events", events) + (("--out", trace) if a.forces else ())
        cpu, summary, why = run(a.host_sim, a.machine, a.t_end, a.timeout, extra)
        if why:
            fail(f"{a.machine}: the reference run did not finish: {why}")
        reference = cpu
        checked = ""
        if a.forces:
            count, least = pulling(trace, weight(machine, None))
            checked = f", {count} trace rows with a foot pulling (least force {least:.6g} N)"
        try:
            for b in bodies:
                for seed in range(a.seed, a.seed + a.layouts):
                    feet, spring = layout(seed, b, max(low, 2 * b), high)
                    path = os.path.join(folder, f".contacts-random-{b}-body-{seed}.toml")
                    written.append(path)
                    with open(path, "w", encoding="utf-8") as f:
                        f.write(machine_text(text, machine, feet, spring))
                    cpu, summary, why = run(a.host_sim, path, a.t_end, a.timeout, extra)
                    hit, outside = struck(events, feet) if os.path.exists(events) else (set(), 0)
                    pull = None
                    if a.forces and os.path.exists(trace):
                        pull = pulling(trace, weight(machine, spring))
                    for done in (events, trace):
                        if os.path.exists(done):
                            os.remove(done)
                    if why:
                        kept.append((path, why))
                    rows.append((seed, b, feet, spring, cpu, summary, why, hit, outside, pull))
        finally:
            for path in written:
                if os.path.exists(path) and not a.keep and path not in (p for p, _ in kept):
                    os.remove(path)
    print(f"{a.t_end:g} s simulated, --command right, one run each; reference: "
          f"{a.machine} (two feet), {reference:.3f} s of CPU{checked}\n")
    print("| seed | bodies | feet (platform + sled) | CPU | against the reference "
          "| mean velocity (mm/s) | impact instants | feet that struck | impacts outside the cones "
          "| trace rows with a foot pulling (least force) | steps past an event | other warnings "
          "| notes |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    warned = []
    for seed, b, feet, spring, cpu, s, why, hit, outside, pull in rows:
        on = sum(f["body"] == "platform" for f in feet)
        split = f"{len(feet)}" if b == 1 else f"{len(feet)} ({on} + {len(feet) - on})"
        head = (f"| {seed} | {b} | {split} | {cpu:.3f} s | {cpu / reference:.2f} ")
        pulls = "not checked" if pull is None else (
            f"{pull[0]} ({pull[1]:.4g} N)" if pull[0] else "0")
        if why:
            print(head + f"| did not finish (below) | | {len(hit)} of {len(feet)} | {outside} "
                  f"| {pulls} | | | |")
            continue
        v = "null" if s["mean_velocity"] is None else f"{s['mean_velocity'] * 1e3:+.3f}"
        told = kinds(w for w in s["warnings"] if not w.startswith(SEVERAL_BODIES))
        past = sum(len(ws) for k, ws in told.items() if k.endswith(PAST_AN_EVENT))
        other = sum(len(ws) for k, ws in told.items() if not k.endswith(PAST_AN_EVENT))
        notes = [] if s["state"] == "running" and not s["faults"] else [
            "controller " + " ".join([s["state"], *s["faults"]])]
        if s["not_a_travel"]:
            notes.append(s["not_a_travel"])
        print(head + f"| {v} | {s['impacts']} | {len(hit)} of {len(feet)} | {outside} "
              f"| {pulls} | {past} | {other} | {'; '.join(notes)} |")
        warned.extend((seed, b, ws) for ws in told.values())
    if warned:
        print("\nThe warnings, by kind (the numbers in them aside): how many, the first.")
    for seed, b, ws in warned:
        print(f"\n- seed {seed}, {b} {'body' if b == 1 else 'bodies'}: {len(ws)} x {ws[0]}")
    for path, why in kept:
        rel = os.path.relpath(path)
        print(f"\nnot finished: {a.host_sim} run {rel} --command right --t-end {a.t_end:g} "
              f"--format json\n  {why}")
    if kept:
        sys.exit(1)


if __name__ == "__main__":
    main()
