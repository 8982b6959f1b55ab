//! Motor outputs on the board: the two H-bridges on TIM8 (CH1/CH2 motor 1 IN1/IN2,
//! CH3/CH4 motor 2 IN1/IN2, see `board.rs`), driven by the shared driver
//! ([`crate::drive::Drive`] over `shared::drive::HBridge`), TIM8's hardware break
//! on the E-stop, and [`cut`], which switches all four outputs off from any
//! context, the panic and fault handlers included.
//!
//! # Drive scheme: slow decay (the machine file's `[drive] decay`)
//!
//! A DRV8871-class bridge: IN1/IN2 = 1/0 forward, 0/1 reverse, 1/1 brake (both
//! low-side switches on), 0/0 coast. In slow decay (the default) forward holds IN1
//! high and pulses IN2 with the high fraction `1 - d`: forward for `d` of each
//! period, brake for the rest, so the winding's mean voltage is `d V_s` whichever
//! way its current flows, the controller's model. Duty 0 with the outputs enabled
//! brakes; the outputs off (MOE = 0) coast. (Fast decay, IN1 = PWM `d` and IN2 low,
//! drives forward then coasts: far less current at low duty and no braking;
//! `docs/plant-model.md`, "The H-bridge".) The mapping, and the order
//! of the two writes of a reversal, are `shared::drive`'s, tested on the host.
//!
//! # The timer: centre-aligned, its update the ADC's trigger
//!
//! TIM8 counts up and down (`shared::drive::CentreAligned`: `ARR = 4200` at 20 kHz, 4200 steps
//! of duty), PWM mode 1: each input is high around the counter's valley. So in
//! slow decay both bridges brake around the valley and drive around the peak,
//! and the update event (every period up to 50 kHz, `RCR`) falls on one of the two
//! extremes, the middle of a part whatever the duty: TRGO = update starts the
//! ADC's conversions there (`sense`). The HAL sets the timer up edge-aligned;
//! [`MotorOut::new`] stops it, sets CMS, PSC, ARR, RCR and MMS, and starts it
//! again. The driver writes through [`CentreChannel`], whose full scale is `ARR`
//! (the HAL's channel reports the edge-aligned `ARR + 1`): a fraction is then
//! exact to the rounding of one count, `0.5 / ARR` (1.2e-4 of the supply).
//!
//! # Off state: MOE = 0, every input driven low
//!
//! The four channels stay enabled (CCxE = 1, active high, idle level OISx = 0) from
//! [`MotorOut::new`] on; whether the bridges are driven is decided by TIM8's main
//! output enable (MOE) alone. With OSSI = 1 ("off-state selection for idle"), MOE = 0
//! makes the timer drive every output to its idle level, low: both inputs of both
//! bridges low, coast. The pins are driven, not left floating, so the bridge's own
//! pull-downs (the DRV8871 has them inside) matter only before init and after a reset.
//!
//! MOE is cleared in three ways:
//! - **in hardware by the break input** (BKIN, PA6, wired to the same normally
//!   closed E-stop contact as PB0): BKE = 1, BKP = 1 (active high: the circuit
//!   opened lets the pull-up take it high). The break clears MOE asynchronously,
//!   without the clock or any software, within the gate delays, and sets BIF. While
//!   the input stays active MOE cannot be set, neither by software nor by AOE;
//! - **by [`cut`]**, from the E-stop interrupt (EXTI0 on PB0), the panic and
//!   HardFault handlers and every control tick that does not enable;
//! - **by a debugger halt**: DBG_TIM8_STOP (board.rs) stops TIM8 while the core is
//!   halted, and the timer then disables its outputs as if MOE were 0.
//!
//! AOE = 0: MOE is never set again automatically (at an update event) after a break.
//! Only [`MotorOut::apply`] sets it, when the controller enables *and* neither the
//! E-stop pins nor the break flag say stop. A break the controller has not yet seen
//! (BIF set) keeps the outputs off: [`crate::estop::open`] reports it, the
//! controller latches `ESTOP`, and the flag is cleared by the next tick that does
//! not enable ([`MotorOut::apply`]), so `ResetFaults` then works as for any E-stop.
//!
//! BDTR is configured once, at [`MotorOut::new`]; afterwards only MOE (and AOE,
//! cleared again) is written, by [`cut`] and [`MotorOut::apply`]. The LOCK field
//! cannot protect it: the HAL's PWM setup writes BDTR first (AOE), and the first
//! write after reset freezes LOCK (RM0090, TIMx_BDTR), at "off".

