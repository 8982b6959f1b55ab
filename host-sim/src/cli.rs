//! The command line: `host-sim <COMMAND> ...`, parsed with clap, dispatched to the
//! command's module, and its output written whole.
//!
//! Each command owns its arguments (`run::RunArgs`, ...) and its module; the
//! arguments several commands share are declared once in [`crate::args`]. Every
//! command returns `Result<(), Failure>` ([`crate::failure`]); [`execute`] is the
//! one place that writes a failure's message and turns it into the exit status:
//! 0 success; 1 a failed run or a device failure; 2 a user mistake (bad or missing
//! file, bad option value; clap's own usage errors are 2 too). User mistakes never
//! panic: every problem is one line on stderr.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::calibrate::CalibrateArgs;
use crate::device::args::{DeviceArgs, DeviceSimArgs};
use crate::failure::{Console, Failure, EXIT_OK};
use crate::impact::ImpactArgs;
use crate::run::RunArgs;
use crate::scenario::ScenarioArgs;
use crate::tune::merge::MergeArgs;
use crate::tune::TuneArgs;
use crate::{calibrate, device, impact, run, scenario, tune};

/// The vibro driver's host simulator, impact analysis and tuning tool.
#[derive(Debug, Parser)]
#[command(name = "host-sim", version, about, propagate_version = true)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Solve one impact of a rigid body at one or several contact points.
    Impact(ImpactArgs),
    /// Simulate a machine file: the platform, its rotors, motors and impacts.
    Run(RunArgs),
    /// Run a scenario file: timed commands and injected faults, with expectations
    /// judged PASS or FAIL (exit 0 all pass, 1 any fails, 2 a bad file).
    Scenario(ScenarioArgs),
    /// Sweep rotor speed and phase offset in closed loop; find the best offsets
    /// for rightward and leftward travel at each speed (see docs/tuning.md).
    Tune(TuneArgs),
    /// Combine the partial results of `tune --shard I/N` into the whole sweep's
    /// output, as `tune` without `--shard` gives it (see docs/scale-out.md).
    Merge(MergeArgs),
    /// Fit keys of the machine file to travel speeds measured on the real machine
    /// (see docs/calibration.md).
    Calibrate(CalibrateArgs),
    /// Talk to the board over its UART (a serial port or tcp:HOST:PORT): status,
    /// travel, stop, hold, reset, telemetry, self-test, tuning table (see
    /// docs/cli-device.md).
    Device(DeviceArgs),
    /// A simulated board to talk to with `device`: the firmware's controller and
    /// link on simulated rotors, behind a pseudo-terminal or a TCP port.
    DeviceSim(DeviceSimArgs),
}

/// What a command produced, captured: its whole stdout and stderr text and its exit
/// status (for tests and for callers that run a command inside the process).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Output {
    /// Text for stdout.
    pub stdout: String,
    /// Text for stderr (problems, one per line).
    pub stderr: String,
    /// Exit status.
    pub status: u8,
}

/// Runs a parsed command line on `console`; writes a failure's message there and
/// returns the exit status.
pub fn execute(cli: Cli, console: &mut Console<'_>) -> u8 {
    let result: Result<(), Failure> = match cli.command {
        Command::Impact(args) => impact::run(&args, console),
        Command::Run(args) => run::run(&args, console),
        Command::Scenario(args) => scenario::run(&args, console),
        Command::Tune(args) => tune::run(&args, console),
        Command::Merge(args) => tune::merge::run(&args, console),
        Command::Calibrate(args) => calibrate::run(&args, console),
        Command::Device(args) => device::commands::run(&args, console),
        Command::DeviceSim(args) => device::serve::run(&args, console),
    };
    match result {
        Ok(()) => EXIT_OK,
        Err(failure) => {
            console.note(&failure.message());
            failure.status()
        }
    }
}

/// Runs a parsed command line with its output captured.
pub fn run(cli: Cli) -> Output {
    let (mut stdout, mut stderr) = (Vec::new(), Vec::new());
    let status = execute(cli, &mut Console::new(&mut stdout, &mut stderr));
    Output {
        stdout: String::from_utf8_lossy(&stdout).into_owned(),
        stderr: String::from_utf8_lossy(&stderr).into_owned(),
        status,
    }
}

/// The program: parses the arguments (clap prints usage errors and exits 2 itself),
/// runs the command with its output going out as it comes.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    // Unlocked handles: a command's threads may print too.
    let (mut out, mut err) = (std::io::stdout(), std::io::stderr());
    let status = execute(cli, &mut Console::new(&mut out, &mut err));
    ExitCode::from(status)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::args::Format;
    use crate::failure::EXIT_USAGE;
    use crate::impact::LawArg;
    use clap::CommandFactory;

    #[test]
    fn the_command_line_is_well_formed() {
        Cli::command().debug_assert();
    }

    #[test]
    fn impact_options_parse() {
        let cli = Cli::try_parse_from(["host-sim", "impact", "c.toml", "--law", "newton"]).unwrap();
        let Command::Impact(a) = cli.command else {
            panic!("parsed as another command");
        };
        assert_eq!(a.law, Some(LawArg::Newton));
        assert_eq!(a.format.format, Format::Table);
        let e = Cli::try_parse_from(["host-sim", "impact", "c.toml", "--law", "x"]).unwrap_err();
        assert_eq!(e.exit_code(), i32::from(EXIT_USAGE));
    }
}
