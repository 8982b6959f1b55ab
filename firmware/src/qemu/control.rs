//! One control tick of the `qemu` binaries on the rotor model:
//! [`shared::tick::run`] on `QemuBoard`, timed in SysTick counts
//! ([`TickCounts`]).

use shared::controller::{Bridge, Command, Controller, Inputs, Outputs, TickTiming};

use shared::protocol::link::LinkState;
use shared::tick::Port;

use super::counter::{elapsed, now};
use super::plant::{Injected, Plant};
use super::pwm::SimPwm;
use crate::drive::Drive;
use crate::port::{link_port, log_refusals};

/// SysTick counts of one `qemu` control tick.
#[derive(Clone, Copy, Debug, Default)]
pub struct TickCounts {
    /// `Controller::step` alone.
    pub step: u32,
    /// The whole tick (sample, command, step, bridge driver, publish) without the
    /// rotor model's integration, which stands in for the motors, not for code
    /// the board runs.
    pub tick: u32,
}

/// The board of the `qemu` binaries ([`shared::tick::Board`]): the rotor model
/// sampled, the bridges' inputs written through the board's driver (both coasting
/// when the controller does not enable them or the E-stop is open, as the board's
/// E-stop handler and break cut them), then the model run for one tick with
/// `injected`. The model's integration stands in for the motors, not for code the
/// board runs: its SysTick counts are kept apart (`model`), and so are the
/// instants around the controller's step (`sampled`, `stepped`).
struct QemuBoard<'a> {
    plant: &'a mut Plant,
    drive: &'a mut Drive<SimPwm>,
    injected: &'a Injected,
    timing: TickTiming,
    /// SysTick counts of the model's tick.
    model: u32,
    /// When the sample was taken (the step follows the command's take).
    sampled: u32,
    /// When the outputs came to be applied (the step's end).
    stepped: u32,
}

impl shared::tick::Board for QemuBoard<'_> {
    fn sample(&mut self) -> Inputs {
        let s = self.plant.sample();
        let sample = Inputs {
            encoder: s.encoder,
            index: s.index,
            current: s.current,
            supply_voltage: s.supply_voltage,
            estop: self.injected.estop_open,
            command: None,
            timing: self.timing,
        };
        self.sampled = now();
        sample
    }

    fn apply(&mut self, out: &Outputs) {
        self.stepped = now();
        // As the board's `motor_out`: the bridges the controller drives, while
        // the E-stop circuit is closed.
        let bridges = if self.injected.estop_open {
            [Bridge::Off; 2]
        } else {
            out.bridges
        };
        self.drive.apply(bridges);
        let model_start = now();
        self.plant.step(self.injected);
        self.model = elapsed(model_start, now());
    }
}

/// The link's port of the `qemu` binaries: the board's, with the instant the
/// command was taken (the controller's step starts there).
struct QemuPort<P> {
    port: P,
    taken: u32,
}

impl<P: Port> Port for QemuPort<P> {
    fn take(&mut self, controller: &mut Controller) -> Option<Command> {
        let command = self.port.take(controller);
        self.taken = now();
        command
    }

    fn publish(&mut self, inputs: &Inputs, out: &Outputs, controller: &Controller) {
        self.port.publish(inputs, out, controller);
    }
}

/// One control tick on the rotor model: [`shared::tick::run`] on the
/// `QemuBoard`, with the nominal tick and the tick's `timing`. Timed in SysTick
/// counts ([`TickCounts`]): the step from the command's take to the outputs'
/// apply (the step and the copy of its inputs), the whole tick without the model.
pub fn tick(
    controller: &mut Controller,
    plant: &mut Plant,
    drive: &mut Drive<SimPwm>,
    injected: &Injected,
    timing: TickTiming,
    uptime_ms: u32,
    link: &mut impl rtic::Mutex<T = LinkState>,
) -> (Outputs, TickCounts) {
    let start = now();
    let mut board = QemuBoard {
        plant,
        drive,
        injected,
        timing,
        model: 0,
        sampled: start,
        stepped: start,
    };
    let mut port = QemuPort {
        port: link_port(link, uptime_ms),
        taken: start,
    };
    let dt = controller.params().tick_s();
    let out = shared::tick::run(controller, &mut board, &mut port, dt);
    log_refusals(&port.port.taken);
    let step = elapsed(port.taken, board.stepped);
    let tick = elapsed(start, now()).saturating_sub(board.model);
    (out, TickCounts { step, tick })
}
