//! Panic and HardFault handlers.
//!
//! On the board: motors off first, then the log, then wait for the independent
//! watchdog. Nothing feeds the watchdog any more, so it resets the chip within
//! `board::WATCHDOG_TIMEOUT_MS`; the next start reads the watchdog flag and the
//! controller starts in `Fault` with `WATCHDOG_RESET` latched: the motors never
//! restart on their own after a crash. (With a debugger halting the core the
//! watchdog is frozen, so the panic can be inspected.)
//!
//! In the `qemu` build (no motors, no watchdog): the log, then leave QEMU with a
//! failure status, so a panic or a fault (a stack overflow, with flip-link) fails
//! the run instead of hanging it.

use core::panic::PanicInfo;

#[cfg(not(feature = "qemu"))]
use crate::motor_out;

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    // Motors off, with no task left to switch them on again: interrupts stay off.
    cortex_m::interrupt::disable();
    #[cfg(not(feature = "qemu"))]
    motor_out::cut();
    defmt::error!("panic: {}", defmt::Display2Format(info));
    halt()
}

#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    cortex_m::interrupt::disable();
    #[cfg(not(feature = "qemu"))]
    motor_out::cut();
    defmt::error!("hard fault at pc {=u32:#010x}", frame.pc());
    halt()
}

/// Board: wait for the watchdog reset.
#[cfg(not(feature = "qemu"))]
fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

/// QEMU: exit with a failure status.
#[cfg(feature = "qemu")]
fn halt() -> ! {
    crate::qemu::checks::exit(false)
}
