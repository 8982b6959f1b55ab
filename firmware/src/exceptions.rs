//! The panic handler and every exception handler that means "something went
//! wrong": each cuts the motors first, then logs, then stops.
//!
//! | entry | when |
//! | --- | --- |
//! | `panic` | a Rust panic (no input path panics; this is the last line) |
//! | `HardFault` | a fault with its own handler disabled, a fault in a handler, or a stack overflow ([`guard_stack`]) |
//! | `MemoryManagement`, `BusFault`, `UsageFault` | enabled at start ([`enable_fault_exceptions`]): a bad access, a bus error, an undefined instruction or a division by zero |
//! | `NonMaskableInt` | the clock security system: the crystal (HSE) stopped ([`SafeState::clock_failed`]) |
//! | `DefaultHandler` | an interrupt nothing is bound to (cortex-m-rt's own default is `loop {}`, which would leave the bridges at their last duty) |
//!
//! Each binary defines them once, with
//! [`exception_handlers!`](crate::exception_handlers) and the [`SafeState`] of
//! its build: how it cuts, and how it stops.
//!
//! On the board ([`Board`]), cutting is `motor_out::cut` (TIM8's main output
//! enable off, every bridge input low: coast), then the log, then a wait with
//! interrupts off for the independent watchdog, which nothing feeds any more: it
//! resets the chip within `watchdog::Timeout::RUN` (34-94 ms over the LSI's
//! spread). The next start reads the watchdog flag and the controller starts in
//! `Fault` with `WATCHDOG_RESET` latched: the motors never restart on their own
//! after a crash. (A debugger halting the core freezes the watchdog, so the state
//! can be read.)
//!
//! In the `qemu` binaries (no motors, no watchdog; `qemu::safe_state`): the
//! emulated bridge inputs are zeroed (`qemu::pwm::cut`), then the log, then QEMU
//! exits with a failure status, so a panic or a fault (a stack overflow, with
//! flip-link) fails the run instead of hanging it. An unexpected interrupt is the
//! exception in the scripted run: the scripted host pends one on purpose as its
//! last step, and the handler checks that the bridges it found driven are now
//! cut, then ends the run with the verdict (`qemu::script`).

use core::panic::PanicInfo;

use cortex_m::peripheral::scb::Exception;
use cortex_m::peripheral::SCB;
use cortex_m_rt::ExceptionFrame;

/// How a build reaches its safe state from any context, the handlers' own
/// included: the bridges cut, then a stop for good.
pub trait SafeState {
    /// Every bridge input off, from any context.
    fn cut();
    /// Whether any bridge was driven.
    fn driven() -> bool;
    /// Whether the clock security system found the crystal stopped (the NMI's
    /// cause); clears its flag. `false` where there is none.
    fn clock_failed() -> bool {
        false
    }
    /// Stop after the cut and the log, with interrupts off.
    fn halt() -> !;
    /// After an unexpected interrupt's cut: `irqn` the interrupt, `driven`
    /// whether a bridge was driven before the cut. [`SafeState::halt`] unless
    /// the build expects one.
    fn unexpected(irqn: i16, driven: bool) -> ! {
        let _ = (irqn, driven);
        Self::halt()
    }
}

/// The board: [`motor_out::cut`](crate::motor_out::cut), then a wait for the
/// watchdog's reset.
pub struct Board;

impl SafeState for Board {
    #[inline(always)]
    fn cut() {
        crate::motor_out::cut();
    }

    fn driven() -> bool {
        crate::motor_out::outputs_enabled()
    }

    fn clock_failed() -> bool {
        css_tripped()
    }

    /// Wait with interrupts off for the watchdog reset.
    fn halt() -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }
}

