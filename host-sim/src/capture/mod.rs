//! A capture as a file: the board's records of every control tick of a window
//! (`shared::capture`) with what a replay needs to start where the board was,
//! written by `host-sim device capture` and read by `host-sim replay` and
//! `host-sim calibrate --capture` (docs/cli-device.md, "capture").
//!
//! - [`mod@file`]: the CSV text, written and read, its checksum and every check a
//!   read makes (docs/protocol.md, "Capture file").

pub mod file;

pub use file::{CaptureFile, Header};
