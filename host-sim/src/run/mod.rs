//! `host-sim run MACHINE [--command right|left|stop] [--speed RPM] [--offset DEG]
//! [--open-loop V1,V2|V|coast] [--t-end T] [--out FILE.csv]
//! [--events FILE.csv] [--plot FILE.svg] [--animate FILE.html] [--format table|json]
//! [--set KEY=VALUE]... [--firmware ELF [--firmware-log FILE] [--identify [--write
//! OUT.toml] | --capture FILE.csv --capture-for S]]`
//!
//! With the firmware in the loop, `--identify` runs its motor identification
//! instead of a command and `--capture` records its control ticks from the
//! command ([`asks`]).
//!
//! A machine with one rotor: `--open-loop V` takes one voltage (`V1,V2` is for two
//! rotors, `coast` for both kinds); `--command` runs the controller, which holds
//! the rotor's speed only (no phase loop: `right` and `left` set no offset, and
//! `--offset` is refused), and the output says so ([`report`]).
//!
//! Stages:
//! 1. read and check the machine file with the `--set` overrides
//!    ([`crate::machine`]), and the options: every problem at once, exit 2;
//! 2. simulate ([`crate::simulation`]);
//! 3. write the files asked for, each whole or not at all (the animation:
//!    [`crate::output::animate`]), then the summary on stdout as a table or JSON.

pub mod asks;
pub mod plot;
pub mod report;

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicUsize;

use clap::{Args, ValueEnum};
use shared::controller::{Command, Direction};
use shared::impact::MAX_CONTACTS;

use crate::args::Format;
use crate::args::{FormatArg, MachineArg, PlotArg, SetArgs, TEndArg};
use crate::event::EventRow;
use crate::failure::{Console, Failure, Kind};
use crate::help::epilogue;
use crate::identity;
use crate::interrupt;
use crate::machine::{Machine, MachineContact};
use crate::numbers::{sig, signed};
use crate::output::animate::{self, frames::Frames, Film};
use crate::output::csv::{event_line, trace_header, trace_line, EVENTS_HEADER};
use crate::output::file::Staged;
use crate::output::progress::Progress;
use crate::simulation::closed_loop::{self, ControllerDriver};
use crate::simulation::pil::{FirmwareDriver, TickCost};
use crate::simulation::trace::{Summary, TraceRow};
use crate::simulation::{
    limits, simulate_observed, stop_message, Driver, InTheLoop, Observer, OpenLoop, OpenLoopDriver,
    RunOptions, RunResult,
};
use asks::{Asks, CaptureNote};
use plot::plot_svg;
use report::{summary_json, summary_table, summary_value};

