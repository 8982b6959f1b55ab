//! The twin driven as the board was: the machine file's plant, started where
//! the capture starts, with a controller built as the board's, given at each
//! tick what the board's controller was given from outside the machine: the
//! command, the procedures the link started, the supply, the E-stop and the
//! tick's timing. Its own sensors give the rest (counts, index, currents), so
//! what the twin does differently from the record is the plant's doing.
//!
//! The start: the platform as the machine file places it, at rest; each rotor
//! at rest at the angle the capture gives it (from the index latch the board
//! knew, or the first one the capture records: `theta = 2 pi ((count - latch)
//! mod N) / N`, `phi = index_angle + s theta`). The twin's controller is told
//! at its first tick the latch the board's controller knew before the capture
//! ([`told_at_start`]), so that it knows the angle when the board's did; a
//! rotor whose first latch is in the capture is left to the twin's own index
//! pulse, which fires at the tick the board's did (told at the first tick, the
//! twin's controller held the phase from the start where the board's waited
//! for its index: 4 rpm of speed residual over a first capture of the
//! reference machine, 0.4 rpm without).

use std::f64::consts::TAU;

use shared::controller::{Controller, Inputs, Outputs, Params, ResetCause, TickTiming};
use shared::tick::{self, Board, Port};

use crate::capture::CaptureFile;
use crate::machine::Machine;
use crate::plant::bridge::BridgeCommand;
use crate::plant::simulator::Plant;
use crate::simulation::board::{BoardSensors, Injected, PlantBoard};
use crate::simulation::Driver;

use super::shadow::{command_at, start_procedures};

/// Each rotor's angle from its index at the capture's start, counts in
/// `[0, N)`: from the latch the board knew, else from the first latch
/// recorded; `None` when the capture has none.
pub fn start_angles(capture: &CaptureFile, counts_per_rev: u32) -> [Option<u32>; 2] {
    let n = i64::from(counts_per_rev.max(1));
    [0, 1].map(|r| {
        let c0 = capture.records.first()?.encoder[r];
        let latch = capture.header.start.index[r]
            .or_else(|| capture.records.iter().find_map(|rec| rec.index[r]))?;
        Some((i64::from(c0.wrapping_sub(latch) as i32)).rem_euclid(n) as u32)
    })
}

/// Of the start `angles` ([`start_angles`]), those the board's controller knew
/// before the capture (its latch in the capture's start): what the twin's
/// controller is told at its first tick.
pub fn told_at_start(capture: &CaptureFile, angles: [Option<u32>; 2]) -> [Option<u32>; 2] {
    let known = capture.header.start.index;
    [0, 1].map(|r| angles[r].filter(|_| known[r].is_some()))
}

/// Where in its count's angle span a rotor is placed at the start: the middle,
/// the angle the count says with the least error (the count says only that
/// the angle lies in the span).
pub const MIDDLE_OF_THE_COUNT: f64 = 0.5;

/// `machine` with each rotor placed at the capture's start angle `angles`
/// (counts from the index), where known, `within` of the count's span in
/// (in [0, 1); [`MIDDLE_OF_THE_COUNT`] for a replay).
pub fn placed(machine: &Machine, angles: [Option<u32>; 2], within: f64) -> Machine {
    let mut m = machine.clone();
    let n = f64::from(m.sensors.encoder_counts.max(1));
    for (r, rotor) in m.rotors.iter_mut().enumerate() {
        if let Some(a) = angles.get(r).copied().flatten() {
            let theta = TAU * (f64::from(a) + within) / n;
            rotor.angle = rotor.index_angle + rotor.sense.sign() * theta;
        }
    }
    m
}

/// The controller in the twin, fed as the board's was.
pub struct ReplayDriver<'c> {
    capture: &'c CaptureFile,
    controller: Controller,
    sensors: BoardSensors,
    /// The start angles told at the first tick ([`told_at_start`]).
    angles: [Option<u32>; 2],
    dt: f32,
    tick: usize,
    /// The twin's outputs and sensed inputs, every tick.
    pub ticks: Vec<(Inputs, Outputs)>,
}

