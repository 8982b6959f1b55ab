//! The machine behind the simulated device: the plant of `host-sim run`
//! (bodies, contacts and impacts, motors, H-bridges as wired) with the board's
//! sensors, stepped one control tick at a time. The platform either moves
//! ([`Platform::Free`], `host-sim device-sim --machine`) or is held still with
//! every body of the machine ([`Platform::Held`]: the rotors-only bench, the
//! platform clamped; `device-sim` without a machine, or with `--platform-held`).
//!
//! A tick ([`PlantMechanics::advance`]), the stages of `host-sim run`'s loop in the
//! firmware's order (the outputs of the last step act over the tick, the sensors
//! are read at its end for the next step):
//! 1. the controller's last outputs on the H-bridges
//!    ([`crate::simulation::board::bridge_commands`]; open windings before the
//!    first step);
//! 2. the plant integrated to the tick's end, `t_k = k / rate_hz` (a plant that
//!    stopped advancing, [`crate::plant::progress`], stays where it stopped and
//!    says so: [`PlantMechanics::stopped`]); its events dropped
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

use crate::machine::Machine;
use crate::plant::bridge::BridgeCommand;
use crate::plant::model::PlantModel;
use crate::plant::progress::Stop;
use crate::plant::simulator::{Holds, Plant, Settings};
use crate::simulation::board::Injected;
use crate::simulation::board::{bridge_commands, BoardSensors, Readings};
use crate::simulation::breach::{Breach, BreachWatch};

/// The plant's warnings kept word for word; those after are only counted.
pub const MAX_WARNINGS: usize = 20;

/// What the machine's platform does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Platform {
    /// It moves on its contacts, as in `host-sim run`.
    Free,
    /// It is held still at its start pose with every other body of the machine
    /// ([`Holds::bodies`]): only the rotors turn, as on a bench with the platform
    /// clamped.
    Held,
}

/// The reference machine file (`examples/vibro-driver.toml`), built in.
const REFERENCE_MACHINE: &str = include_str!("../../../examples/vibro-driver.toml");

/// The reference machine as it stands on the bench at power-on: the machine file
/// with the platform clamped on its side, the rotor axes vertical, so gravity
/// acts along the axes (`fundament.gravity = [0, 0]` in the plane of motion) and
/// puts no torque on the eccentrics: a stopped rotor stays where it stopped.
/// The rotors at rest, rotor 1 30 degrees past its index in its driven sense
/// (counter-clockwise), rotor 2 200 degrees (clockwise). The machine behind
/// `host-sim device-sim` without `--machine`, its platform [`Platform::Held`].
pub fn reference_bench() -> Machine {
    reference_bench_with(&[])
}

/// [`reference_bench`] with the machine file's keys `sets` overridden (`--set`'s
/// `KEY=VALUE`), which must be valid.
pub fn reference_bench_with(sets: &[&str]) -> Machine {
    // theta = s (phi - index_angle), index angles 0: phi = theta / s.
    let (theta1, theta2) = (30f64.to_radians(), 200f64.to_radians());
    let mut all = vec![
        "fundament.gravity=[0.0, 0.0]".to_string(),
        format!("rotors.0.angle={theta1}"),
        format!("rotors.1.angle={}", -theta2),
    ];
    all.extend(sets.iter().map(|s| s.to_string()));
    Machine::from_text(
        "examples/vibro-driver.toml",
        REFERENCE_MACHINE,
        std::path::Path::new("examples"),
        &all,
    )
    .expect("the built-in reference machine with valid overrides")
}

/// The platform's pose: its centre of mass and angle, as the trace of `host-sim
/// run --out` gives them (columns `x`, `y`, `angle`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlatformPose {
    /// Centre of mass along the floor, m (+x right).
    pub x: f64,
    /// Centre of mass height, m (+y up).
    pub y: f64,
    /// Angle, rad (counter-clockwise positive, 0 level as at the start).
    pub angle: f64,
}

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
    /// Whether the platform moves or is held.
    platform: Platform,
}

impl PlantMechanics {
    /// `machine` at its start state (`t = 0`), windings open, its platform
    /// `platform`, integrated at the machine file's `[simulation].rtol`.
    pub fn new(machine: &Machine, platform: Platform) -> Self {
        let settings = Settings {
            rtol: machine.simulation.rtol,
            progress_budget: machine.simulation.progress_budget,
            ..Settings::default()
        };
        let model = PlantModel::new(machine);
        let y0 = model.initial_state(machine);
        let mut plant = Plant::new(
            model,
            y0,
            settings,
            Holds {
                bodies: platform == Platform::Held,
                ..Holds::default()
            },
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
            platform,
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

    /// Advance `dt` s with the controller's outputs `out` on the H-bridges (the
    /// windings open before the first); what the sensors read at the end. `dt` is
    /// the machine's control period, `1 / rate_hz` (the device's tick).
    pub fn advance(&mut self, out: Option<&Outputs>, dt: f64) -> Readings {
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

    /// The supply voltage the board measures, V.
    pub fn supply(&self) -> f32 {
        self.supply as f32
    }

    /// The rotor speeds, rpm, in each rotor's driven sense (the simulation's
    /// truth, not the controller's estimate; 0 for a rotor there is not).
    pub fn speeds_rpm(&self) -> [f64; 2] {
        // In the driven sense, s_k dphi_k/dt; rad/s to rpm: x 60 / (2 pi).
        let rotors = &self.plant.model.rotors;
        [0, 1].map(|k| match rotors.get(k) {
            Some(r) => r.sense * self.plant.rotor_angle(k).1 * 60.0 / std::f64::consts::TAU,
            None => 0.0,
        })
    }

    /// Whether the platform moves or is held.
    pub fn platform_mode(&self) -> Platform {
        self.platform
    }

    /// The platform's pose (the simulation's truth).
    pub fn platform(&self) -> PlatformPose {
        let [x, y, angle, ..] = self.plant.platform_motion();
        PlatformPose { x, y, angle }
    }

    /// The winding currents, A (the simulation's truth, not the board's reading).
    pub fn currents(&self) -> [f64; 2] {
        let y = &self.plant.y;
        [0, 1].map(|k| match self.plant.model.rotors.get(k) {
            Some(_) => y[self.plant.model.current(k)],
            None => 0.0,
        })
    }

    /// What the simulation warned about so far (deduplicated).
    pub fn warnings(&self) -> Vec<String> {
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

    /// Why the platform's motion so far is no travel, in a few words (a body went
    /// through the fundament or tipped over, [`crate::simulation::breach`]);
    /// `None` while it is one.
    pub fn no_travel(&self) -> Option<String> {
        self.breaches.found().first().map(Breach::short)
    }

    /// Why the simulation cannot go on, if it cannot: the plant stopped advancing
    /// (its progress guard, a step size underflow; [`crate::plant::progress`]).
    /// `None` while it goes on.
    pub fn stopped(&self) -> Option<String> {
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
        let mut m = PlantMechanics::new(&machine, Platform::Free);
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
