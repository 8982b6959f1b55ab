//! The command line: `host-sim <COMMAND> ...`, parsed with clap, dispatched to the
//! command's module, and its output written whole.
//!
//! Exit status: 0 success; 1 an internal failure (the solver gave up); 2 a user
//! mistake (bad or missing file, bad option value; clap's own usage errors are 2
//! too). User mistakes never panic: every problem is one line on stderr.
//!
//! More commands (`run`, `tune`, `scenario`, `device`) are added as variants of
//! [`Command`], each with its own arguments struct and module.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};
use shared::impact::ImpactLaw;

pub use crate::device::args::{DeviceArgs, DeviceSimArgs};
use crate::{device, impact_command, run_command, scenario_command, tune_command};

/// Exit status of a success.
pub const EXIT_OK: u8 = 0;
/// Exit status of an internal failure (not the user's mistake).
pub const EXIT_FAILURE: u8 = 1;
/// Exit status of a user mistake: bad input file or option (as clap's usage errors).
pub const EXIT_USAGE: u8 = 2;

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
    /// Talk to the board over its UART (a serial port or tcp:HOST:PORT): status,
    /// travel, stop, hold, reset, telemetry, self-test, tuning table (see
    /// docs/cli-device.md).
    Device(DeviceArgs),
    /// A simulated board to talk to with `device`: the firmware's controller and
    /// link on simulated rotors, behind a pseudo-terminal or a TCP port.
    DeviceSim(DeviceSimArgs),
}

/// Arguments of `host-sim scenario`.
#[derive(Debug, Args)]
pub struct ScenarioArgs {
    /// The scenario file (TOML; see docs/scenarios.md).
    #[arg(value_name = "SCENARIO.toml")]
    pub scenario: PathBuf,
    /// Output format of the report.
    #[arg(long, value_enum, default_value_t = Format::Table)]
    pub format: Format,
}

/// Arguments of `host-sim run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The machine file (TOML; see docs/machine-file.md).
    #[arg(value_name = "MACHINE.toml")]
    pub machine: PathBuf,
    /// Command the controller (the firmware's, in the loop at `rate_hz`): travel
    /// right or left at `--speed`, or stop.
    #[arg(long, value_enum, value_name = "right|left|stop")]
    pub command: Option<CommandArg>,
    /// Rotor speed for `--command`, rpm (default: `[controller].speed_rpm`).
    #[arg(long, value_name = "RPM")]
    pub speed: Option<f64>,
    /// Hold this phase offset, degrees, instead of the tuning table's.
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub offset: Option<f64>,
    /// Drive the windings open loop: constant voltages `V1,V2` (V, signed; `0,0`
    /// shorts the windings), or `coast` (windings open).
    #[arg(long, value_name = "V1,V2|coast", allow_hyphen_values = true)]
    pub open_loop: Option<String>,
    /// End time, s (default: the file's `simulation.t_end`).
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub t_end: Option<f64>,
    /// Write the trace as CSV (one row per `output_step`, and around each event).
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
    /// Write the events as CSV (one row per contact per event).
    #[arg(long, value_name = "FILE.csv")]
    pub events: Option<PathBuf>,
    /// Write a plot of the run as SVG.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Output format of the summary.
    #[arg(long, value_enum, default_value_t = Format::Table)]
    pub format: Format,
    /// Override a key of the machine file, e.g. `contacts.K1.friction=0.2`
    /// (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

/// Arguments of `host-sim tune`.
#[derive(Debug, Args)]
pub struct TuneArgs {
    /// The machine file (TOML; see docs/machine-file.md).
    #[arg(value_name = "MACHINE.toml")]
    pub machine: PathBuf,
    /// Rotor speeds, rpm: `A:B:STEP` from A to B, both included, or one value
    /// (default: `[controller].speed_rpm` -500 to +500 in steps of 250).
    #[arg(long, value_name = "A:B:STEP", allow_hyphen_values = true)]
    pub speeds: Option<String>,
    /// Phase offsets, degrees: `A:B:STEP` from A to B, both included (360 is 0
    /// and runs once), or one value [default: 0:360:15].
    #[arg(long, value_name = "A:B:STEP", allow_hyphen_values = true)]
    pub offsets: Option<String>,
    /// End time of each run, s; the mean velocity is over the second half
    /// [default: 5].
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub t_end: Option<f64>,
    /// Write the tuning table (best offsets per speed) that
    /// `[controller].tuning_table` names.
    #[arg(long, value_name = "FILE.toml")]
    pub write: Option<PathBuf>,
    /// Write a plot of mean velocity against offset, one line per speed, as SVG.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Output format of the result.
    #[arg(long, value_enum, default_value_t = Format::Table)]
    pub format: Format,
    /// Override a key of the machine file, e.g. `contacts.K1.friction=0.2`
    /// (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

/// Arguments of `host-sim impact`.
#[derive(Debug, Args)]
pub struct ImpactArgs {
    /// The impact case file (TOML; see docs/cli-impact.md).
    #[arg(value_name = "CASE.toml")]
    pub case: PathBuf,
    /// Impact law, overriding the file's `law` (whose default is poisson).
    #[arg(long, value_enum, value_name = "LAW")]
    pub law: Option<LawArg>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Table)]
    pub format: Format,
}

/// An impact law named on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LawArg {
    /// Poisson: restitution impulse = R x compression impulse (the paper's).
    Poisson,
    /// Newton: normal velocity after = -R x normal velocity before.
    Newton,
    /// Stronge: restitution work = R^2 x compression work.
    Stronge,
}

impl From<LawArg> for ImpactLaw {
    fn from(law: LawArg) -> Self {
        match law {
            LawArg::Poisson => ImpactLaw::Poisson,
            LawArg::Newton => ImpactLaw::Newton,
            LawArg::Stronge => ImpactLaw::Stronge,
        }
    }
}

/// What `--command` asks of the controller.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CommandArg {
    /// Travel right.
    Right,
    /// Travel left.
    Left,
    /// Stay stopped.
    Stop,
}

/// How a command prints its result.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Aligned text for people.
    Table,
    /// One JSON document for programs.
    Json,
}

/// What a command produced: its whole stdout and stderr text and its exit status.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Output {
    /// Text for stdout.
    pub stdout: String,
    /// Text for stderr (problems, one per line).
    pub stderr: String,
    /// Exit status ([`EXIT_OK`], [`EXIT_FAILURE`] or [`EXIT_USAGE`]).
    pub status: u8,
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Output {
    match cli.command {
        Command::Impact(args) => impact_command::run(&args),
        Command::Run(args) => run_command::run(&args),
        Command::Scenario(args) => scenario_command::run(&args),
        Command::Tune(args) => tune_command::run(&args),
        Command::Device(args) => device::commands::run(&args),
        Command::DeviceSim(args) => device::serve::run(&args),
    }
}

/// The program: parses the arguments (clap prints usage errors and exits 2 itself),
/// runs the command, writes its output once.
pub fn main() -> ExitCode {
    let output = run(Cli::parse());
    // A closed pipe (`host-sim ... | head`) is not an error worth a message.
    let _ = std::io::stdout().lock().write_all(output.stdout.as_bytes());
    let _ = std::io::stderr().lock().write_all(output.stderr.as_bytes());
    ExitCode::from(output.status)
}

#[cfg(test)]
mod tests {
    use super::*;
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
        assert_eq!(a.format, Format::Table);
        let e = Cli::try_parse_from(["host-sim", "impact", "c.toml", "--law", "x"]).unwrap_err();
        assert_eq!(e.exit_code(), i32::from(EXIT_USAGE));
    }
}
