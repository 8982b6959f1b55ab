#!/usr/bin/env python3
"""The cost of a closed-loop run against the number of contacts.

Writes variants of a machine file whose platform stands on N collinear feet
(the file's two feet K1, K2 kept where they are, N - 2 more spread evenly
between them, with K1's restitution, friction and weight): from N = 3 on, the
contact system is singular (rank 3: a rigid platform has three degrees of
freedom in the plane). Runs each one `--repeats` times and reports the least
CPU time (user + system of the child; the least is the one least disturbed by
other work on the machine), the travel speed and the impact instants.

Usage (from the repository root, after `cargo build --release -p host-sim`):

  python3 benchmarks/contacts_scaling.py target/release/host-sim examples/vibro-driver.toml \
      [--feet 2,3,4,6,8] [--t-end 10] [--repeats 3]

The variants are written beside the machine file (its relative paths, the tuning
table, then hold), as .contacts-scaling-N.toml, and removed at the end.

A run that ends with exit 1 (the plant's progress guard) or outlasts
`--timeout` wall seconds is reported in the table as not finished, with its
reason, and the script then exits 1 after the table. Standard library only
(Python >= 3.11 for tomllib). Exit status 2 on bad arguments, a machine file it
cannot vary, or a run that fails otherwise.
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tomllib


# The plant's limit on contacts (shared::impact::MAX_CONTACTS).
MAX_CONTACTS = 16


def fail(message):
    """Exit 2 with `message`, named by the script that runs (this one, or one that
    imports its helpers)."""
    name = os.path.splitext(os.path.basename(sys.argv[0]))[0]
    print(f"{name}: {message}", file=sys.stderr)
    sys.exit(2)


def counts(text):
    try:
        values = [int(v) for v in text.split(",") if v]
    except ValueError:
        fail(f"--feet: not a comma-separated list of integers: {text!r}")
    if not values or any(v < 2 or v > MAX_CONTACTS for v in values):
        fail(f"--feet: counts from 2 to {MAX_CONTACTS} (the plant's limit), got {text!r}")
    return values


def variant(text, machine, feet):
    """The machine file's text with feet K3.. inserted before its first rotor."""
    contacts = machine.get("contacts", [])
    names = [c.get("name") for c in contacts]
    if len(contacts) != 2 or names != ["K1", "K2"] or machine.get("bodies"):
        fail("needs a single platform on exactly two contacts named K1 and K2")
    (x1, y1), (x2, y2) = contacts[0]["point"], contacts[1]["point"]
    if y1 != y2:
        fail("K1 and K2 at different heights: the feet would not be collinear")
    law = contacts[0]
    extra = []
    for i in range(1, feet - 1):
        x = x1 + (x2 - x1) * i / (feet - 1)
        extra.append(
            f'[[contacts]]\nname = "K{i + 2}"\npoint = [{x!r}, {y1!r}]\n'
            f'restitution = {law["restitution"]!r}\nfriction = {law["friction"]!r}\n'
            f'weight = {law.get("weight", 1.0)!r}\n\n'
        )
    at = text.find("[[rotors]]")
    if at < 0:
        fail("no [[rotors]] table to insert the feet before")
    return text[:at] + "".join(extra) + text[at:]


def read_machine(binary, path):
    """The machine file's text, its tables and its folder, where its variants are
    written (its relative paths, the tuning table, then hold there); the binary
    and the file checked to exist."""
    for name in (binary, path):
        if not os.path.isfile(name):
            fail(f"{name}: no such file")
    with open(path, encoding="utf-8") as f:
        text = f.read()
    try:
        machine = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        fail(f"{path}: {e}")
    return text, machine, os.path.dirname(os.path.abspath(path))


def run(binary, path, t_end, timeout, extra=()):
    """The run's CPU time and summary; the summary is None for a run that failed
    (exit 1: the progress guard) or took longer than `timeout` s of wall time,
    and then the CPU time is what it took and the reason is returned instead (the
    tool's whole message). `extra`: more arguments of `host-sim run`."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        done = subprocess.run(
            [binary, "run", path, "--command", "right", "--t-end", f"{t_end:g}",
             "--format", "json", *extra],
            capture_output=True, text=True, timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        done = None
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if done is None:
        return cpu, None, f"stopped after {timeout:g} s of wall time"
    if done.returncode == 1:
        lines = done.stderr.strip().splitlines()
        said = next((l for l in lines if l.startswith("error")), lines[-1] if lines else "no message")
        return cpu, None, f"exit 1: {said}"
    if done.returncode != 0:
        fail(f"{path}: host-sim exited {done.returncode}: {done.stderr.strip()}")
    return cpu, json.loads(done.stdout), None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("host_sim")
    ap.add_argument("machine")
    ap.add_argument("--feet", default="2,3,4,6,8")
    ap.add_argument("--t-end", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=None,
                    help="wall seconds after which a run is stopped and reported (default: none)")
    a = ap.parse_args()
    feet = counts(a.feet)
    if not (a.t_end > 0) or a.repeats < 1:
        fail("--t-end must be > 0 and --repeats >= 1")
    text, machine, folder = read_machine(a.host_sim, a.machine)
    rows, written = [], []
    try:
        for n in feet:
            path = os.path.join(folder, f".contacts-scaling-{n}.toml")
            written.append(path)
            with open(path, "w", encoding="utf-8") as f:
                f.write(variant(text, machine, n) if n > 2 else text)
            best, summary, why = None, None, None
            for _ in range(a.repeats):
                cpu, summary, why = run(a.host_sim, path, a.t_end, a.timeout)
                best = cpu if best is None else min(best, cpu)
                if why:
                    break
            rows.append((n, best, summary, why))
    finally:
        for path in written:
            if os.path.exists(path):
                os.remove(path)
    base = rows[0][1]
    print(f"{a.t_end:g} s simulated, --command right, least CPU of {a.repeats} runs\n")
    print("| feet | CPU | against the first | real-time factor | mean velocity (mm/s) | impact instants |")
    print("|---|---|---|---|---|---|")
    for n, cpu, s, why in rows:
        if why:
            print(f"| {n} | {cpu:.3f} s | {cpu / base:.2f} | did not finish | {why[:160]} | |")
            continue
        print(f"| {n} | {cpu:.3f} s | {cpu / base:.2f} | {a.t_end / cpu:.1f} "
              f"| {s['mean_velocity'] * 1e3:+.3f} | {s['impacts']} |")
    if any(why for *_, why in rows):
        sys.exit(1)


if __name__ == "__main__":
    main()