/// Arguments of `host-sim run`.
#[derive(Debug, Args)]
#[command(mut_arg("t_end", |a| a.help("End time, s (default: the file's `simulation.t_end`)")))]
#[command(mut_arg("plot", |a| a.help("Write a plot of the run as SVG")))]
#[command(mut_arg("format", |a| a.help("Output format of the summary")))]
#[command(mut_arg("animate", |a| a.help(animate::option_help())))]
#[command(after_help = help())]
pub struct RunArgs {
    /// The machine file.
    #[command(flatten)]
    pub machine: MachineArg,
    /// Command the controller (the firmware's, in the loop at `rate_hz`): travel
    /// right or left at `--speed`, or stop.
    #[arg(long, value_enum, value_name = "right|left|stop")]
    pub command: Option<CommandArg>,
    /// Rotor speed for `--command`, rpm (default: `[controller].speed_rpm`).
    #[arg(long, value_name = "RPM", allow_negative_numbers = true)]
    pub speed: Option<f64>,
    /// Hold this phase offset, degrees, instead of the tuning table's.
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub offset: Option<f64>,
    /// Drive the windings open loop: constant voltages `V1,V2` (V, signed; `0,0`
    /// shorts the windings), one voltage `V` on a one-rotor machine, or `coast`
    /// (windings open).
    #[arg(long, value_name = "V1,V2|V|coast", allow_hyphen_values = true, value_parser = parse_open_loop)]
    pub open_loop: Option<OpenLoop>,
    /// End time.
    #[command(flatten)]
    pub t_end: TEndArg,
    /// Write the trace as CSV (one row per `output_step`, and around each event).
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
    /// Write the events as CSV (one row per contact per event).
    #[arg(long, value_name = "FILE.csv")]
    pub events: Option<PathBuf>,
    /// The plot.
    #[command(flatten)]
    pub plot: PlotArg,
    /// Write the run as an HTML page that plays it ([`animate::option_help`]).
    #[arg(long, value_name = "FILE.html")]
    pub animate: Option<PathBuf>,
    /// Output format.
    #[command(flatten)]
    pub format: FormatArg,
    /// Run the firmware's binary `pil` (built for this machine file:
    /// `cd firmware && cargo build --release --features pil --bin pil`) on QEMU as
    /// the controller, with the plant as its board (processor in the loop,
    /// docs/pil.md); with --command or --identify.
    #[arg(long, value_name = "ELF")]
    pub firmware: Option<PathBuf>,
    /// With --firmware: where its decoded defmt log goes (default: ELF.log).
    #[arg(long, value_name = "FILE", requires = "firmware")]
    pub firmware_log: Option<PathBuf>,
    /// With --firmware, instead of --command: run the firmware's motor
    /// identification on the simulated plant and print its result as `host-sim
    /// device identify` does; the run ends with it (default --t-end: its worst
    /// case, 60 s a rotor and 10 s for rest).
    #[arg(long)]
    pub identify: bool,
    /// With --identify: write the machine file with the measured motor keys and
    /// rotor inertias, every comment kept (as `device identify --write`).
    #[arg(long, value_name = "OUT.toml")]
    pub write: Option<PathBuf>,
    /// With --firmware and --command: arm the firmware's capture before the
    /// command, read it out after its window and write it as a capture file
    /// (`host-sim replay MACHINE FILE.csv` replays it).
    #[arg(long, value_name = "FILE.csv")]
    pub capture: Option<PathBuf>,
    /// The capture's window from the command, s (at most the firmware's
    /// buffer, 2.048 s at 1 kHz).
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub capture_for: Option<f64>,
    /// Overrides.
    #[command(flatten)]
    pub set: SetArgs,
}

