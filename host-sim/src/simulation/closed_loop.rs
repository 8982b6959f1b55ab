//! Software in the loop: the `shared` controller (the code the firmware runs)
//! stepped at the machine's control rate, seeing the simulated sensors and
//! driving the simulated motors.
//!
//! Each control tick ([`ControllerDriver::bridges`]) is the firmware's,
//! [`shared::tick::run`], on the plant's board ([`PlantBoard`]) and the scenario's
//! link (its scheduled commands):
//! 1. sample the sensors from the plant's state: quadrature encoders (quantised,
//!    wrapping 32-bit counters, index pulses, edge jitter) and the current
//!    measurement (noise, offset), all from the machine's seed;
//! 2. hand the controller the commands due, a heartbeat (the host is present),
//!    the supply voltage and the E-stop input;
//! 3. step the controller with `dt = 1 / rate_hz` (time is passed in);
//! 4. command the H-bridges with the duties (the plant's `bridge` makes them the
//!    windings' voltages as the bridge is wired), or off when the controller
//!    disables its outputs;
//! 5. record the controller's state changes and faults as events.
//!
//! Steps 1 and 4 are [`super::board`]'s.
//!
//! A machine with one rotor ([`RotorCount::One`], from its machine file): only
//! rotor 1's encoder and current are sampled (`Plant::rotor_angle(0)` and
//! `mean_currents()[0]`); the controller gets rotor 2's inputs at rest (counter 0,
//! no index, 0 A), which it does not read; rotor 2's bridge is always commanded
//! `Off` and its duty recorded 0. The controller holds rotor 1's speed only.
//!
//! A self-test ([`shared::controller::self_test`]) starts at a set time
//! ([`ControllerDriver::start_self_test_at`]), as the firmware starts it when the
//! link asks: [`Controller::start_self_test`] just before that tick's step.

use shared::controller::{
    Command, Controller, Faults, Inputs, Outputs, Params, ResetCause, RotorCount, State,
};
use shared::tick::{self, Port};

use crate::machine::input::Problem;
use crate::machine::tuning_file;
use crate::machine::{machine_constants, Machine};
use crate::plant::bridge::BridgeCommand;
use crate::plant::simulator::Plant;

use crate::event::{EventKind, EventRow};
use crate::simulation::board::{BoardSensors, Injected, PlantBoard};
use crate::simulation::Driver;

/// The controller in the loop.
pub struct ControllerDriver {
    controller: Controller,
    /// One rotor or two (the machine's, as the controller's parameters say).
    rotor_count: RotorCount,
    /// The encoders and current sensors of the rotors there are.
    sensors: BoardSensors,
    supply: f64,
    dt: f32,
    /// Commands still to send: (time, command), in time order.
    schedule: Vec<(f64, Command)>,
    /// Faults injected now.
    pub injected: Injected,
    last: Option<Outputs>,
    events: Vec<EventRow>,
    /// Telemetry of every tick: (t, outputs).
    pub history: Vec<(f64, Outputs)>,
    record_history: bool,
    /// When to start a self-test, s (taken once tried).
    self_test_at: Option<f64>,
    /// When the self-test was asked for, and whether it started.
    self_test_started: Option<(f64, bool)>,
}

/// The controller's speed range on machine `m`, rpm: `[min_speed_rpm,
/// max_speed_rpm]`, from its constants alone (no file is read).
pub fn speed_range_rpm(m: &Machine) -> (f64, f64) {
    let p = Params::from_machine(&machine_constants(m));
    (f64::from(p.min_speed_rpm), f64::from(p.max_speed_rpm))
}

/// The controller in the loop as a run's summary reads it: its last tick's
/// outputs (`None` before its first) and the rotors it drives. The controller
/// in the loop's and the firmware's alike.
#[derive(Clone, Copy, Debug)]
pub struct LastTick<'a> {
    /// The outputs of its last tick.
    pub last: Option<&'a Outputs>,
    /// One rotor or two.
    pub rotors: RotorCount,
}

