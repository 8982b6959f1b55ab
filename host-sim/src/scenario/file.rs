//! Scenario files: a machine, a timed list of commands to the controller and of
//! faults injected into the simulation, and expectations on what the controller and
//! the platform do; `docs/scenarios.md` gives every key, default and rule.
//!
//! ```toml
//! machine = "../../examples/vibro-driver.toml"   # relative to the scenario file
//! t_end = 4.0
//!
//! [[commands]]
//! t = 0.0
//! command = "right"
//! speed_rpm = 3000
//!
//! [[faults]]
//! t = 2.0
//! kind = "encoder_dropout"
//! rotor = 1
//!
//! [[expect]]
//! kind = "fault"
//! fault = "encoder"
//! within = [2.0, 2.4]
//! ```
//!
//! Reading a scenario ([`load`]):
//! 1. read and parse the TOML ([`crate::machine::input`]);
//! 2. every key on its own, with its key path (`faults[1].kind`), unknown keys with a
//!    "did you mean";
//! 3. the machine file, relative to the scenario file, with the scenario's `set`
//!    overrides ([`Machine::load`]) and its controller parameters;
//! 4. what needs the machine: times within `t_end` (default the machine's
//!    `simulation.t_end`), at most one command per control tick, the run speed of a
//!    command (default the machine's `controller.speed_rpm`); on a machine with
//!    one rotor, no rotor 2 in a fault or a speed expectation and no phase
//!    expectation (its controller holds speed only);
//! 5. every problem at once.

//!
//! Running it: [`super::judge::run`].

use std::path::{Path, PathBuf};

use shared::controller::{Command, Direction, Faults, Params, State};
use shared::Enumerated;
use toml::{Table, Value};

use crate::machine::input::{self, Limit, Location, Need, Problem, Problems, Section};
use crate::machine::kind::{self, FileKind};
use crate::machine::set::{Origin, Override};
use crate::machine::Machine;
use crate::numbers::{sig, signed};
use crate::simulation::closed_loop;

/// A command a scenario can send, as written in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandName {
    /// Travel right.
    Right,
    /// Travel left.
    Left,
    /// Stop.
    Stop,
    /// Hold an offset.
    Hold,
    /// Reset the latched faults.
    Reset,
    /// Heartbeat.
    Heartbeat,
}

impl Enumerated for CommandName {
    const ALL: &'static [CommandName] = &[
        CommandName::Right,
        CommandName::Left,
        CommandName::Stop,
        CommandName::Hold,
        CommandName::Reset,
        CommandName::Heartbeat,
    ];

    fn name(self) -> &'static str {
        match self {
            CommandName::Right => "right",
            CommandName::Left => "left",
            CommandName::Stop => "stop",
            CommandName::Hold => "hold",
            CommandName::Reset => "reset",
            CommandName::Heartbeat => "heartbeat",
        }
    }
}

/// A fault a scenario can inject, as written in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultKind {
    /// A rotor's encoder cut.
    EncoderDropout,
    /// A rotor held still.
    JammedRotor,
    /// The supply voltage dropped.
    SupplySag,
    /// An offset on a rotor's current measurement.
    CurrentOffset,
    /// The host's commands lost.
    LostCommands,
    /// The E-stop pressed.
    Estop,
    /// Control ticks started late.
    LateTicks,
}

impl Enumerated for FaultKind {
    const ALL: &'static [FaultKind] = &[
        FaultKind::EncoderDropout,
        FaultKind::JammedRotor,
        FaultKind::SupplySag,
        FaultKind::CurrentOffset,
        FaultKind::LostCommands,
        FaultKind::Estop,
        FaultKind::LateTicks,
    ];

    fn name(self) -> &'static str {
        match self {
            FaultKind::EncoderDropout => "encoder_dropout",
            FaultKind::JammedRotor => "jammed_rotor",
            FaultKind::SupplySag => "supply_sag",
            FaultKind::CurrentOffset => "current_offset",
            FaultKind::LostCommands => "lost_commands",
            FaultKind::Estop => "estop",
            FaultKind::LateTicks => "late_ticks",
        }
    }
}

/// A kind of expectation, as written in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExpectKind {
    /// The controller in a state.
    State,
    /// Travel one way.
    Travel,
    /// The rotors at a speed.
    Speed,
    /// The phase offset in a range.
    Phase,
    /// A fault latched.
    Fault,
    /// No fault latched.
    NoFault,
    /// The motors safe.
    Safe,
    /// A body through the fundament.
    ThroughFundament,
    /// A body tipped over.
    TippedOver,
}

impl Enumerated for ExpectKind {
    const ALL: &'static [ExpectKind] = &[
        ExpectKind::State,
        ExpectKind::Travel,
        ExpectKind::Speed,
        ExpectKind::Phase,
        ExpectKind::Fault,
        ExpectKind::NoFault,
        ExpectKind::Safe,
        ExpectKind::ThroughFundament,
        ExpectKind::TippedOver,
    ];

    fn name(self) -> &'static str {
        match self {
            ExpectKind::State => "state",
            ExpectKind::Travel => "travel",
            ExpectKind::Speed => "speed",
            ExpectKind::Phase => "phase",
            ExpectKind::Fault => "fault",
            ExpectKind::NoFault => "no_fault",
            ExpectKind::Safe => "safe",
            ExpectKind::ThroughFundament => "through_fundament",
            ExpectKind::TippedOver => "tipped_over",
        }
    }
}

/// A controller state an expectation may name: all but the self-test, which a
/// scenario never starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExpectedState(pub State);

impl Enumerated for ExpectedState {
    const ALL: &'static [ExpectedState] = &[
        ExpectedState(State::Idle),
        ExpectedState(State::Starting),
        ExpectedState(State::Running),
        ExpectedState(State::Stopping),
        ExpectedState(State::Fault),
    ];

    fn name(self) -> &'static str {
        self.0.name()
    }
}

