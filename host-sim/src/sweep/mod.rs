//! The sweep of speeds and phase offsets, below the commands that sweep
//! (`host-sim tune`, `calibrate`, `device tune`): the grid ([`Grid`], from the
//! `A:B:STEP` ranges), one closed-loop run per point ([`run_point`]), all of them
//! in parallel ([`run_points`]), and the best offsets from the runs ([`best`]).

pub mod best;

use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use shared::controller::{Command, Outputs, State, Telemetry};

use crate::failure::Failure;
use crate::machine::input;
use crate::machine::Machine;
use crate::numbers;
use crate::output::progress::Progress;
use crate::plant::progress::Stop;
use crate::simulation::closed_loop::ControllerDriver;
use crate::simulation::trace::EndState;
use crate::simulation::trace::MAX_VELOCITY_MPS;
use crate::simulation::{simulate_observed, Interruptible, RunOptions};
use shared::controller::angle::{wrap_deg_f64, wrap_deg_signed_f64};

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
/// ([`crate::machine::tuning_file::write`] writes one decimal), so that the offset checked, the
/// one reported and the one written are the same number.
pub(crate) const OFFSET_RESOLUTION_DEG: f64 = 0.1;

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

/// The machine of file `path` (its `text`) with the `--set`s `set`, as tune
/// runs it: two rotors, no tuning table. Refused, the user's to fix.
pub fn load_machine(path: &Path, text: &str, set: &[String]) -> Result<Machine, Failure> {
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut machine = Machine::from_text(&path.display().to_string(), text, dir, set)?;
    if machine.rotors.len() == 1 {
        return Err(Failure::usage(one_rotor_refusal(path, &machine)));
    }
    machine.controller.tuning_table = None;
    Ok(machine)
}

/// Why `--write` cannot hold a table of `speeds` (given as `speeds_text`): more
/// rows than the controller's table, or two speeds that print alike; one text
/// each.
pub fn table_problems(speeds: &[f64], speeds_text: &str) -> Vec<String> {
    let mut problems = Vec::new();
    if speeds.len() > shared::controller::MAX_TUNING_ROWS {
        problems.push(format!(
            "--write: the controller's table holds at most {} rows (speeds), --speeds {speeds_text} gives {}",
            shared::controller::MAX_TUNING_ROWS,
            speeds.len()
        ));
    }
    let written: Vec<String> = speeds.iter().map(|v| format!("{v:.1}")).collect();
    if written.windows(2).any(|w| w[0] == w[1]) {
        problems.push(format!(
            "--write: --speeds {speeds_text} has speeds closer than the table's 0.1 rpm"
        ));
    }
    problems
}

/// Why `tune` refuses a one-rotor machine: it sweeps the phase offset between two
/// rotors and writes the offsets of the tuning table, and a single rotor has
/// neither (its controller holds speed only).
fn one_rotor_refusal(path: &std::path::Path, machine: &Machine) -> String {
    format!(
        "{}: rotors: the machine has one rotor (\"{}\"): tune sweeps the phase offset between two rotors and writes their offsets, and one rotor has no offset (its controller holds speed only); nothing to tune: run it with `host-sim run {} --command right --speed RPM`",
        path.display(),
        machine.rotors.rotor1().name,
        path.display()
    )
}

/// The progress of `total` runs on stderr, `name` heading it: a bar on a
/// terminal, else a line every few seconds ([`Progress`]).
pub fn progress_bar(name: &str, total: usize) -> Progress {
    Progress::new(name, total as u64, "runs")
}

/// A failure of `command` (`tune`, `merge`) when a signal stopped the runs
/// ([`crate::interrupt`]; `what` is what that left undone): nothing is written then.
pub fn refuse_interrupted(command: &str, what: &str) -> Result<(), Failure> {
    if crate::interrupt::interrupted() {
        return Err(Failure::run(format!(
            "{command}: {}: {what}, nothing written",
            crate::interrupt::interruption()
        )));
    }
    Ok(())
}

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

