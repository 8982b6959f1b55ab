#!/usr/bin/env python3
"""MuJoCo model of a host-sim machine file, side by side with host-sim.

Reads a machine file (examples/vibro-driver.toml), writes an MJCF model of it
(planar platform on two point feet against the floor, two unbalance rotors held
at a constant speed and phase offset by stiff servos) and runs it with MuJoCo.
Standard library, mujoco and numpy only (Python >= 3.11 for tomllib).

Usage (from the repository root, a venv with `pip install mujoco numpy`):

  python benchmarks/mujoco/reference_machine.py xml examples/vibro-driver.toml [--out model.xml]
      print (or write) the generated MJCF, with the restitution calibration applied
  python benchmarks/mujoco/reference_machine.py calibrate examples/vibro-driver.toml
      drop test of one foot: the damping ratio that gives each contact's restitution
  python benchmarks/mujoco/reference_machine.py run examples/vibro-driver.toml \
          --speed 3000 --offset 90 --step 1e-4 [--t-end 10] [--format table|json]
      one run: mean velocity over the second half, like `host-sim run ... --format json`
  python benchmarks/mujoco/reference_machine.py converge examples/vibro-driver.toml \
          --speed 3000 --offsets 90,120 --steps 1e-4,5e-5,2e-5,1e-5
      the mean travel speed at each time step (pick the largest within ~2 % of the finest)
  python benchmarks/mujoco/reference_machine.py bench examples/vibro-driver.toml \
          --host-sim target/release/host-sim --step 1e-4 [--repeats 5] [--cpu 1] \
          [--host-sim-set simulation.rtol=1e-3]
      wall time of host-sim and of MuJoCo, alternating, both pinned to one core

Conventions. The plane of motion (x right, y up) is MuJoCo's x-z plane; angles
are counter-clockwise positive in the machine file's sense, i.e. MuJoCo hinges
about -y. The platform body's frame is its centre of mass (the platform without
the eccentric masses); the rotor joints' angles are the eccentric angles phi in
the platform frame (docs/plant-model.md). The phase offset is
theta_1 - theta_2 with theta_k = s_k (phi_k - index_angle_k), s = +1 ccw, -1 cw
(docs/machine-file.md, "The phase convention"). Each rotor follows
theta_k(t) = integral of omega(t) dt +- offset / 2, omega ramped from 0 to the
speed over --ramp seconds, by a PD servo on its joint (a position actuator whose
reference is an integrator activation, plus a velocity actuator).

Contacts are MuJoCo's soft contacts: solref = (timeconst, dampratio), with
dampratio found by a drop test (`calibrate`) so that one foot dropped on the
floor rebounds with the file's restitution. Exit status 2 on bad arguments or a
machine file this model cannot represent.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
import tomllib

import numpy as np

try:
    import mujoco
except ImportError:  # pragma: no cover
    print("error: the Python package `mujoco` is not installed (pip install mujoco numpy)",
          file=sys.stderr)
    sys.exit(2)


class InputError(Exception):
    """A problem with the arguments or the machine file: exit status 2."""


# ---------------------------------------------------------------------------
# Machine file


def _vec2(table, key, path):
    v = table.get(key)
    if (not isinstance(v, list) or len(v) != 2
            or not all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in v)):
        raise InputError(f"{path}.{key}: expected [x, y] numbers, got {v!r}")
    return float(v[0]), float(v[1])


def _num(table, key, path, default=None, positive=False, nonneg=False):
    if key not in table:
        if default is None:
            raise InputError(f"{path}.{key}: missing")
        return float(default)
    v = table[key]
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
        raise InputError(f"{path}.{key}: expected a number, got {v!r}")
    if positive and v <= 0:
        raise InputError(f"{path}.{key}: must be > 0, got {v}")
    if nonneg and v < 0:
        raise InputError(f"{path}.{key}: must be >= 0, got {v}")
    return float(v)


def load_machine(path):
    """The parts of a machine file the MuJoCo model uses, validated."""
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file")
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"{path}: not valid TOML: {e}")
    if "bodies" in doc or "joints" in doc:
        raise InputError(f"{path}: [[bodies]]/[[joints]]: this model has one platform only")
    fund = doc.get("fundament", {})
    point = _vec2(fund, "point", "fundament") if "point" in fund else (0.0, 0.0)
    normal = _vec2(fund, "normal", "fundament") if "normal" in fund else (0.0, 1.0)
    gravity = _vec2(fund, "gravity", "fundament") if "gravity" in fund else (0.0, -9.81)
    nn = math.hypot(*normal)
    if nn == 0 or abs(normal[0] / nn) > 1e-12 or normal[1] <= 0:
        raise InputError("fundament.normal: this model supports a level floor only ([0, 1])")
    plat = doc.get("platform")
    if not isinstance(plat, dict):
        raise InputError(f"{path}: [platform] missing")
    m = {
        "floor_y": point[1],
        "gravity": gravity,
        "mass": _num(plat, "mass", "platform", positive=True),
        "inertia": _num(plat, "inertia", "platform", positive=True),
        "position": _vec2(plat, "position", "platform"),
        "angle": _num(plat, "angle", "platform", default=0.0),
        "velocity": _vec2(plat, "velocity", "platform") if "velocity" in plat else (0.0, 0.0),
        "angular_velocity": _num(plat, "angular_velocity", "platform", default=0.0),
    }
    contacts = doc.get("contacts")
    if not isinstance(contacts, list) or not contacts:
        raise InputError(f"{path}: [[contacts]]: at least one contact needed")
    m["contacts"] = []
    for i, c in enumerate(contacts):
        name = c.get("name", f"#{i + 1}")
        p = f"contacts.{name}"
        if "obstacle" in c or "body" in c:
            raise InputError(f"{p}: contacts against bodies are not modelled here")
        e = _num(c, "restitution", p)
        if not 0.0 <= e <= 1.0:
            raise InputError(f"{p}.restitution: must be in [0, 1], got {e}")
        pt = _vec2(c, "point", p)
        if pt[1] < m["floor_y"] - 1e-12:
            raise InputError(f"{p}.point: below the fundament at t = 0")
        m["contacts"].append({"name": str(name), "point": pt, "restitution": e,
                              "friction": _num(c, "friction", p, nonneg=True)})
    rotors = doc.get("rotors")
    if not isinstance(rotors, list) or len(rotors) != 2:
        raise InputError(f"{path}: [[rotors]]: exactly two rotors needed")
    m["rotors"] = []
    for i, r in enumerate(rotors):
        p = f"rotors.{r.get('name', i + 1)}"
        sense = r.get("sense")
        if sense not in ("ccw", "cw"):
            raise InputError(f"{p}.sense: must be \"ccw\" or \"cw\", got {sense!r}")
        m["rotors"].append({
            "name": str(r.get("name", f"rotor{i + 1}")),
            "axis": _vec2(r, "axis", p),
            "mass": _num(r, "eccentric_mass", p, nonneg=True),
            "ecc": _num(r, "eccentricity", p, nonneg=True),
            "inertia": _num(r, "inertia", p, positive=True),
            "sense": 1.0 if sense == "ccw" else -1.0,
            "index_angle": _num(r, "index_angle", p, default=0.0),
        })
    return m


# ---------------------------------------------------------------------------
# MJCF


def _body_frame(m, world_pt):
    """A world point at t = 0 in the platform frame (relative to C, unrotated)."""
    dx = world_pt[0] - m["position"][0]
    dy = world_pt[1] - m["position"][1]
    c, s = math.cos(m["angle"]), math.sin(m["angle"])
    return c * dx + s * dy, -s * dx + c * dy


FOOT_RADIUS = 1.0e-3  # m: the feet are small spheres whose lowest point is the contact point


def mjcf(m, step, timeconst, dampratios, kp, kv, solimp=(0.99, 0.99, 0.001, 0.5, 2.0)):
    """The MJCF text. dampratios: one per contact (from the calibration)."""
    g = m["gravity"]
    fy = m["floor_y"]
    px, py = m["position"]
    si = " ".join(f"{v:g}" for v in solimp)
    feet = []
    for c, zeta in zip(m["contacts"], dampratios):
        bx, by = _body_frame(m, c["point"])
        feet.append(
            f'      <geom name="{c["name"]}" type="sphere" size="{FOOT_RADIUS!r}" '
            f'pos="{bx!r} 0 {by + FOOT_RADIUS!r}" condim="3" priority="1" '
            f'friction="{c["friction"]!r} 0 0" solref="{timeconst!r} {zeta!r}" '
            f'solimp="{si}" contype="1" conaffinity="1"/>')
    rotors, acts = [], []
    for k, r in enumerate(m["rotors"]):
        bx, by = _body_frame(m, r["axis"])
        j = r["inertia"]
        rotors.append(
            f'      <body name="rotor{k + 1}" pos="{bx!r} 0 {by!r}">\n'
            f'        <joint name="phi{k + 1}" type="hinge" axis="0 -1 0"/>\n'
            # the eccentric mass at e along the rotor's x (phi = joint angle), the rotor's
            # own inertia about the axis carried by the same body (parallel axes: I + m e^2)
            f'        <inertial pos="{r["ecc"]!r} 0 0" mass="{max(r["mass"], 1e-9)!r}" '
            f'diaginertia="{j!r} {j!r} {j!r}"/>\n'
            f'      </body>')
        # PD on the trajectory: kp (act - phi) with act' = ctrl (the reference angle),
        # plus kv (ctrl' - phi') from a velocity actuator whose ctrl is the reference speed
        acts.append(
            f'    <general name="pos{k + 1}" joint="phi{k + 1}" dyntype="integrator" '
            f'gaintype="fixed" gainprm="{kp!r}" biastype="affine" biasprm="0 {-kp!r} 0" '
            f'ctrllimited="false" forcelimited="false" actlimited="false"/>')
        acts.append(
            f'    <velocity name="vel{k + 1}" joint="phi{k + 1}" kv="{kv!r}" '
            f'ctrllimited="false" forcelimited="false"/>')
    ip = m["inertia"]
    return f"""<mujoco model="vibro-driver">
  <!-- generated by benchmarks/mujoco/reference_machine.py from the machine file -->
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{step!r}" gravity="{g[0]!r} 0 {g[1]!r}" integrator="implicitfast"
          cone="elliptic"/>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" pos="0 0 {fy!r}" condim="3"
          friction="0 0 0" priority="0" contype="1" conaffinity="1"/>
    <body name="platform" pos="{px!r} 0 {py!r}">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 0 1"/>
      <joint name="theta" type="hinge" axis="0 -1 0"/>
      <inertial pos="0 0 0" mass="{m["mass"]!r}" diaginertia="{ip!r} {ip!r} {ip!r}"/>
      <geom name="block" type="box" size="0.1 0.0105 0.03" contype="0" conaffinity="0"
            mass="0" rgba="0.6 0.6 0.7 0.4"/>
{chr(10).join(feet)}
{chr(10).join(rotors)}
    </body>
  </worldbody>
  <actuator>
{chr(10).join(acts)}
  </actuator>