/// Default `min_speed` of a travel expectation, m/s: 1 mm/s, far above the drift
/// of a platform that only rattles in place (the reference machine standing still
/// moves by nothing; at the vertical-force offset 180 degrees, by well under
/// 0.1 mm/s) and far below the 29 mm/s it travels at 3000 rpm.
pub const DEFAULT_MIN_TRAVEL_SPEED: f64 = 1.0e-3;

/// Slack on times when deciding whether a control tick lies in a window, s: ticks
/// are `k / rate_hz` in floating point, a window's ends decimal numbers.
pub(crate) const TIME_EPS: f64 = 1.0e-9;

/// A command to the controller at a time.
#[derive(Clone, Debug, PartialEq)]
pub struct TimedCommand {
    /// When, s: sent at the first control tick at or after it.
    pub t: f64,
    /// The command (run speeds resolved).
    pub command: Command,
    /// Its key path in the file (`commands[0]`).
    pub key: String,
    /// Its name in the file (`right`, `reset`, ...).
    pub name: &'static str,
}

/// A fault injected into the simulation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InjectedFault {
    /// The encoder of rotor `rotor` (0 or 1) loses its signals: the counter
    /// stops, no index pulse.
    EncoderDropout {
        /// Rotor index, 0 or 1.
        rotor: usize,
    },
    /// Rotor `rotor` (0 or 1) seizes: it stops at once relative to the platform
    /// and stays at rest ([`crate::plant::simulator::Plant::set_jam`]).
    JammedRotor {
        /// Rotor index, 0 or 1.
        rotor: usize,
    },
    /// The supply sags (or rises) to `voltage`, V: the controller measures it and
    /// the H-bridges put `duty x voltage` on the windings.
    SupplySag {
        /// Supply voltage, V, >= 0.
        voltage: f64,
    },
    /// The current measurement of rotor `rotor` (0 or 1) reads `amps` too high.
    CurrentOffset {
        /// Rotor index, 0 or 1.
        rotor: usize,
        /// Offset added to the measurement, A.
        amps: f64,
    },
    /// Commands and heartbeats from the host are lost (a command due meanwhile is
    /// lost, not delayed).
    LostCommands,
    /// The E-stop input is active.
    Estop,
    /// The control ticks start `late_us` microseconds after their nominal time
    /// (the tick timing the firmware measures: a starved loop on the board).
    LateTicks {
        /// Lateness, us, >= 0.
        late_us: f64,
    },
}

impl InjectedFault {
    /// Its kind as written in the file.
    pub fn kind(&self) -> &'static str {
        match self {
            InjectedFault::EncoderDropout { .. } => "encoder_dropout",
            InjectedFault::JammedRotor { .. } => "jammed_rotor",
            InjectedFault::SupplySag { .. } => "supply_sag",
            InjectedFault::CurrentOffset { .. } => "current_offset",
            InjectedFault::LostCommands => "lost_commands",
            InjectedFault::Estop => "estop",
            InjectedFault::LateTicks { .. } => "late_ticks",
        }
    }

    /// The rotor it acts on (index 0 or 1), if it acts on one.
    pub fn rotor(&self) -> Option<usize> {
        match self {
            InjectedFault::EncoderDropout { rotor }
            | InjectedFault::JammedRotor { rotor }
            | InjectedFault::CurrentOffset { rotor, .. } => Some(*rotor),
            _ => None,
        }
    }

    /// A short description: `encoder_dropout rotor 1`, `supply_sag 8 V`.
    pub fn describe(&self) -> String {
        match self {
            InjectedFault::EncoderDropout { rotor } | InjectedFault::JammedRotor { rotor } => {
                format!("{} rotor {}", self.kind(), rotor + 1)
            }
            InjectedFault::SupplySag { voltage } => format!("supply_sag {} V", sig(*voltage)),
            InjectedFault::CurrentOffset { rotor, amps } => {
                format!("current_offset rotor {} {} A", rotor + 1, signed(*amps))
            }
            InjectedFault::LostCommands | InjectedFault::Estop => self.kind().to_string(),
            InjectedFault::LateTicks { late_us } => format!("late_ticks {} us", sig(*late_us)),
        }
    }
}

/// A fault injected over a time window.
#[derive(Clone, Debug, PartialEq)]
pub struct Injection {
    /// Start, s: in force from the first control tick at or after it.
    pub t: f64,
    /// End, s (`t + duration`): gone from the first control tick at or after it;
    /// `None` until the end of the run.
    pub until: Option<f64>,
    /// What is injected.
    pub fault: InjectedFault,
    /// Its key path in the file (`faults[0]`).
    pub key: String,
}

impl Injection {
    /// Whether it is in force at the control tick at `t`.
    pub fn active(&self, t: f64) -> bool {
        t >= self.t - TIME_EPS && self.until.is_none_or(|u| t < u - TIME_EPS)
    }
}

/// When a condition is judged: at some tick of a window, or at every tick of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum When {
    /// `within = [t0, t1]`: at some control tick in the window (ends included).
    Within([f64; 2]),
    /// `between = [t0, t1]`: at every control tick in the window (ends included).
    Between([f64; 2]),
}

impl When {
    /// `at some tick in [0, 1.5] s` or `at every tick in [2, 4] s`.
    pub(crate) fn describe(&self) -> String {
        match self {
            When::Within(w) => format!("at some tick in {}", window(*w)),
            When::Between(w) => format!("at every tick in {}", window(*w)),
        }
    }
}

