//! Running a scenario and judging it: simulate with the [`ScenarioDriver`], then
//! every expectation on the recorded ticks ([`Outcome`]) and the first fault latched
//! after each injection ([`Detection`]), into a [`Report`].

use shared::controller::{Bridge, Direction, Faults, Outputs, State};

use super::driver::ScenarioDriver;
use super::driver::Tick;
use super::file::window;
use super::file::Expectation;
use super::file::Scenario;
use super::file::When;
use super::file::TIME_EPS;
use crate::numbers::sig;
use crate::plant::progress::Stop;
use crate::simulation::breach::Breach;
use crate::simulation::{simulate_observed, Driver, Interruptible, Observer, RunOptions};

/// How one expectation came out.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// Its key path, `expect[0]`.
    pub key: String,
    /// Its kind, `state`, `fault`, ...
    pub kind: &'static str,
    /// Whether it holds.
    pub pass: bool,
    /// What it asks, in words.
    pub expected: String,
    /// What the run did, in words.
    pub measured: String,
}

/// The first fault latched at or after an injection's start.
#[derive(Clone, Debug, PartialEq)]
pub struct Detection {
    /// The injection's key path, `faults[0]`.
    pub key: String,
    /// What was injected, `encoder_dropout rotor 1`.
    pub injected: String,
    /// Its start, s.
    pub t: f64,
    /// The faults newly latched at the first tick that latched any, and that
    /// tick's time, s; `None` if none was latched to the end.
    pub latched: Option<(Vec<String>, f64)>,
}

/// What running a scenario produced.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// The scenario file, as named.
    pub scenario: String,
    /// The machine file, resolved.
    pub machine: String,
    /// End time, s.
    pub t_end: f64,
    /// One per expectation, in file order.
    pub outcomes: Vec<Outcome>,
    /// One per injected fault, in file order.
    pub detections: Vec<Detection>,
    /// The controller's state at the end.
    pub final_state: State,
    /// Why the run ended early, if it did (nothing judged): Ctrl-C, or a plant
    /// that stopped advancing.
    pub stopped: Option<Stop>,
    /// The run's warnings (`host-sim run`'s): a body through the fundament, a
    /// Painleve configuration, ...
    pub warnings: Vec<String>,
}

impl Report {
    /// Every expectation holds.
    pub fn passed(&self) -> bool {
        self.outcomes.iter().all(|o| o.pass)
    }
}

/// Runs `scenario` with the controller in the loop (stages of the module doc),
/// on the parameters its check read.
pub fn run(scenario: &Scenario) -> Report {
    let mut driver = ScenarioDriver::controller(scenario);
    run_observed(scenario, &mut driver, &mut Interruptible::new())
}

/// Runs `scenario` with `driver`, `observer` watching the simulation (the
/// animation's frames) and deciding whether it goes on.
pub fn run_observed(
    scenario: &Scenario,
    driver: &mut ScenarioDriver<'_>,
    observer: &mut dyn Observer,
) -> Report {
    // 1.-3. Simulate with the scenario's driver.
    let mut options = RunOptions::new(scenario.t_end);
    options.keep_rows = false;
    options.keep_events = false;
    let result = simulate_observed(&scenario.machine, driver, &options, observer);
    let mut samples: Vec<(f64, f64)> = driver.ticks.iter().map(|k| (k.t, k.x)).collect();
    if let Some(row) = result.last_row {
        if samples.last().is_none_or(|s| s.0 < row.t) {
            samples.push((row.t, row.x));
        }
    }
    let ticks = &driver.ticks;

    // 4. Judge.
    let outcomes = scenario
        .expectations
        .iter()
        .map(|(key, e)| {
            let run = Run {
                ticks,
                samples: &samples,
                breaches: &result.summary.breaches,
                t_end: scenario.t_end,
            };
            let (pass, expected, measured) = judge(e, &run);
            Outcome {
                key: key.clone(),
                kind: e.kind(),
                pass,
                expected,
                measured,
            }
        })
        .collect();
    let detections = scenario
        .faults
        .iter()
        .map(|f| Detection {
            key: f.key.clone(),
            injected: f.fault.describe(),
            t: f.t,
            latched: first_latch_after(ticks, f.t),
        })
        .collect();
    Report {
        scenario: scenario.file.clone(),
        machine: scenario.machine_file.display().to_string(),
        t_end: scenario.t_end,
        outcomes,
        detections,
        final_state: driver.last_tick().map_or(State::Idle, |c| c.state()),
        stopped: result.stopped,
        warnings: result.summary.warnings,
    }
}

/// Whether the tick at `t` lies in `w` (ends included).
fn in_window(t: f64, w: [f64; 2]) -> bool {
    t >= w[0] - TIME_EPS && t <= w[1] + TIME_EPS
}