</mujoco>
"""


# ---------------------------------------------------------------------------
# Restitution calibration: the drop test of one foot


def drop_test_xml(step, timeconst, zeta, friction, solimp=(0.99, 0.99, 0.001, 0.5, 2.0),
                  mass=1.0):
    si = " ".join(f"{v:g}" for v in solimp)
    return f"""<mujoco>
  <option timestep="{step!r}" gravity="0 0 -9.81" integrator="implicitfast" cone="elliptic"/>
  <worldbody>
    <geom type="plane" size="0 0 1" condim="3" friction="0 0 0" priority="0"/>
    <body name="foot" pos="0 0 0">
      <joint name="z" type="slide" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="{mass!r}" diaginertia="1e-3 1e-3 1e-3"/>
      <geom type="sphere" size="{FOOT_RADIUS!r}" pos="0 0 {FOOT_RADIUS!r}" condim="3"
            priority="1" friction="{max(friction, 1e-5)!r} 0 0" solref="{timeconst!r} {zeta!r}"
            solimp="{si}"/>
    </body>
  </worldbody>
</mujoco>
"""


def drop_restitution(step, timeconst, zeta, friction, v0):
    """One foot arriving at the floor at v0 (m/s) from just above it: -v_after / v_before,
    the velocities at the last step before the contact closes and the first after it
    opens (what a rebound-height measurement, e = sqrt(h_rebound / h_drop), gives)."""
    model = mujoco.MjModel.from_xml_string(drop_test_xml(step, timeconst, zeta, friction))
    data = mujoco.MjData(model)
    h0 = 1e-6
    data.qpos[0] = h0
    data.qvel[0] = -math.sqrt(v0 * v0 + 2 * 9.81 * h0)
    t_touch = v_before = None
    for _ in range(int(1.0 / step)):
        v = data.qvel[0]
        mujoco.mj_step(model, data)
        if data.ncon > 0 and t_touch is None:
            t_touch, v_before = data.time - step, v
        elif data.ncon == 0 and t_touch is not None:
            return -data.qvel[0] / v_before
    return 0.0  # no rebound within 1 s: fully plastic


def calibrate_dampratio(e_target, step, timeconst, friction, v0):
    """Bisection on solref's dampratio for the rebound ratio e_target at impact speed v0."""
    if e_target >= 1.0:
        return 0.0
    lo, hi = 0.0, 5.0  # e falls as the damping ratio grows
    if drop_restitution(step, timeconst, hi, friction, v0) > e_target:
        raise InputError(f"restitution {e_target}: below what dampratio {hi} gives")
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if drop_restitution(step, timeconst, mid, friction, v0) > e_target:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-5:
            break
    return 0.5 * (lo + hi)