/// What a scenario expects.
#[derive(Clone, Debug, PartialEq)]
pub enum Expectation {
    /// The controller is in `state` (at some tick, or at every tick, of a window).
    State {
        /// The state.
        state: State,
        /// When.
        when: When,
    },
    /// The platform travels `direction`: its mean velocity `(x(t1) - x(t0)) / (t1 -
    /// t0)` has that sign and at least `min_speed` m/s.
    Travel {
        /// Which way.
        direction: Direction,
        /// The window `[t0, t1]`, s.
        between: [f64; 2],
        /// Least |mean velocity|, m/s.
        min_speed: f64,
    },
    /// The controller's measured (filtered) speed of each rotor named stays in
    /// `range_rpm` at every tick of the window.
    Speed {
        /// Rotor indices (0, 1), both when the file names none.
        rotors: Vec<usize>,
        /// `[low, high]`, rpm, in the driven sense.
        range_rpm: [f64; 2],
        /// The window `[t0, t1]`, s.
        between: [f64; 2],
    },
    /// The measured phase offset `theta_1 - theta_2` lies in the circular range
    /// from `range_deg[0]` up to `range_deg[1]` (at some tick, or at every tick).
    Phase {
        /// `[from, to]`, degrees, `from <= to < from + 360`.
        range_deg: [f64; 2],
        /// When.
        when: When,
    },
    /// `fault` is newly latched at some tick of `within`, and from that tick the
    /// outputs are safe (enable off, duty 0) for as long as it stays latched.
    Fault {
        /// The fault flag.
        fault: Faults,
        /// Its name.
        name: &'static str,
        /// The window, s.
        within: [f64; 2],
    },
    /// No fault is latched at any tick of the window (the whole run when `None`).
    NoFault {
        /// The window, s.
        between: Option<[f64; 2]>,
    },
    /// The outputs are safe (enable off, duty 0 on both motors) at every tick of
    /// the window (`from = t` is `[t, t_end]`).
    Safe {
        /// The window, s.
        between: [f64; 2],
    },
    /// A body went through the fundament (`through_fundament`), or a free body
    /// tipped over (`tipped_over`), first found at a trace row in the window
    /// ([`crate::simulation::breach`]).
    Breach {
        /// Through the fundament, else tipped over.
        fundament: bool,
        /// The body, by name; any body when `None`.
        body: Option<String>,
        /// The window, s (the whole run when `None`).
        within: Option<[f64; 2]>,
    },
}

impl Expectation {
    /// Its kind as written in the file.
    pub fn kind(&self) -> &'static str {
        match self {
            Expectation::State { .. } => "state",
            Expectation::Travel { .. } => "travel",
            Expectation::Speed { .. } => "speed",
            Expectation::Phase { .. } => "phase",
            Expectation::Fault { .. } => "fault",
            Expectation::NoFault { .. } => "no_fault",
            Expectation::Safe { .. } => "safe",
            Expectation::Breach {
                fundament: true, ..
            } => "through_fundament",
            Expectation::Breach { .. } => "tipped_over",
        }
    }
}

/// A checked scenario, ready to run.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// The scenario file, as named.
    pub file: String,
    /// The machine file, resolved against the scenario file's directory.
    pub machine_file: PathBuf,
    /// The machine, with the scenario's overrides applied.
    pub machine: Machine,
    /// The controller's parameters for the machine, its tuning table read once.
    pub params: Params,
    /// The `--set KEY=VALUE` overrides of the machine file (`set`).
    pub sets: Vec<String>,
    /// End time, s.
    pub t_end: f64,
    /// Commands, in time order.
    pub commands: Vec<TimedCommand>,
    /// Injected faults, in file order.
    pub faults: Vec<Injection>,
    /// Expectations, in file order, with their key paths (`expect[0]`).
    pub expectations: Vec<(String, Expectation)>,
}

/// Reads and checks the scenario file at `path` (stages of the module doc): every
/// problem at once, those of the scenario file first, then the machine file's.
pub fn load(path: &Path) -> Result<Scenario, Vec<Problem>> {
    let text = input::read_text(path).map_err(|p| vec![p])?;
    let dir = path.parent().unwrap_or(Path::new(""));
    from_text(&path.display().to_string(), &text, dir)
}

/// Checks the text of a scenario file named `file` (for messages) whose machine
/// path is relative to `dir`, as [`load`] does.
pub fn from_text(file: &str, text: &str, dir: &Path) -> Result<Scenario, Vec<Problem>> {
    // 1. TOML.
    let table = input::parse(file, text).map_err(|p| vec![p])?;
    if let Some(p) = kind::wrong_kind(file, &table, FileKind::Scenario) {
        return Err(vec![p]);
    }

    // 2. Every key on its own.
    let problems = Problems::new(file);
    let raw = read(&table, &problems);

    // 3. The machine, only with its overrides all read (else it is another machine).
    let (machine, machine_problems) = match (&raw.machine, &raw.sets) {
        (Some(rel), Some(sets)) => load_machine(&dir.join(rel), sets, file, &problems),
        _ => (None, Vec::new()),
    };

    // 4. What needs the machine.
    let scenario = resolve(raw, machine, &problems);

    // 5. Every problem.
    let mut all = problems.into_vec();
    all.extend(machine_problems);
    match scenario {
        Some(s) if all.is_empty() => Ok(s),
        _ => {
            if all.is_empty() {
                all.push(Problem {
                    file: file.to_string(),
                    location: Location::File,
                    message: "internal error: the scenario was refused without a reason".into(),
                });
            }
            Err(all)
        }
    }
}

/// The machine file as stage 3 found it: where, the machine, and its
/// controller's parameters.
type LoadedMachine = (PathBuf, Machine, Params);

