//! The E-stop's state as the firmware sees it, from anywhere (interrupts, the
//! control tick, the motor outputs): the two pins of the one contact, TIM8's break
//! flag, and the latch of the E-stop interrupt (`docs/hardware.md`, "The E-stop on
//! two pins"). Register and atomic accesses only, no peripheral owned.

use core::sync::atomic::{AtomicBool, Ordering};

use stm32f4xx_hal::pac;

/// An E-stop opening seen by its interrupt and not yet taken by a control tick.
static LATCH: AtomicBool = AtomicBool::new(false);

/// Whether the E-stop circuit is open (pressed, or a wire broken): PB0 high or PA6
/// (TIM8_BKIN) high (pulled up; the closed contact holds them at GND), or TIM8's
/// break has cut the outputs since the last tick that did not drive (a break the
/// pins no longer show: a short opening, or a fault on the PA6 side only), or the
/// E-stop interrupt latched an opening no tick has taken yet ([`latch`]).
pub fn open() -> bool {
    // SAFETY: read-only access to the input data registers of GPIOA and GPIOB.
    let (pb0, pa6) = unsafe {
        (
            (*pac::GPIOB::ptr()).idr().read().idr0().bit_is_set(),
            (*pac::GPIOA::ptr()).idr().read().idr6().bit_is_set(),
        )
    };
    pb0 || pa6 || break_tripped() || LATCH.load(Ordering::SeqCst)
}

/// The E-stop interrupt saw the circuit open: remembered until a control tick
/// takes it, so an opening shorter than a tick (the pins closed again by the time
/// the tick reads them) still reaches the controller.
pub fn latch() {
    LATCH.store(true, Ordering::SeqCst);
}

/// Take the latch (the control tick, once per tick): whether an opening was seen
/// since the last take.
pub fn take_latch() -> bool {
    LATCH.swap(false, Ordering::SeqCst)
}

/// TIM8's status register, without owning the timer.
fn tim8() -> &'static pac::tim1::RegisterBlock {
    // SAFETY: reads of SR, and the rc_w0 write that clears BIF alone.
    unsafe { &*pac::TIM8::ptr() }
}

/// Whether TIM8's break has occurred (BIF) since the flag was last cleared: the
/// break input went active and cleared MOE in hardware. A register read.
pub fn break_tripped() -> bool {
    tim8().sr().read().bif().bit_is_set()
}

/// Clear the break flag (BIF). The hardware keeps it set while the break input is
/// still active, so this never hides a present E-stop.
pub fn clear_break() {
    tim8().sr().write(|w| w.bif().clear());
}