# ---------------------------------------------------------------------------
# The run


class Runner:
    def __init__(self, m, step, timeconst, dampratios, kp, kv):
        self.m = m
        self.xml = mjcf(m, step, timeconst, dampratios, kp, kv)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.step = step

    def run(self, speed_rpm, offset_deg, t_end, ramp=0.5, tick=1e-3, per_step=False):
        """Holds the rotors at speed_rpm and offset_deg; returns the summary (dict)."""
        m, model = self.m, self.model
        data = mujoco.MjData(model)
        px = m["position"][0]
        # initial state: the file's platform state; rotors at the reference's phases
        data.qvel[0], data.qvel[1] = m["velocity"]
        data.qpos[2] = m["angle"]  # the feet and axes are given in the unrotated platform frame
        data.qvel[2] = m["angular_velocity"]
        off = math.radians(offset_deg)
        half = (0.5 * off, -0.5 * off)
        phi0 = []
        for k, r in enumerate(m["rotors"]):
            # theta_k = half_k at t = 0; phi_k = index + s theta_k; the servo's reference
            # angle (the activation) grows at s_k omega
            p = r["index_angle"] + r["sense"] * half[k]
            phi0.append(p)
            data.qpos[3 + k] = p
            data.act[k] = p
        omega = speed_rpm * 2 * math.pi / 60
        senses = [r["sense"] for r in m["rotors"]]
        n_tick = max(1, round(tick / self.step))
        n_ticks = round(t_end / (n_tick * self.step))
        half_tick = n_ticks // 2
        x_half = None
        theta_err = []
        nstep_ok = True
        for i in range(n_ticks):
            t = i * n_tick * self.step
            w = omega * min(1.0, (t + 0.5 * n_tick * self.step) / ramp) if ramp > 0 else omega
            for k in range(2):
                data.ctrl[2 * k] = senses[k] * w       # reference angle rate
                data.ctrl[2 * k + 1] = senses[k] * w   # reference speed
            if i == half_tick:
                x_half = data.qpos[0]
            if per_step:
                for _ in range(n_tick):
                    mujoco.mj_step(model, data)
            else:
                mujoco.mj_step(model, data, n_tick)
            if i >= half_tick:
                th = [senses[k] * (data.qpos[3 + k] - m["rotors"][k]["index_angle"])
                      for k in range(2)]
                theta_err.append(th[0] - th[1] - off)
            if not np.all(np.isfinite(data.qpos)):
                nstep_ok = False
                break
        t_sim = n_ticks * n_tick * self.step
        err = np.array(theta_err)
        err = (err + math.pi) % (2 * math.pi) - math.pi
        return {
            "t_end": t_sim,
            "step": self.step,
            "mean_velocity": (data.qpos[0] - x_half) / (t_sim / 2) if nstep_ok else float("nan"),
            "distance": float(data.qpos[0]),
            "phase_error_deg_rms": math.degrees(math.sqrt(float(np.mean(err ** 2)))),
            "final": {"position": [px + float(data.qpos[0]), m["position"][1] + float(data.qpos[1])],
                      "angle": float(data.qpos[2])},
            "finite": nstep_ok,
        }


