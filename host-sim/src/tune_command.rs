//! `host-sim tune MACHINE [--speeds A:B:STEP] [--offsets A:B:STEP] [--t-end T]
//! [--write FILE] [--plot FILE.svg] [--format table|json] [--set KEY=VALUE]...`
//!
//! Sweeps rotor speed and phase offset in closed loop and finds, at every speed,
//! the offset that travels right fastest and the one that travels left fastest
//! (spec `machine.md`, `host-sim tune`; docs/tuning.md).
//!
//! Stages of [`run`]:
//! 1. read and check the machine file with the `--set` overrides, and the options
//!    into a [`Grid`]: every problem at once, exit 2, before any run;
//! 2. sweep: one closed-loop run per grid point ([`run_point`]: the `shared`
//!    controller holding the point's offset, `Command::HoldOffset` from `t = 0`),
//!    in parallel on all cores; results are collected by grid index, so the output
//!    is the same whatever the number of threads;
//! 3. best offsets per speed and direction ([`best_offsets`]): the grid's extreme,
//!    refined by a parabola through it and its two neighbours in offset, the
//!    refined offset checked by one more run (also in parallel);
//! 4. warnings: runs whose offset was not held, speeds with no travel one way;
//! 5. outputs: `--write` and `--plot` files, each whole or not at all, then the
//!    result on stdout as a table or JSON; one summary line on stderr.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use serde_json::{Map, Value};
use shared::controller::{Command, Outputs, State};

use crate::cli::{Format, Output, TuneArgs, EXIT_FAILURE, EXIT_OK, EXIT_USAGE};
use crate::closed_loop::{self, ControllerDriver};
use crate::input;
use crate::machine::Machine;
use crate::run_output::write_whole;
use crate::simulation::{simulate, RunOptions};
use crate::summary::{wrap_deg_180, wrap_deg_360};
use crate::text::{self, Align, Table};
use crate::tune_plot;
use crate::tuning_file;

/// Default `--t-end`, s: every offset held over the whole second half, over
/// which `mean_velocity` is measured. On the reference machine the phase loop
/// closes about 0.2 s after the start with its reference at the measured offset
/// (near 0: both eccentrics start along +x), which then ramps at 180 deg/s, via
/// 180 deg for offsets in (180, 360) (a change of side): up to 360 deg, so the
/// reference reaches the held offset by 2.2 s at the latest; the controller is
/// `running` (speed reached) from 0.55 s at 2500 rpm to 1.05 s at 4000 rpm.
/// `T = 5 s` puts `T/2` 0.3 s after the latest, and averages the second half
/// over 125 revolutions at 3000 rpm. (4 s would leave the offsets above about
/// 325 deg still ramping at `T/2`.)
pub const DEFAULT_T_END: f64 = 5.0;

/// Default `--offsets`: every 15 degrees around the turn (24 runs a speed; 360
/// is 0 and runs once). Fine enough for the parabola through the best three.
pub const DEFAULT_OFFSETS: &str = "0:360:15";

/// Default `--speeds`: `[controller].speed_rpm` and this many rpm either side...
pub const DEFAULT_SPEED_SPAN_RPM: f64 = 500.0;

/// ...in steps of this many rpm (5 speeds: 2500 to 3500 rpm for the reference
/// machine, all above its lift-off at 2125 rpm), dropping those outside the
/// controller's speed range.
pub const DEFAULT_SPEED_STEP_RPM: f64 = 250.0;

/// Most points one range, or the whole grid, may have (10 000 runs of 5 s are
/// about 20 minutes of two cores: a run costs 0.22 s of one).
pub const MAX_POINTS: usize = 10_000;

/// A run whose phase error over the second half exceeds this RMS, degrees, did
/// not hold its offset (a held offset stays within a degree).
pub const HELD_ERROR_DEG_RMS: f64 = 5.0;

/// Rounding of a refined offset, degrees: the tuning file's resolution
/// ([`tuning_file::write`] writes one decimal), so that the offset checked, the
/// one reported and the one written are the same number.
const OFFSET_RESOLUTION_DEG: f64 = 0.1;

/// What the sweep covers.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Rotor speeds, rpm, ascending.
    pub speeds_rpm: Vec<f64>,
    /// Phase offsets, degrees in [0, 360), ascending, each once.
    pub offsets_deg: Vec<f64>,
    /// End time of each run, s.
    pub t_end: f64,
}

impl Grid {
    /// The grid points in their order: speed by speed, offsets ascending within.
    pub fn points(&self) -> Vec<(f64, f64)> {
        self.speeds_rpm
            .iter()
            .flat_map(|&s| self.offsets_deg.iter().map(move |&o| (s, o)))
            .collect()
    }

    /// Whether the offsets go round the whole turn: the gap from the last one
    /// back to the first (through 360) is no wider than the widest gap between
    /// neighbours. Then the neighbours of the first offset include the last.
    pub fn circular(&self) -> bool {
        let o = &self.offsets_deg;
        let (Some(first), Some(last)) = (o.first(), o.last()) else {
            return false;
        };
        let widest = o.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
        o.len() >= 3 && first + 360.0 - last <= widest * (1.0 + 1e-9)
    }
}

/// What one closed-loop run gave.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOutcome {
    /// Rotor speed, rpm.
    pub speed_rpm: f64,
    /// Phase offset held, degrees in [0, 360).
    pub offset_deg: f64,
    /// `(x_C(T) - x_C(T/2)) / (T/2)`, m/s (the run's summary).
    pub mean_velocity: f64,
    /// Why the offset was not held over the second half, if it was not: the
    /// controller faulted or never reached `running` in time, or the phase error
    /// was large.
    pub not_held: Option<String>,
    /// Warnings of the plant (e.g. a Painleve configuration).
    pub plant_warnings: Vec<String>,
}

/// How a best offset was found.
#[derive(Clone, Debug, PartialEq)]
pub enum Refinement {
    /// The parabola's vertex, checked by a run that travelled at least as fast.
    Parabola,
    /// The grid point, because the parabola is degenerate (the reason).
    Degenerate(String),
    /// The grid point, because the run at the vertex (offset, mean velocity)
    /// travelled slower or did not hold its offset.
    Slower(f64, f64),
}

