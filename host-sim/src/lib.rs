//! host-sim: the vibro driver's simulator, impact analysis and tuning tool.
//!
//! Modules, from input to output:
//! - [`input`]: checked reading of TOML files, every problem with its key path;
//! - [`impact_case`]: the impact case file, checked into the solver's types;
//! - [`impact_command`]: `host-sim impact`, from file to printed result;
//! - [`impact_report`]: the result as the spec's JSON document or as a table;
//! - [`text`]: numbers and aligned tables for people;
//! - [`machine`]: the machine file, checked into plain values;
//! - [`machine_set`]: `--set KEY=VALUE` overrides of machine-file keys;
//! - [`plant`]: the simulated platform, rotors, motors, contacts and sensors;
//! - [`trace`]: what a run records (trace rows, events, summary);
//! - [`summary`]: the run's summary statistics computed from its trace and events;
//! - [`run_output`]: the summary as JSON or a table, trace and events as CSV, whole files;
//! - [`plot`]: the run as an SVG figure for people;
//! - [`closed_loop`]: the `shared` controller in the loop with the simulated sensors;
//! - [`simulation`]: a whole run, tick by tick, with trace, events and summary;
//! - [`run_command`]: `host-sim run`, from machine file to outputs;
//! - [`scenario`]: scenario files (timed commands, injected faults, expectations)
//!   and their runner;
//! - [`scenario_command`]: `host-sim scenario`, from scenario file to PASS/FAIL report;
//! - [`tuning_file`]: the tuning table file (speed -> best offsets);
//! - [`tune_command`]: `host-sim tune`, the sweep of speed and offset, best offsets;
//! - [`tune_plot`]: the sweep as an SVG figure for people;
//! - [`svg`]: text escaping and axis ticks for the SVG figures;
//! - [`device`]: `host-sim device` (the UART link to the board) and
//!   `host-sim device-sim` (a simulated board to talk to);
//! - [`cli`]: the command line and exit statuses.
#![warn(missing_docs)]

pub mod cli;
pub mod closed_loop;
pub mod device;
pub mod impact_case;
pub mod impact_command;
pub mod impact_report;
pub mod input;
pub mod machine;
pub mod machine_set;
pub mod plant;
pub mod plot;
pub mod run_command;
pub mod run_output;
pub mod scenario;
pub mod scenario_command;
pub mod simulation;
pub mod summary;
pub mod svg;
pub mod text;
pub mod trace;
pub mod tune_command;
pub mod tune_plot;
pub mod tuning_file;