/// The panic handler, the fault, NMI and default handlers of a binary, each
/// cutting through `$safe` ([`SafeState`]) first. Used once, in the binary's root;
/// they come together, so a binary without them does not build (no panic handler)
/// and none runs with cortex-m-rt's default handlers.
#[macro_export]
macro_rules! exception_handlers {
    ($safe:ty) => {
        #[panic_handler]
        fn panic(info: &::core::panic::PanicInfo) -> ! {
            $crate::exceptions::panic::<$safe>(info)
        }

        #[::cortex_m_rt::exception]
        unsafe fn HardFault(frame: &::cortex_m_rt::ExceptionFrame) -> ! {
            $crate::exceptions::hard_fault::<$safe>(frame)
        }

        #[::cortex_m_rt::exception]
        fn MemoryManagement() -> ! {
            $crate::exceptions::configurable_fault::<$safe>("memory management fault")
        }

        #[::cortex_m_rt::exception]
        fn BusFault() -> ! {
            $crate::exceptions::configurable_fault::<$safe>("bus fault")
        }

        #[::cortex_m_rt::exception]
        fn UsageFault() -> ! {
            $crate::exceptions::configurable_fault::<$safe>("usage fault")
        }

        #[::cortex_m_rt::exception]
        unsafe fn NonMaskableInt() {
            $crate::exceptions::non_maskable::<$safe>()
        }

        #[::cortex_m_rt::exception]
        unsafe fn DefaultHandler(irqn: i16) {
            $crate::exceptions::unexpected_interrupt::<$safe>(irqn)
        }
    };
}

/// Bytes at the bottom of the stack that the MPU forbids ([`guard_stack`]).
pub const STACK_GUARD_BYTES: usize = 1024;
/// The stack's bottom: the start of RAM, where flip-link puts it (memory.x:
/// `RAM : ORIGIN = 0x20000000`).
const STACK_BOTTOM: u32 = 0x2000_0000;

/// First in every binary's init: faults to their own handlers, which cut first
/// ([`enable_fault_exceptions`]), and a stack overflow caught while a handler can
/// still run ([`guard_stack`]).
pub fn setup(scb: &mut SCB, mpu: &mut cortex_m::peripheral::MPU) {
    enable_fault_exceptions(scb);
    guard_stack(mpu);
}

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

/// A Rust panic: cut, log, stop.
#[inline(always)]
pub fn panic<S: SafeState>(info: &PanicInfo) -> ! {
    // Motors off, with no task left to switch them on again: interrupts stay off.
    cortex_m::interrupt::disable();
    S::cut();
    defmt::error!("panic: {}", defmt::Display2Format(info));
    S::halt()
}

/// HardFault: cut, log where, stop.
#[inline(always)]
pub fn hard_fault<S: SafeState>(frame: &ExceptionFrame) -> ! {
    cortex_m::interrupt::disable();
    S::cut();
    defmt::error!("hard fault at pc {=u32:#010x}", frame.pc());
    S::halt()
}

/// The three configurable faults: cut, log the cause register, stop.
pub fn configurable_fault<S: SafeState>(what: &str) -> ! {
    cortex_m::interrupt::disable();
    S::cut();
    defmt::error!("{=str}, CFSR {=u32:#010x}", what, cfsr());
    S::halt()
}

/// The NMI: on this board only the clock security system raises it. The core
/// runs on the HSI by now and TIM8's break has already cleared its outputs in
/// hardware (RM0090: a clock failure is a break source of TIM1 and TIM8); cut
/// anyway, clear the flag (an uncleared CSSF re-enters the NMI at once), and wait
/// for the watchdog: the control loop's timing assumed the crystal.
#[inline(always)]
pub fn non_maskable<S: SafeState>() -> ! {
    cortex_m::interrupt::disable();
    S::cut();
    let css = S::clock_failed();
    defmt::error!("NMI (clock security system: {=bool}): motors cut", css);
    S::halt()
}

/// An interrupt without a task: cut, then stop (board) or check and end the run
/// (the scripted `qemu` run).
#[inline(always)]
pub fn unexpected_interrupt<S: SafeState>(irqn: i16) -> ! {
    cortex_m::interrupt::disable();
    let driven = S::driven();
    S::cut();
    defmt::error!(
        "unexpected interrupt {=i16}: motors cut (driven before: {=bool})",
        irqn,
        driven
    );
    S::unexpected(irqn, driven)
}

/// The configurable fault status register (its bits name the fault's cause).
fn cfsr() -> u32 {
    // SAFETY: a read of a status register.
    unsafe { (*SCB::PTR).cfsr.read() }
}

/// Whether the clock security system found the HSE stopped (RCC_CIR.CSSF); clears
/// the flag (CSSC), which the NMI needs to return or be left.
fn css_tripped() -> bool {
    // SAFETY: reads RCC_CIR and writes its clear bit for CSSF only.
    let rcc = unsafe { &*stm32f4xx_hal::pac::RCC::ptr() };
    let tripped = rcc.cir().read().cssf().bit_is_set();
    rcc.cir().modify(|_, w| w.cssc().set_bit());
    tripped
}