impl LastTick<'_> {
    /// Its state after the last tick; [`State::Idle`] before the first.
    pub fn state(&self) -> State {
        self.last.map_or(State::Idle, |o| o.state)
    }

    /// The faults latched at the last tick.
    pub fn faults(&self) -> Faults {
        self.last.map(|o| o.faults).unwrap_or_default()
    }

    /// The offset the last tick held while running, degrees; none on one rotor
    /// (no phase loop).
    pub fn held_offset_deg(&self) -> Option<f64> {
        self.last
            .filter(|o| o.state == State::Running && self.phase_loop())
            .map(|o| f64::from(o.telemetry.target_offset_deg))
    }

    /// Whether a phase loop holds the rotors' offset: on two rotors.
    pub fn phase_loop(&self) -> bool {
        self.rotors.has_rotor2()
    }
}

/// The controller's parameters for a machine file, with its tuning table if it
/// names one (problems name the table file and key).
pub fn params(m: &Machine) -> Result<Params, Vec<Problem>> {
    let mut p = Params::from_machine(&machine_constants(m));
    if let Some(path) = &m.controller.tuning_table {
        p.tuning = tuning_file::read_table(path)?;
    }
    Ok(p)
}

/// What the controller's constants leave out on a machine of several bodies:
/// its lift-off band and resonance are computed from the platform and the
/// eccentrics alone ([`machine_constants`]), as the firmware's build, which
/// refuses such a machine, says. `None` for a single platform.
pub fn constants_warning(m: &Machine) -> Option<String> {
    let beyond = m.beyond_the_platform();
    (!beyond.is_empty()).then(|| {
        format!(
            "the controller's constants (lift-off band, resonance) are a single platform's, computed from the platform and the eccentrics alone; this machine has more: {} (the firmware's build refuses it)",
            beyond.join(", ")
        )
    })
}

impl ControllerDriver {
    /// The controller for `machine`, powered on, with `schedule` commands; its
    /// parameters read from the machine ([`params`]).
    pub fn new(machine: &Machine, schedule: Vec<(f64, Command)>) -> Result<Self, Vec<Problem>> {
        Ok(ControllerDriver::with_params(
            machine,
            &params(machine)?,
            schedule,
        ))
    }

    /// The controller for `machine` on `params` read before (a scenario's),
    /// powered on, with `schedule` commands.
    pub fn with_params(machine: &Machine, params: &Params, schedule: Vec<(f64, Command)>) -> Self {
        ControllerDriver {
            rotor_count: params.rotor_count,
            controller: Controller::new(params, ResetCause::PowerOn),
            sensors: BoardSensors::new(machine),
            supply: machine.drive.supply_voltage,
            dt: (1.0 / machine.controller.rate_hz) as f32,
            schedule,
            injected: Injected::default(),
            last: None,
            events: Vec::new(),
            history: Vec::new(),
            record_history: false,
            self_test_at: None,
            self_test_started: None,
        }
    }

    /// Start a self-test at the first control tick at or after `t` s (just before
    /// that tick's step, as the firmware's control task does).
    pub fn start_self_test_at(&mut self, t: f64) {
        self.self_test_at = Some(t);
    }

    /// When the self-test was asked for and whether the controller started it.
    pub fn self_test_started(&self) -> Option<(f64, bool)> {
        self.self_test_started
    }

    /// The controller in the loop.
    pub fn controller(&self) -> &Controller {
        &self.controller
    }

    /// Keep every tick's outputs in [`ControllerDriver::history`] (scenarios).
    pub fn record_history(&mut self, on: bool) {
        self.record_history = on;
    }

    /// The last outputs.
    pub fn last(&self) -> Option<&Outputs> {
        self.last.as_ref()
    }

    /// One rotor or two.
    pub fn rotor_count(&self) -> RotorCount {
        self.rotor_count
    }
}

