//! `host-sim scenario FILE [--format table|json] [--animate FILE.html]`: runs one
//! scenario file (`docs/scenarios.md`) and reports every expectation, PASS or FAIL,
//! with what was expected and what was measured.
//!
//! Stages:
//! 1. read and check the scenario and its machine ([`file::load`]): every
//!    problem at once with its key path, exit 2;
//! 2. run it ([`judge::run`]), filmed for `--animate`;
//! 3. write the animation (whole or not at all, [`crate::output::animate`]; also
//!    when an expectation fails), then the report as a table or JSON; exit 0 when
//!    every expectation holds, 1 when any fails.

pub mod driver;
pub mod file;
pub mod judge;
pub mod report;

use std::path::PathBuf;

use clap::Args;

use crate::args::Format;
use crate::args::FormatArg;
use crate::failure::{Console, Failure};
use crate::help::epilogue;
use crate::output::animate::{self, frames::Frames, Film};
use crate::output::file::Staged;
use crate::simulation::{limits, Interruptible};

/// Arguments of `host-sim scenario`.
#[derive(Debug, Args)]
#[command(mut_arg("format", |a| a.help("Output format of the report")))]
#[command(mut_arg("animate", |a| a.help(animate::option_help())))]
#[command(after_help = epilogue(
    &[
        "host-sim scenario tests/scenarios/travel-right.toml",
        "host-sim scenario tests/scenarios/estop.toml --format json --animate estop.html",
    ],
    &[],
    &["docs/scenarios.md", "docs/cli-run.md#limits"],
))]
pub struct ScenarioArgs {
    /// The scenario file (TOML; see docs/scenarios.md).
    #[arg(value_name = "SCENARIO.toml")]
    pub scenario: PathBuf,
    /// Output format.
    #[command(flatten)]
    pub format: FormatArg,
    /// Write the run as an HTML page that plays it ([`animate::option_help`]).
    #[arg(long, value_name = "FILE.html")]
    pub animate: Option<PathBuf>,
}

/// Runs the command (stages of the module doc). Expectations that do not hold are
/// a failed run (exit 1); the report has already said which.
pub fn run(args: &ScenarioArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    // 1. Read and check.
    let scenario = file::load(&args.scenario)?;

    let t_end_key = format!("{}: t_end", args.scenario.display());
    let mut problems = limits::check(&scenario.machine, scenario.t_end, &t_end_key);
    if args.animate.is_some() {
        problems.extend(animate::check_duration(scenario.t_end, &t_end_key));
    }
    if !problems.is_empty() {
        return Err(Failure::Usage(problems.join("\n")));
    }

    // 2. Run, the animation's file opened first (refused before the run).
    let mut staged = Staged::new();
    let animation = staged.add_optional("--animate", args.animate.as_deref())?;
    let mut film = Film {
        frames: animation.map(|_| Frames::new(&scenario.machine)),
        inner: &mut Interruptible::new(),
    };
    let report = judge::run_observed(&scenario, &mut film)?;

    // 3. The animation, then the report.
    if let (Some(i), Some(mut frames)) = (animation, film.frames) {
        let title = format!(
            "host-sim scenario {} (machine {})",
            args.scenario.display(),
            scenario.machine_file.display()
        );
        staged.write(i, &animate::page(&title, &scenario.machine, &mut frames))?;
    }
    staged.commit()?;
    if let Some(stop) = &report.stopped {
        let why = crate::simulation::stop_message(stop, None);
        return Err(Failure::Run(format!(
            "error: scenario: {why}: nothing judged{}",
            if args.animate.is_some() {
                "; the animation holds the run up to there"
            } else {
                ""
            }
        )));
    }

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