/// The best offset for one direction at one speed.
#[derive(Clone, Debug, PartialEq)]
pub struct Best {
    /// Rotor speed, rpm.
    pub speed_rpm: f64,
    /// The best offset, degrees in [0, 360).
    pub offset_deg: f64,
    /// The mean velocity measured at that offset, m/s.
    pub mean_velocity: f64,
    /// The best grid offset, degrees.
    pub grid_offset_deg: f64,
    /// The mean velocity at the best grid offset, m/s.
    pub grid_mean_velocity: f64,
    /// How `offset_deg` was found.
    pub refinement: Refinement,
}

/// Travel direction, for the search of the extreme.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Way {
    /// Rightward: the largest mean velocity.
    Right,
    /// Leftward: the most negative mean velocity.
    Left,
}

impl Way {
    /// `right` or `left`.
    pub fn name(self) -> &'static str {
        match self {
            Way::Right => "right",
            Way::Left => "left",
        }
    }

    /// The velocity turned so that larger is better.
    fn score(self, v: f64) -> f64 {
        match self {
            Way::Right => v,
            Way::Left => -v,
        }
    }
}

/// The result of a sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct Tuning {
    /// What was swept.
    pub grid: Grid,
    /// One outcome per grid point, in [`Grid::points`] order.
    pub runs: Vec<RunOutcome>,
    /// Best rightward offset per speed (speeds with a finite velocity).
    pub right: Vec<Best>,
    /// Best leftward offset per speed.
    pub left: Vec<Best>,
    /// Warnings: runs that did not hold their offset, speeds without travel one
    /// way, plant warnings.
    pub warnings: Vec<String>,
    /// Runs made: the grid's and the checks of refined offsets.
    pub run_count: usize,
}

/// Parses a range `A:B:STEP` (or a single value `A`) of option `option` into its
/// points: `A, A + STEP, ...` up to `B`, both ends included (`B` is appended when
/// the steps do not land on it). Refused: a malformed text, a value that is not
/// finite, `STEP <= 0`, `B < A`, more than [`MAX_POINTS`] points.
pub fn parse_range(option: &str, text: &str) -> Result<Vec<f64>, String> {
    let bad = |why: String| format!("error: {option} {text}: {why}");
    let parts: Vec<Option<f64>> = text
        .split(':')
        .map(|p| p.trim().parse::<f64>().ok())
        .collect();
    let (a, b, step) = match parts.as_slice() {
        [Some(a)] => (*a, *a, 1.0),
        [Some(a), Some(b), Some(step)] => (*a, *b, *step),
        _ => {
            return Err(bad(
                "expected A:B:STEP, from A to B (both included) in steps of STEP, e.g. 0:360:15, or a single value"
                    .into(),
            ))
        }
    };
    if !(a.is_finite() && b.is_finite() && step.is_finite()) {
        return Err(bad("A, B and STEP must be finite numbers".into()));
    }
    if step <= 0.0 {
        return Err(bad(format!("STEP must be > 0 (got {})", text::sig(step))));
    }
    if b < a {
        return Err(bad(format!(
            "B must be >= A: the range runs up from A = {} to B = {}",
            text::sig(a),
            text::sig(b)
        )));
    }
    // Whole steps from A towards B; rounding within 1e-9 of a step lands on B.
    let steps = (b - a) / step;
    if steps + 1.0 > MAX_POINTS as f64 {
        let count = (steps + 1.0).floor();
        let count = if count < 1e12 {
            format!("{count:.0}")
        } else {
            text::sig(count)
        };
        return Err(bad(format!(
            "{count} points, at most {MAX_POINTS} (use a larger STEP)"
        )));
    }
    let whole = (steps + 1e-9).floor();
    let mut points: Vec<f64> = (0..=whole as usize).map(|i| a + i as f64 * step).collect();
    if steps - whole <= 1e-9 {
        if let Some(last) = points.last_mut() {
            *last = b;
        }
    } else {
        points.push(b);
    }
    if points.len() > MAX_POINTS {
        return Err(bad(format!(
            "{} points, at most {MAX_POINTS} (use a larger STEP)",
            points.len()
        )));
    }
    Ok(points)
}

/// Offsets wrapped to [0, 360), ascending, each once (360 is 0; offsets within
/// 1e-9 degrees are the same).
pub fn wrap_offsets(offsets: &[f64]) -> Vec<f64> {
    let mut out: Vec<f64> = offsets.iter().map(|&o| wrap_deg_360(o) + 0.0).collect();
    out.sort_by(f64::total_cmp);
    out.dedup_by(|b, a| (*b - *a).abs() <= 1e-9);
    if out.len() > 1 && out[out.len() - 1] >= 360.0 - 1e-9 && out[0] <= 1e-9 {
        out.pop();
    }
    out
}

/// The default speeds for a machine: `[controller].speed_rpm` +- 0, 250 and 500
/// rpm within `[lo, hi]` rpm, as a range text for messages (`2500:3500:250`).
fn default_speeds(nominal: f64, lo: f64, hi: f64) -> (Vec<f64>, String) {
    let k = (DEFAULT_SPEED_SPAN_RPM / DEFAULT_SPEED_STEP_RPM).round() as i32;
    let speeds: Vec<f64> = (-k..=k)
        .map(|i| nominal + f64::from(i) * DEFAULT_SPEED_STEP_RPM)
        .filter(|s| *s >= lo && *s <= hi)
        .collect();
    let text = match (speeds.first(), speeds.last()) {
        (Some(a), Some(b)) => format!(
            "{}:{}:{}",
            text::sig(*a),
            text::sig(*b),
            text::sig(DEFAULT_SPEED_STEP_RPM)
        ),
        _ => String::new(),
    };
    (speeds, text)
}