/// A mean velocity: a JSON number when finite, else `"NaN"`, `"inf"`, `"-inf"`.
pub mod maybe_finite {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    #[derive(Serialize, Deserialize)]
    #[serde(untagged)]
    enum Number {
        Finite(f64),
        Other(String),
    }

    /// `x` as a JSON number when finite, else as its name.
    pub fn serialize<S: Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
        match *x {
            x if x.is_finite() => Number::Finite(x),
            x if x.is_nan() => Number::Other("NaN".into()),
            x if x > 0.0 => Number::Other("inf".into()),
            _ => Number::Other("-inf".into()),
        }
        .serialize(s)
    }

    /// A number, or `"NaN"`, `"inf"`, `"-inf"`; any other string is refused.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        match Number::deserialize(d)? {
            Number::Finite(x) => Ok(x),
            Number::Other(s) => match s.as_str() {
                "NaN" => Ok(f64::NAN),
                "inf" => Ok(f64::INFINITY),
                "-inf" => Ok(f64::NEG_INFINITY),
                _ => Err(serde::de::Error::custom(format!(
                    "mean_velocity {s:?}: expected a number, \"NaN\", \"inf\" or \"-inf\""
                ))),
            },
        }
    }
}

/// What one closed-loop run gave. As JSON (a fit's partial result holds its
/// runs so) its mean velocity is a number when finite, else `"NaN"`, `"inf"` or
/// `"-inf"` ([`maybe_finite`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunOutcome {
    /// Rotor speed, rpm.
    pub speed_rpm: f64,
    /// Phase offset held, degrees in [0, 360).
    pub offset_deg: f64,
    /// `(x_C(T) - x_C(T/2)) / (T/2)`, m/s (the run's summary); NaN when the run
    /// was no travel.
    #[serde(with = "maybe_finite")]
    pub mean_velocity: f64,
    /// Why the offset was not held over the second half, if it was not: the
    /// controller faulted or never reached `running` in time, or the phase error
    /// was large. `None` for a run that was no travel (`not_a_travel` says why).
    pub not_held: Option<String>,
    /// Why the run was no travel, if it was not: the plant stopped advancing
    /// (the progress guard, a step size underflow: [`Stop`]'s message), a body
    /// went through the fundament or tipped over ([`crate::simulation::breach`]),
    /// or the mean velocity is beyond [`MAX_VELOCITY_MPS`]. Its mean velocity is
    /// then NaN.
    pub not_a_travel: Option<String>,
    /// Warnings of the plant (e.g. a Painleve configuration): at most
    /// [`MAX_PLANT_WARNINGS`], then one counting the others.
    pub plant_warnings: Vec<String>,
}

/// The most plant warnings a run keeps; the others are counted in one more
/// (`... and 12 more plant warnings in this run`). The plant warns once per
/// kind and time (a Painleve configuration at each `t`), so a run may have many.
pub const MAX_PLANT_WARNINGS: usize = 8;

/// The most bytes of a warning or a reason a run keeps; a longer one is cut
/// ([`input::cut`]: a name of the machine file may be in it). The plant's own are
/// under 300 bytes. With [`MAX_PLANT_WARNINGS`] a run's outcome stays under 5
/// KB, so that a partial result of the largest grid fits its 64 MiB.
pub const MAX_REASON_BYTES: usize = 400;

impl RunOutcome {
    /// The outcome with its texts bounded: at most [`MAX_PLANT_WARNINGS`] plant
    /// warnings and one counting the rest, each text cut at [`MAX_REASON_BYTES`].
    pub(crate) fn bounded(mut self) -> RunOutcome {
        let cut = |s: &str| input::cut(s, MAX_REASON_BYTES);
        let more = self.plant_warnings.len().saturating_sub(MAX_PLANT_WARNINGS);
        self.plant_warnings.truncate(MAX_PLANT_WARNINGS);
        self.plant_warnings = self.plant_warnings.iter().map(|w| cut(w)).collect();
        if more > 0 {
            self.plant_warnings.push(format!(
                "... and {} in this run",
                numbers::count(more, "more plant warning")
            ));
        }
        self.not_held = self.not_held.as_deref().map(cut);
        self.not_a_travel = self.not_a_travel.as_deref().map(cut);
        self
    }

