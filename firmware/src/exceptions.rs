//! The panic handler and every exception handler that means "something went
//! wrong": each cuts the motors first, then logs, then stops.
//!
//! | entry | when |
//! | --- | --- |
//! | `panic` | a Rust panic (no input path panics; this is the last line) |
//! | `HardFault` | a fault with its own handler disabled, a fault in a handler, or a stack overflow ([`guard_stack`]) |
//! | `MemoryManagement`, `BusFault`, `UsageFault` | enabled at start ([`enable_fault_exceptions`]): a bad access, a bus error, an undefined instruction or a division by zero |
//! | `NonMaskableInt` | the clock security system: the crystal (HSE) stopped ([`css_tripped`]) |
//! | `DefaultHandler` | an interrupt nothing is bound to (cortex-m-rt's own default is `loop {}`, which would leave the bridges at their last duty) |
//!
//! On the board, cutting is `motor_out::cut` (TIM8's main output enable off, every
//! bridge input low: coast), then the log, then a wait with interrupts off for the
//! independent watchdog, which nothing feeds any more: it resets the chip within
//! `watchdog::Timeout::RUN` (34-94 ms over the LSI's spread). The next start
//! reads the watchdog flag and the controller starts in `Fault` with
//! `WATCHDOG_RESET` latched: the motors never restart on their own after a crash.
//! (A debugger halting the core freezes the watchdog, so the state can be read.)
//!
//! In the `qemu` builds (no motors, no watchdog): the emulated bridge inputs are
//! zeroed (`qemu::pwm::cut`), then the log, then QEMU exits with a failure
//! status, so a panic or a fault (a stack overflow, with flip-link) fails the run
//! instead of hanging it. An unexpected interrupt is the exception: the scripted
//! host pends one on purpose as its last step, and the handler checks that the
//! bridges it found driven are now cut, then ends the run with the verdict
//! (`qemu::script`).

use core::panic::PanicInfo;

use cortex_m::peripheral::scb::Exception;
use cortex_m::peripheral::SCB;

/// Every bridge input off, from any context.
#[inline(always)]
fn cut() {
    #[cfg(not(feature = "qemu"))]
    crate::motor_out::cut();
    #[cfg(feature = "qemu")]
    crate::qemu::pwm::cut();
}

/// Bytes at the bottom of the stack that the MPU forbids ([`guard_stack`]).
pub const STACK_GUARD_BYTES: usize = 1024;
/// The stack's bottom: the start of RAM, where flip-link puts it (memory.x:
/// `RAM : ORIGIN = 0x20000000`).
const STACK_BOTTOM: u32 = 0x2000_0000;

/// A stack overflow must still cut. flip-link puts the stack at the bottom of
/// RAM, so an overflow runs below RAM and faults; but the fault's entry then
/// pushes its frame on the same overflowed stack, fails again, and the core
/// locks up without running any handler (the watchdog would reset it, the bridges
/// meanwhile at their last duty).
///
/// The MPU's region 0 forbids the lowest [`STACK_GUARD_BYTES`] of the stack: an
/// overflow faults there, with that much real RAM still below the stack pointer.
/// The memory-management fault's own entry fails on the same region and
/// escalates to HardFault, which runs with the MPU off (`MPU_CTRL.HFNMIENA = 0`),
/// so its frame and its handler fit in the guard: it cuts, logs, stops. Every
/// other address keeps the default memory map (`PRIVDEFENA`; all code runs
/// privileged). ARMv7-M ARM, B3.5 (the PMSAv7 MPU).
pub fn guard_stack(mpu: &mut cortex_m::peripheral::MPU) {
    // RASR: XN (28), AP = 000 no access (26:24), TEX/S/C/B 0, SIZE = log2(bytes) - 1
    // (5:1), ENABLE (0).
    const SIZE: u32 = STACK_GUARD_BYTES.trailing_zeros() - 1;
    const RASR: u32 = (1 << 28) | (SIZE << 1) | 1;
    // SAFETY: region 0 set while the MPU is off, then the MPU on with the default
    // map for privileged code; the barriers make it take effect before the next
    // stack access.
    unsafe {
        mpu.ctrl.write(0);
        mpu.rnr.write(0);
        mpu.rbar.write(STACK_BOTTOM);
        mpu.rasr.write(RASR);
        // CTRL: ENABLE (0), HFNMIENA = 0 (1): off in HardFault and NMI, PRIVDEFENA (2).
        mpu.ctrl.write((1 << 2) | 1);
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
}

/// Route memory-management, bus and usage faults to their own handlers (below)
/// instead of escalating them to HardFault; a divide by zero traps (a usage
/// fault) instead of returning 0. Call once at start.
pub fn enable_fault_exceptions(scb: &mut SCB) {
    scb.enable(Exception::MemoryManagement);
    scb.enable(Exception::BusFault);
    scb.enable(Exception::UsageFault);
    // CCR.DIV_0_TRP (bit 4): the controller never divides integers by a value
    // that can be 0, so a trap here is a bug worth stopping for.
    // SAFETY: sets one trap bit of the configuration and control register.
    unsafe { scb.ccr.modify(|r| r | (1 << 4)) };
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    // Motors off, with no task left to switch them on again: interrupts stay off.
    cortex_m::interrupt::disable();
    cut();
    defmt::error!("panic: {}", defmt::Display2Format(info));
    halt()
}

#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    cortex_m::interrupt::disable();
    cut();
    defmt::error!("hard fault at pc {=u32:#010x}", frame.pc());
    halt()
}