# ---------------------------------------------------------------------------
# CLI


def _positive_float(name):
    def parse(s):
        try:
            v = float(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}: expected a number, got {s!r}")
        if not math.isfinite(v) or v <= 0:
            raise argparse.ArgumentTypeError(f"{name}: must be a positive number, got {s!r}")
        return v
    return parse


def _float_list(name, positive=False):
    def parse(s):
        out = []
        for part in s.split(","):
            try:
                v = float(part)
            except ValueError:
                raise argparse.ArgumentTypeError(f"{name}: expected numbers separated by commas, got {s!r}")
            if not math.isfinite(v) or (positive and v <= 0):
                raise argparse.ArgumentTypeError(f"{name}: {part!r} is not a positive number")
            out.append(v)
        return out
    return parse


def build_parser():
    p = argparse.ArgumentParser(
        prog="reference_machine.py",
        description="MuJoCo model of a host-sim machine file (see the docstring).")
    sub = p.add_subparsers(dest="cmd", required=True)

    def common(sp, step=True):
        sp.add_argument("machine", help="machine file (TOML)")
        sp.add_argument("--timeconst", type=_positive_float("--timeconst"), default=5e-4,
                        help="contact solref time constant, s (default 5e-4)")
        sp.add_argument("--calib-step", type=_positive_float("--calib-step"), default=1e-5,
                        help="time step of the drop test, s (default 1e-5)")
        sp.add_argument("--calib-speed", type=_positive_float("--calib-speed"), default=0.08,
                        help="impact speed of the drop test, m/s (default 0.08: host-sim's "
                             "landing speed at 3000 rpm, 90 deg)")
        sp.add_argument("--kp", type=_positive_float("--kp"), default=100.0,
                        help="rotor servo stiffness, N m/rad (default 100)")
        sp.add_argument("--kv", type=_positive_float("--kv"), default=None,
                        help="rotor servo damping, N m s/rad (default: critical for kp)")
        if step:
            sp.add_argument("--step", type=_positive_float("--step"), default=1e-4,
                            help="MuJoCo time step, s (default 1e-4: benchmarks/plant.md, \"MuJoCo side by side\")")

    sp = sub.add_parser("xml", help="print or write the MJCF")
    common(sp)
    sp.add_argument("--out", help="write the MJCF here instead of stdout")
    sp = sub.add_parser("calibrate", help="drop test: dampratio for each restitution")
    common(sp, step=False)
    sp.add_argument("--speeds", type=_float_list("--speeds", True), default=[0.02, 0.08, 0.3],
                    help="impact speeds to report the calibrated model's restitution at")
    sp.add_argument("--steps", type=_float_list("--steps", True), default=[1e-4, 5e-5, 2e-5, 1e-5],
                    help="time steps to report it at")
    sp = sub.add_parser("run", help="one run, summary like host-sim run --format json")
    common(sp)
    sp.add_argument("--speed", type=_positive_float("--speed"), default=None, help="rpm")
    sp.add_argument("--offset", type=float, required=True, help="phase offset, degrees")
    sp.add_argument("--t-end", type=_positive_float("--t-end"), default=10.0)
    sp.add_argument("--format", choices=("table", "json"), default="table")
    sp = sub.add_parser("converge", help="mean velocity against the time step")
    common(sp, step=False)
    sp.add_argument("--speed", type=_positive_float("--speed"), default=None, help="rpm")
    sp.add_argument("--offsets", type=_float_list("--offsets"), default=[90.0, 120.0])
    sp.add_argument("--steps", type=_float_list("--steps", True), default=[1e-4, 5e-5, 2e-5, 1e-5])
    sp.add_argument("--t-end", type=_positive_float("--t-end"), default=10.0)
    sp.add_argument("--format", choices=("table", "json"), default="table")
    sp = sub.add_parser("bench", help="time host-sim and MuJoCo alternately on one core")
    common(sp)
    sp.add_argument("--host-sim", required=True, help="path of the host-sim binary")
    sp.add_argument("--host-sim-set", action="append", default=[], metavar="KEY=VALUE",
                    help="passed to host-sim as --set KEY=VALUE (repeatable), e.g. "
                         "simulation.rtol=1e-3")
    sp.add_argument("--speed", type=_positive_float("--speed"), default=None, help="rpm")
    sp.add_argument("--offset", type=float, default=90.0, help="phase offset, degrees")
    sp.add_argument("--t-end", type=_positive_float("--t-end"), default=10.0)
    sp.add_argument("--repeats", type=int, default=5)
    sp.add_argument("--cpu", type=int, default=None,
                    help="the core to pin both to (default: the last one allowed)")
    sp.add_argument("--format", choices=("table", "json"), default="table")
    return p


