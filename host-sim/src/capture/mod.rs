//! A capture as a file: the board's records of every control tick of a window
//! (`shared::capture`) with what a replay needs to start where the board was,
//! written by `host-sim device capture` and read by `host-sim replay` and
//! `host-sim calibrate --capture` (docs/cli-device.md, "capture").
//!
//! - [`mod@file`]: the CSV text, written and read, its checksum and every check a
//!   read makes (docs/protocol.md, "Capture file").

pub mod file;

pub use file::{CaptureFile, Header};

/// The largest speed estimate at a capture's start that counts as settled at
/// rest, rpm. A replay's controllers start with their speed filters at 0; the
/// board's decays there from the last count it saw move (one count a tick is
/// 14.6 rpm at 4096 counts a turn and 1 kHz), so a filter still above this
/// would make the board's first duties differ from the re-run's.
pub const SETTLED_RPM: f32 = 0.01;

/// Whether a status shows the machine settled for a capture to start from:
/// idle, both speed estimates within [`SETTLED_RPM`].
pub fn settled(s: &shared::protocol::StatusReport) -> bool {
    s.state == shared::controller::State::Idle
        && s.telemetry.speed_rpm.iter().all(|v| v.abs() <= SETTLED_RPM)
}
