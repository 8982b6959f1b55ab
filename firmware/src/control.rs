//! The board at a control tick ([`shared::tick::Board`]): what the board's control
//! task samples and where it writes the outputs.

use shared::controller::{Inputs, Outputs, TickTiming};

use crate::board::{self, Encoders};
use crate::estop;
use crate::motor_out::MotorOut;
use crate::sense::Sense;

/// The board at a control tick: the encoders, the index counts latched by the
/// index tasks, the ADC's means, the E-stop, the tick's timing; the outputs to
/// TIM8 through `motor_out`.
pub struct BoardIo<'a, I> {
    /// The two encoder counters.
    pub encoders: &'a mut Encoders,
    /// The counts the index tasks latched since the last tick.
    pub index: &'a mut I,
    /// The currents and the supply.
    pub sense: &'a mut Sense,
    /// The bridges on TIM8.
    pub motors: &'a mut MotorOut,
    /// The tick's lateness and the last tick's duration.
    pub timing: TickTiming,
}

impl<I: rtic::Mutex<T = [Option<u32>; 2]>> shared::tick::Board for BoardIo<'_, I> {
    fn sample(&mut self) -> Inputs {
        let encoder = self.encoders.counts();
        let index = self.index.lock(core::mem::take);
        board::index_rearm();
        let analog = self.sense.read();
        Inputs {
            encoder,
            index,
            current: analog.current,
            supply_voltage: analog.supply_voltage,
            estop: estop::take_latch() | estop::open(),
            command: None,
            timing: self.timing,
        }
    }

    fn apply(&mut self, out: &Outputs) {
        self.motors.apply(out.bridges);
    }
}