def calibration(args, m):
    """dampratio per contact (one bisection per distinct restitution and friction)."""
    cache = {}
    out = []
    for c in m["contacts"]:
        key = (c["restitution"], c["friction"])
        if key not in cache:
            cache[key] = calibrate_dampratio(c["restitution"], args.calib_step, args.timeconst,
                                             c["friction"], args.calib_speed)
        out.append(cache[key])
    return out


def make_runner(args, m, step):
    if 2 * step > args.timeconst * (1 + 1e-12):
        raise InputError(f"--step {step:g}: MuJoCo needs timeconst >= 2 x step "
                         f"(timeconst {args.timeconst:g}); lower the step or raise --timeconst")
    kv = args.kv
    if kv is None:
        j = max(r["inertia"] + r["mass"] * r["ecc"] ** 2 for r in m["rotors"])
        kv = 2 * math.sqrt(args.kp * j)
    return Runner(m, step, args.timeconst, args.zetas, args.kp, kv)


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        m = load_machine(args.machine)
        if getattr(args, "speed", "absent") is None:
            with open(args.machine, "rb") as f:
                args.speed = float(tomllib.load(f).get("controller", {}).get("speed_rpm", 3000))
        if args.cmd == "bench" and args.repeats < 1:
            raise InputError(f"--repeats: must be >= 1, got {args.repeats}")
        if args.cmd == "bench" and not os.access(args.host_sim, os.X_OK):
            raise InputError(f"--host-sim {args.host_sim}: not an executable file")
        if 2 * args.calib_step > args.timeconst:
            raise InputError(f"--calib-step {args.calib_step:g}: MuJoCo needs timeconst >= 2 x step")
        for name in ("steps",):
            for s in getattr(args, name, []) or []:
                if args.cmd == "converge" and 2 * s > args.timeconst * (1 + 1e-12):
                    raise InputError(f"--steps {s:g}: MuJoCo needs timeconst >= 2 x step "
                                     f"(timeconst {args.timeconst:g})")
        args.zetas = calibration(args, m)
        return COMMANDS[args.cmd](args, m)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