/// Stage 1: the machine (its tuning table dropped: the sweep holds explicit
/// offsets, so a missing or stale table must not stop its own regeneration) and
/// the grid, with the range texts used (for the table file's header).
fn read_options(args: &TuneArgs) -> Result<(Machine, Grid, String, String), String> {
    let mut machine = match Machine::load(&args.machine, &args.set) {
        Ok(m) => m,
        Err(problems) => return Err(input::render(&problems)),
    };
    machine.controller.tuning_table = None;
    let params = match closed_loop::params(&machine) {
        Ok(p) => p,
        Err(problems) => return Err(input::render(&problems)),
    };
    let (lo, hi) = (
        f64::from(params.min_speed_rpm),
        f64::from(params.max_speed_rpm),
    );
    let mut problems = Vec::new();

    // Speeds: given, or around the nominal speed; all within the controller's range.
    let (speeds, speeds_text) = match &args.speeds {
        Some(t) => (parse_range("--speeds", t), t.clone()),
        None => {
            let (s, t) = default_speeds(machine.controller.speed_rpm, lo, hi);
            if s.is_empty() {
                (
                    Err(format!(
                        "error: tune: [controller].speed_rpm = {} is outside the controller's speed range [{}, {}] rpm; give --speeds",
                        text::sig(machine.controller.speed_rpm),
                        text::sig(lo),
                        text::sig(hi)
                    )),
                    t,
                )
            } else {
                (Ok(s), t)
            }
        }
    };
    let speeds = match speeds {
        Ok(s) => {
            let outside: Vec<String> = s
                .iter()
                .filter(|v| !(**v >= lo && **v <= hi))
                .map(|v| text::sig(*v))
                .collect();
            if outside.is_empty() {
                Some(s)
            } else {
                problems.push(format!(
                    "error: --speeds {speeds_text}: {} rpm outside the controller's speed range [{}, {}] rpm (min_speed_rpm to max_speed_rpm, 80 % of the no-load speed): the controller would refuse the command",
                    outside.join(", "),
                    text::sig(lo),
                    text::sig(hi)
                ));
                None
            }
        }
        Err(e) => {
            problems.push(e);
            None
        }
    };

    // Offsets: at most one turn, wrapped to [0, 360).
    let offsets_text = args
        .offsets
        .clone()
        .unwrap_or_else(|| DEFAULT_OFFSETS.to_string());
    let offsets = match parse_range("--offsets", &offsets_text) {
        Ok(o) if o.last().zip(o.first()).is_some_and(|(b, a)| b - a > 360.0) => {
            problems.push(format!(
                "error: --offsets {offsets_text}: spans more than one turn (B - A must be <= 360 degrees)"
            ));
            None
        }
        Ok(o) => Some(wrap_offsets(&o)),
        Err(e) => {
            problems.push(e);
            None
        }
    };

    // The end time.
    let t_end = args.t_end.unwrap_or(DEFAULT_T_END);
    if !(t_end.is_finite() && t_end > 0.0) {
        problems.push(format!(
            "error: --t-end {t_end}: must be a positive number of seconds"
        ));
    }

    // The whole grid, and what the table file can hold.
    if let (Some(s), Some(o)) = (&speeds, &offsets) {
        let n = s.len() * o.len();
        if n > MAX_POINTS {
            problems.push(format!(
                "error: --speeds {speeds_text} --offsets {offsets_text}: {} speeds x {} offsets = {n} runs, at most {MAX_POINTS}",
                s.len(),
                o.len()
            ));
        }
        if args.write.is_some() {
            if s.len() > shared::controller::MAX_TUNING_ROWS {
                problems.push(format!(
                    "error: --write: the controller's table holds at most {} rows (speeds), --speeds {speeds_text} gives {}",
                    shared::controller::MAX_TUNING_ROWS,
                    s.len()
                ));
            }
            let written: Vec<String> = s.iter().map(|v| format!("{v:.1}")).collect();
            if written.windows(2).any(|w| w[0] == w[1]) {
                problems.push(format!(
                    "error: --write: --speeds {speeds_text} has speeds closer than the table's 0.1 rpm"
                ));
            }
        }
    }
    match (speeds, offsets) {
        (Some(speeds_rpm), Some(offsets_deg)) if problems.is_empty() => Ok((
            machine,
            Grid {
                speeds_rpm,
                offsets_deg,
                t_end,
            },
            speeds_text,
            offsets_text,
        )),
        _ => Err(problems.join("\n") + "\n"),
    }
}

/// One closed-loop run of `machine` to `t_end` with the controller holding
/// `offset_deg` at `speed_rpm` from `t = 0`. The offset counts as held when the
/// controller ends `running`, got there by `T/2`, and its phase error over the
/// second half is within [`HELD_ERROR_DEG_RMS`].
pub fn run_point(machine: &Machine, speed_rpm: f64, offset_deg: f64, t_end: f64) -> RunOutcome {
    let command = Command::HoldOffset {
        speed_rpm: speed_rpm as f32,
        offset_deg: offset_deg as f32,
    };
    let mut outcome = RunOutcome {
        speed_rpm,
        offset_deg,
        mean_velocity: f64::NAN,
        not_held: None,
        plant_warnings: Vec::new(),
    };
    let mut driver = match ControllerDriver::new(machine, vec![(0.0, command)]) {
        Ok(d) => d,
        Err(problems) => {
            outcome.not_held = Some(input::render(&problems).trim_end().to_string());
            return outcome;
        }
    };
    driver.record_history(true);
    let options = RunOptions::new(t_end);
    let result = simulate(machine, &mut driver, &options);
    let s = &result.summary;
    outcome.mean_velocity = s.mean_velocity;
    outcome.plant_warnings = s.warnings.clone();

    // Was the offset held over the second half? Settled: running, the phase loop
    // closed, the ramped offset reference at the held offset, from then on.
    let settled = |o: &Outputs| {
        let t = &o.telemetry;
        o.state == State::Running
            && t.phase_loop_closed
            && wrap_deg_180(f64::from(t.commanded_offset_deg - t.target_offset_deg)).abs() < 1e-3
    };
    let history = &driver.history;
    let settled_at = match history.iter().rposition(|(_, o)| !settled(o)) {
        None => history.first().map(|(t, _)| *t),
        Some(i) => history.get(i + 1).map(|(t, _)| *t),
    };
    outcome.not_held = if s.state == "starting" {
        Some(
            "the controller was still `starting` at the end (speed ramp or phase lock unfinished): raise --t-end"
                .to_string(),
        )
    } else if s.state != "running" {
        let faults = if s.faults.is_empty() {
            String::new()
        } else {
            format!(", faults {}", s.faults.join(", "))
        };
        Some(format!("the controller ended `{}`{faults}", s.state))
    } else if settled_at.is_none_or(|t| t > 0.5 * t_end) {
        Some(format!(
            "the offset reference reached the held offset only at t = {} s, after T/2 = {} s (raise --t-end)",
            settled_at.map_or("-".to_string(), text::sig),
            text::sig(0.5 * t_end)
        ))
    } else if s.phase_error_deg_rms.is_nan() || s.phase_error_deg_rms > HELD_ERROR_DEG_RMS {
        Some(format!(
            "phase error {} deg RMS over the second half (held offsets stay within {} deg)",
            text::sig(s.phase_error_deg_rms),
            text::sig(HELD_ERROR_DEG_RMS)
        ))
    } else if !s.mean_velocity.is_finite() {
        Some("the mean velocity is not a number".to_string())
    } else {
        None
    };
    outcome
}

