//! The whole machine behind the simulated device (`host-sim device-sim
//! --machine`): the plant of `host-sim run` (platform, contacts and impacts,
//! motors, H-bridges as wired) with the board's sensors, stepped one control tick
//! at a time.
//!
//! A tick ([`Mechanics::advance`]), the stages of `host-sim run`'s loop in the
//! firmware's order (the outputs of the last step act over the tick, the sensors
//! are read at its end for the next step):
//! 1. the controller's last outputs on the H-bridges
//!    ([`crate::simulation::board::bridge_commands`]; open windings before the
//!    first step);
//! 2. the plant integrated to the tick's end, `t_k = k / rate_hz` (a plant that
//!    stopped advancing, [`crate::plant::progress`], stays where it stopped and
//!    says so: [`Mechanics::stopped`]); its events dropped
//!    (nobody records them here, and a long run must not pile them up), its
//!    warnings taken into a list of at most [`MAX_WARNINGS`] and a count of the
//!    rest (the plant's each name their time, so a run of hours could pile up a
//!    warning a tick);
//! 3. the sensors read there ([`BoardSensors::read`]): encoders, index pulses and
//!    currents averaged over the tick, with the machine's noise and seed;
//! 4. every body's pose checked as `host-sim run` checks its trace rows
//!    ([`BreachWatch`]): a body through the fundament or tipped over is a warning,
//!    and the platform's motion is no travel from then on.

use shared::controller::Outputs;

use super::mechanics::{Mechanics, PlatformPose};
use crate::machine::Machine;
use crate::plant::bridge::BridgeCommand;
use crate::plant::model::{initial_state, PlantModel};
use crate::plant::simulator::{Holds, Plant, Settings, Stop};
use crate::simulation::board::{bridge_commands, BoardSensors, Readings};
use crate::simulation::breach::{Breach, BreachWatch};
use crate::simulation::closed_loop::Injected;

/// The plant's warnings kept word for word; those after are only counted.
pub const MAX_WARNINGS: usize = 20;

/// A machine file's plant with its board's sensors.
pub struct PlantMechanics {
    plant: Plant,
    /// The plant's first [`MAX_WARNINGS`] warnings.
    warnings: Vec<String>,
    /// The plant's warnings after those.
    more_warnings: u64,
    sensors: BoardSensors,
    /// Control ticks integrated so far.
    ticks: u64,
    /// The machine's control rate, Hz: tick `k` ends at `k / rate_hz`, the
    /// times `host-sim run` stops its plant at.
    rate_hz: f64,
    /// Nominal supply voltage, V.
    supply: f64,
    /// Every body's pose at every tick, against the fundament and the tilt limit.
    breaches: BreachWatch,
    /// Why the plant stopped, once it has.
    stopped: Option<Stop>,
}

impl PlantMechanics {
    /// `machine` at its start state (`t = 0`), windings open, integrated at the
    /// machine file's `[simulation].rtol`.
    pub fn new(machine: &Machine) -> Self {
        let settings = Settings {
            rtol: machine.simulation.rtol,
            progress_budget: machine.simulation.progress_budget,
            ..Settings::default()
        };
        let mut plant = Plant::new(
            PlantModel::new(machine),
            initial_state(machine),
            settings,
            Holds::default(),
        );
        // A signal ends a tick that takes long (device-sim's Ctrl-C).
        plant.stop_when(crate::interrupt::flag());
        PlantMechanics {
            plant,
            warnings: Vec::new(),
            more_warnings: 0,
            sensors: BoardSensors::new(machine),
            ticks: 0,
            rate_hz: machine.controller.rate_hz,
            supply: machine.drive.supply_voltage,
            breaches: BreachWatch::new(machine),
            stopped: None,
        }
    }

    /// The plant's new warnings into the bounded list, the plant's own emptied.
    fn take_warnings(&mut self) {
        for w in self.plant.warnings.drain(..) {
            if self.warnings.contains(&w) {
                continue;
            }
            if self.warnings.len() < MAX_WARNINGS {
                self.warnings.push(w);
            } else {
                self.more_warnings += 1;
            }
        }
    }

    /// Simulated time, s.
    pub fn t(&self) -> f64 {
        self.plant.t
    }
}

impl Mechanics for PlantMechanics {
    /// `dt` is the machine's control period, `1 / rate_hz` (the device's tick).
    fn advance(&mut self, out: Option<&Outputs>, dt: f64) -> Readings {
        debug_assert!((dt * self.rate_hz - 1.0).abs() < 1e-9, "dt {dt}");
        // 1. The bridges.
        let commands = out.map_or([BridgeCommand::Off; 2], |o| {
            bridge_commands(o, [false; 2]).0
        });
        self.plant.set_bridges(commands);
        // 2. To the tick's end.
        self.ticks += 1;
        let t = self.ticks as f64 / self.rate_hz;
        if let Err(stop) = self.plant.advance_to(t, &mut |_| {}) {
            self.stopped.get_or_insert(stop);
        }
        self.plant.events.clear();
        self.take_warnings();
        // 3. The sensors.
        let readings = self.sensors.read(t, &self.plant, &Injected::default());
        // 4. The bodies against the fundament and the tilt limit.
        let plant = &self.plant;
        self.breaches.row(t, |b| {
            let [x, y, angle, ..] = plant.model.body_motion(b, &plant.y);
            [x, y, angle]
        });
        readings
    }

    fn supply(&self) -> f32 {
        self.supply as f32
    }

    fn speeds_rpm(&self) -> [f64; 2] {
        // In the driven sense, s_k dphi_k/dt; rad/s to rpm: x 60 / (2 pi).
        let rotors = &self.plant.model.rotors;
        [0, 1].map(|k| match rotors.get(k) {
            Some(r) => r.sense * self.plant.rotor_angle(k).1 * 60.0 / std::f64::consts::TAU,
            None => 0.0,
        })
    }

    fn platform(&self) -> Option<PlatformPose> {
        let [x, y, angle, ..] = self.plant.platform_motion();
        Some(PlatformPose { x, y, angle })
    }

    fn warnings(&self) -> Vec<String> {
        let mut all: Vec<String> = self.breaches.found().iter().map(Breach::warning).collect();
        all.extend(self.warnings.iter().cloned());
        if self.more_warnings > 0 {
            all.push(format!(
                "{} more warnings of the plant after these",
                self.more_warnings
            ));
        }
        all
    }

    fn no_travel(&self) -> Option<String> {
        self.breaches.found().first().map(Breach::short)
    }

    fn stopped(&self) -> Option<String> {
        // A signal is device-sim's own end, not the plant's failure.
        self.stopped
            .as_ref()
            .filter(|s| !s.is_signal())
            .map(Stop::to_string)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_warning_a_tick_for_a_long_run_keeps_a_bounded_list() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/vibro-driver.toml");
        let machine = Machine::load(std::path::Path::new(path), &[]).expect("the machine");
        let mut m = PlantMechanics::new(&machine);
        let dt = 1.0 / m.rate_hz;
        let ticks = 200;
        for k in 0..ticks {
            // As the plant words them: each names its time, so none repeats.
            m.plant.warnings.push(format!("warning at tick {k}"));
            m.advance(None, dt);
            assert!(m.plant.warnings.is_empty(), "the plant's own list grows");
        }
        let w = m.warnings();
        assert_eq!(w.len(), MAX_WARNINGS + 1);
        assert_eq!(w[0], "warning at tick 0");
        assert_eq!(
            w[MAX_WARNINGS],
            format!(
                "{} more warnings of the plant after these",
                ticks - MAX_WARNINGS
            )
        );
    }
}