def cmd_xml(args, m):
    text = make_runner(args, m, args.step).xml
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)
    return 0


def cmd_calibrate(args, m):
    print(f"drop test of one foot, solref timeconst {args.timeconst:g} s, solimp 0.99 0.99 0.001;"
          f" calibrated at step {args.calib_step:g} s, impact speed {args.calib_speed:g} m/s")
    seen = set()
    for c, z in zip(m["contacts"], args.zetas):
        if (c["restitution"], c["friction"]) in seen:
            continue
        seen.add((c["restitution"], c["friction"]))
        print(f"\ncontact {c['name']}: restitution {c['restitution']:g} -> dampratio {z:.5f}")
        print("step \\ impact speed | " + " | ".join(f"{v:g} m/s" for v in args.speeds))
        for s in args.steps:
            row = [drop_restitution(s, args.timeconst, z, c["friction"], v) for v in args.speeds]
            print(f"{s:g} s | " + " | ".join(f"{e:.4f}" for e in row))
    return 0


def cmd_run(args, m):
    r = make_runner(args, m, args.step)
    t0 = time.perf_counter()
    res = r.run(args.speed, args.offset, args.t_end)
    res["wall_s"] = time.perf_counter() - t0
    if args.format == "json":
        print(json.dumps(res))
    else:
        for k, v in res.items():
            print(f"{k}: {v}")
    return 0


def cmd_converge(args, m):
    rows = []
    for s in args.steps:
        r = make_runner(args, m, s)
        row = {"step": s}
        for o in args.offsets:
            t0 = time.perf_counter()
            res = r.run(args.speed, o, args.t_end)
            row[o] = res["mean_velocity"]
            row[f"err{o}"] = res["phase_error_deg_rms"]
            row[f"wall{o}"] = time.perf_counter() - t0
        rows.append(row)
        print(f"# step {s:g} done", file=sys.stderr, flush=True)
    finest = min(rows, key=lambda r: r["step"])
    if args.format == "json":
        print(json.dumps(rows))
        return 0
    print("| step (s) | " + " | ".join(f"{o:g} deg: mm/s (vs finest) | phase err RMS" for o in args.offsets)
          + " | wall per run (s) |")
    print("|---|" + "---|---|" * len(args.offsets) + "---|")
    for r in rows:
        cells = []
        for o in args.offsets:
            rel = (r[o] - finest[o]) / abs(finest[o]) * 100 if finest[o] else float("nan")
            cells.append(f"{r[o] * 1e3:.3f} ({rel:+.1f} %) | {r[f'err{o}']:.3f} deg")
        walls = sum(r[f"wall{o}"] for o in args.offsets) / len(args.offsets)
        print(f"| {r['step']:g} | " + " | ".join(cells) + f" | {walls:.1f} |")
    return 0