#[cortex_m_rt::exception]
fn MemoryManagement() -> ! {
    configurable_fault("memory management fault")
}

#[cortex_m_rt::exception]
fn BusFault() -> ! {
    configurable_fault("bus fault")
}

#[cortex_m_rt::exception]
fn UsageFault() -> ! {
    configurable_fault("usage fault")
}

/// The three configurable faults: cut, log the cause register, stop.
fn configurable_fault(what: &str) -> ! {
    cortex_m::interrupt::disable();
    cut();
    defmt::error!("{=str}, CFSR {=u32:#010x}", what, cfsr());
    halt()
}

/// The NMI: on this board only the clock security system raises it. The core
/// runs on the HSI by now and TIM8's break has already cleared its outputs in
/// hardware (RM0090: a clock failure is a break source of TIM1 and TIM8); cut
/// anyway, clear the flag (an uncleared CSSF re-enters the NMI at once), and wait
/// for the watchdog: the control loop's timing assumed the crystal.
#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() {
    cortex_m::interrupt::disable();
    cut();
    #[cfg(not(feature = "qemu"))]
    let css = css_tripped();
    #[cfg(feature = "qemu")]
    let css = false;
    defmt::error!("NMI (clock security system: {=bool}): motors cut", css);
    halt()
}

/// An interrupt without a task: cut, then stop (board) or check and end the run
/// (qemu).
#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    cortex_m::interrupt::disable();
    let driven = driven();
    cut();
    defmt::error!(
        "unexpected interrupt {=i16}: motors cut (driven before: {=bool})",
        irqn,
        driven
    );
    end_unexpected(irqn, driven)
}

/// Whether any bridge was driven.
fn driven() -> bool {
    #[cfg(not(feature = "qemu"))]
    return crate::motor_out::outputs_enabled();
    #[cfg(feature = "qemu")]
    return crate::qemu::pwm::driven();
}

/// After an unexpected interrupt's cut: the scripted `qemu` run checks and ends.
#[cfg(all(feature = "qemu", not(feature = "qemu-uart")))]
fn end_unexpected(irqn: i16, driven: bool) -> ! {
    crate::qemu::script::unexpected_interrupt(irqn, driven)
}

/// After an unexpected interrupt's cut: stop ([`halt`]).
#[cfg(not(all(feature = "qemu", not(feature = "qemu-uart"))))]
fn end_unexpected(_irqn: i16, _driven: bool) -> ! {
    halt()
}

/// The configurable fault status register (its bits name the fault's cause).
fn cfsr() -> u32 {
    // SAFETY: a read of a status register.
    unsafe { (*SCB::PTR).cfsr.read() }
}

/// Whether the clock security system found the HSE stopped (RCC_CIR.CSSF); clears
/// the flag (CSSC), which the NMI needs to return or be left.
#[cfg(not(feature = "qemu"))]
fn css_tripped() -> bool {
    // SAFETY: reads RCC_CIR and writes its clear bit for CSSF only.
    let rcc = unsafe { &*stm32f4xx_hal::pac::RCC::ptr() };
    let tripped = rcc.cir().read().cssf().bit_is_set();
    rcc.cir().modify(|_, w| w.cssc().set_bit());
    tripped
}

/// Board: wait with interrupts off for the watchdog reset.
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
