//! A whole simulation run of a machine: the plant stepped from control tick to
//! control tick, what drives the motors decided at each tick, the trace and the
//! events recorded, the summary computed.
//!
//! Stages of [`simulate`]:
//! 1. build the plant from the machine file ([`crate::plant`]);
//! 2. at every control tick `t_k = k / rate_hz`, ask the [`Driver`] for the
//!    windings (open loop: constant; the controller later), then integrate to the
//!    next tick; the integrator stops exactly at ticks and locates every event
//!    between them;
//! 3. record a trace row every `output_step` (from the integrator's dense output)
//!    and just before and after each event;
//! 4. summarize ([`crate::simulation::summary`]).
//!
//! A machine with one rotor: its driver commands rotor 2's H-bridge off
//! (`BridgeCommand::Off`), and the plant, which has no rotor 2, writes the
//! trace's rotor 2 columns (`phi2`, `omega2`, `i2`, `duty2`) as 0
//! ([`TraceRow::of`]).

pub mod board;
pub mod breach;
pub mod closed_loop;
pub mod limits;
pub mod pil;
pub mod summary;
pub mod trace;

use std::sync::atomic::AtomicUsize;

use crate::event::{EventKind, EventRow};
use crate::failure::Failure;
use crate::machine::Machine;
use crate::numbers::sig;
use crate::plant::bridge::BridgeCommand;
use crate::plant::contact::ContactForces;
use crate::plant::model::PlantModel;
use crate::plant::model::NY;
use crate::plant::progress::Stop;
use crate::plant::simulator::{Holds, Output, Plant, Settings};
use crate::simulation::closed_loop::LastTick;
use crate::simulation::summary::{ImpactInstants, SummaryBuilder};
use crate::simulation::trace::{Summary, TraceRow};

/// Why a run ended early, for a command's message: the signal by its name and
/// the time (`interrupted by SIGTERM at t = 1.5 s`, then ` of T s` where
/// `t_end` is given), or the plant's own reason ([`Stop`]'s text).
pub fn stop_message(stop: &Stop, t_end: Option<f64>) -> String {
    match stop {
        Stop::Interrupted { t } => {
            let of = t_end.map_or(String::new(), |t_end| format!(" of {} s", sig(t_end)));
            format!(
                "{} at t = {} s{of}",
                crate::interrupt::interruption(),
                sig(*t)
            )
        }
        other => other.to_string(),
    }
}

/// What decides the bridges' commands at each tick: a driver of the host's
/// (`H`: the open loop or the controller in the loop) or the firmware on QEMU
/// (processor in the loop). `run` holds any host driver (`dyn Driver`), a
/// scenario the controller in the loop.
pub enum InTheLoop<H: ?Sized> {
    /// A driver of the host's.
    Host(Box<H>),
    /// The firmware on QEMU.
    Firmware(Box<pil::FirmwareDriver>),
}

impl InTheLoop<dyn Driver> {
    /// The driver, whichever it is.
    pub fn driver(&mut self) -> &mut dyn Driver {
        match self {
            InTheLoop::Host(d) => &mut **d,
            InTheLoop::Firmware(f) => &mut **f,
        }
    }
}

/// What drives the windings, asked at every control tick.
pub trait Driver {
    /// Acts on the plant before the tick's windings are asked for (fault
    /// injection: a jammed rotor). Nothing by default.
    fn before_tick(&mut self, _t: f64, _plant: &mut Plant) {}
    /// What the H-bridges are commanded from `t` to the next tick (a duty takes
    /// effect at the next PWM period start, off at once), and the duties to record.
    fn bridges(&mut self, t: f64, plant: &Plant) -> ([BridgeCommand; 2], [f64; 2]);
    /// The controller in the loop, for the summary: its last tick and its
    /// rotors. `None` by default: open loop, no controller.
    fn last_tick(&self) -> Option<LastTick<'_>> {
        None
    }
    /// Events of the driver since the last call (state changes, faults).
    fn events(&mut self) -> Vec<EventRow> {
        Vec::new()
    }
    /// Why the driver cannot go on (the firmware in the loop lost): the run ends
    /// at that tick. `None` by default.
    fn failure(&self) -> Option<Failure> {
        None
    }
    /// Whether the driver has done what the run was for (the firmware's
    /// identification reported): the run ends after this tick, as at its end
    /// time. `false` by default.
    fn finished(&self) -> bool {
        false
    }
}

