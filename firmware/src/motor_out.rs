//! Motor outputs: a signed duty per motor onto the two PWM inputs of its H-bridge
//! (TIM8 CH1/CH2 for motor 1, CH3/CH4 for motor 2, see `board.rs`), and [`cut`],
//! which switches all four outputs off from any context, the panic handler included.
//!
//! # Drive scheme (sign-magnitude, coasting in the off-time)
//!
//! An H-bridge with two inputs IN1/IN2 (DRV8871-like): IN1 = PWM, IN2 = low drives
//! forward with duty `d`; IN1 = low, IN2 = PWM drives in reverse; both low leaves the
//! bridge in coast (outputs high-impedance). So `duty = d` in [-1, 1] maps to
//! `(IN1, IN2) = (max(d, 0), max(-d, 0))` ([`bridge_duties`]).
//!
//! # Off state
//!
//! [`cut`] clears MOE (main output enable) and AOE (automatic output enable, which
//! the HAL sets and which would set MOE again at the next update event), disables
//! the four channels (CCxE) and zeroes the compare registers. With MOE = 0 and
//! CCxE = 0 the timer no longer drives the pins: the H-bridge inputs need pull-downs
//! (the DRV8871 has them inside) so the bridge sees both inputs low (coast).

use stm32f4xx_hal::pac::{self, TIM8};
use stm32f4xx_hal::timer::{ErasedChannel, PwmHzManager};

/// `(IN1, IN2)` duty fractions in [0, 1] for a signed duty: the positive part on
/// IN1, the negative part on IN2, the other input low. Clamped to [-1, 1]; a NaN
/// gives `(0, 0)` (coast).
pub fn bridge_duties(duty: f32) -> (f32, f32) {
    // NaN fails both comparisons and ends up as 0.
    let d = if duty > 1.0 {
        1.0
    } else if duty < -1.0 {
        -1.0
    } else if duty.is_nan() {
        0.0
    } else {
        duty
    };
    if d >= 0.0 {
        (d, 0.0)
    } else {
        (0.0, -d)
    }
}

/// Compare value for a duty fraction in [0, 1] of `max` (rounded to nearest).
fn compare(fraction: f32, max: u16) -> u16 {
    let c = fraction * f32::from(max) + 0.5;
    if c <= 0.0 {
        0
    } else if c >= f32::from(max) {
        max
    } else {
        c as u16
    }
}

/// The two H-bridges on TIM8: channels in the order CH1..CH4 (motor 1 IN1, IN2,
/// motor 2 IN1, IN2).
pub struct MotorOut {
    /// Kept so the timer stays configured and running.
    _pwm: PwmHzManager<TIM8>,
    /// TIM8 CH1..CH4.
    channels: [ErasedChannel<TIM8>; 4],
    /// Compare value for 100 % duty (the auto-reload value + 1).
    max_duty: u16,
}

impl MotorOut {
    /// Take the configured timer and its four channels; leaves the outputs cut.
    pub fn new(pwm: PwmHzManager<TIM8>, channels: [ErasedChannel<TIM8>; 4]) -> Self {
        let max_duty = pwm.get_max_duty();
        cut();
        MotorOut {
            _pwm: pwm,
            channels,
            max_duty,
        }
    }

    /// Write one tick's outputs: the signed duties of motors 1 and 2 when `enable`,
    /// otherwise (or when the E-stop circuit is open) [`cut`].
    ///
    /// Called every control tick with the controller's fresh outputs, so a stale
    /// duty never survives a tick.
    pub fn apply(&mut self, duty: [f32; 2], enable: bool) {
        if !enable || crate::board::estop_open() {
            cut();
            return;
        }
        // Compare values: IN1/IN2 of motor 1, then of motor 2.
        let max = self.max_duty;
        for (m, d) in duty.iter().enumerate() {
            let (in1, in2) = bridge_duties(*d);
            self.channels[2 * m].set_duty(compare(in1, max));
            self.channels[2 * m + 1].set_duty(compare(in2, max));
        }
        for ch in self.channels.iter_mut() {
            ch.enable();
        }
        // MOE last, and only while the E-stop circuit is closed: checked with
        // interrupts off, so the E-stop interrupt cannot cut between the check and
        // the write and then have its cut undone by this write.
        cortex_m::interrupt::free(|_| {
            if !crate::board::estop_open() {
                // SAFETY: a single read-modify-write of TIM8 BDTR with interrupts
                // off; the only other writer is `cut`, which cannot preempt here.
                let tim = unsafe { &*TIM8::ptr() };
                tim.bdtr().modify(|_, w| w.moe().set_bit());
            }
        });
    }
}

/// Switch all four H-bridge inputs off at once: clear MOE and AOE, disable CH1..CH4,
/// zero the compare registers. Writes TIM8's registers directly, without owning the
/// peripheral, so the E-stop interrupt, the panic and fault handlers can call it
/// whatever state the rest of the firmware is in. Idempotent; harmless before TIM8
/// is clocked (the writes are then ignored).
pub fn cut() {
    // SAFETY: only writes that switch outputs off; racing with `MotorOut::apply`
    // is resolved there (MOE set with interrupts off after an E-stop check).
    let tim: &pac::tim1::RegisterBlock = unsafe { &*TIM8::ptr() };
    // Main output off first: it acts at once, asynchronously to the counter.
    tim.bdtr()
        .modify(|_, w| w.moe().clear_bit().aoe().clear_bit());
    // Then the channels and their compare values (preloaded: they act at the next
    // update, the channel disable at once).
    tim.ccer().modify(|_, w| {
        w.cc1e()
            .clear_bit()
            .cc2e()
            .clear_bit()
            .cc3e()
            .clear_bit()
            .cc4e()
            .clear_bit()
    });
    for i in 0..4 {
        tim.ccr(i).write(|w| unsafe { w.bits(0) });
    }
}