use core::convert::Infallible;
use stm32f4xx_hal::gpio::{Alternate, PA6};
use stm32f4xx_hal::pac::{self, TIM8};

use embedded_hal::pwm::{ErrorType, SetDutyCycle};
use shared::controller::Bridge;
use stm32f4xx_hal::timer::{ErasedChannel, PwmHzManager};

use crate::drive::Drive;
use crate::estop;

/// TIM8's registers, without owning the peripheral.
fn tim8() -> &'static pac::tim1::RegisterBlock {
    // SAFETY: the callers only read, or write bits that switch outputs off (MOE,
    // BIF, the compare values), except `MotorOut`, which owns the timer.
    unsafe { &*TIM8::ptr() }
}

/// The two H-bridges on TIM8: the shared driver over channels CH1..CH4 (motor 1
/// IN1, IN2, motor 2 IN1, IN2), and the break input.
pub struct MotorOut {
    /// Kept so the timer stays configured and running.
    _pwm: PwmHzManager<TIM8>,
    /// The bridges over TIM8 CH1..CH4.
    drive: Drive<CentreChannel>,
    /// PA6 as TIM8_BKIN, held so nothing else can take the pin.
    _break_input: PA6<Alternate<3>>,
}

impl MotorOut {
    /// Take the configured timer, its four channels and the break input pin (PA6
    /// in AF3 with its pull-up); cut the outputs, arm the hardware break and set
    /// the off state (module documentation). The outputs stay off until the first
    /// [`MotorOut::apply`] that enables.
    pub fn new(
        pwm: PwmHzManager<TIM8>,
        mut channels: [ErasedChannel<TIM8>; 4],
        break_input: PA6<Alternate<3>>,
    ) -> Self {
        cut();
        // One write of BDTR: break enabled, active high; no automatic output
        // enable; with MOE = 0 the enabled outputs driven to their idle level, low
        // (OSSI; OSSR = 1 likewise, which matters only for complementary outputs,
        // unused here); no dead time (the bridge inserts its own between its
        // switches; its two inputs never need one); MOE = 0.
        let tim = tim8();
        tim.bdtr().write(|w| {
            w.moe().clear_bit();
            w.aoe().clear_bit();
            w.bkp().set_bit();
            w.bke().set_bit();
            w.ossr().set_bit();
            w.ossi().set_bit();
            w.lock().off();
            w.dtg().set(0)
        });
        centre_aligned(tim);
        // Idle levels low (OIS1..OIS4 in CR2 = 0, the reset value, never written).
        // Compare values 0 (done by `cut`), then the channels on for good: with
        // MOE = 0 they drive the idle level.
        for ch in channels.iter_mut() {
            ch.enable();
        }
        let [c1, c2, c3, c4] = channels;
        // A break latched while the timer was being set up is not an E-stop the
        // controller should see: clear it if the input is inactive now.
        estop::clear_break();
        MotorOut {
            _pwm: pwm,
            drive: Drive::new(
                [
                    CentreChannel(c1),
                    CentreChannel(c2),
                    CentreChannel(c3),
                    CentreChannel(c4),
                ],
                crate::machine::MACHINE.bridge.decay,
            ),
            _break_input: break_input,
        }
    }

    /// Write one tick's outputs: the signed duties of the `bridges` the controller
    /// drives (`Outputs::bridges`; those off coast), or, driving none, [`cut`]
    /// (and clear a break flag the controller has seen).
    ///
    /// Called every control tick with the controller's fresh outputs, so a stale
    /// duty never survives a tick. MOE is set only when the controller drives a
    /// bridge, the E-stop pins read closed and no break has occurred since the last
    /// tick that drove none ([`crate::estop::open`]).
    pub fn apply(&mut self, bridges: [Bridge; 2]) {
        if !bridges.iter().any(|b| b.is_driven()) {
            cut();
            // The compare values through the driver too, so what it last wrote is
            // what the timer holds (a cut from an interrupt zeroes them behind it).
            self.drive.coast();
            // The controller has had the E-stop (the break flag is part of
            // `estop_open`) in this tick's inputs and is not driving: the flag has
            // done its job. Clears only once the input is inactive again.
            estop::clear_break();
            return;
        }
        if crate::estop::open() {
            // Leaves a break flag set: the next tick's inputs report it.
            cut();
            self.drive.coast();
            return;
        }
        // Compare values (preloaded: they act at the next update event), in the
        // order the driver chooses; then MOE. TIM8's channels cannot fail (their
        // error type is Infallible); for any other output, what failed coasts and
        // the rest is cut too.
        let switching_on = !outputs_enabled();
        if !self.drive.apply(bridges) {
            cut();
            return;
        }
        // Switching on from coast (both inputs at 0), a bridge's two inputs both
        // rise, and an update falling between the two writes would load one new
        // value with the other old: in slow decay a period driven forward at up
        // to 100 % before a reverse duty. The driver's write order guards the
        // changes while running (a reversal brakes); here the outputs are still
        // off, so force the update now (UG): both compare values load together
        // before MOE is set. It restarts the period (and triggers one extra
        // conversion), harmless with the outputs off.
        if switching_on {
            tim8().egr().write(|w| w.ug().set_bit());
        }
        // MOE last, and only while the E-stop circuit is closed and no break has
        // occurred: checked with interrupts off, so the E-stop interrupt cannot cut
        // between the check and the write and then have its cut undone by this
        // write. (While the break input is active the hardware refuses MOE anyway.)
        cortex_m::interrupt::free(|_| {
            if !crate::estop::open() {
                tim8().bdtr().modify(|_, w| w.moe().set_bit());
            }
        });
    }
}