def cmd_bench(args, m):
    allowed = sorted(os.sched_getaffinity(0))
    cpu = allowed[-1] if args.cpu is None else args.cpu
    if cpu not in allowed:
        raise InputError(f"--cpu {cpu}: not one of the allowed cores {allowed}")
    os.sched_setaffinity(0, {cpu})  # host-sim inherits it
    r = make_runner(args, m, args.step)
    cmd = [args.host_sim, "run", args.machine, "--command", "right", "--speed", f"{args.speed:g}",
           "--offset", f"{args.offset:g}", "--t-end", f"{args.t_end:g}", "--format", "json"]
    for kv in args.host_sim_set:
        cmd += ["--set", kv]
    hs, mj, mjp = [], [], []
    hs_v = mj_v = mjp_v = None
    for i in range(args.repeats):
        t0 = time.perf_counter()
        out = subprocess.run(cmd, capture_output=True, text=True)
        t1 = time.perf_counter()
        if out.returncode != 0:
            raise InputError(f"host-sim failed ({out.returncode}): {out.stderr.strip()}")
        hs.append(t1 - t0)
        hs_v = json.loads(out.stdout)
        t0 = time.perf_counter()
        res = r.run(args.speed, args.offset, args.t_end)
        mj.append(time.perf_counter() - t0)
        mj_v = res
        t0 = time.perf_counter()
        res = r.run(args.speed, args.offset, args.t_end, per_step=True)
        mjp.append(time.perf_counter() - t0)
        mjp_v = res
        print(f"# repeat {i + 1}: host-sim {hs[-1]:.3f} s, MuJoCo {mj[-1]:.3f} s "
              f"(per-step loop {mjp[-1]:.3f} s)", file=sys.stderr, flush=True)
    summary = {
        "cpu": cpu, "t_end": args.t_end, "speed_rpm": args.speed, "offset_deg": args.offset,
        "mujoco_step": args.step, "repeats": args.repeats, "host_sim_set": args.host_sim_set,
        "host_sim": {"wall_s": hs, "median_s": float(np.median(hs)),
                     "rtf": args.t_end / float(np.median(hs)),
                     "mean_velocity": hs_v["mean_velocity"],
                     "phase_error_deg_rms": hs_v.get("phase_error_deg_rms"),
                     "impacts": hs_v.get("impacts")},
        "mujoco": {"wall_s": mj, "median_s": float(np.median(mj)),
                   "rtf": args.t_end / float(np.median(mj)),
                   "mean_velocity": mj_v["mean_velocity"],
                   "phase_error_deg_rms": mj_v["phase_error_deg_rms"]},
        "mujoco_per_step_loop": {"wall_s": mjp, "median_s": float(np.median(mjp)),
                                 "rtf": args.t_end / float(np.median(mjp)),
                                 "mean_velocity": mjp_v["mean_velocity"]},
    }
    if args.format == "json":
        print(json.dumps(summary))
        return 0
    print(f"one core ({cpu}), {args.t_end:g} s simulated, {args.speed:g} rpm, offset "
          f"{args.offset:g} deg, {args.repeats} alternating repeats, median wall time")
    print("| engine | wall (s), median | real-time factor | mean velocity (mm/s) |")
    print("|---|---|---|---|")
    host_sim = " ".join(["host-sim run --command right"] + [f"--set {kv}" for kv in args.host_sim_set])
    for name, key in ((host_sim, "host_sim"),
                      (f"MuJoCo, step {args.step:g} s, mj_step(nstep) per 1 ms tick", "mujoco"),
                      (f"MuJoCo, step {args.step:g} s, Python loop of mj_step", "mujoco_per_step_loop")):
        s = summary[key]
        print(f"| {name} | {s['median_s']:.3f} | {s['rtf']:.1f} | {s['mean_velocity'] * 1e3:.3f} |")
    return 0


COMMANDS = {"xml": cmd_xml, "calibrate": cmd_calibrate, "run": cmd_run,
            "converge": cmd_converge, "bench": cmd_bench}

if __name__ == "__main__":
    sys.exit(main())