/// Open loop: constant winding voltages, or open windings (coast).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OpenLoop {
    /// Constant voltages on both windings of a two-rotor machine, V (signed,
    /// within the supply).
    Voltages([f64; 2]),
    /// The constant voltage on the winding of a one-rotor machine's rotor, V
    /// (signed, within the supply); rotor 2's bridge off.
    Voltage(f64),
    /// Windings open: the rotors coast.
    Coast,
}

impl OpenLoop {
    /// How many rotors it drives: 2 for [`OpenLoop::Voltages`], 1 for
    /// [`OpenLoop::Voltage`]; `None` for [`OpenLoop::Coast`], which fits any.
    pub fn rotors(self) -> Option<usize> {
        match self {
            OpenLoop::Voltages(_) => Some(2),
            OpenLoop::Voltage(_) => Some(1),
            OpenLoop::Coast => None,
        }
    }

    /// Its winding voltages, V (none for [`OpenLoop::Coast`]).
    pub fn volts(&self) -> &[f64] {
        match self {
            OpenLoop::Voltages(v) => v,
            OpenLoop::Voltage(v) => std::slice::from_ref(v),
            OpenLoop::Coast => &[],
        }
    }
}

/// As `--open-loop` takes it: `V1,V2`, `V` or `coast`.
impl std::fmt::Display for OpenLoop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OpenLoop::Coast => write!(f, "coast"),
            OpenLoop::Voltages([a, b]) => write!(f, "{a},{b}"),
            OpenLoop::Voltage(v) => write!(f, "{v}"),
        }
    }
}

/// The open-loop driver.
pub struct OpenLoopDriver {
    mode: OpenLoop,
    supply: f64,
}

impl OpenLoopDriver {
    /// Voltages are clamped to the supply (the H-bridge cannot do more).
    pub fn new(mode: OpenLoop, supply: f64) -> Self {
        OpenLoopDriver { mode, supply }
    }
}

impl Driver for OpenLoopDriver {
    fn bridges(&mut self, _t: f64, _plant: &Plant) -> ([BridgeCommand; 2], [f64; 2]) {
        match self.mode {
            OpenLoop::Coast => ([BridgeCommand::Off, BridgeCommand::Off], [0.0, 0.0]),
            // The volts mean the duty V / V_s in either decay mode.
            OpenLoop::Voltages(v) => {
                let duty = v.map(|u| (u / self.supply).clamp(-1.0, 1.0));
                (duty.map(BridgeCommand::Duty), duty)
            }
            OpenLoop::Voltage(v) => {
                let duty = (v / self.supply).clamp(-1.0, 1.0);
                ([BridgeCommand::Duty(duty), BridgeCommand::Off], [duty, 0.0])
            }
        }
    }
}

/// Options of a run.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// End time, s.
    pub t_end: f64,
    /// Numerical settings of the plant; its `rtol` and `progress_budget` are the
    /// machine file's (`[simulation]`), like the file's output step and seed.
    pub settings: Settings,
    /// Coordinates held still (tests only; the command holds nothing).
    pub holds: Holds,
    /// Keep every trace row in [`RunResult::rows`] (for a plot, for tests). Off,
    /// the rows go only to the [`Observer`] and memory stays bounded however long
    /// the run.
    pub keep_rows: bool,
    /// Keep every event in [`RunResult::events`] (for a plot, for tests). Off,
    /// the events go only to the [`Observer`], tick by tick.
    pub keep_events: bool,
}

