//! SysTick as an instruction counter in QEMU: the counter's reads and the loop of
//! known length that measures counts per instruction.
//!
//! Under `-icount shift=0` every guest instruction advances QEMU's virtual clock
//! by exactly 1 ns, and netduinoplus2's SysTick counts that clock at 168 MHz, so
//! `n` instructions move it on by about `0.168 n` counts. [`count_loop`] measures
//! the ratio rather than assuming it.
//!
//! This file uses `cortex_m` alone: `benchmarks/impact-m4`, a workspace of its
//! own without RTIC and the HAL, includes it by path and measures the same way.

use cortex_m::peripheral::SYST;

/// The counter now (it counts down).
#[inline(always)]
pub fn now() -> u32 {
    SYST::get_current()
}

/// Counts elapsed from the read `before` to the later read `after`, the counter
/// not having wrapped in between.
#[inline(always)]
pub fn elapsed(before: u32, after: u32) -> u32 {
    before.wrapping_sub(after)
}

/// Counts between two back-to-back reads of the counter: the cost of a read,
/// subtracted from a measurement.
pub fn read_overhead() -> u32 {
    let a = now();
    let b = now();
    elapsed(a, b)
}

/// `(instructions, counts)` of `iterations` passes of a two-instruction loop
/// (`subs`, `bne`), the counts less the cost of reading the counter.
///
/// SysTick must be running, its reload above the loop's counts, with no
/// interrupt taken meanwhile; a caller that cannot rule out a wrap checks
/// COUNTFLAG around the call.
pub fn count_loop(iterations: u32) -> (u32, u32) {
    let overhead = read_overhead();
    let before = now();
    let mut n = iterations;
    // SAFETY: a countdown in one register, no memory touched.
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
    core::hint::black_box(n);
    (
        iterations.saturating_mul(2),
        elapsed(before, after).saturating_sub(overhead),
    )
}