/// Runs `points` (speed, offset) in parallel on rayon's pool (all cores, or
/// `RAYON_NUM_THREADS`), outcomes in the order of `points`, ticking `progress`.
pub fn run_points(
    machine: &Machine,
    points: &[(f64, f64)],
    t_end: f64,
    progress: &ProgressBar,
) -> Vec<RunOutcome> {
    points
        .par_iter()
        .map(|&(speed, offset)| {
            let outcome = run_point(machine, speed, offset, t_end);
            progress.inc(1);
            outcome
        })
        .collect()
}

/// The vertex of the parabola through `(x[i], v[i])`, `x` ascending: its abscissa
/// and value, when the parabola opens downwards (`way` right: a maximum) or
/// upwards (left: a minimum). Otherwise the reason it is degenerate.
///
/// With the divided differences `d01 = (v1 - v0) / (x1 - x0)`,
/// `d12 = (v2 - v1) / (x2 - x1)` and `a = (d12 - d01) / (x2 - x0)` (half the
/// second derivative), the parabola is `p(x) = v1 + b (x - x1) + a (x - x1)^2`
/// with `b = d01 + a (x1 - x0)`, and its vertex is at `x* = x1 - b / (2 a)`,
/// `p(x*) = v1 - b^2 / (4 a)`: Newton's divided differences, the same vertex as
/// Press et al., Numerical Recipes, 3rd ed., section 10.3, eq. (10.3.1).
pub fn parabola_vertex(x: [f64; 3], v: [f64; 3], way: Way) -> Result<(f64, f64), String> {
    if !x.iter().chain(&v).all(|z| z.is_finite()) {
        return Err("a neighbour's velocity is not a number".into());
    }
    if !(x[0] < x[1] && x[1] < x[2]) {
        return Err("the three offsets are not distinct".into());
    }
    let d01 = (v[1] - v[0]) / (x[1] - x[0]);
    let d12 = (v[2] - v[1]) / (x[2] - x[1]);
    let a = (d12 - d01) / (x[2] - x[0]);
    let opens_right_way = match way {
        Way::Right => a < 0.0,
        Way::Left => a > 0.0,
    };
    if !opens_right_way {
        return Err(format!(
            "the three velocities are not a {} (flat or curving the wrong way)",
            match way {
                Way::Right => "peak",
                Way::Left => "trough",
            }
        ));
    }
    let b = d01 + a * (x[1] - x[0]);
    let vertex = x[1] - b / (2.0 * a);
    let value = v[1] - b * b / (4.0 * a);
    if !(vertex.is_finite() && value.is_finite()) || vertex < x[0] || vertex > x[2] {
        return Err("the vertex lies outside the three offsets".into());
    }
    Ok((vertex, value))
}

/// The refinement planned for one speed and direction: the best grid point and
/// the rounded vertex to check, or why there is none.
#[derive(Clone, Debug, PartialEq)]
struct Candidate {
    speed_rpm: f64,
    /// Index of the best grid point in the tuning's runs.
    grid_index: usize,
    /// The vertex, rounded and wrapped, if the fit is not degenerate.
    vertex: Result<f64, String>,
}

/// The best grid point for `way` among the runs of one speed (`runs`, offsets
/// ascending): the extreme among the runs that held their offset (all runs when
/// none did), the first of equals; `None` when no velocity is finite.
fn extreme(runs: &[RunOutcome], way: Way) -> Option<usize> {
    let any_held = runs
        .iter()
        .any(|r| r.not_held.is_none() && r.mean_velocity.is_finite());
    let mut best: Option<usize> = None;
    for (i, r) in runs.iter().enumerate() {
        if !r.mean_velocity.is_finite() || (any_held && r.not_held.is_some()) {
            continue;
        }
        if best.is_none_or(|b| way.score(r.mean_velocity) > way.score(runs[b].mean_velocity)) {
            best = Some(i);
        }
    }
    best
}

/// Stage 3, planning: for each speed and direction the best grid point and the
/// vertex of the parabola through it and its neighbours in offset (circularly
/// when the offsets go round the turn).
fn candidates(grid: &Grid, runs: &[RunOutcome], way: Way) -> Vec<Candidate> {
    let n = grid.offsets_deg.len();
    let circular = grid.circular();
    let mut out = Vec::new();
    for (k, &speed) in grid.speeds_rpm.iter().enumerate() {
        let row = &runs[k * n..(k + 1) * n];
        let Some(i) = extreme(row, way) else { continue };
        let o = &grid.offsets_deg;
        // The neighbours' offsets, unwrapped around the best one.
        let neighbours = if circular {
            let (p, q) = ((i + n - 1) % n, (i + 1) % n);
            Some((
                p,
                o[i] - (o[i] - o[p]).rem_euclid(360.0),
                q,
                o[i] + (o[q] - o[i]).rem_euclid(360.0),
            ))
        } else if i > 0 && i + 1 < n {
            Some((i - 1, o[i - 1], i + 1, o[i + 1]))
        } else {
            None
        };
        let vertex = match neighbours {
            None => Err("the best offset is at an end of the offset range".to_string()),
            Some((p, xp, q, xq)) => parabola_vertex(
                [xp, o[i], xq],
                [
                    row[p].mean_velocity,
                    row[i].mean_velocity,
                    row[q].mean_velocity,
                ],
                way,
            )
            .map(|(x, _)| {
                wrap_deg_360((x / OFFSET_RESOLUTION_DEG).round() * OFFSET_RESOLUTION_DEG) + 0.0
            }),
        };
        out.push(Candidate {
            speed_rpm: speed,
            grid_index: k * n + i,
            vertex,
        });
    }
    out
}

