//! `host-sim device` (the host's end of the UART link to the board) and
//! `host-sim device-sim` (a board without hardware), both speaking the `shared`
//! protocol over the link of [`crate::link`] (`docs/protocol.md`,
//! `docs/cli-device.md`).
//!
//! - [`args`]: the command lines;
//! - [`commands`]: `host-sim device <COMMAND>`, from options to printed answers;
//! - [`telemetry_stream`]: the telemetry stream turned on, heartbeated, watched
//!   for silence and turned off, each frame to a sink;
//! - [`telemetry`]: `host-sim device telemetry`, the stream printed;
//! - [`live`]: `host-sim device telemetry --serve`, the stream on a live web page;
//! - [`tune`]: `host-sim device tune`, the tuning sweep on the machine, answers
//!   from the operator appended to a [`measured`] file, the table made by
//!   [`tune_table`];
//! - [`procedure`]: a procedure the device runs on its own (the self-test, the
//!   motor identification), asked for, watched and stopped on Ctrl-C;
//! - [`identify`]: `host-sim device identify`, the motors measured, compared with
//!   a machine file and written into one;
//! - [`capture`]: `host-sim device capture`, a window of control ticks recorded
//!   on the board, read out and written as a capture file;
//! - [`report`]: status, telemetry (lines, CSV) and self-test for people;
//! - Ctrl-C as a flag, so streams end cleanly: [`crate::interrupt`];
//! - [`plant`]: what the simulated device drives and senses, a tick at a time: a
//!   machine's plant with its sensors, its platform free or held;
//! - [`sim`]: the simulated device: the firmware's control tick and link task;
//! - [`truth`]: the platform's true pose streamed to a CSV file (`--truth`);
//! - [`serve`]: `host-sim device-sim`, the simulated device in real time behind a
//!   pseudo-terminal or a TCP port.

pub mod args;
pub mod capture;
pub mod commands;
pub mod identify;
pub mod live;
pub mod measured;
pub mod plant;
pub mod procedure;
pub mod report;
pub mod serve;
pub mod sim;
pub mod telemetry;
pub mod telemetry_stream;
pub mod truth;
pub mod tune;
pub mod tune_table;