/// The ticks in `w`.
fn ticks_in(ticks: &[Tick], w: [f64; 2]) -> impl Iterator<Item = &Tick> + '_ {
    ticks.iter().filter(move |k| in_window(k.t, w))
}

/// Safe outputs: driver disabled, both bridges off (duty 0 on both motors).
fn is_safe(out: &Outputs) -> bool {
    out.bridges == [Bridge::Off; 2]
}

/// `x(t)` interpolated linearly between samples (held beyond them).
pub(crate) fn x_at(samples: &[(f64, f64)], t: f64) -> f64 {
    let i = samples.partition_point(|s| s.0 < t);
    match (
        i.checked_sub(1).and_then(|j| samples.get(j)),
        samples.get(i),
    ) {
        (Some(a), Some(b)) if b.0 > a.0 => a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0),
        (_, Some(b)) => b.1,
        (Some(a), None) => a.1,
        (None, None) => 0.0,
    }
}

/// Whether `o` lies in the circular range from `r[0]` up to `r[1]`, degrees.
pub(crate) fn in_phase_range(o: f64, r: [f64; 2]) -> bool {
    (o - r[0]).rem_euclid(360.0) <= r[1] - r[0] + 1e-9
}

/// The faults newly latched at the first tick at or after `t0` that latched any.
fn first_latch_after(ticks: &[Tick], t0: f64) -> Option<(Vec<String>, f64)> {
    let mut before = Faults::NONE;
    for k in ticks {
        let new = k.out.faults.without(before);
        if k.t >= t0 - TIME_EPS && !new.is_empty() {
            return Some((new.names().map(str::to_string).collect(), k.t));
        }
        before = k.out.faults;
    }
    None
}

/// What an expectation asks and what the run did: (pass, expected, measured).
type Verdict = (bool, String, String);

/// What the expectations are judged on.
struct Run<'r> {
    /// The control ticks.
    ticks: &'r [Tick],
    /// The platform's `x` at every tick and at the end, `(t, x)`.
    samples: &'r [(f64, f64)],
    /// The bodies through the fundament or tipped over, by time.
    breaches: &'r [Breach],
    /// End time, s.
    t_end: f64,
}

/// Judges one expectation on the run.
fn judge(e: &Expectation, run: &Run<'_>) -> Verdict {
    let (ticks, t_end) = (run.ticks, run.t_end);
    match e {
        Expectation::State { state, when } => judge_state(*state, when, ticks),
        Expectation::Travel {
            direction,
            between,
            min_speed,
        } => judge_travel(*direction, *between, *min_speed, run),
        Expectation::Speed {
            rotors,
            range_rpm,
            between,
        } => judge_speed(rotors, *range_rpm, *between, ticks),
        Expectation::Phase { range_deg, when } => judge_phase(*range_deg, when, ticks),
        Expectation::Fault {
            fault,
            name,
            within,
        } => judge_fault(*fault, name, *within, ticks, t_end),
        Expectation::NoFault { between } => judge_no_fault(between.unwrap_or([0.0, t_end]), ticks),
        Expectation::Safe { between } => judge_safe(*between, ticks),
        Expectation::Breach {
            fundament,
            body,
            within,
        } => judge_breach(
            *fundament,
            body.as_deref(),
            within.unwrap_or([0.0, t_end]),
            run.breaches,
        ),
    }
}

/// `no control tick in [t0, t1] s`: a window between two ticks judges nothing.
fn none_in(w: [f64; 2]) -> String {
    format!("no control tick in {}", window(w))
}

/// The state at some tick (reached), or at every tick, of the window.
fn judge_state(state: State, when: &When, ticks: &[Tick]) -> Verdict {
    let expected = format!("{} {}", state.name(), when.describe());
    let (pass, measured) = match when {
        When::Within(w) => match ticks_in(ticks, *w).find(|k| k.out.state == state) {
            Some(k) => (true, format!("reached at {} s", sig(k.t))),
            None => {
                let seen = states_seen(ticks_in(ticks, *w));
                (false, format!("not reached; states in the window: {seen}"))
            }
        },
        When::Between(w) => {
            let mut inside = ticks_in(ticks, *w).peekable();
            if inside.peek().is_none() {
                (false, none_in(*w))
            } else {
                match inside.find(|k| k.out.state != state) {
                    Some(k) => (false, format!("{} at {} s", k.out.state.name(), sig(k.t))),
                    None => (true, format!("{} throughout", state.name())),
                }
            }
        }
    };
    (pass, expected, measured)
}