/// Stage 3: the best offsets of both directions, checking each refined offset by
/// a run (in parallel). A refined offset is kept when its run held the offset and
/// travelled at least as fast as the best grid point; otherwise the grid point
/// is. Returns (right, left, the check runs made).
pub fn best_offsets(
    machine: &Machine,
    grid: &Grid,
    runs: &[RunOutcome],
    progress: &ProgressBar,
) -> (Vec<Best>, Vec<Best>, usize) {
    let plans: Vec<(Way, Candidate)> = [Way::Right, Way::Left]
        .into_iter()
        .flat_map(|w| candidates(grid, runs, w).into_iter().map(move |c| (w, c)))
        .collect();

    // The check runs: vertices that differ from their grid offset.
    let checks: Vec<(f64, f64)> = plans
        .iter()
        .filter_map(|(_, c)| match c.vertex {
            Ok(x) if x != runs[c.grid_index].offset_deg => Some((c.speed_rpm, x)),
            _ => None,
        })
        .collect();
    progress.inc_length(checks.len() as u64);
    let checked = run_points(machine, &checks, grid.t_end, progress);
    let mut checked = checked.into_iter();

    let (mut right, mut left) = (Vec::new(), Vec::new());
    for (way, c) in plans {
        let at = &runs[c.grid_index];
        let mut best = Best {
            speed_rpm: c.speed_rpm,
            offset_deg: at.offset_deg,
            mean_velocity: at.mean_velocity,
            grid_offset_deg: at.offset_deg,
            grid_mean_velocity: at.mean_velocity,
            refinement: Refinement::Parabola,
        };
        match c.vertex {
            Err(why) => best.refinement = Refinement::Degenerate(why),
            // The vertex is the grid point itself: nothing to check.
            Ok(x) if x == at.offset_deg => {}
            Ok(x) => {
                // In `checks` order: the same filter, the same sequence.
                if let Some(r) = checked.next() {
                    let faster = way.score(r.mean_velocity) >= way.score(at.mean_velocity);
                    if r.not_held.is_none() && faster {
                        best.offset_deg = x;
                        best.mean_velocity = r.mean_velocity;
                    } else {
                        best.refinement = Refinement::Slower(x, r.mean_velocity);
                    }
                }
            }
        }
        match way {
            Way::Right => right.push(best),
            Way::Left => left.push(best),
        }
    }
    (right, left, checks.len())
}

/// Stage 4: the warnings, in grid order, then by speed.
fn warnings(grid: &Grid, runs: &[RunOutcome], right: &[Best], left: &[Best]) -> Vec<String> {
    let mut out = Vec::new();
    for r in runs {
        let at = format!(
            "{} rpm, {} deg",
            text::sig(r.speed_rpm),
            text::sig(r.offset_deg)
        );
        if let Some(why) = &r.not_held {
            out.push(format!("{at}: offset not held: {why}"));
        }
        for w in &r.plant_warnings {
            out.push(format!("{at}: {w}"));
        }
    }
    for &speed in &grid.speeds_rpm {
        let has = |list: &[Best]| list.iter().any(|b| b.speed_rpm == speed);
        if !has(right) || !has(left) {
            out.push(format!(
                "{} rpm: no run gave a mean velocity: no best offset",
                text::sig(speed)
            ));
        }
    }
    for (list, way) in [(right, Way::Right), (left, Way::Left)] {
        for b in list {
            if way.score(b.mean_velocity) <= 0.0 {
                out.push(format!(
                    "{} rpm: no offset travels {}: the best is {} deg at {} mm/s",
                    text::sig(b.speed_rpm),
                    way.name(),
                    text::sig(b.offset_deg),
                    mm_s(b.mean_velocity)
                ));
            }
        }
    }
    out
}

/// Stages 2 to 4 on a checked machine and grid.
pub fn tune(machine: &Machine, grid: Grid, progress: &ProgressBar) -> Tuning {
    let points = grid.points();
    let runs = run_points(machine, &points, grid.t_end, progress);
    let (right, left, checks) = best_offsets(machine, &grid, &runs, progress);
    let warnings = warnings(&grid, &runs, &right, &left);
    Tuning {
        run_count: runs.len() + checks,
        grid,
        runs,
        right,
        left,
        warnings,
    }
}

/// A JSON number, `null` when not finite.
fn number(x: f64) -> Value {
    Value::from(x)
}

/// `{"speed_rpm", "offset_deg", "mean_velocity"}`.
fn point_value(speed: f64, offset: f64, velocity: f64) -> Value {
    let mut m = Map::new();
    m.insert("speed_rpm".into(), number(speed));
    m.insert("offset_deg".into(), number(offset));
    m.insert("mean_velocity".into(), number(velocity));
    Value::Object(m)
}

/// The spec's JSON document, `{"grid": [...], "best": {"right": [...], "left":
/// [...]}}`, and the project's `"warnings": [...]`, pretty-printed.
pub fn tuning_json(t: &Tuning) -> String {
    let mut doc = Map::new();
    doc.insert(
        "grid".into(),
        Value::Array(
            t.runs
                .iter()
                .map(|r| point_value(r.speed_rpm, r.offset_deg, r.mean_velocity))
                .collect(),
        ),
    );
    let list = |bests: &[Best]| {
        Value::Array(
            bests
                .iter()
                .map(|b| point_value(b.speed_rpm, b.offset_deg, b.mean_velocity))
                .collect(),
        )
    };
    let mut best = Map::new();
    best.insert("right".into(), list(&t.right));
    best.insert("left".into(), list(&t.left));
    doc.insert("best".into(), Value::Object(best));
    doc.insert(
        "warnings".into(),
        Value::Array(t.warnings.iter().map(|w| Value::from(w.as_str())).collect()),
    );
    let mut text = serde_json::to_string_pretty(&Value::Object(doc))
        .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    text.push('\n');
    text
}

