//! The controller in the loop, or the firmware on QEMU (processor in the loop),
//! with a scenario's injected faults: before every control tick the faults in
//! force are set ([`ScenarioDriver`]) where the board applies them
//! ([`Injected`]: the sample, the bridges' supply, the link; a jam on the
//! plant), and every tick is recorded ([`Tick`]) for judging.

use shared::controller::Outputs;
use shared::pil::MAX_LATE_US;

use super::file::InjectedFault;
use super::file::Injection;
use super::file::Scenario;
use crate::event::EventRow;
use crate::failure::{Failure, Kind};
use crate::plant::bridge::BridgeCommand;
use crate::plant::simulator::Plant;
use crate::simulation::board::Injected;
use crate::simulation::closed_loop::ControllerDriver;
use crate::simulation::closed_loop::LastTick;
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

/// The controller a scenario runs: the controller in the loop (its schedule
/// holds the scenario's commands) or the firmware on QEMU (its link sends them).
pub type InTheLoop = crate::simulation::InTheLoop<ControllerDriver>;

/// The controller with a scenario's injected faults, recording every tick.
pub struct ScenarioDriver<'s> {
    /// The controller.
    pub inner: InTheLoop,
    /// The faults to inject.
    faults: &'s [Injection],
    /// The machine's rotors (a one-rotor machine's scenario names no rotor 2).
    rotors: usize,
    /// The control period, s.
    dt: f64,
    /// Every tick so far.
    pub ticks: Vec<Tick>,
}

/// The faults of a processor-in-the-loop run that cannot be injected there,
/// by name: `late_ticks` of a tick or more (the firmware would skip ticks).
pub fn refused_in_pil(scenario: &Scenario) -> Result<(), Failure> {
    let refused: Vec<String> = scenario
        .faults
        .iter()
        .filter(|f| {
            matches!(f.fault, InjectedFault::LateTicks { late_us } if late_us.round() >= f64::from(MAX_LATE_US))
        })
        .map(|f| {
            format!(
                "{}: {}: {}: cannot be injected with --firmware: {} us late or more skips a tick on the firmware",
                scenario.file,
                f.key,
                f.fault.describe(),
                MAX_LATE_US
            )
        })
        .collect();
    if refused.is_empty() {
        Ok(())
    } else {
        Err(Failure::new(Kind::Usage, refused))
    }
}

/// The faults in force at `t`, from scratch: overlapping windows combine
/// (dropouts and jams by rotor, current offsets add, the lowest supply wins);
/// the board's faults and the rotors jammed.
pub fn injected_at(faults: &[Injection], t: f64) -> (Injected, [bool; 2]) {
    let mut injected = Injected::default();
    let mut jam = [false; 2];
    for f in faults.iter().filter(|f| f.active(t)) {
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
    (injected, jam)
}

impl<'s> ScenarioDriver<'s> {
    /// `inner` for `scenario`, whose commands its schedule or link holds.
    pub fn new(scenario: &'s Scenario, inner: InTheLoop) -> Self {
        ScenarioDriver {
            inner,
            faults: &scenario.faults,
            rotors: scenario.machine.rotors.len(),
            dt: 1.0 / scenario.machine.controller.rate_hz,
            ticks: Vec::new(),
        }
    }

    /// The controller in the loop for `scenario`.
    pub fn controller(scenario: &'s Scenario) -> Self {
        let inner =
            ControllerDriver::with_params(&scenario.machine, &scenario.params, schedule(scenario));
        Self::new(scenario, InTheLoop::Host(Box::new(inner)))
    }

    fn driver(&mut self) -> &mut dyn Driver {
        match &mut self.inner {
            InTheLoop::Host(d) => d.as_mut(),
            InTheLoop::Firmware(d) => d.as_mut(),
        }
    }

    fn driver_ref(&self) -> &dyn Driver {
        match &self.inner {
            InTheLoop::Host(d) => d.as_ref(),
            InTheLoop::Firmware(d) => d.as_ref(),
        }
    }

    fn last(&self) -> Option<&Outputs> {
        match &self.inner {
            InTheLoop::Host(d) => d.last(),
            InTheLoop::Firmware(d) => d.last(),
        }
    }
}

/// `scenario`'s commands: (time, command), in time order.
pub fn schedule(scenario: &Scenario) -> Vec<(f64, shared::controller::Command)> {
    scenario.commands.iter().map(|c| (c.t, c.command)).collect()
}

impl Driver for ScenarioDriver<'_> {
    fn before_tick(&mut self, t: f64, plant: &mut Plant) {
        let (injected, jam) = injected_at(self.faults, t);
        match &mut self.inner {
            InTheLoop::Host(d) => d.injected = injected,
            InTheLoop::Firmware(d) => {
                // This tick's record carries the link's bytes until the next
                // tick, taken there: lost if the link is lost there; and how
                // late the next tick starts (the firmware spins after this one).
                let next = injected_at(self.faults, t + self.dt).0;
                d.injected = Injected {
                    link_lost: next.link_lost,
                    tick_late_s: next.tick_late_s,
                    ..injected
                };
            }
        }
        for (k, on) in jam.into_iter().enumerate().take(self.rotors) {
            plant.set_jam(k, on);
        }
        self.driver().before_tick(t, plant);
    }

    fn bridges(&mut self, t: f64, plant: &Plant) -> ([BridgeCommand; 2], [f64; 2]) {
        let w = self.driver().bridges(t, plant);
        if let Some(out) = self.last().copied() {
            self.ticks.push(Tick {
                t,
                x: plant.platform_motion()[0],
                out,
            });
        }
        w
    }

    fn last_tick(&self) -> Option<LastTick<'_>> {
        self.driver_ref().last_tick()
    }

    fn events(&mut self) -> Vec<EventRow> {
        self.driver().events()
    }

    fn failure(&self) -> Option<Failure> {
        self.driver_ref().failure()
    }
}
