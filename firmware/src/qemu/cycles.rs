//! SysTick: the control tick of the `qemu` binaries, and the clock that times one
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
use shared::controller::TickTiming;
use shared::timing::TickClock;

use super::counter::{count_loop, now};

/// SysTick's clock in QEMU's netduinoplus2, Hz.
pub const SYSTICK_HZ: u32 = 168_000_000;
/// SysTick reload for one control tick.
pub const RELOAD: u32 = SYSTICK_HZ / shared::controller::CONTROL_RATE_HZ as u32 - 1;

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

/// Counts since the counter last reloaded from `reload`: the latency of the
/// control task from its timer event, when read at the task's start.
#[inline(always)]
pub fn since_reload(reload: u32) -> u32 {
    reload.saturating_sub(now())
}

/// The control tick's timing in the `qemu` binaries: [`TickClock`] on SysTick
/// counts, standing in for the board's TIM7 counter and DWT cycle counter. The
/// free-running count is the ticks' whole periods plus the counts since the
/// latest reload; exact while no tick is skipped (a skipped tick shows in the
/// next tick's lateness anyway).
pub struct SysTickClock {
    clock: TickClock,
    reload: u32,
    /// Periods before the current tick's.
    laps: u32,
    /// Counts from the reload to the current tick's start.
    latency: u32,
}

impl SysTickClock {
    /// For a tick every `reload + 1` counts.
    pub const fn new(reload: u32) -> Self {
        SysTickClock {
            clock: TickClock::new(SYSTICK_HZ, reload + 1),
            reload,
            laps: 0,
            latency: 0,
        }
    }

    /// At the start of tick number `tick` (1 for the first): its timing.
    pub fn begin(&mut self, tick: u32) -> TickTiming {
        self.latency = since_reload(self.reload);
        self.laps = tick.wrapping_sub(1);
        let now = self.count(self.laps, self.latency);
        self.clock.begin(now, self.latency)
    }

    /// At the end of the tick: a period later if the counter reloaded meanwhile
    /// (at most once: a longer tick has missed the next, which its lateness shows).
    pub fn end(&mut self) {
        let since = since_reload(self.reload);
        let laps = if since < self.latency {
            self.laps.wrapping_add(1)
        } else {
            self.laps
        };
        self.clock.end(self.count(laps, since));
    }

    /// The previous tick's duration, ns of virtual time: SysTick's counts at
    /// [`SYSTICK_HZ`], `ns = counts x 10^9 / SYSTICK_HZ`, rounded down (one
    /// instruction each under `-icount shift=0`).
    pub fn last_busy_ns(&self) -> u32 {
        let ns = u64::from(self.clock.last_busy()) * 1_000_000_000 / u64::from(SYSTICK_HZ);
        u32::try_from(ns).unwrap_or(u32::MAX)
    }

    fn count(&self, laps: u32, since: u32) -> u32 {
        laps.wrapping_mul(self.reload + 1).wrapping_add(since)
    }
}

/// Spin for `counts` SysTick counts, across reloads from `reload` (the counter
/// counts down): an injected overrun of the control task.
pub fn spin(counts: u32, reload: u32) {
    let mut last = now();
    let mut spent = 0u32;
    while spent < counts {
        let t = now();
        spent = spent.saturating_add(if t <= last {
            last - t
        } else {
            last + (reload + 1 - t)
        });
        last = t;
    }
}

/// The calibration: `(instructions, counts)` of a loop of known length
/// ([`count_loop`]). SysTick must be running with a reload above the loop's
/// counts, interrupts off.
pub fn calibrate() -> (u32, u32) {
    // Right after it is cleared the counter reads 0 until it reloads.
    while now() == 0 {}
    count_loop(CAL_ITERATIONS)
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