/// The end of `run --help`: examples, the limits of a run (from the constants
/// that enforce them), the documents.
fn help() -> String {
    let mut limits = String::from("Limits (a value beyond one is refused before the run, exit 2):");
    for line in limits::describe() {
        limits.push_str(&format!("\n  {line}"));
    }
    limits.push_str(&format!(
        "\n  --animate: runs of at most {} s\n  [[contacts]]: 1 to {MAX_CONTACTS} (the impact solver's)",
        sig(animate::MAX_SECONDS)
    ));
    epilogue(
        &[
            "host-sim run examples/vibro-driver.toml --command right --t-end 5",
            "host-sim run examples/vibro-driver.toml --open-loop 12,12 --t-end 2 --out trace.csv --events events.csv --plot run.svg",
            "host-sim run examples/vibro-driver.toml --command left --set contacts.K1.friction=0.2 --format json",
            "host-sim run examples/vibro-driver.toml --firmware firmware/target/thumbv7em-none-eabihf/release/pil --identify",
            "host-sim run examples/vibro-driver.toml --firmware firmware/target/thumbv7em-none-eabihf/release/pil --command right --t-end 4 --capture travel.csv --capture-for 2",
        ],
        &[limits],
        &["docs/cli-run.md", "docs/machine-file.md", "docs/pil.md"],
    )
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

/// Parses `--open-loop` (a clap value parser): `coast`, two voltages `V1,V2`, or
/// one `V` (for a one-rotor machine: [`check_open_loop`] matches the count with
/// the machine's rotors).
pub fn parse_open_loop(text: &str) -> Result<OpenLoop, String> {
    if text.trim() == "coast" {
        return Ok(OpenLoop::Coast);
    }
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let volts: Vec<Option<f64>> = parts
        .iter()
        .map(|p| p.parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect();
    match volts.as_slice() {
        [Some(a), Some(b)] => Ok(OpenLoop::Voltages([*a, *b])),
        [Some(a)] => Ok(OpenLoop::Voltage(*a)),
        _ => Err(
            "expected two winding voltages in V, `V1,V2` (e.g. `12,12`; `0,0` shorts the windings), one `V` for a machine with one rotor, or `coast` (windings open)"
                .to_string(),
        ),
    }
}

/// `--open-loop` against the machine: one voltage per rotor (`coast` fits any),
/// else the user's failure.
pub fn check_open_loop(open_loop: OpenLoop, machine: &Machine) -> Result<(), Failure> {
    let rotors = machine.rotors.len();
    match open_loop.rotors() {
        Some(n) if n != rotors => {
            let want = if rotors == 1 {
                "one winding voltage `V`"
            } else {
                "two winding voltages `V1,V2`"
            };
            Err(Failure::usage(format!(
                "--open-loop {open_loop}: {n} voltage{} for a machine with {rotors} rotor{}: give {want} (V, signed), or `coast`",
                if n == 1 { "" } else { "s" },
                if rotors == 1 { "" } else { "s" },
            )))
        }
        _ => Ok(()),
    }
}

/// Runs the command (stages of the module doc).
pub fn run(args: &RunArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    // 1. The machine and the options.
    let machine = Machine::load(&args.machine.path, &args.set.keys)?;
    let (drive, t_end, window) = check_options(args, &machine)?;
    // What the run asks of the firmware beyond its command: the machine file
    // the identification compares with read, and its --write staged, before
    // anything runs.
    let asks = match (args.identify, window, &drive) {
        (true, _, _) => Some(Asks::Identify(Box::new(identity::prepare(
            Some(&args.machine.path),
            args.write.as_deref(),
        )?))),
        (false, Some(w), Drive::Controller(schedule)) => {
            schedule.first().map(|(_, c)| Asks::Capture(w, *c))
        }
        _ => None,
    };

    // What drives the motors, built before any output is opened: a controller
    // that cannot be built (its tuning table) is refused with nothing written.
    let mut warnings = Vec::new();
    let (mut driver, how) = build_driver(args, &machine, &drive, asks.as_ref(), &mut warnings)?;
    let firmware_log = args.firmware.as_ref().map(|elf| {
        args.firmware_log
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("{}.log", elf.display())))
    });

    // The output files, checked and opened before the run: a path that cannot be
    // written is refused at once and nothing is left behind. The capture is
    // staged on its own: written only once it was read out whole.
    let (mut staged, files) = open_outputs(args, &machine, firmware_log.as_deref())?;
    let mut capture_out = Staged::new();
    let capture_index = capture_out.add_optional("--capture", args.capture.as_deref())?;

    // 2. Simulate, the trace and the events streamed to their files.
    let (mut result, failure, frames) =
        simulate_to_files(&machine, &mut driver, t_end, &mut staged, &files)?;
    let cost = finish_firmware(&mut driver, &mut staged, files.log, &mut warnings)?;
    if let Some(why) = failure {
        return Err(driver_failure(why, &driver, firmware_log.as_deref()));
    }
    result.summary.warnings.extend(warnings);
    // A run that is no travel (through the fundament, tipped over) has no way
    // it went.
    let travel =
        Some(result.summary.mean_velocity).filter(|_| result.summary.not_a_travel().is_none());
    result
        .summary
        .warnings
        .extend(one_rotor_direction(args.command, &machine, travel));

    // 3. The plot and the animation, then the summary.
    let title = format!("host-sim run {} ({how})", args.machine.path.display());
    if let Some(i) = files.plot {
        staged.write(i, &plot_svg(&result.rows, &result.events, &machine, &title))?;
    }
    if let (Some(i), Some(mut frames)) = (files.animation, frames) {
        staged.write(i, &animate::page(&title, &machine, &mut frames))?;
    }
    if let Some(stop) = &result.stopped {
        // A signal, or a plant that stopped advancing: what was simulated is
        // written whole; no summary of part of a run, no capture.
        staged.commit()?;
        let why = stop_message(stop, Some(t_end));
        let capture = if args.capture.is_some() {
            ", no capture"
        } else {
            ""
        };
        return Err(Failure::run(format!(
            "run: {why}; the files asked for hold the run up to there, no summary{capture}"
        )));
    }
    // The capture read out of the firmware, or nothing written.
    let capture = match (capture_index, &driver, &args.capture) {
        (Some(i), InTheLoop::Firmware(f), Some(path)) => {
            let file = asks::captured(f, path, (t_end, t_end_origin(args)))?;
            capture_out.write(i, &file.to_text())?;
            Some(CaptureNote::of(&file, path))
        }
        _ => None,
    };
    staged.commit()?;
    capture_out.commit()?;
    let firmware_line = args.firmware.as_ref().zip(firmware_log.as_ref());
    if let (Some(Asks::Identify(prepared)), InTheLoop::Firmware(f), Some((elf, log))) =
        (asks, &driver, firmware_line)
    {
        let ended = result.last_row.map_or(0.0, |r| r.t);
        let mut note = format!(
            "identification: the firmware {} on QEMU (processor in the loop) on the plant of {}, {} s simulated; its log: {}\n{}\n",
            elf.display(),
            args.machine.path.display(),
            sig(ended),
            log.display(),
            cost_line(&cost.unwrap_or_default())
        );
        for w in &result.summary.warnings {
            note.push_str(&format!("warning: {w}\n"));
        }
        return asks::conclude_identify(
            f,
            prepared,
            args.format.format,
            (t_end, t_end_origin(args)),
            &note,
            console,
        );
    }
    console.print(&summary_text(
        args.format.format,
        &result.summary,
        firmware_line,
        &cost.unwrap_or_default(),
        capture.as_ref(),
    ));
    Ok(())
}

