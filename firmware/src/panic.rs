//! Panic and HardFault handlers: motors off first, then the log, then wait for the
//! independent watchdog.
//!
//! Nothing feeds the watchdog any more, so it resets the chip within
//! [`crate::board::WATCHDOG_TIMEOUT_MS`]; the next start reads the watchdog flag
//! and the controller starts in `Fault` with `WATCHDOG_RESET` latched: the motors
//! never restart on their own after a crash. (With a debugger halting the core the
//! watchdog is frozen, so the panic can be inspected.)

use core::panic::PanicInfo;

use crate::motor_out;

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    // Motors off, with no task left to switch them on again: interrupts stay off.
    cortex_m::interrupt::disable();
    motor_out::cut();
    defmt::error!("panic: {}", defmt::Display2Format(info));
    loop {
        // Wait for the watchdog reset.
        cortex_m::asm::wfi();
    }
}

#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    cortex_m::interrupt::disable();
    motor_out::cut();
    defmt::error!("hard fault at pc {=u32:#010x}", frame.pc());
    loop {
        cortex_m::asm::wfi();
    }
}