/// The sign and size of the mean velocity over the window; none if a body went
/// through the fundament or tipped over by the window's end.
fn judge_travel(direction: Direction, between: [f64; 2], min_speed: f64, run: &Run<'_>) -> Verdict {
    let samples = run.samples;
    let (name, sign) = match direction {
        Direction::Right => ("right", 1.0),
        Direction::Left => ("left", -1.0),
    };
    let expected = format!(
        "{name}: mean velocity {}{} mm/s or more over {}",
        if sign > 0.0 { "+" } else { "-" },
        sig(min_speed * 1e3),
        window(between)
    );
    if let Some(b) = run.breaches.first().filter(|b| b.t <= between[1]) {
        return (false, expected, format!("not a travel: {}", b.short()));
    }
    let v = (x_at(samples, between[1]) - x_at(samples, between[0])) / (between[1] - between[0]);
    let pass = v * sign >= min_speed && v * sign > 0.0;
    (pass, expected, format!("{:+.2} mm/s", v * 1e3))
}

/// A body (`body`, or any) through the fundament (`fundament`) or tipped over,
/// first found in the window.
fn judge_breach(
    fundament: bool,
    body: Option<&str>,
    within: [f64; 2],
    breaches: &[Breach],
) -> Verdict {
    let what = if fundament {
        "through the fundament"
    } else {
        "tipped over (turned past simulation.max_tilt)"
    };
    let who = body.map_or("a body".to_string(), str::to_string);
    let expected = format!(
        "{who} {what}, first at some trace row in {}",
        window(within)
    );
    let mut found = breaches
        .iter()
        .filter(|b| b.through_fundament() == fundament && body.is_none_or(|n| b.body == n));
    let (pass, measured) = match found.clone().find(|b| in_window(b.t, within)) {
        Some(b) => (true, b.short()),
        None => match found.next() {
            Some(b) => (false, format!("{} (outside the window)", b.short())),
            None => (
                false,
                format!(
                    "none: no {}",
                    if fundament {
                        "body went through the fundament"
                    } else {
                        "free body tipped over"
                    }
                ),
            ),
        },
    };
    (pass, expected, measured)
}

/// The rotors' measured speeds at every tick of the window.
fn judge_speed(
    rotors: &[usize],
    range_rpm: [f64; 2],
    between: [f64; 2],
    ticks: &[Tick],
) -> Verdict {
    let names: Vec<String> = rotors.iter().map(|r| (r + 1).to_string()).collect();
    let expected = format!(
        "rotor {} in [{}, {}] rpm at every tick in {}",
        names.join(" and "),
        sig(range_rpm[0]),
        sig(range_rpm[1]),
        window(between)
    );
    let mut parts = Vec::new();
    let mut pass = true;
    for &r in rotors {
        let speeds: Vec<(f64, f64)> = ticks_in(ticks, between)
            .map(|k| (k.t, f64::from(k.out.telemetry.speed_rpm[r])))
            .collect();
        if speeds.is_empty() {
            return (false, expected, none_in(between));
        }
        let lo = speeds.iter().map(|s| s.1).fold(f64::INFINITY, f64::min);
        let hi = speeds.iter().map(|s| s.1).fold(f64::NEG_INFINITY, f64::max);
        let mut part = format!("rotor {}: {:.1} to {:.1} rpm", r + 1, lo, hi);
        let out = speeds
            .iter()
            .find(|s| !(s.1 >= range_rpm[0] && s.1 <= range_rpm[1]));
        if let Some(s) = out {
            pass = false;
            part.push_str(&format!(" (first out at {} s: {:.1})", sig(s.0), s.1));
        }
        parts.push(part);
    }
    (pass, expected, parts.join("; "))
}

/// The measured phase offset at some tick, or at every tick, of the window.
fn judge_phase(range_deg: [f64; 2], when: &When, ticks: &[Tick]) -> Verdict {
    let expected = format!(
        "offset in [{}, {}] deg {}",
        sig(range_deg[0]),
        sig(range_deg[1]),
        when.describe()
    );
    let offset = |k: &Tick| {
        k.out
            .telemetry
            .phase_valid
            .then_some(f64::from(k.out.telemetry.phase_offset_deg))
    };
    let (pass, measured) = match when {
        When::Within(w) => {
            let hit = ticks_in(ticks, *w).find_map(|k| {
                offset(k)
                    .filter(|o| in_phase_range(*o, range_deg))
                    .map(|o| (k.t, o))
            });
            match hit {
                Some((t, o)) => (true, format!("{o:.1} deg at {} s", sig(t))),
                None => (false, "never in the range in the window".to_string()),
            }
        }
        When::Between(w) => {
            let inside: Vec<&Tick> = ticks_in(ticks, *w).collect();
            let bad = inside
                .iter()
                .find(|k| !offset(k).is_some_and(|o| in_phase_range(o, range_deg)));
            match (inside.first(), bad) {
                (None, _) => (false, none_in(*w)),
                (_, Some(k)) => match offset(k) {
                    Some(o) => (false, format!("{o:.1} deg at {} s", sig(k.t))),
                    None => (
                        false,
                        format!("not measured at {} s (no index yet)", sig(k.t)),
                    ),
                },
                (Some(first), None) => {
                    let last = inside.last().map_or(first, |k| k);
                    (
                        true,
                        format!(
                            "in range throughout ({:.1} deg at {} s, {:.1} deg at {} s)",
                            offset(first).unwrap_or(0.0),
                            sig(first.t),
                            offset(last).unwrap_or(0.0),
                            sig(last.t)
                        ),
                    )
                }
            }
        }
    };
    (pass, expected, measured)
}

