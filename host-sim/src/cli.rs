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
use crate::help::epilogue;
use crate::impact::ImpactArgs;
use crate::parts::MergeArgs;
use crate::replay::ReplayArgs;
use crate::run::RunArgs;
use crate::scenario::ScenarioArgs;
use crate::tune::TuneArgs;
use crate::{calibrate, device, impact, replay, run, scenario, tune};

/// The vibro driver's host simulator, impact analysis and tuning tool.
#[derive(Debug, Parser)]
#[command(name = "host-sim", version, about, propagate_version = true)]
#[command(after_help = epilogue(
    &[
        "host-sim run examples/vibro-driver.toml --command right --t-end 5",
        "host-sim impact examples/impact/fig7-four-points.toml",
    ],
    &["Every command's --help ends with its own examples and documents.".to_string()],
    &["README.md", "docs/cli-run.md"],
))]
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
    /// Fit keys of the machine file to travel speeds measured on the real machine,
    /// or its motor keys to a capture of the board (see docs/calibration.md).
    Calibrate(CalibrateArgs),
    /// Drive the twin with a capture's commands from the capture's start and
    /// compare, tick by tick, speeds, phase offset, currents and duties with
    /// what the board recorded (see docs/calibration.md).
    Replay(ReplayArgs),
    /// Talk to the board over its UART (a serial port or tcp:HOST:PORT): status,
    /// travel, stop, hold, reset, telemetry, self-test, identify (the motors
    /// measured), capture (every control tick of a window, recorded on the
    /// board), table (the tuning table), tune (a sweep measured on the machine)
    /// (see docs/cli-device.md).
    Device(DeviceArgs),
    /// A simulated board to talk to with `device`: the firmware's controller and
    /// link on a simulated machine (the reference machine's rotors, the platform
    /// held, or a machine file's plant), behind a pseudo-terminal or a TCP port.
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
    // The simulating commands end at their next control tick on SIGINT, SIGTERM
    // or SIGHUP, their files whole ([`crate::interrupt`]): caught from the start,
    // so that a signal while they read their inputs and open their outputs is
    // theirs to handle too, not the end of the process.
    if matches!(
        cli.command,
        Command::Run(_)
            | Command::Scenario(_)
            | Command::Tune(_)
            | Command::Merge(_)
            | Command::Calibrate(_)
            | Command::Replay(_)
    ) {
        crate::interrupt::catch();
    }
    let result: Result<(), Failure> = match cli.command {
        Command::Impact(args) => impact::run(&args, console),
        Command::Run(args) => run::run(&args, console),
        Command::Scenario(args) => scenario::run(&args, console),
        Command::Tune(args) => tune::run(&args, console),
        // A fit's parts (calibrate --shard) or a sweep's (tune --shard).
        Command::Merge(args) if calibrate::part::names_a_fit(&args.parts) => {
            calibrate::part::merge(&args, console)
        }
        Command::Merge(args) => tune::merge::run(&args, console),
        Command::Calibrate(args) => calibrate::run(&args, console),
        Command::Replay(args) => replay::run(&args, console),
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

    /// Every command, `host-sim` itself and its subcommands at any depth (clap's
    /// own `help` aside), with the names that lead to it.
    fn every_command(
        cmd: &clap::Command,
        path: Vec<String>,
        out: &mut Vec<(Vec<String>, clap::Command)>,
    ) {
        out.push((path.clone(), cmd.clone()));
        for sub in cmd.get_subcommands().filter(|s| s.get_name() != "help") {
            let mut p = path.clone();
            p.push(sub.get_name().to_string());
            every_command(sub, p, out);
        }
    }

    /// `line` split into words as a shell does, with single quotes.
    fn words(line: &str) -> Vec<String> {
        let mut words = vec![String::new()];
        let mut quoted = false;
        for c in line.chars() {
            match c {
                '\'' => quoted = !quoted,
                ' ' if !quoted => words.push(String::new()),
                c => words.last_mut().unwrap().push(c),
            }
        }
        words.retain(|w| !w.is_empty());
        words
    }

    /// The names of the subcommands `words` select (`["device", "status"]`).
    fn selected(words: &[String]) -> Vec<String> {
        let matches = Cli::command()
            .try_get_matches_from(words)
            .unwrap_or_else(|e| panic!("{words:?}: {e}"));
        let mut names = Vec::new();
        let mut m = &matches;
        while let Some((name, sub)) = m.subcommand() {
            names.push(name.to_string());
            m = sub;
        }
        names
    }

    /// Each command's help (walking clap's tree, so a new command is covered)
    /// ends with examples and documents: every example parses, at least one
    /// shows the command itself, the shipped files they read exist, and so do the
    /// documents named.
    #[test]
    fn every_help_has_examples_that_parse_and_documents_that_exist() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut all = Vec::new();
        every_command(&Cli::command(), Vec::new(), &mut all);
        assert!(all.len() > 15, "{} commands", all.len());
        for (path, cmd) in all {
            let name = format!("host-sim {}", path.join(" "));
            let help = cmd
                .get_after_help()
                .map(|h| h.to_string())
                .unwrap_or_default();
            let examples: Vec<&str> = help
                .lines()
                .skip_while(|l| *l != "Examples:")
                .skip(1)
                .take_while(|l| !l.is_empty())
                .map(str::trim)
                .collect();
            assert!(!examples.is_empty(), "{name}: no examples in {help:?}");
            let mut shows_itself = false;
            for example in &examples {
                let words = words(example);
                assert_eq!(words[0], "host-sim", "{name}: {example}");
                Cli::try_parse_from(&words).unwrap_or_else(|e| panic!("{name}: {example}: {e}"));
                shows_itself |= selected(&words).starts_with(&path);
                for w in words
                    .iter()
                    .filter(|w| w.starts_with("examples/") || w.starts_with("tests/"))
                {
                    assert!(root.join(w).is_file(), "{name}: {example}: no file {w}");
                }
            }
            assert!(shows_itself, "{name}: no example of it: {examples:?}");
            let docs = help
                .lines()
                .find_map(|l| l.strip_prefix("Documentation: "))
                .unwrap_or_else(|| panic!("{name}: no documents in {help:?}"));
            let named: Vec<&str> = docs
                .split([',', ' '])
                .filter(|w| w.ends_with(".md") || w.contains(".md#"))
                .collect();
            assert!(!named.is_empty(), "{name}: {docs}");
            for doc in named {
                let file = doc.split('#').next().unwrap();
                assert!(root.join(file).is_file(), "{name}: no document {doc}");
            }
        }
    }

    /// `run --help` states the limits of a run, from the constants that enforce
    /// them.
    #[test]
    fn run_help_states_its_limits() {
        let cli = Cli::command();
        let help = cli
            .find_subcommand("run")
            .and_then(|r| r.get_after_help())
            .unwrap()
            .to_string();
        for line in crate::simulation::limits::describe() {
            assert!(help.contains(&line), "{line:?} not in {help}");
        }
        for said in [
            "--t-end (or simulation.t_end): at most 3600 s",
            "at most 1e7",
            "--animate: runs of at most 600 s",
            "[[contacts]]: 1 to 16",
        ] {
            assert!(help.contains(said), "{said:?} not in {help}");
        }
    }

    /// The top-level `device` line names every `device` command.
    #[test]
    fn the_device_line_names_every_device_command() {
        let cli = Cli::command();
        let device = cli.find_subcommand("device").unwrap();
        let about = device.get_about().unwrap().to_string();
        let said: Vec<&str> = about
            .split(|c: char| !(c.is_alphanumeric() || c == '-'))
            .collect();
        for sub in device.get_subcommands().filter(|s| s.get_name() != "help") {
            assert!(
                said.contains(&sub.get_name()),
                "{}: {about}",
                sub.get_name()
            );
        }
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
