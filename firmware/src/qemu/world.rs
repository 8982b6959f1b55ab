//! What the control task and the scripted host share beyond the link's state: the
//! faults the script injects into the model, and per-tick facts the script checks
//! (the outputs, the model's true speeds, angles and offset, the first faulted tick,
//! where the self-test's drives started, the cost of the control steps).

use shared::controller::{Bridge, Faults, Outputs, State};

use super::control::TickCounts;
use super::plant::{Injected, Plant};

/// The first tick in `Fault` after an injection, as the control task saw it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultSeen {
    /// Control tick number.
    pub tick: u32,
    /// Faults latched.
    pub faults: Faults,
    /// The bridges of that tick.
    pub bridges: [Bridge; 2],
}

/// The start of one rotor's self-test drive, as the model saw it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveStart {
    /// The control tick whose step started the drive (its first duty > 0).
    pub tick: u32,
    /// The model's true angle when that tick sampled the encoder (the test's start
    /// count `c0`), turns in [0, 1) from the index.
    pub angle_turns: f32,
}

/// SysTick counts of `Controller::step` (or of a whole tick), over the ticks in
/// one state class.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepCost {
    /// Steps counted.
    pub steps: u32,
    /// Sum of their counts.
    pub total: u64,
    /// The largest.
    pub max: u32,
}

impl StepCost {
    fn add(&mut self, counts: u32) {
        self.steps += 1;
        self.total += u64::from(counts);
        self.max = self.max.max(counts);
    }

    /// Mean counts, rounded down (0 without steps).
    pub fn mean(&self) -> u32 {
        if self.steps == 0 {
            0
        } else {
            (self.total / u64::from(self.steps)) as u32
        }
    }
}

/// Shared between the control task and the script.
#[derive(Clone, Debug, Default)]
pub struct World {
    /// Faults injected into the model (set by the script).
    pub injected: Injected,
    /// Cleared by the script when it injects; set by the control task at the
    /// first tick it ends in `Fault`.
    pub first_fault: Option<FaultSeen>,
    /// The latest tick's bridges.
    pub bridges: [Bridge; 2],
    /// The model's true speeds, rpm.
    pub true_speed_rpm: [f32; 2],
    /// The model's true phase offset `theta_1 - theta_2`, degrees in [0, 360).
    pub true_offset_deg: f32,
    /// The model's true angles after the latest tick, turns in [0, 1) from the index.
    pub angle_turns: [f32; 2],
    /// The model's encoder counts a turn.
    pub encoder_counts: u32,
    /// Ticks the control task ended in `SelfTest` (cleared by the script).
    pub self_test_ticks: u32,
    /// Per rotor, the first tick of its self-test drive (cleared by the script).
    pub drive_start: [Option<DriveStart>; 2],
    /// Per rotor, the ticks driven by the self-test (cleared by the script).
    pub drive_ticks: [u32; 2],
    /// Per rotor, the model's highest true speed while driven by the self-test, rpm
    /// (cleared by the script).
    pub drive_peak_rpm: [f32; 2],
    /// Step cost while the motors are off (idle, fault).
    pub cost_off: StepCost,
    /// Step cost while driving (starting, running, stopping).
    pub cost_driving: StepCost,
    /// Step cost in the self-test (kept apart: its steps are lighter than a run's).
    pub cost_self_test: StepCost,
    /// Step cost in the motor identification, its last step (which ends it)
    /// included (kept apart: a rotor's coast puts its fits together a share a
    /// step).
    pub cost_identify: StepCost,
    /// The state the previous tick ended in.
    pub last_state: Option<State>,
    /// The whole tick's cost without the rotor model, motors off.
    pub tick_off: StepCost,
    /// The whole tick's cost without the rotor model, driving (self-test included,
    /// the identification not).
    pub tick_driving: StepCost,
    /// The whole tick's cost without the rotor model in the identification.
    pub tick_identify: StepCost,
    /// Most stack the control task used below its stack pointer at entry, bytes.
    pub control_stack: usize,
}

impl World {
    /// Record the tick `tick`: its outputs, the model after it, its counts.
    pub fn observe(&mut self, tick: u32, out: &Outputs, plant: &Plant, counts: TickCounts) {
        let step_counts = counts.step;
        let identify = out.state == State::Identify || self.last_state == Some(State::Identify);
        self.last_state = Some(out.state);
        if identify {
            self.tick_identify.add(counts.tick);
        } else if out.state.drives() {
            self.tick_driving.add(counts.tick);
        } else {
            self.tick_off.add(counts.tick);
        }
        self.bridges = out.bridges;
        self.true_speed_rpm = plant.speed_rpm();
        self.true_offset_deg = plant.offset_deg();
        if out.state == State::SelfTest {
            self.self_test_ticks += 1;
            for k in 0..2 {
                if out.bridges[k].duty() > 0.0 {
                    // The angles before this tick's model step: what it sampled.
                    let angle_turns = self.angle_turns[k];
                    self.drive_start[k].get_or_insert(DriveStart { tick, angle_turns });
                    self.drive_ticks[k] += 1;
                    self.drive_peak_rpm[k] = self.drive_peak_rpm[k].max(self.true_speed_rpm[k]);
                }
            }
        }
        self.angle_turns = plant.angle_turns();
        self.encoder_counts = plant.encoder_counts();
        if out.state == State::Fault && self.first_fault.is_none() {
            self.first_fault = Some(FaultSeen {
                tick,
                faults: out.faults,
                bridges: out.bridges,
            });
        }
        if out.state == State::SelfTest {
            self.cost_self_test.add(step_counts);
        } else if identify {
            self.cost_identify.add(step_counts);
        } else if out.state.drives() {
            self.cost_driving.add(step_counts);
        } else {
            self.cost_off.add(step_counts);
        }
    }
}