/// A velocity in mm/s with a sign and one decimal: `+29.2`, `-0.4`, `0.0`.
fn mm_s(v: f64) -> String {
    if !v.is_finite() {
        return "nan".into();
    }
    let s = format!("{:+.1}", v * 1e3);
    if s == "+0.0" || s == "-0.0" {
        "0.0".into()
    } else {
        s
    }
}

/// `1 speed`, `5 speeds`.
fn count(n: usize, what: &str) -> String {
    if n == 1 {
        format!("1 {what}")
    } else {
        format!("{n} {what}s")
    }
}

/// How a best offset was found, for people.
fn describe(b: &Best) -> String {
    match &b.refinement {
        Refinement::Parabola if b.offset_deg == b.grid_offset_deg => {
            "grid (the vertex is the grid point)".into()
        }
        Refinement::Parabola => format!(
            "vertex (grid {} deg: {} mm/s)",
            text::sig(b.grid_offset_deg),
            mm_s(b.grid_mean_velocity)
        ),
        Refinement::Degenerate(why) => format!("grid ({why})"),
        Refinement::Slower(x, v) => {
            format!("grid (vertex {} deg: {} mm/s)", text::sig(*x), mm_s(*v))
        }
    }
}

/// The result for people: the grid of mean velocities (speeds as rows, offsets
/// as columns, mm/s; `*` marks a run that did not hold its offset), the best
/// offsets, and the warnings.
pub fn tuning_table(t: &Tuning, machine_path: &Path) -> String {
    let g = &t.grid;
    let mut out = format!(
        "tune {}: {} x {}, runs of {} s holding the offset from t = 0; mean velocity over the second half, mm/s\n\n",
        machine_path.display(),
        count(g.speeds_rpm.len(), "speed"),
        count(g.offsets_deg.len(), "offset"),
        text::sig(g.t_end)
    );

    // The grid.
    let titles: Vec<String> = std::iter::once("rpm \\ deg".to_string())
        .chain(g.offsets_deg.iter().map(|o| text::sig(*o)))
        .collect();
    let columns: Vec<(&str, Align)> = titles
        .iter()
        .enumerate()
        .map(|(i, s)| (s.as_str(), if i == 0 { Align::Left } else { Align::Right }))
        .collect();
    let mut grid = Table::new(&columns);
    let n = g.offsets_deg.len();
    let mut marked = false;
    for (k, speed) in g.speeds_rpm.iter().enumerate() {
        let mut cells = vec![text::sig(*speed)];
        for r in &t.runs[k * n..(k + 1) * n] {
            let mark = if r.not_held.is_some() { "*" } else { "" };
            marked |= r.not_held.is_some();
            cells.push(format!("{}{mark}", mm_s(r.mean_velocity)));
        }
        grid.row(cells);
    }
    out.push_str(&grid.render());
    if marked {
        out.push_str("* the offset was not held in this run (see the warnings)\n");
    }

    // The best offsets.
    out.push_str("\nbest offsets (parabola through the best grid point and its neighbours, checked by a run)\n");
    let mut best = Table::new(&[
        ("speed (rpm)", Align::Right),
        ("right (deg)", Align::Right),
        ("mm/s", Align::Right),
        ("left (deg)", Align::Right),
        ("mm/s", Align::Right),
        ("right from", Align::Left),
        ("left from", Align::Left),
    ]);
    for speed in &g.speeds_rpm {
        let find = |list: &[Best]| list.iter().find(|b| b.speed_rpm == *speed).cloned();
        let (r, l) = (find(&t.right), find(&t.left));
        let cell = |b: &Option<Best>, f: &dyn Fn(&Best) -> String| b.as_ref().map_or("-".into(), f);
        best.row(vec![
            text::sig(*speed),
            cell(&r, &|b| text::sig(b.offset_deg)),
            cell(&r, &|b| mm_s(b.mean_velocity)),
            cell(&l, &|b| text::sig(b.offset_deg)),
            cell(&l, &|b| mm_s(b.mean_velocity)),
            cell(&r, &describe),
            cell(&l, &describe),
        ]);
    }
    out.push_str(&best.render());

    // Warnings.
    if t.warnings.is_empty() {
        out.push_str("\nwarnings: none\n");
    } else {
        out.push_str("\nwarnings:\n");
        for w in &t.warnings {
            let _ = writeln!(out, "  - {w}");
        }
    }
    out
}

/// The tuning table file for `--write`: a header that says how it was made (no
/// date, so the same sweep writes the same file) and one row per speed with a
/// best offset both ways.
pub fn table_file(t: &Tuning, args: &TuneArgs, speeds_text: &str, offsets_text: &str) -> String {
    let g = &t.grid;
    let mut command = format!(
        "host-sim tune {} --speeds {speeds_text} --offsets {offsets_text} --t-end {}",
        args.machine.display(),
        text::sig(g.t_end)
    );
    for s in &args.set {
        let _ = write!(command, " --set {s}");
    }
    if let Some(w) = &args.write {
        let _ = write!(command, " --write {}", w.display());
    }
    let mut header = format!(
        "Tuning table: the best phase offset for rightward and leftward travel per rotor speed.\n\
         Written by `host-sim tune` (see docs/tuning.md); regenerate with\n  {command}\n\
         Grid: {} x {} ({}), runs of {} s holding each offset from t = 0,\n\
         mean velocity over the second half. The best grid offset is refined by a parabola\n\
         through it and its two neighbours and kept when a run there is at least as fast.\n\
         Measured mean velocities, m/s:\n",
        count(g.speeds_rpm.len(), "speed"),
        count(g.offsets_deg.len(), "offset"),
        if g.circular() {
            "around the turn"
        } else {
            "part of the turn"
        },
        text::sig(g.t_end)
    );
    for (r, l) in table_rows_bests(t) {
        let _ = writeln!(
            header,
            "  {} rpm: right {:.1} deg {}, left {:.1} deg {}",
            text::sig(r.speed_rpm),
            r.offset_deg,
            text::signed(r.mean_velocity),
            l.offset_deg,
            text::signed(l.mean_velocity)
        );
    }
    if !t.warnings.is_empty() {
        let _ = writeln!(
            header,
            "The sweep gave {}: see the output of the command above.",
            count(t.warnings.len(), "warning")
        );
    }
    let rows: Vec<tuning_file::Row> = table_rows_bests(t)
        .iter()
        .map(|(r, l)| (r.speed_rpm, r.offset_deg, l.offset_deg))
        .collect();
    tuning_file::write(&rows, header.trim_end())
}