impl RunOptions {
    /// A run to `t_end` with the default settings, nothing held.
    pub fn new(t_end: f64) -> Self {
        RunOptions {
            t_end,
            settings: Settings::default(),
            holds: Holds::default(),
            keep_rows: true,
            keep_events: true,
        }
    }
}

/// Watches a run as it goes: every trace row as it is recorded, and after every
/// control tick whether to go on.
pub trait Observer {
    /// A trace row, times ascending.
    fn row(&mut self, _row: &TraceRow) {}
    /// The events of a control tick (the plant's and the driver's), times
    /// ascending, each batch after the last.
    fn events(&mut self, _batch: &[EventRow]) {}
    /// After the control tick that ended at `t`, s: `false` ends the run there
    /// (Ctrl-C, say). Goes on by default.
    fn go_on(&mut self, _t: f64) -> bool {
        true
    }
    /// A flag that ends the run within one integrator attempt once it is
    /// non-zero, inside a control tick too (the signals' flag,
    /// [`crate::interrupt::flag`]); none by default.
    fn stop_flag(&self) -> Option<&'static AtomicUsize> {
        None
    }
}

/// An observer that watches nothing.
pub struct Unobserved;

impl Observer for Unobserved {}

/// An observer that ends the run on Ctrl-C (and watches nothing else).
pub struct Interruptible;

impl Interruptible {
    /// Catches Ctrl-C from now on ([`crate::interrupt`]).
    pub fn new() -> Self {
        crate::interrupt::catch();
        Interruptible
    }
}

impl Default for Interruptible {
    fn default() -> Self {
        Interruptible::new()
    }
}

impl Observer for Interruptible {
    fn go_on(&mut self, _t: f64) -> bool {
        !crate::interrupt::interrupted()
    }

    fn stop_flag(&self) -> Option<&'static AtomicUsize> {
        Some(crate::interrupt::flag())
    }
}

/// What a run produced.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// Trace rows: every `output_step`, and just before and after every event
    /// (empty unless [`RunOptions::keep_rows`]).
    pub rows: Vec<TraceRow>,
    /// The last trace row.
    pub last_row: Option<TraceRow>,
    /// Why the run ended before `t_end`, if it did: the observer said so or its
    /// stop flag was set ([`Stop::Interrupted`]), or the plant stopped advancing
    /// ([`Stop::NoProgress`], [`Stop::StepUnderflow`]). The rows, events and
    /// summary are then of the run up to there.
    pub stopped: Option<Stop>,
    /// Events, in time order (empty unless [`RunOptions::keep_events`]).
    pub events: Vec<EventRow>,
    /// The summary.
    pub summary: Summary,
    /// Accepted integration steps.
    pub steps: u64,
}

/// The run's events, taken tick by tick: the plant's and the driver's merged in
/// time order (the plant's first at equal times), counted, passed on, kept if
/// asked. Every event of a batch is at or after the last batch's.
struct Events {
    kept: Vec<EventRow>,
    keep: bool,
    impacts: ImpactInstants,
}

impl Events {
    fn take(&mut self, plant: &mut Plant, driver: &mut dyn Driver, observer: &mut dyn Observer) {
        let mut batch = std::mem::take(&mut plant.events);
        batch.extend(driver.events());
        if batch.is_empty() {
            return;
        }
        batch.sort_by(|a, b| a.t.total_cmp(&b.t));
        for e in batch.iter().filter(|e| e.kind == EventKind::Impact) {
            self.impacts.add(e.t);
        }
        observer.events(&batch);
        if self.keep {
            self.kept.extend(batch);
        }
    }
}

/// Collects trace rows from the plant's outputs: into the summary, to the
/// observer, and kept if asked.
struct Recorder<'r, 'm> {
    rows: Vec<TraceRow>,
    keep_rows: bool,
    last: Option<TraceRow>,
    summary: SummaryBuilder<'m>,
    observer: &'r mut dyn Observer,
    /// The plant's model (its coordinate layout for the rows).
    model: PlantModel,
    output_step: f64,
    /// Index of the next regular output time `k * output_step`.
    next: u64,
    duty: [f64; 2],
}