/// The option that set the run's end time, for the messages about it.
fn t_end_origin(args: &RunArgs) -> &'static str {
    if args.t_end.seconds.is_some() {
        "--t-end"
    } else if args.identify {
        "--identify's default end time"
    } else {
        "simulation.t_end"
    }
}

/// Stage 1's check of the options against the machine: what drives the motors,
/// the run's end time, s, and the capture's window, ticks (with `--capture`).
/// Every problem at once, as a usage failure (exit 2); the limits of a run are
/// checked only once the options themselves are sound.
fn check_options(args: &RunArgs, machine: &Machine) -> Result<(Drive, f64, Option<u16>), Failure> {
    let mut problems = Vec::new();
    let drive = choose_drive(args, machine, &mut problems);
    if args.firmware.is_some() && args.command.is_none() && !args.identify {
        problems.push(
            "--firmware runs the firmware as the controller: give --command right|left|stop"
                .to_string(),
        );
    }
    if args.command.is_none() && (args.speed.is_some() || args.offset.is_some()) {
        problems.push("--speed and --offset go with --command".to_string());
    }
    let t_end = args.t_end.seconds.unwrap_or(if args.identify {
        asks::identify_t_end(machine)
    } else {
        machine.simulation.t_end
    });
    if !(t_end.is_finite() && t_end > 0.0) {
        problems.push(format!(
            "--t-end {t_end}: must be a positive number of seconds"
        ));
    }
    let window = asks::check(args, machine, t_end, t_end_origin(args), &mut problems);
    if args.animate.is_some() {
        problems.extend(animate::check_duration(t_end, t_end_origin(args)));
    }
    let Some(drive) = drive.filter(|_| problems.is_empty()) else {
        return Err(Failure::new(Kind::Usage, problems));
    };

    problems.extend(limits::check(machine, t_end, t_end_origin(args)));
    if !problems.is_empty() {
        return Err(Failure::new(Kind::Usage, problems));
    }
    Ok((drive, t_end, window))
}

