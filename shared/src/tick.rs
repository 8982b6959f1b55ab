//! One control tick, the same on every board: the firmware's control task, its
//! QEMU builds, `host-sim device-sim` and `host-sim`'s closed loop all call
//! [`run`], each with its own [`Board`] (where the sample comes from and where
//! the outputs go) and its own [`Port`] (where the command comes from and where
//! the status goes). None of them builds [`Inputs`] by hand.
//!
//! The stages, in order:
//! 1. [`Board::sample`]: the encoder counts, the index latches taken since the
//!    last tick, the mean currents over the tick just ended, the supply, the
//!    E-stop (its latch taken) and the tick's timing (how late it started, how
//!    long the previous one worked);
//! 2. [`Port::take`]: the command received since the last tick (and, through the
//!    link's state, a stored tuning table handed over and a requested self-test
//!    or identification started, before the step);
//! 3. [`Controller::step`] with the nominal tick `dt`;
//! 4. [`Board::apply`]: each bridge driven at its duty or off (through
//!    [`crate::drive`] on a board: the timer's compare values and its output
//!    enable);
//! 5. [`Port::publish`]: the tick's status and the procedures' reports, for the
//!    link.
//!
//! What follows a tick is the board's: the firmware feeds its watchdog and ends
//! its timing after [`run`] returns, so that a tick that panics or hangs never
//! feeds it.

use crate::controller::{Command, Controller, Inputs, Outputs};
use crate::protocol::link::{ForTick, StateLock};

/// What a board provides to a control tick: its sample, and where the outputs go.
pub trait Board {
    /// Samples this tick's inputs (stage 1): everything but the command, which
    /// is the port's ([`Port::take`] fills it in; a board leaves it `None`).
    fn sample(&mut self) -> Inputs;
    /// Writes the tick's outputs to the bridges (stage 4): every tick, each
    /// bridge driven at its duty or off as [`Outputs::bridges`] says.
    fn apply(&mut self, out: &Outputs);
}

/// The link's side of a control tick.
pub trait Port {
    /// The command for this tick (stage 2), after anything the link hands the
    /// controller before its step.
    fn take(&mut self, controller: &mut Controller) -> Option<Command>;
    /// Publishes the tick's status and the procedures' reports, read from
    /// `controller`, and the tick stepped on `inputs` for a capture (stage 5).
    fn publish(&mut self, inputs: &Inputs, out: &Outputs, controller: &Controller);
}

/// One control tick: sample, take the command, step with `dt` (s), apply,
/// publish. Returns the outputs.
pub fn run(
    controller: &mut Controller,
    board: &mut impl Board,
    port: &mut impl Port,
    dt: f32,
) -> Outputs {
    let mut inputs = board.sample();
    inputs.command = port.take(controller);
    let out = controller.step(&inputs, dt);
    board.apply(&out);
    port.publish(&inputs, &out, controller);
    out
}

/// The [`Port`] of a device: the link's shared state ([`crate::protocol::link`]),
/// under the lock `L` (on the host `&mut LinkState`, on the board an RTIC lock),
/// and the uptime its status reports.
pub struct LinkPort<L: StateLock> {
    /// The link's state, under its lock.
    pub state: L,
    /// Time since start, ms, for the status report.
    pub uptime_ms: u32,
    /// What the last [`Port::take`] did besides the command: a tuning table or a
    /// self-test or an identification the controller refused (for the board's
    /// log).
    pub taken: ForTick,
}

impl<L: StateLock> LinkPort<L> {
    /// The port of `state` at `uptime_ms`.
    pub fn new(state: L, uptime_ms: u32) -> Self {
        LinkPort {
            state,
            uptime_ms,
            taken: ForTick::default(),
        }
    }
}

impl<L: StateLock> Port for LinkPort<L> {
    fn take(&mut self, controller: &mut Controller) -> Option<Command> {
        self.taken = self.state.lock(|l| l.take_for_tick(controller));
        self.taken.command
    }

    fn publish(&mut self, inputs: &Inputs, out: &Outputs, controller: &Controller) {
        let uptime_ms = self.uptime_ms;
        self.state
            .lock(|l| l.publish(uptime_ms, inputs, out, controller));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::{Bridge, Direction, Faults, Params, ResetCause, State};
    use crate::protocol::link::LinkState;

    /// A board that counts its calls and keeps what it was given.
    struct Recording {
        sample: Inputs,
        calls: heapless::Vec<&'static str, 8>,
        applied: Option<Outputs>,
    }

    impl Board for Recording {
        fn sample(&mut self) -> Inputs {
            self.calls.push("sample").unwrap();
            self.sample
        }
        fn apply(&mut self, out: &Outputs) {
            self.calls.push("apply").unwrap();
            self.applied = Some(*out);
        }
    }

    fn powered_on() -> Controller {
        Controller::new(&Params::reference(), ResetCause::PowerOn)
    }

    fn supplied() -> Inputs {
        Inputs {
            supply_voltage: 12.0,
            ..Inputs::default()
        }
    }

    /// The stages run in their order, the step sees the board's sample with the
    /// port's command, and the outputs it returns are the ones applied and
    /// published.
    #[test]
    fn a_tick_steps_on_the_sample_and_the_command_and_hands_its_outputs_on() {
        let mut c = powered_on();
        let mut board = Recording {
            sample: supplied(),
            calls: heapless::Vec::new(),
            applied: None,
        };
        let mut state = LinkState::at_start(&c, None);
        state.command = Some(Command::Travel {
            direction: Direction::Right,
            speed_rpm: 3000.0,
        });
        let mut port = LinkPort::new(&mut state, 7);
        let out = run(&mut c, &mut board, &mut port, 1e-3);
        assert_eq!(board.calls.as_slice(), ["sample", "apply"]);
        assert_eq!(out.state, State::Starting, "the command reached the step");
        assert!(out.bridges.iter().all(|b| b.is_driven()), "{out:?}");
        assert_eq!(board.applied, Some(out));
        assert!(state.command.is_none(), "the command was taken");
        assert_eq!(state.status.uptime_ms, 7, "the status published");
        assert_eq!(state.status.state, out.state);
    }

    /// The E-stop of the sample reaches the controller: the fault latches, and the
    /// board is told to cut both bridges on that very tick.
    #[test]
    fn an_open_estop_in_the_sample_cuts_the_bridges_on_the_same_tick() {
        let mut c = powered_on();
        let mut state = LinkState::at_start(&c, None);
        state.command = Some(Command::HoldOffset {
            speed_rpm: 3000.0,
            offset_deg: 90.0,
        });
        let mut board = Recording {
            sample: supplied(),
            calls: heapless::Vec::new(),
            applied: None,
        };
        run(&mut c, &mut board, &mut LinkPort::new(&mut state, 1), 1e-3);
        assert!(board.applied.unwrap().bridges.iter().all(|b| b.is_driven()));
        board.sample.estop = true;
        let out = run(&mut c, &mut board, &mut LinkPort::new(&mut state, 2), 1e-3);
        assert!(out.faults.contains(Faults::ESTOP), "{out:?}");
        assert_eq!(board.applied.unwrap().bridges, [Bridge::Off; 2]);
    }
}