/// Stage 3: the machine file at `path` (the scenario's `machine`) with the
/// scenario's overrides `sets`, and its controller's parameters. A path that is
/// no file is a problem of the scenario's `machine`; the machine file's own
/// problems are returned apart (a `set` entry's at the scenario's `set[i]`), to
/// follow the scenario's.
fn load_machine(
    path: &Path,
    sets: &[String],
    file: &str,
    problems: &Problems,
) -> (Option<LoadedMachine>, Vec<Problem>) {
    if !path.is_file() {
        let what = if path.is_dir() {
            "is a directory, not a machine file"
        } else if path.exists() {
            "is not a regular file"
        } else {
            "no such file"
        };
        problems.at(
            "machine",
            format!(
                "{what}: {} (the path is relative to the scenario file)",
                path.display()
            ),
        );
        return (None, Vec::new());
    }
    // A refused entry of `set` is said at its key, `set[i]`.
    let overrides: Vec<Override> = sets
        .iter()
        .enumerate()
        .map(|(i, arg)| {
            Override::new(
                arg.clone(),
                Origin::Entry {
                    file: file.to_string(),
                    key_path: format!("set[{i}]"),
                },
            )
        })
        .collect();
    match Machine::load_overridden(path, &overrides) {
        Ok(m) => match closed_loop::params(&m) {
            Ok(params) => (Some((path.to_path_buf(), m, params)), Vec::new()),
            Err(ps) => (None, ps),
        },
        Err(ps) => (None, ps),
    }
}

/// A command as read, its speed not yet defaulted.
#[derive(Clone, Copy, Debug, PartialEq)]
enum RawCommand {
    Travel(Direction, Option<f64>),
    Hold(Option<f64>, f64),
    Stop,
    Reset,
    Heartbeat,
}