/// What drives the motors: exactly one of `--command` (the controller, with its
/// schedule) and `--open-loop` (its voltages matched with the machine's rotors).
/// `None` with the problems added to `problems` when neither or both are given or
/// the one given does not fit the machine.
fn choose_drive(args: &RunArgs, machine: &Machine, problems: &mut Vec<String>) -> Option<Drive> {
    if args.identify {
        // The firmware drives the motors itself, no command sent
        // ([`asks::check`] says what does not go with it).
        return Some(Drive::Controller(Vec::new()));
    }
    match (args.command, args.open_loop) {
        (Some(_), Some(_)) => {
            problems.push(
                "run: give either --command (the controller drives) or --open-loop, not both"
                    .to_string(),
            );
            None
        }
        (Some(c), None) => match controller_schedule(c, args, machine) {
            Ok(schedule) => Some(Drive::Controller(schedule)),
            Err(e) => {
                problems.extend(e);
                None
            }
        },
        (None, Some(o)) => match check_open_loop(o, machine) {
            Ok(()) => Some(Drive::OpenLoop(o)),
            Err(f) => {
                problems.push(f.text());
                None
            }
        },
        (None, None) => {
            problems.push(
                "run: nothing drives the motors: give --command right|left|stop (the controller), --open-loop V1,V2 (winding voltages, V; one V for a one-rotor machine) or --open-loop coast"
                    .to_string(),
            );
            None
        }
    }
}

/// The driver of the windings for `drive` (the open loop, the controller in the
/// loop, or with `--firmware` the firmware on QEMU, asked `asks` beyond its
/// command) and the plot title's words for it. Warnings about the drive
/// (voltages clamped to the supply, the controller's constants, `--set` unseen
/// by the firmware) go to `warnings`.
fn build_driver(
    args: &RunArgs,
    machine: &Machine,
    drive: &Drive,
    asks: Option<&Asks>,
    warnings: &mut Vec<String>,
) -> Result<(InTheLoop<dyn Driver>, String), Failure> {
    let supply = machine.drive.supply_voltage;
    Ok(match drive {
        Drive::OpenLoop(open_loop) => {
            if open_loop.volts().iter().any(|u| u.abs() > supply) {
                warnings.push(format!(
                    "--open-loop {open_loop}: clamped to the supply of {supply} V"
                ));
            }
            let how = match open_loop {
                OpenLoop::Coast => "open loop, coast".to_string(),
                OpenLoop::Voltages(v) => format!("open loop, {} V, {} V", v[0], v[1]),
                OpenLoop::Voltage(v) => format!("open loop, {v} V, one rotor"),
            };
            (
                InTheLoop::Host(Box::new(OpenLoopDriver::new(*open_loop, supply))),
                how,
            )
        }
        Drive::Controller(schedule) => {
            warnings.extend(closed_loop::constants_warning(machine));
            let how = if args.identify {
                "the firmware's identification".to_string()
            } else {
                describe_command(args, machine)
            };
            match &args.firmware {
                Some(elf) => {
                    if !args.set.keys.is_empty() {
                        warnings.push(
                            "--firmware with --set: the firmware's controller is built from the machine file as written; the overrides change the plant only"
                                .to_string(),
                        );
                    }
                    // A capture sends the command itself, once it is armed.
                    let schedule = match asks {
                        Some(Asks::Capture(..)) => Vec::new(),
                        _ => schedule.clone(),
                    };
                    let mut firmware =
                        FirmwareDriver::start(machine, &args.machine.path, elf, schedule)?;
                    if let Some(asks) = asks {
                        firmware = firmware.with_script(asks::script(asks));
                    }
                    (
                        InTheLoop::Firmware(Box::new(firmware)),
                        format!("{how}, firmware {}", elf.display()),
                    )
                }
                None => (
                    InTheLoop::Host(Box::new(ControllerDriver::new(machine, schedule.clone())?)),
                    how,
                ),
            }
        }
    })
}

/// The files a run writes, by their index among the staged files (`None`: not
/// asked for).
struct Outputs {
    /// `--out`, the trace.
    trace: Option<usize>,
    /// `--events`.
    events: Option<usize>,
    /// `--plot`.
    plot: Option<usize>,
    /// `--animate`.
    animation: Option<usize>,
    /// The firmware's log (`--firmware-log`, or the ELF's name with `.log`).
    log: Option<usize>,
}