/// The fault newly latched in the window, and safe outputs while it stays latched.
fn judge_fault(fault: Faults, name: &str, within: [f64; 2], ticks: &[Tick], t_end: f64) -> Verdict {
    let expected = format!(
        "{name} latched at some tick in {}, outputs safe while latched",
        window(within)
    );
    // Rising edges of the flag.
    let edges: Vec<usize> = (0..ticks.len())
        .filter(|&i| {
            ticks[i].out.faults.contains(fault)
                && (i == 0 || !ticks[i - 1].out.faults.contains(fault))
        })
        .collect();
    let Some(&i) = edges.iter().find(|&&i| in_window(ticks[i].t, within)) else {
        let elsewhere = match edges.first() {
            Some(&i) => format!(" (latched at {} s)", sig(ticks[i].t)),
            None => format!(" (never latched; faults seen: {})", faults_seen(ticks)),
        };
        return (
            false,
            expected,
            format!("not latched in the window{elsewhere}"),
        );
    };
    let held: Vec<&Tick> = ticks[i..]
        .iter()
        .take_while(|k| k.out.faults.contains(fault))
        .collect();
    let latched = format!("latched at {} s", sig(ticks[i].t));
    match held.iter().find(|k| !is_safe(&k.out)) {
        Some(k) => (
            false,
            expected,
            format!(
                "{latched}, but not safe at {} s (enable {}, duty [{:.3}, {:.3}])",
                sig(k.t),
                k.out.drives(),
                k.out.duties()[0],
                k.out.duties()[1]
            ),
        ),
        None => {
            let until = match ticks.get(i + held.len()) {
                Some(k) => format!("until cleared at {} s", sig(k.t)),
                None => format!("to the end ({} s)", sig(t_end)),
            };
            (true, expected, format!("{latched}, safe {until}"))
        }
    }
}

/// No fault at any tick of the window.
fn judge_no_fault(w: [f64; 2], ticks: &[Tick]) -> Verdict {
    let expected = format!("no fault at any tick in {}", window(w));
    match ticks_in(ticks, w).find(|k| !k.out.faults.is_empty()) {
        Some(k) => (
            false,
            expected,
            format!("{} at {} s", k.out.faults, sig(k.t)),
        ),
        None => (true, expected, "none".to_string()),
    }
}

/// Safe outputs at every tick of the window.
fn judge_safe(between: [f64; 2], ticks: &[Tick]) -> Verdict {
    let expected = format!("enable off and duty 0 at every tick in {}", window(between));
    let mut inside = ticks_in(ticks, between).peekable();
    if inside.peek().is_none() {
        return (false, expected, none_in(between));
    }
    match inside.find(|k| !is_safe(&k.out)) {
        Some(k) => (
            false,
            expected,
            format!(
                "{} at {} s: enable {}, duty [{:.3}, {:.3}]",
                k.out.state.name(),
                sig(k.t),
                k.out.drives(),
                k.out.duties()[0],
                k.out.duties()[1]
            ),
        ),
        None => (true, expected, "safe throughout".to_string()),
    }
}

/// The states of `ticks` in order of appearance, each with the time it first
/// shows: `starting (0 s), running (0.71 s)`.
fn states_seen<'a>(ticks: impl Iterator<Item = &'a Tick>) -> String {
    let mut seen: Vec<(State, f64)> = Vec::new();
    for k in ticks {
        if seen.last().is_none_or(|s| s.0 != k.out.state) {
            seen.push((k.out.state, k.t));
        }
    }
    if seen.is_empty() {
        return "none (no control tick)".to_string();
    }
    seen.iter()
        .map(|(s, t)| format!("{} ({} s)", s.name(), sig(*t)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Every fault latched during the run, with the time it was first latched.
fn faults_seen(ticks: &[Tick]) -> String {
    let mut seen: Vec<String> = Vec::new();
    let mut before = Faults::NONE;
    for k in ticks {
        for name in k.out.faults.without(before).names() {
            seen.push(format!("{name} at {} s", sig(k.t)));
        }
        before = k.out.faults;
    }
    if seen.is_empty() {
        "none".to_string()
    } else {
        seen.join(", ")
    }
}