    /// Why `tune` never makes this outcome (a partial result's run that `merge`
    /// refuses), if it does not: a mean velocity beyond [`MAX_VELOCITY_MPS`], or
    /// not a number where the run held its offset and travelled, or a number
    /// where it was no travel; more plant warnings or longer texts than
    /// `RunOutcome::bounded` keeps. The texts quoted cut.
    pub fn problem(&self) -> Option<String> {
        let v = self.mean_velocity;
        if v.is_finite() && v.abs() > MAX_VELOCITY_MPS {
            return Some(format!(
                "mean_velocity {} m/s: beyond the {} m/s of any travel by impacts (tune writes no such run)",
                numbers::sig(v),
                numbers::sig(MAX_VELOCITY_MPS)
            ));
        }
        if let Some(why) = &self.not_a_travel {
            if !v.is_nan() || self.not_held.is_some() {
                return Some(format!(
                    "mean_velocity {} with not_a_travel {}: a run that was no travel has no mean velocity (NaN) and no not_held",
                    numbers::sig(v),
                    input::quoted(why)
                ));
            }
        } else if self.not_held.is_none() && !v.is_finite() {
            return Some(format!(
                "mean_velocity {v} with not_held and not_a_travel null: a run that held its offset and travelled has a finite mean velocity"
            ));
        }
        let most = MAX_PLANT_WARNINGS + 1;
        if self.plant_warnings.len() > most {
            return Some(format!(
                "{}: tune keeps at most {most} a run",
                numbers::count(self.plant_warnings.len(), "plant warning")
            ));
        }
        let texts = self
            .plant_warnings
            .iter()
            .map(|w| ("a plant warning", w))
            .chain(self.not_held.iter().map(|w| ("not_held", w)))
            .chain(self.not_a_travel.iter().map(|w| ("not_a_travel", w)));
        for (what, s) in texts {
            if s.len() > input::cut_bound(MAX_REASON_BYTES) {
                return Some(format!(
                    "{what} {}: tune cuts such a text at {MAX_REASON_BYTES} bytes",
                    input::quoted(s)
                ));
            }
        }
        None
    }

    /// The run's speed, m/s: its mean velocity where it held its offset and was a
    /// travel (and the number is finite), else `None`. The one test of whether a
    /// run gives a speed, for `tune`, `tune --robust`, `merge` and `calibrate`.
    pub fn velocity(&self) -> Option<f64> {
        (self.not_held.is_none() && self.not_a_travel.is_none() && self.mean_velocity.is_finite())
            .then_some(self.mean_velocity)
    }

    /// Why the run gives no speed, for a message: `not a travel: WHY` or
    /// `offset not held: WHY`; `None` where it gives one.
    pub fn no_speed(&self) -> Option<String> {
        match (&self.not_a_travel, &self.not_held) {
            (Some(why), _) => Some(format!("not a travel: {why}")),
            (None, Some(why)) => Some(format!("offset not held: {why}")),
            (None, None) if !self.mean_velocity.is_finite() => {
                Some("the mean velocity is not a number".into())
            }
            (None, None) => None,
        }
    }
}