/// Opens every file asked for (`firmware_log`: the firmware's log, with
/// `--firmware`) and writes the trace's and the events' CSV headers: a path that
/// cannot be written is refused before the run.
fn open_outputs(
    args: &RunArgs,
    machine: &Machine,
    firmware_log: Option<&Path>,
) -> Result<(Staged, Outputs), Failure> {
    let mut staged = Staged::new();
    let files = Outputs {
        trace: staged.add_optional("--out", args.out.as_deref())?,
        events: staged.add_optional("--events", args.events.as_deref())?,
        plot: staged.add_optional("--plot", args.plot.file.as_deref())?,
        animation: staged.add_optional("--animate", args.animate.as_deref())?,
        log: staged.add_optional("--firmware-log", firmware_log)?,
    };
    let contacts = machine.contacts.len();
    if let Some(i) = files.trace {
        let names: Vec<String> = machine.contacts.iter().map(|c| c.name.clone()).collect();
        let bodies: Vec<String> = machine.bodies.iter().map(|b| b.name.clone()).collect();
        staged.write(
            i,
            &format!(
                "{}\n",
                trace_header(&names[..contacts.min(MAX_CONTACTS)], &bodies)
            ),
        )?;
    }

    if let Some(i) = files.events {
        staged.write(i, &format!("{EVENTS_HEADER}\n"))?;
    }
    Ok((staged, files))
}

/// Stage 2: simulates to `t_end`, s, streaming the trace and the events to their
/// files and filming the run if it is animated. The run's result, the driver's
/// failure if it failed, and the animation's frames; a write error ends the run
/// and is returned.
fn simulate_to_files(
    machine: &Machine,
    driver: &mut InTheLoop<dyn Driver>,
    t_end: f64,
    staged: &mut Staged,
    files: &Outputs,
) -> Result<(RunResult, Option<Failure>, Option<Frames>), Failure> {
    let mut options = RunOptions::new(t_end);
    options.keep_rows = files.plot.is_some();
    options.keep_events = files.plot.is_some();
    let shape = (machine.contacts.len(), machine.bodies.len());
    let mut watch = Watch::new(
        t_end,
        staged,
        (files.trace, files.events),
        shape,
        &machine.contacts,
    );
    let mut film = Film {
        frames: files.animation.map(|_| Frames::new(machine)),
        inner: &mut watch,
    };
    let result = simulate_observed(machine, driver.driver(), &options, &mut film);
    let failure = driver.driver().failure();
    let frames = film.frames;
    watch.finish()?;
    Ok((result, failure, frames))
}

/// Ends the firmware on QEMU, if it was the controller: its warnings go to
/// `warnings`, its log to the file `log`, and its control task's cost is returned
/// (`None` for a driver of the host's).
fn finish_firmware(
    driver: &mut InTheLoop<dyn Driver>,
    staged: &mut Staged,
    log: Option<usize>,
    warnings: &mut Vec<String>,
) -> Result<Option<TickCost>, Failure> {
    let InTheLoop::Firmware(f) = driver else {
        return Ok(None);
    };
    let cost = f.cost();
    f.finish();
    warnings.extend(f.warnings());
    if let Some(i) = log {
        staged.write(i, f.log())?;
    }
    Ok(Some(cost))
}

/// The failure of a run whose driver failed (`why`): the firmware's log is kept
/// at `firmware_log`, to say why, and named after it; nothing else is written.
fn driver_failure(
    why: Failure,
    driver: &InTheLoop<dyn Driver>,
    firmware_log: Option<&Path>,
) -> Failure {
    if let (InTheLoop::Firmware(f), Some(path)) = (driver, firmware_log) {
        let _ = std::fs::write(path, f.log());
        return why.with_detail(format!("the firmware's log: {}", path.display()));
    }
    why
}