impl Driver for ControllerDriver {
    /// The supply the bridges see: nominal, or the injected sag.
    fn before_tick(&mut self, _t: f64, plant: &mut Plant) {
        plant.set_supply(self.injected.supply(self.supply));
    }

    fn bridges(&mut self, t: f64, plant: &Plant) -> ([BridgeCommand; 2], [f64; 2]) {
        // 1 and 4: the board (sensors, bridges); 2: the commands due; 3: the step.
        let mut board = PlantBoard {
            sensors: &mut self.sensors,
            plant,
            t,
            injected: &self.injected,
            supply: self.injected.supply(self.supply),
            bridges: ([BridgeCommand::Off; 2], [0.0; 2]),
        };
        let mut port = SchedulePort {
            t,
            schedule: &mut self.schedule,
            link_lost: self.injected.link_lost,
            self_test_at: &mut self.self_test_at,
            self_test_started: &mut self.self_test_started,
        };
        let out = tick::run(&mut self.controller, &mut board, &mut port, self.dt);
        let bridges = board.bridges;

        // 5. Events: state changes and new faults.
        let before = self.last.map(|o| (o.state, o.faults));
        self.events
            .extend(controller_events(t, before, out.state, out.faults));
        self.last = Some(out);
        if self.record_history {
            self.history.push((t, out));
        }
        bridges
    }

    fn last_tick(&self) -> Option<LastTick<'_>> {
        Some(LastTick {
            last: self.last.as_ref(),
            rotors: self.rotor_count,
        })
    }

    fn events(&mut self) -> Vec<EventRow> {
        std::mem::take(&mut self.events)
    }
}

/// The controller's events of a tick at `t`, s, that ended in `state` with
/// `faults`, after a tick that ended in `before` (`None`: the first tick): the
/// state, if it changed or this is the first tick, and every fault newly latched.
pub fn controller_events(
    t: f64,
    before: Option<(State, Faults)>,
    state: State,
    faults: Faults,
) -> Vec<EventRow> {
    let mut events = Vec::new();
    let (old_state, old_faults) = before.unwrap_or((State::Idle, Faults::default()));
    if state != old_state || before.is_none() {
        events.push(EventRow::controller(
            t,
            EventKind::State,
            state.name().to_string(),
        ));
    }
    for name in faults.names() {
        if !old_faults.names().any(|n| n == name) {
            events.push(EventRow::controller(t, EventKind::Fault, name.to_string()));
        }
    }
    events
}

/// The link of the closed loop ([`shared::tick::Port`]): the scheduled commands
/// due at the tick, else a heartbeat (the host is present), none while the link
/// is lost; a self-test due is started before the step, as the firmware's link
/// starts a requested one. Nothing is published (the driver records the outputs).
struct SchedulePort<'a> {
    /// The tick's time, s.
    t: f64,
    /// Commands still to send: (time, command), in time order.
    schedule: &'a mut Vec<(f64, Command)>,
    /// Commands and heartbeats from the host are lost.
    link_lost: bool,
    /// When to start a self-test, s (taken once tried).
    self_test_at: &'a mut Option<f64>,
    /// When the self-test was asked for, and whether it started.
    self_test_started: &'a mut Option<(f64, bool)>,
}

impl Port for SchedulePort<'_> {
    fn take(&mut self, controller: &mut Controller) -> Option<Command> {
        let t = self.t;
        let mut command = None;
        while self
            .schedule
            .first()
            .is_some_and(|(tc, _)| *tc <= t + 1e-12)
        {
            let (_, c) = self.schedule.remove(0);
            command = Some(c);
        }
        if self.link_lost {
            command = None;
        } else if command.is_none() {
            command = Some(Command::Heartbeat);
        }
        if self.self_test_at.is_some_and(|ts| ts <= t + 1e-12) {
            *self.self_test_at = None;
            // Started, the state change shows as an event of the step.
            *self.self_test_started = Some((t, controller.start_self_test()));
        }
        command
    }

    fn publish(&mut self, _inputs: &Inputs, _out: &Outputs, _controller: &Controller) {}
}