impl<'c> ReplayDriver<'c> {
    /// The driver of `capture` on the twin `machine` (placed at the start
    /// `angles`, [`placed`]) with the controller of `params`.
    pub fn new(
        capture: &'c CaptureFile,
        machine: &Machine,
        params: &Params,
        angles: [Option<u32>; 2],
    ) -> Self {
        ReplayDriver {
            capture,
            controller: Controller::new(params, ResetCause::PowerOn),
            sensors: BoardSensors::new(machine),
            angles: told_at_start(capture, angles),
            dt: capture.header.tick_s as f32,
            tick: 0,
            ticks: Vec::with_capacity(capture.records.len()),
        }
    }
}

/// The plant's board with the world's inputs of the record, and at the first
/// tick the index latch matching the start angle.
struct ReplayBoard<'a, 'b> {
    inner: PlantBoard<'a>,
    record: &'b shared::capture::Record,
    /// The latch to tell at this tick: `count - angle` per rotor.
    angles: Option<[Option<u32>; 2]>,
    sampled: Option<Inputs>,
}

impl Board for ReplayBoard<'_, '_> {
    fn sample(&mut self) -> Inputs {
        let mut inputs = self.inner.sample();
        inputs.supply_voltage = self.record.supply_voltage;
        inputs.estop = self.record.estop;
        inputs.timing = TickTiming {
            late_s: f32::from(self.record.timing_us[0]) * 1e-6,
            busy_s: f32::from(self.record.timing_us[1]) * 1e-6,
        };
        if let Some(angles) = self.angles {
            for ((index, count), angle) in inputs.index.iter_mut().zip(inputs.encoder).zip(angles) {
                if let (None, Some(a)) = (*index, angle) {
                    *index = Some(count.wrapping_sub(a));
                }
            }
        }
        self.sampled = Some(inputs);
        inputs
    }

    fn apply(&mut self, out: &Outputs) {
        self.inner.apply(out);
    }
}

/// The record's command and the procedures its link started.
struct RecordPort<'b> {
    record: &'b shared::capture::Record,
    command: Option<shared::controller::Command>,
}

impl Port for RecordPort<'_> {
    fn take(&mut self, controller: &mut Controller) -> Option<shared::controller::Command> {
        start_procedures(controller, self.record);
        self.command
    }

    fn publish(&mut self, _inputs: &Inputs, _out: &Outputs, _controller: &Controller) {}
}

impl Driver for ReplayDriver<'_> {
    /// The supply the bridges see: the recorded one.
    fn before_tick(&mut self, _t: f64, plant: &mut Plant) {
        if let Some(r) = self.capture.records.get(self.tick) {
            plant.set_supply(f64::from(r.supply_voltage));
        }
    }

    fn bridges(&mut self, t: f64, plant: &Plant) -> ([BridgeCommand; 2], [f64; 2]) {
        let Some(record) = self.capture.records.get(self.tick) else {
            return ([BridgeCommand::Off; 2], [0.0; 2]);
        };
        let injected = Injected::default();
        let mut board = ReplayBoard {
            inner: PlantBoard {
                sensors: &mut self.sensors,
                plant,
                t,
                injected: &injected,
                supply: f64::from(record.supply_voltage),
                bridges: ([BridgeCommand::Off; 2], [0.0; 2]),
            },
            record,
            angles: (self.tick == 0).then_some(self.angles),
            sampled: None,
        };
        let mut port = RecordPort {
            record,
            command: command_at(self.capture, self.tick),
        };
        let out = tick::run(&mut self.controller, &mut board, &mut port, self.dt);
        let bridges = board.inner.bridges;
        if let Some(inputs) = board.sampled {
            self.ticks.push((inputs, out));
        }
        self.tick += 1;
        bridges
    }
}
