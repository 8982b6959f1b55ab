#!/usr/bin/env python3
"""The cost of the processor in the loop against the controller in the loop.

Runs `host-sim run MACHINE --command right --t-end T --format json` with the
controller in the loop (SIL) and with `--firmware ELF` (PIL, docs/pil.md),
alternately, `--reps` times each, so that both see the same machine load. For
each run: the wall time, the CPU time (user + system of host-sim and of what it
waited for: QEMU and defmt-print in PIL) and the summary's mean velocity; for
PIL also the firmware's control task's instructions per tick, from its own clock
(the summary's `firmware.instructions_per_tick`). Prints a Markdown table of the
medians and the PIL/SIL ratios.

    python3 benchmarks/pil_cost.py target/release/host-sim examples/vibro-driver.toml \\
        firmware/target/thumbv7em-none-eabihf/release/pil --t-end 10 --reps 5
"""

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time


def children_cpu():
    """User + system seconds of every waited-for child so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def one_run(host_sim, machine, t_end, elf):
    """Wall and CPU seconds of one run, and its JSON summary."""
    args = [host_sim, "run", machine, "--command", "right", "--t-end", str(t_end),
            "--format", "json"]
    if elf:
        args += ["--firmware", elf, "--firmware-log", "/dev/null"]
    cpu0, wall0 = children_cpu(), time.perf_counter()
    done = subprocess.run(args, capture_output=True, text=True, check=False)
    wall, cpu = time.perf_counter() - wall0, children_cpu() - cpu0
    if done.returncode != 0:
        sys.exit(f"error: {' '.join(args)} exited {done.returncode}:\n{done.stderr}")
    return wall, cpu, json.loads(done.stdout)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("host_sim")
    p.add_argument("machine")
    p.add_argument("elf")
    p.add_argument("--t-end", type=float, default=10.0)
    p.add_argument("--reps", type=int, default=5)
    a = p.parse_args()
    if a.reps < 1:
        p.error(f"--reps {a.reps}: at least 1")
    if not a.t_end > 0:
        p.error(f"--t-end {a.t_end}: above 0 s")

    runs = {"sil": [], "pil": []}
    for _ in range(a.reps):
        runs["sil"].append(one_run(a.host_sim, a.machine, a.t_end, None))
        runs["pil"].append(one_run(a.host_sim, a.machine, a.t_end, a.elf))

    med = {k: (statistics.median(r[0] for r in v), statistics.median(r[1] for r in v))
           for k, v in runs.items()}
    print(f"{a.reps} runs each of {a.t_end:g} s, alternately; medians\n")
    print("| | wall (s) | real-time factor | CPU (s) | mean velocity (m/s) |")
    print("| --- | --- | --- | --- | --- |")
    for k, name in (("sil", "controller in the loop"), ("pil", "firmware in the loop")):
        wall, cpu = med[k]
        v = runs[k][0][2]["mean_velocity"]
        print(f"| {name} | {wall:.3f} | {a.t_end / wall:.1f}x | {cpu:.3f} | {v:+.7f} |")
    print(f"| PIL / SIL | {med['pil'][0] / med['sil'][0]:.2f} | | "
          f"{med['pil'][1] / med['sil'][1]:.2f} | |")
    cost = runs["pil"][0][2]["firmware"].get("instructions_per_tick")
    if cost:
        print(f"\nthe firmware's control task: mean {cost['mean']:.0f}, max {cost['max']} "
              f"instructions a tick over {cost['ticks']} ticks")
    else:
        print("\nthe firmware's control task: not in this host-sim's summary (before 2026-11-29)")
    walls = {k: ", ".join(f"{r[0]:.3f}" for r in v) for k, v in runs.items()}
    print(f"every wall time (s): SIL {walls['sil']}; PIL {walls['pil']}")


if __name__ == "__main__":
    main()