/// A TIM8 channel with the full scale of the centre-aligned counter, `ARR`:
/// an input is high for `CCR / ARR` of the period (PWM mode 1: while the counter
/// is below `CCR` counting up and at or below it counting down, `2 CCR` of the
/// `2 ARR` counts). The HAL's channel reports `ARR + 1`, the edge-aligned count,
/// which would bias every fraction low by up to `1 / ARR` (2.4e-4 at 20 kHz).
pub struct CentreChannel(ErasedChannel<TIM8>);

impl ErrorType for CentreChannel {
    type Error = Infallible;
}

impl SetDutyCycle for CentreChannel {
    fn max_duty_cycle(&self) -> u16 {
        crate::drive::PWM_TIMER.arr
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        self.0.set_duty_cycle(duty)
    }
}

/// The timer for `shared::drive::CentreAligned` PWM at the machine's `[drive] pwm_hz`, its
/// update event as the ADC's trigger (module documentation). CMS may change only
/// with the counter stopped (RM0090, TIMx_CR1); the update generated at the end
/// loads the prescaler, the auto-reload, the repetition counter and the compare
/// values (all zero: [`cut`] has run).
fn centre_aligned(tim: &pac::tim1::RegisterBlock) {
    let t = crate::drive::PWM_TIMER;
    tim.cr1().modify(|_, w| w.cen().clear_bit());
    // SAFETY: CMS 01 (centre-aligned mode 1), PSC, ARR and RCR take any value;
    // MMS 010 is "update" as TRGO.
    unsafe {
        tim.cr1()
            .modify(|_, w| w.cms().bits(0b01).dir().clear_bit().arpe().set_bit());
        tim.psc().write(|w| w.psc().bits(t.psc));
        tim.arr().write(|w| w.arr().bits(t.arr));
        tim.rcr().write(|w| w.rep().bits(t.rcr));
        tim.cnt().write(|w| w.bits(0));
        tim.cr2().modify(|_, w| w.mms().bits(0b010));
    }
    tim.egr().write(|w| w.ug().set_bit());
    tim.cr1().modify(|_, w| w.cen().set_bit());
}

/// Whether the bridges' outputs are enabled (TIM8's MOE): a register read.
pub fn outputs_enabled() -> bool {
    tim8().bdtr().read().moe().bit_is_set()
}

/// Switch all four H-bridge inputs off at once: clear MOE (and AOE), so the timer
/// drives every input to its idle level (low: coast), and zero the compare
/// registers. Writes TIM8's registers directly, without owning the peripheral, so
/// the E-stop interrupt, the panic and fault handlers can call it whatever state
/// the rest of the firmware is in. Idempotent; harmless before TIM8 is clocked (the
/// writes are then ignored). Before [`MotorOut::new`] has set the off-state
/// configuration the channels are disabled, so MOE = 0 leaves the pins undriven
/// (the bridge's pull-downs hold them low).
pub fn cut() {
    let tim = tim8();
    // Main output off first: it acts at once, asynchronously to the counter. AOE
    // off too: the HAL's PWM setup sets it, and it would set MOE again at the next
    // update event (`MotorOut::new` leaves it off for good).
    tim.bdtr()
        .modify(|_, w| w.moe().clear_bit().aoe().clear_bit());
    // Then the compare values (preloaded: they act at the next update), so a later
    // MOE does not start from old duties.
    for i in 0..4 {
        // SAFETY: any value is a valid compare value.
        tim.ccr(i).write(|w| unsafe { w.bits(0) });
    }
}