/// The summary on stdout in `format`; with the firmware in the loop
/// (`firmware_line`: its ELF and its log) also the firmware, its log and its
/// control task's `cost`, and the `capture` written, if one was.
fn summary_text(
    format: Format,
    summary: &Summary,
    firmware_line: Option<(&PathBuf, &PathBuf)>,
    cost: &TickCost,
    capture: Option<&CaptureNote>,
) -> String {
    match (format, firmware_line) {
        (Format::Json, None) => summary_json(summary),
        (Format::Table, None) => summary_table(summary),
        (Format::Json, Some((elf, log))) => {
            let mut v = summary_value(summary);
            v["firmware"] = serde_json::json!({
                "elf": elf.display().to_string(),
                "log": log.display().to_string(),
                "instructions_per_tick": {
                    "ticks": cost.ticks,
                    "mean": cost.mean(),
                    "max": cost.max,
                },
            });
            if let Some(c) = capture {
                v["firmware"]["capture"] = serde_json::json!({
                    "file": c.path.display().to_string(),
                    "ticks": c.ticks,
                    "contents": c.contents,
                });
            }
            let mut text = serde_json::to_string_pretty(&v).unwrap_or_default();
            text.push('\n');
            text
        }
        (Format::Table, Some((elf, log))) => format!(
            "{}\nthe controller: the firmware {} on QEMU (processor in the loop); its log: {}\n{}\n{}",
            summary_table(summary),
            elf.display(),
            log.display(),
            cost_line(cost),
            capture.map_or(String::new(), |c| format!(
                "its capture: {}; written to {}\n",
                c.contents,
                c.path.display()
            ))
        ),
    }
}

/// Watches a run: streams its trace rows to the trace file, shows progress on a
/// terminal, and ends the run on Ctrl-C.
struct Watch<'s> {
    staged: &'s mut Staged,
    /// The trace's and the events' files among `staged`'s, if asked for.
    trace: Option<usize>,
    events: Option<usize>,
    /// The machine's contacts (their bodies: the events' columns).
    machine_contacts: &'s [MachineContact],
    /// The machine's contacts and bodies after the platform (the trace's columns).
    contacts: usize,
    bodies: usize,
    line: String,
    /// The first write error: the run stops there.
    error: Option<Failure>,
    progress: Progress,
}

impl<'s> Watch<'s> {
    fn new(
        t_end: f64,
        staged: &'s mut Staged,
        (trace, events): (Option<usize>, Option<usize>),
        (contacts, bodies): (usize, usize),
        machine_contacts: &'s [MachineContact],
    ) -> Self {
        interrupt::catch();
        // Progress in ms of simulated time: a bar on a terminal, else lines.
        let progress = Progress::new("run", (t_end * 1e3).ceil() as u64, "ms simulated");
        Watch {
            staged,
            trace,
            events,
            machine_contacts,
            contacts,
            bodies,
            line: String::new(),
            error: None,
            progress,
        }
    }

    /// The write error, if one stopped the run.
    fn finish(self) -> Result<(), Failure> {
        self.progress.finish_and_clear();
        self.error.map_or(Ok(()), Err)
    }
}

impl Observer for Watch<'_> {
    fn row(&mut self, row: &TraceRow) {
        if let (Some(i), None) = (self.trace, &self.error) {
            self.line.clear();
            trace_line(row, self.contacts, self.bodies, &mut self.line);
            if let Err(e) = self.staged.write(i, &self.line) {
                self.error = Some(e);
            }
        }
    }

    fn events(&mut self, batch: &[EventRow]) {
        if let (Some(i), None) = (self.events, &self.error) {
            self.line.clear();
            for e in batch {
                event_line(e, self.machine_contacts, &mut self.line);
            }
            if let Err(e) = self.staged.write(i, &self.line) {
                self.error = Some(e);
            }
        }
    }

    fn go_on(&mut self, t: f64) -> bool {
        self.progress.set_position((t * 1e3) as u64);
        self.error.is_none() && !interrupt::interrupted()
    }

    fn stop_flag(&self) -> Option<&'static AtomicUsize> {
        Some(interrupt::flag())
    }
}

/// The firmware's control task's cost in the summary's table.
fn cost_line(cost: &TickCost) -> String {
    match cost.mean() {
        Some(mean) => format!(
            "its control task: mean {mean:.0}, max {} instructions a tick over {} ticks (QEMU's clock: 1 ns an instruction; the record exchange included)",
            cost.max, cost.ticks
        ),
        None => "its control task: no tick ran".to_string(),
    }
}

/// What drives the motors in a run.
enum Drive {
    /// Open loop.
    OpenLoop(OpenLoop),
    /// The controller, with its commands.
    Controller(Vec<(f64, Command)>),
}

