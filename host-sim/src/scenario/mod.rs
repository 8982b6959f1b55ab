//! `host-sim scenario FILE [--format table|json] [--animate FILE.html]
//! [--firmware ELF [--firmware-log FILE]]`: runs one scenario file
//! (`docs/scenarios.md`) with the controller in the loop, or the firmware on QEMU
//! (`docs/pil.md`), and reports every expectation, PASS or FAIL, with what was
//! expected and what was measured.
//!
//! Stages:
//! 1. read and check the scenario and its machine ([`file::load`]): every
//!    problem at once with its key path, exit 2;
//! 2. run it ([`judge::run_observed`]), filmed for `--animate`; with
//!    `--firmware`, QEMU stopped and the firmware's log written after it;
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
use crate::failure::{Console, Failure, Kind};
use crate::help::epilogue;
use crate::output::animate::{self, frames::Frames, Film};
use crate::output::file::Staged;
use crate::simulation::pil::FirmwareDriver;
use crate::simulation::{limits, Driver, Interruptible};
use driver::{InTheLoop, ScenarioDriver};

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
    &["docs/scenarios.md", "docs/pil.md", "docs/cli-run.md#limits"],
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
    /// Run the firmware's binary `pil` (built for the scenario's machine file:
    /// `cd firmware && cargo build --release --features pil --bin pil`) on QEMU
    /// as the controller (processor in the loop, docs/pil.md).
    #[arg(long, value_name = "ELF")]
    pub firmware: Option<PathBuf>,
    /// With --firmware: where its decoded defmt log goes (default: ELF.log).
    #[arg(long, value_name = "FILE", requires = "firmware")]
    pub firmware_log: Option<PathBuf>,
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
        return Err(Failure::new(Kind::Usage, problems));
    }

    // 2. Run, the output files opened first (refused before the run).
    let firmware_log = args.firmware.as_ref().map(|elf| {
        args.firmware_log
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("{}.log", elf.display())))
    });
    let mut staged = Staged::new();
    let animation = staged.add_optional("--animate", args.animate.as_deref())?;
    let log = staged.add_optional("--firmware-log", firmware_log.as_deref())?;
    let mut driver = match &args.firmware {
        Some(elf) => {
            driver::refused_in_pil(&scenario)?;
            let firmware = FirmwareDriver::start(
                &scenario.machine,
                &scenario.machine_file,
                elf,
                driver::schedule(&scenario),
            )?;
            ScenarioDriver::new(&scenario, InTheLoop::Firmware(Box::new(firmware)))
        }
        None => ScenarioDriver::controller(&scenario),
    };
    let mut film = Film {
        frames: animation.map(|_| Frames::new(&scenario.machine)),
        inner: &mut Interruptible::new(),
    };
    let mut report = judge::run_observed(&scenario, &mut driver, &mut film);
    let failure = driver.failure();
    if let InTheLoop::Firmware(f) = &mut driver.inner {
        f.finish();
        report.warnings.extend(f.warnings());
        if let (Some(why), Some(path)) = (failure, &firmware_log) {
            // The firmware's log is kept, to say why; nothing else is written.
            let _ = std::fs::write(path, f.log());
            return Err(why.with_detail(format!("the firmware's log: {}", path.display())));
        }
        if let Some(i) = log {
            staged.write(i, f.log())?;
        }
    }

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
        return Err(Failure::run(format!(
            "scenario: {why}: nothing judged{}",
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
        Err(Failure::reported(Kind::Run))
    }
}

#[cfg(test)]
mod tests;