/// A `[[commands]]` table as read: its time, s, its name and the command.
type ReadCommand = (f64, &'static str, RawCommand);

/// A `[[faults]]` table as read: its start, s, its duration, s (`None`: to the
/// end), and the fault.
type ReadFault = (f64, Option<f64>, InjectedFault);

/// The scenario as read, key by key (`None` where refused).
struct Raw {
    machine: Option<String>,
    t_end: Option<f64>,
    /// `Some(vec![])` without a `set`; `None` when refused.
    sets: Option<Vec<String>>,
    /// The commands, with their key paths.
    commands: Vec<(String, ReadCommand)>,
    /// The faults, with their key paths.
    faults: Vec<(String, ReadFault)>,
    /// The expectations, with their key paths.
    expects: Vec<(String, RawExpect)>,
    /// Some element was refused.
    refused: bool,
}

/// An expectation as read: `from` of a `safe` needs `t_end`.
enum RawExpect {
    Ready(Expectation),
    SafeFrom(f64),
}

/// Stage 2: every key on its own.
fn read(table: &Table, problems: &Problems) -> Raw {
    let root = Section::root(table, problems);
    let machine = root.string("machine", Need::Required);
    let t_end = root.number("t_end", Need::Optional, Limit::Positive);
    let sets = read_sets(&root, table);
    let mut refused = false;
    let commands = read_tables(
        root.sections("commands"),
        "commands",
        read_command,
        &mut refused,
    );
    let faults = read_tables(root.sections("faults"), "faults", read_fault, &mut refused);
    let has_expect = root.has("expect");
    let expects = root.sections("expect");
    let no_expect = expects.as_ref().is_some_and(|e| e.is_empty());
    let expects = read_tables(expects, "expect", read_expect, &mut refused);
    let raw = Raw {
        machine,
        t_end,
        sets,
        commands,
        faults,
        expects,
        refused,
    };
    if no_expect {
        let what = if has_expect { "is empty" } else { "is missing" };
        root.problem(
            "expect",
            format!("{what}: a scenario needs at least one [[expect]] to pass or fail"),
        );
    }
    root.finish();
    raw
}

/// Every table of the array of tables `key` (`commands`, `faults`, `expect`; its
/// `tables` as [`Section::sections`] gives them) read by `read`, with its key
/// path (`commands[0]`); `refused` is set when one was refused.
fn read_tables<T>(
    tables: Option<Vec<Option<Section<'_>>>>,
    key: &str,
    read: impl Fn(&Section<'_>) -> Option<T>,
    refused: &mut bool,
) -> Vec<(String, T)> {
    let mut read_ones = Vec::new();
    for (i, s) in tables.unwrap_or_default().iter().enumerate() {
        match s.as_ref().and_then(&read) {
            Some(value) => read_ones.push((format!("{key}[{i}]"), value)),
            None => *refused = true,
        }
    }
    read_ones
}

/// `set = ["KEY=VALUE", ...]`: an array of strings.
fn read_sets(root: &Section<'_>, table: &Table) -> Option<Vec<String>> {
    if !root.has("set") {
        return Some(Vec::new());
    }
    let Some(Value::Array(items)) = table.get("set") else {
        root.problem(
            "set",
            "must be an array of strings \"KEY=VALUE\" (machine-file overrides, as --set takes)",
        );
        return None;
    };
    let mut sets = Vec::new();
    let mut ok = true;
    for (i, item) in items.iter().enumerate() {
        match item {
            Value::String(s) => sets.push(s.clone()),
            other => {
                root.problem(
                    &format!("set[{i}]"),
                    format!("must be a string \"KEY=VALUE\" (got {other})"),
                );
                ok = false;
            }
        }
    }
    ok.then_some(sets)
}

/// A window `[t0, t1]` with `0 <= t0 <= t1` (`t1 <= t_end` is checked later).
fn read_window(s: &Section<'_>, key: &'static str, need: Need<[f64; 2]>) -> Option<[f64; 2]> {
    if need == Need::Required && !s.has(key) {
        s.problem(key, "missing; required: a time window [t0, t1], s");
        return None;
    }
    let w = s.vec2(key, Need::Optional, Limit::NonNegative)?;
    if w[0] > w[1] {
        s.problem(
            key,
            format!(
                "must be [t0, t1] with t0 <= t1, s (got {})",
                input::vector(w)
            ),
        );
        return None;
    }
    Some(w)
}

/// Reports keys that `kind` does not take when present (and marks them known, so
/// that they are not also reported as unknown).
fn not_for(s: &Section<'_>, keys: &[&'static str], kind: &str, takers: &str) {
    for key in keys {
        if s.has(key) {
            s.problem(key, format!("does not apply to {kind} (only to {takers})"));
        }
    }
}

/// The key `key`, one of `T`'s values, that decides which other keys a table takes
/// (`command`, `kind`). Without its value the other keys cannot be judged: the
/// table is finished (its unknown keys reported) only when the key is missing,
/// since a misspelt key is then among the unknown ones; a value not allowed
/// leaves the other keys unjudged.
fn deciding_choice<T: Enumerated>(s: &Section<'_>, key: &'static str) -> Option<T> {
    let choice = s.one_of(key, Need::Required);
    if choice.is_none() && !s.has(key) {
        s.finish();
    }
    choice
}

/// Of a key and `between`, which exclude each other, the one a table gives.
enum Given<T> {
    /// The other key's value (`within`, `from`).
    Other(T),
    /// `between = [t0, t1]`, s.
    Between([f64; 2]),
}

/// Exactly one of `other` (read by `read_other`) and `between = [t0, t1]`: the
/// one given, `None` when refused. Both given is a problem at `between` (`both`
/// says which to keep), neither a problem of the table (`neither` says what is
/// missing).
fn other_or_between<T>(
    s: &Section<'_>,
    other: &'static str,
    read_other: impl FnOnce(&Section<'_>) -> Option<T>,
    both: &str,
    neither: &str,
) -> Option<Given<T>> {
    let has = (s.has(other), s.has("between"));
    let value = read_other(s);
    let between = read_window(s, "between", Need::Optional);
    match has {
        (true, true) => {
            s.problem("between", both);
            None
        }
        (false, false) => {
            s.problems().at(s.path(), neither);
            None
        }
        (true, false) => value.map(Given::Other),
        (false, true) => between.map(Given::Between),
    }
}

/// A rotor number 1 or 2, as index 0 or 1.
fn read_rotor(s: &Section<'_>, need: Need<i64>) -> Option<usize> {
    s.integer("rotor", need, Limit::Between(1.0, 2.0))
        .map(|r| r as usize - 1)
}

/// One `[[commands]]` table: (t, name, command).
fn read_command(s: &Section<'_>) -> Option<ReadCommand> {
    let t = s.number("t", Need::Required, Limit::NonNegative);
    let command_name: CommandName = deciding_choice(s, "command")?;
    let name = command_name.name();
    let command = match command_name {
        CommandName::Right | CommandName::Left | CommandName::Hold => {
            let speed = s.number("speed_rpm", Need::Optional, Limit::Positive);
            let speed_ok = speed.is_some() || !s.has("speed_rpm");
            if command_name == CommandName::Hold {
                let offset = s.number("offset_deg", Need::Required, Limit::Any);
                offset
                    .filter(|_| speed_ok)
                    .map(|o| RawCommand::Hold(speed, o))
            } else {
                not_for(s, &["offset_deg"], "command right or left", "command hold");
                let d = if command_name == CommandName::Right {
                    Direction::Right
                } else {
                    Direction::Left
                };
                speed_ok.then_some(RawCommand::Travel(d, speed))
            }
        }
        _ => {
            not_for(
                s,
                &["speed_rpm", "offset_deg"],
                &format!("command {name}"),
                "commands right, left and hold",
            );
            Some(match command_name {
                CommandName::Stop => RawCommand::Stop,
                CommandName::Reset => RawCommand::Reset,
                _ => RawCommand::Heartbeat,
            })
        }
    };
    s.finish();
    Some((t?, name, command?))
}

/// One `[[faults]]` table: (t, duration, fault).
fn read_fault(s: &Section<'_>) -> Option<ReadFault> {
    let t = s.number("t", Need::Required, Limit::NonNegative);
    let kind: FaultKind = deciding_choice(s, "kind")?;
    let duration = s.number("duration", Need::Optional, Limit::Positive);
    let duration_ok = duration.is_some() || !s.has("duration");
    let fault = match kind {
        FaultKind::EncoderDropout => {
            read_rotor(s, Need::Required).map(|rotor| InjectedFault::EncoderDropout { rotor })
        }
        FaultKind::JammedRotor => {
            read_rotor(s, Need::Required).map(|rotor| InjectedFault::JammedRotor { rotor })
        }
        FaultKind::SupplySag => s
            .number("voltage", Need::Required, Limit::NonNegative)
            .map(|voltage| InjectedFault::SupplySag { voltage }),
        FaultKind::CurrentOffset => {
            let rotor = read_rotor(s, Need::Required);
            let amps = s.number("amps", Need::Required, Limit::Any);
            rotor
                .zip(amps)
                .map(|(rotor, amps)| InjectedFault::CurrentOffset { rotor, amps })
        }
        FaultKind::LostCommands => Some(InjectedFault::LostCommands),
        FaultKind::LateTicks => s
            .number("late_us", Need::Required, Limit::NonNegative)
            .map(|late_us| InjectedFault::LateTicks { late_us }),
        FaultKind::Estop => Some(InjectedFault::Estop),
    };
    s.finish();
    let fault = fault?;
    duration_ok.then_some(())?;
    Some((t?, duration, fault))
}

/// `within` or `between`, exactly one.
fn read_when(s: &Section<'_>) -> Option<When> {
    let given = other_or_between(
        s,
        "within",
        |s| read_window(s, "within", Need::Optional),
        "give either `within` (at some tick) or `between` (at every tick), not both",
        "missing `within = [t0, t1]` (at some tick) or `between = [t0, t1]` (at every tick)",
    )?;
    Some(match given {
        Given::Other(w) => When::Within(w),
        Given::Between(w) => When::Between(w),
    })
}

/// One `[[expect]]` table.
fn read_expect(s: &Section<'_>) -> Option<RawExpect> {
    let kind: ExpectKind = deciding_choice(s, "kind")?;
    let e = read_expect_keys(s, kind);
    s.finish();
    e
}

/// The keys of an `[[expect]]` of `kind`, each kind's by its own reader.
fn read_expect_keys(s: &Section<'_>, kind: ExpectKind) -> Option<RawExpect> {
    match kind {
        ExpectKind::State => read_state_expect(s),
        ExpectKind::Travel => read_travel_expect(s),
        ExpectKind::Speed => read_speed_expect(s),
        ExpectKind::Phase => read_phase_expect(s),
        ExpectKind::Fault => read_fault_expect(s),
        ExpectKind::NoFault => read_no_fault_expect(s),
        ExpectKind::ThroughFundament => read_breach_expect(s, true),
        ExpectKind::TippedOver => read_breach_expect(s, false),
        ExpectKind::Safe => read_safe_expect(s),
    }
}

/// `state`: a controller state and when (`within` or `between`).
fn read_state_expect(s: &Section<'_>) -> Option<RawExpect> {
    let state = s
        .one_of::<ExpectedState>("state", Need::Required)
        .map(|e| e.0);
    let when = read_when(s);
    Some(RawExpect::Ready(Expectation::State {
        state: state?,
        when: when?,
    }))
}

/// `travel`: a direction over a window of some length (`t0 < t1`, so that a mean
/// velocity exists), at `min_speed` m/s at least.
fn read_travel_expect(s: &Section<'_>) -> Option<RawExpect> {
    let direction = s.one_of::<Direction>("direction", Need::Required);
    let between = read_window(s, "between", Need::Required);
    let min_speed = s.number(
        "min_speed",
        Need::Default(DEFAULT_MIN_TRAVEL_SPEED),
        Limit::NonNegative,
    );
    if let Some(w) = between.filter(|w| w[0] >= w[1]) {
        s.problem(
            "between",
            format!(
                "must be [t0, t1] with t0 < t1, s (got {})",
                input::vector(w)
            ),
        );
        return None;
    }
    Some(RawExpect::Ready(Expectation::Travel {
        direction: direction?,
        between: between?,
        min_speed: min_speed?,
    }))
}

/// `speed`: a range of speeds, rpm, for one rotor (both when none is named) at
/// every tick of a window.
fn read_speed_expect(s: &Section<'_>) -> Option<RawExpect> {
    let rotor = read_rotor(s, Need::Optional);
    let rotor_ok = rotor.is_some() || !s.has("rotor");
    let range = s.vec2("range_rpm", Need::Required, Limit::Any);
    let between = read_window(s, "between", Need::Required);
    if let Some(r) = range.filter(|r| r[0] > r[1]) {
        s.problem(
            "range_rpm",
            format!(
                "must be [low, high] with low <= high, rpm (got {})",
                input::vector(r)
            ),
        );
        return None;
    }
    rotor_ok.then_some(())?;
    Some(RawExpect::Ready(Expectation::Speed {
        rotors: rotor.map_or(vec![0, 1], |r| vec![r]),
        range_rpm: range?,
        between: between?,
    }))
}

/// `phase`: a circular range of phase offsets, degrees, less than a turn wide,
/// and when.
fn read_phase_expect(s: &Section<'_>) -> Option<RawExpect> {
    let range = s.vec2("range_deg", Need::Required, Limit::Any);
    let when = read_when(s);
    if let Some(r) = range.filter(|r| !(r[0] <= r[1] && r[1] < r[0] + 360.0)) {
        s.problem(
            "range_deg",
            format!(
                "must be [from, to] with from <= to < from + 360, degrees, read counter-clockwise from `from` (e.g. [350, 370] for 350 to 10) (got {})",
                input::vector(r)
            ),
        );
        return None;
    }
    Some(RawExpect::Ready(Expectation::Phase {
        range_deg: range?,
        when: when?,
    }))
}

/// `fault`: a fault by its name, latched within a window.
fn read_fault_expect(s: &Section<'_>) -> Option<RawExpect> {
    let names: Vec<&'static str> = Faults::ALL.iter().map(|(_, n)| *n).collect();
    let name = s.choice("fault", Need::Required, &names);
    let within = read_window(s, "within", Need::Required);
    let name = name?;
    let fault = Faults::ALL.iter().find(|(_, n)| *n == name)?.0;
    Some(RawExpect::Ready(Expectation::Fault {
        fault,
        name,
        within: within?,
    }))
}

/// `no_fault`: over a window, or the whole run without one.
fn read_no_fault_expect(s: &Section<'_>) -> Option<RawExpect> {
    let has_between = s.has("between");
    let between = read_window(s, "between", Need::Optional);
    if has_between && between.is_none() {
        return None;
    }
    Some(RawExpect::Ready(Expectation::NoFault { between }))
}

/// `through_fundament` (`fundament`) or `tipped_over`: of one body or any,
/// within a window or the whole run.
fn read_breach_expect(s: &Section<'_>, fundament: bool) -> Option<RawExpect> {
    let has = (s.has("body"), s.has("within"));
    let body = s.string("body", Need::Optional);
    let within = read_window(s, "within", Need::Optional);
    if (has.0 && body.is_none()) || (has.1 && within.is_none()) {
        return None;
    }
    Some(RawExpect::Ready(Expectation::Breach {
        fundament,
        body,
        within,
    }))
}

/// `safe`: from a time to the end (the end is known only with the machine) or
/// over a window.
fn read_safe_expect(s: &Section<'_>) -> Option<RawExpect> {
    let given = other_or_between(
        s,
        "from",
        |s| s.number("from", Need::Optional, Limit::NonNegative),
        "give either `from = t` (to the end) or `between = [t0, t1]`, not both",
        "missing `from = t` (to the end) or `between = [t0, t1]`",
    )?;
    Some(match given {
        Given::Other(t) => RawExpect::SafeFrom(t),
        Given::Between(between) => RawExpect::Ready(Expectation::Safe { between }),
    })
}

/// What stage 4 checks a scenario's times and rotors against: the run's end, the
/// control ticks and the rotors of the machine (when it was read).
struct Bounds<'m> {
    /// The machine, if it was read.
    machine: Option<&'m Machine>,
    /// End of the run, s (the scenario's `t_end`, else the machine's; infinite
    /// without either).
    t_end: f64,
    /// Where `t_end` comes from, for the messages.
    end_note: String,
    /// The control rate, Hz.
    rate: Option<f64>,
    /// On a machine with one rotor, its name (for the messages): rotor 2 is not
    /// there.
    one_rotor: Option<String>,
}

impl<'m> Bounds<'m> {
    /// The bounds of a scenario whose own `t_end` is `t_end`, on machine `m`.
    fn new(t_end: Option<f64>, m: Option<&'m Machine>) -> Self {
        let end = t_end
            .or(m.map(|m| m.simulation.t_end))
            .unwrap_or(f64::INFINITY);
        let end_note = if t_end.is_some() {
            format!("t_end = {} s", sig(end))
        } else {
            format!("t_end = {} s, the machine's simulation.t_end", sig(end))
        };
        Bounds {
            machine: m,
            t_end: end,
            end_note,
            rate: m.map(|m| m.controller.rate_hz),
            one_rotor: m
                .filter(|m| m.rotors.len() == 1)
                .map(|m| m.rotors.rotor1().name.clone()),
        }
    }

    /// The control tick a command at `t`, s, is sent at: the first at or after it.
    fn tick_of(&self, t: f64) -> Option<u64> {
        self.rate.map(|r| (t * r - 1e-6).ceil().max(0.0) as u64)
    }

    /// Whether a command or a fault at `t`, s, comes before the end of the run;
    /// if not, says so at `key.t`.
    fn before_the_end(&self, problems: &Problems, key: &str, t: f64) -> bool {
        if t >= self.t_end {
            problems.at(
                &format!("{key}.t"),
                format!("must be before the end, {} (got {})", self.end_note, sig(t)),
            );
            return false;
        }
        true
    }
}

/// Stage 4: times against `t_end` and the control ticks, speeds defaulted.
fn resolve(raw: Raw, machine: Option<LoadedMachine>, problems: &Problems) -> Option<Scenario> {
    // Without the machine only what the scenario itself says is checked.
    let bounds = Bounds::new(raw.t_end, machine.as_ref().map(|(_, m, _)| m));
    let commands = resolve_commands(&raw.commands, &bounds, problems);
    let faults = resolve_faults(&raw.faults, &bounds, problems);
    let expectations = resolve_expectations(raw.expects, &bounds, problems);
    let t_end = bounds.t_end;

    if raw.refused || raw.machine.is_none() || !problems.is_empty() {
        return None;
    }
    let (machine_file, machine, params) = machine?;
    Some(Scenario {
        file: problems.file().to_string(),
        machine_file,
        machine,
        params,
        sets: raw.sets.unwrap_or_default(),
        t_end,
        commands,
        faults,
        expectations,
    })
}

/// The commands: before the end, one a control tick, in time order, their speeds
/// defaulted to the machine's `controller.speed_rpm`; no phase offset to hold on
/// one rotor.
fn resolve_commands(
    raw: &[(String, ReadCommand)],
    bounds: &Bounds<'_>,
    problems: &Problems,
) -> Vec<TimedCommand> {
    let mut commands: Vec<TimedCommand> = Vec::new();
    for (key, (t, name, c)) in raw {
        if let (Some(rotor), RawCommand::Hold(..)) = (&bounds.one_rotor, c) {
            problems.at(
                &format!("{key}.command"),
                format!(
                    "\"hold\" holds a phase offset: the machine has one rotor (\"{rotor}\"), there is none to hold (use `right` or `left` with `speed_rpm`)"
                ),
            );
            continue;
        }
        if !bounds.before_the_end(problems, key, *t) {
            continue;
        }
        let default_speed = bounds.machine.map_or(0.0, |m| m.controller.speed_rpm);
        let speed = |s: Option<f64>| s.unwrap_or(default_speed) as f32;
        let command = match *c {
            RawCommand::Travel(direction, s) => Command::Travel {
                direction,
                speed_rpm: speed(s),
            },
            RawCommand::Hold(s, o) => Command::HoldOffset {
                speed_rpm: speed(s),
                offset_deg: o.rem_euclid(360.0) as f32,
            },
            RawCommand::Stop => Command::Stop,
            RawCommand::Reset => Command::ResetFaults,
            RawCommand::Heartbeat => Command::Heartbeat,
        };
        if let Some(other) = commands
            .iter()
            .find(|o| bounds.tick_of(o.t).is_some() && bounds.tick_of(o.t) == bounds.tick_of(*t))
        {
            problems.at(
                &format!("{key}.t"),
                format!(
                    "{} s falls on the same control tick as {}.t = {} s: the controller takes one command a tick ({} Hz)",
                    sig(*t),
                    other.key,
                    sig(other.t),
                    sig(bounds.rate.unwrap_or(0.0))
                ),
            );
            continue;
        }
        commands.push(TimedCommand {
            t: *t,
            command,
            key: key.clone(),
            name,
        });
    }
    commands.sort_by(|a, b| a.t.total_cmp(&b.t));
    commands
}

/// Says at `key.rotor` that a machine with one rotor, `name`, has no rotor 2.
fn no_rotor_2(problems: &Problems, key: &str, name: &str) {
    problems.at(
        &format!("{key}.rotor"),
        format!(
            "must be 1: the machine has one rotor (\"{name}\"), rotor 2 does not exist (got 2)"
        ),
    );
}

/// The faults: starting before the end, on a rotor there is.
fn resolve_faults(
    raw: &[(String, ReadFault)],
    bounds: &Bounds<'_>,
    problems: &Problems,
) -> Vec<Injection> {
    let mut faults = Vec::new();
    for (key, (t, duration, fault)) in raw {
        if let (Some(name), Some(1)) = (&bounds.one_rotor, fault.rotor()) {
            no_rotor_2(problems, key, name);
            continue;
        }
        if !bounds.before_the_end(problems, key, *t) {
            continue;
        }
        faults.push(Injection {
            t: *t,
            until: duration.map(|d| t + d),
            fault: *fault,
            key: key.clone(),
        });
    }
    faults
}

/// The expectations: on what the machine has (rotors, bodies), their windows
/// within the run.
fn resolve_expectations(
    raw: Vec<(String, RawExpect)>,
    bounds: &Bounds<'_>,
    problems: &Problems,
) -> Vec<(String, Expectation)> {
    let mut expectations = Vec::new();
    for (key, mut e) in raw {
        if let Some(name) = &bounds.one_rotor {
            if !fit_one_rotor(&key, &mut e, name, problems) {
                continue;
            }
        }
        let (e, window_key, w) = with_window(e, bounds.t_end);
        if let (
            Expectation::Breach {
                fundament,
                body: Some(body),
                ..
            },
            Some(m),
        ) = (&e, bounds.machine)
        {
            if let Err(why) = breach_body(m, body, *fundament) {
                problems.at(&format!("{key}.body"), why);
                continue;
            }
        }
        if w[1] > bounds.t_end + TIME_EPS {
            let got = if window_key == "from" {
                sig(w[0])
            } else {
                window(w)
            };
            problems.at(
                &format!("{key}.{window_key}"),
                format!(
                    "must lie within the run, [0, {}] s ({}; got {got})",
                    sig(bounds.t_end),
                    bounds.end_note
                ),
            );
            continue;
        }
        expectations.push((key, e));
    }
    expectations
}

/// An expectation at `key` on a machine with one rotor, `name`: a phase
/// expectation does not apply (no phase offset) and a speed expectation of rotor
/// 2 names a rotor that is not there (`false`, the problem said); a speed
/// expectation naming no rotor is of the one there is.
fn fit_one_rotor(key: &str, e: &mut RawExpect, name: &str, problems: &Problems) -> bool {
    match e {
        RawExpect::Ready(Expectation::Phase { .. }) => {
            problems.at(
                &format!("{key}.kind"),
                format!(
                    "\"phase\" does not apply: the machine has one rotor (\"{name}\"), no phase offset; its controller holds speed only (expect `speed` or `state`)"
                ),
            );
            false
        }
        RawExpect::Ready(Expectation::Speed { rotors, .. }) => {
            if rotors.len() == 1 && rotors[0] == 1 {
                no_rotor_2(problems, key, name);
                return false;
            }
            // No rotor named: the one there is.
            rotors.retain(|k| *k == 0);
            true
        }
        _ => true,
    }
}

/// The expectation `e` with `safe`'s `from` ended at `t_end`, s, and the key and
/// the window, s, whose end must lie within the run (`[0, 0]` for an expectation
/// over the whole run, `[t, t]` for `from = t`).
fn with_window(e: RawExpect, t_end: f64) -> (Expectation, &'static str, [f64; 2]) {
    match e {
        RawExpect::SafeFrom(t) => (
            Expectation::Safe {
                between: [t, t_end],
            },
            "from",
            [t, t],
        ),
        RawExpect::Ready(e) => {
            let (name, w) = match &e {
                Expectation::State { when, .. } | Expectation::Phase { when, .. } => match when {
                    When::Within(w) => ("within", *w),
                    When::Between(w) => ("between", *w),
                },
                Expectation::Travel { between, .. }
                | Expectation::Speed { between, .. }
                | Expectation::Safe { between } => ("between", *between),
                Expectation::Fault { within, .. } => ("within", *within),
                Expectation::NoFault { between } => ("between", between.unwrap_or([0.0, 0.0])),
                Expectation::Breach { within, .. } => ("within", within.unwrap_or([0.0, 0.0])),
            };
            (e, name, w)
        }
    }
}

/// Whether `body` names a body of `m` that a `through_fundament` (`fundament`)
/// or `tipped_over` expectation can judge: any body goes through the fundament,
/// only a free one (no joint to the fundament or to a parent) tips over.
fn breach_body(m: &Machine, body: &str, fundament: bool) -> Result<(), String> {
    let model = crate::plant::model::PlantModel::new(m);
    let names: Vec<&str> = model.bodies.iter().map(|b| b.name.as_str()).collect();
    let Some(b) = model.bodies.iter().find(|b| b.name == body) else {
        return Err(format!(
            "no body named {body:?} (bodies: {})",
            names.join(", ")
        ));
    };
    let free = matches!(b.mount, crate::plant::model::Mount::Free { .. });
    if fundament || free {
        Ok(())
    } else {
        Err(format!(
            "{body:?} is held by a joint: only a free body is judged for tipping over (free bodies: {})",
            model
                .bodies
                .iter()
                .filter(|b| matches!(b.mount, crate::plant::model::Mount::Free { .. }))
                .map(|b| b.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ))
    }
}

/// `[t0, t1] s`.
pub(crate) fn window(w: [f64; 2]) -> String {
    format!("[{}, {}] s", sig(w[0]), sig(w[1]))
}
