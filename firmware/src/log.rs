//! What the control task has to say, logged by the idle task: the control task
//! never formats a log line.
//!
//! defmt encodes and copies every line into the RTT buffer on the caller's
//! stack and time. The board's logger is non-blocking and never masks interrupts
//! (`defmt-rtt` with `disable-blocking-mode` and `drop-on-contention`: a full
//! buffer or a line interrupted by another drops the line), so a log line cannot
//! stall the loop; logging from idle also keeps the lines' cost out of the
//! tick's budget (`Faults::DEADLINE`). The control task only raises flags
//! ([`note`]) and publishes its status; idle reads the status
//! the link already shares and logs ([`Logger::poll`]):
//!
//! - every state change, with the faults;
//! - the telemetry once a second while the motors are driven;
//! - the events flagged by the control task (a tuning table or a self-test
//!   refused);
//! - received bytes lost, when their count grows.
//!
//! A state that lasts less than one idle pass (the control task publishes every
//! tick, idle may be busy for longer) is not logged; the link's status and the
//! controller's latched faults still have it.

use core::sync::atomic::{AtomicU8, Ordering};

use shared::controller::State;
use shared::protocol::StatusReport;

/// An event the control task flags for the log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Event {
    /// A new tuning table was not taken: the motors were running.
    TuningRefused = 1 << 0,
    /// A self-test was not started: not idle, a fault, or a rotor turning.
    SelfTestRefused = 1 << 1,
    /// An identification was not started: not idle, a fault, or a rotor turning.
    IdentifyRefused = 1 << 2,
}

/// The flags raised since idle last looked.
static EVENTS: AtomicU8 = AtomicU8::new(0);

/// Flag `event` for the log (any context; a single atomic OR).
pub fn note(event: Event) {
    EVENTS.fetch_or(event as u8, Ordering::Relaxed);
}

/// Period of the telemetry line in the log while the motors are driven, ms.
pub const TELEMETRY_LOG_MS: u32 = 1000;

/// The idle task's side: what it last logged.
pub struct Logger {
    last_state: Option<State>,
    last_telemetry_ms: u32,
    last_rx_dropped: u16,
}

impl Default for Logger {
    fn default() -> Self {
        Logger::new()
    }
}

impl Logger {
    /// Nothing logged yet.
    pub const fn new() -> Self {
        Logger {
            last_state: None,
            last_telemetry_ms: 0,
            last_rx_dropped: 0,
        }
    }

    /// Log what changed since the last call, from the status the control task
    /// published.
    pub fn poll(&mut self, status: &StatusReport) {
        let events = EVENTS.swap(0, Ordering::Relaxed);
        if events & Event::TuningRefused as u8 != 0 {
            defmt::warn!("new tuning table not taken: motors running");
        }
        if events & Event::SelfTestRefused as u8 != 0 {
            defmt::warn!("self-test not started: not idle, a fault, or a rotor turning");
        }
        if events & Event::IdentifyRefused as u8 != 0 {
            defmt::warn!("identification not started: not idle, a fault, or a rotor turning");
        }
        if status.rx_dropped != self.last_rx_dropped {
            defmt::warn!(
                "link: {=u16} received bytes lost since start (ring full or UART error)",
                status.rx_dropped
            );
            self.last_rx_dropped = status.rx_dropped;
        }
        if self.last_state != Some(status.state) {
            // The first status is the one at start, which `start` has logged.
            if self.last_state.is_some() {
                defmt::info!(
                    "state {=str}, faults {}",
                    status.state.name(),
                    status.faults
                );
            }
            self.last_state = Some(status.state);
        }
        // The defmt side of the telemetry: once a second while the motors are
        // driven (the full stream at any rate is the link's, `StreamTelemetry`).
        let now = status.uptime_ms;
        if status.state.drives() && now.wrapping_sub(self.last_telemetry_ms) >= TELEMETRY_LOG_MS {
            self.last_telemetry_ms = now;
            let t = &status.telemetry;
            defmt::info!(
                "speed {=f32} {=f32} rpm (ref {=f32} {=f32}), offset {=f32} deg (target {=f32}, loop closed {=bool}), current {=f32} {=f32} A, duty {=f32} {=f32}, tick late {=u16} us busy {=u16} us",
                t.speed_rpm[0],
                t.speed_rpm[1],
                t.speed_ref_rpm[0],
                t.speed_ref_rpm[1],
                t.phase_offset_deg,
                t.target_offset_deg,
                t.phase_loop_closed,
                t.current[0],
                t.current[1],
                t.duty[0],
                t.duty[1],
                t.tick_late_us,
                t.tick_busy_us
            );
        }
    }
}