/// The controller's command at t = 0 for `--command`, `--speed`, `--offset`.
fn controller_schedule(
    c: CommandArg,
    args: &RunArgs,
    machine: &Machine,
) -> Result<Vec<(f64, Command)>, Vec<String>> {
    let mut problems = Vec::new();
    let speed = args.speed.unwrap_or(machine.controller.speed_rpm);
    // The controller refuses speeds outside its range (and would stay idle):
    // say so here instead. Stop needs no speed.
    let limits = closed_loop::speed_range_rpm(machine);
    let in_range = speed.is_finite() && speed >= limits.0 && speed <= limits.1;
    if c != CommandArg::Stop && !in_range {
        let origin = if args.speed.is_some() {
            "--speed"
        } else {
            "controller.speed_rpm"
        };
        problems.push(format!(
            "{origin} {speed}: the controller runs the rotors from {:.0} to {:.0} rpm (80 % of the motors' no-load speed)",
            limits.0, limits.1
        ));
    }
    if let Some(o) = args.offset {
        if machine.rotors.len() == 1 {
            problems.push(format!(
                "--offset {o}: the machine has one rotor ({:?}): there is no phase offset to hold (the controller holds its speed only)",
                machine.rotors[0].name
            ));
        } else if !o.is_finite() {
            problems.push(format!("--offset {o}: must be a finite angle in degrees"));
        }
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    let command = match (c, args.offset) {
        (CommandArg::Stop, _) => Command::Stop,
        (_, Some(offset)) => Command::HoldOffset {
            speed_rpm: speed as f32,
            offset_deg: offset.rem_euclid(360.0) as f32,
        },
        (CommandArg::Right, None) => Command::Travel {
            direction: Direction::Right,
            speed_rpm: speed as f32,
        },
        (CommandArg::Left, None) => Command::Travel {
            direction: Direction::Left,
            speed_rpm: speed as f32,
        },
    };
    Ok(vec![(0.0, command)])
}

/// The warning of `--command right|left` on a one-rotor machine (`None`
/// otherwise): it has no direction to choose, its controller runs the rotor at
/// the speed and ignores the direction, and the platform goes where its rotor
/// and feet take it, here at `mean_velocity`, m/s (`None`: the run was no
/// travel, a body went through the fundament or tipped over).
fn one_rotor_direction(
    command: Option<CommandArg>,
    machine: &Machine,
    mean_velocity: Option<f64>,
) -> Option<String> {
    let asked = match command {
        Some(CommandArg::Right) => "right",
        Some(CommandArg::Left) => "left",
        _ => return None,
    };
    if machine.rotors.len() != 1 {
        return None;
    }
    let went = match mean_velocity {
        None => "was no travel (see the warning of its breach)".to_string(),
        Some(v) => {
            let way = if v > 0.0 {
                "right"
            } else if v < 0.0 {
                "left"
            } else {
                "nowhere"
            };
            format!("went {way} ({} m/s over the second half)", signed(v))
        }
    };
    Some(format!(
        "--command {asked}: the machine has one rotor ({:?}): it has no direction to choose; the controller runs the rotor at the speed and ignores `{asked}`, and the platform goes where its rotor and feet take it: this run {went}",
        machine.rotors[0].name,
    ))
}

/// The plot title's description of a controller run.
fn describe_command(args: &RunArgs, machine: &Machine) -> String {
    let speed = args.speed.unwrap_or(machine.controller.speed_rpm);
    if machine.rotors.len() == 1 {
        return match args.command {
            Some(CommandArg::Stop) => "controller, stop (one rotor)".to_string(),
            _ => format!("controller, one rotor held at {speed} rpm, no phase loop"),
        };
    }
    match (args.command, args.offset) {
        (Some(CommandArg::Stop), _) => "controller, stop".to_string(),
        (_, Some(o)) => format!("controller, offset {o} deg at {speed} rpm"),
        (Some(CommandArg::Left), None) => format!("controller, travel left at {speed} rpm"),
        _ => format!("controller, travel right at {speed} rpm"),
    }
}
