//! host-sim: the vibro driver's simulator, impact analysis and tuning tool.
//!
//! One folder per command and one per concept; a command's folder holds its
//! arguments' handling, its stages and its outputs. From input to output:
//! - [`machine`]: the machine file and the tuning file, read and checked into plain
//!   values (every problem with its key path), `--set` overrides, the checked TOML
//!   reader the other files use: the `machine-file` crate, which the firmware's
//!   build script reads the same files with;
//! - [`measured`]: the measured travel file, one row per run on the real machine,
//!   which `device tune` writes and `calibrate` reads;
//! - [`plant`]: the simulated platform, rotors, motors, contacts and sensors;
//! - [`event`]: what happened at an instant of a run (the `--events` rows), which
//!   the plant and the controller in the loop both write;
//! - [`simulation`]: a whole run, tick by tick, with the `shared` controller in the
//!   loop, its trace, events and summary statistics;
//! - [`output`]: whole files, CSV, SVG pieces and tables for people;
//! - [`numbers`]: figures and counts written for people and files;
//! - [`failure`]: the error model, a failure's kind and its reasons;
//! - [`sweep`]: the sweep of speeds and phase offsets, below the commands that
//!   sweep (`tune`, `calibrate`, `device tune`);
//! - [`parts`]: a computation in parts (`--shard`) and `merge`'s arguments;
//! - [`link`]: the host's end of the UART link to a board (a serial port, TCP or
//!   a pseudo-terminal, and the protocol's client);
//! - the commands: [`impact`] (one impact from a case file), [`run`] (a machine file
//!   simulated), [`scenario`] (timed commands, injected faults, judged
//!   expectations), [`tune`] (the sweep of speed and phase offset), [`calibrate`]
//!   (machine keys fitted to measured travel), [`device`] (a board over the
//!   link, and a simulated board);
//! - [`cli`]: the top-level command line and the one place that turns a
//!   command's result into output and an exit status; [`args`]: the arguments
//!   commands share; [`help`]: the end of every `--help` (examples and documents);
//!   [`interrupt`]: Ctrl-C and the termination signals as a flag.
//!
//! docs/development.md draws these as layers (a module uses only lower ones),
//! checked by `host-sim/tests/layers.rs`.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod args;
pub mod calibrate;
pub mod capture;
pub mod cli;
pub mod device;
pub mod event;
pub mod failure;
pub mod help;
pub mod identity;
pub mod impact;
pub mod interrupt;
pub mod link;
pub use machine_file as machine;
pub mod measured;
pub mod numbers;
pub mod output;
pub mod parts;
pub mod plant;
pub mod replay;
pub mod run;
pub mod scenario;
pub mod simulation;
pub mod sweep;
pub mod tune;