impl Recorder<'_, '_> {
    fn regular_time(&self) -> f64 {
        self.next as f64 * self.output_step
    }

    fn take(&mut self, out: Output<'_>) {
        match out {
            Output::Dense(step, upto) => {
                while self.regular_time() <= upto {
                    let t = self.regular_time();
                    let y = step.at(t);
                    self.push(t, &y, &step.forces(&y));
                    self.next += 1;
                }
            }
            Output::Before(at) | Output::After(at) => self.push(at.t, at.y, &at.forces()),
        }
    }

    fn push(&mut self, t: f64, y: &[f64; NY], forces: &ContactForces) {
        let row = TraceRow::of(&self.model, t, y, self.duty, forces);
        self.summary.push(&row);
        self.observer.row(&row);
        if self.keep_rows {
            self.rows.push(row);
        }
        self.last = Some(row);
    }
}

/// Simulates `machine` from `t = 0` to `options.t_end` with `driver` at the
/// machine's control rate.
pub fn simulate(machine: &Machine, driver: &mut dyn Driver, options: &RunOptions) -> RunResult {
    simulate_observed(machine, driver, options, &mut Unobserved)
}

/// [`simulate`] with an [`Observer`] that sees every row and may end the run early.
pub fn simulate_observed(
    machine: &Machine,
    driver: &mut dyn Driver,
    options: &RunOptions,
    observer: &mut dyn Observer,
) -> RunResult {
    // 1. The plant.
    let model = PlantModel::new(machine);
    let settings = Settings {
        rtol: machine.simulation.rtol,
        progress_budget: machine.simulation.progress_budget,
        ..options.settings
    };
    let y0 = model.initial_state(machine);
    let mut plant = Plant::new(model, y0, settings, options.holds);
    if let Some(flag) = observer.stop_flag() {
        plant.stop_when(flag);
    }

    // 2.-3. Tick by tick.
    let rate = machine.controller.rate_hz;
    let mut rec = Recorder {
        rows: Vec::new(),
        keep_rows: options.keep_rows,
        last: None,
        summary: SummaryBuilder::new(machine, 0.0, options.t_end),
        observer,
        model: plant.model.clone(),
        output_step: machine.simulation.output_step,
        next: 0,
        duty: [0.0; 2],
    };
    let mut tick: u64 = 0;
    let mut stopped = None;
    let mut events = Events {
        kept: Vec::new(),
        keep: options.keep_events,
        impacts: ImpactInstants::default(),
    };
    loop {
        let t = tick as f64 / rate;
        if t >= options.t_end {
            break;
        }
        driver.before_tick(t, &mut plant);
        let (commands, duty) = driver.bridges(t, &plant);
        if driver.failure().is_some() {
            break;
        }
        plant.set_bridges(commands);
        rec.duty = duty;
        if tick == 0 {
            let y = plant.y;
            rec.push(0.0, &y, &plant.forces_at(&y));
            rec.next = 1;
        }
        tick += 1;
        let t_next = (tick as f64 / rate).min(options.t_end);
        let advanced = plant.advance_to(t_next, &mut |out| rec.take(out));
        events.take(&mut plant, driver, rec.observer);
        if let Err(stop) = advanced {
            stopped = Some(stop);
            break;
        }
        if driver.finished() {
            break;
        }
        if t_next < options.t_end && !rec.observer.go_on(t_next) {
            stopped = Some(Stop::Interrupted { t: t_next });
            break;
        }
    }
    if rec.last.is_none_or(|r| r.t < plant.t) {
        let y = plant.y;
        rec.push(plant.t, &y, &plant.forces_at(&y));
    }

    // 4. Summary, the last events first.
    events.take(&mut plant, driver, rec.observer);
    let summary = rec.summary.finish(
        events.impacts.count(),
        driver.last_tick(),
        plant.warnings.clone(),
    );
    RunResult {
        rows: rec.rows,
        last_row: rec.last,
        stopped,
        events: events.kept,
        summary,
        steps: plant.steps,
    }
}
