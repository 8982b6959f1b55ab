#!/usr/bin/env python3
"""The platform's horizontal velocity over a window of a run, with its impacts
marked: the plot of docs/paper-fig8.md, made like the paper's Fig. 9.

    host-sim run examples/paper-fig8.toml --command right --speed 3000 --t-end 1.2 \\
        --set simulation.output_step=1e-4 --out trace.csv --events events.csv
    python3 scripts/paper-fig8-plot.py trace.csv events.csv OUT.svg [--from 1.0] [--to 1.1]

Reads the trace's `t` and `vx` columns and the events' impact rows; writes one SVG
(standard library only), whole or not at all (a path such as /dev/stdout is
written through). Bad arguments: a message, exit 2.
"""

import argparse
import csv
import math
import os
import sys
import tempfile

WIDTH, HEIGHT = 760, 370
LEFT, RIGHT, TOP, BOTTOM = 70, 20, 40, 62


def fail(message):
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def read_trace(path, t0, t1):
    try:
        with open(path, newline="") as f:
            rows = csv.DictReader(f)
            if rows.fieldnames is None or not {"t", "vx"} <= set(rows.fieldnames):
                fail(f"{path}: not a trace of `host-sim run --out` (needs columns t, vx)")
            return [(float(r["t"]), float(r["vx"])) for r in rows
                    if t0 <= float(r["t"]) <= t1]
    except OSError as e:
        fail(f"{path}: {e.strerror}")
    except (ValueError, TypeError):
        fail(f"{path}: line {rows.line_num}: not a number where one is expected "
             "(a truncated or edited file?)")


def read_impacts(path, t0, t1):
    """Impact instants in the window with the contacts that struck."""
    struck = {}
    try:
        with open(path, newline="") as f:
            rows = csv.DictReader(f)
            if rows.fieldnames is None or not {"t", "kind", "contact"} <= set(rows.fieldnames):
                fail(f"{path}: not an events file of `host-sim run --events`")
            for r in rows:
                t = float(r["t"])
                if r["kind"] == "impact" and t0 <= t <= t1:
                    struck.setdefault(t, set()).add(r["contact"])
    except OSError as e:
        fail(f"{path}: {e.strerror}")
    except (ValueError, TypeError):
        fail(f"{path}: line {rows.line_num}: not a number where one is expected "
             "(a truncated or edited file?)")
    return sorted(struck.items())


def kind(contacts):
    """How an impact instant is drawn: (colour, label)."""
    feet = contacts & {"K1", "K2"}
    if {"K3", "K4"} <= contacts:
        return ("#d62728", "K3 + K4 with a foot") if feet else ("#ff7f0e", "K3 + K4")
    if contacts & {"K3", "K4"}:
        return "#9467bd", "K3 or K4 alone (or with a foot)"
    return "#7f7f7f", "feet only"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("trace")
    p.add_argument("events")
    p.add_argument("out")
    p.add_argument("--from", dest="t0", type=float, default=1.0, help="window start, s")
    p.add_argument("--to", dest="t1", type=float, default=1.1, help="window end, s")
    a = p.parse_args()
    if not (math.isfinite(a.t0) and math.isfinite(a.t1)):
        fail(f"--from {a.t0} --to {a.t1}: give finite times in seconds")
    if not a.t1 > a.t0:
        fail(f"--from {a.t0} --to {a.t1}: the window must have --to after --from")
    trace = read_trace(a.trace, a.t0, a.t1)
    if len(trace) < 2:
        fail(f"{a.trace}: fewer than 2 rows between {a.t0} and {a.t1} s")
    impacts = read_impacts(a.events, a.t0, a.t1)

    v = [vx * 1e3 for _, vx in trace]
    vmin, vmax = min(v + [0.0]), max(v + [0.0])
    pad = 0.05 * (vmax - vmin or 1.0)
    vmin, vmax = vmin - pad, vmax + pad
    w, h = WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM

    def x(t):
        return LEFT + (t - a.t0) / (a.t1 - a.t0) * w

    def y(mm_s):
        return TOP + (vmax - mm_s) / (vmax - vmin) * h

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{WIDTH}" height="{HEIGHT}" fill="white"/>',
           f'<text x="{LEFT}" y="20" font-size="14">Platform 2: horizontal velocity '
           f'(examples/paper-fig8.toml)</text>',
           f'<rect x="{LEFT}" y="{TOP}" width="{w}" height="{h}" fill="none" stroke="black"/>',
           f'<line x1="{LEFT}" y1="{y(0):.1f}" x2="{LEFT + w}" y2="{y(0):.1f}" '
           f'stroke="#bbbbbb"/>']
    for i in range(6):
        t = a.t0 + (a.t1 - a.t0) * i / 5
        out.append(f'<text x="{x(t):.1f}" y="{TOP + h + 16}" text-anchor="middle">'
                   f'{t:.3f}</text>')
        mm_s = vmin + (vmax - vmin) * i / 5
        out.append(f'<text x="{LEFT - 6}" y="{y(mm_s) + 4:.1f}" text-anchor="end">'
                   f'{mm_s:.0f}</text>')
    out.append(f'<text x="{LEFT + w / 2}" y="{TOP + h + 32}" text-anchor="middle">t, s</text>')
    out.append(f'<text x="16" y="{TOP + h / 2}" transform="rotate(-90 16 {TOP + h / 2})" '
               f'text-anchor="middle">vx, mm/s</text>')
    seen = {}
    for t, contacts in impacts:
        colour, label = kind(contacts)
        seen[label] = colour
        out.append(f'<line x1="{x(t):.1f}" y1="{TOP}" x2="{x(t):.1f}" y2="{TOP + 8}" '
                   f'stroke="{colour}"/>')
    points = " ".join(f"{x(t):.1f},{y(vx * 1e3):.1f}" for t, vx in trace)
    out.append(f'<polyline points="{points}" fill="none" stroke="#1f77b4" stroke-width="1.2"/>')
    # The impacts' legend under the plot, after the axis label's line.
    lx = LEFT
    for label, colour in sorted(seen.items()):
        out.append(f'<line x1="{lx}" y1="{HEIGHT - 8}" x2="{lx}" y2="{HEIGHT}" '
                   f'stroke="{colour}" stroke-width="2"/>')
        out.append(f'<text x="{lx + 5}" y="{HEIGHT - 1}">{label}</text>')
        lx += 20 + 7 * len(label)
    out.append("</svg>")

    write_whole(a.out, "\n".join(out) + "\n")


def write_whole(path, text):
    """Writes `text` to `path` whole or not at all: a regular file (or a new one)
    through a temporary file beside it, renamed over it; a device or a stream
    (/dev/stdout, a pipe, anything under /dev or /proc) written through as it is."""
    absolute = os.path.abspath(path)
    special = absolute.startswith(("/dev/", "/proc/")) or (
        os.path.exists(absolute) and not os.path.isfile(absolute))
    real = os.path.realpath(absolute)
    if special:
        try:
            with open(path, "w") as f:
                f.write(text)
        except OSError as e:
            fail(f"{path}: {e.strerror}")
        return
    try:
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(real), suffix=".svg.part")
        try:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)
            with os.fdopen(fd, "w") as f:
                f.write(text)
            os.replace(tmp, real)
        except BaseException:
            os.unlink(tmp)
            raise
    except OSError as e:
        fail(f"{path}: {e.strerror}")

if __name__ == "__main__":
    main()