/// Parses a range `A:B:STEP` (or a single value `A`) of option `option` into its
/// points: `A, A + STEP, ...` up to `B`, both ends included (`B` is appended when
/// the steps do not land on it). Refused: a malformed text, a value that is not
/// finite, `STEP <= 0`, `B < A`, more than [`MAX_POINTS`] points.
pub fn parse_range(text: &str) -> Result<Vec<f64>, String> {
    let bad = |why: String| why;
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
        return Err(bad(format!(
            "STEP must be > 0 (got {})",
            numbers::sig(step)
        )));
    }
    if b < a {
        return Err(bad(format!(
            "B must be >= A: the range runs up from A = {} to B = {}",
            numbers::sig(a),
            numbers::sig(b)
        )));
    }
    // Whole steps from A towards B; rounding within 1e-9 of a step lands on B.
    let steps = (b - a) / step;
    if steps + 1.0 > MAX_POINTS as f64 {
        let count = (steps + 1.0).floor();
        let count = if count < 1e12 {
            format!("{count:.0}")
        } else {
            numbers::sig(count)
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

/// A range option as given (`A:B:STEP`, kept for the table file's header) and its
/// points.
#[derive(Clone, Debug, PartialEq)]
pub struct Range {
    /// The text on the command line.
    pub text: String,
    /// Its points, ascending.
    pub points: Vec<f64>,
}

/// `--speeds`: a range of rotor speeds, rpm ([`parse_range`]).
pub fn parse_speeds(text: &str) -> Result<Range, String> {
    Ok(Range {
        text: text.to_string(),
        points: parse_range(text)?,
    })
}

/// `--offsets`: a range of phase offsets, degrees, at most one turn
/// ([`parse_range`]).
pub fn parse_offsets(text: &str) -> Result<Range, String> {
    let points = parse_range(text)?;
    if points
        .last()
        .zip(points.first())
        .is_some_and(|(b, a)| b - a > 360.0)
    {
        return Err("spans more than one turn (B - A must be <= 360 degrees)".to_string());
    }
    Ok(Range {
        text: text.to_string(),
        points,
    })
}

/// Offsets wrapped to [0, 360), ascending, each once (360 is 0; offsets within
/// 1e-9 degrees are the same).
pub fn wrap_offsets(offsets: &[f64]) -> Vec<f64> {
    let mut out: Vec<f64> = offsets.iter().map(|&o| wrap_deg_f64(o) + 0.0).collect();
    out.sort_by(f64::total_cmp);
    out.dedup_by(|b, a| (*b - *a).abs() <= 1e-9);
    if out.len() > 1 && out[out.len() - 1] >= 360.0 - 1e-9 && out[0] <= 1e-9 {
        out.pop();
    }
    out
}

/// The default speeds for a machine: `[controller].speed_rpm` +- 0, 250 and 500
/// rpm within `[lo, hi]` rpm, as a range text for messages (`2500:3500:250`).
pub(crate) fn default_speeds(nominal: f64, lo: f64, hi: f64) -> (Vec<f64>, String) {
    let k = (DEFAULT_SPEED_SPAN_RPM / DEFAULT_SPEED_STEP_RPM).round() as i32;
    let speeds: Vec<f64> = (-k..=k)
        .map(|i| nominal + f64::from(i) * DEFAULT_SPEED_STEP_RPM)
        .filter(|s| *s >= lo && *s <= hi)
        .collect();
    let text = match (speeds.first(), speeds.last()) {
        (Some(a), Some(b)) => format!(
            "{}:{}:{}",
            numbers::sig(*a),
            numbers::sig(*b),
            numbers::sig(DEFAULT_SPEED_STEP_RPM)
        ),
        _ => String::new(),
    };
    (speeds, text)
}

/// Whether a controller in `state` with telemetry `t` holds its offset: running,
/// the phase loop closed, the ramped offset reference at the target (within
/// 1e-3 degrees). The same test for a simulated run ([`run_point`]) and for the
/// device's status reports (`host-sim device tune`).
pub fn offset_held(state: State, t: &Telemetry) -> bool {
    state == State::Running
        && t.phase_loop_closed
        && wrap_deg_signed_f64(f64::from(t.commanded_offset_deg - t.target_offset_deg)).abs() < 1e-3
}

/// One closed-loop run of `machine` to `t_end` with the controller holding
/// `offset_deg` at `speed_rpm` from `t = 0`. The offset counts as held when the
/// controller ends `running`, got there by `T/2`, and its phase error over the
/// second half is within [`HELD_ERROR_DEG_RMS`]. A run whose plant stopped
/// advancing ([`Stop`]), one in which a body went through the fundament or
/// tipped over ([`crate::simulation::breach`]), or one whose
/// mean velocity is beyond [`MAX_VELOCITY_MPS`] either way (no travel by impacts
/// goes that fast: the measured file's bound), is no travel: `not_a_travel` says
/// why, and it has no mean velocity (NaN).
pub fn run_point(machine: &Machine, speed_rpm: f64, offset_deg: f64, t_end: f64) -> RunOutcome {
    simulate_point(machine, speed_rpm, offset_deg, t_end).bounded()
}

/// [`run_point`] without the bounds of its texts.
fn simulate_point(machine: &Machine, speed_rpm: f64, offset_deg: f64, t_end: f64) -> RunOutcome {
    let command = Command::HoldOffset {
        speed_rpm: speed_rpm as f32,
        offset_deg: offset_deg as f32,
    };
    let mut outcome = RunOutcome {
        speed_rpm,
        offset_deg,
        mean_velocity: f64::NAN,
        not_held: None,
        not_a_travel: None,
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
    let mut options = RunOptions::new(t_end);
    options.keep_rows = false;
    options.keep_events = false;
    let result = simulate_observed(machine, &mut driver, &options, &mut Interruptible::new());
    let s = &result.summary;
    // A plant that stopped advancing: the run is not a travel, and says why (a
    // signal is the sweep's to report: `refuse_interrupted`). A body through the
    // fundament or tipped over: no travel to count (the run's own summary gives
    // no number either); nor a speed no travel by impacts reaches.
    let stalled = result.stopped.as_ref().filter(|stop| !stop.is_signal());
    outcome.not_a_travel = stalled.map(Stop::to_string).or_else(|| s.not_a_travel());
    outcome.mean_velocity = match outcome.not_a_travel {
        None => s.mean_velocity,
        Some(_) => f64::NAN,
    };
    outcome.plant_warnings = s.warnings.clone();
    if outcome.not_a_travel.is_some() {
        return outcome;
    }

    // Was the offset held over the second half? Settled from then on.
    let settled = |o: &Outputs| offset_held(o.state, &o.telemetry);
    let history = &driver.history;
    let settled_at = match history.iter().rposition(|(_, o)| !settled(o)) {
        None => history.first().map(|(t, _)| *t),
        Some(i) => history.get(i + 1).map(|(t, _)| *t),
    };
    outcome.not_held = if s.state == EndState::Controller(State::Starting) {
        Some(
            "the controller was still `starting` at the end (speed ramp or phase lock unfinished): raise --t-end"
                .to_string(),
        )
    } else if s.state != EndState::Controller(State::Running) {
        let faults = if s.faults.is_empty() {
            String::new()
        } else {
            format!(", faults {}", s.faults)
        };
        Some(format!("the controller ended `{}`{faults}", s.state))
    } else if settled_at.is_none_or(|t| t > 0.5 * t_end) {
        Some(match settled_at {
            Some(t) => format!(
                "the offset reference reached the held offset only at t = {} s, after T/2 = {} s (raise --t-end)",
                numbers::sig(t),
                numbers::sig(0.5 * t_end)
            ),
            // Not held at the last tick: it never settled.
            None => format!(
                "the offset reference had not reached the held offset by the end of the run, t = {} s (raise --t-end)",
                numbers::sig(t_end)
            ),
        })
    } else if s.phase_error_deg_rms.is_nan() || s.phase_error_deg_rms > HELD_ERROR_DEG_RMS {
        Some(format!(
            "phase error {} deg RMS over the second half (held offsets stay within {} deg)",
            numbers::sig(s.phase_error_deg_rms),
            numbers::sig(HELD_ERROR_DEG_RMS)
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
    progress: &Progress,
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
