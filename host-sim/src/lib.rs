//! host-sim: the vibro driver's simulator, impact analysis and tuning tool.
//!
//! Modules, from input to output:
//! - [`input`]: checked reading of TOML files, every problem with its key path;
//! - [`impact_case`]: the impact case file, checked into the solver's types;
//! - [`impact_command`]: `host-sim impact`, from file to printed result;
//! - [`impact_report`]: the result as the spec's JSON document or as a table;
//! - [`text`]: numbers and aligned tables for people;
//! - [`cli`]: the command line and exit statuses.
#![warn(missing_docs)]

pub mod cli;
pub mod impact_case;
pub mod impact_command;
pub mod impact_report;
pub mod input;
pub mod text;
