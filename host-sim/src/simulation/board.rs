//! The board's two ends on the plant, as the firmware's control task sees them:
//! the sensors sampled into the controller's inputs ([`BoardSensors::read`]) and
//! the controller's outputs put on the H-bridges ([`bridge_commands`]). The
//! controller in the loop of `host-sim run` ([`super::closed_loop`]) and the
//! simulated device of `host-sim device-sim --machine` share them.
//!
//! A machine with one rotor: only rotor 1's encoder and current sensor exist;
//! rotor 2 reads at rest (counter 0, no index, 0 A), and its bridge stays off as
//! long as the controller does not drive it (it never does on one rotor).

use shared::controller::{Bridge, Inputs, Outputs, TickTiming};
use shared::tick::Board;

use crate::machine::Machine;
use crate::plant::bridge::BridgeCommand;
use crate::plant::sensors::{CurrentSensor, Encoder};
use crate::plant::simulator::Plant;

/// Faults injected from outside the controller (scenarios).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Injected {
    /// Encoder signals lost: the counter and index of rotor k stop.
    pub encoder_dropout: [bool; 2],
    /// Supply voltage instead of the nominal one, V.
    pub supply_voltage: Option<f64>,
    /// Offset added to the current measurement of rotor k, A.
    pub current_offset: [f64; 2],
    /// Commands and heartbeats from the host are lost.
    pub link_lost: bool,
    /// The E-stop input is active.
    pub estop: bool,
    /// Encoder channels A and B of rotor k swapped: the controller sees its counter
    /// and index latch negated (counting down when the rotor turns forward).
    pub encoder_reversed: [bool; 2],
    /// Motor leads of rotor k swapped between the H-bridge and the motor (and its
    /// current sense): the winding gets `-duty x supply`; the current measured in
    /// the winding follows it.
    pub motor_reversed: [bool; 2],
    /// How late the control ticks start, s (a starved loop on the board; the
    /// simulation's ticks are otherwise on time).
    pub tick_late_s: f64,
}

impl Injected {
    /// The supply the bridges see and the board measures, V: the injected sag,
    /// else `nominal`.
    pub fn supply(&self, nominal: f64) -> f64 {
        self.supply_voltage.unwrap_or(nominal)
    }
}

/// What the sensors read at a control tick: the controller's
/// [`shared::controller::Inputs`] from the plant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Readings {
    /// The encoder counters (wrapping 32-bit).
    pub encoder: [u32; 2],
    /// The counter latched at the last index pulse since the previous reading.
    pub index: [Option<u32>; 2],
    /// The winding currents, A, averaged over the tick just ended.
    pub current: [f32; 2],
}

/// The encoders and current sensors of a machine's rotors (rotor 1's, then rotor
/// 2's, as many as it has), their noise from the machine's seed.
#[derive(Clone, Debug)]
pub struct BoardSensors {
    encoders: Vec<Encoder>,
    /// The counter where a lost encoder stopped.
    frozen_count: [Option<u32>; 2],
    currents: Vec<CurrentSensor>,
}

impl BoardSensors {
    /// The sensors of `machine` at its start angles.
    pub fn new(machine: &Machine) -> Self {
        let seed = machine.simulation.seed;
        BoardSensors {
            encoders: machine
                .rotors
                .iter()
                .enumerate()
                .map(|(k, r)| Encoder::for_rotor(k, r, &machine.sensors, seed))
                .collect(),
            frozen_count: [None; 2],
            currents: (0..machine.rotors.len())
                .map(|k| CurrentSensor::for_rotor(k, &machine.sensors, seed))
                .collect(),
        }
    }

    /// The readings at time `t`, s, of `plant` (its state at `t`), with the
    /// sensor faults of `injected` (encoder reversed or lost, current offset).
    pub fn read(&mut self, t: f64, plant: &Plant, injected: &Injected) -> Readings {
        let mut r = Readings::default();
        // The encoders: quantised, wrapping, index pulses, edge jitter.
        for (k, e) in self.encoders.iter_mut().enumerate() {
            let (phi, phi_dot) = plant.rotor_angle(k);
            let mut reading = e.sample(t, phi, phi_dot);
            if injected.encoder_reversed[k] {
                reading.count = reading.count.wrapping_neg();
                reading.index_count = reading.index_count.map(u32::wrapping_neg);
            }
            if injected.encoder_dropout[k] {
                r.encoder[k] = *self.frozen_count[k].get_or_insert(reading.count);
            } else {
                self.frozen_count[k] = None;
                r.encoder[k] = reading.count;
                r.index[k] = reading.index_count;
            }
        }
        // The currents averaged over the tick just ended, as the firmware's ADC
        // buffer gives them (`Inputs::current`).
        let i = plant.mean_currents();
        for (k, sensor) in self.currents.iter_mut().enumerate() {
            r.current[k] = (sensor.measure(i[k]) + injected.current_offset[k]) as f32;
        }
        r
    }
}

/// The H-bridge commands for the controller's outputs `out`: the duty on the
/// bridges it drives (negated where the motor's leads are swapped,
/// `motor_reversed`), the others off; and the duties to record (0 where off).
pub fn bridge_commands(out: &Outputs, motor_reversed: [bool; 2]) -> ([BridgeCommand; 2], [f64; 2]) {
    let commands = [0, 1].map(|k| match out.bridges[k] {
        Bridge::Off => BridgeCommand::Off,
        Bridge::Driven(duty) if motor_reversed[k] => BridgeCommand::Duty(-f64::from(duty)),
        Bridge::Driven(duty) => BridgeCommand::Duty(f64::from(duty)),
    });
    (commands, out.duties().map(f64::from))
}

/// The board of a simulated machine at one control tick ([`shared::tick::Board`]):
/// the plant's sensors at time `t` with the faults injected, the supply the
/// bridges see, and the bridges' commands the tick's outputs make.
pub struct PlantBoard<'a> {
    /// The sensors, sampled at `t`.
    pub sensors: &'a mut BoardSensors,
    /// The plant, its state at `t`.
    pub plant: &'a Plant,
    /// The tick's time, s.
    pub t: f64,
    /// Faults injected now.
    pub injected: &'a Injected,
    /// The supply the bridges see, V (the nominal, or the injected sag).
    pub supply: f64,
    /// What [`Board::apply`] wrote: the bridges' commands and the duties to record.
    pub bridges: ([BridgeCommand; 2], [f64; 2]),
}

impl Board for PlantBoard<'_> {
    fn sample(&mut self) -> Inputs {
        let r = self.sensors.read(self.t, self.plant, self.injected);
        Inputs {
            encoder: r.encoder,
            index: r.index,
            current: r.current,
            supply_voltage: self.supply as f32,
            estop: self.injected.estop,
            command: None,
            // A lockstep simulation's ticks are on time, unless late ones are
            // injected.
            timing: TickTiming {
                late_s: self.injected.tick_late_s as f32,
                busy_s: 0.0,
            },
        }
    }

    fn apply(&mut self, out: &Outputs) {
        self.bridges = bridge_commands(out, self.injected.motor_reversed);
    }
}
