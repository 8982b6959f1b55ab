//! `host-sim scenario FILE [--format table|json]`: runs one scenario file
//! (`docs/scenarios.md`) and reports every expectation, PASS or FAIL, with what was
//! expected and what was measured.
//!
//! Stages:
//! 1. read and check the scenario and its machine ([`file::load`]): every
//!    problem at once with its key path, exit 2;
//! 2. run it ([`judge::run`]);
//! 3. write the report as a table or JSON; exit 0 when every expectation holds, 1
//!    when any fails.

pub mod driver;
pub mod file;
pub mod judge;
pub mod report;

use std::path::PathBuf;

use clap::Args;

use crate::args::Format;
use crate::args::FormatArg;
use crate::failure::{Console, Failure};
use crate::simulation::limits;

/// Arguments of `host-sim scenario`.
#[derive(Debug, Args)]
#[command(mut_arg("format", |a| a.help("Output format of the report")))]
pub struct ScenarioArgs {
    /// The scenario file (TOML; see docs/scenarios.md).
    #[arg(value_name = "SCENARIO.toml")]
    pub scenario: PathBuf,
    /// Output format.
    #[command(flatten)]
    pub format: FormatArg,
}

/// Runs the command (stages of the module doc). Expectations that do not hold are
/// a failed run (exit 1); the report has already said which.
pub fn run(args: &ScenarioArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    // 1. Read and check.
    let scenario = file::load(&args.scenario)?;

    let t_end_key = format!("{}: t_end", args.scenario.display());
    let problems = limits::check(&scenario.machine, scenario.t_end, &t_end_key);
    if !problems.is_empty() {
        return Err(Failure::Usage(problems.join("\n")));
    }

    // 2. Run.
    let report = judge::run(&scenario)?;
    if let Some(t) = report.stopped_at {
        return Err(Failure::Run(format!(
            "error: scenario: interrupted at t = {} s (Ctrl-C): nothing judged",
            crate::output::text::sig(t)
        )));
    }

    // 3. Report.
    console.print(&match args.format.format {
        Format::Table => report::table(&report),
        Format::Json => report::json(&report),
    });
    if report.passed() {
        Ok(())
    } else {
        Err(Failure::Run(String::new()))
    }
}

#[cfg(test)]
mod tests;
