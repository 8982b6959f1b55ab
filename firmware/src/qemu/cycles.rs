//! SysTick: the control tick of the `qemu` build, and the clock that times one
//! control step.
//!
//! QEMU's netduinoplus2 clocks SysTick (processor clock source) at a fixed
//! 168 MHz of *virtual* time, whatever RCC says. Under `-icount shift=0` every
//! guest instruction advances virtual time by exactly `2^0 = 1 ns`, so a stretch
//! of `n` instructions moves SysTick on by `n x 0.168` counts. [`calibrate`] checks
//! that ratio on a loop of known length, and [`instructions`] converts a count
//! difference into instructions with the measured ratio, so the result does not
//! rest on the reasoning above.

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;

/// SysTick's clock in QEMU's netduinoplus2, Hz.
pub const SYSTICK_HZ: u32 = 168_000_000;

/// Iterations of the calibration loop; 2 instructions each (`subs`, `bne`).
const CAL_ITERATIONS: u32 = 20_000;

/// Start SysTick counting down from `reload` at the processor clock, its
/// interrupt on.
pub fn start(syst: &mut SYST, reload: u32) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(reload);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// The counter now (counts down).
#[inline(always)]
pub fn now() -> u32 {
    SYST::get_current()
}

/// Counts elapsed from `before` to `after` (no wrap in between).
pub fn elapsed(before: u32, after: u32) -> u32 {
    before.wrapping_sub(after)
}

/// The calibration: `(instructions, counts)` of a loop of known length, the
/// counts corrected for the cost of reading the counter. SysTick must be running
/// with a reload above the loop's counts, interrupts off.
pub fn calibrate() -> (u32, u32) {
    // Right after it is cleared the counter reads 0 until it reloads.
    while now() == 0 {}
    let overhead = read_overhead();
    let before = now();
    let mut n = CAL_ITERATIONS;
    // SAFETY: a register-only countdown loop.
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {n}, {n}, #1",
            "bne 2b",
            n = inout(reg) n,
            options(nomem, nostack),
        );
    }
    let after = now();
    let _ = n;
    (
        2 * CAL_ITERATIONS,
        elapsed(before, after).saturating_sub(overhead),
    )
}

/// Counts between two back-to-back reads of the counter (subtracted from every
/// measurement).
pub fn read_overhead() -> u32 {
    let a = now();
    let b = now();
    elapsed(a, b)
}

/// `counts` of SysTick in instructions, by the calibration `(instructions,
/// counts)`, rounded to nearest.
pub fn instructions(counts: u32, calibration: (u32, u32)) -> u32 {
    let (ins, cal) = calibration;
    if cal == 0 {
        return 0;
    }
    ((u64::from(counts) * u64::from(ins) + u64::from(cal) / 2) / u64::from(cal)) as u32
}
