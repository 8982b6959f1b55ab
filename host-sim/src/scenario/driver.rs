//! The controller in the loop with a scenario's injected faults: before every
//! control tick the faults in force are set ([`ScenarioDriver`]), and every tick is
//! recorded ([`Tick`]) for judging.

use shared::controller::Outputs;

use super::file::InjectedFault;
use super::file::Injection;
use super::file::Scenario;
use crate::machine::input::Problem;
use crate::plant::bridge::BridgeCommand;
use crate::plant::simulator::Plant;
use crate::simulation::closed_loop::{ControllerDriver, Injected};
use crate::simulation::trace::EventRow;
use crate::simulation::Driver;

/// One control tick as recorded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tick {
    /// Time, s.
    pub t: f64,
    /// The platform's x (centre of mass) at the tick, m.
    pub x: f64,
    /// What the controller wrote at the tick.
    pub out: Outputs,
}

/// The controller in the loop with a scenario's injected faults, recording every
/// tick.
pub struct ScenarioDriver<'s> {
    /// The controller in the loop (its schedule holds the scenario's commands).
    pub inner: ControllerDriver,
    /// The faults to inject.
    faults: &'s [Injection],
    /// Every tick so far.
    pub ticks: Vec<Tick>,
}

impl<'s> ScenarioDriver<'s> {
    /// The controller for `scenario`'s machine with its commands as the schedule.
    pub fn new(scenario: &'s Scenario) -> Result<Self, Vec<Problem>> {
        let schedule = scenario.commands.iter().map(|c| (c.t, c.command)).collect();
        Ok(ScenarioDriver {
            inner: ControllerDriver::new(&scenario.machine, schedule)?,
            faults: &scenario.faults,
            ticks: Vec::new(),
        })
    }
}

impl Driver for ScenarioDriver<'_> {
    /// The faults in force at `t`, from scratch: overlapping windows combine
    /// (dropouts and jams by rotor, current offsets add, the lowest supply wins).
    fn before_tick(&mut self, t: f64, plant: &mut Plant) {
        let mut injected = Injected::default();
        let mut jam = [false; 2];
        for f in self.faults.iter().filter(|f| f.active(t)) {
            match f.fault {
                InjectedFault::EncoderDropout { rotor } => injected.encoder_dropout[rotor] = true,
                InjectedFault::JammedRotor { rotor } => jam[rotor] = true,
                InjectedFault::SupplySag { voltage } => {
                    injected.supply_voltage = Some(
                        injected
                            .supply_voltage
                            .map_or(voltage, |v: f64| v.min(voltage)),
                    );
                }
                InjectedFault::CurrentOffset { rotor, amps } => {
                    injected.current_offset[rotor] += amps;
                }
                InjectedFault::LostCommands => injected.link_lost = true,
                InjectedFault::Estop => injected.estop = true,
                InjectedFault::LateTicks { late_us } => {
                    injected.tick_late_s = injected.tick_late_s.max(late_us * 1e-6);
                }
            }
        }
        self.inner.injected = injected;
        // The rotors there are (a one-rotor machine's scenario names no rotor 2).
        let rotors = self.inner.rotor_count().count();
        for (k, on) in jam.into_iter().enumerate().take(rotors) {
            plant.set_jam(k, on);
        }
        self.inner.before_tick(t, plant);
    }

    fn bridges(&mut self, t: f64, plant: &Plant) -> ([BridgeCommand; 2], [f64; 2]) {
        let w = self.inner.bridges(t, plant);
        if let Some(out) = self.inner.last() {
            self.ticks.push(Tick {
                t,
                x: plant.platform_motion()[0],
                out: *out,
            });
        }
        w
    }

    fn state(&self) -> String {
        self.inner.state()
    }

    fn commanded_offset_deg(&self) -> Option<f64> {
        self.inner.commanded_offset_deg()
    }

    fn phase_loop(&self) -> bool {
        self.inner.phase_loop()
    }

    fn faults(&self) -> Vec<String> {
        self.inner.faults()
    }

    fn events(&mut self) -> Vec<EventRow> {
        self.inner.events()
    }
}
