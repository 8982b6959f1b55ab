//! The control tick's timing from a cycle counter: how late each tick started and
//! how long the previous one worked ([`TickTiming`]), what the
//! controller's deadline check (`Faults::DEADLINE`) looks at.
//!
//! Two measurements of lateness, the larger counts:
//! - the *latency*: cycles from the tick's timer event to the task's first
//!   instruction (the board reads TIM7's counter, which restarts at the update
//!   event; the `qemu` build reads SysTick's, which reloads);
//! - the *interval*: cycles from the previous tick's start, less one period, so
//!   a tick delayed past a whole period (the latency then reads small again: the
//!   timer has wrapped) still shows.
//!
//! ```text
//!   late = max(latency, (start_n - start_{n-1}) - T)      cycles
//!   busy = end_{n-1} - start_{n-1}                         cycles
//! ```
//!
//! The counter is a free-running, wrapping `u32` (the board's DWT cycle counter:
//! 2^32 / 168 MHz = 25.6 s a lap, far above any interval measured here).

use crate::controller::TickTiming;

/// The control loop's clock: the previous tick's start and duration.
pub struct TickClock {
    /// Cycles per second of the counter, as f32 for the conversion.
    hz: f32,
    /// Cycles per control period.
    period: u32,
    /// The cycle count at the previous tick's start (none before the first).
    last_start: Option<u32>,
    /// The previous tick's duration, cycles.
    last_busy: u32,
}

impl TickClock {
    /// A clock counting `hz` cycles per second, ticks every `period` cycles.
    pub const fn new(hz: u32, period: u32) -> Self {
        TickClock {
            hz: hz as f32,
            period,
            last_start: None,
            last_busy: 0,
        }
    }

    /// At a tick's start: `now` the counter, `latency` the cycles since the
    /// tick's timer event. The timing for this tick's inputs.
    pub fn begin(&mut self, now: u32, latency: u32) -> TickTiming {
        let interval_late = match self.last_start {
            Some(last) => now.wrapping_sub(last).saturating_sub(self.period),
            None => 0,
        };
        self.last_start = Some(now);
        TickTiming {
            late_s: latency.max(interval_late) as f32 / self.hz,
            busy_s: self.last_busy as f32 / self.hz,
        }
    }

    /// The previous tick's duration (from [`TickClock::begin`] to
    /// [`TickClock::end`]), cycles; 0 before the first tick has ended.
    pub fn last_busy(&self) -> u32 {
        self.last_busy
    }

    /// At a tick's end: `now` the counter. Its duration goes into the next
    /// tick's timing.
    pub fn end(&mut self, now: u32) {
        if let Some(start) = self.last_start {
            self.last_busy = now.wrapping_sub(start);
        }
    }
}