/// The speeds with a best offset both ways, as (right, left) pairs.
fn table_rows_bests(t: &Tuning) -> Vec<(Best, Best)> {
    t.right
        .iter()
        .filter_map(|r| {
            t.left
                .iter()
                .find(|l| l.speed_rpm == r.speed_rpm)
                .map(|l| (r.clone(), l.clone()))
        })
        .collect()
}

/// Runs the command (stages of the module doc).
pub fn run(args: &TuneArgs) -> Output {
    // 1. The machine and the grid.
    let (machine, grid, speeds_text, offsets_text) = match read_options(args) {
        Ok(x) => x,
        Err(stderr) => {
            return Output {
                stderr,
                status: EXIT_USAGE,
                ..Output::default()
            }
        }
    };

    // 2.-4. The sweep, with a progress bar on stderr (drawn only on a terminal).
    let started = Instant::now();
    let total = grid.speeds_rpm.len() * grid.offsets_deg.len();
    let progress = ProgressBar::with_draw_target(Some(total as u64), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(
        "tune {bar:40} {pos}/{len} runs, {elapsed} elapsed, ~{eta} left",
    ) {
        progress.set_style(style);
    }
    let tuning = tune(&machine, grid, &progress);
    progress.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();

    // 5. Files, then the result.
    let mut files: Vec<(&Path, String)> = Vec::new();
    if let Some(path) = &args.write {
        if tuning.right.is_empty() || tuning.left.is_empty() {
            return Output {
                stderr: "error: --write: no speed has a best offset both ways (no run gave a mean velocity): nothing to write\n".into(),
                status: EXIT_FAILURE,
                ..Output::default()
            };
        }
        let text = table_file(&tuning, args, &speeds_text, &offsets_text);
        // What is written must read back as a table the controller takes.
        let readable = tuning_file::parse(&path.display().to_string(), &text)
            .ok()
            .and_then(|rows| tuning_file::table(&rows));
        if readable.is_none() {
            return Output {
                stderr: format!(
                    "error: --write {}: the table does not read back (an internal error)\n",
                    path.display()
                ),
                status: EXIT_FAILURE,
                ..Output::default()
            };
        }
        files.push((path, text));
    }
    if let Some(path) = &args.plot {
        let title = format!("host-sim tune {}", args.machine.display());
        files.push((path, tune_plot::plot_svg(&tuning, &title)));
    }
    for (path, contents) in files {
        if let Err(e) = write_whole(path, &contents) {
            return Output {
                stderr: format!("error: {e}\n"),
                status: EXIT_USAGE,
                ..Output::default()
            };
        }
    }
    Output {
        stdout: match args.format {
            Format::Json => tuning_json(&tuning),
            Format::Table => tuning_table(&tuning, &args.machine),
        },
        stderr: format!(
            "tune: {} runs in {:.1} s on {}{}\n",
            tuning.run_count,
            seconds,
            count(rayon::current_num_threads(), "thread"),
            if tuning.warnings.is_empty() {
                String::new()
            } else {
                format!(", {}", count(tuning.warnings.len(), "warning"))
            }
        ),
        status: EXIT_OK,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_include_both_ends() {
        assert_eq!(
            parse_range("--speeds", "2500:3500:250").unwrap(),
            [2500.0, 2750.0, 3000.0, 3250.0, 3500.0]
        );
        assert_eq!(parse_range("--speeds", "3000").unwrap(), [3000.0]);
        assert_eq!(parse_range("--speeds", "3000:3000:10").unwrap(), [3000.0]);
        // B not on the steps: appended.
        assert_eq!(
            parse_range("--offsets", "0:100:30").unwrap(),
            [0.0, 30.0, 60.0, 90.0, 100.0]
        );
        // Rounding: 0.1 x 3600 lands on 360 exactly.
        let r = parse_range("--offsets", "0:360:0.1").unwrap();
        assert_eq!(r.len(), 3601);
        assert_eq!(r[3600], 360.0);
    }

    #[test]
    fn bad_ranges_name_the_option_and_the_reason() {
        for (text, why) in [
            ("0:360:0", "STEP must be > 0"),
            ("0:360:-15", "STEP must be > 0"),
            ("360:0:15", "B must be >= A"),
            ("nan:360:15", "finite"),
            ("0:inf:15", "finite"),
            ("0:360", "expected A:B:STEP"),
            ("a:b:c", "expected A:B:STEP"),
            ("", "expected A:B:STEP"),
            ("0:1e9:1e-9", "at most 10000"),
            ("0:10001:1", "at most 10000"),
        ] {
            let e = parse_range("--offsets", text).unwrap_err();
            assert!(e.starts_with(&format!("error: --offsets {text}: ")), "{e}");
            assert!(e.contains(why), "{text}: {e}");
        }
        assert!(parse_range("--offsets", "0:9999:1").is_ok());
    }

    #[test]
    fn offsets_wrap_and_run_once() {
        let o = wrap_offsets(&parse_range("--offsets", "0:360:90").unwrap());
        assert_eq!(o, [0.0, 90.0, 180.0, 270.0]);
        let o = wrap_offsets(&[-90.0, 0.0, 90.0, -0.0, 360.0, 720.0 - 1e-12]);
        assert_eq!(o, [0.0, 90.0, 270.0]);
        assert!(o[0].is_sign_positive());
        let grid = |offsets_deg: Vec<f64>| Grid {
            speeds_rpm: vec![3000.0],
            offsets_deg,
            t_end: 1.0,
        };
        assert!(grid(vec![0.0, 90.0, 180.0, 270.0]).circular());
        assert!(grid(vec![10.0, 130.0, 250.0]).circular());
        assert!(!grid(vec![0.0, 30.0, 60.0, 90.0]).circular());
        assert!(!grid(vec![0.0, 180.0]).circular());
    }

    #[test]
    fn the_vertex_of_a_known_parabola() {
        // v = 3 - 0.01 (x - 97)^2 through 80, 90, 100 (uneven around the vertex).
        let p = |x: f64| 3.0 - 0.01 * (x - 97.0) * (x - 97.0);
        let (x, v) = parabola_vertex(
            [80.0, 90.0, 110.0],
            [p(80.0), p(90.0), p(110.0)],
            Way::Right,
        )
        .unwrap();
        assert!((x - 97.0).abs() < 1e-9, "{x}");
        assert!((v - 3.0).abs() < 1e-9, "{v}");
        // The mirror image is a trough for the left.
        let (x, v) = parabola_vertex(
            [80.0, 90.0, 110.0],
            [-p(80.0), -p(90.0), -p(110.0)],
            Way::Left,
        )
        .unwrap();
        assert!((x - 97.0).abs() < 1e-9 && (v + 3.0).abs() < 1e-9);
        // Degenerate: flat, the wrong curvature, not a number.
        assert!(parabola_vertex([0.0, 1.0, 2.0], [1.0, 1.0, 1.0], Way::Right).is_err());
        assert!(parabola_vertex([0.0, 1.0, 2.0], [1.0, 0.0, 1.0], Way::Right).is_err());
        assert!(parabola_vertex([0.0, 1.0, 2.0], [0.0, 1.0, 0.0], Way::Left).is_err());
        assert!(parabola_vertex([0.0, 1.0, 2.0], [0.0, f64::NAN, 0.0], Way::Right).is_err());
        assert!(parabola_vertex([0.0, 0.0, 2.0], [0.0, 1.0, 0.0], Way::Right).is_err());
    }

    fn outcome(speed: f64, offset: f64, v: f64) -> RunOutcome {
        RunOutcome {
            speed_rpm: speed,
            offset_deg: offset,
            mean_velocity: v,
            not_held: None,
            plant_warnings: vec![],
        }
    }

    /// A sweep of `v(offset) = sin(offset - 10 deg)` at two speeds.
    fn synthetic() -> (Grid, Vec<RunOutcome>) {
        let grid = Grid {
            speeds_rpm: vec![2500.0, 3000.0],
            offsets_deg: (0..24).map(|i| f64::from(i) * 15.0).collect(),
            t_end: 4.0,
        };
        let runs = grid
            .points()
            .into_iter()
            .map(|(s, o)| outcome(s, o, 0.02 * (o - 10.0).to_radians().sin()))
            .collect();
        (grid, runs)
    }

    #[test]
    fn candidates_refine_around_the_extreme_circularly() {
        let (grid, runs) = synthetic();
        let right = candidates(&grid, &runs, Way::Right);
        assert_eq!(right.len(), 2);
        assert_eq!(runs[right[0].grid_index].offset_deg, 105.0);
        let x = right[0].vertex.clone().unwrap();
        assert!((x - 100.0).abs() < 0.5, "{x}");
        let left = candidates(&grid, &runs, Way::Left);
        assert_eq!(runs[left[1].grid_index].offset_deg, 285.0);
        assert!((left[1].vertex.clone().unwrap() - 280.0).abs() < 0.5);
        // An extreme at offset 0 takes 345 as its left neighbour.
        let mut runs = runs;
        for r in &mut runs {
            r.mean_velocity = 0.02 * (r.offset_deg - 355.0).to_radians().cos();
        }
        let right = candidates(&grid, &runs, Way::Right);
        assert_eq!(runs[right[0].grid_index].offset_deg, 0.0);
        let x = right[0].vertex.clone().unwrap();
        assert!((x - 355.0).abs() < 0.5, "{x}");
    }

    #[test]
    fn runs_that_did_not_hold_their_offset_are_not_chosen() {
        let (grid, mut runs) = synthetic();
        let i = runs.iter().position(|r| r.offset_deg == 105.0).unwrap();
        runs[i].not_held = Some("the controller ended `fault`".into());
        runs[i].mean_velocity = 1.0;
        let right = candidates(&grid, &runs, Way::Right);
        assert_ne!(right[0].grid_index, i);
        assert_eq!(runs[right[0].grid_index].offset_deg, 90.0);
        // At an end of a partial range there is no fit.
        let partial = Grid {
            speeds_rpm: vec![3000.0],
            offsets_deg: vec![0.0, 30.0, 60.0, 90.0],
            t_end: 4.0,
        };
        let runs: Vec<RunOutcome> = partial
            .points()
            .into_iter()
            .map(|(s, o)| outcome(s, o, o))
            .collect();
        let right = candidates(&partial, &runs, Way::Right);
        assert!(right[0].vertex.as_ref().unwrap_err().contains("end"));
    }

    #[test]
    fn speeds_without_travel_one_way_are_warned() {
        let (grid, mut runs) = synthetic();
        for r in &mut runs {
            r.mean_velocity = r.mean_velocity.abs() + 1e-3;
        }
        let best = |way: Way| -> Vec<Best> {
            candidates(&grid, &runs, way)
                .into_iter()
                .map(|c| Best {
                    speed_rpm: c.speed_rpm,
                    offset_deg: runs[c.grid_index].offset_deg,
                    mean_velocity: runs[c.grid_index].mean_velocity,
                    grid_offset_deg: runs[c.grid_index].offset_deg,
                    grid_mean_velocity: runs[c.grid_index].mean_velocity,
                    refinement: Refinement::Parabola,
                })
                .collect()
        };
        let w = warnings(&grid, &runs, &best(Way::Right), &best(Way::Left));
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(
            w[0].starts_with("2500 rpm: no offset travels left"),
            "{w:?}"
        );
    }

    #[test]
    fn velocities_for_people() {
        assert_eq!(mm_s(0.0292), "+29.2");
        assert_eq!(mm_s(-0.00002), "0.0");
        assert_eq!(mm_s(-0.0304), "-30.4");
        assert_eq!(mm_s(f64::NAN), "nan");
    }
}
