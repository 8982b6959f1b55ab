//! The `qemu` binaries' stand-in for TIM8's four compare registers (QEMU emulates no
//! TIM8): PWM outputs for [`crate::drive::Drive`], the same driver the board runs,
//! whose written values the rotor model ([`super::plant`]) reads as the bridges'
//! inputs.

use core::convert::Infallible;
use core::sync::atomic::{AtomicU16, Ordering};

use embedded_hal::pwm::{ErrorType, SetDutyCycle};

use crate::drive::Drive;
use crate::machine::MACHINE;

/// The channels' full scale as the board's report it (`motor_out::CentreChannel`):
/// `ARR` of TIM8 set up for the machine's `[drive]` (`crate::drive::PWM_TIMER`;
/// 4200 at 20 kHz).
pub const MAX_DUTY: u16 = crate::drive::PWM_TIMER.arr;

/// The four compare values, CH1..CH4: motor 1 IN1, IN2, motor 2 IN1, IN2.
static COMPARE: [AtomicU16; 4] = [
    AtomicU16::new(0),
    AtomicU16::new(0),
    AtomicU16::new(0),
    AtomicU16::new(0),
];

/// One emulated channel.
pub struct SimPwm(usize);

impl SimPwm {
    /// The four channels, CH1..CH4.
    pub fn channels() -> [SimPwm; 4] {
        [SimPwm(0), SimPwm(1), SimPwm(2), SimPwm(3)]
    }
}

/// The board's bridge driver on the four channels, in the machine's decay mode
/// (`[drive] decay`).
pub fn drive() -> Drive<SimPwm> {
    Drive::new(SimPwm::channels(), MACHINE.bridge.decay)
}

impl ErrorType for SimPwm {
    type Error = Infallible;
}

impl SetDutyCycle for SimPwm {
    fn max_duty_cycle(&self) -> u16 {
        MAX_DUTY
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        COMPARE[self.0].store(duty.min(MAX_DUTY), Ordering::Relaxed);
        Ok(())
    }
}

/// The high fractions `[IN1, IN2]` of motor `k`'s bridge inputs, as the driver
/// last wrote them.
pub fn inputs(k: usize) -> [f32; 2] {
    let f = |ch: usize| f32::from(COMPARE[ch].load(Ordering::Relaxed)) / f32::from(MAX_DUTY);
    [f(2 * k), f(2 * k + 1)]
}

/// Every compare value to 0, both inputs of both bridges low (coast): the `qemu`
/// build's `motor_out::cut`, callable from any context.
pub fn cut() {
    for c in &COMPARE {
        c.store(0, Ordering::Relaxed);
    }
}

/// Whether any bridge input is driven high for part of the period.
pub fn driven() -> bool {
    COMPARE.iter().any(|c| c.load(Ordering::Relaxed) != 0)
}

/// The four compare values as the driver last wrote them, CH1..CH4.
pub fn compare_values() -> [u16; 4] {
    COMPARE.each_ref().map(|c| c.load(Ordering::Relaxed))
}
